//! Preconditioned conjugate gradient on the symmetric form of the radiosity system.
//!
//! Row i of L_i − ρ_i Σ_j F_ij L_j = E_i multiplied by a_i/ρ_i (a_i = the patch's visible area,
//! ρ_i > 0) reads (a_i/ρ_i) L_i − Σ_j a_i F_ij L_j = (a_i/ρ_i) E_i. With reciprocity
//! a_i F_ij = a_j F_ji the matrix M = diag(a/ρ) − A·F is symmetric, and since its rows are
//! strictly diagonally dominant (Σ_j a_i F_ij ≤ a_i < a_i/ρ_i for ρ_i < 1) it is positive
//! definite: conjugate gradient applies (Hestenes & Stiefel 1952; Saad, *Iterative Methods
//! for Sparse Linear Systems*, §9.2 for the preconditioned form). Estimated form factors are
//! reciprocal only up to their error, so A·F is replaced by its symmetric part
//! S = (A·F + (A·F)ᵀ)/2 — the system `--reciprocity` gives. Rows with ρ_i = 0 (or no visible
//! area) are eliminated per channel: L_i = E_i, moved to the right-hand side.
//!
//! The preconditioner is the diagonal a/ρ (Jacobi). The spectrum of the preconditioned
//! matrix lies in [1 − ρ_max, 1 + ρ_max], so the error falls per iteration by about
//! (√κ − 1)/(√κ + 1) with κ = (1 + ρ)/(1 − ρ): iterations grow as 1/√(1 − ρ) where Jacobi's
//! grow as 1/(1 − ρ). The three channels run as three independent recurrences sharing each
//! product with S. Dot products are summed in fixed chunks in a fixed order, so the result
//! does not depend on the thread count.

use rayon::prelude::*;

use super::{Problem, Run, Settings};
use crate::{form_factor, Result};

/// Rows per chunk of the fixed-order reductions.
const CHUNK: usize = 4096;

/// Σ_i f(i) over 0..n, in chunks of [`CHUNK`] summed in order.
pub(super) fn sum<const C: usize>(n: usize, f: impl Fn(usize) -> [f64; C] + Sync) -> [f64; C] {
    let parts: Vec<[f64; C]> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|k| {
            let mut s = [0.0; C];
            for i in k * CHUNK..((k + 1) * CHUNK).min(n) {
                let v = f(i);
                for c in 0..C {
                    s[c] += v[c];
                }
            }
            s
        })
        .collect();
    let mut s = [0.0; C];
    for p in parts {
        for c in 0..C {
            s[c] += p[c];
        }
    }
    s
}

pub(crate) fn solve<const C: usize>(p: &Problem<C>, s: &Settings) -> Result<Run<C>> {
    let n = p.len();
    let ff = p.system.form_factors;
    let area: Vec<f64> = (0..n)
        .map(|i| ff.area.get(i).copied().unwrap_or(0.0) * ff.visible_fraction[i])
        .collect();
    // F̃ with a_i F̃_ij = S_ij: the symmetric part, as a row-scaled F.
    let sym = form_factor::symmetric_part(&ff.matrix, &area)?;
    let row = |i: usize| {
        let m = &sym;
        let indptr = m.indptr();
        let indptr = indptr.raw_storage();
        let (lo, hi) = (indptr[i] as usize, indptr[i + 1] as usize);
        (&m.indices()[lo..hi], &m.data()[lo..hi])
    };
    // Active unknowns per channel; d = a/ρ on them.
    let active: Vec<[bool; C]> = (0..n)
        .map(|i| std::array::from_fn(|c| p.rho[i][c] > 0.0 && area[i] > 0.0))
        .collect();
    let d: Vec<[f64; C]> = (0..n)
        .map(|i| {
            std::array::from_fn(|c| {
                if active[i][c] {
                    area[i] / p.rho[i][c]
                } else {
                    1.0
                }
            })
        })
        .collect();
    // (S x)_i = a_i Σ_j F̃_ij x_j for active i (x zero on inactive j), 0 elsewhere.
    let s_times = |x: &[[f64; C]], y: &mut [[f64; C]]| {
        y.par_iter_mut().enumerate().for_each(|(i, yi)| {
            let (cols, vals) = row(i);
            let mut g = [0.0f64; C];
            for (&j, &f) in cols.iter().zip(vals) {
                let xj = &x[j as usize];
                for c in 0..C {
                    g[c] += f as f64 * xj[c];
                }
            }
            *yi = std::array::from_fn(|c| if active[i][c] { area[i] * g[c] } else { 0.0 });
        });
    };
    // Right-hand side: d E on active rows plus S E_inactive (the eliminated unknowns).
    let e_inactive: Vec<[f64; C]> = (0..n)
        .map(|i| std::array::from_fn(|c| if active[i][c] { 0.0 } else { p.e[i][c] }))
        .collect();
    let mut b = vec![[0.0; C]; n];
    s_times(&e_inactive, &mut b);
    for i in 0..n {
        for c in 0..C {
            b[i][c] = if active[i][c] {
                d[i][c] * p.e[i][c] + b[i][c]
            } else {
                0.0
            };
        }
    }
    // x0 = E on active rows (a good start: the emitted light), 0 on inactive ones.
    let mut x: Vec<[f64; C]> = (0..n)
        .map(|i| std::array::from_fn(|c| if active[i][c] { p.e[i][c] } else { 0.0 }))
        .collect();
    let mut q = vec![[0.0; C]; n];
    let apply_m = |x: &[[f64; C]], q: &mut [[f64; C]]| {
        s_times(x, q);
        q.par_iter_mut().enumerate().for_each(|(i, qi)| {
            for c in 0..C {
                qi[c] = if active[i][c] {
                    d[i][c] * x[i][c] - qi[c]
                } else {
                    0.0
                };
            }
        });
    };
    apply_m(&x, &mut q);
    let mut r: Vec<[f64; C]> = (0..n)
        .map(|i| std::array::from_fn(|c| b[i][c] - q[i][c]))
        .collect();
    // Residual in radiance units: (b − M x)/d is the residual of the (symmetrised) equation
    // L_i − E_i − ρ_i Σ_j F̃_ij L_j, comparable with the other methods'.
    let e_norm = p.e_norm();
    let relative = |r: &[[f64; C]]| {
        let sq: [f64; C] = sum(n, |i| std::array::from_fn(|c| (r[i][c] / d[i][c]).powi(2)));
        sq.iter().sum::<f64>().sqrt() / e_norm
    };
    let mut z: Vec<[f64; C]> = (0..n)
        .map(|i| std::array::from_fn(|c| r[i][c] / d[i][c]))
        .collect();
    let mut dir = z.clone();
    let mut rz: [f64; C] = sum(n, |i| std::array::from_fn(|c| r[i][c] * z[i][c]));
    let mut history = Vec::new();
    let mut residual = relative(&r);
    let mut iterations = 0;
    let mut converged = residual <= s.tolerance;
    while !converged && iterations < s.max_iterations {
        apply_m(&dir, &mut q);
        let dq: [f64; C] = sum(n, |i| std::array::from_fn(|c| dir[i][c] * q[i][c]));
        // A channel whose residual vanished has rz = 0: its step is 0 and it stays put.
        let alpha: [f64; C] =
            std::array::from_fn(|c| if dq[c] > 0.0 { rz[c] / dq[c] } else { 0.0 });
        x.par_iter_mut()
            .zip(r.par_iter_mut())
            .zip(z.par_iter_mut())
            .enumerate()
            .for_each(|(i, ((xi, ri), zi))| {
                for c in 0..C {
                    xi[c] += alpha[c] * dir[i][c];
                    ri[c] -= alpha[c] * q[i][c];
                    zi[c] = ri[c] / d[i][c];
                }
            });
        let rz_next: [f64; C] = sum(n, |i| std::array::from_fn(|c| r[i][c] * z[i][c]));
        let beta: [f64; C] =
            std::array::from_fn(|c| if rz[c] > 0.0 { rz_next[c] / rz[c] } else { 0.0 });
        rz = rz_next;
        dir.par_iter_mut().enumerate().for_each(|(i, di)| {
            for c in 0..C {
                di[c] = z[i][c] + beta[c] * di[c];
            }
        });
        iterations += 1;
        residual = relative(&r);
        history.push(residual);
        super::report_sweep(iterations, residual);
        converged = residual <= s.tolerance;
    }
    let radiance = (0..n)
        .map(|i| std::array::from_fn(|c| if active[i][c] { x[i][c] } else { p.e[i][c] }))
        .collect();
    Ok(Run {
        radiance,
        iterations,
        residual,
        residual_history: history,
        converged,
    })
}
