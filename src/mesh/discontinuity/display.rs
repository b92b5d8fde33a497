//! The hierarchical display cut along the contact lines ([`split_patches`]): the hierarchical
//! solver's roots stay the input triangles (see [`super::Discontinuities::Auto`]), so the
//! contact lines cut the output patches after the solve instead, where the final gather needs
//! its vertices to stop at them.

use std::collections::HashMap;

use glam::DVec3;
use rayon::prelude::*;

use super::face::Face;
use super::{bits, merge_edge_points, points_on_edges, shared_point, ContactStats, TOUCH};
use crate::mesh::Patches;
use crate::scene::{NO_TWIN, ZERO_AREA_RELATIVE};

/// The display's faces cut along the scene's contact lines (`lines`, from
/// [`contact_lines`](super::contact_lines)), for a solve whose patches were not (the hierarchical
/// one: its roots are the input triangles, see
/// [`Discontinuities::Auto`](super::Discontinuities::Auto)). Each patch crossed by a contact
/// segment of its source triangle is re-triangulated with the segment's part inside it as a
/// constrained edge, and the points where segments end on a patch's edge go into the patch across
/// it too, so the display stays conforming. The pieces keep their patch's material, normal and
/// source triangle; corner normals are interpolated in it. Returns the new patches, the patch each
/// piece came from, its region, and what was done (`segments`: the clipped pieces inserted): a
/// [`Split`].
/// A twin is cut as its front (its lower-numbered partner) is, each piece reversed and
/// placed right after the front's: pairs stay pairs.
pub fn split_patches(lines: &[Vec<[DVec3; 2]>], patches: &Patches, extent: f64) -> Option<Split> {
    split_patches_binned(lines, patches, extent, GRID_MIN_SEGMENTS)
}

/// The display's faces cut along lines ([`split_patches`]).
#[derive(Debug, Clone)]
pub struct Split {
    /// The pieces.
    pub patches: Patches,
    /// The patch each piece came from.
    pub parent: Vec<u32>,
    /// Each piece's region: the first piece (index) of the pieces of its patch that no line
    /// separates from it (joined across edges that lie on no segment). A patch the lines cross
    /// has two or more regions; one only touched at its edges by a neighbour's segment, one.
    pub region: Vec<u32>,
    /// What the cut did.
    pub stats: ContactStats,
}

/// Whether the piece edge `a`–`b` lies along one of `segs` (within `touch`, scene units): a
/// constrained edge of the cut, which separates regions.
fn on_segment(a: DVec3, b: DVec3, segs: &[[DVec3; 2]], touch: f64) -> bool {
    segs.iter().any(|&[p, q]| {
        let d = q - p;
        let len2 = d.length_squared();
        if len2 == 0.0 {
            return false;
        }
        let near = |x: DVec3| {
            let t = (x - p).dot(d) / len2;
            let slack = touch / len2.sqrt();
            (-slack..=1.0 + slack).contains(&t) && (x - (p + t * d)).length() <= touch
        };
        near(a) && near(b)
    })
}

/// The regions of one face's `pieces` (see [`Split::region`]): for each piece, the index in
/// `pieces` of its region's first piece.
fn regions(pieces: &[[DVec3; 3]], segs: &[[DVec3; 2]], touch: f64) -> Vec<usize> {
    let mut root: Vec<usize> = (0..pieces.len()).collect();
    fn find(root: &mut [usize], mut i: usize) -> usize {
        while root[i] != i {
            root[i] = root[root[i]];
            i = root[i];
        }
        i
    }
    let mut edges: HashMap<([u64; 3], [u64; 3]), usize> = HashMap::new();
    for (k, t) in pieces.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            let key = if bits(a) < bits(b) {
                (bits(a), bits(b))
            } else {
                (bits(b), bits(a))
            };
            if let Some(&other) = edges.get(&key) {
                if !on_segment(a, b, segs, touch) {
                    let (x, y) = (find(&mut root, k), find(&mut root, other));
                    root[x.max(y)] = x.min(y);
                }
            } else {
                edges.insert(key, k);
            }
        }
    }
    (0..pieces.len()).map(|k| find(&mut root, k)).collect()
}

/// [`split_patches`], binning the segments of triangles with more than `grid_from` of them
/// ([`SegmentGrid`]; the same result whatever `grid_from`).
pub(super) fn split_patches_binned(
    lines: &[Vec<[DVec3; 2]>],
    patches: &Patches,
    extent: f64,
    grid_from: usize,
) -> Option<Split> {
    let touch = TOUCH * extent;
    let n = patches.len();
    // Each patch's part of its source triangle's segments: of a triangle with many (a floor
    // under a hall's furniture has thousands, and thousands of patches), only those whose box
    // comes within `touch` of the patch's, which are all that can cross it.
    // Boxed: one pointer a triangle where most have no grid (10⁶ triangles: 8 MB, not 100).
    let grids: Vec<Option<Box<SegmentGrid>>> = lines
        .par_iter()
        .map(|segs| (segs.len() > grid_from).then(|| Box::new(SegmentGrid::new(segs))))
        .collect();
    let cut: Vec<(Face, Vec<[DVec3; 2]>)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let face = Face::from_corners(patches.corners(i));
            let t = patches.source_triangle[i] as usize;
            let segs = lines
                .get(t)
                .map(|segs| {
                    let clip = |&[p, q]: &[DVec3; 2]| {
                        face.clip([face.to_2d(p), face.to_2d(q)], touch / face.size)
                            .map(|[p, q]| [face.point_at(p), face.point_at(q)])
                    };
                    match &grids[t] {
                        Some(grid) => {
                            let (lo, hi) = face.bounds(2.0 * touch);
                            grid.near(lo, hi)
                                .into_iter()
                                .filter_map(|k| clip(&segs[k as usize]))
                                .collect()
                        }
                        None => segs.iter().filter_map(clip).collect(),
                    }
                })
                .unwrap_or_default();
            (face, segs)
        })
        .collect();
    let mut on_edge: HashMap<(u32, u32), Vec<DVec3>> = HashMap::new();
    for (i, (face, segs)) in cut.iter().enumerate() {
        for s in segs {
            for &p in s {
                if let Some(e) = face.edge_through(p, touch) {
                    let v = patches.triangles[i];
                    let (a, b) = (v[e], v[(e + 1) % 3]);
                    on_edge.entry((a.min(b), a.max(b))).or_default().push(p);
                }
            }
        }
    }
    merge_edge_points(&mut on_edge, touch);
    let mut stats = ContactStats {
        triangles: n,
        ..ContactStats::default()
    };
    let mut out = Patches::with_capacity(patches.positions.clone(), n);
    out.material_transmittance = patches.material_transmittance.clone();
    let mut parent = Vec::with_capacity(n);
    let mut region: Vec<u32> = Vec::with_capacity(n);
    let mut index: HashMap<[u64; 3], u32> = HashMap::new();
    let min_area = ZERO_AREA_RELATIVE * extent * extent;
    // A twin is cut as its front is, its pieces reversed right after the front's.
    let back = |i: usize| patches.twin.get(i).copied().filter(|&j| j != NO_TWIN);
    let push = |out: &mut Patches, parent: &mut Vec<u32>, i: usize, t: [u32; 3]| {
        out.push_inside(t, &patches.parent(i));
        parent.push(i as u32);
        if let Some(j) = back(i) {
            out.push_inside([t[0], t[2], t[1]], &patches.parent(j as usize));
            parent.push(j);
            let k = out.len() as u32;
            out.twin[(k - 2) as usize] = k - 1;
            out.twin[(k - 1) as usize] = k - 2;
        }
    };
    for (i, (face, segs)) in cut.iter().enumerate() {
        if back(i).is_some_and(|j| (j as usize) < i) {
            continue; // a twin: pushed with its front
        }
        let v = patches.triangles[i];
        let edge_points = points_on_edges(&on_edge, v);
        let segs: Vec<[DVec3; 2]> = (segs.iter())
            .map(|s| s.map(|p| shared_point(&on_edge, v, face, p, touch)))
            .collect();
        let pieces = if segs.is_empty() && edge_points.is_empty() {
            None
        } else {
            face.triangulate(&segs, &edge_points, true)
        };
        let Some(pieces) = pieces else {
            let first = out.len() as u32;
            push(&mut out, &mut parent, i, v);
            region.extend(first..out.len() as u32);
            continue;
        };
        stats.faces_split += 1;
        stats.segments += segs.len();
        let pieces: Vec<[DVec3; 3]> = (pieces.into_iter())
            .filter(|&[p, q, r]| 0.5 * (q - p).cross(r - p).length() > min_area)
            .collect();
        let of = regions(&pieces, &segs, touch);
        // Each piece pushes one patch, or two with its twin's: the k-th piece's first patch.
        let stride = if back(i).is_some() { 2 } else { 1 };
        let first = out.len();
        for (k, [p, q, r]) in pieces.into_iter().enumerate() {
            let at = (first + stride * of[k]) as u32;
            region.push(at);
            if stride == 2 {
                region.push(at + 1);
            }
            let mut id = |x: DVec3| {
                if let Some(k) = face.corners.iter().position(|&c| c == x) {
                    return v[k];
                }
                *index.entry(bits(x)).or_insert_with(|| {
                    out.positions.push(x);
                    (out.positions.len() - 1) as u32
                })
            };
            let t = [id(p), id(q), id(r)];
            push(&mut out, &mut parent, i, t);
        }
    }
    stats.triangles = out.len();
    Some(Split {
        patches: out,
        parent,
        region,
        stats,
    })
}

/// Segments of one source triangle from which [`split_patches`] bins them ([`SegmentGrid`]).
pub(super) const GRID_MIN_SEGMENTS: usize = 32;

/// One source triangle's contact segments binned by their boxes on a grid over the two widest
/// axes of their bounds (they lie in the triangle's plane), about one segment a cell: which
/// segments may come near a box, without testing them all.
struct SegmentGrid {
    lo: DVec3,
    /// The two binned axes, the cells along each and their size.
    axes: [usize; 2],
    dims: [usize; 2],
    size: [f64; 2],
    /// Per cell (row-major), the segments whose boxes overlap it, in ascending order.
    cells: Vec<Vec<u32>>,
}

impl SegmentGrid {
    fn new(segs: &[[DVec3; 2]]) -> SegmentGrid {
        let (lo, hi) = crate::geometry::bounds(segs.iter().flatten().copied());
        let extent = hi - lo;
        let mut order = [0, 1, 2];
        order.sort_by(|&a, &b| extent[b].total_cmp(&extent[a]));
        let axes = [order[0], order[1]];
        let side = (segs.len() as f64).sqrt().ceil().max(1.0) as usize;
        let dims = axes.map(|a| if extent[a] > 0.0 { side } else { 1 });
        let size = [0, 1].map(|k| (extent[axes[k]] / dims[k] as f64).max(f64::MIN_POSITIVE));
        let mut grid = SegmentGrid {
            lo,
            axes,
            dims,
            size,
            cells: vec![Vec::new(); dims[0] * dims[1]],
        };
        for (k, &[p, q]) in segs.iter().enumerate() {
            let ([x0, x1], [y0, y1]) = grid.span(p.min(q), p.max(q));
            for y in y0..=y1 {
                for x in x0..=x1 {
                    grid.cells[y * dims[0] + x].push(k as u32);
                }
            }
        }
        grid
    }

    /// The cells (x and y ranges, inclusive) a box overlaps, clamped to the grid.
    fn span(&self, lo: DVec3, hi: DVec3) -> ([usize; 2], [usize; 2]) {
        let cell = |k: usize, v: f64| {
            let c = ((v - self.lo[self.axes[k]]) / self.size[k]).floor();
            c.clamp(0.0, (self.dims[k] - 1) as f64) as usize
        };
        let range = |k: usize| [cell(k, lo[self.axes[k]]), cell(k, hi[self.axes[k]])];
        (range(0), range(1))
    }

    /// The segments whose cells the box overlaps, each once, in ascending order (a superset of
    /// those whose boxes overlap it).
    fn near(&self, lo: DVec3, hi: DVec3) -> Vec<u32> {
        let ([x0, x1], [y0, y1]) = self.span(lo, hi);
        let mut out = Vec::new();
        for y in y0..=y1 {
            for x in x0..=x1 {
                out.extend_from_slice(&self.cells[y * self.dims[0] + x]);
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }
}
