//! What the harness writes: the fitted convergence orders, the CSV files, the summary for
//! BENCHMARKS.md and the charts.

use super::*;

/// One fitted order.
pub(super) struct Order {
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

pub(super) fn fit_orders(runs: &[Run]) -> Vec<Order> {
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

pub(super) fn write_runs_csv(path: &Path, runs: &[Run]) -> Result<()> {
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

pub(super) fn write_residuals_csv(path: &Path, study: &[SolverRun]) -> Result<()> {
    let mut s = String::from("method,rho,iteration,residual\n");
    for r in study {
        for (k, res) in r.history.iter().enumerate() {
            writeln!(s, "{},{},{},{:.6e}", r.method, r.rho, k + 1, res)?;
        }
    }
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

pub(super) fn write_orders_csv(path: &Path, orders: &[Order]) -> Result<()> {
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
pub(super) fn summary(
    args: &HarnessArgs,
    results: &Results,
    orders: &[Order],
    seconds: f64,
) -> String {
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
pub(super) fn plot_errors(dir: &Path, runs: &[Run], text: bool) -> Result<()> {
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
pub(super) fn plot_residuals(dir: &Path, study: &[SolverRun], text: bool) -> Result<()> {
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
