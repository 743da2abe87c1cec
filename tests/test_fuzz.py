"""Fuzzing: mutated input files through every reader and every CLI command that takes them.

Mutants (hypothesis, reproducible draws, bounded by ``max_examples`` and a per-example
deadline): byte flips, truncations, inserted and removed chunks of real and generated files —
the DNGs in data_samples/ and ../shared/realdata/raw, IES/LDT files (../shared/realdata/
photometry, else small files written here), OpenEXR and Radiance HDR maps, and TOML camera
profiles, scenes, survey manifests and design problems; for the text formats also replaced number tokens, and
for TOML replaced, removed and added values. Each mutant must give a result or an
:class:`~lsadphoto.errors.LsadError` from a reader, and from a command exit code 0, or 2 with
one error line on stderr and nothing left in the output folder. The count of mutants per
reader and command is printed at the end of the test run (tests/conftest.py).
"""

import io
import re
import shutil
import tempfile
import tomllib
import warnings
from contextlib import redirect_stderr, redirect_stdout
from datetime import timedelta
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lsadphoto.calibrate import CameraProfile
from lsadphoto.calibrate.profile import load_profile, save_profile
from lsadphoto.cli import main
from lsadphoto.datasets import SyntheticCamera, uniform_field, write_dng
from lsadphoto.design.problem import load_problem
from lsadphoto.errors import LsadError
from lsadphoto.geometry.pinhole import PinholeProjection
from lsadphoto.io import read_map, write_exr, write_hdr
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.raw.decode import decode_raw
from lsadphoto.solver import load_scene
from lsadphoto.solver.examples import canonical_room_toml
from lsadphoto.solver.photometry import read_photometry

from .conftest import REALDATA
from .test_photometry import write_ies, write_ldt

ROOT = Path(__file__).resolve().parents[1]
#: Per-example deadline: a mutant that takes this long to be read or refused hangs a user.
#: Generous: on a loaded 2-core machine one example of a CLI command has taken 51 s.
DEADLINE = timedelta(seconds=120)


# --------------------------------------------------------------------------- mutations


def _where(size):
    """A byte position: anywhere, or in the first 4 KiB where the headers are (half the draws)."""
    last = max(size - 1, 0)
    return st.one_of(st.integers(0, min(last, 4095)), st.integers(0, last))


def byte_mutations(size):
    """Strategy of byte-level mutations of a file of ``size`` bytes."""
    where = _where(size)
    return st.one_of(
        st.tuples(st.just("flip"), st.lists(st.tuples(where, st.integers(0, 255)), min_size=1, max_size=8)),
        st.tuples(st.just("truncate"), where),
        st.tuples(st.just("insert"), st.tuples(where, st.binary(min_size=1, max_size=64))),
        st.tuples(st.just("remove"), st.tuples(where, st.integers(1, 512))),
    )


#: Numbers that readers must refuse or handle: signs, zero, huge counts, non-finite, junk.
ODD_TOKENS = ["0", "-1", "-0", "1", "2", "3", "1e308", "-1e308", "nan", "inf", "999999999", "1e9",
              "4294967297", "180", "360", "-90", "0.5", "x", "1,5", ""]


def token_mutations(text):
    """Strategy replacing one whitespace-separated token of ``text`` by an odd one."""
    n = len(text.split())
    return st.tuples(st.just("token"), st.tuples(st.integers(0, max(n - 1, 0)), st.sampled_from(ODD_TOKENS)))


def _leaves(data, prefix=()):
    if isinstance(data, dict):
        for key, value in data.items():
            yield from _leaves(value, prefix + (key,))
    elif isinstance(data, list) and data:
        for i, value in enumerate(data):
            yield from _leaves(value, prefix + (i,))
    yield prefix


TOML_VALUES = st.one_of(
    st.integers(-(2**40), 2**40), st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8),
    st.booleans(), st.lists(st.integers(-5, 5), max_size=4), st.just({}), st.just([[1, 2], [3]]),
    st.just({"unknown_key": 1}),
)


def toml_mutations(data):
    """Strategy replacing, removing or adding a value anywhere in a parsed TOML document."""
    paths = [p for p in _leaves(data) if p]
    return st.tuples(st.sampled_from(["set", "delete", "add"]),
                     st.tuples(st.sampled_from(paths), TOML_VALUES))


def apply(data, mutation):
    """The mutated bytes of ``data`` (bytes)."""
    kind, arg = mutation
    if kind == "flip":
        out = bytearray(data)
        for pos, value in arg:
            out[pos % len(out)] = value
        return bytes(out)
    if kind == "truncate":
        return data[:arg]
    if kind == "insert":
        pos, chunk = arg
        return data[:pos] + chunk + data[pos:]
    if kind == "remove":
        pos, length = arg
        return data[:pos] + data[pos + length:]
    if kind == "token":
        index, token = arg
        parts = re.split(r"(\s+)", data.decode("latin-1"))
        words = [i for i, p in enumerate(parts) if p and not p.isspace()]
        if words:
            parts[words[index % len(words)]] = token
        return "".join(parts).encode("latin-1")
    action, (path, value) = arg if kind == "toml" else (kind, arg)
    doc = tomllib.loads(data.decode("utf-8"))
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    last = path[-1]
    if action == "set":
        parent[last] = value
    elif action == "delete":
        del parent[last]
    else:
        target = parent[last] if isinstance(parent[last], dict) else parent
        if isinstance(target, dict):
            target["fuzz_extra"] = value
    return tomli_w.dumps(doc).encode("utf-8")


def toml_or_bytes(data):
    """Mutations of a TOML file: its values (half the draws), or its bytes."""
    doc = tomllib.loads(data.decode("utf-8"))
    return st.one_of(
        toml_mutations(doc).map(lambda m: ("toml", (m[0], m[1]))), byte_mutations(len(data)))


def text_or_bytes(data):
    return st.one_of(token_mutations(data.decode("latin-1")), byte_mutations(len(data)))


# --------------------------------------------------------------------------- running


def _quiet_call(function, *args):
    """``function(*args)``; an LsadError is a clean refusal. Warnings are not errors here (a
    mutant may rightly warn), anything else propagates and fails the example."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            function(*args)
        except LsadError:
            pass


def run_cli(argv):
    """``lsadphoto ARGV`` in this process: exit code, stdout, stderr (warnings print as lines)."""
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err), warnings.catch_warnings():
        warnings.simplefilter("default")
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse
            code = exc.code
    return code, out.getvalue(), err.getvalue()


def check_cli(argv, outdir, expected=(), *, batch=False):
    """Exit 0 (only the expected outputs in ``outdir``) or 2 (one error line, ``outdir`` empty).

    ``batch``: a survey, whose views may fail one by one (exit 1, each failure reported and
    the finished work kept: docs/user-guide-survey.md).
    """
    code, out, err = run_cli(argv)
    lines = err.strip().splitlines()
    errors = [line for line in lines if not line.startswith("lsadphoto: warning:")]
    left = sorted(p.name for p in Path(outdir).iterdir())
    if batch and code == 1 and not errors:
        assert "failed" in out, out
        return
    assert code in (0, 2), f"exit {code}: {err}"
    if code == 2:
        assert len(errors) == 1 and errors[0].startswith("lsadphoto: error: "), err
        assert not left, f"left behind after an error: {left}"
    else:
        assert not errors, err
        assert set(left) <= set(expected), f"unexpected files: {left}"


def fuzz(record_property, name, seed, strategy, check, *, examples, suffix=None, siblings=()):
    """Run ``check(mutant_path, outdir)`` on ``examples`` mutants of ``seed`` (a file); the
    ``siblings`` (files the seed names by relative path) are copied beside each mutant."""
    data = Path(seed).read_bytes()
    count = 0
    work = Path(tempfile.mkdtemp(prefix="lsad-fuzz-"))

    @settings(max_examples=examples, deadline=DEADLINE, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(strategy(data))
    def run(mutation):
        nonlocal count
        count += 1
        case = work / f"case{count}"
        outdir = case / "out"
        outdir.mkdir(parents=True)
        for sibling in siblings:
            shutil.copy(sibling, case / Path(sibling).name)
        mutant = case / (Path(seed).stem + (suffix or Path(seed).suffix))
        mutant.write_bytes(apply(data, mutation))
        try:
            check(mutant, outdir)
        finally:
            shutil.rmtree(case, ignore_errors=True)

    # The unmutated seed first: it must pass too, and it pays the one-time costs (imports,
    # numba compilation: minutes on a loaded machine) outside the per-example deadline.
    warm = work / "seed"
    (warm / "out").mkdir(parents=True)
    for sibling in siblings:
        shutil.copy(sibling, warm / Path(sibling).name)
    shutil.copy(seed, warm / (Path(seed).stem + (suffix or Path(seed).suffix)))
    try:
        check(warm / (Path(seed).stem + (suffix or Path(seed).suffix)), warm / "out")
        run()
    finally:
        shutil.rmtree(work, ignore_errors=True)
        record_property("fuzz_mutants", (name, count))


# --------------------------------------------------------------------------- seed files


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fuzz-seeds")
    cam = SyntheticCamera(width=64, height=48)
    raw = cam.expose(uniform_field((48, 64), 50.0), exposure_time=1 / 125, f_number=4.0, iso=100, noise=False)
    write_dng(folder / "tiny.dng", raw, cam, exposure_time=1 / 125, f_number=4.0, iso=100)
    profile = CameraProfile(id="fuzz", sensor_width=cam.sensor_width, sensor_height=cam.sensor_height,
                            width=cam.width, height=cam.height, focal_length=cam.focal_length,
                            calibration_constant=cam.calibration_constant)
    save_profile(profile, folder / "profile.toml")
    projection = PinholeProjection(40.0, 40.0, 15.5, 11.5, 32, 24)
    lum = np.logspace(-1, 4, 24 * 32).reshape(24, 32).astype(np.float32)
    lmap = LuminanceMap(lum, projection=projection, uncertainty=0.05 * lum, calibrated=True)
    write_exr(lmap, folder / "map.exr")
    write_hdr(lmap, folder / "map.hdr")
    (folder / "room.toml").write_text(canonical_room_toml(size=8))
    photometry = sorted((REALDATA / "photometry").glob("*.ies")) + sorted((REALDATA / "photometry").glob("*.ldt"))
    if not photometry:  # a user's fresh clone: small files of both formats written here
        gamma, c = np.linspace(0, 90, 4), np.array([0.0])
        photometry = [write_ies(folder / "lamp.ies", gamma, c, [[100, 90, 50, 0]]),
                      write_ldt(folder / "lamp.ldt", [0.0], gamma, [100, 90, 50, 0], isym=1)]
    manifest = {"schema": "lsadphoto.survey/1", "profile": str(folder / "profile.toml"),
                "view": [{"id": "tiny", "raw": [str(folder / "tiny.dng")],
                          "spots": [{"row": 24, "col": 32, "cd_m2": 50.0}]}]}
    (folder / "survey.toml").write_text(tomli_w.dumps(manifest))
    code, _, err = run_cli(["simulate", folder / "room.toml", "-o", folder / "room.npz", "--samples", 256,
                            "--quiet"])
    assert code == 0, err
    return {"folder": folder, "photometry": photometry}


def _scene_with(folder, photometry):
    """A closed room lit by one point luminaire with ``photometry``; the scene file's path."""
    text = canonical_room_toml(size=8).split("\n[[luminaires]]")[0]
    text += (f'\n[[luminaires]]\ntype = "point"\nname = "lamp"\nposition = [3, 2, 2.5]\n'
             f'photometry = "{photometry.name}"\n')
    path = folder / "lamp-room.toml"
    path.write_text(text)
    return path


def _raw_seeds():
    seeds = [ROOT / "data_samples" / "office" / "office_1.dng", ROOT / "data_samples" / "flat" / "flat_1.dng"]
    real = REALDATA / "raw" / "tinydng_colorchart.dng"
    return seeds + ([real] if real.exists() else [])


# --------------------------------------------------------------------------- readers


@pytest.mark.parametrize("seed", _raw_seeds(), ids=lambda p: p.name)
def test_raw_reader(record_property, seed):
    examples = 6 if seed.stat().st_size > 1_000_000 else 25
    fuzz(record_property, "raw.decode_raw", seed, lambda d: byte_mutations(len(d)),
         lambda path, _: _quiet_call(decode_raw, path), examples=examples)


def test_photometry_readers(record_property, seeds):
    for seed in seeds["photometry"]:
        fuzz(record_property, f"photometry.read_{'ies' if seed.suffix == '.ies' else 'eulumdat'}", seed,
             text_or_bytes, lambda path, _: _quiet_call(read_photometry, path), examples=12)


@pytest.mark.parametrize("name", ["map.exr", "map.hdr"])
def test_map_readers(record_property, seeds, name):
    seed = seeds["folder"] / name
    fuzz(record_property, f"io.read_{name[-3:]}", seed, lambda d: byte_mutations(len(d)),
         lambda path, _: _quiet_call(read_map, path), examples=80)


@pytest.mark.parametrize("relative", ["hdr/raytraverse_rendered_desk_vta.hdr", "hdr/openexr_Desk.exr"])
def test_map_readers_on_real_files(record_property, relative):
    from .conftest import realdata

    seed = realdata(relative)
    fuzz(record_property, f"io.read_{seed.suffix[1:]} (real)", seed, lambda d: byte_mutations(len(d)),
         lambda path, _: _quiet_call(read_map, path), examples=5)


def test_toml_readers(record_property, seeds):
    from lsadphoto import survey

    folder = seeds["folder"]
    cases = [("calibrate.load_profile", ROOT / "calibration" / "synthetic-demo.toml", load_profile),
             ("calibrate.load_profile", ROOT / "calibration" / "ideal-fisheye-180.toml", load_profile),
             ("solver.load_scene", folder / "room.toml", load_scene),
             ("solver.load_scene", ROOT / "data_samples" / "stations" / "models" / "rows.toml", load_scene),
             ("survey.load_manifest", folder / "survey.toml", survey.load_manifest)]
    for name, seed, reader in cases:
        fuzz(record_property, name, seed, toml_or_bytes, lambda path, _, r=reader: _quiet_call(r, path),
             examples=30)
    design = ROOT / "data_samples" / "design"
    fuzz(record_property, "design.load_problem", design / "problem.toml", toml_or_bytes,
         lambda path, _: _quiet_call(load_problem, path), examples=30,
         siblings=[p for p in sorted(design.iterdir()) if p.name != "problem.toml"])


# --------------------------------------------------------------------------- commands


def test_cli_raw_commands(record_property, seeds):
    folder = seeds["folder"]
    seed = folder / "tiny.dng"
    fuzz(record_property, "cli luminance (RAW)", seed, lambda d: byte_mutations(len(d)),
         lambda path, out: check_cli(
             ["luminance", path, "--profile", folder / "profile.toml", "--spot", "24,32,50",
              "-o", out / "m.exr", "--hdr", out / "m.hdr", "--png", out / "m.png"],
             out, ("m.exr", "m.hdr", "m.png")), examples=15)
    fuzz(record_property, "cli calibrate vignetting (RAW)", seed, lambda d: byte_mutations(len(d)),
         lambda path, out: check_cli(["calibrate", "vignetting", path, "--id", "fuzz", "-o", out / "p.toml"],
                                     out, ("p.toml",)), examples=10)


@pytest.mark.parametrize("name", ["map.exr", "map.hdr"])
def test_cli_map_commands(record_property, seeds, name):
    folder = seeds["folder"]
    fuzz(record_property, f"cli score ({name[-3:].upper()})", folder / name, lambda d: byte_mutations(len(d)),
         lambda path, out: check_cli(["score", path, "--output-json", out / "s.json",
                                      "--sources-png", out / "s.png"], out, ("s.json", "s.png")),
         examples=12)
    fuzz(record_property, f"cli compare ({name[-3:].upper()})", folder / name, lambda d: byte_mutations(len(d)),
         lambda path, out: check_cli(["compare", folder / name, path, "--output-json", out / "c.json"],
                                     out, ("c.json",)), examples=8)
    fuzz(record_property, f"cli view ({name[-3:].upper()})", folder / name, lambda d: byte_mutations(len(d)),
         lambda path, out: check_cli(["view", path, "-o", out / "v.html"], out, ("v.html",)), examples=6)


def test_cli_toml_commands(record_property, seeds):
    folder = seeds["folder"]
    fuzz(record_property, "cli luminance --profile (TOML)", folder / "profile.toml", toml_or_bytes,
         lambda path, out: check_cli(["luminance", folder / "tiny.dng", "--profile", path, "--spot", "24,32,50",
                                      "-o", out / "m.exr"], out, ("m.exr",)), examples=10)
    fuzz(record_property, "cli render --profile (TOML)", ROOT / "calibration" / "synthetic-demo.toml",
         toml_or_bytes,
         lambda path, out: check_cli(["render", folder / "room.npz", "--profile", path, "--size", "40x26",
                                      "--position", "1,2,1.2", "--line-of-sight", "1,0,0",
                                      "--nodes-per-pixel", "1", "--quiet", "-o", out / "r.exr"],
                                     out, ("r.exr",)), examples=8)
    fuzz(record_property, "cli simulate (TOML scene)", folder / "room.toml", toml_or_bytes,
         lambda path, out: check_cli(["simulate", path, "--samples", "64", "--quiet", "-o", out / "s.npz"],
                                     out, ("s.npz",)), examples=10)
    fuzz(record_property, "cli render (TOML scene)", folder / "room.toml", toml_or_bytes,
         lambda path, out: check_cli(["render", path, "--samples", "64", "--nodes-per-pixel", "1", "--quiet",
                                      "-o", out / "r.exr"], out, ("r.exr",)), examples=8)
    fuzz(record_property, "cli survey (TOML manifest)", folder / "survey.toml", toml_or_bytes,
         lambda path, out: check_cli(["survey", path, "-o", out / "survey", "--workers", "0", "--quiet",
                                      "--no-report"], out, ("survey",), batch=True), examples=6)


def test_cli_photometry_in_a_scene(record_property, seeds):
    for seed in seeds["photometry"][:2] + seeds["photometry"][-1:]:
        def check(path, out, seed=seed):
            scene = _scene_with(path.parent, path)
            check_cli(["simulate", scene, "--samples", "64", "--quiet", "-o", out / "s.npz"], out, ("s.npz",))

        fuzz(record_property, f"cli simulate ({seed.suffix[1:].upper()} in a scene)", seed, text_or_bytes,
             check, examples=6)



def test_cli_design_command(record_property, tmp_path):
    # The worked example reduced to 2 positions × (off, downlight) = 4 designs on 16² views
    # with few chains, so that a mutant that stays valid runs a whole design quickly.
    from lsadphoto.datasets.design import make_design_samples

    folder = tmp_path / "design"
    make_design_samples(folder, size=16)
    problem = tomllib.loads((folder / "problem.toml").read_text())
    problem["catalogue"] = {"downlight": problem["catalogue"]["downlight"]}
    problem["positions"] = problem["positions"][:2]
    problem["simulation"] = {"samples": 512, "grid_nodes": 64}
    (folder / "problem.toml").write_text(tomli_w.dumps(problem))
    fuzz(record_property, "cli design (TOML problem)", folder / "problem.toml", toml_or_bytes,
         lambda path, out: check_cli(["design", path, "-o", out / "d", "--quiet"], out, ("d",)),
         examples=10, siblings=[p for p in sorted(folder.iterdir()) if p.name != "problem.toml"])

# --------------------------------------------------------------------------- found by fuzzing


def test_dng_with_an_empty_focal_plane_unit_is_read(tmp_path):
    # Byte 292 of office_1.dng set to 1 empties the FocalPlaneResolutionUnit tag's values
    # (exifread): the reader raised IndexError; the unit is now missing, the rest is read.
    data = bytearray((ROOT / "data_samples" / "office" / "office_1.dng").read_bytes())
    data[292] = 1
    path = tmp_path / "office_1.dng"
    path.write_bytes(bytes(data))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        image = decode_raw(path)
    assert image.sensor_shape == (424, 640)


def test_profile_with_a_table_as_lens_model_is_refused(tmp_path):
    # lens_model.model = {} raised TypeError (unhashable) in the schema checker.
    text = (ROOT / "calibration" / "synthetic-demo.toml").read_text().replace(
        'model = "pinhole"', "model = {}")
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(LsadError, match="lens_model.model must be one of"):
        load_profile(path)


def test_dng_with_corrupt_tags_is_one_line(seeds):
    # A zero byte inserted at 121 of the tiny DNG: tifffile raised TypeError inside the DNG tag
    # reader (an internal error, exit 1), and tifffile and exifread logged every bad tag to
    # stderr (35 lines); now exit 2 with our one line.
    folder = seeds["folder"]
    data = (folder / "tiny.dng").read_bytes()
    case = folder / "corrupt-tags"
    (case / "out").mkdir(parents=True)
    (case / "tiny.dng").write_bytes(data[:121] + b"\x00" + data[121:])
    code, _, err = run_cli(["luminance", case / "tiny.dng", "--profile", folder / "profile.toml",
                            "--spot", "24,32,50", "-o", case / "out" / "m.exr"])
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert not list((case / "out").iterdir())
