//! The lamps' near shadows as lines of the display ([`lamp_lines_on`]): where an edge close above
//! a surface hides a lamp from part of it (a partition's top over the desk it stands on, a
//! seat over the floor, a shelf board over the one below), the lamp's light on that surface
//! falls from all to none across a penumbra `h·w/D` wide (h the edge's height over the
//! surface, w the lamp's width across the edge, D its distance from the edge): 15 cm beside a
//! partition 45 cm high under a panel 0.6 m wide 1.8 m above its top. The light inside a
//! penumbra bends at its two borders and is nearly linear between; vertex colours interpolated across display triangles wider than the
//! penumbra show it as a ramp as wide as the triangle, at the wrong place, where a viewer sees
//! a soft but distinct shadow. These lines put output edges along both borders, so linear
//! interpolation between them follows the penumbra (discontinuity meshing of an area source:
//! Heckbert, "Discontinuity meshing for radiosity", Eurographics Workshop on Rendering 1992;
//! Lischinski, Tampieri & Greenberg, IEEE CG&A 1992, the D1 and D2 lines, here the two outer
//! ones of each edge and lamp).
//!
//! A lamp is a connected set of coplanar emitting triangles of one material (a panel's two
//! triangles, a window's pane). For a straight edge and a point L of the lamp, the shadow of
//! the edge on a receiver's plane is the edge projected from L (a central projection, which
//! keeps lines straight); the penumbra is bounded by the projections from the lamp's corners
//! that fall furthest out on either side, measured across the projection from the lamp's
//! centre.
//!
//! Which edges and lamps: the edge must be a silhouette seen from the lamp's centre (its
//! triangles do not all face the centre alike, or it has not exactly two), in front of the
//! lamp, and the lamp must give at least [`SIGNIFICANT`] of the light all lamps give there
//! unoccluded (by power × cosθ / d², the receiver's cosine aside), and be one of the
//! [`MAX_LAMPS_PER_EDGE`] that give the most. The edge's midpoint is
//! traced away from the lamp's centre to the surface its shadow falls on; the penumbra there
//! must be narrower than [`MAX_HALF_WIDTH`] × the scene's extent on each side (wider ones the
//! display's refinement follows with its own vertices). Then, as for the sun
//! ([`super::sun`]), points along the edge are traced, and a line pair is kept along each run
//! of them whose shadow falls on one plane and where the lamp's centre is seen on one side and
//! not on the other (the edge is lit, is a silhouette there, and nothing else already shades
//! the receiver). Every choice is ordered by the edges' vertex indices and the lamps' first
//! triangles, so the lines are the same for any thread count.

use glam::DVec3;
use rayon::prelude::*;

use super::sun::{edges, on_receivers, plane_runs, unit_normal, Edge, Line, Sample};
use super::sun::{MAX_SAMPLES, MIN_HALF_WIDTH, SAMPLE_SPACING, SIDE, STEP};
use crate::color::luminance;
use crate::scene::{Scene, NO_TWIN};
use crate::visibility::{Visibility, NONE};

/// The least share of the unoccluded light of all lamps at an edge (power × cosθ / d², the
/// receiver's cosine aside) that a lamp must give there for the edge's shadow of it to be
/// drawn: a lamp giving less moves the light under the edge by less than this share.
pub const SIGNIFICANT: f64 = 0.1;

/// Half the widest penumbra drawn, as a fraction of the scene's extent (44 cm in a 28 m
/// office, a quarter of [`crate::mesh::default_max_edge`]): a wider one bends the light over
/// many display triangles, whose refinement follows it. On the office of 10⁵ triangles
/// (BENCHMARKS.md "Large outputs", every significant lamp drawn) half as wide a bound kept
/// two-thirds of the gain in RMS with two-fifths of the lines.
pub const MAX_HALF_WIDTH: f64 = 1.0 / 64.0;

/// The lamps whose shadows one edge casts lines for, at most: the [`SIGNIFICANT`] ones that
/// give the most light there. Under many lamps of like power (a hall's rows of ceiling
/// panels) every edge would otherwise cast two lines for each of ten, in a comb of slivers.
pub const MAX_LAMPS_PER_EDGE: usize = 2;

/// A receiver within this cosine of edge-on to the lamp's centre gets no lines.
const GRAZING: f64 = 0.02;

/// An emitting surface: a connected set of coplanar emitting triangles of one material.
struct Lamp {
    /// Its triangles' corners (each once).
    corners: Vec<DVec3>,
    /// The area-weighted centre.
    centre: DVec3,
    /// The unit front normal.
    normal: DVec3,
    /// The largest distance from the centre to a corner.
    radius: f64,
    /// Area × the luminance of Le (W·sr⁻¹, up to a constant: only ratios are used).
    power: f64,
}

/// The lamps' near-shadow lines on each scene triangle (scene coordinates, on the triangle's
/// plane), of the edges of the triangles `on` picks (an edge counts as its lowest-numbered
/// triangle's). See the module documentation. `None` when no line is found.
pub fn lamp_lines_on(
    scene: &Scene,
    on: &(dyn Fn(usize) -> bool + Sync),
) -> Option<Vec<Vec<[DVec3; 2]>>> {
    let n = scene.triangles.len();
    let (lo, hi) = scene.bounds();
    let extent = (hi - lo).length();
    let lamps = lamps(scene);
    if n == 0 || extent <= 0.0 || lamps.is_empty() {
        return None;
    }
    let normals: Vec<DVec3> = (0..n).map(|t| unit_normal(scene, t)).collect();
    let vis = &scene.visibility();
    let mut edges = edges(scene);
    edges.retain(|e| on(e.triangles[0] as usize));
    let found: Vec<Vec<Line>> = edges
        .par_iter()
        .map(|e| {
            let [a, b] = e.vertices.map(|v| scene.positions[v as usize]);
            let mid = 0.5 * (a + b);
            let reach = |l: &Lamp| {
                let d = mid - l.centre;
                let r2 = d.length_squared();
                let cos = l.normal.dot(d) / r2.sqrt();
                if cos > 0.0 {
                    l.power * cos / r2
                } else {
                    0.0
                }
            };
            let reaches: Vec<f64> = lamps.iter().map(reach).collect();
            let total: f64 = reaches.iter().sum();
            let mut chosen: Vec<(f64, usize)> = reaches
                .into_iter()
                .enumerate()
                .map(|(k, r)| (r, k))
                .filter(|&(r, _)| r >= SIGNIFICANT * total && total > 0.0)
                .collect();
            chosen.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
            chosen
                .iter()
                .take(MAX_LAMPS_PER_EDGE)
                .flat_map(|&(_, k)| edge_lines(scene, vis, &normals, e, &lamps[k], extent))
                .collect()
        })
        .collect();
    on_receivers(scene, vis, &normals, found, extent)
}

/// The scene's lamps (see the module documentation), in the order of their first triangles.
/// Only the emitting triangles' normals are computed: a scene without lamps pays one pass
/// over its materials.
fn lamps(scene: &Scene) -> Vec<Lamp> {
    let normal = |t: usize| unit_normal(scene, t);
    let n = scene.triangles.len();
    let emits = |t: usize| {
        let back = scene
            .twin
            .get(t)
            .is_some_and(|&w| w != NO_TWIN && (w as usize) < t);
        let m = &scene.materials[scene.triangles[t].material as usize];
        !back && m.is_emitter() && luminance(m.emission) > 0.0
    };
    // Union-find over emitting triangles sharing an edge (by its corners' bits, so an
    // unwelded mesh's panels join too), of one material and plane.
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let key = |v: u32| scene.positions[v as usize].to_array().map(f64::to_bits);
    let mut by_edge: std::collections::HashMap<([u64; 3], [u64; 3]), usize> =
        std::collections::HashMap::new();
    for t in (0..n).filter(|&t| emits(t)) {
        let v = scene.triangles[t].vertices;
        for k in 0..3 {
            let (p, q) = (key(v[k]), key(v[(k + 1) % 3]));
            let edge = if p <= q { (p, q) } else { (q, p) };
            match by_edge.get(&edge) {
                Some(&u)
                    if scene.triangles[u].material == scene.triangles[t].material
                        && normal(u).dot(normal(t)) > 1.0 - 1e-9 =>
                {
                    let (ru, rt) = (root(&mut parent, u), root(&mut parent, t));
                    let (lo, hi) = (ru.min(rt), ru.max(rt));
                    parent[hi] = lo;
                }
                Some(_) => {}
                None => {
                    by_edge.insert(edge, t);
                }
            }
        }
    }
    let mut groups: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
    for t in (0..n).filter(|&t| emits(t)) {
        groups.entry(root(&mut parent, t)).or_default().push(t);
    }
    groups
        .into_values()
        .filter_map(|tris| {
            let mut corners: Vec<DVec3> = Vec::new();
            let (mut area, mut centre) = (0.0, DVec3::ZERO);
            for &t in &tris {
                let [a, b, c] = scene.triangles[t]
                    .vertices
                    .map(|v| scene.positions[v as usize]);
                let s = 0.5 * (b - a).cross(c - a).length();
                area += s;
                centre += s * (a + b + c) / 3.0;
                for p in [a, b, c] {
                    if !corners.contains(&p) {
                        corners.push(p);
                    }
                }
            }
            if area <= 0.0 {
                return None;
            }
            let centre = centre / area;
            let radius = corners
                .iter()
                .map(|&p| (p - centre).length())
                .fold(0.0, f64::max);
            let le = scene.materials[scene.triangles[tris[0]].material as usize].emission;
            Some(Lamp {
                corners,
                centre,
                normal: normal(tris[0]),
                radius,
                power: area * luminance(le),
            })
        })
        .collect()
}

/// The penumbra lines of `lamp` cast by edge `e` (see the module documentation), one pair per
/// run of its traced points whose shadow falls on one plane and is a real shadow edge there.
fn edge_lines(
    scene: &Scene,
    vis: &Visibility,
    normals: &[DVec3],
    e: &Edge,
    lamp: &Lamp,
    extent: f64,
) -> Vec<Line> {
    let [a, b] = e.vertices.map(|v| scene.positions[v as usize]);
    let length = (b - a).length();
    let c = lamp.centre;
    let mid = 0.5 * (a + b);
    if length <= 0.0 || lamp.normal.dot(mid - c) <= 0.0 {
        return Vec::new();
    }
    // A silhouette from the lamp's centre.
    if let [t0, t1] = e.triangles[..] {
        let faces = |t: u32| normals[t as usize].dot(c - mid) > 0.0;
        if faces(t0) == faces(t1) {
            return Vec::new();
        }
    }
    let side = SIDE * extent;
    // The shadow of point x of the edge, traced from `side` past it away from the centre.
    let shadow = |x: DVec3| {
        let u = (x - c).normalize();
        let start = x + u * side;
        let hit = vis.closest_hit(start, u, f64::INFINITY, e.triangles[0])?;
        let n = normals[hit.triangle as usize];
        (n.dot(-u) >= GRAZING && hit.t >= side).then_some((
            hit.triangle,
            start + u * hit.t,
            hit.t + side,
        ))
    };
    // The penumbra at the midpoint: narrow enough to draw?
    let Some((_, at, _)) = shadow(mid) else {
        return Vec::new();
    };
    // Half its width, h·w/(2D), bounded by the lamp's radius for w/2 (its widest way across).
    let half_width = lamp.radius * (at - mid).length() / (mid - c).length();
    if half_width > MAX_HALF_WIDTH * extent {
        return Vec::new();
    }
    let dir = (b - a) / length;
    let k = ((length / (SAMPLE_SPACING * extent)).ceil() as usize).clamp(1, MAX_SAMPLES);
    let samples: Vec<Option<Sample>> = (0..k)
        .map(|i| {
            let t = (i as f64 + 0.5) / k as f64;
            let x = a + (b - a) * t;
            let (r, at, distance) = shadow(x)?;
            let n = normals[r as usize];
            let u = (x - c).normalize();
            let along = dir - u * (dir.dot(n) / u.dot(n));
            let beside = n.cross(along).normalize_or_zero() * side;
            let on_surface = |p: DVec3| {
                vis.closest_hit(p + n * side, -n, 2.0 * side, NONE)
                    .is_some_and(|h| normals[h.triangle as usize].dot(n) > 1.0 - 1e-6)
            };
            // Toward the lamp's centre from `side` off the surface, stopping just short of it.
            let seen = |p: DVec3| {
                let start = p + (c - p).normalize() * side;
                vis.transmittance(start, c - start, 1.0 - 1e-4, r)
            };
            let (p, q) = (at + beside, at - beside);
            (on_surface(p) && on_surface(q) && (seen(p) - seen(q)).abs() >= STEP).then_some(
                Sample {
                    t,
                    receiver: r,
                    at,
                    distance,
                },
            )
        })
        .collect();
    plane_runs(scene, normals, &samples, extent)
        .into_iter()
        .filter_map(|run| {
            let [p, q] = run.t.map(|t| a + (b - a) * t);
            let min_half = MIN_HALF_WIDTH * extent;
            let segments = penumbra(lamp, [p, q], run.origin, run.normal, min_half)?;
            Some(Line {
                point: run.origin,
                normal: run.normal,
                segments,
            })
        })
        .collect()
}

/// The segment `pq` of an edge projected from `from` onto the plane through `origin` with unit
/// normal `n`, or `None` where `from` is not further in front of the plane than both ends.
fn project(from: DVec3, [p, q]: [DVec3; 2], origin: DVec3, n: DVec3) -> Option<[DVec3; 2]> {
    let height = (from - origin).dot(n);
    let onto = |x: DVec3| {
        let drop = (from - x).dot(n);
        (drop > 1e-9 * height.abs()).then(|| from + (x - from) * (height / drop))
    };
    Some([onto(p)?, onto(q)?])
}

/// The two borders of the penumbra of the edge segment `pq` under `lamp` on the plane through
/// `origin` with unit normal `n`: of the segment's projections from the lamp's corners
/// ([`project`]), the two furthest out on either side of its projection from the centre (by
/// their midpoints' offsets across it), at least `min_half` from it on each side.
fn penumbra(
    lamp: &Lamp,
    pq: [DVec3; 2],
    origin: DVec3,
    n: DVec3,
    min_half: f64,
) -> Option<[[DVec3; 2]; 2]> {
    let [cp, cq] = project(lamp.centre, pq, origin, n)?;
    let across = n.cross(cq - cp).normalize_or_zero();
    if across == DVec3::ZERO {
        return None;
    }
    let centre_mid = 0.5 * (cp + cq);
    let (mut lo, mut hi) = ((0.0, [cp, cq]), (0.0, [cp, cq]));
    for &corner in &lamp.corners {
        let Some(s) = project(corner, pq, origin, n) else {
            continue;
        };
        let offset = across.dot(0.5 * (s[0] + s[1]) - centre_mid);
        if offset < lo.0 {
            lo = (offset, s);
        }
        if offset > hi.0 {
            hi = (offset, s);
        }
    }
    // A border closer to the centre's line than `min_half` is moved out to it, parallel.
    let out = |(offset, s): (f64, [DVec3; 2]), sign: f64| {
        if offset * sign >= min_half {
            s
        } else {
            let shift = across * (sign * min_half - offset);
            [s[0] + shift, s[1] + shift]
        }
    };
    Some([out(lo, -1.0), out(hi, 1.0)])
}
