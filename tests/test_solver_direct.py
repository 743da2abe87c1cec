"""Direct light from many luminaires: importance sampling of luminaires (issue 13, item 2).

References are closed forms (I·cos θ/r², Lambert's polygon formula) and the every-luminaire
estimate, which is exact per point for point luminaires (one shadow ray each: no sampling).
"""

import math

import numpy as np
import pytest

from lsadphoto.errors import BadInputError
from lsadphoto.solver import scene_from_dict
from lsadphoto.solver.direct import (ALL_LUMINAIRES_UP_TO, LuminaireTable, direct_illuminance,
                                     projected_solid_angle, sampled_direct_illuminance,
                                     unoccluded_illuminance)
from lsadphoto.solver.engine import engine_for

#: A hall floor 40 × 10 m with 40 isotropic points of 100…490 cd at 4 m, in two rows.
POSITIONS = [[1.0 + 2 * i, 3.0 + 4 * (i % 2), 4.0] for i in range(20)] + \
            [[2.0 + 2 * i, 7.0 - 4 * (i % 2), 4.0] for i in range(20)]
INTENSITIES = [100.0 + 10 * k for k in range(40)]


def hall(*, columns=False, extent=None):
    surfaces = [{"type": "polygon", "material": "grey",
                 "vertices": [[0, 0, 0], [40, 0, 0], [40, 10, 0], [0, 10, 0]]}]
    if columns:  # 1 m square columns that shadow parts of the floor
        surfaces += [{"type": "box", "material": "grey", "min": [4.0 * k + 2.5, 4.5, 0],
                      "max": [4.0 * k + 3.5, 5.5, 3.5]} for k in range(9)]
    luminaires = [{"type": "point", "position": p, "intensity": i,
                   **({"extent": extent} if extent else {})}
                  for p, i in zip(POSITIONS, INTENSITIES, strict=True)]
    return scene_from_dict({"materials": {"grey": {"reflectance": 0.5}}, "surfaces": surfaces,
                            "luminaires": luminaires})


def floor_points(n, seed=0):
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(0.5, 39.5, n), rng.uniform(0.5, 9.5, n), np.zeros(n)])
    return pts, np.tile([0.0, 0.0, 1.0], (n, 1))


def test_sampled_luminaires_are_exact_where_everything_is_visible():
    # With nothing in the way each drawn luminaire's estimate is its exact unoccluded value and
    # it is drawn with p ∝ that value, so every draw returns the whole sum: zero variance.
    scene = hall()
    pts, nrm = floor_points(200)
    r = np.asarray(POSITIONS)[None, :, :] - pts[:, None, :]
    d2 = (r ** 2).sum(axis=2)
    expected = (np.asarray(INTENSITIES) * r[..., 2] / np.sqrt(d2) / d2).sum(axis=1)
    assert len(POSITIONS) > ALL_LUMINAIRES_UP_TO  # "auto" samples here
    e, var = direct_illuminance(scene, engine_for(scene), pts, nrm)
    # 1e-9: an isotropic intensity table is exact, so only the rounding of 40 terms remains
    assert np.allclose(e, expected, rtol=1e-9)
    assert np.all(var < 1e-12 * expected ** 2)


def test_sampled_luminaires_are_unbiased_in_shadows_and_their_variance_honest():
    scene = hall(columns=True)
    engine = engine_for(scene)
    pts, nrm = floor_points(60, seed=1)
    exact, var_all = direct_illuminance(scene, engine, pts, nrm, luminaires="all")
    assert np.all(var_all == 0)  # point luminaires, one shadow ray each: no sampling
    runs = 300
    est = np.empty((runs, len(pts)))
    rep = np.empty((runs, len(pts)))
    for k in range(runs):
        est[k], rep[k] = direct_illuminance(scene, engine, pts, nrm, luminaires=4, seed=k)
    shadowed = est.std(axis=0) > 0
    assert shadowed.sum() >= 10  # the columns make the sampling matter at many points
    z = (est.mean(axis=0) - exact) / (est.std(axis=0, ddof=1) / math.sqrt(runs) + 1e-300)
    # unbiased: |z| < 4.5 for each of ≤ 60 points (a false alarm at 4.5σ has p ≈ 4e-4 over all)
    assert np.all(np.abs(z[shadowed]) < 4.5), z[shadowed]
    assert np.allclose(est[:, ~shadowed], exact[~shadowed], rtol=1e-9)
    # the reported variance is of the right size on average (stratified draws: conservative)
    ratio = rep[:, shadowed].mean(axis=0) / est[:, shadowed].var(axis=0, ddof=1)
    assert 0.7 < np.median(ratio) < 3.0, np.median(ratio)


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
    e, var = direct_illuminance(scene, engine_for(scene), pts, nrm, luminaires=3)
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
