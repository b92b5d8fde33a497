//! Many segments from one point: the light buffer of Haines & Greenberg ("The Light Buffer: A
//! Shadow-Testing Accelerator", IEEE CG&A 6(9), 1986), a shaft structure per origin. The
//! directions around the origin are cut into the cells of a cube map (six faces of
//! [`CELLS`] × [`CELLS`]); each cell holds the set of triangles that some direction of the cell
//! may meet. A segment from the origin tests only the triangles of its direction's cell, first
//! the one that blocked the previous blocked segment (their "last occluder" cache: a form-factor
//! row aims at neighbouring patches one after another), and of the others only those that the
//! segment can reach (its length against their distance) and whose plane it crosses (its ends'
//! signed distances). Each test is the watertight ray and triangle test of
//! [`Visibility::occluded_points`], so every answer is that query's answer, bit for bit.
//!
//! Why the cell sets are complete: if the `f32` ray of a segment hits triangle T, the exact
//! segment passes within the rounding of the canonical frame (≲ 1e-3 canonical units, see
//! [`super`]) of a point y of T, so within [`SLACK`] (1/16 canonical unit), and its direction is
//! within θ ≤ asin(SLACK / D) of y's, D a lower bound of T's distance from the origin (to its
//! bounding sphere, or to its plane). On a face, where the major component of a unit direction is
//! at least 1/√3, the cube-map coordinates (`u/w`, `v/w`) then differ from y's by at most
//! 2θ / (1/√3 − θ) < 4.5·SLACK/D (for D ≥ [`NEAR`]·SLACK, θ ≤ 1/16). So each face takes T clipped
//! to the face's pyramid of directions widened by that much, projects it (central projection
//! maps it to the convex polygon of its projected corners, all with `w > 0`), and marks the cells
//! of the projection's bounds widened alike, and by [`CELL_EPS`] against the rounding of the
//! division. A triangle nearer than `NEAR`·SLACK is in every cell. The two culls before a test
//! are conservative by the same SLACK.
//!
//! A buffer holds one bit per triangle and cell, so it serves triangle sets of at most
//! [`MAX_TRIANGLES`] (the form factors' occluders are the scene triangles off the convex hull:
//! 22 in the Cornell box); beyond that every query tries the last occluder and then traverses
//! the BVH as [`Visibility::occluded_points`] does. Its memory is reused between origins (no
//! allocation per origin or per segment). Measured in BENCHMARKS.md ("Visibility: rays against
//! Embree").

use glam::DVec3;

use super::{Point, Visibility};

/// Cells along each side of a cube-map face.
pub const CELLS: usize = 16;

/// Triangle sets up to this size are buffered (four 64-bit words per cell).
pub const MAX_TRIANGLES: usize = 256;

/// How near a segment may pass a triangle that its `f32` ray hits, canonical units, with room
/// to spare (1/16: about 6e-5 of the scene's extent, far above the `f32` rounding of rays and
/// triangles in the canonical frame, ≲ 1e-3 canonical units, and four times the BVH's box
/// padding).
pub const SLACK: f64 = 1.0 / 16.0;

/// Triangles closer to the origin than this many [`SLACK`]s are candidates in every cell.
pub const NEAR: f64 = 16.0;

/// Widening of each cell range in cube-map coordinates (which lie in [−1, 1]), far above the
/// rounding of one `f64` division.
pub const CELL_EPS: f64 = 1e-9;

/// The light buffer of one origin over the triangles of a [`Visibility`] (see the module
/// documentation). Invariant once aimed: `cells` holds `6·CELLS²·words` words, bit `t` of cell
/// `c` set if triangle `t` of `vis` may block a segment from `origin` whose direction lies in
/// cell `c`, and `near[t]`, `side[t]` belong to `origin`.
pub struct LightBuffer<'a> {
    vis: &'a Visibility,
    /// 64-bit words per cell; 0 when the buffer falls back to the BVH.
    words: usize,
    cells: Vec<u64>,
    /// Per triangle: a lower bound of its distance from the origin less [`SLACK`] (infinite
    /// for an ignored one), canonical units.
    near: Vec<f64>,
    /// Per triangle: its bounding sphere (centre, radius), canonical units.
    spheres: Vec<(DVec3, f64)>,
    /// Per triangle: its plane, unit normal `n` and offset `n·a` (`f64` from its `f32` corners).
    planes: Vec<(DVec3, f64)>,
    /// Per triangle: the origin's signed distance to its plane.
    side: Vec<f64>,
    origin: Option<Point>,
    /// The triangle that blocked the last blocked segment (tested first: consecutive segments
    /// from one origin to neighbouring patches are often blocked by the same triangle, the
    /// light buffer's "last occluder" cache), or `usize::MAX`.
    last: std::cell::Cell<usize>,
    /// The input triangle the origin lies on (left out of every cell), or [`super::NONE`].
    ignore: u32,
}

/// The cube-map cell of canonical direction `d` (not zero): face `2·m + (d_m < 0)` for the axis
/// `m` of the largest magnitude, then the cells of the other two coordinates divided by it.
#[inline(always)]
fn cell_of(d: DVec3) -> usize {
    let a = d.abs();
    let m = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    let w = a[m];
    let (u, v) = (d[(m + 1) % 3] / w, d[(m + 2) % 3] / w);
    let face = 2 * m + (d[m] < 0.0) as usize;
    (face * CELLS + coordinate_cell(u)) * CELLS + coordinate_cell(v)
}

/// The cell along one side of a face of cube-map coordinate `u` ∈ [−1, 1] (clamped).
#[inline(always)]
fn coordinate_cell(u: f64) -> usize {
    (((u + 1.0) * (CELLS as f64 / 2.0)) as usize).min(CELLS - 1)
}

/// The cells of cube-map face `face` (axis `m = face / 2`, `w = ±x_m`) that directions to
/// the triangle `corners` (relative to the origin) reach, each coordinate's range widened by
/// `widen`: `[(u0, u1), (v0, v1)]`, or `None` if none. The triangle is clipped to the face's
/// pyramid of directions widened alike (`|x_u|, |x_v| ≤ (1 + widen)·w`), where central
/// projection maps it to the convex polygon of its projected corners.
fn face_range(corners: &[DVec3; 3], face: usize, widen: f64) -> Option<[(usize, usize); 2]> {
    let (m, sign) = (face / 2, if face.is_multiple_of(2) { 1.0 } else { -1.0 });
    // Face-local coordinates (u, v, w).
    let local = |x: DVec3| DVec3::new(x[(m + 1) % 3], x[(m + 2) % 3], sign * x[m]);
    let mut poly = [DVec3::ZERO; 8];
    let mut len = 3;
    for (k, c) in corners.iter().enumerate() {
        poly[k] = local(*c);
    }
    let k = 1.0 + widen;
    // The four planes of the widened pyramid: k·w ± u ≥ 0, k·w ± v ≥ 0.
    let planes = [
        DVec3::new(1.0, 0.0, k),
        DVec3::new(-1.0, 0.0, k),
        DVec3::new(0.0, 1.0, k),
        DVec3::new(0.0, -1.0, k),
    ];
    // Each corner's values of the four planes: wholly outside one plane, no cell; wholly
    // inside all four (the common case), nothing to clip.
    let values = poly[..3].iter().map(|x| planes.map(|p| p.dot(*x)));
    let (mut inside, mut outside) = ([true; 4], [true; 4]);
    for v in values {
        for (i, f) in v.into_iter().enumerate() {
            inside[i] &= f >= 0.0;
            outside[i] &= f < 0.0;
        }
    }
    if outside.contains(&true) {
        return None;
    }
    for (plane, _) in planes.into_iter().zip(inside).filter(|(_, inside)| !inside) {
        let mut out = [DVec3::ZERO; 8];
        let mut n = 0;
        let mut a = poly[len - 1];
        let mut fa = plane.dot(a);
        for &b in &poly[..len] {
            let fb = plane.dot(b);
            if (fa >= 0.0) != (fb >= 0.0) {
                out[n] = a + (b - a) * (fa / (fa - fb));
                n += 1;
            }
            if fb >= 0.0 {
                out[n] = b;
                n += 1;
            }
            (a, fa) = (b, fb);
        }
        if n == 0 {
            return None;
        }
        (poly, len) = (out, n);
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for x in &poly[..len] {
        if x.z <= 0.0 {
            // Only the origin itself has w ≤ 0 inside the pyramid, and it is far from the
            // triangle; rounding at the apex: take the whole face.
            return Some([(0, CELLS - 1); 2]);
        }
        for (axis, value) in [x.x / x.z, x.y / x.z].into_iter().enumerate() {
            lo[axis] = lo[axis].min(value);
            hi[axis] = hi[axis].max(value);
        }
    }
    let range = |axis: usize| {
        let (min, max) = (lo[axis] - widen - CELL_EPS, hi[axis] + widen + CELL_EPS);
        (
            coordinate_cell(min.clamp(-1.0, 1.0)),
            coordinate_cell(max.clamp(-1.0, 1.0)),
        )
    };
    Some([range(0), range(1)])
}

impl<'a> LightBuffer<'a> {
    /// An unaimed buffer over `vis`'s triangles.
    pub fn new(vis: &'a Visibility) -> LightBuffer<'a> {
        let n = vis.tris.len();
        let words = if n == 0 || n > MAX_TRIANGLES {
            0
        } else {
            n.div_ceil(64)
        };
        // Triangles with per-triangle tables: all of them when there are cells, else none.
        let m = if words == 0 { 0 } else { n };
        LightBuffer {
            vis,
            words,
            cells: vec![0; 6 * CELLS * CELLS * words],
            near: vec![0.0; m],
            spheres: vis.tris[..m]
                .iter()
                .map(|tri| {
                    let [a, b, c] = tri.map(|v| v.as_dvec3());
                    let centre = (a + b + c) / 3.0;
                    let r = centre
                        .distance(a)
                        .max(centre.distance(b))
                        .max(centre.distance(c));
                    (centre, r * (1.0 + 1e-9))
                })
                .collect(),
            planes: vis.tris[..m]
                .iter()
                .map(|tri| {
                    let [a, b, c] = tri.map(|v| v.as_dvec3());
                    let normal = (b - a).cross(c - a).normalize_or_zero();
                    (normal, normal.dot(a))
                })
                .collect(),
            side: vec![0.0; m],
            origin: None,
            last: std::cell::Cell::new(usize::MAX),
            ignore: super::NONE,
        }
    }

    /// Prepares for segments from `origin`, a point on input triangle `ignore` (or
    /// [`super::NONE`]): `ignore` and its twin never block them.
    pub fn aim(&mut self, origin: &Point, ignore: u32) {
        self.origin = Some(*origin);
        self.last.set(usize::MAX);
        self.ignore = ignore;
        if self.words == 0 {
            return;
        }
        self.cells.fill(0);
        let vis = self.vis;
        let p = origin.canonical;
        for (t, tri) in vis.tris.iter().enumerate() {
            let (normal, offset) = self.planes[t];
            self.side[t] = normal.dot(p) - offset;
            if vis.ignored(t, [ignore, ignore]) {
                // Never a candidate: no bit, and no distance to test.
                self.near[t] = f64::INFINITY;
                continue;
            }
            let corners = tri.map(|v| v.as_dvec3() - p);
            let (centre, radius) = self.spheres[t];
            let v = centre - p;
            // Lower bounds of the distance from the origin to the triangle: to its bounding
            // sphere, to its plane.
            let near = (v.length() - radius).max(0.0);
            self.near[t] = (near - SLACK).max(0.0);
            let distance = near.max(self.side[t].abs());
            let (word, bit) = (t / 64, 1u64 << (t % 64));
            if distance < NEAR * SLACK {
                // The origin lies on or next to the triangle: every direction may meet it.
                for cell in self.cells.chunks_exact_mut(self.words) {
                    cell[word] |= bit;
                }
                continue;
            }
            // A segment that the `f32` ray makes hit the triangle passes within SLACK of one of
            // its points y, so its direction is within θ ≤ asin(SLACK / distance) of y's; on a
            // face, cube-map coordinates move by at most 2θ / (1/√3 − θ) < 4.5·SLACK/distance
            // (the module documentation).
            let widen = 4.5 * SLACK / distance;
            for face in 0..6 {
                if let Some([(u0, u1), (v0, v1)]) = face_range(&corners, face, widen) {
                    for u in u0..=u1 {
                        for w in v0..=v1 {
                            let cell = (face * CELLS + u) * CELLS + w;
                            self.cells[cell * self.words + word] |= bit;
                        }
                    }
                }
            }
        }
    }

    /// Too many triangles for cells: [`Visibility::occluded_points`] through the BVH, after the
    /// last occluder (the cache serves here too; the many-occluder rows of a furnished hall
    /// are blocked one segment in two, mostly by the triangle that blocked the one before).
    fn occluded_by_bvh(&self, p: &Point, q: &Point, both: [u32; 2]) -> bool {
        let mut last = self.last.get();
        let blocked = self.vis.occluded_points_after(p, q, both, &mut last);
        self.last.set(last);
        blocked
    }

    /// [`Visibility::occluded_points`]`(origin, q, [ignore of aim, ignore])`, the same answer
    /// bit for bit, testing only the triangles of the segment's cell.
    ///
    /// # Panics
    /// If the buffer was never aimed.
    #[inline]
    pub fn occluded(&self, q: &Point, ignore: u32) -> bool {
        let p = self
            .origin
            .as_ref()
            .expect("LightBuffer::aim before occluded");
        let both = [self.ignore, ignore];
        if self.words == 0 {
            return self.occluded_by_bvh(p, q, both);
        }
        let d = q.canonical - p.canonical;
        if d == DVec3::ZERO {
            // No segment (equal points among them): never occluded, as `occluded_points`.
            return false;
        }
        let cell = cell_of(d);
        let masks = &self.cells[cell * self.words..(cell + 1) * self.words];
        if masks.iter().all(|&m| m == 0) {
            return false;
        }
        let vis = self.vis;
        let length = d.length();
        let last = self.last.get();
        // The segment can reach triangle t and crosses its plane (conservative by SLACK).
        let crosses = |t: usize| {
            let (normal, offset) = self.planes[t];
            let (hp, hq) = (self.side[t], normal.dot(q.canonical) - offset);
            self.near[t] <= length
                && hp.min(hq) <= SLACK
                && hp.max(hq) >= -SLACK
                && !vis.ignored(t, both)
        };
        let cached = last != usize::MAX && masks[last / 64] >> (last % 64) & 1 == 1;
        let mut ray = None;
        if cached && crosses(last) {
            let Some(r) = vis.segment_ray_along(p, d, length) else {
                return false;
            };
            if r.intersect(&vis.tris[last], r.t_lo, r.t_hi).is_some() && !vis.lets_through(last, &r)
            {
                return true;
            }
            ray = Some(r);
        }
        // The cell's other triangles that the segment crosses.
        for (w, &mask) in masks.iter().enumerate() {
            let mut bits = mask;
            while bits != 0 {
                let t = w * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                if t == last || !crosses(t) {
                    continue;
                }
                if ray.is_none() {
                    ray = vis.segment_ray_along(p, d, length);
                }
                let Some(r) = &ray else {
                    return false;
                };
                if r.intersect(&vis.tris[t], r.t_lo, r.t_hi).is_some() && !vis.lets_through(t, r) {
                    self.last.set(t);
                    return true;
                }
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A direction's cell does not depend on the sign of its zero components (a segment's
    /// direction is a difference, never −0.0, but the lookup must not care), and each face's
    /// cells are where the face's axis is largest.
    #[test]
    fn cells_ignore_the_sign_of_zero() {
        for d in [
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, -2.0, 0.0),
            DVec3::new(0.5, 0.0, -3.0),
            DVec3::new(0.0, 1.0, 1.0),
        ] {
            let flipped = DVec3::new(
                if d.x == 0.0 { -0.0 } else { d.x },
                if d.y == 0.0 { -0.0 } else { d.y },
                if d.z == 0.0 { -0.0 } else { d.z },
            );
            assert_eq!(cell_of(d), cell_of(flipped), "{d}");
        }
        // +x, −y and −z faces: 0, 3 and 5.
        assert_eq!(cell_of(DVec3::new(1.0, 0.0, 0.0)) / (CELLS * CELLS), 0);
        assert_eq!(cell_of(DVec3::new(0.1, -2.0, 0.3)) / (CELLS * CELLS), 3);
        assert_eq!(cell_of(DVec3::new(0.5, 0.0, -3.0)) / (CELLS * CELLS), 5);
    }
}
