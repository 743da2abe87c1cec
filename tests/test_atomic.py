"""The grouped atomic writer (lsadphoto._atomic) and every command's outputs through it.

Each case reproduces a defect of issue 17 item 1: outputs left behind after an output problem,
output problems reported as internal errors, checks made only after the work.
"""

import errno
import os

import numpy as np
import pytest

from lsadphoto._atomic import plan_outputs
from lsadphoto.calibrate import save_profile
from lsadphoto.cli import main
from lsadphoto.errors import BadInputError, OutputError



def _files(folder):
    return sorted(p.name for p in folder.rglob("*"))


def _one_error_line(capsys):
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("lsadphoto: error: "), err
    return lines[0]


@pytest.fixture
def luminance_args(camera, shoot, profile_for, tmp_path):
    dng = shoot(camera, np.full((camera.height, camera.width), 30.0))
    profile = tmp_path / "camera.toml"
    save_profile(profile_for(camera), profile)
    return ["luminance", str(dng), "--profile", str(profile)]


def test_output_that_is_a_folder_writes_nothing(luminance_args, tmp_path, capsys):
    out = tmp_path / "out"
    (out / "existing_dir.png").mkdir(parents=True)
    code = main([*luminance_args, "-o", str(out / "o.exr"), "--hdr", str(out / "o.hdr"),
                 "--png", str(out / "existing_dir.png")])
    assert code == 2  # was: internal error (exit 1) with o.exr and o.hdr left behind
    assert "existing_dir.png is an existing folder" in _one_error_line(capsys)
    assert _files(out) == ["existing_dir.png"]


def test_three_outputs_on_one_path_are_refused(luminance_args, tmp_path, capsys):
    same = tmp_path / "out" / "same.exr"
    code = main([*luminance_args, "-o", str(same), "--hdr", str(same), "--png", str(same)])
    assert code == 2  # was: "wrote same.exr", with a PNG in it
    assert "are the same file" in _one_error_line(capsys)
    assert not same.parent.exists()


def test_parent_that_is_a_file(luminance_args, tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("x")
    assert main([*luminance_args, "-o", str(tmp_path / "notes.txt" / "m.exr")]) == 2
    assert "notes.txt is a file, not a folder" in _one_error_line(capsys)


def test_folder_that_cannot_be_written(tmp_path, capsys):
    # /proc refuses new files even for root, for whom a chmod'ed folder would be writable.
    code = main(["luminance", str(tmp_path / "nope.dng"), "-o", "/proc/lsad_test.exr"])
    assert code == 2  # was: an internal error after the work
    assert "/proc is not writable" in _one_error_line(capsys)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder(tmp_path, capsys):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        assert main(["luminance", str(tmp_path / "nope.dng"), "-o", str(folder / "m.exr")]) == 2
    finally:
        folder.chmod(0o700)
    assert "is not writable" in _one_error_line(capsys)


def _commands(tmp_path, bad):
    """Every command with outputs, its input missing and one output on an existing folder: the
    output must be refused before the input is even read."""
    missing = str(tmp_path / "missing")
    return {
        "luminance": ["luminance", missing + ".dng", "-o", bad],
        "vignetting": ["calibrate", "vignetting", missing + ".dng", "-o", bad],
        "geometry": ["calibrate", "geometry", missing + ".png", "--pattern", "chessboard:9x6:25", "-o", bad],
        "score sources": ["score", missing + ".exr", "--sources-png", bad],
        "score contrast": ["score", missing + ".exr", "--contrast-png", bad],
        "score json": ["score", missing + ".exr", "--output-json", bad],
        "compare ratio": ["compare", missing + ".exr", missing + ".exr", "--ratio-png", bad],
        "compare report": ["compare", missing + ".exr", missing + ".exr", "--report", bad],
        "study json": ["study", missing + ".csv", missing + ".csv", "--output-json", bad],
        "study figures": ["study", missing + ".csv", missing + ".csv", "--figures", str(tmp_path / "f.txt")],
        "simulate": ["simulate", missing + ".toml", "-o", bad],
        "render": ["render", missing + ".toml", "-o", bad],
        "view": ["view", missing + ".exr", "-o", str(tmp_path / "taken.html")],
    }


def test_every_command_checks_outputs_before_work(tmp_path, capsys):
    bad = tmp_path / "taken.exr"
    bad.mkdir()
    (tmp_path / "taken.html").mkdir()
    (tmp_path / "f.txt").write_text("a file where a folder is wanted")
    for name, argv in _commands(tmp_path, str(bad)).items():
        assert main(argv) == 2, name
        line = _one_error_line(capsys)
        assert ("is an existing folder" in line or "f.txt is an existing file" in line), (name, line)
    assert _files(tmp_path) == ["f.txt", "taken.exr", "taken.html"]


def test_oserror_while_writing_is_one_line_and_keeps_targets(tmp_path):
    old = tmp_path / "a.txt"
    old.write_text("old")
    plan = plan_outputs({"a": old, "b": tmp_path / "sub" / "b.txt"})
    with pytest.raises(OutputError, match="cannot write .*No space left"):
        with plan.write() as temps:
            temps["a"].write_text("new")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(temps["b"]))
    assert old.read_text() == "old" and _files(tmp_path) == ["a.txt"]  # no temporaries, no 'sub'


def test_rename_failure_rolls_back_every_target(tmp_path):
    # Another process makes a folder at the second target while the first was being written.
    first, second = tmp_path / "a.exr", tmp_path / "b.hdr"
    first.write_text("old a")
    plan = plan_outputs({"a": first, "b": second})
    with pytest.raises(OutputError, match="b.hdr"):
        with plan.write() as temps:
            temps["a"].write_text("new a")
            temps["b"].write_text("new b")
            second.mkdir()
    assert first.read_text() == "old a"
    assert _files(tmp_path) == ["a.exr", "b.hdr"]


def test_folder_output_is_staged_and_merged(tmp_path):
    target = tmp_path / "figures"
    target.mkdir()
    (target / "keep.png").write_text("kept")
    (target / "r.png").write_text("old")
    plan = plan_outputs({}, folders={"figures": target})
    with plan.write() as temps:
        (temps["figures"] / "r.png").write_text("new")
        (temps["figures"] / "s.png").write_text("new")
    assert {p.name: p.read_text() for p in target.iterdir()} == {"keep.png": "kept", "r.png": "new",
                                                               "s.png": "new"}
    assert _files(tmp_path) == ["figures", "keep.png", "r.png", "s.png"]


def test_same_file_under_two_spellings(tmp_path):
    (tmp_path / "d").mkdir()
    with pytest.raises(BadInputError, match="same file"):
        plan_outputs({"x": tmp_path / "m.exr", "y": tmp_path / "d" / ".." / "m.exr"})


def test_luminance_outputs_all_written(luminance_args, tmp_path):
    out = tmp_path / "new" / "deeper"
    assert main([*luminance_args, "--spot", "115,128,60", "-o", str(out / "m.exr"),
                 "--hdr", str(out / "m.hdr"), "--png", str(out / "m.png")]) == 0
    assert _files(out) == ["m.exr", "m.hdr", "m.png"]


def test_error_in_a_writer_names_the_target_not_the_temporary(tmp_path, monkeypatch):
    from lsadphoto.io import exr as exr_module
    from lsadphoto.io import write_exr
    from lsadphoto.luminance_map import LuminanceMap

    class FullDisk:
        def __init__(self, header, channels):
            pass

        def write(self, name):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), name)

    monkeypatch.setattr(exr_module.OpenEXR, "File", FullDisk)
    target = tmp_path / "m.exr"
    plan = plan_outputs({"exr": target})
    with pytest.raises(OutputError) as caught:
        with plan.write() as temps:
            write_exr(LuminanceMap(np.ones((2, 2))), temps["exr"])
    assert str(caught.value) == f"cannot write {target}: No space left on device"
    assert _files(tmp_path) == []
