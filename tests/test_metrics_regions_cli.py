"""``lsadphoto score`` with evalglare 3.06's analyses: the JSON keys, and one-line errors
(exit code 2, nothing written) for bad analysis options."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from lsadphoto.datasets import disk_sources_scene
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.io import read_hdr, write_hdr
from lsadphoto.luminance_map import LuminanceMap

SIZE = 200


def run_cli(*args):
    proc = subprocess.run([sys.executable, "-m", "lsadphoto.cli", *map(str, args)],
                          capture_output=True, text=True)
    return proc.returncode, proc.stdout, proc.stderr


@pytest.fixture(scope="module")
def pictures(tmp_path_factory):
    """A fisheye office with a window crossing the zone border, and a window mask."""
    folder = tmp_path_factory.mktemp("cli")
    cam = IdealFisheyeProjection("equidistant", (SIZE - 1) / 2, (SIZE - 1) / 2, SIZE / 2, 180.0,
                                 SIZE, SIZE)
    d = cam.directions(*cam.pixel_grid())
    window = np.array([math.sin(0.75), 0.0, math.cos(0.75)])
    L = disk_sources_scene(d, background=70.0, sources=[(window, 0.5, 6000.0)])
    with np.errstate(invalid="ignore"):
        inside = d @ (window / np.linalg.norm(window)) >= math.cos(0.45)
    write_hdr(LuminanceMap(L, projection=cam, calibrated=True), folder / "map.hdr")
    write_hdr(LuminanceMap(np.where(inside, 500.0, 0.0), projection=cam), folder / "mask.hdr")
    small = IdealFisheyeProjection("equidistant", 49.5, 49.5, 50.0, 180.0, 100, 100)
    write_hdr(LuminanceMap(np.ones((100, 100)), projection=small), folder / "small.hdr")
    return folder


@pytest.mark.slow
def test_score_writes_every_analysis_key(pictures, tmp_path):
    check = tmp_path / "check.hdr"
    code, out, err = run_cli(
        "score", pictures / "map.hdr", "--json", "--band-deg", 20, "--zones",
        f"px:{SIZE // 2},{SIZE // 2},40,80", "--checkfile", check, "--task",
        f"px:{SIZE // 2},{SIZE // 2}", "--age", 40, "--illuminance", 2000, "--correction-mode",
        "l+", "--dgp-coefficients", "2,1,1.87,2,1,5.87e-5,0.092,0.159")
    assert code == 0, err
    record = json.loads(out)
    keys = ("solid_angle", "mean", "median", "std", "p75", "p95", "min", "max")
    assert set(keys) <= set(record["band"])
    assert len(record["zones"]) == 2
    assert set(keys + ("illuminance", "n_pixels")) <= set(record["zones"][0])
    # The task cone holds background only: 70 cd/m² as the RGBE file stores it (within one
    # mantissa step, 1/128 at worst).
    assert record["task"]["luminance"] == pytest.approx(70.0, rel=8e-3)
    for source in record["sources"]:
        assert {"Eglare", "Lveil_cie", "r_contrast", "r_dgp", "zone"} <= set(source)
    assert {s["zone"] for s in record["sources"]} >= {1, 2}  # the window is split
    assert read_hdr(check).luminance.shape == (SIZE, SIZE)  # a picture Radiance tools read
    # The mask run: statistics, illuminance and the three PGSV values.
    code, out, err = run_cli("score", pictures / "map.hdr", "--json", "--mask",
                             pictures / "mask.hdr", "--task", f"px:{SIZE // 2},{SIZE // 2}")
    assert code == 0, err
    mask = json.loads(out)["mask"]
    assert set(keys + ("illuminance", "n_pixels", "PGSV", "PGSV_sat", "PGSV_con")) <= set(mask)
    assert mask["min"] == pytest.approx(6000.0, rel=1e-2)  # the mask holds the window only


@pytest.mark.slow
@pytest.mark.parametrize("case", ["mask of another size", "zone centre off the image",
                                  "zone direction behind", "band angle 0", "band angle 181",
                                  "checkfile is a directory", "fill rows reversed"])
def test_bad_analysis_options_are_one_line_and_write_nothing(pictures, tmp_path, case):
    (tmp_path / "folder").mkdir()
    args = {
        "mask of another size": ("--mask", pictures / "small.hdr"),
        "zone centre off the image": ("--zones", f"px:{SIZE + 5},10,30"),
        "zone direction behind": ("--zones", "0,0,0,30"),
        "band angle 0": ("--band-deg", 0),
        "band angle 181": ("--band-deg", 181),
        "checkfile is a directory": ("--checkfile", tmp_path / "folder"),
        "fill rows reversed": ("--illuminance-fill", "2000,150,20"),
    }[case]
    out_json, check = tmp_path / "out.json", tmp_path / "check.hdr"
    extra = () if case == "checkfile is a directory" else ("--checkfile", check)
    code, out, err = run_cli("score", pictures / "map.hdr", *args, *extra, "--output-json",
                             out_json)
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert not out_json.exists() and not check.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder"]
    assert not any((tmp_path / "folder").iterdir())
