#!/usr/bin/env python3
"""A room lit through a glazed window, for the transparency benchmark (BENCHMARKS.md,
"A room lit through glazed windows").

A y-up room 4 (x) by 3 (y) by 4 (z) m with inward-facing walls (floor rho 0.5, ceiling 0.8,
walls 0.7), a 2 x 1.5 m window in the wall x = 4 holding a pane of `d` D (transmittance
1 - D, Kd KD), and outside it, 2 m away, a 3 x 3 m panel of Le 10 facing the window.

Usage: python3 tools/glazed_room.py OUT.obj [--d D] [--kd KD] [--no-pane]
Writes OUT.obj and OUT.mtl beside it.
"""
import argparse
import os

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("out")
parser.add_argument("--d", type=float, default=0.3, help="the pane's d (covered share)")
parser.add_argument("--kd", type=float, default=0.05, help="the pane's Kd")
parser.add_argument("--no-pane", action="store_true", help="an open window")
args = parser.parse_args()

vertices, faces = [], []


def quad(corners, material):
    base = len(vertices) + 1
    vertices.extend(corners)
    faces.append((material, [base, base + 1, base + 2, base + 3]))


W, H, D = 4.0, 3.0, 4.0
quad([(0, 0, 0), (0, 0, D), (W, 0, D), (W, 0, 0)], "floor")
quad([(0, H, 0), (W, H, 0), (W, H, D), (0, H, D)], "ceiling")
quad([(0, 0, 0), (W, 0, 0), (W, H, 0), (0, H, 0)], "wall")
quad([(0, 0, D), (0, H, D), (W, H, D), (W, 0, D)], "wall")
quad([(0, 0, 0), (0, H, 0), (0, H, D), (0, 0, D)], "wall")


def window_wall(ys, zs, material="wall"):
    (ya, yb), (za, zb) = ys, zs
    quad([(W, ya, za), (W, ya, zb), (W, yb, zb), (W, yb, za)], material)


y0, y1, z0, z1 = 0.75, 2.25, 1.0, 3.0
window_wall((0, y0), (0, D))
window_wall((y1, H), (0, D))
window_wall((y0, y1), (0, z0))
window_wall((y0, y1), (z1, D))
if not args.no_pane:
    window_wall((y0, y1), (z0, z1), "glass")
quad([(6, 0, 0.5), (6, 0, 3.5), (6, 3, 3.5), (6, 3, 0.5)], "panel")

stem = os.path.splitext(args.out)[0]
mtl = os.path.basename(stem) + ".mtl"
with open(stem + ".mtl", "w") as m:
    m.write("newmtl floor\nKd 0.5\nnewmtl ceiling\nKd 0.8\nnewmtl wall\nKd 0.7\n")
    m.write(f"newmtl glass\nKd {args.kd}\nd {args.d}\nnewmtl panel\nKd 0\nKe 10 10 10\n")
with open(args.out, "w") as o:
    o.write(f"mtllib {mtl}\n")
    for v in vertices:
        o.write("v %g %g %g\n" % v)
    current = None
    for material, idx in faces:
        if material != current:
            o.write(f"usemtl {material}\n")
            current = material
        o.write("f " + " ".join(map(str, idx)) + "\n")
