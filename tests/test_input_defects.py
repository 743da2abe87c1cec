"""Bad inputs of issue 17 (items 5–7) that were accepted, crashed or misled: each is
reproduced through the command a user runs and must now be one line, exit 2, nothing written
(or a warning where the input is legal but suspicious)."""

import shutil
from pathlib import Path

import numpy as np
import pytest

from lsadphoto.cli import main

from .conftest import realdata

DEMO_PROFILE = "calibration/synthetic-demo.toml"


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _error(capsys, *argv):
    code, _, err = _run(capsys, *argv)
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("lsadphoto: error: "), err
    return lines[0]


# --- camera profiles (item 6: internal errors; item 5: degree-50 polynomials) -------------

@pytest.mark.parametrize("edit, message", [
    (("width_px = 640", 'width_px = "640"'), "sensor.width_px must be an integer, got '640'"),
    (("    -0.3,", '    "-0.3",'), "vignetting.coefficients[0] must be a number, got '-0.3'"),
    (("    -0.3,", "    " + "0.0, " * 49 + "-0.3,"), "vignetting.coefficients must have 0 to 6 elements, got 51"),
    (("[noise]", "[nosie]"), "unknown key 'nosie' (did you mean 'noise'?)"),
    (("height_mm = 15.4", "heigth_mm = 15.4"), "[sensor] unknown key 'heigth_mm' (did you mean 'height_mm'?)"),
    (("calibration_constant = 12.0", "calibration_constant = -12.0"), "photometric.calibration_constant must be > 0"),
])
def test_bad_profile_is_one_line_before_any_work(tmp_path, capsys, edit, message):
    text = Path(DEMO_PROFILE).read_text(encoding="utf-8")
    assert edit[0] in text
    profile = tmp_path / "p.toml"
    profile.write_text(text.replace(edit[0], edit[1], 1))
    line = _error(capsys, "luminance", "data_samples/office/office_1.dng", "--profile", profile,
                  "-o", tmp_path / "out" / "m.exr")
    assert message in line and str(profile) in line
    assert not (tmp_path / "out").exists()


# --- calibration that wrote a profile as if fine (item 5) ---------------------------------

def test_vignetting_from_non_flat_frames_is_refused(tmp_path, capsys):
    out = tmp_path / "v.toml"
    line = _error(capsys, "calibrate", "vignetting", "data_samples/office/office_1.dng", "-o", out, "--id", "x")
    assert "RMS residual of 46.0 % (at most 5 % for a flat field)" in line
    assert not out.exists()


def test_vignetting_degree_beyond_the_maximum_is_refused(tmp_path, capsys):
    line = _error(capsys, "calibrate", "vignetting", "data_samples/flat/flat_1.dng", "-o", tmp_path / "v.toml",
                  "--degree", "50")
    assert "must be an integer from 1 to 6, got 50" in line


def test_real_flat_field_still_fits(tmp_path, capsys):
    # The shipped flats: a uniform field through the demo lens (V = 1 − 0.3 r² + 0.05 r⁴,
    # calibration/synthetic-demo.toml); residual 0.42 % is photon noise.
    code, out, err = _run(capsys, "calibrate", "vignetting", "data_samples/flat/flat_1.dng",
                          "data_samples/flat/flat_2.dng", "-o", tmp_path / "v.toml", "--id", "x")
    assert code == 0, err


@pytest.mark.realdata
def test_geometry_from_one_image_four_times_is_refused(tmp_path, capsys):
    image = sorted(realdata("calib/fisheye_chessboard").glob("*.jpg"))[0]
    copies = []
    for i in range(4):
        copies.append(tmp_path / f"view{i}.jpg")
        shutil.copy(image, copies[-1])
    line = _error(capsys, "calibrate", "geometry", *copies, "--pattern", "chessboard:6x9:25",
                  "--model", "fisheye", "-o", tmp_path / "g.toml")
    assert "needs at least 3 usable views" in line and "view1.jpg: same view as view0.jpg" in line
    assert not (tmp_path / "g.toml").exists()


def test_geometry_glob_that_matched_nothing(tmp_path, capsys):
    line = _error(capsys, "calibrate", "geometry", tmp_path / "*.png", "--pattern", "chessboard:9x6:25",
                  "-o", tmp_path / "g.toml")
    assert "*.png: does not exist" in line and "a shell pattern that matched no file" in line


# --- choices and defaults come from the library (issue 17, "one place for each") ----------

def test_cli_choices_and_defaults_are_the_librarys():
    import inspect

    from lsadphoto.cli import build_parser
    from lsadphoto.metrics.score import score_map
    from lsadphoto.raw.decode import DEMOSAIC_METHODS, decode_raw

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices
    lum = {a.dest: a for a in sub["luminance"]._actions}
    assert list(lum["demosaic"].choices) == list(DEMOSAIC_METHODS)
    assert inspect.signature(decode_raw).parameters["demosaic"].default == DEMOSAIC_METHODS[0]
    # score keeps explicit defaults (shown in --help): each must be score_map's own.
    score = {a.dest: a for a in sub["score"]._actions}
    params = inspect.signature(score_map).parameters
    for dest, param in [("source_method", "source_method"), ("background", "background_method"),
                        ("position_index", "position_index_method"),
                        ("peak_luminance", "peak_luminance"), ("N", "n_thresholds"),
                        ("alpha_arcmin", "size_arcmin"), ("task_opening_deg", "task_opening_deg"),
                        ("q_weight_exponent", "q_weight_exponent")]:
        assert score[dest].default == params[param].default, dest
    assert list(score["source_method"].choices)[0] == params["source_method"].default
    # the search angle is given in degrees; unset, the command passes the library's own radians
    from lsadphoto.metrics.grouping import DEFAULT_SEARCH_ANGLE

    assert score["search_angle_deg"].default is None
    assert params["search_angle"].default == DEFAULT_SEARCH_ANGLE


def test_unknown_choice_lists_the_librarys_values(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["score", "m.exr", "--background", "median"])
    assert exit_.value.code == 2
    assert "invalid choice: 'median' (choose from 'CIE', 'mean', 'Ev')" in capsys.readouterr().err


# --- spot readings (items 5 and 7) ---------------------------------------------------------

OFFICE = "data_samples/office/office_1.dng"  # 640×424 sensor px; spots.csv beside it


@pytest.mark.parametrize("angle", ["0", "-1"])
def test_spot_acceptance_angle_must_be_positive(tmp_path, capsys, angle):
    # was: 0 moved k from 15 573 to 46 132, −1 was taken as +1
    line = _error(capsys, "luminance", OFFICE, "--profile", DEMO_PROFILE, "--spot", "263,320,60",
                  "--acceptance-angle-deg", angle, "-o", tmp_path / "m.exr")
    assert f"acceptance angle must be above 0° and below 180° (full cone), got {float(angle):g}°" in line


def test_two_disagreeing_spots_warn_with_both_values(tmp_path, capsys):
    import warnings

    # spots.csv reads 28.5 cd/m² at (360, 96); 16× that disagrees with the 60 cd/m² at (263, 320)
    # (office_2: the bracket's frame where neither spot is saturated).
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        code, out, err = _run(capsys, "luminance", "data_samples/office/office_2.dng", "--profile", DEMO_PROFILE,
                              "--spot", "263,320,60", "--spot", "360,96,456", "-o", tmp_path / "m.exr")
    assert code == 0, err
    line = next(line for line in err.splitlines() if "spots disagree" in line)
    assert "at (263, 320) (60 cd/m²)" in line and "at (360, 96) (456 cd/m²)" in line, line
    assert "u = 7" in line or "u = 8" in line or "u = 9" in line, line  # the issue measured 88 %


def test_spot_off_the_image_is_named_in_sensor_pixels(tmp_path, capsys):
    line = _error(capsys, "luminance", OFFICE, "--profile", DEMO_PROFILE, "--spot", "5000,800,50",
                  "-o", tmp_path / "m.exr")
    # was: "spot at (2499.75, 399.75) is off the image (212×320 px)", superpixel coordinates
    assert "spot at (5000, 800) is off the image (424×640 sensor px" in line


def test_negative_spot_coordinate_hint(capsys):
    with pytest.raises(SystemExit):
        main(["luminance", OFFICE, "--spot", "-5,800,50", "-o", "m.exr"])
    assert "must be attached with '=': --spot=-5,800,50" in capsys.readouterr().err


def test_missing_exposure_names_real_ways_out(camera, shoot, tmp_path, capsys):
    no_meta = shoot(camera, np.full((camera.height, camera.width), 20.0), exposure_time=None)
    line = _error(capsys, "luminance", no_meta, "-o", tmp_path / "m.exr")
    assert "sidecar" not in line  # no such mechanism exists
    assert "--spot" in line and "exiftool" in line


# --- maps: geometry, metadata, uncertainty (items 5–7) -----------------------------------

def _pinhole_map(path, **fields):
    from lsadphoto.geometry import PinholeProjection
    from lsadphoto.io import write_exr
    from lsadphoto.luminance_map import LuminanceMap

    projection = PinholeProjection(30.0, 30.0, 15.5, 11.5, 32, 24)
    write_exr(LuminanceMap(np.full((24, 32), 100.0, np.float32), projection=projection, calibrated=True,
                           **fields), path)
    return path


def test_line_of_sight_through_a_point_off_a_pinhole_map(tmp_path, capsys):
    path = _pinhole_map(tmp_path / "m.exr")
    # was: accepted (a pinhole gives a direction for any point, even far off the image)
    line = _error(capsys, "score", path, "--line-of-sight", "px:9999,9999")
    assert "px:9999,9999: the point is off the image (24×32 px: ROW 0…23, COL 0…31)" in line


def _exr_with(path, header_extra, channels_extra=None):
    import OpenEXR

    channels = {"Y": np.full((4, 4), 10.0, np.float32), **(channels_extra or {})}
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, **header_extra},
                 channels).write(str(path))
    return path


_GOOD_PROJECTION = {"model": "pinhole", "fx": 4.0, "fy": 4.0, "cx": 1.5, "cy": 1.5, "width": 4, "height": 4}


@pytest.mark.parametrize("crafted", [
    {"calibration_factor": "banana"},
    {"calibrated": "no"},  # was: bool("no") is True
    {"calibration_uncertainty": -0.5},
    {"projection": dict(_GOOD_PROJECTION, fx=[1])},
    {"projection": dict(_GOOD_PROJECTION, width=9, height=9)},
    {"line_of_sight": "up"},
    {"provenance": 3},
])
def test_crafted_map_metadata_is_one_line(tmp_path, capsys, crafted):
    import json

    record = {"schema": "lsadphoto.luminance-map/1", "projection": _GOOD_PROJECTION, "calibrated": True, **crafted}
    path = _exr_with(tmp_path / "m.exr", {"lsadphoto.metadata": json.dumps(record)})
    line = _error(capsys, "score", path)  # was: internal errors (TypeError, ValueError) or accepted
    assert f"{path}: corrupt lsadphoto metadata" in line or f"{path}: projection is for" in line, line


def test_uncrafted_metadata_scores(tmp_path, capsys):
    import json

    record = {"schema": "lsadphoto.luminance-map/1", "projection": _GOOD_PROJECTION, "calibrated": True}
    path = _exr_with(tmp_path / "m.exr", {"lsadphoto.metadata": json.dumps(record)})
    code, _, err = _run(capsys, "score", path)
    assert code == 0, err


def test_negative_uncertainty_in_a_map_is_refused(tmp_path, capsys):
    uncertainty = np.full((4, 4), 1.0, np.float32)
    uncertainty[0, 0] = -1.0
    path = _exr_with(tmp_path / "m.exr", {}, {"Y.uncertainty": uncertainty})
    line = _error(capsys, "score", path)
    assert "uncertainty map has 1 negative value(s)" in line


@pytest.mark.parametrize("value", [np.inf, -np.inf])
@pytest.mark.parametrize("with_nan", [False, True])
def test_an_infinite_luminance_is_refused(value, with_nan):
    # NaN (pixels without a value) is allowed and must not hide an infinite one.
    from lsadphoto.errors import BadInputError
    from lsadphoto.luminance_map import LuminanceMap

    luminance = np.full((6, 7), 100.0, np.float32)
    if with_nan:
        luminance[0, :] = np.nan
    LuminanceMap(luminance.copy())
    luminance[4, 5] = value
    with pytest.raises(BadInputError, match="luminance map has infinite values"):
        LuminanceMap(luminance)


def test_negative_luminance_is_kept_and_noted():
    from lsadphoto.geometry import PinholeProjection
    from lsadphoto.luminance_map import LuminanceMap
    from lsadphoto.metrics.score import score_map

    luminance = np.full((24, 32), 100.0, np.float32)
    luminance[0, :5] = -2.0  # noise about zero in a signed map (issue 12)
    lmap = LuminanceMap(luminance, projection=PinholeProjection(30.0, 30.0, 15.5, 11.5, 32, 24), calibrated=True)
    assert np.count_nonzero(lmap.luminance < 0) == 5
    notes = score_map(lmap).notes
    assert any(n.startswith("5 pixel(s) have negative luminance") for n in notes), notes


def test_parallel_view_is_named(tmp_path, capsys):
    path = tmp_path / "parallel.hdr"
    pixel = bytes([128, 128, 128, 129])
    path.write_bytes(b"#?RADIANCE\nVIEW= -vtl -vp 0 0 0 -vd 0 1 0 -vh 10 -vv 10\nFORMAT=32-bit_rle_rgbe\n\n"
                     b"-Y 2 +X 2\n" + pixel * 4)
    line = _error(capsys, "score", path)  # was: "no VIEW= line" although there is one
    assert "VIEW= line '-vtl -vp 0 0 0 -vd 0 1 0 -vh 10 -vv 10'" in line and "-vtl (parallel)" in line


@pytest.mark.realdata
def test_radiance_rendering_note_says_what_uncalibrated_means(capsys):
    import json

    path = realdata("hdr/raytraverse_rendered_desk_vta.hdr")
    code, out, err = _run(capsys, "score", path, "--json")
    assert code == 0, err
    notes = json.loads(out)["notes"]
    assert any("a foreign file, e.g. a Radiance rendering" in n for n in notes), notes


# --- native libraries' chatter (item 7) ----------------------------------------------------

def _cli(*args):
    """A real process: the libraries write to file descriptors 1 and 2, past Python."""
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "lsadphoto.cli", *map(str, args)], capture_output=True, text=True)
    return proc.returncode, proc.stdout, proc.stderr


def test_truncated_dng_and_exr_print_only_our_line(tmp_path):
    dng = tmp_path / "cut.dng"
    dng.write_bytes(Path(OFFICE).read_bytes()[:5000])
    code, out, err = _cli("luminance", dng, "--profile", DEMO_PROFILE, "-o", tmp_path / "m.exr")
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert "truncated" in err and "Unexpected end of file" not in err.split(": error: ")[0]
    full = _pinhole_map(tmp_path / "full.exr")
    exr = tmp_path / "cut.exr"
    exr.write_bytes(full.read_bytes()[:-200])
    code, out, err = _cli("score", exr)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, (out, err)
    assert "not a readable OpenEXR file" in err


# --- render views (item 5) -----------------------------------------------------------------

@pytest.fixture(scope="module")
def room(tmp_path_factory):
    from lsadphoto.solver.examples import canonical_room_toml

    path = tmp_path_factory.mktemp("room") / "room.toml"
    path.write_text(canonical_room_toml(size=8))
    return path


@pytest.mark.parametrize("view, message", [
    ("banana", "'banana' in view 'banana' is not a Radiance view option"),
    ("-vta -vp 1 2 1.2 -vd 1 0 0 -vz 3", "'-vz' in view"),
    ("-vtx -vp 1 2 1.2", "unknown Radiance view type -vtx"),
    ("-vta -vd 1 0 0", "gives no eye position (-vp X Y Z [m])"),
    ("-vta -vp 1 2", "bad view option -vp"),
])
def test_render_view_is_checked(room, tmp_path, capsys, view, message):
    # was: "banana" rendered from (0, 0, 0), unknown options were ignored
    line = _error(capsys, "render", room, f"--view={view}", "--size", "8x8", "-o", tmp_path / "m.exr")
    assert message in line
    assert not (tmp_path / "m.exr").exists()


# --- solver inputs (item 5) ----------------------------------------------------------------

def test_target_error_below_the_floor_is_refused(room, tmp_path, capsys):
    # was: --target-error 1e-9 ran on towards 16 M chains
    line = _error(capsys, "simulate", room, "--target-error", "1e-9", "-o", tmp_path / "s.npz")
    assert "target_error must be a relative error from 0.0001 to below 1, got 1e-09" in line
    assert not (tmp_path / "s.npz").exists()


def test_luminaire_outside_the_room_warns(tmp_path):
    import warnings

    from lsadphoto.errors import SolverWarning
    from lsadphoto.solver import load_scene
    from lsadphoto.solver.examples import canonical_room_toml

    text = canonical_room_toml(size=8)
    inside, outside = tmp_path / "in.toml", tmp_path / "out.toml"
    inside.write_text(text)
    assert text.count("2.99]") == 16  # four luminaires at z = 2.99 m under the 3 m ceiling
    outside.write_text(text.replace("2.99]", "12.99]"))  # 10 m above the room
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_scene(inside)  # was and is: no warning
    # was: no warning, and a black render
    with pytest.warns(SolverWarning, match=r"luminaire 'L1' near \(1.5, 1, 12.99\) m \(and 3 more\) is outside the closed room"):
        load_scene(outside)
