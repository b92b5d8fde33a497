//! The exact direct light of a triangular or convex quadrilateral emitter at a point, shadows
//! included: the part of the emitter the point sees, as convex polygons, and its form factor
//! by Lambert's contour integral, in place of a visible fraction estimated by shadow rays.
//!
//! Every occluding triangle between the point x and the emitter E is clipped to the pyramid
//! with apex x over E (the planes through x and E's edges, E's plane, and x's horizon),
//! and what is left is projected from x onto E's plane: the shadow it casts on E as x sees it.
//! E less the union of these convex shadows is a set of convex pieces (each shadow subtracted
//! edge by edge, as Sutherland–Hodgman clipping), and the unoccluded form factor of those
//! pieces is the visible form factor F(x → E)·V̄(x, E) exactly, V̄ weighted by the kernel as
//! the shadow rays' estimate is. This is how Nishita & Nakamae computed the light of polygonal
//! sources with shadows ("Continuous tone representation of three-dimensional objects taking
//! account of shadows and interreflection", SIGGRAPH 1985; the visible part of a source as
//! seen from a point is the "backprojection" of Drettakis & Fiume, SIGGRAPH 1994, and
//! Stewart & Ghali, SIGGRAPH 1994).
//!
//! Shadow rays answer a penumbra with noise of a few per cent at 256 rays, and where only a
//! sliver of the emitter is visible their first 16 can all miss it and call the point wholly
//! shadowed: in the Cornell box, a floor point in the tall block's penumbra gets a direct
//! light that varies between seeds by most of its mean, and is 0 for many of them. The
//! visible pieces have neither error. Their cost is a box query and a few clips a triangle,
//! bounded by [`MAX_CANDIDATES`], [`MAX_OCCLUDERS`] and [`MAX_PIECES`]: beyond them, the
//! caller casts rays instead.

use glam::{DVec2, DVec3};

use super::clip::clip_polygon;
use super::kernel::point_to_convex_polygon;

/// Triangles in the pyramid (casting a shadow on the emitter), at most; with more (a point
/// under a crowded scene), [`visible_form_factor`] gives up and the caller samples visibility
/// by rays.
///
/// The three bounds ([`MAX_OCCLUDERS`], [`MAX_CANDIDATES`], [`MAX_PIECES`]) set where the
/// exact pieces stop paying. A point that gives up has spent its clipping for nothing and
/// then casts its rays all the same, so a bound set high costs most where the answer is rays
/// anyway. In a furnished office (chairs, plants, shelves: `generate office`), about a third
/// of the calls gave up at twice these bounds, having done three fifths of all the clipping;
/// at these, its whole bake takes about 7 % less time and its displayed error is the same
/// over three seeds. Rooms whose views are less crowded (the Cornell box, the living room, the
/// study, the kitchen, the hall of many lights) show the same picture either way (BENCHMARKS.md,
/// "Large outputs: the `cache` gather").
pub const MAX_OCCLUDERS: usize = 32;

/// Triangles overlapping the pyramid's box that are clipped to it, at most (most of them miss
/// it: the box of a slanted pyramid is far larger); beyond, [`visible_form_factor`] gives up
/// (see [`MAX_OCCLUDERS`]).
pub const MAX_CANDIDATES: usize = 256;

/// Convex pieces the visible part of an emitter may be cut into, at most, before
/// [`visible_form_factor`] gives up (the shadows of many small occluders; see
/// [`MAX_OCCLUDERS`]).
pub const MAX_PIECES: usize = 24;

/// Pieces smaller than this fraction of the emitter's area are dropped: slivers left by the
/// rounding of shadows that share an edge (two triangles of one occluder's face).
const SLIVER: f64 = 1e-12;

/// The form factor from the point `x` (unit normal `n`) to the part of the emitter `e`, a
/// triangle or a planar convex quadrilateral (unit front normal `e_normal`, x in front of
/// it), not hidden by the triangles `occluders` offers: `Some(F·V̄)`, dimensionless in
/// [0, F(x → e)], or `None` when more than [`MAX_CANDIDATES`] triangles are offered, more
/// than [`MAX_OCCLUDERS`] of them reach into the pyramid, or the visible part needs more than
/// [`MAX_PIECES`] pieces.
///
/// `occluders` calls its argument with every triangle that may lie between x and e (scene
/// units; a superset is fine: triangles outside the pyramid are clipped away), until it returns
/// `false`, and returns `false` if it was stopped. `margin` (scene units, > 0) is the
/// thickness kept clear above x's horizon, in front of e's plane and around x: the surface x
/// lies on, e's own plane and a surface through x do not occlude, as the shadow rays' lift
/// makes them not.
pub fn visible_form_factor(
    x: DVec3,
    n: DVec3,
    e: &[DVec3],
    e_normal: DVec3,
    margin: f64,
    occluders: impl FnOnce(&[(DVec3, DVec3)], &mut dyn FnMut(&[DVec3; 3]) -> bool) -> bool,
) -> Option<f64> {
    debug_assert!((3..=4).contains(&e.len()), "a triangle or a quadrilateral");
    let dx = e_normal.dot(x - e[0]);
    if dx <= 2.0 * margin {
        return Some(crate::geometry::point_to_polygon(x, n, e));
    }
    // The pyramid: keep m·(p − x) ≥ 0 for each side plane (through x and an edge of e; e is
    // convex, so every other corner lies on its inner side).
    let count = e.len();
    let mut sides = [DVec3::ZERO; 4];
    for (k, side) in sides.iter_mut().enumerate().take(count) {
        let (a, b, c) = (e[k], e[(k + 1) % count], e[(k + 2) % count]);
        let m = (a - x).cross(b - x);
        *side = if m.dot(c - x) < 0.0 { -m } else { m };
    }
    let sides = &sides[..count];
    // Coordinates in e's plane.
    let u = (e[1] - e[0]).normalize();
    let v = e_normal.cross(u);
    let to_2d = |y: DVec3| DVec2::new(u.dot(y - e[0]), v.dot(y - e[0]));
    let mut emitter: Vec<DVec2> = e.iter().map(|&y| to_2d(y)).collect();
    if area(&emitter) < 0.0 {
        emitter.reverse();
    }
    let sliver = SLIVER * area(&emitter);
    let mut pieces = Pieces::default();
    pieces.push(&emitter);
    // The buffers every occluder reuses: its clipped corners, its shadow, what is left.
    let mut next = Pieces::default();
    let mut scratch = Scratch::default();
    let mut shadow: Vec<DVec2> = Vec::with_capacity(12);

    let (mut a, mut b) = (Vec::with_capacity(12), Vec::with_capacity(12));
    let mut tried = 0;
    let mut too_complex = false;
    let mut cast = 0;
    // The pyramid as half-spaces (normal, point on the plane), for the caller's query to cull
    // with: its sides, x's horizon and e's front. Looser than the clips below (no
    // margins), so nothing they keep is culled.
    // The sides first, then x's horizon (the array's fill) and e's front.
    let mut pyramid = [(n, x); 6];
    for (plane, &m) in pyramid.iter_mut().zip(sides) {
        *plane = (m, x);
    }
    pyramid[count + 1] = (e_normal, e[0]);
    let finished = occluders(&pyramid[..count + 2], &mut |t: &[DVec3; 3]| {
        tried += 1;
        if tried > MAX_CANDIDATES {
            too_complex = true;
            return false;
        }
        // The part of t inside the pyramid, clear of x and of e's plane.
        a.clear();
        a.extend_from_slice(t);
        for m in sides {
            clip_polygon(&a, |p| m.dot(p - x), &mut b);
            std::mem::swap(&mut a, &mut b);
        }
        clip_polygon(&a, |p| n.dot(p - x) - margin, &mut b);
        clip_polygon(&b, |p| e_normal.dot(p - e[0]) - margin, &mut a);
        clip_polygon(&a, |p| dx - margin - e_normal.dot(p - e[0]), &mut b);
        if b.len() < 3 {
            return true;
        }
        cast += 1;
        if cast > MAX_OCCLUDERS {
            too_complex = true;
            return false;
        }
        // Its shadow on e's plane, from x: p = x + s(y − x) with s = (dx − d_p)/dx ≥ margin/dx.
        shadow.clear();
        shadow.extend(b.iter().map(|&p| {
            let s = (dx - e_normal.dot(p - e[0])) / dx;
            to_2d(x + (p - x) / s)
        }));
        let signed = area(&shadow);
        if signed.abs() <= sliver {
            return true;
        }
        if signed < 0.0 {
            shadow.reverse();
        }
        subtract(&pieces, &shadow, sliver, &mut next, &mut scratch);
        std::mem::swap(&mut pieces, &mut next);
        if pieces.len() > MAX_PIECES {
            too_complex = true;
            return false;
        }
        !pieces.is_empty()
    });
    if too_complex || (!finished && !pieces.is_empty()) {
        return None;
    }
    let to_3d = |p: DVec2| e[0] + p.x * u + p.y * v;
    let mut corners: Vec<DVec3> = Vec::with_capacity(12);
    Some(
        pieces
            .iter()
            .map(|piece| {
                corners.clear();
                corners.extend(piece.iter().map(|&p| to_3d(p)));
                point_to_convex_polygon(x, n, &corners)
            })
            .sum(),
    )
}

/// Convex polygons stored end to end, piece k at `points[ends[k - 1]..ends[k]]` (from 0 for
/// the first): the visible part of an emitter, cut and cut again without a vector per piece.
#[derive(Default)]
struct Pieces {
    points: Vec<DVec2>,
    ends: Vec<usize>,
}

impl Pieces {
    fn len(&self) -> usize {
        self.ends.len()
    }

    fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }

    fn clear(&mut self) {
        self.points.clear();
        self.ends.clear();
    }

    fn push(&mut self, piece: &[DVec2]) {
        self.points.extend_from_slice(piece);
        self.ends.push(self.points.len());
    }

    fn iter(&self) -> impl Iterator<Item = &[DVec2]> {
        (0..self.ends.len()).map(|k| {
            let start = k.checked_sub(1).map_or(0, |j| self.ends[j]);
            &self.points[start..self.ends[k]]
        })
    }
}

/// [`subtract`]'s working polygons, kept from one occluder to the next.
#[derive(Default)]
struct Scratch {
    corners: Vec<DVec2>,
    outside: Vec<DVec2>,
    inside: Vec<DVec2>,
    rest: Vec<DVec2>,
}

/// A hole's edge shorter than this share of its extent is no edge ([`subtract`]).
const SHORT_EDGE: f64 = 1e-9;

/// The signed area of a 2-D polygon (positive when counter-clockwise).
fn area(p: &[DVec2]) -> f64 {
    let mut s = 0.0;
    let mut a = p[p.len() - 1];
    for &b in p {
        s += a.perp_dot(b);
        a = b;
    }
    0.5 * s
}

/// The convex pieces `pieces` (counter-clockwise) less the convex polygon `hole`
/// (counter-clockwise), as convex pieces, into `out` (cleared first): for each edge of the hole
/// in turn, the part of what is left outside that edge is kept and the part inside goes on to
/// the next edge; what is inside every edge is the hole's. Pieces of area at most `sliver` are
/// dropped.
///
/// The hole's edges shorter than [`SHORT_EDGE`] of its extent are passed over (their ends
/// merged): a clipped occluder repeats a corner that lies on a clipping plane, and the
/// "outside" of an edge of no length is a half-plane of arbitrary direction, which would keep
/// as seen a part of the emitter the hole covers (a wall strip beside a window, seen by a
/// point on the wall it meets, let through up to all of the light behind it).
fn subtract(pieces: &Pieces, hole: &[DVec2], sliver: f64, out: &mut Pieces, scratch: &mut Scratch) {
    out.clear();
    let Scratch {
        corners,
        outside,
        inside,
        rest,
    } = scratch;
    let (lo, hi) = bounds(hole);
    let short = SHORT_EDGE * (hi - lo).max_element();
    corners.clear();
    for &p in hole {
        if corners.last().is_none_or(|q| q.distance(p) > short) {
            corners.push(p);
        }
    }
    while corners.len() > 1 && corners[0].distance(corners[corners.len() - 1]) <= short {
        corners.pop();
    }
    if corners.len() < 3 {
        pieces.iter().for_each(|piece| out.push(piece));
        return;
    }
    let hole = &corners[..];
    for piece in pieces.iter() {
        let (plo, phi) = bounds(piece);
        if plo.x >= hi.x || plo.y >= hi.y || phi.x <= lo.x || phi.y <= lo.y {
            out.push(piece);
            continue;
        }
        rest.clear();
        rest.extend_from_slice(piece);
        for k in 0..hole.len() {
            let (a, b) = (hole[k], hole[(k + 1) % hole.len()]);
            let along = b - a;
            clip_polygon(rest, |p| -along.perp_dot(p - a), outside);
            if outside.len() >= 3 && area(outside) > sliver {
                out.push(outside);
            }
            clip_polygon(rest, |p| along.perp_dot(p - a), inside);
            std::mem::swap(rest, inside);
            if rest.len() < 3 || area(rest) <= sliver {
                break;
            }
        }
    }
}

/// The bounding box of a 2-D polygon.
fn bounds(p: &[DVec2]) -> (DVec2, DVec2) {
    p.iter()
        .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), &q| {
            (lo.min(q), hi.max(q))
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::point_to_polygon;
    use crate::sampling::Rng;

    /// The emitter: the unit square at height 1 (two triangles), facing down.
    fn square() -> [[DVec3; 3]; 2] {
        let c = [
            DVec3::new(-0.5, -0.5, 1.0),
            DVec3::new(0.5, -0.5, 1.0),
            DVec3::new(0.5, 0.5, 1.0),
            DVec3::new(-0.5, 0.5, 1.0),
        ];
        [[c[0], c[2], c[1]], [c[0], c[3], c[2]]]
    }

    const DOWN: DVec3 = DVec3::NEG_Z;
    const MARGIN: f64 = 1e-9;

    fn exact(x: DVec3, n: DVec3, e: &[DVec3; 3], occluders: &[[DVec3; 3]]) -> Option<f64> {
        visible_form_factor(x, n, e, DOWN, MARGIN, |_, visit| {
            occluders.iter().all(visit)
        })
    }

    /// The oracle: F·V̄ by a fine grid of jittered points over `e`, each weighted by the
    /// kernel cosθ cosθ' / (π r²) dA and counted where no occluder meets the segment
    /// (Möller–Trumbore, independent of the clipping above).
    fn by_rays(x: DVec3, n: DVec3, e: &[DVec3; 3], occluders: &[[DVec3; 3]], k: usize) -> f64 {
        let area = 0.5 * (e[1] - e[0]).cross(e[2] - e[0]).length();
        let mut rng = Rng::new(&[3, k as u64]);
        let mut sum = 0.0;
        for i in 0..k {
            for j in 0..k {
                let (mut s, mut t) = (
                    (i as f64 + rng.next_f64()) / k as f64,
                    (j as f64 + rng.next_f64()) / k as f64,
                );
                if s + t > 1.0 {
                    (s, t) = (1.0 - s, 1.0 - t);
                }
                let y = e[0] + s * (e[1] - e[0]) + t * (e[2] - e[0]);
                let d = y - x;
                let r2 = d.length_squared();
                let g = (n.dot(d) * -DOWN.dot(d)).max(0.0) / (std::f64::consts::PI * r2 * r2);
                if g > 0.0 && !occluders.iter().any(|o| segment_hits(x, y, o)) {
                    sum += g;
                }
            }
        }
        sum * area / (k * k) as f64
    }

    /// `count` random small triangles between the plane z = 0 and the emitter at z = 1:
    /// centres over the square at heights 0.2–0.8, sizes 0.2–0.8, slightly tilted.
    fn random_occluders(rng: &mut Rng, count: usize) -> Vec<[DVec3; 3]> {
        (0..count)
            .map(|_| {
                let c = DVec3::new(
                    rng.next_f64() - 0.5,
                    rng.next_f64() - 0.5,
                    0.2 + 0.6 * rng.next_f64(),
                );
                let r = 0.6 * rng.next_f64() + 0.2;
                std::array::from_fn(|_| {
                    c + r * DVec3::new(
                        rng.next_f64() - 0.5,
                        rng.next_f64() - 0.5,
                        0.4 * (rng.next_f64() - 0.5),
                    )
                })
            })
            .collect()
    }

    fn segment_hits(p: DVec3, q: DVec3, t: &[DVec3; 3]) -> bool {
        let d = q - p;
        let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
        let h = d.cross(e2);
        let a = e1.dot(h);
        if a.abs() < 1e-15 {
            return false;
        }
        let s = p - t[0];
        let u = s.dot(h) / a;
        let qv = s.cross(e1);
        let v = d.dot(qv) / a;
        let w = e2.dot(qv) / a;
        u >= 0.0 && v >= 0.0 && u + v <= 1.0 && w > 1e-9 && w < 1.0 - 1e-9
    }

    #[test]
    fn with_nothing_in_the_way_it_is_the_unoccluded_form_factor() {
        // To rounding: the one piece is the emitter itself.
        let x = DVec3::new(0.2, -0.1, 0.0);
        for e in square() {
            let f = point_to_polygon(x, DVec3::Z, &e);
            assert!((exact(x, DVec3::Z, &e, &[]).unwrap() - f).abs() <= 1e-15 * f.max(1e-300));
            // Occluders beside the pyramid, behind x or beyond the emitter change nothing.
            let far = [
                [
                    DVec3::new(3.0, 3.0, 0.5),
                    DVec3::new(4.0, 3.0, 0.5),
                    DVec3::new(3.0, 4.0, 0.5),
                ],
                [
                    DVec3::new(-1.0, -1.0, -0.5),
                    DVec3::new(1.0, -1.0, -0.5),
                    DVec3::new(0.0, 1.0, -0.5),
                ],
                [
                    DVec3::new(-1.0, -1.0, 1.5),
                    DVec3::new(1.0, -1.0, 1.5),
                    DVec3::new(0.0, 1.0, 1.5),
                ],
            ];
            let with = exact(x, DVec3::Z, &e, &far).unwrap();
            assert!((with - f).abs() <= 1e-12 * f, "{with} against {f}");
        }
    }

    #[test]
    fn a_wall_over_half_the_pyramid_leaves_the_other_half() {
        // A large triangle at height 0.5 over x < 0 casts its shadow from the origin on the
        // emitter's x < 0 half exactly: what is left is the closed-form F of the x > 0 half.
        let x = DVec3::ZERO;
        let wall = [
            DVec3::new(0.0, -5.0, 0.5),
            DVec3::new(0.0, 5.0, 0.5),
            DVec3::new(-5.0, 0.0, 0.5),
        ];
        let half = [
            DVec3::new(0.0, -0.5, 1.0),
            DVec3::new(0.5, -0.5, 1.0),
            DVec3::new(0.5, 0.5, 1.0),
            DVec3::new(0.0, 0.5, 1.0),
        ];
        let expected = point_to_polygon(x, DVec3::Z, &half);
        let got: f64 = square()
            .iter()
            .map(|e| exact(x, DVec3::Z, e, &[wall]).unwrap())
            .sum();
        assert!((got - expected).abs() <= 1e-12, "{got} against {expected}");
        // A second triangle over the rest hides it all.
        let other = [
            DVec3::new(0.0, -5.0, 0.5),
            DVec3::new(5.0, 0.0, 0.5),
            DVec3::new(0.0, 5.0, 0.5),
        ];
        for e in square() {
            assert_eq!(exact(x, DVec3::Z, &e, &[wall, other]), Some(0.0));
        }
    }

    #[test]
    fn a_wall_strip_meeting_the_receivers_wall_hides_the_window_light_behind_it() {
        // A room's side wall z = 4 (facing −z) meets the window wall x = 4; the window wall's
        // strip beside the opening (x = 4, 0.75 ≤ y ≤ 2.25, 3 ≤ z ≤ 4) stands between a point
        // of the side wall and a panel outside (x = 6): every segment from the point to the
        // panel crosses x = 4 at 3.04 ≤ z ≤ 3.87 and 0.81 ≤ y ≤ 1.64, inside the strip. Clipped
        // at the point's horizon, the strip's corners there repeat, and the shadow of each of
        // its triangles had an edge of no length: the panel came out 63 % and 100 % seen.
        let x = DVec3::new(3.25, 1.125, 4.0);
        let n = DVec3::new(0.0, 0.0, -1.0);
        let panel = [
            [
                DVec3::new(6.0, 0.0, 0.5),
                DVec3::new(6.0, 3.0, 3.5),
                DVec3::new(6.0, 3.0, 0.5),
            ],
            [
                DVec3::new(6.0, 0.0, 0.5),
                DVec3::new(6.0, 0.0, 3.5),
                DVec3::new(6.0, 3.0, 3.5),
            ],
        ];
        let strip = [
            [
                DVec3::new(4.0, 0.75, 3.0),
                DVec3::new(4.0, 2.25, 4.0),
                DVec3::new(4.0, 2.25, 3.0),
            ],
            [
                DVec3::new(4.0, 2.25, 4.0),
                DVec3::new(4.0, 0.75, 3.0),
                DVec3::new(4.0, 0.75, 4.0),
            ],
        ];
        for e in &panel {
            assert!(
                point_to_polygon(x, n, e) > 0.04,
                "the panel faces the point"
            );
            // The panel faces the room (−x); the margin is the bake's lift in this room.
            let seen = visible_form_factor(x, n, e, DVec3::NEG_X, 7.8e-6, |_, visit| {
                strip.iter().all(visit)
            });
            assert_eq!(seen, Some(0.0));
        }
    }

    #[test]
    fn walls_on_a_grid_agree_with_shadow_rays() {
        // Axis-aligned walls (two triangles each) with corners on a grid of eighths, some
        // standing on the receiving point's plane, others hanging across the pyramid, seen
        // from points on the same grid: as in architecture, a clipped corner often lands
        // exactly on the next clipping plane, and the clipped polygon repeats it (random
        // coordinates almost never do). The same oracle and tolerance as for random occluders
        // below; a shadow's edge of no length let light through by up to all of F.
        let mut rng = Rng::new(&[23]);
        let eighth = |rng: &mut Rng, lo: i32, hi: i32| {
            (lo + (rng.next_f64() * (hi - lo + 1) as f64) as i32) as f64 / 8.0
        };
        let mut checked = 0;
        for case in 0..32 {
            let x = DVec3::new(eighth(&mut rng, -3, 3), eighth(&mut rng, -3, 3), 0.0);
            let mut occluders: Vec<[DVec3; 3]> = Vec::new();
            for _ in 0..1 + case % 3 {
                let (lo, hi) = (eighth(&mut rng, 0, 4), eighth(&mut rng, 2, 7));
                let (u, v) = (eighth(&mut rng, -8, 0), eighth(&mut rng, 0, 8));
                let at = eighth(&mut rng, -6, 6);
                let corner = |s: f64, z: f64| match case % 2 {
                    0 => DVec3::new(at, s, z),
                    _ => DVec3::new(s, at, z),
                };
                let (a, b, c, d) = (corner(u, lo), corner(v, lo), corner(v, hi), corner(u, hi));
                occluders.push([a, b, c]);
                occluders.push([a, c, d]);
            }
            for e in square() {
                let f = point_to_polygon(x, DVec3::Z, &e);
                let got = exact(x, DVec3::Z, &e, &occluders).unwrap();
                let want = by_rays(x, DVec3::Z, &e, &occluders, 400);
                assert!(
                    (got - want).abs() <= 1e-3 * f,
                    "case {case}: exact {got} against rays {want} (F {f})"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 64);
    }

    #[test]
    fn a_quadrilateral_sees_what_its_two_triangles_see() {
        // The unit square as one convex quadrilateral against the sum of its two triangles,
        // each already checked against shadow rays (below), under random occluders: the same
        // visible pieces cut along the diagonal or not, so equal to rounding.
        let [t0, t1] = square();
        let quad = [t0[0], t1[1], t0[1], t0[2]];
        let mut rng = Rng::new(&[23]);
        let mut hidden = 0;
        for case in 0..32 {
            let x = DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, 0.0);
            let occluders = random_occluders(&mut rng, 1 + case % 4);
            let whole = visible_form_factor(x, DVec3::Z, &quad, DOWN, MARGIN, |_, visit| {
                occluders.iter().all(visit)
            })
            .unwrap();
            let parts: f64 = [t0, t1]
                .iter()
                .map(|t| exact(x, DVec3::Z, t, &occluders).unwrap())
                .sum();
            let f = point_to_polygon(x, DVec3::Z, &quad);
            assert!(
                (whole - parts).abs() <= 1e-9 * f,
                "case {case}: the quadrilateral {whole} against its triangles {parts}"
            );
            hidden += (whole < 0.999 * f) as usize;
        }
        assert!(
            hidden >= 24,
            "only {hidden} of the cases were partly hidden"
        );
    }

    #[test]
    fn random_occluders_agree_with_shadow_rays() {
        // Random small triangles between random points and the emitter: the exact visible
        // form factor against a 400 × 400 jittered grid of kernel-weighted shadow rays. The
        // grid's error is that of its cells along the shadows' edges: at most 2e-4 of F over
        // these cases (measured); 1e-3 leaves room, and a clipping or projection error (a
        // shadow misplaced or of the wrong size) is far larger.
        let mut rng = Rng::new(&[17]);
        let mut checked = 0;
        for case in 0..24 {
            let x = DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, 0.0);
            let n = (DVec3::Z + 0.3 * DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, 0.0))
                .normalize();
            let occluders = random_occluders(&mut rng, 1 + case % 5);
            for e in square() {
                let f = point_to_polygon(x, n, &e);
                let got = exact(x, n, &e, &occluders).unwrap();
                let oracle = by_rays(x, n, &e, &occluders, 400);
                assert!(
                    got <= f * (1.0 + 1e-12),
                    "case {case}: {got} above the unoccluded {f}"
                );
                assert!(
                    (got - oracle).abs() <= 3e-3 * f,
                    "case {case}: {got} against {oracle} (F {f})"
                );
                checked += (got < 0.999 * f) as usize;
            }
        }
        assert!(
            checked >= 24,
            "only {checked} of the cases were partly hidden"
        );
    }

    #[test]
    fn too_many_occluders_or_pieces_are_left_to_the_rays() {
        let e = square()[0];
        let x = DVec3::new(0.1, -0.2, 0.0);
        // Many disjoint specks: each splits the pieces.
        let specks: Vec<[DVec3; 3]> = (0..MAX_OCCLUDERS + 1)
            .map(|k| {
                let c = DVec3::new(
                    0.3 * (k % 10) as f64 / 10.0,
                    -0.3 + 0.05 * (k / 10) as f64,
                    0.5,
                );
                [
                    c,
                    c + DVec3::new(0.01, 0.0, 0.0),
                    c + DVec3::new(0.0, 0.01, 0.0),
                ]
            })
            .collect();
        assert_eq!(exact(x, DVec3::Z, &e, &specks), None);
        assert!(exact(x, DVec3::Z, &e, &specks[..3]).is_some());
    }
}
