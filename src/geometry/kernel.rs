//! The integrands of the form factor: the point-to-point kernel G of the area formulation and
//! the exact point-to-polygon form factor (Lambert's contour integral). Pure geometry, no rays.

use glam::DVec3;
use std::f64::consts::PI;

use super::clip::{clip_above, clip_polygon};

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
    // Work with R_k = v_k − p throughout; clip only when some corner is below the horizon.
    let n = poly.len();
    debug_assert!((3..=4).contains(&n));
    let mut r = [DVec3::ZERO; 4];
    let mut below = false;
    for k in 0..n {
        r[k] = poly[k] - p;
        below |= np.dot(r[k]) < 0.0;
    }
    let sum = if below {
        let mut clipped = [DVec3::ZERO; 8];
        let m = clip_above(np, &r[..n], &mut clipped);
        contour_sum(np, &clipped[..m])
    } else {
        contour_sum(np, &r[..n])
    };
    (sum.abs() / (2.0 * PI)).min(1.0)
}

/// [`point_to_polygon`] for a planar convex polygon of any number of corners (the visible
/// pieces of an emitter, [`crate::gather`]): clipped to the half-space above p's tangent plane,
/// then Lambert's contour sum. Dimensionless, in [0, 1]; fewer than 3 corners give 0.
pub fn point_to_convex_polygon(p: DVec3, np: DVec3, poly: &[DVec3]) -> f64 {
    if (3..=4).contains(&poly.len()) {
        return point_to_polygon(p, np, poly);
    }
    let r: Vec<DVec3> = poly.iter().map(|&v| v - p).collect();
    let mut clipped = Vec::with_capacity(r.len() + 1);
    clip_polygon(&r, |v| np.dot(v), &mut clipped);
    (contour_sum(np, &clipped).abs() / (2.0 * PI)).min(1.0)
}

/// Σ_k γ_k n·(R_k × R_{k+1}) / |R_k × R_{k+1}| over the closed polygon `r` (corners relative to
/// the receiving point); fewer than 3 corners give 0.
#[inline]
fn contour_sum(np: DVec3, r: &[DVec3]) -> f64 {
    let m = r.len();
    if m < 3 {
        return 0.0;
    }
    let mut sum = 0.0;
    let mut a = r[m - 1];
    for &b in r {
        let c = a.cross(b);
        let len = c.length();
        if len > 0.0 {
            // γ via atan2(|a×b|, a·b): accurate for small and near-π angles, unlike acos.
            sum += angle(len, a.dot(b)) * np.dot(c) / len;
        }
        a = b;
    }
    sum
}

/// atan2(y, x) for y ≥ 0, in [0, π], to within 5e-12 (absolute) of the correctly rounded
/// value, several times faster than libm's `atan2`, which would otherwise take a large share
/// of the contour estimator's time. Octant reduction to t = min/max ∈ [0, 1], then to
/// |u| ≤ tan(π/8) with atan t = π/4 + atan((t − 1)/(t + 1)), then atan u = u·P(u²) with P of
/// degree 6 fitted to minimise the largest error on [0, tan(π/8)] (iteratively reweighted
/// least squares; max error 4.2e-12). The error is far below the f32 storage of F (6e-8 relative).
#[inline]
pub fn angle(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};
    const TAN_PI_8: f64 = 0.414_213_562_373_095_03;
    const P: [f64; 7] = [
        9.999_999_998_467_06e-1,
        -3.333_332_995_640_025e-1,
        1.999_978_419_877_117e-1,
        -1.427_959_860_346_548_8e-1,
        1.102_115_504_291_284e-1,
        -8.365_991_317_740_744e-2,
        4.545_439_503_578_544e-2,
    ];
    debug_assert!(y >= 0.0);
    let ax = x.abs();
    let (num, den, swap) = if y <= ax {
        (y, ax, false)
    } else {
        (ax, y, true)
    };
    if den == 0.0 {
        return 0.0;
    }
    let t = num / den;
    let (u, base) = if t > TAN_PI_8 {
        ((t - 1.0) / (t + 1.0), FRAC_PI_4)
    } else {
        (t, 0.0)
    };
    let s = u * u;
    let p = P[0] + s * (P[1] + s * (P[2] + s * (P[3] + s * (P[4] + s * (P[5] + s * P[6])))));
    let a = base + u * p;
    let a = if swap { FRAC_PI_2 - a } else { a };
    if x < 0.0 {
        PI - a
    } else {
        a
    }
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

    /// The contour integral written out directly (libm atan2, clipping by brute force), as the
    /// oracle of the optimised [`point_to_polygon`].
    fn contour_reference(p: DVec3, np: DVec3, poly: &[DVec3]) -> f64 {
        let n = poly.len();
        let mut pts = Vec::new();
        for k in 0..n {
            let (a, b) = (poly[k], poly[(k + 1) % n]);
            let (da, db) = (np.dot(a - p), np.dot(b - p));
            if da >= 0.0 {
                pts.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                pts.push(a + da / (da - db) * (b - a));
            }
        }
        let m = pts.len();
        let mut sum = 0.0;
        for k in 0..m {
            let (a, b) = (pts[k] - p, pts[(k + 1) % m] - p);
            let c = a.cross(b);
            if c.length() > 0.0 {
                sum += c.length().atan2(a.dot(b)) * np.dot(c) / c.length();
            }
        }
        if m < 3 {
            0.0
        } else {
            (sum.abs() / (2.0 * PI)).min(1.0)
        }
    }

    #[test]
    fn point_to_polygon_matches_the_direct_formula() {
        let mut rng = crate::sampling::Rng::new(&[5]);
        let v = |r: &mut crate::sampling::Rng| {
            DVec3::new(r.next_f64(), r.next_f64(), r.next_f64()) * 2.0 - DVec3::ONE
        };
        for k in 0..20_000 {
            let p = v(&mut rng) * 0.5;
            let np = v(&mut rng).normalize();
            let corners = if k % 2 == 0 { 3 } else { 4 };
            // Planar quads: a parallelogram.
            let (a, b, c) = (v(&mut rng), v(&mut rng), v(&mut rng));
            let poly: Vec<DVec3> = if corners == 3 {
                vec![a, b, c]
            } else {
                vec![a, b, c, c + a - b]
            };
            let (got, want) = (
                point_to_polygon(p, np, &poly),
                contour_reference(p, np, &poly),
            );
            assert!((got - want).abs() < 1e-11, "{k}: {got} vs {want}");
        }
    }

    #[test]
    fn fast_angle_matches_atan2() {
        // Every octant, tiny and huge ratios, zeros and the reduction boundaries.
        let mut worst: f64 = 0.0;
        let mut rng = crate::sampling::Rng::new(&[11]);
        for k in 0..200_000 {
            let (y, x) = if k < 8 {
                [
                    (0.0, 1.0),
                    (0.0, -1.0),
                    (1.0, 0.0),
                    (0.0, 0.0),
                    (1.0, 1.0),
                    (1.0, -1.0),
                    (0.414_213_562_373_095, 1.0),
                    (1e-300, -1.0),
                ][k]
            } else {
                let e = |r: &mut crate::sampling::Rng| 10f64.powf(12.0 * r.next_f64() - 6.0);
                let y = e(&mut rng) * rng.next_f64();
                let x = e(&mut rng) * (2.0 * rng.next_f64() - 1.0);
                (y, x)
            };
            worst = worst.max((angle(y, x) - y.atan2(x)).abs());
        }
        assert!(worst < 5e-12, "{worst:e}");
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
