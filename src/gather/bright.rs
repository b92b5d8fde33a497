//! The bright patches of a solution as sources of the gather's indirect light, sampled
//! directly (next-event estimation on reflected light) and combined with the hemisphere rays
//! by multiple importance sampling.
//!
//! The hemisphere rays of [`super::indirect`] find a surface's light in proportion to the
//! solid angle it fills. A small, far, very bright surface (the floor where the sun falls
//! through a window, tens of times brighter than the rest of the room) is then met by few
//! rays or none: the gather at a point across the room sees it or misses it by chance, and
//! the light it reflects, most of a daylit room's indirect light, comes out with a noise of
//! several per cent even at a thousand rays, in blotches that no display hides.
//!
//! So the patches whose reflected radiance R = L − Le is more than [`BRIGHT_FACTOR`] times
//! the area-weighted mean of the scene's non-emitting patches (luminance) form a set B, and a
//! gathering point also casts [`bright_rays`] shadow rays to points of B: patch h drawn with
//! probability P(h) = Y(R_h) A_h / Σ_B Y(R) A (systematic sampling, Kitagawa 1996), a uniform
//! point y of it, bringing R_h cosθ_x cosθ_y / (π r²) / (P(h) / A_h) where y is seen. Each ray
//! of either kind that reaches a far point of B (beyond the near-hit reach,
//! [`super::indirect::NEAR_HIT`], where the hemisphere rays evaluate the radiance one bounce
//! further instead of R_h) counts with the balance heuristic's weight (Veach & Guibas 1995):
//! a hemisphere ray in a stratum of n_k rays (of S strata) w = c_h / (c_h + c_l), a bright
//! ray w = c_l / (c_h + c_l), with c_h = n_k S cosθ_x / π and c_l = K P(h)/A_h · r² / cosθ_y,
//! the two strategies' sample densities over directions. The weights sum to one at every
//! direction, so the estimate stays unbiased; where a bright patch fills much of the
//! hemisphere (a point beside the sun patch) the hemisphere rays carry it, where it is a
//! speck, the bright rays. Elsewhere (a hit on any other patch, a near hit) nothing changes,
//! and a scene with no patch that bright gathers as before.

use glam::DVec3;

use crate::color::{luminance, Rgb};
use crate::mesh::Patches;

/// A non-emitting patch is a bright source of the gather when its reflected radiance's
/// luminance is more than this many times the area-weighted mean of the non-emitting patches':
/// the sun's patches on a daylit floor are tens of times the mean, the brightest surfaces of
/// a room under lamps a few times.
pub const BRIGHT_FACTOR: f64 = 8.0;

/// Shadow rays to the bright patches at a gathering point (a `cache` record, a `full` vertex,
/// a display-refinement test), where there are any, at the fewest ([`bright_rays`]).
pub const BRIGHT_RAYS: usize = 32;

/// The bright rays' share of a gathering point's hemisphere rays, past [`BRIGHT_RAYS`].
///
/// The balance heuristic combines the two strategies by their numbers of samples (Veach &
/// Guibas 1995), so a fixed count of bright rays is a smaller share of the estimate the more
/// hemisphere rays there are: with 32 of them beside 1,024 hemisphere rays, most of the
/// bright patches' light still came from the hemisphere rays that happen to meet them. A
/// fixed share keeps the variance reduction at every count. Gathered at the daylit office's
/// probes by 1,024 hemisphere rays, one gather's noise was 5.30 % RMS with no bright rays,
/// 3.15 % with 32 and 2.32 % with 256 (its ceiling, lit by the sun's patches on the floor:
/// 5.45, 3.53 and 2.19 %); a bright ray is a shadow ray, cheaper than a hemisphere ray that
/// reads what it hits (BENCHMARKS.md "A daylit office").
pub const BRIGHT_SHARE: f64 = 0.25;

/// The bright rays beside `rays` hemisphere rays: [`BRIGHT_SHARE`] of them, at least
/// [`BRIGHT_RAYS`].
pub fn bright_rays(rays: usize) -> usize {
    BRIGHT_RAYS.max((rays as f64 * BRIGHT_SHARE) as usize)
}

/// The bright patches and how a gathering point draws them.
pub(super) struct Bright {
    /// Cumulative Y(R_h) A_h over `keys`, normalised to end at 1.
    cdf: Vec<f64>,
    /// The bright patches, in index order.
    keys: Vec<u32>,
    /// P(h) / A_h for each patch (0 for those not bright): the area density of a draw on h.
    density: Vec<f64>,
}

impl Bright {
    /// The bright patches of `radiance` over `patches` (see the module documentation), or
    /// `None` where there are none.
    pub(super) fn of(patches: &Patches, radiance: &[Rgb]) -> Option<Bright> {
        let reflected = |h: usize| {
            let (l, le) = (radiance[h], patches.emission[h]);
            luminance(std::array::from_fn(|c| (l[c] - le[c]).max(0.0)))
        };
        let unlit = |h: usize| patches.emission[h].iter().all(|&e| e == 0.0);
        let (mut sum, mut area) = (0.0, 0.0);
        for h in (0..patches.len()).filter(|&h| unlit(h)) {
            sum += reflected(h) * patches.area[h];
            area += patches.area[h];
        }
        if !(area > 0.0 && sum > 0.0) {
            return None;
        }
        let threshold = BRIGHT_FACTOR * sum / area;
        let (mut cdf, mut keys, mut total) = (Vec::new(), Vec::new(), 0.0);
        for h in (0..patches.len()).filter(|&h| unlit(h)) {
            let y = reflected(h);
            if y > threshold && patches.area[h] > 0.0 {
                total += y * patches.area[h];
                cdf.push(total);
                keys.push(h as u32);
            }
        }
        if keys.is_empty() {
            return None;
        }
        let mut density = vec![0.0; patches.len()];
        let mut before = 0.0;
        for (c, &h) in cdf.iter_mut().zip(&keys) {
            let p = (*c - before) / total;
            before = *c;
            density[h as usize] = p / patches.area[h as usize];
            *c /= total;
        }
        Some(Bright { cdf, keys, density })
    }

    /// The solid-angle density c_l / K with which a bright ray from `x` proposes the direction
    /// to the point `y` of patch `h` (unit normal `ny`): P(h)/A_h · r² / cosθ_y; 0 where `h` is
    /// not bright or `y` is seen edge-on.
    pub(super) fn direction_density(&self, h: usize, x: DVec3, y: DVec3, ny: DVec3) -> f64 {
        let a = self.density[h];
        if a == 0.0 {
            return 0.0;
        }
        let d = y - x;
        let r2 = d.length_squared();
        let cos = -ny.dot(d) / r2.sqrt();
        if cos > 0.0 {
            a * r2 / cos
        } else {
            0.0
        }
    }

    /// The bright patches drawn by `count` systematic draws from `u` ∈ [0, 1).
    pub(super) fn draws(&self, count: usize, u: f64) -> impl Iterator<Item = usize> + '_ {
        crate::sampling::systematic(&self.cdf, count, u).map(|(at, _)| self.keys[at] as usize)
    }
}
