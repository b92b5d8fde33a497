//! Two-sided surfaces (`Settings::two_sided`, `Scene::make_two_sided`): closed forms first
//! (Howell's parallel plates with a two-sided receiver or source, the furnace with two-sided
//! walls), then the twin map through subdivision and the BVH, and the checks that must not
//! misfire. What belongs here: the physics and data structures of twins; `--two-sided` on the
//! command line is tested in the cli package.

use glam::DVec3;
use radiosity::form_factor::Estimator;
use radiosity::pipeline::{self, Outcome};
use radiosity::scene::{Scene, SceneBuilder, NO_TWIN};
use radiosity::solve::Method;
use radiosity::validation::{closed_forms, scenes};
use radiosity::visibility::Visibility;

use crate::support::{assert_rel, cornell, ff, settings};

/// Area-weighted mean red radiance over the patches `pick` selects.
fn mean_radiance(out: &Outcome, pick: impl Fn(usize) -> bool) -> f64 {
    let p = &out.patches;
    let (mut sum, mut area) = (0.0, 0.0);
    for i in (0..p.len()).filter(|&i| pick(i)) {
        sum += p.area[i] * out.solution.radiance[i][0];
        area += p.area[i];
    }
    assert!(area > 0.0, "no patch selected");
    sum / area
}

/// Tolerance of a mean radiance ρ·F·Le per estimator: the contour integrand is exact per
/// point (1e-3 is the target, met with room to spare); the area estimator's point
/// pairs and the hemisphere's rays are Monte Carlo estimates (the verify suite's 5e-3 plus
/// noise: 3σ of 256 rays × 100 patches for F ≈ 0.2 is 1.2e-2).
fn tolerance(estimator: Estimator) -> f64 {
    match estimator {
        Estimator::Contour => 1e-3,
        Estimator::Area => 5e-3,
        Estimator::Hemisphere => 2e-2,
    }
}

fn plate_settings(estimator: Estimator) -> pipeline::Settings {
    let mut s = settings(0.1, estimator, 3, Method::GaussSeidel, 1);
    s.form_factors.rays = 256;
    s
}

#[test]
fn two_sided_receiver_gets_rho_f_le_in_front_and_nothing_behind() {
    // Howell C-11: unit squares 1 apart. The source (Le = 1, ρ = 0) stays one-sided; the
    // receiver (ρ = 0.5) gets a back side, which faces away from everything: radiance 0. With
    // ρ = 0 at the source nothing comes back, so one bounce is the whole answer.
    let f = closed_forms::parallel_rectangles(1.0, 1.0, 1.0);
    let mut scene = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
    assert_eq!(scene.make_two_sided_where(|_, m| m.name == "receiver"), 2);
    for estimator in [Estimator::Contour, Estimator::Area, Estimator::Hemisphere] {
        let out = crate::support::run(&scene, &plate_settings(estimator));
        let p = &out.patches;
        let receiver = |i: usize| p.material[i] == 1;
        let front = mean_radiance(&out, |i| receiver(i) && p.normal[i].z < 0.0);
        assert_rel(
            &format!("{estimator:?} front"),
            front,
            0.5 * f,
            tolerance(estimator),
        );
        for i in (0..p.len()).filter(|&i| receiver(i) && p.normal[i].z > 0.0) {
            assert_eq!(
                out.solution.radiance[i], [0.0; 3],
                "{estimator:?} back patch {i}"
            );
        }
        for i in (0..p.len()).filter(|&i| !receiver(i)) {
            assert_eq!(
                out.solution.radiance[i], [1.0; 3],
                "{estimator:?} source patch {i}"
            );
            assert_eq!(p.twin[i], NO_TWIN, "the source stays one-sided");
        }
    }
    // The whole scene two-sided (`--two-sided`): the source's back emits away from the
    // receiver, which changes nothing on the receiver; the source's back carries Le.
    let s = pipeline::Settings {
        two_sided: true,
        ..plate_settings(Estimator::Contour)
    };
    let plain = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
    let out = crate::support::run(&plain, &s);
    let p = &out.patches;
    let front = mean_radiance(&out, |i| p.material[i] == 1 && p.normal[i].z < 0.0);
    assert_rel("whole scene two-sided, front", front, 0.5 * f, 1e-3);
    let back = mean_radiance(&out, |i| p.material[i] == 1 && p.normal[i].z > 0.0);
    assert_eq!(back, 0.0);
    let source_back = mean_radiance(&out, |i| p.material[i] == 0 && p.normal[i].z < 0.0);
    assert_eq!(source_back, 1.0);
}

/// The a × b plate at z = 0 with corner at the origin, facing +z, of `material`.
fn source_plate(builder: &mut SceneBuilder, a: f64, b: f64, material: u32) {
    let corners = [(0.0, 0.0), (a, 0.0), (a, b), (0.0, b)].map(|(x, y)| DVec3::new(x, y, 0.0));
    builder.quad(corners, material);
}

/// A two-sided source plate (Le = 1, ρ = 0) at z = 0 between two receivers (ρ = 0.5) at
/// z = ±c facing it, all a × b and directly opposed.
fn sandwich(a: f64, b: f64, c: f64) -> Scene {
    let mut builder = SceneBuilder::new();
    let src = builder.material("source", [0.0; 3], [1.0; 3]);
    let rcv = builder.material("receiver", [0.5; 3], [0.0; 3]);
    let q = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    source_plate(&mut builder, a, b, src);
    builder.quad(
        [q(0.0, 0.0, c), q(0.0, b, c), q(a, b, c), q(a, 0.0, c)],
        rcv,
    );
    builder.quad(
        [q(0.0, 0.0, -c), q(a, 0.0, -c), q(a, b, -c), q(0.0, b, -c)],
        rcv,
    );
    let mut scene = builder.build().unwrap();
    scene.make_two_sided_where(|_, m| m.name == "source");
    scene
}

#[test]
fn two_sided_source_between_two_receivers_lights_both_alike() {
    // Each receiver sees one side of the source: both get ρ·F·Le (Howell C-11), and the
    // receivers cannot see each other past the source (a segment between them crosses it).
    let (a, b, c) = (1.0, 2.0, 0.7);
    let f = closed_forms::parallel_rectangles(a, b, c);
    let scene = sandwich(a, b, c);
    for estimator in [Estimator::Contour, Estimator::Area, Estimator::Hemisphere] {
        let out = crate::support::run(&scene, &plate_settings(estimator));
        let p = &out.patches;
        for (side, z) in [("above", c), ("below", -c)] {
            let got = mean_radiance(&out, |i| {
                p.material[i] == 1 && (p.centroid[i].z - z).abs() < 1e-9
            });
            assert_rel(
                &format!("{estimator:?}, receiver {side}"),
                got,
                0.5 * f,
                tolerance(estimator),
            );
        }
        // Both sides of the source carry exactly Le.
        for i in (0..p.len()).filter(|&i| p.material[i] == 0) {
            assert_eq!(out.solution.radiance[i], [1.0; 3]);
        }
    }
}

#[test]
fn furnace_with_two_sided_walls() {
    // The furnace room (closed, two floating boxes; Le = 1, ρ = 0.5 everywhere), every face
    // two-sided. Inside the room and inside each box (a closed cavity of the boxes' back
    // faces) every row sums to 1: L = Le/(1 − ρ) = 2. The room's outer sides face away from
    // everything: they reflect nothing and carry exactly their own Le = 1.
    let rho = 0.5;
    let expected = closed_forms::furnace_radiance(rho, 1.0);
    let mut scene = scenes::furnace_room(rho, 1.0).unwrap();
    let n = scene.triangles.len();
    assert_eq!(scene.make_two_sided(), n);
    // Scene triangles: 0..12 the room (fronts inward), 12..36 the boxes (fronts outward),
    // then the twins in the same order.
    let outer_room = |t: u32| t as usize >= n && (t as usize - n) < 12;
    for (estimator, tolerance) in [
        // Hemisphere rows are hit counts: exact in every closed region (f32 storage of F
        // and the solver's tolerance remain).
        (Estimator::Hemisphere, 1e-5),
        // Without the closed-scene row normalisation (the outer sides let probes escape, so
        // the scene as a whole is open) the contour estimator's rows next to occluders miss 1
        // by its one-ray-per-point visibility error, amplified by 1/(1 − ρ) = 2.
        (Estimator::Contour, 2e-2),
    ] {
        let mut s = settings(0.25, estimator, 3, Method::GaussSeidel, 1);
        s.form_factors.rays = 128;
        let out = crate::support::run(&scene, &s);
        assert!(!ff(&out).stats.closed_scene, "{estimator:?}");
        assert_eq!(ff(&out).stats.patches_partly_hidden, 0, "{estimator:?}");
        let p = &out.patches;
        let mut worst: f64 = 0.0;
        for i in 0..p.len() {
            let l = out.solution.radiance[i][0];
            if outer_room(p.source_triangle[i]) {
                assert_eq!(l, 1.0, "{estimator:?} outer patch {i}");
            } else {
                worst = worst.max((l - expected).abs() / expected);
            }
        }
        assert!(worst <= tolerance, "{estimator:?}: worst {worst:.3e}");
        if estimator == Estimator::Hemisphere {
            // Every inner row is exactly 1; the outer rows are empty.
            for (i, s) in ff(&out).row_sums().into_iter().enumerate() {
                let want = if outer_room(p.source_triangle[i]) {
                    0.0
                } else {
                    1.0
                };
                assert!((s - want).abs() < 1e-6, "row {i} sums to {s}");
            }
        }
    }
}

#[test]
fn twins_subdivide_identically_and_the_bvh_finds_the_same_pairs() {
    let mut scene = Scene::load(cornell().as_ref()).unwrap();
    let n = scene.triangles.len();
    assert_eq!(scene.make_two_sided(), n);
    scene.validate().unwrap();
    // Twins are not overlapping faces, and no other check runs again.
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    for t in 0..n {
        assert_eq!(scene.twin[t] as usize, t + n);
        assert_eq!(scene.twin[t + n] as usize, t);
    }
    let p =
        radiosity::mesh::subdivide(&scene, 60.0, radiosity::mesh::DEFAULT_CREASE_DEGREES).unwrap();
    p.validate().unwrap();
    let half = p.len() / 2;
    assert_eq!(p.len(), 2 * half);
    // Matched by geometry, not by construction: each patch's twin has the same centroid
    // (bitwise), the opposite normal, the same area, and comes from the twin triangle.
    for i in 0..p.len() {
        let j = p.twin[i] as usize;
        assert_eq!(p.twin[j] as usize, i);
        assert_eq!(p.centroid[i], p.centroid[j], "patch {i}");
        assert_eq!(p.normal[i], -p.normal[j], "patch {i}");
        assert_eq!(p.area[i], p.area[j]);
        assert_eq!(
            scene.twin[p.source_triangle[i] as usize],
            p.source_triangle[j]
        );
        let [a, b, c] = p.corners(i);
        assert_eq!(p.corners(j), [a, c, b]);
    }
    let same_centroid = |i: usize| {
        (0..p.len())
            .filter(|&j| j != i && p.centroid[j] == p.centroid[i])
            .collect::<Vec<_>>()
    };
    for i in (0..p.len()).step_by(97) {
        assert_eq!(same_centroid(i), [p.twin[i] as usize], "patch {i}");
    }
    // The BVH pairs the same patches by itself, from their corners alone.
    let corners: Vec<_> = (0..p.len()).map(|i| p.corners(i)).collect();
    let vis = Visibility::build(&corners);
    assert_eq!(vis.twin_pairs(), half);
    for i in 0..p.len() {
        assert_eq!(vis.twin(i as u32), p.twin[i], "patch {i}");
    }
    // The front sides are the one-sided scene's patches, in the same order.
    let one = Scene::load(cornell().as_ref()).unwrap();
    let q =
        radiosity::mesh::subdivide(&one, 60.0, radiosity::mesh::DEFAULT_CREASE_DEGREES).unwrap();
    assert_eq!(q.len(), half);
    assert_eq!(q.triangles.len(), half);
    for i in 0..half {
        assert_eq!(q.corners(i), p.corners(i));
        assert_eq!(q.corner_normal[i], p.corner_normal[i]);
    }
}

#[test]
fn faces_modelled_with_both_sides_are_paired_not_doubled() {
    // A receiver modelled as two reversed quads over the same corners (a thin two-sided
    // wall, as some meshes come): --two-sided pairs them (each keeps its material) and adds a
    // back only to the source. The answer is the two-sided one.
    let (a, c) = (1.0, 1.0);
    let mut b = SceneBuilder::new();
    let src = b.material("source", [0.0; 3], [1.0; 3]);
    let front = b.material("front", [0.5; 3], [0.0; 3]);
    let back = b.material("back", [0.3; 3], [0.0; 3]);
    let q = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    source_plate(&mut b, a, a, src);
    let rcv = [q(0.0, 0.0, c), q(0.0, a, c), q(a, a, c), q(a, 0.0, c)];
    b.quad(rcv, front);
    // Reversed with the same diagonal, so its triangles are exactly the front's reversed
    // (pairing is per triangle: a back quad cut along the other diagonal is not a twin).
    let [p0, p1, p2, p3] = rcv;
    b.quad([p0, p3, p2, p1], back);
    let mut scene = b.build().unwrap();
    assert_eq!(scene.make_two_sided(), 2, "only the source gets a new back");
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("already had a reversed face")),
        "{:?}",
        scene.warnings
    );
    assert_eq!(scene.make_two_sided(), 0, "idempotent");
    let out = crate::support::run(&scene, &plate_settings(Estimator::Contour));
    let f = closed_forms::parallel_rectangles(a, a, c);
    let got = mean_radiance(&out, |i| out.patches.material[i] == front);
    assert_rel("front side", got, 0.5 * f, 1e-3);
    let got = mean_radiance(&out, |i| out.patches.material[i] == back);
    assert_eq!(got, 0.0);
}
