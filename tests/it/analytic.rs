//! Every `radiosity verify` case, per solver and per estimator. The tolerances are those of
//! the verify suite itself (each justified where the case is defined in src/verify.rs).

use radiosity::form_factor::{self, Estimator};
use radiosity::solve::Method;
use radiosity::verify::{self, Case};

fn settings(estimator: Estimator, solver: Method) -> verify::Settings {
    verify::Settings {
        form_factors: form_factor::Settings {
            estimator,
            samples: 3,
            seed: 1,
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
    for estimator in [Estimator::Contour, Estimator::Area] {
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
    for estimator in [Estimator::Contour, Estimator::Area] {
        for case in verify::plates(&settings(estimator, Method::Neumann)).unwrap() {
            check(case);
        }
    }
}
