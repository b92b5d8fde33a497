//! The hierarchical-solver harness: `cargo bench -p radiosity-tools --bench hierarchical --
//! [SECTION…] [--quick] [--out DIR]`, sections `epsilon`, `equal-time`, `growth`, `targets`
//! (all when none is named). Every run is a child process of this harness (`--child SPEC`),
//! so its peak memory is its own. Writes to DIR (default `target/hierarchical`):
//!
//! - `epsilon.md`, `epsilon.csv`, `error_vs_epsilon.png`, `links_vs_elements.png`: the Cornell
//!   box (largest per-surface error against the path-traced reference) and the integrating
//!   sphere (one bounce and all bounces, against the closed form) as ε falls; links against
//!   elements;
//! - `equal-time.md`, `equal_time_cornell.png`: error against seconds, matrix (the default and
//!   coarser and finer meshes) and hierarchical (several ε), on the Cornell box;
//! - `growth.md`, `growth.csv`: the generated hall (`radiosity generate hall`) from 10⁴ to 10⁶
//!   triangles at a fixed ε: seconds, peak memory, leaves, links, and the fitted exponents
//!   p of time and memory ∝ leavesᵖ;
//! - `targets.md`: the hierarchical method's targets (Cornell box with ≥ 100,000 leaves; 10⁶
//!   triangles), as BENCHMARKS.md states them ("Hierarchical radiosity", "The hierarchical
//!   method on growing scenes").
//!
//! Everything is timed on the machine it runs on; the date and machine head every file.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Result};
use radiosity::pipeline::{self, Method};
use radiosity::scene::Scene;
use radiosity::validation::{scenes, verify};
use radiosity_tools::{
    chart, fit_order, harness_args, load_font, mib, surface_means, write_sections, Curve,
};

struct Args {
    sections: Vec<String>,
    quick: bool,
    out: PathBuf,
}

const SECTIONS: [&str; 4] = ["epsilon", "equal-time", "growth", "targets"];

fn parse_args() -> Result<Args> {
    let h = harness_args(
        "target/hierarchical",
        "cargo bench -p radiosity-tools --bench hierarchical -- \
         [epsilon|equal-time|growth|targets]… [--quick] [--out DIR]",
    )?;
    let sections = radiosity_tools::sections(h.other, &SECTIONS, &SECTIONS, child)?;
    Ok(Args {
        sections,
        quick: h.quick,
        out: h.out,
    })
}

fn main() -> Result<()> {
    let args = parse_args()?;
    let text = load_font();
    write_sections(&args.out, &args.sections, |s| match s {
        "epsilon" => epsilon(&args, text),
        "equal-time" => equal_time(&args, text),
        "growth" => growth(&args),
        "targets" => targets(&args),
        _ => unreachable!(),
    })
}

/// What a child run reports.
#[derive(serde::Deserialize, serde::Serialize, Debug, Clone)]
struct ChildResult {
    spec: String,
    triangles: usize,
    patches: usize,
    leaves: usize,
    elements: usize,
    links: u64,
    rays: u64,
    sweeps: u32,
    seconds: f64,
    peak_bytes: u64,
    /// Cornell: largest per-surface relative error against the reference; sphere: the
    /// one-bounce and all-bounce mean per-patch relative errors; hall: −1 (none).
    errors: Vec<f64>,
}

/// `SCENE:METHOD:X:Y`: SCENE `cornell`, `sphere` or `hall-N`; METHOD `matrix` (X = max edge,
/// 0 for the default), `hierarchical` (X = ε, Y = minimum area) or `hierarchical-links` (the
/// same with links carrying all emission: no direct light at the elements); a fifth part
/// `nogather` turns the final gather off.
fn child(spec: &str) -> Result<()> {
    let parts: Vec<&str> = spec.split(':').collect();
    if !(4..=5).contains(&parts.len()) {
        bail!("bad spec {spec}");
    }
    let mut s = pipeline::Settings::default();
    if parts.get(4) == Some(&"nogather") {
        s.gather = radiosity::gather::Gather::None;
    }
    let x: f64 = parts[2].parse()?;
    match parts[1] {
        "matrix" => {
            s.method = Method::Matrix;
            s.max_edge = (x > 0.0).then_some(x);
        }
        method => {
            s.method = Method::Hierarchical;
            s.hierarchical.epsilon = x;
            s.hierarchical.min_area = parts[3].parse()?;
            s.hierarchical.direct = method != "hierarchical-links";
        }
    }
    let scene_name = parts[0];
    let t = Instant::now();
    let (out, scene, errors) = if scene_name == "sphere" {
        let scene = scenes::integrating_sphere(1.0, 3, 30.0, 0.5, [1.0; 3])?;
        s.max_edge = Some(0.5); // the facets are the roots (as `radiosity verify` does)
        let mut errors = Vec::new();
        let mut last = None;
        for bounces in [Some(1), None] {
            let mut si = s.clone();
            match bounces {
                Some(n) => {
                    si.solver.method = radiosity::solve::Method::Neumann;
                    si.solver.bounces = n;
                }
                None => si.solver.tolerance = 1e-9,
            }
            let o = pipeline::solve_scene(&scene, &si)?;
            errors.push(
                verify::sphere_wall_errors(&o.patches, &o.solution.radiance, 0.5, bounces)
                    .mean_patch_relative,
            );
            last = Some(o);
        }
        (last.unwrap(), scene, errors)
    } else {
        let scene = if scene_name == "cornell" {
            Scene::load(&radiosity_tools::root().join("meshes/cornell_box.obj"))?
        } else if let Some(n) = scene_name.strip_prefix("hall-") {
            scenes::furnished_hall(n.parse()?)?
        } else {
            bail!("unknown scene {scene_name}");
        };
        let out = pipeline::solve_scene(&scene, &s)?;
        let errors = match radiosity_tools::cornell_reference() {
            Some(reference) if scene_name == "cornell" => {
                vec![radiosity_tools::max_relative_difference(
                    &surface_means(&scene, &out),
                    &reference,
                )]
            }
            _ => vec![f64::NAN],
        };
        (out, scene, errors)
    };
    let seconds = t.elapsed().as_secs_f64();
    // JSON has no NaN: "no error measured" travels as −1.
    let errors = errors
        .into_iter()
        .map(|e| if e.is_nan() { -1.0 } else { e })
        .collect();
    let h = out.report.hierarchical.clone().unwrap_or_default();
    let res = ChildResult {
        spec: spec.into(),
        triangles: scene.triangles.len(),
        patches: out.patches.len(),
        leaves: h.leaves,
        elements: h.elements,
        links: if out.report.hierarchical.is_some() {
            h.links
        } else {
            out.report.form_factors.nnz
        },
        rays: out.report.form_factors.rays_cast,
        sweeps: out.report.iterations,
        seconds,
        peak_bytes: pipeline::report::peak_memory_bytes().unwrap_or(0),
        errors,
    };
    println!("{}", serde_json::to_string(&res)?);
    Ok(())
}

fn spawn(spec: &str) -> Result<ChildResult> {
    let r: ChildResult = radiosity_tools::run_child(spec)?;
    eprintln!(
        "  {spec}: {} leaves, {} links, {:.2} s, {:.0} MiB, errors {:?}",
        r.leaves,
        r.links,
        r.seconds,
        mib(r.peak_bytes),
        r.errors
    );
    Ok(r)
}

/// The default minimum area of the sweeps: small enough that ε decides.
const SWEEP_MIN_AREA: f64 = 1e-7;

fn epsilon(args: &Args, text: bool) -> Result<String> {
    let eps: Vec<f64> = if args.quick {
        vec![1e-3, 1e-4, 1e-5]
    } else {
        vec![3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 3e-6, 1e-6, 3e-7]
    };
    let mut md = String::from(
        "Error against ε (minimum area 1e-7 of the scene, so ε decides). Cornell box: largest \
         relative difference of the per-surface visible means from the path-traced reference \
         (docs/bench/cornell_reference.csv; its own standard error is ≈ 1e-3). Integrating \
         sphere (1280 facets as roots, ρ = 0.5): area-weighted mean per-patch relative error \
         against the closed form, one bounce and all bounces.\n\n\
         | scene | ε | leaves | links | links/leaf | seconds | peak MiB | error | error (all bounces) |\n\
         |---|---|---|---|---|---|---|---|---|\n",
    );
    let mut csv =
        String::from("scene,epsilon,leaves,elements,links,seconds,peak_MiB,error,error2\n");
    let mut curves = Vec::new();
    let mut links_curves = Vec::new();
    for (k, scene) in ["cornell", "sphere"].into_iter().enumerate() {
        let mut points = [Vec::new(), Vec::new()];
        let mut lp = Vec::new();
        for &e in &eps {
            let r = spawn(&format!("{scene}:hierarchical:{e}:{SWEEP_MIN_AREA}"))?;
            let e2 = r.errors.get(1).copied().unwrap_or(f64::NAN).max(f64::NAN);
            writeln!(
                md,
                "| {scene} | {e:.0e} | {} | {} | {:.1} | {:.2} | {:.0} | {:.2e} | {} |",
                r.leaves,
                r.links,
                r.links as f64 / r.leaves as f64,
                r.seconds,
                mib(r.peak_bytes),
                r.errors[0],
                if e2.is_nan() {
                    "–".to_string()
                } else {
                    format!("{e2:.2e}")
                }
            )?;
            writeln!(
                csv,
                "{scene},{e},{},{},{},{:.3},{:.1},{:.4e},{:.4e}",
                r.leaves,
                r.elements,
                r.links,
                r.seconds,
                mib(r.peak_bytes),
                r.errors[0],
                e2
            )?;
            points[0].push((e, r.errors[0]));
            points[1].push((e, e2));
            lp.push((r.elements as f64, r.links as f64));
        }
        curves.push(Curve {
            label: format!("{scene}{}", if k == 1 { ", one bounce" } else { "" }),
            points: points[0].clone(),
            colour: 2 * k,
            style: 0,
        });
        if k == 1 {
            curves.push(Curve {
                label: "sphere, all bounces".into(),
                points: points[1].clone(),
                colour: 3,
                style: 1,
            });
        }
        if let Some((p, r2)) = fit_order(&lp) {
            writeln!(
                md,
                "\n{scene}: links ∝ elements^{p:.2} (r² = {r2:.3}) over the sweep.\n"
            )?;
        }
        links_curves.push(Curve {
            label: scene.into(),
            points: lp,
            colour: 2 * k,
            style: 0,
        });
    }
    std::fs::write(args.out.join("epsilon.csv"), csv)?;
    chart(
        &args.out.join("error_vs_epsilon.png"),
        "Hierarchical radiosity: error against ε",
        ("ε (fraction of emitted power per link)", "relative error"),
        true,
        &curves,
        text,
    )?;
    chart(
        &args.out.join("links_vs_elements.png"),
        "Links against elements",
        ("elements", "links"),
        true,
        &links_curves,
        text,
    )?;
    Ok(md)
}

fn equal_time(args: &Args, text: bool) -> Result<String> {
    let matrix: Vec<f64> = if args.quick {
        vec![0.0, 40.0]
    } else {
        vec![120.0, 80.0, 0.0, 45.0, 35.0]
    };
    let eps: Vec<f64> = if args.quick {
        vec![1e-3, 1e-4]
    } else {
        vec![3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5]
    };
    let mut md = String::from(
        "Cornell box, error (largest per-surface relative difference from the path-traced \
         reference) against seconds. Matrix: contour estimator with 2 refinement rounds \
         (max edge 0 = the default, diagonal / 16). Hierarchical: default minimum area.\n\n\
         | method | setting | patches | links / non-zeros | seconds | peak MiB | error |\n\
         |---|---|---|---|---|---|---|\n",
    );
    let mut curves = vec![
        Curve {
            label: "matrix".into(),
            points: vec![],
            colour: 0,
            style: 1,
        },
        Curve {
            label: "hierarchical".into(),
            points: vec![],
            colour: 1,
            style: 0,
        },
    ];
    let min_area = pipeline::Settings::default().hierarchical.min_area;
    // (curve, method, setting, spec) of every run, matrix first.
    let runs = matrix
        .iter()
        .map(|&m| {
            let setting = if m == 0.0 {
                "max edge default".to_string()
            } else {
                format!("max edge {m}")
            };
            (0, setting, format!("cornell:matrix:{m}:0"))
        })
        .chain(eps.iter().map(|&e| {
            (
                1,
                format!("ε {e:.0e}"),
                format!("cornell:hierarchical:{e}:{min_area}"),
            )
        }));
    for (curve, setting, spec) in runs {
        let r = spawn(&spec)?;
        writeln!(
            md,
            "| {} | {setting} | {} | {} | {:.2} | {:.0} | {:.2e} |",
            curves[curve].label,
            r.patches,
            r.links,
            r.seconds,
            mib(r.peak_bytes),
            r.errors[0]
        )?;
        curves[curve].points.push((r.seconds, r.errors[0]));
    }
    chart(
        &args.out.join("equal_time_cornell.png"),
        "Cornell box: error against time",
        ("seconds", "largest surface error"),
        true,
        &curves,
        text,
    )?;
    Ok(md)
}

/// ε and minimum area of the growth runs.
const GROWTH: (f64, f64) = (1e-4, 1e-7);

fn growth(args: &Args) -> Result<String> {
    let sizes: Vec<usize> = if args.quick {
        vec![10_000, 30_000, 100_000]
    } else {
        vec![10_000, 30_000, 100_000, 300_000, 1_000_000]
    };
    let (eps, min_area) = GROWTH;
    let mut md = format!(
        "The generated hall (`radiosity generate hall --triangles N`), hierarchical, ε = {eps:.0e}, \
         minimum area {min_area:.0e}, links carrying all emission and no final gather at every \
         size (the hall of 10⁴ triangles would otherwise have its direct light by rays of each \
         emitter's own and be gathered, the larger ones by rays drawn from the light tree and \
         not: the fit would mix methods); time \
         and peak memory of the whole solve and bake, load excluded.\n\n\
         | triangles | leaves | elements | links | links/leaf | rays | sweeps | seconds | peak MiB |\n\
         |---|---|---|---|---|---|---|---|---|\n"
    );
    let mut csv = String::from("triangles,leaves,elements,links,rays,sweeps,seconds,peak_MiB\n");
    let mut t_points = Vec::new();
    let mut m_points = Vec::new();
    let mut l_points = Vec::new();
    for &n in &sizes {
        let r = spawn(&format!(
            "hall-{n}:hierarchical-links:{eps}:{min_area}:nogather"
        ))?;
        writeln!(
            md,
            "| {} | {} | {} | {} | {:.1} | {:.2e} | {} | {:.1} | {:.0} |",
            r.triangles,
            r.leaves,
            r.elements,
            r.links,
            r.links as f64 / r.leaves as f64,
            r.rays as f64,
            r.sweeps,
            r.seconds,
            mib(r.peak_bytes)
        )?;
        writeln!(
            csv,
            "{},{},{},{},{},{},{:.3},{:.1}",
            r.triangles,
            r.leaves,
            r.elements,
            r.links,
            r.rays,
            r.sweeps,
            r.seconds,
            mib(r.peak_bytes)
        )?;
        t_points.push((r.leaves as f64, r.seconds));
        m_points.push((r.leaves as f64, r.peak_bytes as f64));
        l_points.push((r.leaves as f64, r.links as f64));
    }
    std::fs::write(args.out.join("growth.csv"), csv)?;
    let fit = |p: &[(f64, f64)]| {
        fit_order(p).map_or("–".to_string(), |(p, r2)| format!("{p:.2} (r² {r2:.3})"))
    };
    writeln!(
        md,
        "\nFitted over the sizes: time ∝ leaves^{}, peak memory ∝ leaves^{}, links ∝ leaves^{}.",
        fit(&t_points),
        fit(&m_points),
        fit(&l_points)
    )?;
    Ok(md)
}

fn targets(args: &Args) -> Result<String> {
    let _ = args;
    let mut md = String::from(
        "| target | run | leaves | links | seconds | peak MiB | error |\n|---|---|---|---|---|---|---|\n",
    );
    let runs = [
        (
            "Cornell box, ≥ 100,000 leaves: < 30 s, < 1 GiB, surfaces within 0.5 %",
            "cornell:hierarchical:3e-7:1e-7",
        ),
        (
            "1,000,000 triangles with area lights: < 10 min, < 4 GiB",
            "hall-1000000:hierarchical:1e-4:1e-7",
        ),
    ];
    for (target, spec) in runs {
        let r = spawn(spec)?;
        writeln!(
            md,
            "| {target} | `{spec}` ({} triangles) | {} | {} | {:.1} | {:.0} | {:.2e} |",
            r.triangles,
            r.leaves,
            r.links,
            r.seconds,
            mib(r.peak_bytes),
            r.errors[0]
        )?;
    }
    Ok(md)
}
