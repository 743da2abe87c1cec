"""Directions computed from the fisheye models' parameters where the metrics need them, against
the map-based path as the reference (docs/performance.md, "Directions from the camera model").

For the ideal and the OpenCV fisheye, :func:`pixel_geometry` stores no direction map: the
visual-field kernel, Q, the grouping and the sources' position pixels compute directions from
the model (``PixelGeometry.directions_at``, ``stencil_directions``). The
reference is the same geometry with its map made (``geometry.directions``, which every
consumer then reads, as before this change), and a geometry of the map alone (``model=None``):
each value is the same function of the pixel's coordinates, so the results are equal bit for
bit — no tolerance. The map itself is tested against the projections' own methods in
tests/test_geometry_field.py.
"""

import math

import numpy as np
import pytest

from lsadphoto.datasets import disk_sources_scene, window_scene
from lsadphoto.geometry import (
    IdealFisheyeProjection,
    ObserverFrame,
    OpenCVFisheyeProjection,
    clear_geometry_cache,
    pixel_geometry,
    visual_field,
)
from lsadphoto.geometry import field as field_module
from lsadphoto.geometry.field import PixelGeometry
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.metrics.grouping import group_sources_evalglare
from lsadphoto.metrics.quality import gradient_components, q_Budak2021
from lsadphoto.metrics.score import score_map

CAMERAS = {
    "equidistant": IdealFisheyeProjection("equidistant", 101.3, 72.6, 70.0, 180.0, 203, 149),
    "equisolid-cut": IdealFisheyeProjection("equisolid", 60.2, 80.7, 95.0, 180.0, 203, 149),
    "opencv-fisheye": OpenCVFisheyeProjection(60.0, 60.0, 101.7, 73.2,
                                              (0.05, -0.01, 0.003, -0.0005), 203, 149),
}


@pytest.fixture(autouse=True)
def _fresh_cache(monkeypatch):
    # These pictures are small: without this their geometry would store the map (it does up
    # to DIRECTION_MAP_MAX_PIXELS), and nothing below would compute directions from a model.
    monkeypatch.setattr(field_module, "DIRECTION_MAP_MAX_PIXELS", 0)
    clear_geometry_cache()
    yield
    clear_geometry_cache()


def test_small_pictures_store_the_map_and_large_ones_do_not(monkeypatch):
    cam = CAMERAS["equidistant"]
    monkeypatch.setattr(field_module, "DIRECTION_MAP_MAX_PIXELS", cam.shape[0] * cam.shape[1])
    stored = pixel_geometry(cam)
    assert stored._directions is not None
    clear_geometry_cache()
    monkeypatch.setattr(field_module, "DIRECTION_MAP_MAX_PIXELS", cam.shape[0] * cam.shape[1] - 1)
    computed = pixel_geometry(cam)
    assert computed._directions is None
    np.testing.assert_array_equal(computed.directions, stored.directions)
    np.testing.assert_array_equal(computed.solid_angle, stored.solid_angle)
    np.testing.assert_array_equal(computed.valid, stored.valid)


def _map_only(geometry):
    """The same geometry as a stored map without a model: the map-based path."""
    return PixelGeometry(geometry.directions, geometry.solid_angle, geometry.valid)


@pytest.mark.parametrize("name", CAMERAS)
def test_directions_from_the_model_equal_the_map(name):
    cam = CAMERAS[name]
    geometry = pixel_geometry(cam)
    assert geometry.model is not None and geometry._directions is None  # no map stored
    rng = np.random.default_rng(3)
    rows, cols = cam.shape
    r, c = rng.integers(0, rows, 500), rng.integers(0, cols, 500)
    at = geometry.directions_at(r, c)
    # Row segments (runs), some crossing the image circle, one after the other.
    run_rows = rng.integers(0, rows, 40)
    run_cols = rng.integers(0, cols - 30, 40)
    lengths = rng.integers(1, 30, 40)
    runs = geometry.directions_of_runs(run_rows, run_cols, lengths)
    sample = rng.integers(1, rows - 1, 300) * cols + rng.integers(1, cols - 1, 300)  # interior
    flat, i, step = geometry.stencil_directions(sample)  # 5 per stencil < the image: no map
    assert geometry._directions is None and step == 2
    full = geometry.directions  # the map, made now: the reference
    np.testing.assert_array_equal(at, full[r, c])
    run_pixels = [(i, j) for i, j0, n in zip(run_rows, run_cols, lengths, strict=True)
                  for j in range(j0, j0 + n)]
    expected = np.array([full[i, j] for i, j in run_pixels])
    np.testing.assert_array_equal(runs, expected)
    np.testing.assert_array_equal(geometry.directions_of_runs(run_rows, run_cols, lengths),
                                  expected)  # from the map, made now
    reference = full.reshape(-1, 3)
    for offset, image_offset in ((-1, -1), (1, 1), (-step, -cols), (step, cols)):
        np.testing.assert_array_equal(flat[i + offset], reference[sample + image_offset])
    # With the map made, the stencil is the map itself.
    flat, i, step = geometry.stencil_directions(sample)
    assert flat.base is full or np.shares_memory(flat, full)
    assert step == cols and np.array_equal(i, sample)


@pytest.mark.parametrize("name", CAMERAS)
@pytest.mark.parametrize("method", ["evalglare", "Guth", "Kim2011"])
def test_visual_field_from_the_model_equals_the_map_path(name, method):
    cam = CAMERAS[name]
    frame = ObserverFrame((0.1, -0.2, 0.97), (0.0, -1.0, 0.0))
    field = visual_field(cam, frame, position_index_method=method)
    assert pixel_geometry(cam)._directions is None
    from lsadphoto.geometry.field import VisualField

    reference = VisualField(_map_only(pixel_geometry(cam)), frame.axes(), method)
    for name_ in ("position_index", "cos_sigma", "sigma", "tau"):
        np.testing.assert_array_equal(getattr(field, name_), getattr(reference, name_))


def _window_luminance(cam):
    d = cam.directions(*cam.pixel_grid())
    window = dict(azimuth=(-20, 80), elevation=(-10, 60), luminance=(2500.0, 12000.0),
                  side_gradient=0.5, mullions=(30.0,), mullion_width=3.0)
    return window_scene(d, background=(40.0, 160.0), windows=[window])


@pytest.mark.parametrize("name", CAMERAS)
def test_grouping_and_q_with_the_geometry_equal_the_map_path(name):
    cam = CAMERAS[name]
    geometry = pixel_geometry(cam)
    luminance = np.where(geometry.valid, _window_luminance(cam), np.nan)
    omega = geometry.solid_angle
    mask = geometry.valid & (luminance > 2000.0)
    sources, labels = group_sources_evalglare(luminance, geometry, omega, mask)
    q = q_Budak2021(luminance, geometry, omega, None, size_arcmin=40.0, blur="none",
                    valid=geometry.valid)
    assert geometry._directions is None or 5 * q.settings["n_evaluated"] >= mask.size
    reference = _map_only(geometry)
    sources_ref, labels_ref = group_sources_evalglare(luminance, reference.directions, omega, mask)
    q_ref = q_Budak2021(luminance, reference.directions, omega, None, size_arcmin=40.0,
                        blur="none", valid=geometry.valid)
    assert len(sources) > 0 and sources == sources_ref
    np.testing.assert_array_equal(labels, labels_ref)
    assert math.isfinite(q.q) and q.q == q_ref.q
    np.testing.assert_array_equal(q.contrast, q_ref.contrast)


def test_gradient_components_from_the_model_equal_the_map_path():
    # A few stencils (fewer than a fifth of the pixels): computed from the model, no map.
    cam = CAMERAS["equidistant"]
    geometry = pixel_geometry(cam)
    filled = np.where(geometry.valid, _window_luminance(cam), 0.0).astype(np.float32)
    index = np.flatnonzero(geometry.valid[1:-1, 1:-1].ravel())[::13]
    rows, cols = cam.shape
    index = (index // (cols - 2) + 1) * cols + index % (cols - 2) + 1
    a, b = gradient_components(filled, geometry, index, sigma_px=0.0)
    assert geometry._directions is None
    a_ref, b_ref = gradient_components(filled, _map_only(geometry).directions, index, sigma_px=0.0)
    np.testing.assert_array_equal(a, a_ref)
    np.testing.assert_array_equal(b, b_ref)


def test_q_on_a_large_picture_computes_only_its_candidates_stencils():
    # Above 2²⁰ px Q screens its pixels, so only the candidates' stencils are computed from
    # the model (no map of the 1.2 MP picture); the same Q and contrasts as from the map.
    cam = IdealFisheyeProjection("equidistant", 549.5, 549.5, 550.0, 180.0, 1100, 1100)
    geometry = pixel_geometry(cam)
    luminance = np.where(geometry.valid, _window_luminance(cam), np.nan)
    q = q_Budak2021(luminance, geometry, geometry.solid_angle, None, valid=geometry.valid)
    assert geometry._directions is None
    q_ref = q_Budak2021(luminance, _map_only(geometry).directions, geometry.solid_angle, None,
                        valid=geometry.valid)
    assert math.isfinite(q.q) and q.q == q_ref.q
    np.testing.assert_array_equal(q.contrast, q_ref.contrast)


@pytest.mark.parametrize("options", [{}, {"source_position": "direction"},
                                     {"band_deg": 20.0, "task_direction": (0.2, -0.1, 0.97)}])
def test_score_without_the_map_equals_the_score_with_it(options):
    cam = IdealFisheyeProjection("equidistant", 99.5, 99.5, 100.0, 180.0, 200, 200)
    up = np.array([0.0, -math.sin(0.5), math.cos(0.5)])
    L = disk_sources_scene(cam.directions(*cam.pixel_grid()), background=90.0,
                           sources=[(up, 0.08, 25000.0), ((0.5, 0.1, 0.86), 0.05, 8000.0)])
    lmap = LuminanceMap(L, projection=cam, calibrated=True)
    without = score_map(lmap, **options).to_dict()
    clear_geometry_cache()
    made = pixel_geometry(cam).directions  # every consumer now reads the map: the old path
    assert made is pixel_geometry(cam).directions
    with_map = score_map(lmap, **options).to_dict()
    without.pop("provenance"), with_map.pop("provenance")
    assert without["n_sources"] == 2 and without == with_map


@pytest.mark.parametrize("name", CAMERAS)
@pytest.mark.parametrize("method", ["evalglare", "Guth", "Kim2011"])
def test_geometry_and_field_in_one_pass_equal_the_map_path(name, method):
    # With neither cached, visual_field computes the geometry and its own maps in one pass of
    # fisheye_geometry (each centre direction once); the reference is the separate passes
    # from a stored map.
    cam = CAMERAS[name]
    frame = ObserverFrame((0.1, -0.2, 0.97), (0.0, -1.0, 0.0))
    field = visual_field(cam, frame, position_index_method=method)
    geometry = pixel_geometry(cam)
    assert field._inputs[0] is geometry and geometry._directions is None
    from lsadphoto.geometry.field import VisualField

    clear_geometry_cache()
    separate = pixel_geometry(cam)
    reference = VisualField(_map_only(separate), frame.axes(), method)
    np.testing.assert_array_equal(geometry.solid_angle, separate.solid_angle)
    np.testing.assert_array_equal(geometry.valid, separate.valid)
    for name_ in ("position_index", "cos_sigma", "sigma", "tau"):
        np.testing.assert_array_equal(getattr(field, name_), getattr(reference, name_))


def test_q_refuses_a_geometry_of_another_shape():
    from lsadphoto.errors import BadInputError

    geometry = pixel_geometry(CAMERAS["equidistant"])
    with pytest.raises(BadInputError, match="pixel geometry has shape"):
        q_Budak2021(np.ones((10, 10)), geometry, np.ones((10, 10)), None)
