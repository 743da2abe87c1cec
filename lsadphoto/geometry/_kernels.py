"""Compiled (numba) kernels of the per-pixel geometry maps of :mod:`~lsadphoto.geometry.field`.

One pass over the image computes, per pixel, what the numpy reference methods compute in
many full-frame passes: the direction of its centre, the directions of its corners (each
corner once, shared by the four pixels that meet there), its solid angle and validity; a
second pass gives σ, τ, cos σ and the position index, computing the centre directions again
from the model (:func:`_centre_row`, the one per-pixel projection function) rather than
reading a stored map, as :func:`fisheye_directions` does for the pixels the metrics ask
for (the map is written only on request). Rows are distributed over threads
(``prange``); the kernels are compiled on first use and cached on disk (``cache=True``).
Only the span of a row that can hold valid pixels is computed — the chord of the image
circle (ideal fisheye) or of the ellipse ρ < ρmax (OpenCV) plus a margin of two pixels, in
which the per-pixel tests decide; in the second pass the span from the first to the last
valid pixel. The pixels outside get the values their NaN directions would give (NaN
directions, σ, τ and position index; zero solid angle and cos σ; not valid) directly: half
of the frame for a 180° circular fisheye in a 3:2 image.

Numerics: IEEE float64 throughout (the position index and cos σ are stored as float32,
each rounded once from its float64 value: :func:`_store_field_row`), no ``fastmath`` (no
reassociation, no contraction into fused multiply–adds), the same operations in the same
order as the numpy reference methods — for the ideal fisheye the maps equal
:meth:`IdealFisheyeProjection.directions` and :meth:`~IdealFisheyeProjection.solid_angles`
bit for bit (tested), but for the equidistant kind's tan. Three libm functions are
replaced by branch-free Cephes approximations so that loops run on SIMD lanes: tan in the
OpenCV (Kannala–Brandt) and the ideal equidistant directions (:func:`tan_half_range`),
atan2 in σ, τ and Iwata's β (:func:`atan2_nonnegative`) and exp in the position index
(:func:`exp_bounded`), each within a few ulp of libm (tested), far inside the tolerances
to which the maps are tested (1e-11 for OpenCV directions, 1e-14 rad for σ, τ, relative
1e-12 for the position index before its rounding to float32).
``error_model="numpy"`` makes x/0 give ±inf or NaN as in numpy instead of raising, which
also lets the compiler vectorise the loops. What does not vectorise on AVX2 — libm calls,
table look-ups (gathers), float-to-integer conversions — is kept
in loops of its own; vectorised loops index arrays from 0 (slices of the span), so that the
compiler knows the index is not negative. Small helpers are inlined at the numba level only
where a vectorised loop needs them (compile time: about 15 s for these kernels on first use
in a fresh installation, then loaded from the on-disk cache).

References
----------
A. Van Oosterom & J. Strackee, IEEE Trans. Biomed. Eng. BME-30(2), 1983, 125–126 (solid
angle of a triangle). FORMULAS.md §2.1–2.4 (directions, position index, pixel solid angles).
"""

import math

import numpy as np
from .._compiled import intrinsic, njit, prange

__all__ = [
    "FISHEYE_KINDS",
    "IDEAL_FISHEYE",
    "OPENCV_FISHEYE",
    "POSITION_INDEX_METHODS",
    "atan2_nonnegative",
    "exp_bounded",
    "fisheye_directions",
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
#: Newton steps of the vectorised Kannala–Brandt inversion from the table's θ (field.py's
#: table of 2¹⁶ intervals: θ to ~10⁻¹⁰ rad, one step to rounding).
_KB_NEWTON_STEPS = 1
#: Columns added on each side of the computed span of possibly valid pixel centres of a row
#: (:func:`_centre_span`): far more than the rounding of its bounds (≪ 10⁻³ px).
_SPAN_MARGIN = 2
#: Segments per chunk of :func:`fisheye_directions` (chunks are shared out among the threads).
_SEGMENT_CHUNK = 256


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


@njit(**_OPTIONS,
      aot="void(float64[:, ::1], float64[:, ::1], float64[:, ::1], float64[:, ::1])")
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
def _kb_direction(p, col, row):
    """Kannala–Brandt direction of image point (row, col) with θ(ρ) from the safeguarded
    solver (:func:`_kb_theta_safeguarded`): the points near the fold that table and Newton
    step leave at a residual ≥ 1e-13; NaN beyond ρmax (as the numpy version in field.py)."""
    cx, cy, fx, fy, k1, k2, k3, k4, theta_max, rho_max = (
        p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9])
    xd = (col - cx) / fx
    yd = (row - cy) / fy
    rho = math.sqrt(xd * xd + yd * yd)
    if not rho < rho_max:
        return np.nan, np.nan, np.nan
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
    # Cephes' octant ⌊4x/π⌋ (0, 1 or 2 here) rounded up to even, y = 0 or 2, by a comparison:
    # the float-to-integer conversion of the original has no SIMD instruction before AVX-512.
    big = x * _FOUR_OVER_PI >= 1.0
    y = 2.0 if big else 0.0
    z = ((x - y * _TAN_DP1) - y * _TAN_DP2) - y * _TAN_DP3
    w = z * z
    r = z + z * (w * ((_TAN_P0 * w + _TAN_P1) * w + _TAN_P2)
                 / ((((w + _TAN_Q0) * w + _TAN_Q1) * w + _TAN_Q2) * w + _TAN_Q3))
    return -1.0 / r if big else r


@njit(**_OPTIONS)
def _kb_row(p, table, row, col_offset, ox, oy, oz):
    """Kannala–Brandt directions of the points (row, j + col_offset), j = 0…len(ox) − 1,
    into ``ox, oy, oz``: θ(ρ) from ``table`` (linear interpolation) and one Newton step,
    branch-free (vectorised), with NaN where ρ ≥ ρmax or the residual |θd(θ) − ρ| is still
    ≥ 1e-13 (near the fold of the mapping, about 0.1 % of the points); those points are then
    redone one by one with :func:`_kb_direction` (NaN again beyond ρmax)."""
    cx, cy, fx, fy, k1, k2, k3, k4, theta_max, rho_max, step = (
        p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10])
    n = table.size - 1
    yd = (row - cy) / fy
    # x, ρ and the table position u of every point (parked in ``ox, oy, oz``) on SIMD lanes;
    # then the table look-up (a gather, and a float-to-integer conversion, neither of which
    # vectorises on AVX2) in a scalar loop of its own, the starting θ parked in ``oz``.
    for j in range(ox.size):
        xd = ((j + col_offset) - cx) / fx
        rho = math.sqrt(xd * xd + yd * yd)
        ox[j] = xd
        oy[j] = rho
        oz[j] = min(rho, rho_max) / step
    for j in range(ox.size):
        u = oz[j]
        i = min(int(u), n - 1)
        f = u - i
        oz[j] = table[i] * (1.0 - f) + table[i + 1] * f
    for j in range(ox.size):
        xd = ox[j]
        rho = oy[j]
        theta = oz[j]
        for _ in range(_KB_NEWTON_STEPS):
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
            ox[j], oy[j], oz[j] = _kb_direction(p, j + col_offset, row)


@njit(**_OPTIONS)
def _ideal_row(p, row, col_offset, ox, oy, oz, corner):
    """Ideal-fisheye directions of the points (row, j + col_offset) into ``ox, oy, oz``:
    IdealFisheyeProjection._unclipped_components (the same operations; for the equidistant
    kind tan(θ/2) is :func:`tan_half_range`, within 2 ulp of the C library's, so that the
    whole loop runs on SIMD lanes: directions within a few ulp of the model's, the other
    kinds equal bit for bit), and, for pixel centres, the image-circle test (NaN outside;
    centre rule: corners are not clipped)."""
    cx, cy, kind, coefficient, limit = p[0], p[1], int(p[2]), p[3], p[4]
    y = row - cy
    n = ox.size
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
        else:  # equidistant: t = tan(θ/2); stereographic: t = r·coefficient
            t = tan_half_range(min(r * coefficient, math.pi) * 0.5) if kind == 0 \
                else r * coefficient
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
def _centre_span(model, p, row, cols):
    """Columns ``j0, j1`` (j0 ≤ j < j1) outside which no pixel centre of ``row`` is valid:
    the chord of the image circle (ideal fisheye: √(x² + y²) ≤ R·(1 + 1e-12)) or of the
    ellipse ρ < ρmax (OpenCV) at that row, widened by :data:`_SPAN_MARGIN` columns on each
    side and clipped to the image; the pixels' own tests decide inside it."""
    if model == OPENCV_FISHEYE:
        yd = (row - p[1]) / p[3]
        half = p[2] * math.sqrt(max(p[9] * p[9] - yd * yd, 0.0))
    else:
        y = row - p[1]
        half = math.sqrt(max(p[4] * p[4] - y * y, 0.0))
    j0 = min(max(math.floor(p[0] - half) - _SPAN_MARGIN, 0), cols)
    j1 = max(min(math.ceil(p[0] + half) + _SPAN_MARGIN + 1, cols), j0)
    return j0, j1


@njit(**_OPTIONS)
def _corner_row(model, p, table, row, j0, j1, corners, mirror_cols):
    """Directions of the corners (row, j − ½), j0 ≤ j < j1, into ``corners[:, j]``
    (:func:`_mirrored_columns` where ``mirror_cols`` ≥ 0)."""
    cx, cy, cz = corners[0, j0:j1], corners[1, j0:j1], corners[2, j0:j1]
    _mirrored_columns(model, p, table, row, j0 - 0.5, cx, cy, cz, True, mirror_cols)


@njit(inline="always", **_OPTIONS)
def _model_row(model, p, table, row, col_offset, ox, oy, oz, corner):
    """The model's directions of the points (row, col_offset + j) into ``ox, oy, oz``:
    :func:`_kb_row` or :func:`_ideal_row` (``corner``: without the image-circle test)."""
    if model == OPENCV_FISHEYE:
        _kb_row(p, table, row, col_offset, ox, oy, oz)
    else:
        _ideal_row(p, row, col_offset, ox, oy, oz, corner)


@njit(**_OPTIONS)
def _mirrored_columns(model, p, table, row, col_offset, ox, oy, oz, corner, mirror_cols):
    """The directions of :func:`_model_row`. Where ``mirror_cols`` = 2·cx ≥ 0 (a whole
    number), a point right of the column cx whose mirror image 2·cx − c lies in the range is
    copied from that image with x negated: the column offsets c − cx and (2·cx − c) − cx are
    exact opposites, and both models compute a direction from x and y only through x² + y²
    (ρ, θ, the image-circle test) and a final product by x — the same bits as computing it,
    but for the sign of a NaN, which the consumers only test for. Points right of the
    mirror image of the range's first point are computed, so any range is right."""
    n = ox.size
    if mirror_cols < 0:
        _model_row(model, p, table, row, col_offset, ox, oy, oz, corner)
        return
    # Point j's mirror image is point s − j (s whole: col_offset is whole or a half).
    s = int(mirror_cols - 2.0 * col_offset)
    k1 = min(n, max(0, s // 2 + 1))  # points j ≤ s/2 (left of cx or on it): computed
    k2 = min(n, max(k1, s + 1))  # k1 ≤ j < k2: mirror images of computed points
    _model_row(model, p, table, row, col_offset, ox[:k1], oy[:k1], oz[:k1], corner)
    for j in range(k1, k2):
        m = s - j
        ox[j] = -ox[m]
        oy[j] = oy[m]
        oz[j] = oz[m]
    if k2 < n:
        _model_row(model, p, table, row, col_offset + k2, ox[k2:], oy[k2:], oz[k2:], corner)


@njit(**_OPTIONS)
def _centre_row(model, p, table, row, col_offset, ox, oy, oz):
    """Directions of the pixel centres (row, col_offset + j), j < len(ox): the projection's
    per-pixel function, which every kernel that needs a direction calls (the maps of
    :func:`fisheye_geometry`, :func:`fisheye_directions`, :func:`visual_field_maps`). Each
    value is a pure function of its pixel's coordinates (:func:`fisheye_geometry` copies the
    mirror images of computed ones, the same bits: :func:`_mirrored_columns`)."""
    _model_row(model, p, table, row, col_offset, ox, oy, oz, False)


@njit(parallel=True, **_OPTIONS,
      aot=("void(int64, float64[::1], float64[::1], boolean[:, ::1], int64[::1], int64[::1], "
           "int64[::1], int64[::1], float64[:, ::1])"))
def fisheye_directions(model, p, table, valid, seg_row, seg_col, seg_length, seg_start, out):
    """Centre directions of row segments: segment k is the pixels (seg_row[k], seg_col[k] + j),
    j < seg_length[k], inside the image, written to ``out[seg_start[k] + j]``; NaN where the
    pixel is not ``valid`` — the values of :func:`fisheye_geometry`'s ``directions`` map bit
    for bit, without the map."""
    n_segments = seg_row.size
    longest = 0
    for k in range(n_segments):
        longest = max(longest, seg_length[k])
    n_chunks = (n_segments + _SEGMENT_CHUNK - 1) // _SEGMENT_CHUNK
    for chunk in prange(n_chunks):
        scratch = np.empty((3, longest))  # one per chunk of segments, not per segment
        for k in range(chunk * _SEGMENT_CHUNK, min(n_segments, (chunk + 1) * _SEGMENT_CHUNK)):
            n = seg_length[k]
            r, c0, o = seg_row[k], seg_col[k], seg_start[k]
            cx, cy, cz = scratch[0, :n], scratch[1, :n], scratch[2, :n]
            _centre_row(model, p, table, float(r), float(c0), cx, cy, cz)
            ok = valid[r, c0:c0 + n]
            for j in range(n):
                good = ok[j]
                out[o + j, 0] = cx[j] if good else np.nan
                out[o + j, 1] = cy[j] if good else np.nan
                out[o + j, 2] = cz[j] if good else np.nan


@njit(inline="always", **_OPTIONS)
def _mirrored(d, ok, n, v, u, h):
    """Whether the span's pixel ``n − 1 − j`` has, for every j, the same ``ok`` and the same
    bits of d̂·v̂ (forward), d̂·û (up) and |d̂·ĥ| (side) as pixel j: then its σ, τ, cos σ and
    position index are the same bits too (they are functions of these alone, see
    :func:`_field_row`). True for the rows of a centred fisheye seen along its axis (its
    directions mirror exactly: x → −x; the frame's v̂ and û without a component along x,
    ĥ along x)."""
    v0, v1, v2, u0, u1, u2, h0, h1, h2 = v[0], v[1], v[2], u[0], u[1], u[2], h[0], h[1], h[2]
    same = True
    for j in range(n // 2):  # branch-free (SIMD lanes): every pair is compared
        k = n - 1 - j
        a0, a1, a2, b0, b1, b2 = d[3 * j], d[3 * j + 1], d[3 * j + 2], d[3 * k], d[3 * k + 1], \
            d[3 * k + 2]
        same &= ((ok[j] == ok[k])
                 & (_float64_bits(a0 * v0 + a1 * v1 + a2 * v2)
                    == _float64_bits(b0 * v0 + b1 * v1 + b2 * v2))
                 & (_float64_bits(a0 * u0 + a1 * u1 + a2 * u2)
                    == _float64_bits(b0 * u0 + b1 * u1 + b2 * u2))
                 & (_float64_bits(abs(a0 * h0 + a1 * h1 + a2 * h2))
                    == _float64_bits(abs(b0 * h0 + b1 * h1 + b2 * h2))))
    return same


@njit(inline="always", **_OPTIONS)
def _field_row(d, ok, n, v, u, h, method, cap, angles, field, s_row, t_row, p_row, c_row):
    """τ, cos σ (0 where not ``ok``), σ where ``angles`` or where the position index needs
    it, and, where ``field``, the position index of the ``n`` interleaved directions ``d``
    of one row's span (see :func:`visual_field_maps`). Where the span is its own mirror
    image (:func:`_mirrored`), the first half is computed and copied to the second: the same
    values, half the arc tangents and exponentials. The "evalglare" position index takes
    Guth's formula (σ, τ) above the line of sight and Iwata's (β) below it (τ > π/2): each
    formula's arc tangent and exponentials are computed for the row only where one of its
    pixels takes it (a row of a fisheye seen along its axis lies wholly above or below) —
    the same values as computing both for every pixel and selecting."""
    half_pi = 0.5 * math.pi
    v0, v1, v2, u0, u1, u2, h0, h1, h2 = v[0], v[1], v[2], u[0], u[1], u[2], h[0], h[1], h[2]
    iwata = method == 0
    total = n
    if _mirrored(d, ok, n, v, u, h):
        n = (n + 1) // 2
    below = 0
    for j in range(n):
        dx, dy, dz = d[3 * j], d[3 * j + 1], d[3 * j + 2]
        forward = dx * v0 + dy * v1 + dz * v2
        up = dx * u0 + dy * u1 + dz * u2
        side = dx * h0 + dy * h1 + dz * h2
        lateral = math.sqrt(up * up + side * side)
        t = atan2_nonnegative(abs(side), up)
        # On the line of sight τ is undefined: 0 where the lateral part is at rounding
        # level (as field._angles did).
        t = 0.0 if lateral < 1e-15 else t
        t_row[j] = t
        c_row[j] = forward if ok[j] else 0.0
        below += 1 if t > half_pi else 0
    guth = field and (not iwata or below < n)  # σ for Guth's and Kim's formulas
    beta = field and iwata and below > 0
    if angles or guth:
        for j in range(n):
            dx, dy, dz = d[3 * j], d[3 * j + 1], d[3 * j + 2]
            forward = dx * v0 + dy * v1 + dz * v2
            up = dx * u0 + dy * u1 + dz * u2
            side = dx * h0 + dy * h1 + dz * h2
            s_row[j] = atan2_nonnegative(math.sqrt(up * up + side * side), forward)
    if beta:  # Iwata's β, kept in the output row
        for j in range(n):
            dx, dy, dz = d[3 * j], d[3 * j + 1], d[3 * j + 2]
            forward = dx * v0 + dy * v1 + dz * v2
            up = dx * u0 + dy * u1 + dz * u2
            side = dx * h0 + dy * h1 + dz * h2
            p_row[j] = atan2_nonnegative(math.sqrt(side * side + 1.3225 * (up * up)), forward)
    if field:
        if method == 2:  # Kim2011
            for j in range(n):
                s = s_row[j] * _DEGREES
                t = t_row[j] * _DEGREES
                centre = -9e-6 * t ** 3 + 0.0014 * t ** 2 + 0.0866 * t + 21.633
                width = -9e-6 * t ** 3 + 0.0013 * t ** 2 + 0.0853 * t + 8.772
                p_row[j] = exp_bounded((s - centre) / width)
        elif not guth:  # evalglare, every pixel below the line of sight: Iwata
            for j in range(n):
                value = exp_bounded(_iwata_exponent(p_row[j] * _DEGREES))
                p_row[j] = cap if value > cap else value  # noqa: FURB136 (NaN stays NaN, as np.minimum)
        else:
            for j in range(n):
                exponent = _guth_exponent(s_row[j] * _DEGREES, t_row[j] * _DEGREES)
                if beta:  # evalglare: Iwata below the line of sight
                    exponent = _iwata_exponent(p_row[j] * _DEGREES) if t_row[j] > half_pi \
                        else exponent
                value = exp_bounded(exponent)
                p_row[j] = cap if value > cap else value  # noqa: FURB136 (NaN stays NaN, as np.minimum)
    for j in range(n, total):  # the mirrored half, where there is one
        k = total - 1 - j
        s_row[j], t_row[j], c_row[j] = s_row[k], t_row[k], c_row[k]
        if field:
            p_row[j] = p_row[k]


@njit(inline="always", **_OPTIONS)
def _valid_span(ok, cols):
    """First and last + 1 valid column of a row (equal where none is valid)."""
    j0, j1 = 0, cols
    while j0 < j1 and not ok[j0]:
        j0 += 1
    while j1 > j0 and not ok[j1 - 1]:
        j1 -= 1
    return j0, j1


@njit(inline="always", **_OPTIONS)
def _masked_interleaved(cx, cy, cz, ok, n):
    """The directions (cx, cy, cz) of a span interleaved, NaN where not ``ok``: the values of
    the stored map."""
    d = np.empty(3 * n)
    for j in range(n):
        good = ok[j]
        d[3 * j] = cx[j] if good else np.nan
        d[3 * j + 1] = cy[j] if good else np.nan
        d[3 * j + 2] = cz[j] if good else np.nan
    return d


@njit(inline="always", **_OPTIONS)
def _field_outputs(i, j0, j1, rows_out, fill):
    """The span [j0, j1) of row ``i`` of ``rows_out`` (the rest set to ``fill``)."""
    rows_out[i, :j0] = fill
    rows_out[i, j1:] = fill
    return rows_out[i, j0:j1]


@njit(inline="always", **_OPTIONS)
def _store_field_row(i, j0, j1, p_row, c_row, position_index, cos_sigma):
    """Row ``i`` of the float32 position-index and cos σ maps: the float64 values ``p_row``,
    ``c_row`` of its span [j0, j1) rounded once, NaN and 0 outside it."""
    p_out = _field_outputs(i, j0, j1, position_index, np.float32(np.nan))
    c_out = _field_outputs(i, j0, j1, cos_sigma, np.float32(0.0))
    for j in range(j1 - j0):
        p_out[j] = np.float32(p_row[j])
        c_out[j] = np.float32(c_row[j])


@njit(inline="always", **_OPTIONS)
def _row_solid_angles(w, ok, cx, cy, cz, x0, y0, z0, x1, y1, z1, n):
    """Solid angle and validity of the ``n`` pixels of a row's span from their corner rows
    above (``x0, y0, z0``) and below (``x1, y1, z1``), n + 1 corners each, and their centre
    directions: the quad (above j, above j + 1, below j + 1, below j)."""
    # Solid angles by the series on SIMD lanes (−1 where it does not apply)...
    for j in range(n):
        w[j] = _quad_series(x0[j], y0[j], z0[j], x0[j + 1], y0[j + 1], z0[j + 1],
                            x1[j + 1], y1[j + 1], z1[j + 1], x1[j], y1[j], z1[j])
    # ... the rest (NaN corners, large pixels) by the full formula...
    for j in range(n):
        if not w[j] >= 0:
            w[j] = _quad(x0[j], y0[j], z0[j], x0[j + 1], y0[j + 1], z0[j + 1],
                         x1[j + 1], y1[j + 1], z1[j + 1], x1[j], y1[j], z1[j])
    # ... and validity, branch-free.
    for j in range(n):
        omega = w[j]
        good = ((omega > 0) & (abs(omega) < np.inf) & (abs(cx[j]) < np.inf)
                & (abs(cy[j]) < np.inf) & (abs(cz[j]) < np.inf))
        w[j] = omega if good else 0.0
        ok[j] = good


@njit(inline="always", **_OPTIONS)
def _write_row(r, j0, j1, cx, cy, cz, store_directions, directions, solid_angle, valid, field,
               v, u, h, method, cap, position_index, cos_sigma, x0, y0, z0, x1, y1, z1):
    """Row ``r`` of the maps from its span's centre directions and its corner rows above
    (``x0, y0, z0``) and below (``x1, y1, z1``); pixels outside the span [j0, j1) invalid
    without computing anything."""
    cols = valid.shape[1]
    w = solid_angle[r]
    ok = valid[r]
    if store_directions:
        directions[r, :j0] = np.nan
        directions[r, j1:] = np.nan
    w[:j0] = 0.0
    w[j1:] = 0.0
    ok[:j0] = False
    ok[j1:] = False
    # The span as arrays of its own: loops over range(n) index from 0, which the compiler
    # knows to be non-negative (no wraparound select) and vectorises.
    n = j1 - j0
    _row_solid_angles(w[j0:j1], ok[j0:j1], cx, cy, cz, x0, y0, z0, x1, y1, z1, n)
    if store_directions:
        d = directions[r, j0:j1]
        for j in range(n):
            good = ok[j0 + j]
            d[j, 0] = cx[j] if good else np.nan
            d[j, 1] = cy[j] if good else np.nan
            d[j, 2] = cz[j] if good else np.nan
    if field:  # the visual field over the row's valid span, as visual_field_maps
        a, b = _valid_span(ok, cols)
        m = b - a
        d = _masked_interleaved(cx[a - j0:b - j0], cy[a - j0:b - j0], cz[a - j0:b - j0],
                                ok[a:b], m)
        p_row, c_row = np.empty(m), np.empty(m)
        _field_row(d, ok[a:b], m, v, u, h, method, cap, False, True, np.empty(m),
                   np.empty(m), p_row, c_row)
        _store_field_row(r, a, b, p_row, c_row, position_index, cos_sigma)


@njit(parallel=True, **_OPTIONS,
      aot=("void(int64, float64[::1], float64[::1], int64, int64, int64, int64, int64, "
           "boolean, float64[:, :, ::1], float64[:, ::1], boolean[:, ::1], boolean, "
           "float64[::1], float64[::1], float64[::1], int64, float64, float32[:, ::1], "
           "float32[:, ::1])"))
def fisheye_geometry(model, p, table, band_rows, row0, row1, mirror, mirror_cols,
                     store_directions, directions, solid_angle, valid, field, v, u, h, method,
                     cap, position_index, cos_sigma):
    """Fill the image rows ``row0`` … ``row1 − 1`` of ``directions`` (rows, cols, 3),
    ``solid_angle`` and ``valid`` (rows, cols) — where ``mirror`` ≥ 0, also each such row's
    mirror image ``mirror − r`` about the centre row where it lies below it in the image —
    so that threads can share an image out in blocks of rows
    (:func:`lsadphoto._compiled.run_blocks`).

    ``model`` is :data:`IDEAL_FISHEYE` (``p`` = cx, cy, kind code, radial coefficient,
    R·(1 + 1e-12)) or :data:`OPENCV_FISHEYE` (``p`` = cx, cy, fx, fy, k1…k4, θmax, ρmax, table
    step; ``table`` θ on a uniform grid of ρ). ``directions`` is written only where
    ``store_directions`` (else it may be any array: the metrics compute directions from the
    model where they need them, :func:`fisheye_directions`, 24 bytes per pixel not stored). Bands of ``band_rows`` rows are shared out
    among the threads (one parallel region); a band walks down its rows keeping two rows of
    corner directions (above and below the current pixel row, a few hundred kB), so that
    every corner is computed once, except the top row of each band, which the band above
    computed too. Per pixel row only the span of :func:`_centre_span` is computed (its
    corners over the union of the spans of the two rows that share them); pixels outside it
    are set invalid directly. Each corner and pixel is a pure function of its coordinates
    (the spans too): the result does not depend on the bands or the number of threads.
    Where ``field``, the visual field's position index and cos σ (float32 maps;
    :func:`visual_field_maps`'s arguments ``v, u, h, method, cap``) are computed in the same
    pass from the same centre directions, equal bit for bit to that kernel's.

    ``mirror`` = 2·cy where the model's directions mirror exactly about the row cy, else −1:
    the fisheye models with 2·cy a whole number (:func:`~lsadphoto.geometry.field.
    _compute_pixel_geometry`), where the row offsets of a row and of its mirror image,
    y = g − cy and (2·cy − g) − cy, are exact opposites, and every direction is computed
    from x, y through x² + y² and a final product by y. The mirror row's centre and corner
    directions are then this row's with y negated (its corners above are this row's below,
    its span this row's), and are handed to the same per-row code as if computed: the maps
    equal those of rows computed one by one, bit for bit (tested), with half the directions
    computed. Likewise ``mirror_cols`` = 2·cx where 2·cx is a whole number, else −1: the
    centre and corner directions right of the column cx are copied from their mirror images
    with x negated (:func:`_mirrored_columns`), halving the directions computed again.
    """
    rows, cols = valid.shape
    n_bands = (row1 - row0 + band_rows - 1) // band_rows
    for band in prange(n_bands):
        r0 = row0 + band * band_rows
        r1 = min(r0 + band_rows, row1)
        corners = np.empty((2, 3, cols + 1))
        # Centre directions are computed into contiguous rows: written straight into the
        # interleaved ``directions`` row (stride 3) the loops of _kb_row do not vectorise.
        centres = np.empty((3, cols))
        flipped = np.empty((3, cols + 1))  # y of a mirrored row's centres and corners
        top = 0
        # Each row of corners is computed over the union of the spans of the two pixel rows
        # that share it (one more corner than pixels). Rows are integers: exact as floats.
        above = _centre_span(model, p, float(r0) - 1.0, cols)
        below = _centre_span(model, p, float(r0), cols)
        _corner_row(model, p, table, float(r0) - 0.5, min(above[0], below[0]),
                    max(above[1], below[1]) + 1, corners[0], mirror_cols)
        for r in range(r0, r1):
            g = float(r)
            j0, j1 = below
            below = _centre_span(model, p, g + 1.0, cols)
            bottom = 1 - top
            _corner_row(model, p, table, g + 0.5, min(j0, below[0]), max(j1, below[1]) + 1,
                        corners[bottom], mirror_cols)
            n = j1 - j0
            x0, y0, z0 = corners[top, 0, j0:j1 + 1], corners[top, 1, j0:j1 + 1], \
                corners[top, 2, j0:j1 + 1]
            x1, y1, z1 = corners[bottom, 0, j0:j1 + 1], corners[bottom, 1, j0:j1 + 1], \
                corners[bottom, 2, j0:j1 + 1]
            cx, cy, cz = centres[0, :n], centres[1, :n], centres[2, :n]
            _mirrored_columns(model, p, table, g, float(j0), cx, cy, cz, False, mirror_cols)
            _write_row(r, j0, j1, cx, cy, cz, store_directions, directions, solid_angle, valid,
                       field, v, u, h, method, cap, position_index, cos_sigma,
                       x0, y0, z0, x1, y1, z1)
            image = mirror - r
            if mirror >= 0 and r < image < rows:
                # The mirror image: centres and corners with y negated, its upper corners
                # the mirror of this row's lower ones and its lower ones of the upper.
                my, upper_y, lower_y = flipped[0, :n], flipped[1, :n + 1], flipped[2, :n + 1]
                for j in range(n):
                    my[j] = -cy[j]
                for j in range(n + 1):
                    upper_y[j] = -y1[j]
                    lower_y[j] = -y0[j]
                _write_row(image, j0, j1, cx, my, cz, store_directions, directions,
                           solid_angle, valid, field, v, u, h, method, cap, position_index,
                           cos_sigma, x1, upper_y, z1, x0, lower_y, z0)
            top = bottom


# --- visual field ---------------------------------------------------------------------------

@intrinsic
def _float64_bits(typingctx, x):
    """The bits of a float64 as an int64 (a reinterpretation, which vectorises; no
    conversion)."""
    from numba import types

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], context.get_value_type(types.int64))
    return types.int64(types.float64), codegen


@intrinsic
def _bits_float64(typingctx, bits):
    """The float64 whose bits are the int64 ``bits`` (inverse of :func:`_float64_bits`)."""
    from numba import types

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], context.get_value_type(types.float64))
    return types.float64(types.int64), codegen


# Cephes exp (S. L. Moshier, Cephes Math Library 2.2, exp.c): exp x = 2ⁿ·exp r with
# n = round(x·log₂e), r = x − n·ln 2 (ln 2 in two parts C1 + C2, C1 of 15 bits so that n·C1 is
# exact), and
# exp r = 1 + 2r·P(r²)/(Q(r²) − r·P(r²)) on |r| ≤ ½ ln 2; peak relative error 2.0e-16
# (Moshier's test, IEEE double, |x| ≤ 708).
_EXP_P0, _EXP_P1, _EXP_P2 = (
    1.26177193074810590878e-4, 3.02994407707441961300e-2, 9.99999999999999999910e-1)
_EXP_Q0, _EXP_Q1, _EXP_Q2, _EXP_Q3 = (
    3.00198505138664455042e-6, 2.52448340349684104192e-3, 2.27265548208155028766e-1,
    2.00000000000000000009e0)
_EXP_C1, _EXP_C2 = 6.93145751953125e-1, 1.42860682030941723212e-6
_LOG2E = 1.4426950408889634073599
#: 1.5·2⁵² + 1023: adding it to x·log₂e rounds to the integer n, which then sits in the low
#: mantissa bits, already offset by the exponent bias (n + 1023 ∈ [2, 2046] for the clamped x).
_EXP_SHIFT = 6755399441055744.0 + 1023.0
#: Arguments of :func:`exp_bounded` are clamped to [_EXP_MIN, _EXP_MAX] (normal results).
_EXP_MIN, _EXP_MAX = -708.0, 709.0


@njit(inline="always", **_OPTIONS)
def exp_bounded(x):
    """exp x for −708 ≤ x ≤ 709, branch-free so that loops vectorise (Cephes' exp; within
    2 ulp of ``math.exp``, tested); beyond, the value at the bound (3.3e-308, 8.2e307); NaN
    in, NaN out. 2ⁿ is built from its bits (exponent field n + 1023), exactly as ldexp."""
    x = _EXP_MAX if x > _EXP_MAX else (_EXP_MIN if x < _EXP_MIN else x)  # noqa: FURB136 (NaN stays NaN)
    shifted = x * _LOG2E + _EXP_SHIFT
    n = shifted - _EXP_SHIFT
    r = (x - n * _EXP_C1) - n * _EXP_C2
    rr = r * r
    px = r * ((_EXP_P0 * rr + _EXP_P1) * rr + _EXP_P2)
    e = 1.0 + 2.0 * (px / ((((_EXP_Q0 * rr + _EXP_Q1) * rr + _EXP_Q2) * rr + _EXP_Q3) - px))
    # The low 12 bits of ``shifted`` are n + 1023; shifted up into the exponent field.
    return e * _bits_float64(_float64_bits(shifted) << 52)


@njit(inline="always", **_OPTIONS)
def _guth_exponent(s, t):
    """ln of position_index_Guth with σ, τ already in degrees."""
    return ((35.2 - 0.31889 * t - 1.22 * exp_bounded(-2.0 * t / 9.0)) * 1e-3 * s
            + (21.0 + 0.26667 * t - 0.002963 * t * t) * 1e-5 * s * s)


@njit(inline="always", **_OPTIONS)
def _iwata_exponent(b):
    """ln of Iwata's position index below the line of sight with β in degrees (as
    :func:`~lsadphoto.geometry.position_index.position_index_Iwata`)."""
    return 6.49e-3 * b + 21e-5 * b * b


@njit(parallel=True, **_OPTIONS,
      aot=("void(float64[:, :, ::1], boolean[:, ::1], int64, float64[::1], float64[::1], "
           "float64[::1], float64[::1], float64[::1], int64, float64, boolean, boolean, "
           "float64[:, ::1], float64[:, ::1], float32[:, ::1], float32[:, ::1])"))
def visual_field_maps(directions, valid, model, p, table, v, u, h, method, cap, angles, field,
                      sigma, tau, position_index, cos_sigma):
    """σ, τ [rad] (float64), position index and cos σ (float32, rounded once from float64)
    of every pixel (see field.visual_field).

    The pixel directions are read from the ``directions`` map where ``model`` is negative;
    otherwise they are computed per row from the fisheye ``model`` (``p``, ``table`` as in
    :func:`fisheye_geometry`, NaN where not ``valid``: the map's values bit for bit) and
    ``directions`` may be any array. ``v, u, h``: line of sight, up and side axes; ``method`` a code of
    :data:`POSITION_INDEX_METHODS`; ``cap`` the Guth/Iwata cap. Only the maps asked for are
    written: σ and τ where ``angles``, the position index and cos σ where ``field``; the others
    are computed into a scratch row per image row (the arrays passed for them are not touched
    and may be of any shape), so that a caller needing only P and cos σ allocates and faults
    in two full-size maps fewer, with the same values bit for bit. The formulas of
    :mod:`~lsadphoto.geometry.position_index` (Iwata's β from the components, as
    position_index_from_components). Per row, between its first and last valid pixel, the
    angles are computed on SIMD lanes (:func:`atan2_nonnegative`; the "evalglare" method
    also Iwata's β, kept in the output row, in rows with a pixel below the line of sight),
    then the position index (:func:`exp_bounded`: also on SIMD lanes, the Guth/Iwata choice
    by a select where a row holds both, :func:`_field_row`); invalid pixels (NaN directions)
    get NaN σ, τ and position index and 0 cos σ — outside that span directly.
    """
    rows, cols = valid.shape
    # Flat rows: the loads vectorise (interleaved). (A map of any shape where it is not read.)
    flat = directions.reshape(rows, 3 * cols) if model < 0 else directions.reshape(1, -1)
    for i in prange(rows):
        ok = valid[i]
        j0, j1 = _valid_span(ok, cols)
        # The span as arrays of its own: loops over range(n) index from 0, which the compiler
        # knows to be non-negative (no wraparound select) and vectorises.
        n = j1 - j0
        if model < 0:
            d = flat[i, 3 * j0:3 * j1]
        else:
            centres = np.empty((3, n))
            _centre_row(model, p, table, float(i), float(j0), centres[0], centres[1], centres[2])
            d = _masked_interleaved(centres[0], centres[1], centres[2], ok[j0:j1], n)
        if angles:
            s_row = _field_outputs(i, j0, j1, sigma, np.nan)
            t_row = _field_outputs(i, j0, j1, tau, np.nan)
        else:
            s_row, t_row = np.empty(n), np.empty(n)
        p_row, c_row = np.empty(n), np.empty(n)
        _field_row(d, ok[j0:j1], n, v, u, h, method, cap, angles, field, s_row, t_row, p_row,
                   c_row)
        if field:
            _store_field_row(i, j0, j1, p_row, c_row, position_index, cos_sigma)
