//! The `radiosity` binary: parses the command line ([`cli`]), runs the library, prints the
//! summary and maps errors to exit statuses: 0 success, 1 internal failure, 2 bad input or
//! usage, 3 the solver stopped at --max-iterations without converging (the output is written).

mod cli;
mod progress_bars;

use std::process::ExitCode;

use clap::Parser;

use cli::{BakeArgs, Cli, Command, GenerateArgs, InfoArgs, RenderArgs, SceneKind, VerifyArgs};
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
    progress_bars::install(cli.quiet, cli.verbose);
    let result = match &cli.command {
        Command::Bake(args) => bake(args, cli.quiet),
        Command::Verify(args) => verify(args, cli.quiet),
        Command::Generate(args) => generate(args),
        Command::Render(args) => render(args, cli.quiet),
        Command::Info(args) => info(args),
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
    let overrides = args.materials.overrides()?;
    let options = args.write_options()?;
    for path in args.report.iter().chain(&args.png) {
        export::check_output_dir(path)?;
    }
    if args.png.is_some() {
        // Validate the picture options before the long work (the mesh is not needed for it).
        args.view.view(&export::BakedMesh::default(), 1.0)?;
    }
    let outcome = pipeline::run_with(&args.input, &args.output, &settings, &options, &overrides)?;
    let report = &outcome.report;
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(path) = &args.report {
        report.write_json(path)?;
    }
    if let Some(path) = &args.png {
        let view = args.view.view(&outcome.baked, report.exposure)?;
        png::save(path, &png::render(&outcome.baked, &view))?;
    }
    if !quiet {
        eprintln!("{}: {}", args.output.display(), report.summary());
    }
    radiosity::progress::note(|| {
        let s = &report.seconds;
        format!(
            "seconds: load {:.3}, patches {:.3}, bvh {:.3}, form factors {:.3}, solve {:.3}, \
             bake {:.3}, write {:.3}",
            s.load, s.patches, s.bvh, s.form_factors, s.solve, s.bake, s.write
        )
    });
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

fn render(args: &RenderArgs, quiet: bool) -> Result<u8, Error> {
    use radiosity::export::{ply, BakedMesh};
    cli::check_output(&args.output, "render", "png")?;
    cli::check_exposure(args.exposure)?;
    let overrides = args.materials.overrides()?;
    let is_ply = args
        .input
        .extension()
        .map(|e| e.eq_ignore_ascii_case("ply"))
        == Some(true);
    let mut code = 0;
    // A PLY written by `radiosity bake` is rendered as it is (unless material overrides ask
    // for a new bake); any other input, including other PLY files, is a scene baked first.
    let baked = if is_ply && overrides.is_empty() {
        ply::read(&args.input)
            .ok()
            .and_then(|b| match (b.vertex_radiance, b.face_radiance) {
                (Some(vr), Some(fr)) => Some((b.positions, b.faces, vr, fr, b.camera)),
                _ => None,
            })
    } else {
        None
    };
    if baked.is_some() && args.solve.two_sided {
        // Its radiance is already solved: doubling its faces now would only add black backs.
        return Err(Error::usage(
            "--two-sided",
            format!(
                "{} was written by `radiosity bake` and is rendered as it is (a bake made with \
                 --two-sided already has both sides); bake the original scene with \
                 --two-sided, or give material overrides to bake this mesh again as a scene",
                args.input.display()
            ),
        ));
    }
    let mesh = if let Some((positions, faces, vr, fr, camera)) = baked {
        let f64s = |v: Vec<[f32; 3]>| v.into_iter().map(|x| x.map(f64::from)).collect();
        BakedMesh {
            positions: f64s(positions),
            vertex_radiance: f64s(vr),
            faces,
            face_radiance: f64s(fr),
            camera,
        }
    } else {
        let settings = args.solve.settings()?;
        let mut scene = radiosity::scene::Scene::load(&args.input)?;
        scene.apply_overrides(&overrides)?;
        let outcome = pipeline::solve_scene(&scene, &settings)?;
        for w in &outcome.report.warnings {
            eprintln!("warning: {w}");
        }
        if !outcome.report.converged {
            eprintln!(
                "warning: the solver did not converge (residual {:.3e})",
                outcome.report.residual
            );
            code = EXIT_NOT_CONVERGED;
        }
        if !quiet {
            eprintln!("{}: {}", args.input.display(), outcome.report.summary());
        }
        outcome.baked
    };
    mesh.validate()?;
    let exposure = args
        .exposure
        .unwrap_or_else(|| export::auto_exposure(&mesh));
    let view = args.view.view(&mesh, exposure)?;
    png::save(&args.output, &png::render(&mesh, &view))?;
    Ok(code)
}

fn info(args: &InfoArgs) -> Result<u8, Error> {
    let overrides = args.materials.overrides()?;
    let mut scene = radiosity::scene::Scene::load(&args.input)?;
    scene.apply_overrides(&overrides)?;
    if args.two_sided {
        scene.make_two_sided();
    }
    let info = radiosity::info::SceneInfo::of(&scene)?;
    if args.json {
        println!("{}", info.to_json());
    } else {
        print!("{}", info.text());
    }
    Ok(0)
}

fn generate(args: &GenerateArgs) -> Result<u8, Error> {
    use radiosity::scenes;
    cli::check_output(&args.output, "generate", "obj")?;
    let scene = match args.scene {
        SceneKind::IntegratingSphere => scenes::integrating_sphere(1.0, 3, 30.0, 0.5, [1.0; 3])?,
        SceneKind::Furnace => scenes::furnace_room(0.5, 1.0)?,
        SceneKind::ParallelPlates => scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0)?,
        SceneKind::PerpendicularPlates => scenes::perpendicular_plates(1.0, 1.0, 1.0, 0.5, 1.0)?,
    };
    radiosity::scene::obj::save(&scene, &args.output)?;
    Ok(0)
}
