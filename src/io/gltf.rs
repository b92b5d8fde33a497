//! glTF 2.0 binary (`.glb`) out: the baked mesh as one triangle primitive that engines and
//! Blender read with its colours (Khronos, *glTF 2.0 Specification*, §3.7.2 "Meshes", §4.4
//! "GLB File Format"). This module owns writing the file; baking is [`crate::bake`]'s.
//!
//! What is written:
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

use serde_json::json;

use crate::bake::BakedMesh;
use crate::scene::Up;

/// `GLB` magic, version 2, and the chunk types (little-endian ASCII "JSON" and "BIN\0").
const MAGIC: u32 = 0x4654_6C67;
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// glTF's component types and buffer-view targets.
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// A position of the scene (up axis `up`) in glTF's frame (+Y up, right-handed).
pub fn to_gltf(p: [f64; 3], up: Up) -> [f32; 3] {
    let [x, y, z] = p;
    let q = match up {
        Up::Y => [x, y, z],
        // +Z up → +Y up: a rotation of −90° about +X.
        Up::Z => [x, z, -y],
        // +X up → +Y up: a rotation of +90° about +Z.
        Up::X => [-y, x, z],
    };
    q.map(|c| c as f32)
}

/// Writes `mesh` as GLB to `w` (colours at `exposure`; positions turned so that `up` is +Y).
pub fn write_to<W: Write>(w: &mut W, mesh: &BakedMesh, exposure: f64, up: Up) -> io::Result<()> {
    let n = mesh.positions.len();
    let mut bin: Vec<u8> = Vec::with_capacity(n * 36 + mesh.faces.len() * 12);
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in &mesh.positions {
        let q = to_gltf(*p, up);
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
    let document = json!({
        "asset": {
            "version": "2.0",
            "generator": concat!("radiosity ", env!("CARGO_PKG_VERSION")),
        },
        "extensionsUsed": ["KHR_materials_unlit"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "baked"}],
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
    let mut text = serde_json::to_vec(&document).map_err(io::Error::other)?;
    // Chunks are 4-byte aligned: JSON padded with spaces, BIN with zeros.
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
    w.write_all(&out)
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
