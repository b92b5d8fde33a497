//! Patches: the finite elements of the radiosity solve. This module owns the conforming
//! subdivision of the scene's triangles into patches no longer than `max_edge`, and each
//! patch's geometry (vertices, centroid, unit normal, area) and material (ρ, Le). It does not
//! know about rays or form factors.
//!
//! Subdivision is edge-based and therefore conforming: every round splits *every* edge longer
//! than `max_edge` at its midpoint, the midpoint is shared by both triangles on that edge (an
//! edge is keyed by its two vertex indices), and each triangle is re-triangulated according to
//! how many of its edges were split (1 → 2 children, 2 → 3, 3 → 4, the classic red/green
//! refinement). Neighbouring patches therefore always share vertices: no T-junctions appear
//! that were not already in the input.
//!
//! Two-sided scenes ([`Scene::make_two_sided`]): only one triangle of each twin pair is
//! subdivided; the other's patches are its patches mirrored (reversed winding, negated normals,
//! the same corners at their own copies of the vertices), appended after all others and linked
//! in [`Patches::twin`]. Subdividing both would not do: the re-triangulation breaks ties by
//! vertex order, which the reversal changes, so twins could be cut differently.

pub(crate) mod adjacency;
pub mod discontinuity;
mod normals;
pub mod refine;
mod subdivide;

pub(crate) use adjacency::{groups, VertexFaces};
pub use discontinuity::{
    contact_lines, contact_lines_on, display_lines_on, split_contacts, split_patches, sun_lines,
    ContactStats, Discontinuities, Split,
};
pub use normals::corner_normals;
pub(crate) use subdivide::barycentric;
pub use subdivide::{refine, subdivide};

use glam::DVec3;

use crate::scene::{Scene, NO_TWIN};
use crate::{Error, Result};

/// Default crease angle, degrees. Where the faces around a vertex meet at angles up to this,
/// the mesh is taken to sample one smooth surface: the form factors use its interpolated
/// normal ([`corner_normals`]) and the bake shares the vertex. 30° keeps tessellated spheres
/// of a few hundred faces smooth (neighbour normals differ by ≲ 15°) while every corner of a
/// room or box (90°) stays sharp.
pub const DEFAULT_CREASE_DEGREES: f64 = 30.0;

/// Refuse subdivisions that would make more patches than this (memory and time guard).
pub const MAX_PATCHES: usize = 20_000_000;

/// The patch mesh. All vectors indexed by patch have the same length; patch `i`'s triangle is
/// `triangles[i]`, counter-clockwise seen from its front (emitting and reflecting) side.
#[derive(Debug, Clone)]
pub struct Patches {
    /// Vertex positions of the patch mesh, scene units. Shared between neighbouring patches.
    pub positions: Vec<DVec3>,
    /// Vertex indices of each patch, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
    /// Centroid of each patch, scene units.
    pub centroid: Vec<DVec3>,
    /// Unit normal of each patch (front side, right-hand rule on the vertex order).
    pub normal: Vec<DVec3>,
    /// Normal of the smooth surface the mesh approximates, at each corner of each patch
    /// (interpolated from the input mesh's vertex normals, [`corner_normals`]). Not unit
    /// length: interpolate linearly, then normalise ([`Patches::surface_normal`]). Equals
    /// `normal` on flat surfaces and wherever the crease angle is 0.
    pub corner_normal: Vec<[DVec3; 3]>,
    /// Area of each patch, scene units squared; > 0.
    pub area: Vec<f64>,
    /// Index into the scene's materials.
    pub material: Vec<u32>,
    /// ρ, diffuse reflectance per RGB channel, in [0, 1].
    pub reflectance: Vec<[f64; 3]>,
    /// Le, emitted radiance per RGB channel, W·sr⁻¹·m⁻², ≥ 0.
    pub emission: Vec<[f64; 3]>,
    /// Index of the scene triangle each patch was cut from.
    pub source_triangle: Vec<u32>,
    /// The patch on the other side of the same surface ([`NO_TWIN`] for none: every patch of a
    /// one-sided scene). Invariants: `twin[twin[i]] == i`; twins have the same corners (at
    /// different vertex indices) in reverse order, opposite normals, the same area, and come
    /// from twin scene triangles.
    pub twin: Vec<u32>,
    /// The transmittance t of each of the scene's materials (indexed like
    /// [`Patches::material`]'s values, not by patch; [`crate::scene::Material::transmittance`]):
    /// empty when every material is opaque. [`Patches::transmittance`] gives it per patch.
    pub material_transmittance: Vec<f64>,
}

/// What a triangle cut from a larger one takes from it ([`Patches::push_inside`]).
pub(crate) struct Parent {
    /// Its corners, scene units.
    pub corners: [DVec3; 3],
    /// Its corner normals (not unit length, see [`Patches::corner_normal`]).
    pub corner_normal: [DVec3; 3],
    /// Its unit front normal.
    pub normal: DVec3,
    /// Its material, ρ and Le (see the fields of [`Patches`]).
    pub material: u32,
    pub reflectance: [f64; 3],
    pub emission: [f64; 3],
    /// The scene triangle it was cut from.
    pub source_triangle: u32,
}

impl Patches {
    /// No patches yet over the vertices `positions`, with room for `n`.
    pub fn with_capacity(positions: Vec<DVec3>, n: usize) -> Patches {
        Patches {
            positions,
            triangles: Vec::with_capacity(n),
            centroid: Vec::with_capacity(n),
            normal: Vec::with_capacity(n),
            corner_normal: Vec::with_capacity(n),
            area: Vec::with_capacity(n),
            material: Vec::with_capacity(n),
            reflectance: Vec::with_capacity(n),
            emission: Vec::with_capacity(n),
            source_triangle: Vec::with_capacity(n),
            twin: Vec::with_capacity(n),
            material_transmittance: Vec::new(),
        }
    }

    /// The share 1 − t of patch `i`'s area its material covers ([`Patches::transmittance`]):
    /// 1 for an opaque patch.
    pub fn coverage(&self, i: usize) -> f64 {
        1.0 - self
            .material_transmittance
            .get(self.material[i] as usize)
            .copied()
            .unwrap_or(0.0)
    }

    /// Patch `i`'s emission as the light its whole area sends, W·sr⁻¹·m⁻² per channel: Le
    /// times the covered share ([`Patches::coverage`]); Le itself for an opaque patch. What
    /// emitters' exact direct light uses.
    pub fn sent_emission(&self, i: usize) -> [f64; 3] {
        let c = self.coverage(i);
        self.emission[i].map(|e| e * c)
    }

    /// The transmittance t in [0, 1] of each patch ([`Patches::material_transmittance`]),
    /// for [`crate::visibility::Visibility::with_transmittance`]; empty when every patch is
    /// opaque.
    pub fn transmittance(&self) -> Vec<f64> {
        if !self.material_transmittance.iter().any(|&t| t > 0.0) {
            return Vec::new();
        }
        self.material
            .iter()
            .map(|&m| {
                self.material_transmittance
                    .get(m as usize)
                    .copied()
                    .unwrap_or(0.0)
            })
            .collect()
    }

    /// Number of patches.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// True when there are no patches.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// The three corners of patch `i`, scene units.
    #[inline]
    pub fn corners(&self, i: usize) -> [DVec3; 3] {
        let [a, b, c] = self.triangles[i];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Unit surface normal at the point with barycentric coordinates `b` (weights of the
    /// corners, summing to 1) of patch `i`: the smooth surface's normal where the mesh is
    /// smooth ([`corner_normals`]), the patch's own normal on flat surfaces. This is the
    /// normal the form-factor kernels take at a receiving point (cosθ of the receiver).
    #[inline]
    pub fn surface_normal(&self, i: usize, b: [f64; 3]) -> DVec3 {
        let m = self.corner_normal[i];
        let n = b[0] * m[0] + b[1] * m[1] + b[2] * m[2];
        // Corner normals lie within the crease angle (< 90°) of the patch normal, so their
        // convex combination cannot vanish; the fallback only guards rounding.
        n.try_normalize().unwrap_or(self.normal[i])
    }

    /// Appends the triangle `t` (vertex indices into `positions`, counter-clockwise) lying in
    /// the plane of `parent` and inside it: its own centroid and area, `parent`'s normal and
    /// material, and its corner normals interpolated in `parent` (so that interpolating them
    /// inside it is interpolation in `parent`). Used where a patch or an element is cut
    /// further (the hierarchy's output, the display cut along contact lines).
    pub(crate) fn push_inside(&mut self, t: [u32; 3], parent: &Parent) {
        let p = t.map(|v| self.positions[v as usize]);
        let m = parent.corner_normal;
        let normal_at = |x: DVec3| {
            let b = barycentric(x, parent.corners);
            b[0] * m[0] + b[1] * m[1] + b[2] * m[2]
        };
        self.triangles.push(t);
        self.centroid.push((p[0] + p[1] + p[2]) / 3.0);
        self.normal.push(parent.normal);
        self.corner_normal.push(p.map(normal_at));
        self.area
            .push(0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length());
        self.material.push(parent.material);
        self.reflectance.push(parent.reflectance);
        self.emission.push(parent.emission);
        self.source_triangle.push(parent.source_triangle);
        self.twin.push(NO_TWIN);
    }

    /// Patch `i` as the [`Parent`] of triangles cut from it.
    pub(crate) fn parent(&self, i: usize) -> Parent {
        Parent {
            corners: self.corners(i),
            corner_normal: self.corner_normal[i],
            normal: self.normal[i],
            material: self.material[i],
            reflectance: self.reflectance[i],
            emission: self.emission[i],
            source_triangle: self.source_triangle[i],
        }
    }

    /// Total area of all patches, scene units squared.
    pub fn total_area(&self) -> f64 {
        self.area.iter().sum()
    }

    /// Check the invariants documented on the fields.
    pub fn validate(&self) -> Result<()> {
        let n = self.len();
        let lengths = [
            self.centroid.len(),
            self.normal.len(),
            self.corner_normal.len(),
            self.area.len(),
            self.material.len(),
            self.reflectance.len(),
            self.emission.len(),
            self.source_triangle.len(),
            self.twin.len(),
        ];
        if lengths.iter().any(|&l| l != n) {
            return Err(Error::Internal(format!(
                "patch arrays disagree in length: {n} triangles vs {lengths:?}"
            )));
        }
        for i in 0..n {
            if self.triangles[i]
                .iter()
                .any(|&v| v as usize >= self.positions.len())
            {
                return Err(Error::Internal(format!(
                    "patch {i}: vertex index out of range"
                )));
            }
            if !(self.area[i] > 0.0 && self.area[i].is_finite()) {
                return Err(Error::Internal(format!(
                    "patch {i}: area {} ≤ 0",
                    self.area[i]
                )));
            }
            if (self.normal[i].length() - 1.0).abs() > 1e-9 {
                return Err(Error::Internal(format!("patch {i}: normal not unit")));
            }
            if self.corner_normal[i]
                .iter()
                .any(|m| !m.is_finite() || m.dot(self.normal[i]) <= 0.0)
            {
                return Err(Error::Internal(format!(
                    "patch {i}: a corner normal faces away from the patch's front"
                )));
            }
            let u = self.twin[i];
            if u != NO_TWIN {
                let ok = (u as usize) < n
                    && self.twin[u as usize] == i as u32
                    && self.corners(u as usize) == {
                        let [a, b, c] = self.corners(i);
                        [a, c, b]
                    };
                if !ok {
                    return Err(Error::Internal(format!(
                        "patch {i}: twin {u} is not its mirror image"
                    )));
                }
            }
            let ok_rho = self.reflectance[i].iter().all(|r| (0.0..=1.0).contains(r));
            let ok_le = self.emission[i].iter().all(|e| e.is_finite() && *e >= 0.0);
            if !ok_rho || !ok_le {
                return Err(Error::Internal(format!("patch {i}: material out of range")));
            }
        }
        Ok(())
    }
}

/// The default patch size: the scene's bounding-box diagonal / 16. For the Cornell box
/// (diagonal ≈ 963 mm) that is ≈ 60 mm, which gives about three thousand patches.
pub fn default_max_edge(scene: &Scene) -> f64 {
    let (lo, hi) = scene.bounds();
    (hi - lo).length() / 16.0
}

#[cfg(test)]
mod tests;
