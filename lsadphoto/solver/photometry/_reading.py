"""What the photometric file readers share: text, tokens, angle checks, symmetry expansion.

References
----------
ANSI/IES LM-63-19 (delimiters, horizontal-angle symmetries); Stockmar, A. W. (1990),
"EULUMDAT – ein Leuchtendatenformat für den europäischen Beleuchtungsplaner" (symmetry
indicator Isym).
"""

import functools
import inspect
import math
import re
from pathlib import Path

import numpy as np

from ...errors import BadInputError, UnsupportedFileError
from .distribution import ANGLE_EPS

#: Mirror images of a stored C angle [deg] for each symmetry.
_MIRRORS = {
    "none": lambda c: [],
    "rotational": None,  # handled separately
    "plane C0-C180": lambda c: [360.0 - c],
    "plane C90-C270": lambda c: [(180.0 - c) % 360.0],
    "quadrant": lambda c: [180.0 - c, 180.0 + c, (360.0 - c) % 360.0],
}


def expand(c_stored, rows, symmetry, name):
    """Full 0..360° C grid and (n_c, n_gamma) rows from the stored planes and a symmetry."""
    rows = np.asarray(rows, dtype=float)
    if symmetry == "rotational":
        return np.array([0.0, 360.0]), np.vstack([rows[0], rows[0]])
    planes = {}
    for angle, row in zip(c_stored, rows):
        planes.setdefault(round(float(angle), 9), row)
    for angle, row in zip(c_stored, rows):
        for mirrored in _MIRRORS[symmetry](float(angle) % 360.0):
            planes.setdefault(round(mirrored % 360.0, 9), row)
    if 0.0 not in planes:
        raise UnsupportedFileError(f"{name}: the C-planes ({symmetry} symmetry) do not include C = 0 after expansion")
    if 360.0 not in planes:
        planes[360.0] = planes[0.0]
    angles = np.array(sorted(planes))
    return angles, np.vstack([planes[a] for a in angles])




def read_text(path):
    """Text of a photometric file; empty / unreadable → UnsupportedFileError."""
    path = Path(path)
    if not path.exists():
        raise BadInputError(f"photometric file {path} does not exist")
    if not path.is_file():
        raise BadInputError(f"photometric file {path} is not a file")
    data = path.read_bytes()
    if not data.strip():
        raise UnsupportedFileError(f"{path}: the file is empty")
    if b"\x00" in data:
        raise UnsupportedFileError(f"{path}: binary data (NUL bytes), not a text photometric file")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        text = data.decode("latin-1")  # older files: Windows-1252 / Latin-1 header text
    return text.removeprefix("\ufeff")  # a byte-order mark written by some editors


class Tokens:
    """Numeric tokens of a whitespace/comma-delimited block, with messages naming the file."""

    def __init__(self, text, name, *, decimal_comma=False):
        # IES allows commas as delimiters (LM-63-02 §3); EULUMDAT has one value per line, where
        # a comma can only be a decimal comma (written by some European tools).
        if decimal_comma:
            self.items = [t.replace(",", ".") for t in text.split()]
        else:
            self.items = [t for t in re.split(r"[\s,]+", text) if t]
        self.pos = 0
        self.name = name

    def number(self, what):
        if self.pos >= len(self.items):
            raise UnsupportedFileError(f"{self.name}: truncated, {what} missing")
        token = self.items[self.pos]
        self.pos += 1
        try:
            value = float(token)
        except ValueError:
            raise UnsupportedFileError(f"{self.name}: non-numeric value {token[:20]!r} for {what}") from None
        if not math.isfinite(value):
            raise UnsupportedFileError(f"{self.name}: non-finite value {token!r} for {what}")
        return value

    def integer(self, what, minimum=None):
        value = self.number(what)
        if value != int(value):
            raise UnsupportedFileError(f"{self.name}: {what} must be an integer, got {value:g}")
        if minimum is not None and value < minimum:
            raise UnsupportedFileError(f"{self.name}: {what} must be at least {minimum}, got {value:g}")
        return int(value)

    def numbers(self, count, what):
        start = self.pos
        if start + count > len(self.items):
            raise UnsupportedFileError(
                f"{self.name}: truncated, {what} needs {count} values but only {len(self.items) - start} remain")
        return np.array([self.number(f"{what} #{k + 1}") for k in range(count)])

    def rest(self):
        return self.items[self.pos:]


def check_angles(angles, what, name, low, high):
    if np.any(np.diff(angles) <= 0):
        raise UnsupportedFileError(f"{name}: {what} are not strictly ascending")
    if angles[0] < low - ANGLE_EPS or angles[-1] > high + ANGLE_EPS:
        raise UnsupportedFileError(f"{name}: {what} {angles[0]:g}..{angles[-1]:g} outside {low:g}..{high:g} degrees")


def guarded(reader):
    """Run a reader; any stray parsing exception becomes a one-line UnsupportedFileError."""

    signature = inspect.signature(reader)

    @functools.wraps(reader)
    def wrapped(path, **kwargs):
        signature.bind(path, **kwargs)  # a wrong option is the caller's TypeError, not the file's
        try:
            return reader(path, **kwargs)
        except BadInputError:
            raise
        except (IndexError, ValueError, KeyError, TypeError, ZeroDivisionError, OverflowError) as exc:
            message = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise UnsupportedFileError(f"{path}: cannot parse the file ({message})") from None

    return wrapped
