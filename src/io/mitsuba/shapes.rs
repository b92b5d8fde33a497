//! The geometry of Mitsuba's built-in shapes in their own (object) space, as triangles with
//! counter-clockwise fronts, and the `lookat` frame of its transforms. Lengths are in the
//! shape's own units; [`super`] applies `to_world`.

use std::collections::HashMap;

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
    let g = (1.0 + 5f64.sqrt()) / 2.0;
    let mut unit: Vec<DVec3> = [
        (-1.0, g, 0.0),
        (1.0, g, 0.0),
        (-1.0, -g, 0.0),
        (1.0, -g, 0.0),
        (0.0, -1.0, g),
        (0.0, 1.0, g),
        (0.0, -1.0, -g),
        (0.0, 1.0, -g),
        (g, 0.0, -1.0),
        (g, 0.0, 1.0),
        (-g, 0.0, -1.0),
        (-g, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
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
    // Outward fronts whatever the table's order: a face whose normal points at the centre
    // is turned over.
    for t in &mut triangles {
        let [a, b, c] = t.map(|v| unit[v as usize]);
        if (b - a).cross(c - a).dot(a + b + c) < 0.0 {
            t.swap(1, 2);
        }
    }
    for _ in 0..subdivisions {
        let mut middle: HashMap<(u32, u32), u32> = HashMap::new();
        let mut split = |i: u32, j: u32, unit: &mut Vec<DVec3>| {
            *middle.entry((i.min(j), i.max(j))).or_insert_with(|| {
                unit.push((unit[i as usize] + unit[j as usize]).normalize());
                unit.len() as u32 - 1
            })
        };
        let mut finer = Vec::with_capacity(triangles.len() * 4);
        for [a, b, c] in triangles {
            let (ab, bc, ca) = (
                split(a, b, &mut unit),
                split(b, c, &mut unit),
                split(c, a, &mut unit),
            );
            finer.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = finer;
    }
    Mesh {
        positions: unit.iter().map(|&p| centre + p * radius).collect(),
        triangles,
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
