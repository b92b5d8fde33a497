//! Likely modelling mistakes that are not errors: coincident overlapping faces (z-fighting)
//! and inconsistent winding between neighbouring faces. This module only finds them (as
//! pairs of triangle indices, in a deterministic order); `scene::finish` turns them into
//! warnings and decides what happens (both faces are kept, see [`coincident_faces`]).
//!
//! Both checks are cheap: O(n log n) in the number of triangles, never all pairs.

use std::collections::HashMap;

use glam::{DVec2, DVec3};

use super::SceneTriangle;

/// Planes are bucketed by their unit normal and their offset (relative to the scene's
/// bounding-box diagonal) rounded to this step. Faces in the same plane computed from
/// different corners differ by rounding (~1e-16), far below the step, so they land in the
/// same bucket unless a coordinate sits within ~1e-16 of a rounding boundary. Axis-aligned
/// planes (the usual case: a light in a ceiling) have exact normals and offsets and are
/// never missed.
pub const PLANE_KEY_STEP: f64 = 1e-9;

/// Pairs (i, j), i < j, of triangles that lie in the same plane, face the same way, and
/// whose interiors overlap (touching along an edge or at a corner does not count). Sorted.
///
/// What a pair means for the solve, and why both faces are kept: the two faces occupy the
/// same surface, so every estimator sees the overlap twice over (the contour and area
/// estimators count light exchanged with both; the hemisphere estimator sends each ray to
/// whichever face the BVH reports first at equal distance, deterministically for a given
/// scene). Dropping either face would be worse: a light in a ceiling's plane is usually the
/// later, smaller face, and dropping the ceiling instead would open a hole. So the faces are
/// kept and the warning asks the user to move one off the plane or cut a hole.
///
/// Faces in the same plane facing opposite ways (a two-sided thin wall) are not reported.
pub fn coincident_faces(
    positions: &[DVec3],
    triangles: &[SceneTriangle],
    diagonal: f64,
) -> Vec<(usize, usize)> {
    if diagonal.is_nan() || diagonal <= 0.0 {
        return Vec::new();
    }
    let mut buckets: HashMap<[i64; 4], Vec<usize>> = HashMap::new();
    for (t, tri) in triangles.iter().enumerate() {
        let [a, b, c] = tri.vertices.map(|v| positions[v as usize]);
        let n = (b - a).cross(c - a).normalize();
        if !n.is_finite() {
            continue;
        }
        // Offset of the plane from the origin through the centroid (symmetric in the corners).
        let d = n.dot((a + b + c) / 3.0) / diagonal;
        let q = |x: f64| (x / PLANE_KEY_STEP).round() as i64;
        buckets
            .entry([q(n.x), q(n.y), q(n.z), q(d)])
            .or_default()
            .push(t);
    }
    let mut pairs = Vec::new();
    for members in buckets.values().filter(|m| m.len() > 1) {
        // Project onto the plane's dominant axis and sweep along the first 2D coordinate.
        let t0 = &triangles[members[0]];
        let [a, b, c] = t0.vertices.map(|v| positions[v as usize]);
        let n = (b - a).cross(c - a).abs();
        let drop_axis = if n.x >= n.y && n.x >= n.z {
            0
        } else if n.y >= n.z {
            1
        } else {
            2
        };
        let project = |p: DVec3| match drop_axis {
            0 => DVec2::new(p.y, p.z),
            1 => DVec2::new(p.z, p.x),
            _ => DVec2::new(p.x, p.y),
        };
        let mut items: Vec<(usize, [DVec2; 3], DVec2, DVec2)> = members
            .iter()
            .map(|&t| {
                let p = triangles[t]
                    .vertices
                    .map(|v| project(positions[v as usize]));
                let lo = p[0].min(p[1]).min(p[2]);
                let hi = p[0].max(p[1]).max(p[2]);
                (t, p, lo, hi)
            })
            .collect();
        items.sort_by(|x, y| x.2.x.total_cmp(&y.2.x).then(x.0.cmp(&y.0)));
        for (k, (ti, pi, lo_i, hi_i)) in items.iter().enumerate() {
            for (tj, pj, lo_j, hi_j) in &items[k + 1..] {
                if lo_j.x >= hi_i.x {
                    break;
                }
                if lo_j.y >= hi_i.y || lo_i.y >= hi_j.y {
                    continue;
                }
                if interiors_overlap(pi, pj) {
                    pairs.push((*ti.min(tj), *ti.max(tj)));
                }
            }
        }
    }
    pairs.sort_unstable();
    pairs
}

/// True if two 2D triangles' interiors intersect. Separating-axis test over the six edge
/// normals: convex polygons have disjoint interiors iff some edge normal separates them,
/// touching counted as separated. Sharing an edge is therefore not an overlap; the slack of
/// 1e-9 of the triangles' extent absorbs the rounding of the projection.
fn interiors_overlap(a: &[DVec2; 3], b: &[DVec2; 3]) -> bool {
    let extent = a
        .iter()
        .chain(b)
        .fold(0.0f64, |m, p| m.max(p.x.abs()).max(p.y.abs()));
    for tri in [a, b] {
        for k in 0..3 {
            let e = tri[(k + 1) % 3] - tri[k];
            let axis = DVec2::new(-e.y, e.x);
            let slack = 1e-9 * extent * axis.length();
            let range = |t: &[DVec2; 3]| {
                t.iter()
                    .map(|p| axis.dot(*p))
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                        (lo.min(x), hi.max(x))
                    })
            };
            let (lo_a, hi_a) = range(a);
            let (lo_b, hi_b) = range(b);
            if hi_a <= lo_b + slack || hi_b <= lo_a + slack {
                return false;
            }
        }
    }
    true
}

/// Pairs (i, j), i < j, of triangles that use the same edge in the same direction: seen from
/// one side, one turns counter-clockwise and the other clockwise, so one of them faces the
/// wrong way (a flipped face). Consistently oriented neighbours traverse a shared edge in
/// opposite directions. Only edges with exactly two faces are judged: where more meet (two
/// closed boxes touching along an edge, such as an L-shaped counter's two blocks), faces of
/// different solids run the edge the same way with nothing flipped. Each pair once, sorted;
/// triangles must be welded (shared corners share indices), as `scene::finish` ensures.
pub fn inconsistent_winding(triangles: &[SceneTriangle]) -> Vec<(usize, usize)> {
    // Each undirected edge's faces, by a sorted list of (edge, forward, triangle): a run of
    // equal edges is the edge's faces.
    let mut uses: Vec<((u32, u32), bool, usize)> = Vec::with_capacity(3 * triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        let v = tri.vertices;
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            if a != b {
                uses.push(((a.min(b), a.max(b)), a < b, t));
            }
        }
    }
    uses.sort_unstable();
    let mut pairs: Vec<(usize, usize)> = uses
        .chunk_by(|x, y| x.0 == y.0)
        .filter_map(|run| match run {
            [(_, d, s), (_, e, t)] if d == e && s != t => Some((*s.min(t), *s.max(t))),
            _ => None,
        })
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(v: [u32; 3]) -> SceneTriangle {
        SceneTriangle {
            vertices: v,
            material: 0,
            uv: crate::scene::NO_UV,
        }
    }

    #[test]
    fn overlap_found_but_shared_edges_and_opposite_faces_are_not() {
        let p = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(0.2, 0.1, 0.0),
            DVec3::new(0.6, 0.1, 0.0),
            DVec3::new(0.6, 0.5, 0.0),
        ];
        // A quad (0, 1, 2) + (0, 2, 3): shares an edge, no overlap.
        let quad = [tri([0, 1, 2]), tri([0, 2, 3])];
        assert!(coincident_faces(&p, &quad, 2.0).is_empty());
        // A small triangle inside the first half, same facing: overlap.
        let mut with_light = quad.to_vec();
        with_light.push(tri([4, 5, 6]));
        assert_eq!(coincident_faces(&p, &with_light, 2.0), [(0, 2)]);
        // The same triangle facing the other way (back to back): not reported.
        let mut back = quad.to_vec();
        back.push(tri([4, 6, 5]));
        assert!(coincident_faces(&p, &back, 2.0).is_empty());
        // Lifted off the plane by 1e-3: not coplanar.
        let mut q = p.clone();
        for v in &mut q[4..] {
            v.z = 1e-3;
        }
        assert!(coincident_faces(&q, &with_light, 2.0).is_empty());
    }

    #[test]
    fn winding_flags_same_direction_edges_only() {
        // (0,1,2) and (0,2,3) traverse 0–2 in opposite directions: consistent.
        assert!(inconsistent_winding(&[tri([0, 1, 2]), tri([0, 2, 3])]).is_empty());
        // (0,3,2) is the second face flipped: both traverse 2→0.
        assert_eq!(
            inconsistent_winding(&[tri([0, 1, 2]), tri([0, 3, 2])]),
            [(0, 1)]
        );
        // Listed once even when the pair shares more than one edge direction.
        assert_eq!(
            inconsistent_winding(&[tri([0, 1, 2]), tri([0, 1, 2])]),
            [(0, 1)]
        );
        // Four faces on one edge (two boxes touching along it: each box's two faces run it
        // opposite ways, and each face of one box runs it as a face of the other does): not
        // judged.
        assert!(inconsistent_winding(&[
            tri([0, 1, 2]),
            tri([1, 0, 3]),
            tri([0, 1, 4]),
            tri([1, 0, 5])
        ])
        .is_empty());
    }
}
