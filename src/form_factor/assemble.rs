//! Putting F together: CSR assembly from the pair loop's per-task results and from whole
//! rows, and the row operations on the result (sums, scaling). All indices are `u32`; more
//! than `u32::MAX` entries is an error, not a wrap-around.

use sprs::CsMatI;

use crate::{Error, Result};

/// What task i produces: (column j, F_ij) for j > i, and (row j, F_ji) for j > i.
pub(super) type PairRows = (Vec<(u32, f32)>, Vec<(u32, f32)>);

/// Assemble CSR from per-task results: task i holds row i's entries right of the diagonal
/// (sorted by column) and, for each j > i, the entry (j, i) of row j. Rows are put together as
/// [lower entries in increasing column i] ++ [upper entries], so columns come out sorted.
pub(super) fn assemble(n: usize, rows: Vec<PairRows>) -> Result<CsMatI<f32, u32>> {
    let mut counts = vec![0usize; n + 1];
    for (i, (upper, lower)) in rows.iter().enumerate() {
        counts[i + 1] += upper.len();
        for &(j, _) in lower {
            counts[j as usize + 1] += 1;
        }
    }
    for i in 0..n {
        counts[i + 1] += counts[i];
    }
    let nnz = counts[n];
    if nnz > u32::MAX as usize {
        return Err(Error::Internal(format!(
            "{nnz} form factors do not fit 32-bit indices; use a larger --max-edge"
        )));
    }
    let mut indices = vec![0u32; nnz];
    let mut data = vec![0f32; nnz];
    let mut fill = counts.clone();
    // Lower-triangle entries: iterate tasks in increasing i so row j's columns are increasing.
    for (i, (_, lower)) in rows.iter().enumerate() {
        for &(j, f) in lower {
            let at = &mut fill[j as usize];
            indices[*at] = i as u32;
            data[*at] = f;
            *at += 1;
        }
    }
    for (i, (upper, _)) in rows.into_iter().enumerate() {
        for (j, f) in upper {
            let at = &mut fill[i];
            indices[*at] = j;
            data[*at] = f;
            *at += 1;
        }
    }
    let indptr: Vec<u32> = counts.iter().map(|&c| c as u32).collect();
    CsMatI::try_new((n, n), indptr, indices, data)
        .map_err(|e| Error::Internal(format!("CSR assembly: {}", e.3)))
}

/// CSR from complete rows (each sorted by column).
pub(super) fn assemble_rows(n: usize, rows: Vec<Vec<(u32, f32)>>) -> Result<CsMatI<f32, u32>> {
    let mut indptr = Vec::with_capacity(n + 1);
    indptr.push(0u32);
    let nnz: usize = rows.iter().map(|r| r.len()).sum();
    if nnz > u32::MAX as usize {
        return Err(Error::Internal(format!(
            "{nnz} form factors do not fit 32-bit indices"
        )));
    }
    let (mut indices, mut data) = (Vec::with_capacity(nnz), Vec::with_capacity(nnz));
    for row in rows {
        for (j, f) in row {
            indices.push(j);
            data.push(f);
        }
        indptr.push(indices.len() as u32);
    }
    CsMatI::try_new((n, n), indptr, indices, data)
        .map_err(|e| Error::Internal(format!("CSR assembly: {}", e.3)))
}

/// Σ_j F_ij per row, in f64.
pub(super) fn row_sums_of(m: &CsMatI<f32, u32>) -> Vec<f64> {
    m.outer_iterator()
        // `+ 0.0` turns the empty sum's −0.0 into 0.
        .map(|r| r.data().iter().map(|&f| f as f64).sum::<f64>() + 0.0)
        .collect()
}

/// Divide row i by `fraction[i]` where fraction > 0 and ≠ 1 (rows with fraction 0 are left).
pub(super) fn scale_rows(m: &mut CsMatI<f32, u32>, fraction: &[f64]) {
    let indptr: Vec<u32> = m.indptr().raw_storage().to_vec();
    let data = m.data_mut();
    for (i, &f) in fraction.iter().enumerate() {
        if f > 0.0 && f != 1.0 {
            for x in &mut data[indptr[i] as usize..indptr[i + 1] as usize] {
                *x = (*x as f64 / f) as f32;
            }
        }
    }
}
