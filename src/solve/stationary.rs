//! The stationary methods: the Neumann series, Jacobi and block-parallel Gauss–Seidel with
//! over-relaxation. Each sweep is one pass over F with every channel gathered at once.

use rayon::prelude::*;

use super::{norm, Problem, Run, Settings};

/// Row blocks of the Gauss–Seidel sweep: the sequential part of a sweep is the lower
/// triangles of the diagonal blocks, 1/(2·BLOCKS) of F.
pub const BLOCKS: usize = 16;

/// y = K x = diag(ρ) F x, rows in parallel.
fn apply_k<const C: usize>(p: &Problem<C>, x: &[[f64; C]], y: &mut [[f64; C]]) {
    y.par_iter_mut().enumerate().for_each(|(i, yi)| {
        let g = p.gather(i, x);
        *yi = std::array::from_fn(|c| p.rho[i][c] * g[c]);
    });
}

/// E + KE + … + K^N E; stops early when a bounce adds exactly nothing.
pub(crate) fn neumann<const C: usize>(p: &Problem<C>, bounces: u32) -> Run<C> {
    let mut l = p.e.clone();
    let mut term = l.clone();
    let mut next = vec![[0.0; C]; l.len()];
    let mut done = 0;
    for _ in 0..bounces {
        apply_k(p, &term, &mut next);
        std::mem::swap(&mut term, &mut next);
        done += 1;
        if norm(&term) == 0.0 {
            break;
        }
        for (li, ti) in l.iter_mut().zip(&term) {
            for c in 0..C {
                li[c] += ti[c];
            }
        }
    }
    let residual = p.relative_residual(&l);
    Run {
        radiance: l,
        iterations: done,
        residual,
        residual_history: vec![residual],
        converged: true,
    }
}

/// Jacobi: L ← E + K L from L = E. The update is the residual of the iterate it replaces.
pub(crate) fn jacobi<const C: usize>(p: &Problem<C>, s: &Settings) -> Run<C> {
    let e_norm = p.e_norm();
    let mut l = p.e.clone();
    let mut next = vec![[0.0; C]; l.len()];
    let mut history = Vec::new();
    let mut clock = super::SweepClock::new(s.tolerance);
    let mut iterations = 0;
    let mut converged = false;
    while iterations < s.max_iterations {
        apply_k(p, &l, &mut next);
        for (x, e) in next.iter_mut().zip(&p.e) {
            for c in 0..C {
                x[c] += e[c];
            }
        }
        let diff: f64 = next
            .iter()
            .zip(&l)
            .map(|(a, b)| (0..C).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>())
            .sum::<f64>()
            .sqrt();
        std::mem::swap(&mut l, &mut next);
        iterations += 1;
        // Residual of the iterate just replaced; the new iterate's is ≤ ‖K‖ times smaller.
        let r_prev = diff / e_norm;
        history.push(r_prev);
        clock.report(iterations, r_prev);
        if r_prev <= s.tolerance {
            converged = true;
            break;
        }
    }
    let residual = p.relative_residual(&l);
    Run {
        radiance: l,
        iterations,
        residual,
        residual_history: history,
        converged: converged || residual <= s.tolerance,
    }
}

/// Gauss–Seidel / SOR, exactly (row i uses the new values of every row before it and the old
/// values of every row after it), with most of the work spread over the cores: each row's sum
/// Σ_j F_ij L_j is split by column into three parts,
///
/// - j > i: old values, known at the start of the sweep — all rows in parallel;
/// - j before the row's block: new values, known once the earlier blocks are done — the
///   block's rows in parallel;
/// - j in the row's block, j < i: the only truly sequential part, a 1/(2·[`BLOCKS`]) share of
///   the matrix.
///
/// Each row then moves ω of the way past its Gauss–Seidel value:
/// L_i ← L_i + ω (E_i + ρ_i Σ_j F_ij L_j − L_i). Every value is computed by the same
/// arithmetic in the same order whatever the thread count. The history records each sweep's
/// relative update ‖ΔL‖₂/‖E‖₂ (free); the true residual — one more pass over F — is computed
/// when the update falls below the tolerance, and the solve stops when it does too.
pub(crate) fn gauss_seidel<const C: usize>(p: &Problem<C>, s: &Settings) -> Run<C> {
    let n = p.len();
    let block = n.div_ceil(BLOCKS).max(1);
    let omega = s.omega.unwrap_or(1.0);
    let mut l = p.e.clone();
    let mut history = Vec::new();
    let mut clock = super::SweepClock::new(s.tolerance);
    let mut iterations = 0;
    let mut converged = false;
    let mut residual = p.relative_residual(&l);
    // Σ over a row's entries with columns in `range` of F_ij x_j.
    let partial = |i: usize, x: &[[f64; C]], range: std::ops::Range<usize>| {
        let (cols, vals) = p.system.row(i);
        let lo = cols.partition_point(|&j| (j as usize) < range.start);
        let hi = cols.partition_point(|&j| (j as usize) < range.end);
        let mut g = [0.0f64; C];
        for (&j, &f) in cols[lo..hi].iter().zip(&vals[lo..hi]) {
            let xj = &x[j as usize];
            for c in 0..C {
                g[c] += f as f64 * xj[c];
            }
        }
        g
    };
    let mut upper = vec![[0.0f64; C]; n];
    let mut before = vec![[0.0f64; C]; n];
    let e_norm = p.e_norm();
    while iterations < s.max_iterations {
        let mut update = 0.0f64;
        // Old values of the rows after each row.
        upper
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, u)| *u = partial(i, &l, i + 1..n));
        for start in (0..n).step_by(block) {
            let end = (start + block).min(n);
            // New values of the blocks before this one.
            before[start..end]
                .par_iter_mut()
                .enumerate()
                .for_each(|(r, w)| *w = partial(start + r, &l, 0..start));
            for i in start..end {
                let inner = partial(i, &l, start..i);
                for c in 0..C {
                    let g = before[i][c] + inner[c] + upper[i][c];
                    let gs = p.e[i][c] + p.rho[i][c] * g;
                    let step = omega * (gs - l[i][c]);
                    l[i][c] += step;
                    update += step * step;
                }
            }
        }
        iterations += 1;
        // The relative size of the sweep's update is free; the true residual costs a pass
        // over F, so it is computed only once the update is that small (a converging sweep
        // changes L by about its residual) and at the last allowed sweep.
        let step = update.sqrt() / e_norm;
        history.push(step);
        clock.report(iterations, step);
        if !step.is_finite() {
            residual = step;
            break;
        }
        if step <= s.tolerance || iterations == s.max_iterations {
            residual = p.relative_residual(&l);
            if residual <= s.tolerance {
                converged = true;
                break;
            }
        }
    }
    Run {
        radiance: l,
        iterations,
        residual,
        residual_history: history,
        converged,
    }
}
