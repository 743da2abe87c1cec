"""Speed of the per-pixel geometry maps for 24-megapixel fisheyes (docs/performance.md).

Run: ``.venv/bin/python benchmarks/bench_geometry.py [--size 6000x4000] [--repeat 3]
[--baseline]``; ``--profile MODEL`` prints a pyinstrument profile of one first call instead
(single-threaded, so that the profile shows where the time goes; the compiled kernels
appear as single entries).

The fisheye maps come from numba kernels (``lsadphoto/geometry/_kernels.py``) that run on
all CPUs; ``NUMBA_NUM_THREADS=1`` times them on one thread (wall ≈ CPU). The first call in
a process also loads the compiled kernels from numba's on-disk cache (0.3–0.4 s; it is the
"worst" of the repeats); with an empty cache (``NUMBA_CACHE_DIR=$(mktemp -d)``) it
includes compiling them (≈ 15 s once). On a shared machine compare the CPU column.

For each camera model it times, best and worst of ``--repeat`` runs (``time.perf_counter``,
plus the process CPU time of the best run, which shows how much of the two cores was used):

* ``pixel_geometry``: first call (cache emptied before), directions, solid angles, validity;
* ``visual_field``: first call for the default observer frame (σ, τ, position index of the
  evalglare method, cos σ), with the pixel geometry already cached;
* ``cached``: a second call of both (a cache hit; should be microseconds).

``--baseline`` also times the uncached per-pixel methods of the projection
(``directions`` + ``solid_angles`` on the whole pixel grid, ``ObserverFrame.angles`` +
``position_index``), i.e. what a caller did before the cache.

Models: an ideal equidistant 180° fisheye (image circle of 0.975 × the image height, the
Radiance ``-vta`` camera) and an OpenCV (Kannala–Brandt) fisheye with mild distortion and an
off-centre principal point.
"""

import argparse
import os
import platform
import sys
import time

import numpy as np

from lsadphoto.geometry import (
    IdealFisheyeProjection,
    ObserverFrame,
    OpenCVFisheyeProjection,
    clear_geometry_cache,
    pixel_geometry,
    position_index,
    visual_field,
)


def parse_size(text):
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 6000x4000, got {text!r}") from None
    return width, height


def models(width, height):
    radius = 0.4875 * height
    return {
        "equidistant 180°": IdealFisheyeProjection(
            "equidistant", (width - 1) / 2, (height - 1) / 2, radius, 180.0, width, height),
        "opencv-fisheye": OpenCVFisheyeProjection(
            radius / (np.pi / 2) * 0.98, radius / (np.pi / 2) * 0.98, (width - 1) / 2 + 3.2,
            (height - 1) / 2 - 1.7, (0.02, -0.005, 0.001, -0.0002), width, height),
    }


def timed(function):
    wall, cpu = time.perf_counter(), time.process_time()
    result = function()
    return time.perf_counter() - wall, time.process_time() - cpu, result


def bench(camera, repeat, baseline):
    frame = ObserverFrame()
    rows = {"geometry": [], "field": [], "cached": []}
    for _ in range(repeat):
        clear_geometry_cache()
        rows["geometry"].append(timed(lambda: pixel_geometry(camera))[:2])
        rows["field"].append(timed(lambda: visual_field(camera, frame))[:2])
        rows["cached"].append(timed(lambda: (pixel_geometry(camera), visual_field(camera, frame)))[:2])
    clear_geometry_cache()
    if baseline:
        def uncached():
            r, c = camera.pixel_grid()
            d = camera.directions(r, c)
            camera.solid_angles(r, c)
            sigma, tau = frame.angles(d)
            position_index(sigma, tau)

        rows["uncached methods"] = [timed(uncached)[:2]]
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=parse_size, default=(6000, 4000))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--baseline", action="store_true", help="also time the uncached methods")
    parser.add_argument("--profile", choices=["equidistant", "opencv"], default=None)
    args = parser.parse_args(argv)
    width, height = args.size
    cameras = models(width, height)
    if args.profile:
        from pyinstrument import Profiler

        import numba

        from lsadphoto.geometry import field

        field.os.cpu_count = lambda: 1  # the numpy path of the other models
        numba.set_num_threads(1)  # the compiled fisheye kernels
        camera = list(cameras.values())[0 if args.profile == "equidistant" else 1]
        profiler = Profiler()
        profiler.start()
        pixel_geometry(camera)
        visual_field(camera, ObserverFrame())
        profiler.stop()
        print(profiler.output_text(unicode=True))
        return 0
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"# {width}×{height} px = {width * height / 1e6:.1f} MP; {os.cpu_count()} CPUs "
          f"({platform.processor() or platform.machine()}); Python {platform.python_version()}, "
          f"numpy {np.__version__}; load average before: {load:.2f}")
    print(f"# best of {args.repeat} (worst in parentheses); cpu = process CPU time of the best run")
    print("| model | size | step | first call [s] | cpu [s] | cached call [s] |")
    print("|---|---|---|---|---|---|")
    for name, camera in cameras.items():
        result = bench(camera, args.repeat, args.baseline)
        cached = min(w for w, _ in result.pop("cached"))
        for step, runs in result.items():
            wall = [w for w, _ in runs]
            best = int(np.argmin(wall))
            worst = f" ({max(wall):.2f})" if len(wall) > 1 else ""
            cache_text = f"{cached * 1e6:.0f} µs" if step == "geometry" else "—"
            print(f"| {name} | {width}×{height} | {step} | {wall[best]:.2f}{worst} | {runs[best][1]:.2f} | {cache_text} |",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
