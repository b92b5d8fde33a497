//! Adaptive refinement: which patches to split after a solve. Constant radiance per patch is
//! a first-order approximation; where the solved radiance changes fast (shadow and penumbra
//! edges, the dark strip along a contact line, the neighbourhood of a light) neighbouring
//! patches differ most, and that is where a finer mesh pays. This module owns the rule that
//! marks patches; [`crate::mesh::refine()`] splits them and the pipeline solves again
//! (Cohen & Wallace, *Radiosity and Realistic Image Synthesis*, ch. 8, "adaptive subdivision"
//! driven by radiosity differences between neighbouring elements).
//!
//! The rule: two patches that share an edge and lie on the same smooth surface (same
//! material, normals within the crease angle: a jump across a material border or a crease is
//! real, not a discretisation error) are both marked when their luminances differ by more
//! than `threshold` relative to the larger one. Relative, so that dim surfaces (a block's side
//! in shadow) are refined as readily as bright ones: the accuracy asked is relative per
//! surface.

use std::collections::HashMap;

use crate::color::Rgb;
use crate::mesh::Patches;
use crate::scene::Scene;
use crate::Result;

/// Default relative luminance jump between neighbours that marks both for splitting.
pub const DEFAULT_THRESHOLD: f64 = 0.3;

/// Luminance (Rec. 709 weights) of a radiance triple, W·sr⁻¹·m⁻².
fn luminance(l: &Rgb) -> f64 {
    0.2126 * l[0] + 0.7152 * l[1] + 0.0722 * l[2]
}

/// Patches to split (see the module documentation). `radiance[i]` is patch i's solved
/// radiance; `crease_degrees` as for the bake.
pub fn marks(
    patches: &Patches,
    radiance: &[Rgb],
    threshold: f64,
    crease_degrees: f64,
) -> Vec<bool> {
    jumps(patches, radiance, crease_degrees)
        .into_iter()
        .map(|j| j > threshold)
        .collect()
}

/// For each patch, the largest relative luminance jump to a neighbour on the same surface
/// (|Lᵢ − Lⱼ| / max(Lᵢ, Lⱼ), in [0, 1]; 0 without such a neighbour): [`marks`] marks the
/// patches whose jump exceeds the threshold, and [`within_budget`] splits the largest first.
pub fn jumps(patches: &Patches, radiance: &[Rgb], crease_degrees: f64) -> Vec<f64> {
    let cos_crease = crease_degrees.to_radians().cos();
    let mut by_edge: HashMap<(u32, u32), u32> = HashMap::new();
    let mut jump = vec![0.0f64; patches.len()];
    for (i, t) in patches.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let key = (a.min(b), a.max(b));
            let Some(&j) = by_edge.get(&key) else {
                by_edge.insert(key, i as u32);
                continue;
            };
            let j = j as usize;
            let same_surface = patches.material[i] == patches.material[j]
                && patches.normal[i].dot(patches.normal[j]) >= cos_crease;
            if !same_surface {
                continue;
            }
            let (li, lj) = (luminance(&radiance[i]), luminance(&radiance[j]));
            let scale = li.max(lj);
            if scale > 0.0 {
                let r = (li - lj).abs() / scale;
                jump[i] = jump[i].max(r);
                jump[j] = jump[j].max(r);
            }
        }
    }
    jump
}

/// The default bound on the patches adaptive refinement may make: twice the patches it
/// starts from, but never more than [`REFINE_MAX_PATCHES`] (and never fewer than it starts
/// from, which then allows no split). The matrix method's time and memory grow as patches²,
/// so the bound keeps a default bake within 4× the work of its first solve, and its matrices
/// below 12,000² × 32 B ≈ 4.3 GiB even where every patch sees every other (about 2 GiB at the
/// Cornell box's fill of 0.45; the default Cornell box starts from 4,004 patches and may make
/// up to 8,008).
pub fn default_budget(initial_patches: usize) -> usize {
    (2 * initial_patches).min(REFINE_MAX_PATCHES.max(initial_patches))
}

/// The most patches the default refinement budget allows, whatever the scene.
pub const REFINE_MAX_PATCHES: usize = 12_000;

/// One round of adaptive refinement that keeps the patch count within `budget`: the patches
/// whose [`jumps`] exceed `threshold` are split ([`crate::mesh::refine()`]); if that would
/// make more than `budget` patches, only the largest jumps are split, as many as fit (a
/// split patch becomes 4 and its neighbours along the split edges 2 each, so the count is
/// found by trying). `None` when nothing is marked or not even the largest jump fits; the
/// second value is true when marks were left out for the budget.
pub fn within_budget(
    scene: &Scene,
    patches: &Patches,
    jumps: &[f64],
    threshold: f64,
    crease_degrees: f64,
    budget: usize,
) -> Result<Option<(Vec<bool>, Patches, bool)>> {
    let mut order: Vec<usize> = (0..patches.len())
        .filter(|&i| jumps[i] > threshold)
        .collect();
    if order.is_empty() {
        return Ok(None);
    }
    // Largest jump first; ties by index, so the choice is deterministic.
    order.sort_by(|&a, &b| jumps[b].total_cmp(&jumps[a]).then(a.cmp(&b)));
    let n = patches.len();
    let mut keep = order.len();
    loop {
        let mut marked = vec![false; n];
        for &i in &order[..keep] {
            marked[i] = true;
        }
        let refined = crate::mesh::refine(scene, patches, &marked, crease_degrees)?;
        if refined.len() <= budget {
            return Ok(Some((marked, refined, keep < order.len())));
        }
        // Growth is about proportional to the marks: scale them to the room left, with a
        // margin, and always shrink.
        let room = budget.saturating_sub(n) as f64;
        let grown = (refined.len() - n).max(1) as f64;
        let next = ((keep as f64 * room / grown * 0.9).floor() as usize).min(keep - 1);
        if next == 0 {
            return Ok(None);
        }
        keep = next;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{subdivide, DEFAULT_CREASE_DEGREES};
    use crate::validation::scenes;

    #[test]
    fn jumps_within_a_surface_are_marked_and_jumps_across_creases_are_not() {
        // The perpendicular plates: a receiver (material 1) and a source (material 0) meeting
        // at 90°. A radiance step on the receiver marks the patches on both sides of it; the
        // step between receiver and source (another material, across a crease) marks nothing.
        let scene = scenes::perpendicular_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        let p = subdivide(&scene, 0.26, DEFAULT_CREASE_DEGREES).unwrap();
        let radiance: Vec<Rgb> = (0..p.len())
            .map(|i| {
                if p.material[i] == 0 {
                    [10.0; 3]
                } else if p.centroid[i].y < 0.5 {
                    [1.0; 3]
                } else {
                    [1.1; 3]
                }
            })
            .collect();
        let m = marks(&p, &radiance, 0.2, DEFAULT_CREASE_DEGREES);
        assert!(!m.contains(&true), "a 10 % step is below a 20 % threshold");
        let m = marks(&p, &radiance, 0.05, DEFAULT_CREASE_DEGREES);
        for (i, _) in m.iter().enumerate().filter(|(_, &marked)| marked) {
            let near_step = p.material[i] == 1 && (p.centroid[i].y - 0.5).abs() < 0.2;
            assert!(near_step, "patch {i} at {} marked", p.centroid[i]);
        }
        assert!(m.iter().filter(|&&x| x).count() >= 8);
    }
}
