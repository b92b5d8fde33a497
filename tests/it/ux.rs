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
    let o = bake(&["--reflectance", "*=0", "--emission", "light=2,3,4"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
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
