//! Clipping convex polygons to a half-space (Sutherland & Hodgman, "Reentrant polygon
//! clipping", CACM 1974): the part of an emitter above a receiver's horizon, a shadow cut from
//! an emitter. Two forms of one algorithm: [`clip_polygon`] for any number of corners, in
//! space or in a plane, and [`clip_above`], the contour kernel's fixed-size form for a patch
//! (at most 4 corners in, 8 out, no allocation) on its hot path. They start their walk at
//! different corners, so their outputs list the same polygon from different first corners.

use glam::DVec3;

/// Sutherland–Hodgman: the part of the convex polygon `poly` (in space or in a plane) where
/// `dist ≥ 0`, into `out` (cleared first; empty or fewer than 3 corners when nothing of area
/// is left).
pub fn clip_polygon<P>(poly: &[P], dist: impl Fn(P) -> f64, out: &mut Vec<P>)
where
    P: Copy
        + std::ops::Add<Output = P>
        + std::ops::Sub<Output = P>
        + std::ops::Mul<f64, Output = P>,
{
    out.clear();
    let n = poly.len();
    if n == 0 {
        return;
    }
    let mut a = poly[n - 1];
    let mut da = dist(a);
    for &b in poly {
        let db = dist(b);
        if (da >= 0.0) != (db >= 0.0) {
            let t = da / (da - db);
            out.push(a + (b - a) * t);
        }
        if db >= 0.0 {
            out.push(b);
        }
        a = b;
        da = db;
    }
}

/// Sutherland–Hodgman clip of a convex polygon (≤ 4 corners relative to the receiving point
/// in, ≤ 8 out) to the closed half-space np·x ≥ 0. Returns the number of corners written.
pub fn clip_above(np: DVec3, poly: &[DVec3], out: &mut [DVec3; 8]) -> usize {
    let n = poly.len();
    let dist: [f64; 4] = std::array::from_fn(|k| if k < n { np.dot(poly[k]) } else { 0.0 });
    if dist[..n].iter().all(|&d| d >= 0.0) {
        out[..n].copy_from_slice(poly);
        return n;
    }
    let mut m = 0;
    for k in 0..n {
        let (a, b) = (poly[k], poly[(k + 1) % n]);
        let (da, db) = (dist[k], dist[(k + 1) % n]);
        if da >= 0.0 {
            out[m] = a;
            m += 1;
        }
        if (da >= 0.0) != (db >= 0.0) {
            let t = da / (da - db);
            out[m] = a + t * (b - a);
            m += 1;
        }
    }
    m
}
