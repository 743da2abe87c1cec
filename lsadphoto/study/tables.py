"""Reading and checking the two tables of an observer study: ratings and metrics.

``RATINGS.csv`` has one row per (observer, scene) rating, with the columns ``scene``,
``observer`` and ``rating``; ``METRICS.csv`` has one row per scene, the column ``scene`` and
one numeric column per metric, the Q(N) sweep among them as ``<prefix><N>`` (``q_n1`` …
``q_n100``). Both formats are described in ``docs/user-guide-study.md``.

Every problem raises :class:`~lsadphoto.errors.BadInputError` with a one-line message that
names the file, the row (the line number in the file, the header being line 1) and the
column. A rating cell may be empty (or ``NA``, ``N/A``, ``NaN``, ``null``): that rating is
skipped. Metric cells must be finite numbers or empty; an empty cell is allowed except in
the analysed metric and the sweep columns, which :func:`~lsadphoto.study.run_study` requires
complete (another metric column with empty cells is correlated over the scenes that have a
value).
"""

import csv
import math
import re
from dataclasses import dataclass

import numpy as np

from .._validation import check_file
from ..errors import BadInputError

__all__ = ["MISSING_TOKENS", "Ratings", "Metrics", "SceneRatings", "read_ratings",
           "read_metrics", "scene_ratings", "sweep_columns"]

#: Cell contents (compared case-insensitively after stripping blanks) read as "no value".
MISSING_TOKENS = frozenset({"", "na", "n/a", "nan", "null", "none"})


@dataclass(frozen=True)
class Ratings:
    """Individual ratings: parallel arrays, one entry per non-missing rating.

    ``line`` is the line number of each rating in the file (header = line 1), kept for
    error messages; ``n_missing`` counts the skipped empty ratings.
    """

    path: str
    scene: tuple
    observer: tuple
    rating: np.ndarray
    line: tuple
    n_missing: int


@dataclass(frozen=True)
class Metrics:
    """Metric values per scene: ``values[name]`` is a float64 array over ``scenes``
    (NaN where the cell was empty); ``line[i]`` is the file line of scene ``i``."""

    path: str
    scenes: tuple
    values: dict
    line: tuple


@dataclass(frozen=True)
class SceneRatings:
    """Per-scene summary of the ratings, in the order of ``scenes``.

    ``mean``, ``sd`` (sample standard deviation, ddof = 1; NaN for one rating), ``n`` and
    ``sem`` = sd/√n, the standard error of the mean [rating units].
    """

    scenes: tuple
    mean: np.ndarray
    sd: np.ndarray
    n: np.ndarray
    sem: np.ndarray


def _read_rows(path, name, required):
    """Header and rows of a CSV file; checks the required columns and the row lengths."""
    path = check_file(path, name)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = list(csv.reader(fh))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise BadInputError(f"{path}: not a readable UTF-8 CSV file ({exc})") from None
    # Drop blank lines but keep line numbers (csv.reader yields [] for them).
    numbered = [(i + 1, row) for i, row in enumerate(rows) if any(c.strip() for c in row)]
    if not numbered:
        raise BadInputError(f"{path}: no header row")
    header_line, header = numbered[0]
    header = [c.strip() for c in header]
    for column in required:
        if column not in header:
            raise BadInputError(f"{path}, line {header_line}: missing column {column!r} "
                                f"(columns: {', '.join(header)})")
    seen = set()
    for column in header:
        if column == "":
            raise BadInputError(f"{path}, line {header_line}: empty column name")
        if column in seen:
            raise BadInputError(f"{path}, line {header_line}: duplicate column {column!r}")
        seen.add(column)
    body = numbered[1:]
    for line, row in body:
        if len(row) != len(header):
            raise BadInputError(f"{path}, line {line}: {len(row)} cells, header has "
                                f"{len(header)}")
    return path, header, body


def _number(text, path, line, column, *, allow_missing):
    """Parse one cell as a finite float (NaN for a missing cell where allowed)."""
    stripped = text.strip()
    if stripped.lower() in MISSING_TOKENS:
        if allow_missing:
            return math.nan
        raise BadInputError(f"{path}, line {line}, column {column!r}: missing value")
    try:
        value = float(stripped)
    except ValueError:
        raise BadInputError(f"{path}, line {line}, column {column!r}: not a number: "
                            f"{stripped!r}") from None
    if not math.isfinite(value):
        raise BadInputError(f"{path}, line {line}, column {column!r}: not finite: "
                            f"{stripped!r}")
    return value


def _label(text, path, line, column):
    label = text.strip()
    if not label:
        raise BadInputError(f"{path}, line {line}, column {column!r}: empty {column} name")
    return label


def read_ratings(path, *, rating_scale=None):
    """Read ``RATINGS.csv``: one row per (observer, scene) rating.

    Parameters
    ----------
    path : path-like
        CSV file with the columns ``scene``, ``observer``, ``rating`` (others are ignored).
    rating_scale : (float, float), optional
        Lowest and highest rating allowed (e.g. ``(1, 10)`` for the paper's 10-point scale);
        a rating outside raises. ``None`` (default) checks nothing.

    Returns
    -------
    Ratings

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "r.csv").write_text("scene,observer,rating\\nA,o1,7\\nA,o2,\\nB,o1,4\\n")
    >>> r = read_ratings(folder / "r.csv", rating_scale=(1, 10))
    >>> r.rating.tolist(), r.n_missing
    ([7.0, 4.0], 1)
    """
    path, header, body = _read_rows(path, "ratings file", ("scene", "observer", "rating"))
    i_scene, i_obs, i_rating = (header.index(c) for c in ("scene", "observer", "rating"))
    if rating_scale is not None:
        low, high = (float(v) for v in rating_scale)
        if not low < high:
            raise BadInputError(f"rating_scale must be (low, high) with low < high, got "
                                f"{rating_scale!r}")
    scenes, observers, ratings, lines = [], [], [], []
    first_line = {}
    n_missing = 0
    for line, row in body:
        scene = _label(row[i_scene], path, line, "scene")
        observer = _label(row[i_obs], path, line, "observer")
        key = (scene, observer)
        if key in first_line:
            raise BadInputError(f"{path}, line {line}, columns 'scene','observer': observer "
                                f"{observer!r} rated scene {scene!r} again (first on line "
                                f"{first_line[key]})")
        first_line[key] = line
        value = _number(row[i_rating], path, line, "rating", allow_missing=True)
        if math.isnan(value):
            n_missing += 1
            continue
        if rating_scale is not None and not low <= value <= high:
            raise BadInputError(f"{path}, line {line}, column 'rating': {value:g} is outside "
                                f"the rating scale {low:g}–{high:g}")
        scenes.append(scene)
        observers.append(observer)
        ratings.append(value)
        lines.append(line)
    if not ratings:
        raise BadInputError(f"{path}: no ratings (every 'rating' cell is empty)")
    return Ratings(str(path), tuple(scenes), tuple(observers), np.array(ratings, np.float64),
                   tuple(lines), n_missing)


def _text_column(body, index):
    """True when no cell of the column parses as a number (and it is not all empty)."""
    seen_text = False
    for _, row in body:
        cell = row[index].strip() if index < len(row) else ""
        if cell == "" or cell.lower() in MISSING_TOKENS:
            continue
        try:
            float(cell)
        except ValueError:
            seen_text = True
            continue
        return False
    return seen_text


def read_metrics(path):
    """Read ``METRICS.csv``: one row per scene, column ``scene`` plus numeric metric columns.

    The id column may also be called ``view``, as in the survey's ``metrics.csv``.

    Every column other than ``scene`` that holds numbers is a metric; empty cells (see
    :data:`MISSING_TOKENS`) become NaN. Columns in which no cell is a number (provenance
    such as file names or versions, as the survey table carries) are not metrics and are
    skipped; a column mixing numbers and text is an error. Scene names must be unique.

    Returns
    -------
    Metrics
    """
    path = check_file(path, "metrics file")
    with open(path, newline="", encoding="utf-8-sig") as fh:
        first = fh.readline()
    # The survey's metrics.csv names its scenes "view"; either name is the id column.
    id_column = "view" if "view" in [c.strip() for c in first.split(",")] and \
        "scene" not in [c.strip() for c in first.split(",")] else "scene"
    path, header, body = _read_rows(path, "metrics file", (id_column,))
    i_scene = header.index(id_column)
    columns = [c for c in header
               if c != id_column and not _text_column(body, header.index(c))]
    if not columns:
        raise BadInputError(f"{path}: no metric columns besides 'scene'")
    scenes, lines = [], []
    values = {c: [] for c in columns}
    first_line = {}
    for line, row in body:
        scene = _label(row[i_scene], path, line, id_column)
        if scene in first_line:
            raise BadInputError(f"{path}, line {line}, column 'scene': scene {scene!r} "
                                f"appears again (first on line {first_line[scene]})")
        first_line[scene] = line
        scenes.append(scene)
        lines.append(line)
        for c in columns:
            values[c].append(_number(row[header.index(c)], path, line, c, allow_missing=True))
    if not scenes:
        raise BadInputError(f"{path}: no scene rows")
    return Metrics(str(path), tuple(scenes),
                   {c: np.array(v, np.float64) for c, v in values.items()}, tuple(lines))


def sweep_columns(metrics, prefix):
    """The sweep columns ``<prefix><N>`` of ``metrics``, sorted by N.

    N is the suffix: digits with an optional decimal part (``q_n50``, ``q_n2.5``).

    Returns
    -------
    list of (float, str)
        (N, column name) pairs in increasing N; empty if no column matches.
    """
    pattern = re.compile(re.escape(prefix) + r"(\d+(?:\.\d+)?)")
    found = {}
    for column in metrics.values:
        match = pattern.fullmatch(column)
        if match:
            n = float(match.group(1))
            if n in found:
                raise BadInputError(f"{metrics.path}: columns {found[n]!r} and {column!r} "
                                    f"both give N = {n:g}")
            found[n] = column
    return sorted(found.items())


def rated_scenes_only(metrics, ratings):
    """``metrics`` restricted to the scenes that have ratings, and the scenes left out.

    A survey may hold views nobody rated; they cannot enter a correlation with ratings.
    """
    rated = set(ratings.scene)
    keep = [i for i, s in enumerate(metrics.scenes) if s in rated]
    dropped = [s for s in metrics.scenes if s not in rated]
    if not dropped:
        return metrics, []
    idx = np.asarray(keep, dtype=np.intp)
    return Metrics(metrics.path, tuple(metrics.scenes[i] for i in keep),
                   {k: v[idx] for k, v in metrics.values.items()},
                   tuple(metrics.line[i] for i in keep)), dropped


def scene_ratings(ratings, metrics):
    """Per-scene mean, SD, count and standard error of the ratings, in the metrics' order.

    Every rated scene must be a row of the metrics file and every metrics row must have at
    least one rating; otherwise :class:`BadInputError` names the scene and its line.
    """
    index = {s: i for i, s in enumerate(metrics.scenes)}
    for scene, line in zip(ratings.scene, ratings.line):
        if scene not in index:
            raise BadInputError(f"{ratings.path}, line {line}, column 'scene': scene "
                                f"{scene!r} is not in {metrics.path}")
    where = np.array([index[s] for s in ratings.scene], dtype=np.intp)
    n = np.bincount(where, minlength=len(metrics.scenes))
    for i, count in enumerate(n):
        if count == 0:
            raise BadInputError(f"{metrics.path}, line {metrics.line[i]}, column 'scene': "
                                f"scene {metrics.scenes[i]!r} has no ratings in "
                                f"{ratings.path}")
    total = np.bincount(where, ratings.rating, len(n))
    mean = total / n
    squares = np.bincount(where, (ratings.rating - mean[where]) ** 2, len(n))
    with np.errstate(invalid="ignore", divide="ignore"):
        sd = np.where(n > 1, np.sqrt(squares / np.maximum(n - 1, 1)), np.nan)
        sem = sd / np.sqrt(n)
    return SceneRatings(metrics.scenes, mean, sd, n, sem)
