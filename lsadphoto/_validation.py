"""Input checks that name the offending parameter (never ``assert`` in library code)."""

from pathlib import Path

import numpy as np

from .errors import BadInputError


def check_array(value, name, *, ndim=None, shape=None, finite=False, dtype=None):
    """Return ``value`` as a numpy array after checking it; raise :class:`BadInputError`."""
    try:
        array = np.asarray(value) if dtype is None else np.asarray(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise BadInputError(f"{name} is not a numeric array: {exc}") from None
    if ndim is not None and array.ndim not in np.atleast_1d(ndim):
        raise BadInputError(f"{name} must have {ndim} dimensions, got shape {array.shape}")
    if shape is not None and array.shape != tuple(shape):
        raise BadInputError(f"{name} must have shape {tuple(shape)}, got {array.shape}")
    if finite and array.dtype.kind in "fc" and not np.all(np.isfinite(array)):
        raise BadInputError(f"{name} contains NaN or infinite values")
    return array


def check_positive(value, name, *, allow_zero=False):
    """Return ``float(value)`` after checking it is finite and positive."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise BadInputError(f"{name} must be a number, got {value!r}") from None
    if not np.isfinite(number) or number < 0 or (number == 0 and not allow_zero):
        kind = "non-negative" if allow_zero else "positive"
        raise BadInputError(f"{name} must be a finite {kind} number, got {value!r}")
    return number


def check_positive_int(value, name):
    """Return ``int(value)`` after checking it is a whole number ≥ 1 (not a bool)."""
    try:
        whole = not isinstance(value, bool) and int(value) == value and value >= 1
    except (TypeError, ValueError):
        whole = False
    if not whole:
        raise BadInputError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def check_choice(value, name, choices):
    """Check that ``value`` is one of ``choices``; the error lists the valid ones."""
    if value not in choices:
        valid = ", ".join(repr(c) for c in choices)
        raise BadInputError(f"unknown {name} {value!r}; valid: {valid}")
    return value


def check_file(path, name="file"):
    """Return ``Path(path)`` after checking that it is a readable, non-empty file."""
    path = Path(path)
    if not path.exists():
        raise BadInputError(f"{name} {path} does not exist")
    if not path.is_file():
        raise BadInputError(f"{name} {path} is not a file")
    if path.stat().st_size == 0:
        raise BadInputError(f"{name} {path} is empty")
    return path
