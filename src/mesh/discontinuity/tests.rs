//! Contact lines, near shadows and the display cut on small scenes: a box on a floor, a
//! light under a ceiling, crossing and nearly coincident segments.

use super::face::split_at_crossings;
use super::*;
use crate::mesh::Patches;
use crate::pipeline::{self, Settings};
use crate::scene::SceneBuilder;
use crate::validation::scenes::add_box;

/// A builder holding a 4 × 4 floor (z = 0, facing up) of the material "white", and the
/// materials "white" and "light".
fn floor() -> (SceneBuilder, u32, u32) {
    let mut b = SceneBuilder::new();
    let white = b.material("white", [0.5; 3], [0.0; 3]);
    let light = b.material("light", [0.0; 3], [5.0; 3]);
    let z = |x: f64, y: f64| DVec3::new(x, y, 0.0);
    b.quad([z(0., 0.), z(4., 0.), z(4., 4.), z(0., 4.)], white);
    (b, white, light)
}

/// A 4 × 4 floor (z = 0, facing up) under a light, with a box standing on it, turned 30°
/// about the vertical so its footprint crosses the floor's diagonal. Returns the scene and
/// the footprint's corners (counter-clockwise).
fn box_on_floor() -> (Scene, [DVec3; 4]) {
    let (mut b, white, light) = floor();
    let z = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    b.quad(
        [z(1., 1., 3.), z(1., 3., 3.), z(3., 3., 3.), z(3., 1., 3.)],
        light,
    );
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let foot = [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)]
        .map(|(x, y)| z(2.0 + c * x - s * y, 2.0 + s * x + c * y, 0.0));
    let up = DVec3::new(0.0, 0.0, 1.0);
    for k in 0..4 {
        let (p, q) = (foot[k], foot[(k + 1) % 4]);
        b.quad([p, q, q + up, p + up], white); // outward: counter-clockwise seen outside
    }
    b.quad(
        [foot[0] + up, foot[1] + up, foot[2] + up, foot[3] + up],
        white,
    );
    (b.build().unwrap(), foot)
}

/// Signed area test: > 0 when `p` is left of a → b (inside a counter-clockwise polygon).
fn left(a: DVec3, b: DVec3, p: DVec3) -> f64 {
    (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x)
}

/// Contact points are snapped to 1e-9 of the face (4 units here): within 1e-8 of the
/// footprint's sides is "on the line", neither inside nor outside.
const ON_LINE: f64 = 1e-8;

/// `x` lies strictly inside the footprint.
fn inside(foot: &[DVec3; 4], x: DVec3) -> bool {
    (0..4).all(|k| left(foot[k], foot[(k + 1) % 4], x) > ON_LINE)
}

/// `x` lies strictly outside the footprint.
fn outside(foot: &[DVec3; 4], x: DVec3) -> bool {
    (0..4).any(|k| left(foot[k], foot[(k + 1) % 4], x) < -ON_LINE)
}

/// Some corner of the triangle lies strictly inside the footprint and another strictly
/// outside.
fn straddles(foot: &[DVec3; 4], corners: &[DVec3; 3]) -> bool {
    corners.iter().any(|&c| inside(foot, c)) && corners.iter().any(|&c| outside(foot, c))
}

#[test]
fn contact_lines_of_a_box_on_a_floor_become_edges() {
    let (scene, foot) = box_on_floor();
    let (split, stats) = split_contacts(&scene);
    split.validate().unwrap();
    assert_eq!(stats.faces_split, 2, "the floor's two triangles: {stats:?}");
    // The footprint crosses the diagonal: its four sides give 4 segments on one half and
    // 2 on the other (the two sides the diagonal cuts are counted on both).
    assert_eq!(stats.segments, 6, "{stats:?}");
    let area = |s: &Scene, floor: bool| {
        (0..s.triangles.len())
            .filter(|&t| {
                let n = s.triangles[t].vertices.map(|v| s.positions[v as usize]);
                floor == (n.iter().all(|p| p.z == 0.0))
            })
            .map(|t| s.triangle_area(t))
            .sum::<f64>()
    };
    // The floor keeps its area and its facing (every new triangle faces up).
    assert!((area(&split, true) - 16.0).abs() < 1e-9);
    assert!((area(&split, false) - area(&scene, false)).abs() < 1e-9);
    for t in &split.triangles {
        let [a, b, c] = t.vertices.map(|v| split.positions[v as usize]);
        if a.z == 0.0 && b.z == 0.0 && c.z == 0.0 {
            assert!((b - a).cross(c - a).z > 0.0);
        }
    }
    // No patch of the bake straddles the footprint: each floor patch is wholly inside or
    // wholly outside it (corners on the footprint's sides count as either).
    let out = pipeline::solve_scene(&scene, &Settings::default()).unwrap();
    let p = &out.patches;
    let mut under = 0;
    for i in 0..p.len() {
        let corners = p.corners(i);
        if !corners.iter().all(|c| c.z == 0.0) {
            continue;
        }
        assert!(
            !straddles(&foot, &corners),
            "floor patch {i} straddles the footprint: {corners:?}"
        );
        under += usize::from(inside(&foot, p.centroid[i]));
        // Inside the footprint: buried (nobody sees it); outside: visible.
        let expected = if inside(&foot, p.centroid[i]) {
            0.0
        } else {
            1.0
        };
        assert_eq!(out.visible_fraction[i], expected, "patch {i}");
    }
    assert!(under > 0, "some floor patches lie under the box");
    // Without the split, some patch straddles (what the split is for).
    let none = Settings {
        discontinuities: Discontinuities::None,
        ..Settings::default()
    };
    let out = pipeline::solve_scene(&scene, &none).unwrap();
    assert!((0..out.patches.len()).any(|i| {
        let c = out.patches.corners(i);
        c.iter().all(|x| x.z == 0.0) && straddles(&foot, &c)
    }));
}

#[test]
fn split_patches_cut_along_the_footprint_and_stay_conforming() {
    let (scene, foot) = box_on_floor();
    let patches = crate::mesh::subdivide(&scene, 0.7, 0.0).unwrap();
    let lines = contact_lines(&scene).expect("the box touches the floor");
    let super::Split {
        patches: cut,
        parent,
        region,
        stats,
    } = split_patches(&lines, &patches, 6.0).unwrap();
    cut.validate().unwrap();
    assert!(
        stats.faces_split > 0 && stats.triangles == cut.len(),
        "{stats:?}"
    );
    assert_eq!(parent.len(), cut.len());
    // Each patch's pieces tile it: the same area, material, normal and source triangle.
    let mut area = vec![0.0; patches.len()];
    for (k, &i) in parent.iter().enumerate() {
        let i = i as usize;
        area[i] += cut.area[k];
        assert_eq!(cut.source_triangle[k], patches.source_triangle[i]);
        assert_eq!(cut.material[k], patches.material[i]);
        assert!(
            cut.normal[k].dot(patches.normal[i]) > 1.0 - 1e-12,
            "piece {k}"
        );
    }
    // Contact points are snapped to 1e-9 of the patch (`Face::to_2d`), so the pieces' area
    // may differ from their patch's by a few times that.
    for (i, a) in area.iter().enumerate() {
        let want = patches.area[i];
        assert!((a - want).abs() < 1e-8 * want, "patch {i}: {a} vs {want}");
    }
    // No floor piece straddles the footprint (some patch did before).
    let on_floor = |p: &Patches, i: usize| p.corners(i).iter().all(|c| c.z == 0.0);
    let straddling =
        |p: &Patches| (0..p.len()).any(|i| on_floor(p, i) && straddles(&foot, &p.corners(i)));
    assert!(straddling(&patches));
    assert!(!straddling(&cut));
    // Regions: a piece's region is a piece of its own patch; pieces of one patch inside and
    // outside the footprint are in different regions, pieces on one side of it in one (the
    // footprint is convex, and the floor's patches are convex: each side's part of a patch
    // is connected where the footprint's outline crosses it once; no floor patch here holds
    // a whole corner of it and more, checked by the count below).
    let inside = |k: usize| {
        let c = cut.centroid[k];
        (0..4).all(|e| left(foot[e], foot[(e + 1) % 4], c) > 0.0)
    };
    let mut two_regions = 0;
    for k in 0..cut.len() {
        let r = region[k] as usize;
        assert!(r <= k && region[r] as usize == r, "piece {k}: region {r}");
        assert_eq!(parent[r], parent[k], "piece {k}");
        if on_floor(&cut, k) {
            for j in (0..k).filter(|&j| parent[j] == parent[k]) {
                let same = region[j] == region[k];
                assert_eq!(same, inside(j) == inside(k), "pieces {j}, {k}");
                two_regions += usize::from(!same);
            }
        }
    }
    assert!(
        two_regions > 0,
        "some floor patch is crossed by the footprint"
    );
    // Conforming: an edge of one floor piece only is on the floor's border (a point
    // inserted into one side of an edge and not the other would leave two such edges).
    let mut edges: HashMap<(u32, u32), usize> = HashMap::new();
    for i in (0..cut.len()).filter(|&i| on_floor(&cut, i)) {
        let t = cut.triangles[i];
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    for ((a, b), n) in edges {
        let (p, q) = (cut.positions[a as usize], cut.positions[b as usize]);
        let border = |x: f64, y: f64| [x, y].iter().any(|&v| v == 0.0 || v == 4.0);
        let on_border = (p.x == q.x && border(p.x, -1.0)) || (p.y == q.y && border(-1.0, p.y));
        assert!(
            n == 2 || (n == 1 && on_border),
            "edge {p} – {q} in {n} pieces"
        );
    }
}

/// The display cut with the segments binned on a grid is the cut with every segment tried
/// at every patch, point for point: 49 small boxes on the floor give its two triangles about
/// a hundred contact segments each, past the grid's threshold.
#[test]
fn binned_contact_segments_cut_the_display_as_all_of_them_do() {
    let (mut b, white, _) = floor();
    for i in 0..7 {
        for j in 0..7 {
            let lo = DVec3::new(0.2 + 0.55 * i as f64, 0.25 + 0.53 * j as f64, 0.0);
            add_box(&mut b, lo, lo + DVec3::new(0.3, 0.2, 0.3), false, white);
        }
    }
    let scene = b.build().unwrap();
    let patches = crate::mesh::subdivide(&scene, 0.2, 0.0).unwrap();
    let lines = contact_lines(&scene).expect("the boxes touch the floor");
    assert!(lines.iter().any(|l| l.len() > display::GRID_MIN_SEGMENTS));
    let binned = display::split_patches_binned(&lines, &patches, 6.0, display::GRID_MIN_SEGMENTS);
    let all = display::split_patches_binned(&lines, &patches, 6.0, usize::MAX);
    let (a, b) = (binned.unwrap(), all.unwrap());
    assert!(a.stats.faces_split > 0, "{:?}", a.stats);
    assert_eq!(a.parent, b.parent);
    assert_eq!(a.region, b.region);
    assert_eq!(a.patches.positions, b.patches.positions);
    assert_eq!(a.patches.triangles, b.patches.triangles);
    assert_eq!(a.stats, b.stats);
}

#[test]
fn the_hierarchical_display_is_cut_along_the_contact_lines() {
    // The hierarchy's roots stay the input triangles; the gathered display's faces stop at
    // the footprint, so no vertex's light is interpolated across it.
    let (scene, foot) = box_on_floor();
    let settings = |discontinuities| Settings {
        method: pipeline::Method::Hierarchical,
        discontinuities,
        ..Settings::default()
    };
    let straddling = |out: &pipeline::Outcome| {
        let b = &out.baked;
        b.faces.iter().any(|f| {
            let c = f.map(|v| DVec3::from(b.positions[v as usize]));
            c.iter().all(|x| x.z == 0.0) && straddles(&foot, &c)
        })
    };
    let out = pipeline::solve_scene(&scene, &settings(Discontinuities::Auto)).unwrap();
    let stats = out
        .report
        .display_contacts
        .as_ref()
        .expect("the display was cut");
    assert!(stats.faces_split > 0, "{stats:?}");
    assert!(out.report.contacts.is_none(), "the roots were not cut");
    assert!(!straddling(&out));
    let out = pipeline::solve_scene(&scene, &settings(Discontinuities::None)).unwrap();
    assert!(out.report.display_contacts.is_none());
    assert!(straddling(&out));
}

#[test]
fn crossing_segments_are_cut_at_one_shared_point() {
    // An X: four pieces meeting at the crossing.
    let x = split_at_crossings(&[[[0.0, 0.0], [1.0, 1.0]], [[0.0, 1.0], [1.0, 0.0]]]);
    assert_eq!(x.len(), 4, "{x:?}");
    assert!(x.iter().all(|s| s.contains(&[0.5, 0.5])));
    // A T (one ends on the other): the other is cut at that very end.
    let t = split_at_crossings(&[[[0.0, 0.0], [1.0, 0.0]], [[0.3, 1.0], [0.3, 1e-12]]]);
    assert_eq!(t.len(), 3, "{t:?}");
    assert!(t.contains(&[[0.0, 0.0], [0.3, 1e-12]]));
    // Parallel, and meeting at their ends: unchanged.
    let p = [
        [[0.0, 0.0], [1.0, 0.0]],
        [[0.0, 0.5], [1.0, 0.5]],
        [[1.0, 0.5], [0.2, 0.9]],
    ];
    assert_eq!(split_at_crossings(&p).len(), 3);
}

#[test]
fn nearly_coincident_contact_lines_triangulate_without_panicking() {
    // One face of LibreQuake's e1m2 (in its own frame, longest edge 1): the same contact
    // line found from several faces, as a chain of pieces and as one segment along it
    // whose end is 1e-9 off the chain's. spade's own splitting of crossing constraints
    // failed an internal assertion here (`add_constraint_and_split`); the face must be
    // cut, its pieces covering it exactly.
    let v = |x: f64, y: f64| DVec3::new(x, y, 0.0);
    let face = Face::from_corners([
        v(0.0, 0.0),
        v(1.0, 0.0),
        v(0.05882352963089943, 0.23529411759227514),
    ]);
    let (a, b) = (
        v(0.5147058824077249, 0.05882352963089943),
        v(0.397058823145926, 0.08823529444634914),
    );
    let c = v(0.16176470555365086, 0.147058823145926);
    let (far, near) = (
        v(0.04411764722317457, 0.1764705879613757),
        v(0.7499999990686774, 0.0),
    );
    let segments = [
        [v(0.75, 0.0), a],
        [v(0.5, 0.0), a],
        [a, v(0.5, 0.0)],
        [a, b],
        [v(0.375, 0.0), b],
        [b, v(0.375, 0.0)],
        [b, c],
        [c, v(0.125, 0.0)],
        [far, near],
    ];
    let edge_points = [
        v(0.75, 0.0),
        v(0.5, 0.0),
        v(0.375, 0.0),
        v(0.125, 0.0),
        near,
        far,
    ];
    let pieces = face
        .triangulate(&segments, &edge_points, false)
        .expect("the face is cut");
    let area: f64 = pieces
        .iter()
        .map(|[p, q, r]| 0.5 * (q - p).cross(r - p).z)
        .sum();
    // The face's area is 0.5 · 1 · 0.2353; rounding of the pieces' corners (snapped to
    // 1e-9 of the face) moves it by far less than 1e-9.
    assert!(
        (area - 0.5 * 0.23529411759227514).abs() < 1e-9,
        "area {area}"
    );
    assert!(pieces.iter().all(|[p, q, r]| (q - p).cross(r - p).z >= 0.0));
}

#[test]
fn a_light_mounted_under_a_ceiling_outlines_itself_on_it() {
    // A 4 × 4 ceiling (facing down) and a 1 × 1 light (facing down) below it: within 1e-3
    // of the room's extent (6.9e-3 here), or within 5 % of the light's width (its
    // triangles' smallest altitude, 0.71: 3.5e-2), the light's outline becomes edges of
    // the ceiling and the light itself is not split. 0.1 below, it is too far for either,
    // but within the light's width and 1/64 of the extent (0.108): a near shadow, and its
    // silhouette alone (not its diagonal) becomes edges of the ceiling. 0.2 below, nothing.
    for (gap, mounted) in [(4e-4, true), (0.02, true), (0.1, true), (0.2, false)] {
        let (mut b, white, light) = floor();
        crate::test_support::ceiling_with_mounted_light(
            &mut b,
            (white, light),
            4.0,
            gap,
            [1.5, 1.2],
        );
        let scene = b.build().unwrap();
        let (split, stats) = split_contacts(&scene);
        split.validate().unwrap();
        if !mounted {
            assert_eq!(stats.faces_split, 0, "gap {gap}: {stats:?}");
            continue;
        }
        assert_eq!(
            stats.faces_split, 2,
            "gap {gap}: the ceiling's triangles only: {stats:?}"
        );
        let mut diagonal = 0;
        for t in &split.triangles {
            let c = t.vertices.map(|v| split.positions[v as usize]);
            if c.iter().all(|p| p.z == 4.0) {
                let centroid = (c[0] + c[1] + c[2]) / 3.0;
                let under =
                    centroid.x > 1.5 && centroid.x < 2.5 && centroid.y > 1.2 && centroid.y < 2.2;
                // Snapped to 1e-9 of the face (4 units): 1e-8 is "on the outline".
                for p in c {
                    let strictly_in = p.x > 1.5 + 1e-8
                        && p.x < 2.5 - 1e-8
                        && p.y > 1.2 + 1e-8
                        && p.y < 2.2 - 1e-8;
                    let strictly_out = p.x < 1.5 - 1e-8
                        || p.x > 2.5 + 1e-8
                        || p.y < 1.2 - 1e-8
                        || p.y > 2.2 + 1e-8;
                    assert!(
                        if under { !strictly_out } else { !strictly_in },
                        "gap {gap}: {c:?}"
                    );
                }
                // The mounted light's outline includes its triangles' shared diagonal; the
                // near shadow's is the silhouette alone.
                let on_diagonal = |p: DVec3| {
                    (p.y - p.x + 0.3).abs() < 1e-8 && p.x > 1.5 - 1e-8 && p.x < 2.5 + 1e-8
                };
                for k in 0..3 {
                    let (p, q) = (c[k], c[(k + 1) % 3]);
                    diagonal += (on_diagonal(p) && on_diagonal(q)) as usize;
                }
            }
        }
        assert_eq!(
            diagonal > 0,
            gap < 0.1,
            "gap {gap}: {diagonal} edges on the diagonal"
        );
    }
}

#[test]
fn scenes_without_contacts_are_unchanged() {
    let scene = crate::validation::scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
    let (split, stats) = split_contacts(&scene);
    assert_eq!(split.triangles, scene.triangles);
    assert_eq!(split.positions, scene.positions);
    assert_eq!(stats.faces_split, 0);
    // A room's walls meet its floor only along the floor's border: no split either.
    let mut b = SceneBuilder::new();
    let m = b.material("white", [0.5; 3], [1.0; 3]);
    add_box(&mut b, DVec3::ZERO, DVec3::ONE, true, m);
    let room = b.build().unwrap();
    assert_eq!(split_contacts(&room).1.faces_split, 0);
}

#[test]
fn a_two_sided_scene_is_cut_as_its_fronts_are_and_its_twins_follow() {
    // Cutting then making every face two-sided, and making two-sided then cutting, give the
    // same scene: the same triangles in the same order, the same pairs. With only the floor
    // two-sided, its pieces (and only they) come with twins; the contact lines a display cut
    // would use give each twin its front's segments.
    let (scene, _) = box_on_floor();
    let (cut, _) = split_contacts(&scene);
    let (two_then_cut, stats) = split_contacts(&scene.to_two_sided());
    let cut_then_two = cut.to_two_sided();
    two_then_cut.validate().unwrap();
    assert_eq!(two_then_cut.triangles, cut_then_two.triangles);
    assert_eq!(two_then_cut.twin, cut_then_two.twin);
    assert_eq!(stats.triangles, 2 * cut.triangles.len());

    let mut floor_only = scene.clone();
    assert_eq!(floor_only.make_two_sided_where(|t, _| t < 2), 2);
    let (out, _) = split_contacts(&floor_only);
    out.validate().unwrap();
    let floor_pieces = (0..cut.triangles.len())
        .filter(|&t| {
            let [a, b, c] = cut.triangles[t].vertices.map(|v| cut.positions[v as usize]);
            (b - a).cross(c - a).z > 0.0 && a.z == 0.0 && b.z == 0.0 && c.z == 0.0
        })
        .count();
    assert!(floor_pieces > 2, "the floor is cut: {floor_pieces}");
    let paired = out.twin.iter().filter(|&&u| u != NO_TWIN).count();
    assert_eq!(paired, 2 * floor_pieces);
    let lines = contact_lines(&floor_only).unwrap();
    for t in 0..floor_only.triangles.len() {
        let u = floor_only.twin[t];
        if u != NO_TWIN {
            assert_eq!(lines[t], lines[u as usize], "{t}");
        }
    }
    assert!(!lines[0].is_empty() || !lines[1].is_empty());
}

/// The sun's penumbra lines from a 1 × 1 plate 1 above the 4 × 4 floor, and from a 2 × 2
/// plate 2 above it that shades part of the first plate and of its shadow, under a sun at 45°
/// along +x. Each line is where a plane through a plate's edge tangent to the sun's disc meets
/// the floor (or the lower plate): for an edge across the sun's direction (along y, at height
/// h above the receiver) x = x_edge − h / tan(45° ± α); for an edge along it (along x),
/// y = y_edge ∓ h·tan ψ, sin ψ = sin α / sin 45°. Only where the shadow edge is seen (the sun
/// seen on one side of it, hidden on the other) is a line drawn: not where the upper plate's
/// shadow already covers the floor.
#[test]
fn sun_lines_follow_each_penumbra_where_its_edge_is_seen() {
    let (mut b, white, _) = floor();
    let z = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    b.quad(
        [
            z(1.5, 1.5, 1.),
            z(2.5, 1.5, 1.),
            z(2.5, 2.5, 1.),
            z(1.5, 2.5, 1.),
        ],
        white,
    );
    b.quad(
        [z(1., 1., 2.), z(3., 1., 2.), z(3., 3., 2.), z(1., 3., 2.)],
        white,
    );
    let scene = b.build().unwrap();
    let e = 45f64.to_radians();
    let sun = DVec3::new(e.cos(), 0.0, e.sin());
    let alpha = 0.25f64.to_radians();
    let lines = sun_lines(&scene, sun, alpha).expect("lines");
    // Triangles 0, 1: the floor; 2, 3: the lower plate; 4, 5: the upper one.
    assert!(
        lines[4].is_empty() && lines[5].is_empty(),
        "nothing falls on the top plate"
    );
    assert_eq!(lines[0], lines[1], "a line goes to every face of its plane");
    assert_eq!(lines[2], lines[3]);
    // Where each segment lies: x of a segment along y, y of one along x.
    let at = |segs: &[[DVec3; 2]], along_y: bool| -> Vec<f64> {
        let mut v: Vec<f64> = segs
            .iter()
            .filter(|[p, q]| ((p.x - q.x).abs() < 1e-12) == along_y)
            .map(|[p, _]| if along_y { p.x } else { p.y })
            .collect();
        v.sort_by(f64::total_cmp);
        v
    };
    let close = |got: &[f64], want: &[f64]| {
        assert_eq!(got.len(), want.len(), "{got:?} against {want:?}");
        for (g, w) in got.iter().zip(want) {
            assert!((g - w).abs() < 1e-9, "{got:?} against {want:?}");
        }
    };
    for segs in [&lines[0], &lines[2]] {
        for [p, q] in segs.iter() {
            assert!(
                (p.z - q.z).abs() < 1e-12,
                "on the receiver's plane: {p} {q}"
            );
        }
    }
    let across = |x_edge: f64, h: f64| {
        let mut v = [
            x_edge - h / (e + alpha).tan(),
            x_edge - h / (e - alpha).tan(),
        ];
        v.sort_by(f64::total_cmp);
        v
    };
    // The floor, across the sun: the lower plate's far edge (x = 2.5, h = 1), and the upper
    // plate's far edge (x = 3, h = 2) beside the lower plate's shadow (y in [1, 1.5] and
    // [2.5, 3]: two runs). The near edges' shadows (x = 0.5 and −1) lie in the upper plate's
    // shadow or off the floor.
    let mut want = [across(2.5, 1.0), across(3.0, 2.0), across(3.0, 2.0)].concat();
    want.sort_by(f64::total_cmp);
    close(&at(&lines[0], true), &want);
    // The lower plate: the upper plate's far edge (x = 3), h = 1 above it.
    close(&at(&lines[2], true), &across(3.0, 1.0));
    // Along the sun: the lower plate's sides y = 1.5, 2.5 (h = 1) and the upper's y = 1, 3
    // (h = 2) on the floor.
    let psi = (alpha.sin() / e.sin()).asin();
    let side = |y: f64, h: f64| [y - h * psi.tan(), y + h * psi.tan()];
    let mut want = [
        side(1.5, 1.0),
        side(2.5, 1.0),
        side(1.0, 2.0),
        side(3.0, 2.0),
    ]
    .concat();
    want.sort_by(f64::total_cmp);
    close(&at(&lines[0], false), &want);
    // The lower plate's sides shade the floor for x in [0.5, 1.5], but x < 1 is in the upper
    // plate's shadow already: only x in [1, 1.5] is drawn, to within half the spacing of the
    // traced points (SAMPLE_SPACING of the extent, 6: 0.0075).
    for [p, q] in lines[0].iter().filter(|[p, q]| (p.x - q.x).abs() > 1e-12) {
        let (lo, hi) = (p.x.min(q.x), p.x.max(q.x));
        if (p.y - 2.0).abs() < 0.6 {
            assert!(
                lo > 0.99 && hi < 1.51,
                "the seen part of the shadow: {lo}..{hi}"
            );
        }
    }
}

/// The luminance a bake's display shows on the floor (z = 0, facing up) at (x, y),
/// interpolated from its vertex colours as a viewer sees it.
fn floor_shown(out: &pipeline::Outcome, x: f64, y: f64) -> f64 {
    let probe = crate::validation::pointwise::Probe {
        triangle: 0,
        position: DVec3::new(x, y, 0.0),
        normal: DVec3::Z,
        radiance: [0.0; 3],
        std_error: 0.0,
        paths: 0,
    };
    let display = crate::validation::pointwise::Display::from_baked(&out.baked);
    crate::color::luminance(display.at(&[probe])[0].expect("on the floor").interpolated)
}

/// The hierarchical display of a plate's sun shadow on a floor, with no display refinement
/// (`gather_tolerance = 0`), so that only the sun lines put vertices at the shadow's edge.
/// 3 cm on the lit side of the penumbra (it is about 1 cm wide here: 1.41 × 2 tan 0.265° /
/// sin 45°) the floor shows what it shows 40 cm further in, within 2 %: the sun's light is
/// the same, and the indirect light (from the plate's underside alone: the floor does not see
/// itself) is a few per cent of it. 3 cm on the shaded side it shows under a tenth of that
/// (the underside's light alone). Without the lines the vertices either side of the edge are
/// the leaves' corners, up to a leaf apart, and what lies between them is interpolated across
/// the edge.
#[test]
fn the_hierarchical_display_follows_the_suns_shadow_edge() {
    use crate::scene::{Environment, Sun, Up};
    let (mut b, white, _) = floor();
    let z = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    b.quad(
        [
            z(1.5, 1.5, 1.),
            z(2.5, 1.5, 1.),
            z(2.5, 2.5, 1.),
            z(1.5, 2.5, 1.),
        ],
        white,
    );
    let scene = b.build().unwrap();
    // Up z: north +y, east +x; the sun 45° up in the east.
    let environment = Environment {
        sun: Some(Sun {
            azimuth_degrees: 90.0,
            elevation_degrees: 45.0,
            irradiance: [100.0; 3],
        }),
        up: Up::Z,
        ..Environment::default()
    };
    let settings = |discontinuities| Settings {
        method: pipeline::Method::Hierarchical,
        discontinuities,
        environment: environment.clone(),
        gather_tolerance: 0.0,
        ..Settings::default()
    };
    // The lower plate's far edge x = 2.5 casts the shadow's edge at x = 1.5 on the floor.
    let shown = floor_shown;
    let out = pipeline::solve_scene(&scene, &settings(Discontinuities::Auto)).unwrap();
    assert!(out.report.sun_lines > 0, "{}", out.report.sun_lines);
    for y in [1.7, 2.0, 2.3] {
        let (lit, near_lit) = (shown(&out, 1.93, y), shown(&out, 1.53, y));
        let near_shade = shown(&out, 1.47, y);
        assert!(
            (near_lit / lit - 1.0).abs() < 0.02,
            "lit at y = {y}: {near_lit} against {lit}"
        );
        assert!(
            near_shade < 0.1 * lit,
            "shaded at y = {y}: {near_shade} against {lit}"
        );
    }
    let out = pipeline::solve_scene(&scene, &settings(Discontinuities::None)).unwrap();
    assert_eq!(out.report.sun_lines, 0);
    let worst = [1.7, 2.0, 2.3]
        .iter()
        .map(|&y| (shown(&out, 1.53, y) / shown(&out, 1.93, y) - 1.0).abs())
        .fold(0.0, f64::max);
    assert!(
        worst > 0.02,
        "without the lines the edge is blurred: {worst}"
    );
}

/// The sun through a pane (transmittance 0.3) in a window of a wall: its patch on the floor is
/// bounded by the opening's four edges, so lines follow them there (the pane passes 0.3 of
/// the sun, the wall none: a jump of 0.3). The same window shut by an opaque pane, and the
/// wall's outer side (turned from the room, its back to the sun), get none.
#[test]
fn sun_lines_follow_a_sun_patch_through_a_pane() {
    let window = |transmittance: f64| {
        let (mut b, white, _) = floor();
        let glass = b.material("glass", [0.05; 3], [0.0; 3]);
        if transmittance > 0.0 {
            b.set_transmittance(glass, transmittance);
        }
        // The wall x = 4 facing the room (−x), with an opening y in [1, 3], z in [1, 2].
        let wall = |b: &mut SceneBuilder, y: [f64; 2], z: [f64; 2], m: u32| {
            let p = |y: f64, z: f64| DVec3::new(4.0, y, z);
            b.quad(
                [p(y[0], z[0]), p(y[0], z[1]), p(y[1], z[1]), p(y[1], z[0])],
                m,
            );
        };
        wall(&mut b, [0., 4.], [0., 1.], white);
        wall(&mut b, [0., 4.], [2., 3.], white);
        wall(&mut b, [0., 1.], [1., 2.], white);
        wall(&mut b, [3., 4.], [1., 2.], white);
        wall(&mut b, [1., 3.], [1., 2.], glass);
        b.build().unwrap()
    };
    let e = 30f64.to_radians();
    let sun = DVec3::new(e.cos(), 0.0, e.sin());
    let alpha = 0.265f64.to_radians();
    let lines = sun_lines(&window(0.3), sun, alpha).expect("lines");
    assert!(
        lines[2..].iter().all(Vec::is_empty),
        "none on the wall or the pane"
    );
    // Across the sun: the opening's bottom (z = 1) and top (z = 2) edges, on the floor at
    // x = 4 − z / tan 30°, each as the two sides of its penumbra.
    let mut xs: Vec<f64> = lines[0]
        .iter()
        .filter(|[p, q]| (p.x - q.x).abs() < 1e-9)
        .map(|[p, _]| p.x)
        .collect();
    xs.sort_by(f64::total_cmp);
    // Each edge of the opening is two edges of the mesh (the pane's, and the wall's beside
    // it, longer: a T-junction), which cast the same line.
    xs.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    assert_eq!(xs.len(), 4, "{xs:?}");
    for (pair, z) in xs.chunks(2).zip([2.0, 1.0]) {
        let want = [4.0 - z / (e - alpha).tan(), 4.0 - z / (e + alpha).tan()];
        for (got, want) in pair.iter().zip(want) {
            assert!((got - want).abs() < 1e-9, "{pair:?} for z = {z}: {want}");
        }
    }
    // Along the sun: the opening's sides y = 1 and 3 (edges between the pane and the wall,
    // both facing the room: they cast lines because the pane passes the sun), each line within
    // its penumbra's half-width (4 m · tan 0.265° at most) of them.
    for y in [1.0, 3.0] {
        let near = |p: DVec3| (p.y - y).abs() < 4.0 * alpha.tan() * 1.01;
        assert!(
            lines[0].iter().any(|[p, q]| near(*p) && near(*q)),
            "y = {y}"
        );
    }
    assert!(
        sun_lines(&window(0.0), sun, alpha).is_none(),
        "a shut window casts no sun patch"
    );
}

#[test]
fn a_contact_line_across_a_shared_edge_leaves_no_sliver() {
    // The shipped Cornell box: the light's outline on the ceiling crosses the diagonal its
    // two triangles share, and each triangle finds the crossing in its own frame, 2e-6 mm
    // apart. Both must take one point, or a sliver of that width lies between the two: no
    // triangle of the cut scene thinner than TOUCH × its extent. (Vertices of different
    // surfaces may lie that close: a block's corner and the floor's point under it.)
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/cornell_box.obj");
    let scene = Scene::load(&path).unwrap();
    let (split, stats) = split_contacts(&scene);
    split.validate().unwrap();
    assert!(stats.faces_split > 0);
    let (lo, hi) = split.bounds();
    let touch = TOUCH * (hi - lo).length();
    for t in &split.triangles {
        let [a, b, c] = t.vertices.map(|v| split.positions[v as usize]);
        let longest = (b - a).length().max((c - b).length()).max((a - c).length());
        let height = (b - a).cross(c - a).length() / longest;
        assert!(height > touch, "{a} {b} {c}: {height} thin");
    }
}

/// The 4 × 4 floor with a 0.5 × 0.5 plate (facing up) at `height` over x ∈ [2.25, 2.75],
/// y ∈ [1.75, 2.25], and a 0.5 × 0.5 lamp facing down 3 above the floor, centred at (2, 2)
/// beside the plate. Triangles 0, 1: the floor; 2, 3: the plate; 4, 5: the lamp.
fn plate_under_lamp(height: f64) -> Scene {
    let (mut b, white, light) = floor();
    let z = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    b.quad(
        [
            z(2.25, 1.75, height),
            z(2.75, 1.75, height),
            z(2.75, 2.25, height),
            z(2.25, 2.25, height),
        ],
        white,
    );
    // Clockwise seen from above: the lamp faces down.
    b.quad(
        [
            z(1.75, 1.75, 3.),
            z(1.75, 2.25, 3.),
            z(2.25, 2.25, 3.),
            z(2.25, 1.75, 3.),
        ],
        light,
    );
    b.build().unwrap()
}

/// The lamps' penumbra lines of a 0.5 × 0.5 plate 0.25 above the floor, under a 0.5 × 0.5
/// lamp 3 above the floor beside it. The plate's edges are parallel to the floor, so each one's
/// projection from a point L of the lamp onto the floor is the line through
/// L + (edge − L)·3/2.75: an edge at x_e (along y) falls at x_L + (x_e − x_L)·12/11, and the
/// penumbra's borders are the projections from the lamp's sides x_L = 1.75 and 2.25 (and
/// alike for the edges along x). Lifted to 1.5 above the floor, the plate's penumbrae are
/// wider than [`lamp::MAX_HALF_WIDTH`] allows, and no line is drawn.
#[test]
fn lamp_lines_follow_a_near_plates_penumbrae() {
    let lines = lamp::lamp_lines_on(&plate_under_lamp(0.25), &|_| true).expect("lines");
    // Triangles 0, 1: the floor; 2, 3: the plate; 4, 5: the lamp.
    assert!(lines[2..].iter().all(Vec::is_empty), "{:?}", &lines[2..]);
    assert_eq!(lines[0], lines[1], "a line goes to every face of its plane");
    let project = |e: f64, l: f64| l + (e - l) * 12.0 / 11.0;
    let borders = |e: f64| {
        let mut v = [project(e, 1.75), project(e, 2.25)];
        v.sort_by(f64::total_cmp);
        v
    };
    for [p, q] in &lines[0] {
        assert!(
            p.z.abs() < 1e-12 && q.z.abs() < 1e-12,
            "on the floor: {p} {q}"
        );
    }
    // Where each segment lies: x of a segment along y, y of one along x.
    let at = |along_y: bool| -> Vec<f64> {
        let mut v: Vec<f64> = lines[0]
            .iter()
            .filter(|[p, q]| ((p.x - q.x).abs() < 1e-12) == along_y)
            .map(|[p, _]| if along_y { p.x } else { p.y })
            .collect();
        v.sort_by(f64::total_cmp);
        v
    };
    let mut want = [borders(1.75), borders(2.25)].concat();
    want.sort_by(f64::total_cmp);
    let close = |got: &[f64], want: &[f64]| {
        assert_eq!(got.len(), want.len(), "{got:?} against {want:?}");
        for (g, w) in got.iter().zip(want) {
            assert!((g - w).abs() < 1e-9, "{got:?} against {want:?}");
        }
    };
    close(&at(false), &want);
    let mut want = [borders(2.25), borders(2.75)].concat();
    want.sort_by(f64::total_cmp);
    close(&at(true), &want);
    assert!(lamp::lamp_lines_on(&plate_under_lamp(1.5), &|_| true).is_none());
}

/// The hierarchical display of the plate's shadow in
/// [`lamp_lines_follow_a_near_plates_penumbrae`], with no display refinement
/// (`gather_tolerance = 0`), so that only the lamp lines put vertices at the penumbra's
/// borders. The penumbra of the plate's far edge is x ∈ [2.7955, 2.8409] on the floor: 1 cm
/// inside its inner border the floor sees none of the lamp (the umbra: only the light the
/// plate's underside reflects, a few per cent), 1 cm outside its outer border all of it.
/// With the lines the display shows the umbra under a tenth of the lit floor beside it;
/// without them the display triangles' corners lie up to a leaf apart on both sides, and
/// the lit light is interpolated into the umbra.
#[test]
fn the_hierarchical_display_follows_a_lamps_near_penumbra() {
    let scene = plate_under_lamp(0.25);
    let settings = |discontinuities| Settings {
        method: pipeline::Method::Hierarchical,
        discontinuities,
        gather_tolerance: 0.0,
        ..Settings::default()
    };
    let shown = floor_shown;
    let ratio = |out: &pipeline::Outcome| {
        [1.9, 2.0, 2.1]
            .iter()
            .map(|&y| shown(out, 2.7855, y) / shown(out, 2.8509, y))
            .fold(0.0, f64::max)
    };
    let out = pipeline::solve_scene(&scene, &settings(Discontinuities::Auto)).unwrap();
    assert!(out.report.lamp_lines > 0, "{}", out.report.lamp_lines);
    let with = ratio(&out);
    let out = pipeline::solve_scene(&scene, &settings(Discontinuities::None)).unwrap();
    assert_eq!(out.report.lamp_lines, 0);
    let without = ratio(&out);
    assert!(
        with < 0.1,
        "the umbra against the lit floor: {with} (without the lines {without})"
    );
    assert!(
        without > 0.1,
        "without the lines the penumbra is blurred: {without}"
    );
}
