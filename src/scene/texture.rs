//! Textures as reflectance that varies across a surface: a material's `map_Kd` (OBJ) or base
//! colour texture (glTF) with the faces' texture coordinates, so that a brick wall's patches
//! take the brick's colour and bleed it onto the floor.
//!
//! A patch's ρ is the material's ρ (Kd × the texture's mean colour, what a face without
//! texture coordinates gets) times the texture averaged over the patch's footprint in texture
//! space, divided by the texture's mean, per channel:
//!
//! ρ_patch = ρ_material · (1/|T|) ∫_T tex(u, v) du dv / mean(tex),
//!
//! so that the patches of a face that covers the texture once average (by area) to ρ_material.
//! The footprint T is the patch's corners mapped by its scene triangle's [`UvMap`]; the
//! integral is 16 bilinear samples at the centroids of a 4 × 4 split of T, at the level of a
//! box-filtered mip pyramid whose texels are as wide as the samples' spacing (Williams 1983,
//! "Pyramidal parametrics"). Texture coordinates wrap (repeat), as OBJ and glTF default to.
//!
//! The matrix method's patches (and refined patches) each get their own ρ; the hierarchical
//! method's elements take their root's, so there ρ varies per input triangle.

use glam::{DVec2, DVec3};

use crate::color::Rgb;

/// The triangle has no texture coordinates (or its material no texture): ρ is the material's.
pub const NO_UV: u32 = u32::MAX;

/// The largest side of a texture's finest level kept, texels: larger images are box-filtered
/// down on loading (a patch spans many texels; 256² texels of 3 × f32 are 768 KiB a texture).
pub const MAX_SIDE: u32 = 256;

/// One level of the pyramid: linear RGB, row 0 at the image's top.
#[derive(Debug, Clone)]
struct Level {
    width: usize,
    height: usize,
    texels: Vec<[f32; 3]>,
}

impl Level {
    /// Half the size (at least 1 × 1), each texel the mean of the (up to) 2 × 2 it covers.
    fn halved(&self) -> Level {
        let (w, h) = (self.width.div_ceil(2), self.height.div_ceil(2));
        let mut texels = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let mut sum = [0.0f32; 3];
                let mut n = 0.0f32;
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (sx, sy) = (2 * x + dx, 2 * y + dy);
                    if sx < self.width && sy < self.height {
                        let t = self.texels[sy * self.width + sx];
                        sum = std::array::from_fn(|c| sum[c] + t[c]);
                        n += 1.0;
                    }
                }
                texels.push(sum.map(|s| s / n));
            }
        }
        Level {
            width: w,
            height: h,
            texels,
        }
    }

    /// Bilinear lookup at (u, v) (u right, v down, 1 = the image's width or height), wrapping.
    fn bilinear(&self, u: f64, v: f64) -> [f64; 3] {
        let x = u * self.width as f64 - 0.5;
        let y = v * self.height as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let wrap = |i: f64, n: usize| (i.rem_euclid(n as f64) as usize).min(n - 1);
        let (xa, xb) = (wrap(x0, self.width), wrap(x0 + 1.0, self.width));
        let (ya, yb) = (wrap(y0, self.height), wrap(y0 + 1.0, self.height));
        let t = |x: usize, y: usize| self.texels[y * self.width + x].map(f64::from);
        let (a, b, c, d) = (t(xa, ya), t(xb, ya), t(xa, yb), t(xb, yb));
        std::array::from_fn(|k| {
            (1.0 - fy) * ((1.0 - fx) * a[k] + fx * b[k]) + fy * ((1.0 - fx) * c[k] + fx * d[k])
        })
    }
}

/// A texture's linear colour, as a mip pyramid, and its mean.
#[derive(Debug, Clone)]
pub struct Texture {
    /// Where it came from (a file's path, or a glTF image's index), for messages.
    pub source: String,
    /// The mean linear colour over the whole image at full resolution, each channel in [0, 1].
    pub mean: Rgb,
    /// Finest first; the last is 1 × 1.
    levels: Vec<Level>,
}

impl Texture {
    /// A texture from `width` × `height` linear RGB texels (row 0 at the top) and the mean of
    /// the full-resolution image (`mean`; the texels may already be reduced). Levels coarser
    /// than [`MAX_SIDE`] are what is kept. `None` without texels.
    pub fn new(
        source: String,
        width: usize,
        height: usize,
        texels: Vec<[f32; 3]>,
        mean: Rgb,
    ) -> Option<Texture> {
        if width == 0 || height == 0 || texels.len() != width * height {
            return None;
        }
        let mut level = Level {
            width,
            height,
            texels,
        };
        while level.width.max(level.height) > MAX_SIDE as usize {
            level = level.halved();
        }
        let mut levels = vec![level];
        while levels.last().is_some_and(|l| l.width > 1 || l.height > 1) {
            let next = levels[levels.len() - 1].halved();
            levels.push(next);
        }
        Some(Texture {
            source,
            mean,
            levels,
        })
    }

    /// The mean linear colour over the triangle `uv` of texture space (u right, v down, 1 =
    /// the image's side; wrapping), by 16 bilinear samples at the centroids of its 4 × 4 split,
    /// at the pyramid level whose texels are about the samples' spacing.
    pub fn mean_over(&self, uv: [DVec2; 3]) -> Rgb {
        let base = &self.levels[0];
        let area = 0.5 * (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]).abs();
        let texels = area * (base.width * base.height) as f64;
        // Spacing between the samples: the footprint's side over 4, in finest texels.
        let spacing = texels.sqrt() / 4.0;
        let level = if spacing > 1.0 {
            (spacing.log2().floor() as usize).min(self.levels.len() - 1)
        } else {
            0
        };
        let l = &self.levels[level];
        let mut sum = [0.0; 3];
        const N: usize = 4;
        let mut count = 0.0;
        for i in 0..N {
            for j in 0..N - i {
                // Upward sub-triangle (i, j) and, where there is one, the downward one beside it.
                let mut add = |b: [f64; 3]| {
                    let p = uv[0] * b[0] + uv[1] * b[1] + uv[2] * b[2];
                    let t = l.bilinear(p.x, p.y);
                    for c in 0..3 {
                        sum[c] += t[c];
                    }
                    count += 1.0;
                };
                // Centroids in (b1, b2) = (i + 1/3, j + 1/3)/N and (i + 2/3, j + 2/3)/N; all
                // 16 sub-triangles have the same area, so the plain mean is the integral's.
                let (fi, fj, n) = (i as f64, j as f64, N as f64);
                let at = |b1: f64, b2: f64| [1.0 - b1 - b2, b1, b2];
                add(at((fi + 1.0 / 3.0) / n, (fj + 1.0 / 3.0) / n));
                if i + j < N - 1 {
                    add(at((fi + 2.0 / 3.0) / n, (fj + 2.0 / 3.0) / n));
                }
            }
        }
        sum.map(|s| (s / count).clamp(0.0, 1.0))
    }
}

/// The affine map from a scene triangle's plane to texture space: uv(x) = uv₀ + (du·(x − o),
/// dv·(x − o)), exact at the triangle's corners and linear inside, so it serves every patch
/// cut from the triangle (they lie in its plane).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UvMap {
    /// Index into [`crate::scene::Scene::textures`].
    pub texture: u32,
    origin: DVec3,
    uv_origin: DVec2,
    du: DVec3,
    dv: DVec3,
}

impl UvMap {
    /// The map of the triangle `corners` whose texture coordinates are `uv` (u right, v down).
    /// `None` for a degenerate triangle or non-finite coordinates.
    pub fn new(texture: u32, corners: [DVec3; 3], uv: [DVec2; 3]) -> Option<UvMap> {
        let (e1, e2) = (corners[1] - corners[0], corners[2] - corners[0]);
        let (t1, t2) = (uv[1] - uv[0], uv[2] - uv[0]);
        // The linear functional g on the plane with g(e1) = a, g(e2) = b is α e1 + β e2 with
        // the Gram matrix [[e1·e1, e1·e2], [e1·e2, e2·e2]] (α, β) = (a, b).
        let (g11, g12, g22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        let det = g11 * g22 - g12 * g12;
        if det.is_nan() || det <= 0.0 || !uv.iter().all(|p| p.is_finite()) {
            return None;
        }
        let dual = |a: f64, b: f64| {
            let alpha = (g22 * a - g12 * b) / det;
            let beta = (g11 * b - g12 * a) / det;
            alpha * e1 + beta * e2
        };
        Some(UvMap {
            texture,
            origin: corners[0],
            uv_origin: uv[0],
            du: dual(t1.x, t2.x),
            dv: dual(t1.y, t2.y),
        })
    }

    /// The texture coordinates of the point `x` of the triangle's plane.
    pub fn uv(&self, x: DVec3) -> DVec2 {
        let d = x - self.origin;
        self.uv_origin + DVec2::new(self.du.dot(d), self.dv.dot(d))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An 8 × 1 texture: red on the left half, green on the right (wide enough that bilinear
    /// lookups a quarter of the way in see one colour).
    fn halves() -> Texture {
        let texels = (0..8)
            .map(|x| {
                if x < 4 {
                    [1.0, 0.0, 0.0]
                } else {
                    [0.0, 1.0, 0.0]
                }
            })
            .collect();
        Texture::new("halves".into(), 8, 1, texels, [0.5, 0.5, 0.0]).unwrap()
    }

    #[test]
    fn the_map_is_exact_at_the_corners_and_affine_inside() {
        let corners = [
            DVec3::new(1.0, 2.0, 3.0),
            DVec3::new(4.0, 2.5, 3.0),
            DVec3::new(1.5, 5.0, 4.0),
        ];
        let uv = [
            DVec2::new(0.1, 0.2),
            DVec2::new(0.9, 0.3),
            DVec2::new(0.2, 1.7),
        ];
        let m = UvMap::new(0, corners, uv).unwrap();
        for (p, t) in corners.iter().zip(uv) {
            assert!((m.uv(*p) - t).length() < 1e-12);
        }
        let b = [0.2, 0.3, 0.5];
        let x = corners[0] * b[0] + corners[1] * b[1] + corners[2] * b[2];
        let t = uv[0] * b[0] + uv[1] * b[1] + uv[2] * b[2];
        assert!((m.uv(x) - t).length() < 1e-12);
        assert!(UvMap::new(0, [DVec3::ZERO, DVec3::X, DVec3::X * 2.0], uv).is_none());
    }

    #[test]
    fn a_footprint_takes_the_colour_under_it() {
        let t = halves();
        // A small triangle in the middle of the left half: red; of the right half: green.
        let tri = |u: f64| {
            [
                DVec2::new(u - 0.05, 0.4),
                DVec2::new(u + 0.05, 0.4),
                DVec2::new(u, 0.6),
            ]
        };
        let left = t.mean_over(tri(0.2));
        let right = t.mean_over(tri(0.8));
        assert!(left[0] > 0.95 && left[1] < 0.05, "{left:?}");
        assert!(right[1] > 0.95 && right[0] < 0.05, "{right:?}");
        // The two triangles covering the whole image (and a repeat of it): the mean.
        for s in [1.0, 3.0] {
            let a = t.mean_over([DVec2::ZERO, DVec2::new(s, 0.0), DVec2::new(s, 1.0)]);
            let b = t.mean_over([DVec2::ZERO, DVec2::new(s, 1.0), DVec2::new(0.0, 1.0)]);
            for c in 0..3 {
                // 16 samples of a two-valued image: the average of both halves is within one
                // sample's weight (1/16) of the mean.
                assert!(
                    ((a[c] + b[c]) / 2.0 - t.mean[c]).abs() <= 1.0 / 16.0 + 1e-12,
                    "{a:?} {b:?}"
                );
            }
        }
    }

    #[test]
    fn large_images_are_reduced_and_keep_their_mean() {
        let (w, h) = (1000, 300);
        let texels: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                if (i % w) < w / 2 {
                    [1.0, 0.0, 0.0]
                } else {
                    [0.0, 0.0, 1.0]
                }
            })
            .collect();
        let t = Texture::new("big".into(), w, h, texels, [0.5, 0.0, 0.5]).unwrap();
        assert!(t.levels[0].width <= MAX_SIDE as usize && t.levels[0].height <= MAX_SIDE as usize);
        let top = t.levels.last().unwrap();
        assert_eq!((top.width, top.height), (1, 1));
        assert!(
            (f64::from(top.texels[0][0]) - 0.5).abs() < 0.02,
            "{:?}",
            top.texels[0]
        );
    }
}
