//! Baking: from patch radiance (constant per patch) to radiance at the vertices of the output
//! mesh, for smooth vertex colours. This module owns the rule that decides which patches share
//! an output vertex:
//!
//! At each vertex of the patch mesh, the patches around it are grouped into *surfaces*: two
//! patches belong to the same surface when they have the same material and their normals
//! differ by at most the crease angle given (union–find over the patches at that vertex). Each
//! group becomes its own output vertex, with the area-weighted mean radiance of its patches,
//! L_v = Σ A_p L_p / Σ A_p. So the red wall does not bleed into the floor's corner vertices.
//! With [`bake_sites_apart`], patches covered by a face a thin gap in front of them are a
//! surface of their own too (the light jumps at the covering face's outline), and so are
//! buried ones, flush under another surface (nobody sees their value).
//!
//! The pipeline's bake groups by the crease angle its solve takes the mesh with (`--crease`):
//! where faces meet at smaller angles they sample one smooth surface, for the form factors'
//! interpolated normals and for the display alike, so a vertex of a tessellated ball or column
//! is one output vertex, gathered with the surface's normal there (the area-weighted mean of
//! its facets'). The faceted geometry's own light differs from facet to facet by their
//! cosines: inside the integrating sphere of 1,280 facets by up to 14 % at a facet's corner,
//! where the closed form of the sphere the solve assumes is uniform. With `--crease 0` every
//! face is flat, in the solve and in the display.
//!
//! It also owns the hand-off type [`BakedMesh`] (what the writers in [`crate::io`] and the
//! rasteriser in [`crate::render`] read) with its [`BakedMesh::validate`], and the exposure
//! the colours are taken at by default ([`BakedMesh::auto_exposure`]).

use glam::DVec3;

use crate::color::{self, Rgb};
use crate::mesh::{groups, Patches, VertexFaces};
use crate::scene::{Camera, Sky};
use crate::{Error, Result};

/// Bake patch radiance into a [`BakedMesh`] (see the module documentation for the rule).
/// `radiance[i]` is patch i's radiance, W·sr⁻¹·m⁻² per channel.
pub fn bake(patches: &Patches, radiance: &[Rgb], crease_degrees: f64) -> BakedMesh {
    bake_sites(patches, radiance, crease_degrees).0
}

/// The patches of a [`Site`]: up to four inline, more on the heap.
pub type SitePatches = smallvec::SmallVec<[u32; 4]>;

/// An output vertex as a point of the surface: where the final gather
/// ([`crate::gather`]) evaluates the radiance it shows.
#[derive(Debug, Clone, PartialEq)]
pub struct Site {
    /// Position, scene units.
    pub position: DVec3,
    /// Unit normal: the area-weighted mean of its patches' normals.
    pub normal: DVec3,
    /// The patches whose corner this vertex is (one surface group: same material, normals
    /// within the crease angle); up to four kept inline (most vertices have one to four).
    pub patches: SitePatches,
    /// Other output vertices share its position: it lies on a crease or a material border,
    /// where surfaces meet.
    pub shared: bool,
    /// The patch-mesh vertex it stands at: output vertices split at a crease or a material
    /// border have the same one.
    pub mesh_vertex: u32,
    /// Where it lies on the outline of a face covering part of its surface a thin gap in
    /// front of it (either side of the outline, [`bake_sites_apart`]): that gap, scene units;
    /// 0 elsewhere.
    pub gap: f32,
}

/// A radiance below 0 by no more than this fraction of the largest value in its set is
/// rounding: the sums of a solve or a fit that are 0 in exact arithmetic (a patch that no
/// light reaches, one channel of a coloured light) come out as ±1e-29 or so, some 10⁻²⁵ of the
/// scene's radiance, and f64 carries 16 digits; a value more negative than 10⁻⁹ of the
/// largest is not rounding but a mistake, and [`BakedMesh::validate`] still rejects it.
pub const ROUNDING: f64 = 1e-9;

/// Sets to 0 every channel of `radiance` that is negative by at most [`ROUNDING`] × the
/// largest channel value in it (W·sr⁻¹·m⁻²), so that a display value of rounding size never
/// costs a bake. Leaves larger negatives, and values that are not finite, as they are.
pub fn clamp_rounding(radiance: &mut [Rgb]) {
    let largest = radiance
        .iter()
        .flatten()
        .copied()
        .filter(|c| c.is_finite())
        .fold(0.0, |m: f64, c| m.max(c.abs()));
    let floor = -ROUNDING * largest;
    for c in radiance.iter_mut().flatten() {
        if *c < 0.0 && *c >= floor {
            *c = 0.0;
        }
    }
}

/// [`bake`], with the [`Site`] of every output vertex (indexed like the mesh's positions).
pub fn bake_sites(
    patches: &Patches,
    radiance: &[Rgb],
    crease_degrees: f64,
) -> (BakedMesh, Vec<Site>) {
    bake_sites_apart(patches, radiance, crease_degrees, &[], &[])
}

/// [`bake_sites`], where moreover a patch covered by a face a thin gap in front of it
/// (`covers[p]` > 0, that gap in scene units, [`crate::gather::Gatherer::covers`]; empty:
/// none) shares no output vertex with one that is not: the covering face's outline is a jump
/// of the light at the display's scale, and each side shows its own. Both sides' vertices
/// on the outline carry the gap ([`Site::gap`]). Likewise a buried patch (`buried[p]`,
/// [`crate::gather::Gatherer::buried_patches`]; empty: none), flush under another surface
/// (a screen's strip behind the desk top that abuts it, the floor under a leg), shares no
/// output vertex with a seen one: the seen side's vertices on the contact line are its own,
/// refined, flipped and fitted with the seen faces alone, and the buried side keeps the
/// solve's values where nobody sees them.
pub fn bake_sites_apart(
    patches: &Patches,
    radiance: &[Rgb],
    crease_degrees: f64,
    covers: &[f64],
    buried: &[bool],
) -> (BakedMesh, Vec<Site>) {
    let gap = |p: usize| covers.get(p).copied().unwrap_or(0.0);
    let is_covered = |p: usize| gap(p) > 0.0;
    let is_buried = |p: usize| buried.get(p).copied().unwrap_or(false);
    let mut sites = Vec::new();
    let cos_crease = crease_degrees.to_radians().cos();
    let nv = patches.positions.len();
    let around = VertexFaces::new(&patches.triangles, nv);

    let mut mesh = BakedMesh {
        positions: Vec::new(),
        vertex_radiance: Vec::new(),
        faces: patches.triangles.clone(),
        face_radiance: radiance.to_vec(),
        camera: None,
        sky: None,
    };
    // out_vertex[slot of a (vertex, patch) incidence] = its output vertex.
    let mut out_vertex = vec![u32::MAX; around.len()];
    for v in 0..nv {
        let ps = around.faces(v);
        if ps.is_empty() {
            continue;
        }
        let group = groups(ps.len(), |a, b| {
            let (pa, pb) = (ps[a] as usize, ps[b] as usize);
            patches.material[pa] == patches.material[pb]
                && patches.normal[pa].dot(patches.normal[pb]) >= cos_crease
                && is_covered(pa) == is_covered(pb)
                && is_buried(pa) == is_buried(pb)
        });
        // One output vertex per group, in order of the group's first patch (deterministic).
        let first_out = mesh.positions.len();
        let mut sums: Vec<([f64; 3], f64)> = Vec::new();
        let pos = patches.positions[v];
        for (a, &g) in group.iter().enumerate() {
            if g == sums.len() {
                sums.push(([0.0; 3], 0.0));
                sites.push(Site {
                    position: pos,
                    normal: DVec3::ZERO,
                    patches: SitePatches::new(),
                    shared: false,
                    mesh_vertex: v as u32,
                    gap: 0.0,
                });
            }
            let p = ps[a] as usize;
            let w = patches.area[p];
            for (s, l) in sums[g].0.iter_mut().zip(radiance[p]) {
                *s += w * l;
            }
            sums[g].1 += w;
            let site = &mut sites[first_out + g];
            site.normal += w * patches.normal[p];
            site.patches.push(p as u32);
            out_vertex[around.offset(v) + a] = (first_out + g) as u32;
        }
        if sums.len() > 1 {
            // On a covering face's outline: the widest gap over the covered patches here.
            let outline = ps.iter().any(|&q| is_covered(q as usize))
                && ps.iter().any(|&q| !is_covered(q as usize));
            let widest = ps.iter().map(|&q| gap(q as usize)).fold(0.0, f64::max);
            for site in &mut sites[first_out..] {
                site.shared = true;
                if outline {
                    site.gap = widest as f32;
                }
            }
        }
        for (s, w) in sums {
            mesh.positions.push([pos.x, pos.y, pos.z]);
            mesh.vertex_radiance.push([s[0] / w, s[1] / w, s[2] / w]);
        }
    }
    // Re-index faces to output vertices.
    for (p, face) in mesh.faces.iter_mut().enumerate() {
        for v in face.iter_mut() {
            let vi = *v as usize;
            let slot = around
                .faces(vi)
                .iter()
                .position(|&q| q as usize == p)
                .expect("every patch is listed at its own vertices");
            *v = out_vertex[around.offset(vi) + slot];
        }
    }
    for site in &mut sites {
        site.normal = site.normal.normalize_or_zero();
    }
    // Grown by doubling: up to twice the output's vertices held through the gather.
    sites.shrink_to_fit();
    mesh.positions.shrink_to_fit();
    mesh.vertex_radiance.shrink_to_fit();
    (mesh, sites)
}

/// A mesh ready to write: baked vertices (split at creases and material borders) and patch faces.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BakedMesh {
    /// Vertex positions, scene units; finite and representable as `f32` (both formats store `f32`).
    pub positions: Vec<[f64; 3]>,
    /// Baked vertex radiance, linear, W·sr⁻¹·m⁻² per RGB channel; finite and >= 0.
    /// One entry per position.
    pub vertex_radiance: Vec<[f64; 3]>,
    /// Triangles (indices into positions), counter-clockwise seen from the front side.
    pub faces: Vec<[u32; 3]>,
    /// Solved radiance of each face's patch, W·sr⁻¹·m⁻² per RGB channel; finite and >= 0.
    /// One entry per face (PLY only: OBJ has nowhere to put it).
    pub face_radiance: Vec<[f64; 3]>,
    /// The scene file's camera, repeated in the output (`comment camera: …` in PLY, `# camera:
    /// …` in OBJ) so a picture of the baked file uses it too; `None` if the scene had none.
    pub camera: Option<Camera>,
    /// The bake's sky, which a picture shows where its rays leave the scene (`comment sky: …`
    /// in PLY, so a picture of the baked file shows it too); `None` without a sky.
    pub sky: Option<Sky>,
}

/// Whether `x` is finite and within f32's range (|x| ≤ 3.4e38), as every position and
/// radiance of a [`BakedMesh`] must be ([`BakedMesh::validate`]); the glTF loader holds its
/// transforms and the positions they give to it too (an OBJ's numbers are checked so as they
/// are read).
pub fn fits_f32(x: f64) -> bool {
    x.abs() <= f64::from(f32::MAX)
}

impl BakedMesh {
    /// The exposure the colours are taken at unless one is given: [`color::auto_exposure`]
    /// over the vertex radiance, each vertex weighted by the area it stands for
    /// ([`BakedMesh::vertex_areas`]): the area-weighted log-average luminance maps to the key
    /// 0.18 of white, with at most 2 % of the lit area clipping.
    pub fn auto_exposure(&self) -> f64 {
        color::auto_exposure(&self.vertex_radiance, &self.vertex_areas())
    }

    /// The area each vertex stands for, scene units²: a third of the area of every face it is
    /// a corner of (0 for a vertex of no face). Indices out of range are skipped.
    pub fn vertex_areas(&self) -> Vec<f64> {
        let mut areas = vec![0.0; self.positions.len()];
        for face in &self.faces {
            let Some(p) = face
                .iter()
                .map(|&v| {
                    self.positions
                        .get(v as usize)
                        .map(|p| DVec3::from_array(*p))
                })
                .collect::<Option<Vec<_>>>()
            else {
                continue;
            };
            let third = (p[1] - p[0]).cross(p[2] - p[0]).length() / 6.0;
            for &v in face {
                areas[v as usize] += third;
            }
        }
        areas
    }

    /// Sets to 0 the negative values of rounding size in its radiance ([`clamp_rounding`]),
    /// per vertex and per face.
    pub fn clamp_rounding(&mut self) {
        clamp_rounding(&mut self.vertex_radiance);
        clamp_rounding(&mut self.face_radiance);
    }

    /// Checks the invariants the writers rely on: per-vertex and per-face arrays have matching
    /// lengths, every index is in range (and fits the PLY `int` index type), every value is
    /// finite and fits in `f32`, and radiance is >= 0. A failure is an [`Error::Internal`]:
    /// the bake stage is supposed to guarantee all of this.
    pub fn validate(&self) -> Result<()> {
        let bad = |message: String| Err(Error::Internal(format!("baked mesh: {message}")));
        if self.vertex_radiance.len() != self.positions.len() {
            return bad(format!(
                "{} vertex radiance values for {} vertices",
                self.vertex_radiance.len(),
                self.positions.len()
            ));
        }
        if self.face_radiance.len() != self.faces.len() {
            return bad(format!(
                "{} face radiance values for {} faces",
                self.face_radiance.len(),
                self.faces.len()
            ));
        }
        // PLY stores indices as `int`; every index must fit even though ours are u32.
        if self.positions.len() > i32::MAX as usize + 1 {
            return bad(format!(
                "{} vertices exceed the PLY index range",
                self.positions.len()
            ));
        }
        for (i, p) in self.positions.iter().enumerate() {
            if !p.iter().all(|&c| fits_f32(c)) {
                return bad(format!("vertex {i} position {p:?} is not a finite f32"));
            }
        }
        let radiance_ok = |r: &[f64; 3]| r.iter().all(|&c| fits_f32(c) && c >= 0.0);
        for (i, r) in self.vertex_radiance.iter().enumerate() {
            if !radiance_ok(r) {
                return bad(format!(
                    "vertex {i} radiance {r:?} is not finite and >= 0 (or exceeds f32)"
                ));
            }
        }
        for (i, f) in self.faces.iter().enumerate() {
            if let Some(&v) = f.iter().find(|&&v| v as usize >= self.positions.len()) {
                return bad(format!(
                    "face {i} refers to vertex {v} but there are {} vertices",
                    self.positions.len()
                ));
            }
        }
        for (i, r) in self.face_radiance.iter().enumerate() {
            if !radiance_ok(r) {
                return bad(format!(
                    "face {i} radiance {r:?} is not finite and >= 0 (or exceeds f32)"
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::sample_mesh;

    #[test]
    fn the_pipeline_shows_a_curved_surface_as_its_solve_takes_it() {
        // An 80-facet sphere (42 corners, neighbouring facets ~20° apart), one patch per
        // facet: within the default crease angle the form factors take it for one smooth
        // surface, and the output shares each of its 42 corners; with a crease angle of 0
        // every facet is flat in both, a vertex per facet corner, 240. A quad's two coplanar
        // triangles share their diagonal either way.
        let sphere =
            crate::validation::scenes::integrating_sphere(1.0, 1, 30.0, 0.5, [1.0; 3]).unwrap();
        assert_eq!(sphere.triangles.len(), 80);
        let settings = crate::pipeline::Settings {
            max_edge: Some(10.0),
            refine_rounds: 0,
            gather: crate::gather::Gather::None,
            ..crate::pipeline::Settings::default()
        };
        let faceted = crate::pipeline::Settings {
            crease_degrees: 0.0,
            ..settings.clone()
        };
        // A corner on the cap's rim is two output vertices (cap and wall are two materials).
        let materials = |v: u32| {
            let mut m: Vec<u32> = (sphere.triangles.iter())
                .filter(|t| t.vertices.contains(&v))
                .map(|t| t.material)
                .collect();
            m.sort_unstable();
            m.dedup();
            m.len()
        };
        let shared: usize = (0..42).map(materials).sum();
        assert!(shared > 42, "the rim is counted twice");
        let out = crate::pipeline::solve_scene(&sphere, &settings).unwrap();
        assert_eq!(out.patches.len(), 80);
        assert_eq!(out.baked.positions.len(), shared);
        let out = crate::pipeline::solve_scene(&sphere, &faceted).unwrap();
        assert_eq!(out.baked.positions.len(), 240);
        let plates = crate::validation::scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        for s in [&settings, &faceted] {
            let out = crate::pipeline::solve_scene(&plates, s).unwrap();
            assert_eq!(out.patches.len(), 4);
            assert_eq!(
                out.baked.positions.len(),
                8,
                "two squares, four corners each"
            );
        }
    }

    #[test]
    fn rounding_negatives_are_clamped_and_mistakes_are_not() {
        // A bake once lost at the end to [2.8e-26, -3.2e-29, -6.0e-28] beside values of order
        // 1: rounding, to be shown as 0. A value −1e-3 of the largest is a mistake, kept for
        // validate() to reject; NaN stays NaN.
        let mut mesh = sample_mesh(5, 2);
        mesh.vertex_radiance[0] = [2.8e-26, -3.2e-29, -6.0e-28];
        mesh.vertex_radiance[1] = [1.0, 0.5, 0.25];
        mesh.face_radiance[0] = [-1e-12, 0.0, 1.0];
        mesh.clamp_rounding();
        assert_eq!(mesh.vertex_radiance[0], [2.8e-26, 0.0, 0.0]);
        assert_eq!(mesh.face_radiance[0], [0.0, 0.0, 1.0]);
        mesh.validate().unwrap();
        mesh.vertex_radiance[2] = [-1e-3, 0.0, 0.0];
        mesh.vertex_radiance[3] = [f64::NAN, 0.0, 0.0];
        mesh.clamp_rounding();
        assert_eq!(mesh.vertex_radiance[2][0], -1e-3);
        assert!(mesh.vertex_radiance[3][0].is_nan());
        assert!(mesh.validate().is_err());
    }

    #[test]
    fn validate_rejects_each_broken_invariant() {
        let good = sample_mesh(10, 6);
        good.validate().unwrap();
        let mut breakages: Vec<(BakedMesh, &str)> = Vec::new();
        let mut m = good.clone();
        m.vertex_radiance.pop();
        breakages.push((m, "vertex radiance values"));
        let mut m = good.clone();
        m.face_radiance.push([0.0; 3]);
        breakages.push((m, "face radiance values"));
        let mut m = good.clone();
        m.faces[3][1] = 10;
        breakages.push((m, "face 3 refers to vertex 10"));
        let mut m = good.clone();
        m.positions[2][0] = f64::INFINITY;
        breakages.push((m, "vertex 2 position"));
        let mut m = good.clone();
        m.positions[2][0] = 1e39;
        breakages.push((m, "vertex 2 position"));
        let mut m = good.clone();
        m.vertex_radiance[4][2] = f64::NAN;
        breakages.push((m, "vertex 4 radiance"));
        let mut m = good.clone();
        m.vertex_radiance[4][2] = -1e-9;
        breakages.push((m, "vertex 4 radiance"));
        let mut m = good.clone();
        m.face_radiance[5][0] = f64::NAN;
        breakages.push((m, "face 5 radiance"));
        for (mesh, needle) in breakages {
            let err = mesh.validate().unwrap_err();
            assert!(matches!(err, Error::Internal(_)));
            assert!(err.to_string().contains(needle), "{err} lacks {needle}");
        }
    }

    #[test]
    fn auto_exposure_weights_vertices_by_their_area() {
        // Two triangles of a strip sharing no vertex: a small bright one (area 0.005) and a
        // large dim one (area 0.5). Weighted by area the dim one sets the key; black vertices
        // do not count.
        let mesh = BakedMesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [0.1, 0.0, 0.0],
                [0.0, 0.1, 0.0],
                [1.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [5.0, 5.0, 5.0],
            ],
            vertex_radiance: vec![
                [8.0; 3], [8.0; 3], [8.0; 3], [0.5; 3], [0.5; 3], [0.5; 3], [0.0; 3],
            ],
            faces: vec![[0, 1, 2], [3, 4, 5]],
            ..BakedMesh::default()
        };
        let areas = mesh.vertex_areas();
        assert!((areas[0] - 0.005 / 3.0).abs() < 1e-15 && (areas[3] - 0.5 / 3.0).abs() < 1e-15);
        assert_eq!(areas[6], 0.0);
        // L̄ = exp((0.005 ln 8 + 0.5 ln 0.5) / 0.505); the bright 1 % of the area may clip.
        let log_avg = ((0.005 * 8.0f64.ln() + 0.5 * 0.5f64.ln()) / 0.505).exp();
        assert!((mesh.auto_exposure() * log_avg / color::KEY - 1.0).abs() < 1e-12);
    }

    #[test]
    fn auto_exposure_weights_channels_by_luminance() {
        // Only blue: Y = 0.0722 · B, and the key would put B = 2 at 2.5: it may not clip.
        let mesh = BakedMesh {
            positions: vec![[0.0; 3]; 2],
            vertex_radiance: vec![[0.0, 0.0, 2.0], [0.0; 3]],
            ..BakedMesh::default()
        };
        assert_eq!(mesh.auto_exposure(), 0.5);
        // Only green: Y = 0.7152 · G, and the key puts G at 0.25.
        let mesh = BakedMesh {
            vertex_radiance: vec![[0.0, 3.0, 0.0], [0.0; 3]],
            ..mesh
        };
        assert!((mesh.auto_exposure() - color::KEY / (0.7152 * 3.0)).abs() < 1e-12);
    }

    #[test]
    fn auto_exposure_of_black_mesh_is_one() {
        let mesh = BakedMesh {
            positions: vec![[0.0; 3]; 3],
            vertex_radiance: vec![[0.0; 3]; 3],
            ..BakedMesh::default()
        };
        assert_eq!(mesh.auto_exposure(), 1.0);
        assert_eq!(BakedMesh::default().auto_exposure(), 1.0);
    }
}
