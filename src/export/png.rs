//! Pictures of a baked mesh: one primary ray per sub-pixel through the BVH, shaded with the
//! baked vertex radiance interpolated across the hit face (or the face's own patch radiance
//! with `flat`), then the same exposure and sRGB mapping as the vertex colours. This module
//! owns the camera and the image; it does no lighting of its own (a radiosity solution is
//! view-independent: the picture is a look-up).

use std::path::Path;

use glam::DVec3;
use image::{Rgb, RgbImage};
use rayon::prelude::*;

use super::colour::radiance_to_srgb8;
use super::BakedMesh;
use crate::visibility::{Visibility, NONE};
use crate::{Error, Result};

/// A pinhole camera.
#[derive(Debug, Clone, Copy)]
pub struct Camera {
    /// Eye position, scene units.
    pub eye: DVec3,
    /// Point looked at, scene units.
    pub target: DVec3,
    /// Up direction (need not be unit or orthogonal to the view direction).
    pub up: DVec3,
    /// Vertical field of view, degrees, in (0, 180).
    pub vfov_degrees: f64,
}

impl Camera {
    /// The default view: looking along +z at the centre of the bounding box [lo, hi] from in
    /// front of it (its −z side), up +y, 39.3° vertical field of view (the Cornell box's
    /// published camera lens), far enough back that the box's front face fills the picture
    /// height. For the Cornell box this puts the eye at about (278, 274, −770), close to the
    /// published (278, 273, −800).
    pub fn framing(lo: DVec3, hi: DVec3) -> Camera {
        let vfov_degrees = 2.0 * (12.5f64 / 35.0).atan().to_degrees();
        let centre = 0.5 * (lo + hi);
        let half = 0.5 * (hi - lo);
        let half_extent = half.x.max(half.y);
        let distance = half_extent / (0.5 * vfov_degrees.to_radians()).tan() + half.z;
        Camera {
            eye: centre - DVec3::Z * distance,
            target: centre,
            up: DVec3::Y,
            vfov_degrees,
        }
    }
}

/// Render `mesh` as seen by `camera` into a `width` × `height` picture, with `spp`² stratified
/// samples per pixel. Back faces and misses are black.
pub fn render(
    mesh: &BakedMesh,
    camera: &Camera,
    width: u32,
    height: u32,
    spp: u32,
    exposure: f64,
    flat: bool,
) -> RgbImage {
    let tris: Vec<[DVec3; 3]> = mesh
        .faces
        .iter()
        .map(|f| f.map(|v| DVec3::from_array(mesh.positions[v as usize])))
        .collect();
    let vis = Visibility::build(&tris);
    let forward = (camera.target - camera.eye).normalize();
    let right = forward.cross(camera.up).normalize();
    let up = right.cross(forward);
    let tan_half = (0.5 * camera.vfov_degrees.to_radians()).tan();
    let aspect = width as f64 / height as f64;
    let spp = spp.max(1);
    let mut pixels = vec![[0u8; 3]; (width * height) as usize];
    pixels
        .par_chunks_mut(width as usize)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, px) in row.iter_mut().enumerate() {
                let mut sum = [0.0; 3];
                for sy in 0..spp {
                    for sx in 0..spp {
                        let fx = (x as f64 + (sx as f64 + 0.5) / spp as f64) / width as f64;
                        let fy = (y as f64 + (sy as f64 + 0.5) / spp as f64) / height as f64;
                        let dir = forward
                            + right * ((2.0 * fx - 1.0) * tan_half * aspect)
                            + up * ((1.0 - 2.0 * fy) * tan_half);
                        let l = shade(mesh, &tris, &vis, camera.eye, dir, flat);
                        for c in 0..3 {
                            sum[c] += l[c];
                        }
                    }
                }
                let n = (spp * spp) as f64;
                *px = radiance_to_srgb8([sum[0] / n, sum[1] / n, sum[2] / n], exposure);
            }
        });
    RgbImage::from_fn(width, height, |x, y| Rgb(pixels[(y * width + x) as usize]))
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
    super::write_atomic(path, &bytes)
}
