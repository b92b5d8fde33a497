//! Unit tests of the patch mesh: subdivision (area, orientation, edge bound, conformity),
//! refinement, corner normals, twins mirrored, bad max_edge.

use std::collections::HashMap;

use super::subdivide::barycentric;
use super::*;
use crate::scene::SceneBuilder;

fn two_quads() -> Scene {
    // An L: a floor quad and a wall quad sharing the edge x ∈ [0, 1], y = z = 0.
    let mut b = SceneBuilder::new();
    let m = b.material("white", [0.5; 3], [0.0; 3]);
    b.quad(
        [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 0.0),
        ],
        m,
    );
    b.quad(
        [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 0.7, 0.0),
            DVec3::new(0.0, 0.7, 0.0),
        ],
        m,
    );
    b.build().unwrap()
}

#[test]
fn subdivision_preserves_area_orientation_and_edge_bound() {
    let scene = two_quads();
    for max_edge in [2.0, 0.5, 0.3, 0.11, 0.05] {
        let p = subdivide(&scene, max_edge, DEFAULT_CREASE_DEGREES).unwrap();
        p.validate().unwrap();
        // Area is preserved exactly up to rounding (children tile the parent).
        assert!((p.total_area() - 1.7).abs() < 1e-12, "{}", p.total_area());
        for i in 0..p.len() {
            let c = p.corners(i);
            for k in 0..3 {
                assert!(c[k].distance(c[(k + 1) % 3]) <= max_edge * (1.0 + 1e-9));
            }
            // Children keep the parent's normal.
            let parent = p.source_triangle[i] as usize;
            let t = scene.triangles[parent]
                .vertices
                .map(|v| scene.positions[v as usize]);
            let n0 = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
            assert!(p.normal[i].dot(n0) > 1.0 - 1e-12);
        }
    }
}

/// Panics unless the patch mesh is conforming: every edge is used by exactly two patches
/// (interior or shared edge) or by one (open boundary of the input), and no vertex lies
/// inside a boundary edge (a T-junction).
fn assert_conforming(p: &Patches) {
    let mut uses: HashMap<(u32, u32), i32> = HashMap::new();
    for t in &p.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *uses.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    assert!(uses.values().all(|&u| u == 1 || u == 2));
    // A T-junction would leave a vertex lying in the interior of some other edge.
    for (&(a, b), _) in uses.iter().filter(|(_, &u)| u == 1) {
        let (pa, pb) = (p.positions[a as usize], p.positions[b as usize]);
        for (v, &q) in p.positions.iter().enumerate() {
            if v as u32 == a || v as u32 == b {
                continue;
            }
            let t = (q - pa).dot(pb - pa) / (pb - pa).length_squared();
            let off = (pa + t * (pb - pa)).distance(q);
            assert!(
                !(t > 1e-9 && t < 1.0 - 1e-9 && off < 1e-12),
                "T-junction at {q}"
            );
        }
    }
}

#[test]
fn subdivision_is_conforming() {
    let scene = two_quads();
    assert_conforming(&subdivide(&scene, 0.13, DEFAULT_CREASE_DEGREES).unwrap());
}

#[test]
fn refinement_splits_marked_patches_and_stays_conforming() {
    let scene = two_quads();
    let p = subdivide(&scene, 0.3, DEFAULT_CREASE_DEGREES).unwrap();
    // Mark every third patch, including some on the crease between the two quads.
    let marked: Vec<bool> = (0..p.len()).map(|i| i % 3 == 0).collect();
    let r = refine(&scene, &p, &marked, DEFAULT_CREASE_DEGREES).unwrap();
    r.validate().unwrap();
    assert_conforming(&r);
    assert!((r.total_area() - p.total_area()).abs() < 1e-12);
    // Each marked patch became 4, and a neighbour of a marked patch at least 2.
    let marked_count = marked.iter().filter(|&&m| m).count();
    assert!(
        r.len() >= p.len() + 3 * marked_count,
        "{} → {}",
        p.len(),
        r.len()
    );
    // No patch grew.
    let largest = |q: &Patches| q.area.iter().cloned().fold(0.0, f64::max);
    assert!(largest(&r) <= largest(&p) + 1e-15);
    // Marking nothing changes nothing.
    let same = refine(&scene, &p, &vec![false; p.len()], DEFAULT_CREASE_DEGREES).unwrap();
    assert_eq!(same.triangles, p.triangles);
}

#[test]
fn corner_normals_are_exact_on_a_sphere_and_flat_across_creases() {
    // Max's weights give the exact normal at any vertex whose neighbours lie on a sphere,
    // however irregular the fan: the geodesic sphere's corner normals are radial (inward,
    // its front side) to rounding.
    let sphere =
        crate::validation::scenes::integrating_sphere(2.0, 2, 30.0, 0.5, [1.0; 3]).unwrap();
    let normals = corner_normals(&sphere, DEFAULT_CREASE_DEGREES);
    for (tri, corners) in sphere.triangles.iter().zip(&normals) {
        for (v, n) in tri.vertices.iter().zip(corners) {
            let radial = -sphere.positions[*v as usize].normalize();
            assert!((*n - radial).length() < 1e-12, "vertex {v}");
        }
    }
    // With a crease angle of 0 every corner keeps its facet's normal.
    for (t, n) in corner_normals(&sphere, 0.0).iter().enumerate() {
        let [a, b, c] = sphere.triangles[t]
            .vertices
            .map(|v| sphere.positions[v as usize]);
        let facet = (b - a).cross(c - a).normalize();
        assert!(n.iter().all(|m| (*m - facet).length() < 1e-15));
    }
    // The L of two quads meets at 90°: a crease, so both keep their own normals, and
    // sub-patches carry them unchanged.
    let scene = two_quads();
    let p = subdivide(&scene, 0.3, DEFAULT_CREASE_DEGREES).unwrap();
    for i in 0..p.len() {
        for m in p.corner_normal[i] {
            assert!((m - p.normal[i]).length() < 1e-12);
        }
        assert!((p.surface_normal(i, [0.2, 0.3, 0.5]) - p.normal[i]).length() < 1e-12);
    }
}

#[test]
fn sub_patch_normals_interpolate_the_source_triangle() {
    // Subdividing a smooth triangle must not change its normal field: at any point the
    // sub-patch's surface normal equals the interpolation in the source triangle.
    let sphere =
        crate::validation::scenes::integrating_sphere(1.0, 1, 30.0, 0.5, [1.0; 3]).unwrap();
    let coarse = corner_normals(&sphere, DEFAULT_CREASE_DEGREES);
    let p = subdivide(&sphere, 0.2, DEFAULT_CREASE_DEGREES).unwrap();
    assert!(p.len() > 4 * sphere.triangles.len());
    p.validate().unwrap();
    for i in (0..p.len()).step_by(7) {
        let b = [0.6, 0.3, 0.1];
        let c = p.corners(i);
        let x = b[0] * c[0] + b[1] * c[1] + b[2] * c[2];
        let src = p.source_triangle[i] as usize;
        let t = sphere.triangles[src]
            .vertices
            .map(|v| sphere.positions[v as usize]);
        let w = barycentric(x, t);
        let expected =
            (w[0] * coarse[src][0] + w[1] * coarse[src][1] + w[2] * coarse[src][2]).normalize();
        assert!((p.surface_normal(i, b) - expected).length() < 1e-12, "{i}");
    }
}

#[test]
fn backs_mirror_fronts_where_a_second_subdivision_would_cut_differently() {
    // An isosceles triangle whose two long sides are split: the remaining quad's diagonals
    // tie, and the tie goes by vertex order, which the reverse changes.
    let corners = |p: &Patches, i: usize| {
        let mut c: Vec<[u64; 3]> = p
            .corners(i)
            .iter()
            .map(|v| v.to_array().map(f64::to_bits))
            .collect();
        c.sort();
        c
    };
    let mut b = SceneBuilder::new();
    let m = b.material("white", [0.5; 3], [0.0; 3]);
    let v = [
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(0.5, 2.0, 0.0),
    ]
    .map(|p| b.vertex(p));
    b.triangle([v[0], v[1], v[2]], m);
    let front_only = b.clone().build().unwrap();
    // The reverse given as a face of its own (one-sided) is cut the other way.
    b.triangle([v[0], v[2], v[1]], m);
    let both = b.build().unwrap();
    let p = subdivide(&both, 1.5, 0.0).unwrap();
    let of = |src: u32| {
        let mut all: Vec<_> = (0..p.len())
            .filter(|&i| p.source_triangle[i] == src)
            .map(|i| corners(&p, i))
            .collect();
        all.sort();
        all
    };
    assert_eq!(p.len(), 6);
    assert_ne!(of(0), of(1));
    // Made two-sided, the back's patches are the front's mirrored.
    let mut two = front_only.clone();
    two.make_two_sided();
    let p = subdivide(&two, 1.5, 0.0).unwrap();
    p.validate().unwrap();
    assert_eq!(p.len(), 6);
    for i in 0..3 {
        let j = p.twin[i] as usize;
        assert_eq!((j, p.twin[j] as usize), (i + 3, i));
        let [a, b, c] = p.corners(i);
        assert_eq!(p.corners(j), [a, c, b]);
        assert_eq!(p.normal[j], -p.normal[i]);
        assert_eq!(p.source_triangle[j], 1);
        // Own vertex copies: the sides never share an output vertex.
        assert!(p.triangles[i].iter().all(|v| !p.triangles[j].contains(v)));
    }
    assert_eq!(
        subdivide(&front_only, 1.5, 0.0).unwrap().twin,
        [NO_TWIN; 3],
        "one-sided scenes have no twins"
    );
}

#[test]
fn bad_max_edge_is_a_usage_error() {
    let scene = two_quads();
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e-9] {
        let err = subdivide(&scene, bad, DEFAULT_CREASE_DEGREES).unwrap_err();
        assert!(matches!(err, Error::Setting { .. }), "{bad}: {err}");
    }
}
