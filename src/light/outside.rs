//! What the lights outside the mesh (the sky, the sun, point and spot lights:
//! [`crate::scene::lights`]) bring to a point, with visibility. None is a surface of the
//! scene, so none has a patch: each adds its direct light to the emission vector of the
//! discrete rendering equation at every patch (or element, or output vertex), and the bounces
//! follow as for any light:
//!
//! E_i = Le_i + ρ_i · D_i,   D(x) = (1/π) ∫_Ω L_env(ω) V(x, ω) cosθ dω   (radiance units),
//!
//! the mean of D over the patch ([`patch_light`]). The matrix method ([`crate::pipeline`]), the
//! hierarchical solver's elements ([`crate::hierarchical`]) and the final gather
//! ([`crate::gather`]) call these estimates.
//!
//! - **Sky**: radiance L_sky from every direction above the horizon (ω · up > 0), none from
//!   below (the ground is the scene's own business). `uniform`: L = L_sky; `overcast`: the CIE
//!   standard overcast sky (Moon & Spencer 1942, CIE S 011/E:2003 type 1), L(α) = L_sky ·
//!   (1 + 2 sin α) / 3 at elevation α, so L_sky is the zenith's radiance. A plate with nothing
//!   around it facing a uniform sky at tilt θ from up receives E = π L_sky (1 + cos θ)/2 (the
//!   share of its cosine-weighted hemisphere above the horizon); facing up under the overcast
//!   sky, E = 7π/9 · L_sky.
//! - **Sun**: a distant disc of [`SUN_DIAMETER_DEGREES`] in the direction of its azimuth and
//!   elevation ([`Environment::sun_direction`]), bringing the irradiance E_sun on a surface
//!   facing it: E = E_sun cos θ on a surface at θ from the sun, times the visible share of the
//!   disc (soft shadow edges: rays to uniform points of the disc).
//! - **Point and spot lights** (glTF's `KHR_lights_punctual`): radiant intensity I from a
//!   point; E = I cos θ / r² (times a spot's falloff, glTF's) where nothing lies between, one
//!   shadow ray (hard shadows).
//!
//! Estimates at a point x (unit normal n), each ray starting `lift` above the surface:
//! - sun: [`SUN_RAYS`] shadow rays to stratified points of the disc; D = E_sun cos θ V̄ / π;
//! - uniform sky: cosine-weighted rays; of those above the horizon, the share that leaves the
//!   scene, times the exact unoccluded value L_sky (1 + n·up)/2: a ratio estimate, exact where
//!   nothing is in the way (the plate's closed form to rounding) and noisy only in visibility;
//! - overcast sky: the plain mean of L(ω) over the rays that leave the scene upward.

use std::f64::consts::PI;

use glam::DVec3;

use super::{LightTree, Receiver};
use crate::color::Rgb;
use crate::geometry::orthonormal_basis;
use crate::mesh::Patches;
use crate::sampling::{gauss_rule, malley, Rng};
use crate::scene::lights::{Environment, PointLight, SkyModel, Toward};
use crate::visibility::Visibility;

/// The sun's angular diameter seen from the earth, degrees.
pub const SUN_DIAMETER_DEGREES: f64 = 0.53;

/// Shadow rays to the sun's disc per point: its edge is a penumbra 0.53° wide, so a few rays
/// stratified over the disc give soft edges without bias.
pub const SUN_RAYS: usize = 4;

/// Shadow rays to the sun's disc at a shown point whose [`SUN_RAYS`] disagree
/// ([`Environment::sharp_direct_shown`]): the penumbra is a few centimetres wide indoors,
/// and a display vertex or a point-wise probe there took its light from four rays, a
/// quarter of the sun at a time (on the daylit office, gathered at a probe on a sun patch's
/// edge, 63 % off).
pub const SUN_PENUMBRA_RAYS: usize = 32;

/// Shadow rays of the pilot that decides whether a shown point lies in the sun's penumbra
/// ([`Environment::in_sun_penumbra`]): the disc's centre and eight points of a ring.
pub const SUN_PILOT: usize = 9;

/// The radius of the pilot's ring, as a fraction of the sun's disc
/// ([`Environment::in_sun_penumbra`]): near the rim, so that an edge near the rim is met, and
/// inside it, so that the ring's points are not the disc's very edge.
pub const SUN_PILOT_RING: f64 = 0.9;

/// The grid of the sun's `rays` ([`Environment::sun_direct`]): `(rings, sectors)` with
/// rings × sectors = `rays`, the rings as many as divide `rays` up to √(rays / 2) (1 × 4 for
/// 4 rays, 4 × 8 for 32, 1 × 1 for one), so that the cells are about as wide as they are deep.
pub fn sun_grid(rays: usize) -> (usize, usize) {
    let rays = rays.max(1);
    let most = ((rays as f64 / 2.0).sqrt() as usize).max(1);
    let rings = (1..=most)
        .rev()
        .find(|&r| rays.is_multiple_of(r))
        .unwrap_or(1);
    (rings, rays / rings)
}

/// Sky rays per point where a point's sky is estimated by rays (the elements of the
/// hierarchical solver and the patches of the matrix method use it at each of their 7 rule
/// points, so 112 rays a patch).
pub const SKY_RAYS: usize = 16;

/// Point lights computed exactly at a point when there are more than this and
/// [`SAMPLED_LIGHTS`] together: the ones that would bring the most ([`Environment::sharp_direct`]).
pub const EXACT_LIGHTS: usize = 16;

/// Shadow rays shared by the other point lights, drawn in proportion to what each would
/// bring ([`Environment::sharp_direct`]).
pub const SAMPLED_LIGHTS: usize = 16;

/// Directions drawn per sky ray at most, where most fall below the horizon: a surface tilted
/// 179.9° from up still gets its rays (the share above is (1 + cos θ)/2 ≈ 10⁻⁶ there: some are
/// then missing, and the estimate is the share of those cast).
pub const MAX_SKY_DRAWS: usize = 4096;

impl Environment {
    /// The direct light D(x) (radiance units: irradiance / π, before ρ) at the receiver `at`,
    /// from the sun ([`SUN_RAYS`] shadow rays), the point lights and the sky (`sky_rays` rays;
    /// 0 = no sky).
    pub fn direct(&self, at: &Receiver, sky_rays: usize, rng: &mut Rng) -> Rgb {
        let mut d = self.sharp_direct(at, rng);
        if sky_rays > 0 {
            let s = self.sky_direct(at, sky_rays, rng);
            for (d, s) in d.iter_mut().zip(s) {
                *d += s;
            }
        }
        d
    }

    /// The sun's and the point lights' part of [`Environment::direct`]. Point lights that
    /// can bring nothing to `x` (behind its surface, outside a spot's cone) are skipped; of
    /// the others, up to [`EXACT_LIGHTS`] + [`SAMPLED_LIGHTS`] get a shadow ray each. Beyond
    /// that (a level's thousand lamps), the [`EXACT_LIGHTS`] that would bring the most
    /// unoccluded light get one each, and the rest share [`SAMPLED_LIGHTS`] shadow rays drawn
    /// in proportion to what each would bring, each weighted by the inverse of its chance: an
    /// unbiased estimate of their sum whose noise is confined to the weakest lights (the
    /// many-light scheme of Shirley, Wang & Zimmerman 1996, "Monte Carlo techniques for direct
    /// lighting calculations", with the strongest lights split off as in Ward 1991, "Adaptive
    /// shadow testing for ray tracing").
    pub fn sharp_direct(&self, at: &Receiver, rng: &mut Rng) -> Rgb {
        self.sharp_direct_with(at, (EXACT_LIGHTS, SAMPLED_LIGHTS), SUN_RAYS, rng)
    }

    /// [`Environment::sharp_direct`] with one shadow ray for all the point lights together
    /// and one to the sun: unbiased, and noisy alone. For the many points of a gather that are
    /// averaged (a near hit's reflected light), where a level's hundred lamps would otherwise cost
    /// a hundred rays at every one. Up to [`EXACT_LIGHTS`] + [`SAMPLED_LIGHTS`] lights, the light
    /// is drawn in proportion to what it would bring unoccluded, all weighed; beyond that, by the
    /// light tree `tree` (built over this environment's lights), in O(log n) instead of weighing
    /// every lamp at every point.
    pub fn sharp_direct_sampled(&self, tree: &LightTree, at: &Receiver, rng: &mut Rng) -> Rgb {
        if self.lights.len() <= EXACT_LIGHTS + SAMPLED_LIGHTS {
            return self.sharp_direct_with(at, (0, 1), 1, rng);
        }
        debug_assert_eq!(tree.len(), self.lights.len(), "the tree of these lights");
        let mut d = self.sun_direct(at, 1, rng);
        let (x, n) = (at.origin(), at.n);
        if let Some((k, p)) = tree.sample(x, n, rng.next_f64(), |k| self.lights[k].potential(x, n))
        {
            let l = self.point_direct(&self.lights[k], at);
            for (d, l) in d.iter_mut().zip(l) {
                *d += l / p;
            }
        }
        d
    }

    /// [`Environment::sharp_direct`] with `exact` strongest lights and `sampled` shadow rays
    /// for the rest (all exactly when that many or fewer can bring light), and `sun_rays`
    /// rays to the sun.
    fn sharp_direct_with(
        &self,
        at: &Receiver,
        (exact, sampled): (usize, usize),
        sun_rays: usize,
        rng: &mut Rng,
    ) -> Rgb {
        let mut d = self.sun_direct(at, sun_rays, rng);
        let mut add = |p: Rgb, scale: f64| {
            for (d, p) in d.iter_mut().zip(p) {
                *d += p * scale;
            }
        };
        if self.lights.len() <= exact + sampled {
            // A ray each (one that can bring nothing returns 0 before casting).
            for l in &self.lights {
                add(self.point_direct(l, at), 1.0);
            }
            return d;
        }
        let origin = at.origin();
        let mut candidates: Vec<(f64, usize)> = self
            .lights
            .iter()
            .enumerate()
            .map(|(k, l)| (l.potential(origin, at.n), k))
            .filter(|&(w, _)| w > 0.0)
            .collect();
        if candidates.len() <= exact + sampled {
            for &(_, k) in &candidates {
                add(self.point_direct(&self.lights[k], at), 1.0);
            }
            return d;
        }
        // The strongest first (ties by index: the same choice on every run).
        if exact > 0 {
            candidates
                .select_nth_unstable_by(exact, |a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        }
        let (strong, weak) = candidates.split_at(exact);
        for &(_, k) in strong {
            add(self.point_direct(&self.lights[k], at), 1.0);
        }
        let mut cdf = Vec::with_capacity(weak.len());
        let mut total = 0.0;
        for &(w, _) in weak {
            total += w;
            cdf.push(total);
        }
        for _ in 0..sampled {
            let u = rng.next_f64() * total;
            let j = cdf.partition_point(|&c| c <= u).min(weak.len() - 1);
            let (w, k) = weak[j];
            let p = self.point_direct(&self.lights[k], at);
            add(p, total / (w * sampled as f64));
        }
        d
    }

    /// Shadow rays a point casts at most to the sun ([`SUN_RAYS`]) and the point lights
    /// ([`Environment::sharp_direct`]).
    pub fn sharp_rays(&self) -> usize {
        let sun = if self.sun.is_some() { SUN_RAYS } else { 0 };
        sun + self.lights.len().min(EXACT_LIGHTS + SAMPLED_LIGHTS)
    }

    /// One point light's part: I · falloff · cos θ / r² / π, times the share that passes
    /// what lies between (one shadow ray, [`Visibility::transmittance`]: a point casts hard
    /// shadows, a pane of transmittance t passes t of its light).
    pub fn point_direct(&self, light: &PointLight, at: &Receiver) -> Rgb {
        let origin = at.origin();
        let Some(Toward {
            to,
            r,
            r2,
            cos,
            falloff,
        }) = light.toward(origin, at.n)
        else {
            return [0.0; 3];
        };
        // The segment to the light, short of it by the lift (nothing stands on a point light).
        let pass = at
            .vis
            .transmittance(origin, to, 1.0 - at.lift / r, at.ignore);
        if pass == 0.0 {
            return [0.0; 3];
        }
        light
            .intensity
            .map(|i| i * falloff * cos * pass / (r2 * PI))
    }

    /// The sun's part of [`Environment::direct`]: E_sun cos θ V̄ / π, V̄ the mean share that
    /// passes ([`Visibility::transmittance`]: 0 or 1, or the product of the panes'
    /// transmittances on the way) over `rays` shadow rays to points of the disc stratified over its
    /// solid angle ([`SUN_RAYS`] at a point that is shown; one, unbiased and noisy alone, at a near
    /// hit's point, of which a gather averages many).
    pub fn sun_direct(&self, at: &Receiver, rays: usize, rng: &mut Rng) -> Rgb {
        self.sun_rays(at, rays, rng).0
    }

    /// [`Environment::sharp_direct`] at a point that is shown (a gathered vertex, a display
    /// test): [`SUN_PILOT`] pilot rays decide whether it lies in the sun's penumbra
    /// ([`Environment::in_sun_penumbra`]), and then
    /// [`SUN_PENUMBRA_RAYS`] fresh rays estimate the sun's light there, else [`SUN_RAYS`]
    /// fresh ones. The pilot's rays only choose the count and are not part of the estimate, so
    /// it stays unbiased (the scheme of [`crate::gather`]'s other lights).
    pub fn sharp_direct_shown(&self, at: &Receiver, rng: &mut Rng) -> Rgb {
        let sun_rays = if self.sun.is_some() && self.in_sun_penumbra(at, rng) {
            SUN_PENUMBRA_RAYS
        } else {
            SUN_RAYS
        };
        self.sharp_direct_with(at, (EXACT_LIGHTS, SAMPLED_LIGHTS), sun_rays, rng)
    }

    /// A cheap, deterministic estimate of [`Environment::sharp_direct`] at the receiver, to
    /// find shadows between shown points, not to value anything: the sun by one shadow ray to
    /// its disc's centre, and the point lights by one each where they are at most
    /// [`EXACT_LIGHTS`] (a level's hundreds of lamps are left out: a ray to each would cost
    /// more than the tests it orders). The rays from nearby points go the same way, so an
    /// occluder that hides the sun from a midpoint and not from its edge's ends (a chair
    /// leg's shadow between two lit vertices) shows as a departure from the ends' mean.
    pub fn coarse_sharp_direct(&self, at: &Receiver) -> Rgb {
        let (mut d, _) = self.sun_points(at, 1, |_| (0.0, 0.0));
        if self.coarse_counts_all() {
            // No light is drawn at random (no sampled rays): the generator is never read.
            let mut rng = Rng::new(&[0]);
            let lights = self.sharp_direct_with(at, (EXACT_LIGHTS, 0), 0, &mut rng);
            for (d, l) in d.iter_mut().zip(lights) {
                *d += l;
            }
        }
        d
    }

    /// Whether [`Environment::coarse_sharp_direct`] counts every light outside the mesh (the
    /// point lights are at most [`EXACT_LIGHTS`]).
    pub fn coarse_counts_all(&self) -> bool {
        self.lights.len() <= EXACT_LIGHTS
    }

    /// [`Environment::sun_direct`], and whether its rays disagreed.
    ///
    /// The rays go to points of the disc jittered in a grid of [`sun_grid`] cells of equal
    /// solid angle (rings of equal area in cos θ, each cut into equal sectors in φ): a shadow
    /// edge across the disc then leaves its noise to the few cells it crosses, a standard error
    /// falling as n^(−3/4) rather than the n^(−1/2) of rays independent in φ (jittered
    /// sampling; Mitchell 1996, "Consequences of stratified sampling in graphics"). Where the
    /// edge cuts the disc in half, 32 rays independent in φ within their rings left the sun's
    /// light at a point a standard error of 9 % of the whole sun; these leave a few per cent.
    fn sun_rays(&self, at: &Receiver, rays: usize, rng: &mut Rng) -> (Rgb, bool) {
        let (rings, sectors) = sun_grid(rays);
        self.sun_points(at, rays, |k| {
            let (ring, sector) = (k / sectors, k % sectors);
            let u = (ring as f64 + rng.next_f64()) / rings as f64;
            let v = (sector as f64 + rng.next_f64()) / sectors as f64;
            (u, v)
        })
    }

    /// Whether the receiver lies in the sun's penumbra, by [`SUN_PILOT`] shadow rays in a
    /// fixed pattern at a random rotation: the disc's centre and points on a ring at
    /// [`SUN_PILOT_RING`] of its radius, evenly spaced. A straight shadow edge that hides or
    /// shows more than 4.1 % of the disc (a segment beyond 0.83 of its radius, 0.9 cos 22.5°)
    /// leaves an arc of the ring wider than the points' spacing on its other side, so it
    /// separates the centre from some point of the ring: such a point is always found in the
    /// penumbra, where four random rays all on one side of the edge missed it often (at a
    /// share of 0.3, a quarter of the time).
    pub fn in_sun_penumbra(&self, at: &Receiver, rng: &mut Rng) -> bool {
        let turn = rng.next_f64();
        // u grows as the square of the angle from the disc's centre.
        let ring = SUN_PILOT_RING * SUN_PILOT_RING;
        self.sun_points(at, SUN_PILOT, |k| match k {
            0 => (0.0, 0.0),
            _ => (ring, turn + (k - 1) as f64 / (SUN_PILOT - 1) as f64),
        })
        .1
    }

    /// The sun's light at the receiver by `rays` shadow rays to the points `point(k)` of its
    /// disc, k in 0..rays, each (u, v) in [0, 1]² mapped to the disc uniformly in solid
    /// angle (cos θ = 1 − u (1 − cos α), α its angular radius; φ = 2π v), and whether the
    /// rays disagreed.
    fn sun_points(
        &self,
        at: &Receiver,
        rays: usize,
        mut point: impl FnMut(usize) -> (f64, f64),
    ) -> (Rgb, bool) {
        let (Some(sun), Some(s)) = (self.sun, self.sun_direction()) else {
            return ([0.0; 3], false);
        };
        let n = at.n;
        let cos = n.dot(s);
        if cos <= 0.0 {
            return ([0.0; 3], false);
        }
        let (t, b) = orthonormal_basis(s);
        let cos_max = (0.5 * SUN_DIAMETER_DEGREES).to_radians().cos();
        let origin = at.origin();
        let mut seen = 0.0;
        let (mut least, mut most) = (f64::INFINITY, f64::NEG_INFINITY);
        for k in 0..rays {
            let (u, v) = point(k);
            let c = 1.0 - u * (1.0 - cos_max);
            let phi = 2.0 * PI * v;
            let sin = (1.0 - c * c).max(0.0).sqrt();
            let dir = c * s + sin * (phi.cos() * t + phi.sin() * b);
            let pass = if dir.dot(n) > 0.0 {
                at.vis.transmittance(origin, dir, f64::INFINITY, at.ignore)
            } else {
                0.0
            };
            seen += pass;
            (least, most) = (least.min(pass), most.max(pass));
        }
        let v = seen / rays.max(1) as f64;
        (sun.irradiance.map(|e| e * cos * v / PI), least < most)
    }

    /// The sky's part of [`Environment::direct`], by `rays` rays above the horizon, drawn
    /// cosine-weighted (stratified in the radial coordinate) and kept if above the horizon:
    /// for a surface facing nearly down the sky is a sliver of its hemisphere, and rays
    /// spent below the horizon would leave its estimate to chance. At most
    /// [`MAX_SKY_DRAWS`] × `rays` directions are drawn (no ray is cast for a rejected one).
    pub fn sky_direct(&self, at: &Receiver, rays: usize, rng: &mut Rng) -> Rgb {
        let (n, up) = (at.n, self.up.axis());
        let unoccluded = 0.5 * (1.0 + n.dot(up));
        if rays == 0 || self.sky.iter().all(|&l| l <= 0.0) || unoccluded <= 0.0 {
            return [0.0; 3];
        }
        let (t, b) = orthonormal_basis(n);
        let origin = at.origin();
        // `open`: the rays' summed share that leaves the scene ([`Visibility::transmittance`]).
        let (mut cast, mut open, mut drawn) = (0usize, 0.0, 0usize);
        let mut sum = [0.0; 3];
        while cast < rays && drawn < MAX_SKY_DRAWS * rays {
            let s = ((drawn % rays) as f64 + rng.next_f64()) / rays as f64;
            drawn += 1;
            let dir = malley(s, rng.next_f64(), t, b, n);
            if dir.dot(up) <= 0.0 {
                continue;
            }
            cast += 1;
            let pass = at.vis.transmittance(origin, dir, f64::INFINITY, at.ignore);
            if pass == 0.0 {
                continue;
            }
            open += pass;
            for (s, l) in sum.iter_mut().zip(self.sky_radiance(dir)) {
                *s += pass * l;
            }
        }
        if cast == 0 {
            return [0.0; 3];
        }
        match self.sky_model {
            // Ratio estimate: the exact unoccluded value times the open share of the rays
            // above the horizon.
            SkyModel::Uniform => self.uniform_sky(n, open, cast),
            // D = (1/π) ∫ L cos dω over the sky = P(above) · E[L · open | above], with
            // P(above) = (1 + n·up)/2 for cosine-weighted directions.
            SkyModel::Overcast => sum.map(|s| s / cast as f64 * unoccluded),
        }
    }

    /// A uniform sky's D at a surface of unit normal `n` by the ratio estimate: its exact
    /// unoccluded value L_sky (1 + n·up)/2 times the share `open / above` of the rays above the
    /// horizon that left the scene (`open` counts each ray by the share of it that passed,
    /// 1 without panes on the way; 0 when no ray was above it). [`Environment::sky_direct`]
    /// and the final gather's hemisphere rays both estimate it so.
    pub fn uniform_sky(&self, n: DVec3, open: f64, above: usize) -> Rgb {
        if above == 0 {
            return [0.0; 3];
        }
        let unoccluded = 0.5 * (1.0 + n.dot(self.up.axis()));
        let share = open / above as f64;
        self.sky.map(|l| l * unoccluded * share)
    }

    /// Light that a ray leaving the scene in direction `dir` brings (the gather's hemisphere
    /// rays): the sky's radiance there. The sun's disc is the direct term's, not the rays'.
    pub fn escaped(&self, dir: DVec3) -> Rgb {
        self.sky_radiance(dir.normalize())
    }
}

/// D per patch (radiance units, before ρ): [`Environment::direct`] at the 7 points of each
/// patch's Gauss rule ([`gauss_rule`], degree 5), with [`SKY_RAYS`] sky rays each, averaged by
/// the rule's weights over the points that are not buried under contact geometry
/// ([`Visibility::buried`]: the floor under a block sees no sky, and its patch's visible part
/// should not be darkened by it). Rays are traced against every patch. Deterministic: each patch's
/// rays are keyed by (`seed`, patch). All zeros when the environment is dark.
pub fn patch_light(patches: &Patches, env: &Environment, seed: u64) -> Vec<Rgb> {
    use rayon::prelude::*;
    if !env.is_lit() {
        return vec![[0.0; 3]; patches.len()];
    }
    let corners: Vec<[DVec3; 3]> = (0..patches.len()).map(|i| patches.corners(i)).collect();
    let vis = Visibility::build(&corners).with_transmittance(&patches.transmittance());
    let (lo, hi) = crate::geometry::bounds(patches.positions.iter().copied());
    let lift = 1e-6 * (hi - lo).length();
    let rule = gauss_rule(7).expect("the 7-point rule exists");
    (0..patches.len())
        .into_par_iter()
        .map(|i| {
            let [a, b, c] = corners[i];
            let mut rng = Rng::new(&[seed, i as u64, 0xE5B1]);
            let (mut sum, mut weight) = ([0.0; 3], 0.0);
            for &(w, wt) in &rule {
                let x = w[0] * a + w[1] * b + w[2] * c;
                if vis.buried(x, patches.normal[i], i as u32) {
                    continue;
                }
                let n = patches.surface_normal(i, w);
                let at = Receiver {
                    vis: &vis,
                    x,
                    n,
                    ignore: i as u32,
                    lift,
                };
                let d = env.direct(&at, SKY_RAYS, &mut rng);
                for (s, d) in sum.iter_mut().zip(d) {
                    *s += wt * d;
                }
                weight += wt;
            }
            if weight > 0.0 {
                sum.map(|s| s / weight)
            } else {
                [0.0; 3]
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Spot, Sun, Up};

    /// The receiver at `x` (normal `n`) on triangle 0 of `vis`, its rays lifted by `lift`.
    fn at(vis: &Visibility, x: DVec3, n: DVec3, lift: f64) -> Receiver<'_> {
        Receiver {
            vis,
            x,
            n,
            ignore: 0,
            lift,
        }
    }

    /// A unit square at the origin with unit normal `n` (two triangles) as a visibility set.
    fn plate(n: DVec3) -> ([[DVec3; 3]; 2], Visibility) {
        let (t, b) = orthonormal_basis(n);
        let p = |u: f64, v: f64| (u - 0.5) * t + (v - 0.5) * b;
        let tris = [
            [p(0., 0.), p(1., 0.), p(1., 1.)],
            [p(0., 0.), p(1., 1.), p(0., 1.)],
        ];
        // Check the winding faces n.
        assert!(
            (tris[0][1] - tris[0][0])
                .cross(tris[0][2] - tris[0][0])
                .dot(n)
                > 0.0
        );
        let vis = Visibility::build(&tris);
        (tris, vis)
    }

    /// Triangle 0: half of a 10 × 10 floor at z = 0 (the origin on its edge); triangles 1 and 2:
    /// a square of half-side `half` centred at `centre`, across the unit `axis`: an occluder.
    fn floor_and_square(centre: DVec3, axis: DVec3, half: f64) -> Visibility {
        let (t, b) = orthonormal_basis(axis);
        let q = |u: f64, v: f64| centre + u * half * t + v * half * b;
        Visibility::build(&[
            [
                DVec3::new(-5., -5., 0.),
                DVec3::new(5., -5., 0.),
                DVec3::new(5., 5., 0.),
            ],
            [q(-1., -1.), q(1., -1.), q(1., 1.)],
            [q(-1., -1.), q(1., 1.), q(-1., 1.)],
        ])
    }

    #[test]
    fn a_lone_plate_under_a_uniform_sky_gets_the_closed_form() {
        // E = π L (1 + cos θ)/2 for a plate tilted θ from up, nothing around: exact (the ratio
        // estimate is exact where nothing is in the way), for every tilt and every up axis.
        for up in [Up::Y, Up::Z] {
            let env = Environment {
                sky: [1.0, 2.0, 0.5],
                up,
                ..Environment::default()
            };
            for degrees in [0.0, 30.0, 60.0, 89.0, 120.0, 179.0] {
                let theta = f64::to_radians(degrees);
                let n = theta.cos() * up.axis() + theta.sin() * up.forward();
                let (_, vis) = plate(n);
                let mut rng = Rng::new(&[3, degrees as u64]);
                let d = env.direct(&at(&vis, DVec3::ZERO, n, 1e-4), 64, &mut rng);
                for c in 0..3 {
                    let exact = env.sky[c] * (1.0 + theta.cos()) / 2.0;
                    assert!((d[c] - exact).abs() < 1e-12, "{up:?} {degrees}°: {d:?}");
                }
            }
        }
    }

    #[test]
    fn the_overcast_sky_on_a_horizontal_plate_is_seven_ninths() {
        // E = 7π/9 L_zenith: D = 7/9 L. Monte Carlo over cosine-weighted rays, stratified in
        // the radial coordinate: the mean of 400 seeds × 64 rays is within 4 standard errors.
        let env = Environment {
            sky: [1.0; 3],
            sky_model: SkyModel::Overcast,
            up: Up::Z,
            ..Environment::default()
        };
        let (_, vis) = plate(DVec3::Z);
        let values: Vec<f64> = (0..400)
            .map(|s| {
                let mut rng = Rng::new(&[s]);
                env.sky_direct(&at(&vis, DVec3::ZERO, DVec3::Z, 1e-4), 64, &mut rng)[0]
            })
            .collect();
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / 399.0;
        let se = (var / 400.0).sqrt();
        assert!((mean - 7.0 / 9.0).abs() < 4.0 * se + 1e-12, "{mean} ± {se}");
    }

    #[test]
    fn the_suns_grid_covers_its_rays_in_cells_about_square() {
        // rings × sectors = rays, with rings the largest divisor up to √(rays / 2).
        for (rays, grid) in [
            (0, (1, 1)),
            (1, (1, 1)),
            (4, (1, 4)),
            (7, (1, 7)),
            (32, (4, 8)),
        ] {
            assert_eq!(sun_grid(rays), grid, "{rays} rays");
        }
    }

    #[test]
    fn a_shadow_edge_across_the_sun_at_any_angle_is_found_and_estimated_closely() {
        // The sun at the zenith over a floor point; a roof 3 above it covers the half-plane
        // beyond a straight edge at angle `turn` whose direction from the point is δ off the
        // zenith, so the roof hides the segment of the disc (angular radius α) beyond δ: a
        // share (θ − sin θ cos θ)/π with cos θ = δ/α (plane geometry: the disc's radius is 0.27°,
        // where the sphere's curvature changes the share by about α² ≈ 2e-5).
        let env = Environment {
            sun: Some(Sun {
                azimuth_degrees: 0.0,
                elevation_degrees: 90.0,
                irradiance: [1.0; 3],
            }),
            up: Up::Z,
            ..Environment::default()
        };
        let alpha = (0.5 * SUN_DIAMETER_DEGREES).to_radians();
        for turn in [0.3f64, 1.1, 2.0, 4.0] {
            // Shares hidden from 5 % to a half: above the 4.1 % the pilot's pattern always
            // finds (its documentation), on both sides of the disc's centre.
            for hidden in [0.05, 0.3, 0.5] {
                let theta = solve_segment(hidden);
                let delta = alpha * theta.cos();
                let (m, w) = (
                    DVec3::new(turn.cos(), turn.sin(), 0.0),
                    DVec3::new(-turn.sin(), turn.cos(), 0.0),
                );
                let q = DVec3::new(0.0, 0.0, 3.0) + 3.0 * delta.tan() * m;
                let (a, b) = (q - 50.0 * w, q + 50.0 * w);
                let (c, d) = (b + 50.0 * m, a + 50.0 * m);
                let vis = Visibility::build(&[
                    [
                        DVec3::new(-5., -5., 0.),
                        DVec3::new(5., -5., 0.),
                        DVec3::new(5., 5., 0.),
                    ],
                    [a, c, b],
                    [a, d, c],
                ]);
                let at = at(&vis, DVec3::ZERO, DVec3::Z, 1e-6);
                let seeds = 400u64;
                let mut values = Vec::new();
                for seed in 0..seeds {
                    let mut rng = Rng::new(&[seed, 0x5F, (10.0 * turn) as u64]);
                    // The pilot's fixed pattern finds the penumbra at every seed.
                    assert!(
                        env.in_sun_penumbra(&at, &mut rng),
                        "turn {turn}, hidden {hidden}, seed {seed}: not found"
                    );
                    values.push(env.sharp_direct_shown(&at, &mut rng)[0] * PI);
                }
                let m = seeds as f64;
                let mean = values.iter().sum::<f64>() / m;
                let sd =
                    (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (m - 1.0)).sqrt();
                let exact = 1.0 - hidden;
                assert!(
                    (mean - exact).abs() < 4.0 * sd / m.sqrt() + 1e-4,
                    "turn {turn}, hidden {hidden}: {mean} ± {sd} against {exact}"
                );
                // A point's 32 jittered rays: the edge crosses at most 2 sectors of each of the
                // 4 rings, 8 of the 32 cells, each a Bernoulli trial of variance at most ¼, so
                // a standard error of at most √(8 · ¼)/32 = 4.4 % of the sun, where 32 rays
                // independent in φ within their rings leave √(s(1 − s)/32), 8.8 % at a half.
                assert!(sd < 0.055, "turn {turn}, hidden {hidden}: spread {sd}");
            }
        }
    }

    /// θ in [0, π/2] with (θ − sin θ cos θ)/π = `share` (a circle's segment beyond the chord
    /// at distance cos θ from its centre, as a share of the circle), by bisection.
    fn solve_segment(share: f64) -> f64 {
        let (mut lo, mut hi) = (0.0, PI / 2.0);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if (mid - mid.sin() * mid.cos()) / PI < share {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    #[test]
    fn the_sun_gives_e_cos_theta_and_an_occluder_blocks_it() {
        // The sun at 40° elevation, azimuth 90° (east = north × up): a horizontal plate gets
        // E_sun sin 40°; a plate facing the sun gets E_sun; one facing away gets nothing.
        let env = Environment {
            sun: Some(Sun {
                azimuth_degrees: 90.0,
                elevation_degrees: 40.0,
                irradiance: [1000.0, 900.0, 800.0],
            }),
            up: Up::Z,
            ..Environment::default()
        };
        let s = env.sun_direction().unwrap();
        let east = Up::Z.forward().cross(DVec3::Z);
        assert!(s.dot(east) > 0.7 && (s.z - 40f64.to_radians().sin()).abs() < 1e-12);
        let mut rng = Rng::new(&[1]);
        let (_, vis) = plate(DVec3::Z);
        let d = env.direct(&at(&vis, DVec3::ZERO, DVec3::Z, 1e-4), 0, &mut rng);
        let expected = 1000.0 * 40f64.to_radians().sin() / PI;
        assert!((d[0] - expected).abs() < 1e-9 * expected, "{d:?}");
        let (_, vis) = plate(s);
        let d = env.direct(&at(&vis, DVec3::ZERO, s, 1e-4), 0, &mut rng);
        assert!((d[1] - 900.0 / PI).abs() < 1e-9, "{d:?}");
        let (_, vis) = plate(-s);
        assert_eq!(
            env.direct(&at(&vis, DVec3::ZERO, -s, 1e-4), 0, &mut rng),
            [0.0; 3]
        );
        // An occluder between the point and the sun: a large square 1 unit toward the sun,
        // facing it: shadow, while a point beside the shadow stays lit.
        let vis = floor_and_square(s, s, 0.3);
        assert_eq!(
            env.direct(&at(&vis, DVec3::ZERO, DVec3::Z, 1e-4), 0, &mut rng),
            [0.0; 3]
        );
        let beside = DVec3::new(-3.0, 3.0, 0.0);
        let d = env.direct(&at(&vis, beside, DVec3::Z, 1e-4), 0, &mut rng);
        assert!((d[0] - expected).abs() < 1e-9 * expected, "{d:?}");
    }

    #[test]
    fn a_point_light_is_blocked_by_what_lies_between() {
        // A light 2 above the origin; a square at height 1 between them shadows the origin
        // and nothing beside it; the light's own position is never "behind" anything.
        let env = Environment {
            lights: vec![PointLight {
                position: DVec3::new(0.0, 0.0, 2.0),
                intensity: [4.0; 3],
                spot: None,
            }],
            up: Up::Z,
            ..Environment::default()
        };
        let vis = floor_and_square(DVec3::new(0.0, 0.0, 1.0), DVec3::Z, 0.2);
        let l = &env.lights[0];
        assert_eq!(
            env.point_direct(l, &at(&vis, DVec3::ZERO, DVec3::Z, 1e-6)),
            [0.0; 3]
        );
        let x = DVec3::new(2.0, 0.0, 0.0);
        let d = env.point_direct(l, &at(&vis, x, DVec3::Z, 1e-6));
        // E = I cos θ / r² with r² = 8, cos θ = 2/√8.
        let exact = 4.0 * (2.0 / 8f64.sqrt()) / 8.0 / PI;
        assert!((d[0] - exact).abs() < 1e-5 * exact, "{d:?}");
        // Facing away: nothing.
        assert_eq!(env.point_direct(l, &at(&vis, x, -DVec3::Z, 1e-6)), [0.0; 3]);
    }

    #[test]
    fn one_sampled_light_is_unbiased_for_all_of_them() {
        // Four coloured lights: one hidden from the origin by the square, one behind the
        // floor (sends nothing), a spot, and one far off. The mean of the one-ray estimate
        // over many draws must be the exact sum of their parts.
        let light = |p: [f64; 3], i: Rgb, spot: Option<Spot>| PointLight {
            position: DVec3::from_array(p),
            intensity: i,
            spot,
        };
        let env = Environment {
            lights: vec![
                light([0.0, 0.0, 2.0], [4.0, 1.0, 1.0], None),
                light([1.0, 1.0, -1.0], [9.0; 3], None),
                light(
                    [2.0, 0.0, 1.0],
                    [1.0, 3.0, 1.0],
                    Some(Spot {
                        direction: DVec3::new(-1.0, 0.0, -1.0).normalize(),
                        inner_degrees: 10.0,
                        outer_degrees: 60.0,
                    }),
                ),
                light([-4.0, 3.0, 6.0], [2.0, 2.0, 8.0], None),
            ],
            up: Up::Z,
            ..Environment::default()
        };
        let vis = floor_and_square(DVec3::new(0.0, 0.0, 1.0), DVec3::Z, 0.2);
        let mut rng = Rng::new(&[5]);
        for x in [DVec3::ZERO, DVec3::new(0.5, -0.3, 0.0)] {
            let exact = env.sharp_direct(&at(&vis, x, DVec3::Z, 1e-6), &mut rng);
            let tree = LightTree::new(&env.lights);
            assert_unbiased(exact, 40_000, || {
                env.sharp_direct_sampled(&tree, &at(&vis, x, DVec3::Z, 1e-6), &mut rng)
            });
        }
    }

    /// Asserts that the mean of `draws` values of `estimate` is within 4 standard errors of
    /// `exact` (every channel positive: not trivially); returns one estimate's standard
    /// deviation per channel.
    fn assert_unbiased(exact: Rgb, draws: usize, mut estimate: impl FnMut() -> Rgb) -> Rgb {
        let (mut sum, mut sum2) = ([0.0; 3], [0.0; 3]);
        for _ in 0..draws {
            let d = estimate();
            for c in 0..3 {
                sum[c] += d[c];
                sum2[c] += d[c] * d[c];
            }
        }
        std::array::from_fn(|c| {
            let n = draws as f64;
            let mean = sum[c] / n;
            let sd = (sum2[c] / n - mean * mean).max(0.0).sqrt();
            assert!(exact[c] > 0.0);
            assert!(
                (mean - exact[c]).abs() <= 4.0 * sd / n.sqrt() + 1e-12,
                "channel {c}: {mean} vs {} (sd {sd})",
                exact[c]
            );
            sd
        })
    }

    #[test]
    fn many_lights_the_strongest_exact_the_rest_sampled_without_bias() {
        // 60 lights over the floor (more than EXACT_LIGHTS + SAMPLED_LIGHTS): some hidden
        // from the origin by the square, some below the floor, some spots. The exact sum of
        // their parts, one shadow ray each, against the mean of the hybrid estimate.
        let lights = crate::light::scattered_lights(60);
        let env = Environment {
            lights,
            up: Up::Z,
            ..Environment::default()
        };
        let vis = floor_and_square(DVec3::new(0.0, 0.0, 0.3), DVec3::Z, 0.25);
        let mut rng = Rng::new(&[9]);
        for x in [DVec3::ZERO, DVec3::new(0.8, -0.4, 0.0)] {
            let lit = env.lights.iter().filter(|l| l.potential(x, DVec3::Z) > 0.0);
            assert!(
                lit.count() > EXACT_LIGHTS + SAMPLED_LIGHTS,
                "the sampled path is taken"
            );
            let mut exact = [0.0; 3];
            for l in &env.lights {
                let p = env.point_direct(l, &at(&vis, x, DVec3::Z, 1e-6));
                exact = std::array::from_fn(|c| exact[c] + p[c]);
            }
            // The strongest lights exact, so one estimate's spread is a small part of the whole.
            let sd = assert_unbiased(exact, 4000, || {
                env.sharp_direct(&at(&vis, x, DVec3::Z, 1e-6), &mut rng)
            });
            for c in 0..3 {
                assert!(sd[c] < 0.5 * exact[c], "{sd:?} {exact:?}");
            }
            // One light drawn by the light tree: unbiased too.
            let tree = LightTree::new(&env.lights);
            assert_unbiased(exact, 40_000, || {
                env.sharp_direct_sampled(&tree, &at(&vis, x, DVec3::Z, 1e-6), &mut rng)
            });
        }
    }
}
