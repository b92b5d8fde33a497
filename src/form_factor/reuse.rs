//! Reuse between refinement rounds: adaptive refinement splits a few patches and keeps the
//! rest, so a pair of patches that both survive unchanged (same corners, same source
//! triangle) keeps its two entries of the earlier F instead of being computed again (the
//! `reuse` shortcut). A reused entry equals what computing it again with the earlier indices
//! would give, up to one f32 rounding.

use std::collections::HashMap;

use sprs::CsMatI;

use super::{Estimator, FormFactors, Settings};
use crate::mesh::Patches;
use crate::visibility::NONE;

/// The pair estimators' F of an earlier patch mesh, for [`super::compute_reusing`].
pub struct Reuse<'a> {
    /// The earlier F as the pair estimator made it (before closed-scene normalisation or
    /// symmetrisation: [`FormFactors::pair_matrix`]).
    pub matrix: &'a CsMatI<f32, u32>,
    /// Its transpose (column j of the earlier F as row j), for F_ji.
    transpose: CsMatI<f32, u32>,
    /// For each new patch, its index in the earlier mesh, or [`NONE`].
    pub old_of_new: Vec<u32>,
}

impl<'a> Reuse<'a> {
    /// Reuse of `matrix` (F of the earlier mesh) with `old_of_new[i]` the earlier index of new
    /// patch i, or [`NONE`] where it is new.
    pub fn new(matrix: &'a CsMatI<f32, u32>, old_of_new: Vec<u32>) -> Reuse<'a> {
        Reuse {
            transpose: matrix.transpose_view().to_csr(),
            matrix,
            old_of_new,
        }
    }

    /// What `ff`, computed for the patches `old`, can give to their refinement `new`: `None`
    /// when it cannot serve: the shortcut is off, the estimator is hemisphere shooting (its
    /// rows change when any patch they hit is split), or `ff` was normalised or symmetrised
    /// without keeping the pair estimator's own matrix (as a cache hit gives).
    pub fn between(
        ff: &'a FormFactors,
        settings: &Settings,
        old: &Patches,
        new: &Patches,
    ) -> Option<Reuse<'a>> {
        let raw_known =
            ff.pair_matrix.is_some() || !(ff.stats.closed_scene || settings.reciprocity);
        if !(settings.shortcuts.reuse && raw_known && settings.estimator != Estimator::Hemisphere) {
            return None;
        }
        let old_index: HashMap<([u32; 3], u32), u32> = old
            .triangles
            .iter()
            .zip(&old.source_triangle)
            .enumerate()
            .map(|(k, (t, s))| ((*t, *s), k as u32))
            .collect();
        let old_of_new = new
            .triangles
            .iter()
            .zip(&new.source_triangle)
            .map(|(t, s)| old_index.get(&(*t, *s)).copied().unwrap_or(NONE))
            .collect();
        Some(Reuse::new(
            ff.pair_matrix.as_ref().unwrap_or(&ff.matrix),
            old_of_new,
        ))
    }

    /// Row `i` (a new index) of the earlier F and of its transpose, if patch i is unchanged.
    pub(super) fn rows(&self, i: usize) -> Option<OldRows<'_>> {
        let oi = self.old_of_new[i];
        (oi != NONE).then(|| {
            let a = self.matrix.outer_view(oi as usize).expect("row in range");
            let b = self
                .transpose
                .outer_view(oi as usize)
                .expect("row in range");
            OldRows {
                row: a.into_raw_storage(),
                col: b.into_raw_storage(),
                at: (0, 0),
            }
        })
    }
}

/// Row `oi` of an earlier F and of its transpose, read at increasing old columns `oj`
/// (unchanged patches keep their order through refinement, so a cursor moves forward; a step
/// back, should one happen, restarts with a binary search).
pub(super) struct OldRows<'a> {
    row: (&'a [u32], &'a [f32]),
    col: (&'a [u32], &'a [f32]),
    at: (usize, usize),
}

impl OldRows<'_> {
    /// (F_{oi,oj}, F_{oj,oi}) of the earlier F, 0 where absent.
    pub fn next(&mut self, oj: u32) -> (f64, f64) {
        fn seek(entries: (&[u32], &[f32]), at: &mut usize, oj: u32) -> f64 {
            let idx = entries.0;
            if *at > 0 && idx[*at - 1] >= oj {
                *at = idx.partition_point(|&c| c < oj);
            }
            while *at < idx.len() && idx[*at] < oj {
                *at += 1;
            }
            if *at < idx.len() && idx[*at] == oj {
                entries.1[*at] as f64
            } else {
                0.0
            }
        }
        (
            seek(self.row, &mut self.at.0, oj),
            seek(self.col, &mut self.at.1, oj),
        )
    }
}
