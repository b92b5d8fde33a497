//! Refinement of the links (HSA91 §4): every link asks the oracle ([`super::links`]) whether
//! it may carry more than ε of the emitted power; a link that must be finer is replaced by
//! links one level down (the larger end split: elements 1 → 4 down to the minimum area,
//! clusters into their children), each estimated afresh. Leaves whose own direct light varies
//! by more than ε are split too ([`Hierarchy::direct_splits`]). Once the links are final, each
//! finds its shares through its source's grandchildren, so the final solve gathers its source
//! two levels down ([`super::links::grandchild_shares`]).

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use super::links::{self, Action, Link};
use super::tree::{self, Node};
use super::Hierarchy;

impl Hierarchy<'_> {
    /// One refinement pass: every link asks the oracle; links that must be finer are replaced
    /// by links one level down (elements split as needed, in link order: deterministic).
    /// Returns whether anything changed.
    pub fn refine_pass(&mut self) -> bool {
        let actions: Vec<Action> = self
            .links
            .par_iter()
            .map(|l| {
                if !self.refines(l.receiver) {
                    return Action::Keep;
                }
                // Bounded by the brightest leaf below the source, not its mean: a link from a
                // cluster gathers its area-mean radiance, which dilutes a small light among
                // dark surfaces the receiver may not see at all (energy lost). With the bound,
                // what that can take away is at most the power the oracle allows.
                let ls = self.max_radiance(l.source);
                links::oracle(
                    &self.tree,
                    l,
                    |n| self.max_reflectance(n),
                    ls,
                    self.epsilon,
                    self.min_area,
                )
            })
            .collect();
        let direct_splits = self.direct_splits();
        let changed = actions.iter().any(|&a| a != Action::Keep) || !direct_splits.is_empty();
        // Over several ranks: whether any rank changed anything ([`super::ranks`]).
        if !self.comm.any(changed) {
            return false;
        }
        // The elements that must be split: for the direct light, then in link order (over
        // several ranks, every rank's, in the order one process finds them).
        let by_link = self
            .links
            .iter()
            .zip(&actions)
            .filter_map(|(l, &a)| {
                let node = match a {
                    Action::SplitReceiver => l.receiver,
                    Action::SplitSource => l.source,
                    _ => return None,
                };
                node.as_element().map(|e| (l.receiver, l.source, e))
            })
            .collect();
        for e in self.splits_in_order(direct_splits, by_link) {
            if self.tree.elements[e].first_child == tree::NO_CHILD {
                self.tree.split(e);
            }
        }
        self.update_new_elements();
        // The kept links compacted in place (a second list of them would double the peak
        // memory at the largest scenes: 6·10⁷ links are 1.2 GB), the others replaced by pairs
        // one level down, estimated a chunk of links at a time: the largest pass of a solve
        // at 10⁶ triangles makes about 10⁷ new links, and a list of all their pairs and
        // estimates beside the new links would raise the peak by 200 MB.
        let mut kept = std::mem::take(&mut self.links);
        let n = kept.len();
        let mut new = Vec::new();
        let rays = self.settings.rays as usize;
        let cast = AtomicU64::new(0);
        let mut w = 0;
        let mut pairs = Vec::new();
        for chunk in (0..n).step_by(REFINE_CHUNK) {
            pairs.clear();
            for i in chunk..(chunk + REFINE_CHUNK).min(n) {
                let l = kept[i];
                match actions[i] {
                    Action::Keep => {
                        // w ≤ i: only links already read are overwritten.
                        kept[w] = l;
                        w += 1;
                    }
                    Action::SplitReceiver => {
                        for c in self.tree.children(l.receiver) {
                            pairs.push((c, l.source));
                        }
                    }
                    Action::SplitSource => {
                        for c in self.tree.children(l.source) {
                            pairs.push((l.receiver, c));
                        }
                    }
                    Action::SplitBoth => {
                        let kids = self.tree.children(l.receiver);
                        for &a in &kids {
                            for &b in &kids {
                                pairs.push((a, b));
                            }
                        }
                    }
                }
            }
            let estimates: Vec<Option<Link>> = pairs
                .par_iter()
                .map(|&(r, s)| {
                    let e = links::estimate(
                        &self.tree,
                        self.occluders(),
                        r,
                        s,
                        rays,
                        self.burial(),
                        self.seed,
                    );
                    cast.fetch_add(e.rays, Ordering::Relaxed);
                    e.link.map(|mut l| {
                        l.f *= self.coverage(l.source) as f32;
                        l
                    })
                })
                .collect();
            // Room for exactly this chunk (growth by doubling could leave as much again
            // unused).
            new.reserve_exact(estimates.len());
            new.extend(estimates.into_iter().flatten());
        }
        kept.truncate(w);
        kept.shrink_to_fit();
        drop(actions);
        self.stats.rays_cast += cast.into_inner();
        // Links into another rank's nodes (below a cluster of several ranks) go to it.
        let mut new = self.to_receivers(new);
        // The kept links are still in order: sort the new ones and merge (a full sort of all
        // links every pass would be a large share of a fine solve's time).
        new.par_sort_unstable_by_key(link_key);
        merge_into(&mut kept, new);
        self.set_links(kept);
        // New elements start at their parent's radiance (so the oracle sees light there).
        let n_old = self.elem_l.len();
        for e in n_old..self.tree.elements.len() {
            let p = self.tree.elements[e].parent as usize;
            self.elem_l.push(self.elem_l[p]);
            self.elem_max.push(self.elem_max[p]);
        }
        // A closed scene's row sums, found again before the next sweep needs them
        // ([`Hierarchy::sweep`]): a pass that no sweep follows costs no gather of them.
        if self.stats.closed_scene {
            self.rows_stale = true;
        }
        true
    }

    /// Replaces the links, sorted by receiver (then source), and finds each node's run.
    pub(super) fn set_links(&mut self, links: Vec<Link>) {
        debug_assert!(links.windows(2).all(|w| link_key(&w[0]) < link_key(&w[1])));
        self.grandchild_shares = GrandchildShares::default();
        self.near.clear();
        // Elements first, then clusters, as the links sort.
        let elements = self.tree.elements.len();
        let nodes = elements + self.tree.clusters.len();
        let index = |n: Node| match n.as_element() {
            Some(e) => e,
            None => elements + n.as_cluster().unwrap(),
        };
        self.first_link.clear();
        self.first_link.reserve_exact(nodes + 1);
        for (i, l) in links.iter().enumerate() {
            let r = index(l.receiver);
            while self.first_link.len() <= r {
                self.first_link.push(i);
            }
        }
        self.first_link.resize(nodes + 1, links.len());
        self.links = links;
        self.links.shrink_to_fit();
    }

    /// The leaves whose direct light varies over them by more than ε allows (ρ · spread · A
    /// above ε, the largest channels; [`direct::Direct::spread`]) and that can still be
    /// split: the direct light's own refinement, where a shadow edge or the fall-off next to
    /// a light crosses a leaf, whatever its links.
    pub(super) fn direct_splits(&self) -> Vec<usize> {
        if self.emitters.is_empty() && !self.env.has_sharp() {
            return Vec::new();
        }
        let t = &self.tree;
        (0..t.elements.len())
            .into_par_iter()
            .filter(|&e| {
                let el = &t.elements[e];
                el.first_child == tree::NO_CHILD
                    && self.owns_element(e)
                    && 0.25 * el.area >= self.min_area
                    && self.refines(Node::element(e))
                    && self.max_reflectance(Node::element(e)) * self.direct[e].spread * el.area
                        > self.epsilon
            })
            .collect()
    }

    /// Finds [`Hierarchy::grandchild_shares`] for the current links.
    pub(super) fn find_grandchild_shares(&mut self) {
        let t = &self.tree;
        // Only links from a source whose children are split have shares: a first pass finds
        // them, so memory goes to those alone (a bit a link, 16 bytes for each such link).
        let deep = |l: &Link| match (l.receiver.as_element(), l.source.as_element()) {
            (Some(r), Some(s)) => {
                let first = t.elements[s].first_child;
                let split = first != tree::NO_CHILD
                    && (first..first + 4)
                        .any(|c| t.elements[c as usize].first_child != tree::NO_CHILD);
                split.then_some((r, s))
            }
            _ => None,
        };
        let has: Vec<u64> = self
            .links
            .par_chunks(64)
            .map(|chunk| {
                chunk.iter().enumerate().fold(0u64, |word, (b, l)| {
                    word | ((deep(l).is_some() as u64) << b)
                })
            })
            .collect();
        let mut before = Vec::with_capacity(has.len());
        let mut count = 0u32;
        for word in &has {
            before.push(count);
            count += word.count_ones();
        }
        // Filled in place, a run of words at a time: a list of the (receiver, source) pairs
        // beside the shares would add 16 bytes a link with shares to the solve's peak memory
        // (at 10⁶ triangles, 130 MB).
        const WORDS: usize = 1024;
        let mut shares = vec![[0u8; 16]; count as usize];
        let mut runs = Vec::with_capacity(has.len().div_ceil(WORDS));
        let mut rest = shares.as_mut_slice();
        for words in has.chunks(WORDS) {
            let n: u32 = words.iter().map(|w| w.count_ones()).sum();
            let (run, tail) = rest.split_at_mut(n as usize);
            runs.push(run);
            rest = tail;
        }
        runs.into_par_iter()
            .zip(self.links.par_chunks(64 * WORDS))
            .for_each(|(run, links)| {
                let mut out = run.iter_mut();
                for (r, s) in links.iter().filter_map(deep) {
                    *out.next().unwrap() = links::grandchild_shares(t, r, s);
                }
            });
        self.grandchild_shares = GrandchildShares {
            has,
            before,
            shares,
        };
    }

    /// Whether links with `node` as receiver are refined: always, but in a pilot's sampling
    /// phase only where its sample holds the receiver ([`super::pilot`]).
    pub(super) fn refines(&self, node: Node) -> bool {
        self.sample
            .as_ref()
            .is_none_or(|s| !s.active || s.holds(&self.tree, node))
    }

    /// Largest reflectance channel of a node.
    pub(super) fn max_reflectance(&self, node: Node) -> f64 {
        match node.as_element() {
            Some(e) => {
                let r = self.tree.elements[e].root as usize;
                self.roots.reflectance[r]
                    .iter()
                    .copied()
                    .fold(0.0, f64::max)
            }
            None => self.tree.clusters[node.as_cluster().unwrap()].max_reflectance,
        }
    }

    /// The brightest channel of any leaf below `node`, W·sr⁻¹·m⁻².
    pub(super) fn max_radiance(&self, node: Node) -> f64 {
        match node.as_element() {
            Some(e) => self.elem_max[e],
            None => self.cluster_max[node.as_cluster().unwrap()],
        }
    }
}

/// The shares of each link's form factor through its element source's 16 grandchildren
/// ([`links::grandchild_shares`]), for the links whose source's children are split. Which
/// links have shares is a bit per link, and a link's place among `shares` the number of set
/// bits before it (a rank): an index per link would take 4 bytes a link, 150 MB at 10⁶
/// triangles, where few links have shares.
#[derive(Debug, Default)]
pub(super) struct GrandchildShares {
    /// Bit i % 64 of word i / 64: link i has shares.
    has: Vec<u64>,
    /// Per word of `has`: the set bits in the words before it.
    before: Vec<u32>,
    shares: Vec<[u8; 16]>,
}

impl GrandchildShares {
    /// Link `i`'s shares, if it has any.
    pub(super) fn get(&self, i: usize) -> Option<&[u8; 16]> {
        let (w, b) = (i / 64, i % 64);
        let word = *self.has.get(w)?;
        if word & (1 << b) == 0 {
            return None;
        }
        let below = (word & ((1u64 << b) - 1)).count_ones();
        self.shares.get((self.before[w] + below) as usize)
    }
}

/// Links refined a chunk at a time ([`Hierarchy::refine_pass`]): enough pairs for the threads
/// to share, few enough that their list and estimates take little memory.
const REFINE_CHUNK: usize = 1 << 18;

/// The order of the links: by receiver, then source (each pair at most once).
pub(super) fn link_key(l: &Link) -> (Node, Node) {
    (l.receiver, l.source)
}

/// Merges `b` into `a`, both sorted by [`link_key`], in place: from the back, into the room
/// `a` reserves at its end, so no third list is made (at 10⁷ links a copy is 240 MB).
pub(super) fn merge_into(a: &mut Vec<Link>, b: Vec<Link>) {
    let (n, m) = (a.len(), b.len());
    // Exactly the room needed: amortised doubling would leave up to as much again unused
    // (at 6·10⁷ links, 1.4 GB).
    a.reserve_exact(m);
    a.extend_from_slice(&b); // the room, overwritten below
    let (mut i, mut j, mut k) = (n, m, n + m);
    while j > 0 {
        k -= 1;
        if i > 0 && link_key(&a[i - 1]) > link_key(&b[j - 1]) {
            a[k] = a[i - 1];
            i -= 1;
        } else {
            a[k] = b[j - 1];
            j -= 1;
        }
    }
}
