#!/usr/bin/env python3
"""What a bake of an integrating sphere displays, against the closed form.

A sphere seen from inside, uniform reflectance rho, an emitting cap (the materials whose `Ke`
is not zero, Le = the first channel): every wall point's radiance is rho/(1-rho)*mean(Le) and
every cap point's Le plus that (mean(Le) over the sphere's area). Measured on the baked PLY
(`radiosity bake SPHERE.obj -o out.ply`, binary, as the bake writes it; a grey sphere, whose
luminance is its radiance), leaving out the
points within 5 degrees of the cap's rim, where the light jumps:

- at the vertices: the walls' (and those on the sphere, the input's corners), the cap's;
- at random points, uniform by area over the display's faces (`--points N`, default 20,000,
  seed 1), the vertex colours interpolated as a viewer sees them: the walls', the cap's.

Errors are relative, in per cent of the closed form's radiance (the cap's of its L).

    python3 tools/sphere_display.py SPHERE.obj BAKED.ply [--points N]

`--uv NU NV RADIUS RHO CAP_DEGREES OUT.obj` writes a UV sphere instead (NU segments around,
NV rings; the faces whose centroid is within CAP_DEGREES of +z emit Le = 1), seen from
inside, to bake and check. Needs numpy.
"""

import math
import sys

import numpy as np

from display_split import read_ply  # the bake's binary PLY: positions, luminance, faces


def read_obj(path):
    """Positions, triangles and each triangle's Le from an OBJ and its MTL (first channel)."""
    positions, triangles, emission, material, le, mtl = [], [], [], None, {}, None
    with open(path) as f:
        for line in f:
            s = line.split()
            if not s:
                continue
            if s[0] == "mtllib":
                mtl = s[1]
            elif s[0] == "v":
                positions.append([float(x) for x in s[1:4]])
            elif s[0] == "usemtl":
                material = s[1]
            elif s[0] == "f":
                idx = [int(x.split("/")[0]) - 1 for x in s[1:]]
                for k in range(1, len(idx) - 1):
                    triangles.append([idx[0], idx[k], idx[k + 1]])
                    emission.append(material)
    if mtl:
        name = None
        with open(path.rsplit("/", 1)[0] + "/" + mtl if "/" in path else mtl) as f:
            for line in f:
                s = line.split()
                if s and s[0] == "newmtl":
                    name = s[1]
                elif s and s[0] == "Ke" and name:
                    le[name] = float(s[1])
    e = np.array([le.get(m, 0.0) for m in emission])
    return np.array(positions), np.array(triangles), e


def uv_sphere(nu, nv, radius, rho, cap, out):
    v = [(0.0, 0.0, radius)]
    for j in range(1, nv):
        th = math.pi * j / nv
        for i in range(nu):
            ph = 2 * math.pi * i / nu
            v.append((radius * math.sin(th) * math.cos(ph),
                      radius * math.sin(th) * math.sin(ph), radius * math.cos(th)))
    v.append((0.0, 0.0, -radius))
    south = len(v) - 1

    def at(j, i):
        return 1 + (j - 1) * nu + i % nu

    faces = [(0, at(1, i), at(1, i + 1)) for i in range(nu)]
    for j in range(1, nv - 1):
        for i in range(nu):
            a, b, c, d = at(j, i), at(j, i + 1), at(j + 1, i), at(j + 1, i + 1)
            faces += [(a, c, d), (a, d, b)]
    faces += [(south, at(nv - 1, i + 1), at(nv - 1, i)) for i in range(nu)]
    p = np.array(v)
    groups = {"wall": [], "cap": []}
    for f in faces:
        a, b, c = p[list(f)]
        centre = (a + b + c) / 3
        if np.dot(np.cross(b - a, c - a), centre) > 0:  # the front faces the centre
            f = (f[0], f[2], f[1])
        emits = math.degrees(math.acos(centre[2] / np.linalg.norm(centre))) < cap
        groups["cap" if emits else "wall"].append(f)
    base = out.rsplit(".", 1)[0]
    with open(base + ".mtl", "w") as m:
        m.write(f"newmtl wall\nKd {rho} {rho} {rho}\nKe 0 0 0\n")
        m.write(f"newmtl cap\nKd {rho} {rho} {rho}\nKe 1 1 1\n")
    with open(out, "w") as o:
        o.write(f"mtllib {base.rsplit('/', 1)[-1]}.mtl\n")
        for x in v:
            o.write("v %.9f %.9f %.9f\n" % x)
        for name, fs in groups.items():
            o.write(f"usemtl {name}\n")
            for f in fs:
                o.write("f %d %d %d\n" % tuple(k + 1 for k in f))


def rms(e):
    return 100 * math.sqrt(float(np.mean(e * e))) if len(e) else float("nan")


def worst(e):
    return 100 * float(np.abs(e).max()) if len(e) else float("nan")


def main():
    args = sys.argv[1:]
    if args and args[0] == "--uv":
        nu, nv, radius, rho, cap, out = args[1:7]
        uv_sphere(int(nu), int(nv), float(radius), float(rho), float(cap), out)
        return
    if len(args) < 2:
        sys.exit(__doc__)
    points = int(args[args.index("--points") + 1]) if "--points" in args else 20000
    v, t, le = read_obj(args[0])
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    emits = le > 0
    if not emits.any():
        sys.exit(f"{args[0]}: no emitting material (Ke) in its MTL")
    radius = float(np.linalg.norm(v, axis=1).mean())
    # Reflectance: the closed form needs it; read it from the MTL's first Kd.
    rho = None
    mtl = args[0].rsplit(".", 1)[0] + ".mtl"
    with open(mtl) as f:
        for line in f:
            s = line.split()
            if s and s[0] == "Kd":
                rho = float(s[1])
                break
    mean_le = float((area * le).sum() / area.sum())
    wall_l = rho / (1 - rho) * mean_le
    cap_l = float(le[emits].max()) + wall_l
    axis = ((area * le)[:, None] * (a + b + c) / 3).sum(0)
    axis /= np.linalg.norm(axis)

    def degrees(x):
        return np.degrees(np.arccos(np.clip((x / np.linalg.norm(x, axis=1)[:, None]) @ axis, -1, 1)))

    rim = degrees(v[np.unique(t[emits])]).max()  # the cap's outermost corner
    inner = degrees(v[np.unique(t[~emits])]).min()  # the walls' innermost corner
    p, r, faces = read_ply(args[1])
    ang = degrees(p)
    wall, cap = ang > rim + 5, ang < inner - 5
    on = np.abs(np.linalg.norm(p, axis=1) - radius) < 1e-5 * radius
    ew, ec = (r[wall] - wall_l) / wall_l, (r[cap] - cap_l) / cap_l
    print(f"{args[1]}: rho {rho}, mean Le {mean_le:.5f}, walls' L {wall_l:.5f}, cap's {cap_l:.5f}")
    print(f"vertices: walls {wall.sum()} {rms(ew):.2f} % RMS (worst {worst(ew):.2f} %), "
          f"of them on the sphere {(wall & on).sum()} {rms((r[wall & on] - wall_l) / wall_l):.2f} %; "
          f"cap {cap.sum()} {rms(ec):.2f} % (worst {worst(ec):.2f} %)")
    fa, fb, fc = p[faces[:, 0]], p[faces[:, 1]], p[faces[:, 2]]
    fa_area = 0.5 * np.linalg.norm(np.cross(fb - fa, fc - fa), axis=1)
    rng = np.random.default_rng(1)
    k = rng.choice(len(faces), points, p=fa_area / fa_area.sum())
    u, w = rng.random(points), rng.random(points)
    flip = u + w > 1
    u[flip], w[flip] = 1 - u[flip], 1 - w[flip]
    x = fa[k] + u[:, None] * (fb[k] - fa[k]) + w[:, None] * (fc[k] - fa[k])
    shown = (1 - u - w) * r[faces[k, 0]] + u * r[faces[k, 1]] + w * r[faces[k, 2]]
    ang = degrees(x)
    wall, cap = ang > rim + 5, ang < inner - 5
    ew, ec = (shown[wall] - wall_l) / wall_l, (shown[cap] - cap_l) / cap_l
    print(f"random points: walls {wall.sum()} {rms(ew):.2f} % RMS (worst {worst(ew):.2f} %); "
          f"cap {cap.sum()} {rms(ec):.2f} % (worst {worst(ec):.2f} %)")


if __name__ == "__main__":
    main()
