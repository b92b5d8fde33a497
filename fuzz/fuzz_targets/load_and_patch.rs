//! Fuzz target: arbitrary bytes as an OBJ file (with the Cornell box's MTL beside it, so
//! `mtllib cornell_box.mtl` and its materials resolve) through `Scene::load` and
//! `mesh::subdivide`. Errors are fine; a panic, or a loaded scene or patch mesh that breaks
//! its documented invariants, is a crash. Run with `RUSTC_BOOTSTRAP=1 cargo fuzz run
//! load_and_patch` from the repository root (see docs/robustness.md; the other readers have
//! targets of their own beside this one).
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use radiosity::mesh;
use radiosity::scene::Scene;

/// A per-process directory holding the MTL; the OBJ is rewritten for every input.
fn dir() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("radiosity-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mtl = concat!(env!("CARGO_MANIFEST_DIR"), "/../meshes/cornell_box.mtl");
        std::fs::copy(mtl, dir.join("cornell_box.mtl")).unwrap();
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    let path = dir().join("input.obj");
    std::fs::write(&path, data).unwrap();
    if let Ok(scene) = Scene::load(&path) {
        scene.validate().expect("a loaded scene is valid");
        let (lo, hi) = scene.bounds();
        // A coarse max-edge keeps each input fast; the patch-count guard covers the rest.
        if let Ok(patches) = mesh::subdivide(
            &scene,
            (hi - lo).length() / 4.0,
            mesh::DEFAULT_CREASE_DEGREES,
        ) {
            patches.validate().expect("patches are valid");
        }
    }
});
