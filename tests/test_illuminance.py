"""Illuminance-meter calibration and cross-check of a hemispherical map (analytic scene)."""

import math
import warnings

import numpy as np
import pytest

from lsadphoto.calibrate import CameraProfile, SpotReading
from lsadphoto.calibrate.illuminance import IlluminanceReading
from lsadphoto.datasets import SyntheticCamera, write_dng
from lsadphoto.errors import BadInputError, MetadataWarning
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.luminance import luminance_from_raw

SIZE, RADIUS, L0 = 400, 190.0, 100.0
#: L = L0·(1 + cos θ) over the hemisphere: E = ∫ L cos θ dω = L0·(π + 2π/3) [lx] (analytic).
E_TRUE = L0 * (math.pi + 2 * math.pi / 3)
#: Noise-free map: the pixel sum misses < 1e-4 of the hemisphere (centre rule), and the 2 × 2
#: superpixels at the circle's rim mix inside and outside values where cos θ ≈ 0: 0.5 %.
E_RTOL = 0.005


@pytest.fixture(scope="module")
def fisheye_shot(tmp_path_factory):
    camera = SyntheticCamera(width=SIZE, height=SIZE, sensor_width=10.0, sensor_height=10.0)
    fisheye = IdealFisheyeProjection("equidistant", (SIZE - 1) / 2, (SIZE - 1) / 2, RADIUS, 180.0, SIZE, SIZE)
    rows, cols = fisheye.pixel_grid()
    d = fisheye.directions(rows.astype(float), cols.astype(float))
    luminance = np.where(np.isfinite(d[..., 2]), L0 * (1 + np.nan_to_num(d[..., 2])), 0.0)
    raw = camera.expose(luminance, exposure_time=1 / 1000, f_number=4.0, iso=100, noise=False)
    path = write_dng(tmp_path_factory.mktemp("fisheye") / "fisheye.dng", raw, camera, exposure_time=1 / 1000,
                     f_number=4.0, iso=100)
    profile = CameraProfile(id="fisheye", camera="lsadphoto synthetic camera", width=SIZE, height=SIZE,
                            lens_projection=fisheye)
    return path, profile, luminance


def test_illuminance_calibrates_hemispherical_map(fisheye_shot):
    path, profile, luminance = fisheye_shot
    result = luminance_from_raw([path], profile=profile, illuminance=IlluminanceReading(E_TRUE))
    assert result.summary["calibration_method"] == "illuminance" and result.map.calibrated
    truth = luminance.reshape(SIZE // 2, 2, SIZE // 2, 2).mean(axis=(1, 3))
    inner = truth > 1.2 * L0  # θ < 78°: away from the rim superpixels
    np.testing.assert_allclose(result.map.luminance[inner], truth[inner], rtol=E_RTOL)
    # The factor's uncertainty is the meter's combined with the map's noise model over the
    # hemisphere (tiny here: 2e-6 of 4.3 %).
    meter = 0.075 / math.sqrt(3)
    assert meter < result.summary["calibration_uncertainty"] < meter * (1 + 1e-3)


@pytest.mark.parametrize("scale,agrees", [(1.0, True), (1.3, False)])
def test_illuminance_cross_checks_spots(fisheye_shot, scale, agrees):
    """A spot reading consistent with the meter passes; one 30 % high warns with both numbers."""
    path, profile, luminance = fisheye_shot
    centre = SIZE // 2
    spot = SpotReading(row=centre, col=centre, luminance=scale * float(luminance[centre, centre]))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = luminance_from_raw([path], profile=profile, spots=[spot], illuminance=IlluminanceReading(E_TRUE))
    check = result.summary["illuminance"]
    assert check["agrees"] is agrees
    assert check["map_illuminance"] == pytest.approx(scale * E_TRUE, rel=E_RTOL)
    messages = [str(w.message) for w in caught if issubclass(w.category, MetadataWarning)]
    if agrees:
        assert not messages
    else:
        assert len(messages) == 1 and f"{E_TRUE:.4g} lx" in messages[0] and f"{scale * E_TRUE:.4g}"[:3] in messages[0]


def test_illuminance_needs_a_hemisphere(tmp_path, shoot, camera, profile_for):
    path = shoot(camera, np.full((camera.height, camera.width), 50.0))
    with pytest.raises(BadInputError, match="needs a hemispherical map: this view covers"):
        luminance_from_raw([path], profile=profile_for(camera), illuminance=IlluminanceReading(300.0))
