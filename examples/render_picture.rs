//! User task: render a picture of a baked scene.
//!
//! `cargo run --release --example render_picture -- [OUTPUT.png]`: bakes the Cornell box and
//! renders it from its published camera (278, 273, −800), looking +z, 39.3° field of view.

use radiosity::pipeline::{solve_scene, Settings};
use radiosity::render::{self, Camera, View};
use radiosity::scene::Scene;

fn picture(max_edge: Option<f64>, size: u32) -> radiosity::Result<image::RgbImage> {
    let input = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/cornell_box.obj");
    let scene = Scene::load(&input)?;
    let out = solve_scene(
        &scene,
        &Settings {
            max_edge,
            ..Default::default()
        },
    )?;
    let view = View {
        camera: Camera::parse("278,273,-800,278,273,0,0,1,0,39.3")?,
        width: size,
        height: size,
        spp: 2,
        flat: false,
        false_colour: false,
        exposure: out.baked.auto_exposure(),
    };
    Ok(render::render(&out.baked, &view))
}

fn main() -> radiosity::Result<()> {
    let output = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "cornell.png".into());
    render::save(output.as_ref(), &picture(None, 512)?)?;
    println!("wrote {output}");
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_red_wall_is_on_the_left_and_the_green_on_the_right() {
        let img = super::picture(Some(150.0), 64).unwrap();
        let (left, right) = (img.get_pixel(4, 32).0, img.get_pixel(59, 32).0);
        assert!(left[0] > left[1] && left[0] > left[2], "left {left:?}");
        assert!(
            right[1] > right[0] && right[1] > right[2],
            "right {right:?}"
        );
    }
}
