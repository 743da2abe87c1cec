"""``lsadphoto score``: JSON record, figures, and one-line errors."""

import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

from lsadphoto.datasets import disk_sources_scene
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.io import write_exr, write_hdr
from lsadphoto.luminance_map import LuminanceMap


def run_cli(*args):
    proc = subprocess.run([sys.executable, "-m", "lsadphoto.cli", *map(str, args)],
                          capture_output=True, text=True)
    return proc.returncode, proc.stdout, proc.stderr


@pytest.fixture(scope="module")
def fisheye_map():
    cam = IdealFisheyeProjection("equidistant", 149.5, 149.5, 150.0, 180.0, 300, 300)
    d = cam.directions(*cam.pixel_grid())
    up = np.array([0.0, -math.sin(0.5), math.cos(0.5)])
    L = disk_sources_scene(d, background=90.0, sources=[(up, 0.08, 25000.0)])
    return LuminanceMap(L, projection=cam, calibrated=True, calibration_uncertainty=0.02)


@pytest.mark.parametrize("suffix", [".exr", ".hdr"])
def test_score_json_and_figures(tmp_path, fisheye_map, suffix):
    path = tmp_path / f"map{suffix}"
    (write_exr if suffix == ".exr" else write_hdr)(fisheye_map, path)
    code, out, err = run_cli("score", path, "--json", "--sweep", "--sources-png",
                             tmp_path / "s.png", "--contrast-png", tmp_path / "c.png",
                             "--output-json", tmp_path / "r.json")
    assert code == 0, err
    record = json.loads(out)
    for key in ("ugr_pixel", "ugr_grouped", "q", "dgp", "background_luminance",
                "vertical_illuminance", "sources", "settings", "provenance"):
        assert key in record
    assert record["n_sources"] == 1
    assert len(record["q_sweep"]["q"]) == 100
    assert json.loads((tmp_path / "r.json").read_text())["ugr_grouped"] == record["ugr_grouped"]
    for png in ("s.png", "c.png"):
        assert (tmp_path / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_score_text_line_and_line_of_sight_pixel(tmp_path, fisheye_map):
    path = tmp_path / "map.exr"
    write_exr(fisheye_map, path)
    code, out, err = run_cli("score", path, "--line-of-sight", "px:149.5,149.5")
    assert code == 0, err
    assert "UGR pixel" in out and "glare sources" in out


def test_score_bad_inputs_are_one_line(tmp_path, fisheye_map):
    garbage = tmp_path / "bad.hdr"
    garbage.write_bytes(b"not a picture")
    no_view = tmp_path / "noview.exr"
    write_exr(LuminanceMap(np.ones((8, 8))), no_view)
    good = tmp_path / "map.exr"
    write_exr(fisheye_map, good)
    cases = [
        (garbage,),
        (tmp_path / "missing.exr",),
        (no_view,),
        (good, "--line-of-sight", "1,2"),
        (good, "--line-of-sight", "0,0,0"),
        (good, "--line-of-sight", "px:0,0"),  # outside the image circle
        (good, "--N", "-3"),
        (good, "--noise-samples", "-1"),
    ]
    for args in cases:
        code, out, err = run_cli("score", *args)
        assert code == 2, (args, err)
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, (args, err)


def test_source_position_and_noise_in_the_text_output(tmp_path, fisheye_map):
    noisy = LuminanceMap(fisheye_map.luminance, uncertainty=0.1 * fisheye_map.luminance,
                         projection=fisheye_map.projection, calibrated=True,
                         calibration_uncertainty=0.02)
    path = tmp_path / "noisy.exr"
    write_exr(noisy, path)
    code, out, err = run_cli("score", path, "--source-position", "direction", "--json",
                             "--q-noise-samples", "4")
    assert code == 0, err
    record = json.loads(out)
    assert record["settings"]["source_position"] == "direction"
    assert record["sources"][0]["position_pixel"] is None
    assert record["sources"][0]["position_direction"] == record["sources"][0]["direction"]
    # Calibration (2 %) and noise parts combine in quadrature into "uncertainty".
    for key in ("ugr_grouped", "dgp", "q"):
        assert record["uncertainty"][key] == pytest.approx(math.hypot(
            record["uncertainty_calibration"][key], record["uncertainty_noise"][key]), rel=1e-9)
    code, out, err = run_cli("score", path, "--q-noise-samples", "4")
    assert code == 0, err
    # Values to their uncertainty's two significant digits; Q's noise bias (noise adds
    # gradients to a flat background) is printed.
    shown = re.search(r"grouped (\d+)\.(\d+) ± 0\.(0*)([1-9]\d)\b", out)
    assert shown is not None, out
    assert len(shown.group(2)) == len(shown.group(3)) + 2
    assert "bias from pixel noise" in out and "Q +" in out
