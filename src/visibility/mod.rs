//! Ray queries against the scene's triangles: `occluded(p, q)` for the open segment between two
//! surface points (the visibility term of the form factors) and `closest_hit` for a ray. This
//! module owns the BVH (an obvhs compressed wide BVH8), the watertight ray–triangle test and the
//! numerical conventions that make the answers independent of the scene's units. It does not
//! know about patches, materials or sampling: callers pass points and triangle indices.
//!
//! # Canonical frame
//! obvhs works in `f32` and clamps the entry distance of every box test to a fixed `1e-4`. To make
//! answers independent of the scene's scale and position, [`Visibility::build`] maps the scene
//! into a canonical frame, `canonical = (scene − centre) · scale`, where `centre` is the centre of
//! the triangles' bounding box and `scale = 1024 / largest extent`, and the canonical
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
//! - The BVH is built over triangle boxes padded by `BOX_PAD` canonical units. obvhs's
//!   quantised box test is not conservative (a ray grazing a box face can miss the box by one
//!   rounding), which would undo the watertight triangle test for rays along box boundaries
//!   (e.g. through the edges of an axis-aligned grid). The padding is far larger than the `f32`
//!   rounding of the box test and far smaller than any triangle that matters.
//! - Ray origins are moved back along the ray by `ORIGIN_SHIFT` (in the ray's parameter), so
//!   obvhs's fixed `t ≥ 1e-4` box clamp lies before the start of every query interval.
//!
//! # Twins: the two sides of one surface
//! A triangle and its reverse over the same three corners (bitwise the same canonical
//! coordinates, opposite winding) are *twins*: the front and the back of one two-sided surface
//! (what `--two-sided` makes of every face, and what a two-sided bake writes). [`Visibility::build`]
//! pairs them itself, so callers need no extra input, and traces each pair as one triangle:
//! - [`Visibility::occluded`] ignores the twins of the triangles in `ignore` as well (a point on
//!   one side lies on the other side too);
//! - [`Visibility::closest_hit`] ignores the twin of `ignore` and reports, of a pair, the
//!   triangle whose front faces the ray (so a caller that checks `normal · dir < 0` sees a front
//!   face), with barycentrics in that triangle's own vertex order.
//!
//! Pairing is deterministic: in input order, each triangle pairs with the earliest unpaired
//! triangle over the same corners with the opposite winding. A third copy (a duplicate face
//! with the same winding as one of a pair) stays a separate triangle, as any coincident face does.

use std::collections::HashMap;
use std::fmt;
use std::time::Duration;

use glam::{DVec3, Mat3A, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray, RayHit};
use obvhs::BvhBuildParams;

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

/// Distance, in units of the ray's direction vector, by which ray origins are moved back along
/// the ray. Must exceed obvhs's box-test clamp `t ≥ 1e-4` with margin.
const ORIGIN_SHIFT: f64 = 1.0 / 1024.0;

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
/// the canonical-frame, non-degenerate triangle `ids[i]` of the input, in the BVH's primitive
/// order (`tris[i]` is the primitive the traversal reports as id `i`). A twin pair (see the
/// module documentation) is one primitive: `ids[i]` is the earlier of the two input indices,
/// `twins[i]` the later (or [`NONE`]), and corner `k` of the twin is corner
/// `twin_corners[i][k]` of `tris[i]`. `twin_of` is empty when there are no twins, else it maps
/// every input index to its twin or [`NONE`]. `bvh` is only traversed when `tris` is non-empty.
#[derive(Clone)]
pub struct Visibility {
    /// Compressed wide BVH8 over the padded boxes of `tris`.
    bvh: CwBvh,
    /// Triangles in canonical coordinates, reordered by `bvh.primitive_indices`.
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
    /// Boxes (scene coordinates, padded) of the connected groups of triangles, when there are
    /// at most [`MAX_CLUSTERS`]: a segment that meets none of them meets no triangle, and
    /// [`Visibility::occluded`] answers without tracing. Empty: no such test.
    clusters: Vec<[DVec3; 2]>,
}

/// Most connected groups of triangles whose boxes [`Visibility::occluded`] tests before
/// tracing (a room's few pieces of furniture, the light); more, and every segment is traced.
const MAX_CLUSTERS: usize = 32;

impl fmt::Debug for Visibility {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Visibility")
            .field("len", &self.len)
            .field("traced_triangles", &self.tris.len())
            .field("twin_pairs", &self.twin_pairs())
            .field("bvh_nodes", &self.bvh.nodes.len())
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
        assert!(
            triangles.len() < NONE as usize,
            "at most u32::MAX - 1 triangles are supported, got {}",
            triangles.len()
        );
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

        let mut tris = Vec::with_capacity(triangles.len());
        let mut ids = Vec::with_capacity(triangles.len());
        for (i, t) in triangles.iter().enumerate() {
            let c = t.map(|v| vis.to_canonical(v).as_vec3a());
            let area2 =
                (c[1].as_dvec3() - c[0].as_dvec3()).cross(c[2].as_dvec3() - c[0].as_dvec3());
            if finite(t) && c.iter().all(|v| v.is_finite()) && area2 != DVec3::ZERO {
                tris.push(c);
                ids.push(i as u32);
            }
        }
        vis.set_triangles(tris, ids);
        vis
    }

    /// A `Visibility` of `len` input triangles in the given frame with nothing traced yet
    /// ([`Visibility::set_triangles`] fills it).
    fn untraced(len: usize, centre: DVec3, scale: f64, min_distance: f64) -> Visibility {
        Visibility {
            bvh: CwBvh::default(),
            tris: Vec::new(),
            ids: Vec::new(),
            twins: Vec::new(),
            twin_corners: Vec::new(),
            twin_of: Vec::new(),
            len,
            centre,
            scale,
            min_distance,
            clusters: Vec::new(),
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
        // `build_cwbvh` is what `build_cwbvh_from_tris` runs when `pre_split` is off (as in
        // `fast_build`), with our padded boxes in place of the exact triangle boxes.
        let bvh = build_cwbvh(
            &boxes,
            BvhBuildParams::fast_build(),
            &mut Duration::default(),
        );
        // Reorder once so the primitive id a traversal reports indexes `tris` directly.
        let order = &bvh.primitive_indices;
        self.tris = permute(order, &tris);
        self.ids = permute(order, &ids);
        self.twins = permute(order, &twins);
        self.twin_corners = permute(order, &twin_corners);
        debug_assert_eq!(
            self.tris.len(),
            tris.len(),
            "no spatial splits: a permutation"
        );
        self.bvh = bvh;
        self.clusters = self.cluster_boxes();
    }

    /// Boxes of the connected groups (shared corners) of the traced triangles, in scene
    /// coordinates, padded by the BVH's box padding plus 1e-6 of the extent; empty when there
    /// are more than [`MAX_CLUSTERS`] groups.
    fn cluster_boxes(&self) -> Vec<[DVec3; 2]> {
        let mut parent: Vec<usize> = (0..self.tris.len()).collect();
        fn find(parent: &mut [usize], mut a: usize) -> usize {
            while parent[a] != a {
                parent[a] = parent[parent[a]];
                a = parent[a];
            }
            a
        }
        let mut first_at: std::collections::HashMap<[u32; 3], usize> = Default::default();
        for (k, tri) in self.tris.iter().enumerate() {
            for corner in tri {
                let key = corner.to_array().map(f32::to_bits);
                let other = *first_at.entry(key).or_insert(k);
                let (a, b) = (find(&mut parent, k), find(&mut parent, other));
                parent[a.max(b)] = a.min(b);
            }
        }
        let mut boxes: std::collections::BTreeMap<usize, [Vec3A; 2]> = Default::default();
        for (k, tri) in self.tris.iter().enumerate() {
            let root = find(&mut parent, k);
            let b = boxes
                .entry(root)
                .or_insert([Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)]);
            for c in tri {
                b[0] = b[0].min(*c);
                b[1] = b[1].max(*c);
            }
            if boxes.len() > MAX_CLUSTERS {
                return Vec::new();
            }
        }
        let pad = BOX_PAD as f64 + CANONICAL_EXTENT * 1e-6;
        boxes
            .values()
            .map(|[lo, hi]| {
                [
                    (lo.as_dvec3() - pad) / self.scale + self.centre,
                    (hi.as_dvec3() + pad) / self.scale + self.centre,
                ]
            })
            .collect()
    }

    /// True when the segment p–q meets the box of some group of triangles (or there is no
    /// such test): only then can a triangle block it.
    fn may_block(&self, p: DVec3, q: DVec3) -> bool {
        if self.clusters.is_empty() {
            return true;
        }
        let d = q - p;
        self.clusters.iter().any(|[lo, hi]| {
            // Slab test of the segment x(t) = p + t·d, t ∈ [0, 1], against [lo, hi].
            let (mut t0, mut t1) = (0.0f64, 1.0f64);
            for k in 0..3 {
                if d[k] == 0.0 {
                    if p[k] < lo[k] || p[k] > hi[k] {
                        return false;
                    }
                    continue;
                }
                let inv = 1.0 / d[k];
                let (a, b) = ((lo[k] - p[k]) * inv, (hi[k] - p[k]) * inv);
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
                if t0 > t1 {
                    return false;
                }
            }
            true
        })
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
        if !self.may_block(p.scene, q.scene) {
            return false;
        }
        let Some(ray) = self.canonical_segment_ray(p, q) else {
            return false;
        };
        let obvhs_ray = ray.obvhs_ray();
        !self.bvh.ray_traverse_miss(obvhs_ray, |_, i| {
            if self.ignored(i, ignore) {
                return f32::INFINITY;
            }
            // Any hit in [t_lo, t_hi] blocks; obvhs counts a hit only if the returned t is
            // below the ray's t_max, so report t_lo rather than a t that may equal t_hi.
            match ray.intersect(&self.tris[i], ray.t_lo, ray.t_hi) {
                Some(_) => ray.t_lo,
                None => f32::INFINITY,
            }
        })
    }

    /// Oracle for tests: [`Visibility::occluded`] answered by testing every triangle with the
    /// same ray and the same watertight test, without the BVH.
    pub fn occluded_brute_force(&self, p: DVec3, q: DVec3, ignore: [u32; 2]) -> bool {
        let Some(ray) = self.segment_ray(p, q) else {
            return false;
        };
        (0..self.tris.len()).any(|i| {
            !self.ignored(i, ignore) && ray.intersect(&self.tris[i], ray.t_lo, ray.t_hi).is_some()
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
    /// rays from corner patches in hemisphere shooting). Both sides of triangles are hit. Ties in `t` go to the lowest
    /// triangle index. Returns `None` for a zero or non-finite `dir`.
    pub fn closest_hit(&self, origin: DVec3, dir: DVec3, t_max: f64, ignore: u32) -> Option<Hit> {
        let (ray, m) = self.direction_ray(origin, dir, t_max)?;
        let mut best: Option<(f32, u32, f32, f32)> = None;
        let mut hit = RayHit::none();
        self.bvh.ray_traverse(ray.obvhs_ray(), &mut hit, |_, i| {
            if self.ignored(i, [ignore, ignore]) {
                return f32::INFINITY;
            }
            let t_hi = best.map_or(ray.t_hi, |b| b.0);
            match ray.intersect(&self.tris[i], ray.t_lo, t_hi) {
                Some((t, u, v)) => {
                    let (id, u, v) = self.facing(i, ray.dir, u, v);
                    if best.is_none_or(|b| t < b.0 || (t == b.0 && id < b.1)) {
                        best = Some((t, id, u, v));
                    }
                    t
                }
                None => f32::INFINITY,
            }
        });
        best.map(|b| ray.hit(b, m))
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
            if self.ignored(i, [ignore, ignore]) {
                continue;
            }
            let t_hi = best.map_or(ray.t_hi, |b| b.0);
            if let Some((t, u, v)) = ray.intersect(tri, ray.t_lo, t_hi) {
                let (id, u, v) = self.facing(i, ray.dir, u, v);
                if best.is_none_or(|b| t < b.0 || (t == b.0 && id < b.1)) {
                    best = Some((t, id, u, v));
                }
            }
        }
        best.map(|b| ray.hit(b, m))
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
        let (pc, qc) = (p.canonical, q.canonical);
        let d = qc - pc;
        let length = d.length();
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

/// Twin pairing of canonical triangles (see the module documentation): for each triangle, its
/// twin's position in `tris` and which of its own corners each corner of the *later* of the two
/// is (`corners[k]` = the earlier triangle's corner that is the later one's corner `k`), or
/// `None`. Symmetric: if `k` pairs with `j`, `j` pairs with `k` (with the same `corners`).
fn pair_twins(tris: &[[Vec3A; 3]]) -> Vec<Option<(usize, [u8; 3])>> {
    // Corner bits with −0.0 made +0.0, so the two sides of one surface always match.
    let bits = |p: Vec3A| (p + Vec3A::ZERO).to_array().map(f32::to_bits);
    // (sorted corners, parity of the sort) of each triangle: twins have the same corners and
    // opposite parity (a reversed triangle is an odd permutation of the original's corners).
    let keyed: Vec<([[u32; 3]; 3], bool)> = tris
        .iter()
        .map(|t| {
            let mut c = t.map(bits);
            let mut odd = false;
            for (a, b) in [(0, 1), (1, 2), (0, 1)] {
                if c[a] > c[b] {
                    c.swap(a, b);
                    odd = !odd;
                }
            }
            (c, odd)
        })
        .collect();
    // Corner sets that occur more than once, each with its triangles in input order. One hash
    // insert per triangle; map iteration order is never used, so nothing depends on hashing.
    let mut first: HashMap<[[u32; 3]; 3], usize> = HashMap::with_capacity(tris.len());
    let mut group_of_first: HashMap<usize, usize> = HashMap::new();
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (k, (corners, _)) in keyed.iter().enumerate() {
        let f = *first.entry(*corners).or_insert(k);
        if f != k {
            let g = *group_of_first.entry(f).or_insert_with(|| {
                groups.push(vec![f]);
                groups.len() - 1
            });
            groups[g].push(k);
        }
    }
    let mut pairs = vec![None; tris.len()];
    for group in &groups {
        // Each member pairs with the earliest unpaired member of the opposite winding.
        let mut waiting: [Vec<usize>; 2] = [Vec::new(), Vec::new()];
        for &k in group {
            let odd = keyed[k].1 as usize;
            if waiting[1 - odd].is_empty() {
                waiting[odd].push(k);
                continue;
            }
            let j = waiting[1 - odd].remove(0);
            let earlier = tris[j].map(bits);
            let later = tris[k].map(bits);
            let map = later.map(|c| earlier.iter().position(|&e| e == c).unwrap_or(0) as u8);
            pairs[j] = Some((k, map));
            pairs[k] = Some((j, map));
        }
    }
    pairs
}

/// `v` in the order `order` (element k of the result is `v[order[k]]`).
fn permute<T: Copy>(order: &[u32], v: &[T]) -> Vec<T> {
    order.iter().map(|&k| v[k as usize]).collect()
}

/// Canonical coordinates are multiples of this (2⁻²⁰ canonical units): far below `f32`
/// resolution at the frame's size (≈ 6e-5 at 1024), far above f64 rounding (≈ 1e-13).
const CANONICAL_GRID: f64 = 1.0 / (1u64 << 20) as f64;

/// Unit ray directions are snapped to multiples of 2⁻⁴⁰.
const DIRECTION_GRID: f64 = 1.0 / (1u64 << 40) as f64;

/// `x` rounded to the nearest multiple of `grid` in each coordinate.
fn snap(x: DVec3, grid: f64) -> DVec3 {
    (x / grid).round() * grid
}

/// A ray prepared once for the watertight test of Woop, Benthin & Wald (JCGT 2013), in the
/// canonical frame: `x(t) = origin + t·dir` with the origin moved back by `ORIGIN_SHIFT`
/// (so internal parameters are `t + ORIGIN_SHIFT`).
#[derive(Clone, Copy, Debug)]
struct WatertightRay {
    /// Shifted origin, canonical `f32`.
    origin: Vec3A,
    /// Direction, canonical `f32`.
    dir: Vec3A,
    /// Permutation and shear to ray space: for `a = vertex − origin`, `shear · a =
    /// (a[kx] − Sx·a[kz], a[ky] − Sy·a[kz], Sz·a[kz])`.
    shear: Mat3A,
    /// Query interval in internal (shifted) parameters, inclusive.
    t_lo: f32,
    t_hi: f32,
}

impl WatertightRay {
    /// Ray from `origin` along `dir` (canonical, `f64`), counting hits with
    /// `t ∈ [t_lo, t_hi]`. `None` if it cannot be represented in `f32`.
    fn new(origin: DVec3, dir: DVec3, t_lo: f64, t_hi: f64) -> Option<WatertightRay> {
        // `+ 0.0` turns −0.0 components into +0.0: obvhs picks a box's near plane by
        // `dir < 0.0` (false for −0.0) but inverts −0.0 to −1/ε, so a direction such as a floor's
        // normal (0, 1, −0) would miss every box it should enter.
        let dir32 = dir.as_vec3a() + Vec3A::ZERO;
        let origin32 = (origin - ORIGIN_SHIFT * dir).as_vec3a();
        if !(origin32.is_finite() && dir32.is_finite()) || dir32 == Vec3A::ZERO {
            return None;
        }
        // Step 1 (paper §3): kz is the dimension where the direction is largest in magnitude;
        // kx, ky follow cyclically and swap when dir[kz] < 0 to keep the triangles' winding.
        let kz = dir32.abs().max_position();
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if dir32[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        // Step 2: shear constants that map the ray onto the +z axis of ray space.
        let sz = 1.0 / dir32[kz];
        let sx = dir32[kx] * sz;
        let sy = dir32[ky] * sz;
        let mut cols = [Vec3A::ZERO; 3];
        cols[kx] = Vec3A::X;
        cols[ky] = Vec3A::Y;
        cols[kz] = Vec3A::new(-sx, -sy, sz);
        Some(WatertightRay {
            origin: origin32,
            dir: dir32,
            shear: Mat3A::from_cols(cols[0], cols[1], cols[2]),
            t_lo: (t_lo + ORIGIN_SHIFT) as f32,
            t_hi: (t_hi + ORIGIN_SHIFT) as f32,
        })
    }

    /// The obvhs ray for traversal; its `tmax` bounds the box tests.
    fn obvhs_ray(&self) -> Ray {
        Ray::new(self.origin, self.dir, self.t_lo, self.t_hi)
    }

    /// Watertight intersection with `tri` for internal parameters in `[t_lo, t_hi]`; returns
    /// `(t, u, v)` with `u`, `v` the barycentric weights of `tri[1]`, `tri[2]`. Both sides hit.
    ///
    /// Watertightness rests on each vertex being transformed to ray space independently of the
    /// triangle (so a shared edge gives exactly opposite edge functions in its two triangles)
    /// and on edge functions that are exactly 0 being recomputed in `f64`, where the products of
    /// `f32` values are exact and the sign of the difference is therefore exact.
    #[inline(always)]
    fn intersect(&self, tri: &[Vec3A; 3], t_lo: f32, t_hi: f32) -> Option<(f32, f32, f32)> {
        // Step 3: vertices relative to the origin, permuted and sheared to ray space.
        let a = self.shear * (tri[0] - self.origin);
        let b = self.shear * (tri[1] - self.origin);
        let c = self.shear * (tri[2] - self.origin);
        // Step 4: scaled barycentric coordinates (2D edge functions at the ray's (0, 0)).
        let mut e0 = c.x * b.y - c.y * b.x;
        let mut e1 = a.x * c.y - a.y * c.x;
        let mut e2 = b.x * a.y - b.y * a.x;
        // Step 5: fall back to f64 on the edge (exactly 0) for a consistent decision.
        if e0 == 0.0 || e1 == 0.0 || e2 == 0.0 {
            let edge = |p: f32, q: f32, r: f32, s: f32| {
                (f64::from(p) * f64::from(q) - f64::from(r) * f64::from(s)) as f32
            };
            e0 = edge(c.x, b.y, c.y, b.x);
            e1 = edge(a.x, c.y, a.y, c.x);
            e2 = edge(b.x, a.y, b.y, a.x);
        }
        // Step 6: inside if all edge functions share a sign (0 counts as either: the tie rule
        // that makes both triangles of a shared edge report the hit). No backface culling.
        if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
            return None;
        }
        let det = e0 + e1 + e2;
        if det == 0.0 {
            return None;
        }
        // Step 7: scaled hit distance, compared with the interval without dividing.
        let t_scaled = e0 * a.z + e1 * b.z + e2 * c.z;
        let sign = det.to_bits() & 0x8000_0000;
        let t_signed = f32::from_bits(t_scaled.to_bits() ^ sign);
        let det_abs = det.abs();
        if t_signed < t_lo * det_abs || t_signed > t_hi * det_abs {
            return None;
        }
        let rcp = 1.0 / det;
        Some((t_scaled * rcp, e1 * rcp, e2 * rcp))
    }

    /// Converts an internal `(t, id, u, v)` to a [`Hit`] for a direction scaled by `m`.
    fn hit(&self, (t, triangle, u, v): (f32, u32, f32, f32), m: f64) -> Hit {
        Hit {
            triangle,
            t: (f64::from(t) - ORIGIN_SHIFT) / m,
            u: f64::from(u),
            v: f64::from(v),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::dvec3;
    use rayon::prelude::*;
    use std::time::Instant;

    /// SplitMix64 (Steele, Lea & Flood 2014): small, seedable, good enough for test inputs.
    struct Rng(u64);

    impl Rng {
        fn next_u64(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }
        /// Uniform in [0, 1).
        fn f64(&mut self) -> f64 {
            (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.f64()
        }
        fn vec(&mut self, lo: f64, hi: f64) -> DVec3 {
            dvec3(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
        }
        fn index(&mut self, n: usize) -> usize {
            (self.next_u64() % n as u64) as usize
        }
        /// Uniform point on a triangle.
        fn on_triangle(&mut self, t: &[DVec3; 3]) -> DVec3 {
            let (mut a, mut b) = (self.f64(), self.f64());
            if a + b > 1.0 {
                (a, b) = (1.0 - a, 1.0 - b);
            }
            t[0] + a * (t[1] - t[0]) + b * (t[2] - t[0])
        }
        /// Uniform direction.
        fn direction(&mut self) -> DVec3 {
            loop {
                let d = self.vec(-1.0, 1.0);
                let l = d.length();
                if l > 0.1 && l <= 1.0 {
                    return d / l;
                }
            }
        }
    }

    /// Closed axis-aligned box `[lo, hi]`, each face an `n × n` grid of squares split into two
    /// triangles; vertices are shared exactly between faces and triangles. Outward winding.
    fn grid_box(lo: DVec3, hi: DVec3, n: usize) -> Vec<[DVec3; 3]> {
        let mut tris = Vec::new();
        for axis in 0..3 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for side in [false, true] {
                let point = |i: usize, j: usize| {
                    let mut p = DVec3::ZERO;
                    p[axis] = if side { hi[axis] } else { lo[axis] };
                    p[u] = lo[u] + (hi[u] - lo[u]) * i as f64 / n as f64;
                    p[v] = lo[v] + (hi[v] - lo[v]) * j as f64 / n as f64;
                    p
                };
                for i in 0..n {
                    for j in 0..n {
                        let (a, b, c, d) = (
                            point(i, j),
                            point(i + 1, j),
                            point(i + 1, j + 1),
                            point(i, j + 1),
                        );
                        // Alternate the diagonal so vertices have 4 or 8 incident triangles.
                        let quads = if (i + j) % 2 == 0 {
                            [[a, b, c], [a, c, d]]
                        } else {
                            [[a, b, d], [b, c, d]]
                        };
                        for t in quads {
                            tris.push(if side { t } else { [t[0], t[2], t[1]] });
                        }
                    }
                }
            }
        }
        tris
    }

    /// Random triangles of size ~1–3 in [0, 10]³ plus a closed 12-triangle box.
    fn random_scene(rng: &mut Rng, n: usize) -> Vec<[DVec3; 3]> {
        let mut tris: Vec<[DVec3; 3]> = (0..n)
            .map(|_| {
                let c = rng.vec(0.0, 10.0);
                [
                    c + rng.vec(-1.5, 1.5),
                    c + rng.vec(-1.5, 1.5),
                    c + rng.vec(-1.5, 1.5),
                ]
            })
            .collect();
        tris.extend(grid_box(dvec3(3.0, 3.5, 4.0), dvec3(5.0, 6.0, 5.5), 1));
        tris
    }

    /// Segments of three kinds: free endpoints, surface to surface (ignoring both triangles),
    /// surface to free point (ignoring the start triangle).
    fn random_segments(
        rng: &mut Rng,
        tris: &[[DVec3; 3]],
        n: usize,
    ) -> Vec<(DVec3, DVec3, [u32; 2])> {
        (0..n)
            .map(|k| match k % 3 {
                0 => (rng.vec(-1.0, 11.0), rng.vec(-1.0, 11.0), [NONE, NONE]),
                1 => {
                    let (i, j) = (rng.index(tris.len()), rng.index(tris.len()));
                    let (p, q) = (rng.on_triangle(&tris[i]), rng.on_triangle(&tris[j]));
                    (p, q, [i as u32, j as u32])
                }
                _ => {
                    let i = rng.index(tris.len());
                    (
                        rng.on_triangle(&tris[i]),
                        rng.vec(-1.0, 11.0),
                        [i as u32, NONE],
                    )
                }
            })
            .collect()
    }

    #[test]
    fn bvh_matches_brute_force() {
        let mut rng = Rng(1);
        let tris = random_scene(&mut rng, 300);
        let vis = Visibility::build(&tris);
        assert_eq!(vis.len(), 312);
        let segments = random_segments(&mut rng, &tris, 6000);
        let mut blocked = 0;
        for (k, &(p, q, ignore)) in segments.iter().enumerate() {
            let fast = vis.occluded(p, q, ignore);
            assert_eq!(
                fast,
                vis.occluded_brute_force(p, q, ignore),
                "segment {k}: {p} -> {q}, ignore {ignore:?}"
            );
            blocked += fast as usize;
        }
        // Both answers must be common, or the comparison proves little.
        assert!(
            blocked > 1000 && blocked < 5000,
            "{blocked} of 6000 blocked"
        );

        let mut hits = 0;
        for k in 0..3000 {
            let origin = rng.vec(-1.0, 11.0);
            let dir = rng.direction() * rng.range(0.1, 10.0);
            let t_max = if k % 2 == 0 {
                f64::INFINITY
            } else {
                rng.range(0.1, 3.0)
            };
            let ignore = if k % 3 == 0 {
                NONE
            } else {
                rng.index(tris.len()) as u32
            };
            let fast = vis.closest_hit(origin, dir, t_max, ignore);
            let slow = vis.closest_hit_brute_force(origin, dir, t_max, ignore);
            assert_eq!(fast, slow, "ray {k}: {origin} + t {dir}, t_max {t_max}");
            if let Some(h) = fast {
                hits += 1;
                assert!(h.t > 0.0 && h.t <= t_max && h.triangle != ignore);
                // The reported (t, u, v) describe the same point.
                let t = &tris[h.triangle as usize];
                let on_tri = (1.0 - h.u - h.v) * t[0] + h.u * t[1] + h.v * t[2];
                let on_ray = origin + h.t * dir;
                assert!((on_tri - on_ray).length() < 1e-4, "{on_tri} vs {on_ray}");
            }
        }
        assert!(hits > 500 && hits < 2900, "{hits} of 3000 rays hit");
    }

    /// Segments from interior points through each target to beyond it (scaled by 2 from the
    /// interior point), all of which must be blocked by the closed `tris`.
    fn assert_all_blocked(vis: &Visibility, inside: &[DVec3], targets: &[DVec3]) {
        let mut leaks = Vec::new();
        for &p in inside {
            for &x in targets {
                let q = p + 2.0 * (x - p);
                if !vis.occluded(p, q, [NONE, NONE]) {
                    leaks.push((p, x));
                }
            }
        }
        assert!(
            leaks.is_empty(),
            "{} of {} segments leaked, first: {:?}",
            leaks.len(),
            inside.len() * targets.len(),
            leaks.first()
        );
    }

    /// Vertices, edge midpoints and face centres of a triangle list, deduplicated.
    fn edge_and_vertex_targets(tris: &[[DVec3; 3]]) -> Vec<DVec3> {
        let mut v: Vec<DVec3> = tris
            .iter()
            .flat_map(|t| {
                [
                    t[0],
                    t[1],
                    t[2],
                    0.5 * (t[0] + t[1]),
                    0.5 * (t[1] + t[2]),
                    0.5 * (t[2] + t[0]),
                ]
            })
            .collect();
        v.sort_by(|a, b| a.to_array().partial_cmp(&b.to_array()).unwrap());
        v.dedup();
        v
    }

    #[test]
    fn closed_meshes_are_watertight() {
        // Dyadic coordinates: the canonical frame (scale 512) and the rays are exact, so the rays
        // pass exactly through the shared vertices and edges and the f64 fallback is exercised.
        let inside = [
            dvec3(0.0, 0.0, 0.0),
            dvec3(0.25, -0.125, 0.375),
            dvec3(-0.5, 0.5, -0.25),
            dvec3(0.75, 0.0, -0.5),
        ];
        for n in [1, 16] {
            let tris = grid_box(DVec3::splat(-1.0), DVec3::splat(1.0), n);
            let vis = Visibility::build(&tris);
            let targets = edge_and_vertex_targets(&tris);
            assert!(targets.len() >= if n == 1 { 26 } else { 3000 });
            assert_all_blocked(&vis, &inside, &targets);
            // Non-dyadic interior points and random directions.
            let mut rng = Rng(2);
            let random_inside: Vec<DVec3> = (0..64).map(|_| rng.vec(-0.99, 0.99)).collect();
            let random_outside: Vec<DVec3> = (0..64).map(|_| 3.0 * rng.direction()).collect();
            assert_all_blocked(&vis, &random_inside, &random_outside);
            // The test can fail: segments inside the box, or outside and clear of it, are free.
            assert!(!vis.occluded(inside[0], inside[1], [NONE, NONE]));
            assert!(!vis.occluded(dvec3(2.0, 2.0, 2.0), dvec3(2.0, -2.0, 2.0), [NONE, NONE]));
        }

        // The same grid with every vertex displaced (shared vertices identically): edges in
        // general position, coordinates not exactly representable.
        let mut rng = Rng(3);
        let mut jitter = std::collections::HashMap::new();
        let tris: Vec<[DVec3; 3]> = grid_box(DVec3::splat(-1.0), DVec3::splat(1.0), 16)
            .iter()
            .map(|t| {
                t.map(|v| {
                    let key = v.to_array().map(f64::to_bits);
                    v + *jitter.entry(key).or_insert_with(|| rng.vec(-0.03, 0.03))
                })
            })
            .collect();
        let vis = Visibility::build(&tris);
        let targets = edge_and_vertex_targets(&tris);
        assert_all_blocked(&vis, &inside, &targets);
        let inside: Vec<DVec3> = (0..50).map(|_| rng.vec(-0.9, 0.9)).collect();
        let outside: Vec<DVec3> = (0..100).map(|_| 3.0 * rng.direction()).collect();
        assert_all_blocked(&vis, &inside, &outside);
    }

    #[test]
    fn open_segment_between_touching_and_facing_surfaces() {
        // Floor z = 0 and wall x = 0 over [0, 1]², 4 × 4 grids, meeting along the y axis.
        let floor_and_wall: Vec<[DVec3; 3]> = grid_box(DVec3::ZERO, DVec3::ONE, 4)
            .into_iter()
            .filter(|t| t.iter().all(|v| v.z == 0.0) || t.iter().all(|v| v.x == 0.0))
            .collect();
        assert_eq!(floor_and_wall.len(), 64);
        let vis = Visibility::build(&floor_and_wall);
        let find = |p: DVec3| {
            let i = floor_and_wall
                .iter()
                .position(|t| {
                    let n = (t[1] - t[0]).cross(t[2] - t[0]);
                    let inside =
                        (0..3).all(|k| (t[(k + 1) % 3] - t[k]).cross(p - t[k]).dot(n) > 0.0);
                    inside && n.dot(p - t[0]).abs() < 1e-12
                })
                .expect("point on a triangle");
            i as u32
        };
        let mut rng = Rng(4);
        let mut checked = 0;
        for k in 0..500 {
            // Half of the pairs close to each other near the shared edge (the corner, where the
            // form-factor kernel is largest), half anywhere.
            let (p, q) = if k % 2 == 0 {
                let r = 0.02;
                let p = dvec3(rng.range(0.0, r), rng.range(r, 1.0 - r), 0.0);
                (p, dvec3(0.0, p.y + rng.range(-r, r), rng.range(0.0, r)))
            } else {
                (
                    dvec3(rng.f64(), rng.f64(), 0.0),
                    dvec3(0.0, rng.f64(), rng.f64()),
                )
            };
            let (i, j) = (find(p), find(q));
            assert!(!vis.occluded(p, q, [i, j]), "{p} -> {q}");
            // Without `ignore`, the endpoints' own triangles count too, which rounding can only
            // resolve away from grazing angles (see `MIN_DISTANCE_REL`).
            let d = (q - p).normalize();
            if d.z.abs() > 0.05 && d.x.abs() > 0.05 {
                assert!(
                    !vis.occluded(p, q, [NONE, NONE]),
                    "{p} -> {q} without ignore"
                );
                checked += 1;
            }
            assert!(vis.closest_hit(p, q - p, 1.0 - 1e-3, i).is_none());
        }
        assert!(
            checked > 250,
            "{checked} of 500 pairs checked without ignore"
        );

        // Facing squares at z = 0 and z = 2 with a blocker at z = 1.
        let square = |z: f64, lo: f64, hi: f64| {
            let (a, b) = (dvec3(lo, lo, z), dvec3(hi, lo, z));
            let (c, d) = (dvec3(hi, hi, z), dvec3(lo, hi, z));
            [[a, b, c], [a, c, d]]
        };
        let mut tris = Vec::new();
        tris.extend(square(0.0, 0.0, 1.0)); // 0, 1
        tris.extend(square(2.0, 0.0, 1.0)); // 2, 3
        tris.extend(square(1.0, -1.0, 2.0)); // 4, 5: the blocker
        let vis = Visibility::build(&tris);
        for _ in 0..200 {
            let (i, j) = (rng.index(2), 2 + rng.index(2));
            let (p, q) = (rng.on_triangle(&tris[i]), rng.on_triangle(&tris[j]));
            let (i, j) = (i as u32, j as u32);
            assert!(vis.occluded(p, q, [i, j]));
            assert!(vis.occluded(p, q, [NONE, NONE]));
            assert!(vis.occluded(p, q, [4, NONE]) || vis.occluded(p, q, [5, NONE]));
            assert!(!vis.occluded(p, q, [4, 5]), "blocker ignored");
            let hit = vis.closest_hit(p, q - p, 1.0, i).expect("blocker hit");
            assert!(hit.triangle == 4 || hit.triangle == 5);
            assert!((hit.t - 0.5).abs() < 1e-6, "t = {}", hit.t);
        }
    }

    #[test]
    fn answers_do_not_depend_on_scale_or_position() {
        let mut rng = Rng(5);
        let tris = random_scene(&mut rng, 200);
        let segments = random_segments(&mut rng, &tris, 3000);
        let rays: Vec<(DVec3, DVec3)> = (0..1000)
            .map(|_| (rng.vec(-1.0, 11.0), rng.direction()))
            .collect();
        let answers = |scale: f64, offset: DVec3| {
            let map = |x: DVec3| x * scale + offset;
            let vis = Visibility::build(&tris.iter().map(|t| t.map(map)).collect::<Vec<_>>());
            let occluded: Vec<bool> = segments
                .iter()
                .map(|&(p, q, ignore)| vis.occluded(map(p), map(q), ignore))
                .collect();
            let hits: Vec<Option<(u32, f64)>> = rays
                .iter()
                .map(|&(o, d)| vis.closest_hit(map(o), d, f64::INFINITY, NONE))
                .map(|h| h.map(|h| (h.triangle, h.t / scale)))
                .collect();
            (occluded, hits)
        };
        let (occluded, hits) = answers(1.0, DVec3::ZERO);
        let blocked = occluded.iter().filter(|&&b| b).count();
        assert!(blocked > 500 && blocked < 2500, "{blocked} of 3000 blocked");
        for (scale, offset) in [
            (1e-3, DVec3::ZERO),
            (1e3, DVec3::ZERO),
            (1e-3, DVec3::splat(1e4)),
            (1e3, DVec3::splat(1e4)),
            (1.0, dvec3(1e4, -1e4, 1e4)),
        ] {
            let (o, h) = answers(scale, offset);
            assert_eq!(o, occluded, "scale {scale}, offset {offset}");
            for (k, (a, b)) in hits.iter().zip(&h).enumerate() {
                match (a, b) {
                    (None, None) => {}
                    (Some(a), Some(b)) => {
                        assert_eq!(a.0, b.0, "ray {k}, scale {scale}, offset {offset}");
                        assert!((a.1 - b.1).abs() <= 1e-5 * a.1.max(1.0), "{a:?} vs {b:?}");
                    }
                    _ => panic!("ray {k}, scale {scale}, offset {offset}: {a:?} vs {b:?}"),
                }
            }
        }
    }

    #[test]
    fn empty_and_degenerate_inputs() {
        let vis = Visibility::build(&[]);
        assert!(vis.is_empty());
        assert_eq!(vis.len(), 0);
        let (p, q) = (DVec3::ZERO, DVec3::ONE);
        assert!(!vis.occluded(p, q, [NONE, NONE]));
        assert!(!vis.occluded_brute_force(p, q, [NONE, NONE]));
        assert_eq!(vis.closest_hit(p, q, f64::INFINITY, NONE), None);

        let point = [DVec3::ONE; 3];
        let segment = [DVec3::ZERO, DVec3::ONE, DVec3::splat(2.0)];
        let nan = [DVec3::ZERO, DVec3::X, DVec3::NAN];
        let real = [
            dvec3(-1.0, -1.0, 0.5),
            dvec3(3.0, -1.0, 0.5),
            dvec3(-1.0, 3.0, 0.5),
        ];

        // Only degenerate triangles: never occludes, never hits.
        let vis = Visibility::build(&[point, segment, nan]);
        assert_eq!(vis.len(), 3);
        assert!(!vis.is_empty());
        assert!(!vis.occluded(dvec3(1.0, 1.0, 0.0), dvec3(1.0, 1.0, 2.0), [NONE, NONE]));
        assert!(!vis.occluded(DVec3::ZERO, DVec3::splat(2.0), [NONE, NONE]));
        assert_eq!(vis.closest_hit(DVec3::ZERO, DVec3::ONE, 10.0, NONE), None);

        // Degenerate triangles around a real one: ids still refer to the input list.
        let vis = Visibility::build(&[point, segment, real, nan]);
        assert_eq!(vis.len(), 4);
        let (p, q) = (dvec3(0.5, 0.5, 0.0), dvec3(0.5, 0.5, 1.0));
        assert!(vis.occluded(p, q, [NONE, NONE]));
        assert!(vis.occluded(p, q, [0, 1]));
        assert!(!vis.occluded(p, q, [2, NONE]));
        assert!(!vis.occluded(p, p, [NONE, NONE]), "degenerate segment");
        let hit = vis.closest_hit(p, q - p, f64::INFINITY, NONE).expect("hit");
        assert_eq!(hit.triangle, 2);
        assert!((hit.t - 0.5).abs() < 1e-6);
        assert!(
            (hit.u - 0.375).abs() < 1e-6 && (hit.v - 0.375).abs() < 1e-6,
            "{hit:?}"
        );
        assert_eq!(
            vis.closest_hit(p, DVec3::ZERO, 1.0, NONE),
            None,
            "zero direction"
        );
        assert_eq!(vis.closest_hit(p, -DVec3::Z, f64::INFINITY, NONE), None);
    }

    /// `tris` followed by the reverse of each (corners rotated differently per triangle, so every
    /// corner correspondence occurs), then one same-facing duplicate of triangle 0.
    fn with_twins(tris: &[[DVec3; 3]]) -> Vec<[DVec3; 3]> {
        let mut all = tris.to_vec();
        for (k, &[a, b, c]) in tris.iter().enumerate() {
            all.push([[a, c, b], [c, b, a], [b, a, c]][k % 3]);
        }
        all.push(tris[0]);
        all
    }

    #[test]
    fn twins_are_paired_deterministically() {
        let mut rng = Rng(7);
        let tris = random_scene(&mut rng, 100);
        let n = tris.len() as u32;
        let all = with_twins(&tris);
        let vis = Visibility::build(&all);
        assert_eq!(vis.twin_pairs(), tris.len());
        for i in 0..n {
            assert_eq!(vis.twin(i), i + n, "{i}");
            assert_eq!(vis.twin(i + n), i, "{i}");
        }
        // The third copy (same winding as triangle 0) stays a separate triangle.
        assert_eq!(vis.twin(2 * n), NONE);
        assert_eq!(vis.twin(u32::MAX - 1), NONE);
        // One-sided scenes have no twins; a coincident same-facing pair is not one.
        let one = Visibility::build(&tris);
        assert_eq!((one.twin_pairs(), one.twin(0)), (0, NONE));
        assert_eq!(Visibility::build(&[tris[0], tris[0]]).twin_pairs(), 0);
        // −0.0 and +0.0 are the same corner.
        let t = [
            dvec3(-0.0, 0.0, 0.0),
            dvec3(1.0, 0.0, 0.0),
            dvec3(0.0, 1.0, 0.0),
        ];
        let r = [
            dvec3(0.0, 0.0, 0.0),
            dvec3(0.0, 1.0, 0.0),
            dvec3(1.0, 0.0, 0.0),
        ];
        assert_eq!(Visibility::build(&[t, r]).twin(0), 1);
    }

    #[test]
    fn twins_block_like_one_surface_and_report_the_side_facing_the_ray() {
        let mut rng = Rng(8);
        let tris = random_scene(&mut rng, 150);
        let n = tris.len() as u32;
        let one = Visibility::build(&tris);
        let two = Visibility::build(&with_twins(&tris));
        // Occlusion: the two-sided scene blocks exactly what the one-sided scene blocks, and
        // ignoring a triangle ignores its twin (either index names the surface).
        let twin = |i: u32| if i == NONE { NONE } else { i + n };
        for (k, (p, q, ignore)) in random_segments(&mut rng, &tris, 3000)
            .into_iter()
            .enumerate()
        {
            let expected = one.occluded(p, q, ignore);
            assert_eq!(two.occluded(p, q, ignore), expected, "segment {k}");
            assert_eq!(
                two.occluded(p, q, ignore.map(twin)),
                expected,
                "segment {k}"
            );
            assert_eq!(
                two.occluded_brute_force(p, q, ignore),
                expected,
                "segment {k}"
            );
        }
        // Closest hit: the same surface at the same distance, reported as the side whose front
        // faces the ray, with barycentrics of that side's own corners.
        let all = with_twins(&tris);
        let mut fronts = [0, 0];
        for k in 0..3000 {
            let (origin, dir) = (rng.vec(-1.0, 11.0), rng.direction());
            let ignore = if k % 2 == 0 {
                NONE
            } else {
                rng.index(tris.len()) as u32
            };
            let a = one.closest_hit(origin, dir, f64::INFINITY, ignore);
            let b = two.closest_hit(origin, dir, f64::INFINITY, twin(ignore));
            assert_eq!(
                b,
                two.closest_hit_brute_force(origin, dir, f64::INFINITY, ignore)
            );
            assert_eq!(b, two.closest_hit(origin, dir, f64::INFINITY, ignore));
            let (Some(a), Some(b)) = (a, b) else {
                assert_eq!(a.is_none(), b.is_none(), "ray {k}");
                continue;
            };
            assert_eq!(b.triangle % n, a.triangle, "ray {k}");
            assert_eq!(b.t, a.t, "ray {k}");
            let t = &all[b.triangle as usize];
            let normal = (t[1] - t[0]).cross(t[2] - t[0]);
            assert!(normal.dot(dir) < 0.0, "ray {k}: reported a back face");
            let on_tri = (1.0 - b.u - b.v) * t[0] + b.u * t[1] + b.v * t[2];
            assert!((on_tri - (origin + b.t * dir)).length() < 1e-4, "ray {k}");
            fronts[(b.triangle >= n) as usize] += 1;
        }
        assert!(fronts[0] > 300 && fronts[1] > 300, "{fronts:?}");
    }

    /// `cargo test --release -- --ignored --nocapture throughput`
    #[test]
    #[ignore]
    fn throughput() {
        // A closed room of 26 × 26 squares per face with ten subdivided boxes inside.
        let mut tris = grid_box(DVec3::ZERO, DVec3::splat(10.0), 26);
        let mut rng = Rng(6);
        for _ in 0..10 {
            let lo = rng.vec(0.5, 8.0);
            tris.extend(grid_box(lo, lo + rng.vec(0.5, 1.5), 4));
        }
        let start = Instant::now();
        let vis = Visibility::build(&tris);
        println!("{} triangles, build {:.1?}", tris.len(), start.elapsed());
        let segments: Vec<(DVec3, DVec3, [u32; 2])> = (0..1_000_000)
            .map(|_| {
                let (i, j) = (rng.index(tris.len()), rng.index(tris.len()));
                let (p, q) = (rng.on_triangle(&tris[i]), rng.on_triangle(&tris[j]));
                (p, q, [i as u32, j as u32])
            })
            .collect();
        let start = Instant::now();
        let blocked = segments
            .iter()
            .filter(|s| vis.occluded(s.0, s.1, s.2))
            .count();
        let secs = start.elapsed().as_secs_f64();
        println!(
            "occluded, 1 thread: {:.2} M rays/s ({blocked} blocked)",
            segments.len() as f64 / secs / 1e6
        );
        let start = Instant::now();
        let blocked_par = segments
            .par_iter()
            .filter(|s| vis.occluded(s.0, s.1, s.2))
            .count();
        let secs = start.elapsed().as_secs_f64();
        println!(
            "occluded, rayon ({} threads): {:.2} M rays/s",
            rayon::current_num_threads(),
            segments.len() as f64 / secs / 1e6
        );
        assert_eq!(blocked, blocked_par);
        let start = Instant::now();
        let hits = segments
            .iter()
            .filter(|s| {
                vis.closest_hit(s.0, s.1 - s.0, f64::INFINITY, s.2[0])
                    .is_some()
            })
            .count();
        let secs = start.elapsed().as_secs_f64();
        println!(
            "closest_hit, 1 thread: {:.2} M rays/s ({hits} hits)",
            segments.len() as f64 / secs / 1e6
        );
    }
}
