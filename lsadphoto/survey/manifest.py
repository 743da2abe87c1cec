r"""The survey manifest: its declared schema and the complete check of it.

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

The structure, the types, the ranges and the choices of every key — the score options
among them — are declared once in :data:`MANIFEST_SCHEMA` and checked by the one TOML
checker, :mod:`lsadphoto._schema` (unknown keys refused); :func:`load_manifest` then checks
what a schema cannot: files exist, camera profiles and scene models load, CSV tables of
spots and ratings parse, ids are unique and safe as file names. Options given outside the manifest
(``run_survey(score_options=...)``, the CLI's ``--N``) go through the same declaration with
:func:`check_score_options`. So a bad value stops the run before any view is processed
(issue 17, defect 3).

References
----------
TOML v1.0.0, https://toml.io/en/v1.0.0.
"""

import csv
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from .._schema import ArrayOf, Key, Table, read_toml, validate
from .._validation import check_file
from ..calibrate.spot import SpotReading
from ..errors import BadInputError
from ..raw.colour import COLOUR_METHODS
from ..raw.decode import DEMOSAIC_METHODS

__all__ = ["SCHEMA", "MANIFEST_SCHEMA", "SCORE_SCHEMA", "Manifest", "SurveyView",
           "load_manifest", "check_score_options"]

SCHEMA = "lsadphoto.survey/1"

#: A view id becomes a folder and file names: no separators, no leading dot.
_ID_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")

_SPOT_COLUMNS = ("row", "col", "cd_m2")


class _Either(Key):
    """A value that is a path (string) or a list checked by ``check_list``."""

    def __init__(self, check_list, **kwargs):
        super().__init__(str, **kwargs)
        self.check_list = check_list

    def check(self, value, where):
        if isinstance(value, str):
            if not value.strip():
                raise BadInputError(f"{where} must not be an empty path")
            return value
        if isinstance(value, list) and value:
            return self.check_list(value, where)
        raise BadInputError(f"{where} must be {self.doc}, got {value!r}")


class _PeakLuminance(Key):
    """``peak_luminance``: a positive number [cd·m⁻²], or ``false`` (TOML has no null)."""

    def __init__(self):
        super().__init__(float, minimum=0, exclusive=True,
                         doc="peak-extraction limit [cd/m²]; false switches it off")

    def check(self, value, where):
        return None if value is False else super().check(value, where)


def _vector(doc):
    return Key(list, items=float, length=3, doc=doc)


def _score_schema():
    from ..geometry.position_index import GUTH_FIELDS
    from ..geometry.position_index import METHODS as POSITION_INDEX_METHODS
    from ..metrics.field import BACKGROUND_METHODS
    from ..metrics.glare_indices import DGP_COEFFICIENTS
    from ..metrics.quality import CUTOFFS, THRESHOLDS
    from ..metrics.sources import SOURCE_METHODS

    positive = {"minimum": 0, "exclusive": True}
    return Table({
        "line_of_sight": _vector("observer's line of sight, camera frame"),
        "up": _vector("observer's up, camera frame"),
        "task_direction": _vector("task direction, camera frame"),
        "source_method": Key(str, choices=SOURCE_METHODS),
        "background_method": Key(str, choices=BACKGROUND_METHODS),
        "position_index_method": Key(str, choices=POSITION_INDEX_METHODS),
        "q_threshold": Key(str, choices=THRESHOLDS),
        "q_cutoff": Key(str, choices=CUTOFFS),
        "dgp_coefficients": Key(str, choices=tuple(DGP_COEFFICIENTS)),
        "source_threshold": Key(float, **positive, doc="[cd/m²] (fixed) or factor"),
        "task_opening_deg": Key(float, minimum=0, maximum=360, exclusive=True,
                                doc="full opening of the task cone [deg]"),
        "search_angle": Key(float, **positive, doc="evalglare -r [rad]"),
        "n_thresholds": Key(float, **positive, doc="N of the Q criterion"),
        "size_arcmin": Key(float, **positive, doc="critical detail α [arcmin]"),
        "vcp_constant": Key(float, **positive),
        "q_weight_exponent": Key(int, minimum=0),
        "guth_field": Key(int, choices=GUTH_FIELDS),
        "peak_luminance": _PeakLuminance(),
    }, doc="options of lsadphoto.metrics.score.score_map")


def _spot_list(value, where):
    spot = Table({"row": Key(float, required=True, minimum=0),
                  "col": Key(float, required=True, minimum=0),
                  "cd_m2": Key(float, required=True, minimum=0, exclusive=True)})
    if not all(isinstance(v, dict) for v in value):
        raise BadInputError(f"{where} must be a CSV path or a list of tables {{row, col, cd_m2}}")
    return [spot.check(v, f"{where}[{i}]") for i, v in enumerate(value)]


def _number_list(value, where):
    return Key(list, items=float).check(value, where)


def _path_list(value, where):
    return Key(list, items=str).check(value, where)


#: Options of :func:`~lsadphoto.metrics.score.score_map` a manifest may set (``[score]``,
#: ``[view.score]``, ``run_survey(score_options=...)``), with their types, ranges and choices.
SCORE_SCHEMA = _score_schema()

#: The whole manifest (schema ``lsadphoto.survey/1``).
MANIFEST_SCHEMA = Table({
    "schema": Key(str, default=SCHEMA, choices=(SCHEMA,)),
    "name": Key(str), "description": Key(str),
    "profile": Key(str, doc="camera profile of every view"),
    "demosaic": Key(str, default=DEMOSAIC_METHODS[0], choices=DEMOSAIC_METHODS),
    "colour_method": Key(str, default=COLOUR_METHODS[0], choices=COLOUR_METHODS),
    "acceptance_angle_deg": Key(float, default=1.0, minimum=0, maximum=180, exclusive=True,
                                doc="spot meter's full acceptance angle [deg]"),
    "score": SCORE_SCHEMA,
    "view": ArrayOf(Table({
        "id": Key(str, required=True),
        "raw": _Either(_path_list, required=True, doc="a path or a non-empty list of paths"),
        "profile": Key(str),
        "spots": _Either(_spot_list, doc="a CSV path or a non-empty list of {row, col, cd_m2}"),
        "line_of_sight": _vector("observer's line of sight, camera frame"),
        "ratings": _Either(_number_list, doc="a CSV path or a non-empty list of numbers"),
        "model": Table({
            "scene": Key(str, required=True, doc="scene model file"),
            "position": Key(list, items=float, length=3, required=True, doc="eye position [m]"),
            "direction": Key(list, items=float, length=3, required=True,
                             doc="optical axis in the scene"),
            "up": _vector("up in the scene"),
            "samples": Key(int, default=20000, minimum=1),
            "nodes_per_pixel": Key(int, default=16, minimum=1),
            "seed": Key(int, default=0, minimum=0),
        }),
        "score": SCORE_SCHEMA,
        "note": Key(str),
    }), required=True, min_items=1, doc="the views ([[view]])"),
})


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


def check_score_options(options, *, source="score options"):
    """Check a mapping of :func:`~lsadphoto.metrics.score.score_map` options against
    :data:`SCORE_SCHEMA`; return them as ``score_map`` takes them.

    Vectors become tuples, ``peak_luminance = false`` becomes None. ``source`` names the
    options in the one-line error (e.g. the CLI's ``--N``).

    Examples
    --------
    >>> check_score_options({"line_of_sight": [0, 0, 1], "n_thresholds": 50})
    {'line_of_sight': (0.0, 0.0, 1.0), 'n_thresholds': 50.0}
    >>> check_score_options({"n_thresholds": -2}, source="--N")
    Traceback (most recent call last):
    ...
    lsadphoto.errors.BadInputError: --N: n_thresholds must be > 0, got -2.0
    """
    if not isinstance(options, dict):
        raise BadInputError(f"{source} must be a mapping of score_map options, got {options!r}")
    checked = validate(options, SCORE_SCHEMA, source=source)
    return _score_options(checked, source)


def _score_options(checked, where):
    out = {}
    for key, value in checked.items():
        if isinstance(value, list):
            if not any(value):
                raise BadInputError(f"{where}: {key} must not be the zero vector")
            value = tuple(value)
        out[key] = value
    return out


class _Where:
    """Builds one-line errors naming the manifest, the view and the field."""

    def __init__(self, path, view=None):
        self.path, self.view = path, view

    def error(self, field_name, message):
        view = "" if self.view is None else f"view {self.view}: "
        return BadInputError(f"{self.path}: {view}{field_name}: {message}")


def _file(base, text, where, field_name, what):
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
    if isinstance(value, list):  # checked by the schema
        return tuple(SpotReading(s["row"], s["col"], s["cd_m2"], acceptance_angle) for s in value)
    path = _file(base, value, where, "spots", "spot readings file")
    rows = _read_csv(path, where, "spots", _SPOT_COLUMNS)
    spots = []
    for line, r in enumerate(rows, start=2):
        row, col, luminance = (_csv_number(r[k], path, line, k, where, "spots")
                               for k in _SPOT_COLUMNS)
        if row < 0 or col < 0:
            raise where.error("spots", f"{path} line {line}: row and col must not be negative")
        if luminance <= 0:
            raise where.error("spots", f"{path} line {line}: cd_m2 must be positive, "
                                       f"got {luminance:g}")
        spots.append(SpotReading(row, col, luminance, acceptance_angle))
    return tuple(spots)


def _ratings(value, base, where, view_id):
    if isinstance(value, list):  # numbers, checked by the schema
        return tuple((str(i), v) for i, v in enumerate(value, start=1))
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


def _model(value, base, where):
    from ..solver import read_scene

    model = dict(value)
    scene = _file(base, value["scene"], where, "model.scene", "scene model")
    try:
        read_scene(scene)  # read and checked now, not after the view's map was computed
    except BadInputError as exc:
        raise where.error("model.scene", str(exc)) from None
    model["scene"] = str(scene)
    for key in ("direction", "up"):
        if key in value and not any(value[key]):
            raise where.error(f"model.{key}", "must not be the zero vector")
    return model


def load_manifest(path):
    r"""Read and check a survey manifest (TOML, schema ``lsadphoto.survey/1``) completely.

    Every problem — a missing field, an unknown key, a value of the wrong type or out of
    range (score options included), a missing file, a duplicate or unsafe view id, an
    unreadable camera profile or CSV table — is one :class:`~lsadphoto.errors.BadInputError`
    naming the manifest, the view and the field, before anything is processed.

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
    lsadphoto.errors.BadInputError: .../survey.toml: [view[0]] unknown key 'raws' (did you mean 'raw'?); valid: id, raw, ...
    """
    from ..calibrate.profile import load_profile

    path = check_file(path, "survey manifest").resolve()
    data = read_toml(path, MANIFEST_SCHEMA, what="survey manifest")
    base = path.parent
    where = _Where(path)
    profiles = {}

    def profile(value, w):
        file = _file(base, value, w, "profile", "camera profile")
        if file not in profiles:
            try:
                load_profile(file)
            except BadInputError as exc:
                raise w.error("profile", str(exc)) from None
            profiles[file] = True
        return file

    acceptance_angle = math.radians(data["acceptance_angle_deg"])
    manifest = Manifest(
        path=path, views=[],
        profile=profile(data["profile"], where) if "profile" in data else None,
        demosaic=data["demosaic"], colour_method=data["colour_method"],
        acceptance_angle=acceptance_angle,
        score=_score_options(data.get("score", {}), f"{path}: score"),
        name=data.get("name"), description=data.get("description"),
    )
    seen = {}
    for number, entry in enumerate(data["view"], start=1):
        view_id = entry["id"]
        if not _ID_PATTERN.fullmatch(view_id):
            raise _Where(path, f"#{number}").error(
                "id", f"{view_id!r} is not safe as a file name: use 1–100 letters, digits, "
                      "'.', '_' or '-', starting with a letter or digit")
        w = _Where(path, repr(view_id))
        # Compared case-insensitively: on macOS and Windows "A" and "a" are one folder.
        if view_id.lower() in seen:
            raise w.error("id", f"duplicate id (view #{seen[view_id.lower()]} has it too)")
        seen[view_id.lower()] = number
        raw_list = [entry["raw"]] if isinstance(entry["raw"], str) else entry["raw"]
        raw_files = tuple(_file(base, r, w, "raw", "RAW file") for r in raw_list)
        if len(set(raw_files)) != len(raw_files):
            raise w.error("raw", "lists the same file twice")
        line_of_sight = None
        if "line_of_sight" in entry:
            line_of_sight = _score_options({"line_of_sight": entry["line_of_sight"]},
                                           f"{path}: view {view_id!r}")["line_of_sight"]
        manifest.views.append(SurveyView(
            id=view_id, raw=raw_files, raw_as_written=tuple(raw_list),
            profile=profile(entry["profile"], w) if "profile" in entry else None,
            spots=_spots(entry["spots"], base, w, acceptance_angle) if "spots" in entry else (),
            line_of_sight=line_of_sight,
            ratings=_ratings(entry["ratings"], base, w, view_id) if "ratings" in entry else None,
            model=_model(entry["model"], base, w) if "model" in entry else None,
            score=_score_options(entry.get("score", {}), f"{path}: view {view_id!r}: score"),
            note=entry.get("note"),
        ))
    return manifest
