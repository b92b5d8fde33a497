#!/usr/bin/env python3
"""Check our glTF input and output with an independent library (pygltflib, from PyPI).

Output: bakes the shipped Cornell box twice with the same settings, to .glb and to binary .ply,
reads the .glb with pygltflib and checks, vertex by vertex:
- the file is a valid GLB that pygltflib parses, with POSITION, COLOR_0 and _RADIANCE;
- _RADIANCE equals the PLY's float radiance (the same bake: the same numbers, as f32);
- COLOR_0 is linear: encoded with the sRGB curve and rounded to 8 bits it gives the PLY's
  colour bytes (which MeshLab reads; tools/meshlab_check.py checks those);
- positions equal the PLY's (the Cornell box is y-up: no turn).

Round trip: writes the Cornell box as a .gltf with pygltflib (its OBJ parsed here: positions,
fan-triangulated faces, Kd as baseColorFactor with metallicFactor 0, Ke as emissiveFactor with
KHR_materials_emissive_strength), bakes that to .glb, reads it back with pygltflib and checks
that its colours are the OBJ bake's: the same scene through another door. Positions become
f32 in glTF while an OBJ is read in double precision, so the OBJ baked beside it is a copy
with its coordinates rounded to f32 (the same numbers through both doors); the bake's
decisions (contact lines, refinement) are not continuous in the positions, so two files
that differ by rounding may differ by more than rounding somewhere. Every colour byte within
1 of the OBJ bake's.

Usage:
    python3 tools/gltf_check.py
It creates a virtual environment in target/gltf-venv with pygltflib on first use. Exit status 0
when every check passes, 1 otherwise, 3 when pygltflib cannot be installed (no network to
PyPI: the check did not run).
"""
import os
import struct
import subprocess
import sys
import tempfile

import venv_module

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def srgb8(x):
    """Linear [0, 1] to an 8-bit sRGB code, as the PLY writer does (IEC 61966-2-1)."""
    x = min(max(x, 0.0), 1.0)
    v = 12.92 * x if x <= 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055
    return int(round(255 * v))


def read_ply(path):
    """Positions, colour bytes and float radiance per vertex of our binary PLY."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    nv = next(int(l.split()[2]) for l in header if l.startswith("element vertex"))
    # Positions are doubles where single precision would round them (far from the origin).
    fmt = "<dddBBBfff" if "property double x" in header else "<fffBBBfff"
    size = struct.calcsize(fmt)
    out = []
    for k in range(nv):
        x, y, z, r, g, b, lr, lg, lb = struct.unpack_from(fmt, data, end + size * k)
        out.append(((x, y, z), (r, g, b), (lr, lg, lb)))
    return out


def accessor_floats(gltf, blob, index):
    """The VEC3 float values of accessor `index`."""
    acc = gltf.accessors[index]
    view = gltf.bufferViews[acc.bufferView]
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    return [struct.unpack_from("<fff", blob, start + 12 * k) for k in range(acc.count)]


def obj_to_gltf(obj, out):
    """The Cornell box OBJ + MTL as a .gltf written by pygltflib (see the module doc)."""
    import base64
    import pygltflib

    folder = os.path.dirname(obj)
    positions, faces, materials, current = [], [], {}, None
    for line in open(obj):
        w = line.split()
        if not w:
            continue
        if w[0] == "v":
            positions.append(tuple(float(x) for x in w[1:4]))
        elif w[0] == "usemtl":
            current = w[1]
        elif w[0] == "f":
            idx = [int(t.split("/")[0]) - 1 for t in w[1:]]
            for k in range(1, len(idx) - 1):
                faces.append((current, (idx[0], idx[k], idx[k + 1])))
        elif w[0] == "mtllib":
            name = None
            for m in open(os.path.join(folder, w[1])):
                u = m.split()
                if u[:1] == ["newmtl"]:
                    name = u[1]
                    materials[name] = {"Kd": [0.5] * 3, "Ke": [0.0] * 3}
                elif u[:1] in (["Kd"], ["Ke"]) and name:
                    vals = [float(x) for x in u[1:4]]
                    materials[name][u[0]] = vals * 3 if len(vals) == 1 else vals
    # Materials in the MTL's order; primitives are the runs of faces with one material, in the
    # OBJ's order, so that the triangles come in the same order as from the OBJ.
    order = list(materials)
    runs = []
    for m, t in faces:
        if not runs or runs[-1][0] != m:
            runs.append((m, []))
        runs[-1][1].append(t)
    blob = b"".join(struct.pack("<fff", *p) for p in positions)
    lo = [min(p[c] for p in positions) for c in range(3)]
    hi = [max(p[c] for p in positions) for c in range(3)]
    gltf = pygltflib.GLTF2()
    gltf.extensionsUsed = ["KHR_materials_emissive_strength"]
    gltf.accessors.append(pygltflib.Accessor(bufferView=0, componentType=pygltflib.FLOAT,
                                             count=len(positions), type="VEC3", min=lo, max=hi))
    gltf.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=0, byteLength=len(blob)))
    for name in order:
        m = materials[name]
        strength = max(max(m["Ke"]), 1.0)
        gltf.materials.append(pygltflib.Material(
            name=name,
            pbrMetallicRoughness=pygltflib.PbrMetallicRoughness(
                baseColorFactor=m["Kd"] + [1.0], metallicFactor=0.0),
            emissiveFactor=[e / strength for e in m["Ke"]],
            extensions={"KHR_materials_emissive_strength": {"emissiveStrength": strength}},
        ))
    prims = []
    for name, tris in runs:
        offset = len(blob)
        blob += b"".join(struct.pack("<III", *t) for t in tris)
        gltf.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=offset,
                                                     byteLength=12 * len(tris)))
        gltf.accessors.append(pygltflib.Accessor(bufferView=len(gltf.bufferViews) - 1,
                                                 componentType=pygltflib.UNSIGNED_INT,
                                                 count=3 * len(tris), type="SCALAR"))
        prims.append(pygltflib.Primitive(attributes=pygltflib.Attributes(POSITION=0),
                                         indices=len(gltf.accessors) - 1,
                                         material=order.index(name)))
    gltf.meshes.append(pygltflib.Mesh(primitives=prims))
    gltf.nodes.append(pygltflib.Node(mesh=0))
    gltf.scenes.append(pygltflib.Scene(nodes=[0]))
    gltf.scene = 0
    uri = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
    gltf.buffers.append(pygltflib.Buffer(byteLength=len(blob), uri=uri))
    gltf.save(out)


def glb_colours(path):
    """COLOR_0 per vertex of one of our .glb files, as read by pygltflib."""
    import pygltflib

    gltf = pygltflib.GLTF2().load(path)
    blob = gltf.binary_blob()
    prim = gltf.meshes[0].primitives[0]
    return accessor_floats(gltf, blob, prim.attributes.COLOR_0)


def round_trip(tmp):
    """Failures of the glTF-in, .glb-out round trip (see the module doc)."""
    import shutil

    # The OBJ with its coordinates rounded to f32, as the glTF stores them (repr of the f32
    # value widened to f64 reads back as exactly that value).
    original = os.path.join(ROOT, "meshes", "cornell_box.obj")
    obj = os.path.join(tmp, "cornell_box.obj")
    shutil.copy(os.path.join(ROOT, "meshes", "cornell_box.mtl"), tmp)
    with open(original) as f, open(obj, "w") as out:
        for line in f:
            w = line.split()
            if w[:1] == ["v"]:
                xyz = [struct.unpack("<f", struct.pack("<f", float(c)))[0] for c in w[1:4]]
                line = "v " + " ".join(repr(c) for c in xyz) + "\n"
            out.write(line)
    src = os.path.join(tmp, "cornell.gltf")
    obj_to_gltf(obj, src)
    outs = {}
    for name, scene in (("via_obj", obj), ("via_gltf", src)):
        out = os.path.join(tmp, name + ".glb")
        subprocess.check_call(
            ["cargo", "run", "--release", "--quiet", "--", "bake", scene, "-o", out,
             "--max-edge", "110", "--refine", "0", "--exposure", "0.05", "-q"],
            cwd=ROOT,
        )
        outs[name] = [tuple(srgb8(x) for x in c) for c in glb_colours(out)]
    a, b = outs["via_obj"], outs["via_gltf"]
    if len(a) != len(b):
        return [f"round trip: {len(b)} vertices through glTF, {len(a)} through OBJ"]
    worst = max(max(abs(x - y) for x, y in zip(p, q)) for p, q in zip(a, b))
    print(f"gltf_check: round trip through a pygltflib .gltf: {len(b)} vertices, "
          f"largest colour difference {worst} (of 255)")
    return [] if worst <= 1 else [f"round trip: a colour differs by {worst} of 255"]


def main():
    venv_module.ensure("pygltflib", "gltf-venv", "gltf_check", "glTF check")
    import pygltflib

    failures = []
    with tempfile.TemporaryDirectory() as tmp:
        glb, ply = os.path.join(tmp, "c.glb"), os.path.join(tmp, "c.ply")
        for out in (glb, ply):
            subprocess.check_call(
                ["cargo", "run", "--release", "--quiet", "--", "bake",
                 os.path.join(ROOT, "meshes", "cornell_box.obj"), "-o", out,
                 "--max-edge", "110", "--refine", "0", "-q"],
                cwd=ROOT,
            )
        gltf = pygltflib.GLTF2().load(glb)
        blob = gltf.binary_blob()
        prim = gltf.meshes[0].primitives[0]
        attrs = prim.attributes
        radiance_index = getattr(attrs, "_RADIANCE", None)
        if radiance_index is None:
            failures.append("no _RADIANCE attribute")
        positions = accessor_floats(gltf, blob, attrs.POSITION)
        colours = accessor_floats(gltf, blob, attrs.COLOR_0)
        radiance = accessor_floats(gltf, blob, radiance_index) if radiance_index is not None else []
        vertices = read_ply(ply)
        if len(vertices) != len(positions):
            failures.append(f"{len(positions)} glTF vertices, {len(vertices)} PLY vertices")
        for k, (p, c, l) in enumerate(vertices[: len(positions)]):
            if positions[k] != p:
                failures.append(f"vertex {k}: position {positions[k]} != PLY {p}")
            if radiance and radiance[k] != l:
                failures.append(f"vertex {k}: _RADIANCE {radiance[k]} != PLY {l}")
            bytes_ = tuple(srgb8(x) for x in colours[k])
            if bytes_ != c:
                failures.append(f"vertex {k}: sRGB(COLOR_0) {bytes_} != PLY colour {c}")
            if len(failures) > 10:
                break
        print(f"gltf_check: {len(positions)} vertices, {prim.indices is not None and gltf.accessors[prim.indices].count // 3} triangles read by pygltflib")
        failures += round_trip(tmp)
    if failures:
        for f in failures:
            print("gltf_check: FAIL:", f)
        return 1
    print("gltf_check: glTF positions, COLOR_0 and _RADIANCE agree with the PLY; the round trip "
          "through glTF gives the OBJ's colours")
    return 0


if __name__ == "__main__":
    sys.exit(main())
