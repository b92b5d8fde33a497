//! Material overrides: replace a material's reflectance ρ or emission Le in a loaded
//! [`Scene`] without editing its files (`--reflectance MAT=r,g,b`, `--emission MAT=r,g,b`).
//! This module owns parsing the `MATERIAL=VALUE` text, checking the values and applying
//! them, with errors that name the property as the setting it is ([`Property::name`]:
//! `reflectance`, `emission`; a command line maps that to its option); it does not touch
//! geometry.
//!
//! Semantics: overrides apply in the order given, so a later one wins over an earlier one
//! for the same material and property (`*=0.5` then `white=0.7` leaves white at 0.7; the
//! other way round everything is 0.5). A name may be a pattern: `*` stands for any run of
//! characters and `?` for one (`tlight*` names every material whose name starts `tlight`, so
//! a level's lights are one option); `*` alone names every material of the scene, including
//! unused ones and the default material of faces without one. A name or pattern that names
//! no material is an error.

use super::Scene;
use crate::{Error, Result};

/// Which material property an [`Override`] replaces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Property {
    /// ρ, diffuse reflectance per RGB channel, each in [0, 1] (MTL `Kd`).
    Reflectance,
    /// Le, emitted radiance per RGB channel, W·sr⁻¹·m⁻², each finite and ≥ 0 (MTL `Ke`).
    Emission,
}

impl Property {
    /// The property's name as a setting (`reflectance`, `emission`); errors name it.
    pub fn name(self) -> &'static str {
        match self {
            Property::Reflectance => "reflectance",
            Property::Emission => "emission",
        }
    }

    /// Checks one value: ρ in [0, 1], Le finite and ≥ 0 (NaN fails both).
    fn check(self, value: [f64; 3]) -> std::result::Result<(), String> {
        match self {
            Property::Reflectance if value.iter().any(|r| !(0.0..=1.0).contains(r)) => {
                Err(format!("reflectance ρ = {value:?} is not in [0, 1]"))
            }
            Property::Emission if value.iter().any(|e| !(e.is_finite() && *e >= 0.0)) => {
                Err(format!("emission Le = {value:?} must be finite and ≥ 0"))
            }
            _ => Ok(()),
        }
    }
}

/// One override: set `property` of the materials `material` names (`*` = every material,
/// see [`names`]) to `value` (per RGB channel).
#[derive(Debug, Clone, PartialEq)]
pub struct Override {
    /// A material name of the scene, or a pattern with `*` and `?` ([`names`]).
    pub material: String,
    /// What to replace.
    pub property: Property,
    /// The new value per RGB channel; its range is [`Property`]'s.
    pub value: [f64; 3],
}

impl Override {
    /// Parses `MATERIAL=R,G,B` or `MATERIAL=X` (grey: X in every channel). The name is
    /// everything before the last `=`, so names containing `=` work. Errors are
    /// [`Error::Setting`] named by [`Property::name`].
    pub fn parse(property: Property, text: &str) -> Result<Override> {
        let bad = |why: String| Error::setting(property.name(), format!("{text:?}: {why}"));
        let (material, values) = text.rsplit_once('=').ok_or_else(|| {
            bad("expected MATERIAL=R,G,B or MATERIAL=X (MATERIAL may be *)".into())
        })?;
        let material = material.trim();
        if material.is_empty() {
            return Err(bad("no material name before `=` (use * for all)".into()));
        }
        let numbers: Vec<f64> = values
            .split(',')
            .map(|v| {
                v.trim()
                    .parse::<f64>()
                    .map_err(|_| bad(format!("malformed number {:?}", v.trim())))
            })
            .collect::<Result<_>>()?;
        let value = match numbers[..] {
            [x] => [x; 3],
            [r, g, b] => [r, g, b],
            _ => {
                return Err(bad(format!(
                    "expected 1 or 3 numbers, found {}",
                    numbers.len()
                )))
            }
        };
        property.check(value).map_err(bad)?;
        Ok(Override {
            material: material.to_string(),
            property,
            value,
        })
    }
}

/// The override as its property and its text: `reflectance white=0.5,0.5,0.5`.
impl std::fmt::Display for Override {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [r, g, b] = self.value;
        write!(f, "{} {}={r},{g},{b}", self.property.name(), self.material)
    }
}

/// True if `pattern` names the material `name`: the name itself, or a match where `*` stands
/// for any run of characters (also none) and `?` for exactly one.
pub fn names(pattern: &str, name: &str) -> bool {
    if pattern == name {
        return true;
    }
    let (p, n): (Vec<char>, Vec<char>) = (pattern.chars().collect(), name.chars().collect());
    // Greedy glob matching with one backtrack point (the last `*`): linear in practice.
    let (mut i, mut j) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while j < n.len() {
        if i < p.len() && (p[i] == '?' || p[i] == n[j]) {
            i += 1;
            j += 1;
        } else if i < p.len() && p[i] == '*' {
            star = Some((i, j));
            i += 1;
        } else if let Some((si, sj)) = star {
            i = si + 1;
            j = sj + 1;
            star = Some((si, sj + 1));
        } else {
            return false;
        }
    }
    p[i..].iter().all(|&c| c == '*')
}

impl Scene {
    /// Applies `overrides` in order (later ones win). Checks each first: a material name the
    /// scene does not have is an [`Error::Setting`] named by the property, listing the scene's
    /// materials; a value out of range (ρ ∉ [0, 1], Le < 0, NaN) is an [`Error::Setting`] too.
    /// Nothing is changed when any override fails.
    pub fn apply_overrides(&mut self, overrides: &[Override]) -> Result<()> {
        for o in overrides {
            let option = o.property.name();
            o.property
                .check(o.value)
                .map_err(|why| Error::setting(option, format!("{}: {why}", o.material)))?;
            if !self.materials.iter().any(|m| names(&o.material, &m.name)) {
                let list: Vec<&str> = self.materials.iter().map(|m| m.name.as_str()).collect();
                return Err(Error::setting(
                    option,
                    format!(
                        "no material '{}' in {}; its materials are: {} (or * for all, and \
                         patterns such as light*)",
                        o.material,
                        super::source_path(&self.source).display(),
                        list.join(", ")
                    ),
                ));
            }
        }
        for o in overrides {
            if o.property == Property::Reflectance {
                // A reflectance set by hand is the face's ρ everywhere: its texture no longer
                // varies it.
                for t in self.triangles.iter_mut() {
                    if names(&o.material, &self.materials[t.material as usize].name) {
                        t.uv = super::NO_UV;
                    }
                }
            }
            for m in self
                .materials
                .iter_mut()
                .filter(|m| names(&o.material, &m.name))
            {
                match o.property {
                    Property::Reflectance => m.reflectance = o.value,
                    Property::Emission => m.emission = o.value,
                }
            }
        }
        self.validate()
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    #[test]
    fn patterns_name_materials() {
        for (pattern, name) in [
            ("*", "anything"),
            ("*", ""),
            ("tlight*", "tlight"),
            ("tlight*", "tlight_blue2"),
            ("*light", "skylight"),
            ("t?ght", "tight"),
            ("a*b*c", "aXXbYYbZc"),
            ("white", "white"),
            ("a*b", "a*b"),
        ] {
            assert!(names(pattern, name), "{pattern} {name}");
        }
        for (pattern, name) in [
            ("tlight*", "light"),
            ("*light", "lights"),
            ("t?ght", "tght"),
            ("a*b*c", "aXXbYYbZ"),
            ("white", "whites"),
            ("", "x"),
        ] {
            assert!(!names(pattern, name), "{pattern} {name}");
        }
        // Applied: a pattern sets every material it names and no other; one that names
        // nothing is an error that changes nothing.
        let mut scene = two_materials();
        let o = Override::parse(Property::Emission, "?a*=5").unwrap();
        scene.apply_overrides(&[o]).unwrap();
        let le: Vec<[f64; 3]> = scene.materials.iter().map(|m| m.emission).collect();
        assert_eq!(le, [[5.0; 3], [5.0; 3]], "lamp and wall");
        let o = Override::parse(Property::Reflectance, "w*=0").unwrap();
        scene.apply_overrides(&[o]).unwrap();
        assert_eq!(scene.materials[0].reflectance, [0.5; 3], "lamp kept");
        assert_eq!(scene.materials[1].reflectance, [0.0; 3]);
        let o = Override::parse(Property::Reflectance, "x*=1").unwrap();
        let e = scene.apply_overrides(&[o]).unwrap_err().to_string();
        assert!(e.contains("no material 'x*'"), "{e}");
        assert_eq!(scene.materials[1].reflectance, [0.0; 3]);
    }

    use super::*;
    use crate::scene::SceneBuilder;

    fn two_materials() -> Scene {
        let mut b = SceneBuilder::new();
        let lamp = b.material("lamp", [0.5; 3], [1.0, 2.0, 3.0]);
        let wall = b.material("wall", [0.2, 0.3, 0.4], [0.0; 3]);
        b.quad([DVec3::ZERO, DVec3::X, DVec3::ONE, DVec3::Y], lamp);
        b.quad(
            [
                DVec3::Z,
                DVec3::Z + DVec3::Y,
                DVec3::ONE,
                DVec3::Z + DVec3::X,
            ],
            wall,
        );
        b.build().unwrap()
    }

    #[test]
    fn parse_accepts_grey_rgb_star_and_names_with_equals() {
        let o = Override::parse(Property::Reflectance, "white=0.25").unwrap();
        assert_eq!((o.material.as_str(), o.value), ("white", [0.25; 3]));
        let o = Override::parse(Property::Emission, " * = 1, 2 ,3").unwrap();
        assert_eq!((o.material.as_str(), o.value), ("*", [1.0, 2.0, 3.0]));
        let o = Override::parse(Property::Emission, "a=b=4").unwrap();
        assert_eq!((o.material.as_str(), o.value), ("a=b", [4.0; 3]));
        assert_eq!(o.to_string(), "emission a=b=4,4,4");
        let back = Override::parse(Property::Emission, "a=b=4,4,4").unwrap();
        assert_eq!(back, o, "the display form parses back");
    }

    #[test]
    fn parse_rejects_bad_text_and_values_naming_the_option() {
        let cases = [
            (Property::Reflectance, "white", "MATERIAL=R,G,B"),
            (Property::Reflectance, "=0.5", "no material name"),
            (Property::Reflectance, "white=0.5,0.5", "1 or 3 numbers"),
            (Property::Reflectance, "white=x", "malformed number \"x\""),
            (Property::Reflectance, "white=1.5", "not in [0, 1]"),
            (Property::Reflectance, "white=NaN", "not in [0, 1]"),
            (Property::Emission, "light=1,-1,1", "≥ 0"),
            (Property::Emission, "light=inf", "≥ 0"),
            (Property::Emission, "light=nan", "≥ 0"),
        ];
        for (property, text, needle) in cases {
            let e = Override::parse(property, text).unwrap_err();
            let msg = e.to_string();
            assert!(matches!(e, Error::Setting { .. }), "{text}: {e:?}");
            assert!(msg.contains(property.name()), "{text}: {msg}");
            assert!(msg.contains(needle), "{text}: {needle} not in {msg}");
        }
    }

    #[test]
    fn later_overrides_win_and_star_means_all() {
        let rho = |s: &Scene| {
            s.materials
                .iter()
                .map(|m| m.reflectance)
                .collect::<Vec<_>>()
        };
        let mut s = two_materials();
        let star = Override::parse(Property::Reflectance, "*=0.5").unwrap();
        let wall = Override::parse(Property::Reflectance, "wall=0.7").unwrap();
        s.apply_overrides(&[star.clone(), wall.clone()]).unwrap();
        assert_eq!(rho(&s), [[0.5; 3], [0.7; 3]]);
        s.apply_overrides(&[wall, star]).unwrap();
        assert_eq!(rho(&s), [[0.5; 3], [0.5; 3]]);

        let off = Override::parse(Property::Emission, "lamp=0").unwrap();
        assert!(s.has_emitters());
        s.apply_overrides(&[off]).unwrap();
        assert!(!s.has_emitters());
        assert_eq!(s.materials[0].reflectance, [0.5; 3], "emission only");
    }

    #[test]
    fn unknown_material_or_bad_value_changes_nothing() {
        let mut s = two_materials();
        let before = s.materials.clone();
        let ok = Override::parse(Property::Emission, "wall=5").unwrap();
        let unknown = Override::parse(Property::Emission, "nosuch=1").unwrap();
        let e = s.apply_overrides(&[ok.clone(), unknown]).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, Error::Setting { .. }), "{e:?}");
        for needle in ["invalid emission", "'nosuch'", "lamp, wall"] {
            assert!(msg.contains(needle), "{needle} not in {msg}");
        }
        assert_eq!(s.materials, before);

        // Fields are public: a value built by hand is checked too.
        let hot = Override {
            material: "*".into(),
            property: Property::Reflectance,
            value: [0.5, 1.01, 0.5],
        };
        let e = s.apply_overrides(&[ok, hot]).unwrap_err();
        assert!(e.to_string().contains("invalid reflectance"), "{e}");
        assert_eq!(s.materials, before);
    }
}
