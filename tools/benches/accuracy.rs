//! The run-time-vs-error harness: `cargo bench -p radiosity-tools --bench accuracy -- [--quick] [--out DIR]`.
//!
//! Sweeps the analytic scenes of [`radiosity::validation::scenes`] and the Cornell box over resolution,
//! estimator and sample count, measures each run's error the way `radiosity verify` does
//! (against [`radiosity::validation::closed_forms`], or a finer run for the Cornell box), and writes to DIR
//! (default `target/bench`):
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
//! error measures themselves follow `src/verify.rs`.

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

use radiosity_tools::{
    chart, fit_order, harness_args, load_font, machine, unknown_argument, utc_date, Curve,
    HarnessArgs,
};

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
        form_factors: &out.form_factors,
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

/// Area-weighted mean of `f` over the patches `which`.
fn area_mean(out: &Outcome, which: &[usize], f: impl Fn(usize) -> f64) -> f64 {
    let p = &out.patches;
    let area: f64 = which.iter().map(|&i| p.area[i]).sum();
    which.iter().map(|&i| p.area[i] * f(i)).sum::<f64>() / area
}

// ---------------------------------------------------------------------------------------------
// The scenes

/// Integrating sphere, radius 1, 30° cap, ρ = 0.5, Le = 1 (as in `verify::integrating_sphere`):
/// one bounce (Neumann N = 1) and all bounces (Gauss–Seidel) on the same F.
fn sphere(plan: &Plan, results: &mut Results) -> Result<()> {
    let rho = 0.5;
    for &level in &plan.sphere_levels {
        let scene = scenes::integrating_sphere(1.0, level, 30.0, rho, [1.0; 3])?;
        for ff in estimator_settings() {
            // max-edge above the facets' edges: the facets are the patches.
            let s = settings(10.0, ff, neumann(1));
            let (out, base) = run(&scene, "integrating_sphere", &s)?;
            let errors = |l: &[[f64; 3]], bounces| {
                let e = verify::sphere_wall_errors(&out.patches, l, rho, bounces);
                vec![
                    ("mean_patch_rel".to_string(), e.mean_patch_relative),
                    ("rel_of_mean".to_string(), e.relative_of_mean),
                ]
            };
            let mut one = base.clone();
            one.errors = errors(&out.solution.radiance, Some(1));
            push(results, one);
            let (solution, mut all_bounces) = resolve(
                &out,
                &base,
                &out.patches.reflectance,
                &gauss_seidel(SWEEP_TOLERANCE),
            )?;
            all_bounces.errors = errors(&solution.radiance, None);
            push(results, all_bounces);
        }
    }
    Ok(())
}

/// Per-patch relative errors against the furnace's L = Le/(1 − ρ): (max, area-weighted mean).
fn furnace_errors(out: &Outcome, l: &[[f64; 3]], rho: f64) -> Vec<(String, f64)> {
    let expected = closed_forms::furnace_radiance(rho, 1.0);
    let rel = |i: usize| (l[i][0] - expected).abs() / expected;
    let all: Vec<usize> = (0..l.len()).collect();
    vec![
        (
            "max_patch_rel".to_string(),
            all.iter().map(|&i| rel(i)).fold(0.0, f64::max),
        ),
        ("mean_patch_rel".to_string(), area_mean(out, &all, rel)),
    ]
}

/// Furnace room (closed, two boxes inside), Le = 1, every ρ of the plan on one F.
fn furnace(plan: &Plan, results: &mut Results) -> Result<()> {
    let scene = scenes::furnace_room(plan.furnace_rhos[0], 1.0)?;
    for &edge in &plan.furnace_edges {
        for ff in estimator_settings() {
            let solver = gauss_seidel(SWEEP_TOLERANCE);
            let (out, base) = run(&scene, "furnace", &settings(edge, ff, solver))?;
            for &rho in &plan.furnace_rhos {
                let reflectance = vec![[rho; 3]; out.patches.len()];
                let (solution, mut r) = resolve(&out, &base, &reflectance, &solver)?;
                if rho == plan.furnace_rhos[0] {
                    r.seconds.solve = base.seconds.solve;
                }
                r.scene = format!("furnace_rho{rho}");
                r.errors = furnace_errors(&out, &solution.radiance, rho);
                push(results, r);
            }
        }
    }
    Ok(())
}

/// Unit plates, parallel 1 apart (Howell C-11) and perpendicular with a common edge (C-14):
/// relative error of the receiver → source form factor.
fn plates(plan: &Plan, results: &mut Results) -> Result<()> {
    // The verify suite's two cases, named as the CSV and the charts name them.
    let [(_, parallel, f_parallel), (_, perpendicular, f_perpendicular)] = verify::plate_cases()?;
    let cases = [
        ("parallel_plates", parallel, f_parallel),
        ("perpendicular_plates", perpendicular, f_perpendicular),
    ];
    for (name, scene, expected) in &cases {
        for &edge in &plan.plate_edges {
            for ff in estimator_settings() {
                let (out, mut r) = run(scene, name, &settings(edge, ff, neumann(1)))?;
                let got = verify::surface_form_factor(&out, 1, 0);
                r.errors = vec![("form_factor_rel".into(), (got - expected).abs() / expected)];
                push(results, r);
            }
        }
    }
    Ok(())
}

fn cornell(plan: &Plan, results: &mut Results) -> Result<()> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/cornell_box.obj");
    let scene = Scene::load(&path)?;
    let solver = gauss_seidel(SWEEP_TOLERANCE);
    let traced = radiosity_tools::cornell_reference();
    if traced.is_none() {
        eprintln!("warning: docs/bench/cornell_reference.csv missing: no path-traced errors");
    }
    // Self-convergence: a much finer run (default estimator, two refinement rounds).
    let mut fine = settings(
        plan.cornell_reference_edge,
        form_factor::Settings::default(),
        solver,
    );
    fine.refine_rounds = 2;
    eprintln!(
        "cornell_box self-convergence reference: max-edge {} + 2 refinement rounds…",
        plan.cornell_reference_edge
    );
    let (out, mut r) = run(&scene, "cornell_box", &fine)?;
    let finer = radiosity_tools::surface_means(&scene, &out);
    r.estimator = format!("{} (refined)", r.estimator);
    r.errors = match &traced {
        Some(t) => vec![(
            "max_surface_vs_path_traced".into(),
            radiosity_tools::max_relative_difference(&finer, t),
        )],
        None => vec![],
    };
    push(results, r);
    drop(out);
    let mut measure = |s: &pipeline::Settings, label: &str| -> Result<()> {
        let (out, mut r) = run(&scene, "cornell_box", s)?;
        let means = radiosity_tools::surface_means(&scene, &out);
        if !label.is_empty() {
            r.estimator = format!("{} ({label})", r.estimator);
        }
        r.errors = vec![(
            "max_surface_vs_finer".into(),
            radiosity_tools::max_relative_difference(&means, &finer),
        )];
        if let Some(t) = &traced {
            r.errors.push((
                "max_surface_vs_path_traced".into(),
                radiosity_tools::max_relative_difference(&means, t),
            ));
        }
        push(results, r);
        Ok(())
    };
    for &edge in &plan.cornell_edges {
        for ff in estimator_settings() {
            measure(&settings(edge, ff, solver), "")?;
        }
    }
    // The defaults: two adaptive refinement rounds from diagonal/16.
    let mut defaults = settings(60.0, form_factor::Settings::default(), solver);
    defaults.refine_rounds = pipeline::Settings::default().refine_rounds;
    measure(&defaults, "defaults: refined")?;
    Ok(())
}

/// Jacobi and Gauss–Seidel on the furnace at several ρ, to a relative residual of 1e-10.
fn solver_study(plan: &Plan, results: &mut Results) -> Result<()> {
    let scene = scenes::furnace_room(0.5, 1.0)?;
    let s = settings(
        plan.solver_edge,
        form_factor::Settings::default(),
        neumann(1),
    );
    let (out, base) = run(&scene, "furnace", &s)?;
    eprintln!(
        "solver study: furnace, max-edge {}, {} patches",
        plan.solver_edge, base.patches
    );
    for &rho in &plan.solver_rhos {
        let reflectance = vec![[rho; 3]; out.patches.len()];
        for method in [Method::Jacobi, Method::GaussSeidel] {
            let solver = solve::Settings {
                method,
                tolerance: 1e-10,
                max_iterations: 100_000,
                ..solve::Settings::default()
            };
            let (solution, r) = resolve(&out, &base, &reflectance, &solver)?;
            let max_error = furnace_errors(&out, &solution.radiance, rho)[0].1;
            eprintln!(
                "  {:<12} ρ = {rho:<5} {:>6} sweeps {:>7.3} s  residual {:.1e}  max error {max_error:.2e}",
                method.name(),
                solution.iterations,
                r.seconds.solve,
                solution.residual
            );
            results.solver_study.push(SolverRun {
                method: method.name().to_string(),
                rho,
                history: solution.residual_history,
                seconds: r.seconds.solve,
                max_error,
            });
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Convergence orders

/// One fitted order.
struct Order {
    scene: String,
    estimator: String,
    solver: String,
    kind: String,
    /// "h" or "samples".
    variable: &'static str,
    /// What was held fixed: "samples=3" or "h=0.0430".
    fixed: String,
    /// Its value (samples, or h).
    fixed_value: f64,
    order: f64,
    r2: f64,
    points: usize,
}

fn fit_orders(runs: &[Run]) -> Vec<Order> {
    // Key: (scene, estimator, solver, kind, variable, fixed); value: (fixed value, points
    // (x, error)).
    type Key = (String, String, String, String, &'static str, String);
    let mut groups: BTreeMap<Key, (f64, Vec<(f64, f64)>)> = BTreeMap::new();
    for r in runs {
        for (kind, e) in &r.errors {
            let key = |variable, fixed| {
                (
                    r.scene.clone(),
                    r.estimator.clone(),
                    r.solver.clone(),
                    kind.clone(),
                    variable,
                    fixed,
                )
            };
            groups
                .entry(key("h", format!("samples={}", r.samples)))
                .or_insert((r.samples as f64, vec![]))
                .1
                .push((r.h, *e));
            groups
                .entry(key("samples", format!("h={:.4}", r.h)))
                .or_insert((r.h, vec![]))
                .1
                .push((r.samples as f64, *e));
        }
    }
    let mut out = Vec::new();
    for ((scene, estimator, solver, kind, variable, fixed), (fixed_value, points)) in groups {
        if let Some((order, r2)) = fit_order(&points) {
            out.push(Order {
                scene,
                estimator,
                solver,
                kind,
                variable,
                fixed,
                fixed_value,
                order,
                r2,
                points: points.len(),
            });
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Output files

fn write_runs_csv(path: &Path, runs: &[Run]) -> Result<()> {
    let mut s = String::from(
        "scene,estimator,samples,max_edge,solver,patches,h,rays,seconds_patches,seconds_bvh,\
         seconds_form_factors,seconds_solve,seconds_total,error,error_kind\n",
    );
    for r in runs {
        for (kind, e) in &r.errors {
            let e = if e.is_finite() {
                format!("{e:.6e}")
            } else {
                String::new()
            };
            writeln!(
                s,
                "{},{},{},{},{},{},{:.6},{},{:.6},{:.6},{:.6},{:.6},{:.6},{},{}",
                r.scene,
                r.estimator,
                r.samples,
                r.max_edge,
                r.solver,
                r.patches,
                r.h,
                r.rays,
                r.seconds.patches,
                r.seconds.bvh,
                r.seconds.form_factors,
                r.seconds.solve,
                r.seconds.total(),
                e,
                kind
            )?;
        }
    }
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

fn write_residuals_csv(path: &Path, study: &[SolverRun]) -> Result<()> {
    let mut s = String::from("method,rho,iteration,residual\n");
    for r in study {
        for (k, res) in r.history.iter().enumerate() {
            writeln!(s, "{},{},{},{:.6e}", r.method, r.rho, k + 1, res)?;
        }
    }
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

fn write_orders_csv(path: &Path, orders: &[Order]) -> Result<()> {
    let mut s = String::from("scene,estimator,solver,error_kind,variable,fixed,order,r2,points\n");
    for o in orders {
        writeln!(
            s,
            "{},{},{},{},{},{},{:.3},{:.3},{}",
            o.scene, o.estimator, o.solver, o.kind, o.variable, o.fixed, o.order, o.r2, o.points
        )?;
    }
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

/// Markdown tables: per scene one row per run, then the solver study and the fitted orders.
fn summary(args: &HarnessArgs, results: &Results, orders: &[Order], seconds: f64) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "## Run time against error\n");
    let _ = writeln!(
        s,
        "`cargo bench -p radiosity-tools --bench accuracy --{}` ({:.0} s). Measured {}; {}.\n",
        if args.quick { " -- --quick" } else { "" },
        seconds,
        utc_date(),
        machine()
    );
    let mut scenes: Vec<&str> = Vec::new();
    for r in &results.runs {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    for scene in scenes {
        let runs: Vec<&Run> = results.runs.iter().filter(|r| r.scene == scene).collect();
        let mut kinds: Vec<&str> = Vec::new();
        for r in &runs {
            for (k, _) in &r.errors {
                if k != "reference" && !kinds.contains(&k.as_str()) {
                    kinds.push(k);
                }
            }
        }
        let _ = writeln!(s, "### {scene}\n");
        let _ = writeln!(
            s,
            "| estimator | samples | max-edge | solver | patches | rays | F s | total s | {} |",
            kinds.join(" | ")
        );
        let _ = writeln!(
            s,
            "|---|---|---|---|---|---|---|---|{}",
            "---|".repeat(kinds.len())
        );
        for r in runs {
            let errors: Vec<String> = kinds
                .iter()
                .map(|k| match r.errors.iter().find(|(rk, _)| rk == k) {
                    Some((_, e)) => format!("{e:.2e}"),
                    None if r.errors.iter().any(|(rk, _)| rk == "reference") => {
                        "(reference)".into()
                    }
                    None => String::new(),
                })
                .collect();
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {:.3e} | {:.3} | {:.3} | {} |",
                r.estimator,
                r.samples,
                r.max_edge,
                r.solver,
                r.patches,
                r.rays as f64,
                r.seconds.form_factors,
                r.seconds.total(),
                errors.join(" | ")
            );
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "### Solver study (furnace, relative residual 1e-10)\n");
    let _ = writeln!(
        s,
        "| method | ρ | sweeps | solve s | final residual | max patch error |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    for r in &results.solver_study {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.3} | {:.1e} | {:.2e} |",
            r.method,
            r.rho,
            r.history.len(),
            r.seconds,
            r.history.last().copied().unwrap_or(f64::NAN),
            r.max_error
        );
    }
    let _ = writeln!(
        s,
        "\n### Fitted orders\n\n\
         p of error ≈ C·x^p, least squares in log-log (every fit, with r², in orders.csv): \
         x = h (mean √area of the patches) at each sample count, and x = samples at the \
         finest h. The Cornell errors are against a finer run, so they flatten near it.\n"
    );
    let _ = writeln!(
        s,
        "| scene | estimator | solver | error | p vs h (samples) | p vs samples |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    type Row = (Vec<String>, Option<(f64, f64)>);
    let mut rows: BTreeMap<(&str, &str, &str, &str), Row> = BTreeMap::new();
    for o in orders {
        let row = rows
            .entry((&o.scene, &o.estimator, &o.solver, &o.kind))
            .or_default();
        if o.variable == "h" {
            row.0.push(format!("{:.2} (s{})", o.order, o.fixed_value));
        } else if row.1.is_none_or(|(h, _)| o.fixed_value < h) {
            row.1 = Some((o.fixed_value, o.order));
        }
    }
    for ((scene, estimator, solver, kind), (by_h, by_samples)) in rows {
        let _ = writeln!(
            s,
            "| {scene} | {estimator} | {solver} | {kind} | {} | {} |",
            by_h.join(", "),
            by_samples.map_or(String::new(), |(_, p)| format!("{p:.2}"))
        );
    }
    s
}

// ---------------------------------------------------------------------------------------------
// Charts

/// `error_vs_time_<scene>.png`: the scene's first error kind against total seconds, one curve
/// per (estimator, samples, solver) through its resolutions; colour by (estimator, samples),
/// line style by solver.
fn plot_errors(dir: &Path, runs: &[Run], text: bool) -> Result<()> {
    let mut scenes: Vec<&str> = Vec::new();
    for r in runs {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    for scene in scenes {
        let runs: Vec<&Run> = runs
            .iter()
            .filter(|r| r.scene == scene && r.errors.iter().all(|(k, _)| k != "reference"))
            .collect();
        let Some(kind) = runs
            .iter()
            .find_map(|r| r.errors.first().map(|e| e.0.clone()))
        else {
            continue;
        };
        let (mut colours, mut styles): (Vec<(String, u32)>, Vec<String>) = (vec![], vec![]);
        let mut curves: Vec<Curve> = Vec::new();
        for r in runs {
            let Some(&(_, e)) = r.errors.iter().find(|(k, _)| *k == kind) else {
                continue;
            };
            let c = (r.estimator.clone(), r.samples);
            let colour = colours.iter().position(|x| *x == c).unwrap_or_else(|| {
                colours.push(c);
                colours.len() - 1
            });
            let style = styles
                .iter()
                .position(|x| *x == r.solver)
                .unwrap_or_else(|| {
                    styles.push(r.solver.clone());
                    styles.len() - 1
                });
            let label = format!("{} s{} {}", r.estimator, r.samples, r.solver);
            match curves.iter_mut().find(|c| c.label == label) {
                Some(c) => c.points.push((r.seconds.total(), e)),
                None => curves.push(Curve {
                    label,
                    points: vec![(r.seconds.total(), e)],
                    colour,
                    style,
                }),
            }
        }
        for c in &mut curves {
            c.points.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        chart(
            &dir.join(format!("error_vs_time_{scene}.png")),
            &format!("{scene}: {kind} vs time"),
            ("total seconds", &kind),
            true,
            &curves,
            text,
        )?;
    }
    Ok(())
}

/// `residual_vs_iteration.png`: one curve per (method, ρ); colour by ρ, line style by method.
fn plot_residuals(dir: &Path, study: &[SolverRun], text: bool) -> Result<()> {
    let mut rhos: Vec<f64> = study.iter().map(|r| r.rho).collect();
    rhos.dedup();
    let curves: Vec<Curve> = study
        .iter()
        .map(|r| Curve {
            label: format!("{} ρ={}", r.method, r.rho),
            points: (r.history.iter().enumerate())
                .map(|(k, &v)| ((k + 1) as f64, v))
                .collect(),
            colour: rhos.iter().position(|&x| x == r.rho).unwrap_or(0),
            style: (r.method != "jacobi") as usize,
        })
        .collect();
    chart(
        &dir.join("residual_vs_iteration.png"),
        "furnace: relative residual per sweep",
        ("sweep", "relative residual"),
        false,
        &curves,
        text,
    )
}
