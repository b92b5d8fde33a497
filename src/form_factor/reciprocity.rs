//! Reciprocity enforced: a version of F with A_i F_ij = A_j F_ji exactly that keeps every
//! row's sum (`reciprocity` setting, and the symmetric form conjugate gradient solves).

use rayon::prelude::*;
use sprs::CsMatI;

use super::assemble::assemble_rows;
use crate::Result;

/// A reciprocal version F̃ of F: A_i F̃_ij = A_j F̃_ji exactly, with every row summing to what
/// it did (energy conservation is kept: a closed scene's rows still sum to 1). Rows with
/// A_i = 0 (no visible area) are left as they are.
///
/// The exchange matrix X = A·F is symmetric in theory (reciprocity) and only approximately
/// so when estimated. Its symmetric part X̄ = (X + Xᵀ)/2 is reciprocal but shifts light
/// between rows; the balanced S = D X̄ D, with the diagonal D chosen so that S's row sums
/// equal X's, is both (symmetric Sinkhorn–Knopp scaling, d ← √(d · t / (X̄ d)) from d = 1;
/// Knight, "The Sinkhorn–Knopp algorithm: convergence and applications", SIAM J. Matrix
/// Anal. Appl. 30(1), 2008). Iterates until every row sum is within 1e-10 (relative) or 500
/// rounds. Then F̃_ij = S_ij / A_i. Sparsity pattern: the union of F's and Fᵀ's.
pub fn symmetric_part(f: &CsMatI<f32, u32>, area: &[f64]) -> Result<CsMatI<f32, u32>> {
    let n = f.rows();
    let ft: CsMatI<f32, u32> = f.transpose_view().to_csr();
    // X̄ row by row, in f64: (column j, (A_i F_ij + A_j F_ji)/2); rows of A_i = 0 keep F.
    let rows: Vec<Vec<(u32, f64)>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let a = f.outer_view(i).expect("row in range");
            let b = ft.outer_view(i).expect("row in range");
            // Merge two sorted rows: F_ij from `a`, F_ji from `b` (row i of Fᵀ).
            let (ai, ad) = (a.indices(), a.data());
            let (bi, bd) = (b.indices(), b.data());
            let (mut p, mut q) = (0, 0);
            let mut out = Vec::with_capacity(ai.len().max(bi.len()));
            while p < ai.len() || q < bi.len() {
                let ja = ai.get(p).copied().unwrap_or(u32::MAX);
                let jb = bi.get(q).copied().unwrap_or(u32::MAX);
                let j = ja.min(jb);
                let fij = if ja == j {
                    p += 1;
                    ad[p - 1] as f64
                } else {
                    0.0
                };
                let fji = if jb == j {
                    q += 1;
                    bd[q - 1] as f64
                } else {
                    0.0
                };
                let both = area[i] > 0.0 && area[j as usize] > 0.0;
                let v = if both {
                    0.5 * (area[i] * fij + area[j as usize] * fji)
                } else {
                    fij
                };
                if v > 0.0 {
                    out.push((j, v));
                }
            }
            out
        })
        .collect();
    // Target row sums t_i = A_i Σ_j F_ij; scaling only where every partner has area.
    let target: Vec<f64> = (0..n)
        .map(|i| {
            let r = f.outer_view(i).expect("row in range");
            r.data().iter().map(|&x| x as f64).sum::<f64>() * area[i]
        })
        .collect();
    let balanced: Vec<bool> = (0..n).map(|i| area[i] > 0.0 && target[i] > 0.0).collect();
    let mut d = vec![1.0f64; n];
    for _ in 0..500 {
        let xd: Vec<f64> = (0..n)
            .into_par_iter()
            .map(|i| {
                rows[i]
                    .iter()
                    .filter(|(j, _)| balanced[*j as usize])
                    .map(|&(j, v)| v * d[j as usize])
                    .sum()
            })
            .collect();
        let worst = (0..n)
            .filter(|&i| balanced[i])
            .map(|i| (d[i] * xd[i] / target[i] - 1.0).abs())
            .fold(0.0, f64::max);
        if worst < 1e-10 {
            break;
        }
        for i in (0..n).filter(|&i| balanced[i] && xd[i] > 0.0) {
            d[i] = (d[i] * target[i] / xd[i]).sqrt();
        }
    }
    let rows: Vec<Vec<(u32, f32)>> = rows
        .into_iter()
        .enumerate()
        .map(|(i, row)| {
            row.into_iter()
                .map(|(j, v)| {
                    let ju = j as usize;
                    let f = if balanced[i] && balanced[ju] {
                        d[i] * v * d[ju] / area[i]
                    } else if area[i] > 0.0 && area[ju] > 0.0 {
                        v / area[i]
                    } else {
                        v
                    };
                    (j, f as f32)
                })
                .collect()
        })
        .collect();
    assemble_rows(n, rows)
}
