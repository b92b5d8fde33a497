//! The integration test binary: analytic references first (the verify suite per solver and
//! estimator), then the solvers against a dense LU oracle, form-factor invariants, visibility
//! against brute force on a real scene, and the command line end to end.

mod analytic;
mod camera;
mod cli;
mod form_factors;
mod golden;
mod properties;
mod robust;
mod solvers;
mod stress;
mod support;
mod two_sided;
mod ux;
