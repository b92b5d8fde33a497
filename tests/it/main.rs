//! The library's integration test binary: whole scenes through the library's API, one file per
//! subject. What belongs here: behaviour that needs a real scene or the whole pipeline; what
//! one module does on constructed inputs is unit-tested beside it in src/, and what a user
//! sees through the binary is tested in cli/tests.
//!
//! - `closed_forms`: the verify suite per estimator and solver, and the path-traced Cornell box;
//! - `solvers`, `form_factors`, `visibility`, `mesh`: each stage on real scenes, against oracles
//!   (dense LU, brute-force visibility) and invariants (row sums, reciprocity, conformity);
//! - `loaders`: hostile bytes through the scene loaders;
//! - `mitsuba`: Mitsuba XML scenes through the pipeline (a closed room's closed form);
//! - `hostile_geometry`: the unit of length and pathological meshes;
//! - `materials`, `two_sided`: overrides and two-sided surfaces through the pipeline;
//! - `lights`: the lights outside the mesh (sky, sun, lamps), closed forms and shadows, both
//!   methods;
//! - `distributed`: a bake over several ranks (threads here) is the one-process bake, bit for bit;
//! - `layers`: the modules' imports read from src/: no cycle, a ground floor that names no stage;
//! - `scenes`: the generated benchmark scenes keep their own promises (counts, lights, no
//!   modelling mistakes).

mod closed_forms;
mod distributed;
mod form_factors;
mod hierarchical;
mod hostile_geometry;
mod layers;
mod lights;
mod loaders;
mod materials;
mod mesh;
mod mitsuba;
mod scenes;
mod solvers;
mod support;
mod two_sided;
mod visibility;
