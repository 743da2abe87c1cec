"""Luminous overflow: reported with its size and the illuminance at risk; repaired from a meter
reading or an ND-filter frame (a fisheye view with a 'sun' far above the white level)."""

import math
import warnings

import numpy as np
import pytest

from lsadphoto.calibrate import CameraProfile, SpotReading
from lsadphoto.calibrate.illuminance import IlluminanceReading, hemisphere_illuminance
from lsadphoto.datasets import SyntheticCamera, write_dng
from lsadphoto.errors import BadInputError, SaturationWarning
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.luminance import luminance_from_raw

SIZE, RADIUS, L0 = 400, 190.0, 100.0
SUN, SUN_RADIUS_DEG, SUN_THETA_DEG = 1.0e6, 4.0, 30.0
OMEGA_SUN = 2 * math.pi * (1 - math.cos(math.radians(SUN_RADIUS_DEG)))
#: E of the scene [lx]: background L0(1 + cos θ) over the hemisphere minus what the sun covers,
#: plus the sun (its cos θ varies by ±3.5 % over the disk: the integral of cos over a small cap
#: about θ₀ is Ω·cos θ₀·(1 + O(r²)), error < 1e-3 here).
E_BACKGROUND = L0 * (math.pi + 2 * math.pi / 3)
E_SUN = (SUN - L0 * (1 + math.cos(math.radians(SUN_THETA_DEG)))) * OMEGA_SUN * math.cos(math.radians(SUN_THETA_DEG))


@pytest.fixture(scope="module")
def sun_view(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sun")
    camera = SyntheticCamera(width=SIZE, height=SIZE, sensor_width=10.0, sensor_height=10.0)
    fisheye = IdealFisheyeProjection("equidistant", (SIZE - 1) / 2, (SIZE - 1) / 2, RADIUS, 180.0, SIZE, SIZE)
    rows, cols = fisheye.pixel_grid()
    d = fisheye.directions(rows.astype(float), cols.astype(float))
    inside = np.isfinite(d[..., 2])
    luminance = np.where(inside, L0 * (1 + np.nan_to_num(d[..., 2])), 0.0)
    t = math.radians(SUN_THETA_DEG)
    sun = np.nan_to_num(d @ np.array([math.sin(t), 0.0, math.cos(t)]), nan=-1) >= math.cos(math.radians(SUN_RADIUS_DEG))
    luminance = np.where(sun, SUN, luminance)
    paths = []
    for name, scale in (("normal", 1.0), ("nd10", 2.0**-10)):  # ND 3.0 ≈ 10 stops: the scene's light / 1024
        raw = camera.expose(luminance * scale, exposure_time=1 / 1000, f_number=4.0, iso=100, noise=False)
        paths.append(write_dng(folder / f"{name}.dng", raw, camera, exposure_time=1 / 1000, f_number=4.0, iso=100))
    profile = CameraProfile(id="fisheye", camera="lsadphoto synthetic camera", width=SIZE, height=SIZE,
                            lens_projection=fisheye)
    spot = SpotReading(row=SIZE // 2, col=SIZE // 2, luminance=2 * L0)  # the zenith of the background
    return paths, profile, spot, sun


def test_overflow_reported_with_size_and_illuminance_at_risk(sun_view):
    paths, profile, spot, _ = sun_view
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = luminance_from_raw(paths[:1], profile=profile, spots=[spot])
    overflow = result.summary["overflow"]
    messages = [str(w.message) for w in caught if issubclass(w.category, SaturationWarning)]
    assert len(messages) == 1 and "luminous overflow" in messages[0] and "--nd-filter" in messages[0]
    # The overflow region is the sun's disk plus the superpixels its edge reaches.
    assert OMEGA_SUN < overflow["solid_angle"] < 1.3 * OMEGA_SUN
    # Lower bounds are bounds: below the truth, and the share at risk below the true share.
    assert overflow["luminance_lower_bound"] < SUN
    assert 0 < overflow["illuminance_lower_bound"] < E_SUN
    assert 0 < overflow["share_at_least"] < E_SUN / (E_SUN + E_BACKGROUND)
    # Unknown pixels: the overflow, and the colour artefacts just outside the sun's rim (a
    # superpixel whose channels straddle a 10⁹ cd/m² edge; luminance_from_raw counts them).
    unknown = np.isnan(result.map.luminance)
    artefacts = result.summary["colour_artefact_pixels"]
    assert unknown.sum() == overflow["pixels"] + artefacts and artefacts < overflow["pixels"]


def test_overflow_repaired_from_meter_reading(sun_view):
    """With spots and a meter reading, the deficit fills the overflow: the repaired map's
    illuminance is the reading, and the sun's light lands where the sun is."""
    paths, profile, spot, _ = sun_view
    reading = IlluminanceReading(E_BACKGROUND + E_SUN)
    result = luminance_from_raw(paths[:1], profile=profile, spots=[spot], illuminance=reading)
    overflow = result.summary["overflow"]
    assert overflow["repair"].startswith("illuminance")
    e, _, _ = hemisphere_illuminance(result.map.luminance, result.map.projection)
    assert e == pytest.approx(reading.illuminance, rel=1e-4)
    # The overflow region is larger than the disk, so the uniform fill is lower than the sun
    # but carries its light: L_fill·Ω_overflow within 3 % of L_sun·Ω_sun (cos θ ≈ cos 30°).
    assert overflow["repaired_luminance"] * overflow["solid_angle"] == pytest.approx(SUN * OMEGA_SUN, rel=0.03)
    assert overflow["repaired_uncertainty"] > 0


def test_nd_filter_frame_removes_the_overflow(sun_view):
    """A 10-stop ND frame joins the bracket with its exposure / 1024: nothing overflows and the
    sun's core comes out at its luminance (noise-free: within 1 %)."""
    paths, profile, spot, sun = sun_view
    result = luminance_from_raw(paths, profile=profile, spots=[spot], nd_filter=[0, 10])
    assert result.summary["overflow"] is None
    core = sun.reshape(SIZE // 2, 2, SIZE // 2, 2).all(axis=(1, 3))
    np.testing.assert_allclose(result.map.luminance[core], SUN, rtol=0.01)


def test_illuminance_alone_cannot_calibrate_an_overflowing_map(sun_view):
    paths, profile, _, _ = sun_view
    with pytest.raises(BadInputError, match="cannot both calibrate the map and fill in the overflow"):
        luminance_from_raw(paths[:1], profile=profile, illuminance=IlluminanceReading(E_BACKGROUND + E_SUN))
    with pytest.raises(BadInputError, match="one ND filter density per frame"):
        luminance_from_raw(paths, profile=profile, nd_filter=[3])


def test_score_says_when_metrics_rest_on_a_repair(sun_view):
    from lsadphoto.metrics.score import score_map

    paths, profile, spot, _ = sun_view
    repaired = luminance_from_raw(paths[:1], profile=profile, spots=[spot],
                                  illuminance=IlluminanceReading(E_BACKGROUND + E_SUN)).map
    notes = score_map(repaired, noise_samples=0, q_noise_samples=0).notes
    assert any("rest on a luminous-overflow repair" in n for n in notes)
