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
    let cos_crease = crease_degrees.to_radians().cos();
    let mut by_edge: HashMap<(u32, u32), u32> = HashMap::new();
    let mut marked = vec![false; patches.len()];
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
            if scale > 0.0 && (li - lj).abs() > threshold * scale {
                marked[i] = true;
                marked[j] = true;
            }
        }
    }
    marked
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
