//! The integrands of the form factor: the point-to-point kernel G of the area formulation and
//! the exact point-to-polygon form factor (Lambert's contour integral). Pure geometry, no rays.

use glam::DVec3;
use std::f64::consts::PI;

/// Point-to-point kernel of the area formulation, G(p, q) = cosθp cosθq / (π r²), in m⁻²
/// (scene units⁻²). Zero when either point is behind the other's plane (one-sided surfaces).
///
/// F_ij = (1/A_i) ∫_Ai ∫_Aj G V dA_j dA_i (Cohen & Wallace, *Radiosity and Realistic Image
/// Synthesis*, eq. 4.12).
#[inline]
pub fn point_to_point(p: DVec3, np: DVec3, q: DVec3, nq: DVec3) -> f64 {
    let d = q - p;
    let r2 = d.length_squared();
    let cp = np.dot(d);
    let cq = -nq.dot(d);
    if cp <= 0.0 || cq <= 0.0 || r2 == 0.0 {
        return 0.0;
    }
    // cosθp cosθq / (π r²) = (np·d)(−nq·d) / (π r⁴)
    cp * cq / (PI * r2 * r2)
}

/// Exact form factor from a differential area at `p` with unit normal `np` to the polygon
/// `poly` (planar, convex, any vertex order), with no occlusion:
///
/// F_dA→A = (1 / 2π) Σ_k γ_k · n_p · (R_k × R_{k+1}) / |R_k × R_{k+1}|,
///
/// where R_k = v_k − p and γ_k is the angle between R_k and R_{k+1} (Lambert 1760; Baum,
/// Rushmeier & Winget, "Improving radiosity solutions through the use of analytically
/// determined form-factors", SIGGRAPH 1989, eq. 4; Cohen & Wallace eq. 4.19). The polygon is
/// first clipped to the half-space above p's tangent plane, because the contour formula
/// assumes the whole polygon is visible from p's hemisphere. Dimensionless, in [0, 1].
///
/// The polygon's own facing is the caller's business (the caller checks that p lies in front
/// of it); this function integrates the projected solid angle regardless of orientation.
pub fn point_to_polygon(p: DVec3, np: DVec3, poly: &[DVec3]) -> f64 {
    let mut clipped = [DVec3::ZERO; 8];
    let m = clip_above(p, np, poly, &mut clipped);
    if m < 3 {
        return 0.0;
    }
    let mut sum = 0.0;
    for k in 0..m {
        let a = clipped[k] - p;
        let b = clipped[(k + 1) % m] - p;
        let c = a.cross(b);
        let len = c.length();
        if len == 0.0 {
            continue;
        }
        // γ via atan2(|a×b|, a·b): accurate for small and near-π angles, unlike acos.
        let gamma = len.atan2(a.dot(b));
        sum += gamma * np.dot(c) / len;
    }
    (sum.abs() / (2.0 * PI)).min(1.0)
}

/// Sutherland–Hodgman clip of a convex polygon (≤ 4 vertices in, ≤ 8 out) to the closed
/// half-space np·(x − p) ≥ 0. Returns the number of vertices written to `out`.
fn clip_above(p: DVec3, np: DVec3, poly: &[DVec3], out: &mut [DVec3; 8]) -> usize {
    let n = poly.len();
    let dist: [f64; 4] = std::array::from_fn(|k| if k < n { np.dot(poly[k] - p) } else { 0.0 });
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

#[cfg(test)]
mod tests {
    use super::*;

    fn square(z: f64, half: f64) -> [DVec3; 4] {
        [
            DVec3::new(-half, -half, z),
            DVec3::new(half, -half, z),
            DVec3::new(half, half, z),
            DVec3::new(-half, half, z),
        ]
    }

    #[test]
    fn point_to_disk_like_square_matches_closed_form() {
        // Differential area to a parallel coaxial square of side 2a at height h (Howell
        // catalog B-? / Cohen & Wallace table): F = (2/π)[ A/√(1+A²) · atan(A/√(1+A²)) ]·2
        // with A = a/h; written as 4 × the corner-rectangle formula
        // F_corner(X, Y) = (1/2π)[X/√(1+X²) atan(Y/√(1+X²)) + Y/√(1+Y²) atan(X/√(1+Y²))].
        let (a, h) = (0.7f64, 1.3f64);
        let (x, y): (f64, f64) = (a / h, a / h);
        let corner = (x / (1.0 + x * x).sqrt() * (y / (1.0 + x * x).sqrt()).atan()
            + y / (1.0 + y * y).sqrt() * (x / (1.0 + y * y).sqrt()).atan())
            / (2.0 * PI);
        let got = point_to_polygon(DVec3::ZERO, DVec3::Z, &square(h, a));
        assert!(
            (got - 4.0 * corner).abs() < 1e-12,
            "{got} vs {}",
            4.0 * corner
        );
        // Orientation of the polygon does not matter.
        let mut rev = square(h, a);
        rev.reverse();
        assert!((point_to_polygon(DVec3::ZERO, DVec3::Z, &rev) - got).abs() < 1e-15);
    }

    #[test]
    fn clipping_a_polygon_straddling_the_horizon() {
        // A huge square through p's tangent plane: half of it is above. Its form factor is
        // that of the half above, which for a wall of infinite extent is 1/2.
        let wall = [
            DVec3::new(1e-3, -1e6, -1e6),
            DVec3::new(1e-3, 1e6, -1e6),
            DVec3::new(1e-3, 1e6, 1e6),
            DVec3::new(1e-3, -1e6, 1e6),
        ];
        let got = point_to_polygon(DVec3::ZERO, DVec3::Z, &wall);
        assert!((got - 0.5).abs() < 1e-6, "{got}");
        // An infinite plane parallel above: 1.
        let got = point_to_polygon(DVec3::ZERO, DVec3::Z, &square(1.0, 1e7));
        assert!((got - 1.0).abs() < 1e-6, "{got}");
        // Entirely below: 0.
        assert_eq!(
            point_to_polygon(DVec3::ZERO, DVec3::Z, &square(-1.0, 1.0)),
            0.0
        );
    }

    #[test]
    fn kernel_matches_far_field_of_contour() {
        // Far away, F_dA→A ≈ A · G at the centre (relative error O(A/r²)).
        let q = DVec3::new(0.0, 0.0, 50.0);
        let g = point_to_point(DVec3::ZERO, DVec3::Z, q, -DVec3::Z);
        let exact = point_to_polygon(DVec3::ZERO, DVec3::Z, &square(50.0, 0.5));
        assert!((g * 1.0 - exact).abs() / exact < 1e-3, "{g} {exact}");
        assert_eq!(point_to_point(DVec3::ZERO, DVec3::Z, q, DVec3::Z), 0.0);
    }
}
