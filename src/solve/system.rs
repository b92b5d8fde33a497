//! The linear system of the discrete rendering equation, (I − K) L = E with K = diag(ρ)·F,
//! per RGB channel (Cohen & Wallace eq. 2.6 written for radiance: L_i = Le_i + ρ_i Σ_j F_ij L_j).
//! F is stored once (geometry only, f32 CSR); ρ is applied per channel on the fly, so the
//! channels share every pass over F. This module owns the system's data ([`System`]), its
//! form in any number of channels that the methods iterate on ([`Problem`]: the gather of a
//! row, the residual) and the norm every stopping rule uses.

use rayon::prelude::*;

use crate::color::Rgb;
use crate::form_factor::FormFactors;

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

    /// Row i of F: its column indices (sorted) and values F_ij.
    #[inline]
    pub fn row(&self, i: usize) -> (&[u32], &[f32]) {
        let m = &self.form_factors.matrix;
        let indptr = m.indptr();
        let indptr = indptr.raw_storage();
        let (lo, hi) = (indptr[i] as usize, indptr[i + 1] as usize);
        (&m.indices()[lo..hi], &m.data()[lo..hi])
    }

    /// ‖E‖₂ over all channels.
    pub fn emission_norm(&self) -> f64 {
        norm(self.emission)
    }
}

/// A system in `C` channels: F shared, ρ and E per channel. The solvers are written once for
/// any channel count; a grey scene runs them with C = 1.
pub struct Problem<'a, const C: usize> {
    /// Form factors and visible areas (through [`System`]).
    pub system: &'a System<'a>,
    /// ρ per patch and channel.
    pub rho: Vec<[f64; C]>,
    /// E = Le per patch and channel.
    pub e: Vec<[f64; C]>,
}

impl<const C: usize> Problem<'_, C> {
    /// Number of patches.
    pub fn len(&self) -> usize {
        self.e.len()
    }

    /// True when there are no patches.
    pub fn is_empty(&self) -> bool {
        self.e.is_empty()
    }

    /// Σ_j F_ij x_j for row i, all channels in one pass over the row.
    #[inline]
    pub fn gather(&self, i: usize, x: &[[f64; C]]) -> [f64; C] {
        let (cols, vals) = self.system.row(i);
        let mut acc = [0.0f64; C];
        for (&j, &f) in cols.iter().zip(vals) {
            let xj = &x[j as usize];
            let f = f as f64;
            for c in 0..C {
                acc[c] += f * xj[c];
            }
        }
        acc
    }

    /// ‖E‖₂ over all channels.
    pub fn e_norm(&self) -> f64 {
        norm(&self.e)
    }

    /// Relative residual ‖E − (I − K) L‖₂ / ‖E‖₂ over all channels, summed in a fixed order
    /// (the stopping decision must not depend on the thread count).
    pub fn relative_residual(&self, l: &[[f64; C]]) -> f64 {
        let terms: Vec<f64> = (0..self.len())
            .into_par_iter()
            .map(|i| {
                let g = self.gather(i, l);
                (0..C)
                    .map(|c| {
                        let r = self.e[i][c] - l[i][c] + self.rho[i][c] * g[c];
                        r * r
                    })
                    .sum::<f64>()
            })
            .collect();
        let e = self.e_norm();
        let r = terms.iter().sum::<f64>().sqrt();
        if e == 0.0 {
            r
        } else {
            r / e
        }
    }
}

/// Euclidean norm over all entries and channels.
pub fn norm<const C: usize>(x: &[[f64; C]]) -> f64 {
    x.iter()
        .map(|v| v.iter().map(|a| a * a).sum::<f64>())
        .sum::<f64>()
        .sqrt()
}
