//! Wavefront OBJ + MTL loading through `tobj`, into a [`Scene`]. This module owns reading
//! the files, reporting their mistakes with `path:line:`, and mapping `Kd` → ρ and `Ke` →
//! Le; welding, zero-area clean-up and validation are shared with the builder
//! (`scene::finish`).
//!
//! How a file is read:
//! 1. We scan the OBJ text ourselves first, because `tobj` reports errors without a line
//!    number and silently accepts some mistakes (faces with fewer than 3 vertices, NaN or
//!    overflowing coordinates), and does not join a line ending in `\` to the next (the
//!    OBJ specification's continuation). The scan joins them, checks every line we use and
//!    hands `tobj` a normalised copy with the same line numbering: `v x y z [w]` (vertex
//!    colours dropped), `f` with absolute 1-based position indices only (texture and normal
//!    indices dropped: radiosity uses neither), `o`/`g`/`usemtl`/`mtllib` with single
//!    spaces; every other line (`vt`, `vn`, `l`, `p`, `s`, comments, unknown statements)
//!    becomes empty. Dropping `l` matters: `tobj` would turn a polyline of 3+ points into
//!    triangles.
//! 2. `tobj::load_obj_buf` (what `tobj::load_obj` calls after opening the file) parses that
//!    copy with `LoadOptions { single_index: false, triangulate: true, ignore_points: true,
//!    ignore_lines: true }`; polygons are fan-triangulated (convex polygons only).
//! 3. Each `mtllib` is read by our own loader callback, relative to the OBJ's directory (its
//!    files: `mtllib a.mtl b.mtl` names two, unless one file has that name with its space),
//!    which scans the MTL text the same way (keeping `newmtl`, `Kd`, `Ke`; a single-value
//!    `Kd r` means `r r r`, as the MTL spec says, and is expanded because `tobj` would panic
//!    on it) and records any failure. `tobj` keeps only the last material error and drops
//!    it when another library loaded; we report the first one. The scan also records each
//!    material's `map_Kd` and `Ks` ([`super::mtl::Extras`]): a texture's mean colour
//!    multiplies ρ, and a specular-only material (`Kd 0`, `Ks > 0`) is a warning, since a
//!    diffuse solver bakes it black.
//!
//! Decisions: faces before any `usemtl` get [`Scene::default_material`]; a `usemtl` whose
//! material no earlier `mtllib` defines is an error at that line (`tobj` would silently
//! leave those faces without a material), unless a library before it is missing: a missing
//! MTL file is a warning naming the `mtllib` line and the MTL path, and the faces of the
//! materials it would have defined get the default material (models are often shared without
//! their MTL); an MTL file that is there but cannot be read or parsed is an error. A material
//! without `Kd` gets ρ = 0.5 with a warning.
//!
//! A comment `# camera: EX EY EZ TX TY TZ UX UY UZ FOV` gives the scene its camera
//! ([`crate::scene::camera`]; eye, target and up in scene units, vertical field of view in
//! degrees). A malformed one, or a second one, is an error at its line; other comments are ignored.

use std::cell::RefCell;
use std::collections::HashSet;
use std::io::Cursor;
use std::path::{Path, PathBuf};

use glam::DVec3;

use super::mtl::{
    apply_extras, apply_transmittance, convert_material, read_mtl, tobj_failure, Extras,
};
use super::{parse_number, read_text};
use crate::io::parse_error;
use crate::scene::camera::{Camera, CameraLine};
use crate::scene::{finish, Material, Scene, SceneTriangle};
use crate::{Error, Result};

/// The options the scene loader passes to `tobj`.
const LOAD_OPTIONS: tobj::LoadOptions = tobj::LoadOptions {
    single_index: false,
    triangulate: true,
    ignore_points: true,
    ignore_lines: true,
};

/// The MTL files of one `mtllib` line, relative to the OBJ's directory `dir`: the line's
/// whole text as one file name if there is such a file (a name with spaces), else its
/// names split at white space (the OBJ specification's `mtllib a.mtl b.mtl`) when any of
/// them exists, else the whole text (reported as missing).
fn library_files(dir: &Path, name: &Path) -> Vec<PathBuf> {
    let whole = dir.join(name);
    if whole.exists() {
        return vec![whole];
    }
    let parts: Vec<PathBuf> = name
        .to_str()
        .map(|s| s.split_whitespace().map(|p| dir.join(p)).collect())
        .unwrap_or_default();
    if parts.len() > 1 && parts.iter().any(|p| p.exists()) {
        parts
    } else {
        vec![whole]
    }
}

/// The files an OBJ's scene reads beside it: the MTL files its `mtllib` lines name and the
/// texture images (`map_Kd`) those name, as [`load`] finds them, those that exist. A cheap
/// scan (no image decoded), so the outputs can be checked against them before any work;
/// what cannot be read is left to [`load`] to report.
pub fn companion_files(path: &Path) -> Vec<PathBuf> {
    let Ok(text) = read_text(path) else {
        return Vec::new();
    };
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut files = Vec::new();
    for (line, joined, _) in logical_lines(&text) {
        let Some(name) = joined.trim().strip_prefix("mtllib") else {
            continue;
        };
        if !name.starts_with(char::is_whitespace) {
            continue;
        }
        for mtl in library_files(dir, Path::new(name.trim())) {
            let Ok((_, extras)) = super::mtl::read_mtl(path, line, &mtl) else {
                continue;
            };
            files.extend(
                extras
                    .iter()
                    .filter_map(|e| e.texture.as_ref())
                    .map(|(file, _)| super::mtl::texture_path(&mtl, file)),
            );
            files.push(mtl);
        }
    }
    files.retain(|f| f.exists());
    files
}

/// Loads an OBJ file and the MTL files it references into a welded, cleaned and validated
/// [`Scene`]. Errors name the file and, where there is one, the line (1-based).
pub fn load(path: &Path) -> Result<Scene> {
    let text = read_text(path)?;
    let scan = scan_obj(path, &text)?;
    let dir = path.parent().unwrap_or(Path::new(""));

    // One record per `mtllib` line, in order (tobj calls the loader once per line).
    let libraries: RefCell<Vec<HashSet<String>>> = RefCell::new(Vec::new());
    let extras: RefCell<Vec<(PathBuf, Extras)>> = RefCell::new(Vec::new());
    let first_error: RefCell<Option<Error>> = RefCell::new(None);
    let missing: RefCell<Vec<(usize, PathBuf)>> = RefCell::new(Vec::new());
    let loader = |name: &Path| -> tobj::MTLLoadResult {
        let k = libraries.borrow().len();
        let line = scan.mtllib_lines.get(k).copied().unwrap_or(0);
        let mut materials = Vec::new();
        let mut names: Vec<(String, usize)> = Vec::new();
        for mtl in library_files(dir, name) {
            if !mtl.exists() {
                // Shared without its library, as models often are: a warning, and the faces
                // of its materials get the default one (below).
                missing.borrow_mut().push((line, mtl));
                continue;
            }
            let result = read_mtl(path, line, &mtl).and_then(|(text, found)| {
                extras
                    .borrow_mut()
                    .extend(found.into_iter().map(|e| (mtl.clone(), e)));
                tobj::load_mtl_buf(&mut Cursor::new(text.as_bytes()))
                    .map_err(|e| tobj_failure(&mtl, e))
            });
            match result {
                // Several libraries on one line: the later one's materials after the
                // earlier's, a name defined twice taking the later definition.
                Ok((found, map)) => {
                    let offset = materials.len();
                    materials.extend(found);
                    names.extend(map.into_iter().map(|(n, i)| (n, i + offset)));
                }
                Err(e) => {
                    libraries.borrow_mut().push(HashSet::new());
                    first_error.borrow_mut().get_or_insert(e);
                    return Err(tobj::LoadError::GenericFailure);
                }
            }
        }
        libraries
            .borrow_mut()
            .push(names.iter().map(|(n, _)| n.clone()).collect());
        Ok((materials, names.into_iter().collect()))
    };
    let loaded = tobj::load_obj_buf(
        &mut Cursor::new(scan.normalised.as_bytes()),
        &LOAD_OPTIONS,
        loader,
    );
    if let Some(e) = first_error.into_inner() {
        return Err(e);
    }
    let (models, tobj_materials) = loaded.map_err(|e| tobj_failure(path, e))?;
    let tobj_materials = tobj_materials.map_err(|e| tobj_failure(path, e))?;

    // A `usemtl` must name a material of an `mtllib` that comes before it, unless one of
    // those libraries is missing: then it is one of the missing library's, given the default.
    let libraries = libraries.into_inner();
    let missing = missing.into_inner();
    let mut undefined: Vec<String> = Vec::new();
    for u in &scan.usemtl {
        let known = libraries
            .iter()
            .take(u.libraries_before)
            .any(|lib| lib.contains(&u.name));
        let after_missing = missing.iter().any(|&(line, _)| {
            scan.mtllib_lines[..u.libraries_before.min(scan.mtllib_lines.len())].contains(&line)
        });
        if !known && after_missing {
            if !undefined.contains(&u.name) {
                undefined.push(u.name.clone());
            }
            continue;
        }
        if !known {
            let hint = if u.libraries_before == 0 {
                " (no mtllib before this line)"
            } else {
                ""
            };
            return Err(parse_error(
                path,
                u.line,
                format!(
                    "usemtl {}: material not defined by any mtllib before this line{hint}",
                    u.name
                ),
            ));
        }
    }

    let mut warnings = Vec::new();
    let mut details = Vec::new();
    if !missing.is_empty() {
        let libraries: Vec<String> = missing
            .iter()
            .map(|(line, mtl)| format!("{} (mtllib at line {line})", mtl.display()))
            .collect();
        let whose = if undefined.is_empty() {
            "; no face uses its materials".to_string()
        } else {
            format!(
                "; the faces of its material{} {} get the default material (ρ {}, no emission)",
                if undefined.len() == 1 { "" } else { "s" },
                crate::scene::listed_names_all(
                    "materials_of_missing_libraries",
                    &undefined,
                    &mut details
                ),
                Scene::default_material().reflectance[0],
            )
        };
        warnings.push(format!(
            "{}: material librar{} not found: {}{whose}; put the MTL file beside the OBJ for \
             the file's colours and lights",
            path.display(),
            if missing.len() == 1 { "y" } else { "ies" },
            libraries.join(", "),
        ));
    }
    let extras = extras.into_inner();
    let textured = |name: &str| {
        extras
            .iter()
            .rev()
            .find(|(_, e)| e.name == name)
            .is_some_and(|(_, e)| e.texture.is_some())
    };
    let mut materials: Vec<Material> = tobj_materials
        .iter()
        .map(|m| convert_material(m, textured(&m.name), &mut warnings))
        .collect();
    apply_transmittance(&mut materials, &extras, &mut warnings);
    let (textures, texture_of) =
        apply_extras(&mut materials, &extras, (&mut warnings, &mut details));
    // tobj keeps faces in file order and fan-triangulates a face of n vertices into n − 2
    // triangles (corners 0, j + 1, j + 2), so triangle k comes from the k-th (face, j) below
    // (checked by the count).
    let fans: Vec<(usize, usize)> = scan
        .faces
        .iter()
        .enumerate()
        .flat_map(|(f, &(_, n))| (0..n - 2).map(move |j| (f, j)))
        .collect();
    let mut uv_maps = Vec::new();

    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    let mut default_material = None;
    for model in &models {
        let mesh = &model.mesh;
        let base = positions.len();
        positions.extend(
            mesh.positions
                .chunks_exact(3)
                .map(|p| DVec3::new(p[0], p[1], p[2])),
        );
        let material = match mesh.material_id {
            Some(id) => id,
            None => *default_material.get_or_insert_with(|| {
                materials.push(Scene::default_material());
                materials.len() - 1
            }),
        };
        // Indices past u32::MAX saturate; `finish` rejects such a scene by its vertex count.
        let to_u32 = |i: usize| u32::try_from(i).unwrap_or(u32::MAX);
        for t in mesh.indices.chunks_exact(3) {
            let vertices = [t[0], t[1], t[2]].map(|v| to_u32(base + v as usize));
            // The texture's map on this triangle, when its material has a texture and its
            // face texture coordinates (OBJ's v counts up from the image's bottom row).
            let k = triangles.len();
            let uv = texture_of
                .get(material)
                .copied()
                .flatten()
                .zip(
                    fans.get(k)
                        .and_then(|&(f, j)| scan.face_uvs[f].as_ref().map(|c| (c, j))),
                )
                .and_then(|(texture, (corners, j))| {
                    let at = |i: usize| {
                        let p = scan.uvs[corners[i] as usize];
                        glam::DVec2::new(p.x, 1.0 - p.y)
                    };
                    let points = vertices.map(|v| positions[v as usize]);
                    crate::scene::UvMap::new(texture, points, [at(0), at(j + 1), at(j + 2)])
                })
                .map_or(crate::scene::NO_UV, |m| {
                    uv_maps.push(m);
                    to_u32(uv_maps.len() - 1)
                });
            triangles.push(SceneTriangle {
                vertices,
                material: to_u32(material),
                uv,
            });
        }
    }
    if triangles.is_empty() {
        return Err(Error::Input {
            path: path.to_path_buf(),
            message: "the mesh is empty: no faces with 3 or more vertices".into(),
        });
    }
    let far = far_from_origin(&positions);
    if let Some(far) = &far {
        warnings.push(format!("{}: {far}", path.display()));
    }
    let face_lines: Vec<usize> = fans.iter().map(|&(f, _)| scan.faces[f].0).collect();
    let mut scene = finish(
        Some(path.to_path_buf()),
        positions,
        triangles,
        materials,
        (textures, uv_maps),
        (warnings, details),
        Some(face_lines),
    )
    // A scene the rounding has flattened fails as degenerate: the reason goes with it.
    .map_err(|e| match (e, far) {
        (Error::Input { path, message }, Some(far)) => Error::Input {
            path,
            message: format!("{message}; {far}"),
        },
        (e, _) => e,
    })?;
    scene.camera = scan.camera;
    Ok(scene)
}

/// Rounding of the coordinates, as a share of the scene's size, above which a load warns
/// ([`far_from_origin`]): a ten-thousandth of a room is a millimetre.
pub const FAR_ROUNDING: f64 = 1e-4;

/// What to tell the user when the OBJ's coordinates lie so far from the origin for the
/// scene's size that reading them in double precision (as `tobj` reads them with its
/// `use_f64` feature, 53 bits: steps of 2⁻⁵² |x| at most) rounds them by more than
/// [`FAR_ROUNDING`] of its bounding box's diagonal (a metre-sized model 10¹² m out); `None`
/// when it does not. A building in map coordinates (5.6·10⁶ m out, 50 m across) is read to
/// 10⁻⁹ m, and bakes as it would at the origin: the ray casting works in coordinates
/// centred on the scene ([`crate::visibility`]), and the outputs keep the positions in
/// double precision ([`crate::io::needs_double`]).
fn far_from_origin(positions: &[DVec3]) -> Option<String> {
    let (lo, hi) = crate::geometry::bounds(positions.iter().copied());
    let extent = (hi - lo).length();
    let largest = lo.abs().max(hi.abs()).max_element();
    let step = largest * f64::EPSILON;
    (extent.is_finite() && step > FAR_ROUNDING * extent).then(|| {
        let share = if step < extent {
            format!("{:.2} % of the scene", 100.0 * step / extent)
        } else {
            "as much as the scene's size, or more".to_string()
        };
        format!(
            "its coordinates lie far from the origin for its size (up to {largest:.4e}, the \
             scene {extent:.4e} across as read): an OBJ's numbers are read in double \
             precision, which rounds them here in steps of up to {step:.1e} ({share}), so its \
             shape may not be the file's; moved near the origin, the model keeps it"
        )
    })
}

/// A `usemtl` statement: the name, its line, and how many `mtllib` lines precede it.
struct UseMtl {
    name: String,
    line: usize,
    libraries_before: usize,
}

/// What the OBJ scan found: the normalised text for `tobj` (same line numbering) and the
/// statements resolved after `tobj` has loaded the materials.
struct ObjScan {
    normalised: String,
    usemtl: Vec<UseMtl>,
    mtllib_lines: Vec<usize>,
    /// Every `f` statement: its line and its number of vertices (≥ 3).
    faces: Vec<(usize, usize)>,
    /// Per `f` statement: its vertices' `vt` indices (0-based), when every vertex has one.
    face_uvs: Vec<Option<Vec<u32>>>,
    /// The `vt` statements' coordinates (u, v), in file order.
    uvs: Vec<glam::DVec2>,
    /// The `# camera: …` comment's camera (at most one such line).
    camera: Option<Camera>,
}

/// The 1-based absolute index that `text`, one index of the face vertex `token`, names among
/// the `count` items (`what` = (its name, the items' name, count)) defined before line `ln`:
/// positive indices count from 1, negative ones back from the latest item. 0 and indices out
/// of range are errors at the line.
fn face_index(
    path: &Path,
    ln: usize,
    token: &str,
    text: &str,
    (name, items, count): (&str, &str, usize),
) -> Result<i64> {
    let k: i64 = text
        .parse()
        .map_err(|_| parse_error(path, ln, format!("face: malformed vertex '{token}'")))?;
    let absolute = if k < 0 { count as i64 + k + 1 } else { k };
    if k == 0 {
        return Err(parse_error(
            path,
            ln,
            format!("face: {name} 0 (OBJ indices start at 1)"),
        ));
    }
    if absolute < 1 || absolute > count as i64 {
        return Err(parse_error(
            path,
            ln,
            format!("face: {name} {k} out of range ({count} {items} defined before this line)"),
        ));
    }
    Ok(absolute)
}

/// The OBJ text's statements: each with its first line's number (1-based), its text with
/// continuation lines joined (a line ending in `\\` goes on in the next, as the OBJ
/// specification allows), and how many more lines it took.
fn logical_lines(text: &str) -> impl Iterator<Item = (usize, std::borrow::Cow<'_, str>, usize)> {
    let mut lines = text.lines().enumerate();
    std::iter::from_fn(move || {
        let (i, first) = lines.next()?;
        let Some(head) = first.trim_end().strip_suffix('\\') else {
            return Some((i + 1, std::borrow::Cow::Borrowed(first), 0));
        };
        let (mut joined, mut continued) = (head.to_string(), 0);
        for (_, next) in lines.by_ref() {
            continued += 1;
            joined.push(' ');
            match next.trim_end().strip_suffix('\\') {
                Some(more) => joined.push_str(more),
                None => {
                    joined.push_str(next);
                    break;
                }
            }
        }
        Some((i + 1, std::borrow::Cow::Owned(joined), continued))
    })
}

/// Checks every OBJ statement the loader uses and produces the normalised copy for `tobj`
/// (see the module documentation). The first offending line is an [`Error::Parse`].
fn scan_obj(path: &Path, text: &str) -> Result<ObjScan> {
    let mut out = String::with_capacity(text.len());
    let mut usemtl = Vec::new();
    let mut mtllib_lines = Vec::new();
    let mut faces = Vec::new();
    let mut face_uvs = Vec::new();
    let mut uvs: Vec<glam::DVec2> = Vec::new();
    let mut camera = CameraLine::default();
    let mut vertices = 0usize;
    for (ln, joined, continued) in logical_lines(text) {
        let line = joined.trim();
        let mut words = line.split_whitespace();
        let keyword = words.next().unwrap_or("");
        let rest: Vec<&str> = words.collect();
        match keyword {
            "v" => {
                if rest.len() < 3 {
                    return Err(parse_error(
                        path,
                        ln,
                        format!("vertex needs 3 coordinates x y z, found {}", rest.len()),
                    ));
                }
                let mut xyz = [0.0; 3];
                for (c, s) in xyz.iter_mut().zip(&rest) {
                    *c = parse_number(path, ln, "vertex", s)?;
                }
                // `v x y z w` is homogeneous (tobj divides by w); 6 values are x y z r g b.
                let keep = if rest.len() == 4 {
                    let w = parse_number(path, ln, "vertex w", rest[3])?;
                    if w == 0.0 {
                        return Err(parse_error(path, ln, "vertex has w = 0"));
                    }
                    xyz = xyz.map(|c| c / w);
                    4
                } else {
                    3
                };
                if xyz.iter().any(|c| !c.is_finite()) {
                    return Err(parse_error(
                        path,
                        ln,
                        format!(
                            "vertex has a non-finite coordinate ({}, {}, {})",
                            xyz[0], xyz[1], xyz[2]
                        ),
                    ));
                }
                out.push_str("v ");
                out.push_str(&rest[..keep].join(" "));
                vertices += 1;
            }
            "f" => {
                if rest.len() < 3 {
                    return Err(parse_error(
                        path,
                        ln,
                        format!("face has {} vertices; at least 3 are needed", rest.len()),
                    ));
                }
                out.push('f');
                faces.push((ln, rest.len()));
                let mut texture_indices = Some(Vec::with_capacity(rest.len()));
                for token in &rest {
                    let index = token.split('/').next().unwrap_or("");
                    match token.split('/').nth(1).filter(|t| !t.is_empty()) {
                        None => texture_indices = None,
                        Some(t) => {
                            let what = ("texture coordinate index", "vt", uvs.len());
                            let absolute = face_index(path, ln, token, t, what)?;
                            if let Some(list) = texture_indices.as_mut() {
                                list.push((absolute - 1) as u32);
                            }
                        }
                    }
                    let absolute = face_index(
                        path,
                        ln,
                        token,
                        index,
                        ("vertex index", "vertices", vertices),
                    )?;
                    out.push(' ');
                    out.push_str(&absolute.to_string());
                }
                face_uvs.push(texture_indices);
            }
            "vt" => {
                // u [v [w]]; v defaults to 0. Texture space is OBJ's: v up from the image's
                // bottom (flipped to the image's rows by the loader).
                if rest.is_empty() {
                    return Err(parse_error(path, ln, "vt needs a coordinate u [v]"));
                }
                let u = parse_number(path, ln, "vt", rest[0])?;
                let v = match rest.get(1) {
                    Some(t) => parse_number(path, ln, "vt", t)?,
                    None => 0.0,
                };
                if !(u.is_finite() && v.is_finite()) {
                    return Err(parse_error(
                        path,
                        ln,
                        format!("vt has a non-finite coordinate ({u}, {v})"),
                    ));
                }
                uvs.push(glam::DVec2::new(f64::from(u), f64::from(v)));
            }
            _ if keyword.starts_with('#') => {
                camera
                    .read(&line[1..], ln)
                    .map_err(|why| parse_error(path, ln, why))?;
            }
            "o" | "g" => out.push_str(line),
            "usemtl" | "mtllib" => {
                // Names may contain spaces: everything after the keyword.
                let name = line[keyword.len()..].trim();
                if name.is_empty() {
                    return Err(parse_error(path, ln, format!("{keyword} without a name")));
                }
                if keyword == "usemtl" {
                    usemtl.push(UseMtl {
                        name: name.to_string(),
                        line: ln,
                        libraries_before: mtllib_lines.len(),
                    });
                } else {
                    mtllib_lines.push(ln);
                }
                out.push_str(keyword);
                out.push(' ');
                out.push_str(name);
            }
            _ => {}
        }
        out.push('\n');
        // The lines a continuation took stay, empty, so that the copy keeps the numbering.
        (0..continued).for_each(|_| out.push('\n'));
    }
    Ok(ObjScan {
        normalised: out,
        usemtl,
        mtllib_lines,
        faces,
        face_uvs,
        uvs,
        camera: camera.camera(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::TestDir;

    /// Writes `obj` (and the MTL files given) into a fresh directory and loads `scene.obj`.
    fn load_text(tag: &str, obj: &str, mtls: &[(&str, &str)]) -> Result<Scene> {
        let dir = TestDir::new(tag);
        for (name, text) in mtls {
            dir.write(name, text);
        }
        Scene::load(&dir.write("scene.obj", obj))
    }

    /// Asserts `e` is an [`Error::Parse`] at `file:line` and its message says so and
    /// contains every string in `words`.
    fn assert_parse(e: &Error, file: &str, line: usize, words: &[&str]) {
        let msg = e.to_string();
        match e {
            Error::Parse { path, line: l, .. } => {
                assert!(path.ends_with(file), "path {path:?} is not {file}: {msg}");
                assert_eq!(*l, line, "{msg}");
            }
            other => panic!("expected Error::Parse at {file}:{line}, got {other:?}"),
        }
        assert!(msg.contains(&format!("{file}:{line}: ")), "{msg}");
        for w in words {
            assert!(msg.contains(w), "'{w}' not in: {msg}");
        }
    }

    const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

    #[test]
    fn coordinates_far_from_the_origin_for_the_scene_s_size_warn() {
        // A unit square 10¹³ units from the origin: double precision rounds there in steps
        // of 2⁻⁹, 0.1 % of its diagonal, which the load says; the same square at the origin,
        // or at map coordinates (5.6·10⁶ away: steps of 10⁻⁹), says nothing.
        let square = |o: f64| {
            format!(
                "v {o} {o} 0\nv {} {o} 0\nv {} {} 0\nv {o} {} 0\nf 1 2 3 4\n",
                o + 1.0,
                o + 1.0,
                o + 1.0,
                o + 1.0
            )
        };
        let far = load_text("obj-far", &square(1e13), &[]).unwrap();
        let said: Vec<&String> = far
            .warnings
            .iter()
            .filter(|w| w.contains("far from the origin"))
            .collect();
        assert_eq!(said.len(), 1, "{:?}", far.warnings);
        assert!(said[0].contains("scene.obj") && said[0].contains("double precision"));
        // 10¹⁷ units away, double precision flattens every face: the error says why.
        let flat = load_text("obj-flat", &square(1e17), &[])
            .unwrap_err()
            .to_string();
        assert!(
            flat.contains("non-zero area") && flat.contains("far from the origin"),
            "{flat}"
        );
        for o in [0.0, 1e3, 5.6e6] {
            let near = load_text("obj-near", &square(o), &[]).unwrap();
            assert!(
                near.warnings
                    .iter()
                    .all(|w| !w.contains("far from the origin")),
                "{o}: {:?}",
                near.warnings
            );
        }
    }

    fn normal(s: &Scene, t: usize) -> DVec3 {
        let [a, b, c] = s.triangles[t].vertices.map(|v| s.positions[v as usize]);
        (b - a).cross(c - a).normalize()
    }

    /// `mtllib a.mtl b.mtl` names two libraries (the OBJ specification's form): both are
    /// read, a missing one is the usual warning; a library whose name has a space is read as
    /// one file.
    #[test]
    fn one_mtllib_line_may_name_several_libraries_or_one_with_spaces() {
        let obj = format!(
            "mtllib a.mtl b.mtl\n{TRIANGLE}v 0 0 1\nusemtl red\nf 1 2 3\nusemtl lamp\nf 1 2 4\n"
        );
        let libraries = [
            ("a.mtl", "newmtl red\nKd 0.6 0.1 0.1\n"),
            ("b.mtl", "newmtl lamp\nKd 0.2\nKe 5 5 5\n"),
        ];
        let s = load_text("obj-two-libraries", &obj, &libraries).unwrap();
        assert_eq!(m_of(&s, "red").reflectance, [0.6, 0.1, 0.1]);
        assert_eq!(m_of(&s, "lamp").emission, [5.0; 3]);
        assert!(
            s.warnings.iter().all(|w| !w.contains("not found")),
            "{:?}",
            s.warnings
        );

        let obj = obj.replace("b.mtl", "gone.mtl");
        let s = load_text("obj-one-library-gone", &obj, &libraries[..1]).unwrap();
        assert_eq!(m_of(&s, "red").reflectance, [0.6, 0.1, 0.1]);
        let w = s.warnings.join("\n");
        assert!(w.contains("gone.mtl (mtllib at line 1)"), "{w}");

        let obj = format!("mtllib my lib.mtl\n{TRIANGLE}usemtl red\nf 1 2 3\n");
        let s = load_text(
            "obj-spaced-library",
            &obj,
            &[("my lib.mtl", libraries[0].1)],
        )
        .unwrap();
        assert_eq!(m_of(&s, "red").reflectance, [0.6, 0.1, 0.1]);
    }

    #[test]
    fn a_byte_order_mark_is_no_part_of_the_first_statement() {
        // Windows tools may begin a UTF-8 file with U+FEFF. Read as part of the first word,
        // it made `mtllib` an unknown keyword: no library was read and `usemtl` failed.
        let obj = format!("\u{feff}mtllib a.mtl\n{TRIANGLE}usemtl lamp\nf 1 2 3\n");
        let mtl = "\u{feff}newmtl lamp\nKd 0.2\nKe 5 5 5\n";
        let s = load_text("obj-bom", &obj, &[("a.mtl", mtl)]).unwrap();
        assert_eq!(m_of(&s, "lamp").emission, [5.0; 3]);
        assert_eq!(m_of(&s, "lamp").reflectance, [0.2; 3]);
        // Only a leading mark is dropped: one inside a line is still an error there.
        let e = load_text(
            "obj-inner-bom",
            &format!("{TRIANGLE}f 1 2 \u{feff}3\n"),
            &[],
        );
        assert!(e.is_err(), "{e:?}");
    }

    fn m_of<'a>(s: &'a Scene, name: &str) -> &'a Material {
        s.materials.iter().find(|m| m.name == name).unwrap()
    }

    #[test]
    fn d_and_tr_make_panes_and_fully_clear_faces_are_left_out() {
        // `d` is the covered share (t = 1 − d) and wins over `Tr` (t = Tr); ρ and Le stay the
        // material's. A fully clear material's faces are left out with a warning; a glassy
        // material that lets light through is not called "specular only".
        let mtl = "newmtl wall\nKd 0.5\n\
                   newmtl glass\nKd 0 0 0\nKs 0.9\nd 0.25\n\
                   newmtl tinted\nKd 0.4\nTr 0.3\n\
                   newmtl both\nKd 0.4\nd 0.8\nTr 0.9\n\
                   newmtl air\nKd 0.5\nd 0\n";
        let obj = format!(
            "mtllib m.mtl\n{TRIANGLE}v 0 0 1\nv 1 1 1\nusemtl wall\nf 1 2 3\nusemtl glass\n\
             f 1 2 4\nusemtl tinted\nf 1 3 4\nusemtl both\nf 2 3 4\nusemtl air\nf 2 3 5\n"
        );
        let s = load_text("obj-transparency", &obj, &[("m.mtl", mtl)]).unwrap();
        let m = |name: &str| s.materials.iter().find(|m| m.name == name).unwrap();
        assert_eq!(m("wall").transmittance, 0.0);
        assert!((m("glass").transmittance - 0.75).abs() < 1e-7);
        assert!(
            (m("tinted").transmittance - 0.3).abs() < 1e-7,
            "read from the MTL"
        );
        assert!(
            (m("both").transmittance - 0.2).abs() < 1e-7,
            "d wins over Tr"
        );
        assert_eq!(m("tinted").reflectance, [0.4; 3], "ρ stays the material's");
        assert_eq!(m("air").transmittance, 1.0);
        assert_eq!(s.triangles.len(), 4, "the clear face is left out");
        let w = s.warnings.join("\n");
        assert!(w.contains("left out 1 face") && w.contains("'air'"), "{w}");
        assert!(
            w.contains("partly transparent") && w.contains("'glass'"),
            "{w}"
        );
        assert!(!w.contains("specular only"), "{w}");

        // A share outside [0, 1] is an error at its line.
        let e = load_text(
            "obj-bad-d",
            &format!("mtllib m.mtl\n{TRIANGLE}usemtl a\nf 1 2 3\n"),
            &[("m.mtl", "newmtl a\nKd 0.5\nd 1.5\n")],
        )
        .unwrap_err();
        assert_parse(&e, "m.mtl", 3, &["material 'a': d", "[0, 1]"]);

        // Every material clear: an exporter's inverted convention, read as opaque.
        let mtl = "newmtl a\nKd 0.5\nd 0\nnewmtl b\nKd 0.7\nTr 1\n";
        let obj =
            format!("mtllib m.mtl\n{TRIANGLE}v 0 0 1\nusemtl a\nf 1 2 3\nusemtl b\nf 1 2 4\n");
        let s = load_text("obj-inverted-d", &obj, &[("m.mtl", mtl)]).unwrap();
        assert!(s.materials.iter().all(|m| m.transmittance == 0.0));
        assert_eq!(s.triangles.len(), 2);
        assert!(
            s.warnings.iter().any(|w| w.contains("inverted convention")),
            "{:?}",
            s.warnings
        );
    }

    #[test]
    fn textures_give_their_mean_colour_and_specular_only_materials_say_so() {
        // A 2 × 1 texture: sRGB 188 (linear 0.502886) and 0 in red; 0 and 255 in green;
        // 255 in blue. Mean linear colour (0.251443, 0.5, 1), times Kd 0.8 0.5 1.
        let dir = TestDir::new("obj-texture");
        let mut img = image::RgbImage::new(2, 1);
        img.put_pixel(0, 0, image::Rgb([188, 0, 255]));
        img.put_pixel(1, 0, image::Rgb([0, 255, 255]));
        std::fs::create_dir_all(dir.path().join("maps")).unwrap();
        img.save(dir.path().join("maps/brick.png")).unwrap();
        dir.write(
            "m.mtl",
            "newmtl brick\nKd 0.8 0.5 1\nmap_Kd -s 1 1 1 maps\\brick.png\n\
             newmtl plain\nmap_Kd maps/brick.png\n\
             newmtl lost\nKd 0.3\nmap_Kd nowhere.png\n\
             newmtl mirror\nKd 0 0 0\nKs 0.9 0.9 0.9\n\
             newmtl glossy\nKd 0.4\nKs 0.5\n\
             newmtl lamp\nKe 1 1 1\nKd 0.5\n",
        );
        let obj = format!(
            "mtllib m.mtl\n{TRIANGLE}v 0 0 1\nusemtl brick\nf 1 2 3\nusemtl plain\nf 1 2 4\n\
             usemtl lost\nf 1 3 4\nusemtl mirror\nf 2 3 4\nusemtl glossy\nf 1 4 2\n\
             usemtl lamp\nf 1 4 3\n"
        );
        let s = Scene::load(&dir.write("scene.obj", &obj)).unwrap();
        let rho = |name: &str| {
            s.materials
                .iter()
                .find(|m| m.name == name)
                .unwrap()
                .reflectance
        };
        let mean = [0.502_886 / 2.0, 0.5, 1.0];
        let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-5);
        // The backslash path (as Windows exporters write it) and the options before it.
        assert!(
            close(rho("brick"), [0.8 * mean[0], 0.5 * mean[1], 1.0]),
            "{:?}",
            rho("brick")
        );
        // No Kd: the texture's mean alone, and no "has no Kd" warning.
        assert!(close(rho("plain"), mean), "{:?}", rho("plain"));
        assert!(close(rho("lost"), [0.3; 3]), "unreadable texture: Kd alone");
        let w = s.warnings.join("\n");
        assert!(!w.contains("has no Kd"), "{w}");
        assert!(
            w.contains("material 'lost': its texture") && w.contains("nowhere.png"),
            "{w}"
        );
        assert!(
            w.contains("2 materials with a texture") && w.contains("'brick', 'plain'"),
            "{w}"
        );
        // Specular only: said once, naming it; a glossy material with a diffuse part is not.
        assert!(
            w.contains("1 material is specular only") && w.contains("'mirror'"),
            "{w}"
        );
        assert!(!w.contains("'glossy'"), "{w}");
        let about_materials = s.warnings.iter().filter(|w| !w.contains("winding")).count();
        assert_eq!(about_materials, 3, "{w}");
        assert!(w.contains("m.mtl:8"), "the line of its map_Kd: {w}");
    }

    #[test]
    fn texture_coordinates_vary_rho_per_patch() {
        // A 16 × 16 texture, its left half red and its right half green (sRGB 255: linear 1),
        // on a unit quad whose vt put the image's left at x = 0 (a quad line: fan-triangulated)
        // and, in a second copy, mirrored (u = 1 at x = 0). OBJ's v counts up from the bottom
        // row; the image is split left/right, so only u matters here.
        let dir = TestDir::new("obj-uv");
        let img = image::RgbImage::from_fn(16, 16, |x, _| {
            if x < 8 {
                image::Rgb([255, 0, 0])
            } else {
                image::Rgb([0, 255, 0])
            }
        });
        img.save(dir.path().join("halves.png")).unwrap();
        dir.write(
            "m.mtl",
            "newmtl halves\nKd 0.8 0.8 0.8\nmap_Kd halves.png\n",
        );
        let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                   v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
                   vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl halves\n\
                   f 1/1 2/2 3/3 4/4\nf 5/2 6/1 7/4 8/3\n";
        let s = Scene::load(&dir.write("uv.obj", obj)).unwrap();
        assert_eq!(s.textures.len(), 1);
        assert!(s.triangles.iter().all(|t| t.uv != crate::scene::NO_UV));
        let p = crate::mesh::subdivide(&s, 0.13, 0.0).unwrap();
        let mut area = [0.0; 2];
        let mut weighted = [[0.0; 3]; 2];
        let mut sides = [0; 2];
        for i in 0..p.len() {
            let c = p.centroid[i];
            let z = c.z.round() as usize;
            let rho = p.reflectance[i];
            // Patches clear of the middle line and of the edges (bilinear lookups blend within
            // a texel of the middle, and wrap round at the edges, as a tiled texture does):
            // the colour under them, times Kd; the mirrored copy the other way round.
            let (left, right) = (c.x > 0.15 && c.x < 0.4, c.x > 0.6 && c.x < 0.85);
            let red_side = (left && z == 0) || (right && z == 1);
            let green_side = (right && z == 0) || (left && z == 1);
            if red_side {
                assert!(rho[0] > 0.79 && rho[1] < 0.01, "{c}: {rho:?}");
                sides[0] += 1;
            }
            if green_side {
                assert!(rho[1] > 0.79 && rho[0] < 0.01, "{c}: {rho:?}");
                sides[1] += 1;
            }
            area[z] += p.area[i];
            for k in 0..3 {
                weighted[z][k] += p.area[i] * rho[k];
            }
        }
        assert!(sides[0] > 20 && sides[1] > 20, "{sides:?}");
        // Each face covers the texture once: its patches' ρ average, by area, to the
        // material's ρ = Kd × the mean (0.4, 0.4, 0), to the 16-sample rule's error at the
        // middle line (patches of 0.13 straddling it: a few per cent of their share).
        for z in 0..2 {
            let mean = weighted[z].map(|w| w / area[z]);
            let material = s.materials[0].reflectance;
            for k in 0..3 {
                assert!(
                    (mean[k] - material[k]).abs() < 0.01,
                    "{mean:?} vs {material:?}"
                );
            }
        }
        // A reflectance set by hand is uniform again.
        let mut plain = s.clone();
        plain
            .apply_overrides(&[crate::scene::Override {
                material: "halves".into(),
                property: crate::scene::Property::Reflectance,
                value: [0.3; 3],
            }])
            .unwrap();
        let q = crate::mesh::subdivide(&plain, 0.13, 0.0).unwrap();
        assert!(q.reflectance.iter().all(|r| *r == [0.3; 3]));
    }

    #[test]
    fn bad_texture_coordinates_are_errors_at_their_line() {
        let dir = TestDir::new("obj-bad-vt");
        for (obj, wanted) in [
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n",
                "uv.obj:5: face: texture coordinate index 2 out of range (1 vt",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt x 0\nf 1 2 3\n",
                "uv.obj:4: vt: malformed number 'x'",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt\nf 1 2 3\n",
                "uv.obj:4: vt needs a coordinate",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/0 2/1 3/1\n",
                "uv.obj:5: face: texture coordinate index 0",
            ),
        ] {
            let e = Scene::load(&dir.write("uv.obj", obj))
                .unwrap_err()
                .to_string();
            assert!(e.contains(wanted), "{e}");
        }
        // Texture coordinates without a texture, or on some corners only: ρ is the material's.
        let s = Scene::load(&dir.write(
            "uv.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 2/1 4 3\n",
        ))
        .unwrap();
        assert!(s.triangles.iter().all(|t| t.uv == crate::scene::NO_UV));
    }

    #[test]
    fn cornell_box_loads_with_inward_normals() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/cornell_box.obj");
        let s = Scene::load(&path).unwrap();
        assert_eq!(s.triangles.len(), 2 * 16);
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        let names: Vec<&str> = s.materials.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["white", "red", "green", "light"]);
        let light = &s.materials[3];
        assert_eq!(light.emission, [17.0, 12.0, 4.0]);
        assert!(light.reflectance.iter().all(|r| (r - 0.78).abs() < 1e-6));
        let white = &s.materials[0];
        assert!((white.reflectance[0] - 0.725).abs() < 1e-6 && white.emission == [0.0; 3]);
        assert!(s.has_emitters());

        let (lo, hi) = s.bounds();
        assert!(lo.abs_diff_eq(DVec3::ZERO, 1e-4), "{lo}");
        assert!(
            hi.abs_diff_eq(DVec3::new(556.0, 548.8, 559.2), 1e-4),
            "{hi}"
        );
        let total: f64 = (0..s.triangles.len()).map(|t| s.triangle_area(t)).sum();
        assert!(total > 5.0 * 550.0 * 550.0 && total < 8.0 * 560.0 * 560.0);

        // Every front side faces the inside of the room: walls inwards, blocks outwards.
        let near = |x: f64, y: f64| (x - y).abs() < 1e-3;
        let mut block_sides = 0;
        for (t, tri) in s.triangles.iter().enumerate() {
            let p = tri.vertices.map(|v| s.positions[v as usize]);
            let all = |f: &dyn Fn(DVec3) -> bool| p.iter().all(|&q| f(q));
            let n = normal(&s, t);
            let expected = match s.materials[tri.material as usize].name.as_str() {
                "light" => Some(-DVec3::Y),
                "red" => Some(-DVec3::X),
                "green" => Some(DVec3::X),
                _ if all(&|q| q.y == 0.0) => Some(DVec3::Y),
                _ if all(&|q| near(q.y, 548.8)) => Some(-DVec3::Y),
                _ if all(&|q| near(q.z, 559.2)) => Some(-DVec3::Z),
                _ if all(&|q| q.y == 165.0) || all(&|q| q.y == 330.0) => Some(DVec3::Y),
                _ => None,
            };
            match expected {
                Some(d) => assert!(n.dot(d) > 0.99, "triangle {t}: normal {n}, expected {d}"),
                None => {
                    let short = p.iter().all(|q| q.y <= 165.0);
                    let axis = if short {
                        DVec3::new(185.5, 0.0, 169.0)
                    } else {
                        DVec3::new(368.5, 0.0, 351.25)
                    };
                    let centroid = (p[0] + p[1] + p[2]) / 3.0;
                    let out = (centroid - axis) * DVec3::new(1.0, 0.0, 1.0);
                    assert!(n.y.abs() < 1e-9 && n.dot(out) > 0.0, "side {t}: {n}");
                    block_sides += 1;
                }
            }
        }
        assert_eq!(block_sides, 16);
    }

    #[test]
    fn duplicated_corners_are_welded_and_default_material_used() {
        let obj = "o a\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n\
                   o b\nv 1 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nf 5 6 7 8\n";
        let s = load_text("weld", obj, &[]).unwrap();
        assert_eq!(s.triangles.len(), 4);
        assert_eq!(s.positions.len(), 6);
        // Quad b's corners 5 and 8 are quad a's corners 2 and 3.
        assert_eq!(s.triangles[2].vertices[0], s.triangles[0].vertices[1]);
        assert_eq!(s.triangles[3].vertices[2], s.triangles[0].vertices[2]);
        assert_eq!(s.materials, [Scene::default_material()]);
        assert!(s.triangles.iter().all(|t| t.material == 0));
        assert_eq!(s.materials[0].reflectance, [0.5; 3]);
        assert!(!s.has_emitters());
        assert!((normal(&s, 0) - DVec3::Z).length() < 1e-12);
    }

    /// A statement continued over lines ending in `\\` (the OBJ specification's form) is one
    /// statement, and the lines after it keep their numbers in messages.
    #[test]
    fn continued_lines_are_one_statement_and_keep_the_numbering() {
        let dir = TestDir::new("continued");
        let obj = "v 0 0 \\\n 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 \\\n  2 \\\n  3\nf 1 2 4\n";
        let s = Scene::load(&dir.write("scene.obj", obj)).unwrap();
        assert_eq!((s.triangles.len(), s.positions.len()), (2, 4));
        let e = Scene::load(&dir.write("bad.obj", format!("{obj}f 1 2 9\n"))).unwrap_err();
        assert_parse(&e, "bad.obj", 10, &["vertex index 9 out of range"]);
    }

    #[test]
    fn accepts_common_obj_variants() {
        // Uppercase extension, texture/normal indices, negative indices, a polyline `l`
        // (which tobj alone would turn into a triangle), vertex colours, tabs.
        let dir = TestDir::new("variants");
        dir.write(
            "m.mtl",
            "newmtl grey\nKd 0.3\nNs 10\nillum 2\nnewmtl lamp\nKe 1 2 3\n",
        );
        let obj = "mtllib m.mtl\nv 0 0 0 1 0 0\nv 1 0 0 1 0 0\nv 0 1 0 1 0 0\nv 0 0 2 2\n\
                   vt 0 0\nvn 0 0 1\nusemtl\tgrey\nf 1/1/1 2/1/1 3/1/1\nl 1 2 4\n\
                   usemtl lamp\nf -4//1 -3//1 -1//1\n";
        let s = Scene::load(&dir.write("scene.OBJ", obj)).unwrap();
        assert_eq!(s.triangles.len(), 2);
        assert_eq!(s.positions.len(), 4);
        assert!(
            s.positions.contains(&DVec3::new(0.0, 0.0, 1.0)),
            "w divides"
        );
        assert!(s.materials[0]
            .reflectance
            .iter()
            .all(|r| (r - 0.3).abs() < 1e-6));
        assert_eq!(s.materials[1].emission, [1.0, 2.0, 3.0]);
        assert_eq!(s.materials[1].reflectance, [0.5; 3]);
        // The two faces both run 1 → 2: a (true) winding warning, naming their lines.
        assert_eq!(s.warnings.len(), 2, "{:?}", s.warnings);
        assert!(
            s.warnings[0].contains("'lamp' has no Kd"),
            "{:?}",
            s.warnings
        );
        assert!(
            s.warnings[1].contains("inconsistent winding")
                && s.warnings[1].contains("scene.OBJ:9) and 1 (")
                && s.warnings[1].contains("scene.OBJ:12)"),
            "{:?}",
            s.warnings
        );
        assert_eq!(s.triangles[1].material, 1);
        assert!(s.has_emitters());
    }

    #[test]
    fn zero_area_triangles_are_dropped_with_a_warning() {
        let obj = format!("{TRIANGLE}v 2 0 0\nf 1 2 3\nf 1 2 4\nf 1 1 2\n");
        let s = load_text("zero", &obj, &[]).unwrap();
        assert_eq!(s.triangles.len(), 1);
        assert_eq!(s.positions.len(), 3);
        assert_eq!(s.warnings.len(), 1);
        assert!(s.warnings[0].contains("skipped 2 zero-area triangles"));

        let e = load_text("allzero", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", &[]).unwrap_err();
        assert!(matches!(e, Error::Input { .. }), "{e:?}");
        assert!(
            e.to_string().contains("no triangles with non-zero area"),
            "{e}"
        );
    }

    #[test]
    fn file_level_errors_name_the_path() {
        let dir = TestDir::new("files");
        let missing = dir.path().join("missing.obj");
        let e = Scene::load(&missing).unwrap_err();
        assert!(
            matches!(&e, Error::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound)
        );
        assert!(e.to_string().contains("missing.obj"), "{e}");

        let e = Scene::load(dir.path()).unwrap_err();
        assert!(matches!(e, Error::Input { .. }), "{e:?}");
        assert!(
            e.to_string().contains(&dir.path().display().to_string()),
            "{e}"
        );
        let sub = dir.path().join("dir.obj");
        std::fs::create_dir(&sub).unwrap();
        assert!(matches!(load(&sub).unwrap_err(), Error::Io { .. }));

        let e = Scene::load(&dir.write("scene.stl", TRIANGLE)).unwrap_err();
        assert!(matches!(e, Error::Input { .. }), "{e:?}");
        assert!(e.to_string().contains("scene.stl"), "{e}");

        let e = load_text("empty", TRIANGLE, &[]).unwrap_err();
        assert!(matches!(e, Error::Input { .. }), "{e:?}");
        assert!(e.to_string().contains("scene.obj") && e.to_string().contains("empty"));
    }

    #[test]
    fn obj_syntax_errors_give_the_line() {
        let cases: [(&str, usize, &str); 10] = [
            ("v 0 0 0\nv 1 abc 0\n", 2, "malformed number 'abc'"),
            ("v 0 0\n", 1, "3 coordinates"),
            ("v 0 0 0\nv nan 0 0\n", 2, "non-finite"),
            (
                "# big\nv 1e39 0 0\n",
                2,
                "'1e39' is beyond single precision",
            ),
            ("v 0 0 0\nv inf 0 0\n", 2, "non-finite"),
            ("v 0 0 0 0\n", 1, "w = 0"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 4\n",
                5,
                "vertex index 4 out of range",
            ),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4, "index 0"),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", 4, "at least 3"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 x 3\n",
                4,
                "malformed vertex 'x'",
            ),
        ];
        for (obj, line, words) in cases {
            let e = load_text("syntax", obj, &[]).unwrap_err();
            assert_parse(&e, "scene.obj", line, &[words]);
        }
        let e = load_text("neg", &format!("{TRIANGLE}f -1 -2 -4\n"), &[]).unwrap_err();
        assert_parse(&e, "scene.obj", 4, &["vertex index -4 out of range"]);
    }

    #[test]
    fn material_reference_errors_give_the_obj_line() {
        let mtl = [("m.mtl", "newmtl grey\nKd 0.5 0.5 0.5\n")];
        let obj = format!("mtllib m.mtl\n{TRIANGLE}usemtl nosuch\nf 1 2 3\n");
        let e = load_text("undef", &obj, &mtl).unwrap_err();
        assert_parse(&e, "scene.obj", 5, &["nosuch", "not defined"]);

        let obj = format!("{TRIANGLE}usemtl grey\nf 1 2 3\nmtllib m.mtl\n");
        let e = load_text("late", &obj, &mtl).unwrap_err();
        assert_parse(&e, "scene.obj", 4, &["grey", "no mtllib before this line"]);

        // A missing library is a warning naming it and its line, and the faces of materials
        // only it could define get the default material, even when another library loaded;
        // the other library's materials are its own.
        let obj = format!(
            "mtllib m.mtl\nmtllib gone.mtl\n{TRIANGLE}v 0 0 1\nusemtl lost\nf 1 2 3\n\
             usemtl grey\nf 1 2 4\n"
        );
        let s = load_text("missing", &obj, &mtl).unwrap();
        let w = s.warnings.join("\n");
        assert!(
            w.contains("gone.mtl (mtllib at line 2)") && w.contains("'lost'"),
            "{w}"
        );
        let by_name = |t: usize| s.materials[s.triangles[t].material as usize].name.as_str();
        assert_eq!((by_name(0), by_name(1)), ("default", "grey"));
        // A library that is there but unreadable is still an error at its line.
        let dir = TestDir::new("unreadable");
        dir.write("bad.mtl", [0xff, 0xfe, 0x00]);
        let e = Scene::load(&dir.write("scene.obj", format!("mtllib bad.mtl\n{TRIANGLE}")))
            .unwrap_err();
        assert_parse(
            &e,
            "scene.obj",
            1,
            &["bad.mtl", "cannot read material library"],
        );

        let e = load_text("nomtl", &format!("usemtl\n{TRIANGLE}"), &[]).unwrap_err();
        assert_parse(&e, "scene.obj", 1, &["usemtl without a name"]);
    }

    #[test]
    fn material_value_errors_give_the_mtl_line_and_material() {
        let cases = [
            (
                "newmtl a\nKd 0.5 0.5 0.5\n\nnewmtl hot\nKd 1.5 0.5 0.5\n",
                5,
                "hot",
                "[0, 1]",
            ),
            ("newmtl neg\nKd 0.5 0.5 0.5\nKe 1 -2 3\n", 3, "neg", "≥ 0"),
            ("newmtl n\nKd NaN 0.5 0.5\n", 2, "n", "[0, 1]"),
            (
                "newmtl big\nKe 1e39 0 0\n",
                2,
                "big",
                "'1e39' is beyond single precision",
            ),
            ("newmtl inf\nKe inf 0 0\n", 2, "inf", "finite"),
            ("newmtl two\nKd 0.5 0.5\n", 2, "two", "expected 3 numbers"),
            ("newmtl sp\nKd spectral file.rfl\n", 2, "sp", "spectral"),
            (
                "newmtl bad\nKd 0.5 x 0.5\n",
                2,
                "bad",
                "malformed number 'x'",
            ),
            ("newmtl\n", 1, "newmtl", "without a material name"),
        ];
        for (mtl, line, material, words) in cases {
            let obj = format!("mtllib m.mtl\n{TRIANGLE}usemtl {material}\nf 1 2 3\n");
            let e = load_text("mtlvalues", &obj, &[("m.mtl", mtl)]).unwrap_err();
            assert_parse(&e, "m.mtl", line, &[material, words]);
        }
    }
}
