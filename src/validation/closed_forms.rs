//! Closed-form references: configuration factors from Howell's catalog (J. R. Howell, *A
//! Catalog of Radiation Heat Transfer Configuration Factors*, 3rd ed.; also Siegel & Howell,
//! *Thermal Radiation Heat Transfer*, appendix C) and the analytic radiance of the integrating
//! sphere and the furnace. Used by `radiosity verify`, the tests and the benchmarks; nothing
//! here casts a ray.

use std::f64::consts::PI;

/// Howell C-11: two identical, parallel, directly opposed rectangles a × b at distance c.
/// Dimensionless. (1 × 1 squares 1 apart: 0.199825.)
pub fn parallel_rectangles(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (x2, y2) = (x * x, y * y);
    let log = (((1.0 + x2) * (1.0 + y2)) / (1.0 + x2 + y2)).sqrt().ln();
    2.0 / (PI * x * y)
        * (log
            + x * (1.0 + y2).sqrt() * (x / (1.0 + y2).sqrt()).atan()
            + y * (1.0 + x2).sqrt() * (y / (1.0 + x2).sqrt()).atan()
            - x * x.atan()
            - y * y.atan())
}

/// Howell B-3: from a differential area to a parallel rectangle a × b at distance c, the
/// area's normal through one corner of the rectangle. Dimensionless. (Under the corner of a
/// unit square 1 away: 0.138532.)
pub fn point_to_parallel_rectangle_corner(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    1.0 / (2.0 * PI) * (x / sx * (y / sx).atan() + y / sy * (x / sy).atan())
}

/// Howell C-14: from rectangle 1 (common edge length `l`, width `w`) to rectangle 2 (same
/// common edge, width `h`), at 90° sharing the edge. Dimensionless. (Unit squares: 0.200044.)
pub fn perpendicular_rectangles(l: f64, w: f64, h: f64) -> f64 {
    let (h, w) = (h / l, w / l);
    let (h2, w2) = (h * h, w * w);
    let a = (1.0 + w2) * (1.0 + h2) / (1.0 + w2 + h2);
    let b = (w2 * (1.0 + w2 + h2) / ((1.0 + w2) * (w2 + h2))).powf(w2);
    let c = (h2 * (1.0 + h2 + w2) / ((1.0 + h2) * (h2 + w2))).powf(h2);
    (w * (1.0 / w).atan() + h * (1.0 / h).atan()
        - (h2 + w2).sqrt() * (1.0 / (h2 + w2).sqrt()).atan()
        + 0.25 * (a * b * c).ln())
        / (PI * w)
}

/// Howell C-41: from a disk of radius r1 to a parallel coaxial disk of radius r2 at distance h.
pub fn coaxial_disks(r1: f64, r2: f64, h: f64) -> f64 {
    let (r1, r2) = (r1 / h, r2 / h);
    let x = 1.0 + (1.0 + r2 * r2) / (r1 * r1);
    0.5 * (x - (x * x - 4.0 * (r2 / r1).powi(2)).sqrt())
}

/// Radiance of a non-emitting wall of an ideal integrating sphere with uniform ρ, where the
/// area-weighted mean emitted radiance over the whole sphere is `mean_le`.
///
/// Every point of a sphere sees every area element with the same form factor dA/A (the
/// sphere's F_ij = A_j / A), so the irradiance is uniform: after one bounce the walls carry
/// ρ·mean(Le), and summing the geometric series of bounces, L = Le + ρ/(1 − ρ)·mean(Le).
pub fn sphere_wall_radiance(rho: f64, mean_le: f64, bounces: Option<u32>) -> f64 {
    match bounces {
        // Σ_{b=1}^{N} ρ^b mean(Le)
        Some(n) => (1..=n).map(|b| rho.powi(b as i32)).sum::<f64>() * mean_le,
        None => rho / (1.0 - rho) * mean_le,
    }
}

/// Radiance everywhere in a closed enclosure of any shape with uniform Le and ρ (the
/// "furnace"): L = Le + ρ L since every row of F sums to 1, so L = Le / (1 − ρ).
pub fn furnace_radiance(rho: f64, le: f64) -> f64 {
    le / (1.0 - rho)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tabulated_values() {
        // Values printed in Howell's catalog and in Siegel & Howell's figures.
        assert!((parallel_rectangles(1.0, 1.0, 1.0) - 0.19982).abs() < 1e-5);
        assert!((parallel_rectangles(2.0, 2.0, 1.0) - 0.41525).abs() < 1e-4);
        assert!((perpendicular_rectangles(1.0, 1.0, 1.0) - 0.20004).abs() < 1e-5);
        // Coaxial unit disks one radius apart: 0.38197 (= (3 − √5)/2).
        assert!((coaxial_disks(1.0, 1.0, 1.0) - 0.381966).abs() < 1e-6);
    }

    #[test]
    fn perpendicular_reciprocity() {
        // A1 F12 = A2 F21 for the common-edge pair.
        let (l, w, h) = (1.3, 0.4, 2.1);
        let f12 = perpendicular_rectangles(l, w, h);
        let f21 = perpendicular_rectangles(l, h, w);
        assert!((l * w * f12 - l * h * f21).abs() < 1e-12);
    }

    #[test]
    fn sphere_series_sums_to_closed_form() {
        let all = sphere_wall_radiance(0.6, 2.0, None);
        let many = sphere_wall_radiance(0.6, 2.0, Some(200));
        assert!((all - many).abs() < 1e-12);
        assert!((sphere_wall_radiance(0.6, 2.0, Some(1)) - 1.2).abs() < 1e-15);
    }
}
