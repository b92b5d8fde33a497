//! The pinhole camera a picture is taken with: its description (eye, target, up, vertical field
//! of view), checking it, reading and writing it as text, and the automatic framing used when
//! nothing else says where to look. This module owns the camera as data; scene files carry one
//! (`# camera: …` in OBJ, `comment camera: …` in PLY headers, read by [`crate::scene`]), baked
//! files repeat it ([`crate::io`]), and [`crate::render`] renders with it. It casts no
//! rays.
//!
//! Which camera a picture uses: `--camera` if given, else the scene file's camera, else an
//! automatic view of the bounding box that is level about the scene's up axis (`--up`): one of
//! the four views from outside its sides ([`Camera::framings`]) or of the four eye-height views
//! from just inside them ([`Camera::eye_height_views`], a room seen from within), and the view
//! from above only when no level view sees a front face (a flat ground plane);
//! [`crate::render::camera_for`] chooses by what each sees.
//!
//! Text form: ten numbers `EX EY EZ TX TY TZ UX UY UZ FOV` (eye, target and up in scene units,
//! the vertical field of view in degrees), separated by commas and/or whitespace. Written with
//! Rust's shortest round-trip decimals ([`Camera::to_text`]), so reading a written camera gives
//! back exactly the same `f64`s.

use std::fmt;

use glam::DVec3;

use crate::{Error, Result};

/// The vertical field of view of the Cornell box's published camera, degrees: a 35 mm lens on
/// a 25 mm film, 2·atan(12.5/35) ≈ 39.30765°.
pub fn cornell_vfov_degrees() -> f64 {
    2.0 * (12.5f64 / 35.0).atan().to_degrees()
}

/// The scene's up axis, for the automatic framing (`--up`): Wavefront files from most tools
/// are y-up, Blender's and Quake's native coordinates z-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Up {
    X,
    #[default]
    Y,
    Z,
}

impl Up {
    /// The axis as a unit vector.
    pub fn axis(self) -> DVec3 {
        match self {
            Up::X => DVec3::X,
            Up::Y => DVec3::Y,
            Up::Z => DVec3::Z,
        }
    }

    /// The first horizontal direction a framing looks along: +z with y up (the Cornell box's
    /// view), +y with z up (Blender's front view), +z with x up.
    pub fn forward(self) -> DVec3 {
        match self {
            Up::X | Up::Y => DVec3::Z,
            Up::Z => DVec3::Y,
        }
    }
}

impl crate::Choice for Up {
    const SETTING: &'static str = "view.up";
    const ALL: &'static [Up] = &[Up::X, Up::Y, Up::Z];

    fn name(self) -> &'static str {
        match self {
            Up::X => "x",
            Up::Y => "y",
            Up::Z => "z",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Up::X => "+x is up",
            Up::Y => "+y is up (most OBJ files)",
            Up::Z => "+z is up (Blender, Quake levels)",
        }
    }
}

/// The marker that starts a camera line in a scene file: `# camera: …` (OBJ) and
/// `comment camera: …` (PLY header).
pub const FILE_KEYWORD: &str = "camera:";

/// A pinhole camera.
///
/// Invariants of a camera from [`Camera::new`] or [`Camera::parse`] (what every constructor in
/// this crate guarantees): all coordinates finite, `eye ≠ target`, `up` not zero and not
/// parallel to the view direction `target − eye`, `0 < vfov_degrees < 180`, and the picture's
/// frame (the unit view direction and the unit vector across it and `up`) finite in f64.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position, scene units.
    pub eye: DVec3,
    /// Point looked at, scene units.
    pub target: DVec3,
    /// Up direction (need not be unit or orthogonal to the view direction; only its component
    /// across the view direction matters).
    pub up: DVec3,
    /// Vertical field of view, degrees, in (0, 180).
    pub vfov_degrees: f64,
}

impl Camera {
    /// A camera from its ten numbers, checked against the invariants. The error says which one
    /// fails, in words; callers wrap it with the option or the file and line.
    pub fn new(
        eye: DVec3,
        target: DVec3,
        up: DVec3,
        vfov_degrees: f64,
    ) -> std::result::Result<Camera, String> {
        let camera = Camera {
            eye,
            target,
            up,
            vfov_degrees,
        };
        if ![eye, target, up].iter().all(|v| v.is_finite()) || !vfov_degrees.is_finite() {
            return Err("numbers must be finite".into());
        }
        let forward = target - eye;
        if forward.length() == 0.0 {
            return Err("eye and target coincide".into());
        }
        if forward.cross(up).length() <= 1e-12 * forward.length() * up.length() {
            return Err("up is zero or parallel to the view direction".into());
        }
        // The frame a picture is taken with (`render`: the unit view direction, and the unit
        // right vector across it and up) must exist in f64: numbers near f64's limits (an eye
        // 1e200 from its target, an up of 1e-200) overflow or underflow the test above, which
        // then passes on NaN.
        let unit = |v: DVec3| v.is_finite() && (v.length() - 1.0).abs() < 1e-9;
        let direction = forward.normalize();
        if !unit(direction) || !unit(direction.cross(up).normalize()) {
            return Err(
                "the view direction and up give no frame in f64 (numbers too large or too small)"
                    .into(),
            );
        }
        if !(vfov_degrees > 0.0 && vfov_degrees < 180.0) {
            return Err("the field of view must be in (0, 180) degrees".into());
        }
        Ok(camera)
    }

    /// Parses the text form (ten numbers separated by commas and/or whitespace; see the module
    /// documentation). The error says what is wrong, in words.
    pub fn from_text(text: &str) -> std::result::Result<Camera, String> {
        let v: Vec<f64> = text
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .map(|s| {
                s.parse::<f64>()
                    .map_err(|_| format!("{s:?} is not a number"))
            })
            .collect::<std::result::Result<_, _>>()?;
        if v.len() != 10 {
            return Err(format!(
                "expected 10 numbers (eye x y z, target x y z, up x y z, vertical field of view \
                 in degrees), got {}",
                v.len()
            ));
        }
        Camera::new(
            DVec3::new(v[0], v[1], v[2]),
            DVec3::new(v[3], v[4], v[5]),
            DVec3::new(v[6], v[7], v[8]),
            v[9],
        )
    }

    /// Parses `--camera EX,EY,EZ,TX,TY,TZ,UX,UY,UZ,FOV` ([`Camera::from_text`]); errors are
    /// [`Error::Setting`] named `camera` and quoting the text.
    pub fn parse(text: &str) -> Result<Camera> {
        Camera::from_text(text).map_err(|m| Error::setting("camera", format!("{text:?}: {m}")))
    }

    /// The ten numbers separated by single spaces, in Rust's shortest round-trip form, as
    /// scene files and baked files carry them after [`FILE_KEYWORD`].
    pub fn to_text(&self) -> String {
        let n = [
            self.eye.x,
            self.eye.y,
            self.eye.z,
            self.target.x,
            self.target.y,
            self.target.z,
            self.up.x,
            self.up.y,
            self.up.z,
            self.vfov_degrees,
        ];
        n.map(|x| x.to_string()).join(" ")
    }

    /// The first framing of [`Camera::framings`] with +y up: looking along +z at the centre of
    /// the bounding box [lo, hi] from its −z side. For the Cornell box this puts the eye at
    /// about (278, 274, −770), close to the published (278, 273, −800).
    pub fn framing(lo: DVec3, hi: DVec3) -> Camera {
        Camera::framings(lo, hi, Up::Y)[0]
    }

    /// The five views of the bounding box [lo, hi] for the `up` axis: looking horizontally at
    /// its centre from each side in turn (first along [`Up::forward`], then turning 90° at a
    /// time), then looking straight down from above (what a flat ground plane is seen from,
    /// when no level view sees it), with the Cornell box's published lens
    /// ([`cornell_vfov_degrees`]), far enough back that the box's near face fills the picture's
    /// height or width.
    pub fn framings(lo: DVec3, hi: DVec3, up: Up) -> [Camera; 5] {
        let vfov_degrees = cornell_vfov_degrees();
        let centre = 0.5 * (lo + hi);
        let half = 0.5 * (hi - lo);
        let (up, first) = (up.axis(), up.forward());
        let side = first.cross(up);
        // (view direction, the picture's up)
        let views = [
            (first, up),
            (side, up),
            (-first, up),
            (-side, up),
            (-up, first),
        ];
        views.map(|(forward, picture_up)| {
            let right = forward.cross(picture_up);
            let across = half.dot(right.abs()).max(half.dot(picture_up.abs()));
            let distance =
                across / (0.5 * vfov_degrees.to_radians()).tan() + half.dot(forward.abs());
            Camera {
                eye: centre - forward * distance,
                target: centre,
                up: picture_up,
                vfov_degrees,
            }
        })
    }
}

/// Vertical field of view of the eye-height views from inside the bounding box
/// ([`Camera::eye_height_views`]), degrees: a wide lens, as interiors are photographed.
pub const INSIDE_VFOV_DEGREES: f64 = 60.0;

/// How far inside the bounding box the eye of an eye-height view stands, as a share of the
/// box's depth along the view (from the side it looks from).
pub const INSIDE_INSET: f64 = 0.05;

impl Camera {
    /// The four level views of the bounding box [lo, hi] from just inside it, for the `up`
    /// axis: the eye [`INSIDE_INSET`] of the box's depth in from one side (in the order of
    /// [`Camera::framings`]' sides), halfway up the box (its height along `up`), looking
    /// horizontally across at the far side with a [`INSIDE_VFOV_DEGREES`] lens and `up` as the
    /// picture's up. A room whose walls face inward shows only their backs from outside; from
    /// here it is seen as someone standing in it sees it.
    pub fn eye_height_views(lo: DVec3, hi: DVec3, up: Up) -> [Camera; 4] {
        let centre = 0.5 * (lo + hi);
        let half = 0.5 * (hi - lo);
        let (up, first) = (up.axis(), up.forward());
        let side = first.cross(up);
        [first, side, -first, -side].map(|forward| {
            // The half-depth along the view, and the eye that far back from the centre less
            // the inset; the target ahead at the same height, so the view stays level (a box
            // flat along the view still gets a target apart from the eye).
            let depth = half.dot(forward.abs());
            let eye = centre - forward * (depth * (1.0 - 2.0 * INSIDE_INSET));
            let reach = [depth, half.length(), 1.0]
                .into_iter()
                .find(|&d| d > 0.0)
                .unwrap_or(1.0);
            Camera {
                eye,
                target: eye + forward * reach,
                up,
                vfov_degrees: INSIDE_VFOV_DEGREES,
            }
        })
    }
}

impl fmt::Display for Camera {
    /// `eye (x y z), target (x y z), up (x y z), vertical field of view F°`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = |p: DVec3| format!("{} {} {}", p.x, p.y, p.z);
        write!(
            f,
            "eye ({}), target ({}), up ({}), vertical field of view {}°",
            v(self.eye),
            v(self.target),
            v(self.up),
            self.vfov_degrees
        )
    }
}

/// Reads the camera of a scene-file comment, if the comment is a camera line.
///
/// `comment` is the text after the comment marker (`#` in OBJ, `comment` in PLY). If its first
/// word is [`FILE_KEYWORD`] the rest must be a valid camera ([`Camera::from_text`]): `Some(Ok)`
/// or `Some(Err(why))`; any other comment is `None`.
pub fn from_comment(comment: &str) -> Option<std::result::Result<Camera, String>> {
    let rest = comment.trim_start().strip_prefix(FILE_KEYWORD)?;
    Some(Camera::from_text(rest).map_err(|why| {
        format!("malformed camera line ({FILE_KEYWORD} EX EY EZ TX TY TZ UX UY UZ FOV): {why}")
    }))
}

/// The camera lines of one file, read comment by comment: at most one is allowed. Every
/// reader of a file that may carry a camera (the OBJ and PLY scene loaders, the read-back of
/// baked files) goes through it, so they all apply the same rule.
#[derive(Debug, Default)]
pub struct CameraLine {
    /// The camera found, with its line.
    found: Option<(usize, Camera)>,
}

impl CameraLine {
    /// Reads the comment at `line` (the text after the comment marker): a camera line is
    /// parsed and kept; a malformed one, or a second one, is an error message for that line.
    /// Any other comment is ignored.
    pub fn read(&mut self, comment: &str, line: usize) -> std::result::Result<(), String> {
        let Some(camera) = from_comment(comment) else {
            return Ok(());
        };
        let camera = camera?;
        if let Some((first, _)) = self.found {
            return Err(format!("a second camera line (the first is line {first})"));
        }
        self.found = Some((line, camera));
        Ok(())
    }

    /// The camera the file carries, if any.
    pub fn camera(&self) -> Option<Camera> {
        self.found.map(|(_, c)| c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_and_validate() {
        let c = Camera::parse("278,273,-800,278,273,0,0,1,0,39.3").unwrap();
        assert_eq!(c.eye, DVec3::new(278.0, 273.0, -800.0));
        assert_eq!(c.vfov_degrees, 39.3);
        // Whitespace works as well as commas.
        assert_eq!(
            Camera::from_text(" 278 273 -800  278 273 0\t0 1 0 39.3 ").unwrap(),
            c
        );
        for bad in [
            "1,2,3",
            "0,0,0,0,0,0,0,1,0,40",
            "0,0,0,0,0,1,0,0,1,40",
            "0,0,0,0,0,1,0,1,0,0",
            "0,0,0,0,0,1,0,1,0,180",
            "a,0,0,0,0,1,0,1,0,40",
            "0,0,0,0,0,1,0,1,0,nan",
            "0,0,0,0,0,inf,0,1,0,40",
            "",
            // Found by the camera_line fuzzer: |target − eye|² overflows, the test of up
            // against the view passed on NaN, and the frame was NaN (a zero up).
            "27,1.1e201,0,2,5,6,0,0,0,34",
            // The same with a non-zero up, and an eye and target each finite whose
            // difference overflows.
            "0,1e200,0,0,0,0,1,0,0,40",
            "-1e308,0,0,1e308,0,0,0,1,0,40",
        ] {
            assert!(
                matches!(Camera::parse(bad), Err(Error::Setting { .. })),
                "{bad}"
            );
        }
    }

    #[test]
    fn text_form_round_trips_exactly() {
        let c = Camera::new(
            DVec3::new(278.0, 273.0, -800.0),
            DVec3::new(0.1, 1.0 / 3.0, -0.0),
            DVec3::new(1e-300, 1.0, 2e10),
            cornell_vfov_degrees(),
        )
        .unwrap();
        assert_eq!(Camera::from_text(&c.to_text()).unwrap(), c);
        assert_eq!(
            from_comment(&format!(" camera: {}", c.to_text())),
            Some(Ok(c))
        );
        assert_eq!(from_comment(" a camera: is mentioned"), None);
        assert_eq!(from_comment("cameras: 1 2 3"), None);
        let err = from_comment("camera: 1 2 3").unwrap().unwrap_err();
        assert!(err.contains("expected 10 numbers"), "{err}");
    }

    #[test]
    fn framings_look_level_from_four_sides_and_down_from_above() {
        let (lo, hi) = (DVec3::ZERO, DVec3::new(4.0, 2.0, 1.0));
        for up in [Up::X, Up::Y, Up::Z] {
            let cams = Camera::framings(lo, hi, up);
            let down = (cams[4].target - cams[4].eye).normalize();
            assert!(down.abs_diff_eq(-up.axis(), 1e-12), "the fifth looks down");
            for (k, c) in cams.iter().enumerate() {
                Camera::new(c.eye, c.target, c.up, c.vfov_degrees).unwrap();
                let dir = (c.target - c.eye).normalize();
                assert!(
                    k == 4 || dir.dot(up.axis()).abs() < 1e-12,
                    "level: {up:?} {k}"
                );
                assert_eq!(c.target, DVec3::new(2.0, 1.0, 0.5));
                // Outside the box, on the side it looks from.
                let outside = (0..3).any(|a| c.eye[a] < lo[a] || c.eye[a] > hi[a]);
                assert!(outside, "{up:?} {k}: {}", c.eye);
            }
            assert!((cams[0].target - cams[0].eye)
                .normalize()
                .abs_diff_eq(up.forward(), 1e-12));
            assert!(
                (cams[2].eye - cams[0].eye).dot(up.forward()) > 0.0,
                "opposite sides"
            );
        }
    }

    #[test]
    fn framing_is_close_to_the_published_cornell_camera() {
        let c = Camera::framing(DVec3::ZERO, DVec3::new(556.0, 548.8, 559.2));
        let published = DVec3::new(278.0, 273.0, -800.0);
        assert!(c.eye.distance(published) < 30.0, "{}", c.eye);
        assert!((cornell_vfov_degrees() - 39.30765).abs() < 1e-5);
    }
}
