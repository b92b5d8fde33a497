//! Baking: from patch radiance (constant per patch) to radiance at the vertices of the output
//! mesh, for smooth vertex colours. This module owns the rule that decides which patches share
//! an output vertex:
//!
//! At each vertex of the patch mesh, the patches around it are grouped into *surfaces*: two
//! patches belong to the same surface when they have the same material and their normals
//! differ by at most the crease angle (union–find over the patches at that vertex, so a
//! smoothly curved surface stays one group). Each group becomes its own output vertex, with
//! the area-weighted mean radiance of its patches, L_v = Σ A_p L_p / Σ A_p. So the red wall does
//! not bleed into the floor's corner vertices, and a sphere stays smooth.

use crate::export::BakedMesh;
use crate::matrix::Rgb;
pub use crate::patch::DEFAULT_CREASE_DEGREES;
use crate::patch::{groups, Patches, VertexFaces};

/// Bake patch radiance into a [`BakedMesh`] (see the module documentation for the rule).
/// `radiance[i]` is patch i's radiance, W·sr⁻¹·m⁻² per channel.
pub fn bake(patches: &Patches, radiance: &[Rgb], crease_degrees: f64) -> BakedMesh {
    let cos_crease = crease_degrees.to_radians().cos();
    let nv = patches.positions.len();
    let around = VertexFaces::new(&patches.triangles, nv);

    let mut mesh = BakedMesh {
        positions: Vec::new(),
        vertex_radiance: Vec::new(),
        faces: patches.triangles.clone(),
        face_radiance: radiance.to_vec(),
        camera: None,
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
        });
        // One output vertex per group, in order of the group's first patch (deterministic).
        let first_out = mesh.positions.len();
        let mut sums: Vec<([f64; 3], f64)> = Vec::new();
        for (a, &g) in group.iter().enumerate() {
            if g == sums.len() {
                sums.push(([0.0; 3], 0.0));
            }
            let p = ps[a] as usize;
            let w = patches.area[p];
            for (s, l) in sums[g].0.iter_mut().zip(radiance[p]) {
                *s += w * l;
            }
            sums[g].1 += w;
            out_vertex[around.offset(v) + a] = (first_out + g) as u32;
        }
        let pos = patches.positions[v];
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
    mesh
}
