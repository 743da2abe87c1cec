"""Veiling luminance of disability glare from grouped glare sources.

Two forms, both as evalglare 3.06 reports them:

``veiling_luminance_Poynter`` (evalglare's ``Lveil``)
    L_veil = 5 · Σ_s L_s·cos σ_s·ω_s / σ_s[deg] [cd·m⁻²], the form evalglare's source calls
    "disability glare according to Poynter": each source's direct illuminance at the eye
    L_s·cos σ_s·ω_s divided by its angle from the line of sight in degrees.
``veiling_luminance_CIE146`` (evalglare's per-source and summed ``Lveil_cie``)
    The Stiles–Holladay equation L_veil = 10 · E_glare/θ² per source, θ [deg] its angle from
    the line of sight and E_glare [lx] the illuminance its pixels give at the eye (Σ L·cos σ·ω
    over the source, evalglare's ``Eglare``). With an observer ``age`` [years] the factor
    1 + (A/70)⁴ of the CIE age-adjusted Stiles–Holladay equation multiplies it (CIE
    146:2002, valid for 1° < θ < 30°); evalglare 3.06 has no age option (its ``-a`` stops
    with "age factor not supported any more"), so without ``age`` the result is evalglare's.

evalglare takes σ and θ at the pixel that holds the source's L·ω-weighted pixel centroid
(its coordinates truncated to integers); the functions here take the angles as given.

References
----------
CIE 146:2002, *CIE equations for disability glare* (age-adjusted Stiles–Holladay
equation); Vos, J. J. (2003), On the cause of disability glare and its dependence on glare
angle, age and ocular pigmentation, Clin. Exp. Optom. 86(6), 363–370. Holladay, L. L.
(1926), The fundamentals of glare and visibility, J. Opt. Soc. Am. 12(4), 271–319. Radiance
``src/util/evalglare.c`` v3.06 (get_disability; ``Lveil_cie`` in the ``-d`` table).
"""

import numpy as np

from .._validation import check_positive

__all__ = ["veiling_luminance_Poynter", "veiling_luminance_CIE146", "age_factor_CIE146"]

#: evalglare's guard against a source on the line of sight (added to σ, and to θ²).
_EPS_SIGMA = 1e-11
_EPS_THETA2 = 1e-16


def veiling_luminance_Poynter(luminance, solid_angle, sigma):
    """Veiling luminance 5·Σ L_s·cos σ_s·ω_s/σ_s[deg] [cd·m⁻²] (evalglare ``Lveil``).

    Parameters
    ----------
    luminance, solid_angle : array_like, shape (n,)
        Per source L_s [cd·m⁻²] and ω_s [sr].
    sigma : array_like, shape (n,)
        Angle of each source from the line of sight [rad].

    Returns
    -------
    float
        0 without sources (as evalglare).

    Examples
    --------
    One source of 10 000 cd·m⁻², 0.01 sr, 10° off the line of sight:

    >>> round(veiling_luminance_Poynter([1e4], [0.01], [np.radians(10)]), 4)
    49.2404

    References
    ----------
    Radiance ``src/util/evalglare.c`` v3.06 (get_disability).
    """
    L, w, s = (np.asarray(a, dtype=np.float64) for a in (luminance, solid_angle, sigma))
    terms = L * np.cos(s + _EPS_SIGMA) * w / (np.degrees(s) + _EPS_SIGMA)
    return float(5.0 * np.sum(terms))


def age_factor_CIE146(age):
    """The CIE age factor 1 + (A/70)⁴ of the age-adjusted Stiles–Holladay equation [–].

    Examples
    --------
    >>> age_factor_CIE146(70)
    2.0

    References
    ----------
    CIE 146:2002; Vos (2003), Clin. Exp. Optom. 86(6), 363–370.
    """
    return 1.0 + (check_positive(age, "age") / 70.0) ** 4


def veiling_luminance_CIE146(illuminance, theta, *, age=None):
    """Veiling luminance of each source, 10·E_glare/θ²·[1 + (A/70)⁴] [cd·m⁻²].

    Parameters
    ----------
    illuminance : array_like, shape (n,)
        E_glare of each source at the eye [lx].
    theta : array_like, shape (n,)
        Angle of each source from the line of sight [rad].
    age : float, optional
        Observer age A [years]; None (default) gives the Stiles–Holladay equation without
        the age factor, as evalglare.

    Returns
    -------
    ndarray, shape (n,)

    Examples
    --------
    >>> veiling_luminance_CIE146([2.0], [np.radians(5.0)]).round(6).tolist()
    [0.8]

    References
    ----------
    CIE 146:2002; Radiance ``src/util/evalglare.c`` v3.06 (``Lveil_cie``).
    """
    e = np.asarray(illuminance, dtype=np.float64)
    t = np.degrees(np.asarray(theta, dtype=np.float64))
    factor = 1.0 if age is None else age_factor_CIE146(age)
    return 10.0 * e / (t * t + _EPS_THETA2) * factor
