//! The guarded import of a glTF file: what the `gltf` crate (1.4) leaves unchecked is checked
//! here before the crate reads it, so that a broken or hostile file is an [`Error`] naming the
//! file and the item (buffer, buffer view, accessor, image, camera, node) instead of a panic, a
//! hang, or triangles made of whatever bytes follow an accessor's data. This module owns those
//! checks; what the scene walk makes of the data is [`super::load`]'s.
//!
//! Before the crate's importer runs ([`import`]):
//! - a GLB's length field lies between its 12-byte header and the file's size (the crate
//!   subtracts the header from it unchecked), and only that many bytes are read, as
//!   `gltf::import` does;
//! - every primitive attribute names an accessor the file has (the crate's validator indexes
//!   the POSITION accessor unchecked); an image has a `uri`, or a `bufferView` with its
//!   `mimeType`; a camera has the projection its `type` names;
//! - a buffer's or an image's `uri` that names a file (not a `data:` URI) names a regular file
//!   (`/dev/zero` or a FIFO would never end), and its `%XX` escapes decode to UTF-8;
//! - every buffer view lies within its buffer's `byteLength`.
//!
//! Per accessor the reader uses ([`check_accessor`]): a count of at least 1; the type and
//! component type the reader reads for its role; a `byteStride` at least the element's size;
//! `byteOffset + stride × (count − 1) + element size` within its buffer view; for a sparse
//! accessor, its indices and values within their views and the indices strictly increasing
//! and below the count; the accessors without a buffer view (zeros but their sparse values:
//! data the file does not hold, which a few bytes of JSON could make billions of) at most
//! [`MAX_ZERO_FILLED`] elements in all, each use counted.

use std::path::{Path, PathBuf};

use glam::{DMat4, DQuat, DVec3};
use gltf::accessor::{DataType, Dimensions};

use crate::{Error, Result};

/// The most elements a file's accessors without a buffer view (all zeros, but for their sparse
/// values) may give in all, each use counted: their counts are backed by no data, so they are
/// bounded here instead (2^24).
pub const MAX_ZERO_FILLED: usize = 1 << 24;

/// What [`import`] gives: the document, its buffers' bytes, its decoded images and each
/// node's local transform in double precision ([`local_transforms`]).
pub(super) type Imported = (
    gltf::Document,
    Vec<gltf::buffer::Data>,
    Vec<gltf::image::Data>,
    Vec<Option<DMat4>>,
);

/// `kind index`, with `('name')` when the item has a name: how every message names an item.
pub(super) fn label(kind: &str, index: usize, name: Option<&str>) -> String {
    match name {
        Some(name) => format!("{kind} {index} ('{name}')"),
        None => format!("{kind} {index}"),
    }
}

/// Reads `path` (`.gltf` or `.glb`) with its buffers and images as `gltf::import` does, with
/// the checks of the module documentation first. Errors are [`Error::Io`] when the file itself
/// cannot be read, else [`Error::Input`] naming the file and the item.
pub(super) fn import(path: &Path) -> Result<Imported> {
    let input = |message: String| Error::Input {
        path: path.to_path_buf(),
        message,
    };
    let unreadable = |e: gltf::Error| input(format!("not a readable glTF 2.0 file: {e}"));
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let bytes =
        glb_extent(&bytes).map_err(|why| input(format!("not a readable glTF 2.0 file: {why}")))?;
    let transforms = local_transforms(bytes);
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(bytes).map_err(unreadable)?;
    let root = document.into_json();
    before_validation(&root).map_err(input)?;
    let document = gltf::Document::from_json(root).map_err(unreadable)?;
    // Where `gltf::import` resolves relative URIs.
    let base = path.parent().unwrap_or_else(|| Path::new("./"));
    for b in document.buffers() {
        if let gltf::buffer::Source::Uri(uri) = b.source() {
            readable_uri(base, uri)
                .map_err(|why| input(format!("{}: {why}", label("buffer", b.index(), b.name()))))?;
        }
    }
    let buffers = gltf::import_buffers(&document, Some(base), blob).map_err(unreadable)?;
    for v in document.views() {
        let b = v.buffer();
        if v.offset()
            .checked_add(v.length())
            .is_none_or(|end| end > b.length())
        {
            return Err(input(format!(
                "{}: byteOffset {} + byteLength {} runs past the end of {} ({} bytes)",
                label("buffer view", v.index(), v.name()),
                v.offset(),
                v.length(),
                label("buffer", b.index(), b.name()),
                b.length()
            )));
        }
    }
    for image in document.images() {
        if let gltf::image::Source::Uri { uri, .. } = image.source() {
            readable_uri(base, uri).map_err(|why| {
                input(format!(
                    "{}: {why}",
                    label("image", image.index(), image.name())
                ))
            })?;
        }
    }
    let images = gltf::import_images(&document, Some(base), &buffers).map_err(unreadable)?;
    Ok((document, buffers, images, transforms))
}

/// Each node's local transform (glTF §3.5.3: its `matrix`, or T·R·S from its `translation`,
/// `rotation` and `scale`) from the file's JSON as written, in double precision: the `gltf`
/// crate reads them as `f32`, which rounds a translation to map coordinates (a building
/// 5.6·10⁶ m north) in steps of 0.5 m. `None` for a node whose numbers are not there as the
/// specification has them (the crate's reading then stands), and none at all for JSON this
/// cannot read (the crate reports what is wrong with it).
fn local_transforms(bytes: &[u8]) -> Vec<Option<DMat4>> {
    // A GLB's JSON is its first chunk: length and type after the 12-byte header.
    let json = if bytes.starts_with(b"glTF") {
        let word = |at: usize| {
            bytes
                .get(at..at + 4)
                .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]) as usize)
        };
        match (word(12), word(16)) {
            (Some(length), Some(chunk)) if chunk == super::CHUNK_JSON as usize => {
                bytes.get(20..20 + length)
            }
            _ => None,
        }
    } else {
        Some(bytes)
    };
    let Some(root) = json.and_then(|j| serde_json::from_slice::<serde_json::Value>(j).ok()) else {
        return Vec::new();
    };
    let numbers = |node: &serde_json::Value, key: &str, n: usize| -> Option<Option<Vec<f64>>> {
        match node.get(key) {
            None => Some(None),
            Some(v) => {
                let values: Option<Vec<f64>> = v.as_array()?.iter().map(|x| x.as_f64()).collect();
                values.filter(|v| v.len() == n).map(Some)
            }
        }
    };
    let local = |node: &serde_json::Value| -> Option<DMat4> {
        if let Some(m) = numbers(node, "matrix", 16)? {
            return Some(DMat4::from_cols_slice(&m));
        }
        let t = numbers(node, "translation", 3)?.unwrap_or(vec![0.0; 3]);
        let r = numbers(node, "rotation", 4)?.unwrap_or(vec![0.0, 0.0, 0.0, 1.0]);
        let s = numbers(node, "scale", 3)?.unwrap_or(vec![1.0; 3]);
        Some(DMat4::from_scale_rotation_translation(
            DVec3::from_slice(&s),
            DQuat::from_slice(&r),
            DVec3::from_slice(&t),
        ))
    };
    root.get("nodes")
        .and_then(|n| n.as_array())
        .map_or_else(Vec::new, |nodes| nodes.iter().map(local).collect())
}

/// The bytes of the file the crate may read: a GLB (magic `glTF`) up to the length its header
/// declares, which must lie between the header's 12 bytes and the file's size; anything else
/// whole (JSON).
fn glb_extent(bytes: &[u8]) -> std::result::Result<&[u8], String> {
    if !bytes.starts_with(b"glTF") {
        // A `.gltf`'s JSON, less the UTF-8 byte-order mark some Windows tools write (JSON
        // parsers refuse it as the first value's first character).
        return Ok(bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes));
    }
    let Some(&[a, b, c, d]) = bytes.get(8..12) else {
        return Err(format!(
            "the GLB header is cut short ({} bytes of 12)",
            bytes.len()
        ));
    };
    let length = u32::from_le_bytes([a, b, c, d]) as usize;
    if (12..=bytes.len()).contains(&length) {
        Ok(&bytes[..length])
    } else {
        Err(format!(
            "the GLB header declares a length of {length} bytes, but the file has {} (and the \
             header alone 12)",
            bytes.len()
        ))
    }
}

/// What the crate's validator or importer dereferences without checking: a primitive
/// attribute's accessor, an image's source and MIME type, a camera's projection.
fn before_validation(root: &gltf::json::Root) -> std::result::Result<(), String> {
    let accessors = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &prim.attributes {
                if index.value() >= accessors {
                    let semantic = match semantic {
                        gltf::json::validation::Checked::Valid(s) => s.to_string(),
                        gltf::json::validation::Checked::Invalid => "an attribute".into(),
                    };
                    return Err(format!(
                        "{} primitive {p}: {semantic} names accessor {}, but the file has {} \
                         accessors",
                        label("mesh", m, mesh.name.as_deref()),
                        index.value(),
                        accessors
                    ));
                }
            }
        }
    }
    for (i, image) in root.images.iter().enumerate() {
        let problem = match (&image.uri, &image.buffer_view, &image.mime_type) {
            (None, None, _) => "has neither a uri nor a bufferView",
            (None, Some(_), None) => "has a bufferView but no mimeType",
            _ => continue,
        };
        return Err(format!(
            "{} {problem}",
            label("image", i, image.name.as_deref())
        ));
    }
    for (i, camera) in root.cameras.iter().enumerate() {
        use gltf::json::camera::Type;
        use gltf::json::validation::Checked::Valid;
        let missing = match camera.type_ {
            Valid(Type::Perspective) if camera.perspective.is_none() => "perspective",
            Valid(Type::Orthographic) if camera.orthographic.is_none() => "orthographic",
            _ => continue,
        };
        return Err(format!(
            "{}: its type is {missing} but it has no `{missing}` object",
            label("camera", i, camera.name.as_deref())
        ));
    }
    Ok(())
}

/// Checks a buffer's or an image's `uri` as the crate will resolve it (relative to `base`, or
/// a `file:` URI): a `data:` URI or another scheme is left to the crate (which decodes the one
/// and refuses the other); a file must exist and be a regular file, and a relative URI's
/// `%XX` escapes must decode to UTF-8.
fn readable_uri(base: &Path, uri: &str) -> std::result::Result<(), String> {
    let file = if uri.contains(':') {
        if let Some(rest) = uri.strip_prefix("file://") {
            PathBuf::from(rest)
        } else if let Some(rest) = uri.strip_prefix("file:") {
            PathBuf::from(rest)
        } else {
            return Ok(());
        }
    } else {
        let decoded = String::from_utf8(percent_decode(uri.as_bytes())).map_err(|_| {
            format!("its uri {uri:?} is not UTF-8 once its %XX escapes are decoded")
        })?;
        base.join(decoded)
    };
    match std::fs::metadata(&file) {
        Ok(meta) if meta.is_file() => Ok(()),
        Ok(_) => Err(format!(
            "its uri {uri:?} names {}, which is not a regular file",
            file.display()
        )),
        Err(e) => Err(format!(
            "its uri {uri:?} names {}, which cannot be read: {e}",
            file.display()
        )),
    }
}

/// `%XX` escapes (two hexadecimal digits) decoded to their byte; a `%` not followed by two
/// hexadecimal digits is kept, as the crate's decoder (`urlencoding` 2) keeps it.
fn percent_decode(bytes: &[u8]) -> Vec<u8> {
    let hex = |b: u8| (b as char).to_digit(16).map(|d| d as u8);
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            if let (Some(h), Some(l)) = (
                bytes.get(i + 1).and_then(|&b| hex(b)),
                bytes.get(i + 2).and_then(|&b| hex(b)),
            ) {
                out.push((h << 4) | l);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    out
}

/// What an accessor is read as, for the types the reader accepts and for messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Role {
    /// A primitive's `POSITION`: VEC3 of FLOAT.
    Positions,
    /// A primitive's `indices`: SCALAR of UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT.
    Indices,
    /// A primitive's `TEXCOORD_n`: VEC2 of FLOAT, UNSIGNED_BYTE or UNSIGNED_SHORT.
    TexCoords(u32),
}

impl Role {
    /// The attribute's name in the file (`POSITION`, `indices`, `TEXCOORD_0`).
    pub(super) fn name(self) -> String {
        match self {
            Role::Positions => "POSITION".into(),
            Role::Indices => "indices".into(),
            Role::TexCoords(set) => format!("TEXCOORD_{set}"),
        }
    }

    fn accepts(self, dimensions: Dimensions, data: DataType) -> bool {
        use DataType::{F32, U16, U32, U8};
        match self {
            Role::Positions => dimensions == Dimensions::Vec3 && data == F32,
            Role::Indices => dimensions == Dimensions::Scalar && matches!(data, U8 | U16 | U32),
            Role::TexCoords(_) => dimensions == Dimensions::Vec2 && matches!(data, F32 | U8 | U16),
        }
    }

    fn expected(self) -> &'static str {
        match self {
            Role::Positions => "VEC3 of FLOAT",
            Role::Indices => "SCALAR of UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT",
            Role::TexCoords(_) => "VEC2 of FLOAT, UNSIGNED_BYTE or UNSIGNED_SHORT",
        }
    }
}

/// glTF's names of the types (`SCALAR`, `VEC3`, …, `FLOAT`, …).
fn type_name(dimensions: Dimensions, data: DataType) -> String {
    let d = match dimensions {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    };
    let c = match data {
        DataType::I8 => "BYTE",
        DataType::U8 => "UNSIGNED_BYTE",
        DataType::I16 => "SHORT",
        DataType::U16 => "UNSIGNED_SHORT",
        DataType::U32 => "UNSIGNED_INT",
        DataType::F32 => "FLOAT",
    };
    format!("{d} of {c}")
}

/// The bytes `count` (≥ 1) elements of `size` bytes, `stride` apart from `offset`, reach
/// (`offset + stride × (count − 1) + size`); `None` past `usize`.
fn extent(offset: usize, stride: usize, count: usize, size: usize) -> Option<usize> {
    offset
        .checked_add(stride.checked_mul(count.checked_sub(1)?)?)?
        .checked_add(size)
}

/// Checks that `elements` elements of `size` bytes from `offset` in buffer view `view`
/// (`stride` apart when the view sets one) lie within the view; `what` names them. Returns the
/// stride.
fn within_view(
    view: &gltf::buffer::View,
    offset: usize,
    elements: usize,
    size: usize,
    what: &str,
) -> std::result::Result<usize, String> {
    let stride = view.stride().unwrap_or(size);
    let view_name = label("buffer view", view.index(), view.name());
    if stride < size {
        return Err(format!(
            "{what}: {view_name} has byteStride {stride}, less than the {size} bytes of an element"
        ));
    }
    match extent(offset, stride, elements, size) {
        Some(end) if end <= view.length() => Ok(stride),
        end => Err(format!(
            "{what}: {elements} element(s) of {size} bytes, {stride} apart from byteOffset \
             {offset}, {} past the end of {view_name} ({} bytes)",
            end.map_or_else(|| "run".to_string(), |end| format!("end at byte {end},")),
            view.length()
        )),
    }
}

/// Checks accessor `a`, read as `role` by the primitive `owner` names, against the rules of
/// the module documentation; the message names the owner, the role and the accessor.
/// `zero_filled` counts the elements of the accessors without a buffer view read so far (each
/// use counts: a node instancing a mesh reads its accessors again), which may not pass
/// [`MAX_ZERO_FILLED`].
pub(super) fn check_accessor(
    a: &gltf::Accessor,
    role: Role,
    owner: &str,
    buffers: &[gltf::buffer::Data],
    zero_filled: &mut usize,
) -> std::result::Result<(), String> {
    let what = format!(
        "{owner}: {} ({})",
        label("accessor", a.index(), a.name()),
        role.name()
    );
    if !role.accepts(a.dimensions(), a.data_type()) {
        return Err(format!(
            "{what} is {}; {} is read as {}",
            type_name(a.dimensions(), a.data_type()),
            role.name(),
            role.expected()
        ));
    }
    let (count, size) = (a.count(), a.size());
    if count == 0 {
        return Err(format!("{what} has count 0 (at least 1 element)"));
    }
    match a.view() {
        Some(view) => {
            within_view(&view, a.offset(), count, size, &what)?;
        }
        None => {
            *zero_filled = zero_filled.saturating_add(count);
            if *zero_filled > MAX_ZERO_FILLED {
                return Err(format!(
                    "{what} has no bufferView (its elements are zeros but for its sparse \
                     values) and count {count}: the accessors without one come to {} elements \
                     (each use counted), more than the {MAX_ZERO_FILLED} this reader allows",
                    *zero_filled
                ));
            }
        }
    }
    let Some(sparse) = a.sparse() else {
        return Ok(());
    };
    let n = sparse.count();
    if n == 0 || n > count {
        return Err(format!(
            "{what}: its sparse count {n} is not in 1..={count} (the accessor's count)"
        ));
    }
    let indices = sparse.indices();
    let (view, offset) = (indices.view(), indices.offset());
    let index_size = indices.index_type().size();
    let stride = within_view(
        &view,
        offset,
        n,
        index_size,
        &format!("{what}: its sparse indices"),
    )?;
    within_view(
        &sparse.values().view(),
        sparse.values().offset(),
        n,
        size,
        &format!("{what}: its sparse values"),
    )?;
    // The indices must strictly increase and stay below the count (the crate's reader would
    // silently skip the values of the others).
    let data = buffers
        .get(view.buffer().index())
        .and_then(|b| b.get(view.offset()..view.offset() + view.length()))
        .ok_or_else(|| format!("{what}: its sparse indices' buffer is missing"))?;
    let mut previous: Option<u64> = None;
    for k in 0..n {
        let at = offset + k * stride;
        let bytes = data
            .get(at..at + index_size)
            .ok_or_else(|| format!("{what}: sparse index {k} lies outside its buffer view"))?;
        let mut word = [0u8; 8];
        word[..index_size].copy_from_slice(bytes);
        let i = u64::from_le_bytes(word);
        if i >= count as u64 || previous.is_some_and(|p| i <= p) {
            return Err(format!(
                "{what}: sparse index {k} is {i}; sparse indices must increase strictly and stay \
                 below the count {count}"
            ));
        }
        previous = Some(i);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_escapes_decode_as_the_crate_decodes_them() {
        assert_eq!(percent_decode(b"a%20b.bin"), b"a b.bin");
        assert_eq!(percent_decode(b"%41%4a%4A"), b"AJJ");
        // Incomplete or non-hexadecimal escapes are kept.
        assert_eq!(percent_decode(b"100%"), b"100%");
        assert_eq!(percent_decode(b"%4"), b"%4");
        assert_eq!(percent_decode(b"%G1%1G"), b"%G1%1G");
        assert_eq!(percent_decode(b"%ff"), [0xff]);
    }

    #[test]
    fn extents_do_not_overflow() {
        assert_eq!(extent(0, 12, 4, 12), Some(48));
        assert_eq!(extent(4, 8, 1, 4), Some(8));
        assert_eq!(extent(0, 4, 0, 4), None);
        assert_eq!(extent(usize::MAX, 4, 2, 4), None);
        assert_eq!(extent(0, usize::MAX, 3, 4), None);
    }
}
