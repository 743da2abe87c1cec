"""What a ``lsadphoto score`` process loads: only what scoring needs.

A user waits for the whole process; a heavy library imported but unused costs every run
(docs/performance.md, "Latency of a whole score process"). The process below is the console
script's (``main()`` reading ``sys.argv``), on a Radiance fisheye picture, and must not import
any module that scoring does not use. Before the package's names were imported lazily it
loaded every module listed here.
"""

import json
import math
import os
import subprocess
import sys

import numpy as np

from lsadphoto.datasets import disk_sources_scene
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.io import write_hdr
from lsadphoto.luminance_map import LuminanceMap

from .conftest import skip_without_ahead_of_time_kernels

#: Modules a score run without figure options has no use for: numba and LLVM (the kernels
#: run from their ahead-of-time compilation, lsadphoto._compiled), RAW decoding and its
#: metadata readers, OpenEXR (the input is HDR), plotting, SciPy (numba loaded
#: scipy.linalg for its BLAS bindings), survey executors, and the package's own stages that
#: scoring does not touch, nor what only other camera models use (thread pools, numpy's
#: polynomials: 7 and 5 ms to import), nor OpenCV (0.03–0.07 s; Q has its own filters).
UNUSED = ["cv2", "concurrent.futures", "numpy.polynomial", "numba", "llvmlite", "scipy", "rawpy", "tifffile", "exifread", "OpenEXR",
          "matplotlib", "PIL", "colour", "dask", "pandas", "lsadphoto.raw.decode",
          "lsadphoto.calibrate", "lsadphoto.report", "lsadphoto.solver", "lsadphoto.study",
          "lsadphoto.survey", "lsadphoto.luminance", "lsadphoto.datasets", "lsadphoto.io.exr"]

#: The thread count at the end of a score process. The kernels' threads (``run_blocks``,
#: ``background``) are joined before ``score`` returns, but a joined thread may still be
#: leaving the kernel's task list for a moment, so the count is read once it has settled
#: (within 2 s); a thread pool (OpenBLAS's) stays and is still counted.
SCRIPT = """
import json, os, sys, time
from lsadphoto.cli import main
code = main()
def count():
    return len(os.listdir("/proc/self/task")) if os.path.isdir("/proc/self/task") else None
deadline = time.monotonic() + 2.0
while (count() or 1) > 1 and time.monotonic() < deadline:
    time.sleep(0.01)
print(json.dumps([sorted(sys.modules), count()]), file=sys.stderr)
sys.exit(code)
"""
#: Variables that choose OpenBLAS's number of threads (a score process sets one where none is).
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")


def test_score_process_imports_only_what_it_uses(tmp_path):
    cam = IdealFisheyeProjection("equidistant", 99.5, 99.5, 100.0, 180.0, 200, 200)
    up = np.array([0.0, -math.sin(0.5), math.cos(0.5)])
    L = disk_sources_scene(cam.directions(*cam.pixel_grid()), background=90.0,
                           sources=[(up, 0.08, 25000.0)])
    path = tmp_path / "view.hdr"
    write_hdr(LuminanceMap(L, projection=cam, calibrated=True), path)
    env = {k: v for k, v in os.environ.items() if k not in BLAS_THREADS}
    done = subprocess.run([sys.executable, "-c", SCRIPT, "score", str(path), "--json"],
                          capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["n_sources"] == 1  # it did score the picture
    modules, threads = json.loads(done.stderr.strip().splitlines()[-1])
    loaded = set(modules)
    assert "lsadphoto.metrics.score" in loaded
    if "numba" in loaded:
        skip_without_ahead_of_time_kernels()
    unused = [m for m in UNUSED if m in loaded]
    assert unused == [], f"lsadphoto score imported {unused}"
    # No idle thread pools: OpenBLAS started none (it would start one per core with numpy).
    assert threads in (None, 1), f"lsadphoto score ended with {threads} threads"


HUGEPAGE_SCRIPT = """
import sys
from lsadphoto.cli import main
import numpy._core.multiarray as multiarray
try:
    code = main()
finally:
    print(multiarray._get_madvise_hugepage(), file=sys.stderr)
sys.exit(code)
"""


def test_score_process_asks_for_small_pages_unless_told(tmp_path):
    """A score process of a large file turns numpy's huge-page advice off (fresh huge pages
    cost a virtual machine several times what small ones do, docs/performance.md "Small
    pages"); a small picture, a user's own NUMPY_MADVISE_HUGEPAGE and other commands keep
    numpy's default."""
    from lsadphoto.cli import _SMALL_PAGES_MIN_BYTES, _largest_file

    cam = IdealFisheyeProjection("equidistant", 19.5, 19.5, 20.0, 180.0, 40, 40)
    L = disk_sources_scene(cam.directions(*cam.pixel_grid()), background=90.0, sources=[])
    small = tmp_path / "view.hdr"
    write_hdr(LuminanceMap(L, projection=cam, calibrated=True), small)
    large = tmp_path / "large.hdr"  # not a picture: the command fails after the preamble
    large.write_bytes(bytes(_SMALL_PAGES_MIN_BYTES))
    base = {k: v for k, v in os.environ.items() if k != "NUMPY_MADVISE_HUGEPAGE"}
    for env, command, code, advised in [
            (base, ["score", str(large), "--json"], 2, "False"),
            (base, ["score", str(small), "--json"], 0, "True"),
            ({**base, "NUMPY_MADVISE_HUGEPAGE": "1"}, ["score", str(large), "--json"], 2, "True"),
            (base, ["calibrate", str(large)], 2, "True")]:
        done = subprocess.run([sys.executable, "-c", HUGEPAGE_SCRIPT, *command],
                              check=False, capture_output=True, text=True, env=env)
        assert done.returncode == code, done.stderr
        assert done.stderr.strip().splitlines()[-1] == advised, (command, done.stderr)
    assert _largest_file([str(small), str(large), str(tmp_path), "no-such-file"]) == \
        _SMALL_PAGES_MIN_BYTES
    assert _largest_file([]) == 0
