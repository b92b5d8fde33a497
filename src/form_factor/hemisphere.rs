//! Hemisphere shooting: the solid-angle form of the form factor. From stratified points of
//! patch i, cosine-weighted directions are traced to their first hit; the fraction of rays
//! that land on the front of patch j estimates F_ij (Cohen & Wallace §4.9; Malley's method for
//! the cosine-weighted directions, pbrt-v4 `SampleCosineHemisphere`):
//!
//! F_ij = (1/A_i) ∫_Ai ∫_Ω (cosθ/π) · [ray(x, ω) first hits j] dω dA_i ≈ (1/N) Σ_k [hit_k = j].
//!
//! Every ray lands on at most one patch, so a row sums to (rays that hit a front face)/N ≤ 1,
//! and exactly 1 in a closed scene: the furnace is exact whatever the noise. The cost is
//! O(patches × rays) instead of O(patches²), so it is the estimator for large scenes; its
//! error is Monte Carlo noise, O(N^-½) per entry.

use rayon::prelude::*;

use crate::geometry::orthonormal_basis;
use crate::mesh::Patches;
use crate::sampling::{malley, permutation, triangle_barycentrics, Rng};
use crate::visibility::Visibility;

/// Barycentric margin that keeps ray origins off the patch's edges (an unsampled strip of
/// relative area ≈ 6e-4, a bias far below the estimator's noise).
const EDGE_MARGIN: f64 = 1e-4;

/// One patch's row of F.
#[derive(Debug, Clone)]
pub struct Row {
    /// (column j, F_ij), sorted by column.
    pub entries: Vec<(u32, f32)>,
    /// Rays cast (including the buried-origin tests).
    pub rays: u64,
    /// Fraction of the ray origins that are not buried ([`Visibility::buried`]).
    pub visible_fraction: f64,
    /// Rays from unburied origins that left the scene or met the back of a surface: light
    /// lost from an open scene. 0 for every patch ⇔ (as far as these rays tell) closed.
    pub escaped: usize,
}

/// The row of F for patch `i`.
pub fn row(patches: &Patches, vis: &Visibility, i: usize, rays: u32, seed: u64) -> Row {
    let n = rays as usize;
    let mut rng = Rng::new(&[seed, i as u64, 0x4E4D]);
    // Latin-hypercube strata, independent permutations for position (u, v) and direction
    // (s, t): every 1D projection is stratified.
    let perms: [Vec<usize>; 3] = std::array::from_fn(|_| permutation(n, &mut rng));
    let [a, b, c] = patches.corners(i);
    let facet = patches.normal[i];
    let mut hits: Vec<u32> = Vec::with_capacity(n);
    let (mut buried, mut extra_rays, mut escaped) = (0usize, 0usize, 0usize);
    #[allow(clippy::needless_range_loop)] // k is the stratum index of four arrays
    for k in 0..n {
        let u = (k as f64 + rng.next_f64()) / n as f64;
        let v = (perms[0][k] as f64 + rng.next_f64()) / n as f64;
        // Barycentrics pulled in by EDGE_MARGIN: an origin within f32 rounding of an edge
        // could otherwise "hit" the coplanar neighbour from behind at t ≈ 0, or start so
        // close to an adjacent wall that the hit falls below the minimum distance.
        let w = triangle_barycentrics(u, v).map(|x| (x + EDGE_MARGIN) / (1.0 + 3.0 * EDGE_MARGIN));
        let origin = w[0] * a + w[1] * b + w[2] * c;
        // Cosine-weighted about the surface normal at the origin (the facet's own normal on
        // flat surfaces; see [`Patches::surface_normal`]). The basis flips where n.z changes
        // sign; snap the normal first so that a component that is 0 in one unit of length and
        // ±1e-19 in another picks the same basis (same rays).
        let normal = patches.surface_normal(i, w);
        let (tangent, bitangent) =
            orthonormal_basis((normal * 2f64.powi(40)).round() / 2f64.powi(40));
        let s = (perms[1][k] as f64 + rng.next_f64()) / n as f64;
        let t = (perms[2][k] as f64 + rng.next_f64()) / n as f64;
        let mut dir = malley(s, t, tangent, bitangent, normal);
        if facet.dot(dir) <= 0.0 {
            // Where the surface normal leans off the facet's, a sliver of its hemisphere
            // (projected measure O(tilt²)) lies behind the facet: on the smooth surface those
            // grazing directions meet the neighbouring surface, on the facet they would pass
            // through it. Mirror them into the facet's hemisphere so no energy is lost.
            dir -= 2.0 * facet.dot(dir) * facet;
        }
        if let Some(hit) = vis.closest_hit(origin, dir, f64::INFINITY, i as u32) {
            let j = hit.triangle;
            // Only the front of a one-sided surface receives light.
            if patches.normal[j as usize].dot(dir) < 0.0 {
                hits.push(j);
            } else {
                // A back face: either light lost through an open scene, or an origin buried
                // in contact geometry, which must not count as a sample of the patch at all.
                extra_rays += 1;
                // A back met within the contact distance: the origin touches that object and
                // the ray slipped in through the seam (a chair leg's side at the seat).
                if hit.t <= vis.contact_distance()
                    || vis.buried(origin, patches.normal[i], i as u32)
                {
                    buried += 1;
                } else {
                    escaped += 1;
                }
            }
        } else if vis.buried(origin, patches.normal[i], i as u32) {
            // Nothing ahead: open, unless the origin lies face to face on another surface
            // (a leg's bottom on the floor), which hides it.
            extra_rays += 1;
            buried += 1;
        } else {
            escaped += 1;
        }
    }
    hits.sort_unstable();
    let counted = (n - buried).max(1);
    let mut row: Vec<(u32, f32)> = Vec::new();
    for j in hits {
        match row.last_mut() {
            Some(last) if last.0 == j => last.1 += 1.0,
            _ => row.push((j, 1.0)),
        }
    }
    for e in &mut row {
        e.1 /= counted as f32;
    }
    Row {
        entries: row,
        rays: (n + extra_rays) as u64,
        visible_fraction: (n - buried) as f64 / n as f64,
        escaped,
    }
}

/// The rows in `needed` (each keeping only the needed columns; the other rows empty, with
/// no ray cast), in parallel (deterministic: each row depends only on (seed, i)).
pub fn rows(
    patches: &Patches,
    vis: &Visibility,
    rays: u32,
    seed: u64,
    needed: &super::Needed,
) -> Vec<Row> {
    let progress = crate::progress::stage("form factors", Some(patches.len() as u64));
    (0..patches.len())
        .into_par_iter()
        .map(|i| {
            progress.advance(1);
            if !needed.rows[i] {
                return Row {
                    entries: Vec::new(),
                    rays: 0,
                    visible_fraction: 1.0,
                    escaped: 0,
                };
            }
            let mut r = row(patches, vis, i, rays, seed);
            r.entries.retain(|&(j, _)| needed.columns[j as usize]);
            r
        })
        .collect()
}
