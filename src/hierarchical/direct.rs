//! Direct light at the elements: what the emitters send to each element, computed at the
//! element's own rule points instead of through links. This module owns that estimate and the
//! choice of the emitters it covers.
//!
//! Why: a link carries the light it transports to its receiver as a whole, and push-pull gives
//! every leaf below the receiver the same irradiance. Direct light is the sharpest part of the
//! radiance (shadow edges, the fall-off next to a light), so carried by links it is smeared
//! over each link's receiver, and the second bounce gathers the smeared light: a block's dim
//! side sees the floor beside it, in its shadow, as bright as the floor's mean. Computed at the
//! element, the direct light is exact to the element's quadrature and shadow rays whatever the
//! links, and links carry only the reflected radiance L − Le of their sources (what an
//! emitter reflects still travels by link), which is smooth and dim, so they can stay coarser.
//! Leaves whose direct light varies over them are split by their own rule
//! ([`super::Hierarchy`]'s refinement: ρ · spread · A > ε), as links are. This is the
//! separation of direct and indirect light of Lischinski, Tampieri & Greenberg ("Combining
//! hierarchical radiosity and discontinuity meshing", SIGGRAPH 1993) and of the final gather
//! ([`crate::gather`]), applied to the elements of the solve: on the Cornell box it halves the
//! worst surface's error against the path-traced reference with fewer links.
//!
//! At a rule point x (unit normal n) of an element, from every chosen emitter e:
//!
//! D(x) = Σ_e Le_e · F(x → e) · V̄(x, e)   (radiance units, before the element's ρ),
//!
//! one emitter's term estimated by [`crate::light::emitter`] (F the exact unoccluded
//! point-to-polygon form factor, V̄ its visible share by kernel-weighted shadow rays): a fixed
//! number of rays per point, [`ELEMENT_SHADOW_RAYS`] or [`ELEMENT_FEW_SHADOW_RAYS`] where the
//! kernel is nearly even over the emitter, not adapted to what the first rays see (stopping
//! when a few rays agree would take points in a thin penumbra for lit more often than not: a
//! bias). In a scene of many emitters ([`ShadowRays::Shared`]) a point's
//! [`ELEMENT_SHARED_SHADOW_RAYS`] are drawn over the emitters in proportion to Le·F instead
//! (F's differential form beyond [`crate::light::emitter::FAR_RADII`] radii,
//! [`crate::light::Emitter::form_factor_weight`]), so that the rays follow the light and not
//! the count of lights; in a scene of very many
//! ([`ShadowRays::Tree`]: hundreds of lamps in a hall, thousands at 10⁶ triangles) they are
//! drawn by the light tree over the emitters ([`LightTree`], Conty Estevez & Kulla 2018),
//! whose chances follow a bound on each node's light, so that a point's cost grows as the
//! logarithm of the lights. Each drawn emitter's term (its exact F) is weighted by its rays
//! over N times its chance: unbiased either way, exact when unoccluded where the chances are
//! ∝ Le·F (every emitter within [`crate::light::emitter::FAR_RADII`] radii). The
//! element's direct light is the rule's weighted mean of D over its unburied points.

use glam::DVec3;

use super::rule::{receiver_rule, unburied_weights, RECEIVER_POINTS};
use super::tree::Tree;
use crate::color::Rgb;
use crate::light::emitter::{
    ELEMENT_FEW_SHADOW_RAYS, ELEMENT_SHADOW_RAYS, ELEMENT_SHARED_SHADOW_RAYS,
    ELEMENT_TREE_SHADOW_RAYS,
};
use crate::light::{Emitter, LightTree, Receiver, Share, SKY_RAYS};
use crate::mesh::Patches;
use crate::sampling::{systematic, Rng};
use crate::scene::Environment;
use crate::visibility::Visibility;

/// The elements compute the direct light of every emitter with shadow rays of its own
/// ([`ELEMENT_SHADOW_RAYS`], [`ELEMENT_FEW_SHADOW_RAYS`]: [`ShadowRays::Own`]) when the
/// emitters (the scene's emitting triangles, [`merged`]) × max(roots, [`DIRECT_ROOTS_FLOOR`])
/// is at most this. The
/// Cornell box (2 emitting triangles, at any `--max-edge` up to 10⁶ roots), the integrating
/// sphere (88 emitters of 1,280 roots) and the generated hall at 10⁴ triangles (82 of
/// 10,786) qualify. Past it, [`DIRECT_BUDGET_MANY`].
pub const DIRECT_BUDGET: usize = 2_000_000;

/// Past [`DIRECT_BUDGET`], the elements compute every emitter's direct light with
/// [`ELEMENT_SHARED_SHADOW_RAYS`] per rule point shared among the emitters, drawn by their
/// weights ([`ShadowRays::Shared`]) while the emitters × max(roots, [`DIRECT_ROOTS_FLOOR`]) is
/// at most this (the bound it had when each point cast 2 rays to every emitter: each point
/// weighs every emitter by its exact form factor, work that grows as emitters × elements),
/// and beyond it drawn by the light tree over them ([`ShadowRays::Tree`]: a point's work
/// grows as the logarithm of the emitters). A furnished interior of 10⁵ triangles under a
/// dozen ceiling panels (40 emitting triangles, 4·10⁶) draws by the weights; the generated
/// hall at 4·10⁴ triangles (328 emitters) and more, and LibreQuake's levels of hundreds of
/// emitting faces, by the tree.
///
/// Why the elements compute it: carried by links, the panels' light is smeared over each
/// link's receiver, and the floor under a desk reads as lit as the floor beside it; the
/// second bounce then brightens the desk's underside and the floor under it again (the
/// gather reads these patches). Computed at the elements, the desk's shadow is in the
/// solution. Carried by links, a hall's hundreds of lamps left its floor and its tables'
/// undersides reading brighter than they are (BENCHMARKS.md, the many-emitters bullet),
/// and the gather's indirect light inherited that.
pub const DIRECT_BUDGET_MANY: usize = DIRECT_BUDGET * ELEMENT_SHADOW_RAYS / 2;

/// See [`DIRECT_BUDGET`]: a scene of few roots still refines into many elements.
pub const DIRECT_ROOTS_FLOOR: usize = 10_000;

/// Nor when the emitters cover more than this fraction of the scene's area (like the matrix
/// method's exact direct columns, [`crate::form_factor::Shortcuts::exact_direct`], which
/// take at most 1/20 of the patches): large
/// emitters (a furnace, where everything emits; a luminous ceiling) light the scene smoothly,
/// which the links follow well, and in a closed scene the links' row normalisation then
/// keeps the energy balance exact (the shadow rays of the direct light would not sum to
/// exactly one).
pub const MAX_EMITTING_AREA: f64 = 0.05;

/// An emitting triangle of the scene whose direct light the elements compute themselves: the
/// root patches it was split into, lit as one emitter. The cost of the elements' direct light
/// is then the scene's emitting triangles × elements, whatever `--max-edge` cut them into (a
/// patch per emitter would multiply the shadow rays by the patches of each light, and past
/// [`DIRECT_BUDGET`] hand all emission back to the links: the Cornell box's light at
/// `--max-edge 12.5` is 512 patches of 2 triangles).
#[derive(Clone, Debug)]
pub struct RootEmitter {
    /// The root patches it covers, ascending.
    pub roots: Vec<u32>,
    /// The scene triangle as an emitter (one root patch's triangle where the patches could
    /// not be told to tile one triangle exactly, [`merged`]).
    pub emitter: Emitter,
    /// How an element's rule point casts its shadow rays to it: its own, or a share of
    /// those drawn over all emitters in a scene of many ([`chosen`]).
    pub rays: ShadowRays,
}

/// The shadow rays of an element's rule point to an emitter ([`element_direct`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShadowRays {
    /// Rays of its own: [`ELEMENT_SHADOW_RAYS`], or [`ELEMENT_FEW_SHADOW_RAYS`] where the
    /// kernel is nearly even over it ([`Emitter::element_shadow_rays`]).
    Own,
    /// A share of the point's [`ELEMENT_SHARED_SHADOW_RAYS`], drawn over every emitter so
    /// marked in proportion to Le·F.
    Shared,
    /// A share of the point's [`ELEMENT_TREE_SHADOW_RAYS`], drawn by the light tree over
    /// every emitter so marked ([`LightTree`]; its leaves weighed by π·Le·F): past
    /// [`DIRECT_BUDGET_MANY`], where weighing every emitter at every rule point would cost
    /// emitters × elements.
    Tree,
}

impl ShadowRays {
    /// A rule point's shadow rays: at most, to each emitter ([`ShadowRays::Own`]), or in all,
    /// shared among the emitters.
    pub fn per_point(self) -> usize {
        match self {
            ShadowRays::Own => ELEMENT_SHADOW_RAYS,
            ShadowRays::Shared => ELEMENT_SHARED_SHADOW_RAYS,
            ShadowRays::Tree => ELEMENT_TREE_SHADOW_RAYS,
        }
    }
}

/// The emitters whose direct light the elements compute ([`chosen`]) and, where their rays
/// are drawn by it ([`ShadowRays::Tree`]), the light tree over them (empty otherwise).
#[derive(Clone, Debug, Default)]
pub struct Emitters {
    /// The emitters, ascending by their first root.
    pub list: Vec<RootEmitter>,
    /// The light tree over `list`'s emitters, its leaf k `list[k]`.
    pub tree: LightTree,
}

impl Emitters {
    /// `list` with the light tree over it if any of them draws by it.
    pub fn new(list: Vec<RootEmitter>) -> Emitters {
        let tree = if list.iter().any(|e| e.rays == ShadowRays::Tree) {
            let lights: Vec<Emitter> = list.iter().map(|e| e.emitter.clone()).collect();
            LightTree::new(&lights)
        } else {
            LightTree::default()
        };
        Emitters { list, tree }
    }

    /// True if the links carry all emission.
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }
}

impl RootEmitter {
    /// Root patch `r` of `roots` as an emitter of its own.
    pub fn of(roots: &Patches, r: usize) -> RootEmitter {
        RootEmitter {
            roots: vec![r as u32],
            emitter: Emitter::new(roots.corners(r), roots.normal[r], roots.sent_emission(r)),
            rays: ShadowRays::Own,
        }
    }
}

/// The emitting root patches `emitting` (ascending) as emitters: the patches cut from one
/// scene triangle as that triangle, where they tile it exactly (one normal, one Le, and the
/// triangle spanned by their corners has their summed area to 1e-9 relative); otherwise a
/// patch each. The triangle's corners are found among the patches' corners: the one farthest
/// from the first patch's centroid, the one farthest from it, and the one farthest from the
/// line through both (each a corner of the triangle, as a triangle's farthest point from any
/// point or line is one of its corners).
pub fn merged(roots: &Patches, emitting: &[usize]) -> Vec<RootEmitter> {
    let mut by_source: std::collections::BTreeMap<u32, Vec<usize>> = Default::default();
    for &r in emitting {
        by_source
            .entry(roots.source_triangle[r])
            .or_default()
            .push(r);
    }
    let mut out = Vec::with_capacity(by_source.len());
    for group in by_source.into_values() {
        match tiled_triangle(roots, &group) {
            Some(corners) => {
                let r = group[0];
                out.push(RootEmitter {
                    roots: group.iter().map(|&r| r as u32).collect(),
                    emitter: Emitter::new(corners, roots.normal[r], roots.sent_emission(r)),
                    rays: ShadowRays::Own,
                });
            }
            None => out.extend(group.iter().map(|&r| RootEmitter::of(roots, r))),
        }
    }
    out.sort_by_key(|e| e.roots[0]);
    out
}

/// The triangle the patches `group` tile exactly, counter-clockwise about their normal, or
/// `None` (see [`merged`]).
fn tiled_triangle(roots: &Patches, group: &[usize]) -> Option<[DVec3; 3]> {
    let first = group[0];
    if group.len() == 1 {
        return Some(roots.corners(first));
    }
    let (n, le) = (roots.normal[first], roots.emission[first]);
    if group
        .iter()
        .any(|&r| roots.normal[r].dot(n) < 1.0 - 1e-9 || roots.emission[r] != le)
    {
        return None;
    }
    let points: Vec<DVec3> = group.iter().flat_map(|&r| roots.corners(r)).collect();
    let farthest = |d: &dyn Fn(DVec3) -> f64| {
        points
            .iter()
            .copied()
            .fold((points[0], f64::NEG_INFINITY), |best, p| {
                let dp = d(p);
                if dp > best.1 {
                    (p, dp)
                } else {
                    best
                }
            })
            .0
    };
    let c = roots.centroid[first];
    let a = farthest(&|p| p.distance_squared(c));
    let b = farthest(&|p| p.distance_squared(a));
    let ab = (b - a).normalize_or_zero();
    let mut third = farthest(&|p| (p - a).reject_from_normalized(ab).length_squared());
    let mut second = b;
    let cross = (second - a).cross(third - a);
    if cross.dot(n) < 0.0 {
        std::mem::swap(&mut second, &mut third);
    }
    let area = 0.5 * cross.length();
    let sum: f64 = group.iter().map(|&r| roots.area[r]).sum();
    ((area - sum).abs() <= 1e-9 * sum).then_some([a, second, third])
}

/// The emitting roots whose direct light the elements compute ([`DIRECT_BUDGET`],
/// [`DIRECT_BUDGET_MANY`], [`MAX_EMITTING_AREA`]): all of them, or none where they cover
/// too much of the scene; as the scene's emitting triangles ([`merged`]), each with the way
/// it gets its shadow rays, and the light tree over them where they are drawn by it.
pub fn chosen(roots: &Patches) -> Emitters {
    let emitting: Vec<usize> = (0..roots.len())
        .filter(|&r| roots.emission[r].iter().any(|&x| x > 0.0) && roots.area[r] > 0.0)
        .collect();
    let emitting_area: f64 = emitting.iter().map(|&r| roots.area[r]).sum();
    let mut emitters = merged(roots, &emitting);
    let cost = emitters.len() * roots.len().max(DIRECT_ROOTS_FLOOR);
    if emitting_area > MAX_EMITTING_AREA * roots.total_area() {
        return Emitters::default();
    }
    let rays = if cost > DIRECT_BUDGET_MANY {
        ShadowRays::Tree
    } else if cost > DIRECT_BUDGET {
        ShadowRays::Shared
    } else {
        ShadowRays::Own
    };
    for e in &mut emitters {
        e.rays = rays;
    }
    Emitters::new(emitters)
}

/// The direct light of one element.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Direct {
    /// The rule's mean over the element's unburied points of D(x), W·sr⁻¹·m⁻² per channel
    /// (before the element's reflectance).
    pub mean: Rgb,
    /// The largest minus the smallest D(x) over those points (largest channel), W·sr⁻¹·m⁻²:
    /// how much the direct light varies over the element.
    pub spread: f64,
    /// The part of `mean` from the sky and the sun ([`crate::light::outside`]), W·sr⁻¹·m⁻².
    pub environment: Rgb,
    /// Shadow rays cast.
    pub rays: u64,
}

/// The lights outside the mesh as the elements see them: the [`Environment`], the BVH over
/// every root (a sky ray is stopped by any face, also the walls of the scene's hull that
/// `occluders` leaves out) and how far rays start above the surface, scene units.
#[derive(Clone, Copy)]
pub struct Outside<'a> {
    pub env: &'a Environment,
    pub vis: &'a Visibility,
    pub lift: f64,
}

/// The direct light of element `e` from `emitters` and from `outside` (the sky and the sun,
/// [`Environment::direct`] with [`SKY_RAYS`] sky rays at each point), its rule points marked in
/// `buried` left out. `occluders` answers the emitters' shadow rays (each ignores the element's
/// root and the emitter's); `shadows` false means nothing can occlude (a convex enclosure): no
/// such ray is cast. The spread counts the emitters and the sun, not the sky: the sky's light
/// varies smoothly, and its rays' noise would split leaves for nothing. Random numbers are
/// keyed by (`seed`, `e`).
#[allow(clippy::too_many_arguments)]
pub fn element_direct(
    tree: &Tree,
    occluders: &Visibility,
    shadows: bool,
    emitters: &Emitters,
    outside: Outside,
    e: usize,
    buried: u16,
    seed: u64,
) -> Direct {
    let rule = receiver_rule();
    let weights = unburied_weights(buried);
    let total: f64 = weights.iter().sum();
    let mut out = Direct::default();
    let lit = outside.env.is_lit();
    if total == 0.0 || (emitters.is_empty() && !lit) {
        return out;
    }
    let root = tree.elements[e].root;
    let points: [(DVec3, DVec3); RECEIVER_POINTS] =
        std::array::from_fn(|k| (tree.point(e, rule[k].0), tree.surface_normal(e, rule[k].0)));
    let mut rng = Rng::new(&[seed, e as u64, 0xD1_EC7]);
    let mut values = [[0.0; 3]; RECEIVER_POINTS];
    let most = [
        ELEMENT_SHADOW_RAYS,
        ELEMENT_FEW_SHADOW_RAYS,
        ELEMENT_SHARED_SHADOW_RAYS,
        ELEMENT_TREE_SHADOW_RAYS,
    ];
    let mut targets = Vec::with_capacity(most.into_iter().max().unwrap_or(0));
    let own = |em: &RootEmitter| em.roots.binary_search(&root).is_err();
    // The segment meets the emitter's plane only at its end, where no triangle blocks
    // ([`Visibility::occluded`]): the emitter's own patches need no ignoring.
    let ignore = [root, crate::visibility::NONE];
    if shadows {
        let mut drawn = Drawn::default();
        for (k, &(x, n)) in points.iter().enumerate() {
            if weights[k] == 0.0 {
                continue;
            }
            drawn.draw(emitters, &own, x, n, &mut rng);
            let (from, mut last) = (occluders.point(x), usize::MAX);
            for &(i, f, count, p) in &drawn.picks {
                let em = &emitters.list[i].emitter;
                let mut share = Share::default();
                let occluded = |y| {
                    occluders.occluded_points_after(&from, &occluders.point(y), ignore, &mut last)
                };
                out.rays +=
                    em.cast_shadow_rays(x, n, count, &mut rng, &mut targets, &mut share, occluded);
                // n_e / (N p_e): its expectation is 1, and over the emitters these weights
                // make the unoccluded sum exact where p_e ∝ Le_max F (Σ Le_max F_e n_e /
                // (N p_e) = Σ Le_max F), unbiased where p_e is the tree's.
                let weight = count as f64 / (drawn.rays as f64 * p);
                let v = share.visible().unwrap_or(1.0);
                for (value, le) in values[k].iter_mut().zip(em.le) {
                    *value += le * f * v * weight;
                }
            }
        }
    }
    for e_root in emitters
        .list
        .iter()
        .filter(|em| own(em) && (em.rays == ShadowRays::Own || !shadows))
    {
        let em = &e_root.emitter;
        for (k, &(x, n)) in points.iter().enumerate() {
            if weights[k] == 0.0 {
                continue; // buried
            }
            let Some(f) = em.form_factor(x, n) else {
                continue; // it sends no light this way
            };
            let v = if shadows {
                let mut share = Share::default();
                let rays = em.element_shadow_rays(x, n);
                // The blocker of one shadow ray is tested first for the next (the same answers).
                let (from, mut last) = (occluders.point(x), usize::MAX);
                let occluded = |y| {
                    occluders.occluded_points_after(&from, &occluders.point(y), ignore, &mut last)
                };
                out.rays +=
                    em.cast_shadow_rays(x, n, rays, &mut rng, &mut targets, &mut share, occluded);
                share.visible().unwrap_or(1.0)
            } else {
                1.0
            };
            for (value, le) in values[k].iter_mut().zip(em.le) {
                *value += le * f * v;
            }
        }
    }
    // The sky and the sun, from a stream of their own (no other estimate changes with them).
    let mut sky = [[0.0; 3]; RECEIVER_POINTS];
    if lit {
        let mut rng = Rng::new(&[seed, e as u64, 0x5C1E5]);
        let Outside { env, vis, lift } = outside;
        for (k, &(x, n)) in points.iter().enumerate() {
            if weights[k] == 0.0 {
                continue;
            }
            let at = Receiver {
                vis,
                x,
                n,
                ignore: root,
                lift,
            };
            let sun = env.sharp_direct(&at, &mut rng);
            let s = env.sky_direct(&at, SKY_RAYS, &mut rng);
            out.rays += (env.sharp_rays() + SKY_RAYS) as u64;
            sky[k] = s;
            for c in 0..3 {
                values[k][c] += sun[c];
                out.environment[c] += weights[k] * (sun[c] + s[c]) / total;
            }
        }
    }
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for (k, value) in values.iter().enumerate() {
        if weights[k] == 0.0 {
            continue;
        }
        for ((m, v), s) in out.mean.iter_mut().zip(value).zip(sky[k]) {
            *m += weights[k] * (v + s) / total;
        }
        let largest = value.iter().copied().fold(0.0, f64::max);
        lo = lo.min(largest);
        hi = hi.max(largest);
    }
    out.spread = hi - lo;
    out
}

/// The draw of a rule point's N shadow rays ([`ELEMENT_SHARED_SHADOW_RAYS`] by the weights,
/// [`ELEMENT_TREE_SHADOW_RAYS`] by the tree) over the emitters whose rays are shared
/// ([`ShadowRays::Shared`], [`ShadowRays::Tree`]), those `own` rejects (the element's own)
/// left out. Weighed: systematic sampling over the weights Le_max · F ([`systematic`]; F by
/// [`crate::light::Emitter::form_factor_weight`], its differential form for the far
/// emitters, the exact F computed only for those drawn), so an emitter of probability p gets
/// ⌊N p⌋ or ⌈N p⌉ rays, and at least one ray in the point's N goes to every emitter with
/// p ≥ 1/N. By the tree: N descents of the light tree at the stratified numbers (i + u)/N,
/// its leaves weighed π·Le_max·F (F as above; the units of its inner nodes' bound,
/// [`LightTree`]), an emitter drawn by successive numbers given their count.
#[derive(Default)]
struct Drawn {
    /// Cumulative weights of the emitters that send light to the point.
    cdf: Vec<f64>,
    /// Those emitters' indices.
    keys: Vec<usize>,
    /// Each drawn emitter: its index in the list, F, its rays and its probability.
    picks: Vec<(usize, f64, usize, f64)>,
    /// The rays drawn, N.
    rays: usize,
}

impl Drawn {
    fn draw(
        &mut self,
        emitters: &Emitters,
        own: &impl Fn(&RootEmitter) -> bool,
        x: DVec3,
        n: DVec3,
        rng: &mut Rng,
    ) {
        self.cdf.clear();
        self.keys.clear();
        self.picks.clear();
        let list = &emitters.list;
        if !emitters.tree.is_empty() {
            self.rays = ShadowRays::Tree.per_point();
            let rays = self.rays;
            let leaf = |k: usize| {
                let e = &list[k];
                if e.rays != ShadowRays::Tree || !own(e) {
                    return 0.0;
                }
                std::f64::consts::PI * e.emitter.form_factor_weight(x, n) * e.emitter.le_max()
            };
            let u = rng.next_f64();
            for i in 0..rays {
                let Some((k, p)) = emitters
                    .tree
                    .sample(x, n, (i as f64 + u) / rays as f64, leaf)
                else {
                    continue;
                };
                Self::pick(&mut self.picks, list, k, p, x, n);
            }
            return;
        }
        self.rays = ShadowRays::Shared.per_point();
        let mut total = 0.0;
        for (i, e) in list.iter().enumerate() {
            if e.rays != ShadowRays::Shared || !own(e) {
                continue;
            }
            let w = e.emitter.form_factor_weight(x, n) * e.emitter.le_max();
            if w > 0.0 {
                total += w;
                self.cdf.push(total);
                self.keys.push(i);
            }
        }
        if self.keys.is_empty() {
            return;
        }
        for (at, p) in systematic(&self.cdf, self.rays, rng.next_f64()) {
            Self::pick(&mut self.picks, list, self.keys[at], p, x, n);
        }
    }

    /// Counts a ray drawn to emitter `k` of `list` with chance `p` in `picks`
    /// ([`Drawn::picks`]): one more for the last pick if it is `k` (both draws give an
    /// emitter's rays in a row), else a new pick with its exact F at `x` (unit normal `n`),
    /// computed once per emitter drawn.
    fn pick(
        picks: &mut Vec<(usize, f64, usize, f64)>,
        list: &[RootEmitter],
        k: usize,
        p: f64,
        x: DVec3,
        n: DVec3,
    ) {
        match picks.last_mut() {
            Some(last) if last.0 == k => last.2 += 1,
            _ => {
                let f = list[k].emitter.form_factor(x, n).unwrap_or(0.0);
                picks.push((k, f, 1, p));
            }
        }
    }
}
