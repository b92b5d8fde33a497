//! Does each emitter light anything? A light wound the wrong way (a sky quad over an atrium
//! facing up, away from the scene) emits into the void, and the bake is black with exit 0.
//! This module casts a few probe rays from each emitting material's front sides and names the
//! materials none of whose rays reaches the front of any surface; the pipeline turns them into
//! warnings. It owns only that test; it changes nothing.

use super::Scene;
use crate::geometry::orthonormal_basis;
use crate::sampling::{malley, point_in_triangle, ByArea, Rng};

/// Probe rays per emitting material: cosine-weighted from points spread over its triangles
/// by area. An emitter that lights some surface with a share s of its light has all of them
/// miss with probability (1 − s)^64: 0.2 % at s = 10 %. A light whose share is smaller than
/// that may be named wrongly; the warning says what the probes saw.
pub const PROBES: usize = 64;

/// The names of the emitting materials (with their probe counts) none of whose [`PROBES`] rays
/// meets the front of a surface: each ray leaves the scene or meets a back. Deterministic for
/// a `seed`. `scene` must satisfy the [`Scene`] invariants.
pub fn unlit_emitters(scene: &Scene, seed: u64) -> Vec<String> {
    let emitting: Vec<usize> = (0..scene.materials.len())
        .filter(|&m| scene.materials[m].is_emitter())
        .collect();
    if emitting.is_empty() {
        return Vec::new();
    }
    let corners = scene.triangle_corners();
    // Panes pass the probes by their share, as they pass the bake's rays.
    let vis = scene.visibility();
    let mut unlit = Vec::new();
    for m in emitting {
        let tris: Vec<usize> = (0..scene.triangles.len())
            .filter(|&t| scene.triangles[t].material as usize == m)
            .collect();
        let total: f64 = tris.iter().map(|&t| scene.triangle_area(t)).sum();
        if tris.is_empty() || total <= 0.0 {
            continue;
        }
        let mut rng = Rng::new(&[seed, m as u64, 0x11D7]);
        let areas: Vec<f64> = tris.iter().map(|&t| scene.triangle_area(t)).collect();
        let mut strata = ByArea::new(&areas, PROBES);
        let lights_something = (0..PROBES).any(|p| {
            // Stratified by area: the probe's target share of the total area picks its triangle.
            let t = tris[strata.pick(p, &mut rng)];
            let [a, b, c] = corners[t];
            let n = (b - a).cross(c - a).normalize();
            let origin = point_in_triangle(corners[t], &mut rng);
            let (tangent, bitangent) = orthonormal_basis(n);
            let dir = malley(rng.next_f64(), rng.next_f64(), tangent, bitangent, n);
            vis.closest_hit(origin, dir, f64::INFINITY, t as u32)
                .is_some_and(|hit| {
                    let [p, q, r] = corners[hit.triangle as usize];
                    (q - p).cross(r - p).dot(dir) < 0.0
                })
        });
        if !lights_something {
            unlit.push(scene.materials[m].name.clone());
        }
    }
    unlit
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::SceneBuilder;
    use glam::DVec3;

    /// A floor (0..1 at z = 0, facing up) and a lamp above it at z = 1, facing down (toward
    /// the floor) or up (away from everything).
    fn floor_and_lamp(lamp_faces_down: bool) -> Scene {
        let mut b = SceneBuilder::new();
        let grey = b.material("grey", [0.5; 3], [0.0; 3]);
        let lamp = b.material("lamp", [0.5; 3], [3.0; 3]);
        let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        b.quad(
            [p(0., 0., 0.), p(1., 0., 0.), p(1., 1., 0.), p(0., 1., 0.)],
            grey,
        );
        let up = [
            p(0.3, 0.3, 1.),
            p(0.7, 0.3, 1.),
            p(0.7, 0.7, 1.),
            p(0.3, 0.7, 1.),
        ];
        let down = [up[0], up[3], up[2], up[1]];
        b.quad(if lamp_faces_down { down } else { up }, lamp);
        b.build().unwrap()
    }

    #[test]
    fn a_lamp_facing_away_lights_nothing_and_is_named() {
        assert!(unlit_emitters(&floor_and_lamp(true), 1).is_empty());
        assert_eq!(unlit_emitters(&floor_and_lamp(false), 1), ["lamp"]);
        // Two-sided, its back faces the floor: lit.
        let mut both = floor_and_lamp(false);
        both.make_two_sided();
        assert!(unlit_emitters(&both, 1).is_empty());
    }

    #[test]
    fn a_lamp_behind_a_pane_lights_what_the_pane_lets_it() {
        // A large pane between the lamp (facing down) and the floor, its back to the lamp:
        // opaque, the lamp sees only its back; with t = 0.5 half the probes pass to the floor.
        let with_pane = |t: f64| {
            let mut s = floor_and_lamp(true);
            let m = s.materials.len() as u32;
            s.materials.push(
                crate::scene::Material::opaque("pane", [0.5; 3], [0.0; 3]).with_transmittance(t),
            );
            let base = s.positions.len() as u32;
            for (x, y) in [(-1.0, -1.0), (2.0, -1.0), (2.0, 2.0), (-1.0, 2.0)] {
                s.positions.push(DVec3::new(x, y, 0.5));
            }
            // Facing down (toward the floor): clockwise seen from above.
            for v in [[0, 2, 1], [0, 3, 2]] {
                s.triangles.push(crate::scene::SceneTriangle {
                    vertices: v.map(|k| base + k),
                    material: m,
                    uv: crate::scene::NO_UV,
                });
            }
            s
        };
        assert_eq!(unlit_emitters(&with_pane(0.0), 3), ["lamp"]);
        assert!(unlit_emitters(&with_pane(0.5), 3).is_empty());
    }

    #[test]
    fn a_lamp_that_sees_only_backs_lights_nothing() {
        // The floor flipped (facing down): the lamp facing down meets only its back.
        let mut s = floor_and_lamp(true);
        for t in s.triangles.iter_mut().filter(|t| t.material == 0) {
            t.vertices.swap(1, 2);
        }
        assert_eq!(unlit_emitters(&s, 7), ["lamp"]);
    }
}
