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

from ._sampling import GroupStreams, cosine_directions, orthonormal_basis, stream, triangle_points
from .store import KIND_COSINE, KIND_POINT, LsadStore

ABSORPTION_MODES = ("weight", "roulette")

#: Kind of the emission samples of distant sources (never stored as nodes).
KIND_DISTANT = 2

__all__ = [
    "ABSORPTION_MODES",
    "CHAIN_BLOCK",
    "MAX_BOUNCES",
    "WEIGHT_FLOOR",
    "EmissionSampler",
    "KIND_DISTANT",
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
    """Samples emission points on the luminaires of a scene, in proportion to their flux.

    Vectorised over luminaires: one draw over all emitting triangles (probability
    Φ_l·a_t/A_l for triangle t of area luminaire l), the point luminaires' rectangles and
    frames as arrays, and their first directions drawn once per distinct intensity table
    (luminaires of one photometric file share it), so the cost does not grow with a Python
    loop over hundreds of luminaires.
    """

    def __init__(self, scene):
        self.scene = scene
        self.total_flux = scene.total_flux
        area = scene.area_luminaires
        points = scene.point_luminaires
        self.n_area = len(area)
        fluxes = np.array([l.flux for l in area] + [l.flux for l in points], dtype=float)
        # One CDF over every emission choice: each emitting triangle, then each point luminaire.
        if area:
            self._tri = np.concatenate([l.triangles for l in area])
            self._tri_lum = np.concatenate([np.full(len(l.triangles), k) for k, l in enumerate(area)])
            a = scene.areas[self._tri]
            lum_area = np.array([scene.areas[l.triangles].sum() for l in area])
            tri_mass = fluxes[self._tri_lum] * a / lum_area[self._tri_lum]
        else:
            self._tri = np.zeros(0, np.int64)
            self._tri_lum = np.zeros(0, np.int64)
            tri_mass = np.zeros(0)
        # … then each distant source, its flux through the scene's bounding sphere
        self.distant = list(scene.distant_sources)
        dist_flux = np.array([scene.distant_flux(d) for d in self.distant], dtype=float)
        mass = np.concatenate([tri_mass, fluxes[self.n_area:], dist_flux])
        self._n_point = len(points)
        # whether each choice can be a light source of Radiance's direct calculation (point
        # luminaires are ``light``s or ``spotlight``s; area luminaires within their radius)
        self._light_source = np.concatenate([
            np.array([l.light_source_radius > 0 for l in area], bool)[self._tri_lum], np.ones(len(points), bool),
            np.array([d.light_source for d in self.distant], bool)])
        self._cdf = np.cumsum(mass) / mass.sum()
        self._cdf[-1] = 1.0
        self._n_tri = len(self._tri)
        if points:
            self._positions = np.array([l.position for l in points], dtype=float)
            self._frames = np.array([l.frame for l in points], dtype=float)
            self._extents = np.array([l.extent for l in points], dtype=float)
            self._coef = self.total_flux / np.array([l.flux for l in points])
            self._multipliers = np.array([l.multiplier for l in points], dtype=float)
            tables = {}
            for k, l in enumerate(points):
                tables.setdefault(id(l.photometry), (l.photometry, []))[1].append(k)
            self._table_of = np.zeros(len(points), np.int64)
            self.tables = []
            for j, (table, members) in enumerate(tables.values()):
                self._table_of[members] = j
                self.tables.append(table)

    def sample(self, rng, n):
        """``n`` emission points: dict of position, normal, luminaire, kind, coefficient.

        ``luminaire`` indexes area luminaires (kind 0), point luminaires (kind 1) or distant
        sources (:data:`KIND_DISTANT`); ``light_source`` says whether it can be a light source
        of Radiance's direct calculation (:meth:`light_source_at` says where).
        ``coefficient`` is Φ_total/π for Lambertian emitters
        and Φ_total/Φ_luminaire for point luminaires (see
        :class:`~lsadphoto.solver.store.LsadStore`). A distant sample is a direction ω
        towards its source (``direction``, drawn by
        :meth:`~lsadphoto.solver.sky.DistantSource.sample`, weight ``factor`` = L/(p·K)) and
        a point uniform on the disc of the bounding sphere's radius R perpendicular to ω on
        the sphere's ω side (``position``; ``normal`` = −ω, the way its light travels), with
        coefficient Φ_total/(πR²): then Φ_total/(πR²)·factor·g estimates ∫L(ω)g(ω)dω.
        """
        scene = self.scene
        u_choice = rng.random(n)
        u_pt = rng.random((n, 2))
        which = np.minimum(np.searchsorted(self._cdf, u_choice, side="right"), len(self._cdf) - 1)
        on_tri = which < self._n_tri
        position = np.zeros((n, 3))
        normal = np.zeros((n, 3))
        kind = np.where(on_tri, KIND_COSINE, KIND_POINT).astype(np.int8)
        lum_index = np.zeros(n, dtype=np.int64)
        coefficient = np.zeros(n)
        triangle = np.full(n, -1, dtype=np.int64)
        if on_tri.any():
            t = self._tri[which[on_tri]]
            triangle[on_tri] = t
            lum_index[on_tri] = self._tri_lum[which[on_tri]]
            position[on_tri] = triangle_points(scene.triangles[t], u_pt[on_tri])
            normal[on_tri] = scene.normals[t]
            coefficient[on_tri] = self.total_flux / math.pi
        pt = ~on_tri & (which < self._n_tri + self._n_point)
        if pt.any():
            k = which[pt] - self._n_tri
            lum_index[pt] = k
            frames = self._frames[k]
            offs = (u_pt[pt] - 0.5) * self._extents[k]
            position[pt] = self._positions[k] + offs[:, :1] * frames[:, 0] + offs[:, 1:] * frames[:, 1]
            normal[pt] = frames[:, 2]
            coefficient[pt] = self._coef[k]
        out = {"position": position, "normal": normal, "kind": kind, "luminaire": lum_index,
               "coefficient": coefficient, "triangle": triangle, "light_source": self._light_source[which]}
        if self.distant:
            self._sample_distant(rng, which, out)
        return out

    def _sample_distant(self, rng, which, out):
        """Fill the distant samples of :meth:`sample` in ``out`` (its uniforms are drawn only
        for scenes with distant sources, so other scenes keep their random streams)."""
        n = len(which)
        u = rng.random((n, 5))
        out["direction"] = np.zeros((n, 3))
        out["factor"] = np.ones(n)
        rows = np.flatnonzero(which >= self._n_tri + self._n_point)
        if not rows.size:
            return
        k = which[rows] - self._n_tri - self._n_point
        centre, radius = self.scene.sphere
        for j, src in enumerate(self.distant):
            m = rows[k == j]
            if m.size:
                out["direction"][m], out["factor"][m] = src.sample(u[m, :3])
        d = out["direction"][rows]
        t, b = orthonormal_basis(d)
        r = radius * np.sqrt(u[rows, 3])
        phi = 2 * math.pi * u[rows, 4]
        out["position"][rows] = (centre + radius * d + (r * np.cos(phi))[:, None] * t
                                 + (r * np.sin(phi))[:, None] * b)
        out["normal"][rows] = -d
        out["kind"][rows] = KIND_DISTANT
        out["luminaire"][rows] = k
        out["coefficient"][rows] = self.total_flux / (math.pi * radius ** 2)

    def light_source_at(self, src, points):
        """Whether the emission samples ``src`` (of :meth:`sample`) are light sources of
        Radiance's direct calculation at ``points`` (n, 3) [m] (bool, shape (n,)): area
        luminaires within their light-source radius
        (:meth:`~lsadphoto.solver.scene.Scene.light_source_at`), the others by their kind
        (the ``"radiance"`` rule of :data:`~lsadphoto.solver.materials.FRESNEL_RULES`)."""
        out = src["light_source"].copy()
        area = np.flatnonzero(out & (src["kind"] == KIND_COSINE))
        out[area] = self.scene.light_source_at(src["luminaire"][area], np.asarray(points)[area])
        return out

    def point_intensity(self, luminaire, directions):
        """Intensity [cd] of point luminaires ``luminaire`` (indices, shape (n,)) towards
        world ``directions`` (n, 3), evaluated once per distinct intensity table."""
        luminaire = np.asarray(luminaire)
        out = np.zeros(luminaire.size)
        table_of = self._table_of[luminaire]
        for j, table in enumerate(self.tables):
            rows = np.flatnonzero(table_of == j)
            if rows.size:
                out[rows] = (table.evaluate(directions[rows], self._frames[luminaire[rows]])
                             * self._multipliers[luminaire[rows]])
        return out

    def first_directions(self, rng, src):
        """First directions and weight factors of the chains started at ``src``: cosine
        directions for Lambertian emitters, each point luminaire's distribution (drawn once
        per distinct intensity table and turned into each luminaire's frame)."""
        n = len(src["kind"])
        direction = cosine_directions(src["normal"], rng.random((n, 2)))
        factor = np.ones(n)
        if self.distant:
            far = src["kind"] == KIND_DISTANT
            direction[far] = src["normal"][far]
            factor = src["factor"].copy()
        point = np.flatnonzero(src["kind"] == KIND_POINT)
        if point.size:
            table_of = self._table_of[src["luminaire"][point]]
            for j, table in enumerate(self.tables):
                rows = point[table_of == j]
                if rows.size:
                    d, w = table.sample(rng, rows.size, self._frames[src["luminaire"][rows]])
                    direction[rows] = d
                    factor[rows] = w
        return direction, factor


def _chain_starts(engine, sampler, seed, block, n, batches):
    """The emission of the ``n`` chains of one block (global chain index block·CHAIN_BLOCK + i):
    its random stream, the source nodes (lists of arrays, as the node records, with ``direct``:
    whether the luminaire can be a light source of Radiance's direct calculation), each chain's
    batch, first direction, weight [lm] and ray origin, and the emission samples
    (:meth:`EmissionSampler.sample`)."""
    rng = stream(seed, "chains", block)
    src = sampler.sample(rng, n)
    batch = ((block * CHAIN_BLOCK + np.arange(n)) % batches).astype(np.int16)
    # distant sources leave no source node: their direct light is next-event estimated
    # where it arrives (lsadphoto.solver.sky.distant_illuminance)
    near = src["kind"] != KIND_DISTANT
    out = {
        "position": [src["position"][near]], "normal": [src["normal"][near]],
        "coefficient": [src["coefficient"][near]], "kind": [src["kind"][near]],
        "luminaire": [np.where(src["kind"] == KIND_POINT, src["luminaire"], -1)[near].astype(np.int32)],
        "batch": [batch[near]], "depth": [np.zeros(int(near.sum()), np.int16)],
        "triangle": [src["triangle"][near]], "direct": [src["light_source"][near]],
    }
    direction, factor = sampler.first_directions(rng, src)
    origin = src["position"] + engine.epsilon * np.where(
        (src["kind"] == KIND_COSINE)[:, None], src["normal"], 0.0)
    return rng, out, batch, direction, sampler.total_flux * factor, origin, src


def _block_chains(scene, engine, sampler, seed, block, n, batches, max_depth, absorption):
    """Nodes of the ``n`` chains of one block (global chain index block·CHAIN_BLOCK + i)."""
    rng, out, batch, direction, weight, origin, _ = _chain_starts(engine, sampler, seed, block, n, batches)
    del out["direct"]  # Lambertian scenes have no Fresnel factor
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


#: Chain blocks traced together by :func:`trace_material_chains` (one array per bounce; each
#: block draws from its own stream, so the nodes are those of one block at a time).
MATERIAL_GROUP = 64


def _material_block_group(scene, engine, sampler, seed, blocks, batches, limit, rule):
    """Nodes of the chains of ``blocks`` (consecutive), in block order as if traced one block
    at a time: the blocks' chains share the arrays of each bounce, each block's random
    numbers come from its own stream (:class:`~lsadphoto.solver._sampling.GroupStreams`).
    ``rule``: :data:`~lsadphoto.solver.materials.FRESNEL_RULES`; a surface node's ``direct``
    says whether its light came straight from a light source of Radiance's direct calculation
    (through straight-through transmissions only, as Radiance's shadow rays)."""
    bsdf = scene.bsdf
    floor = WEIGHT_FLOOR * sampler.total_flux
    n = CHAIN_BLOCK
    starts = [_chain_starts(engine, sampler, seed, block, n, batches) for block in blocks]
    streams = GroupStreams([s[0] for s in starts])
    out = {key: [np.concatenate([s[1][key][0] for s in starts])] for key in starts[0][1]}
    batch, direction, weight, origin = (np.concatenate([s[k] for s in starts]) for k in range(2, 6))
    # whether each chain's light may still be straight from a Radiance light source, and its
    # area luminaire (−1: none), which is one only within its radius
    straight = np.concatenate([s[6]["light_source"] for s in starts])
    source = np.concatenate([np.where(s[6]["kind"] == KIND_COSINE, s[6]["luminaire"], -1) for s in starts])
    group = np.repeat(np.arange(len(starts)), n)   # of each chain
    # the source nodes of each block (distant sources leave none)
    sources = np.repeat(np.arange(len(starts)), [len(s[1]["batch"][0]) for s in starts])
    out.update(incoming=[np.zeros((sources.size, 3))], front=[np.ones(sources.size, bool)], group=[sources])
    alive = np.arange(group.size)
    depth = 0
    while alive.size and depth < limit:
        depth += 1
        prim, dist = engine.closest_hit(origin, direction)
        streams.counts = np.bincount(group[alive], minlength=len(starts))
        u = streams.random((alive.size, 3))
        hit = prim >= 0
        alive, origin, direction, weight, prim, dist, u, straight, source = (
            alive[hit], origin[hit], direction[hit], weight[hit], prim[hit], dist[hit], u[hit], straight[hit],
            source[hit])
        if not alive.size:
            break
        point = origin + dist[:, None] * direction
        direct = straight.copy()
        area = np.flatnonzero(straight & (source >= 0))
        direct[area] = scene.light_source_at(source[area], point[area])
        nrm, front = scene.facing_normals(prim, direction)
        mat = scene.material[prim]
        p = bsdf.parts(mat, -np.einsum("ij,ij->i", direction, nrm), front)
        keep = (p["kd"] + p["td"] + p["rs"] + p["ts"]) > 0
        for key, value in (("position", point), ("normal", nrm), ("coefficient", weight),
                           ("incoming", -direction), ("front", front), ("triangle", prim),
                           ("batch", batch[alive]), ("group", group[alive]), ("direct", direct)):
            out[key].append(value[keep])
        k = int(keep.sum())
        out["kind"].append(np.zeros(k, np.int8))
        out["luminaire"].append(np.full(k, -1, np.int32))
        out["depth"].append(np.full(k, depth, np.int16))
        wi, w, delta, _ = bsdf.sample(mat, nrm, -direction, u, front, rule=rule, direct=direct, adjoint=True)
        weight = weight * w
        low = weight < floor
        q = np.where(low, weight / floor, 1.0)
        survive = (w > 0) & (u[:, 2] < q)
        weight = np.where(low, floor, weight)
        side = np.sign(np.einsum("ij,ij->i", wi, nrm))
        straight = straight & delta & (side < 0)
        alive, point, nrm, wi, weight, side, straight, source = (
            alive[survive], point[survive], nrm[survive], wi[survive], weight[survive], side[survive],
            straight[survive], source[survive])
        direction = wi
        origin = point + engine.epsilon * side[:, None] * nrm
    nodes = {key: np.concatenate(v) for key, v in out.items()}
    order = np.argsort(nodes.pop("group"), kind="stable")   # block by block, each by depth
    return {key: v[order] for key, v in nodes.items()}


def trace_material_chains(scene, engine, *, seed, first_block, blocks, batches, max_depth=None, sampler=None,
                          progress=None, fresnel_rule="reciprocal"):
    """An :class:`LsadStore` with the chains of blocks ``first_block … first_block+blocks−1``
    of a scene with non-Lambertian materials (``scene.bsdf``).

    As :func:`trace_chains` with ``absorption="weight"``, but at every hit the chain samples
    the material's BSDF (:meth:`~lsadphoto.solver.materials.MaterialTable.sample`: the weight
    W is multiplied by f·|μ_i|/p, or R, T through a delta), and the node it leaves is
    recorded with coefficient W (not W·ρ/π), its incoming direction and whether it was hit on
    the front side (the store's ``incoming`` and ``front``), so that the local estimate
    evaluates W·f(ω_in, ω_out)·|cos θ_out| towards any point. Hits on purely specular
    surfaces (mirror, glass) leave no node. Blocks are traced :data:`MATERIAL_GROUP` at a
    time, each from its own stream, so the nodes do not depend on how the blocks are split
    between calls; ``progress(blocks_done)`` is called after each group. ``fresnel_rule``
    (:data:`~lsadphoto.solver.materials.FRESNEL_RULES`) decides the smooth materials' factor
    1 − F of the arriving light at the nodes (recorded in the store, with each node's
    ``direct``).
    """
    sampler = sampler or EmissionSampler(scene)
    limit = MAX_BOUNCES if max_depth is None else int(max_depth)
    parts = []
    for lo in range(0, blocks, MATERIAL_GROUP):
        hi = min(lo + MATERIAL_GROUP, blocks)
        parts.append(_material_block_group(scene, engine, sampler, seed, range(first_block + lo, first_block + hi),
                                           batches, limit, fresnel_rule))
        if progress is not None:
            progress(hi)
    nodes = {key: np.concatenate([q[key] for q in parts]) for key in parts[0]}
    return LsadStore(scene, **nodes, chains=blocks * CHAIN_BLOCK, batches=batches, seed=seed,
                     fresnel_rule=fresnel_rule)
