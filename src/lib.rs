//! # radiosity
//!
//! A radiosity (finite-element) solver for the diffuse rendering equation. It reads an OBJ/MTL
//! scene (`Kd` = diffuse reflectance ρ, `Ke` = emitted radiance Le in W·sr⁻¹·m⁻²), cuts it into
//! patches, estimates the form factors F_ij by ray casting, solves (I − K)L = E with
//! K = diag(ρ)·F, and bakes the patch radiance into vertex colours written as PLY or OBJ.
//!
//! The data flow is one function, [`pipeline::run`]:
//! load ([`scene`]) → patches ([`patch`]) → BVH ([`visibility`]) → form factors
//! ([`form_factor`]) → matrix ([`matrix`]) → solve ([`solve`]) → bake ([`bake`]) → write
//! ([`export`]), with a [`report::Report`] of counts and timings.
//!
//! ```no_run
//! use radiosity::pipeline::{run, Settings, WriteOptions};
//! let outcome = run(
//!     "meshes/cornell_box.obj".as_ref(),
//!     "cornell_lit.ply".as_ref(),
//!     &Settings::default(),
//!     &WriteOptions::default(),
//! )?;
//! eprintln!("{}", outcome.report.summary());
//! # Ok::<(), radiosity::Error>(())
//! ```

pub mod bake;
pub mod error;
pub mod export;
pub mod form_factor;
pub mod info;
pub mod matrix;
pub mod patch;
pub mod pipeline;
pub mod reference;
pub mod report;
pub mod scene;
pub mod scenes;
pub mod solve;
pub mod verify;
pub mod visibility;

pub use error::{Error, Result};
