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
from ..materials import shadow_transmittance
from ..scene import Scene
from ..sky import (GATHER_DISTANT_SAMPLES, background_luminance, distant_illuminance, distant_reflection,
                   distant_uniforms, stratified)
from ..store import KIND_COSINE, LsadStore
from .eye import (check_pose, chunk_hits, chunk_size, emitted_luminance,
                  luminance_map_from_batches, luminous_openings, near_step, primary_rays,
                  run_chunks, warn_odd_view)

__all__ = ["AUTO_NODES_PER_PIXEL", "FULL_GATHER_PAIRS", "NEAR_FIELD_TREATMENTS",
           "RELATIVE_NEAR_DISTANCE", "render_local_estimate", "render_local_estimate_materials"]

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
        self.n_b = store.chains_per_batch
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
        total = self._distant(points, normals, batch, block_ids)
        if P == 0 or idx_all.size == 0:
            return total
        origins = points + self.engine.epsilon * normals
        if self.per_pixel is not None:
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
        return out + total

    def _distant(self, points, normals, batch, block_ids):
        """E·N_b [lm·m⁻²·chains] of the distant sources at ``points``, next-event estimated
        (:func:`~lsadphoto.solver.sky.distant_illuminance`: they leave no source nodes)."""
        if not self.scene.distant_sources or len(points) == 0:
            return np.zeros(len(points))
        blocks = np.zeros(len(points), np.int64) if block_ids is None else block_ids
        u = distant_uniforms(self.scene, self.seed, (1, batch), blocks, GATHER_DISTANT_SAMPLES, self._gens)
        return distant_illuminance(self.scene, self.engine, points, normals, u)[0] * self.n_b


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




# --- scenes with glossy, specular and transmitting materials ---------------------------------

#: Delta (mirror or straight-through) bounces an eye path follows at most.
MAX_DELTA_BOUNCES = 16


class _MaterialGatherer:
    """Node terms W·f_n(ω_in, ω_out)|cos θ_n|·f_p(ω_{p→n}, ω_o)|cos θ_p|/r²·T at points.

    ``nodes`` is :func:`~lsadphoto.solver.chains.trace_material_chains`' dict. Each point
    draws K nodes of its batch uniformly with replacement, K/2 from the source nodes (direct
    light) and K/2 from the surface nodes, each stratum scaled by its size over its draws
    (unbiased). T is the shadow transmittance (glass passes light straight through).

    What the connections estimate is a part of the reflection integral only: at the point
    they evaluate the full non-delta BSDF f_p towards point-luminaire nodes (which no ray can
    hit), its diffuse part towards surface nodes, the diffuse part plus the glossy part times
    the balance-heuristic weight w_L = K_s p_L/(K_s p_L + p_B) towards emitter nodes (p_L:
    solid-angle density of emission points, K_s source draws, p_B the BSDF sampler's
    density; Veach 1997, §9.2), and nothing closer than ε; the rest — the glossy part over
    surfaces, w_B = 1 − w_L of it over emitters, and the near field — is left to
    BSDF-sampled rays (:func:`_scattered`), whose weights carry exactly that complement, so
    the sum is unbiased while narrow lobes are sampled by rays and small luminaires by nodes.
    """

    def __init__(self, scene, engine, sampler, nodes, *, per_pixel, near_distance):
        self.scene, self.engine, self.sampler, self.nodes = scene, engine, sampler, nodes
        self.k = int(per_pixel)
        self.eps2 = near_distance ** 2
        self.n_b = nodes["chains"] / nodes["batches"]
        order = np.argsort(nodes["batch"], kind="stable")
        bounds = np.searchsorted(nodes["batch"][order], np.arange(nodes["batches"] + 1))
        # emission-point density per unit area [m⁻²] of each area luminaire: (Φ_l/Φ)/A_l
        self.area_density = np.array([lum.flux / (sampler.total_flux * scene.areas[lum.triangles].sum())
                                      for lum in scene.area_luminaires])
        self.strata = []
        for b in range(nodes["batches"]):
            idx = order[bounds[b]:bounds[b + 1]]
            self.strata.append([s for s in (idx[nodes["depth"][idx] == 0], idx[nodes["depth"][idx] > 0])
                                if s.size])

    def source_draws(self, batch):
        """Source-node draws per point of ``batch`` (0 when it has no source nodes)."""
        st = self.strata[batch]
        if not st or self.nodes["depth"][st[0][0]] != 0:
            return 0
        return max(1, self.k // len(st))

    def light_weight(self, batch, triangles, r2, cos_y, p_bsdf):
        """Balance-heuristic weight w_L = K_s p_L/(K_s p_L + p_B) of emission points on
        ``triangles`` at squared distance ``r2`` seen at cos θ_y, against the BSDF density."""
        p_l = (self.source_draws(batch) * self.area_density[self.scene.emitter[triangles]] * r2
               / np.maximum(cos_y, 1e-12))
        return p_l / np.maximum(p_l + p_bsdf, 1e-300)

    def gather(self, rng, x, n, wo, mat, batch, front):
        """The connections' share of the luminance at points ``x`` towards ``wo`` [cd·m⁻²],
        with the distant sources' light by next-event estimation (they leave no nodes)."""
        P = len(x)
        total = np.zeros(P)
        if P and self.scene.distant_sources:
            u = stratified(rng.random((P, len(self.scene.distant_sources), GATHER_DISTANT_SAMPLES, 2)))
            sky = distant_reflection(self.scene, self.engine, x, n, wo, mat, u)
        else:
            sky = 0.0
        strata = self.strata[batch]
        if not P or not strata:
            return total + sky
        k_each = max(1, self.k // len(strata))
        nd = self.nodes
        bsdf = self.scene.bsdf
        eps = self.engine.epsilon
        for stratum in strata:
            pick = stratum[rng.integers(0, stratum.size, size=(P, k_each))].ravel()
            owner = np.repeat(np.arange(P), k_each)
            y, ny = nd["position"][pick], nd["normal"][pick]
            v = y - x[owner]
            r2 = np.einsum("ij,ij->i", v, v)
            w = v / np.sqrt(np.maximum(r2, 1e-300))[:, None]
            np_ = n[owner]
            cos_p = np.einsum("ij,ij->i", w, np_)
            f_d, f_g = bsdf.evaluate(mat[owner], np_, wo[owner], w, split=True)
            kind = nd["kind"][pick]
            surface = nd["depth"][pick] > 0
            cos_n = -np.einsum("ij,ij->i", w, ny)
            f_p = np.where(kind == KIND_COSINE, f_d, f_d + f_g)
            emitter = np.flatnonzero((kind == KIND_COSINE) & ~surface & (f_g > 0))
            if emitter.size:
                p_b = bsdf.pdf(mat[owner[emitter]], np_[emitter], wo[owner[emitter]], w[emitter],
                               np.asarray(front)[owner[emitter]])
                f_p[emitter] += f_g[emitter] * self.light_weight(
                    batch, nd["triangle"][pick[emitter]], r2[emitter], np.maximum(cos_n[emitter], 0.0), p_b)
            intensity = np.where(kind == KIND_COSINE, nd["coefficient"][pick] * np.maximum(cos_n, 0.0), 0.0)
            if surface.any():
                s = np.flatnonzero(surface)
                m_n = self.scene.material[nd["triangle"][pick[s]]]
                f_n = bsdf.evaluate(m_n, ny[s], nd["incoming"][pick[s]], -w[s])
                intensity[s] = nd["coefficient"][pick[s]] * f_n * np.abs(cos_n[s])
            point = np.flatnonzero(kind != KIND_COSINE)
            if point.size:
                intensity[point] = nd["coefficient"][pick[point]] * self.sampler.point_intensity(
                    nd["luminaire"][pick[point]], -w[point])
            near = (kind == KIND_COSINE) & (r2 < self.eps2)
            val = np.where(near | (r2 <= 0), 0.0, f_p * np.abs(cos_p) * intensity / np.maximum(r2, 1e-300))
            ok = np.flatnonzero(val > 0)
            if ok.size:
                side_p = np.sign(cos_p[ok])[:, None]
                side_n = np.where(surface[ok], np.sign(cos_n[ok]), 1.0)[:, None]
                target = y[ok] + eps * side_n * ny[ok] * (kind[ok] == KIND_COSINE)[:, None]
                val[ok] *= shadow_transmittance(self.scene, self.engine, x[owner[ok]] + eps * side_p * np_[ok],
                                                target)
            total += np.bincount(owner, weights=val, minlength=P) * (stratum.size / k_each)
        return total / self.n_b + sky


def _material_paths(scene, engine, gatherer, rng, x, n, front, tri, wo, batch, near_distance):
    """Per-path luminance [cd·m⁻²] towards ``wo`` at the primary points (emission excluded):
    the eye path followed through delta surfaces, and at each vertex the connections plus
    the BSDF-sampled rays of the rest (:func:`_scattered`)."""
    bsdf = scene.bsdf
    eps = engine.epsilon
    total = np.zeros(len(x))
    idx = np.arange(len(x))
    for _ in range(MAX_DELTA_BOUNCES + 1):
        if not idx.size:
            break
        mat = scene.material[tri]
        total[idx] += gatherer.gather(rng, x, n, wo, mat, batch, front)
        total[idx] += _scattered(scene, engine, gatherer, rng, x, n, front, wo, mat, batch, near_distance)
        # continue through the delta parts: survive with R + T, choose one in proportion
        r, t = bsdf.delta(mat, np.einsum("ij,ij->i", n, wo), front)
        u = rng.random((len(idx), 2))
        go = u[:, 0] < r + t
        refl = u[:, 1] * (r + t) < r
        d = np.where(refl[:, None], 2 * np.einsum("ij,ij->i", n, wo)[:, None] * n - wo, -wo)
        side = np.where(refl, 1.0, -1.0)[:, None]
        idx, x, n, d, side = idx[go], x[go], n[go], d[go], side[go]
        if not idx.size:
            break
        prim, dist = engine.closest_hit(x + eps * side * n, d)
        hit = prim >= 0
        if scene.distant_sources:  # the sky seen through glass or in a mirror
            total[idx[~hit]] += background_luminance(scene, d[~hit])
        idx, x, n, d, side, prim, dist = idx[hit], x[hit], n[hit], d[hit], side[hit], prim[hit], dist[hit]
        x = x + eps * side * n + dist[:, None] * d
        n, front = scene.facing_normals(prim, d)
        wo, tri = -d, prim
        total[idx] += emitted_luminance(scene, prim, wo)
    return total


def _scattered(scene, engine, gatherer, rng, x, n, front, wo, mat, batch, near_distance):
    """What the connections leave out, by BSDF-sampled rays.

    At each vertex one ray is drawn from the BSDF mixture (weight w = f·|μ_i|/p, or R/P_R,
    T/P_T for a delta; at the first vertex the eye path follows the deltas itself). A path
    carries two weights: β for the radiance that the previous vertex's connections did not
    cover (h = f_glossy + f_diffuse·[hit closer than ε], and for emission the
    balance-heuristic complement), and β_f for radiance reflected by a delta at the hit,
    which no connection reaches (the full w). A delta reflection turns β_f into the weight
    of everything beyond it; a straight-through transmission keeps both (connections pass
    it). Russian roulette min(1, w) after the first ray.
    """
    bsdf = scene.bsdf
    eps = engine.epsilon
    total = np.zeros(len(x))
    idx = np.arange(len(x))
    beta = np.ones(len(x))
    beta_f = np.ones(len(x))
    # weight of the distant sources' radiance, which the connections' next-event estimate
    # covers except after delta reflections (and straight transmissions after those)
    beta_s = np.zeros(len(x))
    first = True
    while idx.size:
        u = rng.random((idx.size, 4))
        wi, w, delta, _ = bsdf.sample(mat, n, wo, u[:, :3], front)
        keep = (w > 0) & ~(delta & first)
        idx, beta, beta_f, beta_s, x, n, wi, w, delta, wo, mat, u = (
            idx[keep], beta[keep], beta_f[keep], beta_s[keep], x[keep], n[keep], wi[keep], w[keep], delta[keep],
            wo[keep], mat[keep], u[keep])
        front = np.asarray(front)[keep]
        if not idx.size:
            break
        side = np.sign(np.einsum("ij,ij->i", wi, n))[:, None]
        prim, dist = engine.closest_hit(x + eps * side * n, wi)
        reflected = delta & (side[:, 0] > 0)
        # weights of the hit's reflected radiance (b), delta radiance (bf) and emission (be)
        b = np.where(reflected, beta_f, beta) * w
        bf = np.where(delta, beta_f, beta) * w
        be = b.copy()
        nd = np.flatnonzero(~delta & (prim >= 0))
        if nd.size:
            f_d, f_g = bsdf.evaluate(mat[nd], n[nd], wo[nd], wi[nd], split=True)
            pdf = bsdf.pdf(mat[nd], n[nd], wo[nd], wi[nd], front[nd])
            mu = np.abs(np.einsum("ij,ij->i", n[nd], wi[nd]))
            near = dist[nd] < near_distance
            scale = np.where(pdf > 0, mu / np.maximum(pdf, 1e-300), 0.0)
            b[nd] = beta[nd] * (f_g + f_d * near) * scale
            lit = scene.emitter[prim[nd]] >= 0
            w_b = np.ones(nd.size)
            if lit.any():
                cos_y = np.abs(np.einsum("ij,ij->i", scene.normals[prim[nd][lit]], wi[nd][lit]))
                w_b[lit] = 1 - gatherer.light_weight(batch, prim[nd][lit], dist[nd][lit] ** 2, cos_y, pdf[lit])
            be[nd] = beta[nd] * np.where(near, f_d + f_g, f_g * w_b) * scale
        hit = prim >= 0
        if hit.any():
            total[idx[hit]] += be[hit] * emitted_luminance(scene, prim[hit], -wi[hit])
        bs = np.where(delta, np.where(reflected, beta_f, beta_s), 0.0) * w
        away = np.flatnonzero(~hit & (bs > 0))
        if away.size and scene.distant_sources:
            total[idx[away]] += bs[away] * background_luminance(scene, wi[away])
        q = np.ones(idx.size) if first else np.minimum(w, 1.0)
        go = hit & ((b > 0) | (bf > 0)) & (u[:, 3] < q)
        idx, beta, beta_f, beta_s, x, n, wi, side, prim, dist = (
            idx[go], b[go] / q[go], bf[go] / q[go], bs[go] / q[go], x[go], n[go], wi[go], side[go], prim[go],
            dist[go])
        if not idx.size:
            break
        x = x + eps * side * n + dist[:, None] * wi
        n, front = scene.facing_normals(prim, wi)
        wo, mat = -wi, scene.material[prim]
        total[idx] += beta * gatherer.gather(rng, x, n, wo, mat, batch, front)
        first = False
    return total


def render_local_estimate_materials(scene, projection, *, position, rotation, samples=65536, seed=0,
                                    batches=16, nodes_per_pixel=AUTO_NODES_PER_PIXEL, near_distance=None,
                                    max_depth=None, chunk_pixels=2048, workers=1, progress=None):
    """Luminance map [cd·m⁻²] of a scene with glossy, specular or transmitting materials by the
    double local estimate.

    ``samples`` light chains (:func:`~lsadphoto.solver.chains.trace_material_chains`, each
    sampling the BSDFs) in ``batches`` batches; for each pixel and batch the eye path is
    followed through perfectly specular surfaces (mirror, glass, smooth plastic's mirror part:
    one delta chosen in proportion to R and T, survival R + T) and at every vertex the
    non-delta BSDF is evaluated towards the eye and connected to ``nodes_per_pixel`` chain
    nodes (:class:`_MaterialGatherer`), with the near field (nodes closer than
    ``near_distance``, default 1 % of the scene size) replaced by BSDF-sampled rays.
    Connections pass straight-through transmitters (glass) with their transmittance; light
    that reaches a non-specular point after a delta reflection (a floor lit by a mirror, by
    the reflection of a luminaire in glass) comes from the sampled rays (:func:`_scattered`).

    References
    ----------
    Marchuk et al. (1980), §3.3 (local estimates). Veach (1997), §10 (connections and
    specular vertices).
    """
    from ..chains import CHAIN_BLOCK as _BLOCK
    from ..chains import EmissionSampler, trace_material_chains

    if not isinstance(scene, Scene) or scene.bsdf is None:
        raise BadInputError("render_local_estimate_materials needs a Scene with non-Lambertian materials")
    position, rotation = check_pose(position, rotation)
    samples, batches = int(samples), int(batches)
    if batches < 2 or _BLOCK % batches or samples < _BLOCK:
        raise BadInputError(f"samples ({samples}) must be ≥ {_BLOCK} and batches ({batches} ≥ 2) divide {_BLOCK}")
    near_distance = float(RELATIVE_NEAR_DISTANCE * scene.size if near_distance is None else near_distance)
    if not near_distance > 0:
        raise BadInputError(f"near_distance must be positive, got {near_distance!r}")
    t0 = time.perf_counter()
    engine = engine_for(scene)
    sampler = EmissionSampler(scene)
    nodes = trace_material_chains(scene, engine, seed=seed, blocks=-(-samples // _BLOCK), batches=batches,
                                  max_depth=max_depth, sampler=sampler)
    gatherer = _MaterialGatherer(scene, engine, sampler, nodes, per_pixel=nodes_per_pixel,
                                 near_distance=near_distance)
    valid, prim, dist, d = primary_rays(scene, engine, projection, position, rotation)
    hit = np.flatnonzero(prim >= 0)
    lum_b = np.zeros((valid.size, batches))
    chunk = chunk_size(chunk_pixels)

    def work(start):
        c = chunk_hits(scene, position, hit, prim, dist, d, start, chunk)
        out = np.repeat(c.emitted[:, None], batches, axis=1)
        for j in np.unique(c.block):
            m = np.flatnonzero(c.block == j)
            for b in range(batches):
                rng = stream(seed, "near", b, j)
                out[m, b] += _material_paths(scene, engine, gatherer, rng, c.point[m], c.normal[m], c.front[m],
                                             c.triangle[m], -d[c.index[m]], b, near_distance)
        return c.index, out

    run_chunks(work, range(0, hit.size, chunk), lum_b, workers, progress, t0, hit.size)
    openings = luminous_openings(scene, position, d, dist)
    return luminance_map_from_batches(
        projection, valid, lum_b, model=scene, estimator="double local estimate (materials)",
        openings=openings,
        extra={"samples": int(nodes["chains"]), "chains": int(nodes["chains"]),
               "nodes": int(nodes["position"].shape[0]), "near_field": "unbiased",
               "near_distance_m": near_distance, "near_field_biased": False,
               "nodes_per_pixel": int(nodes_per_pixel), "seed": int(seed),
               },
        elapsed=time.perf_counter() - t0, pose=(position, rotation))
