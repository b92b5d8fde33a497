//! The speed-and-scale harness: `cargo bench -p radiosity-tools --bench scale -- [SECTION…] [--quick]
//! [--out DIR]`, sections `skips`, `solvers`, `scale`, `rays`, `matvec`, `reference` (all but
//! `reference` when none is named). Writes to DIR (default `target/scale`):
//!
//! - `skips.csv` / `skips.md`: every skip of the pipeline, the same work with and without it in
//!   one run (seconds, the counter that shows it in `--report`, and whether the answer is the
//!   same);
//! - `solvers.csv` / `solvers.md`, `omega.csv`, `solver_residuals.csv`, `solver_residuals.png`:
//!   sweeps and seconds to a relative residual of 1e-6 per solver on the closed furnace room at
//!   ρ = 0.5 … 0.999, the measured convergence factor per sweep against theory, and the
//!   over-relaxation study of Gauss–Seidel;
//! - `scale.csv` / `scale.md`: the Cornell box from ~1k to ~100k patches, seconds per stage and
//!   peak memory (each run in a child process of its own, so peaks do not mix), the fitted
//!   growth exponents, and the two scale targets with their error against the path-traced
//!   reference;
//! - `rays.md` (+ `rays.bin` for `tools/embree_rays.py`): occlusion rays per second per core on
//!   a 10k-triangle room, ours against Embree's (`embreex` from PyPI, run in a virtual
//!   environment under `target/` when it can be installed);
//! - `matvec.md`: bytes per second of the F·L product against this machine's copy bandwidth
//!   measured in the same run;
//! - `reference`: `docs/bench/cornell_reference.csv`, the per-surface mean radiance of the
//!   Cornell box by path tracing ([`radiosity::validation::path_tracer`]; 16M paths per surface, ~5 min).
//!
//! Everything is timed on the machine it runs on; the date and machine head every file.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use radiosity::form_factor::{self, Estimator};
use radiosity::pipeline::{self, Outcome};
use radiosity::scene::Scene;
use radiosity::solve::System;
use radiosity::solve::{self, Method};
use radiosity::validation::{path_tracer, scenes};
use radiosity::visibility::Visibility;

use radiosity_tools::{
    chart, fit_order, harness_args, load_font, machine, surface_means, unknown_argument, utc_date,
    Curve,
};

/// The command line: sections to run (all but `reference` by default), `--quick`, `--out
/// DIR`, and the internal `--child SPEC` (one Cornell run in this process, JSON on stdout).
struct Args {
    sections: Vec<String>,
    quick: bool,
    out: PathBuf,
}

fn parse_args() -> Result<Args> {
    let h = harness_args(
        "target/scale",
        "cargo bench -p radiosity-tools --bench scale -- \
         [skips|solvers|scale|rays|matvec|reference]… [--quick] [--out DIR]",
    )?;
    let mut sections = Vec::new();
    let mut it = h.other.into_iter();
    while let Some(x) = it.next() {
        match x.as_str() {
            "--child" => {
                let spec = it.next().context("--child needs a run spec")?;
                child(&spec)?;
                std::process::exit(0);
            }
            "skips" | "solvers" | "scale" | "rays" | "matvec" | "reference" => sections.push(x),
            other => return Err(unknown_argument(other)),
        }
    }
    if sections.is_empty() {
        sections = ["skips", "solvers", "scale", "rays", "matvec"]
            .map(String::from)
            .to_vec();
    }
    Ok(Args {
        sections,
        quick: h.quick,
        out: h.out,
    })
}

fn main() -> Result<()> {
    let args = parse_args()?;
    std::fs::create_dir_all(&args.out)?;
    let header = format!("Measured {} on {}.\n\n", utc_date(), machine());
    for s in &args.sections {
        let t = Instant::now();
        eprintln!("== {s}");
        let md = match s.as_str() {
            "skips" => skips(&args)?,
            "solvers" => solvers(&args)?,
            "scale" => scale(&args)?,
            "rays" => rays(&args)?,
            "matvec" => matvec(&args)?,
            "reference" => reference(&args)?,
            _ => unreachable!(),
        };
        let path = args.out.join(format!("{s}.md"));
        std::fs::write(&path, format!("{header}{md}"))?;
        eprintln!(
            "{} written ({:.0} s)",
            path.display(),
            t.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

fn cornell() -> Result<Scene> {
    Ok(Scene::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/cornell_box.obj"),
    )?)
}

fn run(scene: &Scene, s: &pipeline::Settings) -> Result<(Outcome, f64)> {
    let t = Instant::now();
    let out = pipeline::solve_scene(scene, s)?;
    Ok((out, t.elapsed().as_secs_f64()))
}

fn settings(max_edge: f64) -> pipeline::Settings {
    pipeline::Settings {
        max_edge: Some(max_edge),
        ..pipeline::Settings::default()
    }
}

// ---------------------------------------------------------------------------------------------
// Skips

/// One skip measured: the same work with it off ("before") and on ("after").
struct SkipRow {
    skip: &'static str,
    scene: &'static str,
    before: f64,
    after: f64,
    counter: String,
    same: String,
}

fn skips(args: &Args) -> Result<String> {
    let cornell = cornell()?;
    let mut rows: Vec<SkipRow> = Vec::new();
    let same_radiance = |a: &Outcome, b: &Outcome| {
        if a.solution.radiance == b.solution.radiance {
            "identical".to_string()
        } else {
            let worst = a
                .solution
                .radiance
                .iter()
                .zip(&b.solution.radiance)
                .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs() / y[c].abs().max(1e-12)))
                .fold(0.0, f64::max);
            format!("max rel. diff {worst:.1e}")
        }
    };
    // Form-factor seconds of a run with a form-factor setting changed.
    let with = |scene: &Scene,
                base: &pipeline::Settings,
                f: &dyn Fn(&mut form_factor::Settings)|
     -> Result<(Outcome, f64)> {
        let mut s = base.clone();
        f(&mut s.form_factors);
        let (out, _) = run(scene, &s)?;
        let secs = out.report.seconds.form_factors;
        Ok((out, secs))
    };
    let mut base = settings(60.0);
    base.refine_rounds = 0;

    // 1. Faces on the convex hull leave the occlusion BVH.
    let (off, t_off) = with(&cornell, &base, &|f| f.shortcuts.skip_hull = false)?;
    let (on, t_on) = with(&cornell, &base, &|_| {})?;
    rows.push(SkipRow {
        skip: "hull faces out of the occlusion tests",
        scene: "Cornell box, 3160 patches",
        before: t_off,
        after: t_on,
        counter: format!(
            "occluder_patches {} of {}",
            on.form_factors.stats.occluder_patches,
            on.patches.len()
        ),
        same: same_radiance(&on, &off),
    });
    // 2. Convex enclosure: no visibility ray at all.
    let sphere =
        scenes::integrating_sphere(1.0, if args.quick { 3 } else { 4 }, 30.0, 0.5, [1.0; 3])?;
    let mut sb = settings(10.0);
    sb.refine_rounds = 0;
    let (off, t_off) = with(&sphere, &sb, &|f| f.shortcuts.skip_hull = false)?;
    let (on, t_on) = with(&sphere, &sb, &|_| {})?;
    rows.push(SkipRow {
        skip: "convex enclosure: no visibility rays",
        scene: "integrating sphere",
        before: t_off,
        after: t_on,
        counter: format!(
            "convex_enclosure {}, rays {:.2e} → {:.2e}",
            on.form_factors.stats.convex_enclosure,
            off.form_factors.stats.rays_cast as f64,
            on.form_factors.stats.rays_cast as f64
        ),
        same: same_radiance(&on, &off),
    });
    // 3. Pairs behind each other's plane.
    let (off, t_off) = with(&cornell, &base, &|f| f.shortcuts.cull_behind = false)?;
    let (on, t_on) = with(&cornell, &base, &|_| {})?;
    rows.push(SkipRow {
        skip: "pairs behind each other's plane",
        scene: "Cornell box, 3160 patches",
        before: t_off,
        after: t_on,
        counter: format!(
            "pairs_culled {} of {}",
            on.form_factors.stats.pairs_culled, on.form_factors.stats.pairs
        ),
        same: same_radiance(&on, &off),
    });
    // 4. Black patches' rows.
    let mut black = cornell.clone();
    for m in &mut black.materials {
        if m.name == "red" || m.name == "green" {
            m.reflectance = [0.0; 3];
        }
    }
    let (off, t_off) = with(&black, &base, &|f| f.shortcuts.skip_unneeded = false)?;
    let (on, t_on) = with(&black, &base, &|_| {})?;
    rows.push(SkipRow {
        skip: "rows of black patches (ρ = 0)",
        scene: "Cornell box, red and green walls black",
        before: t_off,
        after: t_on,
        counter: format!("rows_skipped {}", on.form_factors.stats.rows_skipped),
        same: same_radiance(&on, &off),
    });
    // 5. One bounce: only the emitters' columns.
    let mut direct = base.clone();
    direct.solver.method = Method::Neumann;
    direct.solver.bounces = 1;
    let (off, t_off) = with(&cornell, &direct, &|f| f.shortcuts.skip_unneeded = false)?;
    let (on, t_on) = with(&cornell, &direct, &|_| {})?;
    rows.push(SkipRow {
        skip: "--bounces 1: emitters' columns only",
        scene: "Cornell box, 3160 patches",
        before: t_off,
        after: t_on,
        counter: format!(
            "pairs_skipped {} of {}",
            on.form_factors.stats.pairs_skipped, on.form_factors.stats.pairs
        ),
        same: same_radiance(&on, &off),
    });
    // 6. No emitters: a black result at once.
    let mut dark = cornell.clone();
    for m in &mut dark.materials {
        m.emission = [0.0; 3];
    }
    let (_, t_lit) = run(&cornell, &base)?;
    let (d, t_dark) = run(&dark, &base)?;
    rows.push(SkipRow {
        skip: "no emitters: no form factors, no solve",
        scene: "Cornell box with the light off (before: lit)",
        before: t_lit,
        after: t_dark,
        counter: format!("warning: {:?}", d.report.warnings.first().map(|w| &w[..30])),
        same: "black".into(),
    });
    // 7. Refinement rounds reuse unchanged pairs.
    let (off, t_off) = with(&cornell, &settings(60.0), &|f| f.shortcuts.reuse = false)?;
    let (on, t_on) = with(&cornell, &settings(60.0), &|_| {})?;
    rows.push(SkipRow {
        skip: "refinement reuses unchanged pairs",
        scene: "Cornell box, default (2 rounds)",
        before: t_off,
        after: t_on,
        counter: format!(
            "pairs_reused {} (last round)",
            on.form_factors.stats.pairs_reused
        ),
        same: format!(
            "per-surface means within {:.1e} of each other (other sample pairings, so other \
             refinement marks: {} vs {} patches)",
            surface_difference(&cornell, &on, &off),
            on.patches.len(),
            off.patches.len()
        ),
    });
    // 8. The form-factor cache.
    let dir = args.out.join("ff-cache");
    let _ = std::fs::remove_dir_all(&dir);
    let mut cached = settings(60.0);
    cached.cache = Some(dir.clone());
    let (first, t_first) = run(&cornell, &cached)?;
    let mut relit = cornell.clone();
    for m in &mut relit.materials {
        if m.name == "light" {
            m.emission = [4.0, 8.0, 17.0];
        }
    }
    cached.refine_rounds = 0;
    let (_, _) = run(&cornell, &cached)?; // stores the unrefined F too
    let (hit, t_hit) = run(&relit, &cached)?;
    let mut plain = settings(60.0);
    plain.refine_rounds = 0;
    let (fresh, t_fresh) = run(&relit, &plain)?;
    let _ = first;
    let _ = t_first;
    rows.push(SkipRow {
        skip: "--cache: relighting reads F",
        scene: "Cornell box relit, 3160 patches",
        before: t_fresh,
        after: t_hit,
        counter: format!(
            "cache hits {}, seconds_saved {:.2}",
            hit.report.cache.as_ref().map_or(0, |c| c.hits),
            hit.report.cache.as_ref().map_or(0.0, |c| c.seconds_saved)
        ),
        same: same_radiance(&hit, &fresh),
    });
    let _ = std::fs::remove_dir_all(&dir);
    // 9. Grey scenes solve one channel.
    let furnace = scenes::furnace_room(0.9, 1.0)?;
    let mut fs = settings(0.1);
    fs.form_factors.estimator = Estimator::Hemisphere;
    fs.form_factors.rays = 256;
    fs.solver.tolerance = 1e-10;
    let (grey, _) = run(&furnace, &fs)?;
    let system = |out: &Outcome, rho: &[[f64; 3]]| -> Result<(f64, solve::Solution)> {
        let sys = System {
            form_factors: &out.form_factors,
            reflectance: rho,
            emission: &out.patches.emission,
        };
        let t = Instant::now();
        let s = solve::solve(&sys, &fs.solver)?;
        Ok((t.elapsed().as_secs_f64(), s))
    };
    let (t_grey, sg) = system(&grey, &grey.patches.reflectance)?;
    let tinted: Vec<[f64; 3]> = grey
        .patches
        .reflectance
        .iter()
        .map(|r| [r[0], r[1], r[2] * (1.0 - 1e-12)])
        .collect();
    let (t_rgb, sr) = system(&grey, &tinted)?;
    let diff = sg
        .radiance
        .iter()
        .zip(&sr.radiance)
        .map(|(a, b)| (a[0] - b[0]).abs() / b[0])
        .fold(0.0, f64::max);
    rows.push(SkipRow {
        skip: "grey scene: one channel",
        scene: "furnace room ρ = 0.9, solve only",
        before: t_rgb,
        after: t_grey,
        counter: format!("grey {} vs {}", sg.grey, sr.grey),
        same: format!("max rel. diff {diff:.1e} (ρ_blue changed by 1e-12)"),
    });
    // 10. The solve stops at the tolerance.
    let mut fixed = fs.solver;
    fixed.tolerance = 1e-300;
    fixed.max_iterations = 200;
    let sys = System {
        form_factors: &grey.form_factors,
        reflectance: &grey.patches.reflectance,
        emission: &grey.patches.emission,
    };
    let t = Instant::now();
    let all = solve::solve(&sys, &fixed)?;
    let t_fixed = t.elapsed().as_secs_f64();
    rows.push(SkipRow {
        skip: "solve stops at the tolerance (1e-10)",
        scene: "furnace room ρ = 0.9 (before: until a sweep changes nothing)",
        before: t_fixed,
        after: t_grey,
        counter: format!("iterations {} vs {}", sg.iterations, all.iterations),
        same: format!("residual {:.1e} vs {:.1e}", sg.residual, all.residual),
    });

    let mut csv = String::from("skip,scene,before_s,after_s,speedup,counter,same\n");
    let mut md = String::from(
        "| skip | scene | without (s) | with (s) | gain | counter in --report | answer |\n|---|---|---|---|---|---|---|\n",
    );
    for r in &rows {
        let gain = r.before / r.after.max(1e-9);
        writeln!(
            csv,
            "{},{},{:.4},{:.4},{:.2},\"{}\",\"{}\"",
            r.skip, r.scene, r.before, r.after, gain, r.counter, r.same
        )?;
        writeln!(
            md,
            "| {} | {} | {:.3} | {:.3} | {:.1}× | {} | {} |",
            r.skip, r.scene, r.before, r.after, gain, r.counter, r.same
        )?;
    }
    std::fs::write(args.out.join("skips.csv"), csv)?;
    Ok(md)
}

// ---------------------------------------------------------------------------------------------
// Solvers

fn solvers(args: &Args) -> Result<String> {
    // The furnace room, hemisphere rows (exact sums): every solver's error is its own.
    let scene = scenes::furnace_room(0.5, 1.0)?;
    let mut s = settings(if args.quick { 0.2 } else { 0.12 });
    s.form_factors.estimator = Estimator::Hemisphere;
    s.form_factors.rays = 256;
    s.refine_rounds = 0;
    // No solve here (bounces 0), but the whole F: every solver below reads it.
    s.solver.method = Method::Neumann;
    s.solver.bounces = 0;
    s.form_factors.shortcuts.skip_unneeded = false;
    let (out, _) = run(&scene, &s)?;
    let n = out.patches.len();
    let max_row = out.form_factors.row_sums().into_iter().fold(0.0, f64::max);
    // Only the room's ceiling emits: with uniform emission the furnace's answer is a multiple
    // of Le, which conjugate gradient finds in one step; a lit ceiling exercises the spectrum.
    let emission: Vec<[f64; 3]> = out
        .patches
        .centroid
        .iter()
        .map(|c| if c.y > 1.0 - 1e-9 { [1.0; 3] } else { [0.0; 3] })
        .collect();
    let rhos = [0.5, 0.9, 0.99, 0.999];
    let solve_with = |rho: f64, method: Method, omega: f64| -> Result<(solve::Solution, f64)> {
        let reflectance = vec![[rho; 3]; n];
        let sys = System {
            form_factors: &out.form_factors,
            reflectance: &reflectance,
            emission: &emission,
        };
        let settings = solve::Settings {
            method,
            tolerance: 1e-6,
            max_iterations: 200_000,
            bounces: 0,
            omega: Some(omega),
        };
        let t = Instant::now();
        let sol = solve::solve(&sys, &settings)?;
        Ok((sol, t.elapsed().as_secs_f64()))
    };
    // Over-relaxation: sweeps of Gauss–Seidel against ω at each ρ.
    let omegas = [1.0, 1.1, 1.2, 1.3, 1.5, 1.7, 1.9];
    let mut omega_csv = String::from("rho,omega,sweeps,seconds\n");
    let mut best_omega = Vec::new();
    for &rho in &rhos {
        let mut best = (u32::MAX, 1.0);
        for &w in &omegas {
            // Over-relaxation can diverge; that is a result here, not a failure.
            match solve_with(rho, Method::GaussSeidel, w) {
                Ok((sol, t)) => {
                    writeln!(omega_csv, "{rho},{w:.1},{},{t:.4}", sol.iterations)?;
                    if sol.converged && sol.iterations < best.0 {
                        best = (sol.iterations, w);
                    }
                }
                Err(e) => writeln!(omega_csv, "{rho},{w:.1},diverged,\"{e}\"")?,
            }
        }
        best_omega.push(best.1);
    }
    std::fs::write(args.out.join("omega.csv"), omega_csv)?;
    let mut csv = String::from("rho,solver,omega,sweeps,seconds,residual,factor,theory\n");
    let mut residuals = String::from("rho,solver,sweep,residual\n");
    let mut md = format!(
        "The furnace room (closed, two boxes inside), {n} patches, hemisphere rows (max row sum \
         {max_row:.6}), only the ceiling emitting, one channel (grey); to relative residual 1e-6. Convergence factor: geometric mean of the \
         residual ratio over the second half of the sweeps (Southwell: per n = {n} shots).\n\n\
         | ρ | solver | sweeps | seconds | factor per sweep | theory |\n|---|---|---|---|---|---|\n"
    );
    let mut curves: Vec<Curve> = Vec::new();
    for (k, &rho) in rhos.iter().enumerate() {
        let kappa = (1.0 + rho) / (1.0 - rho);
        let cg_bound = (kappa.sqrt() - 1.0) / (kappa.sqrt() + 1.0);
        for (name, method, omega, theory) in [
            (
                "jacobi",
                Method::Jacobi,
                1.0,
                format!("ρ·max row sum = {:.4}", rho * max_row),
            ),
            (
                "gauss-seidel",
                Method::GaussSeidel,
                1.0,
                format!("≈ (ρ·max row sum)² = {:.4}", (rho * max_row).powi(2)),
            ),
            ("gauss-seidel (SOR)", Method::GaussSeidel, best_omega[k], {
                let j = rho * max_row;
                let w = 2.0 / (1.0 + (1.0 - j * j).sqrt());
                format!("≈ ω_opt − 1 = {:.4} at ω_opt = {w:.2}", w - 1.0)
            }),
            (
                "cg",
                Method::Cg,
                1.0,
                format!("≤ (√κ−1)/(√κ+1) = {cg_bound:.4}"),
            ),
            ("southwell", Method::Southwell, 1.0, String::from("–")),
        ] {
            let (sol, t) = solve_with(rho, method, omega)?;
            let h = &sol.residual_history;
            let tail = &h[h.len() / 2..];
            let factor = if tail.len() >= 2 && tail[0] > 0.0 {
                (tail[tail.len() - 1] / tail[0]).powf(1.0 / (tail.len() - 1) as f64)
            } else {
                f64::NAN
            };
            let label = if method == Method::GaussSeidel && omega != 1.0 {
                format!("{name} ω = {omega:.1}")
            } else {
                name.to_string()
            };
            let sweeps = if method == Method::Southwell {
                format!(
                    "{:.1} ({} shots)",
                    sol.iterations as f64 / n as f64,
                    sol.iterations
                )
            } else {
                sol.iterations.to_string()
            };
            writeln!(
                csv,
                "{rho},{name},{omega:.1},{},{t:.4},{:.3e},{factor:.5},\"{theory}\"",
                sol.iterations, sol.residual
            )?;
            writeln!(
                md,
                "| {rho} | {label} | {sweeps} | {t:.3} | {factor:.4} | {theory} |{}",
                if sol.converged {
                    ""
                } else {
                    " (not converged)"
                }
            )?;
            for (i, r) in h.iter().enumerate() {
                writeln!(residuals, "{rho},{label},{},{r:e}", i + 1)?;
            }
            if rho == 0.99 {
                curves.push(Curve {
                    label: label.clone(),
                    points: h
                        .iter()
                        .enumerate()
                        .map(|(i, &r)| ((i + 1) as f64, r))
                        .collect(),
                    colour: curves.len(),
                    style: 0,
                });
            }
        }
    }
    std::fs::write(args.out.join("solvers.csv"), csv)?;
    std::fs::write(args.out.join("solver_residuals.csv"), residuals)?;
    let text = load_font();
    chart(
        &args.out.join("solver_residuals.png"),
        "Relative residual per sweep, furnace ρ = 0.99",
        ("sweep", "relative residual"),
        true,
        &curves,
        text,
    )?;
    writeln!(
        md,
        "\nBest ω for Gauss–Seidel (fewest sweeps of ω ∈ {{1.0, 1.1, 1.2, 1.3, 1.5, 1.7, 1.9}}; \
         omega.csv has them all): {}.",
        rhos.iter()
            .zip(&best_omega)
            .map(|(r, w)| format!("ρ = {r}: {w:.1}"))
            .collect::<Vec<_>>()
            .join(", ")
    )?;
    Ok(md)
}

// ---------------------------------------------------------------------------------------------
// Scale

/// What a child run reports.
#[derive(serde::Deserialize, serde::Serialize, Debug, Clone)]
struct ChildResult {
    spec: String,
    patches: usize,
    nnz: u64,
    rays: u64,
    seconds: [f64; 4], // patches, bvh, form factors, solve
    total: f64,
    peak_bytes: u64,
    max_surface_error: f64,
    iterations: u32,
}

/// `estimator:max_edge:rays:refine[:threshold]`, e.g. `contour:60:0:2`.
fn child(spec: &str) -> Result<()> {
    let parts: Vec<&str> = spec.split(':').collect();
    let estimator = match parts[0] {
        "hemisphere" => Estimator::Hemisphere,
        _ => Estimator::Contour,
    };
    let mut s = settings(parts[1].parse()?);
    s.form_factors.estimator = estimator;
    s.form_factors.rays = parts[2].parse::<u32>()?.max(1);
    s.refine_rounds = parts[3].parse()?;
    if let Some(th) = parts.get(4) {
        s.refine_threshold = th.parse()?;
    }
    let scene = cornell()?;
    let (out, total) = run(&scene, &s)?;
    let r = &out.report;
    let error = surface_error(&scene, &out).unwrap_or(f64::NAN);
    let res = ChildResult {
        spec: spec.into(),
        patches: r.patches,
        nnz: r.form_factors.nnz,
        rays: r.form_factors.rays_cast,
        seconds: [
            r.seconds.patches,
            r.seconds.bvh,
            r.seconds.form_factors,
            r.seconds.solve,
        ],
        total,
        peak_bytes: radiosity::pipeline::report::peak_memory_bytes().unwrap_or(0),
        max_surface_error: error,
        iterations: r.iterations,
    };
    println!("{}", serde_json::to_string(&res)?);
    Ok(())
}

/// Largest relative difference of two outcomes' per-surface means.
fn surface_difference(scene: &Scene, a: &Outcome, b: &Outcome) -> f64 {
    radiosity_tools::max_relative_difference(&surface_means(scene, a), &surface_means(scene, b))
}

/// Largest relative difference, over surfaces and channels, of the visible-area mean radiance
/// from the path-traced reference in docs/bench/cornell_reference.csv.
fn surface_error(scene: &Scene, out: &Outcome) -> Option<f64> {
    let reference = radiosity_tools::cornell_reference()?;
    Some(radiosity_tools::max_relative_difference(
        &surface_means(scene, out),
        &reference,
    ))
}

fn spawn(spec: &str) -> Result<ChildResult> {
    let exe = std::env::current_exe()?;
    let o = Command::new(exe).args(["--child", spec]).output()?;
    if !o.status.success() {
        bail!(
            "child {spec} failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let r: ChildResult = serde_json::from_slice(&o.stdout)?;
    eprintln!(
        "  {spec}: {} patches, {:.2} s, {:.0} MiB, error {:.2e}",
        r.patches,
        r.total,
        r.peak_bytes as f64 / (1 << 20) as f64,
        r.max_surface_error
    );
    Ok(r)
}

fn scale(args: &Args) -> Result<String> {
    let mut md = String::new();
    let mut csv = String::from(
        "spec,patches,nnz,rays,patches_s,bvh_s,form_factors_s,solve_s,total_s,peak_MiB,max_surface_error\n",
    );
    let mut table = |rows: &[ChildResult], title: &str, md: &mut String| -> Result<()> {
        writeln!(
            md,
            "\n{title}\n\n| run | patches | non-zeros | rays | form factors s | solve s | total s | peak MiB | bytes/patch | max surface error |\n|---|---|---|---|---|---|---|---|---|---|"
        )?;
        for r in rows {
            writeln!(
                csv,
                "{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.1},{:.3e}",
                r.spec,
                r.patches,
                r.nnz,
                r.rays,
                r.seconds[0],
                r.seconds[1],
                r.seconds[2],
                r.seconds[3],
                r.total,
                r.peak_bytes as f64 / (1 << 20) as f64,
                r.max_surface_error
            )?;
            writeln!(
                md,
                "| `{}` | {} | {:.3e} | {:.3e} | {:.2} | {:.2} | {:.2} | {:.0} | {:.0} | {:.1e} |",
                r.spec,
                r.patches,
                r.nnz as f64,
                r.rays as f64,
                r.seconds[2],
                r.seconds[3],
                r.total,
                r.peak_bytes as f64 / (1 << 20) as f64,
                r.peak_bytes as f64 / r.patches as f64,
                r.max_surface_error
            )?;
        }
        Ok(())
    };
    // Scaling: uniform meshes, no refinement.
    let contour: Vec<f64> = if args.quick {
        vec![120.0, 60.0, 45.0]
    } else {
        vec![160.0, 120.0, 80.0, 60.0, 45.0, 35.0, 30.0]
    };
    let hemi: Vec<f64> = if args.quick {
        vec![60.0, 30.0]
    } else {
        vec![60.0, 30.0, 22.0, 15.0, 11.0]
    };
    let c_rows: Vec<ChildResult> = contour
        .iter()
        .map(|e| spawn(&format!("contour:{e}:0:0")))
        .collect::<Result<_>>()?;
    let h_rows: Vec<ChildResult> = hemi
        .iter()
        .map(|e| spawn(&format!("hemisphere:{e}:256:0")))
        .collect::<Result<_>>()?;
    table(
        &c_rows,
        "**Contour estimator, uniform meshes** (`estimator:max-edge:rays:refine`)",
        &mut md,
    )?;
    table(
        &h_rows,
        "**Hemisphere estimator, 256 rays per patch, uniform meshes**",
        &mut md,
    )?;
    let exponent = |rows: &[ChildResult], f: &dyn Fn(&ChildResult) -> f64| {
        let pts: Vec<(f64, f64)> = rows.iter().map(|r| (r.patches as f64, f(r))).collect();
        fit_order(&pts).map_or(f64::NAN, |(p, _)| p)
    };
    writeln!(
        md,
        "\nFitted growth exponents (time or memory ∝ patches^p): contour form factors p = {:.2}, \
         solve p = {:.2}, peak memory p = {:.2}; hemisphere form factors p = {:.2}, solve p = \
         {:.2}, peak memory p = {:.2}.",
        exponent(&c_rows, &|r| r.seconds[2]),
        exponent(&c_rows, &|r| r.seconds[3]),
        exponent(&c_rows, &|r| r.peak_bytes as f64),
        exponent(&h_rows, &|r| r.seconds[2]),
        exponent(&h_rows, &|r| r.seconds[3]),
        exponent(&h_rows, &|r| r.peak_bytes as f64),
    )?;
    // The targets.
    let targets: Vec<ChildResult> = [
        "contour:60:0:2",
        "contour:60:0:3:0.2",
        "hemisphere:30:1024:0",
        if args.quick {
            "hemisphere:22:256:0"
        } else {
            "hemisphere:11:256:0"
        },
    ]
    .iter()
    .map(|s| spawn(s))
    .collect::<Result<_>>()?;
    table(
        &targets,
        "**The targets** (default settings; ~10k patches; ~100k patches)",
        &mut md,
    )?;
    std::fs::write(args.out.join("scale.csv"), csv)?;
    Ok(md)
}

// ---------------------------------------------------------------------------------------------
// Rays against Embree

/// An occlusion query: two points and the triangles they lie on.
type Segment = (glam::DVec3, glam::DVec3, [u32; 2]);

/// A closed room of 26 × 26 squares per face with ten boxes inside, 10,032 triangles (the
/// scene of `visibility::tests::throughput`), and 1M segments between random surface points.
fn ray_scene() -> (Vec<[glam::DVec3; 3]>, Vec<Segment>) {
    use glam::DVec3;
    let mut rng = form_factor::sampling::Rng::new(&[6]);
    let grid_box = |lo: DVec3, hi: DVec3, k: usize| {
        let mut out = Vec::new();
        for face in scenes::box_faces(lo, hi) {
            let [a, b, _, d] = face;
            let (u, v) = ((b - a) / k as f64, (d - a) / k as f64);
            for i in 0..k {
                for j in 0..k {
                    let p = a + u * i as f64 + v * j as f64;
                    out.push([p, p + u, p + u + v]);
                    out.push([p, p + u + v, p + v]);
                }
            }
        }
        out
    };
    let mut tris = grid_box(DVec3::ZERO, DVec3::splat(10.0), 26);
    for _ in 0..10 {
        let lo = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 7.5 + 0.5;
        let size = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) + 0.5;
        tris.extend(grid_box(lo, lo + size, 4));
    }
    let on = |t: &[DVec3; 3], rng: &mut form_factor::sampling::Rng| {
        let (u, v) = (rng.next_f64(), rng.next_f64());
        let (u, v) = if u + v > 1.0 {
            (1.0 - u, 1.0 - v)
        } else {
            (u, v)
        };
        t[0] + u * (t[1] - t[0]) + v * (t[2] - t[0])
    };
    let segments = (0..1_000_000)
        .map(|_| {
            let (i, j) = (rng.below(tris.len()), rng.below(tris.len()));
            (
                on(&tris[i], &mut rng),
                on(&tris[j], &mut rng),
                [i as u32, j as u32],
            )
        })
        .collect();
    (tris, segments)
}

fn rays(args: &Args) -> Result<String> {
    let (tris, segments) = ray_scene();
    let vis = Visibility::build(&tris);
    // One thread: rays per second per core.
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let (ours, blocked) = pool.install(|| {
        let t = Instant::now();
        let blocked = segments
            .iter()
            .filter(|s| vis.occluded(s.0, s.1, s.2))
            .count();
        (segments.len() as f64 / t.elapsed().as_secs_f64(), blocked)
    });
    // The same triangles and segments for Embree: f32 little-endian, counts first.
    let bin = args.out.join("rays.bin");
    let mut bytes = Vec::new();
    bytes.extend_from_slice(&(tris.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&(segments.len() as u64).to_le_bytes());
    for t in &tris {
        for v in t {
            for x in v.to_array() {
                bytes.extend_from_slice(&(x as f32).to_le_bytes());
            }
        }
    }
    for (p, q, _) in &segments {
        for x in p.to_array().into_iter().chain(q.to_array()) {
            bytes.extend_from_slice(&(x as f32).to_le_bytes());
        }
    }
    std::fs::write(&bin, bytes)?;
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/embree_rays.py");
    let o = Command::new("python3").arg(&script).arg(&bin).output()?;
    let text = String::from_utf8_lossy(&o.stdout).to_string();
    let mut md = format!(
        "{} triangles, {} segments between random surface points; occlusion (any hit), one \
         thread.\n\n| engine | rays/s per core | blocked |\n|---|---|---|\n| radiosity \
         (obvhs CWBVH + watertight test) | {:.2} M | {} |\n",
        tris.len(),
        segments.len(),
        ours / 1e6,
        blocked
    );
    match text.lines().find(|l| l.starts_with("embree")) {
        Some(line) => {
            // "embree <rays per second> <blocked>"
            let f: Vec<&str> = line.split_whitespace().collect();
            let theirs: f64 = f[1].parse()?;
            writeln!(
                md,
                "| Embree 4 (embreex, rtcOccluded1 per ray) | {:.2} M | {} |",
                theirs / 1e6,
                f[2]
            )?;
            writeln!(md, "\nRatio ours / Embree: **{:.2}**.", ours / theirs)?;
        }
        None => writeln!(
            md,
            "\nEmbree could not be run here: {}",
            String::from_utf8_lossy(&o.stderr)
                .lines()
                .last()
                .unwrap_or("no output")
        )?,
    }
    Ok(md)
}

// ---------------------------------------------------------------------------------------------
// Mat-vec bandwidth

fn matvec(args: &Args) -> Result<String> {
    let scene = cornell()?;
    let mut s = settings(if args.quick { 45.0 } else { 30.0 });
    s.refine_rounds = 0;
    s.form_factors.estimator = Estimator::Hemisphere;
    s.form_factors.rays = 2048;
    s.solver.method = Method::Neumann;
    s.solver.bounces = 0;
    s.form_factors.shortcuts.skip_unneeded = false;
    let (out, _) = run(&scene, &s)?;
    let m = &out.form_factors.matrix;
    let (n, nnz) = (m.rows(), m.nnz());
    let x: Vec<[f64; 3]> = (0..n).map(|i| [i as f64, 1.0, 0.5]).collect();
    let mut y = vec![[0.0f64; 3]; n];
    let reps = 20;
    let sys = System {
        form_factors: &out.form_factors,
        reflectance: &out.patches.reflectance,
        emission: &out.patches.emission,
    };
    let t = Instant::now();
    for _ in 0..reps {
        y.par_iter_mut().enumerate().for_each(|(i, yi)| {
            let (cols, vals) = sys.row(i);
            let mut acc = [0.0f64; 3];
            for (&j, &f) in cols.iter().zip(vals) {
                let xj = &x[j as usize];
                for c in 0..3 {
                    acc[c] += f as f64 * xj[c];
                }
            }
            *yi = acc;
        });
    }
    let secs = t.elapsed().as_secs_f64() / reps as f64;
    // Bytes the product must move at least: every value (f32) and column index (u32) once,
    // the row pointers, and L read and written once (x is small enough to stay in cache).
    let bytes = (nnz * 8 + (n + 1) * 4 + 2 * n * 24) as f64;
    // The machine's bandwidth, with every core, on 512 MiB (pages touched first, so no page
    // faults are timed): reading it (a sum, what a product mostly does) and copying it (read
    // + write counted).
    use rayon::prelude::*;
    let len = 64 << 20;
    let mut src: Vec<f64> = (0..len).into_par_iter().map(|i| i as f64).collect();
    let mut dst = vec![0.0f64; len];
    dst.par_chunks_mut(1 << 16).for_each(|d| d.fill(1.0));
    let t = Instant::now();
    let mut total = 0.0;
    for _ in 0..3 {
        // Eight independent sums per chunk: bound by memory, not by the latency of one chain.
        total += src
            .par_chunks(1 << 16)
            .map(|s| {
                let mut acc = [0.0f64; 8];
                for c in s.chunks_exact(8) {
                    for (a, x) in acc.iter_mut().zip(c) {
                        *a += x;
                    }
                }
                acc.iter().sum::<f64>()
            })
            .sum::<f64>();
    }
    let read = (3 * len * 8) as f64 / t.elapsed().as_secs_f64();
    std::hint::black_box(total);
    // Back and forth, so that no copy is a dead store the compiler may drop.
    let t = Instant::now();
    for k in 0..4 {
        let (to, from) = if k % 2 == 0 {
            (&mut dst, &src)
        } else {
            (&mut src, &dst)
        };
        to.par_chunks_mut(1 << 16)
            .zip(from.par_chunks(1 << 16))
            .for_each(|(d, s)| d.copy_from_slice(s));
        std::hint::black_box(&*to);
    }
    let copy = (4 * 2 * len * 8) as f64 / t.elapsed().as_secs_f64();
    let rate = bytes / secs;
    Ok(format!(
        "F of the Cornell box with {n} patches, {nnz} non-zeros (f32 values, u32 columns); y = F·x \
         for three channels at once with every core, mean of {reps}.\n\n| | bytes/s |\n|---|---|\n\
         | F·x ({:.1} ms, {:.0} MiB moved) | {:.2} GB/s |\n| memory read (sum), 512 MiB | {:.2} \
         GB/s |\n| memory copy, 512 MiB (read + write) | {:.2} GB/s |\n\nFraction of the read \
         bandwidth: **{:.2}**; of the copy bandwidth: {:.2}.\n",
        secs * 1e3,
        bytes / (1 << 20) as f64,
        rate / 1e9,
        read / 1e9,
        copy / 1e9,
        rate / read,
        rate / copy
    ))
}

// ---------------------------------------------------------------------------------------------
// The path-traced reference

fn reference(args: &Args) -> Result<String> {
    let scene = cornell()?;
    let (labels, count) = path_tracer::surfaces(&scene);
    let paths = if args.quick { 1_000_000 } else { 16_000_000 };
    let t = Instant::now();
    let means = path_tracer::surface_means(
        &scene,
        &labels,
        count,
        &path_tracer::Settings {
            paths_per_surface: paths,
            seed: 1,
        },
    );
    let secs = t.elapsed().as_secs_f64();
    let mut csv = String::from(
        "surface,material,area,visible_fraction,mean_r,mean_g,mean_b,se_r,se_g,se_b,visible_mean_r,visible_mean_g,visible_mean_b\n",
    );
    for (k, m) in means.iter().enumerate() {
        let t = labels
            .iter()
            .position(|&l| l as usize == k)
            .expect("a triangle");
        let material = &scene.materials[scene.triangles[t].material as usize].name;
        writeln!(
            csv,
            "{k},{material},{:.1},{:.5},{:.7e},{:.7e},{:.7e},{:.3e},{:.3e},{:.3e},{:.7e},{:.7e},{:.7e}",
            m.area,
            m.visible_fraction,
            m.mean[0],
            m.mean[1],
            m.mean[2],
            m.std_error[0],
            m.std_error[1],
            m.std_error[2],
            m.visible_mean[0],
            m.visible_mean[1],
            m.visible_mean[2]
        )?;
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/bench/cornell_reference.csv");
    std::fs::write(&path, csv)?;
    Ok(format!(
        "Path-traced reference of the Cornell box: {count} surfaces, {paths} paths each, seed 1, \
         {secs:.0} s; written to {}.\n",
        path.display()
    ))
}
