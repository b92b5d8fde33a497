//! Everything that controls a bake ([`Settings`]) and how its result is written
//! ([`WriteOptions`]), with the one [`Settings::validate`] every entry point calls before any
//! work: [`super::run`], [`super::solve_scene`], the command line and the benchmark tools.
//! Errors name the setting in the library's own words ([`crate::Error::Setting`]).

use std::path::PathBuf;

use std::fmt;

use serde::Serialize;

use crate::choice::Choice;
use crate::color;
use crate::gather::Gather;
use crate::mesh::{self, refine};
use crate::{form_factor, hierarchical, solve, Error, Result};

/// How the light transport is discretised and solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// `matrix` when the scene cuts into at most [`AUTO_MATRIX_MAX_PATCHES`] patches at the
    /// matrix method's `max_edge` (after its contact lines are cut), else `hierarchical`
    /// ([`Settings::resolved`]).
    Auto,
    /// Every pair of patches gets a form factor (a sparse n × n matrix), solved by
    /// `solver`, with adaptive refinement rounds between solves. Cost ∝ n².
    Matrix,
    /// Hierarchical radiosity with clustering ([`crate::hierarchical`]): links between
    /// elements and clusters at the level the error bound ε allows. Cost ∝ n.
    Hierarchical,
}

impl Choice for Method {
    const SETTING: &'static str = "method";
    const ALL: &'static [Method] = &[Method::Auto, Method::Matrix, Method::Hierarchical];

    fn name(self) -> &'static str {
        match self {
            Method::Auto => "auto",
            Method::Matrix => "matrix",
            Method::Hierarchical => "hierarchical",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Method::Auto => "matrix up to 10,000 patches, hierarchical beyond",
            Method::Matrix => {
                "form factors between every pair of patches, a sparse matrix: cost ∝ n²"
            }
            Method::Hierarchical => {
                "hierarchical radiosity with clustering: links at the level ε allows, cost ∝ n"
            }
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// `method = auto` takes the matrix method for a scene that cuts into at most this many
/// patches at its `max_edge`, and the hierarchical solver beyond. The matrix method's pair
/// loop and memory grow as patches² (and its refinement rounds add more than half again), so
/// a few times the default Cornell box's patches already take gigabytes, and the generated
/// hall of 10⁴ triangles takes the matrix method many times the hierarchical solver's time
/// and memory (BENCHMARKS.md "The matrix method on growing meshes"). The hierarchical solver
/// grows as the elements, but on the small benchmark scene the matrix method has the lower
/// error at equal time (BENCHMARKS.md "Hierarchical radiosity"), so small scenes keep it.
pub const AUTO_MATRIX_MAX_PATCHES: usize = 10_000;

/// [`Settings::finer`] at most: a `max_edge` a fifth of the scene's default, or finer, divides
/// the hierarchical ε by 25 and multiplies the gather's ray budget by 25. Without the bound a
/// tenth of the default would divide ε by 100, and the links grow about as ε^-0.4 on top of the
/// roots' growth.
pub const MAX_FINER: f64 = 25.0;

/// Everything that controls a bake.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Matrix or hierarchical.
    pub method: Method,
    /// Settings of the hierarchical solver (`method = hierarchical` only).
    pub hierarchical: hierarchical::Settings,
    /// Longest patch edge, scene units, finite and > 0; `None` = [`mesh::default_max_edge`]
    /// (the bounding-box diagonal / 16).
    pub max_edge: Option<f64>,
    /// Form-factor estimation.
    pub form_factors: form_factor::Settings,
    /// Linear solve.
    pub solver: solve::Settings,
    /// Crease angle, degrees, in [0, 180]: where faces meet at smaller angles the mesh samples
    /// one smooth surface, for the form factors (interpolated normals) and the output (shared
    /// vertices, gathered with the surface's normal); 0 = every face flat.
    pub crease_degrees: f64,
    /// Light from outside the mesh: the sky and the sun ([`crate::light::outside`]); the default
    /// has none.
    pub environment: crate::scene::Environment,
    /// Give every face a back side with its material ([`crate::scene::Scene::make_two_sided`]).
    pub two_sided: bool,
    /// Repair faces wound the wrong way before patching ([`crate::scene::orient`]).
    pub orient: crate::scene::orient::Orient,
    /// Adaptive refinement: rounds of splitting the patches whose radiance jumps against a
    /// neighbour's by more than `refine_threshold` (relative), each followed by a new solve
    /// ([`mod@crate::mesh::refine`]); 0 = none.
    pub refine_rounds: u32,
    /// Relative luminance jump that marks two neighbours for splitting; finite and > 0.
    pub refine_threshold: f64,
    /// The most patches refinement may make, ≥ 1: a round that would pass it splits only the
    /// largest jumps that fit ([`refine::within_budget`]); `None` =
    /// [`refine::default_budget`] (twice the initial patches, at most 12,000).
    pub refine_max_patches: Option<usize>,
    /// The most memory a bake may be estimated to need, bytes, finite and > 0
    /// ([`super::Estimate`]): [`super::run`] refuses a larger one before it starts; `None` =
    /// the memory the machine has available ([`super::estimate::available_memory`]).
    pub max_memory: Option<f64>,
    /// The time budget of a bake, seconds, finite and > 0; `None` = no budget. [`super::run`]
    /// coarsens the settings the estimate says would take longer ([`super::estimate::fit_time`]),
    /// and the hierarchical refinement and the display refinement stop where their share of
    /// it is spent.
    pub max_time: Option<f64>,
    /// No display refinement level starts after this instant (set by [`super::run`] from
    /// `max_time`; `None`: no limit).
    pub display_deadline: Option<std::time::Instant>,
    /// Form-factor cache directory: F is read from it when these patches and estimator
    /// settings were computed before, and stored otherwise ([`crate::form_factor::cache`]).
    pub cache: Option<PathBuf>,
    /// Discontinuities made mesh edges before patching ([`mesh::discontinuity`]).
    pub discontinuities: mesh::Discontinuities,
    /// Final gather at the output vertices ([`crate::gather`]).
    pub gather: Gather,
    /// Hemisphere rays per vertex of the `full` gather, in 1..=65536; `None` =
    /// [`crate::gather::auto_rays`] (a budget of 4·10⁶ rays over the vertices, times
    /// [`Settings::finer`], 64 to 1024 each).
    /// From 122 rays on (12 × 12 strata), [`crate::gather::EDGE_RAYS`] more go beside edges of
    /// the incident light.
    pub gather_rays: Option<u32>,
    /// Display refinement after the gather ([`mod@crate::gather::refine`]): an output edge is
    /// split where the light at its midpoint departs from the linear interpolation of its
    /// ends by more than this fraction of the local luminance; finite and >= 0 (0 = none).
    /// The same bound limits the local fits after it, which also fit the values to the
    /// midpoints tested and left whole ([`mod@crate::gather::local_fit`]).
    pub gather_tolerance: f64,
    /// A factor on the display refinement's bound on new vertices and on its midpoint tests
    /// ([`crate::gather::refine::budget_for`]), in (0, [`MAX_DISPLAY_BUDGET`]]; 1 = the
    /// default bound. Where the bound binds (a furnished scene under many lights), more
    /// vertices follow more of the shadows, at about the refinement's cost times the factor:
    /// the time a user trades for the picture (BENCHMARKS.md "Large outputs: the `cache`
    /// gather" measures it).
    pub display_budget: f64,
}

/// The largest [`Settings::display_budget`]: past it the refinement's cost, about the
/// gather's times the factor, would dwarf the rest of any bake.
pub const MAX_DISPLAY_BUDGET: f64 = 64.0;

impl Default for Settings {
    fn default() -> Self {
        Settings {
            method: Method::Auto,
            hierarchical: hierarchical::Settings::default(),
            max_edge: None,
            form_factors: form_factor::Settings::default(),
            solver: solve::Settings::default(),
            crease_degrees: mesh::DEFAULT_CREASE_DEGREES,
            environment: crate::scene::Environment::default(),
            two_sided: false,
            orient: crate::scene::orient::Orient::Auto,
            refine_rounds: 2,
            refine_threshold: refine::DEFAULT_THRESHOLD,
            refine_max_patches: None,
            max_memory: None,
            max_time: None,
            display_deadline: None,
            cache: None,
            discontinuities: mesh::Discontinuities::Auto,
            gather: Gather::Auto,
            gather_rays: None,
            gather_tolerance: crate::gather::refine::DEFAULT_TOLERANCE,
            display_budget: 1.0,
        }
    }
}

impl Settings {
    /// How much finer than the scene's default ([`mesh::default_max_edge`]) `max_edge` asks
    /// the patches to be, by area: (default / `max_edge`)², at least 1 (a coarser or no
    /// `max_edge`) and at most [`MAX_FINER`]. A finer mesh asks for a finer answer, not only
    /// for smaller patches: [`Settings::resolved`] divides the hierarchical ε by it, and the
    /// `full` gather's ray budget is multiplied by it ([`crate::gather::auto_rays`]).
    pub fn finer(&self, scene: &crate::scene::Scene) -> f64 {
        self.max_edge.map_or(1.0, |e| {
            (mesh::default_max_edge(scene) / e)
                .powi(2)
                .clamp(1.0, MAX_FINER)
        })
    }

    /// Whether the solve's patches are cut along the scene's contact lines (resolved
    /// settings): `auto` cuts them for the matrix method only (the hierarchical method cuts its
    /// display instead), `contacts` always, `none` never.
    pub fn cuts_contacts(&self) -> bool {
        match self.discontinuities {
            crate::mesh::Discontinuities::Auto => self.method == Method::Matrix,
            d => d == crate::mesh::Discontinuities::Contacts,
        }
    }

    /// These settings with the scene file's lights added to [`Settings::environment`], the
    /// hierarchical ε divided by [`Settings::finer`], and `method = auto` resolved for
    /// `scene`: `matrix` when the scene cuts into at most [`AUTO_MATRIX_MAX_PATCHES`] patches
    /// as the matrix bake cuts it (along the contact lines first, as
    /// [`Settings::cuts_contacts`] says, then to the matrix method's `max_edge`: the given
    /// one, or [`mesh::default_max_edge`]; both sides with `two_sided`), or when a
    /// form-factor cache is given (it stores a matrix); else `hierarchical`. Other methods
    /// are kept. `bake` and `info` (through [`super::Estimate`]) both decide here, on the
    /// same counts.
    ///
    /// The patches are counted by cutting the scene only when two lower bounds allow the
    /// matrix: every triangle is at least one patch, and a patch whose edges are at most
    /// `max_edge` long covers at most √3/4 · max_edge² (the equilateral triangle). A large scene,
    /// or a small one asked for a very fine mesh, is sent to the hierarchy without making
    /// millions of patches only to count them.
    pub fn resolved(&self, scene: &crate::scene::Scene) -> Result<Settings> {
        let mut s = self.clone();
        s.environment.add_scene_lights(scene);
        s.hierarchical.epsilon = self.hierarchical.epsilon / self.finer(scene);
        if s.method == Method::Auto {
            s.method = if s.cache.is_some() {
                Method::Matrix
            } else {
                let max_edge = s.max_edge.unwrap_or_else(|| mesh::default_max_edge(scene));
                let sides = if s.two_sided && !scene.is_two_sided() {
                    2
                } else {
                    1
                };
                let area: f64 = (0..scene.triangles.len())
                    .map(|t| scene.triangle_area(t))
                    .sum();
                let by_area = area / (0.75f64.sqrt() / 2.0 * max_edge * max_edge);
                let at_least = scene.triangles.len().max(by_area.floor() as usize);
                // Counted as the matrix bake cuts the scene: along its contact lines first
                // (which only adds patches, so the bounds above stay lower bounds).
                let matrix = Settings {
                    method: Method::Matrix,
                    ..s.clone()
                };
                let few = sides * at_least <= AUTO_MATRIX_MAX_PATCHES && {
                    let split = matrix
                        .cuts_contacts()
                        .then(|| mesh::split_contacts(scene).0);
                    let cut = split.as_ref().unwrap_or(scene);
                    sides * mesh::subdivide(cut, max_edge, s.crease_degrees)?.len()
                        <= AUTO_MATRIX_MAX_PATCHES
                };
                if few {
                    Method::Matrix
                } else {
                    Method::Hierarchical
                }
            };
        }
        Ok(s)
    }

    /// Checks every range before any work: `max_edge` (when given) finite and > 0,
    /// `crease_degrees` in [0, 180], `refine_threshold` finite and > 0, and the form-factor and
    /// solver settings ([`form_factor::Settings::validate`], [`solve::Settings::validate`]).
    /// The first failure is an [`Error::Setting`] naming the field (`max_edge`,
    /// `crease_degrees`, `refine_threshold`, `form_factors.samples`, `solver.tolerance`, …).
    pub fn validate(&self) -> Result<()> {
        if let Some(e) = self.max_edge {
            if !(e > 0.0 && e.is_finite()) {
                return Err(Error::setting(
                    "max_edge",
                    format!("{e} is not a positive length"),
                ));
            }
        }
        if !(0.0..=180.0).contains(&self.crease_degrees) {
            return Err(Error::setting(
                "crease_degrees",
                format!("{} is not in [0, 180] degrees", self.crease_degrees),
            ));
        }
        if !(self.refine_threshold > 0.0 && self.refine_threshold.is_finite()) {
            return Err(Error::setting(
                "refine_threshold",
                format!("{} is not a positive number", self.refine_threshold),
            ));
        }
        if self.refine_max_patches == Some(0) {
            return Err(Error::setting(
                "refine_max_patches",
                "0 is not a patch count >= 1",
            ));
        }
        if let Some(m) = self.max_memory {
            if !(m > 0.0 && m.is_finite()) {
                return Err(Error::setting(
                    "max_memory",
                    format!("{m} is not a positive number of bytes"),
                ));
            }
        }
        if let Some(t) = self.max_time {
            if !(t > 0.0 && t.is_finite()) {
                return Err(Error::setting(
                    "max_time",
                    format!("{t} is not a positive number of seconds"),
                ));
            }
        }
        if !(self.gather_tolerance >= 0.0 && self.gather_tolerance.is_finite()) {
            return Err(Error::setting(
                "gather_tolerance",
                format!("{} is not a number >= 0", self.gather_tolerance),
            ));
        }
        if !(self.display_budget > 0.0 && self.display_budget <= MAX_DISPLAY_BUDGET) {
            return Err(Error::setting(
                "display_budget",
                format!(
                    "{} is not a factor in (0, {MAX_DISPLAY_BUDGET}]",
                    self.display_budget
                ),
            ));
        }
        if let Some(r) = self.gather_rays {
            if !(1..=65536).contains(&r) {
                return Err(Error::setting(
                    "gather_rays",
                    format!("{r} is not in 1..=65536"),
                ));
            }
        }
        self.form_factors.validate()?;
        self.solver.validate()?;
        self.environment.validate()?;
        if self.method != Method::Matrix {
            self.hierarchical.validate()?;
        }
        if self.method == Method::Hierarchical && self.cache.is_some() {
            return Err(Error::setting(
                "cache",
                "the form-factor cache stores a matrix: it applies to method matrix only",
            ));
        }
        Ok(())
    }
}

/// Output options of [`super::run`].
#[derive(Debug, Clone, Copy, Default)]
pub struct WriteOptions {
    /// ASCII instead of binary PLY.
    pub ascii: bool,
    /// Exposure (radiance multiplier before sRGB), finite and > 0; `None` =
    /// [`crate::bake::BakedMesh::auto_exposure`].
    pub exposure: Option<f64>,
}

impl WriteOptions {
    /// Checks the exposure, when given: finite and > 0 (an [`Error::Setting`] named
    /// `exposure`).
    pub fn validate(&self) -> Result<()> {
        self.exposure.map_or(Ok(()), color::check_exposure)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each bad value of each setting, and the name the error must give.
    #[test]
    fn validate_names_the_first_bad_setting() {
        Settings::default().validate().unwrap();
        type Breakage = (fn(&mut Settings), &'static str);
        let cases: [Breakage; 21] = [
            (|s| s.max_memory = Some(0.0), "max_memory"),
            (|s| s.max_time = Some(0.0), "max_time"),
            (|s| s.max_time = Some(f64::NAN), "max_time"),
            (|s| s.refine_max_patches = Some(0), "refine_max_patches"),
            (|s| s.gather_rays = Some(0), "gather_rays"),
            (|s| s.gather_tolerance = -0.01, "gather_tolerance"),
            (|s| s.gather_tolerance = f64::INFINITY, "gather_tolerance"),
            (|s| s.display_budget = 0.0, "display_budget"),
            (|s| s.display_budget = f64::NAN, "display_budget"),
            (|s| s.display_budget = 65.0, "display_budget"),
            (|s| s.max_edge = Some(0.0), "max_edge"),
            (|s| s.max_edge = Some(f64::NAN), "max_edge"),
            (|s| s.max_edge = Some(-2.0), "max_edge"),
            (|s| s.crease_degrees = -1.0, "crease_degrees"),
            (|s| s.crease_degrees = 181.0, "crease_degrees"),
            (|s| s.refine_threshold = 0.0, "refine_threshold"),
            (|s| s.refine_threshold = f64::INFINITY, "refine_threshold"),
            (|s| s.form_factors.samples = 0, "form_factors.samples"),
            (|s| s.form_factors.rays = 0, "form_factors.rays"),
            (|s| s.solver.tolerance = 0.0, "solver.tolerance"),
            (|s| s.solver.omega = Some(2.0), "solver.omega"),
        ];
        for (breakage, name) in cases {
            let mut s = Settings::default();
            breakage(&mut s);
            match s.validate() {
                Err(Error::Setting { name: n, message }) => {
                    assert_eq!(n, name, "{message}");
                    assert!(!message.is_empty());
                }
                other => panic!("{name}: {other:?}"),
            }
        }
        for x in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let o = WriteOptions {
                exposure: Some(x),
                ..WriteOptions::default()
            };
            assert!(matches!(o.validate(), Err(Error::Setting { name, .. }) if name == "exposure"));
        }
        WriteOptions::default().validate().unwrap();
    }
}
