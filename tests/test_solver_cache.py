"""Direct light per point and the surface cache of indirect illuminance.

References
----------
Projected solid angle of a rectangle seen from a point on its normal through a corner
(the corner-rectangle form factor, e.g. Howell, *A Catalog of Radiation Heat Transfer
Configuration Factors*, B-3; Walsh 1958, *Photometry*, §3): F = (1/2π)·[X/√(1+X²)·
atan(Y/√(1+X²)) + Y/√(1+Y²)·atan(X/√(1+Y²))], X = a/c, Y = b/c. Integrating sphere: every
non-emitting point receives E_dir = Φ/A and E = Φ/(A(1 − ρ)) in all (see
tests/test_solver_accuracy.py). Point source: E = I·cos θ/d².
"""

import dataclasses
import json
import math

import numpy as np
import pytest

from lsadphoto.cli import main
from lsadphoto.errors import BadInputError
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.io import read_exr
from lsadphoto.solver import (
    camera_to_world,
    load_store,
    read_scene,
    render,
    scene_from_dict,
    simulate,
)
from lsadphoto.solver.direct import direct_illuminance, projected_solid_angle
from lsadphoto.solver.examples import canonical_room, canonical_room_toml
from lsadphoto.solver.cache_grid import SurfaceCache
from lsadphoto.solver.engine import RayEngine, engine_for
from lsadphoto.solver.integrators.eye import primary_rays
from lsadphoto.solver.integrators.surface_cache import (
    build_surface_cache,
    indirect_illuminance,
    render_cached,
)

from .test_solver_accuracy import DOWN, FISHEYE, K_SIGMA, REL_TOL, sphere_scene


def corner_factor(a, b, c):
    x, y = a / c, b / c
    return (x / math.hypot(1, x) * math.atan(y / math.hypot(1, x))
            + y / math.hypot(1, y) * math.atan(x / math.hypot(1, y))) / (2 * math.pi)


def quad(p0, p1, p2, p3):
    """Two triangles of a planar quad (front side by the order)."""
    return np.array([[p0, p1, p2], [p0, p2, p3]], dtype=float)


# --- projected solid angle and direct light -------------------------------------------------

def test_projected_solid_angle_of_rectangles_equals_the_corner_form_factor():
    # A 3 × 2 m rectangle 1.5 m above a point, offset so that the point's normal passes
    # through a corner, facing down: Π = π·F exactly (rounding only).
    rect = quad([0, 0, 1.5], [0, 2, 1.5], [3, 2, 1.5], [3, 0, 1.5])
    pi_ = projected_solid_angle([[0, 0, 0]], [[0, 0, 1]], rect).sum()
    assert pi_ == pytest.approx(math.pi * corner_factor(3, 2, 1.5), rel=1e-12)
    # Seen from behind (the point above it), a one-sided emitter contributes nothing.
    assert projected_solid_angle([[0, 0, 3]], [[0, 0, -1]], rect).sum() == 0


def test_projected_solid_angle_clips_at_the_horizon():
    # A vertical 2 × 2 m square 1 m away whose lower half lies below the point's horizon:
    # only the upper half may count. Checked against midpoint quadrature of
    # cos⁺θ_x·cos θ_y/r² over the upper half (independent of Lambert's formula; 400² cells,
    # relative error O(h²) < 1e-4).
    wall = quad([-1, 1, -1], [1, 1, -1], [1, 1, 1], [-1, 1, 1])  # front normal −y, towards the point
    pi_ = projected_solid_angle([[0, 0, 0]], [[0, 0, 1]], wall).sum()
    n = 400
    u = (np.arange(n) + 0.5) / n
    xs, zs = np.meshgrid(-1 + 2 * u, u)  # the upper half z ∈ (0, 1)
    r2 = xs ** 2 + 1 + zs ** 2
    integrand = zs * 1.0 / r2 ** 2  # cos θ_x = z/r, cos θ_y = 1/r
    assert pi_ == pytest.approx(integrand.mean() * 2.0, rel=1e-4)


def test_projected_solid_angle_of_a_triangle_that_starts_below_the_horizon():
    # Lambert's formula streams the clipped polygon's vertices; here the first vertex lies
    # below the point's horizon, so the polygon starts at a crossing. The vertical triangle
    # (0, 1, −1), (2, 1, 1), (0, 1, 1) (front normal −y, towards the point at the origin):
    # above the horizon it covers 0 < z < 1, 0 < x < z + 1 on the plane y = 1. Checked against
    # midpoint quadrature of cos⁺θ_x·cos θ_y/r² over that region (400² cells, O(h²) < 1e-4).
    tri = np.array([[[0, 1, -1], [2, 1, 1], [0, 1, 1]]], dtype=float)
    pi_ = projected_solid_angle([[0, 0, 0]], [[0, 0, 1]], tri).sum()
    n = 400
    u = (np.arange(n) + 0.5) / n
    xs, zs = np.meshgrid(2 * u, u)  # cells over the box 0 < x < 2, 0 < z < 1
    inside = xs < zs + 1  # the triangle: x < z + 1 (its hypotenuse from (0, −1) to (2, 1))
    r2 = xs ** 2 + 1 + zs ** 2
    integrand = np.where(inside, zs / r2 ** 2, 0.0)
    assert pi_ == pytest.approx(integrand.mean() * 2.0, rel=1e-4)


def test_visibility_of_segments():
    # RayEngine.visible: a segment through a wall is blocked, one beside it is not, one that
    # ends on the wall is shortened by ε and visible, a zero-length one counts as visible.
    engine = RayEngine(quad([1, -1, -1], [1, 1, -1], [1, 1, 1], [1, -1, 1]), epsilon=1e-5)
    origins = np.array([[0, 0, 0], [0, 0, 0], [0, 0, 0], [0.5, 0.5, 0.5]], dtype=float)
    targets = np.array([[2, 0, 0], [2, 3, 0], [1, 0.2, 0.1], [0.5, 0.5, 0.5]], dtype=float)
    assert engine.visible(origins, targets).tolist() == [False, True, True, True]
    # many segments at once, alternately through the wall and beside it
    k = 1001
    ends = np.where((np.arange(k) % 2 == 0)[:, None], [[2.0, 0.0, 0.0]], [[0.5, 0.0, 0.0]])
    assert engine.visible(np.zeros((k, 3)), ends).tolist() == [i % 2 == 1 for i in range(k)]


def test_direct_light_of_a_half_occluded_luminaire():
    # A 1 × 1 m Lambertian panel 2 m above a point; an opaque black sheet 2 cm below the
    # panel covers its half x < 0. The point lies under the sheet's edge (x = 0), so from it
    # the sheet hides exactly that half: E = L·Π(half x > 0) (Lambert, exact). 4000
    # independent estimates of 8 samples: their mean within 3 standard errors (the ratio
    # form's O(1/s) bias is below that resolution, 0.4 %); the reported variance is
    # conservative (it ignores the stratification) but not by more than 4×.
    flux = 1000.0
    scene = scene_from_dict({
        "materials": {"grey": {"reflectance": 0.5}, "black": {"reflectance": 0.0}},
        "surfaces": [
            {"type": "polygon", "material": "grey",
             "vertices": [[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]]},
            {"type": "polygon", "material": "black",
             "vertices": [[-0.6, -0.6, 1.98], [0, -0.6, 1.98], [0, 0.6, 1.98], [-0.6, 0.6, 1.98]]},
        ],
        "luminaires": [{"type": "area", "flux": flux, "material": "black", "shape": {
            "type": "polygon", "vertices": [[-0.5, -0.5, 2], [-0.5, 0.5, 2], [0.5, 0.5, 2], [0.5, -0.5, 2]]}}],
    })
    engine = engine_for(scene)
    luminance = flux / math.pi  # 1 m²
    half = quad([0, -0.5, 2], [0, 0.5, 2], [0.5, 0.5, 2], [0.5, -0.5, 2])
    point = np.array([[0.0, 0.05, 0.0]])
    expected = luminance * projected_solid_angle(point, [[0, 0, 1]], half).sum()
    n = 4000
    e, var = direct_illuminance(scene, engine, np.repeat(point, n, axis=0),
                                np.tile([0, 0, 1.0], (n, 1)), samples=8, seed=3,
                                block_ids=np.arange(n))
    assert np.any(var > 0) and np.all(e >= 0)  # partial shadow: sampled; never negative
    assert abs(e.mean() - expected) <= K_SIGMA * e.std(ddof=1) / math.sqrt(n)
    assert 1.0 <= var.mean() / e.var(ddof=1) < 4.0


def test_direct_light_is_exact_where_luminaires_are_fully_visible():
    # Inside the convex canonical room nothing occludes the panels: the estimate is Lambert's
    # closed form itself, with zero variance (rounding only).
    room = canonical_room(size=8)
    pts = np.array([[3.0, 2.0, 0.0], [0.0, 1.0, 1.5], [5.0, 3.5, 2.5]])
    nrm = np.array([[0, 0, 1.0], [1, 0, 0], [0, -1, 0]])
    e, var = direct_illuminance(room, engine_for(room), pts, nrm, samples=4)
    expected = sum(lum.luminance(room) * projected_solid_angle(pts, nrm, room.triangles[lum.triangles]).sum(axis=1)
                   for lum in room.area_luminaires)
    assert np.allclose(e, expected, rtol=1e-12)
    assert np.all(var == 0)


def test_direct_light_of_a_point_luminaire():
    # 100 cd isotropic (Φ = 400π lm) 2 m above the floor: E = I·cos θ/d².
    scene = scene_from_dict({
        "materials": {"grey": {"reflectance": 0.5}},
        "surfaces": [{"type": "disc", "centre": [0, 0, 0], "normal": [0, 0, 1], "radius": 5,
                      "material": "grey"}],
        "luminaires": [{"type": "point", "position": [0, 0, 2], "flux": 400 * math.pi}],
    })
    pts = np.array([[0.0, 0, 0], [1.5, 0, 0], [0, -3, 0]])
    e, var = direct_illuminance(scene, engine_for(scene), pts, np.tile([0, 0, 1.0], (3, 1)))
    d2 = (pts ** 2).sum(axis=1) + 4
    assert np.allclose(e, 100 * 2 / np.sqrt(d2) / d2, rtol=1e-4)  # 1° intensity table: 1e-4
    assert np.all(var == 0)


# --- indirect illuminance and the cache --------------------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize("rho", [0.5, 0.95])
def test_integrating_sphere_from_the_cache(rho):
    # Every wall point: E_ind = Φ/A·ρ/(1 − ρ). ε = 0.3 R makes the near-field paths carry a
    # large share (see test_solver_accuracy), so the unbiasedness of the near-field split is
    # tested too. Facets (edge 0.063 R) are smaller than the default spacing: one cache point
    # per facet side, the interpolation is exact for this constant field. Polyhedron
    # geometry: O(δ²) ≈ 2e-3 point-wise (test_solver_accuracy), inside the 1 % tolerance.
    scene = sphere_scene(rho)
    store = simulate(scene, samples=8192, seed=3)
    cache = build_surface_cache(store, nodes=256, near_distance=0.3, seed=4, workers=2)
    lmap = render_cached(store, FISHEYE, position=[0, 0, 0], rotation=DOWN, cache=cache)
    p = lmap.provenance
    expected = rho * 1000.0 / (math.pi * scene.areas.sum() * (1 - rho))
    assert abs(p["field_mean_luminance"] - expected) <= K_SIGMA * p["field_mean_standard_error"]
    assert abs(p["field_mean_luminance"] / expected - 1) <= REL_TOL


def _refined_small_room_cache():
    """A 2 × 1.5 × 1 m grey room under a point light and its cache with refined cells (low
    contrast threshold)."""
    scene = scene_from_dict({
        "materials": {"grey": {"reflectance": 0.5}},
        "surfaces": [{"type": "box", "min": [0, 0, 0], "max": [2, 1.5, 1], "facing": "inward",
                      "material": "grey"}],
        "luminaires": [{"type": "point", "position": [0.5, 0.5, 0.9], "flux": 1000}],
    })
    store = simulate(scene, samples=2048, seed=1)
    cache = build_surface_cache(store, spacing=0.4, nodes=32, contrast=0.05, seed=2)
    assert cache.refined_key.size > 0
    return scene, cache


def _random_surface_points(scene, triangles, n, seed):
    """``n`` uniform points on randomly chosen triangles (indices, points)."""
    rng = np.random.default_rng(seed)
    t = triangles[rng.integers(0, len(triangles), n)]
    u = rng.random((n, 2))
    su = np.sqrt(u[:, 0])
    tri = scene.triangles[t]
    return t, ((1 - su)[:, None] * tri[:, 0] + (u[:, 1] * su)[:, None] * tri[:, 1]
               + (su - u[:, 1] * su)[:, None] * tri[:, 2])


def test_interpolation_reproduces_linear_fields_in_plain_and_refined_cells():
    # A small room with a low contrast threshold so that many cells are refined; the cache
    # values are then replaced by a linear function of position: linear interpolation must
    # reproduce it at any surface point, up to the inset of the cache points (10 ray
    # offsets ≈ 2e-4 m × |∇f| = 1 → 1e-3 absolute at most).
    scene, cache = _refined_small_room_cache()
    f = lambda p: 3.0 + p[:, 0] - 2.0 * p[:, 1] + 0.5 * p[:, 2]
    cache.values = np.repeat(f(cache.positions)[:, None], cache.values.shape[1], axis=1)
    t, x = _random_surface_points(scene, np.arange(len(scene.triangles)), 5000, 0)
    got = cache.interpolate(scene, t, x, np.zeros(len(t), int))
    assert np.allclose(got[:, 0], f(x), rtol=0, atol=1e-3)
    index, _, _, _ = cache._cells(scene, t, x, np.zeros(len(t), int))
    assert np.any(index >= cache.refined_offset.min())  # refined cells were used


def test_interpolation_bias_is_exact_for_quadratic_fields_and_linear_fields_on_patches():
    # Linear interpolation errs for a quadratic field by ½Σ w_a w_b e_abᵀHe_ab, which the
    # second differences of the grid give exactly (Hessian constant); the patch kernel
    # average errs for a linear field by ∇f·ū, which the weighted plane fit gives exactly
    # where its points span the plane, and which the patches' value subtracts (fully here:
    # equal groups, no noise to shrink it by). Tolerances: the cache points' inset (10 ray offsets ≈
    # 2e-4 m) × |∇f| ≤ 3 → 1e-3 absolute on the grid; on patches the part of ∇f along the
    # normal times the points' offsets from the tangent plane (up to sin 30° × the kernel
    # radius, and the corners where fewer than three points qualify) is not fitted: the
    # error's rms must fall at least 2× from the kernel average's, value + bias (measured 2.5×).
    scene, cache = _refined_small_room_cache()
    f = lambda p: 3.0 + p[:, 0] ** 2 - 2.0 * p[:, 1] * p[:, 0] + 0.5 * p[:, 2] ** 2 + p[:, 1] * p[:, 2]
    cache.values = np.repeat(f(cache.positions)[:, None], cache.values.shape[1], axis=1)
    t, x = _random_surface_points(scene, np.arange(len(scene.triangles)), 5000, 0)
    side = np.zeros(len(t), int)
    value, bias = cache.interpolate_with_bias(scene, t, x, side)
    assert np.array_equal(value, cache.interpolate(scene, t, x, side))  # one pass, same values
    err, bias = value[:, 0] - f(x), bias[:, 0]
    assert np.abs(err).max() > 0.05  # a bias worth estimating
    assert np.allclose(bias, err, rtol=0, atol=2e-3)
    # patches: the canonical room cut into small triangles
    room = canonical_room(size=16)
    fine = _tessellated(room, 3)
    cache = build_surface_cache(simulate(fine, samples=1024, seed=5), nodes=64, spacing=0.5)
    lin = lambda p: 3.0 + p[:, 0] - 0.5 * p[:, 1] + 0.3 * p[:, 2]
    cache.values = np.repeat(lin(cache.positions)[:, None], cache.values.shape[1], axis=1)
    t, x = _random_surface_points(fine, np.flatnonzero(cache.level == 0), 3000, 1)
    side = np.zeros(len(t), int)
    value, bias = cache.interpolate_with_bias(fine, t, x, side)
    assert np.array_equal(value, cache.interpolate(fine, t, x, side))
    err, bias = value[:, 0] - lin(x), bias[:, 0]
    assert np.sqrt(np.mean(err ** 2)) < 0.5 * np.sqrt(np.mean((err + bias) ** 2))


def test_rendered_uncertainty_covers_the_interpolation_error_of_a_known_field():
    # Through render_cached: a coarse cache of the canonical room whose values are replaced
    # by a known smooth field E(x) with independent noise per group (the groups' spread is
    # the map's noise); the truth per pixel is the render of a zero field (direct light and
    # emission only: exact here, every luminaire fully visible) plus ρ/π·E at the pixel's
    # hit. Its interpolation error (95th percentile 4 % at 0.8 m spacing) is far outside the
    # noise (median 0.12 %): with the bias estimate in the uncertainty, |z| ≤ 3 holds for
    # 98.5–99.1 % of the ≈ 1 700 pixels (measured over three seeds; the issue asks 99 %, the
    # assertion 98 % allows the spread of one realisation), rms z 1.19–1.27 (asserted
    # 0.6–1.5: neither blind nor a blanket margin); the noise part alone covers 51 %
    # (asserted < 80 %).
    room = canonical_room(size=48)
    view = room.views[0]
    store = simulate(room, samples=1024, seed=3)
    cache = build_surface_cache(store, spacing=0.8, nodes=64, seed=4)
    # the known field is smooth across the luminaires' outlines, where real E_ind is not:
    # the ceiling's points 1 cm behind them would be dropped (their clearance), so the rule
    # is off here — it has its own test (test_wall_points_behind_a_panel_...)
    cache.clearance[:] = np.inf
    G = cache.values.shape[1]
    field = lambda p: 80.0 * (1 + 0.5 * np.cos(2 * np.pi * p[:, 0] / 6)) * (1 + 0.3 * (p[:, 2] / 3) ** 2)
    rng = np.random.default_rng(7)
    exact = field(cache.positions)[:, None]
    kw = {"position": view.position, "rotation": view.rotation, "cache": cache}
    cache.values = np.zeros_like(cache.values)
    zero = render_cached(store, view.projection, **kw)
    cache.values = exact * (1 + 0.02 * rng.standard_normal((len(exact), G)))
    lmap = render_cached(store, view.projection, **kw)
    engine = engine_for(room)
    valid, prim, dist, d = primary_rays(room, engine, view.projection, view.position, view.rotation)
    lit = prim >= 0
    rho = np.where(lit, room.triangle_reflectance[np.maximum(prim, 0)], 0.0)
    truth = zero.luminance.ravel()[valid] + rho / math.pi * field(view.position + d * dist[:, None])
    ours = lmap.luminance.ravel()[valid]
    sigma = lmap.uncertainty.ravel()[valid].astype(float)
    ok = lit & (rho > 0)
    err = (ours - truth)[ok]
    z = err / sigma[ok]
    p = lmap.provenance
    assert np.mean(np.abs(z) <= 3) >= 0.98
    assert 0.6 < np.sqrt(np.mean(z ** 2)) < 1.5
    # the noise part alone (its median, from the provenance) would not cover the errors
    noise = p["pixel_relative_noise_median"] * truth[ok]
    assert np.mean(np.abs(err) <= 3 * noise) < 0.8
    assert p["pixel_relative_bias_p95"] > 3 * p["pixel_relative_noise_median"]


@pytest.mark.slow
def test_cached_render_agrees_with_the_per_pixel_double_local_estimate():
    # Two independent estimators of one room (separate stores): the field means agree within
    # 3 combined standard errors and 1 %; per pixel, the differences divided by their
    # combined standard error have a median |z| below 1.5 (0.67 for pure noise; measured
    # 0.77 with the interpolation-bias estimate in the cache's errors: the margin allows the
    # local estimate's heavy tails next to concave edges and the bias the estimate misses
    # where E_ind jumps).
    room = canonical_room(size=32)
    view = room.views[0]
    cached = render_cached(simulate(room, samples=16384, seed=5), view.projection,
                           position=view.position, rotation=view.rotation,
                           cache=None, workers=2)
    _assert_agrees_with_the_local_estimate(cached, room)


@pytest.mark.slow
def test_reported_uncertainty_matches_the_spread_over_independent_seeds():
    # Issue 13/14 (session 12): the σ that render(..., estimator="cache") reports — the
    # groups' spread, the direct light's sampling variance, the interpolation-bias estimate —
    # against the spread of maps from independent stores and caches (seeds 20–22). Per pair,
    # z = (L₁ − L₂)/√(σ₁² + σ₂²) over the lit pixels: mean z² within [0.5, 1.5] (1 for an
    # honest noise estimate; the common interpolation bias cancels in L₁ − L₂ and only widens
    # σ, and it is ≈ 0 here: median 0.002 % of L; measured 0.70–1.13 over six pairs of four
    # seeds; neighbouring pixels share cache points, so the ≈ 790 pixels count as about a
    # hundred independent values and mean z² spreads by ≈ ±0.14) and |z| ≤ 3 for at least
    # 98 % of them (measured 99.0–100 %; 99.5 % for a normal z whose σ comes from 16 groups).
    room = canonical_room(size=32)
    view = room.views[0]
    maps = [render(room, view.projection, position=view.position, rotation=view.rotation,
                   estimator="cache", samples=16384, seed=seed, workers=2) for seed in (20, 21, 22)]
    for i, j in ((0, 1), (0, 2), (1, 2)):
        a, b = maps[i], maps[j]
        combined = np.hypot(a.uncertainty, b.uncertainty)
        ok = np.isfinite(combined) & (combined > 0) & (a.luminance > 1)  # not the panels
        z = (a.luminance - b.luminance)[ok] / combined[ok]
        assert 0.5 <= np.mean(z ** 2) <= 1.5
        assert np.mean(np.abs(z) <= K_SIGMA) >= 0.98


def test_refined_cells_near_the_refinement_test_report_the_coarse_interpolation_difference():
    # Issue 13 (session 12): the build refines a cell when its corner values pass a contrast
    # test that follows their noise, so an independent cache leaves a cell near the test's
    # threshold unrefined and interpolates it on the coarse grid, which all its groups share.
    # Such a refined cell reports |fine − coarse interpolation| in its bias. Here the cache's
    # map through render(..., estimator="cache") against the map of the same cache with its
    # refined cells removed (the coarse interpolation an independent cache could have made;
    # same store and render seed, so only the refined pixels differ): the difference lies
    # within 3σ of the refined map for 99.0, 99.7 and 100 % of the 289–396 changed pixels
    # (three seeds; before, 93.1 % for the first; the cells that pass the test by 3 standard
    # errors or more keep their finer estimate's bias only, hence not 100 %): asserted 97 %.
    from lsadphoto.geometry.pinhole import PinholeProjection

    scene = scene_from_dict({
        "materials": {"grey": {"reflectance": 0.5}},
        "surfaces": [{"type": "box", "min": [0, 0, 0], "max": [2, 1.5, 1], "facing": "inward", "material": "grey"},
                     {"type": "box", "min": [0.9, 0.3, 0], "max": [1.3, 1.2, 0.4], "facing": "outward",
                      "material": "grey"}],
        "luminaires": [{"type": "point", "position": [0.5, 0.5, 0.9], "flux": 1000}],
    })
    size = 32
    focal = size / (2 * math.tan(math.radians(45)))
    proj = PinholeProjection(fx=focal, fy=focal, cx=(size - 1) / 2, cy=(size - 1) / 2, width=size, height=size)
    pose = {"position": np.array([1.95, 0.1, 0.8]), "rotation": camera_to_world([-1, 0.8, -0.5])}
    store = simulate(scene, samples=8192, seed=1)
    store.surface_cache = build_surface_cache(store, spacing=0.3, nodes=256, seed=2)
    assert store.surface_cache.refined_key.size > 0
    fine = render(store, proj, estimator="cache", seed=3, **pose)
    store.surface_cache = dataclasses.replace(store.surface_cache, refined_key=np.zeros(0, np.int64),
                                              refined_offset=np.zeros(0, np.int64))
    coarse = render(store, proj, estimator="cache", seed=3, **pose)
    difference = np.abs(fine.luminance - coarse.luminance)
    changed = np.isfinite(difference) & (difference > 0)
    assert changed.sum() > 100
    assert np.mean(difference[changed] <= K_SIGMA * fine.uncertainty[changed]) >= 0.97


def _assert_agrees_with_the_local_estimate(cached, room):
    """The cached map against the double local estimate of ``room``'s first view (its own
    store): field means within 3 combined standard errors and 1 %, median |z| < 1.5 over the
    lit pixels (not the panels)."""
    view = room.views[0]
    local = render(simulate(room, samples=16384, seed=6), view.projection, position=view.position,
                   rotation=view.rotation, nodes_per_pixel=64, workers=2)
    a, b = cached.provenance, local.provenance
    se = math.hypot(a["field_mean_standard_error"], b["field_mean_standard_error"])
    assert abs(a["field_mean_luminance"] - b["field_mean_luminance"]) <= K_SIGMA * se
    assert abs(a["field_mean_luminance"] / b["field_mean_luminance"] - 1) <= REL_TOL
    combined = np.hypot(cached.uncertainty, local.uncertainty)
    ok = np.isfinite(local.luminance) & (local.luminance > 1) & (combined > 0)  # not the panels
    z = (cached.luminance - local.luminance)[ok] / combined[ok]
    assert np.median(np.abs(z)) < 1.5


def test_results_do_not_depend_on_threads_or_chunks():
    room = canonical_room(size=24)
    view = room.views[0]
    store = simulate(room, samples=2048, seed=1)
    c1 = build_surface_cache(store, nodes=64, workers=1)
    c2 = build_surface_cache(store, nodes=64, workers=2)
    assert np.array_equal(c1.values, c2.values)
    kw = {"position": view.position, "rotation": view.rotation, "cache": c1}
    m1 = render_cached(store, view.projection, workers=1, chunk_pixels=256, **kw)
    m2 = render_cached(store, view.projection, workers=2, chunk_pixels=4096, **kw)
    assert np.array_equal(m1.luminance, m2.luminance, equal_nan=True)
    assert np.array_equal(m1.uncertainty, m2.uncertainty, equal_nan=True)


def test_indirect_estimates_of_different_keys_are_independent():
    store = simulate(canonical_room(size=8), samples=4096, seed=1)
    x = np.array([[3.0, 2.0, 0.0], [0.0, 2.0, 1.5]])
    n = np.array([[0, 0, 1.0], [1, 0, 0]])
    e1 = indirect_illuminance(store, x, n, nodes=512, key=1)
    e2 = indirect_illuminance(store, x, n, nodes=512, key=2)
    assert not np.array_equal(e1, e2)
    # Both unbiased for one quantity: the means agree within 4 combined standard errors.
    se = np.hypot(e1.std(axis=1, ddof=1), e2.std(axis=1, ddof=1)) / 4
    assert np.all(np.abs(e1.mean(axis=1) - e2.mean(axis=1)) <= 4 * se)


def test_store_keeps_its_surface_cache(tmp_path):
    room = canonical_room(size=16)
    view = room.views[0]
    store = simulate(room, samples=1024, seed=1)
    store.surface_cache = build_surface_cache(store, nodes=32)
    store.save(tmp_path / "s.npz")
    again = load_store(tmp_path / "s.npz")
    assert isinstance(again.surface_cache, SurfaceCache)
    for name in ("level", "offset", "values", "positions", "refined_key", "refined_offset", "clearance"):
        assert np.array_equal(getattr(again.surface_cache, name), getattr(store.surface_cache, name))
    kw = {"position": view.position, "rotation": view.rotation}
    assert np.array_equal(render_cached(store, view.projection, **kw).luminance,
                          render_cached(again, view.projection, **kw).luminance, equal_nan=True)
    # a store saved before the clearance existed loads with it ∞: the plain interpolation
    with np.load(tmp_path / "s.npz") as data:
        np.savez_compressed(tmp_path / "old.npz", **{k: data[k] for k in data.files if k != "cache_clearance"})
    old = load_store(tmp_path / "old.npz").surface_cache
    assert np.all(np.isinf(old.clearance)) and old.clearance.size == old.size
    store.extend(simulate(room, samples=1024, seed=2))
    assert store.surface_cache is None  # stale after new chains


def test_bad_input():
    room = canonical_room(size=8)
    store = simulate(room, samples=256, seed=1)
    for kwargs in ({"spacing": 0}, {"spacing": float("nan")}, {"nodes": 0}, {"refine": 0},
                   {"contrast": 0}, {"workers": 0}, {"patch_refine": -1}, {"patch_refine": 0.5}):
        with pytest.raises(BadInputError):
            build_surface_cache(store, **kwargs)
    with pytest.raises(BadInputError):
        build_surface_cache(room)
    with pytest.raises(BadInputError):
        render_cached(room, room.views[0].projection, position=[1, 2, 1], rotation=np.eye(3))
    with pytest.raises(BadInputError):
        direct_illuminance(room, engine_for(room), [[1, 1, 0]], [[0, 0, 1]], samples=0)
    with pytest.raises(BadInputError, match="luminaire draws must be a positive integer, got 0"):
        render_cached(store, room.views[0].projection, position=[1, 2, 1], rotation=np.eye(3),
                      luminaire_draws=0)


def test_cli_simulate_with_cache_and_render_from_it(tmp_path, capsys):
    scene = tmp_path / "room.toml"
    scene.write_text(canonical_room_toml(size=24))
    store = tmp_path / "s.npz"
    assert main(["simulate", str(scene), "-o", str(store), "--samples", "2048", "--surface-cache",
                 "--cache-nodes", "64", "--quiet"]) == 0
    assert load_store(store).surface_cache is not None
    capsys.readouterr()
    out = tmp_path / "m.exr"
    assert main(["render", str(store), "--estimator", "cache", "-o", str(out), "--quiet", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["provenance"]["estimator"].startswith("surface cache")
    assert record["provenance"]["cache_nodes_per_point"] == 64
    lmap = read_exr(out)
    assert np.nanmax(lmap.luminance) > 0
    assert main(["simulate", str(scene), "-o", str(store), "--samples", "64", "--surface-cache",
                 "--cache-spacing", "-1", "--quiet"]) == 2
    assert "cache spacing" in capsys.readouterr().err


def test_touching_planes_render_as_one_from_the_cache():
    # A floor split into two touching squares under a 100 cd isotropic point 2 m above:
    # only the floor reflects, so E_ind = 0 and every pixel is the closed form
    # L = ρ·I·cos θ/(π d²) — no leak or seam where the squares meet (float32 map: 1e-6;
    # the 1° intensity table of the isotropic luminaire is exact).
    scene = scene_from_dict({
        "materials": {"grey": {"reflectance": 0.5}},
        "surfaces": [
            {"type": "polygon", "material": "grey", "vertices": [[-3, -3, 0], [0, -3, 0], [0, 3, 0], [-3, 3, 0]]},
            {"type": "polygon", "material": "grey", "vertices": [[0, -3, 0], [3, -3, 0], [3, 3, 0], [0, 3, 0]]},
        ],
        "luminaires": [{"type": "point", "position": [0, 0, 2], "flux": 400 * math.pi}],
    })
    camera = IdealFisheyeProjection("equidistant", 15.5, 15.5, 16.0, 120.0, 32, 32)
    position = np.array([0.1, 0.2, 3.0])
    rotation = camera_to_world([0, 0, -1], [0, 1, 0])
    store = simulate(scene, samples=512, seed=1)
    lmap = render_cached(store, camera, position=position, rotation=rotation,
                         cache=build_surface_cache(store, nodes=64))
    rows, cols = camera.pixel_grid()
    d = camera.directions(rows, cols) @ rotation.T
    hit = position + (-position[2] / d[..., 2])[..., None] * d
    inside = np.all(np.abs(hit[..., :2]) < 3, axis=-1) & np.isfinite(d[..., 2])
    d2 = hit[..., 0] ** 2 + hit[..., 1] ** 2 + 4.0
    expected = 0.5 * 100 * (2 / np.sqrt(d2)) / (math.pi * d2)
    assert np.allclose(lmap.luminance[inside], expected[inside], rtol=1e-5)


def _tessellated(scene, times):
    """``scene`` with every non-emitting triangle split ``times`` times into four (midpoints);
    the first piece keeps the triangle's index, so luminaires keep theirs."""
    tris, mat, em = scene.triangles, scene.material, scene.emitter
    split = np.flatnonzero(em < 0)
    pieces = tris[split]
    for _ in range(times):
        a, b, c = pieces[:, 0], pieces[:, 1], pieces[:, 2]
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        pieces = np.stack([np.stack(t, axis=1) for t in
                           ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))], axis=1).reshape(-1, 3, 3)
    k = 4 ** times
    pieces = pieces.reshape(len(split), k, 3, 3)
    new = tris.copy()
    new[split] = pieces[:, 0]
    rest = pieces[:, 1:].reshape(-1, 3, 3)
    return dataclasses.replace(scene, triangles=np.concatenate([new, rest]),
                               material=np.concatenate([mat, np.repeat(mat[split], k - 1)]),
                               emitter=np.concatenate([em, np.full(len(rest), -1, em.dtype)]))


@pytest.mark.slow
def test_a_finely_tessellated_room_costs_its_area_and_renders_as_the_plain_one():
    # The canonical room with every surface cut into 256 triangles (3072 in all, each
    # smaller than the cache spacing): the cache shares points across them (patches), so it
    # has fewer points than the triangles have sides, and its render agrees with the
    # per-pixel double local estimate of the plain room (an independent estimator and
    # store): field means within 3 combined standard errors and 1 %, median |z| < 1.5 per
    # pixel as in the test above (0.67 for pure noise; measured 0.79 with the kernel
    # average's estimated bias in the cache's errors).
    room = canonical_room(size=32)
    fine = _tessellated(room, 4)
    view = room.views[0]
    store = simulate(fine, samples=16384, seed=5)
    cache = build_surface_cache(store, nodes=2048, workers=2)
    assert cache.provenance["grid_points"] == 0
    assert cache.size < len(fine.triangles)
    cached = render_cached(store, view.projection, position=view.position, rotation=view.rotation,
                           cache=cache, workers=2)
    _assert_agrees_with_the_local_estimate(cached, room)


def _room_with_column():
    """A 4 × 4 × 3 m grey room (ρ = 0.5) with a closed square column (outward box, 0.4 m, 1.8–2.2 m
    in x and y) and a point luminaire, every surface cut into small triangles (patches)."""
    scene = scene_from_dict({
        "materials": {"grey": {"reflectance": 0.5}},
        "surfaces": [{"type": "box", "min": [0, 0, 0], "max": [4, 4, 3], "facing": "inward",
                      "material": "grey"},
                     {"type": "box", "min": [1.8, 1.8, 0], "max": [2.2, 2.2, 3], "facing": "outward",
                      "material": "grey"}],
        "luminaires": [{"type": "point", "position": [1, 1, 2.5], "flux": 1000}],
    })
    return _tessellated(scene, 3)


def test_patch_interpolation_keeps_parallel_sheets_apart():
    # A closed square column (outward box, 0.4 m, cut into small triangles) in a room: the
    # sides inside the column see no light (E_ind = 0 there), the outer sides do. Written
    # into the cache as 0 inside and 1 outside, the kernel average on every outer side is
    # exactly 1 (constants are reproduced; the inner side of the opposite face, parallel
    # and 0.4 m away within the 1.5 m kernel, may not leak in), and 0 inside.
    scene = _room_with_column()
    store = simulate(scene, samples=512, seed=1)
    cache = build_surface_cache(store, spacing=1.0, nodes=16, patch_refine=0, seed=2)
    # the column's four sides (its top and bottom lie in the ceiling's and floor's planes)
    column = np.flatnonzero(np.all((scene.triangles[:, :, :2] > 1.7) & (scene.triangles[:, :, :2] < 2.3),
                                   axis=(1, 2)) & (np.abs(scene.normals[:, 2]) < 0.5))
    assert np.all(cache.level[column] == 0)
    outer_rows = cache.patch_row[np.unique(cache.patch[column, 0])]
    inner_rows = cache.patch_row[np.unique(cache.patch[column, 1])]
    assert not np.intersect1d(outer_rows, inner_rows).size
    cache.values[:] = 0.0
    cache.values[outer_rows] = 1.0
    rng = np.random.default_rng(0)
    t = rng.choice(column, 400)
    u = rng.random((400, 2))
    su = np.sqrt(u[:, 0])
    tri = scene.triangles[t]
    x = ((1 - su)[:, None] * tri[:, 0] + (u[:, 1] * su)[:, None] * tri[:, 1]
         + (su - u[:, 1] * su)[:, None] * tri[:, 2])
    assert np.all(cache.interpolate(scene, t, x, np.zeros(400, int)) == 1.0)
    assert np.all(cache.interpolate(scene, t, x, np.ones(400, int)) == 0.0)


def test_patch_kernel_lean_marks_pixels_beyond_their_points():
    # The lean of the patch kernel (interpolate_with_bias(support=True)): the distance from a
    # point to its kernel points' weighted centroid on the tangent plane. On a face of the
    # closed column above (0.4 × 3 m, cut into small triangles; patch points at 0.5, 1.38 and
    # 2.38–2.5 m), a point below the lowest points or above the highest sees them all on one
    # side: lean ≈ support (measured 0.95–0.98 of it at 0.1, 0.3 and 2.9 m), which the render's
    # lean test (PIXEL_LEAN = 0.8) marks as an extrapolation; a point between points has a
    # small lean (0.06–0.11 of the support at 1.0, 1.5 and 2.0 m). Asserted against those
    # bounds with margin; and 0 ≤ lean ≤ support everywhere (|Σ w·u|/Σ w ≤ Σ w·|x − q|/Σ w).
    from lsadphoto.solver.integrators.surface_cache import PIXEL_LEAN

    scene = _room_with_column()
    cache = build_surface_cache(simulate(scene, samples=512, seed=1), spacing=1.0, nodes=16, patch_refine=0,
                                seed=2)
    z = np.array([0.1, 0.3, 2.9, 1.0, 1.5, 2.0])
    x = np.column_stack([np.full(z.size, 1.8), np.full(z.size, 2.0), z])
    prim = engine_for(scene).closest_hit(x - [0.8, 0, 0], np.tile([1.0, 0, 0], (z.size, 1)))[0]
    assert np.all(cache.level[prim] == 0)
    side = np.where(scene.normals[prim, 0] < 0, 0, 1)  # the side facing −x, out of the column
    _, _, support, lean = cache.interpolate_with_bias(scene, prim, x, side, support=True)
    ratio = lean / support
    assert np.all(ratio[:3] > 0.9) and PIXEL_LEAN < 0.9
    assert np.all(ratio[3:] < 0.25)
    column = np.flatnonzero(np.all((scene.triangles[:, :, :2] > 1.7) & (scene.triangles[:, :, :2] < 2.3),
                                   axis=(1, 2)) & (np.abs(scene.normals[:, 2]) < 0.5))
    t = np.random.default_rng(3).choice(column, 300)
    centre = scene.triangles[t].mean(axis=1)
    _, _, support, lean = cache.interpolate_with_bias(scene, t, centre, np.zeros(300, int), support=True)
    assert np.all(lean >= 0) and np.all(lean <= support * (1 + 1e-12))



def test_cells_of_a_thin_grid_triangle_are_no_longer_than_the_grid_cell_edge():
    # A grid's level follows the triangle's area (√(2A)/m ≈ spacing), so the cells of a thin
    # triangle were up to 3 spacings long: on the station hall's end walls (slivers fanned
    # under the vault) 2.4 m tall cells, across which E_ind rises and falls, put pixels 12–15 %
    # low at a reported 0.5 % (docs/accuracy.md, session 16). The level now also keeps every
    # cell edge within GRID_CELL_EDGE spacings, which the area rule already gives a
    # rectangle's halves (the room's walls: 1.47 spacings, their level unchanged). Here a
    # 3.6 m × 0.3 m sliver on the floor (area rule: level 4, cells 0.9 m = 2.8 spacings long)
    # and the room's own triangles, against those bounds.
    from lsadphoto.solver.integrators.surface_cache import GRID_CELL_EDGE, RELATIVE_CACHE_SPACING

    room = _canonical_room_with({"type": "polygon", "material": "wall", "vertices": [
        [1.0, 1.0, 0.01], [4.6, 1.0, 0.01], [1.0, 1.3, 0.01]]})
    cache = build_surface_cache(simulate(room, samples=512, seed=1), nodes=16, refine=1, patch_refine=0, seed=2)
    spacing = RELATIVE_CACHE_SPACING * room.size
    tris = room.triangles
    longest = np.linalg.norm(tris - np.roll(tris, 1, axis=1), axis=2).max(axis=1)
    grid = np.flatnonzero(cache.level >= 1)
    sliver = int(np.flatnonzero(np.all(np.isclose(tris[:, :, 2], 0.01), axis=1))[0])
    by_area = np.ceil(np.maximum(np.sqrt(2 * room.areas), longest / 3) / spacing).astype(int)
    assert sliver in grid and longest[sliver] / by_area[sliver] > 2.5 * spacing
    assert np.all(longest[grid] / cache.level[grid] <= GRID_CELL_EDGE * spacing)
    rest = grid[grid != sliver]
    assert np.array_equal(cache.level[rest], by_area[rest])

def _canonical_room_with(surface):
    """The canonical room (its TOML with an 8 × 8 px view) with one more surface (a TOML surface table)."""
    import tomllib

    data = tomllib.loads(canonical_room_toml(size=8))
    data["surfaces"].append(surface)
    return scene_from_dict(data)


def test_wall_points_behind_a_panel_do_not_darken_the_wall_beside_it():
    # The canonical room with a grey 1.4 × 1.2 m panel 1 cm in front of the wall x = 6: the
    # wall's cache points in the gap are dark, and interpolated into the visible wall they
    # made the pixels 1–10 cm outside the panel's outline 7 % too dark on average (22 % at
    # worst; median |z| 2.2, 55 % within 3σ, measured with the clearance rule off). The
    # reference per pixel is independent of the cache: ρ/π·(E_dir + E_ind) at the pixel's hit,
    # E_dir by 64 shadow samples per luminaire and E_ind by the cache's estimator evaluated
    # there (its own streams, 4096 node draws: 0.45 % standard error), no interpolation.
    # Measured with the rule: mean ratio 0.989, median |z| 0.91, 89 % within 3σ; asserted
    # within 3 % (the rule removes 6 of the 7 %), median |z| < 1.5 (0.67 for pure noise; the
    # margin for the constant extrapolation from the corners left) and 80 % within 3σ.
    from lsadphoto.geometry.pinhole import PinholeProjection

    room = _canonical_room_with({"type": "polygon", "material": "wall", "vertices": [
        [5.99, 1.3, 0.8], [5.99, 2.7, 0.8], [5.99, 2.7, 2.0], [5.99, 1.3, 2.0]]})
    store = simulate(room, samples=2 ** 15, seed=11)
    store.surface_cache = build_surface_cache(store, nodes=512, seed=12)
    size = 64
    focal = size / (2 * math.tan(math.radians(30)))
    proj = PinholeProjection(fx=focal, fy=focal, cx=(size - 1) / 2, cy=(size - 1) / 2, width=size, height=size)
    pos, rot = np.array([3.0, 2.0, 1.4]), camera_to_world([1, 0, 0])
    lmap = render(store, proj, position=pos, rotation=rot, estimator="cache", seed=15)
    engine = engine_for(room)
    valid, prim, dist, d = primary_rays(room, engine, proj, pos, rot)
    x = pos + d * dist[:, None]
    outside = np.maximum(np.maximum(1.3 - x[:, 1], x[:, 1] - 2.7), np.maximum(0.8 - x[:, 2], x[:, 2] - 2.0))
    band = np.flatnonzero((prim >= 0) & (np.abs(x[:, 0] - 6) < 1e-6) & (outside > 0.01) & (outside < 0.10))
    assert band.size > 100
    normal = np.tile([-1.0, 0, 0], (band.size, 1))
    e_ind = indirect_illuminance(store, x[band], normal, nodes=4096, seed=13, key=5)
    e_dir, var = direct_illuminance(room, engine, x[band], normal, samples=64, seed=14,
                                    block_ids=np.arange(band.size))
    k = 0.5 / math.pi
    ref = k * (e_dir + e_ind.mean(axis=1))
    ref_se = k * np.hypot(np.sqrt(var), e_ind.std(axis=1, ddof=1) / math.sqrt(e_ind.shape[1]))
    ours = lmap.luminance.ravel()[valid][band]
    z = (ours - ref) / np.hypot(lmap.uncertainty.ravel()[valid][band], ref_se)
    assert abs(np.mean(ours / ref) - 1) < 0.03
    assert np.median(np.abs(z)) < 1.5
    assert np.mean(np.abs(z) <= 3) >= 0.8


def test_floor_points_inside_a_box_standing_on_the_floor_do_not_darken_the_floor_beside_it():
    # A closed 0.4 × 0.4 × 1 m box standing on the canonical room's floor (two large
    # triangles with their own grids): the floor's cache points inside its footprint get no
    # light (E_ind = 0 there), and their normal ray reaches the box's lid 1 m up, so the
    # clearance rule keeps them. Written into the cache as 0 there and 1 everywhere else, the
    # interpolation at floor points 1–15 cm outside the box must reproduce the constant 1
    # (corners hidden from the point are left out): before the visibility test a quarter of
    # them came out darker (down to 0.52, mean 0.948); the rule's fallback (a cell whose
    # corners with a positive weight are all hidden keeps its plain interpolation) may leave
    # a few.
    room = _canonical_room_with({"type": "box", "min": [2.8, 1.8, 0.0], "max": [3.2, 2.2, 1.0],
                                 "facing": "outward", "material": "wall"})
    store = simulate(room, samples=2 ** 12, seed=11)
    cache = build_surface_cache(store, nodes=16, seed=12)
    floor = np.flatnonzero(np.all(np.abs(room.triangles[:, :, 2]) < 1e-9, axis=1) & (room.normals[:, 2] > 0.5))
    assert floor.size == 2 and np.all(cache.level[floor] >= 1)
    p = cache.positions
    inside = (np.abs(p[:, 2]) < 1e-6) & (np.abs(p[:, 0] - 3) < 0.2) & (np.abs(p[:, 1] - 2) < 0.2)
    assert inside.sum() > 10
    cache.values[:] = 1.0
    cache.values[inside] = 0.0
    rng = np.random.default_rng(0)
    xy = rng.uniform([2.6, 1.6], [3.4, 2.4], (8000, 2))
    gap = np.maximum(np.abs(xy[:, 0] - 3), np.abs(xy[:, 1] - 2)) - 0.2
    xy = xy[(gap > 0.01) & (gap < 0.15)]
    x = np.column_stack([xy, np.zeros(len(xy))])
    engine = engine_for(room)
    prim, _ = engine.closest_hit(x + [0, 0, 0.5], np.tile([0.0, 0.0, -1.0], (len(x), 1)))
    assert np.all(np.isin(prim, floor))
    value = cache.interpolate(room, prim, x, np.zeros(len(x), int))
    assert np.mean(np.abs(value - 1.0) < 1e-9) >= 0.99


@pytest.mark.slow
def test_wall_of_small_triangles_just_above_a_bench_in_front_takes_its_indirect_light_at_the_pixel():
    # The station hall's column faces just above a bench seat (docs/accuracy.md, session 13):
    # the canonical room cut into small triangles (its sides interpolate patch points of
    # 1 m) with a 0.45 m high bench standing 0.2 m in front of the wall x = 6; the pixels on
    # the wall 0.02–0.3 m above the seat, whose normal ray passes over the bench (so the
    # validity test with the normal ray alone keeps their interpolation), see the bench
    # below them and get less E_ind than the patch points 0.5–1 m away. Reference per
    # pixel, independent of the cache and of the render's store: ρ/π·(E_dir + E_ind) at the
    # pixel's hit, E_dir by 64 shadow samples per luminaire and E_ind by the cache's
    # estimator on another store (4096 node draws). Mean ratio over the 414 pixels, seeds
    # 1–4: before 1.003, 0.957, 0.961, 0.961 (seed 2 asserted here: 0.957); with the probe
    # rings (render_cached's Notes) 1.005, 0.992, 1.015, 1.009. Asserted within 2.5 % (the two
    # stores' chain noise, common to all pixels and in neither σ, moves the mean by ≈ 1 %:
    # the four seeds' spread after) and the bias of before (−4.3 %) excluded.
    from lsadphoto.geometry.pinhole import PinholeProjection

    room = _tessellated(_canonical_room_with({"type": "box", "min": [5.3, 1.0, 0.0], "max": [5.8, 3.0, 0.45],
                                              "facing": "outward", "material": "wall"}), 3)
    store = simulate(room, samples=2 ** 15, seed=2)
    store.surface_cache = build_surface_cache(store, spacing=1.0, nodes=512, seed=3)
    size = 64
    focal = size / (2 * math.tan(math.radians(20)))
    proj = PinholeProjection(fx=focal, fy=focal, cx=(size - 1) / 2, cy=(size - 1) / 2, width=size, height=size)
    pose = {"position": np.array([3.0, 2.0, 0.9]), "rotation": camera_to_world([1, 0, -0.08])}
    lmap = render(store, proj, estimator="cache", seed=6, **pose)
    engine = engine_for(room)
    valid, prim, dist, d = primary_rays(room, engine, proj, pose["position"], pose["rotation"])
    x = pose["position"] + d * dist[:, None]
    band = np.flatnonzero((prim >= 0) & (np.abs(x[:, 0] - 6) < 1e-6) & (x[:, 2] > 0.47) & (x[:, 2] < 0.75)
                          & (np.abs(x[:, 1] - 2) < 0.8))
    assert band.size > 300 and np.all(store.surface_cache.level[prim[band]] == 0)
    assert lmap.provenance["pixels_estimated_without_cache"] > band.size
    normal = np.tile([-1.0, 0, 0], (band.size, 1))
    e_ind = indirect_illuminance(simulate(room, samples=2 ** 15, seed=52), x[band], normal, nodes=4096, seed=4, key=5)
    e_dir, _ = direct_illuminance(room, engine, x[band], normal, samples=64, seed=5, block_ids=np.arange(band.size))
    ref = 0.5 / math.pi * (e_dir + e_ind.mean(axis=1))
    assert abs(np.mean(lmap.luminance.ravel()[valid][band] / ref) - 1) < 0.025


@pytest.mark.slow
def test_column_top_above_the_luminaires_takes_its_indirect_light_at_the_pixel(tmp_path):
    # The station hall's column tops above the luminaires' plane (docs/accuracy.md, session
    # 14): the 0.35-scale hall of the accuracy benchmark (columns of 2 m × 0.31 m facets to
    # 6 m, point luminaires at 5.5 m beside them), a narrow view of the top 0.4 m of the
    # nearest column. E_ind there falls by a third from 5 m to 6 m (no direct light above
    # the luminaires' plane, the lit column faces below it seen less and less), while the
    # top patch's points lie at 4.7 and 5.3 m, all below these pixels: the kernel
    # extrapolates from one side, and neither its plane nor the probe rings (nothing near)
    # see it. With the lean test (render_cached's Notes) the pixels take E_ind at their own
    # point. Reference per pixel, independent of the cache and of the render's store:
    # ρ/π·(E_dir + E_ind) at the pixel's hit, E_dir by 64 shadow samples per luminaire and
    # E_ind by the cache's estimator on another store (16 384 node draws). Mean ratio over
    # the 244 pixels, seeds 1–3: before 1.114, 1.170, 1.225; after 0.971, 0.979, 1.009
    # (seed 2 asserted). Asserted within 6 %: the two stores' chain noise is common to all
    # pixels and in neither σ (the seeds' spread, ±2–5 % before and after), and the bias of
    # before (+17 % at seed 2) is excluded.
    from lsadphoto.datasets.hall import make_station_hall
    from lsadphoto.geometry.pinhole import PinholeProjection

    hall = read_scene(make_station_hall(tmp_path, length=21.0, width=10.0, luminaires=42, detail=0.35,
                                        view_size=16))
    store = simulate(hall, samples=2 ** 16, seed=2)
    store.surface_cache = build_surface_cache(store, nodes=4096, seed=3)
    size = 48
    focal = size / (2 * math.tan(math.radians(6)))
    proj = PinholeProjection(fx=focal, fy=focal, cx=(size - 1) / 2, cy=(size - 1) / 2, width=size, height=size)
    eye = np.array([3.0, 5.0, 1.6])
    pose = {"position": eye, "rotation": camera_to_world(np.array([3.6, 6.5, 5.6]) - eye)}
    lmap = render(store, proj, estimator="cache", seed=7, **pose)
    engine = engine_for(hall)
    valid, prim, dist, d = primary_rays(hall, engine, proj, pose["position"], pose["rotation"])
    x = eye + d * dist[:, None]
    band = np.flatnonzero((prim >= 0) & (x[:, 2] > 5.55) & (x[:, 2] < 5.95)
                          & (np.hypot(x[:, 0] - 3.675, x[:, 1] - 6.6667) < 0.41))
    assert band.size > 200 and np.all(store.surface_cache.level[prim[band]] == 0)
    normal, _ = hall.facing_normals(prim[band], d[band])
    e_ind = indirect_illuminance(simulate(hall, samples=2 ** 16, seed=52), x[band], normal, nodes=16384, seed=4,
                                 key=5)
    e_dir, _ = direct_illuminance(hall, engine, x[band], normal, samples=64, seed=5, block_ids=np.arange(band.size))
    ref = 0.4 / math.pi * (e_dir + e_ind.mean(axis=1))
    assert abs(np.mean(lmap.luminance.ravel()[valid][band] / ref) - 1) < 0.06


@pytest.mark.slow
def test_floor_under_a_low_bench_takes_its_indirect_light_at_the_pixel():
    # A 1.2 × 1.6 m bench seat 0.25 m over the canonical room's floor (a box 5 cm thick, no
    # legs), seen from 0.15 m above the floor, with a coarse cache (1 m cells, refinement
    # off): under the seat E_dir = 0 and E_ind is a fraction of the open floor's, but every
    # floor corner under the seat is farther from the pixel than its clearance (0.25 m) and is
    # dropped, so the interpolation extrapolated the open floor's corners outside it: 1.8–2.1×
    # the reference, 17–33 % of the pixels within 3σ, median |z| 4.3–5.1 (three seeds). Where
    # the interpolation's support distance exceeds half the pixel's free distance
    # (render_cached's Notes) the pixel's E_ind is the cache's estimator at its point. The
    # reference is independent of the cache: the per-pixel double local estimate of another
    # store (256 nodes per pixel: 11–16 % relative standard error per pixel here, all of it
    # from the indirect light). Measured over six seeds: mean ratio 0.96–1.11 (the two stores'
    # noise is common to all pixels, so the mean over pixels keeps much of a pixel's 11 %),
    # median |z| 0.73–0.82, 100 % within 3σ; asserted within 15 % (the before was +80 % or
    # more), median |z| < 1.5 (0.67 for pure noise) and 95 % within 3σ. The pixels' own
    # estimates draw from their pixel blocks' streams: the map does not depend on chunks or
    # threads.
    from lsadphoto.geometry.pinhole import PinholeProjection

    room = _canonical_room_with({"type": "box", "min": [2.4, 1.2, 0.25], "max": [3.6, 2.8, 0.3],
                                 "facing": "outward", "material": "wall"})
    store = simulate(room, samples=2 ** 14, seed=11)
    store.surface_cache = build_surface_cache(store, spacing=1.0, refine=1, nodes=512, seed=12)
    size = 48
    focal = size / (2 * math.tan(math.radians(30)))
    proj = PinholeProjection(fx=focal, fy=focal, cx=(size - 1) / 2, cy=(size - 1) / 2, width=size, height=size)
    pose = {"position": np.array([1.6, 2.0, 0.15]), "rotation": camera_to_world([1, 0, -0.15])}
    lmap = render(store, proj, estimator="cache", seed=15, **pose)
    local = render(simulate(room, samples=2 ** 14, seed=21), proj, nodes_per_pixel=256, seed=22, **pose)
    valid, prim, dist, d = primary_rays(room, engine_for(room), proj, pose["position"], pose["rotation"])
    x = pose["position"] + d * dist[:, None]
    under = np.flatnonzero((prim >= 0) & (np.abs(x[:, 2]) < 1e-6) & (np.abs(x[:, 0] - 3) < 0.55)
                           & (np.abs(x[:, 1] - 2) < 0.75))
    assert under.size > 100
    assert lmap.provenance["pixels_estimated_without_cache"] >= under.size
    ours, ref = lmap.luminance.ravel()[valid][under], local.luminance.ravel()[valid][under]
    z = (ours - ref) / np.hypot(lmap.uncertainty.ravel()[valid][under], local.uncertainty.ravel()[valid][under])
    assert abs(np.mean(ours) / np.mean(ref) - 1) < 0.15
    assert np.median(np.abs(z)) < 1.5
    assert np.mean(np.abs(z) <= 3) >= 0.95
    again = render(store, proj, estimator="cache", seed=15, chunk_pixels=512, workers=2, **pose)
    assert np.array_equal(again.luminance, lmap.luminance, equal_nan=True)
    assert np.array_equal(again.uncertainty, lmap.uncertainty, equal_nan=True)


def test_node_pools_follow_the_morton_curve_of_each_group():
    # _pools_along_curve against the definition, bit by bit: pool g holds the nodes of
    # batches ≡ g (mod groups) in the order of their cells' Morton codes (bit b of the cell
    # index along axis a at bit 3b + a, 2¹⁰ cells per axis of the scene's bounding cube),
    # equal codes in the nodes' order (a stable sort).
    from types import SimpleNamespace

    from lsadphoto.solver.integrators.surface_cache import _NodeHull

    rng = np.random.default_rng(5)
    n = 3000
    position = rng.uniform([0, 0, 0], [6, 4, 3], size=(n, 3))
    position[n // 2:n // 2 + 40] = position[7]  # equal codes
    batch = rng.integers(0, 37, size=n).astype(np.int16)
    scene = SimpleNamespace(triangles=np.array([[[0, 0, 0], [6, 0, 0], [0, 4, 3]]], dtype=float))
    hull = SimpleNamespace(scene=scene, store=SimpleNamespace(position=position, batch=batch))
    nodes = np.sort(rng.choice(n, size=2500, replace=False))
    pools = _NodeHull._pools_along_curve(hull, nodes, 16)

    def code(p):
        q = [min(max(int((p[a] - 0.0) / 6.0 * 1024), 0), 1023) for a in range(3)]
        return sum(((q[a] >> b) & 1) << (3 * b + a) for b in range(10) for a in range(3))

    for g in range(16):
        members = [i for i in nodes if batch[i] % 16 == g]
        expected = sorted(members, key=lambda i: code(position[i]))  # Python's sort is stable
        assert pools[g].tolist() == expected
