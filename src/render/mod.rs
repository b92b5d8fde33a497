//! Pictures of a baked mesh: one primary ray per sub-pixel through the BVH, shaded with the
//! baked vertex radiance interpolated across the hit face (or the face's own patch radiance
//! with `flat`), then the same exposure and sRGB mapping as the vertex colours. This module
//! owns the image and the choice of camera ([`camera_for`]; the [`Camera`] itself is scene data,
//! [`crate::scene::camera`]); it does no lighting of its own (a
//! radiosity solution is view-independent: the picture is a look-up). A surface made of a
//! face and its reversed twin over the same corners (a two-sided bake) shows each side's own
//! radiance: the BVH reports the face whose front faces the ray ([`Visibility::closest_hit`]).
//! A ray that leaves the scene shows the sky the bake had ([`BakedMesh::sky`], carried by its
//! PLY), through the same exposure and sRGB mapping; without a sky it is black.
//!
//! The automatic camera ([`best_framing`]) is level about the scene's up axis: from outside
//! the bounding box, or at eye height from inside it when that sees much more (a room), and
//! from above only when no level view sees anything.

use std::path::Path;

use glam::DVec3;
use image::{Rgb, RgbImage};
use rayon::prelude::*;

use crate::bake::BakedMesh;
use crate::color::{luminance, radiance_to_srgb8};
pub use crate::scene::camera::{Camera, Up};
use crate::visibility::{Visibility, NONE};
use crate::{Error, Result};

/// What a picture shows and how.
#[derive(Debug, Clone, Copy)]
pub struct View {
    pub camera: Camera,
    /// Picture size, pixels.
    pub width: u32,
    pub height: u32,
    /// Samples per pixel along each axis (spp² stratified rays per pixel).
    pub spp: u32,
    /// Each face's own patch radiance instead of the interpolated vertex radiance.
    pub flat: bool,
    /// Luminance on a colour scale (with a legend) instead of sRGB colours.
    pub false_colour: bool,
    /// Radiance multiplier before the sRGB curve (for false colour: the luminance at the top
    /// of the scale is 1/exposure).
    pub exposure: f64,
}

/// Largest picture side, pixels.
pub const MAX_SIZE: u32 = 16384;

/// Most samples per pixel along each axis.
pub const MAX_SPP: u32 = 16;

impl View {
    /// Checks the ranges: width and height in 1..=[`MAX_SIZE`], `spp` in 1..=[`MAX_SPP`],
    /// exposure finite and > 0. Errors are [`Error::Setting`] named `view.size`, `view.spp`,
    /// `exposure`.
    pub fn validate(&self) -> Result<()> {
        let side = 1..=MAX_SIZE;
        if !(side.contains(&self.width) && side.contains(&self.height)) {
            return Err(Error::setting(
                "view.size",
                format!(
                    "{}x{} is not within 1..={MAX_SIZE} pixels each way",
                    self.width, self.height
                ),
            ));
        }
        if !(1..=MAX_SPP).contains(&self.spp) {
            return Err(Error::setting(
                "view.spp",
                format!("{} is not in 1..={MAX_SPP}", self.spp),
            ));
        }
        crate::color::check_exposure(self.exposure)
    }
}

/// The camera a picture of `mesh` is taken with: `given` if there is one, else the camera the
/// scene file carried ([`BakedMesh::camera`]), else the automatic view of the mesh's bounding
/// box, level about `up` ([`best_framing`]).
pub fn camera_for(mesh: &BakedMesh, given: Option<Camera>, up: Up) -> Camera {
    given
        .or(mesh.camera)
        .unwrap_or_else(|| best_framing(&triangles(mesh), up))
}

/// The mesh's faces as corner triples, scene units.
fn triangles(mesh: &BakedMesh) -> Vec<[DVec3; 3]> {
    mesh.faces
        .iter()
        .map(|f| f.map(|v| DVec3::from_array(mesh.positions[v as usize])))
        .collect()
}

/// Rays per side of the grid [`coverage`] casts.
pub const COVERAGE_GRID: u32 = 24;

/// The automatic camera for `triangles` with the scene's `up` axis: a level view about `up`
/// whenever one sees anything, chosen by [`coverage`] (the share of the picture that shows the
/// front of a face):
///
/// 1. the best of the four views from outside the bounding box's sides ([`Camera::framings`],
///    the first on a tie), unless
/// 2. the best of the four eye-height views from just inside them
///    ([`Camera::eye_height_views`]) sees more than twice as much: a room whose walls face
///    inward shows only their backs from outside, or a little through a doorway, and is then
///    seen from within;
/// 3. the view from above only when no level view sees any front face (a flat ground plane,
///    seen edge-on from every side).
///
/// So a box open on one side (McGuire's Cornell box opens toward +z) is looked into through
/// its opening, a z-up level is seen level with `Up::Z`, and a roofless room is not seen from
/// above however much floor it has.
pub fn best_framing(triangles: &[[DVec3; 3]], up: Up) -> Camera {
    let (lo, hi) = crate::geometry::bounds(triangles.iter().flatten().copied());
    let framings = Camera::framings(lo, hi, up);
    if triangles.is_empty() {
        return framings[0];
    }
    let vis = Visibility::build(triangles);
    // The first camera of `cameras` with the most coverage, and that coverage.
    let best = |cameras: &[Camera]| {
        let mut best = (cameras[0], -1.0);
        for c in cameras {
            let seen = coverage(triangles, &vis, c, COVERAGE_GRID);
            if seen > best.1 {
                best = (*c, seen);
            }
        }
        best
    };
    let outside = best(&framings[..4]);
    // A box with no height (a flat ground plane) has no eye height: its eye would lie on it.
    let inside = if (hi - lo).dot(up.axis()) > 0.0 {
        best(&Camera::eye_height_views(lo, hi, up))
    } else {
        (framings[4], 0.0)
    };
    if inside.1 > 2.0 * outside.1 {
        inside.0
    } else if outside.1 > 0.0 {
        outside.0
    } else {
        framings[4]
    }
}

/// The share of a `grid` × `grid` set of primary rays of `camera` (square picture) that meet
/// the front of a face of `triangles` (`vis` built over them): 0 when the picture would show
/// only black (misses and backs).
pub fn coverage(triangles: &[[DVec3; 3]], vis: &Visibility, camera: &Camera, grid: u32) -> f64 {
    let forward = (camera.target - camera.eye).normalize();
    let right = forward.cross(camera.up).normalize();
    let up = right.cross(forward);
    let tan_half = (0.5 * camera.vfov_degrees.to_radians()).tan();
    let mut seen = 0u32;
    for y in 0..grid {
        for x in 0..grid {
            let fx = (x as f64 + 0.5) / grid as f64;
            let fy = (y as f64 + 0.5) / grid as f64;
            let dir = forward
                + right * ((2.0 * fx - 1.0) * tan_half)
                + up * ((1.0 - 2.0 * fy) * tan_half);
            if let Some(hit) = vis.closest_hit(camera.eye, dir, f64::INFINITY, NONE) {
                let [a, b, c] = triangles[hit.triangle as usize];
                if (b - a).cross(c - a).dot(dir) < 0.0 {
                    seen += 1;
                }
            }
        }
    }
    seen as f64 / (grid * grid) as f64
}

/// True if a picture of `mesh` with `camera` would show only black: no ray of a
/// [`COVERAGE_GRID`]² grid meets the front of a face (a closed room seen from outside, or a
/// framing that looks at the backs of walls).
pub fn sees_nothing(mesh: &BakedMesh, camera: &Camera) -> bool {
    let tris = triangles(mesh);
    let vis = Visibility::build(&tris);
    coverage(&tris, &vis, camera, COVERAGE_GRID) == 0.0
}

/// Render `mesh` as `view` says (a [`View::validate`]d view). Back faces are black; a ray that
/// misses every face shows the bake's sky in its direction ([`BakedMesh::sky`]), black without
/// one or below the horizon.
pub fn render(mesh: &BakedMesh, view: &View) -> RgbImage {
    let tris = triangles(mesh);
    let vis = Visibility::build(&tris);
    let camera = &view.camera;
    let (width, height) = (view.width, view.height);
    let forward = (camera.target - camera.eye).normalize();
    let right = forward.cross(camera.up).normalize();
    let up = right.cross(forward);
    let tan_half = (0.5 * camera.vfov_degrees.to_radians()).tan();
    let aspect = width as f64 / height as f64;
    let spp = view.spp.max(1);
    let mut pixels = vec![[0u8; 3]; (width * height) as usize];
    let progress = crate::progress::stage("render", Some(height as u64));
    pixels
        .par_chunks_mut(width as usize)
        .enumerate()
        .for_each(|(y, row)| {
            progress.advance(1);
            for (x, px) in row.iter_mut().enumerate() {
                let mut sum = [0.0; 3];
                for sy in 0..spp {
                    for sx in 0..spp {
                        let fx = (x as f64 + (sx as f64 + 0.5) / spp as f64) / width as f64;
                        let fy = (y as f64 + (sy as f64 + 0.5) / spp as f64) / height as f64;
                        let dir = forward
                            + right * ((2.0 * fx - 1.0) * tan_half * aspect)
                            + up * ((1.0 - 2.0 * fy) * tan_half);
                        let l = shade(mesh, &tris, &vis, camera.eye, dir, view.flat);
                        for (s, l) in sum.iter_mut().zip(l) {
                            *s += l;
                        }
                    }
                }
                let n = (spp * spp) as f64;
                let mean = sum.map(|s| s / n);
                *px = if view.false_colour {
                    false_colour(luminance(mean) * view.exposure)
                } else {
                    radiance_to_srgb8(mean, view.exposure)
                };
            }
        });
    let mut image = RgbImage::from_fn(width, height, |x, y| Rgb(pixels[(y * width + x) as usize]));
    if view.false_colour {
        draw_legend(&mut image, 1.0 / view.exposure);
    }
    image
}

/// A perceptually ordered scale (control points of matplotlib's viridis) for t in [0, 1];
/// values above 1 are white, so saturation is visible.
pub fn false_colour(t: f64) -> [u8; 3] {
    const STOPS: [[f64; 3]; 5] = [
        [68.0, 1.0, 84.0],
        [59.0, 82.0, 139.0],
        [33.0, 145.0, 140.0],
        [94.0, 201.0, 98.0],
        [253.0, 231.0, 37.0],
    ];
    if t.is_nan() || t <= 0.0 {
        return [0, 0, 0];
    }
    if t > 1.0 {
        return [255, 255, 255];
    }
    let x = t * (STOPS.len() - 1) as f64;
    let k = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - k as f64;
    std::array::from_fn(|c| (STOPS[k][c] * (1.0 - f) + STOPS[k + 1][c] * f).round() as u8)
}

/// A colour bar along the bottom with its end values (luminance, W·sr⁻¹·m⁻²) written in a
/// built-in 3×5 pixel font, so no font file is needed.
fn draw_legend(image: &mut RgbImage, top: f64) {
    let (w, h) = image.dimensions();
    if w < 64 || h < 64 {
        return;
    }
    let bar = (h / 20).max(8);
    let y0 = h - bar - 14;
    for y in y0 - 2..h {
        for x in 0..w {
            image.put_pixel(x, y, Rgb([0, 0, 0]));
        }
    }
    for x in 4..w - 4 {
        let t = (x - 4) as f64 / (w - 9) as f64;
        let c = false_colour(t.max(1e-9));
        for y in y0..y0 + bar {
            image.put_pixel(x, y, Rgb(c));
        }
    }
    let scale = 2;
    draw_text(image, 4, y0 + bar + 2, "0", scale);
    let label = format!("{top:.3e}");
    let width = label.len() as u32 * 4 * scale;
    draw_text(
        image,
        w.saturating_sub(width + 4),
        y0 + bar + 2,
        &label,
        scale,
    );
}

/// Draw `text` (digits, '.', '-', '+', 'e') with a 3×5 bitmap font, white, top-left at (x, y).
fn draw_text(image: &mut RgbImage, x: u32, y: u32, text: &str, scale: u32) {
    for (i, ch) in text.chars().enumerate() {
        let glyph: [u8; 5] = match ch {
            '0' => [7, 5, 5, 5, 7],
            '1' => [2, 6, 2, 2, 7],
            '2' => [7, 1, 7, 4, 7],
            '3' => [7, 1, 7, 1, 7],
            '4' => [5, 5, 7, 1, 1],
            '5' => [7, 4, 7, 1, 7],
            '6' => [7, 4, 7, 5, 7],
            '7' => [7, 1, 1, 1, 1],
            '8' => [7, 5, 7, 5, 7],
            '9' => [7, 5, 7, 1, 7],
            '.' => [0, 0, 0, 0, 2],
            '-' => [0, 0, 7, 0, 0],
            '+' => [0, 2, 7, 2, 0],
            'e' => [0, 7, 7, 4, 7],
            _ => [0; 5],
        };
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) != 0 {
                    for dy in 0..scale {
                        for dx in 0..scale {
                            let px = x + (i as u32 * 4 + col) * scale + dx;
                            let py = y + row as u32 * scale + dy;
                            if px < image.width() && py < image.height() {
                                image.put_pixel(px, py, Rgb([255, 255, 255]));
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Radiance seen along one primary ray.
fn shade(
    mesh: &BakedMesh,
    tris: &[[DVec3; 3]],
    vis: &Visibility,
    eye: DVec3,
    dir: DVec3,
    flat: bool,
) -> [f64; 3] {
    let Some(hit) = vis.closest_hit(eye, dir, f64::INFINITY, NONE) else {
        // Leaves the scene: the bake's sky there (black below the horizon), else black.
        return mesh
            .sky
            .map_or([0.0; 3], |sky| sky.radiance_toward(dir.normalize()));
    };
    let f = hit.triangle as usize;
    let [a, b, c] = tris[f];
    if (b - a).cross(c - a).dot(dir) >= 0.0 {
        return [0.0; 3]; // the back of a one-sided surface
    }
    if flat {
        return mesh.face_radiance[f];
    }
    let w = [1.0 - hit.u - hit.v, hit.u, hit.v];
    let face = mesh.faces[f];
    let mut l = [0.0; 3];
    for (k, &v) in face.iter().enumerate() {
        for (lc, vc) in l.iter_mut().zip(mesh.vertex_radiance[v as usize]) {
            *lc += w[k] * vc;
        }
    }
    l
}

/// Save a picture as PNG, atomically (temporary file + rename).
pub fn save(path: &Path, image: &RgbImage) -> Result<()> {
    let mut bytes = Vec::new();
    image
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .map_err(|e| Error::Internal(format!("PNG encoding: {e}")))?;
    crate::io::write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn render_a_lit_quad_in_front_of_the_camera() {
        // One quad at z = 1 facing the camera (−z) with radiance 0.5: the centre pixel is
        // sRGB(0.5) = 188 at exposure 1, the corners (outside the quad) black.
        let mesh = BakedMesh {
            positions: vec![
                [-1.0, -1.0, 1.0],
                [1.0, -1.0, 1.0],
                [1.0, 1.0, 1.0],
                [-1.0, 1.0, 1.0],
            ],
            vertex_radiance: vec![[0.5; 3]; 4],
            faces: vec![[0, 2, 1], [0, 3, 2]],
            face_radiance: vec![[0.5; 3]; 2],
            camera: None,
            sky: None,
        };
        let view = View {
            camera: Camera {
                eye: DVec3::new(0.0, 0.0, -1.0),
                target: DVec3::ZERO,
                up: DVec3::Y,
                vfov_degrees: 60.0,
            },
            width: 32,
            height: 32,
            spp: 1,
            flat: false,
            false_colour: false,
            exposure: 1.0,
        };
        let img = render(&mesh, &view);
        assert_eq!(img.get_pixel(16, 16).0, [188; 3]);
        // Seen from behind (the quad's back) everything is black.
        let back = View {
            camera: Camera {
                eye: DVec3::new(0.0, 0.0, 3.0),
                target: DVec3::ZERO,
                ..view.camera
            },
            ..view
        };
        assert_eq!(render(&mesh, &back).get_pixel(16, 16).0, [0; 3]);
        // False colour: luminance 0.5 at exposure 1 is the middle of the scale.
        let fc = render(
            &mesh,
            &View {
                false_colour: true,
                width: 128,
                height: 128,
                ..view
            },
        );
        assert_eq!(fc.get_pixel(64, 40).0, false_colour(0.5));
    }

    /// An axis-aligned rectangle on the plane `axis` = `at`, spanning [lo, hi] on the other
    /// two axes, as two triangles whose front faces the side `facing` (±1) of the plane.
    fn rect(axis: usize, at: f64, lo: [f64; 2], hi: [f64; 2], facing: f64) -> Vec<[DVec3; 3]> {
        let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
        let corner = |u: f64, v: f64| {
            let mut p = DVec3::ZERO;
            p[axis] = at;
            p[a] = u;
            p[b] = v;
            p
        };
        let q = [
            corner(lo[0], lo[1]),
            corner(hi[0], lo[1]),
            corner(hi[0], hi[1]),
            corner(lo[0], hi[1]),
        ];
        let mut n = DVec3::ZERO;
        n[axis] = facing;
        [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
            .map(|[p, q, r]| {
                if (q - p).cross(r - p).dot(n) > 0.0 {
                    [p, q, r]
                } else {
                    [p, r, q]
                }
            })
            .to_vec()
    }

    /// A closed box [lo, hi], faces outward.
    fn solid(lo: DVec3, hi: DVec3) -> Vec<[DVec3; 3]> {
        let mut t = Vec::new();
        for axis in 0..3 {
            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
            let span = ([lo[a], lo[b]], [hi[a], hi[b]]);
            t.extend(rect(axis, lo[axis], span.0, span.1, -1.0));
            t.extend(rect(axis, hi[axis], span.0, span.1, 1.0));
        }
        t
    }

    /// A z-up room 6 × 4 m, walls 2.5 m high facing in, a floor, no ceiling, three boxes.
    fn roofless_room_z_up() -> Vec<[DVec3; 3]> {
        let mut t = rect(2, 0.0, [0.0, 0.0], [6.0, 4.0], 1.0);
        t.extend(rect(0, 0.0, [0.0, 0.0], [4.0, 2.5], 1.0));
        t.extend(rect(0, 6.0, [0.0, 0.0], [4.0, 2.5], -1.0));
        t.extend(rect(1, 0.0, [0.0, 0.0], [2.5, 6.0], 1.0));
        t.extend(rect(1, 4.0, [0.0, 0.0], [2.5, 6.0], -1.0));
        t.extend(solid(DVec3::new(1.0, 1.0, 0.0), DVec3::new(2.0, 1.8, 0.9)));
        t.extend(solid(DVec3::new(3.5, 2.5, 0.0), DVec3::new(4.5, 3.2, 0.5)));
        t.extend(solid(DVec3::new(4.8, 0.5, 0.0), DVec3::new(5.5, 1.2, 1.1)));
        t
    }

    #[test]
    fn a_roofless_room_is_framed_level_about_its_up_axis() {
        let z_up = roofless_room_z_up();
        let cam = best_framing(&z_up, Up::Z);
        let dir = (cam.target - cam.eye).normalize();
        assert!(dir.dot(DVec3::Z).abs() < 1e-9, "level: {dir}");
        assert_eq!(cam.up, DVec3::Z);
        // From inside the room (its walls face in: from outside only their backs show), at
        // half the wall's height.
        assert!(cam.eye.x > 0.0 && cam.eye.x < 6.0 && cam.eye.y > 0.0 && cam.eye.y < 4.0);
        assert!((cam.eye.z - 1.25).abs() < 1e-9, "{}", cam.eye);
        let vis = Visibility::build(&z_up);
        let seen = coverage(&z_up, &vis, &cam, COVERAGE_GRID);
        // The floor, the far walls and the boxes; the sky above the walls is the rest.
        assert!(seen > 0.6, "{seen}");

        // The same room turned y-up (z → y, y → −z: a rotation, faces keep their fronts).
        let turn = |p: DVec3| DVec3::new(p.x, p.z, -p.y);
        let y_up: Vec<[DVec3; 3]> = z_up.iter().map(|t| t.map(turn)).collect();
        let cam_y = best_framing(&y_up, Up::Y);
        let dir_y = (cam_y.target - cam_y.eye).normalize();
        assert!(dir_y.dot(DVec3::Y).abs() < 1e-9, "level: {dir_y}");
        assert_eq!(cam_y.up, DVec3::Y);
        assert!((cam_y.eye.y - 1.25).abs() < 1e-9, "{}", cam_y.eye);
        // It is one of the turned room's eye-height views, and sees what the z-up one sees
        // from the corresponding place.
        let (lo, hi) = (DVec3::new(0.0, 0.0, -4.0), DVec3::new(6.0, 2.5, 0.0));
        assert!(Camera::eye_height_views(lo, hi, Up::Y).contains(&cam_y));
        let vis_y = Visibility::build(&y_up);
        let turned = Camera {
            eye: turn(cam.eye),
            target: turn(cam.target),
            up: turn(cam.up),
            ..cam
        };
        let seen_y = coverage(&y_up, &vis_y, &cam_y, COVERAGE_GRID);
        assert!(seen_y >= coverage(&y_up, &vis_y, &turned, COVERAGE_GRID) - 0.01);
        assert!((seen_y - seen).abs() < 0.05, "{seen_y} vs {seen}");
    }

    #[test]
    fn a_flat_ground_plane_is_seen_from_above_and_an_open_box_from_its_open_side() {
        // Edge-on from every side, a floor shows nothing level: the view from above.
        let floor = rect(2, 0.0, [0.0, 0.0], [4.0, 4.0], 1.0);
        let cam = best_framing(&floor, Up::Z);
        assert!((cam.target - cam.eye)
            .normalize()
            .abs_diff_eq(-DVec3::Z, 1e-12));
        // A box open toward +z (y up) is looked into from outside its opening.
        let mut open = rect(2, 0.0, [0.0, 0.0], [1.0, 1.0], 1.0);
        open.extend(rect(0, 0.0, [0.0, 0.0], [1.0, 1.0], 1.0));
        open.extend(rect(0, 1.0, [0.0, 0.0], [1.0, 1.0], -1.0));
        open.extend(rect(1, 0.0, [0.0, 0.0], [1.0, 1.0], 1.0));
        open.extend(rect(1, 1.0, [0.0, 0.0], [1.0, 1.0], -1.0));
        let cam = best_framing(&open, Up::Y);
        assert!(cam.eye.z > 1.0, "{}", cam.eye);
        assert_eq!(
            cam.vfov_degrees,
            crate::scene::camera::cornell_vfov_degrees()
        );
    }

    #[test]
    fn rays_that_leave_the_scene_show_the_sky() {
        use crate::scene::{Sky, SkyModel};
        // A floor quad (y up) under a uniform sky, seen level from above its edge: the upper
        // half of the picture is sky, the lower half floor.
        let sky = Sky {
            radiance: [0.8, 0.9, 1.2],
            model: SkyModel::Uniform,
            up: Up::Y,
        };
        let mesh = BakedMesh {
            positions: vec![
                [-50.0, 0.0, -50.0],
                [50.0, 0.0, -50.0],
                [50.0, 0.0, 50.0],
                [-50.0, 0.0, 50.0],
            ],
            vertex_radiance: vec![[0.3; 3]; 4],
            faces: vec![[0, 2, 1], [0, 3, 2]],
            face_radiance: vec![[0.3; 3]; 2],
            camera: None,
            sky: Some(sky),
        };
        let view = View {
            camera: Camera {
                eye: DVec3::new(0.0, 1.0, 0.0),
                target: DVec3::new(0.0, 1.0, 1.0),
                up: DVec3::Y,
                vfov_degrees: 60.0,
            },
            width: 16,
            height: 16,
            spp: 1,
            flat: false,
            false_colour: false,
            exposure: 0.7,
        };
        let img = render(&mesh, &view);
        let expected = radiance_to_srgb8(sky.radiance, 0.7);
        for y in 0..8 {
            for x in 0..16 {
                assert_eq!(img.get_pixel(x, y).0, expected, "({x}, {y})");
            }
        }
        // Below the horizon, the floor.
        assert_eq!(img.get_pixel(8, 15).0, radiance_to_srgb8([0.3; 3], 0.7));
        // Without a sky, black.
        let dark = render(
            &BakedMesh {
                sky: None,
                ..mesh.clone()
            },
            &view,
        );
        assert_eq!(dark.get_pixel(8, 2).0, [0; 3]);
        // Overcast: brighter toward the zenith.
        let overcast = BakedMesh {
            sky: Some(Sky {
                model: SkyModel::Overcast,
                ..sky
            }),
            ..mesh
        };
        let img = render(&overcast, &view);
        let lum = |p: [u8; 3]| p.iter().map(|&c| c as u32).sum::<u32>();
        assert!(lum(img.get_pixel(8, 0).0) > lum(img.get_pixel(8, 7).0));
    }

    #[test]
    fn false_colour_scale_is_monotone_in_brightness() {
        let lum = |c: [u8; 3]| 0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64;
        let mut last = -1.0;
        for k in 1..=100 {
            let l = lum(false_colour(k as f64 / 100.0));
            assert!(l > last, "{k}");
            last = l;
        }
        assert_eq!(false_colour(2.0), [255; 3]);
        assert_eq!(false_colour(0.0), [0; 3]);
    }
}
