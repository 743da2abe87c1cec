"""Speed of scoring a fisheye luminance map, beside evalglare on the same pictures.

For each size, a square 180° equidistant fisheye picture with several glare sources (the
project's generator) is written as Radiance HDR; then, in the same run:

* lsadphoto: the geometry (directions, solid angles, σ/τ, position index) is built once and
  cached; the timed part is the metrics — source selection, evalglare grouping, pixel-UGR,
  grouped UGR and the other indices, and Q — i.e. ``score_map`` on a warm cache.
* evalglare ``-d`` on the same file (reading the file included, as it cannot be separated).

Usage::

    python benchmarks/bench_metrics.py [--sizes 775,1581,3162,4899] [--no-evalglare]
                                      [--evalglare-max-mp 24] [--repeat 3]

The first call includes building the geometry maps (and, in a fresh installation, compiling
the numba kernels; their on-disk cache makes later processes skip that). The machine may be
shared: compare the CPU columns, and the wall times only at a low load average.

Prints a Markdown table for docs/performance.md.
"""

import argparse
import math
import os
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from lsadphoto.datasets import disk_sources_scene
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.geometry.field import clear_geometry_cache
from lsadphoto.io import read_hdr, write_hdr
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.metrics.score import score_map


def _direction(sigma_deg, tau_deg):
    s, t = math.radians(sigma_deg), math.radians(tau_deg)
    return np.array([math.sin(s) * math.sin(t), -math.sin(s) * math.cos(t), math.cos(s)])


SOURCES = [(_direction(20, 10), 0.02, 30000.0), (_direction(35, 180), 0.07, 5000.0),
           (_direction(50, 90), 0.14, 3000.0), (_direction(40, 300), 0.04, 80000.0)]


def _evalglare():
    import pyradiance

    return os.path.join(os.path.dirname(pyradiance.__file__), "bin", "evalglare")


def bench(size, folder, run_evalglare, repeat):
    cam = IdealFisheyeProjection("equidistant", (size - 1) / 2, (size - 1) / 2, size / 2, 180.0,
                                 size, size)
    L = disk_sources_scene(cam.directions(*cam.pixel_grid()), background=150.0, sources=SOURCES)
    path = Path(folder) / f"fisheye_{size}.hdr"
    write_hdr(LuminanceMap(L, projection=cam, calibrated=True), path)
    lmap = read_hdr(path)
    clear_geometry_cache()
    t0, c0 = time.perf_counter(), time.process_time()
    first = score_map(lmap)
    t_first, c_first = time.perf_counter() - t0, time.process_time() - c0
    runs = []
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        warm = score_map(lmap)
        runs.append((time.perf_counter() - t0, time.process_time() - c0))
    t_warm, c_warm = min(runs)
    row = {"size": size, "mp": size * size / 1e6, "first_s": t_first, "first_cpu_s": c_first,
           "warm_s": t_warm, "warm_cpu_s": c_warm, "warm_worst_s": max(w for w, _ in runs),
           "ugr": warm.values["ugr_grouped"], "n_sources": warm.values["n_sources"]}
    assert first.values["ugr_grouped"] == warm.values["ugr_grouped"]
    if run_evalglare:
        t0 = time.perf_counter()
        proc = subprocess.run([_evalglare(), "-d", str(path)], capture_output=True, text=True,
                              check=True)
        row["evalglare_s"] = time.perf_counter() - t0
        summary = next(x for x in proc.stdout.splitlines() if x.startswith("dgp,av_lum"))
        row["evalglare_ugr"] = float(summary.split(":", 1)[1].split()[6])
    path.unlink()
    return row


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="775,1581,3162,4899")
    parser.add_argument("--no-evalglare", action="store_true")
    parser.add_argument("--evalglare-max-mp", type=float, default=24.1)
    parser.add_argument("--repeat", type=int, default=3,
                        help="warm calls timed; the best is reported (worst in parentheses)")
    args = parser.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"# {os.cpu_count()} CPUs; load average before: {load:.2f}; warm: best of "
          f"{args.repeat} (worst in parentheses); cpu = process CPU time (all threads)")
    print("| picture | megapixels | lsadphoto first call [s] | cpu [s] | lsadphoto metrics, geometry "
          "cached [s] | cpu [s] | evalglare [s] | evalglare / lsadphoto (cached) | UGR ours / evalglare |")
    print("|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        for size in (int(s) for s in args.sizes.split(",")):
            run_peer = not args.no_evalglare and size * size / 1e6 <= args.evalglare_max_mp
            r = bench(size, folder, run_peer, args.repeat)
            peer = f"{r['evalglare_s']:.1f}" if "evalglare_s" in r else "—"
            ratio = f"{r['evalglare_s'] / r['warm_s']:.0f}×" if "evalglare_s" in r else "—"
            ugr = (f"{r['ugr']:.2f} / {r['evalglare_ugr']:.2f}" if "evalglare_ugr" in r
                   else f"{r['ugr']:.2f}")
            print(f"| {size}×{size} | {r['mp']:.1f} | {r['first_s']:.2f} | {r['first_cpu_s']:.2f} | "
                  f"{r['warm_s']:.2f} ({r['warm_worst_s']:.2f}) | {r['warm_cpu_s']:.2f} | "
                  f"{peer} | {ratio} | {ugr} |", flush=True)


if __name__ == "__main__":
    main()
