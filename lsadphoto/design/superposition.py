"""Superposition: a design's maps and grids as the weighted sum of per-candidate solutions.

Light transport is linear in the luminaires' emission: with the space's geometry and
materials fixed, the luminance L(x, ω) and illuminance E(x) of a set of luminaires, each
scaled by a dimming weight w_c ≥ 0, are

    L = Σ_c w_c·L_c,    E = Σ_c w_c·E_c,

where L_c, E_c are the solutions with candidate c alone at full output. Each candidate is
simulated once (:func:`solve_candidate`); any design is then a weighted sum
(:func:`superpose`) — exact, no new Monte Carlo. The candidates' solutions come from
independent random streams, so the design's per-pixel variance is Σ_c w_c²·σ_c².

The design module needs only what this returns — maps, grids and their errors — never the
solver's internals.

References
----------
Budak, V. P. et al., seed paper (§5: "the inverse problem — designing for a given
quality"). Ashdown, I. (1994), *Radiosity: A Programmer's Perspective*, Wiley (the
radiosity solution is linear in the sources' exitance).
"""

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import BadInputError
from ..luminance_map import LuminanceMap
from ..solver import render, scene_from_dict, simulate
from ..solver.grids import CalculationGrid, GridIlluminance, grid_illuminance

__all__ = ["CandidateSolution", "solve_candidate", "superpose"]


@dataclass
class CandidateSolution:
    """One candidate luminaire's maps (per view name) and grids (per grid name) at full output."""

    name: str
    luminaire: dict
    maps: dict
    grids: dict
    flux: float
    provenance: dict = field(default_factory=dict)


def solve_candidate(space, luminaire, *, name=None, base=None, grids=(), samples=65536, seed=0,
                    render_options=None, grid_options=None):
    """Simulate the space lit by ``luminaire`` alone; render its views and grids.

    Parameters
    ----------
    space : dict
        The space as a scene document (the TOML scene schema of
        :func:`~lsadphoto.solver.scene_from_dict`) with its ``views`` and without the
        candidate's luminaire.
    luminaire : dict or None
        One ``[[luminaires]]`` entry (None: the space's own luminaires alone) (``type = "point"`` with ``photometry``, ``position``,
        ``nadir``…, or ``type = "area"``).
    base : path, optional
        Folder that relative paths (photometric files) are resolved against.
    grids : sequence of CalculationGrid
    samples, seed : int
        Light chains and the seed of this candidate's streams (give every candidate its own).
    render_options, grid_options : dict, optional
        Keywords of :func:`~lsadphoto.solver.render` and
        :func:`~lsadphoto.solver.grids.grid_illuminance`.

    Returns
    -------
    CandidateSolution
    """
    if not isinstance(space, dict) or not (luminaire is None or isinstance(luminaire, dict)):
        raise BadInputError("a candidate needs the space as a scene table and one luminaire table")
    doc = dict(space)
    doc["luminaires"] = list(space.get("luminaires", [])) + ([] if luminaire is None else [luminaire])
    scene = scene_from_dict(doc, base=base)
    if not scene.views:
        raise BadInputError("the design space has no views to evaluate")
    store = simulate(scene, samples=samples, seed=seed)
    options = dict(render_options or {})
    maps = {v.name: render(store, v.projection, position=v.position, rotation=v.rotation,
                           seed=seed, **options) for v in scene.views}
    results = {}
    for g in grids:
        if not isinstance(g, CalculationGrid):
            raise BadInputError("grids must be CalculationGrid objects (see work_plane_grid)")
        results[g.name] = grid_illuminance(store, g, seed=seed, **dict(grid_options or {}))
    return CandidateSolution(name=name or str((luminaire or {}).get("name", "space")), luminaire=luminaire,
                             maps=maps, grids=results, flux=float(scene.total_flux),
                             provenance={"chains": int(store.chains), "seed": int(seed)})


def superpose(solutions, weights):
    """The maps and grids of the design ``Σ w_c·solution_c``.

    Parameters
    ----------
    solutions : sequence of CandidateSolution
        Solved with independent random streams (distinct seeds).
    weights : array_like, shape (C,)
        Dimming weights w_c ≥ 0 (0 = off, 1 = full output).

    Returns
    -------
    (maps, grids) : tuple of dict
        ``maps[view]`` a :class:`~lsadphoto.LuminanceMap` [cd·m⁻²] with the combined
        per-pixel standard error √(Σ w_c²σ_c²); ``grids[name]`` a
        :class:`~lsadphoto.solver.grids.GridIlluminance` likewise.

    """
    solutions = list(solutions)
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    if len(w) != len(solutions) or not solutions:
        raise BadInputError(f"{len(w)} weights for {len(solutions)} candidate solutions")
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise BadInputError(f"dimming weights must be finite and ≥ 0, got {w.tolist()}")
    names = solutions[0].maps.keys()
    maps = {}
    for view in names:
        first = solutions[0].maps[view]
        lum = np.zeros(first.shape)
        var = np.zeros(first.shape)
        for wc, sol in zip(w, solutions):
            m = sol.maps.get(view)
            if m is None or m.shape != first.shape:
                raise BadInputError(f"candidate {sol.name!r} has no map of view {view!r} of the same size")
            lum += wc * m.luminance
            if m.uncertainty is not None:
                var += (wc * m.uncertainty.astype(np.float64)) ** 2
        maps[view] = LuminanceMap(lum.astype(np.float32), uncertainty=np.sqrt(var).astype(np.float32),
                                  projection=first.projection, line_of_sight=first.line_of_sight,
                                  calibrated=True,
                                  provenance={"design": "superposition", "weights": w.tolist(),
                                              "candidates": [s.name for s in solutions]})
    grids = {}
    for name in solutions[0].grids:
        parts = [s.grids[name] for s in solutions]
        E = sum(wc * p.illuminance for wc, p in zip(w, parts))
        se = np.sqrt(sum((wc * p.standard_error) ** 2 for wc, p in zip(w, parts)))
        direct = sum(wc * p.direct for wc, p in zip(w, parts))
        indirect = sum(wc * p.indirect for wc, p in zip(w, parts))
        avg = float(E.mean())
        avg_se = math.sqrt(sum((wc * p.average_standard_error) ** 2 for wc, p in zip(w, parts)))
        minimum = float(E.min())
        grids[name] = GridIlluminance(grid=parts[0].grid, illuminance=E, standard_error=se, direct=direct,
                                      indirect=indirect, average=avg, average_standard_error=avg_se,
                                      minimum=minimum, uniformity=minimum / avg if avg > 0 else math.nan,
                                      notes=list(parts[0].notes))
    return maps, grids
