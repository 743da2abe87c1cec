"""Bad inputs of issue 17 (items 5–7) that were accepted, crashed or misled: each is
reproduced through the command a user runs and must now be one line, exit 2, nothing written
(or a warning where the input is legal but suspicious)."""

import shutil
from pathlib import Path

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
                        ("position_index", "position_index_method"), ("search_angle", "search_angle"),
                        ("peak_luminance", "peak_luminance"), ("N", "n_thresholds"),
                        ("alpha_arcmin", "size_arcmin"), ("task_opening_deg", "task_opening_deg"),
                        ("q_weight_exponent", "q_weight_exponent")]:
        assert score[dest].default == params[param].default, dest
    assert list(score["source_method"].choices)[0] == params["source_method"].default


def test_unknown_choice_lists_the_librarys_values(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["score", "m.exr", "--background", "median"])
    assert exit_.value.code == 2
    assert "invalid choice: 'median' (choose from 'CIE', 'mean', 'Ev')" in capsys.readouterr().err
