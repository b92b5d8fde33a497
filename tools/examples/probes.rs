//! Path-traced probes for any scene file, to score its bakes with the `score` example: points
//! uniform by area (emitters and buried points left out), each traced until the standard
//! error of its luminance is at most the given share of it, written as the point-wise
//! benchmark's CSV.
//! `cargo run --release -p radiosity-tools --example probes -- SCENE OUT.csv [N] [ERROR]
//! [--sky L] [--sun AZIMUTH,ELEVATION,E] [--up x|y|z] [--seed S]`
//! (N probes, 500 by default; ERROR 0.01 by default; S draws the points and seeds the paths,
//! 1 by default: another S is an independent probe set). The tracer knows the scene's emitters
//! and materials (transmittance included) and, as the bake takes them, a uniform grey sky of
//! radiance L (W·sr⁻¹·m⁻²) and the sun (degrees, W·m⁻²) about the up axis (y by default);
//! not lamps files.
//! `probes SCENE OUT.csv --refilter IN.csv` writes IN.csv's probes without those the
//! sampler's burial test leaves out now (`pointwise::buried`), their references unchanged.

use std::path::Path;

use anyhow::{bail, Context, Result};
use radiosity::scene::{Environment, Scene, Sun, Up};
use radiosity::validation::pointwise::{self, ReferenceSettings};
use radiosity::Choice;

fn main() -> Result<()> {
    let usage =
        "usage: probes SCENE OUT.csv [N] [ERROR] [--sky L] [--sun AZ,EL,E] [--up x|y|z] [--seed S] \
         | probes SCENE OUT.csv --refilter IN.csv";
    let mut positional = Vec::new();
    let mut env = Environment::default();
    let mut seed = 1;
    let mut refilter = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || {
            args.next()
                .with_context(|| format!("{a} needs a value; {usage}"))
        };
        match a.as_str() {
            "--sky" => env.sky = [value()?.parse().context("--sky: a number")?; 3],
            "--sun" => {
                let v: Vec<f64> = value()?
                    .split(',')
                    .map(str::parse)
                    .collect::<Result<_, _>>()
                    .context("--sun: AZIMUTH,ELEVATION,E")?;
                let [azimuth_degrees, elevation_degrees, e] = v[..] else {
                    bail!("--sun: AZIMUTH,ELEVATION,E (three numbers)");
                };
                env.sun = Some(Sun {
                    azimuth_degrees,
                    elevation_degrees,
                    irradiance: [e; 3],
                });
            }
            "--up" => {
                let v = value()?;
                env.up = Up::from_name(&v).with_context(|| format!("--up: x, y or z, not {v}"))?
            }
            "--seed" => seed = value()?.parse().context("--seed: a whole number")?,
            "--refilter" => refilter = Some(value()?),
            _ => positional.push(a),
        }
    }
    env.validate()?;
    let scene_path = positional.first().context(usage)?;
    let out = positional.get(1).context(usage)?;
    let n: usize = positional
        .get(2)
        .map_or(Ok(500), |s| s.parse())
        .context(usage)?;
    let error: f64 = positional
        .get(3)
        .map_or(Ok(0.01), |s| s.parse())
        .context(usage)?;
    let scene = Scene::load(Path::new(scene_path))?;
    if let Some(input) = refilter {
        let probes = pointwise::read_csv(Path::new(&input))?;
        let buried = pointwise::buried(&scene, &probes);
        let kept: Vec<_> = probes
            .into_iter()
            .zip(&buried)
            .filter(|(_, &b)| !b)
            .map(|(p, _)| p)
            .collect();
        pointwise::write_csv(Path::new(out), &kept)?;
        let left = buried.iter().filter(|&&b| b).count();
        println!(
            "{input}: {left} buried probes left out, {} kept: {out}",
            kept.len()
        );
        return Ok(());
    }
    let mut probes = pointwise::sample_points(&scene, n, seed)?;
    let settings = ReferenceSettings {
        relative_error: error,
        seed,
        ..ReferenceSettings::default()
    };
    let t = std::time::Instant::now();
    pointwise::trace_reference_lit(&scene, &env, &mut probes, &settings);
    pointwise::write_csv(Path::new(out), &probes)?;
    println!(
        "{n} probes traced to {:.1} % in {:.1} s: {out}",
        100.0 * error,
        t.elapsed().as_secs_f64()
    );
    Ok(())
}
