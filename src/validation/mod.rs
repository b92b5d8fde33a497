//! Checking the solver against answers known independently of it: closed forms
//! ([`closed_forms`]: Howell's form-factor tables, the integrating sphere, the furnace), the
//! procedural scenes they hold for ([`scenes`], also what `radiosity generate` writes), an
//! independent path tracer of the same triangles for scenes without a closed form
//! ([`path_tracer`]: the Cornell box), the point-wise benchmark of what a baked mesh
//! displays against that tracer at random visible points ([`pointwise`]), and the built-in
//! suite that runs the pipeline on those scenes and scores it ([`verify`], `radiosity
//! verify`).

pub mod closed_forms;
pub mod path_tracer;
pub mod pointwise;
pub mod scenes;
pub mod verify;
