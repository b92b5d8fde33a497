//! Where the final gather evaluates an output vertex ([`Gatherer::spot`]). A vertex whose
//! normal ray meets the back of a surface (buried under contact geometry) keeps the bake's
//! value. Where surfaces meet at the vertex (a crease or material border, a partly buried
//! patch around it, or another object's surface through it: a contact line), the point
//! gathered at is moved [`NUDGE`] of the way toward the centroid of the most visible patch
//! around it, at most [`NUDGE_MAX`] of the scene's extent where contact lines are mesh edges:
//! at the vertex itself a neighbouring surface would be seen edge-on (form factor 0), though
//! every point beside the vertex sees it fill part of the hemisphere.

use glam::DVec3;

use super::{Gatherer, LIFT};
use crate::bake::Site;

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

/// Where the gather evaluates at a site: the point, its normal and the patch it lies on
/// (whose rays ignore), or `None` when the point is buried.
pub(crate) struct Spot {
    pub(super) x: DVec3,
    pub(super) n: DVec3,
    pub(super) patch: u32,
}

impl Gatherer<'_> {
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
        let p = self.patches;
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
            let d = NUDGE * (p.centroid[q as usize] - site.position);
            let x = site.position + d * (self.nudge_max / d.length()).min(1.0);
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
        let reach = TOUCH_REACH / LIFT * self.lift;
        let ignore = self.surfaces.traced(patch);
        [t, b, (t + b).normalize(), (t - b).normalize()]
            .iter()
            .any(|&d| {
                let from = x + self.lift * n - reach * d;
                self.surfaces.vis().blocked(from, d, 2.0 * reach, ignore)
            })
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
        self.surfaces
            .vis()
            .first_hit_from_behind(x + self.lift * n, n, self.surfaces.traced(ignore))
            .unwrap_or(false)
    }
}
