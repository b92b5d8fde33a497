//! The traversal: a four-wide BVH of our own, tested four boxes or four triangles at a time
//! with SIMD (`wide::f32x4`: SSE2 on x86-64, NEON on AArch64, plain arrays elsewhere, the same
//! IEEE operations on every path, so the same answers).
//!
//! obvhs builds the tree (a binary BVH by PLOC over the padded triangle boxes, the builder the
//! wide CWBVH came from); [`Bvh4::build`] collapses it into nodes of four children, the way
//! Embree's BVH4 is laid out (Wald et al., "Embree: A Kernel Framework for Efficient CPU Ray
//! Tracing", SIGGRAPH 2014): each node holds its children's boxes as structure-of-arrays, so one
//! slab test decides all four, and every subtree of at most four triangles becomes one leaf
//! *packet* holding its triangles' corners as structure-of-arrays, so one watertight test decides
//! all four.
//!
//! The triangle test is [`WatertightRay::intersect`] evaluated lane by lane with the same
//! operations in the same order (ray-space transform, edge functions, the sign rules, the scaled
//! distance), so every lane decides exactly as the scalar test; a lane whose edge function is
//! exactly zero (the ray through an edge or a corner, or in the triangle's plane) has its edge
//! functions recomputed in `f64` as the scalar test does. The box test is the slab test in `f32` on
//! boxes padded by [`super::BOX_PAD`], which is far larger than its rounding, so a box is never
//! missed by a ray that meets a triangle inside it: the traversal visits a superset of what it
//! must, and the answers are those of testing every triangle (the brute-force oracle of the tests).
//!
//! Nothing is allocated per query: the traversal stack is a fixed array on the call stack,
//! sized by the tree's depth at build time (a heap stack only for trees deeper than
//! `STACK` allows, which no builder output here comes near).
//!
//! Unit tests (in `super::tests`): every lane of [`Ray4::hits`] equals the scalar test on
//! random, grid-aligned (rays through edges and corners), coplanar and scaled triangles; the
//! queries equal the brute-force oracles.

use std::time::Duration;

use glam::Vec3A;
use obvhs::aabb::Aabb;
use obvhs::bvh2::builder::build_bvh2;
use obvhs::BvhBuildParams;
use wide::f32x4;

use super::ray::{exact_edges, WatertightRay};

/// Flag of a child that is a leaf packet (the rest of the word is the packet's index).
const LEAF: u32 = 1 << 31;

/// An empty child slot (its box is inverted, so no ray enters it).
const EMPTY: u32 = u32::MAX;

/// Factor by which [`Bvh4::closest`] widens the best hit's parameter before pruning with it:
/// 2⁻¹⁰ relative, far more than the rounding of the scaled comparison (a few ulp) and far less
/// than any gap that matters (a pruned box lies farther by its padding).
const BOUND_SLACK: f32 = 1.0 + 1.0 / 1024.0;

/// Entries of the fixed traversal stack; a tree needs at most `3 × depth + 2` (each node popped
/// pushes at most four children in place of itself).
const STACK: usize = 64;

/// Four children's boxes (canonical units), structure-of-arrays: lane `i` of `lo[k]` is the
/// lower bound of child `i` along axis `k`. Invariant: an [`EMPTY`] child's box has
/// `lo = +∞`, `hi = −∞`.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Node {
    lo: [f32x4; 3],
    hi: [f32x4; 3],
    child: [u32; 4],
}

/// Up to four triangles (canonical units), structure-of-arrays: lane `i` of `v[c][k]` is
/// coordinate `k` of corner `c` of triangle `prim[i]` (an index into the caller's triangle
/// list). Invariant: a packet of fewer than four triangles repeats its last one in the unused
/// lanes (a repeated test gives the repeated answer).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
struct Packet {
    v: [[f32x4; 3]; 3],
    prim: [u32; 4],
}

/// A four-wide BVH over triangles in the canonical frame.
///
/// Invariants: `root` is [`EMPTY`] (no triangles), `LEAF | p` for a packet index `p`, or a node
/// index; every triangle index `0..n` given to [`Bvh4::build`] is in exactly one packet lane
/// (possibly repeated within it); `depth` bounds the number of nodes on any root-to-leaf path.
#[derive(Clone, Debug, Default)]
pub(super) struct Bvh4 {
    nodes: Vec<Node>,
    packets: Vec<Packet>,
    root: u32,
    depth: usize,
}

/// The ray as the four-lane tests need it, prepared once per query.
struct Ray4 {
    /// Origin, each coordinate in every lane.
    origin: [f32x4; 3],
    /// Per axis: 1/direction (a large finite value for a zero component).
    inv: [f32x4; 3],
    /// Per axis: the direction is negative, so the near plane is the box's upper bound.
    negative: [bool; 3],
    /// The permutation to ray space ([`WatertightRay::k`]).
    k: [usize; 3],
    /// The shear constants ([`WatertightRay::s`]), in every lane.
    s: [f32x4; 3],
}

impl Ray4 {
    fn new(ray: &WatertightRay) -> Ray4 {
        let inv = |d: f32| {
            // A zero component gets a large finite inverse: the slab is then all or nothing
            // (no 0·∞ = NaN), decided by whether the origin lies between the planes.
            let i = 1.0 / d;
            if i.is_finite() {
                i
            } else {
                1e30
            }
        };
        let i = [inv(ray.dir.x), inv(ray.dir.y), inv(ray.dir.z)];
        Ray4 {
            origin: ray.origin.to_array().map(f32x4::splat),
            inv: i.map(f32x4::splat),
            negative: i.map(|i| i < 0.0),
            k: ray.k,
            s: ray.s.map(f32x4::splat),
        }
    }

    /// Slab test of the four boxes of `node` for parameters in `[t_lo, t_hi]`: a bit per child
    /// whose box the ray enters, and the entry parameters.
    #[inline(always)]
    fn enter(&self, node: &Node, t_lo: f32x4, t_hi: f32x4) -> (u32, f32x4) {
        let mut near = t_lo;
        let mut far = t_hi;
        for k in 0..3 {
            let (n, f) = if self.negative[k] {
                (node.hi[k], node.lo[k])
            } else {
                (node.lo[k], node.hi[k])
            };
            near = near.fast_max((n - self.origin[k]) * self.inv[k]);
            far = far.fast_min((f - self.origin[k]) * self.inv[k]);
        }
        (near.simd_le(far).to_bitmask(), near)
    }

    /// Corner `c` of the packet's four triangles in ray space: the operations of
    /// [`WatertightRay::intersect`]'s step 3.
    #[inline(always)]
    fn corner(&self, p: &Packet, c: usize) -> [f32x4; 3] {
        let [kx, ky, kz] = self.k;
        let v = &p.v[c];
        let a = [
            v[0] - self.origin[0],
            v[1] - self.origin[1],
            v[2] - self.origin[2],
        ];
        [
            a[kx] - self.s[0] * a[kz],
            a[ky] - self.s[1] * a[kz],
            self.s[2] * a[kz],
        ]
    }

    /// The lanes of `p` whose triangle the ray meets for internal parameters in
    /// `[t_lo, t_hi]`, as a bit mask, by the steps of [`WatertightRay::intersect`] on four lanes
    /// (a lane whose edge function is exactly zero has all three recomputed in `f64`, as
    /// there).
    #[inline(always)]
    fn hits(&self, p: &Packet, t_lo: f32, t_hi: f32) -> u32 {
        let (a, b, c) = (self.corner(p, 0), self.corner(p, 1), self.corner(p, 2));
        let mut e0 = c[0] * b[1] - c[1] * b[0];
        let mut e1 = a[0] * c[1] - a[1] * c[0];
        let mut e2 = b[0] * a[1] - b[1] * a[0];
        let zero = f32x4::ZERO;
        let on_edge = (e0.simd_eq(zero) | e1.simd_eq(zero) | e2.simd_eq(zero)).to_bitmask();
        if on_edge != 0 {
            // Step 5 lane by lane: the products of f32 values are exact in f64.
            let [a, b, c] = [a, b, c].map(|v| v.map(|x| x.to_array()));
            let (mut f0, mut f1, mut f2) = (e0.to_array(), e1.to_array(), e2.to_array());
            for i in lanes(on_edge) {
                let xy = |v: &[[f32; 4]; 3]| [v[0][i], v[1][i]];
                [f0[i], f1[i], f2[i]] = exact_edges(xy(&a), xy(&b), xy(&c));
            }
            (e0, e1, e2) = (f32x4::from(f0), f32x4::from(f1), f32x4::from(f2));
        }
        let negative = e0.simd_lt(zero) | e1.simd_lt(zero) | e2.simd_lt(zero);
        let positive = e0.simd_gt(zero) | e1.simd_gt(zero) | e2.simd_gt(zero);
        let det = e0 + e1 + e2;
        let t_scaled = e0 * a[2] + e1 * b[2] + e2 * c[2];
        // t_scaled with the sign of det, against the interval scaled by |det|.
        let sign = det & f32x4::splat(-0.0);
        let t_signed = t_scaled ^ sign;
        let det_abs = det.abs();
        let outside = (negative & positive)
            | det.simd_eq(zero)
            | t_signed.simd_lt(f32x4::splat(t_lo) * det_abs)
            | t_signed.simd_gt(f32x4::splat(t_hi) * det_abs);
        !outside.to_bitmask() & 0xf
    }
}

impl Bvh4 {
    /// The tree over `tris` (canonical frame), whose padded boxes are `boxes`. Triangle `i`
    /// is reported as `i`.
    pub fn build(tris: &[[Vec3A; 3]], boxes: &[Aabb]) -> Bvh4 {
        if tris.is_empty() {
            return Bvh4 {
                root: EMPTY,
                ..Bvh4::default()
            };
        }
        let params = BvhBuildParams {
            max_prims_per_leaf: 1,
            ..BvhBuildParams::fast_build()
        };
        let bvh2 = build_bvh2(boxes, params, &mut Duration::default());
        let nodes2 = &bvh2.nodes;
        // Triangles under each binary node (the children of inner node n are
        // nodes2[first_index] and nodes2[first_index + 1]; a leaf lists prim_count of
        // primitive_indices), children before parents: the optimiser moves nodes, so the
        // array's order says nothing.
        let mut count = vec![0u32; nodes2.len()];
        let mut todo = vec![(0usize, false)];
        while let Some((n, children_done)) = todo.pop() {
            let node = &nodes2[n];
            let f = node.first_index as usize;
            if node.prim_count > 0 {
                count[n] = node.prim_count;
            } else if children_done {
                count[n] = count[f] + count[f + 1];
            } else {
                todo.extend([(n, true), (f, false), (f + 1, false)]);
            }
        }
        let mut out = Bvh4::default();
        // Every triangle under binary node n, in the tree's order.
        let triangles_under = |n: usize, into: &mut Vec<u32>| {
            let mut todo = vec![n];
            while let Some(m) = todo.pop() {
                let node = &nodes2[m];
                if node.prim_count > 0 {
                    let f = node.first_index as usize;
                    into.extend(&bvh2.primitive_indices[f..f + node.prim_count as usize]);
                } else {
                    todo.push(node.first_index as usize + 1);
                    todo.push(node.first_index as usize);
                }
            }
        };
        let area = |n: usize| nodes2[n].aabb().half_area();
        // Work list: (binary node, slot (node, child) to patch with its encoding, depth).
        type Slot = Option<(usize, usize)>;
        let mut todo: Vec<(usize, Slot, usize)> = vec![(0, None, 1)];
        let mut scratch = Vec::new();
        while let Some((n, slot, depth)) = todo.pop() {
            let encoded = if count[n] <= 4 {
                scratch.clear();
                triangles_under(n, &mut scratch);
                let packet = Packet::new(tris, &scratch);
                out.packets.push(packet);
                LEAF | (out.packets.len() - 1) as u32
            } else {
                // Open the largest child until there are four (or only leaves-to-be remain).
                let first = nodes2[n].first_index as usize;
                let mut kids = vec![first, first + 1];
                while kids.len() < 4 {
                    let open = kids
                        .iter()
                        .enumerate()
                        .filter(|(_, &k)| count[k] > 4)
                        .max_by(|a, b| area(*a.1).total_cmp(&area(*b.1)))
                        .map(|(i, _)| i);
                    let Some(i) = open else { break };
                    let k = kids.swap_remove(i);
                    let f = nodes2[k].first_index as usize;
                    kids.extend([f, f + 1]);
                }
                let index = out.nodes.len();
                out.nodes.push(Node::empty());
                out.depth = out.depth.max(depth);
                for (i, &k) in kids.iter().enumerate() {
                    let b = nodes2[k].aabb();
                    let node = &mut out.nodes[index];
                    for axis in 0..3 {
                        node.lo[axis] = set_lane(node.lo[axis], i, b.min[axis]);
                        node.hi[axis] = set_lane(node.hi[axis], i, b.max[axis]);
                    }
                    todo.push((k, Some((index, i)), depth + 1));
                }
                index as u32
            };
            match slot {
                Some((node, i)) => out.nodes[node].child[i] = encoded,
                None => out.root = encoded,
            }
        }
        out
    }

    /// True if the ray meets a triangle `i` with internal parameter in `[ray.t_lo, ray.t_hi]`
    /// for which `blocks(i)` holds (called only for triangles met).
    pub fn any_hit(&self, ray: &WatertightRay, blocks: impl Fn(usize) -> bool) -> bool {
        self.each_hit(ray, blocks)
    }

    /// Calls `visit(i)` once for every triangle `i` the ray meets with internal parameter in
    /// `[ray.t_lo, ray.t_hi]` (the four-lane test, exact as the scalar one), in no particular
    /// order, until `visit` returns true (then returns true).
    pub fn each_hit(&self, ray: &WatertightRay, mut visit: impl FnMut(usize) -> bool) -> bool {
        if self.root == EMPTY {
            return false;
        }
        let r4 = Ray4::new(ray);
        let (t_lo, t_hi) = (f32x4::splat(ray.t_lo), f32x4::splat(ray.t_hi));
        self.walk(
            |node| r4.enter(node, t_lo, t_hi).0,
            |p| {
                let mask = r4.hits(p, ray.t_lo, ray.t_hi);
                lanes(mask).any(|lane| {
                    // A packet repeats a triangle to fill its lanes: visit each once.
                    !p.prim[..lane].contains(&p.prim[lane]) && visit(p.prim[lane] as usize)
                })
            },
        )
    }

    /// Depth first over the tree until `leaf` returns true (then returns true): `enter(node)`
    /// gives a bit per child to descend into, and `leaf(packet)` is called for every packet
    /// reached, a node's leaf children before its inner children are opened (so a query that
    /// a leaf can end, like [`Bvh4::any_hit`], opens no more nodes than it must).
    #[inline(always)]
    fn walk(
        &self,
        mut enter: impl FnMut(&Node) -> u32,
        mut leaf: impl FnMut(&Packet) -> bool,
    ) -> bool {
        self.with_stack(|stack| {
            let mut top = 0;
            stack[top] = self.root;
            top += 1;
            while top > 0 {
                top -= 1;
                let c = stack[top];
                if c & LEAF != 0 {
                    if leaf(&self.packets[(c & !LEAF) as usize]) {
                        return true;
                    }
                    continue;
                }
                let node = &self.nodes[c as usize];
                for i in lanes(enter(node)) {
                    let child = node.child[i];
                    if child & LEAF != 0 {
                        if leaf(&self.packets[(child & !LEAF) as usize]) {
                            return true;
                        }
                    } else {
                        stack[top] = child;
                        top += 1;
                    }
                }
            }
            false
        })
    }

    /// Visits every triangle `i` the ray may meet with internal parameter in
    /// `[ray.t_lo, bound]`, calling `hit(i)`, where `bound` starts at `ray.t_hi` and becomes
    /// what `hit` returns (the best hit's parameter so far; `None` leaves it). Children are
    /// visited nearest first, so far subtrees are pruned. The bound is widened by
    /// [`BOUND_SLACK`] before it prunes, so a triangle whose exact parameter ties the best is
    /// still visited: the caller's choice among ties is then independent of the visiting
    /// order.
    pub fn closest(&self, ray: &WatertightRay, mut hit: impl FnMut(usize) -> Option<f32>) {
        if self.root == EMPTY {
            return;
        }
        let r4 = Ray4::new(ray);
        let t_lo = f32x4::splat(ray.t_lo);
        let mut t_hi = ray.t_hi;
        let mut leaf = |p: &Packet, t_hi: &mut f32| {
            // Lanes that may hit within the current bound; each is then decided (and its hit
            // recorded) by the caller's exact test, in lane order.
            let mask = r4.hits(p, ray.t_lo, *t_hi);
            for lane in lanes(mask) {
                if lane > 0 && p.prim[..lane].contains(&p.prim[lane]) {
                    continue; // a repeated lane
                }
                if let Some(t) = hit(p.prim[lane] as usize) {
                    *t_hi = (t * BOUND_SLACK).min(ray.t_hi);
                }
            }
        };
        self.with_stack(|stack| {
            let mut top = 0;
            stack[top] = self.root;
            top += 1;
            while top > 0 {
                top -= 1;
                let c = stack[top];
                if c & LEAF != 0 {
                    leaf(&self.packets[(c & !LEAF) as usize], &mut t_hi);
                    continue;
                }
                let node = &self.nodes[c as usize];
                let (mask, near) = r4.enter(node, t_lo, f32x4::splat(t_hi));
                // Push the entered children farthest first, so the nearest is popped next.
                let near = near.to_array();
                let mut order = [0usize; 4];
                let mut n = 0;
                for i in lanes(mask) {
                    // Insert i among the first n, by decreasing entry parameter.
                    let mut at = n;
                    while at > 0 && near[order[at - 1]] < near[i] {
                        order[at] = order[at - 1];
                        at -= 1;
                    }
                    order[at] = i;
                    n += 1;
                }
                for &i in &order[..n] {
                    stack[top] = node.child[i];
                    top += 1;
                }
            }
        });
    }

    /// Calls `visit(i)` for every triangle `i` whose box overlaps the box `[lo, hi]` and which
    /// is not wholly outside any of `planes` by more than `tol` (a plane `(m, c)` keeps the
    /// points p with m·p + c ≥ 0; canonical units; none: the box alone), each once, until
    /// `visit` returns `false`. A node is skipped when its box is so outside one
    /// plane (its corner farthest along m is), so a thin slanted region (a point's view of a
    /// light) visits far fewer nodes and triangles than its bounding box holds. A superset of
    /// the triangles meeting the region. Returns `false` if it was stopped.
    pub fn overlapping_convex(
        &self,
        lo: Vec3A,
        hi: Vec3A,
        planes: &[(Vec3A, f32)],
        tol: f32,
        mut visit: impl FnMut(usize) -> bool,
    ) -> bool {
        if self.root == EMPTY {
            return true;
        }
        let (lo4, hi4) = (
            lo.to_array().map(f32x4::splat),
            hi.to_array().map(f32x4::splat),
        );
        let floor = f32x4::splat(-tol);
        let stopped = self.walk(
            |node| {
                let mut mask = (0..3).fold(0b1111, |mask, k| {
                    mask & node.lo[k].simd_le(hi4[k]).to_bitmask()
                        & lo4[k].simd_le(node.hi[k]).to_bitmask()
                });
                for &(m, c) in planes {
                    if mask == 0 {
                        break;
                    }
                    // m·p + c at each child box's corner farthest along m.
                    let mut far = f32x4::splat(c);
                    for k in 0..3 {
                        let corner = if m[k] >= 0.0 { node.hi[k] } else { node.lo[k] };
                        far += corner * f32x4::splat(m[k]);
                    }
                    mask &= far.simd_ge(floor).to_bitmask();
                }
                mask
            },
            |p| {
                // The lanes whose triangle's own box overlaps and which reach into every
                // plane, a repeated lane once.
                let mut mask = 0b1111;
                for k in 0..3 {
                    let tlo = p.v[0][k].fast_min(p.v[1][k]).fast_min(p.v[2][k]);
                    let thi = p.v[0][k].fast_max(p.v[1][k]).fast_max(p.v[2][k]);
                    mask &= tlo.simd_le(hi4[k]).to_bitmask() & lo4[k].simd_le(thi).to_bitmask();
                }
                for &(m, c) in planes {
                    let at = |v: &[f32x4; 3]| {
                        (0..3).fold(f32x4::splat(c), |acc, k| acc + v[k] * f32x4::splat(m[k]))
                    };
                    let far = at(&p.v[0]).fast_max(at(&p.v[1])).fast_max(at(&p.v[2]));
                    mask &= far.simd_ge(floor).to_bitmask();
                }
                lanes(mask).any(|lane| {
                    !p.prim[..lane].contains(&p.prim[lane]) && !visit(p.prim[lane] as usize)
                })
            },
        );
        !stopped
    }

    /// Runs `f` with a traversal stack deep enough for this tree.
    #[inline(always)]
    fn with_stack<R>(&self, f: impl FnOnce(&mut [u32]) -> R) -> R {
        let need = 3 * self.depth + 2;
        if need <= STACK {
            let mut stack = [0u32; STACK];
            f(&mut stack)
        } else {
            f(&mut vec![0u32; need])
        }
    }

    /// Bytes held by the tree.
    pub fn bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node>()
            + self.packets.len() * std::mem::size_of::<Packet>()
    }
}

impl Node {
    fn empty() -> Node {
        Node {
            lo: [f32x4::splat(f32::INFINITY); 3],
            hi: [f32x4::splat(f32::NEG_INFINITY); 3],
            child: [EMPTY; 4],
        }
    }
}

impl Packet {
    /// The packet of triangles `ids` (one to four) of `tris`, the last repeated in unused lanes.
    fn new(tris: &[[Vec3A; 3]], ids: &[u32]) -> Packet {
        debug_assert!((1..=4).contains(&ids.len()));
        let prim: [u32; 4] = std::array::from_fn(|i| ids[i.min(ids.len() - 1)]);
        let v = std::array::from_fn(|c| {
            std::array::from_fn(|k| f32x4::from(prim.map(|t| tris[t as usize][c][k])))
        });
        Packet { v, prim }
    }
}

/// `v` with lane `i` set to `x`.
fn set_lane(v: f32x4, i: usize, x: f32) -> f32x4 {
    let mut a = v.to_array();
    a[i] = x;
    f32x4::from(a)
}

/// The set bits of a four-lane mask, lowest first.
#[inline(always)]
fn lanes(mut mask: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        if mask == 0 {
            return None;
        }
        let lane = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        Some(lane)
    })
}

/// For tests: the mask [`Ray4::hits`] gives for the packet of `tris` (one to four, the last
/// repeated) and `ray`, for internal parameters in `[t_lo, t_hi]`.
#[cfg(test)]
pub(super) fn packet_hits(tris: &[[Vec3A; 3]], ray: &WatertightRay, t_lo: f32, t_hi: f32) -> u32 {
    let ids: Vec<u32> = (0..tris.len() as u32).collect();
    Ray4::new(ray).hits(&Packet::new(tris, &ids), t_lo, t_hi)
}
