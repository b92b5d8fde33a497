//! Near links at the leaves: where a link held high in a receiver's hierarchy has its source
//! close beside it (the floor meeting a wall, a block's face standing on the floor), the
//! form factor varies across the receiver far more than the BF oracle can see, and pushing
//! the link's receiver-averaged F to every leaf alike (push-pull) gives the leaves along the
//! shared edge too little and those away from it too much. This module owns the correction:
//! once the links are final, every leaf below such a link takes its own form factor to the
//! link's source.
//!
//! The leaf's F is the exact unoccluded point-to-polygon form factor integrated by the
//! receiver rule over the leaf (`links::unoccluded_form_factor`, Lambert's contour integral:
//! exact also where the two share an edge), times the visible share of F the link's rays
//! found over the whole receiver: F_e = U_e · F_link / U_link. What the leaf gathers through
//! the link is then F_e · L_s instead of F_link · L_s; the difference is kept per (leaf, link)
//! and added to the leaf's own gather in the final solve (`Hierarchy::gather`), so the row
//! sums that normalise closed roots count it too. This is the re-evaluation of a coarse link
//! at the receiving point of Lischinski, Tampieri & Greenberg, "Combining hierarchical
//! radiosity and discontinuity meshing" (SIGGRAPH 1993), for the unoccluded kernel, with the
//! link's visibility kept; links whose kernel hardly varies over the receiver are left alone
//! ([`NEAR_SPREAD`]).

use rayon::prelude::*;

use super::links;
use super::tree;
use super::Hierarchy;

/// A link is corrected at its receiver's leaves when the unoccluded point form factor to its
/// source, at the receiver's corners and centroid, spreads over more than this (max − min,
/// times the link's visible share): the largest error in F that pushing the link's mean to a
/// leaf can make there. Beside a shared edge the spread is about 0.5 (the point form factor
/// to a perpendicular face is ½ at the edge); links far against the receiver's size spread
/// by little and are left alone, which keeps the corrections to the few links per element
/// that are near.
pub const NEAR_SPREAD: f64 = 0.02;

/// One leaf's correction to one link: the leaf gathers `delta` · (the link's source radiance)
/// more than the link's F pushed down gives it.
#[derive(Clone, Copy, Debug)]
pub(super) struct Correction {
    pub leaf: u32,
    pub link: u32,
    /// F_e − F_link, dimensionless.
    pub delta: f32,
}

impl Hierarchy<'_> {
    /// Finds the corrections of the final links ([`Hierarchy::near`]), sorted by leaf then
    /// link. Deterministic: no random numbers, the same for any thread count.
    pub(super) fn find_near_corrections(&mut self) {
        let t = &self.tree;
        let mut found: Vec<Correction> = self
            .links
            .par_iter()
            .enumerate()
            .flat_map_iter(|(i, l)| {
                let mut out = Vec::new();
                let (Some(a), Some(s)) = (l.receiver.as_element(), l.source.as_element()) else {
                    return out;
                };
                if t.elements[a].first_child == tree::NO_CHILD || l.f <= 0.0 {
                    return out;
                }
                let Some(u_a) = links::unoccluded_form_factor(t, a, s, self.buried[a]) else {
                    return out;
                };
                if u_a <= 0.0 {
                    return out;
                }
                let visible_share = (l.f as f64 / u_a).min(1.0);
                if links::point_form_factor_spread(t, a, s) * visible_share < NEAR_SPREAD {
                    return out;
                }
                t.leaves(a, &mut |e| {
                    if let Some(u_e) = links::unoccluded_form_factor(t, e, s, self.buried[e]) {
                        let delta = u_e * visible_share - l.f as f64;
                        out.push(Correction {
                            leaf: e as u32,
                            link: i as u32,
                            delta: delta as f32,
                        });
                    }
                });
                out
            })
            .collect();
        found.par_sort_unstable_by_key(|c| (c.leaf, c.link));
        self.stats.near_corrections = found.len() as u64;
        self.near = found;
    }

    /// Adds to each leaf's gather `ge` what its corrections bring: Σ delta · L over them
    /// (`with_radiance`, L each link's source radiance as the link gathers it), else Σ delta.
    pub(super) fn add_near(&self, ge: &mut [crate::color::Rgb], with_radiance: bool) {
        let sums: Vec<(usize, crate::color::Rgb)> = self
            .near
            .par_chunk_by(|a, b| a.leaf == b.leaf)
            .map(|run| {
                let mut g = [0.0; 3];
                for c in run {
                    let d = c.delta as f64;
                    let i = c.link as usize;
                    let v = if with_radiance {
                        self.link_radiance(i, &self.links[i]).map(|x| d * x)
                    } else {
                        [d; 3]
                    };
                    g = super::push_pull::add(g, v);
                }
                (run[0].leaf as usize, g)
            })
            .collect();
        for (e, g) in sums {
            ge[e] = super::push_pull::add(ge[e], g);
        }
    }
}
