//! Shared helpers of the library's integration tests: approximate assertions that print
//! everything, scene runs with explicit settings, dense reference solves, paths.

use std::path::PathBuf;

use nalgebra::{DMatrix, DVector};
use radiosity::form_factor::{self, Estimator};
use radiosity::gather::Gather;
use radiosity::pipeline::{self, Outcome};
use radiosity::scene::Scene;
use radiosity::solve::{self, Method};
use radiosity::Rgb;

/// Assert |got − expected| ≤ tol·|expected| and say all four numbers when not.
#[track_caller]
pub fn assert_rel(what: &str, got: f64, expected: f64, tol: f64) {
    let err = (got - expected).abs() / expected.abs().max(f64::MIN_POSITIVE);
    assert!(
        err <= tol,
        "{what}: got {got}, expected {expected}, relative error {err:.3e} > tolerance {tol:.1e} \
         (difference {:.3e})",
        got - expected
    );
}

/// Pipeline settings with the given discretisation, estimator and solver.
pub fn settings(
    max_edge: f64,
    estimator: Estimator,
    samples: u32,
    method: Method,
    bounces: u32,
) -> pipeline::Settings {
    pipeline::Settings {
        max_edge: Some(max_edge),
        form_factors: form_factor::Settings {
            estimator,
            samples,
            seed: 7,
            ..form_factor::Settings::default()
        },
        solver: solve::Settings {
            method,
            tolerance: 1e-12,
            max_iterations: 100_000,
            bounces,
            ..solve::Settings::default()
        },
        // These tests read the solution (the patches' radiance), not the display: no final
        // gather, whose own tests are the library's (gather) and the command line's.
        gather: Gather::None,
        ..pipeline::Settings::default()
    }
}

/// The form factors of a matrix-method run.
pub fn ff(out: &Outcome) -> &radiosity::form_factor::FormFactors {
    out.form_factors
        .as_ref()
        .expect("a matrix-method run has form factors")
}

/// Run the pipeline (no file output) and panic with the error's text on failure.
pub fn run(scene: &Scene, settings: &pipeline::Settings) -> Outcome {
    pipeline::solve_scene(scene, settings).unwrap_or_else(|e| panic!("pipeline failed: {e}"))
}

/// Oracle: solve (I − K) L = E per channel with a dense LU decomposition (nalgebra).
#[allow(clippy::needless_range_loop)] // c indexes ρ, Le and L alike
pub fn dense_solve(out: &Outcome) -> Vec<Rgb> {
    let n = out.patches.len();
    let mut l = vec![[0.0; 3]; n];
    for c in 0..3 {
        let mut a = DMatrix::<f64>::identity(n, n);
        for (i, row) in out
            .form_factors
            .as_ref()
            .unwrap()
            .matrix
            .outer_iterator()
            .enumerate()
        {
            for (j, &f) in row.iter() {
                a[(i, j)] -= out.patches.reflectance[i][c] * f as f64;
            }
        }
        let e = DVector::from_iterator(n, (0..n).map(|i| out.patches.emission[i][c]));
        let x = a.lu().solve(&e).expect("I − K is non-singular for ρ < 1");
        for i in 0..n {
            l[i][c] = x[i];
        }
    }
    l
}

/// Largest relative difference between two radiance vectors (relative to the largest value).
pub fn max_rel_diff(a: &[Rgb], b: &[Rgb]) -> f64 {
    let scale = a.iter().flatten().fold(0.0f64, |m, &x| m.max(x.abs()));
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs()))
        .fold(0.0, f64::max)
        / scale
}

/// The repository's meshes/ folder.
pub fn meshes() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("meshes")
}

/// A fresh, empty temporary directory for one test.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("radiosity-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The shipped Cornell box OBJ.
pub fn cornell() -> String {
    meshes().join("cornell_box.obj").display().to_string()
}
