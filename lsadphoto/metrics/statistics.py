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

from .field import evaluated_field

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


def _histograms(luminance, solid_angle, group, n_groups):
    """Solid angle per (group, log-luminance bin), per group at L = 0, and the bin origin."""
    positive = luminance > 0
    logs = np.log10(luminance[positive])
    if logs.size:
        origin = math.floor(float(logs.min()))
        n_bins = int((math.floor(float(logs.max())) + 1 - origin) * QUANTILE_BINS_PER_DECADE)
        bins = np.minimum(((logs - origin) * QUANTILE_BINS_PER_DECADE).astype(np.int64),
                          n_bins - 1)
        index = group[positive] * n_bins + bins
        hist = np.bincount(index, solid_angle[positive], n_groups * n_bins).reshape(n_groups, -1)
    else:
        origin, n_bins, hist = 0, 1, np.zeros((n_groups, 1))
    zero = np.bincount(group[~positive], solid_angle[~positive], n_groups)
    return hist, zero, origin


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
                         ring_edges_deg=DEFAULT_RING_EDGES_DEG, percentiles=DEFAULT_PERCENTILES):
    """Solid-angle-weighted luminance statistics [cd·m⁻²] of the field and of σ rings.

    Parameters
    ----------
    luminance, solid_angle, cos_sigma : ndarray
        Per pixel (any shape): L [cd·m⁻²], ω [sr], cos σ [–].
    ring_edges_deg : sequence of float
        σ edges of the rings [deg].
    percentiles : sequence of float
        Percentiles of the solid-angle distribution of luminance [%].

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
    field = evaluated_field(luminance, solid_angle, cos_sigma)
    everything = field.all()
    L = np.asarray(luminance, dtype=np.float64).ravel()
    w = np.asarray(solid_angle, dtype=np.float64).ravel()
    c = np.asarray(cos_sigma, dtype=np.float64).ravel()
    if not everything:
        keep = field.ravel()
        L, w, c = L[keep], w[keep], c[keep]
    edges = [float(e) for e in ring_edges_deg]
    # Ring number per pixel from cos σ (decreasing in σ; the last ring includes its upper
    # edge); pixels in no ring go to an extra group, which only the field statistics use.
    cos_edges = np.cos(np.radians(edges))
    n_rings = len(edges) - 1
    ring = n_rings - np.searchsorted(cos_edges[::-1], c, side="left")
    ring[c == cos_edges[-1]] = n_rings - 1
    group = np.where((c <= cos_edges[0]) & (c >= cos_edges[-1]), ring, n_rings)
    n_groups = n_rings + 1
    hist, zero, origin = _histograms(L, w, group, n_groups)
    omega = np.bincount(group, w, n_groups)
    lw = np.bincount(group, L * w, n_groups)
    count = np.bincount(group, minlength=n_groups)
    low = np.full(n_groups, np.inf)
    high = np.full(n_groups, -np.inf)
    for k in np.flatnonzero(count):
        values = L[group == k]
        low[k], high[k] = values.min(), values.max()

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
