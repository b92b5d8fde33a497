//! PLY scene loading (ASCII and binary little-endian), into a [`Scene`]. This module owns
//! reading the header and the body, reporting mistakes with `path:line:` (ASCII, and every
//! header) or the element index (binary body), and turning per-face or per-vertex
//! `reflectance_r/g/b` (ρ) and `emission_r/g/b` (Le) into materials; welding, zero-area
//! clean-up and validation are shared with the OBJ loader (`scene::finish`).
//!
//! What is read: `element vertex` with scalar `x`, `y`, `z` (any numeric type; every other
//! property, e.g. normals, colours or our own `radiance_r/g/b`, is ignored) and
//! `element face` with a `vertex_indices` (or `vertex_index`) list; a face of n ≥ 3
//! vertices is fan-triangulated into (v0, v_k, v_k+1) like the OBJ loader does (convex
//! polygons only). Other elements (edges, materials, …) are read past and ignored.
//! Materials: when the face element has a property group (`reflectance_r/g/b` or
//! `emission_r/g/b`) each face takes it; else when the vertex element has it, a face takes
//! the mean over its corners (before triangulation); a group neither has keeps the default
//! (ρ = 0.5, Le = 0). Faces with equal (ρ, Le) share a material; materials are named
//! `ply_0`, `ply_1`, … in the order faces first use them, so names are deterministic and
//! `--reflectance ply_0=…` can address them. A file with neither group gives every face
//! [`Scene::default_material`] (named `default`). A group must be complete (all of `_r`,
//! `_g`, `_b`): a partial one is a header error, because silently reading ρ = (r, 0.5, 0.5)
//! would be a surprise. ρ outside [0, 1], Le negative or not finite, non-finite
//! coordinates, out-of-range or non-integer indices and faces of fewer than 3 vertices are
//! errors naming the line (ASCII) or the element index (binary). An ASCII body is read as
//! one record per non-blank line (what every writer we know of produces); lines or bytes
//! after the last record are ignored. An element with records but no properties is refused
//! (reading it would loop over nothing as many times as the header claims).
//!
//! A header comment `comment camera: EX EY EZ TX TY TZ UX UY UZ FOV` gives the scene its
//! camera ([`crate::scene::camera`]), as `radiosity bake` writes it; a malformed one, or a second
//! one, is an error at its header line. Other comments are ignored.
//!
//! Decision: a hand-written reader, not a crate. `ply-rs-bw` (the maintained fork of
//! `ply-rs`, 4.0.1) needs Rust 1.87 while this crate supports 1.85, and we want the loader's
//! error positions (header line, body line, element index) in our own error type like the
//! OBJ loader's; the subset of PLY 1.0 we need (two encodings, eight scalar types, lists)
//! is about two hundred lines. Big-endian binary is refused with a clear message.

use std::collections::HashMap;
use std::path::Path;

use glam::DVec3;

use super::header::{parse_error, Element, Header, Scalar};
use crate::scene::{finish, Material, Scene, SceneTriangle};
use crate::{Error, Result};

/// Where a body record is, for error messages: its element and index, and in an ASCII body
/// its line.
#[derive(Clone, Copy)]
struct At<'a> {
    element: &'a str,
    index: usize,
    line: Option<usize>,
}

/// An error about record `at`: [`Error::Parse`] at its line (ASCII) or [`Error::Input`]
/// (binary), the message prefixed with the element and index either way.
fn error_at(path: &Path, at: At, message: impl Into<String>) -> Error {
    let message = format!("{} {}: {}", at.element, at.index, message.into());
    match at.line {
        Some(line) => parse_error(path, line, message),
        None => Error::Input {
            path: path.to_path_buf(),
            message,
        },
    }
}

/// The body, read record by record in either encoding.
enum Body<'a> {
    Ascii {
        lines: Box<dyn Iterator<Item = (usize, &'a str)> + 'a>,
        last_line: usize,
    },
    Binary {
        bytes: &'a [u8],
        pos: usize,
    },
}

impl<'a> Body<'a> {
    /// Reads record `index` of `element`: one value per property into `values` (NaN for
    /// lists) and the items of property `want_list` into `list`. Returns where it was.
    fn record(
        &mut self,
        path: &Path,
        element: &'a Element,
        index: usize,
        want_list: Option<usize>,
        values: &mut Vec<f64>,
        list: &mut Vec<f64>,
    ) -> Result<At<'a>> {
        values.clear();
        list.clear();
        match self {
            Body::Ascii { lines, last_line } => {
                let Some((line, text)) = lines.next() else {
                    return Err(parse_error(
                        path,
                        *last_line,
                        format!(
                            "the file ends at {} {index} of {} (the header promises more)",
                            element.name, element.count
                        ),
                    ));
                };
                let at = At {
                    element: &element.name,
                    index,
                    line: Some(line),
                };
                let mut tokens = text.split_whitespace();
                // A value declared `float` is rounded to f32, as a binary file would store it.
                let mut next = |what: &str, ty: Scalar| -> Result<f64> {
                    let token = tokens
                        .next()
                        .ok_or_else(|| error_at(path, at, format!("missing {what}")))?;
                    let x = token.parse::<f64>().map_err(|_| {
                        error_at(path, at, format!("{what}: malformed number '{token}'"))
                    })?;
                    Ok(if ty == Scalar::F32 {
                        x as f32 as f64
                    } else {
                        x
                    })
                };
                for (k, p) in element.properties.iter().enumerate() {
                    if let Some(count_type) = p.list {
                        let n = next(&p.name, count_type)?;
                        if !(n >= 0.0 && n.fract() == 0.0) {
                            return Err(error_at(
                                path,
                                at,
                                format!("{}: list length {n} is not a count", p.name),
                            ));
                        }
                        for _ in 0..n as usize {
                            let x = next(&p.name, p.scalar)?;
                            if want_list == Some(k) {
                                list.push(x);
                            }
                        }
                        values.push(f64::NAN);
                    } else {
                        values.push(next(&p.name, p.scalar)?);
                    }
                }
                if tokens.next().is_some() {
                    return Err(error_at(
                        path,
                        at,
                        "more values than the header's properties",
                    ));
                }
                Ok(at)
            }
            Body::Binary { bytes, pos } => {
                let at = At {
                    element: &element.name,
                    index,
                    line: None,
                };
                let mut take = |ty: Scalar| -> Result<f64> {
                    let end = *pos + ty.size();
                    let b = bytes.get(*pos..end).ok_or_else(|| {
                        error_at(
                            path,
                            at,
                            format!(
                                "the file ends inside this record (the header promises {})",
                                element.count
                            ),
                        )
                    })?;
                    *pos = end;
                    Ok(ty.read_le(b))
                };
                for (k, p) in element.properties.iter().enumerate() {
                    match p.list {
                        Some(count_type) => {
                            let n = take(count_type)?;
                            if n < 0.0 {
                                return Err(error_at(
                                    path,
                                    at,
                                    format!("{}: negative list length {n}", p.name),
                                ));
                            }
                            for _ in 0..n as usize {
                                let x = take(p.scalar)?;
                                if want_list == Some(k) {
                                    list.push(x);
                                }
                            }
                            values.push(f64::NAN);
                        }
                        None => values.push(take(p.scalar)?),
                    }
                }
                Ok(at)
            }
        }
    }
}

/// A material value group read from the file: ρ or Le per face or per vertex.
fn check_group(path: &Path, at: At, what: &str, v: [f64; 3]) -> Result<[f64; 3]> {
    let ok = match what {
        "reflectance" => v.iter().all(|r| (0.0..=1.0).contains(r)),
        _ => v.iter().all(|e| e.is_finite() && *e >= 0.0),
    };
    if ok {
        Ok(v)
    } else if what == "reflectance" {
        Err(error_at(
            path,
            at,
            format!("reflectance ρ = {v:?} is not in [0, 1]"),
        ))
    } else {
        Err(error_at(
            path,
            at,
            format!("emission Le = {v:?} must be finite and ≥ 0"),
        ))
    }
}

/// Loads a PLY file into a welded, cleaned and validated [`Scene`]; see the module docs.
pub fn load(path: &Path) -> Result<Scene> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let header = Header::parse(path, &bytes)?;
    let input = |message: String| Error::Input {
        path: path.to_path_buf(),
        message,
    };
    let find = |name: &str| header.elements.iter().find(|e| e.name == name);
    let vertex = find("vertex").ok_or_else(|| input("no `element vertex` in the header".into()))?;
    let face = find("face").ok_or_else(|| {
        input("no `element face` in the header: a point cloud has no surfaces".into())
    })?;
    let xyz = ["x", "y", "z"].map(|c| {
        vertex
            .find(c)
            .filter(|&i| vertex.properties[i].list.is_none())
    });
    let [Some(x), Some(y), Some(z)] = xyz else {
        return Err(parse_error(
            path,
            vertex.line,
            "element vertex needs scalar properties x, y and z",
        ));
    };
    let indices = face
        .find("vertex_indices")
        .or_else(|| face.find("vertex_index"))
        .filter(|&i| face.properties[i].list.is_some())
        .ok_or_else(|| {
            parse_error(
                path,
                face.line,
                "element face needs a list property vertex_indices",
            )
        })?;
    let groups = ["reflectance", "emission"];
    let vertex_groups = [
        vertex.group(path, groups[0])?,
        vertex.group(path, groups[1])?,
    ];
    let face_groups = [face.group(path, groups[0])?, face.group(path, groups[1])?];

    let body_bytes = &bytes[header.body_start..];
    let mut body = if header.ascii {
        let text = std::str::from_utf8(body_bytes).map_err(|e| {
            let valid = &body_bytes[..e.valid_up_to()];
            let line = header.lines + 1 + valid.iter().filter(|&&b| b == b'\n').count();
            parse_error(path, line, "ASCII PLY body is not UTF-8 text")
        })?;
        let first = header.lines + 1;
        let lines: Box<dyn Iterator<Item = (usize, &str)>> = Box::new(
            text.lines()
                .enumerate()
                .map(move |(i, l)| (first + i, l))
                .filter(|(_, l)| !l.trim().is_empty()),
        );
        Body::Ascii {
            lines,
            last_line: header.lines + text.lines().count().max(1),
        }
    } else {
        Body::Binary {
            bytes: body_bytes,
            pos: 0,
        }
    };

    // No reservation from the header's counts: a hostile file could claim billions.
    let mut positions = Vec::new();
    // Per-vertex material groups, when the vertex element has them.
    let mut vertex_values: [Vec<[f64; 3]>; 2] = [Vec::new(), Vec::new()];
    // Per face: where it is, its corners, and its own (ρ, Le) when the face element has them.
    type Face<'a> = (At<'a>, Vec<u32>, [Option<[f64; 3]>; 2]);
    let mut faces: Vec<Face> = Vec::new();
    let (mut values, mut list) = (Vec::new(), Vec::new());
    for element in &header.elements {
        for i in 0..element.count {
            let is_vertex = std::ptr::eq(element, vertex);
            let is_face = std::ptr::eq(element, face);
            let want = is_face.then_some(indices);
            let at = body.record(path, element, i, want, &mut values, &mut list)?;
            if is_vertex {
                let p = DVec3::new(values[x], values[y], values[z]);
                if !p.is_finite() {
                    return Err(error_at(path, at, format!("non-finite coordinate ({p})")));
                }
                positions.push(p);
                for (g, group) in vertex_groups.iter().enumerate() {
                    if let Some([r, gr, b]) = *group {
                        let v = [values[r], values[gr], values[b]];
                        vertex_values[g].push(check_group(path, at, groups[g], v)?);
                    }
                }
            } else if is_face {
                if list.len() < 3 {
                    return Err(error_at(
                        path,
                        at,
                        format!("{} vertices; at least 3 are needed", list.len()),
                    ));
                }
                let mut corners = Vec::with_capacity(list.len());
                for &v in &list {
                    if !(v >= 0.0 && v.fract() == 0.0 && v < vertex.count as f64) {
                        return Err(error_at(
                            path,
                            at,
                            format!(
                                "vertex index {v} out of range (the file has {} vertices)",
                                vertex.count
                            ),
                        ));
                    }
                    corners.push(v as u32);
                }
                let mut own = [None, None];
                for (g, group) in face_groups.iter().enumerate() {
                    if let Some([r, gr, b]) = *group {
                        let v = [values[r], values[gr], values[b]];
                        own[g] = Some(check_group(path, at, groups[g], v)?);
                    }
                }
                faces.push((at, corners, own));
            }
        }
    }

    // Materials: face value, else the mean of the corners' vertex values, else the default.
    let default = Scene::default_material();
    let any_group = (0..2).any(|g| face_groups[g].is_some() || vertex_groups[g].is_some());
    let mut materials: Vec<Material> = Vec::new();
    let mut by_value: HashMap<[u64; 6], u32> = HashMap::new();
    let mut triangles = Vec::new();
    let mut face_lines = Vec::new();
    for (at, corners, own) in &faces {
        let value = |g: usize, fallback: [f64; 3]| {
            own[g].unwrap_or_else(|| {
                if vertex_values[g].is_empty() {
                    return fallback;
                }
                let mut sum = [0.0; 3];
                for &v in corners {
                    for (s, x) in sum.iter_mut().zip(vertex_values[g][v as usize]) {
                        *s += x;
                    }
                }
                // The mean of values in [0, 1] can round a hair above 1: clamp to the range.
                let n = corners.len() as f64;
                let mean = sum.map(|s| s / n);
                if g == 0 {
                    mean.map(|m| m.clamp(0.0, 1.0))
                } else {
                    mean
                }
            })
        };
        let material = if any_group {
            let rho = value(0, default.reflectance);
            let le = value(1, default.emission);
            let mut key = [0u64; 6];
            for (k, x) in rho.iter().chain(&le).enumerate() {
                key[k] = (x + 0.0).to_bits();
            }
            *by_value.entry(key).or_insert_with(|| {
                materials.push(Material::opaque(
                    format!("ply_{}", materials.len()),
                    rho,
                    le,
                ));
                (materials.len() - 1) as u32
            })
        } else {
            if materials.is_empty() {
                materials.push(default.clone());
            }
            0
        };
        for k in 1..corners.len() - 1 {
            triangles.push(SceneTriangle {
                vertices: [corners[0], corners[k], corners[k + 1]],
                material,
                uv: crate::scene::NO_UV,
            });
            if let Some(line) = at.line {
                face_lines.push(line);
            }
        }
    }
    if triangles.is_empty() {
        return Err(input("the mesh is empty: no faces".into()));
    }
    let mut scene = finish(
        Some(path.to_path_buf()),
        positions,
        triangles,
        materials,
        (Vec::new(), Vec::new()),
        (Vec::new(), Vec::new()),
        header.ascii.then_some(face_lines),
    )?;
    scene.camera = header.camera;
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::TestDir;

    /// Writes `bytes` as `name` in a fresh temporary directory (unique per call, tests run
    /// in parallel) and loads it.
    fn load_bytes(name: &str, bytes: &[u8]) -> Result<Scene> {
        load(&TestDir::new("ply").write(name, bytes))
    }

    /// A unit floor quad (z = 0, facing +z) and an emitting triangle above it facing down.
    const ASCII: &str = "ply\nformat ascii 1.0\ncomment a lit floor\n\
        element vertex 7\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\n\
        element face 2\nproperty list uchar int vertex_indices\n\
        property float reflectance_r\nproperty float reflectance_g\nproperty float reflectance_b\n\
        property float emission_r\nproperty float emission_g\nproperty float emission_b\n\
        end_header\n\
        0 0 0 9\n1 0 0 9\n1 1 0 9\n0 1 0 9\n0.2 0.2 1 9\n0.8 0.2 1 9\n0.5 0.8 1 9\n\
        4 0 1 2 3 0.25 0.5 0.75 0 0 0\n\
        3 4 6 5 0.5 0.5 0.5 1 2 3\n";

    /// The same scene as [`ASCII`], binary: double coordinates, uint indices, float groups.
    fn binary() -> Vec<u8> {
        let mut b = b"ply\nformat binary_little_endian 1.0\n\
            element vertex 7\nproperty double x\nproperty double y\nproperty double z\n\
            property uchar red\n\
            element face 2\nproperty list uchar uint vertex_indices\n\
            property float reflectance_r\nproperty float reflectance_g\nproperty float reflectance_b\n\
            property float emission_r\nproperty float emission_g\nproperty float emission_b\n\
            end_header\n"
            .to_vec();
        let corners = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.2, 0.2, 1.0],
            [0.8, 0.2, 1.0],
            [0.5, 0.8, 1.0],
        ];
        for p in corners {
            for c in p {
                b.extend_from_slice(&f64::to_le_bytes(c));
            }
            b.push(200);
        }
        let faces: [(&[u32], [f32; 6]); 2] = [
            (&[0, 1, 2, 3], [0.25, 0.5, 0.75, 0.0, 0.0, 0.0]),
            (&[4, 6, 5], [0.5, 0.5, 0.5, 1.0, 2.0, 3.0]),
        ];
        for (idx, values) in faces {
            b.push(idx.len() as u8);
            for i in idx {
                b.extend_from_slice(&i.to_le_bytes());
            }
            for v in values {
                b.extend_from_slice(&v.to_le_bytes());
            }
        }
        b
    }

    fn check_lit_floor(s: &Scene, point_two: f64) {
        assert_eq!(s.positions.len(), 7);
        assert_eq!(s.triangles.len(), 3, "quad fan-triangulated");
        assert_eq!(s.positions[4], DVec3::new(point_two, point_two, 1.0));
        let names: Vec<&str> = s.materials.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["ply_0", "ply_1"]);
        assert_eq!(s.materials[0].reflectance, [0.25, 0.5, 0.75]);
        assert_eq!(s.materials[0].emission, [0.0; 3]);
        assert_eq!(s.materials[1].emission, [1.0, 2.0, 3.0]);
        let t: Vec<([u32; 3], u32)> = s
            .triangles
            .iter()
            .map(|t| (t.vertices, t.material))
            .collect();
        assert_eq!(t, [([0, 1, 2], 0), ([0, 2, 3], 0), ([4, 6, 5], 1)]);
        assert!(s.has_emitters());
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    }

    #[test]
    fn ascii_and_binary_per_face_materials() {
        let a = load_bytes("ascii.ply", ASCII.as_bytes()).unwrap();
        // ASCII `float` values are rounded to f32, binary `double` ones are kept.
        check_lit_floor(&a, 0.2f32 as f64);
        let b = load_bytes("binary.PLY", &binary()).unwrap();
        check_lit_floor(&b, 0.2);
        // Through Scene::load's dispatch too.
        let dir = TestDir::new("ply-dispatch");
        let path = dir.write("s.ply", ASCII);
        let s = Scene::load(&path).unwrap();
        assert_eq!(s.source.as_deref(), Some(path.as_path()));
    }

    #[test]
    fn per_vertex_values_are_averaged_and_no_values_mean_the_default() {
        // Emission per vertex only: the face takes the mean over its corners; ρ stays 0.5.
        let text = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
            property float z\nproperty float emission_r\nproperty float emission_g\n\
            property float emission_b\nelement face 2\nproperty list uchar int vertex_index\n\
            end_header\n0 0 0 0 0 0\n1 0 0 3 0 0\n1 1 0 0 3 0\n0 1 0 0 0 0\n3 0 1 2\n3 0 2 3\n";
        let s = load_bytes("vertex.ply", text.as_bytes()).unwrap();
        assert_eq!(s.materials.len(), 2);
        assert_eq!(s.materials[0].emission, [1.0, 1.0, 0.0]);
        assert_eq!(s.materials[1].emission, [0.0, 1.0, 0.0]);
        assert!(s.materials.iter().all(|m| m.reflectance == [0.5; 3]));
        assert_eq!(s.triangles[1].material, 1);

        let plain = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
            property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
            0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
        let s = load_bytes("plain.ply", plain.as_bytes()).unwrap();
        assert_eq!(s.materials, [Scene::default_material()]);
        assert!(!s.has_emitters());
    }

    #[test]
    fn a_baked_ply_loads_as_a_scene() {
        use crate::{bake::BakedMesh, io::ply as out};
        let mesh = BakedMesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [0.0, 2.0, 0.0],
                [2.0, 2.0, 0.0],
            ],
            vertex_radiance: vec![[1.0, 2.0, 3.0]; 4],
            faces: vec![[0, 1, 2], [1, 3, 2]],
            face_radiance: vec![[4.0, 5.0, 6.0]; 2],
            camera: None,
            sky: None,
        };
        for ascii in [true, false] {
            let mut bytes = Vec::new();
            out::write_to(&mut bytes, &mesh, 1.0, ascii).unwrap();
            let s = load_bytes("baked.ply", &bytes).unwrap();
            assert_eq!(s.triangles.len(), 2, "ascii {ascii}");
            assert_eq!(s.positions[3], DVec3::new(2.0, 2.0, 0.0));
            assert_eq!(s.materials, [Scene::default_material()], "radiance ignored");
        }
    }

    /// Asserts `e` is a parse error at `line` (or, with `line` 0, an input error) whose
    /// message contains `needle`.
    #[track_caller]
    fn assert_error(e: &Error, line: usize, needle: &str) {
        let msg = e.to_string();
        match e {
            Error::Parse { line: l, path, .. } => {
                assert_eq!(*l, line, "{msg}");
                assert!(path.ends_with("bad.ply"), "{msg}");
            }
            Error::Input { path, .. } => {
                assert_eq!(line, 0, "expected a parse error at line {line}: {msg}");
                assert!(path.ends_with("bad.ply"), "{msg}");
            }
            other => panic!("unexpected {other:?}"),
        }
        assert!(msg.contains(needle), "{needle:?} not in: {msg}");
    }

    #[test]
    fn ascii_errors_name_the_line() {
        let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
            property float z\nelement face 1\nproperty list uchar int vertex_indices\n";
        let group = "property float reflectance_r\nproperty float reflectance_g\n\
            property float reflectance_b\n";
        let tri = "0 0 0\n1 0 0\n0 1 0\n";
        let cases: Vec<(String, usize, &str)> = vec![
            ("solid x\n".into(), 1, "not a PLY file"),
            (
                "ply\nformat binary_big_endian 1.0\nend_header\n".into(),
                2,
                "binary_big_endian",
            ),
            (
                format!("{head}property float8 q\nend_header\n"),
                9,
                "unknown property type",
            ),
            (
                format!("{head}end_header\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n"),
                11,
                "non-finite",
            ),
            (
                format!("{head}end_header\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n"),
                11,
                "malformed number 'x'",
            ),
            (
                format!("{head}end_header\n{tri}3 0 1 3\n"),
                13,
                "vertex index 3 out of range",
            ),
            (
                format!("{head}end_header\n{tri}3 0 1 -1\n"),
                13,
                "vertex index -1",
            ),
            (
                format!("{head}end_header\n{tri}2 0 1\n"),
                13,
                "face 0: 2 vertices; at least 3",
            ),
            (
                format!("{head}end_header\n{tri}3 0 1\n"),
                13,
                "missing vertex_indices",
            ),
            (
                format!("{head}end_header\n{tri}3 0 1 2 7\n"),
                13,
                "more values",
            ),
            (
                format!("{head}end_header\n{tri}"),
                12,
                "the file ends at face 0",
            ),
            (
                format!("{head}{group}end_header\n{tri}3 0 1 2 0.5 1.5 0.5\n"),
                16,
                "not in [0, 1]",
            ),
            (
                format!("{head}{group}end_header\n{tri}3 0 1 2 0.5 nan 0.5\n"),
                16,
                "not in [0, 1]",
            ),
            (
                format!("{head}property float emission_r\nend_header\n{tri}3 0 1 2 1\n"),
                7,
                "emission_r, emission_g and emission_b",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                 property float emission_r\nproperty float emission_g\nproperty float emission_b\n\
                 end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 1 -2 1\n"
                    .into(),
                16,
                "≥ 0",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 1\n".into(),
                4,
                "no end_header",
            ),
            (
                head.replacen(
                    "element vertex",
                    "element junk 99999999999\nelement vertex",
                    1,
                ) + "end_header\n",
                3,
                "element junk has records but no properties",
            ),
        ];
        for (text, line, needle) in cases {
            let e = load_bytes("bad.ply", text.as_bytes()).unwrap_err();
            assert_error(&e, line, needle);
            assert_eq!(e.exit_code(), 2);
        }
        let no_face =
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
            property float z\nend_header\n0 0 0\n";
        assert_error(
            &load_bytes("bad.ply", no_face.as_bytes()).unwrap_err(),
            0,
            "point cloud",
        );
    }

    #[test]
    fn binary_errors_name_the_element() {
        let good = binary();
        // Cut inside face 1.
        let e = load_bytes("bad.ply", &good[..good.len() - 3]).unwrap_err();
        assert_error(&e, 0, "face 1: the file ends inside this record");
        // Face 1's last index (before its six floats) → 7.
        let mut b = good.clone();
        let at = b.len() - 24 - 4;
        b[at..at + 4].copy_from_slice(&7u32.to_le_bytes());
        assert_error(
            &load_bytes("bad.ply", &b).unwrap_err(),
            0,
            "face 1: vertex index 7 out of range",
        );
        // Vertex 2's y → NaN (each vertex record is 3 doubles and a uchar: 25 bytes).
        let header_len = good.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
        let mut b = good.clone();
        let at = header_len + 2 * 25 + 8;
        b[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        assert_error(
            &load_bytes("bad.ply", &b).unwrap_err(),
            0,
            "vertex 2: non-finite coordinate",
        );
    }
}
