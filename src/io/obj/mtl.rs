//! MTL material libraries: read and checked line by line (`newmtl`, `Kd` → ρ, `Ke` → Le; a
//! single-value `Kd r` means `r r r`), handed to `tobj` as a normalised copy with the same line
//! numbering, and its materials converted to ours.

use std::path::Path;

use super::parse_number;
use crate::io::parse_error;
use crate::scene::Material;
use crate::{Error, Result};

/// Reads the MTL file `mtl` named by the `mtllib` at `obj:line` and returns its normalised
/// text for `tobj`.
pub(super) fn read_mtl(obj: &Path, line: usize, mtl: &Path) -> Result<String> {
    let text = match std::fs::read(mtl) {
        Ok(bytes) => String::from_utf8(bytes).map_err(|_| "not UTF-8 text".to_string()),
        Err(e) => Err(e.to_string()),
    }
    .map_err(|why| {
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
/// grey) and returns the normalised copy for `tobj`: those statements only, same lines.
fn scan_mtl(path: &Path, text: &str) -> Result<String> {
    let mut out = String::with_capacity(text.len());
    let mut current: Option<&str> = None;
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
                out.push_str("newmtl ");
                out.push_str(name);
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
    Ok(out)
}

/// `Kd` → ρ (0.5 grey with a warning when missing), `Ke` → Le (tobj ≥ 4.0.4 fills
/// `emissive`; older versions left it in `unknown_param["Ke"]`), 0 when missing.
pub(super) fn convert_material(m: &tobj::Material, warnings: &mut Vec<String>) -> Material {
    let reflectance = m.diffuse.map(|c| c.map(f64::from)).unwrap_or_else(|| {
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
    Material {
        name: m.name.clone(),
        reflectance,
        emission,
    }
}
