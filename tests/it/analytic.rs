//! Every `radiosity verify` case, per solver and per estimator. The tolerances are those of
//! the verify suite itself (each justified where the case is defined in src/verify.rs).

use radiosity::form_factor::{self, Estimator};
use radiosity::solve::Method;
use radiosity::verify::{self, Case};

fn settings(estimator: Estimator, solver: Method) -> verify::Settings {
    verify::Settings {
        form_factors: form_factor::Settings {
            estimator,
            ..form_factor::Settings::default()
        },
        solver,
    }
}

#[track_caller]
fn check(case: Case) {
    assert!(
        case.pass,
        "{}: expected {}, got {}, relative error {:.3e} > tolerance {:.1e}",
        case.name, case.expected, case.got, case.relative_error, case.tolerance
    );
}

#[test]
fn integrating_sphere_one_bounce() {
    for estimator in [Estimator::Contour, Estimator::Area, Estimator::Hemisphere] {
        check(verify::integrating_sphere(&settings(estimator, Method::Neumann), Some(1)).unwrap());
    }
}

#[test]
fn integrating_sphere_all_bounces_every_solver() {
    for solver in [Method::Jacobi, Method::GaussSeidel] {
        check(verify::integrating_sphere(&settings(Estimator::Contour, solver), None).unwrap());
    }
    // The Neumann series with enough bounces: ρ^N = 0.5^40 ≈ 1e-12 left out.
    check(
        verify::integrating_sphere(&settings(Estimator::Contour, Method::Neumann), Some(40))
            .unwrap(),
    );
}

#[test]
fn furnace_every_solver() {
    for solver in [Method::Jacobi, Method::GaussSeidel] {
        check(verify::furnace(&settings(Estimator::Contour, solver)).unwrap());
    }
}

#[test]
fn howell_plates_every_estimator() {
    for estimator in [Estimator::Contour, Estimator::Area, Estimator::Hemisphere] {
        for case in verify::plates(&settings(estimator, Method::Neumann)).unwrap() {
            check(case);
        }
    }
}

#[test]
fn furnace_at_high_reflectance_with_hemisphere_shooting() {
    // Issue target: ρ = 0.9, every patch within 1e-3 of Le/(1 − ρ). Hemisphere rows sum to 1
    // up to f32 storage (≲ 1e-6), amplified by ρ/(1 − ρ) = 9: expected error ≲ 1e-5.
    use radiosity::{reference, scenes};
    let scene = scenes::furnace_room(0.9, 1.0).unwrap();
    let mut s = crate::support::settings(0.2, Estimator::Hemisphere, 1, Method::GaussSeidel, 1);
    s.form_factors.rays = 256;
    let out = crate::support::run(&scene, &s);
    let expected = reference::furnace_radiance(0.9, 1.0);
    for (i, l) in out.solution.radiance.iter().enumerate() {
        crate::support::assert_rel(&format!("patch {i}"), l[0], expected, 1e-3);
    }
}

#[test]
fn plates_match_howell_to_1e_3_with_the_contour_estimator() {
    // Issue target: mean receiver radiance within 1e-3 of ρ·F·Le. The contour integrand is
    // exact per point and the Gauss rule integrates it to ~1e-8 (see verify::plates).
    use radiosity::{reference, scenes};
    let s = crate::support::settings(0.25, Estimator::Contour, 3, Method::Neumann, 1);
    for (scene, f) in [
        (
            scenes::parallel_plates(1.0, 2.0, 0.7, 0.5, 1.0).unwrap(),
            reference::parallel_rectangles(1.0, 2.0, 0.7),
        ),
        (
            scenes::perpendicular_plates(1.0, 0.6, 1.5, 0.5, 1.0).unwrap(),
            reference::perpendicular_rectangles(1.0, 0.6, 1.5),
        ),
    ] {
        let out = crate::support::run(&scene, &s);
        let p = &out.patches;
        let rcv: Vec<usize> = (0..p.len()).filter(|&i| p.material[i] == 1).collect();
        let area: f64 = rcv.iter().map(|&i| p.area[i]).sum();
        let mean = rcv
            .iter()
            .map(|&i| p.area[i] * out.solution.radiance[i][0])
            .sum::<f64>()
            / area;
        crate::support::assert_rel("receiver radiance", mean, 0.5 * f, 1e-3);
    }
}

#[test]
fn closed_scenes_are_exact_with_every_estimator() {
    // The furnace room is closed: hemisphere rows are exact hit counts, and the pair
    // estimators' rows are normalised to 1 once the closure probes find no escape. Left: f32
    // storage of F (6e-8) × 1/(1 − ρ) = 10 and the solver tolerance: 1e-5 is ample.
    use radiosity::{reference, scenes};
    let scene = scenes::furnace_room(0.9, 1.0).unwrap();
    let expected = reference::furnace_radiance(0.9, 1.0);
    for estimator in [Estimator::Contour, Estimator::Area, Estimator::Hemisphere] {
        let mut s = crate::support::settings(0.25, estimator, 3, Method::GaussSeidel, 1);
        s.form_factors.rays = 128;
        let out = crate::support::run(&scene, &s);
        if estimator != Estimator::Hemisphere {
            assert!(out.form_factors.stats.closed_scene, "{estimator:?}");
        }
        for (i, l) in out.solution.radiance.iter().enumerate() {
            crate::support::assert_rel(&format!("{estimator:?} patch {i}"), l[0], expected, 1e-5);
        }
    }
    // Without the normalisation the contour estimator's visibility error shows (≈ 1e-2 at
    // ρ = 0.9): the normalisation is what the assertion above measures.
    let mut s = crate::support::settings(0.25, Estimator::Contour, 3, Method::GaussSeidel, 1);
    s.form_factors.normalise_closed = false;
    let raw = crate::support::run(&scene, &s);
    let worst = raw
        .solution
        .radiance
        .iter()
        .map(|l| (l[0] - expected).abs() / expected)
        .fold(0.0, f64::max);
    assert!(worst > 1e-4, "{worst}");
}
