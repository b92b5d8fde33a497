//! The loop of the pair estimators (area, contour): every unordered pair {i, j} once, both
//! directions from the same rays ([`super::pair`]), rows in parallel, deterministic for any
//! thread count. Before the loop: which patches can occlude ([`super::occluders`]), the
//! sample points ([`super::samples`]) and what contact geometry buries ([`super::burial`]);
//! in the loop, per pair: skip it if the solve reads neither entry ([`Needed`]), take it from
//! the previous refinement round if both patches are unchanged ([`Reuse`]), else estimate it;
//! after it: assemble F and divide each row by its patch's visible quadrature weight.

use rayon::prelude::*;
use sprs::CsMatI;

use super::assemble::{assemble, scale_rows, PairRows};
use super::burial::Burial;
use super::occluders::Coarse;
use super::pair::{Pair, PairEstimator, PatchGeometry};
use super::samples::SamplePoints;
use super::{occluders, Needed, Reuse, Settings, Stats};
use crate::mesh::Patches;
use crate::visibility::{Visibility, NONE};
use crate::Result;

/// Counters of one row's task, summed after the loop.
#[derive(Default)]
struct Counts {
    rays: u64,
    culled: u64,
    skipped: u64,
    reused: u64,
}

/// F of the pair estimators for `needed`, reusing `reuse` where it can; fills the pair
/// counters of `stats`, and `visible_fraction` unless the scene is a convex enclosure.
pub(super) fn pairwise(
    patches: &Patches,
    vis: &Visibility,
    settings: &Settings,
    needed: &Needed,
    reuse: Option<&Reuse>,
    stats: &mut Stats,
    visible_fraction: &mut Vec<f64>,
) -> Result<CsMatI<f32, u32>> {
    let n = patches.len();
    // Only patches off the convex hull can block a segment: trace against those alone.
    let occluder_mask = if settings.shortcuts.skip_hull {
        occluders(patches)
    } else {
        vec![true; n]
    };
    stats.occluder_patches = occluder_mask.iter().filter(|&&o| o).count() as u64;
    let convex = stats.occluder_patches == 0;
    stats.convex_enclosure = convex;
    // Traced as the scene triangles the occluding patches were cut from, in `vis`'s frame
    // (the sample points are prepared in it).
    let coarse = Coarse::of(patches, &occluder_mask);
    let blockers = vis
        .in_frame_of(&coarse.triangles)
        .with_transmittance(&coarse.transmittance);
    stats.occluder_triangles = coarse.triangles.len() as u64;
    // The sample points of every patch, and which of them contact geometry buries.
    let samples = SamplePoints::place(patches, vis, settings);
    let mut burial = Burial::find(patches, vis, &samples, convex);
    stats.rays_cast += burial.rays;
    if let Some(fraction) = burial.visible_fraction.take() {
        *visible_fraction = fraction;
    }
    let geometry = PatchGeometry::of_all(patches);
    let estimator = PairEstimator {
        settings,
        samples: &samples,
        burial: &burial,
        blockers: &blockers,
        occluder_of: &coarse.of_patch,
        convex,
        geometry: &geometry,
    };
    let visible = &burial.quadrature_visible;

    // Task i: (j, F_ij) and (j, F_ji) for every j > i.
    let progress =
        crate::progress::stage("form factors", Some((n * n.saturating_sub(1) / 2) as u64));
    let tasks: Vec<(PairRows, Counts)> = (0..n)
        .into_par_iter()
        // One scratch per worker (its light buffers are re-aimed at each row's points).
        .map_init(
            || estimator.scratch(),
            |scratch, i| {
                progress.advance((n - i - 1) as u64);
                let (mut upper, mut lower) = (Vec::new(), Vec::new());
                let mut counts = Counts::default();
                // Row i of the earlier F and of its transpose (column i), walked in step with j.
                let mut old = reuse.and_then(|r| r.rows(i));
                for j in i + 1..n {
                    let need = (needed.entry(i, j), needed.entry(j, i));
                    if need == (false, false) {
                        counts.skipped += 1;
                        continue;
                    }
                    let oj = reuse.map_or(NONE, |r| r.old_of_new[j]);
                    if let Some(rows) = old.as_mut().filter(|_| oj != NONE) {
                        // Both unchanged: the earlier entries, back to the unscaled form (rows are
                        // divided by the visible weight below).
                        counts.reused += 1;
                        let (fij, fji) = rows.next(oj);
                        if need.0 && fij > 0.0 {
                            upper.push((j as u32, (fij * visible[i]) as f32));
                        }
                        if need.1 && fji > 0.0 {
                            lower.push((j as u32, (fji * visible[j]) as f32));
                        }
                        continue;
                    }
                    match estimator.estimate(i, j, need, scratch) {
                        Pair::Culled => counts.culled += 1,
                        Pair::Estimated { fij, fji, rays } => {
                            counts.rays += rays as u64;
                            // An unneeded direction is zero (its gathering points count as buried).
                            if fij > 0.0 {
                                upper.push((j as u32, fij as f32));
                            }
                            if fji > 0.0 {
                                lower.push((j as u32, fji as f32));
                            }
                        }
                    }
                }
                ((upper, lower), counts)
            },
        )
        .collect();

    let mut rows = Vec::with_capacity(n);
    for (task, counts) in tasks {
        rows.push(task);
        stats.rays_cast += counts.rays;
        stats.pairs_culled += counts.culled;
        stats.pairs_skipped += counts.skipped;
        stats.pairs_reused += counts.reused;
    }
    stats.pairs = (n as u64) * (n as u64).saturating_sub(1) / 2;
    let mut matrix = assemble(n, rows)?;
    // Each row was integrated over the whole patch with zero from its buried points: divide
    // by the visible weight so the row describes the visible part, whose radiance is what the
    // rest of the scene sees (hidden-area elimination).
    scale_rows(&mut matrix, visible);
    Ok(matrix)
}
