//! The ground floor's geometry: pure functions of points, normals and polygons that every
//! stage shares, with no rays, no scene and no patches. It owns the orthonormal frames about
//! a normal ([`frame`]), the form factor's integrands (the point-to-point kernel G and the
//! exact point-to-polygon form factor by Lambert's contour integral, [`kernel`]), clipping of
//! convex polygons to a half-space ([`clip`]), the visible part of a polygon seen from a point
//! past occluding triangles and its exact form factor ([`visible`]), the winding key that
//! recognises a triangle's reverse ([`winding`]), the unit icosphere the scene generators and
//! the Mitsuba reader's spheres share ([`icosphere`]), and the faces of an axis-aligned box
//! the generators and the speed workload share ([`box_faces`]), and the bounding box of points
//! ([`bounds`]).
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

use glam::DVec3;

/// Unit icosphere: vertices on the unit sphere, faces counter-clockwise seen from outside;
/// an icosahedron whose faces are split in four `level` times, the new vertices pushed onto
/// the sphere (20·4^level faces).
pub fn icosphere(level: u32) -> (Vec<DVec3>, Vec<[usize; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<DVec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid = std::collections::HashMap::new();
        let mut midpoint = |a: usize, b: usize, v: &mut Vec<DVec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                v.push((v[a] + v[b]).normalize());
                v.len() - 1
            })
        };
        let mut next = Vec::with_capacity(f.len() * 4);
        for [a, b, c] in f {
            let ab = midpoint(a, b, &mut v);
            let bc = midpoint(b, c, &mut v);
            let ca = midpoint(c, a, &mut v);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    (v, f)
}

/// The axis-aligned bounding box of `points` as (min, max); of none, the empty box (+∞, −∞).
pub fn bounds(points: impl IntoIterator<Item = DVec3>) -> (DVec3, DVec3) {
    points
        .into_iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        })
}

/// The six faces of the axis-aligned box [lo, hi], each counter-clockwise seen from outside,
/// in the order −x, +x, −y, +y, −z, +z.
pub fn box_faces(lo: DVec3, hi: DVec3) -> [[DVec3; 4]; 6] {
    let c = |x: bool, y: bool, z: bool| {
        DVec3::new(
            if x { hi.x } else { lo.x },
            if y { hi.y } else { lo.y },
            if z { hi.z } else { lo.z },
        )
    };
    let (f, t) = (false, true);
    [
        [c(f, f, f), c(f, f, t), c(f, t, t), c(f, t, f)],
        [c(t, f, f), c(t, t, f), c(t, t, t), c(t, f, t)],
        [c(f, f, f), c(t, f, f), c(t, f, t), c(f, f, t)],
        [c(f, t, f), c(f, t, t), c(t, t, t), c(t, t, f)],
        [c(f, f, f), c(f, t, f), c(t, t, f), c(t, f, f)],
        [c(f, f, t), c(t, f, t), c(t, t, t), c(f, t, t)],
    ]
}
