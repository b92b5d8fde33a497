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
        json["estimate"]["patches"].as_u64().unwrap(),
        json["estimate"]["max_edge"].as_f64().unwrap(),
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
}

#[test]
fn info_estimates_the_bake_its_options_describe_and_bake_refuses_what_would_not_fit() {
    // info with the bake's options counts the patches the bake starts from: a bake with the
    // same options and no refinement reports that many.
    let input = cornell();
    let dir = temp_dir("estimate");
    let out = dir.join("lit.ply");
    let report = dir.join("report.json");
    let options = ["--max-edge", "150", "--refine", "0", "--gather", "none"];
    let mut args = vec!["info", &input, "--json"];
    args.extend(options);
    let o = radiosity(&args);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let e = &json["estimate"];
    assert_eq!(e["method"], "matrix");
    assert_eq!(e["max_patches"], e["patches"], "no refinement");
    assert_eq!(e["gather"], "none");
    let (out_s, report_s) = (out.to_str().unwrap(), report.to_str().unwrap());
    let mut args = vec!["bake", &input, "-o", out_s, "--report", report_s, "-q"];
    args.extend(options);
    let o = radiosity(&args);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["patches"], e["patches"]);
    assert_eq!(r["estimate"]["patches"], e["patches"]);
    // The estimate is an upper bound on the matrix method's memory: the run stayed below it.
    let peak = r["peak_memory_bytes"].as_f64().unwrap();
    assert!(peak < e["memory_bytes"].as_f64().unwrap(), "{peak} {e}");

    // A bound below the estimate: refused before any work, exit 2, nothing written, and the
    // message names the input, the need and what would lower it.
    std::fs::remove_file(&out).unwrap();
    let mut args = vec!["bake", &input, "-o", out_s, "--max-memory", "1M"];
    args.extend(options);
    let o = radiosity(&args);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    for word in ["cornell_box.obj", "--max-memory", "--max-edge", "MiB"] {
        assert!(err.contains(word), "{word}: {err}");
    }
    assert!(!out.exists());
    // Hierarchical (the Cornell box has too few roots for a pilot): a bound above the estimate
    // but below what detailed interiors have needed (HIERARCHICAL_MEMORY_SPREAD × it) runs,
    // warned of before it starts; a bound above that runs without the warning.
    let o = radiosity(&["info", &input, "--method", "hierarchical", "--json"]);
    let info: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let need = info["estimate"]["memory_bytes"].as_f64().unwrap();
    let spread = radiosity::pipeline::estimate::HIERARCHICAL_MEMORY_SPREAD;
    for (bound, warned) in [(2.0 * need, true), (1.1 * spread * need, false)] {
        let bound = format!("{}", bound.round());
        let args = [
            "bake",
            &input,
            "-o",
            out_s,
            "--method",
            "hierarchical",
            "--max-memory",
            &bound,
        ];
        let o = radiosity(&args);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        assert_eq!(
            stderr(&o).contains("bakes have needed up to"),
            warned,
            "{bound}: {}",
            stderr(&o)
        );
    }
    // Sizes read with binary units; anything else is a usage error.
    for bad in ["4Q", "-1G", "lots"] {
        let o = radiosity(&["bake", &input, "-o", out_s, "--max-memory", bad]);
        assert_eq!(o.status.code(), Some(2), "{bad}");
        assert!(stderr(&o).contains("--max-memory"), "{}", stderr(&o));
    }
}

/// `info` names the method and the final gather the bake of the same scene with the same
/// options takes (both decide on the patches after the contact lines are cut).
#[test]
fn info_names_the_method_and_gather_the_bake_takes() {
    let input = cornell();
    let dir = temp_dir("info-as-bake");
    for extra in [&[][..], &["--max-edge", "25"][..]] {
        let mut args = vec!["info", input.as_str(), "--json"];
        args.extend_from_slice(extra);
        let o = radiosity(&args);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let info: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();

        let report = dir.join(format!("report{}.json", extra.len()));
        let report_arg = report.display().to_string();
        let mut options = vec!["--report", report_arg.as_str()];
        options.extend_from_slice(extra);
        let out = dir.join(format!("lit{}.ply", extra.len()));
        let o = crate::support::bake(&input, &out, &options);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let baked: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        for field in ["method", "gather"] {
            assert_eq!(
                info["estimate"][field], baked[field],
                "{field} with {extra:?}: info vs the bake's report"
            );
        }
    }
}
