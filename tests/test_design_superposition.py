"""Superposition of per-candidate solutions against a direct simulation of the combined scene."""

import tomllib

import numpy as np
import pytest

from lsadphoto.design import solve_candidate, superpose
from lsadphoto.errors import BadInputError
from lsadphoto.solver import render, scene_from_dict, simulate
from lsadphoto.solver.examples import canonical_room_toml
from lsadphoto.solver.grids import grid_illuminance, work_plane_grid

LUMINAIRES = [
    {"type": "point", "name": "a", "position": [1.5, 1.0, 2.9], "intensity": 400.0},
    {"type": "point", "name": "b", "position": [4.5, 3.0, 2.9], "intensity": 900.0},
]


def _space(size=20):
    doc = tomllib.loads(canonical_room_toml(size=size))
    doc.pop("luminaires")
    return doc


@pytest.mark.slow
def test_weighted_sum_equals_the_combined_scene():
    space = _space()
    grid = work_plane_grid((0, 0), (6, 4), height=0.8, spacing=2.0, border=0.5)
    sols = [solve_candidate(space, lum, grids=[grid], samples=16384, seed=11 + k,
                            grid_options={"nodes": 1024})
            for k, lum in enumerate(LUMINAIRES)]
    maps, grids = superpose(sols, [1.0, 0.5])
    # The reference: one simulation of the space with both luminaires, b dimmed to half
    # through its multiplier — independent streams (another seed).
    both = dict(space, luminaires=[LUMINAIRES[0], dict(LUMINAIRES[1], multiplier=0.5)])
    scene = scene_from_dict(both)
    store = simulate(scene, samples=16384, seed=99)
    view = scene.views[0]
    ref = render(store, view.projection, position=view.position, rotation=view.rotation, seed=99)
    got = maps[view.name]
    sigma = np.hypot(got.uncertainty, ref.uncertainty)
    ok = np.isfinite(ref.luminance) & (sigma > 0)
    exact = np.isfinite(ref.luminance) & (sigma == 0)  # no noise on either side: must agree
    np.testing.assert_allclose(got.luminance[exact], ref.luminance[exact], rtol=1e-5)
    z = (got.luminance[ok] - ref.luminance[ok]) / sigma[ok]
    # Both are unbiased estimates with honest standard errors: |z| ≤ 3 for ≥ 97 % of pixels
    # (99.7 % for Gaussian errors; the local estimate's tails are heavier) and no mean shift
    # beyond 3 standard errors of the mean z.
    assert np.mean(np.abs(z) <= 3) >= 0.97
    assert abs(z.mean()) <= 3 * z.std() / np.sqrt(z.size) + 0.05
    ref_grid = grid_illuminance(store, grid, seed=99, nodes=1024)
    g = grids[grid.name]
    zg = (g.illuminance - ref_grid.illuminance) / np.hypot(g.standard_error, ref_grid.standard_error)
    assert np.all(np.abs(zg) <= 3.5)
    assert abs(g.average - ref_grid.average) <= 3 * np.hypot(g.average_standard_error,
                                                             ref_grid.average_standard_error)


def test_superpose_is_linear_and_checks_its_weights():
    space = _space(size=8)
    sols = [solve_candidate(space, lum, samples=256, seed=k) for k, lum in enumerate(LUMINAIRES)]
    maps, _ = superpose(sols, [2.0, 0.0])
    view = next(iter(maps))
    # Doubling one candidate and switching the other off: exactly twice its map (float32).
    np.testing.assert_allclose(maps[view].luminance, 2.0 * sols[0].maps[view].luminance, rtol=1e-6)
    np.testing.assert_allclose(maps[view].uncertainty, 2.0 * sols[0].maps[view].uncertainty, rtol=1e-6)
    with pytest.raises(BadInputError, match="2 weights for 1"):
        superpose(sols[:1], [1.0, 1.0])
    with pytest.raises(BadInputError, match="≥ 0"):
        superpose(sols, [1.0, -0.5])
