//! The point-wise benchmark: what a viewer of a baked mesh sees, scored point by point against
//! path-traced radiance. Per-surface means are a weak measure (a path tracer gets a surface's
//! mean cheaply, and a mean hides a lit vertex bleeding into a shadow); this measures the
//! radiance a viewer is shown at points spread uniformly over the scene.
//!
//! 1. **Probes** ([`sample_points`]): `n` points drawn uniformly by area over the scene's
//!    triangles (fixed seed), leaving out emitters (their radiance is their own Le, no test of
//!    the solve) and buried points (the floor under a block, a cabinet's back flush against
//!    a wall: no viewer sees them; the bake's own test, as [`path_tracer`](super::path_tracer)
//!    applies it).
//! 2. **Reference** ([`trace_reference`]): outgoing radiance at each probe from the independent
//!    path tracer ([`super::path_tracer`], next-event estimation with MIS), paths added per
//!    probe until the standard error of its luminance is at most a target fraction of it
//!    (0.3 % by default) or a path limit is reached; the probes the score counts get a higher
//!    limit, so that they all reach the target. A traced reference can be continued where it
//!    stopped (to a stricter rule) with the same result as tracing it afresh.
//! 3. **What the bake displays** ([`Display::at`]): the baked mesh's radiance at each probe,
//!    interpolated barycentrically from its three vertices (what MeshLab shows with vertex
//!    colours) and the face's own solved value (flat shading).
//! 4. **Score** ([`score`]): over the probes brighter than a tenth of the probes' mean
//!    luminance (so a relative error is not dominated by near-black corners), the relative
//!    error of luminance e = (Y_shown − Y_ref) / Y_ref; reported as its root mean square,
//!    median and 90th percentile of |e|, and the mean e (a bias).
//!
//! [`trace_for`] gives the same tracer a time budget at the same points: the equal-time
//! comparison of a bake with path tracing, the tracer spending all of it on the probes;
//! [`trace_for_frame`] gives the probes only their share of a frame of more points, as a
//! renderer of one view would. Every estimate is keyed by (seed, probe, batch), so
//! a fixed seed gives the same numbers for any thread count.
//!
//! [`spread`] splits the error of several bakes made with other seeds and the same settings
//! into what a seed decides and what every seed shows.

use std::path::Path;
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::path_tracer::Tracer;
use crate::bake::BakedMesh;
use crate::color::{luminance, Rgb};
use crate::io::ReadBack;
use crate::sampling::Rng;
use crate::scene::lights::Environment;
use crate::scene::Scene;
use crate::visibility::{Visibility, NONE};
use crate::{Error, Result};

/// A point of the scene where the radiance is measured, with the reference found there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Probe {
    /// The scene triangle the point lies on.
    pub triangle: u32,
    /// Position, scene units.
    pub position: DVec3,
    /// Unit front normal of the triangle.
    pub normal: DVec3,
    /// Path-traced outgoing radiance, W·sr⁻¹·m⁻² per RGB channel (0 before tracing).
    pub radiance: Rgb,
    /// Standard error of the luminance of `radiance` (same units).
    pub std_error: f64,
    /// Paths traced.
    pub paths: u32,
}

/// How the reference is traced.
#[derive(Debug, Clone, Copy)]
pub struct ReferenceSettings {
    /// Stop adding paths to a probe once the standard error of its luminance is at most this
    /// fraction of the luminance.
    pub relative_error: f64,
    /// Paths per probe at least (so the error estimate itself is trustworthy) …
    pub min_paths: u32,
    /// … and at most (a probe in deep shadow may never reach `relative_error`) …
    pub max_paths: u32,
    /// … except a probe the score counts (brighter than a tenth of the probes' mean
    /// luminance, [`scored`]): it goes on to this many, so the reference's noise at the
    /// scored probes stays at `relative_error` (a room lit through a doorway has scored probes
    /// a tenth as bright as the mean, which need several million paths for 0.3 %).
    pub scored_max_paths: u32,
    pub seed: u64,
}

impl Default for ReferenceSettings {
    fn default() -> Self {
        ReferenceSettings {
            relative_error: 0.003,
            min_paths: 4096,
            max_paths: 1 << 20,
            scored_max_paths: 1 << 22,
            seed: 1,
        }
    }
}

/// Paths traced per probe between checks of the stopping rule.
const BATCH: u32 = 1024;

/// `n` probes drawn uniformly by area over the scene's non-emitting triangles, skipping buried
/// points, from `seed`. An error if the scene has no such area, or if most draws are buried.
pub fn sample_points(scene: &Scene, n: usize, seed: u64) -> Result<Vec<Probe>> {
    let tracer = Tracer::new(scene);
    let candidates: Vec<usize> = (0..scene.triangles.len())
        .filter(|&t| !scene.materials[scene.triangles[t].material as usize].is_emitter())
        .collect();
    let mut cdf = Vec::with_capacity(candidates.len());
    let mut total = 0.0;
    for &t in &candidates {
        total += tracer.area[t];
        cdf.push(total);
    }
    if total <= 0.0 {
        return Err(Error::Internal(
            "point-wise benchmark: the scene has no non-emitting area to sample".into(),
        ));
    }
    let mut rng = Rng::new(&[seed, 0x50_1E7]);
    let mut probes = Vec::with_capacity(n);
    let mut draws = 0usize;
    while probes.len() < n {
        draws += 1;
        if draws > 100 * n.max(1) {
            return Err(Error::Internal(format!(
                "point-wise benchmark: {draws} draws found only {} unburied points",
                probes.len()
            )));
        }
        let q = rng.next_f64() * total;
        let t = candidates[cdf.partition_point(|&c| c <= q).min(candidates.len() - 1)];
        let x = tracer.point(t, rng.next_f64(), rng.next_f64());
        if tracer.buried(t, x) {
            continue;
        }
        probes.push(Probe {
            triangle: t as u32,
            position: x,
            normal: tracer.normal[t],
            radiance: [0.0; 3],
            std_error: 0.0,
            paths: 0,
        });
    }
    Ok(probes)
}

/// Whether each probe is buried by [`sample_points`]' test (the bake's,
/// [`crate::visibility::Visibility::buried`]): stored probe sets drawn before a change of
/// that test are filtered by it, keeping their references.
pub fn buried(scene: &Scene, probes: &[Probe]) -> Vec<bool> {
    let tracer = Tracer::new(scene);
    probes
        .iter()
        .map(|p| tracer.buried(p.triangle as usize, p.position))
        .collect()
}

/// Running sums of one probe's path estimates.
#[derive(Clone, Copy, Default)]
struct Sums {
    rgb: Rgb,
    y: f64,
    y2: f64,
    paths: u32,
}

impl Sums {
    /// Adds `count` paths of probe `k`'s batch `batch`.
    fn add(&mut self, tracer: &Tracer, probe: &Probe, key: [u64; 3], count: u32) {
        let mut rng = Rng::new(&[key[0], key[1], key[2], 0x9A7_B0B]);
        for _ in 0..count {
            let (l, _) = tracer.radiance_out(probe.triangle as usize, probe.position, &mut rng);
            let y = luminance(l);
            for (s, v) in self.rgb.iter_mut().zip(l) {
                *s += v;
            }
            self.y += y;
            self.y2 += y * y;
        }
        self.paths += count;
    }

    /// The sums a traced probe stands for, rebuilt from its mean and standard error (zero
    /// for a probe not yet traced).
    fn of(probe: &Probe) -> Sums {
        let n = probe.paths as f64;
        if probe.paths == 0 {
            return Sums::default();
        }
        let mean = luminance(probe.radiance);
        // std_error² = var / n, var = (y2/n − mean²) · n/(n − 1).
        let var = probe.std_error * probe.std_error * n;
        let y2 = if probe.paths > 1 {
            n * (var * (n - 1.0) / n + mean * mean)
        } else {
            n * mean * mean
        };
        Sums {
            rgb: probe.radiance.map(|c| c * n),
            y: mean * n,
            y2,
            paths: probe.paths,
        }
    }

    fn mean(&self) -> Rgb {
        let n = self.paths.max(1) as f64;
        self.rgb.map(|s| s / n)
    }

    /// Standard error of the mean luminance (sample variance / n, square-rooted).
    fn std_error(&self) -> f64 {
        let n = self.paths as f64;
        if n < 2.0 {
            return f64::INFINITY;
        }
        let mean = self.y / n;
        let var = ((self.y2 / n - mean * mean) * n / (n - 1.0)).max(0.0);
        (var / n).sqrt()
    }
}

/// Path-traces the reference radiance at every probe (see [`ReferenceSettings`]): paths in
/// batches until the probe's standard error is at most `relative_error` of its luminance, or
/// `max_paths`; then the probes the score counts ([`scored`], by the luminance found) that
/// stopped at `max_paths` go on up to `scored_max_paths`. A probe already traced (`paths` > 0,
/// as read from a reference file) is continued where it stopped: its batches keep their keys,
/// so the result is the same as tracing it afresh under these settings (up to the rounding of
/// the sums rebuilt from the mean and the standard error), and one given no new path is left
/// as it was.
pub fn trace_reference(scene: &Scene, probes: &mut [Probe], settings: &ReferenceSettings) {
    trace_reference_lit(scene, &Environment::default(), probes, settings);
}

/// [`trace_reference`] with the lights outside the mesh `env` too (`--sky`, `--sun`, point
/// and spot lights; the path tracer's own estimates of them, [`super::path_tracer`]).
pub fn trace_reference_lit(
    scene: &Scene,
    env: &Environment,
    probes: &mut [Probe],
    settings: &ReferenceSettings,
) {
    let tracer = Tracer::new(scene).lit_by(env);
    let mut sums: Vec<Sums> = probes.iter().map(Sums::of).collect();
    let extend = |sums: &mut [Sums], limit: &(dyn Fn(usize) -> u32 + Sync)| {
        sums.par_iter_mut().enumerate().for_each(|(k, s)| {
            let cap = limit(k);
            loop {
                let y = s.y / s.paths.max(1) as f64;
                let done = s.paths >= settings.min_paths
                    && (y == 0.0 || s.std_error() <= settings.relative_error * y);
                if done || s.paths >= cap {
                    break;
                }
                let batch = (s.paths / BATCH) as u64;
                s.add(&tracer, &probes[k], [settings.seed, k as u64, batch], BATCH);
            }
        });
    };
    extend(&mut sums, &|_| settings.max_paths);
    let counted = scored(&sums.iter().map(Sums::mean).collect::<Vec<_>>());
    extend(&mut sums, &|k| {
        if counted[k] {
            settings.scored_max_paths.max(settings.max_paths)
        } else {
            settings.max_paths
        }
    });
    // A probe given no new path keeps its values bit for bit (not the rounding of the sums
    // rebuilt from them).
    for (probe, s) in probes
        .iter_mut()
        .zip(&sums)
        .filter(|(p, s)| s.paths != p.paths)
    {
        probe.radiance = s.mean();
        probe.std_error = s.std_error();
        probe.paths = s.paths;
    }
}

/// Which of the reference values the score counts: those brighter than a tenth of their mean
/// luminance (see [`score`]).
pub fn scored(reference: &[Rgb]) -> Vec<bool> {
    let mean_y =
        reference.iter().map(|&l| luminance(l)).sum::<f64>() / reference.len().max(1) as f64;
    reference
        .iter()
        .map(|&l| {
            let y = luminance(l);
            !y.is_nan() && y > 0.1 * mean_y
        })
        .collect()
}

/// The same path tracer given `seconds` (wall clock, its set-up included) at the probes:
/// rounds of a few paths at every probe until the time is spent. Returns each probe's
/// estimate and the paths each got. Seeds differ from the reference's, so its error is
/// independent of the reference's noise.
pub fn trace_for(scene: &Scene, probes: &[Probe], seconds: f64, seed: u64) -> (Vec<Rgb>, u32) {
    trace_for_lit(scene, &Environment::default(), probes, seconds, seed)
}

/// [`trace_for`] with the lights outside the mesh `env` too, as [`trace_reference_lit`].
pub fn trace_for_lit(
    scene: &Scene,
    env: &Environment,
    probes: &[Probe],
    seconds: f64,
    seed: u64,
) -> (Vec<Rgb>, u32) {
    trace_share(scene, env, probes, seconds, 1.0, seed)
}

/// The same path tracer given `seconds` (wall clock, its set-up included) for a frame of
/// `points` ≥ the probes' number, scored at the probes: after the set-up, the probes get
/// their share of the time, probes / `points` of it, as a frame's pixels would each get theirs
/// (a pixel's paths do not depend on the other pixels', so the probes are a sample of such a
/// frame). What a renderer of one view shows in the seconds a bake of every surface takes.
pub fn trace_for_frame(
    scene: &Scene,
    probes: &[Probe],
    seconds: f64,
    points: f64,
    seed: u64,
) -> (Vec<Rgb>, u32) {
    assert!(points >= probes.len() as f64, "a frame holds its probes");
    let share = probes.len() as f64 / points;
    trace_share(scene, &Environment::default(), probes, seconds, share, seed)
}

/// Rounds of a few paths at every probe until `share` of `seconds` after the tracer's set-up
/// is spent (the set-up counted in full).
fn trace_share(
    scene: &Scene,
    env: &Environment,
    probes: &[Probe],
    seconds: f64,
    share: f64,
    seed: u64,
) -> (Vec<Rgb>, u32) {
    const ROUND: u32 = 4;
    let start = Instant::now();
    let tracer = Tracer::new(scene).lit_by(env);
    let set_up = start.elapsed().as_secs_f64();
    let budget = set_up + share * (seconds - set_up).max(0.0);
    let mut sums = vec![Sums::default(); probes.len()];
    let mut round = 0u64;
    while round == 0 || start.elapsed().as_secs_f64() < budget {
        sums.par_iter_mut().enumerate().for_each(|(k, s)| {
            s.add(
                &tracer,
                &probes[k],
                [seed ^ 0xE0_A1, k as u64, round],
                ROUND,
            )
        });
        round += 1;
    }
    (
        sums.iter().map(Sums::mean).collect(),
        sums.first().map_or(0, |s| s.paths),
    )
}

/// A baked mesh as a viewer sees it: triangles with radiance at their vertices and a value per
/// face. Radiance in W·sr⁻¹·m⁻² per RGB channel.
pub struct Display {
    pub positions: Vec<DVec3>,
    pub faces: Vec<[u32; 3]>,
    pub vertex_radiance: Vec<Rgb>,
    pub face_radiance: Vec<Rgb>,
}

/// What a display shows at one probe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shown {
    /// Barycentric interpolation of the face's vertex radiance (smooth shading).
    pub interpolated: Rgb,
    /// The face's own radiance (flat shading).
    pub flat: Rgb,
}

impl Display {
    pub fn from_baked(mesh: &BakedMesh) -> Display {
        Display {
            positions: mesh.positions.iter().map(|&p| DVec3::from(p)).collect(),
            faces: mesh.faces.clone(),
            vertex_radiance: mesh.vertex_radiance.clone(),
            face_radiance: mesh.face_radiance.clone(),
        }
    }

    /// From a baked PLY read back ([`crate::io::ply::read`]); `path` names the file in the
    /// error when it carries no radiance (OBJ output keeps only 8-bit colours).
    pub fn from_read_back(back: &ReadBack, path: &Path) -> Result<Display> {
        let (Some(v), Some(f)) = (&back.vertex_radiance, &back.face_radiance) else {
            return Err(Error::Input {
                path: path.to_path_buf(),
                message: "has no radiance properties (score a .ply bake, not an .obj)".into(),
            });
        };
        let widen = |r: &[f32; 3]| r.map(|c| c as f64);
        Ok(Display {
            positions: back.positions.iter().map(|&p| DVec3::from(p)).collect(),
            faces: back.faces.clone(),
            vertex_radiance: v.iter().map(widen).collect(),
            face_radiance: f.iter().map(widen).collect(),
        })
    }

    /// What the display shows at each probe: the face found by a short ray from just in front
    /// of the probe (a millionth of the mesh's extent) back along its normal, hitting a face
    /// from its front (past a back side over the same positions). `None` where no face of the
    /// display covers the probe.
    pub fn at(&self, probes: &[Probe]) -> Vec<Option<Shown>> {
        let corners: Vec<[DVec3; 3]> = self
            .faces
            .iter()
            .map(|f| f.map(|v| self.positions[v as usize]))
            .collect();
        let vis = Visibility::build(&corners);
        let (lo, hi) = crate::geometry::bounds(self.positions.iter().copied());
        let delta = 1e-6 * (hi - lo).length().max(f64::MIN_POSITIVE);
        probes
            .par_iter()
            .map(|p| {
                let origin = p.position + delta * p.normal;
                let faces_probe = |f: u32| {
                    let [a, b, c] = corners[f as usize];
                    (b - a).cross(c - a).dot(p.normal) > 0.0
                };
                let mut hit = vis.closest_hit(origin, -p.normal, 2.0 * delta, NONE)?;
                if !faces_probe(hit.triangle) {
                    // A back side of its own (`--two-sided`, `--orient auto`) lies over the
                    // same positions as its front, as near: the front is the other one.
                    hit = vis.closest_hit(origin, -p.normal, 2.0 * delta, hit.triangle)?;
                    if !faces_probe(hit.triangle) {
                        return None;
                    }
                }
                let f = hit.triangle as usize;
                let [va, vb, vc] = self.faces[f].map(|v| self.vertex_radiance[v as usize]);
                let w = [1.0 - hit.u - hit.v, hit.u, hit.v];
                Some(Shown {
                    interpolated: std::array::from_fn(|ch| {
                        w[0] * va[ch] + w[1] * vb[ch] + w[2] * vc[ch]
                    }),
                    flat: self.face_radiance[f],
                })
            })
            .collect()
    }
}

/// Relative errors of luminance at the probes.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Score {
    /// Probes scored: brighter than a tenth of the probes' mean luminance.
    pub scored: usize,
    /// Of those, probes the display did not cover (scored as showing black: error −1).
    pub missing: usize,
    /// Root mean square of e = (Y_shown − Y_ref) / Y_ref.
    pub rms: f64,
    /// Median of |e|.
    pub median: f64,
    /// 90th percentile of |e| (nearest rank).
    pub p90: f64,
    /// Mean of e: the bias (> 0: shown too bright).
    pub bias: f64,
    /// Root mean square of the reference's own relative standard error at the scored probes:
    /// the floor under `rms` that the reference's noise sets.
    pub reference_noise: f64,
}

/// The relative errors e = (Y_shown − Y_ref) / Y_ref at the probes the score counts (see
/// [`scored`]; nothing shown counts as black, e = −1), the number of those shown nothing,
/// and the sum of the references' squared relative standard errors there.
fn errors(probes: &[Probe], shown: &[Option<Rgb>]) -> (Vec<f64>, usize, f64) {
    let counted = scored(&probes.iter().map(|p| p.radiance).collect::<Vec<_>>());
    errors_where(probes, shown, &counted)
}

/// [`errors`] at the probes `counted` picks.
fn errors_where(
    probes: &[Probe],
    shown: &[Option<Rgb>],
    counted: &[bool],
) -> (Vec<f64>, usize, f64) {
    assert_eq!(probes.len(), shown.len(), "one shown value per probe");
    let mut errors = Vec::new();
    let (mut missing, mut noise2) = (0, 0.0);
    for ((p, s), _) in probes.iter().zip(shown).zip(counted).filter(|(_, &c)| c) {
        let y_ref = luminance(p.radiance);
        let y = match s {
            Some(rgb) => luminance(*rgb),
            None => {
                missing += 1;
                0.0
            }
        };
        errors.push((y - y_ref) / y_ref);
        noise2 += (p.std_error / y_ref).powi(2);
    }
    (errors, missing, noise2)
}

/// Scores `shown` (one value per probe, `None` where nothing is shown) against the probes'
/// reference radiance (see the module documentation).
pub fn score(probes: &[Probe], shown: &[Option<Rgb>]) -> Score {
    summary(errors(probes, shown))
}

/// The [`Score`] of the relative errors, the probes shown nothing and the references' summed
/// squared relative standard errors ([`errors`]).
fn summary((errors, missing, noise2): (Vec<f64>, usize, f64)) -> Score {
    let n = errors.len();
    if n == 0 {
        return Score::default();
    }
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt();
    let bias = errors.iter().sum::<f64>() / n as f64;
    let mut abs: Vec<f64> = errors.iter().map(|e| e.abs()).collect();
    abs.sort_by(f64::total_cmp);
    let rank = |q: f64| abs[((q * n as f64).ceil() as usize).clamp(1, n) - 1];
    Score {
        scored: n,
        missing,
        rms,
        median: rank(0.5),
        p90: rank(0.9),
        bias,
        reference_noise: (noise2 / n as f64).sqrt(),
    }
}

/// A class of probes ([`by_class`]): by where they face, or by how bright they are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    /// The normal within about 25° of up (cos > [`Class::FACING`]): floors, table tops.
    FacingUp,
    /// The normal within about 25° of down: ceilings, undersides.
    FacingDown,
    /// Neither: walls, furniture's sides.
    Sideways,
    /// The reference's luminance above all probes' mean.
    Bright,
    /// Between 0.3 × the mean and the mean.
    Mid,
    /// At most 0.3 × the mean (and above the tenth of it that [`score`] counts).
    Dim,
}

impl Class {
    /// Every class: the three facings, then the three brightnesses.
    pub const ALL: [Class; 6] = [
        Class::FacingUp,
        Class::FacingDown,
        Class::Sideways,
        Class::Bright,
        Class::Mid,
        Class::Dim,
    ];

    /// The cosine between the normal and up (or down) beyond which a probe faces up (down):
    /// a floor's or a gently sloped roof's probe faces up, a wall's sideways.
    pub const FACING: f64 = 0.9;

    /// Its name in a table.
    pub fn name(self) -> &'static str {
        match self {
            Class::FacingUp => "facing up",
            Class::FacingDown => "facing down",
            Class::Sideways => "sideways",
            Class::Bright => "bright",
            Class::Mid => "mid",
            Class::Dim => "dim",
        }
    }

    /// Whether a probe whose normal has the cosine `facing` with up, and whose reference has
    /// the luminance `y`, is of this class, the probes' mean luminance being `mean_y`.
    fn holds(self, facing: f64, y: f64, mean_y: f64) -> bool {
        match self {
            Class::FacingUp => facing > Class::FACING,
            Class::FacingDown => facing < -Class::FACING,
            Class::Sideways => facing.abs() <= Class::FACING,
            Class::Bright => y > mean_y,
            Class::Mid => y > 0.3 * mean_y && y <= mean_y,
            Class::Dim => y <= 0.3 * mean_y,
        }
    }
}

/// The score of one class of probes ([`by_class`]).
#[derive(Debug, Clone)]
pub struct ClassScore {
    /// Which probes.
    pub class: Class,
    /// Its score, of the probes of the class that [`score`] counts (the same threshold: a
    /// tenth of all probes' mean).
    pub score: Score,
    /// Its share of the squared error summed over all counted probes (the classes of one
    /// kind, facing or brightness, add up to 1).
    pub share: f64,
}

/// The score broken down by where the probes face (relative to the unit vector `up`) and
/// how bright their reference is ([`Class`]): where a bake's error lies (the floor, ceilings
/// and undersides, walls and furniture's sides; lit or dim surfaces), each class with its
/// share of the squared error ([`ClassScore`]).
pub fn by_class(probes: &[Probe], shown: &[Option<Rgb>], up: DVec3) -> Vec<ClassScore> {
    let reference: Vec<Rgb> = probes.iter().map(|p| p.radiance).collect();
    let counted = scored(&reference);
    let mean_y =
        reference.iter().map(|&l| luminance(l)).sum::<f64>() / reference.len().max(1) as f64;
    let squared = |e: &[f64]| e.iter().map(|e| e * e).sum::<f64>();
    let total = squared(&errors_where(probes, shown, &counted).0);
    Class::ALL
        .into_iter()
        .map(|class| {
            let picked: Vec<bool> = (probes.iter().zip(&counted))
                .map(|(p, &c)| c && class.holds(p.normal.dot(up), luminance(p.radiance), mean_y))
                .collect();
            let found = errors_where(probes, shown, &picked);
            let share = if total > 0.0 {
                squared(&found.0) / total
            } else {
                0.0
            };
            ClassScore {
                class,
                score: summary(found),
                share,
            }
        })
        .collect()
}

/// How the errors of K bakes of one scene, made with the same settings and different seeds,
/// split at the probes ([`spread`]). With e_k the relative error of bake k at a probe and ē
/// their mean there: varying² is the sample variance Σ_k (e_k − ē)² / (K − 1), pooled (its
/// mean over the probes), and shared² the mean of ē² less what of varying² is left in a
/// mean of K, varying² / K. For one bake, shared² + varying² is about its RMS²: the error a
/// seed decides (Monte Carlo noise, and which edges the display's refinement splits) and
/// the error every seed shows (the gather's bias, the display's resolution where every seed
/// refines alike). Relative, as [`Score`]'s.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Spread {
    /// Bakes compared.
    pub bakes: usize,
    /// Probes scored (as [`Score::scored`]).
    pub scored: usize,
    /// RMS of a bake's departure from the bakes' mean at a probe (the pooled standard
    /// deviation).
    pub varying: f64,
    /// RMS of the error the bakes share (0 where the mean's error is all leftover variation).
    pub shared: f64,
}

/// [`Spread`] of the `bakes` (each one shown value per probe, as [`score`] takes), or `None`
/// for fewer than two.
pub fn spread(probes: &[Probe], bakes: &[Vec<Option<Rgb>>]) -> Option<Spread> {
    let k = bakes.len();
    if k < 2 {
        return None;
    }
    let errors: Vec<Vec<f64>> = bakes.iter().map(|b| errors(probes, b).0).collect();
    let n = errors[0].len();
    if n == 0 {
        return Some(Spread {
            bakes: k,
            ..Spread::default()
        });
    }
    let (mut variance, mut mean2) = (0.0, 0.0);
    for i in 0..n {
        let mean = errors.iter().map(|e| e[i]).sum::<f64>() / k as f64;
        variance += errors.iter().map(|e| (e[i] - mean).powi(2)).sum::<f64>() / (k - 1) as f64;
        mean2 += mean * mean;
    }
    let (variance, mean2) = (variance / n as f64, mean2 / n as f64);
    Some(Spread {
        bakes: k,
        scored: n,
        varying: variance.sqrt(),
        shared: (mean2 - variance / k as f64).max(0.0).sqrt(),
    })
}

/// Columns of the probes' CSV.
const CSV_HEADER: &str = "triangle,x,y,z,nx,ny,nz,r,g,b,std_error,paths";

/// Writes probes as CSV (full `f64` precision), atomically.
pub fn write_csv(path: &Path, probes: &[Probe]) -> Result<()> {
    let mut text = String::from(CSV_HEADER);
    text.push('\n');
    for p in probes {
        let (x, n, r) = (p.position, p.normal, p.radiance);
        text.push_str(&format!(
            "{},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{}\n",
            p.triangle, x.x, x.y, x.z, n.x, n.y, n.z, r[0], r[1], r[2], p.std_error, p.paths
        ));
    }
    crate::io::write_atomic(path, text.as_bytes())
}

/// Reads probes written by [`write_csv`]; errors name the file and line.
pub fn read_csv(path: &Path) -> Result<Vec<Probe>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let bad = |line: usize, message: String| Error::Parse {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h.trim() == CSV_HEADER => {}
        _ => return Err(bad(1, format!("expected the header `{CSV_HEADER}`"))),
    }
    let mut probes = Vec::new();
    for (i, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != 12 {
            return Err(bad(i + 1, format!("{} fields, expected 12", fields.len())));
        }
        let num = |k: usize| -> Result<f64> {
            fields[k]
                .trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    bad(
                        i + 1,
                        format!("field {} `{}` is not a number", k + 1, fields[k]),
                    )
                })
        };
        let int = |k: usize| -> Result<u32> {
            fields[k].trim().parse::<u32>().map_err(|_| {
                bad(
                    i + 1,
                    format!("field {} `{}` is not a count", k + 1, fields[k]),
                )
            })
        };
        probes.push(Probe {
            triangle: int(0)?,
            position: DVec3::new(num(1)?, num(2)?, num(3)?),
            normal: DVec3::new(num(4)?, num(5)?, num(6)?),
            radiance: [num(7)?, num(8)?, num(9)?],
            std_error: num(10)?,
            paths: int(11)?,
        });
    }
    Ok(probes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::kernel::point_to_polygon;
    use crate::validation::scenes;

    /// The scene's own triangles as a display, with radiance `field` at each vertex and at
    /// each face's centroid.
    fn display_of(scene: &Scene, field: impl Fn(DVec3) -> Rgb) -> Display {
        let faces: Vec<[u32; 3]> = scene.triangles.iter().map(|t| t.vertices).collect();
        Display {
            vertex_radiance: scene.positions.iter().map(|&p| field(p)).collect(),
            face_radiance: faces
                .iter()
                .map(|f| {
                    field(
                        f.iter()
                            .map(|&v| scene.positions[v as usize])
                            .sum::<DVec3>()
                            / 3.0,
                    )
                })
                .collect(),
            positions: scene.positions.clone(),
            faces,
        }
    }

    #[test]
    fn display_interpolates_a_linear_field_exactly() {
        // Barycentric interpolation reproduces a linear field, so what is shown at every probe
        // equals the field there: this checks that each probe finds its own face and the
        // barycentrics of the hit (a wrong face or swapped weights would be off by O(1)).
        let scene = scenes::perpendicular_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        let probes = sample_points(&scene, 300, 5).unwrap();
        let field = |p: DVec3| [1.0 + p.x, 2.0 + 0.5 * p.y - 0.25 * p.z, 3.0 + p.z];
        let shown = display_of(&scene, field).at(&probes);
        for (p, s) in probes.iter().zip(&shown) {
            let s = s.expect("every probe lies on a face of the display");
            let want = field(p.position);
            for ch in 0..3 {
                // The hit's barycentrics come from the BVH's f32 triangle test: ~1e-7 relative,
                // so 1e-6 of these values of order 1 (a wrong face: off by 0.1 or more).
                assert!(
                    (s.interpolated[ch] - want[ch]).abs() < 1e-6,
                    "{s:?} vs {want:?}"
                );
            }
        }
    }

    #[test]
    fn a_back_side_over_the_same_positions_does_not_hide_the_front() {
        // Each face gets a back side over the same positions, reversed and cut at its centroid
        // into three (a bake's back sides, `--orient auto` or `--two-sided`, are refined apart
        // from their fronts), showing another value: both lie at the probe, the ray meets
        // either first, and each probe, sampled on a front, must show the front's value
        // (before, the probes whose ray met the back first showed nothing).
        let scene = scenes::perpendicular_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        let probes = sample_points(&scene, 300, 7).unwrap();
        let (front, back) = ([0.25; 3], [4.0; 3]);
        let fronts = display_of(&scene, |_| front);
        // The backs first: where two hits tie, the lower index wins.
        let mut display = Display {
            positions: fronts.positions.clone(),
            faces: Vec::new(),
            vertex_radiance: vec![back; fronts.positions.len()],
            face_radiance: Vec::new(),
        };
        for f in &fronts.faces {
            let c = display.positions.len() as u32;
            let centroid = f
                .iter()
                .map(|&v| fronts.positions[v as usize])
                .sum::<DVec3>()
                / 3.0;
            display.positions.push(centroid);
            display.vertex_radiance.push(back);
            for k in 0..3 {
                display.faces.push([f[(k + 1) % 3], f[k], c]);
                display.face_radiance.push(back);
            }
        }
        let m = display.positions.len() as u32;
        display.positions.extend(&fronts.positions);
        display.vertex_radiance.extend(&fronts.vertex_radiance);
        display
            .faces
            .extend(fronts.faces.iter().map(|f| f.map(|v| v + m)));
        display.face_radiance.extend(&fronts.face_radiance);
        for s in display.at(&probes) {
            assert_eq!(s.map(|s| s.interpolated), Some(front));
        }
    }

    #[test]
    fn a_frame_of_many_points_gives_the_probes_their_share_of_the_time() {
        // Half a second for the probes alone runs thousands of rounds on two plates; as a
        // frame of 10⁶ points the probes get 50/10⁶ of it after the set-up (25 µs: one round,
        // or a few). Each returns finite, non-negative radiance at every probe.
        let scene = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        let probes = sample_points(&scene, 50, 3).unwrap();
        let (alone, alone_paths) = trace_for(&scene, &probes, 0.5, 1);
        let (frame, frame_paths) = trace_for_frame(&scene, &probes, 0.5, 1e6, 1);
        assert!(
            10 * frame_paths < alone_paths,
            "{frame_paths} paths a probe in a frame, {alone_paths} alone"
        );
        for l in alone.iter().chain(&frame) {
            assert!(l.iter().all(|c| c.is_finite() && *c >= 0.0), "{l:?}");
        }
    }

    #[test]
    fn constant_radiance_scores_zero_and_an_empty_display_scores_missing() {
        // Probes whose reference is a constant, and a display showing exactly that: 0 error;
        // a display with no faces shows nothing at any probe.
        let scene = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        let l = 0.25;
        let mut probes = sample_points(&scene, 200, 2).unwrap();
        for p in &mut probes {
            p.radiance = [l; 3];
        }
        let shown: Vec<Option<Rgb>> = display_of(&scene, |_| [l; 3])
            .at(&probes)
            .iter()
            .map(|s| s.map(|s| s.interpolated))
            .collect();
        let s = score(&probes, &shown);
        assert_eq!((s.scored, s.missing), (200, 0));
        assert!(s.rms < 1e-12 && s.p90 < 1e-12, "{s:?}");
        let empty = Display {
            positions: vec![],
            faces: vec![],
            vertex_radiance: vec![],
            face_radiance: vec![],
        };
        let none: Vec<Option<Rgb>> = empty
            .at(&probes)
            .iter()
            .map(|s| s.map(|s| s.flat))
            .collect();
        let s = score(&probes, &none);
        assert_eq!(s.missing, 200);
        assert!((s.rms - 1.0).abs() < 1e-12 && (s.bias + 1.0).abs() < 1e-12);
    }

    /// A probe of luminance `y` (grey), its reference exact.
    fn probe(y: f64) -> Probe {
        Probe {
            triangle: 0,
            position: DVec3::ZERO,
            normal: DVec3::Z,
            radiance: [y; 3],
            std_error: 0.0,
            paths: 1,
        }
    }

    #[test]
    fn spread_splits_known_shared_and_varying_errors() {
        // Two bakes whose errors at each group of four probes are s ± d with every pair of
        // signs of d (shared s, alternating in sign between groups; d the seed's): the pooled
        // sample variance of the pairs is d² exactly, and their means' mean square s² + d²/2,
        // so varying = d and shared = s. A dark probe (left out) and one bake alone change
        // nothing or give nothing.
        let (s, d) = (0.03, 0.02);
        let mut probes = Vec::new();
        let mut bakes = vec![Vec::new(), Vec::new()];
        for group in 0..5 {
            let shared = if group % 2 == 0 { s } else { -s };
            for (a, b) in [(d, d), (d, -d), (-d, d), (-d, -d)] {
                probes.push(probe(1.0));
                bakes[0].push(Some([1.0 + shared + a; 3]));
                bakes[1].push(Some([1.0 + shared + b; 3]));
            }
        }
        probes.push(probe(0.01));
        bakes[0].push(Some([3.0; 3]));
        bakes[1].push(None);
        let split = spread(&probes, &bakes).expect("two bakes");
        assert_eq!((split.bakes, split.scored), (2, 20));
        assert!((split.varying - d).abs() < 1e-12, "{split:?}");
        assert!((split.shared - s).abs() < 1e-12, "{split:?}");
        // Each bake's own RMS² is s² + d² here: what the two parts add up to.
        for b in &bakes {
            let rms = score(&probes, b).rms;
            assert!((rms * rms - s * s - d * d).abs() < 1e-12, "{rms}");
        }
        assert!(spread(&probes, &bakes[..1]).is_none());
    }

    #[test]
    fn the_score_by_class_splits_the_squared_error() {
        // Four probes facing up (luminance 1, errors +2 %), four facing down (luminance 0.15,
        // errors −4 %), two sideways (luminance 1, errors 0 and +6 %) and a dark one (left
        // out): mean luminance 0.60 over the 11, so the up and sideways ones are bright, the
        // down ones dim (below 0.18). Squared errors 16, 64 and 36 (×10⁻⁴) of 116.
        let mut probes = Vec::new();
        let mut shown = Vec::new();
        let mut add = |y: f64, normal: DVec3, e: f64| {
            probes.push(Probe { normal, ..probe(y) });
            shown.push(Some([y * (1.0 + e); 3]));
        };
        (0..4).for_each(|_| add(1.0, DVec3::Z, 0.02));
        (0..4).for_each(|_| add(0.15, -DVec3::Z, -0.04));
        add(1.0, DVec3::X, 0.0);
        add(1.0, DVec3::Y, 0.06);
        add(0.01, DVec3::Z, 5.0);
        let classes = by_class(&probes, &shown, DVec3::Z);
        let get = |class: Class| classes.iter().find(|c| c.class == class).unwrap();
        let (up, down, side) = (
            get(Class::FacingUp),
            get(Class::FacingDown),
            get(Class::Sideways),
        );
        assert_eq!(
            (up.score.scored, down.score.scored, side.score.scored),
            (4, 4, 2)
        );
        assert!((up.score.rms - 0.02).abs() < 1e-12 && (up.share - 16.0 / 116.0).abs() < 1e-12);
        assert!(
            (down.score.bias + 0.04).abs() < 1e-12 && (down.share - 64.0 / 116.0).abs() < 1e-12
        );
        assert!((side.score.rms - 0.0018f64.sqrt()).abs() < 1e-12);
        let (bright, mid, dim) = (get(Class::Bright), get(Class::Mid), get(Class::Dim));
        assert_eq!(
            (bright.score.scored, mid.score.scored, dim.score.scored),
            (6, 0, 4)
        );
        assert!((bright.share + mid.share + dim.share - 1.0).abs() < 1e-12);
        assert!((dim.share - down.share).abs() < 1e-12);
    }

    #[test]
    fn score_statistics_on_known_errors() {
        // Ten probes of luminance 1 shown with errors 0, 1, …, 9 % (one probe at 0.05 of the
        // mean is dark and left out): RMS √(Σk²/10) %, median 4 %, 90th percentile 8 %.
        let mut probes: Vec<Probe> = (0..10).map(|_| probe(1.0)).collect();
        let mut shown: Vec<Option<Rgb>> =
            (0..10).map(|k| Some([1.0 + 0.01 * k as f64; 3])).collect();
        probes.push(probe(0.05));
        shown.push(Some([7.0; 3]));
        let s = score(&probes, &shown);
        assert_eq!(s.scored, 10);
        let rms = ((0..10).map(|k| (k * k) as f64).sum::<f64>() / 10.0).sqrt() / 100.0;
        assert!((s.rms - rms).abs() < 1e-12, "{s:?}");
        assert!(
            (s.median - 0.04).abs() < 1e-12 && (s.p90 - 0.08).abs() < 1e-12,
            "{s:?}"
        );
        assert!((s.bias - 0.045).abs() < 1e-12, "{s:?}");
    }

    #[test]
    fn scored_probes_go_past_the_path_limit_and_a_reference_continues_where_it_stopped() {
        // The plates again: every probe is on the lit receiver, so every one is scored. A
        // path limit of one batch stops them all short of 1 % (the receiver's estimates
        // spread by tens of per cent a path); the scored probes' own limit lets them reach it.
        let scene = scenes::parallel_plates(1.0, 1.0, 0.5, 0.5, 2.0).unwrap();
        let strict = ReferenceSettings {
            relative_error: 0.01,
            min_paths: 1024,
            max_paths: 1024,
            scored_max_paths: 1 << 18,
            seed: 7,
        };
        let mut afresh = sample_points(&scene, 6, 5).unwrap();
        trace_reference(&scene, &mut afresh, &strict);
        for p in &afresh {
            assert!(p.paths > 1024, "{p:?}");
            assert!(p.std_error <= 0.01 * luminance(p.radiance), "{p:?}");
        }
        // Traced first to a laxer rule (3 %), then continued to the strict one: the same
        // paths, the same estimates up to the rounding of the rebuilt sums.
        let mut continued = sample_points(&scene, 6, 5).unwrap();
        let lax = ReferenceSettings {
            relative_error: 0.03,
            ..strict
        };
        trace_reference(&scene, &mut continued, &lax);
        assert!(continued
            .iter()
            .zip(&afresh)
            .all(|(c, a)| c.paths < a.paths));
        trace_reference(&scene, &mut continued, &strict);
        for (c, a) in continued.iter().zip(&afresh) {
            assert_eq!(c.paths, a.paths);
            for (x, y) in c.radiance.iter().zip(a.radiance) {
                assert!((x - y).abs() <= 1e-12 * y, "{c:?} vs {a:?}");
            }
            assert!((c.std_error - a.std_error).abs() <= 1e-9 * a.std_error);
        }
        // Continued again under the rule it already meets, nothing moves, not even a bit.
        let done = continued.clone();
        trace_reference(&scene, &mut continued, &strict);
        assert_eq!(continued, done);
    }

    #[test]
    fn reference_matches_the_exact_point_form_factor() {
        // Parallel plates, the source black (ρ = 0): the receiver's radiance at x is
        // ρ·Le·F(x → source) exactly, F the contour integral. The tracer's only error is its
        // noise, and it stops at the asked relative standard error (2 % here, for speed).
        let (rho, le) = (0.5, 2.0);
        let scene = scenes::parallel_plates(1.0, 1.0, 0.5, rho, le).unwrap();
        let source = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let mut probes = sample_points(&scene, 12, 3).unwrap();
        let settings = ReferenceSettings {
            relative_error: 0.02,
            min_paths: 1024,
            max_paths: 1 << 16,
            scored_max_paths: 1 << 16,
            seed: 4,
        };
        trace_reference(&scene, &mut probes, &settings);
        for p in &probes {
            assert!(
                (p.position.z - 0.5).abs() < 1e-12,
                "probes lie on the receiver only"
            );
            let expected = rho * le * point_to_polygon(p.position, p.normal, &source);
            let y = luminance(p.radiance);
            assert!(p.std_error <= 0.02 * y, "{p:?}");
            assert!(
                (y - expected).abs() < 5.0 * p.std_error,
                "{p:?} vs {expected}"
            );
        }
        // Determinism: the same seed, the same bits.
        let mut again = sample_points(&scene, 12, 3).unwrap();
        trace_reference(&scene, &mut again, &settings);
        assert_eq!(again, probes);
    }

    #[test]
    fn reference_under_sky_sun_and_lamp_matches_their_closed_forms() {
        // A plate (ρ = 0.5) under a uniform sky, the sun at the zenith and a point lamp, a
        // black square hung above it facing down: one bounce, so at a plate point x the
        // radiance is exactly ρ·(L_sky·(1 − F(x → square)) + E_sun·V_sun/π + I·cosθ·V/(π r²)),
        // V 0 or 1 by where x lies under the square. The tracer's only error is its noise (the
        // sky's share that meets the square): within 5 standard errors of the asked 1 %.
        use crate::scene::{PointLight, SceneBuilder, Sun, Up};
        use glam::dvec3;
        use std::f64::consts::PI;
        let (rho, sky, sun, lamp) = (0.5, 1.0, 3.0, 2.0);
        let light = dvec3(0.9, 0.5, 1.5);
        let mut b = SceneBuilder::new();
        let grey = b.material("grey", [rho; 3], [0.0; 3]);
        let black = b.material("black", [0.0; 3], [0.0; 3]);
        let (lo, hi, h) = (0.25, 0.75, 0.5);
        b.quad(
            [
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ]
            .map(DVec3::from),
            grey,
        );
        let square = [[lo, lo, h], [lo, hi, h], [hi, hi, h], [hi, lo, h]].map(DVec3::from);
        b.quad(square, black);
        let scene = b.build().unwrap();
        let env = Environment {
            sky: [sky; 3],
            sun: Some(Sun {
                azimuth_degrees: 0.0,
                elevation_degrees: 90.0,
                irradiance: [sun; 3],
            }),
            lights: vec![PointLight {
                position: light,
                intensity: [lamp; 3],
                spot: None,
            }],
            up: Up::Z,
            ..Environment::default()
        };
        let under = |p: DVec3, margin: f64| {
            let inside = |v: f64| v > lo + margin && v < hi - margin;
            let outside = |v: f64| v < lo - margin || v > hi + margin;
            if inside(p.x) && inside(p.y) {
                Some(true)
            } else if outside(p.x) || outside(p.y) {
                Some(false)
            } else {
                None // within the margin of the square's outline
            }
        };
        let mut probes: Vec<Probe> = sample_points(&scene, 60, 5)
            .unwrap()
            .into_iter()
            .filter(|p| p.position.z == 0.0)
            .collect();
        let settings = ReferenceSettings {
            relative_error: 0.01,
            min_paths: 1024,
            max_paths: 1 << 16,
            scored_max_paths: 1 << 16,
            seed: 6,
        };
        trace_reference_lit(&scene, &env, &mut probes, &settings);
        let mut checked = [0; 2];
        for p in &probes {
            let x = p.position;
            // The sun's disc is 0.53° wide: its penumbra 5 mm from the outline at most.
            let Some(sun_hidden) = under(x, 5e-3) else {
                continue;
            };
            // The lamp's ray crosses the square's plane a third of the way up.
            let Some(lamp_hidden) = under(x + (light - x) * (h / light.z), 1e-6) else {
                continue;
            };
            let to = light - x;
            let lamp_part = if lamp_hidden {
                0.0
            } else {
                lamp * to.z / to.length() / (PI * to.length_squared())
            };
            let f = point_to_polygon(x, DVec3::Z, &square).abs();
            let sun_part = if sun_hidden { 0.0 } else { sun / PI };
            let expected = rho * (sky * (1.0 - f) + sun_part + lamp_part);
            let y = luminance(p.radiance);
            assert!(
                (y - expected).abs() <= 5.0 * p.std_error + 1e-9 * expected,
                "{p:?}: {y} against {expected}"
            );
            checked[usize::from(sun_hidden)] += 1;
        }
        assert!(checked[0] >= 5 && checked[1] >= 5, "{checked:?}");
    }

    #[test]
    fn csv_round_trips_and_errors_name_the_line() {
        let scene = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        let mut probes = sample_points(&scene, 5, 9).unwrap();
        probes[2].radiance = [0.1, 0.2, 0.3];
        let dir = std::env::temp_dir().join(format!("radiosity-probes-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("probes.csv");
        write_csv(&path, &probes).unwrap();
        assert_eq!(read_csv(&path).unwrap(), probes);
        // The red radiance of the third probe (line 4) made unreadable.
        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        let mut fields: Vec<&str> = lines[3].split(',').collect();
        fields[7] = "zero";
        lines[3] = fields.join(",");
        std::fs::write(&path, lines.join("\n")).unwrap();
        let err = read_csv(&path).unwrap_err().to_string();
        assert!(
            err.contains("probes.csv:4:") && err.contains("`zero`"),
            "{err}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
