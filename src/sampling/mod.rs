//! Deterministic, seedable sampling, the ground floor every stage draws from: a
//! counter-based random generator keyed by (seed, patch, …) ([`rng`]), so every sample
//! depends only on its key and never on thread scheduling; quadrature rules on the triangle
//! ([`quadrature`]); and the sampling rules (this file): stratified points on triangles,
//! cosine-weighted directions (Malley), points of a triangle by solid angle (Arvo), the
//! kernel-weighted points of an emitter above a receiver's horizon, and systematic draws over
//! weights (many-light sampling).

use glam::DVec3;

use crate::geometry::clip_above;

pub mod quadrature;
pub mod rng;

pub use quadrature::{gauss_rule, lattice_barycentrics};
pub use rng::{mix64, Rng};

/// `n` stratified points on a triangle, as barycentric coordinates (weights of its corners a,
/// b, c), written to `out`.
///
/// Latin-hypercube ("N-rooks") stratification of the unit square — each of the n rows and n
/// columns holds one jittered sample, for any n — mapped to the triangle by the area-preserving
/// map p = (1 − √u) a + √u (1 − v) b + √u v c (Shirley, "Nonuniform random point sets via
/// warping", Graphics Gems III, 1992), so strata of equal area stay equal in area.
pub fn stratified_triangle_barycentrics(n: usize, rng: &mut Rng, out: &mut Vec<[f64; 3]>) {
    let perm = permutation(n, rng);
    for (k, &pk) in perm.iter().enumerate() {
        let u = (k as f64 + rng.next_f64()) / n as f64;
        let v = (pk as f64 + rng.next_f64()) / n as f64;
        out.push(triangle_barycentrics(u, v));
    }
}

/// A uniformly random permutation of 0..n (Fisher–Yates, n − 1 draws of `rng`).
pub fn permutation(n: usize, rng: &mut Rng) -> Vec<usize> {
    let mut p: Vec<usize> = (0..n).collect();
    for k in (1..n).rev() {
        p.swap(k, rng.below(k + 1));
    }
    p
}

/// Barycentrics of the point of a triangle at (u, v) ∈ [0, 1]² by the area-preserving map
/// (1 − √u, √u (1 − v), √u v) (Shirley 1992): uniform (u, v) give points uniform by area.
pub fn triangle_barycentrics(u: f64, v: f64) -> [f64; 3] {
    let su = u.sqrt();
    [1.0 - su, su * (1.0 - v), su * v]
}

/// A point uniform by area in the triangle `corners`, from two draws of `rng` (the unit
/// square folded onto the triangle along its diagonal).
pub fn point_in_triangle(corners: [DVec3; 3], rng: &mut Rng) -> DVec3 {
    let [a, b, c] = corners;
    let (u, v) = (rng.next_f64(), rng.next_f64());
    let (u, v) = if u + v > 1.0 {
        (1.0 - u, 1.0 - v)
    } else {
        (u, v)
    };
    a + u * (b - a) + v * (c - a)
}

/// Strata by area over a list of triangles: the p-th of `count` points lies in the triangle
/// whose share of the running total of the areas holds (p + ξ) / count. Ask for p in
/// increasing order ([`ByArea::pick`]); each pick draws one number.
pub struct ByArea<'a> {
    areas: &'a [f64],
    total: f64,
    count: usize,
    cum: f64,
    k: usize,
}

impl<'a> ByArea<'a> {
    /// Strata for `count` points over triangles of `areas` (≥ 0, not all 0).
    pub fn new(areas: &'a [f64], count: usize) -> ByArea<'a> {
        ByArea {
            areas,
            total: areas.iter().sum(),
            count,
            cum: 0.0,
            k: 0,
        }
    }

    /// The position in `areas` of the triangle of stratum `p`.
    pub fn pick(&mut self, p: usize, rng: &mut Rng) -> usize {
        let target = (p as f64 + rng.next_f64()) / self.count as f64 * self.total;
        while self.k + 1 < self.areas.len() && self.cum + self.areas[self.k] < target {
            self.cum += self.areas[self.k];
            self.k += 1;
        }
        self.k
    }
}

/// The cosine-weighted direction for (s, t) ∈ [0, 1)² about the unit normal `n` with the
/// tangents `tangent`, `bitangent` (Malley's method: (s, t) mapped uniformly onto the unit
/// disk by the polar map, then lifted onto the hemisphere, which gives density cosθ/π).
pub fn malley(s: f64, t: f64, tangent: DVec3, bitangent: DVec3, n: DVec3) -> DVec3 {
    let r = s.sqrt();
    let phi = 2.0 * std::f64::consts::PI * t;
    r * phi.cos() * tangent + r * phi.sin() * bitangent + (1.0 - s).max(0.0).sqrt() * n
}

/// The point of triangle `corners` with barycentrics `b` when the triangle lies wholly above
/// the horizon of the point `x` (unit normal `n`); else `b` mapped to a uniform point of the
/// part above it (the clipped polygon fanned into triangles, one chosen ∝ area with a draw of
/// `rng`). `None` when nothing of the triangle is above. So rays from `x` aim only at the part
/// of a source that `x` can see at all, the part its exact form factor
/// ([`crate::geometry::kernel::point_to_polygon`]) integrates.
pub fn point_above(
    corners: &[DVec3; 3],
    x: DVec3,
    n: DVec3,
    b: [f64; 3],
    rng: &mut Rng,
) -> Option<DVec3> {
    if corners.iter().all(|&v| n.dot(v - x) >= 0.0) {
        return Some(b[0] * corners[0] + b[1] * corners[1] + b[2] * corners[2]);
    }
    let mut clipped = [DVec3::ZERO; 8];
    let m = clip_above(n, &corners.map(|v| v - x), &mut clipped);
    if m < 3 {
        return None;
    }
    let mut area = [0.0; 8];
    for i in 1..m - 1 {
        area[i] = 0.5
            * (clipped[i] - clipped[0])
                .cross(clipped[i + 1] - clipped[0])
                .length();
    }
    let total: f64 = area.iter().sum();
    if total <= 0.0 {
        return None;
    }
    let (i, _) = pick_fan(&area, m, total, rng.next_f64());
    Some(x + b[0] * clipped[0] + b[1] * clipped[i] + b[2] * clipped[i + 1])
}

/// The fan triangle (p₀, p_j, p_{j+1}), j in 1..m − 1, of an m-gon that `u` ∈ [0, 1] falls in
/// when each takes `weight[j]` of `total` = Σ weight, and where u falls within it, in [0, 1].
fn pick_fan(weight: &[f64; 8], m: usize, total: f64, u: f64) -> (usize, f64) {
    let mut rest = u * total;
    for (j, &w) in weight.iter().enumerate().take(m - 1).skip(1) {
        if rest < w || j == m - 2 {
            return (j, (rest / w).clamp(0.0, 1.0));
        }
        rest -= w;
    }
    (m - 2, 1.0)
}

/// A point y of the part of triangle `corners` above the horizon of the point `x` (unit normal
/// `n`), drawn uniformly by the solid angle it subtends at x (the clipped polygon fanned into
/// triangles from x's view, one chosen ∝ its solid angle by `u`, then Arvo's sampling of that
/// spherical triangle with the rest of `u` and `v`: J. Arvo, "Stratified sampling of spherical
/// triangles", SIGGRAPH 1995), with that total solid angle Ω in steradians. Stratifying `u`
/// stratifies the points. The kernel G = cosθ_x cosθ_y / r² over a large or near source varies
/// by orders of magnitude, and this density follows all of it but the cosθ_x: cosθ_x · Ω / (π F)
/// (F the exact point-to-polygon form factor of the same part) is a sample's weight of mean 1.
/// `None` when nothing is above the horizon or the solid angle is too small to sample
/// robustly (under 10⁻⁹ sr: the source is then far against its size, and a uniform point by
/// area, [`point_above`], does as well).
pub fn point_by_solid_angle(
    corners: &[DVec3; 3],
    x: DVec3,
    n: DVec3,
    u: f64,
    v: f64,
) -> Option<(DVec3, f64)> {
    let mut clipped = [DVec3::ZERO; 8];
    let m = clip_above(n, &corners.map(|c| c - x), &mut clipped);
    if m < 3 {
        return None;
    }
    let mut dirs = [DVec3::ZERO; 8];
    for (d, c) in dirs.iter_mut().zip(&clipped[..m]) {
        *d = c.normalize_or_zero();
        if *d == DVec3::ZERO {
            return None;
        }
    }
    let mut omega = [0.0; 8];
    for i in 1..m - 1 {
        omega[i] = spherical_triangle_area(dirs[0], dirs[i], dirs[i + 1]);
    }
    let total: f64 = omega.iter().sum();
    if total.is_nan() || total <= MIN_SAMPLED_SOLID_ANGLE {
        return None;
    }
    let (i, rest) = pick_fan(&omega, m, total, u.clamp(0.0, 1.0));
    let dir = arvo(dirs[0], dirs[i], dirs[i + 1], rest, v)?;
    // Where the direction meets the source's plane (every point of the fan triangle is on it).
    let (a, b, c) = (clipped[0], clipped[i], clipped[i + 1]);
    let plane = (b - a).cross(c - a);
    let t = a.dot(plane) / dir.dot(plane);
    (t.is_finite() && t > 0.0).then(|| (x + t * dir, total))
}

/// Below this solid angle (sr) [`point_by_solid_angle`] declines: Arvo's trigonometry loses
/// its precision on spherical triangles this thin.
const MIN_SAMPLED_SOLID_ANGLE: f64 = 1e-9;

/// Solid angle of the spherical triangle with unit corners a, b, c, sr (Van Oosterom &
/// Strackee, IEEE Trans. Biomed. Eng. 1983).
fn spherical_triangle_area(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let num = a.dot(b.cross(c)).abs();
    let den = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
    2.0 * num.atan2(den)
}

/// The angle between unit vectors, robust near 0 and π.
fn angle_between(a: DVec3, b: DVec3) -> f64 {
    2.0 * (a - b).length().atan2((a + b).length())
}

/// A direction uniform by solid angle over the spherical triangle with unit corners a, b, c,
/// from (u, v) ∈ [0, 1)² (Arvo 1995, §2: u picks the sub-triangle of area u·Ω through a, v the
/// point along the arc from b). `None` for a degenerate triangle.
fn arvo(a: DVec3, b: DVec3, c: DVec3, u: f64, v: f64) -> Option<DVec3> {
    let (n_ab, n_bc, n_ca) = (
        a.cross(b).try_normalize()?,
        b.cross(c).try_normalize()?,
        c.cross(a).try_normalize()?,
    );
    // The spherical triangle's angles at a, b and c.
    let alpha = angle_between(n_ab, -n_ca);
    let beta = angle_between(n_bc, -n_ab);
    let gamma = angle_between(n_ca, -n_bc);
    let area = alpha + beta + gamma - std::f64::consts::PI;
    if area.is_nan() || area <= 0.0 {
        return None;
    }
    let sub = u * area;
    let (s, t) = (sub - alpha).sin_cos();
    let (sin_a, cos_a) = alpha.sin_cos();
    let cos_c = a.dot(b);
    let uu = t - cos_a;
    let vv = s + sin_a * cos_c;
    let q = (((vv * t - uu * s) * cos_a - vv) / ((vv * s + uu * t) * sin_a)).clamp(-1.0, 1.0);
    if !q.is_finite() {
        return None;
    }
    let c_hat = q * a + (1.0 - q * q).max(0.0).sqrt() * (c - c.dot(a) * a).try_normalize()?;
    let z = (1.0 - v * (1.0 - c_hat.dot(b))).clamp(-1.0, 1.0);
    let along = (c_hat - c_hat.dot(b) * b)
        .try_normalize()
        .unwrap_or(DVec3::ZERO);
    (z * b + (1.0 - z * z).max(0.0).sqrt() * along).try_normalize()
}

/// `count` stratified points y of the part of the triangle `corners` (unit front normal
/// `normal`) above the horizon of the point `x` (unit normal `n`), each passed to `visit` with
/// its point-pair kernel G = cosθ_x cosθ_y / r² ([`point_above`]; points where G = 0 are left
/// out). Σ G V / Σ G over them, V the visibility of the segment x–y, is the visible share of
/// the form factor from x to the triangle: what shadow rays to an emitter estimate (the final
/// gather's, [`crate::gather`], and the hierarchy's elements', [`crate::hierarchical::direct`]).
/// `scratch` holds the barycentrics between calls.
#[allow(clippy::too_many_arguments)]
pub fn kernel_samples(
    corners: &[DVec3; 3],
    normal: DVec3,
    x: DVec3,
    n: DVec3,
    count: usize,
    rng: &mut Rng,
    scratch: &mut Vec<[f64; 3]>,
    mut visit: impl FnMut(DVec3, f64),
) {
    scratch.clear();
    stratified_triangle_barycentrics(count, rng, scratch);
    for &b in scratch.iter() {
        let Some(y) = point_above(corners, x, n, b, rng) else {
            continue;
        };
        let d = y - x;
        let r2 = d.length_squared();
        let g = n.dot(d).max(0.0) * (-normal.dot(d)).max(0.0) / (r2 * r2);
        if g > 0.0 {
            visit(y, g);
        }
    }
}

/// Systematic sampling (Kitagawa, "Monte Carlo filter and smoother for non-Gaussian nonlinear
/// state space models", 1996): `n` draws at the even steps (j + `offset`) / n, j = 0 … n − 1,
/// of the cumulative weights `cdf` (non-decreasing, its last value the total, > 0; `offset`
/// uniform in [0, 1)). Yields each draw's position in `cdf` and that position's probability
/// (its weight over the total), in order: a position of probability p is drawn ⌊n p⌋ or
/// ⌈n p⌉ times, its draws in a row, and every position with p ≥ 1/n at least once.
pub fn systematic(cdf: &[f64], n: usize, offset: f64) -> impl Iterator<Item = (usize, f64)> + '_ {
    let total = cdf.last().copied().unwrap_or(0.0);
    (0..if total > 0.0 { n } else { 0 }).map(move |j| {
        let u = (j as f64 + offset) / n as f64 * total;
        let at = cdf.partition_point(|&c| c <= u).min(cdf.len() - 1);
        let below = if at == 0 { 0.0 } else { cdf[at - 1] };
        (at, (cdf[at] - below) / total)
    })
}

#[cfg(test)]
mod tests {

    #[test]
    fn systematic_draws_give_each_weight_its_share_of_the_draws() {
        // Weights 1, 0, 2.5, 0.5, 4 (probabilities 0.125, 0, 0.3125, 0.0625, 0.5) and 16
        // draws: each position is drawn ⌊16 p⌋ or ⌈16 p⌉ times, in order, never one of
        // weight 0, for any offset.
        let cdf = [1.0, 1.0, 3.5, 4.0, 8.0];
        let p: [f64; 5] = [0.125, 0.0, 0.3125, 0.0625, 0.5];
        for offset in [0.0, 0.3, 0.999] {
            let draws: Vec<(usize, f64)> = systematic(&cdf, 16, offset).collect();
            assert_eq!(draws.len(), 16);
            assert!(draws.windows(2).all(|w| w[0].0 <= w[1].0), "in order");
            for (at, &pk) in p.iter().enumerate() {
                let count = draws.iter().filter(|d| d.0 == at).count() as f64;
                assert!(
                    count == (16.0 * pk).floor() || count == (16.0 * pk).ceil(),
                    "offset {offset}: position {at} drawn {count} times for p {pk}"
                );
                assert!(draws.iter().filter(|d| d.0 == at).all(|d| d.1 == pk));
            }
        }
        assert_eq!(systematic(&[], 4, 0.5).count(), 0);
        assert_eq!(systematic(&[0.0, 0.0], 4, 0.5).count(), 0);
    }
    use super::*;
    use glam::DVec3;

    /// Stratified points on the triangle (0, X, Y).
    fn points(n: usize, key: &[u64]) -> Vec<DVec3> {
        let mut w = Vec::new();
        stratified_triangle_barycentrics(n, &mut Rng::new(key), &mut w);
        w.iter()
            .map(|w| w[1] * DVec3::X + w[2] * DVec3::Y)
            .collect()
    }

    #[test]
    fn solid_angle_points_weighted_by_the_cosine_give_the_exact_form_factor() {
        // Ω · mean(cosθ_x) / π over points uniform in solid angle is the form factor; checked
        // against Lambert's contour integral for a near large triangle cut by the horizon,
        // a far small one, and one seen at a grazing angle. 20,000 stratified points: the
        // estimate's relative standard error is under 0.5 %, so 2 % is four of them.
        use crate::geometry::kernel::point_to_polygon;
        let cases = [
            (
                [
                    DVec3::new(-5.0, -5.0, 0.0),
                    DVec3::new(20.0, -5.0, 0.0),
                    DVec3::new(0.0, 20.0, 0.0),
                ],
                DVec3::new(0.3, 0.2, 0.1),
                DVec3::X,
            ),
            (
                [
                    DVec3::new(5.0, 0.0, 3.0),
                    DVec3::new(5.0, 0.1, 3.0),
                    DVec3::new(5.0, 0.0, 3.1),
                ],
                DVec3::ZERO,
                DVec3::new(1.0, 0.0, 1.0).normalize(),
            ),
            (
                [
                    DVec3::new(0.0, 0.0, 0.0),
                    DVec3::new(1.0, 0.0, 0.0),
                    DVec3::new(0.0, 1.0, 0.0),
                ],
                DVec3::new(0.2, 0.2, 0.05),
                DVec3::new(1.0, 0.0, -0.2).normalize(),
            ),
        ];
        for (k, (corners, x, n)) in cases.into_iter().enumerate() {
            let exact = point_to_polygon(x, n, &corners);
            let mut rng = Rng::new(&[k as u64]);
            let count = 20_000;
            let (mut sum, mut omega) = (0.0, 0.0);
            for i in 0..count {
                let u = (i as f64 + rng.next_f64()) / count as f64;
                let (y, w) = point_by_solid_angle(&corners, x, n, u, rng.next_f64())
                    .expect("visible and not tiny");
                let plane = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
                assert!(
                    (y - corners[0]).dot(plane).abs() < 1e-9 * plane.length(),
                    "on the plane"
                );
                sum += n.dot((y - x).normalize());
                omega = w;
            }
            let estimate = omega * sum / count as f64 / std::f64::consts::PI;
            assert!(
                (estimate / exact - 1.0).abs() < 0.02,
                "case {k}: {estimate} against {exact}"
            );
        }
    }

    #[test]
    fn points_lie_inside_and_are_deterministic() {
        let a = points(16, &[7, 3]);
        assert_eq!(a, points(16, &[7, 3]));
        for p in &a {
            assert!(p.x > 0.0 && p.y > 0.0 && p.x + p.y < 1.0, "{p}");
        }
        // The mean of many stratified points converges to the centroid (1/3, 1/3).
        let many = points(10_000, &[1]);
        let mean = many.iter().sum::<DVec3>() / many.len() as f64;
        // Stratified error ≪ the 1/√n = 1e-2 of independent samples.
        assert!(
            (mean - DVec3::new(1.0 / 3.0, 1.0 / 3.0, 0.0)).length() < 2e-3,
            "{mean}"
        );
    }
}
