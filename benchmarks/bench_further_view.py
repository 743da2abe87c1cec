"""A further view of a stored simulation, as a user waits for it: a whole
``lsadphoto render STORE --view … --size 512x512`` process (issue 13: "the other views of a
stored simulation still render in ≤ 2 s at 512²").

The store is the canonical room (``lsadphoto.solver.examples.canonical_room_rad``, read as
Radiance) simulated with 65 536 light chains (seed 1) and its surface cache of 16 384 node
draws per point, as in ``bench_solver_vs_rpict.py``; the view is a second observer at
(4, 2, 1.2) m looking −x, a 180° equidistant fisheye. Each command runs ``--runs`` times as a
fresh process, after one untimed run (kernel caches and the page cache warm). Reported: the
median wall time with the spread (min–max) and the median CPU time of the process (all
threads, ``getrusage`` of the child), and the same view rendered inside this process
(``load_store`` + ``render_cached``, imports and kernels already loaded: the figure earlier
sessions reported).

``--before TREE`` runs the same command from another source tree (an earlier commit unpacked
with ``git archive``), interleaved with this tree's runs, so that both see the same load.

Usage::

    python benchmarks/bench_further_view.py [--runs 5] [--size 512] [--before TREE]
"""

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from _clock import Clock

from lsadphoto.solver import camera_to_world, load_store, read_radiance_scene, simulate
from lsadphoto.solver.examples import canonical_room_rad
from lsadphoto.solver.integrators.surface_cache import build_surface_cache, render_cached

HERE = Path(__file__).resolve().parent
VIEW = "-vta -vp 4 2 1.2 -vd -1 0 0 -vu 0 0 1 -vh 180 -vv 180"


def build_store(folder, size):
    """The canonical room's store with its surface cache, saved in ``folder``."""
    rad = folder / "room.rad"
    rad.write_text(canonical_room_rad())
    scene = read_radiance_scene(rad, views=[{
        "name": "observer", "position": [1.0, 2.0, 1.2], "line_of_sight": [1, 0, 0], "up": [0, 0, 1],
        "projection": {"model": "fisheye-ideal", "kind": "equidistant", "fov_deg": 180,
                       "width": size, "height": size}}])
    store = simulate(scene, samples=65536, seed=1)
    store.surface_cache = build_surface_cache(store, nodes=16384, seed=1, workers=os.cpu_count() or 1)
    path = folder / "room.lsad.npz"
    store.save(path)
    return path, scene.views[0].projection


def process(tree, store, size, output):
    """Wall and CPU [s] of one ``lsadphoto render`` process from source tree ``tree``."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [tree, os.environ.get("PYTHONPATH")]))}
    command = [sys.executable, "-m", "lsadphoto.cli", "render", str(store), "--view", VIEW,
               "--size", f"{size}x{size}", "-o", str(output), "--quiet"]
    with Clock() as c:  # from this folder: the working folder is not put first on sys.path
        subprocess.run(command, check=True, capture_output=True, env=env, cwd=HERE)
    return c.wall, c.cpu


def summary(times):
    walls, cpus = [t[0] for t in times], [t[1] for t in times]
    return (f"{statistics.median(walls):.2f} ({min(walls):.2f}–{max(walls):.2f}) s wall, "
            f"{statistics.median(cpus):.2f} s CPU")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--before", help="another lsadphoto source tree, interleaved as `before`")
    args = parser.parse_args(argv)
    this = str(HERE.parent)
    trees = {"this tree": this, **({"before": os.path.abspath(args.before)} if args.before else {})}
    folder = Path(tempfile.mkdtemp(prefix="bench_further_view_"))
    with Clock() as c:
        store, projection = build_store(folder, args.size)
    print(f"# {os.cpu_count()} CPUs; store: 65536 chains + 16384-node cache in {c.wall:.1f} s; "
          f"load average {os.getloadavg()[0]:.2f}", flush=True)
    times = {name: [] for name in trees}
    for name, tree in trees.items():  # untimed: caches warm
        process(tree, store, args.size, folder / "warm.exr")
    for _ in range(args.runs):
        for name, tree in trees.items():
            times[name].append(process(tree, store, args.size, folder / f"{name}.exr"))
    inside = []
    for _ in range(args.runs + 1):
        with Clock() as c:
            render_cached(load_store(store), projection, position=[4.0, 2.0, 1.2],
                          rotation=camera_to_world([-1, 0, 0], [0, 0, 1]), seed=0,
                          workers=os.cpu_count() or 1)
        inside.append((c.wall, c.cpu))
    print(f"Command: `{' '.join([os.path.basename(sys.executable), *sys.argv])}`; load average after "
          f"{os.getloadavg()[0]:.2f}")
    for name in trees:
        print(f"* whole `lsadphoto render` process, {name}: {summary(times[name])}")
    print(f"* inside one process (load_store + render_cached, after a first render), this tree: "
          f"{summary(inside[1:])}")


if __name__ == "__main__":
    main()
