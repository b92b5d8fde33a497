//! The whole data flow in one place — start reading here:
//!
//! load → contact lines → patches → BVH → form factors → matrix → solve → (refine ↺) → bake →
//! gather → write
//!
//! [`run`] does all of it for a file; [`solve_scene`] does the middle for a scene already in
//! memory (the verification suite and the tests use it). Each step is a call into the module
//! that owns it; this file only sequences them and times them. The [`Settings`] and their one
//! [`Settings::validate`] are in [`settings`], the [`Report`] of counts and seconds in
//! [`report`], and the summary `radiosity info` prints in [`info`].

pub mod estimate;
pub mod info;
pub mod report;
pub mod settings;
pub mod speed;

pub use estimate::Estimate;
pub use report::{Report, Seconds};
pub use settings::{
    Method, Settings, WriteOptions, AUTO_MATRIX_MAX_PATCHES, MAX_DISPLAY_BUDGET, MAX_FINER,
};

use std::path::Path;
use std::time::{Duration, Instant};

use crate::bake::{self, BakedMesh};
use crate::distributed::{Exchange, Solo};
use crate::form_factor::{self, cache, FormFactors, Needed, Reuse};
use crate::gather::{self, Gather};
use crate::hierarchical;
use crate::io::{self, Format};
use crate::mesh::{self, refine, Patches};
use crate::scene::orient::{self, Orient};
use crate::scene::{Override, Scene};
use crate::solve::{self, Solution, System};
use crate::visibility::Visibility;
use crate::Result;
use glam::DVec3;

/// What [`solve_scene`] produces: every intermediate a caller may want to inspect.
#[derive(Debug)]
pub struct Outcome {
    /// The patches of the last solve (after refinement).
    pub patches: Patches,
    /// Their form factors (`method = matrix`; the hierarchical solver has links instead,
    /// counted in [`Report::hierarchical`]).
    pub form_factors: Option<FormFactors>,
    /// Their radiance.
    pub solution: Solution,
    /// The visible (unburied) fraction of each patch's area, in [0, 1]: what a viewer can
    /// see of it (the floor under a block is 0).
    pub visible_fraction: Vec<f64>,
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
    run_on(input, output, settings, options, overrides, &Solo)
}

/// [`run_with`] as one rank of a bake over several processes ([`crate::distributed`]): every
/// rank calls it with the same arguments. The hierarchical solve is shared among the ranks
/// ([`hierarchical::solve_on`]); the rest runs on every rank alike (the matrix method
/// whole, with a warning), and rank 0 alone writes the output. Every rank returns the
/// outcome one process would.
pub fn run_on(
    input: &Path,
    output: &Path,
    settings: &Settings,
    options: &WriteOptions,
    overrides: &[Override],
    comm: &dyn Exchange,
) -> Result<Outcome> {
    // Check every setting and the output before any work, so a typo costs nothing.
    settings.validate()?;
    options.validate()?;
    let format = match Format::from_path(output, options.ascii)? {
        // glTF is +Y up: the scene's own up axis is turned to it.
        Format::Glb { .. } => Format::Glb {
            up: settings.environment.up,
        },
        format => format,
    };
    io::check_output_dir(output)?;
    io::check_distinct(&[input], &[("output", output)])?;

    let t = Instant::now();
    // The scene as loaded is dropped once prepared (the bake reads the prepared copy).
    let (prepared, load_seconds) = {
        let mut scene = Scene::load(input)?;
        scene.apply_overrides(overrides)?;
        let load_seconds = t.elapsed().as_secs_f64();
        (prepare(&scene, settings), load_seconds)
    };
    let scene = &prepared.scene;

    // What it will cost, before any of it is done: refused if it would not fit in memory,
    // announced if it is long.
    // A time budget: coarser settings where the estimate says these would take longer, and
    // the refinements stop where their share of it is spent.
    // Over several ranks, the solve and the gather are shared among all their threads.
    let threads = rayon::current_num_threads() * comm.size();
    let (mut settings, estimate) = match settings.max_time {
        Some(budget) => {
            let (mut fitted, estimate, chosen) =
                estimate::fit_time_on(scene, settings, threads, budget, comm)?;
            if let Some(chosen) = chosen {
                crate::progress::warning(&format!("{}: {chosen}", input.display()));
            }
            fitted.hierarchical.deadline = Some(t + Duration::from_secs_f64(SOLVE_SHARE * budget));
            fitted.display_deadline = Some(t + Duration::from_secs_f64(DISPLAY_SHARE * budget));
            (fitted, estimate)
        }
        // Over several ranks, every rank takes its share of the pilot (and each refuses a
        // bake that will not fit its own memory).
        None => (
            settings.clone(),
            Estimate::of_on(scene, settings, threads, comm)?,
        ),
    };
    let limit = check_estimate(input, &estimate, settings.max_memory)?;
    // The hierarchy's links are what outgrows an estimate: refinement stops, with a warning,
    // before they would pass the memory limit.
    if let Some(limit) = limit {
        let most = estimate::links_within(limit);
        settings.hierarchical.max_links = settings.hierarchical.max_links.min(most);
    }

    // Every rank's own limit (each may be on a machine of its own): the smallest, so all
    // ranks stop refining at the same pass.
    settings.hierarchical.max_links = comm.min_u64(settings.hierarchical.max_links);

    let mut outcome = solve_prepared_on(&prepared, &settings, comm)?;

    let t = Instant::now();
    let exposure = options
        .exposure
        .unwrap_or_else(|| outcome.baked.auto_exposure());
    if comm.rank() == 0 {
        io::write(output, &outcome.baked, format, exposure)?;
    }
    let report = &mut outcome.report;
    report.exposure = exposure;
    report.input = Some(input.display().to_string());
    report.output = Some(output.display().to_string());
    report.overrides = overrides.iter().map(Override::to_string).collect();
    report.seconds.load = load_seconds;
    report.seconds.write = t.elapsed().as_secs_f64();
    report.estimate = Some(estimate);
    report.stream_warnings();
    report.peak_memory_bytes = report::peak_memory_bytes();
    Ok(outcome)
}

/// True if anything lights the scene: an emitting material, the sky, the sun or a point light.
fn lit(scene: &Scene, settings: &Settings) -> bool {
    scene.has_emitters() || settings.environment.is_lit()
}

/// The share of `--max-time` after which no hierarchical refinement pass starts (the gather
/// and its display come after the solve, and take about as long on large scenes).
pub const SOLVE_SHARE: f64 = 0.45;

/// The share of `--max-time` after which no display refinement level starts (the local fits
/// and the write come after it).
pub const DISPLAY_SHARE: f64 = 0.9;

/// Seconds past which a bake says, before it starts, how long it will take.
pub const LONG_BAKE_SECONDS: f64 = 60.0;

/// Refuses a bake whose estimated memory is more than `max_memory` bytes (`None`: the memory
/// the machine has available, when it can be read), naming what would bring it down; a bake
/// estimated to take longer than [`LONG_BAKE_SECONDS`] says so through
/// [`crate::progress::warning`] before it starts. Returns the memory limit, bytes, if known.
fn check_estimate(
    input: &Path,
    estimate: &Estimate,
    max_memory: Option<f64>,
) -> Result<Option<f64>> {
    let (limit, what) = match max_memory {
        Some(m) => (Some(m), "--max-memory allows"),
        None => (estimate::available_memory(), "is available now"),
    };
    if let Some(limit) = limit {
        if estimate.memory_bytes > limit {
            return Err(crate::Error::setting(
                "max_memory",
                format!(
                    "{}: this bake would need {} ({}), more than the {} that {what}; try {}, \
                     or raise --max-memory",
                    input.display(),
                    estimate::bytes(estimate.memory_bytes),
                    estimate.what(),
                    estimate::bytes(limit),
                    estimate.remedies()
                ),
            ));
        }
        let worst = estimate.memory_bytes * estimate.memory_spread();
        if estimate.method == Method::Hierarchical && worst > limit {
            crate::progress::warning(&format!(
                "{}: this bake should need about {}, but bakes have needed up to {}× such an \
                 estimate ({}), more than the {} that {what}; if it needs more, its \
                 refinement stops at the limit with a coarser solution; for a finer one in this \
                 memory, try {}",
                input.display(),
                estimate::bytes(estimate.memory_bytes),
                estimate.memory_spread(),
                estimate::bytes(worst),
                estimate::bytes(limit),
                estimate.remedies()
            ));
        }
    }
    if estimate.seconds > LONG_BAKE_SECONDS {
        crate::progress::warning(&format!(
            "{}: this bake will take about {} ({}; {}); {} would make it faster",
            input.display(),
            estimate::duration(estimate.seconds),
            estimate.what(),
            estimate::bytes(estimate.memory_bytes),
            estimate.remedies()
        ));
    }
    Ok(limit)
}

/// The scene as the bake sees it: with `orient = auto`, its faces turned and the surfaces
/// seen from both sides given back sides ([`orient::orient`]; not when the scene has twins
/// already or every face gets them); with `two_sided`, every face a back side. The
/// estimate ([`Estimate::of`]) and the bake ([`solve_prepared`]) both start from it, so
/// they count the same faces.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The scene to bake.
    pub scene: Scene,
    /// What `orient = auto` turned and gave back sides; `None` when it did not run.
    pub orientation: Option<orient::Orientation>,
    /// Wall-clock seconds taken.
    pub seconds: f64,
}

/// [`Prepared`]: `scene` made ready for `settings`' bake.
pub fn prepare(scene: &Scene, settings: &Settings) -> Prepared {
    let t = Instant::now();
    let oriented = (settings.orient == Orient::Auto
        && !settings.two_sided
        && scene.twin.is_empty())
    .then(|| {
        let lights: Vec<DVec3> = settings
            .environment
            .lights
            .iter()
            .chain(&scene.lights)
            .map(|l| l.position)
            .collect();
        orient::orient(scene, &lights, settings.form_factors.seed)
    });
    let (mut scene, orientation) = match oriented {
        Some((s, o)) => (s, Some(o)),
        None => (scene.clone(), None),
    };
    if settings.two_sided {
        scene.make_two_sided();
    }
    Prepared {
        scene,
        orientation,
        seconds: t.elapsed().as_secs_f64(),
    }
}

/// patches → BVH → form factors → matrix → solve (→ refine, again) → bake, for a scene in
/// memory: [`prepare`], then [`solve_prepared`].
pub fn solve_scene(scene: &Scene, settings: &Settings) -> Result<Outcome> {
    settings.validate()?;
    solve_prepared(&prepare(scene, settings), settings)
}

/// [`solve_scene`] for a scene [`prepare`] made ready for these `settings`.
pub fn solve_prepared(prepared: &Prepared, settings: &Settings) -> Result<Outcome> {
    solve_prepared_on(prepared, settings, &Solo)
}

/// [`solve_prepared`] as one rank of `comm` (see [`run_on`]).
pub fn solve_prepared_on(
    prepared: &Prepared,
    settings: &Settings,
    comm: &dyn Exchange,
) -> Result<Outcome> {
    settings.validate()?;
    let scene = &prepared.scene;
    let settings = &settings.resolved(scene)?;
    let input_triangles = scene.triangles.len();
    // Contact lines become edges (twins are cut as their fronts are: pairs stay pairs).
    let t = Instant::now();
    let split = settings
        .cuts_contacts()
        .then(|| mesh::split_contacts(scene));
    let scene = split.as_ref().map_or(scene, |(s, _)| s);
    let contact_seconds = t.elapsed().as_secs_f64();
    scene.validate()?;
    let mut report = Report::new(settings);
    report.warnings.extend(scene.warnings.iter().cloned());
    if let Some(o) = &prepared.orientation {
        if o.changed() {
            report.warnings.push(o.summary());
        }
        report.orientation = Some(o.clone());
    }
    report
        .warning_details
        .extend(scene.warning_details.iter().cloned());
    let unlit = crate::scene::reach::unlit_emitters(scene, settings.form_factors.seed);
    if !unlit.is_empty() {
        let n = unlit.len();
        let names =
            crate::scene::listed_names_all("unlit_emitters", &unlit, &mut report.warning_details);
        report.warnings.push(format!(
            "{n} emitting material{} light{} nothing: none of {} rays from the front \
             (counter-clockwise) side of {} faces meets the front of a surface; if {} away \
             from the scene, reverse {} winding or bake with --two-sided: {names}",
            if n == 1 { "" } else { "s" },
            if n == 1 { "s" } else { "" },
            crate::scene::reach::PROBES,
            if n == 1 { "its" } else { "their" },
            if n == 1 { "it faces" } else { "they face" },
            if n == 1 { "its" } else { "their" },
        ));
    }
    report.stream_warnings();
    report.input_triangles = input_triangles;
    report.contacts = split.as_ref().map(|(_, stats)| stats.clone());
    report.seconds.patches = prepared.seconds + contact_seconds;

    if settings.method == Method::Hierarchical {
        return hierarchical_scene(scene, settings, report, comm);
    }
    if comm.size() > 1 {
        report.warnings.push(format!(
            "the matrix method runs whole on each of the {} ranks: only the hierarchical \
             solve is shared among them (--method hierarchical)",
            comm.size()
        ));
    }

    // Patches.
    let t = Instant::now();
    report.max_edge = settings
        .max_edge
        .unwrap_or_else(|| mesh::default_max_edge(scene));
    let mut patches = mesh::subdivide(scene, report.max_edge, settings.crease_degrees)?;
    report.seconds.patches += t.elapsed().as_secs_f64();

    // BVH → form factors → matrix → solve.
    let (mut form_factors, mut solution) =
        light_transport(scene, &patches, settings, None, &mut report)?;

    // Adaptive refinement: split where neighbours' radiance jumps and solve again, within
    // a bound on the patches; pairs of patches a round leaves unchanged keep their form
    // factors.
    let budget = settings
        .refine_max_patches
        .unwrap_or_else(|| refine::default_budget(patches.len()));
    report.refine_budget = budget;
    for _ in 0..settings.refine_rounds {
        let t = Instant::now();
        let jumps = refine::jumps(&patches, &solution.radiance, settings.crease_degrees);
        let Some((marked, refined, capped)) = refine::within_budget(
            scene,
            &patches,
            &jumps,
            settings.refine_threshold,
            settings.crease_degrees,
            budget,
        )?
        else {
            report.refine_capped |= jumps.iter().any(|&j| j > settings.refine_threshold);
            break;
        };
        report.refine_capped |= capped;
        report.refine_rounds += 1;
        crate::progress::note(|| report::refine_note(report.refine_rounds, &marked, &refined));
        report.seconds.patches += t.elapsed().as_secs_f64();
        let reuse = Reuse::between(&form_factors, &settings.form_factors, &patches, &refined);
        (form_factors, solution) =
            light_transport(scene, &refined, settings, reuse.as_ref(), &mut report)?;
        patches = refined;
    }
    report.patches = patches.len();
    report.stream_warnings();

    let baked = bake_stage(
        scene,
        &patches,
        &solution.radiance,
        &form_factors.visible_fraction,
        settings,
        None,
        &mut report,
        comm,
    );
    Ok(Outcome {
        patches,
        visible_fraction: form_factors.visible_fraction.clone(),
        form_factors: Some(form_factors),
        solution,
        baked,
        report,
    })
}

/// patches → hierarchies → links ⇄ solve → leaves → bake: [`solve_scene`] for
/// `method = hierarchical`. The root patches are the scene's triangles, split to `max_edge`
/// only when one is given.
fn hierarchical_scene(
    scene: &Scene,
    settings: &Settings,
    mut report: Report,
    comm: &dyn Exchange,
) -> Result<Outcome> {
    let t = Instant::now();
    report.max_edge = settings.max_edge.unwrap_or_else(|| {
        let (lo, hi) = scene.bounds();
        (hi - lo).length()
    });
    let roots = mesh::subdivide(scene, report.max_edge, settings.crease_degrees)?;
    report.seconds.patches += t.elapsed().as_secs_f64();

    let t = Instant::now();
    let h = hierarchical::solve_on(
        &roots,
        &settings.hierarchical,
        &settings.environment,
        &settings.solver,
        settings.form_factors.seed,
        comm,
    )?;
    if !lit(scene, settings) {
        report.warn_no_emitters();
    }
    report.warnings.extend(h.warnings);
    report.stream_warnings();
    report.seconds.solve = t.elapsed().as_secs_f64();
    report.patches = h.patches.len();
    report.iterations = h.solution.iterations;
    report.residual = h.solution.residual;
    report.converged = h.solution.converged;
    report.form_factors.rays_cast = h.stats.rays_cast;
    report.worst_row = h.worst_row.map(|w| report::WorstRow {
        sum: w.sum,
        patch: w.root,
        material: scene.materials[roots.material[w.root] as usize]
            .name
            .clone(),
        centroid: w.centroid.to_array(),
    });
    crate::progress::note(|| report::hierarchical_note(&h.stats, &h.solution));
    report.hierarchical = Some(h.stats);
    // The roots are the solve's; the display and its gather read the leaves.
    drop(roots);

    // The display's faces cut along the contact lines, for the gather at their vertices.
    let t = Instant::now();
    let display = display_contacts(
        scene,
        &h.patches,
        &h.radiance,
        &h.visible_fraction,
        settings,
    );
    report.seconds.patches += t.elapsed().as_secs_f64();
    let baked = match display {
        Some(cut) => {
            report.display_contacts = Some(cut.stats);
            report.lamp_lines = cut.lamp_lines;
            report.sun_lines = cut.sun_lines;
            bake_stage(
                scene,
                &cut.patches,
                &cut.radiance,
                &cut.visible_fraction,
                settings,
                Some(cut.uncut_vertices),
                &mut report,
                comm,
            )
        }
        None => bake_stage(
            scene,
            &h.patches,
            &h.radiance,
            &h.visible_fraction,
            settings,
            None,
            &mut report,
            comm,
        ),
    };
    Ok(Outcome {
        patches: h.patches,
        visible_fraction: h.visible_fraction,
        form_factors: None,
        solution: h.solution,
        baked,
        report,
    })
}

/// The gather that runs on an output of `vertices` vertices: `settings.gather` resolved
/// ([`Gather::resolve`]), or none when nothing lights the scene or the solve is a Neumann
/// series (a chosen number of bounces: gathering on it would add one, so its vertices show
/// the patches' own N-bounce radiance).
fn gather_mode(scene: &Scene, settings: &Settings, vertices: usize) -> Gather {
    let neumann = settings.solver.method == solve::Method::Neumann;
    if !lit(scene, settings) || neumann {
        return Gather::None;
    }
    settings
        .gather
        .resolve(vertices, settings.gather_rays.is_some())
}

/// The hierarchical solution's output patches cut along the scene's contact lines
/// ([`mesh::split_patches`]) and the lamps' and the sun's penumbra lines
/// ([`mesh::display_lines_on`]); `None` unless `discontinuities = auto`, the scene has such lines and a
/// gather runs on the cut output (its pieces would otherwise only show their leaves' values).
fn display_contacts(
    scene: &Scene,
    patches: &Patches,
    radiance: &[crate::Rgb],
    visible_fraction: &[f64],
    settings: &Settings,
) -> Option<CutDisplay> {
    let crease = settings.crease_degrees;
    let uncut_vertices = bake::bake_sites(patches, radiance, crease).1.len();
    if settings.discontinuities != mesh::Discontinuities::Auto
        || gather_mode(scene, settings, uncut_vertices) == Gather::None
    {
        return None;
    }
    let lines = mesh::display_lines_on(scene, sun_disc(&settings.environment), &|_| true)?;
    let (lo, hi) = scene.bounds();
    let mesh::Split {
        patches: cut,
        parent,
        region,
        stats,
    } = mesh::split_patches(&lines.lines, patches, (hi - lo).length())?;
    let cut_radiance: Vec<crate::Rgb> = parent.iter().map(|&i| radiance[i as usize]).collect();
    // Each piece of a cut leaf takes its own share of the leaf's reflected light.
    let cut_radiance = gather::Gatherer::new(
        scene,
        &cut,
        &cut_radiance,
        &settings.environment,
        settings.form_factors.seed,
    )
    .piece_shares(&parent, &region, gather::pieces::PIECE_RAYS);
    let cut_visible = parent
        .iter()
        .map(|&i| visible_fraction[i as usize])
        .collect();
    Some(CutDisplay {
        patches: cut,
        radiance: cut_radiance,
        visible_fraction: cut_visible,
        stats,
        uncut_vertices,
        lamp_lines: lines.lamp,
        sun_lines: lines.sun,
    })
}

/// The sun's unit direction (toward it) and angular radius (radians,
/// [`crate::light::outside::SUN_DIAMETER_DEGREES`] / 2), if there is a sun: what its
/// penumbra lines are drawn from ([`mesh::display_lines_on`]).
fn sun_disc(environment: &crate::scene::Environment) -> Option<(DVec3, f64)> {
    let radius = (0.5 * crate::light::outside::SUN_DIAMETER_DEGREES).to_radians();
    environment.sun_direction().map(|s| (s, radius))
}

/// The hierarchical display cut along its discontinuity lines ([`display_contacts`]): the
/// pieces, each with its leaf's radiance (W·sr⁻¹·m⁻²) and visible fraction, what the cut did,
/// and the lamps' and the sun's lines it took.
struct CutDisplay {
    patches: Patches,
    radiance: Vec<crate::Rgb>,
    visible_fraction: Vec<f64>,
    stats: mesh::ContactStats,
    /// The output's vertices before the cut: what `gather = auto` decides on.
    uncut_vertices: usize,
    lamp_lines: usize,
    sun_lines: usize,
}

/// Bake: patch radiance → the output mesh's vertices (→ final gather at them, unless
/// `gather = none`), with the scene's camera and the environment's sky (for pictures); fills the
/// report's vertex count and bake and gather seconds. The gather is chosen for
/// `mode_vertices` output vertices where given (the hierarchical display's before its
/// discontinuity lines cut it: the lines add vertices along shadows, not a finer display whose
/// cost `auto` bounds), else for the output's own.
#[allow(clippy::too_many_arguments)]
fn bake_stage(
    scene: &Scene,
    patches: &Patches,
    radiance: &[crate::Rgb],
    visible_fraction: &[f64],
    settings: &Settings,
    mode_vertices: Option<usize>,
    report: &mut Report,
    comm: &dyn Exchange,
) -> BakedMesh {
    let t = Instant::now();
    let (mut baked, mut sites) = bake::bake_sites(patches, radiance, settings.crease_degrees);
    report.vertices = baked.positions.len();
    report.seconds.bake = t.elapsed().as_secs_f64();
    let mode = gather_mode(scene, settings, mode_vertices.unwrap_or(sites.len()));
    report.gather = mode;
    if mode != Gather::None {
        let t = Instant::now();
        let gatherer = gather::Gatherer::new(
            scene,
            patches,
            radiance,
            &settings.environment,
            settings.form_factors.seed,
        );
        // Patches under a face close in front of them show their own light, not the open
        // side's, and buried ones (flush under another surface) nobody sees: the vertices of
        // both are apart from the seen ones' at the outline.
        let covers = gatherer.covers(scene);
        let buried = gatherer.buried_patches();
        if covers.iter().any(|&g| g > 0.0) || buried.iter().any(|&b| b) {
            (baked, sites) = bake::bake_sites_apart(
                patches,
                radiance,
                settings.crease_degrees,
                &covers,
                &buried,
            );
        }
        let gatherer = gatherer
            // The nudge bound needs the display refinement to follow the light beside a contact.
            .with_contact_edges(report.contacts.is_some() && settings.gather_tolerance > 0.0)
            .with_cache(mode == Gather::Cache)
            .with_covers(covers)
            .with_comm(comm);
        // A display refinement vertex of the `cache` gather gathers in full, with the rays a
        // `full` gather of the output would give each vertex.
        let rays = settings.gather_rays.map_or_else(
            || gather::auto_rays(sites.len(), settings.finer(scene)),
            |r| r as usize,
        );
        let (values, cache) = gather::gather(
            &gatherer,
            &sites,
            &baked.vertex_radiance,
            mode,
            rays,
            settings.gather_rays.map(|r| r as usize),
            visible_fraction,
        );
        let plan = gather::Plan {
            mode,
            rays,
            tolerance: settings.gather_tolerance,
            budget: gather::refine::scaled(
                gather::refine::budget_for(
                    mode,
                    rays,
                    gatherer.direct_cost_per_point(),
                    sites.len(),
                ),
                settings.display_budget,
            ),
            deadline: settings.display_deadline,
        };
        let refined = gather::refine(
            &gatherer,
            &mut baked,
            sites,
            values,
            &plan,
            cache.as_ref(),
            visible_fraction,
        );
        report.vertices = baked.positions.len();
        if refined.out_of_time {
            report.warnings.push(format!(
                "the display refinement stopped after {} of its levels, {} new vertices of \
                 the {} it could add: its share of the time budget (--max-time) was spent",
                refined.levels, refined.vertices, plan.budget
            ));
        }
        report.display_refinement = refined;
        report.gather_cache = cache.map(|c| c.stats);
        report.seconds.gather = t.elapsed().as_secs_f64();
    }
    baked.camera = scene.camera;
    baked.sky = settings.environment.sky();
    // Values of rounding size below 0 (a fit's or a mean's sums that are 0 in exact
    // arithmetic) are shown as 0, not taken for a broken bake.
    baked.clamp_rounding();
    baked
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
    let form_factors = if lit(scene, settings) {
        form_factors(patches, settings, reuse, report)?
    } else {
        // Without emitters L = 0 whatever F is: skip the BVH and the form factors.
        report.warn_no_emitters();
        FormFactors::empty(patches.len())
    };
    report.form_factors = form_factors.stats.clone();
    if !patches.is_empty() && form_factors.stats.nnz > 0 {
        // Said before the solve, once (the first round that finds such a row).
        let worst = report::WorstRow::of(scene, patches, &form_factors.stats);
        let said = report
            .worst_row
            .as_ref()
            .is_some_and(|w| w.sum > form_factor::ROW_SUM_LIMIT);
        if worst.sum > form_factor::ROW_SUM_LIMIT && !said {
            let [x, y, z] = worst.centroid;
            let capped = match form_factors.stats.rows_capped {
                0 => String::new(),
                n => format!(
                    ". The {n} rows past {} were scaled to sum to 1",
                    form_factor::row_sum_limit(settings.form_factors.estimator)
                ),
            };
            report.warnings.push(format!(
                "the form factors of patch {} (material '{}', at {x:.4}, {y:.4}, {z:.4}) sum \
                 to {:.3}: more than 1, so light would be created there; coincident or \
                 intersecting faces near it are the usual cause{capped}",
                worst.patch, worst.material, worst.sum
            ));
            report.stream_warnings();
        }
        report.worst_row = Some(worst);
    }

    let t = Instant::now();
    // E = Le + ρ·D_env: the sky's and the sun's direct light at each patch counts as emitted.
    let env = &settings.environment;
    let emission: Vec<crate::Rgb> = if env.is_lit() {
        let d = crate::light::patch_light(patches, env, settings.form_factors.seed);
        (0..patches.len())
            .map(|i| {
                let (le, rho) = (patches.emission[i], patches.reflectance[i]);
                [0, 1, 2].map(|c| le[c] + rho[c] * d[i][c])
            })
            .collect()
    } else {
        patches.emission.clone()
    };
    let system = System {
        form_factors: &form_factors,
        reflectance: &patches.reflectance,
        emission: &emission,
    };
    let solution = solve::solve(&system, &settings.solver)?;
    crate::progress::note(|| report::solve_note(patches.len(), &form_factors.stats, &solution));
    report.iterations = solution.iterations;
    report.omega = solution.omega;
    report.residual = solution.residual;
    report.converged = solution.converged;
    report.seconds.solve += t.elapsed().as_secs_f64();
    report.stream_warnings();
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
    let visibility = Visibility::build(&corners).with_transmittance(&patches.transmittance());
    let bvh_seconds = t.elapsed().as_secs_f64();
    report.seconds.bvh += bvh_seconds;

    let t = Instant::now();
    // A cached F must serve any materials: compute every entry then.
    let needed = if settings.form_factors.shortcuts.skip_unneeded
        && key.is_none()
        && !settings.environment.is_lit()
    {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::TestDir;
    use crate::validation::scenes;

    const DEFAULT_CREASE: f64 = mesh::DEFAULT_CREASE_DEGREES;
    use crate::Error;

    /// The name of a setting error, or a panic.
    fn setting_name(e: Error) -> String {
        match e {
            Error::Setting { name, .. } => name,
            other => panic!("expected a setting error, got {other:?}"),
        }
    }

    #[test]
    fn settings_and_output_are_checked_before_any_work() {
        let dir = TestDir::new("pipeline-checks");
        // The input does not exist: any error but a setting's would mean it was read first.
        let missing = dir.path().join("missing.obj");
        let out = dir.path().join("out.ply");
        let options = WriteOptions::default();
        let bad = Settings {
            max_edge: Some(-1.0),
            ..Settings::default()
        };
        let e = run(&missing, &out, &bad, &options).unwrap_err();
        assert_eq!(setting_name(e), "max_edge");
        let dark = WriteOptions {
            exposure: Some(0.0),
            ..options
        };
        let e = run(&missing, &out, &Settings::default(), &dark).unwrap_err();
        assert_eq!(setting_name(e), "exposure");
        let stl = dir.path().join("out.stl");
        let e = run(&missing, &stl, &Settings::default(), &options).unwrap_err();
        assert_eq!(setting_name(e), "output");
        // And only then the input.
        let e = run(&missing, &out, &Settings::default(), &options).unwrap_err();
        assert!(matches!(e, Error::Io { .. }), "{e:?}");
        assert!(
            dir.entries().is_empty(),
            "nothing written: {:?}",
            dir.entries()
        );
        // solve_scene checks the same settings.
        let scene = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        let e = solve_scene(
            &scene,
            &Settings {
                crease_degrees: 200.0,
                ..Settings::default()
            },
        );
        assert_eq!(setting_name(e.err().unwrap()), "crease_degrees");
    }

    #[test]
    fn the_report_counts_what_the_stages_made() {
        let scene = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        let settings = Settings {
            max_edge: Some(0.25),
            refine_rounds: 1,
            refine_threshold: 0.05,
            ..Settings::default()
        };
        let uniform = mesh::subdivide(&scene, 0.25, settings.crease_degrees).unwrap();
        let out = solve_scene(&scene, &settings).unwrap();
        let r = &out.report;
        assert_eq!(r.input_triangles, scene.triangles.len());
        assert_eq!(r.max_edge, 0.25);
        // The receiver's radiance falls off towards its edges by far more than 5 %: one round
        // of refinement splits patches, and the report describes the refined mesh.
        assert_eq!(r.refine_rounds, 1);
        assert!(out.patches.len() > uniform.len());
        assert_eq!(r.patches, out.patches.len());
        assert_eq!(r.vertices, out.baked.positions.len());
        assert_eq!(out.baked.faces.len(), out.patches.len());
        assert_eq!(
            r.form_factors.nnz,
            out.form_factors.as_ref().unwrap().matrix.nnz() as u64
        );
        assert_eq!(r.iterations, out.solution.iterations);
        assert_eq!((r.residual, r.converged), (out.solution.residual, true));
        assert!(
            r.form_factors.pairs_reused > 0,
            "unchanged pairs kept their entries"
        );
        let s = &r.seconds;
        assert!([s.patches, s.bvh, s.form_factors, s.solve, s.bake]
            .iter()
            .all(|&x| x >= 0.0));
        assert!(r
            .summary()
            .starts_with(&format!("{} patches, {} vertices", r.patches, r.vertices)));
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    }

    /// A `max_edge` finer than the scene's default asks for a finer answer: ε is divided by
    /// how much smaller the patches are by area, and the gather's budget multiplied, so that a
    /// vertex keeps the rays it gets at the default size; coarser or absent changes nothing,
    /// and the factor stops at MAX_FINER.
    #[test]
    fn a_finer_max_edge_asks_for_a_finer_answer() {
        let scene = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        let default = mesh::default_max_edge(&scene);
        let with = |max_edge| Settings {
            max_edge,
            ..Settings::default()
        };
        assert_eq!(with(None).finer(&scene), 1.0);
        assert_eq!(with(Some(2.0 * default)).finer(&scene), 1.0);
        let half = with(Some(0.5 * default));
        assert!((half.finer(&scene) - 4.0).abs() < 1e-12);
        assert_eq!(with(Some(0.01 * default)).finer(&scene), MAX_FINER);
        let epsilon = Settings::default().hierarchical.epsilon;
        let resolved = half.resolved(&scene).unwrap().hierarchical.epsilon;
        assert!(
            (resolved - epsilon / 4.0).abs() < 1e-12 * epsilon,
            "{resolved}"
        );
        assert_eq!(
            with(None).resolved(&scene).unwrap().hierarchical.epsilon,
            epsilon
        );
        // Four times the vertices at a quarter of the area: the same rays each, within the
        // bounds; the bounds hold.
        for vertices in [500, 4_000, 20_000] {
            assert_eq!(
                gather::auto_rays(4 * vertices, 4.0),
                gather::auto_rays(vertices, 1.0)
            );
        }
        assert_eq!(gather::auto_rays(1, 25.0), 1024);
        assert_eq!(gather::auto_rays(10_000_000, 1.0), gather::MIN_AUTO_RAYS);
    }

    #[test]
    fn refinement_never_passes_its_budget() {
        // The receiver's fall-off asks for a split at every round at a 1 % threshold: five
        // rounds would multiply the patches many times over. Each budget bounds them, the
        // report says when marks were left out, and a budget equal to the initial patches
        // allows no round at all.
        let scene = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        let initial = mesh::subdivide(&scene, 0.25, DEFAULT_CREASE).unwrap().len();
        for budget in [initial, initial + 7, 2 * initial, 5 * initial] {
            let settings = Settings {
                max_edge: Some(0.25),
                refine_rounds: 5,
                refine_threshold: 0.01,
                refine_max_patches: Some(budget),
                gather: Gather::None,
                ..Settings::default()
            };
            let r = solve_scene(&scene, &settings).unwrap().report;
            assert_eq!(r.refine_budget, budget);
            assert!(r.patches <= budget, "{} patches > {budget}", r.patches);
            assert!(r.refine_capped, "budget {budget}: marks were left out");
            if budget == initial {
                assert_eq!((r.refine_rounds, r.patches), (0, initial));
            } else {
                assert!(r.patches > initial && r.refine_rounds >= 1);
            }
        }
        // The default budget: twice the initial patches, at most 12,000.
        assert_eq!(refine::default_budget(4004), 8008);
        assert_eq!(refine::default_budget(9000), refine::REFINE_MAX_PATCHES);
        assert_eq!(refine::default_budget(20_000), 20_000);
    }

    #[test]
    fn a_row_above_one_is_named_with_its_patch() {
        // A flat open box (1 × 1 × 0.3, its y = 0 side open) lit by its ceiling, with a second
        // floor on the first, split along the other diagonal (so not a duplicate face, and
        // kept): the ceiling sees the floor twice, its rows sum to about 1.5, and the run says
        // so before the solve, naming a ceiling patch, and scales those rows to 1. Without the
        // second floor nothing is said.
        let build = |second_floor: bool| {
            let mut b = crate::scene::SceneBuilder::new();
            let white = b.material("white", [0.5; 3], [0.0; 3]);
            let light = b.material("light", [0.5; 3], [1.0; 3]);
            let h = 0.3;
            let p = |x: f64, y: f64, z: f64| glam::DVec3::new(x, y, z);
            b.quad(
                [p(0., 0., 0.), p(1., 0., 0.), p(1., 1., 0.), p(0., 1., 0.)],
                white,
            );
            b.quad(
                [p(0., 0., h), p(0., 1., h), p(1., 1., h), p(1., 0., h)],
                light,
            );
            b.quad(
                [p(0., 0., 0.), p(0., 1., 0.), p(0., 1., h), p(0., 0., h)],
                white,
            );
            b.quad(
                [p(1., 0., 0.), p(1., 0., h), p(1., 1., h), p(1., 1., 0.)],
                white,
            );
            b.quad(
                [p(0., 1., 0.), p(1., 1., 0.), p(1., 1., h), p(0., 1., h)],
                white,
            );
            if second_floor {
                b.quad(
                    [p(1., 0., 0.), p(1., 1., 0.), p(0., 1., 0.), p(0., 0., 0.)],
                    white,
                );
            }
            b.build().unwrap()
        };
        // The winding as built: orientation repair would turn the second floor over.
        let settings = Settings {
            max_edge: Some(0.25),
            refine_rounds: 0,
            gather: Gather::None,
            orient: crate::scene::orient::Orient::Keep,
            ..Settings::default()
        };
        let r = solve_scene(&build(false), &settings).unwrap().report;
        let worst = r.worst_row.unwrap();
        assert!(worst.sum <= form_factor::ROW_SUM_LIMIT, "{worst:?}");
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        let out = solve_scene(&build(true), &settings).unwrap();
        let r = out.report;
        let worst = r.worst_row.unwrap();
        assert!(worst.sum > 1.3 && worst.material == "light", "{worst:?}");
        assert!((worst.centroid[2] - 0.3).abs() < 1e-12, "on the ceiling");
        let said = r
            .warnings
            .iter()
            .find(|w| w.contains("form factors of patch"))
            .expect("the row is named");
        assert!(said.contains(&format!("patch {}", worst.patch)), "{said}");
        // The rows past the limit were scaled to 1 before the solve: no light is created.
        let capped = r.form_factors.rows_capped;
        assert!(
            capped > 0 && said.contains(&format!("The {capped} rows")),
            "{said}"
        );
        let sums = out.form_factors.unwrap().row_sums();
        let max = sums.iter().copied().fold(0.0, f64::max);
        assert!(max <= form_factor::ROW_SUM_LIMIT, "largest row sum {max}");
    }

    #[test]
    fn the_report_holds_every_item_of_a_list_warning() {
        // 50 overlapping quads in one plane: thousands of pairs of coincident faces.
        let mut b = crate::scene::SceneBuilder::new();
        let m = b.material("grey", [0.5; 3], [0.0; 3]);
        for i in 0..50 {
            let x = 0.01 * i as f64;
            b.quad(
                [
                    glam::DVec3::new(x, 0.0, 0.0),
                    glam::DVec3::new(x + 1.0, 0.0, 0.0),
                    glam::DVec3::new(x + 1.0, 1.0, 0.0),
                    glam::DVec3::new(x, 1.0, 0.0),
                ],
                m,
            );
        }
        let scene = b.build().unwrap();
        let pairs = crate::scene::checks::coincident_faces(&scene.positions, &scene.triangles, 2.0);
        let settings = Settings {
            method: Method::Matrix,
            ..Settings::default()
        };
        let r = solve_scene(&scene, &settings).unwrap().report;
        let line = r
            .warnings
            .iter()
            .find(|w| w.contains("coincident overlapping faces"))
            .unwrap();
        assert!(line.starts_with(&pairs.len().to_string()), "{line}");
        assert!(line.chars().count() < 400, "{line}");
        let json = serde_json::to_value(&r).unwrap();
        let details = json["warning_details"].as_array().unwrap();
        let z = details.iter().find(|d| d["kind"] == "z_fighting").unwrap();
        assert_eq!(z["count"], pairs.len());
        let items = z["items"].as_array().unwrap();
        assert_eq!(items.len(), pairs.len());
        let (i, j) = pairs[pairs.len() - 1];
        assert_eq!(items[pairs.len() - 1], format!("triangles {i} and {j}"));
    }

    #[test]
    fn a_hierarchical_report_names_its_worst_row() {
        // A closed room: every leaf's row sums to about 1. The hierarchy's rows are found
        // with a few rays per link and a 7-point rule, before a closed root's are normalised:
        // its worst leaf here sums to about 1.37.
        let scene = scenes::furnace_room(0.5, 1.0).unwrap();
        let settings = Settings {
            method: Method::Hierarchical,
            gather: Gather::None,
            ..Settings::default()
        };
        let out = solve_scene(&scene, &settings).unwrap();
        let w = out.report.worst_row.expect("a worst row");
        assert!(w.sum > 0.9 && w.sum < 1.5, "worst row sum {}", w.sum);
        assert!(w.patch < scene.triangles.len(), "root {}", w.patch);
        let (lo, hi) = scene.bounds();
        let c = glam::DVec3::from_array(w.centroid);
        assert!(c.cmpge(lo).all() && c.cmple(hi).all(), "{c}");
        assert_eq!(w.material, scene.materials[0].name);
    }

    #[test]
    fn auto_counts_the_patches_after_the_contact_lines_are_cut() {
        let scene = Scene::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/cornell_box.obj"),
        )
        .unwrap();
        let count =
            |scene: &Scene, e: f64| mesh::subdivide(scene, e, DEFAULT_CREASE).unwrap().len();
        let cut = mesh::split_contacts(&scene).0;
        // A patch size at which the scene alone cuts into few enough patches for the matrix,
        // but not once its contact lines are cut too.
        let crossing = (0..160)
            .map(|k| 60.0 - 0.25 * k as f64)
            .find(|&e| {
                count(&scene, e) <= AUTO_MATRIX_MAX_PATCHES
                    && count(&cut, e) > AUTO_MATRIX_MAX_PATCHES
            })
            .expect("a max_edge between the two counts");
        for (e, method) in [
            (Some(crossing), Method::Hierarchical),
            (None, Method::Matrix),
        ] {
            let settings = Settings {
                max_edge: e,
                ..Settings::default()
            };
            assert_eq!(
                settings.resolved(&scene).unwrap().method,
                method,
                "max_edge {e:?}"
            );
        }
    }

    #[test]
    fn a_scene_without_emitters_is_black_with_one_warning() {
        let scene = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 0.0).unwrap();
        let out = solve_scene(
            &scene,
            &Settings {
                max_edge: Some(0.5),
                ..Settings::default()
            },
        )
        .unwrap();
        assert!(out.solution.radiance.iter().flatten().all(|&l| l == 0.0));
        assert_eq!(out.report.warnings.len(), 1, "{:?}", out.report.warnings);
        assert!(out.report.warnings[0].contains("no emitters"));
        assert_eq!(
            out.report.form_factors.rays_cast, 0,
            "no form factors computed"
        );
    }

    #[test]
    fn run_writes_the_bake_and_fills_the_report() {
        let dir = TestDir::new("pipeline-run");
        let input = dir.path().join("plates.obj");
        let scene = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        io::obj::save(&scene, &input).unwrap();
        let output = dir.path().join("lit.ply");
        let settings = Settings {
            max_edge: Some(0.5),
            ..Settings::default()
        };
        let overrides = [Override::parse(crate::scene::Property::Emission, "source=2").unwrap()];
        let out = run_with(
            &input,
            &output,
            &settings,
            &WriteOptions::default(),
            &overrides,
        )
        .unwrap();
        let r = &out.report;
        assert_eq!(
            r.input.as_deref(),
            Some(input.display().to_string().as_str())
        );
        assert_eq!(
            r.output.as_deref(),
            Some(output.display().to_string().as_str())
        );
        assert_eq!(r.overrides, ["emission source=2,2,2"]);
        assert_eq!(r.exposure, out.baked.auto_exposure());
        let back = io::ply::read(&output).unwrap();
        // One face per patch, and more where the display refinement split them.
        assert_eq!(back.faces.len(), out.baked.faces.len());
        assert!(back.faces.len() >= r.patches);
        assert_eq!(out.baked.positions.len(), r.vertices);
        // The override doubled the source's Le.
        let le = out
            .patches
            .emission
            .iter()
            .map(|e| e[0])
            .fold(0.0, f64::max);
        assert_eq!(le, 2.0);
    }
}
