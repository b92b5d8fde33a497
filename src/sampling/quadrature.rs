//! Deterministic rules on the triangle: Dunavant's symmetric Gauss rules (the receivers'
//! quadrature of form factors, elements and the gather's patch means) and the lattice of
//! sub-triangle centroids (area fractions, such as the buried part of a patch).

/// Centroids of the n² congruent triangles of the regular n-fold split of a triangle, as
/// barycentric coordinates: n² points of equal weight that cover the triangle evenly (a
/// deterministic estimate of area fractions with error ≤ one sub-triangle per boundary
/// crossing).
pub fn lattice_barycentrics(n: usize) -> Vec<[f64; 3]> {
    let mut out = Vec::with_capacity(n * n);
    let third = 1.0 / (3 * n) as f64;
    for i in 0..n {
        for j in 0..n - i {
            // Upright sub-triangle (i, j), (i+1, j), (i, j+1) in lattice coordinates.
            let (u, v) = ((3 * i + 1) as f64 * third, (3 * j + 1) as f64 * third);
            out.push([1.0 - u - v, u, v]);
            if i + j + 2 <= n {
                // Inverted sub-triangle (i+1, j), (i, j+1), (i+1, j+1).
                let (u, v) = ((3 * i + 2) as f64 * third, (3 * j + 2) as f64 * third);
                out.push([1.0 - u - v, u, v]);
            }
        }
    }
    out
}

/// Symmetric Gauss quadrature rules on the triangle (Dunavant, "High degree efficient
/// symmetrical Gaussian quadrature rules for the triangle", IJNME 21, 1985), for the point
/// counts that have a rule with positive weights: 1 (degree 1), 3 (degree 2), 6 (degree 4),
/// 7 (degree 5), 12 (degree 6). Each entry is (barycentric coordinates, weight); weights sum
/// to 1, so Σ w_k f(x_k) approximates the mean of f over the triangle.
pub fn gauss_rule(n: usize) -> Option<Vec<([f64; 3], f64)>> {
    // Orbits: a centroid, (a, a, 1 − 2a) with its 3 permutations, (a, b, c) with 6.
    fn s3(w: f64) -> Vec<([f64; 3], f64)> {
        vec![([1.0 / 3.0; 3], w)]
    }
    fn s21(a: f64, w: f64) -> Vec<([f64; 3], f64)> {
        let b = 1.0 - 2.0 * a;
        vec![([a, a, b], w), ([a, b, a], w), ([b, a, a], w)]
    }
    fn s111(a: f64, b: f64, w: f64) -> Vec<([f64; 3], f64)> {
        let c = 1.0 - a - b;
        [
            [a, b, c],
            [a, c, b],
            [b, a, c],
            [b, c, a],
            [c, a, b],
            [c, b, a],
        ]
        .into_iter()
        .map(|p| (p, w))
        .collect()
    }
    let rule = match n {
        1 => s3(1.0),
        3 => s21(1.0 / 6.0, 1.0 / 3.0),
        6 => [
            s21(0.445_948_490_915_965, 0.223_381_589_678_011),
            s21(0.091_576_213_509_771, 0.109_951_743_655_322),
        ]
        .concat(),
        7 => [
            s3(0.225),
            s21(0.470_142_064_105_115, 0.132_394_152_788_506),
            s21(0.101_286_507_323_456, 0.125_939_180_544_827),
        ]
        .concat(),
        12 => [
            s21(0.249_286_745_170_910, 0.116_786_275_726_379),
            s21(0.063_089_014_491_502, 0.050_844_906_370_207),
            s111(
                0.053_145_049_844_817,
                0.310_352_451_033_784,
                0.082_851_075_618_374,
            ),
        ]
        .concat(),
        _ => return None,
    };
    Some(rule)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lattice_points_are_the_sub_triangle_centroids() {
        for n in 1..6 {
            let pts = lattice_barycentrics(n);
            assert_eq!(pts.len(), n * n);
            // Inside, and their mean is the centroid (the sub-triangles tile the triangle).
            let mut mean = [0.0; 3];
            for b in &pts {
                assert!(b.iter().all(|&w| w > 0.0) && (b.iter().sum::<f64>() - 1.0).abs() < 1e-12);
                for k in 0..3 {
                    mean[k] += b[k] / pts.len() as f64;
                }
            }
            assert!(
                mean.iter().all(|&m| (m - 1.0 / 3.0).abs() < 1e-12),
                "{n}: {mean:?}"
            );
        }
    }

    #[test]
    fn gauss_rules_integrate_polynomials_of_their_degree() {
        // Mean of x^a y^b over the unit right triangle is 2·a!·b!/(a+b+2)!.
        let fact = |n: u32| (1..=n).map(|k| k as f64).product::<f64>();
        for (n, degree) in [(1, 1), (3, 2), (6, 4), (7, 5), (12, 6)] {
            let rule = gauss_rule(n).unwrap();
            assert_eq!(rule.len(), n);
            assert!((rule.iter().map(|r| r.1).sum::<f64>() - 1.0).abs() < 1e-12);
            for a in 0..=degree {
                for b in 0..=degree - a {
                    let exact = 2.0 * fact(a) * fact(b) / fact(a + b + 2);
                    let got: f64 = rule
                        .iter()
                        .map(|(p, w)| w * p[1].powi(a as i32) * p[2].powi(b as i32))
                        .sum();
                    assert!(
                        (got - exact).abs() < 1e-12,
                        "n={n} x^{a} y^{b}: {got} vs {exact}"
                    );
                }
            }
        }
        assert!(gauss_rule(4).is_none());
    }
}
