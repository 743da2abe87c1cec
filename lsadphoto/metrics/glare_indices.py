"""Glare indices beyond UGR, over grouped sources, as evalglare computes them.

Each function takes per-source arrays — luminance L_s [cd·m⁻²], solid angle ω_s [sr],
position index P_s [–] — and the field quantities it needs. With no sources every index
except DGP has no value and is NaN (evalglare prints 0, and VCP 100); the scoring layer
reports null with the reason. Formulas: FORMULAS.md §2.4.8 and §7, checked against
Radiance ``src/util/evalglare.c``.

References
----------
Wienold, J., Christoffersen, J. (2006), Evaluation methods and development of a new glare
prediction model for daylight environments with the use of CCD cameras, Energy and Buildings
38(7), 743–757 (DGP). Hopkinson, R. G. (1972), Glare from daylighting in buildings, Applied
Ergonomics 3(4), 206–215 (DGI). Fisekis, K., Davies, M., Kolokotroni, M., Langford, P.
(2003), Prediction of discomfort glare from windows, Lighting Res. Technol. 35(4), 360–371
(DGI_mod, UGR_exp). Hirning, M. B., Isoardi, G. L., Cowling, I. (2014), Energy and Buildings
70, 427–440 (UGP); Hirning et al. (2017), Building and Environment 113, 107–120 (UGP2).
Guth, S. K. (1963); IES Lighting Handbook (DGR, VCP). Einhorn, H. D. (1979), Lighting Res.
Technol. 11(2), 90–94 (CGI).
"""

import math

import numpy as np

from .._validation import check_choice
from ..errors import BadInputError
from .ugr import ugr_sum

__all__ = ["DGP_COEFFICIENTS", "dgp_coefficients", "dgp_Wienold2006", "dgi_Hopkinson1972",
           "dgi_mod_Fisekis2003",
           "ugr_exp_Fisekis2003", "ugp_Hirning2014", "ugp2_Hirning2016", "dgr_Guth1963",
           "vcp_Guth1963", "cgi_Einhorn1979"]

#: DGP coefficient sets: (a1, a2, a3, a4, a5, c1, c2, c3). ``"evalglare"`` is the code's
#: default (v3.06); ``"Wienold2006"`` the published paper's values.
DGP_COEFFICIENTS = {
    "evalglare": (2.0, 1.0, 1.87, 2.0, 1.0, 5.87e-5, 0.092, 0.159),
    "Wienold2006": (2.0, 1.0, 1.87, 2.0, 1.0, 5.87e-5, 9.18e-2, 0.16),
}


def dgp_coefficients(coefficients):
    """DGP coefficients (a1, a2, a3, a4, a5, c1, c2, c3) of a named set or given explicitly.

    ``coefficients`` is a name of :data:`DGP_COEFFICIENTS` or eight finite numbers, as
    evalglare's ``-w a1 a2 a3 a4 a5 c1 c2 c3``.

    Examples
    --------
    >>> dgp_coefficients("Wienold2006")[6]
    0.0918
    """
    if isinstance(coefficients, str):
        check_choice(coefficients, "DGP coefficient set", tuple(DGP_COEFFICIENTS))
        return DGP_COEFFICIENTS[coefficients]
    try:
        values = tuple(float(c) for c in coefficients)
    except (TypeError, ValueError):
        values = ()
    if len(values) != 8 or not all(math.isfinite(v) for v in values):
        raise BadInputError("DGP coefficients must be a set name "
                            f"({', '.join(DGP_COEFFICIENTS)}) or eight numbers a1,a2,a3,a4,a5,"
                            f"c1,c2,c3, got {coefficients!r}")
    return values


def _arrays(luminance, solid_angle, position_index):
    return (np.asarray(luminance, dtype=np.float64), np.asarray(solid_angle, dtype=np.float64),
            np.asarray(position_index, dtype=np.float64))


def dgp_Wienold2006(vertical_illuminance, luminance, solid_angle, position_index, *,
                    coefficients="evalglare", low_light_correction=False):
    """Daylight glare probability [–].

    DGP = c1·E_v^a5 + c2·log10(1 + Σ L_s^a1·ω_s^a2/(E_v^a3·P_s^a4)) + c3, capped at 1;
    without sources c1·E_v + c3. ``low_light_correction`` multiplies by
    e^(0.024E_v−4)/(1 + e^(0.024E_v−4)) below 1000 lx (off by default, as in evalglare ≥ 2.14).

    Examples
    --------
    No sources at 2000 lx: 5.87e-5·2000 + 0.159:

    >>> round(dgp_Wienold2006(2000.0, [], [], []), 6)
    0.2764
    """
    a1, a2, a3, a4, a5, c1, c2, c3 = dgp_coefficients(coefficients)
    e_v = float(vertical_illuminance)
    if not e_v > 0:
        return math.nan
    L, w, P = _arrays(luminance, solid_angle, position_index)
    dgp = c1 * e_v**a5 + c3
    if L.size:
        total = float(np.sum(L**a1 * w**a2 / P**a4))
        dgp += c2 * math.log10(1.0 + total / e_v**a3)
    if low_light_correction and e_v < 1000.0:
        x = math.exp(0.024 * e_v - 4.0)
        dgp *= x / (1.0 + x)
    return min(dgp, 1.0)


def dgi_Hopkinson1972(luminance, solid_angle, position_index, background_luminance):
    """Daylight glare index DGI = 10·log10 Σ 0.478·L^1.6·Ω^0.8/(L_b + 0.07·ω^0.5·L), Ω = ω/P²."""
    L, w, P = _arrays(luminance, solid_angle, position_index)
    if L.size == 0:
        return math.nan
    terms = 0.478 * L**1.6 * (w / P**2) ** 0.8 / (background_luminance + 0.07 * np.sqrt(w) * L)
    return 10.0 * math.log10(float(np.sum(terms)))


def dgi_mod_Fisekis2003(luminance, solid_angle, position_index, vertical_illuminance):
    """DGI with L_b replaced by L_a^0.85, L_a = E_v/π (Fisekis et al. 2003)."""
    return dgi_Hopkinson1972(luminance, solid_angle, position_index,
                             (vertical_illuminance / math.pi) ** 0.85)


def ugr_exp_Fisekis2003(luminance, solid_angle, position_index, vertical_illuminance,
                        background_luminance):
    """UGR_exp = 8·log10(E_v/π) + 8·log10(Σ L·ω/P² / L_b), L_b the CIE background."""
    L, w, P = _arrays(luminance, solid_angle, position_index)
    if L.size == 0 or not background_luminance > 0 or not vertical_illuminance > 0:
        return math.nan
    total = float(np.sum(L * w / P**2))
    return 8.0 * math.log10(vertical_illuminance / math.pi) + 8.0 * math.log10(
        total / background_luminance)


def ugp_Hirning2014(luminance, solid_angle, position_index, background_luminance):
    """Unified glare probability UGP = 0.26·log10((0.25/L_b)·Σ L²ω/P²)."""
    if np.size(luminance) == 0 or not background_luminance > 0:
        return math.nan
    return 0.26 * math.log10(0.25 / background_luminance
                             * ugr_sum(luminance, solid_angle, position_index))


def ugp2_Hirning2016(luminance, solid_angle, position_index, background_luminance):
    """UGP2 = [1 + (2/7)·(Σ L²ω/P² / L_b)^(−0.2)]^(−10)."""
    if np.size(luminance) == 0 or not background_luminance > 0:
        return math.nan
    ratio = ugr_sum(luminance, solid_angle, position_index) / background_luminance
    return (1.0 + 2.0 / 7.0 * ratio ** (-0.2)) ** (-10.0)


def dgr_Guth1963(luminance, solid_angle, position_index, adaptation_luminance):
    """Discomfort glare rating DGR = [Σ 0.5·L·Q(ω)/(P·F^0.44)]^(n^−0.0914).

    Q(ω) = 20.4ω + 1.52ω^0.2 − 0.075; F the adaptation luminance (evalglare: the field's
    mean luminance L̄); n the number of sources.
    """
    L, w, P = _arrays(luminance, solid_angle, position_index)
    if L.size == 0 or not adaptation_luminance > 0:
        return math.nan
    q = 20.4 * w + 1.52 * w**0.2 - 0.075
    total = float(np.sum(0.5 * L * q / (P * adaptation_luminance**0.44)))
    return total ** (L.size ** -0.0914)


def vcp_Guth1963(dgr, *, constant=6.374):
    """Visual comfort probability [%] from DGR: 50·erf((c − 1.3227·ln DGR)/√2) + 50.

    c = 6.374 as published (IES Lighting Handbook) and in evalglare since v2.07, whose
    change log records the fix of an earlier 6.347 (pass ``constant=6.347`` to reproduce
    older evalglare results). 100 below DGR = 20 and 0 above 750, as in evalglare.
    """
    if not np.isfinite(dgr):
        return math.nan
    if dgr < 20.0:
        return 100.0
    if dgr > 750.0:
        return 0.0
    return 50.0 * math.erf((constant - 1.3227 * math.log(dgr)) / math.sqrt(2.0)) + 50.0


def cgi_Einhorn1979(luminance, solid_angle, position_index, vertical_illuminance,
                    direct_illuminance):
    """CIE glare index CGI = 8·log10[2·(1 + E_d/500)/(E_d + E_i)·Σ L²ω/P²], E_d + E_i = E_v."""
    if np.size(luminance) == 0 or not vertical_illuminance > 0:
        return math.nan
    total = ugr_sum(luminance, solid_angle, position_index)
    return 8.0 * math.log10(2.0 * (1.0 + direct_illuminance / 500.0) / vertical_illuminance
                            * total)
