//! `radiosity bake` end to end: the Cornell box to PLY and OBJ, read back; the same bytes for
//! any thread count; the usage errors of bake's options lose nothing; non-convergence exits 3;
//! a generated scene bakes to its closed form; the form-factor cache.

use radiosity::io::{obj, ply};

use crate::support::{bake_cornell as bake, cornell, radiosity, stderr, temp_dir};

#[test]
fn bake_cornell_to_ply_and_obj_and_read_back() {
    let dir = temp_dir("bake");
    let (ply_path, obj_path, report) = (dir.join("c.ply"), dir.join("c.obj"), dir.join("r.json"));
    let o = bake(&ply_path, &["--report", report.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("panicked"));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let patches = json["patches"].as_u64().unwrap() as usize;
    let vertices = json["vertices"].as_u64().unwrap() as usize;
    assert!(json["form_factors"]["rays_cast"].as_u64().unwrap() > 0);
    assert!(json["converged"].as_bool().unwrap());
    for stage in [
        "load",
        "patches",
        "bvh",
        "form_factors",
        "solve",
        "bake",
        "write",
    ] {
        assert!(json["seconds"][stage].as_f64().unwrap() >= 0.0, "{stage}");
    }
    let p = ply::read(&ply_path).unwrap();
    // One face per patch, and more where the display refinement split them.
    assert!(p.faces.len() >= patches, "{} faces", p.faces.len());
    assert_eq!(p.positions.len(), vertices);
    let vr = p.vertex_radiance.as_ref().unwrap();
    let fr = p.face_radiance.as_ref().unwrap();
    assert!(vr.iter().flatten().all(|x| x.is_finite() && *x >= 0.0));
    // The light's faces carry at least Le = (17, 12, 4); nothing else comes near.
    let brightest = fr.iter().map(|r| r[0]).fold(0.0f32, f32::max);
    assert!(brightest >= 17.0, "{brightest}");
    // Colour bleeding: the white blocks' and floor's vertices near the red wall (x ≈ 550) are
    // redder than those near the green wall (x ≈ 0): compare mean red/green ratios.
    let ratio = |sel: &dyn Fn(f64) -> bool| {
        let (mut r, mut g) = (0.0, 0.0);
        for (v, rad) in p.positions.iter().zip(vr) {
            if v[1] < 1.0 && sel(v[0]) {
                r += rad[0];
                g += rad[1];
            }
        }
        r / g
    };
    assert!(ratio(&|x| x > 450.0) > ratio(&|x| x < 100.0) * 1.1);

    let o = bake(&obj_path, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let q = obj::read(&obj_path).unwrap();
    assert_eq!(q.faces, p.faces);
    assert_eq!(q.positions.len(), p.positions.len());
    // Same automatic exposure ⇒ the same 8-bit colours in both formats.
    assert_eq!(q.colours, p.colours);
}

#[test]
fn output_is_identical_for_one_and_two_threads() {
    let dir = temp_dir("threads");
    let (a, b) = (dir.join("a.ply"), dir.join("b.ply"));
    // The final gather (the default, `full`) once, with the default estimator; then each
    // other estimator and every solver without it (the gather reads only the solution, so its
    // own determinism does not depend on them), which keeps the 14 bakes' time down.
    for estimator in ["contour", "area", "hemisphere"] {
        let gather: &[&str] = if estimator == "contour" {
            &[]
        } else {
            &["--gather", "none"]
        };
        let ff = [&["--form-factors", estimator, "--rays", "64"][..], gather].concat();
        assert!(bake(&a, &[&ff[..], &["--threads", "1"]].concat())
            .status
            .success());
        assert!(bake(&b, &[&ff[..], &["--threads", "2"]].concat())
            .status
            .success());
        assert_eq!(
            std::fs::read(&a).unwrap(),
            std::fs::read(&b).unwrap(),
            "{estimator}"
        );
    }
    // Every solver, including the parallel Gauss–Seidel sweep and CG's reductions.
    for solver in ["jacobi", "gauss-seidel", "cg", "southwell"] {
        let s = ["--solver", solver, "--omega", "1.2", "--gather", "none"];
        assert!(bake(&a, &[&s[..], &["--threads", "1"]].concat())
            .status
            .success());
        assert!(bake(&b, &[&s[..], &["--threads", "2"]].concat())
            .status
            .success());
        assert_eq!(
            std::fs::read(&a).unwrap(),
            std::fs::read(&b).unwrap(),
            "{solver}"
        );
    }
}

#[test]
fn bad_input_is_a_clear_error_and_loses_nothing() {
    let dir = temp_dir("errors");
    let out = dir.join("keep.ply");
    std::fs::write(&out, b"precious").unwrap();
    let missing = dir.join("nope.obj");
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![
                "bake".into(),
                missing.display().to_string(),
                "-o".into(),
                out.display().to_string(),
            ],
            "nope.obj",
        ),
        (
            vec![
                "bake".into(),
                dir.display().to_string(),
                "-o".into(),
                out.display().to_string(),
            ],
            "radiosity-cli",
        ),
        (
            vec![
                "bake".into(),
                cornell(),
                "-o".into(),
                dir.join("x.stl").display().to_string(),
            ],
            "x.stl",
        ),
        (
            vec![
                "bake".into(),
                cornell(),
                "-o".into(),
                out.display().to_string(),
                "--max-edge".into(),
                "0".into(),
            ],
            "--max-edge",
        ),
        (
            vec![
                "bake".into(),
                cornell(),
                "-o".into(),
                out.display().to_string(),
                "--samples".into(),
                "0".into(),
            ],
            "--samples",
        ),
        (
            vec![
                "bake".into(),
                cornell(),
                "-o".into(),
                out.display().to_string(),
                "--tolerance".into(),
                "-1".into(),
            ],
            "--tolerance",
        ),
        (
            vec![
                "bake".into(),
                cornell(),
                "-o".into(),
                dir.join("missing/x.ply").display().to_string(),
            ],
            "missing",
        ),
    ];
    for (args, needle) in cases {
        let args: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
        let o = radiosity(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains(needle),
            "{args:?}: stderr does not name {needle:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
        assert_eq!(
            std::fs::read(&out).unwrap(),
            b"precious",
            "{args:?} touched the output"
        );
    }
}

#[test]
fn non_convergence_exits_non_zero_with_a_warning() {
    let dir = temp_dir("noconv");
    let out = dir.join("c.ply");
    let o = bake(&out, &["--max-iterations", "1", "--tolerance", "1e-12"]);
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(stderr(&o).contains("not converged"));
}

#[test]
fn generated_sphere_bakes_to_the_closed_form() {
    // generate → bake from the file → read the PLY back: every wall face's radiance after one
    // bounce is ρ·mean(Le). Tolerance as in `verify` (3e-3 for the area-weighted mean of the
    // per-face relative errors; measured 1.6e-3): this holds only if the file's shared
    // vertices are welded so the receiving cosine uses the smooth sphere's normals (flat
    // facets give 4.9e-3).
    let dir = temp_dir("generate");
    let obj = dir.join("sphere.obj");
    let o = radiosity(&[
        "generate",
        "integrating-sphere",
        "-o",
        obj.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.join("sphere.mtl").exists());
    let ply_path = dir.join("sphere.ply");
    let o = radiosity(&[
        "bake",
        obj.to_str().unwrap(),
        "-o",
        ply_path.to_str().unwrap(),
        "--max-edge",
        "1",
        "--solver",
        "neumann",
        "--bounces",
        "1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let p = ply::read(&ply_path).unwrap();
    let fr = p.face_radiance.unwrap();
    let area = |f: &[u32; 3]| {
        let [a, b, c] = f.map(|v| glam::DVec3::from_array(p.positions[v as usize]));
        0.5 * (b - a).cross(c - a).length()
    };
    // Emitting faces carry Le = 1 plus their reflection: radiance ≥ 1.
    let emitting = |l: &[f32; 3]| l[0] >= 1.0;
    let total: f64 = p.faces.iter().map(area).sum();
    let emitted: f64 = p
        .faces
        .iter()
        .zip(&fr)
        .filter(|(_, l)| emitting(l))
        .map(|(f, _)| area(f))
        .sum();
    let expected = 0.5 * emitted / total;
    let (mut wall_area, mut error_sum) = (0.0, 0.0);
    for (f, l) in p.faces.iter().zip(&fr).filter(|(_, l)| !emitting(l)) {
        wall_area += area(f);
        error_sum += area(f) * (l[0] as f64 - expected).abs() / expected;
    }
    let err = error_sum / wall_area;
    assert!(err < 3e-3, "mean per-face relative error {err:.3e}");
}

#[test]
fn form_factor_cache_serves_relighting_and_survives_corruption() {
    let dir = temp_dir("cache");
    let cache = dir.join("ff");
    let c = cache.to_str().unwrap();
    let report = |name: &str| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(dir.join(name)).unwrap()).unwrap()
    };
    let run = |out: &str, json: &str, extra: &[&str]| {
        let o = bake(
            &dir.join(out),
            &[
                &[
                    "--refine",
                    "0",
                    "--report",
                    dir.join(json).to_str().unwrap(),
                ][..],
                extra,
            ]
            .concat(),
        );
        assert!(o.status.success(), "{}", stderr(&o));
        o
    };
    // First run stores, second reads: same bytes out, no form-factor time.
    run("a.ply", "a.json", &["--cache", c]);
    run("b.ply", "b.json", &["--cache", c]);
    let (a, b) = (report("a.json"), report("b.json"));
    assert_eq!(a["cache"]["stored"], 1);
    assert_eq!(b["cache"]["hits"], 1);
    assert!(b["cache"]["seconds_saved"].as_f64().unwrap() > 0.0);
    assert_eq!(b["seconds"]["form_factors"].as_f64().unwrap(), 0.0);
    assert_eq!(
        std::fs::read(dir.join("a.ply")).unwrap(),
        std::fs::read(dir.join("b.ply")).unwrap()
    );
    // Relighting (other emission and reflectance) hits the cache and gives exactly what a
    // run without the cache gives.
    let relight = ["--emission", "light=20,10,2", "--reflectance", "red=0.3"];
    run("c.ply", "c.json", &[&relight[..], &["--cache", c]].concat());
    assert_eq!(report("c.json")["cache"]["hits"], 1);
    run("d.ply", "d.json", &relight);
    assert_eq!(
        std::fs::read(dir.join("c.ply")).unwrap(),
        std::fs::read(dir.join("d.ply")).unwrap()
    );
    // A corrupted cache file is a warning and a recomputation, and is replaced.
    let file = std::fs::read_dir(&cache)
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let mut bytes = std::fs::read(&file).unwrap();
    bytes.truncate(bytes.len() / 2);
    std::fs::write(&file, &bytes).unwrap();
    let o = run("e.ply", "e.json", &["--cache", c]);
    assert!(
        stderr(&o).contains("cache") || report("e.json")["warnings"].to_string().contains("cache")
    );
    assert_eq!(report("e.json")["cache"]["stored"], 1);
    assert_eq!(
        std::fs::read(dir.join("a.ply")).unwrap(),
        std::fs::read(dir.join("e.ply")).unwrap()
    );
    assert!(std::fs::read(&file).unwrap().len() > bytes.len());
}
