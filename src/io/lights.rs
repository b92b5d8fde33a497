//! A lights file: the sky, the sun and any number of point and spot lights for a scene whose
//! format has no lights (OBJ), as JSON, so a level's hundred lamps are one option
//! (`--lights FILE`) rather than a hundred flags. The units are those of the flags and of
//! [`crate::scene::Environment`]: sky radiance W·sr⁻¹·m⁻², sun irradiance W·m⁻², intensity W·sr⁻¹,
//! positions in scene units, angles in degrees.
//!
//! ```json
//! {
//!   "sky": [0.8, 0.9, 1.0],
//!   "sky_model": "overcast",
//!   "sun": { "azimuth": 135, "elevation": 40, "irradiance": [900, 850, 800] },
//!   "lights": [
//!     { "name": "lamp", "position": [0, 2.9, 0], "intensity": 12 },
//!     { "position": [1, 2, 0], "intensity": [40, 35, 30],
//!       "spot": { "direction": [0, -1, 0], "inner": 20, "outer": 30 } }
//!   ]
//! }
//! ```
//!
//! Every key is optional; a colour is three numbers or one (grey). Unknown keys are errors (a
//! misspelt `"intensty"` must not leave a lamp dark), as are values out of range, named by the
//! light's place in the list (and its `name`, if it has one). The file is one
//! [`LightSources`]; how it joins a bake's other lights is [`LightSources::over`]'s rule.

use std::path::Path;

use glam::DVec3;
use serde::Deserialize;

use crate::color::Rgb;
use crate::scene::{LightSources, PointLight, SkyModel, Spot, Sun, Up};
use crate::{Error, Result};

/// A colour as written: one number (grey) or three.
#[derive(Debug, Deserialize)]
#[serde(try_from = "serde_json::Value")]
struct Colour(Rgb);

impl TryFrom<serde_json::Value> for Colour {
    type Error = String;

    fn try_from(v: serde_json::Value) -> std::result::Result<Self, String> {
        let number = |v: &serde_json::Value| v.as_f64();
        let rgb = match &v {
            serde_json::Value::Array(a) if a.len() == 3 => {
                match (number(&a[0]), number(&a[1]), number(&a[2])) {
                    (Some(r), Some(g), Some(b)) => Some([r, g, b]),
                    _ => None,
                }
            }
            other => number(other).map(|x| [x; 3]),
        };
        rgb.map(Colour)
            .ok_or_else(|| format!("{v}: expected a colour, one number (grey) or three [r, g, b]"))
    }
}

impl Colour {
    fn rgb(&self) -> Rgb {
        self.0
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileSun {
    azimuth: f64,
    elevation: f64,
    irradiance: Colour,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileSpot {
    direction: [f64; 3],
    inner: f64,
    outer: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileLight {
    #[serde(default)]
    name: Option<String>,
    position: [f64; 3],
    intensity: Colour,
    #[serde(default)]
    spot: Option<FileSpot>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Document {
    #[serde(default)]
    sky: Option<Colour>,
    #[serde(default)]
    sky_model: Option<String>,
    #[serde(default)]
    sun: Option<FileSun>,
    #[serde(default)]
    lights: Vec<FileLight>,
}

/// Reads a lights file (format in the module's documentation), checked item by item: every
/// error names `path`, and the line (syntax, unknown keys, wrong types) or the light's place
/// in the list and its name (values out of range).
pub fn read(path: &Path) -> Result<LightSources> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse(&crate::io::without_bom(text), path)
}

/// [`read`] on text already in memory (`path` names it in errors).
pub fn parse(text: &str, path: &Path) -> Result<LightSources> {
    let file: Document = serde_json::from_str(text).map_err(|e| Error::Parse {
        path: path.to_path_buf(),
        line: e.line(),
        message: format!("{e}"),
    })?;
    let input = |message: String| Error::Input {
        path: path.to_path_buf(),
        message,
    };
    let sky_model = match file.sky_model.as_deref() {
        None | Some("uniform") => SkyModel::Uniform,
        Some("overcast") => SkyModel::Overcast,
        Some(other) => {
            return Err(input(format!(
                "sky_model {other:?}: expected \"uniform\" or \"overcast\""
            )))
        }
    };
    let mut sources = LightSources {
        sky: file.sky.as_ref().map(Colour::rgb),
        sky_model,
        sun: file.sun.as_ref().map(|s| Sun {
            azimuth_degrees: s.azimuth,
            elevation_degrees: s.elevation,
            irradiance: s.irradiance.rgb(),
        }),
        lights: Vec::new(),
    };
    // The sky and the sun first, then each light on its own, so an error names the item.
    (sources.clone().environment(Up::default()))
        .validate()
        .map_err(|e| input(format!("sky or sun: {}", reason(e))))?;
    for (k, l) in file.lights.iter().enumerate() {
        let label = match &l.name {
            Some(name) => format!("lights[{k}] ({name:?})"),
            None => format!("lights[{k}]"),
        };
        let spot = match &l.spot {
            None => None,
            Some(s) => {
                let axis = DVec3::from_array(s.direction);
                if !(axis.is_finite() && axis.length() > 0.0) {
                    return Err(input(format!(
                        "{label}: the spot's direction {:?} must be a finite, non-zero vector",
                        s.direction
                    )));
                }
                Some(Spot {
                    direction: axis.normalize(),
                    inner_degrees: s.inner,
                    outer_degrees: s.outer,
                })
            }
        };
        let light = PointLight {
            position: DVec3::from_array(l.position),
            intensity: l.intensity.rgb(),
            spot,
        };
        light
            .check()
            .map_err(|problem| input(format!("{label}: the light {problem}")))?;
        sources.lights.push(light);
    }
    Ok(sources)
}

/// The message of a setting error, without the setting's name (the file's item replaces it).
fn reason(e: Error) -> String {
    match e {
        Error::Setting { message, .. } => message,
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_text(text: &str) -> Result<LightSources> {
        parse(text, Path::new("lights.json"))
    }

    #[test]
    fn a_file_beginning_with_a_byte_order_mark_reads() {
        let dir = crate::test_support::TestDir::new("lights-bom");
        let path = dir.write("l.json", "\u{feff}{ \"sky\": [0.5, 0.5, 0.5] }");
        let l = read(&path).unwrap();
        assert_eq!(l.environment(Up::Y).sky, [0.5; 3]);
    }

    #[test]
    fn every_part_is_read_in_the_units_of_the_flags() {
        let l = parse_text(
            r#"{ "sky": [0.1, 0.2, 0.3], "sky_model": "overcast",
                 "sun": { "azimuth": 135, "elevation": 40, "irradiance": 900 },
                 "lights": [
                   { "name": "lamp", "position": [0, 2.9, 0], "intensity": 12 },
                   { "position": [1, 2, 0], "intensity": [40, 35, 30],
                     "spot": { "direction": [0, -2, 0], "inner": 20, "outer": 30 } } ] }"#,
        )
        .unwrap();
        let e = l.environment(Up::Y);
        assert_eq!(e.sky, [0.1, 0.2, 0.3]);
        assert_eq!(e.sky_model, SkyModel::Overcast);
        let sun = e.sun.unwrap();
        assert_eq!(
            (sun.azimuth_degrees, sun.elevation_degrees, sun.irradiance),
            (135.0, 40.0, [900.0; 3])
        );
        assert_eq!(e.lights.len(), 2);
        assert_eq!(e.lights[0].intensity, [12.0; 3]);
        assert_eq!(e.lights[0].position, DVec3::new(0.0, 2.9, 0.0));
        assert!(e.lights[0].spot.is_none());
        let spot = e.lights[1].spot.unwrap();
        // The direction is normalised, as the flag's is.
        assert_eq!(spot.direction, DVec3::new(0.0, -1.0, 0.0));
        assert_eq!((spot.inner_degrees, spot.outer_degrees), (20.0, 30.0));
        assert!(e.validate().is_ok());
    }

    #[test]
    fn an_empty_file_has_no_light() {
        let l = parse_text("{}").unwrap();
        assert!(l.sky.is_none() && !l.environment(Up::Y).is_lit());
    }

    #[test]
    fn errors_name_the_line_or_the_light() {
        let message = |text: &str| parse_text(text).unwrap_err().to_string();
        // A misspelt key is an error at its line, not a dark lamp.
        let m = message("{\n \"lights\": [\n {\"position\": [0,0,0], \"intensty\": 3}\n ]\n}");
        assert!(
            m.starts_with("lights.json:3:") && m.contains("intensty"),
            "{m}"
        );
        let m = message("{ \"sky\": [1, 2] }");
        assert!(m.starts_with("lights.json:1:"), "{m}");
        let m = message(
            r#"{ "lights": [ { "position": [0,0,0], "intensity": 1 },
                { "name": "torch", "position": [0,0,0], "intensity": -1 } ] }"#,
        );
        assert!(
            m.contains("lights[1] (\"torch\")") && m.contains("≥ 0"),
            "{m}"
        );
        let m = message(
            r#"{ "lights": [ { "position": [0,0,0], "intensity": 1,
                 "spot": { "direction": [0,0,0], "inner": 1, "outer": 2 } } ] }"#,
        );
        assert!(m.contains("lights[0]") && m.contains("non-zero"), "{m}");
        let m = message(
            r#"{ "lights": [ { "position": [0,0,0], "intensity": 1,
                 "spot": { "direction": [0,1,0], "inner": 30, "outer": 20 } } ] }"#,
        );
        assert!(
            m.contains("lights[0]") && m.contains("inner < outer"),
            "{m}"
        );
        let m = message(r#"{ "sun": { "azimuth": 0, "elevation": -5, "irradiance": 1 } }"#);
        assert!(m.contains("sky or sun") && m.contains("elevation"), "{m}");
        let m = message(r#"{ "sky_model": "cloudy" }"#);
        assert!(m.contains("cloudy"), "{m}");
        let m = message("not json");
        assert!(m.starts_with("lights.json:1:"), "{m}");
    }
}
