//! Push-pull (HSA91 §3): what a node gathered over its links is pushed down to every leaf
//! below it (irradiance is intensive: the same on every part; a cluster whose faces look
//! different ways gives each face its cosine's share, [`ClusterGather`]), leaves take
//! L = Le + ρ·(D + G), and radiance is pulled up as area-weighted means, weighted by visible
//! area so that a buried part of an element does not dilute the part that is seen; each
//! cluster also keeps its radiance by the direction it leaves in ([`OrientedRadiance`]).

use glam::DVec3;
use rayon::prelude::*;

use super::tree;
use super::{Hierarchy, ORIENTED_CONE_COS};
use crate::color::Rgb;

impl Hierarchy<'_> {
    /// No light has bounced yet: leaves hold the emission links carry, pulled up (L = Le
    /// without the emission the elements compute themselves, which only reaches other
    /// elements as their direct light, from the first sweep on).
    pub(super) fn reset(&mut self) {
        let t = &self.tree;
        let leaves = (0..t.elements.len())
            .map(|e| {
                let el = &t.elements[e];
                if el.first_child == tree::NO_CHILD {
                    self.carried_emission(el.root as usize)
                } else {
                    [0.0; 3]
                }
            })
            .collect();
        self.pull(leaves);
    }

    /// What each element gathers through its own links and all its ancestors' (clusters'
    /// included): the push half of push-pull. A root element takes from its clusters what
    /// its own orientation receives ([`ClusterGather::at`]).
    ///
    /// Both gathers are summed down in place (copies of them would add 100 MB to every sweep
    /// at 10⁶ triangles).
    pub(super) fn push_down(&self, ge: Vec<Rgb>, gc: Vec<ClusterGather>) -> Vec<Rgb> {
        let t = &self.tree;
        let mut cdown = gc;
        for c in 0..t.clusters.len() {
            let cl = &t.clusters[c];
            for k in cl.first..cl.first + cl.count {
                if let Some(child) = t.cluster_children[k as usize].as_cluster() {
                    let parent = cdown[c].clone();
                    cdown[child].add_all(&parent);
                }
            }
        }
        // The roots (the first elements, no parent) take from their clusters, in parallel;
        // then the elements split from them, each after its parent.
        let mut down = ge;
        let roots = t.roots.min(down.len());
        down[..roots].par_iter_mut().enumerate().for_each(|(e, d)| {
            if !t.clusters.is_empty() {
                *d = add(
                    *d,
                    cdown[t.root_parent[e] as usize].at(t.elements[e].normal),
                );
            }
        });
        for e in roots..t.elements.len() {
            let p = t.elements[e].parent as usize;
            down[e] = add(down[e], down[p]);
        }
        down
    }

    /// Push-pull: leaves take L = Le + ρ·(D + G) (D their direct light when `with_direct`,
    /// G what the links bring, normalised by the row sum in closed scenes; Le only the
    /// emission links carry), inner elements and clusters the area-weighted mean of their
    /// children.
    pub(super) fn push_pull(&mut self, ge: Vec<Rgb>, gc: Vec<ClusterGather>, with_direct: bool) {
        // What each leaf gathered through its own links, apart from its ancestors': where
        // rows are normalised, the shortfall goes to the ancestors' part ([`Self::gathered`]).
        let own = if self.own_row_sum.is_empty() {
            Vec::new()
        } else {
            ge.clone()
        };
        let down = self.push_down(ge, gc);
        let leaves = self.leaf_radiance(&down, &own, with_direct);
        drop(down);
        self.pull(leaves);
    }

    /// Each leaf's L = Le + ρ·(D + G) from what it gathered, `down` (see [`Self::push_pull`]);
    /// inner elements 0.
    fn leaf_radiance(&self, down: &[Rgb], own: &[Rgb], with_direct: bool) -> Vec<Rgb> {
        let t = &self.tree;
        (0..t.elements.len())
            .into_par_iter()
            .map(|e| {
                let el = &t.elements[e];
                if el.first_child != tree::NO_CHILD {
                    return [0.0; 3];
                }
                let r = el.root as usize;
                let g = self.gathered(e, down[e], own.get(e).copied());
                let le = self.carried_emission(r);
                let d = if with_direct {
                    self.direct[e].mean
                } else {
                    [0.0; 3]
                };
                let rho = self.roots.reflectance[r];
                std::array::from_fn(|c| le[c] + rho[c] * (d[c] + g[c]))
            })
            .collect()
    }

    /// What leaf `e` takes from `down`, the light gathered through its links and its
    /// ancestors' (radiance units), normalised where its root's rows are (Cohen & Wallace
    /// §4.11; see the module documentation of [`super`]) so that its effective row sum is 1.
    ///
    /// A row misses 1 through the links of the leaf's ancestors, whose form factor is their
    /// receiver's mean, not this leaf's: beside a chair, the floor's leaves see the chair
    /// through the whole floor's link (nearly nothing) and fall short; far from it, they
    /// take more than their share. The leaf's own links are its own. So the difference goes
    /// to the ancestors' part: G = G_own + G_anc · (1 − F_own) / F_anc, the sources seen
    /// through the coarse links standing for what is missing. Dividing the whole by the row
    /// sum instead gives the shortfall the mean radiance of everything the leaf sees, the
    /// lamps its own links reach included: in a hall of hundreds of lamps, whose links carry
    /// their emission, every leaf beside furniture came out lit by 1/s, the ceiling of the
    /// generated hall of 10⁵ triangles 9 % bright (12 % at a finer ε, whose smaller leaves
    /// fall shorter). A closed enclosure of uniform radiance stays exact either way (both
    /// parts read L). Where the ancestors carry too little of the row to stand for the
    /// rest (F_anc below [`ANCESTOR_SHARE`] of the shortfall's size, or the own links alone
    /// over 1), the whole is divided.
    fn gathered(&self, e: usize, down: Rgb, own: Option<Rgb>) -> Rgb {
        let Some(&s) = self.row_sum.get(e).filter(|&&s| s > 0.0) else {
            return down;
        };
        if let (Some(g_own), Some(&f_own)) = (own, self.own_row_sum.get(e)) {
            let f_anc = s - f_own;
            if f_own < 1.0 && f_anc > ANCESTOR_SHARE * (1.0 - s).abs() {
                let k = (1.0 - f_own) / f_anc;
                return std::array::from_fn(|c| g_own[c] + (down[c] - g_own[c]) * k);
            }
        }
        down.map(|x| x / s)
    }

    /// Sets every element's and cluster's radiance from the leaves' (the entries of `l` at
    /// leaves; the others are overwritten): the pull half of push-pull. Linear in the leaves'
    /// radiance, with fixed weights.
    pub(super) fn pull(&mut self, mut l: Vec<Rgb>) {
        let t = &self.tree;
        let n = t.elements.len();
        // Radiance is pulled up weighted by visible area: a source's buried part (the floor
        // under a block) emits nothing and is seen by nobody, and its visibility rays already
        // count it as blocked, so its darkness must not dilute the visible part's radiance.
        let mut visible_area = vec![0.0; n];
        let mut lmax = vec![0.0f64; n];
        // A leaf: (L, visible area, largest channel).
        let leaf = |e: usize, l: Rgb| {
            (
                l,
                t.elements[e].area * self.visible[e],
                l.iter().copied().fold(0.0, f64::max),
            )
        };
        // An inner element from its four children, which come after every root (`tail`
        // holds the elements from `roots` on).
        let roots = t.roots.min(n);
        let inner = |e: usize, l: &[Rgb], va: &[f64], lm: &[f64]| {
            let first = t.elements[e].first_child as usize - roots;
            let kids = first..first + 4;
            let max = kids.clone().map(|k| lm[k]).fold(0.0, f64::max);
            let (mean, visible) =
                weighted_mean(kids.map(|k| (l[k], va[k], t.elements[roots + k].area)));
            (mean, visible, max)
        };
        let (l_roots, l_tail) = l.split_at_mut(roots);
        let (va_roots, va_tail) = visible_area.split_at_mut(roots);
        let (lm_roots, lm_tail) = lmax.split_at_mut(roots);
        // The split elements first, children before parents; then the roots, in parallel.
        for e in (roots..n).rev() {
            let i = e - roots;
            (l_tail[i], va_tail[i], lm_tail[i]) = if t.elements[e].first_child == tree::NO_CHILD {
                leaf(e, l_tail[i])
            } else {
                inner(e, l_tail, va_tail, lm_tail)
            };
        }
        l_roots
            .par_iter_mut()
            .zip(va_roots.par_iter_mut())
            .zip(lm_roots.par_iter_mut())
            .enumerate()
            .for_each(|(e, ((l, va), lm))| {
                (*l, *va, *lm) = if t.elements[e].first_child == tree::NO_CHILD {
                    leaf(e, *l)
                } else {
                    inner(e, l_tail, va_tail, lm_tail)
                };
            });
        let mut cl = vec![[0.0; 3]; t.clusters.len()];
        // Refilled in place: on a scene of 10⁶ triangles it is about 100 MB.
        let mut oriented = std::mem::take(&mut self.cluster_oriented);
        oriented.clear();
        oriented.resize(t.clusters.len(), OrientedRadiance::default());
        let mut cluster_visible = vec![0.0; t.clusters.len()];
        let mut cmax = vec![0.0f64; t.clusters.len()];
        for c in (0..t.clusters.len()).rev() {
            let kids = t.kids(c);
            cmax[c] = kids
                .iter()
                .map(|&child| match child.as_element() {
                    Some(e) => lmax[e],
                    None => cmax[child.as_cluster().unwrap()],
                })
                .fold(0.0, f64::max);
            (cl[c], cluster_visible[c]) =
                weighted_mean(kids.iter().map(|&child| match child.as_element() {
                    Some(e) => (l[e], visible_area[e], t.elements[e].area),
                    None => {
                        let j = child.as_cluster().unwrap();
                        (cl[j], cluster_visible[j], t.clusters[j].area)
                    }
                }));
            let mut o = OrientedRadiance::default();
            for &child in kids {
                match child.as_element() {
                    Some(e) => o.add(t.elements[e].normal, visible_area[e], l[e]),
                    None => o.add_all(&oriented[child.as_cluster().unwrap()]),
                }
            }
            oriented[c] = o;
        }
        self.elem_l = l;
        self.cluster_l = cl;
        self.cluster_oriented = oriented;
        self.elem_max = lmax;
        self.cluster_max = cmax;
    }

    /// Every element's radiance L, W·sr⁻¹·m⁻²: what the links transport plus the emission the
    /// elements compute themselves.
    pub(super) fn total_radiance(&self) -> Vec<Rgb> {
        let t = &self.tree;
        (0..t.elements.len())
            .map(|e| {
                let r = t.elements[e].root as usize;
                if self.exact[r] {
                    add(self.elem_l[e], self.roots.emission[r])
                } else {
                    self.elem_l[e]
                }
            })
            .collect()
    }
}

/// [`Hierarchy::gathered`] gives a row's shortfall (or excess) to the ancestors' links only
/// where their share of the row F_anc is at least this many times it: scaled by more than
/// 1 + 1/this, a few coarse links would stand for too much.
pub const ANCESTOR_SHARE: f64 = 1.0;

/// What a cluster gathers, kept by the direction it arrives from, so that each face below
/// receives what its orientation lets it see: a cluster receives light through one link
/// and pushes it to every face below, and pushed uniformly, the faces of a block that look
/// away from a light would get as much of it as the top that faces it (on the Cornell box cut
/// into many small roots, a block face that looks at the dark open front would show far too
/// bright).
///
/// A link's light v from direction d (unit, the source's centre seen from the cluster's) is
/// spread over the faces below in proportion to the clamped cosine between each face's
/// normal n and d, in the separable form c(n, d) = Σ_a |d_a| · max(0, sign(d_a) n_a) (exact
/// for faces and directions along the axes, an upper estimate otherwise), normalised by the
/// mean of it over the cluster's seen area ([`tree::Cluster::seen_facing`], as the link's
/// form factor is a mean over the seen area): so the area-mean over the cluster
/// of what its faces take is v, as the link's form factor (an area-mean over the cluster)
/// says, and a face turned away from d takes none. Links whose direction no face below
/// meets (a mean of 0) are pushed uniformly, and so are those whose form factor F is at
/// least that mean: the face that faces d best would take F / mean ≥ 1 through the link, more
/// than its whole hemisphere holds. There the link's F, found from the true cosines at its
/// samples, is not the bins' (a wide or near source, seen by faces the bins count as turned
/// away), and the few faces turned toward d would take all of it (in a generated office, a
/// 20 cm² strip of a window frame summed a row of 1.6·10⁵). So is everything a cluster
/// gathers whose faces all lie within [`ORIENTED_CONE_COS`] of their mean normal: there the
/// cosine's variation is small and, on a curved surface, mostly cancelled by parallax (inside
/// a sphere, exactly: every point receives alike), which one direction per link cannot follow.
#[derive(Clone, Debug, Default)]
pub struct ClusterGather {
    /// Pushed to every face alike, per channel.
    uniform: Rgb,
    /// Per axis direction (+x, +y, +z, −x, −y, −z), per channel: light already divided by the
    /// cluster's mean cosine; a face with normal n takes max(0, ±n_a) of each.
    by_axis: [Rgb; 6],
}

impl ClusterGather {
    /// Adds light `v` (per channel) that cluster `cluster` gathers from direction `d` (any
    /// length; 0 pushes uniformly) through a link of form factor `f` (dimensionless, ≥ 0).
    pub(super) fn add(&mut self, cluster: &tree::Cluster, d: DVec3, f: f64, v: Rgb) {
        let oriented = cluster.cone_cos < ORIENTED_CONE_COS;
        let Some(d) = d.try_normalize().filter(|_| oriented) else {
            self.uniform = add(self.uniform, v);
            return;
        };
        let bin = |a: usize| axis_bin(d, a);
        let mean: f64 = (0..3)
            .map(|a| d[a].abs() * cluster.seen_facing[bin(a)])
            .sum::<f64>()
            / cluster.seen_area;
        if mean.is_nan() || mean <= 1e-12 || f >= mean {
            self.uniform = add(self.uniform, v);
            return;
        }
        for a in 0..3 {
            let w = d[a].abs() / mean;
            self.by_axis[bin(a)] = add(self.by_axis[bin(a)], v.map(|x| w * x));
        }
    }

    /// The 21 numbers it holds (uniform, then the axes), for an exchange between ranks.
    pub(super) fn to_array(&self) -> [f64; 21] {
        let mut a = [0.0; 21];
        for (k, rgb) in std::iter::once(&self.uniform)
            .chain(&self.by_axis)
            .enumerate()
        {
            a[3 * k..3 * k + 3].copy_from_slice(rgb);
        }
        a
    }

    /// The gather [`ClusterGather::to_array`] gave.
    pub(super) fn from_array(a: [f64; 21]) -> Self {
        let rgb = |k: usize| [a[3 * k], a[3 * k + 1], a[3 * k + 2]];
        ClusterGather {
            uniform: rgb(0),
            by_axis: std::array::from_fn(|k| rgb(k + 1)),
        }
    }

    /// Adds everything `other` holds (a parent's gather, pushed to a child).
    pub(super) fn add_all(&mut self, other: &ClusterGather) {
        self.uniform = add(self.uniform, other.uniform);
        for (a, b) in self.by_axis.iter_mut().zip(&other.by_axis) {
            *a = add(*a, *b);
        }
    }

    /// What a face with unit normal `n` below the cluster receives, per channel.
    pub(super) fn at(&self, n: DVec3) -> Rgb {
        let mut g = self.uniform;
        for (bin, w) in self.by_axis.iter().zip(tree::axis_weights(n)) {
            g = add(g, bin.map(|x| w * x));
        }
        g
    }
}

/// A cluster's radiance by the direction it leaves in: the mean over its faces weighted by
/// how much of each faces that way, so that a receiver gathers from the faces turned toward
/// it. The isotropic cluster of Sillion (IEEE TVCG 1995) has one radiance, the area mean: seen
/// from the floor, a desk's cluster would then shine with its lit top rather than its dark
/// underside, and a cluster holding floor and ceiling would light the ceiling with the
/// ceiling's own darkness mixed into the floor's light. The source-side twin of
/// [`ClusterGather`], in the same separable form: a face with unit normal n and seen area A
/// counts A·max(0, ±n_a) in each axis bin, and toward a unit direction d the radiance is
/// Σ_a |d_a| S_bin(a) / Σ_a |d_a| W_bin(a), bin(a) the +a bin where d_a ≥ 0, else −a (exact
/// for faces and directions along the axes; for one flat face, its own radiance whatever d).
#[derive(Clone, Copy, Debug, Default)]
pub struct OrientedRadiance {
    /// Per axis direction (+x, +y, +z, −x, −y, −z): Σ A·max(0, ±n_a), scene units squared.
    weight: [f64; 6],
    /// The same sums times each face's radiance, per channel.
    sum: [Rgb; 6],
}

impl OrientedRadiance {
    /// Adds a face (or element) with unit normal `n`, seen area `area` and radiance `l`.
    pub(super) fn add(&mut self, n: DVec3, area: f64, l: Rgb) {
        for (a, w) in tree::axis_weights(n).into_iter().enumerate() {
            let w = w * area;
            self.weight[a] += w;
            self.sum[a] = add(self.sum[a], l.map(|x| w * x));
        }
    }

    /// Adds everything `other` holds (a child cluster's sums).
    pub(super) fn add_all(&mut self, other: &OrientedRadiance) {
        for a in 0..6 {
            self.weight[a] += other.weight[a];
            self.sum[a] = add(self.sum[a], other.sum[a]);
        }
    }

    /// The radiance leaving toward unit direction `d`. Where no face turns that way by the
    /// bins, the faces along an axis `d` does not move on (|d_a| ≤ [`GRAZING`], either sign)
    /// meet `d` at grazing angles: the bins round their cosines to 0, but a link's form factor,
    /// from true cosines at sampled points, counts them, so they send their own radiance.
    /// With none of those either, every face is turned away from `d` (the direction between
    /// the two ends' centres), yet a link's form factor may count faces that part of its
    /// receiver sees, off that centre: they send the radiance of the faces nearest to facing
    /// `d`, the bin whose direction has the largest component along `d` (ties to the lower
    /// bin). Not 0, which would lose their light (in the closed furnace hall, the faces
    /// gathering through such links read up to a few per cent low, where every face must show
    /// Le/(1 − ρ)), and not the cluster's mean, which would send the light of faces turned
    /// further away (a box whose top alone emits would light the floor under it through the
    /// faces of its sides). 0 from a cluster without seen faces.
    pub(super) fn toward(&self, d: DVec3) -> Rgb {
        let (mut w, mut s) = (0.0, [0.0; 3]);
        for a in 0..3 {
            let bin = axis_bin(d, a);
            let k = d[a].abs();
            w += k * self.weight[bin];
            s = add(s, self.sum[bin].map(|x| k * x));
        }
        if w <= 1e-300 {
            for a in (0..3).filter(|&a| d[a].abs() <= GRAZING) {
                for bin in [a, a + 3] {
                    w += self.weight[bin];
                    s = add(s, self.sum[bin]);
                }
            }
        }
        if w <= 1e-300 {
            // The faces nearest to facing d: bin b < 3 is +b, b ≥ 3 is −(b − 3).
            let along = |b: usize| if b < 3 { d[b] } else { -d[b - 3] };
            let nearest = (0..6)
                .filter(|&b| self.weight[b] > 1e-300)
                .max_by(|&x, &y| along(x).total_cmp(&along(y)).then(y.cmp(&x)));
            return nearest.map_or([0.0; 3], |b| self.sum[b].map(|x| x / self.weight[b]));
        }
        s.map(|x| x / w)
    }
}

/// A unit direction's component along an axis at most this counts as none
/// ([`OrientedRadiance::toward`]): rounding of the centres that give a link's direction.
pub const GRAZING: f64 = 1e-9;

/// The visible-area-weighted mean radiance of (radiance, visible area, area) parts, with their
/// total visible area; the area-weighted mean when nothing is visible.
pub(super) fn weighted_mean(parts: impl Iterator<Item = (Rgb, f64, f64)> + Clone) -> (Rgb, f64) {
    let visible: f64 = parts.clone().map(|p| p.1).sum();
    let by_visible = visible > 0.0;
    let weight = |p: &(Rgb, f64, f64)| if by_visible { p.1 } else { p.2 };
    let total: f64 = parts.clone().map(|p| weight(&p)).sum();
    let sum = parts.fold([0.0; 3], |acc, p| add(acc, p.0.map(|x| weight(&p) * x)));
    (sum.map(|s| s / total), visible)
}

/// The axis bin (+x, +y, +z, −x, −y, −z) of direction `d` along axis `a`: the +a bin where
/// d_a ≥ 0, else −a ([`ClusterGather`], [`OrientedRadiance`]).
fn axis_bin(d: DVec3, a: usize) -> usize {
    if d[a] >= 0.0 {
        a
    } else {
        a + 3
    }
}

pub(super) fn add(a: Rgb, b: Rgb) -> Rgb {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
