"""Observer-study statistics: correlation coefficients and tests against scipy.stats, the
Fisher interval, the Chaddock scale, the CSV tables and their one-line errors, the r(N)
sweep on data with a known answer, and run_study end to end."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from lsadphoto.errors import BadInputError
from lsadphoto.study import (
    best_index,
    chaddock_label,
    correlate,
    fisher_interval_Fisher1921,
    kendall_tau_b,
    pearson_r,
    read_metrics,
    read_ratings,
    run_study,
    scene_ratings,
    sweep_correlations,
)
from lsadphoto.study.correlation import ranks

# Coefficients and p-values are sums of O(n) products of O(1) numbers in float64, computed
# here and in scipy by different but equally stable formulas; their difference is a few ulp
# times n, far below 1e-12 for n ≤ 60.
EPS = 1e-12


def _pairs(seed, n, *, ties=False):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=n)
    y = 0.5 * x + rng.normal(size=n)
    if ties:  # ratings-like data: rounded to a 10-point scale, metric to one decimal
        x, y = np.round(x, 1), np.clip(np.round(5 + 2 * y), 1, 10)
    return x, y


@pytest.mark.parametrize("n", [5, 12, 21, 33, 34, 60])
@pytest.mark.parametrize("ties", [False, True])
def test_coefficients_and_p_values_equal_scipy(n, ties):
    # n = 33/34 straddle the exact/asymptotic switch of Kendall's p-value.
    for seed in range(3):
        x, y = _pairs(seed, n, ties=ties)
        ours = correlate(x, y)
        pearson = stats.pearsonr(x, y)
        spearman = stats.spearmanr(x, y)
        kendall = stats.kendalltau(x, y)
        assert ours["n"] == n
        assert ours["pearson_r"] == pytest.approx(pearson.statistic, abs=EPS)
        assert ours["pearson_p"] == pytest.approx(pearson.pvalue, abs=EPS)
        assert ours["spearman_rho"] == pytest.approx(spearman.statistic, abs=EPS)
        assert ours["spearman_p"] == pytest.approx(spearman.pvalue, abs=EPS)
        assert ours["kendall_tau"] == pytest.approx(kendall.statistic, abs=EPS)
        assert ours["kendall_p"] == pytest.approx(kendall.pvalue, abs=EPS)


def test_kendall_exact_extremes_match_scipy():
    # Perfect agreement and one swap: the exact branch's closed-form corners.
    x = np.arange(40.0)
    for y in (x.copy(), np.r_[x[:-2], x[-1], x[-2]], -x):
        tau, p = kendall_tau_b(x, y)
        ref = stats.kendalltau(x, y)
        assert tau == pytest.approx(ref.statistic, abs=EPS)
        assert p == pytest.approx(ref.pvalue, abs=EPS)


def test_ranks_average_ties_equal_scipy():
    values = np.array([3.0, 1.0, 4.0, 1.0, 5.0, 9.0, 2.0, 6.0, 5.0, 3.0, 5.0])
    np.testing.assert_array_equal(ranks(values), stats.rankdata(values))


@pytest.mark.parametrize("confidence", [0.8, 0.95, 0.99])
def test_fisher_interval_equals_scipy(confidence):
    for seed, n in ((0, 5), (1, 21), (2, 100)):
        x, y = _pairs(seed, n)
        r = pearson_r(x, y)
        ci = stats.pearsonr(x, y).confidence_interval(confidence_level=confidence)
        low, high = fisher_interval_Fisher1921(r, n, confidence=confidence)
        assert low == pytest.approx(ci.low, abs=EPS)
        assert high == pytest.approx(ci.high, abs=EPS)


def test_fisher_interval_edge_cases():
    assert all(math.isnan(v) for v in fisher_interval_Fisher1921(0.5, 3))
    assert fisher_interval_Fisher1921(1.0, 10) == (1.0, 1.0)
    with pytest.raises(BadInputError):
        fisher_interval_Fisher1921(0.5, 10, confidence=1.0)


def test_paper_r_is_noticeable_with_wide_interval():
    # The paper: r = 0.61 over 21 stations, "noticeable" on the Chaddock scale. Its 95 %
    # Fisher interval (tanh(atanh 0.61 ± 1.96/√18), computed by hand: 0.242 … 0.825)
    # shows how little 21 scenes pin r down.
    assert chaddock_label(0.61) == "noticeable"
    low, high = fisher_interval_Fisher1921(0.61, 21)
    z, half = math.atanh(0.61), 1.959963984540054 / math.sqrt(18)
    assert (low, high) == pytest.approx((math.tanh(z - half), math.tanh(z + half)), abs=EPS)
    assert round(low, 3) == 0.242 and round(high, 3) == 0.825


@pytest.mark.parametrize("r, label", [
    (0.0, "none"), (0.0999, "none"), (0.1, "weak"), (-0.29, "weak"), (0.3, "moderate"),
    (0.5, "noticeable"), (-0.62, "noticeable"), (0.7, "high"), (0.73, "high"),
    (0.9, "very high"), (-1.0, "very high"), (math.nan, None)])
def test_chaddock_scale(r, label):
    assert chaddock_label(r) == label


def test_constant_metric_gives_nan_not_error():
    out = correlate([1.0, 1.0, 1.0, 1.0], [1.0, 2.0, 3.0, 4.0])
    assert math.isnan(out["pearson_r"]) and out["chaddock"] is None
    assert math.isnan(out["kendall_tau"])


# --- the r(N) sweep ------------------------------------------------------------------------

def test_sweep_finds_perfect_linear_relation_at_its_n():
    # Q(N) is pure noise except at N = 37, where it is an exact linear function of the
    # rating: r(37) = 1 to rounding and 37 is the best N (the others are |r| < 1).
    rng = np.random.default_rng(5)
    rating = rng.uniform(2, 9, 21)
    n_values = np.arange(1, 101)
    metrics = rng.normal(size=(21, 100))
    metrics[:, 36] = 3.0 * rating + 7.0
    r = sweep_correlations(metrics, rating)
    assert r[36] == pytest.approx(1.0, abs=EPS)
    assert n_values[best_index(r)] == 37
    # A discomfort-like metric: exact decreasing relation, found with direction="negative".
    metrics[:, 36] = -3.0 * rating
    r = sweep_correlations(metrics, rating)
    assert r[36] == pytest.approx(-1.0, abs=EPS)
    assert n_values[best_index(r, direction="negative")] == 37
    assert n_values[best_index(r, direction="either")] == 37
    assert n_values[best_index(r)] != 37


def test_best_index_ignores_nan_and_prefers_smallest_n_on_ties():
    assert best_index([np.nan, 0.5, 0.5, 0.2]) == 1
    assert best_index([np.nan, np.nan]) == -1
    with pytest.raises(BadInputError, match="valid: 'positive'"):
        best_index([0.1], direction="largest")


# --- tables --------------------------------------------------------------------------------

def _write_study(folder, *, n_scenes=6, n_observers=4, seed=0, sweep=(10, 50, 90),
                 extra_ratings="", metrics_header=None):
    """A small study: ratings follow Q at N = 50 plus noise; returns the two paths."""
    rng = np.random.default_rng(seed)
    quality = rng.uniform(1, 5, n_scenes)
    lines = ["scene,observer,rating"]
    for s in range(n_scenes):
        for o in range(n_observers):
            rating = np.clip(np.round(2 + 1.5 * quality[s] + rng.normal(0, 1)), 1, 10)
            lines.append(f"S{s},obs{o},{rating:g}")
    ratings = Path(folder) / "RATINGS.csv"
    ratings.write_text("\n".join(lines) + "\n" + extra_ratings)
    header = metrics_header or ["scene", "ugr_pixel", "q"] + [f"q_n{n}" for n in sweep]
    rows = [",".join(header)]
    for s in range(n_scenes):
        q_n = [quality[s] * (1 + 0.5 * rng.normal()) if n != 50 else quality[s]
               for n in sweep]
        rows.append(",".join([f"S{s}", f"{20 + quality[s] + rng.normal():.4f}",
                              f"{quality[s]:.6f}"] + [f"{v:.6f}" for v in q_n]))
    metrics = Path(folder) / "METRICS.csv"
    metrics.write_text("\n".join(rows) + "\n")
    return ratings, metrics


def test_scene_ratings_mean_sd_sem_and_missing(tmp_path):
    path = tmp_path / "r.csv"
    path.write_text("scene,observer,rating,comment\nA,o1,7,x\nA,o2,5,\nA,o3,,skipped\n"
                    "B,o1,3,\nB,o2,NA,\nC,o1,10,\nC,o2,8,\nC,o3,9,\n")
    (tmp_path / "m.csv").write_text("scene,q\nA,1\nB,2\nC,3\n")
    ratings = read_ratings(path, rating_scale=(1, 10))
    assert ratings.n_missing == 2
    summary = scene_ratings(ratings, read_metrics(tmp_path / "m.csv"))
    np.testing.assert_allclose(summary.mean, [6.0, 3.0, 9.0], rtol=EPS)
    np.testing.assert_array_equal(summary.n, [2, 1, 3])
    np.testing.assert_allclose(summary.sd[[0, 2]], [np.std([7, 5], ddof=1), 1.0], rtol=EPS)
    assert math.isnan(summary.sd[1]) and math.isnan(summary.sem[1])
    assert summary.sem[2] == pytest.approx(1.0 / math.sqrt(3), rel=EPS)


def _error(tmp_path, ratings_text=None, metrics_text=None, **kwargs):
    ratings, metrics = _write_study(tmp_path)
    if ratings_text is not None:
        ratings.write_text(ratings_text)
    if metrics_text is not None:
        metrics.write_text(metrics_text)
    with pytest.raises(BadInputError) as info:
        run_study(ratings, metrics, n_jitter=0, n_bootstrap=0, **kwargs)
    message = str(info.value)
    assert "\n" not in message  # one line, for the CLI
    return message


def test_error_missing_ratings_column(tmp_path):
    message = _error(tmp_path, ratings_text="scene,observer,score\nS0,o,5\n")
    assert "RATINGS.csv" in message and "line 1" in message and "'rating'" in message


def test_error_missing_metrics_scene_column(tmp_path):
    message = _error(tmp_path, metrics_text="station,q\nS0,1\n")
    assert "METRICS.csv" in message and "line 1" in message and "'scene'" in message


def test_error_non_numeric_rating_names_file_line_column(tmp_path):
    message = _error(tmp_path, ratings_text="scene,observer,rating\nS0,o1,5\nS1,o1,good\n")
    assert "RATINGS.csv, line 3, column 'rating'" in message and "'good'" in message


def test_error_non_numeric_metric(tmp_path):
    text = "scene,q\nS0,1\nS1,two\nS2,3\n"
    message = _error(tmp_path, metrics_text=text)
    assert "METRICS.csv, line 3, column 'q'" in message


def test_error_unknown_scene_in_ratings(tmp_path):
    ratings, metrics = _write_study(tmp_path, extra_ratings="S99,obs0,5\n")
    with pytest.raises(BadInputError, match=r"RATINGS\.csv, line 26, column 'scene': "
                                            r"scene 'S99' is not in"):
        run_study(ratings, metrics, n_jitter=0, n_bootstrap=0)


def test_scene_without_ratings_is_left_out_with_a_note(tmp_path):
    ratings, metrics = _write_study(tmp_path)
    before = run_study(ratings, metrics, n_jitter=0, n_bootstrap=0).to_dict()
    metrics.write_text(metrics.read_text() + "S_new,1,2,3,4,5\n")
    after = run_study(ratings, metrics, n_jitter=0, n_bootstrap=0).to_dict()
    assert any("S_new" in note for note in after["notes"])
    assert after["correlations"] == before["correlations"]


def test_error_fewer_than_three_scenes(tmp_path):
    message = _error(tmp_path, ratings_text="scene,observer,rating\nS0,o,5\nS1,o,6\n",
                     metrics_text="scene,q\nS0,1\nS1,2\n")
    assert "2 scene(s)" in message and "at least 3" in message


def test_error_duplicate_rating_and_scene(tmp_path):
    message = _error(tmp_path, ratings_text="scene,observer,rating\nS0,o,5\nS0,o,6\n")
    assert "line 3" in message and "first on line 2" in message
    message = _error(tmp_path, metrics_text="scene,q\nS0,1\nS0,2\n")
    assert "line 3" in message and "appears again" in message


def test_error_unknown_metric_lists_columns(tmp_path):
    message = _error(tmp_path, metric="ugr")
    assert "no metric column 'ugr'" in message and "ugr_pixel" in message


def test_error_missing_value_in_selected_metric_and_sweep(tmp_path):
    ratings, metrics = _write_study(tmp_path)
    lines = metrics.read_text().splitlines()
    cells = lines[3].split(",")
    cells[3] = ""  # q_n10 of scene S2 (line 4)
    lines[3] = ",".join(cells)
    metrics.write_text("\n".join(lines) + "\n")
    with pytest.raises(BadInputError, match=r"line 4, column 'q_n10': missing value"):
        run_study(ratings, metrics, n_jitter=0, n_bootstrap=0)


def test_error_rating_outside_scale_and_ragged_row(tmp_path):
    message = _error(tmp_path, ratings_text="scene,observer,rating\nS0,o,11\n",
                     rating_scale=(1, 10))
    assert "line 2, column 'rating'" in message and "outside" in message
    message = _error(tmp_path, ratings_text="scene,observer,rating\nS0,o,5,extra\n")
    assert "line 2" in message and "4 cells" in message


def test_error_bad_options(tmp_path):
    assert "direction" in _error(tmp_path, direction="up")
    assert "jitter level" in _error(tmp_path, jitter_level="observer")
    assert "confidence" in _error(tmp_path, confidence=95)
    assert "seed" in _error(tmp_path, seed=-1)


def test_error_missing_file(tmp_path):
    with pytest.raises(BadInputError, match="does not exist"):
        run_study(tmp_path / "none.csv", tmp_path / "none2.csv")


# --- run_study end to end ------------------------------------------------------------------

def test_run_study_end_to_end(tmp_path):
    ratings, metrics = _write_study(tmp_path, n_scenes=8, n_observers=5)
    result = run_study(ratings, metrics, n_jitter=300, n_bootstrap=300, seed=3)
    data = result.to_dict()
    json.dumps(data, allow_nan=False)  # JSON-ready: no NaN, only builtins
    assert json.loads(result.to_json()) == data
    # The detailed metric's statistics are correlate() of the table's columns.
    table = np.genfromtxt(metrics, delimiter=",", names=True, dtype=None, encoding="utf-8")
    means = np.array([s["mean"] for s in data["scenes"]])
    ref = correlate(table["q"], means)
    assert data["correlations"]["q"]["pearson_r"] == pytest.approx(ref["pearson_r"], abs=EPS)
    assert set(data["correlations"]) == {"ugr_pixel", "q"}  # sweep columns kept apart
    assert data["between_metrics"]["ugr_pixel"]["pearson_r"] == pytest.approx(
        stats.pearsonr(table["ugr_pixel"], table["q"]).statistic, abs=EPS)
    # Sweep: Q(50) = Q exactly, so r(50) = r(q).
    sweep = data["sweep"]
    assert sweep["n"] == [10, 50, 90] and sweep["column"] == ["q_n10", "q_n50", "q_n90"]
    assert sweep["r"][1] == pytest.approx(ref["pearson_r"], abs=EPS)
    assert sweep["best"]["n"] in sweep["n"]
    assert data["jitter"]["n_trials"] == 300
    assert sum(data["jitter"]["best_n_counts"].values()) == 300
    loo = data["leave_one_out"]
    assert len(loo["folds"]) == 8 and sum(loo["chosen_n_counts"].values()) == 8
    assert data["provenance"]["arguments"]["seed"] == 3
    assert len(data["provenance"]["ratings_csv"]["sha256"]) == 64
    # Reproducible for a seed; another seed moves the Monte Carlo parts only.
    again = run_study(ratings, metrics, n_jitter=300, n_bootstrap=300, seed=3).to_dict()
    assert again == data
    other = run_study(ratings, metrics, n_jitter=300, n_bootstrap=300, seed=4).to_dict()
    assert other["jitter"]["sd"] != data["jitter"]["sd"]
    assert other["correlations"] == data["correlations"]


def test_run_study_figures_written_atomically(tmp_path):
    ratings, metrics = _write_study(tmp_path)
    result = run_study(ratings, metrics, n_jitter=50, n_bootstrap=50)
    written = result.figures(tmp_path / "fig")
    assert [p.name for p in written] == ["scatter_q.png", "r_vs_n.png"]
    for path in written:
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in (tmp_path / "fig").iterdir()) == ["r_vs_n.png",
                                                                    "scatter_q.png"]


def test_run_study_without_sweep_and_with_three_scenes(tmp_path):
    ratings, metrics = _write_study(tmp_path, n_scenes=3, metrics_header=None)
    metrics.write_text("scene,q,dgp\nS0,1,0.3\nS1,2,\nS2,4,0.5\n")
    result = run_study(ratings, metrics, sweep_prefix=None, n_jitter=20, n_bootstrap=20)
    data = result.to_dict()
    assert data["sweep"] is None and data["leave_one_out"] is None
    assert data["correlations"]["q"]["pearson_ci"] == [None, None]  # n = 3
    assert "dgp" not in data["correlations"]  # given for 2 scenes only
    assert any("fewer than 4 scenes" in note for note in data["notes"])
    assert any("'dgp'" in note for note in data["notes"])
    assert [p.name for p in result.figures(tmp_path / "fig")] == ["scatter_q.png"]


def test_run_study_metric_may_be_a_sweep_column(tmp_path):
    ratings, metrics = _write_study(tmp_path)
    data = run_study(ratings, metrics, metric="q_n50", n_jitter=10, n_bootstrap=10).to_dict()
    assert data["correlations"]["q_n50"]["pearson_r"] == pytest.approx(
        data["correlations"]["q"]["pearson_r"], abs=EPS)


def test_text_columns_of_a_survey_table_are_skipped_and_mixed_ones_refused(tmp_path):
    from lsadphoto.study.tables import read_metrics

    good = tmp_path / "m.csv"
    good.write_text("scene,q,raw_files,lsadphoto_version\n"
                    "a,1.5,a.dng,0.1.0\nb,2.5,b.dng,0.1.0\nc,,c.dng,0.1.0\n")
    metrics = read_metrics(good)
    assert list(metrics.values) == ["q"]
    assert math.isnan(metrics.values["q"][2])
    mixed = tmp_path / "x.csv"
    mixed.write_text("scene,q\na,1.5\nb,good\nc,2\n")
    with pytest.raises(BadInputError, match="line 3, column 'q'"):
        read_metrics(mixed)


def test_study_cli_summary_json_and_one_line_errors(tmp_path):
    import subprocess
    import sys

    rng = np.random.default_rng(5)
    q = rng.uniform(1, 5, 8)
    ratings = ["scene,observer,rating"] + [f"s{i},o{j},{2 * v + rng.normal(0, 0.5):.3f}"
                                           for i, v in enumerate(q) for j in range(4)]
    (tmp_path / "r.csv").write_text("\n".join(ratings) + "\n")
    (tmp_path / "m.csv").write_text("scene,q\n" + "".join(f"s{i},{v}\n" for i, v in enumerate(q)))

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "lsadphoto.cli", "study", *map(str, args)],
                              capture_output=True, text=True)

    proc = cli(tmp_path / "r.csv", tmp_path / "m.csv", "--sweep-prefix", "", "--n-jitter", "50",
               "--n-bootstrap", "50", "--json")
    assert proc.returncode == 0, proc.stderr
    record = json.loads(proc.stdout)
    x = np.array([record["scenes"][i]["mean"] for i in range(8)])
    assert record["correlations"]["q"]["pearson_r"] == pytest.approx(stats.pearsonr(q, x)[0],
                                                                      abs=1e-12)
    proc = cli(tmp_path / "r.csv", tmp_path / "missing.csv")
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1


# --- issue 17, defect 4: degenerate studies and the outputs of a failed one -----------------

def _study_cli(*args):
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "lsadphoto.cli", "study", *map(str, args)],
                          capture_output=True, text=True, timeout=600)


def _degenerate_tables(folder, constant):
    """Five scenes, three observers; the ratings or the metric q the same for every scene."""
    ratings = ["scene,observer,rating"] + [
        f"S{s},o{o},{5 if constant == 'ratings' else 1 + s + o % 2}"
        for s in range(5) for o in range(3)]
    metrics = ["scene,q,ugr_pixel,q_n1,q_n2"] + [
        f"S{s},{1.0 if constant == 'metric' else 0.5 * s + 0.1 * (s % 2)},{20 - s},{s},{s * s}"
        for s in range(5)]
    (folder / "R.csv").write_text("\n".join(ratings) + "\n")
    (folder / "M.csv").write_text("\n".join(metrics) + "\n")
    return folder / "R.csv", folder / "M.csv"


@pytest.mark.parametrize("constant", ["ratings", "metric"])
def test_constant_ratings_or_metric_give_nulls_with_a_note(tmp_path, constant):
    """Was "internal error: TypeError: 'NoneType' object is not subscriptable", with figures
    and JSON left behind; the guide promises null values with a note."""
    ratings, metrics = _degenerate_tables(tmp_path, constant)
    proc = _study_cli(ratings, metrics, "--n-jitter", "40", "--n-bootstrap", "40",
                      "--figures", tmp_path / "figs", "--output-json", tmp_path / "s.json")
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr
    record = json.loads((tmp_path / "s.json").read_text())
    q = record["correlations"]["q"]
    assert q["pearson_r"] is None and q["spearman_rho"] is None and q["chaddock"] is None
    expected = ("the mean rating is the same for every scene" if constant == "ratings"
                else "metric 'q' is constant")
    assert any(expected in note for note in record["notes"]), record["notes"]
    assert f"note: {expected}" in proc.stdout
    assert "Pearson r = — " in proc.stdout  # the text summary prints undefined values as —
    if constant == "ratings":  # every r(N) is undefined too: no best N, said why
        assert record["sweep"]["best"] is None and record["leave_one_out"]["r_loo"] is None
        assert any("no best N" in note for note in record["notes"])
        assert "ugr_pixel" in record["correlations"]
        assert record["correlations"]["ugr_pixel"]["pearson_r"] is None
    else:  # the other metrics still correlate
        assert record["correlations"]["ugr_pixel"]["pearson_r"] == pytest.approx(-1.0)
    assert sorted(p.name for p in (tmp_path / "figs").iterdir()) == ["r_vs_n.png", "scatter_q.png"]


def test_too_few_rated_scenes_blame_the_ratings_file(tmp_path):
    """Ratings for one scene of a five-scene metrics table: the error named metrics.csv."""
    _, metrics = _degenerate_tables(tmp_path, None)
    ratings = tmp_path / "one.csv"
    ratings.write_text("scene,observer,rating\nS0,o1,4\nS0,o2,5\n")
    with pytest.raises(BadInputError) as info:
        run_study(ratings, metrics, n_jitter=0, n_bootstrap=0)
    assert str(info.value) == (f"{ratings}: rates 1 of the 5 scene(s) of {metrics}; a "
                               "correlation needs at least 3 rated scenes")


def test_report_into_a_missing_survey_folder_is_one_line_and_writes_nothing(tmp_path):
    """--report /nonexistent wrote a report of an empty survey there."""
    ratings, metrics = _degenerate_tables(tmp_path, None)
    missing = tmp_path / "no" / "such-survey"
    proc = _study_cli(ratings, metrics, "--n-jitter", "0", "--n-bootstrap", "0",
                      "--report", missing, "--figures", tmp_path / "figs",
                      "--output-json", tmp_path / "s.json")
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr == (f"lsadphoto: error: survey folder {missing} does not exist (--report "
                           "takes the output folder of `lsadphoto survey`)\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["M.csv", "R.csv"]
