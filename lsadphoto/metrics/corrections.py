"""Corrections evalglare 3.06 applies before or after the glare evaluation.

``fill_rows_evalglare`` (evalglare ``-I Ev y_max y_min``)
    Pictures cut at the top or bottom (a fisheye circle taller than the sensor) are filled
    with the last known values before anything is evaluated. evalglare counts rows ``y`` from
    the bottom; here rows count from the top, ``row = rows − 1 − y``, and the two numbers
    keep evalglare's meaning after that conversion:

    * ``row_max`` (evalglare's ``y_max``): every valid pixel in rows 0…``row_max`` takes the
      luminance of the pixel below it, working upwards from row ``row_max``, so that the
      values of row ``row_max + 1`` propagate to the top (an invalid pixel passes on 0, as
      evalglare has zeroed it by then);
    * ``row_min`` (evalglare's ``y_min``): rows ``row_min``…``rows − 2`` take the values of
      row ``row_min − 1`` (every pixel, as evalglare; the last row is not filled).

    The same option gives DGP an external vertical illuminance (see ``illuminance`` of
    :func:`~lsadphoto.metrics.score.score_map`, evalglare ``-i``).
Low-light correction modes (evalglare ``-C``)
    ``"l+"`` switches the DGP low-light correction on, ``"l-"`` and ``"0"`` (every
    correction) off — the default of evalglare ≥ 2.14 (:data:`CORRECTION_MODES`).

References
----------
Radiance ``src/util/evalglare.c`` v3.06 (``-I``: fill loops before the illuminance pass;
``-C``; ``-i``).
"""

import numpy as np

from .._validation import check_choice
from ..errors import BadInputError

__all__ = ["CORRECTION_MODES", "low_light_correction_on", "fill_rows_evalglare"]

#: evalglare ``-C`` modes and whether each switches the DGP low-light correction on.
CORRECTION_MODES = {"l+": True, "l-": False, "0": False}


def low_light_correction_on(mode):
    """Whether evalglare's ``-C`` ``mode`` ("l+", "l-", "0") applies the low-light correction.

    Examples
    --------
    >>> low_light_correction_on("l+"), low_light_correction_on("0")
    (True, False)
    """
    return CORRECTION_MODES[check_choice(mode, "correction mode", tuple(CORRECTION_MODES))]


def fill_rows_evalglare(luminance, valid, *, row_max, row_min):
    """Fill the rows of a cut picture with the last known values (evalglare ``-I``).

    Parameters
    ----------
    luminance : ndarray, shape (rows, cols)
        L [cd·m⁻²] as read (not modified).
    valid : ndarray of bool, shape (rows, cols)
        Pixels evalglare evaluates (in front of the observer, ω > 0).
    row_max, row_min : int
        evalglare's ``y_max`` and ``y_min`` converted to rows from the top (see the module
        notes); ``row_max < row_min``.

    Returns
    -------
    ndarray, float64, shape (rows, cols)

    Examples
    --------
    A column of five pixels, the top two and the bottom one cut:

    >>> L = np.array([[0.0], [0.0], [5.0], [7.0], [0.0]])
    >>> fill_rows_evalglare(L, np.ones((5, 1), bool), row_max=1, row_min=4)[:, 0].tolist()
    [5.0, 5.0, 5.0, 7.0, 0.0]

    References
    ----------
    Radiance ``src/util/evalglare.c`` v3.06 (``-I Ev y_max y_min``).
    """
    out = np.array(luminance, dtype=np.float64)
    valid = np.asarray(valid, dtype=bool)
    rows = out.shape[0]
    if out.ndim != 2 or valid.shape != out.shape:
        raise BadInputError(f"luminance {out.shape} and valid {valid.shape} must be one 2-d shape")
    for name, value in (("row_max", row_max), ("row_min", row_min)):
        if int(value) != value or not 0 <= value < rows:
            raise BadInputError(f"fill {name} must be a row of the picture (0…{rows - 1}), "
                                f"got {value!r}")
    row_max, row_min = int(row_max), int(row_min)
    if not row_max < row_min:
        raise BadInputError(f"fill rows: row_max ({row_max}) must lie above row_min ({row_min})")
    # evalglare's y = rows − 1 − row: y ≤ y_min (y ≥ 1) from y_min + 1, every pixel.
    if row_min <= rows - 2:
        out[row_min:rows - 1] = out[row_min - 1]
    # y ≥ y_max, valid pixels, from y − 1 upwards; invalid pixels have been zeroed.
    for row in range(row_max, -1, -1):
        below = np.where(valid[row + 1], out[row + 1], 0.0)
        out[row] = np.where(valid[row], below, out[row])
    return out
