//! Materials changed after loading (`Scene::apply_overrides`, the `reflectance` and `emission`
//! overrides) solved through the pipeline: what the light does when a material changes.
//! What belongs here: the physics of overrides; their parsing and errors are unit tests in
//! `src/scene/overrides.rs`, their command-line form is tested in the cli package.

use radiosity::pipeline::{self, Settings};
use radiosity::scene::{Override, Property, Scene};

use crate::support::cornell;

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
