//! The generated scenes of the benchmarks (`radiosity::validation::scenes`) at the sizes they
//! are measured at: the triangles they promise, their lights, and none of the modelling
//! mistakes the loaders warn about. What belongs here: a generated scene's own promises; how
//! the pipeline does on it is the benchmarks' business.

use glam::DVec3;
use radiosity::scene::checks;
use radiosity::validation::scenes;

/// The office at the point-wise benchmark's smaller size: at least 50,000 triangles, each of
/// real area; both kinds of light (the ceiling panels facing down 1 cm under the ceiling,
/// the sky in the windows facing into the room); inside its room (the sky's openings
/// 20 cm deep in the wall y = 0); valid, without a coincident face or a flipped neighbour.
#[test]
fn office_has_its_triangles_both_lights_and_no_modelling_mistake() {
    let scene = scenes::office(50_000).unwrap();
    let n = scene.triangles.len();
    assert!(n >= 50_000, "{n} triangles");
    scene.validate().unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);

    let (lo, hi) = scene
        .positions
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    assert_eq!(
        (lo, hi),
        (DVec3::new(0.0, -0.2, 0.0), DVec3::new(24.0, 14.0, 3.0))
    );
    let diagonal = (hi - lo).length();
    assert!(checks::coincident_faces(&scene.positions, &scene.triangles, diagonal).is_empty());
    assert!(checks::inconsistent_winding(&scene.triangles).is_empty());

    let (mut lamps, mut sky) = (0, 0);
    for (t, tri) in scene.triangles.iter().enumerate() {
        // The smallest faces are the crowns' (about 1.4·10⁻⁴ m²); 10⁻⁶ m² is far above the
        // builder's zero-area threshold and far below any face meant to be there.
        let area = scene.triangle_area(t);
        assert!(area > 1e-6, "triangle {t}: area {area:e}");
        let [a, b, c] = tri.vertices.map(|v| scene.positions[v as usize]);
        let normal = (b - a).cross(c - a).normalize();
        let material = &scene.materials[tri.material as usize];
        match material.name.as_str() {
            "lamp" => {
                lamps += 1;
                assert!(normal.z < -0.999, "lamp triangle {t} faces {normal}");
                assert!([a, b, c].iter().all(|p| (p.z - 2.99).abs() < 1e-12));
            }
            "sky" => {
                sky += 1;
                assert!(normal.y > 0.999, "sky triangle {t} faces {normal}");
                assert!([a, b, c].iter().all(|p| p.y == -0.2));
            }
            name => assert!(!material.is_emitter(), "{name} emits"),
        }
    }
    // Twelve panels and eight windows, two triangles each.
    assert_eq!((lamps, sky), (24, 16));
}
