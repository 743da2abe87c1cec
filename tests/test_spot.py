"""Spot-meter calibration: cone size, robust combination, refusals and warnings."""

import warnings

import numpy as np
import pytest

from lsadphoto.calibrate import SpotReading, calibrate_spots, spot_cone
from lsadphoto.constants import LS100_RELATIVE_STANDARD_UNCERTAINTY
from lsadphoto.errors import BadInputError, NonUniformSpotWarning
from lsadphoto.geometry import PinholeProjection

CAM = PinholeProjection(3000.0, 3000.0, 299.5, 199.5, 600, 400)


def test_cone_area_matches_analytic_solid_angle():
    _, mask, weights = spot_cone(CAM, 199.5, 299.5, np.deg2rad(1.0))
    # A 1° cone subtends 2π(1 − cos 0.5°) = 2.392e-4 sr; the pixel-centre rule matches it
    # to the perimeter's discretisation (radius 26 px → ≈ 2 %).
    assert weights[mask].sum() == pytest.approx(2 * np.pi * (1 - np.cos(np.deg2rad(0.5))), rel=0.02)
    assert mask.sum() == pytest.approx(np.pi * (3000 * np.tan(np.deg2rad(0.5))) ** 2, rel=0.03)


def test_factor_of_a_uniform_target():
    relative = np.full(CAM.shape, 2.0)
    result = calibrate_spots(relative, np.zeros(CAM.shape, bool), CAM, [SpotReading(200, 300, 50.0)])
    assert result.factor == pytest.approx(25.0, rel=1e-12)
    # A noiseless uniform target: only the meter's uncertainty is left.
    assert result.relative_uncertainty == pytest.approx(LS100_RELATIVE_STANDARD_UNCERTAINTY, rel=1e-9)


def test_several_spots_combine_and_outlier_is_dropped():
    relative = np.full(CAM.shape, 1.0)
    readings = [SpotReading(100, 100, 10.0), SpotReading(100, 500, 10.2), SpotReading(300, 100, 9.9),
                SpotReading(300, 500, 10.1), SpotReading(200, 300, 14.0)]
    with pytest.warns(NonUniformSpotWarning, match="disagrees"):
        result = calibrate_spots(relative, np.zeros(CAM.shape, bool), CAM, readings)
    kept = [10.0, 10.2, 9.9, 10.1]
    assert result.factor == pytest.approx(np.mean(kept), rel=1e-12)
    scatter = np.std(kept, ddof=1) / 2 / np.mean(kept)
    assert result.relative_uncertainty == pytest.approx(np.hypot(LS100_RELATIVE_STANDARD_UNCERTAINTY, scatter))
    assert [s["used"] for s in result.spots] == [True, True, True, True, False]


def test_refusals_and_non_uniform_warning():
    relative = np.full(CAM.shape, 1.0)
    saturated = np.zeros(CAM.shape, bool)
    with pytest.raises(BadInputError, match="off the image"):
        calibrate_spots(relative, saturated, CAM, [SpotReading(500, 10, 1.0)])
    with pytest.raises(BadInputError, match="beyond the image edge"):
        calibrate_spots(relative, saturated, CAM, [SpotReading(5, 300, 1.0)])
    saturated[200, 300] = True
    with pytest.raises(BadInputError, match="saturated"):
        calibrate_spots(relative, saturated, CAM, [SpotReading(200, 300, 1.0)])
    striped = relative.copy()
    striped[:, ::2] = 1.5
    with pytest.warns(NonUniformSpotWarning, match="varies"):
        calibrate_spots(striped, np.zeros(CAM.shape, bool), CAM, [SpotReading(200, 300, 1.0)])
    nan = relative.copy()
    nan[200, 300] = np.nan
    with pytest.raises(BadInputError, match="unknown luminance"):
        calibrate_spots(nan, np.zeros(CAM.shape, bool), CAM, [SpotReading(200, 300, 1.0)])


def test_binned_coordinates():
    """Spot positions are sensor pixels; on a 2 × 2-binned map they land on (r − ½)/2."""
    relative = np.zeros((200, 300))
    relative[80:121, 130:171] = 1.0  # bright block around binned (100, 150), cone radius 13 px
    half = CAM.binned(2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = calibrate_spots(relative, np.zeros(relative.shape, bool), half, [SpotReading(200.5, 300.5, 3.0)],
                                 binning=2)
    assert result.factor == pytest.approx(3.0)


@pytest.mark.parametrize("text", ["1,2", "a,b,c", "1,2,nan", "1,2,-5", "1,2,inf"])
def test_parse_rejects_bad_spots(text):
    with pytest.raises(BadInputError):
        SpotReading.parse(text)


def test_cone_of_the_calibration_matches_direct_cone_sampling():
    """The bundled spot readings (lsadphoto.datasets.samples.meter_reading) sample the meter's
    cone directly (rings of equal solid angle, each direction read where it projects); the
    calibration's pixel cone must give the same mean on the demo's true scene, so the factor
    from each reading is 1 within the reading's 3-digit rounding (half a unit of the third
    digit, relative to the value)."""
    from lsadphoto.datasets.samples import DEMO_CAMERA, SPOT_POSITIONS, demo_projection, demo_scene, meter_reading

    scene, projection = demo_scene(), demo_projection()
    for fr, fc in SPOT_POSITIONS:
        row, col = round(fr * DEMO_CAMERA.height), round(fc * DEMO_CAMERA.width)
        reading = meter_reading(scene, projection, row, col)
        result = calibrate_spots(scene, np.zeros(scene.shape, bool), projection, [SpotReading(row, col, reading)])
        rounding = 0.5 * 10.0 ** (np.floor(np.log10(reading)) - 2) / reading
        assert abs(result.factor - 1.0) <= rounding, (row, col, reading, result.factor)
