//! Links: which node gathers light from which, with the form factor of that transfer, and the
//! refinement oracle that decides whether a link is fine enough. This module owns the
//! form-factor estimate of a link (exact point-to-polygon between elements, isotropic clusters
//! otherwise, visibility from a few rays) and the BF criterion.

use std::f64::consts::PI;

use glam::DVec3;

use super::rule::{pick_proportional, receiver_rule, unburied_weights, Burial, RECEIVER_POINTS};
use super::tree::{Node, Tree, MAX_PARTS};
use crate::geometry::kernel::{point_to_point, point_to_polygon};
use crate::sampling::{permutation, point_above, point_by_solid_angle, triangle_barycentrics, Rng};
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
    /// computed independently of the samples of `f` (see [`estimate`]), ≥ 0. Partly or wholly
    /// occluded links are thus refined as far as unoccluded ones. [`MUST_OPEN`] (negative)
    /// marks a link whose estimate is meaningless ([`Link::must_open`]); a flag of its own
    /// would make every link 4 bytes larger (24 instead of 20), 150 MB at 10⁶ triangles.
    pub bound: f32,
    /// Weights of the source's parts, all 0 where there is nothing to weigh; only ratios
    /// matter ([`Hierarchy::link_radiance`](super::Hierarchy::link_radiance)).
    /// - An element source: the share of the unoccluded F_rs that arrives at each of its four
    ///   children (as [`Tree::split`] makes them, in its order), in 255ths of their sum,
    ///   rounded; once the source is split the gather weights its children's radiance by
    ///   these.
    /// - A cluster source: the form factor from the receiver to each of its [`Tree::parts`]
    ///   (two levels down, at most [`MAX_PARTS`]; `part_form_factors`), 4 bits each in
    ///   15ths of the largest ([`part_share`]); the gather weights the parts' radiance by
    ///   these, where the cluster's mean would miss how the parts' radiance and what the
    ///   receiver sees of them vary together.
    pub children: [u8; 4],
}

/// [`Link::bound`] of a link that must be opened.
pub const MUST_OPEN: f32 = -1.0;

impl Link {
    /// A link whose estimate is meaningless (a cluster too close to the other node for the
    /// far-field formula): refined unconditionally, transferring nothing meanwhile.
    pub fn opening(receiver: Node, source: Node) -> Link {
        Link {
            receiver,
            source,
            f: 0.0,
            bound: MUST_OPEN,
            children: [0; 4],
        }
    }

    /// Whether the oracle must open this link whatever it carries ([`Link::opening`]).
    pub fn must_open(&self) -> bool {
        self.bound < 0.0
    }
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
/// `burial` says which rule points ([`receiver_rule`]) of the receiver are buried: they are
/// left out and the others reweighted, so an element gathers for its visible part, and a
/// cluster for its roots' visible parts.
///
/// - Element ← element (`element_pair_estimate`): the receiver rule (degree 5) over the
///   exact unoccluded point-to-polygon form factor to the source (Lambert's contour integral,
///   [`point_to_polygon`]; exact for unoccluded pairs as the elements are refined, also when
///   they share an edge), times the visible share of F from `rays` rays, each from a rule
///   point picked ∝ its share of F to a point of the part of the source above that point's
///   horizon drawn by solid angle, weighted by its cosine there (so the share follows the
///   kernel, not the source's area).
/// - With a cluster at either end: the Monte Carlo estimate of the area formulation,
///   F_rs ≈ A_s · mean_k G(x_k, y_k) V(x_k, y_k) with x_k uniform on the receiver's seen
///   surfaces (an element's unburied rule points, picked ∝ weight; a cluster's roots by seen
///   area, [`Tree::sample_seen`]) and
///   y_k on the source's (area-weighted through the cluster tree), G = cosθ_x cosθ_y/(π r²) with
///   the surfaces' own normals — the real orientations, not an isotropic guess (a flat cluster
///   facing another would be underestimated 16× by Sillion's isotropic A/4). The oracle
///   does not trust this noisy estimate but the bound A_s / (π gap²) (cosines ≤ 1, every
///   distance ≥ the gap between the bounding spheres), so a cluster link carries at most ε
///   whatever the samples say; what the cluster gathers is pushed to its elements by their
///   orientation, and a cluster source gives the radiance of its faces turned toward the
///   receiver (Sillion, IEEE TVCG 1995, with oriented rather than isotropic clusters; Smits,
///   Arvo & Greenberg, SIGGRAPH 1994 bound cluster links the same way).
pub fn estimate(
    tree: &Tree,
    vis: &Visibility,
    receiver: Node,
    source: Node,
    rays: usize,
    burial: Burial,
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
            link: Some(Link::opening(receiver, source)),
            rays: 0,
        };
    }
    if let (Some(r), Some(s)) = (receiver.as_element(), source.as_element()) {
        if behind(tree, s, r) || behind(tree, r, s) {
            return none;
        }
    }
    let mut rng = Rng::new(&[seed, receiver.id(), source.id(), 0x4C494E4B]);
    let element_pair = receiver.as_element().zip(source.as_element());
    let sums = match element_pair {
        Some((r, s)) => element_pair_estimate(tree, vis, r, s, rays, burial.mask(r), &mut rng),
        None => cluster_pair_estimate(tree, vis, receiver, source, rays, burial, &mut rng),
    };
    let Some(Sums {
        f,
        f_unoccluded,
        largest,
        cast,
        children,
    }) = sums
    else {
        return none;
    };

    // The oracle's form factor must not depend on the samples of `f`: keeping the links whose
    // random estimate happened to be low and refining the others would bias the kept sum
    // low (a closed box's row sums would come out short of 1).
    let bound = match element_pair {
        None => {
            // Any orientation: cosines ≤ 1 and every distance ≥ the gap.
            (tree.area(source) / (PI * gap * gap)).min(1.0)
        }
        Some((r, s)) => {
            let bound = largest_point_form_factor(tree, r, s).max(largest);
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
            children,
        }),
        rays: cast,
    }
}

/// F_rs of a link the refinement left [`Link::must_open`] when it stopped early (at a memory
/// or time limit): the Monte Carlo estimate of the area formulation with `rays` sample pairs
/// (as for any link with a cluster end), clamped to 1, the bound of any form factor. Noisy
/// where the ends are close (the kernel 1/r² is unbounded there), but such a link then carries
/// its light instead of none: a stop in the middle of opening the overlapping clusters would
/// otherwise leave whole parts of the scene unlit.
pub fn overlapping_estimate(
    tree: &Tree,
    vis: &Visibility,
    link: &Link,
    rays: usize,
    burial: Burial,
    seed: u64,
) -> Estimate {
    let mut rng = Rng::new(&[seed, link.receiver.id(), link.source.id(), 0x4F50454E]);
    let sums = cluster_pair_estimate(
        tree,
        vis,
        link.receiver,
        link.source,
        rays,
        burial,
        &mut rng,
    );
    let (f, cast) = sums.map_or((0.0, 0), |s| (s.f.min(1.0), s.cast));
    Estimate {
        link: Some(Link {
            f: f as f32,
            ..*link
        }),
        rays: cast,
    }
}

/// What estimating a link sums up.
struct Sums {
    /// F_rs with visibility.
    f: f64,
    /// F_rs without visibility.
    f_unoccluded: f64,
    /// The largest unoccluded point form factor at the rule's points (element pairs; else 0).
    largest: f64,
    /// Rays cast.
    cast: u64,
    /// See [`Link::children`].
    children: [u8; 4],
}

/// F_rs between elements: the receiver rule over its unburied points of the exact
/// point-to-polygon form factor, times the visible share of it estimated by `rays` rays. Ray
/// k starts at a rule point x picked with probability ∝ w·F (systematic sampling) and aims at
/// a point y of the part of the source above x's horizon, drawn uniformly by the solid angle
/// it subtends at x (stratified; [`point_by_solid_angle`]), with weight w_k = cosθ_x · Ω /
/// (π F(x)), whose mean is 1: Σ w_k V_k / Σ w_k estimates Σ w F V̄ / Σ w F, V̄(x) the share of
/// F(x) that x sees, with a bias O(1/rays) and exactly 1 when every ray passes.
///
/// Why not points uniform by area: the visibility would then be the source's visible *area*
/// share, not its share of F. The two differ wherever what is hidden is far and what is seen
/// is near, which is the rule beside furniture: a chair leg sees the floor within a metre
/// (most of its F), while the rest of a floor triangle metres across is hidden by other
/// furniture. By area, the generated hall's chair legs and seats get row sums Σ F far short
/// of 1 where they see nothing but the fronts of surfaces (1 is right), and the whole
/// solution comes out dark against the path-traced probes; by solid angle their row sums are
/// close to 1. `None` when every rule point is buried.
fn element_pair_estimate(
    tree: &Tree,
    vis: &Visibility,
    r: usize,
    s: usize,
    rays: usize,
    buried: u16,
    rng: &mut Rng,
) -> Option<Sums> {
    let RuleForm {
        weighted,
        point_f,
        largest,
        f_unoccluded,
    } = rule_form_factor(tree, r, s, buried)?;
    let rule = receiver_rule();
    let children = child_shares(tree, r, s);
    let mut sums = Sums {
        f: 0.0,
        f_unoccluded,
        largest,
        cast: 0,
        children,
    };
    let Some(picks) = pick_proportional(&weighted, rays, rng.next_f64()) else {
        return Some(sums);
    };
    let roots = [tree.elements[r].root, tree.elements[s].root];
    let corners = tree.corners(s);
    let (mut seen, mut all) = (0.0, 0.0);
    // The blocker of one ray is tested first for the next (the same answers).
    let mut last = usize::MAX;
    // The solid-angle strata in random order: picks come in rule order, so strata in order
    // would give each rule point the same part of the source every time, a bias.
    let strata = permutation(rays, rng);
    for (&j, k) in strata.iter().zip(picks) {
        let rb = rule[k].0;
        let (x, n) = (tree.point(r, rb), tree.surface_normal(r, rb));
        // F > 0 at a picked point, so some of the source is above its horizon. The point is
        // drawn by solid angle, so near parts of a large source (which carry most of F and
        // are the likeliest seen) get their share of rays; its weight cosθ_x · Ω / (π F) has
        // mean 1, and Σ w V / Σ w is the visible share of F at these points.
        let u = (j as f64 + rng.next_f64()) / rays as f64;
        let (y, w) = match point_by_solid_angle(&corners, x, n, u, rng.next_f64()) {
            Some((y, omega)) => {
                let cos = n.dot((y - x).normalize_or_zero()).max(0.0);
                (y, cos * omega / (PI * point_f[k]))
            }
            None => {
                // Uniform by area (a source this small against its distance).
                let b = triangle_barycentrics(u, rng.next_f64());
                let y = point_above(&corners, x, n, b, rng).unwrap_or_else(|| tree.point(s, b));
                (y, 1.0)
            }
        };
        if !(w.is_finite() && w > 0.0) {
            continue;
        }
        all += w;
        if !vis.occluded_points_after(&vis.point(x), &vis.point(y), roots, &mut last) {
            seen += w;
        }
    }
    sums.cast = rays as u64;
    sums.f = if all > 0.0 {
        f_unoccluded * seen / all
    } else {
        0.0
    };
    Some(sums)
}

/// The unoccluded form factor from element `r` to element `s` by the receiver rule over
/// `r`'s unburied points, and what the ray picks of [`element_pair_estimate`] need of it.
struct RuleForm {
    /// Each rule point's weight (0 where buried) times its point form factor.
    weighted: [f64; RECEIVER_POINTS],
    /// Each unburied rule point's unoccluded point form factor.
    point_f: [f64; RECEIVER_POINTS],
    /// The largest of `point_f`.
    largest: f64,
    /// F_rs without visibility, over `r`'s visible part: the rule's weighted mean, or on `r`'s
    /// quarters where the kernel spreads too much ([`SPREAD_FOR_QUARTERS`]).
    f_unoccluded: f64,
}

/// [`RuleForm`] of `r` gathering from `s`, with `r`'s points in `buried` left out; `None` when
/// every point is buried.
fn rule_form_factor(tree: &Tree, r: usize, s: usize, buried: u16) -> Option<RuleForm> {
    let rule = receiver_rule();
    let mut weighted = unburied_weights(buried);
    let visible: f64 = weighted.iter().sum();
    if visible == 0.0 {
        return None;
    }
    let (mut largest, mut smallest) = (0.0f64, f64::INFINITY);
    let mut point_f = [0.0; RECEIVER_POINTS];
    for (k, &(b, _)) in rule.iter().enumerate() {
        if weighted[k] == 0.0 {
            continue;
        }
        let f = point_form_factor(tree, tree.point(r, b), tree.surface_normal(r, b), s);
        point_f[k] = f;
        largest = largest.max(f);
        smallest = smallest.min(f);
        weighted[k] *= f;
    }
    let mut f_unoccluded = weighted.iter().sum::<f64>() / visible;
    // A kernel that varies too much over the receiver: integrate on its quarters (with
    // buried points the one rule's reweighting stands).
    if buried == 0 && largest - smallest > SPREAD_FOR_QUARTERS * f_unoccluded {
        f_unoccluded = composite_form_factor(tree, r, s, 1);
    }
    Some(RuleForm {
        weighted,
        point_f,
        largest,
        f_unoccluded,
    })
}

/// The unoccluded F_rs from element `r` to element `s` over `r`'s points not in `buried`
/// ([`RuleForm::f_unoccluded`]); `None` when every point is buried.
pub(super) fn unoccluded_form_factor(tree: &Tree, r: usize, s: usize, buried: u16) -> Option<f64> {
    rule_form_factor(tree, r, s, buried).map(|f| f.f_unoccluded)
}

/// Where the receiver rule's point values of F spread over more than this many times their
/// mean (a receiver large against its distance to the source, or one cut by the source's
/// plane), the rule under-integrates the kernel: F_rs is integrated again on the receiver's
/// four quarters (`composite_form_factor`). Against the generated hall's path-traced probes
/// this takes out much of the solution's low bias for little more time: a lower threshold
/// integrates many more receivers again for no better answer, a higher one leaves part of
/// the bias.
pub const SPREAD_FOR_QUARTERS: f64 = 2.0;

/// The unoccluded F_rs by the receiver rule on each of the 4^`depth` sub-triangles of `r`
/// (split at edge midpoints `depth` times): a composite rule for receivers on which one rule
/// under-integrates the kernel.
pub(crate) fn composite_form_factor(tree: &Tree, r: usize, s: usize, depth: u32) -> f64 {
    // Sub-triangles as barycentric corners in r.
    let mut parts = vec![[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]];
    for _ in 0..depth {
        let mut next = Vec::with_capacity(4 * parts.len());
        for [a, b, c] in parts {
            let m = |p: [f64; 3], q: [f64; 3]| std::array::from_fn(|i| 0.5 * (p[i] + q[i]));
            let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
            next.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [bc, ca, ab]]);
        }
        parts = next;
    }
    let share = 1.0 / parts.len() as f64;
    let mut sum = 0.0;
    for q in &parts {
        for &(b, w) in receiver_rule() {
            let at: [f64; 3] =
                std::array::from_fn(|i| b[0] * q[0][i] + b[1] * q[1][i] + b[2] * q[2][i]);
            let f = point_form_factor(tree, tree.point(r, at), tree.surface_normal(r, at), s);
            sum += share * w * f;
        }
    }
    sum
}

/// F_rs with a cluster at either end: the Monte Carlo estimate A_s · mean_k G(x_k, y_k)
/// V(x_k, y_k) of the area formulation (see [`estimate`]). Receiving points: on an element,
/// its unburied rule points picked ∝ weight (so the mean is over its visible part); in a
/// cluster, uniform over its seen area ([`Tree::sample_seen`]: the ceiling buried behind a lamp
/// mounted under it must not dilute what the lamp gathers, since the cluster's F is pushed to
/// the lamp as the mean). `None` when every rule point of an element receiver, or the whole of
/// a cluster receiver, is buried.
fn cluster_pair_estimate(
    tree: &Tree,
    vis: &Visibility,
    receiver: Node,
    source: Node,
    rays: usize,
    burial: Burial,
    rng: &mut Rng,
) -> Option<Sums> {
    let mut xs = Vec::with_capacity(rays);
    match receiver.as_element() {
        Some(r) => {
            let picks = pick_proportional(&unburied_weights(burial.mask(r)), rays, rng.next_f64())?;
            xs.extend(picks.into_iter().map(|k| (r, receiver_rule()[k].0)));
        }
        // Over the cluster's seen part: what it gathers is pushed to its faces as the mean
        // over what is seen, so a lamp mounted under a ceiling is not dimmed by the buried
        // ceiling behind it.
        None => {
            tree.sample_seen(receiver.as_cluster().unwrap(), rays, burial, rng, &mut xs);
            if xs.is_empty() {
                return None;
            }
        }
    }
    let mut ys = Vec::with_capacity(rays);
    tree.sample(source, rays, rng, &mut ys);
    // A_s · G(x, y) for y ∝ area on the source: an unbiased estimate of F_rs.
    let a_s = tree.area(source);
    let mut sums = Sums {
        f: 0.0,
        f_unoccluded: 0.0,
        largest: 0.0,
        cast: 0,
        children: [0; 4],
    };
    // What arrives through each part of the source: unoccluded for an element source (its
    // quarters, as [`child_shares`], which the gather weights by the quarters' visible
    // fractions); for a cluster source ([`Tree::parts`]) seen and unoccluded, for each
    // part's visible share.
    let mut through = [0.0f64; MAX_PARTS];
    let mut unoccluded = [0.0f64; MAX_PARTS];
    let source_is_element = source.as_element().is_some();
    // The receiving points and their normals, for the samples and the parts alike.
    let at: Vec<(DVec3, DVec3)> = xs
        .iter()
        .map(|&(er, br)| (tree.point(er, br), tree.surface_normal(er, br)))
        .collect();
    // The blocker of one ray is tested first for the next (the same answers).
    let mut last = usize::MAX;
    for ((&(er, _), &(x, nx)), y) in xs.iter().zip(&at).zip(&ys) {
        let es = y.element;
        let y_at = tree.point(es, y.at);
        let g = a_s * point_to_point(x, nx, y_at, tree.elements[es].normal) / rays as f64;
        if g == 0.0 {
            continue;
        }
        sums.f_unoccluded += g;
        sums.cast += 1;
        unoccluded[y.part as usize] += g;
        let roots = [tree.elements[er].root, tree.elements[es].root];
        let seen = !vis.occluded_points_after(&vis.point(x), &vis.point(y_at), roots, &mut last);
        if seen {
            sums.f += g;
        }
        if seen || source_is_element {
            through[y.part as usize] += g;
        }
    }
    sums.children = match source.as_cluster() {
        None => in_255ths([through[0], through[1], through[2], through[3]]),
        Some(c) => {
            let seen = std::array::from_fn(|k| {
                if unoccluded[k] > 0.0 {
                    through[k] / unoccluded[k]
                } else if sums.f_unoccluded > 0.0 {
                    sums.f / sums.f_unoccluded
                } else {
                    0.0
                }
            });
            in_nibbles(part_form_factors(tree, c, &at, seen, burial))
        }
    };
    Some(sums)
}

/// The form factor from the receiving points `xs` (positions and unit normals) to each part
/// of cluster `c`
/// ([`Tree::parts`], in order), up to a common factor: Σ_x cos θ_x · A⊥_k / r², each part as
/// a point at its centre (an element's centroid, a cluster's box centre) of seen area A⊥_k
/// projected toward x (an element's visible area times its cosine, a cluster's seen area by
/// its six facings), times `seen[k]`, the part's visible share from the link's samples.
///
/// Why: a cluster's radiance varies over it with the light's own shadows and fall-off, and
/// what a receiver sees of it varies too; the cluster's mean radiance times F misses their
/// correlation. Under the Cornell box's ceiling the floor's parts beneath the light, the
/// brightest, are also the ones the ceiling there sees best, and read by their mean the
/// ceiling came out 0.45 % low against a path tracer (the matrix method: 0.11 %). The link's
/// few samples (3) land in few of eight parts, so their kernels alone would weigh parts by
/// chance (the integrating sphere's walls 1 % off patch by patch); the centres' kernel is
/// deterministic, and only the visible shares come from the samples.
pub(super) fn part_form_factors(
    tree: &Tree,
    c: usize,
    xs: &[(DVec3, DVec3)],
    seen: [f64; MAX_PARTS],
    burial: Burial,
) -> [f64; MAX_PARTS] {
    let mut w = [0.0; MAX_PARTS];
    for (k, part) in tree.parts(c).enumerate() {
        let at = tree.sphere(part).0;
        let mut kernel = 0.0;
        for &(x, nx) in xs {
            let d = at - x;
            let Some(dir) = d.try_normalize() else {
                continue;
            };
            let cos_x = nx.dot(dir).max(0.0);
            // The part's seen area projected toward x, along −dir.
            let a = match part.as_element() {
                Some(e) => {
                    let el = &tree.elements[e];
                    el.area * burial.visible(e) * (-el.normal.dot(dir)).max(0.0)
                }
                None => {
                    let f = &tree.clusters[part.as_cluster().unwrap()].seen_facing;
                    (0..3)
                        .map(|i| dir[i].abs() * f[if dir[i] <= 0.0 { i } else { i + 3 }])
                        .sum()
                }
            };
            kernel += cos_x * a / d.length_squared();
        }
        w[k] = kernel * seen[k];
    }
    w
}

/// Shares (≥ 0) in 255ths of their sum, rounded; all 0 when they sum to 0.
fn in_255ths<const N: usize>(shares: [f64; N]) -> [u8; N] {
    let total: f64 = shares.iter().sum();
    if total <= 0.0 || !total.is_finite() {
        return [0; N];
    }
    shares.map(|x| (255.0 * x / total).round() as u8)
}

/// [`MAX_PARTS`] shares (≥ 0) in 4 bits each, in 15ths of the largest, rounded (share k in
/// byte k / 2, the low half for even k); all 0 when every share is 0. [`part_share`] reads
/// them.
fn in_nibbles(shares: [f64; MAX_PARTS]) -> [u8; 4] {
    let largest = shares.iter().copied().fold(0.0, f64::max);
    let mut out = [0u8; 4];
    if largest <= 0.0 || !largest.is_finite() {
        return out;
    }
    for (k, x) in shares.iter().enumerate() {
        let q = (15.0 * x / largest).round() as u8;
        out[k / 2] |= q << (4 * (k % 2));
    }
    out
}

/// Share `k` of the shares `in_nibbles` packed, in 15ths of the largest.
pub fn part_share(packed: [u8; 4], k: usize) -> u8 {
    (packed[k / 2] >> (4 * (k % 2))) & 0xF
}

/// [`Link::children`] of element `r` gathering from element `s`: the unoccluded form factor
/// from `r`'s centroid to each of `s`'s four children, as shares of their sum in 255ths (all
/// 0 when the centroid sees none of `s`). One point: the shares only need to say which part
/// of the source the receiver favours, and on the Cornell box one point gives the same
/// surfaces as the receiver's whole [`RECEIVER_POINTS`]-point rule, at a fraction of the cost.
fn child_shares(tree: &Tree, r: usize, s: usize) -> [u8; 4] {
    // The children share the source's plane, so a point in front of it is in front of each.
    centroid_shares(tree, r, s, child_corners(tree.corners(s)))
}

/// The shares of the unoccluded F from element `r`'s centroid that arrive at each of element
/// `s`'s 16 grandchildren (as [`Tree::split`] would make them twice: child q's child k is
/// share 4q + k), in 255ths of their sum (rounded; all 0 when the centroid sees none of `s`).
/// Like [`Link::children`], one point is enough to say which parts of the source the
/// receiver favours.
pub fn grandchild_shares(tree: &Tree, r: usize, s: usize) -> [u8; 16] {
    let children = child_corners(tree.corners(s));
    let parts = std::array::from_fn(|i| child_corners(children[i / 4])[i % 4]);
    centroid_shares(tree, r, s, parts)
}

/// The unoccluded form factor from element `r`'s centroid to each of `parts` (triangles in
/// element `s`'s plane), as shares of their sum in 255ths (rounded); all 0 when the centroid
/// is behind `s` or sees none of it.
fn centroid_shares<const N: usize>(
    tree: &Tree,
    r: usize,
    s: usize,
    parts: [[DVec3; 3]; N],
) -> [u8; N] {
    let third = [1.0 / 3.0; 3];
    let (x, n) = (tree.point(r, third), tree.surface_normal(r, third));
    if (x - tree.corners(s)[0]).dot(tree.elements[s].normal) <= 0.0 {
        return [0; N];
    }
    in_255ths(parts.map(|q| point_to_polygon(x, n, &q)))
}

/// The corners of the four children [`Tree::split`] makes of a triangle with `corners`, in
/// its order (the same midpoints, so the same triangles).
pub(crate) fn child_corners([a, b, c]: [DVec3; 3]) -> [[DVec3; 3]; 4] {
    let (ab, bc, ca) = (0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a));
    [[a, ab, ca], [ab, b, bc], [ca, bc, c], [bc, ca, ab]]
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
    corners_and_centroid()
        .into_iter()
        .map(|b| point_form_factor(tree, tree.point(r, b), tree.surface_normal(r, b), s))
        .fold(0.0, f64::max)
}

/// The spread (largest − smallest) of the unoccluded point form factor from the corners and
/// the centroid of element `r` to element `s`: how much the kernel varies over `r`.
pub(super) fn point_form_factor_spread(tree: &Tree, r: usize, s: usize) -> f64 {
    let (lo, hi) = corners_and_centroid()
        .into_iter()
        .map(|b| point_form_factor(tree, tree.point(r, b), tree.surface_normal(r, b), s))
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), f| {
            (lo.min(f), hi.max(f))
        });
    hi - lo
}

/// Barycentrics of a triangle's three corners and its centroid.
fn corners_and_centroid() -> [[f64; 3]; 4] {
    let third = 1.0 / 3.0;
    [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [third, third, third],
    ]
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
    if !link.must_open() {
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
    let prefer_receiver = if link.must_open() {
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
