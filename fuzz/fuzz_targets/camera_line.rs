//! Fuzz target: arbitrary bytes as the comments of a scene file, each line read by
//! `radiosity::scene::camera::CameraLine` (the rule every OBJ and PLY reader applies: at most
//! one `camera:` line, well formed), and the whole text as `Camera::from_text` (the
//! `--camera` option's form). Errors are fine; a panic, a hang, or a camera that breaks its
//! documented invariants or whose frame is not finite (`common::check_camera`) is a crash.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use radiosity::scene::camera::{from_comment, Camera, CameraLine};

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(c) = Camera::from_text(&text) {
        common::check_camera(&c);
    }
    let mut cameras = CameraLine::default();
    let mut found = 0;
    for (i, line) in text.lines().enumerate() {
        if let Some(Ok(c)) = from_comment(line) {
            common::check_camera(&c);
        }
        match cameras.read(line, i + 1) {
            Ok(()) => {}
            Err(why) => {
                assert!(!why.is_empty());
                return;
            }
        }
        if cameras.camera().is_some() {
            found += 1;
        }
    }
    if let Some(c) = cameras.camera() {
        assert!(found > 0);
        common::check_camera(&c);
    }
});
