//! Southwell iteration, i.e. progressive refinement radiosity (Cohen, Chen, Wallace &
//! Greenberg, SIGGRAPH 1988): keep the radiance L and the unshot radiance U (both start at E);
//! repeatedly pick the patch i with the most unshot power A_i·ΣU_i and shoot it — every patch
//! j receives ρ_j F_ji U_i, added to both L_j and U_j — then set U_i = 0. The invariant
//! L = E + K (L − U) holds throughout (all light but U has been propagated), so the residual
//! E − (I − K) L equals K U: the iteration converges as the unshot light is absorbed, and
//! the brightest sources go first, which is why a few shots already give a useful picture.
//!
//! Shooting reads column i of F (F_ji for every j), so F is transposed once. The choice of
//! the next patch is a scan over all patches (ties to the lowest index), sequential and
//! deterministic. The residual ‖K U‖₂ / ‖E‖₂ is evaluated every n shots (a "sweep" of work,
//! one product with F), which is also when the stopping rule is checked.

use sprs::CsMatI;

use super::{Problem, Run, Settings};

pub(crate) fn solve<const C: usize>(p: &Problem<C>, s: &Settings) -> Run<C> {
    let n = p.len();
    let ff = p.system.form_factors;
    let columns: CsMatI<f32, u32> = ff.matrix.transpose_view().to_csr();
    let area: Vec<f64> = (0..n)
        .map(|i| ff.area.get(i).copied().unwrap_or(1.0))
        .collect();
    let mut l = p.e.clone();
    let mut unshot = p.e.clone();
    let e_norm = p.e_norm();
    let residual_of = |u: &[[f64; C]]| {
        // ‖K U‖₂ / ‖E‖₂.
        let sq: f64 = (0..n)
            .map(|i| {
                let g = p.gather(i, u);
                (0..C).map(|c| (p.rho[i][c] * g[c]).powi(2)).sum::<f64>()
            })
            .sum();
        sq.sqrt() / e_norm
    };
    let mut history = Vec::new();
    let mut shots: u64 = 0;
    let max_shots = s.max_iterations as u64 * n as u64;
    let mut residual = residual_of(&unshot);
    let mut converged = residual <= s.tolerance;
    while !converged && shots < max_shots {
        // The patch with the most unshot power.
        let (mut best, mut best_power) = (usize::MAX, 0.0);
        for (i, u) in unshot.iter().enumerate() {
            let power = area[i] * u.iter().sum::<f64>();
            if power > best_power {
                (best, best_power) = (i, power);
            }
        }
        if best == usize::MAX {
            // Nothing left to shoot: the solution is exact.
            residual = 0.0;
            converged = true;
            break;
        }
        let u = std::mem::replace(&mut unshot[best], [0.0; C]);
        if let Some(col) = columns.outer_view(best) {
            for (j, &f) in col.iter() {
                for c in 0..C {
                    let dl = p.rho[j][c] * f as f64 * u[c];
                    l[j][c] += dl;
                    unshot[j][c] += dl;
                }
            }
        }
        shots += 1;
        if shots.is_multiple_of(n as u64) || shots == max_shots {
            residual = residual_of(&unshot);
            history.push(residual);
            super::report_sweep((shots / n as u64) as u32, residual);
            converged = residual <= s.tolerance;
        }
    }
    Run {
        radiance: l,
        iterations: shots.min(u32::MAX as u64) as u32,
        residual,
        residual_history: history,
        converged,
    }
}
