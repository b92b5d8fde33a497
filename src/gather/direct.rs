//! The final gather's direct term at a point: Σ_e Le_e F(x → e) V̄(x, e) over the scene's
//! emitting triangles, plus the sun's and the point lights' ([`crate::light::outside`]).
//!
//! - The emitters computed exactly at a point ([`Gatherer::exact_emitters`]: all of them, or
//!   the [`MAX_EXACT_EMITTERS`] with the largest bound there, the two triangles of a convex
//!   quadrilateral counting as one) get their visible pieces ([`crate::geometry::visible`]):
//!   F·V̄ exactly, shadows included, a quadrilateral's as one polygon's. Where those would be
//!   too many (a crowded view), V̄ is estimated by kernel-weighted shadow rays
//!   ([`crate::light::Emitter::cast_shadow_rays`]), adaptive: [`GATHER_SHADOW_RAYS`] per
//!   emitter, and when any emitter's rays disagree (the point is in a penumbra) up to
//!   [`GATHER_MAX_SHADOW_RAYS`] for every emitter (at a vertex of the `cache` gather,
//!   [`crate::light::emitter::CACHE_MAX_SHADOW_RAYS`]).
//! - The others that are small as seen from the point ([`SAMPLED_SPREAD`]) share
//!   [`OTHER_LIGHT_SAMPLES`] shadow rays, drawn in proportion to Le·F, or beyond
//!   [`MAX_WEIGHED_EMITTERS`] by a light tree (many-light next-event estimation); the large
//!   near ones are left to the hemisphere rays ([`super::indirect`]).
//!
//! Unoccluded, the direct term is exact to rounding.

use std::collections::HashMap;
use std::f64::consts::PI;

use glam::DVec3;
use rayon::prelude::*;

use super::sites::{Spot, StarFace};
use super::{Gathered, Gatherer};
use crate::color::{luminance, Rgb};
use crate::geometry::kernel::point_to_polygon;
use crate::geometry::visible;
use crate::light::emitter::{GATHER_MAX_SHADOW_RAYS, GATHER_SHADOW_RAYS};
use crate::light::{Emitter, Receiver, Share};
use crate::sampling::{gauss_rule, kernel_samples, systematic, Rng};
use crate::visibility::Point;

/// What an exact emitter's visible pieces cost a gathering point, in hemisphere rays (each of
/// which may evaluate a near hit one bounce further): the point's fixed cost less its
/// other-light samples' shadow rays (about half a hemisphere ray each), over its exact
/// emitters, timed on the generated hall (many lights, [`MAX_EXACT_EMITTERS`] exact at
/// every point). A ratio of two times, it sets only how many vertices the display
/// refinement's budget buys ([`Gatherer::direct_cost_per_point`]), not how any is computed.
pub const EXACT_EMITTER_COST: usize = 2;

/// An emitter whose exactly computed visible share ([`visible`]) is within this of 0 or 1 is
/// wholly hidden or wholly seen: it does not put its point in a penumbra.
const VISIBLE_TIE: f64 = 1e-9;

/// Emitters whose direct light is computed exactly at a point, at most, the two halves of a
/// quadrilateral counting as one (`pair_emitters`): with more in the scene, the ones with
/// the largest bound on their contribution (Le · A / (π d²), d the distance to the emitter's
/// centre less its radius); the others' light is estimated by
/// [`OTHER_LIGHT_SAMPLES`] shadow rays to emitters drawn in proportion to their unoccluded
/// contribution (those small as seen from the point, [`SAMPLED_SPREAD`]) or by the hemisphere
/// rays (the large near ones).
pub const MAX_EXACT_EMITTERS: usize = 8;

/// Shadow rays at a point for the emitters beyond its [`MAX_EXACT_EMITTERS`]: each ray goes to
/// an emitter drawn with probability ∝ Le_max · F(x → e) (the unoccluded form factor, its
/// differential form for the far ones, [`Emitter::form_factor_weight`]; systematic sampling
/// over the emitters' cumulative weights, Kitagawa 1996), so the estimate Σ Le F V̂ / (N p)
/// carries little but the noise of visibility: a point that sees all of them unoccluded gets
/// their light to within the differential form's O((r/d)²). Next-event estimation over many
/// lights (Shirley, Wang & Zimmerman, "Monte Carlo techniques for direct lighting
/// calculations", TOG 1996).
/// Without them only a hemisphere ray that happened to hit such an emitter would bring its
/// Le: in a scene of many small bright lights (the generated hall) that noise would be most
/// of the gather's error even at four times the rays, and with these samples what is left
/// is mostly the solution's own bias.
pub const OTHER_LIGHT_SAMPLES: usize = 16;

/// Shadow rays for the others at a point where the [`OTHER_LIGHT_PILOT`] rays disagree (some
/// met their emitter, some did not: the point sees part of the other lights). In a furnished
/// room lit through windows, the others are the far windows and lamps seen past desks,
/// partitions and shelves: [`OTHER_LIGHT_SAMPLES`] rays leave the walls' direct light with a
/// noise of several per cent at every vertex, which more rays where the pilot finds the others
/// partly hidden take out where it arises. Four times as many halve that noise; more cost the
/// many-light hall a sixth more bake time (its pilots disagree under every table) for no
/// better display (BENCHMARKS.md "Large outputs: the `cache` gather").
pub const OTHER_LIGHT_MAX_SAMPLES: usize = 4 * OTHER_LIGHT_SAMPLES;

/// Shadow rays of the pilot that decides how many the others' estimate gets
/// ([`OTHER_LIGHT_SAMPLES`] or [`OTHER_LIGHT_MAX_SAMPLES`]), drawn as the estimate's are.
/// The estimate uses fresh rays only, never the pilot's: drawn independently of the pilot,
/// they are unbiased whatever it decided. Adding the pilot's rays would not be: where they
/// happen to agree (all seen, or all hidden) their mean is conditioned on that, and points
/// that see most of the others would come out too bright, those that see little too dark.
pub const OTHER_LIGHT_PILOT: usize = OTHER_LIGHT_SAMPLES;

/// The points of an emitter triangle (barycentric) that [`Gatherer::coarse_direct`] aims its
/// shadow rays at: the centroid of each of the four triangles of its midpoint subdivision, so
/// that each stands for a quarter of the emitter's area.
pub const COARSE_POINTS: [[f64; 3]; 4] = [
    [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
    [2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0],
    [1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0],
    [1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0],
];

/// Up to this many emitters in the scene, the others' shadow rays at a point draw emitters by
/// weights computed there for every emitter (Le·F); with more, by the light tree over them
/// ([`LightTree`](crate::light::LightTree): a bound on each node's light at the point by its
/// power, distance and orientation; Conty Estevez & Kulla 2018), so that the cost per point
/// and per near hit stays O(log n) however many emitting triangles a scene has (a tessellated
/// sky, a level's emissive textures, the 7,570 of the generated hall of 10⁶ triangles, where
/// weighing all would cost about a millisecond a point). The tree's bound is loose for near
/// nodes: on the generated hall of 10⁵ (784 emitting triangles), weighing them all displays
/// the error of the tree (10.26 against 10.29 % RMS) in 0.92× the bake (BENCHMARKS.md "Large
/// outputs"). Both are unbiased.
pub const MAX_WEIGHED_EMITTERS: usize = 1024;

/// [`MAX_WEIGHED_EMITTERS`] for a near hit's one ray to the others
/// ([`super::NEAR_HIT`]): beyond this many emitters it draws from the light tree. Near hits
/// are many (a furnished room's hemisphere rays meet chair seats and table undersides close by
/// at most points), and weighing every emitter for each one's single ray cost the generated
/// hall of 10⁵ (784 emitting triangles) a tenth of its bake; a draw from the tree costs a few
/// dozen node weighings. The tree's looser importance leaves the display's error where it was
/// on the hall of 10⁴ (82 emitting triangles, three seeds) in 0.93× the bake (BENCHMARKS.md
/// "Large outputs"). Below this, weighing is cheap and the draws are the exact bound's.
pub const MAX_WEIGHED_NEAR_HIT_EMITTERS: usize = 64;

/// An emitter beyond a point's exact ones is sampled by [`OTHER_LIGHT_SAMPLES`] when its radius
/// is at most this fraction of its distance (a cone of half-angle under 15°), else left to the
/// hemisphere rays. One ray to a uniform point of a large near emitter weights its parts by
/// area instead of by the kernel G, and is noisy: in the furnace room, where every wall
/// emits, sampling all of them would leave the gather an order of magnitude noisier than
/// this split does (the test `full_gather_in_the_furnace_is_le_over_one_minus_rho`).
pub const SAMPLED_SPREAD: f64 = 0.25;

/// The least luminance [`SharpStar::shown`] weighs a point by, as a fraction of the
/// brightest point's: a contrast of 100:1, past which a display's dark shades (8 bits, after
/// tone mapping) tell nothing apart.
pub const SHARP_STAR_FLOOR: f64 = 0.01;

/// The sun's and the point lights' reflected light over a display vertex's faces
/// ([`Gatherer::rim_direct`]): per point, its weight (the vertex's hat function there times
/// twice its face's area) and the light (radiance units).
#[derive(Clone, Debug)]
pub(crate) struct SharpStar {
    pub(super) points: Vec<(f64, Rgb)>,
}

impl SharpStar {
    /// `gathered` (its value without the sharp lights) with the sharp lights' part that its
    /// vertex shows: the value s that minimises the squared *relative* error of the linear
    /// interpolation over the vertex's faces, Σ w_k ((s − L_k)/Y_k)², L_k the gathered value
    /// plus the sharp light at point k and Y_k its luminance: s = Σ (w_k/Y_k²) L_k /
    /// Σ (w_k/Y_k²), per channel. Not the plain mean: where a band 6 mm wide along a
    /// leg's top is sunlit and the rest lies dark under the table top, the mean would show the
    /// whole top at a fifth of the sun's light, several times its dark value, where a viewer
    /// sees it dark but for the band (a relative error, as the eye weighs light; the display's
    /// fit weighs its midpoints so too, [`super::local_fit`]). Where the light is the same
    /// at every point, s is that value. Y_k is floored at [`SHARP_STAR_FLOOR`] of the
    /// brightest point's: a point in full shadow with no other light (Y_k = 0) would otherwise
    /// weigh infinitely, or, left out, leave the lit points alone to decide.
    pub(crate) fn shown(&self, mut gathered: Gathered) -> Gathered {
        let base = gathered.radiance;
        let light = |sharp: &Rgb| -> Rgb { std::array::from_fn(|c| base[c] + sharp[c]) };
        let brightest = self
            .points
            .iter()
            .map(|(_, sharp)| luminance(light(sharp)))
            .fold(0.0, f64::max);
        let floor = SHARP_STAR_FLOOR * brightest;
        let (mut num, mut den) = ([0.0; 3], 0.0);
        for &(w, sharp) in &self.points {
            let l = light(&sharp);
            let y = luminance(l).max(floor);
            if w <= 0.0 || y <= 0.0 {
                continue;
            }
            let k = w / (y * y);
            for c in 0..3 {
                num[c] += k * l[c];
            }
            den += k;
        }
        if den > 0.0 {
            for c in 0..3 {
                let sharp = (num[c] / den - base[c]).max(0.0);
                gathered.direct[c] += sharp;
                gathered.radiance[c] += sharp;
            }
        }
        gathered
    }
}

impl Gatherer<'_> {
    /// Σ_e Le_e F(x → e) V̄(x, e): the irradiance from the emitters at the point `x` (unit
    /// normal `n`) divided by π, per channel (radiance units). `ignore` is the patch `x` lies
    /// on.
    pub fn direct(&self, x: DVec3, n: DVec3, ignore: u32, rng: &mut Rng) -> Rgb {
        let rays = (
            GATHER_SHADOW_RAYS,
            GATHER_MAX_SHADOW_RAYS,
            OTHER_LIGHT_SAMPLES,
        );
        self.direct_from(x, n, ignore, &self.exact_emitters(x), rays, false, rng)
            .0
    }

    /// The emitters whose light is computed exactly at `x`, sorted: all of them, or the
    /// [`MAX_EXACT_EMITTERS`] with the largest bound (ties to the lower index), each with its
    /// partner if it has one (`pair_emitters`: the two halves of a quadrilateral count as
    /// one, and their visible pieces are computed as one polygon's, for little more than a
    /// triangle's cost). From 64 emitters on (`brightest::INDEX_FROM`), the largest bounds
    /// are found by a tree over the emitters (`gather::brightest`), not by weighing every
    /// one at every point: the same emitters, in time that grows about as their logarithm.
    pub fn exact_emitters(&self, x: DVec3) -> Vec<u32> {
        if self.groups <= MAX_EXACT_EMITTERS {
            return (0..self.emitters.len() as u32).collect();
        }
        // A paired half ranks by its quadrilateral's bound, the two halves' sum: it is
        // computed as one with its partner, and a large lamp of two triangles must not lose
        // its place to a smaller single triangle that outranks each half.
        // The first MAX_EXACT_EMITTERS groups by bound lie among the first twice as many
        // emitters (a group's members share its bound and are at most two).
        let top = (2 * MAX_EXACT_EMITTERS).min(self.emitters.len());
        let own = |k: u32| self.emitters[k as usize].bound(x);
        let key = |k: u32| own(k) + self.partner[k as usize].map_or(0.0, |(j, _)| own(j));
        let ranked: Vec<(f64, u32)> = match &self.brightest {
            // Many emitters: those of the largest keys found by their tree, the same.
            Some(tree) => tree.top(x, top, key),
            None => {
                let mut bounds: Vec<(f64, u32)> = (0..self.emitters.len() as u32)
                    .map(|k| (key(k), k))
                    .collect();
                let by_bound =
                    |a: &(f64, u32), b: &(f64, u32)| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1));
                bounds.select_nth_unstable_by(top - 1, by_bound);
                bounds.truncate(top);
                bounds.sort_unstable_by(by_bound);
                bounds
            }
        };
        let mut chosen: Vec<u32> = Vec::with_capacity(top);
        let mut groups = 0;
        for &(_, k) in &ranked {
            if groups == MAX_EXACT_EMITTERS {
                break;
            }
            if chosen.contains(&k) {
                continue;
            }
            chosen.push(k);
            chosen.extend(self.partner[k as usize].map(|(j, _)| j));
            groups += 1;
        }
        chosen.sort_unstable();
        chosen
    }

    /// [`Gatherer::direct`]: the emitters `exact` with `first` shadow rays per emitter and,
    /// when any emitter's disagree, up to `max` in all for every emitter, and the other
    /// emitters by `others` shadow rays in all ([`OTHER_LIGHT_SAMPLES`]; `rays = (first, max,
    /// others)`), or by [`OTHER_LIGHT_MAX_SAMPLES`] where a pilot finds them partly hidden
    /// (`others` ≥ 2); and whether some exact emitter is partly hidden (`x` is in a penumbra). The
    /// point and spot lights outside the mesh get one shadow ray each, or, if `one_light` (a
    /// near hit's point, of which a gather averages many), one shadow ray in all
    /// ([`Environment::sharp_direct_sampled`]).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn direct_from(
        &self,
        x: DVec3,
        n: DVec3,
        ignore: u32,
        exact: &[u32],
        rays: (usize, usize, usize),
        one_light: bool,
        rng: &mut Rng,
    ) -> (Rgb, bool) {
        let (mut sum, penumbra) = self.emitters_direct(x, n, ignore, exact, rays, rng);
        if self.env.has_sharp() {
            for (s, o) in sum
                .iter_mut()
                .zip(self.sharp_direct(x, n, ignore, one_light, rng))
            {
                *s += o;
            }
        }
        (sum, penumbra)
    }

    /// The point `x` (unit normal `n`) on patch `patch` as the lights outside the mesh see it:
    /// its rays ignore the patch and start the gather's lift above it.
    fn receiver(&self, x: DVec3, n: DVec3, patch: u32) -> Receiver<'_> {
        Receiver {
            vis: self.surfaces.vis(),
            x,
            n,
            ignore: self.surfaces.traced(patch),
            lift: self.lift,
        }
    }

    /// The part of [`Gatherer::direct_from`] from the point and spot lights and the sun
    /// outside the mesh (radiance units, before ρ).
    fn sharp_direct(&self, x: DVec3, n: DVec3, ignore: u32, one_light: bool, rng: &mut Rng) -> Rgb {
        let at = self.receiver(x, n, ignore);
        if one_light {
            self.env.sharp_direct_sampled(&self.light_tree, &at, rng)
        } else {
            self.env.sharp_direct_shown(&at, rng)
        }
    }

    /// The part of [`Gatherer::direct_from`] from the mesh's emitters (radiance units, before
    /// ρ), and whether some exact emitter is partly hidden.
    pub(super) fn emitters_direct(
        &self,
        x: DVec3,
        n: DVec3,
        ignore: u32,
        exact: &[u32],
        (first, max_rays, others): (usize, usize, usize),
        rng: &mut Rng,
    ) -> (Rgb, bool) {
        let mut targets = Vec::with_capacity(max_rays.max(first));
        let from = self.surfaces.point(x + self.lift * n);
        // Per emitter in front of x: its form factor, and its visible share as far as the
        // shadow rays cast so far tell.
        let mut seen: Vec<(usize, f64, Share)> = Vec::with_capacity(exact.len());
        for &k in exact {
            if let Some(f) = self.emitters[k as usize].form_factor(x, n) {
                seen.push((k as usize, f, Share::default()));
            }
        }
        // V̄ by kernel-weighted shadow rays ([`Emitter::cast_shadow_rays`]): every emitter
        // first gets `first`; if any emitter's rays disagree, x is in a penumbra and every
        // emitter gets the rest up to `max_rays` ([`GATHER_SHADOW_RAYS`]).
        let mut penumbra = false;
        // Exactly where the shadow rays would be many (a gathering point or a test, not a near
        // hit's point): the visible pieces of the emitter ([`visible`]). An emitter done so
        // has a share known exactly and is passed over by the rays; the rest get rays.
        if first > 1 {
            for i in 0..seen.len() {
                let (k, f, _) = seen[i];
                let e = &self.emitters[k];
                // A pair of halves of one quadrilateral, both seen: its visible pieces once,
                // by the lower-numbered half (the emitters' shares are the quadrilateral's).
                let pair = self.partner[k].and_then(|(j, quad)| {
                    let at = seen.iter().position(|s| s.0 == j as usize)?;
                    Some((at, quad))
                });
                let corners: &[DVec3] = match &pair {
                    Some((at, _)) if seen[*at].0 < k => continue,
                    Some((_, quad)) => quad,
                    None => &e.corners,
                };
                let (lo, hi) = corners
                    .iter()
                    .fold((x, x), |(lo, hi), &c| (lo.min(c), hi.max(c)));
                let fv = visible::visible_form_factor(
                    x,
                    n,
                    corners,
                    e.normal,
                    self.lift,
                    |pyramid, visit| {
                        self.surfaces
                            .overlapping_convex(lo, hi, pyramid, ignore, visit)
                    },
                );
                if let Some(fv) = fv {
                    let all = f + pair.map_or(0.0, |(at, _)| seen[at].1);
                    let v = (fv / all).clamp(0.0, 1.0);
                    for at in std::iter::once(i).chain(pair.map(|(at, _)| at)) {
                        (seen[at].2.seen, seen[at].2.all) = (v, 1.0);
                    }
                    penumbra |= v > VISIBLE_TIE && v < 1.0 - VISIBLE_TIE;
                }
            }
        }
        // The desk that hides one sample of a lamp hides most of the next.
        let mut last = usize::MAX;
        for round in [first, max_rays.saturating_sub(first)] {
            for (k, _, share) in seen.iter_mut() {
                if share.all > 0.0 && share.agree == [false, false] {
                    continue; // computed exactly
                }
                let e = &self.emitters[*k];
                e.cast_shadow_rays(x, n, round, rng, &mut targets, share, |y| {
                    let to = self.surfaces.point(y + self.lift * e.normal);
                    self.surfaces.occluded_after(&from, &to, ignore, &mut last)
                });
                penumbra |= share.penumbra();
            }
            if !penumbra {
                break; // the first rays agree: wholly lit or wholly shadowed
            }
        }
        let mut sum = [0.0; 3];
        for &(k, f, share) in &seen {
            let Some(v) = share.visible() else {
                continue;
            };
            for (s, le) in sum.iter_mut().zip(self.emitters[k].le) {
                *s += le * f * v;
            }
        }
        if others > 0 && exact.len() < self.emitters.len() {
            let mut weighed = None;
            let mut estimate = |rays, rng: &mut Rng| {
                let draw = (exact, rays, &mut weighed);
                self.others_direct(x, n, &from, ignore, draw, rng, &mut targets)
            };
            // A gathering point's rays are as many as a pilot decides ([`OTHER_LIGHT_PILOT`]:
            // `others` where its rays agree, [`OTHER_LIGHT_MAX_SAMPLES`] where some met their
            // emitter and some did not), the estimate's fresh; a near hit's one ray is not.
            let rays = if others >= 2 && estimate(OTHER_LIGHT_PILOT, rng).1.partial() {
                OTHER_LIGHT_MAX_SAMPLES.max(others)
            } else {
                others
            };
            let (other, _) = estimate(rays, rng);
            for (s, o) in sum.iter_mut().zip(other) {
                *s += o;
            }
        }
        (sum, penumbra)
    }

    /// Whether the emitter `e`, if not computed exactly at `x`, is sampled by the others' shadow
    /// rays there ([`OTHER_LIGHT_SAMPLES`]): when it is small as seen from `x` (its radius at
    /// most [`SAMPLED_SPREAD`] × its distance). A larger one is left to the hemisphere rays,
    /// which bring its Le: they hit it often, and one shadow ray to a uniform point of it
    /// would weight its parts by area rather than by the kernel G. Each emitter is counted by
    /// exactly one of the two estimators at a point, so their sum is unbiased.
    pub(super) fn sampled(&self, e: &Emitter, x: DVec3) -> bool {
        e.radius <= SAMPLED_SPREAD * x.distance(e.centre)
    }

    /// Whether the others' shadow rays at `x` may go to the emitter `e`: it is sampled there
    /// ([`Gatherer::sampled`]) and `x` lies in front of it.
    fn sampled_toward(&self, e: &Emitter, x: DVec3) -> bool {
        self.sampled(e, x) && e.in_front(x)
    }

    /// Σ_{e ∉ exact, sampled} Le_e F(x → e) V̄(x, e) estimated by `count` shadow rays:
    /// emitters drawn with probability p_e by [`Gatherer::draw_others`], one point of each
    /// drawn emitter (area-uniform over its part above the horizon), each ray adding
    /// Le_e F V / (count p_e) if the emitter is one of these others (see
    /// [`OTHER_LIGHT_SAMPLES`]). With `count` ≥ 2 (a gathering point) and up to
    /// [`MAX_WEIGHED_EMITTERS`] emitters, p_e ∝ max(Le_e) F (the far ones' F in its
    /// differential form, [`Emitter::form_factor_weight`]), so an unoccluded point gets their
    /// light all but exactly; beyond, p_e follows a bound on it (the light tree).
    ///
    /// Unbiased up to V̄'s area (not G) weighting within one emitter, negligible for the
    /// emitters that are not the point's largest ([`SAMPLED_SPREAD`]). Also returns what the
    /// rays to those others met.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn others_direct(
        &self,
        x: DVec3,
        n: DVec3,
        from: &Point,
        ignore: u32,
        (exact, count, weighed): (&[u32], usize, &mut Option<Weighed>),
        rng: &mut Rng,
        targets: &mut Vec<[f64; 3]>,
    ) -> (Rgb, Seen) {
        let is_other = |k: usize, e: &Emitter| {
            exact.binary_search(&(k as u32)).is_err() && self.sampled_toward(e, x)
        };
        let mut sum = [0.0; 3];
        let mut seen = Seen::default();
        let mut last = usize::MAX;
        for (k, p) in self.draw_others(x, n, exact, count, weighed, rng) {
            let e = &self.emitters[k];
            if !is_other(k, e) {
                continue;
            }
            let f = point_to_polygon(x, n, &e.corners);
            if f <= 0.0 {
                continue;
            }
            let mut visible = false;
            kernel_samples(&e.corners, e.normal, x, n, 1, rng, targets, |y, _| {
                let to = self.surfaces.point(y + self.lift * e.normal);
                visible = !self.surfaces.occluded_after(from, &to, ignore, &mut last);
            });
            seen.add(visible);
            if visible {
                for (s, le) in sum.iter_mut().zip(e.le) {
                    *s += le * f / (count as f64 * p);
                }
            }
        }
        (sum, seen)
    }

    /// The `count` emitters [`Gatherer::others_direct`] casts its rays to at `x` (unit normal
    /// `n`), each with the probability it was drawn with: systematic sampling (Kitagawa 1996)
    /// over weights w_e, zero for the emitters `exact` and those not sampled at `x`
    /// ([`SAMPLED_SPREAD`]) or facing away. Up to [`MAX_WEIGHED_EMITTERS`] emitters, w_e is
    /// max(Le_e) F(x → e) (the unoccluded form factor, [`Emitter::form_factor_weight`]: its
    /// differential form beyond [`crate::light::emitter::FAR_RADII`] radii) with `count` ≥ 2,
    /// or up to [`MAX_WEIGHED_NEAR_HIT_EMITTERS`] with one ray the cheap bound
    /// max(Le_e) A_e / (π d²) ([`Emitter::bound`]). Beyond, the
    /// emitters are drawn by the light tree over them ([`crate::light::LightTree`]), its
    /// leaves weighed the same way: for `count` ≥ 2 over the tree's draw less the
    /// u-intervals of the exact emitters ([`crate::light::tree::Skip`]), so that no ray is
    /// spent on them; with one ray, with the exact emitters' leaves weighed 0.
    fn draw_others(
        &self,
        x: DVec3,
        n: DVec3,
        exact: &[u32],
        count: usize,
        weighed: &mut Option<Weighed>,
        rng: &mut Rng,
    ) -> Vec<(usize, f64)> {
        let is_exact = |k: usize| exact.binary_search(&(k as u32)).is_ok();
        // w_e for an emitter not left out by `exact`.
        let weight = |k: usize| {
            let e = &self.emitters[k];
            if !self.sampled_toward(e, x) {
                0.0
            } else if count >= 2 {
                e.form_factor_weight(x, n) * e.le_max()
            } else if e.corners.iter().any(|&c| (c - x).dot(n) > 0.0) {
                e.bound(x)
            } else {
                0.0
            }
        };
        let most = if count >= 2 {
            MAX_WEIGHED_EMITTERS
        } else {
            MAX_WEIGHED_NEAR_HIT_EMITTERS
        };
        if self.emitters.len() <= most {
            let weigh = || {
                let all = self.emitters.len();
                let (mut cdf, mut keys) = (Vec::with_capacity(all), Vec::with_capacity(all));
                let mut total = 0.0;
                for k in 0..all {
                    let w = if is_exact(k) { 0.0 } else { weight(k) };
                    if w > 0.0 {
                        total += w;
                        cdf.push(total);
                        keys.push(k);
                    }
                }
                Weighed::Sums { cdf, keys }
            };
            // A gathering point's pilot and estimate draw by the same weights: found once.
            let fresh;
            let w = if count >= 2 {
                &*weighed.get_or_insert_with(weigh)
            } else {
                fresh = weigh();
                &fresh
            };
            let Weighed::Sums { cdf, keys } = w else {
                unreachable!("a point's draws all weigh its emitters, or all take the tree");
            };
            if cdf.is_empty() {
                return Vec::new();
            }
            return systematic(cdf, count, rng.next_f64())
                .map(|(at, p)| (keys[at], p))
                .collect();
        }
        // The tree's inner nodes bound Le·A·cos·cos/d², which is π·Le·F for a small far
        // emitter: its leaves' weights in the same units.
        let tree = &self.emitter_tree;
        let u0 = rng.next_f64();
        if count >= 2 {
            let leaf = |k: usize| PI * weight(k);
            // The pilot's and the estimate's draws leave out the same intervals: found once.
            let w = weighed.get_or_insert_with(|| {
                Weighed::Tree(tree.skip(exact.iter().map(|&k| k as usize), x, n, leaf))
            });
            let Weighed::Tree(skip) = &*w else {
                unreachable!("a point's draws all weigh its emitters, or all take the tree");
            };
            let kept = skip.kept();
            if kept <= 1e-12 {
                return Vec::new();
            }
            (0..count)
                .filter_map(|i| {
                    let v = (i as f64 + u0) / count as f64 * kept;
                    let (k, p) = tree.sample(x, n, skip.place(v), leaf)?;
                    Some((k, p / kept))
                })
                .collect()
        } else {
            let leaf = |k: usize| if is_exact(k) { 0.0 } else { PI * weight(k) };
            (0..count)
                .filter_map(|i| tree.sample(x, n, (i as f64 + u0) / count as f64, leaf))
                .collect()
        }
    }

    /// Each patch's own direct light, Σ_e Le_e F V̄ averaged over its 7-point Gauss rule
    /// (radiance units, before its reflectance).
    pub(super) fn patch_direct(&self) -> Vec<Rgb> {
        let rule = gauss_rule(7).expect("the 7-point rule exists");
        (0..self.patches.len())
            .into_par_iter()
            .map(|i| {
                let mut rng = Rng::new(&[self.seed, i as u64, 0xD1_EC7]);
                let c = self.patches.corners(i);
                let n = self.patches.normal[i];
                let mut sum = [0.0; 3];
                for &(b, w) in &rule {
                    let x = b[0] * c[0] + b[1] * c[1] + b[2] * c[2];
                    let d = self.direct(x, n, i as u32, &mut rng);
                    for ch in 0..3 {
                        sum[ch] += w * d[ch];
                    }
                }
                sum
            })
            .collect()
    }

    /// The reflected direct light ρ·Σ_e Le_e F V̄ at `spot` (up to `max_rays` shadow rays per
    /// emitter), whether it is in a penumbra, and the emitters computed exactly there.
    pub(crate) fn reflected_direct(
        &self,
        spot: &Spot,
        max_rays: usize,
        rng: &mut Rng,
    ) -> (Rgb, bool, Vec<u32>) {
        self.reflected_direct_with(spot, max_rays, true, rng)
    }

    /// [`Gatherer::reflected_direct`], the sun's and the point lights' part included only if
    /// `sharp` (the emitters' part draws the same rays either way, first).
    fn reflected_direct_with(
        &self,
        spot: &Spot,
        max_rays: usize,
        sharp: bool,
        rng: &mut Rng,
    ) -> (Rgb, bool, Vec<u32>) {
        let exact = self.exact_emitters(spot.x);
        let (x, n, patch) = (spot.x, spot.n, spot.patch);
        let rays = (GATHER_SHADOW_RAYS, max_rays, OTHER_LIGHT_SAMPLES);
        let (direct, penumbra) = match sharp {
            true => self.direct_from(x, n, patch, &exact, rays, false, rng),
            false => self.emitters_direct(x, n, patch, &exact, rays, rng),
        };
        let rho = self.patches.reflectance[patch as usize];
        (std::array::from_fn(|c| rho[c] * direct[c]), penumbra, exact)
    }

    /// [`Gatherer::reflected_direct`] for a vertex on a covering face's outline or under it
    /// ([`Gatherer::rim_gap`]), gathered at `spot` inside its faces `faces`, without the sun's
    /// and the point lights' light where it is to be shown by [`SharpStar::shown`]: then
    /// also their reflected light at [`COARSE_POINTS`] of each face, weighed by the vertex's
    /// hat function there. Under a gap g, a directional light reaches only a band g·cot θ wide
    /// along the outline on its side (θ its elevation over the face): a point inside the faces,
    /// wherever it is put, sees the band's full light or none of it, and the vertex shows that
    /// across its faces. Where the sharp lights are too many for their cheap estimate to count
    /// them all ([`Environment::coarse_counts_all`]), or every point is buried, this is
    /// [`Gatherer::reflected_direct`] and no star.
    ///
    /// [`Environment::coarse_counts_all`]: crate::scene::Environment::coarse_counts_all
    pub(crate) fn rim_direct(
        &self,
        spot: &Spot,
        faces: &[StarFace],
        max_rays: usize,
        rng: &mut Rng,
    ) -> ((Rgb, bool, Vec<u32>), Option<SharpStar>) {
        let rho = self.patches.reflectance[spot.patch as usize];
        let star = (self.env.has_sharp() && self.env.coarse_counts_all())
            .then(|| self.star_sharp(spot.n, faces, rho))
            .flatten();
        // The star shows the sharp lights' part: the point's own leaves it out.
        let direct = self.reflected_direct_with(spot, max_rays, star.is_none(), rng);
        (direct, star)
    }

    /// The sharp lights' cheap estimate ([`Environment::coarse_sharp_direct`]) times `rho` at
    /// [`COARSE_POINTS`] of each of `faces` (normal `n`), with the weight of their shared
    /// vertex's hat function there; `None` where every point is buried.
    ///
    /// [`Environment::coarse_sharp_direct`]: crate::scene::Environment::coarse_sharp_direct
    fn star_sharp(&self, n: DVec3, faces: &[StarFace], rho: Rgb) -> Option<SharpStar> {
        let mut points = Vec::with_capacity(faces.len() * COARSE_POINTS.len());
        for f in faces {
            let area = f.doubled_area();
            for b in COARSE_POINTS {
                let x = b[0] * f.corners[0] + b[1] * f.corners[1] + b[2] * f.corners[2];
                if self.buried(x, n, f.patch) {
                    continue;
                }
                let at = self.receiver(x, n, f.patch);
                let d = self.env.coarse_sharp_direct(&at);
                points.push((b[f.vertex] * area, std::array::from_fn(|c| rho[c] * d[c])));
            }
        }
        let star = SharpStar { points };
        (star.points.iter().any(|p| p.0 > 0.0)).then_some(star)
    }

    /// A cheap, deterministic estimate of the reflected direct light at `spot` from the
    /// emitters `exact`: each one's unoccluded form factor (exact) times the share of its
    /// [`COARSE_POINTS`] that a shadow ray from the spot reaches; and from the sun and the
    /// point lights,
    /// [`Environment::coarse_sharp_direct`](crate::scene::Environment::coarse_sharp_direct).
    /// The points are the same on an emitter from every receiver, so the estimates at nearby
    /// points are correlated: an edge whose ends and midpoint all see every point gets the
    /// unoccluded light at each, whose departure from linearity is small, and an occluder
    /// that hides points from the midpoint alone (a leg's shadow between two lit vertices)
    /// shows as a departure of the midpoint from its ends' mean. The display refinement orders
    /// its exact tests by it ([`super::refine`]); it values nothing.
    pub(crate) fn coarse_direct(&self, spot: &Spot, exact: &[u32]) -> Rgb {
        let from = self.surfaces.point(spot.x + self.lift * spot.n);
        let mut sum = [0.0; 3];
        let mut last = usize::MAX;
        for &k in exact {
            let e = &self.emitters[k as usize];
            let Some(f) = e.form_factor(spot.x, spot.n) else {
                continue;
            };
            let seen = COARSE_POINTS
                .iter()
                .filter(|b| {
                    let y = b[0] * e.corners[0] + b[1] * e.corners[1] + b[2] * e.corners[2];
                    let to = self.surfaces.point(y + self.lift * e.normal);
                    !self
                        .surfaces
                        .occluded_after(&from, &to, spot.patch, &mut last)
                })
                .count();
            let v = seen as f64 / COARSE_POINTS.len() as f64;
            for (s, le) in sum.iter_mut().zip(e.le) {
                *s += le * f * v;
            }
        }
        if self.env.has_sharp() {
            let at = self.receiver(spot.x, spot.n, spot.patch);
            for (s, d) in sum.iter_mut().zip(self.env.coarse_sharp_direct(&at)) {
                *s += d;
            }
        }
        let rho = self.patches.reflectance[spot.patch as usize];
        std::array::from_fn(|c| rho[c] * sum[c])
    }

    /// Whether the hemisphere rays at `x` would bring some emitter's Le that `exact` and the
    /// other-light samples leave out: a large near emitter ([`SAMPLED_SPREAD`]) not among the
    /// exact ones (found through [`Gatherer::with_cache`]'s index beyond
    /// [`MAX_WEIGHED_EMITTERS`] emitters; without it, there, taken to be so).
    pub(super) fn leaves_emitters_to_rays(&self, x: DVec3, exact: &[u32]) -> bool {
        let left = |k: usize| {
            !self.sampled(&self.emitters[k], x) && exact.binary_search(&(k as u32)).is_err()
        };
        if self.emitters.len() <= MAX_WEIGHED_EMITTERS {
            return (0..self.emitters.len()).any(left);
        }
        let Some(index) = &self.unsampled else {
            return true;
        };
        let mut any = false;
        index.near(x, |k| any |= left(k as usize));
        any
    }

    /// Emitters whose direct light is computed exactly at each point: all of them, at most
    /// [`MAX_EXACT_EMITTERS`].
    pub fn exact_per_point(&self) -> usize {
        self.emitters.len().min(MAX_EXACT_EMITTERS)
    }

    /// The cost of a gathering point's direct light, in hemisphere rays: [`EXACT_EMITTER_COST`]
    /// per exact emitter (its visible pieces, [`visible`]; shadow rays only where they are too
    /// many to compute), the others' pilot and [`OTHER_LIGHT_SAMPLES`] when there are more
    /// emitters (where the pilot asks for [`OTHER_LIGHT_MAX_SAMPLES`], more), and the shadow
    /// rays of the lights outside the mesh
    /// ([`Environment::sharp_rays`](crate::scene::Environment::sharp_rays)).
    pub fn direct_cost_per_point(&self) -> usize {
        emitters_cost(self.emitters.len()) + self.env.sharp_rays()
    }
}

/// Pairs the emitting triangles that make a convex quadrilateral (a lamp's panel, a window,
/// each two triangles): two of the same Le that share an edge (the same two corners, equal to
/// the bit, run in opposite directions, so their fronts agree; whether or not the file shares
/// the vertices), with the same front normal (to 1e-9), whose union is strictly convex. In
/// index order, each unpaired triangle pairs with the lowest-numbered such triangle still
/// unpaired, so the pairs are the same on every run. Returns, per emitter, its partner and the
/// quadrilateral's corners, counter-clockwise seen from its front: its visible pieces are
/// then one polygon's, the pair one of [`MAX_EXACT_EMITTERS`] at a point.
pub(super) fn pair_emitters(emitters: &[Emitter]) -> Vec<Option<(u32, [DVec3; 4])>> {
    type Key = [u64; 3];
    let key = |p: DVec3| p.to_array().map(f64::to_bits);
    let mut by_edge: HashMap<(Key, Key), Vec<u32>> = HashMap::new();
    for (k, e) in emitters.iter().enumerate() {
        let c = e.corners;
        for i in 0..3 {
            by_edge
                .entry((key(c[i]), key(c[(i + 1) % 3])))
                .or_default()
                .push(k as u32);
        }
    }
    let mut partner: Vec<Option<(u32, [DVec3; 4])>> = vec![None; emitters.len()];
    for (k, e) in emitters.iter().enumerate() {
        if partner[k].is_some() {
            continue;
        }
        let v = e.corners;
        let mut best: Option<(u32, [DVec3; 4])> = None;
        for i in 0..3 {
            let (a, b, c) = (v[i], v[(i + 1) % 3], v[(i + 2) % 3]);
            for &j in by_edge.get(&(key(b), key(a))).into_iter().flatten() {
                let other = &emitters[j as usize];
                if j as usize == k
                    || partner[j as usize].is_some()
                    || best.is_some_and(|(bj, _)| bj < j)
                    || other.le != e.le
                    || other.normal.dot(e.normal) < 1.0 - 1e-9
                {
                    continue;
                }
                let far = |&w: &DVec3| key(w) != key(a) && key(w) != key(b);
                let Some(&d) = other.corners.iter().find(|w| far(w)) else {
                    continue;
                };
                let quad = [a, d, b, c];
                if strictly_convex(&quad, e.normal) {
                    best = Some((j, quad));
                }
            }
        }
        if let Some((j, quad)) = best {
            partner[k] = Some((j, quad));
            partner[j as usize] = Some((k as u32, quad));
        }
    }
    partner
}

/// Whether the planar polygon `p` turns left at every corner, seen from the side of `normal`
/// (by more than rounding: a corner on a straight line is not one).
fn strictly_convex(p: &[DVec3], normal: DVec3) -> bool {
    let count = p.len();
    (0..count).all(|i| {
        let (a, b, c) = (p[i], p[(i + 1) % count], p[(i + 2) % count]);
        let (u, w) = (b - a, c - b);
        u.cross(w).dot(normal) > 1e-9 * u.length() * w.length()
    })
}

/// What `emitters` emitters in the mesh cost a gathering point's direct light, in hemisphere
/// rays ([`Gatherer::direct_cost_per_point`] without the lights outside the mesh):
/// [`EXACT_EMITTER_COST`] for each of at most [`MAX_EXACT_EMITTERS`] exact ones, and the
/// others' pilot and [`OTHER_LIGHT_SAMPLES`] when there are more.
pub fn emitters_cost(emitters: usize) -> usize {
    let others = if emitters > MAX_EXACT_EMITTERS {
        OTHER_LIGHT_PILOT + OTHER_LIGHT_SAMPLES
    } else {
        0
    };
    EXACT_EMITTER_COST * emitters.min(MAX_EXACT_EMITTERS) + others
}

/// What the others' shadow rays at one gathering point are drawn by
/// ([`Gatherer::draw_others`]): found once for the point's pilot and its estimate.
pub(super) enum Weighed {
    /// Up to [`MAX_WEIGHED_EMITTERS`] emitters, the weights as a running sum over the emitters
    /// the rays may go to.
    Sums {
        /// Running sums of the weights, increasing.
        cdf: Vec<f64>,
        /// The emitter of each sum.
        keys: Vec<usize>,
    },
    /// Beyond, the light tree's draw less the exact emitters' u-intervals.
    Tree(crate::light::tree::Skip),
}

/// What the shadow rays of [`Gatherer::others_direct`] met: whether any reached its emitter,
/// whether any was stopped.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Seen {
    visible: bool,
    hidden: bool,
}

impl Seen {
    fn add(&mut self, visible: bool) {
        self.visible |= visible;
        self.hidden |= !visible;
    }

    /// Some rays met their emitter and some did not: the point sees part of the others.
    fn partial(self) -> bool {
        self.visible && self.hidden
    }
}
