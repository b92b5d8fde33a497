//! The `scale` section: the Cornell box at growing patch counts, each run in a child process of
//! this harness (`--child SPEC`) so that its peak memory is its own.

use super::*;

/// What a child run reports.
#[derive(serde::Deserialize, serde::Serialize, Debug, Clone)]
pub(super) struct ChildResult {
    spec: String,
    patches: usize,
    nnz: u64,
    rays: u64,
    seconds: [f64; 4], // patches, bvh, form factors, solve
    total: f64,
    peak_bytes: u64,
    max_surface_error: f64,
    iterations: u32,
}

/// `estimator:max_edge:rays:refine[:threshold]`, e.g. `contour:60:0:2`.
pub(super) fn child(spec: &str) -> Result<()> {
    let parts: Vec<&str> = spec.split(':').collect();
    let estimator = match parts[0] {
        "hemisphere" => Estimator::Hemisphere,
        _ => Estimator::Contour,
    };
    let mut s = settings(parts[1].parse()?);
    s.form_factors.estimator = estimator;
    s.form_factors.rays = parts[2].parse::<u32>()?.max(1);
    s.refine_rounds = parts[3].parse()?;
    if let Some(th) = parts.get(4) {
        s.refine_threshold = th.parse()?;
    }
    let scene = cornell()?;
    let (out, total) = run(&scene, &s)?;
    let r = &out.report;
    let error = surface_error(&scene, &out).unwrap_or(f64::NAN);
    let res = ChildResult {
        spec: spec.into(),
        patches: r.patches,
        nnz: r.form_factors.nnz,
        rays: r.form_factors.rays_cast,
        seconds: [
            r.seconds.patches,
            r.seconds.bvh,
            r.seconds.form_factors,
            r.seconds.solve,
        ],
        total,
        peak_bytes: radiosity::pipeline::report::peak_memory_bytes().unwrap_or(0),
        max_surface_error: error,
        iterations: r.iterations,
    };
    println!("{}", serde_json::to_string(&res)?);
    Ok(())
}

/// Largest relative difference of two outcomes' per-surface means.
pub(super) fn surface_difference(scene: &Scene, a: &Outcome, b: &Outcome) -> f64 {
    radiosity_tools::max_relative_difference(&surface_means(scene, a), &surface_means(scene, b))
}

/// Largest relative difference, over surfaces and channels, of the visible-area mean radiance
/// from the path-traced reference in docs/bench/cornell_reference.csv.
pub(super) fn surface_error(scene: &Scene, out: &Outcome) -> Option<f64> {
    let reference = radiosity_tools::cornell_reference()?;
    Some(radiosity_tools::max_relative_difference(
        &surface_means(scene, out),
        &reference,
    ))
}

pub(super) fn spawn(spec: &str) -> Result<ChildResult> {
    let r: ChildResult = radiosity_tools::run_child(spec)?;
    eprintln!(
        "  {spec}: {} patches, {:.2} s, {:.0} MiB, error {:.2e}",
        r.patches,
        r.total,
        radiosity_tools::mib(r.peak_bytes),
        r.max_surface_error
    );
    Ok(r)
}

pub(super) fn scale(args: &Args) -> Result<String> {
    let mut md = String::new();
    let mut csv = String::from(
        "spec,patches,nnz,rays,patches_s,bvh_s,form_factors_s,solve_s,total_s,peak_MiB,max_surface_error\n",
    );
    let mut table = |rows: &[ChildResult], title: &str, md: &mut String| -> Result<()> {
        writeln!(
            md,
            "\n{title}\n\n| run | patches | non-zeros | rays | form factors s | solve s | total s | peak MiB | bytes/patch | max surface error |\n|---|---|---|---|---|---|---|---|---|---|"
        )?;
        for r in rows {
            writeln!(
                csv,
                "{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.1},{:.3e}",
                r.spec,
                r.patches,
                r.nnz,
                r.rays,
                r.seconds[0],
                r.seconds[1],
                r.seconds[2],
                r.seconds[3],
                r.total,
                radiosity_tools::mib(r.peak_bytes),
                r.max_surface_error
            )?;
            writeln!(
                md,
                "| `{}` | {} | {:.3e} | {:.3e} | {:.2} | {:.2} | {:.2} | {:.0} | {:.0} | {:.1e} |",
                r.spec,
                r.patches,
                r.nnz as f64,
                r.rays as f64,
                r.seconds[2],
                r.seconds[3],
                r.total,
                radiosity_tools::mib(r.peak_bytes),
                r.peak_bytes as f64 / r.patches as f64,
                r.max_surface_error
            )?;
        }
        Ok(())
    };
    // Scaling: uniform meshes, no refinement.
    let contour: Vec<f64> = if args.quick {
        vec![120.0, 60.0, 45.0]
    } else {
        vec![160.0, 120.0, 80.0, 60.0, 45.0, 35.0, 30.0]
    };
    let hemi: Vec<f64> = if args.quick {
        vec![60.0, 30.0]
    } else {
        vec![60.0, 30.0, 22.0, 15.0, 11.0]
    };
    let c_rows: Vec<ChildResult> = contour
        .iter()
        .map(|e| spawn(&format!("contour:{e}:0:0")))
        .collect::<Result<_>>()?;
    let h_rows: Vec<ChildResult> = hemi
        .iter()
        .map(|e| spawn(&format!("hemisphere:{e}:256:0")))
        .collect::<Result<_>>()?;
    table(
        &c_rows,
        "**Contour estimator, uniform meshes** (`estimator:max-edge:rays:refine`)",
        &mut md,
    )?;
    table(
        &h_rows,
        "**Hemisphere estimator, 256 rays per patch, uniform meshes**",
        &mut md,
    )?;
    let exponent = |rows: &[ChildResult], f: &dyn Fn(&ChildResult) -> f64| {
        let pts: Vec<(f64, f64)> = rows.iter().map(|r| (r.patches as f64, f(r))).collect();
        fit_order(&pts).map_or(f64::NAN, |(p, _)| p)
    };
    writeln!(
        md,
        "\nFitted growth exponents (time or memory ∝ patches^p): contour form factors p = {:.2}, \
         solve p = {:.2}, peak memory p = {:.2}; hemisphere form factors p = {:.2}, solve p = \
         {:.2}, peak memory p = {:.2}.",
        exponent(&c_rows, &|r| r.seconds[2]),
        exponent(&c_rows, &|r| r.seconds[3]),
        exponent(&c_rows, &|r| r.peak_bytes as f64),
        exponent(&h_rows, &|r| r.seconds[2]),
        exponent(&h_rows, &|r| r.seconds[3]),
        exponent(&h_rows, &|r| r.peak_bytes as f64),
    )?;
    // The targets.
    let targets: Vec<ChildResult> = [
        "contour:60:0:2",
        "contour:60:0:3:0.2",
        "hemisphere:30:1024:0",
        if args.quick {
            "hemisphere:22:256:0"
        } else {
            "hemisphere:11:256:0"
        },
    ]
    .iter()
    .map(|s| spawn(s))
    .collect::<Result<_>>()?;
    table(
        &targets,
        "**The targets** (default settings; ~10k patches; ~100k patches)",
        &mut md,
    )?;
    std::fs::write(args.out.join("scale.csv"), csv)?;
    Ok(md)
}

// ---------------------------------------------------------------------------------------------
// Rays against Embree
