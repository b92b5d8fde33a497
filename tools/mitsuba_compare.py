#!/usr/bin/env python3
"""Compare a bake of a Mitsuba scene file with Mitsuba 3's own rendering of the same file,
point by point (BENCHMARKS.md, "A Mitsuba scene against Mitsuba").

1. Probes: N random points of the scene's sensor's film (uniform over the film, seeded). Each
   is the centre of one pixel of a virtual film of 32768 pixels across with the sensor's
   field of view and placement, so the probe is a single ray: Mitsuba's own camera ray, its
   first hit by Mitsuba's own intersector gives the point and the triangle's front normal.
   Rays that miss, or meet a face from behind, are left out (counted).
2. Reference: Mitsuba's `path` integrator (unbounded depth, Russian roulette: unbiased)
   renders that one pixel with a box filter, `--spp` samples in `--batches` independent
   batches; the batches' spread gives each probe's standard error. The pixel is 1/32768 of
   the field of view wide, so its mean is the radiance at the point to far below the noise.
3. Our display at the same points: `score` (tools/examples/score.rs) looks the bake's
   vertex colours up at each probe, as the point-wise benchmark does everywhere else.
4. Mitsuba given the bake's seconds: the scene's own image (its film size, box filter) in the
   bake's wall-clock time on the same cores; each probe reads the pixel it falls in. This is
   the picture a user of a path tracer would have after the same wait.

Usage:
    python3 tools/mitsuba_compare.py SCENE.xml BAKE.ply --seconds T [--probes N] [--spp S]
        [--batches B] [--seed K] [--csv PROBES.csv] [--reference-from PROBES.csv]
BAKE.ply is `radiosity bake SCENE.xml -o BAKE.ply`; T its wall-clock seconds. Needs Mitsuba 3
from PyPI (`pip install mitsuba`; the scalar_rgb variant, CPU only). The probe file is kept
with --csv, to score other bakes with the score example, or to run steps 3 and 4 again
without step 2 (--reference-from).
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VIRTUAL = 32768  # virtual film width in pixels: a probe's pixel is a ray, not an area


def luminance(rgb):
    """Rec. 709 luminance, the weights of radiosity::color::luminance."""
    return 0.2126 * rgb[..., 0] + 0.7152 * rgb[..., 1] + 0.0722 * rgb[..., 2]


def sensor_dict(mi, sensor, width, height, spp, crop=None):
    """The scene's sensor (pose, horizontal field of view, clip planes) on a film of
    width x height pixels with a box filter, optionally cropped to the one pixel `crop`."""
    params = mi.traverse(sensor)
    film = {
        "type": "hdrfilm",
        "width": width,
        "height": height,
        "rfilter": {"type": "box"},
        "pixel_format": "rgb",
    }
    if crop is not None:
        film.update(crop_offset_x=crop[0], crop_offset_y=crop[1], crop_width=1, crop_height=1)
    return mi.load_dict(
        {
            "type": "perspective",
            "fov_axis": "x",
            "fov": float(params["x_fov"][0] if hasattr(params["x_fov"], "__len__") else params["x_fov"]),
            "near_clip": float(params["near_clip"]),
            "far_clip": float(params["far_clip"]),
            "to_world": sensor.world_transform(),
            "film": film,
            "sampler": {"type": "independent", "sample_count": spp},
        }
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene")
    parser.add_argument("bake")
    parser.add_argument("--seconds", type=float, required=True, help="the bake's wall-clock seconds")
    parser.add_argument("--probes", type=int, default=1000)
    parser.add_argument("--spp", type=int, default=1 << 16, help="reference samples per probe")
    parser.add_argument("--batches", type=int, default=8)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--csv", help="keep the probe file here")
    parser.add_argument("--reference-from", help="read the reference from a probe file --csv kept")
    args = parser.parse_args()

    try:
        import mitsuba as mi
    except ImportError:
        print("mitsuba_compare: Mitsuba 3 is not installed (pip install mitsuba)")
        sys.exit(3)
    mi.set_variant("scalar_rgb")
    scene = mi.load_file(os.path.abspath(args.scene))
    sensor = scene.sensors()[0]
    width, height = (int(x) for x in sensor.film().size())
    vw, vh = VIRTUAL, max(1, round(VIRTUAL * height / width))
    virtual = sensor_dict(mi, sensor, vw, vh, 1)

    # 1. Probes: Mitsuba's own camera rays and first hits.
    rng = np.random.default_rng(args.seed)
    probes, missed, behind = [], 0, 0
    while len(probes) < args.probes:
        px, py = int(rng.integers(vw)), int(rng.integers(vh))
        ray, _ = virtual.sample_ray(0.0, 0.5, mi.Point2f((px + 0.5) / vw, (py + 0.5) / vh), mi.Point2f(0.5, 0.5))
        si = scene.ray_intersect(ray)
        if not si.is_valid():
            missed += 1
            continue
        n = np.array(si.n, dtype=float)
        if np.dot(n, np.array(ray.d, dtype=float)) >= 0.0:
            behind += 1
            continue
        probes.append(((px, py), np.array(si.p, dtype=float), n))
    print(f"mitsuba_compare: {len(probes)} probes ({missed} rays missed the scene, {behind} met a back face)")

    # 2. Reference: each probe's pixel, in independent batches (or read back).
    start = time.time()
    per_batch = max(1, args.spp // args.batches)
    reference = np.zeros((len(probes), 3))
    std_error = np.zeros(len(probes))
    if args.reference_from:
        rows = np.genfromtxt(args.reference_from, delimiter=",", skip_header=1)
        if len(rows) != len(probes) or any(int(r[0]) != py * vw + px for r, ((px, py), _, _) in zip(rows, probes)):
            sys.exit(f"mitsuba_compare: {args.reference_from} holds other probes (scene, --probes or --seed differ)")
        reference, std_error = rows[:, 7:10], rows[:, 10]
        per_batch = int(rows[0, 11]) // args.batches
    for k, ((px, py), _, _) in enumerate(probes if not args.reference_from else []):
        crop = sensor_dict(mi, sensor, vw, vh, per_batch, crop=(px, py))
        batches = np.array(
            [np.array(mi.render(scene, sensor=crop, spp=per_batch, seed=args.seed * 7919 + k * args.batches + b)).reshape(3)
             for b in range(args.batches)]
        )
        reference[k] = batches.mean(axis=0)
        std_error[k] = luminance(batches).std(ddof=1) / np.sqrt(args.batches)
    if not args.reference_from:
        print(f"mitsuba_compare: reference {args.batches} x {per_batch} samples per probe in {time.time() - start:.0f} s")

    # 3. Our display at the probes, by the score example.
    # The probe's virtual pixel stands in the `triangle` column, so a probe file can be
    # read back (--reference-from) for the same scene, --probes and --seed.
    csv = args.csv or os.path.join(tempfile.mkdtemp(), "probes.csv")
    with open(csv, "w") as f:
        f.write("triangle,x,y,z,nx,ny,nz,r,g,b,std_error,paths\n")
        for k, ((px, py), p, n) in enumerate(probes):
            fields = [*p, *n, *reference[k], std_error[k]]
            f.write(f"{py * vw + px}," + ",".join(repr(float(x)) for x in fields) + f",{args.batches * per_batch}\n")
    score = ["cargo", "run", "--release", "-q", "-p", "radiosity-tools", "--example", "score", "--", os.path.abspath(csv), os.path.abspath(args.bake)]
    print(subprocess.run(score, cwd=ROOT, check=True, capture_output=True, text=True).stdout.strip())
    y_ref = luminance(reference)
    scored = y_ref > 0.1 * y_ref.mean()
    noise = np.sqrt(np.mean((std_error[scored] / y_ref[scored]) ** 2))
    print(f"reference noise (RMS relative standard error at the scored probes): {100 * noise:.2f} %")

    # 4. Mitsuba's own picture after the bake's seconds.
    probe_sensor = sensor_dict(mi, sensor, width, height, 16)
    t = time.time()
    mi.render(scene, sensor=probe_sensor, spp=16, seed=args.seed)
    rate = 16 / (time.time() - t)  # samples per pixel per second, this machine, all cores
    spp = max(1, int(rate * args.seconds))
    t = time.time()
    image = np.array(mi.render(scene, sensor=sensor_dict(mi, sensor, width, height, spp), spp=spp, seed=args.seed + 1))
    took = time.time() - t
    shown = np.array([image[py * height // vh, px * width // vw, :3] for (px, py), _, _ in probes])
    e = (luminance(shown[scored]) - y_ref[scored]) / y_ref[scored]
    a = np.sort(np.abs(e))
    p90 = a[max(0, int(np.ceil(0.9 * len(a))) - 1)]
    print(f"| Mitsuba path, {width}x{height} at {spp} spp ({took:.1f} s) | {scored.sum()} | "
          f"{100 * np.sqrt(np.mean(e ** 2)):.2f} % | {100 * np.median(a):.2f} % | {100 * p90:.2f} % | {100 * e.mean():+.2f} % |")


if __name__ == "__main__":
    main()
