//! The speed-and-scale harness: `cargo bench -p radiosity-tools --bench scale -- [SECTION…]
//! [--quick] [--out DIR]`, sections `skips`, `solvers`, `scale`, `rays`, `matvec`, `reference` (all
//! but `reference` when none is named). Writes to DIR (default `target/scale`):
//!
//! - `skips.csv` / `skips.md`: every skip of the pipeline, the same work with and without it in
//!   one run (seconds, the counter that shows it in `--report`, and whether the answer is the
//!   same);
//! - `solvers.csv` / `solvers.md`, `omega.csv`, `solver_residuals.csv`, `solver_residuals.png`:
//!   sweeps and seconds to a relative residual of 1e-6 per solver on the closed furnace room at
//!   ρ = 0.5 … 0.999, the measured convergence factor per sweep against theory, and the
//!   over-relaxation study of Gauss–Seidel;
//! - `scale.csv` / `scale.md`: the Cornell box from ~1k to ~100k patches, seconds per stage and
//!   peak memory (each run in a child process of its own, so peaks do not mix), the fitted
//!   growth exponents, and the two scale targets with their error against the path-traced
//!   reference;
//! - `rays.md` (+ `rays.bin` for `tools/embree_rays.py`): occlusion rays per second per core on
//!   a 10k-triangle room, ours against Embree's (`embreex` from PyPI, run in a virtual
//!   environment under `target/` when it can be installed);
//! - `matvec.md`: bytes per second of the F·L product against this machine's copy bandwidth
//!   measured in the same run;
//! - `reference`: `docs/bench/cornell_reference.csv`, the per-surface mean radiance of the
//!   Cornell box by path tracing ([`radiosity::validation::path_tracer`]; 16M paths per surface, a
//!   few minutes).
//!
//! Everything is timed on the machine it runs on; the date and machine head every file.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

use anyhow::Result;
use radiosity::form_factor::{self, Estimator};
use radiosity::pipeline::{self, Outcome};
use radiosity::scene::Scene;
use radiosity::solve::System;
use radiosity::solve::{self, Method};
use radiosity::validation::{path_tracer, scenes};
use radiosity::visibility::Visibility;

mod matvec;
mod rays;
mod reference;
mod sizes;
mod skips;
mod solvers;

use radiosity_tools::{
    chart, fit_order, harness_args, load_font, surface_means, write_sections, Curve,
};
use sizes::surface_difference;

/// The command line: sections to run (all but `reference` by default), `--quick`, `--out
/// DIR`, and the internal `--child SPEC` (one Cornell run in this process, JSON on stdout).
struct Args {
    sections: Vec<String>,
    quick: bool,
    out: PathBuf,
}

fn parse_args() -> Result<Args> {
    let h = harness_args(
        "target/scale",
        "cargo bench -p radiosity-tools --bench scale -- \
         [skips|solvers|scale|rays|matvec|reference]… [--quick] [--out DIR]",
    )?;
    let sections = radiosity_tools::sections(
        h.other,
        &["skips", "solvers", "scale", "rays", "matvec", "reference"],
        &["skips", "solvers", "scale", "rays", "matvec"],
        sizes::child,
    )?;
    Ok(Args {
        sections,
        quick: h.quick,
        out: h.out,
    })
}

fn main() -> Result<()> {
    let args = parse_args()?;
    write_sections(&args.out, &args.sections, |s| match s {
        "skips" => skips::skips(&args),
        "solvers" => solvers::solvers(&args),
        "scale" => sizes::scale(&args),
        "rays" => rays::rays(&args),
        "matvec" => matvec::matvec(&args),
        "reference" => reference::reference(&args),
        _ => unreachable!(),
    })
}

fn cornell() -> Result<Scene> {
    Ok(Scene::load(
        &radiosity_tools::root().join("meshes/cornell_box.obj"),
    )?)
}

fn run(scene: &Scene, s: &pipeline::Settings) -> Result<(Outcome, f64)> {
    let t = Instant::now();
    let out = pipeline::solve_scene(scene, s)?;
    Ok((out, t.elapsed().as_secs_f64()))
}

fn settings(max_edge: f64) -> pipeline::Settings {
    pipeline::Settings {
        max_edge: Some(max_edge),
        ..pipeline::Settings::default()
    }
}

// ---------------------------------------------------------------------------------------------
// Skips
