//! The generated open-plan office ([`office`]): the point-wise benchmark's furnished scene at
//! scale, and its furniture (desk pods, chairs on pedestals, bookcases, potted plants).

use glam::DVec3;

use super::{add_box, box_faces, convex, oriented_box, rectangle, turned_about_z};
use crate::sampling::Rng;
use crate::scene::{Scene, SceneBuilder};
use crate::Result;

/// An open-plan office for the point-wise benchmark at scale (metres, z up), written as a
/// scene nothing was tuned to (committed before its first measurement). A 24 × 14 × 3 m room:
/// grey-blue carpet (ρ ≈ 0.25), walls 0.7, ceiling 0.8. Its long wall y = 0 has eight window
/// openings (2.2 × 1.6 m, sill 0.9 m, 20 cm reveals), each closed at the reveals' outer edge
/// by the sky, an emitting quad facing into the room (Le ≈ 3.5–4.6, slightly blue: the
/// path tracer has no environment light), behind a mullion and two transom halves (thin
/// boxes). Twelve 1.2 × 0.6 m ceiling panels (Le ≈ 10) 1 cm under the ceiling, facing down.
/// Eight pods of four desks (1.58 × 0.79 m tops at 0.72–0.75 m, wood ρ ≈ 0.5, on two panel
/// legs each), facing pairs split by a fabric screen from the floor to 1.15 m, a monitor on
/// every desk (base, neck and screen); 32 office chairs (dark, ρ ≈ 0.12: a 16-sided base on
/// the floor, a central column, seat and back) turned 10–60° off their desk's axis; three
/// round columns from floor to ceiling; five low bookcases (boards) against the wall
/// y = 14 and a cabinet against each end wall; six potted plants (a pot, a trunk and a crown of
/// 1280 small triangles whose radii are jittered, resting by its lowest point on the trunk).
/// Every surface one-sided, facing into the room (the furniture outward); nothing floats but
/// the lamps, and nothing intersects.
///
/// The shell's walls, floor and ceiling and the desks' upper faces are cut into grids of
/// equal, nearly square cells, the coarsest (cells at most 1 m) that brings the whole to at
/// least `triangles` triangles; the rest of the room is 15,352 triangles (7,680 of them the
/// crowns). So the scene has at least max(`triangles`, 17,268) triangles, a little more where
/// the cells round up: 50,016 for 50,000, 100,540 for 100,000, 1,000,308 for 10⁶.
/// Deterministic (the variations come from fixed [`Rng`] keys), so a size names a scene.
pub fn office(triangles: usize) -> Result<Scene> {
    office_in(triangles, false)
}

/// [`office`] by daylight: the same room, furniture and cells, but its eight window openings
/// open (no sky quads: the light comes from the bake's `--sky` and `--sun`, the wall y = 0
/// facing south with z up, so a sun of azimuth 135–225° shines in) and its ceiling panels
/// dark (ρ = Le = 0). Baked with, for example, `--up z --sky 4 --sun 200,35,100`, and traced
/// with the same lights by the point-wise tools (`probes … --sky 4 --sun 200,35,100 --up z`).
pub fn office_daylit(triangles: usize) -> Result<Scene> {
    office_in(triangles, true)
}

/// [`office`], or [`office_daylit`] if `daylight`.
fn office_in(triangles: usize, daylight: bool) -> Result<Scene> {
    let mut b = SceneBuilder::new();
    let carpet = b.material("carpet", [0.22, 0.25, 0.3], [0.0; 3]);
    let walls = b.material("walls", [0.7, 0.7, 0.68], [0.0; 3]);
    let ceiling = b.material("ceiling", [0.8; 3], [0.0; 3]);
    let frame = b.material("frame", [0.6; 3], [0.0; 3]);
    let desk = b.material("desk", [0.55, 0.45, 0.33], [0.0; 3]);
    let screen = b.material("screen", [0.35, 0.4, 0.45], [0.0; 3]);
    let monitor = b.material("monitor", [0.06; 3], [0.0; 3]);
    let chair = b.material("chair", [0.12, 0.12, 0.14], [0.0; 3]);
    let shelf = b.material("shelf", [0.6, 0.55, 0.5], [0.0; 3]);
    let cabinet = b.material("cabinet", [0.5, 0.52, 0.55], [0.0; 3]);
    let column = b.material("column", [0.7, 0.7, 0.68], [0.0; 3]);
    let plant = [
        b.material("pot", [0.5, 0.3, 0.2], [0.0; 3]),
        b.material("soil", [0.15, 0.1, 0.07], [0.0; 3]),
        b.material("bark", [0.3, 0.22, 0.15], [0.0; 3]),
        b.material("leaves", [0.1, 0.35, 0.12], [0.0; 3]),
    ];
    let (lamp, sky) = if daylight {
        (b.material("lamp", [0.0; 3], [0.0; 3]), None)
    } else {
        (
            b.material("lamp", [0.0; 3], [10.0, 9.8, 9.3]),
            Some(b.material("sky", [0.0; 3], [3.5, 3.9, 4.6])),
        )
    };
    let v = DVec3::new;
    let (length, depth, height) = (24.0, 14.0, 3.0);

    // The shell, to be cut into cells once the step is known; the window wall y = 0 is
    // pieced around its openings by `office_windows`.
    let mut grids = vec![
        GridRect::new(v(0.0, 0.0, 0.0), v(length, depth, 0.0), 5, carpet),
        GridRect::new(v(0.0, 0.0, height), v(length, depth, height), 4, ceiling),
        GridRect::new(v(0.0, 0.0, 0.0), v(0.0, depth, height), 1, walls),
        GridRect::new(v(length, 0.0, 0.0), v(length, depth, height), 0, walls),
        GridRect::new(v(0.0, depth, 0.0), v(length, depth, height), 2, walls),
    ];
    office_windows(
        &mut b,
        &mut grids,
        v(length, 0.0, height),
        (walls, sky, frame),
    );

    // Ceiling panels over the two rows of pods and the aisle between them; round columns in
    // the aisle, floor to ceiling.
    for x in [3.4, 9.0, 14.6, 20.2] {
        for y in [3.4, 6.4, 9.4] {
            let (lo, hi) = (v(x - 0.6, y - 0.3, height), v(x + 0.6, y + 0.3, height));
            rectangle(&mut b, lo - DVec3::Z * 0.01, hi - DVec3::Z * 0.01, 4, lamp);
        }
    }
    for x in [6.2, 12.0, 17.8] {
        let base = v(x, 6.4, 0.0);
        prism(&mut b, base, (0.25, 0.25), height, 24, 0.0, [column; 2]);
    }

    // Eight pods of four desks, each with its monitor and chair.
    let mut seat = 0;
    for py in [2.6, 8.6] {
        for px in [1.8, 7.4, 13.0, 18.6] {
            let materials = [desk, screen, monitor, chair];
            desk_pod(&mut b, &mut grids, v(px, py, 0.0), seat, materials);
            seat += 4;
        }
    }

    // Bookcases against the wall y = 14, a cabinet against each end wall, and plants in the
    // corners and beside two of the columns.
    for x in [2.4, 6.6, 10.8, 15.0, 19.2] {
        bookcase(
            &mut b,
            v(x, depth - 0.4, 0.0),
            v(x + 1.8, depth, 1.1),
            shelf,
        );
    }
    add_box(&mut b, v(0.0, 5.6, 0.0), v(0.5, 7.2, 0.75), false, cabinet);
    let end = v(length - 0.5, 5.6, 0.0);
    add_box(&mut b, end, v(length, 7.2, 0.75), false, cabinet);
    let crown = crate::geometry::icosphere(3);
    let spots = [
        (0.8, 0.9),
        (23.2, 0.9),
        (0.8, 13.2),
        (23.2, 13.2),
        (7.3, 6.4),
        (16.7, 6.4),
    ];
    for (k, (x, y)) in spots.into_iter().enumerate() {
        potted_plant(&mut b, v(x, y, 0.0), k as u64, &crown, plant);
    }

    // The grids, fine enough for `triangles` in all.
    let step = grid_step(&grids, triangles.saturating_sub(b.triangle_count()));
    for r in grids {
        grid(&mut b, r, step);
    }
    b.build()
}

/// The window wall y = 0 of [`office`]'s room [0, `size`]: eight openings 2.2 × 1.6 m (sill
/// 0.9 m), 3 m apart, their reveals (jambs, sill and head, 20 cm deep) and, closing each at
/// the reveals' outer edge, the sky facing into the room behind a mullion and two transom
/// halves (boxes 8 cm deep, 6 cm in front of the sky). The wall's pieces around the openings
/// (under the sills, over the heads, the piers) go to `grids`. `materials`: walls and frame,
/// and the sky's (`None`: the openings are left open).
fn office_windows(
    b: &mut SceneBuilder,
    grids: &mut Vec<GridRect>,
    size: DVec3,
    (walls, sky, frame): (u32, Option<u32>, u32),
) {
    let v = DVec3::new;
    let (sill, head, reveal) = (0.9, 2.5, 0.2);
    grids.push(GridRect::new(
        v(0.0, 0.0, 0.0),
        v(size.x, 0.0, sill),
        3,
        walls,
    ));
    grids.push(GridRect::new(
        v(0.0, 0.0, head),
        v(size.x, 0.0, size.z),
        3,
        walls,
    ));
    let mut pier = 0.0;
    for k in 0..8 {
        let (x0, x1) = (0.4 + 3.0 * k as f64, 2.6 + 3.0 * k as f64);
        grids.push(GridRect::new(
            v(pier, 0.0, sill),
            v(x0, 0.0, head),
            3,
            walls,
        ));
        pier = x1;
        rectangle(b, v(x0, -reveal, sill), v(x0, 0.0, head), 1, walls);
        rectangle(b, v(x1, -reveal, sill), v(x1, 0.0, head), 0, walls);
        rectangle(b, v(x0, -reveal, sill), v(x1, 0.0, sill), 5, walls);
        rectangle(b, v(x0, -reveal, head), v(x1, 0.0, head), 4, walls);
        if let Some(sky) = sky {
            rectangle(b, v(x0, -reveal, sill), v(x1, -reveal, head), 3, sky);
        }
        let (c, y0, y1) = ((x0 + x1) / 2.0, -0.14, -0.06);
        add_box(
            b,
            v(c - 0.025, y0, sill),
            v(c + 0.025, y1, head),
            false,
            frame,
        );
        add_box(b, v(x0, y0, 2.0), v(c - 0.025, y1, 2.05), false, frame);
        add_box(b, v(c + 0.025, y0, 2.0), v(x1, y1, 2.05), false, frame);
    }
    grids.push(GridRect::new(
        v(pier, 0.0, sill),
        v(size.x, 0.0, head),
        3,
        walls,
    ));
}

/// One pod of [`office`]: 2 × 2 desks from `corner` (3.2 × 1.6 m), the facing pairs 2 cm
/// apart with a screen between them from the floor to 1.15 m. Each desk: a 1.58 × 0.79 m top
/// at 0.72–0.75 m (its upper face to `grids`) on two panel legs, a monitor at the screen's
/// side facing the chair, and the chair 55 cm out from the desk's front edge, shifted up to
/// 10 cm sideways and turned 10–60° either way, from the key (`first_seat` + desk).
/// `materials`: [desk, screen, monitor, chair].
fn desk_pod(
    b: &mut SceneBuilder,
    grids: &mut Vec<GridRect>,
    corner: DVec3,
    first_seat: u64,
    materials: [u32; 4],
) {
    let [desk, screen, monitor, chair] = materials;
    let v = DVec3::new;
    let (px, py) = (corner.x, corner.y);
    let screen_lo = v(px + 0.05, py + 0.79, 0.0);
    add_box(b, screen_lo, v(px + 3.15, py + 0.81, 1.15), false, screen);
    for (k, (i, j)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
        // The top (its upper face a grid) and the legs.
        let x0 = px + 1.6 * i as f64 + 0.01;
        let y0 = py + 0.81 * j as f64;
        let (lo, hi) = (v(x0, y0, 0.72), v(x0 + 1.58, y0 + 0.79, 0.75));
        for q in box_faces(lo, hi).into_iter().take(5) {
            b.quad(q, desk);
        }
        grids.push(GridRect::new(v(lo.x, lo.y, hi.z), hi, 5, desk));
        for x in [x0 + 0.03, x0 + 1.525] {
            add_box(
                b,
                v(x, y0 + 0.05, 0.0),
                v(x + 0.025, y0 + 0.74, 0.72),
                false,
                desk,
            );
        }
        // The monitor faces −y on the first desk of a pair, +y on the second.
        let cx = x0 + 0.79;
        let (toward, stand) = if j == 0 {
            (-1.0, y0 + 0.57)
        } else {
            (1.0, y0 + 0.22)
        };
        desk_monitor(b, v(cx, stand, hi.z), toward, monitor);
        // The chair.
        let mut rng = Rng::new(&[0x0FF1CE, first_seat + k as u64]);
        let turn = 10.0 + 50.0 * rng.next_f64();
        let turn = if rng.next_f64() < 0.5 { -turn } else { turn };
        let shift = 0.2 * rng.next_f64() - 0.1;
        let (y, facing) = if j == 0 {
            (y0 - 0.55, 0.0)
        } else {
            (y0 + 0.79 + 0.55, 180.0)
        };
        office_chair(b, v(cx + shift, y, 0.0), facing + turn, chair);
    }
}

/// A monitor standing on a desk at `foot`, its screen facing `toward` (±1) along y: a
/// 0.24 × 0.18 × 0.012 m base, a 5 × 3 cm neck up to 0.2 m, and a 0.56 × 0.33 m screen 2.5 cm
/// thick from 0.12 m up, fixed to the neck's face. 36 triangles.
fn desk_monitor(b: &mut SceneBuilder, foot: DVec3, toward: f64, material: u32) {
    let v = DVec3::new;
    let (x, y, z) = (foot.x, foot.y, foot.z);
    add_box(
        b,
        v(x - 0.12, y - 0.09, z),
        v(x + 0.12, y + 0.09, z + 0.012),
        false,
        material,
    );
    let (n0, n1) = ordered(y, y - 0.03 * toward);
    add_box(
        b,
        v(x - 0.025, n0, z + 0.012),
        v(x + 0.025, n1, z + 0.2),
        false,
        material,
    );
    let (s0, s1) = ordered(y, y + 0.025 * toward);
    add_box(
        b,
        v(x - 0.28, s0, z + 0.12),
        v(x + 0.28, s1, z + 0.45),
        false,
        material,
    );
}

/// The two numbers in increasing order.
fn ordered(a: f64, b: f64) -> (f64, f64) {
    (a.min(b), a.max(b))
}

/// An axis-aligned rectangle [lo, hi] (one extent zero) with its front towards `side`
/// (numbered as [`box_faces`] numbers a box's faces), to be cut into cells by [`grid`].
#[derive(Debug, Clone, Copy)]
struct GridRect {
    lo: DVec3,
    hi: DVec3,
    side: usize,
    material: u32,
}

impl GridRect {
    fn new(lo: DVec3, hi: DVec3, side: usize, material: u32) -> Self {
        GridRect {
            lo,
            hi,
            side,
            material,
        }
    }

    /// Its in-plane axes (u, v): after the normal's axis a = side / 2 come u = a + 1 and
    /// v = a + 2 (mod 3), so that u × v points along +a.
    fn axes(&self) -> (usize, usize) {
        let a = self.side / 2;
        ((a + 1) % 3, (a + 2) % 3)
    }

    /// Its cells at `step` along u and along v: ⌈extent / step⌉, at least 1.
    fn cells(&self, step: f64) -> (usize, usize) {
        let (u, v) = self.axes();
        let cells = |k: usize| (((self.hi[k] - self.lo[k]) / step).ceil() as usize).max(1);
        (cells(u), cells(v))
    }

    fn area(&self) -> f64 {
        let d = self.hi - self.lo;
        d.x * d.y + d.y * d.z + d.z * d.x
    }
}

/// The coarsest step, at most 1 (to 2⁻⁶⁰ of the range searched), at which the rectangles'
/// grids have at least `wanted` triangles in all.
fn grid_step(rects: &[GridRect], wanted: usize) -> f64 {
    let count = |step: f64| -> usize {
        rects
            .iter()
            .map(|r| {
                let (nu, nv) = r.cells(step);
                2 * nu * nv
            })
            .sum()
    };
    let mut coarse = 1.0;
    if count(coarse) >= wanted {
        return coarse;
    }
    // A rectangle of area A has at least A / step² cells, so this step is fine enough.
    let area: f64 = rects.iter().map(GridRect::area).sum();
    let mut fine = (2.0 * area / wanted as f64).sqrt();
    for _ in 0..60 {
        let mid = 0.5 * (fine + coarse);
        if count(mid) >= wanted {
            fine = mid;
        } else {
            coarse = mid;
        }
    }
    fine
}

/// The rectangle `r` cut into its [`GridRect::cells`] at `step`: equal cells, two triangles
/// each, sharing the lattice's vertices. A lattice coordinate is computed from its index
/// alone and the last one is `hi` exactly, so two rectangles with the same span and cell
/// count along a border share its vertices bitwise (welded by the builder).
fn grid(b: &mut SceneBuilder, r: GridRect, step: f64) {
    let (u, v) = r.axes();
    let (nu, nv) = r.cells(step);
    let at = |k: usize, i: usize, n: usize| {
        if i == n {
            r.hi[k]
        } else {
            r.lo[k] + (r.hi[k] - r.lo[k]) * i as f64 / n as f64
        }
    };
    let mut ids = Vec::with_capacity((nu + 1) * (nv + 1));
    for j in 0..=nv {
        for i in 0..=nu {
            let mut p = r.lo;
            p[u] = at(u, i, nu);
            p[v] = at(v, j, nv);
            ids.push(b.vertex(p));
        }
    }
    let id = |i: usize, j: usize| ids[j * (nu + 1) + i];
    // (i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1) turn counter-clockwise about +a.
    let towards_plus = r.side % 2 == 1;
    for j in 0..nv {
        for i in 0..nu {
            let [p, q, s, t] = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
            if towards_plus {
                b.triangle([p, q, s], r.material);
                b.triangle([p, s, t], r.material);
            } else {
                b.triangle([p, s, q], r.material);
                b.triangle([p, t, s], r.material);
            }
        }
    }
}

/// A closed prism (a frustum when the radii differ) standing on `base`: regular `sides`-gons
/// of radius `radii.0` at the bottom and `radii.1` at `height` above it, the first corner at
/// `phase` radians about z; fronts outward, the sides and the bottom of `materials[0]`, the
/// top of `materials[1]`.
fn prism(
    b: &mut SceneBuilder,
    base: DVec3,
    radii: (f64, f64),
    height: f64,
    sides: usize,
    phase: f64,
    materials: [u32; 2],
) {
    let ring = |r: f64, z: f64| -> Vec<DVec3> {
        (0..sides)
            .map(|k| {
                let a = phase + std::f64::consts::TAU * k as f64 / sides as f64;
                base + DVec3::new(r * a.cos(), r * a.sin(), z)
            })
            .collect()
    };
    let (bottom, top) = (ring(radii.0, 0.0), ring(radii.1, height));
    for k in 0..sides {
        let l = (k + 1) % sides;
        b.quad([bottom[k], bottom[l], top[l], top[k]], materials[0]);
    }
    convex(b, &bottom, materials[0], base - DVec3::Z);
    convex(b, &top, materials[1], base + DVec3::Z * (height + 1.0));
}

/// An office chair standing on the floor at `at`, facing `degrees` about z from +y: a
/// 16-sided base 0.3 m in radius and 4 cm high, a central column (radius 3.5 cm) up to the
/// seat, a 0.48 × 0.46 × 0.07 m seat at 0.42 m and a 0.44 × 0.05 × 0.52 m back standing on
/// the seat's rear, 1 cm in from its edge. 120 triangles.
fn office_chair(b: &mut SceneBuilder, at: DVec3, degrees: f64, material: u32) {
    let (along, across) = turned_about_z(degrees);
    let phase = degrees.to_radians();
    let z = DVec3::Z;
    prism(b, at, (0.3, 0.3), 0.04, 16, phase, [material; 2]);
    prism(
        b,
        at + z * 0.04,
        (0.035, 0.035),
        0.38,
        10,
        phase,
        [material; 2],
    );
    let seat = at + z * 0.42 - along * 0.24 - across * 0.23;
    oriented_box(b, seat, [along * 0.48, across * 0.46, z * 0.07], material);
    let back = at + z * 0.49 - along * 0.22 - across * 0.22;
    oriented_box(b, back, [along * 0.44, across * 0.05, z * 0.52], material);
}

/// An open bookcase filling [lo, hi] against a wall at y = hi.y, open towards −y, of boxes 2 cm
/// thick: a back board, two sides, a plinth 8 cm high and three boards (at 0.38 m, 0.73 m
/// and the top) between the sides. 84 triangles.
fn bookcase(b: &mut SceneBuilder, lo: DVec3, hi: DVec3, material: u32) {
    let t = 0.02;
    let v = DVec3::new;
    add_box(b, v(lo.x, hi.y - t, lo.z), hi, false, material);
    for x in [lo.x, hi.x - t] {
        add_box(
            b,
            v(x, lo.y, lo.z),
            v(x + t, hi.y - t, hi.z),
            false,
            material,
        );
    }
    for (z0, z1) in [
        (lo.z, lo.z + 0.08),
        (lo.z + 0.38, lo.z + 0.4),
        (lo.z + 0.73, lo.z + 0.75),
        (hi.z - t, hi.z),
    ] {
        add_box(
            b,
            v(lo.x + t, lo.y, z0),
            v(hi.x - t, hi.y - t, z1),
            false,
            material,
        );
    }
}

/// A potted plant standing on the floor at `at`: a 12-sided pot (radius 0.16 m at the floor,
/// 0.21 m at its rim 0.42 m up) filled to the rim with soil, a trunk 0.3 m tall, and a
/// crown: the unit sphere `crown` (vertices, faces facing out) with each vertex's radius
/// jittered to 0.7–1.15 × 0.36 m and stretched 1.25 times upward, resting by its lowest
/// vertex on the middle of the trunk's top. A sphere's vertices moved along their own
/// directions keep it a closed surface facing out that does not cross itself, however
/// rough. `seed` varies the jitter and the pot's turn; `materials` are [pot, soil, bark,
/// leaves]. 64 triangles and the crown's.
fn potted_plant(
    b: &mut SceneBuilder,
    at: DVec3,
    seed: u64,
    crown: &(Vec<DVec3>, Vec<[usize; 3]>),
    materials: [u32; 4],
) {
    let [pot, soil, bark, leaves] = materials;
    let mut rng = Rng::new(&[0x91A47, seed]);
    let phase = rng.next_f64();
    prism(b, at, (0.16, 0.21), 0.42, 12, phase, [pot, soil]);
    let trunk = at + DVec3::Z * 0.42;
    prism(b, trunk, (0.025, 0.02), 0.3, 6, phase, [bark; 2]);
    let top = trunk + DVec3::new(0.0, 0.0, 0.3);
    let (units, faces) = crown;
    let jittered: Vec<DVec3> = units
        .iter()
        .map(|u| {
            let r = 0.36 * (0.7 + 0.45 * rng.next_f64());
            DVec3::new(u.x * r, u.y * r, u.z * r * 1.25)
        })
        .collect();
    let lowest = jittered
        .iter()
        .copied()
        .min_by(|p, q| p.z.total_cmp(&q.z))
        .unwrap_or(DVec3::ZERO);
    let ids: Vec<u32> = jittered
        .iter()
        .map(|&p| b.vertex(top + (p - lowest)))
        .collect();
    for f in faces {
        b.triangle([ids[f[0]], ids[f[1]], ids[f[2]]], leaves);
    }
}
