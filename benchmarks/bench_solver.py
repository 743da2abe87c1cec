"""Speed/accuracy trade of the solver on the canonical room (FORMULAS.md Part A).

Measures, for a 180° equidistant fisheye view of the canonical room:

* simulation time and stored nodes against the number of light chains;
* render time of the double local estimate from one store at 256² and 512² px, against the
  nodes gathered per pixel and batch, with the achieved relative standard error of the
  field-mean luminance and the median per-pixel relative standard error;
* the full double local estimate (every node, small image) and the biased clamp option;
* the path tracer (next-event estimation) at equal image size, for comparison.

Writes a Markdown table with the command line to ``--output`` (default
``/tmp/frag_solver_performance.md``). Run::

    /tmp/venv/bin/python benchmarks/bench_solver.py            # full (several minutes)
    /tmp/venv/bin/python benchmarks/bench_solver.py --quick    # smaller sizes
"""

import argparse
import os
import platform
import sys
import time

import numpy as np

from lsadphoto.solver import render, render_path_traced, simulate
from lsadphoto.solver.examples import canonical_room


def _row(label, size, seconds, lmap=None, extra=""):
    if lmap is None:
        return f"| {label} | {size} | {seconds:.2f} | – | – | {extra} |"
    p = lmap.provenance
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = lmap.uncertainty / lmap.luminance
    med = float(np.nanmedian(rel[np.isfinite(rel) & (lmap.luminance > 0)]))
    return (f"| {label} | {size} | {seconds:.2f} | {100 * p['achieved_relative_error']:.3f} % "
            f"| {100 * med:.2f} % | {extra} |")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller images and fewer chains")
    parser.add_argument("--output", default="/tmp/frag_solver_performance.md")
    args = parser.parse_args(argv)
    sizes = (64, 128) if args.quick else (256, 512)
    chains = (4096, 16384) if args.quick else (16384, 65536, 262144)
    lines = []
    room = canonical_room(size=sizes[0])
    view = room.views[0]
    pose = {"position": view.position, "rotation": view.rotation}

    lines += ["### Simulation (light chains → store)", "",
              "| chains | nodes | time [s] | chains/s |", "|---|---|---|---|"]
    stores = {}
    for n in chains:
        t0 = time.perf_counter()
        stores[n] = simulate(room, samples=n, seed=1)
        dt = time.perf_counter() - t0
        lines.append(f"| {n} | {stores[n].nodes} | {dt:.2f} | {n / dt:,.0f} |")
        print(lines[-1], flush=True)
    store = stores[chains[1]]

    lines += ["", "### Rendering one view", "",
              (f"Store: {store.chains} chains, {store.nodes} nodes, 16 batches. "
               "Field error: relative standard error of the field-mean luminance (solid-angle "
               "weighted); pixel error: median per-pixel relative standard error."), "",
              "| estimator | image | time [s] | field error | pixel error | notes |",
              "|---|---|---|---|---|---|"]
    for size in sizes:
        proj = canonical_room(size=size).views[0].projection
        for k in ((8, 32) if size == sizes[0] else (8,)):
            t0 = time.perf_counter()
            lmap = render(store, proj, **pose, nodes_per_pixel=k)
            lines.append(_row(f"double local, {k} nodes/pixel/batch", f"{size}²",
                              time.perf_counter() - t0, lmap, "unbiased near field"))
            print(lines[-1], flush=True)
        if size == sizes[0]:
            t0 = time.perf_counter()
            lmap = render(store, proj, **pose, nodes_per_pixel=8, near_field="clamp")
            lines.append(_row("double local, 8 nodes/pixel/batch", f"{size}²",
                              time.perf_counter() - t0, lmap, "**clamp (biased)**"))
            print(lines[-1], flush=True)
            for spp in (16, 64):
                t0 = time.perf_counter()
                lmap = render_path_traced(room, proj, **pose, samples=spp)
                lines.append(_row(f"path tracing, {spp} paths/pixel", f"{size}²",
                                  time.perf_counter() - t0, lmap, "cross-check estimator"))
                print(lines[-1], flush=True)
    small = canonical_room(size=32).views[0].projection
    t0 = time.perf_counter()
    lmap = render(stores[chains[0]], small, **pose, nodes_per_pixel="all")
    lines.append(_row(f"double local, all {stores[chains[0]].nodes} nodes", "32²",
                      time.perf_counter() - t0, lmap, "full estimate: cost ∝ pixels × nodes"))
    print(lines[-1], flush=True)
    t0 = time.perf_counter()
    target = simulate(room, target_error=0.002, samples=4096, seed=2)
    p = target.provenance
    lines += ["", "### Accuracy control", "",
              (f"`simulate(target_error=0.002)` on the canonical room: {p['chains']} chains, "
               f"achieved {100 * p['achieved_relative_error']:.3f} % ({p['error_measured_on']}, "
               f"≤ 24 px per side), {time.perf_counter() - t0:.1f} s.")]
    head = [
        "## Solver performance (canonical room, 180° equidistant fisheye)", "",
        f"Command: `{' '.join([os.path.basename(sys.executable), *sys.argv])}`  ",
        (f"Machine: {platform.machine()}, {os.cpu_count()} cores (shared with other jobs; "
         f"times are indicative), Python {platform.python_version()}, numpy {np.__version__}."), "",
    ]
    text = "\n".join(head + lines) + "\n"
    with open(args.output, "w", encoding="utf-8") as fh:
        fh.write(text)
    print(text)


if __name__ == "__main__":
    main()
