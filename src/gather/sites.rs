//! Where the final gather evaluates an output vertex ([`Gatherer::spot`]). A vertex whose
//! normal ray meets the back of a surface (buried under contact geometry) keeps the bake's
//! value. Where surfaces meet at the vertex (a crease or material border, a partly buried
//! patch around it, or another object's surface through it: a contact line), the point
//! gathered at is moved [`NUDGE`] of the way toward the centroid of the most visible patch
//! around it, at most [`NUDGE_MAX`] of the scene's extent where contact lines are mesh edges:
//! at the vertex itself a neighbouring surface would be seen edge-on (form factor 0), though
//! every point beside the vertex sees it fill part of the hemisphere.
//!
//! A face a thin gap in front of a surface (a leg's top 5 mm under a table top, a chair's back
//! on its seat) covers it ([`Gatherer::covers`]): under it the light falls within a few gaps
//! of the outline to a small share of the open light, a jump at the display's scale. The
//! covered patches get vertices of their own at the outline
//! ([`crate::bake::bake_sites_apart`]), and those vertices, on either side, are gathered where
//! the rim's profile is its mean over their faces ([`rim_inset`]), first over the patches, and
//! again over the faces the display refinement left ([`super::refine`]). Otherwise a vertex at
//! the outline showed the rim's own light, about half the open value, across the whole
//! footprint (a table's underside above each leg 1.5 times as bright as it is, the leg's top
//! 1.8 times).

use glam::DVec3;

use rayon::prelude::*;

use super::trace::Surfaces;
use super::{Gatherer, LIFT};
use crate::bake::Site;
use crate::mesh::discontinuity::mounted_gap;
use crate::mesh::Patches;
use crate::scene::Scene;

/// Where surfaces meet at a vertex, the gather point is moved this fraction of the way to the
/// centroid of the most visible patch around it. Far enough to leave the steep part of the
/// radiance next to a contact (a light mounted half a millimetre under the Cornell box's
/// ceiling darkens the ceiling within about a millimetre of its edge), near enough that the
/// value stands for the vertex. The displayed error against the path-traced probes is
/// flat over a wide range around this value (the point-wise benchmark, BENCHMARKS.md
/// "Displayed error against a path tracer"). Where contact lines are mesh edges the display
/// refinement follows that steep part itself, and [`NUDGE_MAX`] bounds the move.
pub const NUDGE: f64 = 0.05;

/// Where the contact lines are mesh edges ([`Gatherer::with_contact_edges`]), the gather
/// point moves at most this fraction of the scene's extent off the vertex ([`NUDGE`]): three
/// times the reach at which a surface through the vertex counts as touching it (1e-5 of the
/// extent), enough to see that surface at an angle rather than edge-on. The display
/// refinement splits edges down to a tenth of a millimetre beside the Cornell box's light,
/// so a vertex on the light's rim must show the rim's own light: nudged [`NUDGE`] of the way
/// to a patch centroid (about a millimetre there) it would show the ceiling's value well
/// outside the rim, and the probes next to the rim would read far too bright. The bound is
/// applied only where contact lines are mesh edges: without them (the hall's hierarchy,
/// whose elements straddle the lights' outlines and whose display refinement runs out of
/// budget) no vertex lies that close to an outline, and the full nudge is what keeps a
/// vertex out of the steep part; bounded there, the hall's display is worse.
pub const NUDGE_MAX: f64 = 3e-5;

/// How far from a vertex another surface may pass and still be taken to touch it
/// ([`Gatherer::touched`]), as a fraction of the scene's extent: ten times [`LIFT`], so the
/// rays' lift cannot carry them past a surface through the vertex, far below any gap the
/// gather resolves.
const TOUCH_REACH: f64 = 1e-5;

/// How far a patch's corners are moved toward its centroid before [`buried_patches`]
/// tests them: off the corner, where the neighbouring surface's edge passes, by a share the
/// contact lines' cuts leave wholly on one side.
const BURIED_INSET: f64 = 0.05;

/// Whether each of `patches` (of `scene`) is buried all over: at its centroid and its
/// corners (each moved 5 % of the way to the centroid, off the patch's own edges), the first
/// surface along the patch's normal is seen from behind. A strip of a screen behind the desk
/// top that abuts it, the floor under a leg's foot: the contact lines cut such pieces out of
/// the seen faces, and nobody sees them. A patch buried only in part counts as seen. What
/// [`crate::bake::bake_sites_apart`] keeps apart (and the estimate counts).
pub fn buried_patches(scene: &Scene, patches: &Patches) -> Vec<bool> {
    let (lo, hi) = scene.bounds();
    buried_in(&Surfaces::new(patches), patches, LIFT * (hi - lo).length())
}

/// [`buried_patches`] with the patches' traced `surfaces` and the rays' `lift` (scene units).
fn buried_in(surfaces: &Surfaces, p: &Patches, lift: f64) -> Vec<bool> {
    (0..p.len())
        .into_par_iter()
        .map(|q| {
            let (c, n) = (p.centroid[q], p.normal[q]);
            let corner = |k: usize| {
                let v = p.positions[p.triangles[q][k] as usize];
                v + BURIED_INSET * (c - v)
            };
            [c, corner(0), corner(1), corner(2)]
                .into_iter()
                .all(|x| buried_at(surfaces, lift, x, n, q as u32))
        })
        .collect()
}

/// [`Gatherer::buried`]'s test with the traced `surfaces` and the rays' `lift`.
fn buried_at(surfaces: &Surfaces, lift: f64, x: DVec3, n: DVec3, ignore: u32) -> bool {
    surfaces
        .vis()
        .first_hit_from_behind(x + lift * n, n, surfaces.traced(ignore))
        .unwrap_or(false)
}

/// Where the gather evaluates at a site: the point, its normal and the patch it lies on
/// (whose rays ignore), or `None` when the point is buried.
pub(crate) struct Spot {
    pub(super) x: DVec3,
    pub(super) n: DVec3,
    pub(super) patch: u32,
}

/// How far from a covering face's outline (gap `g`) a vertex on it, or under the face, is
/// gathered, on a face whose centroid is `to_centroid` away (scene units). Across the outline
/// the light changes by about its whole value within a few g: under the face, the share of
/// the open light that reaches a point x inside is the projected share of a slit of width g,
/// f(x) = ½(1 − x/√(x² + g²)), and beside it the face hides as much ([`MOUNTED`]'s note). The
/// display interpolates each side linearly from the vertex over its faces, about
/// ℓ = 1.5 × `to_centroid` wide, so the value that keeps the profile's integral over them
/// (∫ f dx = g/2, over a hat whose integral is ℓ/2) is g/ℓ, which f's far field g²/4x² takes
/// at d = ½√(g·ℓ); at most half way to the centroid. (f itself takes g/ℓ nearer the rim,
/// brighter: on the plate of the test `the_floor_under_a_plate_a_thin_gap_…`, the generated
/// hall and the office, all three showed more error so.)
///
/// [`MOUNTED`]: crate::mesh::discontinuity::MOUNTED
pub(crate) fn rim_inset(g: f64, to_centroid: f64) -> f64 {
    (0.5 * (g * 1.5 * to_centroid).sqrt()).min(0.5 * to_centroid)
}

/// One face of a display vertex's star (the faces around it): its corners (scene
/// coordinates), which of them is the vertex, and the patch it lies on.
#[derive(Clone, Copy, Debug)]
pub(crate) struct StarFace {
    pub corners: [DVec3; 3],
    pub vertex: usize,
    pub patch: u32,
}

impl StarFace {
    /// Twice the face's area (scene units²).
    pub(super) fn doubled_area(&self) -> f64 {
        let [a, b, c] = self.corners;
        (b - a).cross(c - a).length()
    }

    /// The distance from the vertex to the face's centroid (scene units).
    pub(super) fn reach(&self) -> f64 {
        let [a, b, c] = self.corners;
        self.corners[self.vertex].distance((a + b + c) / 3.0)
    }
}

/// A parallel face counts as covering a patch where its normals are within this angle's
/// cosine of opposite (8°).
const COVER_COS: f64 = 0.99;

impl Gatherer<'_> {
    /// Each patch's gap (scene units) under a face that covers it, 0 where none: a leg's top
    /// 5 mm under its table top, a seat's back on its seat. The first surface along the
    /// patch's normal from its centroid is the front of a parallel face (normals within 8° of
    /// opposite), further than a touch (ten times the rays' lift) and no further than the
    /// contact lines' rule for a mounted face ([`mounted_gap`]), whose outline they project
    /// onto the patch's plane: [`NEAR`] of the scene's extent, or [`MOUNTED`] of the narrower
    /// one's width (the smallest altitude of its scene triangle: the input triangle for the
    /// hierarchical display; for the matrix method's patches, the piece the contact lines
    /// cut, where the rule is then the stricter). Under such a face light enters only through
    /// the gap g, so the radiance falls from about half its open value at the outline to near
    /// nothing a few g inside ([`MOUNTED`]'s note): at the display's scale a jump, which
    /// [`bake_sites_apart`](crate::bake::bake_sites_apart) keeps by giving the covered and the
    /// open patches at an outline their own vertices. (A blocker 10 cm over a 1 m receiver,
    /// its shadow's penumbra 11 cm wide, is no cover: the light under it does not come in
    /// through a slit, and across its outline it changes no faster than the penumbra.)
    /// Emitting patches are never covered (their own light is what they show). `scene` is the
    /// one the patches were made from.
    ///
    /// [`NEAR`]: crate::mesh::discontinuity::NEAR
    /// [`MOUNTED`]: crate::mesh::discontinuity::MOUNTED
    pub fn covers(&self, scene: &Scene) -> Vec<f64> {
        let p = self.patches;
        let touch = self.touch_reach();
        let source = |q: u32| p.source_triangle[q as usize] as usize;
        (0..p.len())
            .into_par_iter()
            .map(|q| {
                let n = p.normal[q];
                if p.emission[q].iter().any(|&e| e > 0.0) {
                    return 0.0;
                }
                let from = p.centroid[q] + self.lift * n;
                let Some(hit) = self.surfaces.closest(from, n, q as u32) else {
                    return 0.0;
                };
                let gap = hit.t + self.lift;
                let reach = mounted_gap(scene, source(q as u32), source(hit.patch), self.extent());
                let facing = p.normal[hit.patch as usize].dot(n) < -COVER_COS;
                if facing && gap > touch && gap <= reach {
                    gap
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// [`buried_patches`] of this gatherer's patches.
    pub fn buried_patches(&self) -> Vec<bool> {
        buried_in(&self.surfaces, self.patches, self.lift)
    }

    /// Gather covered vertices inside their cover ([`Gatherer::covers`]; `cover` indexed by
    /// patch, as it returns).
    pub fn with_covers(mut self, cover: Vec<f64>) -> Self {
        self.cover = cover;
        self
    }

    /// The point a site is gathered at (see the module documentation: nudged into the most
    /// visible patch where surfaces meet), or `None` when it is buried. Where that point is
    /// buried, the point nudged into each patch around the vertex is tried in turn, the most
    /// visible first: a vertex on the border between a buried face and a seen one (the
    /// ceiling's vertex exactly above a mounted light's corner, whose faces above the light
    /// and beside it are equally visible by their leaf's share) shows the seen face's light,
    /// not the bake's mean. (Otherwise the generated hall's ceiling vertices above its lights'
    /// corners are buried so, the edges from them across the lit ceiling are never refined,
    /// and the ceiling between the lights and the walls shows dark.)
    pub(crate) fn spot(&self, site: &Site, visible_fraction: &[f64]) -> Option<Spot> {
        self.spot_within(site, visible_fraction, None)
    }

    /// A site's gap under a covering face, scene units: the gap of the face whose outline
    /// it lies on ([`Site::gap`]), or where surfaces meet at it (a leg's top at its sides), the
    /// widest its patches are covered by ([`Gatherer::covers`]); 0 elsewhere.
    pub(crate) fn rim_gap(&self, site: &Site) -> f64 {
        if site.gap > 0.0 {
            return f64::from(site.gap);
        }
        if !site.shared || self.cover.is_empty() {
            return 0.0;
        }
        site.patches
            .iter()
            .map(|&q| self.cover[q as usize])
            .fold(0.0, f64::max)
    }

    /// [`Gatherer::spot`], where a vertex on a covering face's outline or under it
    /// ([`Gatherer::rim_gap`]) is gathered [`rim_inset`] of `reach` inside its patch: the mean
    /// distance from the vertex to its faces' centroids, once the display refinement has
    /// made them ([`refine`](super::refine) gathers such a vertex again then); by default,
    /// to its patch's centroid.
    pub(crate) fn spot_within(
        &self,
        site: &Site,
        visible_fraction: &[f64],
        reach: Option<f64>,
    ) -> Option<Spot> {
        let p = self.patches;
        let gap = self.rim_gap(site);
        // The most visible patch around the vertex (of equals, the last one listed): evaluate
        // from its side.
        let visible = |q: u32| visible_fraction.get(q as usize).copied().unwrap_or(1.0);
        let (best, _) = site
            .patches
            .iter()
            .map(|&q| (q, visible(q)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .expect("a site has patches");
        // Where surfaces meet (a crease, a material border, a contact line: a patch
        // around it partly buried), the vertex is on the plane of a neighbouring surface,
        // which it would see edge-on (form factor 0, its rays grazing it) while every
        // point next to it sees that surface fill part of its hemisphere: gather just
        // inside the most visible patch instead. Elsewhere, exactly at the vertex.
        let contact = site.shared
            || site.patches.iter().any(|&q| visible(q) < 1.0)
            || self.touched(site.position, site.normal, best);
        let n = site.normal;
        let nudged = |q: u32| {
            let to_centroid = p.centroid[q as usize] - site.position;
            let x = if gap > 0.0 {
                // On a covering face's outline or under it: where the rim's profile is its
                // mean over its faces ([`rim_inset`]), inside the patch, off the outline's
                // plane by at least a touch as every gather point.
                let length = to_centroid.length();
                let inset = rim_inset(gap, reach.unwrap_or(length))
                    .min(0.5 * length)
                    .max(self.touch_reach());
                site.position + to_centroid * (inset / length)
            } else {
                let d = NUDGE * to_centroid;
                site.position + d * (self.nudge_max / d.length()).min(1.0)
            };
            (!self.buried(x, n, q)).then_some(Spot { x, n, patch: q })
        };
        if contact {
            if let Some(spot) = nudged(best) {
                return Some(spot);
            }
        } else if !self.buried(site.position, n, best) {
            let x = site.position;
            return Some(Spot { x, n, patch: best });
        }
        // Buried there: the point nudged into each patch around the vertex, the most visible
        // first (of equals, the last one listed), but the one just tried.
        let mut order: Vec<(u32, f64)> = site
            .patches
            .iter()
            .rev()
            .map(|&q| (q, visible(q)))
            .collect();
        order.sort_by(|a, b| b.1.total_cmp(&a.1));
        order
            .into_iter()
            .filter(|&(q, _)| !(contact && q == best))
            .find_map(|(q, _)| nudged(q))
    }

    /// Whether another surface passes through the point `x` (unit normal `n`, on patch
    /// `patch`): a block's foot on the floor, whose vertices are not the floor's (they are
    /// different objects) and so are not `shared`. Short rays along the surface, [`LIFT`]
    /// above it, through `x` from [`TOUCH_REACH`] before it to as far beyond, in four
    /// directions (a surface through `x` crosses at least three of them): any hit is such a
    /// surface, as its own plane and its coplanar neighbours lie parallel to the rays.
    pub(super) fn touched(&self, x: DVec3, n: DVec3, patch: u32) -> bool {
        let (t, b) = n.any_orthonormal_pair();
        let reach = self.touch_reach();
        let ignore = self.surfaces.traced(patch);
        [t, b, (t + b).normalize(), (t - b).normalize()]
            .iter()
            .any(|&d| {
                let from = x + self.lift * n - reach * d;
                self.surfaces.vis().blocked(from, d, 2.0 * reach, ignore)
            })
    }

    /// [`TOUCH_REACH`] in scene units: how far another surface may pass and still touch.
    fn touch_reach(&self) -> f64 {
        TOUCH_REACH / LIFT * self.lift
    }

    /// True when the first surface along `n` from `x` is seen from behind: `x` is buried
    /// ([`crate::visibility::Visibility::buried`]'s test, along the vertex's own normal rather than
    /// one patch's: on a curved surface the two differ).
    ///
    /// The ray starts [`LIFT`] above `x`, as the shadow and hemisphere rays do. From `x`
    /// itself, a vertex shared by several patches of a face that is not aligned with the axes
    /// (a rotated block's side) could meet one of the other patches at `t` of the order of the
    /// `f32` rounding of their corners, from behind, and be taken for buried, keeping the
    /// patches' mean instead of its gather (the Cornell box's rotated blocks have many such
    /// vertices). Contact geometry buries a point by far more than
    /// the lift (the floor under a block is covered wherever it is buried).
    pub(super) fn buried(&self, x: DVec3, n: DVec3, ignore: u32) -> bool {
        buried_at(&self.surfaces, self.lift, x, n, ignore)
    }
}
