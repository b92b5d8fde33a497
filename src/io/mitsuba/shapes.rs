//! The geometry of Mitsuba's built-in shapes in their own (object) space, as triangles with
//! counter-clockwise fronts, and the `lookat` frame of its transforms. Lengths are in the
//! shape's own units; [`super`] applies `to_world`.

use glam::{DMat4, DVec3, DVec4};

/// Segments of a disk's rim.
pub(super) const DISK_SEGMENTS: usize = 64;

/// How many times a sphere's icosahedron is subdivided: 20 · 4⁴ = 5120 triangles, whose area
/// falls short of the sphere's by about 0.2 %.
pub(super) const SPHERE_SUBDIVISIONS: u32 = 4;

/// Triangles over their own positions, fronts counter-clockwise.
#[derive(Debug, Clone, Default)]
pub(super) struct Mesh {
    pub positions: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
}

/// Mitsuba's `rectangle`: the square [−1, 1]² in the plane z = 0, its front facing +z.
pub(super) fn rectangle() -> Mesh {
    Mesh {
        positions: vec![
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(1.0, -1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.0),
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// Mitsuba's `cube`: the box [−1, 1]³, six squares facing outward (the same corner appears
/// once per face; the scene's welding joins them).
pub(super) fn cube() -> Mesh {
    let mut mesh = Mesh::default();
    for a in 0..3 {
        for sign in [1.0, -1.0] {
            let axis = |k: usize| DVec3::from_array(std::array::from_fn(|i| f64::from(i == k)));
            let (b, c) = (axis((a + 1) % 3), axis((a + 2) % 3));
            // e_b × e_c = e_a: swap them on the negative side so that u × v points outward.
            let (u, v) = if sign > 0.0 { (b, c) } else { (c, b) };
            let centre = axis(a) * sign;
            let base = mesh.positions.len() as u32;
            mesh.positions.extend([
                centre - u - v,
                centre + u - v,
                centre + u + v,
                centre - u + v,
            ]);
            mesh.triangles
                .extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
        }
    }
    mesh
}

/// Mitsuba's `disk`: the unit disk in the plane z = 0, front facing +z, as a fan of
/// `segments` triangles around its centre.
pub(super) fn disk(segments: usize) -> Mesh {
    let mut positions = vec![DVec3::ZERO];
    positions.extend((0..segments).map(|k| {
        let phi = std::f64::consts::TAU * k as f64 / segments as f64;
        DVec3::new(phi.cos(), phi.sin(), 0.0)
    }));
    let n = segments as u32;
    let triangles = (0..n).map(|k| [0, 1 + k, 1 + (k + 1) % n]).collect();
    Mesh {
        positions,
        triangles,
    }
}

/// Mitsuba's `sphere`: a sphere of `radius` around `centre`, as an icosahedron subdivided
/// `subdivisions` times with its vertices pushed onto the sphere, fronts facing outward.
pub(super) fn sphere(centre: DVec3, radius: f64, subdivisions: u32) -> Mesh {
    // The one icosphere of the scene generators, already wound outward.
    let (unit, faces) = crate::geometry::icosphere(subdivisions);
    Mesh {
        positions: unit.iter().map(|&p| centre + p * radius).collect(),
        triangles: faces.iter().map(|f| f.map(|v| v as u32)).collect(),
    }
}

/// Mitsuba's `lookat` transform: the frame at `origin` whose +z looks at `target`, whose +y
/// is `up` made perpendicular to it and whose +x is up × forward (to the left of the view).
/// `None` when `target` is `origin` or `up` is parallel to the view (or either is zero).
pub(super) fn lookat(origin: DVec3, target: DVec3, up: DVec3) -> Option<DMat4> {
    let forward = (target - origin).try_normalize()?;
    let left = up.cross(forward).try_normalize()?;
    let up = forward.cross(left);
    Some(DMat4::from_cols(
        left.extend(0.0),
        up.extend(0.0),
        forward.extend(0.0),
        DVec4::new(origin.x, origin.y, origin.z, 1.0),
    ))
}
