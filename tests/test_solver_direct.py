"""Direct light from many luminaires: importance sampling of luminaires (issue 13, item 2).

References are closed forms (I·cos θ/r², Lambert's polygon formula) and the every-luminaire
estimate, which is exact per point for point luminaires (one shadow ray each: no sampling).
"""

import math
from dataclasses import replace

import numpy as np
import pytest

from lsadphoto.errors import BadInputError
from lsadphoto.solver import scene_from_dict
from lsadphoto.solver.direct import (
    ALL_LUMINAIRES_UP_TO,
    LUMINAIRE_CANDIDATES,
    LuminaireTable,
    direct_illuminance,
    projected_solid_angle,
    sampled_direct_illuminance,
    unoccluded_illuminance,
)
from lsadphoto.solver.engine import engine_for
from lsadphoto.solver.photometry import (
    Photometry,
    luminaire_frame,
    pack_photometries,
    packed_intensity,
)
from lsadphoto.solver.scene import PointLuminaire

#: A hall floor 40 × 10 m with 40 isotropic points of 100…490 cd at 4 m, in two rows.
POSITIONS = [[1.0 + 2 * i, 3.0 + 4 * (i % 2), 4.0] for i in range(20)] + \
            [[2.0 + 2 * i, 7.0 - 4 * (i % 2), 4.0] for i in range(20)]
INTENSITIES = [100.0 + 10 * k for k in range(40)]


def hall(*, columns=False, extent=None, count=40):
    surfaces = [{"type": "polygon", "material": "grey",
                 "vertices": [[0, 0, 0], [40, 0, 0], [40, 10, 0], [0, 10, 0]]}]
    if columns:  # 1 m square columns that shadow parts of the floor
        surfaces += [{"type": "box", "material": "grey", "min": [4.0 * k + 2.5, 4.5, 0],
                      "max": [4.0 * k + 3.5, 5.5, 3.5]} for k in range(9)]
    luminaires = [{"type": "point", "position": p, "intensity": i,
                   **({"extent": extent} if extent else {})}
                  for p, i in zip(POSITIONS[:count], INTENSITIES[:count], strict=True)]
    return scene_from_dict({"materials": {"grey": {"reflectance": 0.5}}, "surfaces": surfaces,
                            "luminaires": luminaires})


def floor_points(n, seed=0):
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(0.5, 39.5, n), rng.uniform(0.5, 9.5, n), np.zeros(n)])
    return pts, np.tile([0.0, 0.0, 1.0], (n, 1))


def test_sampled_luminaires_are_exact_where_everything_is_visible():
    # With nothing in the way and every luminaire a candidate of the planning pass (at most
    # LUMINAIRE_CANDIDATES), each drawn luminaire's estimate is its exact unoccluded value and
    # it is drawn with p ∝ that value, so every draw returns the whole sum: zero variance.
    count = LUMINAIRE_CANDIDATES
    scene = hall(count=count)
    pts, nrm = floor_points(200)
    r = np.asarray(POSITIONS[:count])[None, :, :] - pts[:, None, :]
    d2 = (r ** 2).sum(axis=2)
    expected = (np.asarray(INTENSITIES[:count]) * r[..., 2] / np.sqrt(d2) / d2).sum(axis=1)
    assert count > ALL_LUMINAIRES_UP_TO  # "auto" samples here
    e, var = direct_illuminance(scene, engine_for(scene), pts, nrm)
    # 1e-9: an isotropic intensity table is exact, so only the rounding of the terms remains
    assert np.allclose(e, expected, rtol=1e-9)
    assert np.all(var < 1e-12 * expected ** 2)


def test_many_luminaires_unoccluded_are_unbiased_with_a_small_spread():
    # Above LUMINAIRE_CANDIDATES luminaires the others are drawn by their region's weights, not
    # their exact values: no longer exact, but unbiased. 40 luminaires, 200 floor points, 200
    # seeds: |z| < 4.5 at every point (p ≈ 1e-3 of a false alarm over all), and the spread
    # per estimate below 10 % (0.7 % median, 1.6 % at most here; the region weights are the values at the
    # cell's centre).
    scene = hall()
    assert len(POSITIONS) > LUMINAIRE_CANDIDATES
    pts, nrm = floor_points(200)
    r = np.asarray(POSITIONS)[None, :, :] - pts[:, None, :]
    d2 = (r ** 2).sum(axis=2)
    expected = (np.asarray(INTENSITIES) * r[..., 2] / np.sqrt(d2) / d2).sum(axis=1)
    engine = engine_for(scene)
    runs = np.array([direct_illuminance(scene, engine, pts, nrm, seed=k)[0] for k in range(200)])
    z = (runs.mean(axis=0) - expected) / (runs.std(axis=0, ddof=1) / math.sqrt(len(runs)) + 1e-300)
    assert np.all(np.abs(z) < 4.5), z
    assert np.all(runs.std(axis=0) < 0.1 * expected)


@pytest.mark.parametrize("draws", [4, 5, 32])
def test_sampled_luminaires_are_unbiased_in_shadows_and_their_variance_honest(draws):
    scene = hall(columns=True)
    engine = engine_for(scene)
    pts, nrm = floor_points(60, seed=1)
    exact, var_all = direct_illuminance(scene, engine, pts, nrm, luminaires="all")
    assert np.all(var_all == 0)  # point luminaires, one shadow ray each: no sampling
    runs = 300
    est = np.empty((runs, len(pts)))
    rep = np.empty((runs, len(pts)))
    for k in range(runs):
        est[k], rep[k] = direct_illuminance(scene, engine, pts, nrm, luminaires=draws, seed=k)
    shadowed = est.std(axis=0) > 0
    assert shadowed.sum() >= 10  # the columns make the sampling matter at many points
    z = (est.mean(axis=0) - exact) / (est.std(axis=0, ddof=1) / math.sqrt(runs) + 1e-300)
    # unbiased: |z| < 4.5 for each of ≤ 60 points (a false alarm at 4.5σ has p ≈ 4e-4 over all)
    assert np.all(np.abs(z[shadowed]) < 4.5), z[shadowed]
    assert np.allclose(est[:, ~shadowed], exact[~shadowed], rtol=1e-9)
    # The reported variance of the stratified draws (collapsed strata: pairs of adjacent
    # strata, the last three together for an odd count) is conservative, by the spread of the
    # strata means within a pair: its mean over the runs against the observed variance has
    # a median over the points of 1.15 (4 draws), 1.27 (5), 1.63 (32) here. Bounds: ≥ 0.9
    # (each point's ratio has a relative noise ≈ √(2/299) ≈ 8 %, its median over ≥ 10 points
    # far less) and ≤ 2 — the plain sample variance of the draws, which ignores the
    # stratification, gave 2.9 at 32 draws.
    ratio = rep[:, shadowed].mean(axis=0) / est[:, shadowed].var(axis=0, ddof=1)
    assert 0.9 < np.median(ratio) < 2.0, np.median(ratio)


def test_area_luminaires_sampled_are_exact_unoccluded():
    # 12 ceiling panels (1 m², 1000 lm each): Lambert's closed form, summed.
    panels = [[[x, y, 3], [x, y + 1, 3], [x + 1, y + 1, 3], [x + 1, y, 3]]
              for x in (1.0, 4.0, 7.0, 10.0) for y in (1.0, 4.0, 7.0)]
    scene = scene_from_dict({
        "materials": {"grey": {"reflectance": 0.5}, "black": {"reflectance": 0.0}},
        "surfaces": [{"type": "polygon", "material": "grey",
                      "vertices": [[0, 0, 0], [12, 0, 0], [12, 9, 0], [0, 9, 0]]}],
        "luminaires": [{"type": "area", "flux": 1000.0, "material": "black",
                        "shape": {"type": "polygon", "vertices": v}} for v in panels]})
    pts = np.array([[0.5, 0.5, 0.0], [6.0, 4.5, 0.0], [11.0, 8.0, 0.0]])
    nrm = np.tile([0.0, 0.0, 1.0], (3, 1))
    expected = sum(1000.0 / math.pi * projected_solid_angle(pts, nrm, scene.triangles[lum.triangles]).sum(axis=1)
                   for lum in scene.area_luminaires)
    e, _ = direct_illuminance(scene, engine_for(scene), pts, nrm, luminaires=3)
    assert np.allclose(e, expected, rtol=1e-9)  # rounding only (see the first test)
    u, exact = unoccluded_illuminance(scene, pts, nrm)
    assert exact.all() and np.allclose(u.sum(axis=1), expected, rtol=1e-12)


def test_sampled_luminaires_do_not_depend_on_chunking():
    # Each block of points draws from its own stream: the points in one call or block by block
    # give the same values, bit for bit (renders promise results independent of chunk size).
    # Block 0 lies between the rows (no luminaire dominates), block 1 right under luminaires
    # (one is taken whole besides the draws), so the blocks evaluate different numbers of
    # luminaires per point; luminous rectangles make each estimate use its uniforms.
    scene = hall(columns=True, extent=[0.6, 0.6])
    engine = engine_for(scene)
    between, nrm = floor_points(32, seed=2)
    between[:, 1] = 5.0
    under = np.asarray(POSITIONS[:32]) * [1.0, 1.0, 0.0]
    pts, nrm = np.vstack([between, under]), np.vstack([nrm, nrm])
    blocks = np.arange(64) // 32
    whole = direct_illuminance(scene, engine, pts, nrm, luminaires=4, seed=5, block_ids=blocks)
    for j in range(2):
        m = blocks == j
        part = direct_illuminance(scene, engine, pts[m], nrm[m], luminaires=4, seed=5,
                                  block_ids=blocks[m])
        np.testing.assert_array_equal(part[0], whole[0][m])
        np.testing.assert_array_equal(part[1], whole[1][m])


def test_luminaire_draws_are_checked():
    scene = hall()
    pts, nrm = floor_points(2)
    with pytest.raises(BadInputError, match="luminaire draws"):
        direct_illuminance(scene, engine_for(scene), pts, nrm, luminaires=0)


def test_one_luminaire_drawn_from_a_region_table_is_unbiased():
    # The surface cache's near field draws one luminaire per hit from a per-region table
    # (LuminaireTable): unbiased against the every-luminaire estimate (exact per point for
    # point luminaires), in the columns' shadows and on a column's side (the luminaires
    # behind its tangent plane have only the floor probability), with a table of cells far
    # coarser than the luminaire spacing. 1000 draws per point: |z| < 4.5 at each of ≤ 40
    # points (a false alarm has p ≈ 3e-4 over all).
    scene = hall(columns=True)
    engine = engine_for(scene)
    pts, nrm = floor_points(30, seed=2)
    side = np.column_stack([4.0 * np.arange(10) % 36 + 2.5, np.full(10, 5.0),
                            np.linspace(0.5, 3.0, 10)])
    pts = np.vstack([pts, side - [1e-3, 0, 0]])
    nrm = np.vstack([nrm, np.tile([-1.0, 0, 0], (10, 1))])
    exact, _ = direct_illuminance(scene, engine, pts, nrm, luminaires="all")
    table = LuminaireTable(scene, 6.0)
    runs = 1000
    x = np.repeat(pts, runs, axis=0)
    n = np.repeat(nrm, runs, axis=0)
    e = sampled_direct_illuminance(scene, engine, x, n, table=table, seed=5,
                                   block_ids=np.tile(np.arange(runs), len(pts))).reshape(len(pts), runs)
    assert np.all(e >= 0)
    lit = exact > 0
    z = (e.mean(axis=1) - exact)[lit] / (e.std(axis=1, ddof=1)[lit] / math.sqrt(runs))
    assert np.all(np.abs(z) < 4.5), z
    assert np.all(e[~lit] == 0)
    # each region's row is built once, for all luminaires: far fewer rows than points
    assert 0 < len(table.rows) < len(pts)


def _asymmetric():
    """A distribution without rotational symmetry, on an irregular γ grid stopping at 150°."""
    c = np.linspace(0.0, 360.0, 25)
    g = np.concatenate([np.linspace(0.0, 60.0, 13), np.linspace(70.0, 150.0, 9)])
    cc, gg = np.meshgrid(np.radians(c), np.radians(g), indexing="ij")
    cd = 100.0 * (1.2 + np.cos(cc) + 0.3 * np.sin(2 * cc)) * np.cos(gg / 2) ** 2
    return Photometry(c, g, cd, format="function")


def test_packed_intensity_equals_the_photometry_evaluation():
    # The compiled look-up against Photometry.evaluate (numpy, the reference): the same
    # bilinear interpolation in degrees, so equal to rounding (1e-12 of the peak), on random
    # directions, on the grid's own directions (snapping) and beyond its γ range (0).
    photometries = [_asymmetric(), Photometry.isotropic(7.0),
                    Photometry.from_function(lambda c, g: 1 + np.cos(g) ** 2, c_step_deg=90)]
    index, tables = pack_photometries(photometries + photometries[:1])
    assert index.tolist() == [0, 1, 2, 0]  # the same object shares its table
    rng = np.random.default_rng(3)
    d = rng.normal(size=(4000, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    p = photometries[0]
    cc, gg = np.meshgrid(np.radians(p.c_angles[:-1]), np.radians(p.gamma_angles), indexing="ij")
    on_grid = np.stack([np.sin(gg) * np.cos(cc), np.sin(gg) * np.sin(cc), -np.cos(gg)], axis=-1)
    for k, phot in enumerate(photometries):
        frame = luminaire_frame(rng.normal(size=3), rng.normal(size=3))
        dirs = np.vstack([d, on_grid.reshape(-1, 3) @ frame]) if k == 0 else d
        got = np.array([packed_intensity(tables, index[k], *v, frame) for v in dirs])
        ref = phot.evaluate(dirs, frame)
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * phot.candela.max())
        if k == 0:
            assert np.any(ref == 0)  # directions above 150° are dark, and found so


def test_unoccluded_illuminance_of_aimed_asymmetric_luminaires():
    # I(ω)·cos θ/r² by Photometry.evaluate for luminaires aimed askew (one with a luminous
    # rectangle: its centre's value, flagged as a guide), on a floor and a wall; and the
    # estimate with luminaires="all" equals it where nothing is in the way (1e-9: rounding;
    # a rectangle's 4 samples differ from the centre by < 3 % here).
    scene = hall(count=2)
    phot = _asymmetric()
    frames = [luminaire_frame([0.3, 0.2, -1.0], [1.0, 1.0, 0.0]), luminaire_frame([-0.5, 0.1, -1.0], [0.0, 1.0, 0.3])]
    scene.point_luminaires = [PointLuminaire(f"l{k}", np.array([10.0 + 7 * k, 5.0, 3.0]), phot, f,
                                             extent=(0.3, 0.2) if k else (0.0, 0.0), multiplier=1.5)
                              for k, f in enumerate(frames)]
    pts, nrm = floor_points(300, seed=4)
    pts[:100, 1] = 10.0  # on the wall y = 10 (facing −y)
    pts[:100, 2] = np.linspace(0.1, 3.9, 100)
    nrm[:100] = [0.0, -1.0, 0.0]
    u, exact = unoccluded_illuminance(scene, pts, nrm)
    assert exact.tolist() == [True, False]
    for k, lum in enumerate(scene.point_luminaires):
        r = lum.position - pts
        d2 = (r ** 2).sum(axis=1)
        cos = np.maximum((r * nrm).sum(axis=1) / np.sqrt(d2), 0.0)
        ref = 1.5 * phot.evaluate(-r / np.sqrt(d2)[:, None], lum.frame) * cos / d2
        np.testing.assert_allclose(u[:, k], ref, rtol=1e-12, atol=1e-14 * ref.max())
    engine = engine_for(scene)
    # the rectangle's estimate (4 random points of it per call) against a 40 × 40 midpoint
    # quadrature over it by Photometry.evaluate: unbiased, |z| < 4.5 at each of 300 points
    # over 100 seeds (p ≈ 2e-3 of a false alarm over all)
    rect = scene.point_luminaires[1]
    a = (np.arange(40) + 0.5) / 40 - 0.5
    y = (rect.position + (a[:, None, None] * 0.3 * rect.frame[0] + a[None, :, None] * 0.2 * rect.frame[1])).reshape(-1, 3)
    r = y[None, :, :] - pts[:, None, :]
    d2 = (r ** 2).sum(axis=2)
    cos = np.maximum((r * nrm[:, None, :]).sum(axis=2) / np.sqrt(d2), 0.0)
    ref = (1.5 * phot.evaluate(-r / np.sqrt(d2)[..., None], rect.frame) * cos / d2).mean(axis=1)
    runs = np.array([direct_illuminance(scene, engine, pts, nrm, luminaires="all", seed=k)[0]
                     for k in range(100)]) - u[:, 0]
    sd = runs.std(axis=0, ddof=1) / 10
    lit = sd > 0
    assert lit.sum() > 100 and np.all(np.abs(runs.mean(axis=0) - ref)[lit] < 4.5 * sd[lit])
    assert np.allclose(runs[:, ~lit], ref[~lit], rtol=1e-9, atol=1e-12)
    # points only: the estimate is the exact sum where nothing is in the way
    scene.point_luminaires[1] = replace(rect, extent=(0.0, 0.0))
    scene._packed_lights = None
    e, _ = direct_illuminance(scene, engine, pts, nrm, luminaires="all")
    assert np.allclose(e, unoccluded_illuminance(scene, pts, nrm)[0].sum(axis=1), rtol=1e-9)


def test_region_table_weights_are_positive_and_candidates_the_largest_bounds():
    # Unbiased sampling needs p > 0 for every luminaire that may give light (all of them here);
    # the candidates are each region's largest bounds, the others carry weights only.
    scene = hall(columns=True)
    table = LuminaireTable(scene, 2.0)
    pts, nrm = floor_points(500, seed=6)
    _, cand, n_cand, rest_w, rest_cum = table.plan_rows(pts, nrm)
    assert cand.shape == (len(table.rows), LUMINAIRE_CANDIDATES) and np.all(n_cand == LUMINAIRE_CANDIDATES)
    bound = np.diff(table._cdf, axis=1, prepend=0.0)
    for r in range(len(cand)):
        others = np.setdiff1d(np.arange(40), cand[r])
        assert np.all(rest_w[r, cand[r]] == 0) and np.all(rest_w[r, others] > 0)
        assert bound[r, cand[r]].min() >= bound[r, others].max()
    np.testing.assert_allclose(rest_cum[:, -1], rest_w.sum(axis=1), rtol=1e-12)
    assert np.all(bound > 0)


def test_region_tables_shared_by_threads_give_the_serial_result():
    # Renderers call direct_illuminance from several threads on one scene, whose region table
    # grows as new regions are met: the threads' results equal a serial run's, bit for bit
    # (a race once handed out rows without content).
    from concurrent.futures import ThreadPoolExecutor

    pts, nrm = floor_points(4096, seed=7)
    blocks = np.arange(len(pts)) // 256
    parts = np.array_split(np.arange(len(pts)), 16)

    def run(scene, idx):
        return direct_illuminance(scene, engine_for(scene), pts[idx], nrm[idx], block_ids=blocks[idx])[0]

    serial = hall(columns=True)
    expected = np.concatenate([run(serial, idx) for idx in parts])
    shared = hall(columns=True)
    with ThreadPoolExecutor(4) as pool:
        got = np.concatenate(list(pool.map(lambda idx: run(shared, idx), parts)))
    np.testing.assert_array_equal(got, expected)


def _gauss_square(centre, half, count=400):
    """Gauss–Legendre nodes (x, y) and weights [m²] over a square of half-width ``half``."""
    g, w = np.polynomial.legendre.leggauss(count)
    return centre[0] + half * g, centre[1] + half * g, np.outer(w, w) * half * half


def test_fresnel_weighted_illuminance_matches_quadrature():
    # E_F = ∫(1 − F(μ))·L·μ dω at points of a smooth floor (fresnel=True): the irradiance that
    # Radiance's smooth plastic scatters diffusely. References, each independent of the
    # estimators: a 400² Gauss–Legendre quadrature of L·(1 − F(μ))·μ·cos θ_y/r² over a 3 × 3 m
    # panel 0.5 m above the floor (smooth integrand: 200² gives the same to 1e-12), a 1-D
    # quadrature for a uniform sky hemisphere, and I·μ/r²·(1 − F(μ)) for a point.
    from scipy.integrate import quad

    from lsadphoto.solver import read_radiance_scene
    from lsadphoto.solver.materials import fresnel_estimate

    floor = "void plastic smooth 0 0 5 .3 .3 .3 .05 0\nsmooth polygon f 0 0 12 -3 -3 0  3 -3 0  3 3 0  -3 3 0\n"
    scene = read_radiance_scene("void light lamp 0 0 3 10 10 10\n"
                                "lamp polygon panel 0 0 12 -1 -1 .5  -1 2 .5  2 2 .5  2 -1 .5\n" + floor)
    engine = engine_for(scene)
    # under the panel, under its corner and 1.5 m beside it (rays at 60–90° from the normal)
    pts = np.array([[0.0, 0.0, 0.0], [1.5, 1.5, 0.0], [-2.0, 0.5, 0.0]])
    nrm = np.tile([0.0, 0.0, 1.0], (3, 1))
    xs, ys, w = _gauss_square((0.5, 0.5), 1.5)

    def reference(p, weighted):
        r2 = (xs[:, None] - p[0]) ** 2 + (ys[None, :] - p[1]) ** 2 + 0.25
        mu = 0.5 / np.sqrt(r2)
        return 1790.0 * (w * mu * mu / r2 * ((1 - fresnel_estimate(mu)) if weighted else 1.0)).sum()

    ref = np.array([reference(p, True) for p in pts])
    plain = np.array([reference(p, False) for p in pts])
    runs = [direct_illuminance(scene, engine, pts, nrm, seed=k, fresnel=np.ones(3, bool)) for k in range(400)]
    est, var = np.array([r[0] for r in runs]), np.array([r[1] for r in runs])
    se = est.std(axis=0, ddof=1) / math.sqrt(len(est))
    # unbiased at the default 4 samples: within 4 standard errors of 400 estimates (0.03–0.5 %),
    # where the plain E lies 2.3–23 % away
    assert np.all(np.abs(est.mean(axis=0) - ref) < 4 * se), (est.mean(axis=0), ref, se)
    assert np.all(np.abs(plain - ref) > 20 * se)
    # the delta-method variance is conservative by the stratification it ignores (measured
    # 1.5–3.1 × the observed variance here), never below it by more than its own scatter
    ratio = var.mean(axis=0) / est.var(axis=0, ddof=1)
    assert np.all((ratio > 0.7) & (ratio < 4.0)), ratio
    # without the flag, the closed form as before
    assert np.allclose(direct_illuminance(scene, engine, pts, nrm, fresnel=np.zeros(3, bool))[0], plain, rtol=1e-9)
    # one luminaire drawn per point from a table, one sample each: unbiased, within 4 SE
    table = LuminaireTable(scene, 0.5)
    one = np.array([sampled_direct_illuminance(scene, engine, pts, nrm, table=table, seed=k, fresnel=np.ones(3, bool))
                    for k in range(2000)])
    assert np.all(np.abs(one.mean(axis=0) - ref) < 4 * one.std(axis=0, ddof=1) / math.sqrt(len(one)))
    # a uniform sky hemisphere of 179 cd/m² (1 W·sr⁻¹·m⁻²): E_F = 2π·179·∫(1 − F(μ))μ dμ
    sky = read_radiance_scene("void glow sky_glow 0 0 4 1 1 1 0\nsky_glow source sky 0 0 4 0 0 1 180\n" + floor)
    expected = 2 * math.pi * 179 * quad(lambda mu: (1 - float(fresnel_estimate(mu))) * mu, 0, 1)[0]
    e, v = direct_illuminance(sky, engine_for(sky), np.zeros((64, 3)), np.tile([0.0, 0.0, 1.0], (64, 1)),
                              samples=64, block_ids=np.arange(64), fresnel=np.ones(64, bool))
    assert abs(e.mean() - expected) < 4 * e.std(ddof=1) / 8, (e.mean(), expected)
    assert abs(e.mean() - math.pi * 179) > 20 * e.std(ddof=1) / 8
    # a point luminaire: one exact term per point, I·μ/r²·(1 − F(μ))
    point = hall(count=1)
    x = np.array([[1.0, 3.0, 0.0], [5.0, 3.0, 0.0], [1.0, 9.0, 0.0]])
    d = np.asarray(POSITIONS[0]) - x
    r = np.linalg.norm(d, axis=1)
    mu = d[:, 2] / r
    e, _ = direct_illuminance(point, engine_for(point), x, np.tile([0.0, 0.0, 1.0], (3, 1)), fresnel=np.ones(3, bool))
    assert np.allclose(e, INTENSITIES[0] * mu / r ** 2 * (1 - fresnel_estimate(mu)), rtol=1e-9)
