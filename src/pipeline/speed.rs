//! How fast this machine runs the bake's inner loops now, against the machine state the
//! estimate's constants were fitted in ([`super::estimate`]): a fixed workload, timed once per
//! process, whose time over [`REFERENCE_SECONDS`] scales every modelled second of the
//! estimate. The same 2-core benchmark machine has run the same bakes twice as fast on one
//! day as on another (a faster or slower host, neighbours on its cores), and constants fitted
//! on one day read that far off on the other; a yardstick measured where and when the bake
//! runs follows the machine, and the constants are left to describe the scene.
//!
//! The workload is what dominates a large bake's time: closest-hit rays (the final gather's
//! hemispheres, the leaves' regather), any-hit shadow segments (the elements' direct light,
//! the links' visibility) and contour form factors, in a room of 18,144 triangles holding
//! 1,400 boxes (furniture's sizes, so the rays meet what a furnished scene's do). Each round
//! runs it on every worker thread at once, as the bake keeps them all busy; the median of
//! [`ROUNDS`] rounds counts, so a moment's interruption does not read as a slow machine.
//! About a quarter of a second.
//! The machine's speed drifts by about ±15 % from one second to the next, and the factor
//! carries that.

use std::sync::OnceLock;
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::geometry::{box_faces, kernel::point_to_polygon};
use crate::sampling::Rng;
use crate::visibility::{Visibility, NONE};

/// The median round of the workload ([`measure`]) where the estimate's constants hold,
/// seconds: its median on the benchmark machine (both threads busy) divided by how many
/// times the constants' seconds the generated office of 10⁵ triangles and the hall of 10⁴
/// baked in at the same time (2.2×; BENCHMARKS.md "Large scenes: the estimate against the
/// bake").
pub const REFERENCE_SECONDS: f64 = 0.0172;

/// Rounds of the workload; the median is kept.
pub const ROUNDS: usize = 9;

/// Boxes in the workload's room ([`furnished_room`]).
const BOXES: usize = 1400;

/// Rays and segments of a round (each also one contour form factor).
const RAYS: usize = 20_000;

/// The factor is kept within [1 / `CLAMP`, `CLAMP`]: beyond, the workload itself went wrong
/// (a debugger, a machine stopped for seconds), not the machine's speed.
const CLAMP: f64 = 10.0;

/// The environment variable that fixes the factor instead of measuring it: a positive number
/// (1 gives the reference machine's estimate, the same on every machine: reproducible
/// `info` output).
pub const SPEED_VARIABLE: &str = "RADIOSITY_SPEED";

/// This machine's time for the bake's inner loops over the reference's ([`REFERENCE_SECONDS`]),
/// measured on the first call of the process and kept: > 1 on a slower machine. Given by
/// [`SPEED_VARIABLE`] where that is set (one that is not a positive number is warned of and
/// measured instead).
pub fn factor() -> f64 {
    static FACTOR: OnceLock<f64> = OnceLock::new();
    *FACTOR.get_or_init(|| {
        if let Some(text) = std::env::var_os(SPEED_VARIABLE) {
            let text = text.to_string_lossy();
            if let Some(x) = given(&text) {
                return x;
            }
            crate::progress::warning(&format!(
                "{SPEED_VARIABLE}={text}: not a positive number; the machine's speed is \
                 measured instead"
            ));
        }
        (measure() / REFERENCE_SECONDS).clamp(1.0 / CLAMP, CLAMP)
    })
}

/// The factor [`SPEED_VARIABLE`]'s `text` gives: a finite positive number, else `None`.
fn given(text: &str) -> Option<f64> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|x| x.is_finite() && *x > 0.0)
}

/// The median of [`ROUNDS`] rounds of the workload, seconds.
pub fn measure() -> f64 {
    let (triangles, lo, hi) = furnished_room();
    let vis = Visibility::build(&triangles);
    let mut times: Vec<f64> = (0..ROUNDS)
        .map(|round| {
            // Every worker thread runs a round at once, as the bake keeps them all busy (two
            // threads on one core's siblings each run slower than one alone).
            let t = Instant::now();
            let sum: f64 = (0..rayon::current_num_threads())
                .into_par_iter()
                .map(|k| workload(&vis, &triangles, lo, hi, (round * 64 + k) as u64))
                .sum();
            std::hint::black_box(sum);
            t.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[ROUNDS / 2]
}

/// The workload's scene: a 24 × 14 × 3 room (its floor and ceiling as 1 m cells) holding
/// [`BOXES`] boxes of 0.1–1 m at random places below 1.5 m, as desks, shelves and chairs
/// would be (18,144 triangles), and the room's box.
fn furnished_room() -> (Vec<[DVec3; 3]>, DVec3, DVec3) {
    let (lo, hi) = (DVec3::ZERO, DVec3::new(24.0, 14.0, 3.0));
    let mut triangles = Vec::new();
    // A quad as its two triangles, as the scene builder splits one.
    let mut quad = |[a, b, c, d]: [DVec3; 4]| triangles.extend([[a, b, c], [a, c, d]]);
    // The floor and the ceiling, 1 m cells.
    for i in 0..24 {
        for j in 0..14 {
            let (x, y) = (i as f64, j as f64);
            for z in [0.0, 3.0] {
                quad([
                    DVec3::new(x, y, z),
                    DVec3::new(x + 1.0, y, z),
                    DVec3::new(x + 1.0, y + 1.0, z),
                    DVec3::new(x, y + 1.0, z),
                ]);
            }
        }
    }
    let mut rng = Rng::new(&[0xF0_2417]);
    for _ in 0..BOXES {
        let size = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 0.9 + 0.1;
        let at = DVec3::new(
            rng.next_f64() * (hi.x - size.x),
            rng.next_f64() * (hi.y - size.y),
            rng.next_f64() * (1.5 - size.z).max(0.0),
        );
        box_faces(at, at + size).into_iter().for_each(&mut quad);
    }
    (triangles, lo, hi)
}

/// One round: [`RAYS`] closest-hit rays from points of the box (`lo`, `hi`) in uniform
/// directions, as many shadow segments between two such points, and a contour form factor from
/// each point to a triangle; returns a sum of what was found, so nothing is optimised away.
fn workload(vis: &Visibility, triangles: &[[DVec3; 3]], lo: DVec3, hi: DVec3, round: u64) -> f64 {
    let mut rng = Rng::new(&[0x5BEED, round]);
    let point =
        |rng: &mut Rng| lo + (hi - lo) * DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
    let mut sum = 0.0;
    for _ in 0..RAYS {
        let x = point(&mut rng);
        let z = 2.0 * rng.next_f64() - 1.0;
        let phi = std::f64::consts::TAU * rng.next_f64();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let dir = DVec3::new(r * phi.cos(), r * phi.sin(), z);
        if let Some(hit) = vis.closest_hit(x, dir, f64::INFINITY, NONE) {
            sum += hit.t;
        }
        let y = point(&mut rng);
        sum += f64::from(u8::from(vis.occluded(x, y, [NONE, NONE])));
        let t = &triangles[rng.below(triangles.len())];
        sum += point_to_polygon(x, dir, t);
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The factor is measured once a process and kept (two estimates in one process agree),
    /// and lies within its clamp; the workload's room is as documented; the environment's
    /// factor is taken only where it is a positive number.
    #[test]
    fn the_factor_is_measured_once_and_kept() {
        let a = factor();
        assert!((1.0 / CLAMP..=CLAMP).contains(&a), "{a}");
        assert_eq!(a, factor());
        let m = measure();
        assert!(m > 0.0);
        let (triangles, lo, hi) = furnished_room();
        // The environment's factor: a positive number, nothing else.
        assert_eq!(given(" 1.5 "), Some(1.5));
        for bad in ["0", "-2", "inf", "NaN", "fast", ""] {
            assert_eq!(given(bad), None, "{bad}");
        }
        assert_eq!(triangles.len(), 24 * 14 * 4 + 12 * BOXES);
        assert!(triangles
            .iter()
            .flatten()
            .all(|v| v.cmpge(lo).all() && v.cmple(hi).all()));
    }
}
