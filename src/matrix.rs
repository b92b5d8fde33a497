//! The linear system of the discrete rendering equation, (I − K) L = E with K = diag(ρ)·F,
//! per RGB channel (Cohen & Wallace eq. 2.6 written for radiance: L_i = Le_i + ρ_i Σ_j F_ij L_j).
//! F is stored once (geometry only, f32 CSR); ρ is applied per channel on the fly, so the
//! channels share every pass over F. This module owns the system's data; the products with K
//! and the residual live with the solvers ([`crate::solve::Problem`]).

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
        crate::solve::norm(self.emission)
    }
}
