"""Latency as a user feels it: a whole ``lsadphoto score MAP.hdr --json`` process beside a
whole ``evalglare -d MAP.hdr`` process on the same picture, in the same run.

For each size a square 180° equidistant (``-vta``) fisheye picture is written as Radiance
HDR by the project's generator — ``disks``: the four glare sources of
``bench_metrics.py``; ``window``: a window of 1.8 sr (2500–12 000 cd·m⁻², brighter upwards
and to one side, a mullion), like the daylit office photograph of issue 11 — then the two commands run one after the other,
``--runs`` times (interleaved, so that both see the same machine load), each as a fresh
process. Reported: median wall time, the spread (min–max), median process CPU time (all
threads, from ``getrusage`` of the child), and the ratio of the medians. Before the timed
runs each command runs once untimed, so that the kernel caches and the page cache are warm
(a fresh installation compiles the kernels once, in its first run; that run is not what a
user waits for afterwards).

Per-stage timings inside our process come from ``--stages``: the same command run through
``lsadphoto.cli.main`` in a child that times the imports, reading the picture, scoring it,
the time spent loading the kernels (inside those two: the ahead-of-time extension of
``lsadphoto._compiled``, and numba's import and cache loads where a kernel runs just in time)
and the output; the interpreter's start-up is the process wall time minus the time inside.

Usage::

    python benchmarks/bench_score_process.py [--sizes 786,1572,4899] [--runs 5]
        [--evalglare-runs-large 1] [--large-mp 10] [--scene disks|window] [--stages 3]
        [--kernels auto,cold,nocache,jit] [--before TREE]

``--before TREE`` adds the same command run from another source tree (an earlier commit,
unpacked with ``git archive``), interleaved with the others: before and after in one run.

``--kernels`` compares the kernels' compilations (``LSADPHOTO_KERNELS``, see
``lsadphoto._compiled``): ``auto`` (the default: ahead of time) and ``jit`` (numba only, its
parallel code, as every process ran before the ahead-of-time build); their runs interleave
with evalglare's.

The geometry cache (``lsadphoto.geometry._map_cache``): every process of this benchmark
uses a cache folder of its own run, empty at the start, so the untimed first run of a
variant writes the camera's maps and the timed runs of ``auto`` (and ``jit``) read them:
**warm**, a survey's second and later photos of one camera. ``--kernels auto,cold`` adds
the **cold** process, the first photo of a camera: each of its runs starts with an empty
cache folder, computes the maps into a new cache file and flushes it to disk (the folder
is deleted after the run); ``nocache`` runs with ``LSADPHOTO_GEOMETRY_CACHE=off``.

The package's modules are byte-compiled first (``compileall``), as an installed package
has them: with ``PYTHONDONTWRITEBYTECODE`` set and no ``__pycache__``, every process would
compile the ~50 modules of the score path from source (0.1 s here).

Sizes above ``--large-mp`` megapixels run evalglare ``--evalglare-runs-large`` times (at
24 MP one evalglare run takes about five minutes). The machine may be shared: the load
average before and after is printed; compare the ratios, which interleaving keeps fair.
"""

import argparse
import contextlib
import io
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def _luminance(name, directions):
    """Luminance [cd·m⁻²] of the benchmark scene ``name`` for the pixel ``directions``."""
    from bench_metrics import SOURCES

    from lsadphoto.datasets import disk_sources_scene, window_scene

    if name == "disks":
        return disk_sources_scene(directions, background=150.0, sources=SOURCES)
    # (100° of azimuth) × (sin 60° + sin 10°) = 1.8 sr, brighter upwards and to one side.
    window = dict(azimuth=(-20, 80), elevation=(-10, 60), luminance=(2500.0, 12000.0),
                  side_gradient=0.5, mullions=(30.0,), mullion_width=3.0)
    return window_scene(directions, background=(40.0, 160.0), windows=[window])


def write_picture(size, scene, folder):
    """The generated fisheye picture of ``size``² pixels as a Radiance HDR file."""
    from lsadphoto.geometry import IdealFisheyeProjection
    from lsadphoto.io import write_hdr
    from lsadphoto.luminance_map import LuminanceMap

    cam = IdealFisheyeProjection("equidistant", (size - 1) / 2, (size - 1) / 2, size / 2, 180.0,
                                 size, size)
    L = _luminance(scene, cam.directions(*cam.pixel_grid()))
    path = Path(folder) / f"{scene}_{size}.hdr"
    write_hdr(LuminanceMap(L, projection=cam, calibrated=True), path)
    return path


def _lsadphoto_command(path):
    return [sys.executable, "-c", "import sys; from lsadphoto.cli import main; sys.exit(main())",
            "score", str(path), "--json"]


def _evalglare_command(path):
    import pyradiance

    return [os.path.join(os.path.dirname(pyradiance.__file__), "bin", "evalglare"), "-d", str(path)]


#: Source tree of the ``before`` variant (``--before``), put first on its PYTHONPATH.
BEFORE = {"tree": None}


#: The geometry cache folder of the benchmark's processes (lsadphoto.geometry._map_cache):
#: a folder of this run, not the user's cache, so that every run starts without one.
GEOMETRY_CACHE = {"folder": None}


def _env(kernels, cold_folder=None):
    """Environment of a variant: ``LSADPHOTO_KERNELS=kernels``, or for ``before`` the tree
    of ``--before`` (default kernels); ``cold`` and ``nocache`` run the default kernels with
    an empty geometry cache folder (``cold_folder``) and without the cache. Every variant
    but ``nocache`` uses the run's geometry cache folder (``warm`` after the untimed
    first run)."""
    env = dict(os.environ)
    if GEOMETRY_CACHE["folder"] is not None:
        env["LSADPHOTO_GEOMETRY_CACHE"] = GEOMETRY_CACHE["folder"]
    if kernels is None:
        return env
    if kernels == "before":
        path = os.pathsep.join([BEFORE["tree"], *filter(None, [os.environ.get("PYTHONPATH")])])
        return {**env, "PYTHONPATH": path}
    if kernels == "cold":
        return {**env, "LSADPHOTO_GEOMETRY_CACHE": cold_folder}
    if kernels == "nocache":
        return {**env, "LSADPHOTO_GEOMETRY_CACHE": "off"}
    return {**env, "LSADPHOTO_KERNELS": kernels}


def timed(command, kernels=None):
    """(wall [s], CPU of the child [s], stdout) of one fresh process (``LSADPHOTO_KERNELS``
    set to ``kernels`` where given; ``cold``: with an empty geometry cache, deleted after)."""
    import shutil

    cold_folder = tempfile.mkdtemp(prefix="lsadphoto-cold-cache-") if kernels == "cold" else None
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    # From this folder: ``python -c`` puts the working folder first on sys.path, so from a
    # source tree's root it would import that tree's package whatever PYTHONPATH says.
    try:
        done = subprocess.run(command, capture_output=True, text=True, check=True,
                              env=_env(kernels, cold_folder), cwd=HERE)
    finally:
        wall = time.perf_counter() - t0
        if cold_folder is not None:
            shutil.rmtree(cold_folder, ignore_errors=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, done.stdout


def _child_stages(path):
    """Run ``lsadphoto score PATH --json`` inside this process, timing its stages; prints
    one JSON line of {stage: [wall, cpu]} on stderr."""
    t_start, c_start = time.perf_counter(), time.process_time()
    stages = {}

    def lap(name, t, c):
        now_t, now_c = time.perf_counter(), time.process_time()
        stages[name] = [now_t - t, now_c - c]
        return now_t, now_c

    t, c = t_start, c_start
    sys.argv = ["lsadphoto", "score", str(path), "--json"]  # as the console script sees it
    import lsadphoto.cli as cli
    t, c = lap("import cli", t, c)
    import lsadphoto.io
    import lsadphoto.metrics.score as score_module
    t, c = lap("import score modules", t, c)

    from lsadphoto import _compiled

    loading = [0.0, 0.0]

    def counted(function):
        def timed_call(*args, **kwargs):
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                return function(*args, **kwargs)
            finally:
                loading[0] += time.perf_counter() - t0
                loading[1] += time.process_time() - c0
        return timed_call

    numba_ = _compiled._numba

    def numba_with_compile_timer():
        # Importing numba and, once imported, every load of a cached kernel count as loading.
        first = _compiled._STATE["numba"] is None
        numba = numba_()
        if first:
            from numba.core import dispatcher

            dispatcher.Dispatcher.compile = counted(dispatcher.Dispatcher.compile)
        return numba

    _compiled._numba = counted(numba_with_compile_timer)
    _compiled._library = counted(_compiled._library)
    inner = {}

    def wrap(module, name, label):
        function = getattr(module, name)

        def timed_call(*args, **kwargs):
            t0, c0 = time.perf_counter(), time.process_time()
            l0 = list(loading)
            try:
                return function(*args, **kwargs)
            finally:
                inner[label] = [time.perf_counter() - t0 - (loading[0] - l0[0]),
                                time.process_time() - c0 - (loading[1] - l0[1])]

        setattr(module, name, timed_call)

    wrap(lsadphoto.io, "read_map", "read picture")
    wrap(score_module, "score_map", "score_map")
    with contextlib.redirect_stdout(io.StringIO()):
        code = cli.main()  # as the console script calls it: the process is the command
    t, c = lap("command", t, c)
    stages.update(inner)
    stages["kernel loading (extension; numba where used)"] = list(loading)
    command = stages.pop("command")
    rest = [command[i] - sum(v[i] for k, v in inner.items()) - loading[i] for i in range(2)]
    stages["rest of the command (options, JSON)"] = rest
    stages["total inside"] = [time.perf_counter() - t_start, time.process_time() - c_start]
    print(json.dumps(stages), file=sys.stderr)
    return code


def stage_table(path, repeat, kernels=None):
    """Median per-stage [wall, cpu] over ``repeat`` fresh processes, and the process wall."""
    import shutil

    runs = []
    for _ in range(repeat):
        cold = tempfile.mkdtemp(prefix="lsadphoto-cold-cache-") if kernels == "cold" else None
        t0 = time.perf_counter()
        done = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--child", str(path)],
                              capture_output=True, text=True, check=True, env=_env(kernels, cold))
        wall = time.perf_counter() - t0
        if cold is not None:
            shutil.rmtree(cold, ignore_errors=True)
        stages = json.loads(done.stderr.strip().splitlines()[-1])
        stages["interpreter start-up and exit"] = [wall - stages["total inside"][0], math.nan]
        stages["process"] = [wall, math.nan]
        runs.append(stages)
    return {k: [statistics.median(r[k][i] for r in runs) for i in range(2)] for k in runs[0]}


def _median_spread(values):
    return statistics.median(values), min(values), max(values)


def bench(size, scene, folder, runs, evalglare_runs, modes):
    """One row per kernel mode of ``modes`` (``LSADPHOTO_KERNELS``), all interleaved with
    evalglare's runs."""
    path = write_picture(size, scene, folder)
    peer_cmd = _evalglare_command(path)
    ours_cmd = _lsadphoto_command(path)
    ours = {mode: [] for mode in modes}
    for mode in modes:
        timed(ours_cmd, mode)  # warm-up: kernel caches, page cache
    peer = []
    for k in range(runs):
        for mode in modes:
            ours[mode].append(timed(ours_cmd, mode))
        if k < evalglare_runs:
            peer.append(timed(peer_cmd))
    peer_ugr = math.nan
    if peer:
        summary = next(x for x in peer[-1][2].splitlines() if x.startswith("dgp,av_lum"))
        peer_ugr = float(summary.split(":", 1)[1].split()[6])
    rows = []
    for mode in modes:
        record = json.loads(ours[mode][-1][2])
        rows.append({"size": size, "mp": size * size / 1e6, "file_mb": path.stat().st_size / 1e6,
                     "kernels": mode,
                     "ours_wall": _median_spread([w for w, _, _ in ours[mode]]),
                     "ours_cpu": statistics.median(c for _, c, _ in ours[mode]),
                     "peer_wall": _median_spread([w for w, _, _ in peer] or [math.nan]),
                     "peer_cpu": statistics.median([c for _, c, _ in peer] or [math.nan]),
                     "runs": len(ours[mode]), "peer_runs": len(peer),
                     "ugr": record["ugr_grouped"], "peer_ugr": peer_ugr, "path": path})
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="786,1572,4899")
    parser.add_argument("--scene", choices=("disks", "window"), default="disks")
    parser.add_argument("--runs", type=int, default=5, help="interleaved runs of each command")
    parser.add_argument("--large-mp", type=float, default=10.0)
    parser.add_argument("--evalglare-runs-large", type=int, default=1)
    parser.add_argument("--stages", type=int, default=3, help="processes timed stage by stage")
    parser.add_argument("--kernels", default="auto",
                        help="variants to compare, comma-separated: LSADPHOTO_KERNELS values "
                        "(auto, jit; with the geometry cache warm), cold (an empty geometry "
                        "cache in every process: its first process on a camera), nocache "
                        "(LSADPHOTO_GEOMETRY_CACHE=off)")
    parser.add_argument("--before", help="another lsadphoto source tree (e.g. an earlier "
                        "commit's `git archive`): its processes interleave as variant `before`")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        sys.exit(_child_stages(args.child))
    variants = args.kernels.split(",")
    if args.before:
        BEFORE["tree"] = os.path.abspath(args.before)
        variants.append("before")
    sys.path.insert(0, str(HERE))
    # The package byte-compiled, as an installation has it (pip compiles it; an environment
    # with PYTHONDONTWRITEBYTECODE would otherwise compile every module in every process).
    import compileall

    import lsadphoto

    compileall.compile_dir(os.path.dirname(lsadphoto.__file__), quiet=1)
    if args.before:
        compileall.compile_dir(os.path.join(BEFORE["tree"], "lsadphoto"), quiet=1)
    print(f"# {os.cpu_count()} CPUs; load average before: {os.getloadavg()[0]:.2f}; scene "
          f"{args.scene}; medians of interleaved fresh processes, spread min–max; cpu = user + "
          f"system time of the process (all threads)")
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        GEOMETRY_CACHE["folder"] = os.path.join(folder, "geometry-cache")
        for size in (int(s) for s in args.sizes.split(",")):
            peer_runs = args.runs if size * size / 1e6 <= args.large_mp else args.evalglare_runs_large
            for r in bench(size, args.scene, folder, args.runs, peer_runs, variants):
                r["stages"] = stage_table(r["path"], args.stages, r["kernels"]) \
                    if args.stages else None
                rows.append(r)
            r["path"].unlink()
            print(f"# done {size}² (load {os.getloadavg()[0]:.2f})", file=sys.stderr, flush=True)
    print("\n| picture | MP | HDR file [MB] | kernels | lsadphoto score: wall median (min–max) [s] "
          "| cpu [s] | evalglare -d: wall median (min–max) [s] | cpu [s] | runs ours / evalglare "
          "| wall ratio | cpu ratio | UGR ours / evalglare |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        (ow, olo, ohi), (pw, plo, phi) = r["ours_wall"], r["peer_wall"]
        print(f"| {r['size']}² | {r['mp']:.1f} | {r['file_mb']:.1f} | {r['kernels']} "
              f"| {ow:.2f} ({olo:.2f}–{ohi:.2f}) "
              f"| {r['ours_cpu']:.2f} | {pw:.1f} ({plo:.1f}–{phi:.1f}) | {r['peer_cpu']:.1f} "
              f"| {r['runs']} / {r['peer_runs']} | {pw / ow:.1f}× | {r['peer_cpu'] / r['ours_cpu']:.1f}× "
              f"| {r['ugr']:.2f} / {r['peer_ugr']:.2f} |")
    if any(r["stages"] for r in rows):
        names = list(rows[0]["stages"])
        print("\nStages of our process (median of fresh processes; wall / cpu [s]):\n")
        print("| stage | " + " | ".join(f"{r['size']}² {r['kernels']}" for r in rows) + " |")
        print("|---|" + "---|" * len(rows))
        for name in names:
            cells = []
            for r in rows:
                w, c = r["stages"][name]
                cells.append(f"{w:.3f}" + ("" if math.isnan(c) else f" / {c:.3f}"))
            print(f"| {name} | " + " | ".join(cells) + " |")
    print(f"\n# load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
