//! Buried sample points: contact geometry (a block on the floor, a light mounted on the
//! ceiling) hides parts of patches. A point there receives no light and is seen by nobody,
//! so it must not dilute its patch's radiance: it gathers nothing, and its patch's rows are
//! rescaled to the visible part (hidden-area elimination). This module finds the buried
//! points ([`Visibility::buried`]) and measures each patch's visible part.

use rayon::prelude::*;

use super::samples::SamplePoints;
use crate::mesh::Patches;
use crate::sampling;
use crate::visibility::Visibility;

/// The visible (unburied) fraction of a patch's area is measured at the centroids of its
/// regular split into this many squared sub-triangles ([`sampling::lattice_barycentrics`]).
pub const VISIBLE_AREA_LATTICE: usize = 4;

/// What burial leaves of each patch.
pub(super) struct Burial {
    /// Per sample point (indexed like [`SamplePoints::points`]): buried.
    pub hidden: Vec<bool>,
    /// Per patch: the quadrature weight of its unburied sample points, what its row is
    /// divided by (the rows integrate over those points only).
    pub quadrature_visible: Vec<f64>,
    /// Per patch: the visible fraction of its area in [0, 1], measured on the finer lattice
    /// (three points would quantise it to thirds); `None` in a convex enclosure, where nothing
    /// is buried.
    pub visible_fraction: Option<Vec<f64>>,
    /// Rays the tests cast.
    pub rays: u64,
}

impl Burial {
    /// Tests every sample point, and the lattice of every patch; in a convex enclosure
    /// (`convex`) nothing can be buried and no ray is cast.
    pub fn find(patches: &Patches, vis: &Visibility, samples: &SamplePoints, convex: bool) -> Self {
        let (n, ns) = (patches.len(), samples.per_patch);
        let hidden: Vec<bool> = if convex {
            vec![false; samples.points.len()]
        } else {
            samples
                .points
                .par_iter()
                .enumerate()
                .map(|(k, &x)| vis.buried(x, patches.normal[k / ns], (k / ns) as u32))
                .collect()
        };
        let quadrature_visible: Vec<f64> = (0..n)
            .map(|i| {
                (0..ns)
                    .filter(|&k| !hidden[i * ns + k])
                    .map(|k| samples.weights[k])
                    .sum()
            })
            .collect();
        let mut rays = hidden.len() as u64 * (!convex) as u64;
        let visible_fraction = (!convex).then(|| {
            let lattice = sampling::lattice_barycentrics(VISIBLE_AREA_LATTICE);
            rays += (n * lattice.len()) as u64;
            (0..n)
                .into_par_iter()
                .map(|i| {
                    let t = patches.corners(i);
                    let buried = lattice
                        .iter()
                        .filter(|b| {
                            let x = b[0] * t[0] + b[1] * t[1] + b[2] * t[2];
                            vis.buried(x, patches.normal[i], i as u32)
                        })
                        .count();
                    1.0 - buried as f64 / lattice.len() as f64
                })
                .collect()
        });
        Burial {
            hidden,
            quadrature_visible,
            visible_fraction,
            rays,
        }
    }
}
