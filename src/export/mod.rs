//! Writing the baked mesh to disk for MeshLab. This module owns the hand-off type
//! [`BakedMesh`] and its validation, the choice of [`Format`] from the output path, the
//! default exposure rule ([`auto_exposure`]) and the atomic replacement of the output file
//! ([`write()`]: temporary file in the same directory, sync, rename). The byte layout of each
//! format lives in [`ply`] and [`obj`] (with readers for our own files, used by the tests and
//! by later tools); the radiance → 8-bit sRGB pipeline lives in [`colour`]. It does not bake
//! radiance into vertices (that is `bake`) and it does not read scenes (that is `scene`).

pub mod colour;
pub mod obj;
pub mod ply;
pub mod png;

use std::ffi::OsString;
use std::fs::{self, File};
use std::io::{self, BufWriter, Write};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::camera::Camera;
use crate::{Error, Result};

/// A mesh ready to write: baked vertices (split at creases and material borders) and patch faces.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BakedMesh {
    /// Vertex positions, scene units; finite and representable as `f32` (both formats store `f32`).
    pub positions: Vec<[f64; 3]>,
    /// Baked vertex radiance, linear, W·sr⁻¹·m⁻² per RGB channel; finite and >= 0.
    /// One entry per position.
    pub vertex_radiance: Vec<[f64; 3]>,
    /// Triangles (indices into positions), counter-clockwise seen from the front side.
    pub faces: Vec<[u32; 3]>,
    /// Solved radiance of each face's patch, W·sr⁻¹·m⁻² per RGB channel; finite and >= 0.
    /// One entry per face (PLY only: OBJ has nowhere to put it).
    pub face_radiance: Vec<[f64; 3]>,
    /// The scene file's camera, repeated in the output (`comment camera: …` in PLY, `# camera:
    /// …` in OBJ) so a picture of the baked file uses it too; `None` if the scene had none.
    pub camera: Option<Camera>,
}

impl BakedMesh {
    /// Checks the invariants the writers rely on: per-vertex and per-face arrays have matching
    /// lengths, every index is in range (and fits the PLY `int` index type), every value is
    /// finite and fits in `f32`, and radiance is >= 0. A failure is an [`Error::Internal`]:
    /// the bake stage is supposed to guarantee all of this.
    pub fn validate(&self) -> Result<()> {
        let bad = |message: String| Err(Error::Internal(format!("baked mesh: {message}")));
        if self.vertex_radiance.len() != self.positions.len() {
            return bad(format!(
                "{} vertex radiance values for {} vertices",
                self.vertex_radiance.len(),
                self.positions.len()
            ));
        }
        if self.face_radiance.len() != self.faces.len() {
            return bad(format!(
                "{} face radiance values for {} faces",
                self.face_radiance.len(),
                self.faces.len()
            ));
        }
        // PLY stores indices as `int`; every index must fit even though ours are u32.
        if self.positions.len() > i32::MAX as usize + 1 {
            return bad(format!(
                "{} vertices exceed the PLY index range",
                self.positions.len()
            ));
        }
        let fits_f32 = |v: f64| v.is_finite() && v.abs() <= f32::MAX as f64;
        for (i, p) in self.positions.iter().enumerate() {
            if !p.iter().all(|&c| fits_f32(c)) {
                return bad(format!("vertex {i} position {p:?} is not a finite f32"));
            }
        }
        let radiance_ok = |r: &[f64; 3]| r.iter().all(|&c| fits_f32(c) && c >= 0.0);
        for (i, r) in self.vertex_radiance.iter().enumerate() {
            if !radiance_ok(r) {
                return bad(format!(
                    "vertex {i} radiance {r:?} is not finite and >= 0 (or exceeds f32)"
                ));
            }
        }
        for (i, f) in self.faces.iter().enumerate() {
            if let Some(&v) = f.iter().find(|&&v| v as usize >= self.positions.len()) {
                return bad(format!(
                    "face {i} refers to vertex {v} but there are {} vertices",
                    self.positions.len()
                ));
            }
        }
        for (i, r) in self.face_radiance.iter().enumerate() {
            if !radiance_ok(r) {
                return bad(format!(
                    "face {i} radiance {r:?} is not finite and >= 0 (or exceeds f32)"
                ));
            }
        }
        Ok(())
    }
}

/// Output file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// PLY 1.0: `uchar` sRGB colours for MeshLab plus `float` radiance per vertex and per face;
    /// `binary_little_endian` unless `ascii`.
    Ply { ascii: bool },
    /// Wavefront OBJ with `v x y z r g b` vertex colours (no radiance values).
    Obj,
}

impl Format {
    /// The format named by the output path's extension (`.ply` / `.obj`, case-insensitive);
    /// `ascii` selects ASCII PLY and is ignored for OBJ. Any other extension is an
    /// [`Error::Usage`] naming the path and the supported extensions.
    pub fn from_path(path: &Path, ascii: bool) -> Result<Format> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("ply") => Ok(Format::Ply { ascii }),
            Some("obj") => Ok(Format::Obj),
            _ => Err(Error::usage(
                "output",
                format!(
                    "{}: unsupported output extension (supported: .ply, .obj)",
                    path.display()
                ),
            )),
        }
    }
}

/// Exposure: the factor radiance is multiplied by before the sRGB curve.
///
/// Rule: let Y = 0.2126 R + 0.7152 G + 0.0722 B (Rec.709 / sRGB luminance of the linear
/// radiance) for every vertex; over the vertices with Y > 0 take the 95th percentile of Y by
/// nearest rank (the value at 1-based rank ⌈0.95 n⌉ of the n values sorted ascending);
/// the exposure is 1 / that value. So at most the brightest 5 % of lit vertices (typically
/// the emitters) have luminance above 1 and saturate; unlit vertices do not count, so a large
/// shadowed area does not push the exposure up. If no vertex has Y > 0 the exposure is 1.
/// (Subnormal Y counts as 0, so the result is always finite.) Deterministic: it depends only
/// on the multiset of vertex radiances, not on their order or on threads.
pub fn auto_exposure(mesh: &BakedMesh) -> f64 {
    colour::auto_exposure(&mesh.vertex_radiance)
}

/// Writes `mesh` to `path` in `format`, with colours sRGB(radiance · `exposure`).
///
/// The write is atomic: the file is written through a buffer to a temporary file in the same
/// directory (`.<name>.tmp-<pid>-<n>`), flushed and synced, then renamed over `path`. On any
/// error the temporary file is removed and an existing file at `path` is left untouched.
/// Errors: [`Error::Internal`] if [`BakedMesh::validate`] fails, [`Error::Usage`] if
/// `exposure` is not finite and > 0, [`Error::Io`] naming `path` for any file-system failure
/// (including a missing output directory).
pub fn write(path: &Path, mesh: &BakedMesh, format: Format, exposure: f64) -> Result<()> {
    mesh.validate()?;
    if !(exposure.is_finite() && exposure > 0.0) {
        return Err(Error::usage(
            "exposure",
            format!("{exposure} is not a finite number > 0"),
        ));
    }
    write_atomically(path, |w| match format {
        Format::Ply { ascii } => ply::write_to(w, mesh, exposure, ascii),
        Format::Obj => obj::write_to(w, mesh, exposure),
    })
}

/// Writes `bytes` to `path` atomically (see [`write()`]); used for reports.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically(path, |w| w.write_all(bytes))
}

/// Checks, before any work, that `path`'s directory exists, so a long run does not end in an
/// error it could have reported at once. [`Error::Io`] naming `path` otherwise.
pub fn check_output_dir(path: &Path) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if dir.is_dir() {
        Ok(())
    } else {
        let message = format!("output directory {} does not exist", dir.display());
        Err(Error::io(
            path,
            io::Error::new(io::ErrorKind::NotFound, message),
        ))
    }
}

/// What [`ply::read`] and [`obj::read`] give back from one of our files.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadBack {
    /// Vertex positions as stored (`f32`), scene units.
    pub positions: Vec<[f32; 3]>,
    /// 8-bit sRGB vertex colours as MeshLab sees them (for OBJ, ⌊c · 255⌋ like MeshLab).
    pub colours: Vec<[u8; 3]>,
    /// Vertex radiance, W·sr⁻¹·m⁻² per RGB channel (PLY only; `None` for OBJ).
    pub vertex_radiance: Option<Vec<[f32; 3]>>,
    /// Triangles, 0-based indices into `positions`.
    pub faces: Vec<[u32; 3]>,
    /// Face radiance, W·sr⁻¹·m⁻² per RGB channel (PLY only; `None` for OBJ).
    pub face_radiance: Option<Vec<[f32; 3]>>,
    /// The camera line of the file (`comment camera: …` / `# camera: …`), if it has one.
    pub camera: Option<Camera>,
}

/// Buffer size for writers: large enough that 100k+ vertices cost few system calls.
const WRITE_BUFFER: usize = 1 << 16;

/// Runs `body` on a buffered temporary file next to `path`, then syncs it and renames it over
/// `path`; removes the temporary file if anything fails. Every error names `path`.
fn write_atomically(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> Result<()> {
    // Distinguishes concurrent writes to the same path from one process.
    static COUNTER: AtomicU64 = AtomicU64::new(0);

    let name = path.file_name().ok_or_else(|| {
        Error::io(
            path,
            io::Error::new(io::ErrorKind::InvalidInput, "output path has no file name"),
        )
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut tmp_name = OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(
        ".tmp-{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let tmp = dir.join(tmp_name);

    let file = File::create(&tmp).map_err(|e| {
        if e.kind() == io::ErrorKind::NotFound {
            let message = format!("output directory {} does not exist", dir.display());
            Error::io(path, io::Error::new(e.kind(), message))
        } else {
            Error::io(path, e)
        }
    })?;
    let result = (|| {
        let mut w = BufWriter::with_capacity(WRITE_BUFFER, file);
        body(&mut w)?;
        w.flush()?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        // Best effort: the original error is the one worth reporting.
        let _ = fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

#[cfg(test)]
pub(crate) mod test_support {
    //! Scratch directories and a small mesh shared by the export tests.

    use super::BakedMesh;
    use std::path::{Path, PathBuf};
    use std::sync::atomic::{AtomicU64, Ordering};

    /// A fresh directory under the system temp dir, removed on drop.
    pub struct TestDir(PathBuf);

    impl TestDir {
        pub fn new(tag: &str) -> TestDir {
            static N: AtomicU64 = AtomicU64::new(0);
            let dir = std::env::temp_dir().join(format!(
                "radiosity-export-{tag}-{}-{}",
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
        // SplitMix64, fixed seed.
        let mut state = 0x9E37_79B9_7F4A_7C15_u64;
        let mut next = move || {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        };
        let mut unit = move || (next() >> 11) as f64 / (1u64 << 53) as f64;
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
        }
    }
}

#[cfg(test)]
mod tests {
    use super::test_support::{sample_mesh, TestDir};
    use super::*;

    #[test]
    fn format_from_extension_is_case_insensitive() {
        assert_eq!(
            Format::from_path(Path::new("out/Scene.PLY"), false).unwrap(),
            Format::Ply { ascii: false }
        );
        assert_eq!(
            Format::from_path(Path::new("scene.ply"), true).unwrap(),
            Format::Ply { ascii: true }
        );
        assert_eq!(
            Format::from_path(Path::new("scene.obj"), true).unwrap(),
            Format::Obj
        );
        assert_eq!(
            Format::from_path(Path::new("scene.Obj"), false).unwrap(),
            Format::Obj
        );
    }

    #[test]
    fn format_from_unknown_extension_names_path_and_choices() {
        for p in ["scene.stl", "scene", "ply"] {
            let err = Format::from_path(Path::new(p), false).unwrap_err();
            assert!(matches!(err, Error::Usage { .. }), "{err:?}");
            let text = err.to_string();
            assert!(text.contains(p) && text.contains(".ply") && text.contains(".obj"));
        }
    }

    #[test]
    fn validate_rejects_each_broken_invariant() {
        let good = sample_mesh(10, 6);
        good.validate().unwrap();
        let mut breakages: Vec<(BakedMesh, &str)> = Vec::new();
        let mut m = good.clone();
        m.vertex_radiance.pop();
        breakages.push((m, "vertex radiance values"));
        let mut m = good.clone();
        m.face_radiance.push([0.0; 3]);
        breakages.push((m, "face radiance values"));
        let mut m = good.clone();
        m.faces[3][1] = 10;
        breakages.push((m, "face 3 refers to vertex 10"));
        let mut m = good.clone();
        m.positions[2][0] = f64::INFINITY;
        breakages.push((m, "vertex 2 position"));
        let mut m = good.clone();
        m.positions[2][0] = 1e39;
        breakages.push((m, "vertex 2 position"));
        let mut m = good.clone();
        m.vertex_radiance[4][2] = f64::NAN;
        breakages.push((m, "vertex 4 radiance"));
        let mut m = good.clone();
        m.vertex_radiance[4][2] = -1e-9;
        breakages.push((m, "vertex 4 radiance"));
        let mut m = good.clone();
        m.face_radiance[5][0] = f64::NAN;
        breakages.push((m, "face 5 radiance"));
        for (mesh, needle) in breakages {
            let err = mesh.validate().unwrap_err();
            assert!(matches!(err, Error::Internal(_)));
            assert!(err.to_string().contains(needle), "{err} lacks {needle}");
        }
    }

    #[test]
    fn failed_write_leaves_existing_file_untouched_and_no_temp_file() {
        let dir = TestDir::new("atomic");
        for format in [Format::Ply { ascii: false }, Format::Obj] {
            let path = dir.path().join("out.ply");
            fs::write(&path, b"old contents").unwrap();

            let mut bad = sample_mesh(10, 4);
            bad.vertex_radiance[7][1] = f64::NAN;
            assert!(write(&path, &bad, format, 1.0).is_err());
            let good = sample_mesh(10, 4);
            let err = write(&path, &good, format, f64::NAN).unwrap_err();
            assert!(matches!(err, Error::Usage { .. }), "{err:?}");

            assert_eq!(fs::read(&path).unwrap(), b"old contents");
            assert_eq!(dir.entries(), ["out.ply"]);
        }
    }

    #[test]
    fn failed_rename_removes_temp_file() {
        // The target is a directory: the temporary file is written, then the rename fails.
        let dir = TestDir::new("rename");
        let path = dir.path().join("taken.ply");
        fs::create_dir(&path).unwrap();
        let err = write(&path, &sample_mesh(5, 2), Format::Ply { ascii: true }, 1.0).unwrap_err();
        assert!(matches!(err, Error::Io { .. }), "{err:?}");
        assert!(err.to_string().contains("taken.ply"));
        assert_eq!(dir.entries(), ["taken.ply"]);
        assert!(path.is_dir());
    }

    #[test]
    fn successful_write_replaces_file_and_leaves_no_temp_file() {
        let dir = TestDir::new("replace");
        let path = dir.path().join("out.obj");
        fs::write(&path, b"old contents").unwrap();
        write(&path, &sample_mesh(5, 2), Format::Obj, 1.0).unwrap();
        assert!(fs::read(&path).unwrap().starts_with(b"# radiosity"));
        assert_eq!(dir.entries(), ["out.obj"]);
    }

    #[test]
    fn missing_directory_is_io_error_naming_the_path() {
        let dir = TestDir::new("missing");
        let path = dir.path().join("no-such-dir").join("out.ply");
        let err = write(&path, &sample_mesh(3, 1), Format::Ply { ascii: false }, 1.0).unwrap_err();
        match &err {
            Error::Io { path: p, source } => {
                assert_eq!(p, &path);
                assert_eq!(source.kind(), io::ErrorKind::NotFound);
            }
            other => panic!("expected Error::Io, got {other:?}"),
        }
        let text = err.to_string();
        assert!(text.contains(&*path.to_string_lossy()), "{text}");
        assert!(text.contains("does not exist"), "{text}");
        assert_eq!(dir.entries(), Vec::<String>::new());
    }

    #[test]
    fn auto_exposure_uses_lit_vertices_95th_percentile() {
        // 100 black vertices and grey vertices with Y = 1..=20 (times a scale), in scrambled
        // order. Over the 20 lit vertices the nearest rank is ⌈0.95 · 20⌉ = 19, so the
        // exposure is 1 / (19 · scale); counting the black ones would give rank 114 of 120,
        // i.e. Y = 14.
        let scale = 0.37;
        let mut radiance = vec![[0.0; 3]; 100];
        for k in 1..=20 {
            let y = k as f64 * scale;
            radiance.push([y, y, y]);
        }
        radiance.reverse();
        radiance.swap(3, 110);
        let mesh = BakedMesh {
            positions: vec![[0.0; 3]; radiance.len()],
            vertex_radiance: radiance,
            ..BakedMesh::default()
        };
        let y19 = colour::luminance([19.0 * scale; 3]);
        assert_eq!(auto_exposure(&mesh), 1.0 / y19);
        assert!((auto_exposure(&mesh) * 19.0 * scale - 1.0).abs() < 1e-12);
    }

    #[test]
    fn auto_exposure_weights_channels_by_luminance() {
        // Only blue: Y = 0.0722 · B; one lit vertex is its own 95th percentile.
        let mesh = BakedMesh {
            positions: vec![[0.0; 3]; 2],
            vertex_radiance: vec![[0.0, 0.0, 2.0], [0.0; 3]],
            ..BakedMesh::default()
        };
        assert_eq!(auto_exposure(&mesh), 1.0 / (0.0722 * 2.0));
    }

    #[test]
    fn auto_exposure_of_black_mesh_is_one() {
        let mesh = BakedMesh {
            positions: vec![[0.0; 3]; 3],
            vertex_radiance: vec![[0.0; 3]; 3],
            ..BakedMesh::default()
        };
        assert_eq!(auto_exposure(&mesh), 1.0);
        assert_eq!(auto_exposure(&BakedMesh::default()), 1.0);
    }
}
