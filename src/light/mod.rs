//! Direct light at a point: what the light sources send straight to a point of the scene,
//! with visibility, before any bounce. Every stage that needs it calls this module: the matrix
//! method's emission vector, the hierarchical solver's elements, the final gather's vertices.
//!
//! D(x) = Σ_e Le_e · F(x → e) · V̄(x, e) + (1/π) ∫_Ω L_env(ω) V(x, ω) cosθ dω   (radiance units),
//!
//! - emitting triangles of the scene ([`emitter`]): the exact unoccluded point-to-polygon form
//!   factor F ([`crate::geometry::point_to_polygon`]) times the visible share V̄, by the visible
//!   pieces of the emitter ([`crate::geometry::visible`]) or by kernel-weighted shadow rays;
//! - the lights outside the mesh, the sky, the sun, point and spot lights ([`outside`]); of a
//!   level's hundreds of lamps, or of a hall's hundreds of emitting triangles, one drawn for a
//!   point by a light tree ([`tree`]).
//!
//! A point is a [`Receiver`]: where it is, its normal, the occluders its rays are traced
//! against and how far above the surface they start. Shadow-ray counts are named constants
//! in the two files, one name for one count.

use glam::DVec3;

use crate::visibility::Visibility;

pub mod emitter;
pub mod outside;
pub mod tree;

pub use emitter::{Emitter, Share};

pub use outside::{patch_light, SKY_RAYS};
pub use tree::LightTree;

/// A point where the lights outside the mesh are evaluated: the estimators' common arguments.
#[derive(Clone, Copy)]
pub struct Receiver<'a> {
    /// The occluders its shadow rays are traced against.
    pub vis: &'a Visibility,
    /// The point, scene units.
    pub x: DVec3,
    /// Its unit normal (the front side).
    pub n: DVec3,
    /// The triangle of `vis` it lies on, which its rays ignore.
    pub ignore: u32,
    /// How far its rays start above the surface (and stop short of a point light), scene
    /// units.
    pub lift: f64,
}

impl Receiver<'_> {
    /// Where its rays start: `lift` above the point along the normal.
    pub fn origin(&self) -> DVec3 {
        self.x + self.lift * self.n
    }
}

/// `n` point lights scattered over a floor at z = 0 for the tests: most above it, every
/// seventh below, every fifth a spot aimed down, of varied colours (more than
/// [`outside::EXACT_LIGHTS`] + [`outside::SAMPLED_LIGHTS`] for n ≥ 33).
#[cfg(test)]
pub(crate) fn scattered_lights(n: usize) -> Vec<crate::scene::PointLight> {
    use crate::scene::{PointLight, Spot};
    (0..n)
        .map(|k| {
            let a = k as f64 * 0.61;
            let r = 0.3 + 0.15 * (k % 17) as f64;
            let z = if k % 7 == 0 {
                -1.0
            } else {
                0.5 + 0.1 * (k % 5) as f64
            };
            PointLight {
                position: DVec3::new(r * a.cos(), r * a.sin(), z),
                intensity: [1.0 + (k % 3) as f64, 1.0, 0.5 + (k % 4) as f64],
                spot: (k % 5 == 0).then(|| Spot {
                    direction: DVec3::new(0.2, 0.0, -1.0).normalize(),
                    inner_degrees: 20.0,
                    outer_degrees: 50.0,
                }),
            }
        })
        .collect()
}
