//! The pieces of a leaf the display's lines cut: each piece's own share of its leaf's
//! reflected light, before the vertices gather from them.
//!
//! The hierarchical solve's leaves are not cut along contact lines (cutting the roots there
//! multiplies the links), so one leaf of a bookcase's back board spans the boards that abut
//! it, and holds the mean of the compartments on both sides; the display's lines cut it
//! ([`crate::mesh::split_patches`]), but every piece kept the leaf's radiance. A gather ray
//! from a board's underside that meets the back board then read the mean of its own
//! compartment and the one below: the top compartments' undersides came out dark, the
//! lowest ones bright. A leaf crossed by a lamp's penumbra line spreads the lit and the
//! shaded side's light alike.
//!
//! Here the pieces of each leaf are grouped into regions, the pieces no line separates
//! ([`crate::mesh::Split::region`]); each region of a leaf with two or more seen regions is
//! gathered once, at its largest piece's centroid (the `full` gather: the direct light as at a
//! vertex, the indirect by [`PIECE_RAYS`] rays reading the leaves), and the leaf's reflected
//! radiance R (its radiance less its emission, per channel) is shared among its regions in
//! proportion to what they gathered: R_p = R · r_p / r̄, r̄ = Σ_k A_k r_k / Σ_k A_k over the
//! leaf's seen pieces k. The leaf's area-weighted mean stays the solve's (the energy the links balanced);
//! only its distribution within the leaf follows the gather. This is a final gather's step
//! (Lischinski, Tampieri & Greenberg 1993, §5) on the pieces of a discontinuity mesh the
//! solve did not resolve. Buried pieces (flush under another surface,
//! [`Gatherer::buried_patches`]) keep the leaf's value: nobody sees them, and they are out
//! of the mean. Random numbers are keyed by (seed, region): the same result for any thread
//! count.

use rayon::prelude::*;
use rustc_hash::FxHashMap as HashMap;

use super::sites::Spot;
use super::Gatherer;
use crate::color::Rgb;
use crate::sampling::Rng;

/// Hemisphere rays of a region's gather. A region's share is a ratio of gathers over the same
/// leaf, read by the vertices' own rays from many regions, so a few per cent of noise in one
/// share averages out at the vertices. The direct light is a vertex's (the emitters of the
/// largest bounds exact): where regions differ most (a compartment lit through its opening,
/// a penumbra's sides) shadow rays drawn among all the emitters were noisy enough to show
/// (the lamp-lit office's 90th percentile 3.34 → 3.55 % at 256 of them, BENCHMARKS.md).
pub const PIECE_RAYS: usize = 64;

impl Gatherer<'_> {
    /// The radiance of every patch (W·sr⁻¹·m⁻², per channel) after the regions of each cut
    /// leaf share its reflected light (module documentation). `parent[q]` is patch q's leaf,
    /// `region[q]` its region ([`crate::mesh::Split`]); `radiance` this gatherer's (each piece
    /// its leaf's). Pieces of a leaf with fewer than two seen regions, and buried pieces, keep
    /// their radiance.
    pub fn piece_shares(&self, parent: &[u32], region: &[u32], rays: usize) -> Vec<Rgb> {
        let p = self.patches;
        let buried = self.buried_patches();
        let mut shared: Vec<(u32, u32)> = shared_regions(parent, region, &p.area, &buried)
            .into_iter()
            .collect();
        shared.sort_unstable();
        // The reflected light each shared region gathers at its largest piece's centroid.
        let gathered: Vec<Rgb> = shared
            .par_iter()
            .map(|&(r, b)| {
                let b = b as usize;
                let spot = Spot {
                    x: p.centroid[b],
                    n: p.normal[b],
                    patch: b as u32,
                };
                let mut rng = Rng::new(&[self.seed, u64::from(r), 0x9_1ECE]);
                let g = self.full(&spot, rays, &mut rng);
                std::array::from_fn(|c| g.direct[c] + g.indirect[c])
            })
            .collect();
        let of_region: HashMap<u32, Rgb> = shared.iter().map(|&(r, _)| r).zip(gathered).collect();
        let at = |q: usize| {
            (!buried[q])
                .then(|| of_region.get(&region[q]).copied())
                .flatten()
        };
        // Each cut leaf's area-weighted mean of its seen pieces' gathers.
        let mut sum: HashMap<u32, (Rgb, f64)> = HashMap::default();
        for (q, (&leaf, &area)) in parent.iter().zip(&p.area).enumerate() {
            if let Some(r) = at(q) {
                let s = sum.entry(leaf).or_insert(([0.0; 3], 0.0));
                for (total, value) in s.0.iter_mut().zip(r) {
                    *total += area * value;
                }
                s.1 += area;
            }
        }
        (0..p.len())
            .map(|q| {
                let l = self.radiance[q];
                let Some(r) = at(q) else {
                    return l;
                };
                let (s, a) = sum[&parent[q]];
                let le = p.emission[q];
                std::array::from_fn(|c| {
                    let mean = s[c] / a;
                    let reflected = l[c] - le[c];
                    if mean > 0.0 && reflected > 0.0 {
                        le[c] + reflected * r[c] / mean
                    } else {
                        l[c]
                    }
                })
            })
            .collect()
    }
}

/// The regions (by their first piece, [`crate::mesh::Split::region`]) of the leaves with two
/// or more seen regions, each with its largest seen piece: where [`Gatherer::piece_shares`]
/// gathers. `parent` and `region` as the split gives them; `area` and `buried` per piece.
pub fn shared_regions(
    parent: &[u32],
    region: &[u32],
    area: &[f64],
    buried: &[bool],
) -> HashMap<u32, u32> {
    let mut largest: HashMap<u32, u32> = HashMap::default();
    for q in (0..parent.len()).filter(|&q| !buried[q]) {
        let b = largest.entry(region[q]).or_insert(q as u32);
        if area[q] > area[*b as usize] {
            *b = q as u32;
        }
    }
    let mut seen: HashMap<u32, u32> = HashMap::default();
    for r in largest.keys() {
        *seen.entry(parent[*r as usize]).or_default() += 1;
    }
    largest.retain(|r, _| seen[&parent[*r as usize]] >= 2);
    largest
}
