//! The `radiosity` binary: parses the command line ([`cli`]), runs the library, prints the
//! summary and maps errors to exit statuses: 0 success, 1 internal failure, 2 bad input or
//! usage, 3 the solver stopped at --max-iterations without converging (the output is written).

mod cli;

use std::process::ExitCode;

use clap::Parser;

use cli::{BakeArgs, Cli, Command, GenerateArgs, SceneKind, VerifyArgs};
use radiosity::export::png;
use radiosity::{export, pipeline, verify, Error};

/// Exit status when the solver did not converge (the output is still written).
const EXIT_NOT_CONVERGED: u8 = 3;

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // clap prints help/version to stdout (exit 0) and usage errors to stderr (exit 2).
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    if let Some(n) = cli.threads {
        if n == 0 {
            eprintln!("error: invalid value for --threads: must be at least 1");
            return ExitCode::from(2);
        }
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
        {
            eprintln!("error: cannot start {n} threads: {e}");
            return ExitCode::from(1);
        }
    }
    let result = match &cli.command {
        Command::Bake(args) => bake(args, cli.quiet),
        Command::Verify(args) => verify(args, cli.quiet),
        Command::Generate(args) => generate(args),
    };
    match result {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            eprintln!("error: {e}");
            let mut source = std::error::Error::source(&e);
            while let Some(s) = source {
                eprintln!("  caused by: {s}");
                source = s.source();
            }
            ExitCode::from(e.exit_code() as u8)
        }
    }
}

fn bake(args: &BakeArgs, quiet: bool) -> Result<u8, Error> {
    let settings = args.solve.settings()?;
    let options = args.write_options()?;
    for path in args.report.iter().chain(&args.png) {
        export::check_output_dir(path)?;
    }
    if args.png_size == 0 || args.png_size > 16384 {
        return Err(Error::usage("--png-size", "must be in 1..=16384"));
    }
    let outcome = pipeline::run(&args.input, &args.output, &settings, &options)?;
    let report = &outcome.report;
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(path) = &args.report {
        report.write_json(path)?;
    }
    if let Some(path) = &args.png {
        let (lo, hi) = bounds(&outcome.baked.positions);
        let camera = png::Camera::framing(lo, hi);
        let size = args.png_size;
        let image = png::render(
            &outcome.baked,
            &camera,
            size,
            size,
            2,
            report.exposure,
            false,
        );
        png::save(path, &image)?;
    }
    if !quiet {
        eprintln!("{}: {}", args.output.display(), report.summary());
    }
    if !report.converged {
        eprintln!(
            "warning: the {} solver stopped after {} sweeps at relative residual {:.3e}, \
             above the tolerance {:.1e}: the result is not converged (raise --max-iterations, \
             or check for ρ close to 1 in a closed scene)",
            settings.solver.method.name(),
            report.iterations,
            report.residual,
            settings.solver.tolerance
        );
        return Ok(EXIT_NOT_CONVERGED);
    }
    Ok(0)
}

fn verify(args: &VerifyArgs, quiet: bool) -> Result<u8, Error> {
    let settings = verify::Settings {
        form_factors: args.estimator.settings()?,
        solver: args.solver,
    };
    let cases = verify::run_all(&settings)?;
    print!("{}", verify::table(&cases));
    if let Some(path) = &args.report {
        let text = serde_json::to_string_pretty(&cases)
            .map_err(|e| Error::Internal(format!("report serialisation: {e}")))?;
        export::write_atomic(path, text.as_bytes())?;
    }
    let failed = cases.iter().filter(|c| !c.pass).count();
    if !quiet {
        eprintln!(
            "{} cases, {} passed, {} failed",
            cases.len(),
            cases.len() - failed,
            failed
        );
    }
    Ok(if failed > 0 { 1 } else { 0 })
}

/// Bounding box of a point list.
fn bounds(points: &[[f64; 3]]) -> (glam::DVec3, glam::DVec3) {
    points.iter().fold(
        (glam::DVec3::INFINITY, glam::DVec3::NEG_INFINITY),
        |(lo, hi), p| {
            let p = glam::DVec3::from_array(*p);
            (lo.min(p), hi.max(p))
        },
    )
}

fn generate(args: &GenerateArgs) -> Result<u8, Error> {
    use radiosity::scenes;
    let ext = args.output.extension().map(|e| e.to_ascii_lowercase());
    if ext.as_deref() != Some(std::ffi::OsStr::new("obj")) {
        return Err(Error::usage(
            "--output",
            format!("{}: generate writes .obj files", args.output.display()),
        ));
    }
    export::check_output_dir(&args.output)?;
    let scene = match args.scene {
        SceneKind::IntegratingSphere => scenes::integrating_sphere(1.0, 3, 30.0, 0.5, [1.0; 3])?,
        SceneKind::Furnace => scenes::furnace_room(0.5, 1.0)?,
        SceneKind::ParallelPlates => scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0)?,
        SceneKind::PerpendicularPlates => scenes::perpendicular_plates(1.0, 1.0, 1.0, 0.5, 1.0)?,
    };
    radiosity::scene::obj::save(&scene, &args.output)?;
    Ok(0)
}
