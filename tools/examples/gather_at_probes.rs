//! Gathers at the probes of the point-wise benchmark themselves, from a default bake's
//! solution: what the bake's vertices would show there with no display in between
//! (`Gatherer::at_point`, the `full` gather). Its error against the references is what the
//! solution and the gather leave; the baked mesh's displayed error (`score`) adds the
//! display's. Two seeds apart, the difference is the gather's own noise (its RMS over √2 is
//! one gather's). `cargo run --release -p radiosity-tools --example gather_at_probes --
//! PROBES.csv SCENE [RAYS] [SEED]` (defaults 4096 rays, seed 1; the scene's own lights, the
//! bake's default settings, or `MAX_EDGE=X` and `METHOD=matrix|hierarchical` for the bake's
//! `--max-edge` and `--method`, the two methods' solutions compared at the same probes;
//! `EPSILON=E` for its `--epsilon`; `CONTACTS=1` for the hierarchical roots cut along the
//! contact lines (`--discontinuities contacts`); `SKY=L`, `SUN=AZIMUTH,ELEVATION,E` and
//! `UP=x|y|z` for a grey `--sky`, the `--sun` and `--up`, as the `probes` example takes
//! them).
//! The first row is the solution itself, before any gather: the radiance of the patch under
//! each probe (`Gatherer::patch_at`), the patch's mean where a vertex would gather. Where it
//! is far off, the solve is (a leaf spanning a shadow's edge, a contact); where it is right
//! and the gather is not, the gather; where both are and the baked mesh (`score`) is not,
//! the display.
//! With `GATHER_DUMP=FILE`, each probe's reference, its patch's solved luminance, the
//! gathered luminance and its direct and indirect parts at both seeds go to FILE as CSV.

use std::path::Path;

use anyhow::{Context, Result};
use radiosity::color::luminance;
use radiosity::gather::Gatherer;
use radiosity::mesh::{self, Discontinuities};
use radiosity::pipeline::{self, Method, Settings};
use radiosity::scene::Scene;
use radiosity::validation::pointwise;
use rayon::prelude::*;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: gather_at_probes PROBES.csv SCENE [RAYS] [SEED]";
    let (Some(probes), Some(scene)) = (args.first(), args.get(1)) else {
        anyhow::bail!(usage);
    };
    let number = |k: usize, default: u64| -> Result<u64> {
        args.get(k).map_or(Ok(default), |a| {
            a.parse().with_context(|| usage.to_string())
        })
    };
    let (rays, seed) = (number(2, 4096)? as usize, number(3, 1)?);
    let probes = pointwise::read_csv(Path::new(probes))?;
    let scene = Scene::load(Path::new(scene))?;
    let mut settings = Settings::default();
    if let Some(edge) = radiosity_tools::positive_env("MAX_EDGE", "length")? {
        settings.max_edge = Some(edge);
    }
    if let Some(epsilon) = radiosity_tools::positive_env("EPSILON", "share of the power")? {
        settings.hierarchical.epsilon = epsilon;
    }
    if let Some(m) = std::env::var_os("METHOD") {
        settings.method = match m.to_string_lossy().as_ref() {
            "matrix" => Method::Matrix,
            "hierarchical" => Method::Hierarchical,
            "auto" => Method::Auto,
            other => anyhow::bail!("METHOD={other}: not matrix, hierarchical or auto"),
        };
    }
    if let Some(sky) = std::env::var_os("SKY") {
        let l: f64 = sky.to_string_lossy().parse().context("SKY=L: a number")?;
        settings.environment.sky = [l; 3];
    }
    if let Some(sun) = std::env::var_os("SUN") {
        let v: Vec<f64> = sun
            .to_string_lossy()
            .split(',')
            .map(str::parse)
            .collect::<Result<_, _>>()
            .context("SUN=AZIMUTH,ELEVATION,E")?;
        let [azimuth_degrees, elevation_degrees, e] = v[..] else {
            anyhow::bail!("SUN=AZIMUTH,ELEVATION,E: three numbers");
        };
        settings.environment.sun = Some(radiosity::scene::Sun {
            azimuth_degrees,
            elevation_degrees,
            irradiance: [e; 3],
        });
    }
    if let Some(up) = radiosity_tools::up_env("UP")? {
        settings.environment.up = up;
    }
    settings.environment.validate()?;

    // The gatherer reads the scene the solve's patches came from: where the matrix method
    // splits the contact lines into the scene (the default), or CONTACTS asks the hierarchy
    // to, split them here and solve that.
    let scene = if std::env::var_os("CONTACTS").is_some()
        || settings.resolved(&scene)?.method == Method::Matrix
    {
        settings.discontinuities = Discontinuities::None;
        mesh::split_contacts(&scene).0
    } else {
        scene
    };
    let out = pipeline::solve_scene(&scene, &settings)?;
    let gatherer = Gatherer::new(
        &scene,
        &out.patches,
        &out.solution.radiance,
        &settings.environment,
        settings.form_factors.seed,
    );
    let at = |s: u64| -> Vec<_> {
        probes
            .par_iter()
            .enumerate()
            .map(|(i, p)| {
                gatherer.at_point(
                    p.position,
                    p.normal,
                    rays,
                    s.wrapping_mul(1 << 32) + i as u64,
                )
            })
            .collect()
    };
    let (first, second) = (at(seed), at(seed + 1));
    // The solution at each probe: its patch's radiance, no gather.
    let solved: Vec<Option<radiosity::Rgb>> = probes
        .iter()
        .map(|p| {
            gatherer
                .patch_at(p.position, p.normal)
                .map(|q| out.solution.radiance[q as usize])
        })
        .collect();
    println!(
        "{} probes, {:?} solve, {rays} rays a probe, seeds {seed} and {}",
        probes.len(),
        out.report.method,
        seed + 1
    );
    println!(
        "| at the probes | scored | RMS | median | 90th pct | bias |\n|---|---|---|---|---|---|"
    );
    let radiance = |values: &[Option<radiosity::gather::Gathered>]| -> Vec<_> {
        values.iter().map(|g| g.map(|g| g.radiance)).collect()
    };
    for (name, shown) in [
        ("the solve's patch (no gather)", &solved),
        ("seed", &radiance(&first)),
        ("next seed", &radiance(&second)),
    ] {
        let s = pointwise::score(&probes, shown);
        println!(
            "| {name} | {} | {:.2} % | {:.2} % | {:.2} % | {:+.2} % |",
            s.scored,
            100.0 * s.rms,
            100.0 * s.median,
            100.0 * s.p90,
            100.0 * s.bias
        );
    }
    // One gather's noise: the two seeds' relative difference, RMS over √2, at the probes the
    // score counts (brighter than a tenth of the references' mean).
    let floor =
        0.1 * probes.iter().map(|p| luminance(p.radiance)).sum::<f64>() / probes.len() as f64;
    let (mut sum, mut n) = (0.0, 0usize);
    for ((p, a), b) in probes.iter().zip(&first).zip(&second) {
        if let (Some(a), Some(b)) = (a, b) {
            let reference = luminance(p.radiance);
            if reference > floor {
                sum += ((luminance(a.radiance) - luminance(b.radiance)) / reference).powi(2);
                n += 1;
            }
        }
    }
    println!(
        "noise of one gather: {:.2} % RMS",
        100.0 * (sum / n.max(1) as f64 / 2.0).sqrt()
    );
    if let Some(dump) = std::env::var_os("GATHER_DUMP") {
        let mut csv = String::from(
            "triangle,reference,solved,gathered,direct,indirect,gathered2,direct2,indirect2\n",
        );
        for (((p, a), b), l) in probes.iter().zip(&first).zip(&second).zip(&solved) {
            let y = |g: &Option<radiosity::gather::Gathered>| {
                g.map_or([f64::NAN; 3], |g| {
                    [
                        luminance(g.radiance),
                        luminance(g.direct),
                        luminance(g.indirect),
                    ]
                })
            };
            let (a, b) = (y(a), y(b));
            csv.push_str(&format!(
                "{},{},{},{},{},{},{},{},{}\n",
                p.triangle,
                luminance(p.radiance),
                l.map_or(f64::NAN, luminance),
                a[0],
                a[1],
                a[2],
                b[0],
                b[1],
                b[2]
            ));
        }
        std::fs::write(&dump, csv).with_context(|| format!("writing {dump:?}"))?;
    }
    Ok(())
}
