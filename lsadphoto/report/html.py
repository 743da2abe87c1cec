"""Self-contained HTML reports: a survey (with its observer study) and a model-vs-photo comparison.

One ``.html`` file holds everything: CSS inline, every image a PNG ``data:`` URI, the
interactive luminance viewer of each view (:mod:`lsadphoto.viewer`: its script inline, its
maps embedded), no external request — it can be mailed, archived with the data, or opened
from a USB stick. Every piece of text that came from data (view ids, file names, notes, failure
reasons) is HTML-escaped. Files are written atomically. Missing pieces (no ratings, no sweep
columns, an empty survey, every view failed, no study) never stop a report: the section says
what is missing and why.

* :func:`write_survey_report` — summary, the paper's Figures 1–4 for the survey's data,
  per-view gallery (the interactive viewer, glare sources, contrast), failures,
  observer-study statistics, provenance.
* :func:`write_comparison_report` — ratio statistics over the field and per region, metric
  agreement within the combined uncertainty, ratio map and the viewer of both maps.

The contents are described in ``docs/user-guide-report.md``.

References
----------
Budak, V. P. et al. (2020), GraphiCon 2020, CEUR Vol-2744 short35 (Figures 1–4).
JCGM 100:2008 (GUM) §7.2.2 (reporting a value with its standard uncertainty).
"""

import base64
import csv
import datetime
import hashlib
import html
import json
import math
import platform
import tempfile
import warnings
from pathlib import Path

import numpy as np

from .._version import __version__
from .._atomic import atomic_text

__all__ = ["write_survey_report", "write_comparison_report", "check_survey_folder"]


#: Columns naming the view in metrics.csv, in order of preference.
_ID_COLUMNS = ("view", "scene")
#: Columns holding the mean observer rating of a view, in order of preference.
_RATING_COLUMNS = ("rating_mean", "mean_rating")
#: Prefix of the Q(N) sweep columns.
_SWEEP_PREFIX = "q_n"
#: Per-view provenance columns of metrics.csv shown in the provenance section.
_PROVENANCE_COLUMNS = ("lsadphoto_version", "profile", "calibration_method",
                       "calibration_factor", "calibration_uncertainty", "calibrated",
                       "saturated_fraction", "demosaic", "raw_files", "line_of_sight",
                       "timestamp", "model_comparison", "notes", "warnings")
#: Gallery images of a view: (file suffix, caption).
_GALLERY = (("falsecolour", "false colour luminance"), ("sources", "glare sources (Fig. 3)"),
            ("contrast", "contrast map K"))
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;margin:0;
color:#1d2327;background:#fff;line-height:1.4;font-size:15px}
main{max-width:1220px;margin:0 auto;padding:12px 24px 48px}
h1{font-size:1.6em;margin:0.4em 0 0.2em}h2{font-size:1.3em;margin-top:1.8em;
border-bottom:2px solid #d0d7de;padding-bottom:4px}h3{font-size:1.05em;margin:1.2em 0 0.4em}
nav{font-size:0.9em;margin:0.4em 0 1em}nav a{margin-right:1em;color:#0550ae}
.subtitle{color:#57606a;font-size:0.9em}
table{border-collapse:collapse;margin:0.4em 0 1em;font-size:0.88em}
th,td{border:1px solid #d0d7de;padding:3px 8px;text-align:left;vertical-align:top}
th{background:#f3f5f7}td.num{text-align:right;font-variant-numeric:tabular-nums;
white-space:nowrap}
.cards{display:flex;flex-wrap:wrap;gap:12px;margin:0.6em 0}
.card{border:1px solid #d0d7de;border-radius:6px;padding:8px 14px;background:#f8f9fa}
.card b{display:block;font-size:1.5em}
.figures{display:grid;grid-template-columns:repeat(auto-fill,minmax(540px,1fr));gap:16px}
figure{margin:0;border:1px solid #d0d7de;border-radius:6px;padding:8px;background:#fff}
figure img{width:100%;height:auto;display:block}
figcaption{font-size:0.85em;color:#57606a;margin-top:4px}
.view{border:1px solid #d0d7de;border-radius:6px;padding:8px 12px;margin:12px 0}
.view h3{margin:0.2em 0 0.4em}
.triple{display:grid;grid-template-columns:repeat(3,1fr);gap:8px}
.triple figure{border:none;padding:0}
.note{border-left:4px solid #bf8700;background:#fff8c5;padding:6px 10px;margin:8px 0}
.unavailable{border:2px dashed #afb8c1;border-radius:6px;padding:18px;color:#57606a;
background:#f6f8fa}
.ok{color:#1a7f37;font-weight:600}.bad{color:#cf222e;font-weight:600}
.scroll{overflow-x:auto;max-width:100%}
details{margin:0.4em 0 1em}summary{cursor:pointer;color:#0550ae}
code{font-size:0.9em}
"""


# --------------------------------------------------------------------------- HTML pieces


class _Html(str):
    """Text that is already HTML (escaped where it came from data)."""


def _e(value):
    """``value`` as HTML: escaped unless it is already :class:`_Html`."""
    if isinstance(value, _Html):
        return value
    return _Html(html.escape("" if value is None else str(value), quote=True))


def _cat(*parts):
    return _Html("".join(_e(p) for p in parts))


def _tag(name, content="", *, cls=None, **attrs):
    attributes = "".join(f' {k.rstrip("_")}="{_e(v)}"' for k, v in attrs.items()
                         if v is not None)
    if cls:
        attributes += f' class="{_e(cls)}"'
    return _Html(f"<{name}{attributes}>{_e(content)}</{name}>")


def _number(value):
    """A finite float, or None."""
    if value is None or isinstance(value, bool):
        return None
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def _fmt(value, digits=4):
    """A number with ``digits`` significant digits ("—" for none, NaN or text)."""
    if isinstance(value, bool):
        return "yes" if value else "no"
    number = _number(value)
    if number is None:
        return "—" if value is None or isinstance(value, (int, float)) else str(value)
    if number == int(number) and abs(number) < 1e9:
        return str(int(number))
    return f"{number:.{digits}g}"


def _fmt_pm(value, uncertainty):
    """``value ± u`` with u to two significant digits and the value to the same decimal.

    >>> _fmt_pm(19.2345, 0.3141), _fmt_pm(0.5, None), _fmt_pm(1234.5, 20.0)
    ('19.23 ± 0.31', '0.5', '1234 ± 20')
    """
    v, u = _number(value), _number(uncertainty)
    if v is None:
        return "—"
    if u is None or u <= 0:
        return _fmt(v)
    decimals = min(max(0, 1 - math.floor(math.log10(u))), 8)
    return f"{v:.{decimals}f} ± {u:.{decimals}f}"


def _fmt_fixed(value, decimals):
    v = _number(value)
    return "—" if v is None else f"{v:.{decimals}f}"


def _fmt_r(value):
    v = _number(value)
    return "—" if v is None else f"{v:.3f}"


def _fmt_ci(pair):
    if not isinstance(pair, (list, tuple)) or len(pair) != 2:
        return "—"
    lo, hi = _number(pair[0]), _number(pair[1])
    return "—" if lo is None or hi is None else f"[{lo:.3f}, {hi:.3f}]"


def _fmt_p(value):
    v = _number(value)
    return "—" if v is None else f"{v:.3g}"


def _table(headers, rows, *, numeric=None):
    """A table; cells are escaped unless :class:`_Html`; ``numeric``: right-aligned columns."""
    numeric = set(numeric or ())
    head = _Html("".join(_tag("th", h) for h in headers))
    body = []
    for row in rows:
        cells = "".join(_tag("td", c, cls="num" if i in numeric else None)
                        for i, c in enumerate(row))
        body.append(f"<tr>{cells}</tr>")
    return _Html(f'<div class="scroll"><table><thead><tr>{head}</tr></thead>'
                 f"<tbody>{''.join(body)}</tbody></table></div>")


def _kv_table(mapping, *, depth=0):
    """A nested key/value table of a JSON-like mapping (long lists shortened)."""
    if not isinstance(mapping, dict) or not mapping:
        return _tag("p", "(none)")
    rows = []
    for key, value in mapping.items():
        if isinstance(value, dict) and depth < 4:
            cell = _kv_table(value, depth=depth + 1)
        elif isinstance(value, (list, tuple)):
            shown = [json.dumps(v, default=str, ensure_ascii=False)
                     if isinstance(v, (dict, list)) else _fmt(v, 6) for v in value[:20]]
            cell = ", ".join(shown) + (f" … ({len(value) - 20} more)" if len(value) > 20 else "")
        else:
            cell = _fmt(value, 6)
        rows.append((key, cell))
    return _table(("key", "value"), rows)


def _note(text):
    return _tag("p", text, cls="note")


def _unavailable(what, why):
    return _Html(f'<div class="unavailable"><b>{_e(what)} is not available:</b> '
                 f'{_e(why)}</div>')


def _data_uri(png):
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def _img(png, alt):
    return _Html(f'<img src="{_data_uri(png)}" alt="{_e(alt)}">')


def _figure_html(png, caption):
    return _Html(f"<figure>{_img(png, caption)}{_tag('figcaption', caption)}</figure>")


def _section(anchor, heading, *content):
    return _Html(f'<section id="{_e(anchor)}">{_tag("h2", heading)}'
                 + "".join(_e(c) for c in content) + "</section>")


def _document(title, subtitle, sections, nav):
    links = "".join(f'<a href="#{_e(a)}">{_e(t)}</a>' for a, t in nav)
    return (
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
        f"<meta name=\"generator\" content=\"lsadphoto {_e(__version__)}\">\n"
        f"<title>{_e(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n<main>\n"
        f"<header>{_tag('h1', title)}{_tag('p', subtitle, cls='subtitle')}"
        f"<nav>{links}</nav></header>\n"
        + "\n".join(sections) + "\n</main>\n</body>\n</html>\n")


def _draw(figure_function, *args, **kwargs):
    """PNG bytes of a plots.py figure, or (None, reason) when matplotlib fails on the data."""
    from .plots import png_bytes

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # e.g. a degenerate axis range: the plot is still useful
            return png_bytes(figure_function(*args, **kwargs)), None
    except Exception as error:  # noqa: BLE001 — a report shows the reason instead of failing
        return None, f"the figure could not be drawn ({type(error).__name__}: {error})"


def _versions():
    import matplotlib
    import scipy

    return {"lsadphoto": __version__, "python": platform.python_version(),
            "numpy": np.__version__, "scipy": scipy.__version__,
            "matplotlib": matplotlib.__version__, "platform": platform.platform()}


def _now():
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


# --------------------------------------------------------------------------- survey data


class _Survey:
    """What a survey folder holds, read leniently (problems become notes)."""

    def __init__(self, directory):
        self.directory = Path(directory)
        self.notes = []
        self.columns, self.rows, self.id_column = [], [], None
        self.metrics_sha256 = None
        self.failures = []
        self._read_metrics()
        self._read_failures()

    def _read_metrics(self):
        path = self.directory / "metrics.csv"
        if not path.is_file():
            self.notes.append(f"no metrics.csv in {self.directory}: no view was processed "
                              "(or the survey has not been run)")
            return
        try:
            data = path.read_bytes()
            self.metrics_sha256 = hashlib.sha256(data).hexdigest()
            reader = csv.DictReader(data.decode("utf-8-sig").splitlines())
            self.columns = [c.strip() for c in reader.fieldnames or []]
            self.rows = [{(k or "").strip(): (v or "").strip() for k, v in row.items()
                          if k is not None} for row in reader]
        except (OSError, UnicodeDecodeError, csv.Error) as error:
            self.notes.append(f"metrics.csv could not be read: {error}")
            self.columns, self.rows = [], []
            return
        self.id_column = next((c for c in _ID_COLUMNS if c in self.columns), None)
        if self.id_column is None and self.columns:
            self.notes.append("metrics.csv has no 'view' or 'scene' column; rows are numbered")

    def _read_failures(self):
        path = self.directory / "failures.log"
        if not path.is_file():
            return
        try:
            lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
        except OSError as error:
            self.notes.append(f"failures.log could not be read: {error}")
            return
        for line in lines:
            if line.strip():
                view, sep, reason = line.partition(": ")
                self.failures.append((view, reason) if sep else ("", line))

    def ids(self):
        if self.id_column is None:
            return [f"row {i + 1}" for i in range(len(self.rows))]
        return [row.get(self.id_column, "") for row in self.rows]

    def column(self, name):
        """float64 values of a column over the views (NaN where empty or not a number)."""
        values = [_number(row.get(name)) for row in self.rows]
        return np.array([np.nan if v is None else v for v in values], dtype=np.float64)

    def has(self, name):
        return name in self.columns and np.any(np.isfinite(self.column(name)))

    def rating_column(self):
        return next((c for c in _RATING_COLUMNS if self.has(c)), None)

    def _outputs(self, view):
        """``{kind: Path}`` of a view's files, as its done marker lists them (the survey's
        :class:`~lsadphoto.survey.ViewLayout` names them; the report only reads the marker)."""
        root = (self.directory / "views").resolve()
        try:
            folder = (root / view).resolve()
            marker = json.loads((folder / f"{view}-done.json").read_text(encoding="utf-8"))
            names = marker["outputs"]
            paths = {kind: (folder / name).resolve() for kind, name in names.items()}
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            return {}
        # Only files inside the view's folder (a marker is data, and data may be hostile).
        return {k: p for k, p in paths.items() if p.parent == folder and p.is_file()}

    def view_file(self, view, kind):
        """Path of the view's output of this kind (e.g. ``sources``) if it is there, else None."""
        return self._outputs(view).get(kind)

    def score_record(self, view):
        path = self.view_file(view, "score")
        try:
            return None if path is None else json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None


def _study_dict(study):
    """The study's ``to_dict()`` record, or None."""
    if study is None:
        return None
    if hasattr(study, "to_dict"):
        return study.to_dict()
    if isinstance(study, dict):
        return study
    raise TypeError(f"study must be a StudyResult, its to_dict() or None, got "
                    f"{type(study).__name__}")


def _survey_study(survey, study):
    """The study record the report shows, why there is none, and a note if it was made here.

    Every statistic of the report comes from :func:`lsadphoto.study.run_study`: the one
    given, or, without one, a run on the survey's own ``ratings.csv`` and ``metrics.csv``
    (without the jitter and bootstrap checks, which take the study command's options).
    """
    if study is not None:
        return _study_dict(study), None, None
    ratings, metrics = survey.directory / "ratings.csv", survey.directory / "metrics.csv"
    if not ratings.is_file():
        return None, ("no observer ratings (the survey folder has no ratings.csv: views get "
                      "ratings in the manifest) and no study result was given"), None
    if not metrics.is_file():
        return None, "no metrics.csv (no view was processed)", None
    from ..errors import BadInputError
    from ..study import run_study

    try:
        result = run_study(ratings, metrics, n_jitter=0, n_bootstrap=0)
    except BadInputError as error:
        return None, f"the observer study could not be computed: {error}", None
    return result.to_dict(), None, (
        "Computed here by lsadphoto.study from the survey's ratings.csv and metrics.csv, "
        "without the rating-jitter and bootstrap checks: `lsadphoto study ratings.csv "
        "metrics.csv --report FOLDER` adds them.")


def _floats(values):
    return np.array([np.nan if _number(v) is None else float(v) for v in values],
                    dtype=np.float64)


# --------------------------------------------------------------------------- survey sections


def _summary_section(survey, study):
    ids = survey.ids()
    rating_column = survey.rating_column()
    cards = [("views processed", len(ids)), ("views failed", len(survey.failures))]
    if rating_column:
        cards.append(("views with ratings",
                      int(np.isfinite(survey.column(rating_column)).sum())))
    if study is not None:
        cards.append(("scenes in the study", len(study.get("scenes") or [])))
    parts = [_Html('<div class="cards">' + "".join(
        f'<div class="card"><b>{_e(_fmt(v))}</b>{_e(t)}</div>' for t, v in cards) + "</div>")]
    parts += [_note(n) for n in survey.notes]
    if not ids:
        parts.append(_unavailable("The metrics table",
                                  "no view finished" + (" — every view failed (see Failures)"
                                                        if survey.failures else "")))
        return _section("summary", "Summary", *parts)
    metrics = [(c, *_label_unit(c)) for c in _headline() if c in survey.columns]
    if not metrics:
        parts.append(_note("metrics.csv has none of the key metric columns ("
                           + ", ".join(_headline()) + ")"))
    headers = ["view"] + [f"{label} [{unit}]" for _, label, unit in metrics]
    numeric = set(range(1, len(headers) + 1))
    if rating_column:
        headers.append("mean rating (n)")
    rows = []
    for i, (view, row) in enumerate(zip(ids, survey.rows)):
        cells = [view] + [_fmt_pm(row.get(c), row.get(f"{c}_u")) for c, _, _ in metrics]
        if rating_column:
            n = row.get("rating_n")
            cells.append(_fmt_fixed(row.get(rating_column), 2)
                         + (f" ({_fmt(n)})" if _number(n) is not None else ""))
        rows.append(cells)
    parts.append(_tag("h3", "Key metrics per view (value ± standard uncertainty)"))
    parts.append(_table(headers, rows, numeric=numeric))
    across = []
    for c, label, unit in metrics:
        values = survey.column(c)
        values = values[np.isfinite(values)]
        if values.size:
            across.append((f"{label} [{unit}]", values.size, _fmt(values.min()),
                           _fmt(np.median(values)), _fmt(values.max())))
    if across:
        parts.append(_tag("h3", "Across views"))
        parts.append(_table(("metric", "views", "min", "median", "max"), across,
                            numeric={1, 2, 3, 4}))
    other = [c for c in survey.columns if c != survey.id_column
             and not c.startswith(_SWEEP_PREFIX) and c not in _PROVENANCE_COLUMNS]
    if other:
        table = _table([survey.id_column or "row"] + other,
                       [[v] + [_fmt(r.get(c), 6) if _number(r.get(c)) is not None
                               else r.get(c, "") for c in other]
                        for v, r in zip(ids, survey.rows)])
        parts.append(_Html(f"<details><summary>All scalar columns of metrics.csv "
                           f"({len(other)})</summary>{table}</details>"))
    return _section("summary", "Summary", *parts)


def _fig1(study, why_no_study):
    from .plots import figure_ratings_vs_metric

    what = "Fig. 1 (ratings against Q)"
    if study is None or not study.get("scenes"):
        return _unavailable(what, why_no_study)
    caption = ("Fig. 1 — mean observer rating against the quality criterion, one point per "
               "scene, error bars the standard error of the mean rating, red the "
               "least-squares line.")
    metric = study.get("metric") or "q"
    scenes = study["scenes"]
    x = _floats([s.get(metric) for s in scenes])
    y = _floats([s.get("mean") for s in scenes])
    sem = _floats([s.get("sem") for s in scenes])
    stats = (study.get("correlations") or {}).get(metric) or {}
    png, why = _draw(figure_ratings_vs_metric, x, y, sem=sem,
                     labels=[s.get("scene") for s in scenes],
                     metric_name=_metric_label(metric).replace(" [–]", ""),
                     r=_number(stats.get("pearson_r")))
    if png is None:
        return _unavailable(what, why)
    return _figure_html(png, f"{caption} Data: the observer study (metric {metric!r}, "
                             f"{len(scenes)} scenes).")


def _fig2(study, why_no_study):
    from .plots import figure_r_vs_n

    what = "Fig. 2 (r against N)"
    if study is None:
        return _unavailable(what, why_no_study)
    sweep = study.get("sweep")
    if not sweep:
        return _unavailable(what, "the study has no sweep (no q_n<N> columns in its metrics "
                                  "table)")
    caption = ("Fig. 2 — Pearson r between Q(N) and the mean ratings against the number of "
               "thresholds N; shaded the 95 % Fisher-z band, dashed the best N.")
    best = sweep.get("best") or {}
    loo = (study.get("leave_one_out") or {}).get("chosen_n")
    confidence = (study.get("provenance") or {}).get("arguments", {}).get("confidence", 0.95)
    png, why = _draw(figure_r_vs_n, _floats(sweep.get("n", [])), _floats(sweep.get("r", [])),
                     ci_low=_floats(sweep.get("ci_low", [])),
                     ci_high=_floats(sweep.get("ci_high", [])),
                     best_n=_number(best.get("n")), best_r=_number(best.get("r")),
                     loo_chosen_n=loo, confidence=_number(confidence) or 0.95)
    if png is None:
        return _unavailable(what, why)
    return _figure_html(png, f"{caption} Data: the observer study ({len(sweep.get('n', []))} "
                             f"values of N, best N chosen as the "
                             f"{sweep.get('direction', 'positive')} extreme; green ticks: N "
                             "chosen in each leave-one-scene-out fold).")


def _fig4(survey):
    from .plots import figure_q_vs_ugr

    what = "Fig. 4 (Q against UGR)"
    ugr = next((c for c in ("ugr_pixel", "ugr_grouped") if survey.has(c)), None)
    if not survey.rows:
        return _unavailable(what, "no processed views")
    if ugr is None or not survey.has("q"):
        return _unavailable(what, "metrics.csv lacks " + ("UGR" if ugr is None else "Q")
                            + " values")
    x, y = survey.column(ugr), survey.column("q")
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 2:
        return _unavailable(what, f"only {int(ok.sum())} view(s) have both Q and UGR")
    name = "pixel-wise UGR" if ugr == "ugr_pixel" else "UGR (grouped sources)"
    ids = survey.ids()
    png, why = _draw(figure_q_vs_ugr, x[ok], y[ok],
                     ugr_uncertainty=survey.column(f"{ugr}_u")[ok],
                     q_uncertainty=survey.column("q_u")[ok],
                     labels=[v for v, k in zip(ids, ok) if k], ugr_name=name)
    if png is None:
        return _unavailable(what, why)
    return _figure_html(png, f"Fig. 4 — Q against {name}, one point per view, error bars the "
                             f"standard uncertainties; red the least-squares line. Data: "
                             f"metrics.csv columns {ugr} and q ({int(ok.sum())} views).")


def _figures_section(survey, study, why_no_study):
    parts = [_Html('<div class="figures">'), _fig1(study, why_no_study),
             _fig2(study, why_no_study),
             _fig4(survey), _Html("</div>")]
    n_sources = sum(1 for v in survey.ids() if survey.view_file(v, "sources"))
    parts.append(_tag("p", f"Fig. 3 — the glare-source maps — is drawn per view: "
                           f"{n_sources} of them are in the gallery below."
                      if n_sources else
                      "Fig. 3 — glare-source maps — is not available: no view has a "
                      "sources image."))
    return _section("figures", "Figures of the paper for this survey", *parts)


def _view_viewer(survey, view):
    """The interactive viewer of a view (its map, the model beside it where the survey
    rendered one, the score's glare sources), or (None, why)."""
    from ..viewer import report_viewer

    photo = survey.view_file(view, "exr") if survey.id_column else None
    if photo is None:
        return None, "no luminance map among the view's outputs"
    return report_viewer(photo, second=survey.view_file(view, "model_exr"),
                         score=survey.score_record(view), title=view,
                         source_labels=survey.view_file(view, "source_labels"))


def _gallery_section(survey, max_views, viewers=True):
    ids = survey.ids()
    if not ids:
        return _section("gallery", "Views", _unavailable("The gallery", "no processed views"))
    shown = ids if max_views is None else ids[:max_views]
    parts, shown_viewer = [], False
    if len(shown) < len(ids):
        parts.append(_note(f"the first {len(shown)} of {len(ids)} views are shown "
                           f"(max_gallery_views={max_views})"))
    for view, row in zip(shown, survey.rows):
        facts = [f"{label} {_fmt_pm(row.get(c), row.get(f'{c}_u'))}"
                 for c, (label, _) in ((c, _label_unit(c)) for c in _headline()[:4])
                 if _number(row.get(c)) is not None]
        cells = []
        viewer, why = _view_viewer(survey, view) if viewers else (None, None)
        if why is not None:
            facts.append(f"no interactive viewer: {why}")
        for kind, caption in _GALLERY:
            if kind == "falsecolour" and viewer is not None:
                continue  # the viewer shows the false colour, and points at it
            path = survey.view_file(view, kind) if survey.id_column else None
            png = None
            if path is not None:
                try:
                    png = path.read_bytes()
                except OSError:
                    png = None
            if png is not None and png.startswith(_PNG_SIGNATURE):
                cells.append(_figure_html(png, caption))
            else:
                cells.append(_Html("<figure>" + _unavailable(
                    caption, "not among the view's outputs (none listed by its done marker)")
                    + "</figure>"))
        parts.append(_Html('<div class="view">' + _tag("h3", view)
                           + (_tag("p", "; ".join(facts)) if facts else "") + (viewer or "")
                           + '<div class="triple">' + "".join(cells) + "</div></div>"))
        shown_viewer = shown_viewer or viewer is not None
    if shown_viewer:
        from ..viewer import viewer_assets

        parts.insert(0, _Html(viewer_assets()))
    return _section("gallery", "Views", *parts)


def _failures_section(survey):
    if not survey.failures:
        text = ("No view failed." if (survey.directory / "failures.log").is_file()
                else "No failures.log in the survey folder.")
        return _section("failures", "Failures", _tag("p", text))
    return _section("failures", f"Failures ({len(survey.failures)})",
                    _table(("view", "reason"), survey.failures))


def _correlation_table(correlations, confidence):
    rows = []
    for metric, s in correlations.items():
        rows.append((metric, _fmt(s.get("n")), _fmt_r(s.get("pearson_r")),
                     _fmt_ci(s.get("pearson_ci")), _fmt_p(s.get("pearson_p")),
                     s.get("chaddock") or "—", _fmt_r(s.get("spearman_rho")),
                     _fmt_p(s.get("spearman_p")), _fmt_r(s.get("kendall_tau")),
                     _fmt_p(s.get("kendall_p"))))
    return _table(("metric", "n", "Pearson r", f"{100 * confidence:g} % CI (Fisher z)", "p",
                   "Chaddock", "Spearman ρ", "p", "Kendall τ-b", "p"), rows,
                  numeric={1, 2, 3, 4, 6, 7, 8, 9})


def _study_section(study, why_no_study, computed_here):
    if study is None:
        return _section("study", "Observer-study statistics",
                        _unavailable("Observer-study statistics", why_no_study))
    from ..study.correlation import chaddock_label

    arguments = (study.get("provenance") or {}).get("arguments") or {}
    confidence = _number(arguments.get("confidence")) or 0.95
    metric = study.get("metric")
    parts = [_tag("p", f"Metric analysed in detail: {metric}; {len(study.get('scenes') or [])} "
                       f"scenes; intervals at {100 * confidence:g} %.")]
    if computed_here:
        parts.insert(0, _note(computed_here))
    parts += [_note(n) for n in study.get("notes") or []]
    correlations = study.get("correlations") or {}
    parts.append(_tag("h3", "Correlation of each metric with the mean rating"))
    parts.append(_correlation_table(correlations, confidence) if correlations
                 else _unavailable("The correlation table", "no metric could be correlated"))
    between = study.get("between_metrics") or {}
    if between:
        parts.append(_tag("h3", f"Correlation of {metric} with the other metrics"))
        parts.append(_table(("metric", f"Pearson r with {metric}", "n"),
                            [(k, _fmt_r(v.get("pearson_r")), _fmt(v.get("n")))
                             for k, v in between.items()], numeric={1, 2}))
    sweep = study.get("sweep")
    parts.append(_tag("h3", "Best number of thresholds N"))
    if sweep and sweep.get("best"):
        b = sweep["best"]
        parts.append(_table(("best N", "column", "Pearson r", f"{100 * confidence:g} % CI",
                             "Chaddock", "direction", "N swept"),
                            [(_fmt(b.get("n")), b.get("column", ""), _fmt_r(b.get("r")),
                              _fmt_ci(b.get("ci")), b.get("chaddock") or "—",
                              sweep.get("direction", ""),
                              f"{_fmt(min(sweep['n']))}–{_fmt(max(sweep['n']))} "
                              f"({len(sweep['n'])} values)" if sweep.get("n") else "—")],
                            numeric={0, 2, 3}))
    else:
        parts.append(_unavailable("The best N", "no sweep columns in the study" if not sweep
                                  else "every sweep column is constant"))
    jitter = study.get("jitter")
    parts.append(_tag("h3", "Rating jitter (the paper's robustness check)"))
    if jitter:
        parts.append(_table(
            ("half-width", "level", "trials", "r nominal", "mean r", "SD", "2.5 %", "97.5 %",
             "min", "max", "max relative change"),
            [(_fmt(jitter.get("half_width")), jitter.get("level", ""),
              _fmt(jitter.get("n_trials")), _fmt_r(jitter.get("r_nominal")),
              _fmt_r(jitter.get("mean")), _fmt_r(jitter.get("sd")),
              _fmt_r(jitter.get("percentile_2.5")), _fmt_r(jitter.get("percentile_97.5")),
              _fmt_r(jitter.get("min")), _fmt_r(jitter.get("max")),
              _fmt(jitter.get("max_relative_change"), 3))],
            numeric=set(range(11)) - {1}))
        counts = jitter.get("best_n_counts")
        if counts:
            parts.append(_tag("p", "Best N over the jittered trials: " + ", ".join(
                f"N = {k}: {v}" for k, v in sorted(counts.items(), key=lambda kv: -kv[1]))))
    else:
        parts.append(_unavailable("The jitter check", "it was not run (n_jitter = 0)"))
    boot = study.get("bootstrap")
    parts.append(_tag("h3", "Bootstrap over scenes"))
    if boot:
        parts.append(_table(
            ("resamples", "degenerate", "standard error", "percentile interval",
             "BCa interval", "bias correction ẑ₀", "acceleration â"),
            [(_fmt(boot.get("n_resamples")), _fmt(boot.get("n_degenerate")),
              _fmt(boot.get("standard_error"), 3), _fmt_ci(boot.get("percentile")),
              _fmt_ci(boot.get("bca")), _fmt(boot.get("bias_correction"), 3),
              _fmt(boot.get("acceleration"), 3))], numeric=set(range(7))))
    else:
        parts.append(_unavailable("The bootstrap", "it was not run (n_bootstrap = 0)"))
    loo = study.get("leave_one_out")
    parts.append(_tag("h3", "Leave-one-scene-out choice of N"))
    if loo:
        r_loo = _number(loo.get("r_loo"))
        parts.append(_table(
            ("r in sample", "r out of sample", f"{100 * confidence:g} % CI", "Chaddock",
             "r at the fixed best N", "Q²", "RMSE [rating]", "N chosen (folds)"),
            [(_fmt_r(loo.get("r_in_sample")), _fmt_r(r_loo), _fmt_ci(loo.get("r_loo_ci")),
              (chaddock_label(r_loo) if r_loo is not None else None) or "—",
              _fmt_r(loo.get("r_loo_fixed")), _fmt(loo.get("q2"), 3), _fmt(loo.get("rmse"), 3),
              ", ".join(f"N = {k}: {v}" for k, v in (loo.get("chosen_n_counts") or {}).items()))],
            numeric={0, 1, 2, 4, 5, 6}))
        folds = loo.get("folds") or []
        if folds:
            table = _table(("left-out scene", "N chosen", "training r", "prediction",
                            "mean rating"),
                           [(f.get("scene", ""), _fmt(f.get("chosen_n")), _fmt_r(f.get("train_r")),
                             _fmt(f.get("prediction"), 3), _fmt(f.get("rating"), 3))
                            for f in folds], numeric={1, 2, 3, 4})
            parts.append(_Html(f"<details><summary>Folds ({len(folds)})</summary>{table}"
                               "</details>"))
    else:
        parts.append(_unavailable("The leave-one-out check",
                                  "it needs a sweep and at least 4 scenes"))
    scenes = study.get("scenes") or []
    if scenes:
        parts.append(_tag("h3", "Scenes"))
        parts.append(_table(("scene", "mean rating", "SD", "n", "standard error", metric),
                            [(s.get("scene", ""), _fmt_fixed(s.get("mean"), 2),
                              _fmt(s.get("sd"), 3),
                              _fmt(s.get("n")), _fmt(s.get("sem"), 3), _fmt(s.get(metric), 4))
                             for s in scenes], numeric={1, 2, 3, 4, 5}))
    return _section("study", "Observer-study statistics", *parts)


def _provenance_section(survey, study, extra):
    parts = [_tag("h3", "This report"), _kv_table({**extra, **_versions()})]
    if survey.rows:
        columns = [c for c in _PROVENANCE_COLUMNS if c in survey.columns]
        if columns:
            parts.append(_tag("h3", "Per view (from metrics.csv)"))
            parts.append(_table(["view"] + columns,
                                [[v] + [_fmt(r.get(c), 6) if _number(r.get(c)) is not None
                                        else r.get(c, "") for c in columns]
                                 for v, r in zip(survey.ids(), survey.rows)]))
        record = survey.score_record(survey.ids()[0]) if survey.id_column else None
        if isinstance(record, dict):
            view = survey.ids()[0]
            for key, heading in (("settings", "Scoring settings"),
                                 ("provenance", "Scoring provenance")):
                if isinstance(record.get(key), dict):
                    parts.append(_Html(f"<details><summary>{_e(heading)} (from view "
                                       f"{_e(view)}'s score.json)</summary>"
                                       f"{_kv_table(record[key])}</details>"))
    if study is not None:
        parts.append(_tag("h3", "Observer study"))
        parts.append(_kv_table(study.get("provenance") or {}))
    return _section("provenance", "Provenance", *parts)


# --------------------------------------------------------------------------- entry points


def check_survey_folder(survey_dir, *, option=None):
    """The survey output folder ``survey_dir`` as a Path; one-line error if it is no folder.

    A folder without ``metrics.csv`` is accepted (its report says that nothing was
    processed); a path that does not exist is a typo, not an empty survey.

    Parameters
    ----------
    survey_dir : path-like
    option : str, optional
        The command-line option that gave the folder, named in the message.
    """
    survey_dir = Path(survey_dir)
    if not survey_dir.is_dir():
        from ..errors import BadInputError

        state = "is not a folder" if survey_dir.exists() else "does not exist"
        given = f" ({option} takes the output folder of `lsadphoto survey`)" if option else ""
        raise BadInputError(f"survey folder {survey_dir} {state}{given}")
    return survey_dir


def write_survey_report(survey_dir, path=None, *, study=None, title=None,
                        max_gallery_views=None, viewers=True):
    """Write one self-contained HTML report of a survey folder (and its observer study).

    Sections: summary (views processed and failed, key metrics with their standard
    uncertainties), the paper's Figures 1, 2 and 4 for this data (each replaced by a note
    saying why when the data do not allow it) and a pointer to Figure 3, a per-view gallery
    (false colour, glare sources, contrast map), failures, study statistics (Pearson r with
    its interval and Chaddock label, Spearman, Kendall, best N, jitter, bootstrap,
    leave-one-out) and provenance.

    Parameters
    ----------
    survey_dir : path-like
        Output folder of :func:`lsadphoto.survey.run_survey` (``metrics.csv``,
        ``failures.log``, ``views/<id>/``, optionally ``ratings.csv``). Missing pieces are
        reported, not raised.
    path : path-like, optional
        HTML file to write (atomically); default ``survey_dir/report.html``.
    study : StudyResult or dict, optional
        Result of :func:`lsadphoto.study.run_study` or its ``to_dict()``: Figures 1–2 and
        the statistics come from it. Without one, :func:`~lsadphoto.study.run_study` is run
        here on the folder's ``ratings.csv`` and ``metrics.csv`` (without the jitter and
        bootstrap checks); the report never computes a statistic itself.
    title : str, optional
        Heading (default: "Survey report — <folder name>").
    max_gallery_views : int, optional
        Show only the first views in the gallery (images are embedded, so a survey of
        hundreds of views makes a large file); default all.
    viewers : bool
        Embed the interactive luminance viewer (:mod:`lsadphoto.viewer`) of every shown
        view in place of its false-colour picture: its map losslessly, with the model
        beside it where the survey rendered one and the score's glare sources (about the
        size of the view's EXR file per view).

    Returns
    -------
    Path
        The report written.

    References
    ----------
    Budak, V. P. et al. (2020), GraphiCon 2020, CEUR Vol-2744 short35, Figures 1–4.
    """
    survey_dir = check_survey_folder(survey_dir)
    path = Path(path) if path is not None else survey_dir / "report.html"
    if max_gallery_views is not None and (isinstance(max_gallery_views, bool)
                                          or int(max_gallery_views) != max_gallery_views
                                          or max_gallery_views < 0):
        from ..errors import BadInputError

        raise BadInputError(f"max_gallery_views must be a non-negative integer or None, got "
                            f"{max_gallery_views!r}")
    survey = _Survey(survey_dir)
    study_dict, why_no_study, computed_here = _survey_study(survey, study)
    title = title or f"Survey report — {survey_dir.resolve().name}"
    generated = _now()
    extra = {"generated": generated, "survey folder": str(survey_dir.resolve()),
             "metrics.csv sha256": survey.metrics_sha256 or "—"}
    sections = [_summary_section(survey, study_dict),
                _figures_section(survey, study_dict, why_no_study),
                _gallery_section(survey, max_gallery_views, viewers),
                _failures_section(survey),
                _study_section(study_dict, why_no_study, computed_here),
                _provenance_section(survey, study_dict, extra)]
    nav = [("summary", "Summary"), ("figures", "Figures"), ("gallery", "Views"),
           ("failures", "Failures"), ("study", "Study statistics"),
           ("provenance", "Provenance")]
    subtitle = (f"{len(survey.rows)} view(s) processed, {len(survey.failures)} failed · "
                f"generated {generated} by lsadphoto {__version__}")
    atomic_text(path, _document(title, subtitle, sections, nav))
    return path


def _headline():
    """The headline metrics of the summary tables (the registry's, imported on first use)."""
    from ..metrics.registry import HEADLINE

    return HEADLINE


def _label_unit(key):
    """Label and unit of a metric from the registry (the key itself if it is not listed)."""
    from ..metrics.registry import METRICS

    entry = METRICS.get(key)
    return (entry.label, entry.unit) if entry is not None else (key, "")


def _metric_label(key):
    label, unit = _label_unit(key)
    return f"{label} [{unit}]" if unit else label


def _ratio_rows(entries, describe):
    rows = []
    for entry in entries:
        rows.append((describe(entry), _fmt(entry.get("n_pixels")),
                     _fmt(entry.get("solid_angle"), 4), _fmt(entry.get("mean_ratio"), 4),
                     _fmt(entry.get("median_ratio"), 4), _fmt(entry.get("p05_ratio"), 4),
                     _fmt(entry.get("p95_ratio"), 4),
                     _fmt_percent(entry.get("rms_relative_error")),
                     _fmt_percent(entry.get("within_10_percent"))))
    return rows


def _fmt_percent(value):
    v = _number(value)
    return "—" if v is None else f"{100 * v:.1f} %"


_RATIO_HEADERS = ("pixels", "solid angle [sr]", "mean ratio (geometric)", "median ratio",
                  "5 % ratio", "95 % ratio", "RMS relative error", "within ±10 %")


def _comparison_images(ratio, photo, model, *, false_colour=True):
    """PNG bytes of (caption, png or None, why) for the ratio map and both false-colour maps
    (``false_colour=False``: the ratio map alone)."""
    from ..io.falsecolour import false_colour_range, write_false_colour_png
    from .figures import write_ratio_png

    images = []
    with tempfile.TemporaryDirectory(prefix="lsadphoto-report-") as folder:
        folder = Path(folder)

        def render(caption, writer, *args, **kwargs):
            target = folder / f"{len(images)}.png"
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    writer(*args, target, **kwargs)
                images.append((caption, target.read_bytes(), None))
            except Exception as error:  # noqa: BLE001 — shown as a note in the report
                reason = f"could not be drawn ({type(error).__name__}: {error})"
                images.append((caption, None, reason))

        if ratio is not None:
            render("luminance ratio model / photo (grey: left out)", write_ratio_png, ratio)
        else:
            images.append(("luminance ratio model / photo", None,
                           "no ratio map: pass the Comparison object, or both photo and model"))
        maps = [(name, m) for name, m in (("photo", photo), ("model", model)) if m is not None]
        if maps and false_colour:
            both = np.concatenate([np.asarray(m.luminance, dtype=np.float64).ravel()
                                   for _, m in maps])
            common = false_colour_range(both)  # one legend, so the two maps can be compared
            for name, lmap in maps:
                render(f"{name}: false colour luminance (common scale)",
                       write_false_colour_png, lmap, luminance_range=common,
                       title=f"{name}: luminance")
        for name, m in (("photo", photo), ("model", model)):
            if m is None and false_colour:
                images.append((f"{name}: false colour luminance", None,
                               f"no {name} luminance map was given"))
    return images


def _comparison_viewer(comparison, photo, model):
    """The viewer of photo and model with their scores' overlays where the comparison
    carries them (a :class:`~lsadphoto.compare.Comparison`), or (None, why)."""
    from ..viewer import report_viewer

    scores = tuple(getattr(comparison, "scores", ()) or (None, None))
    return report_viewer(photo, second=model, score=scores[0], second_score=scores[1],
                         title="photo and model")


def write_comparison_report(comparison, path, *, photo=None, model=None, title=None):
    """Write one self-contained HTML report of a model-vs-photo comparison.

    Sections: summary, metric agreement (photo, model, difference ± combined standard
    uncertainty, agreement within 2u), ratio statistics over the field, per σ ring and per
    image block, the interactive viewer of both maps (:mod:`lsadphoto.viewer`; where it
    cannot be made, both false-colour maps on one luminance scale) with the ratio map, and
    provenance.

    Parameters
    ----------
    comparison : Comparison or dict
        Result of :func:`lsadphoto.compare.compare_maps` or its ``to_dict()``.
    path : path-like
        HTML file to write (atomically).
    photo, model : LuminanceMap, optional
        The two maps, for the false-colour images (and the ratio map when ``comparison``
        is a dict, which does not carry it).
    title : str, optional
        Heading (default "Model against photo").

    Returns
    -------
    Path

    References
    ----------
    JCGM 100:2008 (GUM) §5.1.2, §7.2.2.
    """
    if hasattr(comparison, "to_dict"):
        record, ratio = comparison.to_dict(), getattr(comparison, "ratio", None)
    elif isinstance(comparison, dict):
        record, ratio = comparison, None
    else:
        raise TypeError(f"comparison must be a Comparison or its to_dict(), got "
                        f"{type(comparison).__name__}")
    settings = record.get("settings") or {}
    if ratio is None and photo is not None and model is not None:
        p = np.asarray(photo.luminance, dtype=np.float64)
        m = np.asarray(model.luminance, dtype=np.float64)
        if p.shape == m.shape:
            floor = _number(settings.get("floor_luminance")) or 0.0
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where((p > floor) & (m > floor), m / p, np.nan)
    path = Path(path)
    title = title or "Model against photo"
    generated = _now()
    metrics = record.get("metrics") or {}
    field = record.get("field") or {}
    uncertainty = record.get("uncertainty") or {}

    compared = [v for v in metrics.values() if v.get("agree_within_2u") is not None]
    agreeing = sum(1 for v in compared if v["agree_within_2u"])
    cards = [("median ratio model/photo", _fmt(field.get("median_ratio"), 4)),
             ("RMS relative error", _fmt_percent(field.get("rms_relative_error"))),
             ("field within ±10 %", _fmt_percent(field.get("within_10_percent"))),
             ("metrics agreeing within 2u", f"{agreeing} of {len(compared)}")]
    summary = [_Html('<div class="cards">' + "".join(
        f'<div class="card"><b>{_e(v)}</b>{_e(t)}</div>' for t, v in cards) + "</div>"),
        _tag("p", "Relative standard uncertainty of the scale: photo calibration "
                  f"{_fmt_percent(uncertainty.get('photo_calibration_relative'))}, model "
                  f"Monte Carlo {_fmt_percent(uncertainty.get('model_monte_carlo_relative'))}.")]

    rows = []
    for key, entry in metrics.items():
        flag = entry.get("agree_within_2u")
        cell = (_tag("span", "agree", cls="ok") if flag is True else
                _tag("span", "differ", cls="bad") if flag is False else "—")
        u = entry.get("combined_uncertainty")
        rows.append((_metric_label(key),
                     _fmt_pm(entry.get("photo"), entry.get("photo_uncertainty")),
                     _fmt_pm(entry.get("model"), entry.get("model_uncertainty")),
                     _fmt_pm(entry.get("difference"), u), cell))
    agreement = (_table(("metric", "photo ± u", "model ± u",
                         "difference model − photo ± combined u", "within 2u"), rows,
                        numeric={1, 2, 3})
                 if rows else _unavailable("The metric table", "the comparison has no metrics"))

    regions = record.get("regions") or {}
    ratio_parts = [_tag("h3", "Whole field (pixels in front of the observer, both maps above "
                              f"{_fmt(settings.get('floor_luminance'))} cd/m²)"),
                   _table(("region",) + _RATIO_HEADERS,
                          _ratio_rows([field], lambda e: "field") if field else [],
                          numeric=set(range(1, 9)))]
    rings = regions.get("rings") or []
    ratio_parts.append(_tag("h3", "Rings of angle σ from the line of sight"))
    ratio_parts.append(_table(("σ [deg]",) + _RATIO_HEADERS, _ratio_rows(
        rings, lambda e: "–".join(_fmt(v) for v in e.get("sigma_deg", []))),
        numeric=set(range(1, 9))) if rings else _unavailable("Ring statistics", "none given"))
    blocks = regions.get("blocks") or []
    ratio_parts.append(_tag("h3", "Image blocks (rows, columns)"))
    ratio_parts.append(_table(("block",) + _RATIO_HEADERS, _ratio_rows(
        blocks, lambda e: "rows {}–{}, cols {}–{}".format(*(list(e.get("rows") or ["?", "?"])
                                                            + list(e.get("cols") or ["?", "?"])))),
        numeric=set(range(1, 9))) if blocks else _unavailable("Block statistics", "none given"))

    # The interactive viewer of both maps (side by side, one probe, their ratio) in place of
    # the two false-colour pictures, where both maps are given.
    viewer, why = (None, "both maps are needed") if photo is None or model is None else \
        _comparison_viewer(comparison, photo, model)
    images = []
    for caption, png, why_not in _comparison_images(ratio, photo, model,
                                                    false_colour=viewer is None):
        images.append(_figure_html(png, caption) if png is not None
                      else _Html("<figure>" + _unavailable(caption, why_not) + "</figure>"))
    maps_parts = [_Html('<div class="triple">' + "".join(images) + "</div>")]
    if viewer is not None:
        from ..viewer import viewer_assets

        maps_parts = [_Html(viewer_assets()), _Html(viewer)] + maps_parts
    elif photo is not None and model is not None:
        maps_parts.insert(0, _note(f"no interactive viewer: {why}"))

    provenance = [_tag("h3", "This report"),
                  _kv_table({"generated": generated, **_versions()}),
                  _tag("h3", "Comparison settings"), _kv_table(settings)]
    for name, lmap in (("photo", photo), ("model", model)):
        if lmap is not None:
            facts = {"shape": list(lmap.luminance.shape), "calibrated": lmap.calibrated,
                     "calibration_factor": lmap.calibration_factor,
                     "calibration_uncertainty": lmap.calibration_uncertainty,
                     "projection": type(lmap.projection).__name__
                     if lmap.projection is not None else None,
                     "provenance": lmap.provenance}
            provenance.append(_Html(f"<details><summary>{_e(name)} map</summary>"
                                    f"{_kv_table(facts)}</details>"))
    sections = [_section("summary", "Summary", *summary),
                _section("metrics", "Metric agreement", agreement),
                _section("maps", "Maps", *maps_parts),
                _section("ratios", "Ratio statistics (model / photo, solid-angle weighted)",
                         *ratio_parts),
                _section("provenance", "Provenance", *provenance)]
    nav = [("summary", "Summary"), ("metrics", "Metric agreement"), ("maps", "Maps"),
           ("ratios", "Ratio statistics"), ("provenance", "Provenance")]
    atomic_text(path, _document(title, f"generated {generated} by lsadphoto {__version__}",
                                sections, nav))
    return path
