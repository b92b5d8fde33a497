//! What the gather's rays are traced against: not the output patches but the scene triangles
//! they tile ([`Coarse`], the form factors' occluders), with a grid per triangle that finds
//! the patch under a hit point. A hemisphere ray then descends a BVH of the scene's few large
//! triangles instead of one of its patches (the default Cornell box: 32 triangles instead of
//! 6,481 patches) and pays one grid look-up for the patch it hit. Shadow rays only ask whether
//! anything is in the way, which the triangles answer alone.
//!
//! The answers are those of tracing the patches up to the `f32` rounding of the corners that
//! subdivision adds inside a triangle (~1e-9 of the scene): a ray hits a triangle exactly when
//! it hits one of its patches, at the same `t` up to that rounding; a hit point on the edge
//! shared by two patches goes to the first of them in index order (the patch BVH's tie went
//! to the lower index too).

use glam::DVec3;

use crate::form_factor::occluders::Coarse;
use crate::mesh::Patches;
use crate::visibility::{Point, Visibility, NONE};

/// A ray's first surface: the output patch hit and the ray parameter there (scene units for a
/// unit direction).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchHit {
    pub patch: u32,
    pub t: f64,
}

/// The patches of one traced triangle, bucketed on a grid in the triangle's plane.
struct Grid {
    /// The plane's frame: a point and two orthonormal axes, scene units.
    origin: DVec3,
    axes: [DVec3; 2],
    /// Lower corner of the grid in that frame, and cells per unit length along each axis.
    lo: [f64; 2],
    per_unit: [f64; 2],
    /// Cells along each axis (≥ 1), and the index of the first cell in [`Surfaces::cells`].
    dims: [usize; 2],
    first_cell: usize,
}

impl Grid {
    /// A grid over the triangle `tri` (scene units) for `members` patches, about one a cell;
    /// its cells start at `first_cell`.
    fn over(tri: &[DVec3; 3], members: usize, first_cell: usize) -> Grid {
        let normal = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
        let a = (tri[1] - tri[0]).normalize_or_zero();
        let b = normal.cross(a).normalize_or_zero();
        // A degenerate triangle (never hit) keeps its patches in one cell.
        let axes = if a == DVec3::ZERO || b == DVec3::ZERO {
            [DVec3::X, DVec3::Y]
        } else {
            [a, b]
        };
        let mut grid = Grid {
            origin: tri[0],
            axes,
            lo: [0.0; 2],
            per_unit: [0.0; 2],
            dims: [1; 2],
            first_cell,
        };
        let q = tri.map(|p| grid.at(p));
        let lo = [0, 1].map(|k| q.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min));
        let hi = [0, 1].map(|k| q.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max));
        let size = [hi[0] - lo[0], hi[1] - lo[1]];
        // Square cells of about the mean patch's area over the triangle's box.
        let cell = (size[0] * size[1] / members.max(1) as f64).sqrt();
        grid.lo = lo;
        grid.dims = size.map(|s| {
            let n = if cell > 0.0 { (s / cell).ceil() } else { 1.0 };
            (n as usize).clamp(1, 1024)
        });
        grid.per_unit = [0, 1].map(|k| {
            if size[k] > 0.0 {
                grid.dims[k] as f64 / size[k]
            } else {
                0.0
            }
        });
        grid
    }

    /// Plane coordinates of `p`.
    fn at(&self, p: DVec3) -> [f64; 2] {
        let d = p - self.origin;
        [d.dot(self.axes[0]), d.dot(self.axes[1])]
    }

    /// Column and row of the cell holding the plane point `q`, clamped to the grid.
    fn cell(&self, q: [f64; 2]) -> [usize; 2] {
        [0, 1].map(|k| {
            let c = ((q[k] - self.lo[k]) * self.per_unit[k]).floor();
            (c.max(0.0) as usize).min(self.dims[k] - 1)
        })
    }

    /// Index in [`Surfaces::cells`] of the cell holding `q`.
    fn index(&self, q: [f64; 2]) -> usize {
        let [x, y] = self.cell(q);
        self.first_cell + y * self.dims[0] + x
    }
}

/// The gather's ray queries against the output patches (see the module documentation).
pub struct Surfaces {
    vis: Visibility,
    /// The traced triangles, scene units (the BVH holds them in its canonical `f32` frame).
    triangles: Vec<[DVec3; 3]>,
    /// Traced triangle of each patch (never [`NONE`]: every patch is traced).
    of_patch: Vec<u32>,
    /// The patches of each traced triangle, in index order; a triangle that is a patch itself
    /// (one member) has no grid.
    members: Vec<Vec<u32>>,
    grids: Vec<Option<Grid>>,
    /// For cell c, its patches are `items[cells[c]..cells[c + 1]]`.
    cells: Vec<u32>,
    items: Vec<u32>,
    /// Each patch's corners in the plane coordinates of its traced triangle's grid (computed
    /// once, as a look-up would: the same bits), or zeros where the triangle has no grid.
    flat: Vec<[[f64; 2]; 3]>,
}

impl Surfaces {
    /// The traced triangles of `patches` and their grids: time and memory linear in the
    /// patches (a few grid entries of 4 bytes a patch: 4.6 in the living room, 7.5 in a hall;
    /// and 48 bytes a patch of its corners in the grid's plane).
    pub fn new(patches: &Patches) -> Surfaces {
        let coarse = Coarse::of(patches, &vec![true; patches.len()]);
        let mut members = vec![Vec::new(); coarse.triangles.len()];
        for (i, &c) in coarse.of_patch.iter().enumerate() {
            members[c as usize].push(i as u32);
        }
        let (mut cells, mut items) = (vec![0u32], Vec::new());
        let grids: Vec<Option<Grid>> = coarse
            .triangles
            .iter()
            .zip(&members)
            .map(|(tri, members)| {
                if members.len() <= 1 {
                    return None;
                }
                let grid = Grid::over(tri, members.len(), cells.len() - 1);
                // Each patch in every cell its box meets.
                let mut buckets = vec![Vec::new(); grid.dims[0] * grid.dims[1]];
                for &m in members {
                    let c = patches.corners(m as usize).map(|p| grid.at(p));
                    let bound = |pick: fn(f64, f64) -> f64, start: f64| {
                        [0, 1].map(|k| c.iter().map(|p| p[k]).fold(start, pick))
                    };
                    let lo = grid.cell(bound(f64::min, f64::INFINITY));
                    let hi = grid.cell(bound(f64::max, f64::NEG_INFINITY));
                    for y in lo[1]..=hi[1] {
                        for x in lo[0]..=hi[0] {
                            buckets[y * grid.dims[0] + x].push(m);
                        }
                    }
                }
                for b in buckets {
                    items.extend(b);
                    cells.push(items.len() as u32);
                }
                Some(grid)
            })
            .collect();
        let mut flat = vec![[[0.0; 2]; 3]; patches.len()];
        for (grid, members) in grids.iter().zip(&members) {
            if let Some(grid) = grid {
                for &m in members {
                    flat[m as usize] = patches.corners(m as usize).map(|p| grid.at(p));
                }
            }
        }
        let vis = Visibility::build(&coarse.triangles).with_transmittance(&coarse.transmittance);
        Surfaces {
            vis,
            triangles: coarse.triangles,
            of_patch: coarse.of_patch,
            members,
            grids,
            cells,
            items,
            flat,
        }
    }

    /// The traced triangle of patch `p`, or [`NONE`] for [`NONE`].
    pub fn traced(&self, p: u32) -> u32 {
        if p == NONE {
            NONE
        } else {
            self.of_patch[p as usize]
        }
    }

    /// The BVH of the traced triangles, for queries that take a triangle to ignore: pass
    /// [`Surfaces::traced`] of the patch.
    pub fn vis(&self) -> &Visibility {
        &self.vis
    }

    /// Calls `visit` with the corners of every triangle but those of the patch `ignore` that
    /// may meet the box `[lo, hi]` and the convex region inside `planes`
    /// ([`Visibility::overlapping_convex`]: a superset), until it returns `false`; returns
    /// `false` if it was stopped. A partly transparent triangle stops it too: it is no
    /// occluder to clip away whole (the emitter's visible pieces then give way to shadow
    /// rays, which pass it by its share).
    pub fn overlapping_convex(
        &self,
        lo: DVec3,
        hi: DVec3,
        planes: &[(DVec3, DVec3)],
        ignore: u32,
        visit: &mut dyn FnMut(&[DVec3; 3]) -> bool,
    ) -> bool {
        self.vis
            .overlapping_convex(lo, hi, planes, [self.traced(ignore), NONE], |id| {
                !self.vis.transmits(id) && visit(&self.triangles[id as usize])
            })
    }

    /// [`Visibility::point`].
    pub fn point(&self, x: DVec3) -> Point {
        self.vis.point(x)
    }

    /// Whether the open segment between `from` and `to` is blocked by any surface other than
    /// the patch `ignore` (and the rest of its triangle, which the segment leaves at once).
    /// The triangle that blocked the segment before is tested first
    /// ([`Visibility::occluded_points_after`]; `last` starts at `usize::MAX`).
    pub fn occluded_after(&self, from: &Point, to: &Point, ignore: u32, last: &mut usize) -> bool {
        self.vis
            .occluded_points_after(from, to, [self.traced(ignore), NONE], last)
    }

    /// The first patch hit by the ray `origin + t·dir`, `t > 0`, other than those of the
    /// triangle of the patch `ignore` (see [`Visibility::closest_hit`]).
    pub fn closest(&self, origin: DVec3, dir: DVec3, ignore: u32) -> Option<PatchHit> {
        let hit = self
            .vis
            .closest_hit(origin, dir, f64::INFINITY, self.traced(ignore))?;
        let c = hit.triangle as usize;
        let patch = match &self.grids[c] {
            None => self.members[c][0],
            Some(grid) => {
                let q = grid.at(origin + hit.t * dir);
                let cell = grid.index(q);
                let near = &self.items[self.cells[cell] as usize..self.cells[cell + 1] as usize];
                self.inside(near, q)
                    .or_else(|| self.inside(&self.members[c], q))
                    .unwrap_or(self.members[c][0])
            }
        };
        Some(PatchHit { patch, t: hit.t })
    }

    /// Of `candidates` (patches of one gridded triangle), the first whose triangle holds `q`
    /// (plane coordinates of that triangle's grid), or else the one it lies least outside of
    /// (a hit point rounded just past a boundary); `None` for no candidates.
    fn inside(&self, candidates: &[u32], q: [f64; 2]) -> Option<u32> {
        let mut best: Option<(f64, u32)> = None;
        for &m in candidates {
            let w = least_barycentric(self.flat[m as usize], q);
            if w >= 0.0 {
                return Some(m);
            }
            if best.is_none_or(|b| w > b.0) {
                best = Some((w, m));
            }
        }
        best.map(|b| b.1)
    }
}

/// The least barycentric coordinate of `q` in the plane triangle `c` (≥ 0 inside), relative
/// to the triangle's size; −∞ for a degenerate triangle.
fn least_barycentric(c: [[f64; 2]; 3], q: [f64; 2]) -> f64 {
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let area = cross(c[0], c[1], c[2]);
    if area == 0.0 {
        return f64::NEG_INFINITY;
    }
    let w = [
        cross(q, c[1], c[2]) / area,
        cross(c[0], q, c[2]) / area,
        cross(c[0], c[1], q) / area,
    ];
    w[0].min(w[1]).min(w[2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{split_contacts, subdivide};
    use crate::sampling::Rng;
    use crate::validation::scenes;

    /// The patch BVH's answers (the oracle: every patch traced as itself) against the traced
    /// triangles' with the grid look-up, on random rays from random patch points: the same
    /// patch at the same distance, or another that holds the hit point too (within 1e-6 of
    /// the scene's extent): across an edge from it, rarely, or on a coincident face. Rays
    /// starting within rounding of another surface (points on a contact line) are left out.
    #[test]
    fn the_patch_found_is_the_patch_bvh_hit() {
        let mut two_sided = scenes::living_room().unwrap();
        two_sided.make_two_sided();
        for (name, scene) in [
            ("living room", scenes::living_room().unwrap()),
            ("hall", scenes::furnished_hall(2000).unwrap()),
            ("two-sided living room", two_sided),
        ] {
            let (scene, _) = split_contacts(&scene);
            let (lo, hi) = scene.bounds();
            let extent = (hi - lo).length();
            let patches = subdivide(&scene, extent / 24.0, 30.0).unwrap();
            let corners: Vec<[DVec3; 3]> = (0..patches.len()).map(|i| patches.corners(i)).collect();
            let oracle = Visibility::build(&corners);
            let surfaces = Surfaces::new(&patches);
            let entries = surfaces.items.len() as f64 / patches.len() as f64;
            eprintln!("{name}: {entries:.2} grid entries a patch");
            assert!(entries < 16.0, "{name}: {entries} grid entries a patch");
            let mut rng = Rng::new(&[7]);
            let (mut hits, mut across, mut coincident, mut grazing) = (0, 0, 0, 0);
            for _ in 0..20_000 {
                let i = (rng.next_f64() * patches.len() as f64) as usize;
                let c = patches.corners(i);
                let (u, v) = (rng.next_f64(), rng.next_f64());
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                let x = c[0] + u * (c[1] - c[0]) + v * (c[2] - c[0]);
                let z = 2.0 * rng.next_f64() - 1.0;
                let phi = 2.0 * std::f64::consts::PI * rng.next_f64();
                let r = (1.0 - z * z).sqrt();
                let mut dir = DVec3::new(r * phi.cos(), r * phi.sin(), z);
                if dir.dot(patches.normal[i]) < 0.0 {
                    dir = -dir;
                }
                let x = x + 1e-6 * extent * patches.normal[i];
                let want = oracle.closest_hit(x, dir, f64::INFINITY, i as u32);
                let got = surfaces.closest(x, dir, i as u32);
                match (want, got) {
                    (None, None) => {}
                    (Some(w), Some(g)) => {
                        hits += 1;
                        if w.t.min(g.t) <= 1e-6 * extent {
                            // The origin lies on another surface within rounding (a point
                            // on a contact line, under the surface it touches): the two
                            // traversals may round its distance either side of `t_min`.
                            grazing += 1;
                            continue;
                        }
                        assert!(
                            (w.t - g.t).abs() <= 1e-6 * extent,
                            "{name}: t {} vs {}",
                            w.t,
                            g.t
                        );
                        if w.triangle != g.patch {
                            // Both patches must hold the hit point, up to rounding.
                            let y = x + g.t * dir;
                            for p in [w.triangle, g.patch] {
                                let c = patches.corners(p as usize);
                                let d = distance_to_triangle(y, c);
                                assert!(
                                    d <= 1e-6 * extent,
                                    "{name}: patch {p} is {d} from the hit"
                                );
                            }
                            // Patches of one triangle meet at an edge; of two, the triangles
                            // coincide (a contact, or a two-sided surface lying on another),
                            // and which is first is the tie-break's choice.
                            if surfaces.traced(w.triangle) == surfaces.traced(g.patch) {
                                across += 1;
                            } else {
                                coincident += 1;
                            }
                        }
                    }
                    (w, g)
                        if w.is_some_and(|h| h.t <= 1e-6 * extent)
                            || g.is_some_and(|h| h.t <= 1e-6 * extent) =>
                    {
                        grazing += 1
                    }
                    (w, g) => panic!("{name}: oracle {w:?}, traced {g:?}"),
                }
            }
            assert!(hits > 10_000, "{name}: {hits} hits");
            assert!(
                across * 100 < hits,
                "{name}: {across} of {hits} across a boundary"
            );
            assert!(
                grazing * 100 < hits,
                "{name}: {grazing} of {hits} from another surface"
            );
            eprintln!(
                "{name}: {hits} hits, {across} across a boundary, {coincident} on coincident \
                 faces, {grazing} grazing"
            );
        }
    }

    fn distance_to_triangle(p: DVec3, c: [DVec3; 3]) -> f64 {
        let n = (c[1] - c[0]).cross(c[2] - c[0]).normalize();
        let q = p - n * n.dot(p - c[0]);
        let inside = (0..3).all(|k| (c[(k + 1) % 3] - c[k]).cross(q - c[k]).dot(n) >= 0.0);
        if inside {
            return (p - q).length();
        }
        (0..3)
            .map(|k| {
                let (a, b) = (c[k], c[(k + 1) % 3]);
                let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
                p.distance(a + t * (b - a))
            })
            .fold(f64::INFINITY, f64::min)
    }
}
