#!/usr/bin/env python3
"""Check our glTF output with an independent reader (pygltflib, from PyPI).

Bakes the shipped Cornell box twice with the same settings, to .glb and to binary .ply, reads
the .glb with pygltflib and checks, vertex by vertex:
- the file is a valid GLB that pygltflib parses, with POSITION, COLOR_0 and _RADIANCE;
- _RADIANCE equals the PLY's float radiance (the same bake: the same numbers, as f32);
- COLOR_0 is linear: encoded with the sRGB curve and rounded to 8 bits it gives the PLY's
  colour bytes (which MeshLab reads; tools/meshlab_check.py checks those);
- positions equal the PLY's (the Cornell box is y-up: no turn).

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

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VENV = os.path.join(ROOT, "target", "gltf-venv")


def ensure_pygltflib():
    """Re-run this script inside a venv that has pygltflib."""
    try:
        import pygltflib  # noqa: F401
        return
    except ImportError:
        pass
    py = os.path.join(VENV, "bin", "python")
    try:
        if not os.path.exists(py):
            subprocess.check_call([sys.executable, "-m", "venv", VENV])
        subprocess.check_call([py, "-c", "import pygltflib"], stderr=subprocess.DEVNULL)
    except subprocess.CalledProcessError:
        try:
            subprocess.check_call([py, "-m", "pip", "install", "-q", "pygltflib"])
        except (subprocess.CalledProcessError, OSError) as e:
            print(f"gltf_check: cannot install pygltflib ({e}); glTF check not run")
            sys.exit(3)
    os.execv(py, [py] + sys.argv)


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
    out = []
    for k in range(nv):
        x, y, z, r, g, b, lr, lg, lb = struct.unpack_from("<fffBBBfff", data, end + 27 * k)
        out.append(((x, y, z), (r, g, b), (lr, lg, lb)))
    return out


def accessor_floats(gltf, blob, index):
    """The VEC3 float values of accessor `index`."""
    acc = gltf.accessors[index]
    view = gltf.bufferViews[acc.bufferView]
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    return [struct.unpack_from("<fff", blob, start + 12 * k) for k in range(acc.count)]


def main():
    ensure_pygltflib()
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
    if failures:
        for f in failures:
            print("gltf_check: FAIL:", f)
        return 1
    print("gltf_check: glTF positions, COLOR_0 and _RADIANCE agree with the PLY")
    return 0


if __name__ == "__main__":
    sys.exit(main())
