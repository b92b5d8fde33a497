//! One bake over several processes: what the ranks of a distributed bake exchange, and how
//! the work is split among them. This module owns the [`Exchange`] the hierarchical solve
//! talks through, the one-process [`Solo`], an in-process group of ranks on threads
//! ([`Threads`], which the tests use to check a distributed solve against the one-process
//! solve without MPI), the byte codec of what is exchanged, and the [`Partition`] of the
//! root patches among the ranks.
//!
//! The library has no MPI in it: the command line's `mpi` feature implements [`Exchange`]
//! over MPI (rsmpi), and the library only ever calls the two collectives below. Every rank
//! runs the same control flow (each collective is reached by every rank, in the same order),
//! holds the same element tree and node radiance, and holds only the links whose receiver it
//! owns (see [`crate::hierarchical`]): so the radiance every rank computes is the one a
//! single process computes, to the bit, for any number of ranks.

use std::sync::{Arc, Barrier, Mutex};

/// The collectives a distributed bake needs. Every rank must call each collective, in the
/// same order: a rank that skips one leaves the others waiting.
pub trait Exchange: Sync {
    /// This process's rank, in `0..size()`.
    fn rank(&self) -> usize;
    /// The number of ranks, ≥ 1.
    fn size(&self) -> usize;
    /// Every rank's `mine`, in rank order (an all-gather of byte strings of any length).
    fn all_gather(&self, mine: &[u8]) -> Parts;
}

/// What an all-gather returns: every rank's bytes, in rank order, in one buffer (a list of
/// one buffer per rank would be a second copy of all of them: at 10⁶ triangles a sweep
/// gathers about 70 MB).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Parts {
    bytes: Vec<u8>,
    /// Where each rank's part ends in `bytes`; ascending, the last is `bytes.len()`.
    ends: Vec<usize>,
}

impl Parts {
    /// The parts in rank order, one after the other in `bytes`, part k ending at `ends[k]`.
    /// Panics unless `ends` ascends to `bytes.len()` (a bug of the caller).
    pub fn new(bytes: Vec<u8>, ends: Vec<usize>) -> Parts {
        assert!(
            ends.windows(2).all(|w| w[0] <= w[1])
                && ends.last().copied().unwrap_or(0) == bytes.len(),
            "all-gather parts out of order"
        );
        Parts { bytes, ends }
    }

    /// The number of parts (ranks).
    pub fn len(&self) -> usize {
        self.ends.len()
    }

    /// True with no part at all.
    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }

    /// Rank k's bytes.
    pub fn part(&self, k: usize) -> &[u8] {
        let start = if k == 0 { 0 } else { self.ends[k - 1] };
        &self.bytes[start..self.ends[k]]
    }

    /// Every rank's bytes, in rank order.
    pub fn iter(&self) -> impl Iterator<Item = &[u8]> {
        (0..self.len()).map(|k| self.part(k))
    }
}

impl<'a> FromIterator<&'a [u8]> for Parts {
    fn from_iter<I: IntoIterator<Item = &'a [u8]>>(iter: I) -> Parts {
        let mut p = Parts::default();
        for part in iter {
            p.bytes.extend_from_slice(part);
            p.ends.push(p.bytes.len());
        }
        p
    }
}

impl dyn Exchange + '_ {
    /// True when every rank is this one (no exchange is needed).
    pub fn alone(&self) -> bool {
        self.size() == 1
    }

    /// True on every rank if `x` is true on any.
    pub fn any(&self, x: bool) -> bool {
        if self.alone() {
            return x;
        }
        self.all_gather(&[x as u8]).iter().any(|b| b[0] != 0)
    }

    /// Every rank's `x`, in rank order.
    pub fn gather_u64(&self, x: u64) -> Vec<u64> {
        if self.alone() {
            return vec![x];
        }
        self.all_gather(&x.to_le_bytes())
            .iter()
            .map(|b| Reader::new(b).u64())
            .collect()
    }

    /// Σ `x` over the ranks, added in rank order (the same sum on every rank).
    pub fn sum_f64(&self, x: f64) -> f64 {
        if self.alone() {
            return x;
        }
        self.all_gather(&x.to_le_bytes())
            .iter()
            .map(|b| Reader::new(b).f64())
            .sum()
    }

    /// Σ `x` over the ranks.
    pub fn sum_u64(&self, x: u64) -> u64 {
        self.gather_u64(x).iter().sum()
    }

    /// `f(i)` for every `i` in `0..n`, each rank computing a consecutive share of them (in
    /// parallel on its threads), then every rank holding all of them: what
    /// `(0..n).into_par_iter().map(f).collect()` gives one process, value for value, when
    /// `f(i)` depends on `i` alone (its random numbers keyed by `i`, not by a thread).
    /// `write` and `read` code one value.
    pub fn map_shared<T: Send>(
        &self,
        n: usize,
        f: impl Fn(usize) -> T + Sync + Send,
        write: impl Fn(&T, &mut Writer),
        read: impl Fn(&mut Reader) -> T,
    ) -> Vec<T> {
        use rayon::prelude::*;
        if self.alone() {
            return (0..n).into_par_iter().map(f).collect();
        }
        let share = |k: usize| n * k / self.size()..n * (k + 1) / self.size();
        let mut mine: Vec<T> = share(self.rank()).into_par_iter().map(&f).collect();
        let mut w = Writer::default();
        mine.iter().for_each(|v| write(v, &mut w));
        let all = self.all_gather(&w.0);
        let mut out = Vec::with_capacity(n);
        for (k, bytes) in all.iter().enumerate() {
            if k == self.rank() {
                out.append(&mut mine);
            } else {
                let mut r = Reader::new(bytes);
                out.extend(share(k).map(|_| read(&mut r)));
            }
        }
        out
    }

    /// The smallest `x` over the ranks.
    pub fn min_u64(&self, x: u64) -> u64 {
        self.gather_u64(x).into_iter().min().unwrap_or(x)
    }

    /// The largest `x` over the ranks.
    pub fn max_u64(&self, x: u64) -> u64 {
        self.gather_u64(x).into_iter().max().unwrap_or(x)
    }
}

/// One process: the rank 0 of 1; exchanges nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Solo;

impl Exchange for Solo {
    fn rank(&self) -> usize {
        0
    }
    fn size(&self) -> usize {
        1
    }
    fn all_gather(&self, mine: &[u8]) -> Parts {
        Parts::new(mine.to_vec(), vec![mine.len()])
    }
}

/// A group of ranks in one process, one per thread ([`Threads::group`], [`Threads::run`]):
/// the collectives meet at a barrier. For tests and experiments: the solve run over N of
/// these is the solve over N MPI ranks, without MPI.
pub struct Threads {
    rank: usize,
    shared: Arc<Shared>,
}

struct Shared {
    ranks: usize,
    barrier: Barrier,
    slots: Mutex<Vec<Vec<u8>>>,
}

impl Threads {
    /// `n` ranks (n ≥ 1) of one group; give each to its own thread.
    pub fn group(n: usize) -> Vec<Threads> {
        assert!(n >= 1, "a group has at least one rank");
        let shared = Arc::new(Shared {
            ranks: n,
            barrier: Barrier::new(n),
            slots: Mutex::new(vec![Vec::new(); n]),
        });
        (0..n)
            .map(|rank| Threads {
                rank,
                shared: shared.clone(),
            })
            .collect()
    }

    /// `f` run by every rank of a new group of `n`, each on its own thread: every rank's
    /// result, in rank order. A rank's panic is raised again here.
    pub fn run<T: Send>(n: usize, f: impl Fn(&Threads) -> T + Sync) -> Vec<T> {
        let group = Threads::group(n);
        std::thread::scope(|s| {
            let f = &f;
            let handles: Vec<_> = group.iter().map(|t| s.spawn(move || f(t))).collect();
            handles
                .into_iter()
                .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
                .collect()
        })
    }
}

impl Exchange for Threads {
    fn rank(&self) -> usize {
        self.rank
    }
    fn size(&self) -> usize {
        self.shared.ranks
    }
    fn all_gather(&self, mine: &[u8]) -> Parts {
        // Write, wait for all writes, read, wait for all reads (so no rank overwrites its
        // slot with the next collective's bytes before the others have read this one's).
        self.shared.slots.lock().expect("slots")[self.rank] = mine.to_vec();
        self.shared.barrier.wait();
        let all: Parts = self
            .shared
            .slots
            .lock()
            .expect("slots")
            .iter()
            .map(|b| b.as_slice())
            .collect();
        self.shared.barrier.wait();
        all
    }
}

/// Little-endian writer of what ranks exchange.
#[derive(Debug, Default)]
pub struct Writer(pub Vec<u8>);

impl Writer {
    pub fn u32(&mut self, x: u32) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    pub fn u64(&mut self, x: u64) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    pub fn f32(&mut self, x: f32) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    pub fn f64(&mut self, x: f64) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    pub fn bytes(&mut self, x: &[u8]) {
        self.0.extend_from_slice(x);
    }
}

/// Reader of what a [`Writer`] wrote, in the same order. Reading past the end is a bug in
/// the caller (the ranks run the same code), so it panics.
#[derive(Debug)]
pub struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    pub fn new(bytes: &'a [u8]) -> Self {
        Reader { bytes, at: 0 }
    }
    /// True when everything was read.
    pub fn done(&self) -> bool {
        self.at >= self.bytes.len()
    }
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let b: [u8; N] = self.bytes[self.at..self.at + N]
            .try_into()
            .expect("N bytes");
        self.at += N;
        b
    }
    pub fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    pub fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }
    pub fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.take())
    }
    pub fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }
    pub fn bytes<const N: usize>(&mut self) -> [u8; N] {
        self.take()
    }
}

/// Which rank owns each root patch: the roots in the order a depth-first walk of the
/// cluster BVH meets them (so nearby roots are consecutive), cut into `ranks` consecutive
/// runs of about equal weight. At first ([`Partition::new`]) a root weighs 1/n + A/ΣA: its
/// count stands for the per-root work (closure probes, the direct light at its rule points),
/// its area share for the elements refinement makes of it; the solve cuts again by the links
/// (`hierarchical`'s rebalance, [`Partition::cut`]). Each run is a few whole subtrees of the
/// BVH, and only the clusters on the paths between the cuts hold roots of two ranks.
#[derive(Debug, Clone, PartialEq)]
pub struct Partition {
    /// Per root patch, its rank.
    pub root_rank: Vec<u32>,
    /// Per cluster: the rank owning all the roots below it, or [`MIXED`] when they belong to
    /// several ranks (such a cluster's links as receiver are rank 0's).
    pub cluster_rank: Vec<u32>,
}

/// [`Partition::cluster_rank`] of a cluster above roots of more than one rank.
pub const MIXED: u32 = u32::MAX;

impl Partition {
    /// The first partition of `order` (every root once, in the walk's order; `area` per root)
    /// and of the `clusters` clusters whose children `children(c)` gives (as roots or
    /// clusters; parents numbered before children) among `ranks` ranks: each root weighs
    /// 1/n + A/ΣA.
    pub fn new(
        order: &[usize],
        area: &[f64],
        clusters: usize,
        children: &dyn Fn(usize) -> Vec<Child>,
        ranks: usize,
    ) -> Partition {
        let n = area.len();
        let total_area: f64 = area.iter().sum();
        let weight: Vec<f64> = (0..n)
            .map(|r| {
                1.0 / n as f64
                    + if total_area > 0.0 {
                        area[r] / total_area
                    } else {
                        1.0 / n as f64
                    }
            })
            .collect();
        Partition::cut(order, &weight, clusters, children, ranks)
    }

    /// [`Partition::new`] with each root's weight given (`weight[r]` ≥ 0).
    pub fn cut(
        order: &[usize],
        weight: &[f64],
        clusters: usize,
        children: &dyn Fn(usize) -> Vec<Child>,
        ranks: usize,
    ) -> Partition {
        let total: f64 = order.iter().map(|&r| weight[r]).sum();
        let mut root_rank = vec![0u32; weight.len()];
        let mut before = 0.0;
        for &r in order {
            // The rank whose share of the total the middle of this root falls in.
            let mid = before + 0.5 * weight[r];
            let share = if total > 0.0 { mid / total } else { 0.0 };
            root_rank[r] = ((share * ranks as f64) as usize).min(ranks - 1) as u32;
            before += weight[r];
        }
        let mut cluster_rank = vec![MIXED; clusters];
        for c in (0..clusters).rev() {
            let mut rank = None;
            for child in children(c) {
                let r = match child {
                    Child::Root(r) => root_rank[r],
                    Child::Cluster(k) => cluster_rank[k],
                };
                rank = match rank {
                    None => Some(r),
                    Some(x) if x == r => Some(x),
                    _ => Some(MIXED),
                };
            }
            cluster_rank[c] = rank.unwrap_or(0);
        }
        Partition {
            root_rank,
            cluster_rank,
        }
    }

    /// The rank holding the links into cluster `c`.
    pub fn cluster_owner(&self, c: usize) -> u32 {
        match self.cluster_rank[c] {
            MIXED => 0,
            r => r,
        }
    }
}

/// A child of a cluster, for [`Partition::new`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Child {
    Root(usize),
    Cluster(usize),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_thread_group_gathers_every_ranks_bytes_in_rank_order_every_time() {
        let out = Threads::run(3, |t| {
            // Two collectives in a row: the second must not see the first's bytes.
            let _ = t.all_gather(&[t.rank() as u8; 2]);
            let e: &dyn Exchange = t;
            assert_eq!(e.sum_u64(t.rank() as u64 + 1), 6);
            assert!(e.any(t.rank() == 2));
            assert!(!e.any(false));
            t.all_gather(&vec![7; t.rank()])
        });
        for o in out {
            assert_eq!(o.iter().collect::<Vec<_>>(), [&[][..], &[7], &[7, 7]]);
        }
    }

    #[test]
    fn a_partition_gives_consecutive_runs_and_marks_the_clusters_between_them() {
        // Four equal roots under two clusters of two, under a root cluster.
        let children = [
            vec![Child::Cluster(1), Child::Cluster(2)],
            vec![Child::Root(0), Child::Root(1)],
            vec![Child::Root(2), Child::Root(3)],
        ];
        let order = [0, 1, 2, 3];
        let kids = |c: usize| children[c].clone();
        let p = Partition::new(&order, &[1.0; 4], 3, &kids, 2);
        assert_eq!(p.root_rank, vec![0, 0, 1, 1]);
        assert_eq!(p.cluster_rank, vec![MIXED, 0, 1]);
        assert_eq!(p.cluster_owner(0), 0);
        // One rank owns everything; more ranks than roots leave some ranks nothing.
        let one = Partition::new(&order, &[1.0; 4], 3, &kids, 1);
        assert!(one.root_rank.iter().all(|&r| r == 0));
        let many = Partition::new(&order, &[1.0; 4], 3, &kids, 8);
        assert_eq!(many.root_rank, vec![1, 3, 5, 7]);
        // A root of most of the area outweighs the others.
        let heavy = Partition::new(&order, &[10.0, 1.0, 1.0, 1.0], 3, &kids, 2);
        assert_eq!(heavy.root_rank, vec![0, 1, 1, 1]);
    }

    /// Shared over 3 thread ranks, a map gives every rank what one process computes, in
    /// order, also with fewer items than ranks and with none.
    #[test]
    fn a_shared_map_gives_every_rank_every_value_in_order() {
        for n in [0, 2, 10] {
            let out = Threads::run(3, |t| {
                let e: &dyn Exchange = t;
                e.map_shared(n, |i| (i * i) as u64, |v, w| w.u64(*v), |r| r.u64())
            });
            let expected: Vec<u64> = (0..n as u64).map(|i| i * i).collect();
            assert!(out.iter().all(|o| *o == expected), "{n} items: {out:?}");
        }
    }

    #[test]
    fn what_a_writer_writes_a_reader_reads() {
        let mut w = Writer::default();
        w.u32(7);
        w.f64(-0.0);
        w.f32(1.5);
        w.u64(u64::MAX);
        w.bytes(&[1, 2, 3, 4]);
        let mut r = Reader::new(&w.0);
        assert_eq!(r.u32(), 7);
        assert_eq!(r.f64().to_bits(), (-0.0f64).to_bits());
        assert_eq!(r.f32(), 1.5);
        assert_eq!(r.u64(), u64::MAX);
        assert_eq!(r.bytes::<4>(), [1, 2, 3, 4]);
        assert!(r.done());
    }
}
