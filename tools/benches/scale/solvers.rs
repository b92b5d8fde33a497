//! The `solvers` section: sweeps and seconds of every solver, over reflectance, with the SOR scan.

use super::*;

pub(super) fn solvers(args: &Args) -> Result<String> {
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
    let max_row = out
        .form_factors
        .as_ref()
        .expect("matrix method")
        .row_sums()
        .into_iter()
        .fold(0.0, f64::max);
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
            form_factors: out.form_factors.as_ref().expect("matrix method"),
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
