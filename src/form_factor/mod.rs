//! Form factors: estimating F_ij, the fraction of the energy leaving patch i that arrives at
//! patch j, for every pair of patches, with ray-cast visibility. This module owns the
//! estimators and the parallel loop over pairs; it hands a [`FormFactors`] (the sparse matrix
//! F plus counters) to the solver. It does not know about ρ or Le.
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
//! - `Contour`: F_ij ≈ 1/n Σ F_{dA(x_k)→A_j} V_k, with the exact unoccluded point-to-polygon
//!   form factor (Lambert's contour integral, [`kernel::point_to_polygon`]) at stratified
//!   points of i and the visibility of a ray x_k → y_k. Exact for unoccluded pairs up to the
//!   integration over i, including patches that share an edge; in a closed unoccluded scene
//!   each point's form factors sum to exactly 1.
//!
//! The receiving cosine cosθ_i is taken with the surface normal at the sample point
//! ([`Patches::surface_normal`]): the interpolated vertex normal where the mesh samples a
//! smooth surface, the facet's own on flat ones (see [`crate::patch::corner_normals`]).

pub mod hemisphere;
pub mod kernel;
pub mod sampling;

use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;
use sprs::CsMatI;

use crate::patch::Patches;
use crate::visibility::Visibility;
use crate::{Error, Result};
use sampling::{stratified_triangle_barycentrics, Rng};

/// Pairs with squared centroid distance below this multiple of the larger patch area use the
/// exact point-to-polygon integrand even in the `Area` estimator (Baum et al. 1989 use the
/// analytic form wherever the point-source assumption A_j ≪ r² fails).
pub const NEAR_FIELD_FACTOR: f64 = 16.0;

/// Contour estimator with a Gauss rule: pairs with squared centroid distance above this
/// multiple of the larger patch area integrate the source with the same Gauss rule instead of
/// the exact contour integral (a 3-point rule's error there is O((h/r)⁴) ≲ 1e-4 relative:
/// per-surface means of the Cornell box unchanged to 1e-5).
pub const FAR_FIELD_FACTOR: f64 = 64.0;

/// Regular meshes put many pairs exactly on the near-field threshold; a relative nudge far
/// above f64 rounding decides those ties the same way whatever the scene's unit of length.
const NEAR_FIELD_TIE: f64 = 1.0 + 1e-9;

/// Which estimator of F_ij to use; see the module documentation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Estimator {
    /// Point pairs with the kernel G·V (near pairs analytic).
    Area,
    /// Exact point-to-polygon integrand × ray visibility.
    Contour,
    /// Cosine-weighted rays from each patch; the first hit names the receiving patch.
    Hemisphere,
}

/// Settings of the form-factor estimation.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Settings {
    /// The estimator.
    pub estimator: Estimator,
    /// Sample points per patch and visibility rays per patch pair (area, contour); ≥ 1.
    pub samples: u32,
    /// Rays per patch (hemisphere); ≥ 1.
    pub rays: u32,
    /// Enforce reciprocity afterwards ([`symmetric_part`]): the two estimates of each exchange
    /// A_i F_ij = A_j F_ji are averaged (halving their variance) and the result rescaled so
    /// that every row keeps its sum. Off by default: the averaging moves light between
    /// neighbouring patches by the estimators' reciprocity error (up to ~10 % on small patches
    /// next to contact lines), which the unsymmetrised F does not.
    pub reciprocity: bool,
    /// Seed of every random choice; the same seed gives the same F for any thread count.
    pub seed: u64,
    /// Leave the faces that lie on the scene's convex hull out of the occlusion tests
    /// ([`occluders`]): they cannot block a segment between two scene points. In a convex
    /// enclosure (a sphere, an empty room) that is every face, and no visibility ray is cast at
    /// all. On by default; off only to measure or test what the skip saves.
    pub skip_hull: bool,
    /// Normalise the rows of a closed scene to 1 (pair estimators; see [`compute`]); on by
    /// default, off to measure the estimators' raw row error.
    pub normalise_closed: bool,
    /// Hemisphere shooting: compute the emitters' columns (direct light) with the contour
    /// estimator instead of counting rays, when emitters are a small part of the scene
    /// ([`EXACT_DIRECT_FRACTION`], [`EXACT_DIRECT_PAIRS`]). A small light is hit by few of a
    /// patch's rays, so shot direct light is the noisiest part of the estimate; computed
    /// exactly it costs emitters × patches pairs. On by default.
    pub exact_direct: bool,
    /// Contour estimator: integrate far pairs' sources with the Gauss rule instead of the
    /// exact contour integral ([`FAR_FIELD_FACTOR`]); on by default, off to measure it.
    pub far_field: bool,
    /// Skip, without a ray, every pair where one patch lies wholly behind the other's plane
    /// (they cannot exchange light); on by default, off only to measure the saving.
    pub cull_behind: bool,
    /// Adaptive refinement: keep the entries of pairs of patches a round left unchanged
    /// instead of computing them again ([`Reuse`]); on by default, off to measure the saving.
    pub reuse: bool,
    /// Compute only the entries the solve reads ([`Needed::for_solve`]: no rows for black
    /// patches, only emitters' columns for one bounce); on by default, off to measure what
    /// the skip saves.
    pub skip_unneeded: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            estimator: Estimator::Contour,
            samples: 3,
            rays: 1024,
            seed: 1,
            reciprocity: false,
            skip_hull: true,
            normalise_closed: true,
            skip_unneeded: true,
            exact_direct: true,
            far_field: true,
            cull_behind: true,
            reuse: true,
        }
    }
}

/// Which entries F_ij the solve will read: row i when patch i reflects (ρ_i > 0 in some
/// channel: a black patch's radiance is its Le whatever F says), column j when patch j's
/// radiance is gathered at all (with one bounce, only emitters' is). [`compute`] skips every
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
    fn whole_rows(&self) -> Self {
        Needed {
            rows: self.rows.clone(),
            columns: vec![true; self.columns.len()],
        }
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
    /// Patches that can occlude (not on the convex hull, [`occluders`]): the only ones in the
    /// BVH of the visibility rays.
    pub occluder_patches: u64,
    /// Patches with some sample points buried in contact geometry ([`is_hidden`]).
    pub patches_partly_hidden: u64,
    /// True when closure probes found the scene closed and the rows were normalised to 1
    /// (pair estimators with `normalise_closed`).
    pub closed_scene: bool,
    /// True when hemisphere shooting took the emitters' columns from the contour estimator
    /// (`exact_direct`).
    pub exact_direct: bool,
    /// Non-zeros of F.
    pub nnz: u64,
    /// Smallest, mean and largest row sum Σ_j F_ij.
    pub row_sum_min: f64,
    pub row_sum_mean: f64,
    pub row_sum_max: f64,
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
    /// origins); rows describe the visible part ([`is_hidden`]).
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

/// The pair estimators' F of an earlier patch mesh, for [`compute_reusing`]: a pair of
/// patches that both survive unchanged in the new mesh (same corners, same source) keeps its
/// two entries instead of being computed again — what adaptive refinement needs, since it
/// splits a few patches and keeps the rest.
pub struct Reuse<'a> {
    /// The earlier F as the pair estimator made it (before closed-scene normalisation or
    /// symmetrisation: [`FormFactors::pair_matrix`]).
    pub matrix: &'a CsMatI<f32, u32>,
    /// For each new patch, its index in the earlier mesh, or [`crate::visibility::NONE`].
    pub old_of_new: Vec<u32>,
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
    if settings.samples == 0 {
        return Err(Error::usage("--samples", "must be at least 1"));
    }
    if settings.rays == 0 {
        return Err(Error::usage("--rays", "must be at least 1"));
    }
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
        && settings.normalise_closed
        && (0..n).into_par_iter().all(|i| {
            let probe = hemisphere::row(patches, vis, i, CLOSURE_PROBES, settings.seed ^ 0xC105ED);
            probe.escaped == 0
        });
    if pair_estimator && settings.normalise_closed {
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
    let emitter: Vec<bool> = patches
        .emission
        .iter()
        .map(|e| e.iter().any(|&x| x > 0.0))
        .collect();
    let emitters = emitter.iter().filter(|&&e| e).count();
    let exact_direct = settings.estimator == Estimator::Hemisphere
        && settings.exact_direct
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
            let exact = pairwise(
                patches,
                vis,
                &contour,
                &direct,
                None,
                &mut stats,
                &mut visible_fraction,
            )?;
            &shot + &exact
        } else {
            shot
        }
    } else {
        pairwise(
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
    let pair_matrix =
        (pair_estimator && (normalise || settings.reciprocity)).then(|| matrix.clone());
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
        let visible_area: Vec<f64> = patches
            .area
            .iter()
            .zip(&visible_fraction)
            .map(|(a, v)| a * v)
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
    if !sums.is_empty() {
        ff.stats.row_sum_min = sums.iter().copied().fold(f64::INFINITY, f64::min);
        ff.stats.row_sum_max = sums.iter().copied().fold(0.0, f64::max);
        ff.stats.row_sum_mean = sums.iter().sum::<f64>() / sums.len() as f64;
    }
    Ok(ff)
}

/// The pair estimators (area, contour): every unordered pair once, both directions.
fn pairwise(
    patches: &Patches,
    vis: &Visibility,
    settings: &Settings,
    needed: &Needed,
    reuse: Option<&Reuse>,
    stats: &mut Stats,
    visible_fraction: &mut Vec<f64>,
) -> Result<CsMatI<f32, u32>> {
    let n = patches.len();
    let ns = settings.samples as usize;
    // Only patches off the convex hull can block a segment: trace against those alone.
    let occluder_mask = if settings.skip_hull {
        occluders(patches)
    } else {
        vec![true; n]
    };
    stats.occluder_patches = occluder_mask.iter().filter(|&&o| o).count() as u64;
    let convex = stats.occluder_patches == 0;
    stats.convex_enclosure = convex;
    let restricted;
    let blockers = if convex || stats.occluder_patches == n as u64 {
        vis
    } else {
        restricted = vis.restricted(&occluder_mask);
        &restricted
    };
    // Sample points of every patch, fixed per patch, with their quadrature weights (the same
    // for every patch). The contour estimator integrates a smooth integrand over the
    // receiving patch, so it uses a symmetric Gauss rule where one has exactly `samples`
    // points (1, 3, 6, 7, 12); otherwise, and for the area estimator (a Monte Carlo estimate
    // of a double integral), stratified random points keyed by (seed, patch). The same points
    // serve every pair, so in a closed unoccluded scene the contour rows sum to exactly 1.
    let rule: Vec<([f64; 3], f64)> = match settings.estimator {
        Estimator::Contour => sampling::gauss_rule(ns).unwrap_or_default(),
        _ => Vec::new(),
    };
    let weights: Vec<f64> = if rule.is_empty() {
        vec![1.0 / ns as f64; ns]
    } else {
        rule.iter().map(|p| p.1).collect()
    };
    // Each sample point with the surface normal there ([`Patches::surface_normal`]), which
    // is the receiving cosine's normal in the kernels.
    let samples: Vec<(DVec3, DVec3)> = (0..n)
        .into_par_iter()
        .flat_map_iter(|i| {
            let mut bary = Vec::with_capacity(ns);
            if rule.is_empty() {
                let mut rng = Rng::new(&[settings.seed, i as u64, 0x5A4D]);
                stratified_triangle_barycentrics(ns, &mut rng, &mut bary);
            } else {
                bary.extend(rule.iter().map(|p| p.0));
            }
            let t = patches.corners(i);
            bary.into_iter().map(move |b| {
                let x = b[0] * t[0] + b[1] * t[1] + b[2] * t[2];
                (x, patches.surface_normal(i, b))
            })
        })
        .collect();
    let points: Vec<DVec3> = samples.iter().map(|s| s.0).collect();
    // The same points prepared for the visibility queries (canonical frame computed once).
    let prepared: Vec<crate::visibility::Point> =
        points.par_iter().map(|&x| vis.point(x)).collect();
    let point_normals: Vec<DVec3> = samples.iter().map(|s| s.1).collect();
    // Sample points buried in contact geometry (the floor under a block, the ceiling behind a
    // light) see nothing and are seen by nothing; see [`is_hidden`].
    let hidden: Vec<bool> = if convex {
        vec![false; points.len()]
    } else {
        points
            .par_iter()
            .enumerate()
            .map(|(k, &x)| is_hidden(patches, vis, k / ns, x))
            .collect()
    };
    // The rows integrate over the unburied quadrature points only: their weight is what each
    // row is divided by below. The visible area itself (for area weights: reciprocity, surface
    // means) is measured on a finer lattice, since three points quantise it to thirds.
    let quadrature_visible: Vec<f64> = (0..n)
        .map(|i| {
            (0..ns)
                .filter(|&k| !hidden[i * ns + k])
                .map(|k| weights[k])
                .sum()
        })
        .collect();
    stats.rays_cast += hidden.len() as u64 * (!convex) as u64;
    if !convex {
        let lattice = sampling::lattice_barycentrics(VISIBLE_AREA_LATTICE);
        *visible_fraction = (0..n)
            .into_par_iter()
            .map(|i| {
                let t = patches.corners(i);
                let buried = lattice
                    .iter()
                    .filter(|b| is_hidden(patches, vis, i, b[0] * t[0] + b[1] * t[1] + b[2] * t[2]))
                    .count();
                1.0 - buried as f64 / lattice.len() as f64
            })
            .collect();
        stats.rays_cast += (n * lattice.len()) as u64;
    }
    let old_t: Option<CsMatI<f32, u32>> = reuse.map(|r| r.matrix.transpose_view().to_csr());
    // Each patch's geometry in one contiguous record: the inner loop streams through it.
    let geometry: Vec<PatchGeometry> = (0..n)
        .map(|i| PatchGeometry {
            corners: patches.corners(i),
            normal: patches.normal[i],
            centroid: patches.centroid[i],
            area: patches.area[i],
        })
        .collect();
    let rays = AtomicU64::new(0);
    let culled = AtomicU64::new(0);
    let skipped = AtomicU64::new(0);
    let reused = AtomicU64::new(0);

    // Each task i produces (j, F_ij) for j > i and (j, F_ji) for j > i.
    let progress =
        crate::progress::stage("form factors", Some((n * n.saturating_sub(1) / 2) as u64));
    let rows: Vec<PairRows> = (0..n)
        .into_par_iter()
        .map(|i| {
            progress.advance((n - i - 1) as u64);
            let mut upper = Vec::new();
            let mut lower = Vec::new();
            let mut local_rays = 0u64;
            let mut local_culled = 0u64;
            let mut local_skipped = 0u64;
            let mut local_reused = 0u64;
            // Row i of the earlier F and of its transpose (column i), walked in step with j.
            let mut old_rows = reuse.and_then(|r| {
                let oi = r.old_of_new[i];
                (oi != crate::visibility::NONE)
                    .then(|| OldRows::new(r, old_t.as_ref().expect("with reuse"), oi))
            });
            let pi = &points[i * ns..(i + 1) * ns];
            let mi = &point_normals[i * ns..(i + 1) * ns];
            let PatchGeometry {
                corners: ti,
                normal: ni,
                centroid: ci,
                area: ai,
            } = geometry[i];
            let scale_i = ai.sqrt();
            let mut vis_k = vec![false; ns];
            let mut valid_k = vec![false; ns];
            for j in i + 1..n {
                let (need_ij, need_ji) = (needed.entry(i, j), needed.entry(j, i));
                if !need_ij && !need_ji {
                    local_skipped += 1;
                    continue;
                }
                if let (Some(r), Some(rows)) = (reuse, old_rows.as_mut()) {
                    let oj = r.old_of_new[j];
                    if oj != crate::visibility::NONE {
                        // Both unchanged: the earlier entries, back to this function's
                        // unscaled form (rows are divided by the visible weight below).
                        let (fij, fji) = rows.next(oj);
                        if need_ij && fij > 0.0 {
                            upper.push((j as u32, (fij * quadrature_visible[i]) as f32));
                        }
                        if need_ji && fji > 0.0 {
                            lower.push((j as u32, (fji * quadrature_visible[j]) as f32));
                        }
                        local_reused += 1;
                        continue;
                    }
                }
                let PatchGeometry {
                    corners: tj,
                    normal: nj,
                    centroid: cj,
                    area: aj,
                } = geometry[j];
                // Cull: j entirely on or behind i's plane, or i behind j's: no exchange.
                let tol = 1e-9 * (scale_i + aj.sqrt());
                // Heights of each patch's corners over the other's plane.
                let j_over_i = tj.map(|v| ni.dot(v - ci));
                let i_over_j = ti.map(|v| nj.dot(v - cj));
                if settings.cull_behind
                    && (j_over_i.iter().all(|&h| h <= tol) || i_over_j.iter().all(|&h| h <= tol))
                {
                    local_culled += 1;
                    continue;
                }
                let pj = &points[j * ns..(j + 1) * ns];
                let mj = &point_normals[j * ns..(j + 1) * ns];
                // Pair x_k with y_{(k + shift) mod n}: decorrelates the pairings of different
                // pairs while keeping the key deterministic.
                let shift = (sampling::mix64(settings.seed ^ ((i as u64) << 32 | j as u64))
                    % ns as u64) as usize;
                let (mut n_valid, mut n_visible) = (0u32, 0u32);
                for k in 0..ns {
                    let ky = (k + shift) % ns;
                    let (x, y) = (pi[k], pj[ky]);
                    let d = y - x;
                    if hidden[i * ns + k] && hidden[j * ns + ky] {
                        // Both ends buried: neither gathers through this sample; no ray.
                        // (One buried end still needs the ray: the segment is then blocked by
                        // what buries it, which is how the buried part of a patch counts as
                        // invisible to the other.)
                        valid_k[k] = false;
                        continue;
                    }
                    // A segment is a meaningful visibility sample only if each end lies in
                    // front of the other's surface.
                    valid_k[k] = ni.dot(d) > 0.0 && nj.dot(d) < 0.0;
                    if valid_k[k] {
                        n_valid += 1;
                        vis_k[k] = convex || {
                            local_rays += 1;
                            !blockers.occluded_points(
                                &prepared[i * ns + k],
                                &prepared[j * ns + ky],
                                [i as u32, j as u32],
                            )
                        };
                        n_visible += vis_k[k] as u32;
                    }
                }
                if n_valid == 0 {
                    // Only possible for pairs that straddle each other's planes with a sliver
                    // in view: no sample segment can tell; such pairs exchange ~nothing.
                    continue;
                }
                let v_mean = n_visible as f64 / n_valid as f64;
                let r2 = ci.distance_squared(cj);
                let near = r2 < NEAR_FIELD_TIE * NEAR_FIELD_FACTOR * ai.max(aj);
                // The far-field rule needs each patch wholly in front of the other: a polygon
                // straddling the receiver's horizon is clipped by the contour integral, which a
                // few point samples cannot follow.
                let far = !rule.is_empty()
                    && settings.far_field
                    && r2 > NEAR_FIELD_TIE * FAR_FIELD_FACTOR * ai.max(aj)
                    && j_over_i.iter().chain(&i_over_j).all(|&h| h > tol);
                let (mut fij, mut fji) = (0.0, 0.0);
                for k in 0..ns {
                    let ky = (k + shift) % ns;
                    let (x, y) = (pi[k], pj[ky]);
                    let v = if valid_k[k] {
                        vis_k[k] as u8 as f64
                    } else {
                        v_mean
                    };
                    // Buried points gather nothing (their patch's row is rescaled later).
                    let (hx, hy) = (
                        hidden[i * ns + k] || !need_ij,
                        hidden[j * ns + ky] || !need_ji,
                    );
                    if v == 0.0 || (hx && hy) {
                        continue;
                    }
                    match (settings.estimator, near) {
                        (Estimator::Area, false) => {
                            // Monte Carlo over the pair (x, y): uniform weights 1/n.
                            let g = kernel::point_to_point(x, mi[k], y, mj[ky]) * v * weights[k];
                            fij += aj * g * (!hx) as u8 as f64;
                            fji += ai * g * (!hy) as u8 as f64;
                        }
                        _ if far => {
                            // Far apart, the exact point-to-polygon integral is integrated
                            // over the source as well by the same Gauss rule: a degree-2 rule
                            // on a smooth kernel, error O((h/r)⁴) relative (< 1e-3 beyond
                            // [`FAR_FIELD_FACTOR`]), at a third of the contour's cost.
                            // A_src Σ_q w_q G(p, m, y_q, n_src): the point's form factor to the
                            // source by the Gauss rule.
                            let gauss = |p, m, source: &[DVec3], n_src, a_src: f64| {
                                let s: f64 = (0..ns)
                                    .map(|q| {
                                        weights[q] * kernel::point_to_point(p, m, source[q], n_src)
                                    })
                                    .sum();
                                a_src * s
                            };
                            if !hx {
                                fij += weights[k] * gauss(x, mi[k], pj, nj, aj) * v;
                            }
                            if !hy {
                                fji += weights[ky] * gauss(y, mj[ky], pi, ni, ai) * v;
                            }
                        }
                        _ => {
                            // The contour integral needs the point in front of the polygon
                            // (one-sided surfaces); a point behind it sees its back: zero.
                            if !hx && nj.dot(x - cj) > 0.0 {
                                fij += weights[k] * kernel::point_to_polygon(x, mi[k], &tj) * v;
                            }
                            if !hy && ni.dot(y - ci) > 0.0 {
                                fji += weights[ky] * kernel::point_to_polygon(y, mj[ky], &ti) * v;
                            }
                        }
                    }
                }
                if fij > 0.0 {
                    upper.push((j as u32, fij as f32));
                }
                if fji > 0.0 {
                    lower.push((j as u32, fji as f32));
                }
            }
            rays.fetch_add(local_rays, Ordering::Relaxed);
            culled.fetch_add(local_culled, Ordering::Relaxed);
            skipped.fetch_add(local_skipped, Ordering::Relaxed);
            reused.fetch_add(local_reused, Ordering::Relaxed);
            (upper, lower)
        })
        .collect();

    stats.rays_cast += rays.into_inner();
    stats.pairs = (n as u64) * (n as u64).saturating_sub(1) / 2;
    stats.pairs_culled = culled.into_inner();
    stats.pairs_skipped = skipped.into_inner();
    stats.pairs_reused = reused.into_inner();
    let mut matrix = assemble(n, rows)?;
    // Each row was integrated over the whole patch with zero from its buried points: divide
    // by the visible weight so the row describes the visible part, whose radiance is what the
    // rest of the scene sees (hidden-area elimination).
    scale_rows(&mut matrix, &quadrature_visible);
    Ok(matrix)
}

/// A patch's geometry as the pair loop reads it.
#[derive(Clone, Copy)]
struct PatchGeometry {
    corners: [DVec3; 3],
    normal: DVec3,
    centroid: DVec3,
    area: f64,
}

/// Row `oi` of an earlier F and of its transpose, read at increasing old columns `oj`
/// (unchanged patches keep their order through refinement, so a cursor moves forward; a step
/// back, should one happen, restarts with a binary search).
struct OldRows<'a> {
    row: (&'a [u32], &'a [f32]),
    col: (&'a [u32], &'a [f32]),
    at: (usize, usize),
}

impl<'a> OldRows<'a> {
    fn new(r: &'a Reuse, t: &'a CsMatI<f32, u32>, oi: u32) -> Self {
        let a = r.matrix.outer_view(oi as usize).expect("row in range");
        let b = t.outer_view(oi as usize).expect("row in range");
        OldRows {
            row: a.into_raw_storage(),
            col: b.into_raw_storage(),
            at: (0, 0),
        }
    }

    /// (F_{oi,oj}, F_{oj,oi}) of the earlier F, 0 where absent.
    fn next(&mut self, oj: u32) -> (f64, f64) {
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

/// What task i produces: (column j, F_ij) for j > i, and (row j, F_ji) for j > i.
type PairRows = (Vec<(u32, f32)>, Vec<(u32, f32)>);

/// Assemble CSR from per-task results: task i holds row i's entries right of the diagonal
/// (sorted by column) and, for each j > i, the entry (j, i) of row j. Rows are put together as
/// [lower entries in increasing column i] ++ [upper entries], so columns come out sorted.
fn assemble(n: usize, rows: Vec<PairRows>) -> Result<CsMatI<f32, u32>> {
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
fn assemble_rows(n: usize, rows: Vec<Vec<(u32, f32)>>) -> Result<CsMatI<f32, u32>> {
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

/// Which patches can block a segment between two points of the scene: those whose plane is
/// not a supporting plane of the scene (one with every patch vertex on one side of it). A face
/// on a supporting plane lies on the boundary of the scene's convex hull, and a segment
/// between two points of a convex set meets a supporting plane at most at its ends, which the
/// open-segment test never counts; so leaving such faces out of the occlusion BVH changes no
/// answer. In a room that is every wall, floor and ceiling face (only furniture remains); in a
/// convex enclosure (a sphere, an empty room) it is every face, and no ray is needed at all.
///
/// One test per scene triangle (its patches share its plane) against every patch vertex,
/// with a tolerance of 1e-6 of the scene's size (the f32 rounding of OBJ input must not make
/// a tessellated sphere's facets non-supporting; a dent that small hides nothing measurable).
/// A triangle stops at the first vertices found on both sides, so only supporting faces cost
/// a full pass; if that could exceed 4·10⁹ tests, every patch is kept as an occluder.
pub fn occluders(patches: &Patches) -> Vec<bool> {
    let n = patches.len();
    let positions = &patches.positions;
    // First patch of each source triangle (all of its patches share its plane).
    let mut first = std::collections::HashMap::new();
    for i in 0..n {
        first.entry(patches.source_triangle[i]).or_insert(i);
    }
    let mut reps: Vec<usize> = first.into_values().collect();
    reps.sort_unstable();
    if (reps.len() as f64) * (positions.len() as f64) > 4e9 {
        return vec![true; n];
    }
    let (lo, hi) = positions
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    let tol = 1e-6 * (hi - lo).length();
    let supporting: std::collections::HashMap<u32, bool> = reps
        .par_iter()
        .map(|&i| {
            let (c, nrm) = (patches.centroid[i], patches.normal[i]);
            let (mut front, mut back) = (false, false);
            for p in positions {
                let d = nrm.dot(*p - c);
                front |= d > tol;
                back |= d < -tol;
                if front && back {
                    break;
                }
            }
            (patches.source_triangle[i], !(front && back))
        })
        .collect();
    (0..n)
        .map(|i| !supporting[&patches.source_triangle[i]])
        .collect()
}

/// True when the surface point `x` of patch `i` is buried: the first surface hit straight
/// along its normal is seen from behind, i.e. `x` lies inside a closed object or under a
/// surface lying on it (the floor under a block, the ceiling behind a light mounted on it).
/// Such points receive no light and are seen by nobody, so they must not dilute their
/// patch's radiance; their patch's rows are rescaled to its visible part.
pub fn is_hidden(patches: &Patches, vis: &Visibility, i: usize, x: DVec3) -> bool {
    let n = patches.normal[i];
    match vis.closest_hit(x, n, f64::INFINITY, i as u32) {
        Some(hit) => patches.normal[hit.triangle as usize].dot(n) > 0.0,
        None => false,
    }
}

/// The visible (unburied) fraction of a patch's area is measured at the centroids of its
/// regular split into this many squared sub-triangles ([`sampling::lattice_barycentrics`]).
pub const VISIBLE_AREA_LATTICE: usize = 4;

/// Hemisphere shooting computes direct light exactly only when at most 1/this of the patches
/// emit (not in a furnace, where every patch does).
pub const EXACT_DIRECT_FRACTION: usize = 20;

/// … and when emitters × patches (the pairs that costs) is at most this.
pub const EXACT_DIRECT_PAIRS: f64 = 2e8;

/// Probe rays per patch that decide whether a scene is closed ([`compute`]).
pub const CLOSURE_PROBES: u32 = 64;

/// Σ_j F_ij per row, in f64.
fn row_sums_of(m: &CsMatI<f32, u32>) -> Vec<f64> {
    m.outer_iterator()
        // `+ 0.0` turns the empty sum's −0.0 into 0.
        .map(|r| r.data().iter().map(|&f| f as f64).sum::<f64>() + 0.0)
        .collect()
}

/// Divide row i by `fraction[i]` where fraction > 0 and ≠ 1 (rows with fraction 0 are left).
fn scale_rows(m: &mut CsMatI<f32, u32>, fraction: &[f64]) {
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
