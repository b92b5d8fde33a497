//! Path-traced probes for any scene file, to score its bakes with the `score` example: points
//! uniform by area (emitters and buried points left out), each traced until the standard
//! error of its luminance is at most the given share of it, written as the point-wise
//! benchmark's CSV.
//! `cargo run --release -p radiosity-tools --example probes -- SCENE OUT.csv [N] [ERROR]`
//! (N probes, 500 by default; ERROR 0.01 by default). The tracer knows the scene's
//! emitters and materials (transmittance included), not `--sky`, `--sun` or lamps.

use std::path::Path;

use anyhow::{Context, Result};
use radiosity::scene::Scene;
use radiosity::validation::pointwise::{self, ReferenceSettings};

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: probes SCENE OUT.csv [N] [ERROR]";
    let scene_path = args.first().context(usage)?;
    let out = args.get(1).context(usage)?;
    let n: usize = args.get(2).map_or(Ok(500), |s| s.parse()).context(usage)?;
    let error: f64 = args.get(3).map_or(Ok(0.01), |s| s.parse()).context(usage)?;
    let scene = Scene::load(Path::new(scene_path))?;
    let mut probes = pointwise::sample_points(&scene, n, 1)?;
    let settings = ReferenceSettings {
        relative_error: error,
        ..ReferenceSettings::default()
    };
    let t = std::time::Instant::now();
    pointwise::trace_reference(&scene, &mut probes, &settings);
    pointwise::write_csv(Path::new(out), &probes)?;
    println!(
        "{n} probes traced to {:.1} % in {:.1} s: {out}",
        100.0 * error,
        t.elapsed().as_secs_f64()
    );
    Ok(())
}
