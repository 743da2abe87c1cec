"""Profiles drafted from the file (EXIF, lensfun), their checks against frames, nominal values."""

import math
import subprocess
import sys
import warnings

import numpy as np
import pytest

from lsadphoto.calibrate import CameraProfile, SpotReading, draft_profile, load_profile, save_profile
from lsadphoto.datasets import SyntheticCamera, write_dng
from lsadphoto.errors import BadInputError
from lsadphoto.io import read_exr
from lsadphoto.luminance import luminance_from_raw

from .conftest import raw_samples

#: The issue's bound on the field of view of a map made with no profile [–].
FOV_RTOL = 0.02
SAMPLES = raw_samples()


def _fov_35mm(f35, width, height):
    """Horizontal field of view [rad] of the 35-mm equivalent (diagonal 43.27 mm)."""
    half_width = 0.5 * math.hypot(36, 24) * width / math.hypot(width, height)
    return 2 * math.atan(half_width / f35)


def _map_fov(projection):
    rows, cols = projection.shape
    middle = (rows - 1) / 2
    left = projection.directions(np.array([middle]), np.array([-0.5]))[0]
    right = projection.directions(np.array([middle]), np.array([cols - 0.5]))[0]
    return math.acos(float(np.clip(left @ right, -1, 1)))


def _dng(tmp_path, camera, name="shot.dng", **tags):
    raw = camera.expose(np.full((camera.height, camera.width), 50.0), exposure_time=1 / 125, f_number=4.0,
                        iso=100, noise=False)
    return write_dng(tmp_path / name, raw, camera, exposure_time=1 / 125, f_number=4.0, iso=100, **tags)


def _luminance_cli(path, tmp_path, *extra):
    out = tmp_path / "map.exr"
    run = subprocess.run([sys.executable, "-m", "lsadphoto.cli", "luminance", str(path), "--spot", "100,120,50",
                          "-o", str(out), *extra], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    return read_exr(out)


@pytest.mark.parametrize("focal_plane", [True, False], ids=["focal-plane", "35mm-only (crop mode)"])
def test_fov_without_profile_matches_35mm_equivalent(tmp_path, focal_plane):
    """A Canon-550D-sized sensor at 18 mm (35-mm equivalent 29 mm): `lsadphoto luminance` with no
    profile gives a map whose horizontal field of view matches the 35-mm equivalent within 2 %,
    from the focal-plane resolution or, without it, from FocalLengthIn35mmFilm."""
    camera = SyntheticCamera(width=256, height=170, sensor_width=22.3, sensor_height=14.9, focal_length=18.0)
    crop = math.hypot(36, 24) / math.hypot(22.3, 14.9 * 170 / 170)
    f35 = round(18.0 * crop)
    path = _dng(tmp_path, camera, focal_plane=focal_plane, focal_length_35mm=f35)
    lmap = _luminance_cli(path, tmp_path)
    assert _map_fov(lmap.projection) == pytest.approx(_fov_35mm(f35, camera.width, camera.height), rel=FOV_RTOL)
    sources = lmap.provenance["camera_values"]
    assert ("FocalPlane" if focal_plane else "FocalLengthIn35mmFilm") in sources["sensor"]
    assert "noise" in lmap.provenance["nominal"]


@pytest.mark.skipif(not SAMPLES, reason="no real RAW samples (../shared/realdata/raw, LSADPHOTO_RAW_SAMPLES)")
@pytest.mark.parametrize("source", SAMPLES, ids=[p.name for p in SAMPLES])
def test_real_samples_fov_matches_35mm_equivalent(source):
    import exifread

    with open(source, "rb") as fh:
        tags = exifread.process_file(fh, details=False)
    f35 = tags.get("EXIF FocalLengthIn35mmFilm")
    if f35 is None or not f35.values[0]:
        pytest.skip(f"{source.name} records no 35-mm equivalent focal length")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # metadata warnings are tested elsewhere
        profile = draft_profile(source)
    rows, cols = profile.height, profile.width
    projection = profile.projection((rows, cols))
    assert _map_fov(projection) == pytest.approx(_fov_35mm(float(f35.values[0]), cols, rows), rel=FOV_RTOL)


def test_real_canon_dng_drafted_from_lensfun_camera():
    """The real Canon DNG names its body (EOS Kiss X4 = 550D) but no focal length: the draft
    takes the sensor from lensfun's crop factor 1.613 — 22.3 × 14.9 mm, Canon's specification
    of the 550D — says it is nominal, and the luminance stage says the focal length is missing."""
    from .conftest import realdata

    path = realdata("raw/tinydng_colorchart.dng")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        profile = draft_profile(path)
        assert profile.sensor_width == pytest.approx(22.3, abs=0.05)
        assert profile.sensor_height == pytest.approx(14.9, abs=0.05)
        assert "lensfun camera" in profile.sources["sensor"] and "sensor" in profile.nominal
        with pytest.raises(BadInputError, match="needs the focal length, which the file does not record"):
            luminance_from_raw([path], spots=[SpotReading(row=500, col=800, luminance=50.0)])


def test_calibrate_profile_cli_writes_an_editable_profile(tmp_path):
    camera = SyntheticCamera(width=256, height=170, make="Canon", model="Canon EOS 550D", sensor_width=22.3,
                             sensor_height=14.9, focal_length=18.0)
    path = _dng(tmp_path, camera, lens="Canon EF-S 18-55mm f/3.5-5.6 IS")
    out = tmp_path / "drafted.toml"
    run = subprocess.run([sys.executable, "-m", "lsadphoto.cli", "calibrate", "profile", str(path), str(path),
                          "-o", str(out)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    profile = load_profile(out)
    assert profile.lens_projection.model == "lensfun" and profile.lens_projection.distortion == "ptlens"
    assert "lensfun Canon Canon EF-S 18-55mm f/3.5-5.6 IS" in profile.sources["lens_model"]
    assert profile.vignetting.kind == "polynomial" and profile.vignetting.f_number == 4.0
    assert "noise" in profile.nominal_values() and "[noise]" not in out.read_text()
    # The drafted profile is usable as --profile on the same shot.
    lmap = _luminance_cli(path, tmp_path, "--profile", str(out))
    assert lmap.projection == profile.lens_projection.binned(2)


@pytest.mark.parametrize("change,message", [
    ({"camera": "Nikon D3100"}, "is for camera 'Nikon D3100' but the frame has 'lsadphoto synthetic camera'"),
    ({"width": 640, "height": 424}, "is for images of 640×424 px but the frame has 256×170 px"),
    ({"focal_length": 35.0}, "is for focal length 35 mm but the frame has 18 mm; refused, not rescaled"),
    ({"f_number": 8.0}, "is for aperture f/8 (the profile) but the frame has f/4"),
    ({"lens": "Sigma 10-20mm"}, "is for lens 'Sigma 10-20mm' but the frame has 'Canon EF-S 18-55mm f/3.5-5.6 IS'"),
])
def test_contradicting_profile_refused_naming_both_values(tmp_path, change, message):
    camera = SyntheticCamera(width=256, height=170, focal_length=18.0)
    path = _dng(tmp_path, camera, lens="Canon EF-S 18-55mm f/3.5-5.6 IS")
    fields = {"id": "p", "camera": camera.make + " " + camera.model, "sensor_width": camera.sensor_width,
              "sensor_height": camera.sensor_height, "width": 256, "height": 170, "focal_length": 18.0,
              "calibration_constant": camera.calibration_constant}
    fields.update(change)
    with pytest.raises(BadInputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        luminance_from_raw([path], profile=CameraProfile(**fields))


def test_noise_defaults_are_nominal_and_not_written_as_measured(tmp_path):
    path = tmp_path / "p.toml"
    save_profile(CameraProfile(id="geometry-fit", focal_length=18.0), path)
    text = path.read_text()
    assert "[noise]" not in text and 'nominal = "noise"' in text
    assert load_profile(path).nominal_values() == ["noise"]
    measured = CameraProfile(id="m", noise_measured=True)
    save_profile(measured, path)
    assert "[noise]" in path.read_text() and load_profile(path).nominal_values() == []


def test_closed_loop_lensfun_distortion_and_vignetting(tmp_path):
    """A synthetic Canon 550D with the EF-S 18-55 mm at 18 mm, f/4, whose image is distorted and
    vignetted by lensfun itself (lensfunpy's Modifier: reverse distortion gives each recorded
    pixel's place in the ideal rectilinear view, the colour modification gives the pa fall-off,
    43 % at the corners). With no profile, the drafted one undoes both: directions within
    0.1 px of lensfun's (measured 0.075 px), and luminance within 1 % of the truth everywhere
    (measured 0.39 %; noise-free)."""
    lensfunpy = pytest.importorskip("lensfunpy")
    from lsadphoto.calibrate.draft import find_camera, find_lens

    width, height, focal = 768, 512, 18.0
    body = find_camera("Canon", "Canon EOS 550D")
    lens = find_lens(body, "Canon EF-S 18-55mm f/3.5-5.6 IS")
    crop = math.hypot(36, 24) / math.hypot(22.3, 14.9)
    modifier = lensfunpy.Modifier(lens, crop, width, height)
    modifier.initialize(focal, 4.0, 1000.0, pixel_format=np.float32, flags=lensfunpy.ModifyFlags.VIGNETTING)
    ones = np.ones((height, width, 3), np.float32)
    modifier.apply_color_modification(ones)
    gain = 1.0 / ones[..., 0].astype(np.float64)
    modifier = lensfunpy.Modifier(lens, crop, width, height)
    modifier.initialize(focal, 4.0, 1000.0, scale=1.0, flags=lensfunpy.ModifyFlags.DISTORTION, reverse=True)
    ideal = modifier.apply_geometry_distortion().astype(np.float64)  # (rows, cols, (x, y))
    # The ideal view is lensfun's rectilinear image of focal length f in its normalised units.
    size = min(width, height)
    unit = (size - 1) / 2 / (lens.crop_factor / crop * math.hypot(1.5, 1) / math.hypot(width / height, 1))
    f_units = focal / (math.hypot(36, 24) / 2 / math.hypot(1.5, 1) / lens.crop_factor)
    x = (ideal[..., 0] - width / size * (size - 1) / 2) / unit
    y = (ideal[..., 1] - (size - 1) / 2) / unit
    truth_dirs = np.stack([x, y, np.full(x.shape, f_units)], -1)
    truth_dirs /= np.linalg.norm(truth_dirs, axis=-1, keepdims=True)
    luminance = 200.0 * (1 + 0.5 * truth_dirs[..., 0]) * (1 - 0.4 * truth_dirs[..., 1])  # smooth scene [cd/m²]
    camera = SyntheticCamera(width=width, height=height, make="Canon", model="Canon EOS 550D", sensor_width=22.3,
                             sensor_height=14.9, focal_length=focal, vignetting_map=gain)
    raw = camera.expose(luminance, exposure_time=1 / 1000, f_number=4.0, iso=100, noise=False)
    path = write_dng(tmp_path / "lensfun.dng", raw, camera, exposure_time=1 / 1000, f_number=4.0, iso=100,
                     lens="Canon EF-S 18-55mm f/3.5-5.6 IS")
    centre = (height // 2, width // 2)
    result = luminance_from_raw([path], spots=[SpotReading(row=centre[0], col=centre[1],
                                                           luminance=float(luminance[centre]))])
    projection = result.map.projection
    full = draft_profile(path).lens_projection
    rows, cols = np.mgrid[0:height:16, 0:width:16]
    ours = full.directions(rows.astype(float), cols.astype(float))
    angle = np.arccos(np.clip(np.sum(ours * truth_dirs[rows, cols], -1), -1, 1))
    pixel_angle = 1 / (full.scale * full.focal)  # ≈ one pixel at the centre [rad]
    assert angle.max() < 0.1 * pixel_angle
    binned = luminance.reshape(height // 2, 2, width // 2, 2).mean(axis=(1, 3))
    ratio = result.map.luminance / binned
    assert projection.shape == binned.shape
    assert np.nanmax(np.abs(ratio - 1)) < 0.01
    assert "lensfun pa model" in result.summary["camera_values"]["vignetting"]
