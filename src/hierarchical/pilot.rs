//! A pilot of the hierarchical solve: how many links a scene's refinement will make, measured
//! on a random sample of its roots rather than guessed from counts of the scene, so the
//! estimate before a bake ([`crate::pipeline::estimate`]) can say what the solve will cost on
//! any scene, not only on those its constants were fitted to. This module owns the pilot;
//! it uses the solver's own refinement and sweeps.
//!
//! The links per root vary several-fold between scenes (a detailed interior's elements link to
//! a few hundred others, a hall's to a few dozen) and nothing counted before a solve predicts
//! them. So the pilot runs the solve's refinement for real, on a share of it:
//!
//! 1. **A coarse solution of the whole scene**: the solve's own refinement passes until the
//!    links reach [`COARSE_LINKS_PER_ROOT`] per root, the links still unopened estimated as a
//!    solve stopped early estimates them (`Hierarchy::estimate_unopened`), then sweeps to a
//!    loose tolerance. It gives every element radiance of the right order, indirect light
//!    included, which is what the oracle judges a link's source by.
//! 2. **Refinement of a sample's receivers only**: the roots are drawn as whole subtrees of
//!    the cluster tree (units of at most [`UNIT_ROOTS`] roots), each with probability p (a hash
//!    of the seed and the unit, so the same for any thread count); only links whose receiver
//!    is an element of a sampled root, or a cluster holding one, are refined further (their
//!    sources are split as they ask; new links to unsampled children are made but never
//!    refined), until the links are stable at the solution's radiance, as the solve's final
//!    passes are. The rest of the scene keeps the coarse solution's radiance.
//! 3. **The count** is the Horvitz–Thompson estimate (Horvitz & Thompson, "A generalization
//!    of sampling without replacement from a finite universe", JASA 1952) of the links the full
//!    refinement ends with: each link on a sampled receiver weighted by one over the
//!    probability that its receiver is in the sample: p at and inside a unit, 1 − (1 − p)^k
//!    for a cluster above k units. Unbiased as far as a receiver's links depend on its own
//!    path through the trees alone; the oracle's source radiance is the coarse solution's, not
//!    the converged one's, so a pilot estimates, it does not bound (within 15 % of the bake on
//!    the benchmark's scenes: BENCHMARKS.md "Large scenes: the estimate against the bake").
//!    The elements and the rays of their direct light are counted the same way.
//!
//! The roots outside the sample compute their direct light at one point of the receiver rule
//! (what they send is all the pilot reads of it), so the pilot costs a small share of the
//! solve. With every root sampled (p = 1: small scenes) the count is the refinement's own.

use serde::Serialize;

use crate::distributed::{Exchange, Solo};
use crate::mesh::Patches;
use crate::sampling::Rng;
use crate::scene::Environment;
use crate::solve;
use crate::Result;

use super::tree::{self, Node};
use super::{Hierarchy, Settings};

/// Links per root at which the coarse solution of the whole scene stops refining (pilot step 1):
/// with the unopened links estimated, one a root gives every root light from most of what it
/// sees, at a small share of what the refinement ends with (30–300 a root on the benchmark's
/// scenes); four gave the same counts within 4 % on them, for up to twice the pilot's time.
pub const COARSE_LINKS_PER_ROOT: f64 = 1.0;

/// Closure probe rays of the pilot in all (a solve casts 4·10⁶): a root found closed by
/// mistake only brightens the coarse solution a little.
const PILOT_CLOSURE_RAYS: usize = 500_000;

/// Closure probe rays per root of the pilot at least (a solve casts at least 16).
const PILOT_MIN_CLOSURE_PROBES: usize = 4;

/// Sample pairs per link ray of the coarse solution's unopened links
/// ([`Hierarchy::estimate_unopened`]), a quarter of a solve's: at 10⁶ roots about half of the
/// coarse links are unopened, and at the solve's 16 their estimate was a third of the pilot's
/// time. The coarse solution only gives the radiance the oracle weighs links by, summed over
/// many links a receiver, so a noisier estimate of each moves the count little.
const PILOT_UNOPENED_SAMPLES: usize = 4;

/// The relative change per sweep the coarse solution is converged to: radiance of the right
/// order is all the oracle needs.
const COARSE_TOLERANCE: f64 = 1e-2;

/// Sweeps of the coarse solution at most.
const COARSE_SWEEPS: u32 = 30;

/// Roots of a sampling unit at most: the sample is drawn as whole subtrees of the cluster
/// tree (the largest holding at most this many roots), so that only the few clusters above
/// them hold sampled roots of more than one unit. Sampled root by root, nearly every cluster
/// of a few dozen roots would hold one, and the pilot would refine most of the cluster links
/// (half of all links on detailed interiors).
pub const UNIT_ROOTS: u32 = 64;

/// Which roots the pilot refines: whole subtrees of the cluster tree (units), each with
/// probability p; per root and per cluster whether the sample holds it.
#[derive(Debug, Clone)]
pub(super) struct Sample {
    roots: Vec<bool>,
    clusters: Vec<bool>,
    /// Per cluster: the units below it when it is above the units, 0 for a unit or a cluster
    /// inside one.
    units_below: Vec<u32>,
    /// The probability each unit is in the sample, in (0, 1].
    p: f64,
    /// Refinement is restricted to the sample (the pilot's second step).
    pub(super) active: bool,
    /// Rays the sampled roots' elements cast for their direct light.
    pub(super) direct_rays: u64,
}

impl Sample {
    /// Each unit of `tree` with probability `p` (keyed by `seed`).
    pub(super) fn draw(tree: &tree::Tree, p: f64, seed: u64) -> Sample {
        let n = tree.clusters.len();
        let children = |c: usize| tree.kids(c);
        // Roots below each cluster (clusters are stored parents first: from the back).
        let mut below = vec![0u32; n];
        for c in (0..n).rev() {
            below[c] = children(c)
                .iter()
                .map(|k| k.as_cluster().map_or(1, |k| below[k]))
                .sum();
        }
        // From the top: a cluster is a unit when it holds at most UNIT_ROOTS roots and its
        // parent more; inside a unit every cluster and root takes the unit's draw.
        let mut state = vec![None::<bool>; n]; // Some(drawn) at and inside units
        let mut roots = vec![false; tree.roots];
        for c in 0..n {
            if state[c].is_none() && below[c] <= UNIT_ROOTS {
                let r = Rng::new(&[seed, c as u64, 0x50494C4F54]).next_f64();
                state[c] = Some(p >= 1.0 || r < p);
            }
            for &k in children(c) {
                match (k.as_cluster(), k.as_element()) {
                    (Some(k), _) => state[k] = state[c],
                    (_, Some(e)) => roots[e] = state[c].unwrap_or(false),
                    _ => unreachable!("a node is an element or a cluster"),
                }
            }
        }
        // Above the units: whether any unit below is drawn, and how many units are below.
        let mut clusters = vec![false; n];
        let mut units_below = vec![0u32; n];
        for c in (0..n).rev() {
            if let Some(drawn) = state[c] {
                clusters[c] = drawn;
                continue;
            }
            for k in children(c).iter().filter_map(|k| k.as_cluster()) {
                clusters[c] |= clusters[k];
                units_below[c] += if state[k].is_some() {
                    1
                } else {
                    units_below[k]
                };
            }
        }
        Sample {
            roots,
            clusters,
            units_below,
            p,
            active: false,
            direct_rays: 0,
        }
    }

    /// Whether root `r` is in the sample.
    pub(super) fn has_root(&self, r: usize) -> bool {
        self.roots[r]
    }

    /// Whether `node` (an element of any level, or a cluster) receives in the sample.
    pub(super) fn holds(&self, tree: &tree::Tree, node: Node) -> bool {
        match node.as_element() {
            Some(e) => self.roots[tree.elements[e].root as usize],
            None => self.clusters[node.as_cluster().unwrap()],
        }
    }

    /// The probability that `node` (one the sample holds) is held by a sample: p at and
    /// inside a unit, 1 − (1 − p)^k for a cluster above k units; in [p, 1].
    pub(super) fn probability(&self, node: Node) -> f64 {
        if self.p >= 1.0 {
            return 1.0;
        }
        match node.as_cluster().map(|c| self.units_below[c]) {
            Some(k) if k > 0 => 1.0 - (1.0 - self.p).powi(k as i32),
            _ => self.p,
        }
    }
}

/// What the pilot measured, extrapolated to the whole scene.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Pilot {
    /// ε of the refinement piloted (relative, as [`Settings::epsilon`]).
    pub epsilon: f64,
    /// Root elements of the scene.
    pub roots: usize,
    /// Roots in the sample.
    pub sampled: usize,
    /// Links the full refinement is estimated to end with.
    pub links: f64,
    /// Elements (roots and their descendants) it is estimated to make.
    pub elements: f64,
    /// Rays the elements' direct light is estimated to take (emitters in the mesh, the sky,
    /// the sun and the lamps; [`super::direct`]).
    pub direct_rays: f64,
    /// Whether the emitters' share of those rays is drawn by the light tree
    /// ([`super::direct::ShadowRays::Tree`]: each ray with a descent of the tree).
    pub direct_by_tree: bool,
    /// Wall-clock seconds the pilot took (measured, so not reproducible).
    pub seconds: f64,
}

/// The pilot of [`solve()`](super::solve()) on `roots` with the same arguments, sampling about
/// `sample` roots (all of them when the scene has no more); see the module documentation. A scene
/// without light makes no links.
pub fn pilot(
    roots: &Patches,
    settings: &Settings,
    env: &Environment,
    solver: &solve::Settings,
    seed: u64,
    sample: usize,
) -> Result<Pilot> {
    pilot_on(roots, settings, env, solver, seed, sample, &Solo)
}

/// [`pilot`] as one rank of `comm`, shared among the ranks as [`super::solve_on`] shares a
/// solve; every rank gets the same counts (the links' weights summed in rank order).
pub fn pilot_on(
    roots: &Patches,
    settings: &Settings,
    env: &Environment,
    solver: &solve::Settings,
    seed: u64,
    sample: usize,
    comm: &dyn Exchange,
) -> Result<Pilot> {
    settings.validate()?;
    solver.validate()?;
    env.validate()?;
    let _progress = crate::progress::stage("estimate: pilot solve", None);
    let n = roots.len();
    let p = (sample as f64 / n.max(1) as f64).min(1.0);
    let clock = std::time::Instant::now();
    let mut h = Hierarchy::with_sample(roots, settings, env, seed, Some(p), comm);
    let mut out = Pilot {
        epsilon: settings.epsilon,
        roots: n,
        sampled: 0,
        links: 0.0,
        elements: n as f64,
        direct_rays: 0.0,
        direct_by_tree: !h.emitters.tree.is_empty(),
        seconds: 0.0,
    };
    if h.emitted_power() <= 0.0 || h.tree.root().is_none() {
        out.seconds = clock.elapsed().as_secs_f64();
        return Ok(out);
    }
    h.start_with(PILOT_CLOSURE_RAYS, PILOT_MIN_CLOSURE_PROBES);
    // 1. The coarse solution of the whole scene.
    let coarse = COARSE_LINKS_PER_ROOT * n as f64;
    let mut passes = 0;
    let mut stable = false;
    while (h.link_count() as f64) < coarse && passes < settings.max_passes {
        if !h.refine_pass() {
            stable = true;
            break;
        }
        passes += 1;
    }
    if !stable {
        // As a solve stopped early: the unopened links estimated, and the rows their noise
        // takes past 1 normalised (else the coarse solution can grow without bound).
        h.estimate_unopened(PILOT_UNOPENED_SAMPLES);
    }
    if h.cap_rows || h.stats.closed_scene {
        h.refresh_rows();
    }
    let loose = solve::Settings {
        tolerance: COARSE_TOLERANCE.max(solver.tolerance),
        max_iterations: COARSE_SWEEPS,
        ..*solver
    };
    let mut history = Vec::new();
    h.converge(&loose, &mut history);
    // 2. The sample's receivers refined until stable at the solution's radiance.
    if let Some(s) = h.sample.as_mut() {
        s.active = true;
    }
    loop {
        if passes >= settings.max_passes {
            break;
        }
        // No sweeps between the passes: the rest of the scene keeps the coarse solution's
        // radiance, and new elements start at their parent's; the sample's receivers are
        // brought up to date once its links are stable.
        if h.refine_pass() {
            passes += 1;
            continue;
        }
        if h.cap_rows || h.stats.closed_scene {
            h.refresh_rows();
        }
        h.converge(&loose, &mut history);
        if !h.refine_pass() {
            break;
        }
        passes += 1;
    }
    // 3. The count.
    let s = h.sample.take().expect("the sample");
    out.sampled = s.roots.iter().filter(|&&b| b).count();
    let links: f64 = h
        .links
        .iter()
        .filter(|l| s.holds(&h.tree, l.receiver))
        .map(|l| 1.0 / s.probability(l.receiver))
        .sum();
    out.links = comm.sum_f64(links);
    let below_sampled = h.tree.elements[n..]
        .iter()
        .filter(|e| s.roots[e.root as usize])
        .count();
    out.elements = n as f64 + below_sampled as f64 / p;
    out.direct_rays = comm.sum_u64(s.direct_rays) as f64 / p;
    out.seconds = clock.elapsed().as_secs_f64();
    Ok(out)
}
