#!/usr/bin/env python3
"""CI check of tools/quake_map.py end to end: a hand-written Quake map of a closed cubic room
(six wall brushes, 256 units inside, a `light` entity at its centre) converted, then baked by
radiosity with the lights file the converter writes.

Checked:
- the converter's count: 6 brushes × 6 faces = 36 quads, 72 triangles;
- the winding: the room is lit from inside (a wrong winding would face every wall outward and
  the bake would be black);
- the texture: its PNG (64 × 64, every texel sRGB 188: linear 0.5029) is found under
  --textures, every face gets texture coordinates (`vt`), and ρ is the texture's colour;
- the units: at the floor's centre, straight under the light at r = 128 units = 4 m (1/32 m a
  unit), the direct light is ρ I / (π r²) with I = 10 W/sr (a light of 300) and ρ = 0.5029. The bounces add at most ρ/(1 − ρ) of the largest direct light (a closed room:
  the indirect light anywhere is ρ × a mean of radiances ≤ the largest, summed over bounces), so
  ρ I/(π r²) ≤ L ≤ ρ I/(π r²)/(1 − ρ).

Usage: python3 tools/quake_map_check.py [path/to/radiosity]   (exit 0 pass, 1 fail)
"""

import json
import math
import os
import struct
import subprocess
import sys
import tempfile
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))


def brush(x0, y0, z0, x1, y1, z1):
    """An axis-aligned box brush in the standard .map format (three points per plane, Quake's
    winding: the normal (p0 − p1) × (p2 − p1) points out of the brush)."""
    return "\n".join([
        "{",
        f"( {x0} 0 0 ) ( {x0} 1 0 ) ( {x0} 0 1 ) wall 0 0 0 1 1",
        f"( {x1} 0 0 ) ( {x1} 0 1 ) ( {x1} 1 0 ) wall 0 0 0 1 1",
        f"( 0 {y0} 0 ) ( 0 {y0} 1 ) ( 1 {y0} 0 ) wall 0 0 0 1 1",
        f"( 0 {y1} 0 ) ( 1 {y1} 0 ) ( 0 {y1} 1 ) wall 0 0 0 1 1",
        f"( 0 0 {z0} ) ( 1 0 {z0} ) ( 0 1 {z0} ) wall 0 0 0 1 1",
        f"( 0 0 {z1} ) ( 0 1 {z1} ) ( 1 0 {z1} ) wall 0 0 0 1 1",
        "}",
    ])


def room():
    h, t = 128, 16  # half the inside, wall thickness
    o = h + t
    walls = [
        brush(-o, -o, -o, o, o, -h),  # floor
        brush(-o, -o, h, o, o, o),  # ceiling
        brush(-o, -o, -h, -h, o, h),
        brush(h, -o, -h, o, o, h),
        brush(-h, -o, -h, h, -h, h),
        brush(-h, h, -h, h, o, h),
    ]
    return ('{\n"classname" "worldspawn"\n' + "\n".join(walls) + "\n}\n"
            '{\n"classname" "light"\n"origin" "0 0 0"\n"light" "300"\n}\n')


def write_png(path, size, grey):
    """A size × size 8-bit RGB PNG of one grey value (no imaging library needed)."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    rows = b"".join(b"\x00" + bytes([grey]) * 3 * size for _ in range(size))
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", size, size, 8, 2, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def read_ply(path):
    with open(path, "rb") as f:
        header = b""
        while not header.endswith(b"end_header\n"):
            header += f.readline()
        lines = header.decode().splitlines()
        start = next(i for i, l in enumerate(lines) if l.startswith("element vertex"))
        n = int(lines[start].split()[2])
        props = []
        for l in lines[start + 1:]:
            if not l.startswith("property"):
                break
            props.append(l.split()[1:])
        fmt = "<" + "".join({"float": "f", "uchar": "B"}[t] for t, _ in props)
        size = struct.calcsize(fmt)
        names = [name for _, name in props]
        return [dict(zip(names, struct.unpack(fmt, f.read(size)))) for _ in range(n)]


def main():
    exe = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, "..", "target", "release", "radiosity")
    with tempfile.TemporaryDirectory() as d:
        with open(os.path.join(d, "room.map"), "w") as f:
            f.write(room())
        os.mkdir(os.path.join(d, "textures"))
        write_png(os.path.join(d, "textures", "wall.png"), 64, 188)
        obj = os.path.join(d, "room.obj")
        subprocess.run([sys.executable, os.path.join(HERE, "quake_map.py"), os.path.join(d, "room.map"),
                        "-o", obj, "--textures", os.path.join(d, "textures")], check=True)
        text = open(obj).read()
        faces = [l for l in text.splitlines() if l.startswith("f ")]
        lights = os.path.join(d, "room.lights.json")
        info = json.loads(subprocess.run([exe, "info", obj, "--json", "--up", "z", "--lights", lights],
                                         check=True, capture_output=True, text=True).stdout)
        failures = []
        if info["triangles"] != 72:
            failures.append(f"{info['triangles']} triangles, expected 72 (6 brushes x 6 quads)")
        if "\nvt " not in text or not all("/" in l for l in faces):
            failures.append("faces without texture coordinates")
        # sRGB 188 decoded (IEC 61966-2-1): ((188/255 + 0.055)/1.055)^2.4.
        grey = ((188 / 255 + 0.055) / 1.055) ** 2.4
        rho = info["materials"][0]["reflectance"]
        if any(abs(r - grey) > 1e-4 for r in rho):
            failures.append(f"wall reflectance {rho}, expected the texture's {grey:.5f}")
        ply = os.path.join(d, "room.ply")
        subprocess.run([exe, "bake", obj, "-o", ply, "-q", "--up", "z", "--lights", lights], check=True)
        vertices = read_ply(ply)
        # The floor's inside is at z = -128 units = -4 m; its centre is a vertex of the output
        # only by chance, so take the floor vertex nearest the centre, within 0.25 m
        # (the direct light there is within (1 + 0.25²/16)^-1.5 of the centre's: 0.6 % less).
        r = 128 / 32
        floor = [v for v in vertices if abs(v["z"] + r) < 1e-3]
        centre = min(floor, key=lambda v: v["x"] ** 2 + v["y"] ** 2)
        d2 = centre["x"] ** 2 + centre["y"] ** 2
        rho, intensity = grey, 10.0
        dist2 = r * r + d2
        direct = rho * intensity * (r / math.sqrt(dist2)) / (math.pi * dist2)
        upper = rho * intensity / (math.pi * r * r) / (1 - rho)
        got = (centre["radiance_r"] + centre["radiance_g"] + centre["radiance_b"]) / 3
        if d2 > 0.25 ** 2:
            failures.append(f"no floor vertex within 0.25 m of the centre (nearest at {math.sqrt(d2):.3f} m)")
        # 1e-3 relative slack: the PLY's f32 values and the gather's rounding.
        if not direct * (1 - 1e-3) <= got <= upper * (1 + 1e-3):
            failures.append(f"floor centre radiance {got:.6g}, expected in [{direct:.6g}, {upper:.6g}]")
        print(f"quake_map_check: {info['triangles']} triangles; floor centre L = {got:.5g} "
              f"W/(sr m^2), direct alone {direct:.5g}, bound with bounces {upper:.5g}")
        for f in failures:
            print("FAIL:", f)
        return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
