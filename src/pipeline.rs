//! The whole data flow in one place — start reading here:
//!
//! load → patches → BVH → form factors → matrix → solve → bake → write
//!
//! [`run`] does all of it for a file; [`solve_scene`] does the middle for a scene already in
//! memory (the verification suite and the tests use it). Each step is a call into the module
//! that owns it; this file only sequences them, times them and fills the [`Report`].

use std::path::Path;
use std::time::Instant;

use crate::export::{self, BakedMesh, Format};
use crate::form_factor::{self, FormFactors, Needed};
use crate::matrix::System;
use crate::patch::{self, Patches};
use crate::report::{Report, Seconds};
use crate::scene::{Override, Scene};
use crate::solve::{self, Solution};
use crate::visibility::{Visibility, NONE};
use crate::{bake, cache, refine, Result};

/// Everything that controls a bake.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Longest patch edge, scene units; `None` = [`patch::default_max_edge`].
    pub max_edge: Option<f64>,
    /// Form-factor estimation.
    pub form_factors: form_factor::Settings,
    /// Linear solve.
    pub solver: solve::Settings,
    /// Crease angle, degrees: where faces meet at smaller angles the mesh samples one smooth
    /// surface (interpolated normals, shared output vertices).
    pub crease_degrees: f64,
    /// Give every face a back side with its material ([`Scene::make_two_sided`]).
    pub two_sided: bool,
    /// Adaptive refinement: rounds of splitting the patches whose radiance jumps against a
    /// neighbour's by more than `refine_threshold` (relative), each followed by a new solve
    /// ([`crate::refine`]); 0 = none.
    pub refine_rounds: u32,
    /// Relative luminance jump that marks two neighbours for splitting.
    pub refine_threshold: f64,
    /// Form-factor cache directory (`--cache`): F is read from it when these patches and
    /// estimator settings were computed before, and stored otherwise ([`crate::cache`]).
    pub cache: Option<std::path::PathBuf>,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            max_edge: None,
            form_factors: form_factor::Settings::default(),
            solver: solve::Settings::default(),
            crease_degrees: bake::DEFAULT_CREASE_DEGREES,
            two_sided: false,
            refine_rounds: 2,
            refine_threshold: crate::refine::DEFAULT_THRESHOLD,
            cache: None,
        }
    }
}

/// What [`solve_scene`] produces: every intermediate a caller may want to inspect.
pub struct Outcome {
    pub patches: Patches,
    pub form_factors: FormFactors,
    pub solution: Solution,
    pub baked: BakedMesh,
    pub report: Report,
}

/// patches → BVH → form factors → matrix → solve → bake, for a scene in memory.
pub fn solve_scene(scene: &Scene, settings: &Settings) -> Result<Outcome> {
    let two_sided = settings.two_sided.then(|| scene.to_two_sided());
    let scene = two_sided.as_ref().unwrap_or(scene);
    scene.validate()?;
    settings.solver.validate()?;
    let mut report = Report::new(settings);
    report.warnings.extend(scene.warnings.iter().cloned());
    report.input_triangles = scene.triangles.len();
    let mut seconds = Seconds::default();

    let t = Instant::now();
    let max_edge = settings
        .max_edge
        .unwrap_or_else(|| patch::default_max_edge(scene));
    let mut patches = patch::subdivide(scene, max_edge, settings.crease_degrees)?;
    report.max_edge = max_edge;
    seconds.patches = t.elapsed().as_secs_f64();

    let (mut form_factors, mut solution) =
        light_transport(scene, &patches, settings, None, &mut report, &mut seconds)?;
    for _ in 0..settings.refine_rounds {
        let marked = refine::marks(
            &patches,
            &solution.radiance,
            settings.refine_threshold,
            settings.crease_degrees,
        );
        if !marked.contains(&true) {
            break;
        }
        let t = Instant::now();
        let old = patches;
        patches = patch::refine(scene, &old, &marked, settings.crease_degrees)?;
        let before = old.len();
        crate::progress::note(|| {
            format!(
                "refinement round {}: {} of {before} patches marked, {} patches now",
                report.refine_rounds + 1,
                marked.iter().filter(|&&m| m).count(),
                patches.len()
            )
        });
        seconds.patches += t.elapsed().as_secs_f64();
        report.refine_rounds += 1;
        // Pairs of patches that refinement left as they were keep their form factors.
        // (Pair estimators only, and not from a normalised matrix without its raw form, as a
        // cache hit gives.)
        let raw_known = form_factors.pair_matrix.is_some()
            || !(form_factors.stats.closed_scene || settings.form_factors.reciprocity);
        let reuse = (settings.form_factors.reuse
            && raw_known
            && settings.form_factors.estimator != form_factor::Estimator::Hemisphere)
            .then(|| {
                let old_index: std::collections::HashMap<([u32; 3], u32), u32> = old
                    .triangles
                    .iter()
                    .zip(&old.source_triangle)
                    .enumerate()
                    .map(|(k, (t, s))| ((*t, *s), k as u32))
                    .collect();
                form_factor::Reuse {
                    matrix: form_factors
                        .pair_matrix
                        .as_ref()
                        .unwrap_or(&form_factors.matrix),
                    old_of_new: patches
                        .triangles
                        .iter()
                        .zip(&patches.source_triangle)
                        .map(|(t, s)| old_index.get(&(*t, *s)).copied().unwrap_or(NONE))
                        .collect(),
                }
            });
        (form_factors, solution) = light_transport(
            scene,
            &patches,
            settings,
            reuse.as_ref(),
            &mut report,
            &mut seconds,
        )?;
    }
    report.patches = patches.len();

    let t = Instant::now();
    let mut baked = bake::bake(&patches, &solution.radiance, settings.crease_degrees);
    baked.camera = scene.camera;
    report.vertices = baked.positions.len();
    seconds.bake = t.elapsed().as_secs_f64();

    report.seconds = seconds;
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
    reuse: Option<&form_factor::Reuse>,
    report: &mut Report,
    seconds: &mut Seconds,
) -> Result<(FormFactors, Solution)> {
    let form_factors = if scene.has_emitters() {
        form_factors(patches, settings, reuse, report, seconds)?
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
    crate::progress::note(|| {
        let s = &form_factors.stats;
        format!(
            "{} patches: {} pairs ({} culled, {} skipped), {:.3e} rays, {} non-zeros; \
             {} {} iterations, residual {:.2e}{}",
            patches.len(),
            s.pairs,
            s.pairs_culled,
            s.pairs_skipped,
            s.rays_cast as f64,
            s.nnz,
            if solution.omega != 1.0 {
                format!(
                    "{} (ω = {:.2})",
                    settings.solver.method.name(),
                    solution.omega
                )
            } else {
                settings.solver.method.name().to_string()
            },
            solution.iterations,
            solution.residual,
            if solution.grey {
                " (grey: one channel)"
            } else {
                ""
            }
        )
    });
    report.iterations = solution.iterations;
    report.omega = solution.omega;
    report.residual = solution.residual;
    report.converged = solution.converged;
    seconds.solve += t.elapsed().as_secs_f64();
    Ok((form_factors, solution))
}

/// F for `patches`: from the cache when `settings.cache` has it, else BVH → estimator (and
/// stored in the cache).
fn form_factors(
    patches: &Patches,
    settings: &Settings,
    reuse: Option<&form_factor::Reuse>,
    report: &mut Report,
    seconds: &mut Seconds,
) -> Result<FormFactors> {
    let key = settings
        .cache
        .as_ref()
        .map(|dir| (dir, cache::key(patches, &settings.form_factors)));
    if let Some((dir, key)) = &key {
        let entry = report.cache.get_or_insert_with(|| cache::CacheReport {
            dir: dir.display().to_string(),
            ..Default::default()
        });
        match cache::load(dir, key, patches.len()) {
            Ok(Some((ff, saved))) => {
                entry.hits += 1;
                entry.seconds_saved += saved;
                return Ok(ff);
            }
            Ok(None) => {}
            Err(e) => report.warnings.push(e.to_string()),
        }
    }
    let t = Instant::now();
    let corners: Vec<_> = (0..patches.len()).map(|i| patches.corners(i)).collect();
    let visibility = Visibility::build(&corners);
    let bvh_seconds = t.elapsed().as_secs_f64();
    seconds.bvh += bvh_seconds;

    let t = Instant::now();
    // A cached F must serve any materials: compute every entry then.
    let needed = if settings.form_factors.skip_unneeded && key.is_none() {
        let bounces =
            (settings.solver.method == solve::Method::Neumann).then_some(settings.solver.bounces);
        Needed::for_solve(patches, bounces)
    } else {
        Needed::all(patches.len())
    };
    let ff =
        form_factor::compute_reusing(patches, &visibility, &settings.form_factors, &needed, reuse)?;
    let ff_seconds = t.elapsed().as_secs_f64();
    seconds.form_factors += ff_seconds;
    if let Some((dir, key)) = &key {
        cache::store(dir, key, &ff, bvh_seconds + ff_seconds)?;
        if let Some(entry) = report.cache.as_mut() {
            entry.stored += 1;
        }
    }
    Ok(ff)
}

/// Output options of [`run`].
#[derive(Debug, Clone, Copy, Default)]
pub struct WriteOptions {
    /// ASCII instead of binary PLY.
    pub ascii: bool,
    /// Exposure (radiance multiplier before sRGB); `None` = [`export::auto_exposure`].
    pub exposure: Option<f64>,
}

/// The whole bake of a file: load → … → write. Returns the report (and the outcome).
pub fn run(
    input: &Path,
    output: &Path,
    settings: &Settings,
    options: &WriteOptions,
) -> Result<Outcome> {
    run_with(input, output, settings, options, &[])
}

/// [`run`] with material overrides applied to the scene right after loading
/// ([`Scene::apply_overrides`]: later ones win; an unknown material is a usage error).
pub fn run_with(
    input: &Path,
    output: &Path,
    settings: &Settings,
    options: &WriteOptions,
    overrides: &[Override],
) -> Result<Outcome> {
    // Check the output format before any work, so a typo costs nothing.
    let format = Format::from_path(output, options.ascii)?;
    export::check_output_dir(output)?;

    let t = Instant::now();
    let mut scene = Scene::load(input)?;
    scene.apply_overrides(overrides)?;
    let load_seconds = t.elapsed().as_secs_f64();

    let mut outcome = solve_scene(&scene, settings)?;

    let t = Instant::now();
    let exposure = options
        .exposure
        .unwrap_or_else(|| export::auto_exposure(&outcome.baked));
    export::write(output, &outcome.baked, format, exposure)?;
    let report = &mut outcome.report;
    report.exposure = exposure;
    report.input = Some(input.display().to_string());
    report.output = Some(output.display().to_string());
    report.overrides = overrides.iter().map(Override::to_string).collect();
    report.seconds.load = load_seconds;
    report.seconds.write = t.elapsed().as_secs_f64();
    report.peak_memory_bytes = crate::report::peak_memory_bytes();
    Ok(outcome)
}
