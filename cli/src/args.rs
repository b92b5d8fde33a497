//! The command line's arguments (clap derive) and their conversion into the library's settings
//! (ripgrep's two stages, LowArgs → HiArgs): this module only parses; every range is checked
//! by the library's `validate()` before any work ([`radiosity::pipeline::Settings::validate`],
//! [`radiosity::render::View::validate`]), and [`crate::failure`] maps the library's setting
//! names back to these flags. Does no I/O and owns no physics.

use std::path::PathBuf;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Args, Parser, Subcommand};

use glam::DVec3;
use radiosity::bake::BakedMesh;
use radiosity::form_factor::{self, Estimator};
use radiosity::gather::Gather;
use radiosity::hierarchical;
use radiosity::mesh::Discontinuities;
use radiosity::pipeline::{self, WriteOptions};
use radiosity::render::{self, View};
use radiosity::scene::orient::Orient;
use radiosity::scene::{Camera, Override, Property, Up};
use radiosity::scene::{Environment, LightSources, PointLight, SkyModel, Spot, Sun};
use radiosity::solve::{self, Method};
use radiosity::{Choice, Result};

use crate::failure::Failure;

/// A clap parser for one of the library's enumerated settings: its names as the possible
/// values, each with its description (shown by `--help`).
fn choice<T: Choice + Send + Sync>() -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(
        T::ALL
            .iter()
            .map(|c| PossibleValue::new(c.name()).help(c.description())),
    )
    .map(|name| T::from_name(&name).expect("clap accepts only the listed names"))
}

/// Radiosity: diffuse global illumination baked into mesh vertex colours.
///
/// Units: radiance L and emission Le (MTL `Ke`) in W·sr⁻¹·m⁻²; reflectance ρ (MTL `Kd`) in
/// [0, 1] per RGB channel; lengths in the scene's own units.
#[derive(Debug, Parser)]
#[command(name = "radiosity", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, global = true, value_name = "N", allow_negative_numbers = true)]
    pub threads: Option<usize>,
    /// No summary and no progress bars on stderr (warnings and errors are still printed).
    #[arg(long, short, global = true)]
    pub quiet: bool,
    /// More detail on stderr: each solve's counts, refinement rounds, seconds per stage.
    #[arg(long, short, global = true)]
    pub verbose: bool,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Solve a scene and write it with baked vertex colours (PLY or OBJ, by extension).
    Bake(BakeArgs),
    /// Run the built-in analytic suite (integrating sphere, furnace, Howell form factors).
    Verify(VerifyArgs),
    /// Write one of the verification scenes as OBJ + MTL (to try the tool or other renderers).
    Generate(GenerateArgs),
    /// Render a picture (PNG) of a baked PLY, or of a scene (baked first with the options given).
    Render(RenderArgs),
    /// Describe a scene without solving it: counts, bounding box, materials, emitters and
    /// their power, loader warnings, and the patch count the defaults would give.
    Info(InfoArgs),
}

/// Options of `radiosity info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Input scene (OBJ with its MTL, or PLY).
    pub input: PathBuf,
    /// Print JSON instead of text (the same facts; field names in the README).
    #[arg(long)]
    pub json: bool,
    /// The bake's options (`--max-edge`, `--method`, `--refine`, `--epsilon`, …), for the
    /// estimate of its patches, memory and time; `--two-sided` also describes the scene with
    /// its back faces (counts, area and emitted power include them).
    #[command(flatten)]
    pub solve: SolveArgs,
    #[command(flatten)]
    pub materials: MaterialArgs,
}

/// Options of `radiosity render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// A PLY written by `radiosity bake` (rendered as it is, unless material overrides are
    /// given), or a scene OBJ or PLY (baked first).
    pub input: PathBuf,
    /// Output picture (.png).
    #[arg(short, long, value_name = "FILE.png")]
    pub output: PathBuf,
    /// Radiance multiplier before the sRGB curve [default: automatic, as for bake].
    #[arg(
        long,
        value_name = "X",
        allow_negative_numbers = true,
        help_heading = "Picture"
    )]
    pub exposure: Option<f64>,
    #[command(flatten)]
    pub scene: SceneArgs,
}

/// What every command that bakes a scene takes (`bake`, and `render` of a scene): the picture,
/// the discretisation, form-factor and solver options, and material overrides.
#[derive(Debug, Args)]
pub struct SceneArgs {
    #[command(flatten)]
    pub view: ViewArgs,
    #[command(flatten)]
    pub solve: SolveArgs,
    #[command(flatten)]
    pub materials: MaterialArgs,
}

/// Picture options shared by `render` and `bake --png`.
#[derive(Debug, Args)]
pub struct ViewArgs {
    /// Camera as eye,target,up,fov: nine coordinates in scene units and the vertical field of
    /// view in degrees, e.g. 278,273,-800,278,273,0,0,1,0,39.30765 [default: the scene file's
    /// camera line (`# camera:` in OBJ, `comment camera:` in PLY), else frame the bounding box
    /// from its −z side at 39.3°].
    #[arg(
        long,
        value_name = "EX,EY,EZ,TX,TY,TZ,UX,UY,UZ,FOV",
        allow_hyphen_values = true,
        help_heading = "Picture"
    )]
    pub camera: Option<String>,
    /// Picture size in pixels, WIDTHxHEIGHT or one number for a square.
    #[arg(
        long,
        default_value = "512",
        value_name = "WxH",
        help_heading = "Picture"
    )]
    pub size: String,
    /// Samples per pixel along each axis (n² rays per pixel, for anti-aliasing).
    #[arg(long, default_value_t = 2, value_name = "N", help_heading = "Picture")]
    pub spp: u32,
    /// Show each patch's own solved radiance (no interpolation).
    #[arg(long, help_heading = "Picture")]
    pub flat: bool,
    /// Map luminance to a colour scale with a legend instead of sRGB colours.
    #[arg(long, alias = "false-color", help_heading = "Picture")]
    pub false_colour: bool,
}

/// The procedural scenes `radiosity generate` can write.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SceneKind {
    /// Geodesic sphere (1280 faces, radius 1) seen from inside, 30° emitting cap (Le = 1), ρ = 0.5.
    IntegratingSphere,
    /// Closed unit room with two floating boxes, Le = 1 and ρ = 0.5 everywhere (L = 2).
    Furnace,
    /// Unit squares 1 apart, facing (Howell C-11: F = 0.19982).
    ParallelPlates,
    /// Unit squares at 90° sharing an edge (Howell C-14: F = 0.20004).
    PerpendicularPlates,
    /// A furnished hall for measuring scale: tables and chairs on a grid, area lights under
    /// the ceiling, at least --triangles triangles (metres).
    Hall,
    /// A living room (432 triangles, metres, z up): ceiling panel and wall lamp, sofa,
    /// bookshelf, coffee table and a ball; the point-wise benchmark's untuned scene.
    LivingRoom,
    /// Two rooms joined by a doorway (68 triangles, metres, z up): one ceiling panel in the
    /// first, the second lit through the doorway; a point-wise benchmark scene.
    TwoRooms,
    /// A study under one small bright downlight (418 triangles, metres, z up): a desk on legs
    /// with a monitor, a wall shelf and a ball; a point-wise benchmark scene.
    Study,
    /// An attic bedroom under a gabled roof (94 triangles, metres, z up): a skylight in the
    /// slope, a lamp cube on a bedside table, a bed on a rug turned 20°, a chimney up to the
    /// slope; a point-wise benchmark scene.
    Attic,
    /// A kitchen (258 triangles, metres, z up): a window-sized daylight panel, two pendant
    /// lamps over an island, counters with wall cabinets, a fridge, two stools turned off the
    /// axes; a point-wise benchmark scene.
    Kitchen,
    /// A furnished open-plan office (24 × 14 × 3 m, metres, z up, at least --triangles
    /// triangles): twelve ceiling panels and the sky in eight windows, desks with monitors,
    /// turned office chairs, columns, bookcases and potted plants; a point-wise benchmark scene.
    Office,
    /// The office by daylight: its eight windows open and its ceiling panels dark, to bake with
    /// `--up z --sky L --sun AZIMUTH,ELEVATION,E` (the windows face south: azimuth 135–225°).
    OfficeDaylit,
}

/// Options of `radiosity generate`.
#[derive(Debug, Args)]
pub struct GenerateArgs {
    /// Which scene.
    #[arg(value_enum)]
    pub scene: SceneKind,
    /// Output OBJ (its MTL is written beside it with the same name).
    #[arg(short, long, value_name = "FILE.obj")]
    pub output: PathBuf,
    /// Triangles at least (hall and office only; 10⁴ … 10⁶ and more).
    #[arg(long, default_value_t = 100_000, value_name = "N")]
    pub triangles: usize,
}

/// Options of `radiosity bake`.
#[derive(Debug, Args)]
pub struct BakeArgs {
    /// Input scene: OBJ with its MTL (Kd = reflectance, Ke = emitted radiance), or PLY
    /// (optional reflectance_r/g/b and emission_r/g/b per face or vertex).
    pub input: PathBuf,
    /// Output mesh: .ply (binary; --ascii for text) or .obj (vertex colours `v x y z r g b`).
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Write the JSON report (counts, rays, row sums, iterations, seconds per stage) here.
    #[arg(long, value_name = "FILE.json", help_heading = "Output")]
    pub report: Option<PathBuf>,
    /// Write ASCII PLY instead of binary.
    #[arg(long, help_heading = "Output")]
    pub ascii: bool,
    /// Radiance multiplier before the sRGB curve [default: automatic — the area-weighted
    /// log-average luminance maps to 0.18 of white, at most 2 % of the lit area clipping].
    #[arg(
        long,
        value_name = "X",
        allow_negative_numbers = true,
        help_heading = "Output"
    )]
    pub exposure: Option<f64>,
    /// Also render a picture of the result (PNG); see the Picture options.
    #[arg(long, value_name = "FILE.png", help_heading = "Output")]
    pub png: Option<PathBuf>,
    #[command(flatten)]
    pub scene: SceneArgs,
}

/// Material overrides shared by `bake`, `render` and `info`: change ρ or Le of a material
/// without editing the scene's files. Applied in order; a later one wins.
#[derive(Debug, Args)]
pub struct MaterialArgs {
    /// Set the reflectance ρ of MATERIAL (a name, or a pattern: `*` any characters, `?` one;
    /// `*` = every material): R,G,B in [0, 1], or one value for grey. Repeatable; later ones
    /// win.
    #[arg(
        long,
        value_name = "MATERIAL=R,G,B",
        allow_hyphen_values = true,
        help_heading = "Materials"
    )]
    pub reflectance: Vec<String>,
    /// Set the emitted radiance Le of MATERIAL (a name, or a pattern such as `tlight*`; `*` =
    /// every material), W·sr⁻¹·m⁻²: R,G,B ≥ 0, or one value for grey. Repeatable; later ones
    /// win.
    #[arg(
        long,
        value_name = "MATERIAL=R,G,B",
        allow_hyphen_values = true,
        help_heading = "Materials"
    )]
    pub emission: Vec<String>,
}

impl MaterialArgs {
    /// The parsed overrides, reflectances first then emissions, each in command-line order
    /// (the two never act on the same property, so their relative order does not matter).
    pub fn overrides(&self) -> Result<Vec<Override>> {
        let rho = self
            .reflectance
            .iter()
            .map(|t| Override::parse(Property::Reflectance, t));
        let le = self
            .emission
            .iter()
            .map(|t| Override::parse(Property::Emission, t));
        rho.chain(le).collect()
    }
}

/// The method and the hierarchical solver's options, shared by `bake` and `verify`.
#[derive(Debug, Args)]
pub struct MethodArgs {
    /// Light-transport method: `matrix` (form factors between every pair of patches, cost ∝
    /// n²) or `hierarchical` (links between elements and clusters at the level --epsilon
    /// allows, cost ∝ n).
    #[arg(long, value_parser = choice::<pipeline::Method>(), default_value_t = pipeline::Settings::default().method, help_heading = "Method")]
    pub method: pipeline::Method,
    /// Hierarchical: the most power one link may carry, as a fraction of the power the scene
    /// emits; smaller = finer elements and more links. Given for the default --max-edge: a
    /// finer --max-edge divides it by how much smaller the patches are by area (at most 25×).
    #[arg(long, default_value_t = hierarchical::Settings::default().epsilon, value_name = "X", allow_negative_numbers = true, help_heading = "Method")]
    pub epsilon: f64,
    /// Hierarchical: smallest element area, as a fraction of the scene's total area.
    #[arg(long, default_value_t = hierarchical::Settings::default().min_area, value_name = "X", allow_negative_numbers = true, help_heading = "Method")]
    pub min_area: f64,
    /// Hierarchical: visibility rays per link (the form factor uses a 7-point Gauss rule).
    #[arg(long, default_value_t = hierarchical::Settings::default().rays, value_name = "N", allow_negative_numbers = true, help_heading = "Method")]
    pub link_rays: u32,
    /// Hierarchical: refinement passes at most (each opens links one level finer); reaching
    /// it stops the refinement with a warning, the solution coarser than --epsilon asks.
    #[arg(long, default_value_t = hierarchical::Settings::default().max_passes, value_name = "N", allow_negative_numbers = true, help_heading = "Method")]
    pub max_passes: u32,
}

impl MethodArgs {
    /// The hierarchical settings these options give (checked by the library).
    pub fn hierarchical(&self) -> hierarchical::Settings {
        hierarchical::Settings {
            epsilon: self.epsilon,
            min_area: self.min_area,
            rays: self.link_rays,
            max_passes: self.max_passes,
            ..hierarchical::Settings::default()
        }
    }
}

/// Discretisation, form-factor and solver options shared by `bake` and `verify`.
#[derive(Debug, Args)]
pub struct SolveArgs {
    #[command(flatten)]
    pub method: MethodArgs,
    /// Discontinuities made mesh edges before patching: `contacts` (where a face touches or
    /// crosses another's plane, or a parallel face is mounted just in front of it, the
    /// contact line becomes an edge) or `none`.
    #[arg(long, value_parser = choice::<Discontinuities>(), default_value_t = pipeline::Settings::default().discontinuities, help_heading = "Discretisation")]
    pub discontinuities: Discontinuities,
    /// Final gather at the output vertices: `none` (the mean of the patches around each
    /// vertex), `direct` (the direct light computed exactly at each vertex, the indirect from
    /// the patches), `full` (direct exactly and indirect by hemisphere rays at each vertex),
    /// `cache` (direct exactly at each vertex, indirect gathered where nearby surfaces make it
    /// vary and interpolated between: for large outputs) or `auto` (`full` up to 62,500 output
    /// vertices, the hierarchical display's counted before its shadow and contact lines cut
    /// it; `cache` beyond).
    #[arg(long, value_parser = choice::<Gather>(), default_value_t = pipeline::Settings::default().gather, help_heading = "Final gather")]
    pub gather: Gather,
    /// Hemisphere rays per vertex of `--gather full` [default: 4·10⁶ / vertices, at least 64
    /// and at most 1024]. From 122 on (12 × 12 strata), half as many again go where the light has
    /// edges (a bright surface seen through a doorway).
    #[arg(
        long,
        value_name = "N",
        allow_negative_numbers = true,
        help_heading = "Final gather"
    )]
    pub gather_rays: Option<u32>,
    /// Display refinement after the gather: an output edge is split (a new vertex gathered at
    /// its midpoint) where the light there departs from the interpolation of its ends by more
    /// than this fraction of the local luminance; 0 = none. New vertices are bounded: about
    /// twice the gather's ray budget. Vertex values are then fitted locally (the indirect
    /// light's noise averaged, the interpolation made to keep the light's integral) where the
    /// fits are within this fraction too, and to the light found at the midpoints of the edges
    /// tested and left whole.
    #[arg(long, value_name = "FRACTION", allow_negative_numbers = true, default_value_t = pipeline::Settings::default().gather_tolerance, help_heading = "Final gather")]
    pub gather_tolerance: f64,
    /// A factor on the display refinement's bound on new vertices (and its midpoint tests):
    /// where the bound binds, as on a furnished scene under many lights, more vertices follow
    /// more of the shadows, for about the refinement's time times the factor. In (0, 64];
    /// --max-time sets it back to 1 first.
    #[arg(long, value_name = "FACTOR", allow_negative_numbers = true, default_value_t = pipeline::Settings::default().display_budget, help_heading = "Final gather")]
    pub display_budget: f64,
    /// Longest patch edge, scene units [default: bounding-box diagonal / 16].
    #[arg(
        long,
        value_name = "LEN",
        allow_negative_numbers = true,
        help_heading = "Discretisation"
    )]
    pub max_edge: Option<f64>,
    /// Crease angle in degrees: where faces meet at smaller angles the mesh samples one smooth
    /// surface (its interpolated normal enters the form factors); sharper edges stay creases.
    /// 0 = every face flat. Output vertices are shared only within a flat facet, whatever it
    /// is: the output shows the faceted geometry as any renderer of the mesh does.
    #[arg(long, default_value_t = radiosity::mesh::DEFAULT_CREASE_DEGREES, value_name = "DEG", allow_negative_numbers = true, help_heading = "Discretisation")]
    pub crease: f64,
    /// The scene's up axis: the sky's horizon, the sun's elevation, and the automatic framing
    /// of pictures (when neither --camera nor the file gives a camera, the picture looks level
    /// about this axis, from outside the bounding box or at eye height inside it, whichever
    /// shows more front faces; from above only if no level view shows any).
    #[arg(long, value_parser = choice::<Up>(), default_value = "y", value_name = "AXIS", help_heading = "Light")]
    pub up: Up,
    /// A sky above the horizon with this radiance, W·sr⁻¹·m⁻² (R,G,B or one value for grey;
    /// the zenith's with --sky-model overcast): rays leaving the scene upward gather it.
    #[arg(
        long,
        value_name = "R,G,B",
        allow_hyphen_values = true,
        help_heading = "Light"
    )]
    pub sky: Option<String>,
    /// How the sky's radiance varies with direction.
    #[arg(long, value_parser = choice::<SkyModel>(), default_value = "uniform", help_heading = "Light")]
    pub sky_model: SkyModel,
    /// The sun: azimuth (degrees clockwise from north; north is +z with y up, +y with z up),
    /// elevation (degrees above the horizon) and irradiance on a surface facing it, W·m⁻²
    /// (R,G,B or one value), e.g. 135,40,900,850,800.
    #[arg(
        long,
        value_name = "AZIMUTH,ELEVATION,R,G,B",
        allow_hyphen_values = true,
        help_heading = "Light"
    )]
    pub sun: Option<String>,
    /// A point light: position (scene units) and radiant intensity, W·sr⁻¹ (R,G,B or one
    /// value; a surface at distance r facing it receives I/r²). Repeatable.
    #[arg(
        long,
        value_name = "X,Y,Z,R,G,B",
        allow_hyphen_values = true,
        help_heading = "Light"
    )]
    pub point_light: Vec<String>,
    /// A spot light: position, the direction it shines, the inner and outer half-angles of its
    /// cone (degrees, as glTF's) and its intensity on the axis, W·sr⁻¹. Repeatable.
    #[arg(
        long,
        value_name = "X,Y,Z,DX,DY,DZ,INNER,OUTER,R,G,B",
        allow_hyphen_values = true,
        help_heading = "Light"
    )]
    pub spot_light: Vec<String>,
    /// A lights file (JSON): a sky, a sun and any number of point and spot lights, in the
    /// units of the flags above (format in the README, "A lights file"). Its lights join
    /// those of the flags and of the scene file; --sky and --sun replace the file's.
    #[arg(long, value_name = "FILE.json", help_heading = "Light")]
    pub lights: Option<PathBuf>,
    /// Surfaces reflect and emit on both sides: every face gets a back face with the same
    /// material (ρ, Le) and its own radiance, and the output has both (twice the patches).
    #[arg(long, help_heading = "Discretisation")]
    pub two_sided: bool,
    /// Faces wound the wrong way: `auto` makes each surface's faces agree and turns it to
    /// face where the light and the rest of the scene see it from (a warning says what was
    /// turned); `keep` bakes the winding as given.
    #[arg(long, value_parser = choice::<Orient>(), default_value_t = pipeline::Settings::default().orient, help_heading = "Discretisation")]
    pub orient: Orient,
    /// Adaptive refinement rounds: after each solve, split the patches whose radiance differs
    /// from a neighbour's (same surface) by more than --refine-threshold, and solve again.
    #[arg(
        long,
        default_value_t = radiosity::pipeline::Settings::default().refine_rounds,
        value_name = "N",
        allow_negative_numbers = true,
        help_heading = "Discretisation"
    )]
    pub refine: u32,
    /// Relative luminance jump between neighbouring patches that marks both for splitting.
    #[arg(
        long,
        default_value_t = radiosity::mesh::refine::DEFAULT_THRESHOLD,
        value_name = "X",
        allow_negative_numbers = true,
        help_heading = "Discretisation"
    )]
    pub refine_threshold: f64,
    /// The most patches adaptive refinement may make; a round that would pass it splits only
    /// the largest jumps that fit [default: twice the initial patches, at most 12,000].
    #[arg(
        long,
        value_name = "N",
        allow_negative_numbers = true,
        help_heading = "Discretisation"
    )]
    pub refine_max_patches: Option<usize>,
    /// Refuse, before it starts, a bake estimated to need more memory than this: bytes, or
    /// with a binary unit (512M, 4G, 1.5GiB) [default: the memory available now]. `radiosity
    /// info` with the same options prints the estimate.
    #[arg(long, value_name = "SIZE", value_parser = parse_bytes, allow_hyphen_values = true, help_heading = "Limits")]
    pub max_memory: Option<f64>,
    /// A time budget for the bake: seconds, or with a unit (90s, 2m, 1.5h). Settings the
    /// estimate says would take longer are coarsened first (a larger ε, then a lighter
    /// display), with a line saying what was chosen; the refinements stop where their share
    /// of the budget is spent.
    #[arg(long, value_name = "DURATION", value_parser = parse_seconds, allow_hyphen_values = true, help_heading = "Limits")]
    pub max_time: Option<f64>,
    #[command(flatten)]
    pub estimator: FormFactorArgs,
    /// Form-factor cache directory: F (geometry only) is stored there and reused by later
    /// runs with the same geometry and form-factor settings, whatever the materials.
    #[arg(long, value_name = "DIR", help_heading = "Form factors")]
    pub cache: Option<PathBuf>,
    /// Solver of (I − K)L = E.
    #[arg(long, value_parser = choice::<Method>(), default_value_t = solve::Settings::default().method, help_heading = "Solver")]
    pub solver: Method,
    /// Bounces N of the Neumann series E + KE + … + K^N E (solver neumann only).
    #[arg(
        long,
        default_value_t = solve::Settings::default().bounces,
        value_name = "N",
        allow_negative_numbers = true,
        help_heading = "Solver"
    )]
    pub bounces: u32,
    /// Stop when ‖E − (I − K)L‖ / ‖E‖ ≤ this (the iterative solvers: jacobi, gauss-seidel, cg,
    /// southwell; cg measures it on the symmetric system it solves).
    #[arg(
        long,
        default_value = "1e-6",
        value_name = "T",
        allow_negative_numbers = true,
        help_heading = "Solver"
    )]
    pub tolerance: f64,
    /// Give up (warning, exit status 3) after this many sweeps.
    #[arg(
        long,
        default_value_t = solve::Settings::default().max_iterations,
        value_name = "N",
        allow_negative_numbers = true,
        help_heading = "Solver"
    )]
    pub max_iterations: u32,
    /// Over-relaxation ω of Gauss–Seidel (SOR), in (0, 2); 1 = plain Gauss–Seidel
    /// [default: automatic, Young's optimum for the scene's largest ρ·(row sum), at most 1.7].
    #[arg(
        long,
        value_name = "W",
        allow_negative_numbers = true,
        help_heading = "Solver"
    )]
    pub omega: Option<f64>,
}

/// Form-factor estimation options shared by `bake` and `verify`.
#[derive(Debug, Args)]
pub struct FormFactorArgs {
    /// Form-factor estimator.
    #[arg(long, value_parser = choice::<Estimator>(), default_value_t = form_factor::Settings::default().estimator, help_heading = "Form factors")]
    pub form_factors: Estimator,
    /// Sample points per patch = visibility rays per patch pair.
    #[arg(
        long,
        default_value_t = form_factor::Settings::default().samples,
        value_name = "N",
        allow_negative_numbers = true,
        help_heading = "Form factors"
    )]
    pub samples: u32,
    /// Cosine-weighted rays per patch (hemisphere estimator).
    #[arg(
        long,
        default_value_t = form_factor::Settings::default().rays,
        value_name = "N",
        allow_negative_numbers = true,
        help_heading = "Form factors"
    )]
    pub rays: u32,
    /// Seed of all sampling (same seed ⇒ same result for any thread count).
    #[arg(long, default_value_t = form_factor::Settings::default().seed, value_name = "S", help_heading = "Form factors")]
    pub seed: u64,
    /// Enforce reciprocity A_i F_ij = A_j F_ji: the symmetric part of A·F, rescaled (Sinkhorn)
    /// so that every row keeps its sum.
    #[arg(long, help_heading = "Form factors")]
    pub reciprocity: bool,
}

impl FormFactorArgs {
    /// The form-factor settings these options give (checked by the library).
    pub fn settings(&self) -> form_factor::Settings {
        form_factor::Settings {
            estimator: self.form_factors,
            samples: self.samples,
            rays: self.rays,
            seed: self.seed,
            reciprocity: self.reciprocity,
            ..form_factor::Settings::default()
        }
    }
}

/// Options of `radiosity verify`.
#[derive(Debug, Args)]
pub struct VerifyArgs {
    #[command(flatten)]
    pub method: MethodArgs,
    #[command(flatten)]
    pub estimator: FormFactorArgs,
    /// Solver for the all-bounce cases.
    #[arg(long, value_parser = choice::<Method>(), default_value_t = solve::Settings::default().method)]
    pub solver: Method,
    /// Write the table as JSON here.
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
}

impl SolveArgs {
    /// The pipeline settings these options give, checked by the library
    /// ([`pipeline::Settings::validate`]) before any work.
    pub fn settings(&self) -> std::result::Result<pipeline::Settings, Failure> {
        let settings = pipeline::Settings {
            method: self.method.method,
            hierarchical: self.method.hierarchical(),
            max_edge: self.max_edge,
            form_factors: self.estimator.settings(),
            solver: solve::Settings {
                method: self.solver,
                tolerance: self.tolerance,
                max_iterations: self.max_iterations,
                bounces: self.bounces,
                omega: self.omega,
            },
            crease_degrees: self.crease,
            environment: self.environment()?,
            two_sided: self.two_sided,
            orient: self.orient,
            refine_rounds: self.refine,
            refine_threshold: self.refine_threshold,
            refine_max_patches: self.refine_max_patches,
            max_memory: self.max_memory,
            max_time: self.max_time,
            display_deadline: None,
            cache: self.cache.clone(),
            discontinuities: self.discontinuities,
            gather: self.gather,
            gather_rays: self.gather_rays,
            gather_tolerance: self.gather_tolerance,
            display_budget: self.display_budget,
        };
        settings.validate()?;
        Ok(settings)
    }
}

/// Numbers separated by commas: `what` names the option in errors.
fn numbers(text: &str, option: &'static str) -> std::result::Result<Vec<f64>, Failure> {
    text.split(',')
        .map(|t| {
            t.trim().parse::<f64>().map_err(|_| {
                Failure::usage(option, format!("{text:?}: {:?} is not a number", t.trim()))
            })
        })
        .collect()
}

impl SolveArgs {
    /// The lights outside the mesh these options ask for: the flags' own, put over a lights
    /// file's by the library's rule ([`LightSources::over`]); ranges are checked by the
    /// library.
    pub fn environment(&self) -> std::result::Result<Environment, Failure> {
        let rgb = |v: &[f64], option: &'static str, text: &str| match *v {
            [x] => Ok([x; 3]),
            [r, g, b] => Ok([r, g, b]),
            _ => Err(Failure::usage(
                option,
                format!("{text:?}: expected R,G,B or one value for grey"),
            )),
        };
        let sky = match &self.sky {
            Some(t) => Some(rgb(&numbers(t, "--sky")?, "--sky", t)?),
            None => None,
        };
        let sun = match &self.sun {
            Some(t) => {
                let v = numbers(t, "--sun")?;
                if v.len() < 3 {
                    return Err(Failure::usage(
                        "--sun",
                        format!("{t:?}: expected AZIMUTH,ELEVATION,R,G,B or AZIMUTH,ELEVATION,E"),
                    ));
                }
                Some(Sun {
                    azimuth_degrees: v[0],
                    elevation_degrees: v[1],
                    irradiance: rgb(&v[2..], "--sun", t)?,
                })
            }
            None => None,
        };
        let mut lights = Vec::new();
        for t in &self.point_light {
            let v = numbers(t, "--point-light")?;
            if v.len() < 4 {
                return Err(Failure::usage(
                    "--point-light",
                    format!("{t:?}: expected X,Y,Z,R,G,B or X,Y,Z,I"),
                ));
            }
            lights.push(PointLight {
                position: DVec3::new(v[0], v[1], v[2]),
                intensity: rgb(&v[3..], "--point-light", t)?,
                spot: None,
            });
        }
        for t in &self.spot_light {
            let v = numbers(t, "--spot-light")?;
            if v.len() < 9 {
                return Err(Failure::usage(
                    "--spot-light",
                    format!("{t:?}: expected X,Y,Z,DX,DY,DZ,INNER,OUTER,R,G,B (or one I)"),
                ));
            }
            let axis = DVec3::new(v[3], v[4], v[5]);
            if !(axis.length() > 0.0 && axis.is_finite()) {
                return Err(Failure::usage(
                    "--spot-light",
                    format!("{t:?}: the direction must not be zero"),
                ));
            }
            lights.push(PointLight {
                position: DVec3::new(v[0], v[1], v[2]),
                intensity: rgb(&v[8..], "--spot-light", t)?,
                spot: Some(Spot {
                    direction: axis.normalize(),
                    inner_degrees: v[6],
                    outer_degrees: v[7],
                }),
            });
        }
        let flags = LightSources {
            sky,
            sky_model: self.sky_model,
            sun,
            lights,
        };
        let file = match &self.lights {
            Some(path) => radiosity::io::lights::read(path)?,
            None => LightSources::default(),
        };
        Ok(flags.over(file).environment(self.up))
    }
}

/// A size in bytes: a number, optionally followed by K, M, G or T (binary: 1024-based, with or
/// without `iB` or `B`), e.g. `4G`, `512MiB`, `1.5g`, `1000000`.
pub fn parse_bytes(text: &str) -> std::result::Result<f64, String> {
    let t = text.trim();
    let digits = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == 'E'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(digits);
    let power = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 1,
        "m" | "mb" | "mib" => 2,
        "g" | "gb" | "gib" => 3,
        "t" | "tb" | "tib" => 4,
        other => return Err(format!("unknown unit '{other}' (use K, M, G or T)")),
    };
    let x: f64 = number
        .parse()
        .map_err(|_| format!("'{text}' is not a size such as 4G, 512M or 1000000"))?;
    if !(x > 0.0 && x.is_finite()) {
        return Err(format!("'{text}' is not a positive size"));
    }
    Ok(x * 1024f64.powi(power))
}

/// A duration in seconds: a number, optionally followed by s, m (minutes) or h, e.g. `90`,
/// `90s`, `2m`, `1.5h`.
pub fn parse_seconds(text: &str) -> std::result::Result<f64, String> {
    let t = text.trim();
    let digits = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(digits);
    let scale = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "s" | "sec" => 1.0,
        "m" | "min" => 60.0,
        "h" => 3600.0,
        other => return Err(format!("unknown unit '{other}' (use s, m or h)")),
    };
    let x: f64 = number
        .parse()
        .map_err(|_| format!("'{text}' is not a duration such as 90s, 2m or 1.5h"))?;
    if !(x > 0.0 && x.is_finite()) {
        return Err(format!("'{text}' is not a positive duration"));
    }
    Ok(x * scale)
}

/// `--output` of a command that writes one kind of file must end in `.ext` (any case), and
/// its directory must exist; checked before any work.
pub fn check_output(path: &std::path::Path, command: &str, ext: &str) -> Result<(), Failure> {
    if !path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case(ext))
    {
        return Err(Failure::usage(
            "--output",
            format!("{}: {command} writes .{ext} files", path.display()),
        ));
    }
    Ok(radiosity::io::check_output_dir(path)?)
}

impl BakeArgs {
    /// The output options (checked by the library).
    pub fn write_options(&self) -> Result<WriteOptions> {
        let options = WriteOptions {
            ascii: self.ascii,
            exposure: self.exposure,
        };
        options.validate()?;
        Ok(options)
    }
}

impl ViewArgs {
    /// The picture of `mesh` these options ask for at `exposure`, checked by the library
    /// ([`View::validate`]). The camera is [`render::camera_for`]'s: `--camera` if given, else
    /// the one the scene file carries, else the automatic camera, level about `--up`
    /// ([`render::best_framing`]).
    pub fn view(&self, mesh: &BakedMesh, exposure: f64, up: Up) -> Result<View, Failure> {
        let (width, height) = parse_size(&self.size)?;
        let given = self.camera.as_deref().map(Camera::parse).transpose()?;
        let view = View {
            camera: render::camera_for(mesh, given, up),
            width,
            height,
            spp: self.spp,
            flat: self.flat,
            false_colour: self.false_colour,
            exposure,
        };
        view.validate()?;
        Ok(view)
    }
}

impl ViewArgs {
    /// Checks these options before the long work: everything [`ViewArgs::view`] checks, on an
    /// empty mesh (its camera, never used, does not need one).
    pub fn check(&self, exposure: f64) -> Result<(), Failure> {
        self.view(&BakedMesh::default(), exposure, Up::Y).map(drop)
    }
}

/// `W`x`H` or `N` (square); the range is the library's ([`render::MAX_SIZE`]).
fn parse_size(text: &str) -> Result<(u32, u32), Failure> {
    let bad = || {
        Failure::usage(
            "--size",
            format!(
                "{text:?} is not WIDTHxHEIGHT or N (1..={})",
                render::MAX_SIZE
            ),
        )
    };
    let parse = |s: &str| s.trim().parse::<u32>().ok();
    match text.split_once(['x', 'X']) {
        Some((w, h)) => Ok((parse(w).ok_or_else(bad)?, parse(h).ok_or_else(bad)?)),
        None => parse(text).map(|n| (n, n)).ok_or_else(bad),
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use clap::{CommandFactory, Parser};

    use super::*;

    /// Parses `radiosity bake in.obj -o out.ply EXTRA…` into its arguments.
    fn bake(extra: &[&str]) -> BakeArgs {
        let mut args = vec!["radiosity", "bake", "in.obj", "-o", "out.ply"];
        args.extend_from_slice(extra);
        match Cli::try_parse_from(args).unwrap().command {
            Command::Bake(b) => b,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn sizes_in_bytes_and_binary_units() {
        let gib = 1024f64.powi(3);
        assert_eq!(parse_bytes("1000000"), Ok(1e6));
        assert_eq!(parse_bytes("4G"), Ok(4.0 * gib));
        assert_eq!(parse_bytes("4GiB"), Ok(4.0 * gib));
        assert_eq!(parse_bytes("1.5g"), Ok(1.5 * gib));
        assert_eq!(parse_bytes("512 MB"), Ok(512.0 * 1024.0 * 1024.0));
        for bad in ["", "G", "0", "-1G", "4Q", "1e999"] {
            assert!(parse_bytes(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn durations_in_seconds_minutes_and_hours() {
        assert_eq!(parse_seconds("90"), Ok(90.0));
        assert_eq!(parse_seconds("90s"), Ok(90.0));
        assert_eq!(parse_seconds("2m"), Ok(120.0));
        assert_eq!(parse_seconds("1.5h"), Ok(5400.0));
        assert_eq!(parse_seconds(" 3 min"), Ok(180.0));
        for bad in ["", "m", "0", "-1m", "2d", "1e3"] {
            assert!(parse_seconds(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_defaults_are_the_library_s() {
        let parsed = bake(&[]).scene.solve.settings().unwrap();
        // Settings has no PartialEq (it holds a path); its Debug form shows every field.
        assert_eq!(
            format!("{parsed:?}"),
            format!("{:?}", pipeline::Settings::default())
        );
    }

    #[test]
    fn every_option_reaches_its_setting() {
        let b = bake(&[
            "--max-edge",
            "7",
            "--crease",
            "12",
            "--two-sided",
            "--refine",
            "4",
            "--refine-threshold",
            "0.2",
            "--form-factors",
            "area",
            "--samples",
            "6",
            "--rays",
            "99",
            "--seed",
            "5",
            "--reciprocity",
            "--cache",
            "ff",
            "--solver",
            "jacobi",
            "--bounces",
            "3",
            "--tolerance",
            "1e-9",
            "--max-iterations",
            "77",
            "--max-passes",
            "9",
            "--omega",
            "1.3",
            "--exposure",
            "0.5",
            "--ascii",
        ]);
        let s = b.scene.solve.settings().unwrap();
        assert_eq!(s.max_edge, Some(7.0));
        assert_eq!((s.crease_degrees, s.two_sided), (12.0, true));
        assert_eq!((s.refine_rounds, s.refine_threshold), (4, 0.2));
        let f = s.form_factors;
        assert_eq!((f.estimator, f.samples, f.rays), (Estimator::Area, 6, 99));
        assert_eq!((f.seed, f.reciprocity), (5, true));
        assert_eq!(s.cache, Some(PathBuf::from("ff")));
        let v = s.solver;
        assert_eq!(
            (v.method, v.bounces, v.tolerance),
            (Method::Jacobi, 3, 1e-9)
        );
        assert_eq!((v.max_iterations, v.omega), (77, Some(1.3)));
        assert_eq!(s.hierarchical.max_passes, 9);
        let w = b.write_options().unwrap();
        assert_eq!((w.ascii, w.exposure), (true, Some(0.5)));
        // Ranges are the library's: its error, named as the flag by crate::failure.
        for flag in ["--samples", "--max-passes"] {
            let e = bake(&[flag, "0"]).scene.solve.settings().unwrap_err();
            assert_eq!(
                e.to_string(),
                format!("invalid value for {flag}: must be at least 1")
            );
        }
    }

    /// The option table under the README heading that starts with `heading`: each row's
    /// long flag, with the value name shown after it and the default column.
    fn readme_table(heading: &str) -> BTreeMap<String, (Option<String>, String)> {
        let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../README.md"))
            .expect("README.md beside cli/");
        let section = readme
            .split("\n## ")
            .find(|s| s.starts_with(heading))
            .unwrap_or_else(|| panic!("README has no section {heading:?}"));
        let mut rows = BTreeMap::new();
        for line in section.lines().filter(|l| l.starts_with("| `-")) {
            let cells: Vec<&str> = line.split(" | ").collect();
            let option = cells[0].trim_start_matches("| ").trim_matches('`');
            let long = option.split(", ").last().expect("a long flag in every row");
            let (flag, value) = match long.split_once(' ') {
                Some((f, v)) => (f, Some(v.replace("\\|", "|"))),
                None => (long, None),
            };
            rows.insert(flag.to_string(), (value, cells[1].to_string()));
        }
        assert!(!rows.is_empty(), "no option rows under {heading:?}");
        rows
    }

    /// Every `--flag` of `command` (with the global ones) and its clap definition.
    fn flags(command: &str) -> BTreeMap<String, clap::Arg> {
        let cli = Cli::command();
        let sub = cli.find_subcommand(command).unwrap().clone();
        sub.get_arguments()
            .chain(cli.get_arguments())
            .filter_map(|a| Some((format!("--{}", a.get_long()?), a.clone())))
            .filter(|(f, _)| f != "--help" && f != "--version")
            .collect()
    }

    /// The README's option tables and `--help` cannot drift apart: the same flags, the same
    /// value names (or, for a choice, the same values) and the same defaults.
    #[test]
    fn help_agrees_with_the_readme_tables() {
        let bake_table = readme_table("`radiosity bake");
        let render_table = readme_table("`radiosity render");
        let picture = |a: &clap::Arg| a.get_help_heading() == Some("Picture");
        let bake_flags = flags("bake");
        let render_flags = flags("render");
        // bake's table lists every bake option but the picture ones, which render's lists
        // (bake --png takes "the options of render").
        let expect: Vec<&String> = bake_flags
            .iter()
            .filter(|(_, a)| !picture(a))
            .map(|(f, _)| f)
            .collect();
        assert_eq!(
            bake_table.keys().collect::<Vec<_>>(),
            expect,
            "bake table vs --help"
        );
        let expect: Vec<&String> = render_flags
            .iter()
            .filter(|(_, a)| picture(a))
            .map(|(f, _)| f)
            .collect();
        assert_eq!(
            render_table.keys().collect::<Vec<_>>(),
            expect,
            "render table vs --help"
        );

        for (flag, (value, default)) in bake_table.iter().chain(&render_table) {
            let arg = &bake_flags.get(flag).or(render_flags.get(flag)).unwrap();
            let choices: Vec<String> = arg
                .get_possible_values()
                .iter()
                .map(|v| v.get_name().to_string())
                .collect();
            let shown = if arg.get_action().takes_values() {
                Some(if choices.is_empty() {
                    arg.get_value_names().unwrap_or_default().join(" ")
                } else {
                    choices.join("|")
                })
            } else {
                None
            };
            assert_eq!(value, &shown, "{flag}: README value vs --help");
            for d in arg.get_default_values() {
                let d = d.to_string_lossy();
                // Numbers compare as numbers (1e-6 = 0.000001), words as the README quotes them.
                let same = match d.parse::<f64>() {
                    Ok(x) => default
                        .trim_matches('`')
                        .parse::<f64>()
                        .is_ok_and(|y| y == x),
                    Err(_) => default.trim_matches('`') == d,
                };
                assert!(
                    same,
                    "{flag}: README default {default:?}, --help default {d:?}"
                );
            }
        }
    }
}
