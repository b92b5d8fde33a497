//! Which patches can occlude at all: faces on the scene's convex hull cannot block a segment
//! between two scene points, so they leave the occlusion tests (the `skip_hull` shortcut).

use glam::DVec3;
use rayon::prelude::*;

use crate::mesh::Patches;

/// Which patches can block a segment between two points of the scene: those whose plane is
/// not a supporting plane of the scene (one with every patch vertex on one side of it). A face
/// on a supporting plane lies on the boundary of the scene's convex hull, and a segment
/// between two points of a convex set meets a supporting plane at most at its ends, which the
/// open-segment test never counts; so leaving such faces out of the occlusion BVH changes no
/// answer. In a room that is every wall, floor and ceiling face (only furniture remains); in a
/// convex enclosure (a sphere, an empty room) it is every face, and no ray is needed at all.
///
/// One test per scene triangle (its patches share its plane) against every patch vertex,
/// with a tolerance of 1e-6 of the scene's size (the f32 rounding of OBJ input must not make
/// a tessellated sphere's facets non-supporting; a dent that small hides nothing measurable).
/// A triangle stops at the first vertices found on both sides, so only supporting faces cost
/// a full pass; if that could exceed 4·10⁹ tests, every patch is kept as an occluder.
pub fn occluders(patches: &Patches) -> Vec<bool> {
    let n = patches.len();
    let positions = &patches.positions;
    // First patch of each source triangle (all of its patches share its plane).
    let mut first = std::collections::HashMap::new();
    for i in 0..n {
        first.entry(patches.source_triangle[i]).or_insert(i);
    }
    let mut reps: Vec<usize> = first.into_values().collect();
    reps.sort_unstable();
    if (reps.len() as f64) * (positions.len() as f64) > 4e9 {
        return vec![true; n];
    }
    let (lo, hi) = positions
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    let tol = 1e-6 * (hi - lo).length();
    let supporting: std::collections::HashMap<u32, bool> = reps
        .par_iter()
        .map(|&i| {
            let (c, nrm) = (patches.centroid[i], patches.normal[i]);
            let (mut front, mut back) = (false, false);
            for p in positions {
                let d = nrm.dot(*p - c);
                front |= d > tol;
                back |= d < -tol;
                if front && back {
                    break;
                }
            }
            (patches.source_triangle[i], !(front && back))
        })
        .collect();
    (0..n)
        .map(|i| !supporting[&patches.source_triangle[i]])
        .collect()
}
