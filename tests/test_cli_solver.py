"""``lsadphoto simulate`` and ``lsadphoto render``: store, maps that ``score`` takes, errors.

Reference for the numbers: the map rendered through the CLI equals ``render`` called in
Python with the same store, pose and seed (the CLI adds nothing), and a Radiance scene's
light converts with 179 lm/W (FORMULAS.md §2.4.1) — checked in tests/test_solver_radiance.py.
"""

import json
import subprocess
import sys

import numpy as np
import pytest

from lsadphoto.io import read_exr
from lsadphoto.solver import camera_to_world, load_store, render
from lsadphoto.solver.examples import canonical_room_toml


def cli(*args):
    proc = subprocess.run([sys.executable, "-m", "lsadphoto.cli", *map(str, args)],
                          capture_output=True, text=True)
    return proc.returncode, proc.stdout, proc.stderr


@pytest.fixture(scope="module")
def store_path(tmp_path_factory):
    folder = tmp_path_factory.mktemp("solver")
    (folder / "room.toml").write_text(canonical_room_toml(size=32))
    code, out, err = cli("simulate", folder / "room.toml", "-o", folder / "room.npz",
                         "--samples", "4096", "--json")
    assert code == 0, err
    assert json.loads(out)["chains"] == 4096
    return folder / "room.npz"


def test_render_view_equals_python_render_and_scores(store_path, tmp_path):
    view = "-vta -vp 1 2 1.2 -vd 1 0 0 -vu 0 0 1 -vh 180 -vv 180"
    out = tmp_path / "m.exr"
    code, stdout, err = cli("render", store_path, f"--view={view}", "--size", "40x40", "-o", out,
                            "--hdr", tmp_path / "m.hdr", "--nodes-per-pixel", "8", "--json")
    assert code == 0, err
    lmap = read_exr(out)
    from lsadphoto.io.hdr import parse_view, projection_from_view

    proj = projection_from_view(parse_view(view), 40, 40)
    direct = render(load_store(store_path), proj, position=[1, 2, 1.2],
                    rotation=camera_to_world([1, 0, 0], [0, 0, 1]), nodes_per_pixel=8)
    # Same store, pose, seed and estimator: identical up to float32 storage.
    np.testing.assert_array_equal(lmap.luminance, direct.luminance)
    assert lmap.projection == proj
    code, stdout, err = cli("score", out, "--json")
    assert code == 0, err
    assert json.loads(stdout)["vertical_illuminance"] > 0


def test_render_scene_view_and_profile_pose(store_path, tmp_path):
    code, _, err = cli("render", store_path, "-o", tmp_path / "a.exr", "--nodes-per-pixel", "4")
    assert code == 0, err  # the scene's own [[views]] entry
    assert read_exr(tmp_path / "a.exr").shape == (32, 32)


@pytest.mark.parametrize("args, message", [
    (("--view=-vtl -vh 10", "--size", "4x4"), "-vtl"),
    (("--view=-vta -vh 180 -vv 180",), "--size"),
    (("--view-name", "nobody"), "no view 'nobody'"),
    (("--nodes-per-pixel", "many"), "--nodes-per-pixel"),
])
def test_render_bad_options_are_one_line(store_path, tmp_path, args, message):
    code, _, err = cli("render", store_path, *args, "-o", tmp_path / "x.exr")
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "x.exr").exists()


def test_simulate_bad_scene_is_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[[surfaces]]\n")
    code, _, err = cli("simulate", bad, "-o", tmp_path / "s.npz")
    assert code == 2 and "surfaces[0]" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "s.npz").exists()


def test_radiance_scene_renders(tmp_path):
    rad = tmp_path / "box.rad"
    rad.write_text("void plastic grey 0 0 5 .5 .5 .5 0 0\n"
                   "void light lamp 0 0 3 10 10 10\n"
                   "grey polygon floor 0 0 12 0 0 0  1 0 0  1 1 0  0 1 0\n"
                   "lamp polygon panel 0 0 12 0 0 1  0 1 1  1 1 1  1 0 1\n")
    code, _, err = cli("render", rad, "--view=-vtv -vp 0.5 0.5 0.5 -vd 0 0 -1 -vu 0 1 0 -vh 60 -vv 60",
                       "--size", "16x16", "--samples", "2048", "-o", tmp_path / "r.exr")
    assert code == 0, err
    # The floor (ρ = 0.5) under a 1 m² light of 179·10 cd/m² at 1 m: lit, below the light.
    L = read_exr(tmp_path / "r.exr").luminance
    assert 0 < np.nanmedian(L) < 1790


def test_render_through_the_nominal_demo_profile(store_path, tmp_path):
    """``--profile calibration/synthetic-demo.toml`` (a nominal 18 mm pinhole, no calibrated
    lens model): the map is the Python render through the pinhole built from the profile's
    numbers written out here (23.1 × 15.4 mm sensor, 640 × 424 px, f = 18 mm), binned by 4."""
    from pathlib import Path

    from lsadphoto.geometry.pinhole import PinholeProjection

    profile = Path(__file__).resolve().parents[1] / "calibration" / "synthetic-demo.toml"
    out = tmp_path / "nominal.exr"
    code, _, err = cli("render", store_path, "--profile", profile, "--size", "160x106",
                       "--position", "1,2,1.2", "--line-of-sight", "1,0,0", "--nodes-per-pixel", "4",
                       "-o", out)
    assert code == 0, err
    lmap = read_exr(out)
    expected = PinholeProjection.from_sensor(focal_length=18.0, sensor_width=23.1, sensor_height=15.4,
                                             width=640, height=424).binned(4)
    assert lmap.projection == expected
    direct = render(load_store(store_path), expected, position=[1, 2, 1.2],
                    rotation=camera_to_world([1, 0, 0], [0, 0, 1]), nodes_per_pixel=4)
    np.testing.assert_array_equal(lmap.luminance, direct.luminance)
