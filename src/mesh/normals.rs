//! The smooth surface a mesh samples: vertex normals where faces meet within the crease angle
//! (Max's weights), interpolated to each patch corner, so the receiving cosine is second-order
//! accurate on curved surfaces.

use glam::DVec3;

use super::adjacency::{groups, VertexFaces};
use crate::scene::{Scene, NO_TWIN};

/// Normals of the smooth surface the scene's mesh approximates, at each corner of each scene
/// triangle: where the triangles around a vertex meet at angles up to `crease_degrees`
/// (grouped transitively, as the bake groups patches), they are taken to sample one smooth
/// surface and share that vertex's normal; across sharper edges each side keeps its own.
///
/// A flat facet's normal is only a first-order approximation of a curved surface's: on a
/// tessellated sphere it is off by up to half the angle between neighbouring facets, and the
/// receiving cosine inherits that O(h) error (on the integrating sphere, largest next to the
/// emitting cap). Interpolated vertex normals make the receiving cosine second-order accurate
/// (the fitted orders in BENCHMARKS.md "Accuracy against closed forms"). The vertex normal is
/// the weighted sum of the facet normals of its group with Max's weights,
/// (e₁ × e₂)/(|e₁|²|e₂|²) for a facet with edges e₁, e₂ leaving the vertex (N. Max, "Weights
/// for computing vertex normals from facet normals", JGT 4(2), 1999), which is exact for any
/// triangles whose corners lie on a sphere. A group whose weighted sum is not within 90° of a
/// member facet's normal (a folded fan) falls back to that facet's own normal.
///
/// In a two-sided scene the back of each twin pair (the later triangle) takes no part in the
/// grouping and gets the negated corner normals of its front, so the front's normals are those
/// of the one-sided scene.
pub fn corner_normals(scene: &Scene, crease_degrees: f64) -> Vec<[DVec3; 3]> {
    // The backs of twin pairs, mirrored at the end.
    let back = |t: usize| {
        scene
            .twin
            .get(t)
            .is_some_and(|&u| u != NO_TWIN && (u as usize) < t)
    };
    let facet: Vec<DVec3> = scene
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.vertices.map(|v| scene.positions[v as usize]);
            (b - a).cross(c - a).normalize()
        })
        .collect();
    let mut out: Vec<[DVec3; 3]> = facet.iter().map(|&n| [n; 3]).collect();
    if crease_degrees <= 0.0 {
        return out;
    }
    let cos_crease = crease_degrees.to_radians().cos();
    let tris: Vec<[u32; 3]> = scene.triangles.iter().map(|t| t.vertices).collect();
    // Backs are left out of the incidence lists (a triangle with no corners).
    let fronts: Vec<[u32; 3]> = (0..tris.len())
        .map(|t| if back(t) { [u32::MAX; 3] } else { tris[t] })
        .collect();
    let around = VertexFaces::new(&fronts, scene.positions.len());
    for v in 0..scene.positions.len() {
        let faces = around.faces(v);
        let group = groups(faces.len(), |a, b| {
            facet[faces[a] as usize].dot(facet[faces[b] as usize]) >= cos_crease
        });
        // Max's weighted facet normal of each face at v.
        let weighted: Vec<DVec3> = faces
            .iter()
            .map(|&f| {
                let t = tris[f as usize];
                let k = t.iter().position(|&u| u as usize == v).expect("face at v");
                let p = |u: u32| scene.positions[u as usize];
                let (e1, e2) = (p(t[(k + 1) % 3]) - p(t[k]), p(t[(k + 2) % 3]) - p(t[k]));
                e1.cross(e2) / (e1.length_squared() * e2.length_squared())
            })
            .collect();
        for (a, &f) in faces.iter().enumerate() {
            let sum: DVec3 = (0..faces.len())
                .filter(|&b| group[b] == group[a])
                .map(|b| weighted[b])
                .sum();
            let n = sum.normalize_or_zero();
            let k = tris[f as usize]
                .iter()
                .position(|&u| u as usize == v)
                .expect("face at v");
            if n.dot(facet[f as usize]) > 0.0 {
                out[f as usize][k] = n;
            }
        }
    }
    for t in (0..tris.len()).filter(|&t| back(t)) {
        let front = scene.twin[t] as usize;
        out[t] = tris[t].map(|v| {
            let k = tris[front].iter().position(|&w| w == v).unwrap_or(0);
            -out[front][k]
        });
    }
    out
}
