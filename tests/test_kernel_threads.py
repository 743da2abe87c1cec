"""Kernels shared out among threads (lsadphoto._compiled.run_blocks) give what one thread gives.

The ahead-of-time kernels release the GIL, so a caller can run blocks of rows (the fisheye
geometry, the field luminance, Q's field pass, its derivatives and screen, its contrast
map, the RGBE scanlines), blocks of fixed chunks (the field sums, the evaluated field) or
independent calls (Q's two derivative filters, the statistics' stripes) on threads at once.
Every value is a function of its own pixel's inputs or a sum over a fixed chunk or stripe
(the kernels' docstrings), so the maps and the score must be equal bit for bit whatever the
number of threads. The reference is one
thread (``LSADPHOTO_THREADS=1``), which runs the same kernels as before this was added.
"""

import numpy as np
import pytest

from lsadphoto import _compiled
from lsadphoto.datasets import window_scene
from lsadphoto.geometry import (
    IdealFisheyeProjection,
    ObserverFrame,
    OpenCVFisheyeProjection,
    _kernels,
    clear_geometry_cache,
)
from lsadphoto.geometry import field as field_module
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.metrics.score import score_map

from .conftest import skip_without_ahead_of_time_kernels

CAMERAS = {
    "equidistant": IdealFisheyeProjection("equidistant", 101.3, 72.6, 70.0, 180.0, 203, 149),
    "opencv-fisheye": OpenCVFisheyeProjection(60.0, 60.0, 101.7, 73.2,
                                              (0.05, -0.01, 0.003, -0.0005), 203, 149),
}


def test_row_blocks_cover_the_rows_in_multiples():
    assert _compiled.row_blocks(10, 3, 4) == [(0, 4), (4, 8), (8, 10)]
    assert _compiled.row_blocks(10, 1) == [(0, 10)]
    assert _compiled.row_blocks(5, 8) == [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5)]
    assert _compiled.row_blocks(0, 2) == []
    for rows, parts, multiple in ((1000, 2, 7), (999, 3, 64), (17, 2, 100)):
        blocks = _compiled.row_blocks(rows, parts, multiple)
        assert len(blocks) <= parts
        assert [b[0] for b in blocks[1:]] == [b[1] for b in blocks[:-1]]
        assert blocks[0][0] == 0 and blocks[-1][1] == rows
        assert all(b[0] % multiple == 0 for b in blocks)


def test_run_blocks_keeps_the_order_and_raises_a_task_error(monkeypatch):
    monkeypatch.setenv("LSADPHOTO_THREADS", "3")
    assert _compiled.threads() == 3
    blocks = [(k, k + 1) for k in range(20)]
    assert _compiled.run_blocks(lambda a, b: a * b, blocks) == [k * (k + 1) for k in range(20)]

    def fails(a, b):
        if a == 7:
            raise ValueError("block 7")
        return a

    with pytest.raises(ValueError, match="block 7"):
        _compiled.run_blocks(fails, blocks)
    monkeypatch.setenv("LSADPHOTO_THREADS", "1")
    assert _compiled.run_blocks(lambda a, b: a, blocks) == list(range(20))


@pytest.mark.parametrize("threads", ["1", "2"])
def test_background_gives_the_value_or_raises_the_error(monkeypatch, threads):
    # With 2 threads the task runs at once on its own thread (the ahead-of-time kernels
    # loaded), with 1 in result(): the same value, the same exception, raised by result().
    import threading

    monkeypatch.setenv("LSADPHOTO_THREADS", threads)
    seen = []
    pending = _compiled.background(lambda: seen.append(threading.current_thread()) or 42)
    assert pending.result() == 42 and pending.result() == 42 and len(seen) == 1

    def fails():
        raise ValueError("in the task")

    pending = _compiled.background(fails)
    with pytest.raises(ValueError, match="in the task"):
        pending.result()


@pytest.fixture(autouse=True)
def _ahead_of_time():
    # Only the ahead-of-time code is shared out among threads (Kernel.threads_for); without
    # it these tests would compare one thread with itself.
    skip_without_ahead_of_time_kernels()


def _geometry_and_field(cam, threads, monkeypatch):
    monkeypatch.setenv("LSADPHOTO_THREADS", str(threads))
    axes = ObserverFrame((0.1, -0.2, 0.97), (0.0, -1.0, 0.0)).axes()
    geometry, (p, cos_sigma) = field_module._compute_pixel_geometry(cam, (axes, "evalglare"))
    assert _kernels.fisheye_geometry._compiled  # the ahead-of-time code ran it
    return geometry, p, cos_sigma


@pytest.mark.parametrize("name", CAMERAS)
@pytest.mark.parametrize("store", [True, False])
def test_the_geometry_on_threads_equals_one_thread(name, store, monkeypatch):
    cam = CAMERAS[name]
    # Bands of 5 rows, so that each thread gets several bands and a block starts mid-image.
    monkeypatch.setattr(field_module, "_KERNEL_BLOCK_PIXELS", 5 * cam.shape[1])
    monkeypatch.setattr(field_module, "DIRECTION_MAP_MAX_PIXELS", 1 << 30 if store else 0)
    one = _geometry_and_field(cam, 1, monkeypatch)
    for threads in (2, 3):
        other = _geometry_and_field(cam, threads, monkeypatch)
        for a, b in zip(one[1:], other[1:], strict=True):
            np.testing.assert_array_equal(a, b)
        for key in ("solid_angle", "valid", "directions"):
            np.testing.assert_array_equal(getattr(one[0], key), getattr(other[0], key))


def test_a_score_on_threads_equals_one_thread(monkeypatch):
    # A daylit window (grouping, Q with its two derivative filters, statistics) on a picture
    # above DIRECTION_MAP_MAX_PIXELS (lowered here): the one-pass geometry and field.
    cam = IdealFisheyeProjection("equidistant", 149.5, 149.5, 150.0, 180.0, 300, 300)
    window = {"azimuth": (-20, 60), "elevation": (-5, 50), "luminance": (2500.0, 9000.0),
              "side_gradient": 0.5, "mullions": (20.0,), "mullion_width": 3.0}
    L = window_scene(cam.directions(*cam.pixel_grid()), background=(40.0, 160.0),
                     windows=[window])
    lmap = LuminanceMap(L.astype(np.float32), projection=cam, calibrated=True)
    monkeypatch.setattr(field_module, "DIRECTION_MAP_MAX_PIXELS", 0)
    monkeypatch.setattr(field_module, "_KERNEL_BLOCK_PIXELS", 7 * 300)
    records = []
    for threads in (1, 2, 3):
        monkeypatch.setenv("LSADPHOTO_THREADS", str(threads))
        clear_geometry_cache()
        record = score_map(lmap).to_dict()
        record.pop("provenance")
        records.append(record)
    clear_geometry_cache()
    assert records[0]["n_sources"] >= 1 and records[0]["q"] is not None
    assert records[0] == records[1] == records[2]
