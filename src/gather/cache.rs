//! The `cache` gather: the indirect light gathered at some output vertices (the records) and
//! interpolated at the others, so that a gather of 10⁵–10⁶ vertices costs a bounded number of
//! hemispheres while every vertex keeps its own exact direct light. Irradiance caching (Ward,
//! Rubinstein & Clear, "A ray tracing solution for diffuse interreflection", SIGGRAPH 1988):
//!
//! - A record at x_i keeps I_i = ∫_Ω (L − Le)(h(x_i, ω)) cosθ/π dω (the solution's reflected
//!   light, and the sky, arriving there: every emitter's Le is left to the points' direct
//!   terms, `Count::All`) and R_i, the harmonic mean distance of its probe rays' hits (those
//!   that leave the scene left out), clamped to [[`MIN_RADIUS`], [`MAX_RADIUS`]] × the
//!   scene's extent.
//! - Ward's error estimate of using record i at x (normal n) is
//!   ε_i(x) = |x − x_i| / R_i + √(1 − n·n_i): the indirect light changes on the scale of the
//!   distance to the surfaces that shape it, and with the normal. A record serves x where
//!   ε_i < a ([`ACCURACY`]) and x is not behind it; the value at x is the weighted mean of the
//!   records that serve it, with weights 1/ε_i − 1/a (Ward's 1/ε, brought to 0 at the edge of
//!   the record's reach so that the interpolant is continuous), each record's value carried
//!   to x by its gradient: I_i + (x − x_i)·∇I_i.
//! - A record's gradient ∇I_i comes from its own rays, no ray more (Ward & Heckbert,
//!   "Irradiance gradients", 1992: how the light crossing each boundary between its strata
//!   changes as the point moves; `indirect::Gradient`), limited so that it changes the light
//!   by at most a quarter within the record's reach ([`GRADIENT_LIMIT`]). Without it, light
//!   that falls off along a wall or away from a window shows as steps between records, each
//!   flat around its own; with it, the interpolation follows such a slope (the point-wise
//!   benchmark's offices: BENCHMARKS.md "A daylit office").
//! - Records are placed coarse to fine, the same for any thread count: at each level, among
//!   the vertices no record serves, the lowest-numbered one in each cell of a grid (and each of
//!   six normal directions) becomes a record; the cells halve from the largest reach to the
//!   smallest, then every vertex still unserved becomes one. Where surfaces are near (under a
//!   desk, along a wall's foot, between chair legs) R_i is small and the records dense; on an
//!   open wall they are metres apart.
//! - After each level, a record's R_i is clamped to R_j + |x_i − x_j| by every record j within
//!   its reach (neighbour clamping, `clamp_radii`), and the vertices it no longer serves
//!   are placed again: a few probe rays miss a chair's leg a hand's width away, and a record
//!   whose reach spanned it showed the open floor's light under the desk (the generated
//!   office of 10⁵ triangles: 58,669 records → 65,461, displayed RMS 3.66, 3.58, 3.99 →
//!   3.52, 3.39, 3.89 % over seeds 1–3; BENCHMARKS.md "Large outputs: the `cache` gather").
//! - A record's hemisphere rays are shared out of a budget ∝ √(the area it shows), the
//!   budget grown where the records bring most of the light shown ([`budget_factor`]: a
//!   room lit by the sky, where the direct term is the sun's alone).
//!
//! A vertex shows Le + ρ·(D + E + I): D its exact direct term, E the Le of the emitters its
//! direct term leaves to hemisphere rays (large and near: [`super::SAMPLED_SPREAD`]), by a few
//! rays of its own that read only emission (`Gatherer::uncounted_emission`; none where there
//! is no such emitter, as in most rooms lit by lamps), and I the records' interpolated value.
//! (Counting those emitters in D instead, by their visible pieces or shadow rays, was tried: in
//! the furnace it shows a bias of +0.2 % where the boxes hide parts of the walls.)

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;
use rustc_hash::FxBuildHasher;
use serde::Serialize;

use super::bright::bright_rays;
use super::indirect::{Count, Gradient};
use super::sites::Spot;
use super::{Gathered, Gatherer, NEAR_DEPTH};
use crate::color::{luminance, Rgb};
use crate::light::emitter::CACHE_MAX_SHADOW_RAYS;
use crate::sampling::Rng;

/// Ward's a: a record serves a point while its error estimate ε = d/R + √(1 − n·nᵢ) stays under
/// this. Ward suggests 0.1–0.3 for a picture; the smaller, the more records (∝ a⁻² on open
/// surfaces; fewer where the records are already at most vertices). The records' rays are a
/// fixed budget ([`RAY_BUDGET`]), so a smaller a trades rays per record for records: against
/// the point-wise probes with the `cache` gather, 0.1 displays less error than 0.2 on every
/// scene tried (most where the indirect light bends on a small scale, as among a plant's
/// leaves) for at most a third more gather time, and 0.05 spreads the rays too thin
/// (BENCHMARKS.md "Large outputs: the `cache` gather").
pub const ACCURACY: f64 = 0.1;

/// The most a record's gradient may change its light within its reach, as a share of it
/// (`Gradient::limited`). Ward's records serve points within a = 0.1 of R, the distance
/// on which their light changes ([`ACCURACY`]), so the light changes by about a
/// tenth there; a gradient that claims more than 2.5 times that is mostly the noise of a few
/// rays that met a bright surface near by (the daylit office, second probe set, seed 2:
/// limited to the whole light 6.22 % RMS, to half of it 6.11 %, to a quarter 5.51 %, with no
/// gradient 5.98 %; the lamp-lit office 3.04, 2.99, 3.02 against 3.11 %; BENCHMARKS.md
/// "A daylit office").
pub const GRADIENT_LIMIT: f64 = 0.25;

/// Hemisphere rays of all the records when their number per record is not given, shared out
/// ∝ √(the area each record shows), at least [`MIN_RECORD_RAYS`] and at most
/// [`MAX_RECORD_RAYS`] each: twice the `full` gather's ([`super::AUTO_RAY_BUDGET`]), times
/// [`budget_factor`] where the records bring more of the light shown than on the office it
/// was measured on, under its lamps (as in a room lit by the sky and the sun alone). The
/// records' noise is most of the seed-to-seed part of the displayed error on a furnished
/// scene, and twice the rays took the office's displayed RMS from 4.85, 4.85, 5.11 % to 4.66,
/// 4.55, 4.68 % over three seeds for 1.06× the bake, more than 1.06× the time buys a path
/// tracer (its error ∝ time^−½); four times: 4.47 % (BENCHMARKS.md "Large outputs: the
/// `cache` gather").
pub const RAY_BUDGET: usize = 2 * super::AUTO_RAY_BUDGET;

/// The fewest hemisphere rays of a record (a chair leg's vertex, which shows little area).
pub const MIN_RECORD_RAYS: usize = 9;

/// The most hemisphere rays of a record (an open wall's, shown over square metres).
pub const MAX_RECORD_RAYS: usize = 1024;

/// Rays that measure a candidate record's R before it is placed (unshaded: hit distances
/// only).
pub const PROBE_RAYS: usize = 16;

/// Rays at each vertex for the Le of the emitters its direct term leaves to rays
/// (`Gatherer::uncounted_emission`; none are cast where there is none). Unshaded (the
/// first hit's emission only), so cheap next to the direct term; the stratified estimate of a
/// large wall's share errs as rays^-0.75 (its outline's strata), so 256 rays bring the
/// furnace's per-vertex noise under 2e-3 where 64 left 5e-3.
pub const EMISSION_RAYS: usize = 256;

/// R is clamped to at least this fraction of the scene's extent: in a corner it tends to 0, and
/// records would crowd without end.
pub const MIN_RADIUS: f64 = 5e-4;

/// R is clamped to at most this fraction of the scene's extent: a point far from every surface
/// (or under an open sky, whose rays count as infinitely far) still gets records at most
/// a twentieth of the scene apart (a · this).
pub const MAX_RADIUS: f64 = 0.25;

/// A record at xᵢ does not serve a point x in front of it by more than this share of their
/// distance ((x − xᵢ)·(n + nᵢ)/2 < −FRONT·|x − xᵢ|: Ward's test against a record on the far
/// side of a step, seeing a different light).
const FRONT: f64 = 0.1;

/// What the cache did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct CacheStats {
    /// Records gathered (their rays shared out of [`RAY_BUDGET`] unless given).
    pub records: usize,
    /// Vertices interpolated from the records.
    pub interpolated: usize,
    /// Placement levels run.
    pub levels: usize,
    /// Hemisphere rays of all the records (before the rays beside edges).
    pub record_rays: usize,
}

/// One record: where, its normal and R (scene units).
#[derive(Debug, Clone, Copy)]
pub(super) struct Record {
    x: DVec3,
    n: DVec3,
    r: f64,
}

impl Record {
    /// Ward's weight of this record at (x, n), 1/ε − 1/a, or `None` where it does not serve.
    fn weight(&self, x: DVec3, n: DVec3) -> Option<f64> {
        let d = x - self.x;
        let dist = d.length();
        let cos = n.dot(self.n);
        let e = dist / self.r + (1.0 - cos).max(0.0).sqrt();
        if e >= ACCURACY || d.dot(n + self.n) * 0.5 < -FRONT * dist {
            return None;
        }
        Some(1.0 / e.max(1e-12) - 1.0 / ACCURACY)
    }

    /// How far from xᵢ it can serve (ε < a with equal normals).
    fn reach(&self) -> f64 {
        ACCURACY * self.r
    }
}

/// The records with their values, for the display refinement's new vertices and tests
/// (`Cache::at`), and what placing them did.
pub struct Cache {
    records: Vec<Record>,
    /// Each record's reflected light (radiance units, before the receiver's ρ).
    values: Vec<Rgb>,
    /// The gradient of each record's light ([`Gradient`], limited within its reach).
    gradients: Vec<Gradient>,
    index: Index,
    pub stats: CacheStats,
}

impl Cache {
    /// The records' reflected light interpolated at (x, n), each carried to x by its gradient,
    /// or `None` where no record serves.
    pub(super) fn at(&self, x: DVec3, n: DVec3) -> Option<Rgb> {
        let (mut sum, mut total) = ([0.0; 3], 0.0);
        serving(&self.index, &self.records, x, n, |k, w| {
            total += w;
            for (a, b) in sum.iter_mut().zip(self.carried(k as usize, x)) {
                *a += w * b;
            }
        });
        (total > 0.0).then(|| sum.map(|a| a / total))
    }

    /// Record k's reflected light carried to x by its gradient (radiance units).
    fn carried(&self, k: usize, x: DVec3) -> Rgb {
        self.gradients[k].carry(self.values[k], x - self.records[k].x)
    }
}

/// Calls `f` with each record of `records` (indexed by `index`) that serves (x, n), and its
/// Ward weight ([`Record::weight`]).
fn serving(index: &Index, records: &[Record], x: DVec3, n: DVec3, mut f: impl FnMut(u32, f64)) {
    index.near(x, |k| {
        if let Some(w) = records[k as usize].weight(x, n) {
            f(k, w);
        }
    });
}

/// Neighbour clamping of the records' R (Křivánek, Bouatouch, Pattanaik & Žára, "Making
/// radiance and irradiance caching practical: adaptive caching and neighbor clamping", EGSR
/// 2006):
/// R_i ≤ R_j + |x_i − x_j| for every record j that stands within i's reach and not behind it.
/// R_j measures the distance to the surfaces around x_j, so those around x_i are no farther
/// than that plus the way between; a record j on another surface (a chair's pedestal, a
/// desk's leg) bounds R_i by little more than its distance. The few probe rays that measure
/// R at a record alone miss a leg a hand's width away, and a record whose reach spans it
/// shows the open floor's light under the desk. Jacobi on the radii as they are (the same
/// for any thread count). Returns whether some R shrank.
fn clamp_radii(index: &Index, records: &mut [Record]) -> bool {
    // Each record's least bound so far, as the bits of a non-negative f64 (ordered as the
    // numbers are): a minimum is the same in any order, and one word a record, where the list
    // of every (record, bound) pair found ran to gigabytes on a hall of 10⁶ triangles (a
    // coarse level's reach holds thousands of records).
    let least: Vec<AtomicU64> = records
        .iter()
        .map(|r| {
            debug_assert!(r.r.is_sign_positive(), "a record's radius is >= 0");
            AtomicU64::new(r.r.to_bits())
        })
        .collect();
    let shrank = AtomicBool::new(false);
    records.par_iter().enumerate().for_each(|(j, rj)| {
        index.near(rj.x, |i| {
            let ri = &records[i as usize];
            let d = rj.x - ri.x;
            let dist = d.length();
            let bound = rj.r + dist;
            if i as usize != j && dist < ri.reach() && d.dot(ri.n) >= -FRONT * dist && bound < ri.r
            {
                least[i as usize].fetch_min(bound.to_bits(), Ordering::Relaxed);
                shrank.store(true, Ordering::Relaxed);
            }
        });
    });
    for (record, least) in records.iter_mut().zip(least) {
        record.r = f64::from_bits(least.into_inner());
    }
    shrank.into_inner()
}

/// Spheres by centre (the records by their reach, the emitters by the reach within which they
/// are not sampled): a hash grid per level of cell size `top / 2^level`, each sphere in the
/// cell of its centre at the finest level whose cells are at least its radius, so every
/// sphere that contains a point lies in one of the 27 cells around it at the sphere's level.
pub(super) struct Index {
    top: f64,
    /// Cell → the spheres in it, one map per level. Hashed by FxHash: the keys are small
    /// integers, and SipHash would cost more than the 27 lookups a point makes per level.
    levels: Vec<HashMap<[i64; 3], Vec<u32>, FxBuildHasher>>,
}

impl Index {
    pub(super) fn new(top: f64, finest: f64) -> Index {
        let count = ((top / finest).log2().ceil().max(0.0) as usize) + 1;
        Index {
            top,
            levels: (0..count).map(|_| HashMap::default()).collect(),
        }
    }

    fn cell(&self, level: usize, x: DVec3) -> [i64; 3] {
        let size = self.top / (1u64 << level) as f64;
        (x / size).floor().as_i64vec3().to_array()
    }

    /// Adds sphere `k`: centre `x`, radius `reach` (at most `top`; smaller than the finest
    /// cell counts as the finest).
    pub(super) fn insert(&mut self, k: u32, x: DVec3, reach: f64) {
        debug_assert!(reach <= self.top * (1.0 + 1e-9));
        let level =
            ((self.top / reach).log2().floor().max(0.0) as usize).min(self.levels.len() - 1);
        let cell = self.cell(level, x);
        self.levels[level].entry(cell).or_default().push(k);
    }

    /// Calls `f` with every sphere that may contain `x` (and some that do not).
    pub(super) fn near(&self, x: DVec3, mut f: impl FnMut(u32)) {
        for (level, grid) in self.levels.iter().enumerate() {
            if grid.is_empty() {
                continue;
            }
            let [i, j, k] = self.cell(level, x);
            for di in -1..=1 {
                for dj in -1..=1 {
                    for dk in -1..=1 {
                        if let Some(list) = grid.get(&[i + di, j + dj, k + dk]) {
                            list.iter().for_each(|&r| f(r));
                        }
                    }
                }
            }
        }
    }
}

/// The six normal directions a cell keeps apart (the axis of n's largest component, and its
/// sign): a desk's top and its underside, a wall's two faces, each get their own records.
fn normal_bucket(n: DVec3) -> u8 {
    let a = n.abs();
    let axis = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    2 * axis as u8 + u8::from(n[axis] < 0.0)
}

impl Gatherer<'_> {
    /// Ward's R at `spot` (output vertex `v`), without shading: the harmonic mean distance of
    /// [`PROBE_RAYS`] stratified cosine-weighted rays' hits, clamped to
    /// [[`MIN_RADIUS`], [`MAX_RADIUS`]] × the scene's extent.
    fn probe_radius(&self, spot: &Spot, v: usize) -> f64 {
        let mut rng = Rng::new(&[self.seed(), v as u64, 0x9A_D105]);
        let extent = self.extent();
        self.harmonic_distance(spot, PROBE_RAYS, &mut rng)
            .clamp(MIN_RADIUS * extent, MAX_RADIUS * extent)
    }

    /// What a `cache` gather shows at `spot`, whose reflected light arriving is `reflected`
    /// (radiance units, before ρ: from the records): Le + ρ·(D + E + reflected) (see the
    /// module documentation).
    pub(super) fn cached_vertex(&self, spot: &Spot, reflected: Rgb, rng: &mut Rng) -> Gathered {
        let direct = self.reflected_direct(spot, CACHE_MAX_SHADOW_RAYS, rng);
        self.cached_vertex_lit(spot, reflected, direct, rng)
    }

    /// [`Gatherer::cached_vertex`] with its reflected direct light `direct` already computed
    /// at `spot` by [`Gatherer::reflected_direct`] (by the display refinement's test at the
    /// midpoint that then becomes the vertex, with that test's shadow rays).
    pub(super) fn cached_vertex_lit(
        &self,
        spot: &Spot,
        reflected: Rgb,
        (direct, penumbra, exact): (Rgb, bool, Vec<u32>),
        rng: &mut Rng,
    ) -> Gathered {
        let indirect = self.cached_reflected(spot, reflected, &exact, EMISSION_RAYS, rng);
        self.with_emission(spot.patch as usize, (direct, penumbra, &exact), indirect)
    }

    /// The indirect part of [`Gatherer::cached_vertex`] at `spot`, whose direct term computes
    /// the emitters `exact` exactly: ρ·(reflected + the Le its hemisphere brings from the
    /// emitters that term leaves out, by `rays` rays). For a caller that has the direct term
    /// already (a display-refinement test), so that the point's direct light, the costly part,
    /// is not computed twice.
    pub(super) fn cached_reflected(
        &self,
        spot: &Spot,
        reflected: Rgb,
        exact: &[u32],
        rays: usize,
        rng: &mut Rng,
    ) -> Rgb {
        let emitted = self.uncounted_emission(spot, exact, rays, rng);
        let rho = self.patches.reflectance[spot.patch as usize];
        std::array::from_fn(|c| rho[c] * (reflected[c] + emitted[c]))
    }

    /// The reflected light arriving at each gathered point (`spots[v]`, `None` where buried;
    /// `areas[v]` the area its vertex shows, scene units²): records where needed, interpolated
    /// elsewhere (see the module documentation), their rays `rays` each if given, else shared
    /// out of [`RAY_BUDGET`]. Radiance units, before the receiver's ρ; `None` where buried.
    pub(super) fn cached_indirect(
        &self,
        spots: &[Option<Spot>],
        areas: &[f64],
        shares: &[f64],
        rays: Option<usize>,
    ) -> (Vec<Option<Rgb>>, Cache) {
        let extent = self.extent();
        let (top, finest) = (
            ACCURACY * MAX_RADIUS * extent,
            ACCURACY * MIN_RADIUS * extent,
        );
        let mut index = Index::new(top, finest);
        // The records, and the vertex each stands at.
        let mut records: Vec<Record> = Vec::new();
        let mut record_vertex: Vec<usize> = Vec::new();
        let mut own: Vec<Option<u32>> = vec![None; spots.len()];
        let mut unserved: Vec<usize> = (0..spots.len()).filter(|&v| spots[v].is_some()).collect();
        let mut stats = CacheStats::default();
        let spot = |v: usize| {
            spots[v]
                .as_ref()
                .expect("only gathered vertices are placed")
        };
        let levels = index.levels.len();
        for level in 0..=levels {
            if unserved.is_empty() {
                break;
            }
            stats.levels += 1;
            // The lowest-numbered unserved vertex of each cell and normal direction; at the
            // last level, every unserved vertex.
            let chosen: Vec<usize> = if level == levels {
                unserved.clone()
            } else {
                let size = top / (1u64 << level) as f64;
                let mut first: HashMap<([i64; 3], u8), usize, FxBuildHasher> = HashMap::default();
                for &v in &unserved {
                    let s = spot(v);
                    let cell = (s.x / size).floor().as_i64vec3().to_array();
                    first.entry((cell, normal_bucket(s.n))).or_insert(v);
                }
                let mut chosen: Vec<usize> = first.into_values().collect();
                chosen.sort_unstable();
                chosen
            };
            let radii: Vec<f64> = chosen
                .par_iter()
                .map(|&v| self.probe_radius(spot(v), v))
                .collect();
            for (&v, r) in chosen.iter().zip(radii) {
                let k = records.len() as u32;
                let s = spot(v);
                let record = Record { x: s.x, n: s.n, r };
                index.insert(k, record.x, record.reach());
                records.push(record);
                record_vertex.push(v);
                own[v] = Some(k);
            }
            // Neighbour clamping: a record's reach shrinks where another record within it
            // stands by nearer surfaces; the vertices it no longer serves are placed again
            // (not after the last level, which has made every vertex left a record).
            if level < levels && clamp_radii(&index, &mut records) {
                unserved = (0..spots.len()).filter(|&v| spots[v].is_some()).collect();
            }
            unserved = unserved
                .into_par_iter()
                .filter(|&v| {
                    let s = spot(v);
                    let mut served = own[v].is_some();
                    serving(&index, &records, s.x, s.n, |_, _| served = true);
                    !served
                })
                .collect();
        }
        stats.records = records.len();
        // Each vertex's records and normalised weights (its own record alone if it is one).
        let weights: Vec<Vec<(u32, f64)>> = spots
            .par_iter()
            .enumerate()
            .map(|(v, s)| {
                let Some(s) = s else { return Vec::new() };
                if let Some(k) = own[v] {
                    return vec![(k, 1.0)];
                }
                let mut list = Vec::new();
                serving(&index, &records, s.x, s.n, |k, w| list.push((k, w)));
                let total: f64 = list.iter().map(|&(_, w)| w).sum();
                debug_assert!(total > 0.0, "every gathered vertex is served");
                list.iter_mut().for_each(|(_, w)| *w /= total);
                list
            })
            .collect();
        // The area each record shows, and its rays: ∝ √area out of the budget (the area-
        // weighted squared error Σ A σ²/n is least for n ∝ √A at a fixed Σ n); the budget
        // grows with the share of the shown light the records bring ([`budget_factor`]).
        let mut shown = vec![0.0; records.len()];
        let mut weighed = vec![0.0; records.len()];
        for ((list, &a), &s) in weights.iter().zip(areas).zip(shares) {
            for &(k, w) in list {
                shown[k as usize] += w * a;
                weighed[k as usize] += w * a * s * s;
            }
        }
        let total: f64 = shown.iter().map(|a| a.sqrt()).sum();
        let budget = RAY_BUDGET as f64 * budget_factor(&shown, &weighed);
        let rays_of = |k: usize| {
            rays.unwrap_or_else(|| {
                let share = budget * shown[k].sqrt() / total.max(f64::MIN_POSITIVE);
                (share.round() as usize).clamp(MIN_RECORD_RAYS, MAX_RECORD_RAYS)
            })
        };
        let progress = crate::progress::stage("gather: records", Some(records.len() as u64));
        let (values, gradients): (Vec<Rgb>, Vec<Gradient>) = records
            .par_iter()
            .zip(&record_vertex)
            .enumerate()
            .map(|(k, (record, &v))| {
                progress.advance(1);
                let mut rng = Rng::new(&[self.seed(), v as u64, 0xCAC4E]);
                let s = spot(v);
                let (h, g) = self.hemisphere_graded(
                    record.x,
                    record.n,
                    s.patch,
                    (&[], Count::All),
                    (rays_of(k), bright_rays(rays_of(k))),
                    NEAR_DEPTH,
                    true,
                    &mut rng,
                );
                let g = g
                    .expect("asked for")
                    .limited(h.radiance, record.reach(), GRADIENT_LIMIT);
                (h.radiance, g)
            })
            .unzip();
        stats.record_rays = (0..records.len()).map(rays_of).sum();

        let mut cache = Cache {
            records,
            values,
            gradients,
            index,
            stats,
        };
        let out: Vec<Option<Rgb>> = spots
            .iter()
            .zip(&weights)
            .map(|(s, list)| {
                let s = s.as_ref()?;
                let mut sum = [0.0; 3];
                for &(k, w) in list {
                    for (a, b) in sum.iter_mut().zip(cache.carried(k as usize, s.x)) {
                        *a += w * b;
                    }
                }
                Some(sum)
            })
            .collect();
        cache.stats.interpolated = out.iter().flatten().count() - cache.stats.records;
        (out, cache)
    }
}

/// The share of each vertex's shown light that the records bring (its reflected indirect
/// light), as the solution judges it: 1 − lit/L in luminance, with lit = Le + ρ·(D + E) the
/// vertex's own terms (`lit[v]`, gathered) and L the solution's radiance there (`baked[v]`),
/// at least [`MIN_SHARE`]; 1 where the solution shows nothing. L is a patch's mean, so beside
/// a shadow the share is a guess, which only weighs the budget ([`budget_factor`]).
pub fn record_shares(lit: &[Gathered], baked: &[Rgb]) -> Vec<f64> {
    lit.iter()
        .zip(baked)
        .map(|(g, b)| {
            let (own, whole) = (luminance(g.radiance), luminance(*b));
            if whole > 0.0 {
                (1.0 - own / whole).clamp(MIN_SHARE, 1.0)
            } else {
                1.0
            }
        })
        .collect()
}

/// The least share [`record_shares`] gives a vertex.
pub const MIN_SHARE: f64 = 0.1;

/// The records' rays as a multiple of [`RAY_BUDGET`], from the area each shows (`shown`, A_k)
/// and that area weighed by the squared shares of the light it brings there (`weighed`,
/// S_k = Σ_v w_vk a_v s_v², [`record_shares`]). A record's noise reaches what a vertex shows
/// times the share, so at fixed rays the display's noise from the records grows as the mean
/// share s̄ = Σ√S_k / Σ√A_k: the budget is scaled by (s̄ / [`REFERENCE_SHARE`])² to keep it
/// where [`RAY_BUDGET`] was measured, and never below it: between 1 and
/// [`MAX_BUDGET_FACTOR`] (s̄ ≤ 1).
pub fn budget_factor(shown: &[f64], weighed: &[f64]) -> f64 {
    let plain: f64 = shown.iter().map(|a| a.sqrt()).sum();
    let share = weighed.iter().map(|a| a.sqrt()).sum::<f64>() / plain.max(f64::MIN_POSITIVE);
    (share / REFERENCE_SHARE).powi(2).max(1.0)
}

/// The records' mean share of the shown light (s̄ of [`budget_factor`]) on the scene
/// [`RAY_BUDGET`] was measured on: the office of 10⁵ triangles under its twelve lamps, 0.62.
pub const REFERENCE_SHARE: f64 = 0.6;

/// The most [`budget_factor`] gives, where the records bring all the light shown:
/// 1 / [`REFERENCE_SHARE`]², 2.8.
pub const MAX_BUDGET_FACTOR: f64 = 1.0 / (REFERENCE_SHARE * REFERENCE_SHARE);

#[cfg(test)]
mod tests {
    use std::hash::BuildHasher;

    use glam::DVec3;

    use super::{clamp_radii, Index, Record};

    /// A floor record of R = 2 is clamped by a record 0.1 away on a leg (R 0.02) to 0.12, and
    /// the clamp goes no further than that bound: not by a record beyond its reach, nor by one
    /// behind its plane, nor by one whose bound is larger than its R.
    #[test]
    fn a_records_radius_is_clamped_by_the_records_within_its_reach() {
        let record = |x: [f64; 3], n: DVec3, r: f64| Record {
            x: DVec3::from(x),
            n,
            r,
        };
        let mut records = vec![
            record([0.0; 3], DVec3::Z, 2.0),
            record([0.1, 0.0, 0.0], DVec3::X, 0.02),
            record([0.05, 0.0, -0.05], DVec3::Z, 0.01),
            record([0.0, 0.5, 0.0], DVec3::Z, 0.01),
            record([0.0, -0.15, 0.0], DVec3::Z, 1.0),
        ];
        let mut index = Index::new(1.0, 1e-3);
        for (k, r) in records.iter().enumerate() {
            index.insert(k as u32, r.x, r.reach());
        }
        assert!(clamp_radii(&index, &mut records));
        // Reach 0.2: the leg's record (0.1 away) bounds it by 0.02 + 0.1; the one 0.07 away
        // below its plane (0.08 if it counted) and the one 0.5 away do not.
        assert!((records[0].r - 0.12).abs() < 1e-12, "{}", records[0].r);
        // The last record (reach 0.1) does not reach the first (0.15 away).
        assert_eq!(records[4].r, 1.0);
        assert_eq!(
            [records[1].r, records[2].r, records[3].r],
            [0.02, 0.01, 0.01]
        );
        // Clamped once, nothing more shrinks.
        assert!(!clamp_radii(&index, &mut records));
    }

    use rustc_hash::FxBuildHasher;

    /// The grid's cheap hash still tells its keys apart: every cell of a block around the
    /// origin (negative coordinates too) and each of the six normal buckets gets its own
    /// hash, and a key is not its permutation's.
    #[test]
    fn cell_keys_hash_apart() {
        let mut seen = std::collections::HashSet::new();
        for i in -6..6i64 {
            for j in -6..6i64 {
                for k in -6..6i64 {
                    for b in 0..6u8 {
                        let h = FxBuildHasher.hash_one(([i, j, k], b));
                        assert!(seen.insert(h), "{i} {j} {k} {b}");
                    }
                }
            }
        }
        let h = |c: [i64; 3]| FxBuildHasher.hash_one(c);
        assert_ne!(h([1, 2, 3]), h([3, 2, 1]));
    }

    /// A record's share is what its vertex's own terms leave of the solution's light there,
    /// floored, and 1 where the solution is dark; the budget grows as the squared mean share
    /// over the reference share, at least 1, and a record's area counts as √A.
    #[test]
    fn the_records_budget_follows_the_share_of_the_light_they_bring() {
        use super::{budget_factor, record_shares, MIN_SHARE, REFERENCE_SHARE};
        use crate::gather::Gathered;
        let lit = |y: f64| Gathered::buried([y; 3]);
        let shares = record_shares(
            &[lit(0.3), lit(2.0), lit(0.0), lit(1.0)],
            &[[1.0; 3], [1.0; 3], [0.0; 3], [1.0; 3]],
        );
        let expected = [0.7, MIN_SHARE, 1.0, MIN_SHARE];
        for (s, e) in shares.iter().zip(expected) {
            assert!((s - e).abs() < 1e-12, "{shares:?}");
        }
        // Every record's light all the records': (1 / 0.6)² = 2.78.
        let f = budget_factor(&[1.0, 4.0], &[1.0, 4.0]);
        assert!((f - (1.0 / REFERENCE_SHARE).powi(2)).abs() < 1e-12, "{f}");
        // Shares 0.9 on an area of 4 and 0.3 on an area of 1: s̄ = (0.9·2 + 0.3·1) / 3 = 0.7.
        let f = budget_factor(&[1.0, 4.0], &[0.09, 4.0 * 0.81]);
        assert!((f - (0.7 / REFERENCE_SHARE).powi(2)).abs() < 1e-12, "{f}");
        // Below the reference share the budget stays.
        assert_eq!(budget_factor(&[1.0, 4.0], &[0.01, 0.04]), 1.0);
    }
}
