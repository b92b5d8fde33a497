//! The display's edges and the cheap direct light at its vertices and midpoints, shared by
//! the display refinement ([`super::refine()`], which orders its midpoint tests by it) and the
//! edge flips ([`super::flip`], which screen their crossings by it).
//!
//! The cheap estimate is [`Gatherer::coarse_direct`] over the emitters computed exactly at a
//! point: correlated between nearby points, so that an edge's midpoint departing from its
//! ends' mean shows a shadow between them. A vertex's estimate is computed once and kept
//! ([`Coarse`]), shared among ranks.

use super::Gatherer;
use crate::bake::Site;
use crate::color::Rgb;
use crate::distributed::{Reader, Writer};

/// An undirected edge between output vertices (lower index first).
pub(super) type Edge = (u32, u32);

/// The edge between `a` and `b`, either order.
pub(super) fn edge(a: u32, b: u32) -> Edge {
    (a.min(b), a.max(b))
}

/// The three edges of a face.
pub(super) fn face_edges(face: [u32; 3]) -> [Edge; 3] {
    std::array::from_fn(|k| edge(face[k], face[(k + 1) % 3]))
}

/// Each display vertex's cheap direct light and the key of its exact emitters
/// ([`coarse_direct_at`]), once computed; `None` where it is buried. Indexed
/// by vertex (`coarse[&v]`, which panics for a vertex not yet computed): most of a large
/// output's vertices are, and a hash map of them would take twice the bytes.
#[derive(Debug, Default)]
pub(super) struct Coarse(Vec<Option<Option<(u64, Rgb)>>>);

impl Coarse {
    /// Whether vertex `v`'s estimate has been computed.
    pub(super) fn contains_key(&self, v: &u32) -> bool {
        self.0.get(*v as usize).is_some_and(Option::is_some)
    }

    /// Sets the estimates of `found` (vertex, estimate).
    pub(super) fn extend(&mut self, found: impl IntoIterator<Item = (u32, Option<(u64, Rgb)>)>) {
        for (v, c) in found {
            if self.0.len() <= v as usize {
                self.0.resize(v as usize + 1, None);
            }
            self.0[v as usize] = Some(c);
        }
    }
}

impl std::ops::Index<&u32> for Coarse {
    type Output = Option<(u64, Rgb)>;

    fn index(&self, v: &u32) -> &Self::Output {
        self.0[*v as usize]
            .as_ref()
            .expect("a display vertex's cheap direct light is computed before it is read")
    }
}

/// The cheap direct light at a display vertex or midpoint `site`
/// ([`Gatherer::coarse_direct`] over the emitters computed exactly there), with the key of
/// those emitters ([`Gatherer::exact_key`]); `None` where the site is buried.
pub(super) fn coarse_direct_at(
    gatherer: &Gatherer,
    site: &Site,
    visible_fraction: &[f64],
) -> Option<(u64, Rgb)> {
    let spot = gatherer.spot(site, visible_fraction)?;
    let exact = gatherer.exact_emitters(spot.x);
    Some((
        gatherer.exact_key(&exact),
        gatherer.coarse_direct(&spot, &exact),
    ))
}

/// Adds to `coarse_at` the [`coarse_direct_at`] estimate of each of `vertices` (display
/// vertices, at `sites`) it lacks, computed once each, in vertex order, shared among ranks.
pub(super) fn complete_coarse(
    gatherer: &Gatherer,
    sites: &[Site],
    vertices: impl Iterator<Item = u32>,
    coarse_at: &mut Coarse,
    visible_fraction: &[f64],
) {
    let mut fresh: Vec<u32> = vertices.filter(|v| !coarse_at.contains_key(v)).collect();
    fresh.sort_unstable();
    fresh.dedup();
    let found = gatherer.comm.map_shared(
        fresh.len(),
        |i| coarse_direct_at(gatherer, &sites[fresh[i] as usize], visible_fraction),
        write_coarse,
        read_coarse,
    );
    coarse_at.extend(fresh.iter().copied().zip(found));
}

/// Writes a [`coarse_direct_at`] result for another rank ([`read_coarse`] reads it).
fn write_coarse(c: &Option<(u64, Rgb)>, w: &mut Writer) {
    w.bytes(&[c.is_some() as u8]);
    let (k, d) = c.unwrap_or_default();
    w.u64(k);
    d.iter().for_each(|&v| w.f64(v));
}

/// Reads what [`write_coarse`] wrote.
fn read_coarse(r: &mut Reader) -> Option<(u64, Rgb)> {
    let ([some], k) = (r.bytes(), r.u64());
    let d = [r.f64(), r.f64(), r.f64()];
    (some != 0).then_some((k, d))
}
