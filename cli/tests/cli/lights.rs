//! `--sky`, `--sky-model`, `--sun` and `--up` from the command line: a scene without emitters
//! lit from outside, what `info` says of them, and bad values.

use crate::support::{radiosity, stderr, temp_dir, Scratch};

/// A floor (z up) and a wall along its north edge, no emitter: lit only from outside.
const COURT: &str = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 1 1\nv 1 1 1\n\
                     usemtl grey\nf 1 2 3 4\nf 4 3 6 5\n";
const MTL: &str = "newmtl grey\nKd 0.5 0.5 0.5\n";

/// [`COURT`] and its MTL written into a new temporary folder: the folder and the OBJ's path.
fn court(name: &str) -> (Scratch, String) {
    let dir = temp_dir(name);
    std::fs::write(dir.join("m.mtl"), MTL).unwrap();
    let input = dir.join("court.obj");
    std::fs::write(&input, COURT).unwrap();
    (dir, input.to_str().unwrap().to_string())
}

/// A uniform sky, a sun at 45° and a lamp above the court, as flags (the lights file of
/// `a_lights_file_gives_the_same_bake_as_the_flags_and_names_its_mistakes` holds the same).
const SKY_SUN_LAMP: [&str; 6] = [
    "--sky",
    "1",
    "--sun",
    "0,45,800,700,600",
    "--point-light",
    "0.5,0.5,0.8,2",
];

#[test]
fn a_scene_without_emitters_is_lit_by_the_sky_and_the_sun() {
    let (dir, input) = court("environment");
    let (input, out) = (input.as_str(), dir.join("lit.ply"));
    let out = out.to_str().unwrap();
    let light = [["--up", "z"].as_slice(), &SKY_SUN_LAMP].concat();

    // info names both, with what they bring to an open surface facing up.
    let mut args = vec!["info", input];
    args.extend(&light);
    let o = radiosity(&args);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(text.contains("emitters:     none in the mesh"), "{text}");
    assert!(text.contains("sky:          uniform L = (1 1 1)"), "{text}");
    assert!(
        text.contains("sun:          azimuth 0°, elevation 45°"),
        "{text}"
    );

    // A bake: no "no emitters" warning, and the floor gets at least the sky's direct light
    // ρ·L·(1 + cos 0)/2 = 0.5 where nothing hides it (the wall hides part of its sky).
    let mut args = vec!["bake", input, "-o", out, "-q"];
    args.extend(&light);
    let o = radiosity(&args);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("no emitters"), "{}", stderr(&o));
    let baked = radiosity::io::ply::read(std::path::Path::new(out)).unwrap();
    let radiance = baked.vertex_radiance.unwrap();
    let brightest = radiance.iter().map(|l| l[0]).fold(0.0, f32::max);
    assert!(brightest > 0.5, "{brightest}");

    // Without them: black, and said.
    let o = radiosity(&["bake", input, "-o", out, "-q"]);
    assert!(
        stderr(&o).contains("warning: no emitters"),
        "{}",
        stderr(&o)
    );

    // Bad values name their option; nothing is written.
    std::fs::remove_file(out).unwrap();
    for (option, value) in [
        ("--sky", "-1"),
        ("--sky", "1,2"),
        ("--sun", "0,95,100"),
        ("--sun", "0,45"),
        ("--sun", "north,45,100"),
        ("--up", "w"),
        ("--sky-model", "cloudy"),
        ("--point-light", "0,0,1"),
        ("--point-light", "0,0,1,-5"),
        ("--spot-light", "0,0,1,0,0,0,10,20,5"),
        ("--spot-light", "0,0,1,0,0,-1,30,20,5"),
    ] {
        let o = radiosity(&["bake", input, "-o", out, option, value]);
        assert_eq!(o.status.code(), Some(2), "{option} {value}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(option),
            "{option} {value}: {}",
            stderr(&o)
        );
        assert!(!std::path::Path::new(out).exists());
    }
}

#[test]
fn a_gltf_scene_brings_its_lights_and_bakes_to_glb() {
    // A hand-written .gltf (cli/tests/data/lamp_floor.gltf): a 2 × 2 floor (ρ = 0.5) and a
    // KHR_lights_punctual point light of 683 cd (1 W/sr) 1 above its centre. `info` lists the
    // light; a bake to .glb needs no other light, and the floor's brightest vertex, right
    // under the bulb, shows ρ·I/(π r²) = 0.5/π (its point value: `--gather-tolerance 0`, as
    // the display refinement's chord correction would lift the peak of the concave profile to
    // keep the light's integral over the triangles around it).
    let input = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/lamp_floor.gltf");
    let input = input.to_str().unwrap();
    let o = radiosity(&["info", input]);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        text.contains("point light:  at (0 1 0), I = (1 1 1) W·sr⁻¹"),
        "{text}"
    );
    let dir = temp_dir("gltf-bake");
    let (glb, ply) = (dir.join("lit.glb"), dir.join("lit.ply"));
    for out in [&glb, &ply] {
        let out = out.to_str().unwrap();
        let o = radiosity(&["bake", input, "-o", out, "-q", "--gather-tolerance", "0"]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        assert!(!stderr(&o).contains("no emitters"), "{}", stderr(&o));
    }
    let bytes = std::fs::read(&glb).unwrap();
    assert_eq!(&bytes[..4], b"glTF");
    let baked = radiosity::io::ply::read(&ply).unwrap();
    let brightest = baked
        .vertex_radiance
        .unwrap()
        .iter()
        .map(|l| l[0])
        .fold(0.0, f32::max);
    let exact = 0.5 / std::f32::consts::PI;
    assert!(
        (brightest - exact).abs() < 1e-4 * exact,
        "{brightest} vs {exact}"
    );
}

#[test]
fn a_lights_file_gives_the_same_bake_as_the_flags_and_names_its_mistakes() {
    let (dir, input) = court("lights_file");
    let input = input.as_str();
    let lights = dir.join("lights.json");
    std::fs::write(
        &lights,
        r#"{ "sky": 1, "sun": { "azimuth": 0, "elevation": 45, "irradiance": [800, 700, 600] },
             "lights": [ { "name": "lamp", "position": [0.5, 0.5, 0.8], "intensity": 2 },
                         { "position": [0.2, 0.2, 0.9], "intensity": [3, 2, 1],
                           "spot": { "direction": [0, 0, -1], "inner": 20, "outer": 40 } } ] }"#,
    )
    .unwrap();
    let bake = |name: &str, light: &[&str]| {
        let out = dir.join(name);
        let mut args = vec![
            "bake",
            input,
            "-o",
            out.to_str().unwrap(),
            "-q",
            "--up",
            "z",
        ];
        args.extend(light);
        let o = radiosity(&args);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        std::fs::read(out).unwrap()
    };
    // The file and the flags it stands for give the same bytes (same lights, same order).
    let from_flags = bake(
        "flags.ply",
        &[
            SKY_SUN_LAMP.as_slice(),
            &["--spot-light", "0.2,0.2,0.9,0,0,-1,20,40,3,2,1"],
        ]
        .concat(),
    );
    let from_file = bake("file.ply", &["--lights", lights.to_str().unwrap()]);
    assert!(from_flags == from_file, "the lights file's bake differs");
    // --sun replaces the file's sun: a weaker sun gives a different bake.
    let replaced = bake(
        "replaced.ply",
        &["--lights", lights.to_str().unwrap(), "--sun", "0,45,1"],
    );
    assert!(replaced != from_file);

    // info lists the file's lights.
    let o = radiosity(&[
        "info",
        input,
        "--up",
        "z",
        "--lights",
        lights.to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        text.contains("sun:          azimuth 0°, elevation 45°"),
        "{text}"
    );

    // Mistakes name the file and the line or the light; exit 2; nothing written.
    let out = dir.join("bad.ply");
    for (text, wanted) in [
        (
            "{\n \"lights\": [\n {\"position\": [0,0,0], \"intensty\": 3} ] }",
            ":3:",
        ),
        (
            r#"{ "lights": [ { "name": "torch", "position": [0,0,1], "intensity": -1 } ] }"#,
            "lights[0] (\"torch\")",
        ),
    ] {
        std::fs::write(&lights, text).unwrap();
        let o = radiosity(&[
            "bake",
            input,
            "-o",
            out.to_str().unwrap(),
            "--lights",
            lights.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(
            stderr(&o).contains("lights.json") && stderr(&o).contains(wanted),
            "{}",
            stderr(&o)
        );
        assert!(!out.exists());
    }
    let o = radiosity(&[
        "bake",
        input,
        "-o",
        out.to_str().unwrap(),
        "--lights",
        "missing.json",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("missing.json"), "{}", stderr(&o));
}
