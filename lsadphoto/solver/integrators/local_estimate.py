"""The double local estimate of a view from a store's light-chain nodes, per pixel.

Double local estimate (FORMULAS.md §6.1, Lambertian surfaces). For the pixel whose
primary ray first hits x_p (normal n_p turned towards the eye, reflectance ρ_p), batch b of
N_b chains gives

    L_b(p) = L_e(x_p) + ρ_p/π · (1/N_b) Σ_{nodes n of b} c_n·g_n·cos θ_p·V(x_p, x_n)/|x_n − x_p|²

with g_n = cos θ_n for surface and Lambertian-emitter nodes (c_n = W_n·ρ_n/π or W₀/π) and
g_n = I_l(ω_{n→p}) for nodes on point luminaires (c_n = Φ_total/Φ_l). The map is the mean
over the batches; its per-pixel standard error is the standard deviation of the batch
values over √B (B ≥ 8 independent batches).

Near field (1/r² singularity, FORMULAS.md §6.3). The second moment of a node term
diverges as nodes approach x_p at concave edges, so the default treatment
(``near_field="unbiased"``) splits the area integral at a distance ε (``near_distance``):

* nodes with |x_n − x_p| ≥ ε are connected as above (their terms are bounded by c/ε²);
* the part of the integral over surface points y visible from x_p with |y − x_p| < ε is
  estimated by BRDF sampling from x_p: one cosine-distributed ray per pixel and batch; if
  its first hit y lies closer than ε, it adds ρ_p·L_out(y → x_p), where L_out(y) is itself
  estimated the same way (emission of y, plus the far-node gather at y, plus a further
  near-field ray from y, continued with Russian-roulette probability ρ_y).

The two regions partition the surface points visible from x_p, and each part is an
unbiased estimate of its share of the integral (the gather, because the chain nodes are
an unbiased sample of the incident-flux density; the near ray, because cosine sampling of
the Lambertian BRDF has estimator f·L·cos/p = ρ·L), so their sum is unbiased for any ε.
This is the ε-ball exclusion with BRDF sampling of Marchuk's modified local estimate, and
the same split as Kollig & Keller's bias compensation, with the clamped share replaced by
the whole ε-ball. Nodes on point luminaires are never excluded (a point has no
neighbourhood to sample; their 1/r² is bounded unless a luminaire touches a surface).

``near_field="clamp"`` replaces 1/r² by 1/max(r, ε)² and drops the near rays: faster, lower
variance, but biased low (energy from nodes closer than ε is lost); every output says so.

References
----------
Marchuk et al. (1980), *The Monte Carlo Methods in Atmospheric Optics*, Springer, §3.3
(local and modified local estimates). Budak, Zheltov & Kalakutsky (2012), *Computer
Research and Modeling* 4(1), 75–84 (double local estimate). Kollig, T., Keller, A. (2004).
Illumination in the presence of weak singularities. *Monte Carlo and Quasi-Monte Carlo
Methods 2004*, 245–257.
"""


import math
import time

import numpy as np

from ..._validation import check_choice
from ...errors import BadInputError
from .._sampling import stream
from ..engine import engine_for
from ..store import KIND_COSINE, LsadStore
from .eye import (check_pose, chunk_hits, chunk_size, emitted_luminance,
                  luminance_map_from_batches, luminous_openings, near_step, primary_rays,
                  run_chunks, warn_odd_view)

__all__ = ["AUTO_NODES_PER_PIXEL", "FULL_GATHER_PAIRS", "NEAR_FIELD_TREATMENTS",
           "RELATIVE_NEAR_DISTANCE", "render_local_estimate"]

NEAR_FIELD_TREATMENTS = ("unbiased", "clamp")

#: Default near-field distance ε as a fraction of the scene's bounding-box diagonal.
RELATIVE_NEAR_DISTANCE = 0.01

#: "auto" gathers every node while pixels × nodes stays below this (≈ 5–20 s on 2 cores) …
FULL_GATHER_PAIRS = 20_000_000
#: … and this many nodes per pixel and batch above it.
AUTO_NODES_PER_PIXEL = 32

#: Nodes per gather block (fixed, so sums do not depend on the pixel chunk size). With the
#: default 2048-pixel chunks the dense pair arrays of a block take ≈ 8 MB each.
NODE_BLOCK = 512


class _Gatherer:
    """Sums of node contributions c·g·cos θ/r²·V at points, per batch (float64).

    ``per_pixel=None`` connects every point to every node of the batch (the full double
    local estimate); an integer K connects each point to K nodes drawn uniformly (with
    replacement) from the batch, stratified into source and surface nodes (K/2 each),
    each stratum scaled by its node count over its draws. This is unbiased and costs K
    instead of M_b visibility rays per point.
    """

    def __init__(self, store, engine, *, near_field, near_distance, per_pixel=None, seed=0):
        self.store = store
        self.scene = store.scene
        self.engine = engine
        self.near = near_field == "unbiased"
        self.eps2 = near_distance ** 2
        self.per_pixel = per_pixel
        self.seed = seed
        self.tiny = 1e-9 * store.scene.size
        order = np.argsort(store.batch, kind="stable")
        bounds = np.searchsorted(store.batch[order], np.arange(store.batches + 1))
        self.batch_nodes = [order[bounds[b]:bounds[b + 1]] for b in range(store.batches)]
        self._gens = {}
        self._table = None
        self._packed()  # built once, before any worker threads share it
        # Subsampling is stratified: source nodes (depth 0: direct light) and surface nodes
        # (depth ≥ 1: interreflections) each get half of the K draws (all of them when the
        # other stratum is empty); each stratum is scaled by its size over its draws.
        self.strata, self.stratum_draws = [], []
        for nodes in self.batch_nodes:
            src = nodes[store.depth[nodes] == 0]
            srf = nodes[store.depth[nodes] > 0]
            self.strata.append((src, srf))
            if per_pixel is None:
                self.stratum_draws.append((0, 0))
            elif src.size and srf.size:
                k0 = max(1, int(per_pixel) // 2)
                self.stratum_draws.append((k0, max(1, int(per_pixel) - k0)))
            else:
                self.stratum_draws.append((int(per_pixel) if src.size else 0,
                                           int(per_pixel) if srf.size else 0))

    # Packed node table columns: position (0–2), normal (3–5), coefficient (6), cosine
    # kind flag (7), visibility target = position + ε·normal for cosine nodes (8–10),
    # point-luminaire index (11, −1 otherwise).
    def _packed(self):
        if getattr(self, "_table", None) is None:
            s = self.store
            is_cos = (s.kind == KIND_COSINE).astype(float)
            target = s.position + self.engine.epsilon * s.normal * is_cos[:, None]
            self._table = np.column_stack([s.position, s.normal, s.coefficient, is_cos, target,
                                           s.luminaire.astype(float)])
        return self._table

    def _contributions(self, dx, dy, dz, a_p, a_n, r2, is_cos, cand, table_rows, pixel_of,
                       origins):
        """c·g·cos θ_p/r²·V of the candidate pairs (flat indices ``sel`` of ``cand``).

        ``dx, dy, dz`` (node − point), ``a_p`` = r·cos θ_p, ``a_n`` = r·cos θ_n, ``r2`` = r²
        are arrays of the pair grid; ``table_rows(sel)`` returns the packed rows of the
        candidates' nodes and ``pixel_of(sel)`` their points. Returns (sel, terms).
        """
        sel = np.flatnonzero(cand)
        if sel.size == 0:
            return sel, np.zeros(0)
        rows = table_rows(sel)
        r2c = r2.ravel()[sel]
        ap = a_p.ravel()[sel]
        kc = rows[:, 7] > 0.5
        if self.near:
            denom = r2c * r2c
        else:
            denom = r2c * np.where(kc, np.maximum(r2c, self.eps2), r2c)
        val = rows[:, 6] * a_n.ravel()[sel] * ap / denom
        if self.scene.point_luminaires:
            val = np.where(kc, val, 0.0)
            for li, lum in enumerate(self.scene.point_luminaires):
                m = (~kc) & (rows[:, 11] == li)
                if m.any():
                    r = np.sqrt(r2c[m])
                    dirs = -np.stack([dx.ravel()[sel[m]], dy.ravel()[sel[m]], dz.ravel()[sel[m]]],
                                     axis=1) / r[:, None]
                    val[m] = rows[m, 6] * lum.intensity(dirs) * ap[m] / (r * r2c[m])
        ok = val > 0
        terms = np.zeros(sel.size)
        if ok.any():
            vis = self.engine.visible(origins[pixel_of(sel[ok])], rows[ok, 8:11])
            terms[ok] = val[ok] * vis
        return sel, terms

    def _candidates(self, r2, a_p, a_n, is_cos):
        # Grazing pairs (r·cos below 1e-9 × scene size, e.g. nodes in the plane of x_p)
        # are dropped: their terms vanish, and the threshold keeps rounding from deciding.
        cand = (a_p > self.tiny) & (r2 > 0) & ((a_n > self.tiny) | ~is_cos)
        if self.near:
            cand &= ~(is_cos & (r2 < self.eps2))
        return cand

    def _sampled(self, points, normals, origins, ni):
        """Sum over each row of ``ni`` ``(P, k)`` of the node terms at the row's point."""
        P, k = ni.shape
        q = self._packed()[ni]                              # (P, k, 12)
        dx = q[..., 0] - points[:, 0, None]
        dy = q[..., 1] - points[:, 1, None]
        dz = q[..., 2] - points[:, 2, None]
        r2 = dx * dx + dy * dy + dz * dz
        a_p = dx * normals[:, 0, None] + dy * normals[:, 1, None] + dz * normals[:, 2, None]
        a_n = -(dx * q[..., 3] + dy * q[..., 4] + dz * q[..., 5])
        is_cos = q[..., 7] > 0.5
        cand = self._candidates(r2, a_p, a_n, is_cos)
        flat = q.reshape(-1, q.shape[-1])
        sel, terms = self._contributions(dx, dy, dz, a_p, a_n, r2, is_cos, cand,
                                         lambda sel: flat[sel], lambda sel: sel // k, origins)
        out = np.zeros(P * k)
        out[sel] = terms
        return out.reshape(P, k).sum(axis=1)

    def gather(self, points, normals, batch, block_ids=None):
        """E·N_b at ``points`` ``(P, 3)`` [lm·m⁻²·chains] from the nodes of ``batch``.

        ``block_ids`` (pixel block of each point) keys the random node choice of the
        subsampled mode. All geometry is computed element by element (no BLAS, whose
        rounding may depend on array shapes), and each point's terms are added in a fixed
        order (node blocks of :data:`NODE_BLOCK`, or its own K draws), so results do not
        depend on how pixels are chunked.
        """
        P = len(points)
        idx_all = self.batch_nodes[batch]
        if P == 0 or idx_all.size == 0:
            return np.zeros(P)
        origins = points + self.engine.epsilon * normals
        if self.per_pixel is not None:
            total = np.zeros(P)
            for stratum, k in zip(self.strata[batch], self.stratum_draws[batch]):
                if k == 0:
                    continue
                choice = np.empty((P, k), dtype=np.int64)
                for j in np.unique(block_ids):
                    m = block_ids == j
                    g = self._gens.get((batch, j))
                    if g is None:
                        g = self._gens[(batch, j)] = stream(self.seed, "gather", batch, j)
                    choice[m] = g.integers(0, stratum.size, size=(int(m.sum()), k))
                total += self._sampled(points, normals, origins, stratum[choice]) * (stratum.size / k)
            return total
        out = np.zeros(P)
        table = self._packed()
        px, py, pz = (points[:, i, None] for i in range(3))
        nx, ny, nz = (normals[:, i, None] for i in range(3))
        for start in range(0, idx_all.size, NODE_BLOCK):
            q = table[idx_all[start:start + NODE_BLOCK]]     # (K, 12)
            K = len(q)
            dx, dy, dz = q[None, :, 0] - px, q[None, :, 1] - py, q[None, :, 2] - pz
            r2 = dx * dx + dy * dy + dz * dz
            a_p = dx * nx + dy * ny + dz * nz
            a_n = -(dx * q[None, :, 3] + dy * q[None, :, 4] + dz * q[None, :, 5])
            is_cos = (q[:, 7] > 0.5)[None, :]
            cand = self._candidates(r2, a_p, a_n, is_cos)
            sel, terms = self._contributions(dx, dy, dz, a_p, a_n, r2, is_cos, cand,
                                             lambda sel, q=q, K=K: q[sel % K],
                                             lambda sel, K=K: sel // K, origins)
            if sel.size:
                out += np.bincount(sel // K, weights=terms, minlength=P)
        return out


def _near_field_terms(scene, engine, gatherer, points, normals, rho, batch, block_ids, seed,
                      near_distance, n_b):
    """Per-path estimate of ρ_p·(near-field share of the reflected luminance) [cd·m⁻²].

    ``points``/``normals``/``rho``: the primary points (one path per pixel for ``batch``);
    ``block_ids``: pixel-block index of each path (keys the random streams).
    """
    n = len(points)
    total = np.zeros(n)
    active = np.arange(n)
    x, nx, throughput = points, normals, rho.copy()
    gens = {}
    rho_prev = None  # reflectance of the current vertex (set after the first near hit)
    while active.size:
        # one generator per pixel block, drawn in block order, for the paths still active
        u = np.empty((active.size, 3))
        blocks = block_ids[active]
        for j in np.unique(blocks):
            m = blocks == j
            g = gens.get(j)
            if g is None:
                g = gens[j] = stream(seed, "near", batch, j)
            u[m] = g.random((int(m.sum()), 3))
        near, y, ny, d, prim = near_step(scene, engine, x, nx, u, near_distance, rho_prev)
        active = active[near]
        throughput = throughput[near]
        if not active.size:
            break
        blocks_now = block_ids[active]
        rho_y = scene.triangle_reflectance[prim]
        value = emitted_luminance(scene, prim, -d)
        has_rho = rho_y > 0
        if has_rho.any():
            e = gatherer.gather(y[has_rho], ny[has_rho], batch, blocks_now[has_rho])
            value[has_rho] += rho_y[has_rho] / math.pi * e / n_b
        total[active] += throughput * value
        x, nx, rho_prev = y, ny, rho_y
    return total


# --- double local estimate -------------------------------------------------------------------

def render_local_estimate(store, projection, *, position, rotation, seed=0, near_field=None,
                          near_distance=None, nodes_per_pixel="auto", chunk_pixels=2048,
                          workers=1, progress=None):
    """Luminance map of a view of a simulated store by the double local estimate [cd·m⁻²].

    The estimator behind :func:`lsadphoto.solver.render` (which documents the options and
    also takes a scene, simulating it first); ``store`` is an
    :class:`~lsadphoto.solver.store.LsadStore`.
    """
    if not isinstance(store, LsadStore):
        raise BadInputError("render needs an LsadStore or a Scene")
    near_field = check_choice(near_field or store.near_field, "near_field", NEAR_FIELD_TREATMENTS)
    scene = store.scene
    if near_distance is None:
        near_distance = RELATIVE_NEAR_DISTANCE * scene.size
    near_distance = float(near_distance)
    if not near_distance > 0:
        raise BadInputError(f"near_distance must be positive, got {near_distance!r}")
    position, rotation = check_pose(position, rotation)
    engine = engine_for(scene)
    t0 = time.perf_counter()
    valid, prim, dist, d = primary_rays(scene, engine, projection, position, rotation)
    hit = np.flatnonzero(prim >= 0)
    B = store.batches
    n_b = store.chains_per_batch
    lum_b = np.zeros((valid.size, B))
    if int(workers) != workers or workers < 1:
        raise BadInputError(f"workers must be a positive integer, got {workers!r}")
    workers = int(workers)
    if nodes_per_pixel == "all":
        nodes_per_pixel = None
    elif nodes_per_pixel == "auto":
        # The valid pixels are those primary_rays traced: no second pass over the projection.
        nodes_per_pixel = None if valid.size * store.nodes <= FULL_GATHER_PAIRS else AUTO_NODES_PER_PIXEL
    elif nodes_per_pixel is not None and (isinstance(nodes_per_pixel, (str, bool))
                                          or int(nodes_per_pixel) != nodes_per_pixel or nodes_per_pixel < 1):
        raise BadInputError("nodes_per_pixel must be a positive integer, 'all' or 'auto', "
                            f"got {nodes_per_pixel!r}")
    gatherer = _Gatherer(store, engine, near_field=near_field, near_distance=near_distance,
                         per_pixel=nodes_per_pixel, seed=seed)
    chunk = chunk_size(chunk_pixels)

    def work(start):
        c = chunk_hits(scene, position, hit, prim, dist, d, start, chunk)
        x, nrm, rho, block_ids = c.point, c.normal, c.reflectance, c.block
        refl = rho > 0
        out = np.empty((c.index.size, B))
        for b in range(B):
            value = c.emitted.copy()
            if refl.any():
                e = gatherer.gather(x[refl], nrm[refl], b, block_ids[refl])
                value[refl] += rho[refl] / math.pi * e / n_b
                if near_field == "unbiased":
                    value[refl] += _near_field_terms(scene, engine, gatherer, x[refl], nrm[refl],
                                                     rho[refl], b, block_ids[refl], seed,
                                                     near_distance, n_b)
            out[:, b] = value
        return c.index, out

    run_chunks(work, range(0, hit.size, chunk), lum_b, workers, progress, t0, hit.size)
    openings = luminous_openings(scene, position, d, dist)
    # stacklevel 4: the warning points at the caller of lsadphoto.solver.render
    warn_odd_view(scene, engine, prim, dist, np.where(np.isfinite(openings)[:, None], 1.0, lum_b),
                  position, stacklevel=4)
    return luminance_map_from_batches(
        projection, valid, lum_b, model=store, estimator="double local estimate",
        openings=openings,
        extra={"samples": int(store.chains), "chains": int(store.chains),
               "nodes": int(store.nodes),
               "near_field": near_field, "near_distance_m": near_distance,
               "near_field_biased": near_field == "clamp",
               "nodes_per_pixel": "all" if nodes_per_pixel is None else int(nodes_per_pixel),
               "seed": int(seed), "simulation_seed": int(store.seed)},
        elapsed=time.perf_counter() - t0, pose=(position, rotation))


