//! Hierarchical radiosity with clustering: the cost of a bake grows like the number of
//! elements, not its square. This module owns the hierarchical solve, from root patches to
//! leaf radiance; [`crate::pipeline`] calls it for `method = hierarchical`.
//!
//! The method (Hanrahan, Salzman & Aupperle, "A rapid hierarchical radiosity algorithm",
//! SIGGRAPH 1991; with the clusters of Smits, Arvo & Greenberg, SIGGRAPH 1994, and Sillion,
//! IEEE TVCG 1995):
//!
//! 1. **Hierarchies** ([`tree`]): every root patch (a scene triangle, split to `--max-edge`
//!    only when one is given) is the root of an element quadtree; a BVH over the root patches
//!    groups them into clusters, so the whole scene is one root node.
//! 2. **Links** ([`links`]): the light exchange starts as the root's self-link. A refinement
//!    pass asks the BF oracle of every link whether it may carry more than ε of the emitted
//!    power (judged on an upper estimate of the unoccluded form factor, made apart from the
//!    link's own samples); if so the larger end is split (elements 1 → 4 down to the minimum
//!    area, clusters into their children) and the link replaced by links to the children,
//!    each estimated afresh (the receiver's 7-point rule, [`rule`], and a few visibility
//!    rays). So links stay high in the hierarchies where transfers are weak or far, and O(n)
//!    links serve n elements at a fixed ε (HSA91 §5).
//! 3. **Solve** ([`Hierarchy::sweep`]): a Jacobi sweep gathers, at every node, Σ F·L over its
//!    links (from the previous sweep's radiance, in parallel; a split element source gives
//!    its children's radiance weighted by how much of F reaches each, a cluster source its
//!    parts' radiance weighted by their form factors to the receiver, each part sending that
//!    of its faces turned toward the receiver, [`Hierarchy::link_radiance`]),
//!    then *push-pull*: what a node
//!    gathered is pushed down to every leaf below it (irradiance is intensive: the same on
//!    every part; a cluster whose faces look different ways gives each face its cosine's
//!    share, [`ClusterGather`]), leaves take L = Le + ρ·G, and radiance is pulled up as
//!    area-weighted means.
//!    Once the links are final, the leaves below a link whose source is near (sharing an
//!    edge, beside it) gather through it with their own form factor, not the receiver's
//!    mean ([`near`]).
//!    Refinement is interleaved with the solve (refine against the current radiance, sweep,
//!    refine again: the multigridding of HSA91 §4.3), until a converged solution asks for no
//!    more links. Each convergence combines the last sweeps by Anderson acceleration
//!    (`Hierarchy::converge`, [`crate::solve::anderson`]): a Krylov method's sweeps, not
//!    Jacobi's, where the reflectance is high.
//! 4. **Output** ([`output`]): the leaves, triangulated conformingly (a leaf with a split
//!    neighbour is fanned through the neighbour's edge vertices), are the output patches.
//!
//! Buried points (as in [`crate::form_factor`]): a receiving element's rule points whose
//! normal ray meets the back of a surface (the floor under a block) gather nothing, its
//! other points stand for its visible part, a receiving cluster's form factor is its mean
//! over its seen area, and radiance is pulled up weighted by visible area, so a source's
//! buried part does not dilute the radiance of the part that is seen (its visibility rays
//! already count it as blocked).
//!
//! Energy: below a closed root (every probe ray from it lands on the front of a surface) each
//! leaf's gathered light in the final solve (in every sweep when the whole scene is closed)
//! is divided by its effective row sum Σ F over the links it and its
//! ancestors gather through, which is 1 exactly when the estimates are (Cohen & Wallace
//! §4.11's row normalisation): a closed enclosure is then exact whatever the cluster
//! approximations. Decided root by root, not for the whole scene as the matrix estimators
//! do: one open part (a window, the back of a lamp's panel) would otherwise leave every
//! enclosed room unnormalised. That matters more here than for a matrix, because a leaf's
//! links sit at different levels: beside a chair, the floor's leaves see the ceiling through
//! their own links (the chair's occlusion counted) but the chair through an ancestor's (the
//! chair seen from the whole floor: nearly nothing), and their row sums fall to about 0.8:
//! unnormalised, the generated hall's floor comes out dark, the ceiling it lights darker, and
//! the whole solution biased low. Normalising gives the missing share the mean radiance of
//! what the leaf sees through its ancestors' links, whose form factors are the ones that
//! miss it (`push_pull`'s `gathered`; not the mean of everything it sees, which counts the
//! lamps its own links reach), so beside a dark underside the leaf comes out a little
//! bright (the hall's undersides, by a few per cent) rather than dark.

pub mod direct;
pub mod links;
pub mod near;
pub mod output;
pub mod pilot;
mod push_pull;
mod ranks;
mod refine;
pub mod regather;
pub mod rule;
mod sweep;
pub mod tree;

use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

use crate::color::Rgb;
use crate::distributed::{Exchange, Partition, Solo};
use crate::form_factor::{closes, hemisphere, occluders, CLOSURE_PROBES};
use crate::mesh::Patches;
use crate::scene::Environment;
use crate::solve;
use crate::visibility::Visibility;
use crate::{Error, Result};

pub use links::{Action, Link};
pub use push_pull::ClusterGather;
use refine::GrandchildShares;
pub use tree::{Node, Tree};

/// Settings of the hierarchical solver.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Settings {
    /// Refinement threshold ε: a link may carry at most this fraction of the scene's emitted
    /// power (ρ_r · L_s · F_rs · A_r / Σ Le·A, largest channels); in (0, 1). The bake's
    /// settings give it at the scene's default patch size, and a finer `max_edge` divides it
    /// ([`crate::pipeline::Settings::finer`]) before it reaches the solver.
    pub epsilon: f64,
    /// Smallest element area, as a fraction of the scene's total area; in (0, 1).
    pub min_area: f64,
    /// Visibility rays per link, in 1..=1024 (and the Monte Carlo sample pairs of a link with
    /// a cluster end). Element receivers integrate the unoccluded form factor with a fixed
    /// 7-point Gauss rule ([`rule::RECEIVER_POINTS`]) whatever this is; the rays estimate
    /// the visible fraction.
    pub rays: u32,
    /// Refinement passes at most, ≥ 1 (each splits one level; a guard, not a tuning knob):
    /// refinement stops there with a warning (`--max-passes`).
    pub max_passes: u32,
    /// Links at most, ≥ 1: refinement stops with a warning beyond this (memory guard: a link
    /// takes 20 bytes; a bake sets it from `--max-memory`).
    pub max_links: u64,
    /// Compute the emitters' direct light at every element ([`direct`]) when the scene
    /// qualifies ([`direct::chosen`]: emitters that cover a small share of it); false: links
    /// carry all emission.
    pub direct: bool,
    /// No refinement pass starts after this instant: refinement stops with a warning and the
    /// solve converges on the links it has (the time budget of a bake, `--max-time`).
    #[serde(skip)]
    pub deadline: Option<std::time::Instant>,
    /// The least rays a leaf of the leaves' final gather ([`regather`]; more while the
    /// leaves are few), in 0..=4096: once the links have converged, each leaf's reflected
    /// light is traced again from its own points. 0 leaves the links' answer.
    pub regather_rays: u32,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            epsilon: 1e-4,
            min_area: 1e-5,
            rays: 3,
            max_passes: 100,
            max_links: 100_000_000,
            direct: true,
            deadline: None,
            regather_rays: 32,
        }
    }
}

impl Settings {
    /// Checks the ranges documented on the fields ([`Error::Setting`] names
    /// `hierarchical.epsilon`, …).
    pub fn validate(&self) -> Result<()> {
        let fraction = |name: &str, x: f64| {
            if x > 0.0 && x < 1.0 {
                Ok(())
            } else {
                Err(Error::setting(name, format!("{x} is not in (0, 1)")))
            }
        };
        fraction("hierarchical.epsilon", self.epsilon)?;
        fraction("hierarchical.min_area", self.min_area)?;
        if !(1..=1024).contains(&self.rays) {
            return Err(Error::setting(
                "hierarchical.rays",
                format!("{} is not in 1..=1024", self.rays),
            ));
        }
        if self.regather_rays > 4096 {
            return Err(Error::setting(
                "hierarchical.regather_rays",
                format!("{} is not in 0..=4096", self.regather_rays),
            ));
        }
        if self.max_passes == 0 {
            return Err(Error::setting(
                "hierarchical.max_passes",
                "must be at least 1",
            ));
        }
        if self.max_links == 0 {
            return Err(Error::setting(
                "hierarchical.max_links",
                "must be at least 1",
            ));
        }
        Ok(())
    }
}

/// Counts of a hierarchical solve (in the report).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Stats {
    /// Root patches (element-tree roots).
    pub roots: usize,
    /// Clusters of the BVH over the roots.
    pub clusters: usize,
    /// Elements in all trees (roots, inner and leaves).
    pub elements: usize,
    /// Leaf elements.
    pub leaves: usize,
    /// Links of the final solve.
    pub links: u64,
    /// Links with a cluster at one end or both.
    pub cluster_links: u64,
    /// Visibility rays cast (links and closure probes).
    pub rays_cast: u64,
    /// Refinement passes that changed the links.
    pub passes: u32,
    /// Jacobi sweeps, all passes together.
    pub sweeps: u32,
    /// (Leaf, link) pairs whose leaf gathers through the link with its own form factor, the
    /// link's source being near ([`near`]).
    pub near_corrections: u64,
    /// Bytes per link in memory.
    pub bytes_per_link: usize,
    /// Every root was found closed ([`Stats::closed_roots`]).
    pub closed_scene: bool,
    /// Roots none of whose probe rays escaped the scene or met the back of a surface: their
    /// leaves' row sums are normalised to 1.
    pub closed_roots: usize,
    /// ε in absolute units (radiance × area).
    pub epsilon_absolute: f64,
    /// Smallest element area allowed, scene units squared.
    pub min_area_absolute: f64,
    /// Emitters whose direct light every element computes at its own rule points
    /// ([`direct`]: the scene's emitting triangles, [`direct::merged`]); 0 when links carry
    /// all emission.
    pub direct_emitters: usize,
    /// Shadow rays per rule point of that direct light: per emitter, at most
    /// ([`direct::ShadowRays::Own`]), or shared among all the emitters past
    /// [`direct::DIRECT_BUDGET`] ([`direct::ShadowRays::Shared`] and [`direct::ShadowRays::Tree`],
    /// `direct_rays_shared`); 0 when links carry all emission.
    pub direct_shadow_rays: usize,
    /// Whether the `direct_shadow_rays` of a rule point are shared among the emitters.
    pub direct_rays_shared: bool,
    /// Whether those shared rays are drawn by the light tree over the emitters
    /// ([`direct::ShadowRays::Tree`]) rather than by their weights Le·F.
    pub direct_rays_by_tree: bool,
    /// Rays of the leaves' final gather ([`regather`]), all its steps; 0 when it did not run.
    pub regather_rays: u64,
    /// Seconds of the leaves' final gather.
    pub regather_seconds: f64,
    /// Over several ranks ([`crate::distributed`]): the links each rank held at the end, by
    /// rank (empty in one process).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub links_by_rank: Vec<u64>,
    /// Over several ranks: how many times the roots were cut among them again by their links
    /// (the rebalance of `hierarchical::ranks`).
    #[serde(skip_serializing_if = "is_zero")]
    pub rebalances: u32,
    /// Over several ranks: the bytes they sent one another in the sweeps' exchanges of
    /// gathers, all ranks and sweeps together (0 in one process).
    #[serde(skip_serializing_if = "is_zero")]
    pub sweep_exchange_bytes: u64,
    /// Over several ranks: the seconds the slowest rank spent in those exchanges, its wait
    /// for the others included.
    #[serde(skip_serializing_if = "is_zero")]
    pub sweep_exchange_seconds: f64,
}

/// True for a count or a figure that is 0 (left out of the serialized stats).
fn is_zero<T: Default + PartialEq>(x: &T) -> bool {
    *x == T::default()
}

/// The result of [`solve()`].
pub struct Hierarchical {
    /// The output patches: leaves, triangulated conformingly.
    pub patches: Patches,
    /// Radiance of each output patch, W·sr⁻¹·m⁻² per channel.
    pub radiance: Vec<Rgb>,
    /// Visible fraction of each output patch (0 for one buried under contact geometry, else
    /// 1; tested at its centroid).
    pub visible_fraction: Vec<f64>,
    /// The solver's bookkeeping (method Jacobi; Neumann when `bounces` were asked).
    pub solution: solve::Solution,
    pub stats: Stats,
    pub warnings: Vec<String>,
    /// The leaf with the largest effective row sum (Σ F over its links and its ancestors'),
    /// found on the final links: where broken geometry (coincident or intersecting faces)
    /// makes light; `None` when there were no links (nothing emits).
    pub worst_row: Option<WorstLeaf>,
}

/// The leaf of [`Hierarchical::worst_row`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorstLeaf {
    /// Its effective row sum Σ F (about 1 in a closed scene, at most 1 in an open one).
    pub sum: f64,
    /// The root patch it was cut from (an index into the roots given to [`solve()`]).
    pub root: usize,
    /// Its centroid, scene units.
    pub centroid: DVec3,
    /// Its area, scene units squared.
    pub area: f64,
}

/// A cluster pushes what it gathers by its faces' orientation ([`ClusterGather`]) when some
/// face below turns more than arccos(0.8) ≈ 37° from their mean normal (a block's top and
/// sides: 45° and more); flatter clusters push uniformly. The integrating sphere keeps its
/// accuracy only so (its facets' clusters pushed by orientation, its error grows several
/// times: the parallax [`ClusterGather`] describes), while the Cornell box cut
/// into many small roots and the generated hall give the same answers for any threshold
/// from 0.8 to 0.95.
pub const ORIENTED_CONE_COS: f64 = 0.8;

/// Probe rays per root of the closure test, at least: a root that sees open sky or a back
/// over a share p of its hemisphere passes for closed with probability (1 − p)^probes, and its
/// leaves' row sums are then normalised to 1 instead of about 1 − p (its indirect light
/// too bright by about p). At 16, a root 10 % open passes 19 % of the time; scenes of up to
/// 62,500 roots get the full [`CLOSURE_PROBES`] (4·10⁶ rays in all), 10⁶ roots 1.6·10⁷ rays.
const MIN_CLOSURE_PROBES: usize = 16;

/// Hemisphere rays from each closed root with ρ = 1 in some channel, at most, to find whether
/// such roots enclose themselves ([`Hierarchy::check_not_singular`]): an absorbing patch that
/// subtends 1 % of the roots' views is missed by all of them with probability 0.99²⁵⁶ ≈ 8 %
/// from one root, and by every root of a set of ten with probability below 10⁻¹⁰.
const SINGULAR_PROBES: usize = 256;

/// Hemisphere rays of the singular check in all, about: past 15,625 suspect roots, each
/// casts fewer than [`SINGULAR_PROBES`] (down to [`MIN_CLOSURE_PROBES`]), so the check costs
/// no more than the closure test. A set that large misses an absorbing patch only if every
/// one of its thousands of roots does.
const SINGULAR_RAYS: usize = 4_000_000;

/// Sample pairs per link ray of a link estimated where refinement stopped before opening it
/// ([`Hierarchy::estimate_unopened`]): such links are few and coarse, and their kernel is
/// unbounded, so they get more samples than a link of the finished refinement.
const UNOPENED_SAMPLES: usize = 16;

/// Sweeps between refinement passes: the oracle needs radiance of the right order, not a
/// converged one (the final solve converges).
const PASS_SWEEPS: u32 = 2;

/// A refinement pass is followed by [`PASS_SWEEPS`] sweeps only when it changed the number of
/// links by at least this share. The last passes of a large solve open a few thousand links
/// of tens of millions each, and their sweeps (and a closed scene's row sums) cost as much as
/// a pass for a radiance that hardly moves.
const SWEEP_AFTER_GROWTH: f64 = 0.01;

/// Over several ranks, the roots are cut among them again by their links
/// ([`Hierarchy::rebalance`]) once the links reach one a root, and then each time they have
/// grown this many times since: a few times in a solve (at 10⁶ roots, about 1, 4 and 16
/// million links), each moving a share of the links once.
const REBALANCE_GROWTH: u64 = 4;

/// The hierarchical solve of `roots` (patches that are the roots of the element trees).
/// `solver` gives the stopping rule (tolerance on the relative change per sweep, sweep
/// limit) and, for `neumann`, the number of bounces of the final solve; `seed` keys every
/// random choice, so the result is the same for any thread count.
pub fn solve(
    roots: &Patches,
    settings: &Settings,
    env: &Environment,
    solver: &solve::Settings,
    seed: u64,
) -> Result<Hierarchical> {
    solve_on(roots, settings, env, solver, seed, &Solo)
}

/// [`solve()`] as one rank of `comm` ([`crate::distributed`]): every rank calls it with the
/// same arguments, and every rank returns the same result, the one [`solve()`] returns (the
/// counts in its stats are the whole solve's).
pub fn solve_on(
    roots: &Patches,
    settings: &Settings,
    env: &Environment,
    solver: &solve::Settings,
    seed: u64,
    comm: &dyn Exchange,
) -> Result<Hierarchical> {
    settings.validate()?;
    solver.validate()?;
    env.validate()?;
    let _progress = crate::progress::stage("hierarchical solve", None);
    let mut h = Hierarchy::with_sample(roots, settings, env, seed, None, comm);
    let mut warnings = Vec::new();
    let mut history = Vec::new();
    let emitted = h.emitted_power();
    if emitted > 0.0 && h.tree.root().is_some() {
        h.start();
        if solver.method != solve::Method::Neumann {
            h.check_not_singular()?;
        }
        let mut passes = 0;
        // Every decision below is taken on counts over all ranks, so every rank takes it.
        let mut previous_links = h.link_count() as f64;
        let mut balanced_at = 0;
        let mut stopped_early = false;
        loop {
            if passes >= settings.max_passes {
                warnings.push(format!(
                    "hierarchical refinement stopped after {passes} passes, the most \
                     --max-passes allows, before it found that ε asks for no more links: the \
                     solution may be coarser than asked; raise --max-passes for a finer one"
                ));
                break;
            }
            // The next pass may grow the links as much as the last one did: stop before it
            // would pass the limit (a rank's: each rank holds its own links).
            let all_links = h.link_count();
            let links = all_links as f64;
            let growth = (links / previous_links.max(1.0)).max(1.0);
            if h.most_links() as f64 * growth > settings.max_links as f64 {
                stopped_early = true;
                warnings.push(format!(
                    "hierarchical refinement stopped at {} links, short of what ε asks: the \
                     next pass could pass {} (max_links, from the memory limit); the solution \
                     is coarser than asked. Raise --epsilon or --min-area to bake within this \
                     memory, or allow more with --max-memory",
                    all_links, settings.max_links
                ));
                break;
            }
            let late = settings
                .deadline
                .is_some_and(|d| std::time::Instant::now() >= d);
            if h.comm.any(late) {
                stopped_early = true;
                warnings.push(format!(
                    "hierarchical refinement stopped at {} links after {passes} passes, short \
                     of what ε asks: its share of the time budget (--max-time) was spent; the \
                     solution is coarser than asked",
                    all_links
                ));
                break;
            }
            previous_links = links;
            if h.refine_pass() {
                passes += 1;
                // A pass that changed few links leaves the radiance the oracle reads about
                // where it was: no sweeps (the final convergence comes after the last pass).
                let now = h.link_count();
                // Over several ranks, the roots cut again by their links as these grow.
                if now >= REBALANCE_GROWTH * balanced_at && now >= roots.len() as u64 {
                    h.rebalance();
                    balanced_at = now;
                }
                if (now as f64 - links).abs() >= SWEEP_AFTER_GROWTH * links {
                    for _ in 0..PASS_SWEEPS {
                        history.push(h.sweep());
                    }
                }
                crate::progress::note_status(|| {
                    format!(
                        "hierarchical pass {passes}: {now} links, {} elements",
                        h.tree.elements.len()
                    )
                });
                continue;
            }
            // Stable at this radiance: converge, and stop if the converged radiance asks for
            // no more links.
            h.converge(solver, &mut history);
            if !h.refine_pass() {
                break;
            }
            passes += 1;
        }
        h.stats.passes = passes;
        if stopped_early {
            h.estimate_unopened(UNOPENED_SAMPLES);
        }
    }
    // The final solve on the final links, each gathering its source two levels down
    // ([`Hierarchy::link_radiance`]): from L = Le, N sweeps for Neumann (exactly the Neumann
    // partial sum), else to the tolerance.
    h.find_grandchild_shares();
    h.find_near_corrections();
    // The final links' row sums, root by root. During refinement only a closed scene's are
    // normalised: the oracle bounds a source by its brightest leaf, and the few leaves whose
    // few-ray row sums fall far below 1 (a few in a thousand, under 0.5, in a large hall)
    // would, normalised, inflate that bound over whole clusters: many more links, for the
    // same surfaces' means. A closed scene's are found again: the near corrections change them.
    // Neither the links nor their row sums change after this: the worst row is found with
    // them.
    let mut worst_row = None;
    if h.stats.closed_roots > 0 || h.cap_rows {
        worst_row = h.refresh_rows();
    }
    let converged = if emitted == 0.0 {
        true
    } else if solver.method == solve::Method::Neumann {
        h.reset();
        history.clear();
        for _ in 0..solver.bounces {
            history.push(h.sweep());
        }
        true
    } else {
        h.converge(solver, &mut history)
    };
    // The links are done with: free them before the output is built, which would otherwise
    // set the peak memory of the largest bakes (10⁶ triangles: about 1 GB of links and
    // shares alive beside a mesh of 2·10⁶ vertices).
    let worst_row = worst_row.or_else(|| h.worst_row()).map(|(e, sum)| {
        let el = &h.tree.elements[e];
        WorstLeaf {
            sum,
            root: el.root as usize,
            centroid: el.centroid,
            area: el.area,
        }
    });
    let mut stats = h.finish_stats();
    h.free_links();
    // The leaves' final gather ([`regather`]), which reads no link (so they are freed before
    // it); not after `bounces` sweeps, whose answer is the Neumann sum of exactly that many.
    if emitted > 0.0 && solver.method != solve::Method::Neumann {
        let t = std::time::Instant::now();
        let mut rays = 0;
        for _ in 0..regather::STEPS {
            rays += h.regather(settings.regather_rays as usize);
        }
        let rays = h.comm.sum_u64(rays);
        stats.regather_rays = rays;
        stats.rays_cast += rays;
        stats.regather_seconds = t.elapsed().as_secs_f64();
    }
    let output::Leaves {
        patches,
        radiance,
        root,
    } = output::leaves(&h.tree, roots, &h.total_radiance());
    // Buried output patches (the floor under a block): the centroid's normal ray meets the
    // back of a surface ([`Visibility::buried`]). One ray per patch: leaves are small.
    let visible_fraction: Vec<f64> = (0..patches.len())
        .into_par_iter()
        .map(|i| {
            let r = root[i];
            let hidden = h
                .vis
                .buried(patches.centroid[i], roots.normal[r as usize], r);
            if hidden {
                0.0
            } else {
                1.0
            }
        })
        .collect();
    stats.rays_cast += patches.len() as u64;
    let solution = solve::Solution {
        radiance: radiance.clone(),
        iterations: stats.sweeps,
        residual: history.last().copied().unwrap_or(0.0),
        residual_history: history,
        converged,
        grey: false,
        omega: 1.0,
        method: if solver.method == solve::Method::Neumann {
            solve::Method::Neumann
        } else {
            solve::Method::Jacobi
        },
    };
    Ok(Hierarchical {
        patches,
        radiance,
        visible_fraction,
        solution,
        stats,
        warnings,
        worst_row,
    })
}

/// The solver's state: the hierarchies, the links, and the radiance of every node.
pub struct Hierarchy<'a> {
    pub tree: Tree,
    /// The links, sorted by receiver; set through `set_links`. In a solve over several ranks,
    /// the links into this rank's nodes (the `ranks` module).
    pub links: Vec<Link>,
    /// Per node (the elements, then the clusters), where its run of `links` as receiver
    /// starts; `links.len()` last, so node k's run is `first_link[k]..first_link[k + 1]`.
    first_link: Vec<usize>,
    /// Per link, once the links are final: the shares of its form factor through each of its
    /// element source's 16 grandchildren ([`links::grandchild_shares`]); empty before, and
    /// none for links whose source has no split child.
    grandchild_shares: GrandchildShares,
    /// Once the links are final: the leaves' own form factors to the near sources of their
    /// ancestors' links, as corrections to what those links push down ([`near`]), sorted by
    /// leaf; empty before.
    near: Vec<near::Correction>,
    roots: &'a Patches,
    vis: Visibility,
    /// The roots that can occlude ([`occluders`]), when not all of them can; else `vis`
    /// serves (a copy of it would take as much memory again: 140 MB at 10⁶ triangles).
    occluders: Option<Visibility>,
    settings: Settings,
    seed: u64,
    /// Radiance every element sends through links, W·sr⁻¹·m⁻² (leaves: solved; inner:
    /// area-weighted mean of children): its radiance L less the emission that reaches other
    /// elements as their direct light ([`direct`]; L itself when the links carry all
    /// emission).
    pub elem_l: Vec<Rgb>,
    /// The same for every cluster (area-weighted mean of its root elements).
    pub cluster_l: Vec<Rgb>,
    /// Every cluster's radiance by the direction it leaves in ([`push_pull::OrientedRadiance`]).
    cluster_oriented: Vec<push_pull::OrientedRadiance>,
    /// The largest channel of the radiance of any leaf below each element and each cluster:
    /// what the oracle bounds a source's radiance by.
    elem_max: Vec<f64>,
    cluster_max: Vec<f64>,
    /// Per element: bit k set when point k of the receiver rule ([`rule::receiver_rule`]) is
    /// buried under contact geometry (its normal ray meets the back of a surface).
    buried: Vec<u16>,
    /// Per element: the rule weight of its unburied points, its visible fraction in [0, 1].
    visible: Vec<f64>,
    /// Nothing can be buried (no face can occlude: a convex enclosure).
    convex: bool,
    /// Effective row sum of every element (0 where its root is not closed, unless
    /// [`Hierarchy::cap_rows`] and it is over 1), or empty when no row is normalised.
    row_sum: Vec<f64>,
    /// Per element: Σ F over its own links alone (its part of `row_sum`; the rest is its
    /// ancestors'), found with `row_sum`; empty when no row is normalised.
    own_row_sum: Vec<f64>,
    /// The links changed since `row_sum` was found: the next sweep finds it again.
    rows_stale: bool,
    /// Open elements whose rows sum to more than 1 are normalised too: set where links were
    /// estimated as refinement stopped early ([`Hierarchy::estimate_unopened`]), whose noise
    /// can take a row past what any receiver can send on.
    cap_rows: bool,
    /// Per root: none of its probe rays escaped the scene or met the back of a surface.
    closed_roots: Vec<bool>,
    /// The emitters whose direct light the elements compute themselves ([`direct`]); empty
    /// when the links carry all emission.
    emitters: direct::Emitters,
    /// Per root: its emission reaches other elements through their own direct light
    /// ([`direct`]), so links carry only its reflected radiance.
    exact: Vec<bool>,
    /// Per element: its direct light from `emitters` and `env`.
    direct: Vec<direct::Direct>,
    /// The sky and the sun ([`crate::light::outside`]), whose direct light every element computes.
    env: Environment,
    /// How far rays to the sky and the sun start above the surface: 10⁻⁶ of the scene's extent.
    lift: f64,
    /// Absolute ε (radiance × area) and minimum area (scene units²).
    epsilon: f64,
    min_area: f64,
    /// A pilot's sample ([`pilot`]): only links whose receiver it holds are refined, and only
    /// its leaves split for their direct light; `None` in a solve.
    sample: Option<pilot::Sample>,
    /// The ranks the solve runs on ([`crate::distributed`]), and what each owns: `None` for
    /// one rank.
    comm: &'a dyn Exchange,
    partition: Option<Partition>,
    /// Bytes this rank sent in the sweeps' exchanges, and nanoseconds spent in them.
    sweep_exchange: [std::sync::atomic::AtomicU64; 2],
    pub stats: Stats,
}

impl<'a> Hierarchy<'a> {
    /// The share of an element source's area its material covers, 1 − t
    /// ([`crate::scene::Material::transmittance`]): a link gathers from a partly transparent
    /// source only what its covered part sends (what lies behind arrives through the links
    /// past it, whose rays the source lets through). 1 for clusters and opaque sources.
    pub(super) fn coverage(&self, source: Node) -> f64 {
        let t = &self.roots.material_transmittance;
        match source.as_element() {
            Some(e) if !t.is_empty() => {
                let root = self.tree.elements[e].root as usize;
                1.0 - t
                    .get(self.roots.material[root] as usize)
                    .copied()
                    .unwrap_or(0.0)
            }
            _ => 1.0,
        }
    }

    /// Hierarchies over `roots`, no links yet, L = Le, lit also by `env`.
    pub fn new(
        roots: &'a Patches,
        settings: &Settings,
        env: &Environment,
        seed: u64,
    ) -> Hierarchy<'a> {
        Hierarchy::with_sample(roots, settings, env, seed, None, &Solo)
    }

    /// [`Hierarchy::new`] for a pilot ([`pilot`]) that will sample each unit of roots with
    /// probability `p`: the sample is drawn now, inactive (refinement is not restricted until
    /// the pilot activates it), and the roots outside it compute their direct light at one
    /// point of the rule, not all (their mean is all the pilot reads of it). `comm`: the ranks
    /// of the solve ([`ranks`]).
    pub(super) fn with_sample(
        roots: &'a Patches,
        settings: &Settings,
        env: &Environment,
        seed: u64,
        p: Option<f64>,
        comm: &'a dyn Exchange,
    ) -> Hierarchy<'a> {
        let tree = Tree::new(roots);
        let partition = (comm.size() > 1).then(|| tree.partition(comm.size()));
        let sample = p.map(|p| pilot::Sample::draw(&tree, p, seed));
        let corners: Vec<[DVec3; 3]> = (0..roots.len()).map(|i| roots.corners(i)).collect();
        let vis = Visibility::build(&corners).with_transmittance(&roots.transmittance());
        let can_occlude = occluders(roots);
        let convex = !can_occlude.contains(&true);
        let occluders = can_occlude
            .contains(&false)
            .then(|| vis.restricted(&can_occlude));
        let total_area = roots.total_area();
        let mut h = Hierarchy {
            elem_l: Vec::new(),
            cluster_l: Vec::new(),
            cluster_oriented: Vec::new(),
            elem_max: Vec::new(),
            cluster_max: Vec::new(),
            tree,
            links: Vec::new(),
            first_link: Vec::new(),
            grandchild_shares: GrandchildShares::default(),
            near: Vec::new(),
            roots,
            vis,
            occluders,
            settings: *settings,
            seed,
            row_sum: Vec::new(),
            own_row_sum: Vec::new(),
            rows_stale: false,
            cap_rows: false,
            closed_roots: Vec::new(),
            buried: Vec::new(),
            visible: Vec::new(),
            emitters: if settings.direct {
                direct::chosen(roots)
            } else {
                direct::Emitters::default()
            },
            exact: vec![false; roots.len()],
            direct: Vec::new(),
            env: env.clone(),
            lift: 1e-6 * {
                let (lo, hi) = crate::geometry::bounds(roots.positions.iter().copied());
                (hi - lo).length()
            },
            convex: false,
            epsilon: 0.0,
            min_area: settings.min_area * total_area,
            sample,
            comm,
            partition,
            sweep_exchange: Default::default(),
            stats: Stats::default(),
        };
        h.convex = convex;
        for r in h.emitters.list.iter().flat_map(|e| &e.roots) {
            h.exact[*r as usize] = true;
        }
        h.stats.direct_emitters = h.emitters.list.len();
        let rays = h.emitters.list.first().map(|e| e.rays);
        h.stats.direct_rays_shared = matches!(
            rays,
            Some(direct::ShadowRays::Shared | direct::ShadowRays::Tree)
        );
        h.stats.direct_rays_by_tree = rays == Some(direct::ShadowRays::Tree);
        h.stats.direct_shadow_rays = rays.map_or(0, direct::ShadowRays::per_point);
        h.update_new_elements();
        h.epsilon = settings.epsilon * h.emitted_power();
        h.stats.epsilon_absolute = h.epsilon;
        h.stats.min_area_absolute = h.min_area;
        h.reset();
        h
    }

    /// The visibility links and direct light are traced through: the roots that can occlude.
    pub(super) fn occluders(&self) -> &Visibility {
        self.occluders.as_ref().unwrap_or(&self.vis)
    }

    /// Σ max-channel(Le)·A over the roots, and the light the sky and the sun bring to them,
    /// Σ max-channel(ρ·D_env)·A (radiance × area, as Le·A): the scale of ε.
    pub fn emitted_power(&self) -> f64 {
        (0..self.roots.len())
            .map(|i| {
                let max = |v: Rgb| v.iter().copied().fold(0.0, f64::max);
                let env = self.direct.get(i).map_or([0.0; 3], |d| d.environment);
                let rho = self.roots.reflectance[i];
                let reflected = [0, 1, 2].map(|c| rho[c] * env[c]);
                (max(self.roots.emission[i]) + max(reflected)) * self.roots.area[i]
            })
            .sum()
    }

    /// Gives the links still waiting to be opened when refinement stopped early their
    /// estimate ([`links::overlapping_estimate`], with `samples` × the link rays; a solve
    /// uses [`UNOPENED_SAMPLES`]), so they carry light; rows their noise takes past 1 are then
    /// normalised ([`Hierarchy::cap_rows`]).
    pub(super) fn estimate_unopened(&mut self, samples: usize) {
        let rays = samples * self.settings.rays as usize;
        let estimates: Vec<(usize, links::Estimate)> = self
            .links
            .par_iter()
            .enumerate()
            .filter(|(_, l)| l.must_open())
            .map(|(i, l)| {
                let e = links::overlapping_estimate(
                    &self.tree,
                    self.occluders(),
                    l,
                    rays,
                    self.burial(),
                    self.seed,
                );
                (i, e)
            })
            .collect();
        for (i, e) in estimates {
            self.stats.rays_cast += e.rays;
            if let Some(l) = e.link {
                self.links[i] = l;
            }
        }
        self.cap_rows = true;
    }

    /// The root's self-link, and the closure test.
    pub(super) fn start(&mut self) {
        self.start_with(4_000_000, MIN_CLOSURE_PROBES);
    }

    /// [`Hierarchy::start`] with about `closure_rays` probe rays in all (at least `min` and
    /// at most [`CLOSURE_PROBES`] a root).
    pub(super) fn start_with(&mut self, closure_rays: usize, min: usize) {
        let root = self.tree.root().expect("a root");
        // (Over several ranks, the root's owner holds it.)
        self.set_links(match root.as_cluster() {
            Some(_) if self.owns(root) => vec![Link::opening(root, root)],
            _ => Vec::new(),
        });
        // Closure, root by root: probe rays from every root (as the matrix estimators do for
        // the whole scene, form_factor::compute); the leaves of a root none of whose rays
        // escapes or meets the back of a surface have their row sums normalised.
        let n = self.roots.len();
        let probes = (closure_rays / n.max(1)).clamp(min, CLOSURE_PROBES as usize) as u32;
        let (roots, vis, seed) = (self.roots, &self.vis, self.seed);
        let closed = (0..n)
            .into_par_iter()
            .map(|i| self.owns_element(i) && closes(roots, vis, i, probes, seed))
            .collect();
        self.closed_roots = self.owners_values(
            0,
            closed,
            |w, &c| w.bytes(&[c as u8]),
            |r| r.bytes::<1>()[0] != 0,
        );
        let owned = (0..n).filter(|&i| self.owns_element(i)).count();
        self.stats.rays_cast += owned as u64 * probes as u64;
        self.stats.closed_roots = self.closed_roots.iter().filter(|&&c| c).count();
        self.stats.closed_scene = self.stats.closed_roots == n;
    }

    /// The matrix method's [`solve::check_not_singular`] on the roots, before any link: for
    /// each channel, the closed roots ([`Hierarchy::start`]) with ρ = 1 there that gather,
    /// by [`SINGULAR_PROBES`] hemisphere rays each at most ([`hemisphere::row`]), only from one
    /// another ([`solve::closed_full_set`]). Such an enclosure has no finite solution, and
    /// its radiance, growing with every sweep, would ask the oracle for ever more links. Every
    /// rank computes the same rows for the same roots (the closure verdicts are shared), so
    /// every rank returns the same answer. An opening or an absorbing patch smaller than the
    /// rays can see is missed: the system is then all but singular, its radiance some
    /// hundreds of times its emission.
    pub(super) fn check_not_singular(&self) -> Result<()> {
        let full = |i: usize, c: usize| self.roots.reflectance[i][c] >= 1.0;
        let closed = |i: usize| self.closed_roots.get(i) == Some(&true);
        let n = self.roots.len();
        let suspects: Vec<usize> = (0..n)
            .filter(|&i| closed(i) && (0..3).any(|c| full(i, c)))
            .collect();
        if suspects.is_empty() {
            return Ok(());
        }
        let (roots, vis, seed) = (self.roots, &self.vis, self.seed);
        let probes = (SINGULAR_RAYS / suspects.len()).clamp(MIN_CLOSURE_PROBES, SINGULAR_PROBES);
        let rows: Vec<hemisphere::Row> = suspects
            .par_iter()
            .map(|&i| hemisphere::row(roots, vis, i, probes as u32, seed ^ 0x5146_1A12))
            .collect();
        // The suspects that gather from each root. A suspect's rays that escape are passed
        // over: the closure verdict forgives a ray that slips through a seam, and so does
        // this check.
        let mut gatherers: Vec<Vec<u32>> = vec![Vec::new(); n];
        for (&i, row) in suspects.iter().zip(&rows) {
            for &(j, f) in &row.entries {
                if f > 0.0 {
                    gatherers[j as usize].push(i as u32);
                }
            }
        }
        for c in 0..3 {
            let candidates = (0..n).map(|i| closed(i) && full(i, c)).collect();
            let count = solve::closed_full_set(candidates, |j, gatherer| {
                gatherers[j].iter().for_each(|&i| gatherer(i as usize));
            });
            if count > 0 {
                return Err(solve::singular(count, c, "root patches"));
            }
        }
        Ok(())
    }

    /// Prepares the elements made since the last call: tests their rule points for burial
    /// ([`Visibility::buried`]: the point's normal ray meets the back of a surface first), then
    /// computes their direct light ([`direct::element_direct`]).
    pub(super) fn update_new_elements(&mut self) {
        let from = self.buried.len();
        let (tree, roots, vis) = (&self.tree, self.roots, &self.vis);
        let rule = rule::receiver_rule();
        let convex = self.convex;
        let new: Vec<u16> = (from..tree.elements.len())
            .into_par_iter()
            .map(|e| {
                if convex || !self.owns_element(e) {
                    return 0;
                }
                let root = tree.elements[e].root as usize;
                rule.iter().enumerate().fold(0u16, |mask, (k, &(b, _))| {
                    if vis.buried(tree.point(e, b), roots.normal[root], root as u32) {
                        mask | (1 << k)
                    } else {
                        mask
                    }
                })
            })
            .collect();
        if !convex {
            let owned = (from..tree.elements.len())
                .filter(|&e| self.owns_element(e))
                .count();
            self.stats.rays_cast += (owned * rule.len()) as u64;
        }
        let new = self.owners_values(from, new, |w, &m| w.u32(m as u32), |r| r.u32() as u16);
        for mask in new {
            let visible = rule::unburied_weights(mask).iter().sum();
            self.buried.push(mask);
            self.visible.push(visible);
        }
        let (emitters, occluders, buried) = (&self.emitters, self.occluders(), &self.buried);
        // A pilot's roots outside its sample: the first unburied rule point alone.
        let one_point = |e: usize| {
            let out = self
                .sample
                .as_ref()
                .is_some_and(|s| !s.has_root(tree.elements[e].root as usize));
            match (
                out,
                (0..rule::RECEIVER_POINTS).find(|k| buried[e] & (1 << k) == 0),
            ) {
                (true, Some(k)) => !(1u16 << k),
                _ => buried[e],
            }
        };
        let (shadows, seed) = (!convex, self.seed);
        let outside = direct::Outside {
            env: &self.env,
            vis,
            lift: self.lift,
        };
        let new: Vec<direct::Direct> = (from..tree.elements.len())
            .into_par_iter()
            .map(|e| {
                if !self.owns_element(e) {
                    return direct::Direct::default();
                }
                direct::element_direct(
                    tree,
                    occluders,
                    shadows,
                    emitters,
                    outside,
                    e,
                    one_point(e),
                    seed,
                )
            })
            .collect();
        // Each element's direct light from its owner (the rays stay counted where cast).
        let write = |w: &mut crate::distributed::Writer, d: &direct::Direct| {
            d.mean.iter().for_each(|&x| w.f64(x));
            w.f64(d.spread);
            d.environment.iter().for_each(|&x| w.f64(x));
        };
        let read = |r: &mut crate::distributed::Reader| direct::Direct {
            mean: [r.f64(), r.f64(), r.f64()],
            spread: r.f64(),
            environment: [r.f64(), r.f64(), r.f64()],
            rays: 0,
        };
        let new = self.owners_values(from, new, write, read);
        for d in new {
            self.stats.rays_cast += d.rays;
            let e = self.direct.len();
            if let Some(s) = self.sample.as_mut() {
                if s.has_root(self.tree.elements[e].root as usize) {
                    s.direct_rays += d.rays;
                }
            }
            self.direct.push(d);
        }
        if from == 0 {
            // The roots: the clusters' seen areas, for what cluster receivers gather.
            let n = self.tree.roots;
            self.tree.set_seen(&self.visible[..n]);
        }
    }

    /// Which rule points of each element are buried, and each element's visible fraction.
    pub(super) fn burial(&self) -> rule::Burial<'_> {
        rule::Burial {
            buried: &self.buried,
            visible: &self.visible,
        }
    }

    /// The emission links carry from root `r`: none when the elements compute it themselves
    /// ([`direct`]).
    pub(super) fn carried_emission(&self, r: usize) -> Rgb {
        if self.exact[r] {
            [0.0; 3]
        } else {
            self.roots.emission[r]
        }
    }

    /// Drops the links and what is found from them (their shares, the near corrections, the
    /// receivers' runs): the solve is over, the radiance stays.
    fn free_links(&mut self) {
        self.links = Vec::new();
        self.first_link = Vec::new();
        self.grandchild_shares = GrandchildShares::default();
        self.near = Vec::new();
        self.row_sum = Vec::new();
        self.own_row_sum = Vec::new();
    }

    pub(super) fn finish_stats(&self) -> Stats {
        let mut s = self.stats.clone();
        s.roots = self.tree.roots;
        s.clusters = self.tree.clusters.len();
        s.elements = self.tree.elements.len();
        s.leaves = self
            .tree
            .elements
            .iter()
            .filter(|e| e.first_child == tree::NO_CHILD)
            .count();
        s.links = self.link_count();
        s.cluster_links = self.comm.sum_u64(
            self.links
                .iter()
                .filter(|l| l.receiver.as_cluster().is_some() || l.source.as_cluster().is_some())
                .count() as u64,
        );
        s.rays_cast = self.comm.sum_u64(s.rays_cast);
        s.near_corrections = self.comm.sum_u64(s.near_corrections);
        if self.partition.is_some() {
            use std::sync::atomic::Ordering::Relaxed;
            s.links_by_rank = self.comm.gather_u64(self.links.len() as u64);
            s.sweep_exchange_bytes = self.comm.sum_u64(self.sweep_exchange[0].load(Relaxed));
            s.sweep_exchange_seconds =
                self.comm.max_u64(self.sweep_exchange[1].load(Relaxed)) as f64 * 1e-9;
        }
        s.bytes_per_link = std::mem::size_of::<Link>();
        s
    }
}

#[cfg(test)]
mod tests;
