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

use std::collections::HashMap;

use glam::DVec3;

use crate::scene::Scene;
use crate::{Error, Result};

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
}

impl Patches {
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
            self.area.len(),
            self.material.len(),
            self.reflectance.len(),
            self.emission.len(),
            self.source_triangle.len(),
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

/// Subdivide every scene triangle until no patch edge is longer than `max_edge` (scene
/// units). Conforming: see the module documentation.
pub fn subdivide(scene: &Scene, max_edge: f64) -> Result<Patches> {
    if !(max_edge > 0.0 && max_edge.is_finite()) {
        return Err(Error::usage(
            "--max-edge",
            format!("{max_edge} is not a positive length"),
        ));
    }
    // Guard: each patch has area at most √3/4·max_edge², and the subdivision keeps areas
    // within a constant factor of that; refuse before allocating absurd amounts.
    let total_area: f64 = (0..scene.triangles.len())
        .map(|t| scene.triangle_area(t))
        .sum();
    let estimate = total_area / (0.1 * max_edge * max_edge);
    if estimate > MAX_PATCHES as f64 {
        return Err(Error::usage(
            "--max-edge",
            format!(
                "{max_edge} is too small for this scene: it would make about {estimate:.3e} \
                 patches (the limit is {MAX_PATCHES})"
            ),
        ));
    }

    let mut positions = scene.positions.clone();
    // (triangle, source triangle index)
    let mut tris: Vec<([u32; 3], u32)> = scene
        .triangles
        .iter()
        .enumerate()
        .map(|(i, t)| (t.vertices, i as u32))
        .collect();
    let limit2 = (max_edge * (1.0 + 1e-12)).powi(2);
    loop {
        let long = |a: u32, b: u32, positions: &[DVec3]| {
            positions[a as usize].distance_squared(positions[b as usize]) > limit2
        };
        if !tris
            .iter()
            .any(|(t, _)| (0..3).any(|k| long(t[k], t[(k + 1) % 3], &positions)))
        {
            break;
        }
        let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(tris.len() * 4);
        for &(t, src) in &tris {
            // m[k] = midpoint of edge (t[k], t[k+1]) if that edge is split.
            let mut m = [None; 3];
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                if long(a, b, &positions) {
                    let key = (a.min(b), a.max(b));
                    let id = *midpoints.entry(key).or_insert_with(|| {
                        positions.push(0.5 * (positions[a as usize] + positions[b as usize]));
                        (positions.len() - 1) as u32
                    });
                    m[k] = Some(id);
                }
            }
            split_triangle(t, m, &positions, |c| next.push((c, src)));
        }
        tris = next;
        if tris.len() > MAX_PATCHES {
            return Err(Error::usage(
                "--max-edge",
                format!("{max_edge} makes more than {MAX_PATCHES} patches"),
            ));
        }
    }

    let n = tris.len();
    let mut patches = Patches {
        positions,
        triangles: Vec::with_capacity(n),
        centroid: Vec::with_capacity(n),
        normal: Vec::with_capacity(n),
        area: Vec::with_capacity(n),
        material: Vec::with_capacity(n),
        reflectance: Vec::with_capacity(n),
        emission: Vec::with_capacity(n),
        source_triangle: Vec::with_capacity(n),
    };
    for (t, src) in tris {
        let [a, b, c] = t.map(|v| patches.positions[v as usize]);
        let cross = (b - a).cross(c - a);
        let area = 0.5 * cross.length();
        if area.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            // A midpoint split of a non-degenerate triangle never makes a zero-area child;
            // the scene loader already dropped degenerate input triangles.
            return Err(Error::Internal(format!(
                "zero-area patch cut from scene triangle {src}"
            )));
        }
        let material = scene.triangles[src as usize].material;
        let mat = &scene.materials[material as usize];
        patches.triangles.push(t);
        patches.centroid.push((a + b + c) / 3.0);
        patches.normal.push(cross / (2.0 * area));
        patches.area.push(area);
        patches.material.push(material);
        patches.reflectance.push(mat.reflectance);
        patches.emission.push(mat.emission);
        patches.source_triangle.push(src);
    }
    Ok(patches)
}

/// Re-triangulate triangle `t` (counter-clockwise) given the midpoints `m[k]` of the split
/// edges (t[k], t[k+1]); children keep the parent's orientation.
fn split_triangle(
    t: [u32; 3],
    m: [Option<u32>; 3],
    positions: &[DVec3],
    mut emit: impl FnMut([u32; 3]),
) {
    let count = m.iter().filter(|x| x.is_some()).count();
    match count {
        0 => emit(t),
        3 => {
            let (ab, bc, ca) = (m[0].unwrap(), m[1].unwrap(), m[2].unwrap());
            emit([t[0], ab, ca]);
            emit([ab, t[1], bc]);
            emit([ca, bc, t[2]]);
            emit([ab, bc, ca]);
        }
        1 => {
            // Rotate so that the split edge is (a, b).
            let k = m.iter().position(|x| x.is_some()).unwrap();
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            let mid = m[k].unwrap();
            emit([a, mid, c]);
            emit([mid, b, c]);
        }
        _ => {
            // Rotate so that the unsplit edge is (c, a): split edges are (a, b) and (b, c).
            let k = m.iter().position(|x| x.is_none()).unwrap();
            let (a, b, c) = (t[(k + 1) % 3], t[(k + 2) % 3], t[k]);
            let (mab, mbc) = (m[(k + 1) % 3].unwrap(), m[(k + 2) % 3].unwrap());
            emit([mab, b, mbc]);
            // The remaining quad a, mab, mbc, c: cut along its shorter diagonal.
            // Ties (common in regular meshes) go to the first diagonal; the relative margin,
            // far above f64 rounding, keeps that choice the same in any unit of length.
            let p = |v: u32| positions[v as usize];
            let (d1, d2) = (p(a).distance_squared(p(mbc)), p(mab).distance_squared(p(c)));
            if d1 <= d2 * (1.0 + 1e-9) {
                emit([a, mab, mbc]);
                emit([a, mbc, c]);
            } else {
                emit([a, mab, c]);
                emit([mab, mbc, c]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::SceneBuilder;

    fn two_quads() -> Scene {
        // An L: a floor quad and a wall quad sharing the edge x ∈ [0, 1], y = z = 0.
        let mut b = SceneBuilder::new();
        let m = b.material("white", [0.5; 3], [0.0; 3]);
        b.quad(
            [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(0.0, 0.0, 1.0),
                DVec3::new(1.0, 0.0, 1.0),
                DVec3::new(1.0, 0.0, 0.0),
            ],
            m,
        );
        b.quad(
            [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(1.0, 0.7, 0.0),
                DVec3::new(0.0, 0.7, 0.0),
            ],
            m,
        );
        b.build().unwrap()
    }

    #[test]
    fn subdivision_preserves_area_orientation_and_edge_bound() {
        let scene = two_quads();
        for max_edge in [2.0, 0.5, 0.3, 0.11, 0.05] {
            let p = subdivide(&scene, max_edge).unwrap();
            p.validate().unwrap();
            // Area is preserved exactly up to rounding (children tile the parent).
            assert!((p.total_area() - 1.7).abs() < 1e-12, "{}", p.total_area());
            for i in 0..p.len() {
                let c = p.corners(i);
                for k in 0..3 {
                    assert!(c[k].distance(c[(k + 1) % 3]) <= max_edge * (1.0 + 1e-9));
                }
                // Children keep the parent's normal.
                let parent = p.source_triangle[i] as usize;
                let t = scene.triangles[parent]
                    .vertices
                    .map(|v| scene.positions[v as usize]);
                let n0 = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
                assert!(p.normal[i].dot(n0) > 1.0 - 1e-12);
            }
        }
    }

    #[test]
    fn subdivision_is_conforming() {
        // Conforming ⇔ every edge of the patch mesh is used by exactly two patches (interior
        // or shared edge) or by one (open boundary of the input), and every boundary edge
        // lies on a boundary edge of the input: count edge uses, each once per direction.
        let scene = two_quads();
        let p = subdivide(&scene, 0.13).unwrap();
        let mut uses: HashMap<(u32, u32), i32> = HashMap::new();
        for t in &p.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        assert!(uses.values().all(|&u| u == 1 || u == 2));
        // A T-junction would leave a vertex lying in the interior of some other edge.
        for (&(a, b), _) in uses.iter().filter(|(_, &u)| u == 1) {
            let (pa, pb) = (p.positions[a as usize], p.positions[b as usize]);
            for (v, &q) in p.positions.iter().enumerate() {
                if v as u32 == a || v as u32 == b {
                    continue;
                }
                let t = (q - pa).dot(pb - pa) / (pb - pa).length_squared();
                let off = (pa + t * (pb - pa)).distance(q);
                assert!(
                    !(t > 1e-9 && t < 1.0 - 1e-9 && off < 1e-12),
                    "T-junction at {q}"
                );
            }
        }
    }

    #[test]
    fn bad_max_edge_is_a_usage_error() {
        let scene = two_quads();
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e-9] {
            let err = subdivide(&scene, bad).unwrap_err();
            assert!(matches!(err, Error::Usage { .. }), "{bad}: {err}");
        }
    }
}
