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
import math
import os
import subprocess
import sys

import numpy as np

from lsadphoto import _compiled
from lsadphoto.datasets import window_scene
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.io import write_hdr
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.metrics.quality import _weights

from .conftest import skip_without_ahead_of_time_kernels

SCRIPT = """
import json, sys
from lsadphoto.cli import main
code = main()
print(json.dumps("numba" in sys.modules), file=sys.stderr)
sys.exit(code)
"""


def _score(path, **env):
    done = subprocess.run([sys.executable, "-c", SCRIPT, "score", str(path), "--json"],
                          capture_output=True, text=True, env={**os.environ, **env})
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout), json.loads(done.stderr.strip().splitlines()[-1])


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


def test_arguments_outside_the_signatures_run_just_in_time():
    # _weights is compiled ahead of time for float32 P only: P^(-m) elementwise.
    P = np.array([1.0, 2.0, 4.0], dtype=np.float32)
    assert _compiled._matches(_weights._specs[0], (P, 1.0))
    for other in (P.astype(np.float64), P[::2], P.reshape(1, 3)):
        assert not _compiled._matches(_weights._specs[0], (other, 1.0))
    assert not _compiled._matches(_weights._specs[0], (P, 1))  # an int where float64 is compiled
    # P^(-1) exactly; the float64 and strided calls go to numba and agree with numpy.
    np.testing.assert_array_equal(_weights(P, 1.0), np.float32([1.0, 0.5, 0.25]))
    np.testing.assert_array_equal(_weights(P.astype(np.float64), 1.0), [1.0, 0.5, 0.25])
    np.testing.assert_array_equal(_weights(P[::2], 1.0), np.float32([1.0, 0.25]))
