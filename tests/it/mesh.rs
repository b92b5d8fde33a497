//! The patch mesh (`radiosity::mesh`) under property tests (proptest, 64 cases from a fixed
//! seed, no failure files): patch areas sum to the input area, normals are unit and agree with
//! their source triangle, every input triangle yields at least one patch, no edge is longer
//! than the limit, and the mesh is conforming (every patch edge is shared by two patches unless
//! it lies on the input mesh's boundary; none by more than two). What belongs here: invariants
//! of subdivision and refinement over generated inputs.

use std::collections::HashMap;

use glam::DVec3;
use proptest::prelude::*;
use radiosity::mesh;
use radiosity::scene::{Scene, SceneBuilder};

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
        let p = mesh::subdivide(&scene, max_edge, mesh::DEFAULT_CREASE_DEGREES).unwrap();
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
