//! Conforming subdivision (see the module documentation of [`super`]): every edge longer than
//! `max_edge` split at a midpoint shared by both triangles on it, each triangle
//! re-triangulated by how many of its edges were split (red/green refinement); the same
//! splitting serves adaptive refinement ([`refine`]); then the patches' geometry, materials
//! and corner normals are filled in, and the back sides of twin pairs mirrored.

use std::collections::HashMap;

use glam::DVec3;

use super::{corner_normals, Patches, MAX_PATCHES};
use crate::scene::{Scene, NO_TWIN};
use crate::{Error, Result};

/// Subdivide every scene triangle until no patch edge is longer than `max_edge` (scene
/// units). Conforming: see the module documentation. `crease_degrees` decides where the input
/// mesh is a smooth surface for the patches' [`Patches::corner_normal`] (see
/// [`corner_normals`]; 0 = every triangle flat).
pub fn subdivide(scene: &Scene, max_edge: f64, crease_degrees: f64) -> Result<Patches> {
    if !(max_edge > 0.0 && max_edge.is_finite()) {
        return Err(Error::setting(
            "max_edge",
            format!("{max_edge} is not a positive length"),
        ));
    }
    // Guard: each patch has area at most √3/4·max_edge², and the subdivision keeps areas
    // within a constant factor of that; refuse before allocating absurd amounts.
    let total_area: f64 = (0..scene.triangles.len())
        .map(|t| scene.triangle_area(t))
        .sum();
    let estimate = total_area / (0.1 * max_edge * max_edge);
    if estimate > MAX_PATCHES as f64 {
        return Err(Error::setting(
            "max_edge",
            format!(
                "{max_edge} is too small for this scene: it would make about {estimate:.3e} \
                 patches (the limit is {MAX_PATCHES})"
            ),
        ));
    }

    let mut positions = scene.positions.clone();
    // (triangle, source triangle index); of a twin pair only the first is cut (see the module
    // documentation).
    let mirrored = |i: usize| {
        scene
            .twin
            .get(i)
            .is_some_and(|&u| u != NO_TWIN && (u as usize) < i)
    };
    let mut tris: Vec<([u32; 3], u32)> = scene
        .triangles
        .iter()
        .enumerate()
        .filter(|&(i, _)| !mirrored(i))
        .map(|(i, t)| (t.vertices, i as u32))
        .collect();
    let limit2 = (max_edge * (1.0 + 1e-12)).powi(2);
    loop {
        let long = |a: u32, b: u32, positions: &[DVec3]| {
            positions[a as usize].distance_squared(positions[b as usize]) > limit2
        };
        if !tris
            .iter()
            .any(|(t, _)| (0..3).any(|k| long(t[k], t[(k + 1) % 3], &positions)))
        {
            break;
        }
        let snapshot = positions.clone();
        tris = split_edges(&mut positions, &tris, |a, b| long(a, b, &snapshot));
        if tris.len() > MAX_PATCHES {
            return Err(Error::setting(
                "max_edge",
                format!("{max_edge} makes more than {MAX_PATCHES} patches"),
            ));
        }
    }
    build(scene, positions, tris, crease_degrees)
}

/// One round of conforming refinement: every patch marked in `marked` has all three edges
/// split at their midpoints, and each neighbour sharing a split edge is split along it too
/// (1 → 2 children), so the mesh stays conforming. Patches keep their source triangles;
/// corner normals are interpolated afresh ([`subdivide`]). Used for adaptive refinement.
pub fn refine(
    scene: &Scene,
    patches: &Patches,
    marked: &[bool],
    crease_degrees: f64,
) -> Result<Patches> {
    // Two-sided scenes: only the fronts are split (a front is marked if either side is);
    // `build` mirrors them again, so the backs stay exact mirror images.
    let front = |i: usize| patches.twin[i] == NO_TWIN || patches.twin[i] as usize > i;
    let either =
        |i: usize| marked[i] || (patches.twin[i] != NO_TWIN && marked[patches.twin[i] as usize]);
    let mut edges = std::collections::HashSet::new();
    for (i, t) in patches.triangles.iter().enumerate() {
        if !front(i) || !either(i) {
            continue;
        }
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            edges.insert((a.min(b), a.max(b)));
        }
    }
    let tris: Vec<([u32; 3], u32)> = (0..patches.len())
        .filter(|&i| front(i))
        .map(|i| (patches.triangles[i], patches.source_triangle[i]))
        .collect();
    let mut positions = patches.positions.clone();
    let tris = split_edges(&mut positions, &tris, |a, b| {
        edges.contains(&(a.min(b), a.max(b)))
    });
    if tris.len() > MAX_PATCHES {
        return Err(Error::setting(
            "refine_rounds",
            format!("refinement makes more than {MAX_PATCHES} patches"),
        ));
    }
    build(scene, positions, tris, crease_degrees)
}

/// Split every edge (a, b) of `tris` for which `split(a, b)` holds at a midpoint shared by
/// both triangles on it (appended to `positions`), and re-triangulate each triangle by how
/// many of its edges were split ([`split_triangle`]). Children keep the source index.
fn split_edges(
    positions: &mut Vec<DVec3>,
    tris: &[([u32; 3], u32)],
    split: impl Fn(u32, u32) -> bool,
) -> Vec<([u32; 3], u32)> {
    let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
    let mut next = Vec::with_capacity(tris.len() * 4);
    for &(t, src) in tris {
        // m[k] = midpoint of edge (t[k], t[k+1]) if that edge is split.
        let mut m = [None; 3];
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if split(a, b) {
                let key = (a.min(b), a.max(b));
                let id = *midpoints.entry(key).or_insert_with(|| {
                    positions.push(0.5 * (positions[a as usize] + positions[b as usize]));
                    (positions.len() - 1) as u32
                });
                m[k] = Some(id);
            }
        }
        split_triangle(t, m, positions, |c| next.push((c, src)));
    }
    next
}

/// The patches of `tris` (patch triangle, source scene triangle) over `positions`: geometry,
/// materials and corner normals.
fn build(
    scene: &Scene,
    positions: Vec<DVec3>,
    tris: Vec<([u32; 3], u32)>,
    crease_degrees: f64,
) -> Result<Patches> {
    let n = tris.len();
    let smooth = corner_normals(scene, crease_degrees);
    let mut patches = Patches::with_capacity(positions, n);
    if scene.materials.iter().any(|m| m.transmittance > 0.0) {
        patches.material_transmittance = scene.materials.iter().map(|m| m.transmittance).collect();
    }
    for (t, src) in tris {
        let [a, b, c] = t.map(|v| patches.positions[v as usize]);
        let cross = (b - a).cross(c - a);
        let area = 0.5 * cross.length();
        if area.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            // A midpoint split of a non-degenerate triangle never makes a zero-area child;
            // the scene loader already dropped degenerate input triangles.
            return Err(Error::Internal(format!(
                "zero-area patch cut from scene triangle {src}"
            )));
        }
        let material = scene.triangles[src as usize].material;
        let mat = &scene.materials[material as usize];
        // Corner normals of the patch: the source triangle's corner normals interpolated
        // linearly at the patch's corners (which lie in the source triangle's plane), so that
        // interpolating them again inside the patch is interpolation in the source triangle.
        let source = scene.triangles[src as usize]
            .vertices
            .map(|v| scene.positions[v as usize]);
        let ns = smooth[src as usize];
        let corner = [a, b, c].map(|p| {
            let w = barycentric(p, source);
            w[0] * ns[0] + w[1] * ns[1] + w[2] * ns[2]
        });
        patches.triangles.push(t);
        patches.centroid.push((a + b + c) / 3.0);
        patches.normal.push(cross / (2.0 * area));
        patches.corner_normal.push(corner);
        patches.area.push(area);
        patches.material.push(material);
        patches
            .reflectance
            .push(scene.reflectance_over(src as usize, [a, b, c]));
        patches.emission.push(mat.emission);
        patches.source_triangle.push(src);
        patches.twin.push(NO_TWIN);
    }
    if scene.is_two_sided() {
        mirror_twins(scene, &mut patches);
    }
    Ok(patches)
}

/// Appends the mirror image of every patch whose scene triangle has a twin (the twin's
/// patches: reversed winding, negated normals, the twin triangle's material and index), at
/// copies of the corner vertices (so the two sides never share an output vertex in the bake,
/// whatever the crease angle), and links each pair in [`Patches::twin`].
fn mirror_twins(scene: &Scene, patches: &mut Patches) {
    let n = patches.len();
    let mut copy = vec![u32::MAX; patches.positions.len()];
    for i in 0..n {
        let u = scene.twin[patches.source_triangle[i] as usize];
        if u == NO_TWIN {
            continue;
        }
        let [a, b, c] = patches.triangles[i].map(|v| {
            if copy[v as usize] == u32::MAX {
                copy[v as usize] = patches.positions.len() as u32;
                patches.positions.push(patches.positions[v as usize]);
            }
            copy[v as usize]
        });
        let material = scene.triangles[u as usize].material;
        let mat = &scene.materials[material as usize];
        let m = patches.corner_normal[i];
        let j = patches.len() as u32;
        patches.triangles.push([a, c, b]);
        patches.centroid.push(patches.centroid[i]);
        patches.normal.push(-patches.normal[i]);
        patches.corner_normal.push([-m[0], -m[2], -m[1]]);
        patches.area.push(patches.area[i]);
        patches.material.push(material);
        let corners = [a, c, b].map(|v| patches.positions[v as usize]);
        patches
            .reflectance
            .push(scene.reflectance_over(u as usize, corners));
        patches.emission.push(mat.emission);
        patches.source_triangle.push(u);
        patches.twin.push(i as u32);
        patches.twin[i] = j;
    }
}

/// Barycentric coordinates of `p` (a point in the triangle's plane) in triangle `t`.
pub(crate) fn barycentric(p: DVec3, t: [DVec3; 3]) -> [f64; 3] {
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    let inv = 1.0 / n.length_squared();
    let w1 = (p - t[0]).cross(t[2] - t[0]).dot(n) * inv;
    let w2 = (t[1] - t[0]).cross(p - t[0]).dot(n) * inv;
    [1.0 - w1 - w2, w1, w2]
}

/// Re-triangulate triangle `t` (counter-clockwise) given the midpoints `m[k]` of the split
/// edges (t[k], t[k+1]); children keep the parent's orientation.
fn split_triangle(
    t: [u32; 3],
    m: [Option<u32>; 3],
    positions: &[DVec3],
    mut emit: impl FnMut([u32; 3]),
) {
    let count = m.iter().filter(|x| x.is_some()).count();
    match count {
        0 => emit(t),
        3 => {
            let (ab, bc, ca) = (m[0].unwrap(), m[1].unwrap(), m[2].unwrap());
            emit([t[0], ab, ca]);
            emit([ab, t[1], bc]);
            emit([ca, bc, t[2]]);
            emit([ab, bc, ca]);
        }
        1 => {
            // Rotate so that the split edge is (a, b).
            let k = m.iter().position(|x| x.is_some()).unwrap();
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            let mid = m[k].unwrap();
            emit([a, mid, c]);
            emit([mid, b, c]);
        }
        _ => {
            // Rotate so that the unsplit edge is (c, a): split edges are (a, b) and (b, c).
            let k = m.iter().position(|x| x.is_none()).unwrap();
            let (a, b, c) = (t[(k + 1) % 3], t[(k + 2) % 3], t[k]);
            let (mab, mbc) = (m[(k + 1) % 3].unwrap(), m[(k + 2) % 3].unwrap());
            emit([mab, b, mbc]);
            // The remaining quad a, mab, mbc, c: cut along its shorter diagonal.
            // Ties (common in regular meshes) go to the first diagonal; the relative margin,
            // far above f64 rounding, keeps that choice the same in any unit of length.
            let p = |v: u32| positions[v as usize];
            let (d1, d2) = (p(a).distance_squared(p(mbc)), p(mab).distance_squared(p(c)));
            if d1 <= d2 * (1.0 + 1e-9) {
                emit([a, mab, mbc]);
                emit([a, mbc, c]);
            } else {
                emit([a, mab, c]);
                emit([mab, mbc, c]);
            }
        }
    }
}
