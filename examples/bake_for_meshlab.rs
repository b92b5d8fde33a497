//! User task: bake a scene for MeshLab.
//!
//! `cargo run --release --example bake_for_meshlab -- [INPUT.obj] [OUTPUT.ply]`
//! (defaults: the shipped Cornell box → cornell_lit.ply). Open the PLY in MeshLab: vertex
//! colours are 8-bit sRGB, the linear radiance is in `radiance_r/g/b`.

use std::path::Path;

use radiosity::pipeline::{self, Settings, WriteOptions};

fn bake(input: &Path, output: &Path, settings: &Settings) -> radiosity::Result<pipeline::Outcome> {
    pipeline::run(input, output, settings, &WriteOptions::default())
}

fn main() -> radiosity::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let input = args.get(1).map_or("meshes/cornell_box.obj", |s| s.as_str());
    let output = args.get(2).map_or("cornell_lit.ply", |s| s.as_str());
    let outcome = bake(input.as_ref(), output.as_ref(), &Settings::default())?;
    println!("{output}: {}", outcome.report.summary());
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn bakes_the_cornell_box_to_a_ply_meshlab_reads() {
        let dir = std::env::temp_dir().join(format!("radiosity-example-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let out = dir.join("cornell.ply");
        let settings = radiosity::pipeline::Settings {
            max_edge: Some(150.0), // coarse: the example's test is about the workflow
            ..Default::default()
        };
        let input = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/cornell_box.obj");
        let outcome = super::bake(&input, &out, &settings).unwrap();
        let back = radiosity::io::ply::read(&out).unwrap();
        assert_eq!(back.faces.len(), outcome.baked.faces.len());
        assert_eq!(back.positions.len(), outcome.report.vertices);
        // The red wall: red well lit and over twice its green and blue (the bytes are at the
        // auto exposure, so no fixed level of red alone).
        let red = |c: &[u8; 3]| {
            let [r, g, b] = c.map(u16::from);
            r > 120 && r > 2 * g && r > 2 * b
        };
        assert!(back.colours.iter().any(red), "no red-wall colour");
        std::fs::remove_dir_all(dir).unwrap();
    }
}
