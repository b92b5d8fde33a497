//! Unit tests of the solvers on synthetic systems: a random sparse F with known structure,
//! every method against a dense LU solve (nalgebra), the algebra that ties the methods
//! together (Jacobi's iterates are the Neumann partial sums, a grey system solved in one
//! channel equals the three-channel solve), determinism over thread counts, the singular
//! case refused, and the automatic over-relaxation formula.

use nalgebra::{DMatrix, DVector};
use sprs::{CsMatI, TriMatI};

use super::*;
use crate::form_factor::{FormFactors, Stats};
use crate::sampling::Rng;

/// A random F on `n` patches: each row gathers from about a third of the others, entries
/// positive, row sums `row_sum` (≤ 1), areas in [1, 2]. Seeded, so every run sees the same.
fn random_form_factors(n: usize, row_sum: f64, seed: u64) -> FormFactors {
    let mut rng = Rng::new(&[seed, 0xF0F0]);
    let mut tri = TriMatI::<f32, u32>::new((n, n));
    for i in 0..n {
        let cols: Vec<usize> = (0..n).filter(|&j| j != i && rng.below(3) == 0).collect();
        let weights: Vec<f64> = cols.iter().map(|_| 0.1 + rng.next_f64()).collect();
        let total: f64 = weights.iter().sum();
        for (&j, w) in cols.iter().zip(&weights) {
            tri.add_triplet(i, j, (row_sum * w / total) as f32);
        }
    }
    let matrix: CsMatI<f32, u32> = tri.to_csr();
    FormFactors {
        matrix,
        pair_matrix: None,
        stats: Stats::default(),
        area: (0..n).map(|_| 1.0 + rng.next_f64()).collect(),
        visible_fraction: vec![1.0; n],
        closed_row_tolerance: 0.1,
    }
}

/// ρ in [0.1, 0.8] per channel, Le on a fifth of the patches.
fn random_materials(n: usize, seed: u64) -> (Vec<Rgb>, Vec<Rgb>) {
    let mut rng = Rng::new(&[seed, 0xC0C0]);
    let rho = (0..n)
        .map(|_| std::array::from_fn(|_| 0.1 + 0.7 * rng.next_f64()))
        .collect();
    let le = (0..n)
        .map(|i| {
            if i % 5 == 0 {
                std::array::from_fn(|_| 1.0 + rng.next_f64())
            } else {
                [0.0; 3]
            }
        })
        .collect();
    (rho, le)
}

/// Oracle: (I − diag(ρ)F) L = E per channel by dense LU.
fn dense(system: &System) -> Vec<Rgb> {
    let n = system.len();
    let mut out = vec![[0.0; 3]; n];
    for c in 0..3 {
        let mut a = DMatrix::<f64>::identity(n, n);
        for (i, row) in system.form_factors.matrix.outer_iterator().enumerate() {
            for (j, &f) in row.iter() {
                a[(i, j)] -= system.reflectance[i][c] * f as f64;
            }
        }
        let e = DVector::from_iterator(n, (0..n).map(|i| system.emission[i][c]));
        let x = a.lu().solve(&e).expect("ρ < 1: non-singular");
        for (i, o) in out.iter_mut().enumerate() {
            o[c] = x[i];
        }
    }
    out
}

/// Largest difference relative to the largest value.
fn max_rel_diff(a: &[Rgb], b: &[Rgb]) -> f64 {
    let scale = a.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = a
        .iter()
        .zip(b)
        .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs()))
        .fold(0.0, f64::max);
    diff / scale
}

fn settings(method: Method) -> Settings {
    Settings {
        method,
        tolerance: 1e-12,
        max_iterations: 100_000,
        ..Settings::default()
    }
}

#[test]
fn every_method_matches_the_dense_solve() {
    let ff = random_form_factors(60, 0.9, 1);
    let (rho, le) = random_materials(60, 1);
    let system = System {
        form_factors: &ff,
        reflectance: &rho,
        emission: &le,
    };
    let oracle = dense(&system);
    for method in [Method::Jacobi, Method::GaussSeidel, Method::Southwell] {
        let s = solve(&system, &settings(method)).unwrap();
        assert!(s.converged && !s.grey && s.method == method);
        // Residual 1e-12 and ‖(I − K)⁻¹‖ ≤ 1/(1 − 0.8·0.9) ≈ 3.6: the error is below 1e-11.
        let d = max_rel_diff(&oracle, &s.radiance);
        assert!(d < 1e-10, "{method:?}: {d:.3e}");
    }
    // Neumann with enough bounces: the tail after N terms is ≤ 0.72^(N+1)/(1 − 0.72).
    let mut n = settings(Method::Neumann);
    n.bounces = 120;
    let s = solve(&system, &n).unwrap();
    assert!(max_rel_diff(&oracle, &s.radiance) < 1e-12);
    // CG solves with the symmetric part of A·F, which differs from this random (not
    // reciprocal) F: it must match the dense solve of that symmetrised system instead.
    let sym = FormFactors {
        matrix: crate::form_factor::symmetric_part(&ff.matrix, &ff.area).unwrap(),
        ..ff.clone()
    };
    let sym_system = System {
        form_factors: &sym,
        ..system
    };
    let s = solve(&system, &settings(Method::Cg)).unwrap();
    assert!(s.converged);
    let d = max_rel_diff(&dense(&sym_system), &s.radiance);
    assert!(d < 1e-9, "cg: {d:.3e}");
}

#[test]
fn jacobi_iterates_are_the_neumann_partial_sums() {
    let ff = random_form_factors(40, 0.95, 2);
    let (rho, le) = random_materials(40, 2);
    let system = System {
        form_factors: &ff,
        reflectance: &rho,
        emission: &le,
    };
    for k in [1, 2, 7] {
        let mut j = settings(Method::Jacobi);
        (j.max_iterations, j.tolerance) = (k, 1e-300);
        let jacobi = solve(&system, &j).unwrap();
        assert!(!jacobi.converged);
        assert_eq!(jacobi.iterations, k);
        let mut n = settings(Method::Neumann);
        n.bounces = k;
        let neumann = solve(&system, &n).unwrap();
        // The same sums in another order: rounding only.
        let d = max_rel_diff(&neumann.radiance, &jacobi.radiance);
        assert!(d < 1e-14, "k = {k}: {d:.3e}");
    }
}

#[test]
fn a_grey_system_is_solved_in_one_channel_with_the_same_answer() {
    let ff = random_form_factors(50, 0.9, 3);
    let (rho, le) = random_materials(50, 3);
    let grey_rho: Vec<Rgb> = rho.iter().map(|r| [r[1]; 3]).collect();
    let grey_le: Vec<Rgb> = le.iter().map(|e| [e[0]; 3]).collect();
    let grey = System {
        form_factors: &ff,
        reflectance: &grey_rho,
        emission: &grey_le,
    };
    // The same system with a negligible tint in one channel is solved in three.
    let mut tinted_le = grey_le.clone();
    tinted_le[0][2] *= 1.0 + 1e-15;
    let tinted = System {
        emission: &tinted_le,
        ..grey
    };
    for method in [Method::GaussSeidel, Method::Cg, Method::Southwell] {
        let one = solve(&grey, &settings(method)).unwrap();
        let three = solve(&tinted, &settings(method)).unwrap();
        assert!(one.grey && !three.grey, "{method:?}");
        assert!(one.radiance.iter().all(|l| l[0] == l[1] && l[1] == l[2]));
        let d = max_rel_diff(&three.radiance, &one.radiance);
        assert!(d < 1e-10, "{method:?}: {d:.3e}");
    }
}

#[test]
fn gauss_seidel_gives_the_same_bits_on_one_and_two_threads() {
    let ff = random_form_factors(300, 0.9, 4);
    let (rho, le) = random_materials(300, 4);
    let system = System {
        form_factors: &ff,
        reflectance: &rho,
        emission: &le,
    };
    let on = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| solve(&system, &settings(Method::GaussSeidel)).unwrap())
    };
    let (a, b) = (on(1), on(2));
    assert_eq!(a.iterations, b.iterations);
    assert!(a.radiance == b.radiance, "bitwise equal");
}

#[test]
fn automatic_over_relaxation_follows_young_and_is_capped() {
    // Reciprocal F (A_i F_ij = A_j F_ji, as every estimator gives up to its error): the
    // system scaled by A/ρ is symmetric positive definite, so SOR converges for any ω in
    // (0, 2) (Ostrowski–Reich) and the automatic choice is kept.
    let (rho, le) = random_materials(30, 5);
    // q = max ρ·(row sum): 0.8 · 0.5 gives ω ≈ 1.04; 0.995 · 0.999 would give 1.82 > the cap.
    let bright: Vec<Rgb> = rho.iter().map(|_| [0.995; 3]).collect();
    for (rho, row_sum, expect_cap) in [(&rho, 0.5, false), (&bright, 0.999, true)] {
        let raw = random_form_factors(30, row_sum, 5);
        let ff = FormFactors {
            matrix: crate::form_factor::symmetric_part(&raw.matrix, &raw.area).unwrap(),
            ..raw
        };
        let system = System {
            form_factors: &ff,
            reflectance: rho,
            emission: &le,
        };
        let q = rho
            .iter()
            .zip(ff.row_sums())
            .map(|(r, s)| r.iter().cloned().fold(0.0, f64::max) * s)
            .fold(0.0, f64::max);
        let young = 2.0 / (1.0 + (1.0 - q * q).sqrt());
        let omega = auto_omega(&system);
        if expect_cap {
            assert!(young > MAX_AUTO_OMEGA && omega == MAX_AUTO_OMEGA, "q = {q}");
        } else {
            assert!(
                (omega - young).abs() < 1e-15 && omega < MAX_AUTO_OMEGA,
                "q = {q}"
            );
        }
        let s = solve(&system, &settings(Method::GaussSeidel)).unwrap();
        assert!(s.converged);
        assert_eq!(s.omega, omega);
        let d = max_rel_diff(&dense(&system), &s.radiance);
        assert!(d < 1e-9, "q = {q}: {d:.3e}");
    }
}

#[test]
fn a_closed_enclosure_with_reflectance_one_is_refused_and_nothing_emitted_is_black() {
    // Three patches that see only each other (rows sum to 1) with ρ = 1 in green: singular.
    let enclosure = |extra: &[(usize, usize, f32)]| {
        let mut tri = TriMatI::<f32, u32>::new((4, 4));
        for (i, j) in [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)] {
            tri.add_triplet(i, j, 0.5);
        }
        tri.add_triplet(3, 0, 0.5);
        for &(i, j, f) in extra {
            tri.add_triplet(i, j, f);
        }
        tri.to_csr()
    };
    let ff = FormFactors {
        matrix: enclosure(&[]),
        ..random_form_factors(4, 0.5, 6)
    };
    let rho = vec![[0.5, 1.0, 0.5], [0.5, 1.0, 0.5], [0.5, 1.0, 0.5], [0.5; 3]];
    let le = vec![[0.0; 3], [0.0; 3], [0.0; 3], [1.0; 3]];
    let system = System {
        form_factors: &ff,
        reflectance: &rho,
        emission: &le,
    };
    let e = solve(&system, &settings(Method::GaussSeidel)).unwrap_err();
    assert!(matches!(e, Error::Numerical(_)), "{e:?}");
    assert!(
        e.to_string().contains("green") && e.to_string().contains("3 patches"),
        "{e}"
    );
    // Open the enclosure (patch 2 also gathers from 3, outside the set) and it is solvable.
    let open_ff = FormFactors {
        matrix: enclosure(&[(2, 3, 0.1)]),
        ..ff.clone()
    };
    check_not_singular(&System {
        form_factors: &open_ff,
        ..system
    })
    .unwrap();
    // Nothing emitted: L = 0 at once, for any method (even the singular system).
    let dark = vec![[0.0; 3]; 4];
    let s = solve(
        &System {
            emission: &dark,
            ..system
        },
        &settings(Method::Cg),
    )
    .unwrap();
    assert!(s.converged && s.iterations == 0 && s.radiance == dark);
}

#[test]
fn the_time_left_of_a_sweep_follows_its_residuals() {
    // Jacobi on a system whose residual falls by about ρ·row sum a sweep: from the
    // residuals of sweeps k − 1 and k, the sweeps left to the tolerance are predicted
    // within two of those the solve then took (the ratio of successive residuals settles
    // on the spectral radius within a few sweeps; the first sweeps are left out).
    let ff = random_form_factors(120, 0.8, 17);
    let (rho, le) = random_materials(120, 18);
    let system = System {
        form_factors: &ff,
        reflectance: &rho,
        emission: &le,
    };
    let mut j = settings(Method::Jacobi);
    j.tolerance = 1e-10;
    let s = solve(&system, &j).unwrap();
    let h = &s.residual_history;
    assert!(s.converged && h.len() > 20, "{} sweeps", h.len());
    for k in 5..h.len() - 1 {
        let predicted = sweeps_left(h[k - 1], h[k], j.tolerance).unwrap() as i64;
        let actual = (h.len() - 1 - k) as i64;
        assert!(
            (predicted - actual).abs() <= 2,
            "sweep {k}: {predicted} against {actual}"
        );
    }
    // Nothing is predicted once converged, or where the residual does not fall.
    assert_eq!(sweeps_left(1e-3, 1e-11, 1e-10), None);
    assert_eq!(sweeps_left(1e-3, 2e-3, 1e-10), None);
    assert_eq!(sweeps_left(0.0, 0.0, 1e-10), None);
}
