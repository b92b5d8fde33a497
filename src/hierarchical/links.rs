//! Links: which node gathers light from which, with the form factor of that transfer, and the
//! refinement oracle that decides whether a link is fine enough. This module owns the
//! form-factor estimate of a link (exact point-to-polygon between elements, isotropic clusters
//! otherwise, visibility from a few rays) and the BF criterion.

use std::f64::consts::PI;

use glam::DVec3;

use super::tree::{Node, Tree};
use crate::form_factor::kernel::{point_to_point, point_to_polygon};
use crate::form_factor::sampling::{gauss_rule, Rng};
use crate::visibility::Visibility;

/// A link: `receiver` gathers `f · L(source)` (radiance units) per channel, before its
/// reflectance. `f` is the receiver-to-source form factor F_rs (dimensionless, with
/// visibility): the fraction of the light leaving the receiver's area that would arrive at the
/// source (Cohen & Wallace eq. 4.12), so L_r = Le_r + ρ_r Σ_links F_rs L_s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Link {
    pub receiver: Node,
    pub source: Node,
    /// F_rs with visibility; ≥ 0.
    pub f: f32,
    /// The form factor the oracle trusts: an upper estimate of F_rs without visibility,
    /// computed independently of the samples of `f` (see [`estimate`]). Partly or wholly
    /// occluded links are thus refined as far as unoccluded ones.
    pub bound: f32,
    /// The estimate is meaningless (a cluster too close to the other node for the
    /// far-field formula): refine unconditionally, transfer nothing meanwhile.
    pub must_open: bool,
}

/// What estimating one link produced.
pub struct Estimate {
    pub link: Option<Link>,
    pub rays: u64,
}

/// A link with a cluster end whose bounding spheres are closer than this times the sum of
/// their radii is opened unconditionally: its upper bound A_s/(π gap²) would be useless.
pub const CLUSTER_GAP: f64 = 0.0;

/// Estimates F_rs for a new link (`None` when it is zero for certain: an element behind the
/// other's plane, or an element's self-link).
///
/// `buried` marks the receiver's Gauss points that are buried (bit k for point k; 0 for a
/// cluster or without a rule): they are left out and the others reweighted.
///
/// - Element ← element: the mean over `rays` stratified points x of the receiver of the exact
///   unoccluded point-to-polygon form factor to the source (Lambert's contour integral,
///   [`point_to_polygon`]), each times the visibility of one ray from x to a stratified point
///   of the source. Exact for unoccluded pairs as the points are refined, also when the
///   elements share an edge.
/// - With a cluster at either end: the Monte Carlo estimate of the area formulation,
///   F_rs ≈ A_s · mean_k G(x_k, y_k) V(x_k, y_k) with x_k uniform on the receiver's surfaces and
///   y_k on the source's (area-weighted through the cluster tree), G = cosθ_x cosθ_y/(π r²) with
///   the surfaces' own normals — the real orientations, not an isotropic guess (a flat cluster
///   facing another would be underestimated 16× by Sillion's isotropic A/4). The oracle
///   does not trust this noisy estimate but the bound A_s / (π gap²) (cosines ≤ 1, every
///   distance ≥ the gap between the bounding spheres), so a cluster link carries at most ε
///   whatever the samples say; what the cluster gathers is pushed to its elements uniformly
///   (Sillion, IEEE TVCG 1995; Smits, Arvo & Greenberg, SIGGRAPH 1994 bound cluster links the
///   same way).
pub fn estimate(
    tree: &Tree,
    vis: &Visibility,
    receiver: Node,
    source: Node,
    rays: usize,
    buried: u16,
    seed: u64,
) -> Estimate {
    let none = Estimate {
        link: None,
        rays: 0,
    };
    if receiver == source && receiver.as_element().is_some() {
        return none; // a flat element does not see itself
    }
    let (cr, rr) = tree.sphere(receiver);
    let (cs, rs) = tree.sphere(source);
    let is_cluster = receiver.as_cluster().is_some() || source.as_cluster().is_some();
    // Every point of the receiver is at least this far from every point of the source.
    let gap = cr.distance(cs) - (rr + rs);
    if is_cluster && gap <= CLUSTER_GAP * (rr + rs) {
        return Estimate {
            link: Some(Link {
                receiver,
                source,
                f: 0.0,
                bound: 0.0,
                must_open: true,
            }),
            rays: 0,
        };
    }
    if let (Some(r), Some(s)) = (receiver.as_element(), source.as_element()) {
        if behind(tree, s, r) || behind(tree, r, s) {
            return none;
        }
    }
    let mut rng = Rng::new(&[seed, receiver.id(), source.id(), 0x4C494E4B]);
    let (mut xs, mut ys) = (Vec::with_capacity(rays), Vec::with_capacity(rays));
    tree.sample(receiver, rays, &mut rng, &mut xs);
    tree.sample(source, rays, &mut rng, &mut ys);
    // Element receivers integrate with a symmetric Gauss rule when there is one for this
    // many points (as the contour estimator does): deterministic, and far less noisy than
    // random points for the smooth point-to-polygon integrand.
    // Rule points buried under contact geometry (bit k of `buried`) gather nothing, and the
    // others stand for the receiver's visible part (as the matrix estimators rescale rows).
    let mut weights = vec![1.0 / rays as f64; rays];
    if let (Some(r), Some(rule)) = (receiver.as_element(), gauss_rule(rays)) {
        let visible: f64 = (0..rays)
            .filter(|k| buried & (1 << k) == 0)
            .map(|k| rule[k].1)
            .sum();
        if visible == 0.0 {
            return none;
        }
        for (k, (b, w)) in rule.into_iter().enumerate() {
            xs[k] = (r, b);
            weights[k] = if buried & (1 << k) == 0 {
                w / visible
            } else {
                0.0
            };
        }
    }

    let points: Vec<(DVec3, DVec3)> = (0..rays)
        .map(|k| (tree.point(xs[k].0, xs[k].1), tree.point(ys[k].0, ys[k].1)))
        .collect();
    // Unoccluded form factor of each sample, times its weight.
    let element_pair = receiver.as_element().zip(source.as_element());
    let a_s = tree.area(source);
    let unoccluded: Vec<f64> = (0..rays)
        .map(|k| {
            let ((er, br), (es, _)) = (xs[k], ys[k]);
            let (x, y) = points[k];
            weights[k]
                * match element_pair {
                    Some((_, s)) => point_form_factor(tree, x, tree.surface_normal(er, br), s),
                    // A_s · G(x, y) for y ∝ area on the source: an unbiased estimate of F_rs.
                    None => {
                        a_s * point_to_point(
                            x,
                            tree.surface_normal(er, br),
                            y,
                            tree.elements[es].normal,
                        )
                    }
                }
        })
        .collect();
    let f_unoccluded: f64 = unoccluded.iter().sum();
    let mut f = 0.0;
    let mut cast = 0;
    for k in 0..rays {
        if unoccluded[k] == 0.0 {
            continue;
        }
        let ((er, _), (es, _)) = (xs[k], ys[k]);
        let (x, y) = points[k];
        cast += 1;
        if !vis.occluded(x, y, [tree.elements[er].root, tree.elements[es].root]) {
            f += unoccluded[k];
        }
    }
    // The oracle's form factor must not depend on the samples of `f`: keeping the links whose
    // random estimate happened to be low and refining the others would bias the kept sum
    // low (measured: row sums of a closed box 0.98 instead of 1).
    let bound = match element_pair {
        None => {
            // Any orientation: cosines ≤ 1 and every distance ≥ the gap.
            (tree.area(source) / (PI * gap * gap)).min(1.0)
        }
        Some((r, s)) => {
            let bound = largest_point_form_factor(tree, r, s);
            if bound == 0.0 && f_unoccluded == 0.0 {
                return Estimate {
                    link: None,
                    rays: cast,
                };
            }
            bound
        }
    };
    Estimate {
        link: Some(Link {
            receiver,
            source,
            f: f as f32,
            bound: bound as f32,
            must_open: false,
        }),
        rays: cast,
    }
}

/// The unoccluded form factor from the point `x` with unit normal `n` to element `s`
/// (Lambert's contour integral, [`point_to_polygon`]); 0 when `x` is behind `s` (it would see
/// the back of a one-sided surface).
fn point_form_factor(tree: &Tree, x: DVec3, n: DVec3, s: usize) -> f64 {
    let poly = tree.corners(s);
    if (x - poly[0]).dot(tree.elements[s].normal) <= 0.0 {
        0.0
    } else {
        point_to_polygon(x, n, &poly)
    }
}

/// The largest unoccluded point-to-polygon form factor from the corners and the centroid of
/// element `r` to element `s`: a deterministic stand-in for the largest F over `r`.
fn largest_point_form_factor(tree: &Tree, r: usize, s: usize) -> f64 {
    let third = 1.0 / 3.0;
    [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [third, third, third],
    ]
    .into_iter()
    .map(|b| point_form_factor(tree, tree.point(r, b), tree.surface_normal(r, b), s))
    .fold(0.0, f64::max)
}

/// True when every corner of element `a` lies on or behind the plane of element `b`: then `b`
/// cannot see `a` (nor `a` see `b`'s front), and F is zero both ways.
fn behind(tree: &Tree, a: usize, b: usize) -> bool {
    let (p, n) = (
        tree.positions[tree.elements[b].vertices[0] as usize],
        tree.elements[b].normal,
    );
    let scale = tree.elements[a].radius.max(tree.elements[b].radius);
    tree.corners(a)
        .iter()
        .all(|v| n.dot(*v - p) <= 1e-9 * scale)
}

/// How a refinement pass treats a link.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// Fine enough: keep it.
    Keep,
    /// Replace it by links from the receiver's children.
    SplitReceiver,
    /// Replace it by links to the source's children.
    SplitSource,
    /// A cluster's self-link: replace it by the links between all pairs of its children.
    SplitBoth,
}

/// The BF oracle (Hanrahan, Salzman & Aupperle, "A rapid hierarchical radiosity algorithm",
/// SIGGRAPH 1991, §4): a link is fine enough when the power it may carry, ρ_r · L_s · F_rs ·
/// A_r (the largest channel of each; F the oracle's `bound`), is at most `epsilon` (absolute,
/// radiance × area). Otherwise the larger node (by bounding radius) is split, if it can be:
/// clusters always can, elements while their children would keep at least `min_area`.
pub fn oracle(
    tree: &Tree,
    link: &Link,
    max_reflectance: impl Fn(Node) -> f64,
    source_radiance: f64,
    epsilon: f64,
    min_area: f64,
) -> Action {
    let (r, s) = (link.receiver, link.source);
    if r == s {
        return if r.as_cluster().is_some() {
            Action::SplitBoth
        } else {
            Action::Keep
        };
    }
    if !link.must_open {
        let power = max_reflectance(r) * source_radiance * link.bound as f64 * tree.area(r);
        if power <= epsilon {
            return Action::Keep;
        }
    }
    let can_split = |n: Node| match n.as_element() {
        Some(e) => {
            tree.elements[e].first_child != super::tree::NO_CHILD
                || 0.25 * tree.elements[e].area >= min_area
        }
        None => true,
    };
    let (_, rr) = tree.sphere(r);
    let (_, rs) = tree.sphere(s);
    // A must-open link has a cluster end: open the clusters first.
    let prefer_receiver = if link.must_open {
        match (r.as_cluster(), s.as_cluster()) {
            (Some(_), Some(_)) => rr >= rs,
            (Some(_), None) => true,
            _ => false,
        }
    } else {
        rr >= rs
    };
    let order = if prefer_receiver {
        [(r, Action::SplitReceiver), (s, Action::SplitSource)]
    } else {
        [(s, Action::SplitSource), (r, Action::SplitReceiver)]
    };
    for (node, action) in order {
        if can_split(node) {
            return action;
        }
    }
    Action::Keep
}
