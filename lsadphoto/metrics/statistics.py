"""Luminance statistics over the visual field and in bands around the line of sight.

Statistics are weighted by solid angle: a quantile q is the luminance below which a
fraction q of the *field's solid angle* lies (not of the pixel count, which a fisheye
distributes unevenly over the field). Rings are bands of σ (angle from the line of sight).

References
----------
Hyndman, R. J., Fan, Y. (1996), Sample quantiles in statistical packages, Am. Stat. 50(4),
361–365 (the weighted inverse-CDF quantile used here is their definition 4 with weights).
"""

import math

import numpy as np

from .field import evaluated_field

__all__ = ["DEFAULT_RING_EDGES_DEG", "DEFAULT_PERCENTILES", "luminance_statistics",
           "weighted_quantile"]

#: σ edges [deg] of the default rings: central, near and far periphery.
DEFAULT_RING_EDGES_DEG = (0.0, 30.0, 60.0, 90.0)
#: Percentiles reported by default [%].
DEFAULT_PERCENTILES = (5.0, 25.0, 50.0, 75.0, 95.0)


def weighted_quantile(values, weights, quantiles):
    """Quantiles of ``values`` weighted by ``weights`` (inverse of the weighted CDF).

    Examples
    --------
    >>> weighted_quantile(np.array([1.0, 2.0, 3.0]), np.array([1.0, 1.0, 2.0]), [0.5])
    array([2.])
    """
    order = np.argsort(values, kind="stable")
    v = np.asarray(values, dtype=np.float64)[order]
    cdf = np.cumsum(np.asarray(weights, dtype=np.float64)[order])
    cdf /= cdf[-1]
    idx = np.searchsorted(cdf, np.asarray(quantiles, dtype=np.float64), side="left")
    return v[np.minimum(idx, v.size - 1)]


def _summary(L, w, percentiles):
    if L.size == 0 or w.sum() <= 0:
        return {"solid_angle": 0.0, "n_pixels": 0, "mean": None, "min": None, "max": None,
                "percentiles": {f"{p:g}": None for p in percentiles}}
    q = weighted_quantile(L, w, np.asarray(percentiles) / 100.0)
    return {
        "solid_angle": float(w.sum()),
        "n_pixels": int(L.size),
        "mean": float(np.sum(L * w) / w.sum()),
        "min": float(L.min()),
        "max": float(L.max()),
        "percentiles": {f"{p:g}": float(x) for p, x in zip(percentiles, q, strict=True)},
    }


def luminance_statistics(luminance, solid_angle, cos_sigma, *,
                         ring_edges_deg=DEFAULT_RING_EDGES_DEG, percentiles=DEFAULT_PERCENTILES):
    """Solid-angle-weighted luminance statistics [cd·m⁻²] of the field and of σ rings.

    Returns
    -------
    dict
        ``{"field": {...}, "rings": [{"sigma_deg": [lo, hi], ...}, ...]}`` with solid angle
        [sr], pixel count, mean, min, max and percentiles; ``None`` for empty regions.
    """
    field = evaluated_field(luminance, solid_angle, cos_sigma)
    L = np.asarray(luminance, dtype=np.float64)
    w = np.asarray(solid_angle, dtype=np.float64)
    sigma_deg = np.degrees(np.arccos(np.clip(cos_sigma, -1.0, 1.0)))
    out = {"field": _summary(L[field], w[field], percentiles), "rings": []}
    edges = [float(e) for e in ring_edges_deg]
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        ring = field & (sigma_deg >= lo) & ((sigma_deg < hi) | math.isclose(hi, 90.0))
        out["rings"].append({"sigma_deg": [lo, hi], **_summary(L[ring], w[ring], percentiles)})
    return out
