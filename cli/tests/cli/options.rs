//! Options that cut across commands, through the binary: material overrides
//! (`--reflectance`, `--emission`) and their errors, progress and verbosity (`-q`, `-v`).

use crate::support::{bake, bake_cornell, cornell, radiosity, stderr, temp_dir};

#[test]
fn cli_overrides_apply_and_unknown_materials_are_usage_errors() {
    let dir = temp_dir("overrides");
    let out = dir.join("c.ply");
    let bake = |extra: &[&str]| bake_cornell(&out, extra);

    let o = bake(&["--emission", "light=0"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("warning: no emitters"),
        "{}",
        stderr(&o)
    );
    let p = radiosity::io::ply::read(&out).unwrap();
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
        serde_json::json!(["reflectance *=0,0,0", "emission light=2,3,4"])
    );
    let p = radiosity::io::ply::read(&out).unwrap();
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
        &cornell(),
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
}

#[test]
fn progress_is_hidden_off_a_terminal_and_verbose_adds_detail() {
    // Tests run with stderr piped: no bars, no escape codes, only the summary line. `-v` adds
    // one line per solve, per refinement round and the seconds per stage; `-q` removes the
    // summary but not what `-v` asked for.
    let dir = temp_dir("progress");
    let out = dir.join("c.ply");
    let run = |extra: &[&str]| {
        let o = bake(&cornell(), &out, &[&["--max-edge", "150"], extra].concat());
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
}

/// `--method hierarchical` through the binary: a bake with its own summary and report, the
/// matrix-only cache refused, bad settings named by their flags, and the generated hall.
#[test]
fn hierarchical_method_bakes_and_checks_its_settings() {
    let dir = temp_dir("hierarchical");
    let out = dir.join("h.ply");
    let report = dir.join("h.json");
    let hierarchical = |extra: &[&str]| {
        bake(
            &cornell(),
            &out,
            &[&["--method", "hierarchical"], extra].concat(),
        )
    };
    let o = hierarchical(&["--report", report.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stderr(&o).contains(" links ("), "{}", stderr(&o));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["method"], "hierarchical");
    let leaves = json["hierarchical"]["leaves"].as_u64().unwrap();
    assert!(
        leaves > 32,
        "the Cornell box's 32 triangles were refined: {json}"
    );
    let p = radiosity::io::ply::read(&out).unwrap();
    // One face per leaf, and more where the display refinement split them.
    assert!(p.faces.len() as u64 >= json["patches"].as_u64().unwrap());
    assert_eq!(p.positions.len() as u64, json["vertices"].as_u64().unwrap());

    for (extra, flag) in [
        (&["--cache", dir.to_str().unwrap()][..], "--cache"),
        (&["--epsilon", "0"][..], "--epsilon"),
        (&["--min-area", "2"][..], "--min-area"),
        (&["--link-rays", "0"][..], "--link-rays"),
        (&["--display-budget", "0"][..], "--display-budget"),
        (&["--display-budget", "65"][..], "--display-budget"),
    ] {
        let o = hierarchical(extra);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(flag), "{extra:?}: {}", stderr(&o));
    }

    let hall = dir.join("hall.obj");
    let o = radiosity(&[
        "generate",
        "hall",
        "--triangles",
        "3000",
        "-o",
        hall.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let scene = radiosity::scene::Scene::load(&hall).unwrap();
    assert!(scene.triangles.len() >= 3000, "{}", scene.triangles.len());
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert!(scene.has_emitters());
}

/// The point-wise benchmark's rooms through `generate` (the office with `--triangles`): each
/// OBJ loads back with the library's triangles and materials, lights included, and without a
/// warning (before the winding check judged only edges with two faces, the kitchen's two
/// counter blocks, which share an edge, were reported as flipped).
#[test]
fn generated_rooms_load_back_as_built_without_warnings() {
    use radiosity::validation::scenes;
    let area = |s: &radiosity::scene::Scene| -> f64 {
        (0..s.triangles.len()).map(|t| s.triangle_area(t)).sum()
    };
    let dir = temp_dir("rooms");
    for (kind, size, built) in [
        ("living-room", None, scenes::living_room().unwrap()),
        ("two-rooms", None, scenes::two_rooms().unwrap()),
        ("study", None, scenes::study().unwrap()),
        ("attic", None, scenes::attic().unwrap()),
        ("kitchen", None, scenes::kitchen().unwrap()),
        ("office", Some("20000"), scenes::office(20_000).unwrap()),
        (
            "office-daylit",
            Some("20000"),
            scenes::office_daylit(20_000).unwrap(),
        ),
    ] {
        let path = dir.join(format!("{kind}.obj"));
        let mut args = vec!["generate", kind, "-o", path.to_str().unwrap()];
        if let Some(n) = size {
            args.extend(["--triangles", n]);
        }
        let o = radiosity(&args);
        assert_eq!(o.status.code(), Some(0), "{kind}: {}", stderr(&o));
        assert!(built.warnings.is_empty(), "{kind}: {:?}", built.warnings);
        let loaded = radiosity::scene::Scene::load(&path).unwrap();
        assert!(loaded.warnings.is_empty(), "{kind}: {:?}", loaded.warnings);
        assert_eq!(loaded.triangles.len(), built.triangles.len(), "{kind}");
        // Positions pass through f32 in the OBJ (relative rounding 6·10⁻⁸ a coordinate), so
        // the total areas agree to about 10⁻⁷ relative; 10⁻⁶ allows for it, and a lost or
        // doubled face (≥ 10⁻⁵ of any room's area, but for the office's small faces, which
        // the count above catches) still fails.
        let (a, b) = (area(&loaded), area(&built));
        assert!((a - b).abs() < 1e-6 * b, "{kind}: {a} ≠ {b}");
        // The daylit office is lit by the bake's sky and sun alone.
        assert_eq!(loaded.has_emitters(), kind != "office-daylit", "{kind}");
    }
}
