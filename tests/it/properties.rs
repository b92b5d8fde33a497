//! Property tests (proptest, 64 cases from a fixed seed, no failure files) for the geometry and subdivision invariants: patch areas sum to
//! the input area, normals are unit and agree with their source triangle, every input
//! triangle yields at least one patch, and the patch mesh is conforming (every patch edge is
//! shared by two patches unless it lies on the input mesh's boundary; none by more than two).
//! Plus a deterministic "fuzz-lite": thousands of mutated Cornell OBJs and PLY scenes (ASCII
//! and binary) through `Scene::load` + `patch::subdivide`, asserting no panic.

use std::collections::HashMap;

use glam::DVec3;
use proptest::prelude::*;
use radiosity::patch;
use radiosity::scene::{Scene, SceneBuilder};

use crate::support::{meshes, temp_dir};

/// A strip of `n` triangles over random points: triangle k is (p_k, p_{k+1}, p_{k+2}) with
/// alternating orientation so neighbours wind consistently; shared edges are welded.
fn strip(points: &[[f64; 3]], scale: f64) -> Option<Scene> {
    let mut b = SceneBuilder::new();
    let m = b.material("grey", [0.5; 3], [0.0; 3]);
    let v: Vec<u32> = points
        .iter()
        .map(|p| b.vertex(DVec3::from_array(*p) * scale))
        .collect();
    for k in 0..v.len() - 2 {
        let t = if k % 2 == 0 {
            [v[k], v[k + 1], v[k + 2]]
        } else {
            [v[k + 1], v[k], v[k + 2]]
        };
        b.triangle(t, m);
    }
    // Random points can make every triangle degenerate: that is a (tested) error, not a
    // property failure.
    b.build().ok()
}

/// Undirected edge key.
fn key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// Distance from `p` to the segment a–b.
fn distance_to_segment(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let d = b - a;
    let t = ((p - a).dot(d) / d.length_squared()).clamp(0.0, 1.0);
    (a + t * d).distance(p)
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 64,
        failure_persistence: None,
        rng_seed: proptest::test_runner::RngSeed::Fixed(5),
        ..ProptestConfig::default()
    })]

    #[test]
    fn subdivision_preserves_area_normals_and_conformity(
        points in prop::collection::vec(prop::array::uniform3(-1.0f64..1.0), 3..9),
        scale in prop::sample::select(vec![1e-3, 1.0, 1e3]),
        fraction in 0.05f64..1.5,
    ) {
        let Some(scene) = strip(&points, scale) else { return Ok(()) };
        let (lo, hi) = scene.bounds();
        let max_edge = fraction * (hi - lo).length();
        let p = patch::subdivide(&scene, max_edge, patch::DEFAULT_CREASE_DEGREES).unwrap();
        p.validate().unwrap();

        // Areas: every split is exact up to rounding: 1e-9 relative.
        let input: f64 = (0..scene.triangles.len()).map(|t| scene.triangle_area(t)).sum();
        let total = p.total_area();
        prop_assert!((total - input).abs() <= 1e-9 * input, "{} vs {}", total, input);

        // Every input triangle yields ≥ 1 patch; normals unit and equal to the source's.
        let mut count = vec![0usize; scene.triangles.len()];
        for i in 0..p.len() {
            let src = p.source_triangle[i] as usize;
            count[src] += 1;
            let [a, b, c] = scene.triangles[src].vertices.map(|v| scene.positions[v as usize]);
            let n = (b - a).cross(c - a).normalize();
            prop_assert!((p.normal[i].length() - 1.0).abs() < 1e-12);
            prop_assert!(p.normal[i].dot(n) > 1.0 - 1e-9, "patch {} normal {} vs {}", i, p.normal[i], n);
            prop_assert!(p.corners(i).iter().all(|c| (*c - a).dot(n).abs() <= 1e-9 * (hi - lo).length()));
            // No edge longer than max-edge (the subdivision's slack is 1e-12 relative).
            let q = p.corners(i);
            for k in 0..3 {
                prop_assert!(q[k].distance(q[(k + 1) % 3]) <= max_edge * (1.0 + 1e-9));
            }
        }
        prop_assert!(count.iter().all(|&c| c >= 1), "{:?}", count);

        // Conforming: count patch edges; an edge used once must lie on an input boundary
        // edge (an input edge used by one triangle); none used more than twice.
        let mut uses: HashMap<(u32, u32), usize> = HashMap::new();
        for t in &p.triangles {
            for k in 0..3 {
                *uses.entry(key(t[k], t[(k + 1) % 3])).or_default() += 1;
            }
        }
        let mut input_uses: HashMap<(u32, u32), usize> = HashMap::new();
        for t in &scene.triangles {
            let v = t.vertices;
            for k in 0..3 {
                *input_uses.entry(key(v[k], v[(k + 1) % 3])).or_default() += 1;
            }
        }
        let boundary: Vec<(DVec3, DVec3)> = input_uses
            .iter()
            .filter(|(_, &n)| n == 1)
            .map(|(&(a, b), _)| (scene.positions[a as usize], scene.positions[b as usize]))
            .collect();
        let tol = 1e-9 * (hi - lo).length();
        for (&(a, b), &n) in &uses {
            prop_assert!(n <= 2, "edge {:?} used {} times", (a, b), n);
            if n == 1 {
                let (pa, pb) = (p.positions[a as usize], p.positions[b as usize]);
                prop_assert!(
                    boundary.iter().any(|&(x, y)| distance_to_segment(pa, x, y) <= tol
                        && distance_to_segment(pb, x, y) <= tol),
                    "patch edge {} – {} is open but not on the input boundary (T-junction)", pa, pb
                );
            }
        }
    }
}

/// A tiny deterministic generator (SplitMix64) for the mutations.
struct Mix(u64);

impl Mix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

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
    let mesh = radiosity::export::BakedMesh {
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
    radiosity::export::ply::write_to(&mut binary, &mesh, 1.0, false).unwrap();
    mutate_and_load(&binary, &dir.join("b.ply"), 1500, 0xB1A);
    let _ = std::fs::remove_dir_all(dir);
}

/// Writes `cases` mutations of `original` (byte flips, deletions, duplications, token
/// insertions; seeded) to `path` and loads each with `Scene::load`, subdividing what loads.
/// Asserts no panic (saving the crashing input beside `path`), that loaded scenes and their
/// patches validate, and that both loads and rejections occur.
fn mutate_and_load(original: &[u8], path: &std::path::Path, cases: usize, seed: u64) {
    let mut rng = Mix(seed);
    let (mut loaded, mut rejected) = (0, 0);
    for case in 0..cases {
        let mut bytes = original.to_vec();
        for _ in 0..1 + rng.below(4) {
            let at = rng.below(bytes.len());
            match rng.below(5) {
                0 => bytes[at] = rng.next() as u8,
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
                let p = patch::subdivide(
                    &scene,
                    (hi - lo).length() / 4.0,
                    patch::DEFAULT_CREASE_DEGREES,
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
