//! Atomic file replacement: every file the library writes (baked meshes, pictures, reports,
//! the form-factor cache, generated scenes) goes to a temporary file in the same directory,
//! is flushed and synced, then renamed over the target, so an existing file is never left
//! half-written and a failed write leaves it untouched. Also the up-front check that an
//! output's directory exists, so a long run does not end in an error it could have reported
//! at once.

use std::ffi::OsString;
use std::fs::{self, File};
use std::io::{self, BufWriter, Write};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::{Error, Result};

/// Writes `bytes` to `path` atomically (temporary file in the same directory, flushed and
/// synced, then renamed over `path`); used for reports, pictures, the cache and scenes.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically(path, |w| w.write_all(bytes))
}

/// Checks, before any work, that `path`'s directory exists, so a long run does not end in an
/// error it could have reported at once. [`Error::Io`] naming `path` otherwise.
pub fn check_output_dir(path: &Path) -> Result<()> {
    let dir = directory_of(path);
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

/// Checks, before any work, that no output names an input file or another output:
/// `radiosity bake room.obj -o room.obj` would replace the scene with its own bake, and a
/// report or picture named as the baked mesh would replace it. Paths are compared as the
/// files they name (symbolic links and `..` resolved; an output not yet on disk by its
/// directory's and its name); inputs that do not exist are left to their readers.
/// `outputs` pairs each path with the setting that names it (`output`, `report`, `png`).
/// [`Error::Setting`] naming the output's setting and both paths otherwise.
pub fn check_distinct(inputs: &[&Path], outputs: &[(&str, &Path)]) -> Result<()> {
    let inputs: Vec<_> = inputs
        .iter()
        .filter_map(|p| Some((fs::canonicalize(p).ok()?, *p)))
        .collect();
    let mut seen: Vec<(std::path::PathBuf, &str, &Path)> = Vec::new();
    for &(name, path) in outputs {
        let Some(file) = file_identity(path) else {
            continue; // no such directory: check_output_dir says so
        };
        let clash = |message: String| Error::Setting {
            name: name.to_string(),
            message,
        };
        if let Some((_, input)) = inputs.iter().find(|(f, _)| *f == file) {
            return Err(clash(format!(
                "{} is the input {}: writing it would replace what is read; name another file",
                path.display(),
                input.display()
            )));
        }
        if let Some((_, other, earlier)) = seen.iter().find(|(f, _, _)| *f == file) {
            let earlier = match *earlier == path {
                true => String::new(),
                false => format!(" ({})", earlier.display()),
            };
            return Err(clash(format!(
                "{} is also the {other}{earlier}: one would replace the other; name another \
                 file",
                path.display(),
            )));
        }
        seen.push((file, name, path));
    }
    Ok(())
}

/// The file `path` names, for comparing paths: its canonical form if it exists, else its
/// directory's canonical form joined with its name; `None` if neither can be had.
fn file_identity(path: &Path) -> Option<std::path::PathBuf> {
    if let Ok(file) = fs::canonicalize(path) {
        return Some(file);
    }
    Some(
        fs::canonicalize(directory_of(path))
            .ok()?
            .join(path.file_name()?),
    )
}

/// The directory `path` is in: its parent, or `.` for a bare file name.
fn directory_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Buffer size for writers: large enough that 100k+ vertices cost few system calls.
const WRITE_BUFFER: usize = 1 << 16;

/// Runs `body` on a buffered temporary file next to `path`, then syncs it and renames it over
/// `path`; removes the temporary file if anything fails. Every error names `path`.
pub(crate) fn write_atomically(
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
    let dir = directory_of(path);
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
