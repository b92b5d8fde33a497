//! PLY scenes through every command: bake, render and info of a PLY with per-face materials,
//! overrides by the `ply_N` names, a baked PLY read back as a scene, and a bad PLY's error.

use crate::support::{radiosity, stderr, temp_dir};

/// A grey floor quad facing up (ply_0) and an emitting triangle above it facing down (ply_1),
/// per-face materials, ASCII; the faces are on lines 23 and 24.
const LIT_PLY: &str = "ply\nformat ascii 1.0\n\
    element vertex 7\nproperty float x\nproperty float y\nproperty float z\n\
    element face 2\nproperty list uchar int vertex_indices\n\
    property float reflectance_r\nproperty float reflectance_g\nproperty float reflectance_b\n\
    property float emission_r\nproperty float emission_g\nproperty float emission_b\n\
    end_header\n\
    0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.2 0.2 1\n0.8 0.2 1\n0.5 0.8 1\n\
    4 0 1 2 3 0.5 0.5 0.5 0 0 0\n\
    3 4 6 5 0 0 0 1 2 3\n";

#[test]
fn ply_scenes_bake_render_and_describe() {
    let dir = temp_dir("ply-scene");
    let input = dir.join("lit.ply");
    std::fs::write(&input, LIT_PLY).unwrap();
    let input = input.to_str().unwrap();
    let out = dir.join("out.ply");
    let out_s = out.to_str().unwrap();

    let o = radiosity(&["bake", input, "-o", out_s, "--max-edge", "0.5"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let p = radiosity::io::ply::read(&out).unwrap();
    let faces = p.face_radiance.unwrap();
    // The emitter's patches (ρ = 0) carry exactly Le; the floor's are lit but dimmer.
    let lamp = faces.iter().filter(|r| **r == [1.0, 2.0, 3.0]).count();
    assert!(lamp > 0 && lamp < faces.len(), "{lamp} of {}", faces.len());
    assert!(faces
        .iter()
        .all(|r| *r == [1.0, 2.0, 3.0] || (r[0] > 0.0 && r[0] < 1.0)));

    // The generated names are override targets.
    let o = radiosity(&["bake", input, "-o", out_s, "--emission", "ply_1=0"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("warning: no emitters"),
        "{}",
        stderr(&o)
    );

    let o = radiosity(&["info", input, "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["triangles"], 3);
    assert_eq!(json["materials"][0]["name"], "ply_0");
    assert_eq!(
        json["materials"][1]["emission"],
        serde_json::json!([1.0, 2.0, 3.0])
    );

    // A baked PLY is a scene too (radiance ignored, default material), and render bakes a
    // PLY that is not a baked one.
    let o = radiosity(&["info", out_s]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("default"));
    let png = dir.join("v.png");
    let o = radiosity(&[
        "render",
        input,
        "-o",
        png.to_str().unwrap(),
        "--size",
        "16",
        "-q",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(png.exists());

    // Errors name the file and line, exit 2.
    let bad = dir.join("bad.ply");
    std::fs::write(&bad, LIT_PLY.replace("3 4 6 5", "3 4 6 9")).unwrap();
    let o = radiosity(&["bake", bad.to_str().unwrap(), "-o", out_s]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("bad.ply:24: face 1: vertex index 9 out of range"),
        "{}",
        stderr(&o)
    );
    assert!(!stderr(&o).contains("panicked"));
}
