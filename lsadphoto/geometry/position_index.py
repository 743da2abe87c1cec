"""Position index P(σ, τ): how much less a glare source counts away from the line of sight.

Methods (named after their sources, behind :func:`position_index`):

``evalglare`` (default)
    Guth's closed form above the line of sight, Iwata/Osterhaus (CIE 2010) below it, capped
    at 16 — what evalglare ≥ 3.02 computes (FORMULAS.md §2.1–2.2).
``Guth``
    The closed form everywhere (valid for the upper field only), capped at 16.
``Kim2011``
    Kim, Han & Kim's whole-field model, no cap (FORMULAS.md §2.3).

Edge cases, defined here and tested:

* σ = 0 (on the line of sight): P = 1 for every τ and method but Kim2011.
* The seam τ = 90° (φ = 0, horizontal through the line of sight) belongs to the upper field
  (Guth), as in evalglare, which moves φ = 0 to +10⁻⁵ rad before testing φ < 0. The two
  branches meet there to 0.06 % (evalglare's rounded 6.49·10⁻³ against Guth's 6.4999·10⁻³).
* Behind the observer (σ > 90°): evalglare's ``atan(tan σ·…)`` flips β to negative angles
  and would make a source behind the observer count almost as much as one ahead (P ≈ 1.5
  at σ = 120°, τ = 180°); evalglare itself never meets such pixels for ``-vta`` (it drops
  them as invalid). Here β = atan2(sin σ·√(1 + 0.3225 cos² τ), cos σ), which equals
  evalglare's β for σ < 90° and continues it smoothly to 180°, so P keeps growing and
  reaches the cap 16 by σ ≈ 100.5° below the line of sight (and sooner above it). The
  "evalglare" and "Guth" methods therefore give P = 16 for all σ ≥ 100.5°, as raytools
  does behind the viewer; Kim2011 is left uncapped.

:func:`guth_field_mask` gives evalglare's cut of the visual field to Guth's field of view
(``-G 1`` / ``-G 2``, FORMULAS.md §2.4.9).

References
----------
Levin, R. E. (1975). Position index in VCP calculations. *J. Illum. Eng. Soc.* 4(2), 99–105
(closed form of Guth's table; IES Lighting Handbook). Iwata, T., Osterhaus, W. (2010),
CIE x034 (below the line of sight). Kim, W., Han, H., Kim, J. T. (2011). *Indoor and
Built Environment* 20(2), doi:10.1177/1420326X10389267. Radiance ``src/util/evalglare.c``
(get_posindex; get_upper_cut_2eyes, get_lower_cut_2eyes, get_lower_cut_central,
cut_view_1, cut_view_2). S. K. Guth, "A method for the evaluation of discomfort glare",
*Illuminating Engineering* 58(5), 1963, 351–364 (field of view). Raytools
``raytools/evaluate/positionindex.py`` (P = 16 behind the viewer).
"""

import numpy as np

from ..errors import BadInputError

#: Cap of the Guth/Iwata position index (evalglare's default).
POSITION_INDEX_CAP = 16.0

METHODS = ("evalglare", "Guth", "Kim2011")

__all__ = [
    "METHODS", "POSITION_INDEX_CAP", "guth_field_mask", "position_index", "position_index_Guth",
    "position_index_Iwata", "position_index_Kim2011", "position_index_from_components",
]


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


def _iwata(beta):
    """exp(6.49·10⁻³·β + 21·10⁻⁵·β²), β in radians."""
    b = np.degrees(beta)
    return np.exp(6.49e-3 * b + 21e-5 * b * b)


def position_index_Iwata(sigma, tau):
    """Iwata/Osterhaus index below the line of sight (σ, τ in radians), uncapped.

    β = arctan(tan σ · √(1 + 0.3225 cos² τ)) [deg], P = exp(6.49·10⁻³·β + 21·10⁻⁵·β²):
    Guth's formula at τ = 90° with the coefficient rounded as evalglare has it
    (FORMULAS.md §2.2; Guth's own bracket at 90° is 35.2 − 0.31889·90 = 6.4999·10⁻³, so the
    two branches meet at the horizontal to within exp(10⁻⁵·σ), 0.06 % at σ = 60°). β is
    evaluated as atan2(sin σ·√(1 + 0.3225 cos² τ), cos σ), the same for σ < 90° and
    continuous behind the observer (see the module notes).

    Examples
    --------
    >>> round(float(position_index_Iwata(np.radians(30), np.pi)), 3)
    1.576
    """
    sigma = np.asarray(sigma, dtype=np.float64)
    tau = np.asarray(tau, dtype=np.float64)
    cos_tau = np.cos(tau)
    return _iwata(np.arctan2(np.sin(sigma) * np.sqrt(1.0 + 0.3225 * cos_tau * cos_tau), np.cos(sigma)))


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


def _dispatch(sigma, tau, method, iwata):
    if method == "Kim2011":
        return position_index_Kim2011(sigma, tau)
    if method == "Guth":
        return np.minimum(position_index_Guth(sigma, tau), POSITION_INDEX_CAP)
    if method == "evalglare":
        # Each branch is evaluated only where it applies (half the work on a full field).
        below = tau > np.pi / 2
        if below.ndim == 0 or below.all() or not below.any():
            value = iwata(None) if np.all(below) else position_index_Guth(sigma, tau)
        else:
            sigma, tau = np.broadcast_arrays(sigma, tau)
            value = np.empty(below.shape)
            above = ~below
            value[above] = position_index_Guth(sigma[above], tau[above])
            value[below] = iwata(below)
        return np.minimum(value, POSITION_INDEX_CAP)
    raise BadInputError(f"unknown position index method {method!r}; valid: {', '.join(METHODS)}")


def position_index(sigma, tau, *, method="evalglare"):
    """Position index P [–] of directions at σ, τ [rad] (arrays broadcast).

    Parameters
    ----------
    sigma, tau : array_like
        Angle from the line of sight and angle around it from the upward half-plane [rad];
        τ > 90° is below the line of sight. NaN gives NaN.
    method : {"evalglare", "Guth", "Kim2011"}

    Returns
    -------
    numpy.ndarray
        P [–], float64. See the module notes for σ = 0, τ = 90° and σ > 90°.

    References
    ----------
    FORMULAS.md §2.1–2.3; Radiance ``src/util/evalglare.c`` (get_posindex).

    Examples
    --------
    >>> round(float(position_index(np.radians(60), 0.0)), 3)
    16.0
    """
    sigma = np.asarray(sigma, dtype=np.float64)
    tau = np.asarray(tau, dtype=np.float64)
    def iwata(mask):
        if mask is None:
            return position_index_Iwata(sigma, tau)
        s, t = np.broadcast_arrays(sigma, tau)
        return position_index_Iwata(s[mask], t[mask])

    return _dispatch(sigma, tau, method, iwata)


def position_index_from_components(forward, up, side, sigma, tau, *, method="evalglare"):
    """:func:`position_index` from a direction's components along v̂, û, ĥ (and its σ, τ).

    Used for whole images (:func:`~lsadphoto.geometry.field.visual_field`): Iwata's β is
    atan2(√(side² + 1.3225·up²), forward), the same angle as in
    :func:`position_index_Iwata` (tan σ·cos τ = up/forward, tan σ·sin τ = side/forward)
    with one arc tangent instead of four trigonometric functions; equal to it to rounding.
    """
    def iwata(mask):
        f, u, h = (forward, up, side) if mask is None else (forward[mask], up[mask], side[mask])
        return _iwata(np.arctan2(np.sqrt(h * h + 1.3225 * (u * u)), f))

    return _dispatch(sigma, tau, method, iwata)


#: Fields of view of :func:`guth_field_mask` (evalglare ``-G`` types).
GUTH_FIELDS = (1, 2)


def guth_upper_border_total(tau_deg):
    """Upper border σ_max [deg] of evalglare's total field (``-G 1``) at τ [deg] < 90°.

    (7.7458218 + 5.7407915·10⁻⁴τ − 2.1746318·10⁻⁴τ² + 8.5572726·10⁻⁶τ³)²; 59.998° at τ = 0.
    """
    t = np.asarray(tau_deg, dtype=np.float64)
    return (7.7458218 + t * (5.7407915e-4 + t * (-2.1746318e-4 + t * 8.5572726e-6))) ** 2


def guth_lower_border_total(tau_deg):
    """Lower border σ_max [deg] of the total field (``-G 1``) at τ [deg] > 135°.

    −1/(−0.014699242 − 1.5541106·10⁻⁵t′ + 4.6898068·10⁻⁶t′² − 5.1539687·10⁻⁸t′³) with
    t′ = 180° − τ (evalglare's get_lower_cut_2eyes returns the negative value and compares
    it with −σ); 68.03° at τ = 180°.
    """
    t = 180.0 - np.asarray(tau_deg, dtype=np.float64)
    return -1.0 / (-0.014699242 + t * (-1.5541106e-5 + t * (4.6898068e-6 + t * -5.1539687e-8)))


def guth_lower_border_central(tau_deg):
    """Lower border σ_max [deg] of the central field (``-G 2``) at τ [deg] ≥ 90°.

    (68.227109 − 2.9524084t′ + 0.046674262t′²)/(1 − 0.042317294t′ + 7.5698419·10⁻⁴t′²
    − 6.5364285·10⁻⁷t′³) with t′ = 180° − τ, and 60° for t′ > 73° (where the fraction
    reaches 59.998°); 68.23° at τ = 180°.
    """
    t = 180.0 - np.asarray(tau_deg, dtype=np.float64)
    value = (68.227109 + t * (-2.9524084 + t * 0.046674262)) / (
        1.0 + t * (-0.042317294 + t * (7.5698419e-4 + t * -6.5364285e-7)))
    return np.where(t > 73.0, 60.0, value)


def guth_field_mask(sigma, tau, *, kind=1):
    """True for directions inside Guth's field of view as evalglare cuts it (``-G kind``).

    Parameters
    ----------
    sigma, tau : array_like
        Visual angles σ, τ [rad] (arrays broadcast); NaN gives False.
    kind : {1, 2}
        1: evalglare's "total field" (cut_view_1): above the line of sight (τ < 90°)
        σ ≤ :func:`guth_upper_border_total`; below it, only for τ > 135°,
        σ ≤ :func:`guth_lower_border_total`, and no cut for 90° ≤ τ ≤ 135°.
        2: the "central field" (cut_view_2): σ ≤ 60° above the line of sight; below it
        σ ≤ :func:`guth_lower_border_central`.

    Returns
    -------
    numpy.ndarray of bool

    Notes
    -----
    As in evalglare, "above" means φ > 0, i.e. τ < 90°; the seam τ = 90° belongs to the lower
    part. A direction exactly on a border counts as inside (evalglare cuts σ > border).
    The borders are evalglare's polynomial fits (degrees), used as they are; the upper
    border of type 1 rises steeply towards the horizontal (78° at τ = 60°, 151° at τ = 90°),
    so near the horizon type 1 cuts only behind the observer.

    References
    ----------
    Radiance ``src/util/evalglare.c`` (cut_view_1, cut_view_2, get_upper_cut_2eyes,
    get_lower_cut_2eyes, get_lower_cut_central), v3.06; FORMULAS.md §2.4.9.
    S. K. Guth, *Illuminating Engineering* 58(5), 1963, 351–364.

    Examples
    --------
    >>> sigma = np.radians([59.0, 61.0, 67.0, 69.0])
    >>> guth_field_mask(sigma, np.radians([0.0, 0.0, 180.0, 180.0])).tolist()
    [True, False, True, False]
    """
    if kind not in GUTH_FIELDS:
        raise BadInputError(f"unknown Guth field kind {kind!r}; valid: 1 (total), 2 (central)")
    s = np.degrees(np.asarray(sigma, dtype=np.float64))
    t = np.degrees(np.asarray(tau, dtype=np.float64))
    upper = t < 90.0
    with np.errstate(invalid="ignore", divide="ignore"):
        if kind == 1:
            inside_upper = s <= guth_upper_border_total(t)
            inside_lower = (t <= 135.0) | (s <= guth_lower_border_total(t))
        else:
            inside_upper = s <= 60.0
            inside_lower = s <= guth_lower_border_central(t)
    return np.where(upper, inside_upper, inside_lower) & np.isfinite(s) & np.isfinite(t)
