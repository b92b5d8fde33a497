//! The cheap test before a trace: the boxes of the connected groups of triangles (a room's
//! few pieces of furniture, the light). A segment that meets none of them meets no triangle,
//! so [`Visibility::occluded`] answers without traversing the BVH.

use glam::{DVec3, Vec3A};

use super::{Visibility, BOX_PAD, CANONICAL_EXTENT, MAX_CLUSTERS};

impl Visibility {
    /// Boxes of the connected groups (shared corners) of the traced triangles, in scene
    /// coordinates, padded by the BVH's box padding plus 1e-6 of the extent; empty when there
    /// are more than [`MAX_CLUSTERS`] groups.
    pub(super) fn cluster_boxes(&self) -> Vec<[DVec3; 2]> {
        let mut parent: Vec<usize> = (0..self.tris.len()).collect();
        fn find(parent: &mut [usize], mut a: usize) -> usize {
            while parent[a] != a {
                parent[a] = parent[parent[a]];
                a = parent[a];
            }
            a
        }
        let mut first_at: std::collections::HashMap<[u32; 3], usize> = Default::default();
        for (k, tri) in self.tris.iter().enumerate() {
            for corner in tri {
                let key = corner.to_array().map(f32::to_bits);
                let other = *first_at.entry(key).or_insert(k);
                let (a, b) = (find(&mut parent, k), find(&mut parent, other));
                parent[a.max(b)] = a.min(b);
            }
        }
        let mut boxes: std::collections::BTreeMap<usize, [Vec3A; 2]> = Default::default();
        for (k, tri) in self.tris.iter().enumerate() {
            let root = find(&mut parent, k);
            let b = boxes
                .entry(root)
                .or_insert([Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)]);
            for c in tri {
                b[0] = b[0].min(*c);
                b[1] = b[1].max(*c);
            }
            if boxes.len() > MAX_CLUSTERS {
                return Vec::new();
            }
        }
        let pad = BOX_PAD as f64 + CANONICAL_EXTENT * 1e-6;
        boxes
            .values()
            .map(|[lo, hi]| {
                [
                    (lo.as_dvec3() - pad) / self.scale + self.centre,
                    (hi.as_dvec3() + pad) / self.scale + self.centre,
                ]
            })
            .collect()
    }

    /// True when the segment p–q meets the box of some group of triangles (or there is no
    /// such test): only then can a triangle block it.
    pub(super) fn may_block(&self, p: DVec3, q: DVec3) -> bool {
        if self.clusters.is_empty() {
            return true;
        }
        let d = q - p;
        // Per axis: 1/d (computed once for every box), or None where the segment keeps the
        // coordinate.
        let inv = [0, 1, 2].map(|k| (d[k] != 0.0).then(|| 1.0 / d[k]));
        self.clusters.iter().any(|[lo, hi]| {
            // Slab test of the segment x(t) = p + t·d, t ∈ [0, 1], against [lo, hi].
            let (mut t0, mut t1) = (0.0f64, 1.0f64);
            for k in 0..3 {
                let Some(inv) = inv[k] else {
                    if p[k] < lo[k] || p[k] > hi[k] {
                        return false;
                    }
                    continue;
                };
                let (a, b) = ((lo[k] - p[k]) * inv, (hi[k] - p[k]) * inv);
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
                if t0 > t1 {
                    return false;
                }
            }
            true
        })
    }
}
