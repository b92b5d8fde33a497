//! # radiosity
//!
//! A radiosity (finite-element) solver for the diffuse rendering equation. It reads an
//! OBJ/MTL, PLY or glTF scene (`Kd` = diffuse reflectance ρ, `Ke` = emitted radiance Le in
//! W·sr⁻¹·m⁻²), cuts it into patches, estimates the form factors F_ij by ray casting, solves
//! (I − K)L = E with K = diag(ρ)·F, and bakes the patch radiance into vertex colours written
//! as PLY, OBJ or glb.
//! This crate is the library; the `radiosity` command line is the `radiosity-cli` package,
//! built on it (the library pulls in no argument parser, progress bars or anyhow).
//!
//! The data flow is one function, [`pipeline::run`] (start reading there), one folder per
//! stage:
//!
//! | stage | module | what it owns |
//! |---|---|---|
//! | load | [`io`] | scene files in (OBJ + MTL, PLY, glTF, a lights file), baked meshes out (PLY, OBJ, glb), atomic writes |
//! | scene | [`scene`] | triangles, materials, the file's camera and lights, the lights' merge rule, overrides, two-sided twins |
//! | patches | [`mesh`] | conforming subdivision, smooth normals, adaptive refinement, discontinuities as edges |
//! | BVH | [`visibility`] | watertight ray queries in a canonical frame |
//! | direct light | [`light`] | what emitters, the sky, the sun and lamps send to a point, with visibility |
//! | form factors | [`form_factor`] | the estimators, their loop, shortcuts, the cache |
//! | matrix, solve | [`solve`] | (I − K)L = E and five methods to solve it |
//! | or, hierarchically | [`hierarchical`] | element trees, clusters, links, sweeps, push-pull, conforming leaves |
//! | bake | [`bake`] | patch radiance → output vertices; the [`bake::BakedMesh`] |
//! | final gather | [`gather`] | the radiance evaluated again at the output vertices, the display refinement |
//! | write, picture | [`io`], [`render`] | files for MeshLab; PNG pictures of a bake |
//! | checks | [`validation`] | closed forms, procedural scenes, a path tracer, `verify` |
//!
//! Around them: [`pipeline`] (the sequencer, its [`pipeline::Settings`] with the one
//! `validate()`, the [`pipeline::Report`]); on the ground floor, imported by every stage and
//! importing none, [`geometry`] (frames, the point-to-polygon kernel, polygon clipping, the
//! visible part of a polygon) and [`sampling`] (the seeded Rng, quadrature and sampling
//! rules), [`color`] (RGB, luminance, sRGB, exposure), [`progress`] (stage counters a
//! program may draw) and [`Error`] (one error type, in the library's own words).
//!
//! Load, bake, write in a few lines (here a procedural scene; [`scene::Scene::load`] reads
//! a file):
//!
//! ```
//! use radiosity::validation::scenes;
//! use radiosity::{io, pipeline};
//!
//! // Two facing unit squares 1 apart: a source with Le = 1 and a receiver with ρ = 0.5.
//! let scene = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0)?;
//! let settings = pipeline::Settings { max_edge: Some(0.25), ..Default::default() };
//! let outcome = pipeline::solve_scene(&scene, &settings)?;
//! // The receiver's mean radiance is ρ·F·Le with F = 0.19982 (Howell C-11).
//! let p = &outcome.patches;
//! let receiver: Vec<usize> = (0..p.len()).filter(|&i| p.material[i] == 1).collect();
//! let area: f64 = receiver.iter().map(|&i| p.area[i]).sum();
//! let mean = receiver.iter().map(|&i| p.area[i] * outcome.solution.radiance[i][0]).sum::<f64>() / area;
//! assert!((mean - 0.5 * 0.199825).abs() < 1e-4);
//!
//! let path = std::env::temp_dir().join("radiosity-doc-plates.ply");
//! io::write(&path, &outcome.baked, io::Format::Ply { ascii: false }, 1.0)?;
//! # std::fs::remove_file(&path).ok();
//! # Ok::<(), radiosity::Error>(())
//! ```
//!
//! For a file, [`pipeline::run`] does load → … → write in one call.

pub mod bake;
pub mod choice;
pub mod color;
pub mod distributed;

pub mod error;
pub mod form_factor;
pub mod gather;
pub mod geometry;
pub mod hierarchical;
pub mod io;
pub mod light;
pub mod mesh;
pub mod pipeline;
pub mod progress;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod solve;
pub mod validation;
pub mod visibility;

#[cfg(test)]
mod test_support;

pub use choice::Choice;
pub use color::Rgb;
pub use error::{Error, Result};
