"""Position index P(σ, τ): how much less a glare source counts away from the line of sight.

Methods (named after their sources, behind :func:`position_index`):

``evalglare`` (default)
    Guth's closed form above the line of sight, Iwata/Osterhaus (CIE 2010) below it, capped
    at 16 — what evalglare ≥ 3.02 computes (FORMULAS.md §2.1–2.2).
``Guth``
    The closed form everywhere (valid for the upper field only), capped at 16.
``Kim2011``
    Kim, Han & Kim's whole-field model, no cap (FORMULAS.md §2.3).

References
----------
Levin, R. E. (1975). Position index in VCP calculations. *J. Illum. Eng. Soc.* 4(2), 99–105
(closed form of Guth's table; IES Lighting Handbook). Iwata, T., Osterhaus, W. (2010),
CIE x034 (below the line of sight). Kim, W., Han, H., Kim, J. T. (2011). *Indoor and
Built Environment* 20(2), doi:10.1177/1420326X10389267. Radiance ``src/util/evalglare.c``
(get_posindex).
"""

import numpy as np

from ..errors import BadInputError

#: Cap of the Guth/Iwata position index (evalglare's default).
POSITION_INDEX_CAP = 16.0

METHODS = ("evalglare", "Guth", "Kim2011")


def position_index_Guth(sigma, tau):
    """Guth position index, Levin's closed form (σ, τ in radians), uncapped.

    Examples
    --------
    >>> round(float(position_index_Guth(np.radians(30), 0.0)), 3)
    3.348
    """
    s = np.degrees(sigma)
    t = np.degrees(tau)
    return np.exp((35.2 - 0.31889 * t - 1.22 * np.exp(-2.0 * t / 9.0)) * 1e-3 * s
                  + (21.0 + 0.26667 * t - 0.002963 * t * t) * 1e-5 * s * s)


def position_index_Iwata(sigma, tau):
    """Iwata/Osterhaus index below the line of sight (σ, τ in radians), uncapped.

    β = arctan(tan σ · √(1 + 0.3225 cos² τ)) [deg], P = exp(6.49·10⁻³·β + 21·10⁻⁵·β²):
    Guth's formula at τ = 90° with the coefficient rounded as evalglare has it
    (FORMULAS.md §2.2; Guth's own bracket at 90° is 35.2 − 0.31889·90 = 6.4999·10⁻³, so the
    two branches meet at the horizontal to within exp(10⁻⁵·σ), 0.06 % at σ = 60°).

    Examples
    --------
    >>> round(float(position_index_Iwata(np.radians(30), np.pi)), 3)
    1.576
    """
    beta = np.degrees(np.arctan(np.tan(sigma) * np.sqrt(1.0 + 0.3225 * np.cos(tau) ** 2)))
    return np.exp(6.49e-3 * beta + 21e-5 * beta * beta)


def position_index_Kim2011(sigma, tau):
    """Kim et al. (2011) whole-field position index (σ, τ in radians), no cap.

    Examples
    --------
    >>> round(float(position_index_Kim2011(np.radians(10), 0.0)), 3)
    0.265
    """
    s = np.degrees(sigma)
    t = np.degrees(tau)
    centre = -9e-6 * t**3 + 0.0014 * t**2 + 0.0866 * t + 21.633
    width = -9e-6 * t**3 + 0.0013 * t**2 + 0.0853 * t + 8.772
    return np.exp((s - centre) / width)


def position_index(sigma, tau, *, method="evalglare"):
    """Position index P [–] of directions at σ, τ [rad] (arrays broadcast).

    Parameters
    ----------
    sigma, tau : array_like
        Angle from the line of sight and angle around it from the upward half-plane [rad];
        τ > 90° is below the line of sight.
    method : {"evalglare", "Guth", "Kim2011"}

    Examples
    --------
    >>> round(float(position_index(np.radians(60), 0.0)), 3)
    16.0
    """
    sigma = np.asarray(sigma, dtype=np.float64)
    tau = np.asarray(tau, dtype=np.float64)
    if method == "Kim2011":
        return position_index_Kim2011(sigma, tau)
    if method == "Guth":
        return np.minimum(position_index_Guth(sigma, tau), POSITION_INDEX_CAP)
    if method == "evalglare":
        below = tau > np.pi / 2
        value = np.where(below, position_index_Iwata(sigma, tau), position_index_Guth(sigma, tau))
        return np.minimum(value, POSITION_INDEX_CAP)
    raise BadInputError(f"unknown position index method {method!r}; valid: {', '.join(METHODS)}")
