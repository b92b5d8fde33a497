//! PLY 1.0 output (binary little-endian or ASCII) and a reader for exactly our own files.
//! Per vertex: `float x y z` (`double` where single precision would round them,
//! [`crate::io::needs_double`]), `uchar red green blue` (the 8-bit sRGB colours MeshLab shows)
//! and `float radiance_r/g/b` (linear W·sr⁻¹·m⁻², which MeshLab drops but plyfile/trimesh
//! keep); per face: `list uchar int vertex_indices` and `float radiance_r/g/b`. The header
//! records the exposure in a comment, and the scene's camera (`comment camera: EX EY EZ TX TY
//! TZ UX UY UZ FOV`, see [`crate::scene::camera`]) when it has one, and the bake's sky
//! (`comment sky: R G B MODEL UP`, [`crate::scene::Sky`]) when it had one, for pictures. This file
//! owns the byte layout only; atomic file replacement is in [`crate::io::atomic`], the colour
//! pipeline in [`crate::color`], the header's syntax in [`super::header`]. The reader accepts our
//! layout (any comments) and nothing else; any other PLY is a scene ([`super::load`]).

use std::io::{self, Write};
use std::path::Path;

use super::header::{parse_error, Header};
use crate::bake::BakedMesh;
use crate::color::radiance_to_srgb8;
use crate::io::ReadBack;
use crate::scene::{camera, lights};
use crate::{Error, Result};

/// First header comment: what the numbers mean.
const COMMENT_UNITS: &str =
    "comment radiosity: baked radiance, W sr^-1 m^-2, linear; colours = sRGB(radiance * exposure)";

/// Vertex properties, in order, exactly as written when the positions are single precision.
const VERTEX_PROPERTIES: [&str; 9] = [
    "property float x",
    "property float y",
    "property float z",
    "property uchar red",
    "property uchar green",
    "property uchar blue",
    "property float radiance_r",
    "property float radiance_g",
    "property float radiance_b",
];

/// The position properties, when they are written in double precision.
const DOUBLE_POSITIONS: [&str; 3] = [
    "property double x",
    "property double y",
    "property double z",
];

/// The vertex properties as written, positions in double precision if `double`.
fn vertex_properties(double: bool) -> [&'static str; 9] {
    let mut properties = VERTEX_PROPERTIES;
    if double {
        properties[..3].copy_from_slice(&DOUBLE_POSITIONS);
    }
    properties
}

/// Face properties, in order, exactly as written.
const FACE_PROPERTIES: [&str; 4] = [
    "property list uchar int vertex_indices",
    "property float radiance_r",
    "property float radiance_g",
    "property float radiance_b",
];

/// Bytes per binary vertex record: 3 × f32 (or f64, if `double`) position, 3 × u8 colour,
/// 3 × f32 radiance.
const fn vertex_bytes(double: bool) -> usize {
    3 * if double { 8 } else { 4 } + 3 + 12
}
/// Bytes per binary face record: u8 count (3), 3 × i32 index, 3 × f32 radiance.
const FACE_BYTES: usize = 1 + 12 + 12;

/// Writes `mesh` as PLY to `w` with colours sRGB(radiance · `exposure`). Radiance is stored
/// as `f32`, positions too unless [`crate::io::needs_double`] asks for `f64`; ASCII numbers
/// use Rust's shortest round-trip decimal form (plain decimal, no exponent), so they read back
/// to the same values. Expects a validated mesh.
pub fn write_to(
    w: &mut impl Write,
    mesh: &BakedMesh,
    exposure: f64,
    ascii: bool,
) -> io::Result<()> {
    let format = if ascii {
        "ascii"
    } else {
        "binary_little_endian"
    };
    writeln!(w, "ply")?;
    writeln!(w, "format {format} 1.0")?;
    writeln!(w, "{COMMENT_UNITS}")?;
    writeln!(w, "comment exposure {exposure}")?;
    if let Some(camera) = &mesh.camera {
        writeln!(w, "comment {} {}", camera::FILE_KEYWORD, camera.to_text())?;
    }
    if let Some(sky) = &mesh.sky {
        writeln!(w, "comment {} {}", lights::SKY_KEYWORD, sky.to_text())?;
    }
    let double = crate::io::needs_double(&mesh.positions);
    writeln!(w, "element vertex {}", mesh.positions.len())?;
    for p in vertex_properties(double) {
        writeln!(w, "{p}")?;
    }
    writeln!(w, "element face {}", mesh.faces.len())?;
    for p in FACE_PROPERTIES {
        writeln!(w, "{p}")?;
    }
    writeln!(w, "end_header")?;

    let vertices = mesh.positions.iter().zip(&mesh.vertex_radiance);
    let faces = mesh.faces.iter().zip(&mesh.face_radiance);
    if ascii {
        for (p, r) in vertices {
            let [red, green, blue] = radiance_to_srgb8(*r, exposure);
            let [rr, rg, rb] = r.map(|c| c as f32);
            crate::io::write_position(w, *p, double)?;
            writeln!(w, " {red} {green} {blue} {rr} {rg} {rb}")?;
        }
        for (f, r) in faces {
            let [rr, rg, rb] = r.map(|c| c as f32);
            writeln!(w, "3 {} {} {} {rr} {rg} {rb}", f[0], f[1], f[2])?;
        }
    } else {
        let mut buffer = [0u8; vertex_bytes(true)];
        let record = &mut buffer[..vertex_bytes(double)];
        let at = record.len() - 15;
        for (p, r) in vertices {
            if double {
                for (k, c) in p.iter().enumerate() {
                    record[8 * k..8 * k + 8].copy_from_slice(&c.to_le_bytes());
                }
            } else {
                put_f32s(&mut record[0..12], p.map(|c| c as f32));
            }
            record[at..at + 3].copy_from_slice(&radiance_to_srgb8(*r, exposure));
            put_f32s(&mut record[at + 3..], r.map(|c| c as f32));
            w.write_all(record)?;
        }
        let mut record = [0u8; FACE_BYTES];
        record[0] = 3;
        for (f, r) in faces {
            for (k, &v) in f.iter().enumerate() {
                // validate() guarantees v <= i32::MAX.
                record[1 + 4 * k..5 + 4 * k].copy_from_slice(&(v as i32).to_le_bytes());
            }
            put_f32s(&mut record[13..25], r.map(|c| c as f32));
            w.write_all(&record)?;
        }
    }
    Ok(())
}

fn put_f32s(out: &mut [u8], values: [f32; 3]) {
    for (k, v) in values.iter().enumerate() {
        out[4 * k..4 * k + 4].copy_from_slice(&v.to_le_bytes());
    }
}

/// Reads a PLY file written by [`write_to`] (ASCII or binary little-endian, as its header
/// says), with the camera of its `comment camera: …` line and the sky of its `comment sky: …`
/// line if it has them. The header goes
/// through the shared header layer (`Header::parse`) and must then declare exactly our
/// elements and properties. Header and ASCII body problems are [`Error::Parse`] with the
/// line; binary body problems are [`Error::Input`] naming the vertex or face.
pub fn read(path: &Path) -> Result<ReadBack> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let header = Header::parse(path, &bytes)?;
    let layout = Layout::of(path, &header)?;
    let sky = match &header.sky {
        None => None,
        Some((line, text)) => Some(lights::Sky::from_text(text).map_err(|why| {
            parse_error(
                path,
                *line,
                format!(
                    "malformed sky line ({} R G B MODEL UP): {why}",
                    lights::SKY_KEYWORD
                ),
            )
        })?),
    };
    let body = &bytes[header.body_start..];
    let mut back = if header.ascii {
        read_ascii_body(path, &header, &layout, body)
    } else {
        read_binary_body(path, &header, &layout, body)
    }?;
    back.sky = sky;
    Ok(back)
}

/// What a header declaring exactly our layout promises: the record counts, and whether the
/// positions are double precision.
struct Layout {
    vertices: usize,
    faces: usize,
    double: bool,
}

impl Layout {
    /// Checks that `header` declares our two elements with our properties, in order; the
    /// first difference is an error at its header line.
    fn of(path: &Path, header: &Header) -> Result<Layout> {
        let double = header.elements.first().is_some_and(|vertex| {
            let declared = |k: usize| vertex.properties.get(k).map(|p| p.declaration());
            (0..3).all(|k| declared(k).as_deref() == Some(DOUBLE_POSITIONS[k]))
        });
        let vertex = vertex_properties(double);
        let ours: [(&str, &[&str]); 2] = [("vertex", &vertex), ("face", &FACE_PROPERTIES)];
        let mut counts = [0; 2];
        for (k, (name, properties)) in ours.iter().enumerate() {
            let Some(element) = header.elements.get(k) else {
                return Err(parse_error(
                    path,
                    header.lines,
                    format!("header ends before `element {name}`"),
                ));
            };
            if element.name != *name {
                return Err(parse_error(
                    path,
                    element.line,
                    format!(
                        "expected `element {name} <count>`, found `element {}`",
                        element.name
                    ),
                ));
            }
            for (want, found) in properties.iter().zip(&element.properties) {
                if found.declaration() != *want {
                    return Err(parse_error(
                        path,
                        found.line,
                        format!("expected `{want}`, found `{}`", found.declaration()),
                    ));
                }
            }
            if element.properties.len() != properties.len() {
                return Err(parse_error(
                    path,
                    element.line,
                    format!(
                        "element {name} has {} properties; a baked file's has {}",
                        element.properties.len(),
                        properties.len()
                    ),
                ));
            }
            counts[k] = element.count;
        }
        if let Some(extra) = header.elements.get(2) {
            return Err(parse_error(
                path,
                extra.line,
                format!("unexpected `element {}` after the faces", extra.name),
            ));
        }
        Ok(Layout {
            vertices: counts[0],
            faces: counts[1],
            double,
        })
    }
}

fn read_ascii_body(path: &Path, header: &Header, layout: &Layout, body: &[u8]) -> Result<ReadBack> {
    let parse_err = |line: usize, message: String| parse_error(path, line, message);
    let text = std::str::from_utf8(body).map_err(|_| Error::Input {
        path: path.to_path_buf(),
        message: "ASCII PLY body is not UTF-8 text".into(),
    })?;
    // (line number, tokens) of the non-blank body lines.
    let mut rows = text
        .lines()
        .enumerate()
        .map(|(i, l)| (header.lines + 1 + i, l))
        .filter(|(_, l)| !l.trim().is_empty());
    let last_line = header.lines + text.lines().count();

    // Untrusted counts: do not reserve more than the body could hold.
    let cap = |n: usize| n.min(body.len() / 2);
    let mut out = ReadBack {
        positions: Vec::with_capacity(cap(layout.vertices)),
        colours: Vec::with_capacity(cap(layout.vertices)),
        vertex_radiance: None,
        faces: Vec::with_capacity(cap(layout.faces)),
        face_radiance: None,
        camera: header.camera,
        sky: None,
    };
    let mut vertex_radiance = Vec::with_capacity(cap(layout.vertices));
    let mut face_radiance = Vec::with_capacity(cap(layout.faces));

    for i in 0..layout.vertices {
        let (n, line) = rows.next().ok_or_else(|| {
            parse_err(
                last_line,
                format!("file ends after {i} of {} vertices", layout.vertices),
            )
        })?;
        let t: Vec<&str> = line.split_whitespace().collect();
        if t.len() != 9 {
            return Err(parse_err(
                n,
                format!("vertex {i}: expected 9 values, found {}", t.len()),
            ));
        }
        let f = |k: usize| -> Result<f32> {
            t[k].parse::<f32>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    parse_err(n, format!("vertex {i}: `{}` is not a finite number", t[k]))
                })
        };
        let b = |k: usize| -> Result<u8> {
            t[k].parse::<u8>()
                .map_err(|_| parse_err(n, format!("vertex {i}: `{}` is not a colour byte", t[k])))
        };
        // Positions as written: f32 in shortest form (parsed straight to f32), or f64.
        let position = |k: usize| -> Result<f64> {
            if layout.double {
                t[k].parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| {
                        parse_err(n, format!("vertex {i}: `{}` is not a finite number", t[k]))
                    })
            } else {
                f(k).map(f64::from)
            }
        };
        out.positions
            .push([position(0)?, position(1)?, position(2)?]);
        out.colours.push([b(3)?, b(4)?, b(5)?]);
        vertex_radiance.push([f(6)?, f(7)?, f(8)?]);
    }
    for i in 0..layout.faces {
        let (n, line) = rows.next().ok_or_else(|| {
            parse_err(
                last_line,
                format!("file ends after {i} of {} faces", layout.faces),
            )
        })?;
        let t: Vec<&str> = line.split_whitespace().collect();
        if t.len() != 7 || t[0] != "3" {
            return Err(parse_err(n, format!("face {i}: expected `3 a b c r g b`")));
        }
        let idx = |k: usize| -> Result<u32> {
            t[k].parse::<u32>()
                .ok()
                .filter(|&v| (v as usize) < layout.vertices)
                .ok_or_else(|| {
                    parse_err(
                        n,
                        format!(
                            "face {i}: `{}` is not a vertex index below {}",
                            t[k], layout.vertices
                        ),
                    )
                })
        };
        let f = |k: usize| -> Result<f32> {
            t[k].parse::<f32>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| parse_err(n, format!("face {i}: `{}` is not a finite number", t[k])))
        };
        out.faces.push([idx(1)?, idx(2)?, idx(3)?]);
        face_radiance.push([f(4)?, f(5)?, f(6)?]);
    }
    if let Some((n, _)) = rows.next() {
        return Err(parse_err(n, "unexpected data after the last face".into()));
    }
    out.vertex_radiance = Some(vertex_radiance);
    out.face_radiance = Some(face_radiance);
    Ok(out)
}

fn read_binary_body(
    path: &Path,
    header: &Header,
    layout: &Layout,
    body: &[u8],
) -> Result<ReadBack> {
    let input_err = |message: String| Error::Input {
        path: path.to_path_buf(),
        message,
    };
    let vertex_bytes = vertex_bytes(layout.double);
    let expected = layout.vertices.checked_mul(vertex_bytes).and_then(|v| {
        layout
            .faces
            .checked_mul(FACE_BYTES)
            .and_then(|f| v.checked_add(f))
    });
    if expected != Some(body.len()) {
        return Err(input_err(format!(
            "binary body has {} bytes but the header's {} vertices and {} faces need {}",
            body.len(),
            layout.vertices,
            layout.faces,
            expected.map_or("more than fit in memory".to_string(), |e| e.to_string())
        )));
    }
    let f32s = |b: &[u8]| -> [f32; 3] {
        std::array::from_fn(|k| f32::from_le_bytes(b[4 * k..4 * k + 4].try_into().unwrap()))
    };
    let (vertex_records, face_bytes) = body.split_at(layout.vertices * vertex_bytes);

    let mut positions = Vec::with_capacity(layout.vertices);
    let mut colours = Vec::with_capacity(layout.vertices);
    let mut vertex_radiance = Vec::with_capacity(layout.vertices);
    let at = vertex_bytes - 15;
    for (i, rec) in vertex_records.chunks_exact(vertex_bytes).enumerate() {
        let p: [f64; 3] = if layout.double {
            std::array::from_fn(|k| f64::from_le_bytes(rec[8 * k..8 * k + 8].try_into().unwrap()))
        } else {
            f32s(&rec[0..12]).map(f64::from)
        };
        let r = f32s(&rec[at + 3..]);
        if !(p.iter().all(|v| v.is_finite()) && r.iter().all(|v| v.is_finite())) {
            return Err(input_err(format!(
                "vertex {i}: non-finite position or radiance"
            )));
        }
        positions.push(p);
        colours.push([rec[at], rec[at + 1], rec[at + 2]]);
        vertex_radiance.push(r);
    }
    let mut faces = Vec::with_capacity(layout.faces);
    let mut face_radiance = Vec::with_capacity(layout.faces);
    for (i, rec) in face_bytes.chunks_exact(FACE_BYTES).enumerate() {
        if rec[0] != 3 {
            return Err(input_err(format!(
                "face {i}: {} vertices, expected 3",
                rec[0]
            )));
        }
        let mut face = [0u32; 3];
        for (k, slot) in face.iter_mut().enumerate() {
            let v = i32::from_le_bytes(rec[1 + 4 * k..5 + 4 * k].try_into().unwrap());
            *slot = u32::try_from(v)
                .ok()
                .filter(|&v| (v as usize) < layout.vertices)
                .ok_or_else(|| {
                    input_err(format!(
                        "face {i}: vertex index {v} is outside 0..{}",
                        layout.vertices
                    ))
                })?;
        }
        let r = f32s(&rec[13..25]);
        if !r.iter().all(|v| v.is_finite()) {
            return Err(input_err(format!("face {i}: non-finite radiance")));
        }
        faces.push(face);
        face_radiance.push(r);
    }
    Ok(ReadBack {
        positions,
        colours,
        vertex_radiance: Some(vertex_radiance),
        faces,
        face_radiance: Some(face_radiance),
        camera: header.camera,
        sky: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{write, Format};
    use crate::test_support::{sample_mesh, srgb_colours, TestDir};

    fn f32s(v: &[[f64; 3]]) -> Vec<[f32; 3]> {
        v.iter().map(|p| p.map(|c| c as f32)).collect()
    }

    /// The positions as a single-precision file stores them.
    fn single(v: &[[f64; 3]]) -> Vec<[f64; 3]> {
        v.iter().map(|p| p.map(|c| f64::from(c as f32))).collect()
    }

    #[test]
    fn positions_far_from_the_origin_are_written_in_double_precision() {
        // The sample mesh's vertices a few units apart, near the origin and then at map
        // coordinates (5.6e6 units out): there single precision would round them in steps
        // of 0.5, so the file declares doubles and gives them back exactly, in either format.
        let dir = TestDir::new("ply-far");
        let mut mesh = sample_mesh(203, 157);
        let near = |i: usize| [0.01 * i as f64, 0.013 * i as f64, 0.017 * i as f64];
        mesh.positions = (0..mesh.positions.len()).map(near).collect();
        assert!(!crate::io::needs_double(&mesh.positions));
        for p in &mut mesh.positions {
            *p = [p[0] + 5.0e5 + 0.1, p[1] + 5.6e6 + 0.3, p[2]];
        }
        assert!(crate::io::needs_double(&mesh.positions));
        for ascii in [false, true] {
            let path = dir.path().join("far.ply");
            write(&path, &mesh, Format::Ply { ascii }, 1.0).unwrap();
            let text = String::from_utf8_lossy(&std::fs::read(&path).unwrap()).into_owned();
            assert!(text.contains("property double x\nproperty double y\nproperty double z\n"));
            let back = read(&path).unwrap();
            assert_eq!(back.positions, mesh.positions, "ascii {ascii}");
            assert_eq!(back.vertex_radiance, Some(f32s(&mesh.vertex_radiance)));
            assert_eq!(back.faces, mesh.faces);
        }
    }

    fn round_trip(ascii: bool) {
        let dir = TestDir::new("ply");
        let path = dir.path().join("mesh.ply");
        let mesh = sample_mesh(203, 157);
        let exposure = mesh.auto_exposure();
        write(&path, &mesh, Format::Ply { ascii }, exposure).unwrap();
        let back = read(&path).unwrap();
        assert_eq!(back.positions, single(&mesh.positions));
        let colours = srgb_colours(&mesh, exposure);
        assert_eq!(back.colours, colours);
        // The sample exercises both ends of the curve.
        assert!(colours.contains(&[0, 0, 0]) && colours.iter().any(|c| c.contains(&255)));
        assert_eq!(back.vertex_radiance, Some(f32s(&mesh.vertex_radiance)));
        assert_eq!(back.faces, mesh.faces);
        assert_eq!(back.face_radiance, Some(f32s(&mesh.face_radiance)));
    }

    #[test]
    fn binary_round_trip() {
        round_trip(false);
    }

    #[test]
    fn ascii_round_trip() {
        round_trip(true);
    }

    #[test]
    fn header_is_exactly_as_documented() {
        let mesh = sample_mesh(2, 1);
        let mut bytes = Vec::new();
        write_to(&mut bytes, &mesh, 0.5, false).unwrap();
        let expected = "ply\n\
            format binary_little_endian 1.0\n\
            comment radiosity: baked radiance, W sr^-1 m^-2, linear; colours = sRGB(radiance * exposure)\n\
            comment exposure 0.5\n\
            element vertex 2\n\
            property float x\n\
            property float y\n\
            property float z\n\
            property uchar red\n\
            property uchar green\n\
            property uchar blue\n\
            property float radiance_r\n\
            property float radiance_g\n\
            property float radiance_b\n\
            element face 1\n\
            property list uchar int vertex_indices\n\
            property float radiance_r\n\
            property float radiance_g\n\
            property float radiance_b\n\
            end_header\n";
        assert!(bytes.starts_with(expected.as_bytes()));
        assert_eq!(
            bytes.len(),
            expected.len() + 2 * vertex_bytes(false) + FACE_BYTES
        );

        let mut ascii = Vec::new();
        write_to(&mut ascii, &mesh, 0.5, true).unwrap();
        let ascii = String::from_utf8(ascii).unwrap();
        assert!(ascii.starts_with(&expected.replace("binary_little_endian", "ascii")));
        assert!(ascii.ends_with('\n'));
    }

    #[test]
    fn empty_mesh_round_trips() {
        let dir = TestDir::new("ply-empty");
        for ascii in [false, true] {
            let path = dir.path().join("empty.ply");
            write(&path, &BakedMesh::default(), Format::Ply { ascii }, 1.0).unwrap();
            let back = read(&path).unwrap();
            assert!(back.positions.is_empty() && back.faces.is_empty());
        }
    }

    #[test]
    fn reader_errors_name_line_or_item() {
        let dir = TestDir::new("ply-bad");
        let mesh = sample_mesh(4, 2);
        let path = dir.path().join("bad.ply");

        // ASCII: a bad face index on the last line (header is 20 lines, 4 vertices, 2 faces).
        let mut text = Vec::new();
        write_to(&mut text, &mesh, 1.0, true).unwrap();
        let mut text = String::from_utf8(text).unwrap();
        let last = text.trim_end().rfind('\n').unwrap();
        text.truncate(last + 1);
        text.push_str("3 0 1 9 0 0 0\n");
        std::fs::write(&path, &text).unwrap();
        match read(&path).unwrap_err() {
            Error::Parse { line, message, .. } => {
                assert_eq!(line, 26);
                assert!(message.contains("face 1"), "{message}");
            }
            other => panic!("{other:?}"),
        }

        // Header: a property we do not write.
        std::fs::write(&path, text.replace("property float z", "property double z")).unwrap();
        match read(&path).unwrap_err() {
            Error::Parse { line, .. } => assert_eq!(line, 8),
            other => panic!("{other:?}"),
        }

        // Binary: face index out of range, then a truncated body.
        let mut bin = Vec::new();
        write_to(&mut bin, &mesh, 1.0, false).unwrap();
        let n = bin.len();
        bin[n - FACE_BYTES + 1..n - FACE_BYTES + 5].copy_from_slice(&(-1i32).to_le_bytes());
        std::fs::write(&path, &bin).unwrap();
        match read(&path).unwrap_err() {
            Error::Input { message, .. } => assert!(message.contains("face 1"), "{message}"),
            other => panic!("{other:?}"),
        }
        std::fs::write(&path, &bin[..n - 1]).unwrap();
        assert!(matches!(read(&path).unwrap_err(), Error::Input { .. }));
    }
}
