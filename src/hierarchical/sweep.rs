//! The sweep (HSA91 §3): a Jacobi sweep gathers, at every node, Σ F·L over its links from the
//! previous sweep's radiance, in parallel ([`Hierarchy::sweep`]); a split element source
//! gives its children's radiance weighted by how much of F reaches each
//! ([`Hierarchy::link_radiance`]). Push-pull ([`super::push_pull`]) then spreads what each
//! node gathered. Sweeps repeat until the relative change per sweep is below the tolerance
//! ([`Hierarchy::converge`], which combines the last sweeps' radiance by Anderson
//! acceleration, [`crate::solve::anderson`]).

use glam::DVec3;
use rayon::prelude::*;

use super::links::{self, Link};
use super::push_pull::{add, ClusterGather};
use super::tree::{self, Node};
use super::{Hierarchy, ORIENTED_CONE_COS};
use crate::color::Rgb;
use crate::solve::{self, anderson};

impl Hierarchy<'_> {
    /// One Jacobi sweep: gather over all links from the current radiance, then push-pull.
    /// Returns the relative change ‖ΔL‖ / ‖Le‖ over the leaves (area-weighted 2-norms): the
    /// residual E − (I − K)L of the linear system the links define.
    pub fn sweep(&mut self) -> f64 {
        self.sweep_from().0
    }

    /// [`Self::sweep`], also returning the radiance it swept from.
    fn sweep_from(&mut self) -> (f64, Vec<Rgb>) {
        if self.rows_stale {
            self.refresh_rows();
        }
        let (ge, gc) = self.gather(true);
        let old = std::mem::take(&mut self.elem_l);
        self.push_pull(ge, gc, true);
        self.stats.sweeps += 1;
        let (mut num, mut den) = (0.0, 0.0);
        for (e, el) in self.tree.elements.iter().enumerate() {
            if el.first_child != tree::NO_CHILD {
                continue;
            }
            // The source term E = Le + ρ·D_env (the sky's and sun's light counts as emission).
            let r = el.root as usize;
            let (le, rho, env) = (
                self.roots.emission[r],
                self.roots.reflectance[r],
                self.direct[e].environment,
            );
            for c in 0..3 {
                num += el.area * (self.elem_l[e][c] - old[e][c]).powi(2);
                let source = le[c] + rho[c] * env[c];
                den += el.area * source * source;
            }
        }
        let residual = if den > 0.0 { (num / den).sqrt() } else { 0.0 };
        (residual, old)
    }

    /// Sweeps until the residual is at most the tolerance or the sweep limit; true if
    /// converged.
    ///
    /// The sweeps are accelerated ([`anderson`]): a sweep is the affine map L ↦ E + K L over
    /// the leaves' radiance (push-pull sets every other node's from them, linearly), and each
    /// next iterate combines the last [`anderson::DEPTH`] + 1 sweeps' images so that their
    /// residuals, combined alike, are smallest (GMRES-like: in a white room a third to a sixth
    /// of the plain sweeps). The combination is clamped at 0 (the solution is ≥ 0) and the
    /// history restarted wherever a residual grows. The residual reported and tested is the
    /// plain one of the last sweep, and on convergence the radiance kept is that sweep's
    /// image (at the sweep limit, the last combination).
    pub(super) fn converge(&mut self, solver: &solve::Settings, history: &mut Vec<f64>) -> bool {
        let mut clock = solve::SweepClock::new(solver.tolerance);
        // Weighted as the residual is: leaves by area, inner elements not at all.
        let weights = self
            .tree
            .elements
            .iter()
            .map(|el| {
                if el.first_child == tree::NO_CHILD {
                    el.area
                } else {
                    0.0
                }
            })
            .collect();
        let mut accel = anderson::Anderson::new(anderson::DEPTH, weights);
        let mut last = f64::INFINITY;
        for _ in 0..solver.max_iterations {
            let (r, old) = self.sweep_from();
            history.push(r);
            clock.report(self.stats.sweeps, r);
            if r <= solver.tolerance {
                return true;
            }
            if r > last {
                accel.restart();
            }
            last = r;
            let mut next = std::mem::take(&mut self.elem_l);
            if accel.step(&old, &mut next) {
                drop(old);
                for l in &mut next {
                    l.iter_mut().for_each(|x| *x = x.max(0.0));
                }
                self.pull(next);
            } else {
                self.elem_l = next;
            }
        }
        false
    }

    /// What each node gathers over its own links: Σ F·L per channel (`with_radiance`), or
    /// Σ F in every channel. A cluster's gather is kept by direction ([`ClusterGather`]).
    pub(super) fn gather(&self, with_radiance: bool) -> (Vec<Rgb>, Vec<ClusterGather>) {
        let t = &self.tree;
        let value = |i: usize, l: &Link| {
            let f = l.f as f64;
            if with_radiance {
                self.link_radiance(i, l).map(|x| f * x)
            } else {
                [f; 3]
            }
        };
        // Each node's run of links as receiver ([`Hierarchy::first_link`]): the elements',
        // then the clusters'. Written in place: at 10⁶ triangles a list of the runs' sums
        // beside them would add 100 MB to every sweep.
        // (No runs before the first links are set.)
        let runs = &self.first_link;
        let run = |k: usize| match (runs.get(k), runs.get(k + 1)) {
            (Some(&a), Some(&b)) => a..b,
            _ => 0..0,
        };
        let ne = t.elements.len();
        let mut ge = vec![[0.0; 3]; ne];
        ge.par_iter_mut().enumerate().for_each(|(e, g)| {
            *g = run(e).fold([0.0; 3], |g, i| add(g, value(i, &self.links[i])));
        });
        self.add_near(&mut ge, with_radiance);
        let mut gc = vec![ClusterGather::default(); t.clusters.len()];
        gc.par_iter_mut().enumerate().for_each(|(c, cg)| {
            for i in run(ne + c) {
                let l = &self.links[i];
                let d = t.sphere(l.source).0 - t.clusters[c].centre;
                cg.add(&t.clusters[c], d, l.f as f64, value(i, l));
            }
        });
        // Over several ranks, each node's gather from the rank holding its links.
        self.share_gathers(&mut ge, &mut gc);
        (ge, gc)
    }

    /// Finds every element's effective row sum ([`Hierarchy::effective`]) for the current
    /// links; returns [`Hierarchy::worst_row`], found from the same sums (a second gather of
    /// them would cost as much as a sweep, and set the peak memory at the end of a large
    /// solve).
    pub(super) fn refresh_rows(&mut self) -> Option<(usize, f64)> {
        let any = self.link_count() > 0;
        let (own, down) = self.pushed_row_sums();
        let worst = if any { self.worst_of(&down) } else { None };
        self.row_sum = self.effective(down);
        self.own_row_sum = if self.row_sum.is_empty() {
            Vec::new()
        } else {
            own
        };
        self.rows_stale = false;
        worst
    }

    /// Σ F over each element's own links alone (channel 0), and over its own links and its
    /// ancestors' (the same in every channel).
    fn pushed_row_sums(&self) -> (Vec<f64>, Vec<Rgb>) {
        let (ge, gc) = self.gather(false);
        let own = ge.iter().map(|g| g[0]).collect();
        (own, self.push_down(ge, gc))
    }

    /// Each element's effective row sum, from its sum `down`: 0 (not normalised) for the
    /// elements of a root that is not closed, unless the rows are capped
    /// ([`Hierarchy::cap_rows`]) and this one sums to more than 1.
    fn effective(&self, down: Vec<Rgb>) -> Vec<f64> {
        down.iter()
            .zip(&self.tree.elements)
            .map(|(g, el)| {
                if self.closed_roots[el.root as usize] || (self.cap_rows && g[0] > 1.0) {
                    g[0]
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// The leaf whose effective row sum (Σ F over its own links and its ancestors', as in
    /// [`Hierarchy::effective`] but before any normalisation, for every root) is the largest:
    /// its element index and that sum (ties: the lowest index); `None` without links (on any
    /// rank: every rank returns the same).
    pub(super) fn worst_row(&self) -> Option<(usize, f64)> {
        if self.link_count() == 0 {
            return None;
        }
        self.worst_of(&self.pushed_row_sums().1)
    }

    /// [`Hierarchy::worst_row`] of the sums `down` (`None` only without leaves).
    fn worst_of(&self, down: &[Rgb]) -> Option<(usize, f64)> {
        self.tree
            .elements
            .iter()
            .enumerate()
            .filter(|(_, el)| el.first_child == tree::NO_CHILD)
            .map(|(e, _)| (e, down[e][0]))
            .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
    }

    /// The radiance link `l` gathers from its source, W·sr⁻¹·m⁻²: once an element source is
    /// split, its children's radiance weighted by the link's shares of the form factor
    /// through each ([`Link::children`]) times each child's visible fraction; else the
    /// source's mean. So a receiver that sees one part of its source best (the floor next to
    /// a block's face, in its shadow) gathers that part's radiance, not the mean of parts it
    /// hardly sees: one level finer on the source side than the link, for no more links. On
    /// the Cornell box this about halves the worst surface's error at a fine ε.
    ///
    /// Once the links are final, the same two levels down: each split child's four children
    /// weighted by the link's shares through each
    /// ([`links::grandchild_shares`]). A dim face next to a bright
    /// floor sees the part of the floor beside it best, which is where the floor's radiance changes
    /// most (its shadow, its corner with the face). On the Cornell box the worst surface is such a
    /// face: the second level takes out most of what the first leaves, and weighting the source's
    /// leaves however deep adds little more.
    ///
    /// A cluster source: its parts two levels down ([`Tree::parts`](super::tree::Tree::parts)),
    /// each sending toward the receiver as a cluster or face does, weighted by the link's form
    /// factors to each (`links::part_form_factors`).
    pub fn link_radiance(&self, i: usize, l: &Link) -> Rgb {
        if let Some(e) = l.source.as_element() {
            let first = self.tree.elements[e].first_child as usize;
            if let Some(shares) = self.grandchild_shares.get(i).filter(|s| **s != [0; 16]) {
                // Each child split further gives its four children their shares; an unsplit
                // child takes the sum of its quarter.
                let (mut parts, mut n) = ([(0, 0.0); 16], 0);
                for q in 0..4 {
                    let (child, quarter) = (first + q, &shares[4 * q..4 * q + 4]);
                    let grand = self.tree.elements[child].first_child;
                    if grand == tree::NO_CHILD {
                        parts[n] = (child, quarter.iter().map(|&x| x as f64).sum());
                        n += 1;
                    } else {
                        for (k, &share) in quarter.iter().enumerate() {
                            parts[n] = (grand as usize + k, share as f64);
                            n += 1;
                        }
                    }
                }
                let parts = parts[..n].iter().copied();
                if let Some(l) = self.share_weighted(parts) {
                    return l;
                }
            }
            if first != tree::NO_CHILD as usize {
                let parts = (0..4).map(|q| (first + q, l.children[q] as f64));
                if let Some(l) = self.share_weighted(parts) {
                    return l;
                }
            }
        }
        // Only a cluster source reads where its receiver is (an element link's lookup of its
        // receiver, on every sweep, would be a memory access for nothing).
        let Some(c) = l.source.as_cluster() else {
            return self.radiance(l.source);
        };
        let receiver = self.tree.sphere(l.receiver).0;
        if l.children != [0; 4] {
            let (mut sum, mut total) = ([0.0; 3], 0.0);
            for (k, part) in self.tree.parts(c).enumerate() {
                let share = links::part_share(l.children, k);
                if share > 0 {
                    let w = share as f64;
                    total += w;
                    sum = add(sum, self.radiance_toward(part, receiver).map(|x| w * x));
                }
            }
            return sum.map(|x| x / total);
        }
        self.radiance_toward(l.source, receiver)
    }

    /// The radiance `source` sends toward the point `receiver` (a receiving node's centre),
    /// W·sr⁻¹·m⁻²: a cluster whose faces look different ways sends that of the faces turned
    /// toward it (or, where none is, those nearest to it: `OrientedRadiance::toward`); any
    /// other node its mean.
    fn radiance_toward(&self, source: Node, receiver: DVec3) -> Rgb {
        if let Some(c) = source.as_cluster() {
            let cl = &self.tree.clusters[c];
            if cl.cone_cos < ORIENTED_CONE_COS {
                let d = receiver - cl.centre;
                if let Some(d) = d.try_normalize() {
                    return self.cluster_oriented[c].toward(d);
                }
            }
        }
        self.radiance(source)
    }

    /// Σ w·v·L / Σ w·v over (element, share w) parts, v each element's visible fraction;
    /// `None` when the weights sum to 0.
    pub(super) fn share_weighted(&self, parts: impl Iterator<Item = (usize, f64)>) -> Option<Rgb> {
        let mut sum = [0.0; 3];
        let mut total = 0.0;
        for (k, share) in parts {
            let w = share * self.visible[k];
            total += w;
            for (s, l) in sum.iter_mut().zip(self.elem_l[k]) {
                *s += w * l;
            }
        }
        (total > 0.0).then(|| sum.map(|x| x / total))
    }

    pub(super) fn radiance(&self, node: Node) -> Rgb {
        match node.as_element() {
            Some(e) => self.elem_l[e],
            None => self.cluster_l[node.as_cluster().unwrap()],
        }
    }
}
