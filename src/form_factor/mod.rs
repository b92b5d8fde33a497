//! Form factors: estimating F_ij, the fraction of the energy leaving patch i that arrives at
//! patch j, for every pair of patches, with ray-cast visibility. This module owns the
//! estimators and the parallel loop over pairs; it hands a [`FormFactors`] (the sparse matrix
//! F plus counters) to the solver. It does not know about ρ or Le (only which entries the
//! solve will read, [`Needed`]).
//!
//! The quantity (Cohen & Wallace, *Radiosity and Realistic Image Synthesis*, eq. 4.12):
//!
//! F_ij = (1/A_i) ∫_Ai ∫_Aj cosθ_i cosθ_j / (π r²) · V(x, y) dA_j dA_i,
//!
//! with V the binary visibility. Every unordered pair {i, j} is visited once: the same
//! `samples` visibility rays serve both F_ij and F_ji, so reciprocity A_i F_ij = A_j F_ji holds
//! up to the estimators' error and no pair is ray-cast twice.
//!
//! Estimators ([`Estimator`]):
//! - `Area`: point pairs (x_k on i, y_k on j, stratified), F_ij ≈ A_j/n Σ G(x_k, y_k) V_k.
//!   The kernel G grows as 1/r² near a shared edge, where point pairs have huge variance, so
//!   pairs that are close relative to their size (r² < 16·max(A_i, A_j), centroid distance)
//!   switch to the exact point-to-polygon integrand of `Contour` for that pair.
//! - `Contour`: F_ij ≈ 1/n Σ F_{dA(x_k)→A_j} V_k, with the exact unoccluded point-to-polygon form
//!   factor (Lambert's contour integral,
//!   [`point_to_polygon`](crate::geometry::kernel::point_to_polygon)) at stratified points of i and
//!   the visibility of a ray x_k → y_k. Exact for unoccluded pairs up to the integration over i,
//!   including patches that share an edge; in a closed unoccluded scene each point's form factors
//!   sum to exactly 1.
//!
//! The receiving cosine cosθ_i is taken with the surface normal at the sample point
//! ([`Patches::surface_normal`]): the interpolated vertex normal where the mesh samples a
//! smooth surface, the facet's own on flat ones (see [`crate::mesh::corner_normals`]).
//!
//! Where each part lives: [`compute`] (this file) sequences the estimation (closure probes, the
//! estimator, closed-scene normalisation, reciprocity, counters); [`settings`] holds the
//! [`Estimator`], [`Settings`] and [`Shortcuts`]; the pair estimators' loop is `pairwise` (one
//! screen), one pair's estimate `pair` ([`kernel`](crate::geometry::kernel) has the integrands),
//! their sample points `samples` ([`sampling`](crate::sampling) the rules and random numbers),
//! buried points ([`Visibility::buried`]) (`burial`), the convex-hull skip [`occluders`] (whose
//! module also rebuilds the occluding scene triangles the rays are traced against), reuse between
//! refinement rounds [`Reuse`]; hemisphere shooting is [`hemisphere`]; CSR assembly `assemble`;
//! [`symmetric_part`] enforces reciprocity; [`cache`] stores F on disk.

mod assemble;
mod burial;
pub mod cache;
pub mod hemisphere;
mod needed;
pub(crate) mod occluders;
mod pair;
mod pairwise;
mod reciprocity;
mod reuse;
mod samples;
pub mod settings;

pub use burial::VISIBLE_AREA_LATTICE;
pub use needed::Needed;
pub use occluders::{occluders, Coarse};
pub use pair::{FAR_FIELD_FACTOR, NEAR_FIELD_FACTOR};
pub use reciprocity::symmetric_part;
pub use reuse::Reuse;
pub use settings::{Estimator, Settings, Shortcuts};

use rayon::prelude::*;
use serde::Serialize;
use sprs::CsMatI;

use crate::mesh::Patches;
use crate::visibility::Visibility;
use crate::{Error, Result};
use assemble::{assemble_rows, row_sums_of, scale_rows};

/// Hemisphere shooting computes direct light exactly only when at most 1/this of the patches
/// emit (not in a furnace, where every patch does).
pub const EXACT_DIRECT_FRACTION: usize = 20;

/// … and when emitters × patches (the pairs that costs) is at most this.
pub const EXACT_DIRECT_PAIRS: f64 = 2e8;

/// Probe rays per patch that decide whether a scene is closed ([`compute`]).
pub const CLOSURE_PROBES: u32 = 64;

/// A row sum Σ_j F_ij past this is named in a warning: no row can pass 1 (the energy leaving
/// a patch is at most all of it), and the contour estimator's own error reaches 1.0075 on the
/// Cornell box's rows next to its blocks, so past 1.02 its geometry is broken (faces that
/// coincide or intersect: a row was measured at 2.1 near intersecting faces).
pub const ROW_SUM_LIMIT: f64 = 1.02;

/// The largest row sum the estimator's rows are taken at ([`Stats::rows_capped`]). A row
/// past it is scaled to sum to 1 before the solve (energy conservation; the row
/// normalisation of Cohen & Wallace §4.11), or with ρ near 1 the solve would create light.
/// - contour: [`ROW_SUM_LIMIT`], past its own error;
/// - area: 1.5, past its sampling noise (rows of 1.09 with 4 samples a pair on the Cornell
///   box), which is not broken geometry and must not be scaled (that would bias it low);
/// - hemisphere: its rows are fractions of its rays, never past 1.
pub fn row_sum_limit(estimator: Estimator) -> f64 {
    match estimator {
        Estimator::Contour | Estimator::Hemisphere => ROW_SUM_LIMIT,
        Estimator::Area => 1.5,
    }
}

/// Counters of the estimation (reported in `--report`).
#[derive(Debug, Clone, Default, Serialize, serde::Deserialize)]
pub struct Stats {
    /// Visibility rays (segments) cast.
    pub rays_cast: u64,
    /// Unordered pairs considered (n(n−1)/2).
    pub pairs: u64,
    /// Unordered pairs culled without any ray because one lies behind the other's plane.
    pub pairs_culled: u64,
    /// Unordered pairs skipped because the solve needs neither F_ij nor F_ji ([`Needed`]).
    pub pairs_skipped: u64,
    /// Rows not computed because the solve does not read them (black patches, [`Needed`]).
    pub rows_skipped: u64,
    /// Unordered pairs whose entries were taken from the previous refinement round's F
    /// (both patches unchanged, [`Reuse`]).
    pub pairs_reused: u64,
    /// True when the scene was recognised as a convex enclosure (every patch on the scene's
    /// convex hull), where nothing can occlude anything and no visibility ray is cast.
    pub convex_enclosure: bool,
    /// Patches that can occlude (not on the convex hull, [`occluders`]).
    pub occluder_patches: u64,
    /// The triangles the visibility rays are traced against: the scene triangles the
    /// occluding patches tile (fewer than `occluder_patches` once patches are subdivided).
    pub occluder_triangles: u64,
    /// Patches with some sample points buried in contact geometry ([`Visibility::buried`]).
    pub patches_partly_hidden: u64,
    /// True when closure probes found the scene closed and the rows were normalised to 1
    /// (pair estimators with `normalise_closed`).
    pub closed_scene: bool,
    /// True when hemisphere shooting took the emitters' columns from the contour estimator
    /// (`exact_direct`).
    pub exact_direct: bool,
    /// Non-zeros of F.
    pub nnz: u64,
    /// Rows whose sum passed [`row_sum_limit`] and were scaled to 1.
    #[serde(default)]
    pub rows_capped: u64,
    /// Smallest, mean and largest row sum Σ_j F_ij, as estimated (before the rows past
    /// [`row_sum_limit`] were scaled to 1).
    pub row_sum_min: f64,
    pub row_sum_mean: f64,
    pub row_sum_max: f64,
    /// The patch whose row sums to `row_sum_max` (the first such).
    pub row_sum_max_patch: u64,
}

/// The form-factor matrix and its statistics.
#[derive(Debug, Clone)]
pub struct FormFactors {
    /// The pair estimator's F before closed-scene normalisation and symmetrisation, when
    /// those changed it (otherwise `matrix` is it): what the next refinement round reuses.
    pub pair_matrix: Option<CsMatI<f32, u32>>,
    /// F in CSR: row i, column j holds F_ij (dimensionless, ≥ 0, stored as f32 and
    /// accumulated in f64). Invariants: F_ii = 0 for planar patches; every row sum ≤ 1 up to
    /// the estimator's error (= 1 in a closed scene); A_i F_ij ≈ A_j F_ji.
    pub matrix: CsMatI<f32, u32>,
    /// Counters.
    pub stats: Stats,
    /// Area of each patch, scene units² (with `visible_fraction`, the weights of area-weighted
    /// operations: reciprocity, the symmetric form of conjugate gradient, shooting order).
    pub area: Vec<f64>,
    /// Fraction of each patch's area that is not buried in contact geometry, in [0, 1]
    /// (pair estimators: measured on a lattice of 16 points; hemisphere: the unburied ray
    /// origins); rows describe the visible part ([`Visibility::buried`]).
    pub visible_fraction: Vec<f64>,
    /// How far below 1 a row of a closed enclosure may fall with this estimator: 1e-6 for
    /// hemisphere shooting (rows are hit counts, exact up to f32 storage); 0.1 for the pair
    /// estimators, whose rows next to occluders err by the one-ray-per-point visibility
    /// estimate (measured up to 6e-2 at coarse settings). Used to recognise ρ = 1 enclosures.
    pub closed_row_tolerance: f64,
}

impl FormFactors {
    /// Number of patches (rows).
    pub fn len(&self) -> usize {
        self.matrix.rows()
    }

    /// True when there are no patches.
    pub fn is_empty(&self) -> bool {
        self.matrix.rows() == 0
    }

    /// An all-zero n × n matrix (what a scene without emitters needs).
    pub fn empty(n: usize) -> FormFactors {
        FormFactors {
            matrix: CsMatI::zero((n, n)),
            pair_matrix: None,
            stats: Stats::default(),
            area: vec![0.0; n],
            visible_fraction: vec![1.0; n],
            closed_row_tolerance: 1e-6,
        }
    }

    /// Σ_j F_ij for every row i, accumulated in f64.
    pub fn row_sums(&self) -> Vec<f64> {
        row_sums_of(&self.matrix)
    }

    /// Check the structural invariants: square, finite, non-negative, no diagonal, and row
    /// sums ≤ 1 + `row_sum_tolerance`.
    pub fn validate(&self, row_sum_tolerance: f64) -> Result<()> {
        let n = self.len();
        if self.matrix.cols() != n {
            return Err(Error::Internal("form-factor matrix is not square".into()));
        }
        for (i, row) in self.matrix.outer_iterator().enumerate() {
            for (j, &f) in row.iter() {
                if !f.is_finite() || f < 0.0 {
                    return Err(Error::Internal(format!("F[{i}][{j}] = {f}")));
                }
                if i == j {
                    return Err(Error::Internal(format!("F[{i}][{i}] is stored")));
                }
            }
        }
        for (i, s) in self.row_sums().into_iter().enumerate() {
            if s > 1.0 + row_sum_tolerance {
                return Err(Error::Internal(format!(
                    "row {i} of F sums to {s} > 1 + {row_sum_tolerance}"
                )));
            }
        }
        Ok(())
    }
}

/// Whether the scene is closed, as far as `probes` cosine-weighted rays from every patch tell:
/// none escapes the scene or meets the back of a surface. Stops at the first escape.
pub fn is_closed(patches: &Patches, vis: &Visibility, probes: u32, seed: u64) -> bool {
    (0..patches.len())
        .into_par_iter()
        .all(|i| closes(patches, vis, i, probes, seed))
}

/// Whether patch `i` is closed ([`is_closed`] for one patch): none of `probes`
/// cosine-weighted rays from it escapes the scene or meets the back of a surface.
///
/// One escape alone is asked again with [`CLOSURE_RECHECK`] times the rays (another seed):
/// the patch is closed if at most 1 in [`CLOSURE_RECHECK_RAYS`] of those escapes. A grazing
/// ray can slip through a seam by the f32 rounding of its corners (on a furnished hall of 10⁶
/// triangles, 6 of 10⁸ probe rays did, leaving 6 roots unnormalised and their faces up to 25 %
/// off in the furnace); a real opening a patch sees is found again. What a closed verdict
/// can hide is an opening of under 1/[`CLOSURE_RECHECK_RAYS`] of the patch's projected
/// hemisphere, its light then normalised onto the rest.
pub fn closes(patches: &Patches, vis: &Visibility, i: usize, probes: u32, seed: u64) -> bool {
    match hemisphere::row(patches, vis, i, probes, seed ^ 0xC105ED).escaped {
        0 => true,
        1 => {
            let rays = (probes * CLOSURE_RECHECK).max(CLOSURE_RECHECK_RAYS);
            let again = hemisphere::row(patches, vis, i, rays, seed ^ 0x2EC4EC);
            again.escaped as u64 * CLOSURE_RECHECK_RAYS as u64 <= rays as u64
        }
        _ => false,
    }
}

/// How many times the probes a patch with one escaping probe is asked again with ([`closes`]).
pub const CLOSURE_RECHECK: u32 = 16;

/// The fewest rays of that second look; a patch is closed if at most one in this many escape.
pub const CLOSURE_RECHECK_RAYS: u32 = 256;

/// Estimate every F_ij of the patches, casting visibility rays through `vis` (built over the
/// patch triangles, triangle index = patch index). Rows are computed in parallel; the result
/// is deterministic for a given seed whatever the thread count.
///
/// Only the entries in `needed` are computed ([`Needed`]; pass [`Needed::all`] for the whole
/// matrix); the others are absent from the result, as if zero.
pub fn compute(
    patches: &Patches,
    vis: &Visibility,
    settings: &Settings,
    needed: &Needed,
) -> Result<FormFactors> {
    compute_reusing(patches, vis, settings, needed, None)
}

/// Scales column j of `matrix` by the covered share 1 − t_j of patch j (`transmittance`: one
/// t per patch in [0, 1], or empty for an opaque scene, which changes nothing): a receiver
/// gathers from a partly transparent patch only what its material covers, the rest of that
/// solid angle reaching it from behind through the segments the patch lets through
/// ([`crate::visibility::Visibility::with_transmittance`]). So rows stay ≤ 1 (= 1 in a closed
/// scene) and reciprocity holds for the covered areas.
fn cover_columns(matrix: &mut CsMatI<f32, u32>, transmittance: &[f64]) {
    if transmittance.is_empty() {
        return;
    }
    for mut row in matrix.outer_iterator_mut() {
        for (j, f) in row.iter_mut() {
            *f *= (1.0 - transmittance[j]) as f32;
        }
    }
}

/// [`compute`], taking the entries of unchanged pairs from `reuse` (pair estimators only; the
/// hemisphere estimator's rows change when any patch they hit is split). A reused entry equals
/// what computing it again with the earlier indices would give, up to one f32 rounding.
pub fn compute_reusing(
    patches: &Patches,
    vis: &Visibility,
    settings: &Settings,
    needed: &Needed,
    reuse: Option<&Reuse>,
) -> Result<FormFactors> {
    settings.validate()?;
    let n = patches.len();
    let mut stats = Stats::default();
    let mut visible_fraction = vec![1.0; n];
    let pair_estimator = settings.estimator != Estimator::Hemisphere;
    // Energy conservation: in a closed enclosure every (visible) row sums to exactly 1. The
    // pair estimators miss that by their visibility error next to occluders; if probe rays
    // from every patch all land on the front of some surface, the scene is closed and the
    // rows are rescaled to 1 (Cohen & Wallace §4.11 discuss this row normalisation). One
    // escaping probe anywhere and nothing is changed.
    let normalise = pair_estimator
        && settings.shortcuts.normalise_closed
        && is_closed(patches, vis, CLOSURE_PROBES, settings.seed);
    if pair_estimator && settings.shortcuts.normalise_closed {
        stats.rays_cast += n as u64 * CLOSURE_PROBES as u64;
        stats.closed_scene = normalise;
    }
    // Normalising and symmetrising read whole rows.
    let needed = if normalise || settings.reciprocity {
        needed.whole_rows()
    } else {
        needed.clone()
    };
    let needed = if settings.reciprocity {
        Needed::all(n)
    } else {
        needed
    };
    stats.rows_skipped = needed.rows.iter().filter(|&&r| !r).count() as u64;
    let transmittance = patches.transmittance();
    let emitter: Vec<bool> = patches
        .emission
        .iter()
        .map(|e| e.iter().any(|&x| x > 0.0))
        .collect();
    let emitters = emitter.iter().filter(|&&e| e).count();
    let exact_direct = settings.estimator == Estimator::Hemisphere
        && settings.shortcuts.exact_direct
        && emitters > 0
        && emitters * EXACT_DIRECT_FRACTION <= n
        && (emitters as f64) * (n as f64) <= EXACT_DIRECT_PAIRS;
    stats.exact_direct = exact_direct;
    let mut matrix = if settings.estimator == Estimator::Hemisphere {
        // With exact direct light, the emitters' columns come from the contour estimator
        // below and the rays only estimate the others.
        let shot = if exact_direct {
            Needed {
                rows: needed.rows.clone(),
                columns: (0..n).map(|j| needed.columns[j] && !emitter[j]).collect(),
            }
        } else {
            needed.clone()
        };
        let rows = hemisphere::rows(patches, vis, settings.rays, settings.seed, &shot);
        stats.rays_cast = rows.iter().map(|r| r.rays).sum();
        visible_fraction = rows.iter().map(|r| r.visible_fraction).collect();
        let shot = assemble_rows(n, rows.into_iter().map(|r| r.entries).collect())?;
        if exact_direct {
            let direct = Needed {
                rows: needed.rows.clone(),
                columns: (0..n).map(|j| needed.columns[j] && emitter[j]).collect(),
            };
            let contour = Settings {
                estimator: Estimator::Contour,
                ..*settings
            };
            let mut exact = pairwise::pairwise(
                patches,
                vis,
                &contour,
                &direct,
                None,
                &mut stats,
                &mut visible_fraction,
            )?;
            cover_columns(&mut exact, &transmittance);
            &shot + &exact
        } else {
            shot
        }
    } else {
        pairwise::pairwise(
            patches,
            vis,
            settings,
            &needed,
            reuse,
            &mut stats,
            &mut visible_fraction,
        )?
    };
    // The pair estimator's own matrix, for the next refinement round, when what follows
    // changes it.
    let pair_matrix = (pair_estimator
        && (normalise || settings.reciprocity || !transmittance.is_empty()))
    .then(|| matrix.clone());
    if pair_estimator {
        // The hemisphere's rays already pass partly transparent patches by chance.
        cover_columns(&mut matrix, &transmittance);
    }
    if normalise {
        let sums: Vec<f64> = row_sums_of(&matrix);
        let factor: Vec<f64> = sums
            .iter()
            .map(|&s| if s > 0.0 { s } else { 1.0 })
            .collect();
        scale_rows(&mut matrix, &factor);
    }
    stats.patches_partly_hidden = visible_fraction.iter().filter(|&&v| v < 1.0).count() as u64;
    if settings.reciprocity {
        // A partly transparent patch's material covers 1 − t of its area: reciprocity holds
        // for the covered areas (the columns were scaled by them, `cover_columns`).
        let visible_area: Vec<f64> = patches
            .area
            .iter()
            .zip(&visible_fraction)
            .enumerate()
            .map(|(i, (a, v))| a * v * (1.0 - transmittance.get(i).copied().unwrap_or(0.0)))
            .collect();
        matrix = symmetric_part(&matrix, &visible_area)?;
    }
    let mut ff = FormFactors {
        matrix,
        pair_matrix,
        stats,
        area: patches.area.clone(),
        visible_fraction,
        closed_row_tolerance: match settings.estimator {
            Estimator::Hemisphere => 1e-6,
            Estimator::Area | Estimator::Contour => 0.1,
        },
    };
    ff.stats.nnz = ff.matrix.nnz() as u64;
    let sums = ff.row_sums();
    let limit = row_sum_limit(settings.estimator);
    let cap: Vec<f64> = sums
        .iter()
        .map(|&s| if s > limit { s } else { 1.0 })
        .collect();
    ff.stats.rows_capped = cap.iter().filter(|&&f| f != 1.0).count() as u64;
    if ff.stats.rows_capped > 0 {
        scale_rows(&mut ff.matrix, &cap);
    }
    if !sums.is_empty() {
        ff.stats.row_sum_min = sums.iter().copied().fold(f64::INFINITY, f64::min);
        let (worst, max) =
            sums.iter().copied().enumerate().fold(
                (0, 0.0),
                |(k, m), (i, x)| if x > m { (i, x) } else { (k, m) },
            );
        ff.stats.row_sum_max = max;
        ff.stats.row_sum_max_patch = worst as u64;
        ff.stats.row_sum_mean = sums.iter().sum::<f64>() / sums.len() as f64;
    }
    Ok(ff)
}
