"""Camera RGB → CIE XYZ → relative photopic luminance Y.

Four sources of the camera matrix, tried in this order by ``method="auto"``:

``profile``
    A 3 × 3 camera → XYZ matrix from the camera profile (e.g. fitted to a ColorChecker shot).
``libraw-rgb_xyz``
    LibRaw's ``rgb_xyz_matrix`` (its ``cam_xyz``, XYZ → camera, Adobe coefficients);
    camera → XYZ is its inverse. LibRaw leaves it all zeros for DNG files.
``dng-tags``
    The DNG's own tags: ForwardMatrix with AsShotNeutral where present
    (camera → XYZ_D50 = FM · diag(1/neutral)), else the inverse of the ColorMatrix whose
    calibration illuminant is closest to daylight (DNG 1.6 §6 "Mapping Camera Color Space
    to CIE XYZ Space").
``libraw-color_matrix``
    LibRaw's ``color_matrix`` (camera → linear sRGB after the daylight white-balance
    multipliers): camera → XYZ = M_sRGB→XYZ · color_matrix · diag(daylight_wb)
    (PITFALLS.md), with colour-science's sRGB matrix.

All four fix the same scale for a given camera (LibRaw derives ``color_matrix`` and the
multipliers from ``cam_xyz``), which tests/test_colour.py checks.

References
----------
Adobe, *DNG Specification* 1.6, chapter 6. IEC 61966-2-1 (sRGB). CIE 015:2018 (Y as
photopic luminance).
"""

import numpy as np

from .._validation import check_array, check_choice
from ..errors import BadInputError

COLOUR_METHODS = ("auto", "profile", "libraw-rgb_xyz", "dng-tags", "libraw-color_matrix")

# Preference for DNG calibration illuminants (EXIF LightSource codes): daylight first.
_ILLUMINANT_PREFERENCE = {21: 0, 20: 1, 23: 2, 22: 3, 1: 4, 9: 5, 10: 6}


def _srgb_to_xyz():
    # Imported here: colour-science takes seconds to import (it loads its plotting stack),
    # which every CLI call and survey worker would pay although only this route needs it.
    import colour

    return np.asarray(colour.RGB_COLOURSPACES["sRGB"].matrix_RGB_to_XYZ, dtype=np.float64)


def _from_dng_tags(dng):
    forward = dng.get("forward_matrix") or [None, None]
    matrices = dng.get("color_matrix") or [None, None]
    illuminants = dng.get("calibration_illuminant") or [None, None]
    order = sorted(
        (i for i in range(2) if matrices[i] is not None),
        key=lambda i: _ILLUMINANT_PREFERENCE.get(illuminants[i], 99),
    )
    if not order:
        return None
    best = order[0]
    neutral = dng.get("as_shot_neutral")
    if forward[best] is not None and neutral is not None and np.all(neutral > 0):
        return forward[best] @ np.diag(1.0 / neutral)
    return np.linalg.inv(matrices[best])


def camera_to_xyz_matrix(colour_info, *, method="auto", profile_matrix=None):
    """The 3 × 3 matrix taking normalised camera RGB to CIE XYZ, and the method used.

    Parameters
    ----------
    colour_info : CameraColour
        From :func:`~lsadphoto.raw.decode_raw`.
    method : str
        One of :data:`COLOUR_METHODS`.
    profile_matrix : array_like, shape (3, 3), optional
        Camera → XYZ matrix of the camera profile.

    Returns
    -------
    matrix : ndarray, shape (3, 3)
    method : str
    """
    check_choice(method, "colour method", COLOUR_METHODS)
    candidates = []
    if method in ("auto", "profile") and profile_matrix is not None:
        candidates.append(("profile", check_array(profile_matrix, "colour matrix", shape=(3, 3), finite=True, dtype=float)))
    if method in ("auto", "libraw-rgb_xyz") and np.any(colour_info.rgb_xyz_matrix):
        candidates.append(("libraw-rgb_xyz", np.linalg.inv(colour_info.rgb_xyz_matrix)))
    if method in ("auto", "dng-tags") and colour_info.dng:
        matrix = _from_dng_tags(colour_info.dng)
        if matrix is not None:
            candidates.append(("dng-tags", matrix))
    if method in ("auto", "libraw-color_matrix") and np.any(colour_info.color_matrix):
        wb = colour_info.daylight_whitebalance
        if np.all(wb > 0):
            candidates.append(("libraw-color_matrix", _srgb_to_xyz() @ colour_info.color_matrix @ np.diag(wb)))
    if not candidates:
        raise BadInputError(
            f"no camera colour matrix available for method {method!r}; "
            "give a camera profile with a fitted colour matrix"
        )
    name, matrix = candidates[0]
    if not np.all(np.isfinite(matrix)) or matrix[1].sum() <= 0:
        raise BadInputError(f"camera colour matrix from {name} is degenerate")
    return matrix, name


def relative_luminance(rgb, matrix):
    """Relative photopic luminance Y = (M · rgb)_Y of camera RGB ``(rows, cols, 3)``.

    Parameters
    ----------
    rgb : array_like, shape (..., 3)
        Linear camera RGB [–].
    matrix : array_like, shape (3, 3)
        Camera → XYZ matrix.

    Returns
    -------
    ndarray, float32, shape (...)

    Examples
    --------
    >>> relative_luminance([[0.5, 0.5, 0.5]], np.eye(3)).tolist()
    [0.5]
    """
    rgb = np.asarray(rgb)
    weights = np.asarray(matrix, dtype=np.float64)[1]
    return (rgb @ weights.astype(np.float32)).astype(np.float32)
