//! Fuzz target: arbitrary bytes as a lights file (`radiosity::io::lights::parse`). Text that
//! is not UTF-8 is skipped (`io::lights::read` refuses it before parsing). Errors are fine and
//! must name the file; a panic, a hang, or sources whose lights fail `Environment::validate`
//! (a sky, sun or light out of range, a spot's direction not a unit vector) is a crash.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use radiosity::scene::Up;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match radiosity::io::lights::parse(text, Path::new("lights.json")) {
        Ok(sources) => {
            if let Some(sky) = sources.sky {
                assert!(sky.iter().all(|l| l.is_finite() && *l >= 0.0), "{sky:?}");
            }
            for up in [Up::X, Up::Y, Up::Z] {
                let env = sources.clone().environment(up);
                env.validate()
                    .expect("the lights of a parsed file are valid");
                if let Some(d) = env.sun_direction() {
                    assert!(d.is_finite() && (d.length() - 1.0).abs() < 1e-9, "{d}");
                }
            }
        }
        Err(e) => assert!(e.to_string().starts_with("lights.json"), "{e}"),
    }
});
