//! Patches: the finite elements of the radiosity solve. This module owns the conforming
//! subdivision of the scene's triangles into patches no longer than `max_edge`, and each
//! patch's geometry (vertices, centroid, unit normal, area) and material (ρ, Le). It does not
//! know about rays or form factors.
//!
//! Subdivision is edge-based and therefore conforming: every round splits *every* edge longer
//! than `max_edge` at its midpoint, the midpoint is shared by both triangles on that edge (an
//! edge is keyed by its two vertex indices), and each triangle is re-triangulated according to
//! how many of its edges were split (1 → 2 children, 2 → 3, 3 → 4, the classic red/green
//! refinement). Neighbouring patches therefore always share vertices: no T-junctions appear
//! that were not already in the input.
//!
//! Two-sided scenes ([`Scene::make_two_sided`]): only one triangle of each twin pair is
//! subdivided; the other's patches are its patches mirrored (reversed winding, negated normals,
//! the same corners at their own copies of the vertices), appended after all others and linked
//! in [`Patches::twin`]. Subdividing both would not do: the re-triangulation breaks ties by
//! vertex order, which the reversal changes, so twins could be cut differently.

pub mod refine;

use std::collections::HashMap;

use glam::DVec3;

use crate::scene::{Scene, NO_TWIN};
use crate::{Error, Result};

/// Default crease angle, degrees. Where the faces around a vertex meet at angles up to this,
/// the mesh is taken to sample one smooth surface: the form factors use its interpolated
/// normal ([`corner_normals`]) and the bake shares the vertex. 30° keeps tessellated spheres
/// of a few hundred faces smooth (neighbour normals differ by ≲ 15°) while every corner of a
/// room or box (90°) stays sharp.
pub const DEFAULT_CREASE_DEGREES: f64 = 30.0;

/// Refuse subdivisions that would make more patches than this (memory and time guard).
pub const MAX_PATCHES: usize = 20_000_000;

/// The patch mesh. All vectors indexed by patch have the same length; patch `i`'s triangle is
/// `triangles[i]`, counter-clockwise seen from its front (emitting and reflecting) side.
#[derive(Debug, Clone)]
pub struct Patches {
    /// Vertex positions of the patch mesh, scene units. Shared between neighbouring patches.
    pub positions: Vec<DVec3>,
    /// Vertex indices of each patch, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
    /// Centroid of each patch, scene units.
    pub centroid: Vec<DVec3>,
    /// Unit normal of each patch (front side, right-hand rule on the vertex order).
    pub normal: Vec<DVec3>,
    /// Normal of the smooth surface the mesh approximates, at each corner of each patch
    /// (interpolated from the input mesh's vertex normals, [`corner_normals`]). Not unit
    /// length: interpolate linearly, then normalise ([`Patches::surface_normal`]). Equals
    /// `normal` on flat surfaces and wherever the crease angle is 0.
    pub corner_normal: Vec<[DVec3; 3]>,
    /// Area of each patch, scene units squared; > 0.
    pub area: Vec<f64>,
    /// Index into the scene's materials.
    pub material: Vec<u32>,
    /// ρ, diffuse reflectance per RGB channel, in [0, 1].
    pub reflectance: Vec<[f64; 3]>,
    /// Le, emitted radiance per RGB channel, W·sr⁻¹·m⁻², ≥ 0.
    pub emission: Vec<[f64; 3]>,
    /// Index of the scene triangle each patch was cut from.
    pub source_triangle: Vec<u32>,
    /// The patch on the other side of the same surface ([`NO_TWIN`] for none: every patch of a
    /// one-sided scene). Invariants: `twin[twin[i]] == i`; twins have the same corners (at
    /// different vertex indices) in reverse order, opposite normals, the same area, and come
    /// from twin scene triangles.
    pub twin: Vec<u32>,
}

impl Patches {
    /// Number of patches.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// True when there are no patches.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// The three corners of patch `i`, scene units.
    #[inline]
    pub fn corners(&self, i: usize) -> [DVec3; 3] {
        let [a, b, c] = self.triangles[i];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Unit surface normal at the point with barycentric coordinates `b` (weights of the
    /// corners, summing to 1) of patch `i`: the smooth surface's normal where the mesh is
    /// smooth ([`corner_normals`]), the patch's own normal on flat surfaces. This is the
    /// normal the form-factor kernels take at a receiving point (cosθ of the receiver).
    #[inline]
    pub fn surface_normal(&self, i: usize, b: [f64; 3]) -> DVec3 {
        let m = self.corner_normal[i];
        let n = b[0] * m[0] + b[1] * m[1] + b[2] * m[2];
        // Corner normals lie within the crease angle (< 90°) of the patch normal, so their
        // convex combination cannot vanish; the fallback only guards rounding.
        n.try_normalize().unwrap_or(self.normal[i])
    }

    /// Total area of all patches, scene units squared.
    pub fn total_area(&self) -> f64 {
        self.area.iter().sum()
    }

    /// Check the invariants documented on the fields.
    pub fn validate(&self) -> Result<()> {
        let n = self.len();
        let lengths = [
            self.centroid.len(),
            self.normal.len(),
            self.corner_normal.len(),
            self.area.len(),
            self.material.len(),
            self.reflectance.len(),
            self.emission.len(),
            self.source_triangle.len(),
            self.twin.len(),
        ];
        if lengths.iter().any(|&l| l != n) {
            return Err(Error::Internal(format!(
                "patch arrays disagree in length: {n} triangles vs {lengths:?}"
            )));
        }
        for i in 0..n {
            if self.triangles[i]
                .iter()
                .any(|&v| v as usize >= self.positions.len())
            {
                return Err(Error::Internal(format!(
                    "patch {i}: vertex index out of range"
                )));
            }
            if !(self.area[i] > 0.0 && self.area[i].is_finite()) {
                return Err(Error::Internal(format!(
                    "patch {i}: area {} ≤ 0",
                    self.area[i]
                )));
            }
            if (self.normal[i].length() - 1.0).abs() > 1e-9 {
                return Err(Error::Internal(format!("patch {i}: normal not unit")));
            }
            if self.corner_normal[i]
                .iter()
                .any(|m| !m.is_finite() || m.dot(self.normal[i]) <= 0.0)
            {
                return Err(Error::Internal(format!(
                    "patch {i}: a corner normal faces away from the patch's front"
                )));
            }
            let u = self.twin[i];
            if u != NO_TWIN {
                let ok = (u as usize) < n
                    && self.twin[u as usize] == i as u32
                    && self.corners(u as usize) == {
                        let [a, b, c] = self.corners(i);
                        [a, c, b]
                    };
                if !ok {
                    return Err(Error::Internal(format!(
                        "patch {i}: twin {u} is not its mirror image"
                    )));
                }
            }
            let ok_rho = self.reflectance[i].iter().all(|r| (0.0..=1.0).contains(r));
            let ok_le = self.emission[i].iter().all(|e| e.is_finite() && *e >= 0.0);
            if !ok_rho || !ok_le {
                return Err(Error::Internal(format!("patch {i}: material out of range")));
            }
        }
        Ok(())
    }
}

/// The default patch size: the scene's bounding-box diagonal / 16. For the Cornell box
/// (diagonal ≈ 963 mm) that is ≈ 60 mm, which gives about three thousand patches.
pub fn default_max_edge(scene: &Scene) -> f64 {
    let (lo, hi) = scene.bounds();
    (hi - lo).length() / 16.0
}

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
    let mut patches = Patches {
        positions,
        triangles: Vec::with_capacity(n),
        centroid: Vec::with_capacity(n),
        normal: Vec::with_capacity(n),
        corner_normal: Vec::with_capacity(n),
        area: Vec::with_capacity(n),
        material: Vec::with_capacity(n),
        reflectance: Vec::with_capacity(n),
        emission: Vec::with_capacity(n),
        source_triangle: Vec::with_capacity(n),
        twin: Vec::with_capacity(n),
    };
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
        patches.reflectance.push(mat.reflectance);
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
        patches.reflectance.push(mat.reflectance);
        patches.emission.push(mat.emission);
        patches.source_triangle.push(u);
        patches.twin.push(i as u32);
        patches.twin[i] = j;
    }
}

/// Barycentric coordinates of `p` (a point in the triangle's plane) in triangle `t`.
fn barycentric(p: DVec3, t: [DVec3; 3]) -> [f64; 3] {
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    let inv = 1.0 / n.length_squared();
    let w1 = (p - t[0]).cross(t[2] - t[0]).dot(n) * inv;
    let w2 = (t[1] - t[0]).cross(p - t[0]).dot(n) * inv;
    [1.0 - w1 - w2, w1, w2]
}

/// Normals of the smooth surface the scene's mesh approximates, at each corner of each scene
/// triangle: where the triangles around a vertex meet at angles up to `crease_degrees`
/// (grouped transitively, as the bake groups patches), they are taken to sample one smooth
/// surface and share that vertex's normal; across sharper edges each side keeps its own.
///
/// A flat facet's normal is only a first-order approximation of a curved surface's: on a
/// tessellated sphere it is off by up to half the angle between neighbouring facets, and the
/// receiving cosine inherits that O(h) error (a 1280-facet integrating sphere: 0.5 % mean
/// error per wall patch, 3.5 % next to the emitting cap). Interpolated vertex normals make
/// the receiving cosine second-order accurate. The vertex normal is the weighted sum of the
/// facet normals of its group with Max's weights, (e₁ × e₂)/(|e₁|²|e₂|²) for a facet with
/// edges e₁, e₂ leaving the vertex (N. Max, "Weights for computing vertex normals from facet
/// normals", JGT 4(2), 1999), which is exact for any triangles whose corners lie on a sphere.
/// A group whose weighted sum is not within 90° of a member facet's normal (a folded fan)
/// falls back to that facet's own normal.
///
/// In a two-sided scene the back of each twin pair (the later triangle) takes no part in the
/// grouping and gets the negated corner normals of its front, so the front's normals are those
/// of the one-sided scene.
pub fn corner_normals(scene: &Scene, crease_degrees: f64) -> Vec<[DVec3; 3]> {
    // The backs of twin pairs, mirrored at the end.
    let back = |t: usize| {
        scene
            .twin
            .get(t)
            .is_some_and(|&u| u != NO_TWIN && (u as usize) < t)
    };
    let facet: Vec<DVec3> = scene
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.vertices.map(|v| scene.positions[v as usize]);
            (b - a).cross(c - a).normalize()
        })
        .collect();
    let mut out: Vec<[DVec3; 3]> = facet.iter().map(|&n| [n; 3]).collect();
    if crease_degrees <= 0.0 {
        return out;
    }
    let cos_crease = crease_degrees.to_radians().cos();
    let tris: Vec<[u32; 3]> = scene.triangles.iter().map(|t| t.vertices).collect();
    // Backs are left out of the incidence lists (a triangle with no corners).
    let fronts: Vec<[u32; 3]> = (0..tris.len())
        .map(|t| if back(t) { [u32::MAX; 3] } else { tris[t] })
        .collect();
    let around = VertexFaces::new(&fronts, scene.positions.len());
    for v in 0..scene.positions.len() {
        let faces = around.faces(v);
        let group = groups(faces.len(), |a, b| {
            facet[faces[a] as usize].dot(facet[faces[b] as usize]) >= cos_crease
        });
        // Max's weighted facet normal of each face at v.
        let weighted: Vec<DVec3> = faces
            .iter()
            .map(|&f| {
                let t = tris[f as usize];
                let k = t.iter().position(|&u| u as usize == v).expect("face at v");
                let p = |u: u32| scene.positions[u as usize];
                let (e1, e2) = (p(t[(k + 1) % 3]) - p(t[k]), p(t[(k + 2) % 3]) - p(t[k]));
                e1.cross(e2) / (e1.length_squared() * e2.length_squared())
            })
            .collect();
        for (a, &f) in faces.iter().enumerate() {
            let sum: DVec3 = (0..faces.len())
                .filter(|&b| group[b] == group[a])
                .map(|b| weighted[b])
                .sum();
            let n = sum.normalize_or_zero();
            let k = tris[f as usize]
                .iter()
                .position(|&u| u as usize == v)
                .expect("face at v");
            if n.dot(facet[f as usize]) > 0.0 {
                out[f as usize][k] = n;
            }
        }
    }
    for t in (0..tris.len()).filter(|&t| back(t)) {
        let front = scene.twin[t] as usize;
        out[t] = tris[t].map(|v| {
            let k = tris[front].iter().position(|&w| w == v).unwrap_or(0);
            -out[front][k]
        });
    }
    out
}

/// The faces around each vertex of a triangle mesh (compressed: offsets + one list), each
/// vertex's faces in increasing order.
pub(crate) struct VertexFaces {
    offsets: Vec<usize>,
    faces: Vec<u32>,
}

impl VertexFaces {
    /// Corners equal to `u32::MAX` are left out (a triangle to be skipped).
    pub(crate) fn new(triangles: &[[u32; 3]], vertices: usize) -> Self {
        let mut offsets = vec![0usize; vertices + 1];
        for t in triangles {
            for &v in t.iter().filter(|&&v| v != u32::MAX) {
                offsets[v as usize + 1] += 1;
            }
        }
        for v in 0..vertices {
            offsets[v + 1] += offsets[v];
        }
        let mut faces = vec![0u32; offsets[vertices]];
        let mut fill = offsets.clone();
        for (f, t) in triangles.iter().enumerate() {
            for &v in t.iter().filter(|&&v| v != u32::MAX) {
                faces[fill[v as usize]] = f as u32;
                fill[v as usize] += 1;
            }
        }
        VertexFaces { offsets, faces }
    }

    /// The faces at vertex `v`.
    pub(crate) fn faces(&self, v: usize) -> &[u32] {
        &self.faces[self.offsets[v]..self.offsets[v + 1]]
    }

    /// Where vertex `v`'s faces start in the flat list (slot of its first face).
    pub(crate) fn offset(&self, v: usize) -> usize {
        self.offsets[v]
    }

    /// Total number of (vertex, face) incidences.
    pub(crate) fn len(&self) -> usize {
        self.faces.len()
    }
}

/// Partition `0..n` into the connected components of the relation `joined` (union–find);
/// returns a group label per element, labels numbered in order of each group's first member
/// (deterministic).
pub(crate) fn groups(n: usize, joined: impl Fn(usize, usize) -> bool) -> Vec<usize> {
    fn find(parent: &mut [usize], mut a: usize) -> usize {
        while parent[a] != a {
            parent[a] = parent[parent[a]];
            a = parent[a];
        }
        a
    }
    let mut parent: Vec<usize> = (0..n).collect();
    for a in 0..n {
        for b in a + 1..n {
            if joined(a, b) {
                let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
                if ra != rb {
                    parent[ra.max(rb)] = ra.min(rb);
                }
            }
        }
    }
    let mut label = vec![usize::MAX; n];
    let mut next = 0;
    (0..n)
        .map(|a| {
            let r = find(&mut parent, a);
            if label[r] == usize::MAX {
                label[r] = next;
                next += 1;
            }
            label[r]
        })
        .collect()
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::SceneBuilder;

    fn two_quads() -> Scene {
        // An L: a floor quad and a wall quad sharing the edge x ∈ [0, 1], y = z = 0.
        let mut b = SceneBuilder::new();
        let m = b.material("white", [0.5; 3], [0.0; 3]);
        b.quad(
            [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(0.0, 0.0, 1.0),
                DVec3::new(1.0, 0.0, 1.0),
                DVec3::new(1.0, 0.0, 0.0),
            ],
            m,
        );
        b.quad(
            [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(1.0, 0.7, 0.0),
                DVec3::new(0.0, 0.7, 0.0),
            ],
            m,
        );
        b.build().unwrap()
    }

    #[test]
    fn subdivision_preserves_area_orientation_and_edge_bound() {
        let scene = two_quads();
        for max_edge in [2.0, 0.5, 0.3, 0.11, 0.05] {
            let p = subdivide(&scene, max_edge, DEFAULT_CREASE_DEGREES).unwrap();
            p.validate().unwrap();
            // Area is preserved exactly up to rounding (children tile the parent).
            assert!((p.total_area() - 1.7).abs() < 1e-12, "{}", p.total_area());
            for i in 0..p.len() {
                let c = p.corners(i);
                for k in 0..3 {
                    assert!(c[k].distance(c[(k + 1) % 3]) <= max_edge * (1.0 + 1e-9));
                }
                // Children keep the parent's normal.
                let parent = p.source_triangle[i] as usize;
                let t = scene.triangles[parent]
                    .vertices
                    .map(|v| scene.positions[v as usize]);
                let n0 = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
                assert!(p.normal[i].dot(n0) > 1.0 - 1e-12);
            }
        }
    }

    /// Panics unless the patch mesh is conforming: every edge is used by exactly two patches
    /// (interior or shared edge) or by one (open boundary of the input), and no vertex lies
    /// inside a boundary edge (a T-junction).
    fn assert_conforming(p: &Patches) {
        let mut uses: HashMap<(u32, u32), i32> = HashMap::new();
        for t in &p.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        assert!(uses.values().all(|&u| u == 1 || u == 2));
        // A T-junction would leave a vertex lying in the interior of some other edge.
        for (&(a, b), _) in uses.iter().filter(|(_, &u)| u == 1) {
            let (pa, pb) = (p.positions[a as usize], p.positions[b as usize]);
            for (v, &q) in p.positions.iter().enumerate() {
                if v as u32 == a || v as u32 == b {
                    continue;
                }
                let t = (q - pa).dot(pb - pa) / (pb - pa).length_squared();
                let off = (pa + t * (pb - pa)).distance(q);
                assert!(
                    !(t > 1e-9 && t < 1.0 - 1e-9 && off < 1e-12),
                    "T-junction at {q}"
                );
            }
        }
    }

    #[test]
    fn subdivision_is_conforming() {
        let scene = two_quads();
        assert_conforming(&subdivide(&scene, 0.13, DEFAULT_CREASE_DEGREES).unwrap());
    }

    #[test]
    fn refinement_splits_marked_patches_and_stays_conforming() {
        let scene = two_quads();
        let p = subdivide(&scene, 0.3, DEFAULT_CREASE_DEGREES).unwrap();
        // Mark every third patch, including some on the crease between the two quads.
        let marked: Vec<bool> = (0..p.len()).map(|i| i % 3 == 0).collect();
        let r = refine(&scene, &p, &marked, DEFAULT_CREASE_DEGREES).unwrap();
        r.validate().unwrap();
        assert_conforming(&r);
        assert!((r.total_area() - p.total_area()).abs() < 1e-12);
        // Each marked patch became 4, and a neighbour of a marked patch at least 2.
        let marked_count = marked.iter().filter(|&&m| m).count();
        assert!(
            r.len() >= p.len() + 3 * marked_count,
            "{} → {}",
            p.len(),
            r.len()
        );
        // No patch grew.
        let largest = |q: &Patches| q.area.iter().cloned().fold(0.0, f64::max);
        assert!(largest(&r) <= largest(&p) + 1e-15);
        // Marking nothing changes nothing.
        let same = refine(&scene, &p, &vec![false; p.len()], DEFAULT_CREASE_DEGREES).unwrap();
        assert_eq!(same.triangles, p.triangles);
    }

    #[test]
    fn corner_normals_are_exact_on_a_sphere_and_flat_across_creases() {
        // Max's weights give the exact normal at any vertex whose neighbours lie on a sphere,
        // however irregular the fan: the geodesic sphere's corner normals are radial (inward,
        // its front side) to rounding.
        let sphere =
            crate::validation::scenes::integrating_sphere(2.0, 2, 30.0, 0.5, [1.0; 3]).unwrap();
        let normals = corner_normals(&sphere, DEFAULT_CREASE_DEGREES);
        for (tri, corners) in sphere.triangles.iter().zip(&normals) {
            for (v, n) in tri.vertices.iter().zip(corners) {
                let radial = -sphere.positions[*v as usize].normalize();
                assert!((*n - radial).length() < 1e-12, "vertex {v}");
            }
        }
        // With a crease angle of 0 every corner keeps its facet's normal.
        for (t, n) in corner_normals(&sphere, 0.0).iter().enumerate() {
            let [a, b, c] = sphere.triangles[t]
                .vertices
                .map(|v| sphere.positions[v as usize]);
            let facet = (b - a).cross(c - a).normalize();
            assert!(n.iter().all(|m| (*m - facet).length() < 1e-15));
        }
        // The L of two quads meets at 90°: a crease, so both keep their own normals, and
        // sub-patches carry them unchanged.
        let scene = two_quads();
        let p = subdivide(&scene, 0.3, DEFAULT_CREASE_DEGREES).unwrap();
        for i in 0..p.len() {
            for m in p.corner_normal[i] {
                assert!((m - p.normal[i]).length() < 1e-12);
            }
            assert!((p.surface_normal(i, [0.2, 0.3, 0.5]) - p.normal[i]).length() < 1e-12);
        }
    }

    #[test]
    fn sub_patch_normals_interpolate_the_source_triangle() {
        // Subdividing a smooth triangle must not change its normal field: at any point the
        // sub-patch's surface normal equals the interpolation in the source triangle.
        let sphere =
            crate::validation::scenes::integrating_sphere(1.0, 1, 30.0, 0.5, [1.0; 3]).unwrap();
        let coarse = corner_normals(&sphere, DEFAULT_CREASE_DEGREES);
        let p = subdivide(&sphere, 0.2, DEFAULT_CREASE_DEGREES).unwrap();
        assert!(p.len() > 4 * sphere.triangles.len());
        p.validate().unwrap();
        for i in (0..p.len()).step_by(7) {
            let b = [0.6, 0.3, 0.1];
            let c = p.corners(i);
            let x = b[0] * c[0] + b[1] * c[1] + b[2] * c[2];
            let src = p.source_triangle[i] as usize;
            let t = sphere.triangles[src]
                .vertices
                .map(|v| sphere.positions[v as usize]);
            let w = barycentric(x, t);
            let expected =
                (w[0] * coarse[src][0] + w[1] * coarse[src][1] + w[2] * coarse[src][2]).normalize();
            assert!((p.surface_normal(i, b) - expected).length() < 1e-12, "{i}");
        }
    }

    #[test]
    fn backs_mirror_fronts_where_a_second_subdivision_would_cut_differently() {
        // An isosceles triangle whose two long sides are split: the remaining quad's diagonals
        // tie, and the tie goes by vertex order, which the reverse changes.
        let corners = |p: &Patches, i: usize| {
            let mut c: Vec<[u64; 3]> = p
                .corners(i)
                .iter()
                .map(|v| v.to_array().map(f64::to_bits))
                .collect();
            c.sort();
            c
        };
        let mut b = SceneBuilder::new();
        let m = b.material("white", [0.5; 3], [0.0; 3]);
        let v = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.5, 2.0, 0.0),
        ]
        .map(|p| b.vertex(p));
        b.triangle([v[0], v[1], v[2]], m);
        let front_only = b.clone().build().unwrap();
        // The reverse given as a face of its own (one-sided) is cut the other way.
        b.triangle([v[0], v[2], v[1]], m);
        let both = b.build().unwrap();
        let p = subdivide(&both, 1.5, 0.0).unwrap();
        let of = |src: u32| {
            let mut all: Vec<_> = (0..p.len())
                .filter(|&i| p.source_triangle[i] == src)
                .map(|i| corners(&p, i))
                .collect();
            all.sort();
            all
        };
        assert_eq!(p.len(), 6);
        assert_ne!(of(0), of(1));
        // Made two-sided, the back's patches are the front's mirrored.
        let mut two = front_only.clone();
        two.make_two_sided();
        let p = subdivide(&two, 1.5, 0.0).unwrap();
        p.validate().unwrap();
        assert_eq!(p.len(), 6);
        for i in 0..3 {
            let j = p.twin[i] as usize;
            assert_eq!((j, p.twin[j] as usize), (i + 3, i));
            let [a, b, c] = p.corners(i);
            assert_eq!(p.corners(j), [a, c, b]);
            assert_eq!(p.normal[j], -p.normal[i]);
            assert_eq!(p.source_triangle[j], 1);
            // Own vertex copies: the sides never share an output vertex.
            assert!(p.triangles[i].iter().all(|v| !p.triangles[j].contains(v)));
        }
        assert_eq!(
            subdivide(&front_only, 1.5, 0.0).unwrap().twin,
            [NO_TWIN; 3],
            "one-sided scenes have no twins"
        );
    }

    #[test]
    fn bad_max_edge_is_a_usage_error() {
        let scene = two_quads();
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e-9] {
            let err = subdivide(&scene, bad, DEFAULT_CREASE_DEGREES).unwrap_err();
            assert!(matches!(err, Error::Setting { .. }), "{bad}: {err}");
        }
    }
}
