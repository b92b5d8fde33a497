//! The final gather's indirect term at a point: ∫_Ω L_r(h(x, ω)) cosθ/π dω, the reflected
//! radiance of the solution arriving at x, by stratified cosine-weighted rays over the
//! hemisphere (Malley's method), each bringing the *reflected* radiance L − Le of the output
//! patch it hits (the emitted part is the direct term's, [`super::direct`], unless the emitter
//! is one left to these rays); a miss brings the sky's light, the back of a surface nothing.
//!
//! - **Near hits**: a hit closer than the hit patch's size ([`NEAR_HIT`]: a concave corner)
//!   brings instead the radiance at the hit point, one bounce further (its direct light by
//!   [`NEAR_HIT_SHADOW_RAYS`] per emitter, its indirect by [`NEAR_RAYS`] reading the patches,
//!   or, if that ray's hit is near too, the radiance there: [`NEAR_DEPTH`] near hits deep;
//!   past that, a hit in a slot by Russian roulette, [`SLOT_HIT`]).
//! - **Rays beside edges**: where the first rays show an edge of the incident light (a bright
//!   surface seen through a doorway, an occluder's outline), [`EDGE_RAYS`] more rays go into
//!   the strata beside it, each stratum's share chosen from its neighbours' rays only, so the
//!   estimate stays unbiased ([`Gatherer::with_edge_rays`]).
//! - **Bright patches**: where some patches' reflected light is many times the scene's mean
//!   (the floor where the sun falls), shadow rays go to them as well, weighed against the
//!   hemisphere's by multiple importance sampling ([`super::bright`]).
//! - **The sky** comes through the rays that leave the scene above the horizon (a uniform sky
//!   as its exact unoccluded light times the open share of those rays, so an open surface
//!   gets it exactly).

use glam::DVec3;

use std::f64::consts::PI;

use super::bright::{bright_rays, Bright};
use super::openings::{Openings, OPENING_RAYS};
use super::sites::Spot;
use super::trace::PatchHit;
use super::Gatherer;
use crate::color::{luminance, Rgb};
use crate::light::emitter::NEAR_HIT_SHADOW_RAYS;
use crate::sampling::{malley, triangle_barycentrics, Rng};
use crate::scene::SkyModel;
use crate::visibility::NONE;

/// More hemisphere rays, as a share of a gather's `rays`, cast into the strata beside an edge
/// of the incident light (the hemisphere rays of [`Gatherer::indirect`]): a bright surface
/// seen through a doorway or past an occluder, whose outline the stratified rays cross. A
/// stratum on the outline finds either side with its one ray, and those strata carry most of
/// the estimate's variance: there the stratified error falls as rays^-0.75 (the outline's
/// strata, ∝ √rays, each with a variance ∝ 1/rays²), against rays^-1 for a smooth integrand.
/// Half as many rays again, for about a third more gather time: the room lit through a
/// doorway (the point-wise benchmark's `two_rooms`, BENCHMARKS.md "Displayed error against a
/// path tracer") gains most, since most of its light arrives past one bright outline, the
/// part the plain strata resolve worst; scenes with fewer such edges gain a little. The same
/// rays in all with fewer first rays do worse: the edges need the first rays' resolution too.
pub const EDGE_RAYS: f64 = 0.5;

/// Strata per side (of `rays`' √rays × √rays) from which a hemisphere adds [`EDGE_RAYS`]: at 64
/// rays (8 × 8, the least [`auto_rays`](super::auto_rays) gives) a stratum's neighbours span a
/// quarter of the hemisphere's radius and see edges everywhere, so the added rays cost time without
/// going where an edge is (the generated hall, gathered at 64 rays, is no better with them).
pub const EDGE_MIN_SIDE: usize = 12;

/// At most this many more rays in one stratum (16 in all).
pub const EDGE_MAX_PER_STRATUM: usize = 15;

/// A hemisphere ray of the gather that hits a patch closer than this many times the square
/// root of the patch's area brings the radiance at the hit point, evaluated one bounce further
/// ([`NEAR_HIT_SHADOW_RAYS`], [`NEAR_RAYS`]), instead of the patch's mean radiance. Near a
/// concave corner (a ceiling along a wall, a floor beside a block) the hits lie within a patch
/// of the gathering point, where the radiance bends on a scale far below the patch's size (it
/// falls toward the corner) and the patch's mean overstates it: gathered with patch means
/// alone, the Cornell box's ceiling next to the back wall comes out too bright however
/// many rays are cast: a bias, not noise. The same rule as the photon map's final gather,
/// which reads the map only for distant hits (Jensen, "Global Illumination using Photon
/// Maps", EGWR 1996, §4). One patch size catches the corners' hits; a larger reach
/// evaluates more hits at the cost of gather time, for no better display.
pub const NEAR_HIT: f64 = 1.0;

/// Hemisphere rays at a near hit's point ([`NEAR_HIT`]), reading the patches' radiance.
pub const NEAR_RAYS: usize = 1;

/// Near hits followed one after another, at most ([`NEAR_HIT`]): the ray from a near hit's
/// point is itself a near hit where it goes back into the corner or across a narrow gap, and
/// the patch mean it would read there overstates the light as the first one's would. The
/// second level takes out nearly all of the bias the first leaves along the Cornell box's
/// ceiling corners (the test `near_hits_bring_the_radiance_at_the_hit_point_not_the_patch_mean`
/// bounds both) and much of the error at points in narrow gaps (the generated hall's few
/// millimetres between table tops and legs, seats and backs); each further level adds gather
/// time, more of it the deeper, and helps little.
pub const NEAR_DEPTH: u32 = 2;

/// A near hit at the end of a chain ([`NEAR_DEPTH`] followed) closer than this share of the
/// hit patch's size is in a slot (a leg's top a few millimetres under a table top, a seat's
/// underside over its frame): there a chain bounces between the two faces many times before
/// it leaves, and the patch mean it would read overstates the light in the slot many times
/// over. Such a hit is followed further by Russian roulette (Arvo & Kirk, "Particle
/// transport and image synthesis", SIGGRAPH 1990): with probability [`ROULETTE`], its value
/// divided by it, else nothing, so the chain's expected value is that of following it to its
/// end, at an expected cost of one more level a chain.
pub const SLOT_HIT: f64 = 0.25;

/// The probability of following a slot's hit one level more ([`SLOT_HIT`]).
pub const ROULETTE: f64 = 0.5;

/// Rays of [`Gatherer::coarse_indirect`]: 4 × 4 strata, as many as a display test's own
/// ([`super::refine::TEST_RAYS`]).
pub const COARSE_RAYS: usize = 16;

impl Gatherer<'_> {
    /// ∫_Ω L_r(h(x, ω)) cosθ/π dω by `rays` stratified cosine-weighted rays: the reflected
    /// radiance arriving at `x` from the solution (radiance units). A ray that hits within
    /// [`NEAR_HIT`] of the hit patch's size brings the radiance evaluated at the hit point
    /// one bounce further instead of the patch's mean.
    pub fn indirect(
        &self,
        x: DVec3,
        n: DVec3,
        ignore: u32,
        exact: &[u32],
        rays: usize,
        rng: &mut Rng,
    ) -> Rgb {
        let rays = (rays, bright_rays(rays));
        self.hemisphere_with(x, n, ignore, (exact, Count::Rule), rays, NEAR_DEPTH, rng)
            .radiance
    }

    /// The reflected radiance ρ·(direct + indirect) leaving the point `y` of patch `h`, one
    /// sample deep: the exact emitters' form factors with one shadow ray each
    /// ([`NEAR_HIT_SHADOW_RAYS`]) and one cosine-weighted ray reading the patches' radiance
    /// ([`NEAR_RAYS`]), or the radiance at its hit if that is near too and `near_bounces` > 0.
    /// Unbiased for the hit point's direct light up to the ratio estimate of its visible
    /// share, and noisy alone; the gather averages many such hits.
    fn reflected_at_hit(
        &self,
        y: DVec3,
        h: usize,
        exact: &[u32],
        near_bounces: u32,
        rng: &mut Rng,
    ) -> Rgb {
        let ny = self.patches.normal[h];
        // The gathering point's own exact emitters (`y` lies within a patch of it): its
        // direct term counts their emission, the ray at `y` the others'.
        let hi = h as u32;
        let rays = (
            NEAR_HIT_SHADOW_RAYS,
            NEAR_HIT_SHADOW_RAYS,
            NEAR_HIT_SHADOW_RAYS,
        );
        let (direct, _) = self.direct_from(y, ny, hi, exact, rays, true, rng);
        let indirect = self
            .hemisphere(
                y,
                ny,
                hi,
                (exact, Count::Rule),
                NEAR_RAYS,
                near_bounces,
                rng,
            )
            .radiance;
        let rho = self.patches.reflectance[h];
        std::array::from_fn(|c| rho[c] * (direct[c] + indirect[c]))
    }

    /// [`Gatherer::indirect`], following at most `near_bounces` near hits in a chain, with the
    /// standard error of the estimate and the share of its rays that met a back face.
    /// `counted` is the emitters whose Le the point's
    /// direct term counts (`exact`, and by [`Count`] the rule for the others).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn hemisphere(
        &self,
        x: DVec3,
        n: DVec3,
        ignore: u32,
        counted: (&[u32], Count),
        rays: usize,
        near_bounces: u32,
        rng: &mut Rng,
    ) -> Hemisphere {
        self.hemisphere_with(x, n, ignore, counted, (rays, 0), near_bounces, rng)
    }

    /// [`Gatherer::hemisphere`] with `bright` shadow rays to the bright patches (`(rays,
    /// bright)`; [`super::bright`]) and, with `bright` > 0, [`OPENING_RAYS`] rays through the
    /// openings ([`super::openings`]) as well, each combined with the hemisphere rays by
    /// multiple importance sampling; neither where the scene has none, nor at a near hit.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn hemisphere_with(
        &self,
        x: DVec3,
        n: DVec3,
        ignore: u32,
        counted: (&[u32], Count),
        rays: (usize, usize),
        near_bounces: u32,
        rng: &mut Rng,
    ) -> Hemisphere {
        self.hemisphere_graded(x, n, ignore, counted, rays, near_bounces, false, rng)
            .0
    }

    /// [`Gatherer::hemisphere_with`], and with `graded` the estimate's gradients as well
    /// ([`Gradient`], from the same rays: no ray more).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn hemisphere_graded(
        &self,
        x: DVec3,
        n: DVec3,
        ignore: u32,
        counted: (&[u32], Count),
        (rays, bright): (usize, usize),
        near_bounces: u32,
        graded: bool,
        rng: &mut Rng,
    ) -> (Hemisphere, Option<Gradient>) {
        let frame = Frame::of(n);
        let mut sum = [0.0; 3];
        let mut backs = 0usize;
        // Σ Y² of what each ray brings, for the spread.
        let mut squares = 0.0;
        // The sky: rays above the horizon, and those of them that leave the scene.
        let (mut above, mut open) = (0usize, 0usize);
        let up = self.env.up.axis();
        // √rays × √rays strata of the unit square (Malley: uniform on the disc, lifted).
        let side = (rays as f64).sqrt().ceil().max(1.0) as usize;
        let total = side * side;
        // The bright patches' rays and the rays through the openings, where the scene has
        // them, and the weights that share each direction between them and the hemisphere's.
        let top = bright > 0 && near_bounces > 0;
        let bright = self.bright.as_ref().filter(|_| top).map(|b| (b, bright));
        let openings = self.openings.as_ref().filter(|_| top);
        let mis = Mis {
            strata: total as f64,
            bright: bright.map_or(0.0, |(_, k)| k as f64),
            open: if openings.is_some() {
                OPENING_RAYS as f64
            } else {
                0.0
            },
        };
        let origin = x + self.lift * n;
        // Each stratum's first ray, for the rays beside edges.
        let edges = side >= EDGE_MIN_SIDE && self.edge_rays > 0.0;
        let mut strata: Vec<First> = Vec::with_capacity(if edges { total } else { 0 });
        // Each stratum's first ray for the gradients: the radiance it met and how far.
        let mut seen: Vec<(Rgb, f64)> = Vec::with_capacity(if graded { total } else { 0 });
        for k in 0..total {
            let dir = frame.in_stratum(k, side, rng);
            let is_above = dir.dot(up) > 0.0;
            above += usize::from(is_above);
            let (ray, distance) = self.along(x, n, dir, ignore, counted, near_bounces, rng);
            match ray {
                Ray::Back => backs += 1,
                Ray::Left => open += usize::from(is_above),
                Ray::Brought(..) => {}
            }
            if graded {
                let met = match ray {
                    Ray::Brought(l, _) => l,
                    Ray::Back => [0.0; 3],
                    Ray::Left => self.env.sky_radiance(dir),
                };
                seen.push((met, distance));
            }
            let (brought, light) = self.weighed(ray, origin, dir, mis, openings);
            let cos = dir.dot(n);
            let weighted = brought.map(|l| l * mis.hemisphere(light, cos, 1));
            squares += luminance(weighted).powi(2);
            for (s, l) in sum.iter_mut().zip(weighted) {
                *s += l;
            }
            if edges {
                strata.push(First {
                    brought,
                    light,
                    cos,
                });
            }
        }
        let count = total as f64;
        // Rays per stratum (1, or more beside edges).
        let mut per_stratum: Vec<usize> = Vec::new();
        if edges {
            (sum, per_stratum) = self.beside_edges(
                x,
                &frame,
                ignore,
                counted,
                near_bounces,
                &strata,
                (mis, openings),
                rng,
            );
        }
        let mut out = sum.map(|s| s / count);
        let spread = (squares / count - luminance(out).powi(2)).max(0.0);
        let rays_in = |dir: DVec3| {
            per_stratum
                .get(frame.stratum_of(dir, side))
                .copied()
                .unwrap_or(1)
        };
        if let Some((b, k)) = bright {
            let found = self.bright_rays(x, n, ignore, b, k, mis, rays_in, rng);
            for (o, l) in out.iter_mut().zip(found) {
                *o += l;
            }
        }
        if let Some(o) = openings {
            let found = self.opening_rays(origin, n, ignore, o, mis, rays_in, rng);
            for (o, l) in out.iter_mut().zip(found) {
                *o += l;
            }
        } else if self.env.sky_model == SkyModel::Uniform {
            // A uniform sky by the ratio estimate: exact where nothing is in the way.
            for (o, l) in out
                .iter_mut()
                .zip(self.env.uniform_sky(n, open as f64, above))
            {
                *o += l;
            }
        }
        let hemisphere = Hemisphere {
            radiance: out,
            error: (spread / count).sqrt(),
            backs: backs as f64 / count,
        };
        (hemisphere, graded.then(|| gradient(&frame, side, &seen)))
    }

    /// The bright patches' share of ∫ L_r cosθ/π dω at `x` by `count` shadow rays to them
    /// (see [`super::bright`]), each weighted against the hemisphere's rays in its direction's
    /// stratum (`rays_in`). Radiance units.
    #[allow(clippy::too_many_arguments)]
    fn bright_rays(
        &self,
        x: DVec3,
        n: DVec3,
        ignore: u32,
        bright: &Bright,
        count: usize,
        mis: Mis,
        rays_in: impl Fn(DVec3) -> usize,
        rng: &mut Rng,
    ) -> Rgb {
        let origin = x + self.lift * n;
        let from = self.surfaces.point(origin);
        let mut sum = [0.0; 3];
        let draws: Vec<usize> = bright.draws(count, rng.next_f64()).collect();
        let mut last = usize::MAX;
        for h in draws {
            let [a, b, c] = self.patches.corners(h);
            let [wa, wb, wc] = triangle_barycentrics(rng.next_f64(), rng.next_f64());
            let y = wa * a + wb * b + wc * c;
            let ny = self.patches.normal[h];
            let d = y - origin;
            let r = d.length();
            // A near point is the hemisphere rays' alone (they evaluate it one bounce
            // further, not as the patch's mean): see `super::bright`.
            if r == 0.0 || r < NEAR_HIT * self.patches.area[h].sqrt() {
                continue;
            }
            let dir = d / r;
            let cos = n.dot(dir);
            let density = bright.direction_density(h, origin, y, ny);
            if cos <= 0.0 || density <= 0.0 || h as u32 == ignore {
                continue;
            }
            let to = self.surfaces.point(y + self.lift * ny);
            if self.surfaces.occluded_after(&from, &to, ignore, &mut last) {
                continue;
            }
            let w = mis.light(mis.bright * density, cos, rays_in(dir));
            let l = self.radiance[h];
            for (s, l) in sum.iter_mut().zip(l) {
                *s += l * (cos / PI) / density * w / count as f64;
            }
        }
        sum
    }

    /// What a hemisphere ray from `origin` along `dir` brings, and the count-density with which
    /// the bright or the opening rays propose its direction ([`Mis`]). With the openings
    /// sampled, a ray that leaves the scene brings the sky's radiance that way (the ratio
    /// estimate of a uniform sky is not used then).
    fn weighed(
        &self,
        ray: Ray,
        origin: DVec3,
        dir: DVec3,
        mis: Mis,
        openings: Option<&Openings>,
    ) -> (Rgb, f64) {
        match (ray, openings) {
            (Ray::Brought(l, density), _) => (l, mis.bright * density),
            (Ray::Back, _) => ([0.0; 3], 0.0),
            (Ray::Left, Some(o)) => (
                self.env.sky_radiance(dir),
                mis.open * o.direction_density(origin, dir),
            ),
            (Ray::Left, None) => (self.left_along(dir), 0.0),
        }
    }

    /// The sky's share of ∫ L cosθ/π dω at `origin` (unit normal `n`, lifted off its patch
    /// `ignore`) by [`OPENING_RAYS`] rays toward points of the openings (see
    /// [`super::openings`]), each weighed against the hemisphere's rays in its direction's
    /// stratum (`rays_in`). Radiance units.
    #[allow(clippy::too_many_arguments)]
    fn opening_rays(
        &self,
        origin: DVec3,
        n: DVec3,
        ignore: u32,
        openings: &Openings,
        mis: Mis,
        rays_in: impl Fn(DVec3) -> usize,
        rng: &mut Rng,
    ) -> Rgb {
        let mut sum = [0.0; 3];
        let up = self.env.up.axis();
        for q in openings.points(OPENING_RAYS, rng) {
            let dir = (q - origin).normalize();
            let cos = n.dot(dir);
            if cos <= 0.0 || dir.dot(up) <= 0.0 {
                continue;
            }
            let density = openings.direction_density(origin, dir);
            if density <= 0.0 || self.surfaces.closest(origin, dir, ignore).is_some() {
                continue;
            }
            let w = mis.light(mis.open * density, cos, rays_in(dir));
            for (s, l) in sum.iter_mut().zip(self.env.sky_radiance(dir)) {
                *s += l * (cos / PI) / density * w / OPENING_RAYS as f64;
            }
        }
        sum
    }

    /// The stratified sum Σ_k of each stratum's mean, with more rays in the strata beside an
    /// edge of the incident light. `strata` holds the first ray of each of the √n × √n strata
    /// of [`Gatherer::hemisphere`] (row i the radial coordinate, column j the angle, which
    /// wraps round). Stratum k keeps its first ray and adds m_k more drawn uniformly in it;
    /// m_k ∝ the range of the first rays' luminance over its eight neighbours, never its own,
    /// an estimate of its own spread σ_k (Neyman's allocation, n_k ∝ σ_k: Cochran, *Sampling
    /// Techniques*, 3rd ed., 1977, §5.5), sharing out about [`Gatherer::edge_rays`] × n rays
    /// in all, at most [`EDGE_MAX_PER_STRATUM`] in one. The share is normalised by the ranges
    /// of the strata that are neither k nor its neighbours, which do not see k's first ray
    /// either. So m_k does not depend on stratum k's own rays, each stratum's mean stays an
    /// unbiased estimate of its integral, and so does the sum (the test
    /// `rays_beside_edges_keep_the_gather_unbiased_and_cut_its_noise`).
    ///
    /// With the bright patches sampled too, each ray of stratum k counts with the weight of
    /// its stratum's m_k + 1 rays ([`Mis::hemisphere`]); also returns those counts.
    #[allow(clippy::too_many_arguments)]
    fn beside_edges(
        &self,
        x: DVec3,
        frame: &Frame,
        ignore: u32,
        counted: (&[u32], Count),
        near_bounces: u32,
        strata: &[First],
        (mis, openings): (Mis, Option<&Openings>),
        rng: &mut Rng,
    ) -> (Rgb, Vec<usize>) {
        let origin = x + self.lift * frame.n;
        let side = (strata.len() as f64).sqrt().round() as usize;
        debug_assert_eq!(side * side, strata.len());
        // Stratum k and its neighbours: rows i − 1..=i + 1 within the disc, columns j − 1..=j + 1
        // round the circle.
        let block = |k: usize| {
            let (i, j) = (k / side, k % side);
            (i.saturating_sub(1)..(i + 2).min(side))
                .flat_map(move |ii| [j + side - 1, j, j + 1].map(|c| ii * side + c % side))
        };
        let y: Vec<f64> = strata.iter().map(|f| luminance(f.brought)).collect();
        let range: Vec<f64> = (0..strata.len())
            .map(|k| {
                let (lo, hi) = block(k)
                    .filter(|&q| q != k)
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
                        (lo.min(y[q]), hi.max(y[q]))
                    });
                (hi - lo).max(0.0)
            })
            .collect();
        let spread: f64 = range.iter().sum();
        let mut sum = [0.0; 3];
        let mut per_stratum = Vec::with_capacity(strata.len());
        for (k, first) in strata.iter().enumerate() {
            // m_k ∝ range_k, normalised by the ranges that do not see stratum k's own ray (not
            // its neighbours', nor its own), so that m_k stays independent of that ray.
            let (near, count) = block(k).fold((0.0, 0usize), |(r, c), q| (r + range[q], c + 1));
            let others = spread - near;
            let m = if others > 1e-9 * spread {
                let share = self.edge_rays * (strata.len() - count) as f64 / others;
                ((share * range[k]).round() as usize).min(EDGE_MAX_PER_STRATUM)
            } else {
                0
            };
            let w = mis.hemisphere(first.light, first.cos, m + 1);
            let mut stratum = first.brought.map(|l| l * w);
            for _ in 0..m {
                let dir = frame.in_stratum(k, side, rng);
                let (ray, _) = self.along(x, frame.n, dir, ignore, counted, near_bounces, rng);
                let (brought, light) = self.weighed(ray, origin, dir, mis, openings);
                let w = mis.hemisphere(light, dir.dot(frame.n), m + 1);
                for (s, l) in stratum.iter_mut().zip(brought) {
                    *s += l * w;
                }
            }
            for (s, l) in sum.iter_mut().zip(stratum) {
                *s += l / (m + 1) as f64;
            }
            per_stratum.push(m + 1);
        }
        (sum, per_stratum)
    }

    /// What a hemisphere ray that left the scene along `dir` brings: the sky's radiance from
    /// there (none below the horizon), or nothing from a uniform sky, whose light
    /// [`Gatherer::hemisphere`] adds by its ratio estimate.
    fn left_along(&self, dir: DVec3) -> Rgb {
        if self.env.sky_model == SkyModel::Uniform {
            [0.0; 3]
        } else {
            self.env.escaped(dir)
        }
    }

    /// What one hemisphere ray from `x` along `dir` brings from the scene's surfaces (see
    /// [`Gatherer::hemisphere`]).
    #[allow(clippy::too_many_arguments)]
    fn along(
        &self,
        x: DVec3,
        n: DVec3,
        dir: DVec3,
        ignore: u32,
        (exact, rule): (&[u32], Count),
        near_bounces: u32,
        rng: &mut Rng,
    ) -> (Ray, f64) {
        let Some(hit) = self.surfaces.closest(x + self.lift * n, dir, ignore) else {
            return (Ray::Left, f64::INFINITY);
        };
        let h = hit.patch as usize;
        if self.patches.normal[h].dot(dir) >= 0.0 {
            return (Ray::Back, hit.t); // the back of a one-sided surface sends nothing
        }
        // The emitted part of what it sends was counted by the direct term if its emitter
        // is one of `exact` or sampled from here (the others' rays), or every emitter's is.
        let e = self.emitter_of[self.patches.source_triangle[h] as usize];
        let counted = e != NONE
            && (rule == Count::All
                || exact.binary_search(&e).is_ok()
                || self.sampled(&self.emitters[e as usize], x));
        let (l, le) = (self.radiance[h], self.patches.emission[h]);
        let y = x + self.lift * n + hit.t * dir;
        let size = self.patches.area[h].sqrt();
        let reflected = if near_bounces > 0 && hit.t < NEAR_HIT * size {
            // A near hit (a concave corner): the patch's mean is not the radiance at the
            // hit point; evaluate it there, one bounce further (see NEAR_HIT).
            Some(self.reflected_at_hit(y, h, exact, near_bounces - 1, rng))
        } else if near_bounces == 0 && self.roulette > 0.0 && hit.t < SLOT_HIT * size {
            // The chain's end in a slot (see SLOT_HIT): the hit point's reflected light by
            // Russian roulette, followed with probability q and divided by it, else none.
            let q = self.roulette;
            Some(match rng.next_f64() < q {
                true => self.reflected_at_hit(y, h, exact, 0, rng).map(|l| l / q),
                false => [0.0; 3],
            })
        } else {
            None
        };
        if let Some(reflected) = reflected {
            // The emitted part as always, the reflected part from the hit point.
            return (
                Ray::Brought(
                    std::array::from_fn(|c| (if counted { 0.0 } else { le[c] }) + reflected[c]),
                    0.0,
                ),
                hit.t,
            );
        }
        // A far point of a bright patch: how densely the bright rays propose it.
        let density = match &self.bright {
            Some(b) if near_bounces > 0 => {
                b.direction_density(h, x + self.lift * n, y, self.patches.normal[h])
            }
            _ => 0.0,
        };
        let brought = std::array::from_fn(|c| {
            if counted {
                (l[c] - le[c]).max(0.0)
            } else {
                l[c]
            }
        });
        (Ray::Brought(brought, density), hit.t)
    }

    /// The reflected indirect light ρ·∫ L cosθ/π dω at `spot` by `rays` hemisphere rays (as
    /// [`Gatherer::full`] computes it, `exact` the emitters its direct term counts), a bound
    /// on the standard error of its luminance (max ρ × the rays' spread), and the share of
    /// the rays that met the back of a surface: what the display refinement tests a midpoint
    /// with.
    pub(crate) fn reflected_indirect(
        &self,
        spot: &Spot,
        exact: &[u32],
        rays: usize,
        rng: &mut Rng,
    ) -> (Rgb, f64, f64) {
        let h = self.hemisphere_with(
            spot.x,
            spot.n,
            spot.patch,
            (exact, Count::Rule),
            (rays, bright_rays(rays)),
            NEAR_DEPTH,
            rng,
        );
        let rho = self.patches.reflectance[spot.patch as usize];
        let rho_max = rho.iter().copied().fold(0.0, f64::max);
        (
            std::array::from_fn(|c| rho[c] * h.radiance[c]),
            rho_max * h.error,
            h.backs,
        )
    }
}

impl Gatherer<'_> {
    /// The Le the hemisphere rays at `x` bring from the emitters its direct term does not
    /// count (`exact`, and those sampled from `x`): ∫ Le(h(x, ω)) cosθ/π dω over those, by
    /// `rays` stratified cosine-weighted rays reading only the emission of their first hit
    /// (radiance units). The `cache` gather's points add it to the records' reflected light
    /// ([`super::cache`]); 0 without casting where no emitter is left to rays.
    pub(super) fn uncounted_emission(
        &self,
        spot: &Spot,
        exact: &[u32],
        rays: usize,
        rng: &mut Rng,
    ) -> Rgb {
        if !self.leaves_emitters_to_rays(spot.x, exact) {
            return [0.0; 3];
        }
        let mut sum = [0.0; 3];
        let count = self.first_hits(spot, rays, rng, |dir, hit| {
            let Some(hit) = hit else { return };
            let h = hit.patch as usize;
            let e = self.emitter_of[self.patches.source_triangle[h] as usize];
            if e == NONE
                || self.patches.normal[h].dot(dir) >= 0.0
                || exact.binary_search(&e).is_ok()
                || self.sampled(&self.emitters[e as usize], spot.x)
            {
                return;
            }
            for (s, l) in sum.iter_mut().zip(self.patches.emission[h]) {
                *s += l;
            }
        });
        sum.map(|s| s / count as f64)
    }
}

impl Gatherer<'_> {
    /// The reflected indirect light at `spot`, ray by ray and cheaply: [`COARSE_RAYS`]
    /// stratified cosine-weighted rays, each giving the luminance of ρ × what it first meets:
    /// the solution's reflected radiance L − Le of a front face (emission is the direct
    /// term's), nothing from a back, the sky's radiance where it leaves the scene. No near
    /// hits, bright patches or openings: it values nothing. The jitter is the same at every
    /// point (one fixed seed), so points with the same normal cast the same directions, and the
    /// difference of two nearby points' estimates ray by ray keeps what differs between them
    /// (a leg's top 5 mm under one, the floor under the other) while most of what they share
    /// cancels: common random numbers. The display refinement orders and decides its tests of
    /// the indirect light by it ([`super::refine`]).
    pub(crate) fn coarse_indirect(&self, spot: &Spot) -> [f32; COARSE_RAYS] {
        let mut rng = Rng::new(&[self.seed, 0xC0A7_5E1D]);
        let rho = self.patches.reflectance[spot.patch as usize];
        let mut out = [0.0; COARSE_RAYS];
        let mut k = 0;
        self.first_hits(spot, COARSE_RAYS, &mut rng, |dir, hit| {
            let l = match hit {
                None => self.env.escaped(dir),
                Some(hit) => {
                    let h = hit.patch as usize;
                    if self.patches.normal[h].dot(dir) >= 0.0 {
                        [0.0; 3]
                    } else {
                        let (l, le) = (self.radiance[h], self.patches.emission[h]);
                        std::array::from_fn(|c| (l[c] - le[c]).max(0.0))
                    }
                }
            };
            out[k] = luminance(std::array::from_fn(|c| rho[c] * l[c])) as f32;
            k += 1;
        });
        out
    }

    /// Casts √rays × √rays stratified cosine-weighted rays from `spot` (unshaded) and calls
    /// `f` with each direction and its first hit (`None` where it leaves the scene); returns
    /// how many.
    fn first_hits(
        &self,
        spot: &Spot,
        rays: usize,
        rng: &mut Rng,
        mut f: impl FnMut(DVec3, Option<PatchHit>),
    ) -> usize {
        let frame = Frame::of(spot.n);
        let side = (rays as f64).sqrt().ceil().max(1.0) as usize;
        let from = spot.x + self.lift * spot.n;
        for k in 0..side * side {
            let dir = frame.in_stratum(k, side, rng);
            f(dir, self.surfaces.closest(from, dir, spot.patch));
        }
        side * side
    }

    /// The share of `rays` stratified cosine-weighted rays from `spot` that meet the back of a
    /// surface, unshaded (the display refinement's walled-in test where the `cache` gather
    /// gives a midpoint's light).
    pub(super) fn backs(&self, spot: &Spot, rays: usize, rng: &mut Rng) -> f64 {
        let mut backs = 0usize;
        let count = self.first_hits(spot, rays, rng, |dir, hit| {
            backs += usize::from(
                hit.is_some_and(|hit| self.patches.normal[hit.patch as usize].dot(dir) >= 0.0),
            );
        });
        backs as f64 / count as f64
    }

    /// The harmonic mean distance of the hits of `rays` stratified cosine-weighted rays from
    /// `spot` (backs count), over the rays that hit: ∞ where none does. Ward's R
    /// ([`super::cache`]), unshaded. The rays that leave the scene are left out, not counted
    /// as infinitely far: Ward's split sphere bounds the light's change by the distance of
    /// what is seen, and under an open sky a plate a quarter of a metre up changes the light
    /// as fast as a closed ceiling there would, while the rays through to the sky would
    /// stretch R by the share they take (the test
    /// `cache_records_beside_a_plate_serve_only_where_its_light_is_theirs`).
    pub(super) fn harmonic_distance(&self, spot: &Spot, rays: usize, rng: &mut Rng) -> f64 {
        let (mut inverse, mut hits) = (0.0, 0usize);
        self.first_hits(spot, rays, rng, |_, hit| {
            if let Some(hit) = hit {
                inverse += 1.0 / hit.t;
                hits += 1;
            }
        });
        if hits == 0 {
            f64::INFINITY
        } else {
            hits as f64 / inverse
        }
    }
}

/// Which emitters' Le a hemisphere's rays leave out, as the point's direct term counts it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Count {
    /// The point's exact emitters and those its other-light rays sample
    /// ([`Gatherer::sampled`]): the rays bring the rest's Le.
    Rule,
    /// Every emitter's: the rays bring only reflected light (a cache record's, whose value
    /// is read at other points with other direct terms: [`super::cache`]).
    All,
}

/// What one hemisphere ray brings ([`Gatherer::along`]).
enum Ray {
    /// It left the scene (the sky's, if any).
    Left,
    /// It met the back of a one-sided surface, which sends nothing.
    Back,
    /// The radiance it brings from a front face, and the density with which one ray to the
    /// bright patches proposes its direction ([`super::bright`]; 0 unless it reached a far
    /// point of a bright patch and the gather samples them).
    Brought(Rgb, f64),
}

/// A hemisphere's estimate ([`Gatherer::hemisphere`]).
pub(super) struct Hemisphere {
    /// The incident radiance's cosine-weighted mean, ∫ L cosθ/π dω (radiance units).
    pub(super) radiance: Rgb,
    /// The standard error of its luminance, from the rays' spread (an upper bound: the rays
    /// are stratified).
    pub(super) error: f64,
    /// The share of the rays that met the back of a surface, in [0, 1].
    pub(super) backs: f64,
}

/// The first-order change of a hemisphere's I = ∫ L cosθ/π dω (radiance units) with the
/// point's position, per colour channel (Ward & Heckbert, "Irradiance gradients",
/// Eurographics Rendering Workshop 1992; in the notation of Křivánek & Gautron, "Practical
/// global illumination with irradiance caching", 2009, §2.3): at x near x₀ on the same
/// surface, I(x) ≈ I(x₀) + (x − x₀)·∇I, ∇I in radiance per scene unit, in the tangent plane.
///
/// (Ward & Heckbert's rotational gradient, the change with the normal, is not kept: its
/// estimate weighs each ray by tanθ, and the rays near the horizon that meet a sunlit floor
/// made it noisier than the change it models; BENCHMARKS.md "Tried and not kept".)
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Gradient(pub(super) [DVec3; 3]);

impl Gradient {
    /// `value` (the estimate at x₀) carried to x₀ + `offset`, each channel kept in
    /// [0, 2·value]: a first-order estimate that its own noise or a far extrapolation would
    /// otherwise take below zero.
    pub(super) fn carry(&self, value: Rgb, offset: DVec3) -> Rgb {
        std::array::from_fn(|c| (value[c] + offset.dot(self.0[c])).clamp(0.0, 2.0 * value[c]))
    }

    /// The gradient scaled so that within `reach` of x₀ it changes the luminance by at most
    /// `share` of the value's (Křivánek et al., "Making radiance and irradiance caching
    /// practical", EGSR 2006, bound a record's radius by I / |∇I| for the same reason: a
    /// linear extrapolation of a noisy gradient runs far from the light).
    pub(super) fn limited(self, value: Rgb, reach: f64, share: f64) -> Gradient {
        let size = luminance(self.0.map(|g| g.length())) * reach;
        let y = share * luminance(value);
        if size > y {
            let scale = if size > 0.0 { y / size } else { 0.0 };
            Gradient(self.0.map(|g| g * scale))
        } else {
            self
        }
    }
}

/// The translational gradient of a stratified hemisphere from its strata's first rays
/// (`seen[k]`: the radiance met in stratum k of [`Frame::in_stratum`]'s `side` × `side`, and
/// how far; ∞ for a ray that left the scene), by Ward & Heckbert's formula (see
/// [`Gradient`]). The rows of the grid are the strata of sin²θ (their j, M = `side`), its
/// columns those of φ (their k, N = `side`). As the point moves, the surfaces that each
/// boundary between neighbouring strata meets shift in its view, and the light changes by the
/// difference of the two strata's radiance, times the boundary's length in projected solid
/// angle, over the nearer of the two hits' distances:
///
/// π ∇I = Σ_k [ u_k (2π/N) Σ_{j≥1} sinθ⁻_j cos²θ⁻_j (L_{jk} − L_{j−1,k}) / min(r_{jk}, r_{j−1,k})
///      + v⁻_k Σ_j cosθ_j (cosθ⁻_j − cosθ⁺_j) (L_{jk} − L_{j,k−1}) / (sinθ_j min(r_{jk}, r_{j,k−1})) ],
///
/// u_k the tangent direction at the column's centre φ_k, v⁻_k that at φ⁻_k + π/2 (φ⁻_k the
/// column's first angle), θ_j the row's centre and θ⁻_j, θ⁺_j its bounds (sin²θ⁻_j = j/M). A
/// boundary between two rays that both left the scene moves nothing.
fn gradient(frame: &Frame, side: usize, seen: &[(Rgb, f64)]) -> Gradient {
    debug_assert_eq!(seen.len(), side * side);
    let m = side as f64;
    let tangent = |phi: f64| phi.cos() * frame.t + phi.sin() * frame.b;
    // Per column: u_k, at its centre, and v⁻_k, at its first angle plus π/2.
    let u: Vec<DVec3> = (0..side)
        .map(|j| tangent(2.0 * PI * (j as f64 + 0.5) / m))
        .collect();
    let v: Vec<DVec3> = (0..side)
        .map(|j| tangent(2.0 * PI * j as f64 / m + 0.5 * PI))
        .collect();
    let mut g = [DVec3::ZERO; 3];
    let mut add = |dir: DVec3, f: f64, l: Rgb, l2: Rgb| {
        if f.is_finite() {
            for c in 0..3 {
                g[c] += dir * (f * (l[c] - l2[c]));
            }
        }
    };
    for i in 0..side {
        let (lo, centre, hi) = (i as f64 / m, (i as f64 + 0.5) / m, (i + 1) as f64 / m);
        let (sin_c, cos_c) = (centre.sqrt(), (1.0 - centre).sqrt());
        let (sin_lo, cos_lo) = (lo.sqrt(), (1.0 - lo).sqrt());
        let cos_hi = (1.0 - hi).max(0.0).sqrt();
        for j in 0..side {
            let (l, r) = seen[i * side + j];
            if i >= 1 {
                let (l2, r2) = seen[(i - 1) * side + j];
                let f = 2.0 / m * sin_lo * cos_lo * cos_lo / r.min(r2);
                add(u[j], f, l, l2);
            }
            if side > 1 {
                let (l2, r2) = seen[i * side + (j + side - 1) % side];
                let f = cos_c * (cos_lo - cos_hi) / (PI * sin_c * r.min(r2));
                add(v[j], f, l, l2);
            }
        }
    }
    Gradient(g)
}

/// The tangent frame of a hemisphere, and the cosine-weighted direction in one of its strata.
struct Frame {
    t: DVec3,
    b: DVec3,
    /// The unit normal.
    n: DVec3,
}

impl Frame {
    fn of(n: DVec3) -> Frame {
        let (t, b) = n.any_orthonormal_pair();
        Frame { t, b, n }
    }

    /// A direction drawn uniformly (cosine-weighted on the hemisphere: Malley, uniform on the
    /// disc, lifted) in stratum k of the unit square's `side` × `side`: row k / side of the
    /// radial coordinate, column k % side of the angle.
    fn in_stratum(&self, k: usize, side: usize, rng: &mut Rng) -> DVec3 {
        let (i, j) = (k / side, k % side);
        let u = (i as f64 + rng.next_f64()) / side as f64;
        let v = (j as f64 + rng.next_f64()) / side as f64;
        malley(u, v, self.t, self.b, self.n)
    }

    /// The stratum of [`Frame::in_stratum`] that holds the direction `dir` (above the
    /// hemisphere's base): Malley's map inverted, the disc point's squared radius and angle.
    fn stratum_of(&self, dir: DVec3, side: usize) -> usize {
        let (a, b) = (self.t.dot(dir), self.b.dot(dir));
        let u = (a * a + b * b).min(1.0);
        let v = (b.atan2(a) / (2.0 * PI)).rem_euclid(1.0);
        let cell = |x: f64| ((x * side as f64) as usize).min(side - 1);
        cell(u) * side + cell(v)
    }
}

/// A stratum's first hemisphere ray: what it brought, the other strategies' count-density
/// in its direction ([`Mis`]) and its cosine to the normal.
struct First {
    brought: Rgb,
    light: f64,
    cos: f64,
}

/// The balance heuristic between a hemisphere's rays and its rays to the bright patches
/// ([`super::bright`]) and through the openings ([`super::openings`]). Each direction is
/// proposed by the hemisphere and at most one of the two (a direction either meets a patch or
/// leaves the scene), so one "light" density per ray: c_l = K × the density of one of that
/// strategy's rays there (0 where neither proposes it).
#[derive(Clone, Copy)]
struct Mis {
    /// The hemisphere's strata, S.
    strata: f64,
    /// Rays to the bright patches, K_b (0: none).
    bright: f64,
    /// Rays through the openings, K_o (0: none).
    open: f64,
}

impl Mis {
    /// The weight of a hemisphere ray in a stratum of `rays` rays, at cosine `cos` to the
    /// normal, whose direction the other strategies propose with count-density `light`:
    /// c_h / (c_h + c_l), c_h = rays · S · cos/π.
    fn hemisphere(self, light: f64, cos: f64, rays: usize) -> f64 {
        if light <= 0.0 {
            return 1.0;
        }
        let own = rays as f64 * self.strata * cos / PI;
        own / (own + light)
    }

    /// The weight of a bright or opening ray: c_l / (c_h + c_l), the complement of
    /// [`Mis::hemisphere`] in its direction.
    fn light(self, light: f64, cos: f64, rays: usize) -> f64 {
        let own = rays as f64 * self.strata * cos / PI;
        light / (own + light)
    }
}
