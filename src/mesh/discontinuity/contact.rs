//! Contact lines: where a face B touches or crosses the plane of a face A (B's corners on both
//! sides, or an edge of B within [`TOUCH`] × the scene's extent of it), the segment where B
//! meets the plane; where B lies parallel just in front of A (within [`NEAR`] × the extent,
//! or within [`MOUNTED`] × the narrower one's width: a light mounted below a ceiling, a
//! picture on a wall, a leg's top under a table top), B's outline projected onto A
//! (`Face::contact`; the near shadows' part of it is [`super::near_shadow`]'s).

use glam::DVec3;

use super::face::Face;

/// A face whose corner (or edge) is within this fraction of the scene's extent of another
/// face's plane touches it.
pub const TOUCH: f64 = 1e-6;

/// A parallel face within this fraction of the scene's extent in front of another is mounted
/// on it: its outline is projected onto it.
pub const NEAR: f64 = 1e-3;

/// A parallel face within this fraction of its own width (its smallest altitude; or the other
/// face's, if narrower) in front of another is mounted on it too, however large the scene: a
/// ceiling panel 1 cm under the ceiling, a picture 2 cm off a wall. Under B, light enters only
/// through the gap g: the
/// unoccluded share of the hemisphere a point sees falls from about ½ at the outline to
/// g / (distance from the outline) inside it (the form factor to a slit of width g), so
/// with g ≤ 5 % of B's width the region under B is dark but for a rim a few g wide, while
/// outside, ½(1 − x/√(x² + g²)) of it is hidden at a distance x: within 1 % of open by
/// x = 5g. The radiance changes by about its whole value within a few g of the outline: at
/// the scale of any patch, a jump. (The living room's panel, 1 cm under the ceiling, is
/// 1.4e-3 of the room's extent, beyond [`NEAR`]: without this rule the ceiling's vertices
/// beside it would be interpolated from the dark ones under it, and show far too dark.)
pub const MOUNTED: f64 = 0.05;

impl Face {
    /// The segments where face `b` meets this face (see the module documentation), clipped to
    /// this face and projected onto its plane; `silhouette` says which of `b`'s edges are its
    /// plane's outline (see [`silhouettes`]), `None` to leave out the near shadows.
    pub(super) fn contact(
        &self,
        b: &Face,
        silhouette: Option<[bool; 3]>,
        extent: f64,
    ) -> Vec<[DVec3; 2]> {
        let touch = TOUCH * extent;
        let d = b.corners.map(|c| self.normal.dot(c - self.corners[0]));
        let parallel = self.normal.dot(b.normal).abs() > 1.0 - 1e-9;
        let mut raw: Vec<[DVec3; 2]> = Vec::new();
        if parallel {
            // Mounted in front (not coplanar, not behind): its outline; or in front within
            // the shading gap: the silhouette edges of its outline.
            let gap = d[0];
            let (mounted, shading) = self.gaps(Some(b), extent);
            let reach = if silhouette.is_some() {
                shading
            } else {
                mounted
            };
            if gap > touch && gap <= reach && d.iter().all(|&x| x > touch) {
                let outline = silhouette.unwrap_or([true; 3]);
                for k in (0..3).filter(|&k| gap <= mounted || outline[k]) {
                    raw.push([b.corners[k], b.corners[(k + 1) % 3]]);
                }
            }
        } else if d.iter().all(|&x| x.abs() <= touch) {
            // Coplanar within the tolerance but not parallel: degenerate, skip.
        } else {
            // Points where B meets the plane: corners on it, and edges crossing it.
            let mut pts: Vec<DVec3> = Vec::new();
            for k in 0..3 {
                let (p, q) = (b.corners[k], b.corners[(k + 1) % 3]);
                let (dp, dq) = (d[k], d[(k + 1) % 3]);
                if dp.abs() <= touch {
                    pts.push(p);
                }
                if (dp > touch && dq < -touch) || (dp < -touch && dq > touch) {
                    let t = dp / (dp - dq);
                    pts.push(p + t * (q - p));
                }
            }
            if pts.len() >= 2 {
                // The two farthest apart (B is convex: they bound its section).
                let (mut best, mut pair) = (0.0, [pts[0], pts[1]]);
                for i in 0..pts.len() {
                    for j in i + 1..pts.len() {
                        let l = pts[i].distance_squared(pts[j]);
                        if l > best {
                            best = l;
                            pair = [pts[i], pts[j]];
                        }
                    }
                }
                raw.push(pair);
            }
        }
        raw.into_iter()
            .filter_map(|[p, q]| self.clip([self.to_2d(p), self.to_2d(q)], touch / self.size))
            .map(|[p, q]| [self.point_at(p), self.point_at(q)])
            .collect()
    }
}
