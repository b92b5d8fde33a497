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
//!    each estimated afresh (the receiver's 7-point rule and a few visibility rays). So links
//!    stay high in the hierarchies where transfers are weak or far, and O(n) links serve n
//!    elements at a fixed ε (HSA91 §5).
//! 3. **Solve** ([`Hierarchy::sweep`]): a Jacobi sweep gathers, at every node, Σ F·L over its
//!    links (from the previous sweep's radiance, in parallel; a split element source gives
//!    its children's radiance weighted by how much of F reaches each,
//!    [`Hierarchy::link_radiance`]), then *push-pull*: what a node
//!    gathered is pushed down to every leaf below it (irradiance is intensive: the same on
//!    every part; a cluster whose faces look different ways gives each face its cosine's
//!    share, [`ClusterGather`]), leaves take L = Le + ρ·G, and radiance is pulled up as
//!    area-weighted means.
//!    Refinement is interleaved with the solve (refine against the current radiance, sweep,
//!    refine again: the multigridding of HSA91 §4.3), until a converged solution asks for no
//!    more links.
//! 4. **Output** ([`output`]): the leaves, triangulated conformingly (a leaf with a split
//!    neighbour is fanned through the neighbour's edge vertices), are the output patches.
//!
//! Buried points (as in [`crate::form_factor`]): a receiving element's rule points whose
//! normal ray meets the back of a surface (the floor under a block) gather nothing, its
//! other points stand for its visible part, and radiance is pulled up weighted by visible
//! area, so a source's buried part does not dilute the radiance of the part that is seen
//! (its visibility rays already count it as blocked).
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
//! chair seen from the whole floor: nearly nothing), and their row sums fell to 0.8 (the
//! generated hall of 10⁴ triangles: the floor 2.8 % dark on average, the ceiling it lights
//! 4 %; normalised, the hall's median displayed error 2.85 % → 2.02 % and its bias −1.0 % →
//! +0.1 %). Normalising gives the missing share the mean radiance of what the leaf does
//! see, so beside a dark underside the leaf comes out a little bright (the hall's undersides
//! +3.7 % on average) rather than dark.

pub mod direct;
pub mod links;
pub mod output;
pub mod tree;

use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

use crate::color::Rgb;
use crate::form_factor::{closes, occluders, CLOSURE_PROBES};
use crate::mesh::Patches;
use crate::scene::Environment;
use crate::solve;
use crate::visibility::Visibility;
use crate::{Error, Result};

pub use links::{Action, Link};
pub use tree::{Node, Tree};

/// Settings of the hierarchical solver.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Settings {
    /// Refinement threshold ε: a link may carry at most this fraction of the scene's emitted
    /// power (ρ_r · L_s · F_rs · A_r / Σ Le·A, largest channels); in (0, 1).
    pub epsilon: f64,
    /// Smallest element area, as a fraction of the scene's total area; in (0, 1).
    pub min_area: f64,
    /// Visibility rays per link, in 1..=1024 (and the Monte Carlo sample pairs of a link with
    /// a cluster end). Element receivers integrate the unoccluded form factor with a fixed
    /// 7-point Gauss rule ([`links::RECEIVER_POINTS`]) whatever this is; the rays estimate
    /// the visible fraction.
    pub rays: u32,
    /// Refinement passes at most (each splits one level; a guard, not a tuning knob).
    pub max_passes: u32,
    /// Links at most: refinement stops with a warning beyond this (memory guard: a link takes
    /// 24 bytes).
    pub max_links: u64,
    /// Compute the emitters' direct light at every element ([`direct`]) when the scene
    /// qualifies ([`direct::chosen`]: few, small emitters); false: links carry all emission.
    pub direct: bool,
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
        if self.max_passes == 0 || self.max_links == 0 {
            return Err(Error::setting(
                "hierarchical.max_passes",
                "max_passes and max_links must be ≥ 1",
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
    /// Emitting root patches whose direct light every element computes at its own rule
    /// points ([`direct`]); 0 when links carry all emission.
    pub direct_emitters: usize,
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
}

/// A cluster pushes what it gathers by its faces' orientation ([`ClusterGather`]) when some
/// face below turns more than arccos(0.8) ≈ 37° from their mean normal (a block's top and
/// sides: 45° and more); flatter clusters push uniformly. Measured: the integrating sphere
/// (1280 facets) keeps its error (0.24 % at ε = 1e-4; pushed by orientation, 1.6 %), the
/// Cornell box cut into 11,338 roots and the hall are the same for any threshold in
/// 0.8–0.95.
pub const ORIENTED_CONE_COS: f64 = 0.8;

/// Probe rays per root of the closure test, at least: a root that sees open sky or a back
/// over a share p of its hemisphere passes for closed with probability (1 − p)^probes, and its
/// leaves' row sums are then normalised to 1 instead of about 1 − p (its indirect light
/// too bright by about p). At 16, a root 10 % open passes 19 % of the time; scenes of up to
/// 62,500 roots get the full [`CLOSURE_PROBES`] (4·10⁶ rays in all), 10⁶ roots 1.6·10⁷ rays.
const MIN_CLOSURE_PROBES: usize = 16;

/// Sweeps between refinement passes: the oracle needs radiance of the right order, not a
/// converged one (the final solve converges).
const PASS_SWEEPS: u32 = 2;

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
    settings.validate()?;
    solver.validate()?;
    env.validate()?;
    let mut h = Hierarchy::new(roots, settings, env, seed);
    let mut warnings = Vec::new();
    let mut history = Vec::new();
    let emitted = h.emitted_power();
    if emitted > 0.0 && h.tree.root().is_some() {
        h.start();
        let mut passes = 0;
        loop {
            if passes >= settings.max_passes {
                warnings.push(format!(
                    "hierarchical refinement stopped after {passes} passes (max_passes)"
                ));
                break;
            }
            if h.links.len() as u64 > settings.max_links {
                warnings.push(format!(
                    "hierarchical refinement stopped at {} links (max_links {}): raise \
                     --epsilon or --min-area for a finer solution in this memory",
                    h.links.len(),
                    settings.max_links
                ));
                break;
            }
            if h.refine_pass() {
                passes += 1;
                for _ in 0..PASS_SWEEPS {
                    history.push(h.sweep());
                }
                crate::progress::note_status(|| {
                    format!(
                        "hierarchical pass {passes}: {} links, {} elements",
                        h.links.len(),
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
    }
    // The final solve on the final links, each gathering its source two levels down
    // ([`Hierarchy::link_radiance`]): from L = Le, N sweeps for Neumann (exactly the Neumann
    // partial sum), else to the tolerance.
    h.find_grandchild_shares();
    // The final links' row sums, root by root. During refinement only a closed scene's are
    // normalised: the oracle bounds a source by its brightest leaf, and the few leaves whose
    // few-ray row sums fall far below 1 (0.4 % under 0.5 in the hall of 10⁵ triangles) would,
    // normalised, inflate that bound over whole clusters (measured there: 43 % more links,
    // 7.6 M against 5.4 M, for the same surfaces' means within 0.5 %).
    if h.stats.closed_roots > 0 && !h.stats.closed_scene {
        h.row_sum = h.row_sums();
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
    h.stats.rays_cast += patches.len() as u64;
    let stats = h.finish_stats();
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
    })
}

/// The solver's state: the hierarchies, the links, and the radiance of every node.
pub struct Hierarchy<'a> {
    pub tree: Tree,
    /// The links, sorted by receiver; set through `set_links`.
    pub links: Vec<Link>,
    /// Where each receiver's run of `links` starts, and `links.len()` last.
    receiver_starts: Vec<usize>,
    /// Per link, once the links are final: the shares of its form factor through each of its
    /// element source's 16 grandchildren ([`links::grandchild_shares`]); empty before, and
    /// none for links whose source has no split child.
    grandchild_shares: GrandchildShares,
    roots: &'a Patches,
    vis: Visibility,
    occluders: Visibility,
    settings: Settings,
    seed: u64,
    /// Radiance every element sends through links, W·sr⁻¹·m⁻² (leaves: solved; inner:
    /// area-weighted mean of children): its radiance L less the emission that reaches other
    /// elements as their direct light ([`direct`]; L itself when the links carry all
    /// emission).
    pub elem_l: Vec<Rgb>,
    /// The same for every cluster (area-weighted mean of its root elements).
    pub cluster_l: Vec<Rgb>,
    /// The largest channel of the radiance of any leaf below each element and each cluster:
    /// what the oracle bounds a source's radiance by.
    elem_max: Vec<f64>,
    cluster_max: Vec<f64>,
    /// Per element: bit k set when point k of the receiver rule ([`links::receiver_rule`]) is
    /// buried under contact geometry (its normal ray meets the back of a surface).
    buried: Vec<u16>,
    /// Per element: the rule weight of its unburied points, its visible fraction in [0, 1].
    visible: Vec<f64>,
    /// Nothing can be buried (no face can occlude: a convex enclosure).
    convex: bool,
    /// Effective row sum of every element (0 where its root is not closed), or empty when no
    /// root is.
    row_sum: Vec<f64>,
    /// Per root: none of its probe rays escaped the scene or met the back of a surface.
    closed_roots: Vec<bool>,
    /// The emitters whose direct light the elements compute themselves ([`direct`]); empty
    /// when the links carry all emission.
    emitters: Vec<direct::Emitter>,
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
    pub stats: Stats,
}

impl<'a> Hierarchy<'a> {
    /// Hierarchies over `roots`, no links yet, L = Le, lit also by `env`.
    pub fn new(
        roots: &'a Patches,
        settings: &Settings,
        env: &Environment,
        seed: u64,
    ) -> Hierarchy<'a> {
        let tree = Tree::new(roots);
        let corners: Vec<[DVec3; 3]> = (0..roots.len()).map(|i| roots.corners(i)).collect();
        let vis = Visibility::build(&corners);
        let can_occlude = occluders(roots);
        let convex = !can_occlude.contains(&true);
        let occluders = vis.restricted(&can_occlude);
        let total_area = roots.total_area();
        let mut h = Hierarchy {
            elem_l: Vec::new(),
            cluster_l: Vec::new(),
            elem_max: Vec::new(),
            cluster_max: Vec::new(),
            tree,
            links: Vec::new(),
            receiver_starts: vec![0],
            grandchild_shares: GrandchildShares::default(),
            roots,
            vis,
            occluders,
            settings: *settings,
            seed,
            row_sum: Vec::new(),
            closed_roots: Vec::new(),
            buried: Vec::new(),
            visible: Vec::new(),
            emitters: if settings.direct {
                direct::chosen(roots)
            } else {
                Vec::new()
            },
            exact: vec![false; roots.len()],
            direct: Vec::new(),
            env: env.clone(),
            lift: 1e-6 * {
                let (lo, hi) = roots
                    .positions
                    .iter()
                    .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
                        (lo.min(*p), hi.max(*p))
                    });
                (hi - lo).length()
            },
            convex: false,
            epsilon: 0.0,
            min_area: settings.min_area * total_area,
            stats: Stats::default(),
        };
        h.convex = convex;
        for e in &h.emitters {
            h.exact[e.root as usize] = true;
        }
        h.stats.direct_emitters = h.emitters.len();
        h.update_new_elements();
        h.epsilon = settings.epsilon * h.emitted_power();
        h.stats.epsilon_absolute = h.epsilon;
        h.stats.min_area_absolute = h.min_area;
        h.reset();
        h
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

    /// No light has bounced yet: leaves hold the emission links carry, pulled up (L = Le
    /// without the emission the elements compute themselves, which only reaches other
    /// elements as their direct light, from the first sweep on).
    fn reset(&mut self) {
        let n = self.tree.elements.len();
        let zero = vec![[0.0; 3]; n];
        self.elem_l = vec![[0.0; 3]; n];
        self.cluster_l = vec![[0.0; 3]; self.tree.clusters.len()];
        let gz = vec![ClusterGather::default(); self.tree.clusters.len()];
        self.push_pull(&zero, &gz, false);
    }

    /// The root's self-link, and the closure test.
    fn start(&mut self) {
        let root = self.tree.root().expect("a root");
        self.set_links(match root.as_cluster() {
            Some(_) => vec![Link {
                receiver: root,
                source: root,
                f: 0.0,
                bound: 0.0,
                must_open: true,
                children: [0; 4],
            }],
            None => Vec::new(),
        });
        // Closure, root by root: probe rays from every root (as the matrix estimators do for
        // the whole scene, form_factor::compute); the leaves of a root none of whose rays
        // escapes or meets the back of a surface have their row sums normalised.
        let n = self.roots.len();
        let probes =
            (4_000_000 / n.max(1)).clamp(MIN_CLOSURE_PROBES, CLOSURE_PROBES as usize) as u32;
        let (roots, vis, seed) = (self.roots, &self.vis, self.seed);
        self.closed_roots = (0..n)
            .into_par_iter()
            .map(|i| closes(roots, vis, i, probes, seed))
            .collect();
        self.stats.rays_cast += n as u64 * probes as u64;
        self.stats.closed_roots = self.closed_roots.iter().filter(|&&c| c).count();
        self.stats.closed_scene = self.stats.closed_roots == n;
    }

    /// Prepares the elements made since the last call: tests their rule points for burial
    /// ([`Visibility::buried`]: the point's normal ray meets the back of a surface first), then
    /// computes their direct light ([`direct::element_direct`]).
    fn update_new_elements(&mut self) {
        let from = self.buried.len();
        let (tree, roots, vis) = (&self.tree, self.roots, &self.vis);
        let rule = links::receiver_rule();
        let convex = self.convex;
        let new: Vec<u16> = (from..tree.elements.len())
            .into_par_iter()
            .map(|e| {
                if convex {
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
            self.stats.rays_cast += (new.len() * rule.len()) as u64;
        }
        for mask in new {
            let visible = links::unburied_weights(mask).iter().sum();
            self.buried.push(mask);
            self.visible.push(visible);
        }
        let (emitters, occluders, buried) = (&self.emitters, &self.occluders, &self.buried);
        let (shadows, seed) = (!convex, self.seed);
        let outside = direct::Outside {
            env: &self.env,
            vis,
            lift: self.lift,
        };
        let new: Vec<direct::Direct> = (from..tree.elements.len())
            .into_par_iter()
            .map(|e| {
                direct::element_direct(
                    tree, occluders, shadows, emitters, outside, e, buried[e], seed,
                )
            })
            .collect();
        for d in new {
            self.stats.rays_cast += d.rays;
            self.direct.push(d);
        }
    }

    /// The emission links carry from root `r`: none when the elements compute it themselves
    /// ([`direct`]).
    fn carried_emission(&self, r: usize) -> Rgb {
        if self.exact[r] {
            [0.0; 3]
        } else {
            self.roots.emission[r]
        }
    }

    /// The leaves whose direct light varies over them by more than ε allows (ρ · spread · A
    /// above ε, the largest channels; [`direct::Direct::spread`]) and that can still be
    /// split: the direct light's own refinement, where a shadow edge or the fall-off next to
    /// a light crosses a leaf, whatever its links.
    fn direct_splits(&self) -> Vec<usize> {
        if self.emitters.is_empty() && !self.env.has_sharp() {
            return Vec::new();
        }
        let t = &self.tree;
        (0..t.elements.len())
            .into_par_iter()
            .filter(|&e| {
                let el = &t.elements[e];
                el.first_child == tree::NO_CHILD
                    && 0.25 * el.area >= self.min_area
                    && self.max_reflectance(Node::element(e)) * self.direct[e].spread * el.area
                        > self.epsilon
            })
            .collect()
    }

    /// Every element's radiance L, W·sr⁻¹·m⁻²: what the links transport plus the emission the
    /// elements compute themselves.
    fn total_radiance(&self) -> Vec<Rgb> {
        let t = &self.tree;
        (0..t.elements.len())
            .map(|e| {
                let r = t.elements[e].root as usize;
                if self.exact[r] {
                    add(self.elem_l[e], self.roots.emission[r])
                } else {
                    self.elem_l[e]
                }
            })
            .collect()
    }

    /// Largest reflectance channel of a node.
    fn max_reflectance(&self, node: Node) -> f64 {
        match node.as_element() {
            Some(e) => {
                let r = self.tree.elements[e].root as usize;
                self.roots.reflectance[r]
                    .iter()
                    .copied()
                    .fold(0.0, f64::max)
            }
            None => self.tree.clusters[node.as_cluster().unwrap()].max_reflectance,
        }
    }

    /// The brightest channel of any leaf below `node`, W·sr⁻¹·m⁻².
    fn max_radiance(&self, node: Node) -> f64 {
        match node.as_element() {
            Some(e) => self.elem_max[e],
            None => self.cluster_max[node.as_cluster().unwrap()],
        }
    }

    /// The radiance link `l` gathers from its source, W·sr⁻¹·m⁻²: once an element source is
    /// split, its children's radiance weighted by the link's shares of the form factor
    /// through each ([`Link::children`]) times each child's visible fraction; else the
    /// source's mean. So a receiver that sees one part of its source best (the floor next to
    /// a block's face, in its shadow) gathers that part's radiance, not the mean of parts it
    /// hardly sees: one level finer on the source side than the link, for no more links
    /// (measured on the Cornell box at ε = 1e-6: worst surface 2.6 % → 1.4 %).
    ///
    /// Once the links are final, the same two levels down: each split child's four children
    /// weighted by the link's shares through each ([`links::grandchild_shares`]). A
    /// dim face next to a bright floor sees the part of the floor beside it best, which is
    /// where the floor's radiance changes most (its shadow, its corner with the face); on the
    /// Cornell box at ε = 1e-6 the worst surface (such a face) went 0.94 % → 0.66 %, and
    /// weighting the source's leaves however deep only to 0.61 %.
    pub fn link_radiance(&self, i: usize, l: &Link) -> Rgb {
        if let Some(e) = l.source.as_element() {
            let first = self.tree.elements[e].first_child as usize;
            if let Some(shares) = self.grandchild_shares.get(i).filter(|s| **s != [0; 16]) {
                // Each child split further gives its four children their shares; an unsplit
                // child takes the sum of its quarter.
                let (mut parts, mut n) = ([(0, 0.0); 16], 0);
                for q in 0..4 {
                    let (child, quarter) = (first + q, &shares[4 * q..4 * q + 4]);
                    let grand = self.tree.elements[child].first_child;
                    if grand == tree::NO_CHILD {
                        parts[n] = (child, quarter.iter().map(|&x| x as f64).sum());
                        n += 1;
                    } else {
                        for (k, &share) in quarter.iter().enumerate() {
                            parts[n] = (grand as usize + k, share as f64);
                            n += 1;
                        }
                    }
                }
                let parts = parts[..n].iter().copied();
                if let Some(l) = self.share_weighted(parts) {
                    return l;
                }
            }
            if first != tree::NO_CHILD as usize {
                let parts = (0..4).map(|q| (first + q, l.children[q] as f64));
                if let Some(l) = self.share_weighted(parts) {
                    return l;
                }
            }
        }
        self.radiance(l.source)
    }

    /// Σ w·v·L / Σ w·v over (element, share w) parts, v each element's visible fraction;
    /// `None` when the weights sum to 0.
    fn share_weighted(&self, parts: impl Iterator<Item = (usize, f64)>) -> Option<Rgb> {
        let mut sum = [0.0; 3];
        let mut total = 0.0;
        for (k, share) in parts {
            let w = share * self.visible[k];
            total += w;
            for (s, l) in sum.iter_mut().zip(self.elem_l[k]) {
                *s += w * l;
            }
        }
        (total > 0.0).then(|| sum.map(|x| x / total))
    }

    fn radiance(&self, node: Node) -> Rgb {
        match node.as_element() {
            Some(e) => self.elem_l[e],
            None => self.cluster_l[node.as_cluster().unwrap()],
        }
    }

    /// One refinement pass: every link asks the oracle; links that must be finer are replaced
    /// by links one level down (elements split as needed, in link order: deterministic).
    /// Returns whether anything changed.
    pub fn refine_pass(&mut self) -> bool {
        let actions: Vec<Action> = self
            .links
            .par_iter()
            .map(|l| {
                // Bounded by the brightest leaf below the source, not its mean: a link from a
                // cluster gathers its area-mean radiance, which dilutes a small light among
                // dark surfaces the receiver may not see at all (energy lost). With the bound,
                // what that can take away is at most the power the oracle allows.
                let ls = self.max_radiance(l.source);
                links::oracle(
                    &self.tree,
                    l,
                    |n| self.max_reflectance(n),
                    ls,
                    self.epsilon,
                    self.min_area,
                )
            })
            .collect();
        let direct_splits = self.direct_splits();
        if actions.iter().all(|&a| a == Action::Keep) && direct_splits.is_empty() {
            return false;
        }
        for e in direct_splits {
            self.tree.split(e);
        }
        // Split the elements that must be split, in link order.
        for (l, &a) in self.links.iter().zip(&actions) {
            let node = match a {
                Action::SplitReceiver => l.receiver,
                Action::SplitSource => l.source,
                _ => continue,
            };
            if let Some(e) = node.as_element() {
                if self.tree.elements[e].first_child == tree::NO_CHILD {
                    self.tree.split(e);
                }
            }
        }
        self.update_new_elements();
        // The kept links compacted in place (a second list of them would double the peak
        // memory at the largest scenes: 6·10⁷ links are 1.4 GB), the rest turned into pairs.
        let mut kept = std::mem::take(&mut self.links);
        let mut w = 0;
        let mut pairs = Vec::new();
        for i in 0..kept.len() {
            let l = kept[i];
            match actions[i] {
                Action::Keep => {
                    kept[w] = l;
                    w += 1;
                }
                Action::SplitReceiver => {
                    for c in self.tree.children(l.receiver) {
                        pairs.push((c, l.source));
                    }
                }
                Action::SplitSource => {
                    for c in self.tree.children(l.source) {
                        pairs.push((l.receiver, c));
                    }
                }
                Action::SplitBoth => {
                    let kids = self.tree.children(l.receiver);
                    for &a in &kids {
                        for &b in &kids {
                            pairs.push((a, b));
                        }
                    }
                }
            }
        }
        kept.truncate(w);
        kept.shrink_to_fit();
        drop(actions);
        let rays = self.settings.rays as usize;
        let estimates: Vec<links::Estimate> = pairs
            .par_iter()
            .map(|&(r, s)| {
                let buried = r.as_element().map_or(0, |e| self.buried[e]);
                links::estimate(&self.tree, &self.occluders, r, s, rays, buried, self.seed)
            })
            .collect();
        let mut new = Vec::with_capacity(estimates.len());
        for e in estimates {
            self.stats.rays_cast += e.rays;
            new.extend(e.link);
        }
        // The kept links are still in order: sort the new ones and merge (a full sort of all
        // links every pass was a seventh of the Cornell box's solve at ε = 3e-7).
        new.par_sort_unstable_by_key(link_key);
        merge_into(&mut kept, new);
        self.set_links(kept);
        // New elements start at their parent's radiance (so the oracle sees light there).
        let n_old = self.elem_l.len();
        for e in n_old..self.tree.elements.len() {
            let p = self.tree.elements[e].parent as usize;
            self.elem_l.push(self.elem_l[p]);
            self.elem_max.push(self.elem_max[p]);
        }
        if self.stats.closed_scene {
            self.row_sum = self.row_sums();
        }
        true
    }

    /// Replaces the links, sorted by receiver (then source), and finds each receiver's run.
    fn set_links(&mut self, links: Vec<Link>) {
        debug_assert!(links.windows(2).all(|w| link_key(&w[0]) < link_key(&w[1])));
        self.grandchild_shares = GrandchildShares::default();
        self.receiver_starts.clear();
        for (i, l) in links.iter().enumerate() {
            if i == 0 || links[i - 1].receiver != l.receiver {
                self.receiver_starts.push(i);
            }
        }
        self.receiver_starts.push(links.len());
        self.links = links;
        self.links.shrink_to_fit();
    }

    /// Finds [`Hierarchy::grandchild_shares`] for the current links.
    fn find_grandchild_shares(&mut self) {
        let t = &self.tree;
        // Only links from a source whose children are split have shares: a first pass finds
        // them, so memory goes to those alone (4 bytes a link, 16 more for each such link).
        let deep = |l: &Link| match (l.receiver.as_element(), l.source.as_element()) {
            (Some(r), Some(s)) => {
                let first = t.elements[s].first_child;
                let split = first != tree::NO_CHILD
                    && (first..first + 4)
                        .any(|c| t.elements[c as usize].first_child != tree::NO_CHILD);
                split.then_some((r, s))
            }
            _ => None,
        };
        let mut slot = Vec::with_capacity(self.links.len());
        let mut pairs = Vec::new();
        for l in &self.links {
            match deep(l) {
                Some(pair) => {
                    slot.push(pairs.len() as u32);
                    pairs.push(pair);
                }
                None => slot.push(NO_SHARES),
            }
        }
        let shares = pairs
            .par_iter()
            .map(|&(r, s)| links::grandchild_shares(t, r, s))
            .collect();
        self.grandchild_shares = GrandchildShares { slot, shares };
    }

    /// What each node gathers over its own links: Σ F·L per channel (`with_radiance`), or
    /// Σ F in every channel. A cluster's gather is kept by direction ([`ClusterGather`]).
    fn gather(&self, with_radiance: bool) -> (Vec<Rgb>, Vec<ClusterGather>) {
        let t = &self.tree;
        let value = |i: usize, l: &Link| {
            let f = l.f as f64;
            if with_radiance {
                self.link_radiance(i, l).map(|x| f * x)
            } else {
                [f; 3]
            }
        };
        // Links are sorted by receiver and elements sort before clusters, so the element
        // receivers' runs come first.
        let starts = &self.receiver_starts;
        let runs = starts.len() - 1;
        let split =
            starts[..runs].partition_point(|&i| self.links[i].receiver.as_element().is_some());
        let mut ge = vec![[0.0; 3]; t.elements.len()];
        let by_element: Vec<(usize, Rgb)> = starts[..=split]
            .par_windows(2)
            .map(|w| {
                let run = &self.links[w[0]..w[1]];
                let g = (w[0]..w[1]).fold([0.0; 3], |g, i| add(g, value(i, &self.links[i])));
                (run[0].receiver.as_element().unwrap(), g)
            })
            .collect();
        for (e, g) in by_element {
            ge[e] = g;
        }
        let mut gc = vec![ClusterGather::default(); t.clusters.len()];
        let by_cluster: Vec<(usize, ClusterGather)> = starts[split..]
            .par_windows(2)
            .map(|w| {
                let run = &self.links[w[0]..w[1]];
                let c = run[0].receiver.as_cluster().unwrap();
                let mut cg = ClusterGather::default();
                for (i, l) in (w[0]..w[1]).zip(run) {
                    let d = t.sphere(l.source).0 - t.clusters[c].centre;
                    cg.add(&t.clusters[c], d, value(i, l));
                }
                (c, cg)
            })
            .collect();
        for (c, cg) in by_cluster {
            gc[c] = cg;
        }
        (ge, gc)
    }

    /// Each element's effective row sum: Σ F over its own links and its ancestors'; 0 (not
    /// normalised) for the elements of a root that is not closed.
    fn row_sums(&self) -> Vec<f64> {
        let (ge, gc) = self.gather(false);
        let down = self.push_down(&ge, &gc);
        down.iter()
            .zip(&self.tree.elements)
            .map(|(g, el)| {
                if self.closed_roots[el.root as usize] {
                    g[0]
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// What each element gathers through its own links and all its ancestors' (clusters'
    /// included): the push half of push-pull. A root element takes from its clusters what
    /// its own orientation receives ([`ClusterGather::at`]).
    fn push_down(&self, ge: &[Rgb], gc: &[ClusterGather]) -> Vec<Rgb> {
        let t = &self.tree;
        let mut cdown = gc.to_vec();
        for c in 0..t.clusters.len() {
            let cl = &t.clusters[c];
            for k in cl.first..cl.first + cl.count {
                if let Some(child) = t.cluster_children[k as usize].as_cluster() {
                    let parent = cdown[c].clone();
                    cdown[child].add_all(&parent);
                }
            }
        }
        let mut down = ge.to_vec();
        for e in 0..t.elements.len() {
            let p = t.elements[e].parent;
            let above = if p != tree::NO_CHILD {
                down[p as usize]
            } else if t.clusters.is_empty() {
                [0.0; 3]
            } else {
                cdown[t.root_parent[e] as usize].at(t.elements[e].normal)
            };
            down[e] = add(down[e], above);
        }
        down
    }

    /// Push-pull: leaves take L = Le + ρ·(D + G) (D their direct light when `with_direct`,
    /// G what the links bring, normalised by the row sum in closed scenes; Le only the
    /// emission links carry), inner elements and clusters the area-weighted mean of their
    /// children.
    fn push_pull(&mut self, ge: &[Rgb], gc: &[ClusterGather], with_direct: bool) {
        let down = self.push_down(ge, gc);
        let t = &self.tree;
        let n = t.elements.len();
        let mut l = vec![[0.0; 3]; n];
        // Radiance is pulled up weighted by visible area: a source's buried part (the floor
        // under a block) emits nothing and is seen by nobody, and its visibility rays already
        // count it as blocked, so its darkness must not dilute the visible part's radiance.
        let mut visible_area = vec![0.0; n];
        let mut lmax = vec![0.0f64; n];
        for e in (0..n).rev() {
            let el = &t.elements[e];
            if el.first_child == tree::NO_CHILD {
                let r = el.root as usize;
                let norm = match self.row_sum.get(e) {
                    Some(&s) if s > 0.0 => 1.0 / s,
                    _ => 1.0,
                };
                let le = self.carried_emission(r);
                let d = if with_direct {
                    self.direct[e].mean
                } else {
                    [0.0; 3]
                };
                let rho = self.roots.reflectance[r];
                for c in 0..3 {
                    l[e][c] = le[c] + rho[c] * (d[c] + down[e][c] * norm);
                }
                visible_area[e] = el.area * self.visible[e];
                lmax[e] = l[e].iter().copied().fold(0.0, f64::max);
            } else {
                let kids = el.first_child as usize..el.first_child as usize + 4;
                lmax[e] = kids.clone().map(|k| lmax[k]).fold(0.0, f64::max);
                (l[e], visible_area[e]) =
                    weighted_mean(kids.map(|k| (l[k], visible_area[k], t.elements[k].area)));
            }
        }
        let mut cl = vec![[0.0; 3]; t.clusters.len()];
        let mut cluster_visible = vec![0.0; t.clusters.len()];
        let mut cmax = vec![0.0f64; t.clusters.len()];
        for c in (0..t.clusters.len()).rev() {
            let k = &t.clusters[c];
            let kids = &t.cluster_children[k.first as usize..(k.first + k.count) as usize];
            cmax[c] = kids
                .iter()
                .map(|&child| match child.as_element() {
                    Some(e) => lmax[e],
                    None => cmax[child.as_cluster().unwrap()],
                })
                .fold(0.0, f64::max);
            (cl[c], cluster_visible[c]) =
                weighted_mean(kids.iter().map(|&child| match child.as_element() {
                    Some(e) => (l[e], visible_area[e], t.elements[e].area),
                    None => {
                        let j = child.as_cluster().unwrap();
                        (cl[j], cluster_visible[j], t.clusters[j].area)
                    }
                }));
        }
        self.elem_l = l;
        self.cluster_l = cl;
        self.elem_max = lmax;
        self.cluster_max = cmax;
    }

    /// One Jacobi sweep: gather over all links from the current radiance, then push-pull.
    /// Returns the relative change ‖ΔL‖ / ‖Le‖ over the leaves (area-weighted 2-norms): the
    /// residual E − (I − K)L of the linear system the links define.
    pub fn sweep(&mut self) -> f64 {
        let (ge, gc) = self.gather(true);
        let old = std::mem::take(&mut self.elem_l);
        self.push_pull(&ge, &gc, true);
        self.stats.sweeps += 1;
        let (mut num, mut den) = (0.0, 0.0);
        for (e, el) in self.tree.elements.iter().enumerate() {
            if el.first_child != tree::NO_CHILD {
                continue;
            }
            // The source term E = Le + ρ·D_env (the sky's and sun's light counts as emission).
            let r = el.root as usize;
            let (le, rho, env) = (
                self.roots.emission[r],
                self.roots.reflectance[r],
                self.direct[e].environment,
            );
            for c in 0..3 {
                num += el.area * (self.elem_l[e][c] - old[e][c]).powi(2);
                let source = le[c] + rho[c] * env[c];
                den += el.area * source * source;
            }
        }
        if den > 0.0 {
            (num / den).sqrt()
        } else {
            0.0
        }
    }

    /// Sweeps until the residual is at most the tolerance or the sweep limit; true if
    /// converged.
    fn converge(&mut self, solver: &solve::Settings, history: &mut Vec<f64>) -> bool {
        for _ in 0..solver.max_iterations {
            let r = self.sweep();
            history.push(r);
            solve::report_sweep(self.stats.sweeps, r);
            if r <= solver.tolerance {
                return true;
            }
        }
        false
    }

    fn finish_stats(&self) -> Stats {
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
        s.links = self.links.len() as u64;
        s.cluster_links = self
            .links
            .iter()
            .filter(|l| l.receiver.as_cluster().is_some() || l.source.as_cluster().is_some())
            .count() as u64;
        s.bytes_per_link = std::mem::size_of::<Link>();
        s
    }
}

/// What a cluster gathers, kept by the direction it arrives from, so that each face below
/// receives what its orientation lets it see: a cluster receives light through one link
/// and pushes it to every face below, and pushed uniformly, the faces of a block that look
/// away from a light got as much of it as the top that faces it (measured on the Cornell box
/// cut into 11,338 roots: +42 % on a block face that looks at the dark open front).
///
/// A link's light v from direction d (unit, the source's centre seen from the cluster's) is
/// spread over the faces below in proportion to the clamped cosine between each face's
/// normal n and d, in the separable form c(n, d) = Σ_a |d_a| · max(0, sign(d_a) n_a) (exact
/// for faces and directions along the axes, an upper estimate otherwise), normalised by the
/// cluster's area-mean of it ([`tree::Cluster::facing`]): so the area-mean over the cluster
/// of what its faces take is v, as the link's form factor (an area-mean over the cluster)
/// says, and a face turned away from d takes none. Links whose direction no face below
/// meets (a mean of 0) are pushed uniformly, and so is everything a cluster gathers whose
/// faces all lie within [`ORIENTED_CONE_COS`] of their mean normal: there the cosine's
/// variation is small and, on a curved surface, mostly cancelled by parallax (inside a
/// sphere, exactly: every point receives alike), which one direction per link cannot follow.
#[derive(Clone, Debug, Default)]
pub struct ClusterGather {
    /// Pushed to every face alike, per channel.
    uniform: Rgb,
    /// Per axis direction (+x, +y, +z, −x, −y, −z), per channel: light already divided by the
    /// cluster's mean cosine; a face with normal n takes max(0, ±n_a) of each.
    by_axis: [Rgb; 6],
}

impl ClusterGather {
    /// Adds light `v` (per channel) that cluster `cluster` gathers from direction `d` (any
    /// length; 0 pushes uniformly).
    fn add(&mut self, cluster: &tree::Cluster, d: DVec3, v: Rgb) {
        let oriented = cluster.cone_cos < ORIENTED_CONE_COS;
        let Some(d) = d.try_normalize().filter(|_| oriented) else {
            self.uniform = add(self.uniform, v);
            return;
        };
        let bin = |a: usize| if d[a] >= 0.0 { a } else { a + 3 };
        let mean: f64 = (0..3)
            .map(|a| d[a].abs() * cluster.facing[bin(a)])
            .sum::<f64>()
            / cluster.area;
        if mean.is_nan() || mean <= 1e-12 {
            self.uniform = add(self.uniform, v);
            return;
        }
        for a in 0..3 {
            let w = d[a].abs() / mean;
            self.by_axis[bin(a)] = add(self.by_axis[bin(a)], v.map(|x| w * x));
        }
    }

    /// Adds everything `other` holds (a parent's gather, pushed to a child).
    fn add_all(&mut self, other: &ClusterGather) {
        self.uniform = add(self.uniform, other.uniform);
        for (a, b) in self.by_axis.iter_mut().zip(&other.by_axis) {
            *a = add(*a, *b);
        }
    }

    /// What a face with unit normal `n` below the cluster receives, per channel.
    fn at(&self, n: DVec3) -> Rgb {
        let mut g = self.uniform;
        for (bin, w) in self.by_axis.iter().zip(tree::axis_weights(n)) {
            g = add(g, bin.map(|x| w * x));
        }
        g
    }
}

/// No shares for this link ([`GrandchildShares::slot`]).
const NO_SHARES: u32 = u32::MAX;

/// The shares of each link's form factor through its element source's 16 grandchildren
/// ([`links::grandchild_shares`]), for the links whose source's children are split: per link
/// its place among `shares`, or [`NO_SHARES`].
#[derive(Debug, Default)]
struct GrandchildShares {
    slot: Vec<u32>,
    shares: Vec<[u8; 16]>,
}

impl GrandchildShares {
    /// Link `i`'s shares, if it has any.
    fn get(&self, i: usize) -> Option<&[u8; 16]> {
        match self.slot.get(i) {
            Some(&k) if k != NO_SHARES => self.shares.get(k as usize),
            _ => None,
        }
    }
}

/// The order of the links: by receiver, then source (each pair at most once).
fn link_key(l: &Link) -> (Node, Node) {
    (l.receiver, l.source)
}

/// Merges `b` into `a`, both sorted by [`link_key`], in place: from the back, into the room
/// `a` reserves at its end, so no third list is made (at 10⁷ links a copy is 240 MB).
fn merge_into(a: &mut Vec<Link>, b: Vec<Link>) {
    let (n, m) = (a.len(), b.len());
    // Exactly the room needed: amortised doubling would leave up to as much again unused
    // (at 6·10⁷ links, 1.4 GB).
    a.reserve_exact(m);
    a.extend_from_slice(&b); // the room, overwritten below
    let (mut i, mut j, mut k) = (n, m, n + m);
    while j > 0 {
        k -= 1;
        if i > 0 && link_key(&a[i - 1]) > link_key(&b[j - 1]) {
            a[k] = a[i - 1];
            i -= 1;
        } else {
            a[k] = b[j - 1];
            j -= 1;
        }
    }
}

/// The visible-area-weighted mean radiance of (radiance, visible area, area) parts, with their
/// total visible area; the area-weighted mean when nothing is visible.
fn weighted_mean(parts: impl Iterator<Item = (Rgb, f64, f64)> + Clone) -> (Rgb, f64) {
    let visible: f64 = parts.clone().map(|p| p.1).sum();
    let by_visible = visible > 0.0;
    let weight = |p: &(Rgb, f64, f64)| if by_visible { p.1 } else { p.2 };
    let total: f64 = parts.clone().map(|p| weight(&p)).sum();
    let sum = parts.fold([0.0; 3], |acc, p| add(acc, p.0.map(|x| weight(&p) * x)));
    (sum.map(|s| s / total), visible)
}

fn add(a: Rgb, b: Rgb) -> Rgb {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[cfg(test)]
mod tests;
