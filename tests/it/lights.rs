//! The sky and the sun through the whole pipeline, with both methods and the final gather:
//! closed forms where nothing is in the way (a tilted plate under a uniform sky, a floor under
//! the sun), a shadow where something is, and light that bounces.

use glam::DVec3;
use radiosity::gather::Gather;
use radiosity::pipeline::{self, Method, Outcome};
use radiosity::scene::{Environment, PointLight, Spot, Sun};
use radiosity::scene::{Scene, SceneBuilder, Up};
use radiosity::validation::scenes;

use crate::support::{assert_rel, run};

/// Settings with the environment `env`, the method, a coarse mesh and the full gather.
fn lit_by(env: Environment, method: Method) -> pipeline::Settings {
    pipeline::Settings {
        method,
        max_edge: Some(0.3),
        environment: env,
        gather: Gather::Full,
        ..pipeline::Settings::default()
    }
}

/// A unit square plate of reflectance `rho`, tilted `degrees` from facing up (z up) about
/// the x axis, nothing else.
fn plate(degrees: f64, rho: f64) -> Scene {
    let t = degrees.to_radians();
    let mut b = SceneBuilder::new();
    let m = b.material("plate", [rho; 3], [0.0; 3]);
    let v = DVec3::new(0.0, t.cos(), t.sin());
    b.quad([DVec3::ZERO, DVec3::X, DVec3::X + v, v], m);
    b.build().unwrap()
}

/// A 2 × 2 floor at z = 0 facing up (z up), ρ = 0.5, centred on the origin: material 0.
fn floor(b: &mut SceneBuilder) {
    let m = b.material("floor", [0.5; 3], [0.0; 3]);
    let p = |x: f64, y: f64| DVec3::new(x, y, 0.0);
    b.quad([p(-1., -1.), p(1., -1.), p(1., 1.), p(-1., 1.)], m);
}

/// Every patch's and every output vertex's radiance (red channel).
fn values(out: &Outcome) -> (Vec<f64>, Vec<f64>) {
    let patches = out.solution.radiance.iter().map(|l| l[0]).collect();
    let vertices = out.baked.vertex_radiance.iter().map(|l| l[0]).collect();
    (patches, vertices)
}

#[test]
fn a_tilted_plate_under_a_uniform_sky_has_the_closed_form() {
    // E = π L_sky (1 + cos θ)/2, so L = ρ L_sky (1 + cos θ)/2 on every patch and every vertex,
    // exactly: the sky is estimated as its unoccluded closed form times the open share of the
    // rays above the horizon, and nothing is in the way.
    let env = Environment {
        sky: [2.0, 1.0, 0.5],
        up: Up::Z,
        ..Environment::default()
    };
    for method in [Method::Matrix, Method::Hierarchical] {
        for degrees in [0.0, 45.0, 100.0, 170.0] {
            let out = run(&plate(degrees, 0.6), &lit_by(env.clone(), method));
            let exact = 0.6 * 2.0 * (1.0 + f64::to_radians(degrees).cos()) / 2.0;
            let (patches, vertices) = values(&out);
            for (what, list) in [("patch", patches), ("vertex", vertices)] {
                for l in list {
                    assert!((l - exact).abs() < 1e-12, "{method} {degrees}° {what}: {l}");
                }
            }
            assert!(out.report.warnings.is_empty(), "{:?}", out.report.warnings);
        }
    }
}

#[test]
fn sky_and_sun_light_bounces_and_both_methods_agree() {
    // A courtyard: a floor and two walls facing each other, open above and at both ends, under
    // a uniform sky and a low sun. The walls see the floor and each other, so their light is
    // more than their direct light; the two methods agree on each surface's mean (their
    // discretisations differ: 3 % is a few times the gap measured on the Cornell box).
    let scene = scenes::courtyard([0.7; 3]).unwrap();
    let env = scenes::courtyard_light();
    let mean_by_wall = |out: &Outcome| {
        let p = &out.patches;
        let mut sums = [(0.0, 0.0); 3];
        for i in 0..p.len() {
            let n = p.normal[i];
            let k = if n.z > 0.5 {
                0
            } else if n.x > 0.5 {
                1
            } else {
                2
            };
            sums[k].0 += p.area[i] * out.solution.radiance[i][0];
            sums[k].1 += p.area[i];
        }
        sums.map(|(s, a)| s / a)
    };
    let matrix = run(&scene, &lit_by(env.clone(), Method::Matrix));
    let hierarchical = run(&scene, &lit_by(env.clone(), Method::Hierarchical));
    let (m, h) = (mean_by_wall(&matrix), mean_by_wall(&hierarchical));
    for k in 0..3 {
        assert_rel(&format!("surface {k}"), h[k], m[k], 0.03);
    }
    // Without bounces (Neumann, 0 terms: L = E, the direct light alone) every surface is
    // darker: each sees the others.
    let neumann = pipeline::Settings {
        solver: radiosity::solve::Settings {
            method: radiosity::solve::Method::Neumann,
            bounces: 0,
            ..Default::default()
        },
        ..lit_by(env, Method::Matrix)
    };
    let zero_bounces = mean_by_wall(&run(&scene, &neumann));
    for k in 0..3 {
        assert!(
            m[k] > 1.05 * zero_bounces[k],
            "surface {k}: {} with bounces, {} without",
            m[k],
            zero_bounces[k]
        );
    }
}

#[test]
fn a_point_light_over_a_plane_gives_i_cos_over_r_squared_and_a_spot_its_cone() {
    // A 2 × 2 floor (ρ = 0.5) and a point light 1 above (0.3, 0.2): every output vertex shows
    // ρ I cos θ / (π r²). The rays start 10⁻⁶ of the scene's extent above the surface, which
    // moves r and cos θ by about that much: 1e-5 relative.
    let mut b = SceneBuilder::new();
    floor(&mut b);
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let scene = b.build().unwrap();
    let at = p(0.3, 0.2, 1.0);
    let exact = |x: DVec3, i: f64| {
        let d = at - x;
        0.5 * i * (d.z / d.length()) / (d.length_squared() * std::f64::consts::PI)
    };
    let point = Environment {
        lights: vec![PointLight {
            position: at,
            intensity: [10.0; 3],
            spot: None,
        }],
        up: Up::Z,
        ..Environment::default()
    };
    // A spot straight down from the same place, full within 20° of its axis, none past 30°.
    let spot = Environment {
        lights: vec![PointLight {
            position: at,
            intensity: [10.0; 3],
            spot: Some(Spot {
                direction: -DVec3::Z,
                inner_degrees: 20.0,
                outer_degrees: 30.0,
            }),
        }],
        ..point.clone()
    };
    // The vertices' point values: no display refinement, whose chord correction moves them
    // (by design) to keep the light's integral over the triangles instead.
    let lit_by = |env, method| pipeline::Settings {
        gather_tolerance: 0.0,
        ..lit_by(env, method)
    };
    for method in [Method::Matrix, Method::Hierarchical] {
        let out = run(&scene, &lit_by(point.clone(), method));
        for (v, pos) in out.baked.positions.iter().enumerate() {
            let x = DVec3::from_array(*pos);
            let l = out.baked.vertex_radiance[v][0];
            assert_rel(
                &format!("{method} point light at {x}"),
                l,
                exact(x, 10.0),
                1e-5,
            );
        }
        let out = run(&scene, &lit_by(spot.clone(), method));
        let (mut inside, mut outside) = (0, 0);
        for (v, pos) in out.baked.positions.iter().enumerate() {
            let x = DVec3::from_array(*pos);
            let l = out.baked.vertex_radiance[v][0];
            let angle = (at - x).normalize().dot(DVec3::Z).acos().to_degrees();
            if angle < 20.0 {
                assert_rel(
                    &format!("{method} inside the cone at {x}"),
                    l,
                    exact(x, 10.0),
                    1e-5,
                );
                inside += 1;
            } else if angle > 30.0 {
                assert_eq!(l, 0.0, "{method} outside the cone at {x}");
                outside += 1;
            }
        }
        assert!(inside > 3 && outside > 3, "{inside} {outside}");
    }
}

/// A 2 × 2 floor (ρ = 0.5) and, 1 above its middle, a black 0.6 × 0.6 square of
/// transmittance `t`, under the sun at elevation 60° (azimuth 0: north, +y with z up): the
/// floor gets E cos 30°, and the square's shadow falls 1/tan 60° to the south of the point
/// below it. Lit floor points far from the shadow's edge: ρ E sin 60° / π exactly (4 shadow
/// rays, all open); points deep in the shadow: t times that, exactly (each shadow ray's share
/// is the square's t, not a chance of it; the square is black and the floor flat: no other
/// light). Both methods.
fn sun_over_a_square(t: f64) {
    let mut b = SceneBuilder::new();
    floor(&mut b);
    let square = b.material("square", [0.0; 3], [0.0; 3]);
    b.set_transmittance(square, t);
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let s = 0.3;
    b.quad(
        [p(-s, -s, 1.), p(-s, s, 1.), p(s, s, 1.), p(s, -s, 1.)],
        square,
    );
    let scene = b.build().unwrap();
    let env = Environment {
        sun: Some(Sun {
            azimuth_degrees: 0.0,
            elevation_degrees: 60.0,
            irradiance: [1000.0; 3],
        }),
        up: Up::Z,
        ..Environment::default()
    };
    let lit = 0.5 * 1000.0 * 60f64.to_radians().sin() / std::f64::consts::PI;
    let shadow_centre = p(0.0, -1.0 / 60f64.to_radians().tan(), 0.0);
    for method in [Method::Matrix, Method::Hierarchical] {
        // Point values at the vertices: no display refinement and no fits (which make a
        // vertex show the light's local mean: the fit to the tested midpoints reaches a lit
        // corner a metre from the shadow at 2·10⁻⁶).
        let settings = pipeline::Settings {
            gather_tolerance: 0.0,
            ..lit_by(env.clone(), method)
        };
        let out = run(&scene, &settings);
        let baked = &out.baked;
        let (mut in_light, mut in_shadow) = (0, 0);
        for (v, pos) in baked.positions.iter().enumerate() {
            let x = DVec3::from_array(*pos);
            if x.z != 0.0 {
                continue;
            }
            let d = (x - shadow_centre).abs();
            let l = baked.vertex_radiance[v][0];
            // The penumbra is 0.53° wide: about 0.01 at this distance.
            if d.x.max(d.y) > s + 0.05 {
                assert_rel(&format!("{method} lit vertex at {x}"), l, lit, 1e-12);
                in_light += 1;
            } else if d.x.max(d.y) < s - 0.05 {
                if t == 0.0 {
                    assert_eq!(l, 0.0, "{method} vertex in the shadow at {x}");
                } else {
                    // The transmittance is held to 2⁻³² (its hash threshold).
                    assert_rel(
                        &format!("{method} vertex under the square at {x}"),
                        l,
                        t * lit,
                        1e-9,
                    );
                }
                in_shadow += 1;
            }
        }
        assert!(in_light > 10 && in_shadow > 3, "{in_light} {in_shadow}");
        if t > 0.0 {
            let said = &out.report.warnings;
            assert!(
                said.iter()
                    .any(|w| w.contains("partly transparent") && w.contains("square")),
                "{said:?}"
            );
        }
    }
}

#[test]
fn the_sun_lights_a_floor_and_an_occluder_casts_its_shadow() {
    sun_over_a_square(0.0);
}

#[test]
fn the_sun_through_a_pane_gives_its_transmittance_times_the_open_light() {
    sun_over_a_square(0.6);
}

#[test]
fn an_emitting_screen_sends_only_its_covered_share() {
    // A floor (ρ = 0.5) under a 1 × 1 emitting square facing it, 0.5 above, nothing behind:
    // a square of Le = 1 that lets half the light through (t = 0.5) covers half its area, so
    // the floor must receive exactly what an opaque square of Le = 0.5 sends it. Counting the
    // screen's form factor in full (not its covered share) would double the floor's light.
    // Both methods, the patches' solution and the gathered vertices. Tolerance 2e-2: the
    // transparent square's light reaches the gather's vertices by chance through its hashed
    // rays (each vertex's rays see it or pass it), a few 1e-3 of noise here, against the
    // factor 2 the test guards.
    let scene = |t: f64, le: f64| {
        let mut b = SceneBuilder::new();
        floor(&mut b);
        let lamp = b.material("lamp", [0.0; 3], [le; 3]);
        b.set_transmittance(lamp, t);
        let p = |x: f64, y: f64| DVec3::new(x, y, 0.5);
        let s = 0.5;
        b.quad([p(-s, -s), p(-s, s), p(s, s), p(s, -s)], lamp);
        b.build().unwrap()
    };
    for method in [Method::Matrix, Method::Hierarchical] {
        let settings = pipeline::Settings {
            method,
            max_edge: Some(0.3),
            gather: Gather::Full,
            gather_tolerance: 0.0,
            ..pipeline::Settings::default()
        };
        let screen = run(&scene(0.5, 1.0), &settings);
        let opaque = run(&scene(0.0, 0.5), &settings);
        let floor_mean = |out: &Outcome, vertices: bool| {
            let (mut sum, mut n) = (0.0, 0);
            if vertices {
                for (v, pos) in out.baked.positions.iter().enumerate() {
                    if pos[2] == 0.0 {
                        sum += out.baked.vertex_radiance[v][0];
                        n += 1;
                    }
                }
            } else {
                for (i, l) in out.solution.radiance.iter().enumerate() {
                    if out.patches.centroid[i].z == 0.0 {
                        sum += l[0] * out.patches.area[i];
                        n += 1;
                    }
                }
            }
            (sum, n)
        };
        for vertices in [false, true] {
            let (a, na) = floor_mean(&screen, vertices);
            let (b, nb) = floor_mean(&opaque, vertices);
            assert!(na > 10 && na == nb, "{na} {nb}");
            let what = if vertices { "vertices" } else { "patches" };
            assert_rel(&format!("{method} floor {what}"), a, b, 2e-2);
        }
    }
}

#[test]
fn an_emitter_seen_through_a_pane_gives_its_share() {
    // The floor under an emitting square (Le = 1, facing down, 1 above), with a pane of
    // t = 0.5 halfway between them, larger than both: every bit of the emitter's light
    // crosses the pane, so the floor gets exactly half of what it gets without it. Both
    // methods, the solution's patches and the gathered vertices (whose emitter light, with a
    // pane in the way, comes from shadow rays that pass it by chance, not from the exact
    // visible pieces that would treat it as opaque). Tolerance 3e-2: those rays' noise,
    // averaged over the floor's vertices, is well under 1 %; an opaque pane gives 0.
    let scene = |pane: bool| {
        let mut b = SceneBuilder::new();
        floor(&mut b);
        let lamp = b.material("lamp", [0.0; 3], [1.0; 3]);
        let glass = b.material("glass", [0.0; 3], [0.0; 3]);
        b.set_transmittance(glass, 0.5);
        let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        let s = 0.5;
        b.quad(
            [p(-s, -s, 1.), p(-s, s, 1.), p(s, s, 1.), p(s, -s, 1.)],
            lamp,
        );
        if pane {
            let g = 3.0;
            b.quad(
                [p(-g, -g, 0.5), p(-g, g, 0.5), p(g, g, 0.5), p(g, -g, 0.5)],
                glass,
            );
        }
        b.build().unwrap()
    };
    for method in [Method::Matrix, Method::Hierarchical] {
        let settings = pipeline::Settings {
            method,
            max_edge: Some(0.3),
            gather: Gather::Full,
            gather_tolerance: 0.0,
            // The same mesh for both bakes: their vertices compare one to one.
            refine_rounds: 0,
            ..pipeline::Settings::default()
        };
        let open = run(&scene(false), &settings);
        let glazed = run(&scene(true), &settings);
        // The floor's light: the patches' integral, or the displayed one (each floor face's
        // area times the mean of its vertices' values: the two bakes' meshes differ where
        // the pane's contact-free display is cut).
        let floor_sum = |out: &Outcome, vertices: bool| -> f64 {
            if vertices {
                let m = &out.baked;
                m.faces
                    .iter()
                    .filter(|f| f.iter().all(|&v| m.positions[v as usize][2] == 0.0))
                    .map(|f| {
                        let p = f.map(|v| DVec3::from_array(m.positions[v as usize]));
                        let area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
                        area * f
                            .iter()
                            .map(|&v| m.vertex_radiance[v as usize][0])
                            .sum::<f64>()
                            / 3.0
                    })
                    .sum()
            } else {
                (0..out.patches.len())
                    .filter(|&i| out.patches.centroid[i].z == 0.0)
                    .map(|i| out.solution.radiance[i][0] * out.patches.area[i])
                    .sum()
            }
        };
        for vertices in [false, true] {
            let what = if vertices { "vertices" } else { "patches" };
            let (a, b) = (floor_sum(&glazed, vertices), floor_sum(&open, vertices));
            assert!(b > 0.0);
            assert_rel(
                &format!("{method} floor {what} through the pane"),
                a,
                0.5 * b,
                3e-2,
            );
        }
    }
}
