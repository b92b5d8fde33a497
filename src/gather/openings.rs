//! Where the sky comes into a room: the openings found by a pilot of rays, as cells of the
//! scene's bounding box that the gather's points aim shadow rays through, weighed against
//! the hemisphere's rays by multiple importance sampling.
//!
//! Indoors, the sky is seen through windows and doors that fill a small part of a point's
//! hemisphere, far from most points: the hemisphere rays that leave the scene through them
//! are few and fall by chance, and the sky's light, most of a daylit room's, comes out with
//! a noise of several per cent at every vertex even at a thousand rays (the point-wise
//! benchmark's daylit office). Where a scene is open to the sky through a small share of the
//! directions its surfaces see (a pilot of [`PILOT_RAYS`] cosine-weighted rays from points of
//! its patches drawn by area; under [`ENCLOSED_SHARE`] of those above the horizon leave it),
//! the rays that leave the scene tell where the openings are: each crosses the scene's
//! bounding box (grown by a margin) in one of its faces' [`CELLS`] × [`CELLS`] cells, and the
//! cells any pilot ray crossed are drawn in proportion to their area (portals found by
//! rays rather than given by the user, as in Bitterli et al., "Portal-masked environment map
//! sampling", 2015, whose portals a modeller marks). A gathering point then casts
//! [`OPENING_RAYS`] rays toward uniform points of drawn cells; one that leaves the scene
//! brings the sky's radiance in its direction. Every direction leaves the box through
//! exactly one point, so the density with which those rays propose a direction ω is
//! P(c)/A_c · r²/|cosθ_c| (the cell c it leaves by, at distance r, at angle θ_c to the face's
//! normal), and the rays that leave the scene, the hemisphere's and these, count with the
//! balance heuristic's weights (Veach & Guibas 1995), which sum to one: the estimate stays
//! unbiased. A scene open to most of the sky (outdoors, a roofless hall) keeps the hemisphere's
//! ratio estimate, exact where nothing is in the way.

use glam::DVec3;

use super::trace::Surfaces;
use crate::mesh::Patches;
use crate::sampling::{malley, systematic, Rng};

/// Pilot rays that find the openings.
pub const PILOT_RAYS: usize = 1 << 18;

/// The openings are sampled where fewer than this share of the pilot's rays above the
/// horizon leave the scene: a room whose windows fill a few per cent of its surfaces' view.
/// Beyond it most of the sky is in view, the hemisphere rays find it, and its ratio estimate
/// ([`crate::light::outside`]) is exact where nothing is in the way.
pub const ENCLOSED_SHARE: f64 = 0.25;

/// Cells per side of each face of the bounding box.
pub const CELLS: usize = 64;

/// Rays through the openings at a gathering point.
pub const OPENING_RAYS: usize = 32;

/// The openings of a scene (see the module documentation).
pub(super) struct Openings {
    /// The bounding box, grown by a margin.
    lo: DVec3,
    hi: DVec3,
    /// Cumulative area over `keys`, normalised to end at 1.
    cdf: Vec<f64>,
    /// The cells crossed, as face · CELLS² + row · CELLS + column.
    keys: Vec<u32>,
    /// P(c) / A_c of every cell: 1 / the crossed cells' area, 0 for cells no pilot ray
    /// crossed.
    density: Vec<f64>,
}

impl Openings {
    /// The openings of the patches traced by `surfaces` to a sky above the horizon of `up`, or
    /// `None` where the scene is open to most of it (or to none).
    pub(super) fn find(
        patches: &Patches,
        surfaces: &Surfaces,
        up: DVec3,
        lift: f64,
        seed: u64,
    ) -> Option<Openings> {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for i in 0..patches.len() {
            for c in patches.corners(i) {
                (lo, hi) = (lo.min(c), hi.max(c));
            }
        }
        let margin = 1e-3 * (hi - lo).length().max(f64::MIN_POSITIVE);
        let (lo, hi) = (lo - DVec3::splat(margin), hi + DVec3::splat(margin));
        let cdf: Vec<f64> = patches
            .area
            .iter()
            .scan(0.0, |s, &a| {
                *s += a;
                Some(*s)
            })
            .collect();
        if cdf.last().is_none_or(|&t| t <= 0.0) {
            return None;
        }
        let mut rng = Rng::new(&[seed, 0x009E_4175]);
        let mut counts = vec![0u32; 6 * CELLS * CELLS];
        let (mut above, mut left) = (0usize, 0usize);
        let mut openings = Openings {
            lo,
            hi,
            cdf: Vec::new(),
            keys: Vec::new(),
            density: Vec::new(),
        };
        for (i, _) in systematic(&cdf, PILOT_RAYS, rng.next_f64()) {
            let [a, b, c] = patches.corners(i);
            let [wa, wb, wc] =
                crate::sampling::triangle_barycentrics(rng.next_f64(), rng.next_f64());
            let x = wa * a + wb * b + wc * c;
            let n = patches.normal[i];
            let (t, bt) = n.any_orthonormal_pair();
            let dir = malley(rng.next_f64(), rng.next_f64(), t, bt, n);
            if dir.dot(up) <= 0.0 {
                continue;
            }
            above += 1;
            let origin = x + lift * n;
            if surfaces.closest(origin, dir, i as u32).is_some() {
                continue;
            }
            left += 1;
            if let Some((cell, _, _)) = openings.exit(origin, dir) {
                counts[cell] += 1;
            }
        }
        if left == 0 || left as f64 >= ENCLOSED_SHARE * above as f64 {
            return None;
        }
        // Every crossed cell by its area: uniform over the openings. (By the pilot's counts,
        // a few rays a cell, the cells' weights would be as noisy as those counts, and so
        // would every estimate through them.)
        // And their neighbours on the same face: a few pilot rays a cell leave holes in an
        // opening (cells no ray happened to cross), where only the hemisphere's rays would
        // find the sky; a ring of cells beyond its outline costs a few blocked rays.
        let crossed: Vec<usize> = (0..counts.len())
            .filter(|&c| {
                let (f, row, col) = (c / (CELLS * CELLS), (c / CELLS) % CELLS, c % CELLS);
                let near = |a: usize| a.saturating_sub(1)..(a + 2).min(CELLS);
                near(row).any(|r| near(col).any(|k| counts[f * CELLS * CELLS + r * CELLS + k] > 0))
            })
            .collect();
        let total: f64 = crossed.iter().map(|&c| openings.cell_area(c)).sum();
        let mut sum = 0.0;
        openings.density = vec![0.0; counts.len()];
        for cell in crossed {
            sum += openings.cell_area(cell);
            openings.cdf.push(sum / total);
            openings.keys.push(cell as u32);
            openings.density[cell] = 1.0 / total;
        }
        Some(openings)
    }

    /// The box's face `f` as (axis, side): axis 0, 1, 2 and side 0 (lo) or 1 (hi).
    fn face(f: usize) -> (usize, usize) {
        (f / 2, f % 2)
    }

    /// The other two axes of a face's plane.
    fn across(axis: usize) -> (usize, usize) {
        ((axis + 1) % 3, (axis + 2) % 3)
    }

    fn cell_area(&self, cell: usize) -> f64 {
        let (axis, _) = Self::face(cell / (CELLS * CELLS));
        let (u, v) = Self::across(axis);
        let size = self.hi - self.lo;
        size[u] * size[v] / (CELLS * CELLS) as f64
    }

    /// Where the ray from `origin` (inside the box) along `dir` leaves the box: the cell, the
    /// distance and |cos| of the angle to the face's normal.
    fn exit(&self, origin: DVec3, dir: DVec3) -> Option<(usize, f64, f64)> {
        let mut best: Option<(f64, usize)> = None;
        for axis in 0..3 {
            if dir[axis] == 0.0 {
                continue;
            }
            let (side, bound) = if dir[axis] > 0.0 {
                (1, self.hi[axis])
            } else {
                (0, self.lo[axis])
            };
            let t = (bound - origin[axis]) / dir[axis];
            if t >= 0.0 && best.is_none_or(|(bt, _)| t < bt) {
                best = Some((t, 2 * axis + side));
            }
        }
        let (t, f) = best?;
        let (axis, _) = Self::face(f);
        let (u, v) = Self::across(axis);
        let p = origin + t * dir;
        let size = self.hi - self.lo;
        let cell = |k: usize| {
            let s = ((p[k] - self.lo[k]) / size[k] * CELLS as f64).floor();
            (s.max(0.0) as usize).min(CELLS - 1)
        };
        let index = f * CELLS * CELLS + cell(u) * CELLS + cell(v);
        Some((index, t, dir[axis].abs() / dir.length()))
    }

    /// The solid-angle density with which one opening ray from `origin` proposes the
    /// direction `dir` (unit): P(c)/A_c · r² / |cosθ_c| at the cell c it leaves the box by.
    pub(super) fn direction_density(&self, origin: DVec3, dir: DVec3) -> f64 {
        match self.exit(origin, dir) {
            Some((cell, r, cos)) if cos > 0.0 => self.density[cell] * r * r / cos,
            _ => 0.0,
        }
    }

    /// `count` points of the openings, drawn by systematic sampling of the cells from `rng`
    /// and uniformly within each cell.
    pub(super) fn points(&self, count: usize, rng: &mut Rng) -> Vec<DVec3> {
        let cells: Vec<usize> = systematic(&self.cdf, count, rng.next_f64())
            .map(|(at, _)| self.keys[at] as usize)
            .collect();
        cells
            .into_iter()
            .map(|cell| {
                let f = cell / (CELLS * CELLS);
                let (row, col) = ((cell / CELLS) % CELLS, cell % CELLS);
                let (axis, side) = Self::face(f);
                let (u, v) = Self::across(axis);
                let size = self.hi - self.lo;
                let mut p = self.lo;
                p[axis] = if side == 1 {
                    self.hi[axis]
                } else {
                    self.lo[axis]
                };
                p[u] = self.lo[u] + (row as f64 + rng.next_f64()) / CELLS as f64 * size[u];
                p[v] = self.lo[v] + (col as f64 + rng.next_f64()) / CELLS as f64 * size[v];
                p
            })
            .collect()
    }
}
