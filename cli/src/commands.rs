//! The five commands, each a short sequence of library calls: parse-level checks first (so a
//! typo costs nothing), then the work, then what the user is told (warnings, the summary line,
//! the exit status). Each returns the exit status of a run that completed.

use radiosity::distributed::Exchange;
use radiosity::pipeline::{self, info::SceneInfo};
use radiosity::scene::Scene;
use radiosity::validation::{scenes, verify};
use radiosity::{io, render, Error};

use crate::args::{
    check_output, BakeArgs, GenerateArgs, InfoArgs, RenderArgs, SceneKind, VerifyArgs,
};
use crate::failure::{Failure, EXIT_NOT_CONVERGED};

/// `radiosity bake`: load → … → write, then the report and the picture if asked. As one rank of
/// several (`comm`), rank 0 alone writes and speaks.
pub fn bake(args: &BakeArgs, quiet: bool, comm: &dyn Exchange) -> Result<u8, Failure> {
    let settings = args.scene.solve.settings()?;
    let overrides = args.scene.materials.overrides()?;
    let options = args.write_options()?;
    for path in args.report.iter().chain(&args.png) {
        io::check_output_dir(path)?;
    }
    // No output may replace an input (the scene, its lights file, an OBJ's material
    // libraries and texture images) or another output.
    let companions = io::companion_files(&args.input);
    let inputs: Vec<&std::path::Path> = std::iter::once(args.input.as_path())
        .chain(args.scene.solve.lights.as_deref())
        .chain(companions.iter().map(|p| p.as_path()))
        .collect();
    let outputs: Vec<(&str, &std::path::Path)> = std::iter::once(("output", args.output.as_path()))
        .chain(args.report.as_deref().map(|p| ("report", p)))
        .chain(args.png.as_deref().map(|p| ("png", p)))
        .collect();
    io::check_distinct(&inputs, &outputs)?;
    if args.png.is_some() {
        args.scene.view.check(1.0)?;
    }
    let outcome = pipeline::run_on(
        &args.input,
        &args.output,
        &settings,
        &options,
        &overrides,
        comm,
    )?;
    if comm.rank() != 0 {
        return Ok(if outcome.report.converged {
            0
        } else {
            EXIT_NOT_CONVERGED
        });
    }
    let report = &outcome.report;
    for w in report.unshown_warnings() {
        eprintln!("warning: {w}");
    }
    if let Some(path) = &args.report {
        report.write_json(path)?;
    }
    if let Some(path) = &args.png {
        let view = args
            .scene
            .view
            .view(&outcome.baked, report.exposure, args.scene.solve.up)?;
        warn_if_blank(&outcome.baked, &view);
        render::save(path, &render::render(&outcome.baked, &view))?;
    }
    if !quiet {
        eprintln!("{}: {}", args.output.display(), report.summary());
    }
    radiosity::progress::note(|| {
        let s = &report.seconds;
        format!(
            "seconds: load {:.3}, patches {:.3}, bvh {:.3}, form factors {:.3}, solve {:.3}, \
             bake {:.3}, gather {:.3}, write {:.3}",
            s.load, s.patches, s.bvh, s.form_factors, s.solve, s.bake, s.gather, s.write
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

/// `radiosity verify`: the analytic suite, a table on stdout; 1 if any case fails.
pub fn verify(args: &VerifyArgs, quiet: bool) -> Result<u8, Failure> {
    let settings = verify::Settings {
        method: args.method.method,
        hierarchical: args.method.hierarchical(),
        form_factors: args.estimator.settings(),
        solver: args.solver,
    };
    settings.form_factors.validate()?;
    settings.hierarchical.validate()?;
    let cases = verify::run_all(&settings)?;
    print!("{}", verify::table(&cases));
    if let Some(path) = &args.report {
        let text = serde_json::to_string_pretty(&cases)
            .map_err(|e| Error::Internal(format!("report serialisation: {e}")))?;
        io::write_atomic(path, text.as_bytes())?;
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

/// `radiosity render`: a PLY written by `bake` is rendered as it is (unless material overrides
/// ask for a new bake); any other input, including other PLY files, is a scene baked first.
pub fn render(args: &RenderArgs, quiet: bool) -> Result<u8, Failure> {
    check_output(&args.output, "render", "png")?;
    args.scene.view.check(args.exposure.unwrap_or(1.0))?;
    let overrides = args.scene.materials.overrides()?;
    let is_ply = args
        .input
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ply"));
    let baked = (is_ply && overrides.is_empty())
        .then(|| io::ply::read(&args.input).ok()?.into_baked())
        .flatten();
    if baked.is_some() && args.scene.solve.two_sided {
        // Its radiance is already solved: doubling its faces now would only add black backs.
        return Err(Failure::usage(
            "--two-sided",
            format!(
                "{} was written by `radiosity bake` and is rendered as it is (a bake made with \
                 --two-sided already has both sides); bake the original scene with \
                 --two-sided, or give material overrides to bake this mesh again as a scene",
                args.input.display()
            ),
        ));
    }
    let mut code = 0;
    let mesh = match baked {
        Some(mesh) => mesh,
        None => {
            let settings = args.scene.solve.settings()?;
            let mut scene = Scene::load(&args.input)?;
            scene.apply_overrides(&overrides)?;
            let outcome = pipeline::solve_scene(&scene, &settings)?;
            for w in outcome.report.unshown_warnings() {
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
        }
    };
    mesh.validate()?;
    let exposure = args.exposure.unwrap_or_else(|| mesh.auto_exposure());
    let view = args.scene.view.view(&mesh, exposure, args.scene.solve.up)?;
    warn_if_blank(&mesh, &view);
    render::save(&args.output, &render::render(&mesh, &view))?;
    Ok(code)
}

/// `radiosity info`: the scene described, as text or JSON.
pub fn info(args: &InfoArgs) -> Result<u8, Failure> {
    let overrides = args.materials.overrides()?;
    let settings = args.solve.settings()?;
    let mut scene = Scene::load(&args.input)?;
    scene.apply_overrides(&overrides)?;
    // The scene as the bake sees it (faces turned, back sides made), and the estimate of
    // that bake; with --max-time, of the settings the bake would fit to it (the method and
    // gather it would take).
    let prepared = pipeline::prepare(&scene, &settings);
    let scene = &prepared.scene;
    if let Some(o) = prepared.orientation.as_ref().filter(|o| o.changed()) {
        radiosity::progress::warning(&format!("{}: {}", args.input.display(), o.summary()));
    }
    let threads = rayon::current_num_threads();
    let estimate = match settings.max_time {
        Some(budget) => pipeline::estimate::fit_time(scene, &settings, threads, budget)?.1,
        None => pipeline::Estimate::of(scene, &settings, threads)?,
    };
    // The lights a bake uses: the options' and the scene file's own (glTF's).
    let environment = settings.resolved(scene)?.environment;
    let info = SceneInfo::of(scene, &environment, estimate)?;
    if args.json {
        println!("{}", info.to_json());
    } else {
        print!("{}", info.text());
    }
    Ok(0)
}

/// `radiosity generate`: one of the verification scenes as OBJ + MTL.
pub fn generate(args: &GenerateArgs) -> Result<u8, Failure> {
    check_output(&args.output, "generate", "obj")?;
    let scene = match args.scene {
        SceneKind::IntegratingSphere => scenes::integrating_sphere(1.0, 3, 30.0, 0.5, [1.0; 3])?,
        SceneKind::Furnace => scenes::furnace_room(0.5, 1.0)?,
        SceneKind::ParallelPlates => scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0)?,
        SceneKind::PerpendicularPlates => scenes::perpendicular_plates(1.0, 1.0, 1.0, 0.5, 1.0)?,
        SceneKind::Hall => scenes::furnished_hall(triangles(args)?)?,
        SceneKind::LivingRoom => scenes::living_room()?,
        SceneKind::TwoRooms => scenes::two_rooms()?,
        SceneKind::Study => scenes::study()?,
        SceneKind::Attic => scenes::attic()?,
        SceneKind::Kitchen => scenes::kitchen()?,
        SceneKind::Office => scenes::office(triangles(args)?)?,
        SceneKind::OfficeDaylit => scenes::office_daylit(triangles(args)?)?,
    };
    io::obj::save(&scene, &args.output)?;
    Ok(0)
}

/// `--triangles` of the scenes that take it (hall, office), checked.
fn triangles(args: &GenerateArgs) -> Result<usize, Failure> {
    if !(1..=50_000_000).contains(&args.triangles) {
        return Err(Failure::usage(
            "--triangles",
            format!("{} is not in 1..=50000000", args.triangles),
        ));
    }
    Ok(args.triangles)
}

/// Warns when the picture about to be rendered would be black: its camera sees no front face.
fn warn_if_blank(mesh: &radiosity::bake::BakedMesh, view: &render::View) {
    if render::sees_nothing(mesh, &view.camera) {
        eprintln!(
            "warning: the picture shows nothing: no ray from the camera ({}) meets the front \
             of a face (backs and misses are black); give --camera, or --up for a scene whose \
             up axis is not y",
            view.camera
        );
    }
}
