//! Two-sided scenes: every face a back side of its own, as a *twin* (see the module
//! documentation of [`super`], "Two-sided scenes").

use std::collections::HashMap;

use super::{Material, Scene, SceneTriangle, NO_TWIN};
use crate::geometry::winding_key;

impl Scene {
    /// True if some triangle has a twin (a back side of its own; see [`Scene::make_two_sided`]).
    pub fn is_two_sided(&self) -> bool {
        self.twin.iter().any(|&u| u != NO_TWIN)
    }

    /// A copy with every face two-sided ([`Scene::make_two_sided`]).
    pub fn to_two_sided(&self) -> Scene {
        let mut scene = self.clone();
        scene.make_two_sided();
        scene
    }

    /// Makes every face two-sided (`--two-sided`; see the module documentation) and returns
    /// the number of back faces added: [`Scene::make_two_sided_where`] for every material.
    pub fn make_two_sided(&mut self) -> usize {
        self.make_two_sided_where(|_, _| true)
    }

    /// Gives each triangle `t` that `pick(t, its material)` accepts a back side of its own
    /// (`t` indexes the triangles as they are before the call), and returns
    /// the number of back faces added. In triangle order, a picked triangle without a twin is
    /// paired with the first unpaired triangle over the same three vertices in the opposite
    /// winding, if the scene has one (a back face modelled in the file: it keeps its own
    /// material; the pairs found are counted in a warning), and otherwise gets a new twin
    /// appended at the end: its vertices reversed, `[v0, v2, v1]`, with the same material (ρ
    /// and Le are the same on both sides). Positions, materials and the order of the existing
    /// triangles are unchanged, and calling it again adds nothing.
    ///
    /// The loader's checks are not run again: twins lie in the same plane facing opposite
    /// ways, which the overlap check already accepts, and every shared edge is now used in
    /// both directions on purpose.
    pub fn make_two_sided_where(
        &mut self,
        mut pick: impl FnMut(usize, &Material) -> bool,
    ) -> usize {
        let n = self.triangles.len();
        if self.twin.is_empty() {
            self.twin = vec![NO_TWIN; n];
        }
        // Triangles over the same vertex set, by sorted indices and winding parity.
        let key = winding_key::<u32>;
        let mut unpaired: HashMap<([u32; 3], bool), Vec<usize>> = HashMap::new();
        for t in 0..n {
            if self.twin[t] == NO_TWIN {
                unpaired
                    .entry(key(self.triangles[t].vertices))
                    .or_default()
                    .push(t);
            }
        }
        let mut paired_in_file = 0;
        let mut added = 0;
        for t in 0..n {
            let tri = self.triangles[t];
            if self.twin[t] != NO_TWIN || !pick(t, &self.materials[tri.material as usize]) {
                continue;
            }
            let (sorted, odd) = key(tri.vertices);
            let partner = unpaired
                .get_mut(&(sorted, !odd))
                .and_then(|list| (!list.is_empty()).then(|| list.remove(0)));
            if let Some(u) = partner {
                self.twin[t] = u as u32;
                self.twin[u] = t as u32;
                if let Some(list) = unpaired.get_mut(&(sorted, odd)) {
                    list.retain(|&x| x != t);
                }
                paired_in_file += 1;
                continue;
            }
            let [a, b, c] = tri.vertices;
            self.triangles.push(SceneTriangle {
                vertices: [a, c, b],
                ..tri
            });
            let u = self.triangles.len() - 1;
            self.twin.push(t as u32);
            self.twin[t] = u as u32;
            added += 1;
        }
        if paired_in_file > 0 {
            self.warnings.push(format!(
                "two-sided: {paired_in_file} face{} already had a reversed face over the same \
                 corners; each such pair is taken as the two sides of one surface (each side \
                 keeps its own material) instead of being doubled",
                if paired_in_file == 1 { "" } else { "s" }
            ));
        }
        added
    }
}
