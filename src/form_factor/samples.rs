//! Where the pair estimators sample each patch: a fixed set of points per patch, the same for
//! every pair the patch is in, with their quadrature weights and the surface normal there.
//!
//! The contour estimator integrates a smooth integrand over the receiving patch, so it uses a
//! symmetric Gauss rule (Dunavant) where one has exactly `samples` points (1, 3, 6, 7, 12);
//! otherwise, and for the area estimator (a Monte Carlo estimate of a double integral),
//! stratified random points keyed by (seed, patch). Because the same points serve every pair,
//! in a closed unoccluded scene the contour rows sum to exactly 1.

use glam::DVec3;
use rayon::prelude::*;

use super::{Estimator, Settings};
use crate::mesh::Patches;
use crate::sampling::{self, stratified_triangle_barycentrics, Rng};
use crate::visibility::{self, Visibility};

/// The sample points of every patch, `per_patch` each, patch i's at
/// `[i * per_patch, (i + 1) * per_patch)`.
pub(super) struct SamplePoints {
    /// Points per patch (the `samples` setting), ≥ 1.
    pub per_patch: usize,
    /// Quadrature weight of the k-th point of every patch (the same for every patch; sum 1).
    pub weights: Vec<f64>,
    /// True when the points are a symmetric Gauss rule (then far pairs may integrate the
    /// source by the same rule: [`super::pair::FAR_FIELD_FACTOR`]).
    pub gauss: bool,
    /// The points, scene units.
    pub points: Vec<DVec3>,
    /// The surface normal at each point ([`Patches::surface_normal`]): the receiving cosine's
    /// normal in the kernels. Unit length.
    pub normals: Vec<DVec3>,
    /// The points prepared for visibility queries (canonical frame computed once).
    pub prepared: Vec<visibility::Point>,
}

impl SamplePoints {
    /// Places `settings.samples` points on every patch (see the module documentation).
    pub fn place(patches: &Patches, vis: &Visibility, settings: &Settings) -> SamplePoints {
        let n = patches.len();
        let ns = settings.samples as usize;
        let rule: Vec<([f64; 3], f64)> = match settings.estimator {
            Estimator::Contour => sampling::gauss_rule(ns).unwrap_or_default(),
            _ => Vec::new(),
        };
        let weights: Vec<f64> = if rule.is_empty() {
            vec![1.0 / ns as f64; ns]
        } else {
            rule.iter().map(|p| p.1).collect()
        };
        let samples: Vec<(DVec3, DVec3)> = (0..n)
            .into_par_iter()
            .flat_map_iter(|i| {
                let mut bary = Vec::with_capacity(ns);
                if rule.is_empty() {
                    let mut rng = Rng::new(&[settings.seed, i as u64, 0x5A4D]);
                    stratified_triangle_barycentrics(ns, &mut rng, &mut bary);
                } else {
                    bary.extend(rule.iter().map(|p| p.0));
                }
                let t = patches.corners(i);
                bary.into_iter().map(move |b| {
                    let x = b[0] * t[0] + b[1] * t[1] + b[2] * t[2];
                    (x, patches.surface_normal(i, b))
                })
            })
            .collect();
        let points: Vec<DVec3> = samples.iter().map(|s| s.0).collect();
        let prepared = points.par_iter().map(|&x| vis.point(x)).collect();
        SamplePoints {
            per_patch: ns,
            weights,
            gauss: !rule.is_empty(),
            normals: samples.iter().map(|s| s.1).collect(),
            points,
            prepared,
        }
    }

    /// Patch i's points and the normals there.
    #[inline]
    pub fn of(&self, i: usize) -> (&[DVec3], &[DVec3]) {
        let range = i * self.per_patch..(i + 1) * self.per_patch;
        (&self.points[range.clone()], &self.normals[range])
    }
}
