//! The point-wise harness: `cargo bench -p radiosity-tools --bench pointwise -- [reference]
//! [curves] [--scene NAME[,NAME…]]… [--quick] [--out DIR]` (`curves` when no section is
//! named, every scene when none is). What a viewer of the baked mesh sees, scored at probe
//! points against path-traced radiance ([`radiosity::validation::pointwise`]), and the same
//! path tracer given the bake's seconds.
//!
//! - `reference`: traces the probes of each scene (2,000 points, fixed seed, ≤ 0.3 % standard
//!   error at each probe the score counts) into `docs/bench/probes_SCENE.csv`, or continues
//!   the file there to the current rule. `curves` traces them first when the file is missing.
//! - `curves`: bakes each scene at several settings (matrix and hierarchical); for each bake,
//!   the displayed radiance (vertex-interpolated and flat) is scored, and the path tracer is
//!   given the bake's seconds at the same probes. Writes `curves.md` and
//!   `pointwise_SCENE.png` (RMS relative error against seconds) to DIR (default
//!   `target/pointwise`).
//!
//! Scenes: `cornell` (meshes/cornell_box.obj), `hall` (the generated furnished hall,
//! `radiosity generate hall --triangles 10000`: a room of tables and chairs under 162 ceiling
//! lights) and `living_room` (`radiosity generate living-room`: two lights, furniture against
//! the walls, a ball on the floor), scenes nothing here was tuned to when they were first
//! measured (rules have since been found at their worst probes); and `two_rooms` and `study`
//! (`radiosity generate two-rooms|study`), written as scenes nothing was tuned to and first
//! measured at the defaults only after both were fixed (defaults only: they check that the
//! defaults carry over, not the settings' curves); and `attic` and `kitchen` (`radiosity
//! generate attic|kitchen`: sloped faces, furniture turned off the axes, an emitting cube,
//! pendant lamps), written as scenes nothing was tuned to and committed before their first
//! measurement, for the same purpose; and `office` (`radiosity generate office`, 100,540
//! triangles: an open-plan office under twelve ceiling panels and the sky in eight windows,
//! desks, turned chairs, columns, plants with crowns of small faces), the same at a size
//! where the hierarchical solver is the default, defaults only.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use radiosity::gather::Gather;
use radiosity::mesh::Discontinuities;
use radiosity::pipeline::{self, Method};
use radiosity::scene::Scene;
use radiosity::validation::pointwise::{self, Display, ReferenceSettings, Score};
use radiosity::validation::scenes;
use radiosity_tools::{chart, harness_args, load_font, root, write_sections, Curve};

const SECTIONS: [&str; 2] = ["reference", "curves"];
const SCENES: [&str; 9] = [
    "cornell",
    "cornell_seed2",
    "hall",
    "living_room",
    "two_rooms",
    "study",
    "attic",
    "kitchen",
    "office",
];
/// Probes per scene, and their seed: 1, and 2 for `cornell_seed2`, a second draw of points on
/// the Cornell box (its defaults' error is mostly a few points' near sub-millimetre features,
/// so one draw of 2,000 says little alone).
const PROBES: usize = 2000;
fn probe_seed(name: &str) -> u64 {
    if name == "cornell_seed2" {
        2
    } else {
        1
    }
}

/// The command line: sections, the scenes they run on (`--scene`), `--quick`, `--out DIR`.
struct Args {
    sections: Vec<String>,
    scenes: Vec<&'static str>,
    quick: bool,
    out: PathBuf,
}

fn main() -> Result<()> {
    let usage = format!(
        "cargo bench -p radiosity-tools --bench pointwise -- [reference|curves]… \
         [--scene NAME[,NAME…]]… [--quick] [--out DIR]\n\n\
         --scene NAMES  only these scenes (repeatable, or a comma list) [default: all of {}]",
        SCENES.join(", ")
    );
    let h = harness_args("target/pointwise", &usage)?;
    let (scenes, other) = scene_names(h.other)?;
    let sections = radiosity_tools::sections(other, &SECTIONS, &["curves"], |_| {
        anyhow::bail!("this harness runs no child processes")
    })?;
    let args = Args {
        sections,
        scenes,
        quick: h.quick,
        out: h.out,
    };
    let text = load_font();
    write_sections(&args.out, &args.sections, |s| match s {
        "reference" => reference(&args),
        "curves" => curves(&args, text),
        _ => unreachable!(),
    })
}

/// The scenes `--scene NAME` names (repeatable, each a name or a comma list of names from
/// [`SCENES`]), in [`SCENES`]' order; all of them when none is named. The other words are
/// returned, in order, for [`radiosity_tools::sections`].
fn scene_names(words: Vec<String>) -> Result<(Vec<&'static str>, Vec<String>)> {
    let (mut named, mut other) = (Vec::new(), Vec::new());
    let mut it = words.into_iter();
    while let Some(word) = it.next() {
        if word != "--scene" {
            other.push(word);
            continue;
        }
        let list = it.next().context("--scene needs a scene name")?;
        for name in list.split(',') {
            if !SCENES.contains(&name) {
                anyhow::bail!(
                    "unknown scene {name:?} for --scene (one of {})",
                    SCENES.join(", ")
                );
            }
            named.push(name.to_string());
        }
    }
    let scenes = SCENES
        .into_iter()
        .filter(|s| named.is_empty() || named.iter().any(|n| n == s))
        .collect();
    Ok((scenes, other))
}

fn load(name: &str) -> Result<Scene> {
    Ok(match name {
        "cornell" | "cornell_seed2" => Scene::load(&root().join("meshes/cornell_box.obj"))?,
        "hall" => scenes::furnished_hall(10_000)?,
        "living_room" => scenes::living_room()?,
        "two_rooms" => scenes::two_rooms()?,
        "study" => scenes::study()?,
        "attic" => scenes::attic()?,
        "kitchen" => scenes::kitchen()?,
        "office" => scenes::office(100_000)?,
        _ => anyhow::bail!("unknown scene {name}"),
    })
}

fn probes_path(name: &str) -> PathBuf {
    root().join(format!("docs/bench/probes_{name}.csv"))
}

/// Traces the probes of `name` and writes them; returns a Markdown line.
fn trace(name: &str) -> Result<String> {
    let scene = load(name)?;
    let t = Instant::now();
    let path = probes_path(name);
    // A reference already written is continued where it stopped (to the current rule), not
    // traced again: the same numbers as afresh, for the new paths only.
    let mut probes = if path.exists() {
        pointwise::read_csv(&path)?
    } else {
        pointwise::sample_points(&scene, PROBES, probe_seed(name))?
    };
    let settings = reference_settings(name);
    pointwise::trace_reference(&scene, &mut probes, &settings);
    let seconds = t.elapsed().as_secs_f64();
    pointwise::write_csv(&path, &probes)?;
    let paths: u64 = probes.iter().map(|p| p.paths as u64).sum();
    let counted = pointwise::scored(&probes.iter().map(|p| p.radiance).collect::<Vec<_>>());
    let capped = probes
        .iter()
        .zip(&counted)
        .filter(|&(p, &c)| {
            p.paths
                >= if c {
                    settings.scored_max_paths
                } else {
                    settings.max_paths
                }
        })
        .count();
    let line = format!(
        "| {name} | {} | {paths} | {seconds:.0} | {capped} |\n",
        probes.len()
    );
    eprintln!("  {} written: {line}", path.display());
    Ok(line)
}

/// The reference's stopping rule: 0.3 % standard error (at most 2²⁰ paths, 2²² at the probes
/// the score counts) but in the hall and the office: 0.5 % (at most 2¹⁸), whose dim corners
/// under small lights (in the office also its ceiling, lit only indirectly, and the floor
/// under desks and chairs) would otherwise take hours (the hall's bakes' errors are several
/// per cent, far above either). Many of their probes stop at the cap, a little above 0.5 %;
/// the reference's own noise is part of the score's table.
fn reference_settings(name: &str) -> ReferenceSettings {
    match name {
        "hall" | "office" => ReferenceSettings {
            relative_error: 0.005,
            max_paths: 1 << 18,
            scored_max_paths: 1 << 18,
            ..ReferenceSettings::default()
        },
        _ => ReferenceSettings::default(),
    }
}

fn reference(args: &Args) -> Result<String> {
    let mut md = String::from(
        "Probes: 2,000 points uniform by area (seed 1, and 2 for cornell_seed2; emitters and buried points left out), \
         path-traced until the standard error of each one's luminance is ≤ 0.3 % of it \
         (at least 4,096 paths, at most 1,048,576, or 4,194,304 at a probe the score counts), \
         ≤ 0.5 % in the hall and the office (at most 262,144); 'capped' probes stopped at the \
         limit. A file already written is continued to the rule, not traced again ('seconds' \
         are the continuation's).\n\n\
         | scene | probes | paths | seconds | capped |\n|---|---|---|---|---|\n",
    );
    for &name in &args.scenes {
        md.push_str(&trace(name)?);
    }
    Ok(md)
}

/// The bakes measured on each scene: (label, settings). On the Cornell box, the matrix
/// method with and without each part (contact lines, final gather, display refinement) and the
/// hierarchical solver; on the untuned scenes the defaults (what a user gets: the hierarchical
/// solver in the hall, the matrix method in the living room) and the hierarchical solver
/// with and without the gather.
fn bakes(quick: bool, name: &str) -> Vec<(String, pipeline::Settings)> {
    let with = |method, discontinuities, gather, epsilon| {
        let mut s = pipeline::Settings {
            method,
            discontinuities,
            gather,
            ..pipeline::Settings::default()
        };
        s.hierarchical.epsilon = epsilon;
        s
    };
    let (none, contacts, auto) = (
        Discontinuities::None,
        Discontinuities::Contacts,
        Discontinuities::Auto,
    );
    let mut runs = Vec::new();
    if name == "cornell" {
        let unrefined = |s: pipeline::Settings| pipeline::Settings {
            gather_tolerance: 0.0,
            ..s
        };
        for (d, g, refine, label) in [
            (
                none,
                Gather::None,
                false,
                "matrix, no contact lines, no gather",
            ),
            (
                contacts,
                Gather::None,
                false,
                "matrix, contact lines, no gather",
            ),
            (
                none,
                Gather::Full,
                false,
                "matrix, no contact lines, full gather",
            ),
            (
                auto,
                Gather::Full,
                false,
                "matrix, contact lines, full gather",
            ),
            (
                auto,
                Gather::Full,
                true,
                "matrix, contact lines, full gather, display refinement (the defaults)",
            ),
        ] {
            let s = with(Method::Matrix, d, g, 1e-4);
            runs.push((label.to_string(), if refine { s } else { unrefined(s) }));
        }
    }
    if name != "cornell" {
        runs.push(("the defaults".to_string(), pipeline::Settings::default()));
    }
    if [
        "cornell_seed2",
        "two_rooms",
        "study",
        "attic",
        "kitchen",
        "office",
    ]
    .contains(&name)
    {
        return runs;
    }
    let eps: &[f64] = if quick { &[1e-4] } else { &[1e-4, 1e-5] };
    for &e in eps {
        if name != "cornell" {
            runs.push((
                format!("hierarchical, ε {e:.0e}, no gather"),
                with(Method::Hierarchical, auto, Gather::None, e),
            ));
        }
        runs.push((
            format!("hierarchical, ε {e:.0e}, full gather, display refinement"),
            with(Method::Hierarchical, auto, Gather::Full, e),
        ));
    }
    runs
}

fn score_row(md: &mut String, what: &str, seconds: f64, s: &Score) {
    writeln!(
        md,
        "| {what} | {seconds:.2} | {:.2} % | {:.2} % | {:.2} % | {:+.2} % | {} |",
        100.0 * s.rms,
        100.0 * s.median,
        100.0 * s.p90,
        100.0 * s.bias,
        s.missing
    )
    .unwrap();
}

fn curves(args: &Args, text: bool) -> Result<String> {
    let mut md = String::from(
        "Relative error of luminance at the probes (those brighter than a tenth of the mean), \
         against the path-traced reference (docs/bench/probes_SCENE.csv). 'shown' is what the \
         baked mesh displays with vertex colours (barycentric interpolation), 'flat' the \
         face's own value; 'path tracer' is the reference's tracer given the bake's seconds \
         at the same probes. Seconds: the solve and bake (no file loading or writing).\n",
    );
    for &name in &args.scenes {
        let path = probes_path(name);
        if !path.exists() {
            eprintln!("  {} is missing: tracing it", path.display());
            trace(name)?;
        }
        let probes = pointwise::read_csv(&path)?;
        let scene = load(name)?;
        let noise = pointwise::score(
            &probes,
            &probes.iter().map(|p| Some(p.radiance)).collect::<Vec<_>>(),
        );
        writeln!(
            md,
            "\n## {name}\n\n{} probes scored; the reference's own noise: RMS {:.2} %.\n\n\
             | run | seconds | RMS | median | 90th pct | bias | missing |\n\
             |---|---|---|---|---|---|---|",
            noise.scored,
            100.0 * noise.reference_noise
        )?;
        let mut shown = Curve {
            label: "bake, vertex colours".into(),
            points: vec![],
            colour: 0,
            style: 0,
        };
        let mut flat = Curve {
            label: "bake, flat".into(),
            points: vec![],
            colour: 1,
            style: 1,
        };
        let mut tracer = Curve {
            label: "path tracer".into(),
            points: vec![],
            colour: 2,
            style: 1,
        };
        for (label, settings) in bakes(args.quick, name) {
            let t = Instant::now();
            let out = pipeline::solve_scene(&scene, &settings)
                .with_context(|| format!("{name}: {label}"))?;
            let seconds = t.elapsed().as_secs_f64();
            let at = Display::from_baked(&out.baked).at(&probes);
            let s_shown = pointwise::score(
                &probes,
                &at.iter()
                    .map(|a| a.map(|a| a.interpolated))
                    .collect::<Vec<_>>(),
            );
            let s_flat = pointwise::score(
                &probes,
                &at.iter().map(|a| a.map(|a| a.flat)).collect::<Vec<_>>(),
            );
            let (traced, paths) = pointwise::trace_for(&scene, &probes, seconds, 7);
            let s_traced =
                pointwise::score(&probes, &traced.into_iter().map(Some).collect::<Vec<_>>());
            score_row(&mut md, &format!("{label}: shown"), seconds, &s_shown);
            score_row(&mut md, &format!("{label}: flat"), seconds, &s_flat);
            score_row(
                &mut md,
                &format!("path tracer, same seconds ({paths} paths per probe)"),
                seconds,
                &s_traced,
            );
            eprintln!(
                "  {name} {label}: {seconds:.2} s, shown {:.4}, flat {:.4}, tracer {:.4}",
                s_shown.rms, s_flat.rms, s_traced.rms
            );
            shown.points.push((seconds, s_shown.rms));
            flat.points.push((seconds, s_flat.rms));
            tracer.points.push((seconds, s_traced.rms));
        }
        let png = args.out.join(format!("pointwise_{name}.png"));
        chart(
            &png,
            &format!("{name}: what the viewer sees, RMS relative error"),
            ("seconds", "RMS relative error of luminance"),
            true,
            &[shown, flat, tracer],
            text,
        )?;
        writeln!(md, "\n![{name}](pointwise_{name}.png)")?;
    }
    Ok(md)
}
