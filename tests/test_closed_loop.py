"""Closed loop: known luminance → synthetic camera → real DNG → lsadphoto → luminance.

The independent reference is the luminance map the synthetic camera was given.
"""

import warnings

import numpy as np
import pytest

from lsadphoto import luminance_from_raw
from lsadphoto.calibrate import SpotReading
from lsadphoto.errors import SaturationWarning

from .conftest import binned_truth, interior_scene, smooth_mask


def _truth_for(result, luminance):
    return binned_truth(luminance) if result.summary["demosaic"] == "superpixel" else luminance


def _run(paths, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SaturationWarning)  # the luminaires saturate on purpose
        return luminance_from_raw(paths, **kwargs)


@pytest.mark.parametrize("demosaic", ["superpixel", "linear", "ahd", "dcb"])
def test_noise_free_error_within_one_percent(camera, shoot, profile_for, demosaic):
    truth = interior_scene((camera.height, camera.width))
    path = shoot(camera, truth)
    result = _run([path], profile=profile_for(camera), demosaic=demosaic)
    expected = _truth_for(result, truth)
    # "Smooth": within ±7.5 % over 9 × 9 sensor px (the gradient), i.e. away from the edges of
    # the target and the luminaires.
    radius = 2 if demosaic == "superpixel" else 4  # the same 9 sensor pixels
    smooth = smooth_mask(expected, radius=radius, tolerance=0.15) & np.isfinite(result.map.luminance)
    error = np.abs(result.map.luminance[smooth] / expected[smooth] - 1)
    # Issue requirement: ≤ 1 % median on smooth unsaturated regions. The residual comes
    # from 14-bit quantisation and LibRaw's 16-bit output (≤ 0.1 % here).
    assert np.median(error) <= 0.01
    assert smooth.mean() > 0.5  # the check covers most of the image
    assert not result.summary["calibrated"]


def test_spot_factor_within_half_percent_with_noise(shoot, profile_for):
    from lsadphoto.datasets import SyntheticCamera

    # A 50 mm lens on 1024 px puts ≈ 300 binned pixels in the 1° cone: the noise of their
    # mean (≈ 0.1 %) leaves room to test the 0.5 % requirement at ISO 400.
    camera = SyntheticCamera(width=1024, height=768, focal_length=50.0)
    truth = interior_scene((camera.height, camera.width))
    path = shoot(camera, truth, noise=True, iso=400, seed=3, exposure_time=1 / 1000)
    # The grey target (60 cd/m²) at rows 0.52–0.72, cols centred: aim at its centre.
    spot = SpotReading(0.62 * camera.height, 0.5 * camera.width, 60.0)
    result = _run([path], profile=profile_for(camera), spots=[spot])
    # The exposure-normalised relative luminance is L / C exactly, so the true factor is C.
    factor = result.summary["calibration_factor"]
    assert abs(factor / camera.calibration_constant - 1) < 0.005
    assert result.summary["calibrated"]
    assert result.map.calibrated


def test_errors_consistent_with_noise_model(camera, shoot, profile_for):
    """With shot + read noise, (L − L_true)/u_noise has unit spread (superpixel, smooth areas)."""
    truth = np.full((camera.height, camera.width), 40.0)
    path = shoot(camera, truth, noise=True, iso=800, seed=11, exposure_time=1 / 500)
    result = _run([path], profile=profile_for(camera))
    lmap = result.map
    u_cal = lmap.calibration_uncertainty * lmap.luminance
    u_noise = np.sqrt(lmap.uncertainty.astype(float) ** 2 - u_cal.astype(float) ** 2)
    z = (lmap.luminance - binned_truth(truth)) / u_noise
    # 24 576 values: the sample SD of unit-variance noise is within ±3 % of 1 at >5σ; the
    # model ignores quantisation (0.29 ADU) and Poisson skew, so allow ±10 %.
    assert 0.9 < np.std(z) < 1.1
    assert abs(np.mean(z)) < 0.05


@pytest.mark.slow
def test_bracket_recovers_seven_decades(tmp_path, profile_for, shoot):
    from lsadphoto.datasets import SyntheticCamera

    camera = SyntheticCamera(width=400, height=64)
    # A horizontal log ramp from 0.01 to 100 000 cd/m².
    ramp = np.logspace(-2, 5, camera.width)
    truth = np.tile(ramp, (camera.height, 1))
    # e = t·S/N² of 12.5, 0.039 and 1e-4 s: 8.3 and 8.6 stops apart, ISO 100.
    settings = [(0.5, 2.0), (1 / 160, 4.0), (1 / 16000, 8.0)]
    times = [t for t, _ in settings]
    paths = [shoot(camera, truth, exposure_time=t, f_number=n, iso=100) for t, n in settings]
    result = _run(paths, profile=profile_for(camera))
    got = result.map.luminance
    expected = binned_truth(truth)
    known = np.isfinite(got)
    assert known.all(), "the shortest frame leaves 100 000 cd/m² unsaturated"
    error = np.abs(got / expected - 1)
    # Issue requirement: within 2 % wherever some frame is unsaturated (here: everywhere).
    assert error.max() < 0.02
    assert [f["exposure_time"] for f in result.summary["frames"]] == pytest.approx(times, rel=1e-3)


def test_coloured_targets_recover_luminance(camera, shoot, profile_for):
    """Saturated colours (sRGB primaries' chromaticities) give the same luminance back."""
    truth = np.full((camera.height, camera.width), 50.0)
    xy = np.empty((camera.height, camera.width, 2))
    xy[...] = (0.3127, 0.3290)
    thirds = camera.width // 3
    xy[:, :thirds] = (0.64, 0.33)  # sRGB red primary (IEC 61966-2-1)
    xy[:, thirds : 2 * thirds] = (0.30, 0.60)  # green
    xy[:, 2 * thirds :] = (0.15, 0.06)  # blue
    path = shoot(camera, truth, chromaticity=xy, exposure_time=1 / 500)
    result = _run([path], profile=profile_for(camera))
    inner = smooth_mask(binned_truth(xy[..., 0]), tolerance=1e-9)
    error = np.abs(result.map.luminance[inner] / 50.0 - 1)
    # The camera model is exactly linear through the DNG ColorMatrix, so only quantisation
    # remains (blue primary: a few hundred ADU in R → ≤ 0.3 %).
    assert error.max() < 0.005


def test_bracket_noise_weights_match_scatter(camera, shoot, profile_for):
    """Two noisy frames 2 stops apart: the merged uncertainty predicts the scatter, and it is
    smaller than that of the better frame alone (inverse-variance weighting pays)."""
    truth = np.full((camera.height, camera.width), 30.0)
    paths = [shoot(camera, truth, noise=True, iso=800, exposure_time=t, seed=40 + i)
             for i, t in enumerate((1 / 500, 1 / 2000))]
    merged = _run(paths, profile=profile_for(camera)).map
    single = _run(paths[:1], profile=profile_for(camera)).map

    def noise_part(lmap):
        return np.sqrt(lmap.uncertainty.astype(float) ** 2 - (lmap.calibration_uncertainty * lmap.luminance) ** 2)

    z = (merged.luminance - 30.0) / noise_part(merged)
    # 24 576 pixels: unit spread within ±10 % (as the single-frame test).
    assert 0.9 < np.std(z) < 1.1
    assert np.std(merged.luminance) < np.std(single.luminance)


def test_all_black_and_fully_saturated_frames(camera, shoot, profile_for):
    from lsadphoto.errors import BadInputError

    shape = (camera.height, camera.width)
    dark = luminance_from_raw([shoot(camera, np.zeros(shape))], profile=profile_for(camera))
    # No light: every pixel is 0 cd/m² (noise-free), known, with a finite uncertainty.
    assert np.all(dark.map.luminance == 0) and np.all(np.isfinite(dark.map.uncertainty))
    assert dark.summary["saturated_fraction"] == 0
    with pytest.raises(BadInputError, match="sees no light"):
        luminance_from_raw([shoot(camera, np.zeros(shape))], profile=profile_for(camera),
                           spots=[SpotReading(96, 128, 10.0)])
    with pytest.warns(SaturationWarning, match="100.00 %"):
        white = luminance_from_raw([shoot(camera, np.full(shape, 1e9))], profile=profile_for(camera))
    assert np.all(np.isnan(white.map.luminance)) and white.summary["saturated_fraction"] == 1.0
