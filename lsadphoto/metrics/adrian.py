"""Threshold luminance difference ΔL of a target against its background: Adrian's (1989) model.

Adrian fitted Blackwell's threshold data with an analytic model: for adaptation (background)
luminance L_b [cd·m⁻²] and target size α [arcmin],

    ΔL₀ = k·(√Φ(L_b)/α + √L(L_b))²                       [cd·m⁻²]

with a Ricco function √Φ and a Weber function √L that take different closed forms in three
luminance regimes (L_b ≥ 0.6, 0.00418 < L_b < 0.6, L_b ≤ 0.00418 cd·m⁻²). Factors then correct
for the exposure time t, for negative contrast (target darker than its background) and for
the observer's age A:

    ΔL = ΔL₀ · (a(α, L_b) + t)/t · [F_cp if negative] · AF(A)

Conventions chosen here (FORMULAS.md §4.1 leaves them open):

* **Time factor** — the RP-8-00 convention: (a(α, L_b) + t)/t is applied for every finite t
  and every α, with /2.1 outside the square root (RP-8 errata). TU Berlin's
  ``calcDeltaL.m`` instead skips it for t ≥ 2 s and α ≥ 60′; we do not, so that ΔL is one
  smooth function of t and α. ``exposure_time=np.inf`` gives the factor 1 (t → ∞).
  The default t = 2 s (FORMULAS.md Part A) makes the factor 1.05–1.09.
* **Age factor** — Adrian's fit is for 23 ≤ A ≤ 75 years; ages outside raise
  :class:`~lsadphoto.errors.BadInputError` (the quadratic fit is not extrapolated; pass 23
  for younger observers: AF(23) = 0.997). ``age=None`` leaves the factor out (AF ≡ 1, the
  basic model of Blackwell's young observers).
* **Negative contrast** — F_cp as in RP-8-00, with the positive threshold at t = 2 s in its
  denominator and F_cp = 0.5 for log10 L_b ≤ −2.4, for both constant sets.
* **L_b = 0** — the model is a fit in log10 L_b and has no value in darkness: ΔL is NaN
  there (NaN means "unknown" throughout lsadphoto). Negative or infinite L_b is bad input;
  NaN in gives NaN out.

Known properties of the model (checked in ``tests/test_adrian.py``):

* The regime formulas join to about 1 % in √Φ and √L (1.04 % and 0.55 % at 0.6 cd·m⁻²);
  ΔL₀, their square, drops by 1.1–2.0 % across 0.6 cd·m⁻² as L_b rises (2.0 % at α = 1′,
  1.7 % at 10′) and changes by at most 1.1 % across 0.00418 cd·m⁻².
* In the middle regime the Ricco function has a minimum at log10 L_b = −1.947
  (L_b = 0.0113 cd·m⁻²), so for small targets (α ≲ 10′) ΔL *falls* slightly with rising L_b
  between 0.00418 and about 0.01 cd·m⁻² (−5.4 % at α = 1′). Above 0.6 cd·m⁻² ΔL rises
  with L_b and falls with α, as expected.

References
----------
Adrian, W. (1989). Visibility of targets: model for calculation. *Lighting Research and
Technology* 21(4), 181–188.
ANSI/IESNA RP-8-00 (2000), *American National Standard Practice for Roadway Lighting*,
Annex A (small target visibility) and its errata.
TU Berlin FG Lichttechnik, VisibilityLevel-Evaluation-MATLAB, ``helper/measures/calcDeltaL.m``
("as published in Adrian89") and ``calcDeltaL_RP800.m`` ("as published in ANSI IESNA RP 800").
Blackwell, H. R. (1946). Contrast thresholds of the human eye. *J. Opt. Soc. Am.* 36(11),
624–643. FORMULAS.md §4.
"""

import math

import numpy as np

from .._validation import check_choice, check_positive
from ..errors import BadInputError

__all__ = [
    "DEFAULT_K",
    "METHODS",
    "threshold_Adrian1989",
    "threshold_luminance_difference",
    "weber_limit_Adrian1989",
]

#: Probability factor k of Adrian's model (2.6: RP-8 small-target visibility convention).
DEFAULT_K = 2.6

#: Methods of :func:`threshold_luminance_difference`.
METHODS = ("Adrian1989", "Weber")

#: Constant sets: the first Ricco constant, the a(α) denominator constant, and the age-factor
#: centre and branch rule. "RP-8-00" follows ANSI/IESNA RP-8-00 as coded in TU Berlin's
#: ``calcDeltaL_RP800.m`` (4.2841, 2.789, 56.5, first age branch up to and including 64).
_CONSTANTS = {
    "Adrian1989": {"ricco": 4.1925, "a_alpha": 2.7895, "age_centre": 56.6, "age_64_first": False},
    "RP-8-00": {"ricco": 4.2841, "a_alpha": 2.789, "age_centre": 56.5, "age_64_first": True},
}

#: Regime boundaries of the model [cd·m⁻²].
_PHOTOPIC = 0.6
_SCOTOPIC = 0.00418

#: Ages covered by Adrian's age factor [years].
_AGE_RANGE = (23.0, 75.0)


def _luminance(value, name="adaptation_luminance"):
    try:
        L = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise BadInputError(f"{name} is not a numeric array") from None
    if np.any(L < 0):
        raise BadInputError(f"{name} must be ≥ 0 cd/m², got a minimum of {np.nanmin(L)!r}")
    if np.any(np.isinf(L)):
        raise BadInputError(f"{name} contains infinite values")
    return L


def _size(value):
    try:
        alpha = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise BadInputError("size_arcmin is not a numeric array") from None
    if not np.all(np.isfinite(alpha) & (alpha > 0)):
        raise BadInputError("size_arcmin must be finite and > 0 arcmin "
                            "(use weber_limit_Adrian1989 for the α → ∞ limit)")
    return alpha


def _ricco_weber(L, ricco):
    """√Φ and √L of the three regimes (L > 0; NaN elsewhere)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ell = np.log10(np.where(L > 0, L, np.nan))
        photopic = L >= _PHOTOPIC
        scotopic = L <= _SCOTOPIC
        sqrt_phi = np.where(
            photopic, np.log10(ricco * L ** 0.1556) + 0.1684 * L ** 0.5867,
            np.where(scotopic, 10.0 ** (0.028 + 0.173 * ell),
                     10.0 ** (-0.072 + 0.3372 * ell + 0.0866 * ell * ell)))
        sqrt_l = np.where(
            photopic, 0.05946 * L ** 0.466,
            np.where(scotopic, 10.0 ** (-0.891 + 0.5275 * ell + 0.0227 * ell * ell),
                     10.0 ** (-1.256 + 0.319 * ell)))
    return sqrt_phi, sqrt_l, ell


def _time_constant(alpha, ell, a_alpha_constant):
    """a(α, L_b) = √(a(α)² + a(L)²)/2.1 of the exposure-time factor (RP-8 errata form)."""
    B = np.log10(alpha) + 0.523
    C = ell + 6.0
    a_alpha = 0.36 - 0.0972 * B * B / (B * B - 2.513 * B + a_alpha_constant)
    a_lum = 0.355 - 0.1217 * C * C / (C * C - 10.4 * C + 52.28)
    return np.sqrt(a_alpha * a_alpha + a_lum * a_lum) / 2.1


def _age_factor(age, constants):
    if age is None:
        return 1.0
    age = check_positive(age, "age")
    low, high = _AGE_RANGE
    if not low <= age <= high:
        raise BadInputError(f"age must be within {low:g}–{high:g} years (the range of Adrian's "
                            f"age factor; use 23 for younger observers), got {age!r}")
    first = age <= 64 if constants["age_64_first"] else age < 64
    if first:
        return (age - 19.0) ** 2 / 2160.0 + 0.99
    return (age - constants["age_centre"]) ** 2 / 116.3 + 1.43


def threshold_Adrian1989(adaptation_luminance, size_arcmin, *, exposure_time=2.0, age=23,
                         polarity="positive", k=DEFAULT_K, constant="Adrian1989"):
    """Threshold luminance difference ΔL [cd·m⁻²] of Adrian's (1989) visibility model.

    Vectorised: ``adaptation_luminance`` and ``size_arcmin`` broadcast against each other.

    Parameters
    ----------
    adaptation_luminance : array_like
        Adaptation (background) luminance L_b [cd·m⁻²], ≥ 0. NaN gives NaN; 0 gives NaN (the
        model has no value in darkness).
    size_arcmin : array_like
        Angular size α of the target [arcmin], finite and > 0.
    exposure_time : float
        Observation time t [s], > 0; ``np.inf`` leaves out the time factor. Default 2 s.
    age : float or None
        Observer age A [years], 23–75; None leaves out the age factor. Default 23.
    polarity : {"positive", "negative"}
        Target brighter ("positive") or darker ("negative") than its background.
    k : float
        Probability factor, > 0 (2.6: 99.9 % detection, RP-8 convention).
    constant : {"Adrian1989", "RP-8-00"}
        Constant set: Adrian's paper (Ricco constant 4.1925, a(α) constant 2.7895, age centre
        56.6) or RP-8-00 as printed (4.2841, 2.789, 56.5; changes ΔL by 0.2 % at
        100 cd·m⁻², 10′).

    Returns
    -------
    ndarray or numpy.float64
        ΔL [cd·m⁻²], the broadcast shape of the two inputs (a scalar for scalar inputs).

    Notes
    -----
    See the module docstring for the chosen conventions (time factor applied for every t,
    ages outside 23–75 rejected, F_cp as in RP-8-00) and the model's known quirks.

    References
    ----------
    Adrian, W. (1989). *Lighting Res. Technol.* 21(4), 181–188. ANSI/IESNA RP-8-00, Annex A.
    FORMULAS.md §4.1–4.2.

    Examples
    --------
    FORMULAS.md §4.2: ΔL₀ = 1.891 cd·m⁻² at 100 cd·m⁻², 10′; the time factor at 2 s is 1.052
    and AF(23) = 0.997:

    >>> round(float(threshold_Adrian1989(100.0, 10.0, exposure_time=np.inf, age=None)), 4)
    1.891
    >>> round(float(threshold_Adrian1989(100.0, 10.0, age=None)), 3)
    1.99
    >>> round(float(threshold_Adrian1989(100.0, 4.0, exposure_time=0.2, age=60)), 2)
    14.49
    """
    constants = _CONSTANTS[check_choice(constant, "constant", tuple(_CONSTANTS))]
    check_choice(polarity, "polarity", ("positive", "negative"))
    k = check_positive(k, "k")
    try:
        t = float(exposure_time)
    except (TypeError, ValueError):
        raise BadInputError(f"exposure_time must be a number, got {exposure_time!r}") from None
    if not t > 0:  # also rejects NaN
        raise BadInputError(f"exposure_time must be > 0 s (np.inf: no time factor), got {exposure_time!r}")
    age_factor = _age_factor(age, constants)
    L = _luminance(adaptation_luminance)
    alpha = _size(size_arcmin)
    L, alpha = np.broadcast_arrays(L, alpha)

    sqrt_phi, sqrt_l, ell = _ricco_weber(L, constants["ricco"])
    basic = k * (sqrt_phi / alpha + sqrt_l) ** 2
    with np.errstate(invalid="ignore"):
        a = _time_constant(alpha, ell, constants["a_alpha"])
    delta = basic if math.isinf(t) else basic * (a + t) / t
    if polarity == "negative":
        with np.errstate(invalid="ignore", divide="ignore"):
            factor = np.where(L >= 0.1, 0.125, 0.075)
            m = 10.0 ** (-(10.0 ** (-(factor * (ell + 1.0) ** 2 + 0.0245))))
            beta = 0.6 * L ** -0.1488
            f_cp = 1.0 - m * alpha ** (-beta) / (2.4 * basic * (a + 2.0) / 2.0)
            f_cp = np.where(ell <= -2.4, 0.5, f_cp)
        delta = delta * f_cp
    delta = delta * age_factor
    return delta[()] if delta.ndim == 0 else delta


def weber_limit_Adrian1989(adaptation_luminance, *, k=DEFAULT_K):
    """Large-target (α → ∞) limit of Adrian's ΔL₀: k·(√L(L_b))² [cd·m⁻²].

    The Ricco term √Φ/α vanishes and the Weber function alone remains: in the photopic
    regime ΔL = k·0.05946²·L_b^0.932, a threshold contrast ΔL/L_b of about 0.67 % at
    100 cd·m⁻². No time or age factor is applied (the t → ∞ basic model).

    Parameters
    ----------
    adaptation_luminance : array_like
        L_b [cd·m⁻²], ≥ 0 (0 gives NaN, as in :func:`threshold_Adrian1989`).
    k : float
        Probability factor, > 0.

    Returns
    -------
    ndarray or numpy.float64
        ΔL [cd·m⁻²].

    References
    ----------
    Adrian, W. (1989). *Lighting Res. Technol.* 21(4), 181–188. FORMULAS.md §4.2
    ("Large-target (Weber) limit").

    Examples
    --------
    >>> round(float(weber_limit_Adrian1989(100.0)), 3)
    0.672
    """
    k = check_positive(k, "k")
    L = _luminance(adaptation_luminance)
    _, sqrt_l, _ = _ricco_weber(L, _CONSTANTS["Adrian1989"]["ricco"])
    delta = k * sqrt_l ** 2
    return delta[()] if delta.ndim == 0 else delta


def threshold_luminance_difference(adaptation_luminance, size_arcmin=None, *, method="Adrian1989",
                                   **options):
    """Threshold luminance difference ΔL [cd·m⁻²] by the named method.

    Parameters
    ----------
    adaptation_luminance : array_like
        L_b [cd·m⁻²].
    size_arcmin : array_like, optional
        Target size α [arcmin]; required by "Adrian1989", unused by "Weber" (α → ∞).
    method : {"Adrian1989", "Weber"}
        :func:`threshold_Adrian1989` or :func:`weber_limit_Adrian1989`.
    **options
        Keyword options of the chosen function; an option it does not take is an error.

    References
    ----------
    See :func:`threshold_Adrian1989` and :func:`weber_limit_Adrian1989`.

    Examples
    --------
    >>> round(float(threshold_luminance_difference(100.0, 10.0, exposure_time=np.inf, age=None)), 3)
    1.891
    >>> round(float(threshold_luminance_difference(100.0, method="Weber")), 3)
    0.672
    """
    check_choice(method, "threshold method", METHODS)
    if method == "Weber":
        unknown = sorted(set(options) - {"k"})
        if unknown:
            raise BadInputError(f"option(s) {', '.join(unknown)} do not apply to method 'Weber'; valid: k")
        return weber_limit_Adrian1989(adaptation_luminance, **options)
    allowed = {"exposure_time", "age", "polarity", "k", "constant"}
    unknown = sorted(set(options) - allowed)
    if unknown:
        raise BadInputError(f"option(s) {', '.join(unknown)} do not apply to method 'Adrian1989'; "
                            f"valid: {', '.join(sorted(allowed))}")
    if size_arcmin is None:
        raise BadInputError("method 'Adrian1989' needs size_arcmin")
    return threshold_Adrian1989(adaptation_luminance, size_arcmin, **options)
