//! Scores baked PLY files against a probe file of the point-wise benchmark: what a viewer of
//! each bake sees (vertex colours interpolated), at the probes, against their path-traced
//! radiance. `cargo run --release -p radiosity-tools --example score -- PROBES.csv BAKE.ply…`
//! With `SCORE_DUMP=FILE`, each probe's triangle and reference and shown luminance are also
//! written to FILE as CSV (the last bake's), to break the error down by surface. With
//! `TRACE=SCENE TRACE_SECONDS=S`, the path tracer that made the references, given S seconds
//! (wall clock, on this machine, nothing else running) and another seed, is scored the same
//! way: the bake's error against a tracer's at equal time (the scene's own lights only).
//! That tracer spends all S seconds on the probes alone, where a bake lights every surface.
//! With `TRACE_POINTS=N` as well (N ≥ the probes), it is given the share of S that N points
//! would each get after its set-up, probes / N of the rest: the error of a tracer rendering a
//! frame of N pixels in S seconds, read at the probes' pixels (each pixel's paths are
//! independent of the others', so the probes are a sample of such a frame's points;
//! Mitsuba's 256 × 256 frame at equal time, BENCHMARKS.md, is N = 65,536).
//! With `SCORE_SEEDS=1` and two or more bakes of one scene made with the same settings and
//! different seeds, a last line splits their error into what a seed decides and what they
//! all share ([`pointwise::Spread`]). With `SCORE_CLASSES=x|y|z` (the scene's up axis), each
//! bake's score is broken down as well, by where the probes face and how bright they are,
//! with each class's share of the squared error ([`pointwise::by_class`]).

use std::path::Path;

use anyhow::{Context, Result};
use radiosity::io::ply;
use radiosity::scene::Scene;
use radiosity::validation::pointwise::{self, Display, Score};

/// One row of the table: what was scored, and how.
fn row(what: &str, s: &Score) {
    println!(
        "| {what} | {} | {:.2} % | {:.2} % | {:.2} % | {:+.2} % |",
        s.scored,
        100.0 * s.rms,
        100.0 * s.median,
        100.0 * s.p90,
        100.0 * s.bias
    );
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (probes, bakes) = args
        .split_first()
        .context("usage: score PROBES.csv BAKE.ply…")?;
    let seeds = std::env::var_os("SCORE_SEEDS").is_some();
    if seeds && bakes.len() < 2 {
        anyhow::bail!("SCORE_SEEDS: give two or more bakes (other seeds, the same settings)");
    }
    let probes = pointwise::read_csv(Path::new(probes))?;
    let classes = radiosity_tools::up_env("SCORE_CLASSES")?.map(|up| up.axis());
    println!("| bake | scored | RMS | median | 90th pct | bias |\n|---|---|---|---|---|---|");
    let mut all_shown = Vec::new();
    for bake in bakes {
        let path = Path::new(bake);
        let display = Display::from_read_back(&ply::read(path)?, path)?;
        let shown: Vec<_> = display
            .at(&probes)
            .iter()
            .map(|s| s.map(|s| s.interpolated))
            .collect();
        if let Some(dump) = std::env::var_os("SCORE_DUMP") {
            // Each probe's triangle, reference and shown luminance, for a breakdown by hand.
            let mut csv = String::from("triangle,reference,shown\n");
            for (p, s) in probes.iter().zip(&shown) {
                let y = s.map_or(f64::NAN, radiosity::color::luminance);
                let reference = radiosity::color::luminance(p.radiance);
                csv.push_str(&format!("{},{reference},{y}\n", p.triangle));
            }
            std::fs::write(&dump, csv).with_context(|| format!("writing {dump:?}"))?;
        }
        row(bake, &pointwise::score(&probes, &shown));
        if let Some(up) = &classes {
            for c in pointwise::by_class(&probes, &shown, *up) {
                let what = format!(
                    "{bake}: {}, {:.1} % of the error²",
                    c.class.name(),
                    100.0 * c.share
                );
                row(&what, &c.score);
            }
        }
        if seeds {
            all_shown.push(shown);
        }
    }
    if seeds {
        let split = pointwise::spread(&probes, &all_shown).context("two or more bakes")?;
        println!(
            "between the {} bakes ({} probes): {:.2} % RMS varies with the seed, {:.2} % is \
             shared",
            split.bakes,
            split.scored,
            100.0 * split.varying,
            100.0 * split.shared
        );
    }
    if let Some(scene) = std::env::var_os("TRACE") {
        if let Some(seconds) = radiosity_tools::positive_env("TRACE_SECONDS", "number")? {
            let scene = Scene::load(Path::new(&scene))?;
            let ((traced, paths), frame) =
                match radiosity_tools::positive_env("TRACE_POINTS", "count")? {
                    Some(n) if n < probes.len() as f64 => anyhow::bail!(
                        "TRACE_POINTS={n}: fewer points than the {} probes",
                        probes.len()
                    ),
                    Some(n) => (
                        pointwise::trace_for_frame(&scene, &probes, seconds, n, 7),
                        format!(", a frame of {n} points"),
                    ),
                    None => (
                        pointwise::trace_for(&scene, &probes, seconds, 7),
                        String::new(),
                    ),
                };
            let traced: Vec<_> = traced.into_iter().map(Some).collect();
            let what = format!("path tracer, {seconds} s{frame} ({paths} paths a probe)");
            row(&what, &pointwise::score(&probes, &traced));
        }
    }
    Ok(())
}
