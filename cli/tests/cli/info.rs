//! `radiosity info`: counts, materials, emitted power, camera and the default patch count,
//! as text and JSON, with overrides; errors exit 2.

use radiosity::scene::Scene;

use crate::support::{cornell, radiosity, stderr, temp_dir};

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
    // The same count a default bake starts from (contact lines made edges, then subdivided).
    let (patches, max_edge) = (
        json["default_patches"].as_u64().unwrap(),
        json["default_max_edge"].as_f64().unwrap(),
    );
    let scene = Scene::load(input.as_ref()).unwrap();
    let (scene, _) = radiosity::mesh::split_contacts(&scene);
    let expected =
        radiosity::mesh::subdivide(&scene, max_edge, radiosity::mesh::DEFAULT_CREASE_DEGREES)
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
