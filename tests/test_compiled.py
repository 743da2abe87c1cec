"""The kernels' two compilations (lsadphoto._compiled) give the same results.

A score process runs the kernels from their ahead-of-time compilation (one thread, no numba
loaded); with ``LSADPHOTO_KERNELS=jit`` from numba's just-in-time compilation (parallel),
which the peer tests against evalglare have checked for years of the project. Both must
give the same record, bit for bit: neither allows fast-math and the parallel loops keep no
floating-point reduction across iterations. Arguments outside the compiled signatures must
reach the just-in-time code, never the ahead-of-time function (which would read a float32
array as float64 garbage).
"""

import json
import mmap
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from lsadphoto import _compiled
from lsadphoto.datasets import window_scene
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.io import write_hdr
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.geometry._kernels import quad_solid_angle_grid

from .conftest import skip_without_ahead_of_time_kernels

SCRIPT = """
import json, sys
from lsadphoto.cli import main
code = main()
print(json.dumps("numba" in sys.modules), file=sys.stderr)
sys.exit(code)
"""


def _score(path, *options, **env):
    done = subprocess.run([sys.executable, "-c", SCRIPT, "score", str(path), "--json", *options],
                          capture_output=True, text=True, env={**os.environ, **env})
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout), json.loads(done.stderr.strip().splitlines()[-1])


def _resident_pages(array):
    """Pages of ``array``'s whole pages that are in memory (mincore)."""
    import ctypes
    import mmap

    libc = ctypes.CDLL(None, use_errno=True)
    page = mmap.PAGESIZE
    start = -(-array.ctypes.data // page) * page
    n = (array.ctypes.data + array.nbytes - start) // page
    vec = (ctypes.c_ubyte * n)()
    assert libc.mincore(ctypes.c_void_p(start), ctypes.c_size_t(n * page), vec) == 0
    return sum(v & 1 for v in vec), n


@pytest.mark.skipif(not sys.platform.startswith("linux")
                    or tuple(int(x) for x in os.uname().release.split(".")[:2]) < (5, 14),
                    reason="MADV_POPULATE_WRITE is Linux 5.14 and later")
def test_populate_faults_fresh_pages_in_and_keeps_values():
    # An anonymous mapping of its own, not yet written: nothing resident (np.empty could reuse
    # heap pages that earlier tests of the same process made resident: glibc raises its mmap
    # threshold after large frees).
    fresh = np.frombuffer(mmap.mmap(-1, 16 << 20), np.uint8)
    before, n = _resident_pages(fresh)
    _compiled.populate(fresh)
    assert before < n // 2 and _resident_pages(fresh) == (n, n)
    values = np.random.default_rng(1).random((1024, 1024))  # 8 MB, written
    kept = values.copy()
    _compiled.populate(values[256:768], values[:, ::2])  # a block of rows; a strided view (left)
    assert np.array_equal(values, kept)


@pytest.mark.slow  # a fresh machine compiles the score's kernels just in time here (1–2 min)
def test_ahead_of_time_and_just_in_time_scores_are_identical(tmp_path):
    # A daylit window of about 1 sr with gradients and a mullion (grouping, Q, statistics).
    cam = IdealFisheyeProjection("equidistant", 119.5, 119.5, 120.0, 180.0, 240, 240)
    window = dict(azimuth=(-20, 60), elevation=(-5, 50), luminance=(2500.0, 9000.0),
                  side_gradient=0.5, mullions=(20.0,), mullion_width=3.0)
    L = window_scene(cam.directions(*cam.pixel_grid()), background=(40.0, 160.0),
                     windows=[window])
    path = tmp_path / "window.hdr"
    write_hdr(LuminanceMap(L, projection=cam, calibrated=True), path)
    ahead, numba_loaded = _score(path)
    if numba_loaded:
        skip_without_ahead_of_time_kernels()
    assert not numba_loaded
    just_in_time, numba_loaded = _score(path, LSADPHOTO_KERNELS="jit")
    assert numba_loaded
    assert ahead["n_sources"] >= 1 and math.isfinite(ahead["q"])
    for record in (ahead, just_in_time):
        record.pop("provenance")
    assert ahead == just_in_time


@pytest.mark.parametrize("method", ["fixed", "task", "mean", "contrast"])
def test_every_source_method_scores_without_numba(tmp_path, method):
    # Every kernel call of a score matches an ahead-of-time signature: the visual field's
    # float32 P and cos σ maps reach the selection rules' field sums too (the mean and
    # contrast rules once paired them with a float64 P and fell back to numba's JIT).
    cam = IdealFisheyeProjection("equidistant", 59.5, 59.5, 60.0, 180.0, 120, 120)
    window = dict(azimuth=(-20, 60), elevation=(-5, 50), luminance=(2500.0, 9000.0))
    L = window_scene(cam.directions(*cam.pixel_grid()), background=(40.0, 160.0),
                     windows=[window])
    path = tmp_path / "window.hdr"
    write_hdr(LuminanceMap(L, projection=cam, calibrated=True), path)
    record, numba_loaded = _score(path, "--source-method", method)
    if numba_loaded:
        skip_without_ahead_of_time_kernels()
    assert not numba_loaded
    assert record["settings"]["source_method"] == method


def test_a_further_view_from_a_store_renders_without_numba_and_as_just_in_time(tmp_path):
    # `lsadphoto render STORE` runs the solver's kernels (direct light, the cache's
    # interpolation, far node connections, luminous openings) from the ahead-of-time
    # extension: no numba import, no kernel loading (0.8 s of a 512² view's process), and
    # the map equal bit for bit to numba's just-in-time code.
    from lsadphoto.io import read_map
    from lsadphoto.solver import simulate
    from lsadphoto.solver.examples import canonical_room
    from lsadphoto.solver.integrators.surface_cache import build_surface_cache

    room = canonical_room(size=24)
    store = simulate(room, samples=2048, seed=5)
    store.surface_cache = build_surface_cache(store, nodes=256, seed=5)
    store.save(tmp_path / "room.lsad.npz")
    view = "-vta -vp 4 2 1.2 -vd -1 0 0 -vu 0 0 1 -vh 180 -vv 180"
    maps = []
    for name, env in (("aot", {}), ("jit", {"LSADPHOTO_KERNELS": "jit"})):
        out = tmp_path / f"{name}.exr"
        done = subprocess.run([sys.executable, "-c", SCRIPT, "render", str(tmp_path / "room.lsad.npz"),
                               "--view", view, "--size", "24x24", "-o", str(out), "--quiet"],
                              capture_output=True, text=True, env={**os.environ, **env})
        assert done.returncode == 0, done.stderr
        numba_loaded = json.loads(done.stderr.strip().splitlines()[-1])
        if name == "aot":
            if numba_loaded:
                skip_without_ahead_of_time_kernels()
            assert not numba_loaded
        maps.append(read_map(out))
    assert maps[0].provenance["estimator"].startswith("surface cache")
    assert np.array_equal(maps[0].luminance, maps[1].luminance, equal_nan=True)
    assert np.array_equal(maps[0].uncertainty, maps[1].uncertainty, equal_nan=True)


def test_arguments_outside_the_signatures_run_just_in_time():
    # quad_solid_angle_grid is compiled ahead of time for C-ordered float64 grids only. The
    # corners of a cube's face, seen from its centre, bound a sixth of the sphere: 2π/3 sr.
    corner = 1.0 / math.sqrt(3.0)
    grid = (np.array([[-corner, corner], [-corner, corner]]),
            np.array([[-corner, -corner], [corner, corner]]), np.full((2, 2), corner))
    spec = quad_solid_angle_grid._specs[0]
    out = np.empty((1, 1))
    assert _compiled._matches(spec, (*grid, out))
    for other in (grid[0].astype(np.float32), np.asfortranarray(grid[0]), grid[0].reshape(4)):
        assert not _compiled._matches(spec, (other, *grid[1:], out))
    quad_solid_angle_grid(*grid, out)
    assert out[0, 0] == pytest.approx(2.0 * math.pi / 3.0, rel=1e-15)  # rounding of a few operations
    # The float32 and Fortran-ordered calls go to numba and agree (float32 inputs: to its
    # rounding, 6e-8 relative).
    for other, rel in ((grid[0].astype(np.float32), 1e-6), (np.asfortranarray(grid[0]), 1e-15)):
        result = np.empty((1, 1))
        quad_solid_angle_grid(other, *grid[1:], result)
        assert result[0, 0] == pytest.approx(2.0 * math.pi / 3.0, rel=rel)


def test_tuple_arguments_match_only_their_declared_types():
    # The ahead-of-time functions read tuples of arrays (the luminaires' packed tables) without
    # checks: a tuple with another length, dtype or memory order must go to numba instead.
    spec = _compiled._argument_specs("void(Tuple((float64[::1], Tuple((int64[::1], boolean[::1])))), int64)")
    good = (np.zeros(3), (np.zeros(2, dtype=np.int64), np.zeros(2, dtype=bool)))
    assert _compiled._matches(spec, (good, 1))
    for bad in ((np.zeros(3, dtype=np.float32), good[1]), (np.zeros(3), (good[1][0].astype(np.int32), good[1][1])),
                (np.zeros(3),), (np.zeros((3, 2))[:, 0], good[1]), [np.zeros(3), good[1]]):
        assert not _compiled._matches(spec, (bad, 1))


def test_threads_that_load_the_library_at_once_all_get_it(monkeypatch):
    # A render's worker threads make the first kernel calls of a process together; one that
    # found the extension still loading once took it as empty and ran numba's JIT.
    import threading

    full = _compiled._library()
    if not full:
        skip_without_ahead_of_time_kernels()
    monkeypatch.setitem(_compiled._STATE, "library", None)
    barrier, got = threading.Barrier(4), []

    def load():
        barrier.wait()
        got.append(len(_compiled._library()))

    threads = [threading.Thread(target=load) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert got == [len(full)] * 4
