"""Light chains from the sources (the forward Markov chain of the double local estimate).

Each chain starts on a luminaire chosen in proportion to its flux, at a point sampled in
proportion to exitance (uniform on a Lambertian emitter, uniform on a photometric
luminaire's luminous rectangle), with weight W₀ = Φ_total (per chain, before division by
the number of chains). Its direction follows the emission distribution (cosine lobe, or the
tabulated I(C, γ) with weight I/(Φ·p)); at every surface hit the chain survives with
probability ρ (Russian roulette, weight unchanged) and leaves in a cosine-distributed
direction (or, by default, carries the weight W·ρ, see ``absorption`` in
:func:`trace_chains`). Every node — the source point included — is recorded with the coefficient that
the double local estimate multiplies by the geometry term (:mod:`lsadphoto.solver.store`).

References
----------
Marchuk, G. I., Mikhailov, G. A., Nazaraliev, M. A., Darbinjan, R. A., Kargin, B. A.,
Elepov, B. S. (1980). *The Monte Carlo Methods in Atmospheric Optics*. Springer, ch. 2–3
(analog and weighted chains, local estimates). Budak, Zheltov & Kalakutsky (2012),
*Computer Research and Modeling* 4(1), 75–84. FORMULAS.md §6.1.
"""

import math

import numpy as np

from ._sampling import cosine_directions, stream, triangle_points
from .store import KIND_COSINE, KIND_POINT, LsadStore

ABSORPTION_MODES = ("weight", "roulette")

__all__ = [
    "ABSORPTION_MODES",
    "CHAIN_BLOCK",
    "MAX_BOUNCES",
    "WEIGHT_FLOOR",
    "EmissionSampler",
    "trace_chains",
]

#: Light chains per random-stream block. Simulations run in whole blocks, so a simulation
#: of N chains is the same whether made at once or in rounds, whatever the chunking.
CHAIN_BLOCK = 256

#: Weight floor (fraction of W₀) below which weighted chains play Russian roulette.
WEIGHT_FLOOR = 0.05

#: Safety cap on bounces when ``max_depth`` is None (Russian roulette ends chains long
#: before: with ρ = 0.95 the chance of 2000 bounces is 0.95²⁰⁰⁰ ≈ 1e-45).
MAX_BOUNCES = 2000


class EmissionSampler:
    """Samples emission points on the luminaires of a scene, in proportion to their flux."""

    def __init__(self, scene):
        self.scene = scene
        self.total_flux = scene.total_flux
        fluxes = [l.flux for l in scene.area_luminaires] + [l.flux for l in scene.point_luminaires]
        self.n_area = len(scene.area_luminaires)
        self._lum_cdf = np.cumsum(fluxes) / np.sum(fluxes)
        self._lum_cdf[-1] = 1.0
        self._tri_cdf = []
        for lum in scene.area_luminaires:
            a = np.cumsum(scene.areas[lum.triangles])
            self._tri_cdf.append(a / a[-1])

    def sample(self, rng, n):
        """``n`` emission points: dict of position, normal, luminaire, kind, coefficient.

        ``luminaire`` indexes area luminaires (kind 0) or point luminaires (kind 1).
        ``coefficient`` is Φ_total/π for Lambertian emitters and Φ_total/Φ_luminaire for
        point luminaires (see :class:`~lsadphoto.solver.store.LsadStore`).
        """
        scene = self.scene
        u_lum = rng.random(n)
        u_tri = rng.random(n)
        u_pt = rng.random((n, 2))
        which = np.minimum(np.searchsorted(self._lum_cdf, u_lum, side="right"), len(self._lum_cdf) - 1)
        position = np.zeros((n, 3))
        normal = np.zeros((n, 3))
        kind = np.where(which < self.n_area, KIND_COSINE, KIND_POINT).astype(np.int8)
        lum_index = np.where(which < self.n_area, which, which - self.n_area)
        coefficient = np.zeros(n)
        triangle = np.full(n, -1, dtype=np.int64)
        for k, lum in enumerate(scene.area_luminaires):
            m = which == k
            if not m.any():
                continue
            t = lum.triangles[np.minimum(np.searchsorted(self._tri_cdf[k], u_tri[m], side="right"),
                                         len(lum.triangles) - 1)]
            triangle[m] = t
            position[m] = triangle_points(scene.triangles[t], u_pt[m])
            normal[m] = scene.normals[t]
            coefficient[m] = self.total_flux / math.pi
        for k, lum in enumerate(scene.point_luminaires):
            m = which == self.n_area + k
            if not m.any():
                continue
            offs = (u_pt[m] - 0.5) * np.asarray(lum.extent)
            position[m] = lum.position + offs[:, :1] * lum.frame[0] + offs[:, 1:] * lum.frame[1]
            normal[m] = lum.frame[2]
            coefficient[m] = self.total_flux / lum.flux
        return {"position": position, "normal": normal, "kind": kind, "luminaire": lum_index,
                "coefficient": coefficient, "triangle": triangle}


def _block_chains(scene, engine, sampler, seed, block, n, batches, max_depth, absorption):
    """Nodes of the ``n`` chains of one block (global chain index block·CHAIN_BLOCK + i)."""
    rng = stream(seed, "chains", block)
    src = sampler.sample(rng, n)
    chain_id = block * CHAIN_BLOCK + np.arange(n)
    batch = (chain_id % batches).astype(np.int16)
    out = {
        "position": [src["position"]], "normal": [src["normal"]],
        "coefficient": [src["coefficient"]], "kind": [src["kind"]],
        "luminaire": [np.where(src["kind"] == KIND_POINT, src["luminaire"], -1).astype(np.int32)],
        "batch": [batch], "depth": [np.zeros(n, np.int16)], "triangle": [src["triangle"]],
    }
    # first directions
    u_dir = rng.random((n, 2))
    direction = cosine_directions(src["normal"], u_dir)
    weight = np.full(n, sampler.total_flux)
    for k, lum in enumerate(scene.point_luminaires):
        m = (src["kind"] == KIND_POINT) & (src["luminaire"] == k)
        count = int(m.sum())
        if count:
            d, w = lum.table.sample(rng, count, lum.frame)
            direction[m] = d
            weight[m] *= w
    origin = src["position"] + engine.epsilon * np.where(
        (src["kind"] == KIND_COSINE)[:, None], src["normal"], 0.0)
    alive = np.arange(n)
    depth = 0
    limit = MAX_BOUNCES if max_depth is None else int(max_depth)
    rho_tri = scene.triangle_reflectance
    while alive.size and depth < limit:
        depth += 1
        prim, dist = engine.closest_hit(origin, direction)
        hit = prim >= 0
        u = rng.random((alive.size, 3))  # roulette + next direction, drawn for every live chain
        alive, origin, direction, weight, prim, dist, u = (
            alive[hit], origin[hit], direction[hit], weight[hit], prim[hit], dist[hit], u[hit])
        if not alive.size:
            break
        point = origin + dist[:, None] * direction
        nrm, _ = scene.facing_normals(prim, direction)
        rho = rho_tri[prim]
        keep = rho > 0
        out["position"].append(point[keep])
        out["normal"].append(nrm[keep])
        out["coefficient"].append(weight[keep] * rho[keep] / math.pi)
        out["kind"].append(np.zeros(int(keep.sum()), np.int8))
        out["luminaire"].append(np.full(int(keep.sum()), -1, np.int32))
        out["batch"].append(batch[alive[keep]])
        out["depth"].append(np.full(int(keep.sum()), depth, np.int16))
        out["triangle"].append(prim[keep])
        if absorption == "roulette":
            survive = u[:, 0] < rho               # analog: weight unchanged
        else:
            weight = weight * rho                 # weighted: absorption in the weight …
            low = weight < WEIGHT_FLOOR * sampler.total_flux
            q = np.where(low, weight / (WEIGHT_FLOOR * sampler.total_flux), 1.0)
            survive = (rho > 0) & (u[:, 0] < q)   # … and roulette below the floor
            weight = np.where(low, WEIGHT_FLOOR * sampler.total_flux, weight)
        alive, point, nrm, weight = alive[survive], point[survive], nrm[survive], weight[survive]
        direction = cosine_directions(nrm, u[survive, 1:])
        origin = point + engine.epsilon * nrm
    return {k: np.concatenate(v) for k, v in out.items()}


def trace_chains(scene, engine, *, seed, first_block, blocks, batches, max_depth=None,
                 absorption="weight", sampler=None, progress=None):
    """An :class:`LsadStore` with the chains of blocks ``first_block … first_block+blocks−1``.

    Parameters
    ----------
    scene : Scene
    engine : RayEngine
    seed : int
        Root of every random stream.
    first_block, blocks : int
        Range of chain blocks (:data:`CHAIN_BLOCK` chains each) to trace.
    batches : int
        Number of independent batches (chain ``i`` belongs to batch ``i mod batches``).
    max_depth : int, optional
        Largest number of bounces (truncation is biased: default None, unlimited).
    absorption : {"weight", "roulette"}
        "roulette": analog chains, survival with probability ρ, weight unchanged.
        "weight": the weight is multiplied by ρ at every reflection, and Russian roulette
        (survival W/W_floor, weight set to W_floor) starts only below
        W_floor = :data:`WEIGHT_FLOOR` × W₀. Both are unbiased; "weight" removes the
        chain-length variance that dominates in bright rooms (ρ → 1) at the cost of
        longer chains.
    progress : callable, optional
        Called as ``progress(blocks_done)`` after each block.
    """
    sampler = sampler or EmissionSampler(scene)
    parts = []
    for k in range(blocks):
        parts.append(_block_chains(scene, engine, sampler, seed, first_block + k, CHAIN_BLOCK,
                                   batches, max_depth, absorption))
        if progress is not None:
            progress(k + 1)
    nodes = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    return LsadStore(scene, **nodes, chains=blocks * CHAIN_BLOCK, batches=batches, seed=seed)
