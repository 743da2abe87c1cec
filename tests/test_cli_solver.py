"""``lsadphoto simulate`` and ``lsadphoto render``: store, maps that ``score`` takes, errors.

Reference for the numbers: the map rendered through the CLI equals ``render`` called in
Python with the same store, pose and seed (the CLI adds nothing), and a Radiance scene's
light converts with 179 lm/W (FORMULAS.md §2.4.1) — checked in tests/test_solver_radiance.py.
"""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from lsadphoto.io import read_exr
from lsadphoto.solver import camera_to_world, load_store, render
from lsadphoto.solver.examples import canonical_room_toml
from .conftest import radiance_tool


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
    # E_v of the rendered map is Σ L·ω·cos θ over its pixels (the definition; cos θ about the
    # optical axis, the default line of sight), with ω and θ from the camera model.
    grid = proj.pixel_grid()
    omega, d = proj.solid_angles(*grid), proj.directions(*grid)
    known = np.isfinite(lmap.luminance) & (omega > 0)
    cos_theta = np.clip(d[known][:, 2], 0, None)
    luminance = np.asarray(lmap.luminance, np.float64)[known]
    e_v = float(np.sum(luminance * omega[known] * cos_theta))
    # The score's cos σ map is float32 (VisualField: each value rounded once, relative
    # 2⁻²⁴): to 1e-9 the sum with cos θ so rounded, and within 2⁻²⁴ of the float64 sum.
    stored = float(np.sum(luminance * omega[known] * cos_theta.astype(np.float32)))
    assert json.loads(stdout)["vertical_illuminance"] == pytest.approx(stored, rel=1e-9)
    assert json.loads(stdout)["vertical_illuminance"] == pytest.approx(e_v, rel=2.0 ** -24)


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


@pytest.mark.parametrize("view", [
    "-vta -vp 1 2 1.2 -vd 1 0 0 -vu 0 0 1 -vh 180 -vv 150",
    "-vtv -vp 4.5 1.5 1.6 -vd -1 0.5 -0.2 -vu 0 0 1 -vh 60 -vv 45",
])
def test_rendered_hdr_view_is_the_rendered_view(store_path, tmp_path, view):
    """Issue 13: the VIEW= line of a render carries its pose; Radiance's vwrays on that line
    gives the very rays the renderer traced (world directions of every pixel centre)."""
    from lsadphoto.io import read_hdr
    from lsadphoto.io.hdr import parse_view

    hdr, exr = tmp_path / "m.hdr", tmp_path / "m.exr"
    code, _, err = cli("render", store_path, f"--view={view}", "--size", "12x10", "-o", exr,
                       "--hdr", hdr, "--quiet")
    assert code == 0, err
    line = next(t for t in hdr.read_bytes().split(b"\n\n", 1)[0].decode().splitlines()
                if t.startswith("VIEW="))
    written = parse_view(line[5:])
    assert " -0 " not in line + " ", line  # a negative zero means nothing to a reader of the header
    given = parse_view(view)
    for key in ("vp", "vd", "vu"):
        direction = np.asarray(given[key], float)
        if key != "vp":
            direction = direction / np.linalg.norm(direction)
            if key == "vu":  # Radiance keeps only the part of vu orthogonal to vd
                vd = np.asarray(given["vd"], float) / np.linalg.norm(given["vd"])
                direction = direction - direction.dot(vd) * vd
                direction /= np.linalg.norm(direction)
        np.testing.assert_allclose(np.asarray(written[key], float), direction, atol=1e-12)
    out = subprocess.run([radiance_tool("vwrays"), "-fd", "-x", "12", "-y", "10", "-pa", "0",
                          "-vf", str(hdr)], capture_output=True, check=True).stdout
    rays = np.frombuffer(out, dtype=np.float64).reshape(10, 12, 6)  # scanlines from the top
    lmap = read_hdr(hdr)
    rows, cols = lmap.projection.pixel_grid()
    d_cam = lmap.projection.directions(rows, cols).reshape(10, 12, 3)
    rot = camera_to_world(given["vd"], given["vu"])
    d_world = d_cam @ rot.T
    ok = np.all(np.isfinite(d_world), axis=-1)
    # Both evaluate closed forms in double precision from 17-digit view options.
    np.testing.assert_allclose(rays[..., 3:][ok], d_world[ok], atol=1e-9)
    np.testing.assert_allclose(rays[..., :3][ok], np.broadcast_to(given["vp"], d_world.shape)[ok], atol=1e-12)


def test_options_that_cannot_apply_to_a_store_are_errors(store_path, tmp_path):
    view = "-vta -vp 1 2 1.2 -vd 1 0 0 -vu 0 0 1 -vh 180 -vv 180"
    out = tmp_path / "m.exr"
    for extra, message in ((["--samples", "100"], "--samples applies when rendering a scene directly"),
                           (["--target-error", "0.02"], "--target-error applies when rendering a scene"),
                           (["--cache-nodes", "64"], "--cache-nodes apply to the surface cache (--estimator cache)")):
        code, _, err = cli("render", store_path, f"--view={view}", "--size", "8x8", "-o", out, *extra)
        assert code == 2 and message in err and err.count("\n") == 1, err
        assert not out.exists()


def test_render_a_scene_to_a_per_pixel_target_error(tmp_path):
    # The target bounds the mean absolute relative error that the map's own uncertainties
    # imply, √(2/π)·mean(σ/L): recomputed here from its EXR (luminance and per-pixel
    # uncertainty, float32), it must be at most the target.
    scene = tmp_path / "room.toml"
    scene.write_text(canonical_room_toml(size=16))
    out = tmp_path / "m.exr"
    code, stdout, err = cli("render", scene, "--samples", "1024", "--target-error", "0.015",
                            "--estimator", "local", "--quiet", "-o", out)
    assert code == 0, err
    assert "target per-pixel error 1.5 % reached (chains per round: 1024 → " in stdout, stdout
    lmap = read_exr(out)
    lit = np.isfinite(lmap.luminance) & (lmap.luminance > 0)
    assert math.sqrt(2 / math.pi) * np.mean(lmap.uncertainty[lit] / lmap.luminance[lit]) <= 0.015 * (1 + 1e-5)
    # The default: a scene without --samples renders to 2 % per pixel, by the surface cache
    # ("auto" says so), whose rounds grow chains, node draws and shadow rays together.
    code, stdout, err = cli("render", scene, "--quiet", "-o", out)
    assert code == 0, err
    assert "estimator auto: cache (a per-pixel target" in stdout, stdout
    assert "target per-pixel error 2 % reached" in stdout, stdout
    lmap = read_exr(out)
    lit = np.isfinite(lmap.luminance) & (lmap.luminance > 0)
    assert math.sqrt(2 / math.pi) * np.mean(lmap.uncertainty[lit] / lmap.luminance[lit]) <= 0.02 * (1 + 1e-5)
    assert "cache" in lmap.provenance["estimator"] and lmap.provenance["rounds"][0]["cache_nodes"] > 0
    code, _, err = cli("render", scene, "--estimator", "cache", "--nodes-per-pixel", "4", "-o", out)
    assert code == 2 and "--nodes-per-pixel applies to --estimator local" in err


#: A glossy floor (Radiance plastic, specularity 0.05) under a 1 m² light panel of 1790 cd/m².
GLOSSY_RAD = ("void plastic floor 0 0 5 .2 .2 .2 .05 .05\nvoid light lamp 0 0 3 10 10 10\n"
              "floor polygon f 0 0 12 -3 -3 0  3 -3 0  3 3 0  -3 3 0\n"
              "lamp polygon panel 0 0 12 -.5 -.5 3  -.5 .5 3  .5 .5 3  .5 -.5 3\n")


@pytest.mark.slow
def test_a_glossy_scene_renders_by_default_and_says_how(tmp_path):
    # "auto" renders a scene with materials by the double local estimate with materials (the
    # unbiased reference; the surface cache is a choice), to the default per-pixel target of
    # 2 % (rounds of chains), and says so. The floor under the panel must be lit and darker than the panel's 1790 cd/m² (ρ ≤ 0.25).
    rad = tmp_path / "glossy.rad"
    rad.write_text(GLOSSY_RAD)
    out = tmp_path / "g.exr"
    code, stdout, err = cli("render", rad, "--view=-vtv -vp 0 0 1.5 -vd 0 0 -1 -vu 0 1 0 -vh 60 -vv 60",
                            "--size", "8x8", "--quiet", "-o", out)
    assert code == 0, err
    assert "estimator auto: local (non-Lambertian materials" in stdout, stdout
    assert "target per-pixel error 2 % reached" in stdout, stdout
    lmap = read_exr(out)
    L = lmap.luminance
    assert 0 < np.nanmedian(L) < 1790
    lit = np.isfinite(L) & (L > 0)
    assert math.sqrt(2 / math.pi) * np.mean(lmap.uncertainty[lit] / L[lit]) <= 0.02 * (1 + 1e-5)


def test_a_glossy_scene_simulates_once_and_renders_many_views(tmp_path):
    # simulate writes a store of the material chains; every view rendered from it by the CLI
    # equals render() of the scene itself in Python with the same chains and seed (one call,
    # no store file), to float32 storage; options that cannot apply to it are one-line errors.
    from lsadphoto.io.hdr import parse_view, projection_from_view
    from lsadphoto.solver import read_radiance_scene

    rad, store = tmp_path / "glossy.rad", tmp_path / "glossy.npz"
    rad.write_text(GLOSSY_RAD)
    code, out, err = cli("simulate", rad, "--samples", "1024", "--seed", "5", "-o", store, "--quiet", "--json")
    assert code == 0, err
    assert json.loads(out)["chains"] == 1024
    scene = read_radiance_scene(rad)
    for view in ("-vtv -vp 0 0 1.5 -vd 0 0 -1 -vu 0 1 0 -vh 60 -vv 60",
                 "-vtv -vp 2 -2 1 -vd -1 1 -0.6 -vu 0 0 1 -vh 50 -vv 50"):
        code, _, err = cli("render", store, f"--view={view}", "--size", "6x6", "--seed", "5", "--quiet",
                           "-o", tmp_path / "m.exr")
        assert code == 0, err
        given = parse_view(view)
        direct = render(scene, projection_from_view(given, 6, 6), position=given["vp"],
                        rotation=camera_to_world(given["vd"], given["vu"]), samples=1024, seed=5)
        lmap = read_exr(tmp_path / "m.exr")
        np.testing.assert_array_equal(lmap.luminance, direct.luminance)
        np.testing.assert_array_equal(lmap.uncertainty, np.asarray(direct.uncertainty, np.float32))
    # to a target: the scene has no view, so the error is that of the flux arriving on its surfaces
    code, out, err = cli("simulate", rad, "--target-error", "0.01", "-o", tmp_path / "t.npz", "--quiet")
    assert code == 0 and "relative error of the surface-incident flux" in out, (out, err)
    assert load_store(tmp_path / "t.npz").provenance["achieved_relative_error"] <= 0.01
    view = "--view=-vtv -vp 0 0 1.5 -vd 0 0 -1 -vu 0 1 0 -vh 60 -vv 60"
    for command, message in (
            (("render", store, view, "--size", "4x4", "--nodes-per-pixel", "all"), "'all' applies to Lambertian"),
            (("render", store, view, "--size", "4x4", "--target-error", "0.02"), "--target-error applies when")):
        code, _, err = cli(*command, "--quiet", "-o", tmp_path / "bad.exr")
        assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
        assert not (tmp_path / "bad.exr").exists()


def test_fresnel_rule_option(tmp_path):
    # --fresnel-rule radiance: the store records it, the CLI's map equals render() of the scene
    # in Python under the same rule (the CLI adds nothing); another rule for that store, or an
    # unknown one, is a one-line error with exit 2.
    from lsadphoto.io.hdr import parse_view, projection_from_view
    from lsadphoto.solver import read_radiance_scene

    rad, store = tmp_path / "smooth.rad", tmp_path / "smooth.npz"
    rad.write_text(GLOSSY_RAD.replace(".05 .05\n", ".05 0\n"))   # a smooth floor: the rule matters
    code, out, err = cli("simulate", rad, "--samples", "512", "--seed", "5", "--fresnel-rule", "radiance",
                         "-o", store, "--quiet", "--json")
    assert code == 0, err
    assert json.loads(out)["provenance"]["fresnel_rule"] == "radiance"
    assert load_store(store).fresnel_rule == "radiance"
    view = "-vtv -vp 0 0 1.5 -vd 0 0 -1 -vu 0 1 0 -vh 60 -vv 60"
    code, _, err = cli("render", store, f"--view={view}", "--size", "4x4", "--seed", "5", "--quiet",
                       "-o", tmp_path / "m.exr")
    assert code == 0, err
    given = parse_view(view)
    direct = render(read_radiance_scene(rad), projection_from_view(given, 4, 4), position=given["vp"],
                    rotation=camera_to_world(given["vd"], given["vu"]), samples=512, seed=5, fresnel_rule="radiance")
    np.testing.assert_array_equal(read_exr(tmp_path / "m.exr").luminance, direct.luminance)
    code, _, err = cli("render", store, f"--view={view}", "--size", "4x4", "--fresnel-rule", "reciprocal",
                       "--quiet", "-o", tmp_path / "bad.exr")
    assert code == 2 and "differs from the store's 'radiance'" in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "bad.exr").exists()
    # argparse's own message for an unknown choice (usage, then one error line naming the valid ones)
    code, _, err = cli("simulate", rad, "--fresnel-rule", "ward", "-o", tmp_path / "bad.npz")
    assert code == 2 and "invalid choice: 'ward' (choose from 'reciprocal', 'radiance')" in err.splitlines()[-1]
    assert not (tmp_path / "bad.npz").exists()
