//! Final gather: the radiance shown at each output vertex, computed at the vertex from the
//! solution instead of averaged from the patches around it. The finite-element solution is
//! good on average over a patch, but a patch mesh does not follow shadow edges, and the area
//! mean of the patches around a vertex blurs them; evaluating the rendering equation once more
//! at the vertex, with the solution as the light arriving there, puts the sharp part (the
//! direct light) exactly where the viewer looks (Reichert 1992; Lischinski, Tampieri &
//! Greenberg, "Combining hierarchical radiosity and discontinuity meshing", SIGGRAPH 1993, §5).
//!
//! At a vertex x with unit normal n, reflectance ρ and emission Le:
//!
//! L(x) = Le + ρ · ( Σ_e Le_e · F(x → e) · V̄(x, e)  +  ∫_Ω L_r(h(x, ω)) cosθ/π dω ).
//!
//! Where each part lives:
//!
//! | part | file | what it computes |
//! |---|---|---|
//! | the modes, the [`Gatherer`], [`gather()`] | this file | which vertices get what; the scene's emitters; the entry point |
//! | where a vertex is gathered | `sites` | the point, nudged off contacts ([`NUDGE`]); buried vertices |
//! | the direct term | `direct` | the emitters' F·V̄ (exact visible pieces, else shadow rays: [`crate::light::emitter`]), many-light sampling, the sun and lamps |
//! | the indirect term (`full`) | `indirect` | hemisphere rays into the solved patches, near hits ([`NEAR_HIT`]), rays beside edges ([`EDGE_RAYS`]), the sky |
//! | bright patches | `bright` | the solution's far brighter patches (a daylit floor's sun patches), reached by shadow rays too, weighed against the hemisphere's |
//! | openings | `openings` | where the sky comes into an enclosed scene, found by a pilot of rays, reached by rays too, weighed likewise |
//! | rays against the patches | `trace` | the scene triangles the patches tile, and the patch hit on a grid |
//! | display refinement | [`mod@refine`] | output edges split where the light departs from linear ([`refine::DEFAULT_TOLERANCE`]) |
//! | the cheap direct light | `coarse` | the display's edges; a correlated estimate at vertices and midpoints that orders the tests and screens the flips |
//! | flips | [`flip`] | diagonals of coplanar triangles turned to follow the direct light |
//! | the values shown | [`local_fit`] | noise fitted away, the chord correction, the tested midpoints' least squares |
//!
//! `direct` mode keeps the solution's indirect light: at each patch, the solved radiance less
//! its emission and its own direct light (the same estimator at the patch's 7-point Gauss
//! rule), averaged to the vertices as the bake does, plus the exact direct light at the
//! vertex. Every random choice is keyed by (seed, vertex), so a fixed seed gives the same
//! colours for any thread count.

use std::fmt;

use glam::DVec3;

use rayon::prelude::*;
use serde::Serialize;

use crate::bake::Site;
use crate::choice::Choice;
use crate::color::Rgb;
use crate::distributed::{Exchange, Reader, Solo, Writer};
use crate::light::emitter::GATHER_MAX_SHADOW_RAYS;
use crate::light::{Emitter, LightTree};
use crate::mesh::Patches;
use crate::sampling::Rng;
use crate::scene::{Environment, Scene};
use crate::visibility::NONE;
use sites::Spot;
use trace::Surfaces;

mod bright;
mod brightest;
pub mod cache;
mod coarse;
mod direct;
pub mod flip;
mod indirect;
pub mod local_fit;
mod openings;
pub mod pieces;
pub mod refine;
mod sites;
mod trace;

pub use cache::{Cache, CacheStats};
pub use direct::{
    emitters_cost, EXACT_EMITTER_COST, MAX_EXACT_EMITTERS, MAX_WEIGHED_EMITTERS,
    MAX_WEIGHED_NEAR_HIT_EMITTERS, OTHER_LIGHT_MAX_SAMPLES, OTHER_LIGHT_PILOT, OTHER_LIGHT_SAMPLES,
    SAMPLED_SPREAD,
};
pub use indirect::{
    EDGE_MAX_PER_STRATUM, EDGE_MIN_SIDE, EDGE_RAYS, NEAR_DEPTH, NEAR_HIT, NEAR_RAYS, ROULETTE,
    SLOT_HIT,
};
pub use refine::{refine, Plan, Refined};
pub use sites::{buried_patches, NUDGE, NUDGE_MAX};

/// What the final gather recomputes at the output vertices.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Gather {
    /// `full` when the output has at most [`FULL_GATHER_MAX_VERTICES`] vertices (or the
    /// hemisphere rays per vertex are given), else `cache` ([`Gather::resolve`]).
    Auto,
    /// Vertex colours are the area-weighted mean of the patches around each vertex.
    None,
    /// The direct light exactly at each vertex; the indirect light from the solution.
    Direct,
    /// Direct light exactly and indirect light gathered by hemisphere rays at each vertex.
    Full,
    /// Direct light exactly at each vertex; indirect light gathered at some vertices, where
    /// nearby surfaces make it vary, and interpolated between them (irradiance caching:
    /// [`cache`]).
    Cache,
}

impl Choice for Gather {
    const SETTING: &'static str = "gather";
    const ALL: &'static [Gather] = &[
        Gather::Auto,
        Gather::None,
        Gather::Direct,
        Gather::Full,
        Gather::Cache,
    ];

    fn name(self) -> &'static str {
        match self {
            Gather::Auto => "auto",
            Gather::None => "none",
            Gather::Direct => "direct",
            Gather::Full => "full",
            Gather::Cache => "cache",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Gather::Auto => {
                "full up to 62,500 output vertices (the hierarchical display's before its \
                 shadow and contact lines cut it), cache beyond"
            }
            Gather::None => "vertex colours are the mean of the patches around each vertex",
            Gather::Direct => {
                "direct light computed exactly at each vertex, indirect from the patches"
            }
            Gather::Full => "direct light exactly and indirect by hemisphere rays at each vertex",
            Gather::Cache => {
                "direct light exactly at each vertex, indirect gathered where nearby surfaces make \
                 it vary and interpolated between (irradiance caching)"
            }
        }
    }
}

impl fmt::Display for Gather {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Hemisphere rays of the whole `full` gather when the number per vertex is not given, at the
/// scene's default patch size: the indirect light's noise falls as rays⁻½ while the cost grows
/// with vertices × rays, so a fixed budget keeps a large scene's gather bounded. Against the
/// point-wise benchmark's probes, the Cornell box's displayed error falls all the way from 64
/// rays a vertex to 1024, steeply up to about 128 and slowly after. A finer `--max-edge`
/// multiplies it ([`auto_rays`]).
pub const AUTO_RAY_BUDGET: usize = 4_000_000;

/// Hemisphere rays per vertex for `vertices` output vertices when the patches are `finer`
/// times smaller by area than the scene's default ([`crate::pipeline::Settings::finer`], ≥ 1):
/// [`AUTO_RAY_BUDGET`] × `finer` shared out, at least [`MIN_AUTO_RAYS`] and at most 1024
/// each. The budget grows with `finer` so that a vertex gets the rays it would get at the
/// default size: the vertices multiply as the patches shrink, and a fixed budget would leave
/// each one noisier, so a user asking for a finer mesh would see a worse picture (the Cornell
/// box at a fifth of the default `--max-edge`: 140 rays a vertex instead of 1024).
pub fn auto_rays(vertices: usize, finer: f64) -> usize {
    debug_assert!(finer >= 1.0);
    ((AUTO_RAY_BUDGET as f64 * finer / vertices.max(1) as f64) as usize).clamp(MIN_AUTO_RAYS, 1024)
}

/// The fewest hemisphere rays a vertex gets when their number is not given.
pub const MIN_AUTO_RAYS: usize = 64;

/// `auto` gathers every vertex (`full`) up to this many output vertices: as many as
/// [`AUTO_RAY_BUDGET`] gives [`MIN_AUTO_RAYS`] rays each. Past it, a gather at every vertex
/// would either cost more than its budget or give each vertex fewer rays than its noise
/// allows, so `auto` takes the `cache` gather ([`cache`]): the direct light exactly at every
/// vertex, the indirect light gathered where it varies and interpolated between, and a display
/// refinement bounded by the output's size ([`refine::budget_for`]). Its cost grows as the
/// output vertices times what a point's direct light costs, like the hierarchical solve's
/// growth with the elements, so it stays a bounded share of the bake (BENCHMARKS.md "Large
/// outputs: the `cache` gather").
pub const FULL_GATHER_MAX_VERTICES: usize = AUTO_RAY_BUDGET / MIN_AUTO_RAYS;

impl Gather {
    /// The gather that runs for an output of `vertices` vertices: `auto` becomes `full` when
    /// there are at most [`FULL_GATHER_MAX_VERTICES`] or `rays_given` (the hemisphere rays per
    /// vertex were chosen), else `cache`; the other modes stay what they are.
    pub fn resolve(self, vertices: usize, rays_given: bool) -> Gather {
        match self {
            Gather::Auto if rays_given || vertices <= FULL_GATHER_MAX_VERTICES => Gather::Full,
            Gather::Auto => Gather::Cache,
            mode => mode,
        }
    }
}

/// Shadow rays start [`LIFT`] × the scene's extent above the surface point and end as far
/// in front of the emitter point they aim at, so a ray that grazes a surface (from a point
/// beside a wall to that wall) cannot be blocked by the rounding of the surface's own
/// neighbouring patches: a segment between two points on the front side of a plane stays
/// on that side. Far above the `f32` rounding of the BVH's coordinates (~1e-7 of the extent),
/// far below any feature the gather resolves.
const LIFT: f64 = 1e-6;

/// What the gather reads: the scene's emitters, the output patches with their solved radiance,
/// and a BVH over the patches.
pub struct Gatherer<'a> {
    /// The emitting scene triangles.
    emitters: Vec<Emitter>,
    /// The light tree over `emitters`, which the others' rays draw from beyond
    /// [`MAX_WEIGHED_EMITTERS`] at a gathering point and [`MAX_WEIGHED_NEAR_HIT_EMITTERS`] at a
    /// near hit (empty below both).
    emitter_tree: LightTree,
    /// Index into `emitters` of each scene triangle, or [`NONE`].
    emitter_of: Vec<u32>,
    /// Each emitter's partner, if any: the other half of a convex quadrilateral of the same
    /// Le (a lamp's panel, a window), and that quadrilateral's corners, counter-clockwise
    /// seen from its front ([`direct::pair_emitters`]). The direct term computes the pair's visible
    /// pieces as one ([`Gatherer::exact_emitters`]).
    partner: Vec<Option<(u32, [DVec3; 4])>>,
    /// Emitters counted with a partner as one.
    groups: usize,
    /// The emitters by where their bounds are large, from [`brightest::INDEX_FROM`] of them
    /// ([`Gatherer::exact_emitters`]).
    brightest: Option<brightest::Brightest>,
    patches: &'a Patches,
    radiance: &'a [Rgb],
    /// The patches as traced ([`trace`]).
    surfaces: Surfaces,
    /// How far a contact vertex's gather point may move off it, scene units
    /// ([`Gatherer::with_contact_edges`]; ∞ unless contact lines are mesh edges).
    nudge_max: f64,
    /// How far rays start above the surface and end above an emitter: a millionth of the
    /// scene's extent (see [`Gatherer::direct`]).
    lift: f64,
    seed: u64,
    /// More hemisphere rays beside edges of the incident light, as a share of a gather's rays
    /// ([`EDGE_RAYS`]; [`Gatherer::with_edge_rays`]).
    edge_rays: f64,
    /// The probability of following a slot's near hit past [`NEAR_DEPTH`] ([`ROULETTE`];
    /// [`Gatherer::with_slot_roulette`]).
    roulette: f64,
    /// The lights outside the mesh ([`crate::light::outside`]): the sun and the point lights are
    /// part of the direct term, the sky comes through the hemisphere rays that leave the scene.
    env: Environment,
    /// The tree over `env`'s point lights, to draw one at a near hit's point
    /// ([`Environment::sharp_direct_sampled`]).
    light_tree: LightTree,
    /// The gather is `cache` ([`Gatherer::with_cache`]).
    cache: bool,
    /// For the `cache` gather in a scene of more than [`MAX_WEIGHED_EMITTERS`] emitters: the
    /// emitters by the sphere within which they are not sampled ([`SAMPLED_SPREAD`]), so a
    /// point finds the ones left to its rays without visiting them all.
    unsampled: Option<cache::Index>,
    /// The ranks that share the gather's vertices ([`Gatherer::with_comm`]).
    pub(super) comm: &'a dyn Exchange,
    /// The solution's bright patches, which the gather's points also reach by shadow rays
    /// ([`bright`]); `None` where no patch is that bright.
    bright: Option<bright::Bright>,
    /// Where the sky comes in, where the scene is enclosed ([`openings`]).
    openings: Option<openings::Openings>,
    /// Each patch's gap under a parallel face close in front of it (scene units), 0 where
    /// none ([`Gatherer::covers`]); empty until [`Gatherer::with_covers`].
    cover: Vec<f64>,
}

impl<'a> Gatherer<'a> {
    /// `radiance[i]` is patch i's solved radiance, W·sr⁻¹·m⁻² per channel; `env` the lights
    /// outside the mesh that lit the solution.
    pub fn new(
        scene: &Scene,
        patches: &'a Patches,
        radiance: &'a [Rgb],
        env: &Environment,
        seed: u64,
    ) -> Self {
        // The emitting triangles, and each scene triangle's index among them.
        let mut emitters = Vec::new();
        let mut emitter_of = vec![NONE; scene.triangles.len()];
        for (t, tri) in scene.triangles.iter().enumerate() {
            let m = &scene.materials[tri.material as usize];
            let corners = tri.vertices.map(|v| scene.positions[v as usize]);
            let normal = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
            if !m.is_emitter() || normal.length() == 0.0 {
                continue;
            }
            emitter_of[t] = emitters.len() as u32;
            // A partly transparent emitter sends from its covered share only.
            let sent = m.emission.map(|e| e * (1.0 - m.transmittance));
            emitters.push(Emitter::new(corners, normal.normalize(), sent));
        }
        let (lo, hi) = scene.bounds();
        let emitter_tree =
            if emitters.len() > MAX_WEIGHED_EMITTERS.min(MAX_WEIGHED_NEAR_HIT_EMITTERS) {
                LightTree::new(&emitters)
            } else {
                LightTree::default()
            };
        let partner = direct::pair_emitters(&emitters);
        let surfaces = Surfaces::new(patches);
        let lift = LIFT * (hi - lo).length();
        let openings = if env.sky.iter().any(|&l| l > 0.0) {
            openings::Openings::find(patches, &surfaces, env.up.axis(), lift, seed)
        } else {
            None
        };
        let groups = emitters.len() - partner.iter().flatten().count() / 2;
        let brightest = (emitters.len() >= brightest::INDEX_FROM).then(|| {
            let partners: Vec<Option<u32>> = partner.iter().map(|p| p.map(|(j, _)| j)).collect();
            brightest::Brightest::new(&emitters, &partners)
        });
        Gatherer {
            emitters,
            emitter_tree,
            emitter_of,
            partner,
            groups,
            brightest,
            patches,
            radiance,
            surfaces,
            nudge_max: f64::INFINITY,
            lift,
            seed,
            edge_rays: EDGE_RAYS,
            roulette: ROULETTE,
            env: env.clone(),
            light_tree: LightTree::new(&env.lights),
            cache: false,
            unsampled: None,
            comm: &Solo,
            bright: bright::Bright::of(patches, radiance),
            openings,
            cover: Vec::new(),
        }
    }

    /// The ranks of a bake over several processes ([`crate::distributed`]): each gathers a
    /// consecutive share of the vertices (and of the display refinement's tests and new
    /// vertices), and every rank ends with all of them, the values one process finds.
    pub fn with_comm(mut self, comm: &'a dyn Exchange) -> Self {
        self.comm = comm;
        self
    }

    /// Whether the gather is `cache` ([`cache`]): in a scene of more than
    /// [`MAX_WEIGHED_EMITTERS`] emitters, the emitters are then indexed by where they are left
    /// to the hemisphere rays, for `Gatherer::uncounted_emission`.
    pub fn with_cache(mut self, yes: bool) -> Self {
        self.cache = yes;
        if yes && self.emitters.len() > MAX_WEIGHED_EMITTERS {
            let reach = |e: &Emitter| e.radius / SAMPLED_SPREAD;
            let top = self.emitters.iter().map(reach).fold(0.0, f64::max);
            let finest = self.emitters.iter().map(reach).fold(top, f64::min);
            let mut index = cache::Index::new(top, finest.max(top * 1e-6));
            for (k, e) in self.emitters.iter().enumerate() {
                index.insert(k as u32, e.centre, reach(e));
            }
            self.unsampled = Some(index);
        }
        self
    }

    /// The share of more rays a hemisphere casts beside edges of its incident light, ≥ 0
    /// ([`EDGE_RAYS`] unless set; 0 = the plain stratified gather).
    pub fn with_edge_rays(mut self, share: f64) -> Self {
        debug_assert!(share >= 0.0 && share.is_finite());
        self.edge_rays = share;
        self
    }

    /// The probability in [0, 1) with which a near hit in a slot at the end of a chain is
    /// followed one level more ([`ROULETTE`] unless set; 0 = the chain ends at [`NEAR_DEPTH`]
    /// reading the patch's mean, as a measure of what the roulette buys).
    pub fn with_slot_roulette(mut self, probability: f64) -> Self {
        assert!(
            (0.0..1.0).contains(&probability),
            "roulette probability {probability}"
        );
        self.roulette = probability;
        self
    }

    /// Whether the contact lines are edges of the patch mesh ([`crate::mesh::split_contacts`])
    /// and the display refinement follows the light beside them (the pipeline passes both).
    /// Then a vertex at a contact lies on the discontinuity itself, and its gather point moves
    /// at most [`NUDGE_MAX`] of the extent off it (without the refinement the rim's own light
    /// would be spread over whole faces, so with `--gather-tolerance 0` the bound makes the
    /// Cornell box's display worse).
    /// Otherwise (the hierarchical solver's default) a contact vertex is wherever its
    /// element's corner falls, its patch straddles the contact, and the point moves the whole
    /// [`NUDGE`] toward the patch's visible part.
    pub fn with_contact_edges(mut self, yes: bool) -> Self {
        self.nudge_max = if yes {
            NUDGE_MAX / LIFT * self.lift
        } else {
            f64::INFINITY
        };
        self
    }
}

/// What the gather found at one output vertex.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gathered {
    /// The radiance shown, W·sr⁻¹·m⁻² per channel: Le + `direct` + `indirect`, or the bake's
    /// value at a buried vertex.
    pub radiance: Rgb,
    /// Reflected direct light ρ·Σ_e Le_e F V̄ (radiance units; 0 when `buried`).
    pub direct: Rgb,
    /// Which emitters `direct` computes exactly (a hash of their list, 0 where all of them
    /// are): where two points' differ, their parts do not add up alike (a large near
    /// emitter's light is in one's `direct` and in the other's `indirect`).
    pub exact_key: u64,
    /// Reflected indirect light (radiance units; 0 when `buried`).
    pub indirect: Rgb,
    /// A bound on the standard error of `indirect`'s luminance where hemisphere rays at the
    /// point estimated it (the `full` gather's vertices: ρ_max × the rays' spread / √rays, which
    /// overstates a stratified estimate's), radiance units; 0 where it was interpolated or
    /// fitted (the `cache` gather's records, [`local_fit`]) or the point is buried.
    pub indirect_error: f64,
    /// Some emitter is partly hidden from the point: it lies in a penumbra.
    pub penumbra: bool,
    /// The point is buried under contact geometry and keeps the bake's value.
    pub buried: bool,
}

impl Gathered {
    /// This point's value with `reflected` (radiance units, after its ρ) added to its
    /// indirect light and to what it shows.
    pub(crate) fn with_reflected(mut self, reflected: Rgb) -> Self {
        for ((i, l), r) in self
            .indirect
            .iter_mut()
            .zip(&mut self.radiance)
            .zip(reflected)
        {
            *i += r;
            *l += r;
        }
        self
    }

    /// A buried point showing `radiance` (the bake's value, or its neighbours' mean).
    pub fn buried(radiance: Rgb) -> Self {
        Gathered {
            radiance,
            direct: [0.0; 3],
            exact_key: 0,
            indirect: [0.0; 3],
            indirect_error: 0.0,
            penumbra: false,
            buried: true,
        }
    }

    /// Writes it for another rank ([`crate::distributed`]; [`Gathered::read`] reads it).
    pub fn write(&self, w: &mut Writer) {
        for rgb in [self.radiance, self.direct, self.indirect] {
            rgb.iter().for_each(|&x| w.f64(x));
        }
        w.u64(self.exact_key);
        w.f64(self.indirect_error);
        w.bytes(&[self.penumbra as u8 | (self.buried as u8) << 1]);
    }

    /// What [`Gathered::write`] wrote.
    pub fn read(r: &mut Reader) -> Self {
        let mut rgb = || [r.f64(), r.f64(), r.f64()];
        let (radiance, direct, indirect) = (rgb(), rgb(), rgb());
        let (exact_key, indirect_error) = (r.u64(), r.f64());
        let [flags] = r.bytes();
        Gathered {
            radiance,
            direct,
            exact_key,
            indirect,
            indirect_error,
            penumbra: flags & 1 != 0,
            buried: flags & 2 != 0,
        }
    }
}

impl Gatherer<'_> {
    /// The `full` gather at `spot`: emission, reflected direct light and reflected indirect
    /// light by `rays` hemisphere rays.
    pub(crate) fn full(&self, spot: &Spot, rays: usize, rng: &mut Rng) -> Gathered {
        let direct = self.reflected_direct(spot, GATHER_MAX_SHADOW_RAYS, rng);
        self.full_lit(spot, rays, direct, rng)
    }

    /// [`Gatherer::full`] with its reflected direct light `direct` already computed at `spot`
    /// by [`Gatherer::reflected_direct`] (by the display refinement's test at the midpoint
    /// that then becomes the vertex, with that test's shadow rays).
    pub(super) fn full_lit(
        &self,
        spot: &Spot,
        rays: usize,
        (direct, penumbra, exact): (Rgb, bool, Vec<u32>),
        rng: &mut Rng,
    ) -> Gathered {
        let (indirect, error, _) = self.reflected_indirect(spot, &exact, rays, rng);
        let mut g = self.with_emission(spot.patch as usize, (direct, penumbra, &exact), indirect);
        g.indirect_error = error;
        g
    }

    /// The `full` gather at the surface point `x` (unit normal `n`, on the side it faces) by
    /// `rays` hemisphere rays, keyed by `seed`: what a vertex there would show with no display
    /// in between, for diagnosis against point references (the tools' `gather_at_probes`).
    /// The patch is the first one met from ten times the rays' lift above `x` (1e-5 of the
    /// scene's extent, far below any gap the gather resolves: a thousandth reached past a
    /// table's underside 5 mm above a leg's top and found no patch there), straight down;
    /// `None` where there is none, or it does not face `n`.
    pub fn at_point(&self, x: DVec3, n: DVec3, rays: usize, seed: u64) -> Option<Gathered> {
        let spot = self.spot_at(x, n)?;
        let mut rng = Rng::new(&[self.seed, seed, 0x9_0B_E5]);
        Some(self.full(&spot, rays, &mut rng))
    }

    /// The patch under the surface point `x` (unit normal `n`, on the side it faces), as
    /// [`Gatherer::at_point`] finds it: whose solved radiance a probe there is compared with
    /// (the tools' `gather_at_probes`). `None` where there is none, or it does not face `n`.
    pub fn patch_at(&self, x: DVec3, n: DVec3) -> Option<u32> {
        self.spot_at(x, n).map(|s| s.patch)
    }

    /// The surface point `x` (unit normal `n`, on the side it faces) as a gathering spot, on
    /// the patch [`Gatherer::at_point`] describes.
    pub(crate) fn spot_at(&self, x: DVec3, n: DVec3) -> Option<Spot> {
        let above = 10.0 * self.lift;
        let hit = self.surfaces.closest(x + above * n, -n, NONE)?;
        if hit.t > 2.0 * above || self.patches.normal[hit.patch as usize].dot(n) <= 0.0 {
            return None;
        }
        Some(Spot {
            x,
            n,
            patch: hit.patch,
        })
    }

    /// Le of patch `p` plus the reflected parts: `direct` as [`Gatherer::reflected_direct`]
    /// gives it (the light, whether in a penumbra, the emitters computed exactly).
    pub(super) fn with_emission(
        &self,
        p: usize,
        direct: (Rgb, bool, &[u32]),
        indirect: Rgb,
    ) -> Gathered {
        let (direct, penumbra, exact) = direct;
        let le = self.patches.emission[p];
        let exact_key = self.exact_key(exact);
        Gathered {
            radiance: std::array::from_fn(|c| le[c] + direct[c] + indirect[c]),
            direct,
            exact_key,
            indirect,
            indirect_error: 0.0,
            penumbra,
            buried: false,
        }
    }

    /// [`Gathered::exact_key`] of the list `exact` of emitters computed exactly: a hash of it
    /// (FNV-1a over the indices), 0 where it holds them all.
    pub(crate) fn exact_key(&self, exact: &[u32]) -> u64 {
        if exact.len() < self.emitters.len() {
            exact.iter().fold(0xcbf2_9ce4_8422_2325, |h, &k| {
                (h ^ u64::from(k)).wrapping_mul(0x0100_0000_01b3)
            })
        } else {
            0
        }
    }

    /// The random numbers of output vertex `v`.
    pub(crate) fn vertex_rng(&self, v: usize) -> Rng {
        Rng::new(&[self.seed, v as u64, 0x6A7_4E6])
    }

    /// The scene's extent (its bounding box diagonal), scene units.
    pub(crate) fn extent(&self) -> f64 {
        self.lift / LIFT
    }

    /// The seed every random choice is keyed by.
    pub(crate) fn seed(&self) -> u64 {
        self.seed
    }
}

/// Recomputes the radiance of the output vertices `sites` (from [`crate::bake::bake_sites`])
/// by the final gather `mode`, with `rays` hemisphere rays for `full` (per record for
/// `cache`, where `None` shares out [`cache::RAY_BUDGET`]). `baked[v]` is the bake's value at
/// vertex v (kept for buried vertices; for `direct`, the bake of the indirect part is recomputed
/// here). Returns what was found at each vertex, and for `cache` the records (for the display
/// refinement).
pub fn gather(
    gatherer: &Gatherer,
    sites: &[Site],
    baked: &[Rgb],
    mode: Gather,
    rays: usize,
    cache_rays: Option<usize>,
    visible_fraction: &[f64],
) -> (Vec<Gathered>, Option<Cache>) {
    let p = gatherer.patches;
    debug_assert!(mode != Gather::Auto, "resolved before: Gather::resolve");
    debug_assert!(
        gatherer.cache == (mode == Gather::Cache),
        "Gatherer::with_cache"
    );
    match mode {
        Gather::None => return (baked.iter().map(|&l| Gathered::buried(l)).collect(), None),
        Gather::Cache => {
            let (values, cache) = cached(gatherer, sites, baked, cache_rays, visible_fraction);
            return (values, Some(cache));
        }
        _ => {}
    }
    // `direct`: each patch's indirect part, L − Le − ρ·D, to be averaged like the bake.
    let indirect_part: Vec<Rgb> = if mode == Gather::Direct {
        let d = gatherer.patch_direct();
        (0..p.len())
            .map(|i| {
                std::array::from_fn(|c| {
                    (gatherer.radiance[i][c] - p.emission[i][c] - p.reflectance[i][c] * d[i][c])
                        .max(0.0)
                })
            })
            .collect()
    } else {
        Vec::new()
    };
    let progress = crate::progress::stage("gather", Some(sites.len() as u64));
    let gather_at = |v: usize| {
        let site = &sites[v];
        progress.advance(1);
        let mut rng = gatherer.vertex_rng(v);
        let Some(spot) = gatherer.spot(site, visible_fraction) else {
            return Gathered::buried(baked[v]);
        };
        if mode == Gather::Full {
            return gatherer.full(&spot, rays, &mut rng);
        }
        // `direct`: the patches' reflected indirect light, averaged as the bake does.
        let (direct, penumbra, exact) =
            gatherer.reflected_direct(&spot, GATHER_MAX_SHADOW_RAYS, &mut rng);
        let area: f64 = site.patches.iter().map(|&q| p.area[q as usize]).sum();
        let indirect = std::array::from_fn(|c| {
            let reflected: f64 = site
                .patches
                .iter()
                .map(|&q| p.area[q as usize] * indirect_part[q as usize][c])
                .sum();
            reflected / area
        });
        gatherer.with_emission(spot.patch as usize, (direct, penumbra, &exact), indirect)
    };
    let values = gatherer
        .comm
        .map_shared(sites.len(), gather_at, Gathered::write, Gathered::read);
    (values, None)
}

/// The `cache` gather ([`cache`]): each vertex's exact direct light and the Le its own rays
/// must bring, and the records' reflected light interpolated.
fn cached(
    gatherer: &Gatherer,
    sites: &[Site],
    baked: &[Rgb],
    rays: Option<usize>,
    visible_fraction: &[f64],
) -> (Vec<Gathered>, Cache) {
    let spots: Vec<Option<Spot>> = sites
        .par_iter()
        .map(|site| gatherer.spot(site, visible_fraction))
        .collect();
    // The area each vertex shows: a third of its patches' (scene units²).
    let areas: Vec<f64> = sites
        .iter()
        .map(|site| {
            let a: f64 = site
                .patches
                .iter()
                .map(|&q| gatherer.patches.area[q as usize])
                .sum();
            a / 3.0
        })
        .collect();
    // Each vertex's light but the records' first, Le + ρ·(D + E): what share of it the
    // records bring sets their rays ([`cache::record_shares`]).
    let progress = crate::progress::stage("gather: direct light", Some(spots.len() as u64));
    let lit = |v: usize| {
        progress.advance(1);
        match &spots[v] {
            Some(spot) => gatherer.cached_vertex(spot, [0.0; 3], &mut gatherer.vertex_rng(v)),
            None => Gathered::buried(baked[v]),
        }
    };
    let lit = gatherer
        .comm
        .map_shared(spots.len(), lit, Gathered::write, Gathered::read);
    drop(progress);
    let shares = cache::record_shares(&lit, baked);
    let (indirect, cache) = gatherer.cached_indirect(&spots, &areas, &shares, rays);
    let values = lit
        .into_iter()
        .zip(indirect)
        .zip(&spots)
        .enumerate()
        .map(|(v, ((g, reflected), spot))| match (spot, reflected) {
            (Some(spot), Some(reflected)) => {
                let rho = gatherer.patches.reflectance[spot.patch as usize];
                g.with_reflected(std::array::from_fn(|c| rho[c] * reflected[c]))
            }
            _ => Gathered::buried(baked[v]),
        })
        .collect();
    (values, cache)
}

#[cfg(test)]
mod tests;
