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
use super::samples::SamplePoints;
use super::{Estimator, Settings};
use crate::geometry::kernel;
use crate::mesh::Patches;
use crate::sampling;
use crate::visibility::{LightBuffer, Visibility};

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

/// Scratch of one worker: per sample, whether its ray was cast and what it found, and the
/// light buffers of the gathering patch's sample points (no allocation per pair).
pub(super) struct Scratch<'a> {
    valid: Vec<bool>,
    visible: Vec<bool>,
    /// One per sample point of patch `aimed`, over the blockers: a row's segments leave from
    /// these few points towards every later patch, so each point's buffer serves thousands.
    buffers: Vec<LightBuffer<'a>>,
    /// The patch whose points the buffers are aimed at, or `usize::MAX`.
    aimed: usize,
}

impl<'a> Scratch<'a> {
    fn new(samples: usize, blockers: &'a Visibility) -> Scratch<'a> {
        Scratch {
            valid: vec![false; samples],
            visible: vec![false; samples],
            buffers: (0..samples).map(|_| LightBuffer::new(blockers)).collect(),
            aimed: usize::MAX,
        }
    }
}

/// What every pair's estimate reads.
pub(super) struct PairEstimator<'a> {
    pub settings: &'a Settings,
    pub samples: &'a SamplePoints,
    pub burial: &'a Burial,
    /// The occluders ([`super::occluders`]) as the scene triangles they tile
    /// ([`super::occluders::Coarse`]), or every patch.
    pub blockers: &'a Visibility,
    /// Each patch's triangle in `blockers`, or [`crate::visibility::NONE`].
    pub occluder_of: &'a [u32],
    /// The scene is a convex enclosure: nothing occludes, no ray is cast.
    pub convex: bool,
    pub geometry: &'a [PatchGeometry],
}

impl<'a> PairEstimator<'a> {
    /// A worker's scratch for [`PairEstimator::estimate`].
    pub fn scratch(&self) -> Scratch<'a> {
        Scratch::new(self.samples.per_patch, self.blockers)
    }

    /// F_ij and F_ji of patches i < j (see the module documentation); `need_ij` / `need_ji`
    /// say which directions the solve reads (an unneeded one is left at zero).
    pub fn estimate(
        &self,
        i: usize,
        j: usize,
        (need_ij, need_ji): (bool, bool),
        scratch: &mut Scratch<'_>,
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
        // Segments leave their own patches at once: those triangles cannot block them.
        let ignore = [self.occluder_of[i], self.occluder_of[j]];
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
                    if scratch.aimed != i {
                        // The row's first ray: aim the buffers at patch i's sample points.
                        for (kk, buffer) in scratch.buffers.iter_mut().enumerate() {
                            buffer.aim(&self.samples.prepared[i * ns + kk], ignore[0]);
                        }
                        scratch.aimed = i;
                    }
                    // The same answer as `occluded_points(x_k, y, ignore)`, bit for bit.
                    !scratch.buffers[k].occluded(&self.samples.prepared[j * ns + ky], ignore[1])
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

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::form_factor::{occluders, Shortcuts};
    use crate::mesh::{self, Patches};
    use crate::sampling::gauss_rule;
    use crate::scene::{Scene, SceneBuilder};

    /// Everything a pair's estimate reads, for `scene` cut at `max_edge`.
    struct Fixture {
        patches: Patches,
        vis: Visibility,
        samples: SamplePoints,
        burial: Burial,
        geometry: Vec<PatchGeometry>,
        settings: Settings,
        convex: bool,
        /// Patch i traces as triangle i of `vis`.
        identity: Vec<u32>,
    }

    impl Fixture {
        fn new(scene: &Scene, max_edge: f64, settings: Settings) -> Fixture {
            let patches = mesh::subdivide(scene, max_edge, 0.0).unwrap();
            let corners: Vec<_> = (0..patches.len()).map(|i| patches.corners(i)).collect();
            let vis = Visibility::build(&corners);
            let convex = !occluders(&patches).contains(&true);
            let samples = SamplePoints::place(&patches, &vis, &settings);
            let burial = Burial::find(&patches, &vis, &samples, convex);
            let geometry = PatchGeometry::of_all(&patches);
            let patches_len = patches.len() as u32;
            Fixture {
                patches,
                vis,
                samples,
                burial,
                geometry,
                settings,
                convex,
                identity: (0..patches_len).collect(),
            }
        }

        fn estimate(&self, i: usize, j: usize, need: (bool, bool)) -> Pair {
            let estimator = PairEstimator {
                settings: &self.settings,
                samples: &self.samples,
                burial: &self.burial,
                blockers: &self.vis,
                occluder_of: &self.identity,
                convex: self.convex,
                geometry: &self.geometry,
            };
            estimator.estimate(i, j, need, &mut estimator.scratch())
        }

        /// The patches of material `m`.
        fn of(&self, m: u32) -> Vec<usize> {
            (0..self.patches.len())
                .filter(|&i| self.patches.material[i] == m)
                .collect()
        }
    }

    fn contour(samples: u32) -> Settings {
        Settings {
            samples,
            ..Settings::default()
        }
    }

    /// Unit squares 1 apart (source material 0 at z = 0 facing +z, receiver material 1 at
    /// z = 1 facing −z), and between them, if `blocked`, a larger square at z = 0.5 facing the
    /// source.
    fn plates(blocked: bool) -> Scene {
        let mut b = SceneBuilder::new();
        let src = b.material("source", [0.0; 3], [1.0; 3]);
        let rcv = b.material("receiver", [0.5; 3], [0.0; 3]);
        let wall = b.material("wall", [0.5; 3], [0.0; 3]);
        let square = |z: f64, lo: f64, hi: f64, up: bool| {
            let c = [(lo, lo), (hi, lo), (hi, hi), (lo, hi)].map(|(x, y)| DVec3::new(x, y, z));
            if up {
                c
            } else {
                [c[0], c[3], c[2], c[1]]
            }
        };
        b.quad(square(0.0, 0.0, 1.0, true), src);
        b.quad(square(1.0, 0.0, 1.0, false), rcv);
        if blocked {
            b.quad(square(0.5, -1.0, 2.0, false), wall);
        }
        b.build().unwrap()
    }

    #[test]
    fn coplanar_and_back_to_back_pairs_are_culled_without_a_ray() {
        let f = Fixture::new(&plates(false), 2.0, contour(3));
        let [a, b] = f.of(0)[..] else { panic!() };
        assert_eq!(f.estimate(a, b, (true, true)), Pair::Culled);
        // Without the cull, a coplanar pair has no valid segment and exchanges nothing.
        let mut s = contour(3);
        s.shortcuts = Shortcuts {
            cull_behind: false,
            ..Shortcuts::all()
        };
        let f = Fixture::new(&plates(false), 2.0, s);
        let got = f.estimate(a, b, (true, true));
        assert_eq!(
            got,
            Pair::Estimated {
                fij: 0.0,
                fji: 0.0,
                rays: 0
            }
        );
    }

    #[test]
    fn contour_is_the_gauss_rule_over_the_exact_point_to_polygon_form_factor() {
        // Unoccluded and convex: no ray; F_ij is exactly Σ_k w_k F(x_k → j) at the rule's
        // points x_k of i, and F_ji likewise, computed here independently.
        for samples in [1, 3, 7, 12] {
            let f = Fixture::new(&plates(false), 2.0, contour(samples));
            assert!(f.convex);
            let rule = gauss_rule(samples as usize).unwrap();
            let exact = |from: usize, to: usize| {
                let t = f.patches.corners(from);
                let n = f.patches.normal[from];
                let target = f.patches.corners(to);
                rule.iter()
                    .map(|(b, w)| {
                        let x = b[0] * t[0] + b[1] * t[1] + b[2] * t[2];
                        w * kernel::point_to_polygon(x, n, &target)
                    })
                    .sum::<f64>()
            };
            for &i in &f.of(1) {
                for &j in &f.of(0) {
                    let (lo, hi) = (i.min(j), i.max(j));
                    let Pair::Estimated { fij, fji, rays } = f.estimate(lo, hi, (true, true))
                    else {
                        panic!("culled")
                    };
                    assert_eq!(rays, 0);
                    // The same terms summed in the same order: rounding only.
                    for (got, want) in [(fij, exact(lo, hi)), (fji, exact(hi, lo))] {
                        assert!((got - want).abs() <= 1e-14 * want, "{got} vs {want}");
                    }
                }
            }
        }
    }

    #[test]
    fn the_two_directions_are_reciprocal_to_the_rule_s_accuracy() {
        // A_i F_ij = A_j F_ji holds for the exact integrals; the estimate integrates over the
        // receiving patch with a Gauss rule (exact over the source), so the two directions
        // differ by that rule's error. Patches of unlike size and position (a unit square
        // under a smaller, shifted one) so that no symmetry makes the two sides agree.
        let mut b = SceneBuilder::new();
        let m = b.material("grey", [0.5; 3], [1.0; 3]);
        let at = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        b.quad(
            [
                at(0., 0., 0.),
                at(1., 0., 0.),
                at(1., 1., 0.),
                at(0., 1., 0.),
            ],
            m,
        );
        b.quad(
            [
                at(0.5, 0.3, 0.8),
                at(0.5, 0.9, 0.8),
                at(1.1, 0.9, 0.8),
                at(1.1, 0.3, 0.8),
            ],
            m,
        );
        let scene = b.build().unwrap();
        let worst = |samples: u32| {
            let f = Fixture::new(&scene, 2.0, contour(samples));
            let (low, high): (Vec<usize>, Vec<usize>) =
                (0..f.patches.len()).partition(|&i| f.patches.centroid[i].z < 0.4);
            let mut worst = 0.0f64;
            for &i in &low {
                for &j in &high {
                    let Pair::Estimated { fij, fji, .. } = f.estimate(i, j, (true, true)) else {
                        panic!("culled")
                    };
                    let (ai, aj) = (f.patches.area[i], f.patches.area[j]);
                    worst = worst.max((ai * fij - aj * fji).abs() / (ai * fij));
                }
            }
            worst
        };
        // Measured: 7.8e-3 with 3 points (degree 2), 9.0e-5 with 12 (degree 6): the rule's
        // error falls with its degree as the integrand is smooth at this distance.
        let (three, twelve) = (worst(3), worst(12));
        assert!(three < 2e-2 && twelve < 5e-4, "{three:.2e}, {twelve:.2e}");
        assert!(twelve < three / 10.0, "{three:.2e}, {twelve:.2e}");
    }

    #[test]
    fn a_blocked_pair_casts_one_ray_per_sample_and_exchanges_nothing() {
        let f = Fixture::new(&plates(true), 2.0, contour(3));
        assert!(!f.convex);
        let (src, rcv) = (f.of(0), f.of(1));
        for (&i, &j) in src.iter().zip(&rcv) {
            assert_eq!(
                f.estimate(i, j, (true, true)),
                Pair::Estimated {
                    fij: 0.0,
                    fji: 0.0,
                    rays: 3
                }
            );
        }
        // The wall itself sees the source: a pair with entries, after its rays.
        let wall = f.of(2)[0];
        let Pair::Estimated { fij, rays, .. } = f.estimate(src[0], wall, (true, true)) else {
            panic!("culled")
        };
        assert!(fij > 0.0 && rays == 3);
    }

    #[test]
    fn an_unneeded_direction_is_left_at_zero() {
        let f = Fixture::new(&plates(false), 2.0, contour(3));
        let (i, j) = (f.of(0)[0], f.of(1)[0]);
        let Pair::Estimated { fij, fji, .. } = f.estimate(i, j, (true, true)) else {
            panic!()
        };
        assert_eq!(
            f.estimate(i, j, (true, false)),
            Pair::Estimated {
                fij,
                fji: 0.0,
                rays: 0
            }
        );
        assert_eq!(
            f.estimate(i, j, (false, true)),
            Pair::Estimated {
                fij: 0.0,
                fji,
                rays: 0
            }
        );
    }

    #[test]
    fn far_pairs_agree_between_estimators() {
        // Small patches far apart (r² ≫ 64 A): the far-field Gauss rule, the contour integral
        // and the area estimator's point pairs all estimate the same F: the Gauss rule on the
        // source within O((h/r)⁴) ≈ 2e-7 (measured 1e-8), point pairs within O(A/r²) ≈ 2e-4
        // (measured 5e-5).
        let mut b = SceneBuilder::new();
        let m = b.material("grey", [0.5; 3], [1.0; 3]);
        let d = 0.1;
        let near_tri = [
            DVec3::ZERO,
            DVec3::new(d, 0.0, 0.0),
            DVec3::new(0.0, d, 0.0),
        ];
        let v = near_tri.map(|p| b.vertex(p));
        b.triangle(v, m);
        // The same triangle 5 away, reversed to face the first.
        let offset = DVec3::new(0.3, 0.2, 5.0);
        let v = [near_tri[0], near_tri[2], near_tri[1]].map(|p| b.vertex(p + offset));
        b.triangle(v, m);
        let scene = b.build().unwrap();
        let value = |settings: Settings| {
            let f = Fixture::new(&scene, 1.0, settings);
            match f.estimate(0, 1, (true, true)) {
                Pair::Estimated { fij, fji, .. } => (fij, fji),
                Pair::Culled => panic!("culled"),
            }
        };
        let near = Settings {
            shortcuts: Shortcuts {
                far_field: false,
                ..Shortcuts::all()
            },
            ..contour(3)
        };
        let exact = value(near);
        let gauss = value(contour(3));
        let area = value(Settings {
            estimator: Estimator::Area,
            samples: 16,
            ..contour(3)
        });
        for (name, got, tolerance) in [("gauss", gauss, 1e-6), ("area", area, 5e-4)] {
            for (g, e) in [(got.0, exact.0), (got.1, exact.1)] {
                let rel = (g - e).abs() / e;
                assert!(rel < tolerance, "{name}: {g} vs {e} ({rel:.2e})");
            }
        }
    }
}
