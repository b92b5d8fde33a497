//! Checks a baked PLY of a uniform closed enclosure (the furnace: one reflectance ρ and one
//! emission Le everywhere, so L = Le/(1 − ρ) on every surface) face by face and vertex by
//! vertex against that closed form: the area-weighted mean error, the worst, and how many
//! are off by more than 1e-3 and 1e-2 (relative).
//! `cargo run --release -p radiosity-tools --example uniform -- EXPECTED BAKE.ply…`
//! (for `--reflectance '*=0.5' --emission '*=1'`, EXPECTED is 2).

use std::path::Path;

use anyhow::{bail, Context, Result};
use radiosity::io::ply;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (expected, bakes) = args
        .split_first()
        .context("usage: uniform EXPECTED BAKE.ply…")?;
    let expected: f64 = expected.parse().context("EXPECTED: a radiance")?;
    if !(expected > 0.0 && expected.is_finite()) {
        bail!("EXPECTED must be a positive radiance, not {expected}");
    }
    println!("| bake | of | mean | worst | > 1e-3 | > 1e-2 |\n|---|---|---|---|---|---|");
    for bake in bakes {
        let path = Path::new(bake);
        let read = ply::read(path)?;
        let p = |i: u32| glam::DVec3::from(read.positions[i as usize].map(f64::from));
        let area: Vec<f64> = read
            .faces
            .iter()
            .map(|&[a, b, c]| 0.5 * (p(b) - p(a)).cross(p(c) - p(a)).length())
            .collect();
        let faces = read
            .face_radiance
            .as_ref()
            .with_context(|| format!("{bake}: no face radiance (a PLY written by radiosity)"))?;
        let vertices = read
            .vertex_radiance
            .as_ref()
            .context("no vertex radiance")?;
        let err = |l: &[f32; 3]| {
            l.iter()
                .map(|&c| (c as f64 / expected - 1.0).abs())
                .fold(0.0, f64::max)
        };
        let face_err: Vec<f64> = faces.iter().map(err).collect();
        let vertex_err: Vec<f64> = vertices.iter().map(err).collect();
        let total: f64 = area.iter().sum();
        let mean = face_err.iter().zip(&area).map(|(e, a)| e * a).sum::<f64>() / total;
        for (what, errors, mean) in [
            ("faces", &face_err, Some(mean)),
            ("vertices", &vertex_err, None),
        ] {
            let worst = errors.iter().copied().fold(0.0, f64::max);
            let over = |t: f64| errors.iter().filter(|&&e| e > t).count();
            println!(
                "| {bake} | {} {what} | {} | {worst:.2e} | {} | {} |",
                errors.len(),
                mean.map_or("–".to_string(), |m| format!("{m:.2e}")),
                over(1e-3),
                over(1e-2)
            );
        }
    }
    Ok(())
}
