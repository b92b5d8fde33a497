//! The ground floor's geometry: pure functions of points, normals and polygons that every
//! stage shares, with no rays, no scene and no patches. It owns the orthonormal frames about
//! a normal ([`frame`]), the form factor's integrands (the point-to-point kernel G and the
//! exact point-to-polygon form factor by Lambert's contour integral, [`kernel`]), clipping of
//! convex polygons to a half-space ([`clip`]), the visible part of a polygon seen from a point
//! past occluding triangles and its exact form factor ([`visible`]), and the winding key that
//! recognises a triangle's reverse ([`winding`]).
//!
//! It imports no other module of the crate; [`crate::sampling`] (random numbers, quadrature and
//! sampling rules) stands beside it on the ground floor. Neither imports a stage, and the
//! integration test `layers` keeps it so.

pub mod clip;
pub mod frame;
pub mod kernel;
pub mod visible;
pub mod winding;

pub use clip::{clip_above, clip_polygon};
pub use frame::orthonormal_basis;
pub use kernel::{point_to_convex_polygon, point_to_point, point_to_polygon};
pub use visible::visible_form_factor;
pub use winding::winding_key;
