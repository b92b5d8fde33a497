//! The lights outside the mesh, as a scene describes them: a sky above the horizon, the sun,
//! and point and spot lights ([`Environment`], with [`SkyModel`], [`Sun`], [`PointLight`],
//! [`Spot`]), their units and ranges ([`Environment::validate`]), the radiance and falloff
//! that are closed forms of their own, and the one rule that merges the lights given for a
//! bake from every source ([`LightSources`], [`Environment::add_scene_lights`]). What they
//! bring to a point of the scene, with visibility, is [`crate::light`]'s.
//!
//! Units: sky radiance W·sr⁻¹·m⁻² (the zenith's for the overcast sky), sun irradiance W·m⁻² on
//! a surface facing it, point and spot intensity W·sr⁻¹, positions in scene units, angles in
//! degrees.

use glam::DVec3;
use serde::Serialize;

use super::Up;
use crate::color::Rgb;
use crate::{Error, Result};

/// How the sky's radiance depends on direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum SkyModel {
    /// The same radiance from every direction above the horizon.
    #[default]
    Uniform,
    /// The CIE standard overcast sky: L(α) = L_zenith (1 + 2 sin α)/3.
    Overcast,
}

impl crate::Choice for SkyModel {
    const SETTING: &'static str = "environment.sky_model";
    const ALL: &'static [SkyModel] = &[SkyModel::Uniform, SkyModel::Overcast];

    fn name(self) -> &'static str {
        match self {
            SkyModel::Uniform => "uniform",
            SkyModel::Overcast => "overcast",
        }
    }

    fn description(self) -> &'static str {
        match self {
            SkyModel::Uniform => "the same radiance from every direction above the horizon",
            SkyModel::Overcast => {
                "CIE standard overcast sky: the zenith three times as bright as the horizon"
            }
        }
    }
}

/// The sun: a direction and an irradiance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sun {
    /// Degrees clockwise from north seen from above (north = [`Up::forward`], east =
    /// north × up).
    pub azimuth_degrees: f64,
    /// Degrees above the horizon, in (0, 90].
    pub elevation_degrees: f64,
    /// Irradiance on a surface facing the sun, W·m⁻² per channel, finite and ≥ 0.
    pub irradiance: Rgb,
}

/// A point light, or a spot light when it has a cone: light from a point with no area (glTF's
/// `KHR_lights_punctual` "point" and "spot"; a lamp's bulb seen from afar).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PointLight {
    /// Where it is, scene units.
    #[serde(serialize_with = "as_array")]
    pub position: DVec3,
    /// Radiant intensity, W·sr⁻¹ per channel, finite and ≥ 0 (power 4π·I for a point light):
    /// a surface at distance r facing it receives E = I / r² (lengths in metres).
    pub intensity: Rgb,
    /// The cone of a spot light; `None` for a point light shining every way.
    pub spot: Option<Spot>,
}

/// A spot light's cone, as glTF's: full intensity within `inner_degrees` of the axis, none
/// beyond `outer_degrees`, between them the square of the linear ramp in the cosine.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Spot {
    /// The axis the light shines along (unit).
    #[serde(serialize_with = "as_array")]
    pub direction: DVec3,
    /// Half-angles from the axis, degrees: 0 ≤ inner < outer ≤ 90.
    pub inner_degrees: f64,
    pub outer_degrees: f64,
}

/// A vector as three numbers in JSON.
fn as_array<S: serde::Serializer>(v: &DVec3, s: S) -> std::result::Result<S::Ok, S::Error> {
    serde::Serialize::serialize(&v.to_array(), s)
}

impl PointLight {
    /// What the light would bring unoccluded to a surface at `origin` with unit normal `n`,
    /// as a weight: the luminance of I · falloff · cos θ / r² (0 behind the surface or
    /// outside a spot's cone). Chooses which lights get shadow rays.
    pub fn potential(&self, origin: DVec3, n: DVec3) -> f64 {
        self.toward(origin, n).map_or(0.0, |t| {
            crate::color::luminance(self.intensity) * t.falloff * t.cos / t.r2
        })
    }

    /// The light as seen from `origin` on a surface with unit normal `n`: `None` where it
    /// can bring nothing (behind the surface, at the origin, outside a spot's cone).
    pub(crate) fn toward(&self, origin: DVec3, n: DVec3) -> Option<Toward> {
        let to = self.position - origin;
        let r2 = to.length_squared();
        let cos = n.dot(to);
        if cos <= 0.0 || r2 == 0.0 {
            return None;
        }
        let r = r2.sqrt();
        let (cos, d) = (cos / r, to / r);
        let falloff = self.falloff(-d);
        (falloff != 0.0).then_some(Toward {
            to,
            r,
            r2,
            cos,
            falloff,
        })
    }

    /// Checks the light's own ranges: position and intensity finite, intensity ≥ 0, a spot's
    /// direction a unit vector and its half-angles 0 ≤ inner < outer ≤ 90°. The message names
    /// the light by its position.
    pub fn check(&self) -> std::result::Result<(), String> {
        let finite =
            self.position.is_finite() && self.intensity.iter().all(|i| i.is_finite() && *i >= 0.0);
        let cone = self.spot.is_none_or(|s| {
            s.direction.is_finite()
                && (s.direction.length() - 1.0).abs() < 1e-9
                && 0.0 <= s.inner_degrees
                && s.inner_degrees < s.outer_degrees
                && s.outer_degrees <= 90.0
        });
        if finite && cone {
            return Ok(());
        }
        let p = self.position;
        Err(format!(
            "at ({}, {}, {}): its position and intensity {:?} (W·sr⁻¹) must be finite and the \
             intensity ≥ 0; a spot's direction must be a unit vector and its half-angles \
             0 ≤ inner < outer ≤ 90 degrees ({})",
            p.x,
            p.y,
            p.z,
            self.intensity,
            self.spot.map_or("none".into(), |s| format!(
                "{}°, {}°",
                s.inner_degrees, s.outer_degrees
            ))
        ))
    }

    /// The share of the intensity sent toward unit direction `d` (from the light): 1 for a
    /// point light; for a spot, glTF's smooth falloff clamp((cos − cos_outer) / (cos_inner −
    /// cos_outer), 0, 1)².
    pub fn falloff(&self, d: DVec3) -> f64 {
        let Some(s) = self.spot else { return 1.0 };
        let (ci, co) = (
            s.inner_degrees.to_radians().cos(),
            s.outer_degrees.to_radians().cos(),
        );
        let t = ((d.dot(s.direction) - co) / (ci - co).max(1e-9)).clamp(0.0, 1.0);
        t * t
    }
}

/// A point light seen from a receiving point ([`PointLight::toward`]).
pub(crate) struct Toward {
    /// From the point to the light, and its length and squared length.
    pub to: DVec3,
    pub r: f64,
    pub r2: f64,
    /// Cosine at the receiver, and the spot's falloff toward the point (> 0).
    pub cos: f64,
    pub falloff: f64,
}

/// The lights outside the mesh; [`Environment::default`] has none. What they bring to a point
/// (shadow rays, sky rays) is [`crate::light`]'s.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct Environment {
    /// Sky radiance above the horizon (the zenith's for `overcast`), W·sr⁻¹·m⁻² per channel,
    /// finite and ≥ 0; 0 = no sky.
    pub sky: Rgb,
    /// How the sky's radiance varies with direction.
    pub sky_model: SkyModel,
    /// The sun, if any.
    pub sun: Option<Sun>,
    /// Point and spot lights.
    pub lights: Vec<PointLight>,
    /// The scene's up axis: the horizon of the sky and of the sun's elevation.
    pub up: Up,
}

impl Environment {
    /// True if the sky, the sun or a point light brings any light.
    pub fn is_lit(&self) -> bool {
        self.sky.iter().any(|&l| l > 0.0) || self.has_sharp()
    }

    /// True if the sun or a point light brings light: what casts sharp shadows, computed with
    /// the direct light of emitters (and, like theirs, splitting the hierarchy's leaves where
    /// it varies).
    pub fn has_sharp(&self) -> bool {
        self.sun
            .is_some_and(|s| s.irradiance.iter().any(|&e| e > 0.0))
            || self
                .lights
                .iter()
                .any(|l| l.intensity.iter().any(|&i| i > 0.0))
    }

    /// Checks the ranges: sky and sun values finite and ≥ 0, the sun's elevation in (0, 90]
    /// and its azimuth finite, point and spot lights finite with intensity ≥ 0 and a spot's
    /// cone 0 ≤ inner < outer ≤ 90°. Errors are [`Error::Setting`] named `environment.sky`,
    /// `environment.sun`, `environment.point_lights` or `environment.spot_lights`.
    pub fn validate(&self) -> Result<()> {
        if self.sky.iter().any(|l| !(l.is_finite() && *l >= 0.0)) {
            return Err(Error::setting(
                "environment.sky",
                format!("{:?} must be finite and ≥ 0 (W·sr⁻¹·m⁻²)", self.sky),
            ));
        }
        if let Some(s) = &self.sun {
            if s.irradiance.iter().any(|e| !(e.is_finite() && *e >= 0.0)) {
                return Err(Error::setting(
                    "environment.sun",
                    format!(
                        "irradiance {:?} must be finite and ≥ 0 (W·m⁻²)",
                        s.irradiance
                    ),
                ));
            }
            let elevation_ok = s.elevation_degrees > 0.0 && s.elevation_degrees <= 90.0;
            if !elevation_ok || !s.azimuth_degrees.is_finite() {
                return Err(Error::setting(
                    "environment.sun",
                    format!(
                        "azimuth {}°, elevation {}°: the elevation must be in (0, 90] degrees \
                         and the azimuth finite",
                        s.azimuth_degrees, s.elevation_degrees
                    ),
                ));
            }
        }
        for (k, l) in self.lights.iter().enumerate() {
            if let Err(problem) = l.check() {
                let (name, what) = match l.spot {
                    None => ("environment.point_lights", "point light"),
                    Some(_) => ("environment.spot_lights", "spot light"),
                };
                return Err(Error::setting(name, format!("{what} {} {problem}", k + 1)));
            }
        }
        Ok(())
    }

    /// The unit direction toward the sun's centre, if there is a sun.
    pub fn sun_direction(&self) -> Option<DVec3> {
        let s = self.sun?;
        let (up, north) = (self.up.axis(), self.up.forward());
        let east = north.cross(up);
        let (az, el) = (
            s.azimuth_degrees.to_radians(),
            s.elevation_degrees.to_radians(),
        );
        Some((el.cos() * (az.cos() * north + az.sin() * east) + el.sin() * up).normalize())
    }

    /// The sky's radiance arriving from direction `dir` (unit, pointing away from the
    /// receiver): 0 below the horizon ([`Sky::radiance_toward`]).
    pub fn sky_radiance(&self, dir: DVec3) -> Rgb {
        Sky {
            radiance: self.sky,
            model: self.sky_model,
            up: self.up,
        }
        .radiance_toward(dir)
    }

    /// The sky alone, as pictures show it where a ray leaves the scene; `None` when there is
    /// no sky (radiance 0 in every channel).
    pub fn sky(&self) -> Option<Sky> {
        self.sky.iter().any(|&l| l > 0.0).then_some(Sky {
            radiance: self.sky,
            model: self.sky_model,
            up: self.up,
        })
    }
}

/// The sky on its own: its radiance, model and horizon. A bake hands it to pictures
/// ([`crate::bake::BakedMesh::sky`]) and its PLY output carries it as a header comment
/// (`comment sky: R G B MODEL UP`, [`Sky::to_text`]) so a picture of the baked file shows the
/// same sky where its rays leave the scene.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sky {
    /// Radiance above the horizon (the zenith's for `overcast`), W·sr⁻¹·m⁻² per channel,
    /// finite and ≥ 0.
    pub radiance: Rgb,
    /// How the radiance varies with direction.
    pub model: SkyModel,
    /// The up axis: the horizon is the plane across it.
    pub up: Up,
}

/// The marker that starts a sky line in a baked PLY header: `comment sky: R G B MODEL UP`.
pub const SKY_KEYWORD: &str = "sky:";

impl Sky {
    /// Radiance arriving from unit direction `dir` (pointing away from the receiver),
    /// W·sr⁻¹·m⁻² per channel: 0 at and below the horizon; above it `radiance` (uniform) or
    /// `radiance` · (1 + 2 sin α)/3 at elevation α (overcast).
    pub fn radiance_toward(&self, dir: DVec3) -> Rgb {
        let sin_elevation = dir.dot(self.up.axis());
        if sin_elevation <= 0.0 {
            return [0.0; 3];
        }
        let f = match self.model {
            SkyModel::Uniform => 1.0,
            SkyModel::Overcast => (1.0 + 2.0 * sin_elevation) / 3.0,
        };
        self.radiance.map(|l| l * f)
    }

    /// `R G B MODEL UP`: the radiance in Rust's shortest round-trip decimals, the model's and
    /// the axis's names (`1 0.9 0.8 overcast z`).
    pub fn to_text(&self) -> String {
        use crate::Choice;
        let [r, g, b] = self.radiance;
        format!("{r} {g} {b} {} {}", self.model.name(), self.up.name())
    }

    /// Parses [`Sky::to_text`]'s form; the error says what is wrong, in words.
    pub fn from_text(text: &str) -> std::result::Result<Sky, String> {
        use crate::Choice;
        let words: Vec<&str> = text.split_whitespace().collect();
        let [r, g, b, model, up] = words[..] else {
            return Err(format!(
                "expected R G B MODEL UP (five words), got {}",
                words.len()
            ));
        };
        let number = |w: &str| match w.parse::<f64>() {
            Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
            _ => Err(format!("{w:?} is not a finite radiance ≥ 0")),
        };
        Ok(Sky {
            radiance: [number(r)?, number(g)?, number(b)?],
            model: SkyModel::from_name(model)
                .ok_or_else(|| format!("{model:?} is not a sky model"))?,
            up: Up::from_name(up).ok_or_else(|| format!("{up:?} is not an axis (x, y, z)"))?,
        })
    }
}

/// The lights given for one bake beside the scene file's own, from one source (a program's
/// options, or a lights file: [`crate::io::lights`]); [`LightSources::over`] is the rule that
/// puts one over another, and [`LightSources::environment`] the lights that result.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LightSources {
    /// Sky radiance (the zenith's for `overcast`), W·sr⁻¹·m⁻² per channel, if given.
    pub sky: Option<Rgb>,
    /// How the sky's radiance varies with direction.
    pub sky_model: SkyModel,
    /// The sun, if given.
    pub sun: Option<Sun>,
    /// Point and spot lights.
    pub lights: Vec<PointLight>,
}

impl LightSources {
    /// These sources over `under` (a lights file under a program's options): a sky given here
    /// replaces `under`'s (with its model; the model here stands when neither gives a sky),
    /// so does a sun, and the lights join, `under`'s first.
    pub fn over(self, under: LightSources) -> LightSources {
        let (sky, sky_model) = match (self.sky, under.sky) {
            (Some(sky), _) => (Some(sky), self.sky_model),
            (None, Some(sky)) => (Some(sky), under.sky_model),
            (None, None) => (None, self.sky_model),
        };
        let mut lights = under.lights;
        lights.extend(self.lights);
        LightSources {
            sky,
            sky_model,
            sun: self.sun.or(under.sun),
            lights,
        }
    }

    /// The lights as an [`Environment`] with the scene's `up` axis (no sky: radiance 0).
    pub fn environment(self, up: Up) -> Environment {
        Environment {
            sky: self.sky.unwrap_or([0.0; 3]),
            sky_model: self.sky_model,
            sun: self.sun,
            lights: self.lights,
            up,
        }
    }
}

impl Environment {
    /// The scene file's own lights added (glTF's punctual lights, [`super::Scene::lights`] and
    /// [`super::Scene::sun`], Mitsuba's [`super::Scene::sky`]): its point and spot lights join
    /// these, after them, its sun is taken where these have none, and its sky where these
    /// have none (a sky of radiance 0 counts as none; the sky model stays these settings').
    pub fn add_scene_lights(&mut self, scene: &super::Scene) {
        self.lights.extend(scene.lights.iter().copied());
        if self.sun.is_none() {
            self.sun = scene.sun;
        }
        if let (true, Some(sky)) = (self.sky.iter().all(|&l| l == 0.0), scene.sky) {
            self.sky = sky;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_are_checked() {
        Environment::default().validate().unwrap();
        assert!(!Environment::default().is_lit());
        let bad_sky = Environment {
            sky: [-1.0, 0.0, 0.0],
            ..Environment::default()
        };
        assert!(bad_sky.validate().is_err());
        for (az, el) in [(0.0, 0.0), (0.0, 91.0), (f64::NAN, 10.0), (0.0, -5.0)] {
            let e = Environment {
                sun: Some(Sun {
                    azimuth_degrees: az,
                    elevation_degrees: el,
                    irradiance: [1.0; 3],
                }),
                ..Environment::default()
            };
            assert!(e.validate().is_err(), "{az} {el}");
        }
        let spot = |inner: f64, outer: f64| Environment {
            lights: vec![PointLight {
                position: DVec3::ZERO,
                intensity: [1.0; 3],
                spot: Some(Spot {
                    direction: DVec3::Z,
                    inner_degrees: inner,
                    outer_degrees: outer,
                }),
            }],
            ..Environment::default()
        };
        spot(10.0, 20.0).validate().unwrap();
        for (inner, outer) in [(20.0, 10.0), (-1.0, 10.0), (10.0, 91.0), (10.0, 10.0)] {
            assert!(spot(inner, outer).validate().is_err(), "{inner} {outer}");
        }
    }

    #[test]
    fn given_sky_and_sun_replace_those_under_them_and_lights_join() {
        let lamp = |x: f64| PointLight {
            position: DVec3::new(x, 0.0, 0.0),
            intensity: [1.0; 3],
            spot: None,
        };
        let sun = |e: f64| Sun {
            azimuth_degrees: 0.0,
            elevation_degrees: 45.0,
            irradiance: [e; 3],
        };
        let file = LightSources {
            sky: Some([2.0; 3]),
            sky_model: SkyModel::Overcast,
            sun: Some(sun(100.0)),
            lights: vec![lamp(1.0)],
        };
        // Nothing given over the file: the file's sky with its model, its sun, its lights.
        let only_file = LightSources::default().over(file.clone());
        assert_eq!(only_file.sky, Some([2.0; 3]));
        assert_eq!(only_file.sky_model, SkyModel::Overcast);
        assert_eq!(only_file.sun, Some(sun(100.0)));
        // A sky of 0 given over the file switches its sky off; the given model goes with it.
        let given = LightSources {
            sky: Some([0.0; 3]),
            sky_model: SkyModel::Uniform,
            sun: Some(sun(5.0)),
            lights: vec![lamp(2.0)],
        };
        let merged = given.over(file).environment(Up::Z);
        assert_eq!(merged.sky, [0.0; 3]);
        assert_eq!(merged.sky_model, SkyModel::Uniform);
        assert_eq!(merged.sun, Some(sun(5.0)));
        assert_eq!(merged.lights, vec![lamp(1.0), lamp(2.0)]);
        assert_eq!(merged.up, Up::Z);
        // Neither gives a sky: none, with the upper model.
        let none = LightSources {
            sky_model: SkyModel::Overcast,
            ..LightSources::default()
        }
        .over(LightSources::default());
        assert_eq!((none.sky, none.sky_model), (None, SkyModel::Overcast));
    }
}
