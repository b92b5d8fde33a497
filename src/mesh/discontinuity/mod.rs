//! Discontinuities of the radiance as mesh edges, before patching: the contact lines, where
//! one face touches or crosses another face's plane or is mounted on it (a block standing on
//! the floor, a leg under a table top, a light mounted just below the ceiling: [`contact`]),
//! and the outlines of near shadows ([`near_shadow`]). The line becomes an edge of the face it
//! lies on. The borders of the lamps' near penumbrae ([`lamp`]) and, under a sun, of its
//! penumbrae ([`sun`]) cut the hierarchical display as well.
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
//!   hierarchical display ([`contact_lines`], [`display::split_patches`]): a display face
//!   keeps its element's radiance, and cut small beside a near occluder it would take the
//!   gather's near hits off their one bounce further.
//!
//! The segments are clipped to A; those along A's own edges (a wall meeting the floor at the
//! floor's border) are dropped. A is then re-triangulated with them as constraints (a
//! constrained Delaunay triangulation, the `spade` crate), and the points where segments end
//! on A's edges are inserted into the face across each edge as well, so the result stays
//! conforming (`face`: the plane's frame, the clipping and the triangulation). Faces with no
//! contact are kept as they are.

use std::collections::HashMap;

use glam::DVec3;
use obvhs::aabb::Aabb;
use obvhs::bvh2::builder::build_bvh2;
use obvhs::BvhBuildParams;
use rayon::prelude::*;

use crate::scene::{Scene, SceneTriangle, NO_TWIN, ZERO_AREA_RELATIVE};
use face::Face;
use near_shadow::silhouettes;

pub mod contact;
pub mod display;
mod face;
pub mod lamp;
pub mod near_shadow;
pub mod sun;

pub use contact::{MOUNTED, NEAR, TOUCH};
pub use display::{split_patches, Split};
pub use near_shadow::NEAR_SHADOW;
pub use sun::{sun_lines, sun_lines_on};

/// Which discontinuities of the radiance become mesh edges before patching.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Discontinuities {
    /// `contacts` for the matrix method. For the hierarchical one, contact lines become
    /// edges of the display only ([`split_patches`], after the solve, when the final gather
    /// runs): its roots stay the input triangles, as contact lines inside a large face (a
    /// hall's floor under hundreds of table legs) leave long thin triangles between them that
    /// would cost the generated hall more than twice its links and its time, while the gather
    /// at the display's vertices needs only the display's faces to stop at the contacts.
    /// The display is cut along the lamps' near penumbrae ([`lamp`]) and, under a sun, its
    /// penumbrae ([`sun_lines`]) too.
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
                "contacts for the matrix method; for the hierarchical, contact lines (and the \
                 lamps' near shadows' and the sun's shadow edges) cut the display's faces only"
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

/// The largest gap (scene units) at which the scene triangle `b`, parallel to the scene
/// triangle `a` and in front of it, counts as mounted on it: [`NEAR`] × the scene's
/// `extent`, or [`MOUNTED`] × the narrower one's width (its smallest altitude), the rule the
/// contact lines are cut by.
pub fn mounted_gap(scene: &Scene, a: usize, b: usize, extent: f64) -> f64 {
    Face::new(scene, a)
        .gaps(Some(&Face::new(scene, b)), extent)
        .0
}

/// The contact segments on each scene triangle (see the module documentation; touching,
/// crossing and mounted faces, not the near shadows), in scene coordinates on the triangle's
/// plane; `None` when the scene has fewer than two triangles or no contact. In a two-sided
/// scene a twin has its front's segments (found on the fronts alone: a pair is cut alike).
pub fn contact_lines(scene: &Scene) -> Option<Vec<Vec<[DVec3; 2]>>> {
    contact_lines_on(scene, &|_| true)
}

/// The lines that cut the hierarchical display ([`split_patches`]), on each scene triangle,
/// and how many of them are the lamps' and the sun's ([`display_lines_on`]).
pub struct DisplayLines {
    /// The segments on each scene triangle (scene coordinates, on its plane).
    pub lines: Vec<Vec<[DVec3; 2]>>,
    /// Of them, the lamps' penumbra lines ([`lamp::lamp_lines_on`]).
    pub lamp: usize,
    /// Of them, the sun's penumbra lines ([`sun_lines`]).
    pub sun: usize,
}

/// The lines that cut the hierarchical display ([`split_patches`]): the contact lines, the
/// lamps' penumbra lines of edges near the surfaces they shade ([`lamp::lamp_lines_on`]) and,
/// under a sun (its unit direction, toward it, and its angular radius in radians) its
/// penumbra lines ([`sun_lines`]); of the triangles `on` picks alone, and their edges
/// ([`contact_lines_on`], [`sun::sun_lines_on`]). `None` when there are none.
pub fn display_lines_on(
    scene: &Scene,
    sun: Option<(DVec3, f64)>,
    on: &(dyn Fn(usize) -> bool + Sync),
) -> Option<DisplayLines> {
    let mut out = DisplayLines {
        lines: contact_lines_on(scene, on)
            .unwrap_or_else(|| vec![Vec::new(); scene.triangles.len()]),
        lamp: 0,
        sun: 0,
    };
    let mut add = |found: Option<Vec<Vec<[DVec3; 2]>>>| {
        let found = found?;
        let count = found.iter().map(Vec::len).sum();
        out.lines
            .iter_mut()
            .zip(found)
            .for_each(|(l, s)| l.extend(s));
        Some(count)
    };
    out.lamp = add(lamp::lamp_lines_on(scene, on)).unwrap_or(0);
    out.sun =
        add(sun.and_then(|(sun, radius)| sun::sun_lines_on(scene, sun, radius, on))).unwrap_or(0);
    out.lines.iter().any(|l| !l.is_empty()).then_some(out)
}

/// [`contact_lines`] on the triangles `on` picks alone (the others get none): the segments of
/// a sample of the triangles, at that share of the cost.
pub fn contact_lines_on(
    scene: &Scene,
    on: &(dyn Fn(usize) -> bool + Sync),
) -> Option<Vec<Vec<[DVec3; 2]>>> {
    let (lo, hi) = scene.bounds();
    if !scene.twin.is_empty() {
        let (fronts, base) = fronts(scene);
        let faces: Vec<Face> = (0..base.triangles.len())
            .map(|t| Face::new(&base, t))
            .collect();
        let found = lines_on(&base, &faces, (hi - lo).length(), false, &|k| on(fronts[k]))?;
        let mut lines = vec![Vec::new(); scene.triangles.len()];
        for (k, segs) in found.into_iter().enumerate() {
            let t = fronts[k];
            if scene.twin[t] != NO_TWIN {
                lines[scene.twin[t] as usize] = segs.clone();
            }
            lines[t] = segs;
        }
        return Some(lines);
    }
    let faces: Vec<Face> = (0..scene.triangles.len())
        .map(|t| Face::new(scene, t))
        .collect();
    lines_on(scene, &faces, (hi - lo).length(), false, on)
}

/// [`contact_lines`] for the scene's `faces` (one per triangle) and its extent, with the
/// near shadows' silhouettes ([`NEAR_SHADOW`]) when `near_shadows`.
fn lines_on(
    scene: &Scene,
    faces: &[Face],
    extent: f64,
    near_shadows: bool,
    on: &(dyn Fn(usize) -> bool + Sync),
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
            if !on(a) {
                return found;
            }
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
/// when it has none. A two-sided scene's fronts (the faces without a twin, and the first of
/// each pair) are cut, and each piece of a front with a twin gets a twin of its own (its
/// corners reversed, the twin's material and texture map), appended after the fronts' pieces
/// in their order: twins stay pairs of identical faces, and cutting then making every face
/// two-sided gives the scene that making it two-sided then cutting does.
pub fn split_contacts(scene: &Scene) -> (Scene, ContactStats) {
    if scene.twin.is_empty() {
        let (out, stats, _) = split_one_sided(scene);
        return (out, stats);
    }
    let (fronts, base) = fronts(scene);
    let (mut out, mut stats, source) = split_one_sided(&base);
    let pieces = out.triangles.len();
    out.twin = vec![NO_TWIN; pieces];
    for i in 0..pieces {
        let back = scene.twin[fronts[source[i] as usize]];
        if back == NO_TWIN {
            continue;
        }
        let back = scene.triangles[back as usize];
        let [a, b, c] = out.triangles[i].vertices;
        out.triangles.push(SceneTriangle {
            vertices: [a, c, b],
            ..back
        });
        out.twin.push(i as u32);
        out.twin[i] = (out.triangles.len() - 1) as u32;
    }
    stats.triangles = out.triangles.len();
    (out, stats)
}

/// A two-sided scene's fronts (the faces without a twin, and the first of each pair), and
/// the one-sided scene of them alone (their order kept).
fn fronts(scene: &Scene) -> (Vec<usize>, Scene) {
    let fronts: Vec<usize> = (0..scene.triangles.len())
        .filter(|&t| scene.twin[t] == NO_TWIN || (t as u32) < scene.twin[t])
        .collect();
    let mut base = scene.clone();
    base.triangles = fronts.iter().map(|&t| scene.triangles[t]).collect();
    base.twin = Vec::new();
    (fronts, base)
}

/// [`split_contacts`] for a one-sided scene, with each output triangle's input triangle.
fn split_one_sided(scene: &Scene) -> (Scene, ContactStats, Vec<u32>) {
    let n = scene.triangles.len();
    let mut stats = ContactStats {
        triangles: n,
        ..ContactStats::default()
    };
    let (lo, hi) = scene.bounds();
    let extent = (hi - lo).length();
    let faces: Vec<Face> = (0..n).map(|t| Face::new(scene, t)).collect();
    let Some(segments) = lines_on(scene, &faces, extent, true, &|_| true) else {
        return (scene.clone(), stats, (0..n as u32).collect());
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
    merge_edge_points(&mut on_edge, TOUCH * extent);

    // Re-triangulate the faces with segments or extra edge points.
    let mut positions = scene.positions.clone();
    let mut index: HashMap<[u64; 3], u32> = positions
        .iter()
        .enumerate()
        .map(|(i, p)| (bits(*p), i as u32))
        .collect();
    let mut triangles = Vec::with_capacity(n);
    let mut source = Vec::with_capacity(n);
    let min_area = ZERO_AREA_RELATIVE * extent * extent;
    for (a, tri) in scene.triangles.iter().enumerate() {
        let v = tri.vertices;
        let edge_points = points_on_edges(&on_edge, v);
        if segments[a].is_empty() && edge_points.is_empty() {
            triangles.push(*tri);
            source.push(a as u32);
            continue;
        }
        let segs: Vec<[DVec3; 2]> = (segments[a].iter())
            .map(|s| s.map(|p| shared_point(&on_edge, v, &faces[a], p, TOUCH * extent)))
            .collect();
        let pieces = faces[a].triangulate(&segs, &edge_points, false);
        let Some(pieces) = pieces else {
            triangles.push(*tri); // the triangulation failed: keep the face whole
            source.push(a as u32);
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
            source.push(a as u32);
        }
    }
    stats.triangles = triangles.len();
    let mut out = scene.clone();
    out.positions = positions;
    out.triangles = triangles;
    (out, stats, source)
}

/// Both faces on an edge find the points where segments cross it, each in its own frame: the
/// same point up to rounding (a contact line across a quad's diagonal, found from each of its
/// triangles, lands 10⁻⁹ of the scene apart). One point stands for each cluster within
/// `touch` (scene units), and [`shared_point`] moves the segments' ends to it, so the two
/// sides share it exactly rather than leaving a sliver between their two points.
fn merge_edge_points(on_edge: &mut HashMap<(u32, u32), Vec<DVec3>>, touch: f64) {
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
}

/// The point standing for `p` on the edge of `face` (vertex indices `v`) it lies on, after
/// [`merge_edge_points`]; `p` itself if it lies on none.
fn shared_point(
    on_edge: &HashMap<(u32, u32), Vec<DVec3>>,
    v: [u32; 3],
    face: &Face,
    p: DVec3,
    touch: f64,
) -> DVec3 {
    let Some(e) = face.edge_through(p, touch) else {
        return p;
    };
    let (a, b) = (v[e], v[(e + 1) % 3]);
    on_edge
        .get(&(a.min(b), a.max(b)))
        .and_then(|pts| pts.iter().find(|k| k.distance(p) <= touch))
        .copied()
        .unwrap_or(p)
}

/// The points registered on the edges of the triangle `v` (by its vertex indices, in
/// `on_edge`, keyed by the edge's two indices in increasing order).
pub(super) fn points_on_edges(
    on_edge: &HashMap<(u32, u32), Vec<DVec3>>,
    v: [u32; 3],
) -> Vec<DVec3> {
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

pub(super) fn bits(p: DVec3) -> [u64; 3] {
    [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]
}

#[cfg(test)]
mod tests;
