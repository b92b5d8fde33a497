//! The scene loaders (`radiosity::io`) under hostile bytes: a deterministic "fuzz-lite" of
//! thousands of mutated Cornell OBJs and PLY scenes (ASCII and binary) through `Scene::load`
//! and `mesh::subdivide`, asserting no panic and that whatever loads is valid. What belongs
//! here: loader robustness that needs no hand-written expectation (the exact messages of bad
//! input are checked by the loaders' unit tests and the command-line tests).

use radiosity::mesh;
use radiosity::sampling::Rng;
use radiosity::scene::Scene;

use crate::support::{meshes, temp_dir};

/// Tokens a mutation may insert: numbers at the edges of what parses, keywords, separators.
const TOKENS: &[&str] = &[
    " ",
    "\n",
    "/",
    "-",
    "0",
    "1",
    "-1",
    "nan",
    "inf",
    "1e39",
    "-0",
    "1e-300",
    "f ",
    "v ",
    "usemtl light\n",
    "usemtl ",
    "mtllib ",
    "mtllib cornell_box.mtl\n",
    "o x\n",
    "g\n",
    "f 1 2 3\n",
    "f -1 -2 -3\n",
    "f 1 1 1\n",
    "v 0 0 0\n",
    "4294967296",
    "#",
    "\t",
    "\r",
    "é",
    "\u{0}",
    "element face 4294967295\n",
    "property list uint uint vertex_indices\n",
    "property float emission_r\n",
    "\u{ff}\u{ff}\u{ff}\u{7f}",
];

#[test]
fn fuzz_lite_mutated_cornell_never_panics() {
    // 3000 variants (≈ 1 s): byte flips, deletions, duplications and token insertions on the
    // Cornell OBJ, each loaded and (when it loads) subdivided. The property is only "no
    // panic, and a loaded scene satisfies its documented invariants".
    let dir = temp_dir("fuzz-lite");
    let original = std::fs::read(meshes().join("cornell_box.obj")).unwrap();
    std::fs::copy(
        meshes().join("cornell_box.mtl"),
        dir.join("cornell_box.mtl"),
    )
    .unwrap();
    mutate_and_load(&original, &dir.join("m.obj"), 3000, 0x5EED);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn fuzz_lite_mutated_ply_never_panics() {
    // The same for PLY scenes: an ASCII one with per-face materials and a binary one as
    // `radiosity bake` writes it (the binary body is where a length or index read from the
    // file could send a reader astray).
    let dir = temp_dir("fuzz-lite-ply");
    let ascii = "ply\nformat ascii 1.0\ncomment lit floor\n\
        element vertex 7\nproperty float x\nproperty float y\nproperty float z\n\
        element face 2\nproperty list uchar int vertex_indices\n\
        property float reflectance_r\nproperty float reflectance_g\nproperty float reflectance_b\n\
        property float emission_r\nproperty float emission_g\nproperty float emission_b\n\
        end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.2 0.2 1\n0.8 0.2 1\n0.5 0.8 1\n\
        4 0 1 2 3 0.5 0.5 0.5 0 0 0\n3 4 6 5 0 0 0 1 2 3\n";
    mutate_and_load(ascii.as_bytes(), &dir.join("a.ply"), 1500, 0xA5C11);
    let mesh = radiosity::bake::BakedMesh {
        positions: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ],
        vertex_radiance: vec![[0.5; 3]; 4],
        faces: vec![[0, 1, 2], [0, 2, 3]],
        face_radiance: vec![[0.5; 3]; 2],
        camera: None,
    };
    let mut binary = Vec::new();
    radiosity::io::ply::write_to(&mut binary, &mesh, 1.0, false).unwrap();
    mutate_and_load(&binary, &dir.join("b.ply"), 1500, 0xB1A);
    let _ = std::fs::remove_dir_all(dir);
}

/// Writes `cases` mutations of `original` (byte flips, deletions, duplications, token
/// insertions; seeded) to `path` and loads each with `Scene::load`, subdividing what loads.
/// Asserts no panic (saving the crashing input beside `path`), that loaded scenes and their
/// patches validate, and that both loads and rejections occur.
fn mutate_and_load(original: &[u8], path: &std::path::Path, cases: usize, seed: u64) {
    let mut rng = Rng::new(&[seed]);
    let (mut loaded, mut rejected) = (0, 0);
    for case in 0..cases {
        let mut bytes = original.to_vec();
        for _ in 0..1 + rng.below(4) {
            let at = rng.below(bytes.len());
            match rng.below(5) {
                0 => bytes[at] = rng.next_u64() as u8,
                1 => {
                    let end = (at + rng.below(40)).min(bytes.len());
                    bytes.drain(at..end);
                }
                2 => {
                    let end = (at + rng.below(80)).min(bytes.len());
                    let chunk = bytes[at..end].to_vec();
                    bytes.splice(at..at, chunk);
                }
                _ => {
                    let t = TOKENS[rng.below(TOKENS.len())].as_bytes();
                    bytes.splice(at..at, t.iter().copied());
                }
            }
            if bytes.is_empty() {
                break;
            }
        }
        std::fs::write(path, &bytes).unwrap();
        let outcome = std::panic::catch_unwind(|| match Scene::load(path) {
            Ok(scene) => {
                scene.validate().unwrap();
                let (lo, hi) = scene.bounds();
                let p = mesh::subdivide(
                    &scene,
                    (hi - lo).length() / 4.0,
                    mesh::DEFAULT_CREASE_DEGREES,
                )
                .unwrap();
                p.validate().unwrap();
                true
            }
            Err(e) => {
                assert!(!e.to_string().is_empty());
                false
            }
        });
        match outcome {
            Ok(true) => loaded += 1,
            Ok(false) => rejected += 1,
            Err(_) => {
                let keep = path.with_extension(format!("crash-{case}"));
                std::fs::write(&keep, &bytes).unwrap();
                panic!("case {case} panicked; input saved to {}", keep.display());
            }
        }
    }
    // Both outcomes must occur, or the mutations are not exercising anything.
    let least = cases / 100;
    assert!(
        loaded > least && rejected > least,
        "{}: {loaded} loaded, {rejected} rejected",
        path.display()
    );
}
