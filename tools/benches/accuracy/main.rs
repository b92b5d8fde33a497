//! The run-time-vs-error harness: `cargo bench -p radiosity-tools --bench accuracy -- [--quick]
//! [--out DIR]`.
//!
//! Sweeps the analytic scenes of [`radiosity::validation::scenes`] and the Cornell box over
//! resolution, estimator and sample count, measures each run's error the way `radiosity verify`
//! does (against [`radiosity::validation::closed_forms`], or a finer run for the Cornell box), and
//! writes to DIR (default `target/bench`):
//!
//! - `runs.csv`: one row per (run, error kind), with patches, rays and seconds per stage;
//! - `residuals.csv`: the solver study (Jacobi and Gauss–Seidel on the furnace, ρ up to 0.99),
//!   relative residual per sweep;
//! - `orders.csv`: fitted convergence orders, the least-squares slope of log(error) against
//!   log(h) (h = mean √area of the patches) and against log(samples);
//! - `error_vs_time_<scene>.png`, `residual_vs_iteration.png`: log-log and log-y charts;
//! - `summary.md`: the tables to paste into BENCHMARKS.md, with date and machine.
//!
//! Runs that differ only in ρ or in the solver share one form-factor computation (F depends
//! on geometry and estimator only); each such row reports the seconds of the shared
//! computation, i.e. what a standalone run would have cost. Progress goes to stderr.
//!
//! Chart text needs a TrueType font, loaded at run time (plotters' `ab_glyph` backend has none
//! built in): `$BENCH_FONT` if set, else the first of [`FONT_PATHS`] that exists. Without one
//! the charts are still drawn, with no title, tick labels or legend, and a warning says so.
//! This module owns the sweep, the error measures' bookkeeping and the output files; the
//! error measures themselves follow `src/validation/verify.rs`.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use radiosity::form_factor::{self, Estimator};
use radiosity::pipeline::{self, Outcome};
use radiosity::scene::Scene;
use radiosity::solve::System;
use radiosity::solve::{self, Method, Solution};
use radiosity::validation::{closed_forms, scenes, verify};

mod output;
mod sweeps;

use output::*;
use radiosity_tools::{
    chart, fit_order, harness_args, load_font, machine, unknown_argument, utc_date, Curve,
    HarnessArgs,
};
use sweeps::*;

/// Tolerance of the sweeps' Gauss–Seidel solves: far below every discretisation error measured.
const SWEEP_TOLERANCE: f64 = 1e-8;

/// The command line: `--quick` and `--out DIR` only.
fn parse_args() -> Result<HarnessArgs> {
    let args = harness_args(
        "target/bench",
        "cargo bench -p radiosity-tools --bench accuracy -- [--quick] [--out DIR]\n\n\
         --quick    smaller sweep (~2 min on 2 cores) instead of the full one\n\
         --out DIR  output directory [default: target/bench]",
    )?;
    match args.other.first() {
        Some(word) => Err(unknown_argument(word)),
        None => Ok(args),
    }
}

/// The sweep's sizes; `--quick` shrinks them.
struct Plan {
    sphere_levels: Vec<u32>,
    furnace_rhos: Vec<f64>,
    furnace_edges: Vec<f64>,
    plate_edges: Vec<f64>,
    cornell_edges: Vec<f64>,
    cornell_reference_edge: f64,
    solver_rhos: Vec<f64>,
    solver_edge: f64,
}

impl Plan {
    fn new(quick: bool) -> Plan {
        Plan {
            sphere_levels: if quick { vec![2, 3] } else { vec![2, 3, 4] },
            furnace_rhos: vec![0.5, 0.9],
            furnace_edges: if quick {
                vec![0.35, 0.2, 0.14]
            } else {
                vec![0.35, 0.2, 0.1]
            },
            plate_edges: vec![0.5, 0.25, 0.1],
            cornell_edges: vec![120.0, 90.0, 60.0],
            cornell_reference_edge: if quick { 45.0 } else { 30.0 },
            solver_rhos: vec![0.5, 0.9, 0.99],
            solver_edge: 0.2,
        }
    }
}

/// The sweep variable of an estimator ("samples" in the tables): sample points per patch for
/// the pair estimators, rays per patch for hemisphere shooting.
fn sample_counts(e: Estimator) -> Vec<u32> {
    match e {
        Estimator::Area | Estimator::Contour => vec![1, 3, 6],
        // Hemisphere shooting: the sweep variable is rays per patch.
        Estimator::Hemisphere => vec![256, 1024, 4096],
    }
}

fn estimator_name(e: Estimator) -> String {
    e.to_string()
}

/// Seconds per stage of one run.
#[derive(Debug, Clone, Copy, Default)]
struct Stages {
    patches: f64,
    bvh: f64,
    form_factors: f64,
    solve: f64,
}

impl Stages {
    fn total(&self) -> f64 {
        self.patches + self.bvh + self.form_factors + self.solve
    }
}

/// One run and its errors (one CSV row per error kind).
#[derive(Debug, Clone)]
struct Run {
    scene: String,
    estimator: String,
    samples: u32,
    max_edge: f64,
    solver: String,
    patches: usize,
    /// Mean √area of the patches, scene units: the h of the convergence fits.
    h: f64,
    rays: u64,
    seconds: Stages,
    /// (kind, relative error); the first kind is the one the charts show.
    errors: Vec<(String, f64)>,
}

/// Everything the sweep collects.
#[derive(Default)]
struct Results {
    runs: Vec<Run>,
    /// The solver study, one entry per (method, ρ).
    solver_study: Vec<SolverRun>,
}

struct SolverRun {
    method: String,
    rho: f64,
    history: Vec<f64>,
    seconds: f64,
    max_error: f64,
}

fn main() -> Result<()> {
    let args = parse_args()?;
    let start = Instant::now();
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let plan = Plan::new(args.quick);
    let mut results = Results::default();
    sphere(&plan, &mut results)?;
    furnace(&plan, &mut results)?;
    plates(&plan, &mut results)?;
    cornell(&plan, &mut results)?;
    solver_study(&plan, &mut results)?;
    let sweep_seconds = start.elapsed().as_secs_f64();

    let orders = fit_orders(&results.runs);
    write_runs_csv(&args.out.join("runs.csv"), &results.runs)?;
    write_residuals_csv(&args.out.join("residuals.csv"), &results.solver_study)?;
    write_orders_csv(&args.out.join("orders.csv"), &orders)?;
    let text = load_font();
    if !text {
        eprintln!("warning: no TrueType font found (set BENCH_FONT): charts have no text");
    }
    plot_errors(&args.out, &results.runs, text)?;
    plot_residuals(&args.out, &results.solver_study, text)?;
    let summary = summary(&args, &results, &orders, sweep_seconds);
    std::fs::write(args.out.join("summary.md"), &summary)?;
    println!("{summary}");
    eprintln!(
        "bench: {} runs in {:.1} s; wrote {}",
        results.runs.len(),
        start.elapsed().as_secs_f64(),
        args.out.display()
    );
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Running the pipeline

fn settings(
    max_edge: f64,
    ff: form_factor::Settings,
    solver: solve::Settings,
) -> pipeline::Settings {
    pipeline::Settings {
        max_edge: Some(max_edge),
        // Uniform meshes: the sweep studies resolution, so refinement must not move it.
        refine_rounds: 0,
        // The whole F: several runs solve again on one run's F (`resolve`) with another
        // solver or reflectance, which may read entries a one-bounce solve would skip.
        form_factors: form_factor::Settings {
            shortcuts: form_factor::Shortcuts {
                skip_unneeded: false,
                ..ff.shortcuts
            },
            ..ff
        },
        solver,
        ..pipeline::Settings::default()
    }
}

fn gauss_seidel(tolerance: f64) -> solve::Settings {
    solve::Settings {
        method: Method::GaussSeidel,
        tolerance,
        max_iterations: 100_000,
        ..solve::Settings::default()
    }
}

fn neumann(bounces: u32) -> solve::Settings {
    solve::Settings {
        method: Method::Neumann,
        bounces,
        ..solve::Settings::default()
    }
}

fn solver_name(s: &solve::Settings) -> String {
    match s.method {
        Method::Neumann => format!("neumann-{}", s.bounces),
        m => m.name().to_string(),
    }
}

/// Every (estimator, samples) pair the sweeps cover.
fn estimator_settings() -> Vec<form_factor::Settings> {
    let mut out = Vec::new();
    for &estimator in <Estimator as radiosity::Choice>::ALL {
        for samples in sample_counts(estimator) {
            let mut s = form_factor::Settings {
                estimator,
                samples,
                ..Default::default()
            };
            if estimator == Estimator::Hemisphere {
                s.rays = samples;
                s.samples = 1;
            }
            out.push(s);
        }
    }
    out
}

/// Run the pipeline and fill a [`Run`] (errors left empty).
fn run(scene: &Scene, name: &str, s: &pipeline::Settings) -> Result<(Outcome, Run)> {
    let out = pipeline::solve_scene(scene, s)?;
    if !out.solution.converged {
        eprintln!("warning: {name}: the solver did not converge");
    }
    let r = &out.report;
    let p = &out.patches;
    let h = p.area.iter().map(|a| a.sqrt()).sum::<f64>() / p.len() as f64;
    let run = Run {
        scene: name.to_string(),
        estimator: estimator_name(s.form_factors.estimator),
        samples: match s.form_factors.estimator {
            Estimator::Hemisphere => s.form_factors.rays,
            _ => s.form_factors.samples,
        },
        max_edge: r.max_edge,
        solver: solver_name(&s.solver),
        patches: r.patches,
        h,
        rays: r.form_factors.rays_cast,
        seconds: Stages {
            patches: r.seconds.patches,
            bvh: r.seconds.bvh,
            form_factors: r.seconds.form_factors,
            solve: r.seconds.solve,
        },
        errors: Vec::new(),
    };
    Ok((out, run))
}

/// Solve again on an outcome's form factors with another solver and/or reflectance; the
/// returned run copies `base` with the new solver and solve seconds.
fn resolve(
    out: &Outcome,
    base: &Run,
    reflectance: &[[f64; 3]],
    solver: &solve::Settings,
) -> Result<(Solution, Run)> {
    let system = System {
        form_factors: out.form_factors.as_ref().expect("matrix method"),
        reflectance,
        emission: &out.patches.emission,
    };
    let t = Instant::now();
    let solution = solve::solve(&system, solver)?;
    let mut run = base.clone();
    run.seconds.solve = t.elapsed().as_secs_f64();
    run.solver = solver_name(solver);
    run.errors.clear();
    Ok((solution, run))
}

fn progress(results: &Results, run: &Run) {
    let errors: Vec<String> = run
        .errors
        .iter()
        .map(|(k, e)| format!("{k} {e:.2e}"))
        .collect();
    eprintln!(
        "[{:>3}] {:<22} {:<8} s{} edge {:<6} {:<12} {:>6} patches {:>7.2} s  {}",
        results.runs.len() + 1,
        run.scene,
        run.estimator,
        run.samples,
        run.max_edge,
        run.solver,
        run.patches,
        run.seconds.total(),
        errors.join(", ")
    );
}

fn push(results: &mut Results, run: Run) {
    progress(results, &run);
    results.runs.push(run);
}
