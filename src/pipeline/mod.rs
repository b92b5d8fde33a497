//! The whole data flow in one place — start reading here:
//!
//! load → patches → BVH → form factors → matrix → solve → (refine ↺) → bake → write
//!
//! [`run`] does all of it for a file; [`solve_scene`] does the middle for a scene already in
//! memory (the verification suite and the tests use it). Each step is a call into the module
//! that owns it; this file only sequences them and times them. The [`Settings`] and their one
//! [`Settings::validate`] are in [`settings`], the [`Report`] of counts and seconds in
//! [`report`], and the summary `radiosity info` prints in [`info`].

pub mod info;
pub mod report;
pub mod settings;

pub use report::{Report, Seconds};
pub use settings::{Settings, WriteOptions};

use std::path::Path;
use std::time::Instant;

use crate::bake::{self, BakedMesh};
use crate::form_factor::{self, cache, FormFactors, Needed, Reuse};
use crate::io::{self, Format};
use crate::mesh::{self, refine, Patches};
use crate::scene::{Override, Scene};
use crate::solve::{self, Solution, System};
use crate::visibility::Visibility;
use crate::Result;

/// What [`solve_scene`] produces: every intermediate a caller may want to inspect.
pub struct Outcome {
    /// The patches of the last solve (after refinement).
    pub patches: Patches,
    /// Their form factors.
    pub form_factors: FormFactors,
    /// Their radiance.
    pub solution: Solution,
    /// The radiance baked to the output mesh's vertices.
    pub baked: BakedMesh,
    /// Counts, counters, seconds per stage and warnings.
    pub report: Report,
}

/// The whole bake of a file: load → … → write, with no material overrides.
pub fn run(
    input: &Path,
    output: &Path,
    settings: &Settings,
    options: &WriteOptions,
) -> Result<Outcome> {
    run_with(input, output, settings, options, &[])
}

/// [`run`] with material overrides applied to the scene right after loading
/// ([`Scene::apply_overrides`]: later ones win; an unknown material is an error).
pub fn run_with(
    input: &Path,
    output: &Path,
    settings: &Settings,
    options: &WriteOptions,
    overrides: &[Override],
) -> Result<Outcome> {
    // Check every setting and the output before any work, so a typo costs nothing.
    settings.validate()?;
    options.validate()?;
    let format = Format::from_path(output, options.ascii)?;
    io::check_output_dir(output)?;

    let t = Instant::now();
    let mut scene = Scene::load(input)?;
    scene.apply_overrides(overrides)?;
    let load_seconds = t.elapsed().as_secs_f64();

    let mut outcome = solve_scene(&scene, settings)?;

    let t = Instant::now();
    let exposure = options
        .exposure
        .unwrap_or_else(|| outcome.baked.auto_exposure());
    io::write(output, &outcome.baked, format, exposure)?;
    let report = &mut outcome.report;
    report.exposure = exposure;
    report.input = Some(input.display().to_string());
    report.output = Some(output.display().to_string());
    report.overrides = overrides.iter().map(Override::to_string).collect();
    report.seconds.load = load_seconds;
    report.seconds.write = t.elapsed().as_secs_f64();
    report.peak_memory_bytes = report::peak_memory_bytes();
    Ok(outcome)
}

/// patches → BVH → form factors → matrix → solve (→ refine, again) → bake, for a scene in
/// memory.
pub fn solve_scene(scene: &Scene, settings: &Settings) -> Result<Outcome> {
    settings.validate()?;
    let two_sided = settings.two_sided.then(|| scene.to_two_sided());
    let scene = two_sided.as_ref().unwrap_or(scene);
    scene.validate()?;
    let mut report = Report::new(settings);
    report.warnings.extend(scene.warnings.iter().cloned());
    report.input_triangles = scene.triangles.len();

    // Patches.
    let t = Instant::now();
    report.max_edge = settings
        .max_edge
        .unwrap_or_else(|| mesh::default_max_edge(scene));
    let mut patches = mesh::subdivide(scene, report.max_edge, settings.crease_degrees)?;
    report.seconds.patches = t.elapsed().as_secs_f64();

    // BVH → form factors → matrix → solve.
    let (mut form_factors, mut solution) =
        light_transport(scene, &patches, settings, None, &mut report)?;

    // Adaptive refinement: split where neighbours' radiance jumps and solve again; pairs of
    // patches a round leaves unchanged keep their form factors.
    for _ in 0..settings.refine_rounds {
        let t = Instant::now();
        let marked = refine::marks(
            &patches,
            &solution.radiance,
            settings.refine_threshold,
            settings.crease_degrees,
        );
        if !marked.contains(&true) {
            break;
        }
        let refined = mesh::refine(scene, &patches, &marked, settings.crease_degrees)?;
        report.refine_rounds += 1;
        crate::progress::note(|| report::refine_note(&report, &marked, &refined));
        report.seconds.patches += t.elapsed().as_secs_f64();
        let reuse = Reuse::between(&form_factors, &settings.form_factors, &patches, &refined);
        (form_factors, solution) =
            light_transport(scene, &refined, settings, reuse.as_ref(), &mut report)?;
        patches = refined;
    }
    report.patches = patches.len();

    // Bake.
    let t = Instant::now();
    let mut baked = bake::bake(&patches, &solution.radiance, settings.crease_degrees);
    baked.camera = scene.camera;
    report.vertices = baked.positions.len();
    report.seconds.bake = t.elapsed().as_secs_f64();
    Ok(Outcome {
        patches,
        form_factors,
        solution,
        baked,
        report,
    })
}

/// BVH → form factors → matrix → solve for `patches`: fills the report's counters and adds
/// to the stage times (refinement rounds add up).
fn light_transport(
    scene: &Scene,
    patches: &Patches,
    settings: &Settings,
    reuse: Option<&Reuse>,
    report: &mut Report,
) -> Result<(FormFactors, Solution)> {
    let form_factors = if scene.has_emitters() {
        form_factors(patches, settings, reuse, report)?
    } else {
        // Without emitters L = 0 whatever F is: skip the BVH and the form factors.
        let warning = "no emitters in the scene (no material has Ke > 0): the result is black";
        if !report.warnings.iter().any(|w| w == warning) {
            report.warnings.push(warning.into());
        }
        FormFactors::empty(patches.len())
    };
    report.form_factors = form_factors.stats.clone();

    let t = Instant::now();
    let system = System {
        form_factors: &form_factors,
        reflectance: &patches.reflectance,
        emission: &patches.emission,
    };
    let solution = solve::solve(&system, &settings.solver)?;
    crate::progress::note(|| report::solve_note(patches.len(), &form_factors.stats, &solution));
    report.iterations = solution.iterations;
    report.omega = solution.omega;
    report.residual = solution.residual;
    report.converged = solution.converged;
    report.seconds.solve += t.elapsed().as_secs_f64();
    Ok((form_factors, solution))
}

/// F for `patches`: from the cache when `settings.cache` has it, else BVH → estimator (and
/// stored in the cache).
fn form_factors(
    patches: &Patches,
    settings: &Settings,
    reuse: Option<&Reuse>,
    report: &mut Report,
) -> Result<FormFactors> {
    let key = settings
        .cache
        .as_ref()
        .map(|dir| (dir, cache::key(patches, &settings.form_factors)));
    if let Some((dir, key)) = &key {
        let entry = report
            .cache
            .get_or_insert_with(|| cache::CacheReport::new(dir));
        if let Some(ff) = cache::lookup(dir, key, patches.len(), entry, &mut report.warnings) {
            return Ok(ff);
        }
    }
    let t = Instant::now();
    let corners: Vec<_> = (0..patches.len()).map(|i| patches.corners(i)).collect();
    let visibility = Visibility::build(&corners);
    let bvh_seconds = t.elapsed().as_secs_f64();
    report.seconds.bvh += bvh_seconds;

    let t = Instant::now();
    // A cached F must serve any materials: compute every entry then.
    let needed = if settings.form_factors.shortcuts.skip_unneeded && key.is_none() {
        let bounces =
            (settings.solver.method == solve::Method::Neumann).then_some(settings.solver.bounces);
        Needed::for_solve(patches, bounces)
    } else {
        Needed::all(patches.len())
    };
    let ff =
        form_factor::compute_reusing(patches, &visibility, &settings.form_factors, &needed, reuse)?;
    let ff_seconds = t.elapsed().as_secs_f64();
    report.seconds.form_factors += ff_seconds;
    if let Some((dir, key)) = &key {
        cache::store(dir, key, &ff, bvh_seconds + ff_seconds)?;
        if let Some(entry) = report.cache.as_mut() {
            entry.stored += 1;
        }
    }
    Ok(ff)
}
