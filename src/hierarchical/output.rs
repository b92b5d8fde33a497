//! From leaf elements to output patches without cracks or T-junctions. A leaf whose neighbour
//! was split further has extra vertices on their shared edge (the neighbour's midpoints,
//! recursively); the leaf is then triangulated through them — a fan from the opposite corner
//! when one edge has extra vertices, else a fan from its centroid — so every output edge is
//! shared whole by the triangles on both sides and the bake's shared vertices interpolate
//! consistently. Each output triangle carries its leaf's radiance.

use super::tree::Tree;
use crate::color::Rgb;
use crate::mesh::{Parent, Patches};

/// The output of [`leaves`].
pub struct Leaves {
    /// The output patches.
    pub patches: Patches,
    /// Radiance of each, W·sr⁻¹·m⁻² per channel (its leaf's).
    pub radiance: Vec<Rgb>,
    /// The root patch each lies in.
    pub root: Vec<u32>,
}

/// The conforming triangulation of the leaves of `tree` (whose roots are `roots`), with
/// each triangle's radiance taken from `radiance` (indexed by element).
pub fn leaves(tree: &Tree, roots: &Patches, radiance: &[Rgb]) -> Leaves {
    let mut out = Patches::with_capacity(tree.positions.clone(), tree.elements.len());
    out.material_transmittance = roots.material_transmittance.clone();
    let mut out_radiance = Vec::new();
    let mut out_root = Vec::new();
    let mut chain = Vec::new();
    for root in 0..tree.roots {
        tree.leaves(root, &mut |e| {
            let el = &tree.elements[e];
            let [a, b, c] = el.vertices;
            // The boundary polygon: each corner followed by the extra vertices on the edge to
            // the next corner.
            chain.clear();
            let mut edges_with_extras = 0;
            let mut extra_edge = 0;
            for (k, (p, q)) in [(a, b), (b, c), (c, a)].into_iter().enumerate() {
                chain.push((p, k));
                let before = chain.len();
                edge_vertices(tree, p, q, k, &mut chain);
                if chain.len() > before {
                    edges_with_extras += 1;
                    extra_edge = k;
                }
            }
            let mut emit = |v: [u32; 3], out: &mut Patches| {
                push_triangle(tree, roots, e, v, out);
                out_radiance.push(radiance[e]);
                out_root.push(el.root);
            };
            match edges_with_extras {
                0 => emit([a, b, c], &mut out),
                1 => {
                    // Fan from the corner opposite the one edge with extra vertices.
                    let k = extra_edge;
                    let opposite = el.vertices[(k + 2) % 3];
                    let mut poly: Vec<u32> = chain
                        .iter()
                        .filter(|&&(_, t)| t == k)
                        .map(|&(v, _)| v)
                        .collect();
                    poly.push(el.vertices[(k + 1) % 3]);
                    for w in poly.windows(2) {
                        emit([opposite, w[0], w[1]], &mut out);
                    }
                }
                _ => {
                    let centre = out.positions.len() as u32;
                    out.positions.push(el.centroid);
                    let m = chain.len();
                    for i in 0..m {
                        emit([centre, chain[i].0, chain[(i + 1) % m].0], &mut out);
                    }
                }
            }
        });
    }
    Leaves {
        patches: out,
        radiance: out_radiance,
        root: out_root,
    }
}

/// Appends to `out` the vertices strictly inside edge (p, q), in order from p to q, made by
/// splits of this edge and of its halves (by either triangle that shares them).
fn edge_vertices(tree: &Tree, p: u32, q: u32, k: usize, out: &mut Vec<(u32, usize)>) {
    if let Some(&m) = tree.midpoints.get(&(p.min(q), p.max(q))) {
        edge_vertices(tree, p, m, k, out);
        out.push((m, k));
        edge_vertices(tree, m, q, k, out);
    }
}

/// Adds output triangle `v` (counter-clockwise, inside leaf `e`) with its geometry and the
/// leaf's material; corner normals interpolated in the leaf.
fn push_triangle(tree: &Tree, roots: &Patches, e: usize, v: [u32; 3], out: &mut Patches) {
    let el = &tree.elements[e];
    let r = el.root as usize;
    let leaf = Parent {
        corners: tree.corners(e),
        corner_normal: el.corner_normals,
        normal: el.normal,
        ..roots.parent(r)
    };
    out.push_inside(v, &leaf);
}
