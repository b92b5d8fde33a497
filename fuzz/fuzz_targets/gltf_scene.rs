//! Fuzz target: arbitrary bytes as a glTF 2.0 scene through `Scene::load`: as `input.glb` when
//! they start with the GLB magic `glTF`, else as `input.gltf` (JSON, buffers and images
//! embedded as data URIs; a relative URI resolves in the scratch directory, where only the
//! input lies). Errors are fine; a panic, a hang, or a loaded scene that breaks its invariants
//! (`common::check_scene`: the scene, its lights and its camera) is a crash.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let name = if data.starts_with(b"glTF") {
        "input.glb"
    } else {
        "input.gltf"
    };
    common::load_and_check(&common::write(name, data));
});
