//! The hierarchical solve over several ranks ([`crate::distributed`]): who owns what, and the
//! exchanges that keep every rank's copy of the hierarchy the same.
//!
//! Each rank owns a run of root patches ([`Partition`]), so the elements split from them, and
//! the clusters above only its roots (the clusters above roots of several ranks are rank 0's).
//! A rank holds and refines only the links whose receiver it owns, and computes what is per
//! element (burial, direct light, closure) only for its own elements. What every rank needs
//! of the others' work is exchanged:
//!
//! - after elements are made: their burial masks and direct light (once per element);
//! - after each refinement pass: the elements to split, in the order one process splits
//!   them (the links' global order), so every rank's tree is the same tree; and the new
//!   links whose receiver belongs to another rank (below a cluster of several ranks);
//! - every sweep: what each node gathered over its links, only the nodes that gathered
//!   anything. Push-pull then runs on every rank over the whole hierarchy (O(elements),
//!   cheap beside the O(links) gather), so every rank holds every node's radiance, which is
//!   what its links read;
//! - a few times as the links grow: each root's links, to cut the roots again so that each
//!   rank holds about as many links (the first cut knows only counts and areas), and the
//!   links whose receiver changes rank.
//!
//! Every decision of the refinement loop is taken on global counts, so all ranks take it
//! alike; and what a rank computes for a node is what one process computes for it, summed in
//! the same order: the distributed radiance is the one-process radiance, to the bit.

use rayon::prelude::*;

use super::links::Link;
use super::push_pull::ClusterGather;
use super::refine::{link_key, merge_into};
use super::tree::{Node, Tree};
use super::Hierarchy;
use crate::color::Rgb;
use crate::distributed::{Child, Partition, Reader, Writer};

impl Tree {
    /// The root patches split among `ranks` ranks along a depth-first walk of the clusters.
    pub fn partition(&self, ranks: usize) -> Partition {
        let area: Vec<f64> = self.elements[..self.roots].iter().map(|e| e.area).collect();
        let children = |c: usize| self.children_of(c);
        Partition::new(&self.walk(), &area, self.clusters.len(), &children, ranks)
    }

    /// Cluster `c`'s children.
    fn children_of(&self, c: usize) -> Vec<Child> {
        self.kids(c)
            .iter()
            .map(|k| match k.as_element() {
                Some(e) => Child::Root(e),
                None => Child::Cluster(k.as_cluster().unwrap()),
            })
            .collect()
    }

    /// The root patches in the order a depth-first walk of the clusters meets them: the
    /// roots below any cluster are consecutive.
    fn walk(&self) -> Vec<usize> {
        let mut order = Vec::with_capacity(self.roots);
        if self.clusters.is_empty() {
            order.extend(0..self.roots);
        } else {
            let mut stack = vec![Child::Cluster(0)];
            while let Some(node) = stack.pop() {
                match node {
                    Child::Root(e) => order.push(e),
                    Child::Cluster(c) => stack.extend(self.children_of(c).into_iter().rev()),
                }
            }
        }
        order
    }
}

impl Hierarchy<'_> {
    /// The rank owning node `n`: its root's for an element, [`Partition::cluster_owner`] for a
    /// cluster; 0 in a solve of one rank.
    pub(super) fn owner(&self, n: Node) -> u32 {
        let Some(p) = &self.partition else { return 0 };
        match n.as_element() {
            Some(e) => p.root_rank[self.tree.elements[e].root as usize],
            None => p.cluster_owner(n.as_cluster().unwrap()),
        }
    }

    /// True when this rank owns node `n` (always in a solve of one rank).
    pub(super) fn owns(&self, n: Node) -> bool {
        self.partition.is_none() || self.owner(n) == self.comm.rank() as u32
    }

    /// True when this rank owns element `e`.
    pub(super) fn owns_element(&self, e: usize) -> bool {
        self.owns(Node::element(e))
    }

    /// `mine` holds a value for each element from `from` on, right for the elements this rank
    /// owns (anything for the others'): returns every element's right value, each from its
    /// owner. `write` and `read` code one value.
    pub(super) fn owners_values<T>(
        &self,
        from: usize,
        mut mine: Vec<T>,
        write: impl Fn(&mut Writer, &T),
        read: impl Fn(&mut Reader) -> T,
    ) -> Vec<T> {
        if self.partition.is_none() {
            return mine;
        }
        let rank = self.comm.rank() as u32;
        let mut w = Writer::default();
        for (i, v) in mine.iter().enumerate() {
            if self.owner(Node::element(from + i)) == rank {
                write(&mut w, v);
            }
        }
        let all = self.comm.all_gather(&w.0);
        let mut readers: Vec<Reader> = all.iter().map(Reader::new).collect();
        for (i, v) in mine.iter_mut().enumerate() {
            let k = self.owner(Node::element(from + i));
            let value = read(&mut readers[k as usize]);
            if k != rank {
                *v = value;
            }
        }
        mine
    }

    /// Links, summed over the ranks.
    pub(super) fn link_count(&self) -> u64 {
        self.comm.sum_u64(self.links.len() as u64)
    }

    /// The most links any rank holds.
    pub(super) fn most_links(&self) -> u64 {
        self.comm.max_u64(self.links.len() as u64)
    }

    /// Every rank's elements to split (each list in the order its rank found them), in the
    /// order one process would split them: `direct` (elements, ascending) first, then
    /// `by_link` (the link's receiver and source, and the element), by the links' order.
    pub(super) fn splits_in_order(
        &self,
        direct: Vec<usize>,
        by_link: Vec<(Node, Node, usize)>,
    ) -> Vec<usize> {
        if self.partition.is_none() {
            return direct
                .into_iter()
                .chain(by_link.into_iter().map(|(_, _, e)| e))
                .collect();
        }
        let mut w = Writer::default();
        w.u64(direct.len() as u64);
        for &e in &direct {
            w.u32(e as u32);
        }
        for &(r, s, e) in &by_link {
            w.u32(r.raw());
            w.u32(s.raw());
            w.u32(e as u32);
        }
        let all = self.comm.all_gather(&w.0);
        let (mut direct, mut by_link) = (Vec::new(), Vec::new());
        for bytes in all.iter() {
            let mut r = Reader::new(bytes);
            for _ in 0..r.u64() {
                direct.push(r.u32() as usize);
            }
            while !r.done() {
                by_link.push((Node::from_raw(r.u32()), Node::from_raw(r.u32()), r.u32()));
            }
        }
        // Disjoint sets (an element is its owner's; a link its receiver's): sorted, each is in
        // one process's order.
        direct.sort_unstable();
        by_link.sort_unstable_by_key(|&(r, s, _)| (r, s));
        direct
            .into_iter()
            .chain(by_link.into_iter().map(|(_, _, e)| e as usize))
            .collect()
    }

    /// The new links this rank made whose receiver another rank owns go to it; returns the
    /// links this rank is to hold (its own new ones and those the others made for it).
    pub(super) fn to_receivers(&self, new: Vec<Link>) -> Vec<Link> {
        if self.partition.is_none() {
            return new;
        }
        let (mut mine, theirs): (Vec<Link>, Vec<Link>) =
            new.into_iter().partition(|l| self.owns(l.receiver));
        mine.extend(self.send_links(&theirs));
        mine
    }

    /// Sends `theirs` (links whose receiver another rank owns) to their ranks; returns the
    /// links the other ranks sent this one.
    fn send_links(&self, theirs: &[Link]) -> Vec<Link> {
        let mut w = Writer::default();
        for l in theirs {
            w.u32(l.receiver.raw());
            w.u32(l.source.raw());
            w.f32(l.f);
            w.f32(l.bound);
            w.bytes(&l.children);
        }
        let all = self.comm.all_gather(&w.0);
        let mut links = Vec::new();
        for (k, bytes) in all.iter().enumerate() {
            if k == self.comm.rank() {
                continue;
            }
            let mut r = Reader::new(bytes);
            while !r.done() {
                let l = Link {
                    receiver: Node::from_raw(r.u32()),
                    source: Node::from_raw(r.u32()),
                    f: r.f32(),
                    bound: r.f32(),
                    children: r.bytes(),
                };
                if self.owns(l.receiver) {
                    links.push(l);
                }
            }
        }
        links
    }

    /// Cuts the roots among the ranks again, weighing each by the links into it (a link into
    /// a cluster weighs on every root below it alike), and moves the links whose receiver
    /// changes rank. The first cut ([`Tree::partition`]) knows only the roots' count and
    /// area, and the links per root vary several-fold with what a root sees. Every element's
    /// data is on every rank already, so only links move; the result is unchanged (whichever
    /// rank holds a node's links, it gathers them in their order).
    pub(super) fn rebalance(&mut self) {
        if self.partition.is_none() {
            return;
        }
        // Nothing to gain where the links are about even already.
        let held = self.comm.gather_u64(self.links.len() as u64);
        let mean = held.iter().sum::<u64>() as f64 / held.len() as f64;
        if held.iter().all(|&k| k as f64 <= EVEN_ENOUGH * mean) {
            return;
        }
        self.stats.rebalances += 1;
        let t = &self.tree;
        let n = t.roots;
        let walk = t.walk();
        let mut position = vec![0usize; n];
        for (i, &r) in walk.iter().enumerate() {
            position[r] = i;
        }
        // Each cluster's roots are a run of the walk.
        let mut span = vec![(usize::MAX, 0usize); t.clusters.len()];
        for c in (0..t.clusters.len()).rev() {
            let (mut a, mut b) = (usize::MAX, 0);
            for child in t.children_of(c) {
                let (x, y) = match child {
                    Child::Root(r) => (position[r], position[r] + 1),
                    Child::Cluster(k) => span[k],
                };
                (a, b) = (a.min(x), b.max(y));
            }
            span[c] = (a, b);
        }
        // This rank's links, spread over the walk's positions (a difference array).
        let mut diff = vec![0.0f64; n + 1];
        for l in &self.links {
            let (a, b) = match l.receiver.as_element() {
                Some(e) => {
                    let p = position[t.elements[e].root as usize];
                    (p, p + 1)
                }
                None => span[l.receiver.as_cluster().unwrap()],
            };
            let x = 1.0 / (b - a) as f64;
            diff[a] += x;
            diff[b] -= x;
        }
        let mut w = Writer::default();
        let mut run = 0.0;
        for d in &diff[..n] {
            run += d;
            w.f32(run as f32);
        }
        let all = self.comm.all_gather(&w.0);
        let mut by_position = vec![0.0f64; n];
        for bytes in all.iter() {
            let mut r = Reader::new(bytes);
            by_position.iter_mut().for_each(|x| *x += r.f32() as f64);
        }
        // A root with no link yet still costs its direct light and burial rays.
        let floor = 0.1 * by_position.iter().sum::<f64>() / n.max(1) as f64;
        let mut weight = vec![0.0; n];
        for (i, &r) in walk.iter().enumerate() {
            weight[r] = by_position[i].max(0.0) + floor;
        }
        let children = |c: usize| t.children_of(c);
        let cut = Partition::cut(
            &walk,
            &weight,
            t.clusters.len(),
            &children,
            self.comm.size(),
        );
        self.partition = Some(cut);
        let links = std::mem::take(&mut self.links);
        // The links kept are still in order: the received ones are sorted and merged in.
        let (mut mine, theirs): (Vec<Link>, Vec<Link>) =
            links.into_iter().partition(|l| self.owns(l.receiver));
        let mut received = self.send_links(&theirs);
        received.par_sort_unstable_by_key(link_key);
        merge_into(&mut mine, received);
        self.set_links(mine);
    }

    /// Every rank's gathers made whole: each node's gather is its owner's (the only rank
    /// with links into it); only the nodes that gathered anything are sent.
    pub(super) fn share_gathers(&self, ge: &mut [Rgb], gc: &mut [ClusterGather]) {
        if self.partition.is_none() {
            return;
        }
        let start = std::time::Instant::now();
        let nonzero = |x: &[f64]| x.iter().any(|v| v.to_bits() != 0);
        let mut w = Writer::default();
        let elements: Vec<usize> = (0..ge.len()).filter(|&e| nonzero(&ge[e])).collect();
        w.u64(elements.len() as u64);
        for e in elements {
            w.u32(e as u32);
            ge[e].iter().for_each(|&x| w.f64(x));
        }
        for (c, g) in gc.iter().enumerate() {
            let a = g.to_array();
            if nonzero(&a) {
                w.u32(c as u32);
                a.iter().for_each(|&x| w.f64(x));
            }
        }
        let all = self.comm.all_gather(&w.0);
        // What this rank sent is in `all` too: freed before the rest is read (at 10⁶
        // triangles a sweep's exchange is about 70 MB in all).
        let sent = w.0.len() as u64;
        drop(w);
        for (k, bytes) in all.iter().enumerate() {
            if k == self.comm.rank() {
                continue;
            }
            let mut r = Reader::new(bytes);
            for _ in 0..r.u64() {
                let e = r.u32() as usize;
                ge[e] = [r.f64(), r.f64(), r.f64()];
            }
            while !r.done() {
                let c = r.u32() as usize;
                gc[c] = ClusterGather::from_array(std::array::from_fn(|_| r.f64()));
            }
        }
        use std::sync::atomic::Ordering::Relaxed;
        self.sweep_exchange[0].fetch_add(sent, Relaxed);
        self.sweep_exchange[1].fetch_add(start.elapsed().as_nanos() as u64, Relaxed);
    }
}

/// A rebalance moves no link while every rank holds at most this many times the mean.
const EVEN_ENOUGH: f64 = 1.05;
