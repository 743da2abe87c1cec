"""Camera profiles: the shipped ones load, and every lens model round-trips through TOML."""

from pathlib import Path

import numpy as np
import pytest

from lsadphoto.calibrate import CameraProfile, load_profile, save_profile
from lsadphoto.errors import BadInputError
from lsadphoto.geometry import IdealFisheyeProjection, OpenCVFisheyeProjection, OpenCVPinholeProjection

CALIBRATION = Path(__file__).resolve().parents[1] / "calibration"


@pytest.mark.slow
def test_shipped_profiles_load():
    nikon = load_profile(CALIBRATION / "nikon-d3100-18mm-nominal.toml")
    cam = nikon.projection((3072, 4608))
    # Datasheet: 18 mm on a 23.1 mm wide, 4608 px sensor → f = 18·4608/23.1 px.
    assert cam.fx == pytest.approx(18 * 4608 / 23.1, rel=1e-12)
    assert "UNCALIBRATED" in nikon.provenance["status"]
    # binned 4×4 (250² px: the exact clipped solid angles cost ≈ 17 µs per pixel)
    fisheye = load_profile(CALIBRATION / "ideal-fisheye-180.toml").projection((1000, 1000), binning=4)
    rows, cols = fisheye.pixel_grid()
    # Clipped pixel solid angles of a 180° image circle sum to the hemisphere, 2π.
    assert fisheye.clipped_solid_angles(rows, cols).sum() == pytest.approx(2 * np.pi, rel=1e-9)
    demo = load_profile(CALIBRATION / "synthetic-demo.toml")
    assert demo.calibration_constant == 12.0


@pytest.mark.parametrize("projection", [
    IdealFisheyeProjection("equisolid", 63.5, 47.5, 60.0, 170.0, 128, 96),
    OpenCVPinholeProjection(100.0, 101.0, 63.2, 47.9, [-0.28, 0.09, 1e-3, -5e-4, -0.01], 128, 96),
    OpenCVFisheyeProjection(40.0, 40.0, 63.5, 47.5, [0.05, -0.01, 0.003, -0.0005], 128, 96),
])
def test_lens_models_round_trip(tmp_path, projection):
    profile = CameraProfile(id="x", width=128, height=96, lens_projection=projection)
    save_profile(profile, tmp_path / "p.toml")
    back = load_profile(tmp_path / "p.toml")
    assert back.projection((96, 128)) == projection
    assert back.projection((96, 128), binning=2) == projection.binned(2)
    with pytest.raises(BadInputError, match="not 64×48"):
        back.projection((48, 64))


def test_bad_lens_model(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('id = "x"\n[sensor]\nwidth_px = 10\nheight_px = 10\n[lens_model]\nmodel = "zoom"\n')
    with pytest.raises(BadInputError, match="lens_model.model must be one of .*got 'zoom'"):
        load_profile(path)
    path.write_text('id = "x"\n[lens_model]\nmodel = "fisheye-ideal"\nkind = "equisolid"\ncx = 4.5\n'
                    'cy = 4.5\nradius = 5.0\nfov_deg = 180.0\n')
    with pytest.raises(BadInputError, match="needs sensor.width_px"):
        load_profile(path)


def test_luminance_stage_uses_the_profile_lens_model(camera, shoot, profile_for):
    """The spot cone comes from the profile's lens model: an OpenCV model without distortion
    equal to the nominal pinhole gives the identical calibration factor."""
    import warnings

    from lsadphoto import luminance_from_raw
    from lsadphoto.calibrate import SpotReading
    from lsadphoto.datasets import interior_scene

    path = shoot(camera, interior_scene((camera.height, camera.width)), exposure_time=1 / 1000)
    nominal = profile_for(camera)
    f = camera.focal_length * camera.width / camera.sensor_width
    lens = OpenCVPinholeProjection(f, camera.focal_length * camera.height / camera.sensor_height,
                                   (camera.width - 1) / 2, (camera.height - 1) / 2, [0, 0, 0, 0],
                                   camera.width, camera.height)
    calibrated = profile_for(camera, lens_projection=lens)
    spot = [SpotReading(0.62 * camera.height, 0.5 * camera.width, 60.0)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = luminance_from_raw([path], profile=nominal, spots=spot)
        b = luminance_from_raw([path], profile=calibrated, spots=spot)
    assert isinstance(b.map.projection, OpenCVPinholeProjection)
    assert b.summary["spots"][0]["pixels"] == a.summary["spots"][0]["pixels"]
    assert b.summary["calibration_factor"] == pytest.approx(a.summary["calibration_factor"], rel=1e-9)
