//! Near shadows: a parallel face B in front of a face A, farther than mounted
//! ([`super::contact::MOUNTED`]) but within B's width and [`NEAR_SHADOW`] × the scene's
//! extent (a table leg's back 3 cm from a wall), shades A with a shadow sharper than the
//! patches, and the edges of B's outline that are its silhouette (`silhouettes`: not shared
//! with a coplanar face) are projected onto A. How far in front of A a face counts as mounted
//! or as shading it is `Face::gaps`.

use super::bits;
use super::contact::{MOUNTED, NEAR};
use super::face::Face;

/// A parallel face B in front of another face A, farther than mounted but within B's width
/// (or A's, if narrower) and within this fraction of the scene's extent (a quarter of the
/// default patch size, [`crate::mesh::default_max_edge`]), shades A with a shadow sharper than the
/// patches: the edges of B's outline that are its silhouette (not shared with a coplanar
/// face: a table leg's back face 3 cm from the wall, not the wall's diagonal seen from the
/// leg) are projected onto A. The indirect light under B falls by the share of the hemisphere
/// B fills, within about the gap g of its outline: behind the study's 4 cm legs 3 cm from
/// the wall, a dip of 5–8 % across 10 cm of a wall whose patches are 15 cm, which the display
/// refinement's few test rays at an edge's midpoint cannot see (the point-wise benchmark's
/// study shows it: without these edges its worst probes are those behind the legs). With B
/// narrower than g its shadow is shallow and wide (a long strip of width w at height g hides
/// sin(atan(w/2g)) < 45 % of the light under its middle, spread over several g), and beyond
/// the patches' scale the patches follow it themselves.
pub const NEAR_SHADOW: f64 = 1.0 / 64.0;

/// An edge by its ends' bits, the lesser first.
type EdgeKey = ([u64; 3], [u64; 3]);

/// For each face's edges (corner k to k + 1), whether the edge is a silhouette of its plane:
/// no other face with the same plane and facing shares it (matched by the corners' bits, so
/// an unwelded mesh's duplicated vertices match too).
pub(super) fn silhouettes(faces: &[Face]) -> Vec<[bool; 3]> {
    let key = |f: &Face, k: usize| {
        let (p, q) = (bits(f.corners[k]), bits(f.corners[(k + 1) % 3]));
        if p <= q {
            (p, q)
        } else {
            (q, p)
        }
    };
    // Every face's edges, sorted by key: the faces sharing an edge are a run (no allocation
    // per edge, for scenes of millions of faces).
    let mut edges: Vec<(EdgeKey, u32)> = faces
        .iter()
        .enumerate()
        .flat_map(|(i, f)| (0..3).map(move |k| (key(f, k), i as u32)))
        .collect();
    edges.sort_unstable();
    let sharing = |e: EdgeKey| {
        let first = edges.partition_point(|x| x.0 < e);
        edges[first..]
            .iter()
            .take_while(move |x| x.0 == e)
            .map(|x| x.1)
    };
    faces
        .iter()
        .enumerate()
        .map(|(i, f)| {
            std::array::from_fn(|k| {
                !sharing(key(f, k)).any(|j| {
                    let g = &faces[j as usize];
                    j as usize != i
                        && f.normal.dot(g.normal) > 1.0 - 1e-9
                        && g.corners
                            .iter()
                            .all(|&c| f.normal.dot(c - f.corners[0]).abs() <= 1e-9 * f.size)
                })
            })
        })
        .collect()
}

impl Face {
    /// The largest gaps at which the parallel face `b` in front of this one is mounted on it
    /// ([`NEAR`] × the scene's `extent`, or [`MOUNTED`] × the narrower one's width: the gap
    /// between them shades at most the narrower one's width), and at which it is mounted or
    /// shades it with a shadow sharper than the patches ([`NEAR_SHADOW`]), scene units.
    /// Without `b`, the largest for any `b`.
    pub(super) fn gaps(&self, b: Option<&Face>, extent: f64) -> (f64, f64) {
        let width = b.map_or(self.width(), |b| self.width().min(b.width()));
        let mounted = (NEAR * extent).max(MOUNTED * width);
        (mounted, mounted.max(width.min(NEAR_SHADOW * extent)))
    }
}
