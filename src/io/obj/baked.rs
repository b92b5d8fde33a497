//! Wavefront OBJ output with per-vertex colours (`v x y z r g b`, the extension MeshLab
//! reads) and a reader for exactly our own files. OBJ has no place for radiance values, so
//! only the 8-bit sRGB colours survive (face radiance is dropped); use PLY to keep radiance.
//! The scene's camera, if any, is kept as a `# camera: …` comment (see
//! [`crate::scene::camera`]), so loading the baked OBJ as a scene keeps it. This file owns the
//! text layout only; atomic file replacement is in [`crate::io::atomic`], the colour pipeline
//! in [`crate::color`].

use std::io::{self, Write};
use std::path::Path;

use crate::bake::BakedMesh;
use crate::color::radiance_to_srgb8;
use crate::io::{parse_error, ReadBack};
use crate::scene::camera::{self, CameraLine};
use crate::Result;

/// The OBJ colour component written for 8-bit code `k`.
///
/// MeshLab converts OBJ colours to 8 bits by truncating `c · 255`, so a component written as
/// `k / 255` can read back as `k − 1`. Writing the middle of the bin, `(k + 0.5) / 255`, with
/// six decimals (error ≤ 5e-7, i.e. ≤ 1.3e-4 of a code) reads back as exactly `k`. Code 255 is
/// written as `1` (exactly 255 after scaling) so no component exceeds 1: some readers take a
/// value above 1 as a sign of 0–255 colours.
pub fn colour_component(k: u8) -> f64 {
    if k == u8::MAX {
        1.0
    } else {
        (k as f64 + 0.5) / 255.0
    }
}

/// The 8-bit code MeshLab gets from an OBJ colour component: `⌊c · 255⌋`, clamped to 0..=255.
pub fn component_to_u8(c: f64) -> u8 {
    (c * 255.0).floor().clamp(0.0, 255.0) as u8
}

/// The header comment of a file whose positions are written in double precision.
const DOUBLE_COMMENT: &str = "positions in scene units, double precision";

/// Writes `mesh` as OBJ to `w` with colours sRGB(radiance · `exposure`): a comment header
/// (units, exposure, the scene's camera as `# camera: …` when it has one, counts), `v x y z r g b`
/// per vertex (positions as `f32`, or `f64` where single precision would round them
/// ([`crate::io::needs_double`]), in Rust's shortest round-trip plain decimal form), then
/// `f a b c` per face with 1-based indices. Expects a validated mesh.
pub fn write_to<W: Write>(w: &mut W, mesh: &BakedMesh, exposure: f64) -> io::Result<()> {
    let double = crate::io::needs_double(&mesh.positions);
    let mut comments = vec![
        "radiosity: baked radiance as vertex colours".to_string(),
        if double {
            DOUBLE_COMMENT
        } else {
            "positions in scene units"
        }
        .into(),
        "colours = sRGB(radiance * exposure), radiance linear in W sr^-1 m^-2".into(),
        format!("exposure {exposure}"),
    ];
    if let Some(camera) = &mesh.camera {
        comments.push(format!("{} {}", camera::FILE_KEYWORD, camera.to_text()));
    }
    comments.push(
        "colour byte k is written as (k + 0.5)/255 (1 for 255) so that floor(c * 255) = k".into(),
    );
    comments.push(format!(
        "{} vertices, {} faces",
        mesh.positions.len(),
        mesh.faces.len()
    ));
    let vertex = |w: &mut W, i: usize| {
        crate::io::write_position(w, mesh.positions[i], double)?;
        let [red, green, blue] =
            radiance_to_srgb8(mesh.vertex_radiance[i], exposure).map(colour_component);
        write!(w, " {red:.6} {green:.6} {blue:.6}")
    };
    super::write_obj(
        w,
        &comments,
        None,
        mesh.positions.len(),
        vertex,
        &mesh.faces,
        None,
    )
}

/// Reads an OBJ file written by [`write_to`]: `#` comments, blank lines, `v x y z r g b` and
/// `f a b c` (positive 1-based indices) only. Colours come back as MeshLab sees them
/// ([`component_to_u8`]); radiance is `None`; a `# camera: …` comment gives
/// [`ReadBack::camera`]. Problems are [`crate::Error::Parse`] with the line.
pub fn read(path: &Path) -> Result<ReadBack> {
    let text = super::read_text(path)?;
    let parse_err = |line: usize, message: String| parse_error(path, line, message);

    let mut out = ReadBack {
        positions: Vec::new(),
        colours: Vec::new(),
        vertex_radiance: None,
        faces: Vec::new(),
        face_radiance: None,
        camera: None,
        sky: None,
    };
    let mut camera = CameraLine::default();
    let mut double = false;
    // Faces with the line they came from, checked against the vertex count at the end.
    let mut face_lines = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        let t: Vec<&str> = line.split_whitespace().collect();
        match t.first() {
            None => {}
            Some(s) if s.starts_with('#') => {
                double |= line.trim_start()[1..].trim() == DOUBLE_COMMENT;
                camera
                    .read(&line.trim_start()[1..], n)
                    .map_err(|why| parse_err(n, why))?;
            }
            Some(&"v") => {
                if t.len() != 7 {
                    return Err(parse_err(
                        n,
                        format!("expected `v x y z r g b`, found {} values", t.len() - 1),
                    ));
                }
                let num = |k: usize| -> Result<f64> {
                    t[k].parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| parse_err(n, format!("`{}` is not a finite number", t[k])))
                };
                // Positions were written as f32 in shortest form (parsed straight to f32, the
                // same number) or, as the header says, as f64.
                let pos = |k: usize| -> Result<f64> {
                    let x = num(k)?;
                    Ok(if double {
                        x
                    } else {
                        f64::from(t[k].parse::<f32>().expect("already parsed as f64"))
                    })
                };
                out.positions.push([pos(1)?, pos(2)?, pos(3)?]);
                out.colours.push([
                    component_to_u8(num(4)?),
                    component_to_u8(num(5)?),
                    component_to_u8(num(6)?),
                ]);
            }
            Some(&"f") => {
                if t.len() != 4 {
                    return Err(parse_err(
                        n,
                        format!(
                            "expected a triangle `f a b c`, found {} indices",
                            t.len() - 1
                        ),
                    ));
                }
                let idx = |k: usize| -> Result<u32> {
                    t[k].parse::<u32>()
                        .ok()
                        .filter(|&v| v >= 1)
                        .map(|v| v - 1)
                        .ok_or_else(|| {
                            parse_err(n, format!("`{}` is not a positive vertex index", t[k]))
                        })
                };
                out.faces.push([idx(1)?, idx(2)?, idx(3)?]);
                face_lines.push(n);
            }
            Some(other) => {
                return Err(parse_err(n, format!("unsupported statement `{other}`")));
            }
        }
    }
    let vertices = out.positions.len();
    for (f, &n) in out.faces.iter().zip(&face_lines) {
        if let Some(&v) = f.iter().find(|&&v| v as usize >= vertices) {
            return Err(parse_err(
                n,
                format!(
                    "vertex index {} but the file has {vertices} vertices",
                    v + 1
                ),
            ));
        }
    }
    out.camera = camera.camera();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{write, Format};
    use crate::test_support::{sample_mesh, srgb_colours, TestDir};
    use crate::Error;

    #[test]
    fn every_byte_survives_meshlab_truncation() {
        for k in 0..=255u8 {
            let c = colour_component(k);
            assert!((0.0..=1.0).contains(&c));
            // As written (six decimals), parsed back as f32 (what MeshLab uses) and as f64.
            let text = format!("{c:.6}");
            assert_eq!(component_to_u8(text.parse::<f64>().unwrap()), k);
            let c32: f32 = text.parse().unwrap();
            assert_eq!((c32 * 255.0).floor() as u8, k, "f32 path for {k}");
        }
    }

    #[test]
    fn round_trip() {
        let dir = TestDir::new("obj");
        let path = dir.path().join("mesh.obj");
        let mesh = sample_mesh(211, 149);
        let exposure = mesh.auto_exposure() * 0.8;
        write(&path, &mesh, Format::Obj, exposure).unwrap();
        let back = read(&path).unwrap();
        let positions: Vec<[f64; 3]> = mesh
            .positions
            .iter()
            .map(|p| p.map(|c| f64::from(c as f32)))
            .collect();
        assert_eq!(back.positions, positions);
        // Moved to map coordinates (5.6e6 units out), the positions are written and read
        // back in double precision, exactly.
        let mut far = mesh.clone();
        for (i, p) in far.positions.iter_mut().enumerate() {
            let i = i as f64;
            *p = [5.0e5 + 0.1 + 0.01 * i, 5.6e6 + 0.3 + 0.013 * i, 0.017 * i];
        }
        assert!(crate::io::needs_double(&far.positions));
        write(&path, &far, Format::Obj, exposure).unwrap();
        assert_eq!(read(&path).unwrap().positions, far.positions);
        let colours = srgb_colours(&mesh, exposure);
        assert_eq!(back.colours, colours);
        assert_eq!(back.faces, mesh.faces);
        assert_eq!(back.vertex_radiance, None);
        assert_eq!(back.face_radiance, None);
    }

    #[test]
    fn layout_is_plain_obj() {
        let mesh = BakedMesh {
            positions: vec![[0.0, 1.5, -2.0], [1e-7, 3.0e9, 0.1], [1.0, 0.0, 0.0]],
            vertex_radiance: vec![[0.0, 0.5, 1.0], [0.0; 3], [0.0; 3]],
            faces: vec![[0, 1, 2]],
            face_radiance: vec![[1.0; 3]],
            camera: None,
            sky: None,
        };
        let mut bytes = Vec::new();
        write_to(&mut bytes, &mesh, 1.0).unwrap();
        let text = String::from_utf8(bytes).unwrap();
        let body: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
        assert_eq!(
            body,
            [
                "v 0 1.5 -2 0.001961 0.739216 1.000000",
                "v 0.0000001 3000000000 0.1 0.001961 0.001961 0.001961",
                "v 1 0 0 0.001961 0.001961 0.001961",
                "f 1 2 3",
            ]
        );
        assert!(text.contains("# exposure 1\n"));
    }

    #[test]
    fn reader_errors_name_the_line() {
        let dir = TestDir::new("obj-bad");
        let path = dir.path().join("bad.obj");
        let cases = [
            ("v 0 0 0 1 1 1\nv 1 0 0 1 1 1\nf 1 2 3\n", 3, "2 vertices"),
            ("# c\nv 0 0 0\n", 2, "found 3 values"),
            ("v 0 0 0 1 1 x\n", 1, "`x`"),
            ("v 0 0 0 1 1 1\nf 1 1 0\n", 2, "`0`"),
            ("v 0 0 0 1 1 1\nvn 0 0 1\n", 2, "`vn`"),
            ("v 0 0 0 1 1 1\nf 1 1 1 1\n", 2, "found 4 indices"),
        ];
        for (text, line, needle) in cases {
            std::fs::write(&path, text).unwrap();
            match read(&path).unwrap_err() {
                Error::Parse {
                    line: l, message, ..
                } => {
                    assert_eq!(l, line, "{text:?}: {message}");
                    assert!(message.contains(needle), "{text:?}: {message}");
                }
                other => panic!("{other:?}"),
            }
        }
    }
}
