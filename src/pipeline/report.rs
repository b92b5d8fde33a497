//! The run report: counts, counters and seconds per stage, written as JSON by `--report` and
//! summarised in one line on stderr, and the verbose notes of each solve and refinement
//! round. This module owns the report's shape and wording, not its numbers.

use std::path::Path;

use serde::Serialize;

use super::Settings;
use crate::form_factor;
use crate::mesh::Patches;
use crate::solve::Solution;
use crate::{io, Result};

/// Wall-clock seconds spent in each stage.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Seconds {
    pub load: f64,
    pub patches: f64,
    pub bvh: f64,
    pub form_factors: f64,
    pub solve: f64,
    pub bake: f64,
    /// The final gather at the output vertices (0 for `gather = none`).
    pub gather: f64,
    pub write: f64,
}

impl Seconds {
    /// Sum of all stages.
    pub fn total(&self) -> f64 {
        self.load
            + self.patches
            + self.bvh
            + self.form_factors
            + self.solve
            + self.bake
            + self.gather
            + self.write
    }
}

/// Everything a run reports.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub version: &'static str,
    pub input: Option<String>,
    pub output: Option<String>,
    /// Material overrides applied to the scene after loading, in order, as command-line
    /// options (`--emission light=0,0,0`); empty when there were none.
    pub overrides: Vec<String>,
    /// Triangles in the input after triangulation and cleaning.
    pub input_triangles: usize,
    /// What repairing the faces' orientation turned (`orient = auto`; `None` when it did
    /// not run).
    pub orientation: Option<crate::scene::orient::Orientation>,
    /// What making the contact lines edges did (`discontinuities = contacts`).
    pub contacts: Option<crate::mesh::ContactStats>,
    /// What cutting the display's faces along the contact lines did (the hierarchical
    /// method with `discontinuities = auto` and a final gather, [`crate::mesh::split_patches`]):
    /// `triangles` counts the display's faces after the cut.
    pub display_contacts: Option<crate::mesh::ContactStats>,
    /// The lamps' penumbra lines cut into the display with the contact lines
    /// ([`crate::mesh::discontinuity::lamp`]), before they are clipped to the faces: two per
    /// run of an edge's shadow of one lamp on one plane.
    pub lamp_lines: usize,
    /// The sun's penumbra lines cut into the display with the contact lines
    /// ([`crate::mesh::sun_lines`]), before they are clipped to the faces: two per run of
    /// an edge's shadow on one plane.
    pub sun_lines: usize,
    /// Longest patch edge used, scene units.
    pub max_edge: f64,
    /// Patches of the final solve (after refinement).
    pub patches: usize,
    /// Adaptive refinement rounds performed (each split patches and solved again).
    pub refine_rounds: u32,
    /// What the bake was estimated to cost before it started ([`super::Estimate`]; `None`
    /// when the scene was solved in memory, without [`super::run`]).
    pub estimate: Option<super::Estimate>,
    /// The most patches refinement was allowed to make (`--refine-max-patches`, by default
    /// [`crate::mesh::refine::default_budget`]); 0 with the hierarchical method.
    pub refine_budget: usize,
    /// True when refinement left marked patches unsplit to stay within `refine_budget`.
    pub refine_capped: bool,
    /// Vertices of the output mesh (after splitting at creases and material borders, and the
    /// display refinement).
    pub vertices: usize,
    /// The final gather that ran at the output vertices (`gather = auto` resolved:
    /// [`crate::gather::Gather::resolve`]; `none` when none ran).
    pub gather: crate::gather::Gather,
    /// What the display refinement after the final gather did ([`mod@crate::gather::refine`]).
    pub display_refinement: crate::gather::Refined,
    /// What the `cache` gather did (records gathered, vertices interpolated), if it ran.
    pub gather_cache: Option<crate::gather::CacheStats>,
    /// Matrix or hierarchical.
    pub method: super::Method,
    /// The hierarchical solver's settings (`method = hierarchical`).
    pub hierarchical_settings: Option<crate::hierarchical::Settings>,
    /// Its counts: roots, clusters, elements, leaves, links, rays, passes, sweeps.
    pub hierarchical: Option<crate::hierarchical::Stats>,
    pub form_factor_settings: form_factor::Settings,
    pub solver_settings: crate::solve::Settings,
    /// Rays cast, non-zeros and row-sum statistics of F.
    pub form_factors: form_factor::Stats,
    pub iterations: u32,
    /// Over-relaxation the Gauss–Seidel solve used (automatic unless `--omega`; 1 otherwise).
    pub omega: f64,
    /// Final relative residual ‖E − (I − K)L‖₂ / ‖E‖₂.
    pub residual: f64,
    pub converged: bool,
    /// Exposure used for the 8-bit colours (radiance multiplier before sRGB).
    pub exposure: f64,
    pub seconds: Seconds,
    /// Peak resident memory of the process so far, bytes (Linux: `VmHWM` of
    /// /proc/self/status; `None` elsewhere).
    pub peak_memory_bytes: Option<u64>,
    /// What the form-factor cache did (`--cache`), if one was used.
    pub cache: Option<crate::form_factor::cache::CacheReport>,
    /// The row of the light transport with the largest sum, and where it is: a row above 1
    /// creates energy, and its place leads to the geometry behind it. Matrix method: the
    /// form-factor row of a patch (the last solve's); hierarchical: the leaf element whose
    /// effective row sum (Σ F over its links and its ancestors') is largest. `None` when no
    /// form factors were computed (nothing emits).
    pub worst_row: Option<WorstRow>,
    /// Everything the run warned of, in order (also shown as the run goes, see
    /// [`Report::stream_warnings`]), one line each: a warning that lists things (pairs of
    /// coincident or inconsistently wound faces, duplicate faces, materials) names at most
    /// [`crate::scene::MAX_LISTED_PAIRS`] of them and ends "… N more (all in --report)".
    pub warnings: Vec<String>,
    /// The full list behind each such warning, in the warnings' order: `kind` (`z_fighting`,
    /// `inconsistent_winding`, `duplicate_faces`, `textured_materials`, …), `count` and every
    /// item, worded as in the warning ([`crate::scene::WarningDetail`]).
    pub warning_details: Vec<crate::scene::WarningDetail>,
    /// How many of `warnings` were shown as the run went.
    #[serde(skip)]
    streamed: usize,
}

/// The row with the largest sum ([`Report::worst_row`]).
#[derive(Debug, Clone, Serialize)]
pub struct WorstRow {
    /// Σ_j F_ij: about 1 in a closed scene, at most 1 in an open one, give or take the
    /// estimate's error (the hierarchy's rows, found with a few rays per link and before a
    /// closed root's are normalised, reach about 1.4 in a clean closed room).
    pub sum: f64,
    /// Matrix: the patch i (an index into the final patches); hierarchical: the root patch the
    /// leaf was cut from (an index into the roots: the scene's triangles, in order, each cut
    /// to `--max-edge` only when one is given).
    pub patch: usize,
    /// Its material's name.
    pub material: String,
    /// The centroid of the patch (matrix) or of the leaf (hierarchical), scene units.
    pub centroid: [f64; 3],
}

impl WorstRow {
    /// The worst row of `stats` among `patches` of `scene`.
    pub fn of(scene: &crate::scene::Scene, patches: &Patches, stats: &form_factor::Stats) -> Self {
        let i = stats.row_sum_max_patch as usize;
        WorstRow {
            sum: stats.row_sum_max,
            patch: i,
            material: scene.materials[patches.material[i] as usize].name.clone(),
            centroid: patches.centroid[i].to_array(),
        }
    }
}

impl Report {
    /// An empty report for a run with these settings.
    pub fn new(settings: &Settings) -> Self {
        Report {
            version: env!("CARGO_PKG_VERSION"),
            input: None,
            output: None,
            overrides: Vec::new(),
            input_triangles: 0,
            orientation: None,
            contacts: None,
            display_contacts: None,
            lamp_lines: 0,
            sun_lines: 0,
            max_edge: 0.0,
            patches: 0,
            refine_rounds: 0,
            refine_budget: 0,
            estimate: None,
            refine_capped: false,
            vertices: 0,
            gather: crate::gather::Gather::None,
            display_refinement: crate::gather::Refined::default(),
            gather_cache: None,
            method: settings.method,
            hierarchical_settings: (settings.method == super::Method::Hierarchical)
                .then_some(settings.hierarchical),
            hierarchical: None,
            form_factor_settings: settings.form_factors,
            solver_settings: settings.solver,
            form_factors: form_factor::Stats::default(),
            iterations: 0,
            omega: 1.0,
            residual: 0.0,
            converged: false,
            exposure: 1.0,
            seconds: Seconds::default(),
            peak_memory_bytes: None,
            cache: None,
            worst_row: None,
            warnings: Vec::new(),
            warning_details: Vec::new(),
            streamed: 0,
        }
    }

    /// Warns, once, that the scene has no emitters (L = 0 whatever else).
    /// Shows the warnings not yet shown through [`crate::progress::warning`], as the run
    /// goes (a 15-minute bake tells of a bad material at once, not at its end).
    pub fn stream_warnings(&mut self) {
        while self.streamed < self.warnings.len() {
            if !crate::progress::warning(&self.warnings[self.streamed]) {
                return;
            }
            self.streamed += 1;
        }
    }

    /// The warnings [`Report::stream_warnings`] has not shown.
    pub fn unshown_warnings(&self) -> &[String] {
        &self.warnings[self.streamed..]
    }

    /// The warning that nothing emits, once.
    pub fn warn_no_emitters(&mut self) {
        let warning = "no emitters in the scene (no material has Ke > 0): the result is black";
        if !self.warnings.iter().any(|w| w == warning) {
            self.warnings.push(warning.into());
            self.stream_warnings();
        }
    }

    /// The one-line summary printed to stderr.
    pub fn summary(&self) -> String {
        if let Some(h) = &self.hierarchical {
            return format!(
                "{} patches, {} vertices, {:.3e} rays, {} links ({} elements, {} clusters), \
                 {} sweeps, residual {:.2e}, {:.2} s",
                self.patches,
                self.vertices,
                h.rays_cast as f64,
                h.links,
                h.elements,
                h.clusters,
                self.iterations,
                self.residual,
                self.seconds.total()
            );
        }
        format!(
            "{} patches, {} vertices, {:.3e} rays, {} non-zeros (row sums {:.4}..{:.4}), \
             {} iterations, residual {:.2e}, {:.2} s",
            self.patches,
            self.vertices,
            self.form_factors.rays_cast as f64,
            self.form_factors.nnz,
            self.form_factors.row_sum_min,
            self.form_factors.row_sum_max,
            self.iterations,
            self.residual,
            self.seconds.total()
        )
    }

    /// Write the report as pretty JSON, atomically.
    pub fn write_json(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self)
            .map_err(|e| crate::Error::Internal(format!("report serialisation: {e}")))?;
        io::write_atomic(path, text.as_bytes())
    }
}

/// The verbose note of a hierarchical solve: the hierarchies, the links and the sweeps.
pub fn hierarchical_note(s: &crate::hierarchical::Stats, solution: &Solution) -> String {
    format!(
        "hierarchical: {} roots, {} clusters, {} elements ({} leaves), {} links ({} with a \
         cluster, {} B each), {:.3e} rays, {} passes, {} sweeps, residual {:.2e}{}",
        s.roots,
        s.clusters,
        s.elements,
        s.leaves,
        s.links,
        s.cluster_links,
        s.bytes_per_link,
        s.rays_cast as f64,
        s.passes,
        solution.iterations,
        solution.residual,
        if s.closed_scene { ", closed scene" } else { "" }
    ) + &direct_note(s)
        + &ranks_note(s)
}

/// How a hierarchical solve lit its elements by the emitters in the mesh: at the elements'
/// own rule points ([`crate::hierarchical::direct`]), with which shadow rays, or by links.
fn direct_note(s: &crate::hierarchical::Stats) -> String {
    if s.direct_emitters == 0 {
        return "; links carry all emission".to_string();
    }
    let (most, rays) = if s.direct_rays_by_tree {
        ("", "drawn by the light tree")
    } else if s.direct_rays_shared {
        ("", "drawn by their light")
    } else {
        ("up to ", "to each")
    };
    format!(
        "; the elements compute the direct light of {} emitting triangles, {most}{} shadow rays \
         a rule point {rays}",
        s.direct_emitters, s.direct_shadow_rays
    )
}

/// What the ranks of a solve over several processes held and exchanged (empty for one).
fn ranks_note(s: &crate::hierarchical::Stats) -> String {
    if s.links_by_rank.is_empty() {
        return String::new();
    }
    let most = s.links_by_rank.iter().copied().max().unwrap_or(0) as f64;
    let mean = s.links.max(1) as f64 / s.links_by_rank.len() as f64;
    format!(
        "; {} ranks: links by rank {:?} (the most {:.2}× the mean, {} rebalances), {:.3e} bytes \
         exchanged in the sweeps ({:.2e} a sweep), {:.2} s in those exchanges",
        s.links_by_rank.len(),
        s.links_by_rank,
        most / mean,
        s.rebalances,
        s.sweep_exchange_bytes as f64,
        s.sweep_exchange_bytes as f64 / s.sweeps.max(1) as f64,
        s.sweep_exchange_seconds
    )
}

/// The verbose note of one solve: counts of the form-factor stage and of the solver.
pub fn solve_note(patches: usize, s: &form_factor::Stats, solution: &Solution) -> String {
    let method = solution.method.name();
    format!(
        "{patches} patches: {} pairs ({} culled, {} skipped), {:.3e} rays, {} non-zeros; \
         {} {} iterations, residual {:.2e}{}",
        s.pairs,
        s.pairs_culled,
        s.pairs_skipped,
        s.rays_cast as f64,
        s.nnz,
        if solution.omega != 1.0 {
            format!("{method} (ω = {:.2})", solution.omega)
        } else {
            method.to_string()
        },
        solution.iterations,
        solution.residual,
        if solution.grey {
            " (grey: one channel)"
        } else {
            ""
        }
    )
}

/// The verbose note of refinement round `round` (from 1), which split the `marked` patches
/// into `refined`.
pub fn refine_note(round: u32, marked: &[bool], refined: &Patches) -> String {
    format!(
        "refinement round {round}: {} of {} patches marked, {} patches now",
        marked.iter().filter(|&&m| m).count(),
        marked.len(),
        refined.len()
    )
}

/// Peak resident memory of this process, bytes: `VmHWM` of /proc/self/status (Linux only).
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
