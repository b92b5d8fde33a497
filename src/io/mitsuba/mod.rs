//! Mitsuba XML scenes in (the formats of Mitsuba 0.6, 2 and 3), read with `roxmltree` into a
//! [`Scene`] ([`load`]). This module owns mapping Mitsuba's scene description (shapes,
//! BSDFs, emitters, the sensor) onto ours and saying, in warnings, what it leaves out; the
//! triangle meshes the scene names are read by our own [`crate::io::obj`] and
//! [`crate::io::ply`] loaders, and welding and validation are the shared `scene::finish`'s.
//! It does not write Mitsuba files, and reads no spectral, glossy or volumetric data beyond
//! the diffuse colours below.
//!
//! What is read:
//! - `<default name value>` and `$name` in any attribute value (Mitsuba 3's substitution; a
//!   `$name` without a default is an error naming it);
//! - shapes `obj` and `ply` (the file relative to the XML's directory), `rectangle` ([−1, 1]²
//!   at z = 0, front +z), `cube` ([−1, 1]³, fronts outward), `disk` (unit disk at z = 0,
//!   front +z, `shapes::DISK_SEGMENTS` segments) and `sphere` (`center`, `radius`; an
//!   icosphere of 5120 triangles, fronts outward), each with its `to_world` (`toWorld` in 0.6)
//!   and `flip_normals`; a transform that mirrors turns the winding back, so fronts stay on
//!   the side Mitsuba's normals give;
//! - transforms: `translate`, `scale`, `rotate` (degrees), `matrix` (16 values, row-major)
//!   and `lookat`, each left-multiplying the ones before it as in Mitsuba;
//! - BSDFs, nested in shapes or by `id` and `<ref id>`: `diffuse` (ρ = `reflectance`),
//!   `twosided` (its inner BSDF, on both sides of the faces: they get twins,
//!   [`Scene::make_two_sided_where`]), glass (`dielectric`, `thindielectric`,
//!   `roughdielectric`: clear, [`Material::transmittance`] 1, so the faces are left out and
//!   light passes straight), and any other BSDF by its diffuse
//!   colour (`diffuse_reflectance`, `base_color` or `reflectance`; else ρ = 0.5), each with
//!   one warning. Colours are `rgb`, `srgb` (decoded), `spectrum` (one value: grey; a
//!   `wavelength:value` list: its mean value as grey, with a warning), `float`, or a `bitmap`
//!   texture's mean linear colour (`io::texture_mean`; per-texel variation is not
//!   read, with a warning). A ρ outside [0, 1] is clamped, with a warning;
//! - emitters: `area` in a shape (its `radiance` is the material's Le, W·sr⁻¹·m⁻²), `point`
//!   and `spot` (`intensity` W·sr⁻¹; a spot's `cutoff_angle` and `beam_width`, degrees, as the
//!   outer and inner cone of a [`PointLight`]), `constant` (its `radiance` as
//!   [`Scene::sky`], W·sr⁻¹·m⁻²: our sky lights from above the horizon only) and
//!   `directional` (`irradiance` W·m⁻² as [`Scene::sun`], its direction taken with +Y up,
//!   Mitsuba's usual and the bake's default `--up`). `envmap` is not read (a warning says
//!   to use `--sky`);
//! - the first `perspective` (or `thinlens`) sensor: `to_world` and `fov` along `fov_axis`
//!   (x by default; the film's `width` × `height`, 768 × 576 by default, turns it into our
//!   vertical field of view) as [`Scene::camera`].
//!
//! Everything else (integrators, samplers, media, unknown shapes and emitters, …) is
//! named with its count in one warning. Malformed XML, a bad number, an unknown `ref`, a
//! missing file and the like are [`Error::Parse`] naming the XML file and the line.

mod shapes;

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3};
use roxmltree::{Document, Node, NodeId};

use crate::color::Rgb;
use crate::io::parse_error;
use crate::scene::{
    finish, listed_all, listed_names_all, Camera, Material, Scene, SceneTriangle, NO_UV,
};
use crate::scene::{PointLight, Spot, Sun, Up};
use crate::{Error, Result};

/// The film Mitsuba assumes when the sensor names none, pixels.
pub const DEFAULT_FILM: (f64, f64) = (768.0, 576.0);

/// Loads a Mitsuba XML scene and the meshes it names into a [`Scene`]; see the module
/// documentation for what is read. Errors name the XML file and the line, or the mesh file.
pub fn load(path: &Path) -> Result<Scene> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let text = String::from_utf8(bytes)
        .map_err(|_| parse_error(path, 1, "not UTF-8 text (save the XML as UTF-8)"))?;
    let doc = Document::parse(&text)
        .map_err(|e| parse_error(path, e.pos().row as usize, format!("malformed XML: {e}")))?;
    let root = doc.root_element();
    let mut reader = Reader::new(path, &doc);
    if root.tag_name().name() != "scene" {
        return Err(reader.error(
            root,
            format!(
                "the root element is <{}>, expected <scene>",
                root.tag_name().name()
            ),
        ));
    }
    reader.index(root)?;
    for node in root.children().filter(Node::is_element) {
        reader.top(node)?;
    }
    reader.finish()
}

/// What a BSDF gives the faces of a shape.
#[derive(Debug, Clone)]
struct Surface {
    /// The BSDF's `id`, or its type and line.
    name: String,
    /// ρ per RGB channel, in [0, 1].
    reflectance: Rgb,
    /// Clear glass: transmittance 1.
    glass: bool,
    /// Under a `twosided`: both sides reflect.
    two_sided: bool,
}

/// The state of reading one XML file.
struct Reader<'a, 'input> {
    path: &'a Path,
    dir: PathBuf,
    doc: &'a Document<'input>,
    /// `<default>` values by name.
    defaults: HashMap<String, String>,
    /// Elements with an `id`, for `<ref>`.
    ids: HashMap<String, Node<'a, 'input>>,
    positions: Vec<DVec3>,
    triangles: Vec<SceneTriangle>,
    materials: Vec<Material>,
    /// Our material for a BSDF element (or none: the default) and an emitted radiance.
    material_of: HashMap<(Option<NodeId>, [u64; 3]), u32>,
    surfaces: HashMap<NodeId, Surface>,
    /// Names of the materials whose faces get twins.
    two_sided: Vec<String>,
    glass: Vec<String>,
    /// Other BSDFs: "'name' (type: what was used)".
    other: Vec<String>,
    textured: Vec<String>,
    averaged_spectra: Vec<String>,
    clamped: Vec<String>,
    /// Elements not read, by tag and type, with their counts.
    unread: BTreeMap<String, usize>,
    warnings: Vec<String>,
    /// The full lists behind list-type warnings ([`crate::scene::WarningDetail`]).
    details: Vec<crate::scene::WarningDetail>,
    lights: Vec<PointLight>,
    sun: Option<Sun>,
    sky: Option<Rgb>,
    camera: Option<Camera>,
}

/// True if a property's name is `wanted`, in Mitsuba 3's snake case or 0.6's camel case
/// (`to_world` / `toWorld`).
fn same_name(name: &str, wanted: &str) -> bool {
    let fold = |s: &str| {
        s.chars()
            .filter(|&c| c != '_')
            .map(|c| c.to_ascii_lowercase())
            .collect::<String>()
    };
    fold(name) == fold(wanted)
}

impl<'a, 'input> Reader<'a, 'input> {
    fn new(path: &'a Path, doc: &'a Document<'input>) -> Self {
        Reader {
            path,
            dir: path.parent().unwrap_or(Path::new("")).to_path_buf(),
            doc,
            defaults: HashMap::new(),
            ids: HashMap::new(),
            positions: Vec::new(),
            triangles: Vec::new(),
            materials: Vec::new(),
            material_of: HashMap::new(),
            surfaces: HashMap::new(),
            two_sided: Vec::new(),
            glass: Vec::new(),
            other: Vec::new(),
            textured: Vec::new(),
            averaged_spectra: Vec::new(),
            clamped: Vec::new(),
            unread: BTreeMap::new(),
            warnings: Vec::new(),
            details: Vec::new(),
            lights: Vec::new(),
            sun: None,
            sky: None,
            camera: None,
        }
    }

    /// The 1-based line `node` starts on.
    fn line(&self, node: Node) -> usize {
        self.doc.text_pos_at(node.range().start).row as usize
    }

    /// An [`Error::Parse`] at `node`'s line.
    fn error(&self, node: Node, message: impl Into<String>) -> Error {
        parse_error(self.path, self.line(node), message)
    }

    /// Records `node` as not read, by its tag and type.
    fn skip(&mut self, node: Node) {
        let key = match node.attribute("type") {
            Some(t) => format!("<{}> '{t}'", node.tag_name().name()),
            None => format!("<{}>", node.tag_name().name()),
        };
        *self.unread.entry(key).or_default() += 1;
    }

    /// The `<default>`s of the scene (in order, a later one replacing an earlier) and every
    /// element with an `id`. Ids are substituted with the defaults read before them.
    fn index(&mut self, root: Node<'a, 'input>) -> Result<()> {
        for node in root.children().filter(|n| n.has_tag_name("default")) {
            let (Some(name), Some(value)) = (node.attribute("name"), node.attribute("value"))
            else {
                return Err(self.error(node, "<default> needs a name and a value"));
            };
            let value = self.substitute(node, value)?;
            self.defaults.insert(name.to_string(), value);
        }
        // A `<ref id>` names an element: it is not one.
        for node in root
            .descendants()
            .filter(|n| n.is_element() && !n.has_tag_name("ref"))
        {
            if let Some(id) = self.attr(node, "id")? {
                self.ids.insert(id, node);
            }
        }
        Ok(())
    }

    /// `value` with every `$name` replaced by its default; an error at `node` names a
    /// `$name` without one.
    fn substitute(&self, node: Node, value: &str) -> Result<String> {
        if !value.contains('$') {
            return Ok(value.to_string());
        }
        let mut out = String::with_capacity(value.len());
        let mut rest = value;
        while let Some(i) = rest.find('$') {
            out.push_str(&rest[..i]);
            let after = &rest[i + 1..];
            let len = after
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .unwrap_or(after.len());
            let name = &after[..len];
            match self.defaults.get(name) {
                Some(v) if !name.is_empty() => out.push_str(v),
                _ => {
                    return Err(self.error(
                        node,
                        format!("'${name}' has no <default name=\"{name}\" value=…/>"),
                    ))
                }
            }
            rest = &after[len..];
        }
        out.push_str(rest);
        Ok(out)
    }

    /// Attribute `name` of `node`, substituted.
    fn attr(&self, node: Node, name: &str) -> Result<Option<String>> {
        node.attribute(name)
            .map(|v| self.substitute(node, v))
            .transpose()
    }

    /// The numbers of attribute `name` of `node` (separated by commas and/or whitespace).
    fn numbers(&self, node: Node, name: &str) -> Result<Option<Vec<f64>>> {
        let Some(text) = self.attr(node, name)? else {
            return Ok(None);
        };
        let mut out = Vec::new();
        for word in text.split(|c: char| c == ',' || c.is_whitespace()) {
            if word.is_empty() {
                continue;
            }
            match word.parse::<f64>() {
                Ok(x) if x.is_finite() => out.push(x),
                _ => {
                    return Err(self.error(
                        node,
                        format!(
                            "<{}> {name}=\"{text}\": '{word}' is not a finite number",
                            node.tag_name().name()
                        ),
                    ))
                }
            }
        }
        Ok(Some(out))
    }

    /// Attribute `name` as one number, `default` when absent.
    fn number(&self, node: Node, name: &str, default: f64) -> Result<f64> {
        match self.numbers(node, name)? {
            None => Ok(default),
            Some(v) if v.len() == 1 => Ok(v[0]),
            Some(v) => Err(self.error(
                node,
                format!(
                    "<{}> {name}: expected one number, found {}",
                    node.tag_name().name(),
                    v.len()
                ),
            )),
        }
    }

    /// A vector from `value="x y z"` (or `value="s"` for (s, s, s) when `splat`) or from the
    /// `x`, `y`, `z` attributes, each `default` when absent.
    fn xyz(&self, node: Node, default: f64, splat: bool) -> Result<DVec3> {
        if let Some(v) = self.numbers(node, "value")? {
            return match v[..] {
                [x, y, z] => Ok(DVec3::new(x, y, z)),
                [s] if splat => Ok(DVec3::splat(s)),
                _ => Err(self.error(
                    node,
                    format!(
                        "<{}> value: expected three numbers, found {}",
                        node.tag_name().name(),
                        v.len()
                    ),
                )),
            };
        }
        Ok(DVec3::new(
            self.number(node, "x", default)?,
            self.number(node, "y", default)?,
            self.number(node, "z", default)?,
        ))
    }

    /// The first child element of `node` whose `name` is one of `names`.
    fn prop(&self, node: Node<'a, 'input>, names: &[&str]) -> Result<Option<Node<'a, 'input>>> {
        for child in node.children().filter(Node::is_element) {
            if let Some(name) = self.attr(child, "name")? {
                if names.iter().any(|w| same_name(&name, w)) {
                    return Ok(Some(child));
                }
            }
        }
        Ok(None)
    }

    /// A number property (`<float>` or `<integer>`), `default` when absent.
    fn float_prop(&self, node: Node<'a, 'input>, names: &[&str], default: f64) -> Result<f64> {
        match self.prop(node, names)? {
            Some(p) => self.number(p, "value", default),
            None => Ok(default),
        }
    }

    /// A string property's value.
    fn string_prop(&self, node: Node<'a, 'input>, name: &str) -> Result<Option<String>> {
        match self.prop(node, &[name])? {
            Some(p) => self.attr(p, "value"),
            None => Ok(None),
        }
    }

    /// A `<boolean>` property, false when absent.
    fn bool_prop(&self, node: Node<'a, 'input>, name: &str) -> Result<bool> {
        let Some(p) = self.prop(node, &[name])? else {
            return Ok(false);
        };
        match self.attr(p, "value")?.as_deref() {
            Some("true") => Ok(true),
            Some("false") | None => Ok(false),
            Some(v) => Err(self.error(p, format!("<boolean> {name}: '{v}' is not true or false"))),
        }
    }

    /// A file named by attribute or property `filename` of `node`, relative to the XML's
    /// directory; an error at `node` if it is not a file.
    fn file(&self, node: Node<'a, 'input>, what: &str) -> Result<PathBuf> {
        let Some(name) = self.string_prop(node, "filename")? else {
            return Err(self.error(node, format!("{what} has no filename")));
        };
        let file = self.dir.join(&name);
        if !file.is_file() {
            return Err(self.error(
                node,
                format!("{what}: file '{name}' not found ({})", file.display()),
            ));
        }
        Ok(file)
    }

    /// The element a `<ref id>` names (or `node` itself if it is not a reference).
    fn resolve(&self, node: Node<'a, 'input>) -> Result<Node<'a, 'input>> {
        if !node.has_tag_name("ref") {
            return Ok(node);
        }
        let id = self
            .attr(node, "id")?
            .ok_or_else(|| self.error(node, "<ref> without an id"))?;
        self.ids
            .get(&id)
            .copied()
            .ok_or_else(|| self.error(node, format!("<ref id=\"{id}\">: no element has this id")))
    }

    /// The `to_world` transform of `node` (identity when it has none).
    fn world_transform(&mut self, node: Node<'a, 'input>) -> Result<DMat4> {
        match self.prop(node, &["to_world"])? {
            Some(t) if t.has_tag_name("transform") => self.transform(t),
            Some(t) => Err(self.error(t, "to_world is not a <transform>")),
            None => Ok(DMat4::IDENTITY),
        }
    }

    /// A `<transform>`: its steps in document order, each left-multiplying the product of
    /// those before it (the first step is applied to a point first).
    fn transform(&mut self, node: Node<'a, 'input>) -> Result<DMat4> {
        let mut m = DMat4::IDENTITY;
        for step in node.children().filter(Node::is_element) {
            let t = match step.tag_name().name() {
                "translate" => DMat4::from_translation(self.xyz(step, 0.0, false)?),
                "scale" => DMat4::from_scale(self.xyz(step, 1.0, true)?),
                "rotate" => {
                    let axis = match self.numbers(step, "axis")? {
                        Some(v) if v.len() == 3 => DVec3::new(v[0], v[1], v[2]),
                        Some(_) => {
                            return Err(self.error(step, "<rotate> axis: expected three numbers"))
                        }
                        None => self.xyz(step, 0.0, false)?,
                    };
                    let angle = self.number(step, "angle", 0.0)?;
                    let axis = axis
                        .try_normalize()
                        .ok_or_else(|| self.error(step, "<rotate> needs a non-zero axis"))?;
                    DMat4::from_axis_angle(axis, angle.to_radians())
                }
                "matrix" => {
                    let v = self.numbers(step, "value")?.unwrap_or_default();
                    match v.len() {
                        16 => DMat4::from_cols_slice(&v).transpose(),
                        9 => DMat4::from_mat3(glam::DMat3::from_cols_slice(&v).transpose()),
                        n => {
                            return Err(self.error(
                                step,
                                format!("<matrix> value: expected 16 numbers, found {n}"),
                            ))
                        }
                    }
                }
                "lookat" => {
                    let point = |name: &str| -> Result<Option<DVec3>> {
                        match self.numbers(step, name)? {
                            None => Ok(None),
                            Some(v) if v.len() == 3 => Ok(Some(DVec3::new(v[0], v[1], v[2]))),
                            Some(_) => Err(self
                                .error(step, format!("<lookat> {name}: expected three numbers"))),
                        }
                    };
                    let origin = point("origin")?.unwrap_or(DVec3::ZERO);
                    let target = point("target")?.unwrap_or(DVec3::Z);
                    let up = point("up")?.unwrap_or(DVec3::Y);
                    shapes::lookat(origin, target, up).ok_or_else(|| {
                        self.error(
                            step,
                            "<lookat>: the target is the origin, or up is parallel to the view",
                        )
                    })?
                }
                _ => {
                    self.skip(step);
                    continue;
                }
            };
            m = t * m;
        }
        if !m.is_finite() {
            return Err(self.error(node, "the transform is not finite"));
        }
        Ok(m)
    }

    /// A colour: an `rgb`, `srgb`, `spectrum`, `float` or `texture` element (or a `ref` to
    /// one), for the property of the BSDF or emitter `owner`.
    fn colour(&mut self, node: Node<'a, 'input>, owner: &str) -> Result<Rgb> {
        let node = self.resolve(node)?;
        let tag = node.tag_name().name();
        let grey_or_rgb = |v: Vec<f64>| -> Option<Rgb> {
            match v[..] {
                [g] => Some([g; 3]),
                [r, g, b] => Some([r, g, b]),
                _ => None,
            }
        };
        match tag {
            "rgb" | "srgb" | "float" => {
                let text = self.attr(node, "value")?.unwrap_or_default();
                let rgb = if tag == "srgb" && text.trim_start().starts_with('#') {
                    hex(text.trim()).ok_or_else(|| {
                        self.error(node, format!("<srgb> value=\"{text}\": not #rrggbb"))
                    })?
                } else {
                    let v = self.numbers(node, "value")?.unwrap_or_default();
                    grey_or_rgb(v).ok_or_else(|| {
                        self.error(
                            node,
                            format!("<{tag}> value=\"{text}\": expected one or three numbers"),
                        )
                    })?
                };
                Ok(if tag == "srgb" {
                    rgb.map(crate::color::srgb_decode)
                } else {
                    rgb
                })
            }
            "spectrum" => {
                let Some(text) = self.attr(node, "value")? else {
                    self.skip(node);
                    return Ok([0.5; 3]);
                };
                if text.contains(':') {
                    let mut values = Vec::new();
                    for pair in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
                        let value = pair
                            .split_once(':')
                            .and_then(|(_, v)| v.trim().parse::<f64>().ok())
                            .filter(|v| v.is_finite());
                        values.push(value.ok_or_else(|| {
                            self.error(
                                node,
                                format!("<spectrum> value: '{pair}' is not wavelength:value"),
                            )
                        })?);
                    }
                    self.averaged_spectra.push(owner.to_string());
                    let mean = values.iter().sum::<f64>() / values.len().max(1) as f64;
                    return Ok([mean; 3]);
                }
                let v = self.numbers(node, "value")?.unwrap_or_default();
                if v.len() > 1 {
                    self.averaged_spectra.push(owner.to_string());
                }
                let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
                if v.is_empty() {
                    return Err(self.error(node, "<spectrum> without a value"));
                }
                Ok([mean; 3])
            }
            "texture" => self.texture(node, owner),
            _ => {
                self.skip(node);
                Ok([0.5; 3])
            }
        }
    }

    /// A texture's mean colour: a `bitmap`'s image, a `checkerboard`'s two colours' mean;
    /// other textures 0.5 grey (counted as not read).
    fn texture(&mut self, node: Node<'a, 'input>, owner: &str) -> Result<Rgb> {
        match self.attr(node, "type")?.as_deref() {
            Some("bitmap") => {
                let file = self.file(node, "bitmap texture")?;
                let image = image::open(&file).map_err(|e| {
                    self.error(
                        node,
                        format!("bitmap '{}' cannot be read: {e}", file.display()),
                    )
                })?;
                let mean = crate::io::texture_mean(image).ok_or_else(|| {
                    self.error(node, format!("bitmap '{}' has no pixels", file.display()))
                })?;
                self.textured.push(owner.to_string());
                Ok(mean)
            }
            Some("checkerboard") => {
                let mut mean = [0.0; 3];
                for (name, default) in [("color0", 0.4), ("color1", 0.2)] {
                    let c = match self.prop(node, &[name])? {
                        Some(p) => self.colour(p, owner)?,
                        None => [default; 3],
                    };
                    (0..3).for_each(|k| mean[k] += c[k] / 2.0);
                }
                self.textured.push(owner.to_string());
                Ok(mean)
            }
            _ => {
                self.skip(node);
                Ok([0.5; 3])
            }
        }
    }

    /// The colour property `names` of `node`, `default` when absent.
    fn colour_prop(
        &mut self,
        node: Node<'a, 'input>,
        names: &[&str],
        owner: &str,
    ) -> Result<Option<Rgb>> {
        match self.prop(node, names)? {
            Some(p) => self.colour(p, owner).map(Some),
            None => Ok(None),
        }
    }

    /// How `node` names itself in messages: its `id`, else its tag, type and line.
    fn label(&self, node: Node) -> Result<String> {
        Ok(match self.attr(node, "id")? {
            Some(id) => id,
            None => format!(
                "{} '{}' (line {})",
                node.tag_name().name(),
                node.attribute("type").unwrap_or("?"),
                self.line(node)
            ),
        })
    }

    /// What the BSDF `node` (a `<bsdf>`) gives its faces.
    fn surface(&mut self, node: Node<'a, 'input>) -> Result<Surface> {
        if let Some(s) = self.surfaces.get(&node.id()) {
            return Ok(s.clone());
        }
        let name = self.label(node)?;
        let kind = self.attr(node, "type")?.unwrap_or_default();
        let inner = |r: &Self| -> Result<Option<Node<'a, 'input>>> {
            for child in node.children().filter(Node::is_element) {
                let child = r.resolve(child)?;
                if child.has_tag_name("bsdf") {
                    return Ok(Some(child));
                }
            }
            Ok(None)
        };
        let mut surface = Surface {
            name: name.clone(),
            reflectance: [0.5; 3],
            glass: false,
            two_sided: false,
        };
        match kind.as_str() {
            "diffuse" => {
                if let Some(rho) = self.colour_prop(node, &["reflectance"], &name)? {
                    surface.reflectance = rho;
                }
            }
            "twosided" => {
                if let Some(inner) = inner(self)? {
                    let s = self.surface(inner)?;
                    surface.reflectance = s.reflectance;
                    surface.glass = s.glass;
                    if node.attribute("id").is_none() {
                        surface.name = s.name;
                    }
                }
                surface.two_sided = true;
            }
            "dielectric" | "thindielectric" | "roughdielectric" => {
                surface.glass = true;
                surface.reflectance = [0.0; 3];
                self.glass.push(format!("'{name}' ({kind})"));
            }
            "bumpmap" | "normalmap" | "mask" => {
                if let Some(inner) = inner(self)? {
                    surface = Surface {
                        name,
                        ..self.surface(inner)?
                    };
                }
                self.other
                    .push(format!("'{}' ({kind}: its inner BSDF's ρ)", surface.name));
            }
            _ => {
                let names = [
                    "diffuse_reflectance",
                    "base_color",
                    "reflectance",
                    "diffuse",
                ];
                let used = match self.prop(node, &names)? {
                    Some(p) => {
                        let what = p.attribute("name").unwrap_or("").to_string();
                        surface.reflectance = self.colour(p, &name)?;
                        what
                    }
                    None => "0.5 grey".to_string(),
                };
                self.other.push(format!("'{name}' ({kind}: {used})"));
            }
        }
        let rho = surface.reflectance;
        surface.reflectance = rho.map(|r| r.clamp(0.0, 1.0));
        if surface.reflectance != rho {
            self.clamped.push(surface.name.clone());
        }
        self.surfaces.insert(node.id(), surface.clone());
        Ok(surface)
    }

    /// A top-level element of the scene.
    fn top(&mut self, node: Node<'a, 'input>) -> Result<()> {
        match node.tag_name().name() {
            // Read in `index`, or when a shape refers to them.
            "default" | "bsdf" | "texture" => Ok(()),
            "shape" => self.shape(node),
            "emitter" => self.emitter(node),
            "sensor" => self.sensor(node),
            _ => {
                self.skip(node);
                Ok(())
            }
        }
    }

    /// A shape: its triangles, in world space, with the material of its BSDF and area
    /// emitter.
    fn shape(&mut self, node: Node<'a, 'input>) -> Result<()> {
        let kind = self.attr(node, "type")?.unwrap_or_default();
        let mesh = match kind.as_str() {
            "rectangle" => shapes::rectangle(),
            "cube" => shapes::cube(),
            "disk" => shapes::disk(shapes::DISK_SEGMENTS),
            "sphere" => {
                let centre = match self.prop(node, &["center"])? {
                    Some(p) => self.xyz(p, 0.0, false)?,
                    None => DVec3::ZERO,
                };
                let radius = self.float_prop(node, &["radius"], 1.0)?;
                shapes::sphere(centre, radius, shapes::SPHERE_SUBDIVISIONS)
            }
            "obj" | "ply" => {
                let file = self.file(node, &format!("shape '{kind}'"))?;
                let scene = if kind == "obj" {
                    crate::io::obj::load(&file)?
                } else {
                    crate::io::ply::load(&file)?
                };
                let name = file.file_name().unwrap_or_default().to_string_lossy();
                self.warnings
                    .extend(scene.warnings.iter().map(|w| format!("{name}: {w}")));
                self.details.extend(scene.warning_details.iter().cloned());
                shapes::Mesh {
                    positions: scene.positions,
                    triangles: scene.triangles.iter().map(|t| t.vertices).collect(),
                }
            }
            _ => {
                self.skip(node);
                return Ok(());
            }
        };
        let to_world = self.world_transform(node)?;
        let flip = self.bool_prop(node, "flip_normals")? != (to_world.determinant() < 0.0);

        let mut bsdf = None;
        let mut emission = [0.0; 3];
        for child in node.children().filter(Node::is_element) {
            let target = self.resolve(child)?;
            match target.tag_name().name() {
                "bsdf" => bsdf = bsdf.or(Some(target)),
                "emitter" if target.attribute("type") == Some("area") => {
                    let owner = self.label(node)?;
                    emission = self
                        .colour_prop(target, &["radiance"], &owner)?
                        .unwrap_or([1.0; 3]);
                    if emission.iter().any(|e| *e < 0.0) {
                        return Err(self.error(target, "area emitter: negative radiance"));
                    }
                }
                "emitter" => self.skip(target),
                _ => {}
            }
        }
        let material = self.material(node, bsdf, emission)?;

        let base = self.positions.len() as u32;
        for p in &mesh.positions {
            let q = to_world.transform_point3(*p);
            if !q.is_finite() {
                return Err(self.error(node, "to_world takes a vertex to a non-finite position"));
            }
            self.positions.push(q);
        }
        self.triangles
            .extend(mesh.triangles.iter().map(|&[a, b, c]| {
                let v = if flip { [a, c, b] } else { [a, b, c] };
                SceneTriangle {
                    vertices: v.map(|i| base + i),
                    material,
                    uv: NO_UV,
                }
            }));
        Ok(())
    }

    /// Our material for a shape with the BSDF `bsdf` (Mitsuba's default, diffuse 0.5, when
    /// none) emitting `emission` (W·sr⁻¹·m⁻²); shapes with the same BSDF and emission share
    /// one.
    fn material(
        &mut self,
        shape: Node<'a, 'input>,
        bsdf: Option<Node<'a, 'input>>,
        emission: Rgb,
    ) -> Result<u32> {
        let key = (bsdf.map(|b| b.id()), emission.map(f64::to_bits));
        if let Some(&m) = self.material_of.get(&key) {
            return Ok(m);
        }
        let surface = match bsdf {
            Some(b) => self.surface(b)?,
            None => Surface {
                name: "default".into(),
                reflectance: [0.5; 3],
                glass: false,
                two_sided: false,
            },
        };
        let name = if emission.iter().any(|&e| e > 0.0) {
            format!("{} (area light of {})", surface.name, self.label(shape)?)
        } else {
            surface.name.clone()
        };
        // One-sided as Mitsuba's BSDFs are; those under `twosided` get their twins when the
        // scene is built, so `orient` gives no face of a Mitsuba scene a back side.
        let mut material =
            Material::opaque(name.clone(), surface.reflectance, emission).with_one_sided(true);
        if surface.glass {
            material = material.with_transmittance(1.0);
        }
        if surface.two_sided {
            self.two_sided.push(name);
        }
        self.materials.push(material);
        let m = self.materials.len() as u32 - 1;
        self.material_of.insert(key, m);
        Ok(m)
    }

    /// A top-level emitter.
    fn emitter(&mut self, node: Node<'a, 'input>) -> Result<()> {
        let kind = self.attr(node, "type")?.unwrap_or_default();
        let owner = self.label(node)?;
        match kind.as_str() {
            "point" | "spot" => {
                let to_world = self.world_transform(node)?;
                let position = match self.prop(node, &["position"])? {
                    Some(p) => self.xyz(p, 0.0, false)?,
                    None => to_world.transform_point3(DVec3::ZERO),
                };
                let intensity = self
                    .colour_prop(node, &["intensity"], &owner)?
                    .unwrap_or([1.0; 3]);
                let spot = if kind == "spot" {
                    let outer = self.float_prop(node, &["cutoff_angle"], 20.0)?.min(90.0);
                    let mut inner = self.float_prop(node, &["beam_width"], outer * 0.75)?;
                    if !(0.0..outer).contains(&inner) {
                        inner = outer * 0.75;
                    }
                    let direction = to_world
                        .transform_vector3(DVec3::Z)
                        .try_normalize()
                        .ok_or_else(|| self.error(node, "spot: to_world leaves no direction"))?;
                    Some(Spot {
                        direction,
                        inner_degrees: inner,
                        outer_degrees: outer,
                    })
                } else {
                    None
                };
                let light = PointLight {
                    position,
                    intensity,
                    spot,
                };
                light
                    .check()
                    .map_err(|e| self.error(node, format!("{kind} emitter {e}")))?;
                self.lights.push(light);
            }
            "constant" => {
                let radiance = self
                    .colour_prop(node, &["radiance"], &owner)?
                    .unwrap_or([1.0; 3]);
                if radiance.iter().any(|l| *l < 0.0) {
                    return Err(self.error(node, "constant emitter: negative radiance"));
                }
                if self.sky.is_some() {
                    self.skip(node);
                } else {
                    self.sky = Some(radiance);
                }
            }
            "directional" => {
                let irradiance = self
                    .colour_prop(node, &["irradiance"], &owner)?
                    .unwrap_or([1.0; 3]);
                let direction = match self.prop(node, &["direction"])? {
                    Some(p) => self.xyz(p, 0.0, false)?,
                    None => self.world_transform(node)?.transform_vector3(DVec3::Z),
                };
                // Toward the sun is −direction; azimuth from north (+Z) toward east (−X)
                // with +Y up ([`Sun`]).
                let Some(to) = (-direction).try_normalize() else {
                    return Err(self.error(node, "directional emitter without a direction"));
                };
                let elevation = to.y.clamp(-1.0, 1.0).asin().to_degrees();
                let (north, east) = (Up::Y.forward(), Up::Y.forward().cross(Up::Y.axis()));
                if elevation <= 0.0 || self.sun.is_some() || irradiance.iter().any(|e| *e < 0.0) {
                    self.warnings.push(format!(
                        "directional emitter '{owner}' not read: it shines from below the \
                         horizon (+Y up), has a negative irradiance, or the scene already has \
                         a sun"
                    ));
                } else {
                    self.sun = Some(Sun {
                        azimuth_degrees: to.dot(east).atan2(to.dot(north)).to_degrees(),
                        elevation_degrees: elevation,
                        irradiance,
                    });
                }
            }
            "envmap" => {
                let file = self.string_prop(node, "filename")?.unwrap_or_default();
                self.warnings.push(format!(
                    "envmap emitter '{file}' (line {}) not read: bake with --sky R,G,B for a \
                     uniform sky instead",
                    self.line(node)
                ));
            }
            _ => self.skip(node),
        }
        Ok(())
    }

    /// A sensor: the first perspective one is the scene's camera.
    fn sensor(&mut self, node: Node<'a, 'input>) -> Result<()> {
        let kind = self.attr(node, "type")?.unwrap_or_default();
        if !matches!(kind.as_str(), "perspective" | "thinlens") || self.camera.is_some() {
            self.skip(node);
            return Ok(());
        }
        let (mut width, mut height) = DEFAULT_FILM;
        for child in node.children().filter(Node::is_element) {
            match child.tag_name().name() {
                "film" => {
                    width = self.float_prop(child, &["width"], width)?;
                    height = self.float_prop(child, &["height"], height)?;
                    for grandchild in child.children().filter(Node::is_element) {
                        if grandchild.has_tag_name("rfilter") {
                            self.skip(grandchild);
                        }
                    }
                }
                "sampler" => self.skip(child),
                _ => {}
            }
        }
        if width <= 0.0 || height <= 0.0 {
            return Err(self.error(node, "the film's width and height must be positive"));
        }
        // Without a fov: Mitsuba's default lens, 50 mm on a 36 mm wide film.
        let fov = self.float_prop(node, &["fov"], 2.0 * (18.0f64 / 50.0).atan().to_degrees())?;
        let axis = self.string_prop(node, "fov_axis")?.unwrap_or("x".into());
        let h_over_w = height / width;
        // tan(vfov/2) from tan(fov/2) along the named axis.
        let half = (fov.to_radians() / 2.0).tan();
        let tan_v = match axis.as_str() {
            "x" => half * h_over_w,
            "y" => half,
            "diagonal" => half * height / width.hypot(height),
            "smaller" if width < height => half * h_over_w,
            "larger" if width > height => half * h_over_w,
            "smaller" | "larger" => half,
            other => {
                return Err(self.error(
                    node,
                    format!("fov_axis '{other}': expected x, y, diagonal, smaller or larger"),
                ))
            }
        };
        let vfov = 2.0 * tan_v.atan().to_degrees();
        let m = self.world_transform(node)?;
        let eye = m.transform_point3(DVec3::ZERO);
        let camera = Camera::new(
            eye,
            eye + m.transform_vector3(DVec3::Z),
            m.transform_vector3(DVec3::Y),
            vfov,
        )
        .map_err(|e| self.error(node, format!("sensor: {e}")))?;
        self.camera = Some(camera);
        Ok(())
    }

    /// The scene: the warnings gathered, the shared clean-up, the lights and camera, and the
    /// twins of two-sided materials.
    fn finish(self) -> Result<Scene> {
        let mut warnings = self.warnings;
        let mut details = self.details;
        if !self.unread.is_empty() {
            let named: Vec<String> = self
                .unread
                .iter()
                .map(|(k, n)| format!("{k} ×{n}"))
                .collect();
            warnings.push(format!(
                "not read (radiosity is diffuse and takes its own settings): {}",
                listed_all("not_read", named, ", ", &mut details)
            ));
        }
        if !self.glass.is_empty() {
            warnings.push(format!(
                "{} glass BSDF(s) taken as clear glass (transmittance 1: the faces let all \
                 light through, straight, and are left out; refraction and the panes' \
                 reflection are not modelled): {}",
                self.glass.len(),
                listed_all("glass_bsdfs", self.glass.clone(), ", ", &mut details)
            ));
        }
        if !self.other.is_empty() {
            warnings.push(format!(
                "{} BSDF(s) that are not diffuse keep only a diffuse colour (the solver is \
                 diffuse): {}",
                self.other.len(),
                listed_all("non_diffuse_bsdfs", self.other.clone(), ", ", &mut details)
            ));
        }
        if !self.textured.is_empty() {
            warnings.push(format!(
                "{} BSDF(s) with a texture use its mean colour everywhere (per-texel variation \
                 is not read): {}",
                self.textured.len(),
                listed_names_all("textured_bsdfs", &self.textured, &mut details)
            ));
        }
        if !self.averaged_spectra.is_empty() {
            warnings.push(format!(
                "spectra given per wavelength are read as grey, their mean value: {}",
                listed_names_all("averaged_spectra", &self.averaged_spectra, &mut details)
            ));
        }
        if !self.clamped.is_empty() {
            warnings.push(format!(
                "reflectance above 1 or below 0 clamped into [0, 1]: {}",
                listed_names_all("clamped_reflectance", &self.clamped, &mut details)
            ));
        }
        let mut scene = finish(
            Some(self.path.to_path_buf()),
            self.positions,
            self.triangles,
            self.materials,
            (Vec::new(), Vec::new()),
            (warnings, details),
            None,
        )?;
        scene.lights = self.lights;
        scene.sun = self.sun;
        scene.sky = self.sky;
        scene.camera = self.camera;
        if !self.two_sided.is_empty() {
            let names: HashSet<String> = self.two_sided.into_iter().collect();
            scene.make_two_sided_where(|_, m| names.contains(&m.name));
        }
        Ok(scene)
    }
}

/// An sRGB colour `#rrggbb` as three values in [0, 1] (still encoded).
fn hex(text: &str) -> Option<Rgb> {
    let digits = text.strip_prefix('#')?;
    if digits.len() != 6 || !digits.is_ascii() {
        return None;
    }
    let channel = |k: usize| u8::from_str_radix(&digits[2 * k..2 * k + 2], 16).ok();
    Some([channel(0)?, channel(1)?, channel(2)?].map(|c| f64::from(c) / 255.0))
}

#[cfg(test)]
mod tests;
