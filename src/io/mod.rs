//! Files in and out: scene files read into a [`Scene`] ([`Scene::load`]: OBJ + MTL through
//! [`obj`], PLY through [`ply`], glTF through [`gltf`], Mitsuba XML through [`mitsuba`]), baked
//! meshes written for MeshLab ([`write()`]: PLY or OBJ by the output's extension, see [`Format`])
//! and read back ([`ReadBack`], for tests, `render` and later tools), procedural scenes saved as
//! OBJ + MTL ([`obj::save`]), and the atomic replacement every writer goes through ([`atomic`]).
//! Each format keeps its reader and its writer together: [`ply`] (one header layer shared by the
//! scene reader and the read-back) and [`obj`] (one writer for scenes and baked meshes). It does
//! not bake radiance into vertices ([`crate::bake`]) or draw pictures ([`crate::render`]).

pub mod atomic;
pub mod gltf;
pub mod lights;
pub mod mitsuba;
pub mod obj;
pub mod ply;

use std::path::Path;

pub use atomic::{check_distinct, check_output_dir, write_atomic};

use crate::bake::BakedMesh;
use crate::scene::{Camera, Scene};
use crate::{Error, Result};

/// The mean colour of a texture as linear reflectance per RGB channel, in [0, 1]: each 8- or
/// 16-bit sRGB value decoded to linear (IEC 61966-2-1, [`crate::color::srgb_decode`]) before
/// averaging, alpha ignored, grey images read as grey. `None` for an image without pixels.
/// The OBJ loader's `map_Kd` and the glTF loader's base-colour and emissive textures.
pub(crate) fn texture_mean(image: image::DynamicImage) -> Option<crate::Rgb> {
    linear_texture(image, String::new()).map(|t| t.mean)
}

/// A texture's linear colour ([`crate::scene::Texture`]), decoded as [`texture_mean`] does and
/// box-filtered down, in linear values, to at most [`crate::scene::texture::MAX_SIDE`] texels a
/// side as it is read (blocks of f × f pixels, f the smallest integer that fits), with the
/// exact mean of the full image.
pub(crate) fn linear_texture(
    image: image::DynamicImage,
    source: String,
) -> Option<crate::scene::Texture> {
    let image = image.into_rgb16();
    let (w, h) = (image.width() as usize, image.height() as usize);
    if w == 0 || h == 0 {
        return None;
    }
    let linear: Vec<f64> = (0..=u16::MAX)
        .map(|c| crate::color::srgb_decode(f64::from(c) / 65535.0))
        .collect();
    let side = crate::scene::texture::MAX_SIDE as usize;
    let f = w.max(h).div_ceil(side);
    let (rw, rh) = (w.div_ceil(f), h.div_ceil(f));
    let mut blocks = vec![[0.0f64; 3]; rw * rh];
    let mut counts = vec![0u32; rw * rh];
    let mut sum = [0.0f64; 3];
    for (x, y, px) in image.enumerate_pixels() {
        let b = (y as usize / f) * rw + x as usize / f;
        counts[b] += 1;
        for c in 0..3 {
            let l = linear[px.0[c] as usize];
            blocks[b][c] += l;
            sum[c] += l;
        }
    }
    let texels = blocks
        .iter()
        .zip(&counts)
        .map(|(b, &n)| b.map(|v| (v / f64::from(n.max(1))) as f32))
        .collect();
    let n = (w * h) as f64;
    let mean = sum.map(|s| (s / n).clamp(0.0, 1.0));
    crate::scene::Texture::new(source, rw, rh, texels, mean)
}

/// `text` without the byte-order mark some Windows tools write at the start of a UTF-8 file
/// (U+FEFF): it is no part of the first statement, which would otherwise read as an unknown
/// keyword and be passed over (an OBJ's `mtllib`, and with it every material).
pub(crate) fn without_bom(text: String) -> String {
    match text.strip_prefix('\u{feff}') {
        Some(rest) => rest.to_string(),
        None => text,
    }
}

/// An [`Error::Parse`]: `message` about line `line` (1-based) of `path`.
pub(crate) fn parse_error(path: &Path, line: usize, message: impl Into<String>) -> Error {
    Error::Parse {
        path: path.to_path_buf(),
        line,
        message: message.into(),
    }
}

/// The files a scene file's reader reads beside it, those that exist: for an `.obj` (any
/// case, as [`Scene::load`] dispatches) its material libraries and their texture images
/// ([`obj::companion_files`]); none for the other formats. An output must not replace them.
pub fn companion_files(path: &Path) -> Vec<std::path::PathBuf> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    if ext.eq_ignore_ascii_case("obj") {
        obj::companion_files(path)
    } else {
        Vec::new()
    }
}

impl Scene {
    /// Loads a scene file, dispatching on the extension: `.obj` (any case) goes to
    /// [`obj::load`], `.ply` to [`ply::load`], `.gltf` and `.glb` to [`gltf::load`], `.xml`
    /// (a Mitsuba scene) to [`mitsuba::load`]. A missing path is [`Error::Io`], a directory or
    /// any other extension [`Error::Input`]; all name the path. (Defined here, with the
    /// readers, so that the scene model does not depend on the file formats.)
    pub fn load(path: &Path) -> Result<Scene> {
        let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
        if meta.is_dir() {
            return Err(Error::Input {
                path: path.to_path_buf(),
                message: "is a directory, expected a scene file (.obj, .ply, .gltf, .glb or .xml)"
                    .into(),
            });
        }
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        if ext.eq_ignore_ascii_case("obj") {
            obj::load(path)
        } else if ext.eq_ignore_ascii_case("ply") {
            ply::load(path)
        } else if ext.eq_ignore_ascii_case("gltf") || ext.eq_ignore_ascii_case("glb") {
            gltf::load(path)
        } else if ext.eq_ignore_ascii_case("xml") {
            mitsuba::load(path)
        } else {
            Err(Error::Input {
                path: path.to_path_buf(),
                message:
                    "unsupported scene format (expected a .obj, .ply, .gltf, .glb or .xml file)"
                        .into(),
            })
        }
    }
}

/// Output file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// PLY 1.0: `uchar` sRGB colours for MeshLab plus `float` radiance per vertex and per face
    /// (positions `float`, or `double` far from the origin for their size);
    /// `binary_little_endian` unless `ascii`.
    Ply { ascii: bool },
    /// Wavefront OBJ with `v x y z r g b` vertex colours (no radiance values).
    Obj,
    /// glTF 2.0 binary: linear `COLOR_0` and the radiance as `_RADIANCE` ([`gltf`]), the
    /// scene's `up` axis turned to glTF's +Y.
    Glb { up: crate::scene::Up },
}

impl Format {
    /// The format named by the output path's extension (`.ply` / `.obj`, case-insensitive);
    /// `ascii` selects ASCII PLY and is ignored otherwise; `.glb` is glTF with +Y up (set
    /// [`Format::Glb`]'s `up` to the scene's). Any other extension is an
    /// [`Error::Setting`] named `output`, naming the path and the supported extensions.
    pub fn from_path(path: &Path, ascii: bool) -> Result<Format> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("ply") => Ok(Format::Ply { ascii }),
            Some("obj") => Ok(Format::Obj),
            Some("glb") => Ok(Format::Glb {
                up: crate::scene::Up::Y,
            }),
            _ => Err(Error::setting(
                "output",
                format!(
                    "{}: unsupported output extension (supported: .ply, .obj, .glb)",
                    path.display()
                ),
            )),
        }
    }
}

/// Writes `mesh` to `path` in `format`, with colours sRGB(radiance · `exposure`).
///
/// The write is atomic: the file is written through a buffer to a temporary file in the same
/// directory (`.<name>.tmp-<pid>-<n>`), flushed and synced, then renamed over `path`. On any
/// error the temporary file is removed and an existing file at `path` is left untouched.
/// Errors: [`Error::Internal`] if [`BakedMesh::validate`] fails, [`Error::Setting`] named
/// `exposure` if it is not finite and > 0, [`Error::Io`] naming `path` for any file-system failure
/// (including a missing output directory).
pub fn write(path: &Path, mesh: &BakedMesh, format: Format, exposure: f64) -> Result<()> {
    mesh.validate()?;
    crate::color::check_exposure(exposure)?;
    atomic::write_atomically(path, |w| match format {
        Format::Ply { ascii } => ply::write_to(w, mesh, exposure, ascii),
        Format::Obj => obj::write_to(w, mesh, exposure),
        Format::Glb { up } => gltf::write_to(w, mesh, exposure, up),
    })
}

/// What [`ply::read`] and [`obj::read`] give back from one of our files.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadBack {
    /// Vertex positions as stored (`f32`, or `f64` where [`needs_double`] said so), scene
    /// units.
    pub positions: Vec<[f64; 3]>,
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
    /// The sky line of the file (`comment sky: …`, PLY only), if it has one.
    pub sky: Option<crate::scene::Sky>,
}

/// Rounding of a written position, as a share of the mesh's bounding-box diagonal, above
/// which the writers store positions in double precision. Single precision keeps a mesh near
/// the origin to about 10⁻⁷ of its size, but one far from the origin for its size only to
/// 2⁻²⁴ of that distance: a building in map coordinates, 5.6·10⁶ m north and 50 m across, to
/// 0.25 m.
pub const SINGLE_PRECISION_ROUNDING: f64 = 1e-6;

/// Whether storing `positions` (scene units) in single precision would move a coordinate by
/// more than [`SINGLE_PRECISION_ROUNDING`] of their bounding box's diagonal: then the PLY
/// writer declares them `double` and the OBJ writer prints them in f64's shortest round-trip
/// form, and files of meshes near the origin keep their single-precision layout.
pub fn needs_double(positions: &[[f64; 3]]) -> bool {
    let (lo, hi) = crate::geometry::bounds(positions.iter().map(|&p| glam::DVec3::from(p)));
    let tolerance = SINGLE_PRECISION_ROUNDING * (hi - lo).length();
    positions
        .iter()
        .flatten()
        .any(|&c| (c - f64::from(c as f32)).abs() > tolerance)
}

/// Writes `p` as `x y z` in Rust's shortest round-trip plain decimal form: of its `f64`
/// values if `double` ([`needs_double`]), else of its `f32` values, which read back as f32
/// to the same numbers. The PLY (ASCII) and OBJ writers' positions.
pub(crate) fn write_position(
    w: &mut impl std::io::Write,
    p: [f64; 3],
    double: bool,
) -> std::io::Result<()> {
    if double {
        let [x, y, z] = p;
        write!(w, "{x} {y} {z}")
    } else {
        let [x, y, z] = p.map(|c| c as f32);
        write!(w, "{x} {y} {z}")
    }
}

impl ReadBack {
    /// The baked mesh a PLY written by [`write()`] holds (positions and radiance widened to
    /// f64, with its camera and sky); `None` for a file without radiance (an OBJ, or a PLY from
    /// another tool read as ours).
    pub fn into_baked(self) -> Option<BakedMesh> {
        let (vertex_radiance, face_radiance) = (self.vertex_radiance?, self.face_radiance?);
        let f64s = |v: Vec<[f32; 3]>| v.into_iter().map(|x| x.map(f64::from)).collect();
        Some(BakedMesh {
            positions: self.positions,
            vertex_radiance: f64s(vertex_radiance),
            faces: self.faces,
            face_radiance: f64s(face_radiance),
            camera: self.camera,
            sky: self.sky,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{sample_mesh, TestDir};
    use std::fs;
    use std::io;

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
            assert!(matches!(err, Error::Setting { .. }), "{err:?}");
            let text = err.to_string();
            assert!(text.contains(p) && text.contains(".ply") && text.contains(".obj"));
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
            assert!(matches!(err, Error::Setting { .. }), "{err:?}");

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
    /// An output is refused where it names an input (by any spelling: a symbolic link, `..`)
    /// or an earlier output, and passes where the files differ; outputs not yet on disk are
    /// compared by their directory and name.
    #[test]
    fn an_output_that_would_replace_an_input_or_another_output_is_refused() {
        let dir = TestDir::new("distinct");
        let scene = dir.path().join("room.obj");
        std::fs::write(&scene, "v 0 0 0\n").unwrap();
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        let respelled = dir.path().join("sub").join("..").join("room.obj");
        let (ply, json) = (dir.path().join("out.ply"), dir.path().join("out.json"));
        let refused = |inputs: &[&Path], outputs: &[(&str, &Path)], name: &str, needle: &str| {
            match super::check_distinct(inputs, outputs) {
                Err(Error::Setting { name: n, message }) => {
                    assert_eq!(n, name);
                    assert!(message.contains(needle), "{message}");
                }
                other => panic!("expected a refusal of {name}, got {other:?}"),
            }
        };
        refused(
            &[&scene],
            &[("output", &respelled)],
            "output",
            "is the input",
        );
        let again = dir.path().join("sub").join("..").join("out.ply");
        refused(
            &[&scene],
            &[("output", &ply), ("report", &again)],
            "report",
            "also the output",
        );
        #[cfg(unix)]
        {
            let link = dir.path().join("link.obj");
            std::os::unix::fs::symlink(&scene, &link).unwrap();
            refused(&[&link], &[("output", &scene)], "output", "is the input");
        }
        super::check_distinct(&[&scene], &[("output", &ply), ("report", &json)]).unwrap();
        // An input that does not exist is its reader's to report.
        super::check_distinct(&[&dir.path().join("gone.obj")], &[("output", &ply)]).unwrap();
        assert_eq!(std::fs::read_to_string(&scene).unwrap(), "v 0 0 0\n");
    }
}
