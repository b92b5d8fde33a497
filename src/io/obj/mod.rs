//! Wavefront OBJ + MTL, both ways: scene files read into a [`crate::scene::Scene`] ([`load`],
//! through `tobj`, with our own line-numbered checks), and one writer ([`write_obj`]) behind
//! both outputs: procedural scenes saved as OBJ + MTL ([`save`]) and baked meshes with vertex
//! colours for MeshLab ([`write_to`], read back exactly by [`read`]).

mod baked;
mod scene;

pub use baked::{colour_component, component_to_u8, read, write_to};
pub use scene::{load, save};
