//! Procedural scenes with known answers: the integrating sphere, the furnace room, and plate
//! pairs from Howell's catalog. Used by `radiosity verify`, the tests, the benchmarks and
//! `radiosity generate` (which writes them as OBJ for other tools). Geometry only; the
//! expected answers live in [`crate::validation::closed_forms`].

use glam::DVec3;

pub use crate::geometry::box_faces;
use crate::scene::{Scene, SceneBuilder};
use crate::Result;

mod office;
pub use office::{office, office_daylit};

/// A geodesic sphere of radius `radius` centred at the origin, seen from inside (every face's
/// front side — counter-clockwise winding — faces the centre). Made by subdividing an
/// icosahedron `level` times (20·4^level faces) and projecting onto the sphere. Faces whose
/// centroid lies in the cap z > radius·cos(cap_half_angle) emit `le`; all have reflectance `rho`.
pub fn integrating_sphere(
    radius: f64,
    level: u32,
    cap_half_angle_degrees: f64,
    rho: f64,
    le: [f64; 3],
) -> Result<Scene> {
    let (positions, faces) = crate::geometry::icosphere(level);
    let mut b = SceneBuilder::new();
    let wall = b.material("wall", [rho; 3], [0.0; 3]);
    let cap = b.material("cap", [rho; 3], le);
    let ids: Vec<u32> = positions.iter().map(|p| b.vertex(*p * radius)).collect();
    let z_cap = radius * cap_half_angle_degrees.to_radians().cos();
    for f in faces {
        let centroid = (positions[f[0]] + positions[f[1]] + positions[f[2]]) * (radius / 3.0);
        let m = if centroid.z > z_cap * (1.0 - 1e-12) && cap_half_angle_degrees > 0.0 {
            cap
        } else {
            wall
        };
        // icosphere() winds outward; reverse for the inside.
        b.triangle([ids[f[0]], ids[f[2]], ids[f[1]]], m);
    }
    b.build()
}

/// Add an axis-aligned box [lo, hi] made of six quads, fronts facing inward (`inward`) or
/// outward.
pub fn add_box(b: &mut SceneBuilder, lo: DVec3, hi: DVec3, inward: bool, material: u32) {
    for mut q in box_faces(lo, hi) {
        if inward {
            q.reverse();
        }
        b.quad(q, material);
    }
}

/// A 4 × 3 × 4 room (y up) for the orientation repair: walls of the material "wall" (ρ 0.6),
/// a 1 × 1 lamp ("lamp", Le 5) 1 cm under the ceiling facing down, and a 0.6 m box ("box",
/// ρ 0.4) on the floor facing out, in that order (materials 0, 1, 2). `wrong` lists the
/// walls (0 floor, 1 ceiling, 2–5 the sides) wound outward. With `gaps` each wall is inset
/// by 1 mm from its edges: no wall shares a corner with another, so each is a surface of its
/// own; without, the welded walls are one. A builder, so that tests add faces.
pub fn lamp_room(wrong: &[usize], gaps: bool) -> SceneBuilder {
    let mut b = SceneBuilder::new();
    let wall = b.material("wall", [0.6; 3], [0.0; 3]);
    let lamp = b.material("lamp", [0.0; 3], [5.0; 3]);
    let boxm = b.material("box", [0.4; 3], [0.0; 3]);
    let p = DVec3::new;
    let (w, h, d) = (4.0, 3.0, 4.0);
    // Inward-facing walls.
    let walls = [
        [p(0., 0., 0.), p(0., 0., d), p(w, 0., d), p(w, 0., 0.)],
        [p(0., h, 0.), p(w, h, 0.), p(w, h, d), p(0., h, d)],
        [p(0., 0., 0.), p(w, 0., 0.), p(w, h, 0.), p(0., h, 0.)],
        [p(0., 0., d), p(0., h, d), p(w, h, d), p(w, 0., d)],
        [p(0., 0., 0.), p(0., h, 0.), p(0., h, d), p(0., 0., d)],
        [p(w, 0., 0.), p(w, 0., d), p(w, h, d), p(w, h, 0.)],
    ];
    for (i, q) in walls.iter().enumerate() {
        let centre = (q[0] + q[1] + q[2] + q[3]) / 4.0;
        let q = if gaps {
            q.map(|c| c + 1e-3 * (centre - c).normalize())
        } else {
            *q
        };
        // Reversed about the first corner: the same diagonal, the other way round.
        let q = if wrong.contains(&i) {
            [q[0], q[3], q[2], q[1]]
        } else {
            q
        };
        b.quad(q, wall);
    }
    let y = h - 0.01;
    b.quad(
        [
            p(1.5, y, 1.5),
            p(2.5, y, 1.5),
            p(2.5, y, 2.5),
            p(1.5, y, 2.5),
        ],
        lamp,
    );
    add_box(&mut b, p(1.0, 0.0, 1.0), p(1.6, 0.6, 1.6), false, boxm);
    b
}

/// The furnace: a closed, non-convex enclosure — a unit room (seen from inside) holding two
/// floating boxes (seen from outside), which shadow each other and the walls — with one material of
/// reflectance `rho` and emission `le` everywhere. Expected: L = Le / (1 − ρ) on every patch
/// ([`crate::validation::closed_forms::furnace_radiance`]).
pub fn furnace_room(rho: f64, le: f64) -> Result<Scene> {
    let mut b = SceneBuilder::new();
    let m = b.material("furnace", [rho; 3], [le; 3]);
    add_box(&mut b, DVec3::ZERO, DVec3::ONE, true, m);
    add_box(
        &mut b,
        DVec3::new(0.25, 0.3, 0.2),
        DVec3::new(0.55, 0.6, 0.5),
        false,
        m,
    );
    // A second, flat box near the floor (not touching it: a touching box would hide floor
    // patches from everything, leaving them outside the enclosure).
    add_box(
        &mut b,
        DVec3::new(0.6, 0.05, 0.55),
        DVec3::new(0.85, 0.4, 0.8),
        false,
        m,
    );
    b.build()
}

/// A courtyard open above and at both ends: a 2 × 1 floor (z = 0, facing up) and two 1 m
/// walls facing each other across it (x = 0 and x = 2), all of reflectance `rho`
/// ("white"). Lit by [`courtyard_light`], the walls see the floor and each other.
pub fn courtyard(rho: [f64; 3]) -> Result<Scene> {
    let mut b = SceneBuilder::new();
    let white = b.material("white", rho, [0.0; 3]);
    let p = DVec3::new;
    b.quad(
        [p(0., 0., 0.), p(2., 0., 0.), p(2., 1., 0.), p(0., 1., 0.)],
        white,
    );
    b.quad(
        [p(0., 0., 0.), p(0., 1., 0.), p(0., 1., 1.), p(0., 0., 1.)],
        white,
    );
    b.quad(
        [p(2., 0., 0.), p(2., 0., 1.), p(2., 1., 1.), p(2., 1., 0.)],
        white,
    );
    b.build()
}

/// A uniform sky of radiance 1 and a low sun (azimuth 90°, elevation 35°, 30 W·m⁻²), z up:
/// the [`courtyard`]'s light, one wall in the sun and the other in shade.
pub fn courtyard_light() -> crate::scene::Environment {
    crate::scene::Environment {
        sky: [1.0; 3],
        sky_model: crate::scene::SkyModel::Uniform,
        sun: Some(crate::scene::Sun {
            azimuth_degrees: 90.0,
            elevation_degrees: 35.0,
            irradiance: [30.0; 3],
        }),
        up: crate::scene::Up::Z,
        lights: Vec::new(),
    }
}

/// Two identical parallel, directly opposed rectangles a × b at distance c (Howell C-11):
/// "source" at z = 0 facing +z, "receiver" at z = c facing −z. The receiver has reflectance
/// `rho`, the source emits `le`.
pub fn parallel_plates(a: f64, b_: f64, c: f64, rho: f64, le: f64) -> Result<Scene> {
    let mut b = SceneBuilder::new();
    let src = b.material("source", [0.0; 3], [le; 3]);
    let rcv = b.material("receiver", [rho; 3], [0.0; 3]);
    b.quad(
        [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(a, 0.0, 0.0),
            DVec3::new(a, b_, 0.0),
            DVec3::new(0.0, b_, 0.0),
        ],
        src,
    );
    b.quad(
        [
            DVec3::new(0.0, 0.0, c),
            DVec3::new(0.0, b_, c),
            DVec3::new(a, b_, c),
            DVec3::new(a, 0.0, c),
        ],
        rcv,
    );
    b.build()
}

/// Two rectangles at 90° sharing the edge x ∈ [0, l] (Howell C-14): "receiver" (width w, in
/// the plane z = 0 facing +z, y ∈ [0, w]) and "source" (width h, in the plane y = 0 facing +y,
/// z ∈ [0, h]). Receiver reflectance `rho`, source emission `le`.
pub fn perpendicular_plates(l: f64, w: f64, h: f64, rho: f64, le: f64) -> Result<Scene> {
    let mut b = SceneBuilder::new();
    let src = b.material("source", [0.0; 3], [le; 3]);
    let rcv = b.material("receiver", [rho; 3], [0.0; 3]);
    b.quad(
        [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(l, 0.0, 0.0),
            DVec3::new(l, w, 0.0),
            DVec3::new(0.0, w, 0.0),
        ],
        rcv,
    );
    b.quad(
        [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, h),
            DVec3::new(l, 0.0, h),
            DVec3::new(l, 0.0, 0.0),
        ],
        src,
    );
    b.build()
}

/// Triangles of one cell of [`furnished_hall`]: a table (top and four legs) and a chair
/// (seat, back and four legs), 11 boxes of 12 triangles, 5 mm apart where they meet (boxes
/// that touch would share edges run the same way).
pub const HALL_CELL_TRIANGLES: usize = 132;

/// A furnished hall for measuring scale: a closed room (walls, floor and ceiling seen from
/// inside, ρ = 0.6 grey) holding a k × k grid of 2 m × 2 m cells, each with a table and a chair
/// (boxes, ρ = 0.7 wood, 0.5 red seats) and, over every other cell, a 0.5 m × 0.5 m area light
/// 1 cm below the ceiling facing down (Le = 10). k is the smallest grid with at least
/// `triangles` triangles in all ([`HALL_CELL_TRIANGLES`] per cell, 12 for the room, 2 per
/// light). Lengths in metres; deterministic (no randomness), so a size names a scene.
pub fn furnished_hall(triangles: usize) -> Result<Scene> {
    let per_cell = HALL_CELL_TRIANGLES as f64 + 1.0;
    let k = ((triangles.saturating_sub(12) as f64 / per_cell)
        .sqrt()
        .ceil() as usize)
        .max(1);
    let mut b = SceneBuilder::new();
    let wall = b.material("wall", [0.6; 3], [0.0; 3]);
    let wood = b.material("wood", [0.7, 0.55, 0.35], [0.0; 3]);
    let seat = b.material("seat", [0.6, 0.15, 0.1], [0.0; 3]);
    let light = b.material("light", [0.0; 3], [10.0; 3]);
    let (cell, height) = (2.0, 3.0);
    let size = k as f64 * cell;
    add_box(
        &mut b,
        DVec3::ZERO,
        DVec3::new(size, size, height),
        true,
        wall,
    );
    let boxed = |b: &mut SceneBuilder, lo: [f64; 3], hi: [f64; 3], m: u32| {
        add_box(b, DVec3::from(lo), DVec3::from(hi), false, m)
    };
    // Four square legs, `side` wide and `height` tall, with their low corners at (x, y),
    // (x + dx, y), (x, y + dy) and (x + dx, y + dy).
    let legs = |b: &mut SceneBuilder, (x, y): (f64, f64), (dx, dy): (f64, f64), side, height| {
        for (lx, ly) in [(0.0, 0.0), (dx, 0.0), (0.0, dy), (dx, dy)] {
            boxed(
                b,
                [x + lx, y + ly, 0.0],
                [x + lx + side, y + ly + side, height],
                wood,
            );
        }
    };
    for i in 0..k {
        for j in 0..k {
            let (x, y) = (i as f64 * cell, j as f64 * cell);
            // Table: 1.2 × 0.8 top at 0.72–0.75 m, legs 5 cm square.
            let (tx, ty) = (x + 0.4, y + 0.6);
            boxed(&mut b, [tx, ty, 0.72], [tx + 1.2, ty + 0.8, 0.75], wood);
            legs(&mut b, (tx, ty), (1.15, 0.75), 0.05, 0.715);
            // Chair: 0.45 m seat at 0.43–0.46 m, back 0.45 m high, legs 4 cm.
            let (cx, cy) = (x + 0.78, y + 0.1);
            boxed(&mut b, [cx, cy, 0.43], [cx + 0.45, cy + 0.45, 0.46], seat);
            boxed(&mut b, [cx, cy, 0.465], [cx + 0.45, cy + 0.04, 0.91], seat);
            legs(&mut b, (cx, cy), (0.41, 0.41), 0.04, 0.425);
            if (i + j) % 2 == 0 {
                let (lx, ly, z) = (x + 0.75, y + 0.75, height - 0.01);
                b.quad(
                    [
                        DVec3::new(lx, ly, z),
                        DVec3::new(lx, ly + 0.5, z),
                        DVec3::new(lx + 0.5, ly + 0.5, z),
                        DVec3::new(lx + 0.5, ly, z),
                    ],
                    light,
                );
            }
        }
    }
    b.build()
}

/// A living room (metres, z up), made for the point-wise benchmark as a scene nothing was
/// tuned to: a 5 × 4 × 2.6 m room with an off-white ceiling and walls, a blue wall (x = 5) and a
/// wooden floor; two lights (a 1 × 0.5 m ceiling panel, Le = 12, and a warm 0.3 m wall lamp on
/// the wall y = 0); a sofa against the wall y = 4 and a bookshelf against the blue wall (contact
/// lines with the floor and the walls), a coffee table on 4 cm legs, and a ball of radius
/// 0.25 m resting on the floor (320 faces). 432 triangles; every surface one-sided, facing
/// into the room.
pub fn living_room() -> Result<Scene> {
    let mut b = SceneBuilder::new();
    let white = b.material("plaster", [0.75, 0.72, 0.68], [0.0; 3]);
    let blue = b.material("blue_wall", [0.25, 0.35, 0.6], [0.0; 3]);
    let floor = b.material("floor", [0.45, 0.35, 0.25], [0.0; 3]);
    let sofa = b.material("sofa", [0.2, 0.5, 0.3], [0.0; 3]);
    let wood = b.material("wood", [0.7, 0.55, 0.35], [0.0; 3]);
    let shelf = b.material("shelf", [0.5, 0.3, 0.2], [0.0; 3]);
    let ball = b.material("ball", [0.8; 3], [0.0; 3]);
    let panel = b.material("panel", [0.0; 3], [12.0; 3]);
    let lamp = b.material("lamp", [0.0; 3], [8.0, 6.0, 4.0]);
    let height = 2.6;
    let size = DVec3::new(5.0, 4.0, height);
    // The room, seen from inside, its wall x = 5 (+x) blue.
    room_shell(&mut b, size, floor, white, Some((1, blue)));
    let v = DVec3::new;
    // The ceiling panel, 1 cm under the ceiling, facing down.
    let (lx, ly, z) = (1.1, 1.95, height - 0.01);
    b.quad(
        [
            v(lx, ly, z),
            v(lx, ly + 0.5, z),
            v(lx + 1.0, ly + 0.5, z),
            v(lx + 1.0, ly, z),
        ],
        panel,
    );
    // The wall lamp, 2 cm in front of the wall y = 0, facing +y.
    let (wx, wz, y) = (3.6, 1.7, 0.02);
    b.quad(
        [
            v(wx, y, wz),
            v(wx, y, wz + 0.3),
            v(wx + 0.3, y, wz + 0.3),
            v(wx + 0.3, y, wz),
        ],
        lamp,
    );
    // Sofa: seat block and backrest against the wall y = 4.
    add_box(&mut b, v(1.5, 3.1, 0.0), v(3.5, 4.0, 0.45), false, sofa);
    add_box(&mut b, v(1.55, 3.75, 0.45), v(3.45, 4.0, 0.9), false, sofa);
    // Bookshelf against the blue wall.
    add_box(&mut b, v(4.6, 0.6, 0.0), v(5.0, 1.8, 2.0), false, shelf);
    // Coffee table: 1.0 × 0.6 top at 0.40–0.44 m on four 4 cm legs.
    let (tx, ty) = (2.0, 1.8);
    add_box(
        &mut b,
        v(tx, ty, 0.40),
        v(tx + 1.0, ty + 0.6, 0.44),
        false,
        wood,
    );
    for (dx, dy) in [(0.0, 0.0), (0.96, 0.0), (0.0, 0.56), (0.96, 0.56)] {
        let lo = v(tx + dx, ty + dy, 0.0);
        add_box(&mut b, lo, lo + v(0.04, 0.04, 0.40), false, wood);
    }
    // The ball, resting on the floor.
    add_ball(&mut b, v(3.9, 1.3, 0.25), 0.25, ball);
    b.build()
}

/// A ball of 320 faces (the icosphere of level 2) at `centre`, fronts facing out.
fn add_ball(b: &mut SceneBuilder, centre: DVec3, radius: f64, material: u32) {
    let (positions, faces) = crate::geometry::icosphere(2);
    let ids: Vec<u32> = positions
        .iter()
        .map(|p| b.vertex(centre + *p * radius))
        .collect();
    for f in faces {
        b.triangle([ids[f[0]], ids[f[1]], ids[f[2]]], material);
    }
}

/// The faces of the axis-aligned rectangle [lo, hi] (one of its extents zero) with its front
/// towards `side`, numbered as [`box_faces`] numbers a box's faces (0 −x, 1 +x, 2 −y, 3 +y,
/// 4 −z, 5 +z).
pub(crate) fn rectangle(b: &mut SceneBuilder, lo: DVec3, hi: DVec3, side: usize, material: u32) {
    b.quad(box_faces(lo, hi)[side], material);
}

/// The shell of a room [0, size], seen from inside, with `floor` below and `walls` elsewhere,
/// except that `feature` = (k, m), if given, makes the wall numbered k in [`box_faces`] order
/// of material m.
fn room_shell(
    b: &mut SceneBuilder,
    size: DVec3,
    floor: u32,
    walls: u32,
    feature: Option<(usize, u32)>,
) {
    for (k, mut q) in box_faces(DVec3::ZERO, size).into_iter().enumerate() {
        q.reverse();
        let m = match (k, feature) {
            (4, _) => floor,
            (k, Some((f, m))) if k == f => m,
            _ => walls,
        };
        b.quad(q, m);
    }
}

/// Two rooms joined by a doorway (metres, z up), written as a scene the point-wise
/// benchmark's rules were not found on (fixed before its first measurement). An 8.2 × 4 ×
/// 2.5 m shell split by a 20 cm partition (x = 4 … 4.2) with a doorway 1 m wide and 2 m high
/// (y = 1.5 … 2.5). Room A (x < 4) has the only light, a 0.8 m ceiling panel (Le = 15) 1 cm
/// under the ceiling, and a red cabinet against the wall x = 0. Room B is lit through the
/// doorway: a patch of direct light on its floor and far wall, the rest indirect; it holds a
/// floor-to-ceiling column and a bench against its far wall. The partition meets the shell's
/// floor, ceiling and walls along contact lines. Every surface one-sided, facing the room.
pub fn two_rooms() -> Result<Scene> {
    let mut b = SceneBuilder::new();
    let white = b.material("plaster", [0.7, 0.7, 0.68], [0.0; 3]);
    let floor = b.material("floor", [0.5, 0.5, 0.45], [0.0; 3]);
    let cabinet = b.material("cabinet", [0.6, 0.2, 0.2], [0.0; 3]);
    let bench = b.material("bench", [0.3, 0.45, 0.6], [0.0; 3]);
    let column = b.material("column", [0.7, 0.7, 0.68], [0.0; 3]);
    let panel = b.material("panel", [0.0; 3], [15.0; 3]);
    let v = DVec3::new;
    let (height, depth) = (2.5, 4.0);
    room_shell(&mut b, v(8.2, depth, height), floor, white, None);
    // The partition: its faces towards room A (−x) and room B (+x), each around the doorway,
    // then the doorway's two jambs and its lintel's underside.
    let (x0, x1, door_lo, door_hi, door_top) = (4.0, 4.2, 1.5, 2.5, 2.0);
    for (x, side) in [(x0, 0), (x1, 1)] {
        rectangle(&mut b, v(x, 0.0, 0.0), v(x, door_lo, height), side, white);
        rectangle(&mut b, v(x, door_hi, 0.0), v(x, depth, height), side, white);
        rectangle(
            &mut b,
            v(x, door_lo, door_top),
            v(x, door_hi, height),
            side,
            white,
        );
    }
    rectangle(
        &mut b,
        v(x0, door_lo, 0.0),
        v(x1, door_lo, door_top),
        3,
        white,
    );
    rectangle(
        &mut b,
        v(x0, door_hi, 0.0),
        v(x1, door_hi, door_top),
        2,
        white,
    );
    rectangle(
        &mut b,
        v(x0, door_lo, door_top),
        v(x1, door_hi, door_top),
        4,
        white,
    );
    // The light, facing down.
    rectangle(
        &mut b,
        v(1.6, 1.6, height - 0.01),
        v(2.4, 2.4, height - 0.01),
        4,
        panel,
    );
    add_box(&mut b, v(0.0, 2.8, 0.0), v(0.6, 3.6, 1.1), false, cabinet);
    add_box(&mut b, v(6.0, 1.0, 0.0), v(6.3, 1.3, height), false, column);
    add_box(&mut b, v(7.0, 0.5, 0.0), v(8.2, 2.0, 0.45), false, bench);
    b.build()
}

/// A study under one small lamp (metres, z up), written with [`two_rooms`] as a scene nothing
/// was tuned to (fixed before its first measurement). A 4 × 3 × 2.7 m room with a green wall
/// (y = 3): a 0.3 m downlight (Le = 40) 1 cm under the ceiling lights a desk against the wall
/// y = 0 (its top touching the wall, on four 4 cm legs that touch its underside), a monitor
/// standing on the desk, a shelf board fixed to the green wall and a ball of radius 0.2 m on
/// the floor (320 faces). Sharp shadows from one bright, small light; the rest indirect.
pub fn study() -> Result<Scene> {
    let mut b = SceneBuilder::new();
    let walls = b.material("walls", [0.72, 0.7, 0.65], [0.0; 3]);
    let green = b.material("green_wall", [0.3, 0.5, 0.35], [0.0; 3]);
    let floor = b.material("floor", [0.5, 0.4, 0.3], [0.0; 3]);
    let desk = b.material("desk", [0.6, 0.45, 0.3], [0.0; 3]);
    let monitor = b.material("monitor", [0.1; 3], [0.0; 3]);
    let shelf = b.material("shelf", [0.5; 3], [0.0; 3]);
    let ball = b.material("ball", [0.7; 3], [0.0; 3]);
    let lamp = b.material("lamp", [0.0; 3], [40.0; 3]);
    let v = DVec3::new;
    let height = 2.7;
    room_shell(&mut b, v(4.0, 3.0, height), floor, walls, Some((3, green)));
    rectangle(
        &mut b,
        v(1.6, 0.9, height - 0.01),
        v(1.9, 1.2, height - 0.01),
        4,
        lamp,
    );
    // The desk: a 1.4 × 0.7 m top at 0.72–0.75 m against the wall, legs inset 3 cm.
    let (dx, top) = (1.2, 0.72);
    add_box(
        &mut b,
        v(dx, 0.0, top),
        v(dx + 1.4, 0.7, top + 0.03),
        false,
        desk,
    );
    for (lx, ly) in [(0.03, 0.03), (1.33, 0.03), (0.03, 0.63), (1.33, 0.63)] {
        let lo = v(dx + lx, ly, 0.0);
        add_box(&mut b, lo, lo + v(0.04, 0.04, top), false, desk);
    }
    add_box(
        &mut b,
        v(1.7, 0.15, top + 0.03),
        v(2.2, 0.3, 1.1),
        false,
        monitor,
    );
    add_box(&mut b, v(0.2, 2.75, 1.5), v(1.0, 3.0, 1.53), false, shelf);
    add_ball(&mut b, v(3.2, 2.0, 0.2), 0.2, ball);
    b.build()
}

/// An attic bedroom under a gabled roof (metres, z up), written with [`kitchen`] as scenes
/// nothing was tuned to (committed before either was first measured). Its
/// geometry is what the other scenes lack: sloped surfaces and furniture turned off the axes.
/// A 5 × 4 m floor, knee walls 1.4 m high at y = 0 and y = 4, roof slopes rising to a ridge at
/// 3 m over y = 2, pentagonal gable walls at x = 0 and x = 5. Lights: a 1 × 0.77 m skylight
/// panel (cool daylight, Le ≈ 10) 1 cm under the south slope, facing into the room, and a
/// warm lamp, an emitting 0.2 m cube, standing on a bedside table. A bed on a 1.5 cm rug, both
/// turned 20° about z; an octagonal chimney from the floor up to the south slope (contact
/// lines on a sloped face); a chest against the gable wall x = 5. Every surface one-sided,
/// facing into the room (the furniture outward).
pub fn attic() -> Result<Scene> {
    let mut b = SceneBuilder::new();
    let plaster = b.material("plaster", [0.78, 0.76, 0.72], [0.0; 3]);
    let boards = b.material("boards", [0.55, 0.42, 0.3], [0.0; 3]);
    let rug = b.material("rug", [0.6, 0.25, 0.2], [0.0; 3]);
    let bed = b.material("bed", [0.8, 0.8, 0.75], [0.0; 3]);
    let wood = b.material("wood", [0.45, 0.3, 0.2], [0.0; 3]);
    let brick = b.material("brick", [0.55, 0.35, 0.3], [0.0; 3]);
    let sky = b.material("skylight", [0.0; 3], [9.0, 10.0, 12.0]);
    let lamp = b.material("lamp", [0.0; 3], [7.0, 5.0, 3.0]);
    let v = DVec3::new;
    let (length, depth, eaves, ridge) = (5.0, 4.0, 1.4, 3.0);
    let inside = v(length / 2.0, depth / 2.0, 1.0);
    // The shell: floor, knee walls, the two slopes and the gables (a rectangle and a
    // triangle each), every face turned towards a point inside.
    let roof_z = |y: f64| eaves + (ridge - eaves) * (1.0 - (y - depth / 2.0).abs() / (depth / 2.0));
    convex(
        &mut b,
        &[
            v(0.0, 0.0, 0.0),
            v(length, 0.0, 0.0),
            v(length, depth, 0.0),
            v(0.0, depth, 0.0),
        ],
        boards,
        inside,
    );
    for y in [0.0, depth] {
        convex(
            &mut b,
            &[
                v(0.0, y, 0.0),
                v(length, y, 0.0),
                v(length, y, eaves),
                v(0.0, y, eaves),
            ],
            plaster,
            inside,
        );
        convex(
            &mut b,
            &[
                v(0.0, y, eaves),
                v(length, y, eaves),
                v(length, depth / 2.0, ridge),
                v(0.0, depth / 2.0, ridge),
            ],
            plaster,
            inside,
        );
    }
    for x in [0.0, length] {
        convex(
            &mut b,
            &[
                v(x, 0.0, 0.0),
                v(x, depth, 0.0),
                v(x, depth, eaves),
                v(x, 0.0, eaves),
            ],
            plaster,
            inside,
        );
        convex(
            &mut b,
            &[
                v(x, 0.0, eaves),
                v(x, depth, eaves),
                v(x, depth / 2.0, ridge),
            ],
            plaster,
            inside,
        );
    }
    // The skylight: 1 m along x, from 35 % to 65 % of the south slope, 1 cm inside it.
    let up_slope = v(0.0, depth / 2.0, ridge - eaves);
    let inward = v(0.0, ridge - eaves, -depth / 2.0).normalize();
    let on_slope = |x: f64, s: f64| v(x, 0.0, eaves) + up_slope * s + inward * 0.01;
    convex(
        &mut b,
        &[
            on_slope(1.5, 0.35),
            on_slope(2.5, 0.35),
            on_slope(2.5, 0.65),
            on_slope(1.5, 0.65),
        ],
        sky,
        inside,
    );
    // The rug, the bed on it and the bedside table with its lamp, turned 20° about z.
    let (along, across) = turned_about_z(20.0);
    let centre = v(2.9, 2.3, 0.0);
    let turned = |b: &mut SceneBuilder, c: DVec3, size: DVec3, m: u32| {
        let corner = c - along * (size.x / 2.0) - across * (size.y / 2.0);
        oriented_box(
            b,
            corner,
            [along * size.x, across * size.y, DVec3::Z * size.z],
            m,
        );
    };
    let rug_top = 0.015;
    turned(&mut b, centre, v(2.6, 2.0, rug_top), rug);
    turned(&mut b, centre + DVec3::Z * rug_top, v(2.0, 1.4, 0.5), bed);
    // The table stands on the floor, 5 cm beyond the rug's edge.
    let table = centre - along * 0.75 + across * 1.25;
    turned(&mut b, table, v(0.4, 0.4, 0.55), wood);
    turned(&mut b, table + DVec3::Z * 0.55, v(0.2, 0.2, 0.2), lamp);
    // The chimney: an octagonal prism of radius 0.25 m from the floor to the south slope.
    let (cx, cy, r) = (0.8, 0.7, 0.25);
    let ring: Vec<DVec3> = (0..8)
        .map(|k| {
            let a = (k as f64 + 0.5) * std::f64::consts::FRAC_PI_4;
            v(cx + r * a.cos(), cy + r * a.sin(), 0.0)
        })
        .collect();
    for k in 0..8 {
        let (p, q) = (ring[k], ring[(k + 1) % 8]);
        let (pt, qt) = (v(p.x, p.y, roof_z(p.y)), v(q.x, q.y, roof_z(q.y)));
        // A point outside this side: its midpoint pushed away from the axis.
        let outside = (p + q) - v(cx, cy, -1.0);
        convex(&mut b, &[p, q, qt, pt], brick, outside);
    }
    // The chest against the gable wall x = 5.
    add_box(&mut b, v(4.5, 1.2, 0.0), v(length, 2.8, 0.9), false, wood);
    b.build()
}

/// A kitchen (metres, z up), written with [`attic`] as a scene nothing was tuned to (committed
/// before its first measurement). A 4.5 × 3.5 × 2.6 m room lit by a window-sized daylight panel
/// (1.2 × 1 m, cool, Le ≈ 5.5) 1 cm in front of the wall x = 0 and by two pendant lamps over an
/// island: each a downward 0.26 m emitter (warm, Le ≈ 21) 5 mm under a 0.3 m metal shade hung
/// from the ceiling by a 1 cm cord. An L-shaped counter along two walls with wall cabinets
/// above it (mounted on the wall, their shadow on the counter top), a fridge in the corner, an
/// island whose top overhangs its base, and two stools on thin legs turned 25° and −15° about
/// z. Every surface one-sided, facing into the room (the furniture outward).
pub fn kitchen() -> Result<Scene> {
    let mut b = SceneBuilder::new();
    let walls = b.material("walls", [0.8, 0.78, 0.72], [0.0; 3]);
    let tiles = b.material("tiles", [0.55, 0.5, 0.45], [0.0; 3]);
    let counter = b.material("counter", [0.3, 0.3, 0.32], [0.0; 3]);
    let cabinets = b.material("cabinets", [0.65, 0.55, 0.4], [0.0; 3]);
    let island = b.material("island", [0.2, 0.35, 0.5], [0.0; 3]);
    let fridge = b.material("fridge", [0.85; 3], [0.0; 3]);
    let metal = b.material("metal", [0.6; 3], [0.0; 3]);
    let stools = b.material("stools", [0.5, 0.3, 0.15], [0.0; 3]);
    let window = b.material("window", [0.0; 3], [5.0, 5.5, 6.5]);
    let bulb = b.material("pendant", [0.0; 3], [25.0, 21.0, 16.0]);
    let v = DVec3::new;
    let height = 2.6;
    room_shell(&mut b, v(4.5, 3.5, height), tiles, walls, None);
    rectangle(&mut b, v(0.01, 1.2, 1.0), v(0.01, 2.4, 2.0), 1, window);
    // Counters (0.9 m) along y = 3.5 and x = 4.5, wall cabinets above the first, the fridge.
    add_box(&mut b, v(0.7, 2.9, 0.0), v(4.5, 3.5, 0.9), false, counter);
    add_box(&mut b, v(3.9, 0.8, 0.0), v(4.5, 2.9, 0.9), false, counter);
    add_box(&mut b, v(1.0, 3.15, 1.5), v(4.5, 3.5, 2.2), false, cabinets);
    add_box(&mut b, v(0.0, 2.85, 0.0), v(0.7, 3.5, 1.9), false, fridge);
    // The island: a base and a top overhanging it by 15 cm.
    add_box(
        &mut b,
        v(1.55, 1.25, 0.0),
        v(2.95, 1.95, 0.9),
        false,
        island,
    );
    add_box(&mut b, v(1.4, 1.1, 0.9), v(3.1, 2.1, 0.94), false, island);
    // The pendants: shade, cord up to the ceiling, emitter 5 mm under the shade.
    for x in [1.9, 2.6] {
        let (y, z) = (1.6, 1.75);
        add_box(
            &mut b,
            v(x - 0.15, y - 0.15, z),
            v(x + 0.15, y + 0.15, z + 0.12),
            false,
            metal,
        );
        add_box(
            &mut b,
            v(x - 0.005, y - 0.005, z + 0.12),
            v(x + 0.005, y + 0.005, height),
            false,
            metal,
        );
        rectangle(
            &mut b,
            v(x - 0.13, y - 0.13, z - 0.005),
            v(x + 0.13, y + 0.13, z - 0.005),
            4,
            bulb,
        );
    }
    // Two stools: a 0.35 m seat at 0.65–0.69 m on four 3 cm legs, turned about z.
    for (x, y, degrees) in [(1.9, 0.7, 25.0), (2.65, 0.65, -15.0f64)] {
        let (along, across) = turned_about_z(degrees);
        let seat = v(x, y, 0.0) - (along + across) * 0.175;
        oriented_box(
            &mut b,
            seat + DVec3::Z * 0.65,
            [along * 0.35, across * 0.35, DVec3::Z * 0.04],
            stools,
        );
        for (i, j) in [(0.01, 0.01), (0.31, 0.01), (0.01, 0.31), (0.31, 0.31)] {
            let leg = seat + along * i + across * j;
            oriented_box(
                &mut b,
                leg,
                [along * 0.03, across * 0.03, DVec3::Z * 0.65],
                stools,
            );
        }
    }
    b.build()
}

/// The x and y axes turned by `degrees` about z (counter-clockwise seen from above).
fn turned_about_z(degrees: f64) -> (DVec3, DVec3) {
    let (sin, cos) = degrees.to_radians().sin_cos();
    (DVec3::new(cos, sin, 0.0), DVec3::new(-sin, cos, 0.0))
}

/// The box `corner` + s·a + t·b + u·c (s, t, u in [0, 1]; `axes` = [a, b, c] right-handed),
/// its faces counter-clockwise seen from outside.
fn oriented_box(b: &mut SceneBuilder, corner: DVec3, axes: [DVec3; 3], material: u32) {
    debug_assert!(
        axes[0].cross(axes[1]).dot(axes[2]) > 0.0,
        "left-handed axes"
    );
    let map = |p: DVec3| corner + axes[0] * p.x + axes[1] * p.y + axes[2] * p.z;
    for q in box_faces(DVec3::ZERO, DVec3::ONE) {
        b.quad(q.map(map), material);
    }
}

/// A planar convex polygon (3 or more corners, in order either way round) as a fan of
/// triangles, wound so that its front faces the point `toward`.
fn convex(b: &mut SceneBuilder, corners: &[DVec3], material: u32, toward: DVec3) {
    let n = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
    let mut ids: Vec<u32> = corners.iter().map(|&p| b.vertex(p)).collect();
    if n.dot(toward - corners[0]) < 0.0 {
        ids.reverse();
    }
    for k in 1..ids.len() - 1 {
        b.triangle([ids[0], ids[k], ids[k + 1]], material);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_faces_point_inward_and_cap_emits() {
        let s = integrating_sphere(2.0, 2, 30.0, 0.5, [1.0; 3]).unwrap();
        assert_eq!(s.triangles.len(), 320);
        let mut emitting = 0;
        for (t, tri) in s.triangles.iter().enumerate() {
            let [a, b, c] = tri.vertices.map(|v| s.positions[v as usize]);
            let n = (b - a).cross(c - a);
            let centroid = (a + b + c) / 3.0;
            assert!(n.dot(centroid) < 0.0, "triangle {t} faces outward");
            emitting += (s.materials[tri.material as usize].emission[0] > 0.0) as usize;
        }
        // The 30° cap covers (1 − cos 30°)/2 ≈ 6.7 % of the sphere: about 21 of 320 faces.
        assert!((15..=30).contains(&emitting), "{emitting}");
    }

    #[test]
    fn two_rooms_and_study_face_into_their_rooms() {
        // Two rooms: 12 shell + 3 × 2 × 2 partition + 3 × 2 doorway + 2 light + 3 × 12 boxes.
        // Study: 12 shell + 2 lamp + 12 desk top + 4 × 12 legs + 12 monitor + 12 shelf + 320
        // ball.
        for (scene, triangles, centre, ball) in [
            (two_rooms().unwrap(), 68, DVec3::new(4.1, 2.0, 1.25), None),
            (
                study().unwrap(),
                418,
                DVec3::new(2.0, 1.5, 1.35),
                Some(DVec3::new(3.2, 2.0, 0.2)),
            ),
        ] {
            assert_eq!(scene.triangles.len(), triangles);
            let mut emitting = 0;
            for (t, tri) in scene.triangles.iter().enumerate() {
                let [a, b, c] = tri.vertices.map(|v| scene.positions[v as usize]);
                let n = (b - a).cross(c - a).normalize();
                let centroid = (a + b + c) / 3.0;
                match scene.materials[tri.material as usize].name.as_str() {
                    "panel" | "lamp" => {
                        emitting += 1;
                        assert!(n.dot(DVec3::NEG_Z) > 0.999, "triangle {t}")
                    }
                    "ball" => {
                        let to = centroid - ball.unwrap();
                        assert!(n.dot(to) > 0.0, "triangle {t} faces inward")
                    }
                    // The shell (the partition's faces are "plaster" too: each faces the
                    // middle of its own room, away from the partition's middle x = 4.1).
                    "plaster" if (centroid.x - 4.0).abs() < 1e-9 => assert!(n.x < -0.999),
                    "plaster" if (centroid.x - 4.2).abs() < 1e-9 => assert!(n.x > 0.999),
                    "plaster" if (4.0..=4.2).contains(&centroid.x) => {}
                    "plaster" | "walls" | "green_wall" | "floor" => {
                        assert!(n.dot(centre - centroid) > 0.0, "triangle {t} faces out")
                    }
                    _ => {}
                }
            }
            assert_eq!(emitting, 2);
        }
    }

    #[test]
    fn living_room_faces_into_the_room() {
        // 12 room + 2 + 2 lights + 2 × 12 sofa + 12 shelf + 12 table + 4 × 12 legs + 320 ball.
        let s = living_room().unwrap();
        assert_eq!(s.triangles.len(), 432);
        let centre = DVec3::new(2.5, 2.0, 1.3);
        let ball = DVec3::new(3.9, 1.3, 0.25);
        for (t, tri) in s.triangles.iter().enumerate() {
            let [a, b, c] = tri.vertices.map(|v| s.positions[v as usize]);
            let n = (b - a).cross(c - a).normalize();
            let centroid = (a + b + c) / 3.0;
            let name = &s.materials[tri.material as usize].name;
            match name.as_str() {
                // The lights face the room's middle: the panel down, the lamp along +y.
                "panel" => assert!(n.dot(DVec3::NEG_Z) > 0.999, "triangle {t}"),
                "lamp" => assert!(n.dot(DVec3::Y) > 0.999, "triangle {t}"),
                "ball" => assert!(n.dot(centroid - ball) > 0.0, "triangle {t} faces inward"),
                "plaster" | "blue_wall" | "floor" => {
                    assert!(n.dot(centre - centroid) > 0.0, "triangle {t} faces out")
                }
                _ => {}
            }
        }
    }

    /// Signed volume enclosed by a material's triangles, by the divergence theorem: positive
    /// for closed surfaces facing out, negative for a shell facing in.
    fn signed_volume(s: &Scene, names: &[&str]) -> f64 {
        s.triangles
            .iter()
            .filter(|t| names.contains(&s.materials[t.material as usize].name.as_str()))
            .map(|t| {
                let [a, b, c] = t.vertices.map(|v| s.positions[v as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn attic_and_kitchen_are_closed_where_they_should_be_and_face_the_right_way() {
        // Each closed piece's signed volume is its volume computed from its dimensions (a
        // face wound the wrong way subtracts twice its share); the shells are negative (seen
        // from inside). Attic: 5 m × (4 × 1.4 + ½ × 4 × 1.6) m² of cross-section.
        let attic = attic().unwrap();
        // Shell 16, skylight 2, rug + bed + table + lamp 4 × 12, chimney 8 × 2, chest 12.
        assert_eq!(attic.triangles.len(), 94);
        for (names, volume) in [
            (
                &["plaster", "boards"][..],
                -5.0 * (4.0 * 1.4 + 0.5 * 4.0 * 1.6),
            ),
            (&["bed"][..], 2.0 * 1.4 * 0.5),
            (&["rug"][..], 2.6 * 2.0 * 0.015),
            (&["wood"][..], 0.4 * 0.4 * 0.55 + 0.5 * 1.6 * 0.9),
            (&["lamp"][..], 0.2f64.powi(3)),
        ] {
            let got = signed_volume(&attic, names);
            assert!((got - volume).abs() < 1e-9, "{names:?}: {got} ≠ {volume}");
        }
        let kitchen = kitchen().unwrap();
        // Shell 12, window 2, counters 24, cabinets 12, fridge 12, island 24, pendants 2 × 26,
        // stools 2 × 5 × 12.
        assert_eq!(kitchen.triangles.len(), 258);
        for (names, volume) in [
            (&["walls", "tiles"][..], -4.5 * 3.5 * 2.6),
            (&["counter"][..], 3.8 * 0.6 * 0.9 + 0.6 * 2.1 * 0.9),
            (&["cabinets"][..], 3.5 * 0.35 * 0.7),
            (&["fridge"][..], 0.7 * 0.65 * 1.9),
            (&["island"][..], 1.4 * 0.7 * 0.9 + 1.7 * 1.0 * 0.04),
            (
                &["metal"][..],
                2.0 * (0.3 * 0.3 * 0.12 + 0.01 * 0.01 * 0.73),
            ),
            (
                &["stools"][..],
                2.0 * (0.35 * 0.35 * 0.04 + 4.0 * 0.03 * 0.03 * 0.65),
            ),
        ] {
            let got = signed_volume(&kitchen, names);
            assert!((got - volume).abs() < 1e-9, "{names:?}: {got} ≠ {volume}");
        }
        // The open pieces and the lights: the chimney's sides face away from its axis, the
        // skylight into the room (down the south slope's inward normal), the window along +x,
        // the pendants down.
        let normal = |s: &Scene, t: &crate::scene::SceneTriangle| {
            let [a, b, c] = t.vertices.map(|v| s.positions[v as usize]);
            ((b - a).cross(c - a).normalize(), (a + b + c) / 3.0)
        };
        let slope_in = DVec3::new(0.0, 1.6, -2.0).normalize();
        let mut lights = 0;
        for t in &attic.triangles {
            let (n, centroid) = normal(&attic, t);
            match attic.materials[t.material as usize].name.as_str() {
                "brick" => assert!(n.dot(centroid - DVec3::new(0.8, 0.7, centroid.z)) > 0.0),
                "skylight" => {
                    lights += 1;
                    assert!(n.dot(slope_in) > 0.999);
                }
                _ => {}
            }
        }
        assert_eq!(lights, 2);
        for t in &kitchen.triangles {
            let (n, _) = normal(&kitchen, t);
            match kitchen.materials[t.material as usize].name.as_str() {
                "window" => assert!(n.x > 0.999),
                "pendant" => assert!(n.z < -0.999),
                _ => {}
            }
        }
    }

    #[test]
    fn the_daylit_office_has_no_emitter_and_its_windows_open_to_the_sky() {
        // Its light is the bake's sky and sun: a ray level from the aisle out through a
        // window (the fifth, x ∈ [12.4, 14.6], sill 0.9 m, transom 2.0 m, mullion at 13.5)
        // leaves the scene, and one into the pier beside it (x ∈ [11.6, 12.4]) does not.
        // The lamp-lit office closes the same window with its sky quad.
        let out = |scene: &Scene, x: f64| {
            let corners: Vec<[DVec3; 3]> = (0..scene.triangles.len())
                .map(|t| {
                    scene.triangles[t]
                        .vertices
                        .map(|v| scene.positions[v as usize])
                })
                .collect();
            let vis = crate::visibility::Visibility::build(&corners);
            let from = DVec3::new(x, 5.0, 1.7);
            vis.closest_hit(from, DVec3::NEG_Y, f64::INFINITY, u32::MAX)
                .is_none()
        };
        let daylit = office_daylit(20_000).unwrap();
        assert!(!daylit.has_emitters());
        assert!(daylit.warnings.is_empty(), "{:?}", daylit.warnings);
        assert!(out(&daylit, 13.0), "through the window");
        assert!(!out(&daylit, 12.0), "into the pier");
        assert!(!out(&office(20_000).unwrap(), 13.0), "the sky quad");
    }

    #[test]
    fn furnace_room_is_closed() {
        // Closed ⇔ every directed edge has its reverse partner (each surface closed, consistently
        // wound).
        let s = furnace_room(0.5, 1.0).unwrap();
        let mut uses = std::collections::HashMap::new();
        for t in &s.triangles {
            for k in 0..3 {
                let (a, b) = (t.vertices[k], t.vertices[(k + 1) % 3]);
                *uses.entry((a, b)).or_insert(0) += 1;
            }
        }
        assert_eq!(s.triangles.len(), 36);
        assert!(uses.keys().all(|&(a, b)| uses.get(&(b, a)) == Some(&1)));
    }
}
