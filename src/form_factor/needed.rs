//! Which entries of F the solve will read ([`Needed`]): the estimators skip the rest.

use crate::mesh::Patches;

/// Which entries F_ij the solve will read: row i when patch i reflects (ρ_i > 0 in some
/// channel: a black patch's radiance is its Le whatever F says), column j when patch j's
/// radiance is gathered at all (with one bounce, only emitters' is). [`super::compute`] skips every
/// pair that needs neither F_ij nor F_ji — no rays, no integrals — and leaves unneeded
/// entries out of F. Rows are all computed when they are rescaled to 1 in a closed scene or
/// symmetrised (`reciprocity`), which need the whole row.
#[derive(Debug, Clone, PartialEq)]
pub struct Needed {
    /// Row i is needed.
    pub rows: Vec<bool>,
    /// Column j is needed.
    pub columns: Vec<bool>,
}

impl Needed {
    /// Every entry.
    pub fn all(n: usize) -> Self {
        Needed {
            rows: vec![true; n],
            columns: vec![true; n],
        }
    }

    /// What a solve of these patches reads: rows of reflecting patches; with `bounces` =
    /// Some(1) (direct light only) only the emitters' columns, with Some(0) nothing.
    pub fn for_solve(patches: &Patches, bounces: Option<u32>) -> Self {
        let rows = patches
            .reflectance
            .iter()
            .map(|r| r.iter().any(|&x| x > 0.0))
            .collect();
        let columns = match bounces {
            Some(0) => vec![false; patches.len()],
            Some(1) => patches
                .emission
                .iter()
                .map(|e| e.iter().any(|&x| x > 0.0))
                .collect(),
            _ => vec![true; patches.len()],
        };
        Needed { rows, columns }
    }

    /// Entry (i, j) is needed.
    #[inline]
    pub fn entry(&self, i: usize, j: usize) -> bool {
        self.rows[i] && self.columns[j]
    }

    /// True when nothing is skipped.
    pub fn is_all(&self) -> bool {
        self.rows.iter().chain(&self.columns).all(|&x| x)
    }

    /// The same rows with every column.
    pub(super) fn whole_rows(&self) -> Self {
        Needed {
            rows: self.rows.clone(),
            columns: vec![true; self.columns.len()],
        }
    }
}
