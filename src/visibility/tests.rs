//! Unit tests of the visibility queries: the BVH against brute force on random scenes, closed
//! meshes watertight, open segments between touching and facing surfaces, scale and position
//! invariance, degenerate input, twins.

use super::*;
use crate::sampling;
use glam::dvec3;
use rayon::prelude::*;
use std::time::Instant;

/// SplitMix64 (Steele, Lea & Flood 2014): small, seedable, good enough for test inputs.
struct Rng(sampling::Rng);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }
    /// Uniform in [0, 1).
    fn f64(&mut self) -> f64 {
        self.0.next_f64()
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f64()
    }
    fn vec(&mut self, lo: f64, hi: f64) -> DVec3 {
        dvec3(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }
    fn index(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
    /// Uniform point on a triangle.
    fn on_triangle(&mut self, t: &[DVec3; 3]) -> DVec3 {
        let (mut a, mut b) = (self.f64(), self.f64());
        if a + b > 1.0 {
            (a, b) = (1.0 - a, 1.0 - b);
        }
        t[0] + a * (t[1] - t[0]) + b * (t[2] - t[0])
    }
    /// Uniform direction.
    fn direction(&mut self) -> DVec3 {
        loop {
            let d = self.vec(-1.0, 1.0);
            let l = d.length();
            if l > 0.1 && l <= 1.0 {
                return d / l;
            }
        }
    }
}

/// Closed axis-aligned box `[lo, hi]`, each face an `n × n` grid of squares split into two
/// triangles; vertices are shared exactly between faces and triangles. Outward winding.
fn grid_box(lo: DVec3, hi: DVec3, n: usize) -> Vec<[DVec3; 3]> {
    let mut tris = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [false, true] {
            let point = |i: usize, j: usize| {
                let mut p = DVec3::ZERO;
                p[axis] = if side { hi[axis] } else { lo[axis] };
                p[u] = lo[u] + (hi[u] - lo[u]) * i as f64 / n as f64;
                p[v] = lo[v] + (hi[v] - lo[v]) * j as f64 / n as f64;
                p
            };
            for i in 0..n {
                for j in 0..n {
                    let (a, b, c, d) = (
                        point(i, j),
                        point(i + 1, j),
                        point(i + 1, j + 1),
                        point(i, j + 1),
                    );
                    // Alternate the diagonal so vertices have 4 or 8 incident triangles.
                    let quads = if (i + j) % 2 == 0 {
                        [[a, b, c], [a, c, d]]
                    } else {
                        [[a, b, d], [b, c, d]]
                    };
                    for t in quads {
                        tris.push(if side { t } else { [t[0], t[2], t[1]] });
                    }
                }
            }
        }
    }
    tris
}

/// Random triangles of size ~1–3 in [0, 10]³ plus a closed 12-triangle box.
fn random_scene(rng: &mut Rng, n: usize) -> Vec<[DVec3; 3]> {
    let mut tris: Vec<[DVec3; 3]> = (0..n)
        .map(|_| {
            let c = rng.vec(0.0, 10.0);
            [
                c + rng.vec(-1.5, 1.5),
                c + rng.vec(-1.5, 1.5),
                c + rng.vec(-1.5, 1.5),
            ]
        })
        .collect();
    tris.extend(grid_box(dvec3(3.0, 3.5, 4.0), dvec3(5.0, 6.0, 5.5), 1));
    tris
}

/// Segments of three kinds: free endpoints, surface to surface (ignoring both triangles),
/// surface to free point (ignoring the start triangle).
fn random_segments(rng: &mut Rng, tris: &[[DVec3; 3]], n: usize) -> Vec<(DVec3, DVec3, [u32; 2])> {
    (0..n)
        .map(|k| match k % 3 {
            0 => (rng.vec(-1.0, 11.0), rng.vec(-1.0, 11.0), [NONE, NONE]),
            1 => {
                let (i, j) = (rng.index(tris.len()), rng.index(tris.len()));
                let (p, q) = (rng.on_triangle(&tris[i]), rng.on_triangle(&tris[j]));
                (p, q, [i as u32, j as u32])
            }
            _ => {
                let i = rng.index(tris.len());
                (
                    rng.on_triangle(&tris[i]),
                    rng.vec(-1.0, 11.0),
                    [i as u32, NONE],
                )
            }
        })
        .collect()
}

#[test]
fn bvh_matches_brute_force() {
    let mut rng = Rng(sampling::Rng::new(&[1]));
    let tris = random_scene(&mut rng, 300);
    let vis = Visibility::build(&tris);
    assert_eq!(vis.len(), 312);
    let segments = random_segments(&mut rng, &tris, 6000);
    let mut blocked = 0;
    for (k, &(p, q, ignore)) in segments.iter().enumerate() {
        let fast = vis.occluded(p, q, ignore);
        assert_eq!(
            fast,
            vis.occluded_brute_force(p, q, ignore),
            "segment {k}: {p} -> {q}, ignore {ignore:?}"
        );
        blocked += fast as usize;
    }
    // Both answers must be common, or the comparison proves little.
    assert!(
        blocked > 1000 && blocked < 5000,
        "{blocked} of 6000 blocked"
    );

    let mut hits = 0;
    for k in 0..3000 {
        let origin = rng.vec(-1.0, 11.0);
        let dir = rng.direction() * rng.range(0.1, 10.0);
        let t_max = if k % 2 == 0 {
            f64::INFINITY
        } else {
            rng.range(0.1, 3.0)
        };
        let ignore = if k % 3 == 0 {
            NONE
        } else {
            rng.index(tris.len()) as u32
        };
        let fast = vis.closest_hit(origin, dir, t_max, ignore);
        let slow = vis.closest_hit_brute_force(origin, dir, t_max, ignore);
        assert_eq!(fast, slow, "ray {k}: {origin} + t {dir}, t_max {t_max}");
        // The shadow ray's answer is the closest hit's, ray for ray.
        assert_eq!(
            vis.blocked(origin, dir, t_max, ignore),
            fast.is_some(),
            "ray {k}"
        );
        if let Some(h) = fast {
            hits += 1;
            assert!(h.t > 0.0 && h.t <= t_max && h.triangle != ignore);
            // The reported (t, u, v) describe the same point.
            let t = &tris[h.triangle as usize];
            let on_tri = (1.0 - h.u - h.v) * t[0] + h.u * t[1] + h.v * t[2];
            let on_ray = origin + h.t * dir;
            assert!((on_tri - on_ray).length() < 1e-4, "{on_tri} vs {on_ray}");
        }
    }
    assert!(hits > 500 && hits < 2900, "{hits} of 3000 rays hit");
}

/// Segments from interior points through each target to beyond it (scaled by 2 from the
/// interior point), all of which must be blocked by the closed `tris`.
fn assert_all_blocked(vis: &Visibility, inside: &[DVec3], targets: &[DVec3]) {
    let mut leaks = Vec::new();
    for &p in inside {
        for &x in targets {
            let q = p + 2.0 * (x - p);
            if !vis.occluded(p, q, [NONE, NONE]) {
                leaks.push((p, x));
            }
        }
    }
    assert!(
        leaks.is_empty(),
        "{} of {} segments leaked, first: {:?}",
        leaks.len(),
        inside.len() * targets.len(),
        leaks.first()
    );
}

/// Vertices, edge midpoints and face centres of a triangle list, deduplicated.
fn edge_and_vertex_targets(tris: &[[DVec3; 3]]) -> Vec<DVec3> {
    let mut v: Vec<DVec3> = tris
        .iter()
        .flat_map(|t| {
            [
                t[0],
                t[1],
                t[2],
                0.5 * (t[0] + t[1]),
                0.5 * (t[1] + t[2]),
                0.5 * (t[2] + t[0]),
            ]
        })
        .collect();
    v.sort_by(|a, b| a.to_array().partial_cmp(&b.to_array()).unwrap());
    v.dedup();
    v
}

#[test]
fn closed_meshes_are_watertight() {
    // Dyadic coordinates: the canonical frame (scale 512) and the rays are exact, so the rays
    // pass exactly through the shared vertices and edges and the f64 fallback is exercised.
    let inside = [
        dvec3(0.0, 0.0, 0.0),
        dvec3(0.25, -0.125, 0.375),
        dvec3(-0.5, 0.5, -0.25),
        dvec3(0.75, 0.0, -0.5),
    ];
    for n in [1, 16] {
        let tris = grid_box(DVec3::splat(-1.0), DVec3::splat(1.0), n);
        let vis = Visibility::build(&tris);
        let targets = edge_and_vertex_targets(&tris);
        assert!(targets.len() >= if n == 1 { 26 } else { 3000 });
        assert_all_blocked(&vis, &inside, &targets);
        // Non-dyadic interior points and random directions.
        let mut rng = Rng(sampling::Rng::new(&[2]));
        let random_inside: Vec<DVec3> = (0..64).map(|_| rng.vec(-0.99, 0.99)).collect();
        let random_outside: Vec<DVec3> = (0..64).map(|_| 3.0 * rng.direction()).collect();
        assert_all_blocked(&vis, &random_inside, &random_outside);
        // The test can fail: segments inside the box, or outside and clear of it, are free.
        assert!(!vis.occluded(inside[0], inside[1], [NONE, NONE]));
        assert!(!vis.occluded(dvec3(2.0, 2.0, 2.0), dvec3(2.0, -2.0, 2.0), [NONE, NONE]));
    }

    // The same grid with every vertex displaced (shared vertices identically): edges in
    // general position, coordinates not exactly representable.
    let mut rng = Rng(sampling::Rng::new(&[3]));
    let mut jitter = std::collections::HashMap::new();
    let tris: Vec<[DVec3; 3]> = grid_box(DVec3::splat(-1.0), DVec3::splat(1.0), 16)
        .iter()
        .map(|t| {
            t.map(|v| {
                let key = v.to_array().map(f64::to_bits);
                v + *jitter.entry(key).or_insert_with(|| rng.vec(-0.03, 0.03))
            })
        })
        .collect();
    let vis = Visibility::build(&tris);
    let targets = edge_and_vertex_targets(&tris);
    assert_all_blocked(&vis, &inside, &targets);
    let inside: Vec<DVec3> = (0..50).map(|_| rng.vec(-0.9, 0.9)).collect();
    let outside: Vec<DVec3> = (0..100).map(|_| 3.0 * rng.direction()).collect();
    assert_all_blocked(&vis, &inside, &outside);
}

#[test]
fn open_segment_between_touching_and_facing_surfaces() {
    // Floor z = 0 and wall x = 0 over [0, 1]², 4 × 4 grids, meeting along the y axis.
    let floor_and_wall: Vec<[DVec3; 3]> = grid_box(DVec3::ZERO, DVec3::ONE, 4)
        .into_iter()
        .filter(|t| t.iter().all(|v| v.z == 0.0) || t.iter().all(|v| v.x == 0.0))
        .collect();
    assert_eq!(floor_and_wall.len(), 64);
    let vis = Visibility::build(&floor_and_wall);
    let find = |p: DVec3| {
        let i = floor_and_wall
            .iter()
            .position(|t| {
                let n = (t[1] - t[0]).cross(t[2] - t[0]);
                let inside = (0..3).all(|k| (t[(k + 1) % 3] - t[k]).cross(p - t[k]).dot(n) > 0.0);
                inside && n.dot(p - t[0]).abs() < 1e-12
            })
            .expect("point on a triangle");
        i as u32
    };
    let mut rng = Rng(sampling::Rng::new(&[4]));
    let mut checked = 0;
    for k in 0..500 {
        // Half of the pairs close to each other near the shared edge (the corner, where the
        // form-factor kernel is largest), half anywhere.
        let (p, q) = if k % 2 == 0 {
            let r = 0.02;
            let p = dvec3(rng.range(0.0, r), rng.range(r, 1.0 - r), 0.0);
            (p, dvec3(0.0, p.y + rng.range(-r, r), rng.range(0.0, r)))
        } else {
            (
                dvec3(rng.f64(), rng.f64(), 0.0),
                dvec3(0.0, rng.f64(), rng.f64()),
            )
        };
        let (i, j) = (find(p), find(q));
        assert!(!vis.occluded(p, q, [i, j]), "{p} -> {q}");
        // Without `ignore`, the endpoints' own triangles count too, which rounding can only
        // resolve away from grazing angles (see `MIN_DISTANCE_REL`).
        let d = (q - p).normalize();
        if d.z.abs() > 0.05 && d.x.abs() > 0.05 {
            assert!(
                !vis.occluded(p, q, [NONE, NONE]),
                "{p} -> {q} without ignore"
            );
            checked += 1;
        }
        assert!(vis.closest_hit(p, q - p, 1.0 - 1e-3, i).is_none());
    }
    assert!(
        checked > 250,
        "{checked} of 500 pairs checked without ignore"
    );

    // Facing squares at z = 0 and z = 2 with a blocker at z = 1.
    let square = |z: f64, lo: f64, hi: f64| {
        let (a, b) = (dvec3(lo, lo, z), dvec3(hi, lo, z));
        let (c, d) = (dvec3(hi, hi, z), dvec3(lo, hi, z));
        [[a, b, c], [a, c, d]]
    };
    let mut tris = Vec::new();
    tris.extend(square(0.0, 0.0, 1.0)); // 0, 1
    tris.extend(square(2.0, 0.0, 1.0)); // 2, 3
    tris.extend(square(1.0, -1.0, 2.0)); // 4, 5: the blocker
    let vis = Visibility::build(&tris);
    for _ in 0..200 {
        let (i, j) = (rng.index(2), 2 + rng.index(2));
        let (p, q) = (rng.on_triangle(&tris[i]), rng.on_triangle(&tris[j]));
        let (i, j) = (i as u32, j as u32);
        assert!(vis.occluded(p, q, [i, j]));
        assert!(vis.occluded(p, q, [NONE, NONE]));
        assert!(vis.occluded(p, q, [4, NONE]) || vis.occluded(p, q, [5, NONE]));
        assert!(!vis.occluded(p, q, [4, 5]), "blocker ignored");
        let hit = vis.closest_hit(p, q - p, 1.0, i).expect("blocker hit");
        assert!(hit.triangle == 4 || hit.triangle == 5);
        assert!((hit.t - 0.5).abs() < 1e-6, "t = {}", hit.t);
    }
}

#[test]
fn answers_do_not_depend_on_scale_or_position() {
    let mut rng = Rng(sampling::Rng::new(&[5]));
    let tris = random_scene(&mut rng, 200);
    let segments = random_segments(&mut rng, &tris, 3000);
    let rays: Vec<(DVec3, DVec3)> = (0..1000)
        .map(|_| (rng.vec(-1.0, 11.0), rng.direction()))
        .collect();
    let answers = |scale: f64, offset: DVec3| {
        let map = |x: DVec3| x * scale + offset;
        let vis = Visibility::build(&tris.iter().map(|t| t.map(map)).collect::<Vec<_>>());
        let occluded: Vec<bool> = segments
            .iter()
            .map(|&(p, q, ignore)| vis.occluded(map(p), map(q), ignore))
            .collect();
        let hits: Vec<Option<(u32, f64)>> = rays
            .iter()
            .map(|&(o, d)| vis.closest_hit(map(o), d, f64::INFINITY, NONE))
            .map(|h| h.map(|h| (h.triangle, h.t / scale)))
            .collect();
        (occluded, hits)
    };
    let (occluded, hits) = answers(1.0, DVec3::ZERO);
    let blocked = occluded.iter().filter(|&&b| b).count();
    assert!(blocked > 500 && blocked < 2500, "{blocked} of 3000 blocked");
    for (scale, offset) in [
        (1e-3, DVec3::ZERO),
        (1e3, DVec3::ZERO),
        (1e-3, DVec3::splat(1e4)),
        (1e3, DVec3::splat(1e4)),
        (1.0, dvec3(1e4, -1e4, 1e4)),
    ] {
        let (o, h) = answers(scale, offset);
        assert_eq!(o, occluded, "scale {scale}, offset {offset}");
        for (k, (a, b)) in hits.iter().zip(&h).enumerate() {
            match (a, b) {
                (None, None) => {}
                (Some(a), Some(b)) => {
                    assert_eq!(a.0, b.0, "ray {k}, scale {scale}, offset {offset}");
                    assert!((a.1 - b.1).abs() <= 1e-5 * a.1.max(1.0), "{a:?} vs {b:?}");
                }
                _ => panic!("ray {k}, scale {scale}, offset {offset}: {a:?} vs {b:?}"),
            }
        }
    }
}

#[test]
fn empty_and_degenerate_inputs() {
    let vis = Visibility::build(&[]);
    assert!(vis.is_empty());
    assert_eq!(vis.len(), 0);
    let (p, q) = (DVec3::ZERO, DVec3::ONE);
    assert!(!vis.occluded(p, q, [NONE, NONE]));
    assert!(!vis.occluded_brute_force(p, q, [NONE, NONE]));
    assert_eq!(vis.closest_hit(p, q, f64::INFINITY, NONE), None);

    let point = [DVec3::ONE; 3];
    let segment = [DVec3::ZERO, DVec3::ONE, DVec3::splat(2.0)];
    let nan = [DVec3::ZERO, DVec3::X, DVec3::NAN];
    let real = [
        dvec3(-1.0, -1.0, 0.5),
        dvec3(3.0, -1.0, 0.5),
        dvec3(-1.0, 3.0, 0.5),
    ];

    // Only degenerate triangles: never occludes, never hits.
    let vis = Visibility::build(&[point, segment, nan]);
    assert_eq!(vis.len(), 3);
    assert!(!vis.is_empty());
    assert!(!vis.occluded(dvec3(1.0, 1.0, 0.0), dvec3(1.0, 1.0, 2.0), [NONE, NONE]));
    assert!(!vis.occluded(DVec3::ZERO, DVec3::splat(2.0), [NONE, NONE]));
    assert_eq!(vis.closest_hit(DVec3::ZERO, DVec3::ONE, 10.0, NONE), None);

    // Degenerate triangles around a real one: ids still refer to the input list.
    let vis = Visibility::build(&[point, segment, real, nan]);
    assert_eq!(vis.len(), 4);
    let (p, q) = (dvec3(0.5, 0.5, 0.0), dvec3(0.5, 0.5, 1.0));
    assert!(vis.occluded(p, q, [NONE, NONE]));
    assert!(vis.occluded(p, q, [0, 1]));
    assert!(!vis.occluded(p, q, [2, NONE]));
    assert!(!vis.occluded(p, p, [NONE, NONE]), "degenerate segment");
    let hit = vis.closest_hit(p, q - p, f64::INFINITY, NONE).expect("hit");
    assert_eq!(hit.triangle, 2);
    assert!((hit.t - 0.5).abs() < 1e-6);
    assert!(
        (hit.u - 0.375).abs() < 1e-6 && (hit.v - 0.375).abs() < 1e-6,
        "{hit:?}"
    );
    assert_eq!(
        vis.closest_hit(p, DVec3::ZERO, 1.0, NONE),
        None,
        "zero direction"
    );
    assert_eq!(vis.closest_hit(p, -DVec3::Z, f64::INFINITY, NONE), None);
}

/// `tris` followed by the reverse of each (corners rotated differently per triangle, so every
/// corner correspondence occurs), then one same-facing duplicate of triangle 0.
fn with_twins(tris: &[[DVec3; 3]]) -> Vec<[DVec3; 3]> {
    let mut all = tris.to_vec();
    for (k, &[a, b, c]) in tris.iter().enumerate() {
        all.push([[a, c, b], [c, b, a], [b, a, c]][k % 3]);
    }
    all.push(tris[0]);
    all
}

#[test]
fn twins_are_paired_deterministically() {
    let mut rng = Rng(sampling::Rng::new(&[7]));
    let tris = random_scene(&mut rng, 100);
    let n = tris.len() as u32;
    let all = with_twins(&tris);
    let vis = Visibility::build(&all);
    assert_eq!(vis.twin_pairs(), tris.len());
    for i in 0..n {
        assert_eq!(vis.twin(i), i + n, "{i}");
        assert_eq!(vis.twin(i + n), i, "{i}");
    }
    // The third copy (same winding as triangle 0) stays a separate triangle.
    assert_eq!(vis.twin(2 * n), NONE);
    assert_eq!(vis.twin(u32::MAX - 1), NONE);
    // One-sided scenes have no twins; a coincident same-facing pair is not one.
    let one = Visibility::build(&tris);
    assert_eq!((one.twin_pairs(), one.twin(0)), (0, NONE));
    assert_eq!(Visibility::build(&[tris[0], tris[0]]).twin_pairs(), 0);
    // −0.0 and +0.0 are the same corner.
    let t = [
        dvec3(-0.0, 0.0, 0.0),
        dvec3(1.0, 0.0, 0.0),
        dvec3(0.0, 1.0, 0.0),
    ];
    let r = [
        dvec3(0.0, 0.0, 0.0),
        dvec3(0.0, 1.0, 0.0),
        dvec3(1.0, 0.0, 0.0),
    ];
    assert_eq!(Visibility::build(&[t, r]).twin(0), 1);
}

#[test]
fn twins_block_like_one_surface_and_report_the_side_facing_the_ray() {
    let mut rng = Rng(sampling::Rng::new(&[8]));
    let tris = random_scene(&mut rng, 150);
    let n = tris.len() as u32;
    let one = Visibility::build(&tris);
    let two = Visibility::build(&with_twins(&tris));
    // Occlusion: the two-sided scene blocks exactly what the one-sided scene blocks, and
    // ignoring a triangle ignores its twin (either index names the surface).
    let twin = |i: u32| if i == NONE { NONE } else { i + n };
    for (k, (p, q, ignore)) in random_segments(&mut rng, &tris, 3000)
        .into_iter()
        .enumerate()
    {
        let expected = one.occluded(p, q, ignore);
        assert_eq!(two.occluded(p, q, ignore), expected, "segment {k}");
        assert_eq!(
            two.occluded(p, q, ignore.map(twin)),
            expected,
            "segment {k}"
        );
        assert_eq!(
            two.occluded_brute_force(p, q, ignore),
            expected,
            "segment {k}"
        );
    }
    // Closest hit: the same surface at the same distance, reported as the side whose front
    // faces the ray, with barycentrics of that side's own corners.
    let all = with_twins(&tris);
    let mut fronts = [0, 0];
    for k in 0..3000 {
        let (origin, dir) = (rng.vec(-1.0, 11.0), rng.direction());
        let ignore = if k % 2 == 0 {
            NONE
        } else {
            rng.index(tris.len()) as u32
        };
        let a = one.closest_hit(origin, dir, f64::INFINITY, ignore);
        let b = two.closest_hit(origin, dir, f64::INFINITY, twin(ignore));
        assert_eq!(
            b,
            two.closest_hit_brute_force(origin, dir, f64::INFINITY, ignore)
        );
        assert_eq!(b, two.closest_hit(origin, dir, f64::INFINITY, ignore));
        assert_eq!(two.blocked(origin, dir, f64::INFINITY, ignore), b.is_some());
        let (Some(a), Some(b)) = (a, b) else {
            assert_eq!(a.is_none(), b.is_none(), "ray {k}");
            continue;
        };
        assert_eq!(b.triangle % n, a.triangle, "ray {k}");
        assert_eq!(b.t, a.t, "ray {k}");
        let t = &all[b.triangle as usize];
        let normal = (t[1] - t[0]).cross(t[2] - t[0]);
        assert!(normal.dot(dir) < 0.0, "ray {k}: reported a back face");
        let on_tri = (1.0 - b.u - b.v) * t[0] + b.u * t[1] + b.v * t[2];
        assert!((on_tri - (origin + b.t * dir)).length() < 1e-4, "ray {k}");
        fronts[(b.triangle >= n) as usize] += 1;
    }
    assert!(fronts[0] > 300 && fronts[1] > 300, "{fronts:?}");
}

/// A closed room of 10 × 10 × 10, 26 × 26 squares per face, with ten boxes of 4 × 4 squares per
/// face placed at random inside: 10,032 triangles.
fn room_with_boxes(rng: &mut Rng) -> Vec<[DVec3; 3]> {
    let mut tris = grid_box(DVec3::ZERO, DVec3::splat(10.0), 26);
    for _ in 0..10 {
        let lo = rng.vec(0.5, 8.0);
        tris.extend(grid_box(lo, lo + rng.vec(0.5, 1.5), 4));
    }
    tris
}

/// The four-lane test (`bvh4`) decides every lane as the scalar watertight test does: random
/// triangles, triangles on an integer grid with rays aimed exactly at their corners and edges
/// (edge functions exactly zero: the `f64` recomputation), rays in a triangle's plane, −0.0
/// direction components, and scenes from 1e-3 to 1e3 canonical units; hit intervals that cut
/// hits at their ends.
#[test]
fn four_lane_triangle_test_equals_the_scalar_test() {
    use glam::Vec3A;
    let mut rng = Rng(sampling::Rng::new(&[13]));
    let (mut lanes, mut hits, mut on_edge) = (0usize, 0usize, 0usize);
    for case in 0..20_000 {
        let scale = [1e-3, 1.0, 1e3][case % 3];
        let grid = case % 2 == 1;
        let point = |rng: &mut Rng| {
            let v = rng.vec(-4.0, 4.0);
            if grid {
                v.round() * scale
            } else {
                v * scale
            }
        };
        let n = 1 + case % 4;
        let tris: Vec<[Vec3A; 3]> = (0..n)
            .map(|_| [0, 1, 2].map(|_| point(&mut rng).as_vec3a()))
            .collect();
        // Aim at a corner, an edge's midpoint or inside the first triangle, from a random
        // origin, or (one case in five) along the first triangle's plane.
        let t0 = tris[0].map(|v| v.as_dvec3());
        let target = match case % 3 {
            0 => t0[0],
            1 => 0.5 * (t0[0] + t0[1]),
            _ => rng.on_triangle(&t0),
        };
        let origin = if case % 5 == 0 {
            t0[1] + (t0[1] - t0[2]) * rng.range(0.5, 2.0)
        } else if grid {
            point(&mut rng) // exactly representable: rays exactly through corners and edges
        } else {
            point(&mut rng) + rng.vec(-1.0, 1.0) * scale * 0.01
        };
        let mut dir = target - origin;
        if case % 7 == 0 {
            dir = dir.with_x(-0.0);
        }
        let Some(ray) = ray::WatertightRay::new(origin, dir, 0.0, 2.0) else {
            continue;
        };
        let (t_lo, t_hi) = if case % 4 == 3 {
            (ray.t_lo, ray.t_lo + rng.range(0.0, 1.5) as f32)
        } else {
            (ray.t_lo, ray.t_hi)
        };
        let mask = bvh4::packet_hits(&tris, &ray, t_lo, t_hi);
        for lane in 0..4 {
            let tri = &tris[lane.min(n - 1)];
            let scalar = ray.intersect(tri, t_lo, t_hi).is_some();
            assert_eq!(
                mask >> lane & 1 == 1,
                scalar,
                "case {case}, lane {lane}: {tri:?}, ray {ray:?}, [{t_lo}, {t_hi}]"
            );
            lanes += 1;
            hits += scalar as usize;
            let [a, b, c] = tri.map(|v| v.as_dvec3() - ray.origin.as_dvec3());
            on_edge += (a.cross(b).dot(ray.dir.as_dvec3()) == 0.0
                || b.cross(c).dot(ray.dir.as_dvec3()) == 0.0
                || c.cross(a).dot(ray.dir.as_dvec3()) == 0.0) as usize;
        }
    }
    // Both answers must be common, and the edge cases present, or this proves little.
    assert!(
        hits > lanes / 10 && hits < lanes * 9 / 10,
        "{hits} hits of {lanes}"
    );
    assert!(
        on_edge > 3000,
        "{on_edge} lanes with the ray through an edge or corner"
    );
}

/// The traversal equals the brute-force oracle on a closed room of 10,032 triangles with ten
/// boxes inside, where one segment in nine runs inside a wall's plane (coplanar with every
/// triangle it passes), and on rays from the walls (closest hit).
#[test]
fn traversal_equals_brute_force_in_a_subdivided_room() {
    let mut rng = Rng(sampling::Rng::new(&[17]));
    let tris = room_with_boxes(&mut rng);
    let vis = Visibility::build(&tris);
    let mut blocked = 0;
    for k in 0..1500 {
        let (i, j) = (rng.index(tris.len()), rng.index(tris.len()));
        let (p, q) = (rng.on_triangle(&tris[i]), rng.on_triangle(&tris[j]));
        let ignore = [i as u32, j as u32];
        let fast = vis.occluded(p, q, ignore);
        assert_eq!(
            fast,
            vis.occluded_brute_force(p, q, ignore),
            "segment {k}: {p} -> {q}"
        );
        blocked += fast as usize;
        let dir = rng.direction();
        let fast = vis.closest_hit(p, dir, f64::INFINITY, i as u32);
        assert_eq!(
            fast,
            vis.closest_hit_brute_force(p, dir, f64::INFINITY, i as u32)
        );
    }
    assert!(blocked > 150 && blocked < 1000, "{blocked} of 1500 blocked");
}

/// The last-occluder cache ([`Visibility::occluded_points_after`]) answers every segment as
/// [`Visibility::occluded_points`] does, whatever triangle it remembers: runs of segments from
/// one surface point to random points of another triangle (the shadow rays' pattern, where the
/// cache hits), random segments between them, and a remembered triangle that the next
/// segment ignores or that lies behind its end. So that the cached path is what is tested, at
/// least a third of the runs' blocked segments must be answered by the remembered triangle
/// (measured: about half; a run's first blocked segment is the BVH's, and in this room of
/// boxes the blocker often changes along a run).
#[test]
fn the_last_occluder_cache_gives_the_single_rays_answers() {
    let mut rng = Rng(sampling::Rng::new(&[41]));
    let tris = room_with_boxes(&mut rng);
    let vis = Visibility::build(&tris);
    let mut last = usize::MAX;
    let (mut blocked, mut by_last) = (0, 0);
    for run in 0..150 {
        let (i, j) = (rng.index(tris.len()), rng.index(tris.len()));
        let p = vis.point(rng.on_triangle(&tris[i]));
        if run % 5 == 0 {
            last = j; // remembered, but ignored by the run's segments
        }
        for k in 0..16 {
            let (q, ignore) = if k % 8 == 7 {
                let (_, b, ig) = random_segments(&mut rng, &tris, 1)[0];
                (vis.point(b), ig)
            } else {
                (vis.point(rng.on_triangle(&tris[j])), [i as u32, j as u32])
            };
            let before = last;
            let cached = vis.occluded_points_after(&p, &q, ignore, &mut last);
            assert_eq!(
                cached,
                vis.occluded_points(&p, &q, ignore),
                "run {run}, segment {k}: remembered {before}"
            );
            if cached && k % 8 != 7 {
                blocked += 1;
                by_last += (last == before) as usize;
            }
        }
    }
    assert!(
        blocked > 200 && 3 * by_last > blocked,
        "{by_last} of {blocked} blocked segments by the remembered triangle"
    );
}

/// The light buffer (many segments from one origin) answers every segment as
/// [`Visibility::occluded_points`] does: random scenes of one, two and four 64-triangle words
/// and one past [`light_buffer::MAX_TRIANGLES`] (the fallback), a closed grid box whose
/// segments run from and to its vertices and edge midpoints (through shared edges, along its
/// faces: grazing and coplanar), twins, scenes scaled from 1e-3 to 1e3 and moved off the
/// origin, origins on a triangle (ignored) or free, targets on triangles (ignored), free, in
/// the origin's own plane, and the origin itself.
#[test]
fn light_buffer_answers_equal_single_rays() {
    let mut rng = Rng(sampling::Rng::new(&[29]));
    let mut scenes: Vec<Vec<[DVec3; 3]>> = [40, 100, 230, 300]
        .into_iter()
        .map(|n| random_scene(&mut rng, n))
        .collect();
    scenes.push(grid_box(DVec3::ZERO, dvec3(4.0, 3.0, 5.0), 3));
    let mut boxes = grid_box(DVec3::ZERO, DVec3::splat(10.0), 2);
    boxes.extend(grid_box(dvec3(2.0, 0.0, 2.0), dvec3(5.0, 4.0, 6.0), 2));
    scenes.push(with_twins(&boxes));
    let (mut queries, mut blocked) = (0usize, 0usize);
    for (s, base) in scenes.iter().enumerate() {
        for (scale, offset) in [
            (1.0, DVec3::ZERO),
            (1e-3, dvec3(7.0, -3.0, 1.0)),
            (1e3, DVec3::splat(-2e4)),
        ] {
            let tris: Vec<[DVec3; 3]> =
                base.iter().map(|t| t.map(|v| v * scale + offset)).collect();
            let vis = Visibility::build(&tris);
            let special = edge_and_vertex_targets(&tris);
            let mut buffer = LightBuffer::new(&vis);
            for o in 0..24 {
                // Origins: on a triangle (ignored), at a vertex or edge midpoint, or free.
                let (origin, ig0) = match o % 3 {
                    0 => {
                        let i = rng.index(tris.len());
                        (rng.on_triangle(&tris[i]), i as u32)
                    }
                    1 => (special[rng.index(special.len())], NONE),
                    _ => (rng.vec(-1.0, 11.0) * scale + offset, NONE),
                };
                let p = vis.point(origin);
                buffer.aim(&p, ig0);
                for k in 0..400 {
                    let (target, ig1) = match k % 5 {
                        0 | 1 => {
                            let j = rng.index(tris.len());
                            (rng.on_triangle(&tris[j]), j as u32)
                        }
                        2 => (special[rng.index(special.len())], NONE),
                        3 if ig0 != NONE => {
                            // In the origin's own plane: a grazing or coplanar segment.
                            let t = &tris[ig0 as usize];
                            let (u, v) = (rng.range(-2.0, 2.0), rng.range(-2.0, 2.0));
                            (t[0] + u * (t[1] - t[0]) + v * (t[2] - t[0]), NONE)
                        }
                        3 => (origin, NONE),
                        _ => (rng.vec(-1.0, 11.0) * scale + offset, NONE),
                    };
                    let q = vis.point(target);
                    let expected = vis.occluded_points(&p, &q, [ig0, ig1]);
                    assert_eq!(
                        buffer.occluded(&q, ig1),
                        expected,
                        "scene {s} scale {scale}: {origin} (ignoring {ig0}) -> {target} (ignoring {ig1})"
                    );
                    queries += 1;
                    blocked += expected as usize;
                }
            }
        }
    }
    // Both answers are exercised in earnest.
    assert!(
        blocked > queries / 10 && blocked < queries * 9 / 10,
        "{blocked} of {queries}"
    );
}

/// `cargo test --release -- --ignored --nocapture throughput`
#[test]
#[ignore]
fn throughput() {
    let mut rng = Rng(sampling::Rng::new(&[6]));
    let tris = room_with_boxes(&mut rng);
    let start = Instant::now();
    let vis = Visibility::build(&tris);
    println!("{} triangles, build {:.1?}", tris.len(), start.elapsed());
    let segments: Vec<(DVec3, DVec3, [u32; 2])> = (0..1_000_000)
        .map(|_| {
            let (i, j) = (rng.index(tris.len()), rng.index(tris.len()));
            let (p, q) = (rng.on_triangle(&tris[i]), rng.on_triangle(&tris[j]));
            (p, q, [i as u32, j as u32])
        })
        .collect();
    let start = Instant::now();
    let blocked = segments
        .iter()
        .filter(|s| vis.occluded(s.0, s.1, s.2))
        .count();
    let secs = start.elapsed().as_secs_f64();
    println!(
        "occluded, 1 thread: {:.2} M rays/s ({blocked} blocked)",
        segments.len() as f64 / secs / 1e6
    );
    let start = Instant::now();
    let blocked_par = segments
        .par_iter()
        .filter(|s| vis.occluded(s.0, s.1, s.2))
        .count();
    let secs = start.elapsed().as_secs_f64();
    println!(
        "occluded, rayon ({} threads): {:.2} M rays/s",
        rayon::current_num_threads(),
        segments.len() as f64 / secs / 1e6
    );
    assert_eq!(blocked, blocked_par);
    let start = Instant::now();
    let hits = segments
        .iter()
        .filter(|s| {
            vis.closest_hit(s.0, s.1 - s.0, f64::INFINITY, s.2[0])
                .is_some()
        })
        .count();
    let secs = start.elapsed().as_secs_f64();
    println!(
        "closest_hit, 1 thread: {:.2} M rays/s ({hits} hits)",
        segments.len() as f64 / secs / 1e6
    );
}

/// A leg (a closed box) under a table top (another) whose underside its top touches: a point
/// on the floor inside the leg's footprint sees the leg's top from behind and the underside
/// from the front at the same distance, and is buried whichever order the triangles come in
/// (`closest_hit` reports whichever rounds nearer or comes first: the underside, at four of
/// the six points inside); beside the leg it sees the underside's front.
#[test]
fn a_back_among_coincident_first_hits_is_seen_from_behind() {
    let leg = grid_box(dvec3(0.0, 0.0, 0.0), dvec3(1.0, 1.0, 4.0), 1);
    let table = grid_box(dvec3(-2.0, -2.0, 4.0), dvec3(3.0, 3.0, 5.0), 3);
    for leg_first in [true, false] {
        let tris: Vec<[DVec3; 3]> = if leg_first {
            leg.iter().chain(&table).copied().collect()
        } else {
            table.iter().chain(&leg).copied().collect()
        };
        let vis = Visibility::build(&tris);
        for (x, y) in [(0.5, 0.5), (0.2, 0.9), (0.999, 0.001)] {
            let from = dvec3(x, y, 1e-6);
            assert_eq!(
                vis.first_hit_from_behind(from, DVec3::Z, NONE),
                Some(true),
                "inside the leg at ({x}, {y}), leg first: {leg_first}"
            );
        }
        for (x, y) in [(1.5, 0.5), (-0.5, -0.5), (2.9, 2.9)] {
            let from = dvec3(x, y, 1e-6);
            assert_eq!(
                vis.first_hit_from_behind(from, DVec3::Z, NONE),
                Some(false),
                "beside the leg at ({x}, {y}), leg first: {leg_first}"
            );
        }
        assert_eq!(
            vis.first_hit_from_behind(dvec3(9.0, 9.0, 0.0), DVec3::Z, NONE),
            None
        );
        // Twins: a two-sided surface is never seen from behind.
        let [a, b, c] = [
            dvec3(0.0, 0.0, 1.0),
            dvec3(1.0, 0.0, 1.0),
            dvec3(0.0, 1.0, 1.0),
        ];
        let vis = Visibility::build(&[[a, b, c], [a, c, b]]);
        assert_eq!(vis.twin_pairs(), 1);
        for dir in [DVec3::Z, -DVec3::Z] {
            let from = dvec3(0.2, 0.2, 1.0) - dir;
            assert_eq!(vis.first_hit_from_behind(from, dir, NONE), Some(false));
        }
    }
}

/// A box resting on a floor, and one floating just above it: the resting box's bottom lies
/// face to face on the floor and is buried, though nothing lies beyond it (its normal ray
/// meets nothing: `first_hit_from_behind` alone says None); the floor under it is buried too.
/// Beside the box, on its sides, and under the floating box (a gap of 1e-3, far above the
/// contact distance) nothing is; nor is a point on the floor's coplanar neighbour, which faces
/// the same way.
#[test]
fn a_face_lying_on_another_is_buried() {
    let floor = grid_box(dvec3(-5.0, -5.0, -1.0), dvec3(5.0, 5.0, 0.0), 4);
    let resting = grid_box(dvec3(0.0, 0.0, 0.0), dvec3(1.0, 1.0, 1.0), 2);
    let floating = grid_box(dvec3(2.0, 2.0, 1e-3), dvec3(3.0, 3.0, 1.0), 2);
    // The floor slab's top only, so nothing lies under the resting box's bottom.
    let top: Vec<[DVec3; 3]> = floor
        .into_iter()
        .filter(|t| t.iter().all(|p| p.z == 0.0))
        .collect();
    let tris: Vec<[DVec3; 3]> = top
        .iter()
        .chain(&resting)
        .chain(&floating)
        .copied()
        .collect();
    let vis = Visibility::build(&tris);
    for (x, y) in [(0.5, 0.5), (0.2, 0.9), (0.99, 0.01)] {
        let p = dvec3(x, y, 0.0);
        assert_eq!(vis.first_hit_from_behind(p, -DVec3::Z, NONE), None);
        assert!(
            vis.buried(p, -DVec3::Z, NONE),
            "the box's bottom at ({x}, {y})"
        );
        assert!(
            vis.buried(p, DVec3::Z, NONE),
            "the floor under the box at ({x}, {y})"
        );
    }
    for (x, y) in [(1.5, 0.5), (-0.5, -0.5), (4.0, -4.0), (2.5, 2.5)] {
        let p = dvec3(x, y, 0.0);
        assert!(!vis.buried(p, DVec3::Z, NONE), "the floor at ({x}, {y})");
    }
    assert!(
        !vis.buried(dvec3(2.5, 2.5, 1e-3), -DVec3::Z, NONE),
        "floating bottom"
    );
    assert!(
        !vis.buried(dvec3(1.0, 0.5, 0.5), DVec3::X, NONE),
        "the resting box's side"
    );
    // On the edge between two floor triangles, which face the same way.
    assert!(
        !vis.buried(dvec3(-2.5, -2.5, 0.0), DVec3::Z, NONE),
        "floor seam"
    );
}

#[test]
fn overlapping_visits_every_triangle_in_the_box_once() {
    // The oracle: every triangle whose own box meets the query box must be visited, exactly
    // once; the BVH's padded boxes may add a few more, never far ones (beyond the padding).
    let mut rng = Rng(sampling::Rng::new(&[5]));
    let tris = random_scene(&mut rng, 3000);
    let vis = Visibility::build(&tris);
    let (lo, hi) = scene_bounds(&tris);
    let pad = 1e-2 * (hi - lo).max_element();
    let mut found_some = 0;
    for _ in 0..200 {
        let (a, b) = (rng.vec(lo.x, hi.x), rng.vec(lo.x, hi.x));
        let (qlo, qhi) = (a.min(b), a.min(b) + 0.2 * (a.max(b) - a.min(b)));
        let mut seen = vec![0u32; tris.len()];
        assert!(vis.overlapping(qlo, qhi, [NONE, NONE], |id| {
            seen[id as usize] += 1;
            true
        }));
        for (t, n) in tris.iter().zip(&seen) {
            let (tlo, thi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
            let meets = tlo.cmple(qhi).all() && qlo.cmple(thi).all();
            let near = (tlo - DVec3::splat(pad)).cmple(qhi).all()
                && (qlo - DVec3::splat(pad)).cmple(thi).all();
            assert!(*n <= 1, "visited {n} times");
            assert!(!meets || *n == 1, "a triangle in the box was not visited");
            assert!(near || *n == 0, "a triangle far from the box was visited");
        }
        found_some += seen.iter().any(|&n| n > 0) as usize;
        // Stopping early stops at once.
        let mut calls = 0;
        let finished = vis.overlapping(qlo, qhi, [NONE, NONE], |_| {
            calls += 1;
            false
        });
        assert_eq!((finished, calls.min(1)), (calls == 0, calls));
    }
    assert!(found_some > 50, "only {found_some} boxes met triangles");
}

/// The pyramid query of the exact direct light ([`Visibility::overlapping_convex`]): from
/// random points to random triangles, every triangle that reaches into the pyramid (the
/// oracle: clipped to its four planes, something is left) must be visited, once, and
/// only triangles the box query visits are. The planes must also cull: over all queries the
/// pyramid visits fewer triangles than its bounding box holds (a slanted pyramid's box is far
/// larger than it). Measured: 11,528 triangles met the pyramids, the pyramid query visited
/// 25,404 and the boxes held 99,496; at least half must be culled.
#[test]
fn overlapping_convex_visits_every_triangle_in_the_region_and_culls_the_rest() {
    use crate::geometry::clip::clip_polygon;
    let mut rng = Rng(sampling::Rng::new(&[6]));
    let tris = random_scene(&mut rng, 3000);
    let vis = Visibility::build(&tris);
    let (lo, hi) = scene_bounds(&tris);
    let (mut in_box, mut in_pyramid, mut meeting) = (0usize, 0usize, 0usize);
    for q in 0..200 {
        let x = rng.vec(lo.x, hi.x);
        let e = tris[(q * 13) % tris.len()];
        // The tetrahedron between x and e: three sides through x, and e's plane.
        let mut sides: Vec<(DVec3, DVec3)> = (0..3)
            .map(|k| {
                let (a, b, c) = (e[k], e[(k + 1) % 3], e[(k + 2) % 3]);
                let m = (a - x).cross(b - x);
                (if m.dot(c - x) < 0.0 { -m } else { m }, x)
            })
            .collect();
        let m = (e[1] - e[0]).cross(e[2] - e[0]);
        sides.push((if m.dot(x - e[0]) < 0.0 { -m } else { m }, e[0]));
        let (qlo, qhi) = e.iter().fold((x, x), |(l, h), &v| (l.min(v), h.max(v)));
        let mut boxed = vec![0u32; tris.len()];
        vis.overlapping(qlo, qhi, [NONE, NONE], |id| {
            boxed[id as usize] += 1;
            true
        });
        let mut seen = vec![0u32; tris.len()];
        assert!(
            vis.overlapping_convex(qlo, qhi, &sides, [NONE, NONE], |id| {
                seen[id as usize] += 1;
                true
            })
        );
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for (i, t) in tris.iter().enumerate() {
            a.clear();
            a.extend_from_slice(t);
            for &(m, p) in &sides {
                clip_polygon(&a, |y| m.dot(y - p), &mut b);
                std::mem::swap(&mut a, &mut b);
            }
            let meets = a.len() >= 3;
            assert!(seen[i] <= 1, "visited {} times", seen[i]);
            assert!(
                !meets || seen[i] == 1,
                "query {q}: triangle {i} in the pyramid not visited"
            );
            assert!(seen[i] == 0 || boxed[i] == 1, "visited outside the box");
            meeting += meets as usize;
        }
        in_box += boxed.iter().filter(|&&n| n > 0).count();
        in_pyramid += seen.iter().filter(|&&n| n > 0).count();
    }
    assert!(meeting > 100, "only {meeting} triangles met the pyramids");
    assert!(
        2 * in_pyramid < in_box,
        "the pyramids visited {in_pyramid} triangles, their boxes {in_box}"
    );
}

/// The bounding box of triangles.
fn scene_bounds(tris: &[[DVec3; 3]]) -> (DVec3, DVec3) {
    tris.iter()
        .flatten()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        })
}

/// Partly transparent triangles ([`Visibility::with_transmittance`]): two parallel squares of
/// transmittance 0.6 and 0.5 across the rays' path and one opaque square beside them.
/// - `transmittance` is the product of the t of every square a ray crosses, exactly (0.3
///   through both, 0.6 or 0.5 through one, 1 past them, 0 through the opaque one), and the
///   same through the BVH as through each query alone;
/// - every yes-or-no query (segments, shadow rays, closest hits) lets a ray through with
///   chance t, the same answer for the same ray every time: over 20,000 rays through both
///   squares the share that passes is 0.3 within 4 standard deviations (σ = √(0.3·0.7/20000)
///   ≈ 0.0032), and a closest hit reports the first square in the way that stopped it;
/// - without transmittance (or with all zeros) the answers are the opaque ones, bit for bit.
#[test]
fn partly_transparent_triangles_pass_their_share_of_rays() {
    let square = |z: f64, x0: f64| -> [[DVec3; 3]; 2] {
        let p = |x: f64, y: f64| dvec3(x0 + x, y, z);
        [
            [p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)],
            [p(0.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)],
        ]
    };
    let mut tris = Vec::new();
    tris.extend(square(1.0, 0.0)); // 0, 1: t = 0.6
    tris.extend(square(2.0, 0.0)); // 2, 3: t = 0.5
    tris.extend(square(1.5, 2.0)); // 4, 5: opaque
    let t = [0.6, 0.6, 0.5, 0.5, 0.0, 0.0];
    let opaque = Visibility::build(&tris);
    let vis = opaque.clone().with_transmittance(&t);
    assert!(vis.has_transmittance() && !opaque.has_transmittance());
    let zeros = opaque.clone().with_transmittance(&[0.0; 6]);
    assert!(!zeros.has_transmittance());

    let mut rng = Rng(sampling::Rng::new(&[41]));
    let up = dvec3(0.0, 0.0, 1.0);
    let (n, mut passed_segment, mut passed_ray) = (20_000, 0usize, 0usize);
    for _ in 0..n {
        let (x, y) = (rng.range(0.05, 0.95), rng.range(0.05, 0.95));
        let from = dvec3(x, y, 0.0);
        // Exact shares through both, one and none of the squares.
        assert!((vis.transmittance(from, up, 3.0, NONE) - 0.3).abs() < 1e-6);
        assert!((vis.transmittance(from, up, 1.5, NONE) - 0.6).abs() < 1e-6);
        assert!((vis.transmittance(from + 1.2 * up, up, 3.0, NONE) - 0.5).abs() < 1e-6);
        assert_eq!(vis.transmittance(from, up, 0.5, NONE), 1.0);
        // Ignoring the lower square's triangle under the ray (the triangle below the diagonal
        // x = y is 0).
        let under = if y < x { 0 } else { 1 };
        assert_eq!(
            vis.transmittance(from, up, 3.0, under),
            0.5,
            "ignoring {under}"
        );
        let beside = from + dvec3(2.0, 0.0, 0.0);
        assert_eq!(vis.transmittance(beside, up, 3.0, NONE), 0.0);
        assert_eq!(opaque.transmittance(from, up, 3.0, NONE), 0.0);
        assert_eq!(opaque.transmittance(from, up, 0.5, NONE), 1.0);
        // Yes-or-no queries: chance, the same answer for the same ray.
        let to = from + 3.0 * up;
        let open = !vis.occluded(from, to, [NONE, NONE]);
        assert_eq!(open, !vis.occluded(from, to, [NONE, NONE]));
        assert_eq!(open, !vis.occluded_brute_force(from, to, [NONE, NONE]));
        passed_segment += usize::from(open);
        let blocked = vis.blocked(from, up, 3.0, NONE);
        let hit = vis.closest_hit(from, up, 3.0, NONE);
        assert_eq!(blocked, hit.is_some(), "blocked and the closest hit agree");
        assert_eq!(hit, vis.closest_hit_brute_force(from, up, 3.0, NONE));
        if let Some(h) = hit {
            assert!(h.triangle < 4, "a square in the way: {h:?}");
        }
        passed_ray += usize::from(!blocked);
        assert!(opaque.occluded(from, to, [NONE, NONE]) && opaque.blocked(from, up, 3.0, NONE));
        assert_eq!(
            zeros.closest_hit(from, up, 3.0, NONE),
            opaque.closest_hit(from, up, 3.0, NONE)
        );
    }
    let sigma = (0.3f64 * 0.7 / n as f64).sqrt();
    for (what, passed) in [("segments", passed_segment), ("rays", passed_ray)] {
        let share = passed as f64 / n as f64;
        assert!((share - 0.3).abs() < 4.0 * sigma, "{what}: {share}");
    }
}
