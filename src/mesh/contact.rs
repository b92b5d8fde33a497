//! Contact lines as mesh edges: where one face touches or crosses another face's plane (a
//! block standing on the floor, a leg under a table top, a light mounted just below the
//! ceiling), the line where they meet becomes an edge of the face it lies on, before patching.
//! Then no patch spans both the part a viewer sees and the part the other object hides, so no
//! vertex carries lit light into a hidden region or hidden darkness into a lit one (Lischinski,
//! Tampieri & Greenberg, "Discontinuity meshing for accurate radiosity", IEEE CG&A 1992: these
//! are the D0 discontinuities, where radiance itself jumps).
//!
//! For every face A (a scene triangle) and every face B near it (a BVH over the faces' boxes):
//!
//! - **B touches or crosses A's plane** (B's corners on both sides, or an edge of B within
//!   [`TOUCH`] × the scene's extent of it): the segment where B meets the plane;
//! - **B lies parallel just in front of A** (within [`NEAR`] × the extent, or within
//!   [`MOUNTED`] × the narrower one's width: a light mounted below a ceiling, a picture on a
//!   wall, a leg's top under a table top): B's outline projected onto A;
//! - **B lies parallel a little further in front of A** (within the narrower one's width and
//!   [`NEAR_SHADOW`] × the extent: a table leg's back 3 cm from a wall): B's shadow on A has
//!   edges sharper than the patches, and the edges of B's outline that are its silhouette
//!   (not shared with a coplanar face) are projected onto A. Only when the scene itself is
//!   split ([`split_contacts`], the matrix method's patches), not for the lines that cut the
//!   hierarchical display ([`contact_lines`]): a display face keeps its element's radiance,
//!   and cut small beside a near occluder it took the gather's near hits off their one bounce
//!   further (measured on the generated hall: 4.34 → 4.53 % displayed RMS).
//!
//! The segments are clipped to A; those along A's own edges (a wall meeting the floor at the
//! floor's border) are dropped. A is then re-triangulated with them as constraints (a
//! constrained Delaunay triangulation, the `spade` crate), and the points where segments end
//! on A's edges are inserted into the face across each edge as well, so the result stays
//! conforming. Faces with no contact are kept as they are.

use std::collections::HashMap;

use glam::{DVec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::builder::build_bvh2;
use obvhs::BvhBuildParams;
use rayon::prelude::*;
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

use super::Patches;
use crate::scene::{Scene, SceneTriangle, NO_TWIN, ZERO_AREA_RELATIVE};

/// Which discontinuities of the radiance become mesh edges before patching.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Discontinuities {
    /// `contacts` for the matrix method. For the hierarchical one, contact lines become
    /// edges of the display only ([`split_patches`], after the solve, when the final gather
    /// runs): its roots stay the input triangles, as contact lines inside a large face (a
    /// hall's floor under hundreds of table legs) leave long thin triangles between them that
    /// cost it 2.6× the links (measured on the generated hall of 10⁴ triangles: 0.73 M →
    /// 1.93 M links, 2.2× the time), while the gather at the display's vertices needs only
    /// the display's faces to stop at the contacts.
    Auto,
    /// None: patches follow the input triangles only.
    None,
    /// Contact lines (see the module documentation).
    Contacts,
}

impl crate::choice::Choice for Discontinuities {
    const SETTING: &'static str = "discontinuities";
    const ALL: &'static [Discontinuities] = &[
        Discontinuities::Auto,
        Discontinuities::None,
        Discontinuities::Contacts,
    ];

    fn name(self) -> &'static str {
        match self {
            Discontinuities::Auto => "auto",
            Discontinuities::None => "none",
            Discontinuities::Contacts => "contacts",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Discontinuities::Auto => {
                "contacts for the matrix method; for the hierarchical, contact lines cut the \
                 display's faces only"
            }
            Discontinuities::None => "patches follow the input triangles only",
            Discontinuities::Contacts => {
                "where a face touches or crosses another's plane, the contact line becomes an edge"
            }
        }
    }
}

impl std::fmt::Display for Discontinuities {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(crate::choice::Choice::name(*self))
    }
}

/// A face whose corner (or edge) is within this fraction of the scene's extent of another
/// face's plane touches it.
pub const TOUCH: f64 = 1e-6;
/// A parallel face within this fraction of the scene's extent in front of another is mounted
/// on it: its outline is projected onto it.
pub const NEAR: f64 = 1e-3;
/// A parallel face within this fraction of its own width (its smallest altitude; or the other
/// face's, if narrower) in front of another is mounted on it too, however large the scene: a
/// ceiling panel 1 cm under the ceiling, a picture 2 cm off a wall. Under B, light enters only
/// through the gap g: the
/// unoccluded share of the hemisphere a point sees falls from about ½ at the outline to
/// g / (distance from the outline) inside it (the form factor to a slit of width g), so
/// with g ≤ 5 % of B's width the region under B is dark but for a rim a few g wide, while
/// outside, ½(1 − x/√(x² + g²)) of it is hidden at a distance x: within 1 % of open by
/// x = 5g. The radiance changes by about its whole value within a few g of the outline: at
/// the scale of any patch, a jump. (The living room's panel, 1 cm under the ceiling, is
/// 1.4e-3 of the room's extent: not within [`NEAR`], and the ceiling's vertices beside it
/// showed up to 31 % too dark, interpolated from dark ones under it.)
pub const MOUNTED: f64 = 0.05;
/// A parallel face B in front of another face A, farther than mounted but within B's width
/// (or A's, if narrower) and within this fraction of the scene's extent (a quarter of the
/// default patch size, [`super::default_max_edge`]), shades A with a shadow sharper than the
/// patches: the edges of B's outline that are its silhouette (not shared with a coplanar
/// face: a table leg's back face 3 cm from the wall, not the wall's diagonal seen from the
/// leg) are projected onto A. The indirect light under B falls by the share of the hemisphere
/// B fills, within about the gap g of its outline: behind the study's 4 cm legs 3 cm from
/// the wall, a dip of 5–8 % across 10 cm of a wall whose patches are 15 cm, which the display
/// refinement's few test rays at an edge's midpoint cannot see (measured on the point-wise
/// benchmark's study, whose worst probes were those behind the legs, +8, +5 and +4 %:
/// displayed RMS 0.62 → 0.56 %; the Cornell box, two_rooms and the hall unchanged). With B
/// narrower than g its shadow is shallow and wide (a long strip of width w at height g hides
/// sin(atan(w/2g)) < 45 % of the light under its middle, spread over several g), and beyond
/// the patches' scale the patches follow it themselves.
pub const NEAR_SHADOW: f64 = 1.0 / 64.0;

/// What [`split_contacts`] did.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct ContactStats {
    /// Contact segments inserted (after clipping to the faces they lie on).
    pub segments: usize,
    /// Faces re-triangulated.
    pub faces_split: usize,
    /// Triangles of the scene after the split.
    pub triangles: usize,
}

/// The contact segments on each scene triangle (see the module documentation; touching,
/// crossing and mounted faces, not the near shadows), in scene coordinates on the triangle's
/// plane; `None` when the scene is two-sided (twins must stay pairs of identical faces), has
/// fewer than two triangles, or has no contact.
pub fn contact_lines(scene: &Scene) -> Option<Vec<Vec<[DVec3; 2]>>> {
    let (lo, hi) = scene.bounds();
    let faces: Vec<Face> = (0..scene.triangles.len())
        .map(|t| Face::new(scene, t))
        .collect();
    lines_on(scene, &faces, (hi - lo).length(), false)
}

/// [`contact_lines`] for the scene's `faces` (one per triangle) and its extent, with the
/// near shadows' silhouettes ([`NEAR_SHADOW`]) when `near_shadows`.
fn lines_on(
    scene: &Scene,
    faces: &[Face],
    extent: f64,
    near_shadows: bool,
) -> Option<Vec<Vec<[DVec3; 2]>>> {
    let n = faces.len();
    if !scene.twin.is_empty() || n < 2 {
        return None;
    }
    // Segments on each face, found in parallel against a BVH over the faces' boxes.
    // Each box widened by how far in front of another face that face counts as mounted (a
    // query box of A then meets every B that touches, crosses or is mounted on it).
    let boxes: Vec<Aabb> = faces
        .iter()
        .map(|f| {
            let (mounted, shading) = f.gaps(None, extent);
            f.aabb(if near_shadows { shading } else { mounted })
        })
        .collect();
    let silhouettes = near_shadows.then(|| silhouettes(faces));
    let mut build_time = std::time::Duration::ZERO;
    let bvh = build_bvh2(&boxes, BvhBuildParams::fast_build(), &mut build_time);
    let segments: Vec<Vec<[DVec3; 2]>> = (0..n)
        .into_par_iter()
        .map(|a| {
            let fa = &faces[a];
            let mut found = Vec::new();
            bvh.aabb_traverse(fa.aabb(0.0), |bvh, node| {
                let node = &bvh.nodes[node as usize];
                for k in node.first_index..node.first_index + node.prim_count {
                    let b = bvh.primitive_indices[k as usize] as usize;
                    if b != a {
                        let outline = silhouettes.as_ref().map(|s| s[b]);
                        found.extend(fa.contact(&faces[b], outline, extent));
                    }
                }
                true
            });
            found.sort_by(|p, q| {
                let key = |s: &[DVec3; 2]| [s[0].x, s[0].y, s[0].z, s[1].x, s[1].y, s[1].z];
                key(p)
                    .partial_cmp(&key(q))
                    .unwrap_or(std::cmp::Ordering::Equal)
            });
            found.dedup();
            found
        })
        .collect();
    (!segments.iter().all(|s| s.is_empty())).then_some(segments)
}

/// The scene with its contact lines as edges (see the module documentation); the same scene
/// when it has none, or when it is two-sided (twins must stay pairs of identical faces).
pub fn split_contacts(scene: &Scene) -> (Scene, ContactStats) {
    let n = scene.triangles.len();
    let mut stats = ContactStats {
        triangles: n,
        ..ContactStats::default()
    };
    let (lo, hi) = scene.bounds();
    let extent = (hi - lo).length();
    let faces: Vec<Face> = (0..n).map(|t| Face::new(scene, t)).collect();
    let Some(segments) = lines_on(scene, &faces, extent, true) else {
        return (scene.clone(), stats);
    };

    // Points where segments end on a face's edge, registered on that edge (by its two vertex
    // indices) so the face across it gets them too.
    let mut on_edge: HashMap<(u32, u32), Vec<DVec3>> = HashMap::new();
    for (a, segs) in segments.iter().enumerate() {
        let f = &faces[a];
        for s in segs {
            for &p in s {
                if let Some(e) = f.edge_through(p, TOUCH * extent) {
                    let v = scene.triangles[a].vertices;
                    let (i, j) = (v[e], v[(e + 1) % 3]);
                    on_edge.entry((i.min(j), i.max(j))).or_default().push(p);
                }
            }
        }
    }

    // Re-triangulate the faces with segments or extra edge points.
    let mut positions = scene.positions.clone();
    let mut index: HashMap<[u64; 3], u32> = positions
        .iter()
        .enumerate()
        .map(|(i, p)| (bits(*p), i as u32))
        .collect();
    let mut triangles = Vec::with_capacity(n);
    let min_area = ZERO_AREA_RELATIVE * extent * extent;
    for (a, tri) in scene.triangles.iter().enumerate() {
        let v = tri.vertices;
        let edge_points = points_on_edges(&on_edge, v);
        if segments[a].is_empty() && edge_points.is_empty() {
            triangles.push(*tri);
            continue;
        }
        let pieces = faces[a].triangulate(&segments[a], &edge_points, false);
        let Some(pieces) = pieces else {
            triangles.push(*tri); // the triangulation failed: keep the face whole
            continue;
        };
        stats.faces_split += 1;
        stats.segments += segments[a].len();
        for [p, q, r] in pieces {
            if 0.5 * (q - p).cross(r - p).length() <= min_area {
                continue;
            }
            let mut id = |x: DVec3| {
                *index.entry(bits(x)).or_insert_with(|| {
                    positions.push(x);
                    (positions.len() - 1) as u32
                })
            };
            triangles.push(SceneTriangle {
                vertices: [id(p), id(q), id(r)],
                ..*tri
            });
        }
    }
    stats.triangles = triangles.len();
    let mut out = scene.clone();
    out.positions = positions;
    out.triangles = triangles;
    (out, stats)
}

/// The display's faces cut along the scene's contact lines (`lines`, from [`contact_lines`]),
/// for a solve whose patches were not (the hierarchical one: its roots are the input
/// triangles, see [`Discontinuities::Auto`]). Each patch crossed by a contact segment of its
/// source triangle is re-triangulated with the segment's part inside it as a constrained
/// edge, and the points where segments end on a patch's edge go into the patch across it too,
/// so the display stays conforming. The pieces keep their patch's material, normal and
/// source triangle; corner normals are interpolated in it. Returns the new patches, the
/// patch each piece came from, and what was done (`segments`: the clipped pieces inserted).
/// `None` for two-sided patches (twins must stay pairs).
pub fn split_patches(
    lines: &[Vec<[DVec3; 2]>],
    patches: &Patches,
    extent: f64,
) -> Option<(Patches, Vec<u32>, ContactStats)> {
    if patches.twin.iter().any(|&t| t != NO_TWIN) {
        return None;
    }
    let touch = TOUCH * extent;
    let n = patches.len();
    // Each patch's part of its source triangle's segments.
    let cut: Vec<(Face, Vec<[DVec3; 2]>)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let face = Face::from_corners(patches.corners(i));
            let segs = lines
                .get(patches.source_triangle[i] as usize)
                .map(|segs| {
                    segs.iter()
                        .filter_map(|&[p, q]| {
                            face.clip([face.to_2d(p), face.to_2d(q)], touch / face.size)
                        })
                        .map(|[p, q]| [face.point_at(p), face.point_at(q)])
                        .collect()
                })
                .unwrap_or_default();
            (face, segs)
        })
        .collect();
    let mut on_edge: HashMap<(u32, u32), Vec<DVec3>> = HashMap::new();
    for (i, (face, segs)) in cut.iter().enumerate() {
        for s in segs {
            for &p in s {
                if let Some(e) = face.edge_through(p, touch) {
                    let v = patches.triangles[i];
                    let (a, b) = (v[e], v[(e + 1) % 3]);
                    on_edge.entry((a.min(b), a.max(b))).or_default().push(p);
                }
            }
        }
    }
    // Both patches on an edge find the points where segments cross it, each in its own frame:
    // the same point up to rounding. One point stands for each cluster within `touch`, and
    // segment ends move to it, so the two sides share it exactly.
    for points in on_edge.values_mut() {
        points.sort_by(|p, q| {
            p.to_array()
                .partial_cmp(&q.to_array())
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        let mut kept: Vec<DVec3> = Vec::with_capacity(points.len());
        for &p in points.iter() {
            if kept.iter().all(|k| k.distance(p) > touch) {
                kept.push(p);
            }
        }
        *points = kept;
    }
    let shared = |i: usize, face: &Face, p: DVec3| -> DVec3 {
        let Some(e) = face.edge_through(p, touch) else {
            return p;
        };
        let v = patches.triangles[i];
        let (a, b) = (v[e], v[(e + 1) % 3]);
        on_edge
            .get(&(a.min(b), a.max(b)))
            .and_then(|pts| pts.iter().find(|k| k.distance(p) <= touch))
            .copied()
            .unwrap_or(p)
    };
    let mut stats = ContactStats {
        triangles: n,
        ..ContactStats::default()
    };
    let mut out = Patches::with_capacity(patches.positions.clone(), n);
    let mut parent = Vec::with_capacity(n);
    let mut index: HashMap<[u64; 3], u32> = HashMap::new();
    let min_area = ZERO_AREA_RELATIVE * extent * extent;
    for (i, (face, segs)) in cut.iter().enumerate() {
        let v = patches.triangles[i];
        let edge_points = points_on_edges(&on_edge, v);
        let segs: Vec<[DVec3; 2]> = segs.iter().map(|s| s.map(|p| shared(i, face, p))).collect();
        let pieces = if segs.is_empty() && edge_points.is_empty() {
            None
        } else {
            face.triangulate(&segs, &edge_points, true)
        };
        let Some(pieces) = pieces else {
            out.push_inside(v, &patches.parent(i));
            parent.push(i as u32);
            continue;
        };
        stats.faces_split += 1;
        stats.segments += segs.len();
        for [p, q, r] in pieces {
            if 0.5 * (q - p).cross(r - p).length() <= min_area {
                continue;
            }
            let mut id = |x: DVec3| {
                if let Some(k) = face.corners.iter().position(|&c| c == x) {
                    return v[k];
                }
                *index.entry(bits(x)).or_insert_with(|| {
                    out.positions.push(x);
                    (out.positions.len() - 1) as u32
                })
            };
            let t = [id(p), id(q), id(r)];
            out.push_inside(t, &patches.parent(i));
            parent.push(i as u32);
        }
    }
    stats.triangles = out.len();
    Some((out, parent, stats))
}

/// The 2D segments `segs` cut at their crossings: each pair that crosses (or where one ends on
/// the other, within [`CROSSING`] of its ends) is split at one point shared by both pieces,
/// an end of one of them where the crossing lies that near it, so the pieces meet only at
/// their ends. Zero-length pieces are dropped. O(k²) in the segments of one face.
fn split_at_crossings(segs: &[[[f64; 2]; 2]]) -> Vec<[[f64; 2]; 2]> {
    let sub = |a: [f64; 2], b: [f64; 2]| [a[0] - b[0], a[1] - b[1]];
    let cross = |a: [f64; 2], b: [f64; 2]| a[0] * b[1] - a[1] * b[0];
    let mut cuts: Vec<Vec<(f64, [f64; 2])>> = segs
        .iter()
        .map(|s| vec![(0.0, s[0]), (1.0, s[1])])
        .collect();
    for i in 0..segs.len() {
        for j in i + 1..segs.len() {
            let (p, r) = (segs[i][0], sub(segs[i][1], segs[i][0]));
            let (q, s) = (segs[j][0], sub(segs[j][1], segs[j][0]));
            let d = cross(r, s);
            if d == 0.0 {
                continue; // parallel: spade splits a constraint at vertices lying on it
            }
            let qp = sub(q, p);
            let (t, u) = (cross(qp, s) / d, cross(qp, r) / d);
            let inside = |x: f64| (-CROSSING..=1.0 + CROSSING).contains(&x);
            if !inside(t) || !inside(u) {
                continue;
            }
            let near_end = |x: f64| x.abs() <= CROSSING || (1.0 - x).abs() <= CROSSING;
            let x = match (near_end(t), near_end(u)) {
                (true, true) => continue, // they meet at their ends
                (true, false) => segs[i][usize::from(t > 0.5)],
                (false, true) => segs[j][usize::from(u > 0.5)],
                (false, false) => [p[0] + t * r[0], p[1] + t * r[1]],
            };
            cuts[i].push((t.clamp(0.0, 1.0), x));
            cuts[j].push((u.clamp(0.0, 1.0), x));
        }
    }
    let mut out = Vec::new();
    for mut c in cuts {
        c.sort_by(|x, y| x.0.total_cmp(&y.0));
        for w in c.windows(2) {
            if w[0].1 != w[1].1 {
                out.push([w[0].1, w[1].1]);
            }
        }
    }
    out
}

/// See [`split_at_crossings`]: a crossing this near (a fraction of the segment) to an end is
/// taken at that end.
const CROSSING: f64 = 1e-9;

/// `q` moved onto the edge of the triangle `c` (2D, in units of its longest edge) within
/// [`ONTO_EDGE`] of it, if any: a point where a contact segment crosses an edge, placed on it
/// by the face across the edge in its own frame, lies off it here by the frames' rounding and
/// snapping (up to ~1e-9), and would leave a sliver between itself and the edge.
fn onto_edge(c: [[f64; 2]; 3], q: [f64; 2]) -> [f64; 2] {
    for k in 0..3 {
        let (a, b) = (c[k], c[(k + 1) % 3]);
        let e = [b[0] - a[0], b[1] - a[1]];
        let l2 = e[0] * e[0] + e[1] * e[1];
        let t = ((q[0] - a[0]) * e[0] + (q[1] - a[1]) * e[1]) / l2;
        let on = [a[0] + t * e[0], a[1] + t * e[1]];
        let off = (q[0] - on[0]).hypot(q[1] - on[1]);
        if t > 0.0 && t < 1.0 && off <= ONTO_EDGE {
            return on;
        }
    }
    q
}

/// See [`onto_edge`]: 100 × the snapping grid of [`Face::to_2d`].
const ONTO_EDGE: f64 = 1e-7;

/// The points registered on the edges of the triangle `v` (by its vertex indices, in
/// `on_edge`, keyed by the edge's two indices in increasing order).
fn points_on_edges(on_edge: &HashMap<(u32, u32), Vec<DVec3>>, v: [u32; 3]) -> Vec<DVec3> {
    (0..3)
        .flat_map(|e| {
            let (a, b) = (v[e], v[(e + 1) % 3]);
            on_edge
                .get(&(a.min(b), a.max(b)))
                .into_iter()
                .flatten()
                .copied()
        })
        .collect()
}

/// The grid [`Face::to_2d`] snaps to: 2³⁰ steps per face size.
const SNAP: f64 = (1u64 << 30) as f64;

fn bits(p: DVec3) -> [u64; 3] {
    [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]
}

/// An edge by its ends' bits, the lesser first.
type EdgeKey = ([u64; 3], [u64; 3]);

/// For each face's edges (corner k to k + 1), whether the edge is a silhouette of its plane:
/// no other face with the same plane and facing shares it (matched by the corners' bits, so
/// an unwelded mesh's duplicated vertices match too).
fn silhouettes(faces: &[Face]) -> Vec<[bool; 3]> {
    let key = |f: &Face, k: usize| {
        let (p, q) = (bits(f.corners[k]), bits(f.corners[(k + 1) % 3]));
        if p <= q {
            (p, q)
        } else {
            (q, p)
        }
    };
    // Every face's edges, sorted by key: the faces sharing an edge are a run (no allocation
    // per edge, for scenes of millions of faces).
    let mut edges: Vec<(EdgeKey, u32)> = faces
        .iter()
        .enumerate()
        .flat_map(|(i, f)| (0..3).map(move |k| (key(f, k), i as u32)))
        .collect();
    edges.sort_unstable();
    let sharing = |e: EdgeKey| {
        let first = edges.partition_point(|x| x.0 < e);
        edges[first..]
            .iter()
            .take_while(move |x| x.0 == e)
            .map(|x| x.1)
    };
    faces
        .iter()
        .enumerate()
        .map(|(i, f)| {
            std::array::from_fn(|k| {
                !sharing(key(f, k)).any(|j| {
                    let g = &faces[j as usize];
                    j as usize != i
                        && f.normal.dot(g.normal) > 1.0 - 1e-9
                        && g.corners
                            .iter()
                            .all(|&c| f.normal.dot(c - f.corners[0]).abs() <= 1e-9 * f.size)
                })
            })
        })
        .collect()
}

/// A scene triangle with its plane and a frame in it.
struct Face {
    corners: [DVec3; 3],
    /// Unit front normal.
    normal: DVec3,
    /// In-plane orthonormal axes (origin corner 0).
    u: DVec3,
    w: DVec3,
    /// Length of the longest edge: 2D coordinates are in this unit.
    size: f64,
}

impl Face {
    fn new(scene: &Scene, t: usize) -> Face {
        Face::from_corners(
            scene.triangles[t]
                .vertices
                .map(|v| scene.positions[v as usize]),
        )
    }

    fn from_corners(corners: [DVec3; 3]) -> Face {
        let normal = (corners[1] - corners[0])
            .cross(corners[2] - corners[0])
            .normalize();
        let u = (corners[1] - corners[0]).normalize();
        let size = (0..3)
            .map(|k| corners[k].distance(corners[(k + 1) % 3]))
            .fold(0.0, f64::max);
        Face {
            corners,
            normal,
            u,
            w: normal.cross(u),
            size,
        }
    }

    /// Its smallest altitude (2 × area / longest edge), scene units.
    fn width(&self) -> f64 {
        let [a, b, c] = self.corners;
        (b - a).cross(c - a).length() / self.size.max(f64::MIN_POSITIVE)
    }

    /// The largest gaps at which the parallel face `b` in front of this one is mounted on it
    /// ([`NEAR`] × the scene's `extent`, or [`MOUNTED`] × the narrower one's width: the gap
    /// between them shades at most the narrower one's width), and at which it is mounted or
    /// shades it with a shadow sharper than the patches ([`NEAR_SHADOW`]), scene units.
    /// Without `b`, the largest for any `b`.
    fn gaps(&self, b: Option<&Face>, extent: f64) -> (f64, f64) {
        let width = b.map_or(self.width(), |b| self.width().min(b.width()));
        let mounted = (NEAR * extent).max(MOUNTED * width);
        (mounted, mounted.max(width.min(NEAR_SHADOW * extent)))
    }

    fn aabb(&self, pad: f64) -> Aabb {
        let lo = self.corners[0].min(self.corners[1]).min(self.corners[2]) - pad;
        let hi = self.corners[0].max(self.corners[1]).max(self.corners[2]) + pad;
        // f32 boxes: widen by a rounding step so no touching face is missed.
        let widen = |x: f64, down: bool| {
            let f = x as f32;
            let step = f.abs().max(1.0) * f32::EPSILON * 4.0;
            if down {
                f - step
            } else {
                f + step
            }
        };
        Aabb::new(
            Vec3A::new(widen(lo.x, true), widen(lo.y, true), widen(lo.z, true)),
            Vec3A::new(widen(hi.x, false), widen(hi.y, false), widen(hi.z, false)),
        )
    }

    /// In-plane coordinates in units of the face's longest edge, snapped to a grid of 2⁻³⁰
    /// (1e-9 of the face): a scene scaled by any factor gets bitwise the same coordinates, so
    /// the contact points and the Delaunay triangulation's tie-breaking (the four corners of a
    /// rectangular footprint lie on one circle) are the same at every scale. Contact points
    /// move by at most 1e-9 of the face.
    fn to_2d(&self, p: DVec3) -> [f64; 2] {
        let d = (p - self.corners[0]) / self.size;
        let snap = |x: f64| (x * SNAP).round() / SNAP;
        [snap(d.dot(self.u)), snap(d.dot(self.w))]
    }

    fn point_at(&self, q: [f64; 2]) -> DVec3 {
        self.corners[0] + self.size * (q[0] * self.u + q[1] * self.w)
    }

    /// The segments where face `b` meets this face (see the module documentation), clipped to
    /// this face and projected onto its plane; `silhouette` says which of `b`'s edges are its
    /// plane's outline (see [`silhouettes`]), `None` to leave out the near shadows.
    fn contact(&self, b: &Face, silhouette: Option<[bool; 3]>, extent: f64) -> Vec<[DVec3; 2]> {
        let touch = TOUCH * extent;
        let d = b.corners.map(|c| self.normal.dot(c - self.corners[0]));
        let parallel = self.normal.dot(b.normal).abs() > 1.0 - 1e-9;
        let mut raw: Vec<[DVec3; 2]> = Vec::new();
        if parallel {
            // Mounted in front (not coplanar, not behind): its outline; or in front within
            // the shading gap: the silhouette edges of its outline.
            let gap = d[0];
            let (mounted, shading) = self.gaps(Some(b), extent);
            let reach = if silhouette.is_some() {
                shading
            } else {
                mounted
            };
            if gap > touch && gap <= reach && d.iter().all(|&x| x > touch) {
                let outline = silhouette.unwrap_or([true; 3]);
                for k in (0..3).filter(|&k| gap <= mounted || outline[k]) {
                    raw.push([b.corners[k], b.corners[(k + 1) % 3]]);
                }
            }
        } else if d.iter().all(|&x| x.abs() <= touch) {
            // Coplanar within the tolerance but not parallel: degenerate, skip.
        } else {
            // Points where B meets the plane: corners on it, and edges crossing it.
            let mut pts: Vec<DVec3> = Vec::new();
            for k in 0..3 {
                let (p, q) = (b.corners[k], b.corners[(k + 1) % 3]);
                let (dp, dq) = (d[k], d[(k + 1) % 3]);
                if dp.abs() <= touch {
                    pts.push(p);
                }
                if (dp > touch && dq < -touch) || (dp < -touch && dq > touch) {
                    let t = dp / (dp - dq);
                    pts.push(p + t * (q - p));
                }
            }
            if pts.len() >= 2 {
                // The two farthest apart (B is convex: they bound its section).
                let (mut best, mut pair) = (0.0, [pts[0], pts[1]]);
                for i in 0..pts.len() {
                    for j in i + 1..pts.len() {
                        let l = pts[i].distance_squared(pts[j]);
                        if l > best {
                            best = l;
                            pair = [pts[i], pts[j]];
                        }
                    }
                }
                raw.push(pair);
            }
        }
        raw.into_iter()
            .filter_map(|[p, q]| self.clip([self.to_2d(p), self.to_2d(q)], touch / self.size))
            .map(|[p, q]| [self.point_at(p), self.point_at(q)])
            .collect()
    }

    /// The part of the 2D segment inside this face, `None` if shorter than `tol` or lying
    /// along one of its edges.
    fn clip(&self, s: [[f64; 2]; 2], tol: f64) -> Option<[[f64; 2]; 2]> {
        let c = self.corners.map(|p| self.to_2d(p));
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        let d = [s[1][0] - s[0][0], s[1][1] - s[0][1]];
        for k in 0..3 {
            let (a, b) = (c[k], c[(k + 1) % 3]);
            // Inward normal of edge a→b (counter-clockwise corners in this frame).
            let nrm = [-(b[1] - a[1]), b[0] - a[0]];
            let len = (nrm[0] * nrm[0] + nrm[1] * nrm[1]).sqrt();
            let dist0 = (nrm[0] * (s[0][0] - a[0]) + nrm[1] * (s[0][1] - a[1])) / len;
            let slope = (nrm[0] * d[0] + nrm[1] * d[1]) / len;
            if slope.abs() < 1e-300 {
                if dist0 < -tol {
                    return None;
                }
                continue;
            }
            let t = (-dist0) / slope;
            if slope > 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
        if t1 <= t0 {
            return None;
        }
        let at = |t: f64| [s[0][0] + t * d[0], s[0][1] + t * d[1]];
        let (p, q) = (at(t0), at(t1));
        let length = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
        if length <= tol {
            return None;
        }
        // Along an edge of the face: both ends within tol of the same edge's line.
        for k in 0..3 {
            let (a, b) = (c[k], c[(k + 1) % 3]);
            let e = [b[0] - a[0], b[1] - a[1]];
            let el = (e[0] * e[0] + e[1] * e[1]).sqrt();
            let off = |x: [f64; 2]| ((x[0] - a[0]) * e[1] - (x[1] - a[1]) * e[0]).abs() / el;
            if off(p) <= tol && off(q) <= tol {
                return None;
            }
        }
        Some([p, q])
    }

    /// Which edge (k: corners k → k+1) the point lies on, within `tol`, if any (not a corner).
    fn edge_through(&self, p: DVec3, tol: f64) -> Option<usize> {
        if self.corners.iter().any(|c| c.distance(p) <= tol) {
            return None;
        }
        (0..3).find(|&k| {
            let (a, b) = (self.corners[k], self.corners[(k + 1) % 3]);
            let e = b - a;
            let t = (p - a).dot(e) / e.length_squared();
            t > 0.0 && t < 1.0 && (a + t * e).distance(p) <= tol
        })
    }

    /// The face triangulated with `segments` as constrained edges and `edge_points` as extra
    /// vertices on its border (constrained Delaunay triangulation in the face's plane),
    /// counter-clockwise seen from the front. `None` if the triangulation fails.
    fn triangulate(
        &self,
        segments: &[[DVec3; 2]],
        edge_points: &[DVec3],
        onto_edges: bool,
    ) -> Option<Vec<[DVec3; 3]>> {
        let mut cdt = ConstrainedDelaunayTriangulation::<Point2<f64>>::new();
        // 3D position of each vertex the triangulation holds (by handle index): corners and
        // border points exactly as given, so the faces on either side share them.
        let mut at: HashMap<usize, DVec3> = HashMap::new();
        let corners_2d = self.corners.map(|c| self.to_2d(c));
        let place = |p: DVec3| {
            let q = self.to_2d(p);
            if onto_edges {
                onto_edge(corners_2d, q)
            } else {
                q
            }
        };
        let mut insert = |cdt: &mut ConstrainedDelaunayTriangulation<Point2<f64>>, p: DVec3| {
            let q = place(p);
            let h = cdt.insert(Point2::new(q[0], q[1])).ok()?;
            at.entry(h.index()).or_insert(p);
            Some(h)
        };
        for &c in &self.corners {
            insert(&mut cdt, c)?;
        }
        for &p in edge_points {
            insert(&mut cdt, p)?;
        }
        for s in segments {
            insert(&mut cdt, s[0])?;
            insert(&mut cdt, s[1])?;
        }
        // The segments split where they cross one another, so that no constraint crosses
        // another: spade's own splitting of crossing constraints (`add_constraint_and_split`)
        // can fail an internal assertion where crossings nearly coincide (found on a real
        // scene, LibreQuake's e1m2). A piece that still conflicts by rounding is left out
        // (`try_add_constraint` refuses it): the face is cut along the rest.
        let flat: Vec<[[f64; 2]; 2]> = segments.iter().map(|s| s.map(place)).collect();
        for [a, b] in split_at_crossings(&flat) {
            let a = cdt.insert(Point2::new(a[0], a[1])).ok()?;
            let b = cdt.insert(Point2::new(b[0], b[1])).ok()?;
            if a != b {
                cdt.try_add_constraint(a, b);
            }
        }
        let mut out = Vec::with_capacity(cdt.num_inner_faces());
        for face in cdt.inner_faces() {
            let vs = face.vertices();
            let p = vs.map(|v| {
                at.get(&v.fix().index()).copied().unwrap_or_else(|| {
                    let q = v.position();
                    self.point_at([q.x, q.y])
                })
            });
            // spade's faces are counter-clockwise in (u, w), the face's own orientation.
            out.push(p);
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::{self, Settings};
    use crate::scene::SceneBuilder;
    use crate::validation::scenes::add_box;

    /// A builder holding a 4 × 4 floor (z = 0, facing up) of the material "white", and the
    /// materials "white" and "light".
    fn floor() -> (SceneBuilder, u32, u32) {
        let mut b = SceneBuilder::new();
        let white = b.material("white", [0.5; 3], [0.0; 3]);
        let light = b.material("light", [0.0; 3], [5.0; 3]);
        let z = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        b.quad([z(0., 0.), z(4., 0.), z(4., 4.), z(0., 4.)], white);
        (b, white, light)
    }

    /// A 4 × 4 floor (z = 0, facing up) under a light, with a box standing on it, turned 30°
    /// about the vertical so its footprint crosses the floor's diagonal. Returns the scene and
    /// the footprint's corners (counter-clockwise).
    fn box_on_floor() -> (Scene, [DVec3; 4]) {
        let (mut b, white, light) = floor();
        let z = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        b.quad(
            [z(1., 1., 3.), z(1., 3., 3.), z(3., 3., 3.), z(3., 1., 3.)],
            light,
        );
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let foot = [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)]
            .map(|(x, y)| z(2.0 + c * x - s * y, 2.0 + s * x + c * y, 0.0));
        let up = DVec3::new(0.0, 0.0, 1.0);
        for k in 0..4 {
            let (p, q) = (foot[k], foot[(k + 1) % 4]);
            b.quad([p, q, q + up, p + up], white); // outward: counter-clockwise seen outside
        }
        b.quad(
            [foot[0] + up, foot[1] + up, foot[2] + up, foot[3] + up],
            white,
        );
        (b.build().unwrap(), foot)
    }

    /// Signed area test: > 0 when `p` is left of a → b (inside a counter-clockwise polygon).
    fn left(a: DVec3, b: DVec3, p: DVec3) -> f64 {
        (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x)
    }

    /// Contact points are snapped to 1e-9 of the face (4 units here): within 1e-8 of the
    /// footprint's sides is "on the line", neither inside nor outside.
    const ON_LINE: f64 = 1e-8;

    /// `x` lies strictly inside the footprint.
    fn inside(foot: &[DVec3; 4], x: DVec3) -> bool {
        (0..4).all(|k| left(foot[k], foot[(k + 1) % 4], x) > ON_LINE)
    }

    /// `x` lies strictly outside the footprint.
    fn outside(foot: &[DVec3; 4], x: DVec3) -> bool {
        (0..4).any(|k| left(foot[k], foot[(k + 1) % 4], x) < -ON_LINE)
    }

    /// Some corner of the triangle lies strictly inside the footprint and another strictly
    /// outside.
    fn straddles(foot: &[DVec3; 4], corners: &[DVec3; 3]) -> bool {
        corners.iter().any(|&c| inside(foot, c)) && corners.iter().any(|&c| outside(foot, c))
    }

    #[test]
    fn contact_lines_of_a_box_on_a_floor_become_edges() {
        let (scene, foot) = box_on_floor();
        let (split, stats) = split_contacts(&scene);
        split.validate().unwrap();
        assert_eq!(stats.faces_split, 2, "the floor's two triangles: {stats:?}");
        // The footprint crosses the diagonal: its four sides give 4 segments on one half and
        // 2 on the other (the two sides the diagonal cuts are counted on both).
        assert_eq!(stats.segments, 6, "{stats:?}");
        let area = |s: &Scene, floor: bool| {
            (0..s.triangles.len())
                .filter(|&t| {
                    let n = s.triangles[t].vertices.map(|v| s.positions[v as usize]);
                    floor == (n.iter().all(|p| p.z == 0.0))
                })
                .map(|t| s.triangle_area(t))
                .sum::<f64>()
        };
        // The floor keeps its area and its facing (every new triangle faces up).
        assert!((area(&split, true) - 16.0).abs() < 1e-9);
        assert!((area(&split, false) - area(&scene, false)).abs() < 1e-9);
        for t in &split.triangles {
            let [a, b, c] = t.vertices.map(|v| split.positions[v as usize]);
            if a.z == 0.0 && b.z == 0.0 && c.z == 0.0 {
                assert!((b - a).cross(c - a).z > 0.0);
            }
        }
        // No patch of the bake straddles the footprint: each floor patch is wholly inside or
        // wholly outside it (corners on the footprint's sides count as either).
        let out = pipeline::solve_scene(&scene, &Settings::default()).unwrap();
        let p = &out.patches;
        let mut under = 0;
        for i in 0..p.len() {
            let corners = p.corners(i);
            if !corners.iter().all(|c| c.z == 0.0) {
                continue;
            }
            assert!(
                !straddles(&foot, &corners),
                "floor patch {i} straddles the footprint: {corners:?}"
            );
            under += usize::from(inside(&foot, p.centroid[i]));
            // Inside the footprint: buried (nobody sees it); outside: visible.
            let expected = if inside(&foot, p.centroid[i]) {
                0.0
            } else {
                1.0
            };
            assert_eq!(out.visible_fraction[i], expected, "patch {i}");
        }
        assert!(under > 0, "some floor patches lie under the box");
        // Without the split, some patch straddles (what the split is for).
        let none = Settings {
            discontinuities: Discontinuities::None,
            ..Settings::default()
        };
        let out = pipeline::solve_scene(&scene, &none).unwrap();
        assert!((0..out.patches.len()).any(|i| {
            let c = out.patches.corners(i);
            c.iter().all(|x| x.z == 0.0) && straddles(&foot, &c)
        }));
    }

    #[test]
    fn split_patches_cut_along_the_footprint_and_stay_conforming() {
        let (scene, foot) = box_on_floor();
        let patches = crate::mesh::subdivide(&scene, 0.7, 0.0).unwrap();
        let lines = contact_lines(&scene).expect("the box touches the floor");
        let (cut, parent, stats) = split_patches(&lines, &patches, 6.0).unwrap();
        cut.validate().unwrap();
        assert!(
            stats.faces_split > 0 && stats.triangles == cut.len(),
            "{stats:?}"
        );
        assert_eq!(parent.len(), cut.len());
        // Each patch's pieces tile it: the same area, material, normal and source triangle.
        let mut area = vec![0.0; patches.len()];
        for (k, &i) in parent.iter().enumerate() {
            let i = i as usize;
            area[i] += cut.area[k];
            assert_eq!(cut.source_triangle[k], patches.source_triangle[i]);
            assert_eq!(cut.material[k], patches.material[i]);
            assert!(
                cut.normal[k].dot(patches.normal[i]) > 1.0 - 1e-12,
                "piece {k}"
            );
        }
        // Contact points are snapped to 1e-9 of the patch (`Face::to_2d`), so the pieces' area
        // may differ from their patch's by a few times that.
        for (i, a) in area.iter().enumerate() {
            let want = patches.area[i];
            assert!((a - want).abs() < 1e-8 * want, "patch {i}: {a} vs {want}");
        }
        // No floor piece straddles the footprint (some patch did before).
        let on_floor = |p: &Patches, i: usize| p.corners(i).iter().all(|c| c.z == 0.0);
        let straddling =
            |p: &Patches| (0..p.len()).any(|i| on_floor(p, i) && straddles(&foot, &p.corners(i)));
        assert!(straddling(&patches));
        assert!(!straddling(&cut));
        // Conforming: an edge of one floor piece only is on the floor's border (a point
        // inserted into one side of an edge and not the other would leave two such edges).
        let mut edges: HashMap<(u32, u32), usize> = HashMap::new();
        for i in (0..cut.len()).filter(|&i| on_floor(&cut, i)) {
            let t = cut.triangles[i];
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        for ((a, b), n) in edges {
            let (p, q) = (cut.positions[a as usize], cut.positions[b as usize]);
            let border = |x: f64, y: f64| [x, y].iter().any(|&v| v == 0.0 || v == 4.0);
            let on_border = (p.x == q.x && border(p.x, -1.0)) || (p.y == q.y && border(-1.0, p.y));
            assert!(
                n == 2 || (n == 1 && on_border),
                "edge {p} – {q} in {n} pieces"
            );
        }
    }

    #[test]
    fn the_hierarchical_display_is_cut_along_the_contact_lines() {
        // The hierarchy's roots stay the input triangles; the gathered display's faces stop at
        // the footprint, so no vertex's light is interpolated across it.
        let (scene, foot) = box_on_floor();
        let settings = |discontinuities| Settings {
            method: pipeline::Method::Hierarchical,
            discontinuities,
            ..Settings::default()
        };
        let straddling = |out: &pipeline::Outcome| {
            let b = &out.baked;
            b.faces.iter().any(|f| {
                let c = f.map(|v| DVec3::from(b.positions[v as usize]));
                c.iter().all(|x| x.z == 0.0) && straddles(&foot, &c)
            })
        };
        let out = pipeline::solve_scene(&scene, &settings(Discontinuities::Auto)).unwrap();
        let stats = out
            .report
            .display_contacts
            .as_ref()
            .expect("the display was cut");
        assert!(stats.faces_split > 0, "{stats:?}");
        assert!(out.report.contacts.is_none(), "the roots were not cut");
        assert!(!straddling(&out));
        let out = pipeline::solve_scene(&scene, &settings(Discontinuities::None)).unwrap();
        assert!(out.report.display_contacts.is_none());
        assert!(straddling(&out));
    }

    #[test]
    fn crossing_segments_are_cut_at_one_shared_point() {
        // An X: four pieces meeting at the crossing.
        let x = split_at_crossings(&[[[0.0, 0.0], [1.0, 1.0]], [[0.0, 1.0], [1.0, 0.0]]]);
        assert_eq!(x.len(), 4, "{x:?}");
        assert!(x.iter().all(|s| s.contains(&[0.5, 0.5])));
        // A T (one ends on the other): the other is cut at that very end.
        let t = split_at_crossings(&[[[0.0, 0.0], [1.0, 0.0]], [[0.3, 1.0], [0.3, 1e-12]]]);
        assert_eq!(t.len(), 3, "{t:?}");
        assert!(t.contains(&[[0.0, 0.0], [0.3, 1e-12]]));
        // Parallel, and meeting at their ends: unchanged.
        let p = [
            [[0.0, 0.0], [1.0, 0.0]],
            [[0.0, 0.5], [1.0, 0.5]],
            [[1.0, 0.5], [0.2, 0.9]],
        ];
        assert_eq!(split_at_crossings(&p).len(), 3);
    }

    #[test]
    fn nearly_coincident_contact_lines_triangulate_without_panicking() {
        // One face of LibreQuake's e1m2 (in its own frame, longest edge 1): the same contact
        // line found from several faces, as a chain of pieces and as one segment along it
        // whose end is 1e-9 off the chain's. spade's own splitting of crossing constraints
        // failed an internal assertion here (`add_constraint_and_split`); the face must be
        // cut, its pieces covering it exactly.
        let v = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        let face = Face::from_corners([
            v(0.0, 0.0),
            v(1.0, 0.0),
            v(0.05882352963089943, 0.23529411759227514),
        ]);
        let (a, b) = (
            v(0.5147058824077249, 0.05882352963089943),
            v(0.397058823145926, 0.08823529444634914),
        );
        let c = v(0.16176470555365086, 0.147058823145926);
        let (far, near) = (
            v(0.04411764722317457, 0.1764705879613757),
            v(0.7499999990686774, 0.0),
        );
        let segments = [
            [v(0.75, 0.0), a],
            [v(0.5, 0.0), a],
            [a, v(0.5, 0.0)],
            [a, b],
            [v(0.375, 0.0), b],
            [b, v(0.375, 0.0)],
            [b, c],
            [c, v(0.125, 0.0)],
            [far, near],
        ];
        let edge_points = [
            v(0.75, 0.0),
            v(0.5, 0.0),
            v(0.375, 0.0),
            v(0.125, 0.0),
            near,
            far,
        ];
        let pieces = face
            .triangulate(&segments, &edge_points, false)
            .expect("the face is cut");
        let area: f64 = pieces
            .iter()
            .map(|[p, q, r]| 0.5 * (q - p).cross(r - p).z)
            .sum();
        // The face's area is 0.5 · 1 · 0.2353; rounding of the pieces' corners (snapped to
        // 1e-9 of the face) moves it by far less than 1e-9.
        assert!(
            (area - 0.5 * 0.23529411759227514).abs() < 1e-9,
            "area {area}"
        );
        assert!(pieces.iter().all(|[p, q, r]| (q - p).cross(r - p).z >= 0.0));
    }

    #[test]
    fn a_light_mounted_under_a_ceiling_outlines_itself_on_it() {
        // A 4 × 4 ceiling (facing down) and a 1 × 1 light (facing down) below it: within 1e-3
        // of the room's extent (6.9e-3 here), or within 5 % of the light's width (its
        // triangles' smallest altitude, 0.71: 3.5e-2), the light's outline becomes edges of
        // the ceiling and the light itself is not split. 0.1 below, it is too far for either,
        // but within the light's width and 1/64 of the extent (0.108): a near shadow, and its
        // silhouette alone (not its diagonal) becomes edges of the ceiling. 0.2 below, nothing.
        for (gap, mounted) in [(4e-4, true), (0.02, true), (0.1, true), (0.2, false)] {
            let (mut b, white, light) = floor();
            crate::test_support::ceiling_with_mounted_light(
                &mut b,
                (white, light),
                4.0,
                gap,
                [1.5, 1.2],
            );
            let scene = b.build().unwrap();
            let (split, stats) = split_contacts(&scene);
            split.validate().unwrap();
            if !mounted {
                assert_eq!(stats.faces_split, 0, "gap {gap}: {stats:?}");
                continue;
            }
            assert_eq!(
                stats.faces_split, 2,
                "gap {gap}: the ceiling's triangles only: {stats:?}"
            );
            let mut diagonal = 0;
            for t in &split.triangles {
                let c = t.vertices.map(|v| split.positions[v as usize]);
                if c.iter().all(|p| p.z == 4.0) {
                    let centroid = (c[0] + c[1] + c[2]) / 3.0;
                    let under = centroid.x > 1.5
                        && centroid.x < 2.5
                        && centroid.y > 1.2
                        && centroid.y < 2.2;
                    // Snapped to 1e-9 of the face (4 units): 1e-8 is "on the outline".
                    for p in c {
                        let strictly_in = p.x > 1.5 + 1e-8
                            && p.x < 2.5 - 1e-8
                            && p.y > 1.2 + 1e-8
                            && p.y < 2.2 - 1e-8;
                        let strictly_out = p.x < 1.5 - 1e-8
                            || p.x > 2.5 + 1e-8
                            || p.y < 1.2 - 1e-8
                            || p.y > 2.2 + 1e-8;
                        assert!(
                            if under { !strictly_out } else { !strictly_in },
                            "gap {gap}: {c:?}"
                        );
                    }
                    // The mounted light's outline includes its triangles' shared diagonal; the
                    // near shadow's is the silhouette alone.
                    let on_diagonal = |p: DVec3| {
                        (p.y - p.x + 0.3).abs() < 1e-8 && p.x > 1.5 - 1e-8 && p.x < 2.5 + 1e-8
                    };
                    for k in 0..3 {
                        let (p, q) = (c[k], c[(k + 1) % 3]);
                        diagonal += (on_diagonal(p) && on_diagonal(q)) as usize;
                    }
                }
            }
            assert_eq!(
                diagonal > 0,
                gap < 0.1,
                "gap {gap}: {diagonal} edges on the diagonal"
            );
        }
    }

    #[test]
    fn scenes_without_contacts_are_unchanged() {
        let scene = crate::validation::scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        let (split, stats) = split_contacts(&scene);
        assert_eq!(split.triangles, scene.triangles);
        assert_eq!(split.positions, scene.positions);
        assert_eq!(stats.faces_split, 0);
        // A room's walls meet its floor only along the floor's border: no split either.
        let mut b = SceneBuilder::new();
        let m = b.material("white", [0.5; 3], [1.0; 3]);
        add_box(&mut b, DVec3::ZERO, DVec3::ONE, true, m);
        let room = b.build().unwrap();
        assert_eq!(split_contacts(&room).1.faces_split, 0);
    }
}
