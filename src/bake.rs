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
use crate::patch::Patches;

/// Default crease angle, degrees: normals differing by more split the vertex. 30° keeps
/// tessellated spheres of a few hundred faces smooth (neighbour normals differ by ≲ 15°) while
/// splitting every corner of a room or box (90°).
pub const DEFAULT_CREASE_DEGREES: f64 = 30.0;

/// Bake patch radiance into a [`BakedMesh`] (see the module documentation for the rule).
/// `radiance[i]` is patch i's radiance, W·sr⁻¹·m⁻² per channel.
pub fn bake(patches: &Patches, radiance: &[Rgb], crease_degrees: f64) -> BakedMesh {
    let cos_crease = crease_degrees.to_radians().cos();
    let nv = patches.positions.len();
    // Patches around each vertex (CSR-like: offsets + list), in increasing patch order.
    let mut offsets = vec![0usize; nv + 1];
    for t in &patches.triangles {
        for &v in t {
            offsets[v as usize + 1] += 1;
        }
    }
    for v in 0..nv {
        offsets[v + 1] += offsets[v];
    }
    let mut around = vec![0u32; offsets[nv]];
    let mut fill = offsets.clone();
    for (p, t) in patches.triangles.iter().enumerate() {
        for &v in t {
            around[fill[v as usize]] = p as u32;
            fill[v as usize] += 1;
        }
    }

    let mut mesh = BakedMesh {
        positions: Vec::new(),
        vertex_radiance: Vec::new(),
        faces: patches.triangles.clone(),
        face_radiance: radiance.to_vec(),
    };
    // out_vertex[slot in `around`] = output vertex of that (vertex, patch) incidence.
    let mut out_vertex = vec![u32::MAX; around.len()];
    let mut parent: Vec<usize> = Vec::new();
    for v in 0..nv {
        let ps = &around[offsets[v]..offsets[v + 1]];
        if ps.is_empty() {
            continue;
        }
        // Union–find over the patches at v.
        parent.clear();
        parent.extend(0..ps.len());
        fn find(parent: &mut [usize], mut a: usize) -> usize {
            while parent[a] != a {
                parent[a] = parent[parent[a]];
                a = parent[a];
            }
            a
        }
        for a in 0..ps.len() {
            for b in a + 1..ps.len() {
                let (pa, pb) = (ps[a] as usize, ps[b] as usize);
                if patches.material[pa] == patches.material[pb]
                    && patches.normal[pa].dot(patches.normal[pb]) >= cos_crease
                {
                    let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
                    if ra != rb {
                        parent[ra.max(rb)] = ra.min(rb);
                    }
                }
            }
        }
        // One output vertex per group, in order of the group's first patch (deterministic).
        let first_out = mesh.positions.len();
        let mut group_out = vec![usize::MAX; ps.len()];
        let mut sums: Vec<([f64; 3], f64)> = Vec::new();
        for a in 0..ps.len() {
            let root = find(&mut parent, a);
            if group_out[root] == usize::MAX {
                group_out[root] = sums.len();
                sums.push(([0.0; 3], 0.0));
            }
            let g = group_out[root];
            let p = ps[a] as usize;
            let w = patches.area[p];
            for (s, l) in sums[g].0.iter_mut().zip(radiance[p]) {
                *s += w * l;
            }
            sums[g].1 += w;
            out_vertex[offsets[v] + a] = (first_out + g) as u32;
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
            let slot = around[offsets[vi]..offsets[vi + 1]]
                .iter()
                .position(|&q| q as usize == p)
                .expect("every patch is listed at its own vertices");
            *v = out_vertex[offsets[vi] + slot];
        }
    }
    mesh
}
