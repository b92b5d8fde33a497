//! Geometry that tries to break the estimators, through the whole pipeline: the unit of
//! length (the same scene in millimetres and kilometres gives the same radiance for every
//! estimator) and hand-made hostile meshes (extreme patch-size ratios, slivers, edges shared
//! at grazing angles) that must keep F and L finite, non-negative and within their bounds.
//! What belongs here: robustness of the numbers to the input's shape and scale.

use glam::DVec3;
use radiosity::color::luminance;
use radiosity::form_factor::Estimator;
use radiosity::gather::Gather;
use radiosity::pipeline::Outcome;
use radiosity::scene::{Scene, SceneBuilder};
use radiosity::solve::Method;
use radiosity::validation::pointwise::{self, Probe};
use radiosity::validation::scenes;

use crate::support::{ff, meshes, run, settings, temp_dir};

const ESTIMATORS: [Estimator; 3] = [Estimator::Area, Estimator::Contour, Estimator::Hemisphere];

/// The scene with every position multiplied by `s`.
fn scaled(scene: &Scene, s: f64) -> Scene {
    let mut out = scene.clone();
    for p in &mut out.positions {
        *p *= s;
    }
    out
}

#[test]
fn radiance_does_not_depend_on_the_unit_of_length() {
    let cornell = Scene::load(&meshes().join("cornell_box.obj")).unwrap();
    let furnace = scenes::furnace_room(0.5, 1.0).unwrap();
    let room = lamp_room(false);
    // The factors 1e-3 and 1e3 (and powers of two): the visibility snaps its canonical
    // coordinates to a grid far coarser than f64 rounding, so even rays aimed exactly at an
    // occluder's edge (structured sample points in an axis-aligned scene are) are decided the
    // same way at every scale; see docs/robustness.md, "Scale invariance".
    let factors = [1e-3, 1e3, 1.0 / 1024.0, 1024.0];
    for (name, scene, max_edge) in [
        ("room", &room, 0.3),
        ("cornell", &cornell, 170.0),
        ("furnace", &furnace, 0.4),
    ] {
        for estimator in ESTIMATORS {
            let mut s = settings(max_edge, estimator, 3, Method::GaussSeidel, 1);
            s.form_factors.rays = 64;
            let base: Outcome = run(scene, &s);
            for factor in factors {
                let mut t = s.clone();
                t.max_edge = Some(max_edge * factor);
                let other = run(&scaled(scene, factor), &t);
                assert_eq!(
                    other.patches.len(),
                    base.patches.len(),
                    "{name} {estimator:?}"
                );
                // 1e-6 relative (the target): F is dimensionless and every geometric
                // test is relative, so only rounding differs (f64 ~1e-16, then F's f32
                // storage ~6e-8, amplified by at most 1/(1 − ρ) = 2 in the solve); the solver
                // tolerance (1e-12) adds nothing visible.
                let scale = base
                    .solution
                    .radiance
                    .iter()
                    .flatten()
                    .fold(0.0f64, |m, x| m.max(*x));
                for (i, (a, b)) in base
                    .solution
                    .radiance
                    .iter()
                    .zip(&other.solution.radiance)
                    .enumerate()
                {
                    for c in 0..3 {
                        let err = (a[c] - b[c]).abs() / a[c].abs().max(1e-3 * scale);
                        assert!(
                            err <= 1e-6,
                            "{name} {estimator:?} ×{factor}: patch {i} channel {c}: {} vs {} ({err:.2e})",
                            a[c],
                            b[c]
                        );
                    }
                }
            }
        }
    }
}

/// A 1.3 × 0.7 × 1.1 room lit by one of its walls (Le 3), with a block standing off its
/// floor when `block` (its shadow and the gap under it for the display to follow).
fn lamp_room(block: bool) -> Scene {
    let mut room = SceneBuilder::new();
    let m = room.material("room", [0.5; 3], [0.0; 3]);
    let lamp = room.material("lamp", [0.5; 3], [3.0; 3]);
    let faces = scenes::box_faces(DVec3::ZERO, DVec3::new(1.3, 0.7, 1.1));
    for (k, q) in faces.iter().enumerate() {
        // Reversed: counter-clockwise seen from inside.
        let [a, b, c, d] = *q;
        room.quad([d, c, b, a], if k == 0 { lamp } else { m });
    }
    if block {
        let lo = DVec3::new(0.5, 0.2, 0.05);
        for q in scenes::box_faces(lo, lo + DVec3::new(0.3, 0.25, 0.2)) {
            room.quad(q, m);
        }
    }
    room.build().unwrap()
}

#[test]
fn the_gathered_display_does_not_depend_on_the_unit_of_length() {
    // The final gather, its display refinement and the local fit of its vertex values, in a
    // scene modelled in units 10⁻²⁵ to 10²⁵ times its size: what the display shows at 400
    // points (scaled with it) is the same light. The fit had kept its quadratics' bends per
    // squared scene unit in single precision, which overflowed in units below about 10⁻¹⁹
    // of the scene (the light shown half of it at 10⁻²⁰, a hundredth at 10⁻²⁵) and vanished
    // above 10²⁰. Every other stage is relative to the scene, but the refinement's choices
    // are not bit for bit (an edge's priority rounds differently and the other of two nearly
    // equal edges splits: 7,817 output vertices at 1, 7,828 at 10⁻³). Such an edge changes
    // the light shown over its faces by at most the display's tolerance τ (2 %), and a few
    // dozen of 7,800 differ, so at random points the shown light moves far less: 0.10–0.14 %
    // RMS, the mean 7e-5, at these factors. Bounds: τ/4 at a point, 5e-4 for the mean.
    let room = lamp_room(true);
    let mut s = settings(0.3, Estimator::Contour, 3, Method::GaussSeidel, 1);
    s.gather = Gather::Full;
    let base = run(&room, &s);
    assert!(base.report.display_refinement.vertices > 0);
    let probes = pointwise::sample_points(&room, 400, 3).unwrap();
    for factor in [1e-25, 1e-3, 1e3, 1e25] {
        let mut t = s.clone();
        t.max_edge = Some(0.3 * factor);
        let other = run(&scaled(&room, factor), &t);
        let moved: Vec<Probe> = probes
            .iter()
            .map(|p| Probe {
                position: p.position * factor,
                ..*p
            })
            .collect();
        assert_shown_alike((&base, &probes), (&other, &moved), &format!("×{factor}"));
    }
}

#[test]
fn a_model_in_map_coordinates_bakes_as_at_the_origin() {
    // The lit room with a block, 1.3 units across, saved as OBJ at the origin and at map
    // coordinates (5.6·10⁶ north, as a building in UTM metres), loaded, baked with the final
    // gather, written as PLY and read back. Read in single precision (as the loader once
    // did) its corners rounded in steps of 0.5, a third of the room; in double precision
    // they are exact to 10⁻⁹, the rays work about the scene's centre, and the light shown
    // at 400 points is the origin's within what the refinement's near-ties move (the
    // unit-of-length test above: 0.10–0.14 % RMS there; bounds τ/4 at a point, 5e-4 for the
    // mean). The written positions are the bake's own, far out in double precision, to the
    // bit.
    let dir = temp_dir("map-coordinates");
    let offset = DVec3::new(5.0e5 + 0.123, 5.6e6 + 0.456, 17.0);
    let room = lamp_room(true);
    let mut far = room.clone();
    for p in &mut far.positions {
        *p += offset;
    }
    let mut s = settings(0.3, Estimator::Contour, 3, Method::GaussSeidel, 1);
    s.gather = Gather::Full;
    let bake = |scene: &Scene, name: &str| {
        let path = dir.join(format!("{name}.obj"));
        radiosity::io::obj::save(scene, &path).unwrap();
        let loaded = Scene::load(&path).unwrap();
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        let out = run(&loaded, &s);
        let ply = dir.join(format!("{name}.ply"));
        radiosity::io::write(
            &ply,
            &out.baked,
            radiosity::io::Format::Ply { ascii: false },
            1.0,
        )
        .unwrap();
        let back = radiosity::io::ply::read(&ply).unwrap();
        // Near the origin the file keeps single precision; far out, double.
        let double = radiosity::io::needs_double(&out.baked.positions);
        assert_eq!(double, name == "far");
        let stored: Vec<[f64; 3]> = (out.baked.positions.iter())
            .map(|p| p.map(|c| if double { c } else { f64::from(c as f32) }))
            .collect();
        assert_eq!(back.positions, stored, "{name}");
        (loaded, out)
    };
    let (near_scene, near) = bake(&room, "near");
    let (far_scene, far_out) = bake(&far, "far");
    for (a, b) in near_scene.positions.iter().zip(&far_scene.positions) {
        assert!((*b - offset - *a).abs().max_element() <= 1e-9, "{a} {b}");
    }
    let probes = pointwise::sample_points(&near_scene, 400, 3).unwrap();
    let moved: Vec<Probe> = probes
        .iter()
        .map(|p| Probe {
            position: p.position + offset,
            ..*p
        })
        .collect();
    assert_shown_alike((&near, &probes), (&far_out, &moved), "at map coordinates");
}

/// Asserts that two bakes of one scene (each with the same points, placed in its own
/// coordinates) show the same light: the mean luminance shown within 5e-4 and the points'
/// relative RMS difference within 0.5 % (τ/4; see the tests that call it).
fn assert_shown_alike(want: (&Outcome, &[Probe]), got: (&Outcome, &[Probe]), what: &str) {
    let shown = |(out, probes): (&Outcome, &[Probe])| -> Vec<f64> {
        pointwise::Display::from_baked(&out.baked)
            .at(probes)
            .iter()
            .map(|s| luminance(s.expect("every probe shown").interpolated))
            .collect()
    };
    let (want, got) = (shown(want), shown(got));
    let ratio = got.iter().sum::<f64>() / want.iter().sum::<f64>();
    let rms = (got
        .iter()
        .zip(&want)
        .map(|(g, w)| ((g - w) / w).powi(2))
        .sum::<f64>()
        / want.len() as f64)
        .sqrt();
    assert!(
        (ratio - 1.0).abs() <= 5e-4,
        "{what}: mean shown {ratio} of the first"
    );
    assert!(rms <= 0.005, "{what}: shown {rms:.4} RMS off the first");
}

/// Checks every invariant the issue asks of hostile geometry: F finite and ≥ 0 with no
/// diagonal, rows ≤ 1 + tolerance, and the solution finite and ≥ 0.
fn assert_sane(name: &str, scene: &Scene, max_edge: f64) {
    for estimator in ESTIMATORS {
        let mut s = settings(max_edge, estimator, 3, Method::GaussSeidel, 1);
        s.form_factors.rays = 256;
        // The whole pipeline, the final gather and its display refinement included.
        s.gather = Gather::Auto;
        let out = run(scene, &s);
        // These scenes have no occluders, so the contour estimator's rows are exact per
        // sample point (≤ 1 up to f64 rounding, then f32 storage ~6e-8 per entry) and the
        // hemisphere rows are hit counts / rays ≤ 1. The area estimator uses the exact
        // integrand for near pairs but the point kernel cosθcosθ'/(πr²)·A_j for far ones,
        // which overestimates by O(A_j/r²) (< 1/16 by the near-field switch): 1e-2 as in the
        // form-factor tests.
        let tol = if estimator == Estimator::Area {
            1e-2
        } else {
            1e-5
        };
        if let Err(e) = ff(&out).validate(tol) {
            panic!("{name} {estimator:?}: {e}");
        }
        for (i, l) in out.solution.radiance.iter().enumerate() {
            assert!(
                l.iter().all(|x| x.is_finite() && *x >= 0.0),
                "{name} {estimator:?}: patch {i} radiance {l:?}"
            );
        }
        assert!(out.solution.converged, "{name} {estimator:?}");
        for (v, l) in out.baked.vertex_radiance.iter().enumerate() {
            assert!(
                l.iter().all(|x| x.is_finite() && *x >= 0.0),
                "{name} {estimator:?}: vertex {v} shows {l:?}"
            );
        }
    }
}

#[test]
fn hostile_geometry_keeps_form_factors_and_radiance_sane() {
    // 1. Patch-size ratio 1e10 in area: a 1 km floor and a 1 cm emitter 1 m above it, plus a
    //    1 m wall, unsubdivided (max-edge larger than the scene).
    let mut b = SceneBuilder::new();
    let grey = b.material("grey", [0.7; 3], [0.0; 3]);
    let lamp = b.material("lamp", [0.5; 3], [100.0; 3]);
    let k = 500.0;
    b.quad(
        [
            DVec3::new(-k, -k, 0.0),
            DVec3::new(k, -k, 0.0),
            DVec3::new(k, k, 0.0),
            DVec3::new(-k, k, 0.0),
        ],
        grey,
    );
    let [p, q, r] = [
        DVec3::new(0.0, 0.0, 1.0),
        DVec3::new(0.01, 0.0, 1.0),
        DVec3::new(0.0, 0.01, 1.0),
    ]
    .map(|v| b.vertex(v));
    b.triangle([p, r, q], lamp); // facing down
    b.quad(
        [
            DVec3::new(1.0, -0.5, 0.0),
            DVec3::new(1.0, 0.5, 0.0),
            DVec3::new(1.0, 0.5, 1.0),
            DVec3::new(1.0, -0.5, 1.0),
        ],
        grey,
    );
    assert_sane("size ratio", &b.build().unwrap(), 2000.0);

    // 2. Long thin slivers (aspect 1e4) facing each other and an emitter, side by side with
    //    a shared long edge.
    let mut b = SceneBuilder::new();
    let grey = b.material("grey", [0.7; 3], [0.0; 3]);
    let lamp = b.material("lamp", [0.5; 3], [1.0; 3]);
    let v: Vec<u32> = [
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(10.0, 0.0, 0.0),
        DVec3::new(0.0, 1e-3, 0.0),
        DVec3::new(10.0, 1e-3, 0.0),
        DVec3::new(0.0, 0.0, 0.5),
        DVec3::new(10.0, 0.0, 0.5),
        DVec3::new(0.0, 1e-3, 0.5),
    ]
    .into_iter()
    .map(|p| b.vertex(p))
    .collect();
    b.triangle([v[0], v[1], v[2]], grey); // up
    b.triangle([v[2], v[1], v[3]], grey); // up, shares the long edge 1–2
    b.triangle([v[4], v[6], v[5]], lamp); // down
    assert_sane("slivers", &b.build().unwrap(), 1e3);
    // The same, subdivided: slivers cut into many smaller slivers.
    assert_sane("slivers subdivided", &b_slivers_scene(), 1.0);

    // 3. Two unit squares sharing an edge at grazing dihedral angles: almost folded shut
    //    (0.5°, a deep wedge) and almost flat (179.5°).
    for degrees in [0.5f64, 179.5] {
        let t = degrees.to_radians();
        let mut b = SceneBuilder::new();
        let grey = b.material("grey", [0.7; 3], [0.0; 3]);
        let lamp = b.material("lamp", [0.5; 3], [1.0; 3]);
        // Floor in z = 0 facing +z; the other leaf hinged on the x axis at angle t, facing
        // into the wedge.
        b.quad(
            [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
            ],
            grey,
        );
        let (c, s) = (t.cos(), t.sin());
        b.quad(
            [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(0.0, c, s),
                DVec3::new(1.0, c, s),
                DVec3::new(1.0, 0.0, 0.0),
            ],
            lamp,
        );
        let scene = b.build().unwrap();
        assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
        assert_sane(&format!("wedge {degrees}°"), &scene, 0.3);
    }
}

/// The sliver pair of `hostile_geometry…` with an emitter, for subdivision.
fn b_slivers_scene() -> Scene {
    let mut b = SceneBuilder::new();
    let grey = b.material("grey", [0.7; 3], [0.0; 3]);
    let lamp = b.material("lamp", [0.5; 3], [1.0; 3]);
    b.quad(
        [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::new(10.0, 1e-3, 0.0),
            DVec3::new(0.0, 1e-3, 0.0),
        ],
        grey,
    );
    b.quad(
        [
            DVec3::new(0.0, 0.0, 0.5),
            DVec3::new(0.0, 1e-3, 0.5),
            DVec3::new(10.0, 1e-3, 0.5),
            DVec3::new(10.0, 0.0, 0.5),
        ],
        lamp,
    );
    b.build().unwrap()
}

/// The lamp room ([`scenes::lamp_room`]); `outward` winds every wall the wrong way.
fn room_with_lamp(outward: bool) -> Scene {
    room_with_lamp_and(outward, |_| {})
}

/// [`room_with_lamp`] with more faces added by `more`.
fn room_with_lamp_and(outward: bool, more: impl FnOnce(&mut SceneBuilder)) -> Scene {
    let wrong: &[usize] = if outward { &[0, 1, 2, 3, 4, 5] } else { &[] };
    let mut b = scenes::lamp_room(wrong, false);
    more(&mut b);
    b.build().unwrap()
}

#[test]
fn walls_wound_outward_bake_as_the_right_room_does() {
    // The staircase case: a room whose walls face out of it bakes black with the winding as
    // given (`--orient keep`: the lamp sees only backs), and with the default orientation
    // repair as the room wound right does. Both methods. The turned faces are the right
    // room's faces with a corner order rotated, so the patches and their rays differ a
    // little: surface means agree within 2 % (a tenth of the lamp's direct-light gradient
    // across a patch here), every wall is lit, and the report says what was turned.
    use radiosity::pipeline::Method as Way;
    for method in [Way::Matrix, Way::Hierarchical] {
        let s = radiosity::pipeline::Settings {
            method,
            max_edge: Some(0.5),
            gather: Gather::None,
            ..radiosity::pipeline::Settings::default()
        };
        let right = run(&room_with_lamp(false), &s);
        let repaired = run(&room_with_lamp(true), &s);
        let kept = run(
            &room_with_lamp(true),
            &radiosity::pipeline::Settings {
                orient: radiosity::scene::orient::Orient::Keep,
                ..s.clone()
            },
        );
        let mean = |out: &Outcome, material: u32| {
            let p = &out.patches;
            let (mut sum, mut area) = (0.0, 0.0);
            for i in 0..p.len() {
                if p.material[i] == material {
                    sum += out.solution.radiance[i][0] * p.area[i];
                    area += p.area[i];
                }
            }
            sum / area
        };
        let (r, f, k) = (mean(&right, 0), mean(&repaired, 0), mean(&kept, 0));
        assert!(r > 0.01, "{method}: the right room's walls are lit: {r}");
        assert!(
            (f - r).abs() < 2e-2 * r,
            "{method}: repaired {f} against right {r}"
        );
        assert!(
            k < 1e-3 * r,
            "{method}: kept, the walls face away and bake black: {k}"
        );
        let o = repaired.report.orientation.as_ref().unwrap();
        assert_eq!((o.surfaces_turned, o.faces_turned), (1, 12), "{o:?}");
        assert!(repaired
            .report
            .warnings
            .iter()
            .any(|w| w.contains("orientation repaired")));
        assert!(!right.report.orientation.as_ref().unwrap().changed());
    }
}

#[test]
fn a_screen_seen_from_both_sides_gets_a_back_side_of_its_own() {
    // A free-standing screen of one sheet (2 triangles, standing on the floor at x = 3, its
    // front towards the lamp) in the lamp room: the walls light its back too. By default
    // (`--orient auto`) it alone gets a back side, and the bake is the bake of the scene
    // with the screen made two-sided by hand, to the bit. Its back is lit (about a quarter
    // of its front here), the matrix and the hierarchy (with its display cut along the
    // contact lines: the screen meets the floor) agree on it within 3 % (the hierarchy's
    // refinement against the matrix's 0.5 m patches), and with the winding kept nothing
    // shows behind it. `--two-sided` is no oracle here: it makes the lamp emit upwards too.
    use radiosity::pipeline::{Method as Way, Settings};
    use radiosity::scene::orient::Orient;
    let scene = room_with_lamp_and(false, |b| {
        let m = b.material("screen", [0.7; 3], [0.0; 3]);
        let p = DVec3::new;
        b.quad(
            [
                p(3., 0., 0.5),
                p(3., 0., 3.5),
                p(3., 2., 3.5),
                p(3., 2., 0.5),
            ],
            m,
        );
    });
    let screen = scene
        .materials
        .iter()
        .position(|m| m.name == "screen")
        .unwrap() as u32;
    let mut by_hand = scene.clone();
    assert_eq!(by_hand.make_two_sided_where(|_, m| m.name == "screen"), 2);
    let mut backs = Vec::new();
    for (method, gather) in [
        (Way::Matrix, Gather::None),
        (Way::Hierarchical, Gather::Auto),
    ] {
        let s = Settings {
            method,
            max_edge: Some(0.5),
            gather,
            ..Settings::default()
        };
        let auto = run(&scene, &s);
        let hand = run(&by_hand, &s);
        let kept = run(
            &scene,
            &Settings {
                orient: Orient::Keep,
                ..s.clone()
            },
        );
        // Area-weighted mean radiance of the screen's side facing +x (back) or −x (front),
        // and that side's area.
        let side = |out: &Outcome, back: bool| {
            let p = &out.patches;
            let (mut sum, mut area) = (0.0, 0.0);
            for i in 0..p.len() {
                if p.material[i] == screen && (p.normal[i].x > 0.0) == back {
                    sum += out.solution.radiance[i][0] * p.area[i];
                    area += p.area[i];
                }
            }
            (if area > 0.0 { sum / area } else { 0.0 }, area)
        };
        let o = auto.report.orientation.as_ref().unwrap();
        assert_eq!(
            (o.two_sided_surfaces, o.two_sided_faces),
            (1, 2),
            "{method}: {o:?}"
        );
        assert!(o.summary().contains("'screen'"), "{}", o.summary());
        assert_eq!(auto.solution.radiance, hand.solution.radiance, "{method}");
        assert_eq!(
            auto.baked.vertex_radiance, hand.baked.vertex_radiance,
            "{method}"
        );
        let (back, area) = side(&auto, true);
        let (front, _) = side(&auto, false);
        assert!(
            (area - 6.0).abs() < 1e-9,
            "{method}: the back covers the screen: {area}"
        );
        assert!(
            back > 0.1 * front && back < 0.5 * front,
            "{method}: {back} vs {front}"
        );
        assert_eq!(side(&kept, true).1, 0.0, "{method}: kept, no back side");
        backs.push(back);
    }
    assert!((backs[0] - backs[1]).abs() < 0.03 * backs[0], "{backs:?}");
}
