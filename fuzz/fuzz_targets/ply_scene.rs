//! Fuzz target: arbitrary bytes as a PLY scene (ASCII or binary little-endian, whichever the
//! header says) through `Scene::load`. Errors are fine; a panic, a hang, or a loaded scene
//! that breaks its invariants (`common::check_scene`) is a crash. See docs/robustness.md.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    common::load_and_check(&common::write("input.ply", data));
});
