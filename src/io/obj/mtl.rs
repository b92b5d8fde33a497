//! MTL material libraries: read and checked line by line (`newmtl`, `Kd` → ρ, `Ke` → Le; a
//! single-value `Kd r` means `r r r`), handed to `tobj` as a normalised copy with the same line
//! numbering, and its materials converted to ours. What the solver cannot use as it is, the
//! scan records apart ([`Extras`]): a diffuse texture (`map_Kd`), whose mean colour times `Kd`
//! becomes ρ ([`read_texture`]; across faces with texture coordinates, the texture's colour
//! under each patch: [`crate::scene::texture`]), and a specular `Ks`,
//! which a diffuse solver drops (a material with `Kd 0` and `Ks > 0` bakes black, and says so).

use std::path::Path;

use super::parse_number;
use crate::io::parse_error;
use crate::scene::listed_names_all;
use crate::scene::{Material, Texture, WarningDetail};
use crate::{Error, Result};

/// What a material of an MTL file has beyond `Kd` and `Ke` that the loader acts on.
#[derive(Debug, Clone, Default)]
pub(super) struct Extras {
    /// The material's name.
    pub name: String,
    /// `map_Kd`: the texture's path as written (relative to the MTL's directory) and its line.
    pub texture: Option<(String, usize)>,
    /// `Ks`, the specular colour (ignored by the solver).
    pub specular: Option<[f64; 3]>,
    /// `d`, the covered share (dissolve), in [0, 1].
    pub dissolve: Option<f64>,
    /// `Tr`, the transmitted share (1 − d), in [0, 1].
    pub tr: Option<f64>,
}

/// Reads the MTL file `mtl` named by the `mtllib` at `obj:line` and returns its normalised
/// text for `tobj` and each material's [`Extras`].
pub(super) fn read_mtl(obj: &Path, line: usize, mtl: &Path) -> Result<(String, Vec<Extras>)> {
    // A file that cannot be read, or is not UTF-8 text (then with its own line), is an error
    // at the `mtllib` that names it.
    let text = super::read_text(mtl).map_err(|e| {
        let why = match e {
            Error::Io { source, .. } => source.to_string(),
            other => other.to_string(),
        };
        parse_error(
            obj,
            line,
            format!("cannot read material library {}: {why}", mtl.display()),
        )
    })?;
    scan_mtl(mtl, &text)
}

/// A `tobj` error our own scan did not foresee: no line number to give.
pub(super) fn tobj_failure(path: &Path, e: tobj::LoadError) -> Error {
    Error::Input {
        path: path.to_path_buf(),
        message: format!("tobj could not parse the file: {e} (no offending line found)"),
    }
}

/// Checks `newmtl`, `Kd` and `Ke` (ρ in [0, 1], Le finite and ≥ 0, 3 numbers or 1 meaning
/// grey) and returns the normalised copy for `tobj` (those statements only, same lines) and
/// the [`Extras`] of every material: `map_Kd` (its last word is the file; options before it
/// are ignored) and `Ks` (read leniently: a malformed one is ignored, as the solver does not
/// use it).
fn scan_mtl(path: &Path, text: &str) -> Result<(String, Vec<Extras>)> {
    let mut out = String::with_capacity(text.len());
    let mut current: Option<&str> = None;
    let mut extras: Vec<Extras> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let ln = i + 1;
        let line = raw.trim();
        let mut words = line.split_whitespace();
        let keyword = words.next().unwrap_or("");
        match keyword {
            "newmtl" => {
                let name = line[keyword.len()..].trim();
                if name.is_empty() {
                    return Err(parse_error(path, ln, "newmtl without a material name"));
                }
                current = Some(name);
                extras.push(Extras {
                    name: name.to_string(),
                    ..Extras::default()
                });
                out.push_str("newmtl ");
                out.push_str(name);
            }
            "map_Kd" => {
                if let (Some(e), Some(file)) = (extras.last_mut(), words.last()) {
                    e.texture = Some((file.to_string(), ln));
                }
            }
            "d" | "Tr" => {
                // `d -halo 0.5`: the value is the last word.
                let Some(word) = words.last() else {
                    return Err(parse_error(path, ln, format!("{keyword} without a value")));
                };
                let what = format!("material '{}': {keyword}", current.unwrap_or("?"));
                let v = f64::from(parse_number(path, ln, &what, word)?);
                if !(0.0..=1.0).contains(&v) {
                    return Err(parse_error(
                        path,
                        ln,
                        format!("{what} = {v}: must be in [0, 1] (a share of the light)"),
                    ));
                }
                if let Some(e) = extras.last_mut() {
                    if keyword == "d" {
                        e.dissolve = Some(v);
                    } else {
                        e.tr = Some(v);
                    }
                }
            }
            "Ks" => {
                let v: Vec<f64> = words.filter_map(|w| w.parse().ok()).collect();
                if let Some(e) = extras.last_mut() {
                    e.specular = match v[..] {
                        [x] => Some([x; 3]),
                        [r, g, b, ..] => Some([r, g, b]),
                        _ => None,
                    };
                }
            }
            "Kd" | "Ke" => {
                // Outside a material tobj would drop the value too; ignore it likewise.
                let Some(material) = current else {
                    out.push('\n');
                    continue;
                };
                let what = format!("material '{material}': {keyword}");
                let tokens: Vec<&str> = words.collect();
                let tokens = match tokens.len() {
                    1 => vec![tokens[0]; 3],
                    n if n >= 3 => tokens[..3].to_vec(),
                    n => {
                        let form = if tokens.first().is_some_and(|t| t.parse::<f64>().is_err()) {
                            " (spectral and xyz forms are not supported)"
                        } else {
                            ""
                        };
                        return Err(parse_error(
                            path,
                            ln,
                            format!("{what}: expected 3 numbers r g b, found {n}{form}"),
                        ));
                    }
                };
                let mut rgb = [0.0; 3];
                for (c, s) in rgb.iter_mut().zip(&tokens) {
                    *c = parse_number(path, ln, &what, s)?;
                }
                let bad = if keyword == "Kd" {
                    rgb.iter()
                        .any(|c| !(0.0..=1.0).contains(c))
                        .then_some("reflectance must be in [0, 1]")
                } else {
                    rgb.iter()
                        .any(|c| !c.is_finite() || *c < 0.0)
                        .then_some("emission must be finite and ≥ 0")
                };
                if let Some(why) = bad {
                    return Err(parse_error(
                        path,
                        ln,
                        format!("{what} = {} {} {}: {why}", rgb[0], rgb[1], rgb[2]),
                    ));
                }
                out.push_str(keyword);
                for t in &tokens {
                    out.push(' ');
                    out.push_str(t);
                }
            }
            _ => {}
        }
        out.push('\n');
    }
    Ok((out, extras))
}

/// An image file as a linear texture with its mean colour ([`crate::io::linear_texture`]);
/// reads PNG, JPEG, TGA and BMP, and the error says why a file cannot be used.
pub(super) fn read_texture(file: &Path) -> std::result::Result<Texture, String> {
    let image = image::ImageReader::open(file)
        .map_err(|e| e.to_string())?
        .with_guessed_format()
        .map_err(|e| e.to_string())?
        .decode()
        .map_err(|e| e.to_string())?;
    crate::io::linear_texture(image, file.display().to_string())
        .ok_or_else(|| "the image has no pixels".into())
}

/// `Kd` → ρ (when missing: 1 for a material with a texture, which [`apply_extras`] then
/// multiplies by the texture's mean colour; otherwise 0.5 grey with a warning), `Ke` → Le
/// (tobj ≥ 4.0.4 fills `emissive`; older versions left it in `unknown_param["Ke"]`), 0 when
/// missing.
pub(super) fn convert_material(
    m: &tobj::Material,
    textured: bool,
    warnings: &mut Vec<String>,
) -> Material {
    let reflectance = m.diffuse.map(|c| c.map(f64::from)).unwrap_or_else(|| {
        if textured {
            return [1.0; 3];
        }
        warnings.push(format!("material '{}' has no Kd; using ρ = 0.5", m.name));
        [0.5; 3]
    });
    let emission = m
        .emissive
        .map(|c| c.map(f64::from))
        .or_else(|| {
            let values: Vec<f64> = m
                .unknown_param
                .get("Ke")?
                .split_whitespace()
                .map(str::parse)
                .collect::<std::result::Result<_, _>>()
                .ok()?;
            values.try_into().ok()
        })
        .unwrap_or([0.0; 3]);
    Material::opaque(m.name.clone(), reflectance, emission)
}

/// The share of light a material lets through, from its MTL statements: `d` (dissolve, the
/// covered share: t = 1 − d) when given, else `Tr` (t = Tr, the same thing written the other
/// way), else 0.
fn transmittance(e: &Extras) -> f64 {
    match (e.dissolve, e.tr) {
        (Some(d), _) => 1.0 - d,
        (None, Some(tr)) => tr,
        (None, None) => 0.0,
    }
}

/// Applies each material's `d` / `Tr` ([`transmittance`]; `extras` as for [`apply_extras`],
/// the last definition of a name winning) to the converted `materials`
/// ([`Material::with_transmittance`]). Some exporters write `d 0` or `Tr 1` on every
/// material, meaning opaque (the inverse of the MTL convention): when every material would
/// let all light through there would be nothing to bake, so they stay opaque, with a warning.
pub(super) fn apply_transmittance(
    materials: &mut [Material],
    extras: &[(std::path::PathBuf, Extras)],
    warnings: &mut Vec<String>,
) {
    let t: Vec<f64> = materials
        .iter()
        .map(|m| {
            extras
                .iter()
                .rev()
                .find(|(_, e)| e.name == m.name)
                .map_or(0.0, |(_, e)| transmittance(e))
        })
        .collect();
    if t.iter().all(|&t| t == 0.0) {
        return;
    }
    if t.iter().all(|&t| t >= 1.0) {
        warnings.push(format!(
            "every material is fully transparent by its `d` or `Tr` ({} of them): read as \
             opaque, taking `d 0` / `Tr 1` for an exporter's inverted convention",
            t.len()
        ));
        return;
    }
    for (m, t) in materials.iter_mut().zip(t) {
        *m = m.clone().with_transmittance(t);
    }
}

/// The file of a `map_Kd` named `file` in the MTL file `mtl`: relative to the MTL's
/// directory, a backslash read as a slash (files written on Windows separate folders so).
pub(super) fn texture_path(mtl: &Path, file: &str) -> std::path::PathBuf {
    mtl.parent()
        .unwrap_or(Path::new(""))
        .join(file.replace('\\', "/"))
}

/// Applies what the MTL files had beyond `Kd` and `Ke` to the converted `materials`:
/// `extras` holds each material's [`Extras`] with its MTL file (the last definition of a name
/// wins; texture paths are relative to the MTL's directory). A texture's mean colour
/// ([`read_texture`]) multiplies ρ; a texture that cannot be read is a warning (ρ stays `Kd`,
/// or 0.5 without one). One warning lists the textured materials, one the specular-only
/// materials (ρ = 0 with `Ks` > 0), which bake black. Returns the textures read (each file
/// once) and, per material, the index of its texture among them: faces with texture
/// coordinates vary ρ with it ([`crate::scene::texture`]).
pub(super) fn apply_extras(
    materials: &mut [Material],
    extras: &[(std::path::PathBuf, Extras)],
    (warnings, details): (&mut Vec<String>, &mut Vec<WarningDetail>),
) -> (Vec<Texture>, Vec<Option<u32>>) {
    let mut read: std::collections::HashMap<std::path::PathBuf, std::result::Result<u32, String>> =
        std::collections::HashMap::new();
    let mut textures = Vec::new();
    let mut texture_of = vec![None; materials.len()];
    let mut textured = Vec::new();
    let mut specular_only = Vec::new();
    for (k, m) in materials.iter_mut().enumerate() {
        let Some((mtl, e)) = extras.iter().rev().find(|(_, e)| e.name == m.name) else {
            continue;
        };
        if let Some((file, line)) = &e.texture {
            let path = texture_path(mtl, file);
            let index = read.entry(path.clone()).or_insert_with(|| {
                read_texture(&path).map(|t| {
                    textures.push(t);
                    (textures.len() - 1) as u32
                })
            });
            match index {
                Ok(i) => {
                    let mean = textures[*i as usize].mean;
                    for (r, t) in m.reflectance.iter_mut().zip(mean.iter()) {
                        *r = (*r * t).clamp(0.0, 1.0);
                    }
                    texture_of[k] = Some(*i);
                    textured.push(m.name.clone());
                }
                Err(why) => {
                    let kd = if m.reflectance == [1.0; 3] {
                        m.reflectance = [0.5; 3];
                        "0.5 (it has no Kd)"
                    } else {
                        "its Kd"
                    };
                    warnings.push(format!(
                        "material '{}': its texture {} (map_Kd at {}:{line}) cannot be read \
                         ({why}); ρ is {kd}",
                        m.name,
                        path.display(),
                        mtl.display()
                    ));
                }
            }
        }
        let shiny = e.specular.is_some_and(|ks| ks.iter().any(|&k| k > 0.0));
        if shiny && m.transmittance == 0.0 && m.reflectance.iter().all(|&r| r == 0.0) {
            specular_only.push(m.name.clone());
        }
    }
    if !textured.is_empty() {
        let n = textured.len();
        warnings.push(format!(
            "{n} material{} with a texture (map_Kd): ρ = Kd × the texture averaged over each \
             patch of the faces with texture coordinates (vt), Kd × its mean colour elsewhere; \
             the texture's detail finer than a patch is not baked: {}",
            if n == 1 { "" } else { "s" },
            listed_names_all("textured_materials", &textured, details)
        ));
    }
    if !specular_only.is_empty() {
        let n = specular_only.len();
        warnings.push(format!(
            "{n} material{} specular only (Kd 0 with Ks > 0): the solver is diffuse and \
             reads Kd as ρ, so {} black; give {} a reflectance with --reflectance NAME=R,G,B, \
             or, for glass, `d` below 1 in the MTL so that light passes: {}",
            if n == 1 { " is" } else { "s are" },
            if n == 1 { "it bakes" } else { "they bake" },
            if n == 1 { "it" } else { "them" },
            listed_names_all("specular_only_materials", &specular_only, details)
        ));
    }
    (textures, texture_of)
}
