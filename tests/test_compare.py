"""Model-vs-photo comparison: ratios, regions, metric agreement and combined uncertainty.

References: exact scalings (a model that is the photo × k has ratio k everywhere and UGR,
E_v shifted by 8·log10 k and ×k), and GUM's quadrature combination.
"""

import math

import numpy as np
import pytest

from lsadphoto.compare import compare_maps, model_scale_uncertainty
from lsadphoto.datasets import disk_sources_scene
from lsadphoto.errors import BadInputError
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.luminance_map import LuminanceMap


@pytest.fixture(scope="module")
def photo():
    cam = IdealFisheyeProjection("equidistant", 99.5, 99.5, 100.0, 180.0, 200, 200)
    d = cam.directions(*cam.pixel_grid())
    up = np.array([0.0, -math.sin(0.4), math.cos(0.4)])
    L = disk_sources_scene(d, background=100.0, sources=[(up, 0.1, 20000.0)])
    return LuminanceMap(L, projection=cam, calibrated=True, calibration_uncertainty=0.02)


def test_identical_maps_agree_exactly(photo):
    result = compare_maps(photo, photo)
    assert result.field["mean_ratio"] == pytest.approx(1.0, abs=1e-12)
    assert result.field["within_10_percent"] == 1.0
    for key, entry in result.metrics.items():
        if entry["photo"] is not None:
            assert entry["difference"] == pytest.approx(0.0, abs=1e-9), key


def test_scaled_model_shows_the_scale_everywhere(photo):
    k = 1.1
    model = LuminanceMap(photo.luminance * k, projection=photo.projection,
                         uncertainty=0.01 * photo.luminance * k)
    result = compare_maps(photo, model)
    assert result.field["median_ratio"] == pytest.approx(k, rel=1e-6)  # float32 storage
    assert all(b["mean_ratio"] is None or b["mean_ratio"] == pytest.approx(k, rel=1e-6)
               for b in result.regions["blocks"])
    m = result.metrics
    # Sources far above the 2000 cd/m² threshold: same pixels, UGR shifts by 8·log10 k.
    assert m["ugr_grouped"]["difference"] == pytest.approx(8 * math.log10(k), abs=1e-5)
    assert m["vertical_illuminance"]["model"] / m["vertical_illuminance"]["photo"] == \
        pytest.approx(k, rel=1e-6)
    # Fully correlated bound of 1 % per-pixel errors: 1 % of scale.
    assert result.uncertainty["model_monte_carlo_relative"] == pytest.approx(0.01, rel=1e-6)
    expected = math.hypot(4 * math.log10(1.02 / 0.98), 4 * math.log10(1.01 / 0.99))
    assert m["ugr_grouped"]["combined_uncertainty"] == pytest.approx(expected, rel=1e-6)
    assert m["ugr_grouped"]["agree_within_2u"] is False


def test_different_geometry_is_refused(photo):
    other = IdealFisheyeProjection("equisolid", 99.5, 99.5, 100.0, 180.0, 200, 200)
    with pytest.raises(BadInputError, match="different camera geometries"):
        compare_maps(photo, LuminanceMap(photo.luminance, projection=other))


def test_model_scale_uncertainty_without_errors_is_zero(photo):
    assert model_scale_uncertainty(LuminanceMap(photo.luminance, projection=photo.projection)) == 0


def test_compare_cli_json_png_and_bad_input(tmp_path, photo):
    import json
    import subprocess
    import sys

    from lsadphoto.io import write_exr

    a, b = tmp_path / "photo.exr", tmp_path / "model.exr"
    write_exr(photo, a)
    write_exr(LuminanceMap(photo.luminance * 0.9, projection=photo.projection), b)

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "lsadphoto.cli", "compare", *map(str, args)],
                              capture_output=True, text=True)

    proc = cli(a, b, "--json", "--ratio-png", tmp_path / "r.png")
    assert proc.returncode == 0, proc.stderr
    record = json.loads(proc.stdout)
    assert record["field"]["median_ratio"] == pytest.approx(0.9, rel=1e-6)
    assert (tmp_path / "r.png").read_bytes()[:4] == b"\x89PNG"
    other = tmp_path / "other.exr"
    write_exr(LuminanceMap(photo.luminance[:100], projection=IdealFisheyeProjection(
        "equidistant", 99.5, 49.5, 100.0, 180.0, 200, 100)), other)
    proc = cli(a, other)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1
