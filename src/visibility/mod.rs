//! Ray queries against the scene's triangles: `occluded(p, q)` for the open segment between two
//! surface points (the visibility term of the form factors) and `closest_hit` for a ray. This
//! module owns the BVH (built by obvhs, traversed four boxes and four triangles at a time by our
//! own SIMD code in `bvh4`), the watertight ray–triangle test and the numerical conventions that
//! make the answers independent of the scene's units. It does not know about patches, materials
//! or sampling: callers pass points and triangle indices.
//!
//! # Canonical frame
//! The BVH and the triangle test work in `f32`. To make answers independent of the scene's scale
//! and position, [`Visibility::build`] maps the scene into a canonical frame,
//! `canonical = (scene − centre) · scale`, where `centre` is the centre of the triangles'
//! bounding box and `scale = 1024 / largest extent`, and the canonical
//! coordinates are snapped to a grid of 2⁻²⁰ canonical units (≈ 1e-9 of the extent) before
//! they are rounded to `f32`. The snap absorbs the last-bit differences that rescaling by a
//! non-power of two (millimetres vs metres: ×1e-3) leaves in f64, so a scene in any unit, near
//! the origin or not, gives bit-identical canonical triangles and rays, and a ray aimed exactly
//! at an edge is decided the same way at every scale.
//!
//! # Robustness
//! - The ray–triangle test is the watertight test of Woop, Benthin & Wald, "Watertight
//!   Ray/Triangle Intersection", JCGT 2(1), 2013: a ray through a shared edge or vertex of a
//!   closed mesh hits at least one of the triangles that share it.
//! - The BVH is built over triangle boxes padded by `BOX_PAD` canonical units. A box test in
//!   `f32` is not conservative on its own (a ray grazing a box face can miss the box by one
//!   rounding), which would undo the watertight triangle test for rays along box boundaries
//!   (e.g. through the edges of an axis-aligned grid). The padding is far larger than the `f32`
//!   rounding of the box test and far smaller than any triangle that matters.
//! - The four-lane triangle test performs the scalar test's operations in the same order, lane
//!   by lane, so the traversal's answers are those of testing every triangle (the brute-force
//!   oracles [`Visibility::occluded_brute_force`] and [`Visibility::closest_hit_brute_force`]).
//! - Ray origins are moved back along the ray by `ORIGIN_SHIFT` (in the ray's parameter); the
//!   shift dates from obvhs's traversal (its box test clamps `t ≥ 1e-4`) and is kept so that
//!   every ray, and so every answer, stays what it was.
//!
//! # Twins: the two sides of one surface
//! A triangle and its reverse over the same three corners (bitwise the same canonical
//! coordinates, opposite winding) are *twins*: the front and the back of one two-sided surface
//! (what `--two-sided` makes of every face, and what a two-sided bake writes).
//! [`Visibility::build`] pairs them itself, so callers need no extra input, and traces each pair as
//! one triangle:
//! - [`Visibility::occluded`] ignores the twins of the triangles in `ignore` as well (a point on
//!   one side lies on the other side too);
//! - [`Visibility::closest_hit`] ignores the twin of `ignore` and reports, of a pair, the
//!   triangle whose front faces the ray (so a caller that checks `normal · dir < 0` sees a front
//!   face), with barycentrics in that triangle's own vertex order.
//!
//! Pairing is deterministic: in input order, each triangle pairs with the earliest unpaired
//! triangle over the same corners with the opposite winding. A third copy (a duplicate face
//! with the same winding as one of a pair) stays a separate triangle, as any coincident face does.

mod bvh4;
pub mod light_buffer;
mod ray;
mod twins;

use std::fmt;

use glam::{DVec3, Vec3A};
use obvhs::aabb::Aabb;

use bvh4::Bvh4;
pub use light_buffer::LightBuffer;
use ray::{snap, WatertightRay, CANONICAL_GRID, DIRECTION_GRID};
use twins::pair_twins;

/// Index of a triangle as given to [`Visibility::build`]. [`NONE`] is the "no triangle" sentinel.
pub const NONE: u32 = u32::MAX;

/// Largest extent of the scene in the canonical frame lies in (`CANONICAL_EXTENT`/2,
/// `CANONICAL_EXTENT`], canonical units.
const CANONICAL_EXTENT: f64 = 1024.0;

/// Open-segment margin of [`Visibility::occluded`], relative to the segment: hits with segment
/// parameter `t ≤ SEGMENT_EPS` or `t ≥ 1 − SEGMENT_EPS` (`t = 0` at `p`, `t = 1` at `q`) do not
/// count.
pub const SEGMENT_EPS: f64 = 1e-5;

/// Absolute floor of the open-segment margin and of the closest-hit minimum distance, as a
/// fraction of the scene's largest extent: `1e-5 × extent` (10 µm in a 1 m room). It absorbs
/// the `f32` rounding of canonical coordinates (`3e-5` canonical units at 512, i.e. `3e-8` of
/// the extent) with margin, so a short segment leaving a surface is not blocked by the surface
/// it starts on. Being relative to the scene, it is scale-invariant.
///
/// No margin can absorb the rounding of a segment at a grazing angle θ to the surface it starts
/// or ends on: there the crossing parameter is uncertain by about `(3e-8 × extent / L + 6e-8) /
/// sin θ`. Pass the endpoints' triangles in `ignore`; their coplanar neighbours can then still
/// block a grazing segment whose endpoint lies within rounding of their shared edge.
pub const MIN_DISTANCE_REL: f64 = 1e-5;

/// Minimum hit distance of [`Visibility::closest_hit`], as a fraction of the scene's largest
/// extent: below the `f32` resolution of the canonical frame, i.e. effectively `t > 0`.
pub const HIT_MIN_DISTANCE_REL: f64 = 1e-9;

/// Padding of each triangle's box in the BVH, canonical units (about `1.5e-5` of the largest
/// extent). See the module documentation.
const BOX_PAD: f32 = 1.0 / 64.0;

/// Hits of [`Visibility::first_hit_from_behind`] within this fraction of the scene's largest
/// extent of each other are at the same distance (coincident faces in contact): the
/// tolerance of a touching face, [`crate::mesh::discontinuity::TOUCH`], far above the `f32`
/// rounding of the canonical frame (~3e-8 of the extent).
pub const CONTACT_TIE_REL: f64 = 1e-6;

/// A triangle whose doubled area is below this fraction of its longest edge squared (about
/// the sine of its smallest angle) is a sliver: [`Visibility::lies_face_to_face`] does not
/// trust its orientation. Far above the f32 rounding of the canonical corners (~3e-8 of the
/// extent relative to edges of 1e-3 of it and longer).
const SLIVER_SINE: f64 = 1e-3;

/// A point in scene coordinates with its canonical coordinates ([`Visibility::point`]).
#[derive(Clone, Copy, Debug)]
pub struct Point {
    scene: DVec3,
    canonical: DVec3,
}

/// The closest intersection found by [`Visibility::closest_hit`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Index of the triangle hit, as given to [`Visibility::build`]; never [`NONE`].
    pub triangle: u32,
    /// Ray parameter of the hit: the hit point is `origin + t·dir` in scene coordinates, so `t`
    /// is measured in units of `|dir|` (a distance in scene units when `dir` is a unit vector).
    pub t: f64,
    /// Barycentric weight of the triangle's second vertex `v1`, in [0, 1].
    pub u: f64,
    /// Barycentric weight of the triangle's third vertex `v2`, in [0, 1]; `u + v ≤ 1` and the hit
    /// point is `(1 − u − v)·v0 + u·v1 + v·v2`.
    pub v: f64,
}

/// A BVH over a triangle soup answering occlusion and closest-hit queries.
///
/// Invariants: `tris`, `ids`, `twins` and `twin_corners` have the same length, and `tris[i]` is
/// the canonical-frame, non-degenerate triangle `ids[i]` of the input, in input order
/// (`tris[i]` is the primitive the traversal reports as id `i`). A twin pair (see the
/// module documentation) is one primitive: `ids[i]` is the earlier of the two input indices,
/// `twins[i]` the later (or [`NONE`]), and corner `k` of the twin is corner
/// `twin_corners[i][k]` of `tris[i]`. `twin_of` is empty when there are no twins, else it maps
/// every input index to its twin or [`NONE`]. `bvh` is only traversed when `tris` is non-empty.
#[derive(Clone)]
pub struct Visibility {
    /// Four-wide BVH over the padded boxes of `tris`.
    bvh: Bvh4,
    /// Triangles in canonical coordinates; the BVH reports triangle `i` of this list as `i`.
    tris: Vec<[Vec3A; 3]>,
    /// Input index of each triangle of `tris`.
    ids: Vec<u32>,
    /// Input index of the twin of each triangle of `tris`, or [`NONE`].
    twins: Vec<u32>,
    /// Which corner of `tris[i]` each corner of its twin is (unused without a twin).
    twin_corners: Vec<[u8; 3]>,
    /// Twin of each input index ([`NONE`] for none); empty when no triangle has a twin.
    twin_of: Vec<u32>,
    /// Number of triangles given to `build`, including skipped ones.
    len: usize,
    /// Centre of the scene's bounding box, scene units.
    centre: DVec3,
    /// Canonical units per scene unit (a power of two).
    scale: f64,
    /// `MIN_DISTANCE_REL × largest extent`, canonical units.
    min_distance: f64,
    /// Each input triangle's transmittance t ([`Visibility::with_transmittance`]) as a
    /// threshold t·2³² on a ray's hash ([`Visibility::lets_through`]); empty when every
    /// triangle is opaque (the common case, which then costs one length test per hit).
    clear: Vec<u64>,
}

impl fmt::Debug for Visibility {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Visibility")
            .field("len", &self.len)
            .field("traced_triangles", &self.tris.len())
            .field("twin_pairs", &self.twin_pairs())
            .field("bvh_bytes", &self.bvh.bytes())
            .field("centre", &self.centre)
            .field("scale", &self.scale)
            .finish()
    }
}

impl Visibility {
    /// Builds the BVH over `triangles`, given in scene coordinates (any unit and position).
    ///
    /// Triangles with a non-finite vertex or zero area (collinear vertices after rounding to the
    /// canonical `f32` frame) can never be hit and are left out of the BVH; their indices stay
    /// valid (they are simply never reported). An empty list gives a `Visibility` that never
    /// occludes and never hits. Twins (a triangle and its reverse over the same corners) are
    /// paired and traced as one surface with two sides; see the module documentation.
    ///
    /// # Panics
    /// If `triangles.len() ≥ u32::MAX` (indices are `u32` and [`NONE`] is reserved).
    pub fn build(triangles: &[[DVec3; 3]]) -> Visibility {
        let finite = |t: &[DVec3; 3]| t.iter().all(|v| v.is_finite());
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for v in triangles.iter().filter(|t| finite(t)).flatten() {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
        let extent = (hi - lo).max_element();
        let mut vis = Visibility::untraced(triangles.len(), DVec3::ZERO, 1.0, 0.0);
        if !(extent.is_finite() && extent > 0.0) {
            // Empty, or every finite triangle collapses to one point: nothing can be hit.
            return vis;
        }
        vis.centre = 0.5 * (lo + hi);
        vis.scale = CANONICAL_EXTENT / extent;
        vis.min_distance = MIN_DISTANCE_REL * extent * vis.scale;
        vis.fill(triangles);
        vis
    }

    /// Traces `triangles` (scene coordinates) in this frame: each is mapped to canonical
    /// coordinates and kept unless it is non-finite or degenerate there.
    fn fill(&mut self, triangles: &[[DVec3; 3]]) {
        let mut tris = Vec::with_capacity(triangles.len());
        let mut ids = Vec::with_capacity(triangles.len());
        for (i, t) in triangles.iter().enumerate() {
            let c = t.map(|v| self.to_canonical(v).as_vec3a());
            let area2 =
                (c[1].as_dvec3() - c[0].as_dvec3()).cross(c[2].as_dvec3() - c[0].as_dvec3());
            let finite = t
                .iter()
                .chain(&c.map(|v| v.as_dvec3()))
                .all(|v| v.is_finite());
            if finite && area2 != DVec3::ZERO {
                tris.push(c);
                ids.push(i as u32);
            }
        }
        self.set_triangles(tris, ids);
    }

    /// A `Visibility` of `len` input triangles in the given frame with nothing traced yet
    /// ([`Visibility::set_triangles`] fills it).
    ///
    /// # Panics
    /// If `len ≥ u32::MAX` (indices are `u32` and [`NONE`] is reserved).
    fn untraced(len: usize, centre: DVec3, scale: f64, min_distance: f64) -> Visibility {
        assert!(
            len < NONE as usize,
            "at most u32::MAX - 1 triangles are supported, got {len}"
        );
        Visibility {
            bvh: Bvh4::default(),
            tris: Vec::new(),
            ids: Vec::new(),
            twins: Vec::new(),
            twin_corners: Vec::new(),
            twin_of: Vec::new(),
            len,
            centre,
            scale,
            min_distance,
            clear: Vec::new(),
        }
    }

    /// These triangles with transmittances `t` (indexed as the triangles given to
    /// [`Visibility::build`], each in [0, 1]; an empty slice, or all zeros, leaves them
    /// opaque). A triangle with t > 0 is a screen with holes over the share t of its area
    /// ([`crate::scene::Material::transmittance`]), so every query treats it as follows:
    /// - [`Visibility::transmittance`] multiplies the t of every triangle along a ray: the
    ///   exact share of a light's rays that get through (sun, sky and lamps);
    /// - every other query (segments, closest hits, shadow rays' yes-or-no) lets a given
    ///   ray through with chance t, decided by a hash of the ray and the triangle (hashed
    ///   stochastic transparency, after Enderton, Sintorn, Shirley & Luebke, "Stochastic
    ///   transparency", I3D 2010, and Wyman & McGuire, "Hashed alpha testing", I3D 2017): the
    ///   same ray always gets the same answer, whatever the thread or the traversal order, and
    ///   any estimate that averages rays (form factors, gathers) converges to the transmitted
    ///   share.
    ///
    /// # Panics
    /// If `t` is neither empty nor one value per triangle.
    pub fn with_transmittance(mut self, t: &[f64]) -> Visibility {
        assert!(
            t.is_empty() || t.len() == self.len,
            "one transmittance per triangle"
        );
        if t.iter().any(|&t| t > 0.0) {
            self.clear = t.iter().map(|&t| clear_threshold(t)).collect();
        } else {
            self.clear = Vec::new();
        }
        self
    }

    /// True if input triangle `id` lets some light through (transmittance > 0,
    /// [`Visibility::with_transmittance`]).
    pub fn transmits(&self, id: u32) -> bool {
        self.clear.get(id as usize).is_some_and(|&c| c > 0)
    }

    /// True if some triangle lets light through ([`Visibility::with_transmittance`]).
    pub fn has_transmittance(&self) -> bool {
        !self.clear.is_empty()
    }

    /// True when primitive `i` lets this ray through: the hash of the ray and the triangle
    /// falls under the triangle's transmittance threshold. Always false for opaque triangles.
    #[inline(always)]
    pub(in crate::visibility) fn lets_through(&self, i: usize, ray: &WatertightRay) -> bool {
        if self.clear.is_empty() {
            return false;
        }
        let threshold = self.clear[self.ids[i] as usize];
        threshold != 0 && ray_hash(ray, self.ids[i]) < threshold
    }

    /// The transmittance of primitive `i`: 0 for opaque.
    #[inline(always)]
    fn passing(&self, i: usize) -> f64 {
        match self.clear.get(self.ids[i] as usize) {
            Some(&c) => c as f64 / CLEAR_ONE as f64,
            None => 0.0,
        }
    }

    /// Build the BVH over canonical triangles `tris` (input ids `ids`) and store both in BVH
    /// order. Empty input leaves an empty BVH that is never traversed.
    fn set_triangles(&mut self, tris: Vec<[Vec3A; 3]>, ids: Vec<u32>) {
        if tris.is_empty() {
            return;
        }
        // One primitive per twin pair: the earlier triangle, with its twin attached.
        let pairs = pair_twins(&tris);
        let mut twins = Vec::with_capacity(tris.len());
        let mut twin_corners = Vec::with_capacity(tris.len());
        let mut keep = Vec::with_capacity(tris.len());
        for (k, pair) in pairs.iter().enumerate() {
            match *pair {
                Some((other, _)) if other < k => {} // the later twin: traced with `other`
                Some((other, corners)) => {
                    keep.push(k);
                    twins.push(ids[other]);
                    twin_corners.push(corners);
                }
                None => {
                    keep.push(k);
                    twins.push(NONE);
                    twin_corners.push([0, 1, 2]);
                }
            }
        }
        if keep.len() < tris.len() {
            self.twin_of = vec![NONE; self.len];
            for (&k, &twin) in keep.iter().zip(&twins) {
                if twin != NONE {
                    self.twin_of[ids[k] as usize] = twin;
                    self.twin_of[twin as usize] = ids[k];
                }
            }
        }
        let tris: Vec<[Vec3A; 3]> = keep.iter().map(|&k| tris[k]).collect();
        let ids: Vec<u32> = keep.iter().map(|&k| ids[k]).collect();
        let boxes: Vec<Aabb> = tris
            .iter()
            .map(|t| {
                let min = t[0].min(t[1]).min(t[2]) - Vec3A::splat(BOX_PAD);
                let max = t[0].max(t[1]).max(t[2]) + Vec3A::splat(BOX_PAD);
                Aabb::new(min, max)
            })
            .collect();
        self.bvh = Bvh4::build(&tris, &boxes);
        self.tris = tris;
        self.ids = ids;
        self.twins = twins;
        self.twin_corners = twin_corners;
    }

    /// The same triangles, frame and conventions, with only those where `keep[id]` is true
    /// (`keep` is indexed by the ids given to [`Visibility::build`]): answers are those of a
    /// scene without the others, bit for bit (same canonical triangles and rays).
    ///
    /// # Panics
    /// If `keep.len()` differs from [`Visibility::len`].
    pub fn restricted(&self, keep: &[bool]) -> Visibility {
        assert_eq!(keep.len(), self.len, "one flag per triangle");
        let mut out = Visibility::untraced(self.len, self.centre, self.scale, self.min_distance);
        // Every kept triangle, a twin pair's back rebuilt from its corners, in input order so
        // that pairs form again exactly as in `build`.
        let mut kept: Vec<(u32, [Vec3A; 3])> = Vec::new();
        for (i, tri) in self.tris.iter().enumerate() {
            if keep[self.ids[i] as usize] {
                kept.push((self.ids[i], *tri));
            }
            let twin = self.twins[i];
            if twin != NONE && keep[twin as usize] {
                kept.push((twin, self.twin_corners[i].map(|k| tri[k as usize])));
            }
        }
        kept.sort_unstable_by_key(|&(id, _)| id);
        let (ids, tris): (Vec<u32>, Vec<[Vec3A; 3]>) = kept.into_iter().unzip();
        out.set_triangles(tris, ids);
        out.clear = self.clear.clone();
        out
    }

    /// Other triangles (scene coordinates) in this `Visibility`'s canonical frame, so that points
    /// prepared by [`Visibility::point`] of either serve both ([`Visibility::occluded_points`]).
    /// Degenerate and non-finite triangles are left out as in [`Visibility::build`]; the
    /// frame's rounding is the same, so a triangle given to both traces identically.
    ///
    /// # Panics
    /// If `triangles.len() ≥ u32::MAX`, as [`Visibility::build`].
    pub fn in_frame_of(&self, triangles: &[[DVec3; 3]]) -> Visibility {
        let mut out =
            Visibility::untraced(triangles.len(), self.centre, self.scale, self.min_distance);
        out.fill(triangles);
        out
    }

    /// Number of triangles given to [`Visibility::build`] (including skipped degenerate ones).
    pub fn len(&self) -> usize {
        self.len
    }

    /// True if [`Visibility::build`] was given no triangles.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The twin of input triangle `triangle` (its reverse over the same corners, the other side
    /// of the same surface), or [`NONE`] if it has none (or is out of range).
    pub fn twin(&self, triangle: u32) -> u32 {
        self.twin_of.get(triangle as usize).copied().unwrap_or(NONE)
    }

    /// Number of twin pairs found by [`Visibility::build`].
    pub fn twin_pairs(&self) -> usize {
        self.twins.iter().filter(|&&t| t != NONE).count()
    }

    /// True if primitive `i` (a triangle or a twin pair) is `ignore[0]` or `ignore[1]`.
    #[inline(always)]
    fn ignored(&self, i: usize, ignore: [u32; 2]) -> bool {
        let (id, twin) = (self.ids[i], self.twins[i]);
        id == ignore[0]
            || id == ignore[1]
            || (twin != NONE && (twin == ignore[0] || twin == ignore[1]))
    }

    /// The triangle of primitive `i` a ray along canonical `dir` meets, with barycentrics
    /// `(u, v)` (of the primitive's corners 1 and 2) converted to that triangle's own corners:
    /// the primitive itself, or its twin when the primitive's back faces the ray.
    #[inline]
    fn facing(&self, i: usize, dir: Vec3A, u: f32, v: f32) -> (u32, f32, f32) {
        let twin = self.twins[i];
        if twin == NONE {
            return (self.ids[i], u, v);
        }
        let [a, b, c] = self.tris[i].map(|p| p.as_dvec3());
        if (b - a).cross(c - a).dot(dir.as_dvec3()) < 0.0 {
            return (self.ids[i], u, v);
        }
        // Corner k of the twin is corner twin_corners[i][k] of the primitive.
        let w = [1.0 - u - v, u, v];
        let m = self.twin_corners[i];
        (twin, w[m[1] as usize], w[m[2] as usize])
    }

    /// True if the open segment between `p` and `q` (scene coordinates) is blocked by a triangle
    /// whose index is not in `ignore` (pass [`NONE`] to ignore nothing) and that is not the twin
    /// of one in `ignore`.
    ///
    /// With `x(t) = p + t·(q − p)`, hits count for `t ∈ [m, 1 − m]`, where
    /// `m = max(SEGMENT_EPS, 1e-5 × extent / |q − p|)` ([`SEGMENT_EPS`], [`MIN_DISTANCE_REL`]):
    /// the triangles `p` and `q` lie on do not block, even when not ignored. A degenerate
    /// segment (`p == q`, or shorter than `2e-5 × extent`) is never occluded.
    pub fn occluded(&self, p: DVec3, q: DVec3, ignore: [u32; 2]) -> bool {
        self.occluded_points(&self.point(p), &self.point(q), ignore)
    }

    /// A scene point with its canonical coordinates computed once, for callers that trace many
    /// segments from the same points ([`Visibility::occluded_points`]).
    pub fn point(&self, x: DVec3) -> Point {
        Point {
            scene: x,
            canonical: self.to_canonical(x),
        }
    }

    /// [`Visibility::occluded`] for points prepared by [`Visibility::point`] (of this
    /// `Visibility`, or of one it was [`Visibility::restricted`] from: the frame is the same).
    /// Same answers, bit for bit, without transforming the points again.
    pub fn occluded_points(&self, p: &Point, q: &Point, ignore: [u32; 2]) -> bool {
        let Some(ray) = self.canonical_segment_ray(p, q) else {
            return false;
        };
        self.bvh.any_hit(&ray, |i| {
            !self.ignored(i, ignore) && !self.lets_through(i, &ray)
        })
    }

    /// [`Visibility::occluded_points`] testing first the triangle `last` (a triangle index, or
    /// `usize::MAX` for none), and setting `last` to the blocker when the BVH finds one: the
    /// "last occluder" cache of Haines & Greenberg's light buffer. Segments from one point to
    /// the samples of one emitter, or of a row's neighbouring patches, are mostly blocked by
    /// the triangle that blocked the one before. The same answer bit for bit: a blocked segment
    /// is blocked whichever blocker is found first, and the triangle is tested with the BVH's
    /// own watertight test and filters.
    pub fn occluded_points_after(
        &self,
        p: &Point,
        q: &Point,
        ignore: [u32; 2],
        last: &mut usize,
    ) -> bool {
        let Some(ray) = self.canonical_segment_ray(p, q) else {
            return false;
        };
        if *last < self.tris.len()
            && !self.ignored(*last, ignore)
            && ray
                .intersect(&self.tris[*last], ray.t_lo, ray.t_hi)
                .is_some()
            && !self.lets_through(*last, &ray)
        {
            return true;
        }
        // The BVH calls the filter only for triangles the ray meets: one that passes blocks.
        let mut blocker = usize::MAX;
        let blocked = self.bvh.each_hit(&ray, |i| {
            let blocks = !self.ignored(i, ignore) && !self.lets_through(i, &ray);
            if blocks {
                blocker = i;
            }
            blocks
        });
        if blocked {
            *last = blocker;
        }
        blocked
    }

    /// Oracle for tests: [`Visibility::occluded`] answered by testing every triangle with the
    /// same ray and the same watertight test, without the BVH.
    pub fn occluded_brute_force(&self, p: DVec3, q: DVec3, ignore: [u32; 2]) -> bool {
        let Some(ray) = self.segment_ray(p, q) else {
            return false;
        };
        (0..self.tris.len()).any(|i| {
            !self.ignored(i, ignore)
                && ray.intersect(&self.tris[i], ray.t_lo, ray.t_hi).is_some()
                && !self.lets_through(i, &ray)
        })
    }

    /// The first triangle, other than `ignore` (or [`NONE`]) and its twin, hit by the ray
    /// `origin + t·dir` (scene coordinates) for `t ∈ (t_min, t_max]`. Of a twin pair, the one
    /// whose front faces the ray is reported.
    ///
    /// `t` is measured in units of `|dir|` (`dir` need not be unit; `t_max` may be infinite).
    /// `t_min = 1e-9 × extent / |dir|` ([`HIT_MIN_DISTANCE_REL`]) stands in for 0: the caller
    /// excludes the origin's own triangle with `ignore`, and a larger floor would let rays that
    /// start next to a concave corner pass through the adjacent wall (a leak of ~1e-3 of the
    /// rays from corner patches in hemisphere shooting). Both sides of triangles are hit. The
    /// hit is the least `(t, triangle index)` over all triangles met, `t` as the watertight test
    /// computes it, whatever the traversal order (ties go to the lowest index). Returns `None` for
    /// a zero or non-finite `dir`.
    pub fn closest_hit(&self, origin: DVec3, dir: DVec3, t_max: f64, ignore: u32) -> Option<Hit> {
        let (ray, m) = self.direction_ray(origin, dir, t_max)?;
        let mut best: Option<(f32, u32, f32, f32)> = None;
        self.bvh.closest(&ray, |i| {
            if self.ignored(i, [ignore, ignore]) || self.lets_through(i, &ray) {
                return None;
            }
            let (t, u, v) = ray.intersect(&self.tris[i], ray.t_lo, ray.t_hi)?;
            let (id, u, v) = self.facing(i, ray.dir, u, v);
            if best.is_none_or(|b| t < b.0 || (t == b.0 && id < b.1)) {
                best = Some((t, id, u, v));
            }
            Some(best.map_or(t, |b| b.0))
        });
        best.map(|b| ray.hit(b, m))
    }

    /// True if [`Visibility::closest_hit`] with the same arguments would hit anything: the same
    /// answer, bit for bit (the same ray, the same exact test per triangle), but the walk ends
    /// at the first triangle met instead of seeking the nearest. For shadow rays.
    pub fn blocked(&self, origin: DVec3, dir: DVec3, t_max: f64, ignore: u32) -> bool {
        let Some((ray, _)) = self.direction_ray(origin, dir, t_max) else {
            return false;
        };
        self.bvh.any_hit(&ray, |i| {
            !self.ignored(i, [ignore, ignore])
                && ray.intersect(&self.tris[i], ray.t_lo, ray.t_hi).is_some()
                && !self.lets_through(i, &ray)
        })
    }

    /// The share of light along the ray `origin + t·dir`, `t ∈ (t_min, t_max]` as in
    /// [`Visibility::closest_hit`], that passes every triangle on the way (but `ignore` and its
    /// twin): the product of their transmittances ([`Visibility::with_transmittance`]), in
    /// [0, 1]. Without transparent triangles it is exactly 0 where [`Visibility::blocked`]
    /// holds and 1 elsewhere. For the light of the sun, the sky and lamps through panes: no
    /// noise, where the yes-or-no of one hashed ray would give t on average.
    pub fn transmittance(&self, origin: DVec3, dir: DVec3, t_max: f64, ignore: u32) -> f64 {
        if self.clear.is_empty() {
            return if self.blocked(origin, dir, t_max, ignore) {
                0.0
            } else {
                1.0
            };
        }
        let Some((ray, _)) = self.direction_ray(origin, dir, t_max) else {
            return 1.0;
        };
        let mut share = 1.0;
        // `each_hit` visits only the triangles the ray meets (its exact four-lane test).
        let opaque = self.bvh.each_hit(&ray, |i| {
            if self.ignored(i, [ignore, ignore]) {
                return false;
            }
            share *= self.passing(i);
            share == 0.0
        });
        if opaque {
            0.0
        } else {
            share
        }
    }

    /// True when the surface point `x` (unit normal `n`, on triangle `ignore`) is buried: the
    /// first surface hit straight along its normal is seen from behind, i.e. `x` lies inside a
    /// closed object or under a surface lying on it (the floor under a block, the ceiling behind
    /// a light mounted on it). Such points receive no light and are seen by nobody, so they
    /// must not dilute their patch's radiance (hidden-area elimination: the form factors'
    /// rows, the hierarchy's elements, the environment's patch light, the gather).
    ///
    /// A point lying face to face on another surface (a leg's bottom on the floor) is buried
    /// too ([`Visibility::lies_face_to_face`]): its normal ray starts in the contact, where
    /// the surface it lies on is closer than any hit can be, and may meet nothing beyond.
    pub fn buried(&self, x: DVec3, n: DVec3, ignore: u32) -> bool {
        self.first_hit_from_behind(x, n, ignore) == Some(true)
            || self.lies_face_to_face(x, n, ignore)
    }

    /// [`CONTACT_TIE_REL`] × the largest extent, scene units: surfaces closer than this are in
    /// contact.
    pub fn contact_distance(&self) -> f64 {
        self.contact_tie() / self.scale
    }

    /// [`Visibility::contact_distance`] in canonical units.
    fn contact_tie(&self) -> f64 {
        self.min_distance * (CONTACT_TIE_REL / MIN_DISTANCE_REL)
    }

    /// True when another surface passes through the point `x` (within [`CONTACT_TIE_REL`] × the
    /// extent) facing it: its normal is within 60° of −`n`. A ray leaving such a point along
    /// `n` starts in the contact and cannot meet that surface (hits closer than
    /// [`HIT_MIN_DISTANCE_REL`] do not count), so the question is asked with a short segment
    /// from just in front of `x` back through it. Surfaces meeting `x` edge-on (a wall at the
    /// floor's edge) or facing the same way (the coplanar neighbour) do not cover it; `ignore`
    /// and two-sided (twin) triangles are skipped.
    pub fn lies_face_to_face(&self, x: DVec3, n: DVec3, ignore: u32) -> bool {
        let delta = self.contact_distance();
        let Some((ray, _)) = self.direction_ray(x + delta * n, -n, 2.0 * delta) else {
            return false;
        };
        let mut found = false;
        self.bvh.closest(&ray, |i| {
            // A twin pair faces both ways: it cannot tell a surface lying on `x` from the
            // coplanar neighbour of a two-sided `x`, so it never counts.
            if found || self.twins[i] != NONE || self.ignored(i, [ignore, ignore]) {
                return None;
            }
            ray.intersect(&self.tris[i], ray.t_lo, ray.t_hi)?;
            let [a, b, c] = self.tris[i].map(|p| p.as_dvec3());
            // A sliver's orientation is lost to the f32 rounding of its corners (the ceiling's
            // patches along a diagonal, some turned over): only a triangle whose smallest
            // angle is clear of that rounding tells which way it faces.
            let cross = (b - a).cross(c - a);
            let longest = (b - a)
                .length_squared()
                .max((c - b).length_squared())
                .max((a - c).length_squared());
            if cross.length() >= SLIVER_SINE * longest && cross.normalize().dot(n) < -0.5 {
                found = true;
                return Some(ray.t_lo);
            }
            None
        });
        found
    }

    /// Whether the first surface along the ray `origin + t·dir` (other than `ignore` and its
    /// twin) is seen from behind: `None` when the ray meets nothing, else whether some triangle
    /// hit within [`CONTACT_TIE_REL`] × the extent of the closest hit has its back to the ray
    /// (of a twin pair, the side facing the ray is its front: never from behind).
    ///
    /// This is the burial test's question ([`Visibility::buried`]): a point inside a
    /// closed object, or under a surface lying on it, sees a back first. Where two objects
    /// touch along coincident faces (a table leg's top against the table's underside), a ray
    /// from inside the leg meets the leg's top from behind and the underside from the front
    /// at the same distance up to rounding; [`Visibility::closest_hit`] would report whichever
    /// rounds nearer (or has the lower index), so a point inside the leg would pass for
    /// visible or not by chance. Any back among such ties answers "from behind": the ray came
    /// from inside the object whose face it is.
    pub fn first_hit_from_behind(&self, origin: DVec3, dir: DVec3, ignore: u32) -> Option<bool> {
        let (ray, _) = self.direction_ray(origin, dir, f64::INFINITY)?;
        let tie = self.contact_tie() as f32;
        let mut best = f32::INFINITY;
        // The hits near the best so far: (t, seen from behind); a few at most.
        let mut near = [(0.0f32, false); 8];
        let mut count = 0;
        self.bvh.closest(&ray, |i| {
            if self.ignored(i, [ignore, ignore]) {
                return None;
            }
            let (t, _, _) = ray.intersect(&self.tris[i], ray.t_lo, ray.t_hi)?;
            if t > best + tie {
                return Some(best + tie);
            }
            let [a, b, c] = self.tris[i].map(|p| p.as_dvec3());
            let back = self.twins[i] == NONE && (b - a).cross(c - a).dot(ray.dir.as_dvec3()) > 0.0;
            best = best.min(t);
            // Keep the hits still within the tie of the best, and this one.
            let mut kept = 0;
            for k in 0..count {
                if near[k].0 <= best + tie {
                    near[kept] = near[k];
                    kept += 1;
                }
            }
            count = kept;
            if count < near.len() {
                near[count] = (t, back);
                count += 1;
            }
            Some(best + tie)
        });
        (best < f32::INFINITY).then(|| {
            near[..count]
                .iter()
                .any(|&(t, back)| back && t <= best + tie)
        })
    }

    /// Oracle for tests: [`Visibility::closest_hit`] answered by testing every triangle with the
    /// same ray and the same watertight test, without the BVH.
    pub fn closest_hit_brute_force(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_max: f64,
        ignore: u32,
    ) -> Option<Hit> {
        let (ray, m) = self.direction_ray(origin, dir, t_max)?;
        let mut best: Option<(f32, u32, f32, f32)> = None;
        for (i, tri) in self.tris.iter().enumerate() {
            if self.ignored(i, [ignore, ignore]) || self.lets_through(i, &ray) {
                continue;
            }
            if let Some((t, u, v)) = ray.intersect(tri, ray.t_lo, ray.t_hi) {
                let (id, u, v) = self.facing(i, ray.dir, u, v);
                if best.is_none_or(|b| t < b.0 || (t == b.0 && id < b.1)) {
                    best = Some((t, id, u, v));
                }
            }
        }
        best.map(|b| ray.hit(b, m))
    }

    /// Calls `visit(id)` with the input index of every triangle whose box overlaps the box
    /// `[lo, hi]` (scene coordinates) padded by `BOX_PAD` canonical units (1.5e-5 of the
    /// extent), but those in `ignore` and their twins (pass [`NONE`] to ignore nothing): a
    /// superset of those meeting it, each once (of a twin pair, the earlier index only: the
    /// two are one surface), until `visit` returns `false`. Returns `false` if it was stopped.
    pub fn overlapping(
        &self,
        lo: DVec3,
        hi: DVec3,
        ignore: [u32; 2],
        visit: impl FnMut(u32) -> bool,
    ) -> bool {
        self.overlapping_convex(lo, hi, &[], ignore, visit)
    }

    /// [`Visibility::overlapping`] restricted to the convex region inside every half-space of
    /// `planes` (scene coordinates: `(m, q)` keeps the points p with m·(p − q) ≥ 0): triangles
    /// wholly outside one of them by more than `BOX_PAD` canonical units are not visited
    /// (`Bvh4::overlapping_convex`). Still a superset of those meeting the region.
    pub fn overlapping_convex(
        &self,
        lo: DVec3,
        hi: DVec3,
        planes: &[(DVec3, DVec3)],
        ignore: [u32; 2],
        mut visit: impl FnMut(u32) -> bool,
    ) -> bool {
        if self.tris.is_empty() {
            return true;
        }
        let pad = DVec3::splat(f64::from(BOX_PAD));
        let lo = (self.to_canonical(lo) - pad).as_vec3a();
        let hi = (self.to_canonical(hi) + pad).as_vec3a();
        // In canonical units p_c = (p − centre)·scale: m·(p − q) ≥ 0 is
        // m̂·p_c + m̂·(centre − q)·scale ≥ 0, m̂ the unit normal.
        let mut canonical = [(glam::Vec3A::ZERO, 0.0f32); 8];
        let mut n = 0;
        for &(m, q) in planes.iter().take(canonical.len()) {
            let Some(m) = m.try_normalize() else { continue };
            canonical[n] = (m.as_vec3a(), (m.dot(self.centre - q) * self.scale) as f32);
            n += 1;
        }
        self.bvh
            .overlapping_convex(lo, hi, &canonical[..n], BOX_PAD, |i| {
                self.ignored(i, ignore) || visit(self.ids[i])
            })
    }

    /// Canonical coordinates of the scene point `x`.
    fn to_canonical(&self, x: DVec3) -> DVec3 {
        snap((x - self.centre) * self.scale, CANONICAL_GRID)
    }

    /// The watertight ray for the open segment `p`–`q`, parametrised so that `t ∈ [0, 1]` spans
    /// the segment, or `None` if there is nothing to trace.
    fn segment_ray(&self, p: DVec3, q: DVec3) -> Option<WatertightRay> {
        self.canonical_segment_ray(&self.point(p), &self.point(q))
    }

    /// [`Visibility::segment_ray`] for prepared points.
    fn canonical_segment_ray(&self, p: &Point, q: &Point) -> Option<WatertightRay> {
        if self.tris.is_empty() || p.scene == q.scene {
            return None;
        }
        let d = q.canonical - p.canonical;
        self.segment_ray_along(p, d, d.length())
    }

    /// [`Visibility::canonical_segment_ray`] for `d = q.canonical − p.canonical` and its length,
    /// already computed by the caller (`p.scene != q.scene` and a non-empty scene assumed).
    #[inline(always)]
    fn segment_ray_along(&self, p: &Point, d: DVec3, length: f64) -> Option<WatertightRay> {
        let pc = p.canonical;
        let margin = SEGMENT_EPS.max(self.min_distance / length);
        if !(length > 0.0 && margin < 0.5) {
            return None;
        }
        WatertightRay::new(pc, d, margin, 1.0 - margin)
    }

    /// The watertight ray for `origin + t·dir`, with a unit (snapped) direction; `m` (returned) is
    /// (returned) so that it is about one canonical unit long: internal `t' = m·t`.
    fn direction_ray(&self, origin: DVec3, dir: DVec3, t_max: f64) -> Option<(WatertightRay, f64)> {
        if self.tris.is_empty() || t_max.is_nan() || t_max <= 0.0 {
            return None;
        }
        let dc = dir * self.scale;
        let length = dc.length();
        if !(length > 0.0 && length.is_finite()) {
            return None;
        }
        // Unit direction, snapped so that the same direction at another scene scale gives the
        // same bits; internal t' = m·t with m = |dir| in canonical units.
        let m = length;
        let d = snap(dc / m, DIRECTION_GRID);
        let t_lo = self.min_distance * (HIT_MIN_DISTANCE_REL / MIN_DISTANCE_REL) / length * m;
        let ray = WatertightRay::new(self.to_canonical(origin), d, t_lo, t_max * m)?;
        Some((ray, m))
    }
}

/// [`Visibility::with_transmittance`]'s threshold for t = 1: every hash is below it.
const CLEAR_ONE: u64 = 1 << 32;

/// The hash threshold of transmittance `t` (clamped to [0, 1], NaN opaque): t·2³².
fn clear_threshold(t: f64) -> u64 {
    if t.is_nan() {
        return 0;
    }
    (t.clamp(0.0, 1.0) * CLEAR_ONE as f64).round() as u64
}

/// A hash in [0, 2³²) of a ray (its canonical origin, direction and interval, as `f32`
/// bits) and an input triangle: the sample keys' SplitMix64 mix
/// ([`crate::sampling::mix64`]) over the words in turn. The same ray and triangle always
/// give the same value; different rays, unrelated values.
#[inline]
fn ray_hash(ray: &WatertightRay, triangle: u32) -> u64 {
    let o = ray.origin.to_array().map(f32::to_bits);
    let d = ray.dir.to_array().map(f32::to_bits);
    let words = [
        u64::from(o[0]) | u64::from(o[1]) << 32,
        u64::from(o[2]) | u64::from(d[0]) << 32,
        u64::from(d[1]) | u64::from(d[2]) << 32,
        u64::from(ray.t_hi.to_bits()) | u64::from(triangle) << 32,
    ];
    let h = words.iter().fold(0, |h, &w| crate::sampling::mix64(h ^ w));
    h >> 32
}

#[cfg(test)]
mod tests;
