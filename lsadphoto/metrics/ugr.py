"""Unified Glare Rating: the CIE formula over grouped sources or over single pixels.

    UGR = 8·log10[(0.25/L_b)·Σ L²·ω/P²]

:func:`ugr_CIE117` evaluates it for any list of sources; :func:`ugr_pixel` is the paper's
pixel-wise variant, in which every glare-source pixel is a source with its own solid angle
and position index. For one source split into pixels of a common P,
Σ_j L_j²ω_j = L̄²Ω(1 + CV²), so pixel-UGR − grouped UGR = 8·log10(1 + CV²) ≥ 0 (FORMULAS.md
§3.1): the two agree for uniform sources and the pixel form rises with non-uniformity.

Undefined cases are NaN, never an exception or a sentinel: no sources (UGR has no value;
evalglare prints 0) and L_b ≤ 0 with sources present (the formula diverges; evalglare
prints −99). The scoring layer reports them as null with the reason.

References
----------
CIE 117:1995, *Discomfort glare in interior lighting*, eq. (1). Scheir, G. H., Hanselaer, P.,
Bracke, P., Deconinck, G., Ryckaert, W. R. (2015), Building and Environment 84, 60–67
(pixel-wise UGR of non-uniform sources). Budak et al. (seed paper, §4).
"""

import math

import numpy as np

__all__ = ["ugr_CIE117", "ugr_from_sum", "ugr_pixel", "ugr_sum"]


def ugr_sum(luminance, solid_angle, position_index):
    """Σ L²·ω/P² over sources [cd²·m⁻⁴·sr], float64; sources with P = NaN count as P = ∞."""
    L = np.asarray(luminance, dtype=np.float64)
    w = np.asarray(solid_angle, dtype=np.float64)
    P = np.asarray(position_index, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        terms = L * L * w / (P * P)
    return float(np.sum(terms[np.isfinite(terms)]))


def ugr_from_sum(total, background_luminance):
    """UGR = 8·log10[(0.25/L_b)·Σ] from the source sum Σ = ΣL²·ω/P² [cd²·m⁻⁴·sr].

    The one formula behind :func:`ugr_CIE117` (Σ over grouped sources) and :func:`ugr_pixel`
    (Σ over source pixels). NaN when L_b ≤ 0 or Σ ≤ 0 (no source: see the module notes).

    Examples
    --------
    >>> round(ugr_from_sum(1e4 ** 2 * 0.01, 100.0), 6)
    27.18352
    """
    if not background_luminance > 0 or not total > 0:
        return math.nan
    return 8.0 * math.log10(0.25 / background_luminance * total)


def ugr_CIE117(luminance, solid_angle, position_index, background_luminance):
    """UGR of sources with luminance L [cd·m⁻²], solid angle ω [sr] and position index P.

    Parameters
    ----------
    luminance, solid_angle, position_index : array_like, shape (n,)
        Per source.
    background_luminance : float
        L_b [cd·m⁻²].

    Returns
    -------
    float
        UGR, or NaN when there is no source or L_b ≤ 0 (see the module notes).

    Examples
    --------
    One source of 10 000 cd·m⁻² and 0.01 sr at P = 1 before a 100 cd·m⁻² background:
    8·log10(0.25·10⁸·0.01/100) = 8·log10(2500):

    >>> round(ugr_CIE117([1e4], [0.01], [1.0], 100.0), 6)
    27.18352
    """
    if np.size(luminance) == 0:
        return math.nan
    return ugr_from_sum(ugr_sum(luminance, solid_angle, position_index), background_luminance)


def ugr_pixel(luminance, solid_angle, position_index, source_mask, background_luminance):
    """Pixel-wise UGR: every glare-source pixel its own source (Budak et al.).

    Parameters
    ----------
    luminance, solid_angle, position_index : ndarray, shape (rows, cols)
        Per pixel: L [cd·m⁻²], ω [sr], P [–].
    source_mask : ndarray of bool, shape (rows, cols)
        Glare-source pixels.
    background_luminance : float
        L_b [cd·m⁻²].

    Returns
    -------
    float
        NaN when no pixel is a source or L_b ≤ 0.
    """
    mask = np.asarray(source_mask, dtype=bool)
    return ugr_CIE117(np.asarray(luminance)[mask], np.asarray(solid_angle)[mask],
                      np.asarray(position_index)[mask], background_luminance)
