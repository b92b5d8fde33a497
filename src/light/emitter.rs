//! The direct light of one emitting triangle of the scene at a point x (unit normal n):
//!
//! D_e(x) = Le_e · F(x → e) · V̄(x, e)   (radiance units, before the receiver's ρ),
//!
//! F the exact unoccluded point-to-polygon form factor (Lambert's contour integral, clipped to
//! x's horizon: [`crate::geometry::point_to_polygon`]) and V̄ the visible share of it. This
//! file owns the emitter as the estimators see it ([`Emitter`]), the estimate of V̄ by
//! kernel-weighted shadow rays ([`Emitter::cast_shadow_rays`] into a [`Share`]), and the
//! shadow-ray counts of every caller, each under a name of its own:
//!
//! | caller | rays per emitter and point |
//! |---|---|
//! | a final-gather vertex ([`crate::gather`]) | [`GATHER_SHADOW_RAYS`], up to [`GATHER_MAX_SHADOW_RAYS`] in a penumbra, where the emitter's visible pieces are too many to compute |
//! | a vertex of the `cache` gather ([`crate::gather::cache`]) | [`GATHER_SHADOW_RAYS`], up to [`CACHE_MAX_SHADOW_RAYS`] in a penumbra, as above |
//! | a display-refinement midpoint ([`mod@crate::gather::refine`]) | [`GATHER_SHADOW_RAYS`], up to [`MIDPOINT_SHADOW_RAYS`] |
//! | a near hit's point of a gather ray | [`NEAR_HIT_SHADOW_RAYS`] |
//! | a rule point of a hierarchical element ([`crate::hierarchical::direct`]) | [`ELEMENT_SHADOW_RAYS`], or [`ELEMENT_FEW_SHADOW_RAYS`] where the kernel is nearly even; in a scene of many emitters, [`ELEMENT_SHARED_SHADOW_RAYS`] a point shared among all of them; of very many, [`ELEMENT_TREE_SHADOW_RAYS`] a point drawn by the light tree |
//!
//! V̄ = Σ G_k V_k / Σ G_k over points y_k of the part of e above x's horizon, drawn uniformly
//! by area and stratified ([`crate::sampling::kernel_samples`]), G the point-pair kernel
//! cosθ_x cosθ_y / r²: the visible share of F itself (weighting by G matters for a large
//! emitter close by, where an area fraction would not do). The ratio of sums is biased by
//! O(1/rays) where G varies much over e (grazing light). Where the shadows of the occluders
//! can be cut from e exactly, the gather takes V̄ from the visible pieces instead
//! ([`crate::geometry::visible`]) and casts none of these rays.

use glam::DVec3;

use crate::color::Rgb;
use crate::geometry::point_to_polygon;
use crate::sampling::{kernel_samples, Rng};

/// Shadow rays per emitter at a final-gather vertex before adapting: if the first rays of any
/// emitter disagree (the vertex is in a penumbra), every emitter gets more, up to
/// [`GATHER_MAX_SHADOW_RAYS`] (the parts of one light, or two lights behind one occluder edge,
/// share a penumbra: an emitter whose first rays happened to agree would otherwise keep an
/// all-or-nothing answer).
pub const GATHER_SHADOW_RAYS: usize = 16;

/// Shadow rays per emitter at a final-gather vertex in a penumbra, in all.
pub const GATHER_MAX_SHADOW_RAYS: usize = 256;

/// Shadow rays per emitter at a vertex of the `cache` gather in a penumbra, in all (the
/// emitters whose visible pieces are too many to compute: behind a plant's leaves, a chair's
/// many faces). Its outputs have ≥ 62,500 vertices, the vertices of a penumbra are many, and
/// their values are fitted to each other's ([`crate::gather::local_fit`]): on the generated
/// office of 10⁵ triangles, 64 rays a vertex display the error of 256 (3.24, 3.31, 3.59 %
/// RMS, seeds 1–3, against 3.19, 3.28, 3.57 %) in 0.87× the bake's time, a third of which
/// the 256 rays took (BENCHMARKS.md "Large outputs: the `cache` gather").
pub const CACHE_MAX_SHADOW_RAYS: usize = 64;

/// Shadow rays per emitter at a display-refinement midpoint in a penumbra, in all: the test
/// asks whether the light departs from linear by more than τ, not its value (a new vertex gets
/// [`GATHER_MAX_SHADOW_RAYS`]).
pub const MIDPOINT_SHADOW_RAYS: usize = 64;

/// Shadow rays per exact emitter at a near hit's point of a gather ray (a ray that lands in a
/// concave corner: [`crate::gather::NEAR_HIT`]). One each: the hits of one gather average many
/// such points.
pub const NEAR_HIT_SHADOW_RAYS: usize = 1;

/// Shadow rays per rule point of a hierarchical element and emitter (stratified over the
/// emitter), a fixed number: stopping when a few rays agree (wholly lit or wholly shadowed)
/// would make the estimate biased, as points in a thin penumbra are then taken for lit more
/// often than not.
pub const ELEMENT_SHADOW_RAYS: usize = 10;

/// Shadow rays per rule point of a hierarchical element and emitter where the kernel G is
/// nearly even over the emitter (at most [`EVEN_KERNEL`] between its largest and smallest
/// values at the emitter's corners and centre: a small or far emitter, not at a grazing
/// angle). The ratio Σ G V / Σ G is then nearly the plain visible fraction, whose estimate has
/// no bias at any count, so few rays do. Decided on the geometry alone, never on what rays
/// saw ([`Emitter::element_shadow_rays`]).
pub const ELEMENT_FEW_SHADOW_RAYS: usize = 4;

/// Shadow rays per rule point of a hierarchical element in a scene of many emitters
/// ([`crate::hierarchical::direct::DIRECT_BUDGET`]), shared among all of them: each ray goes
/// to an emitter drawn with probability ∝ Le_max · F (the unoccluded form factor, its
/// differential form beyond [`FAR_RADII`] radii: [`Emitter::form_factor_weight`];
/// systematic sampling, Kitagawa 1996), and the estimate Σ_e Le_e F_e V̄_e · n_e / (N p_e),
/// F_e exact, carries only the noise of visibility and of those weights (Shirley, Wang &
/// Zimmerman, "Monte Carlo techniques for direct lighting calculations", TOG 1996, as the
/// gather's other lights, [`crate::gather`]). A point that sees every emitter (of one
/// chromaticity) unoccluded gets their light exactly where they are near, and within the
/// weights' error where some are far; in a penumbra the rays go where the light comes from,
/// not two to each emitter however faint. On the generated office of 10⁵ triangles (40 emitting
/// triangles, a sky) 16 rays display the error of two per emitter (80 a point) for a fifth
/// of the rays (BENCHMARKS.md "Large outputs: the `cache` gather").
pub const ELEMENT_SHARED_SHADOW_RAYS: usize = 16;

/// Shadow rays per rule point of a hierarchical element in a scene of very many emitters
/// ([`crate::hierarchical::direct::DIRECT_BUDGET_MANY`]), each to an emitter drawn by the
/// light tree over them ([`crate::light::LightTree`]) at stratified numbers, weighted by
/// 1/(N p_e): unbiased, but not exact where unoccluded, as the tree's chances follow a bound
/// on each node's light, not Le·F. Each ray costs a descent of the tree (two nodes weighed a
/// level), so fewer than [`ELEMENT_SHARED_SHADOW_RAYS`]: on the generated hall of 10⁵
/// triangles (784 emitting triangles) 8 rays gather its probes to the error of 16 within one
/// gather's noise, where 16 take the hall of 10⁶'s solve 1.17× as long (BENCHMARKS.md, the
/// many-emitters bullet).
pub const ELEMENT_TREE_SHADOW_RAYS: usize = 8;

/// See [`ELEMENT_FEW_SHADOW_RAYS`].
pub const EVEN_KERNEL: f64 = 1.25;

/// An emitting triangle as the direct-light estimators see it.
#[derive(Clone, Debug)]
pub struct Emitter {
    /// Its corners, scene units, counter-clockwise seen from its front.
    pub corners: [DVec3; 3],
    /// Its unit front normal.
    pub normal: DVec3,
    /// Its Le, W·sr⁻¹·m⁻² per channel.
    pub le: Rgb,
    /// The centre of its bounding sphere (the centroid) and the sphere's radius, scene units.
    pub centre: DVec3,
    pub radius: f64,
    /// The largest channel of Le times its area (W·sr⁻¹ per channel's largest): how much it
    /// can light the scene, what many-light sampling draws by.
    pub power: f64,
    /// Its area, scene units².
    pub area: f64,
}

/// A point nearer an emitter's plane than this share of the emitter's radius lies on the plane
/// ([`Emitter::in_front`]): rounding leaves a point computed on it (a corner, an edge's
/// midpoint) within about 1e-16 of the scene's coordinates off it, far below this; a point
/// meant to be in front lies further out by many orders.
pub const ON_PLANE: f64 = 1e-9;

/// [`Emitter::form_factor_weight`] takes the differential form beyond this many radii of the
/// emitter's bounding sphere: there it is within about (1/this)² of the exact F.
pub const FAR_RADII: f64 = 8.0;

impl Emitter {
    /// The triangle `corners` emitting `le` from the side of its unit front `normal` (given,
    /// not recomputed: a patch's normal is its parent face's).
    pub fn new(corners: [DVec3; 3], normal: DVec3, le: Rgb) -> Emitter {
        let cross = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
        let centre = (corners[0] + corners[1] + corners[2]) / 3.0;
        let radius = corners
            .iter()
            .map(|c| c.distance(centre))
            .fold(0.0, f64::max);
        let le_max = le.iter().copied().fold(0.0, f64::max);
        let area = 0.5 * cross.length();
        Emitter {
            corners,
            normal,
            le,
            centre,
            radius,
            power: area * le_max,
            area,
        }
    }

    /// The largest channel of its Le, W·sr⁻¹·m⁻².
    pub fn le_max(&self) -> f64 {
        self.le.iter().copied().fold(0.0, f64::max)
    }

    /// A cheap bound on what it can send to the point `x`, max(Le)·A / (π d²) with d the
    /// distance from `x` to its bounding sphere (at least a thousandth of its radius): at
    /// least max(Le)·F(x → e) for a point outside the sphere, whatever the orientations. What
    /// the exact emitters are ranked by, and a near hit's one ray drawn by.
    pub fn bound(&self, x: DVec3) -> f64 {
        let d = (x.distance(self.centre) - self.radius).max(1e-3 * self.radius);
        self.power / (std::f64::consts::PI * d * d)
    }

    /// F(x → e) to weigh the emitter by at the point `x` (unit normal `n`), not to value it:
    /// the point-to-differential-area form A cosθ_x cosθ_e / (π d²) at its centroid where `x`
    /// lies beyond [`FAR_RADII`] radii of it and every corner is above x's horizon (Cohen &
    /// Wallace, *Radiosity and Realistic Image Synthesis* §4.9: exact to O((r/d)²) there), else
    /// the exact F ([`point_to_polygon`], a contour integral). Positive wherever F is (all
    /// corners above the horizon, `x` in front), so a draw by it, whose estimate divides the
    /// exact F by the draw's probability, stays unbiased; 0 behind the emitter's plane or on
    /// it. What the gather's other emitters ([`crate::gather`]) and the hierarchical elements'
    /// shared shadow rays ([`crate::hierarchical::direct`]) are drawn by.
    pub fn form_factor_weight(&self, x: DVec3, n: DVec3) -> f64 {
        let d = self.centre - x;
        let d2 = d.length_squared();
        if self.in_front(x)
            && d2 > (FAR_RADII * self.radius).powi(2)
            && self.corners.iter().all(|&c| (c - x).dot(n) > 0.0)
        {
            let cos_e = -self.normal.dot(d);
            return self.area * n.dot(d) * cos_e / (std::f64::consts::PI * d2 * d2);
        }
        self.form_factor(x, n).unwrap_or(0.0)
    }

    /// F(x → e), the unoccluded form factor from the point `x` (unit normal `n`) to the
    /// emitter, or `None` where the emitter sends nothing toward `x`: `x` behind its plane or
    /// on it ([`Emitter::in_front`]), or the emitter wholly below `x`'s horizon.
    pub fn form_factor(&self, x: DVec3, n: DVec3) -> Option<f64> {
        if !self.in_front(x) {
            return None; // behind the emitter or on its plane: it sends no light this way
        }
        let f = point_to_polygon(x, n, &self.corners);
        (f > 0.0).then_some(f)
    }

    /// Whether the point `x` lies in front of the emitter: off its plane, on its front side,
    /// by more than [`ON_PLANE`] of its radius. A point on the plane (a corner or an edge of
    /// the emitter, as the vertices of an emitting mesh are of their neighbours, or a vertex
    /// of a face that meets it flush) sees it edge-on: F = 0. Lambert's contour sum there has
    /// every corner vector in the plane, and its magnitude (the sign that tells which side
    /// faces `x` is lost to rounding) is the share of the plane's angles the emitter spans
    /// around `x`: the corner's wedge (1/6 at a vertex of six equilateral facets), as if `x`
    /// faced the emitter from against it. On a tessellated sphere's emitting cap that gave
    /// every vertex of the cap, and every wall vertex on its rim, the light of its
    /// neighbouring facets at about that share (the cap's vertices 10 % RMS of L off the
    /// closed form, up to 47 %).
    pub fn in_front(&self, x: DVec3) -> bool {
        (x - self.corners[0]).dot(self.normal) > ON_PLANE * self.radius
    }

    /// Casts `rays` shadow rays from `x` (unit normal `n`) to stratified points y of the
    /// emitter's part above `x`'s horizon, each weighted by the kernel G(x, y), adding what
    /// they see to `share`. `occluded(y)` answers whether something lies between `x` and `y`
    /// (the caller's occluders, ignores and lifts). `targets` is scratch space. Returns the
    /// number of rays cast (a point of zero kernel casts none).
    #[allow(clippy::too_many_arguments)]
    pub fn cast_shadow_rays(
        &self,
        x: DVec3,
        n: DVec3,
        rays: usize,
        rng: &mut Rng,
        targets: &mut Vec<[f64; 3]>,
        share: &mut Share,
        mut occluded: impl FnMut(DVec3) -> bool,
    ) -> u64 {
        let mut cast = 0;
        kernel_samples(
            &self.corners,
            self.normal,
            x,
            n,
            rays,
            rng,
            targets,
            |y, g| {
                share.all += g;
                cast += 1;
                let visible = !occluded(y);
                share.agree[visible as usize] = true;
                if visible {
                    share.seen += g;
                }
            },
        );
        cast
    }

    /// The shadow rays a hierarchical element's rule point `x` (unit normal `n`) casts to
    /// this emitter: [`ELEMENT_FEW_SHADOW_RAYS`] where the kernel is nearly even over it
    /// ([`EVEN_KERNEL`]), else [`ELEMENT_SHADOW_RAYS`].
    pub fn element_shadow_rays(&self, x: DVec3, n: DVec3) -> usize {
        let [a, b, c] = self.corners;
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for y in [a, b, c, (a + b + c) / 3.0] {
            let d = y - x;
            let r2 = d.length_squared();
            let g = n.dot(d) * -self.normal.dot(d) / (r2 * r2);
            lo = lo.min(g);
            hi = hi.max(g);
        }
        if lo > 0.0 && hi <= EVEN_KERNEL * lo {
            ELEMENT_FEW_SHADOW_RAYS
        } else {
            ELEMENT_SHADOW_RAYS
        }
    }
}

/// The visible share V̄ of an emitter from a point as far as it is known: Σ G V over the
/// shadow rays cast (`seen`) and Σ G (`all`), or a share known exactly (the visible pieces:
/// `seen` = V̄, `all` = 1, no ray).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Share {
    /// Σ G_k V_k.
    pub seen: f64,
    /// Σ G_k.
    pub all: f64,
    /// Whether some ray found the emitter hidden (`agree[0]`) and some found it seen
    /// (`agree[1]`).
    pub agree: [bool; 2],
}

impl Share {
    /// V̄ = seen / all, or `None` while nothing is known (no ray of positive kernel cast).
    pub fn visible(&self) -> Option<f64> {
        (self.all > 0.0).then(|| self.seen / self.all)
    }

    /// The rays disagree: the point is in the emitter's penumbra.
    pub fn penumbra(&self) -> bool {
        self.agree[0] && self.agree[1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Half of a unit square 1 above the origin (the triangle below its diagonal), facing down.
    fn emitter() -> Emitter {
        let corners = [
            DVec3::new(-0.5, -0.5, 1.0),
            DVec3::new(0.5, 0.5, 1.0),
            DVec3::new(0.5, -0.5, 1.0),
        ];
        Emitter::new(corners, -DVec3::Z, [2.0, 1.0, 0.5])
    }

    #[test]
    fn the_unoccluded_share_is_one_and_the_form_factor_the_contour_integrals() {
        let e = emitter();
        let (x, n) = (DVec3::ZERO, DVec3::Z);
        let f = e.form_factor(x, n).unwrap();
        assert_eq!(f, point_to_polygon(x, n, &e.corners));
        let mut share = Share::default();
        let mut rng = Rng::new(&[1]);
        let cast = e.cast_shadow_rays(x, n, 16, &mut rng, &mut Vec::new(), &mut share, |_| false);
        assert_eq!(cast, 16);
        assert_eq!(share.visible(), Some(1.0));
        assert!(!share.penumbra());
        // The power is the area (1/2) times the largest channel of Le.
        assert!((e.power - 0.5 * 2.0).abs() < 1e-15);
        // Behind the emitter, or with the emitter below the horizon: nothing.
        assert!(e
            .form_factor(DVec3::new(0.0, 0.0, 2.0), -DVec3::Z)
            .is_none());
        assert!(e.form_factor(x, -DVec3::Z).is_none());
    }

    #[test]
    fn a_point_on_the_emitters_plane_sees_it_edge_on() {
        // A corner, an edge's midpoint and a point beside the triangle, on its plane, with
        // the emitter's own normal (a neighbouring facet of the same surface): F = 0. The
        // contour sum's magnitude there is the plane's angle the triangle spans around the
        // point, at the corner its 45° wedge: 1/8, what a point just in front of the corner
        // facing the emitter gets.
        let e = emitter();
        let corner = e.corners[0];
        let wedge = point_to_polygon(corner, e.normal, &e.corners);
        assert!((wedge - 0.125).abs() < 1e-12, "{wedge}");
        let edge = 0.5 * (e.corners[0] + e.corners[1]);
        for x in [corner, edge, DVec3::new(2.0, 0.0, 1.0)] {
            assert!(!e.in_front(x), "{x}");
            assert!(e.form_factor(x, e.normal).is_none(), "{x}");
            assert!(e.form_factor(x, -e.normal).is_none(), "{x}");
        }
        // A millionth of the emitter's size in front of the corner: in front, and facing
        // the emitter it sees the wedge.
        let x = corner + 1e-6 * e.normal;
        assert!(e.in_front(x));
        let f = e.form_factor(x, -e.normal).unwrap();
        assert!((f - 0.125).abs() < 1e-4, "{f}");
        assert!(e.form_factor(x, e.normal).is_none());
    }

    #[test]
    fn a_half_blocked_emitter_is_in_a_penumbra_and_its_share_is_the_kernels() {
        // An occluder hides what lies over x < 0: the visible share is the G-weighted part of
        // the triangle over x > 0, here summed on a fine grid.
        let e = emitter();
        let (x, n) = (DVec3::ZERO, DVec3::Z);
        let mut share = Share::default();
        let mut rng = Rng::new(&[2]);
        let blocked = |y: DVec3| y.x < 0.0;
        e.cast_shadow_rays(x, n, 4096, &mut rng, &mut Vec::new(), &mut share, blocked);
        assert!(share.penumbra());
        let (mut seen, mut all) = (0.0, 0.0);
        let m = 400;
        for i in 0..m {
            for j in 0..m {
                let (u, v) = ((i as f64 + 0.5) / m as f64, (j as f64 + 0.5) / m as f64);
                if u + v > 1.0 {
                    continue;
                }
                let [a, b, c] = e.corners;
                let y = a + u * (b - a) + v * (c - a);
                let d = y - x;
                let g = n.dot(d) * -e.normal.dot(d) / d.length_squared().powi(2);
                all += g;
                if !blocked(y) {
                    seen += g;
                }
            }
        }
        // 4,096 stratified rays: the ratio's error is well under 2 % here (a smooth kernel,
        // one straight shadow edge crossing the strata).
        let v = share.visible().unwrap();
        assert!((v - seen / all).abs() < 0.02, "{v} vs {}", seen / all);
    }

    #[test]
    fn few_rays_only_where_the_kernel_is_nearly_even() {
        let e = emitter();
        // Far below the emitter's centre, facing it: G nearly even.
        assert_eq!(
            e.element_shadow_rays(DVec3::new(0.0, 0.0, -20.0), DVec3::Z),
            ELEMENT_FEW_SHADOW_RAYS
        );
        // Close below, and grazing: G varies over the emitter.
        assert_eq!(
            e.element_shadow_rays(DVec3::ZERO, DVec3::Z),
            ELEMENT_SHADOW_RAYS
        );
        assert_eq!(
            e.element_shadow_rays(DVec3::new(3.0, 0.0, 0.9), -DVec3::X),
            ELEMENT_SHADOW_RAYS
        );
    }

    #[test]
    fn the_weight_is_the_form_factor_near_and_its_differential_form_far() {
        // Random receivers around the unit emitter: within FAR_RADII radii the weight is the
        // exact F; beyond, with every corner above the horizon, within 3/FAR_RADII² of it
        // away from grazing (the differential form's error is O((r/d)²), r/d < 1/FAR_RADII)
        // and within half of it near grazing; wherever F > 0 the weight is too (a draw by it
        // must reach every emitter that sends light), and behind the emitter's plane it is 0.
        let e = emitter();
        let mut rng = Rng::new(&[3]);
        let mut unit = || loop {
            let v = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 2.0 - 1.0;
            if (1e-6..=1.0).contains(&v.length_squared()) {
                break v.normalize();
            }
        };
        let mut distances = Rng::new(&[4]);
        let (mut far, mut near) = (0, 0);
        for _ in 0..20_000 {
            let (dir, n) = (unit(), unit());
            let r = 40.0 * distances.next_f64();
            let x = e.centre + r * dir;
            let exact = point_to_polygon(x, n, &e.corners);
            let w = e.form_factor_weight(x, n);
            if !e.in_front(x) {
                assert_eq!(w, 0.0, "{x} {n}");
                continue;
            }
            assert!(
                w >= 0.0 && (exact <= 0.0 || w > 0.0),
                "{x} {n}: {w} against {exact}"
            );
            let above = e.corners.iter().all(|&c| (c - x).dot(n) > 0.0);
            if r > FAR_RADII * e.radius && above {
                far += 1;
                // The weight only sets the draw's probabilities (not the estimate's mean): a
                // ratio near 1 keeps an unoccluded point's estimate nearly noiseless. Near
                // grazing (the centroid's cos θ_x small) the differential form's error grows as
                // (r/d)² / cos θ_x, so the tight bound holds only away from it.
                let cos_x = n.dot((e.centre - x).normalize());
                let bound = if cos_x >= 0.25 {
                    3.0 / (FAR_RADII * FAR_RADII)
                } else {
                    0.5
                };
                assert!(
                    (w - exact).abs() <= bound * exact,
                    "{x} {n}: {w} against {exact}"
                );
            } else {
                near += 1;
                assert_eq!(w, exact);
            }
        }
        assert!(
            far > 1000 && near > 1000,
            "both forms tried: {far} far, {near} near"
        );
    }
}
