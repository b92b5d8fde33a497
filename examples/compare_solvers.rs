//! User task: compare the solvers on one scene.
//!
//! `cargo run --release --example compare_solvers`: the furnace room at ρ = 0.9 solved by
//! Jacobi, Gauss–Seidel, conjugate gradient, Southwell shooting and the Neumann series, with
//! sweeps (Southwell: shots), residual, seconds and the error against the closed form
//! L = Le/(1 − ρ).

use std::time::Instant;

use radiosity::form_factor::{self, Estimator, FormFactors};
use radiosity::mesh;
use radiosity::solve::System;
use radiosity::solve::{self, Method, Solution};
use radiosity::validation::{closed_forms, scenes};
use radiosity::visibility::Visibility;

fn solve_all(rho: f64, max_edge: f64) -> radiosity::Result<Vec<(Method, Solution, f64, f64)>> {
    let scene = scenes::furnace_room(rho, 1.0)?;
    let patches = mesh::subdivide(&scene, max_edge, mesh::DEFAULT_CREASE_DEGREES)?;
    let tris: Vec<_> = (0..patches.len()).map(|i| patches.corners(i)).collect();
    // Hemisphere shooting: exact row sums in a closed room, so every solver's error is its own.
    let settings = form_factor::Settings {
        estimator: Estimator::Hemisphere,
        rays: 256,
        ..Default::default()
    };
    let ff: FormFactors = form_factor::compute(
        &patches,
        &Visibility::build(&tris),
        &settings,
        &form_factor::Needed::all(patches.len()),
    )?;
    let system = System {
        form_factors: &ff,
        reflectance: &patches.reflectance,
        emission: &patches.emission,
    };
    let expected = closed_forms::furnace_radiance(rho, 1.0);
    let mut rows = Vec::new();
    for method in [
        Method::Jacobi,
        Method::GaussSeidel,
        Method::Cg,
        Method::Southwell,
        Method::Neumann,
    ] {
        let s = solve::Settings {
            method,
            tolerance: 1e-8,
            max_iterations: 100_000,
            bounces: 200,
            ..solve::Settings::default()
        };
        let t = Instant::now();
        let sol = solve::solve(&system, &s)?;
        let seconds = t.elapsed().as_secs_f64();
        let err = sol
            .radiance
            .iter()
            .map(|l| (l[0] - expected).abs() / expected)
            .fold(0.0, f64::max);
        rows.push((method, sol, seconds, err));
    }
    Ok(rows)
}

fn main() -> radiosity::Result<()> {
    println!(
        "{:<14} {:>8} {:>10} {:>9} {:>10}",
        "solver", "sweeps", "residual", "seconds", "max error"
    );
    for (method, sol, seconds, err) in solve_all(0.9, 0.15)? {
        println!(
            "{:<14} {:>8} {:>10.2e} {:>9.3} {:>10.2e}",
            method.name(),
            sol.iterations,
            sol.residual,
            seconds,
            err
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_solver_reaches_the_furnace_answer() {
        let rows = super::solve_all(0.9, 0.35).unwrap();
        for (method, sol, _, err) in &rows {
            // Rows sum to 1 (f32 storage ~1e-7, ×1/(1 − ρ) = 10); tolerance 1e-8 (×10);
            // Neumann's 200-bounce tail is 0.9^201/0.1 ≈ 6e-9: all well under 1e-5.
            assert!(*err < 1e-5, "{method:?}: {err}");
            assert!(sol.converged);
        }
        // Gauss–Seidel needs fewer sweeps than Jacobi, and CG fewer still.
        assert!(rows[1].1.iterations < rows[0].1.iterations);
        assert!(rows[2].1.iterations < rows[1].1.iterations);
    }
}
