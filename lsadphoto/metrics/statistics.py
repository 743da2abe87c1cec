"""Luminance statistics over the visual field and in bands around the line of sight.

Statistics are weighted by solid angle: a quantile q is the luminance below which a
fraction q of the *field's solid angle* lies (not of the pixel count, which a fisheye
distributes unevenly over the field) — the inverse of the weighted distribution function
(Hyndman & Fan 1996, definition 1, with weights), read from a fine logarithmic histogram
(see :data:`QUANTILE_BINS_PER_DECADE`). Rings are bands of σ, the angle from the line of
sight.

References
----------
Hyndman, R. J., Fan, Y. (1996), Sample quantiles in statistical packages, Am. Stat. 50(4),
361–365.
"""

import math

import numpy as np
from .._compiled import njit, prange, run_blocks

__all__ = ["DEFAULT_RING_EDGES_DEG", "DEFAULT_PERCENTILES", "QUANTILE_BINS_PER_DECADE",
           "luminance_statistics"]

#: σ edges [deg] of the default rings: central, near and far periphery.
DEFAULT_RING_EDGES_DEG = (0.0, 30.0, 60.0, 90.0)
#: Percentiles reported by default [%].
DEFAULT_PERCENTILES = (5.0, 25.0, 50.0, 75.0, 95.0)
#: Resolution of the quantiles: histogram bins per decade of luminance. A quantile is
#: the centre of its bin (clipped to the region's min and max), so it is within a relative
#: 10^(1/(2·2000)) − 1 = 0.058 % of the exact weighted quantile — far below any luminance
#: measurement's uncertainty — at the cost of one pass over the pixels instead of a sort.
QUANTILE_BINS_PER_DECADE = 2000


#: Stripes of the image summed separately (in parallel) and then added in order, so that
#: results do not depend on the number of threads.
_STRIPES = 16


@njit(inline="always", cache=True, error_model="numpy", nogil=True)
def _group(c, cos_edges, n_rings):
    """Ring number of cos σ = ``c`` (``cos_edges`` decreasing; the last ring includes its
    upper σ edge), ``n_rings`` outside every ring: ``n_rings − #{edges < c}``, as
    ``np.searchsorted`` on the ascending edges, side "left"."""
    if not (c <= cos_edges[0] and c >= cos_edges[n_rings]):
        return n_rings
    if c == cos_edges[n_rings]:
        return n_rings - 1
    below = 0
    for k in range(n_rings + 1):
        if cos_edges[k] < c:
            below += 1
    return n_rings - below


@njit(parallel=True, cache=True, error_model="numpy", nogil=True,
      aot=tuple(f"float64[:, ::1]({L}[::1], float64[::1], {C}[::1], int64)"
                for L in ("float64", "float32") for C in ("float64", "float32")))
def _positive_range(luminance, solid_angle, cos_sigma, n_stripes):
    """Per stripe: the smallest and largest positive L of the evaluated field (finite L,
    ω > 0, cos σ ≥ 0); +inf and −inf where there is none."""
    n = luminance.size
    out = np.empty((n_stripes, 2))
    step = (n + n_stripes - 1) // n_stripes
    for k in prange(n_stripes):
        lo, hi = np.inf, -np.inf
        for i in range(k * step, min(n, (k + 1) * step)):
            L = np.float64(luminance[i])
            ok = (np.abs(L) < np.inf) & (solid_angle[i] > 0) & (cos_sigma[i] >= 0) & (L > 0)
            lo = min(lo, L if ok else np.inf)
            hi = max(hi, L if ok else -np.inf)
        out[k, 0] = lo
        out[k, 1] = hi
    return out


@njit(parallel=True, cache=True, error_model="numpy", nogil=True,
      aot=tuple(f"void({L}[::1], float64[::1], {C}[::1], float64[::1], int64, float64, "
                "int64, float64, int64[:, ::1], float64[:, :, ::1], float64[:, ::1], "
                "float64[:, ::1], float64[:, :, ::1])" for L in ("float64", "float32")
                for C in ("float64", "float32")))
def _accumulate(luminance, solid_angle, cos_sigma, cos_edges, n_stripes, origin, n_bins,
                per_decade, count, sums, low, high, hist):
    """Per stripe k and group g (ring, or outside every ring): pixel count ``count[k, g]``,
    ``sums[k, :, g]`` = (Σω, ΣL·ω, Σω at L ≤ 0), min and max L, and Σω per bin of log10 L
    (``hist[k, g, bin]``, positive L). Pixels outside the evaluated field are skipped."""
    n = luminance.size
    n_rings = cos_edges.size - 1
    n_groups = n_rings + 1
    step = (n + n_stripes - 1) // n_stripes
    decreasing = True
    for r in range(n_rings):
        decreasing &= cos_edges[r] > cos_edges[r + 1]
    for k in prange(n_stripes):
        # Accumulate locally (no false sharing of the small output rows between threads).
        k_count = np.zeros(n_groups, np.int64)
        k_sums = np.zeros((3, n_groups))
        k_low = np.full(n_groups, np.inf)
        k_high = np.full(n_groups, -np.inf)
        k_hist = hist[k]
        last_L, last_bin = np.nan, 0  # neighbours often share a value: one log10 for a run
        # The current group's accumulators in registers, stored back when the group changes
        # (rings are concentric: a row crosses few borders): every sum is still added to in
        # pixel order, so the results are the same bits.
        g = n_rings
        count_g, w_g, lw_g, zero_g = k_count[g], k_sums[0, g], k_sums[1, g], k_sums[2, g]
        low_g, high_g = k_low[g], k_high[g]
        # The last ring found, as its open-closed interval of cos σ (cos_edges[r + 1],
        # cos_edges[r]]: where the edges decrease, a pixel inside it is in that ring
        # (:func:`_group`), without the search over the edges (neighbouring pixels mostly
        # share a ring).
        ring, ring_lo, ring_hi = n_rings, np.inf, -np.inf
        for i in range(k * step, min(n, (k + 1) * step)):
            L = np.float64(luminance[i])
            w = np.float64(solid_angle[i])
            c = np.float64(cos_sigma[i])
            if not ((np.abs(L) < np.inf) & (w > 0) & (c >= 0)):
                continue
            if ring_lo < c <= ring_hi:
                group = ring
            else:
                group = _group(c, cos_edges, n_rings)
                if group < n_rings and decreasing:
                    ring, ring_lo, ring_hi = group, cos_edges[group + 1], cos_edges[group]
            if group != g:
                k_count[g], k_sums[0, g], k_sums[1, g], k_sums[2, g] = count_g, w_g, lw_g, zero_g
                k_low[g], k_high[g] = low_g, high_g
                g = group
                count_g, w_g, lw_g, zero_g = k_count[g], k_sums[0, g], k_sums[1, g], k_sums[2, g]
                low_g, high_g = k_low[g], k_high[g]
            count_g += 1
            w_g += w
            lw_g += L * w
            if L > 0:
                if L != last_L:
                    last_L = L
                    last_bin = min(int((math.log10(L) - origin) * per_decade), n_bins - 1)
                k_hist[g, last_bin] += w
            else:
                zero_g += w
            low_g = min(low_g, L)
            high_g = max(high_g, L)
        k_count[g], k_sums[0, g], k_sums[1, g], k_sums[2, g] = count_g, w_g, lw_g, zero_g
        k_low[g], k_high[g] = low_g, high_g
        count[k] = k_count
        sums[k] = k_sums
        low[k] = k_low
        high[k] = k_high


def _quantiles(hist, zero, origin, percentiles, low, high):
    total = zero + hist.sum()
    if not total > 0:
        return [None] * len(percentiles)
    cum = np.cumsum(hist)
    out = []
    for p in percentiles:
        target = p / 100.0 * total
        if target <= zero:
            out.append(0.0)
            continue
        b = int(np.searchsorted(cum, target - zero, side="left"))
        value = 10.0 ** (origin + (min(b, hist.size - 1) + 0.5) / QUANTILE_BINS_PER_DECADE)
        out.append(float(min(max(value, low), high)))
    return out


def luminance_statistics(luminance, solid_angle, cos_sigma, *,
                         ring_edges_deg=DEFAULT_RING_EDGES_DEG, percentiles=DEFAULT_PERCENTILES,
                         positive_range=None):
    """Solid-angle-weighted luminance statistics [cd·m⁻²] of the field and of σ rings.

    Parameters
    ----------
    luminance, solid_angle, cos_sigma : ndarray
        Per pixel (any shape): L [cd·m⁻²], ω [sr], cos σ [–].
    ring_edges_deg : sequence of float
        σ edges of the rings [deg].
    percentiles : sequence of float
        Percentiles of the solid-angle distribution of luminance [%].
    positive_range : (float, float), optional
        The smallest and largest positive L of the evaluated field (finite L, ω > 0,
        cos σ ≥ 0; +inf, −inf where there is none) where the caller found them already (a
        score, in its pass over the picture): one pass over the pixels fewer. Found here
        otherwise.

    Returns
    -------
    dict
        ``{"field": {...}, "rings": [{"sigma_deg": [lo, hi], ...}, ...]}`` with solid angle
        [sr], pixel count, mean, min, max and percentiles; ``None`` for empty regions.

    Examples
    --------
    Half the solid angle at 10 cd·m⁻², half at 1000: the median is the lower value.

    >>> s = luminance_statistics(np.array([10.0, 1000.0]), np.array([1.0, 1.0]),
    ...                          np.array([1.0, 0.5]), percentiles=(50, 95))
    >>> s["field"]["mean"], {k: round(v, 2) for k, v in s["field"]["percentiles"].items()}
    (505.0, {'50': 10.01, '95': 1000.0})
    """
    L = np.ascontiguousarray(luminance).ravel()
    w = np.ascontiguousarray(solid_angle).ravel()
    c = np.ascontiguousarray(cos_sigma).ravel()
    edges = [float(e) for e in ring_edges_deg]
    # Ring per pixel from cos σ (decreasing in σ); pixels in no ring go to an extra group,
    # which only the field statistics use.
    cos_edges = np.cos(np.radians(edges))
    n_groups = len(edges)
    stripes = max(1, min(_STRIPES, L.size))
    # Each stripe a call of its own on its pixels (the same stripes as one call over all),
    # the calls shared out among threads.
    step = -(-L.size // stripes)
    bounds = [(k * step, min(L.size, (k + 1) * step)) for k in range(stripes)]
    workers = _positive_range.threads_for(L, w, c, stripes)

    def per_stripe(kernel, arguments, outputs=()):
        def stripe(k, _):
            a, b = bounds[k]
            return kernel(L[a:b], w[a:b], c[a:b], *arguments, *(x[k:k + 1] for x in outputs))
        return run_blocks(stripe, [(k, None) for k in range(stripes)], workers)

    if positive_range is None:
        positive = np.concatenate(per_stripe(_positive_range, (1,)))
        positive_range = positive[:, 0].min(), positive[:, 1].max()
    smallest, largest = (float(v) for v in positive_range)
    if smallest <= largest:  # some positive luminance: bins of log10 L from its decade
        origin = math.floor(math.log10(smallest))
        n_bins = int((math.floor(math.log10(largest)) + 1 - origin) * QUANTILE_BINS_PER_DECADE)
    else:
        origin, n_bins = 0, 1
    count = np.empty((stripes, n_groups), np.int64)
    sums = np.empty((stripes, 3, n_groups))
    low = np.empty((stripes, n_groups))
    high = np.empty((stripes, n_groups))
    hist = np.zeros((stripes, n_groups, n_bins))
    per_stripe(_accumulate, (cos_edges, 1, float(origin), n_bins, float(QUANTILE_BINS_PER_DECADE)),
               (count, sums, low, high, hist))
    # Stripes added in order: the result does not depend on the number of threads.
    count = count.sum(axis=0)
    omega, lw, zero = sums.sum(axis=0)
    low, high, hist = low.min(axis=0), high.max(axis=0), hist.sum(axis=0)

    def summary(select):
        sel = np.asarray(select)
        total_w = float(omega[sel].sum())
        if count[sel].sum() == 0 or not total_w > 0:
            return {"solid_angle": total_w, "n_pixels": int(count[sel].sum()), "mean": None,
                    "min": None, "max": None,
                    "percentiles": {f"{p:g}": None for p in percentiles}}
        lo, hi = float(low[sel].min()), float(high[sel].max())
        q = _quantiles(hist[sel].sum(axis=0), float(zero[sel].sum()), origin, percentiles,
                       lo, hi)
        return {"solid_angle": total_w, "n_pixels": int(count[sel].sum()),
                "mean": float(lw[sel].sum() / total_w), "min": lo, "max": hi,
                "percentiles": {f"{p:g}": x for p, x in zip(percentiles, q, strict=True)}}

    out = {"field": summary(list(range(n_groups))), "rings": []}
    for k, (lo, hi) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
        out["rings"].append({"sigma_deg": [lo, hi], **summary([k])})
    return out
