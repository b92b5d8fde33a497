//! Helpers shared by the library's unit tests: scratch directories, a small baked mesh
//! with awkward values and the statistics of repeated random estimates.

use crate::bake::BakedMesh;
use crate::scene::SceneBuilder;
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A fresh directory under the system temp dir, removed on drop.
pub struct TestDir(PathBuf);

impl TestDir {
    pub fn new(tag: &str) -> TestDir {
        static N: AtomicU64 = AtomicU64::new(0);
        let dir = std::env::temp_dir().join(format!(
            "radiosity-unit-{tag}-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TestDir(dir)
    }

    pub fn path(&self) -> &Path {
        &self.0
    }

    /// Writes `bytes` as the file `name` in the directory and returns its path.
    pub fn write(&self, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
        let path = self.0.join(name);
        std::fs::write(&path, bytes).unwrap();
        path
    }

    /// Names of the directory's entries, sorted.
    pub fn entries(&self) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(&self.0)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }
}

impl Drop for TestDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A small seeded pseudo-random mesh with awkward values: tiny, huge, negative positions,
/// zero and saturating radiance.
pub fn sample_mesh(vertices: usize, faces: usize) -> BakedMesh {
    let mut rng = crate::sampling::Rng::new(&[0x5EED]);
    let mut unit = move || rng.next_f64();
    let mut positions = Vec::new();
    let mut vertex_radiance = Vec::new();
    for i in 0..vertices {
        let scale = [1e-6, 1.0, 1e3, 1e12][i % 4];
        positions.push([
            (unit() - 0.5) * scale,
            (unit() - 0.5) * scale,
            (unit() - 0.5) * scale,
        ]);
        let r = match i % 5 {
            0 => [0.0, 0.0, 0.0],
            1 => [3.0 * unit(), 20.0, 0.5],
            _ => [unit(), unit() * 0.01, unit() * 2.0],
        };
        vertex_radiance.push(r);
    }
    let mut face_list = Vec::new();
    let mut face_radiance = Vec::new();
    for _ in 0..faces {
        face_list.push([
            (unit() * vertices as f64) as u32,
            (unit() * vertices as f64) as u32,
            (unit() * vertices as f64) as u32,
        ]);
        face_radiance.push([unit() * 5.0, 0.0, unit() * 1e-3]);
    }
    BakedMesh {
        positions,
        vertex_radiance,
        faces: face_list,
        face_radiance,
        camera: None,
        sky: None,
    }
}

/// The 8-bit sRGB colours the writers give `mesh`'s vertices at `exposure`.
pub fn srgb_colours(mesh: &BakedMesh, exposure: f64) -> Vec<[u8; 3]> {
    mesh.vertex_radiance
        .iter()
        .map(|&r| crate::color::radiance_to_srgb8(r, exposure))
        .collect()
}

/// Adds a 4 × 4 ceiling at `height` (facing down, material `ceiling`) and a 1 × 1 light
/// (facing down, material `light`) `gap` below it, its lowest corner at `corner` (x, y).
pub fn ceiling_with_mounted_light(
    b: &mut SceneBuilder,
    (ceiling, light): (u32, u32),
    height: f64,
    gap: f64,
    [x, y]: [f64; 2],
) {
    let v = DVec3::new;
    b.quad(
        [
            v(0., 0., height),
            v(0., 4., height),
            v(4., 4., height),
            v(4., 0., height),
        ],
        ceiling,
    );
    let h = height - gap;
    b.quad(
        [
            v(x, y, h),
            v(x, y + 1.0, h),
            v(x + 1.0, y + 1.0, h),
            v(x + 1.0, y, h),
        ],
        light,
    );
}

/// The mean of `calls`, their sample variance and the standard error of the mean.
pub fn mean_variance_error(calls: &[f64]) -> (f64, f64, f64) {
    let n = calls.len() as f64;
    let mean = calls.iter().sum::<f64>() / n;
    let var = calls.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var, (var / n).sqrt())
}
