//! A scene triangle as the discontinuity meshing sees it ([`Face`]): its plane, a frame in it
//! with coordinates snapped to a grid (the same at every scale), clipping of a segment to it,
//! and its constrained Delaunay triangulation with the segments as edges (the `spade`
//! crate), the segments first cut where they cross.

use std::collections::HashMap;

use glam::{DVec3, Vec3A};
use obvhs::aabb::Aabb;
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

use crate::scene::Scene;

/// A scene triangle with its plane and a frame in it.
pub(super) struct Face {
    pub(super) corners: [DVec3; 3],
    /// Unit front normal.
    pub(super) normal: DVec3,
    /// In-plane orthonormal axes (origin corner 0).
    pub(super) u: DVec3,
    pub(super) w: DVec3,
    /// Length of the longest edge: 2D coordinates are in this unit.
    pub(super) size: f64,
}

impl Face {
    pub(super) fn new(scene: &Scene, t: usize) -> Face {
        Face::from_corners(
            scene.triangles[t]
                .vertices
                .map(|v| scene.positions[v as usize]),
        )
    }

    pub(super) fn from_corners(corners: [DVec3; 3]) -> Face {
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
    pub(super) fn width(&self) -> f64 {
        let [a, b, c] = self.corners;
        (b - a).cross(c - a).length() / self.size.max(f64::MIN_POSITIVE)
    }

    /// The box of its corners, widened by `pad` on every side, scene units.
    pub(super) fn bounds(&self, pad: f64) -> (DVec3, DVec3) {
        let [a, b, c] = self.corners;
        (a.min(b).min(c) - pad, a.max(b).max(c) + pad)
    }

    pub(super) fn aabb(&self, pad: f64) -> Aabb {
        let (lo, hi) = self.bounds(pad);
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
    pub(super) fn to_2d(&self, p: DVec3) -> [f64; 2] {
        let d = (p - self.corners[0]) / self.size;
        let snap = |x: f64| (x * SNAP).round() / SNAP;
        [snap(d.dot(self.u)), snap(d.dot(self.w))]
    }

    pub(super) fn point_at(&self, q: [f64; 2]) -> DVec3 {
        self.corners[0] + self.size * (q[0] * self.u + q[1] * self.w)
    }

    /// The part of the 2D segment inside this face, `None` if shorter than `tol` or lying
    /// along one of its edges.
    pub(super) fn clip(&self, s: [[f64; 2]; 2], tol: f64) -> Option<[[f64; 2]; 2]> {
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
    pub(super) fn edge_through(&self, p: DVec3, tol: f64) -> Option<usize> {
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
    pub(super) fn triangulate(
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

/// The 2D segments `segs` cut at their crossings: each pair that crosses (or where one ends on
/// the other, within [`CROSSING`] of its ends) is split at one point shared by both pieces,
/// an end of one of them where the crossing lies that near it, so the pieces meet only at
/// their ends. Zero-length pieces are dropped. O(k²) in the segments of one face.
pub(super) fn split_at_crossings(segs: &[[[f64; 2]; 2]]) -> Vec<[[f64; 2]; 2]> {
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
pub(super) fn onto_edge(c: [[f64; 2]; 3], q: [f64; 2]) -> [f64; 2] {
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

/// The grid [`Face::to_2d`] snaps to: 2³⁰ steps per face size.
const SNAP: f64 = (1u64 << 30) as f64;
