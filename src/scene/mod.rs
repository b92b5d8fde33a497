//! The scene: triangles, their vertex positions and their Lambertian materials, as handed
//! from the loaders to the patcher. This module owns the types, the shared clean-up every
//! scene goes through (vertex welding, dropping zero-area triangles, [`Scene::validate`]),
//! and [`SceneBuilder`] for procedural scenes; file formats live in submodules ([`obj`],
//! [`ply`]); material overrides in [`overrides`].
//! It does not subdivide, compute normals for shading, or know about radiometry beyond
//! checking that reflectances and emissions are physically meaningful.
//!
//! Invariants of a [`Scene`] returned by [`Scene::load`] or [`SceneBuilder::build`]:
//! every index is in range, every position is finite, no two positions are bitwise equal
//! (welded, so faces that share a corner share its index), every position is used by a
//! triangle, no triangle has (relatively) zero area, every ρ is in [0, 1] and every Le is
//! finite and ≥ 0, and there is at least one triangle. A loaded scene is one-sided
//! ([`Scene::twin`] empty); [`Scene::make_two_sided`] gives faces a back side.
//!
//! # Two-sided scenes
//! Every face is one-sided by default: its front is the counter-clockwise side, light arriving
//! at its back is lost, and its back emits nothing. [`Scene::make_two_sided`] (`--two-sided`)
//! appends, for every triangle, its *twin*: the same three vertices in reverse order with the
//! same material, i.e. the back side as a face of its own with its own radiance. Twins are
//! linked in [`Scene::twin`]; the patcher subdivides a twin exactly like its original
//! ([`crate::mesh::subdivide`]) and the ray caster traces a pair as one surface with two
//! sides ([`crate::visibility`]). A face that already has a reversed face over the same
//! corners in the file is paired with it instead of being doubled (each keeps its material).

pub mod camera;
pub mod checks;
pub mod overrides;

pub use camera::Camera;
pub use overrides::{Override, Property};

use std::collections::HashMap;
use std::path::PathBuf;

use glam::DVec3;

use crate::{Error, Result};

/// "No twin" in [`Scene::twin`] (and [`crate::mesh::Patches::twin`]).
pub const NO_TWIN: u32 = u32::MAX;

/// Triangles whose doubled area |(b − a) × (c − a)| is at most this fraction of the squared
/// bounding-box diagonal are treated as zero-area and dropped. Relative to the scene's
/// scale, so a scene gives the same result in millimetres and in metres.
pub const ZERO_AREA_RELATIVE: f64 = 1e-12;

/// A Lambertian material.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Name as given in the MTL file (or to [`SceneBuilder::material`]).
    pub name: String,
    /// ρ, diffuse reflectance (albedo) per RGB channel, dimensionless, each in [0, 1].
    pub reflectance: [f64; 3],
    /// Le, emitted radiance, W·sr⁻¹·m⁻² per RGB channel, each finite and ≥ 0.
    pub emission: [f64; 3],
}

impl Material {
    /// True if any channel of the emitted radiance is positive.
    pub fn is_emitter(&self) -> bool {
        self.emission.iter().any(|&e| e > 0.0)
    }
}

/// One triangle of the scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SceneTriangle {
    /// Indices into [`Scene::positions`], counter-clockwise seen from the front (emitting /
    /// reflecting) side, so the front normal is (p1 − p0) × (p2 − p0).
    pub vertices: [u32; 3],
    /// Index into [`Scene::materials`].
    pub material: u32,
}

/// A triangle mesh with Lambertian materials; see the module documentation for the
/// invariants a loaded or built scene satisfies.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The file the scene was loaded from; `None` for procedural scenes.
    pub source: Option<PathBuf>,
    /// Vertex positions in the file's length unit (any unit: radiosity is scale-free).
    /// Finite, welded (pairwise bitwise distinct), each used by at least one triangle.
    pub positions: Vec<DVec3>,
    /// The triangles; at least one, none of (relatively) zero area.
    pub triangles: Vec<SceneTriangle>,
    /// Materials referenced by [`SceneTriangle::material`]; may include unused ones
    /// (everything the MTL files defined), in file order.
    pub materials: Vec<Material>,
    /// Human-readable warnings found while loading (e.g. "skipped 3 zero-area triangles").
    pub warnings: Vec<String>,
    /// The other side of each triangle ([`Scene::make_two_sided`]): empty for a one-sided
    /// scene (every loaded or built scene); otherwise one entry per triangle, the index of its
    /// twin or [`NO_TWIN`]. Invariants: `twin[twin[t]] == t`, `twin[t] != t`, and a twin has
    /// the same three vertex indices as its triangle in the opposite winding.
    pub twin: Vec<u32>,
    /// The camera the scene file carries (`# camera: …` in OBJ, `comment camera: …` in a PLY
    /// header; see [`crate::scene::camera`]); pictures use it unless `--camera` is given.
    pub camera: Option<Camera>,
}

impl Scene {
    /// The material faces get when the OBJ file gives them none (no `usemtl` before them):
    /// named "default", ρ = 0.5 in every channel (a mid grey that neither absorbs nor
    /// reflects nearly everything), Le = 0.
    pub fn default_material() -> Material {
        Material {
            name: "default".into(),
            reflectance: [0.5; 3],
            emission: [0.0; 3],
        }
    }

    /// Checks the invariants that make the scene usable: at least one triangle, vertex and
    /// material indices in range, positions finite, ρ in [0, 1], Le finite and ≥ 0.
    /// Errors are [`Error::Input`] on [`Scene::source`] (or `<procedural scene>`) and name
    /// the triangle index or material. Welding and zero-area triangles are not checked here.
    pub fn validate(&self) -> Result<()> {
        let fail = |message: String| Err(self.input_error(message));
        if self.triangles.is_empty() {
            return fail("the scene has no triangles".into());
        }
        for (i, p) in self.positions.iter().enumerate() {
            if !p.is_finite() {
                return fail(format!("vertex {i} has a non-finite position {p}"));
            }
        }
        for (m, mat) in self.materials.iter().enumerate() {
            if mat.reflectance.iter().any(|r| !(0.0..=1.0).contains(r)) {
                return fail(format!(
                    "material '{}' (#{m}): reflectance ρ = {:?} is not in [0, 1]",
                    mat.name, mat.reflectance
                ));
            }
            if mat.emission.iter().any(|e| !e.is_finite() || *e < 0.0) {
                return fail(format!(
                    "material '{}' (#{m}): emission Le = {:?} must be finite and ≥ 0",
                    mat.name, mat.emission
                ));
            }
        }
        let n = self.positions.len();
        for (t, tri) in self.triangles.iter().enumerate() {
            if let Some(v) = tri.vertices.iter().find(|&&v| v as usize >= n) {
                return fail(format!(
                    "triangle {t}: vertex index {v} out of range (the scene has {n} vertices)"
                ));
            }
            if tri.material as usize >= self.materials.len() {
                return fail(format!(
                    "triangle {t}: material index {} out of range (the scene has {} materials)",
                    tri.material,
                    self.materials.len()
                ));
            }
        }
        if !self.twin.is_empty() && self.twin.len() != self.triangles.len() {
            return fail(format!(
                "{} twin entries for {} triangles",
                self.twin.len(),
                self.triangles.len()
            ));
        }
        for (t, &u) in self.twin.iter().enumerate() {
            if u == NO_TWIN {
                continue;
            }
            let reversed = |a: [u32; 3], b: [u32; 3]| {
                (0..3).any(|k| a == [b[k], b[(k + 2) % 3], b[(k + 1) % 3]])
            };
            let ok = (u as usize) < self.triangles.len()
                && u as usize != t
                && self.twin[u as usize] == t as u32
                && reversed(
                    self.triangles[t].vertices,
                    self.triangles[u as usize].vertices,
                );
            if !ok {
                return fail(format!(
                    "triangle {t}: twin {u} is not its reverse over the same corners"
                ));
            }
        }
        Ok(())
    }

    /// True if some triangle has a twin (a back side of its own; see [`Scene::make_two_sided`]).
    pub fn is_two_sided(&self) -> bool {
        self.twin.iter().any(|&u| u != NO_TWIN)
    }

    /// A copy with every face two-sided ([`Scene::make_two_sided`]).
    pub fn to_two_sided(&self) -> Scene {
        let mut scene = self.clone();
        scene.make_two_sided();
        scene
    }

    /// Makes every face two-sided (`--two-sided`; see the module documentation) and returns
    /// the number of back faces added: [`Scene::make_two_sided_where`] for every material.
    pub fn make_two_sided(&mut self) -> usize {
        self.make_two_sided_where(|_| true)
    }

    /// Gives each triangle whose material `pick` accepts a back side of its own, and returns
    /// the number of back faces added. In triangle order, a picked triangle without a twin is
    /// paired with the first unpaired triangle over the same three vertices in the opposite
    /// winding, if the scene has one (a back face modelled in the file: it keeps its own
    /// material; the pairs found are counted in a warning), and otherwise gets a new twin
    /// appended at the end: its vertices reversed, `[v0, v2, v1]`, with the same material (ρ
    /// and Le are the same on both sides). Positions, materials and the order of the existing
    /// triangles are unchanged, and calling it again adds nothing.
    ///
    /// The loader's checks are not run again: twins lie in the same plane facing opposite
    /// ways, which the overlap check already accepts, and every shared edge is now used in
    /// both directions on purpose.
    pub fn make_two_sided_where(&mut self, mut pick: impl FnMut(&Material) -> bool) -> usize {
        let n = self.triangles.len();
        if self.twin.is_empty() {
            self.twin = vec![NO_TWIN; n];
        }
        // Triangles over the same vertex set, by sorted indices and winding parity.
        let key = |v: [u32; 3]| {
            let mut s = v;
            let mut odd = false;
            for (a, b) in [(0, 1), (1, 2), (0, 1)] {
                if s[a] > s[b] {
                    s.swap(a, b);
                    odd = !odd;
                }
            }
            (s, odd)
        };
        let mut unpaired: HashMap<([u32; 3], bool), Vec<usize>> = HashMap::new();
        for t in 0..n {
            if self.twin[t] == NO_TWIN {
                unpaired
                    .entry(key(self.triangles[t].vertices))
                    .or_default()
                    .push(t);
            }
        }
        let mut paired_in_file = 0;
        let mut added = 0;
        for t in 0..n {
            let tri = self.triangles[t];
            if self.twin[t] != NO_TWIN || !pick(&self.materials[tri.material as usize]) {
                continue;
            }
            let (sorted, odd) = key(tri.vertices);
            let partner = unpaired
                .get_mut(&(sorted, !odd))
                .and_then(|list| (!list.is_empty()).then(|| list.remove(0)));
            if let Some(u) = partner {
                self.twin[t] = u as u32;
                self.twin[u] = t as u32;
                if let Some(list) = unpaired.get_mut(&(sorted, odd)) {
                    list.retain(|&x| x != t);
                }
                paired_in_file += 1;
                continue;
            }
            let [a, b, c] = tri.vertices;
            self.triangles.push(SceneTriangle {
                vertices: [a, c, b],
                material: tri.material,
            });
            let u = self.triangles.len() - 1;
            self.twin.push(t as u32);
            self.twin[t] = u as u32;
            added += 1;
        }
        if paired_in_file > 0 {
            self.warnings.push(format!(
                "two-sided: {paired_in_file} face{} already had a reversed face over the same                  corners; each such pair is taken as the two sides of one surface (each side                  keeps its own material) instead of being doubled",
                if paired_in_file == 1 { "" } else { "s" }
            ));
        }
        added
    }

    /// Axis-aligned bounding box of all positions as (min, max). An empty scene gives the
    /// empty box (+∞, −∞).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.positions
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            })
    }

    /// Area of triangle `t`, ½ |(p1 − p0) × (p2 − p0)|, in squared length units.
    /// Panics if `t` or its vertex indices are out of range (as slice indexing does).
    pub fn triangle_area(&self, t: usize) -> f64 {
        let [a, b, c] = self.triangles[t]
            .vertices
            .map(|v| self.positions[v as usize]);
        0.5 * (b - a).cross(c - a).length()
    }

    /// True if at least one triangle has a material with positive emission.
    pub fn has_emitters(&self) -> bool {
        self.triangles.iter().any(|t| {
            self.materials
                .get(t.material as usize)
                .is_some_and(Material::is_emitter)
        })
    }

    fn input_error(&self, message: String) -> Error {
        Error::Input {
            path: source_path(&self.source),
            message,
        }
    }
}

/// The path errors about a scene name: its file, or `<procedural scene>`.
fn source_path(source: &Option<PathBuf>) -> PathBuf {
    source
        .clone()
        .unwrap_or_else(|| PathBuf::from("<procedural scene>"))
}

/// Finishes a scene from raw loader or builder output, in order:
/// 1. [`Scene::validate`] the raw data (so the steps below can index freely);
/// 2. weld positions that are bitwise identical (−0.0 counted as +0.0), first occurrence
///    wins, so the result does not depend on hashing;
/// 3. drop triangles with |(b − a) × (c − a)| ≤ [`ZERO_AREA_RELATIVE`] · d², d the
///    bounding-box diagonal of the used positions, with one counted warning;
/// 4. drop positions no triangle uses (keeping their order) and validate again;
/// 5. warn (keeping every face) about coincident overlapping faces and inconsistent winding
///    between neighbours ([`checks`]), naming the triangles and, when `face_lines` gives the
///    source line of every raw triangle, the file and line of their faces.
pub(crate) fn finish(
    source: Option<PathBuf>,
    positions: Vec<DVec3>,
    triangles: Vec<SceneTriangle>,
    materials: Vec<Material>,
    mut warnings: Vec<String>,
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
        return Err(Error::Input {
            path: source_path(&source),
            message: "the mesh is empty: no triangles".into(),
        });
    }
    let raw = Scene {
        source,
        positions,
        triangles,
        materials,
        warnings: Vec::new(),
        twin: Vec::new(),
        camera: None,
    };
    raw.validate()?;
    let Scene {
        source,
        positions,
        triangles,
        materials,
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
            material: t.material,
        })
        .collect();

    // 3. Drop zero-area triangles, relative to the scale of the used geometry.
    let (lo, hi) = triangles
        .iter()
        .flat_map(|t| t.vertices)
        .map(|v| positions[v as usize])
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        });
    let threshold = ZERO_AREA_RELATIVE * (hi - lo).length_squared();
    let total = triangles.len();
    let keep: Vec<bool> = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.vertices.map(|v| positions[v as usize]);
            (b - a).cross(c - a).length() > threshold
        })
        .collect();
    let triangles: Vec<SceneTriangle> = triangles
        .into_iter()
        .zip(&keep)
        .filter_map(|(t, &k)| k.then_some(t))
        .collect();
    let face_lines: Option<Vec<usize>> = face_lines.map(|lines| {
        lines
            .into_iter()
            .zip(&keep)
            .filter_map(|(l, &k)| k.then_some(l))
            .collect()
    });
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

    // 4. Compact: keep used positions in their original order.
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
            material: t.material,
        })
        .collect();

    let mut scene = Scene {
        source,
        positions: kept,
        triangles,
        materials,
        warnings,
        twin: Vec::new(),
        camera: None,
    };
    scene.validate()?;

    // 5. Likely modelling mistakes: warn, keep every face.
    let diagonal = (hi - lo).length();
    let name = |t: usize| match (&face_lines, &scene.source) {
        (Some(lines), Some(path)) => format!("{t} ({}:{})", path.display(), lines[t]),
        _ => t.to_string(),
    };
    let list = |pairs: &[(usize, usize)]| {
        let mut shown: Vec<String> = pairs
            .iter()
            .take(MAX_LISTED_PAIRS)
            .map(|&(i, j)| format!("triangles {} and {}", name(i), name(j)))
            .collect();
        if pairs.len() > MAX_LISTED_PAIRS {
            shown.push(format!("… {} more", pairs.len() - MAX_LISTED_PAIRS));
        }
        shown.join("; ")
    };
    let coincident = checks::coincident_faces(&scene.positions, &scene.triangles, diagonal);
    if !coincident.is_empty() {
        let n = coincident.len();
        scene.warnings.push(format!(
            "{n} pair{} of coincident overlapping faces (same plane, same facing: z-fighting): \
             {}. Both faces of each pair are kept, so light exchanged with the overlap is \
             counted for both; move one face off the plane or cut a hole for it",
            if n == 1 { "" } else { "s" },
            list(&coincident)
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
            list(&flipped)
        ));
    }
    Ok(scene)
}

/// Warnings about pairs of faces list at most this many pairs (and count the rest).
pub const MAX_LISTED_PAIRS: usize = 5;

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
        self.materials.push(Material {
            name: name.to_string(),
            reflectance,
            emission,
        });
        (self.materials.len() - 1) as u32
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
        });
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
            Vec::new(),
            None,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn normal(s: &Scene, t: usize) -> DVec3 {
        let [a, b, c] = s.triangles[t].vertices.map(|v| s.positions[v as usize]);
        (b - a).cross(c - a).normalize()
    }

    #[test]
    fn quad_winding_gives_front_normal() {
        let mut b = SceneBuilder::new();
        let m = b.material("grey", [0.5; 3], [0.0; 3]);
        b.quad(
            [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
            ],
            m,
        );
        let s = b.build().unwrap();
        assert_eq!(s.triangles.len(), 2);
        assert_eq!(s.positions.len(), 4);
        for t in 0..2 {
            assert!((normal(&s, t) - DVec3::Z).length() < 1e-12);
            assert!((s.triangle_area(t) - 0.5).abs() < 1e-12);
        }
        assert!(!s.has_emitters());
        assert_eq!(s.bounds(), (DVec3::ZERO, DVec3::new(1.0, 1.0, 0.0)));
    }

    #[test]
    fn build_welds_shared_corners_and_signed_zero() {
        let mut b = SceneBuilder::new();
        let m = b.material("light", [0.5; 3], [1.0, 2.0, 3.0]);
        b.quad(
            [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
            ],
            m,
        );
        b.quad(
            [
                DVec3::new(1.0, -0.0, 0.0),
                DVec3::new(2.0, 0.0, 0.0),
                DVec3::new(2.0, 1.0, 0.0),
                DVec3::new(1.0, 1.0, -0.0),
            ],
            m,
        );
        let s = b.build().unwrap();
        assert_eq!(s.positions.len(), 6);
        // Second quad's a and d are the first quad's b and c.
        assert_eq!(s.triangles[2].vertices[0], s.triangles[0].vertices[1]);
        assert_eq!(s.triangles[3].vertices[2], s.triangles[0].vertices[2]);
        assert!(s.has_emitters());
        assert!(s.warnings.is_empty());
    }

    #[test]
    fn build_drops_zero_area_and_unused_vertices() {
        let mut b = SceneBuilder::new();
        let m = b.material("grey", [0.5; 3], [0.0; 3]);
        let v: Vec<u32> = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1000.0, 0.0, 0.0),
            DVec3::new(0.0, 1000.0, 0.0),
            DVec3::new(500.0, 0.0, 0.0),
            DVec3::new(7.0, 7.0, 7.0),
        ]
        .into_iter()
        .map(|p| b.vertex(p))
        .collect();
        b.triangle([v[0], v[1], v[2]], m);
        b.triangle([v[0], v[3], v[1]], m); // collinear
        let s = b.build().unwrap();
        assert_eq!(s.triangles.len(), 1);
        assert_eq!(s.positions.len(), 3);
        assert_eq!(s.warnings.len(), 1);
        assert!(s.warnings[0].contains("skipped 1 zero-area triangle"));
    }

    #[test]
    fn build_rejects_bad_input_naming_the_item() {
        let quad = [DVec3::ZERO, DVec3::X, DVec3::ONE, DVec3::Y];
        let mut b = SceneBuilder::new();
        let m = b.material("too bright", [1.2, 0.5, 0.5], [0.0; 3]);
        b.quad(quad, m);
        let e = b.build().unwrap_err();
        assert!(matches!(e, Error::Input { .. }), "{e:?}");
        assert!(e.to_string().contains("too bright"), "{e}");

        let mut b = SceneBuilder::new();
        let m = b.material("neg", [0.5; 3], [0.0, -1.0, 0.0]);
        b.quad(quad, m);
        assert!(b.build().unwrap_err().to_string().contains("neg"));

        let mut b = SceneBuilder::new();
        b.material("grey", [0.5; 3], [0.0; 3]);
        b.quad(quad, 3);
        let e = b.build().unwrap_err().to_string();
        assert!(
            e.contains("triangle 0") && e.contains("material index 3"),
            "{e}"
        );

        let mut b = SceneBuilder::new();
        let m = b.material("grey", [0.5; 3], [0.0; 3]);
        b.triangle([0, 1, 9], m);
        let e = b.build().unwrap_err().to_string();
        assert!(e.contains("vertex index"), "{e}");

        let mut b = SceneBuilder::new();
        let m = b.material("grey", [0.5; 3], [0.0; 3]);
        b.quad([DVec3::ZERO, DVec3::X, DVec3::NAN, DVec3::Y], m);
        assert!(b.build().unwrap_err().to_string().contains("non-finite"));

        let e = SceneBuilder::new().build().unwrap_err();
        assert!(matches!(e, Error::Input { .. }));

        let mut b = SceneBuilder::new();
        let m = b.material("grey", [0.5; 3], [0.0; 3]);
        b.quad([DVec3::ONE; 4], m);
        let e = b.build().unwrap_err().to_string();
        assert!(e.contains("no triangles with non-zero area"), "{e}");
    }

    #[test]
    fn two_sided_appends_reversed_twins_once_and_validate_checks_them() {
        let mut b = SceneBuilder::new();
        let m = b.material("grey", [0.5; 3], [0.0; 3]);
        b.quad(
            [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            m,
        );
        let mut s = b.build().unwrap();
        assert!(!s.is_two_sided() && s.twin.is_empty());
        assert_eq!(s.make_two_sided(), 2);
        assert!(s.is_two_sided());
        assert_eq!(s.twin, [2, 3, 0, 1]);
        let [a, b_, c] = s.triangles[0].vertices;
        assert_eq!(s.triangles[2].vertices, [a, c, b_]);
        assert_eq!(s.triangles[2].material, m);
        assert!((normal(&s, 2) + normal(&s, 0)).length() < 1e-12);
        s.validate().unwrap();
        assert_eq!(s.make_two_sided(), 0, "idempotent");
        assert_eq!(s.triangles.len(), 4);
        assert!(s.warnings.is_empty());

        // A broken twin map is an internal inconsistency validate reports.
        let mut bad = s.clone();
        bad.twin[0] = 3;
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("triangle 0: twin 3"));
        let mut bad = s.clone();
        bad.triangles[2].vertices = [a, b_, c];
        assert!(bad.validate().is_err());
        let mut bad = s.clone();
        bad.twin.pop();
        assert!(bad.validate().is_err());
    }

    #[test]
    fn validate_names_out_of_range_triangle() {
        let s = Scene {
            source: Some(PathBuf::from("x.obj")),
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
            triangles: vec![
                SceneTriangle {
                    vertices: [0, 1, 2],
                    material: 0,
                },
                SceneTriangle {
                    vertices: [0, 1, 3],
                    material: 0,
                },
            ],
            materials: vec![Scene::default_material()],
            warnings: vec![],
            twin: vec![],
            camera: None,
        };
        let e = s.validate().unwrap_err().to_string();
        assert!(e.starts_with("x.obj: triangle 1: vertex index 3"), "{e}");
    }
}
