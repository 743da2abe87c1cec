"""The geometry maps kept on disk between processes (lsadphoto.geometry._map_cache).

The reference is the same maps computed in memory with the cache off: a map read from a
cache file must equal it bit for bit (no tolerance: it is the same bytes), whatever the
camera, frame and position-index method; a file of another key, a damaged file or one
that a crash may have left in part must be ignored and rebuilt, never read. The pictures
are small; the thresholds that keep small pictures out of the cache are lowered here.
"""

import json
import math
import os

import numpy as np
import pytest

from lsadphoto.datasets import disk_sources_scene
from lsadphoto.geometry import (
    IdealFisheyeProjection,
    ObserverFrame,
    OpenCVFisheyeProjection,
    clear_geometry_cache,
    visual_field,
)
from lsadphoto.geometry import _map_cache
from lsadphoto.geometry import field as field_module
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.metrics.score import score_map

CAMERAS = {
    "equidistant": IdealFisheyeProjection("equidistant", 101.0, 74.0, 70.0, 180.0, 203, 149),
    "equisolid-off-centre": IdealFisheyeProjection("equisolid", 60.2, 80.7, 95.0, 180.0, 203,
                                                   149),
    "opencv-fisheye": OpenCVFisheyeProjection(60.0, 60.0, 101.7, 73.2,
                                              (0.05, -0.01, 0.003, -0.0005), 203, 149),
}
TILTED = ObserverFrame((0.2, -0.1, 0.97), (0.0, -1.0, 0.0))


@pytest.fixture(autouse=True)
def _cache_here(monkeypatch, tmp_path):
    """Small pictures through the disk cache, in a folder of the test's own."""
    monkeypatch.setattr(field_module, "DIRECTION_MAP_MAX_PIXELS", 0)
    monkeypatch.setattr(_map_cache, "MIN_PIXELS", 0)
    monkeypatch.setenv("LSADPHOTO_GEOMETRY_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("LSADPHOTO_GEOMETRY_CACHE_MB", raising=False)
    clear_geometry_cache()
    yield
    _map_cache.wait_for_seals()
    clear_geometry_cache()


@pytest.fixture
def computed(monkeypatch):
    """Record whether each geometry-and-field call computed its maps or read them."""
    calls = []
    compute = field_module._compute_pixel_geometry

    def recorded(projection, field=None, allocate=field_module._allocate, stored=False):
        calls.append(not stored)
        return compute(projection, field, allocate, stored)

    monkeypatch.setattr(field_module, "_compute_pixel_geometry", recorded)
    return calls


def _maps(camera, frame=None, method="evalglare"):
    """(ω, validity, P, cos σ) of a fresh :func:`visual_field` call (memory cache cleared)."""
    clear_geometry_cache()
    vf = visual_field(camera, frame or ObserverFrame(), position_index_method=method)
    geometry = vf._inputs[0]
    return geometry.solid_angle, geometry.valid, vf.position_index, vf.cos_sigma


def _reference(monkeypatch, camera, frame=None, method="evalglare"):
    with monkeypatch.context() as m:
        m.setenv("LSADPHOTO_GEOMETRY_CACHE", "off")
        return tuple(np.array(a) for a in _maps(camera, frame, method))


def _assert_same_bits(maps, reference):
    for got, want in zip(maps, reference, strict=True):
        assert got.dtype == want.dtype and got.shape == want.shape
        assert got.tobytes() == want.tobytes()


def _files(folder):
    return sorted(p for p in folder.glob("*.maps"))


@pytest.mark.parametrize("name", sorted(CAMERAS))
@pytest.mark.parametrize("frame, method", [(None, "evalglare"), (TILTED, "evalglare"),
                                           (TILTED, "Guth"), (None, "Kim2011")])
def test_maps_read_from_the_cache_equal_the_computed_maps(name, frame, method, monkeypatch,
                                                          tmp_path, computed):
    camera = CAMERAS[name]
    reference = _reference(monkeypatch, camera, frame, method)
    computed.clear()
    cold = _maps(camera, frame, method)  # computed into a new cache file
    assert computed == [True]
    assert len(_files(tmp_path / "cache")) == 1
    _assert_same_bits(cold, reference)
    warm = _maps(camera, frame, method)  # read from it
    assert computed == [True, False]
    _assert_same_bits(warm, reference)
    assert all(not a.flags.writeable for a in warm)


def test_each_camera_frame_and_method_has_a_file_of_its_own(monkeypatch, tmp_path, computed):
    camera = CAMERAS["equidistant"]
    _maps(camera)
    _maps(camera, TILTED)
    _maps(camera, TILTED, "Guth")
    _maps(CAMERAS["opencv-fisheye"])
    assert computed == [True] * 4
    assert len(_files(tmp_path / "cache")) == 4
    _maps(camera, TILTED)
    assert computed[-1] is False
    # The header holds the whole key; the file name is its hash.
    head = _files(tmp_path / "cache")[0].read_bytes()[:_map_cache._HEADER_BYTES]
    length = int.from_bytes(head[8:16], "little")
    key = json.loads(json.loads(head[_map_cache._JSON_AT:_map_cache._JSON_AT + length])["key"])
    assert {"projection", "shape", "axes", "method", "version", "sources", "kernels"} <= set(key)


def test_the_cache_can_be_turned_off(monkeypatch, tmp_path, computed):
    monkeypatch.setenv("LSADPHOTO_GEOMETRY_CACHE", "off")
    _maps(CAMERAS["equidistant"])
    _maps(CAMERAS["equidistant"])
    assert computed == [True, True]
    assert not (tmp_path / "cache").exists()


def _damage(path, how, other):
    data = bytearray(path.read_bytes())
    layout, _ = _map_cache._layout((149, 203))
    offset = layout["solid_angle"][0]
    if how == "truncated":
        data = data[:-4096]
    elif how == "sampled page changed":
        data[offset + 1000] ^= 0x40  # the first page of ω is sampled
    elif how == "last page zeroed":
        end = layout["valid"][0] + 149 * 203
        data[end - 100:end] = bytes(100)
    elif how == "bad magic":
        data[:8] = b"NOTMAPS\x00"
    elif how == "header not JSON":
        data[_map_cache._JSON_AT:_map_cache._JSON_AT + 4] = b"\xff\xfe{["
    elif how == "another key":  # a whole file of another camera under this name
        data = bytearray(other.read_bytes())
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("how", ["truncated", "sampled page changed", "last page zeroed",
                                 "bad magic", "header not JSON", "another key"])
def test_a_damaged_file_is_ignored_and_rebuilt(how, monkeypatch, tmp_path, computed):
    camera = CAMERAS["equisolid-off-centre"]
    reference = _reference(monkeypatch, camera)
    _maps(CAMERAS["equidistant"])
    other = _files(tmp_path / "cache")[0]
    _maps(camera)
    (path,) = [p for p in _files(tmp_path / "cache") if p != other]
    _damage(path, how, other)
    computed.clear()
    _assert_same_bits(_maps(camera), reference)
    assert computed == [True]  # ignored, computed again ...
    _assert_same_bits(_maps(camera), reference)
    assert computed == [True, False]  # ... and the rebuilt file read


def _written_in_boot_1(monkeypatch, tmp_path, camera, computed):
    """The maps of ``camera`` computed without the cache, and its cache file written (not
    flushed) in a boot "boot-1"; ``computed`` cleared before the write."""
    reference = _reference(monkeypatch, camera)
    computed.clear()
    monkeypatch.setattr(_map_cache, "_boot_id", lambda: "boot-1")
    _maps(camera)
    (path,) = _files(tmp_path / "cache")
    return reference, path


def test_an_unflushed_file_of_an_earlier_boot_is_not_read(monkeypatch, tmp_path, computed):
    """A file renamed into place but never flushed may be in part after a crash: it is
    read only in the boot that wrote it, unless it was sealed (flushed)."""
    camera = CAMERAS["equidistant"]
    reference, path = _written_in_boot_1(monkeypatch, tmp_path, camera, computed)
    assert path.read_bytes()[_map_cache._SEAL_AT] == 0  # written unflushed
    _maps(camera)
    assert computed == [True, False]  # same boot: read
    monkeypatch.setattr(_map_cache, "_boot_id", lambda: "boot-2")
    _assert_same_bits(_maps(camera), reference)
    assert computed == [True, False, True]  # another boot, not sealed: rebuilt


def test_an_old_file_is_sealed_by_a_reader_and_then_read_after_a_reboot(monkeypatch, tmp_path,
                                                                        computed):
    camera = CAMERAS["equidistant"]
    reference, path = _written_in_boot_1(monkeypatch, tmp_path, camera, computed)
    _maps(camera)  # younger than SEAL_AFTER_SECONDS: left unsealed
    _map_cache.wait_for_seals()
    assert path.read_bytes()[_map_cache._SEAL_AT] == 0
    monkeypatch.setattr(_map_cache, "SEAL_AFTER_SECONDS", -1.0)
    _maps(camera)
    _map_cache.wait_for_seals()
    assert path.read_bytes()[_map_cache._SEAL_AT] == 1
    monkeypatch.setattr(_map_cache, "_boot_id", lambda: "boot-2")
    _assert_same_bits(_maps(camera), reference)
    assert computed == [True, False, False, False]


def test_no_boot_id_flushes_and_seals_before_the_rename(monkeypatch, tmp_path, computed):
    monkeypatch.setattr(_map_cache, "_boot_id", lambda: None)
    _maps(CAMERAS["equidistant"])
    (path,) = _files(tmp_path / "cache")
    assert path.read_bytes()[_map_cache._SEAL_AT] == 1
    _maps(CAMERAS["equidistant"])
    assert computed == [True, False]


def test_an_unwritable_cache_folder_falls_back_to_memory(monkeypatch, tmp_path, computed):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("LSADPHOTO_GEOMETRY_CACHE", str(blocker / "cache"))
    camera = CAMERAS["opencv-fisheye"]
    reference = _reference(monkeypatch, camera)
    computed.clear()
    _assert_same_bits(_maps(camera), reference)
    assert computed == [True]
    assert blocker.read_text() == "not a folder"


def test_the_folder_keeps_to_its_size_bound(monkeypatch, tmp_path):
    folder = tmp_path / "cache"
    _maps(CAMERAS["equidistant"])
    (first,) = _files(folder)
    size = first.stat().st_size
    os.utime(first, (1e9, 1e9))  # long unused
    stale = folder / ".left-over.abcd.tmp.maps"
    stale.write_bytes(b"x")
    os.utime(stale, (1e9, 1e9))
    monkeypatch.setenv("LSADPHOTO_GEOMETRY_CACHE_MB", str(1.5 * size / (1 << 20)))
    _maps(CAMERAS["opencv-fisheye"])  # two files exceed the bound: the older one goes
    (kept,) = _files(folder)
    assert kept != first
    assert not stale.exists()
    _maps(CAMERAS["equisolid-off-centre"])
    assert _files(folder) != [kept] and len(_files(folder)) == 1


def test_score_records_equal_with_the_cache_cold_warm_and_off(monkeypatch):
    cam = IdealFisheyeProjection("equidistant", 149.5, 149.5, 150.0, 180.0, 300, 300)
    up = np.array([0.0, -math.sin(0.4), math.cos(0.4)])
    L = disk_sources_scene(cam.directions(*cam.pixel_grid()), background=120.0,
                           sources=[(up, 0.06, 30000.0), (np.array([0.5, 0.1, 0.86]), 0.1,
                                                          8000.0)])
    lmap = LuminanceMap(L.astype(np.float32), projection=cam, calibrated=True)

    def record():
        clear_geometry_cache()
        out = score_map(lmap, sweep=[1, 5, 20])
        _map_cache.wait_for_seals()
        out = out.to_dict()
        out.pop("provenance")
        return json.dumps(out, sort_keys=True)

    cold, warm = record(), record()
    monkeypatch.setenv("LSADPHOTO_GEOMETRY_CACHE", "off")
    assert cold == warm == record()
