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

/// A fresh, empty temporary directory for one test.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("radiosity-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
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
