//! What a bake will cost, before any of it is done: the method `auto` picks, the patches, the
//! memory and the time, from counts of the scene and a cost model fitted to bakes on the
//! benchmark machine (2 cores; the figures are the constants below, and how well the model does
//! is in BENCHMARKS.md "Defaults that scale: the estimate against the bake"). `bake` refuses,
//! before it starts, a run whose estimated memory is more than `--max-memory` (by default the
//! memory the machine has available), and says how long a long run will take; `radiosity info`
//! prints the estimate for the options it is given. This module owns the model; it cuts the
//! scene into patches to count them, and solves nothing.
//!
//! The model's two halves:
//! - **Matrix**: memory and time grow with F's non-zeros. A pair of patches can have a
//!   non-zero entry only if each is in front of the other; the share of such pairs is counted
//!   on up to [`FILL_SAMPLES`] patches against all others, so the estimate is an upper bound
//!   on the non-zeros (visibility removes more: the Cornell box keeps about 70 % of its facing
//!   pairs). With refinement the patches are the refinement budget, the most it may make.
//! - **Hierarchical**: memory and time grow with the links the refinement makes, and the
//!   links per root vary several-fold between scenes (a few dozen in a hall, a few hundred in
//!   a detailed game level), so from [`PILOT_MIN_ROOTS`] roots on they are measured: a pilot
//!   solve refines a random sample of the roots for real against a coarse solution of the
//!   whole scene and extrapolates ([`crate::hierarchical::pilot`], a few seconds, a small
//!   share of the solve). The solve's time is then linear in the links and the rays of the
//!   elements' direct light, and the peak memory in the elements plus the larger of the
//!   links (the solve) and the gathered vertices (the gather, after the links are freed)
//!   (constants fitted to the benchmark's bakes; within 2× of the bake on each of them,
//!   BENCHMARKS.md "Large scenes: the estimate against the bake"). A pilot estimates, it does not
//!   bound: the memory guard ([`links_within`]) is what holds a bake to its memory. On smaller
//!   scenes the estimate grows with the roots alone, and with ε as ε^-0.4 (fitted to the generated
//!   halls: within about ±50 % there, but several times low on detailed interiors, so a bake is
//!   warned of when [`HIERARCHICAL_MEMORY_SPREAD`] times it would not fit).
//! - **This machine**: the constants are seconds of the benchmark machine; every modelled
//!   second is scaled by [`super::speed::factor`], a fixed workload's time now over its time
//!   there, so a slower or busier machine gets a longer estimate (the pilot's seconds are
//!   measured, not scaled).
//! - **The final gather**: its time grows with the output vertices (counted on the roots cut
//!   along the contact lines, as the bake cuts them; on a sample of the triangles beyond
//!   [`DISPLAY_SAMPLE`]), its rays, and the lights outside the mesh.

use serde::Serialize;

use super::{Method, Settings};
use crate::distributed::{Exchange, Solo};
use crate::gather::{self, Gather};
pub use crate::hierarchical::pilot::Pilot;
use crate::mesh::{self, refine, Patches};
pub use crate::progress::duration;
use crate::sampling::Rng;
use crate::scene::Scene;
use crate::Result;

/// Roots the hierarchical pilot samples ([`crate::hierarchical::pilot`]): the links per root
/// vary several-fold within a scene, so a sample of this size (drawn as 30–70 subtrees of
/// nearby roots) counts the links within 19 % on the benchmark's scenes.
pub const PILOT_SAMPLE: usize = 2000;

/// Roots from which the hierarchical estimate runs the pilot. Below, the pilot would sample
/// most of the scene (as long as the solve itself), and the estimate counts the roots alone.
pub const PILOT_MIN_ROOTS: usize = 5000;

/// The piloted hierarchical estimate's peak memory: a base (the program, the scene), bytes
/// per element, and the larger of two phases' own: the solve's links (20 bytes each) and the
/// final gather's output vertices (the display mesh, its records and refinement; the links are
/// freed before it). Fitted to the peaks of the LibreQuake levels, the generated offices, halls
/// and a roofless hall under sky and sun, all within 0.90–1.12× (`tools/bench_large.sh`),
/// before the display's own arrays were cut: a gathered scene's peak is now below it (the
/// halls of 10⁵ and 10⁶ triangles at about three quarters), an estimate on the safe side.
const PILOTED_BASE_BYTES: f64 = 75.0 * 1024.0 * 1024.0;
const PILOTED_BYTES_PER_LINK: f64 = 20.0;
const PILOTED_BYTES_PER_ELEMENT: f64 = 800.0;
const PILOTED_BYTES_PER_GATHERED_VERTEX: f64 = 1600.0;
/// The piloted hierarchical solve's seconds on 2 cores: per link (its estimate's rays, the
/// sweeps over it) and per ray of the elements' direct light (many lamps). Fitted as the
/// bytes above, then scaled to the benchmark machine of `tools/bench_large.sh` (the solve
/// took 0.4–0.8× the earlier fit's seconds there).
const PILOTED_SECONDS_PER_LINK: f64 = 2.3e-6;
const PILOTED_SECONDS_PER_DIRECT_RAY: f64 = 0.053e-6;
/// The same for a ray drawn by the light tree over the emitters (very many lamps,
/// [`crate::hierarchical::direct::ShadowRays::Tree`]): the descent's weighing of two nodes a
/// level and the drawn emitter's exact form factor. Measured on the generated hall of 10⁶
/// triangles (7,570 emitting triangles, `--gather none`): the solve with these rays against
/// one whose links carried all emission, less the links' own time at the rate above.
const PILOTED_SECONDS_PER_TREE_DIRECT_RAY: f64 = 0.3e-6;
/// The same per ray of the leaves' final gather ([`crate::hierarchical::regather`]): a
/// closest hit and the leaf it lands in (the generated office of 10⁵ triangles: 0.5–0.6 µs a
/// ray on a machine that took 1.9× the other constants' seconds; scaled to theirs).
const PILOTED_SECONDS_PER_REGATHER_RAY: f64 = 0.3e-6;

/// Patches whose facing pairs are counted to estimate F's fill (every patch when fewer).
pub const FILL_SAMPLES: usize = 256;

/// Bytes per non-zero of F at the peak of a matrix bake with refinement rounds: the matrix a
/// round reuses and the one it builds are both alive (fitted to the Cornell box's peaks at
/// the defaults and at `--max-edge 40`).
const BYTES_PER_ENTRY_REFINED: f64 = 32.0;
/// Bytes per non-zero without refinement (fitted to the Cornell box at a fine `--max-edge`).
const BYTES_PER_ENTRY: f64 = 17.0;
/// Seconds per non-zero on 2 cores, form factors and solve, with refinement rounds (fitted
/// to the Cornell box at the defaults and at `--max-edge 40`, on the machine of
/// `tools/bench_estimate.sh`).
const SECONDS_PER_ENTRY_REFINED: f64 = 115e-9;
/// The same without refinement (fitted to the Cornell box at fine `--max-edge`).
const SECONDS_PER_ENTRY: f64 = 80e-9;
/// Memory of the program, the scene and the patches apart from F, bytes.
const BASE_BYTES: f64 = 40.0 * 1024.0 * 1024.0;
/// Hierarchical bytes per root element at ε = 10⁻⁴ (fitted to the generated halls of 10⁴ to
/// 10⁶ triangles).
const HIERARCHICAL_BYTES_PER_ROOT: f64 = 3.7 * 1024.0;
/// Hierarchical seconds on 2 cores: a fixed part (the direct light at the elements, the
/// clusters) and a part per root at ε = 10⁻⁴ (fitted to the same halls).
const HIERARCHICAL_SECONDS: f64 = 4.0;
const HIERARCHICAL_SECONDS_PER_ROOT: f64 = 140e-6;
/// How far above its estimate the hierarchical method's peak memory may be without a pilot
/// (fewer than [`PILOT_MIN_ROOTS`] roots): several times on LibreQuake's detailed interiors
/// (BENCHMARKS.md "A Quake-class level: LibreQuake"), which link each element to many more
/// than the generated halls the model was fitted to; the largest such ratio seen, with a
/// margin. A bake whose estimate fits but whose estimate times this does not is warned of
/// before it starts.
pub const HIERARCHICAL_MEMORY_SPREAD: f64 = 5.5;
/// How far above a piloted estimate the hierarchical peak memory may be: the pilots' counts
/// and the fitted bytes came within 30 % of the bakes' peaks on the benchmark's scenes; twice
/// that, with a margin.
pub const PILOTED_MEMORY_SPREAD: f64 = 2.0;
/// Leaves per root at ε = 10⁻⁴ (the generated halls at the defaults).
const LEAVES_PER_ROOT: f64 = 2.0;
/// Seconds on 2 cores of the `full` final gather and its display refinement per hemisphere
/// ray, and per unit of the direct light's cost at a point as the gather prices it in
/// hemisphere rays ([`gather_direct_cost`]: it costs about 5× that price). Two constants fitted
/// to two bakes, the Cornell box (one light) and the generated hall of 10⁴ triangles
/// (82 emitting triangles): the rays and the direct light dominate one each.
const GATHER_SECONDS_PER_RAY: f64 = 0.21e-6;
const GATHER_SECONDS_PER_DIRECT: f64 = 1.2e-6;
/// Seconds on 2 cores of the `cache` gather and its display refinement
/// ([`gather::refine::budget_for`]) per output vertex counted on the roots
/// ([`Estimate::vertices`]): the records' hemisphere rays and what every vertex's direct light
/// costs apart from its emitters (the sun's rays alone: the roofless hall of 10⁵ triangles
/// under sky and sun, 4.5e-5 measured), plus per vertex and per unit of the emitters' cost at a
/// point as the gather prices it ([`gather_direct_cost`]): their exact visible pieces among
/// the occluders. Fitted between the generated office (large sky panels seen past desks and
/// chairs, 3.0–3.5e-4 a vertex) and the generated hall of 10⁵ triangles (small panels,
/// 1.7e-4), both of cost 48 (`tools/bench_large.sh`).
const GATHER_CACHE_SECONDS_PER_VERTEX: f64 = 0.43e-4;
const GATHER_CACHE_SECONDS_PER_DIRECT: f64 = 3.9e-6;
/// The records' hemisphere rays in the bakes the two constants above were fitted to; the
/// records' rays past these ([`gather::cache::RAY_BUDGET`] is a fixed total, spent whenever
/// there are more than a few thousand records) cost [`GATHER_CACHE_SECONDS_PER_RECORD_RAY`]
/// each on 2 cores: the office's bake with 8·10⁶ record rays against 4·10⁶ (`farm-bench -n 2
/// --vs`), 6.6 s longer at 2.24× the reference machine's time.
const FITTED_RECORD_RAYS: f64 = 4.0e6;
const GATHER_CACHE_SECONDS_PER_RECORD_RAY: f64 = 0.74e-6;
/// The share of [`GATHER_CACHE_SECONDS_PER_VERTEX`] left without the display refinement: the
/// refinement's new vertices and tests evaluate the direct light about as many times as the
/// gather did ([`gather::refine::CACHE_REFINE_SHARE`]).
const CACHE_UNREFINED_SHARE: f64 = 0.5;
/// Seconds on 2 cores per shadow ray to a light outside the mesh (a point or spot light, or
/// the sun's [`crate::light::outside::SUN_RAYS`]) at an output vertex: every vertex of the gather
/// and of its display refinement casts one to each, weighs a level's lamps to choose them
/// ([`crate::light::outside::EXACT_LIGHTS`]) and draws more at its near hits. Fitted between
/// two LibreQuake levels of 673 and 489 lamps (2.8e-6 and 1.2e-6 measured).
const GATHER_SECONDS_PER_LIGHT_RAY: f64 = 1.8e-6;

/// The estimate; see the module documentation.
#[derive(Debug, Clone, Serialize)]
pub struct Estimate {
    /// The method the bake will take (`auto` resolved).
    pub method: Method,
    /// Longest patch edge, scene units (the matrix method's default, the diagonal / 16; the
    /// hierarchical method's roots are the input triangles unless `--max-edge` is given).
    pub max_edge: f64,
    /// Matrix: patches of the first solve (counted exactly); hierarchical: root elements.
    pub patches: usize,
    /// Matrix: the most patches refinement may make (the budget; the patches without
    /// refinement); hierarchical: leaves estimated.
    pub max_patches: usize,
    /// How much finer than the scene's default the patches are asked to be, by area
    /// ([`super::Settings::finer`], ≥ 1).
    pub finer: f64,
    /// Hierarchical: ε as the solver takes it (the given one divided by `finer`); `None` for
    /// the matrix method.
    pub epsilon: Option<f64>,
    /// Matrix: the share of ordered pairs of patches that face each other, in [0, 1] (an upper
    /// bound on F's fill); `None` for the hierarchical method.
    pub facing_fraction: Option<f64>,
    /// Matrix: the most non-zeros F can have at `max_patches`.
    pub max_entries: Option<f64>,
    /// Output vertices before the display refinement: counted on the roots (hierarchical) or
    /// the first patches (matrix; scaled by `max_patches` over `patches` when refinement may
    /// add patches), as the bake shares them out ([`crate::bake::bake_sites`]). What the final
    /// gather's choice and its cost go by.
    pub vertices: usize,
    /// The final gather `auto` will run.
    pub gather: Gather,
    /// Hierarchical: the regions of the display's cut leaves that gather their share of the
    /// leaf's light before the vertices gather ([`crate::gather::pieces`]); 0 otherwise.
    pub shared_regions: usize,
    /// Peak memory, bytes (matrix: an upper bound; hierarchical: an estimate, see the module).
    pub memory_bytes: f64,
    /// Wall-clock seconds on `threads` threads (scaled from 2 cores; see the module).
    pub seconds: f64,
    /// The final gather's and its display refinement's part of `seconds`.
    pub gather_seconds: f64,
    /// Worker threads the estimate is for.
    pub threads: usize,
    /// This machine's speed now against the one the constants were fitted on
    /// ([`super::speed::factor`]; > 1 slower): the modelled seconds are scaled by it (the
    /// pilot's are measured).
    pub speed: f64,
    /// Hierarchical, on scenes of [`PILOT_MIN_ROOTS`] roots or more: what the pilot solve
    /// measured ([`crate::hierarchical::pilot`]), from which the memory and the solve's time
    /// are estimated (absent from JSON without one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pilot: Option<Pilot>,
}

impl Estimate {
    /// The estimate of a bake of `scene` with `settings` on `threads` worker threads.
    pub fn of(scene: &Scene, settings: &Settings, threads: usize) -> Result<Estimate> {
        Estimate::of_on(scene, settings, threads, &Solo)
    }

    /// [`Estimate::of`] as one rank of `comm` ([`crate::distributed`]): every rank calls it
    /// alike and gets the same estimate; the pilot solve is shared among the ranks as the
    /// bake's solve is. `threads`: all the ranks' threads.
    pub fn of_on(
        scene: &Scene,
        settings: &Settings,
        threads: usize,
        comm: &dyn Exchange,
    ) -> Result<Estimate> {
        Estimate::with_pilot(scene, settings, threads, None, comm)
    }

    /// [`Estimate::of`] with the links and elements of an earlier `pilot` of the same scene
    /// (scaled to this ε as ε^-0.4) instead of a pilot of its own.
    fn with_pilot(
        scene: &Scene,
        settings: &Settings,
        threads: usize,
        reuse: Option<&Pilot>,
        comm: &dyn Exchange,
    ) -> Result<Estimate> {
        settings.validate()?;
        let s = settings.resolved(scene)?;
        let sides = if s.two_sided && !scene.is_two_sided() {
            2
        } else {
            1
        };
        // The model's seconds are the benchmark machine's on 2 cores: scaled to `threads`,
        // and to this machine's speed now, the same on every rank (the slowest's).
        let speed = f64::from_bits(comm.max_u64(super::speed::factor().to_bits()));
        let per_core = speed * 2.0 / threads.max(1) as f64;
        let finer = s.finer(scene);
        let mut e = match s.method {
            Method::Hierarchical => {
                let (lo, hi) = scene.bounds();
                let max_edge = s.max_edge.unwrap_or((hi - lo).length());
                let root_patches = mesh::subdivide(scene, max_edge, s.crease_degrees)?;
                let roots = sides * root_patches.len();
                let pilot = match reuse {
                    Some(p) => Some(*p),
                    None if roots >= PILOT_MIN_ROOTS => {
                        Some(run_pilot(scene, &s, max_edge, &root_patches, comm)?)
                    }
                    None => None,
                };
                let (uncut, vertices, shared_regions) = display_vertices(scene, &s, &root_patches);
                let vertices = sides * vertices;
                // `auto` decides on the display before its lines cut it, as the bake does.
                let gather = s.gather.resolve(sides * uncut, s.gather_rays.is_some());
                let gathered_bytes = if gather == Gather::None {
                    0.0
                } else {
                    // The default display refinement is in the fitted bytes per vertex; a
                    // raised budget (--display-budget) adds its further vertices.
                    let more = if s.gather_tolerance > 0.0 && s.display_budget > 1.0 {
                        let rays = s
                            .gather_rays
                            .map_or_else(|| gather::auto_rays(vertices, finer), |r| r as usize);
                        let direct = gather_direct_cost(scene) as usize;
                        let budget = gather::refine::budget_for(gather, rays, direct, vertices);
                        (gather::refine::scaled(budget, s.display_budget) - budget) as f64
                    } else {
                        0.0
                    };
                    PILOTED_BYTES_PER_GATHERED_VERTEX * (vertices as f64 + more)
                };
                // The links and elements grow about as ε^-0.4 (the generated hall of 10⁴
                // triangles between ε = 10⁻⁴ and 10⁻⁵).
                let (leaves, memory, solve) = match &pilot {
                    Some(p) => {
                        let k = (p.epsilon / s.hierarchical.epsilon).powf(0.4);
                        let (links, grown) = (p.links * k, (p.elements - roots as f64) * k);
                        let direct_rays =
                            p.direct_rays * (roots as f64 + grown) / p.elements.max(1.0);
                        let per_direct_ray = if p.direct_by_tree {
                            PILOTED_SECONDS_PER_TREE_DIRECT_RAY
                        } else {
                            PILOTED_SECONDS_PER_DIRECT_RAY
                        };
                        let leaves = roots + (0.75 * grown) as usize;
                        let regather_rays = (crate::hierarchical::regather::STEPS
                            * leaves
                            * crate::hierarchical::regather::rays_per_leaf(
                                leaves,
                                s.hierarchical.regather_rays as usize,
                            )) as f64;
                        (
                            leaves,
                            PILOTED_BASE_BYTES
                                + PILOTED_BYTES_PER_ELEMENT * (roots as f64 + grown)
                                + (PILOTED_BYTES_PER_LINK * links).max(gathered_bytes),
                            PILOTED_SECONDS_PER_LINK * links
                                + per_direct_ray * direct_rays
                                + PILOTED_SECONDS_PER_REGATHER_RAY * regather_rays,
                        )
                    }
                    None => {
                        let growth = (1e-4 / s.hierarchical.epsilon).powf(0.4);
                        (
                            (LEAVES_PER_ROOT * roots as f64 * growth) as usize,
                            BASE_BYTES + HIERARCHICAL_BYTES_PER_ROOT * roots as f64 * growth,
                            HIERARCHICAL_SECONDS
                                + HIERARCHICAL_SECONDS_PER_ROOT * roots as f64 * growth,
                        )
                    }
                };
                Estimate {
                    method: Method::Hierarchical,
                    max_edge,
                    patches: roots,
                    max_patches: leaves,
                    finer,
                    epsilon: Some(s.hierarchical.epsilon),
                    shared_regions: sides * shared_regions,
                    facing_fraction: None,
                    max_entries: None,
                    vertices,
                    gather,
                    memory_bytes: memory,
                    seconds: solve * per_core + pilot.as_ref().map_or(0.0, |p| p.seconds),
                    threads,
                    speed,
                    gather_seconds: 0.0,
                    pilot,
                }
            }
            _ => {
                let max_edge = s.max_edge.unwrap_or_else(|| mesh::default_max_edge(scene));
                let split = s.cuts_contacts().then(|| mesh::split_contacts(scene).0);
                let cut = split.as_ref().unwrap_or(scene);
                let patches = mesh::subdivide(cut, max_edge, s.crease_degrees)?;
                let n = sides * patches.len();
                let refined = s.refine_rounds > 0;
                let max_patches = if refined {
                    s.refine_max_patches
                        .unwrap_or_else(|| refine::default_budget(n))
                } else {
                    n
                };
                let facing = facing_fraction(&patches);
                let first = sides * output_vertices(&patches, s.crease_degrees, &[]);
                let vertices =
                    (first as f64 * max_patches as f64 / n.max(1) as f64).round() as usize;
                let m = max_patches as f64;
                let mut entries = facing * m * m;
                if s.form_factors.estimator == crate::form_factor::Estimator::Hemisphere {
                    entries = entries.min(m * s.form_factors.rays as f64);
                }
                let (bytes, secs) = if refined {
                    (BYTES_PER_ENTRY_REFINED, SECONDS_PER_ENTRY_REFINED)
                } else {
                    (BYTES_PER_ENTRY, SECONDS_PER_ENTRY)
                };
                Estimate {
                    method: Method::Matrix,
                    max_edge,
                    patches: n,
                    max_patches,
                    finer,
                    epsilon: None,
                    shared_regions: 0,
                    facing_fraction: Some(facing),
                    max_entries: Some(entries),
                    vertices,
                    gather: s.gather.resolve(vertices, s.gather_rays.is_some()),
                    memory_bytes: BASE_BYTES + bytes * entries,
                    seconds: secs * entries * per_core,
                    threads,
                    speed,
                    gather_seconds: 0.0,
                    pilot: None,
                }
            }
        };
        let neumann = s.solver.method == crate::solve::Method::Neumann;
        if neumann || !(scene.has_emitters() || s.environment.is_lit()) {
            e.gather = Gather::None;
        }
        let before_gather = e.seconds;
        if e.gather != Gather::None {
            let vertices = e.vertices;
            // The cut leaves' regions: a `full` gather each at the shares' rays.
            e.seconds += e.shared_regions as f64
                * (GATHER_SECONDS_PER_RAY * gather::pieces::PIECE_RAYS as f64
                    + GATHER_SECONDS_PER_DIRECT * gather_direct_cost(scene))
                * per_core;
            if e.gather == Gather::Cache {
                // The refinement's part grows with its budget (--display-budget).
                let share = if s.gather_tolerance > 0.0 {
                    CACHE_UNREFINED_SHARE + (1.0 - CACHE_UNREFINED_SHARE) * s.display_budget
                } else {
                    CACHE_UNREFINED_SHARE
                };
                let per_vertex = GATHER_CACHE_SECONDS_PER_VERTEX
                    + GATHER_CACHE_SECONDS_PER_DIRECT * gather_direct_cost(scene);
                // The records' rays grow with the share of the light they bring
                // (`gather::cache::budget_factor`, known only once they are placed): all but
                // the sun's where no triangle emits, the most it gives.
                let factor = if scene.has_emitters() {
                    1.0
                } else {
                    gather::cache::MAX_BUDGET_FACTOR
                };
                let records = (gather::cache::RAY_BUDGET as f64 * factor - FITTED_RECORD_RAYS)
                    * GATHER_CACHE_SECONDS_PER_RECORD_RAY;
                e.seconds += (per_vertex * share * vertices as f64 + records) * per_core;
            } else {
                // In hemisphere rays: at each vertex its rays, the rays beside edges
                // ([`gather::EDGE_RAYS`]) and its direct light; then the display refinement's
                // new vertices (its budget) and their midpoint tests, each with the direct
                // light again.
                let rays = s
                    .gather_rays
                    .map_or_else(|| gather::auto_rays(vertices, e.finer), |r| r as usize);
                let direct = gather_direct_cost(scene);
                let r = rays as f64;
                let mut traced = vertices as f64 * r * (1.0 + gather::EDGE_RAYS);
                let mut points = vertices as f64;
                if s.gather_tolerance > 0.0 {
                    let added = gather::refine::scaled(
                        gather::refine::budget(rays, direct as usize),
                        s.display_budget,
                    ) as f64;
                    let tests = gather::refine::TESTS_PER_NEW_VERTEX as f64;
                    traced += added * (r + tests * gather::refine::TEST_RAYS as f64);
                    points += added * (1.0 + tests);
                }
                e.seconds += (GATHER_SECONDS_PER_RAY * traced
                    + GATHER_SECONDS_PER_DIRECT * direct * points)
                    * per_core;
            }
            // The lights outside the mesh: a shadow ray each at every output vertex and at
            // every vertex the display refinement adds (the bake's own refinement budget).
            let light_rays = s.environment.sharp_rays();
            if light_rays > 0 {
                let hemisphere = match e.gather {
                    Gather::Full | Gather::Cache => gather::auto_rays(vertices, e.finer),
                    _ => 0,
                };
                let refined = if s.gather_tolerance > 0.0 {
                    gather::refine::scaled(
                        gather::refine::budget_for(e.gather, hemisphere, light_rays, vertices),
                        s.display_budget,
                    )
                } else {
                    0
                };
                e.seconds += GATHER_SECONDS_PER_LIGHT_RAY
                    * (light_rays * (vertices + refined)) as f64
                    * per_core;
            }
        }
        e.gather_seconds = e.seconds - before_gather;
        Ok(e)
    }

    /// The method and its patches: "matrix, 4004 patches refined to at most 8008".
    pub fn what(&self) -> String {
        match self.method {
            Method::Hierarchical => format!(
                "hierarchical, {} root elements, about {} leaves",
                self.patches, self.max_patches
            ),
            _ if self.max_patches > self.patches => format!(
                "matrix, {} patches refined to at most {}",
                self.patches, self.max_patches
            ),
            _ => format!("matrix, {} patches", self.patches),
        }
    }

    /// One line: the method, the patches, the memory and the time.
    pub fn summary(&self) -> String {
        let bound = if self.method == Method::Hierarchical {
            "about"
        } else {
            "at most about"
        };
        format!(
            "{}; {bound} {} and {} on {} thread{}",
            self.what(),
            bytes(self.memory_bytes),
            duration(self.seconds),
            self.threads,
            if self.threads == 1 { "" } else { "s" }
        )
    }

    /// How far above this estimate the peak memory may be ([`PILOTED_MEMORY_SPREAD`],
    /// [`HIERARCHICAL_MEMORY_SPREAD`]; 1 for the matrix method's bound).
    pub fn memory_spread(&self) -> f64 {
        match (self.method, &self.pilot) {
            (Method::Hierarchical, Some(_)) => PILOTED_MEMORY_SPREAD,
            (Method::Hierarchical, None) => HIERARCHICAL_MEMORY_SPREAD,
            _ => 1.0,
        }
    }

    /// What would make this bake smaller, as options.
    pub fn remedies(&self) -> &'static str {
        match self.method {
            Method::Hierarchical => "a larger --epsilon or --min-area, or a larger --max-edge",
            _ => "a larger --max-edge, a smaller --refine-max-patches, or --method hierarchical",
        }
    }
}

/// What the `full` gather's direct light costs at a point, in hemisphere rays, as the gather
/// prices it ([`gather::emitters_cost`]; the lights outside the mesh are counted apart), the
/// scene's emitting triangles standing for its emitters.
fn gather_direct_cost(scene: &Scene) -> f64 {
    let emitters = scene
        .triangles
        .iter()
        .filter(|t| {
            scene
                .materials
                .get(t.material as usize)
                .is_some_and(crate::scene::Material::is_emitter)
        })
        .count();
    gather::emitters_cost(emitters) as f64
}

/// The pilot of the hierarchical solve of `scene` ([`crate::hierarchical::pilot`]), on the
/// roots the bake will make (resolved settings `s`, roots cut to `max_edge`).
fn run_pilot(
    scene: &Scene,
    s: &Settings,
    max_edge: f64,
    plain: &Patches,
    comm: &dyn Exchange,
) -> Result<Pilot> {
    // The roots as the bake makes them ([`super::solve_scene`]); `plain` (the scene's own,
    // cut to `max_edge`) when neither contacts nor back sides change them.
    let split = s.cuts_contacts().then(|| mesh::split_contacts(scene).0);
    let two = s
        .two_sided
        .then(|| split.as_ref().unwrap_or(scene).to_two_sided());
    let made = match two.as_ref().or(split.as_ref()) {
        Some(cut) => Some(mesh::subdivide(cut, max_edge, s.crease_degrees)?),
        None => None,
    };
    crate::hierarchical::pilot::pilot_on(
        made.as_ref().unwrap_or(plain),
        &s.hierarchical,
        &s.environment,
        &s.solver,
        s.form_factors.seed,
        PILOT_SAMPLE,
        comm,
    )
}

/// The largest factor `--max-time` may raise ε by ([`fit_time`]).
pub const MAX_EPSILON_RAISE: f64 = 16.0;

/// Settings a bake of `scene` with `settings` on `threads` threads is estimated to finish
/// within `budget` seconds with, their estimate, and what was changed, in a sentence (`None`
/// when nothing had to be). The coarsenings are tried in order of what they cost the picture least,
/// each on top of the last, until the estimate fits: ε doubled (hierarchical; the solve's links and
/// elements, at most [`MAX_EPSILON_RAISE`]×), or no refinement rounds (matrix); then no display
/// refinement (`--gather-tolerance 0`); then `--gather direct` (the indirect light from the
/// solution); then `--gather none` (the solution's own patches). If none fits, the cheapest is
/// taken and the sentence says the estimate is still over. The estimate is only an estimate: the
/// bake's refinements also stop where their share of the budget is spent ([`super::SOLVE_SHARE`],
/// [`super::DISPLAY_SHARE`]).
pub fn fit_time(
    scene: &Scene,
    settings: &Settings,
    threads: usize,
    budget: f64,
) -> Result<(Settings, Estimate, Option<String>)> {
    fit_time_on(scene, settings, threads, budget, &Solo)
}

/// [`fit_time`] as one rank of `comm` (see [`Estimate::of_on`]).
pub fn fit_time_on(
    scene: &Scene,
    settings: &Settings,
    threads: usize,
    budget: f64,
    comm: &dyn Exchange,
) -> Result<(Settings, Estimate, Option<String>)> {
    let first = Estimate::of_on(scene, settings, threads, comm)?;
    if first.seconds <= budget {
        return Ok((settings.clone(), first, None));
    }
    let mut s = settings.clone();
    let mut changes: Vec<String> = Vec::new();
    let mut e = first.clone();
    // A display budget raised past the default is the first to give way.
    if s.display_budget > 1.0 && e.gather != Gather::None && s.gather_tolerance > 0.0 {
        s.display_budget = 1.0;
        e = Estimate::with_pilot(scene, &s, threads, first.pilot.as_ref(), comm)?;
        changes.push("--display-budget 1".into());
    }
    if e.method == Method::Hierarchical {
        let mut raise = 1.0;
        while e.seconds > budget && raise < MAX_EPSILON_RAISE {
            raise *= 2.0;
            s.hierarchical.epsilon = settings.hierarchical.epsilon * raise;
            e = Estimate::with_pilot(scene, &s, threads, first.pilot.as_ref(), comm)?;
        }
        if raise > 1.0 {
            changes.push(format!(
                "--epsilon {:.3e} ({raise}×)",
                s.hierarchical.epsilon
            ));
        }
    } else if s.refine_rounds > 0 {
        s.refine_rounds = 0;
        e = Estimate::of_on(scene, &s, threads, comm)?;
        changes.push("--refine 0".into());
    }
    if e.seconds > budget && e.gather != Gather::None && s.gather_tolerance > 0.0 {
        s.gather_tolerance = 0.0;
        e = Estimate::with_pilot(scene, &s, threads, e.pilot.as_ref(), comm)?;
        changes.push("--gather-tolerance 0".into());
    }
    if e.seconds > budget && matches!(e.gather, Gather::Full | Gather::Cache) {
        s.gather = Gather::Direct;
        e = Estimate::with_pilot(scene, &s, threads, e.pilot.as_ref(), comm)?;
        changes.push("--gather direct".into());
    }
    if e.seconds > budget && e.gather != Gather::None {
        s.gather = Gather::None;
        e = Estimate::with_pilot(scene, &s, threads, e.pilot.as_ref(), comm)?;
        changes.push("--gather none".into());
    }
    let fits = if e.seconds <= budget {
        "fits".to_string()
    } else {
        "is still over; the refinements stop where their share of the budget is spent".into()
    };
    let sentence = format!(
        "the estimate, {}, is over --max-time {}: baking with {}, whose estimate, {}, {fits}",
        duration(first.seconds),
        duration(budget),
        if changes.is_empty() {
            "the same settings".to_string()
        } else {
            changes.join(", ")
        },
        duration(e.seconds)
    );
    Ok((s, e, Some(sentence)))
}

/// Bytes of the peak memory that go with each hierarchical link: the 20-byte link, and in
/// proportion the elements, clusters and refinement buffers that grow with them (the peaks
/// of the LibreQuake levels and the hall of 10⁶ triangles, whose links dominate their memory,
/// were 60–71 bytes a link when a link took 24 bytes and the refinement and sweeps kept
/// larger buffers; BENCHMARKS.md "Large scenes: the estimate against the bake"). The guard
/// is on the safe side since.
pub const PEAK_BYTES_PER_LINK: f64 = 72.0;

/// The most hierarchical links a bake may make within `limit` bytes of memory
/// ([`crate::hierarchical::Settings::max_links`]): what is left after the program's own
/// base, at [`PEAK_BYTES_PER_LINK`] each. Refinement stops there with a warning, so a scene
/// that links far more than its estimate (a detailed interior) ends with a coarser solution
/// instead of running out of memory.
pub fn links_within(limit: f64) -> u64 {
    ((limit - BASE_BYTES).max(0.0) / PEAK_BYTES_PER_LINK) as u64
}

/// The output vertices of a hierarchical bake before any display refinement, counted on its
/// root `patches` as the bake shares them out: cut along the scene's contact lines (and the
/// lamps' and the sun's penumbra lines, [`mesh::display_lines_on`]) first where the bake's
/// display will be ([`mesh::split_patches`]; `discontinuities = auto` with a final gather),
/// which on detailed interiors (brushes meeting walls and floors) makes 1.2–2.3×
/// the roots' vertices, the pieces buried under another surface apart from the seen ones
/// ([`crate::gather::buried_patches`]). The leaves add more where the solve splits roots; they
/// are not known before it. Returns the vertices before the cut and after it, and the
/// regions of the leaves the cut crosses ([`crate::gather::pieces`]).
fn display_vertices(scene: &Scene, s: &Settings, patches: &Patches) -> (usize, usize, usize) {
    let plain = output_vertices(patches, s.crease_degrees, &[]);
    let lit = scene.has_emitters() || s.environment.is_lit();
    let gathered = s.gather.resolve(plain, s.gather_rays.is_some()) != Gather::None;
    if s.discontinuities != mesh::Discontinuities::Auto || !lit || !gathered {
        return (plain, plain, 0);
    }
    // The contact lines of a sample of the triangles, and the lamp and sun lines their edges cast:
    // the vertices their cuts add, scaled up (at 10⁶ triangles all of them take as long as
    // the rest of the estimate).
    let p = (DISPLAY_SAMPLE as f64 / scene.triangles.len().max(1) as f64).min(1.0);
    let seed = s.form_factors.seed;
    let on = |t: usize| p >= 1.0 || Rng::new(&[seed, t as u64, 0xC0_7AC7]).next_f64() < p;
    let lines = mesh::display_lines_on(scene, super::sun_disc(&s.environment), &on);
    let cut = lines.and_then(|lines| {
        let (lo, hi) = scene.bounds();
        mesh::split_patches(&lines.lines, patches, (hi - lo).length())
    });
    match cut {
        Some(split) => {
            // The cut's buried pieces have their own vertices at its lines, as in the bake.
            let buried = crate::gather::buried_patches(scene, &split.patches);
            let added =
                output_vertices(&split.patches, s.crease_degrees, &buried).saturating_sub(plain);
            let shared = crate::gather::pieces::shared_regions(
                &split.parent,
                &split.region,
                &split.patches.area,
                &buried,
            );
            let scale = |n: usize| (n as f64 / p).round() as usize;
            (plain, plain + scale(added), scale(shared.len()))
        }
        None => (plain, plain, 0),
    }
}

/// Triangles whose contact lines the estimate finds, at most (for the display's vertices): on
/// more, a random sample of this many stands for all (every one below).
pub const DISPLAY_SAMPLE: usize = 20_000;

/// The output vertices of a bake of `patches` before any display refinement: the sites
/// [`crate::bake::bake_sites_apart`] makes at the crease angle, the `buried` patches (empty:
/// none) apart.
fn output_vertices(patches: &Patches, crease_degrees: f64, buried: &[bool]) -> usize {
    let dark = vec![[0.0; 3]; patches.len()];
    crate::bake::bake_sites_apart(patches, &dark, crease_degrees, &[], buried)
        .1
        .len()
}

/// The share of ordered pairs (i, j ≠ i) of patches that face each other (each centroid in
/// front of the other's plane), counted from up to [`FILL_SAMPLES`] patches i spread evenly
/// over the list, against every j: F_ij can be non-zero only for such pairs.
pub fn facing_fraction(patches: &Patches) -> f64 {
    let n = patches.len();
    if n < 2 {
        return 0.0;
    }
    let step = n.div_ceil(FILL_SAMPLES).max(1);
    let (mut facing, mut pairs) = (0u64, 0u64);
    for i in (0..n).step_by(step) {
        let (ci, ni) = (patches.centroid[i], patches.normal[i]);
        for j in 0..n {
            if j == i {
                continue;
            }
            let d = patches.centroid[j] - ci;
            if d.dot(ni) > 0.0 && d.dot(patches.normal[j]) < 0.0 {
                facing += 1;
            }
        }
        pairs += (n - 1) as u64;
    }
    facing as f64 / pairs as f64
}

/// The memory the machine has available now (Linux `MemAvailable`), bytes; `None` elsewhere.
pub fn available_memory() -> Option<f64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024.0)
}

/// Bytes in binary units: "397 MiB", "3.1 GiB".
pub fn bytes(b: f64) -> String {
    const MIB: f64 = 1024.0 * 1024.0;
    if b >= 1024.0 * MIB {
        format!("{:.1} GiB", b / (1024.0 * MIB))
    } else {
        format!("{:.0} MiB", (b / MIB).max(1.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::validation::scenes;

    #[test]
    fn facing_pairs_of_a_closed_box_and_of_parallel_plates() {
        // Two parallel plates facing each other: every pair across the gap faces, no pair
        // within a plate does (coplanar: neither is in front of the other).
        let plates = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        let p = mesh::subdivide(&plates, 0.25, 30.0).unwrap();
        let n = p.len() as f64;
        let half = n / 2.0;
        let expected = half * half * 2.0 / (n * (n - 1.0));
        assert!((facing_fraction(&p) - expected).abs() < 1e-12);
        // The furnace room without its boxes is a cube seen from inside: a pair faces unless
        // both lie on the same wall, so 5/6 of the pairs face (less the same-wall pairs'
        // share of the n - 1 partners).
        let cube = scenes::furnace_room(0.5, 1.0).unwrap();
        let p = mesh::subdivide(&cube, 0.3, 30.0).unwrap();
        let f = facing_fraction(&p);
        assert!(f > 0.3 && f < 5.0 / 6.0, "{f}");
    }

    #[test]
    fn the_estimate_follows_the_method_and_the_budget() {
        let scene = scenes::furnace_room(0.5, 1.0).unwrap();
        let matrix = Settings {
            method: Method::Matrix,
            max_edge: Some(0.1),
            ..Settings::default()
        };
        let e = Estimate::of(&scene, &matrix, 2).unwrap();
        assert_eq!(e.method, Method::Matrix);
        assert_eq!(e.max_patches, refine::default_budget(e.patches));
        let entries = e.max_entries.unwrap();
        let m = e.max_patches as f64;
        assert!(entries > 0.0 && entries <= m * m);
        // Twice the threads, half the time; no refinement, fewer patches and less memory.
        let e4 = Estimate::of(&scene, &matrix, 4).unwrap();
        assert!((e4.seconds - e.seconds / 2.0).abs() < 1e-9 * e.seconds);
        let plain = Settings {
            refine_rounds: 0,
            ..matrix.clone()
        };
        let e0 = Estimate::of(&scene, &plain, 2).unwrap();
        assert_eq!(e0.max_patches, e0.patches);
        assert!(e0.memory_bytes < e.memory_bytes);
        // The model's seconds (no pilot, no gather) are the fitted machine's on 2 cores times
        // this machine's speed, the same for every estimate of a process.
        let bare = Settings {
            gather: Gather::None,
            ..plain.clone()
        };
        let b0 = Estimate::of(&scene, &bare, 2).unwrap();
        assert_eq!(b0.speed, super::super::speed::factor());
        assert_eq!(b0.gather_seconds, 0.0);
        let fitted = SECONDS_PER_ENTRY * b0.max_entries.unwrap();
        assert!((b0.seconds - fitted * b0.speed).abs() <= 1e-9 * b0.seconds);
        // The hierarchy: a smaller ε, more leaves, memory and time.
        let h = |epsilon| Settings {
            method: Method::Hierarchical,
            hierarchical: crate::hierarchical::Settings {
                epsilon,
                ..Default::default()
            },
            ..Settings::default()
        };
        let coarse = Estimate::of(&scene, &h(1e-4), 2).unwrap();
        let fine = Estimate::of(&scene, &h(1e-6), 2).unwrap();
        assert_eq!(coarse.patches, scene.triangles.len());
        assert!(coarse.facing_fraction.is_none());
        assert!(fine.max_patches > coarse.max_patches);
        assert!(fine.memory_bytes > coarse.memory_bytes && fine.seconds > coarse.seconds);
        assert!(e.summary().contains("matrix") && fine.summary().contains("hierarchical"));
        // The gather's part: some of the time with a gather, none without one.
        assert!(e.gather_seconds > 0.0 && e.gather_seconds < e.seconds);
        let bare = Settings {
            gather: Gather::None,
            ..matrix.clone()
        };
        let b = Estimate::of(&scene, &bare, 2).unwrap();
        assert_eq!(b.gather_seconds, 0.0);
        assert!((b.seconds - (e.seconds - e.gather_seconds)).abs() < 1e-9 * e.seconds);
    }

    #[test]
    fn units_read_as_people_write_them() {
        assert_eq!(bytes(397.0 * 1024.0 * 1024.0), "397 MiB");
        assert_eq!(bytes(3.1 * 1024.0 * 1024.0 * 1024.0), "3.1 GiB");
        assert_eq!(duration(4.4), "4 s");
        assert_eq!(duration(751.0), "12.5 min");
        assert_eq!(duration(7200.0), "2.0 h");
    }
}
