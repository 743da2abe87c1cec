"""Field integrals of a luminance map: vertical illuminance, mean and background luminance.

Every function takes per-pixel arrays of the same shape — luminance ``L`` [cd·m⁻²], solid
angle ``ω`` [sr] and ``cos σ = d̂·v̂`` (the cosine of the angle from the line of sight) — and
sums over the *evaluated field*: pixels with a finite luminance, ω > 0 and cos σ ≥ 0 (the
observer's front hemisphere; evalglare likewise drops what lies behind the line of sight).
Sums are taken in float64.

References
----------
CIE 117:1995 *Discomfort glare in interior lighting* (L_b = E_ind/π). Radiance
``src/util/evalglare.c`` (E_v, E_v_dir, av_lum, ``-q`` background modes); FORMULAS.md
§2.4.3 and §2.4.7.
"""

import math

import numpy as np

from .._validation import check_choice

__all__ = [
    "BACKGROUND_METHODS",
    "evaluated_field",
    "vertical_illuminance",
    "mean_luminance",
    "background_luminance",
]

#: Background-luminance definitions (evalglare ``-q 0/1/2``).
BACKGROUND_METHODS = ("CIE", "mean", "Ev")


def evaluated_field(luminance, solid_angle, cos_sigma):
    """Mask of the pixels that take part in field integrals (finite L, ω > 0, cos σ ≥ 0)."""
    return np.isfinite(luminance) & (solid_angle > 0) & (cos_sigma >= 0)


def _masked(values, mask):
    values = np.asarray(values, dtype=np.float64)
    return values.ravel() if mask is None else values[mask]


def _field(luminance, solid_angle, cos_sigma, mask):
    """The selection of pixels to sum: None when it is every pixel (no copies then)."""
    field = evaluated_field(luminance, solid_angle, cos_sigma)
    if mask is not None:
        field &= mask
    return None if field.all() else field


def vertical_illuminance(luminance, solid_angle, cos_sigma, *, mask=None):
    """Illuminance at the eye on the plane facing the line of sight, E_v = Σ L·cos σ·ω [lx].

    ``mask`` restricts the sum further (e.g. to glare-source pixels, giving E_dir).

    Examples
    --------
    A uniform hemisphere of 1 cd·m⁻² gives E_v = π lx; one pixel of it:

    >>> float(vertical_illuminance(np.array([1.0]), np.array([2 * np.pi]), np.array([0.5])))
    3.141592653589793
    """
    field = _field(luminance, solid_angle, cos_sigma, mask)
    # np.sum (pairwise) rather than np.dot: BLAS dot results depend on its thread count.
    return float(np.sum(_masked(luminance, field) * _masked(cos_sigma, field)
                        * _masked(solid_angle, field)))


def mean_luminance(luminance, solid_angle, cos_sigma, *, mask=None):
    """Solid-angle-weighted mean luminance L̄ = Σ L·ω / Σ ω over the field [cd·m⁻²].

    NaN when the field is empty.
    """
    field = _field(luminance, solid_angle, cos_sigma, mask)
    omega = _masked(solid_angle, field)
    total = omega.sum()
    if not total > 0:
        return math.nan
    return float(np.sum(_masked(luminance, field) * omega) / total)


def background_luminance(luminance, solid_angle, cos_sigma, source_mask, *, method="CIE"):
    """Background luminance L_b [cd·m⁻²] for UGR-type indices.

    Parameters
    ----------
    luminance, solid_angle, cos_sigma : ndarray
        Per-pixel L [cd·m⁻²], ω [sr] and cos σ [–].
    source_mask : ndarray of bool
        Glare-source pixels.
    method : {"CIE", "mean", "Ev"}
        ``"CIE"`` (default): (E_v − E_dir)/π with E_dir = Σ_sources L·cos σ·ω (CIE 117's
        indirect illuminance; evalglare ``-q 0``). ``"mean"``: ω-weighted mean luminance of
        the non-source pixels (``-q 1``; L̄ when every pixel is a source). ``"Ev"``: E_v/π
        (``-q 2``).

    Examples
    --------
    A uniform field of 50 cd·m⁻² over the front hemisphere has L_b = 50 in CIE mode
    (E_v = π·50):

    >>> L = np.array([50.0]); w = np.array([2 * np.pi]); c = np.array([0.5])
    >>> round(background_luminance(L, w, c, np.array([False])), 9)
    50.0
    """
    check_choice(method, "background luminance method", BACKGROUND_METHODS)
    source_mask = np.asarray(source_mask, dtype=bool)
    if method == "Ev":
        return vertical_illuminance(luminance, solid_angle, cos_sigma) / math.pi
    if method == "CIE":
        # E_v − E_dir summed directly over the non-source pixels (no cancellation).
        return vertical_illuminance(luminance, solid_angle, cos_sigma, mask=~source_mask) / math.pi
    background = mean_luminance(luminance, solid_angle, cos_sigma, mask=~source_mask)
    if math.isnan(background):
        return mean_luminance(luminance, solid_angle, cos_sigma)
    return background
