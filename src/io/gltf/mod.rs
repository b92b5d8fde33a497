//! glTF 2.0 in and out (Khronos, *glTF 2.0 Specification*): scenes read with the `gltf`
//! crate into a [`Scene`] ([`load`]), and baked meshes written as binary glTF (`.glb`, §4.4)
//! that engines and Blender read with their colours ([`write_to`]). This module owns both;
//! baking is [`crate::bake`]'s.
//!
//! What is read ([`load`], `.gltf` or `.glb`): the default scene (else the first), every node's
//! mesh with the node's world transform (a transform that mirrors flips the winding back to
//! counter-clockwise fronts), triangle primitives (`mode` 4; other modes are skipped with a
//! warning); per material, ρ = (1 − metallicFactor) · baseColorFactor · the base-colour
//! texture's mean linear colour (glTF's diffuse part; one warning lists metallic materials and
//! one textured ones) and Le = emissiveFactor · `KHR_materials_emissive_strength` · the
//! emissive texture's mean, taken as W·sr⁻¹·m⁻²; `KHR_lights_punctual` point and spot lights
//! (candela ÷ 683 lm/W → W·sr⁻¹, the luminous efficacy Blender's exporter multiplies by) at
//! their nodes, pointing along the node's −Z; a directional light as the sun (lux ÷ 683 →
//! W·m⁻², azimuth and elevation for glTF's +Y up); the first perspective camera. Materials
//! not marked `doubleSided` are one-sided ([`crate::scene::Material::one_sided`]); the others
//! get back sides where the scene sees them ([`crate::scene::orient`]), and are named in a
//! warning. Positions are metres, +Y up.
//!
//! What is refused (an [`Error::Input`] naming the file and the item, never a panic, a hang or
//! a read past an item's data; the checks are the `import` submodule's): an accessor the
//! reader uses (POSITION, indices, the base-colour texture's TEXCOORD_n) of another type than
//! it reads, of count 0, whose elements (count × stride, from its byteOffset) run past its
//! buffer view, or whose sparse indices or values run past theirs or do not increase; a buffer
//! view past its buffer; an index past its primitive's vertices; texture coordinates not one
//! per vertex; nodes that do not form trees; a transform that is not finite; a light whose
//! intensity or colour is negative or not finite, or a spot's cone outside 0 ≤ inner < outer;
//! URIs naming something other than a regular file. A spot or directional light whose node
//! leaves it no direction (a zero scale) is ignored with a warning.
//!
//! What is written (`.glb`):
//! - `POSITION` (float VEC3, with the `min`/`max` the specification requires), in metres as
//!   glTF assumes (the scene's units are written as they are), turned so that the scene's up
//!   axis becomes glTF's +Y: with `--up z`, (x, y, z) ↦ (x, z, −y), which Blender's importer
//!   turns back to its own +Z up;
//! - `COLOR_0` (float VEC3, linear as glTF requires): the baked radiance times the exposure,
//!   clamped to [0, 1]: what the PLY's sRGB bytes show, before the sRGB curve;
//! - `_RADIANCE` (float VEC3, an application-specific attribute, §3.7.2.1): the baked radiance
//!   itself, W·sr⁻¹·m⁻², unclamped;
//! - the triangles (unsigned int indices, counter-clockwise fronts, as glTF's winding);
//! - one material, white and unlit (`KHR_materials_unlit`), so that a viewer shows the baked
//!   colours as they are instead of lighting them again.
//!
//! Faces are one-sided in glTF unless `doubleSided`: the material is single-sided, as the
//! solution is (a two-sided bake writes both sides as faces of their own).

use std::io::{self, Write};
use std::path::Path;

use glam::{DMat4, DVec3};
use serde_json::json;

use crate::bake::BakedMesh;
use crate::color::Rgb;
use crate::scene::{finish, listed_names_all, Camera, Material, Scene, SceneTriangle, Up};
use crate::scene::{PointLight, Spot, Sun};
use crate::{Error, Result};

mod import;

pub use import::MAX_ZERO_FILLED;
use import::{check_accessor, label, Role};

/// Lumens per watt at 555 nm: glTF's photometric light units (candela, lux) to radiometric
/// ones (W·sr⁻¹, W·m⁻²), the factor Blender's glTF exporter uses the other way.
pub const LUMENS_PER_WATT: f64 = 683.0;

/// Loads a glTF 2.0 file (`.gltf` with its buffers and images, or `.glb`) into a [`Scene`];
/// see the module documentation for what is read. Errors name the file.
pub fn load(path: &Path) -> Result<Scene> {
    let input = |message: String| Error::Input {
        path: path.to_path_buf(),
        message,
    };
    let (doc, buffers, images, transforms) = import::import(path)?;
    let scene = doc
        .default_scene()
        .or_else(|| doc.scenes().next())
        .ok_or_else(|| input("the file has no scene".into()))?;
    let mut loader = Loader {
        transforms: &transforms,
        buffers: &buffers,
        images: &images,
        positions: Vec::new(),
        triangles: Vec::new(),
        materials: Vec::new(),
        material_of: vec![None; doc.materials().len()],
        default_material: None,
        warnings: Vec::new(),
        lights: Vec::new(),
        sun: None,
        camera: None,
        skipped_modes: 0,
        metallic: Vec::new(),
        textured: Vec::new(),
        double_sided: Vec::new(),
        textures: Vec::new(),
        uv_maps: Vec::new(),
        texture_of: std::collections::HashMap::new(),
        texture_of_image: std::collections::HashMap::new(),
        zero_filled: 0,
    };
    // Every material of the file, in its order (as an MTL's), used or not.
    for m in doc.materials() {
        loader.material(&m);
    }
    loader
        .walk(scene.nodes(), doc.nodes().len())
        .map_err(input)?;
    let Loader {
        positions,
        triangles,
        materials,
        mut warnings,
        lights,
        sun,
        camera,
        skipped_modes,
        metallic,
        textured,
        double_sided,
        textures,
        uv_maps,
        ..
    } = loader;
    let mut details = Vec::new();
    if skipped_modes > 0 {
        warnings.push(format!(
            "skipped {skipped_modes} primitive(s) that are not triangle lists (points, lines, \
             strips or fans)"
        ));
    }
    if !metallic.is_empty() {
        warnings.push(format!(
            "{} metallic material(s) keep only their diffuse part, ρ = (1 − metallic) × base \
             colour (the solver is diffuse): {}",
            metallic.len(),
            listed_names_all("metallic_materials", &metallic, &mut details)
        ));
    }
    if !textured.is_empty() {
        warnings.push(format!(
            "{} material(s) with a base-colour texture: ρ = base colour × the texture averaged \
             over each patch of the faces with its texture coordinates, × its mean colour \
             elsewhere; the texture's detail finer than a patch is not baked: {}",
            textured.len(),
            listed_names_all("textured_materials", &textured, &mut details)
        ));
    }
    if !double_sided.is_empty() {
        warnings.push(format!(
            "{} material(s) are double-sided in the file: their faces get a back side where \
             the scene sees their back (--orient auto), every face one with --two-sided: {}",
            double_sided.len(),
            listed_names_all("double_sided_materials", &double_sided, &mut details)
        ));
    }
    let mut out = finish(
        Some(path.to_path_buf()),
        positions,
        triangles,
        materials,
        (textures, uv_maps),
        (warnings, details),
        None,
    )?;
    out.lights = lights;
    out.sun = sun;
    out.camera = camera;
    Ok(out)
}

/// The state of a glTF scene walk.
struct Loader<'a> {
    /// Each node's local transform as written, in double precision (where it could be read).
    transforms: &'a [Option<DMat4>],
    buffers: &'a [gltf::buffer::Data],
    images: &'a [gltf::image::Data],
    positions: Vec<DVec3>,
    triangles: Vec<SceneTriangle>,
    materials: Vec<Material>,
    /// Our material index of each glTF material, once used.
    material_of: Vec<Option<u32>>,
    default_material: Option<u32>,
    warnings: Vec<String>,
    lights: Vec<PointLight>,
    sun: Option<Sun>,
    camera: Option<Camera>,
    skipped_modes: usize,
    metallic: Vec<String>,
    textured: Vec<String>,
    double_sided: Vec<String>,
    /// Base-colour textures read per texel (8- and 16-bit images), for ρ across faces.
    textures: Vec<crate::scene::Texture>,
    uv_maps: Vec<crate::scene::UvMap>,
    /// Our material → its texture among `textures` and the texture coordinate set it reads.
    texture_of: std::collections::HashMap<u32, (u32, u32)>,
    /// Each image read as a base-colour texture ([`Loader::base_texture`]).
    texture_of_image: std::collections::HashMap<usize, (Option<u32>, Option<Rgb>)>,
    /// Elements read so far from accessors without a buffer view ([`MAX_ZERO_FILLED`]).
    zero_filled: usize,
}

impl Loader<'_> {
    /// The nodes under `roots` (a scene's), each with its world transform, depth first and
    /// in file order (a node, then its children in turn). glTF's nodes form trees: a node
    /// reached twice (a second parent, a cycle, a root listed twice) is an error, as is a
    /// transform that is not finite. `nodes` is the file's node count.
    fn walk<'n>(
        &mut self,
        roots: impl Iterator<Item = gltf::Node<'n>>,
        nodes: usize,
    ) -> std::result::Result<(), String> {
        let mut seen = vec![false; nodes];
        // A stack, not recursion: a chain of nodes as deep as the file is long must not
        // overflow the thread's stack.
        let mut stack: Vec<(gltf::Node, DMat4)> = roots.map(|n| (n, DMat4::IDENTITY)).collect();
        stack.reverse();
        while let Some((node, parent)) = stack.pop() {
            let name = label("node", node.index(), node.name());
            if std::mem::replace(&mut seen[node.index()], true) {
                return Err(format!(
                    "{name} is reached twice from the scene's nodes: glTF's nodes form trees \
                     (one parent each, no cycles, a scene lists only roots and each once)"
                ));
            }
            // The file's own numbers in double precision; the crate's f32 where they cannot be
            // read so.
            let local = self
                .transforms
                .get(node.index())
                .copied()
                .flatten()
                .unwrap_or_else(|| {
                    DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)))
                });
            let world = parent * local;
            if !world
                .to_cols_array()
                .iter()
                .all(|&x| crate::bake::fits_f32(x))
            {
                return Err(format!(
                    "{name}: its transform (with its parents') is not finite (or past single \
                     precision's range, 3.4e38)"
                ));
            }
            self.node(&node, world, &name)?;
            let first = stack.len();
            stack.extend(node.children().map(|child| (child, world)));
            stack[first..].reverse();
        }
        Ok(())
    }

    /// What `node` (named `name` in messages) holds, under the world transform `world`.
    fn node(
        &mut self,
        node: &gltf::Node,
        world: DMat4,
        name: &str,
    ) -> std::result::Result<(), String> {
        if let Some(mesh) = node.mesh() {
            let mesh_name = label("mesh", mesh.index(), mesh.name());
            for prim in mesh.primitives() {
                let owner = format!("{mesh_name} primitive {}", prim.index());
                self.primitive(&prim, world, &owner, name)?;
            }
        }
        if let Some(light) = node.light() {
            self.light(&light, world, name)?;
        }
        if let (None, Some(camera)) = (self.camera, node.camera()) {
            if let gltf::camera::Projection::Perspective(p) = camera.projection() {
                let eye = world.transform_point3(DVec3::ZERO);
                let forward = world.transform_vector3(-DVec3::Z);
                let up = world.transform_vector3(DVec3::Y);
                let fov = f64::from(p.yfov()).to_degrees();
                self.camera = Camera::new(eye, eye + forward, up, fov).ok();
            }
        }
        Ok(())
    }

    /// One primitive's triangles (`owner` names it, `node` its node), transformed to world
    /// coordinates. The accessors it reads are checked first ([`check_accessor`]), its
    /// indices against its vertex count and its texture coordinates' count against it.
    fn primitive(
        &mut self,
        prim: &gltf::Primitive,
        world: DMat4,
        owner: &str,
        node: &str,
    ) -> std::result::Result<(), String> {
        if prim.mode() != gltf::mesh::Mode::Triangles {
            self.skipped_modes += 1;
            return Ok(());
        }
        // A primitive without positions is not drawn (glTF 2.0 §3.7.2.1).
        let Some(position_accessor) = prim.get(&gltf::Semantic::Positions) else {
            return Ok(());
        };
        check_accessor(
            &position_accessor,
            Role::Positions,
            owner,
            self.buffers,
            &mut self.zero_filled,
        )?;
        let unread = |a: &gltf::Accessor, role: Role| {
            format!(
                "{owner}: {} ({}) cannot be read",
                label("accessor", a.index(), a.name()),
                role.name()
            )
        };
        let reader = prim.reader(|b| self.buffers.get(b.index()).map(|d| &d.0[..]));
        let positions = reader
            .read_positions()
            .ok_or_else(|| unread(&position_accessor, Role::Positions))?;
        let base = self.positions.len() as u32;
        for (k, p) in positions.enumerate() {
            let local = DVec3::from_array(p.map(f64::from));
            let q = world.transform_point3(local);
            if !q.to_array().iter().all(|&x| crate::bake::fits_f32(x)) {
                let a = label(
                    "accessor",
                    position_accessor.index(),
                    position_accessor.name(),
                );
                return Err(if local.is_finite() {
                    format!(
                        "{node}: its transform takes vertex {k} of {owner} ({local}) to a \
                         non-finite position (or one past single precision's range, 3.4e38)"
                    )
                } else {
                    format!("{owner}: {a} (POSITION): element {k} is not finite ({local})")
                });
            }
            self.positions.push(q);
        }
        let count = self.positions.len() as u32 - base;
        let indices: Vec<u32> = match prim.indices() {
            Some(a) => {
                check_accessor(
                    &a,
                    Role::Indices,
                    owner,
                    self.buffers,
                    &mut self.zero_filled,
                )?;
                let indices: Vec<u32> = reader
                    .read_indices()
                    .ok_or_else(|| unread(&a, Role::Indices))?
                    .into_u32()
                    .collect();
                if let Some((k, i)) = indices.iter().enumerate().find(|(_, &i)| i >= count) {
                    return Err(format!(
                        "{owner}: {} (indices): element {k} is {i}, past the {count} vertices \
                         of its POSITION ({})",
                        label("accessor", a.index(), a.name()),
                        label(
                            "accessor",
                            position_accessor.index(),
                            position_accessor.name()
                        )
                    ));
                }
                indices
            }
            None => (0..count).collect(),
        };
        let material = self.material(&prim.material());
        // The base-colour texture's coordinates (glTF's v counts down from the image's top).
        let textured = self.texture_of.get(&material).copied();
        let mut uvs: Vec<glam::DVec2> = Vec::new();
        if let Some((_, set)) = textured {
            if let Some(a) = prim.get(&gltf::Semantic::TexCoords(set)) {
                let role = Role::TexCoords(set);
                check_accessor(&a, role, owner, self.buffers, &mut self.zero_filled)?;
                if a.count() != count as usize {
                    return Err(format!(
                        "{owner}: {} ({}) has {} elements, but its POSITION ({}) has {count}: \
                         a primitive's attributes have one element per vertex",
                        label("accessor", a.index(), a.name()),
                        role.name(),
                        a.count(),
                        label(
                            "accessor",
                            position_accessor.index(),
                            position_accessor.name()
                        )
                    ));
                }
                uvs = reader
                    .read_tex_coords(set)
                    .ok_or_else(|| unread(&a, role))?
                    .into_f32()
                    .map(|[u, v]| glam::DVec2::new(f64::from(u), f64::from(v)))
                    .collect();
            }
        }
        let mirrored = world.determinant() < 0.0;
        for t in indices.chunks_exact(3) {
            let local = if mirrored {
                [t[0], t[2], t[1]]
            } else {
                [t[0], t[1], t[2]]
            };
            let vertices = local.map(|i| base.saturating_add(i));
            let uv = textured
                .zip(
                    local
                        .iter()
                        .map(|&i| uvs.get(i as usize).copied())
                        .collect::<Option<Vec<_>>>(),
                )
                .and_then(|((texture, _), c)| {
                    let corners = vertices.map(|v| self.positions.get(v as usize).copied());
                    let [Some(a), Some(b), Some(d)] = corners else {
                        return None;
                    };
                    crate::scene::UvMap::new(texture, [a, b, d], [c[0], c[1], c[2]])
                })
                .map_or(crate::scene::NO_UV, |m| {
                    self.uv_maps.push(m);
                    (self.uv_maps.len() - 1) as u32
                });
            self.triangles.push(SceneTriangle {
                vertices,
                material,
                uv,
            });
        }
        Ok(())
    }

    /// Our material for a glTF one (made on first use).
    fn material(&mut self, m: &gltf::Material) -> u32 {
        let Some(index) = m.index() else {
            return *self.default_material.get_or_insert_with(|| {
                self.materials.push(Scene::default_material());
                (self.materials.len() - 1) as u32
            });
        };
        if let Some(k) = self.material_of[index] {
            return k;
        }
        let name = m
            .name()
            .map_or_else(|| format!("material_{index}"), str::to_string);
        let pbr = m.pbr_metallic_roughness();
        let base = pbr.base_color_factor();
        let metallic = f64::from(pbr.metallic_factor()).clamp(0.0, 1.0);
        let mut reflectance: Rgb = [0, 1, 2].map(|c| f64::from(base[c]) * (1.0 - metallic));
        let our = self.materials.len() as u32;
        if let Some(info) = pbr.base_color_texture() {
            let image = info.texture().source().index();
            // 8- and 16-bit images vary ρ across faces; float ones give their mean only.
            let (texture, mean) = self.base_texture(image);
            if let Some(k) = texture {
                self.texture_of.insert(our, (k, info.tex_coord()));
            }
            if let Some(mean) = mean {
                reflectance = [0, 1, 2].map(|c| reflectance[c] * mean[c]);
                self.textured.push(name.clone());
            }
        }
        if metallic > 0.0 {
            self.metallic.push(name.clone());
        }
        if m.double_sided() {
            self.double_sided.push(name.clone());
        }
        let strength = f64::from(m.emissive_strength().unwrap_or(1.0));
        let mut emission: Rgb = m.emissive_factor().map(|e| f64::from(e) * strength);
        if let Some(mean) = m
            .emissive_texture()
            .and_then(|t| self.texture_mean(t.texture().source().index()))
        {
            emission = [0, 1, 2].map(|c| emission[c] * mean[c]);
        }
        // What passes: the uncovered share 1 − α of a blended material, and the share τ of
        // the rest that KHR_materials_transmission transmits (its tint and texture not read).
        let alpha = match m.alpha_mode() {
            gltf::material::AlphaMode::Blend => f64::from(base[3]).clamp(0.0, 1.0),
            _ => 1.0,
        };
        let tau = m
            .transmission()
            .map_or(0.0, |t| f64::from(t.transmission_factor()).clamp(0.0, 1.0));
        self.materials.push(
            Material::opaque(
                name,
                reflectance.map(|r| r.clamp(0.0, 1.0)),
                emission.map(|e| if e.is_finite() { e.max(0.0) } else { 0.0 }),
            )
            .with_transmittance((1.0 - alpha) + alpha * tau)
            .with_one_sided(!m.double_sided()),
        );
        let k = (self.materials.len() - 1) as u32;
        self.material_of[index] = Some(k);
        k
    }

    /// Image `i` as a base-colour texture, read once for every material that uses it: its
    /// index among `textures` when it is an sRGB-encoded 8- or 16-bit image
    /// ([`crate::io::linear_texture`]; `None` for float images, whose colour is only averaged),
    /// and its mean linear colour (`None` without pixels).
    fn base_texture(&mut self, i: usize) -> (Option<u32>, Option<Rgb>) {
        if let Some(&read) = self.texture_of_image.get(&i) {
            return read;
        }
        let read = match self.decoded(i) {
            Ok(image) => match crate::io::linear_texture(image, format!("image {i}")) {
                Some(t) => {
                    let mean = t.mean;
                    self.textures.push(t);
                    (Some((self.textures.len() - 1) as u32), Some(mean))
                }
                None => (None, None),
            },
            Err(mean) => (None, mean),
        };
        self.texture_of_image.insert(i, read);
        read
    }

    /// The mean linear colour of image `i`: sRGB-encoded 8- or 16-bit images through
    /// [`crate::io::texture_mean`], float ones (linear) by their plain mean; `None` without
    /// pixels.
    fn texture_mean(&self, i: usize) -> Option<Rgb> {
        match self.decoded(i) {
            Ok(image) => crate::io::texture_mean(image),
            Err(mean) => mean,
        }
    }

    /// Image `i` as an `image` crate image, or for float images (linear already) their plain
    /// mean colour instead (`Err`; `Err(None)` without pixels).
    fn decoded(&self, i: usize) -> std::result::Result<image::DynamicImage, Option<Rgb>> {
        use gltf::image::Format as F;
        use image::{DynamicImage as D, ImageBuffer};
        let data = self.images.get(i).ok_or(None)?;
        let (w, h, p) = (data.width, data.height, data.pixels.clone());
        // 16-bit samples come as little-endian byte pairs.
        let wide = || -> Vec<u16> {
            data.pixels
                .chunks_exact(2)
                .map(|b| u16::from_le_bytes([b[0], b[1]]))
                .collect()
        };
        let image = match data.format {
            F::R8 => D::ImageLuma8(ImageBuffer::from_raw(w, h, p).ok_or(None)?),
            F::R8G8 => D::ImageLumaA8(ImageBuffer::from_raw(w, h, p).ok_or(None)?),
            F::R8G8B8 => D::ImageRgb8(ImageBuffer::from_raw(w, h, p).ok_or(None)?),
            F::R8G8B8A8 => D::ImageRgba8(ImageBuffer::from_raw(w, h, p).ok_or(None)?),
            F::R16 => D::ImageLuma16(ImageBuffer::from_raw(w, h, wide()).ok_or(None)?),
            F::R16G16 => D::ImageLumaA16(ImageBuffer::from_raw(w, h, wide()).ok_or(None)?),
            F::R16G16B16 => D::ImageRgb16(ImageBuffer::from_raw(w, h, wide()).ok_or(None)?),
            F::R16G16B16A16 => D::ImageRgba16(ImageBuffer::from_raw(w, h, wide()).ok_or(None)?),
            // Float samples are linear already: their plain mean.
            F::R32G32B32FLOAT | F::R32G32B32A32FLOAT => {
                let channels = if data.format == F::R32G32B32FLOAT {
                    3
                } else {
                    4
                };
                let floats: Vec<f32> = data
                    .pixels
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .collect();
                let n = floats.len() / channels;
                if n == 0 {
                    return Err(None);
                }
                let mut sum = [0.0f64; 3];
                for px in floats.chunks_exact(channels) {
                    for (s, &c) in sum.iter_mut().zip(px) {
                        *s += f64::from(c);
                    }
                }
                return Err(Some(sum.map(|s| (s / n as f64).max(0.0))));
            }
        };
        Ok(image)
    }

    /// A `KHR_lights_punctual` light at the node `node` names, with world transform `world`.
    /// An intensity or colour that is negative or not finite, or a spot's cone outside
    /// 0 ≤ inner < outer, is an error naming the light and its node; a spot or directional
    /// light whose node's transform leaves it no direction (a zero scale) is ignored with a
    /// warning, as a directional light from below the horizon is.
    fn light(
        &mut self,
        light: &gltf::khr_lights_punctual::Light,
        world: DMat4,
        node: &str,
    ) -> std::result::Result<(), String> {
        use gltf::khr_lights_punctual::Kind;
        let name = label("KHR_lights_punctual light", light.index(), light.name());
        let colour = light.color().map(f64::from);
        let intensity = f64::from(light.intensity());
        let in_range = |x: &f64| x.is_finite() && *x >= 0.0;
        if !(in_range(&intensity) && colour.iter().all(in_range)) {
            return Err(format!(
                "{name} at {node}: its intensity {intensity} and colour {colour:?} must be finite \
                 and ≥ 0"
            ));
        }
        let value = intensity / LUMENS_PER_WATT;
        let rgb: Rgb = colour.map(|c| c * value);
        let position = world.transform_point3(DVec3::ZERO);
        let axis = world.transform_vector3(-DVec3::Z).normalize_or_zero();
        let ignored = |kind: &str, why: &str| {
            format!(
                "{kind} light '{}' ignored: {why}",
                light.name().unwrap_or("unnamed")
            )
        };
        let no_direction = "its node's transform leaves it no direction (a zero scale)";
        let point = match light.kind() {
            Kind::Point => PointLight {
                position,
                intensity: rgb,
                spot: None,
            },
            Kind::Spot { .. } if axis == DVec3::ZERO => {
                self.warnings.push(ignored("spot", no_direction));
                return Ok(());
            }
            Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => PointLight {
                position,
                intensity: rgb,
                spot: Some(Spot {
                    direction: axis,
                    inner_degrees: f64::from(inner_cone_angle).to_degrees(),
                    outer_degrees: f64::from(outer_cone_angle).to_degrees().min(90.0),
                }),
            },
            Kind::Directional => {
                // The sun: toward it is −axis; azimuth from north (+Z) toward east (−X) for
                // glTF's +Y up ([`crate::scene::Sun`]).
                let to = -axis;
                let elevation = to.y.clamp(-1.0, 1.0).asin().to_degrees();
                let (north, east) = (Up::Y.forward(), Up::Y.forward().cross(Up::Y.axis()));
                let azimuth = to.dot(east).atan2(to.dot(north)).to_degrees();
                if axis == DVec3::ZERO || elevation <= 0.0 || self.sun.is_some() {
                    let why = if axis == DVec3::ZERO {
                        no_direction
                    } else if elevation <= 0.0 {
                        "it shines from below the horizon"
                    } else {
                        "the scene already has a sun"
                    };
                    self.warnings.push(ignored("directional", why));
                    return Ok(());
                }
                self.sun = Some(Sun {
                    azimuth_degrees: azimuth,
                    elevation_degrees: elevation,
                    irradiance: rgb,
                });
                return Ok(());
            }
        };
        point
            .check()
            .map_err(|problem| format!("{name} at {node}: the light {problem}"))?;
        self.lights.push(point);
        Ok(())
    }
}

/// `GLB` magic, version 2, and the chunk types (little-endian ASCII "JSON" and "BIN\0").
const MAGIC: u32 = 0x4654_6C67;
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// glTF's component types and buffer-view targets.
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// A position of the scene (up axis `up`) in glTF's frame (+Y up, right-handed), in double
/// precision.
pub fn to_gltf_f64(p: [f64; 3], up: Up) -> [f64; 3] {
    let [x, y, z] = p;
    match up {
        Up::Y => [x, y, z],
        // +Z up → +Y up: a rotation of −90° about +X.
        Up::Z => [x, z, -y],
        // +X up → +Y up: a rotation of +90° about +Z.
        Up::X => [-y, x, z],
    }
}

/// A position of the scene (up axis `up`) in glTF's frame, as its `f32` accessor stores it.
pub fn to_gltf(p: [f64; 3], up: Up) -> [f32; 3] {
    to_gltf_f64(p, up).map(|c| c as f32)
}

/// Writes `mesh` as GLB to `w` (colours at `exposure`; positions turned so that `up` is +Y).
/// glTF stores positions in single precision; where that would round them
/// ([`crate::io::needs_double`]: a mesh in map coordinates), they are stored about the centre
/// of their bounds and the node that holds them is translated there (a translation is a JSON
/// number, read in double precision), as the specification advises for large offsets.
pub fn write_to<W: Write>(w: &mut W, mesh: &BakedMesh, exposure: f64, up: Up) -> io::Result<()> {
    let n = mesh.positions.len();
    let mut bin: Vec<u8> = Vec::with_capacity(n * 36 + mesh.faces.len() * 12);
    let offset = if crate::io::needs_double(&mesh.positions) {
        let (lo, hi) = crate::geometry::bounds(
            mesh.positions
                .iter()
                .map(|&p| glam::DVec3::from(to_gltf_f64(p, up))),
        );
        ((lo + hi) / 2.0).to_array()
    } else {
        [0.0; 3]
    };
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in &mesh.positions {
        let g = to_gltf_f64(*p, up);
        let q: [f32; 3] = std::array::from_fn(|c| (g[c] - offset[c]) as f32);
        for c in 0..3 {
            lo[c] = lo[c].min(q[c]);
            hi[c] = hi[c].max(q[c]);
            bin.extend_from_slice(&q[c].to_le_bytes());
        }
    }
    let colours_at = bin.len();
    for l in &mesh.vertex_radiance {
        for c in l {
            let v = (c * exposure).clamp(0.0, 1.0) as f32;
            bin.extend_from_slice(&v.to_le_bytes());
        }
    }
    let radiance_at = bin.len();
    for l in &mesh.vertex_radiance {
        for c in l {
            bin.extend_from_slice(&(*c as f32).to_le_bytes());
        }
    }
    let indices_at = bin.len();
    for f in &mesh.faces {
        for i in f {
            bin.extend_from_slice(&i.to_le_bytes());
        }
    }
    let total = bin.len();
    let view = |offset: usize, length: usize, target: u32| json!({"buffer": 0, "byteOffset": offset, "byteLength": length, "target": target});
    let vec3 = |view: usize| json!({"bufferView": view, "componentType": FLOAT, "count": n, "type": "VEC3"});
    let mut position = vec3(0);
    position["min"] = json!(lo);
    position["max"] = json!(hi);
    let mut node = json!({"mesh": 0, "name": "baked"});
    if offset != [0.0; 3] {
        node["translation"] = json!(offset);
    }
    let document = json!({
        "asset": {
            "version": "2.0",
            "generator": concat!("radiosity ", env!("CARGO_PKG_VERSION")),
        },
        "extensionsUsed": ["KHR_materials_unlit"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [node],
        "meshes": [{
            "name": "baked",
            "primitives": [{
                "attributes": {"POSITION": 0, "COLOR_0": 1, "_RADIANCE": 2},
                "indices": 3,
                "material": 0,
                "mode": 4,
            }],
        }],
        "materials": [{
            "name": "baked vertex colours",
            "pbrMetallicRoughness": {
                "baseColorFactor": [1.0, 1.0, 1.0, 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 1.0,
            },
            "extensions": {"KHR_materials_unlit": {}},
        }],
        "buffers": [{"byteLength": total}],
        "bufferViews": [
            view(0, colours_at, ARRAY_BUFFER),
            view(colours_at, radiance_at - colours_at, ARRAY_BUFFER),
            view(radiance_at, indices_at - radiance_at, ARRAY_BUFFER),
            view(indices_at, total - indices_at, ELEMENT_ARRAY_BUFFER),
        ],
        "accessors": [
            position,
            vec3(1),
            vec3(2),
            {"bufferView": 3, "componentType": UNSIGNED_INT, "count": mesh.faces.len() * 3, "type": "SCALAR"},
        ],
    });
    w.write_all(&glb(&document, bin)?)
}

/// The GLB container (§4.4) of a glTF document and its binary buffer: the 12-byte header,
/// then the JSON chunk padded with spaces and the BIN chunk padded with zeros to 4 bytes.
fn glb(document: &serde_json::Value, mut bin: Vec<u8>) -> io::Result<Vec<u8>> {
    let mut text = serde_json::to_vec(document).map_err(io::Error::other)?;
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let length = 12 + 8 + text.len() + 8 + bin.len();
    let length = u32::try_from(length)
        .map_err(|_| io::Error::other(format!("glTF: {length} bytes is more than GLB's 4 GiB")))?;
    let mut out = Vec::with_capacity(length as usize);
    for word in [MAGIC, 2, length, text.len() as u32, CHUNK_JSON] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&text);
    for word in [bin.len() as u32, CHUNK_BIN] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&bin);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A quad of two triangles with known radiance.
    fn quad() -> BakedMesh {
        BakedMesh {
            positions: vec![[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 2.]],
            vertex_radiance: vec![[0.1, 0.2, 0.3], [1.0, 2.0, 0.0], [0.5; 3], [0.0; 3]],
            faces: vec![[0, 1, 2], [0, 2, 3]],
            face_radiance: vec![[0.4; 3], [0.2; 3]],
            camera: None,
            sky: None,
        }
    }

    #[test]
    fn the_glb_reads_back_with_the_gltf_crate() {
        // An independent reader (the `gltf` crate's validating importer): positions turned to
        // +Y up, COLOR_0 the clamped exposed radiance, _RADIANCE the radiance, the indices.
        let mesh = quad();
        let mut bytes = Vec::new();
        write_to(&mut bytes, &mesh, 2.0, Up::Z).unwrap();
        assert!(bytes.len().is_multiple_of(4));
        let (doc, buffers, _) = gltf::import_slice(&bytes).unwrap();
        let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
        let reader = prim.reader(|b| Some(&buffers[b.index()]));
        let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
        assert_eq!(positions[3], [0.0, 2.0, -1.0], "(x, y, z) -> (x, z, -y)");
        let colours: Vec<[f32; 3]> = reader.read_colors(0).unwrap().into_rgb_f32().collect();
        assert_eq!(colours[0], [0.2, 0.4, 0.6]);
        assert_eq!(colours[1], [1.0, 1.0, 0.0], "clamped");
        let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
        assert_eq!(indices, [0, 1, 2, 0, 2, 3]);
        let radiance = prim
            .attributes()
            .find(|(s, _)| s.to_string() == "_RADIANCE");
        let accessor = radiance.expect("_RADIANCE is written").1;
        assert_eq!(
            (accessor.count(), accessor.dimensions()),
            (4, gltf::accessor::Dimensions::Vec3)
        );
        let view = accessor.view().unwrap();
        let data = &buffers[0][view.offset()..view.offset() + view.length()];
        let second: Vec<f32> = data[12..24]
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        assert_eq!(second, [1.0, 2.0, 0.0], "unclamped radiance");
        let material = prim.material();
        assert!(material.unlit());
    }

    #[test]
    fn a_mesh_in_map_coordinates_keeps_its_positions_through_a_glb() {
        // The quad 5.6e6 units out: written about its centre under a translated node (glTF's
        // accessors are f32, which would round it in steps of 0.5), and read back (the
        // node's translation as written, in double precision; the `gltf` crate's own is
        // f32) to within f32's rounding of the quad's own size.
        let dir = crate::test_support::TestDir::new("gltf-far");
        let path = dir.path().join("far.glb");
        let mut mesh = quad();
        let offset = [5.0e5 + 0.123, 17.25, -5.6e6 - 0.456];
        for p in &mut mesh.positions {
            *p = std::array::from_fn(|c| p[c] + offset[c]);
        }
        crate::io::write(&path, &mesh, crate::io::Format::Glb { up: Up::Y }, 1.0).unwrap();
        let scene = load(&path).unwrap();
        assert_eq!(scene.positions.len(), mesh.positions.len());
        for p in &mesh.positions {
            let nearest = (scene.positions.iter())
                .map(|q| (*q - DVec3::from(*p)).length())
                .fold(f64::INFINITY, f64::min);
            assert!(nearest <= 1e-6, "{p:?}: {nearest}");
        }
    }

    /// A GLB with a floor (two triangles, material "clay": base colour (0.8, 0.6, 0.4),
    /// metallic 0.25) under a node translated by (0, 0, −3) and mirrored in x (the winding
    /// must be turned back), a lamp triangle (emissive (1, 0.5, 0.25) × strength 4), a point
    /// light of 683 cd at (0, 2, 0), a spot and a directional light, and a camera.
    fn scene_glb() -> Vec<u8> {
        scene_glb_with(json!([
            {"name": "clay", "pbrMetallicRoughness":
                {"baseColorFactor": [0.8, 0.6, 0.4, 1.0], "metallicFactor": 0.25}},
            {"name": "lamp", "emissiveFactor": [1.0, 0.5, 0.25],
             "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}},
             "pbrMetallicRoughness": {"metallicFactor": 0.0}},
        ]))
    }

    /// [`scene_glb`] with its two materials (floor, lamp) replaced by `materials`.
    fn scene_glb_with(materials: serde_json::Value) -> Vec<u8> {
        let floor: [[f32; 3]; 4] = [[-1., 0., -1.], [1., 0., -1.], [1., 0., 1.], [-1., 0., 1.]];
        let lamp: [[f32; 3]; 3] = [[-0.2, 1., -0.2], [-0.2, 1., 0.2], [0.2, 1., 0.2]];
        let mut bin = Vec::new();
        for p in floor.iter().chain(&lamp) {
            for c in p {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
        // Counter-clockwise seen from +Y: (0, 3, 2), (0, 2, 1) face up.
        for i in [0u32, 3, 2, 0, 2, 1, 0, 1, 2] {
            bin.extend_from_slice(&i.to_le_bytes());
        }
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let doc = json!({
            "asset": {"version": "2.0"},
            "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
            "extensions": {"KHR_lights_punctual": {"lights": [
                {"type": "point", "intensity": 683.0, "color": [1.0, 0.5, 0.25]},
                {"type": "spot", "intensity": 1366.0,
                 "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}},
                {"type": "directional", "intensity": 68300.0},
            ]}},
            "scene": 0,
            "scenes": [{"nodes": [0, 1, 2, 3, 4, 5]}],
            "nodes": [
                {"mesh": 0, "translation": [0.0, 0.0, -3.0], "scale": [-1.0, 1.0, 1.0]},
                {"mesh": 1},
                {"translation": [0.0, 2.0, 0.0],
                 "extensions": {"KHR_lights_punctual": {"light": 0}}},
                // Rotated −90° about X: its −Z axis points down (−Y).
                {"translation": [1.0, 3.0, 0.0], "rotation": [-h, 0.0, 0.0, h],
                 "extensions": {"KHR_lights_punctual": {"light": 1}}},
                {"rotation": [-0.38268343, 0.0, 0.0, 0.92387953],
                 "extensions": {"KHR_lights_punctual": {"light": 2}}},
                {"camera": 0, "translation": [0.0, 1.0, 5.0]},
            ],
            "cameras": [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1}}],
            "meshes": [
                {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]},
                {"primitives": [{"attributes": {"POSITION": 2}, "indices": 3, "material": 1}]},
            ],
            "materials": materials,
            "buffers": [{"byteLength": bin.len()}],
            "bufferViews": [
                {"buffer": 0, "byteOffset": 0, "byteLength": 48},
                {"buffer": 0, "byteOffset": 84, "byteLength": 24},
                {"buffer": 0, "byteOffset": 48, "byteLength": 36},
                {"buffer": 0, "byteOffset": 108, "byteLength": 12},
            ],
            "accessors": [
                {"bufferView": 0, "componentType": FLOAT, "count": 4, "type": "VEC3",
                 "min": [-1.0, 0.0, -1.0], "max": [1.0, 0.0, 1.0]},
                {"bufferView": 1, "componentType": UNSIGNED_INT, "count": 6, "type": "SCALAR"},
                {"bufferView": 2, "componentType": FLOAT, "count": 3, "type": "VEC3",
                 "min": [-0.2, 1.0, -0.2], "max": [0.2, 1.0, 0.2]},
                {"bufferView": 3, "componentType": UNSIGNED_INT, "count": 3, "type": "SCALAR"},
            ],
        });
        glb(&doc, bin).unwrap()
    }

    #[test]
    fn blended_and_transmissive_materials_let_their_share_through() {
        // Alpha blending passes 1 − α; KHR_materials_transmission passes τ of the rest:
        // t = (1 − 0.3) + 0.3 × 0.5 = 0.85. Opaque and masked materials stay opaque; a
        // fully transmissive one (τ = 1) is left out with its faces.
        let load = |floor: serde_json::Value| {
            let dir = crate::test_support::TestDir::new("gltf-glass");
            let path = dir.path().join("scene.glb");
            let lamp = json!({"name": "lamp", "emissiveFactor": [1.0, 1.0, 1.0]});
            std::fs::write(&path, scene_glb_with(json!([floor, lamp]))).unwrap();
            Scene::load(&path).unwrap()
        };
        let s = load(json!({"name": "glass", "alphaMode": "BLEND",
            "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.2, 0.2, 0.3], "metallicFactor": 0.0},
            "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.5}}}));
        assert!(
            (s.materials[0].transmittance - 0.85).abs() < 1e-6,
            "{:?}",
            s.materials[0]
        );
        assert!(
            (s.materials[0].reflectance[0] - 0.2).abs() < 1e-6,
            "ρ stays the material's"
        );
        assert_eq!(s.materials[1].transmittance, 0.0);
        let s = load(json!({"name": "cutout", "alphaMode": "MASK",
            "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 0.3], "metallicFactor": 0.0}}));
        assert_eq!(s.materials[0].transmittance, 0.0);
        let s = load(
            json!({"name": "clear", "pbrMetallicRoughness": {"metallicFactor": 0.0},
            "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}}}),
        );
        assert_eq!(s.triangles.len(), 1, "the clear floor is left out");
        assert!(s
            .warnings
            .iter()
            .any(|w| w.contains("left out") && w.contains("clear")));
    }

    #[test]
    fn a_gltf_scene_loads_with_its_transforms_materials_lights_and_camera() {
        let dir = crate::test_support::TestDir::new("gltf-in");
        let path = dir.path().join("scene.glb");
        std::fs::write(&path, scene_glb()).unwrap();
        let s = Scene::load(&path).unwrap();
        assert_eq!(s.triangles.len(), 3);
        // The floor: translated to z = −3 ± 1, mirrored, and still facing up (+Y).
        let floor: Vec<&SceneTriangle> = s.triangles.iter().filter(|t| t.material == 0).collect();
        assert_eq!(floor.len(), 2);
        for t in floor {
            let [a, b, c] = t.vertices.map(|v| s.positions[v as usize]);
            assert!((b - a)
                .cross(c - a)
                .normalize()
                .abs_diff_eq(DVec3::Y, 1e-12));
            assert!([a, b, c].iter().all(|p| (p.z + 3.0).abs() <= 1.0 + 1e-6));
        }
        let clay = &s.materials[0];
        assert_eq!(clay.name, "clay");
        // ρ = (1 − 0.25) × base colour.
        for (r, b) in clay.reflectance.iter().zip([0.8, 0.6, 0.4]) {
            assert!((r - 0.75 * b).abs() < 1e-6, "{:?}", clay.reflectance);
        }
        let lamp = &s.materials[1];
        for (e, f) in lamp.emission.iter().zip([4.0, 2.0, 1.0]) {
            assert!((e - f).abs() < 1e-6, "{:?}", lamp.emission);
        }
        // 683 cd = 1 W/sr, times the colour; the spot points down with its angles.
        assert_eq!(s.lights.len(), 2);
        let point = &s.lights[0];
        assert!(point.position.abs_diff_eq(DVec3::new(0.0, 2.0, 0.0), 1e-6));
        assert!((point.intensity[1] - 0.5).abs() < 1e-9 && point.spot.is_none());
        let spot = s.lights[1].spot.unwrap();
        assert!(
            spot.direction.abs_diff_eq(-DVec3::Y, 1e-6),
            "{}",
            spot.direction
        );
        assert!((spot.inner_degrees - 0.2f64.to_degrees()).abs() < 1e-4);
        assert!((s.lights[1].intensity[0] - 2.0).abs() < 1e-9);
        // The directional light, its node turned −45° about X, shines down at 45°: the sun
        // at elevation 45°, 68300 lux = 100 W/m².
        let sun = s.sun.unwrap();
        assert!((sun.elevation_degrees - 45.0).abs() < 1e-4, "{sun:?}");
        assert!((sun.irradiance[2] - 100.0).abs() < 1e-6);
        let camera = s.camera.unwrap();
        assert!(camera.eye.abs_diff_eq(DVec3::new(0.0, 1.0, 5.0), 1e-6));
        assert!((camera.vfov_degrees - 0.7f64.to_degrees()).abs() < 1e-4);
        assert!(s
            .warnings
            .iter()
            .any(|w| w.contains("metallic") && w.contains("'clay'")));
    }

    /// A GLB of one triangle, (0,0,0), (1,0,0), (0,0,−1), whose material `name` has base
    /// colour 0.5 and the base-colour texture `img` (a PNG inside the file), with `texcoords`
    /// as its TEXCOORD_0 if given. Returns the loaded scene.
    fn textured_triangle(
        name: &str,
        img: &image::RgbImage,
        texcoords: Option<[[f32; 2]; 3]>,
    ) -> Scene {
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        let mut bin = Vec::new();
        for p in [[0f32, 0., 0.], [1., 0., 0.], [0., 0., -1.]] {
            for c in p {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
        let mut attributes = json!({"POSITION": 0});
        let mut views = vec![json!({"buffer": 0, "byteOffset": 0, "byteLength": 36})];
        let mut accessors = vec![json!({"bufferView": 0, "componentType": FLOAT, "count": 3,
            "type": "VEC3", "min": [0.0, 0.0, -1.0], "max": [1.0, 0.0, 0.0]})];
        if let Some(t) = texcoords {
            for c in t.iter().flatten() {
                bin.extend_from_slice(&c.to_le_bytes());
            }
            attributes["TEXCOORD_0"] = json!(1);
            views.push(json!({"buffer": 0, "byteOffset": 36, "byteLength": 24}));
            accessors.push(json!({"bufferView": 1, "componentType": FLOAT, "count": 3,
                "type": "VEC2"}));
        }
        let png_at = bin.len();
        bin.extend_from_slice(&png);
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        views.push(json!({"buffer": 0, "byteOffset": png_at, "byteLength": png.len()}));
        let doc = json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": attributes, "material": 0}]}],
            "materials": [{"name": name, "pbrMetallicRoughness": {
                "baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0,
                "baseColorTexture": {"index": 0}}}],
            "textures": [{"source": 0}],
            "images": [{"bufferView": views.len() - 1, "mimeType": "image/png"}],
            "buffers": [{"byteLength": bin.len()}],
            "bufferViews": views,
            "accessors": accessors,
        });
        let dir = crate::test_support::TestDir::new("gltf-texture");
        let path = dir.path().join(format!("{name}.glb"));
        std::fs::write(&path, glb(&doc, bin).unwrap()).unwrap();
        Scene::load(&path).unwrap()
    }

    #[test]
    fn texture_coordinates_vary_rho_per_patch() {
        // A 16 × 16 PNG, its left half red and its right half green, on a triangle whose
        // TEXCOORD_0 lie in the red half: every patch of it is red, ρ = base colour 0.5 ×
        // the colour under it (1, 0, 0), while the material lists 0.5 × the mean (0.5, 0.5, 0).
        let img = image::RgbImage::from_fn(16, 16, |x, _| {
            image::Rgb(if x < 8 { [255, 0, 0] } else { [0, 255, 0] })
        });
        let s = textured_triangle("halves", &img, Some([[0.1, 0.2], [0.4, 0.2], [0.1, 0.8]]));
        let m = s.materials[0].reflectance;
        assert!(
            (m[0] - 0.25).abs() < 1e-6 && (m[1] - 0.25).abs() < 1e-6,
            "{m:?}"
        );
        let p = crate::mesh::subdivide(&s, 0.2, 0.0).unwrap();
        assert!(p.len() > 10);
        for rho in &p.reflectance {
            assert!((rho[0] - 0.5).abs() < 1e-3 && rho[1] < 1e-3, "{rho:?}");
        }
    }

    #[test]
    fn a_base_colour_texture_gives_its_mean_linear_colour() {
        // A 2 × 1 PNG inside the GLB (sRGB 188 and 0 in red, 255 in green and blue) under a
        // base colour of 0.5: ρ = 0.5 × (0.502886 / 2, 1, 1), and a warning lists it.
        let mut img = image::RgbImage::new(2, 1);
        img.put_pixel(0, 0, image::Rgb([188, 255, 255]));
        img.put_pixel(1, 0, image::Rgb([0, 255, 255]));
        let s = textured_triangle("brick", &img, None);
        let rho = s.materials[0].reflectance;
        let want = [0.5 * 0.502_886 / 2.0, 0.5, 0.5];
        for (r, w) in rho.iter().zip(want) {
            assert!((r - w).abs() < 1e-5, "{rho:?}");
        }
        assert!(s
            .warnings
            .iter()
            .any(|w| w.contains("texture") && w.contains("'brick'")));
        // Without texture coordinates ρ is the material's on every patch.
        assert!(s.triangles.iter().all(|t| t.uv == crate::scene::NO_UV));
    }

    #[test]
    fn a_broken_gltf_is_an_error_naming_the_file() {
        let dir = crate::test_support::TestDir::new("gltf-bad");
        let path = dir.path().join("broken.glb");
        std::fs::write(&path, b"glTF not really").unwrap();
        let e = Scene::load(&path).unwrap_err().to_string();
        assert!(e.contains("broken.glb") && e.contains("glTF"), "{e}");
    }

    #[test]
    fn every_up_axis_becomes_plus_y() {
        assert_eq!(to_gltf([1.0, 2.0, 3.0], Up::Y), [1.0, 2.0, 3.0]);
        assert_eq!(to_gltf([0.0, 0.0, 1.0], Up::Z), [0.0, 1.0, 0.0]);
        assert_eq!(to_gltf([1.0, 0.0, 0.0], Up::X), [0.0, 1.0, 0.0]);
        // Rotations keep handedness: a right-handed triple stays right-handed.
        let (x, y, z) = (
            to_gltf([1.0, 0.0, 0.0], Up::Z),
            to_gltf([0.0, 1.0, 0.0], Up::Z),
            to_gltf([0.0, 0.0, 1.0], Up::Z),
        );
        let v = |a: [f32; 3]| glam::Vec3::from_array(a);
        assert_eq!(v(x).cross(v(y)), v(z));
        let (x, y, z) = (
            to_gltf([1.0, 0.0, 0.0], Up::X),
            to_gltf([0.0, 1.0, 0.0], Up::X),
            to_gltf([0.0, 0.0, 1.0], Up::X),
        );
        assert_eq!(v(x).cross(v(y)), v(z));
    }
}
