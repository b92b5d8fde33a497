#!/usr/bin/env python3
"""Convert a Quake level's source (.map, as TrenchBroom and the LibreQuake project keep them)
into a scene radiosity reads: OBJ + MTL (z up) and a lights file (--lights) with the level's
light entities, its sun and its sky.

    python3 tools/quake_map.py lq_e1m2.map -o e1m2.obj [--textures DIR] [--scale 0.03125]
    radiosity bake e1m2.obj -o e1m2.ply --up z --lights e1m2.lights.json

What it does (no compiler, no BSP: what an editor's OBJ export gives, so a test of messy input):
- Every brush (an intersection of half-spaces, three points per plane, Quake's winding) becomes
  its convex faces, each a polygon clipped from its plane by all the others, wound
  counter-clockwise seen from outside the brush (the front radiosity lights). Faces of
  neighbouring brushes that touch or hide inside each other stay: qbsp would remove them.
- Tool textures (clip, skip, trigger, hint, origin, nodraw, *skip) and trigger entities are left
  out, as are the sky's brushes: their openings let the sun and the sky in, given in the lights
  file from worldspawn's _sunlight, _sun_mangle and _sunlight2 (sky) keys.
- A texture's material is `Kd 1` with `map_Kd` its PNG (found by name under --textures, `*`
  written `star_`, as LibreQuake's texture folders do), and each face gets texture coordinates
  (`vt`) from its plane's texture axes, offsets and scales (Valve 220 or the standard format),
  so radiosity varies ρ with the texture under each patch; without the PNG, Kd 0.5 grey.
- Each `light*` entity becomes a point light at its origin (a spot where it has a target or
  mangle and a _cone), intensity I = light/300 × --intensity W/sr (Quake's default light is
  300), coloured by _color. Quake's own falloff is linear; radiosity's is physical, 1/r². A
  light with `_surface` makes its texture an emitter instead: Ke = light/300 × --surface
  W/(sr m^2) × _color.
- Lengths are multiplied by --scale (default 1/32: 32 Quake units to the metre), so I/r² is in
  W/m² at the metre scale.
"""

import argparse
import json
import math
import os
import re
import sys

TOOL_TEXTURES = {"clip", "skip", "trigger", "hint", "hintskip", "origin", "nodraw", "null",
                 "skip_dev", "clip_dev", "trigger_dev"}


def is_tool(texture):
    t = texture.lower()
    return t in TOOL_TEXTURES or t.endswith("skip") or t.startswith("clip") or t.startswith("hint")


def is_sky(texture):
    return texture.lower().startswith("sky")


FACE = re.compile(
    r"\(\s*([-\d.eE+]+)\s+([-\d.eE+]+)\s+([-\d.eE+]+)\s*\)\s*"
    r"\(\s*([-\d.eE+]+)\s+([-\d.eE+]+)\s+([-\d.eE+]+)\s*\)\s*"
    r"\(\s*([-\d.eE+]+)\s+([-\d.eE+]+)\s+([-\d.eE+]+)\s*\)\s*(\S+)\s*(.*)$")
NUMBER = r"([-\d.eE+]+)"
VALVE = re.compile(r"\[\s*" + r"\s+".join([NUMBER] * 4) + r"\s*\]\s*\[\s*" + r"\s+".join([NUMBER] * 4)
                   + r"\s*\]\s*" + r"\s+".join([NUMBER] * 3))
STANDARD = re.compile(r"\s+".join([NUMBER] * 5))
# Quake's TextureAxisFromPlane: for the axis nearest the face's normal, the texture's s and t
# axes (qbsp, textures.c).
BASE_AXES = [((0, 0, 1), (1, 0, 0), (0, -1, 0)), ((0, 0, -1), (1, 0, 0), (0, -1, 0)),
             ((1, 0, 0), (0, 1, 0), (0, 0, -1)), ((-1, 0, 0), (0, 1, 0), (0, 0, -1)),
             ((0, 1, 0), (1, 0, 0), (0, 0, -1)), ((0, -1, 0), (1, 0, 0), (0, 0, -1))]
KEY = re.compile(r'^\s*"([^"]*)"\s+"([^"]*)"\s*$')


def parse(path):
    """Entities: [(keys dict, [brush: [(plane points (3 tuples), texture)]])]."""
    entities, keys, brushes, brush, depth = [], None, None, None, 0
    with open(path, encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, 1):
            s = line.strip()
            if not s or s.startswith("//"):
                continue
            if s == "{":
                depth += 1
                if depth == 1:
                    keys, brushes = {}, []
                elif depth == 2:
                    brush = []
                else:
                    sys.exit(f"{path}:{number}: unexpected '{{' (patches and deeper nesting are not Quake 1)")
            elif s == "}":
                if depth == 2:
                    brushes.append(brush)
                elif depth == 1:
                    entities.append((keys, brushes))
                depth -= 1
            elif depth == 1:
                m = KEY.match(s)
                if not m:
                    sys.exit(f"{path}:{number}: expected \"key\" \"value\", found {s[:60]!r}")
                keys[m.group(1)] = m.group(2)
            elif depth == 2:
                m = FACE.match(s)
                if not m:
                    sys.exit(f"{path}:{number}: expected a brush plane ( x y z ) ( x y z ) ( x y z ) TEXTURE")
                v = [float(x) for x in m.groups()[:9]]
                brush.append(((v[0:3], v[3:6], v[6:9]), m.group(10), texture_axes(m.group(11))))
    if depth != 0:
        sys.exit(f"{path}: unbalanced braces at the end of the file")
    return entities


def texture_axes(rest):
    """The texture projection after the name: ('valve', U, uoff, V, voff, su, sv) or
    ('standard', uoff, voff, rotation, su, sv); None if neither parses."""
    m = VALVE.match(rest)
    if m:
        g = [float(x) for x in m.groups()]
        return ("valve", g[0:3], g[3], g[4:7], g[7], g[9] or 1.0, g[10] or 1.0)
    m = STANDARD.match(rest)
    if m:
        g = [float(x) for x in m.groups()]
        return ("standard", g[0], g[1], g[2], g[3] or 1.0, g[4] or 1.0)
    return None


def texel(p, normal, axes):
    """Texture coordinates of point p in texels (s right, t down the image), as qbsp maps."""
    if axes is None:
        return None
    if axes[0] == "valve":
        _, u, uoff, v, voff, su, sv = axes
        return (dot(p, u) / su + uoff, dot(p, v) / sv + voff)
    _, uoff, voff, rotation, su, sv = axes
    best = max(range(6), key=lambda i: dot(normal, BASE_AXES[i][0]))
    s_axis, t_axis = BASE_AXES[best][1], BASE_AXES[best][2]
    a = math.radians(rotation)
    c, s_ = math.cos(a), math.sin(a)
    # Rotate within the axis plane (qbsp rotates the two non-zero components).
    def rot(v):
        out = list(v)
        sv_, tv_ = [k for k in range(3) if s_axis[k] != 0][0], [k for k in range(3) if t_axis[k] != 0][0]
        out[sv_], out[tv_] = c * v[sv_] - s_ * v[tv_], s_ * v[sv_] + c * v[tv_]
        return out
    s_rot, t_rot = rot(s_axis), rot(t_axis)
    return (dot(p, s_rot) / su + uoff, dot(p, t_rot) / sv + voff)


def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    if head[:8] != b"\x89PNG\r\n\x1a\n":
        return None
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def normalise(a):
    n = math.sqrt(dot(a, a))
    return None if n == 0 else (a[0] / n, a[1] / n, a[2] / n)


def plane(points):
    """Quake's plane of three points (qbsp: normal = (p0 − p1) × (p2 − p1)), pointing out of
    the brush: the brush is where n·x ≤ d."""
    p0, p1, p2 = points
    n = normalise(cross(sub(p0, p1), sub(p2, p1)))
    return None if n is None else (n, dot(n, p1))


def brush_faces(brush, eps=1e-3):
    planes = [(plane(p), t, axes) for p, t, axes in brush]
    planes = [(p, t, axes) for p, t, axes in planes if p is not None]
    faces = []
    for i, ((n, d), texture, axes) in enumerate(planes):
        # A large square in the plane, counter-clockwise about n.
        a = (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0)
        u = normalise(cross(a, n))
        v = cross(n, u)
        c = (n[0] * d, n[1] * d, n[2] * d)
        r = 1e5
        poly = [tuple(c[k] + r * (su * u[k] + sv * v[k]) for k in range(3))
                for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        for j, ((m, e), _, _) in enumerate(planes):
            if j == i or not poly:
                continue
            out = []
            for k, p in enumerate(poly):
                q = poly[(k + 1) % len(poly)]
                dp, dq = dot(m, p) - e, dot(m, q) - e
                if dp <= eps:
                    out.append(p)
                if (dp < -eps and dq > eps) or (dp > eps and dq < -eps):
                    t = dp / (dp - dq)
                    out.append(tuple(p[k2] + t * (q[k2] - p[k2]) for k2 in range(3)))
            poly = out if len(out) >= 3 else []
        if poly:
            faces.append((poly, texture, [texel(p, n, axes) for p in poly]))
    return faces


def find_textures(root):
    found = {}
    if root:
        for dirpath, _, files in os.walk(root):
            for f in files:
                if f.lower().endswith(".png"):
                    found.setdefault(f[:-4].lower(), os.path.join(dirpath, f))
    return found


def material_name(texture):
    return texture.replace("*", "star_").replace("+", "plus_")


def colour(keys, name="_color"):
    c = [float(x) for x in keys.get(name, "1 1 1").split()[:3]] or [1, 1, 1]
    if len(c) == 1:
        c = c * 3
    top = max(c)
    return [x / top for x in c] if top > 1 else c


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("map")
    ap.add_argument("-o", "--output", required=True, help="the OBJ to write (.mtl and .lights.json beside it)")
    ap.add_argument("--textures", help="folder searched for TEXTURE.png")
    ap.add_argument("--scale", type=float, default=1 / 32, help="metres per Quake unit")
    ap.add_argument("--intensity", type=float, default=10.0, help="W/sr of a light of 300")
    ap.add_argument("--surface", type=float, default=10.0, help="Le of a surface light of 300, W/(sr m^2)")
    ap.add_argument("--sun", type=float, default=10.0, help="W/m^2 of _sunlight 100")
    ap.add_argument("--sky", type=float, default=1.0, help="W/(sr m^2) of _sunlight2 100")
    args = ap.parse_args()

    entities = parse(args.map)
    textures = find_textures(args.textures)
    world = entities[0][0] if entities else {}
    surface_lights = {}
    lights = []
    skipped = {"tool": 0, "sky": 0, "trigger": 0, "omitted layer": 0}
    s = args.scale
    for keys, _ in entities:
        cls = keys.get("classname", "")
        if not cls.startswith("light") or "origin" not in keys:
            continue
        value = float(keys.get("light", keys.get("_light", "300")).split()[0])
        if value <= 0:
            continue
        rgb = colour(keys)
        if "_surface" in keys:
            surface_lights[keys["_surface"].lower()] = [value / 300 * args.surface * c for c in rgb]
            continue
        o = [float(x) * s for x in keys["origin"].split()]
        lights.append({"name": keys.get("targetname", cls), "position": o,
                       "intensity": [value / 300 * args.intensity * c for c in rgb]})

    faces = []
    for keys, brushes in entities:
        cls = keys.get("classname", "")
        if cls.startswith("trigger"):
            skipped["trigger"] += len(brushes)
            continue
        if keys.get("_tb_layer_omit_from_export") == "1":
            skipped["omitted layer"] += len(brushes)
            continue
        for brush in brushes:
            if any(is_sky(t) for _, t, _ in brush):
                skipped["sky"] += 1
                continue
            for poly, texture, uv in brush_faces(brush):
                if is_tool(texture):
                    skipped["tool"] += 1
                    continue
                faces.append((poly, texture, uv))

    base = os.path.splitext(args.output)[0]
    mtl_path, lights_path = base + ".mtl", base + ".lights.json"
    index, vertices, lines, uvs = {}, [], [], []
    by_texture = {}
    for poly, texture, uv in faces:
        by_texture.setdefault(texture, []).append((poly, uv))
    for texture in sorted(by_texture):
        lines.append(f"usemtl {material_name(texture)}")
        png = textures.get(material_name(texture).lower())
        size = png_size(png) if png else None
        for poly, uv in by_texture[texture]:
            ids = []
            for p, t in zip(poly, uv):
                key = tuple(round(x * s, 5) for x in p)
                if key not in index:
                    index[key] = len(vertices) + 1
                    vertices.append(key)
                if not ids or ids[-1][0] != index[key]:
                    vt = None
                    if size and t is not None:
                        # Texels to [0, 1] of the image; OBJ's v counts up from the bottom.
                        uvs.append((t[0] / size[0], 1.0 - t[1] / size[1]))
                        vt = len(uvs)
                    ids.append((index[key], vt))
            if len(ids) >= 3 and ids[0][0] == ids[-1][0]:
                ids.pop()
            if len(set(i for i, _ in ids)) >= 3:
                with_vt = all(vt is not None for _, vt in ids)
                lines.append("f " + " ".join(f"{i}/{vt}" if with_vt else str(i) for i, vt in ids))
    with open(args.output, "w") as f:
        f.write(f"# {os.path.basename(args.map)} converted by tools/quake_map.py (z up, metres)\n")
        f.write(f"mtllib {os.path.basename(mtl_path)}\n")
        f.writelines(f"v {x:.5f} {y:.5f} {z:.5f}\n" for x, y, z in vertices)
        f.writelines(f"vt {u:.6f} {v:.6f}\n" for u, v in uvs)
        f.write("\n".join(lines) + "\n")
    missing = []
    with open(mtl_path, "w") as f:
        for texture in sorted(by_texture):
            f.write(f"newmtl {material_name(texture)}\n")
            png = textures.get(material_name(texture).lower())
            if png:
                f.write(f"Kd 1 1 1\nmap_Kd {os.path.abspath(png)}\n")
            else:
                missing.append(texture)
                f.write("Kd 0.5 0.5 0.5\n")
            if texture.lower() in surface_lights:
                f.write("Ke {:.6g} {:.6g} {:.6g}\n".format(*surface_lights[texture.lower()]))
    env = {"lights": lights}
    if "_sunlight" in world and "_sun_mangle" in world:
        yaw, pitch = [float(x) for x in world["_sun_mangle"].split()[:2]]
        # The light travels along (yaw, pitch); the sun is the other way. North is +y with z up
        # (radiosity's convention), east +x; azimuth clockwise from north.
        cy, sy = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
        elevation = -pitch
        azimuth = math.degrees(math.atan2(-cy, -sy)) % 360
        if 0 < elevation <= 90:
            sun_rgb = colour(world, "_sunlight_color")
            env["sun"] = {"azimuth": azimuth, "elevation": elevation,
                          "irradiance": [float(world["_sunlight"]) / 100 * args.sun * c for c in sun_rgb]}
    if "_sunlight2" in world:
        env["sky"] = float(world["_sunlight2"]) / 100 * args.sky
    with open(lights_path, "w") as f:
        json.dump(env, f, indent=1)
    triangles = sum(len(l.split()) - 3 for l in lines if l.startswith("f "))
    print(f"{args.output}: {len(vertices)} vertices, {triangles} triangles in {len(by_texture)} "
          f"materials ({len(missing)} without a PNG); left out: "
          + ", ".join(f"{n} {k}" for k, n in skipped.items()))
    print(f"{lights_path}: {len(lights)} point lights, {len(surface_lights)} surface-light textures"
          + (", a sun" if "sun" in env else "") + (", a sky" if "sky" in env else ""))


if __name__ == "__main__":
    main()
