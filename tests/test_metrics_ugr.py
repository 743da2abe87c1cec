"""UGR (pixel-wise and grouped), glare-source rules and evalglare-style grouping.

References: closed forms for a uniform disk source on a uniform background (CIE 117 eq. 1
with the spherical-cap integrals ω = 2π(1 − cos ρ) and ∫cap cos σ dω = π sin²ρ cos σ₀), the
identity pixel-UGR − UGR = 8·log10(1 + CV²) (FORMULAS.md §3.1), and scaling laws. Every
closed form is checked on what :func:`~lsadphoto.metrics.score.score_map` — the production
path of the CLI, the survey and the reports — reports; the identity that needs a common
position index, which no real view has, is checked on the public functions it composes.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lsadphoto.datasets import disk_sources_scene
from lsadphoto.errors import BadInputError
from lsadphoto.geometry import IdealFisheyeProjection, ObserverFrame, position_index, visual_field
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.metrics.field import background_luminance
from lsadphoto.metrics.grouping import group_sources_evalglare
from lsadphoto.metrics.score import score_map
from lsadphoto.metrics.sources import select_source_pixels, task_luminance
from lsadphoto.metrics.ugr import ugr_CIE117, ugr_pixel


def _fisheye(size=1000):
    cam = IdealFisheyeProjection("equidistant", (size - 1) / 2, (size - 1) / 2, size / 2, 180.0,
                                 size, size)
    r, c = cam.pixel_grid()
    d = cam.directions(r, c)
    w = cam.solid_angles(r, c)
    return cam, d, w


@pytest.fixture(scope="module")
def fisheye():
    return _fisheye()


def _up_direction(sigma):
    """Direction σ above the optical axis (camera frame: y down)."""
    return np.array([0.0, -math.sin(sigma), math.cos(sigma)])


def _cap_integral_of_inverse_p2(centre, rho, order=64):
    """∫cap dω/P² by Gauss–Legendre quadrature in polar coordinates about the cap centre."""
    c = centre / np.linalg.norm(centre)
    e1 = np.cross(c, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(c, e1)
    x, wx = np.polynomial.legendre.leggauss(order)
    r = (x + 1) * rho / 2
    wr = wx * rho / 2
    phi = np.linspace(0, 2 * np.pi, 4 * order, endpoint=False)
    R, PHI = np.meshgrid(r, phi, indexing="ij")
    d = (np.cos(R)[..., None] * c + np.sin(R)[..., None]
         * (np.cos(PHI)[..., None] * e1 + np.sin(PHI)[..., None] * e2))
    P = position_index(*ObserverFrame().angles(d))
    weights = (wr * np.sin(r))[:, None] * (2 * np.pi / phi.size)
    return float(np.sum(weights / P**2))


def _maps(d, w):
    frame = ObserverFrame()
    sigma, tau = frame.angles(d)
    cos_sigma = np.where(np.isfinite(sigma), np.cos(sigma), 0.0)
    P = position_index(sigma, tau)
    return cos_sigma, P


def _score(cam, L, **options):
    """score_map of a synthetic map (noise propagation has nothing to do: no uncertainty)."""
    return score_map(LuminanceMap(L, projection=cam, calibrated=True), **options)


@pytest.mark.parametrize("sigma_deg", [20.0, 40.0])
def test_uniform_disk_source_matches_closed_form(fisheye, sigma_deg):
    cam, d, w = fisheye
    L_bg, L_s, rho = 100.0, 20000.0, math.radians(3.0)
    s0 = math.radians(sigma_deg)
    L = disk_sources_scene(d, background=L_bg, sources=[(_up_direction(s0), rho, L_s)])
    score = _score(cam, L)
    v = score.values
    assert v["n_sources"] == 1
    # Closed forms: the cap's solid angle and cosine integral, Guth's P at the cap centre.
    omega = 2 * math.pi * (1 - math.cos(rho))
    l_b_exact = L_bg * (1 - math.sin(rho) ** 2 * math.cos(s0))
    p_exact = float(position_index(s0, 0.0))
    ugr_exact = 8 * math.log10(0.25 / l_b_exact * L_s**2 * omega / p_exact**2)
    e_v_exact = math.pi * L_bg + (L_s - L_bg) * math.pi * math.sin(rho) ** 2 * math.cos(s0)
    # Pixelising a 3° disk (≈17 px radius) misplaces its rim by up to half a pixel: the
    # measured solid angle is within 1 % (8·log10(1.01) = 0.035 UGR); P varies over the
    # disk by ±4 % at σ = 40°, which the pixel sum averages to second order. evalglare's
    # source position (the pixel of the mean pixel position) lies within a pixel (0.18°)
    # of the cap centre: P within 0.3 %, 0.01 UGR.
    assert v["source_solid_angle"] == pytest.approx(omega, rel=0.01)
    assert v["vertical_illuminance"] == pytest.approx(e_v_exact, rel=2e-3)
    assert v["background_luminance"] == pytest.approx(l_b_exact, rel=1e-3)
    for position in ("evalglare", "direction"):
        grouped = score.values["ugr_grouped"] if position == "evalglare" else \
            _score(cam, L, source_position=position).values["ugr_grouped"]
        assert grouped == pytest.approx(ugr_exact, abs=0.05), position
    # Pixel-UGR integrates 1/P² over the disk instead of taking P at its centre: the
    # reference is the same closed form with ω/P₀² replaced by ∫cap dω/P² (quadrature).
    pixel_exact = 8 * math.log10(0.25 / l_b_exact * L_s**2
                                 * _cap_integral_of_inverse_p2(_up_direction(s0), rho))
    assert v["ugr_pixel"] == pytest.approx(pixel_exact, abs=0.05)
    # The production value is the public ugr_pixel of the same pixels (one path), with the
    # visual field's P map (float32, each value rounded once from float64: VisualField).
    P = visual_field(cam, ObserverFrame()).position_index
    assert v["ugr_pixel"] == pytest.approx(ugr_pixel(L, w, P, score.source_mask,
                                                     v["background_luminance"]), abs=1e-9)
    # DGP (Wienold & Christoffersen 2006, evalglare's coefficients) from the same closed forms.
    dgp_exact = (5.87e-5 * e_v_exact + 0.092 * math.log10(
        1 + L_s**2 * omega / (e_v_exact**1.87 * p_exact**2)) + 0.159)
    assert v["dgp"] == pytest.approx(dgp_exact, abs=2e-3)  # what the 1 % solid angle allows


def test_pixel_minus_grouped_ugr_is_8_log_one_plus_cv2(fisheye):
    cam, d, w = fisheye
    rng = np.random.default_rng(3)
    L = disk_sources_scene(d, background=50.0, sources=[(_up_direction(0.4), 0.08, 1.0)])
    inside = L == 1.0
    L[inside] = rng.uniform(3000.0, 40000.0, inside.sum())
    P = np.full(L.shape, 2.5)  # a common position index, as the identity requires
    cos_sigma, _ = _maps(d, w)
    sel = select_source_pixels(L, w, cos_sigma)
    assert np.array_equal(sel.mask, inside)
    # The evaluated field handed over (as score_map does) selects the same pixels; a field
    # of another shape is refused.
    field = np.isfinite(L) & (w > 0) & (cos_sigma >= 0)
    assert np.array_equal(select_source_pixels(L, w, cos_sigma, field_mask=field).mask, inside)
    with pytest.raises(BadInputError, match="field_mask"):
        select_source_pixels(L, w, cos_sigma, field_mask=field[1:])
    groups, _ = group_sources_evalglare(L, d, w, sel.mask)
    assert len(groups) == 1
    l_b = background_luminance(L, w, cos_sigma, sel.mask)
    lj, wj = L[inside], w[inside]
    mean = np.sum(lj * wj) / wj.sum()
    cv2 = np.sum(wj * (lj - mean) ** 2) / wj.sum() / mean**2
    grouped = ugr_CIE117([groups[0].luminance], [groups[0].solid_angle], [2.5], l_b)
    # The identity is exact algebra; 1e-6 leaves room for float64 summation only.
    assert ugr_pixel(L, w, P, sel.mask, l_b) - grouped == pytest.approx(
        8 * math.log10(1 + cv2), abs=1e-6)


@settings(max_examples=15, deadline=None)
@given(k=st.floats(1e-3, 1e6))
def test_ugr_scales_as_8_log_k(k):
    cam, d, w = _fisheye(96)
    L = disk_sources_scene(d, background=80.0, sources=[(_up_direction(0.3), 0.15, 9000.0),
                                                        ((0.5, 0.2, 1.0), 0.1, 30000.0)])

    def ugr(scale):
        # A scale-free rule (factor × field mean) selects the same pixels at every scale.
        v = _score(cam, L * scale, source_method="mean", source_threshold=5.0).values
        return np.array([v["ugr_pixel"], v["ugr_grouped"]])

    # Exact in real arithmetic (L_b and every L_s scale with k, P does not). The map stores
    # k·L as float32 (relative rounding ≤ 2⁻²⁴ per pixel): ΣL² and L_b move by at most
    # 2·2⁻²⁴ and 2⁻²⁴, i.e. UGR by (8/ln 10)·3·2⁻²⁴ = 6.2e-7; 1e-6 covers that.
    assert ugr(k) - ugr(1.0) == pytest.approx(np.full(2, 8 * math.log10(k)), abs=1e-6)


def test_no_source_gives_nan_not_a_crash(fisheye):
    cam, d, w = fisheye
    L = np.where(np.isfinite(d[..., 0]), 100.0, np.nan)
    score = _score(cam, L)
    assert score.sources == [] and not score.source_labels.any()
    for key in ("ugr_pixel", "ugr_grouped", "dgi", "cgi", "ugp", "dgr", "vcp"):
        assert math.isnan(score.values[key]), key
    assert math.isnan(ugr_CIE117([], [], [], score.values["background_luminance"]))


def test_zero_background_gives_nan(fisheye):
    cam, d, w = fisheye
    L = disk_sources_scene(d, background=0.0, sources=[(_up_direction(0.3), 0.05, 5000.0)])
    v = _score(cam, L).values
    assert v["background_luminance"] == 0.0
    assert math.isnan(v["ugr_pixel"]) and math.isnan(v["ugr_grouped"])


def test_grouping_links_within_half_the_search_angle(fisheye):
    cam, d, w = fisheye
    r = math.radians(1.0)
    # Gap between the caps' rims: 0.06 rad (linked, ≤ 0.1) and 0.2 rad (separate).
    a = _up_direction(0.3)
    near = _up_direction(0.3 + 2 * r + 0.06)
    L = disk_sources_scene(d, background=10.0, sources=[(a, r, 8000.0), (near, r, 8000.0)])
    assert _score(cam, L).values["n_sources"] == 1
    # Move the second cap 0.2 rad beyond the rim of the first: two sources.
    second = _up_direction(0.3 + 2 * r + 0.2)
    L2 = disk_sources_scene(d, background=10.0, sources=[(a, r, 8000.0), (second, r, 8000.0)])
    score = _score(cam, L2)
    assert score.values["n_sources"] == 2
    assert set(np.unique(score.source_labels)) == {0, 1, 2}


@pytest.mark.parametrize(("shape", "fraction"), [((1, 1), 0.5), ((7, 1), 0.5), ((1, 9), 0.5),
                                               ((37, 53), 0.3), ((200, 150), 0.7),
                                               ((64, 64), 0.0), ((30, 40), 1.0)])
def test_grouping_nodes_are_numbered_in_row_major_order(shape, fraction):
    # The grouping's nodes: the mask pixels in np.nonzero's (row-major) order, and whether
    # each lies on its patch's boundary. Reference: np.nonzero and the 3×3 neighbourhood of
    # each pixel in the mask padded with False (the box's edge counts as outside); equal
    # exactly.
    from lsadphoto.metrics.grouping import _nodes

    rows, cols = shape
    mask = np.random.default_rng(3).random(shape) < fraction
    node_rows, node_cols = np.nonzero(mask)
    node = np.full(shape, -1, np.int32)
    node[node_rows, node_cols] = np.arange(node_rows.size)
    padded = np.pad(mask, 1)
    inside = np.ones(shape, dtype=bool)
    for dr in (0, 1, 2):
        for dc in (0, 1, 2):
            inside &= padded[dr:dr + rows, dc:dc + cols]
    got = _nodes(mask)
    # Runs along rows start where the pixel to the left is outside the mask (or the box).
    left = np.pad(mask, ((0, 0), (1, 0)))[:, :-1]
    starts = np.flatnonzero(~left[node_rows, node_cols])
    for value, expected in zip(got, (node, ~inside[node_rows, node_cols], node_rows, node_cols,
                                     starts), strict=True):
        np.testing.assert_array_equal(value, expected)


@pytest.mark.parametrize(("shape", "fraction", "seed"), [((1, 1), 1.0, 0), ((9, 1), 0.5, 1),
                                                         ((1, 9), 0.5, 2), ((37, 53), 0.3, 3),
                                                         ((200, 150), 0.45, 4), ((64, 64), 0.0, 5)])
def test_grouping_components_are_numbered_in_column_major_order(shape, fraction, seed):
    # Where every neighbour is within reach (directions all equal) and no boundary pair is
    # given, the components are the 8-connected patches of the mask, numbered in the order
    # of their first pixel in a column-major scan (evalglare's). Reference: scipy's label
    # of the transposed mask with the 3×3 structure (it numbers patches by their first pixel
    # in row-major order, which of the transpose is the column-major order); equal exactly.
    from scipy import ndimage

    from lsadphoto.metrics.grouping import _components, _nodes

    mask = np.random.default_rng(seed).random(shape) < fraction
    node, _, node_rows, node_cols, _ = _nodes(mask)
    directions = np.tile([0.0, 0.0, 1.0], (node_rows.size, 1))
    label = np.empty(node_rows.size, dtype=np.int64)
    empty = np.zeros(0, dtype=np.int64)
    n = _components(node, node_rows, node_cols, directions, 0.1, empty, empty, label)
    expected, n_expected = ndimage.label(mask.T, structure=np.ones((3, 3)))
    assert n == n_expected
    np.testing.assert_array_equal(label, expected.T[node_rows, node_cols])


@pytest.mark.parametrize(("m", "spread", "chord", "seed"), [(0, 0.1, 0.05, 0), (1, 0.1, 0.05, 1),
                                                             (400, 0.05, 0.02, 2),
                                                             (1500, 0.3, 0.04, 3),
                                                             (300, 0.001, 0.01, 4)])
def test_close_pairs_are_every_close_pair_in_search_order(m, spread, chord, seed):
    # Reference: every pair a < b of the directions within the chord, by brute force, in
    # the order of one search of the sorted cube keys per neighbouring cube (dx, dy, dz
    # nested), the order in which the pairs reach the union-find. The last case puts many
    # directions in one cube (hundreds of pairs per node).
    from lsadphoto.metrics.grouping import _close, _close_pairs

    rng = np.random.default_rng(seed)
    d = np.array([0.2, -0.3, 0.93]) + spread * rng.standard_normal((m, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = np.ascontiguousarray(d)
    got = _close_pairs(d, chord)
    close = _close.py_func if hasattr(_close, "py_func") else _close
    cell = np.floor((d + 1.0) / chord).astype(np.int64)
    span = int(math.floor(2.0 / chord)) + 3
    key = ((cell[:, 0] + 1) * span + cell[:, 1] + 1) * span + cell[:, 2] + 1
    order = np.argsort(key)  # the kernel's sort (numba's quicksort: ties may order otherwise)
    expected = [(a, b) for a in range(m) for dx in (-1, 0, 1) for dy in (-1, 0, 1)
                for dz in (-1, 0, 1)
                for b in sorted(order[key[order] == ((cell[a, 0] + dx + 1) * span + cell[a, 1]
                                                      + dy + 1) * span + cell[a, 2] + dz + 1])
                if b > a and close(d, a, b, chord)]
    within = np.sqrt(np.sum((d[:, None, :] - d[None, :, :]) ** 2, axis=-1)) <= chord
    brute = {(a, b) for a, b in zip(*np.nonzero(np.triu(within, 1)), strict=True)}
    brute = {(int(a), int(b)) for a, b in brute}
    assert set(zip(got[0].tolist(), got[1].tolist(), strict=True)) == set(expected) == brute
    # The order, up to the order within one cube (ties of the sort).
    assert sorted(zip(got[0].tolist(), got[1].tolist(), strict=True)) == sorted(expected)
    assert got[0].tolist() == [a for a, _ in expected]


def test_peak_extraction_splits_the_bright_core(fisheye):
    cam, d, w = fisheye
    centre = _up_direction(0.5)
    L = disk_sources_scene(d, background=30.0, sources=[(centre, 0.1, 5000.0),
                                                        (centre, 0.02, 1.6e9)])
    score = _score(cam, L)
    assert sorted(s.peak for s in score.sources) == [False, True]
    peak = next(s for s in score.sources if s.peak)
    assert peak.luminance == pytest.approx(1.6e9)
    # The core's solid angle is the cap's to its pixelisation error (≈3.6 px radius: 10 %).
    assert peak.solid_angle == pytest.approx(2 * math.pi * (1 - math.cos(0.02)), rel=0.1)
    assert _score(cam, L, peak_luminance=None).values["n_sources"] == 1


def test_task_rule_uses_the_cone_mean(fisheye):
    cam, d, w = fisheye
    L = disk_sources_scene(d, background=200.0, sources=[(_up_direction(0.6), 0.05, 1500.0)])
    # The task cone around the axis sees only background: L_task = 200, threshold 1000.
    assert task_luminance(L, d, w, (0, 0, 1), math.radians(20)) == pytest.approx(200.0)
    score = _score(cam, L, source_method="task", source_threshold=5.0,
                   task_direction=(0, 0, 1), task_opening_deg=20.0)
    assert score.settings["source_selection"]["task_luminance"] == pytest.approx(200.0)
    assert np.array_equal(score.source_mask, L == 1500.0)


def test_mean_luminance_of_hemisphere(fisheye):
    cam, d, w = fisheye
    v = _score(cam, np.where(np.isfinite(d[..., 0]), 42.0, np.nan)).values
    assert v["mean_luminance"] == pytest.approx(42.0, rel=1e-12)
    # E_v of a uniform hemisphere is π·L; the centre-rule rim pixels add ≈6e-5 (fisheye.py).
    assert v["vertical_illuminance"] == pytest.approx(math.pi * 42.0, rel=2e-4)
    # L_b (CIE) of a source-free field is E_v/π.
    assert v["background_luminance"] == pytest.approx(v["vertical_illuminance"] / math.pi,
                                                      rel=1e-12)


@pytest.mark.parametrize("shape", [(1, 1), (2, 2)])
def test_tiny_maps(shape):
    """One or four pixels of 5000 cd/m²: every pixel is a source (above the fixed 2000 cd/m²),
    each its own group (the four pixel directions lie ≈ 79° apart, far beyond the 0.2 rad
    search angle); with no background L_b = (E_v − E_dir)/π = 0 and UGR, ∝ log(1/L_b), is
    undefined (NaN); with a given L_b it is CIE 117's 8·log10(0.25/L_b · Σ L²ω/P²)."""
    cam = IdealFisheyeProjection("equidistant", (shape[1] - 1) / 2, (shape[0] - 1) / 2,
                                 shape[0] / 2, 180.0, shape[1], shape[0])
    r, c = cam.pixel_grid()
    d = cam.directions(r, c)
    w = cam.solid_angles(r, c)
    L = np.full(shape, 5000.0)
    cos_sigma, P = _maps(d, w)
    score = _score(cam, L)
    assert score.source_mask.all()
    assert len(score.sources) == L.size and all(s.n_pixels == 1 for s in score.sources)
    assert score.values["background_luminance"] == 0.0
    assert math.isnan(score.values["ugr_pixel"]) and math.isnan(score.values["ugr_grouped"])
    expected = 8.0 * math.log10(0.25 / 20.0 * float(np.sum(L**2 * w / P**2)))
    assert ugr_pixel(L, w, P, score.source_mask, 20.0) == pytest.approx(expected, rel=1e-12)
