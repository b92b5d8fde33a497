//! An independent reference for scenes without a closed form: the mean radiance of each
//! surface by Monte Carlo path tracing of the scene's own triangles. No patches, no form
//! factors, no linear solve — only the rendering equation sampled directly — so its answer
//! shares none of the radiosity pipeline's discretisation and can judge it (the Cornell box's
//! self-convergence says how much a finer run changes; this says how far from the truth).
//!
//! For a Lambertian scene the radiance leaving a point x of a surface with reflectance ρ is
//! (Kajiya 1986, written for radiance)
//!
//! L(x) = Le(x) + ρ(x) ∫_{A_emit} Le(y) G(x, y) V(x, y) dA_y + ρ(x) ∫_Ω (cosθ/π) L_r(h(x, ω)) dω,
//!
//! with G = cosθ_x cosθ_y / (π r²), h(x, ω) the first surface hit from x along ω, and L_r the
//! reflected (non-emitted) part of the radiance leaving it. Emitted light reaching x is
//! sampled two ways and the two combined by multiple importance sampling with the balance
//! heuristic (Veach & Guibas 1995), so neither a small distant light nor a large nearby one
//! gives runaway variance: a point on an emitter chosen by emitted power (next-event
//! estimation, with a shadow ray), and the cosine-weighted direction (Malley's method, whose
//! density cosθ/π cancels the integrand's) that also continues the path, recursively. Paths
//! end at a miss, at the back of a one-sided surface, or by Russian roulette (survival
//! probability = the path weight's largest channel, capped at 1, after three bounces), which
//! keeps the estimator unbiased (Arvo & Kirk 1990; pbrt-v4 `PathIntegrator`).
//!
//! The lights outside the mesh ([`Environment`]: `--sky`, `--sun`, point and spot lights),
//! where given (`pointwise::trace_reference_lit`), are traced the same way and just as independently of the
//! bake's estimates of them ([`crate::light::outside`]): a path that leaves the scene brings
//! the sky's radiance in its direction (none below the horizon), and at every path vertex one
//! shadow ray goes to a uniform point of the sun's disc (E_sun cosθ V / π, the disc's
//! [`SUN_DIAMETER_DEGREES`]) and one to each point light (I · falloff · cosθ V / (π r²), the
//! spot's falloff as glTF gives it). The sun and the lamps are found by those rays only (a
//! direction sample never meets a point, and the sky's radiance leaves the disc out), the
//! sky by the direction samples only, so nothing is counted twice.
//!
//! The mean over a surface is the average of L at points drawn uniformly by area
//! (stratified); points buried in contact geometry ([`Visibility::buried`]'s test: a
//! normal ray that first meets a back face, or a surface lying face to face) see nothing
//! and count as dark, so [`SurfaceMean::mean`] is the mean over the whole surface (what its
//! area emits and reflects in total) and [`SurfaceMean::visible_mean`] the mean over its visible part. Each
//! comes with its standard error. Facet normals only: this is a reference for flat scenes.

use glam::DVec3;
use rayon::prelude::*;

use crate::color::Rgb;
use crate::geometry::orthonormal_basis;
use crate::light::outside::SUN_DIAMETER_DEGREES;
use crate::sampling::{malley, triangle_barycentrics, Rng};
use crate::scene::lights::{Environment, Toward};
use crate::scene::Scene;
use crate::visibility::Visibility;

/// Settings of the path tracer.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// Paths per surface (each from its own point on the surface).
    pub paths_per_surface: u32,
    /// Seed: the same seed gives the same result for any thread count.
    pub seed: u64,
}

/// One surface's estimate. Radiance in W·sr⁻¹·m⁻² per RGB channel.
#[derive(Debug, Clone, Copy, Default)]
pub struct SurfaceMean {
    /// Area of the surface's triangles, scene units².
    pub area: f64,
    /// Fraction of the sampled points that are not buried in contact geometry.
    pub visible_fraction: f64,
    /// Mean radiance over the whole surface (buried parts count as dark).
    pub mean: Rgb,
    /// Standard error of `mean` (one standard deviation of the estimate).
    pub std_error: Rgb,
    /// Mean radiance over the visible part: `mean / visible_fraction` (0 if nothing is visible).
    pub visible_mean: Rgb,
}

/// Surfaces of a scene: triangles with the same material on the same plane (their normals
/// and offsets equal to 1e-6 of the scene's size) share a label; labels run 0.. in order of
/// first appearance. Returns (label per triangle, number of surfaces).
pub fn surfaces(scene: &Scene) -> (Vec<u32>, usize) {
    let planes = Planes::of(scene);
    (planes.labels, planes.list.len())
}

/// The surfaces' planes, for labelling triangles and patches alike.
struct Planes {
    /// (material, unit normal, offset n·x) of each surface.
    list: Vec<(u32, DVec3, f64)>,
    /// Label of each scene triangle.
    labels: Vec<u32>,
    /// Offset tolerance, scene units.
    tol: f64,
}

impl Planes {
    fn of(scene: &Scene) -> Planes {
        let (lo, hi) = scene.bounds();
        let mut planes = Planes {
            list: Vec::new(),
            labels: Vec::with_capacity(scene.triangles.len()),
            tol: 1e-6 * (hi - lo).length().max(f64::MIN_POSITIVE),
        };
        for t in &scene.triangles {
            let [a, b, c] = t.vertices.map(|v| scene.positions[v as usize]);
            let n = (b - a).cross(c - a).normalize();
            let label = match planes.find(t.material, n, n.dot(a)) {
                Some(k) => k,
                None => {
                    planes.list.push((t.material, n, n.dot(a)));
                    (planes.list.len() - 1) as u32
                }
            };
            planes.labels.push(label);
        }
        planes
    }

    fn find(&self, material: u32, n: DVec3, d: f64) -> Option<u32> {
        self.list
            .iter()
            .position(|(m, pn, pd)| {
                *m == material && (*pn - n).length() < 1e-6 && (pd - d).abs() < self.tol
            })
            .map(|k| k as u32)
    }
}

/// The same per-surface visible-area means from a radiosity solution, for comparison with
/// [`surface_means`]: Σ A_i v_i L_i / Σ A_i v_i over the patches of each surface (v_i the
/// patch's visible fraction), RGB. Surfaces with no visible area get 0. Patches are assigned
/// to surfaces by their own plane and material (the pipeline may have cut the scene's
/// triangles along contact lines); one on no surface's plane is left out.
pub fn solution_means(
    scene: &Scene,
    patches: &crate::mesh::Patches,
    radiance: &[Rgb],
    visible_fraction: &[f64],
) -> Vec<Rgb> {
    let planes = Planes::of(scene);
    let mut sums = vec![([0.0; 3], 0.0); planes.list.len()];
    for i in 0..patches.len() {
        let n = patches.normal[i];
        let Some(k) = planes.find(patches.material[i], n, n.dot(patches.centroid[i])) else {
            continue;
        };
        let w = patches.area[i] * visible_fraction[i];
        for (s, l) in sums[k as usize].0.iter_mut().zip(radiance[i]) {
            *s += w * l;
        }
        sums[k as usize].1 += w;
    }
    sums.iter()
        .map(|(s, a)| if *a > 0.0 { s.map(|x| x / a) } else { [0.0; 3] })
        .collect()
}

/// The visible means of a reference written by the scale harness
/// (`cargo bench -p radiosity-tools --bench scale -- reference`: columns surface, material, area,
/// visible_fraction, mean ×3, standard error ×3, visible mean ×3). Errors name the file and
/// line.
pub fn read_reference(path: &std::path::Path) -> crate::Result<Vec<Rgb>> {
    let text = std::fs::read_to_string(path).map_err(|e| crate::Error::io(path, e))?;
    text.lines()
        .enumerate()
        .skip(1)
        .map(|(n, line)| {
            let f: Vec<&str> = line.split(',').collect();
            let value = |k: usize| f.get(k).and_then(|x| x.parse::<f64>().ok());
            match (value(10), value(11), value(12)) {
                (Some(r), Some(g), Some(b)) => Ok([r, g, b]),
                _ => Err(crate::Error::Input {
                    path: path.to_path_buf(),
                    message: format!("line {}: expected 13 comma-separated numbers", n + 1),
                }),
            }
        })
        .collect()
}

/// Paths per parallel task (the unit of the fixed-order reduction).
const CHUNK: u32 = 1024;

/// Bounces before Russian roulette may end a path.
const ROULETTE_AFTER: u32 = 3;

/// Per-surface mean radiance of `scene` for the surfaces `labels` (one per triangle, values
/// `0..count`), by path tracing. Deterministic for a given seed, whatever the thread count.
pub fn surface_means(
    scene: &Scene,
    labels: &[u32],
    count: usize,
    settings: &Settings,
) -> Vec<SurfaceMean> {
    let tracer = Tracer::new(scene);
    (0..count as u32)
        .map(|s| tracer.surface(labels, s, settings))
        .collect()
}

/// The scene prepared for tracing (also the point-wise benchmark's reference,
/// [`super::pointwise`]).
pub(crate) struct Tracer<'a> {
    scene: &'a Scene,
    vis: Visibility,
    pub(crate) corners: Vec<[DVec3; 3]>,
    /// Unit front normal of each scene triangle.
    pub(crate) normal: Vec<DVec3>,
    pub(crate) area: Vec<f64>,
    /// Emitting triangles and the cumulative distribution of their emitted power
    /// (area × largest channel of Le), for next-event estimation.
    emitters: Vec<u32>,
    emitter_cdf: Vec<f64>,
    /// Probability that next-event estimation picks triangle t (0 for non-emitters).
    emitter_pick: Vec<f64>,
    /// The lights outside the mesh ([`Tracer::lit_by`]; none by default).
    env: Environment,
}

impl<'a> Tracer<'a> {
    pub(crate) fn new(scene: &'a Scene) -> Self {
        let corners = scene.triangle_corners();
        let normal = corners
            .iter()
            .map(|[a, b, c]| (*b - *a).cross(*c - *a).normalize())
            .collect();
        let area: Vec<f64> = corners
            .iter()
            .map(|[a, b, c]| 0.5 * (*b - *a).cross(*c - *a).length())
            .collect();
        let (mut emitters, mut emitter_cdf, mut total) = (Vec::new(), Vec::new(), 0.0);
        for (t, tri) in scene.triangles.iter().enumerate() {
            let le = scene.materials[tri.material as usize].emission;
            let power = area[t] * le.iter().cloned().fold(0.0, f64::max);
            if power > 0.0 {
                total += power;
                emitters.push(t as u32);
                emitter_cdf.push(total);
            }
        }
        for c in &mut emitter_cdf {
            *c /= total;
        }
        let mut emitter_pick = vec![0.0; corners.len()];
        for (k, &e) in emitters.iter().enumerate() {
            emitter_pick[e as usize] =
                emitter_cdf[k] - if k > 0 { emitter_cdf[k - 1] } else { 0.0 };
        }
        Tracer {
            scene,
            // Partly transparent faces pass a path with chance t (the screen-door model of
            // `Material::transmittance`).
            vis: scene.visibility(),
            corners,
            normal,
            area,
            emitters,
            emitter_cdf,
            emitter_pick,
            env: Environment::default(),
        }
    }

    /// The same tracer with the lights outside the mesh `env` (sky, sun, point and spot
    /// lights) as well as the scene's emitters (see the module documentation).
    pub(crate) fn lit_by(mut self, env: &Environment) -> Self {
        self.env = env.clone();
        self
    }

    /// One next-event sample of the lights outside the mesh at the point `x` of triangle `t`:
    /// (1/π)·(E_sun cosθ V by one ray to a uniform point of the sun's disc, plus each point
    /// light's I · falloff · cosθ V / r²). Radiance units, before ρ. Rays pass partly
    /// transparent faces by their transmittance ([`Visibility::transmittance`]).
    fn outside_direct(&self, t: usize, x: DVec3, rng: &mut Rng) -> Rgb {
        use std::f64::consts::PI;
        let n = self.normal[t];
        let mut sum = [0.0; 3];
        if let (Some(sun), Some(s)) = (self.env.sun, self.env.sun_direction()) {
            // Uniform over the disc's solid angle: cos uniform in [cos_max, 1].
            let cos_max = (0.5 * SUN_DIAMETER_DEGREES).to_radians().cos();
            let c = 1.0 - rng.next_f64() * (1.0 - cos_max);
            let phi = 2.0 * PI * rng.next_f64();
            let (u, v) = orthonormal_basis(s);
            let sin = (1.0 - c * c).max(0.0).sqrt();
            let dir = c * s + sin * (phi.cos() * u + phi.sin() * v);
            let cos = n.dot(dir);
            if cos > 0.0 {
                let pass = self.vis.transmittance(x, dir, f64::INFINITY, t as u32);
                for (s, e) in sum.iter_mut().zip(sun.irradiance) {
                    *s += e * cos * pass / PI;
                }
            }
        }
        for light in &self.env.lights {
            let Some(Toward {
                to,
                r2,
                cos,
                falloff,
                ..
            }) = light.toward(x, n)
            else {
                continue;
            };
            // The segment x → the light (`to` its whole length), just short of the light.
            let pass = self.vis.transmittance(x, to, 1.0 - 1e-9, t as u32);
            for (s, i) in sum.iter_mut().zip(light.intensity) {
                *s += i * falloff * cos * pass / (r2 * PI);
            }
        }
        sum
    }

    /// ρ at the point `x` of triangle `t`: the material's, varied by its texture where the
    /// triangle has texture coordinates ([`Scene::reflectance_over`] at a point).
    fn rho(&self, t: usize, x: DVec3) -> Rgb {
        self.scene.reflectance_over(t, [x; 3])
    }

    fn le(&self, t: usize) -> Rgb {
        self.scene.materials[self.scene.triangles[t].material as usize].emission
    }

    /// Uniform point on triangle t from (u, v) ∈ [0, 1)² (area-preserving map).
    pub(crate) fn point(&self, t: usize, u: f64, v: f64) -> DVec3 {
        let [a, b, c] = self.corners[t];
        let [wa, wb, wc] = triangle_barycentrics(u, v);
        wa * a + wb * b + wc * c
    }

    /// The estimate for surface `s`.
    fn surface(&self, labels: &[u32], s: u32, settings: &Settings) -> SurfaceMean {
        let tris: Vec<usize> = (0..labels.len()).filter(|&t| labels[t] == s).collect();
        let area: f64 = tris.iter().map(|&t| self.area[t]).sum();
        let mut cdf = Vec::with_capacity(tris.len());
        let mut acc = 0.0;
        for &t in &tris {
            acc += self.area[t] / area;
            cdf.push(acc);
        }
        let n = settings.paths_per_surface.max(1);
        let chunks: Vec<([f64; 3], [f64; 3], u64)> = (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map(|c| {
                let (mut sum, mut sq, mut visible) = ([0.0; 3], [0.0; 3], 0u64);
                for k in c * CHUNK..((c + 1) * CHUNK).min(n) {
                    let mut rng = Rng::new(&[settings.seed, s as u64, k as u64, 0x9A7]);
                    // Stratified over the surface: sample k of n picks its area quantile.
                    let q = (k as f64 + rng.next_f64()) / n as f64;
                    let i = cdf.partition_point(|&x| x < q).min(tris.len() - 1);
                    let t = tris[i];
                    let x = self.point(t, rng.next_f64(), rng.next_f64());
                    let (l, buried) = self.radiance_out(t, x, &mut rng);
                    visible += (!buried) as u64;
                    for ch in 0..3 {
                        sum[ch] += l[ch];
                        sq[ch] += l[ch] * l[ch];
                    }
                }
                (sum, sq, visible)
            })
            .collect();
        let (mut sum, mut sq, mut visible) = ([0.0; 3], [0.0; 3], 0u64);
        for (a, b, v) in chunks {
            for ch in 0..3 {
                sum[ch] += a[ch];
                sq[ch] += b[ch];
            }
            visible += v;
        }
        let nf = n as f64;
        let mean = sum.map(|x| x / nf);
        let std_error = std::array::from_fn(|ch| {
            let var = (sq[ch] / nf - mean[ch] * mean[ch]).max(0.0) * nf / (nf - 1.0).max(1.0);
            (var / nf).sqrt()
        });
        let visible_fraction = visible as f64 / nf;
        SurfaceMean {
            area,
            visible_fraction,
            mean,
            std_error,
            visible_mean: if visible > 0 {
                mean.map(|m| m / visible_fraction)
            } else {
                [0.0; 3]
            },
        }
    }

    /// One estimate of the radiance leaving point `x` of triangle `t` (toward its front), and
    /// whether `x` is buried (then the estimate is 0).
    pub(crate) fn radiance_out(&self, t: usize, x: DVec3, rng: &mut Rng) -> (Rgb, bool) {
        if self.buried(t, x) {
            return ([0.0; 3], true);
        }
        let mut l = self.le(t);
        let mut weight = self.rho(t, x);
        let (mut t, mut x) = (t, x);
        let mut bounce = 0;
        loop {
            if weight.iter().all(|&w| w == 0.0) {
                break;
            }
            // Next-event estimation: Le(y) G(x, y) V(x, y) / p(y).
            if let Some(direct) = self.direct(t, x, rng) {
                for ch in 0..3 {
                    l[ch] += weight[ch] * direct[ch];
                }
            }
            if self.env.has_sharp() {
                let outside = self.outside_direct(t, x, rng);
                for ch in 0..3 {
                    l[ch] += weight[ch] * outside[ch];
                }
            }
            // Continue along a cosine-weighted direction; the reflected light found there is
            // ρ there times its own incident integral.
            let dir = cosine_direction(self.normal[t], rng);
            let Some(hit) = self.vis.closest_hit(x, dir, f64::INFINITY, t as u32) else {
                // Out of the scene: the sky's radiance that way (0 below the horizon; the
                // cosine-weighted density cancels the integrand's cosθ/π).
                let sky = self.env.sky_radiance(dir);
                for ch in 0..3 {
                    l[ch] += weight[ch] * sky[ch];
                }
                break;
            };
            let h = hit.triangle as usize;
            if self.normal[h].dot(dir) >= 0.0 {
                break; // the back of a one-sided surface: absorbs
            }
            let [a, b, c] = self.corners[h];
            let y = (1.0 - hit.u - hit.v) * a + hit.u * b + hit.v * c;
            if self.emitter_pick[h] > 0.0 {
                // Emission found by the direction sample, weighted against next-event
                // estimation's chance of proposing the same direction.
                let p_dir = self.normal[t].dot(dir) / std::f64::consts::PI;
                let w = p_dir / (p_dir + self.light_pdf(h, x, y));
                let le = self.le(h);
                for ch in 0..3 {
                    l[ch] += weight[ch] * le[ch] * w;
                }
            }
            x = y;
            t = h;
            let rho = self.rho(t, x);
            for ch in 0..3 {
                weight[ch] *= rho[ch];
            }
            bounce += 1;
            if bounce >= ROULETTE_AFTER {
                let survive = weight.iter().cloned().fold(0.0, f64::max).min(1.0);
                if rng.next_f64() >= survive {
                    break;
                }
                weight = weight.map(|w| w / survive);
            }
        }
        (l, false)
    }

    /// One next-event sample of ∫ Le(y) G(x, y) V(x, y) dA_y over the emitters, or `None`
    /// when the sampled emitter point cannot contribute.
    fn direct(&self, t: usize, x: DVec3, rng: &mut Rng) -> Option<Rgb> {
        if self.emitters.is_empty() {
            return None;
        }
        let u = rng.next_f64();
        let k = self
            .emitter_cdf
            .partition_point(|&c| c <= u)
            .min(self.emitters.len() - 1);
        let e = self.emitters[k] as usize;
        let p_e = self.emitter_cdf[k] - if k > 0 { self.emitter_cdf[k - 1] } else { 0.0 };
        let y = self.point(e, rng.next_f64(), rng.next_f64());
        let d = y - x;
        let (cx, cy) = (self.normal[t].dot(d), -self.normal[e].dot(d));
        if cx <= 0.0 || cy <= 0.0 || e == t {
            return None;
        }
        if self.vis.occluded(x, y, [t as u32, e as u32]) {
            return None;
        }
        let r2 = d.length_squared();
        // G = cosθx cosθy / (π r²) with cosθ = (n·d)/r; p(y) = p_e / A_e per unit area.
        let g = cx * cy / (std::f64::consts::PI * r2 * r2);
        // A partly transparent emitter sends from its covered share only; a path meets it
        // (below) with that chance.
        let cover =
            1.0 - self.scene.materials[self.scene.triangles[e].material as usize].transmittance;
        let scale = g * self.area[e] * cover / p_e;
        // Balance heuristic against the cosine-weighted direction sample (solid-angle pdfs).
        let p_light = self.light_pdf(e, x, y);
        let p_dir = cx / (r2.sqrt() * std::f64::consts::PI);
        let w = p_light / (p_light + p_dir);
        Some(self.le(e).map(|le| le * scale * w))
    }

    /// Solid-angle density with which next-event estimation from `x` proposes the direction
    /// to point `y` of emitter `e`: (p_e / A_e) · r² / cosθ_y.
    fn light_pdf(&self, e: usize, x: DVec3, y: DVec3) -> f64 {
        let d = y - x;
        let r2 = d.length_squared();
        let cy = -self.normal[e].dot(d) / r2.sqrt();
        if cy <= 0.0 {
            return f64::INFINITY;
        }
        self.emitter_pick[e] / self.area[e] * r2 / cy
    }

    /// True when `x` on triangle `t` is buried: the bake's own test, [`Visibility::buried`]
    /// (the form factors', the hierarchy's and the gather's). The first surface straight
    /// along x's normal is seen from behind (`x` lies inside a closed object or under a
    /// surface resting on it; of objects that touch along coincident faces, a table leg under
    /// its top, whichever face the rounding puts first), or another surface passes through
    /// `x` facing it ([`Visibility::lies_face_to_face`]: a leg's bottom on the floor, a
    /// cabinet's back flush against a one-sided wall). Without the second, a cabinet's back
    /// against an outer wall of a daylit room passed for visible, and its paths, leaving
    /// through the wall's plane at distance 0, read about half the sky: a reference neither
    /// the bake nor a viewer could show.
    pub(crate) fn buried(&self, t: usize, x: DVec3) -> bool {
        self.vis.buried(x, self.normal[t], t as u32)
    }
}

/// A cosine-weighted direction about the unit normal `n` (Malley's method: uniform on the
/// disk, lifted to the hemisphere).
fn cosine_direction(n: DVec3, rng: &mut Rng) -> DVec3 {
    let (s, t) = (rng.next_f64(), rng.next_f64());
    let (tangent, bitangent) = n.any_orthonormal_pair();
    malley(s, t, tangent, bitangent, n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::SceneBuilder;
    use crate::validation::{closed_forms, scenes};

    /// Adds the quadrilateral with corners `c` (counter-clockwise seen from its front).
    fn quad(b: &mut SceneBuilder, c: [[f64; 3]; 4], material: u32) {
        b.quad(c.map(DVec3::from), material);
    }

    /// Which of the triangles `among` holds the point `p` of their plane (the first, where `p`
    /// lies on an edge they share; weights within rounding of 0 count as inside).
    fn triangle_at(scene: &Scene, among: impl IntoIterator<Item = usize>, p: DVec3) -> usize {
        among
            .into_iter()
            .find(|&t| {
                let corners = scene.triangles[t]
                    .vertices
                    .map(|v| scene.positions[v as usize]);
                crate::mesh::barycentric(p, corners)
                    .iter()
                    .all(|&w| w >= -1e-12)
            })
            .expect("a triangle holds the point")
    }

    #[test]
    fn the_floor_under_a_leg_touching_its_table_is_buried() {
        // An open-bottomed leg stands on the floor under a closed table top; the leg's top and
        // the top's underside coincide. From the floor inside the leg's footprint the ray up
        // meets the leg's top from behind and the underside from the front at the same
        // distance: buried, whichever rounds first (the gather's and the form factors' rule).
        use glam::dvec3;
        let mut b = SceneBuilder::new();
        let grey = b.material("grey", [0.5; 3], [0.0; 3]);
        let light = b.material("light", [0.0; 3], [1.0; 3]);
        quad(
            &mut b,
            [
                [-3.0, -3.0, 0.0],
                [4.0, -3.0, 0.0],
                [4.0, 4.0, 0.0],
                [-3.0, 4.0, 0.0],
            ],
            grey,
        );
        quad(
            &mut b,
            [
                [-3.0, -3.0, 8.0],
                [-3.0, 4.0, 8.0],
                [4.0, 4.0, 8.0],
                [4.0, -3.0, 8.0],
            ],
            light,
        );
        // A box's faces, outward (counter-clockwise seen from outside); `bottom` or not.
        let boxed = |b: &mut SceneBuilder, lo: DVec3, hi: DVec3, bottom: bool| {
            let p = |x: usize, y: usize, z: usize| {
                dvec3([lo.x, hi.x][x], [lo.y, hi.y][y], [lo.z, hi.z][z])
            };
            let mut faces = vec![
                [p(0, 0, 1), p(1, 0, 1), p(1, 1, 1), p(0, 1, 1)], // top
                [p(0, 0, 0), p(1, 0, 0), p(1, 0, 1), p(0, 0, 1)], // −y
                [p(1, 1, 0), p(0, 1, 0), p(0, 1, 1), p(1, 1, 1)], // +y
                [p(0, 1, 0), p(0, 0, 0), p(0, 0, 1), p(0, 1, 1)], // −x
                [p(1, 0, 0), p(1, 1, 0), p(1, 1, 1), p(1, 0, 1)], // +x
            ];
            if bottom {
                faces.push([p(0, 0, 0), p(0, 1, 0), p(1, 1, 0), p(1, 0, 0)]);
            }
            for f in faces {
                b.quad(f, grey);
            }
        };
        boxed(&mut b, dvec3(0.0, 0.0, 0.0), dvec3(1.0, 1.0, 4.0), false);
        boxed(&mut b, dvec3(-2.0, -2.0, 4.0), dvec3(3.0, 3.0, 5.0), true);
        let scene = b.build().unwrap();
        let tracer = Tracer::new(&scene);
        let floor = |x: f64, y: f64| {
            // The floor's triangle under (x, y): the first two triangles are the floor's.
            let q = dvec3(x, y, 0.0);
            (triangle_at(&scene, 0..2, q), q)
        };
        for (x, y) in [(0.5, 0.5), (0.2, 0.9), (0.99, 0.01), (0.7, 0.3)] {
            let (t, q) = floor(x, y);
            assert!(tracer.buried(t, q), "inside the leg at ({x}, {y})");
        }
        for (x, y) in [(1.5, 0.5), (-0.5, -0.5), (2.9, 2.9), (3.5, 3.5)] {
            let (t, q) = floor(x, y);
            assert!(!tracer.buried(t, q), "beside the leg at ({x}, {y})");
        }
    }

    #[test]
    fn a_back_flush_against_a_one_sided_wall_is_buried_and_never_a_probe() {
        // A one-sided wall x = 0 facing +x with open space behind it, and a cabinet's back
        // face lying on it, facing −x. The back's normal ray leaves through the wall's plane
        // at distance 0 and meets nothing: only the face-to-face half of the bake's test buries
        // it (and the wall behind the cabinet). Before, the sampler drew probes there, whose
        // paths read about half the sky.
        use crate::validation::pointwise::sample_points;
        use glam::dvec3;
        let mut b = SceneBuilder::new();
        let grey = b.material("grey", [0.5; 3], [0.0; 3]);
        let light = b.material("light", [0.0; 3], [1.0; 3]);
        // The wall (y, z in [0, 2]), counter-clockwise seen from +x.
        quad(
            &mut b,
            [
                [0.0, 0.0, 0.0],
                [0.0, 2.0, 0.0],
                [0.0, 2.0, 2.0],
                [0.0, 0.0, 2.0],
            ],
            grey,
        );
        // The cabinet's back (y, z in [0.5, 1.5]), counter-clockwise seen from −x.
        quad(
            &mut b,
            [
                [0.0, 0.5, 0.5],
                [0.0, 0.5, 1.5],
                [0.0, 1.5, 1.5],
                [0.0, 1.5, 0.5],
            ],
            grey,
        );
        // A lamp in front of the wall, facing it.
        quad(
            &mut b,
            [
                [3.0, 0.0, 0.0],
                [3.0, 0.0, 2.0],
                [3.0, 2.0, 2.0],
                [3.0, 2.0, 0.0],
            ],
            light,
        );
        let scene = b.build().unwrap();
        let tracer = Tracer::new(&scene);
        // Triangles 0, 1: the wall; 2, 3: the cabinet's back.
        let on = |ts: std::ops::Range<usize>, p: DVec3| (triangle_at(&scene, ts, p), p);
        for (y, z) in [(1.0, 1.0), (0.6, 1.4), (1.2, 0.7)] {
            let (t, p) = on(2..4, dvec3(0.0, y, z));
            assert!(tracer.buried(t, p), "the cabinet's back at ({y}, {z})");
            let (t, p) = on(0..2, dvec3(0.0, y, z));
            assert!(
                tracer.buried(t, p),
                "the wall behind the cabinet at ({y}, {z})"
            );
        }
        for (y, z) in [(0.2, 0.2), (1.8, 1.0), (1.0, 1.8)] {
            let (t, p) = on(0..2, dvec3(0.0, y, z));
            assert!(
                !tracer.buried(t, p),
                "the wall beside the cabinet at ({y}, {z})"
            );
        }
        let probes = sample_points(&scene, 300, 4).unwrap();
        assert!(
            probes.iter().all(|p| p.triangle < 2),
            "a probe on the cabinet's back"
        );
        assert!(
            probes
                .iter()
                .all(|p| !(0.5..=1.5).contains(&p.position.y)
                    || !(0.5..=1.5).contains(&p.position.z)),
            "a probe on the wall behind the cabinet"
        );
    }

    #[test]
    fn furnace_room_is_le_over_one_minus_rho() {
        // Closed, uniform Le and ρ: L = Le/(1 − ρ) everywhere; the estimator's only error is
        // its noise. Next-event estimation is at its worst here (every surface emits, so one
        // light sample per bounce is a poor guess): ≈ 2.5 % standard error at 16k paths.
        let scene = scenes::furnace_room(0.5, 1.0).unwrap();
        let (labels, count) = surfaces(&scene);
        assert_eq!(count, 18, "6 room walls and 6 faces of each box");
        let s = Settings {
            paths_per_surface: 16_384,
            seed: 3,
        };
        let expected = closed_forms::furnace_radiance(0.5, 1.0);
        for m in surface_means(&scene, &labels, count, &s) {
            let err = (m.mean[0] - expected).abs();
            assert!(err < 5.0 * m.std_error[0] + 1e-9, "{m:?}");
            assert!(m.std_error[0] < 0.05 * expected, "{m:?}");
            assert_eq!(m.visible_fraction, 1.0);
        }
    }

    #[test]
    fn a_pane_passes_its_share_of_the_paths() {
        // The parallel plates with a pane of t = 0.5 between them, larger than both: every
        // path from the receiver to the source crosses it, so the receiver's mean is half the
        // plates' ρ·F·Le (Howell C-11), within 5 standard errors.
        let mut scene = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        let glass = scene.materials.len() as u32;
        scene.materials.push(
            crate::scene::Material::opaque("glass", [0.0; 3], [0.0; 3]).with_transmittance(0.5),
        );
        // A 3 × 3 square halfway between the plates (z = 0.5), centred on them.
        let (lo, hi) = scene.bounds();
        let c = 0.5 * (lo + hi);
        let base = scene.positions.len() as u32;
        for (dx, dy) in [(-1.5, -1.5), (1.5, -1.5), (1.5, 1.5), (-1.5, 1.5)] {
            scene.positions.push(DVec3::new(c.x + dx, c.y + dy, c.z));
        }
        for v in [[0, 1, 2], [0, 2, 3]] {
            scene.triangles.push(crate::scene::SceneTriangle {
                vertices: v.map(|k| base + k),
                material: glass,
                uv: crate::scene::NO_UV,
            });
        }
        let (labels, count) = surfaces(&scene);
        let s = Settings {
            paths_per_surface: 20_000,
            seed: 1,
        };
        let means = surface_means(&scene, &labels, count, &s);
        let expected = 0.5 * 0.5 * closed_forms::parallel_rectangles(1.0, 1.0, 1.0);
        let receiver = means[1];
        assert!(
            (receiver.mean[0] - expected).abs() < 5.0 * receiver.std_error[0],
            "{receiver:?} vs {expected}"
        );
    }

    #[test]
    fn plates_match_howell() {
        // Receiver of the parallel plates: ρ·F·Le with F from Howell C-11 (no interreflection:
        // the source has ρ = 0). Noise only: 5 standard errors.
        let scene = scenes::parallel_plates(1.0, 1.0, 1.0, 0.5, 1.0).unwrap();
        let (labels, count) = surfaces(&scene);
        let s = Settings {
            paths_per_surface: 20_000,
            seed: 1,
        };
        let means = surface_means(&scene, &labels, count, &s);
        let expected = 0.5 * closed_forms::parallel_rectangles(1.0, 1.0, 1.0);
        let receiver = means[1];
        assert!(
            (receiver.mean[0] - expected).abs() < 5.0 * receiver.std_error[0],
            "{receiver:?} vs {expected}"
        );
        // Determinism: the same seed, the same bits.
        assert_eq!(
            surface_means(&scene, &labels, count, &s)[1].mean,
            receiver.mean
        );
    }
}
