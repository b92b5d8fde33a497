//! The sweeps: each analytic scene and the Cornell box over resolution, estimator and sample
//! count, and the solver study; every run's errors measured as `radiosity verify` measures them.

use super::*;

/// Area-weighted mean of `f` over the patches `which`.
pub(super) fn area_mean(out: &Outcome, which: &[usize], f: impl Fn(usize) -> f64) -> f64 {
    let p = &out.patches;
    let area: f64 = which.iter().map(|&i| p.area[i]).sum();
    which.iter().map(|&i| p.area[i] * f(i)).sum::<f64>() / area
}

// ---------------------------------------------------------------------------------------------
// The scenes

/// Integrating sphere, radius 1, 30° cap, ρ = 0.5, Le = 1 (as in `verify::integrating_sphere`):
/// one bounce (Neumann N = 1) and all bounces (Gauss–Seidel) on the same F.
pub(super) fn sphere(plan: &Plan, results: &mut Results) -> Result<()> {
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
pub(super) fn furnace_errors(out: &Outcome, l: &[[f64; 3]], rho: f64) -> Vec<(String, f64)> {
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
pub(super) fn furnace(plan: &Plan, results: &mut Results) -> Result<()> {
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
pub(super) fn plates(plan: &Plan, results: &mut Results) -> Result<()> {
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
                let got = verify::surface_form_factor(&out, 1, 0).expect("matrix method");
                r.errors = vec![("form_factor_rel".into(), (got - expected).abs() / expected)];
                push(results, r);
            }
        }
    }
    Ok(())
}

pub(super) fn cornell(plan: &Plan, results: &mut Results) -> Result<()> {
    let path = radiosity_tools::root().join("meshes/cornell_box.obj");
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
pub(super) fn solver_study(plan: &Plan, results: &mut Results) -> Result<()> {
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
