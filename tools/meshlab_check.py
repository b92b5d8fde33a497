#!/usr/bin/env python3
"""Check that MeshLab itself reads our baked files as we meant them.

Loads a baked PLY and OBJ with pymeshlab (MeshLab's own I/O, headless) and compares vertex
count, face count and every vertex colour with what the files themselves say, parsed here
independently: the PLY's `uchar red green blue` bytes, and the OBJ's `v x y z r g b` floats
converted to bytes the way MeshLab does (truncation, which is why `radiosity` writes
(k + 0.5)/255).

Usage:
    python3 tools/meshlab_check.py            # bakes the Cornell box coarsely, then checks
    python3 tools/meshlab_check.py A.ply B.obj
It creates a virtual environment in target/meshlab-venv with pymeshlab (PyPI) on first use.
Exit status 0 when every check passes, 1 otherwise, 3 when pymeshlab cannot be installed
(no network to PyPI: the check did not run).
"""
import os
import struct
import subprocess
import sys
import tempfile

import venv_module

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def read_ply(path):
    """(vertex count, face count, [(r, g, b)]) from our own binary or ASCII PLY."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    binary = "format binary_little_endian 1.0" in header
    nv = nf = 0
    vprops = []
    current = None
    for line in header:
        w = line.split()
        if w[:1] == ["element"]:
            current = w[1]
            if current == "vertex":
                nv = int(w[2])
            elif current == "face":
                nf = int(w[2])
        elif w[:1] == ["property"] and current == "vertex":
            vprops.append((w[1], w[2]))
    colours = []
    if binary:
        fmt = "<" + "".join({"float": "f", "double": "d", "uchar": "B"}[t] for t, _ in vprops)
        size = struct.calcsize(fmt)
        names = [n for _, n in vprops]
        ir, ig, ib = names.index("red"), names.index("green"), names.index("blue")
        for k in range(nv):
            v = struct.unpack_from(fmt, data, end + k * size)
            colours.append((v[ir], v[ig], v[ib]))
    else:
        lines = data[end:].decode("ascii").splitlines()
        names = [n for _, n in vprops]
        ir, ig, ib = names.index("red"), names.index("green"), names.index("blue")
        for k in range(nv):
            v = lines[k].split()
            colours.append((int(v[ir]), int(v[ig]), int(v[ib])))
    return nv, nf, colours


def read_obj(path):
    nv = nf = 0
    colours = []
    with open(path) as f:
        for line in f:
            w = line.split()
            if w[:1] == ["v"]:
                nv += 1
                colours.append(tuple(int(float(c) * 255) for c in w[4:7]))
            elif w[:1] == ["f"]:
                nf += 1
    return nv, nf, colours


def check(path, expected):
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(path)
    m = ms.current_mesh()
    nv, nf, colours = expected
    problems = []
    if m.vertex_number() != nv:
        problems.append(f"{m.vertex_number()} vertices, file says {nv}")
    if m.face_number() != nf:
        problems.append(f"{m.face_number()} faces, file says {nf}")
    if not m.has_vertex_color():
        problems.append("MeshLab found no vertex colours")
    else:
        got = m.vertex_color_matrix()  # rows of RGBA floats in [0, 1] = byte / 255
        bad = 0
        for k, (row, want) in enumerate(zip(got, colours)):
            have = tuple(int(round(c * 255)) for c in row[:3])
            if have != want:
                bad += 1
                if bad <= 3:
                    problems.append(f"vertex {k}: MeshLab colour {have}, file {want}")
        if bad:
            problems.append(f"{bad} of {nv} vertex colours differ")
    status = "ok" if not problems else "FAIL"
    print(f"{status}: {path}: {m.vertex_number()} vertices, {m.face_number()} faces, colours checked")
    for p in problems:
        print("   ", p)
    return not problems


def main():
    venv_module.ensure("pymeshlab", "meshlab-venv", "meshlab_check", "MeshLab check")
    files = sys.argv[1:]
    if not files:
        tmp = tempfile.mkdtemp()
        exe = [os.path.join(ROOT, "target", "release", "radiosity")]
        if not os.path.exists(exe[0]):
            exe = ["cargo", "run", "--release", "--quiet", "--"]
        for ext, extra in (("ply", []), ("ascii.ply", ["--ascii"]), ("obj", [])):
            out = os.path.join(tmp, f"cornell.{ext}")
            subprocess.check_call(exe + ["bake", os.path.join(ROOT, "meshes", "cornell_box.obj"),
                                         "-o", out, "--max-edge", "110", "-q"] + extra, cwd=ROOT)
            files.append(out)
    ok = True
    for path in files:
        expected = read_obj(path) if path.lower().endswith(".obj") else read_ply(path)
        ok &= check(path, expected)
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
