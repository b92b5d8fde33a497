//! The sun's shadow edges as lines of the display ([`sun_lines`]): where an edge of the scene
//! casts the edge of a sun patch (a window frame's on the floor, a desk's on the carpet), the
//! irradiance jumps from the sun's full E_sun·cosθ to none across a penumbra only
//! `distance × 2 tan(0.265°)` wide (2.8 cm at 3 m). Vertex colours interpolated across a
//! triangle that such an edge crosses show a ramp as wide as the triangle, and a sawtooth where
//! the edge crosses many; no number of midpoint splits follows it exactly. These lines put
//! output edges along both sides of each penumbra instead, so the triangles between them carry
//! the ramp and those beside them are wholly lit or wholly shaded (discontinuity meshing for a
//! directional source: Heckbert, "Discontinuity meshing for radiosity", Eurographics Workshop
//! on Rendering 1992; Lischinski, Tampieri & Greenberg, IEEE CG&A 1992, the D1/D2 lines of an
//! area source's penumbra, here for an edge and a disc).
//!
//! For a straight edge e and the sun's disc (direction s, angular radius α), the penumbra is
//! bounded by the two planes through e tangent to the disc: normals n = cos ψ·v ± sin ψ·u, with
//! u the unit part of s across e, v = e × u and sin ψ = sin α / |s × e|. Each line is the
//! edge projected onto the receiver's plane along the direction of its plane nearest s.
//!
//! Which edges: an edge of the scene is a candidate unless exactly two triangles share it and
//! both face the sun alike and pass it alike (a crease inside a lit or a shaded surface casts
//! nothing; the edge between a pane and its wall does). Points
//! along a candidate (one every [`SAMPLE_SPACING`] of the extent) are traced away from the sun
//! to the surface their shadow falls on, and the line is kept where the share of the sun's
//! centre seen on one side of it ([`SIDE`] beside it) and on the other differ by [`STEP`] or
//! more (a pane passes its transmittance t, an opaque face none): the test that the edge
//! is lit, that it is a silhouette from the sun and that nothing else already shades the
//! receiver there. A run of samples falling on one plane gives one line pair, which goes to every
//! triangle of that plane it crosses ([`split_patches`](super::split_patches) clips it to each
//! patch). Every choice is ordered by the edges' vertex indices, so the lines are the same for
//! any thread count.

use glam::DVec3;
use rayon::prelude::*;

use crate::scene::{Scene, NO_TWIN};
use crate::visibility::{Visibility, NONE};

/// Spacing of the points traced along a candidate edge, as a fraction of the scene's extent
/// (7.5 cm in a 30 m office): a line's end is placed to within half of it where its shadow
/// passes from one surface to another.
pub const SAMPLE_SPACING: f64 = 2.5e-3;

/// Points traced along one edge, at most.
pub const MAX_SAMPLES: usize = 64;

/// How far beside a shadow line its two sides are tested, as a fraction of the extent (6 mm in
/// a 30 m office): far above rounding, below the patches' sizes.
pub const SIDE: f64 = 2e-4;

/// Half the distance between a penumbra's two lines, at least, as a fraction of the extent:
/// a shadow cast from closer than this allows is drawn as a ramp this wide (1.5 mm in a 30 m
/// office), not as two lines the triangulation could not keep apart.
pub const MIN_HALF_WIDTH: f64 = 5e-5;

/// A face faces the sun where n·s exceeds this: one parallel to the sun (a wall beside its
/// rays, n·s zero but for rounding) does not, so it and a face turned away share no
/// silhouette.
const FACING: f64 = 1e-9;

/// The least jump of the share of the sun's centre seen (its transmittance: 1 unoccluded, a
/// pane's t through a pane, 0 behind an opaque face) across a line for it to be drawn.
pub const STEP: f64 = 0.05;

/// A receiver whose plane is within this cosine of edge-on to the sun is not given lines: it
/// gets almost none of the sun's light to show.
const GRAZING: f64 = 0.02;

/// An edge within this sine of parallel to the sun casts a shadow line too short to draw.
const ALONG_SUN: f64 = 0.05;

/// The sun's shadow lines on each scene triangle (scene coordinates, on the triangle's plane),
/// for the sun in unit direction `sun` (toward it) with angular radius `half_angle` radians,
/// traced against the scene with its panes' transmittance. See the module documentation.
/// `None` when no line is found.
pub fn sun_lines(scene: &Scene, sun: DVec3, half_angle: f64) -> Option<Vec<Vec<[DVec3; 2]>>> {
    sun_lines_on(scene, sun, half_angle, &|_| true)
}

/// [`sun_lines`] cast by the edges of the triangles `on` picks alone (an edge counts as its
/// lowest-numbered triangle's): the lines of a sample of the edges, for an estimate.
pub fn sun_lines_on(
    scene: &Scene,
    sun: DVec3,
    half_angle: f64,
    on: &(dyn Fn(usize) -> bool + Sync),
) -> Option<Vec<Vec<[DVec3; 2]>>> {
    let n = scene.triangles.len();
    let (lo, hi) = scene.bounds();
    let extent = (hi - lo).length();
    if n == 0 || extent <= 0.0 || !sun.is_finite() {
        return None;
    }
    let vis = &scene.visibility();
    let normals: Vec<DVec3> = (0..n).map(|t| unit_normal(scene, t)).collect();
    let mut edges = candidate_edges(scene, &normals, sun);
    edges.retain(|e| on(e.triangles[0] as usize));
    let found: Vec<Vec<Line>> = edges
        .par_iter()
        .map(|e| edge_lines(scene, vis, &normals, e, sun, half_angle, extent))
        .collect();
    on_receivers(scene, vis, &normals, found, extent)
}

/// The lines `found` (each edge's) on each scene triangle of their planes they may cross
/// ([`receivers`]); `None` when there are none.
pub(super) fn on_receivers(
    scene: &Scene,
    vis: &Visibility,
    normals: &[DVec3],
    found: Vec<Vec<Line>>,
    extent: f64,
) -> Option<Vec<Vec<[DVec3; 2]>>> {
    let mut lines = vec![Vec::new(); scene.triangles.len()];
    let mut any = false;
    for line in found.into_iter().flatten() {
        for t in receivers(scene, vis, normals, &line, extent) {
            for seg in line.segments {
                lines[t as usize].push(seg);
            }
            any = true;
        }
    }
    any.then_some(lines)
}

/// An edge of the scene: its two vertex indices (the lower first) and the triangles that have it.
pub(super) struct Edge {
    pub(super) vertices: [u32; 2],
    pub(super) triangles: Vec<u32>,
}

/// A penumbra's two lines on one receiver plane: the plane (a point on it, its unit normal)
/// and the two segments.
pub(super) struct Line {
    pub(super) point: DVec3,
    pub(super) normal: DVec3,
    pub(super) segments: [[DVec3; 2]; 2],
}

/// The unit front normal of triangle `t` (counter-clockwise winding).
pub(super) fn unit_normal(scene: &Scene, t: usize) -> DVec3 {
    let [a, b, c] = scene.triangles[t]
        .vertices
        .map(|v| scene.positions[v as usize]);
    (b - a).cross(c - a).normalize_or_zero()
}

/// The scene's edges that may cast a sun shadow line, in the order of their vertex indices:
/// all but those shared by exactly two surfaces (a twin pair counting once) that face the sun
/// alike and pass it alike (a pane beside a wall does not).
fn candidate_edges(scene: &Scene, normals: &[DVec3], sun: DVec3) -> Vec<Edge> {
    let mut edges = edges(scene);
    edges.retain(|e| {
        let [t0, t1] = e.triangles[..] else {
            return true;
        };
        let (f0, f1) = (normals[t0 as usize].dot(sun), normals[t1 as usize].dot(sun));
        let t =
            |t: u32| scene.materials[scene.triangles[t as usize].material as usize].transmittance;
        (f0 > FACING) != (f1 > FACING) || t(t0) != t(t1)
    });
    edges
}

/// The scene's edges in the order of their vertex indices, each with the triangles that have
/// it (a twin pair counting once, by its earlier triangle).
pub(super) fn edges(scene: &Scene) -> Vec<Edge> {
    let mut all: Vec<(u32, u32, u32)> = Vec::with_capacity(3 * scene.triangles.len());
    for (t, tri) in scene.triangles.iter().enumerate() {
        // A twin pair is one surface: its earlier triangle stands for it.
        if scene
            .twin
            .get(t)
            .is_some_and(|&w| w != NO_TWIN && (w as usize) < t)
        {
            continue;
        }
        let v = tri.vertices;
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            all.push((a.min(b), a.max(b), t as u32));
        }
    }
    all.sort_unstable();
    let mut edges = Vec::new();
    for group in all.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        let triangles: Vec<u32> = group.iter().map(|g| g.2).collect();
        edges.push(Edge {
            vertices: [group[0].0, group[0].1],
            triangles,
        });
    }
    edges
}

/// One traced point of an edge: its parameter along the edge, the receiver triangle and the
/// point its shadow falls on, and how far that is.
pub(super) struct Sample {
    pub(super) t: f64,
    pub(super) receiver: u32,
    pub(super) at: DVec3,
    pub(super) distance: f64,
}

/// A run of an edge's traced points whose shadows fall on one plane: the plane (through its
/// first receiver's corner, not the traced hit, whose f32 rounding it would inherit), the
/// part of the edge the run covers (parameters, half a sample's spacing past its ends), and
/// the mean distance of its ends' shadows.
pub(super) struct Run {
    pub(super) origin: DVec3,
    pub(super) normal: DVec3,
    pub(super) t: [f64; 2],
    pub(super) distance: f64,
}

/// The runs of `samples` (an edge's traced points, in order along it; `None` where a point
/// casts no line) whose shadows fall on one plane.
pub(super) fn plane_runs(
    scene: &Scene,
    normals: &[DVec3],
    samples: &[Option<Sample>],
    extent: f64,
) -> Vec<Run> {
    let k = samples.len();
    let half = 0.5 / k as f64;
    let mut runs = Vec::new();
    let mut i = 0;
    while i < k {
        let Some(first) = &samples[i] else {
            i += 1;
            continue;
        };
        let plane = |s: &Sample| {
            let n = normals[s.receiver as usize];
            s.receiver == first.receiver
                || (n.dot(normals[first.receiver as usize]) > 1.0 - 1e-6
                    && n.dot(s.at - first.at).abs() < 1e-5 * extent)
        };
        let mut j = i;
        while j + 1 < k && samples[j + 1].as_ref().is_some_and(plane) {
            j += 1;
        }
        let last = samples[j].as_ref().unwrap_or(first);
        let receiver = &scene.triangles[first.receiver as usize];
        runs.push(Run {
            origin: scene.positions[receiver.vertices[0] as usize],
            normal: normals[first.receiver as usize],
            t: [(first.t - half).max(0.0), (last.t + half).min(1.0)],
            distance: 0.5 * (first.distance + last.distance),
        });
        i = j + 1;
    }
    runs
}

/// The penumbra lines cast by edge `e` (see the module documentation), one per run of its
/// traced points whose shadow falls on one plane and is a real sun edge there.
fn edge_lines(
    scene: &Scene,
    vis: &Visibility,
    normals: &[DVec3],
    e: &Edge,
    sun: DVec3,
    half_angle: f64,
    extent: f64,
) -> Vec<Line> {
    let [a, b] = e.vertices.map(|v| scene.positions[v as usize]);
    let length = (b - a).length();
    let dir = (b - a) / length;
    let across = sun - sun.dot(dir) * dir;
    let sin_beta = across.length();
    if length <= 0.0 || sin_beta < ALONG_SUN {
        return Vec::new();
    }
    let k = ((length / (SAMPLE_SPACING * extent)).ceil() as usize).clamp(1, MAX_SAMPLES);
    let side = SIDE * extent;
    let samples: Vec<Option<Sample>> = (0..k)
        .map(|i| {
            let t = (i as f64 + 0.5) / k as f64;
            let x = a + (b - a) * t;
            // Traced from `side` past the edge: not into a face that meets it there (its
            // other triangle, or a neighbour's edge along it that is not shared).
            let start = x - sun * side;
            let hit = vis.closest_hit(start, -sun, f64::INFINITY, e.triangles[0])?;
            let r = hit.triangle as usize;
            let n = normals[r];
            if n.dot(sun) < GRAZING || hit.t < side {
                return None;
            }
            let at = start - sun * hit.t;
            // The line's direction on the receiver, and the two sides of it.
            let along = dir - sun * (dir.dot(n) / sun.dot(n));
            let beside = n.cross(along).normalize_or_zero() * side;
            // Each side is a point of the receiver's surface (not past the edge of a floor
            // where its wall stands beside the sun's rays), and its share of the sun.
            let on_surface = |p: DVec3| {
                vis.closest_hit(p + n * side, -n, 2.0 * side, NONE)
                    .is_some_and(|h| normals[h.triangle as usize].dot(n) > 1.0 - 1e-6)
            };
            // Traced from `side` toward the sun: off the surface, on the same side of the line
            // (a point lifted along the normal would see past the edge a little further on).
            let seen = |p: DVec3| vis.transmittance(p + sun * side, sun, f64::INFINITY, r as u32);
            let (p, q) = (at + beside, at - beside);
            (on_surface(p) && on_surface(q) && (seen(p) - seen(q)).abs() >= STEP).then_some(
                Sample {
                    t,
                    receiver: r as u32,
                    at,
                    distance: hit.t + side,
                },
            )
        })
        .collect();
    // The two tangent planes' directions nearest the sun (module documentation).
    let u = across / sin_beta;
    let v = dir.cross(u);
    plane_runs(scene, normals, &samples, extent)
        .into_iter()
        .map(|run| {
            // The penumbra's half-width at this distance, at least MIN_HALF_WIDTH.
            let spread = half_angle.max(MIN_HALF_WIDTH * extent / run.distance);
            let sin_psi = (spread.sin() / sin_beta).min(1.0);
            let cos_psi = (1.0 - sin_psi * sin_psi).sqrt();
            let (origin, n) = (run.origin, run.normal);
            let [p, q] = run.t.map(|t| a + (b - a) * t);
            let segments = [1.0, -1.0].map(|sign| {
                let np = cos_psi * v + sign * sin_psi * u;
                let d = (sun - sun.dot(np) * np).normalize();
                let onto = |x: DVec3| x - d * ((x - origin).dot(n) / d.dot(n));
                [onto(p), onto(q)]
            });
            Line {
                point: origin,
                normal: n,
                segments,
            }
        })
        .collect()
}

/// The triangles of `line`'s plane whose boxes meet its segments' box, and their twins: the
/// faces it may cross.
fn receivers(
    scene: &Scene,
    vis: &Visibility,
    normals: &[DVec3],
    line: &Line,
    extent: f64,
) -> Vec<u32> {
    let pts = line.segments.as_flattened();
    let lo = pts.iter().fold(DVec3::INFINITY, |m, &p| m.min(p));
    let hi = pts.iter().fold(DVec3::NEG_INFINITY, |m, &p| m.max(p));
    let mut found = Vec::new();
    vis.overlapping(lo, hi, [NONE; 2], |t| {
        let n = normals[t as usize];
        let c = scene.positions[scene.triangles[t as usize].vertices[0] as usize];
        if n.dot(line.normal).abs() > 1.0 - 1e-6 && n.dot(c - line.point).abs() < 1e-5 * extent {
            found.push(t);
        }
        true
    });
    let twins: Vec<u32> = found
        .iter()
        .filter_map(|&t| scene.twin.get(t as usize).copied())
        .filter(|&w| w != NO_TWIN)
        .collect();
    found.extend(twins);
    found.sort_unstable();
    found.dedup();
    found
}
