//! The scene: triangles, their vertex positions and their Lambertian materials, as handed
//! from the loaders to the patcher. This module owns the types, the shared clean-up every
//! scene goes through (`build`: vertex welding, dropping zero-area triangles,
//! [`Scene::validate`], the [`checks`] for likely mistakes) and [`SceneBuilder`] for
//! procedural scenes, material overrides ([`overrides`]), two-sided twins (`two_sided`) and
//! the file's [`camera`]. Reading and writing files is [`crate::io`]'s ([`Scene::load`] is
//! defined there, so this model does not depend on the formats).
//! It does not subdivide, compute normals for shading, or know about radiometry beyond
//! checking that reflectances and emissions are physically meaningful.
//!
//! Invariants of a [`Scene`] returned by [`Scene::load`] or [`SceneBuilder::build`]:
//! every index is in range, every position is finite, no two positions are bitwise equal
//! (welded, so faces that share a corner share its index), every position is used by a
//! triangle, no triangle has (relatively) zero area, every ρ is in [0, 1] and every Le is
//! finite and ≥ 0, and there is at least one triangle. A loaded scene is one-sided
//! ([`Scene::twin`] empty), except a Mitsuba scene's faces under a `twosided` BSDF, which come
//! with their twins; [`Scene::make_two_sided`] gives faces a back side.
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

mod build;
pub mod camera;
pub mod checks;
pub mod lights;
pub mod orient;
pub mod overrides;
pub mod reach;
pub mod texture;
mod two_sided;

pub(crate) use build::{finish, listed_all, listed_names_all};
pub use build::{SceneBuilder, WarningDetail, MAX_LISTED_PAIRS};
pub use camera::{Camera, Up};
pub use lights::{Environment, LightSources, PointLight, Sky, SkyModel, Spot, Sun};
pub use overrides::{Override, Property};
pub use texture::{Texture, UvMap, NO_UV};

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
    /// t, the share of the light reaching a face that passes through it unchanged, in
    /// [0, 1]; 0 (opaque) for almost every material. A face with t > 0 is a screen with holes
    /// over the share t of its area (MTL `d` = 1 − t or `Tr` = t, glTF alpha blending and
    /// `KHR_materials_transmission`): `reflectance` and `emission` are its material's, over
    /// the covered share 1 − t; a ray crossing the face carries on with chance t (the light
    /// of the sun, the sky and lamps with weight t,
    /// [`crate::visibility::Visibility::with_transmittance`]), and what others gather from
    /// the face is scaled by 1 − t (the form factors' columns, `form_factor::cover_columns`;
    /// the hierarchy's links). A face with t = 1 adds nothing and is left out when the scene
    /// is built.
    pub transmittance: f64,
    /// True when the file says this material has no back side: a glTF material that is not
    /// `doubleSided`, a Mitsuba BSDF (one outside `twosided` is one-sided; one inside gives
    /// every face its twin as it is read). [`orient`] gives faces seen from both sides a
    /// back side only where the file does not say; `--two-sided` gives every face one.
    pub one_sided: bool,
}

impl Material {
    /// An opaque material (t = 0): ρ per RGB channel in [0, 1], Le in W·sr⁻¹·m⁻² per channel.
    pub fn opaque(name: impl Into<String>, reflectance: [f64; 3], emission: [f64; 3]) -> Material {
        Material {
            name: name.into(),
            reflectance,
            emission,
            transmittance: 0.0,
            one_sided: false,
        }
    }

    /// This material as the file's one-sided kind or not (see [`Material::one_sided`]).
    pub fn with_one_sided(mut self, one_sided: bool) -> Material {
        self.one_sided = one_sided;
        self
    }

    /// This material as a screen that lets the share `t` ∈ [0, 1] of the light through
    /// (clamped; a NaN is opaque).
    pub fn with_transmittance(mut self, t: f64) -> Material {
        self.transmittance = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        self
    }

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
    /// Index into [`Scene::uv_maps`]: how the material's texture lies on the triangle; or
    /// [`NO_UV`] (no texture, or no texture coordinates: ρ is the material's everywhere).
    pub uv: u32,
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
    /// Human-readable warnings found while loading (e.g. "skipped 3 zero-area triangles"),
    /// one line each: a warning that lists things (faces, materials) names at most
    /// [`MAX_LISTED_PAIRS`] of them.
    pub warnings: Vec<String>,
    /// The full lists behind those warnings, one per list-type warning, in order.
    pub warning_details: Vec<WarningDetail>,
    /// The other side of each triangle ([`Scene::make_two_sided`]): empty for a one-sided
    /// scene (every loaded or built scene); otherwise one entry per triangle, the index of its
    /// twin or [`NO_TWIN`]. Invariants: `twin[twin[t]] == t`, `twin[t] != t`, and a twin has
    /// the same three vertex indices as its triangle in the opposite winding.
    pub twin: Vec<u32>,
    /// The camera the scene file carries (`# camera: …` in OBJ, `comment camera: …` in a PLY
    /// header; see [`crate::scene::camera`]); pictures use it unless `--camera` is given.
    pub camera: Option<Camera>,
    /// Point and spot lights the scene file carries (glTF's `KHR_lights_punctual`); a bake
    /// adds them to those of its settings ([`Environment::add_scene_lights`]).
    pub lights: Vec<PointLight>,
    /// The sun the scene file carries (a glTF directional light); a bake's `--sun` replaces it.
    pub sun: Option<Sun>,
    /// The uniform sky the scene file carries (a Mitsuba `constant` emitter), radiance
    /// W·sr⁻¹·m⁻² per channel, finite and ≥ 0; a bake uses it when it is given no sky of its
    /// own (`--sky`, a lights file) ([`Environment::add_scene_lights`]).
    pub sky: Option<crate::color::Rgb>,
    /// Textures whose colour varies ρ across the faces that carry texture coordinates
    /// ([`texture`]); empty for most scenes.
    pub textures: Vec<Texture>,
    /// Per textured triangle ([`SceneTriangle::uv`]): its map to texture space.
    pub uv_maps: Vec<UvMap>,
}

impl Scene {
    /// ρ over the part of triangle `t` with corners `corners` (points of its plane, scene
    /// units): the material's ρ, times the texture averaged over that part divided by the
    /// texture's mean where the triangle is textured ([`texture`]). Each channel in [0, 1].
    pub fn reflectance_over(&self, t: usize, corners: [DVec3; 3]) -> [f64; 3] {
        let tri = &self.triangles[t];
        let rho = self.materials[tri.material as usize].reflectance;
        if tri.uv == NO_UV {
            return rho;
        }
        let map = &self.uv_maps[tri.uv as usize];
        let texture = &self.textures[map.texture as usize];
        let under = texture.mean_over(corners.map(|p| map.uv(p)));
        std::array::from_fn(|c| {
            if texture.mean[c] > 0.0 {
                (rho[c] * under[c] / texture.mean[c]).clamp(0.0, 1.0)
            } else {
                rho[c]
            }
        })
    }

    /// The material faces get when the OBJ file gives them none (no `usemtl` before them):
    /// named "default", ρ = 0.5 in every channel (a mid grey that neither absorbs nor
    /// reflects nearly everything), Le = 0.
    pub fn default_material() -> Material {
        Material::opaque("default", [0.5; 3], [0.0; 3])
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
            let uv_ok = tri.uv == NO_UV
                || self
                    .uv_maps
                    .get(tri.uv as usize)
                    .is_some_and(|m| (m.texture as usize) < self.textures.len());
            if !uv_ok {
                return fail(format!(
                    "triangle {t}: texture map {} out of range ({} maps, {} textures)",
                    tri.uv,
                    self.uv_maps.len(),
                    self.textures.len()
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

    /// Axis-aligned bounding box of all positions as (min, max). An empty scene gives the
    /// empty box (+∞, −∞).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        crate::geometry::bounds(self.positions.iter().copied())
    }

    /// Each triangle's corners, in triangle order (scene units).
    pub fn triangle_corners(&self) -> Vec<[DVec3; 3]> {
        self.triangles
            .iter()
            .map(|t| t.vertices.map(|v| self.positions[v as usize]))
            .collect()
    }

    /// Each triangle's share of the light it lets through, in triangle order: its material's
    /// transmittance, in [0, 1].
    pub fn triangle_transmittance(&self) -> Vec<f64> {
        self.triangles
            .iter()
            .map(|t| self.materials[t.material as usize].transmittance)
            .collect()
    }

    /// The scene's triangles as ray casting sees them ([`crate::visibility::Visibility`], its
    /// triangle `t` the scene's), the partly transparent ones passing rays by their share
    /// ([`Scene::triangle_transmittance`]).
    pub fn visibility(&self) -> crate::visibility::Visibility {
        crate::visibility::Visibility::build(&self.triangle_corners())
            .with_transmittance(&self.triangle_transmittance())
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
pub(crate) fn source_path(source: &Option<PathBuf>) -> PathBuf {
    source
        .clone()
        .unwrap_or_else(|| PathBuf::from("<procedural scene>"))
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

    /// 50 quads in one plane, each shifted a little from the last so that all overlap:
    /// many pairs of coincident faces (z-fighting).
    pub(crate) fn stacked_quads(n: usize) -> SceneBuilder {
        let mut b = SceneBuilder::new();
        let m = b.material("grey", [0.5; 3], [0.0; 3]);
        for i in 0..n {
            let x = 0.01 * i as f64;
            b.quad(
                [
                    DVec3::new(x, 0.0, 0.0),
                    DVec3::new(x + 1.0, 0.0, 0.0),
                    DVec3::new(x + 1.0, 1.0, 0.0),
                    DVec3::new(x, 1.0, 0.0),
                ],
                m,
            );
        }
        b
    }

    #[test]
    fn a_long_list_warning_is_one_short_line_and_its_detail_holds_every_item() {
        let s = stacked_quads(50).build().unwrap();
        let pairs = checks::coincident_faces(&s.positions, &s.triangles, 2.0);
        assert!(pairs.len() > 1000, "{} pairs", pairs.len());
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        let w = &s.warnings[0];
        assert!(
            w.starts_with(&format!(
                "{} pairs of coincident overlapping faces",
                pairs.len()
            )),
            "{w}"
        );
        assert!(
            w.chars().count() < 400,
            "{} characters: {w}",
            w.chars().count()
        );
        assert!(!w.contains('\n'), "{w}");
        let more = pairs.len() - MAX_LISTED_PAIRS;
        assert!(
            w.contains(&format!("… {more} more (all in --report)")),
            "{w}"
        );
        assert_eq!(w.matches("triangles ").count(), MAX_LISTED_PAIRS, "{w}");
        // The detail: every pair, in the warning's order.
        assert_eq!(s.warning_details.len(), 1);
        let d = &s.warning_details[0];
        assert_eq!(
            (d.kind, d.count, d.items.len()),
            ("z_fighting", pairs.len(), pairs.len())
        );
        for (item, &(i, j)) in d.items.iter().zip(&pairs) {
            assert_eq!(item, &format!("triangles {i} and {j}"));
        }
        // Deterministic: the same scene, the same words.
        let again = stacked_quads(50).build().unwrap();
        assert_eq!(
            (&again.warnings, &again.warning_details),
            (&s.warnings, &s.warning_details)
        );
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
                    uv: NO_UV,
                },
                SceneTriangle {
                    vertices: [0, 1, 3],
                    material: 0,
                    uv: NO_UV,
                },
            ],
            materials: vec![Scene::default_material()],
            warnings: vec![],
            warning_details: vec![],
            twin: vec![],
            camera: None,
            lights: Vec::new(),
            sun: None,
            sky: None,
            textures: Vec::new(),
            uv_maps: Vec::new(),
        };
        let e = s.validate().unwrap_err().to_string();
        assert!(e.starts_with("x.obj: triangle 1: vertex index 3"), "{e}");
    }
}
