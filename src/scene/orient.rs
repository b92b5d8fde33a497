//! Orientation repair (`--orient auto`): faces wound the wrong way bake black, since a face
//! emits and reflects on its counter-clockwise side only. This module turns faces over, in
//! two steps, and says what it turned:
//!
//! 1. **Consistency.** Faces joined along an edge that exactly two faces share form a
//!    *surface*; within one, the faces are turned to agree with each other (a shared edge
//!    runs opposite ways in the two faces), keeping the orientation of the larger part by
//!    area. An edge shared by three or more faces (a wall meeting a floor and another wall
//!    along one line) joins nothing: which two belong together is not known.
//! 2. **Facing where it is seen from.** Each surface is then turned, as a whole, to the side
//!    the scene's light and the rest of the scene see it from. Evidence, from points spread
//!    over the surface by area:
//!    - the scene's own light: point lights, and points just in front of emitting faces, in
//!      plain sight of the point count for the side they lie on (twice: light is the
//!      strongest sign of where a surface is meant to be seen from);
//!    - the other surfaces: a ray leaving the point on one side that meets the *front* of
//!      another surface counts for that side, one that meets a *back* counts against it
//!      (its side faces into something's inside). Rays that leave the scene or meet the
//!      same surface say nothing: a closed room and a solid box look alike from themselves.
//!
//!    A surface is turned only when its back is seen ([`FLIP_MIN_VOTES`]) and its front not
//!    at all: the rest of a scene that is mostly right pulls its few wrong faces round, a
//!    face seen from both sides (a pool's surface against its pit's walls, a one-sided
//!    blocker seen by the light above and the floor below) keeps its winding, and so does a
//!    scene with no evidence. Surfaces that neither reflect nor emit (ρ = 0, Le = 0) are
//!    never turned: either side of them is the same. Blender's "recalculate normals" does step 1
//!    and, for closed shells, turns them outward; step 2 differs because an interior's walls are
//!    meant to be seen from inside.
//!
//! 3. **A back side where both are seen.** A surface whose front and back are both seen
//!    from the open (each by at least what a turn needs, counting lights and rays that
//!    travel farther than [`NEAR_SHARE`] of its size: not a panel's back seen by the
//!    ceiling it is mounted under; its back more than it meets other surfaces' backs) gets
//!    twins ([`Scene::make_two_sided_where`]): a free-standing screen, a shelf
//!    of one sheet, a partition between two rooms. Not a surface with an emitting face (a
//!    lamp's back stays dark, as the ceiling just above it should), nor one whose material
//!    the file says is one-sided ([`crate::scene::Material::one_sided`]).
//!
//! It reads no materials but emission, darkness and `one_sided`.

use std::collections::HashMap;

use glam::DVec3;

use super::Scene;
use crate::geometry::orthonormal_basis;
use crate::sampling::{malley, point_in_triangle, ByArea, Rng};
use crate::visibility::{Visibility, NONE};

/// Sample points per surface (at most; fewer on surfaces of fewer faces), spread by area.
pub const POINTS: usize = 24;

/// Rays per sample point and side.
pub const RAYS: usize = 4;

/// Light points (point lights and points in front of emitting faces) each sample point
/// tests, at most.
pub const LIGHTS_PER_POINT: usize = 4;

/// A surface is turned only when nothing sees its front (no light in plain sight, no ray
/// meeting another surface's front) and what sees its back is at least this many votes, and at
/// least [`FLIP_MIN_SHARE`] of the votes its points could cast on one side (a small surface's few
/// points must agree more).
pub const FLIP_MIN_VOTES: i64 = 4;

/// See [`FLIP_MIN_VOTES`].
pub const FLIP_MIN_SHARE: f64 = 0.25;

/// Whether a bake repairs the faces' orientation (`--orient`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Orient {
    /// Turn faces as the module documentation says ([`orient`]); not with `--two-sided`,
    /// where both sides are kept anyway.
    #[default]
    Auto,
    /// Bake the winding as the file gives it.
    Keep,
}

impl crate::choice::Choice for Orient {
    const SETTING: &'static str = "orient";
    const ALL: &'static [Orient] = &[Orient::Auto, Orient::Keep];

    fn name(self) -> &'static str {
        match self {
            Orient::Auto => "auto",
            Orient::Keep => "keep",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Orient::Auto => {
                "make each surface's faces agree and turn it to face where the light and the \
                 rest of the scene see it from (reported)"
            }
            Orient::Keep => "bake the winding as the file gives it",
        }
    }
}

impl std::fmt::Display for Orient {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(crate::choice::Choice::name(*self))
    }
}

/// Passes of step 2 at most: each reads every surface against the others as the last left
/// them.
pub const MAX_PASSES: usize = 4;

/// What [`orient`] turned.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Orientation {
    /// Surfaces found (groups of faces joined along edges two faces share).
    pub surfaces: usize,
    /// Faces turned to agree with the rest of their surface.
    pub made_consistent: usize,
    /// Surfaces turned, as a whole, to face where they are seen from.
    pub surfaces_turned: usize,
    /// Faces those surfaces hold.
    pub faces_turned: usize,
    /// Edges where a surface cannot agree with itself (a Möbius band; the first orientation
    /// met is kept).
    pub conflicts: usize,
    /// The first few turned surfaces, each as "material (face index) × faces".
    pub examples: Vec<String>,
    /// Surfaces seen from both sides that were given a back side of their own.
    pub two_sided_surfaces: usize,
    /// Faces those surfaces hold (each now has a twin: the bake has that many more faces).
    pub two_sided_faces: usize,
    /// The first few of those surfaces, each as "material (face index) × faces".
    pub two_sided_examples: Vec<String>,
}

impl Orientation {
    /// True if a face was turned or given a back side.
    pub fn changed(&self) -> bool {
        self.made_consistent > 0 || self.faces_turned > 0 || self.two_sided_faces > 0
    }

    /// One line for the warnings: what was turned, with a few examples.
    pub fn summary(&self) -> String {
        let mut parts = Vec::new();
        if self.made_consistent > 0 {
            parts.push(format!(
                "{} face{} turned to agree with the surface around {}",
                self.made_consistent,
                if self.made_consistent == 1 { "" } else { "s" },
                if self.made_consistent == 1 {
                    "it"
                } else {
                    "them"
                }
            ));
        }
        if self.surfaces_turned > 0 {
            parts.push(format!(
                "{} surface{} ({} faces) turned over to face where the light and the rest of \
                 the scene see {} from: {}",
                self.surfaces_turned,
                if self.surfaces_turned == 1 { "" } else { "s" },
                self.faces_turned,
                if self.surfaces_turned == 1 {
                    "it"
                } else {
                    "them"
                },
                self.examples.join(", ")
            ));
        }
        if self.two_sided_surfaces > 0 {
            parts.push(format!(
                "{} surface{} ({} faces) seen from both sides given a back side of {}: {}",
                self.two_sided_surfaces,
                if self.two_sided_surfaces == 1 {
                    ""
                } else {
                    "s"
                },
                self.two_sided_faces,
                if self.two_sided_surfaces == 1 {
                    "its own"
                } else {
                    "their own"
                },
                self.two_sided_examples.join(", ")
            ));
        }
        format!(
            "orientation repaired (--orient auto; --orient keep bakes the winding as given): {}",
            parts.join("; ")
        )
    }
}

/// The scene with its faces turned and its surfaces seen from both sides given back sides,
/// as the module documentation says, and what was done. `lights` are positions (scene
/// units) of point lights lighting it. Deterministic for a `seed`. `scene` must satisfy the
/// [`Scene`] invariants and be one-sided (no twins; a scene with twins is returned as it is).
pub fn orient(scene: &Scene, lights: &[DVec3], seed: u64) -> (Scene, Orientation) {
    let n = scene.triangles.len();
    let mut out = scene.clone();
    let mut report = Orientation::default();
    if n == 0 || !scene.twin.is_empty() {
        return (out, report);
    }
    let (surface, flip, conflicts) = surfaces(scene);
    report.conflicts = conflicts;
    let count = surface.iter().map(|&s| s as usize + 1).max().unwrap_or(0);
    report.surfaces = count;
    // Step 1: keep the larger part (by area) of each surface as it is.
    let mut area = vec![[0.0f64; 2]; count];
    for t in 0..n {
        area[surface[t] as usize][usize::from(flip[t])] += scene.triangle_area(t);
    }
    for t in 0..n {
        let s = surface[t] as usize;
        let turn = flip[t] != (area[s][1] > area[s][0]);
        if turn {
            out.triangles[t].vertices.swap(1, 2);
            report.made_consistent += 1;
        }
    }

    // Step 2: each surface to the side it is seen from.
    let mut corners = out.triangle_corners();
    let (lo, hi) = out.bounds();
    let lift = 1e-5 * (hi - lo).length();
    let light_points = light_points(&out, &corners, lights, lift);
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); count];
    for t in 0..n {
        members[surface[t] as usize].push(t);
    }
    // Each surface's evidence is read against the others' current orientation: passes
    // until none turns (a box read against walls still turned wrong turns back once they
    // are right), at most MAX_PASSES.
    let mut turned = vec![false; count];
    let mut votes = Vec::new();
    for pass in 0..=MAX_PASSES {
        votes = vote_pass(
            &out,
            &corners,
            &surface,
            &members,
            &light_points,
            lift,
            seed,
            pass,
        );
        let flips: Vec<bool> = votes.iter().map(|&v| turns(v)).collect();
        // The last pass only reads the votes for the back sides below.
        if !flips.contains(&true) || pass == MAX_PASSES {
            break;
        }
        for (s, faces) in members.iter().enumerate() {
            if flips[s] {
                turned[s] = !turned[s];
                for &t in faces {
                    out.triangles[t].vertices.swap(1, 2);
                }
            }
        }
        corners = out.triangle_corners();
    }
    for (s, faces) in members.iter().enumerate() {
        if !turned[s] {
            continue;
        }
        report.surfaces_turned += 1;
        report.faces_turned += faces.len();
        example(&out, faces, &mut report.examples);
    }

    // Step 3: a back side for each surface seen from both sides, unless a face of it emits
    // (a lamp's back stays dark) or the file says its material is one-sided.
    let mut two_sided = vec![false; n];
    for (s, faces) in members.iter().enumerate() {
        let allowed = faces.iter().all(|&t| {
            let m = &out.materials[out.triangles[t].material as usize];
            !m.is_emitter() && !m.one_sided
        });
        if !allowed || !both_sides_seen(votes[s]) {
            continue;
        }
        report.two_sided_surfaces += 1;
        report.two_sided_faces += faces.len();
        example(&out, faces, &mut report.two_sided_examples);
        for &t in faces {
            two_sided[t] = true;
        }
    }
    if report.two_sided_faces > 0 {
        out.make_two_sided_where(|t, _| two_sided.get(t).copied().unwrap_or(false));
    }
    (out, report)
}

/// Adds the surface `faces` to `examples` as "material (face index) × faces", unless it
/// holds 5 already.
fn example(scene: &Scene, faces: &[usize], examples: &mut Vec<String>) {
    if examples.len() < 5 {
        let t = faces[0];
        let m = &scene.materials[scene.triangles[t].material as usize].name;
        examples.push(format!("'{m}' (face {t}) × {}", faces.len()));
    }
}

/// Each surface's votes against the scene as it is, and the votes a side needs to count as
/// seen ([`FLIP_MIN_VOTES`], [`FLIP_MIN_SHARE`]); `None` for a surface that neither reflects
/// nor emits.
#[allow(clippy::too_many_arguments)]
fn vote_pass(
    scene: &Scene,
    corners: &[[DVec3; 3]],
    surface: &[u32],
    members: &[Vec<usize>],
    lights: &[DVec3],
    lift: f64,
    seed: u64,
    pass: usize,
) -> Vec<Option<([Votes; 2], i64)>> {
    use rayon::prelude::*;
    let vis = Visibility::build(corners);
    members
        .par_iter()
        .enumerate()
        .map(|(s, faces)| {
            let dark = faces.iter().all(|&t| {
                let m = &scene.materials[scene.triangles[t].material as usize];
                m.reflectance.iter().all(|&r| r == 0.0) && !m.is_emitter()
            });
            if dark {
                return None;
            }
            let mut rng = Rng::new(&[seed, s as u64, pass as u64, 0x0121E17]);
            let votes = side_votes(&vis, corners, surface, faces, lights, lift, scene, &mut rng);
            // Every vote the points could cast on one side: rays, and lights at 2.
            let points = POINTS.min(faces.len().max(4)) as i64;
            let possible = points * (RAYS + 2 * LIGHTS_PER_POINT.min(lights.len())) as i64;
            let needed = FLIP_MIN_VOTES.max((FLIP_MIN_SHARE * possible as f64).ceil() as i64);
            Some((votes, needed))
        })
        .collect()
}

/// True if a surface with these votes is turned: its back seen, its front not at all.
fn turns(votes: Option<([Votes; 2], i64)>) -> bool {
    votes.is_some_and(|([front, back], needed)| back.seen >= needed && front.seen == 0)
}

/// True if a surface with these votes gets a back side: both sides seen from the open
/// ([`Votes::seen_far`]), the back more than it faces into something's inside.
fn both_sides_seen(votes: Option<([Votes; 2], i64)>) -> bool {
    votes.is_some_and(|([front, back], needed)| {
        front.seen_far >= needed && back.seen_far >= needed && back.seen > back.against
    })
}

/// Each face's surface (numbered from 0 in order of their first face), whether it must be
/// turned to agree with its surface's first face, and the number of edges that disagree
/// whatever is turned.
fn surfaces(scene: &Scene) -> (Vec<u32>, Vec<bool>, usize) {
    let n = scene.triangles.len();
    // Each undirected edge's faces, with the direction the face runs it (true: low → high).
    let mut edges: HashMap<(u32, u32), Vec<(u32, bool)>> = HashMap::with_capacity(3 * n / 2);
    for (t, tri) in scene.triangles.iter().enumerate() {
        let v = tri.vertices;
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            edges
                .entry((a.min(b), a.max(b)))
                .or_default()
                .push((t as u32, a < b));
        }
    }
    let mut neighbours: Vec<Vec<(u32, bool)>> = vec![Vec::new(); n];
    for faces in edges.values() {
        if let [(a, da), (b, db)] = faces[..] {
            // Agreeing faces run a shared edge opposite ways: "same" asks for a turn.
            neighbours[a as usize].push((b, da == db));
            neighbours[b as usize].push((a, da == db));
        }
    }
    for list in &mut neighbours {
        list.sort_unstable();
    }
    let mut surface = vec![u32::MAX; n];
    let mut flip = vec![false; n];
    let mut conflicts = 0;
    let mut next = 0u32;
    let mut stack = Vec::new();
    for start in 0..n {
        if surface[start] != u32::MAX {
            continue;
        }
        surface[start] = next;
        stack.push(start);
        while let Some(t) = stack.pop() {
            for &(u, turn) in &neighbours[t] {
                let want = flip[t] != turn;
                let u = u as usize;
                if surface[u] == u32::MAX {
                    surface[u] = next;
                    flip[u] = want;
                    stack.push(u);
                } else if flip[u] != want && u > t {
                    conflicts += 1;
                }
            }
        }
        next += 1;
    }
    (surface, flip, conflicts)
}

/// Points the scene's light comes from: the point lights, and a point `lift` in front of
/// the centroid of each emitting face (at most 256 of them, spread over the faces).
fn light_points(scene: &Scene, corners: &[[DVec3; 3]], lights: &[DVec3], lift: f64) -> Vec<DVec3> {
    let mut points: Vec<DVec3> = lights.to_vec();
    let emitting: Vec<usize> = (0..scene.triangles.len())
        .filter(|&t| scene.materials[scene.triangles[t].material as usize].is_emitter())
        .collect();
    let step = emitting.len().div_ceil(256).max(1);
    for &t in emitting.iter().step_by(step) {
        let [a, b, c] = corners[t];
        let n = (b - a).cross(c - a).normalize_or_zero();
        points.push((a + b + c) / 3.0 + lift * n);
    }
    points
}

/// The evidence about one side of a surface.
#[derive(Clone, Copy, Debug, Default)]
struct Votes {
    /// What sees this side: lights in plain sight (2 each) and rays that meet the front of
    /// another surface.
    seen: i64,
    /// Rays from this side that meet the back of another surface: this side faces into
    /// something's inside.
    against: i64,
    /// Of `seen`, the lights and the rays that travel farther than [`NEAR_SHARE`] of the
    /// surface's size (the square root of its area) first: what sees this side from the
    /// open, not through the gap of a panel mounted on a wall.
    seen_far: i64,
}

/// Rays that meet another surface's front within this share of the surface's size (the
/// square root of its area) see it through a gap, as the ceiling sees the back of a panel
/// mounted just under it: they do not count for giving the surface a back side.
pub const NEAR_SHARE: f64 = 0.05;

/// Votes for surface `faces`'s front and back: see the module documentation.
#[allow(clippy::too_many_arguments)]
fn side_votes(
    vis: &Visibility,
    corners: &[[DVec3; 3]],
    surface: &[u32],
    faces: &[usize],
    lights: &[DVec3],
    lift: f64,
    scene: &Scene,
    rng: &mut Rng,
) -> [Votes; 2] {
    let total: f64 = faces.iter().map(|&t| scene.triangle_area(t)).sum();
    if total <= 0.0 {
        return [Votes::default(); 2];
    }
    let own = surface[faces[0]];
    let near = NEAR_SHARE * total.sqrt();
    let points = POINTS.min(faces.len().max(4));
    let mut votes = [Votes::default(); 2];
    let areas: Vec<f64> = faces.iter().map(|&t| scene.triangle_area(t)).collect();
    let mut strata = ByArea::new(&areas, points);
    for p in 0..points {
        let t = faces[strata.pick(p, rng)];
        let [a, b, c] = corners[t];
        let Some(n) = (b - a).cross(c - a).try_normalize() else {
            continue;
        };
        let x = point_in_triangle(corners[t], rng);
        // The light in plain sight.
        if !lights.is_empty() {
            for _ in 0..LIGHTS_PER_POINT.min(lights.len()) {
                let l = lights[(rng.next_u64() % lights.len() as u64) as usize];
                let d = (l - x).dot(n);
                if d.abs() <= lift {
                    continue;
                }
                let from = x + lift.copysign(d) * n;
                if !vis.occluded(from, l, [t as u32, NONE]) {
                    votes[usize::from(d < 0.0)].seen += 2;
                    votes[usize::from(d < 0.0)].seen_far += 2;
                }
            }
        }
        // The other surfaces met on each side.
        let (tangent, bitangent) = orthonormal_basis(n);
        for (side, normal) in [(0, n), (1, -n)] {
            for _ in 0..RAYS {
                let dir = malley(rng.next_f64(), rng.next_f64(), tangent, bitangent, normal);
                let Some(hit) = vis.closest_hit(x, dir, f64::INFINITY, t as u32) else {
                    continue;
                };
                let h = hit.triangle as usize;
                if surface[h] == own {
                    continue;
                }
                let [p, q, r] = corners[h];
                let facing = (q - p).cross(r - p).dot(dir);
                if facing < 0.0 {
                    votes[side].seen += 1;
                    if hit.t > near {
                        votes[side].seen_far += 1;
                    }
                } else if facing > 0.0 {
                    votes[side].against += 1;
                }
            }
        }
    }
    votes
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::SceneBuilder;

    /// [`crate::validation::scenes::lamp_room`], built.
    fn room(wrong: &[usize], gaps: bool) -> Scene {
        crate::validation::scenes::lamp_room(wrong, gaps)
            .build()
            .unwrap()
    }

    fn normal(s: &Scene, t: usize) -> DVec3 {
        let [a, b, c] = s.triangles[t].vertices.map(|v| s.positions[v as usize]);
        (b - a).cross(c - a).normalize()
    }

    #[test]
    fn a_right_room_is_left_as_it_is() {
        for gaps in [false, true] {
            let s = room(&[], gaps);
            let (out, report) = orient(&s, &[], 1);
            assert!(!report.changed(), "{report:?}");
            assert_eq!(out.triangles, s.triangles);
        }
    }

    #[test]
    fn walls_wound_outward_are_turned_to_face_the_room() {
        // Separate walls, three wrong: the lamp and the other walls see their backs.
        let right = room(&[], true);
        let s = room(&[0, 3, 5], true);
        let (out, report) = orient(&s, &[], 1);
        assert_eq!(
            (report.surfaces, report.made_consistent),
            (8, 0),
            "{report:?}"
        );
        assert_eq!(report.surfaces_turned, 3, "{report:?}");
        assert_eq!(report.faces_turned, 6);
        let same = |out: &Scene, right: &Scene| {
            (0..out.triangles.len()).all(|t| normal(out, t).dot(normal(right, t)) > 0.999)
        };
        assert!(same(&out, &right));
        assert!(report.summary().contains("'wall'"));
        // Every wall wrong: the lamp alone (the box faces out, as it should) turns them all.
        let (out, report) = orient(&room(&[0, 1, 2, 3, 4, 5], true), &[], 2);
        assert_eq!(report.surfaces_turned, 6, "{report:?}");
        assert!(same(&out, &right));
        // Welded, the walls are one surface: two wrong walls of six agree with the others
        // (the larger part by area), and all six wrong turn over as one.
        let right = room(&[], false);
        let (out, report) = orient(&room(&[3, 5], false), &[], 3);
        assert_eq!(
            (report.surfaces, report.made_consistent),
            (3, 4),
            "{report:?}"
        );
        assert_eq!(report.surfaces_turned, 0, "{report:?}");
        assert!(same(&out, &right));
        let (out, report) = orient(&room(&[0, 1, 2, 3, 4, 5], false), &[], 4);
        assert_eq!(
            (report.surfaces_turned, report.faces_turned),
            (1, 12),
            "{report:?}"
        );
        assert!(same(&out, &right));
    }

    #[test]
    fn a_sheet_seen_from_both_sides_gets_a_back_side_unless_its_file_says_one_sided() {
        // A shelf of one sheet across the room at half height, facing up, with a gap to
        // every wall: the lamp sees its top, the floor and the walls its underside. It alone
        // gets twins (reversed, same material); the lamp (seen from behind by the ceiling)
        // never does, nor the walls or the box, whose backs see nothing or only backs.
        let with_shelf = |one_sided: bool| {
            let base = room(&[], true);
            let mut b = SceneBuilder::new();
            for m in &base.materials {
                b.material(&m.name, m.reflectance, m.emission);
            }
            let shelf = b.material("shelf", [0.5; 3], [0.0; 3]);
            for t in &base.triangles {
                let v = t.vertices.map(|v| b.vertex(base.positions[v as usize]));
                b.triangle(v, t.material);
            }
            let p = |x: f64, z: f64| DVec3::new(x, 1.5, z);
            b.quad([p(0.5, 0.5), p(0.5, 3.5), p(3.5, 3.5), p(3.5, 0.5)], shelf);
            let mut s = b.build().unwrap();
            s.materials[shelf as usize].one_sided = one_sided;
            (s, shelf)
        };
        let (s, shelf) = with_shelf(false);
        let n = s.triangles.len();
        let (out, report) = orient(&s, &[], 5);
        assert_eq!(
            (report.two_sided_surfaces, report.two_sided_faces),
            (1, 2),
            "{report:?}"
        );
        assert!(report.summary().contains("'shelf'"), "{}", report.summary());
        assert_eq!(out.triangles.len(), n + 2);
        out.validate().unwrap();
        for t in 0..n {
            let twin = out.twin[t];
            assert_eq!(
                twin != crate::scene::NO_TWIN,
                s.triangles[t].material == shelf,
                "{t}"
            );
        }
        let (out, report) = orient(&with_shelf(true).0, &[], 5);
        assert_eq!(report.two_sided_faces, 0, "{report:?}");
        assert!(out.twin.is_empty() || !out.is_two_sided());
    }

    #[test]
    fn a_surface_agrees_with_itself_and_a_point_light_is_evidence() {
        // One welded floor of 2 × 2 quads (8 triangles) with one triangle turned, under a
        // point light: the odd triangle is turned back, and the floor faces the light.
        let mut b = SceneBuilder::new();
        let m = b.material("floor", [0.5; 3], [0.0; 3]);
        let v: Vec<u32> = (0..9)
            .map(|i| b.vertex(DVec3::new((i % 3) as f64, 0.0, (i / 3) as f64)))
            .collect();
        for (i, j) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let c = |di: usize, dj: usize| v[(j + dj) * 3 + i + di];
            // Counter-clockwise seen from +y: (x, z) → ... faces up.
            b.triangle([c(0, 0), c(0, 1), c(1, 1)], m);
            if (i, j) == (1, 1) {
                b.triangle([c(0, 0), c(1, 0), c(1, 1)], m); // the odd one
            } else {
                b.triangle([c(0, 0), c(1, 1), c(1, 0)], m);
            }
        }
        let s = b.build().unwrap();
        let (out, report) = orient(&s, &[DVec3::new(1.0, 2.0, 1.0)], 3);
        assert_eq!(report.surfaces, 1);
        assert_eq!(report.made_consistent, 1, "{report:?}");
        assert_eq!(report.surfaces_turned, 0);
        assert!((0..8).all(|t| normal(&out, t).y > 0.999));
        // The light below: the whole floor turns to face it.
        let (out, report) = orient(&s, &[DVec3::new(1.0, -2.0, 1.0)], 3);
        assert_eq!(report.surfaces_turned, 1, "{report:?}");
        assert!((0..8).all(|t| normal(&out, t).y < -0.999));
    }
}
