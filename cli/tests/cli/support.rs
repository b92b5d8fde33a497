//! Shared helpers of the command-line tests: the repository's paths, scratch directories, and
//! running the `radiosity` binary.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository's root (the workspace, one level above this package).
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("cli/ is inside the repository")
        .to_path_buf()
}

/// The repository's meshes/ folder.
pub fn meshes() -> PathBuf {
    root().join("meshes")
}

/// The shipped Cornell box OBJ.
pub fn cornell() -> String {
    meshes().join("cornell_box.obj").display().to_string()
}

/// A fresh, empty temporary directory for one test, removed when the test ends (kept when
/// it fails, for a look at what it wrote).
pub fn temp_dir(name: &str) -> Scratch {
    let dir = std::env::temp_dir().join(format!("radiosity-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    Scratch(dir)
}

/// A test's scratch directory ([`temp_dir`]): a path, removed with what is in it on drop
/// unless the test is panicking.
pub struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// Run the `radiosity` binary with `args` and collect its output.
pub fn radiosity(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .args(args)
        .output()
        .expect("the binary runs")
}

/// `radiosity bake INPUT -o OUT` with `extra` options.
pub fn bake(input: &str, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["bake", input, "-o", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    radiosity(&args)
}

/// Bake the Cornell box coarsely (max-edge 110 mm: a few hundred patches, fast) to `out`, with
/// `extra` options.
pub fn bake_cornell(out: &Path, extra: &[&str]) -> Output {
    bake(&cornell(), out, &[&["--max-edge", "110"], extra].concat())
}

/// The process's stderr as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}
