//! The emitters with the largest bounds at a point, found by a bounding-volume hierarchy over
//! them instead of by weighing every one: the candidates for a gathering point's exact
//! emitters ([`super::Gatherer::exact_emitters`]) in a scene of many emitting triangles (the
//! generated hall of 10⁶ triangles has 7,570), where the weighing had cost every point (every
//! output vertex, every midpoint test of the display refinement) time in proportion to them.
//!
//! An emitter's key at x is its bound ([`Emitter::bound`], power / (π d²), d the distance to
//! its bounding sphere, at least a thousandth of its radius) plus its partner's (the other
//! half of its quadrilateral, if any). A node's box holds the bounding spheres of its members
//! and of their partners, so no member's key exceeds the node's largest sum of the two powers
//! over π·max(D, r/1000)², D the distance from x to the box and r the least radius among them.
//! The search visits a node only while that bound reaches the k-th largest key found so far
//! (branch and bound), so it returns what weighing every emitter returns, ties to the lower
//! index included.

use glam::DVec3;

use crate::light::Emitter;

/// Emitters from which a scene's exact emitters are found by the tree: below, weighing them
/// all is cheap next to a point's direct light.
pub const INDEX_FROM: usize = 64;

/// Emitters in a leaf, at most.
const LEAF: usize = 4;

/// A node's bound is raised by this relative amount, so that rounding in the distances cannot
/// put a member's key above it.
const SLACK: f64 = 1e-9;

/// A bounding-volume hierarchy over the emitters, for [`Brightest::top`].
pub(super) struct Brightest {
    nodes: Vec<Node>,
    /// The emitters' indices, each leaf's a consecutive run.
    order: Vec<u32>,
}

/// A node: the box around its members' and their partners' bounding spheres, the largest sum
/// of a member's power and its partner's, the least radius among them, and either its members
/// (`count` > 0: `order[first..first + count]`) or its two children (`count` = 0:
/// `nodes[first]` and `nodes[second]`).
struct Node {
    lo: DVec3,
    hi: DVec3,
    power: f64,
    radius: f64,
    first: u32,
    second: u32,
    count: u32,
}

impl Brightest {
    /// The tree over `emitters`, `partner[k]` the other half of emitter k's quadrilateral if
    /// any.
    pub(super) fn new(emitters: &[Emitter], partner: &[Option<u32>]) -> Brightest {
        let mut tree = Brightest {
            nodes: Vec::with_capacity(2 * emitters.len() / LEAF + 1),
            order: (0..emitters.len() as u32).collect(),
        };
        if !emitters.is_empty() {
            tree.build(emitters, partner, 0, emitters.len());
        }
        tree
    }

    /// Builds the node over `order[from..to]` (split at the median of the centres along the
    /// box's longest axis), returning its index.
    fn build(
        &mut self,
        emitters: &[Emitter],
        partner: &[Option<u32>],
        from: usize,
        to: usize,
    ) -> u32 {
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        let (mut power, mut radius) = (0.0_f64, f64::INFINITY);
        let (mut clo, mut chi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for &k in &self.order[from..to] {
            let e = &emitters[k as usize];
            let mut sum = e.power;
            for m in std::iter::once(e).chain(partner[k as usize].map(|j| &emitters[j as usize])) {
                lo = lo.min(m.centre - DVec3::splat(m.radius));
                hi = hi.max(m.centre + DVec3::splat(m.radius));
                radius = radius.min(m.radius);
            }
            if let Some(j) = partner[k as usize] {
                sum += emitters[j as usize].power;
            }
            power = power.max(sum);
            clo = clo.min(e.centre);
            chi = chi.max(e.centre);
        }
        let at = self.nodes.len();
        self.nodes.push(Node {
            lo,
            hi,
            power,
            radius,
            first: from as u32,
            second: 0,
            count: (to - from) as u32,
        });
        if to - from > LEAF {
            let axis = (chi - clo).max_position();
            let mid = (from + to) / 2;
            self.order[from..to].select_nth_unstable_by(mid - from, |&a, &b| {
                let (ca, cb) = (emitters[a as usize].centre, emitters[b as usize].centre);
                ca[axis].total_cmp(&cb[axis]).then(a.cmp(&b))
            });
            let first = self.build(emitters, partner, from, mid);
            let second = self.build(emitters, partner, mid, to);
            let node = &mut self.nodes[at];
            (node.first, node.second, node.count) = (first, second, 0);
        }
        at as u32
    }

    /// The `k` largest `(key(e), e)` at `x`, by key and then by the lower index, largest
    /// first: what sorting every emitter's `key` would put first. `key(e)` must be at most
    /// emitter e's bound plus its partner's at `x` (see the module documentation).
    pub(super) fn top(&self, x: DVec3, k: usize, key: impl Fn(u32) -> f64) -> Vec<(f64, u32)> {
        let mut best: Vec<(f64, u32)> = Vec::with_capacity(k + 1);
        if self.nodes.is_empty() || k == 0 {
            return best;
        }
        // Before `b` in the order sought: a larger key, or the same key and a lower index.
        let before = |a: &(f64, u32), b: &(f64, u32)| a.0 > b.0 || (a.0 == b.0 && a.1 < b.1);
        let mut stack = vec![0u32];
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n as usize];
            if best.len() == k && self.bound(node, x) < best[k - 1].0 {
                continue;
            }
            if node.count > 0 {
                let members = &self.order[node.first as usize..(node.first + node.count) as usize];
                for &e in members {
                    let entry = (key(e), e);
                    if best.len() == k && !before(&entry, &best[k - 1]) {
                        continue;
                    }
                    let at = best.partition_point(|b| before(b, &entry));
                    best.insert(at, entry);
                    best.truncate(k);
                }
            } else {
                // The child of the larger bound is searched first (pushed last).
                let (a, b) = (node.first, node.second);
                let (ba, bb) = (
                    self.bound(&self.nodes[a as usize], x),
                    self.bound(&self.nodes[b as usize], x),
                );
                if ba >= bb {
                    stack.extend([b, a]);
                } else {
                    stack.extend([a, b]);
                }
            }
        }
        best
    }

    /// The most any member's key can be at `x`.
    fn bound(&self, node: &Node, x: DVec3) -> f64 {
        let d = (node.lo - x).max(x - node.hi).max(DVec3::ZERO).length();
        let d = d.max(1e-3 * node.radius);
        node.power / (std::f64::consts::PI * d * d) * (1.0 + SLACK)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// The tree's top k are the linear scan's, over random emitters of unequal power and size,
    /// paired and not, from points inside and outside their spheres.
    #[test]
    fn the_tree_finds_what_weighing_every_emitter_finds() {
        let mut rng = Rng::new(&[7]);
        let mut emitters = Vec::new();
        for i in 0..300 {
            let c = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 10.0;
            let s = 0.05 + 0.5 * rng.next_f64();
            let corners = [c, c + DVec3::new(s, 0.0, 0.0), c + DVec3::new(0.0, s, 0.0)];
            // Some emitters share a power exactly, so that ties occur.
            let le = if i % 7 == 0 {
                5.0
            } else {
                1.0 + 20.0 * rng.next_f64()
            };
            emitters.push(Emitter::new(corners, DVec3::Z, [le; 3]));
        }
        // Every fifth emitter paired with the next.
        let mut partner = vec![None; emitters.len()];
        for k in (0..emitters.len() - 1).step_by(5) {
            partner[k] = Some(k as u32 + 1);
            partner[k + 1] = Some(k as u32);
        }
        let tree = Brightest::new(&emitters, &partner);
        for _ in 0..200 {
            let x = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 12.0 - 1.0;
            let own = |k: u32| emitters[k as usize].bound(x);
            let key = |k: u32| own(k) + partner[k as usize].map_or(0.0, own);
            let mut all: Vec<(f64, u32)> =
                (0..emitters.len() as u32).map(|k| (key(k), k)).collect();
            all.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
            for k in [1, 16, 40] {
                assert_eq!(tree.top(x, k, key), all[..k].to_vec(), "k = {k} at {x}");
            }
        }
        // From a point at an emitter's centre (inside its sphere): it comes first.
        let x = emitters[123].centre;
        let own = |k: u32| emitters[k as usize].bound(x);
        assert_eq!(tree.top(x, 1, own)[0].1, 123);
    }
}
