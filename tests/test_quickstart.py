"""The README's Quickstart runs as written (issue 17, defect 8).

Its command blocks are parsed out of README.md and run, unchanged but for
``.venv/bin/lsadphoto`` (replaced by this interpreter running the lsadphoto under test), in a
``git clone`` of the repository in a temporary folder — what a new user has after cloning.
Every command must exit 0; the outputs are then checked against values known independently
of the code that made them: the synthetic office's true luminance, the demo camera's own
focal length and vignetting, and the survey's photo of a station hall against a separate
Monte Carlo model of the same hall.
"""

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import lsadphoto
from lsadphoto.calibrate import load_profile
from lsadphoto.datasets.samples import DEMO_CAMERA, demo_scene
from lsadphoto.io import read_exr, read_hdr

ROOT = Path(__file__).resolve().parents[1]
#: The package under test (its folder goes first on PYTHONPATH of every command).
PACKAGE_ROOT = Path(lsadphoto.__file__).resolve().parents[1]
ENTRY = ".venv/bin/lsadphoto"


def quickstart_blocks(text):
    """The ``sh`` and ``python`` code blocks of the README's ``## Quickstart`` section, in order."""
    section = text.split("\n## Quickstart\n", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"^```(sh|python)\n(.*?)^```$", section, flags=re.S | re.M)


def test_quickstart_blocks_are_found():
    blocks = quickstart_blocks((ROOT / "README.md").read_text(encoding="utf-8"))
    kinds = [kind for kind, _ in blocks]
    assert kinds.count("sh") >= 3 and kinds.count("python") == 1, kinds
    shell = "\n".join(code for kind, code in blocks if kind == "sh")
    # Every command line of the shell blocks is an lsadphoto command (nothing to set up by hand).
    commands = [line for line in shell.replace("\\\n", " ").splitlines()
                if line.strip() and not line.lstrip().startswith("#")]
    assert commands and all(line.startswith(f"{ENTRY} ") for line in commands), commands


@pytest.fixture(scope="module")
def quickstart(tmp_path_factory):
    """Run every Quickstart block in a fresh clone; returns the clone and each block's stdout."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("the Quickstart test clones the repository: needs git and a git checkout")
    clone = tmp_path_factory.mktemp("quickstart") / "lsadphoto"
    subprocess.run(["git", "clone", "--quiet", str(ROOT), str(clone)], check=True, timeout=120)
    env = dict(os.environ, PYTHONPATH=str(PACKAGE_ROOT), MPLBACKEND="Agg")
    entry = f"{shlex.quote(sys.executable)} -m lsadphoto.cli"
    outputs = []
    for kind, code in quickstart_blocks((clone / "README.md").read_text(encoding="utf-8")):
        if kind == "sh":
            argv = ["bash", "-e", "-c", code.replace(ENTRY, entry)]
        else:
            argv = [sys.executable, "-c", code]
        done = subprocess.run(argv, cwd=clone, env=env, capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, f"{kind} block failed:\n{code}\n{done.stderr}"
        outputs.append(done.stdout)
    return clone, outputs


@pytest.mark.slow
def test_office_map_matches_the_true_scene(quickstart):
    clone, outputs = quickstart
    lmap = read_exr(clone / "office.exr")
    truth = demo_scene()
    truth = truth.reshape(truth.shape[0] // 2, 2, truth.shape[1] // 2, 2).mean(axis=(1, 3))
    known = np.isfinite(lmap.luminance)
    assert known.mean() > 0.99
    error = np.abs(lmap.luminance[known] / truth[known] - 1)
    # The bracket has shot and read noise and the calibration rests on two spot readings
    # rounded to 3 digits (± 0.1 %), with 1.2 % standard uncertainty: the median error is a few
    # per cent at most (`make demo` prints ≈ 1 %).
    assert np.median(error) < 0.03
    summary, _ = json.JSONDecoder().raw_decode(outputs[0])  # luminance --json, then score's
    assert summary["calibrated"] and summary["outputs"]["hdr"] == "office.hdr"
    # The HDR copy holds the same map within the RGBE quantisation bound (2⁻⁸ relative); RGBE
    # has no sign, so negative pixels are written as 0 (see the next test).
    hdr = read_hdr(clone / "office.hdr").luminance
    positive = known & (lmap.luminance >= 0)
    np.testing.assert_allclose(hdr[positive], lmap.luminance[positive], rtol=2.0**-8 + 1e-6)
    for name in ("office.png", "sources.png", "contrast.png"):
        assert (clone / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    if "office-view.html" in (clone / "README.md").read_text(encoding="utf-8"):
        assert (clone / "office-view.html").read_text(encoding="utf-8").lstrip().lower().startswith("<!doctype html")


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="issue 17: after merging main on 2026-12-01 19:05 two pixels of the "
                   "Quickstart's office map read about −2.9e3 cd/m² (0 before); luminance is never negative")
def test_office_map_has_no_negative_luminance(quickstart):
    clone, _ = quickstart
    luminance = read_exr(clone / "office.exr").luminance
    assert np.all(luminance[np.isfinite(luminance)] >= 0)


@pytest.mark.slow
def test_calibrated_profile_is_the_demo_camera(quickstart):
    clone, _ = quickstart
    profile = load_profile(clone / "my-camera.toml")
    assert profile.id == "my-camera"  # its own id, not the demo profile's
    cam = DEMO_CAMERA
    p = profile.lens_projection  # the geometry calibrated first is kept by calibrate vignetting
    assert (p.model, p.width, p.height) == ("opencv-pinhole", cam.width, cam.height)
    # The boards were rendered through f·W/w (focal length over pixel pitch): the fit recovers
    # it to 0.1 % (measured 0.01 % in x, 0.08 % in y); 0.5 % is a loose bound.
    assert p.fx == pytest.approx(cam.focal_length * cam.width / cam.sensor_width, rel=5e-3)
    assert p.fy == pytest.approx(cam.focal_length * cam.height / cam.sensor_height, rel=5e-3)
    # The flat fields were exposed through V = 1 + Σ a_k r^2k with the camera's own a_k; the
    # fitted V agrees within 1 % over the image (the fit's RMS residual is 0.4 %, shot noise).
    r2 = np.linspace(0.0, 1.0, 21)
    true = 1.0 + sum(a * r2 ** (k + 1) for k, a in enumerate(cam.vignetting))
    fitted = 1.0 + sum(a * r2 ** (k + 1) for k, a in enumerate(profile.vignetting.coefficients))
    np.testing.assert_allclose(fitted, true, rtol=0.01)


@pytest.mark.slow
def test_survey_photo_and_its_model_agree(quickstart):
    clone, _ = quickstart
    table = (clone / "out" / "metrics.csv").read_text().splitlines()
    assert len(table) == 1 + 6  # header and the six station halls
    assert (clone / "out" / "report.html").stat().st_size > 0
    photo = read_exr(clone / "out" / "views" / "rows" / "rows.exr")
    model = read_exr(clone / "rows-model.exr")
    assert model.projection == photo.projection  # rendered through the survey's camera
    ratio = model.luminance / photo.luminance
    # The photo is a bracket of DNGs exposed from one Monte Carlo rendering of the hall and
    # calibrated with two spot readings; the model is a second, independent simulation. Their
    # median ratio is 1 within the spot calibration's few per cent (measured 1.011).
    assert np.nanmedian(ratio) == pytest.approx(1.0, abs=0.05)
    assert (clone / "comparison.html").stat().st_size > 0
    fisheye = read_exr(clone / "rows-fisheye.exr")
    assert fisheye.projection.kind == "equidistant" and fisheye.shape == (256, 256)
    header = (clone / "rows-fisheye.hdr").read_bytes().split(b"\n\n", 1)[0]
    assert b"VIEW= -vta" in header  # evalglare reads it


@pytest.mark.slow
def test_python_block_makes_the_command_line_map(quickstart):
    clone, _ = quickstart
    # Same files, profile and demosaic, one spot reading instead of two: the same map up to
    # the calibration factor (a single scale), which the two spots set within their 1.2 %.
    python_map = read_exr(clone / "office-python.exr").luminance
    cli_map = read_exr(clone / "office.exr").luminance
    known = np.isfinite(cli_map)
    np.testing.assert_array_equal(np.isfinite(python_map), known)
    dark = known & (cli_map == 0)  # a few pixels read zero (read noise below black)
    np.testing.assert_array_equal(python_map[dark], 0.0)
    ratio = python_map[known & ~dark] / cli_map[known & ~dark]
    assert ratio.max() / ratio.min() == pytest.approx(1.0, abs=1e-5)
    assert np.median(ratio) == pytest.approx(1.0, abs=0.03)
