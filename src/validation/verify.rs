//! `radiosity verify`: the built-in analytic suite. Each case builds a scene with a known answer
//! ([`crate::validation::scenes`]), runs the same pipeline as a bake, and compares with the closed
//! form ([`crate::validation::closed_forms`]). This module owns the cases and their tolerances;
//! each tolerance says why that much error is expected at that resolution.

use std::time::Instant;

use serde::Serialize;

use super::{closed_forms, scenes};
use crate::color::Rgb;
use crate::mesh::Patches;
use crate::pipeline::{self, Outcome};
use crate::scene::Scene;
use crate::{form_factor, hierarchical, solve, Result};

/// One row of the verification table.
#[derive(Debug, Clone, Serialize)]
pub struct Case {
    pub name: String,
    /// The closed-form value.
    pub expected: f64,
    /// What the solver got (a mean over the patches the case checks).
    pub got: f64,
    /// The case's error measure (each case documents its own): the area-weighted mean of the
    /// per-patch relative errors (sphere), the largest per-patch relative error (furnace), or
    /// the relative error of an aggregated form factor (plates).
    pub relative_error: f64,
    pub tolerance: f64,
    pub seconds: f64,
    pub pass: bool,
}

/// Settings of the suite: which estimator and solver to exercise.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// Matrix or hierarchical.
    pub method: pipeline::Method,
    /// The hierarchical solver's settings (method hierarchical).
    pub hierarchical: hierarchical::Settings,
    pub form_factors: form_factor::Settings,
    /// Solver for the all-bounce cases (the one-bounce case always uses the Neumann series).
    pub solver: solve::Method,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            method: pipeline::Method::Matrix,
            hierarchical: hierarchical::Settings::default(),
            form_factors: form_factor::Settings::default(),
            solver: solve::Method::GaussSeidel,
        }
    }
}

fn run_case(
    scene: &Scene,
    max_edge: f64,
    settings: &Settings,
    method: solve::Method,
    bounces: u32,
) -> Result<Outcome> {
    let pipeline_settings = pipeline::Settings {
        method: settings.method,
        hierarchical: settings.hierarchical,
        max_edge: Some(max_edge),
        form_factors: settings.form_factors,
        solver: solve::Settings {
            method,
            tolerance: 1e-9,
            max_iterations: 10_000,
            bounces,
            ..solve::Settings::default()
        },
        ..pipeline::Settings::default()
    };
    pipeline::solve_scene(scene, &pipeline_settings)
}

/// Bounces N for which the Neumann series' tail Σ_{b>N} ρ^b = ρ^{N+1}/(1 − ρ) (an upper bound of
/// the omitted light relative to Le when row sums ≤ 1) is below 1e-10: the series then stands
/// in for the full solution.
pub fn bounces_for_all(rho: f64) -> u32 {
    ((1e-10 * (1.0 - rho)).ln() / rho.ln()).ceil().max(1.0) as u32
}

fn case(name: &str, expected: f64, got: f64, err: f64, tol: f64, t: Instant) -> Case {
    Case {
        name: name.to_string(),
        expected,
        got,
        relative_error: err,
        tolerance: tol,
        seconds: t.elapsed().as_secs_f64(),
        pass: err <= tol,
    }
}

/// How far a solution inside an integrating sphere is from the closed form, over the wall
/// (non-emitting) patches; channel 0.
#[derive(Debug, Clone, Copy)]
pub struct SphereErrors {
    /// The closed form [`closed_forms::sphere_wall_radiance`], with the tessellation's own
    /// area-weighted mean Le.
    pub expected: f64,
    /// Area-weighted mean wall radiance.
    pub mean: f64,
    /// Area-weighted mean of the walls' per-patch relative errors (the accuracy target's
    /// measure, BENCHMARKS.md "Accuracy against closed forms").
    pub mean_patch_relative: f64,
    /// Relative error of the mean wall radiance.
    pub relative_of_mean: f64,
}

/// [`SphereErrors`] of `radiance` on sphere `patches` of uniform reflectance `rho`, after
/// `bounces` bounces (`None`: all).
pub fn sphere_wall_errors(
    patches: &Patches,
    radiance: &[Rgb],
    rho: f64,
    bounces: Option<u32>,
) -> SphereErrors {
    let p = patches;
    let area_mean = |which: &mut dyn Iterator<Item = usize>, f: &dyn Fn(usize) -> f64| {
        let (num, den) = which.fold((0.0, 0.0), |(n, d), i| {
            (n + p.area[i] * f(i), d + p.area[i])
        });
        num / den
    };
    let mean_le = area_mean(&mut (0..p.len()), &|i| p.emission[i][0]);
    let expected = closed_forms::sphere_wall_radiance(rho, mean_le, bounces);
    let walls = || (0..p.len()).filter(|&i| p.emission[i][0] == 0.0);
    let mean = area_mean(&mut walls(), &|i| radiance[i][0]);
    SphereErrors {
        expected,
        mean,
        mean_patch_relative: area_mean(&mut walls(), &|i| {
            (radiance[i][0] - expected).abs() / expected
        }),
        relative_of_mean: (mean - expected).abs() / expected,
    }
}

/// Integrating sphere, radius 1, 1280-face geodesic (level 3), 30° emitting cap Le = 1,
/// ρ = 0.5. `got` is the area-weighted mean radiance of the wall (non-emitting) patches; the
/// error is the area-weighted mean of the walls' per-patch relative errors, against the
/// closed form evaluated with the tessellation's own area-weighted mean Le
/// ([`sphere_wall_errors`]).
///
/// Tolerance: a 1280-face polyhedron is not a sphere. The receiving cosine uses the normal
/// interpolated from the exact vertex normals ([`crate::mesh::corner_normals`]), so what is
/// left is second order in the facet size: sample points lie up to h²/8R inside the sphere and
/// the cap's outline is made of chords. Measured 1.6e-3 one bounce and 8e-4 all bounces with
/// the contour estimator (1.5e-3 / 7.7e-4 area), falling 4× per level (4.0e-4 at level 4).
/// 3e-3 leaves 2× margin, and fails for any physics error (a wrong cosine, a missing bounce
/// or π is ≥ 30 %) and for flat facet normals (their first-order error is 4.9e-3 here).
pub fn integrating_sphere(settings: &Settings, bounces: Option<u32>) -> Result<Case> {
    let t = Instant::now();
    let rho = 0.5;
    let scene = scenes::integrating_sphere(1.0, 3, 30.0, rho, [1.0; 3])?;
    let (method, n) = match bounces {
        Some(n) => (solve::Method::Neumann, n),
        None => (settings.solver, bounces_for_all(rho)),
    };
    // max-edge above the facets' edge length (≈ 0.16): the facets are the patches.
    let out = run_case(&scene, 0.5, settings, method, n)?;
    let e = sphere_wall_errors(&out.patches, &out.solution.radiance, rho, bounces);
    let name = match bounces {
        Some(1) => "integrating sphere, one bounce".to_string(),
        Some(n) => format!("integrating sphere, {n} bounces"),
        None => format!(
            "integrating sphere, all bounces ({})",
            settings.solver.name()
        ),
    };
    // Hemisphere shooting adds Monte Carlo noise: a wall patch's one-bounce value is ρ·Le times
    // the fraction of its N rays that hit the cap (probability f = mean(Le)/Le), a binomial
    // with relative standard deviation σ = √((1 − f)/(f N)); the mean of |error| over ~1200
    // patches is ≈ 0.8σ with negligible spread, so σ is added to the geometric bound.
    let mean_le = e.expected / closed_forms::sphere_wall_radiance(rho, 1.0, bounces);
    let noise = hemisphere_sigma(settings, mean_le, 1);
    Ok(case(
        &name,
        e.expected,
        e.mean,
        e.mean_patch_relative,
        3e-3 + noise,
        t,
    ))
}

/// Furnace: closed non-convex room (two boxes inside), ρ = 0.5, Le = 1 everywhere: every patch
/// must have L = Le/(1 − ρ) = 2.
///
/// Tolerance: with exact row sums the answer is exact. Every estimator's rows sum to 1 here:
/// hemisphere shooting by construction, the pair estimators because closure probes find the
/// room closed and the rows are normalised ([`crate::form_factor::compute`]). What is left is
/// the f32 storage of F (≈ 6e-8 per entry) times 1/(1 − ρ) = 2 and the solver's 1e-9
/// tolerance: measured 9e-9. 1e-5 leaves margin for that and fails if light leaks anywhere
/// (one escaping probe disables the normalisation: the contour estimator's raw rows err by
/// ~4e-3 next to the boxes).
pub fn furnace(settings: &Settings) -> Result<Case> {
    let t = Instant::now();
    let (rho, le) = (0.5, 1.0);
    let scene = scenes::furnace_room(rho, le)?;
    let out = run_case(&scene, 0.1, settings, settings.solver, bounces_for_all(rho))?;
    let expected = closed_forms::furnace_radiance(rho, le);
    let l = &out.solution.radiance;
    let p = &out.patches;
    let got = (0..p.len()).map(|i| p.area[i] * l[i][0]).sum::<f64>() / p.total_area();
    let err = l
        .iter()
        .map(|x| (x[0] - expected).abs() / expected)
        .fold(0.0, f64::max);
    Ok(case(
        &format!("furnace room, ρ = 0.5 ({})", settings.solver.name()),
        expected,
        got,
        err,
        1e-5,
        t,
    ))
}

/// Aggregate form factor from the patches of material `from` to those of material `to`:
/// F_AB = Σ_{i∈A} A_i Σ_{j∈B} F_ij / Σ_{i∈A} A_i; `None` without a matrix (method
/// hierarchical: use [`one_bounce_form_factor`]).
pub fn surface_form_factor(out: &Outcome, from: u32, to: u32) -> Option<f64> {
    let p = &out.patches;
    let (mut num, mut den) = (0.0, 0.0);
    for (i, row) in out
        .form_factors
        .as_ref()?
        .matrix
        .outer_iterator()
        .enumerate()
    {
        if p.material[i] != from {
            continue;
        }
        den += p.area[i];
        num += p.area[i]
            * row
                .iter()
                .filter(|(j, _)| p.material[*j] == to)
                .map(|(_, &f)| f as f64)
                .sum::<f64>();
    }
    Some(num / den)
}

/// The same aggregate form factor measured by the light, for any method: after one bounce
/// from a uniform source (material `to`, radiance `le`, channel 0) the receiver (material
/// `from`, reflectance `rho`) has L = ρ · Le · F there, so F_AB = mean_A(L) / (ρ Le), area
/// weighted.
pub fn one_bounce_form_factor(out: &Outcome, from: u32, rho: f64, le: f64) -> f64 {
    let p = &out.patches;
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..p.len() {
        if p.material[i] == from {
            num += p.area[i] * out.solution.radiance[i][0];
            den += p.area[i];
        }
    }
    num / den / (rho * le)
}

/// Form factors between unit plates, parallel (1 apart) and perpendicular (sharing an edge),
/// against Howell C-11 and C-14.
///
/// Tolerance: the contour estimator is exact per point; the only error is integrating that
/// smooth integrand over the receiving patches (3-point Gauss rule: measured 7e-8 parallel,
/// 2e-8 perpendicular). With stratified random points instead (other `--samples`) it is
/// ~1e-3 for the perpendicular pair, whose integrand varies fastest along the shared edge,
/// and the area estimator's far-field kernel adds O(A/r²) (measured 6.8e-4). 5e-3 covers every
/// estimator and sample count; a wrong cosine or π is ≥ 20 %.
pub fn plates(settings: &Settings) -> Result<Vec<Case>> {
    let cases = plate_cases()?;
    cases
        .into_iter()
        .map(|(name, scene, expected)| {
            let t = Instant::now();
            let out = run_case(&scene, 0.1, settings, solve::Method::Neumann, 1)?;
            // The plate scenes: receiver ρ = 0.5, source Le = 1 (plate_cases).
            let got = one_bounce_form_factor(&out, 1, 0.5, 1.0);
            let noise = 3.0 * hemisphere_sigma(settings, expected, out.patches.len() / 2);
            let err = (got - expected).abs() / expected;
            Ok(case(name, expected, got, err, 5e-3 + noise, t))
        })
        .collect()
}

/// Howell's two plate configurations, each as (name, scene, F from the receiver, material 1, to
/// the source, material 0): unit squares parallel 1 apart (C-11) and perpendicular with a
/// common edge (C-14). The benchmark harness sweeps the same two.
pub fn plate_cases() -> Result<[(&'static str, Scene, f64); 2]> {
    Ok([
        (
            "form factor, parallel unit squares 1 apart (Howell C-11)",
            scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0)?,
            closed_forms::parallel_rectangles(1.0, 1.0, 1.0),
        ),
        (
            "form factor, perpendicular unit squares, common edge (Howell C-14)",
            scenes::perpendicular_plates(1.0, 1.0, 1.0, 0.5, 1.0)?,
            closed_forms::perpendicular_rectangles(1.0, 1.0, 1.0),
        ),
    ])
}

/// Relative standard deviation of a hemisphere-shooting estimate of a form factor of size `f`
/// from `patches` patches' rays pooled (binomial: √((1 − f)/(f N))); 0 for the other
/// estimators, whose error is deterministic quadrature error.
fn hemisphere_sigma(settings: &Settings, f: f64, patches: usize) -> f64 {
    if settings.form_factors.estimator != form_factor::Estimator::Hemisphere {
        return 0.0;
    }
    let n = settings.form_factors.rays as f64 * patches.max(1) as f64;
    ((1.0 - f) / (f * n)).sqrt()
}

/// The whole suite, in the order the table prints it.
pub fn run_all(settings: &Settings) -> Result<Vec<Case>> {
    let mut cases = vec![
        integrating_sphere(settings, Some(1))?,
        integrating_sphere(settings, None)?,
        furnace(settings)?,
    ];
    cases.extend(plates(settings)?);
    Ok(cases)
}

/// The table `radiosity verify` prints.
pub fn table(cases: &[Case]) -> String {
    let mut s = format!(
        "{:<66} {:>12} {:>12} {:>10} {:>9} {:>8}  result\n",
        "case", "expected", "got", "rel.error", "tolerance", "seconds"
    );
    for c in cases {
        s += &format!(
            "{:<66} {:>12.6} {:>12.6} {:>10.2e} {:>9.1e} {:>8.2}  {}\n",
            c.name,
            c.expected,
            c.got,
            c.relative_error,
            c.tolerance,
            c.seconds,
            if c.pass { "ok" } else { "FAIL" }
        );
    }
    s
}
