//! Issue 6, usability: material overrides (`--reflectance`, `--emission`), `radiosity info`
//! and PLY scenes, at library level and through the binary.

use radiosity::pipeline::{self, Settings};
use radiosity::scene::{Override, Property, Scene};

use crate::support::{cornell, radiosity, stderr, temp_dir};

/// The Cornell box with `overrides` applied, solved coarsely (max-edge 110 mm).
fn cornell_with(overrides: &[Override]) -> pipeline::Outcome {
    let mut scene = Scene::load(cornell().as_ref()).unwrap();
    scene.apply_overrides(overrides).unwrap();
    let settings = Settings {
        max_edge: Some(110.0),
        ..Settings::default()
    };
    pipeline::solve_scene(&scene, &settings).unwrap()
}

#[test]
fn light_switched_off_by_override_gives_black_with_the_warning() {
    let off = Override::parse(Property::Emission, "light=0").unwrap();
    let out = cornell_with(&[off]);
    assert!(
        out.report
            .warnings
            .iter()
            .any(|w| w.contains("no emitters")),
        "{:?}",
        out.report.warnings
    );
    assert!(out.solution.radiance.iter().flatten().all(|&l| l == 0.0));
    assert!(out
        .baked
        .vertex_radiance
        .iter()
        .flatten()
        .all(|&l| l == 0.0));
}

#[test]
fn zero_reflectance_everywhere_leaves_exactly_the_emission() {
    let black = Override::parse(Property::Reflectance, "*=0").unwrap();
    let out = cornell_with(&[black]);
    let mut lit = 0;
    for (l, le) in out.solution.radiance.iter().zip(&out.patches.emission) {
        assert_eq!(l, le, "one bounce with ρ = 0 is no bounce");
        lit += usize::from(le[0] > 0.0);
    }
    assert!(lit > 0, "the light's patches keep Le = (17, 12, 4)");
    // The same scene without the override: reflected light reaches the walls.
    let plain = cornell_with(&[]);
    assert!(
        plain
            .solution
            .radiance
            .iter()
            .filter(|l| l[0] > 0.0)
            .count()
            > lit
    );
}

#[test]
fn cli_overrides_apply_and_unknown_materials_are_usage_errors() {
    let dir = temp_dir("overrides");
    let out = dir.join("c.ply");
    let out_s = out.to_str().unwrap();
    let input = cornell();
    let bake = |extra: &[&str]| {
        let mut args = vec!["bake", &input, "-o", out_s, "--max-edge", "110"];
        args.extend_from_slice(extra);
        radiosity(&args)
    };

    let o = bake(&["--emission", "light=0"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("warning: no emitters"),
        "{}",
        stderr(&o)
    );
    let p = radiosity::export::ply::read(&out).unwrap();
    assert!(p
        .vertex_radiance
        .unwrap()
        .iter()
        .flatten()
        .all(|&l| l == 0.0));

    // ρ = 0 everywhere, then the light's own Le raised: radiance is Le or 0, nothing between.
    let report = dir.join("r.json");
    let o = bake(&[
        "--reflectance",
        "*=0",
        "--emission",
        "light=2,3,4",
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(
        json["overrides"],
        serde_json::json!(["--reflectance *=0,0,0", "--emission light=2,3,4"])
    );
    let p = radiosity::export::ply::read(&out).unwrap();
    for r in p.face_radiance.unwrap() {
        assert!(r == [0.0; 3] || r == [2.0, 3.0, 4.0], "{r:?}");
    }

    std::fs::write(&out, b"precious").unwrap();
    let cases: [(&[&str], &[&str]); 4] = [
        (
            &["--reflectance", "nosuch=0.5"],
            &["--reflectance", "'nosuch'", "white, red, green, light"],
        ),
        (&["--emission", "light=-1"], &["--emission", "≥ 0"]),
        (
            &["--reflectance", "white=1.5"],
            &["--reflectance", "[0, 1]"],
        ),
        (&["--reflectance", "white"], &["MATERIAL=R,G,B"]),
    ];
    for (extra, needles) in cases {
        let o = bake(extra);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {err}");
        for n in needles {
            assert!(err.contains(n), "{extra:?}: {n} not in {err}");
        }
        assert_eq!(std::fs::read(&out).unwrap(), b"precious", "{extra:?}");
    }
    // render takes the same options.
    let png = dir.join("v.png");
    let o = radiosity(&[
        "render",
        &input,
        "-o",
        png.to_str().unwrap(),
        "--max-edge",
        "110",
        "--size",
        "8",
        "--emission",
        "nosuch=1",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("'nosuch'"), "{}", stderr(&o));
    assert!(!png.exists());
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn info_prints_counts_materials_power_and_patches_as_text_and_json() {
    let input = cornell();
    let o = radiosity(&["info", &input]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    for needle in [
        "vertices:     28",
        "triangles:    32",
        "max (556 548.8 559.2)",
        "light",
        "Le = (17 12 4)",
        "warnings:     0",
    ] {
        assert!(text.contains(needle), "{needle} not in:\n{text}");
    }

    let o = radiosity(&["info", &input, "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["triangles"], 32);
    assert_eq!(json["vertices"], 28);
    let names: Vec<&str> = json["materials"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["white", "red", "green", "light"]);
    assert_eq!(json["materials"][3]["emitter"], true);
    assert_eq!(json["materials"][0]["emitter"], false);
    // The light is 130 × 105 mm: Φ_red = π · 17 · 13650.
    let power = json["emitted_power"][0].as_f64().unwrap();
    let expected = std::f64::consts::PI * 17.0 * 13650.0;
    assert!(
        (power - expected).abs() < 1e-3 * expected,
        "{power} vs {expected}"
    );
    // The same count a default bake reports.
    let (patches, max_edge) = (
        json["default_patches"].as_u64().unwrap(),
        json["default_max_edge"].as_f64().unwrap(),
    );
    let scene = Scene::load(input.as_ref()).unwrap();
    let expected =
        radiosity::patch::subdivide(&scene, max_edge, radiosity::patch::DEFAULT_CREASE_DEGREES)
            .unwrap()
            .len();
    assert_eq!(patches as usize, expected);
    assert!((max_edge - json["diagonal"].as_f64().unwrap() / 16.0).abs() < 1e-9);

    // Overrides show up; no emitters is said plainly.
    let o = radiosity(&["info", &input, "--emission", "*=0"]);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(text.contains("emitters:     none"), "{text}");
    let o = radiosity(&["info", &input, "--json", "--reflectance", "nosuch=0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("'nosuch'"), "{}", stderr(&o));
    assert!(o.stdout.is_empty());

    let dir = temp_dir("info");
    let missing = dir.join("nope.obj");
    let o = radiosity(&["info", missing.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("nope.obj"), "{}", stderr(&o));
    let _ = std::fs::remove_dir_all(dir);
}

/// A grey floor quad facing up (ply_0) and an emitting triangle above it facing down (ply_1),
/// per-face materials, ASCII; the faces are on lines 23 and 24.
const LIT_PLY: &str = "ply\nformat ascii 1.0\n\
    element vertex 7\nproperty float x\nproperty float y\nproperty float z\n\
    element face 2\nproperty list uchar int vertex_indices\n\
    property float reflectance_r\nproperty float reflectance_g\nproperty float reflectance_b\n\
    property float emission_r\nproperty float emission_g\nproperty float emission_b\n\
    end_header\n\
    0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.2 0.2 1\n0.8 0.2 1\n0.5 0.8 1\n\
    4 0 1 2 3 0.5 0.5 0.5 0 0 0\n\
    3 4 6 5 0 0 0 1 2 3\n";

#[test]
fn ply_scenes_bake_render_and_describe() {
    let dir = temp_dir("ply-scene");
    let input = dir.join("lit.ply");
    std::fs::write(&input, LIT_PLY).unwrap();
    let input = input.to_str().unwrap();
    let out = dir.join("out.ply");
    let out_s = out.to_str().unwrap();

    let o = radiosity(&["bake", input, "-o", out_s, "--max-edge", "0.5"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let p = radiosity::export::ply::read(&out).unwrap();
    let faces = p.face_radiance.unwrap();
    // The emitter's patches (ρ = 0) carry exactly Le; the floor's are lit but dimmer.
    let lamp = faces.iter().filter(|r| **r == [1.0, 2.0, 3.0]).count();
    assert!(lamp > 0 && lamp < faces.len(), "{lamp} of {}", faces.len());
    assert!(faces
        .iter()
        .all(|r| *r == [1.0, 2.0, 3.0] || (r[0] > 0.0 && r[0] < 1.0)));

    // The generated names are override targets.
    let o = radiosity(&["bake", input, "-o", out_s, "--emission", "ply_1=0"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("warning: no emitters"),
        "{}",
        stderr(&o)
    );

    let o = radiosity(&["info", input, "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["triangles"], 3);
    assert_eq!(json["materials"][0]["name"], "ply_0");
    assert_eq!(
        json["materials"][1]["emission"],
        serde_json::json!([1.0, 2.0, 3.0])
    );

    // A baked PLY is a scene too (radiance ignored, default material), and render bakes a
    // PLY that is not a baked one.
    let o = radiosity(&["info", out_s]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("default"));
    let png = dir.join("v.png");
    let o = radiosity(&[
        "render",
        input,
        "-o",
        png.to_str().unwrap(),
        "--size",
        "16",
        "-q",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(png.exists());

    // Errors name the file and line, exit 2.
    let bad = dir.join("bad.ply");
    std::fs::write(&bad, LIT_PLY.replace("3 4 6 5", "3 4 6 9")).unwrap();
    let o = radiosity(&["bake", bad.to_str().unwrap(), "-o", out_s]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("bad.ply:24: face 1: vertex index 9 out of range"),
        "{}",
        stderr(&o)
    );
    assert!(!stderr(&o).contains("panicked"));
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn progress_is_hidden_off_a_terminal_and_verbose_adds_detail() {
    // Tests run with stderr piped: no bars, no escape codes, only the summary line. `-v` adds
    // one line per solve, per refinement round and the seconds per stage; `-q` removes the
    // summary but not what `-v` asked for.
    let dir = temp_dir("progress");
    let out = dir.join("c.ply");
    let input = cornell();
    let run = |extra: &[&str]| {
        let mut a = vec![
            "bake",
            &input,
            "-o",
            out.to_str().unwrap(),
            "--max-edge",
            "150",
        ];
        a.extend_from_slice(extra);
        let o = radiosity(&a);
        assert!(o.status.success(), "{}", stderr(&o));
        stderr(&o)
    };
    let plain = run(&[]);
    assert!(
        !plain.contains('\u{1b}') && !plain.contains("form factors ["),
        "{plain}"
    );
    assert_eq!(plain.lines().count(), 1, "{plain}");
    let verbose = run(&["-v"]);
    assert!(verbose.contains("refinement round 1"), "{verbose}");
    assert!(verbose.contains("seconds: load"), "{verbose}");
    assert!(
        verbose.contains("gauss-seidel") && verbose.contains("rays"),
        "{verbose}"
    );
    assert!(!verbose.contains('\u{1b}'), "{verbose}");
    let quiet = run(&["-q"]);
    assert!(quiet.is_empty(), "{quiet}");
    let _ = std::fs::remove_dir_all(dir);
}
