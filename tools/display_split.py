#!/usr/bin/env python3
"""Splits a bake's displayed error at the point-wise probes into what the display's mesh
leaves and what its vertex values add.

For each probe it finds the baked triangle the probe lies on, gathers the light afresh at
that triangle's three vertices with many rays (the `gather_at_probes` example, which gathers
from a default bake's solution), and interpolates those values to the probe linearly, as the
display does. Against the probes' references it prints three rows:

- "gathered at the probes": the solution and the gather alone, no display;
- "exact vertices, interpolated": the display's mesh with vertex values as good as the gather
  can make them (what more rays or better records at the same vertices could reach);
- "displayed": the baked file itself (`score`).

Where the middle row is close to the last, the display's error is its resolution (where its
vertices are), not its vertex values.

    python3 tools/display_split.py SCENE PROBES.csv BAKED.ply [RAYS] [-- ENV=VALUE …]

RAYS defaults to 4096; the gather's settings (`UP`, `SKY`, `SUN`, `MAX_EDGE`, `METHOD`) are
read from the environment, as `gather_at_probes` reads them. Needs numpy; builds the example
with cargo. Probes darker than a tenth of the probes' mean are not scored, as in `score`.
"""

import csv
import math
import os
import subprocess
import sys
import tempfile

import numpy as np


def read_ply(path):
    """Vertices (n × 3), their luminance, and the faces (m × 3) of a baked binary PLY."""
    with open(path, "rb") as f:
        header = b""
        while not header.endswith(b"end_header\n"):
            line = f.readline()
            if not line:
                sys.exit(f"{path}: no end_header: not a PLY file")
            header += line
        if b"binary_little_endian" not in header:
            sys.exit(f"{path}: only binary little-endian PLY is read (bake without --ascii)")
        nv = int(header.split(b"element vertex ")[1].split()[0])
        nf = int(header.split(b"element face ")[1].split()[0])
        # Positions are doubles where single precision would round them (far from the origin).
        position = "<f8" if b"property double x" in header else "<f4"
        vertex = np.dtype([("p", position, 3), ("c", "u1", 3), ("l", "<f4", 3)])
        face = np.dtype([("n", "u1"), ("i", "<i4", 3), ("l", "<f4", 3)])
        v = np.frombuffer(f.read(nv * vertex.itemsize), dtype=vertex)
        faces = np.frombuffer(f.read(nf * face.itemsize), dtype=face)
    if nf and (faces["n"] != 3).any():
        sys.exit(f"{path}: faces that are not triangles")
    lum = v["l"] @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    return v["p"].astype(float), lum.astype(float), faces["i"].astype(np.int64)


def locate(points, normals, p, faces, cell=0.5):
    """For each probe, (face, barycentrics) of the baked triangle it lies on (within 1e-4 of
    its plane, normals within 8°), or None."""
    a, b, c = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]
    n = np.cross(b - a, c - a)
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
    lo = points.min(axis=0)
    grid = {}
    for k, centre in enumerate((a + b + c) / 3.0):
        grid.setdefault(tuple(((centre - lo) // cell).astype(int)), []).append(k)
    found = []
    for x, nx in zip(p, normals):
        key = ((x - lo) // cell).astype(int)
        best = None
        for d in np.ndindex(3, 3, 3):
            for k in grid.get(tuple(key + np.array(d) - 1), []):
                if n[k] @ nx < 0.99 or abs((x - a[k]) @ n[k]) > 1e-4:
                    continue
                e0, e1, e2 = b[k] - a[k], c[k] - a[k], x - a[k]
                d00, d01, d11 = e0 @ e0, e0 @ e1, e1 @ e1
                d20, d21 = e2 @ e0, e2 @ e1
                den = d00 * d11 - d01 * d01
                if den <= 0.0:
                    continue
                v = (d11 * d20 - d01 * d21) / den
                w = (d00 * d21 - d01 * d20) / den
                if min(1.0 - v - w, v, w) > -1e-7:
                    best = (k, (1.0 - v - w, v, w))
        found.append(best)
    return found


def stats(errors):
    e = np.array(errors)
    return (
        f"{len(e)} | {100 * math.sqrt((e ** 2).mean()):.2f} % | "
        f"{100 * np.median(abs(e)):.2f} % | {100 * np.percentile(abs(e), 90):.2f} % | "
        f"{100 * e.mean():+.2f} % |"
    )


def main():
    args = sys.argv[1:]
    if len(args) < 3:
        sys.exit(__doc__)
    scene, probes_path, baked = args[:3]
    rays = args[3] if len(args) > 3 else "4096"
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    with open(probes_path, newline="") as f:
        probes = list(csv.DictReader(f))
    if not probes:
        sys.exit(f"{probes_path}: no probes")
    p = np.array([[float(r[k]) for k in ("x", "y", "z")] for r in probes])
    nrm = np.array([[float(r[k]) for k in ("nx", "ny", "nz")] for r in probes])
    ref = np.array([0.2126 * float(r["r"]) + 0.7152 * float(r["g"]) + 0.0722 * float(r["b"])
                    for r in probes])
    points, lum, faces = read_ply(baked)
    found = locate(points, nrm, p, faces)
    # The vertices of each probe's triangle, moved a thousandth of the way toward the probe so
    # that each lies inside the scene's triangle the probe is on (gathered on that triangle).
    rows = []
    for r, x, hit in zip(probes, p, found):
        if hit is None:
            continue
        for i in faces[hit[0]]:
            q = points[i] + 1e-3 * (x - points[i])
            rows.append(dict(r, x=repr(float(q[0])), y=repr(float(q[1])), z=repr(float(q[2]))))
    with tempfile.TemporaryDirectory() as tmp:
        at_vertices = os.path.join(tmp, "vertices.csv")
        with open(at_vertices, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(probes[0].keys()))
            w.writeheader()
            w.writerows(rows)
        gather = ["cargo", "run", "--release", "-q", "-p", "radiosity-tools", "--example",
                  "gather_at_probes", "--"]
        dumps = []
        for name, where in (("probes", probes_path), ("vertices", at_vertices)):
            dump = os.path.join(tmp, name + ".dump.csv")
            env = dict(os.environ, GATHER_DUMP=dump)
            subprocess.run(gather + [os.path.abspath(where), os.path.abspath(scene), rays],
                           cwd=root, env=env, check=True, stdout=subprocess.DEVNULL)
            with open(dump, newline="") as f:
                dumps.append([float(r["gathered"]) for r in csv.DictReader(f)])
    at_probes, at_vertices = dumps
    mean = ref.mean()
    rows = {"gathered at the probes": [], "exact vertices, interpolated": [], "displayed": []}
    k = 0
    for j, hit in enumerate(found):
        if hit is None:
            continue
        face, bary = hit
        gathered = at_vertices[k:k + 3]
        k += 3
        if ref[j] <= 0.1 * mean or any(math.isnan(g) for g in gathered):
            continue
        rows["gathered at the probes"].append(at_probes[j] / ref[j] - 1.0)
        interpolated = sum(b * g for b, g in zip(bary, gathered))
        rows["exact vertices, interpolated"].append(interpolated / ref[j] - 1.0)
        shown = sum(b * lum[i] for b, i in zip(bary, faces[face]))
        rows["displayed"].append(shown / ref[j] - 1.0)
    missing = sum(h is None for h in found)
    print(f"{len(probes)} probes, {missing} not on a baked triangle; {rays} rays a point")
    print("| | scored | RMS | median | 90th pct | bias |")
    print("|---|---|---|---|---|---|")
    for name, errors in rows.items():
        print(f"| {name} | {stats(errors)}")


if __name__ == "__main__":
    main()
