//! A light tree: a bounding-volume tree over the point and spot lights, to draw one of a
//! level's hundreds of lamps in proportion to (a bound on) what it would bring to a point,
//! in O(log n) instead of weighing every lamp at every point.
//!
//! Each node bounds its lights' positions by a box and sums their luminous intensity
//! (luminance of I, W·sr⁻¹). Seen from a point x with unit normal n, a node's importance is
//!
//!   I_node · cos⁺(θ − θ_u) / max(d², r²),
//!
//! with d the distance from x to the box's centre, r its half diagonal, θ the angle between n
//! and the direction to the centre and θ_u = asin(r/d) the half-angle of the box's bounding
//! sphere (cos = 1 where x is inside it), and 0 where the whole box lies behind the surface.
//! A leaf's importance is the light's exact unoccluded share ([`PointLight::potential`], its
//! spot falloff included). A draw descends from the root, taking each child with the share of
//! the two importances, so a light is drawn with probability p = the product of those shares,
//! and p > 0 for every light that can bring anything to x (its own box and every box above it
//! has a corner in front of x). One shadow ray to the light drawn, weighted by 1/p, is an
//! unbiased estimate of all the lights' sum. (A draw can end at a node whose two children can
//! bring nothing though its box could, its lights all behind x or outside their cones: it
//! brings nothing, a lost draw, not a bias.) The tree and the importance are those of Conty
//! Estevez & Kulla 2018, "Importance sampling of many lights with adaptive tree splitting"
//! (without their orientation cones: a spot is bounded as if it shone every way).

use glam::DVec3;

use crate::color::luminance;
use crate::scene::lights::PointLight;

/// One node: the box of its lights' positions and their summed luminance of intensity.
#[derive(Debug, Clone)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    /// Σ luminance(I) over the lights below, W·sr⁻¹ (≥ 0).
    power: f64,
    kind: Kind,
}

#[derive(Debug, Clone, Copy)]
enum Kind {
    /// One light: its index in the light list.
    Leaf(u32),
    /// Two children: their indices in the node list.
    Inner(u32, u32),
}

/// A binary tree over point lights (one light a leaf); see the module comment. Built by
/// median splits along the widest axis of the positions, ties by index: the same tree for the
/// same lights on every run.
#[derive(Debug, Clone, Default)]
pub struct LightTree {
    /// Root first (empty for no lights).
    nodes: Vec<Node>,
}

impl LightTree {
    /// The tree over `lights`.
    pub fn new(lights: &[PointLight]) -> Self {
        let mut tree = LightTree {
            nodes: Vec::with_capacity(2 * lights.len()),
        };
        let mut order: Vec<u32> = (0..lights.len() as u32).collect();
        if !order.is_empty() {
            tree.build(lights, &mut order);
        }
        tree
    }

    /// Appends the subtree over `order` and returns its root's index.
    fn build(&mut self, lights: &[PointLight], order: &mut [u32]) -> u32 {
        let at = |k: &u32| lights[*k as usize].position;
        let (lo, hi) = order.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), k| (lo.min(at(k)), hi.max(at(k))),
        );
        let power = order
            .iter()
            .map(|&k| luminance(lights[k as usize].intensity))
            .sum();
        let index = self.nodes.len() as u32;
        self.nodes.push(Node {
            lo,
            hi,
            power,
            kind: Kind::Leaf(order[0]),
        });
        if order.len() > 1 {
            let axis = (hi - lo).max_position();
            let mid = order.len() / 2;
            order.select_nth_unstable_by(mid, |a, b| {
                at(a)[axis].total_cmp(&at(b)[axis]).then(a.cmp(b))
            });
            let (left, right) = order.split_at_mut(mid);
            let l = self.build(lights, left);
            let r = self.build(lights, right);
            self.nodes[index as usize].kind = Kind::Inner(l, r);
        }
        index
    }

    /// Lights in the tree.
    pub fn len(&self) -> usize {
        self.nodes.len().div_ceil(2)
    }

    /// True if the tree has no light.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Draws one light for the point `x` with unit normal `n`, by the uniform number
    /// `u` ∈ [0, 1): its index and the probability it was drawn with, or `None` where the
    /// draw finds no light that can bring anything to x.
    pub fn sample(
        &self,
        lights: &[PointLight],
        x: DVec3,
        n: DVec3,
        mut u: f64,
    ) -> Option<(usize, f64)> {
        let mut node = self.nodes.first()?;
        if self.importance(lights, node, x, n) <= 0.0 {
            return None;
        }
        let mut p = 1.0;
        loop {
            match node.kind {
                Kind::Leaf(k) => return Some((k as usize, p)),
                Kind::Inner(l, r) => {
                    let (l, r) = (&self.nodes[l as usize], &self.nodes[r as usize]);
                    let (a, b) = (
                        self.importance(lights, l, x, n),
                        self.importance(lights, r, x, n),
                    );
                    if a + b <= 0.0 {
                        return None;
                    }
                    let left = a / (a + b);
                    // The one number rescaled at each level (its precision outlasts the
                    // depth, log₂ of the lights).
                    if u < left {
                        (u, p, node) = (u / left, p * left, l);
                    } else {
                        (u, p, node) = ((u - left) / (1.0 - left), p * (1.0 - left), r);
                    }
                    u = u.min(1.0 - f64::EPSILON);
                }
            }
        }
    }

    /// The node's importance at (x, n) (module comment).
    fn importance(&self, lights: &[PointLight], node: &Node, x: DVec3, n: DVec3) -> f64 {
        if let Kind::Leaf(k) = node.kind {
            return lights[k as usize].potential(x, n);
        }
        let (c, half) = (0.5 * (node.lo + node.hi), 0.5 * (node.hi - node.lo));
        let to = c - x;
        // The box's farthest corner along n still behind the surface: nothing to bring.
        if n.dot(to) + n.abs().dot(half) <= 0.0 {
            return 0.0;
        }
        let (d2, r2) = (to.length_squared(), half.length_squared());
        let cos = if d2 <= r2 {
            1.0
        } else {
            let d = d2.sqrt();
            let cos_t = n.dot(to) / d;
            let sin_u = (r2 / d2).sqrt();
            let cos_u = (1.0 - sin_u * sin_u).max(0.0).sqrt();
            if cos_t >= cos_u {
                1.0
            } else {
                let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
                (cos_t * cos_u + sin_t * sin_u).max(0.0)
            }
        };
        node.power * cos / d2.max(r2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::light::scattered_lights as lights;

    /// Every light's chance of being drawn, by walking the tree (the product of the shares
    /// down to its leaf), in the order the draws' u-intervals take them; `None` for a subtree
    /// whose two children can bring nothing though its box could (a draw that ends there
    /// brings nothing: lost, not biased).
    fn chances(
        tree: &LightTree,
        lights: &[PointLight],
        x: DVec3,
        n: DVec3,
    ) -> Vec<(Option<usize>, f64)> {
        fn walk(
            t: &LightTree,
            l: &[PointLight],
            node: u32,
            p: f64,
            (x, n): (DVec3, DVec3),
            out: &mut Vec<(Option<usize>, f64)>,
        ) {
            match t.nodes[node as usize].kind {
                Kind::Leaf(k) => out.push((Some(k as usize), p)),
                Kind::Inner(a, b) => {
                    let ia = t.importance(l, &t.nodes[a as usize], x, n);
                    let ib = t.importance(l, &t.nodes[b as usize], x, n);
                    if ia + ib > 0.0 {
                        walk(t, l, a, p * ia / (ia + ib), (x, n), out);
                        walk(t, l, b, p * ib / (ia + ib), (x, n), out);
                    } else {
                        out.push((None, p));
                    }
                }
            }
        }
        let mut out = Vec::new();
        walk(tree, lights, 0, 1.0, (x, n), &mut out);
        out
    }

    /// The chances (lost draws included) sum to 1; they are > 0 for every light that can bring
    /// anything (a biased tree would give some such light none); a draw at u returns the light
    /// whose u-interval holds it, with its chance, or nothing in a lost interval. So one light
    /// drawn, weighted by 1/p, is unbiased.
    #[test]
    fn every_light_in_front_can_be_drawn_with_the_chance_it_reports() {
        let lights = lights(61);
        let tree = LightTree::new(&lights);
        assert_eq!(tree.len(), 61);
        for (x, n) in [
            (DVec3::ZERO, DVec3::Z),
            (
                DVec3::new(0.8, -0.4, 0.2),
                DVec3::new(0.3, 0.1, 1.0).normalize(),
            ),
            (DVec3::new(3.0, 0.0, 0.0), -DVec3::X),
        ] {
            let chances = chances(&tree, &lights, x, n);
            let total: f64 = chances.iter().map(|c| c.1).sum();
            assert!((total - 1.0).abs() < 1e-12, "chances sum to {total}");
            let mut from = 0.0;
            let mut drawn_lights = 0;
            for &(k, p) in &chances {
                let drawn = (p > 0.0).then(|| tree.sample(&lights, x, n, from + 0.5 * p));
                match k {
                    Some(k) => {
                        let brings = lights[k].potential(x, n) > 0.0;
                        assert_eq!(p > 0.0, brings, "light {k}: chance {p}");
                        if let Some(drawn) = drawn {
                            let (drawn, q) = drawn.unwrap();
                            assert_eq!(drawn, k);
                            assert!((q - p).abs() <= 1e-12 * p, "light {k}: {q} against {p}");
                            drawn_lights += 1;
                        }
                    }
                    None => assert!(drawn.flatten().is_none()),
                }
                from += p;
            }
            assert!(drawn_lights > 10, "a test of many lights: {drawn_lights}");
        }
    }

    #[test]
    fn no_light_in_front_draws_none() {
        let lights = lights(20);
        let tree = LightTree::new(&lights);
        // Far below every light, facing down.
        assert!(tree
            .sample(&lights, DVec3::new(0.0, 0.0, -5.0), -DVec3::Z, 0.3)
            .is_none());
        assert!(LightTree::new(&[])
            .sample(&[], DVec3::ZERO, DVec3::Z, 0.5)
            .is_none());
    }
}
