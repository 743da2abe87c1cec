"""The lighting-quality criterion Q of Budak et al.: weighted luminance-gradient contrast.

The seed paper (Budak, Chembaev, Meshkova, Zheltov, GraphiCon 2020) defines a generalized
contrast K = p·|∇L|/L̄ (its eq. 11), a criterion Q = weighted mean of K divided by a threshold
contrast K_th (eq. 12), a cut-off luminance L_th = N·ΔL (eq. 13) below which contrasts do not
count (eq. 14), and reports N = 50 as the best fit to observers. The equations themselves were
lost from the available text; what is computed here is **the reconstruction of FORMULAS.md
§5.2**, every reconstructed choice a keyword parameter:

1. Field mean ``L̄ = Σ L_j·ω_j / Σ ω_j`` over the *field*: pixels with finite luminance,
   finite direction, ω > 0, a position index that is not NaN, and ``valid`` where given.
2. Pre-blur to the critical detail α [RECONSTRUCTED]: an isotropic Gaussian of angular
   standard deviation ``s = α/√(2π)``, whose width in pixels is s divided by the mean pixel
   pitch of the field ``p = √(Ω_field/n_field)``. The width α/√(2π) makes a sharp luminance
   step of height H produce ``g·α = H`` at its steepest point (the Gaussian's peak slope
   H/(√(2π)·s) times α) — as averaging over a box α wide would — so the cut-off compares the
   luminance change *across one critical detail* with N thresholds, whatever the pixel size.
   This is what makes Q resolution-independent. It needs a pitch of at most about α/2.5
   (σ_px ≥ 1); below σ_px = 0.5 no blur is applied (``settings["blur_sigma_px"]`` = 0).
3. Angular gradient ``g_j = |∇L|`` [cd·m⁻²·rad⁻¹] of the blurred map: pixel derivatives
   L_u, L_v by the Gaussian's derivative (normalised so that a linear ramp gets its slope
   exactly; central differences without blur), turned into an angular gradient by the local
   metric of the pixel grid on the unit sphere: with tangent vectors
   t_u = (d̂(col+1) − d̂(col−1))/2, t_v = (d̂(row+1) − d̂(row−1))/2 (chords rescaled to arcs,
   θ = 2·arcsin(c/2), by its series), E = t_u·t_u, F = t_u·t_v, G = t_v·t_v,
   ``g² = (G·L_u² − 2F·L_u·L_v + E·L_v²)/(EG − F²)``. Non-square and non-orthogonal pixels
   (fisheye rims, pinhole corners) are handled exactly; no arccos of nearly parallel vectors.
4. ``ΔL_j = g_j·α`` (α in radians) and the cut-off [RECONSTRUCTED]: ``c_j = 1`` if
   ``ΔL_j ≥ L_th = N·ΔL_thr(L̄, α)`` (``cutoff="difference"``, default) or if
   ``L_j − L̄ ≥ L_th`` with L_j the blurred luminance (``cutoff="luminance"``).
   ΔL_thr is Adrian's threshold (``threshold="Adrian1989"``, default, positive contrast,
   ``exposure_time``, ``age``) or its large-target Weber limit (``threshold="Weber"``,
   about 0.67 % of L̄ at 100 cd·m⁻² — the reading of the paper's "N = 50 ≈ 1/3 of the mean
   luminance" remark).
5. ``K_j = w_j·c_j·g_j/L̄`` [rad⁻¹] with ``w_j = P_j^(−m)`` (``weight_exponent`` m, default 1;
   P = ∞ gives w = 0 for m > 0) [RECONSTRUCTED: whether p multiplies or divides].
6. ``Q = (Σ_evaluated K_j·ω_j / Σ_field w_j·ω_j) / K_th`` with ``K_th = ΔL_thr/(L̄·α)``
   [rad⁻¹] unless ``k_th`` is given [RECONSTRUCTED: the normalisation and the value of K_th,
   which the paper leaves to future experiments]. The normalisation runs over the same field
   as L̄ (FORMULAS.md §5.2 item 1); field pixels whose gradient cannot be measured count as
   K = 0.

*Evaluated* pixels are field pixels whose whole stencil — the filter kernel, half-width
``int(4·σ_px + 0.5)`` px (at least 1, for the metric) — lies inside the field and the image:
the fisheye rim and the image border are not turned into spurious edges. The band left out
along the rim is ≈ 1.6·α wide (0.5 % of a 180° fisheye's solid angle at α = 10′) and biases Q
low by its share of Σ w·ω at most; normalising by the field rather than the evaluated
pixels keeps Q independent of how that band's width rounds to whole pixels.

Edge cases (no exception; ``QualityResult.reason`` says why): no field pixel, L̄ ≤ 0
("Q undefined", FORMULAS.md §5.2 item 7), no evaluated pixel (e.g. 1×1 and 2×2 maps),
or all weights zero → Q = NaN. No pixel passing the cut → Q = 0.

Discretisation error (measured in ``tests/test_quality.py``): between a map and the same
angular scene with twice the pixels per axis (σ_px 1.16 → 2.32), Q changes by 0.03 % (median)
to 0.2 % for Gaussian luminaires 3–5α wide, up to 1.1 % when a thin kept ring lies
symmetrically on the grid; for a sharp-edged disk the 1× map (σ_px = 1.16) is 2.4 % below
the converged value and σ_px ≥ 2.3 agrees to 0.05 %. Where the pixel pitch varies across the
field the blur, isotropic in pixels at the mean pitch, has an angular width that varies with
the local pitch: a *sharp* edge's ΔL scales by p/p_local across the edge (equidistant 180°
fisheye: 0.90 for edges around the axis; 0.90·θ/sin θ for edges along a radius, i.e. 0.90 at
the centre, 1.00 at 45°, 1.27 at 80°); smooth content is unaffected.

Large maps (> 2²⁰ px) skip, before computing the exact metric, pixels whose gradient bound
|(L_u, L_v)|/p_min stays below the smallest cut-off; p_min is half the smallest pitch on a
16-px sample (valid for direction maps that are smooth on that scale, as camera models are).
The result is identical to the unscreened computation (tested).

References
----------
Budak, V. P., Chembaev, V. D., Meshkova, A. V., Zheltov, V. S. (2020). Luminance
spatial-angular distribution and the quality criterion of lighting. *GraphiCon 2020*, CEUR-WS
Vol-2744, short35 (eqs. 11–14 and §4). Budak et al. (2020), *Light & Engineering* 28(3)
(Moscow Metro calibration, N = 50). Cai, H. (2013). Luminance gradient for evaluating
lighting. *Lighting Res. Technol.* Adrian, W. (1989), *Lighting Res. Technol.* 21(4),
181–188. FORMULAS.md §5.
"""

import functools
import math
from dataclasses import dataclass
from dataclasses import field as dataclass_field

import numpy as np
from .._compiled import njit, populate, prange, row_blocks, run_blocks

from .._validation import check_choice, check_positive
from ..errors import BadInputError
from ..geometry.field import PixelGeometry
from ._filters import (_column_taps, _parity, _taps, correlate_separable, correlate_separable_each,
                       erode_square)
from .adrian import threshold_luminance_difference

__all__ = [
    "BLURS",
    "CUTOFFS",
    "METHODS",
    "THRESHOLDS",
    "QualityResult",
    "gradient_components",
    "q_Budak2021",
    "q_sweep",
    "quality",
]

#: Threshold models for ΔL_thr (see :func:`~lsadphoto.metrics.adrian.threshold_luminance_difference`).
THRESHOLDS = ("Adrian1989", "Weber")
#: Cut-off rules: on the luminance change across α, or on the luminance above the mean.
CUTOFFS = ("difference", "luminance")
#: Pre-blur to the critical detail: Gaussian of angular s.d. α/√(2π), or none (pixel scale).
BLURS = ("gaussian", "none")
#: Methods of :func:`quality`.
METHODS = ("Budak2021",)

#: Gaussian kernel truncation [standard deviations] (scipy's default).
_TRUNCATE = 4.0
#: Relative tolerance on |d̂| = 1 of the direction vectors (checked on a sample).
_UNIT_TOLERANCE = 1e-3
#: Images larger than this [px] are screened before the exact angular gradient is computed:
#: a pixel is a candidate only if the bound g ≤ |(L_u, L_v)|/p_min reaches the cut-off.
_SCREEN_MIN_PIXELS = 1 << 20
#: Stride [px] of the sample that finds the smallest local pitch p_min for the screen, and the
#: safety factor applied to it (the screen assumes the pitch does not fall below half its
#: smallest sampled value between samples — true of every smooth camera model).
_SCREEN_STRIDE = 16
_SCREEN_SAFETY = 0.5
#: Smallest blur [px] applied; below it (pitch > 0.8·α) the gradient is taken by central
#: differences at the pixel scale, as with ``blur="none"``.
_MIN_SIGMA_PX = 0.5
_ARCMIN = math.pi / (180.0 * 60.0)


@dataclass(frozen=True, eq=False)
class QualityResult:
    """Result of :func:`q_Budak2021`.

    Attributes
    ----------
    q : float
        Quality criterion Q [–]; NaN when undefined (see ``reason``).
    mean_luminance : float
        Field mean L̄ [cd·m⁻²].
    threshold_difference : float
        ΔL_thr(L̄, α) [cd·m⁻²] (Adrian's threshold or its Weber limit).
    cutoff_difference : float
        L_th = N·ΔL_thr [cd·m⁻²].
    k_th : float
        Threshold contrast K_th [rad⁻¹].
    contrast : ndarray, shape (rows, cols), float32
        K = w·c·g/L̄ [rad⁻¹]; 0 where cut, NaN where not evaluated. Made when first read
        (by ``make_contrast``, from the candidates' values): Q itself does not need the map,
        4 bytes per pixel that a score writing no contrast picture would fault in and fill
        (24 MP: 96 MB, 0.05–0.08 s).
    kept_fraction : float
        Share of the field's solid angle that passes the cut [–].
    settings : dict
        Every option, and derived values: ``blur_sigma_px`` (0: no blur),
        ``reference_pitch_rad``, ``field_solid_angle_sr``, ``evaluated_solid_angle_sr``,
        ``weighted_solid_angle_sr`` (Σ w·ω over the field), ``n_field``, ``n_evaluated``.
    reason : str or None
        Why ``q`` is NaN; None when it is defined.
    """

    q: float
    mean_luminance: float
    threshold_difference: float
    cutoff_difference: float
    k_th: float
    make_contrast: object = dataclass_field(repr=False)
    kept_fraction: float
    settings: dict
    reason: str | None = None

    @functools.cached_property
    def contrast(self):
        return self.make_contrast()


# --- input checks ------------------------------------------------------------------------------

def _numeric(array, message):
    """``array`` as an ndarray of a numeric dtype (float32 where a conversion is needed)."""
    try:
        out = np.asarray(array)
        if out.dtype.kind not in "fiub":
            out = out.astype(np.float32)
    except (TypeError, ValueError):
        raise BadInputError(message) from None
    return out


def _check_inputs(luminance, directions, solid_angle, position_index, valid):
    """Shapes and types of the inputs. The values (infinite luminance, negative or infinite
    solid angle, P ≤ 0, all as float32) are checked by :func:`_field_kernel` in its pass;
    :func:`_raise_for_values` raises the errors."""
    L = _numeric(luminance, "luminance is not a numeric array")
    if L.ndim != 2:
        raise BadInputError(f"luminance must have shape (rows, cols), got {L.shape}")
    shape = L.shape
    if valid is not None:
        valid = np.asarray(valid)
        if valid.shape != shape or valid.dtype != bool:
            raise BadInputError(f"valid must be a boolean array of shape {shape}")
    if isinstance(directions, PixelGeometry):
        # Unit directions, NaN exactly where the geometry is not valid: the field takes the
        # geometry's validity instead of testing the directions.
        if directions.valid.shape != shape:
            raise BadInputError(f"the pixel geometry has shape {directions.valid.shape}, "
                                f"the luminance {shape}")
        d = directions
        valid = d.valid if valid is None or valid is d.valid else valid & d.valid
    else:
        d = np.asarray(directions)
        if d.dtype.kind not in "fiu":
            raise BadInputError("directions is not a numeric array")
        if d.shape != shape + (3,):
            raise BadInputError(f"directions must have shape {shape + (3,)}, got {d.shape}")
        sample = np.asarray(d[::max(1, shape[0] // 61), ::max(1, shape[1] // 61)], dtype=np.float64)
        norms = np.linalg.norm(sample, axis=-1)
        norms = norms[np.isfinite(norms)]
        if norms.size and np.max(np.abs(norms - 1.0)) > _UNIT_TOLERANCE:
            raise BadInputError("directions must be unit vectors")
    omega = _numeric(solid_angle, "solid_angle is not a numeric array")
    if omega.shape != shape:
        raise BadInputError(f"solid_angle must have shape {shape}, got {omega.shape}")
    if position_index is None:
        P = None
    else:
        P = _numeric(position_index, "position_index is not a numeric array")
        if P.shape != shape:
            raise BadInputError(f"position_index must have shape {shape}, got {P.shape}")
    return L, d, omega, P, valid


def _stencil(directions, index, cols):
    """(flat directions, indices, row step) around the flat pixels ``index`` for
    :func:`_metric`: the map itself, or what a PixelGeometry computes from its model
    (:meth:`~lsadphoto.geometry.PixelGeometry.stencil_directions`)."""
    if isinstance(directions, PixelGeometry):
        return directions.stencil_directions(index)
    d = np.asarray(directions)
    return d.reshape(-1, 3), np.asarray(index, dtype=np.int64), cols


def _raise_for_values(flags):
    if flags[:, 0].any():
        raise BadInputError("luminance contains infinite values (NaN marks unknown pixels)")
    if flags[:, 1].any():
        raise BadInputError("solid_angle must be finite and ≥ 0 sr (NaN marks unknown pixels)")
    if flags[:, 2].any():
        raise BadInputError("position_index must be > 0 (NaN: unknown, inf: weight 0)")


# --- compiled passes over the image ------------------------------------------------------------

_KERNEL_OPTIONS = {"cache": True, "error_model": "numpy", "nogil": True}


@njit(inline="always", **_KERNEL_OPTIONS)
def _weight(P, m):
    """:func:`_weights` for one float32 P."""
    if m == 1:
        return np.float32(1.0) / P
    if m == 2:
        return np.float32(1.0) / (P * P)
    return P ** np.float32(-m)


@njit(parallel=True, **_KERNEL_OPTIONS,
      aot=tuple(f"void({L}[:, ::1], float64[:, ::1], {P}[:, ::1], boolean[:, ::1], "
                "float64[:, :, ::1], boolean, float64, boolean, boolean, boolean, boolean[:, ::1], "
                "int64[::1], float64[:, ::1], int64[:, ::1], boolean[:, ::1])"
                for L in ("float64", "float32") for P in ("float64", "float32")))
def _field_kernel(L, omega, P, valid, d, check_d, m, use_p, use_valid, weighted, field,
                  counts, sums, extent, flags):
    """The field and the field sums, row by row, in float32 as the numpy version had them
    (L, ω and P converted to float32; products L·ω and ω·w in float32, summed in float64).

    field: finite L, ω > 0, P not NaN (``use_p``), ``valid`` (``use_valid``), finite direction
    (``check_d``; else ``d`` is not read: a pixel geometry's validity stands for it).
    Per row: ``counts`` field pixels, ``sums`` (Σω, ΣL·ω, Σω·w), ``extent`` first and last
    field column, ``flags`` infinite L, bad ω, P ≤ 0. Every output is per row, so callers
    share the rows out among threads in blocks (:func:`lsadphoto._compiled.run_blocks`).
    """
    rows, cols = field.shape
    for i in prange(rows):
        n = 0
        s_w, s_lw, s_ww = 0.0, 0.0, 0.0
        first, last = cols, -1
        bad_l, bad_w, bad_p = False, False, False
        for j in range(cols):
            lum = np.float32(L[i, j])
            w = np.float32(omega[i, j])
            bad_l |= np.isinf(lum)
            bad_w |= (w < 0) | np.isinf(w)
            ok = np.isfinite(lum) & (w > 0)
            p = np.float32(1.0)
            if use_p:
                p = np.float32(P[i, j])
                bad_p |= p <= 0
                ok &= not np.isnan(p)
            if use_valid:
                ok &= valid[i, j]
            if check_d:
                ok &= np.isfinite(d[i, j, 0]) & np.isfinite(d[i, j, 1]) & np.isfinite(d[i, j, 2])
            field[i, j] = ok
            if ok:
                n += 1
                s_w += np.float64(w)
                s_lw += np.float64(lum * w)
                if weighted:
                    s_ww += np.float64(w * _weight(p, m))
                first = min(first, j)
                last = j
        counts[i] = n
        sums[i, 0] = s_w
        sums[i, 1] = s_lw
        sums[i, 2] = s_ww
        extent[i, 0] = first
        extent[i, 1] = last
        flags[i, 0] = bad_l
        flags[i, 1] = bad_w
        flags[i, 2] = bad_p


@njit(inline="always", **_KERNEL_OPTIONS)
def _filled_row(L, field, row, c0, lo, hi, out):
    """``out[j]`` = the filled map at columns ``lo + j`` of image row ``row`` (``c0 + lo`` …
    ``c0 + hi − 1``): L as float32 on the field, 0 elsewhere."""
    zero = np.float32(0.0)
    # The row's slices (columns ≥ 0: the evaluated pixels' stencils lie in the image), so
    # that the loop reads them as contiguous vectors (2-D indexing made it a gather).
    values = L[row, c0 + lo:c0 + hi]
    inside = field[row, c0 + lo:c0 + hi]
    for j in range(hi - lo):
        out[j] = np.float32(values[j]) if inside[j] else zero


@njit(**_KERNEL_OPTIONS,
      aot=tuple(f"int64({L}[:, ::1], boolean[:, ::1], int64, int64, boolean[:, ::1], "
                "float64[:, ::1], float64[::1], float64[::1], int64, int64, float64, int64, "
                "int64, int64[::1], float64[::1], int64[::1], int64[::1], float32[::1], "
                "float32[::1])" for L in ("float64", "float32")))
def _candidates_kernel(L, field, r0, c0, evaluated, omega, derivative, smooth, parity_d,
                       parity_s, limit, e0, e1, counts, omega_sums, local, index, lu, lv):
    """The pixel derivatives of the filled map at the evaluated pixels of box rows ``e0`` …
    ``e1 − 1`` (the box of ``evaluated`` at (``r0``, ``c0``) of the image), the screen and
    Σω, in one pass and without a map of the derivatives.

    L_u (row pass ``derivative``, column pass ``smooth``) and L_v (``smooth``, then
    ``derivative``) are :func:`~lsadphoto.metrics._filters.correlate_separable`'s values
    bit for bit — the same row and column sums (``_taps``, ``_column_taps``) of the same
    filled values (float32 L on the field, 0 elsewhere; never stored) — computed only over
    each row's span of evaluated pixels (each input row over the union of the spans of the
    output rows its taps reach). Per output row ``i``: ``counts[i − e0]`` the evaluated pixels
    whose bound |(L_u, L_v)| reaches ``limit`` (candidates) and ``omega_sums[i − e0]`` Σω
    over the evaluated pixels (float32 ω, float64 sum, in column order). The candidates go,
    in row-major order, to ``local`` (flat box index), ``index`` (flat image index, ``L``'s
    width) and ``lu``, ``lv`` (float32), whose size is at least the evaluated pixels of the
    rows; returns their number. A block's values do not depend on the other blocks, so
    callers share the rows out among threads (:func:`lsadphoto._compiled.run_blocks`)."""
    box_rows, box_cols = evaluated.shape
    image_cols = L.shape[1]
    rd, rs = derivative.size // 2, smooth.size // 2
    reach = max(rd, rs)
    n_rows = e1 - e0
    first = np.empty(n_rows, dtype=np.int64)
    last = np.empty(n_rows, dtype=np.int64)  # one past the last evaluated column
    i_first, i_last = e1, e0 - 1
    for i in range(e0, e1):
        counts[i - e0] = 0
        omega_sums[i - e0] = 0.0
        ok = evaluated[i]
        j0, j1 = 0, box_cols
        while j0 < j1 and not ok[j0]:
            j0 += 1
        while j1 > j0 and not ok[j1 - 1]:
            j1 -= 1
        first[i - e0], last[i - e0] = j0, j1
        if j0 < j1:
            i_first = min(i_first, i)
            i_last = i
    if i_first > i_last:
        return 0
    # Input row m is kept in slot m % size of its ring for the column pass of the other kernel.
    # float32 rows (each row pass summed in float64, rounded once) and column passes in
    # float32, as correlate_separable: half the bytes that the column passes stream (17 rows
    # for each output row at 24 MP) and twice the SIMD lanes.
    ring_d = np.empty((reach + rs + 1, box_cols), dtype=np.float32)  # after the derivative's
    ring_s = np.empty((reach + rd + 1, box_cols), dtype=np.float32)  # after the smoothing
    filled = np.empty(box_cols + 2 * reach, dtype=np.float32)
    row_sums = np.empty(box_cols)
    acc_u = np.empty(box_cols, dtype=np.float32)
    acc_v = np.empty(box_cols, dtype=np.float32)
    smooth32, derivative32 = smooth.astype(np.float32), derivative.astype(np.float32)
    k = 0
    for src in range(i_first - reach, i_last + reach + 1):
        # The columns the output rows within reach of this input row need.
        lo, hi = box_cols, 0
        for i in range(max(src - reach, i_first), min(src + reach, i_last) + 1):
            if first[i - e0] < last[i - e0]:
                lo = min(lo, first[i - e0])
                hi = max(hi, last[i - e0])
        if lo < hi:
            x = filled[:hi - lo + 2 * reach]
            _filled_row(L, field, r0 + src, c0, lo - reach, hi + reach, x)
            n = hi - lo
            _taps(ring_d[src % ring_d.shape[0], lo:hi], row_sums, x[reach - rd:], derivative, rd,
                  parity_d, n)
            _taps(ring_s[src % ring_s.shape[0], lo:hi], row_sums, x[reach - rs:], smooth, rs,
                  parity_s, n)
        i = src - reach  # the output row whose taps this input row completes
        if i < i_first or first[i - e0] >= last[i - e0]:
            continue
        lo, hi = first[i - e0], last[i - e0]
        n = hi - lo
        _column_taps(acc_u[:n], ring_d[:, lo:hi], i, smooth32, rs, parity_s, n)
        _column_taps(acc_v[:n], ring_s[:, lo:hi], i, derivative32, rd, parity_d, n)
        ok = evaluated[i, lo:hi]
        w_row = omega[r0 + i, c0 + lo:c0 + hi]
        count = 0
        s = 0.0
        for j in range(n):
            if ok[j]:
                s += np.float64(np.float32(w_row[j]))
                a = np.float32(acc_u[j])
                b = np.float32(acc_v[j])
                fa, fb = np.float64(a), np.float64(b)
                if math.sqrt(fa * fa + fb * fb) >= limit:
                    local[k] = i * box_cols + lo + j
                    index[k] = (i + r0) * image_cols + c0 + lo + j
                    lu[k] = a
                    lv[k] = b
                    k += 1
                    count += 1
        counts[i - e0] = count
        omega_sums[i - e0] = s
    return k


@njit(parallel=True, **_KERNEL_OPTIONS,
      aot="void(boolean[:, ::1], int64, int64, float32[:, ::1])")
def _contrast_background(evaluated, r0, c0, out):
    """0 on the evaluated pixels of the box at (r0, c0), NaN elsewhere (float32)."""
    rows, cols = out.shape
    box_rows, box_cols = evaluated.shape
    nan = np.float32(np.nan)
    zero = np.float32(0.0)
    for i in prange(rows):
        inside_row = r0 <= i < r0 + box_rows
        for j in range(cols):
            if inside_row and c0 <= j < c0 + box_cols and evaluated[i - r0, j - c0]:
                out[i, j] = zero
            else:
                out[i, j] = nan


def _check_options(n_thresholds, size_arcmin, weight_exponent, threshold, cutoff, exposure_time, age,
                   blur, k_th):
    size_arcmin = check_positive(size_arcmin, "size_arcmin")
    weight_exponent = check_positive(weight_exponent, "weight_exponent", allow_zero=True)
    check_choice(threshold, "threshold", THRESHOLDS)
    check_choice(cutoff, "cutoff", CUTOFFS)
    check_choice(blur, "blur", BLURS)
    if k_th is not None:
        k_th = check_positive(k_th, "k_th")
    options = {} if threshold == "Weber" else {"exposure_time": exposure_time, "age": age}
    # Validates exposure_time and age early (BadInputError names them).
    threshold_luminance_difference(100.0, size_arcmin, method=threshold, **options)
    if n_thresholds is not None:
        n_thresholds = check_positive(n_thresholds, "n_thresholds", allow_zero=True)
    return n_thresholds, size_arcmin, weight_exponent, k_th, options


# --- the shared computation --------------------------------------------------------------------

@dataclass
class _Analysis:
    shape: tuple
    settings: dict
    mean_luminance: float = math.nan
    threshold_difference: float = math.nan
    k_th: float = math.nan
    reason: str | None = None
    box: tuple = None                      # slices of the field's bounding box
    evaluated: np.ndarray = None           # bool over the box: pixels with a complete stencil
    index: np.ndarray = None               # flat indices of the candidate pixels
    key: np.ndarray = None                 # cut-off quantity of the candidates [cd·m⁻²], float64
    contrast: np.ndarray = None            # w·g/L̄ of the candidates [rad⁻¹], float64
    weighted_contrast: np.ndarray = None   # w·g/L̄·ω of the candidates, float64
    omega: np.ndarray = None               # ω of the candidates [sr], float64
    weighted_solid_angle: float = math.nan  # Σ w·ω over the field
    evaluated_solid_angle: float = math.nan
    field_solid_angle: float = math.nan


@njit(inline="always", **_KERNEL_OPTIONS)
def _arc_over_chord(chord_squared):
    """θ/c for an arc θ = 2·arcsin(c/2) of chord c, from c²: 1 + c²/24 + 3c⁴/640 (error < 1e-7·c⁶)."""
    return 1.0 + chord_squared * (1.0 / 24.0 + chord_squared * (3.0 / 640.0))


@njit(inline="always", **_KERNEL_OPTIONS)
def _metric(directions, i, cols):
    """E, F, G [rad²] of the tangent vectors t_u, t_v at flat pixel ``i`` (float64), from the
    flat directions (n, 3): t_u = (d̂(col+1) − d̂(col−1))/2 rescaled from chord to arc, t_v
    likewise along rows."""
    a0 = np.float64(directions[i + 1, 0]) - directions[i - 1, 0]
    a1 = np.float64(directions[i + 1, 1]) - directions[i - 1, 1]
    a2 = np.float64(directions[i + 1, 2]) - directions[i - 1, 2]
    b0 = np.float64(directions[i + cols, 0]) - directions[i - cols, 0]
    b1 = np.float64(directions[i + cols, 1]) - directions[i - cols, 1]
    b2 = np.float64(directions[i + cols, 2]) - directions[i - cols, 2]
    e = a0 * a0 + a1 * a1 + a2 * a2
    f = a0 * b0 + a1 * b1 + a2 * b2
    g = b0 * b0 + b1 * b1 + b2 * b2
    su = 0.5 * _arc_over_chord(e)
    sv = 0.5 * _arc_over_chord(g)
    return e * su * su, f * su * sv, g * sv * sv


@njit(parallel=True, **_KERNEL_OPTIONS,
      aot=("void(int64[::1], int64[::1], float64[:, ::1], float32[::1], float32[::1], int64, "
           "float64[::1])"))
def _gradient_kernel(index, local, directions, lu, lv, cols, out):
    for k in prange(index.size):
        e, f, g = _metric(directions, index[k], cols)
        du = np.float64(lu[local[k]])
        dv = np.float64(lv[local[k]])
        det = e * g - f * f
        value = (g * du * du - 2.0 * f * du * dv + e * dv * dv) / det
        out[k] = math.sqrt(0.0 if value < 0 else value) if det > 0 else np.nan


@njit(**_KERNEL_OPTIONS, aot="void(int64[::1], float64[:, ::1], int64, float64[:, ::1])")
def _metric_kernel(index, directions, cols, out):
    for k in range(index.size):
        out[k, 0], out[k, 1], out[k, 2] = _metric(directions, index[k], cols)


def _angular_gradient(index, local, directions, lu, lv, cols):
    """|∇L| [cd·m⁻²·rad⁻¹] at flat image ``index`` from the pixel derivatives ``lu``, ``lv`` at
    the same pixels' flat ``local`` indices (float64); ``directions`` a map or a PixelGeometry.

    g² = (G·L_u² − 2F·L_u·L_v + E·L_v²)/(EG − F²): the gradient under the metric of the pixel
    grid on the unit sphere. NaN where the metric is degenerate.
    """
    out = np.empty(index.size)
    flat, at, step = _stencil(directions, index, cols)
    _gradient_kernel(at, local, flat, lu, lv, step, out)
    return out


def _metrics_at(index, directions, cols):
    """E, F, G (n, 3) at the flat pixels ``index``; ``directions`` a map or a PixelGeometry."""
    metric = np.empty((index.size, 3))
    flat, at, step = _stencil(directions, index, cols)
    _metric_kernel(at, flat, step, metric)
    return metric


def _pitch_lower_bound(index, directions, cols):
    """Lower bound [rad] of the smallest local pixel pitch: ``_SCREEN_SAFETY`` × the smallest
    at the sample pixels ``index`` (smaller singular value of the tangent vectors); None if
    there is none."""
    if index.size == 0:
        return None
    metric = _metrics_at(index, directions, cols)
    e, f, g = metric.T
    smallest = 0.5 * (e + g) - np.sqrt(0.25 * (e - g) ** 2 + f * f)  # λ_min of the metric
    smallest = smallest[np.isfinite(smallest)]
    if smallest.size == 0 or not smallest.min() > 0:
        return None
    return _SCREEN_SAFETY * math.sqrt(float(smallest.min()))


def _kernels(sigma_px):
    """Smoothing and derivative kernels (float32 columns) and their radius [px].

    A Gaussian of s.d. ``sigma_px`` truncated at 4σ and normalised to sum 1, and its
    derivative x·G(x) normalised so that Σ x·k(x) = 1 (a linear ramp gets its slope
    exactly). Without blur (σ = 0): the identity and central differences [−½, 0, ½].
    """
    if sigma_px <= 0:
        return np.ones((1, 1), np.float32), np.array([[-0.5], [0.0], [0.5]], np.float32), 1
    radius = max(int(_TRUNCATE * sigma_px + 0.5), 1)
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    gauss = np.exp(-0.5 * (x / sigma_px) ** 2)
    smooth = gauss / gauss.sum()
    derivative = x * gauss / np.sum(x * x * gauss)
    return smooth.astype(np.float32)[:, None], derivative.astype(np.float32)[:, None], radius


def _analyse(luminance, directions, solid_angle, position_index, *, size_arcmin, weight_exponent,
             threshold, cutoff, blur, k_th, threshold_options, valid, n_min):
    L, d, omega, P, valid = _check_inputs(luminance, directions, solid_angle, position_index, valid)
    shape = L.shape
    cols = shape[1]
    alpha = size_arcmin * _ARCMIN
    settings = {"size_arcmin": size_arcmin, "weight_exponent": weight_exponent, "threshold": threshold,
                "cutoff": cutoff, "blur": blur, "k_th": k_th, **threshold_options}
    out = _Analysis(shape=shape, settings=settings)

    # The field: finite L and direction, ω > 0, P not NaN, and ``valid``, and its sums, in one
    # pass (rows shared out among threads).
    settings.update(n_field=0, field_solid_angle_sr=0.0, n_evaluated=0, evaluated_solid_angle_sr=0.0,
                    weighted_solid_angle_sr=math.nan)
    weighted = P is not None and weight_exponent != 0
    rows = shape[0]
    field = np.empty(shape, dtype=bool)
    counts = np.empty(rows, dtype=np.int64)
    sums = np.empty((rows, 3))
    extent = np.empty((rows, 2), dtype=np.int64)
    flags = np.empty((rows, 3), dtype=bool)
    from_map = not isinstance(d, PixelGeometry)
    inputs = (L, omega, L if P is None else P, field if valid is None else valid,
              d if from_map else np.empty((1, 1, 3)))
    options = (from_map, float(weight_exponent), P is not None, valid is not None, weighted)
    outputs = (field, counts, sums, extent, flags)

    def field_rows(a, b):
        _field_kernel(*(x[a:b] for x in inputs[:4]), inputs[4][a:b] if from_map else inputs[4],
                      *options, *(x[a:b] for x in outputs))

    workers = _field_kernel.threads_for(*inputs, *options, *outputs)
    run_blocks(field_rows, row_blocks(rows, workers), workers)
    _raise_for_values(flags)
    rows_used = np.flatnonzero(counts)
    if rows_used.size == 0:
        out.reason = "no valid pixel (finite luminance and direction, ω > 0)"
        return out
    # Work on the bounding box of the field (a fisheye's circle leaves the frame's sides out).
    r0, c0 = int(rows_used[0]), int(extent[rows_used, 0].min())
    box = (slice(r0, int(rows_used[-1]) + 1), slice(c0, int(extent[rows_used, 1].max()) + 1))
    out.box = box
    field_box = field[box]
    n_field = int(counts.sum())
    total_omega = float(np.sum(sums[:, 0]))
    settings.update(n_field=n_field, field_solid_angle_sr=total_omega)
    mean = float(np.sum(sums[:, 1])) / total_omega
    out.mean_luminance = mean
    out.field_solid_angle = total_omega
    pitch = math.sqrt(total_omega / n_field)
    sigma_px = alpha / math.sqrt(2.0 * math.pi) / pitch if blur == "gaussian" else 0.0
    if sigma_px < _MIN_SIGMA_PX:  # pixels coarser than the critical detail: nothing to blur
        sigma_px = 0.0
    smooth, derivative, radius = _kernels(sigma_px)
    settings.update(reference_pitch_rad=pitch, blur_sigma_px=sigma_px)
    if not mean > 0:
        out.reason = f"mean luminance L̄ = {mean:g} cd/m² ≤ 0: Q is undefined"
        return out
    delta = float(threshold_luminance_difference(mean, size_arcmin, method=threshold, **threshold_options))
    out.threshold_difference = delta
    out.k_th = k_th if k_th is not None else delta / (mean * alpha)

    # Σ w·ω over the field: the normalisation of Q.
    if weighted:
        out.weighted_solid_angle = float(np.sum(sums[:, 2]))
    else:
        out.weighted_solid_angle = total_omega
    settings["weighted_solid_angle_sr"] = out.weighted_solid_angle

    # Evaluated pixels: the whole stencil (filter kernel, and ±1 px for the metric) inside the
    # field and the image.
    size = 2 * radius + 1
    box_rows, box_cols = field_box.shape
    if box_rows < size or box_cols < size:
        out.reason = f"no pixel has a complete {size}×{size} stencil inside the field"
        return out
    evaluated = erode_square(field_box, radius)
    out.evaluated = evaluated
    settings["n_evaluated"] = int(np.count_nonzero(evaluated))
    if settings["n_evaluated"] == 0:
        out.reason = f"no pixel has a complete {size}×{size} stencil inside the field"
        return out
    # Candidates: evaluated pixels that may pass the smallest cut-off n_min·ΔL_thr. Indices
    # into the box (``local``) and into the whole image (``index``).
    min_cut = n_min * np.float64(delta)

    def to_image(local):
        return (local // box_cols + r0) * cols + (local % box_cols + c0)

    limit = -math.inf  # the screen: every evaluated pixel unless a bound is found below
    if cutoff == "difference" and evaluated.size > _SCREEN_MIN_PIXELS and min_cut > 0:
        sample = np.flatnonzero(evaluated[::_SCREEN_STRIDE, ::_SCREEN_STRIDE])
        sample_cols = (box_cols + _SCREEN_STRIDE - 1) // _SCREEN_STRIDE
        sample = (sample // sample_cols) * _SCREEN_STRIDE * box_cols + (sample % sample_cols) * _SCREEN_STRIDE
        bound = _pitch_lower_bound(to_image(sample), d, cols)
        if bound is not None:
            # g ≤ |(L_u, L_v)|/p_min: pixels whose bound stays below the cut are cut (float32
            # rounding of L_u, L_v is covered by the 1e-5 margin).
            limit = float(min_cut / alpha * bound * (1.0 - 1e-5))
    # The pixel derivatives (correlation; kx runs along each row) at the evaluated pixels that
    # pass the screen, and Σω of the evaluated pixels, in one pass: no map of the derivatives
    # or of the filled field (rows shared out among threads).
    local, index, lu, lv, omega_sums = _candidates(L, field, r0, c0, evaluated, omega,
                                                   derivative, smooth, limit)
    out.evaluated_solid_angle = float(np.sum(omega_sums))
    settings["evaluated_solid_angle_sr"] = out.evaluated_solid_angle

    if cutoff == "luminance":
        # The smoothed luminance needs the filled map: float32 L on the field, 0 elsewhere.
        filled = np.where(field[box], L[box], 0).astype(np.float32)
        smoothed = correlate_separable(filled, smooth, smooth)
        level = mean + min_cut
        candidates = evaluated & (smoothed >= np.float32(level - 1e-5 * abs(level)))  # float32 margin
        at = np.flatnonzero(candidates)
        key = smoothed.ravel()[at].astype(np.float64) - mean
        keep = key >= min_cut
        at, key = at[keep], key[keep]
        # Every evaluated pixel is a candidate of the pass above (no screen): their positions.
        position = np.searchsorted(local, at)
        index = to_image(at)
        grad = _angular_gradient(index, position, d, lu, lv, cols)
    else:
        grad = _angular_gradient(index, np.arange(local.size), d, lu, lv, cols)
        key = grad * alpha
    out.index = index
    out.key = key
    out.contrast, out.omega, out.weighted_contrast = (np.empty(index.size) for _ in range(3))
    _candidate_values(index, grad, (L if P is None else P).reshape(-1), omega.reshape(-1),
                      float(weight_exponent), weighted, mean, out.contrast, out.omega,
                      out.weighted_contrast)
    if not out.weighted_solid_angle > 0:
        out.reason = "every field pixel has weight 0 (position index ∞)"
    return out


@njit(parallel=True, **_KERNEL_OPTIONS,
      aot=tuple(f"void(int64[::1], float64[::1], {P}[::1], float64[::1], float64, boolean, "
                "float64, float64[::1], float64[::1], float64[::1])"
                for P in ("float64", "float32")))
def _candidate_values(index, grad, P, omega, m, weighted, mean, contrast, omega_out,
                      weighted_contrast):
    """Per candidate (flat image ``index``, gradient ``grad``): the contrast w·g/L̄ with the
    weight w = :func:`_weight` of P in float32 (1 unweighted), ω in float32, and their
    product, in one pass (no temporaries of the candidates' size)."""
    for k in prange(index.size):
        i = index[k]
        w = np.float64(np.float32(_weight(np.float32(P[i]), m))) if weighted else 1.0
        c = w * grad[k] / mean
        o = np.float64(np.float32(omega[i]))
        contrast[k] = c
        omega_out[k] = o
        weighted_contrast[k] = c * o


def _candidates(L, field, r0, c0, evaluated, omega, derivative, smooth, limit):
    """(flat box indices, flat image indices, L_u, L_v) of the evaluated pixels whose bound
    |(L_u, L_v)| reaches ``limit``, in row-major order, and Σω of the evaluated pixels per
    box row (:func:`_candidates_kernel`, blocks of rows on threads; each block's outputs are
    sized to its evaluated pixels, of which only the candidates' pages are touched)."""
    box_rows = evaluated.shape[0]
    kd = np.asarray(derivative, dtype=np.float32).reshape(-1).astype(np.float64)
    ks = np.asarray(smooth, dtype=np.float32).reshape(-1).astype(np.float64)
    counts = np.empty(box_rows, dtype=np.int64)
    omega_sums = np.empty(box_rows)
    fixed = (L, field, int(r0), int(c0), evaluated, omega, kd, ks, _parity(kd), _parity(ks),
             float(limit))

    def buffers(n):
        return (np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64),
                np.empty(n, dtype=np.float32), np.empty(n, dtype=np.float32))

    def block(e0, e1):
        out = buffers(int(np.count_nonzero(evaluated[e0:e1])))
        n = _candidates_kernel(*fixed, e0, e1, counts[e0:e1], omega_sums[e0:e1], *out)
        return [x[:n] for x in out]

    workers = _candidates_kernel.threads_for(*fixed, 0, box_rows, counts, omega_sums,
                                             *buffers(0))
    parts = run_blocks(block, row_blocks(box_rows, workers), workers)
    local, index, lu, lv = (np.concatenate([part[k] for part in parts]) for k in range(4))
    return local, index, lu, lv, omega_sums


def _q_value(kept_sum, analysis):
    return kept_sum / analysis.weighted_solid_angle / analysis.k_th


# --- public API ----------------------------------------------------------------------------------

def q_Budak2021(luminance, directions, solid_angle, position_index, *, n_thresholds=50, size_arcmin=10.0,
                weight_exponent=1, threshold="Adrian1989", cutoff="difference", exposure_time=2.0, age=23,
                blur="gaussian", k_th=None, valid=None):
    """Lighting-quality criterion Q of Budak et al. (reconstruction of FORMULAS.md §5.2).

    Certain (from the paper): K = p·|∇L|/L̄, Q = weighted mean of K over the field divided by
    a threshold contrast K_th, L_th = N·ΔL with ΔL Blackwell's (here Adrian's) threshold at
    L_a = L̄ for the task's critical detail, contrasts below L_th cut off, N = 50.
    Reconstructed (keyword parameters; see the module docstring for the formulas): the
    pre-blur to α (``blur``), the angular gradient and ΔL = g·α, the cut-off rule (``cutoff``),
    the threshold model (``threshold``), the weight w = P^(−m) (``weight_exponent``), the
    normalisation by Σ w·ω and K_th = ΔL_thr/(L̄·α) (``k_th``).

    Parameters
    ----------
    luminance : array_like, shape (rows, cols)
        L [cd·m⁻²]; NaN marks unknown pixels (kept as float32).
    directions : array_like, shape (rows, cols, 3), or PixelGeometry
        Unit direction of each pixel in any fixed frame; NaN where invalid (fisheye rim). Or
        the :class:`~lsadphoto.geometry.PixelGeometry` of the picture, whose ``valid`` then
        bounds the field and which computes the directions Q needs from its camera model
        (no map of the whole picture; the same result).
    solid_angle : array_like, shape (rows, cols)
        ω [sr] of each pixel; pixels with ω = 0 or NaN are outside the field.
    position_index : array_like, shape (rows, cols), or None
        P [–] of each pixel (e.g. :func:`lsadphoto.geometry.position_index`); NaN: outside
        the field; ∞: weight 0. None means P = 1 everywhere.
    n_thresholds : float
        N ≥ 0, the number of thresholds of the cut-off (eq. 13). Default 50 (the paper's best).
    size_arcmin : float
        Critical detail α of the visual task [arcmin], > 0. Default 10′.
    weight_exponent : float
        m in w = P^(−m), ≥ 0 (0: no weighting; 1: UGR's L/P analogy, default; 2: P² as in UGR).
    threshold : {"Adrian1989", "Weber"}
        ΔL_thr: Adrian's threshold for α at L̄ (positive contrast), or its α → ∞ Weber limit.
    cutoff : {"difference", "luminance"}
        Keep a pixel when ΔL = g·α ≥ L_th (default) or when L − L̄ ≥ L_th.
    exposure_time : float
        t [s] of Adrian's threshold (default 2 s; ``np.inf``: no time factor). Unused by "Weber".
    age : float or None
        Observer age [years] of Adrian's threshold, 23–75 (default 23; None: no age factor).
        Unused by "Weber".
    blur : {"gaussian", "none"}
        Pre-blur to α (default) or none (gradient at the pixel scale: Q then depends on the
        resolution).
    k_th : float, optional
        Threshold contrast K_th [rad⁻¹]; default ΔL_thr/(L̄·α). A global scale of Q.
    valid : ndarray of bool, shape (rows, cols), optional
        Restricts the field (e.g. to the observer's front hemisphere or the Guth field).

    Returns
    -------
    QualityResult

    References
    ----------
    Budak, V. P., Chembaev, V. D., Meshkova, A. V., Zheltov, V. S. (2020), GraphiCon 2020,
    CEUR-WS Vol-2744 short35, eqs. (11)–(14). FORMULAS.md §5.2 (reconstruction).

    Examples
    --------
    A uniform field has no gradient: Q = 0 (nothing passes the cut).

    >>> rows = cols = 32
    >>> v, u = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    >>> f = 1.0 / 0.002                                    # pinhole, 0.002 rad per pixel
    >>> d = np.stack([(u - 15.5) / f, (v - 15.5) / f, np.ones((rows, cols))], axis=-1)
    >>> d /= np.linalg.norm(d, axis=-1, keepdims=True)
    >>> omega = 0.002 ** 2 * d[..., 2] ** 3                 # pinhole pixel solid angle
    >>> result = q_Budak2021(np.full((rows, cols), 100.0), d, omega, None, size_arcmin=5.0)
    >>> float(result.q), round(result.mean_luminance, 6)
    (0.0, 100.0)
    """
    n_thresholds, size_arcmin, weight_exponent, k_th, options = _check_options(
        n_thresholds, size_arcmin, weight_exponent, threshold, cutoff, exposure_time, age, blur, k_th)
    analysis = _analyse(luminance, directions, solid_angle, position_index, size_arcmin=size_arcmin,
                        weight_exponent=weight_exponent, threshold=threshold, cutoff=cutoff, blur=blur,
                        k_th=k_th, threshold_options=options, valid=valid, n_min=n_thresholds)
    settings = {"n_thresholds": n_thresholds, **analysis.settings}
    cut = n_thresholds * np.float64(analysis.threshold_difference)
    if analysis.index is None:
        return QualityResult(math.nan, analysis.mean_luminance, analysis.threshold_difference, float(cut),
                             analysis.k_th, lambda: np.full(analysis.shape, np.nan, np.float32),
                             math.nan, settings, analysis.reason)
    kept = analysis.key >= cut

    def make_contrast():
        contrast = np.empty(analysis.shape, np.float32)
        r0, c0 = analysis.box[0].start, analysis.box[1].start
        # Blocks of rows on threads (each block's rows from the box's corner relative to its own).
        workers = _contrast_background.threads_for(analysis.evaluated, r0, c0, contrast)

        def block(a, b):
            populate(contrast[a:b])
            _contrast_background(analysis.evaluated, r0 - a, c0, contrast[a:b])

        run_blocks(block, row_blocks(contrast.shape[0], workers), workers)
        contrast.ravel()[analysis.index[kept]] = analysis.contrast[kept]
        return contrast

    kept_fraction = float(np.sum(analysis.omega[kept])) / analysis.field_solid_angle
    if analysis.reason is not None:
        q = math.nan
    else:
        q = _q_value(float(np.sum(analysis.weighted_contrast[kept])), analysis)
    return QualityResult(q, analysis.mean_luminance, analysis.threshold_difference, float(cut), analysis.k_th,
                         make_contrast, kept_fraction, settings, analysis.reason)


def q_sweep(luminance, directions, solid_angle, position_index, *, n_values=range(1, 101), size_arcmin=10.0,
            weight_exponent=1, threshold="Adrian1989", cutoff="difference", exposure_time=2.0, age=23,
            blur="gaussian", k_th=None, valid=None):
    """Q for many N at once: the map is analysed once and each pixel binned by the cut-offs it passes.

    Equal to :func:`q_Budak2021` at each N (same comparisons ΔL ≥ N·ΔL_thr; sums in another
    order, so to float64 rounding). Options as in :func:`q_Budak2021`.

    Parameters
    ----------
    n_values : iterable of float
        The N values (≥ 0), in any order. Default 1…100 (the paper's Fig. 2 range).

    Returns
    -------
    n_values : ndarray, float64
        As given.
    q : ndarray, float64
        Q at each N; all NaN when Q is undefined (see :func:`q_Budak2021`).

    References
    ----------
    Budak et al. (2020), GraphiCon 2020, Fig. 2 (correlation against N). FORMULAS.md §5.

    Examples
    --------
    >>> rows = cols = 32
    >>> v, u = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    >>> d = np.stack([(u - 15.5) * 0.002, (v - 15.5) * 0.002, np.ones((rows, cols))], axis=-1)
    >>> d /= np.linalg.norm(d, axis=-1, keepdims=True)
    >>> n, q = q_sweep(np.full((rows, cols), 100.0), d, 0.002 ** 2 * d[..., 2] ** 3, None,
    ...                n_values=[10, 50], size_arcmin=5.0)
    >>> n.tolist(), q.tolist()
    ([10.0, 50.0], [0.0, 0.0])
    """
    try:
        n = np.array(list(n_values), dtype=np.float64)
    except (TypeError, ValueError):
        raise BadInputError("n_values must be an iterable of numbers") from None
    if n.ndim != 1 or not np.all(np.isfinite(n) & (n >= 0)):
        raise BadInputError("n_values must be finite numbers ≥ 0")
    _, size_arcmin, weight_exponent, k_th, options = _check_options(
        None, size_arcmin, weight_exponent, threshold, cutoff, exposure_time, age, blur, k_th)
    analysis = _analyse(luminance, directions, solid_angle, position_index, size_arcmin=size_arcmin,
                        weight_exponent=weight_exponent, threshold=threshold, cutoff=cutoff, blur=blur,
                        k_th=k_th, threshold_options=options, valid=valid,
                        n_min=float(n.min()) if n.size else 0.0)
    if analysis.index is None or analysis.reason is not None or n.size == 0:
        return n, np.full(n.shape, np.nan)
    cuts = n * np.float64(analysis.threshold_difference)
    order = np.argsort(cuts, kind="stable")
    sorted_cuts = cuts[order]
    # Pixel j passes the i-th smallest cut-off iff i < bins_j = #{cuts ≤ key_j}.
    candidates = analysis.key >= sorted_cuts[0]
    bins = np.searchsorted(sorted_cuts, analysis.key[candidates].astype(np.float64), side="right")
    per_bin = np.bincount(bins, weights=analysis.weighted_contrast[candidates], minlength=n.size + 1)
    kept_sums = np.cumsum(per_bin[::-1])[::-1][1:]   # kept_sums[i] = Σ over bins > i
    q = np.empty(n.size)
    q[order] = [_q_value(float(s), analysis) for s in kept_sums]
    return n, q


def quality(luminance, directions, solid_angle, position_index, *, method="Budak2021", **options):
    """Lighting-quality criterion by the named method (only "Budak2021": :func:`q_Budak2021`).

    References
    ----------
    See :func:`q_Budak2021`.

    Examples
    --------
    >>> quality(np.ones((1, 1)), np.array([[[0.0, 0.0, 1.0]]]), np.ones((1, 1)), None,
    ...         method="Budak2021").reason
    'no pixel has a complete 3×3 stencil inside the field'
    """
    check_choice(method, "quality method", METHODS)
    return q_Budak2021(luminance, directions, solid_angle, position_index, **options)


def gradient_components(filled, directions, index, *, sigma_px):
    """The angular gradient of Q as two components linear in the map: g² = a² + b².

    ``filled`` is a float32 map with the luminance on Q's field and 0 elsewhere; its pixel
    derivatives L_u, L_v (the kernels of :func:`q_Budak2021` for a blur of ``sigma_px``
    pixels, 0 for none) and the metric E, F, G at the flat pixels ``index`` give
    a = √(G/(EG − F²))·(L_u − F·L_v/G) and b = L_v/√G [cd·m⁻²·rad⁻¹], whose a² + b² is
    the g² that Q uses (the Cholesky factor of the inverse metric). Both are linear in the
    map, so a superposition of maps has the superposed components (what the design
    module's batch evaluator uses). NaN where the metric is degenerate.

    Parameters
    ----------
    filled : ndarray, shape (rows, cols), float32
    directions : ndarray, shape (rows, cols, 3), or PixelGeometry
    index : ndarray of int
        Flat pixels with a complete stencil (Q's evaluated pixels).
    sigma_px : float
        ``settings["blur_sigma_px"]`` of :func:`q_Budak2021` for this field.

    Returns
    -------
    (a, b) : tuple of ndarray, float64
    """
    smooth, derivative, _ = _kernels(float(sigma_px))
    image = np.ascontiguousarray(filled, dtype=np.float32)
    lu, lv = (g.ravel()[index].astype(np.float64) for g in
              correlate_separable_each(image, [(derivative, smooth), (smooth, derivative)]))
    e, f, g = _metrics_at(np.asarray(index, dtype=np.int64), directions, image.shape[1]).T
    det = e * g - f * f
    with np.errstate(invalid="ignore", divide="ignore"):
        good = (det > 0) & (g > 0)
        a = np.where(good, np.sqrt(g / det) * (lu - f * lv / g), np.nan)
        b = np.where(good, lv / np.sqrt(g), np.nan)
    return a, b
