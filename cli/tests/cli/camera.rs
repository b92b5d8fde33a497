//! The scene's own camera: OBJ `# camera: …` and PLY `comment camera: …` lines are read into
//! the scene (and shown by `info`), repeated in baked files, and used by `render` and `bake
//! --png` when `--camera` is not given; the shipped Cornell box renders from its published
//! camera; malformed lines are errors at their line.

use glam::DVec3;
use radiosity::bake::BakedMesh;
use radiosity::io::{self, obj, ply, Format};
use radiosity::scene::{Camera, Scene};

use crate::support::{cornell, meshes, radiosity, stderr, temp_dir};

/// The Cornell box's published camera, as `--camera` spells it.
const PUBLISHED: &str = "278,273,-800,278,273,0,0,1,0,39.30765";

fn published() -> Camera {
    Camera::parse(PUBLISHED).unwrap()
}

/// A lit floor as OBJ with `camera_line` on line 3 (faces on lines 9 and 11).
fn obj_with(camera_line: &str) -> String {
    format!(
        "mtllib m.mtl\n# a scene\n{camera_line}\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
         usemtl grey\nf 1 2 3 4\nusemtl lamp\nf 1 4 3\n"
    )
}

const MTL: &str = "newmtl grey\nKd 0.5 0.5 0.5\nnewmtl lamp\nKd 0 0 0\nKe 1 1 1\n";

/// A one-triangle ASCII PLY with `comment` on header line 3.
fn ply_with(comment: &str) -> String {
    format!(
        "ply\nformat ascii 1.0\n{comment}\nelement vertex 3\nproperty float x\n\
         property float y\nproperty float z\nelement face 1\n\
         property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    )
}

#[test]
fn scene_files_carry_their_camera() {
    // The shipped box: exactly the published camera.
    let scene = Scene::load(cornell().as_ref()).unwrap();
    let c = scene.camera.expect("cornell_box.obj has a camera line");
    assert_eq!(c, published());
    assert_eq!(c.eye, DVec3::new(278.0, 273.0, -800.0));
    assert_eq!(c.target, DVec3::new(278.0, 273.0, 0.0));
    assert_eq!(c.up, DVec3::Y);
    assert!((c.vfov_degrees - radiosity::scene::camera::cornell_vfov_degrees()).abs() < 1e-5);
    // The verification scenes have none.
    let furnace = Scene::load(&meshes().join("furnace.obj")).unwrap();
    assert_eq!(furnace.camera, None);
    // `radiosity info` shows the file's camera exactly, or says that pictures frame the box.
    let o = radiosity(&["info", &cornell()]);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    let line = "camera:       eye (278 273 -800), target (278 273 0), up (0 1 0), vertical field \
                of view 39.30765° (from the file)";
    assert!(text.contains(line), "{text}");
    let o = radiosity(&["info", &cornell(), "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        json["camera"]["eye"],
        serde_json::json!([278.0, 273.0, -800.0])
    );
    assert_eq!(json["camera"]["vfov_degrees"], 39.30765);
    let furnace = meshes().join("furnace.obj");
    let o = radiosity(&["info", furnace.to_str().unwrap(), "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(json["camera"].is_null());
    let o = radiosity(&["info", furnace.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        text.contains("camera:       none in the file; pictures look level"),
        "{text}"
    );

    let dir = temp_dir("camera-scenes");
    std::fs::write(dir.join("m.mtl"), MTL).unwrap();
    let expect = Camera::new(
        DVec3::new(0.5, -2.0, 3.0),
        DVec3::new(0.5, 0.5, 0.0),
        DVec3::Z,
        50.0,
    )
    .unwrap();
    for line in [
        "# camera: 0.5 -2 3 0.5 0.5 0 0 0 1 50",
        "#camera: 0.5,-2,3, 0.5,0.5,0, 0,0,1, 50",
    ] {
        let path = dir.join("s.obj");
        std::fs::write(&path, obj_with(line)).unwrap();
        assert_eq!(Scene::load(&path).unwrap().camera, Some(expect), "{line}");
    }
    // Other comments mentioning a camera are just comments.
    let path = dir.join("plain.obj");
    std::fs::write(&path, obj_with("# the camera: see the README")).unwrap();
    assert_eq!(Scene::load(&path).unwrap().camera, None);

    let path = dir.join("s.ply");
    std::fs::write(
        &path,
        ply_with("comment camera: 0.5 -2 3 0.5 0.5 0 0 0 1 50"),
    )
    .unwrap();
    assert_eq!(Scene::load(&path).unwrap().camera, Some(expect));
    std::fs::write(&path, ply_with("comment made by hand")).unwrap();
    assert_eq!(Scene::load(&path).unwrap().camera, None);
}

#[test]
fn malformed_camera_lines_are_errors_with_file_and_line() {
    let dir = temp_dir("camera-errors");
    std::fs::write(dir.join("m.mtl"), MTL).unwrap();
    let out = dir.join("keep.ply");
    std::fs::write(&out, b"precious").unwrap();
    let cases: Vec<(&str, String, &[&str])> = vec![
        (
            "bad.obj",
            obj_with("# camera: 0 0 -5 0 0 0 0 1 0"),
            &["bad.obj:3:", "camera", "expected 10 numbers", "got 9"],
        ),
        (
            "bad.obj",
            obj_with("# camera: 0 0 -5 0 0 0 0 1 0 x"),
            &["bad.obj:3:", "\"x\" is not a number"],
        ),
        (
            "bad.obj",
            obj_with("# camera: 0 0 0 0 0 0 0 1 0 40"),
            &["bad.obj:3:", "eye and target coincide"],
        ),
        (
            "bad.obj",
            obj_with("# camera: 0 0 -5 0 0 0 0 1 0 40\n# camera: 0 0 -5 0 0 0 0 1 0 40"),
            &["bad.obj:4:", "a second camera line (the first is line 3)"],
        ),
        (
            "bad.ply",
            ply_with("comment camera: 0 0 -5 0 0 0 0 1 0 200"),
            &["bad.ply:3:", "field of view must be in (0, 180)"],
        ),
        (
            "bad.ply",
            ply_with("comment camera: 0 0 -5 0 0 0 0 0 1"),
            &["bad.ply:3:", "expected 10 numbers"],
        ),
    ];
    for (name, text, needles) in cases {
        let path = dir.join(name);
        std::fs::write(&path, &text).unwrap();
        for command in ["bake", "info", "render"] {
            let png = dir.join("v.png");
            let target = if command == "render" { &png } else { &out };
            let mut args = vec![command, path.to_str().unwrap()];
            if command != "info" {
                args.extend(["-o", target.to_str().unwrap()]);
            }
            let o = radiosity(&args);
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{command} {name}: {err}");
            for n in needles {
                assert!(err.contains(n), "{command} {name}: {n:?} not in {err}");
            }
            assert!(!err.contains("panicked"), "{err}");
            assert_eq!(std::fs::read(&out).unwrap(), b"precious");
            assert!(!png.exists());
        }
    }
}

#[test]
fn baked_files_carry_the_camera() {
    let dir = temp_dir("camera-bake");
    let (p, q, a) = (dir.join("c.ply"), dir.join("c.obj"), dir.join("a.ply"));
    let input = cornell();
    for (out, extra) in [(&p, None), (&q, None), (&a, Some("--ascii"))] {
        let out = out.to_str().unwrap();
        // No gather: the camera is what is tested, not the light.
        let mut args = vec!["bake", input.as_str(), "-o", out, "--max-edge", "150", "-q"];
        args.extend(["--gather", "none"]);
        args.extend(extra);
        let o = radiosity(&args);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    assert_eq!(ply::read(&p).unwrap().camera, Some(published()));
    assert_eq!(ply::read(&a).unwrap().camera, Some(published()));
    assert_eq!(obj::read(&q).unwrap().camera, Some(published()));
    let header = std::fs::read(&p).unwrap();
    let header = String::from_utf8_lossy(&header[..400]);
    assert!(
        header.contains("\ncomment camera: 278 273 -800 278 273 0 0 1 0 39.30765\n"),
        "{header}"
    );
    // A baked file loaded as a scene keeps it, so baking it again keeps it too.
    assert_eq!(Scene::load(&p).unwrap().camera, Some(published()));
    assert_eq!(Scene::load(&q).unwrap().camera, Some(published()));

    // Library level: any camera survives the writers and readers exactly; none writes none.
    let odd = Camera::new(
        DVec3::new(0.1, 1.0 / 3.0, -7e-9),
        DVec3::new(1e12, -0.0, 5.0),
        DVec3::new(0.0, 0.0, -1.0),
        179.9,
    )
    .unwrap();
    let mesh = BakedMesh {
        positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vertex_radiance: vec![[0.5; 3]; 3],
        faces: vec![[0, 1, 2]],
        face_radiance: vec![[0.5; 3]],
        camera: Some(odd),
        sky: None,
    };
    for (name, format) in [
        ("m.ply", Format::Ply { ascii: false }),
        ("m2.ply", Format::Ply { ascii: true }),
        ("m.obj", Format::Obj),
    ] {
        let path = dir.join(name);
        io::write(&path, &mesh, format, 1.0).unwrap();
        let back = if name.ends_with("ply") {
            ply::read(&path)
        } else {
            obj::read(&path)
        };
        assert_eq!(back.unwrap().camera, Some(odd), "{name}");
        let plain = BakedMesh {
            camera: None,
            ..mesh.clone()
        };
        io::write(&path, &plain, format, 1.0).unwrap();
        let back = if name.ends_with("ply") {
            ply::read(&path)
        } else {
            obj::read(&path)
        };
        assert_eq!(back.unwrap().camera, None, "{name}");
        assert!(!String::from_utf8_lossy(&std::fs::read(&path).unwrap()).contains("camera"));
    }
}

#[test]
fn the_cornell_box_renders_from_its_published_camera_by_itself() {
    let dir = temp_dir("camera-render");
    let input = cornell();
    let common = ["--max-edge", "150", "--size", "96", "-q"];
    let render = |input: &str, name: &str, camera: Option<&str>| {
        let png = dir.join(name);
        let mut args = vec!["render", input, "-o", png.to_str().unwrap()];
        args.extend(common);
        if let Some(c) = camera {
            args.extend(["--camera", c]);
        }
        let o = radiosity(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read(&png).unwrap()
    };
    // From the scene: no --camera is exactly the published camera, byte for byte.
    let by_itself = render(&input, "a.png", None);
    assert_eq!(by_itself, render(&input, "b.png", Some(PUBLISHED)));
    // `bake --png` does the same.
    let (baked, png) = (dir.join("c.ply"), dir.join("c.png"));
    let mut args = vec!["bake", &input, "-o", baked.to_str().unwrap(), "--png"];
    args.push(png.to_str().unwrap());
    args.extend(common);
    let o = radiosity(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read(&png).unwrap(), by_itself);
    // From the baked PLY (radiance stored as f32, so its own reference): the camera it
    // carries, again byte-identical to the explicit one.
    let baked = baked.to_str().unwrap();
    assert_eq!(
        render(baked, "d.png", None),
        render(baked, "e.png", Some(PUBLISHED))
    );
    // --camera wins over the file's camera; without one, framing is within 30 mm of it.
    let framed = Camera::framing(DVec3::ZERO, DVec3::new(556.0, 548.8, 559.2));
    let framed_text = format!(
        "{},{},{},{},{},{},0,1,0,{}",
        framed.eye.x,
        framed.eye.y,
        framed.eye.z,
        framed.target.x,
        framed.target.y,
        framed.target.z,
        framed.vfov_degrees
    );
    assert_ne!(render(&input, "f.png", Some(&framed_text)), by_itself);
}

#[test]
fn without_a_camera_the_picture_looks_into_the_open_side_and_says_when_it_shows_nothing() {
    let dir = temp_dir("framing");
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    // An open box (y up) whose opening faces +z, as McGuire's Cornell box: the first framing
    // (from −z) sees only the back of its back wall; the picture must look in from +z.
    let open = dir.join("open.obj");
    std::fs::write(dir.join("m.mtl"), MTL).unwrap();
    std::fs::write(
        &open,
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
         usemtl grey\n\
         f 1 2 3 4\n\
         f 1 5 6 2\n\
         f 1 4 8 5\n\
         f 2 6 7 3\n\
         usemtl lamp\nf 4 3 7 8\n",
    )
    .unwrap();
    let png = dir.join("open.png");
    let o = radiosity(&["render", &s(&open), "-o", &s(&png), "--size", "32"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("shows nothing"), "{}", stderr(&o));
    let o = radiosity(&["info", &s(&open), "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let eye = json["framing"]["eye"][2].as_f64().unwrap();
    assert!(eye > 1.0, "looks in from +z: eye z = {eye}");

    // A closed room: from outside every side shows backs, so the picture is taken from
    // inside at eye height and shows something; a camera outside it is warned about.
    let furnace = dir.join("furnace.obj");
    let o = radiosity(&["generate", "furnace", "-o", &s(&furnace)]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let png = dir.join("furnace.png");
    // A small, quick render of the furnace room with `extra` options.
    let render = |extra: &[&str]| {
        let (furnace, png) = (s(&furnace), s(&png));
        let mut args = vec![
            "render",
            &furnace,
            "-o",
            &png,
            "--size",
            "32",
            "--refine",
            "0",
            "--gather",
            "none",
            "--max-edge",
            "0.5",
        ];
        args.extend_from_slice(extra);
        radiosity(&args)
    };
    let o = render(&[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("shows nothing"), "{}", stderr(&o));
    let o = radiosity(&["info", &s(&furnace), "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let eye: Vec<f64> = (0..3)
        .map(|k| json["framing"]["eye"][k].as_f64().unwrap())
        .collect();
    let (lo, hi) = (&json["bounds_min"], &json["bounds_max"]);
    for k in 0..3 {
        let (lo, hi) = (lo[k].as_f64().unwrap(), hi[k].as_f64().unwrap());
        assert!(eye[k] > lo && eye[k] < hi, "inside the room: eye {eye:?}");
    }
    let o = render(&["--camera", "0.5,0.5,-5,0.5,0.5,0.5,0,1,0,40"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("warning: the picture shows nothing"),
        "{}",
        stderr(&o)
    );
    // --up names an axis: x, y or z.
    let o = radiosity(&[
        "render",
        &s(&open),
        "-o",
        &s(&png),
        "--size",
        "32",
        "--up",
        "q",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}
