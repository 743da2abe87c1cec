"""No clipping bias: signed luminance maps keep the mean of a dark, noisy view unbiased."""

import numpy as np
import pytest

from lsadphoto.datasets import SyntheticCamera
from lsadphoto.io import read_exr, read_hdr, write_exr, write_hdr
from lsadphoto.luminance import luminance_from_raw

#: Truth of the dark view [cd·m⁻²]: at ISO 3200, 1/1000 s, f/8 (3 e⁻ read noise) the per-pixel
#: relative noise of Y is 1.0 (measured), 16 % of the pixels are negative, and clamping them at
#: 0 biases the mean by +8 %.
DARK = 0.8
#: 1024 × 768 sensor → 196 608 superpixels of relative noise 1.0: the standard error of the
#: mean is 0.23 %; the issue's 0.5 % bound is > 2 standard errors (seeded, reproducible;
#: measured +0.30 % with seed 12, −0.22 % with seed 13).
MEAN_RTOL = 0.005


@pytest.fixture(scope="module")
def dark_view(tmp_path_factory):
    from lsadphoto.calibrate import CameraProfile
    from lsadphoto.datasets import write_dng

    camera = SyntheticCamera(width=1024, height=768)
    raw = camera.expose(np.full((camera.height, camera.width), DARK), exposure_time=1 / 1000,
                        f_number=8.0, iso=3200, rng=np.random.default_rng(12))
    path = write_dng(tmp_path_factory.mktemp("dark") / "dark.dng", raw, camera,
                     exposure_time=1 / 1000, f_number=8.0, iso=3200)
    profile = CameraProfile(id="synthetic", sensor_width=camera.sensor_width, sensor_height=camera.sensor_height,
                            width=camera.width, height=camera.height, focal_length=camera.focal_length,
                            calibration_constant=camera.calibration_constant)
    return luminance_from_raw([path], profile=profile).map


def test_dark_noisy_field_mean_unbiased(dark_view):
    luminance = dark_view.luminance.astype(np.float64)
    negative = luminance < 0
    assert negative.mean() > 0.1  # the view really is noise-dominated
    assert luminance.mean() == pytest.approx(DARK, rel=MEAN_RTOL)
    # What clamping at 0 (the old behaviour) would give: far outside the bound.
    assert np.maximum(luminance, 0).mean() > DARK * (1 + 10 * MEAN_RTOL)


def test_exr_keeps_signed_values_and_hdr_says_it_clamps(dark_view, tmp_path):
    write_exr(dark_view, tmp_path / "dark.exr")
    back = read_exr(tmp_path / "dark.exr")
    np.testing.assert_array_equal(back.luminance, dark_view.luminance)
    write_hdr(dark_view, tmp_path / "dark.hdr")
    header = (tmp_path / "dark.hdr").read_bytes().split(b"\n\n")[0].decode("latin-1")
    count = int(np.count_nonzero(dark_view.luminance < 0))
    assert f"CLAMPED= {count} pixels of negative luminance" in header
    clamped = read_hdr(tmp_path / "dark.hdr").luminance
    assert clamped.min() >= 0 and clamped.astype(np.float64).mean() > DARK * (1 + 10 * MEAN_RTOL)
