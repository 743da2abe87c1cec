"""Luminance statistics against numpy's weighted inverted-CDF quantiles."""

import math

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


def test_histogram_range_from_the_score_pass_gives_the_same_statistics():
    # score_map finds the smallest and largest positive luminance of the valid pixels in its
    # field-luminance pass; reference: numpy's min and max over those pixels (exact).
    from lsadphoto.metrics.score import _field_luminance_kernel

    rng = np.random.default_rng(5)
    image = (10 ** rng.uniform(-2, 6, 200_003)).astype(np.float32)
    image[::7] = 0.0
    image[::11] = -3.0
    image[::13] = np.nan
    evaluated = rng.random(image.size) < 0.9
    cos_sigma = rng.uniform(-0.2, 1.0, image.size)
    luminance = np.empty(image.size)
    dropped, lo, hi = _field_luminance_kernel(image, evaluated, cos_sigma, luminance)
    ok = evaluated & np.isfinite(image) & (cos_sigma >= 0)
    assert dropped == np.count_nonzero(evaluated & ~ok)
    assert np.array_equal(luminance, np.where(ok, image.astype(np.float64), np.nan), equal_nan=True)
    positive = image[ok & (image > 0)].astype(np.float64)
    assert (lo, hi) == (positive.min(), positive.max())
    w = rng.uniform(1e-6, 3e-6, image.size)
    assert luminance_statistics(luminance, w, cos_sigma, positive_range=(lo, hi)) == \
        luminance_statistics(luminance, w, cos_sigma)
    # No positive value: the empty range (+inf, -inf) of both.
    none = np.full(image.size, np.nan)
    assert _field_luminance_kernel(image, np.zeros(image.size, bool), cos_sigma, none)[1:] == \
        (np.inf, -np.inf)


def test_sums_are_added_in_pixel_order():
    # The kernel keeps the current ring's sums in registers while the pixels stay in it.
    # Reference: a Python loop adding each pixel to its ring's sums in pixel order, per
    # stripe, the stripes then added in order (the kernel's documented order): equal bit
    # for bit. Runs of one ring, single pixels between rings, pixels outside every ring
    # (cos σ < 0 or beyond 90°), skipped pixels (NaN, ω = 0) and L ≤ 0 in between.
    from lsadphoto.metrics.statistics import _STRIPES

    rng = np.random.default_rng(8)
    n = 4000
    L = 10 ** rng.uniform(-1, 5, n)
    L[rng.random(n) < 0.05] = 0.0
    L[rng.random(n) < 0.02] = -1.0
    L[rng.random(n) < 0.02] = np.nan
    w = rng.uniform(1e-6, 3e-6, n)
    w[rng.random(n) < 0.02] = 0.0
    ring_of_run = rng.integers(0, 4, n // 40).repeat(40)  # runs of 40 pixels, one ring each
    centre = np.array([15.0, 45.0, 75.0, 120.0])[ring_of_run]
    sigma = centre + rng.uniform(-14.0, 14.0, n)
    sigma[rng.random(n) < 0.1] = rng.uniform(0.0, 120.0)  # single pixels elsewhere
    c = np.cos(np.radians(sigma))
    stats = luminance_statistics(L, w, c)
    edges = np.cos(np.radians([0.0, 30.0, 60.0, 90.0]))
    step = -(-n // _STRIPES)
    totals = np.zeros((3, 2))  # per ring: Σω, ΣL·ω, summed stripe after stripe
    for k in range(_STRIPES):
        part = np.zeros((3, 2))
        for i in range(k * step, min(n, (k + 1) * step)):
            if not (np.isfinite(L[i]) and w[i] > 0 and c[i] >= 0):
                continue
            ring = 0 if c[i] > edges[1] else 1 if c[i] > edges[2] else 2 if c[i] >= edges[3] \
                else None
            if ring is None:
                continue
            part[ring, 0] += w[i]
            part[ring, 1] += L[i] * w[i]
        totals += part
    for ring in range(3):
        assert stats["rings"][ring]["solid_angle"] == totals[ring, 0]
        assert stats["rings"][ring]["mean"] == totals[ring, 1] / totals[ring, 0]


def test_histogram_cells_are_added_in_pixel_order():
    # Reference: a Python loop adding each pixel's ω to its histogram cell (ring, bin) in
    # pixel order; equal bit for bit (a kernel that kept cells in registers must keep it).
    # Runs of equal luminance (one cell), runs crossing ring borders, alternating cells,
    # skipped pixels and L ≤ 0 in between; float32 and float64 maps.
    from lsadphoto.metrics.statistics import _accumulate

    rng = np.random.default_rng(9)
    n = 5000
    L = np.repeat(10 ** rng.uniform(-1, 4, n // 25), 25)  # runs of 25 equal values
    L[rng.random(n) < 0.1] = rng.choice([3.0, 3000.0])  # alternating cells
    L[rng.random(n) < 0.03] = 0.0
    L[rng.random(n) < 0.02] = np.nan
    w = rng.uniform(1e-6, 3e-6, n)
    w[rng.random(n) < 0.02] = 0.0
    sigma = np.repeat(rng.uniform(0.0, 100.0, n // 60 + 1), 60)[:n]
    for dtype in (np.float64, np.float32):
        c = np.cos(np.radians(sigma)).astype(dtype)
        edges = np.cos(np.radians([0.0, 30.0, 60.0, 90.0]))
        origin, per_decade = -2.0, 200.0
        n_bins = int(7 * per_decade)
        outputs = (np.empty((1, 4), np.int64), np.empty((1, 3, 4)), np.empty((1, 4)),
                   np.empty((1, 4)), np.zeros((1, 4, n_bins)))
        _accumulate(L, w, c, edges, 1, origin, n_bins, per_decade, *outputs)
        expected = np.zeros((4, n_bins))
        for i in range(n):
            ci = float(c[i])
            if not (np.isfinite(L[i]) and w[i] > 0 and ci >= 0) or not L[i] > 0:
                continue
            ring = 0 if ci > edges[1] else 1 if ci > edges[2] else 2 if ci >= edges[3] else 3
            cell = min(int((math.log10(L[i]) - origin) * per_decade), n_bins - 1)
            expected[ring, cell] += w[i]
        assert np.array_equal(outputs[4][0].view(np.uint64), expected.view(np.uint64))
        assert np.count_nonzero(expected) > 50


def test_pixels_on_ring_edges_go_to_the_ring_they_open():
    # Rings are σ ∈ [edge_k, edge_k+1), the last one closed (σ = 90° in the 60–90° ring):
    # pixels exactly on an edge's cos σ, after runs of pixels of the rings on either side
    # (the kernel keeps the last ring's interval of cos σ), against the rule applied with
    # np.searchsorted on σ's cosines; pixel counts and Σω equal.
    edges_deg = (0.0, 30.0, 60.0, 90.0)
    cos_edges = np.cos(np.radians(edges_deg))
    inner = np.cos(np.radians([15.0, 45.0, 75.0]))
    c = []
    for k, value in enumerate(cos_edges):
        for run in (inner[max(k - 1, 0)], inner[min(k, 2)]):
            c += [run] * 20 + [value]
    # Four times over: the kernel's 16 stripes each hold runs and edges.
    c = np.array(4 * (c + [np.cos(np.radians(100.0)), cos_edges[3], cos_edges[3]]))
    w = np.arange(1, c.size + 1) * 1e-6
    stats = luminance_statistics(np.full(c.size, 100.0), w, c, ring_edges_deg=edges_deg)
    # Ring of each pixel: cos_edges[k+1] < c ≤ cos_edges[k]; the last ring also at c = cos_edges[3].
    ring = 2 - np.searchsorted(cos_edges[::-1], c, side="left") + 1
    ring = np.where(c == cos_edges[3], 2, ring)
    ring = np.where((c > cos_edges[0]) | (c < cos_edges[3]), -1, ring)
    for k in range(3):
        assert stats["rings"][k]["n_pixels"] == np.count_nonzero(ring == k)
        # Σω added in another order (the kernel's stripes, numpy's pairwise sum): within
        # the bound n·2⁻⁵² of two float64 sums of n positive terms.
        assert stats["rings"][k]["solid_angle"] == pytest.approx(float(w[ring == k].sum()),
                                                                 rel=c.size * 2.0 ** -52)
