//! What every fuzz target asserts about a reader's `Ok`: the documented invariants of what it
//! returns. Shared by the targets with `mod common;` (this file is not a target itself).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use radiosity::mesh;
use radiosity::scene::{Camera, Environment, Scene};

/// A per-process scratch directory (the readers take a path; the input is rewritten there for
/// every run).
pub fn dir() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("radiosity-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    })
}

/// Writes `data` to `name` in [`dir`] and returns its path.
pub fn write(name: &str, data: &[u8]) -> PathBuf {
    let path = dir().join(name);
    std::fs::write(&path, data).unwrap();
    path
}

/// A camera's documented invariants (coordinates finite, eye ≠ target, up not zero nor along
/// the view, 0 < fov < 180), the frame the renderer builds from it finite, and its text form
/// reading back as the same camera.
pub fn check_camera(c: &Camera) {
    assert!(
        [c.eye, c.target, c.up].iter().all(|v| v.is_finite()),
        "{c:?}"
    );
    assert!(c.vfov_degrees > 0.0 && c.vfov_degrees < 180.0, "{c:?}");
    assert!(c.eye != c.target, "{c:?}");
    // The frame of `render::render` and `render::coverage`.
    let forward = (c.target - c.eye).normalize();
    let right = forward.cross(c.up).normalize();
    let up = right.cross(forward);
    assert!(
        forward.is_finite() && right.is_finite() && up.is_finite(),
        "camera frame not finite: {c:?}"
    );
    assert!((forward.length() - 1.0).abs() < 1e-6, "{c:?}");
    assert!((right.length() - 1.0).abs() < 1e-6, "{c:?}");
    Camera::new(c.eye, c.target, c.up, c.vfov_degrees).expect("a camera re-checks");
    assert_eq!(
        Camera::from_text(&c.to_text()).as_ref(),
        Ok(c),
        "round trip"
    );
}

/// A loaded scene's invariants: [`Scene::validate`], its camera, its lights (as a bake merges
/// them: [`Environment::validate`]), and a coarse subdivision that validates.
pub fn check_scene(scene: &Scene) {
    scene.validate().expect("a loaded scene is valid");
    if let Some(c) = &scene.camera {
        check_camera(c);
    }
    let mut env = Environment::default();
    env.add_scene_lights(scene);
    env.validate().expect("the scene's lights are valid");
    let (lo, hi) = scene.bounds();
    assert!(lo.is_finite() && hi.is_finite());
    // A coarse max-edge keeps each input fast; the patch-count guard covers the rest.
    if let Ok(patches) = mesh::subdivide(
        scene,
        (hi - lo).length() / 4.0,
        mesh::DEFAULT_CREASE_DEGREES,
    ) {
        patches.validate().expect("patches are valid");
    }
}

/// Loads `path` as a scene: an error is fine (it must say something and name the file); a
/// scene must pass [`check_scene`].
pub fn load_and_check(path: &Path) {
    match Scene::load(path) {
        Ok(scene) => check_scene(&scene),
        Err(e) => {
            let text = e.to_string();
            assert!(
                text.contains(path.file_name().unwrap().to_str().unwrap()),
                "the error names the file: {text}"
            );
        }
    }
}
