//! The solvers against a dense LU solve, and Jacobi's iterates against the Neumann series.

use radiosity::form_factor::Estimator;
use radiosity::scenes;
use radiosity::solve::{self, Method};

use crate::support::{assert_rel, dense_solve, max_rel_diff, run, settings};

/// A small coloured scene with occlusion and unequal ρ per channel: the furnace room at a
/// coarse resolution with its material recoloured.
fn small_scene() -> radiosity::scene::Scene {
    let mut scene = scenes::furnace_room(0.8, 1.0).unwrap();
    scene.materials[0].reflectance = [0.9, 0.6, 0.3];
    scene.materials[0].emission = [1.0, 2.0, 0.5];
    scene
}

#[test]
fn iterative_solvers_match_dense_lu() {
    let scene = small_scene();
    for method in [Method::Jacobi, Method::GaussSeidel] {
        let out = run(&scene, &settings(0.35, Estimator::Contour, 2, method, 0));
        assert!(
            out.patches.len() > 100 && out.patches.len() < 1500,
            "{}",
            out.patches.len()
        );
        assert!(out.solution.converged);
        let dense = dense_solve(&out);
        // Tolerance 1e-12 on the residual ⇒ error ≤ cond(I − K)·1e-12 ≈ 1e-11 at ρ ≤ 0.9;
        // the requirement is 1e-9.
        let diff = max_rel_diff(&dense, &out.solution.radiance);
        assert!(
            diff < 1e-9,
            "{method:?}: max relative difference {diff:.3e} from dense LU"
        );
    }
}

#[test]
fn neumann_with_many_bounces_matches_dense_lu() {
    let scene = small_scene();
    // ρ ≤ 0.9 and row sums ≤ 1: the tail after N bounces is ≤ 0.9^N/(1 − 0.9); N = 300 ⇒ 1e-13.
    let out = run(
        &scene,
        &settings(0.35, Estimator::Contour, 2, Method::Neumann, 300),
    );
    let diff = max_rel_diff(&dense_solve(&out), &out.solution.radiance);
    assert!(diff < 1e-9, "max relative difference {diff:.3e}");
}

#[test]
fn jacobi_after_n_sweeps_is_the_neumann_series() {
    let scene = small_scene();
    for n in [1, 2, 5] {
        let mut s = settings(0.35, Estimator::Contour, 2, Method::Jacobi, 0);
        s.solver.max_iterations = n;
        s.solver.tolerance = 1e-300;
        let jacobi = run(&scene, &s);
        assert!(!jacobi.solution.converged);
        assert_eq!(jacobi.solution.iterations, n);
        let neumann = run(
            &scene,
            &settings(0.35, Estimator::Contour, 2, Method::Neumann, n),
        );
        // Same operations in the same order up to the summation of the series: 1e-14.
        let diff = max_rel_diff(&neumann.solution.radiance, &jacobi.solution.radiance);
        assert!(diff < 1e-13, "N = {n}: {diff:.3e}");
    }
}

#[test]
fn gauss_seidel_needs_fewer_sweeps_than_jacobi() {
    let scene = small_scene();
    let mut s = settings(0.35, Estimator::Contour, 2, Method::Jacobi, 0);
    s.solver.tolerance = 1e-8;
    let j = run(&scene, &s);
    s.solver.method = Method::GaussSeidel;
    let g = run(&scene, &s);
    assert!(j.solution.converged && g.solution.converged);
    assert!(
        g.solution.iterations < j.solution.iterations,
        "GS {} vs Jacobi {}",
        g.solution.iterations,
        j.solution.iterations
    );
    assert!(g.solution.residual <= 1e-8 && j.solution.residual <= 1e-8);
}

#[test]
fn non_convergence_is_reported() {
    let scene = small_scene();
    let mut s = settings(0.35, Estimator::Contour, 2, Method::GaussSeidel, 0);
    s.solver.max_iterations = 3;
    s.solver.tolerance = 1e-12;
    let out = run(&scene, &s);
    assert!(!out.solution.converged);
    assert!(!out.report.converged);
    assert_eq!(out.solution.iterations, 3);
    assert!(out.solution.residual > 1e-12);
}

#[test]
fn no_emitters_gives_black_and_a_warning() {
    let mut scene = small_scene();
    scene.materials[0].emission = [0.0; 3];
    let out = run(
        &scene,
        &settings(0.35, Estimator::Contour, 1, Method::GaussSeidel, 0),
    );
    assert!(out.solution.radiance.iter().flatten().all(|&x| x == 0.0));
    assert!(out
        .report
        .warnings
        .iter()
        .any(|w| w.contains("no emitters")));
}

#[test]
fn invalid_solver_settings_are_usage_errors() {
    for (tol, iters) in [(0.0, 10), (-1.0, 10), (f64::NAN, 10), (1e-6, 0)] {
        let s = solve::Settings {
            method: Method::Jacobi,
            tolerance: tol,
            max_iterations: iters,
            bounces: 1,
        };
        assert!(matches!(s.validate(), Err(radiosity::Error::Usage { .. })));
    }
    let _ = assert_rel;
}
