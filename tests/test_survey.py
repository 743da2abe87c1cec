"""Survey runner: manifest checks, outputs, resuming, failures, local pool vs Dask.

The views are the bundled synthetic office bracket (``data_samples/office``, made by
``lsadphoto.datasets.samples``) and the demo camera profile, copied beside a manifest so
that relative paths are exercised. One survey with four views (three good, one corrupt RAW)
is run once per module with the local spawn pool; the other tests reuse or copy its output.
"""

import csv
import json
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from lsadphoto.errors import BadInputError
from lsadphoto.survey import LOCK_NAME, SWEEP, StaleLockWarning, load_manifest, run_survey

ROOT = Path(__file__).resolve().parents[1]
OFFICE = ROOT / "data_samples" / "office"
PROFILE = ROOT / "calibration" / "synthetic-demo.toml"
GOOD = ["bracket", "single", "uncalibrated"]
#: Columns that differ between two runs of the same views.
VOLATILE = ("timestamp",)

MANIFEST = """\
schema = "lsadphoto.survey/1"
name = "test survey"
profile = "camera.toml"

[score]
n_thresholds = 50
size_arcmin = 10

[[view]]
id = "bracket"
raw = ["office/office_1.dng", "office/office_2.dng", "office/office_3.dng"]
spots = "office/spots.csv"
ratings = [4, 5, 3]

[[view]]
id = "single"
raw = "office/office_2.dng"
spots = [{row = 263, col = 320, cd_m2 = 60}]
line_of_sight = [0.0, 0.1, 1.0]
ratings = "single-ratings.csv"
note = "one frame, one spot"
[view.model]
scene = "model.toml"
position = [1.0, 2.0, 1.6]
direction = [1.0, 0.0, 0.0]
samples = 2000
nodes_per_pixel = 2

[[view]]
id = "uncalibrated"
raw = ["office/office_1.dng", "office/office_3.dng"]
[view.score]
source_threshold = 1500

[[view]]
id = "corrupt"
raw = "broken.dng"
"""


MODEL = """
[materials]
wall = { reflectance = 0.5 }
[[surfaces]]
type = "box"
min = [0, 0, 0]
max = [6, 4, 3]
material = "wall"
[[luminaires]]
type = "area"
flux = 3000
shape = { type = "polygon", vertices = [[2.7, 1.7, 2.99], [2.7, 2.3, 2.99], [3.3, 2.3, 2.99], [3.3, 1.7, 2.99]] }
"""


#: The manifest with only the corrupt view: a survey that fails fast, without decoding.
CORRUPT_ONLY = MANIFEST[:MANIFEST.index("[[view]]")] + '[[view]]\nid = "corrupt"\nraw = "broken.dng"\n'


def cli(*args):
    return subprocess.run([sys.executable, "-m", "lsadphoto.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=600)


def make_survey(folder, text=MANIFEST):
    """A survey folder: manifest, RAW files, profile, ratings, model; returns the manifest."""
    folder.mkdir(parents=True, exist_ok=True)
    if not (folder / "office").exists():
        shutil.copytree(OFFICE, folder / "office")
    shutil.copy(PROFILE, folder / "camera.toml")
    (folder / "single-ratings.csv").write_text("observer,rating\nanna,6\nboris,7.5\n")
    (folder / "model.toml").write_text(MODEL)
    # Garbage with a RAW suffix, as a truncated copy from a memory card gives.
    (folder / "broken.dng").write_bytes(np.random.default_rng(1).bytes(4096))
    path = folder / "survey.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def surveyed(tmp_path_factory):
    """The four-view survey run once with the local spawn pool (2 workers)."""
    folder = tmp_path_factory.mktemp("survey")
    manifest = make_survey(folder)
    outdir = folder / "out"
    result = run_survey(manifest, outdir, workers=2, progress=False)
    return manifest, outdir, result


def read_csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def stable(table):
    return [{k: v for k, v in row.items() if k not in VOLATILE} for row in table]


def approx_rows(table):
    """Rows for comparing a view redone in this process (workers=0) with a pool's result.

    The pool's workers run BLAS single-threaded (as Dask's do); this process may not, and
    score_map's field sums differ in their last bits with the thread count.
    """
    return [{k: pytest.approx(v, rel=1e-12) if isinstance(v, float) else v
             for k, v in row.items() if k not in VOLATILE} for row in table]


def output_names(view):
    names = {f"{view}.exr", f"{view}.hdr", f"{view}-falsecolour.png", f"{view}-sources.png",
             f"{view}-source-labels.npz", f"{view}-contrast.png", f"{view}-score.json", f"{view}-done.json"}
    if view == "single":  # the view with a scene model
        names |= {f"{view}-model.exr", f"{view}-model-ratio.png", f"{view}-model-comparison.json",
                  f"{view}-model-comparison.html"}
    return names


def mtimes(outdir):
    return {p: p.stat().st_mtime_ns for p in sorted((outdir / "views").rglob("*")) if p.is_file()}


# --------------------------------------------------------------------------- a full run


def test_survey_writes_every_output_and_one_row_per_good_view(surveyed):
    manifest, outdir, result = surveyed
    assert result.processed == [*GOOD, "corrupt"] and result.skipped == []
    assert [row["view"] for row in result.table] == GOOD
    for view in GOOD:
        assert {p.name for p in (outdir / "views" / view).iterdir()} == output_names(view)
    # The corrupt RAW: one failure line with the decoder's one-line reason, no outputs.
    assert result.failures == [("corrupt", result.failures[0][1])]
    assert "not a readable RAW file" in result.failures[0][1]
    log = (outdir / "failures.log").read_text().splitlines()
    assert log == [f"corrupt: {result.failures[0][1]}"]
    assert not (outdir / "views" / "corrupt" / "corrupt-done.json").exists()
    # CSV and Parquet hold the same table as the result.
    rows = read_csv(outdir / "metrics.csv")
    table = pq.read_table(outdir / "metrics.parquet").to_pylist()
    assert [r["view"] for r in rows] == [r["view"] for r in table] == GOOD
    assert table == result.table
    for row, parquet_row in zip(rows, table):
        for key, value in parquet_row.items():
            if isinstance(value, float):
                assert float(row[key]) == value, key  # CSV floats round-trip exactly
    meta = json.loads(pq.read_schema(outdir / "metrics.parquet").metadata[b"lsadphoto.survey"])
    assert meta["manifest"] == str(manifest) and meta["schema"] == "lsadphoto.survey/1"
    assert result.to_dict()["views_failed"] == 1


def test_table_columns_metrics_sweep_ratings_and_provenance(surveyed):
    _, outdir, result = surveyed
    rows = {row["view"]: row for row in result.table}
    columns = list(result.table[0])
    for name in ("ugr_pixel", "ugr_grouped", "q", "dgp", "vertical_illuminance", "n_sources"):
        assert name in columns
    assert "ugr_pixel_u" in columns and "q_u" in columns and "n_sources_u" not in columns
    assert [c for c in columns if c.startswith("q_n")] == [f"q_n{n}" for n in SWEEP]
    bracket = rows["bracket"]
    # The one-pass sweep at the survey's N reproduces Q (up to summation order).
    assert bracket["q_n50"] == pytest.approx(bracket["q"], rel=1e-12)
    assert bracket["rating_mean"] == 4.0 and bracket["rating_n"] == 3
    assert rows["single"]["rating_mean"] == 6.75 and rows["uncalibrated"]["rating_mean"] is None
    # The model of the office view is a different room: the comparison runs and says so. Its
    # table values, recomputed from the two maps the view wrote: the median ratio is the
    # ω-weighted median of model/photo over the pixels both maps know above 1e-3 cd/m² (numpy's
    # inverted-CDF quantile), the Monte Carlo uncertainty Σ u·ω / Σ L·ω of the model map.
    from lsadphoto.io import read_exr

    photo = read_exr(outdir / "views" / "single" / "single.exr")
    model = read_exr(outdir / "views" / "single" / "single-model.exr")
    omega = photo.projection.solid_angles(*photo.projection.pixel_grid())
    L_p, L_m = (np.asarray(m.luminance, np.float64) for m in (photo, model))
    both = np.isfinite(L_p) & np.isfinite(L_m) & (L_p > 1e-3) & (L_m > 1e-3) & (omega > 0)
    median = np.quantile(L_m[both] / L_p[both], 0.5, weights=omega[both], method="inverted_cdf")
    assert float(rows["single"]["model_ratio_median"]) == pytest.approx(median, rel=1e-6)
    known = np.isfinite(L_m) & np.isfinite(model.uncertainty)
    u_mc = np.sum(model.uncertainty[known] * omega[known]) / np.sum(L_m[known] * omega[known])
    assert float(rows["single"]["model_mc_uncertainty"]) == pytest.approx(u_mc, rel=1e-6)
    assert bracket.get("model_ratio_median") is None
    assert bracket["calibrated"] is True and bracket["calibration_method"] == "spot"
    assert rows["uncalibrated"]["calibrated"] is False
    assert rows["uncalibrated"]["calibration_method"] == "exposure-equation"
    assert bracket["raw_files"] == "office/office_1.dng;office/office_2.dng;office/office_3.dng"
    assert bracket["profile"] == "synthetic-demo" and bracket["lsadphoto_version"]
    assert 0 < bracket["calibration_uncertainty"] < 0.1 and bracket["timestamp"]
    los = np.array([0.0, 0.1, 1.0]) / np.linalg.norm([0.0, 0.1, 1.0])
    np.testing.assert_allclose([float(v) for v in rows["single"]["line_of_sight"].split(",")],
                               los, atol=1e-6)
    # Observer ratings in the study module's format (scene, observer, rating).
    assert read_csv(outdir / "ratings.csv") == [
        {"scene": "bracket", "observer": "1", "rating": "4.0"},
        {"scene": "bracket", "observer": "2", "rating": "5.0"},
        {"scene": "bracket", "observer": "3", "rating": "3.0"},
        {"scene": "single", "observer": "anna", "rating": "6.0"},
        {"scene": "single", "observer": "boris", "rating": "7.5"},
    ]


def test_survey_values_match_the_single_view_pipeline(surveyed):
    """The row and the maps equal luminance_from_raw + score_map with the same options."""
    from lsadphoto.calibrate.profile import load_profile
    from lsadphoto.io import read_exr
    from lsadphoto.luminance import luminance_from_raw
    from lsadphoto.metrics.score import score_map

    _manifest, outdir, result = surveyed
    row = next(r for r in result.table if r["view"] == "uncalibrated")
    direct = luminance_from_raw([OFFICE / "office_1.dng", OFFICE / "office_3.dng"],
                                profile=load_profile(PROFILE))
    score = score_map(direct.map, source_threshold=1500, n_thresholds=50, size_arcmin=10,
                      sweep=SWEEP).to_dict()
    # rel 1e-12: BLAS sums in score_map differ in their last bits between this process and
    # the single-threaded workers (see approx_rows).
    for key in ("ugr_pixel", "ugr_grouped", "q", "dgp", "n_sources"):
        assert row[key] == pytest.approx(score[key], rel=1e-12), key
        if key != "n_sources":
            assert row[f"{key}_u"] == pytest.approx(score["uncertainty"][key], rel=1e-12), key
    assert row["q_n7"] == pytest.approx(score["q_sweep"]["q"][6], rel=1e-12)
    saved = read_exr(outdir / "views" / "uncalibrated" / "uncalibrated.exr")
    np.testing.assert_array_equal(saved.luminance, direct.map.luminance)
    record = json.loads((outdir / "views" / "single" / "single-score.json").read_text())
    assert record["survey"]["ratings"] == [{"observer": "anna", "rating": 6.0},
                                           {"observer": "boris", "rating": 7.5}]
    assert record["model_comparison"]["metrics"]["ugr_grouped"]["photo"] == record["ugr_grouped"]
    assert record["survey"]["note"] == "one frame, one spot"
    assert record["settings"]["line_of_sight"] == pytest.approx(
        [0.0, 0.1 / np.hypot(0.1, 1.0), 1.0 / np.hypot(0.1, 1.0)])


# --------------------------------------------------------------------------- resuming


def test_rerun_skips_finished_views_and_rewrites_nothing(surveyed, tmp_path):
    manifest, outdir, first = surveyed
    copy = tmp_path / "out"
    shutil.copytree(outdir, copy)
    before = mtimes(copy)
    # Only the good views: nothing is left to do, so no worker is started at all.
    good_only = manifest.parent / "good-only.toml"
    good_only.write_text(MANIFEST.split('[[view]]\nid = "corrupt"')[0])
    result = run_survey(good_only, copy, workers=2, progress=False)
    assert result.processed == [] and result.skipped == GOOD and result.failures == []
    assert mtimes(copy) == before
    assert result.table == first.table  # timestamps too: the rows come from the markers
    assert (copy / "failures.log").read_text() == ""


def test_rerun_retries_only_the_failed_view(surveyed, tmp_path):
    manifest, outdir, first = surveyed
    copy = tmp_path / "out"
    shutil.copytree(outdir, copy)
    before = mtimes(copy)
    result = run_survey(manifest, copy, workers=0, progress=False)
    assert result.processed == ["corrupt"] and result.skipped == GOOD
    assert result.failures == first.failures
    assert mtimes(copy) == before and result.table == first.table


def test_killed_run_resumes_without_losing_anything(surveyed, tmp_path):
    """A run killed while writing 'single': its marker never came, a temp file stayed."""
    manifest, outdir, first = surveyed
    copy = tmp_path / "out"
    shutil.copytree(outdir, copy)
    view = copy / "views" / "single"
    (view / "single-done.json").unlink()
    (view / "single-contrast.png").unlink()
    (view / ".single-score.k3j2x9.tmp.json").write_text('{"half": ')  # a half-written temp
    # The table of a crashed run may lack the view; the rerun rebuilds it from the markers.
    (copy / "metrics.csv").unlink()
    others = {p: t for p, t in mtimes(copy).items() if p.parent.name != "single"}
    result = run_survey(manifest, copy, workers=0, progress=False)
    assert result.processed == ["single", "corrupt"]
    assert result.skipped == ["bracket", "uncalibrated"]
    assert {p.name for p in view.iterdir()} == output_names("single")  # temp file gone
    assert {p: t for p, t in mtimes(copy).items() if p.parent.name != "single"} == others
    assert stable(result.table) == approx_rows(first.table)
    assert [r["view"] for r in read_csv(copy / "metrics.csv")] == GOOD


def test_changed_inputs_redo_only_that_view(surveyed, tmp_path):
    manifest, outdir, first = surveyed
    copy = tmp_path / "out"
    shutil.copytree(outdir, copy)
    changed = manifest.parent / "changed.toml"
    changed.write_text(MANIFEST.replace("cd_m2 = 60}", "cd_m2 = 66}"))
    result = run_survey(changed, copy, workers=0, progress=False)
    assert result.processed == ["single", "corrupt"]
    rows = {r["view"]: r for r in result.table}
    old = {r["view"]: r for r in first.table}
    assert rows["single"]["calibration_factor"] == pytest.approx(
        old["single"]["calibration_factor"] * 1.1, rel=1e-9)
    assert rows["bracket"] == old["bracket"]


# --------------------------------------------------------------------------- parallelism


def test_dask_cluster_gives_the_same_table_as_the_local_pool(surveyed, tmp_path):
    distributed = pytest.importorskip("distributed")
    manifest, _, local = surveyed
    # Worker processes (spawned, as the local pool): warnings are recorded per process.
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster:
        result = run_survey(manifest, tmp_path / "out", dask_address=cluster.scheduler_address,
                            progress=False)
    assert result.processed == [*GOOD, "corrupt"]
    assert result.failures == local.failures
    assert stable(result.table) == stable(local.table)  # every metric column, exactly


CRASH_HELPER = """\
import os


def crash_on_boom(task):
    # Stand-in for the view processor: the worker dies (as in a native crash) on 'boom'.
    if task["view"] == "boom":
        os._exit(3)
    return {"view": task["view"], "ok": True, "row": {"view": task["view"]}, "reason": None,
            "seconds": 0.0}
"""


def test_a_dying_worker_fails_only_its_own_view(tmp_path, monkeypatch):
    from lsadphoto.survey.executors import run_local

    # A module of its own (spawned workers find it on the inherited sys.path), so that the
    # workers start without importing lsadphoto.
    (tmp_path / "survey_crash_helper.py").write_text(CRASH_HELPER)
    monkeypatch.syspath_prepend(str(tmp_path))
    from survey_crash_helper import crash_on_boom

    outcomes = []
    run_local([{"view": "boom"}, {"view": "fine"}], 2, outcomes.append, function=crash_on_boom)
    by_view = {o["view"]: o for o in outcomes}
    assert set(by_view) == {"boom", "fine"} and len(outcomes) == 2
    assert by_view["fine"]["ok"]
    assert not by_view["boom"]["ok"] and "worker process died" in by_view["boom"]["reason"]


def test_progress_bar_is_silent_off_a_terminal():
    from lsadphoto.survey.run import _progress_bar

    bar = _progress_bar(total=3, initial=1, enabled=True)  # pytest's stderr is no terminal
    assert bar.disable
    bar.close()
    bar = _progress_bar(total=3, initial=0, enabled=False)
    assert bar.disable
    bar.close()


# --------------------------------------------------------------------------- bad input


BAD_MANIFESTS = [
    ("missing raw", ('raw = "broken.dng"\n', ""), "[view[3]] missing required key 'raw'"),
    ("missing id", ('id = "corrupt"\n', ""), "[view[3]] missing required key 'id'"),
    ("unknown view key", ('id = "corrupt"\n', 'id = "corrupt"\nspot = "x.csv"\n'),
     "[view[3]] unknown key 'spot' (did you mean 'spots'?); valid: id, raw, profile, spots"),
    ("unknown top key", ('name = "test survey"\n', 'name = "t"\nworkers = 3\n'),
     "unknown key 'workers'; valid: schema, name"),
    ("unknown score option", ("n_thresholds = 50\n", "N = 50\n"),
     "[score] unknown key 'N'; valid: line_of_sight"),
    ("missing file", ('raw = "broken.dng"\n', 'raw = ["broken.dng", "gone.dng"]\n'),
     "view 'corrupt': raw: RAW file "),
    ("missing spots file", ('spots = "office/spots.csv"\n', 'spots = "office/nope.csv"\n'),
     "view 'bracket': spots: spot readings file "),
    ("duplicate id", ('id = "corrupt"\n', 'id = "Bracket"\n'),
     "view 'Bracket': id: duplicate id (view #1 has it too)"),
    ("unsafe id", ('id = "corrupt"\n', 'id = "../escape"\n'),
     "view #4: id: '../escape' is not safe as a file name"),
    ("bad spot", ("cd_m2 = 60}", "cd_m2 = -60}"), "view[1].spots[0].cd_m2 must be > 0, got -60.0"),
    ("spot lacks a field", ("col = 320, cd_m2 = 60}", "cd_m2 = 60}"), "[view[1].spots[0]] missing required key 'col'"),
    ("bad ratings", ("ratings = [4, 5, 3]", 'ratings = [4, "good", 3]'),
     "view[0].ratings[1] must be a number, got 'good'"),
    ("bad line of sight", ("line_of_sight = [0.0, 0.1, 1.0]", "line_of_sight = [0, 1]"),
     "view[1].line_of_sight must have 3 elements, got 2"),
    ("model without scene", ('scene = "model.toml"\n', ""), "[view[1].model] missing required key 'scene'"),
    ("missing model scene", ('scene = "model.toml"', 'scene = "gone.toml"'),
     "view 'single': model.scene: scene model "),
    ("bad model scene", ('scene = "model.toml"', 'scene = "camera.toml"'),
     "view 'single': model.scene: "),
    ("wrong schema", ('schema = "lsadphoto.survey/1"', 'schema = "lsadphoto.survey/9"'),
     "schema must be one of 'lsadphoto.survey/1', got 'lsadphoto.survey/9'"),
    ("bad demosaic", ('name = "test survey"\n', 'demosaic = "magic"\n'),
     "demosaic must be one of 'superpixel', 'linear'"),
    ("missing profile", ('profile = "camera.toml"', 'profile = "nocamera.toml"'),
     "profile: camera profile "),
]


@pytest.mark.parametrize("old, new, message", [case[1] + (case[2],) for case in BAD_MANIFESTS],
                         ids=[case[0] for case in BAD_MANIFESTS])
def test_bad_manifest_is_one_line_naming_manifest_view_and_field(tmp_path, old, new, message):
    assert old in MANIFEST
    path = make_survey(tmp_path, MANIFEST.replace(old, new, 1))
    with pytest.raises(BadInputError) as info:
        load_manifest(path)
    text = str(info.value)
    assert "\n" not in text
    assert text.startswith(f"{path}: ") and message in text, text


def test_manifest_without_views_and_not_toml(tmp_path):
    path = tmp_path / "survey.toml"
    path.write_text('schema = "lsadphoto.survey/1"\n')
    with pytest.raises(BadInputError, match="missing required key 'view'"):
        load_manifest(path)
    path.write_text("[[view]\n")
    with pytest.raises(BadInputError, match="not a valid TOML survey manifest"):
        load_manifest(path)
    with pytest.raises(BadInputError, match="does not exist"):
        load_manifest(tmp_path / "nothing.toml")


def test_manifest_resolves_paths_against_its_folder(tmp_path):
    manifest = load_manifest(make_survey(tmp_path))
    assert [v.id for v in manifest.views] == [*GOOD, "corrupt"]
    bracket, single = manifest.views[:2]
    assert bracket.raw[0] == (tmp_path / "office" / "office_1.dng").resolve()
    assert [(s.row, s.col, s.luminance) for s in bracket.spots] == [(263, 320, 60), (360, 96, 28.5)]
    assert single.ratings == (("anna", 6.0), ("boris", 7.5))
    assert single.model == {"scene": str((tmp_path / "model.toml").resolve()),
                            "position": [1.0, 2.0, 1.6], "direction": [1.0, 0.0, 0.0],
                            "samples": 2000, "nodes_per_pixel": 2, "seed": 0}
    assert manifest.profile == (tmp_path / "camera.toml").resolve()
    assert manifest.score == {"n_thresholds": 50.0, "size_arcmin": 10.0}


def test_run_survey_option_errors(tmp_path):
    path = make_survey(tmp_path)
    for kwargs, message in [
        ({"workers": -1}, "workers must be a non-negative integer"),
        ({"dask_address": "tcp://x:1", "client": object()}, "either a Dask scheduler address"),
        ({"workers": 2, "dask_address": "tcp://x:1"}, "workers sets the local process pool"),
        ({"score_options": {"alpha": 10}}, "score_options: unknown key 'alpha'"),
        ({"dask_address": "nonsense://host"}, "must look like tcp://HOST:PORT"),
        ({"dask_address": "banana"}, "'banana' must look like tcp://HOST:PORT"),
    ]:
        with pytest.raises(BadInputError, match=None) as info:
            run_survey(path, tmp_path / "out", progress=False, **kwargs)
        assert message in str(info.value)
    assert not (tmp_path / "out").exists()


def test_survey_where_every_view_fails_still_writes_the_tables(tmp_path):
    path = make_survey(tmp_path, MANIFEST[:MANIFEST.index("[[view]]")]
                       + '[[view]]\nid = "corrupt"\nraw = "broken.dng"\n')
    result = run_survey(path, tmp_path / "out", workers=0, progress=False)
    assert result.table == [] and [v for v, _ in result.failures] == ["corrupt"]
    assert (tmp_path / "out" / "metrics.csv").read_text() == "view\n"
    assert pq.read_table(tmp_path / "out" / "metrics.parquet").num_rows == 0
    assert len((tmp_path / "out" / "failures.log").read_text().splitlines()) == 1
    assert not (tmp_path / "out" / "ratings.csv").exists()


def test_cli_survey_rerun_then_study_reads_the_survey_tables(surveyed, tmp_path):
    """`lsadphoto survey` on a finished folder redoes nothing and reports the failed view;
    `lsadphoto study` reads the survey's ratings.csv and metrics.csv as they are."""
    import shutil
    import subprocess
    import sys

    manifest, outdir, _ = surveyed
    copy = tmp_path / "out"
    shutil.copytree(outdir, copy)

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "lsadphoto.cli", *map(str, args)],
                              capture_output=True, text=True)

    proc = cli("survey", manifest, "-o", copy, "--quiet", "--workers", "0")
    assert proc.returncode == 1  # the corrupt view still fails
    assert "failed" in proc.stdout and "Traceback" not in proc.stderr
    assert (copy / "report.html").read_text().startswith("<!DOCTYPE html>")
    proc = cli("study", copy / "ratings.csv", copy / "metrics.csv", "--n-jitter", "20",
               "--n-bootstrap", "20", "--json")
    # The tables parse (the text provenance columns are skipped, the unrated view left out);
    # two rated views are too few for a correlation, which is the one-line answer, naming
    # the ratings (not metrics.csv, which has a third, unrated view).
    assert proc.returncode == 2
    assert proc.stderr == (f"lsadphoto: error: {copy / 'ratings.csv'}: rates 2 of the 3 scene(s) "
                           f"of {copy / 'metrics.csv'}; a correlation needs at least 3 rated "
                           "scenes\n")


# --------------------------------------------------------------------------- checked first


@pytest.mark.parametrize("old, new, message", [
    ("n_thresholds = 50\n", "n_thresholds = -3\n", ": score.n_thresholds must be > 0, got -3.0"),
    ("size_arcmin = 10\n", 'size_arcmin = "ten"\n', ": score.size_arcmin must be a number, got 'ten'"),
    ("source_threshold = 1500\n", 'source_threshold = 1500\nq_cutoff = "sideways"\n',
     ": view[2].score.q_cutoff must be one of 'difference', 'luminance', got 'sideways'"),
    ("source_threshold = 1500\n", "source_threshold = 0\n",
     ": view[2].score.source_threshold must be > 0, got 0.0"),
])
def test_bad_score_option_stops_the_survey_before_any_view(tmp_path, old, new, message):
    """Issue 17, defect 3: a bad score option failed every view after its map was computed."""
    path = make_survey(tmp_path, MANIFEST.replace(old, new, 1))
    with pytest.raises(BadInputError) as info:
        run_survey(path, tmp_path / "out", workers=0, progress=False)
    assert str(info.value) == f"{path}{message}"
    assert not (tmp_path / "out").exists()


def test_cli_bad_options_are_one_line_before_anything_runs(tmp_path):
    """--N=-2 (defect 3) and --dask banana (defect 6: printed its error, then hung 60 s)."""
    path = make_survey(tmp_path, CORRUPT_ONLY)
    for option, message in [("--N=-2", "--N/--alpha-arcmin: n_thresholds must be > 0, got -2.0"),
                            ("--dask=banana", "Dask scheduler address 'banana' must look like")]:
        proc = cli("survey", path, "-o", tmp_path / "out", "--quiet", option)
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr.startswith(f"lsadphoto: error: {message}")
        assert len(proc.stderr.splitlines()) == 1 and proc.stdout == ""
        assert not (tmp_path / "out").exists()


# --------------------------------------------------------------------------- one run per folder

LOCK_HOLDER = """
import sys, time
from pathlib import Path
from lsadphoto.survey import survey_lock
with survey_lock(Path(sys.argv[1]), manifest=sys.argv[2]):
    print("locked", flush=True)
    time.sleep(600)
"""


def test_second_run_refuses_and_a_killed_runs_lock_is_taken_over(tmp_path):
    """Issue 17, defect 2, with two real processes: the second run names the first and
    touches nothing; once the first is killed (SIGKILL: no clean-up), its lock is taken over."""
    path = make_survey(tmp_path, CORRUPT_ONLY)
    out = tmp_path / "out"
    out.mkdir()
    earlier = "corrupt: the first run's reason\n"
    (out / "failures.log").write_text(earlier)
    holder = subprocess.Popen([sys.executable, "-c", LOCK_HOLDER, str(out), str(path)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        proc = cli("survey", path, "-o", out, "--workers", "0", "--quiet")
        assert proc.returncode == 2
        line, = proc.stderr.splitlines()
        assert line.startswith(f"lsadphoto: error: output folder {out} is in use by process "
                               f"{holder.pid} on {socket.gethostname()}, started 20"), line
        assert f"(manifest {path})" in line
        # Nothing of the first run's was touched: no table, its failures.log as it was.
        assert sorted(p.name for p in out.iterdir()) == sorted([LOCK_NAME, "failures.log"])
        assert (out / "failures.log").read_text() == earlier
    finally:
        holder.kill()
        holder.wait()
        holder.stdout.close()
    assert (out / LOCK_NAME).is_file()  # a killed run leaves its lock file behind
    with pytest.warns(StaleLockWarning, match=f"took over the lock of process {holder.pid} on "):
        result = run_survey(path, out, workers=0, progress=False)
    assert [v for v, _ in result.failures] == ["corrupt"]
    log = (out / "failures.log").read_text()
    assert log.startswith("corrupt: ") and "not a readable RAW file" in log and log != earlier
    assert not (out / LOCK_NAME).exists()  # released at the end


def test_interrupted_rerun_keeps_the_earlier_failures(surveyed, tmp_path, monkeypatch):
    """A rerun interrupted before it retried the failed view rewrote failures.log empty."""
    import lsadphoto.survey.run as run_module

    manifest, outdir, first = surveyed
    copy = tmp_path / "out"
    shutil.copytree(outdir, copy)
    before = (copy / "failures.log").read_text()
    assert before.startswith("corrupt: ")

    def interrupted(tasks, report):
        raise KeyboardInterrupt

    monkeypatch.setattr(run_module, "run_serial", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_survey(manifest, copy, workers=0, progress=False)
    assert (copy / "failures.log").read_text() == before
    assert [r["view"] for r in read_csv(copy / "metrics.csv")] == GOOD
    assert not (copy / LOCK_NAME).exists()  # released on the way out


def test_unreachable_dask_scheduler_is_one_error_and_leaves_no_folder(tmp_path):
    """Connected before the output folder is made; distributed's own timeout (2 s here)."""
    dask = pytest.importorskip("dask")
    pytest.importorskip("distributed")
    path = make_survey(tmp_path, CORRUPT_ONLY)
    with dask.config.set({"distributed.comm.timeouts.connect": "2s"}):
        with pytest.raises(BadInputError, match="cannot connect to the Dask scheduler at "
                                                "tcp://127.0.0.1:1: "):
            run_survey(path, tmp_path / "out", dask_address="tcp://127.0.0.1:1", progress=False)
    assert not (tmp_path / "out").exists()
