#!/usr/bin/env python3
"""Embree's side of the ray-throughput comparison (`cargo bench -p radiosity-tools --bench scale -- rays`).

Reads the triangles and segments the harness wrote (rays.bin: u64 triangle count, u64 segment
count, then f32 triangles (9 each) and f32 segments (p, q: 6 each), little-endian), traces the
same open segments as occlusion queries with Embree through `embreex` (PyPI), on one thread,
and prints "embree <rays per second> <blocked>". embreex is installed on first use into a
virtual environment under target/embree-venv (the harness's own machine needs only pip);
exit status 3 if that is impossible (no network), with the reason on stderr.

The segments are shortened by 1e-4 of their length at both ends, as radiosity's own open
segments are (its margin is 1e-5 relative or 1e-5 of the scene, whichever is larger), so a
segment does not count the surfaces it starts and ends on.
"""
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VENV = os.path.join(ROOT, "target", "embree-venv")


def ensure_venv():
    python = os.path.join(VENV, "bin", "python")
    if os.environ.get("EMBREE_VENV_ACTIVE") == "1":
        return
    if not os.path.exists(python):
        try:
            subprocess.run([sys.executable, "-m", "venv", VENV], check=True)
            subprocess.run([python, "-m", "pip", "install", "-q", "embreex", "numpy"], check=True)
        except (subprocess.CalledProcessError, OSError) as e:
            print(f"cannot install embreex: {e}", file=sys.stderr)
            sys.exit(3)
    env = dict(os.environ, EMBREE_VENV_ACTIVE="1")
    os.execve(python, [python] + sys.argv, env)


def main():
    ensure_venv()
    import numpy as np
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    data = open(sys.argv[1], "rb").read()
    n_tris, n_segs = np.frombuffer(data[:16], dtype="<u8")
    floats = np.frombuffer(data[16:], dtype="<f4")
    tris = floats[: n_tris * 9].reshape(n_tris, 3, 3).astype(np.float32)
    segs = floats[n_tris * 9 :].reshape(n_segs, 6).astype(np.float64)
    p, q = segs[:, :3], segs[:, 3:]
    d = q - p
    margin = 1e-4
    origins = (p + margin * d).astype(np.float32)
    directions = d.astype(np.float32)
    tfar = np.full(n_segs, 1.0 - 2 * margin, dtype=np.float32)
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, tris)
    scene.run(origins[:1000], directions[:1000], dists=tfar[:1000], query="OCCLUDED")  # warm-up
    start = time.perf_counter()
    hits = scene.run(origins, directions, dists=tfar, query="OCCLUDED")
    seconds = time.perf_counter() - start
    blocked = int(np.count_nonzero(hits != -1))
    print(f"embree {n_segs / seconds:.1f} {blocked}")


if __name__ == "__main__":
    main()
