"""HTML reports: structure, numbers, embedded images, escaping, robustness to missing pieces,
and a look at the rendered page in a real headless browser (Debian's chromium).

The survey folder is built here with the layout of :func:`lsadphoto.survey.run_survey`
(metrics.csv, failures.log, ratings.csv, views/<id>/<id>-*.png) from small synthetic maps, so
that the report is tested without decoding RAW files; the observer study is a real
:func:`lsadphoto.study.run_study` on constructed tables with known structure.
"""

import base64
import csv
import html
import json
import math
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from lsadphoto.compare import compare_maps
from lsadphoto.datasets import disk_sources_scene
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.io import write_false_colour_png
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.report import (
    figure_q_vs_ugr,
    figure_r_vs_n,
    figure_ratings_vs_metric,
    write_comparison_report,
    write_contrast_png,
    write_glare_source_png,
    write_survey_report,
)
from lsadphoto.study import run_study
from lsadphoto.survey import ViewLayout

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: A view id that must come out escaped.
NASTY = "<b>&x"
VIEWS = ["A1", "B2", "C3", "D4", "E5", NASTY]
SWEEP = (1, 2, 5, 10, 20, 50, 100)


class Page(HTMLParser):
    """Everything the tests look at in a parsed report."""

    VOID = frozenset({"meta", "img", "br", "hr", "input", "link"})

    def __init__(self, text):
        super().__init__(convert_charrefs=True)
        self.tags, self.ids, self.images, self.links, self.text = [], set(), [], [], []
        self.open = []
        self.feed(text)
        self.close()
        assert not self.open, f"unclosed elements: {self.open}"
        self.text = re.sub(r"\s+", " ", " ".join(self.text))  # whitespace as a browser shows it

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.tags.append(tag)
        if tag not in self.VOID:
            self.open.append(tag)
        if "id" in attrs:
            self.ids.add(attrs["id"])
        if tag == "img":
            self.images.append(attrs.get("src", ""))
        for key in ("href", "src", "action", "data"):
            if key in attrs:
                self.links.append(attrs[key])

    def handle_endtag(self, tag):
        # Well-formed: every element closed, in order (html.parser itself is lenient).
        assert self.open and self.open[-1] == tag, (tag, self.open[-5:])
        self.open.pop()

    def handle_data(self, data):
        self.text.append(data)


def _check_self_contained(page, text):
    # Scripts only inline (the interactive viewer's code and data; a src= would be a link).
    assert "link" not in page.tags and "iframe" not in page.tags
    for link in page.links:
        assert not link.lower().startswith(("http:", "https:", "//", "file:")), link
    for link in page.links:
        assert link.startswith(("data:image/png;base64,", "#")), link[:40]
    assert "http://" not in text and "https://" not in text
    assert "url(" not in text  # no CSS that could fetch anything
    for src in page.images:
        png = base64.b64decode(src.split(",", 1)[1], validate=True)
        assert png.startswith(PNG_SIGNATURE)


# --------------------------------------------------------------------------- fixtures


def _quality(n):
    return np.linspace(1.0, 5.0, n) + np.array([0.3, -0.2, 0.1, -0.4, 0.2, 0.0])[:n]


@pytest.fixture(scope="module")
def survey_dir(tmp_path_factory):
    """A finished survey of six views (one with an id to escape) and two failures."""
    root = tmp_path_factory.mktemp("survey")
    L = np.full((24, 32), 50.0)
    L[:, 16:] = 120.0
    L[4:8, 10:16] = 20000.0
    labels = np.zeros(L.shape, dtype=int)
    labels[4:8, 10:16] = 1
    write_false_colour_png(LuminanceMap(L, calibrated=True), root / "falsecolour.png", dpi=40)
    write_glare_source_png(L, labels, root / "sources.png", dpi=40)
    write_contrast_png(np.where(labels > 0, 30.0, 0.0), root / "contrast.png", dpi=40)
    images = {kind: (root / f"{kind}.png").read_bytes()
              for kind in ("falsecolour", "sources", "contrast")}
    rng = np.random.default_rng(1)
    quality = _quality(len(VIEWS))
    rows, ratings = [], []
    for i, view in enumerate(VIEWS):
        rating = [float(np.clip(round(2 + 1.4 * quality[i] + d), 1, 10))
                  for d in rng.normal(0, 0.8, 5)]
        ratings += [(view, f"obs{k}", r) for k, r in enumerate(rating)]
        row = {"view": view, "ugr_pixel": 14 + 2 * quality[i], "ugr_pixel_u": 0.31,
               "ugr_grouped": 13 + 2 * quality[i], "ugr_grouped_u": 0.3,
               "q": quality[i], "q_u": 0.05, "dgp": 0.2 + 0.01 * i, "dgp_u": 0.004,
               "vertical_illuminance": 300.0 + 10 * i, "vertical_illuminance_u": 6.0,
               "background_luminance": 40.0 + i, "background_luminance_u": 0.8}
        for n in SWEEP:
            row[f"q_n{n}"] = quality[i] if n == 20 else quality[i] + rng.normal(0, 1.0)
        row.update({"rating_mean": float(np.mean(rating)), "rating_n": len(rating),
                    "lsadphoto_version": "test", "profile": "synthetic-test",
                    "calibration_method": "spot", "calibration_factor": 1.02,
                    "calibrated": True, "notes": "", "warnings": ""})
        rows.append(row)
        layout = ViewLayout(root, view)
        layout.folder.mkdir(parents=True)
        for kind, png in images.items():  # one set of images serves every view
            layout.path(kind).write_bytes(png)
        layout.path("score").write_text(
            '{"settings": {"sweep": [1, 100], "threshold": 2000}, "provenance": {"x": 1}}')
        # The done marker lists the view's files by kind, as the survey writes it.
        layout.done.write_text(json.dumps(
            {"view": view, "outputs": {k: p.name for k, p in layout.outputs().items()
                                       if k != "done"}}))
    columns = list(dict.fromkeys(c for row in rows for c in row))
    with open(root / "metrics.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, columns)
        writer.writeheader()
        writer.writerows(rows)
    with open(root / "ratings.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["scene", "observer", "rating"])
        writer.writerows(ratings)
    (root / "failures.log").write_text("F7: no spot reading for the view\n"
                                       "F8<i>: RAW file 'x&y.dng' is <corrupt>\n")
    return root


@pytest.fixture(scope="module")
def study(survey_dir, tmp_path_factory):
    """run_study on the survey's own tables rewritten in the study's format."""
    folder = tmp_path_factory.mktemp("study")
    with open(survey_dir / "metrics.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    columns = ["ugr_pixel", "q"] + [f"q_n{n}" for n in SWEEP]
    with open(folder / "METRICS.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["scene"] + columns)
        writer.writerows([[r["view"]] + [r[c] for c in columns] for r in rows])
    shutil.copy(survey_dir / "ratings.csv", folder / "RATINGS.csv")
    return run_study(folder / "RATINGS.csv", folder / "METRICS.csv", n_jitter=200,
                     n_bootstrap=200, seed=3)


# --------------------------------------------------------------------------- survey report


@pytest.fixture(scope="module")
def study_report(survey_dir, study, tmp_path_factory):
    """The survey report with the study (written once, looked at by two tests)."""
    path = tmp_path_factory.mktemp("report") / "report.html"
    assert write_survey_report(survey_dir, path, study=study,
                               title="Metro <survey> & co") == path
    return path


def test_survey_report_with_study(survey_dir, study, study_report, tmp_path):
    path = study_report
    text = path.read_text(encoding="utf-8")
    page = Page(text)
    _check_self_contained(page, text)
    assert {"summary", "figures", "gallery", "failures", "study", "provenance"} <= page.ids
    # Title and ids escaped: the parser sees them as text, never as tags.
    assert "Metro <survey> & co" in page.text and "<survey>" not in text
    assert NASTY in page.text and NASTY not in text and html.escape(NASTY) in text
    assert "F8<i>" in page.text and "is <corrupt>" in page.text and "<corrupt>" not in text
    assert "i" not in page.tags  # no tag came from the data
    # Figures 1, 2, 4 and 3 × 6 gallery images, all embedded.
    assert len(page.images) == 3 + 3 * len(VIEWS)
    for caption in ("Fig. 1", "Fig. 2", "Fig. 3", "Fig. 4"):
        assert caption in page.text
    assert "not available" not in page.text.split("Views")[0]
    # Summary counts and a value ± uncertainty (GUM rounding: u to two digits).
    assert "6 view(s) processed, 2 failed" in page.text
    q0 = _quality(6)[0]
    assert f"{14 + 2 * q0:.2f} ± 0.31" in page.text
    # Study numbers, as the study computed them.
    record = study.to_dict()
    stats = record["correlations"]["q"]
    assert f"{stats['pearson_r']:.3f}" in page.text
    assert f"[{stats['pearson_ci'][0]:.3f}, {stats['pearson_ci'][1]:.3f}]" in page.text
    assert stats["chaddock"] in page.text
    assert f"{stats['spearman_rho']:.3f}" in page.text
    assert f"{stats['kendall_tau']:.3f}" in page.text
    best = record["sweep"]["best"]
    assert best["n"] == 20  # the sweep column equal to Q
    assert f"{best['r']:.3f}" in page.text
    assert f"{record['jitter']['mean']:.3f}" in page.text
    lo, hi = record["bootstrap"]["bca"]
    assert f"[{lo:.3f}, {hi:.3f}]" in page.text
    assert f"{record['leave_one_out']['r_loo']:.3f}" in page.text
    # Provenance: versions, the study's input hashes, per-view columns, score settings.
    assert record["provenance"]["metrics_csv"]["sha256"] in page.text
    assert "synthetic-test" in page.text and "threshold" in page.text
    # The dict form gives the same report body (less the time stamps).
    again = write_survey_report(survey_dir, tmp_path / "again.html", study=record)
    assert len(Page(again.read_text(encoding="utf-8")).images) == len(page.images)


def test_survey_report_without_study_uses_the_table(survey_dir):
    path = write_survey_report(survey_dir)
    assert path == survey_dir / "report.html"
    text = path.read_text(encoding="utf-8")
    page = Page(text)
    _check_self_contained(page, text)
    assert len(page.images) == 3 + 3 * len(VIEWS)
    assert "Computed here by lsadphoto.study from the survey's ratings.csv and metrics.csv" \
        in page.text
    # The statistics are the study's on the survey's own tables (one path, not a copy) …
    own = run_study(survey_dir / "ratings.csv", survey_dir / "metrics.csv", n_jitter=0,
                    n_bootstrap=0).to_dict()
    best = own["sweep"]["best"]
    assert best["n"] == 20 and f"{best['r']:.3f}" in page.text  # the column equal to Q
    assert f"{own['leave_one_out']['r_loo']:.3f}" in page.text
    assert "The jitter check is not available" in page.text
    # … and its Pearson r of Q is numpy's on the table's q and mean-rating columns.
    with open(survey_dir / "metrics.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    r = np.corrcoef([float(r["q"]) for r in rows], [float(r["rating_mean"]) for r in rows])[0, 1]
    assert own["correlations"]["q"]["pearson_r"] == pytest.approx(r, abs=1e-12)
    assert f"{r:.3f}" in page.text
    path.unlink()


def test_gallery_limit(survey_dir, tmp_path):
    page = Page(write_survey_report(survey_dir, tmp_path / "r.html",
                                    max_gallery_views=2).read_text(encoding="utf-8"))
    assert len(page.images) == 3 + 3 * 2
    assert "the first 2 of 6 views are shown" in page.text


def _write_csv(path, header, rows):
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows(rows)


@pytest.mark.parametrize("case", ["empty", "all_failed", "no_ratings", "no_images",
                                  "garbage"])
def test_missing_pieces_give_notes_not_errors(tmp_path, case):
    folder = tmp_path / "out"
    folder.mkdir()
    expected = []
    if case == "empty":
        expected = ["no metrics.csv", "Fig. 1 (ratings against Q) is not available",
                    "Fig. 4 (Q against UGR) is not available: no processed views",
                    "No failures.log", "no observer ratings"]
    elif case == "all_failed":
        (folder / "metrics.csv").write_text("view\n")
        (folder / "failures.log").write_text("a: bad\nb: worse\n")
        expected = ["0 view(s) processed, 2 failed", "every view failed", "worse"]
    elif case == "no_ratings":
        _write_csv(folder / "metrics.csv", ["view", "ugr_pixel", "q", "dgp"],
                   [[f"v{i}", 15 + i, 1 + 0.5 * i, 0.3] for i in range(4)])
        (folder / "failures.log").write_text("")
        expected = ["Fig. 1 (ratings against Q) is not available: no observer ratings",
                    "Fig. 2 (r against N) is not available: no observer ratings",
                    "No view failed", "not among the view's outputs"]
    elif case == "no_images":
        _write_csv(folder / "metrics.csv", ["scene", "q", "rating_mean"],
                   [["s1", 1.0, 3.0], ["s2", 2.0, 4.0]])
        _write_csv(folder / "ratings.csv", ["scene", "observer", "rating"],
                   [["s1", "a", 3], ["s2", "a", 4]])
        expected = ["Fig. 2 (r against N) is not available: the observer study could not be "
                    "computed", "2 scene(s); a correlation needs at least 3",
                    "Fig. 4 (Q against UGR) is not available: metrics.csv lacks UGR",
                    "Fig. 3 — glare-source maps — is not available"]
    elif case == "garbage":
        (folder / "metrics.csv").write_bytes(b"view,q,ugr_pixel\n\xff\xfe,x,\n")
        expected = ["metrics.csv could not be read"]
    text = write_survey_report(folder).read_text(encoding="utf-8")
    page = Page(text)
    _check_self_contained(page, text)
    for phrase in expected:
        assert phrase in page.text, phrase
    if case == "no_ratings":
        assert len(page.images) == 1  # Fig. 4 only


def test_study_without_sweep_or_resampling(tmp_path):
    _write_csv(tmp_path / "R.csv", ["scene", "observer", "rating"],
               [[f"S{s}", f"o{o}", 1 + s + (o % 2)] for s in range(5) for o in range(3)])
    _write_csv(tmp_path / "M.csv", ["scene", "q", "ugr_pixel"],
               [[f"S{s}", 0.5 * s + 0.1 * (s % 2), 20 - s] for s in range(5)])
    study = run_study(tmp_path / "R.csv", tmp_path / "M.csv", n_jitter=0, n_bootstrap=0)
    (tmp_path / "survey").mkdir()
    page = Page(write_survey_report(tmp_path / "survey", study=study).read_text(encoding="utf-8"))
    assert len(page.images) == 1  # Fig. 1 from the study
    for phrase in ("Fig. 2 (r against N) is not available: the study has no sweep",
                   "The jitter check is not available", "The bootstrap is not available",
                   "The leave-one-out check is not available"):
        assert phrase in page.text, phrase


def test_bad_arguments(tmp_path):
    with pytest.raises(TypeError, match="study must be"):
        write_survey_report(tmp_path, study=[1, 2])
    with pytest.raises(TypeError, match="comparison must be"):
        write_comparison_report("x", tmp_path / "c.html")


def test_plot_functions_return_figures():
    x = np.array([1.0, 2.0, 3.0, np.nan])
    assert figure_ratings_vs_metric(x, [2, 3, 5, 1], sem=[0.1, np.nan, 0.2, 0.1]).axes
    assert figure_r_vs_n([1, 2, 3], [0.1, np.nan, 0.5], ci_low=[0, np.nan, 0.2],
                         ci_high=[0.2, np.nan, 0.7], best_n=3, best_r=0.5,
                         loo_chosen_n=[3, None]).axes
    assert figure_q_vs_ugr([10, 12], [1, 1], q_uncertainty=[0.1, 0.1]).axes


# --------------------------------------------------------------------------- comparison report


@pytest.fixture(scope="module")
def maps():
    cam = IdealFisheyeProjection("equidistant", 31.5, 31.5, 32.0, 180.0, 64, 64)
    d = cam.directions(*cam.pixel_grid())
    up = np.array([0.0, -math.sin(0.4), math.cos(0.4)])
    L = disk_sources_scene(d, background=100.0, sources=[(up, 0.15, 20000.0)])
    photo = LuminanceMap(L, projection=cam, calibrated=True, calibration_uncertainty=0.02,
                         provenance={"input": "<photo>.dng"})
    model = LuminanceMap(L * 1.1, projection=cam, uncertainty=0.01 * L * 1.1)
    return photo, model


@pytest.fixture(scope="module")
def comparison(maps):
    return compare_maps(*maps, grid=(2, 2))


def test_comparison_report(maps, comparison, tmp_path):
    photo, model = maps
    path = write_comparison_report(comparison, tmp_path / "c.html", photo=photo, model=model,
                                   title="Station <1>")
    text = path.read_text(encoding="utf-8")
    page = Page(text)
    _check_self_contained(page, text)
    assert {"summary", "metrics", "maps", "ratios", "provenance"} <= page.ids
    assert "Station <1>" in page.text and "<photo>.dng" in page.text
    # The ratio map, and the interactive viewer of both maps in place of their false colour.
    assert len(page.images) == 1 and text.count('class="lsad-viewer"') == 1
    m = comparison.metrics["ugr_grouped"]
    assert f"{m['difference']:.2f}" in page.text  # difference ± u, GUM rounding
    assert "differ" in page.text  # 1.1 × is outside 2u for UGR
    field = comparison.field
    assert f"{field['median_ratio']:.4g}" in page.text
    assert "rows 0–32, cols 32–64" in page.text and "30–60" in page.text
    # The to_dict() form without maps: tables, and notes where the images would be.
    page = Page(write_comparison_report(comparison.to_dict(), tmp_path / "d.html")
                .read_text(encoding="utf-8"))
    assert not page.images
    assert "no ratio map" in page.text and "no photo luminance map was given" in page.text
    # The to_dict() form with the maps: the ratio map is recomputed.
    text = write_comparison_report(comparison.to_dict(), tmp_path / "e.html", photo=photo,
                                   model=model).read_text(encoding="utf-8")
    assert len(Page(text).images) == 1 and 'class="lsad-viewer"' in text
    # An empty record is still a report.
    page = Page(write_comparison_report({}, tmp_path / "f.html").read_text(encoding="utf-8"))
    assert "The metric table is not available" in page.text


# --------------------------------------------------------------------------- real browser

#: Screenshot size [px]: the page at 1280 px wide, the first 2000 px of it.
WINDOW = (1280, 2000)


def _screenshot(report, folder):
    """Render ``report`` with headless chromium; returns the screenshot as an RGB array."""
    chromium = shutil.which("chromium")
    if chromium is None:
        pytest.skip("chromium is not installed (Debian: apt-get install -y chromium); "
                    "the headless-browser check of the report is skipped")
    shot = folder / "shot.png"
    command = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
               "--no-first-run", "--disable-background-networking",
               "--disable-component-update", "--disable-sync", "--hide-scrollbars",
               f"--user-data-dir={folder / 'profile'}", f"--screenshot={shot}",
               f"--window-size={WINDOW[0]},{WINDOW[1]}", Path(report).resolve().as_uri()]
    result = subprocess.run(command, capture_output=True, text=True, timeout=90, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    assert shot.is_file(), result.stderr[-2000:]
    from matplotlib import image

    return image.imread(shot)[..., :3]


def test_survey_report_renders_in_a_browser(study_report, tmp_path):
    rgb = _screenshot(study_report, tmp_path)
    assert rgb.shape[:2] == (WINDOW[1], WINDOW[0])
    assert rgb.std() > 0.05  # not a blank page
    # The figures render: colourful pixels (the plot markers, the false-colour maps) in the
    # figure area below the summary, which plain text and grey tables never give.
    saturation = rgb.max(axis=-1) - rgb.min(axis=-1)
    assert (saturation[400:, :] > 0.3).sum() > 2000
    # Non-white content in every quarter of the page width: the figure grid has two columns.
    dark = rgb.mean(axis=-1) < 0.8
    for quarter in np.array_split(dark[:, 40:1240], 4, axis=1):
        assert quarter.sum() > 500


def test_comparison_report_renders_in_a_browser(maps, comparison, tmp_path):
    photo, model = maps
    report = write_comparison_report(comparison, tmp_path / "c.html",
                                     photo=photo, model=model)
    rgb = _screenshot(report, tmp_path)
    assert rgb.shape[:2] == (WINDOW[1], WINDOW[0])
    saturation = rgb.max(axis=-1) - rgb.min(axis=-1)
    assert (saturation > 0.3).sum() > 5000  # the ratio and false-colour maps drawn
