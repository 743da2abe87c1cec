"""Cache-free per-pixel reference luminance of a view, for the solver's accuracy benchmarks.

At each chosen pixel's own hit point: L = L_e + ρ/π·(E_dir + E_ind), E_dir by the closed form
with occlusion samples (:func:`~lsadphoto.solver.direct.direct_illuminance`), E_ind by the
double local estimate at that very point with ``nodes`` node draws from a simulation of its own
(:func:`~lsadphoto.solver.integrators.surface_cache.indirect_illuminance`): no cache, no
interpolation. The standard error combines both parts' sampling variances.
"""

import math

import numpy as np

from lsadphoto.solver import simulate
from lsadphoto.solver.direct import direct_illuminance
from lsadphoto.solver.engine import engine_for
from lsadphoto.solver.integrators.eye import emitted_luminance, primary_rays
from lsadphoto.solver.integrators.surface_cache import indirect_illuminance


def pixel_reference(scene, view, select, *, chains, nodes, direct_samples, luminaires="auto", seed=1000):
    """Flat pixel indices, L_ref [cd·m⁻²] and σ_ref of the pixels that
    ``select(valid, prim, dist, d)`` picks (positions into ``valid``, the view's valid pixels;
    ``prim`` the hit triangle or −1, ``dist`` [m] and ``d`` the rays)."""
    engine = engine_for(scene)
    valid, prim, dist, d = primary_rays(scene, engine, view.projection, view.position, view.rotation)
    sel = select(valid, prim, dist, d)
    t = prim[sel]
    x = view.position + dist[sel, None] * d[sel]
    n, _ = scene.facing_normals(t, d[sel])
    rho = scene.triangle_reflectance[t]
    store = simulate(scene, samples=chains, seed=seed)
    e_dir, v_dir = direct_illuminance(scene, engine, x, n, samples=direct_samples, seed=seed,
                                      luminaires=luminaires)
    lit = rho > 0
    e_ind = np.zeros((len(sel), 16))
    e_ind[lit] = indirect_illuminance(store, x[lit], n[lit], nodes=nodes, seed=seed, key=7)
    lum = emitted_luminance(scene, t, -d[sel]) + rho / math.pi * (e_dir + e_ind.mean(axis=1))
    sigma = rho / math.pi * np.sqrt(v_dir + e_ind.var(axis=1, ddof=1) / e_ind.shape[1])
    return valid[sel], lum, sigma
