"""Compiled (numba) kernels of the per-pixel geometry maps of :mod:`~lsadphoto.geometry.field`.

One pass over the image computes, per pixel, what the numpy reference methods compute in
many full-frame passes: the direction of its centre, the directions of its corners (each
corner once, shared by the four pixels that meet there), its solid angle and validity; a
second pass gives σ, τ, cos σ and the position index. Rows are distributed over threads
(``prange``); the kernels are compiled on first use and cached on disk (``cache=True``).

Numerics: IEEE float64 throughout, no ``fastmath`` (no reassociation, no contraction into
fused multiply–adds), the same operations in the same order as the numpy reference
methods — for the ideal fisheye the maps equal :meth:`IdealFisheyeProjection.directions`
and :meth:`~IdealFisheyeProjection.solid_angles` bit for bit (tested). Two libm functions
are replaced by branch-free Cephes approximations so that loops run on SIMD lanes: tan in
the OpenCV (Kannala–Brandt) directions (:func:`tan_half_range`) and atan2 in σ, τ and
Iwata's β (:func:`atan2_nonnegative`), each within a few ulp of libm (tested), far inside
the tolerances to which the maps are tested (1e-11 for OpenCV directions, 1e-14 rad for
σ, τ). ``error_model="numpy"`` makes x/0 give ±inf or NaN as in numpy instead of raising,
which also lets the compiler vectorise the loops. Loops that call libm (tan, exp) are kept
apart from the vectorised ones. Small helpers are inlined at the numba level only where a
vectorised loop needs them (compile time: about 15 s for these kernels on first use in a
fresh installation, then loaded from the on-disk cache).

References
----------
A. Van Oosterom & J. Strackee, IEEE Trans. Biomed. Eng. BME-30(2), 1983, 125–126 (solid
angle of a triangle). FORMULAS.md §2.1–2.4 (directions, position index, pixel solid angles).
"""

import math

import numpy as np
from numba import njit, prange

__all__ = [
    "FISHEYE_KINDS",
    "IDEAL_FISHEYE",
    "OPENCV_FISHEYE",
    "POSITION_INDEX_METHODS",
    "atan2_nonnegative",
    "fisheye_geometry",
    "quad_solid_angle_grid",
    "tan_half_range",
    "visual_field_maps",
]

#: Model codes of :func:`fisheye_geometry`.
IDEAL_FISHEYE, OPENCV_FISHEYE = 0, 1
#: Kind codes of the ideal fisheye (index into this tuple).
FISHEYE_KINDS = ("equidistant", "equisolid", "orthographic", "stereographic")
#: Method codes of :func:`visual_field_maps` (index into this tuple).
POSITION_INDEX_METHODS = ("evalglare", "Guth", "Kim2011")

_OPTIONS = {"cache": True, "error_model": "numpy", "nogil": True}
#: Below this tan(Ω/2) the arc tangent is its 3-term series (as in field.py).
_SERIES_LIMIT = 1e-3
_TWO_PI = 2.0 * math.pi
_DEGREES = 180.0 / math.pi
#: Newton tolerance and iteration cap of OpenCVFisheyeProjection.theta (opencv.py).
_KB_TOL = 1e-12
_KB_MAX_ITER = 100


# --- solid angle of one pixel ---------------------------------------------------------------

@njit(inline="always", **_OPTIONS)
def _quad_tangent(a0, a1, a2, b0, b1, b2, c0, c1, c2, e0, e1, e2):
    """Numerator and denominator of tan(Ω/2) for the geodesic quad a, b, c, e (unit
    vectors), split into the triangles abc and ace (Van Oosterom & Strackee, with the
    stable edge-vector triple products): the operations of
    :func:`~lsadphoto.geometry.field.quad_solid_angle_components`, in the same order."""
    ac = a0 * c0 + a1 * c1 + a2 * c2
    p0, p1, p2 = b0 - a0, b1 - a1, b2 - a2
    q0, q1, q2 = c0 - a0, c1 - a1, c2 - a2
    r0, r1, r2 = e0 - a0, e1 - a1, e2 - a2
    n1 = abs(a0 * (p1 * q2 - p2 * q1) + a1 * (p2 * q0 - p0 * q2) + a2 * (p0 * q1 - p1 * q0))
    d1 = 1.0 + (a0 * b0 + a1 * b1 + a2 * b2) + (b0 * c0 + b1 * c1 + b2 * c2) + ac
    n2 = abs(a0 * (q1 * r2 - q2 * r1) + a1 * (q2 * r0 - q0 * r2) + a2 * (q0 * r1 - q1 * r0))
    d2 = 1.0 + ac + (c0 * e0 + c1 * e1 + c2 * e2) + (e0 * a0 + e1 * a1 + e2 * a2)
    return n1 * d2 + n2 * d1, d1 * d2 - n1 * n2


@njit(inline="always", **_OPTIONS)
def _series(t):
    """2·atan(t) by its series, accurate to rounding for t < :data:`_SERIES_LIMIT`."""
    t2 = t * t
    return 2.0 * t * (1.0 - t2 * (1.0 / 3.0 - t2 * 0.2))


@njit(**_OPTIONS)
def _quad(a0, a1, a2, b0, b1, b2, c0, c1, c2, e0, e1, e2):
    """Solid angle [sr] of the geodesic quad a, b, c, e (unit vectors)."""
    num, den = _quad_tangent(a0, a1, a2, b0, b1, b2, c0, c1, c2, e0, e1, e2)
    t = num / den
    if den > 0 and t < _SERIES_LIMIT:
        return _series(t)
    half = math.atan2(num, den)
    if half < 0:
        half += _TWO_PI
    return 2.0 * half


@njit(inline="always", **_OPTIONS)
def _quad_series(a0, a1, a2, b0, b1, b2, c0, c1, c2, e0, e1, e2):
    """:func:`_quad` where it takes the series (tan(Ω/2) < 10⁻³, every pixel of a real
    image), else −1: branch-free, so that a loop over a row runs on SIMD lanes; equal to
    :func:`_quad` bit for bit where it is not −1."""
    num, den = _quad_tangent(a0, a1, a2, b0, b1, b2, c0, c1, c2, e0, e1, e2)
    t = num / den
    series = _series(t)
    return series if (den > 0) & (t < _SERIES_LIMIT) else -1.0


# Cephes atan (S. L. Moshier, Cephes Math Library 2.8, atan.c): rational approximation
# atan(x) = x + x·z·P(z)/Q(z), z = x², on [0, 0.66], and π/4 + atan((x − 1)/(x + 1)) above;
# peak relative error 2.2e-16 (Moshier's test, IEEE double).
_AT_P0, _AT_P1, _AT_P2, _AT_P3, _AT_P4 = (
    -8.750608600031904122785e-01, -1.615753718733365076637e01, -7.500855792314704667340e01,
    -1.228866684490136173410e02, -6.485021904942025371773e01)
_AT_Q0, _AT_Q1, _AT_Q2, _AT_Q3, _AT_Q4 = (
    2.485846490142306297962e01, 1.650270098316988542046e02, 4.328810604912902668951e02,
    4.853903996359136964868e02, 1.945506571482613964425e02)
#: π/2 − fl(π/2): the bits of π/2 beyond double precision (Cephes MOREBITS).
_MOREBITS = 6.123233995736765886130e-17
_PIO4 = math.pi / 4.0
_PIO2 = math.pi / 2.0


@njit(inline="always", **_OPTIONS)
def atan2_nonnegative(y, x):
    """atan2(y, x) [rad] for y ≥ 0 (result in [0, π]), branch-free so that loops vectorise.

    Cephes' atan of min/max(|x|, y) ∈ [0, 1], reflected to π/2 − · and π − · with the
    constants' lost bits added back; within 2 ulp of ``math.atan2`` (tested against it).
    NaN in, NaN out; atan2(0, 0) = 0.
    """
    ax = abs(x)
    swap = y > ax
    hi = y if swap else ax
    lo = ax if swap else y
    a = lo / hi if hi != 0 else 0.0
    big = a > 0.66
    xr = (a - 1.0) / (a + 1.0) if big else a
    z = xr * xr
    p = (((_AT_P0 * z + _AT_P1) * z + _AT_P2) * z + _AT_P3) * z + _AT_P4
    q = ((((z + _AT_Q0) * z + _AT_Q1) * z + _AT_Q2) * z + _AT_Q3) * z + _AT_Q4
    r = xr + xr * (z * p / q)
    r = (_PIO4 + (r + 0.5 * _MOREBITS)) if big else r
    r = ((_PIO2 - r) + _MOREBITS) if swap else r
    return ((2.0 * _PIO2 - r) + 2.0 * _MOREBITS) if x < 0 else r


@njit(**_OPTIONS)
def quad_solid_angle_grid(gx, gy, gz, out):
    """Solid angles ``out`` (n, m) of the pixels whose corner directions are the grid
    ``(gx, gy, gz)``, each (n + 1, m + 1); NaN corners give NaN. Serial, without the GIL
    (callers run blocks on threads)."""
    rows, cols = out.shape
    for i in range(rows):
        for j in range(cols):
            out[i, j] = _quad(gx[i, j], gy[i, j], gz[i, j], gx[i, j + 1], gy[i, j + 1], gz[i, j + 1],
                              gx[i + 1, j + 1], gy[i + 1, j + 1], gz[i + 1, j + 1],
                              gx[i + 1, j], gy[i + 1, j], gz[i + 1, j])


# --- directions of the fisheye models -------------------------------------------------------

@njit(inline="always", **_OPTIONS)
def _kb_theta_d(k1, k2, k3, k4, t):
    t2 = t * t
    return t * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))


@njit(inline="always", **_OPTIONS)
def _kb_dtheta_d(k1, k2, k3, k4, t):
    t2 = t * t
    return 1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)))


@njit(**_OPTIONS)
def _kb_theta_safeguarded(k1, k2, k3, k4, theta_max, rho_max, rho):
    """OpenCVFisheyeProjection.theta for one ρ: bracketed Newton to a residual < 1e-12."""
    if not (rho >= 0 and rho < rho_max):
        return np.nan
    lo, hi = 0.0, theta_max
    theta = min(rho, 0.5 * theta_max)
    res = _kb_theta_d(k1, k2, k3, k4, theta) - rho
    for _ in range(_KB_MAX_ITER):
        if not abs(res) >= _KB_TOL:
            break
        if res < 0:
            lo = theta
        if res > 0:
            hi = theta
        new = theta - res / _kb_dtheta_d(k1, k2, k3, k4, theta)
        if not (new > lo and new < hi):
            new = 0.5 * (lo + hi)
        theta = new
        res = _kb_theta_d(k1, k2, k3, k4, theta) - rho
    return theta if abs(res) < _KB_TOL else np.nan


@njit(**_OPTIONS)
def _kb_direction(p, table, col, row):
    """Kannala–Brandt direction of image point (row, col): θ(ρ) from ``table`` (linear
    interpolation) and two Newton steps, the safeguarded solver where the residual is still
    ≥ 1e-13 (near the fold); NaN beyond ρ_max (as the numpy version in field.py did)."""
    cx, cy, fx, fy, k1, k2, k3, k4, theta_max, rho_max, step = (
        p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10])
    n = table.size - 1
    xd = (col - cx) / fx
    yd = (row - cy) / fy
    rho = math.sqrt(xd * xd + yd * yd)
    if not rho < rho_max:
        return np.nan, np.nan, np.nan
    u = rho / step
    i = min(int(u), n - 1)
    f = u - i
    theta = table[i] * (1.0 - f) + table[i + 1] * f
    for _ in range(2):
        theta = theta - (_kb_theta_d(k1, k2, k3, k4, theta) - rho) / _kb_dtheta_d(k1, k2, k3, k4, theta)
        theta = min(max(theta, 0.0), theta_max)
    if not abs(_kb_theta_d(k1, k2, k3, k4, theta) - rho) < 1e-13:
        theta = _kb_theta_safeguarded(k1, k2, k3, k4, theta_max, rho_max, rho)
    half = math.tan(0.5 * theta)
    h2 = half * half
    s = 2.0 * half / (1.0 + h2)
    c = (1.0 - h2) / (1.0 + h2)
    q = s / rho if rho > 0 else 1.0
    return q * xd, q * yd, c


# Cephes tan (S. L. Moshier, Cephes Math Library 2.8, tan.c): reduction by multiples of π/4
# in three parts DP1 + DP2 + DP3, and tan z = z + z·w·P(w)/Q(w), w = z², on |z| ≤ π/4;
# peak relative error 2.2e-16 (Moshier's test, IEEE double).
_TAN_DP1, _TAN_DP2, _TAN_DP3 = 7.853981554508209228515625e-1, 7.94662735614792836714e-9, \
    3.06161699786838294307e-17
_TAN_P0, _TAN_P1, _TAN_P2 = -1.30936939181383777646e4, 1.15351664838587416140e6, \
    -1.79565251976484877988e7
_TAN_Q0, _TAN_Q1, _TAN_Q2, _TAN_Q3 = 1.36812963470692954678e4, -1.32089234440210967447e6, \
    2.50083801823357915839e7, -5.38695755929454629881e7
_FOUR_OVER_PI = 4.0 / math.pi


@njit(inline="always", **_OPTIONS)
def tan_half_range(x):
    """tan x for 0 ≤ x ≤ π/2, branch-free so that loops vectorise (Cephes' tan; within a few
    ulp of ``math.tan``, tested); NaN in, NaN out."""
    j = int(x * _FOUR_OVER_PI) if x < 4.0 else 4  # octant (x ≥ 4 or NaN cannot occur)
    j = (j + 1) & ~1  # to the nearest even multiple of π/4: 0 or 2
    y = float(j)
    z = ((x - y * _TAN_DP1) - y * _TAN_DP2) - y * _TAN_DP3
    w = z * z
    r = z + z * (w * ((_TAN_P0 * w + _TAN_P1) * w + _TAN_P2)
                 / ((((w + _TAN_Q0) * w + _TAN_Q1) * w + _TAN_Q2) * w + _TAN_Q3))
    r = -1.0 / r if j == 2 else r
    return r + 0.0 * x  # NaN propagates through the integer octant


@njit(**_OPTIONS)
def _kb_row(p, table, row, col_offset, ox, oy, oz):
    """Kannala–Brandt directions of the points (row, j + col_offset), j = 0…len(ox) − 1,
    into ``ox, oy, oz``: the branch-free body of :func:`_kb_direction` (vectorised), with
    NaN where ρ ≥ ρmax or the two Newton steps leave a residual ≥ 1e-13; those points are
    then redone one by one with :func:`_kb_direction` (NaN again beyond ρmax)."""
    cx, cy, fx, fy, k1, k2, k3, k4, theta_max, rho_max, step = (
        p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10])
    n = table.size - 1
    yd = (row - cy) / fy
    # The table look-up (a gather, which keeps a loop from vectorising) in a loop of its own,
    # the starting θ parked in ``oz``.
    for j in range(ox.size):
        xd = ((j + col_offset) - cx) / fx
        u = min(math.sqrt(xd * xd + yd * yd), rho_max) / step
        i = min(int(u), n - 1)
        f = u - i
        oz[j] = table[i] * (1.0 - f) + table[i + 1] * f
    for j in range(ox.size):
        xd = ((j + col_offset) - cx) / fx
        rho = math.sqrt(xd * xd + yd * yd)
        theta = oz[j]
        for _ in range(2):
            theta = theta - (_kb_theta_d(k1, k2, k3, k4, theta) - rho) / _kb_dtheta_d(k1, k2, k3, k4, theta)
            theta = min(max(theta, 0.0), theta_max)
        fine = (rho < rho_max) & (abs(_kb_theta_d(k1, k2, k3, k4, theta) - rho) < 1e-13)
        half = tan_half_range(0.5 * theta)
        h2 = half * half
        s = 2.0 * half / (1.0 + h2)
        c = (1.0 - h2) / (1.0 + h2)
        q = s / rho if rho > 0 else 1.0
        ox[j] = q * xd if fine else np.nan
        oy[j] = q * yd
        oz[j] = c
    for j in range(ox.size):
        if ox[j] != ox[j]:  # NaN
            ox[j], oy[j], oz[j] = _kb_direction(p, table, j + col_offset, row)


@njit(**_OPTIONS)
def _ideal_row(p, row, col_offset, ox, oy, oz, corner):
    """Ideal-fisheye directions of the points (row, j + col_offset) into ``ox, oy, oz``:
    IdealFisheyeProjection._unclipped_components (the same operations, so equal bit for bit),
    split into loops so that all but the libm tan run on SIMD lanes — tan's argument, tan
    (equidistant only), the components — and, for pixel centres, the image-circle test
    (NaN outside; centre rule: corners are not clipped)."""
    cx, cy, kind, coefficient, limit = p[0], p[1], int(p[2]), p[3], p[4]
    y = row - cy
    n = ox.size
    if kind == 0:  # equidistant: t = tan(θ/2), the argument parked in oz
        for j in range(n):
            x = (j + col_offset) - cx
            oz[j] = min(math.sqrt(x * x + y * y) * coefficient, math.pi) * 0.5
        for j in range(n):
            oz[j] = math.tan(oz[j])
    for j in range(n):
        x = (j + col_offset) - cx
        r = math.sqrt(x * x + y * y)
        if kind == 1:  # equisolid: h = sin(θ/2)
            h = min(r * coefficient, 1.0)
            s = 2.0 * h * math.sqrt(1.0 - h * h)
            c = 1.0 - 2.0 * h * h
        elif kind == 2:  # orthographic
            s = min(r * coefficient, 1.0)
            c = math.sqrt(1.0 - s * s)
        else:
            t = oz[j] if kind == 0 else r * coefficient
            t2 = t * t
            s = 2.0 * t / (1.0 + t2)
            c = (1.0 - t2) / (1.0 + t2)
        q = s / r if r > 0 else 0.0
        ox[j] = q * x
        oy[j] = q * y
        oz[j] = c
    if not corner:
        # IdealFisheyeProjection._inside: hypot(x, y) ≤ R·(1 + 1e-12); √(x² + y²) is within
        # an ulp or two of hypot, which decides only next to the rim.
        far, near = limit * limit * (1.0 + 1e-9), limit * limit * (1.0 - 1e-9)
        for j in range(n):
            x = (j + col_offset) - cx
            r2 = x * x + y * y
            if r2 > near and (r2 > far or not math.hypot(x, y) <= limit):
                ox[j], oy[j], oz[j] = np.nan, np.nan, np.nan


@njit(**_OPTIONS)
def _corner_row(model, p, table, row, cx, cy, cz):
    """Directions of the corners (row, j − ½), j = 0…cols, into ``cx, cy, cz``."""
    if model == OPENCV_FISHEYE:
        _kb_row(p, table, row, -0.5, cx, cy, cz)
    else:
        _ideal_row(p, row, -0.5, cx, cy, cz, True)


@njit(parallel=True, **_OPTIONS)
def fisheye_geometry(model, p, table, band_rows, directions, solid_angle, valid):
    """Fill ``directions`` (rows, cols, 3), ``solid_angle`` and ``valid`` (rows, cols).

    ``model`` is :data:`IDEAL_FISHEYE` (``p`` = cx, cy, kind code, radial coefficient,
    R·(1 + 1e-12)) or :data:`OPENCV_FISHEYE` (``p`` = cx, cy, fx, fy, k1…k4, θmax, ρmax, table
    step; ``table`` θ on a uniform grid of ρ). Bands of ``band_rows`` rows are shared out
    among the threads (one parallel region); a band walks down its rows keeping two rows of
    corner directions (above and below the current pixel row, a few hundred kB), so that
    every corner is computed once, except the top row of each band, which the band above
    computed too. Each corner and pixel is a pure function of its coordinates: the result
    does not depend on the bands or the number of threads.
    """
    rows, cols = valid.shape
    n_bands = (rows + band_rows - 1) // band_rows
    for band in prange(n_bands):
        r0 = band * band_rows
        r1 = min(r0 + band_rows, rows)
        corners = np.empty((2, 3, cols + 1))
        top = 0
        _corner_row(model, p, table, r0 - 0.5, corners[0, 0], corners[0, 1], corners[0, 2])
        for r in range(r0, r1):
            bottom = 1 - top
            _corner_row(model, p, table, r + 0.5, corners[bottom, 0], corners[bottom, 1],
                        corners[bottom, 2])
            x0, y0, z0 = corners[top, 0], corners[top, 1], corners[top, 2]
            x1, y1, z1 = corners[bottom, 0], corners[bottom, 1], corners[bottom, 2]
            d = directions[r]
            w = solid_angle[r]
            # Centre directions.
            if model == OPENCV_FISHEYE:
                _kb_row(p, table, float(r), 0.0, d[:, 0], d[:, 1], d[:, 2])
            else:
                _ideal_row(p, float(r), 0.0, d[:, 0], d[:, 1], d[:, 2], False)
            # Solid angles by the series on SIMD lanes (−1 where it does not apply)...
            for j in range(cols):
                w[j] = _quad_series(x0[j], y0[j], z0[j], x0[j + 1], y0[j + 1], z0[j + 1],
                                    x1[j + 1], y1[j + 1], z1[j + 1], x1[j], y1[j], z1[j])
            # ... the rest by the full formula, and validity.
            for j in range(cols):
                omega = w[j]
                if not omega >= 0:
                    omega = _quad(x0[j], y0[j], z0[j], x0[j + 1], y0[j + 1], z0[j + 1],
                                  x1[j + 1], y1[j + 1], z1[j + 1], x1[j], y1[j], z1[j])
                ok = (omega > 0 and math.isfinite(omega) and math.isfinite(d[j, 0])
                      and math.isfinite(d[j, 1]) and math.isfinite(d[j, 2]))
                if ok:
                    w[j] = omega
                else:
                    d[j, 0] = np.nan
                    d[j, 1] = np.nan
                    d[j, 2] = np.nan
                    w[j] = 0.0
                valid[r, j] = ok
            top = bottom


# --- visual field ---------------------------------------------------------------------------

@njit(inline="always", **_OPTIONS)
def _guth(s, t):
    """position_index_Guth with σ, τ already in degrees."""
    return math.exp((35.2 - 0.31889 * t - 1.22 * math.exp(-2.0 * t / 9.0)) * 1e-3 * s
                    + (21.0 + 0.26667 * t - 0.002963 * t * t) * 1e-5 * s * s)


@njit(parallel=True, **_OPTIONS)
def visual_field_maps(directions, valid, v, u, h, method, cap, sigma, tau, position_index,
                      cos_sigma):
    """σ, τ [rad], position index and cos σ of every pixel (see field.visual_field).

    ``v, u, h``: line of sight, up and side axes; ``method`` a code of
    :data:`POSITION_INDEX_METHODS`; ``cap`` the Guth/Iwata cap. The formulas of
    :mod:`~lsadphoto.geometry.position_index` (Iwata's β from the components, as
    position_index_from_components). Per row, the angles are computed on SIMD lanes
    (:func:`atan2_nonnegative`; the "evalglare" method also Iwata's β, kept in the output
    row), then the position index (libm exp) in a second, scalar loop.
    """
    rows, cols = valid.shape
    half_pi = 0.5 * math.pi
    flat = directions.reshape(rows, 3 * cols)  # flat rows: the loads vectorise (interleaved)
    v0, v1, v2, u0, u1, u2, h0, h1, h2 = v[0], v[1], v[2], u[0], u[1], u[2], h[0], h[1], h[2]
    iwata = method == 0
    for i in prange(rows):
        d = flat[i]
        s_row, t_row, p_row, c_row, ok = sigma[i], tau[i], position_index[i], cos_sigma[i], valid[i]
        for j in range(cols):
            dx, dy, dz = d[3 * j], d[3 * j + 1], d[3 * j + 2]
            forward = dx * v0 + dy * v1 + dz * v2
            up = dx * u0 + dy * u1 + dz * u2
            side = dx * h0 + dy * h1 + dz * h2
            lateral = math.sqrt(up * up + side * side)
            s_row[j] = atan2_nonnegative(lateral, forward)
            t = atan2_nonnegative(abs(side), up)
            # On the line of sight τ is undefined: 0 where the lateral part is at rounding
            # level (as field._angles did).
            t_row[j] = 0.0 if lateral < 1e-15 else t
            c_row[j] = forward if ok[j] else 0.0
            if iwata:
                p_row[j] = atan2_nonnegative(math.sqrt(side * side + 1.3225 * (up * up)), forward)
        for j in range(cols):
            s = s_row[j] * _DEGREES
            t = t_row[j] * _DEGREES
            if method == 2:  # Kim2011
                centre = -9e-6 * t ** 3 + 0.0014 * t ** 2 + 0.0866 * t + 21.633
                width = -9e-6 * t ** 3 + 0.0013 * t ** 2 + 0.0853 * t + 8.772
                p_row[j] = math.exp((s - centre) / width)
                continue
            if iwata and t_row[j] > half_pi:  # evalglare, below the line of sight: Iwata
                b = p_row[j] * _DEGREES
                value = math.exp(6.49e-3 * b + 21e-5 * b * b)
            else:
                value = _guth(s, t)
            p_row[j] = cap if value > cap else value  # noqa: FURB136 (NaN stays NaN, as np.minimum)
