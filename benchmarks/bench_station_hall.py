"""The solver at station scale: `simulate` + `render` of the generated hall, as a user runs them.

The hall of :func:`lsadphoto.datasets.hall.make_station_hall` (60 × 20 m, barrel vault,
40 columns, 20 benches, 120 IES luminaires, ≈ 64 000 triangles at ``--detail 1``) is
simulated and one fisheye view rendered by fresh ``lsadphoto`` processes; the cache's
points, each step's wall time, CPU time and peak memory (``resource.getrusage`` of the child) and the rendered map's
per-pixel relative errors (median, 95th percentile) are printed as a table row. Variants:
``--detail 2`` (4× triangles), ``--luminaires 480`` (4× luminaires). With ``--target-error E``
the scene is rendered directly, as ``lsadphoto render hall.toml --estimator cache
--target-error E`` (rounds of simulate + render from ``--samples`` chains until the
per-pixel error is E — since session 11 the expected mean absolute relative error, before it
the median; one process, shown in the render column, with the rounds' chains).

    PYTHONPATH=. .venv/bin/python benchmarks/bench_station_hall.py [--detail 1] [--luminaires 120]
        [--size 1024] [--samples 262144] [--estimator cache|local] [--nodes-per-pixel auto]
        [--target-error 0.02]
"""

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from lsadphoto.datasets.hall import make_station_hall
from lsadphoto.solver import load_scene, load_store


def run(args):
    """Run ``lsadphoto ARGS``; wall [s], CPU [s] and peak RSS [GB] of the child, stdout."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "lsadphoto.cli", *map(str, args)],
                          capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode:
        raise SystemExit(f"lsadphoto {' '.join(map(str, args))} failed: {proc.stderr.strip()}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, after.ru_maxrss / 1e6, proc.stdout


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--detail", type=float, default=1.0)
    ap.add_argument("--luminaires", type=int, default=120)
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--samples", type=int, default=262144)
    ap.add_argument("--estimator", default="cache", choices=("cache", "local"))
    ap.add_argument("--nodes-per-pixel", default="auto")
    ap.add_argument("--target-error", type=float, default=None)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        scene = make_station_hall(Path(tmp) / "hall", luminaires=a.luminaires, detail=a.detail,
                                  view_size=a.size)
        triangles = len(load_scene(scene).triangles)
        if a.target_error is not None:
            return _to_target(a, scene, triangles, Path(tmp) / "view.exr")
        store = Path(tmp) / "hall.npz"
        sim = ["simulate", scene, "-o", store, "--samples", a.samples, "--quiet", "--json"]
        if a.estimator == "cache":
            sim.append("--surface-cache")
        s_wall, s_cpu, s_mem, _ = run(sim)
        cache = load_store(store).surface_cache
        points = "–" if cache is None else (f"{cache.size} ({cache.provenance['grid_points']} grid, "
                                            f"{cache.provenance['leaf_patches']} patches)")
        out = Path(tmp) / "view.exr"
        r_wall, r_cpu, r_mem, r_out = run(["render", store, "--view-name", "along", "--estimator",
                                           a.estimator, "--nodes-per-pixel", a.nodes_per_pixel,
                                           "--quiet", "--json", "-o", out])
        p = json.loads(r_out)["provenance"]
    print("| triangles | luminaires | chains | view | estimator | cache points | simulate: wall / CPU [s] | "
          "render: wall / CPU [s] | peak memory [GB] | per-pixel error median / p95 |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    print(f"| {triangles} | {a.luminaires} | {a.samples} | {a.size}² | {a.estimator} | {points} | "
          f"{s_wall:.0f} / {s_cpu:.0f} | {r_wall:.0f} / {r_cpu:.0f} | {max(s_mem, r_mem):.1f} | "
          f"{100 * p['pixel_relative_error_median']:.2g} % / {100 * p['pixel_relative_error_p95']:.2g} % |")


def _to_target(a, scene, triangles, out):
    """The scene rendered to ``--target-error`` in one process; prints its table row."""
    wall, cpu, mem, text = run(["render", scene, "--view-name", "along", "--estimator", a.estimator,
                                "--target-error", a.target_error, "--samples", a.samples,
                                "--nodes-per-pixel", a.nodes_per_pixel, "--quiet", "--json", "-o", out])
    p = json.loads(text)["provenance"]
    rounds = " → ".join(str(r["chains"]) for r in p["rounds"])
    last = p["rounds"][-1]
    knobs = ", ".join(f"{k} {last[k]}" for k in ("cache_nodes", "direct_samples", "luminaire_draws") if k in last)
    expected = p.get("pixel_relative_error_expected_mean_absolute")
    print("| triangles | luminaires | chains per round | view | estimator | target | last round | "
          "render (simulate included): wall / CPU [s] | peak memory [GB] | per-pixel error median / p95 | "
          "expected mean absolute per-pixel error |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    print(f"| {triangles} | {a.luminaires} | {rounds} | {a.size}² | {a.estimator} | {100 * a.target_error:g} % "
          f"{'reached' if p['target_reached'] else 'NOT reached'} | {knobs} | {wall:.0f} / {cpu:.0f} | {mem:.1f} | "
          f"{100 * p['pixel_relative_error_median']:.2g} % / {100 * p['pixel_relative_error_p95']:.2g} % | "
          f"{'–' if expected is None else f'{100 * expected:.2g} %'} |")
    if "pixels_estimated_without_cache" in p:  # the cache's unresolved pixels (docs/accuracy.md, session 12)
        print(f"\nPixels that took E_ind at their own point: {p['pixels_estimated_without_cache']} "
              f"({p['pixel_records']} records).")


if __name__ == "__main__":
    main()
