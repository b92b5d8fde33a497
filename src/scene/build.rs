//! How every scene is finished, whatever made it (a file loader in [`crate::io`] or the
//! [`SceneBuilder`] of procedural scenes): vertex welding, dropping zero-area triangles,
//! [`Scene::validate`], and the warnings about likely modelling mistakes ([`super::checks`]).

use std::collections::HashMap;
use std::path::PathBuf;

use glam::DVec3;
use serde::Serialize;

use super::{
    checks, source_path, Material, Scene, SceneTriangle, Texture, UvMap, NO_UV, ZERO_AREA_RELATIVE,
};
use crate::{Error, Result};

/// Finishes a scene from raw loader or builder output, in order:
/// 1. [`Scene::validate`] the raw data (so the steps below can index freely);
/// 2. weld positions that are bitwise identical (−0.0 counted as +0.0), first occurrence
///    wins, so the result does not depend on hashing;
/// 3. drop triangles with |(b − a) × (c − a)| ≤ [`ZERO_AREA_RELATIVE`] · d², d the
///    bounding-box diagonal of the used positions, with one counted warning;
/// 4. merge duplicate faces: a triangle with the same three (welded) vertices in the same
///    cyclic order as an earlier one, so facing the same way, is dropped and the earlier one
///    kept, with one warning naming both (McGuire's Cornell box repeats a side face of each
///    block as its "bottom": kept, the light it exchanges would be counted twice and its
///    rows would sum past 1); the same vertices wound the other way are a surface's two
///    sides and both are kept;
/// 5. drop positions no triangle uses (keeping their order) and validate again;
/// 6. warn (keeping every face) about coincident overlapping faces and inconsistent winding
///    between neighbours ([`checks`]), naming the triangles and, when `face_lines` gives the
///    source line of every raw triangle, the file and line of their faces.
///
/// `warnings` and `details` are the loader's own (details: the full lists of its list-type
/// warnings, [`WarningDetail`]); every warning added here that lists things names at most
/// [`MAX_LISTED_PAIRS`] of them and puts all of them in [`Scene::warning_details`].
pub(crate) fn finish(
    source: Option<PathBuf>,
    positions: Vec<DVec3>,
    triangles: Vec<SceneTriangle>,
    materials: Vec<Material>,
    (textures, uv_maps): (Vec<Texture>, Vec<UvMap>),
    (mut warnings, mut details): (Vec<String>, Vec<WarningDetail>),
    face_lines: Option<Vec<usize>>,
) -> Result<Scene> {
    let face_lines = face_lines.filter(|l| l.len() == triangles.len());
    if positions.len() > u32::MAX as usize {
        return Err(Error::Input {
            path: source_path(&source),
            message: format!(
                "{} vertices: more than the supported {}",
                positions.len(),
                u32::MAX
            ),
        });
    }
    if triangles.is_empty() {
        // What loading passed over is likely why (a Mitsuba shape type not read).
        let mut message = String::from("the mesh is empty: no triangles");
        if !warnings.is_empty() {
            message += &format!(" (while loading: {})", warnings.join("; "));
        }
        return Err(Error::Input {
            path: source_path(&source),
            message,
        });
    }
    let raw = Scene {
        source,
        positions,
        triangles,
        materials,
        warnings: Vec::new(),
        warning_details: Vec::new(),
        twin: Vec::new(),
        camera: None,
        lights: Vec::new(),
        sun: None,
        sky: None,
        textures,
        uv_maps,
    };
    raw.validate()?;
    let Scene {
        source,
        positions,
        triangles,
        materials,
        textures,
        uv_maps,
        ..
    } = raw;

    // 2. Weld: `canon[i]` is the first index holding the same position as `i`.
    let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(positions.len());
    let canon: Vec<u32> = positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            // Adding +0.0 turns −0.0 into +0.0 and leaves every other value unchanged.
            let key = (*p + DVec3::ZERO).to_array().map(f64::to_bits);
            *first.entry(key).or_insert(i as u32)
        })
        .collect();
    let triangles: Vec<SceneTriangle> = triangles
        .into_iter()
        .map(|t| SceneTriangle {
            vertices: t.vertices.map(|v| canon[v as usize]),
            ..t
        })
        .collect();

    // 3. Drop zero-area triangles, relative to the scale of the used geometry.
    let (lo, hi) = crate::geometry::bounds(
        triangles
            .iter()
            .flat_map(|t| t.vertices)
            .map(|v| positions[v as usize]),
    );
    let threshold = ZERO_AREA_RELATIVE * (hi - lo).length_squared();
    let total = triangles.len();
    let keep: Vec<bool> = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.vertices.map(|v| positions[v as usize]);
            (b - a).cross(c - a).length() > threshold
        })
        .collect();
    let (mut triangles, mut face_lines) = retain(triangles, face_lines, &keep);
    let dropped = total - triangles.len();
    if triangles.is_empty() {
        return Err(Error::Input {
            path: source_path(&source),
            message: format!("no triangles with non-zero area (all {total} are degenerate)"),
        });
    }
    if dropped > 0 {
        warnings.push(format!(
            "skipped {dropped} zero-area triangle{} (|e1 × e2| ≤ {ZERO_AREA_RELATIVE:e} × bounding-box diagonal²)",
            if dropped == 1 { "" } else { "s" }
        ));
    }

    // 3b. Leave out the faces of fully clear materials (t = 1): they pass all light and
    // reflect none, so they add nothing but rays (Material::transmittance).
    let clear: Vec<bool> = triangles
        .iter()
        .map(|t| {
            materials
                .get(t.material as usize)
                .is_some_and(|m| m.transmittance >= 1.0)
        })
        .collect();
    let n_clear = clear.iter().filter(|&&c| c).count();
    if n_clear > 0 {
        let mut names: Vec<String> = Vec::new();
        for (t, _) in triangles.iter().zip(&clear).filter(|(_, &c)| c) {
            let name = &materials[t.material as usize].name;
            if !names.contains(name) {
                names.push(name.clone());
            }
        }
        let keep: Vec<bool> = clear.iter().map(|&c| !c).collect();
        let (kept, lines) = retain(triangles, face_lines, &keep);
        if kept.is_empty() {
            return Err(Error::Input {
                path: source_path(&source),
                message: format!(
                    "every face is fully transparent (transmittance 1: MTL `d 0` or `Tr 1`, \
                     glTF alpha 0 or transmission 1): nothing to bake ({})",
                    listed_names(&names)
                ),
            });
        }
        warnings.push(format!(
            "left out {n_clear} face{} of fully transparent material{} (transmittance 1: \
             they let all light through and reflect none): {}",
            if n_clear == 1 { "" } else { "s" },
            if names.len() == 1 { "" } else { "s" },
            listed_names_all("clear_materials", &names, &mut details)
        ));
        triangles = kept;
        face_lines = lines;
    }
    let transparent: Vec<String> = materials
        .iter()
        .filter(|m| m.transmittance > 0.0 && m.transmittance < 1.0)
        .map(|m| m.name.clone())
        .collect();
    if triangles.iter().any(|t| {
        let m = &materials[t.material as usize];
        m.transmittance > 0.0
    }) {
        warnings.push(format!(
            "{} partly transparent material{} (MTL `d` < 1 or `Tr` > 0, glTF alpha blending or \
             transmission): the share t passes, straight and untinted; ρ and Le are the \
             covered share's: {}",
            transparent.len(),
            if transparent.len() == 1 { "" } else { "s" },
            listed_names_all("partly_transparent_materials", &transparent, &mut details)
        ));
    }

    // 4. Merge duplicates: the same vertices in the same cyclic order as an earlier face.
    let mut seen: HashMap<[u32; 3], usize> = HashMap::with_capacity(triangles.len());
    let mut duplicates: Vec<(usize, usize)> = Vec::new();
    let keep: Vec<bool> = triangles
        .iter()
        .enumerate()
        .map(|(t, tri)| {
            let v = tri.vertices;
            let r = (0..3).min_by_key(|&k| v[k]).unwrap_or(0);
            let key = [v[r], v[(r + 1) % 3], v[(r + 2) % 3]];
            match seen.get(&key) {
                Some(&first) => {
                    duplicates.push((first, t));
                    false
                }
                None => {
                    seen.insert(key, t);
                    true
                }
            }
        })
        .collect();
    if !duplicates.is_empty() {
        let name = |t: usize| face_name(t, &face_lines, &source);
        let n = duplicates.len();
        let all = duplicates
            .iter()
            .map(|&(kept, dropped)| format!("kept {} and dropped {}", name(kept), name(dropped)))
            .collect();
        warnings.push(format!(
            "{n} duplicate face{} (the same vertices, facing the same way, as an earlier \
             face) merged into the earlier one, so their light is counted once: {}",
            if n == 1 { "" } else { "s" },
            listed_all("duplicate_faces", all, "; ", &mut details)
        ));
    }
    let (triangles, face_lines) = retain(triangles, face_lines, &keep);

    // 5. Compact: keep used positions in their original order.
    let mut new_index = vec![u32::MAX; positions.len()];
    for t in &triangles {
        for &v in &t.vertices {
            new_index[v as usize] = 0;
        }
    }
    let mut kept = Vec::new();
    for (i, p) in positions.iter().enumerate() {
        if new_index[i] == 0 {
            new_index[i] = kept.len() as u32;
            kept.push(*p);
        }
    }
    let triangles = triangles
        .into_iter()
        .map(|t| SceneTriangle {
            vertices: t.vertices.map(|v| new_index[v as usize]),
            ..t
        })
        .collect();

    let mut scene = Scene {
        source,
        positions: kept,
        triangles,
        materials,
        warnings,
        warning_details: details,
        twin: Vec::new(),
        camera: None,
        lights: Vec::new(),
        sun: None,
        sky: None,
        textures,
        uv_maps,
    };
    scene.validate()?;

    // 6. Likely modelling mistakes: warn, keep every face.
    let diagonal = (hi - lo).length();
    let name = |t: usize| face_name(t, &face_lines, &scene.source);
    let mut details = std::mem::take(&mut scene.warning_details);
    let mut list = |kind: &'static str, pairs: &[(usize, usize)]| {
        let all = pairs
            .iter()
            .map(|&(i, j)| format!("triangles {} and {}", name(i), name(j)))
            .collect();
        listed_all(kind, all, "; ", &mut details)
    };
    let coincident = checks::coincident_faces(&scene.positions, &scene.triangles, diagonal);
    if !coincident.is_empty() {
        let n = coincident.len();
        scene.warnings.push(format!(
            "{n} pair{} of coincident overlapping faces (same plane, same facing: z-fighting): \
             {}. Both faces of each pair are kept, so light exchanged with the overlap is \
             counted for both; move one face off the plane or cut a hole for it",
            if n == 1 { "" } else { "s" },
            list("z_fighting", &coincident)
        ));
    }
    let flipped = checks::inconsistent_winding(&scene.triangles);
    if !flipped.is_empty() {
        let n = flipped.len();
        scene.warnings.push(format!(
            "{n} pair{} of neighbouring faces with inconsistent winding (a shared edge runs \
             the same way in both, so one of them faces the wrong way): {}. Faces emit and \
             reflect on their counter-clockwise side only",
            if n == 1 { "" } else { "s" },
            list("inconsistent_winding", &flipped)
        ));
    }
    scene.warning_details = details;
    Ok(scene)
}

/// Warnings list at most this many of what they name (pairs of faces, faces, materials) and
/// count the rest; the full list is in the report ([`WarningDetail`]).
pub const MAX_LISTED_PAIRS: usize = 5;

/// The full list behind one warning that names things (pairs of faces, materials): what a
/// warning line shows at most [`MAX_LISTED_PAIRS`] of. `--report` writes every one of them
/// (`warning_details`), and `radiosity info --json` too.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct WarningDetail {
    /// What is listed, in snake case: `z_fighting` (pairs of coincident overlapping faces),
    /// `inconsistent_winding` (pairs of neighbours), `duplicate_faces` (kept and dropped
    /// faces), `clear_materials`, `textured_materials`, … (material names).
    pub kind: &'static str,
    /// How many there are: the length of `items`, the number the warning gives.
    pub count: usize,
    /// Every one, worded as in the warning, in the warning's (deterministic) order.
    pub items: Vec<String>,
}

/// `items` joined by `separator`, at most [`MAX_LISTED_PAIRS`] of them and then "… N more",
/// followed by `more`.
fn listed_with(
    items: impl ExactSizeIterator<Item = String>,
    separator: &str,
    more: &str,
) -> String {
    let n = items.len();
    let mut shown: Vec<String> = items.take(MAX_LISTED_PAIRS).collect();
    if n > MAX_LISTED_PAIRS {
        shown.push(format!("… {} more{more}", n - MAX_LISTED_PAIRS));
    }
    shown.join(separator)
}

/// `items` joined by `separator`, at most [`MAX_LISTED_PAIRS`] of them and then "… N more":
/// how an error message lists what it names (an error has no report to hold the rest).
pub(crate) fn listed(items: impl ExactSizeIterator<Item = String>, separator: &str) -> String {
    listed_with(items, separator, "")
}

/// How every warning lists what it names: at most [`MAX_LISTED_PAIRS`] of `items`, then
/// "… N more (all in --report)"; all of them go to `details` as a [`WarningDetail`] of
/// `kind`.
pub(crate) fn listed_all(
    kind: &'static str,
    items: Vec<String>,
    separator: &str,
    details: &mut Vec<WarningDetail>,
) -> String {
    let shown = listed_with(items.iter().cloned(), separator, " (all in --report)");
    details.push(WarningDetail {
        kind,
        count: items.len(),
        items,
    });
    shown
}

/// Names (of materials) as an error lists them: quoted, at most [`MAX_LISTED_PAIRS`].
pub(crate) fn listed_names(names: &[String]) -> String {
    listed(names.iter().map(|n| format!("'{n}'")), ", ")
}

/// Names (of materials) as a warning lists them: quoted, at most [`MAX_LISTED_PAIRS`], all of
/// them in `details` ([`listed_all`]).
pub(crate) fn listed_names_all(
    kind: &'static str,
    names: &[String],
    details: &mut Vec<WarningDetail>,
) -> String {
    let quoted = names.iter().map(|n| format!("'{n}'")).collect();
    listed_all(kind, quoted, ", ", details)
}

/// Triangle `t` as a warning names it: with its file and line when the loader gave them.
fn face_name(t: usize, face_lines: &Option<Vec<usize>>, source: &Option<PathBuf>) -> String {
    match (face_lines, source) {
        (Some(lines), Some(path)) => format!("{t} ({}:{})", path.display(), lines[t]),
        _ => t.to_string(),
    }
}

/// The triangles (and their source lines, when known) whose `keep` is true, in order.
fn retain(
    triangles: Vec<SceneTriangle>,
    face_lines: Option<Vec<usize>>,
    keep: &[bool],
) -> (Vec<SceneTriangle>, Option<Vec<usize>>) {
    fn kept<T>(v: Vec<T>, keep: &[bool]) -> Vec<T> {
        v.into_iter()
            .zip(keep)
            .filter_map(|(x, &k)| k.then_some(x))
            .collect()
    }
    (kept(triangles, keep), face_lines.map(|l| kept(l, keep)))
}

/// Builder for procedural scenes used by the verification suite and tests.
///
/// Indices returned by [`SceneBuilder::vertex`] and [`SceneBuilder::material`] are not
/// checked until [`SceneBuilder::build`], which runs the same welding, zero-area clean-up
/// and validation as loading a file.
#[derive(Debug, Default, Clone)]
pub struct SceneBuilder {
    positions: Vec<DVec3>,
    triangles: Vec<SceneTriangle>,
    materials: Vec<Material>,
}

impl SceneBuilder {
    /// An empty builder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a material (ρ per RGB channel in [0, 1], Le in W·sr⁻¹·m⁻² per channel, ≥ 0)
    /// and returns its index. Values are checked by [`SceneBuilder::build`].
    pub fn material(&mut self, name: &str, reflectance: [f64; 3], emission: [f64; 3]) -> u32 {
        self.materials
            .push(Material::opaque(name, reflectance, emission));
        (self.materials.len() - 1) as u32
    }

    /// Makes material `material` (an index [`SceneBuilder::material`] returned) let the share
    /// `t` ∈ [0, 1] of the light through ([`Material::transmittance`]).
    ///
    /// # Panics
    /// If `material` is not a material of this builder.
    pub fn set_transmittance(&mut self, material: u32, t: f64) {
        let m = &mut self.materials[material as usize];
        *m = m.clone().with_transmittance(t);
    }

    /// Adds a vertex and returns its index.
    pub fn vertex(&mut self, p: DVec3) -> u32 {
        self.positions.push(p);
        (self.positions.len() - 1) as u32
    }

    /// Adds a triangle with vertices counter-clockwise seen from its front side.
    pub fn triangle(&mut self, v: [u32; 3], material: u32) {
        self.triangles.push(SceneTriangle {
            vertices: v,
            material,
            uv: NO_UV,
        });
    }

    /// Triangles added so far (before [`SceneBuilder::build`] drops any).
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Planar quad a, b, c, d counter-clockwise seen from the front, as 2 triangles
    /// (a, b, c), (a, c, d), sharing vertices.
    pub fn quad(&mut self, corners: [DVec3; 4], material: u32) {
        let [a, b, c, d] = corners.map(|p| self.vertex(p));
        self.triangle([a, b, c], material);
        self.triangle([a, c, d], material);
    }

    /// Welds, drops zero-area triangles (with a warning) and validates; see the module docs.
    pub fn build(self) -> Result<Scene> {
        finish(
            None,
            self.positions,
            self.triangles,
            self.materials,
            (Vec::new(), Vec::new()),
            (Vec::new(), Vec::new()),
            None,
        )
    }
}
