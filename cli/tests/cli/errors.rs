//! Bad input, end to end through the binary: every kind of bad input gets exit status 2 (1 only
//! for internal failures), a message naming the file and line (or the option) and what is
//! wrong, no panic, and leaves an existing output file byte-identical; likely mistakes that
//! are not errors are counted warnings with exit 0; ρ near and at 1 in a closed scene.
//! Fixtures are small strings written to a temporary directory per test.

use std::path::Path;

use radiosity::io::ply;
use radiosity::validation::scenes;

use crate::support::{cornell, radiosity, stderr, temp_dir, Scratch};

/// An emitting material and a grey one (m.mtl of the valid fixtures).
const MTL: &str = "newmtl light\nKd 0.5 0.5 0.5\nKe 1 1 1\nnewmtl grey\nKd 0.5 0.5 0.5\n";

/// A lit, valid scene: a grey floor quad facing up and an emitting triangle above it facing
/// down. Faces are on lines 10, 12 and 13.
const VALID: &str = "mtllib m.mtl\n\
    v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
    v 0.2 0.2 1\nv 0.8 0.2 1\nv 0.5 0.8 1\n\
    usemtl light\nf 5 7 6\n\
    usemtl grey\nf 1 2 3\nf 1 3 4\n";

/// The sorted names of the files in `dir`.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// One test directory holding m.mtl, a precious pre-existing output `keep.ply` and the
/// fixtures each case writes.
struct Fixture {
    dir: Scratch,
}

impl Fixture {
    fn new(name: &str) -> Fixture {
        let dir = temp_dir(name);
        std::fs::write(dir.join("m.mtl"), MTL).unwrap();
        std::fs::write(dir.join("keep.ply"), b"precious bytes").unwrap();
        Fixture { dir }
    }

    fn path(&self, name: &str) -> String {
        self.dir.join(name).display().to_string()
    }

    fn write(&self, name: &str, text: &str) -> String {
        std::fs::write(self.dir.join(name), text).unwrap();
        self.path(name)
    }

    /// Run `bake INPUT -o keep.ply EXTRA…` (or `args` verbatim when `input` is `None`) and
    /// assert: exit status `code`, stderr contains every needle, never "panicked", keep.ply
    /// is byte-identical and no file appeared or vanished (no temporary left behind).
    #[track_caller]
    fn expect_error(&self, input: &str, extra: &[&str], code: i32, needles: &[&str]) {
        let before = listing(&self.dir);
        let out = self.path("keep.ply");
        let mut args = vec!["bake", input, "-o", &out, "--max-edge", "0.5"];
        args.extend_from_slice(extra);
        let o = radiosity(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(code), "{args:?}: {err}");
        for needle in needles {
            assert!(err.contains(needle), "{args:?}: {needle:?} not in: {err}");
        }
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(err.starts_with("error: "), "{args:?}: {err}");
        assert_eq!(
            std::fs::read(self.dir.join("keep.ply")).unwrap(),
            b"precious bytes",
            "{args:?} touched the existing output"
        );
        assert_eq!(listing(&self.dir), before, "{args:?} left files behind");
    }

    /// Bake `input` to a fresh `name.ply`; return the exit status and stderr (asserting no
    /// panic and that keep.ply is untouched).
    fn bake(&self, input: &str, name: &str, extra: &[&str]) -> (Option<i32>, String) {
        let out = self.path(&format!("{name}.ply"));
        let mut args = vec!["bake", input, "-o", &out, "--max-edge", "0.5"];
        args.extend_from_slice(extra);
        let o = radiosity(&args);
        let err = stderr(&o);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert_eq!(
            std::fs::read(self.dir.join("keep.ply")).unwrap(),
            b"precious bytes"
        );
        (o.status.code(), err)
    }
}

#[test]
fn file_problems_name_the_file() {
    let f = Fixture::new("robust-files");
    // Missing input.
    f.expect_error(&f.path("nope.obj"), &[], 2, &["nope.obj", "No such file"]);
    // A directory as input.
    let sub = f.dir.join("dir.obj");
    std::fs::create_dir(&sub).unwrap();
    f.expect_error(&f.path("dir.obj"), &[], 2, &["dir.obj", "is a directory"]);
    std::fs::remove_dir(&sub).unwrap();
    // Unreadable: bytes that are not text, reported at the line of the first bad byte.
    let bin = f.dir.join("binary.obj");
    std::fs::write(&bin, b"v 0 0 0\nv 1 \xff\xfe 0\n").unwrap();
    f.expect_error(
        &f.path("binary.obj"),
        &[],
        2,
        &["binary.obj:2:", "not UTF-8"],
    );
    // Unreadable by permissions (only observable when not running as root).
    let locked = f.write("locked.obj", VALID);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o000)).unwrap();
        if std::fs::read(&locked).is_err() {
            f.expect_error(&locked, &[], 2, &["locked.obj", "ermission denied"]);
        }
        std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o644)).unwrap();
    }
    // Unsupported input and output extensions, missing output directory.
    let stl = f.write("scene.stl", VALID);
    f.expect_error(&stl, &[], 2, &["scene.stl", "unsupported scene format"]);
    let input = f.write("valid.obj", VALID);
    let (x, missing) = (f.path("x.stl"), f.path("no/such/dir/x.ply"));
    for (out, needles) in [
        (&x, ["x.stl", "unsupported output extension"]),
        (&missing, ["no/such/dir", "does not exist"]),
    ] {
        let before = listing(&f.dir);
        let o = radiosity(&["bake", &input, "-o", out]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(needles.iter().all(|n| err.contains(n)), "{err}");
        assert!(!err.contains("panicked"));
        assert_eq!(listing(&f.dir), before);
    }
    // An output that would replace the scene (by another spelling of its path) or another
    // output: refused before any work, every file on disk as it was.
    let lights = f.write("lights.json", r#"{"sky": [1, 1, 1]}"#);
    let (ply, report) = (f.path("out.ply"), f.path("sub/../out.ply"));
    let spelled = f.path("sub/../valid.obj");
    // The scene's material library, and a texture image it names (the material unused).
    let mtl = f.path("m.mtl");
    let texture = f.path("wood.png");
    image::RgbImage::from_pixel(2, 2, image::Rgb([200, 150, 100]))
        .save(&texture)
        .unwrap();
    let textured = format!("{MTL}newmtl wood\nKd 1 1 1\nmap_Kd wood.png\n");
    std::fs::write(f.dir.join("m.mtl"), textured).unwrap();
    std::fs::create_dir(f.dir.join("sub")).unwrap();
    for (args, needles) in [
        (
            vec!["-o", &spelled],
            ["--output", "is the input", "valid.obj"],
        ),
        (
            vec!["-o", &ply, "--report", &report],
            ["--report", "also the output", "out.ply"],
        ),
        (
            vec!["-o", &ply, "--png", &ply],
            ["--png", "also the output", "out.ply"],
        ),
        (
            vec!["-o", &ply, "--lights", &lights, "--report", &lights],
            ["--report", "is the input", "lights.json"],
        ),
        (
            vec!["-o", &ply, "--report", &mtl],
            ["--report", "is the input", "m.mtl"],
        ),
        (
            vec!["-o", &ply, "--png", &texture],
            ["--png", "is the input", "wood.png"],
        ),
    ] {
        let before = listing(&f.dir);
        let bytes = std::fs::read(&input).unwrap();
        let o = radiosity(&[&["bake", input.as_str()], args.as_slice()].concat());
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(needles.iter().all(|n| err.contains(n)), "{err}");
        assert_eq!(listing(&f.dir), before);
        assert_eq!(std::fs::read(&input).unwrap(), bytes);
    }
    std::fs::write(f.dir.join("m.mtl"), MTL).unwrap();
    // The MTL named by mtllib is there but not text: an error at the mtllib line.
    std::fs::write(f.dir.join("bad.mtl"), [0xffu8, 0xfe, 0x00]).unwrap();
    let obj = f.write("badmtl.obj", &VALID.replace("m.mtl", "bad.mtl"));
    f.expect_error(
        &obj,
        &[],
        2,
        &["badmtl.obj:1:", "bad.mtl", "cannot read material library"],
    );
    // The MTL is missing (models are often shared without it): a warning naming it, and
    // its materials' faces bake with the default material (here: no emitter left, so black,
    // with that warning too).
    let obj = f.write("nomtl.obj", &VALID.replace("m.mtl", "gone.mtl"));
    let out = f.path("nomtl.ply");
    let o = radiosity(&["bake", &obj, "-o", &out]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(
        err.contains("gone.mtl (mtllib at line 1)") && err.contains("'grey'"),
        "{err}"
    );
    // A material used but defined nowhere.
    let obj = f.write("undef.obj", &VALID.replace("usemtl grey", "usemtl nosuch"));
    f.expect_error(&obj, &[], 2, &["undef.obj:11:", "nosuch", "not defined"]);
}

#[test]
fn obj_content_errors_give_file_line_and_reason() {
    let f = Fixture::new("robust-obj");
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let cases: [(&str, String, &[&str]); 12] = [
        (
            "number",
            format!("{tri}v 1 x 0\nf 1 2 3\n"),
            &[":4:", "malformed number 'x'"],
        ),
        (
            "nan",
            format!("{tri}v nan 0 0\nf 1 2 3\n"),
            &[":4:", "non-finite coordinate"],
        ),
        (
            "inf",
            format!("{tri}v 0 inf 0\nf 1 2 3\n"),
            &[":4:", "non-finite coordinate"],
        ),
        (
            "huge",
            format!("{tri}v 0 0 1e39\nf 1 2 3\n"),
            &[":4:", "'1e39' is beyond single precision's range"],
        ),
        (
            "range",
            format!("{tri}f 1 2 4\n"),
            &[":4:", "vertex index 4 out of range"],
        ),
        (
            "negrange",
            format!("{tri}f -1 -2 -4\n"),
            &[":4:", "vertex index -4 out of range"],
        ),
        ("zero", format!("{tri}f 0 1 2\n"), &[":4:", "index 0"]),
        (
            "two",
            format!("{tri}f 1 2\n"),
            &[":4:", "face has 2 vertices; at least 3"],
        ),
        (
            "badface",
            format!("{tri}f 1 2 z\n"),
            &[":4:", "malformed vertex 'z'"],
        ),
        ("nofaces", tri.to_string(), &["the mesh is empty"]),
        ("blank", String::new(), &["the mesh is empty"]),
        (
            "degenerate",
            "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n".into(),
            &["no triangles with non-zero area"],
        ),
    ];
    for (name, text, needles) in cases {
        let file = format!("{name}.obj");
        let input = f.write(&file, &text);
        let mut all = vec![file.as_str()];
        all.extend_from_slice(needles);
        f.expect_error(&input, &[], 2, &all);
    }
}

#[test]
fn material_value_errors_give_mtl_line_and_material() {
    let f = Fixture::new("robust-mtl");
    let cases: [(&str, &[&str]); 6] = [
        (
            "newmtl hot\nKd 1.5 0.5 0.5\n",
            &["bad.mtl:2:", "'hot'", "must be in [0, 1]"],
        ),
        (
            "newmtl hot\nKd -0.1 0.5 0.5\n",
            &["bad.mtl:2:", "'hot'", "must be in [0, 1]"],
        ),
        (
            "newmtl hot\nKd 0.5\nKe 1 -2 3\n",
            &["bad.mtl:3:", "'hot'", "finite and ≥ 0"],
        ),
        (
            "newmtl hot\nKd NaN 0.5 0.5\n",
            &["bad.mtl:2:", "'hot'", "[0, 1]"],
        ),
        (
            "newmtl hot\nKe 1 nan 1\n",
            &["bad.mtl:2:", "'hot'", "finite and ≥ 0"],
        ),
        (
            "newmtl hot\nKe inf 1 1\n",
            &["bad.mtl:2:", "'hot'", "finite and ≥ 0"],
        ),
    ];
    let obj = f.write(
        "uses.obj",
        "mtllib bad.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl hot\nf 1 2 3\n",
    );
    for (mtl, needles) in cases {
        f.write("bad.mtl", mtl);
        f.expect_error(&obj, &[], 2, needles);
    }
}

#[test]
fn option_values_out_of_range_name_the_option() {
    let f = Fixture::new("robust-options");
    let input = f.write("valid.obj", VALID);
    let cases: [(&[&str], &str); 29] = [
        (&["--max-edge", "0"], "--max-edge"),
        (&["--max-edge", "-1"], "--max-edge"),
        (&["--max-edge", "nan"], "--max-edge"),
        (&["--max-edge", "inf"], "--max-edge"),
        (&["--max-edge", "1e-9"], "--max-edge"),
        (&["--samples", "0"], "--samples"),
        (&["--rays", "0"], "--rays"),
        (&["--tolerance", "-1"], "--tolerance"),
        (&["--tolerance", "0"], "--tolerance"),
        (&["--tolerance", "nan"], "--tolerance"),
        (&["--max-iterations", "0"], "--max-iterations"),
        (&["--crease", "200"], "--crease"),
        (&["--exposure", "0"], "--exposure"),
        (&["--png-size", "0"], "--png-size"),
        (&["--threads", "0"], "--threads"),
        (&["--solver", "magic"], "--solver"),
        (&["--samples", "-3"], "--samples"),
        (&["--rays", "-1"], "--rays"),
        (&["--max-iterations", "-5"], "--max-iterations"),
        (&["--bounces", "-1"], "--bounces"),
        (&["--crease", "-5"], "--crease"),
        (&["--threads", "-2"], "--threads"),
        (&["--omega", "0"], "--omega"),
        (&["--omega", "2"], "--omega"),
        (&["--omega", "nan"], "--omega"),
        (&["--refine-threshold", "0"], "--refine-threshold"),
        (&["--refine-threshold", "-0.5"], "--refine-threshold"),
        (&["--refine", "-1"], "--refine"),
        (&["--solver", "cg", "--omega", "3"], "--omega"),
    ];
    for (extra, option) in cases {
        // A later --max-edge overrides the fixture's 0.5 (clap keeps the last value).
        f.expect_error(&input, extra, 2, &[option]);
    }
}

#[test]
fn likely_mistakes_are_counted_warnings_and_the_bake_succeeds() {
    let f = Fixture::new("robust-warnings");
    // Two zero-area triangles (collinear; a sliver 1e-14 thick relative to the scene).
    let zero = f.write(
        "zero.obj",
        &format!("{VALID}v 2 0 0\nv 0.5 1e-14 0\nf 1 2 8\nf 1 9 2\n"),
    );
    let (code, err) = f.bake(&zero, "zero", &[]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("warning: skipped 2 zero-area triangles"),
        "{err}"
    );

    // A light in the floor's plane, facing the same way (z-fighting): warned, both kept.
    let overlap = f.write(
        "overlap.obj",
        &format!("{VALID}v 0.5 0.1 0\nv 0.9 0.1 0\nv 0.9 0.5 0\nusemtl light\nf 8 9 10\n"),
    );
    let (code, err) = f.bake(&overlap, "overlap", &[]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("warning: 1 pair of coincident overlapping faces"),
        "{err}"
    );
    // Floor triangle 1 (line 12) under the new light (triangle 3, line 18); the light lies
    // wholly on triangle 1's side of the floor's diagonal.
    assert!(
        err.contains("triangles 1 (")
            && err.contains("overlap.obj:12) and 3 (")
            && err.contains("overlap.obj:18)"),
        "{err}"
    );
    assert!(err.contains("Both faces of each pair are kept"), "{err}");
    // Deterministic: the same warning every run.
    let (_, again) = f.bake(&overlap, "overlap2", &[]);
    assert_eq!(err.lines().next(), again.lines().next());

    // The second floor triangle flipped: its shared edge runs the same way as the first's.
    let flipped = f.write("flipped.obj", &VALID.replace("f 1 3 4", "f 1 4 3"));
    let (code, err) = f.bake(&flipped, "flipped", &[]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("warning: 1 pair of neighbouring faces with inconsistent winding")
            && err.contains("flipped.obj:12) and 2 (")
            && err.contains("flipped.obj:13)"),
        "{err}"
    );

    // The valid scene has no warnings at all.
    // The floor's first triangle repeated, rotated but wound the same way (as McGuire's
    // Cornell box repeats a side face of each block as its bottom): merged into the first,
    // named by both lines. The same triangle wound the other way is its back side: kept.
    let repeated = f.write("repeated.obj", &format!("{VALID}f 2 3 1\n"));
    let json = f.path("repeated.json");
    let (code, err) = f.bake(&repeated, "repeated", &["--report", &json]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("warning: 1 duplicate face")
            && err.contains("kept 1 (")
            && err.contains("repeated.obj:12) and dropped 3 (")
            && err.contains("repeated.obj:14)"),
        "{err}"
    );
    let report = std::fs::read_to_string(&json).unwrap();
    let report: serde_json::Value = serde_json::from_str(&report).unwrap();
    assert_eq!(report["input_triangles"], 3);
    let back = f.write("back.obj", &format!("{VALID}f 3 2 1\n"));
    let json = f.path("back.json");
    let (code, err) = f.bake(&back, "back", &["--report", &json]);
    assert_eq!(code, Some(0), "{err}");
    assert!(!err.contains("duplicate"), "{err}");
    let report = std::fs::read_to_string(&json).unwrap();
    let report: serde_json::Value = serde_json::from_str(&report).unwrap();
    assert_eq!(report["input_triangles"], 4);

    let valid = f.write("valid.obj", VALID);
    let (code, err) = f.bake(&valid, "valid", &[]);
    assert_eq!(code, Some(0), "{err}");
    assert!(!err.contains("warning:"), "{err}");
}

#[test]
fn no_emitters_bakes_to_black_with_a_warning() {
    let f = Fixture::new("robust-dark");
    let input = f.write("dark.obj", &VALID.replace("usemtl light", "usemtl grey"));
    let (code, err) = f.bake(&input, "dark", &[]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("warning: no emitters"), "{err}");
    let p = ply::read(&f.dir.join("dark.ply")).unwrap();
    assert!(!p.faces.is_empty());
    assert!(p
        .vertex_radiance
        .unwrap()
        .iter()
        .flatten()
        .all(|&x| x == 0.0));
    assert!(p.colours.iter().flatten().all(|&c| c == 0));
}

#[test]
fn reflectance_one_in_a_closed_scene_is_refused_and_near_one_stops_with_status_3() {
    let f = Fixture::new("robust-rho");
    let save = |name: &str, rho: f64| {
        let path = f.dir.join(name);
        radiosity::io::obj::save(&scenes::furnace_room(rho, 1.0).unwrap(), &path).unwrap();
        path.display().to_string()
    };
    // The hemisphere estimator's rows sum to 1 in a closed scene (see solve::check_not_singular).
    let hemisphere = ["--form-factors", "hemisphere", "--rays", "64"];
    let white = save("white.obj", 1.0);
    f.expect_error(
        &white,
        &hemisphere,
        2,
        &[
            "singular",
            "ρ = 1 in the red channel",
            "closed enclosure",
            "Kd",
        ],
    );
    // ρ = 0.999 needs thousands of sweeps; with 3 allowed the bake stops, writes and says so.
    let near = save("near.obj", 0.999);
    let (code, err) = f.bake(
        &near,
        "near",
        &[&hemisphere[..], &["--max-iterations", "3"]].concat(),
    );
    assert_eq!(code, Some(3), "{err}");
    assert!(
        err.contains("not converged") && err.contains("--max-iterations"),
        "{err}"
    );
    assert!(f.dir.join("near.ply").exists());
}

#[test]
fn cornell_box_still_loads_without_warnings() {
    // The detections must not fire on a clean, shipped scene.
    let scene = radiosity::scene::Scene::load(Path::new(&cornell())).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
}
