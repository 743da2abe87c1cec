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
from dataclasses import dataclass, replace

import numpy as np
from .._compiled import njit, prange, row_blocks, run_blocks

from .._validation import check_choice

__all__ = [
    "BACKGROUND_METHODS",
    "FieldSums",
    "evaluated_field",
    "field_sums",
    "NoiseMoments",
    "noise_moments",
    "vertical_illuminance",
    "mean_luminance",
    "background_luminance",
]

#: Background-luminance definitions (evalglare ``-q 0/1/2``).
BACKGROUND_METHODS = ("CIE", "mean", "Ev")


@njit(parallel=True, cache=True, error_model="numpy", nogil=True,
      aot=tuple(f"void({L}[::1], float64[::1], {C}[::1], boolean[::1])"
                for L in ("float64", "float32") for C in ("float64", "float32")))
def _evaluated_field_kernel(luminance, solid_angle, cos_sigma, out):
    n = out.size
    step = 1 << 16
    for k in prange((n + step - 1) // step):
        for i in range(k * step, min(n, (k + 1) * step)):
            out[i] = (np.abs(luminance[i]) < np.inf) & (solid_angle[i] > 0) & (cos_sigma[i] >= 0)


def evaluated_field(luminance, solid_angle, cos_sigma):
    """Mask of the pixels that take part in field integrals (finite L, ω > 0, cos σ ≥ 0).

    Arrays of one shape are tested in one compiled pass; others broadcast (numpy).
    """
    arrays = [np.asarray(a) for a in (luminance, solid_angle, cos_sigma)]
    if arrays[0].ndim == 0 or any(a.shape != arrays[0].shape or a.dtype.kind != "f" for a in arrays):
        return np.isfinite(arrays[0]) & (arrays[1] > 0) & (arrays[2] >= 0)
    out = np.empty(arrays[0].shape, dtype=bool)
    flat = [np.ascontiguousarray(a).reshape(-1) for a in (*arrays, out)]
    # Blocks of whole chunks on threads (each value a function of its own pixel).
    workers = _evaluated_field_kernel.threads_for(*flat)
    run_blocks(lambda a, b: _evaluated_field_kernel(*(x[a:b] for x in flat)),
               row_blocks(out.size, workers, 1 << 16), workers)
    return out


def _sums(luminance, solid_angle, cos_sigma, mask):
    """:func:`field_sums` of per-pixel arrays (broadcast), ``mask`` as its source mask."""
    L, w, c = np.broadcast_arrays(np.asarray(luminance, dtype=np.float64), solid_angle,
                                  cos_sigma)
    m = np.zeros(L.shape, dtype=bool) if mask is None else np.broadcast_to(
        np.asarray(mask, dtype=bool), L.shape)
    # P = 1 everywhere: the position index enters only ugr_sum, unused here. In cos σ's
    # precision (a visual field's float32 map: the compiled signatures pair them).
    return field_sums(L, w, c, np.ones(L.shape, dtype=np.result_type(c.dtype, np.float32)), m)


def vertical_illuminance(luminance, solid_angle, cos_sigma, *, mask=None):
    """Illuminance at the eye on the plane facing the line of sight, E_v = Σ L·cos σ·ω [lx].

    ``mask`` restricts the sum further (e.g. to glare-source pixels, giving E_dir). The value
    is that of :func:`field_sums` (``illuminance``, or ``source_illuminance`` with the mask),
    which :func:`~lsadphoto.metrics.score.score_map` uses.

    Examples
    --------
    A uniform hemisphere of 1 cd·m⁻² gives E_v = π lx; one pixel of it:

    >>> float(vertical_illuminance(np.array([1.0]), np.array([2 * np.pi]), np.array([0.5])))
    3.141592653589793
    """
    sums = _sums(luminance, solid_angle, cos_sigma, mask)
    return sums.illuminance if mask is None else sums.source_illuminance


def mean_luminance(luminance, solid_angle, cos_sigma, *, mask=None):
    """Solid-angle-weighted mean luminance L̄ = Σ L·ω / Σ ω over the field [cd·m⁻²].

    ``mask`` restricts the mean further. NaN when the field is empty. The value is that of
    :attr:`FieldSums.mean_luminance` (of the sums outside a source mask ``~mask`` with one).
    """
    if mask is None:
        return _sums(luminance, solid_angle, cos_sigma, None).mean_luminance
    sums = _sums(luminance, solid_angle, cos_sigma, ~np.asarray(mask, dtype=bool))
    if not sums.background_solid_angle > 0:
        return math.nan
    return sums.background_luminance_solid_angle / sums.background_solid_angle


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

    The value is :meth:`FieldSums.background_luminance` of the map's :func:`field_sums` — the
    one definition that :func:`~lsadphoto.metrics.score.score_map` also uses.

    Examples
    --------
    A uniform field of 50 cd·m⁻² over the front hemisphere has L_b = 50 in CIE mode
    (E_v = π·50):

    >>> L = np.array([50.0]); w = np.array([2 * np.pi]); c = np.array([0.5])
    >>> round(background_luminance(L, w, c, np.array([False])), 9)
    50.0
    """
    check_choice(method, "background luminance method", BACKGROUND_METHODS)
    return _sums(luminance, solid_angle, cos_sigma, source_mask).background_luminance(method)


# --- all field sums in one pass ----------------------------------------------------------------

#: Pixels per chunk of :func:`field_sums`; chunks are summed separately (in parallel) and the
#: chunk sums added in order, so that the result does not depend on the number of threads.
_CHUNK = 1 << 16


@dataclass(frozen=True)
class FieldSums:
    """Sums over the evaluated field (finite L, ω > 0, cos σ ≥ 0), split by a source mask.

    Attributes
    ----------
    n_pixels, n_sources : int
        Pixels of the field; of them, source pixels.
    solid_angle, luminance_solid_angle, illuminance : float
        Σω [sr], ΣL·ω [cd·m⁻²·sr], ΣL·cos σ·ω = E_v [lx] over the field.
    source_illuminance : float
        ΣL·cos σ·ω over the source pixels, E_dir [lx].
    background_solid_angle, background_luminance_solid_angle, background_illuminance : float
        Σω, ΣL·ω and ΣL·cos σ·ω over the non-source pixels.
    ugr_sum : float
        ΣL²·ω/P² over the source pixels whose term is finite [cd²·m⁻⁴·sr] (as
        :func:`~lsadphoto.metrics.ugr.ugr_sum`: P = NaN counts as P = ∞).
    """

    n_pixels: int
    n_sources: int
    solid_angle: float
    luminance_solid_angle: float
    illuminance: float
    source_illuminance: float
    background_solid_angle: float
    background_luminance_solid_angle: float
    background_illuminance: float
    ugr_sum: float

    @property
    def mean_luminance(self):
        """Solid-angle-weighted mean luminance L̄ = ΣL·ω/Σω over the field [cd·m⁻²]; NaN
        when the field is empty."""
        if not self.solid_angle > 0:
            return math.nan
        return self.luminance_solid_angle / self.solid_angle

    def background_luminance(self, method="CIE"):
        """Background luminance L_b [cd·m⁻²] by ``method`` (see :func:`background_luminance`)."""
        check_choice(method, "background luminance method", BACKGROUND_METHODS)
        if method == "CIE":  # (E_v − E_dir)/π, summed over the non-source pixels: no cancellation
            return self.background_illuminance / math.pi
        if method == "Ev":
            return self.illuminance / math.pi
        if self.background_solid_angle > 0:
            return self.background_luminance_solid_angle / self.background_solid_angle
        return self.mean_luminance  # every pixel a source: the field's mean

    def quantities(self, background_method="CIE"):
        """The field quantities of :data:`~lsadphoto.metrics.registry.FIELD` and the pixel
        sum of pixel-wise UGR, as a dict: E_v and E_dir [lx], L_b and L̄ [cd·m⁻²],
        ``pixel_ugr_sum`` [cd²·m⁻⁴·sr]."""
        return {"vertical_illuminance": self.illuminance,
                "direct_illuminance": self.source_illuminance,
                "background_luminance": self.background_luminance(background_method),
                "mean_luminance": self.mean_luminance, "pixel_ugr_sum": self.ugr_sum}

    def scaled(self, factor):
        """The sums of the luminances scaled by ``factor`` (ΣL²ω/P² by its square)."""
        k = float(factor)
        return replace(self, luminance_solid_angle=k * self.luminance_solid_angle,
                       illuminance=k * self.illuminance,
                       source_illuminance=k * self.source_illuminance,
                       background_luminance_solid_angle=k * self.background_luminance_solid_angle,
                       background_illuminance=k * self.background_illuminance,
                       ugr_sum=k * k * self.ugr_sum)


@njit(parallel=True, cache=True, error_model="numpy", nogil=True,
      aot=tuple(f"Tuple((float64[:, ::1], int64[:, ::1]))({L}[::1], float64[::1], {C}[::1], "
                f"{C}[::1], boolean[::1], int64)" for L in ("float64", "float32")
                for C in ("float64", "float32")))
def _field_sums(luminance, solid_angle, cos_sigma, position_index, source_mask, chunk):
    n = luminance.size
    n_chunks = (n + chunk - 1) // chunk
    sums = np.zeros((n_chunks, 8))
    counts = np.zeros((n_chunks, 2), np.int64)
    for k in prange(n_chunks):
        s = np.zeros(8)
        n_field, n_source = 0, 0
        for i in range(k * chunk, min(n, (k + 1) * chunk)):
            L = np.float64(luminance[i])  # float() of a float32 stays float32 in numba
            w = float(solid_angle[i])
            c = np.float64(cos_sigma[i])  # float32 maps too (VisualField)
            if not (math.isfinite(L) and w > 0 and c >= 0):
                continue
            n_field += 1
            lw = L * w
            e = L * c * w
            s[0] += w
            s[1] += lw
            s[2] += e
            if source_mask[i]:
                n_source += 1
                s[3] += e
                P = np.float64(position_index[i])
                term = L * L * w / (P * P)
                if math.isfinite(term):
                    s[7] += term
            else:
                s[4] += w
                s[5] += lw
                s[6] += e
        sums[k] = s
        counts[k, 0] = n_field
        counts[k, 1] = n_source
    return sums, counts


def field_sums(luminance, solid_angle, cos_sigma, position_index, source_mask):
    """Every field sum that :func:`~lsadphoto.metrics.score.score_map` needs, in one pass.

    The evaluated field is that of :func:`evaluated_field`; sums are float64, taken in
    chunks of 2¹⁶ pixels (in parallel) whose sums are added in order.

    Parameters
    ----------
    luminance, solid_angle, cos_sigma, position_index : ndarray
        Per pixel (any shape, all the same): L [cd·m⁻²], ω [sr], cos σ [–], P [–].
    source_mask : ndarray of bool
        Glare-source pixels.

    Returns
    -------
    FieldSums

    Examples
    --------
    >>> s = field_sums(np.array([50.0, 4000.0]), np.array([1.0, 0.01]), np.array([0.5, 1.0]),
    ...                np.array([2.0, 1.0]), np.array([False, True]))
    >>> s.illuminance, s.source_illuminance, s.ugr_sum
    (65.0, 40.0, 160000.0)
    """
    arrays = [np.ascontiguousarray(a).ravel() for a in (luminance, solid_angle, cos_sigma,
                                                        position_index)]
    mask = np.ascontiguousarray(source_mask, dtype=bool).ravel()
    # Blocks of whole chunks on threads: the same chunk sums, added in the same order.
    flat = (*arrays, mask)
    workers = _field_sums.threads_for(*flat, _CHUNK)
    n_chunks = -(-mask.size // _CHUNK)
    parts = run_blocks(lambda a, b: _field_sums(*(x[a * _CHUNK:b * _CHUNK] for x in flat), _CHUNK),
                       row_blocks(n_chunks, workers) or [(0, 0)], workers)
    sums = np.concatenate([part[0] for part in parts])
    counts = np.concatenate([part[1] for part in parts])
    total = sums.sum(axis=0)
    n_field, n_source = (int(v) for v in counts.sum(axis=0))
    return FieldSums(n_field, n_source, *(float(v) for v in total[[0, 1, 2, 3, 4, 5, 6, 7]]))


# --- per-pixel noise: second moments of the field sums -----------------------------------------

@dataclass(frozen=True)
class NoiseMoments:
    """Means and covariances of the sums of :class:`FieldSums` under independent per-pixel noise.

    With pixel luminances L_j + ε_j, ε_j independent with variance v_j, every linear sum
    Σ a_j·L_j gets the variance Σ a_j²·v_j and two sums the covariance Σ a_j·b_j·v_j; sums
    over disjoint pixel sets are independent. The background (non-source field pixels) and
    each source s are such sets. The pixel-UGR sum U = Σ u_j·L_j² (u_j = ω_j/P_j²) is
    quadratic: U + 2Σu_j·L_j·ε_j + Σu_j·ε_j², whose linear part enters the covariances and
    whose quadratic part has mean Σu_j·v_j and, for Gaussian ε, variance 2Σu_j²·v_j² and no
    correlation with the linear sums.

    Attributes
    ----------
    background : ndarray, shape (2, 2)
        Covariance of (ΣL·cos σ·ω, ΣL·ω) over the background pixels.
    source_means : ndarray, shape (n, 3)
        Per source (label order): ΣL·cos σ·ω [lx], ΣL·ω [cd·m⁻²·sr], ΣL²·ω/P².
    source_covariances : ndarray, shape (n, 3, 3)
        Their covariances (linear part for the third).
    quadratic_mean, quadratic_variance : float
        Mean and variance of Σu_j·ε_j² over all source pixels.
    """

    background: np.ndarray
    source_means: np.ndarray
    source_covariances: np.ndarray
    quadratic_mean: float
    quadratic_variance: float


@njit(cache=True, error_model="numpy", nogil=True,
      aot=("Tuple((float64[::1], float64[:, ::1], float64[:, ::1], float64[::1]))(float64[::1], "
           "float64[::1], float64[::1], float64[::1], int64[::1], float64[::1], int64)"))
def _noise_moments(luminance, solid_angle, cos_sigma, position_index, labels, variance, n):
    background = np.zeros(3)
    means = np.zeros((n, 3))
    second = np.zeros((n, 6))  # EE, ET, TT, EU, TU, UU
    quadratic = np.zeros(2)
    for i in range(luminance.size):
        L = float(luminance[i])
        w = float(solid_angle[i])
        c = float(cos_sigma[i])
        if not (math.isfinite(L) and w > 0 and c >= 0):
            continue
        v = float(variance[i])
        if not v > 0:
            v = 0.0
        k = labels[i] - 1
        if k < 0:
            background[0] += v * w * w * c * c
            background[1] += v * w * w * c
            background[2] += v * w * w
            continue
        P = float(position_index[i])
        u = w / (P * P)
        if not math.isfinite(u * L * L):
            u = 0.0
        means[k, 0] += L * w * c
        means[k, 1] += L * w
        means[k, 2] += u * L * L
        second[k, 0] += v * w * w * c * c
        second[k, 1] += v * w * w * c
        second[k, 2] += v * w * w
        second[k, 3] += 2.0 * u * L * v * w * c
        second[k, 4] += 2.0 * u * L * v * w
        second[k, 5] += 4.0 * u * u * L * L * v
        quadratic[0] += u * v
        quadratic[1] += 2.0 * u * u * v * v
    return background, means, second, quadratic


def noise_moments(luminance, solid_angle, cos_sigma, position_index, source_labels, variance,
                  n_sources):
    """The :class:`NoiseMoments` of a map's field sums, in one (serial, float64) pass.

    Parameters
    ----------
    luminance, solid_angle, cos_sigma, position_index : ndarray, shape (rows, cols)
        L [cd·m⁻²], ω [sr], cos σ [–], P [–]; the field is that of :func:`evaluated_field`.
    source_labels : ndarray of int, shape (rows, cols)
        Source number + 1 per pixel, 0 for the background.
    variance : ndarray, shape (rows, cols)
        Variance of each pixel's luminance noise [cd²·m⁻⁴] (NaN or ≤ 0: no noise).
    n_sources : int
        Number of sources (largest label).

    Returns
    -------
    NoiseMoments

    Examples
    --------
    Two background pixels of variance 4 and 9, ω = 0.5 and 1, cos σ = 1: the variance of E_v is
    4·0.25 + 9·1 = 10:

    >>> m = noise_moments(np.array([10.0, 20.0]), np.array([0.5, 1.0]), np.ones(2), np.ones(2),
    ...                   np.zeros(2, int), np.array([4.0, 9.0]), 0)
    >>> float(m.background[0, 0])
    10.0
    """
    flat = [np.ascontiguousarray(a, dtype=np.float64).ravel()
            for a in (luminance, solid_angle, cos_sigma, position_index, variance)]
    labels = np.ascontiguousarray(source_labels, dtype=np.int64).ravel()
    background, means, second, quadratic = _noise_moments(*flat[:4], labels, flat[4],
                                                          int(n_sources))
    ee, et, tt, eu, tu, uu = second.T
    covariances = np.stack([np.stack([ee, et, eu], -1), np.stack([et, tt, tu], -1),
                            np.stack([eu, tu, uu], -1)], -2)
    return NoiseMoments(np.array([[background[0], background[1]], [background[1], background[2]]]),
                        means, covariances, float(quadratic[0]), float(quadratic[1]))
