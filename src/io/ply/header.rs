//! The PLY header, the one layer both PLY readers share (the scene reader of any tool's PLY
//! and the read-back of our own baked files), so they agree on every rule: the `ply` magic
//! line, `format ascii 1.0` or `format binary_little_endian 1.0` (big-endian is refused),
//! `element NAME COUNT` with its `property TYPE NAME` / `property list COUNT_TYPE TYPE NAME`
//! lines, the eight scalar types and their sized aliases, `obj_info` and comments ignored, and
//! one optional `comment camera: …` line ([`crate::scene::camera`]): a malformed one, or a
//! second one, is an error at its line; the first `comment sky: …` line is kept as text for
//! the read-back of baked files. Every error names the file and the header line.

use std::path::Path;

pub(super) use crate::io::parse_error;
use crate::scene::camera::{Camera, CameraLine};
use crate::scene::lights::SKY_KEYWORD;
use crate::Result;

/// A PLY scalar type (`char`…`double`, or the sized aliases `int8`…`float64`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// The type's name as this crate writes it (`float`, `uchar`, …).
    pub(super) fn name(self) -> &'static str {
        match self {
            Scalar::I8 => "char",
            Scalar::U8 => "uchar",
            Scalar::I16 => "short",
            Scalar::U16 => "ushort",
            Scalar::I32 => "int",
            Scalar::U32 => "uint",
            Scalar::F32 => "float",
            Scalar::F64 => "double",
        }
    }

    pub(super) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// The value of `b` (exactly [`Scalar::size`] bytes, little-endian) as f64 (exact for
    /// every type).
    pub(super) fn read_le(self, b: &[u8]) -> f64 {
        match self {
            Scalar::I8 => f64::from(b[0] as i8),
            Scalar::U8 => f64::from(b[0]),
            Scalar::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            Scalar::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            Scalar::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::F64 => f64::from_le_bytes(b[..8].try_into().unwrap_or([0; 8])),
        }
    }
}

/// A property of an element: a scalar, or a list with its count and item types.
#[derive(Debug)]
pub(super) struct Property {
    pub name: String,
    /// The count type of a list property; `None` for a scalar.
    pub list: Option<Scalar>,
    /// The value type (of a list's items).
    pub scalar: Scalar,
    /// Header line of the `property` statement.
    pub line: usize,
}

impl Property {
    /// The property's header line as this crate writes it (`property float x`, `property list
    /// uchar int vertex_indices`): the canonical type names, single spaces.
    pub(super) fn declaration(&self) -> String {
        match self.list {
            Some(count) => format!(
                "property list {} {} {}",
                count.name(),
                self.scalar.name(),
                self.name
            ),
            None => format!("property {} {}", self.scalar.name(), self.name),
        }
    }
}

#[derive(Debug)]
pub(super) struct Element {
    pub name: String,
    /// Records the header promises.
    pub count: usize,
    pub properties: Vec<Property>,
    /// Header line of the `element` statement.
    pub line: usize,
}

impl Element {
    pub fn find(&self, name: &str) -> Option<usize> {
        self.properties.iter().position(|p| p.name == name)
    }

    /// The three indices of `{prefix}_r/g/b`, `None` when none exists; a partial group is
    /// an error at the element's line.
    pub fn group(&self, path: &Path, prefix: &str) -> Result<Option<[usize; 3]>> {
        let found = ["r", "g", "b"].map(|c| self.find(&format!("{prefix}_{c}")));
        match found {
            [None, None, None] => Ok(None),
            [Some(r), Some(g), Some(b)] => {
                for i in [r, g, b] {
                    if self.properties[i].list.is_some() {
                        return Err(parse_error(
                            path,
                            self.line,
                            format!("element {}: {} must be a scalar", self.name, self.properties[i].name),
                        ));
                    }
                }
                Ok(Some([r, g, b]))
            }
            _ => Err(parse_error(
                path,
                self.line,
                format!(
                    "element {}: {prefix}_r, {prefix}_g and {prefix}_b must all be present or all absent",
                    self.name
                ),
            )),
        }
    }
}

pub(super) struct Header {
    /// `format ascii 1.0` (else binary little-endian).
    pub ascii: bool,
    /// The elements in file order.
    pub elements: Vec<Element>,
    /// Byte offset of the first body byte.
    pub body_start: usize,
    /// Number of header lines (the body's first line is `lines + 1`).
    pub lines: usize,
    /// The `comment camera: …` line's camera (at most one such line).
    pub camera: Option<Camera>,
    /// The first `comment sky: …` line (a baked file's sky, [`crate::scene::Sky::from_text`]):
    /// its header line and the text after the marker, unparsed.
    pub sky: Option<(usize, String)>,
}

impl Header {
    /// Reads the header at the start of `bytes` (the file `path`); see the module
    /// documentation for the rules.
    pub fn parse(path: &Path, bytes: &[u8]) -> Result<Header> {
        parse_header(path, bytes)
    }
}

fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header> {
    let mut pos = 0;
    let mut number = 0;
    let mut format = None;
    let mut camera = CameraLine::default();
    let mut sky = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        number += 1;
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(parse_error(
                path,
                number,
                "the header has no end_header line",
            ));
        };
        let raw = &bytes[pos..pos + len];
        pos += len + 1;
        let text = std::str::from_utf8(raw)
            .ok()
            .filter(|t| t.is_ascii())
            .ok_or_else(|| parse_error(path, number, "header line is not ASCII text"))?;
        let words: Vec<&str> = text.split_whitespace().collect();
        if number == 1 {
            if words != ["ply"] {
                return Err(parse_error(
                    path,
                    1,
                    "not a PLY file (first line is not `ply`)",
                ));
            }
            continue;
        }
        match words[..] {
            ["comment", ..] => {
                let comment = text.trim_start().strip_prefix("comment").unwrap_or("");
                camera
                    .read(comment, number)
                    .map_err(|why| parse_error(path, number, why))?;
                if let Some(text) = comment.trim_start().strip_prefix(SKY_KEYWORD) {
                    // Kept as text: only the read-back of baked files reads it (a scene's
                    // PLY may say anything in its comments).
                    sky.get_or_insert((number, text.to_string()));
                }
            }
            [] | ["obj_info", ..] => {}
            ["format", kind, "1.0"] => {
                format = Some(match kind {
                    "ascii" => true,
                    "binary_little_endian" => false,
                    _ => {
                        return Err(parse_error(
                            path,
                            number,
                            format!(
                            "unsupported format {kind} (ascii and binary_little_endian are read)"
                        ),
                        ))
                    }
                })
            }
            ["element", name, count] => {
                let count = count.parse().map_err(|_| {
                    parse_error(
                        path,
                        number,
                        format!("element {name}: malformed count '{count}'"),
                    )
                })?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                    line: number,
                });
            }
            ["property", ..] => {
                let Some(element) = elements.last_mut() else {
                    return Err(parse_error(path, number, "property before any element"));
                };
                let ty = |name: &str| {
                    Scalar::parse(name).ok_or_else(|| {
                        parse_error(path, number, format!("unknown property type '{name}'"))
                    })
                };
                let property = match words[1..] {
                    ["list", count, item, name] => Property {
                        name: name.to_string(),
                        list: Some(ty(count)?),
                        scalar: ty(item)?,
                        line: number,
                    },
                    [scalar, name] if scalar != "list" => Property {
                        name: name.to_string(),
                        list: None,
                        scalar: ty(scalar)?,
                        line: number,
                    },
                    _ => {
                        return Err(parse_error(
                            path,
                            number,
                            format!("malformed property line `{}`", words.join(" ")),
                        ))
                    }
                };
                element.properties.push(property);
            }
            ["end_header"] => break,
            _ => {
                return Err(parse_error(
                    path,
                    number,
                    format!("unknown header line `{}`", words.join(" ")),
                ))
            }
        }
    }
    if let Some(e) = elements
        .iter()
        .find(|e| e.properties.is_empty() && e.count > 0)
    {
        return Err(parse_error(
            path,
            e.line,
            format!("element {} has records but no properties", e.name),
        ));
    }
    let Some(ascii) = format else {
        return Err(parse_error(
            path,
            number,
            "the header has no `format … 1.0` line",
        ));
    };
    Ok(Header {
        ascii,
        elements,
        body_start: pos,
        lines: number,
        camera: camera.camera(),
        sky,
    })
}
