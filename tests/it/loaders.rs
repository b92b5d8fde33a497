//! The scene loaders (`radiosity::io`) under hostile bytes: a deterministic "fuzz-lite" of
//! thousands of mutated Cornell OBJs and PLY scenes (ASCII and binary) through `Scene::load`
//! and `mesh::subdivide`, asserting no panic and that whatever loads is valid; and the
//! regression tests of the fuzz targets (`fuzz/`) and of issue 42: hand-made glTF files (and
//! a camera line) that a reader took without complaint, panicked on or hung on, each now an
//! error naming the file and the item. What belongs here: loader robustness, and each crash
//! a fuzzer finds, once fixed (the exact messages of ordinary bad input are checked by the
//! loaders' unit tests and the command-line tests).

use radiosity::mesh;
use radiosity::sampling::Rng;
use radiosity::scene::Scene;

use crate::support::{meshes, temp_dir};

/// Tokens a mutation may insert: numbers at the edges of what parses, keywords, separators.
const TOKENS: &[&str] = &[
    " ",
    "\n",
    "/",
    "-",
    "0",
    "1",
    "-1",
    "nan",
    "inf",
    "1e39",
    "-0",
    "1e-300",
    "f ",
    "v ",
    "usemtl light\n",
    "usemtl ",
    "mtllib ",
    "mtllib cornell_box.mtl\n",
    "o x\n",
    "g\n",
    "f 1 2 3\n",
    "f -1 -2 -3\n",
    "f 1 1 1\n",
    "v 0 0 0\n",
    "4294967296",
    "#",
    "\t",
    "\r",
    "é",
    "\u{0}",
    "element face 4294967295\n",
    "property list uint uint vertex_indices\n",
    "property float emission_r\n",
    "\u{ff}\u{ff}\u{ff}\u{7f}",
];

#[test]
fn fuzz_lite_mutated_cornell_never_panics() {
    // 3000 variants (≈ 1 s): byte flips, deletions, duplications and token insertions on the
    // Cornell OBJ, each loaded and (when it loads) subdivided. The property is only "no
    // panic, and a loaded scene satisfies its documented invariants".
    let dir = temp_dir("fuzz-lite");
    let original = std::fs::read(meshes().join("cornell_box.obj")).unwrap();
    std::fs::copy(
        meshes().join("cornell_box.mtl"),
        dir.join("cornell_box.mtl"),
    )
    .unwrap();
    mutate_and_load(&original, &dir.join("m.obj"), 3000, 0x5EED);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn fuzz_lite_mutated_ply_never_panics() {
    // The same for PLY scenes: an ASCII one with per-face materials and a binary one as
    // `radiosity bake` writes it (the binary body is where a length or index read from the
    // file could send a reader astray).
    let dir = temp_dir("fuzz-lite-ply");
    let ascii = "ply\nformat ascii 1.0\ncomment lit floor\n\
        element vertex 7\nproperty float x\nproperty float y\nproperty float z\n\
        element face 2\nproperty list uchar int vertex_indices\n\
        property float reflectance_r\nproperty float reflectance_g\nproperty float reflectance_b\n\
        property float emission_r\nproperty float emission_g\nproperty float emission_b\n\
        end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.2 0.2 1\n0.8 0.2 1\n0.5 0.8 1\n\
        4 0 1 2 3 0.5 0.5 0.5 0 0 0\n3 4 6 5 0 0 0 1 2 3\n";
    mutate_and_load(ascii.as_bytes(), &dir.join("a.ply"), 1500, 0xA5C11);
    let mesh = radiosity::bake::BakedMesh {
        positions: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ],
        vertex_radiance: vec![[0.5; 3]; 4],
        faces: vec![[0, 1, 2], [0, 2, 3]],
        face_radiance: vec![[0.5; 3]; 2],
        camera: None,
        sky: None,
    };
    let mut binary = Vec::new();
    radiosity::io::ply::write_to(&mut binary, &mesh, 1.0, false).unwrap();
    mutate_and_load(&binary, &dir.join("b.ply"), 1500, 0xB1A);
    let _ = std::fs::remove_dir_all(dir);
}

/// Writes `cases` mutations of `original` (byte flips, deletions, duplications, token
/// insertions; seeded) to `path` and loads each with `Scene::load`, subdividing what loads.
/// Asserts no panic (saving the crashing input beside `path`), that loaded scenes and their
/// patches validate, and that both loads and rejections occur.
fn mutate_and_load(original: &[u8], path: &std::path::Path, cases: usize, seed: u64) {
    let mut rng = Rng::new(&[seed]);
    let (mut loaded, mut rejected) = (0, 0);
    for case in 0..cases {
        let mut bytes = original.to_vec();
        for _ in 0..1 + rng.below(4) {
            let at = rng.below(bytes.len());
            match rng.below(5) {
                0 => bytes[at] = rng.next_u64() as u8,
                1 => {
                    let end = (at + rng.below(40)).min(bytes.len());
                    bytes.drain(at..end);
                }
                2 => {
                    let end = (at + rng.below(80)).min(bytes.len());
                    let chunk = bytes[at..end].to_vec();
                    bytes.splice(at..at, chunk);
                }
                _ => {
                    let t = TOKENS[rng.below(TOKENS.len())].as_bytes();
                    bytes.splice(at..at, t.iter().copied());
                }
            }
            if bytes.is_empty() {
                break;
            }
        }
        std::fs::write(path, &bytes).unwrap();
        let outcome = std::panic::catch_unwind(|| match Scene::load(path) {
            Ok(scene) => {
                scene.validate().unwrap();
                let (lo, hi) = scene.bounds();
                let p = mesh::subdivide(
                    &scene,
                    (hi - lo).length() / 4.0,
                    mesh::DEFAULT_CREASE_DEGREES,
                )
                .unwrap();
                p.validate().unwrap();
                true
            }
            Err(e) => {
                assert!(!e.to_string().is_empty());
                false
            }
        });
        match outcome {
            Ok(true) => loaded += 1,
            Ok(false) => rejected += 1,
            Err(_) => {
                let keep = path.with_extension(format!("crash-{case}"));
                std::fs::write(&keep, &bytes).unwrap();
                panic!("case {case} panicked; input saved to {}", keep.display());
            }
        }
    }
    // Both outcomes must occur, or the mutations are not exercising anything.
    let least = cases / 100;
    assert!(
        loaded > least && rejected > least,
        "{}: {loaded} loaded, {rejected} rejected",
        path.display()
    );
}

// glTF: what the reader checks before it reads (issue 42). Each case is a hand-made `.gltf`
// (its buffer a data URI) that the reader used to take without complaint, to panic on, or to
// hang on; each must now be an error that names the file and the item.

/// Standard padded base64 (RFC 4648), for data URIs.
fn base64(bytes: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ABC[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// A unit quad facing +Y: buffer 0 holds its four float positions (bytes 0–47, buffer view 0,
/// accessor 0 "corners") and six unsigned-short indices (bytes 48–59, buffer view 1, accessor
/// 1), then four spare bytes (60–63) that a reader running past a view would take.
fn quad() -> (serde_json::Value, Vec<u8>) {
    let mut bin = Vec::new();
    for c in [0f32, 0., 0., 0., 0., 1., 1., 0., 1., 1., 0., 0.] {
        bin.extend_from_slice(&c.to_le_bytes());
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    bin.extend_from_slice(&[0, 0, 128, 63]);
    let doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "floor"}],
        "meshes": [{"name": "quad", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": 64}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 12},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "name": "corners",
             "min": [0.0, 0.0, 0.0], "max": [1.0, 0.0, 1.0]},
            {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
        ],
    });
    (doc, bin)
}

/// Appends `item` to the JSON array `array`.
fn push(array: &mut serde_json::Value, item: serde_json::Value) {
    array.as_array_mut().expect("a JSON array").push(item);
}

/// The `.gltf` file of `doc`, with `bin` as buffer 0's data URI unless the document gives
/// buffer 0 a uri of its own.
fn gltf_bytes(mut doc: serde_json::Value, bin: &[u8]) -> Vec<u8> {
    if doc["buffers"][0].get("uri").is_none() {
        doc["buffers"][0]["uri"] =
            format!("data:application/octet-stream;base64,{}", base64(bin)).into();
    }
    serde_json::to_vec(&doc).unwrap()
}

/// Writes `doc` ([`gltf_bytes`]) as `dir/name` and loads it.
fn load_gltf(
    dir: &std::path::Path,
    name: &str,
    doc: serde_json::Value,
    bin: &[u8],
) -> radiosity::Result<Scene> {
    let path = dir.join(name);
    std::fs::write(&path, gltf_bytes(doc, bin)).unwrap();
    Scene::load(&path)
}

/// Asserts `result` is an input error (exit status 2) naming `name` and containing every
/// one of `needles`.
#[track_caller]
fn assert_gltf_error(result: radiosity::Result<Scene>, name: &str, needles: &[&str]) {
    let e = match result {
        Ok(s) => panic!(
            "{name}: loaded {} triangles, expected an error",
            s.triangles.len()
        ),
        Err(e) => e,
    };
    let text = e.to_string();
    assert_eq!(e.exit_code(), 2, "{text}");
    assert!(
        text.contains(name),
        "{name}: the error names the file: {text}"
    );
    for needle in needles {
        assert!(text.contains(needle), "{name}: {needle:?} not in: {text}");
    }
}

#[test]
fn the_gltf_quad_loads() {
    // The base of every case below is a good file.
    let dir = temp_dir("gltf-quad");
    let (doc, bin) = quad();
    let s = load_gltf(&dir, "quad.gltf", doc.clone(), &bin).unwrap();
    assert_eq!((s.positions.len(), s.triangles.len()), (4, 2));
    // The same JSON after a UTF-8 byte-order mark, as some Windows tools save it: a JSON
    // parser refuses the mark as the first value's first character, the reader drops it.
    let path = dir.join("bom.gltf");
    let mut bytes = b"\xEF\xBB\xBF".to_vec();
    bytes.extend(gltf_bytes(doc, &bin));
    std::fs::write(&path, bytes).unwrap();
    let s = Scene::load(&path).expect("a .gltf after a byte-order mark loads");
    assert_eq!((s.positions.len(), s.triangles.len()), (4, 2));
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_gltf_accessor_past_its_buffer_view_is_an_error_naming_it() {
    // Issue 42's known bug: an accessor whose count (times its stride and element size, plus
    // its byteOffset) runs past its buffer view was read without complaint: indices past
    // their view made the reader fall back to unindexed triangles, positions past theirs
    // dropped the primitive, and the bake went on with exit 0.
    let dir = temp_dir("gltf-accessor-past-view");
    type Edit = fn(&mut serde_json::Value);
    let cases: &[(&str, Edit, &[&str])] = &[
        (
            "indices_count.gltf",
            |d| d["accessors"][1]["count"] = 9.into(),
            &[
                "mesh 0 ('quad') primitive 0",
                "accessor 1 (indices)",
                "9 element(s) of 2 bytes",
                "end at byte 18, past the end of buffer view 1 (12 bytes)",
            ],
        ),
        (
            "positions_count.gltf",
            |d| d["accessors"][0]["count"] = 5.into(),
            &[
                "accessor 0 ('corners') (POSITION)",
                "5 element(s) of 12 bytes",
                "buffer view 0 (48 bytes)",
            ],
        ),
        (
            "positions_offset.gltf",
            |d| d["accessors"][0]["byteOffset"] = 4.into(),
            &[
                "accessor 0 ('corners') (POSITION)",
                "from byteOffset 4",
                "buffer view 0",
            ],
        ),
        (
            "indices_offset.gltf",
            |d| d["accessors"][1]["byteOffset"] = 2.into(),
            &[
                "accessor 1 (indices)",
                "from byteOffset 2",
                "buffer view 1 (12 bytes)",
            ],
        ),
        (
            "positions_stride.gltf",
            |d| d["bufferViews"][0]["byteStride"] = 16.into(),
            &[
                "accessor 0 ('corners') (POSITION)",
                "16 apart",
                "buffer view 0 (48 bytes)",
            ],
        ),
        (
            "stride_below_element.gltf",
            |d| d["bufferViews"][0]["byteStride"] = 8.into(),
            &[
                "accessor 0 ('corners') (POSITION)",
                "byteStride 8",
                "12 bytes of an element",
            ],
        ),
        (
            "view_past_buffer.gltf",
            |d| d["bufferViews"][1]["byteLength"] = 20.into(),
            &[
                "buffer view 1",
                "byteOffset 48 + byteLength 20",
                "runs past the end of buffer 0 (64 bytes)",
            ],
        ),
        (
            "count_zero.gltf",
            |d| d["accessors"][1]["count"] = 0.into(),
            &["accessor 1 (indices)", "count 0"],
        ),
        (
            "index_out_of_range.gltf",
            |d| d["accessors"][0]["count"] = 3.into(),
            &[
                "accessor 1 (indices)",
                "element 5 is 3",
                "past the 3 vertices of its POSITION \
              (accessor 0 ('corners'))",
            ],
        ),
    ];
    for (name, edit, needles) in cases {
        let (mut doc, bin) = quad();
        edit(&mut doc);
        assert_gltf_error(load_gltf(&dir, name, doc, &bin), name, needles);
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn gltf_indices_are_checked_per_primitive_and_texture_coordinates_by_count() {
    let dir = temp_dir("gltf-primitives");
    // Two primitives over the same positions' halves: the second's index 3 is a vertex of
    // the scene (the first primitive's), but not of its own POSITION: an error, not a
    // triangle borrowed from another primitive.
    let (mut doc, bin) = quad();
    push(
        &mut doc["accessors"],
        serde_json::json!({"bufferView": 0, "byteOffset": 0,
        "componentType": 5126, "count": 3, "type": "VEC3",
        "min": [0.0, 0.0, 0.0], "max": [1.0, 0.0, 1.0]}),
    );
    push(
        &mut doc["meshes"][0]["primitives"],
        serde_json::json!({"attributes": {"POSITION": 2}, "indices": 1}),
    );
    assert_gltf_error(
        load_gltf(&dir, "borrowed.gltf", doc, &bin),
        "borrowed.gltf",
        &[
            "mesh 0 ('quad') primitive 1",
            "accessor 1 (indices)",
            "is 3",
            "past the 3 vertices of its POSITION (accessor 2)",
        ],
    );
    // A base-colour texture's coordinates: fewer than the vertices, or past their view.
    let png = {
        let mut png = Vec::new();
        image::RgbImage::from_pixel(2, 2, image::Rgb([200, 100, 50]))
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        png
    };
    let textured = |count: usize, view_length: usize| {
        let (mut doc, bin) = quad();
        doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = 2.into();
        doc["meshes"][0]["primitives"][0]["material"] = 0.into();
        doc["materials"] = serde_json::json!([{"name": "brick", "pbrMetallicRoughness":
            {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}]);
        doc["textures"] = serde_json::json!([{"source": 0}]);
        doc["images"] =
            serde_json::json!([{"uri": format!("data:image/png;base64,{}", base64(&png))}]);
        push(
            &mut doc["bufferViews"],
            serde_json::json!({"buffer": 0, "byteOffset": 0, "byteLength": view_length}),
        );
        push(
            &mut doc["accessors"],
            serde_json::json!({"bufferView": 2, "componentType": 5126,
            "count": count, "type": "VEC2", "name": "uv"}),
        );
        (doc, bin)
    };
    let (doc, bin) = textured(4, 32);
    load_gltf(&dir, "uv.gltf", doc, &bin).expect("the textured quad loads");
    let (doc, bin) = textured(3, 32);
    assert_gltf_error(
        load_gltf(&dir, "uv_count.gltf", doc, &bin),
        "uv_count.gltf",
        &[
            "accessor 2 ('uv') (TEXCOORD_0) has 3 elements",
            "POSITION (accessor 0 ('corners')) has 4",
        ],
    );
    let (doc, bin) = textured(4, 24);
    assert_gltf_error(
        load_gltf(&dir, "uv_view.gltf", doc, &bin),
        "uv_view.gltf",
        &["accessor 2 ('uv') (TEXCOORD_0)", "buffer view 2 (24 bytes)"],
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn gltf_sparse_accessors_are_checked() {
    let dir = temp_dir("gltf-sparse");
    // Accessor 2: the quad's corners with vertex 1 replaced (u8 index at byte 60, value at
    // bytes 48–59: the index bytes, read as floats, do not matter).
    let sparse = |indices: serde_json::Value, count: usize, view: Option<usize>| {
        let (mut doc, bin) = quad();
        push(
            &mut doc["bufferViews"],
            serde_json::json!({"buffer": 0, "byteOffset": 60, "byteLength": 4}),
        );
        let mut a = serde_json::json!({"componentType": 5126, "count": count, "type": "VEC3",
            "min": [0.0, 0.0, 0.0], "max": [1.0, 0.0, 1.0],
            "sparse": {"count": 1, "indices": indices, "values": {"bufferView": 0}}});
        if let Some(v) = view {
            a["bufferView"] = v.into();
        }
        push(&mut doc["accessors"], a);
        doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 2.into();
        (doc, bin)
    };
    let (doc, bin) = sparse(
        serde_json::json!({"bufferView": 2, "componentType": 5121}),
        4,
        Some(0),
    );
    load_gltf(&dir, "sparse.gltf", doc, &bin).expect("a good sparse accessor loads");
    let cases = [
        // The sparse indices past their view (u32 at byte 2 of a 4-byte view).
        (
            sparse(
                serde_json::json!({"bufferView": 2, "byteOffset": 2, "componentType": 5125}),
                4,
                Some(0),
            ),
            &[
                "accessor 2 (POSITION): its sparse indices",
                "buffer view 2 (4 bytes)",
            ][..],
        ),
        // An index past the count (the spare bytes 62–63, 128 and 63: u16 16256).
        (
            sparse(
                serde_json::json!({"bufferView": 2, "byteOffset": 2, "componentType": 5123}),
                4,
                Some(0),
            ),
            &["sparse index 0 is 16256", "below the count 4"][..],
        ),
        // No bufferView: zeros, but so many that they would fill the memory.
        (
            sparse(
                serde_json::json!({"bufferView": 2, "componentType": 5121}),
                1 << 40,
                None,
            ),
            &[
                "accessor 2 (POSITION) has no bufferView",
                "count 1099511627776",
                "more than the 16777216",
            ][..],
        ),
    ];
    for (k, ((doc, bin), needles)) in cases.into_iter().enumerate() {
        let name = format!("sparse_{k}.gltf");
        assert_gltf_error(load_gltf(&dir, &name, doc, &bin), &name, needles);
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn gltf_files_that_panicked_or_hung_the_reader_are_errors() {
    // Found by the gltf_scene fuzzer (fuzz/), minimised by hand, and by reading the `gltf`
    // crate's importer: each used to panic (or, in a build with overflow checks, to
    // overflow), hang, or read past its data.
    let dir = temp_dir("gltf-hostile");
    type Edit = fn(&mut serde_json::Value);
    let cases: &[(&str, Edit, &[&str])] = &[
        // Fuzzer: POSITION names an accessor the file does not have (the crate's validator
        // indexed it unchecked: "index out of bounds").
        (
            "missing_accessor.gltf",
            |d| d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 7.into(),
            &[
                "mesh 0 ('quad') primitive 0: POSITION names accessor 7",
                "has 2 accessors",
            ],
        ),
        // Fuzzer: indices of FLOAT (the crate's reader hit `unreachable!`).
        (
            "float_indices.gltf",
            |d| d["accessors"][1]["componentType"] = 5126.into(),
            &["accessor 1 (indices) is SCALAR of FLOAT", "UNSIGNED_SHORT"],
        ),
        // Fuzzer: POSITION not VEC3 of FLOAT (a debug assertion; without it, the floats were
        // read from whatever the bytes were).
        (
            "vec2_positions.gltf",
            |d| d["accessors"][0]["type"] = "VEC2".into(),
            &[
                "accessor 0 ('corners') (POSITION) is VEC2 of FLOAT",
                "VEC3 of FLOAT",
            ],
        ),
        (
            "short_positions.gltf",
            |d| d["accessors"][0]["componentType"] = 5122.into(),
            &["(POSITION) is VEC3 of SHORT"],
        ),
        // A node that is its own child: the walk recursed until the stack overflowed.
        (
            "cycle.gltf",
            |d| d["nodes"][0]["children"] = serde_json::json!([0]),
            &["node 0 ('floor') is reached twice", "trees"],
        ),
        // A node under two parents (or a root listed twice): each would be read as often
        // as it is reached, exponentially in a chain of such nodes.
        (
            "shared_child.gltf",
            |d| {
                d["nodes"] = serde_json::json!([{"children": [2]}, {"children": [2]},
                    {"mesh": 0}]);
                d["scenes"][0]["nodes"] = serde_json::json!([0, 1]);
            },
            &["node 2 is reached twice"],
        ),
        // An image in a buffer view without a mimeType (the crate unwrapped it).
        (
            "image_mime.gltf",
            |d| d["images"] = serde_json::json!([{"bufferView": 0}]),
            &["image 0 has a bufferView but no mimeType"],
        ),
        (
            "image_source.gltf",
            |d| d["images"] = serde_json::json!([{"name": "nothing"}]),
            &["image 0 ('nothing') has neither a uri nor a bufferView"],
        ),
        // A camera whose type names the projection it does not have (unwrapped).
        (
            "camera_type.gltf",
            |d| {
                d["cameras"] = serde_json::json!([{"type": "orthographic",
                    "perspective": {"yfov": 0.5, "znear": 0.1}}]);
                d["nodes"][0]["camera"] = 0.into();
            },
            &["camera 0: its type is orthographic but it has no `orthographic` object"],
        ),
        // A relative uri whose %XX escapes are not UTF-8 (unwrapped).
        (
            "escape.gltf",
            |d| d["buffers"][0]["uri"] = "%ff%fe.bin".into(),
            &["buffer 0: its uri \"%ff%fe.bin\" is not UTF-8"],
        ),
        // A uri naming a device: reading /dev/zero never ends.
        (
            "device.gltf",
            |d| d["buffers"][0]["uri"] = "/dev/zero".into(),
            &["buffer 0: its uri \"/dev/zero\" names /dev/zero, which is not a regular file"],
        ),
        (
            "file_device.gltf",
            |d| d["buffers"][0]["uri"] = "file:///dev/zero".into(),
            &["which is not a regular file"],
        ),
        (
            "missing_buffer.gltf",
            |d| d["buffers"][0]["uri"] = "gone.bin".into(),
            &["buffer 0: its uri \"gone.bin\" names", "cannot be read"],
        ),
        // Lights out of the ranges glTF allows used to reach the bake unchecked.
        (
            "negative_light.gltf",
            |d| {
                d["extensionsUsed"] = serde_json::json!(["KHR_lights_punctual"]);
                d["extensions"] = serde_json::json!({"KHR_lights_punctual": {"lights": [
                    {"type": "point", "intensity": -683.0, "name": "sink"}]}});
                d["nodes"][0]["extensions"] =
                    serde_json::json!({"KHR_lights_punctual": {"light": 0}});
            },
            &[
                "KHR_lights_punctual light 0 ('sink') at node 0 ('floor')",
                "must be finite and ≥ 0",
            ],
        ),
        (
            "inverted_spot.gltf",
            |d| {
                d["extensionsUsed"] = serde_json::json!(["KHR_lights_punctual"]);
                d["extensions"] = serde_json::json!({"KHR_lights_punctual": {"lights": [
                    {"type": "spot", "spot": {"innerConeAngle": 0.6, "outerConeAngle": 0.3}}]}});
                d["nodes"][0]["extensions"] =
                    serde_json::json!({"KHR_lights_punctual": {"light": 0}});
            },
            &[
                "KHR_lights_punctual light 0 at node 0 ('floor')",
                "0 ≤ inner < outer",
            ],
        ),
        // A scale past f32 (read as infinite): the positions were infinite.
        (
            "infinite_scale.gltf",
            |d| d["nodes"][0]["scale"] = serde_json::json!([1e39, 1.0, 1.0]),
            &["node 0 ('floor'): its transform (with its parents') is not finite"],
        ),
    ];
    for (name, edit, needles) in cases {
        let (mut doc, bin) = quad();
        edit(&mut doc);
        assert_gltf_error(load_gltf(&dir, name, doc, &bin), name, needles);
    }
    // Fuzzer: a GLB whose header declares a length below its own 12 bytes (the crate
    // subtracted the header from it unchecked; without overflow checks it asked for a 4 GiB
    // buffer), and one that declares more than the file has.
    for (name, length) in [("short.glb", 4u32), ("long.glb", 1000)] {
        let mut glb = b"glTF".to_vec();
        glb.extend_from_slice(&2u32.to_le_bytes());
        glb.extend_from_slice(&length.to_le_bytes());
        glb.extend_from_slice(&[0; 12]);
        let path = dir.join(name);
        std::fs::write(&path, &glb).unwrap();
        assert_gltf_error(
            Scene::load(&path),
            name,
            &["GLB header declares a length of"],
        );
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_non_finite_gltf_position_is_an_error_naming_its_element() {
    // Float data can hold NaN and infinities; the loader's validation caught them only after
    // the walk, as "vertex N" of the whole scene.
    let dir = temp_dir("gltf-nan");
    let (doc, mut bin) = quad();
    bin[28..32].copy_from_slice(&f32::NAN.to_le_bytes());
    assert_gltf_error(
        load_gltf(&dir, "nan.gltf", doc, &bin),
        "nan.gltf",
        &["mesh 0 ('quad') primitive 0: accessor 0 ('corners') (POSITION): element 2 is not finite"],
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_gltf_light_without_a_direction_is_ignored_with_a_warning() {
    // A spot or directional light under a node scaled to zero has no direction: a valid file
    // (a zero scale hides things), so the light is left out with a warning, as a sun below
    // the horizon is.
    let dir = temp_dir("gltf-zero-scale");
    let (mut doc, bin) = quad();
    doc["extensionsUsed"] = serde_json::json!(["KHR_lights_punctual"]);
    doc["extensions"] = serde_json::json!({"KHR_lights_punctual": {"lights": [
        {"type": "spot", "name": "hidden", "spot": {}}, {"type": "directional", "name": "off"}]}});
    doc["scenes"][0]["nodes"] = serde_json::json!([0, 1, 2]);
    for light in 0..2 {
        push(
            &mut doc["nodes"],
            serde_json::json!({"scale": [0.0, 0.0, 0.0],
            "extensions": {"KHR_lights_punctual": {"light": light}}}),
        );
    }
    let s = load_gltf(&dir, "zero.gltf", doc, &bin).unwrap();
    assert!(s.lights.is_empty() && s.sun.is_none());
    for w in [
        "spot light 'hidden' ignored",
        "directional light 'off' ignored",
    ] {
        assert!(
            s.warnings
                .iter()
                .any(|x| x.contains(w) && x.contains("no direction")),
            "{w}: {:?}",
            s.warnings
        );
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_camera_line_whose_frame_overflows_is_an_error_at_its_line() {
    // Found by the camera_line fuzzer: |target − eye|² overflows f64, the check of up against
    // the view passed on NaN, and a camera with up = 0 was accepted (its picture all NaN).
    let dir = temp_dir("camera-overflow");
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\n# camera: 27 1.1e201 0 2 5 6 0 0 0 34\nf 1 2 3\n";
    let path = dir.join("far.obj");
    std::fs::write(&path, obj).unwrap();
    let text = Scene::load(&path).unwrap_err().to_string();
    assert!(
        text.contains("far.obj:4:") && text.contains("malformed camera line"),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(dir);
}
