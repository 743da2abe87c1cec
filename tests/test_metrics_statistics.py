"""Luminance statistics against numpy's weighted inverted-CDF quantiles."""

import numpy as np
import pytest

from lsadphoto.metrics.statistics import QUANTILE_BINS_PER_DECADE, luminance_statistics


def test_weighted_percentiles_match_numpy_within_the_bin_resolution():
    rng = np.random.default_rng(11)
    L = 10 ** rng.uniform(-3, 9, 50000)  # the package's whole range, 1e-3 … 1e9 cd/m²
    L[:500] = 0.0
    w = rng.uniform(1e-6, 3e-6, L.size)
    c = rng.uniform(0.0, 1.0, L.size)
    stats = luminance_statistics(L, w, c, percentiles=(0.5, 5, 50, 95, 99.9))
    # Half a bin: the documented worst-case relative error of a histogram quantile.
    tol = 10 ** (0.5 / QUANTILE_BINS_PER_DECADE) - 1
    for key, value in stats["field"]["percentiles"].items():
        exact = np.quantile(L, float(key) / 100, weights=w, method="inverted_cdf")
        assert value == pytest.approx(exact, rel=tol, abs=1e-12), key
    assert stats["field"]["mean"] == pytest.approx(np.sum(L * w) / w.sum(), rel=1e-12)
    assert stats["field"]["max"] == L.max() and stats["field"]["min"] == 0.0
    # Rings partition the field: their solid angles add up.
    assert sum(r["solid_angle"] for r in stats["rings"]) == pytest.approx(w.sum(), rel=1e-12)
    ring = stats["rings"][1]
    sigma = np.degrees(np.arccos(c))
    sel = (sigma >= 30) & (sigma < 60)
    assert ring["n_pixels"] == sel.sum()
    assert ring["percentiles"]["50"] == pytest.approx(
        np.quantile(L[sel], 0.5, weights=w[sel], method="inverted_cdf"), rel=tol)


def test_empty_region_is_none():
    stats = luminance_statistics(np.array([5.0]), np.array([1.0]), np.array([1.0]))
    assert stats["rings"][2]["mean"] is None and stats["rings"][2]["n_pixels"] == 0
