"""Batch processing of a whole survey: many views → maps, scores and one metrics table.

A survey is described by a TOML manifest (schema ``lsadphoto.survey/1``, documented in
``docs/user-guide-survey.md``); paths in it are relative to the manifest's folder::

    schema = "lsadphoto.survey/1"
    name = "Office block B, 2026-11"           # optional, free text
    profile = "camera.toml"                    # default camera profile of every view
    demosaic = "superpixel"                    # default; see lsadphoto.raw.DEMOSAIC_METHODS
    colour_method = "auto"
    acceptance_angle_deg = 1.0                 # spot meter, full cone [deg] (LS-100: 1°)

    [score]                                    # options of lsadphoto.metrics.score_map
    n_thresholds = 50                          # N of the Q criterion
    size_arcmin = 10                           # α [arcmin]

    [[view]]
    id = "b2-corridor"                         # unique; letters, digits, '.', '_', '-'
    raw = ["b2/c_1.dng", "b2/c_2.dng"]         # one file, or a list = exposure bracket
    spots = "b2/spots.csv"                     # CSV row,col,cd_m2 — or a list of tables
    line_of_sight = [0.0, 0.1, 1.0]            # camera frame (x right, y down, z forward)
    ratings = [4, 5, 3]                        # observers' ratings, or a CSV path
    profile = "other-camera.toml"              # override
    [view.score]                               # per-view score options (override)
    source_threshold = 1500
    [view.model]                               # scene model of the same view: rendered
    scene = "models/b2.toml"                   # through the photo's camera and compared
    position = [1.2, 3.4, 1.6]
    direction = [1.0, 0.0, -0.05]

:func:`run_survey` processes every view — luminance map (OpenEXR, Radiance HDR, false
colour), scores (:func:`~lsadphoto.metrics.score.score_map` with the Q(N) sweep N = 1…100),
glare-source and contrast maps, a per-view JSON record — in parallel: worker processes
started with the ``spawn`` context on this machine (fork + OpenMP deadlocks), or the
workers of a Dask cluster. Every file is written atomically and a view's "done" marker is
written last, so a killed run loses no finished view and a rerun skips what is done. A
view that fails is reported with a one-line reason and the others go on. At the end of
every run the metrics table (``metrics.csv``, ``metrics.parquet``) is rebuilt from the
done markers of all the manifest's views.

References
----------
Python ``concurrent.futures.ProcessPoolExecutor`` and ``multiprocessing`` start methods;
Dask.distributed ``Client``. rawpy issue #265 (fork + OpenMP deadlock).
"""

import contextlib
import csv
import dataclasses
import hashlib
import io
import json
import math
import multiprocessing
import os
import re
import sys
import time
import tomllib
import uuid
import warnings
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._validation import check_choice, check_file
from ._provenance import file_record, timestamp
from ._version import __version__
from .calibrate.spot import SpotReading
from .errors import BadInputError, LsadError

__all__ = ["SCHEMA", "Manifest", "SurveyResult", "SurveyView", "load_manifest", "run_survey"]

SCHEMA = "lsadphoto.survey/1"
VIEW_RECORD_SCHEMA = "lsadphoto.survey-view/1"

#: N values of the Q(N) sweep in the metrics table (columns ``q_n1`` … ``q_n100``).
SWEEP = tuple(range(1, 101))

#: A view id becomes a folder and file names: no separators, no leading dot.
_ID_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")

_TOP_KEYS = ("schema", "name", "description", "profile", "demosaic", "colour_method",
             "acceptance_angle_deg", "score", "view")
_VIEW_KEYS = ("id", "raw", "profile", "spots", "line_of_sight", "ratings", "model", "score",
              "note")
_SPOT_KEYS = ("row", "col", "cd_m2")

#: Options of :func:`~lsadphoto.metrics.score.score_map` a manifest may set, by kind.
_SCORE_VECTORS = ("line_of_sight", "up", "task_direction")
_SCORE_TEXT = ("source_method", "background_method", "position_index_method", "q_threshold",
               "q_cutoff", "dgp_coefficients")
_SCORE_NUMBERS = ("source_threshold", "task_opening_deg", "search_angle", "n_thresholds",
                  "size_arcmin", "vcp_constant")
_SCORE_INTEGERS = ("q_weight_exponent", "guth_field")
_SCORE_KEYS = _SCORE_VECTORS + _SCORE_TEXT + _SCORE_NUMBERS + _SCORE_INTEGERS + ("peak_luminance",)

#: Metrics of a Score without an uncertainty (counts and geometry, not luminance scale).
_NO_UNCERTAINTY = ("n_sources", "source_solid_angle")

#: Keys of a view's ``[view.model]`` table.
_MODEL_KEYS = ("scene", "position", "direction", "up", "samples", "nodes_per_pixel", "seed")
#: Metrics of the model map copied into the table (``model_<name>``).
_MODEL_METRICS = ("ugr_pixel", "ugr_grouped", "q", "dgp", "vertical_illuminance",
                  "background_luminance", "mean_luminance")

#: A Dask scheduler address: ``tcp://host:port``, ``tls://…``, ``ws(s)://…``, ``ucx://…``,
#: or ``host:port`` (tcp).
_DASK_ADDRESS = re.compile(r"((tcp|tls|ws|wss|ucx)://)?[^\s/:]+(:\d+)?|(tcp|tls)://\[[0-9a-fA-F:]+\](:\d+)?")


# --------------------------------------------------------------------------- manifest


@dataclass
class SurveyView:
    """One viewpoint of a survey (paths resolved against the manifest's folder).

    Attributes
    ----------
    id : str
        Unique name, used for the output folder and file names.
    raw : tuple of Path
        RAW file(s) of the view; several form an exposure bracket.
    raw_as_written : tuple of str
        The same paths as the manifest gives them (for the table's provenance).
    profile : Path or None
        Camera profile (TOML); None: the survey's, or none.
    spots : tuple of SpotReading
        Spot-meter readings [cd·m⁻²] at full-resolution sensor pixels.
    line_of_sight : tuple of float or None
        Observer's line of sight in the camera frame (x right, y down, z forward) [–].
    ratings : tuple of (str, float) or None
        ``(observer, rating)`` pairs of an observer study.
    model : dict or None
        The model of this view for the model comparison (``scene`` resolved to a path).
    score : dict
        Options of :func:`~lsadphoto.metrics.score.score_map` for this view only.
    note : str or None
        Free text kept in the view's JSON record.
    """

    id: str
    raw: tuple
    raw_as_written: tuple
    profile: Path | None = None
    spots: tuple = ()
    line_of_sight: tuple | None = None
    ratings: tuple | None = None
    model: dict | None = None
    score: dict = field(default_factory=dict)
    note: str | None = None


@dataclass
class Manifest:
    """A survey manifest read by :func:`load_manifest`.

    Attributes
    ----------
    path : Path
        The manifest file.
    views : list of SurveyView
    profile : Path or None
        Default camera profile.
    demosaic, colour_method : str
        Options of :func:`~lsadphoto.luminance.luminance_from_raw` for every view.
    acceptance_angle : float
        Spot meter's full acceptance angle [rad].
    score : dict
        Survey-wide options of :func:`~lsadphoto.metrics.score.score_map`.
    name, description : str or None
    """

    path: Path
    views: list
    profile: Path | None = None
    demosaic: str = "superpixel"
    colour_method: str = "auto"
    acceptance_angle: float = math.radians(1.0)
    score: dict = field(default_factory=dict)
    name: str | None = None
    description: str | None = None


class _Where:
    """Builds one-line errors naming the manifest, the view and the field."""

    def __init__(self, path, view=None):
        self.path = path
        self.view = view

    def error(self, field_name, message):
        place = f"{self.path}: "
        if self.view is not None:
            place += f"view {self.view}: "
        return BadInputError(f"{place}{field_name}: {message}")


def _unknown_keys(table, valid, where, field_name):
    unknown = sorted(set(table) - set(valid))
    if unknown:
        raise where.error(field_name, f"unknown key(s) {', '.join(map(repr, unknown))}; "
                                      f"valid: {', '.join(valid)}")


def _number(value, where, field_name, *, positive=False, minimum=None):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise where.error(field_name, f"must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise where.error(field_name, f"must be positive, got {value!r}")
    if minimum is not None and value < minimum:
        raise where.error(field_name, f"must be at least {minimum}, got {value!r}")
    return float(value)


def _text(value, where, field_name):
    if not isinstance(value, str) or not value.strip():
        raise where.error(field_name, f"must be a non-empty string, got {value!r}")
    return value


def _vector(value, where, field_name):
    if not isinstance(value, list) or len(value) != 3:
        raise where.error(field_name, f"must be three numbers [x, y, z], got {value!r}")
    vector = tuple(_number(v, where, field_name) for v in value)
    if not any(vector):
        raise where.error(field_name, "must not be the zero vector")
    return vector


def _file(base, value, where, field_name, what):
    text = _text(value, where, field_name)
    try:
        return check_file(base / text, what).resolve()
    except BadInputError as exc:
        raise where.error(field_name, str(exc)) from None


def _read_csv(path, where, field_name, required):
    """Rows of a CSV file with a header holding at least ``required`` columns."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.DictReader(fh)
            columns = [c.strip() for c in reader.fieldnames or []]
            rows = [{(k or "").strip(): (v or "").strip() for k, v in r.items()} for r in reader]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise where.error(field_name, f"{path}: not a readable CSV file ({exc})") from None
    missing = [c for c in required if c not in columns]
    if missing:
        raise where.error(field_name, f"{path}: needs the column(s) {', '.join(missing)} "
                                      f"(has {', '.join(columns) or 'none'})")
    if not rows:
        raise where.error(field_name, f"{path}: has no data rows")
    return rows


def _csv_number(text, path, line, column, where, field_name):
    try:
        value = float(text)
    except ValueError:
        raise where.error(field_name, f"{path} line {line}: {column} {text!r} is not a number") from None
    if not math.isfinite(value):
        raise where.error(field_name, f"{path} line {line}: {column} {text!r} is not finite")
    return value


def _spots(value, base, where, acceptance_angle):
    if isinstance(value, str):
        path = _file(base, value, where, "spots", "spot readings file")
        rows = _read_csv(path, where, "spots", _SPOT_KEYS)
        readings = [
            tuple(_csv_number(r[k], path, i, k, where, "spots") for k in _SPOT_KEYS)
            for i, r in enumerate(rows, start=2)
        ]
        places = [f"{path} line {i}" for i in range(2, len(rows) + 2)]
    elif isinstance(value, list) and value:
        readings, places = [], []
        for i, item in enumerate(value, start=1):
            name = f"spots[{i}]"
            if not isinstance(item, dict):
                raise where.error(name, f"must be a table {{row, col, cd_m2}}, got {item!r}")
            _unknown_keys(item, _SPOT_KEYS, where, name)
            missing = [k for k in _SPOT_KEYS if k not in item]
            if missing:
                raise where.error(name, f"lacks {', '.join(missing)}")
            readings.append(tuple(_number(item[k], where, f"{name}.{k}") for k in _SPOT_KEYS))
            places.append(name)
    else:
        raise where.error("spots", f"must be a CSV path or a non-empty list of {{row, col, cd_m2}}, "
                                   f"got {value!r}")
    spots = []
    for (row, col, luminance), place in zip(readings, places):
        if row < 0 or col < 0:
            raise where.error("spots", f"{place}: row and col must not be negative")
        if luminance <= 0:
            raise where.error("spots", f"{place}: cd_m2 must be positive, got {luminance:g}")
        spots.append(SpotReading(row, col, luminance, acceptance_angle))
    return tuple(spots)


def _ratings(value, base, where, view_id):
    if isinstance(value, str):
        path = _file(base, value, where, "ratings", "ratings file")
        rows = _read_csv(path, where, "ratings", ("rating",))
        numbered = list(enumerate(rows, start=2))
        if "scene" in rows[0]:
            # One shared file for the whole survey: this view's rows only.
            numbered = [(i, r) for i, r in numbered if r["scene"] == view_id]
            if not numbered:
                raise where.error("ratings", f"{path}: no row has scene {view_id!r}")
        ratings = []
        for n, (line, r) in enumerate(numbered, start=1):
            observer = r.get("observer") or str(n)
            ratings.append((observer, _csv_number(r["rating"], path, line, "rating", where, "ratings")))
        observers = [o for o, _ in ratings]
        if len(set(observers)) != len(observers):
            raise where.error("ratings", f"{path}: an observer rates the view more than once")
        return tuple(ratings)
    if isinstance(value, list) and value:
        return tuple((str(i), _number(v, where, f"ratings[{i}]")) for i, v in enumerate(value, start=1))
    raise where.error("ratings", f"must be a CSV path or a non-empty list of numbers, got {value!r}")


def _model(value, base, where):
    if not isinstance(value, dict):
        raise where.error("model", f"must be a table {{scene = ..., position = [...], ...}}, got {value!r}")
    if "scene" not in value:
        raise where.error("model", "lacks scene (the scene model file)")
    unknown = sorted(set(value) - set(_MODEL_KEYS))
    if unknown:
        raise where.error("model", f"unknown key(s) {', '.join(unknown)}; valid: {', '.join(_MODEL_KEYS)}")
    for key in ("position", "direction"):
        if key not in value:
            raise where.error("model", f"lacks {key} (the camera's {'eye position [m]' if key == 'position' else 'optical axis in the scene'})")
    model = dict(value)
    model["scene"] = str(_file(base, value["scene"], where, "model.scene", "scene model"))
    for key in ("position", "direction", "up"):
        if key in value:
            model[key] = list(_vector(value[key], where, f"model.{key}"))
    for key, default in (("samples", 20000), ("nodes_per_pixel", 16), ("seed", 0)):
        number = value.get(key, default)
        if not isinstance(number, int) or isinstance(number, bool) or number < (0 if key == "seed" else 1):
            raise where.error("model", f"{key} must be a {'non-negative' if key == 'seed' else 'positive'} integer, got {number!r}")
        model[key] = number
    return model


def _score_options(table, where, field_name="score"):
    """Check a table of score_map options (names and kinds; values are checked by score_map)."""
    if not isinstance(table, dict):
        raise where.error(field_name, f"must be a table of score options, got {table!r}")
    _unknown_keys(table, _SCORE_KEYS, where, field_name)
    options = {}
    for key, value in table.items():
        name = f"{field_name}.{key}"
        if key in _SCORE_VECTORS:
            options[key] = _vector(value, where, name)
        elif key in _SCORE_TEXT:
            options[key] = _text(value, where, name)
        elif key in _SCORE_NUMBERS:
            options[key] = _number(value, where, name)
        elif key in _SCORE_INTEGERS:
            if isinstance(value, bool) or not isinstance(value, int):
                raise where.error(name, f"must be an integer, got {value!r}")
            options[key] = value
        elif key == "peak_luminance":
            # TOML has no null: false switches peak extraction off.
            options[key] = None if value is False else _number(value, where, name, positive=True)
    return options


def load_manifest(path):
    r"""Read and check a survey manifest (TOML, schema ``lsadphoto.survey/1``).

    Every problem — a missing field, an unknown key, a missing file, a duplicate or unsafe
    view id, an unreadable camera profile — is one :class:`~lsadphoto.errors.BadInputError`
    naming the manifest, the view and the field.

    Parameters
    ----------
    path : path-like
        The manifest file; relative paths inside it are taken from its folder.

    Returns
    -------
    Manifest

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "a.dng").write_bytes(b"RAW data")
    >>> _ = (folder / "survey.toml").write_text(
    ...     '[[view]]\nid = "hall"\nraw = "a.dng"\nspots = [{row = 10, col = 20, cd_m2 = 85}]\n')
    >>> view = load_manifest(folder / "survey.toml").views[0]
    >>> view.id, view.raw[0].name, view.spots[0].luminance
    ('hall', 'a.dng', 85.0)
    >>> _ = (folder / "survey.toml").write_text('[[view]]\nid = "hall"\nraws = "a.dng"\n')
    >>> load_manifest(folder / "survey.toml")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    lsadphoto.errors.BadInputError: .../survey.toml: view 'hall': view: unknown key(s) 'raws'; valid: id, raw, ...
    """
    from .calibrate.profile import load_profile
    from .raw.colour import COLOUR_METHODS
    from .raw.decode import DEMOSAIC_METHODS

    path = check_file(path, "survey manifest").resolve()
    where = _Where(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise BadInputError(f"{path}: not a valid TOML survey manifest ({exc})") from None
    base = path.parent
    _unknown_keys(data, _TOP_KEYS, where, "manifest")
    schema = data.get("schema", SCHEMA)
    if schema != SCHEMA:
        raise where.error("schema", f"unsupported {schema!r} (expected {SCHEMA!r})")
    profiles = {}

    def profile(value, w):
        file = _file(base, value, w, "profile", "camera profile")
        if file not in profiles:
            try:
                profiles[file] = load_profile(file)
            except BadInputError as exc:
                raise w.error("profile", str(exc)) from None
        return file

    choices = {}
    for key, name, valid in (("demosaic", "demosaic method", DEMOSAIC_METHODS),
                             ("colour_method", "colour method", COLOUR_METHODS)):
        try:
            choices[key] = check_choice(data.get(key, valid[0]), name, valid)
        except BadInputError as exc:
            raise where.error(key, str(exc)) from None
    angle = _number(data.get("acceptance_angle_deg", 1.0), where, "acceptance_angle_deg", positive=True)
    acceptance_angle = math.radians(angle)
    manifest = Manifest(
        path=path,
        views=[],
        profile=profile(data["profile"], where) if "profile" in data else None,
        demosaic=choices["demosaic"],
        colour_method=choices["colour_method"],
        acceptance_angle=acceptance_angle,
        score=_score_options(data.get("score", {}), where),
        name=_text(data["name"], where, "name") if "name" in data else None,
        description=_text(data["description"], where, "description") if "description" in data else None,
    )
    entries = data.get("view")
    if not isinstance(entries, list) or not entries:
        raise where.error("view", "the manifest has no [[view]] entries")
    seen = {}
    for number, entry in enumerate(entries, start=1):
        w = _Where(path, f"#{number}")
        if not isinstance(entry, dict):
            raise w.error("view", "must be a table")
        if "id" not in entry:
            raise w.error("id", "missing (every view needs a unique id)")
        view_id = entry["id"]
        if not isinstance(view_id, str) or not _ID_PATTERN.fullmatch(view_id):
            raise w.error("id", f"{view_id!r} is not safe as a file name: use 1–100 letters, "
                                "digits, '.', '_' or '-', starting with a letter or digit")
        w = _Where(path, repr(view_id))
        # Compared case-insensitively: on macOS and Windows "A" and "a" are one folder.
        if view_id.lower() in seen:
            raise w.error("id", f"duplicate id (view #{seen[view_id.lower()]} has it too)")
        seen[view_id.lower()] = number
        _unknown_keys(entry, _VIEW_KEYS, w, "view")
        if "raw" not in entry:
            raise w.error("raw", "missing (a RAW file, or a list of them for a bracket)")
        raw = entry["raw"]
        raw_list = [raw] if isinstance(raw, str) else raw
        if not isinstance(raw_list, list) or not raw_list:
            raise w.error("raw", f"must be a path or a non-empty list of paths, got {raw!r}")
        raw_files = tuple(_file(base, r, w, "raw", "RAW file") for r in raw_list)
        if len(set(raw_files)) != len(raw_files):
            raise w.error("raw", "lists the same file twice")
        line_of_sight = None
        if "line_of_sight" in entry:
            line_of_sight = _vector(entry["line_of_sight"], w, "line_of_sight")
        manifest.views.append(SurveyView(
            id=view_id,
            raw=raw_files,
            raw_as_written=tuple(raw_list),
            profile=profile(entry["profile"], w) if "profile" in entry else None,
            spots=_spots(entry["spots"], base, w, acceptance_angle) if "spots" in entry else (),
            line_of_sight=line_of_sight,
            ratings=_ratings(entry["ratings"], base, w, view_id) if "ratings" in entry else None,
            model=_model(entry["model"], base, w) if "model" in entry else None,
            score=_score_options(entry.get("score", {}), w),
            note=_text(entry["note"], w, "note") if "note" in entry else None,
        ))
    return manifest


# --------------------------------------------------------------------------- one view


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)  # paths, and anything else a record may carry


def _clean(value):
    """A table cell: finite float, int, bool, str, or None."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    value = float(value)
    return value if math.isfinite(value) else None


def _outputs(view_dir, view_id, *, with_model=False):
    """Output paths of one view, by kind (the done marker last)."""
    names = {"exr": f"{view_id}.exr", "hdr": f"{view_id}.hdr",
             "falsecolour": f"{view_id}-falsecolour.png", "sources": f"{view_id}-sources.png",
             "contrast": f"{view_id}-contrast.png", "score": f"{view_id}-score.json",
             "done": f"{view_id}-done.json"}
    if with_model:
        names = {**{k: v for k, v in names.items() if k != "done"},
                 "model_exr": f"{view_id}-model.exr", "model_ratio": f"{view_id}-model-ratio.png",
                 "model_json": f"{view_id}-model-comparison.json",
                 "model_report": f"{view_id}-model-comparison.html", "done": names["done"]}
    return {kind: view_dir / name for kind, name in names.items()}


def _remove_stale_temporaries(view_dir):
    """Temporary files of atomic writes that a killed run left behind (``.name.XXXX.tmp.ext``)."""
    if view_dir.is_dir():
        for temp in view_dir.glob(".*.tmp*"):
            with contextlib.suppress(FileNotFoundError):
                temp.unlink()


def _row(task, summary, scalars, record, warning_lines):
    """One line of the metrics table from a view's score record and luminance summary.

    ``scalars`` are the names of the scalar metrics (``Score.values``), in their order.
    """
    row = {"view": task["view"]}
    for key in scalars:
        row[key] = _clean(record[key])
    for key in scalars:
        if key not in _NO_UNCERTAINTY:
            row[f"{key}_u"] = _clean(record["uncertainty"].get(key))
    sweep = record.get("q_sweep") or {"n": [], "q": []}
    for n, q in zip(sweep["n"], sweep["q"]):
        row[f"q_n{int(n)}"] = _clean(q)
    ratings = task["ratings"]
    row["rating_mean"] = float(np.mean([r for _, r in ratings])) if ratings else None
    row["rating_n"] = len(ratings) if ratings else None
    comparison = record.get("model_comparison")
    if comparison is not None:
        row["model_ratio_median"] = _clean(comparison["field"]["median_ratio"])
        row["model_rms_relative_error"] = _clean(comparison["field"]["rms_relative_error"])
        row["model_mc_uncertainty"] = _clean(comparison["uncertainty"]["model_monte_carlo_relative"])
        for key in _MODEL_METRICS:
            row[f"model_{key}"] = _clean(comparison["metrics"].get(key, {}).get("model"))
    los = record["settings"]["line_of_sight"]
    row.update({
        "line_of_sight": ",".join(f"{float(v):.6g}" for v in los),
        "lsadphoto_version": __version__,
        "raw_files": ";".join(task["raw_as_written"]),
        "profile": summary["profile"],
        "calibration_method": summary["calibration_method"],
        "calibration_factor": _clean(summary["calibration_factor"]),
        "calibration_uncertainty": _clean(summary["calibration_uncertainty"]),
        "calibrated": bool(summary["calibrated"]),
        "saturated_fraction": _clean(summary["saturated_fraction"]),
        "demosaic": summary["demosaic"],
        "notes": " | ".join(record["notes"]) or None,
        "warnings": " | ".join(warning_lines) or None,
        "timestamp": timestamp(),
    })
    return row


def _process_view_outputs(task, caught):
    from .calibrate.profile import load_profile
    from .io import write_exr, write_false_colour_png, write_hdr
    from ._atomic import atomic_text
    from .luminance import luminance_from_raw
    from .metrics.score import score_map
    from .report.figures import write_contrast_png, write_glare_source_png

    outputs = {k: Path(v) for k, v in task["outputs"].items()}
    view_dir = outputs["done"].parent
    view_dir.mkdir(parents=True, exist_ok=True)
    # Outputs are about to change: the view is not done until the new marker is written.
    with contextlib.suppress(FileNotFoundError):
        outputs["done"].unlink()
    _remove_stale_temporaries(view_dir)
    profile = load_profile(task["profile"]) if task["profile"] else None
    result = luminance_from_raw(task["raw"], spots=task["spots"], profile=profile,
                                demosaic=task["demosaic"], colour_method=task["colour_method"])
    lmap = result.map
    options = dict(task["score"])
    if options.get("line_of_sight") is not None:
        # The map carries the view's line of sight into its EXR/HDR metadata.
        lmap = dataclasses.replace(lmap, line_of_sight=np.asarray(options["line_of_sight"]))
    write_exr(lmap, outputs["exr"])
    write_hdr(lmap, outputs["hdr"])
    title = f"{task['view']}: luminance"
    write_false_colour_png(lmap, outputs["falsecolour"], title=title)
    score = score_map(lmap, sweep=SWEEP, **options)
    write_glare_source_png(lmap.luminance, score.source_labels, outputs["sources"])
    write_contrast_png(score.contrast, outputs["contrast"])
    record = score.to_dict()
    record["provenance"]["input"] = [str(p) for p in task["raw"]]
    record["survey"] = {
        "manifest": task["manifest"], "view": task["view"], "raw": list(task["raw_as_written"]),
        "note": task["note"],
        "ratings": None if task["ratings"] is None else
        [{"observer": o, "rating": r} for o, r in task["ratings"]],
        "model": task["model"],
    }
    if task["model"] is not None:
        record["model_comparison"] = _compare_with_model(task, lmap, outputs, options)
    warning_lines = _warning_lines(caught)
    record["warnings"] = warning_lines
    atomic_text(outputs["score"], json.dumps(record, indent=2, default=_json_default))
    row = _row(task, result.summary, list(score.values), record, warning_lines)
    marker = {"schema": VIEW_RECORD_SCHEMA, "view": task["view"], "fingerprint": task["fingerprint"],
              "outputs": {k: v.name for k, v in outputs.items() if k != "done"}, "row": row}
    # Written last: its presence means every other output of the view is complete.
    atomic_text(outputs["done"], json.dumps(marker, indent=1, default=_json_default))
    return row


def _compare_with_model(task, photo, outputs, options):
    """Render the view's scene model through the photo's camera and compare (issue: model vs photo)."""
    from .compare import compare_maps
    from .io import write_exr
    from ._atomic import atomic_text
    from .report import write_comparison_report, write_ratio_png
    from .solver import camera_to_world, load_scene, render, simulate

    spec = task["model"]
    scene = load_scene(spec["scene"])
    store = simulate(scene, samples=spec["samples"], seed=spec["seed"])
    rotation = camera_to_world(spec["direction"], spec.get("up", [0.0, 0.0, 1.0]))
    model = render(store, photo.projection, position=spec["position"], rotation=rotation,
                   nodes_per_pixel=spec["nodes_per_pixel"], seed=spec["seed"])
    if photo.line_of_sight is not None:
        model = dataclasses.replace(model, line_of_sight=photo.line_of_sight)
    write_exr(model, outputs["model_exr"])
    score_options = {k: v for k, v in options.items() if k != "line_of_sight"}
    comparison = compare_maps(photo, model, **score_options)
    write_ratio_png(comparison.ratio, outputs["model_ratio"], title=f"{task['view']}: model / photo")
    record = comparison.to_dict()
    record["model"] = {k: (str(v) if k == "scene" else v) for k, v in spec.items()}
    atomic_text(outputs["model_json"], json.dumps(record, indent=2, default=_json_default))
    write_comparison_report(comparison, outputs["model_report"], photo=photo, model=model,
                            title=f"{task['view']}: model against photo")
    return record


def _warning_lines(caught):
    return list(dict.fromkeys(f"{w.category.__name__}: {w.message}" for w in caught))


def _process_view(task):
    """Process one view in a worker; never raises for a problem of the view itself.

    Returns ``{"view", "ok", "row", "reason", "seconds"}``: ``reason`` is the one-line
    message of an :class:`~lsadphoto.errors.LsadError`, or ``"internal error: Type: msg"``.
    Warnings (saturation, non-uniform spots, …) go into the view's record and table row.
    """
    start = time.perf_counter()
    row, reason = None, None
    # Recording warnings changes process-wide state: safe in worker processes (the default),
    # not in several threads of one process at once.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            row = _process_view_outputs(task, caught)
        except LsadError as exc:
            reason = str(exc)
        except MemoryError:
            reason = "out of memory"
        except Exception as exc:  # noqa: BLE001 — reported, and the survey goes on
            reason = f"internal error: {type(exc).__name__}: {exc}"
    reason = None if reason is None else " ".join(reason.split())  # one line
    return {"view": task["view"], "ok": row is not None, "row": row, "reason": reason,
            "seconds": time.perf_counter() - start}


# --------------------------------------------------------------------------- the run


@dataclass
class SurveyResult:
    """What :func:`run_survey` did.

    Attributes
    ----------
    table : list of dict
        One row per finished view, in manifest order (the rows of ``metrics.csv``).
    failures : list of (str, str)
        ``(view id, one-line reason)`` of the views that failed in this run.
    processed : list of str
        Views processed in this run (finished or failed).
    skipped : list of str
        Views already done by an earlier run with the same inputs.
    outdir : Path
    elapsed : float
        Wall-clock time of the run [s].
    """

    table: list
    failures: list
    processed: list
    skipped: list
    outdir: Path
    elapsed: float = 0.0

    def to_dict(self):
        """JSON-ready summary (the table itself is in ``metrics.csv``)."""
        return {
            "outdir": str(self.outdir),
            "views_finished": len(self.table),
            "views_failed": len(self.failures),
            "processed": list(self.processed),
            "skipped": list(self.skipped),
            "failures": [{"view": v, "reason": r} for v, r in self.failures],
            "elapsed_s": self.elapsed,
            "table": self.table,
        }


def _stat(path):
    """Size [B] and modification time [ns] of a file; None if it has gone (the view fails)."""
    try:
        info = os.stat(path)
    except OSError:
        return None, None
    return info.st_size, info.st_mtime_ns




def _task(manifest, view, outdir, score_options):
    """Everything a worker needs for one view, as plain picklable data."""
    profile = view.profile or manifest.profile
    score = {**manifest.score, **(score_options or {}), **view.score}
    if view.line_of_sight is not None:
        score["line_of_sight"] = view.line_of_sight
    task = {
        "view": view.id,
        "manifest": str(manifest.path),
        "raw": [str(p) for p in view.raw],
        "raw_as_written": list(view.raw_as_written),
        "profile": None if profile is None else str(profile),
        "spots": list(view.spots),
        "demosaic": manifest.demosaic,
        "colour_method": manifest.colour_method,
        "score": score,
        "ratings": None if view.ratings is None else [list(r) for r in view.ratings],
        "model": view.model,
        "note": view.note,
    }
    # Inputs that decide the outputs: a changed file, spot or option redoes the view.
    identity = {k: v for k, v in task.items() if k not in ("manifest",)}
    identity["spots"] = [dataclasses.astuple(s) for s in view.spots]
    identity["raw_stat"] = [(p, *_stat(p)) for p in task["raw"]]
    identity["profile_sha256"] = None if profile is None else file_record(profile)["sha256"]
    text = json.dumps(identity, sort_keys=True, default=_json_default)
    task["fingerprint"] = hashlib.sha256(text.encode("utf-8")).hexdigest()
    task["outputs"] = {k: str(v) for k, v in _outputs(Path(outdir) / "views" / view.id, view.id,
                                                        with_model=view.model is not None).items()}
    return task


def _read_done(task):
    """The done marker's row when the view's outputs are complete and current, else None."""
    outputs = {k: Path(v) for k, v in task["outputs"].items()}
    try:
        marker = json.loads(outputs["done"].read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(marker, dict) or marker.get("fingerprint") != task["fingerprint"]:
        return None
    if not all(p.is_file() for k, p in outputs.items()):
        return None
    return marker.get("row")


def _failure(task, reason):
    return {"view": task["view"], "ok": False, "row": None, "reason": reason, "seconds": None}


def _cpu_count():
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


def _run_serial(tasks, report):
    for task in tasks:
        report(_process_view(task))


#: Thread counts of the numeric libraries in each worker process: one, as Dask's nanny sets
#: them (``distributed.nanny.pre-spawn-environ``). N processes × N threads would oversubscribe
#: the CPUs, and BLAS sums depend on the thread count in their last bits: with the same
#: setting, the local pool and a Dask cluster give bit-identical tables.
WORKER_ENVIRONMENT = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


@contextlib.contextmanager
def _worker_environment():
    """Set :data:`WORKER_ENVIRONMENT` (where the user has not) while workers are spawned."""
    added = {k: v for k, v in WORKER_ENVIRONMENT.items() if k not in os.environ}
    os.environ.update(added)
    try:
        yield
    finally:
        for key in added:
            os.environ.pop(key, None)


def _run_local(tasks, workers, report, *, function=_process_view):
    """Worker processes started with ``spawn``; a view whose worker dies is retried alone."""
    context = multiprocessing.get_context("spawn")
    lost = []
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context)
    try:
        # ProcessPoolExecutor starts its spawn workers in submit(): all of them here.
        with _worker_environment():
            futures = {pool.submit(function, task): task for task in tasks}
        for future in as_completed(futures):
            task = futures[future]
            try:
                report(future.result())
            except BrokenProcessPool:
                lost.append(task)  # this view, or another one running beside it, crashed
            except Exception as exc:  # noqa: BLE001 — e.g. a result that could not be pickled
                report(_failure(task, f"internal error: {type(exc).__name__}: {exc}"))
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    # A crashing worker (native code, out of memory) breaks the whole pool: retry each lost
    # view in a pool of its own, so that only the culprit is reported.
    for task in lost:
        with ProcessPoolExecutor(max_workers=1, mp_context=context) as single:
            try:
                with _worker_environment():
                    future = single.submit(function, task)
                outcome = future.result()
            except BrokenProcessPool:
                outcome = _failure(task, "internal error: the worker process died while processing "
                                         "this view (a crash in native code, or out of memory)")
        report(outcome)


def _run_dask(tasks, report, *, client=None, address=None):
    """The tasks on a Dask cluster: an existing ``client``, or a new one for ``address``."""
    from distributed import Client
    from distributed import as_completed as dask_as_completed

    own = client is None
    if own:
        try:
            client = Client(address, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise BadInputError(f"cannot connect to the Dask scheduler at {address}: "
                                f"{' '.join(str(exc).split())}") from None
    token = uuid.uuid4().hex[:8]
    waiting = {}
    try:
        for task in tasks:
            future = client.submit(_process_view, task, key=f"lsadphoto-survey-{task['view']}-{token}",
                                   pure=False)
            waiting[future.key] = (future, task)
        for future in dask_as_completed([f for f, _ in waiting.values()], loop=client.loop):
            task = waiting.pop(future.key)[1]
            try:
                outcome = future.result()
            except Exception as exc:  # noqa: BLE001 — e.g. KilledWorker after repeated crashes
                outcome = _failure(task, f"internal error: {type(exc).__name__}: "
                                         f"{' '.join(str(exc).split())}")
            future.release()
            report(outcome)
    finally:
        if waiting:  # interrupted: withdraw what has not run yet
            client.cancel([f for f, _ in waiting.values()])
        if own:
            client.close()


def _progress_bar(*, total, initial, enabled):
    """tqdm bar on stderr with the estimated time left; silent unless stderr is a terminal."""
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="view", desc="survey", file=sys.stderr,
                disable=not (enabled and sys.stderr.isatty()), dynamic_ncols=True)


def _write_csv(path, columns, rows):
    from ._atomic import atomic_text

    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow(["" if row.get(c) is None else row.get(c) for c in columns])
    atomic_text(path, buffer.getvalue())


def _write_parquet(path, columns, rows, metadata):
    import pyarrow as pa
    import pyarrow.parquet as pq

    from ._atomic import atomic_path

    arrays = {c: pa.array([row.get(c) for row in rows]) for c in columns}
    if not rows:
        arrays = {c: pa.array([], pa.string()) for c in columns}
    table = pa.table(arrays).replace_schema_metadata(
        {"lsadphoto.survey": json.dumps(metadata, default=_json_default)})
    with atomic_path(path) as temp:
        pq.write_table(table, temp)


def _write_tables(manifest, tasks, failures, outdir):
    """metrics.csv/.parquet from every current done marker; failures.log; ratings.csv."""
    from ._atomic import atomic_text

    rows = [row for row in (_read_done(task) for task in tasks) if row is not None]
    columns = list(dict.fromkeys(["view", *(c for row in rows for c in row)]))
    # Every row gets every column (None where a view has no value, e.g. no model).
    rows = [{c: row.get(c) for c in columns} for row in rows]
    metadata = {"schema": SCHEMA, "manifest": str(manifest.path), "name": manifest.name,
                "lsadphoto_version": __version__,
                "written": timestamp()}
    _write_csv(outdir / "metrics.csv", columns, rows)
    _write_parquet(outdir / "metrics.parquet", columns, rows, metadata)
    atomic_text(outdir / "failures.log", "".join(f"{view}: {reason}\n" for view, reason in failures))
    finished = {row["view"] for row in rows}
    ratings = [{"scene": task["view"], "observer": observer, "rating": rating}
               for task in tasks if task["view"] in finished and task["ratings"]
               for observer, rating in task["ratings"]]
    if ratings:
        _write_csv(outdir / "ratings.csv", ["scene", "observer", "rating"], ratings)
    else:  # an earlier run's file would no longer match the table
        with contextlib.suppress(FileNotFoundError):
            (outdir / "ratings.csv").unlink()
    return rows


def run_survey(manifest_or_path, outdir, *, workers=None, dask_address=None, client=None,
               progress=True, score_options=None):
    """Process every view of a survey; resumable, in parallel, failures isolated.

    Parameters
    ----------
    manifest_or_path : Manifest or path-like
        The survey (see :func:`load_manifest`).
    outdir : path-like
        Output folder: ``views/<id>/`` per view, ``metrics.csv``, ``metrics.parquet``,
        ``failures.log`` and, where views carry ratings, ``ratings.csv``.
    workers : int, optional
        Worker processes on this machine (``spawn`` start method); default: one per CPU,
        at most one per view to process. 0 processes the views in this process, one after
        the other (for debugging; a crash in native code then ends the run).
    dask_address : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``): the views are processed
        by its workers, which need lsadphoto and the files at the same paths.
    client : distributed.Client, optional
        An existing Dask client to use instead (left open).
    progress : bool
        Show a progress bar with the estimated time left on stderr (only on a terminal).
    score_options : dict, optional
        Options of :func:`~lsadphoto.metrics.score.score_map` replacing the manifest's
        survey-wide ``[score]`` ones (a view's own settings still win).

    Returns
    -------
    SurveyResult
    """
    start = time.perf_counter()
    manifest = manifest_or_path if isinstance(manifest_or_path, Manifest) else load_manifest(manifest_or_path)
    options = _score_options(score_options or {}, _Where("run_survey"), "score_options")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 0):
        raise BadInputError(f"workers must be a non-negative integer, got {workers!r}")
    if dask_address is not None and client is not None:
        raise BadInputError("give either a Dask scheduler address or a client, not both")
    if workers is not None and (dask_address is not None or client is not None):
        raise BadInputError("workers sets the local process pool; a Dask cluster has its own workers")
    # distributed waits a minute on an unknown protocol before failing: check first.
    if dask_address is not None and not (isinstance(dask_address, str)
                                         and _DASK_ADDRESS.fullmatch(dask_address)):
        raise BadInputError(f"Dask scheduler address {dask_address!r} must look like "
                            "tcp://HOST:PORT (or tls://HOST:PORT)")
    outdir = Path(outdir)
    if outdir.exists() and not outdir.is_dir():
        raise BadInputError(f"output folder {outdir} is a file")
    outdir.mkdir(parents=True, exist_ok=True)
    tasks = [_task(manifest, view, outdir, options) for view in manifest.views]
    skipped = [t["view"] for t in tasks if _read_done(t) is not None]
    pending = [t for t in tasks if t["view"] not in set(skipped)]
    outcomes = {}
    bar = _progress_bar(total=len(tasks), initial=len(skipped), enabled=progress)

    def report(outcome):
        outcomes[outcome["view"]] = outcome
        if not outcome["ok"] and not bar.disable:
            bar.write(f"{outcome['view']}: failed: {outcome['reason']}", file=sys.stderr)
        bar.update(1)
        bar.set_postfix(failed=sum(not o["ok"] for o in outcomes.values()), refresh=False)

    try:
        if pending:
            if client is not None or dask_address is not None:
                _run_dask(pending, report, client=client, address=dask_address)
            elif workers == 0:
                _run_serial(pending, report)
            else:
                n = min(workers or _cpu_count(), len(pending))
                _run_local(pending, n, report)
    finally:
        bar.close()
        failures = [(t["view"], outcomes[t["view"]]["reason"]) for t in tasks
                    if t["view"] in outcomes and not outcomes[t["view"]]["ok"]]
        table = _write_tables(manifest, tasks, failures, outdir)
    return SurveyResult(table=table, failures=failures,
                        processed=[t["view"] for t in tasks if t["view"] in outcomes],
                        skipped=skipped, outdir=outdir, elapsed=time.perf_counter() - start)
