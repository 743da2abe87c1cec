"""Vignetting: fit from flat fields of a camera with known fall-off, and correction."""

import warnings

import numpy as np
import pytest

from lsadphoto import luminance_from_raw
from lsadphoto.calibrate import VignettingModel, fit_vignetting_polynomial, vignetting_gain
from lsadphoto.datasets import SyntheticCamera
from lsadphoto.errors import BadInputError, SaturationWarning
from lsadphoto.raw import decode_raw

from .conftest import binned_truth, interior_scene


def test_polynomial_gain_matches_formula():
    model = VignettingModel(kind="polynomial", coefficients=[-0.3, 0.05])
    gain = vignetting_gain(model, (101, 201), (101, 201))
    # Corner pixel centre: r² = (50² + 100²) / (half-diagonal of the 101 × 201 sensor)².
    r2 = (50**2 + 100**2) / (0.25 * (101**2 + 201**2))
    assert gain[0, 0] == pytest.approx(1 - 0.3 * r2 + 0.05 * r2**2, rel=1e-6)
    assert gain[50, 100] == pytest.approx(1.0)


def test_fit_recovers_known_vignetting(shoot, profile_for):
    camera = SyntheticCamera(width=320, height=240, vignetting=(-0.35, 0.06))
    flats = [decode_raw(shoot(camera, np.full((240, 320), 40.0), noise=True, seed=s)) for s in range(4)]
    rgb = np.mean([f.rgb for f in flats], axis=0)
    model = fit_vignetting_polynomial(rgb.sum(axis=-1), (240, 320), binning=2, degree=3)
    truth = camera.vignetting_gain()
    fitted = vignetting_gain(model, (240, 320), (240, 320))
    # Four noisy frames (σ ≈ 0.6 % per pixel) fit 3 coefficients: gain within 0.3 %.
    assert np.max(np.abs(fitted / truth - 1)) < 0.003
    assert model.rms_residual < 0.01


def test_closed_loop_with_vignetting(shoot, profile_for):
    camera = SyntheticCamera(width=320, height=240, vignetting=(-0.35, 0.06))
    truth = interior_scene((240, 320))
    profile = profile_for(camera, vignetting=VignettingModel(kind="polynomial", coefficients=[-0.35, 0.06]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SaturationWarning)
        result = luminance_from_raw([shoot(camera, truth)], profile=profile)
        uncorrected = luminance_from_raw([shoot(camera, truth)], profile=profile_for(camera))
    expected = binned_truth(truth)
    corner = (slice(0, 10), slice(0, 10))
    assert np.median(np.abs(result.map.luminance[corner] / expected[corner] - 1)) < 0.005
    # Without the correction the corners read ≈ 25 % low: the correction matters.
    assert np.median(uncorrected.map.luminance[corner] / expected[corner]) < 0.8


def test_flat_field_map_and_bad_models():
    # A gain map linear in row and column, 3 × 4 samples: resampled bilinearly to 30 × 40 it is
    # the same linear function at each output pixel centre, taken at the input position
    # (i + ½)·3/30 − ½ (pixel-centre alignment) and held at the edge samples beyond them.
    rows, cols = np.mgrid[0:3, 0:4]
    gain_map = (0.6 + 0.05 * rows + 0.02 * cols).astype(np.float32)
    gain = vignetting_gain(VignettingModel(kind="flat-field", gain_map=gain_map), (30, 40), (30, 40))
    r_in = np.clip((np.arange(30) + 0.5) * 3 / 30 - 0.5, 0, 2)[:, None]
    c_in = np.clip((np.arange(40) + 0.5) * 4 / 40 - 0.5, 0, 3)[None, :]
    # float32 map and bilinear weights: a few ulps of 1 (≈ 1e-7); 1e-5 leaves margin.
    np.testing.assert_allclose(gain, 0.6 + 0.05 * r_in + 0.02 * c_in, rtol=0, atol=1e-5)
    with pytest.raises(BadInputError, match="unknown vignetting model"):
        vignetting_gain(VignettingModel(kind="cosine4"), (3, 4), (3, 4))
    with pytest.raises(BadInputError, match="below 0.05"):
        vignetting_gain(VignettingModel(kind="polynomial", coefficients=[-2.0]), (30, 40), (30, 40))
