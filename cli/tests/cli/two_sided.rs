//! `--two-sided` through the binary: both sides in the output, deterministically for any
//! thread count; a baked PLY is not made two-sided again; `info --two-sided`.

use crate::support::{bake_cornell, cornell, radiosity, stderr, temp_dir};

#[test]
fn two_sided_bake_writes_both_sides_deterministically() {
    let dir = temp_dir("two-sided-bake");
    let (a, b, obj) = (dir.join("a.ply"), dir.join("b.ply"), dir.join("c.obj"));
    for (out, threads) in [(&a, "1"), (&b, "2"), (&obj, "2")] {
        // Without the display refinement, so that faces map to patches one to one.
        let o = bake_cornell(
            out,
            &[
                "--refine",
                "0",
                "--gather-tolerance",
                "0",
                "--two-sided",
                "--threads",
                threads,
            ],
        );
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
    }
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let two = radiosity::io::ply::read(&a).unwrap();
    let one_path = dir.join("one.ply");
    let o = bake_cornell(&one_path, &["--refine", "0", "--gather-tolerance", "0"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let one = radiosity::io::ply::read(&one_path).unwrap();
    // Twice the faces; the second half is the first reversed over the same positions, at
    // vertices of its own.
    let half = one.faces.len();
    assert_eq!(two.faces.len(), 2 * half);
    let fr = two.face_radiance.as_ref().unwrap();
    let mut outside_dark = 0;
    for k in 0..half {
        let (f, g) = (two.faces[k], two.faces[half + k]);
        let pos = |v: u32| two.positions[v as usize];
        assert_eq!([pos(f[0]), pos(f[2]), pos(f[1])], g.map(pos), "face {k}");
        assert!(
            f.iter().all(|v| !g.contains(v)),
            "face {k} shares a vertex with its back"
        );
        outside_dark += usize::from(fr[half + k] == [0.0; 3]);
    }
    // The walls', floor's and ceiling's backs face the outside, which is empty: black.
    assert!(
        outside_dark > half / 2,
        "{outside_dark} of {half} backs black"
    );
    let q = radiosity::io::obj::read(&obj).unwrap();
    assert_eq!(q.faces, two.faces);
}

#[test]
fn two_sided_render_of_a_baked_ply_is_refused_and_info_describes_both_sides() {
    let dir = temp_dir("two-sided-render");
    let input = cornell();
    let baked = dir.join("c.ply");
    let o = radiosity(&[
        "bake",
        &input,
        "-o",
        baked.to_str().unwrap(),
        "--max-edge",
        "150",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let png = dir.join("v.png");
    std::fs::write(&png, b"precious").unwrap();
    let o = radiosity(&[
        "render",
        baked.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--two-sided",
        "--size",
        "16",
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--two-sided") && err.contains("c.ply"),
        "{err}"
    );
    assert!(
        err.contains("bake the original scene with --two-sided"),
        "{err}"
    );
    assert_eq!(std::fs::read(&png).unwrap(), b"precious");
    // A scene is baked two-sided first and rendered.
    let o = radiosity(&[
        "render",
        &input,
        "-o",
        png.to_str().unwrap(),
        "--two-sided",
        "--max-edge",
        "150",
        "--size",
        "16",
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(image::open(&png).is_ok());

    let o = radiosity(&["info", &input, "--two-sided"]);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{}", stderr(&o));
    for needle in [
        "triangles:    64",
        "sides:        two: 32 faces",
        "area:         3868691",
    ] {
        assert!(text.contains(needle), "{needle} not in:\n{text}");
    }
    let o = radiosity(&["info", &input, "--two-sided", "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["two_sided"], true);
    assert_eq!(json["back_faces"], 32);
    // Both sides of the light emit: twice the one-sided power.
    let power = json["emitted_power"][0].as_f64().unwrap();
    let expected = 2.0 * std::f64::consts::PI * 17.0 * 13650.0;
    assert!((power - expected).abs() < 1e-3 * expected, "{power}");
    let o = radiosity(&["info", &input]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("sides:        one"));
}
