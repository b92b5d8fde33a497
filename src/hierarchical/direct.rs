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
//! ([`crate::gather`]), applied to the elements of the solve. Measured on the Cornell box at
//! ε = 1e-6 (BENCHMARKS.md, "Hierarchical radiosity"): worst surface against the path-traced
//! reference 1.43 % → 0.80 %, with 2.18 M links instead of 3.42 M.
//!
//! At a rule point x (unit normal n) of an element, from every chosen emitter e:
//!
//! D(x) = Σ_e Le_e · F(x → e) · V̄(x, e)   (radiance units, before the element's ρ),
//!
//! F the exact unoccluded point-to-polygon form factor (Lambert's contour integral, clipped to
//! x's horizon, [`point_to_polygon`]) and V̄ = Σ G_k V_k / Σ G_k over [`SHADOW_RAYS`] rays
//! ([`FEW_SHADOW_RAYS`] where G is nearly even over e) to
//! stratified points y_k of the part of e above x's horizon ([`kernel_samples`]), G the
//! point-pair kernel cosθ_x cosθ_y / r²: the visible share of F itself. The element's direct
//! light is the rule's weighted mean of D over its unburied points.
//!
//! The number of rays is fixed, not adapted to what the first rays see: stopping when a few
//! rays agree (wholly lit or wholly shadowed) makes the estimate biased, as points in a thin
//! penumbra are then taken for lit more often than not (measured on the Cornell box: 2 rays
//! per point, 14 more where they disagreed, left the floor's direct light 0.28 % high and a
//! block face lit at a grazing angle 0.38 % high, against the matrix method's exact direct
//! columns). V̄'s ratio of sums is biased by O(1/rays) where G varies much over the emitter
//! (grazing light); at these counts the Cornell box's direct light is within 0.18 % of the
//! matrix method's on every surface but one lit at grazing angles (−0.54 %), which gets a
//! twentieth of its light that way.

use glam::DVec3;

use super::links::{receiver_rule, unburied_weights, RECEIVER_POINTS};
use super::tree::Tree;
use crate::color::Rgb;
use crate::geometry::kernel::point_to_polygon;
use crate::light::{Receiver, SKY_RAYS};
use crate::mesh::Patches;
use crate::sampling::{kernel_samples, Rng};
use crate::scene::Environment;
use crate::visibility::Visibility;

/// Shadow rays per rule point and emitter (stratified over the emitter). Measured on the
/// Cornell box's direct light against the matrix method's (one bounce, ε = 1e-6): with 6
/// rays the worst surfaces lit at grazing angles were +0.26 % and −0.72 % of their direct
/// light, with 10 +0.15 % and −0.54 %, with 16 +0.03 % and −0.41 %; the floor +0.09 %,
/// +0.03 %, +0.05 %.
pub const SHADOW_RAYS: usize = 10;

/// The elements compute the direct light of every emitter when emitting roots × max(roots,
/// [`DIRECT_ROOTS_FLOOR`]) is at most this; otherwise the links carry all emission (a scene
/// with many lights: every element would trace rays to every light). The Cornell box (2
/// emitting roots of 32), the integrating sphere (88 of 1,280) and the generated hall at 10⁴
/// triangles (82 of 10,786) qualify; the hall at 4·10⁴ triangles (328) and more does not.
pub const DIRECT_BUDGET: usize = 2_000_000;

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

/// Shadow rays per rule point and emitter where the kernel G is nearly even over the emitter
/// (at most [`EVEN_KERNEL`] between its largest and smallest values at the emitter's corners
/// and centre: a small or far emitter, not at a grazing angle). The ratio Σ G V / Σ G is then
/// nearly the plain visible fraction, whose estimate has no bias at any count, so few rays
/// do. Decided on the geometry alone, never on what rays saw. Measured on the Cornell box's
/// direct light (one bounce, ε = 1e-6): 4 rays where even (1.25), 10 elsewhere, left every
/// surface within 0.18 % of the matrix method's but one lit at grazing angles (−0.54 %);
/// 1 ray where even left the red wall −0.48 % and the floor +0.29 %.
pub const FEW_SHADOW_RAYS: usize = 4;
/// See [`FEW_SHADOW_RAYS`].
pub const EVEN_KERNEL: f64 = 1.25;

/// Shadow rays from the point `x` (unit normal `n`) to emitter `em`: [`FEW_SHADOW_RAYS`]
/// where the kernel is nearly even over it, else [`SHADOW_RAYS`].
fn shadow_rays(x: DVec3, n: DVec3, em: &Emitter) -> usize {
    let [a, b, c] = em.corners;
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for y in [a, b, c, (a + b + c) / 3.0] {
        let d = y - x;
        let r2 = d.length_squared();
        let g = n.dot(d) * -em.normal.dot(d) / (r2 * r2);
        lo = lo.min(g);
        hi = hi.max(g);
    }
    if lo > 0.0 && hi <= EVEN_KERNEL * lo {
        FEW_SHADOW_RAYS
    } else {
        SHADOW_RAYS
    }
}

/// An emitting root patch whose direct light the elements compute themselves.
#[derive(Clone, Debug)]
pub struct Emitter {
    /// The root patch's index.
    pub root: u32,
    /// Its corners, scene units.
    pub corners: [DVec3; 3],
    /// Its unit front normal.
    pub normal: DVec3,
    /// Its Le, W·sr⁻¹·m⁻² per channel.
    pub le: Rgb,
}

impl Emitter {
    /// Root patch `r` of `roots` as an emitter.
    pub fn of(roots: &Patches, r: usize) -> Emitter {
        Emitter {
            root: r as u32,
            corners: roots.corners(r),
            normal: roots.normal[r],
            le: roots.emission[r],
        }
    }
}

/// The emitting roots whose direct light the elements compute ([`DIRECT_BUDGET`],
/// [`MAX_EMITTING_AREA`]): all of them, or none.
pub fn chosen(roots: &Patches) -> Vec<Emitter> {
    let emitting: Vec<usize> = (0..roots.len())
        .filter(|&r| roots.emission[r].iter().any(|&x| x > 0.0) && roots.area[r] > 0.0)
        .collect();
    let emitting_area: f64 = emitting.iter().map(|&r| roots.area[r]).sum();
    if emitting.len() * roots.len().max(DIRECT_ROOTS_FLOOR) > DIRECT_BUDGET
        || emitting_area > MAX_EMITTING_AREA * roots.total_area()
    {
        return Vec::new();
    }
    emitting
        .into_iter()
        .map(|r| Emitter::of(roots, r))
        .collect()
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
    emitters: &[Emitter],
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
    let mut targets = Vec::with_capacity(SHADOW_RAYS.max(FEW_SHADOW_RAYS));
    for em in emitters.iter().filter(|em| em.root != root) {
        for (k, &(x, n)) in points.iter().enumerate() {
            if weights[k] == 0.0 || (x - em.corners[0]).dot(em.normal) <= 0.0 {
                continue; // buried, or behind the emitter: it sends no light this way
            }
            let f = point_to_polygon(x, n, &em.corners);
            if f <= 0.0 {
                continue;
            }
            let v = if shadows {
                let (mut seen, mut all) = (0.0, 0.0);
                let rays = shadow_rays(x, n, em);
                let (c, nn) = (&em.corners, em.normal);
                kernel_samples(c, nn, x, n, rays, &mut rng, &mut targets, |y, g| {
                    all += g;
                    out.rays += 1;
                    if !occluders.occluded(x, y, [root, em.root]) {
                        seen += g;
                    }
                });
                if all > 0.0 {
                    seen / all
                } else {
                    1.0
                }
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
