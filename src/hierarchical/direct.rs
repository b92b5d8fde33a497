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
//! bias). The element's direct light is the rule's weighted mean of D over its unburied
//! points.

use glam::DVec3;

use super::links::{receiver_rule, unburied_weights, RECEIVER_POINTS};
use super::tree::Tree;
use crate::color::Rgb;
use crate::light::emitter::{ELEMENT_FEW_SHADOW_RAYS, ELEMENT_SHADOW_RAYS};
use crate::light::{Emitter, Receiver, Share, SKY_RAYS};
use crate::mesh::Patches;
use crate::sampling::Rng;
use crate::scene::Environment;
use crate::visibility::Visibility;

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

/// An emitting root patch whose direct light the elements compute themselves.
#[derive(Clone, Debug)]
pub struct RootEmitter {
    /// The root patch's index.
    pub root: u32,
    /// The patch as an emitter.
    pub emitter: Emitter,
}

impl RootEmitter {
    /// Root patch `r` of `roots` as an emitter.
    pub fn of(roots: &Patches, r: usize) -> RootEmitter {
        RootEmitter {
            root: r as u32,
            emitter: Emitter::new(roots.corners(r), roots.normal[r], roots.emission[r]),
        }
    }
}

/// The emitting roots whose direct light the elements compute ([`DIRECT_BUDGET`],
/// [`MAX_EMITTING_AREA`]): all of them, or none.
pub fn chosen(roots: &Patches) -> Vec<RootEmitter> {
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
        .map(|r| RootEmitter::of(roots, r))
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
    emitters: &[RootEmitter],
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
    let mut targets = Vec::with_capacity(ELEMENT_SHADOW_RAYS.max(ELEMENT_FEW_SHADOW_RAYS));
    for e_root in emitters.iter().filter(|em| em.root != root) {
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
                let ignore = [root, e_root.root];
                let occluded = |y| occluders.occluded(x, y, ignore);
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
