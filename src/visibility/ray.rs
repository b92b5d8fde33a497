//! The watertight ray–triangle test (Woop, Benthin & Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2(1), 2013) on rays prepared once in the canonical frame, and the grids
//! the frame snaps coordinates and directions to (see the module documentation of
//! [`super`]).

use glam::{DVec3, Vec3A};

use super::Hit;

/// Distance, in units of the ray's direction vector, by which ray origins are moved back along
/// the ray. It was chosen to exceed the box-test clamp `t ≥ 1e-4` of the traversal the project
/// used before its own (obvhs's); kept so that rays, and so answers, stay the same.
const ORIGIN_SHIFT: f64 = 1.0 / 1024.0;

/// Canonical coordinates are multiples of this (2⁻²⁰ canonical units): far below `f32`
/// resolution at the frame's size (≈ 6e-5 at 1024), far above f64 rounding (≈ 1e-13).
pub(super) const CANONICAL_GRID: f64 = 1.0 / (1u64 << 20) as f64;

/// Unit ray directions are snapped to multiples of 2⁻⁴⁰.
pub(super) const DIRECTION_GRID: f64 = 1.0 / (1u64 << 40) as f64;

/// `x` rounded to the nearest multiple of `grid` in each coordinate.
pub(super) fn snap(x: DVec3, grid: f64) -> DVec3 {
    (x / grid).round() * grid
}

/// A ray prepared once for the watertight test of Woop, Benthin & Wald (JCGT 2013), in the
/// canonical frame: `x(t) = origin + t·dir` with the origin moved back by `ORIGIN_SHIFT`
/// (so internal parameters are `t + ORIGIN_SHIFT`).
#[derive(Clone, Copy, Debug)]
pub(super) struct WatertightRay {
    /// Shifted origin, canonical `f32`.
    pub origin: Vec3A,
    /// Direction, canonical `f32`.
    pub dir: Vec3A,
    /// Permutation to ray space: `k[2]` (kz) is the axis where the direction is largest in
    /// magnitude, `k[0]`, `k[1]` (kx, ky) the other two in the order that keeps the winding.
    pub k: [usize; 3],
    /// Shear to ray space: for `a = vertex − origin`, the vertex in ray space is
    /// `(a[kx] − s[0]·a[kz], a[ky] − s[1]·a[kz], s[2]·a[kz])`. The SIMD test
    /// ([`super::bvh4`]) evaluates exactly these operations, so both decide alike.
    pub s: [f32; 3],
    /// Query interval in internal (shifted) parameters, inclusive.
    pub t_lo: f32,
    pub t_hi: f32,
}

impl WatertightRay {
    /// Ray from `origin` along `dir` (canonical, `f64`), counting hits with
    /// `t ∈ [t_lo, t_hi]`. `None` if it cannot be represented in `f32`.
    #[inline]
    pub fn new(origin: DVec3, dir: DVec3, t_lo: f64, t_hi: f64) -> Option<WatertightRay> {
        // `+ 0.0` turns −0.0 components into +0.0: a box test that picks the near plane by
        // `dir < 0.0` (false for −0.0) but inverts −0.0 to −∞ would send a direction such as a
        // floor's normal (0, 1, −0) past every box it should enter (obvhs did; `bvh4` picks by
        // the inverse's sign and gives a zero component a finite inverse, and keeps this too).
        let dir32 = dir.as_vec3a() + Vec3A::ZERO;
        let origin32 = (origin - ORIGIN_SHIFT * dir).as_vec3a();
        if !(origin32.is_finite() && dir32.is_finite()) || dir32 == Vec3A::ZERO {
            return None;
        }
        // Step 1 (paper §3): kz is the dimension where the direction is largest in magnitude;
        // kx, ky follow cyclically and swap when dir[kz] < 0 to keep the triangles' winding.
        let kz = dir32.abs().max_position();
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if dir32[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        // Step 2: shear constants that map the ray onto the +z axis of ray space.
        let sz = 1.0 / dir32[kz];
        let sx = dir32[kx] * sz;
        let sy = dir32[ky] * sz;
        Some(WatertightRay {
            origin: origin32,
            dir: dir32,
            k: [kx, ky, kz],
            s: [sx, sy, sz],
            t_lo: (t_lo + ORIGIN_SHIFT) as f32,
            t_hi: (t_hi + ORIGIN_SHIFT) as f32,
        })
    }

    /// `v − origin` in ray space (step 3 of the paper): permuted and sheared.
    #[inline(always)]
    fn in_ray_space(&self, v: Vec3A) -> Vec3A {
        let a = v - self.origin;
        let [kx, ky, kz] = self.k;
        Vec3A::new(
            a[kx] - self.s[0] * a[kz],
            a[ky] - self.s[1] * a[kz],
            self.s[2] * a[kz],
        )
    }

    /// Watertight intersection with `tri` for internal parameters in `[t_lo, t_hi]`; returns
    /// `(t, u, v)` with `u`, `v` the barycentric weights of `tri[1]`, `tri[2]`. Both sides hit.
    ///
    /// Watertightness rests on each vertex being transformed to ray space independently of the
    /// triangle (so a shared edge gives exactly opposite edge functions in its two triangles)
    /// and on edge functions that are exactly 0 being recomputed in `f64`, where the products of
    /// `f32` values are exact and the sign of the difference is therefore exact.
    #[inline(always)]
    pub fn intersect(&self, tri: &[Vec3A; 3], t_lo: f32, t_hi: f32) -> Option<(f32, f32, f32)> {
        // Step 3: vertices relative to the origin, permuted and sheared to ray space.
        let a = self.in_ray_space(tri[0]);
        let b = self.in_ray_space(tri[1]);
        let c = self.in_ray_space(tri[2]);
        // Step 4: scaled barycentric coordinates (2D edge functions at the ray's (0, 0)).
        let mut e0 = c.x * b.y - c.y * b.x;
        let mut e1 = a.x * c.y - a.y * c.x;
        let mut e2 = b.x * a.y - b.y * a.x;
        // Step 5: fall back to f64 on the edge (exactly 0) for a consistent decision.
        if e0 == 0.0 || e1 == 0.0 || e2 == 0.0 {
            [e0, e1, e2] = exact_edges([a.x, a.y], [b.x, b.y], [c.x, c.y]);
        }
        // Step 6: inside if all edge functions share a sign (0 counts as either: the tie rule
        // that makes both triangles of a shared edge report the hit). No backface culling.
        if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
            return None;
        }
        let det = e0 + e1 + e2;
        if det == 0.0 {
            return None;
        }
        // Step 7: scaled hit distance, compared with the interval without dividing.
        let t_scaled = e0 * a.z + e1 * b.z + e2 * c.z;
        let sign = det.to_bits() & 0x8000_0000;
        let t_signed = f32::from_bits(t_scaled.to_bits() ^ sign);
        let det_abs = det.abs();
        if t_signed < t_lo * det_abs || t_signed > t_hi * det_abs {
            return None;
        }
        let rcp = 1.0 / det;
        Some((t_scaled * rcp, e1 * rcp, e2 * rcp))
    }

    /// Converts an internal `(t, id, u, v)` to a [`Hit`] for a direction scaled by `m`.
    pub fn hit(&self, (t, triangle, u, v): (f32, u32, f32, f32), m: f64) -> Hit {
        Hit {
            triangle,
            t: (f64::from(t) - ORIGIN_SHIFT) / m,
            u: f64::from(u),
            v: f64::from(v),
        }
    }
}

/// Step 5 of the watertight test: the three edge functions of the ray-space corners `a`, `b`,
/// `c` (x, y) recomputed in `f64`, where the products of `f32` values are exact, so the sign of
/// each is exact; rounded back to `f32`. Shared by [`WatertightRay::intersect`] and the
/// four-lane test ([`super::bvh4`]), so both decide alike.
#[inline]
pub(super) fn exact_edges(a: [f32; 2], b: [f32; 2], c: [f32; 2]) -> [f32; 3] {
    let edge = |p: f32, q: f32, r: f32, s: f32| {
        (f64::from(p) * f64::from(q) - f64::from(r) * f64::from(s)) as f32
    };
    [
        edge(c[0], b[1], c[1], b[0]),
        edge(a[0], c[1], a[1], c[0]),
        edge(b[0], a[1], b[1], a[0]),
    ]
}
