//! Wavefront OBJ + MTL, both ways: scene files read into a [`crate::scene::Scene`] ([`load`],
//! through `tobj`, with our own line-numbered checks), and one writer (`write_obj`) behind
//! both outputs: procedural scenes saved as OBJ + MTL ([`save`]) and baked meshes with vertex
//! colours for MeshLab ([`write_to`], read back exactly by [`read`], a strict reader of that
//! one layout for tests and tools).

mod baked;
mod mtl;
mod save;
mod scene;

pub use baked::{colour_component, component_to_u8, read, write_to};
pub use save::save;
pub use scene::{companion_files, load};

use std::io::{self, Write};
use std::path::Path;

use crate::io::{parse_error, without_bom};
use crate::{Error, Result};

/// Reads a text file, less a leading byte-order mark ([`without_bom`]); bytes that are not
/// UTF-8 (a binary file, or a legacy encoding) are an [`Error::Parse`] at the line where the
/// first one is.
pub(super) fn read_text(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    String::from_utf8(bytes).map(without_bom).map_err(|e| {
        let valid = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = 1 + valid.iter().filter(|&&b| b == b'\n').count();
        parse_error(
            path,
            line,
            "not UTF-8 text (a binary file, or a legacy encoding: save it as UTF-8)",
        )
    })
}

/// Parses a number as f32 to check its range: a finite value past single precision's
/// (|x| > 3.4e38; `tobj` reads it in double precision, but every position and material value
/// must fit the outputs' and the visibility's f32) is an error at `line` that says so, as is a
/// malformed one; `inf` and `nan` as written are left to the caller's non-finite checks.
pub(super) fn parse_number(path: &Path, line: usize, what: &str, s: &str) -> Result<f32> {
    let x = s
        .parse::<f32>()
        .map_err(|_| parse_error(path, line, format!("{what}: malformed number '{s}'")))?;
    if x.is_infinite() && s.parse::<f64>().is_ok_and(f64::is_finite) {
        return Err(parse_error(
            path,
            line,
            format!(
                "{what}: '{s}' is beyond single precision's range (|x| ≤ {:.1e}), which \
                 positions and material values must fit",
                f32::MAX
            ),
        ));
    }
    Ok(x)
}

/// Materials of an OBJ's triangles: each triangle's index into the names.
pub(super) struct Groups<'a> {
    pub of_triangle: &'a [u32],
    pub names: &'a [&'a str],
}

/// The one OBJ writer behind [`save`] and [`write_to`]: each of `comments` as a `# ` line,
/// `mtllib` when given, `vertices` `v` lines (`vertex(w, i)` writes what follows `v `), then
/// one `f a b c` per triangle with 1-based indices, preceded by `usemtl NAME` wherever the
/// triangle's material differs from the one before (when `groups` is given).
pub(super) fn write_obj<W: Write>(
    w: &mut W,
    comments: &[String],
    mtllib: Option<&str>,
    vertices: usize,
    mut vertex: impl FnMut(&mut W, usize) -> io::Result<()>,
    triangles: &[[u32; 3]],
    groups: Option<Groups>,
) -> io::Result<()> {
    for c in comments {
        writeln!(w, "# {c}")?;
    }
    if let Some(name) = mtllib {
        writeln!(w, "mtllib {name}")?;
    }
    for i in 0..vertices {
        w.write_all(b"v ")?;
        vertex(w, i)?;
        w.write_all(b"\n")?;
    }
    let mut current = u32::MAX;
    for (k, t) in triangles.iter().enumerate() {
        if let Some(g) = &groups {
            let m = g.of_triangle[k];
            if m != current {
                current = m;
                writeln!(w, "usemtl {}", g.names[m as usize])?;
            }
        }
        writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
    }
    Ok(())
}
