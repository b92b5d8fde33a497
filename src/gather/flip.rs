//! Data-dependent edge flips of the displayed mesh: the diagonal of two coplanar triangles is
//! turned where the other diagonal interpolates the direct light better.
//!
//! Vertex colours interpolate linearly across each triangle, and of the two ways to split a
//! convex quadrilateral (a, d, b, c) into triangles, along (a, b) or along (c, d), the one
//! whose diagonal runs along a shadow's edge shows that edge, the other smears it across both
//! triangles. The display refinement ([`super::refine()`]) splits edges at their midpoints, so its
//! diagonals follow the patch mesh, not the light. Dyn, Levin & Rippa ("Data dependent
//! triangulations for piecewise linear interpolation", IMA J. Numer. Anal. 1990) choose each
//! diagonal by the data at the vertices alone; here the light itself is evaluated where the
//! choice matters:
//!
//! - The two diagonals cross at a point X (at t along (a, b), s along (c, d)). Where the
//!   vertices' luminance interpolated to X along (a, b) and along (c, d) agree within τ of the
//!   local luminance, the choice does not matter and nothing is evaluated.
//! - Elsewhere the cheap, correlated estimate of the direct light the refinement orders its
//!   tests by (`Gatherer::coarse_direct`) is taken at X and the four vertices; where the
//!   turned diagonal interpolates it better by [`MARGIN`] × τ of the local luminance (or
//!   wherever the scene has more point lights than that estimate counts, whose shadow rays
//!   cost little), the direct light at X is computed exactly
//!   (`Gatherer::reflected_direct`, as the refinement's midpoint tests do), and the diagonal
//!   is turned to (c, d) when its interpolation of the vertices' direct light errs less there,
//!   by at least [`MARGIN`] × τ of the local luminance. The direct light is the sharp part of
//!   what the display loses inside its triangles; the indirect light is smooth there and, in
//!   the `cache` gather, known only at the vertices.
//!
//! On the generated office of 10⁵ triangles the cheap estimate leaves about one in seven of
//! the screened crossings to evaluate exactly, and the displayed error is what evaluating them
//! all gives (BENCHMARKS.md "Large outputs: the `cache` gather").
//!
//! Only edges between two faces of one flat surface (one material, the same plane) turn, and
//! only where the quadrilateral is convex, no end is buried, the new diagonal is not an edge
//! already, and all five points compute the same emitters exactly (else their direct parts do
//! not compare). An edge along a contact line stays: the vertices under what stands on it are
//! buried. Up to [`ROUNDS`] rounds, each over the edges of the faces the last one
//! turned; within a round the largest gains first, each face turning at most once. Every
//! choice is ordered by vertex indices and each evaluation seeded by its edge, so a fixed seed
//! gives the same mesh for any thread count.

use std::collections::HashMap;

use super::coarse::{coarse_direct_at, complete_coarse, face_edges, Coarse, Edge};
use super::{Gathered, Gatherer};
use crate::bake::Site;
use crate::color::luminance;
use crate::light::emitter::MIDPOINT_SHADOW_RAYS;
use crate::sampling::Rng;

/// A diagonal turns only where the new one's error at the crossing point is smaller by this
/// share of τ × the local luminance: a smaller gain is within what the exact direct light's
/// shadow rays (in a crowded view) and the vertices' own values leave uncertain.
pub const MARGIN: f64 = 0.5;

/// Rounds of flips, at most: a turned diagonal makes new quadrilaterals around it.
pub const ROUNDS: usize = 3;

/// The faces on each output edge, in the order they were added: a pair inline (16 bytes an
/// edge, no allocation of its own: the map of a large output's every edge is the largest
/// thing the flips hold), the rare edge of three or more faces (a non-manifold output) in a
/// side map.
#[derive(Debug, Default)]
struct FacesOf {
    pairs: HashMap<Edge, [u32; 2], rustc_hash::FxBuildHasher>,
    more: HashMap<Edge, Vec<u32>>,
}

/// An empty slot of [`FacesOf::pairs`].
const NO_FACE: u32 = u32::MAX;
/// Both slots of [`FacesOf::pairs`] for an edge whose faces are in [`FacesOf::more`].
const MORE: u32 = u32::MAX - 1;

impl FacesOf {
    fn add(&mut self, e: Edge, f: usize) {
        let f = f as u32;
        let slot = self.pairs.entry(e).or_insert([NO_FACE; 2]);
        match *slot {
            [NO_FACE, _] => slot[0] = f,
            [MORE, _] => self.more.entry(e).or_default().push(f),
            [_, NO_FACE] => slot[1] = f,
            [a, b] => {
                self.more.insert(e, vec![a, b, f]);
                *slot = [MORE; 2];
            }
        }
    }

    /// Takes face `f` off edge `e` (every time it is listed), and the edge away with its
    /// last face.
    fn remove(&mut self, e: Edge, f: usize) {
        let f = f as u32;
        let Some(slot) = self.pairs.get_mut(&e) else {
            return;
        };
        let mut left: smallvec::SmallVec<[u32; 2]> = match *slot {
            [MORE, _] => self.more.remove(&e).unwrap_or_default().into(),
            pair => pair.into_iter().filter(|&g| g != NO_FACE).collect(),
        };
        left.retain(|g| *g != f);
        match left.len() {
            0 => {
                self.pairs.remove(&e);
            }
            1 | 2 => *slot = [left[0], left.get(1).copied().unwrap_or(NO_FACE)],
            _ => {
                self.more.insert(e, left.into_vec());
            }
        }
    }

    /// The two faces of `e`, if it has exactly two.
    fn pair(&self, e: Edge) -> Option<[usize; 2]> {
        match *self.pairs.get(&e)? {
            [a, b] if a != MORE && b != NO_FACE => Some([a as usize, b as usize]),
            _ => None,
        }
    }

    fn contains(&self, e: Edge) -> bool {
        self.pairs.contains_key(&e)
    }

    fn edges(&self) -> impl Iterator<Item = Edge> + '_ {
        self.pairs.keys().copied()
    }
}

/// What the flips did.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Flipped {
    /// Crossing points where the direct light was evaluated.
    pub tests: usize,
    /// Diagonals turned.
    pub flips: usize,
}

/// A candidate: the edge (a, b) shared by faces f1 = (a, b, c) and f2 = (b, a, d), both
/// counter-clockwise, and where its diagonals cross.
#[derive(Debug, Clone, Copy)]
struct Quad {
    a: u32,
    b: u32,
    c: u32,
    d: u32,
    f1: usize,
    f2: usize,
    /// X = a + t (b − a) = c + s (d − c).
    t: f64,
    s: f64,
    x: glam::DVec3,
    /// τ × the local luminance at X (at least the dark floor).
    scale: f64,
}

/// Turns diagonals of `faces` (whose patches are `face_patch`, vertices `sites` with values
/// `values`, showing `shown`) where the other one interpolates the direct light better (see
/// the module documentation). `tolerance` is τ; `floor` the dark floor's luminance;
/// `coarse_at` each vertex's cheap direct light as far as it is known (the refinement's),
/// completed here.
pub(super) fn flip_edges(
    gatherer: &Gatherer,
    (faces, face_patch): (&mut [[u32; 3]], &[u32]),
    (sites, values, shown): (&[Site], &[Gathered], &[crate::color::Rgb]),
    (tolerance, floor): (f64, f64),
    (coarse_at, visible_fraction): (&mut Coarse, &[f64]),
) -> Flipped {
    let mut done = Flipped::default();
    let mut by_edge = FacesOf::default();
    for (f, &face) in faces.iter().enumerate() {
        for e in face_edges(face) {
            by_edge.add(e, f);
        }
    }
    let mut candidates: Vec<Edge> = by_edge.edges().collect();
    let seed = gatherer.seed();
    for _ in 0..ROUNDS {
        candidates.sort_unstable();
        candidates.dedup();
        let quads: Vec<Quad> = candidates
            .iter()
            .filter_map(|e| quad(gatherer, faces, face_patch, sites, values, &by_edge, *e))
            .filter_map(|q| screened(q, shown, tolerance, floor))
            .collect();
        let quads = if !gatherer.env.coarse_counts_all() {
            quads
        } else {
            promising(
                gatherer,
                quads,
                face_patch,
                sites,
                coarse_at,
                visible_fraction,
            )
        };
        done.tests += quads.len();
        let gains = gatherer.comm.map_shared(
            quads.len(),
            |i| {
                gain(
                    gatherer,
                    &quads[i],
                    face_patch,
                    values,
                    seed,
                    visible_fraction,
                )
            },
            |g, w| w.f64(*g),
            |r| r.f64(),
        );
        let mut order: Vec<(f64, usize)> = gains
            .iter()
            .enumerate()
            .filter(|(i, g)| **g > MARGIN * quads[*i].scale)
            .map(|(i, &g)| (g, i))
            .collect();
        order.sort_unstable_by(|x, y| {
            y.0.total_cmp(&x.0)
                .then((quads[x.1].a, quads[x.1].b).cmp(&(quads[y.1].a, quads[y.1].b)))
        });
        let mut touched = vec![false; faces.len()];
        candidates.clear();
        for (_, i) in order {
            let q = quads[i];
            if touched[q.f1] || touched[q.f2] || by_edge.contains(edge(q.c, q.d)) {
                continue;
            }
            touched[q.f1] = true;
            touched[q.f2] = true;
            for f in [q.f1, q.f2] {
                for e in face_edges(faces[f]) {
                    by_edge.remove(e, f);
                }
            }
            // The quadrilateral a → d → b → c, counter-clockwise: (a, d, c) and (d, b, c).
            faces[q.f1] = [q.a, q.d, q.c];
            faces[q.f2] = [q.d, q.b, q.c];
            for f in [q.f1, q.f2] {
                for e in face_edges(faces[f]) {
                    by_edge.add(e, f);
                    candidates.push(e);
                }
            }
            done.flips += 1;
        }
        if candidates.is_empty() {
            break;
        }
    }
    done
}

fn edge(a: u32, b: u32) -> Edge {
    (a.min(b), a.max(b))
}

/// The quadrilateral around edge `e` if its diagonal may turn: two faces of one flat surface,
/// convex, no end buried (see the module documentation).
fn quad(
    gatherer: &Gatherer,
    faces: &[[u32; 3]],
    face_patch: &[u32],
    sites: &[Site],
    values: &[Gathered],
    by_edge: &FacesOf,
    e: Edge,
) -> Option<Quad> {
    let [f1, f2] = by_edge.pair(e)?;
    // Rotate f1 to (a, b, c) with a → b along it; f2 must run b → a.
    let face = faces[f1];
    let k = (0..3).find(|&k| edge(face[k], face[(k + 1) % 3]) == e)?;
    let (a, b, c) = (face[k], face[(k + 1) % 3], face[(k + 2) % 3]);
    let other = faces[f2];
    let j = (0..3).find(|&j| other[j] == b && other[(j + 1) % 3] == a)?;
    let d = other[(j + 2) % 3];
    if c == d || [a, b, c, d].iter().any(|&v| values[v as usize].buried) {
        return None;
    }
    let p = gatherer.patches;
    let (p1, p2) = (face_patch[f1] as usize, face_patch[f2] as usize);
    let n = p.normal[p1];
    if p.material[p1] != p.material[p2] || n.dot(p.normal[p2]) < 1.0 - 1e-9 {
        return None;
    }
    let at = |v: u32| sites[v as usize].position;
    let (xa, xb, xc, xd) = (at(a), at(b), at(c), at(d));
    let size = xa.distance(xb).max(xc.distance(xd));
    if (xd - xa).dot(n).abs() > 1e-6 * size {
        return None;
    }
    // Convex: both new triangles turn the way the old ones do, with room to spare.
    let area = |u: glam::DVec3, v: glam::DVec3, w: glam::DVec3| (v - u).cross(w - u).dot(n);
    let whole = area(xa, xb, xc) + area(xb, xa, xd);
    if area(xa, xd, xc) <= 1e-6 * whole || area(xd, xb, xc) <= 1e-6 * whole {
        return None;
    }
    // X on both diagonals: a + t (b − a) = c + s (d − c), solved in the plane.
    let (u, v, w) = (xb - xa, xd - xc, xc - xa);
    let det = u.cross(v).dot(n);
    if det.abs() <= 1e-12 * size * size {
        return None;
    }
    let t = w.cross(v).dot(n) / det;
    let s = w.cross(u).dot(n) / det;
    Some(Quad {
        a,
        b,
        c,
        d,
        f1,
        f2,
        t,
        s,
        x: xa + t * u,
        scale: 0.0,
    })
}

/// `q` with its scale if the two diagonals' interpolations of the vertices' luminance at X
/// differ by more than τ × the local luminance (at least `floor`), else `None`.
fn screened(mut q: Quad, shown: &[crate::color::Rgb], tolerance: f64, floor: f64) -> Option<Quad> {
    let y = |v: u32| luminance(shown[v as usize]);
    let along_ab = (1.0 - q.t) * y(q.a) + q.t * y(q.b);
    let along_cd = (1.0 - q.s) * y(q.c) + q.s * y(q.d);
    let reference = (0.5 * (along_ab + along_cd)).max(floor);
    q.scale = tolerance * reference;
    ((along_ab - along_cd).abs() > q.scale).then_some(q)
}

/// How much less the diagonal (c, d) errs than (a, b) in the direct light at X (luminance,
/// radiance units); 0 where X is buried or its exact emitters are not all four vertices'.
fn gain(
    gatherer: &Gatherer,
    q: &Quad,
    face_patch: &[u32],
    values: &[Gathered],
    seed: u64,
    visible_fraction: &[f64],
) -> f64 {
    let site = crossing_site(gatherer, q, face_patch);
    let Some(spot) = gatherer.spot(&site, visible_fraction) else {
        return 0.0;
    };
    let mut rng = Rng::new(&[seed, u64::from(q.c), u64::from(q.d), 0xF11F]);
    let (direct, _, exact) = gatherer.reflected_direct(&spot, MIDPOINT_SHADOW_RAYS, &mut rng);
    let key = gatherer.exact_key(&exact);
    if [q.a, q.b, q.c, q.d]
        .iter()
        .any(|&v| values[v as usize].exact_key != key)
    {
        return 0.0;
    }
    let y = |v: u32| luminance(values[v as usize].direct);
    let at_x = luminance(direct);
    let along_ab = (1.0 - q.t) * y(q.a) + q.t * y(q.b);
    let along_cd = (1.0 - q.s) * y(q.c) + q.s * y(q.d);
    (at_x - along_ab).abs() - (at_x - along_cd).abs()
}

/// The quads of `quads` whose turned diagonal interpolates the cheap, correlated estimate of
/// the direct light at X (`Gatherer::coarse_direct`) better than the one in place,
/// by [`MARGIN`] × τ of the local luminance: the only ones worth the exact evaluation ([`gain`]), at a tenth of its cost each. The
/// estimate sees a shadow that runs along one diagonal (its fixed points on the emitters are
/// hidden from X and from that diagonal's ends alike), not the fine shape of a penumbra.
fn promising(
    gatherer: &Gatherer,
    quads: Vec<Quad>,
    face_patch: &[u32],
    sites: &[Site],
    coarse_at: &mut Coarse,
    visible_fraction: &[f64],
) -> Vec<Quad> {
    let ends = quads.iter().flat_map(|q| [q.a, q.b, q.c, q.d]);
    complete_coarse(gatherer, sites, ends, coarse_at, visible_fraction);
    let coarse_at = &*coarse_at;
    let keep = gatherer.comm.map_shared(
        quads.len(),
        |i| {
            let q = &quads[i];
            let ends = [q.a, q.b, q.c, q.d].map(|v| coarse_at[&v]);
            let Some(ends) = ends.iter().copied().collect::<Option<Vec<_>>>() else {
                return false;
            };
            let site = crossing_site(gatherer, q, face_patch);
            let Some((key, at_x)) = coarse_direct_at(gatherer, &site, visible_fraction) else {
                return false;
            };
            if ends.iter().any(|&(k, _)| k != key) {
                return false;
            }
            let y = |k: usize| luminance(ends[k].1);
            let at_x = luminance(at_x);
            let along_ab = (1.0 - q.t) * y(0) + q.t * y(1);
            let along_cd = (1.0 - q.s) * y(2) + q.s * y(3);
            (at_x - along_ab).abs() - (at_x - along_cd).abs() > MARGIN * q.scale
        },
        |k, w| w.bytes(&[u8::from(*k)]),
        |r| r.bytes::<1>()[0] != 0,
    );
    quads
        .into_iter()
        .zip(keep)
        .filter_map(|(q, k)| k.then_some(q))
        .collect()
}

/// The site of X, on the quad's two patches.
fn crossing_site(gatherer: &Gatherer, q: &Quad, face_patch: &[u32]) -> Site {
    let patches = crate::bake::SitePatches::from_slice(&[face_patch[q.f1], face_patch[q.f2]]);
    Site {
        position: q.x,
        normal: gatherer.patches.normal[patches[0] as usize],
        patches,
        shared: false,
        mesh_vertex: u32::MAX,
        gap: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Adds and removes faces on a few edges, three and four a time on some (a non-manifold
    /// output), and a face listed twice on one (a degenerate face), checking after each step
    /// what the flips read against a plain list per edge.
    #[test]
    fn faces_of_edges_match_a_list_per_edge() {
        let mut faces = FacesOf::default();
        let mut lists: HashMap<Edge, Vec<usize>> = HashMap::new();
        let mut rng = Rng::new(&[7]);
        for step in 0..4000 {
            let e = (rng.below(4) as u32, 9);
            let f = rng.below(6);
            if rng.next_f64() < 0.55 {
                faces.add(e, f);
                lists.entry(e).or_default().push(f);
            } else {
                faces.remove(e, f);
                if let Some(list) = lists.get_mut(&e) {
                    list.retain(|&g| g != f);
                    if list.is_empty() {
                        lists.remove(&e);
                    }
                }
            }
            for k in 0..4 {
                let e = (k, 9);
                let want = lists
                    .get(&e)
                    .and_then(|l| <[usize; 2]>::try_from(l.as_slice()).ok());
                assert_eq!(
                    faces.pair(e),
                    want,
                    "step {step}, edge {e:?}: {:?}",
                    lists.get(&e)
                );
                assert_eq!(faces.contains(e), lists.contains_key(&e), "step {step}");
            }
        }
        let mut edges: Vec<Edge> = faces.edges().collect();
        edges.sort_unstable();
        let mut want: Vec<Edge> = lists.keys().copied().collect();
        want.sort_unstable();
        assert_eq!(edges, want);
    }
}
