//! PLY 1.0, both ways: scene files read into a [`crate::scene::Scene`] ([`load`], any PLY a
//! modelling tool writes: ASCII or binary little-endian, any scalar types, materials from
//! optional `reflectance_*`/`emission_*` properties), baked meshes written for MeshLab
//! ([`write_to`]) and read back exactly ([`read`]). Both readers parse the header with the
//! one header layer of [`header`], so they agree on every header rule (comments, the camera
//! line, a second camera line being an error).

mod baked;
mod header;
mod scene;

pub use baked::{read, write_to};
pub use scene::load;
