//! The linear system of the discrete rendering equation, (I − K) L = E with K = diag(ρ)·F,
//! per RGB channel (Cohen & Wallace eq. 2.6 written for radiance: L_i = Le_i + ρ_i Σ_j F_ij L_j).
//! F is stored once (geometry only, f32 CSR); ρ is applied per channel on the fly, so the three
//! channels share every pass over F. This module owns the products with K and the residual.

use rayon::prelude::*;

use crate::form_factor::FormFactors;

/// An RGB triple (radiance in W·sr⁻¹·m⁻², or a dimensionless per-channel factor).
pub type Rgb = [f64; 3];

/// The system (I − K) L = E.
#[derive(Debug, Clone, Copy)]
pub struct System<'a> {
    /// Form factors F (row i gathers from columns j).
    pub form_factors: &'a FormFactors,
    /// ρ per patch and channel, in [0, 1].
    pub reflectance: &'a [Rgb],
    /// E = Le per patch and channel, W·sr⁻¹·m⁻².
    pub emission: &'a [Rgb],
}

impl System<'_> {
    /// Number of unknowns per channel (patches).
    pub fn len(&self) -> usize {
        self.emission.len()
    }

    /// True when there are no patches.
    pub fn is_empty(&self) -> bool {
        self.emission.is_empty()
    }

    /// Σ_j F_ij x_j for row i, three channels in one pass over the row.
    #[inline]
    pub fn gather(&self, i: usize, x: &[Rgb]) -> Rgb {
        let m = &self.form_factors.matrix;
        let indptr = m.indptr();
        let indptr = indptr.raw_storage();
        let (lo, hi) = (indptr[i] as usize, indptr[i + 1] as usize);
        let (cols, vals) = (&m.indices()[lo..hi], &m.data()[lo..hi]);
        let mut acc = [0.0f64; 3];
        for (&j, &f) in cols.iter().zip(vals) {
            let xj = &x[j as usize];
            let f = f as f64;
            acc[0] += f * xj[0];
            acc[1] += f * xj[1];
            acc[2] += f * xj[2];
        }
        acc
    }

    /// y = K x = diag(ρ) F x, rows in parallel.
    pub fn apply_k(&self, x: &[Rgb], y: &mut [Rgb]) {
        y.par_iter_mut().enumerate().for_each(|(i, yi)| {
            let g = self.gather(i, x);
            let r = self.reflectance[i];
            *yi = [r[0] * g[0], r[1] * g[1], r[2] * g[2]];
        });
    }

    /// ‖E‖₂ over all channels.
    pub fn emission_norm(&self) -> f64 {
        norm(self.emission)
    }

    /// Relative residual ‖E − (I − K) L‖₂ / ‖E‖₂ over all channels (0 when E = 0 and L = 0).
    pub fn relative_residual(&self, l: &[Rgb]) -> f64 {
        // Per-row terms in parallel, summed in a fixed order: the stopping decision must not
        // depend on the thread count.
        let terms: Vec<f64> = (0..self.len())
            .into_par_iter()
            .map(|i| {
                let g = self.gather(i, l);
                (0..3)
                    .map(|c| {
                        let r = self.emission[i][c] - l[i][c] + self.reflectance[i][c] * g[c];
                        r * r
                    })
                    .sum::<f64>()
            })
            .collect();
        let sq: f64 = terms.iter().sum();
        let e = self.emission_norm();
        if e == 0.0 {
            sq.sqrt()
        } else {
            sq.sqrt() / e
        }
    }
}

/// Euclidean norm over all channels.
pub fn norm(x: &[Rgb]) -> f64 {
    x.iter()
        .map(|v| v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        .sum::<f64>()
        .sqrt()
}
