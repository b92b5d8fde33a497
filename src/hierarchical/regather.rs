//! The leaves' final gather: once the links have converged, each leaf's reflected light
//! G is estimated again by rays from its own points, reading the radiance of the leaves the
//! rays hit, in place of what its links brought. One Jacobi step of the rendering equation
//! with its transport traced exactly (Ĝ(e) = mean over e's points x of ∫_Ω L_r(h(x, ω))
//! cosθ/π dω), started from the hierarchical solution.
//!
//! Why: a link carries its transport as a whole. A cluster source or a receiver larger than
//! the shadows within it spreads visibility over the whole link (the floor under a desk
//! gathers the ceiling's light as the open floor beside it does; the desk's underside then
//! reads that floor too bright), and its few rays' visible share is noisy. The rays of this
//! step see what each leaf sees. Its error is the links' error carried one bounce further,
//! where it is damped by the reflectance of what the rays meet (L' − L* = K(L − L*) for the
//! exact transport K): the final gather at the vertices ([`crate::gather`]) takes a second
//! such step. This is the two-step scheme of Lischinski, Tampieri & Greenberg ("Combining
//! hierarchical radiosity and discontinuity meshing", SIGGRAPH 1993, §5: the final pass
//! re-evaluates every element's radiance from the converged solution) with the links' part
//! traced, as in the photon map's final gather (Jensen 1996).
//!
//! Only the reflected part is traced: the emitters' direct light stays the elements' own
//! ([`super::direct`]), so the step runs only when every emitter's light is computed that way
//! (no root's emission travels by link): rays that read a small lamp's emission would be far
//! noisier than the links. A leaf's points are its receiver rule's unburied points
//! ([`super::rule::receiver_rule`]), each ray at one of them chosen with the rule's weight,
//! the directions stratified over the hemisphere (Malley's method). Random numbers are keyed
//! by (seed, leaf): the same result for any thread or rank count.

use glam::DVec3;
use rayon::prelude::*;

use super::rule::{receiver_rule, unburied_weights};
use super::tree::{self, Tree};
use super::Hierarchy;
use crate::color::Rgb;
use crate::geometry::frame::orthonormal_basis;
use crate::sampling::{malley, permutation, Rng};

/// Steps of the leaves' final gather, each reading the last one's radiance. Each step damps
/// what the links got wrong by the reflectance the rays meet, so the second still takes out
/// a useful part of it (on a furnished office under ceiling panels, the floor under the desks
/// kept about half of its bias after one step, a third after two: BENCHMARKS.md), a third
/// little more. A step costs [`Settings::regather_rays`](super::Settings::regather_rays)
/// closest-hit rays a leaf, a few per cent of a solve's rays.
pub const STEPS: usize = 2;

/// Rays of one step over all leaves, when the leaves are few enough to get more than the
/// least ([`Settings::regather_rays`](super::Settings::regather_rays)) each, up to
/// [`MOST_RAYS`]. A leaf's estimate is noisy at a few dozen rays (a sunlit floor seen past
/// a wall's shadow line: ±30 % a leaf at 32 rays). Where a vertex gather follows, its
/// thousand rays meet hundreds of leaves and average that noise away; where the leaves are
/// few, each one's noise shows in the surfaces' means (a courtyard of a hundred leaves:
/// −5 % on a wall at 32 rays a leaf, within 0.1 % at 1,024), and more rays a leaf cost
/// little there.
pub const BUDGET: usize = 1 << 20;

/// The most rays a leaf, however few the leaves.
pub const MOST_RAYS: usize = 1024;

/// Rays a leaf of one step over `leaves` leaves, at least `least` ([`BUDGET`],
/// [`MOST_RAYS`]), rounded up to the square of the strata a side that cast them; 0 when
/// `least` is 0 (no final gather).
pub fn rays_per_leaf(leaves: usize, least: usize) -> usize {
    if least == 0 {
        return 0;
    }
    let rays = (BUDGET / leaves.max(1)).clamp(least, MOST_RAYS.max(least));
    let side = (rays as f64).sqrt().ceil() as usize;
    side * side
}

impl Hierarchy<'_> {
    /// Whether every root's emission reaches the elements as their own direct light, so that
    /// [`Hierarchy::regather`] traces only reflected light.
    pub(super) fn regather_applies(&self) -> bool {
        (0..self.roots.len()).all(|r| self.exact[r] || self.roots.emission[r] == [0.0; 3])
    }

    /// Replaces every leaf's gathered light by a traced estimate (module docs): L = Le +
    /// ρ·(D + Ĝ), with at least `least` rays a leaf, more while the leaves are few
    /// ([`BUDGET`], [`MOST_RAYS`]). Returns the rays cast on this rank. Nothing happens where
    /// [`Hierarchy::regather_applies`] fails or `least` is 0.
    pub(super) fn regather(&mut self, least: usize) -> u64 {
        if least == 0 || !self.regather_applies() {
            return 0;
        }
        let t = &self.tree;
        let n = t.elements.len();
        let leaves = t
            .elements
            .iter()
            .filter(|el| el.first_child == tree::NO_CHILD)
            .count();
        let rays = rays_per_leaf(leaves, least);
        let new: Vec<Option<Rgb>> = (0..n)
            .into_par_iter()
            .map(|e| {
                let el = &t.elements[e];
                let r = el.root as usize;
                let rho = self.roots.reflectance[r];
                if el.first_child != tree::NO_CHILD
                    || !self.owns_element(e)
                    || rho == [0.0; 3]
                    || self.visible[e] == 0.0
                {
                    return None;
                }
                let g = self.gathered_by_rays(e, rays);
                let d = self.direct[e].mean;
                let le = self.carried_emission(r);
                Some(std::array::from_fn(|c| le[c] + rho[c] * (d[c] + g[c])))
            })
            .collect();
        let cast = new.iter().filter(|v| v.is_some()).count() as u64 * rays as u64;
        let write = |w: &mut crate::distributed::Writer, v: &Option<Rgb>| match v {
            Some(l) => {
                w.u32(1);
                l.iter().for_each(|&x| w.f64(x));
            }
            None => w.u32(0),
        };
        let read = |r: &mut crate::distributed::Reader| {
            (r.u32() == 1).then(|| [r.f64(), r.f64(), r.f64()])
        };
        let new = self.owners_values(0, new, write, read);
        for (e, v) in new.into_iter().enumerate() {
            if let Some(l) = v {
                self.elem_l[e] = l;
            }
        }
        cast
    }

    /// Ĝ of leaf `e` by `rays` rays (radiance units, before ρ): the mean of what the leaves
    /// they hit send ([`Hierarchy::elem_l`]); a miss or the back of a face brings nothing
    /// (the sky's light is in the leaf's direct light).
    pub(super) fn gathered_by_rays(&self, e: usize, rays: usize) -> Rgb {
        let t = &self.tree;
        let el = &t.elements[e];
        let rule = receiver_rule();
        let weights = unburied_weights(self.buried[e]);
        let total: f64 = weights.iter().sum();
        let mut rng = Rng::new(&[self.seed, e as u64, 0x4E6A7]);
        let n = el.normal;
        let (tangent, bitangent) = orthonormal_basis(n);
        let side = (rays as f64).sqrt().ceil() as usize;
        let count = side * side;
        // Which point each ray leaves from: the rule's weights' inverse distribution at
        // stratified positions, shuffled against the direction strata.
        let order = permutation(count, &mut rng);
        let mut sum = [0.0; 3];
        for (m, &slot) in order.iter().enumerate() {
            let (i, j) = (m / side, m % side);
            let s = (i as f64 + rng.next_f64()) / side as f64;
            let u = (j as f64 + rng.next_f64()) / side as f64;
            let mut q = (slot as f64 + rng.next_f64()) / count as f64 * total;
            let mut k = 0;
            while k + 1 < weights.len() && (q >= weights[k] || weights[k] == 0.0) {
                q -= weights[k];
                k += 1;
            }
            let x = t.point(e, rule[k].0);
            let dir = malley(s, u, tangent, bitangent, n);
            let Some(hit) = self.vis.closest_hit(x, dir, f64::INFINITY, el.root) else {
                continue;
            };
            let h = hit.triangle as usize;
            if self.roots.normal[h].dot(dir) >= 0.0 {
                continue; // the back of a face
            }
            let leaf = t.leaf_at(h, barycentrics(t.corners(h), x + hit.t * dir));
            for (a, b) in sum.iter_mut().zip(self.elem_l[leaf]) {
                *a += b;
            }
        }
        sum.map(|a| a / count as f64)
    }
}

/// The barycentric coordinates of `p` (on or near the plane of `c`) in triangle `c`
/// ([`crate::mesh::barycentric`]), clamped into the triangle: a hit rounded just past an edge.
fn barycentrics(c: [DVec3; 3], p: DVec3) -> [f64; 3] {
    let b = crate::mesh::barycentric(p, c).map(|x| x.max(0.0));
    let s: f64 = b.iter().sum();
    b.map(|x| x / s)
}

impl Tree {
    /// The leaf below root element `root` holding the point with barycentrics `b` on the
    /// root's corners: down through [`Tree::split`]'s quarters ([`tree::quarter_of`]).
    pub fn leaf_at(&self, root: usize, mut b: [f64; 3]) -> usize {
        let mut e = root;
        loop {
            let first = self.elements[e].first_child;
            if first == tree::NO_CHILD {
                return e;
            }
            let q = tree::quarter_of(b);
            // The point's barycentrics on the child's corners ([`Tree::split`]'s order):
            // a corner's quarter doubles the coordinates, the middle one is 1 − 2b.
            b = match q {
                3 => b.map(|x| 1.0 - 2.0 * x),
                k => std::array::from_fn(|j| {
                    if j == k as usize {
                        2.0 * b[j] - 1.0
                    } else {
                        2.0 * b[j]
                    }
                }),
            };
            b = b.map(|x| x.max(0.0));
            e = first as usize + q as usize;
        }
    }
}
