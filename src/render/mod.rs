//! Pictures of a baked mesh: one primary ray per sub-pixel through the BVH, shaded with the
//! baked vertex radiance interpolated across the hit face (or the face's own patch radiance
//! with `flat`), then the same exposure and sRGB mapping as the vertex colours. This module
//! owns the image and the choice of camera ([`camera_for`]; the [`Camera`] itself is scene data,
//! [`crate::scene::camera`]); it does no lighting of its own (a
//! radiosity solution is view-independent: the picture is a look-up). A surface made of a
//! face and its reversed twin over the same corners (a two-sided bake) shows each side's own
//! radiance: the BVH reports the face whose front faces the ray ([`Visibility::closest_hit`]).

use std::path::Path;

use glam::DVec3;
use image::{Rgb, RgbImage};
use rayon::prelude::*;

use crate::bake::BakedMesh;
use crate::color::{luminance, radiance_to_srgb8};
pub use crate::scene::camera::{Camera, Up};
use crate::visibility::{Visibility, NONE};
use crate::{Error, Result};

/// What a picture shows and how.
#[derive(Debug, Clone, Copy)]
pub struct View {
    pub camera: Camera,
    /// Picture size, pixels.
    pub width: u32,
    pub height: u32,
    /// Samples per pixel along each axis (spp² stratified rays per pixel).
    pub spp: u32,
    /// Each face's own patch radiance instead of the interpolated vertex radiance.
    pub flat: bool,
    /// Luminance on a colour scale (with a legend) instead of sRGB colours.
    pub false_colour: bool,
    /// Radiance multiplier before the sRGB curve (for false colour: the luminance at the top
    /// of the scale is 1/exposure).
    pub exposure: f64,
}

/// Largest picture side, pixels.
pub const MAX_SIZE: u32 = 16384;

/// Most samples per pixel along each axis.
pub const MAX_SPP: u32 = 16;

impl View {
    /// Checks the ranges: width and height in 1..=[`MAX_SIZE`], `spp` in 1..=[`MAX_SPP`],
    /// exposure finite and > 0. Errors are [`Error::Setting`] named `view.size`, `view.spp`,
    /// `exposure`.
    pub fn validate(&self) -> Result<()> {
        let side = 1..=MAX_SIZE;
        if !(side.contains(&self.width) && side.contains(&self.height)) {
            return Err(Error::setting(
                "view.size",
                format!(
                    "{}x{} is not within 1..={MAX_SIZE} pixels each way",
                    self.width, self.height
                ),
            ));
        }
        if !(1..=MAX_SPP).contains(&self.spp) {
            return Err(Error::setting(
                "view.spp",
                format!("{} is not in 1..={MAX_SPP}", self.spp),
            ));
        }
        crate::color::check_exposure(self.exposure)
    }
}

/// The camera a picture of `mesh` is taken with: `given` if there is one, else the camera the
/// scene file carried ([`BakedMesh::camera`]), else the framing of the mesh's bounding box
/// around `up` that sees the most front faces ([`best_framing`]).
pub fn camera_for(mesh: &BakedMesh, given: Option<Camera>, up: Up) -> Camera {
    given
        .or(mesh.camera)
        .unwrap_or_else(|| best_framing(&triangles(mesh), up))
}

/// The mesh's faces as corner triples, scene units.
fn triangles(mesh: &BakedMesh) -> Vec<[DVec3; 3]> {
    mesh.faces
        .iter()
        .map(|f| f.map(|v| DVec3::from_array(mesh.positions[v as usize])))
        .collect()
}

/// Rays per side of the grid [`coverage`] casts.
pub const COVERAGE_GRID: u32 = 24;

/// Of the five framings of the bounding box of `triangles` for `up` ([`Camera::framings`]:
/// four sides and above), the one whose picture shows the most front faces ([`coverage`]);
/// the first on a tie. A box
/// open on one side (McGuire's Cornell box opens toward +z) is looked into through its
/// opening, and a z-up level is seen level with `Up::Z`.
pub fn best_framing(triangles: &[[DVec3; 3]], up: Up) -> Camera {
    let (lo, hi) = triangles
        .iter()
        .flatten()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    let framings = Camera::framings(lo, hi, up);
    if triangles.is_empty() {
        return framings[0];
    }
    let vis = Visibility::build(triangles);
    let mut best = (framings[0], -1.0);
    for c in framings {
        let seen = coverage(triangles, &vis, &c, COVERAGE_GRID);
        if seen > best.1 {
            best = (c, seen);
        }
    }
    best.0
}

/// The share of a `grid` × `grid` set of primary rays of `camera` (square picture) that meet
/// the front of a face of `triangles` (`vis` built over them): 0 when the picture would show
/// only black (misses and backs).
pub fn coverage(triangles: &[[DVec3; 3]], vis: &Visibility, camera: &Camera, grid: u32) -> f64 {
    let forward = (camera.target - camera.eye).normalize();
    let right = forward.cross(camera.up).normalize();
    let up = right.cross(forward);
    let tan_half = (0.5 * camera.vfov_degrees.to_radians()).tan();
    let mut seen = 0u32;
    for y in 0..grid {
        for x in 0..grid {
            let fx = (x as f64 + 0.5) / grid as f64;
            let fy = (y as f64 + 0.5) / grid as f64;
            let dir = forward
                + right * ((2.0 * fx - 1.0) * tan_half)
                + up * ((1.0 - 2.0 * fy) * tan_half);
            if let Some(hit) = vis.closest_hit(camera.eye, dir, f64::INFINITY, NONE) {
                let [a, b, c] = triangles[hit.triangle as usize];
                if (b - a).cross(c - a).dot(dir) < 0.0 {
                    seen += 1;
                }
            }
        }
    }
    seen as f64 / (grid * grid) as f64
}

/// True if a picture of `mesh` with `camera` would show only black: no ray of a
/// [`COVERAGE_GRID`]² grid meets the front of a face (a closed room seen from outside, or a
/// framing that looks at the backs of walls).
pub fn sees_nothing(mesh: &BakedMesh, camera: &Camera) -> bool {
    let tris = triangles(mesh);
    let vis = Visibility::build(&tris);
    coverage(&tris, &vis, camera, COVERAGE_GRID) == 0.0
}

/// Render `mesh` as `view` says (a [`View::validate`]d view). Back faces and misses are black.
pub fn render(mesh: &BakedMesh, view: &View) -> RgbImage {
    let tris = triangles(mesh);
    let vis = Visibility::build(&tris);
    let camera = &view.camera;
    let (width, height) = (view.width, view.height);
    let forward = (camera.target - camera.eye).normalize();
    let right = forward.cross(camera.up).normalize();
    let up = right.cross(forward);
    let tan_half = (0.5 * camera.vfov_degrees.to_radians()).tan();
    let aspect = width as f64 / height as f64;
    let spp = view.spp.max(1);
    let mut pixels = vec![[0u8; 3]; (width * height) as usize];
    let progress = crate::progress::stage("render", Some(height as u64));
    pixels
        .par_chunks_mut(width as usize)
        .enumerate()
        .for_each(|(y, row)| {
            progress.advance(1);
            for (x, px) in row.iter_mut().enumerate() {
                let mut sum = [0.0; 3];
                for sy in 0..spp {
                    for sx in 0..spp {
                        let fx = (x as f64 + (sx as f64 + 0.5) / spp as f64) / width as f64;
                        let fy = (y as f64 + (sy as f64 + 0.5) / spp as f64) / height as f64;
                        let dir = forward
                            + right * ((2.0 * fx - 1.0) * tan_half * aspect)
                            + up * ((1.0 - 2.0 * fy) * tan_half);
                        let l = shade(mesh, &tris, &vis, camera.eye, dir, view.flat);
                        for (s, l) in sum.iter_mut().zip(l) {
                            *s += l;
                        }
                    }
                }
                let n = (spp * spp) as f64;
                let mean = sum.map(|s| s / n);
                *px = if view.false_colour {
                    false_colour(luminance(mean) * view.exposure)
                } else {
                    radiance_to_srgb8(mean, view.exposure)
                };
            }
        });
    let mut image = RgbImage::from_fn(width, height, |x, y| Rgb(pixels[(y * width + x) as usize]));
    if view.false_colour {
        draw_legend(&mut image, 1.0 / view.exposure);
    }
    image
}

/// A perceptually ordered scale (control points of matplotlib's viridis) for t in [0, 1];
/// values above 1 are white, so saturation is visible.
pub fn false_colour(t: f64) -> [u8; 3] {
    const STOPS: [[f64; 3]; 5] = [
        [68.0, 1.0, 84.0],
        [59.0, 82.0, 139.0],
        [33.0, 145.0, 140.0],
        [94.0, 201.0, 98.0],
        [253.0, 231.0, 37.0],
    ];
    if t.is_nan() || t <= 0.0 {
        return [0, 0, 0];
    }
    if t > 1.0 {
        return [255, 255, 255];
    }
    let x = t * (STOPS.len() - 1) as f64;
    let k = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - k as f64;
    std::array::from_fn(|c| (STOPS[k][c] * (1.0 - f) + STOPS[k + 1][c] * f).round() as u8)
}

/// A colour bar along the bottom with its end values (luminance, W·sr⁻¹·m⁻²) written in a
/// built-in 3×5 pixel font, so no font file is needed.
fn draw_legend(image: &mut RgbImage, top: f64) {
    let (w, h) = image.dimensions();
    if w < 64 || h < 64 {
        return;
    }
    let bar = (h / 20).max(8);
    let y0 = h - bar - 14;
    for y in y0 - 2..h {
        for x in 0..w {
            image.put_pixel(x, y, Rgb([0, 0, 0]));
        }
    }
    for x in 4..w - 4 {
        let t = (x - 4) as f64 / (w - 9) as f64;
        let c = false_colour(t.max(1e-9));
        for y in y0..y0 + bar {
            image.put_pixel(x, y, Rgb(c));
        }
    }
    let scale = 2;
    draw_text(image, 4, y0 + bar + 2, "0", scale);
    let label = format!("{top:.3e}");
    let width = label.len() as u32 * 4 * scale;
    draw_text(
        image,
        w.saturating_sub(width + 4),
        y0 + bar + 2,
        &label,
        scale,
    );
}

/// Draw `text` (digits, '.', '-', '+', 'e') with a 3×5 bitmap font, white, top-left at (x, y).
fn draw_text(image: &mut RgbImage, x: u32, y: u32, text: &str, scale: u32) {
    for (i, ch) in text.chars().enumerate() {
        let glyph: [u8; 5] = match ch {
            '0' => [7, 5, 5, 5, 7],
            '1' => [2, 6, 2, 2, 7],
            '2' => [7, 1, 7, 4, 7],
            '3' => [7, 1, 7, 1, 7],
            '4' => [5, 5, 7, 1, 1],
            '5' => [7, 4, 7, 1, 7],
            '6' => [7, 4, 7, 5, 7],
            '7' => [7, 1, 1, 1, 1],
            '8' => [7, 5, 7, 5, 7],
            '9' => [7, 5, 7, 1, 7],
            '.' => [0, 0, 0, 0, 2],
            '-' => [0, 0, 7, 0, 0],
            '+' => [0, 2, 7, 2, 0],
            'e' => [0, 7, 7, 4, 7],
            _ => [0; 5],
        };
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) != 0 {
                    for dy in 0..scale {
                        for dx in 0..scale {
                            let px = x + (i as u32 * 4 + col) * scale + dx;
                            let py = y + row as u32 * scale + dy;
                            if px < image.width() && py < image.height() {
                                image.put_pixel(px, py, Rgb([255, 255, 255]));
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Radiance seen along one primary ray.
fn shade(
    mesh: &BakedMesh,
    tris: &[[DVec3; 3]],
    vis: &Visibility,
    eye: DVec3,
    dir: DVec3,
    flat: bool,
) -> [f64; 3] {
    let Some(hit) = vis.closest_hit(eye, dir, f64::INFINITY, NONE) else {
        return [0.0; 3];
    };
    let f = hit.triangle as usize;
    let [a, b, c] = tris[f];
    if (b - a).cross(c - a).dot(dir) >= 0.0 {
        return [0.0; 3]; // the back of a one-sided surface
    }
    if flat {
        return mesh.face_radiance[f];
    }
    let w = [1.0 - hit.u - hit.v, hit.u, hit.v];
    let face = mesh.faces[f];
    let mut l = [0.0; 3];
    for (k, &v) in face.iter().enumerate() {
        for (lc, vc) in l.iter_mut().zip(mesh.vertex_radiance[v as usize]) {
            *lc += w[k] * vc;
        }
    }
    l
}

/// Save a picture as PNG, atomically (temporary file + rename).
pub fn save(path: &Path, image: &RgbImage) -> Result<()> {
    let mut bytes = Vec::new();
    image
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .map_err(|e| Error::Internal(format!("PNG encoding: {e}")))?;
    crate::io::write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn render_a_lit_quad_in_front_of_the_camera() {
        // One quad at z = 1 facing the camera (−z) with radiance 0.5: the centre pixel is
        // sRGB(0.5) = 188 at exposure 1, the corners (outside the quad) black.
        let mesh = BakedMesh {
            positions: vec![
                [-1.0, -1.0, 1.0],
                [1.0, -1.0, 1.0],
                [1.0, 1.0, 1.0],
                [-1.0, 1.0, 1.0],
            ],
            vertex_radiance: vec![[0.5; 3]; 4],
            faces: vec![[0, 2, 1], [0, 3, 2]],
            face_radiance: vec![[0.5; 3]; 2],
            camera: None,
        };
        let view = View {
            camera: Camera {
                eye: DVec3::new(0.0, 0.0, -1.0),
                target: DVec3::ZERO,
                up: DVec3::Y,
                vfov_degrees: 60.0,
            },
            width: 32,
            height: 32,
            spp: 1,
            flat: false,
            false_colour: false,
            exposure: 1.0,
        };
        let img = render(&mesh, &view);
        assert_eq!(img.get_pixel(16, 16).0, [188; 3]);
        // Seen from behind (the quad's back) everything is black.
        let back = View {
            camera: Camera {
                eye: DVec3::new(0.0, 0.0, 3.0),
                target: DVec3::ZERO,
                ..view.camera
            },
            ..view
        };
        assert_eq!(render(&mesh, &back).get_pixel(16, 16).0, [0; 3]);
        // False colour: luminance 0.5 at exposure 1 is the middle of the scale.
        let fc = render(
            &mesh,
            &View {
                false_colour: true,
                width: 128,
                height: 128,
                ..view
            },
        );
        assert_eq!(fc.get_pixel(64, 40).0, false_colour(0.5));
    }

    #[test]
    fn false_colour_scale_is_monotone_in_brightness() {
        let lum = |c: [u8; 3]| 0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64;
        let mut last = -1.0;
        for k in 1..=100 {
            let l = lum(false_colour(k as f64 / 100.0));
            assert!(l > last, "{k}");
            last = l;
        }
        assert_eq!(false_colour(2.0), [255; 3]);
        assert_eq!(false_colour(0.0), [0; 3]);
    }
}
