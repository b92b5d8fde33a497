//! One pair of patches, both directions: [`PairEstimator::estimate`] gives F_ij and F_ji from
//! the same visibility rays (the pair estimators `area` and `contour`). This is the integrand
//! of the module documentation of [`crate::form_factor`], evaluated at the fixed sample points
//! of [`super::samples`]:
//!
//! 1. *Cull*: if j lies wholly on or behind i's plane, or i behind j's, the two cannot
//!    exchange light (`cull_behind` shortcut).
//! 2. *Visibility*: sample point x_k of i is paired with y_{(k + s) mod n} of j (a shift s
//!    keyed by the pair decorrelates pairings while staying deterministic) and one ray is cast
//!    per pairing whose ends each lie in front of the other's surface; a pairing that cannot
//!    tell (it straddles a horizon) takes the pair's mean visibility.
//! 3. *Integrand* per pairing, weighted by the point's quadrature weight: the point-to-point
//!    kernel (area estimator, far pairs), the Gauss rule on the source (contour, far pairs:
//!    error O((h/r)⁴)), or the exact point-to-polygon contour integral (everything else).
//!
//! Buried sample points gather nothing; the caller rescales rows to the visible part.

use glam::DVec3;

use super::burial::Burial;
use super::kernel;
use super::samples::SamplePoints;
use super::sampling;
use super::{Estimator, Settings};
use crate::mesh::Patches;
use crate::visibility::Visibility;

/// Pairs with squared centroid distance below this multiple of the larger patch area use the
/// exact point-to-polygon integrand even in the `Area` estimator (Baum et al. 1989 use the
/// analytic form wherever the point-source assumption A_j ≪ r² fails).
pub const NEAR_FIELD_FACTOR: f64 = 16.0;

/// Contour estimator with a Gauss rule: pairs with squared centroid distance above this
/// multiple of the larger patch area integrate the source with the same Gauss rule instead of
/// the exact contour integral (a 3-point rule's error there is O((h/r)⁴) ≲ 1e-4 relative:
/// per-surface means of the Cornell box unchanged to 1e-5).
pub const FAR_FIELD_FACTOR: f64 = 64.0;

/// Regular meshes put many pairs exactly on the near-field threshold; a relative nudge far
/// above f64 rounding decides those ties the same way whatever the scene's unit of length.
const NEAR_FIELD_TIE: f64 = 1.0 + 1e-9;

/// A patch's geometry as the pair loop reads it, in one contiguous record (the inner loop
/// streams through them).
#[derive(Clone, Copy)]
pub(super) struct PatchGeometry {
    /// Corners, counter-clockwise seen from the front; scene units.
    pub corners: [DVec3; 3],
    /// Unit front normal of the flat patch.
    pub normal: DVec3,
    pub centroid: DVec3,
    /// Area, scene units².
    pub area: f64,
}

impl PatchGeometry {
    /// Every patch's record.
    pub fn of_all(patches: &Patches) -> Vec<PatchGeometry> {
        (0..patches.len())
            .map(|i| PatchGeometry {
                corners: patches.corners(i),
                normal: patches.normal[i],
                centroid: patches.centroid[i],
                area: patches.area[i],
            })
            .collect()
    }
}

/// What [`PairEstimator::estimate`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Pair {
    /// One patch lies wholly behind the other's plane: no exchange, no ray.
    Culled,
    /// F_ij and F_ji integrated over every sample point of the gathering patch, buried ones
    /// counting zero (not yet divided by the patch's visible quadrature weight), with the
    /// number of visibility rays cast.
    Estimated { fij: f64, fji: f64, rays: u32 },
}

/// Scratch of one worker: per sample, whether its ray was cast and what it found (no
/// allocation per pair).
pub(super) struct Scratch {
    valid: Vec<bool>,
    visible: Vec<bool>,
}

impl Scratch {
    pub fn new(samples: usize) -> Scratch {
        Scratch {
            valid: vec![false; samples],
            visible: vec![false; samples],
        }
    }
}

/// What every pair's estimate reads.
pub(super) struct PairEstimator<'a> {
    pub settings: &'a Settings,
    pub samples: &'a SamplePoints,
    pub burial: &'a Burial,
    /// The occluders ([`super::occluders`]), or every patch.
    pub blockers: &'a Visibility,
    /// The scene is a convex enclosure: nothing occludes, no ray is cast.
    pub convex: bool,
    pub geometry: &'a [PatchGeometry],
}

impl PairEstimator<'_> {
    /// F_ij and F_ji of patches i < j (see the module documentation); `need_ij` / `need_ji`
    /// say which directions the solve reads (an unneeded one is left at zero).
    pub fn estimate(
        &self,
        i: usize,
        j: usize,
        (need_ij, need_ji): (bool, bool),
        scratch: &mut Scratch,
    ) -> Pair {
        let ns = self.samples.per_patch;
        let weights = &self.samples.weights;
        let hidden = &self.burial.hidden;
        let PatchGeometry {
            corners: ti,
            normal: ni,
            centroid: ci,
            area: ai,
        } = self.geometry[i];
        let PatchGeometry {
            corners: tj,
            normal: nj,
            centroid: cj,
            area: aj,
        } = self.geometry[j];

        // 1. Cull: j entirely on or behind i's plane, or i behind j's: no exchange.
        let tol = 1e-9 * (ai.sqrt() + aj.sqrt());
        // Heights of each patch's corners over the other's plane.
        let j_over_i = tj.map(|v| ni.dot(v - ci));
        let i_over_j = ti.map(|v| nj.dot(v - cj));
        if self.settings.shortcuts.cull_behind
            && (j_over_i.iter().all(|&h| h <= tol) || i_over_j.iter().all(|&h| h <= tol))
        {
            return Pair::Culled;
        }

        // 2. Visibility, one ray per pairing (x_k, y_{(k + shift) mod n}).
        let (pi, mi) = self.samples.of(i);
        let (pj, mj) = self.samples.of(j);
        let shift = (sampling::mix64(self.settings.seed ^ ((i as u64) << 32 | j as u64))
            % ns as u64) as usize;
        let (mut n_valid, mut n_visible, mut rays) = (0u32, 0u32, 0u32);
        for k in 0..ns {
            let ky = (k + shift) % ns;
            let d = pj[ky] - pi[k];
            if hidden[i * ns + k] && hidden[j * ns + ky] {
                // Both ends buried: neither gathers through this sample; no ray. (One buried
                // end still needs the ray: the segment is then blocked by what buries it,
                // which is how the buried part of a patch counts as invisible to the other.)
                scratch.valid[k] = false;
                continue;
            }
            // A segment is a meaningful visibility sample only if each end lies in front of
            // the other's surface.
            scratch.valid[k] = ni.dot(d) > 0.0 && nj.dot(d) < 0.0;
            if scratch.valid[k] {
                n_valid += 1;
                scratch.visible[k] = self.convex || {
                    rays += 1;
                    !self.blockers.occluded_points(
                        &self.samples.prepared[i * ns + k],
                        &self.samples.prepared[j * ns + ky],
                        [i as u32, j as u32],
                    )
                };
                n_visible += scratch.visible[k] as u32;
            }
        }
        if n_valid == 0 {
            // Only possible for pairs that straddle each other's planes with a sliver in
            // view: no sample segment can tell; such pairs exchange ~nothing.
            return Pair::Estimated {
                fij: 0.0,
                fji: 0.0,
                rays,
            };
        }
        let v_mean = n_visible as f64 / n_valid as f64;

        // 3. The integrand at each pairing.
        let r2 = ci.distance_squared(cj);
        let near = r2 < NEAR_FIELD_TIE * NEAR_FIELD_FACTOR * ai.max(aj);
        // The far-field rule needs each patch wholly in front of the other: a polygon
        // straddling the receiver's horizon is clipped by the contour integral, which a few
        // point samples cannot follow.
        let far = self.samples.gauss
            && self.settings.shortcuts.far_field
            && r2 > NEAR_FIELD_TIE * FAR_FIELD_FACTOR * ai.max(aj)
            && j_over_i.iter().chain(&i_over_j).all(|&h| h > tol);
        // A_src Σ_q w_q G(p, m, y_q, n_src): a point's form factor to a source by the Gauss rule.
        let gauss = |p, m, source: &[DVec3], n_src, a_src: f64| {
            let s: f64 = (0..ns)
                .map(|q| weights[q] * kernel::point_to_point(p, m, source[q], n_src))
                .sum();
            a_src * s
        };
        let (mut fij, mut fji) = (0.0, 0.0);
        for k in 0..ns {
            let ky = (k + shift) % ns;
            let (x, y) = (pi[k], pj[ky]);
            let v = if scratch.valid[k] {
                scratch.visible[k] as u8 as f64
            } else {
                v_mean
            };
            // Buried points gather nothing (their patch's row is rescaled later).
            let (hx, hy) = (
                hidden[i * ns + k] || !need_ij,
                hidden[j * ns + ky] || !need_ji,
            );
            if v == 0.0 || (hx && hy) {
                continue;
            }
            match (self.settings.estimator, near) {
                (Estimator::Area, false) => {
                    // Monte Carlo over the pair (x, y): uniform weights 1/n.
                    let g = kernel::point_to_point(x, mi[k], y, mj[ky]) * v * weights[k];
                    fij += aj * g * (!hx) as u8 as f64;
                    fji += ai * g * (!hy) as u8 as f64;
                }
                _ if far => {
                    // Far apart, the exact point-to-polygon integral is integrated over the
                    // source as well by the same Gauss rule: a degree-2 rule on a smooth
                    // kernel, error O((h/r)⁴) relative (< 1e-3 beyond [`FAR_FIELD_FACTOR`]),
                    // at a third of the contour's cost.
                    if !hx {
                        fij += weights[k] * gauss(x, mi[k], pj, nj, aj) * v;
                    }
                    if !hy {
                        fji += weights[ky] * gauss(y, mj[ky], pi, ni, ai) * v;
                    }
                }
                _ => {
                    // The contour integral needs the point in front of the polygon (one-sided
                    // surfaces); a point behind it sees its back: zero.
                    if !hx && nj.dot(x - cj) > 0.0 {
                        fij += weights[k] * kernel::point_to_polygon(x, mi[k], &tj) * v;
                    }
                    if !hy && ni.dot(y - ci) > 0.0 {
                        fji += weights[ky] * kernel::point_to_polygon(y, mj[ky], &ti) * v;
                    }
                }
            }
        }
        Pair::Estimated { fij, fji, rays }
    }
}
