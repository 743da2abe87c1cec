"""The command line: outputs, JSON summary, and one-line errors with exit code 2 for bad input."""

import json
import subprocess
import sys

import numpy as np
import pytest

from lsadphoto.calibrate import save_profile
from lsadphoto.cli import main
from lsadphoto.io import read_exr, read_hdr

from .conftest import interior_scene


@pytest.fixture
def scene_dng(camera, shoot):
    return shoot(camera, interior_scene((camera.height, camera.width)), exposure_time=1 / 1000)


@pytest.fixture
def profile_path(camera, profile_for, tmp_path):
    path = tmp_path / "camera.toml"
    save_profile(profile_for(camera), path)
    return path


def run_cli(*args):
    """Run the installed entry point in a subprocess: what a user sees."""
    proc = subprocess.run([sys.executable, "-m", "lsadphoto.cli", *map(str, args)], capture_output=True, text=True)
    return proc.returncode, proc.stdout, proc.stderr


def test_luminance_writes_all_outputs_and_json(scene_dng, profile_path, tmp_path, camera):
    out = tmp_path / "out"
    spot = f"{0.62 * camera.height:.1f},{0.5 * camera.width:.1f},60"
    code, stdout, stderr = run_cli("luminance", scene_dng, "--profile", profile_path, "--spot", spot,
                                   "-o", out / "m.exr", "--hdr", out / "m.hdr", "--png", out / "m.png", "--json")
    assert code == 0, stderr
    summary = json.loads(stdout)
    for key in ("calibration_factor", "calibration_uncertainty", "saturated_fraction", "frames"):
        assert key in summary
    assert summary["frames"][0]["exposure_time"] == pytest.approx(1 / 1000)
    assert summary["calibrated"] is True
    exr, hdr = read_exr(out / "m.exr"), read_hdr(out / "m.hdr")
    assert exr.calibration_factor == summary["calibration_factor"]
    both = np.isfinite(exr.luminance) & (exr.luminance > 0)
    # HDR is RGBE: relative error ≤ ½ of the mantissa step, 0.5/128 at worst.
    assert np.max(np.abs(hdr.luminance[both] / exr.luminance[both] - 1)) < 0.5 / 128 + 1e-6
    assert (out / "m.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_calibrate_vignetting_writes_profile(camera, shoot, tmp_path):
    flats = [shoot(camera, np.full((camera.height, camera.width), 30.0), noise=True, seed=s) for s in (1, 2)]
    target = tmp_path / "fit.toml"
    assert main(["calibrate", "vignetting", *map(str, flats), "-o", str(target), "--id", "cam"]) == 0
    text = target.read_text()
    assert 'model = "polynomial"' in text and 'id = "cam"' in text


def _bad_cases(tmp_path, scene_dng, camera, shoot, profile_path):
    corrupt = tmp_path / "corrupt.dng"
    corrupt.write_bytes(np.random.default_rng(1).integers(0, 256, 50_000, dtype=np.uint8).tobytes())
    truncated = tmp_path / "truncated.dng"
    truncated.write_bytes(scene_dng.read_bytes()[:5000])
    empty = tmp_path / "empty.dng"
    empty.write_bytes(b"")
    text = tmp_path / "notes.txt"
    text.write_text("not a raw file\n")
    no_meta = shoot(camera, np.full((camera.height, camera.width), 20.0), exposure_time=None)
    from lsadphoto.datasets import SyntheticCamera

    other = SyntheticCamera(width=128, height=96)
    small = shoot(other, np.full((96, 128), 20.0))
    saturated = shoot(camera, np.full((camera.height, camera.width), 1e8))
    bad_profile = tmp_path / "bad.toml"
    bad_profile.write_text("id = 'x'\n[photometric]\ncalibration_constant = nan\n")
    p = str(profile_path)
    return {
        "corrupt": ([corrupt, "--profile", p], "not a readable RAW file"),
        "truncated": ([truncated, "--profile", p], "truncated.dng"),
        "empty": ([empty, "--profile", p], "is empty"),
        "missing": ([tmp_path / "nope.dng", "--profile", p], "does not exist"),
        "unsupported": ([text, "--profile", p], "not a readable RAW file"),
        "spot off image": ([scene_dng, "--profile", p, "--spot", "5000,10,50"], "off the image"),
        "spot saturated": ([saturated, "--profile", p, "--spot", "96,128,50"], "saturated"),
        "spot nan": ([scene_dng, "--profile", p, "--spot", "96,128,nan"], "non-finite"),
        "no exposure": ([no_meta, "--profile", p], "missing exposure metadata (exposure_time)"),
        "bracket sizes": ([scene_dng, small, "--profile", p], "differ in size"),
        "no scale": ([scene_dng], "spot readings"),
        "bad profile": ([scene_dng, "--profile", bad_profile], "calibration_constant"),
        "bad demosaic": ([scene_dng, "--profile", p, "--demosaic", "vng"], "invalid choice"),
    }


def test_bad_input_one_line_exit_2_nothing_written(tmp_path, scene_dng, camera, shoot, profile_path):
    cases = _bad_cases(tmp_path, scene_dng, camera, shoot, profile_path)
    for name, (args, message) in cases.items():
        out = tmp_path / f"out_{name.replace(' ', '_')}"
        code, stdout, stderr = run_cli("luminance", *args, "-o", out / "m.exr", "--hdr", out / "m.hdr",
                                       "--png", out / "m.png")
        lines = [line for line in stderr.splitlines() if line.strip()]
        assert code == 2, (name, stderr)
        assert "Traceback" not in stderr, name
        errors = [line for line in lines if "error" in line]
        assert len(errors) == 1 and message in errors[0], (name, stderr)
        assert not out.exists() or not any(out.iterdir()), name  # nothing (half-)written


def test_version_and_debug_flag():
    code, stdout, _ = run_cli("--version")
    assert code == 0 and stdout.startswith("lsadphoto ")


@pytest.mark.realdata
def test_calibrate_geometry_json_on_real_fisheye_set(tmp_path):
    from lsadphoto.calibrate import load_profile

    from .conftest import realdata

    folder = realdata("calib/fisheye_chessboard")
    images = sorted(folder.glob("*.jpg"))
    target = tmp_path / "fisheye.toml"
    code, stdout, stderr = run_cli("calibrate", "geometry", *images, "--pattern", "chessboard:6x9:25",
                                   "--model", "fisheye", "-o", target, "--json")
    assert code == 0, stderr
    summary = json.loads(stdout)
    for key in ("rms_px", "fx", "fy", "cx", "cy", "distortion", "used_images", "rejected_images"):
        assert key in summary
    # The data set's README: an OpenCV fisheye fit gives RMS ≈ 0.28 px (issue: < 0.5 px).
    assert summary["rms_px"] < 0.5
    profile = load_profile(target)
    assert profile.projection((640, 640)).fx == pytest.approx(summary["fx"], rel=1e-12)


def test_calibrate_geometry_bad_pattern_is_one_line(tmp_path):
    code, _, stderr = run_cli("calibrate", "geometry", tmp_path / "x.png", "--pattern", "circles:4x5",
                              "-o", tmp_path / "p.toml")
    assert code == 2 and "Traceback" not in stderr and len(stderr.strip().splitlines()) == 1
    assert not (tmp_path / "p.toml").exists()
