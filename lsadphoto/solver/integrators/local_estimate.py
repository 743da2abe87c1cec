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
from .._sampling import GroupStreams, stream
from ..engine import engine_for
from ..materials import KINDS, diffuse_fresnel_factor, shadow_transmittance
from ..sky import (GATHER_DISTANT_SAMPLES, background_luminance, distant_illuminance, distant_reflection,
                   distant_uniforms, stratified)
from ..store import KIND_COSINE, LsadStore
from .eye import (check_pose, chunk_hits, chunk_size, emitted_luminance,
                  luminance_map_from_batches, luminous_openings, near_step, primary_rays,
                  run_chunks, warn_odd_view)

__all__ = ["AUTO_NODES_PER_PIXEL", "FULL_GATHER_PAIRS", "NEAR_FIELD_TREATMENTS", "RAYS_PER_VERTEX",
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
    if store.materials:
        raise BadInputError("the store's scene has non-Lambertian materials: render it with "
                            "render_local_estimate_materials (lsadphoto.solver.render does)")
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
    warn_odd_view(scene, engine, prim, dist, lum_b, position, openings=openings, stacklevel=4)
    return luminance_map_from_batches(
        projection, valid, lum_b, model=store, estimator="double local estimate",
        openings=openings,
        extra={"samples": int(store.chains), "chains": int(store.chains),
               "nodes": int(store.nodes),
               "near_field": near_field, "near_distance_m": near_distance,
               "near_field_biased": near_field == "clamp",
               "nodes_per_pixel": "all" if nodes_per_pixel is None else int(nodes_per_pixel),
               "seed": int(seed), "simulation_seed": int(store.seed), "fresnel_rule": store.fresnel_rule},
        elapsed=time.perf_counter() - t0, pose=(position, rotation))




# --- scenes with glossy, specular and transmitting materials ---------------------------------

#: Delta (mirror or straight-through) bounces an eye path follows at most.
MAX_DELTA_BOUNCES = 16

#: BSDF-sampled rays per eye vertex (default of :func:`render_local_estimate_materials`):
#: in the rooms of benchmarks/accuracy_materials.py they carry most of the variance at 1
#: (docs/accuracy.md), and cost less than connections.
RAYS_PER_VERTEX = 16

#: Largest number of mirror triangles used as virtual sources (each costs a ray per
#: source-node connection; beyond it, light relayed by mirrors is left to sampled rays).
MAX_VIRTUAL_MIRRORS = 64

#: Delta vertices with both a reflected and a transmitted part (glass) at which an eye path
#: splits into both (at most 2**DELTA_SPLITS branches); beyond them it chooses one.
DELTA_SPLITS = 2

#: Point–node pairs evaluated at once by the material gather (bounds temporary memory:
#: about 40 arrays of this many float64 triples).
GATHER_PAIRS = 1 << 17


class _MaterialGatherer:
    """Node terms W·f_n(ω_in, ω_out)|cos θ_n|·f_p(ω_{p→n}, ω_o)|cos θ_p|/r²·T at points.

    ``nodes`` is the :class:`~lsadphoto.solver.store.LsadStore` of
    :func:`~lsadphoto.solver.chains.trace_material_chains`. Each point
    draws K nodes of its batch uniformly with replacement, K/2 from the source nodes (direct
    light) and K/2 from the surface nodes, each stratum scaled by its size over its draws
    (unbiased). T is the shadow transmittance (glass passes light straight through).

    What the connections estimate is a part of the reflection integral only: at the point
    they evaluate the full non-delta BSDF f_p towards point-luminaire nodes (which no ray can
    hit), its diffuse part towards surface nodes, whose own BSDF f_n they evaluate with its
    diffuse part only, the diffuse part plus the glossy part times the balance-heuristic
    weight w_L = K_s p_L/(K_s p_L + n_B p_B) towards emitter nodes (p_L: solid-angle density
    of emission points, K_s source draws, p_B the BSDF sampler's density, n_B the point's
    BSDF rays; Veach 1997, §9.2), the full f_p towards the images of source nodes behind
    planar mirrors (:meth:`_mirrored`), and nothing closer than ε; the rest — the glossy
    part over surfaces, the glossy light of the surfaces themselves, w_B = 1 − w_L of the
    glossy part over emitters, and the near field — is left to BSDF-sampled rays
    (:func:`_scattered`), whose weights carry exactly that complement, so the sum is
    unbiased while narrow lobes are sampled by rays and small luminaires by nodes. The
    terms are returned split by the point's diffuse and glossy part (the rays weight the
    two differently).
    """

    def __init__(self, scene, engine, sampler, nodes, *, per_pixel, near_distance, rays=1):
        self.scene, self.engine, self.sampler, self.nodes = scene, engine, sampler, nodes
        self.k = int(per_pixel)
        #: BSDF-sampled rays per eye vertex; the vertices they reach gather k/rays nodes
        self.rays = int(rays)
        self.k_secondary = max(1, self.k // self.rays)
        self.eps2 = near_distance ** 2
        self.n_b = nodes.chains / nodes.batches
        B = nodes.batches
        order = np.argsort(nodes.batch, kind="stable")
        bounds = np.searchsorted(nodes.batch[order], np.arange(B + 1))
        # emission-point density per unit area [m⁻²] of each area luminaire: (Φ_l/Φ)/A_l
        self.area_density = np.array([lum.flux / (sampler.total_flux * scene.areas[lum.triangles].sum())
                                      for lum in scene.area_luminaires])
        # the strata (0: source nodes, 1: surface nodes) of every batch, each as one array of
        # node indices in batch order with each batch's offset and size
        per_batch = [(idx[nodes.depth[idx] == 0], idx[nodes.depth[idx] > 0])
                     for idx in (order[bounds[b]:bounds[b + 1]] for b in range(B))]
        self.stratum_nodes = [np.concatenate([st[j] for st in per_batch]) for j in (0, 1)]
        self.stratum_size = np.array([[st[j].size for j in (0, 1)] for st in per_batch], np.int64)   # (B, 2)
        self.stratum_offset = np.cumsum(self.stratum_size, axis=0) - self.stratum_size
        self.strata = (self.stratum_size > 0).sum(axis=1)
        # each surface node's BSDF components towards its incoming direction (fixed per node)
        surface = np.flatnonzero(nodes.depth > 0)
        mu = np.clip(np.einsum("ij,ij->i", nodes.normal[surface], nodes.incoming[surface]), 1e-3, 1.0)
        self.node_parts = scene.bsdf.parts(self.scene.material[nodes.triangle[surface]], mu)
        self.node_row = np.full(nodes.nodes, -1, np.int64)
        self.node_row[surface] = np.arange(surface.size)
        # planar mirrors as virtual sources (Radiance's -dr 1): mirror triangles, when few
        kind = scene.bsdf.code[scene.material]
        mirrors = np.flatnonzero(kind == KINDS.index("mirror"))
        self.mirrors = mirrors if mirrors.size <= MAX_VIRTUAL_MIRRORS else mirrors[:0]
        self.virtual = np.zeros(len(scene.triangles) + 1, bool)   # index −1: no triangle
        self.virtual[self.mirrors] = True
        #: the smooth materials' rule for 1 − F(μ_i) (the store's)
        self.rule = nodes.fresnel_rule

    def draws(self, k):
        """Draws per point and stratum of each batch when a point gathers ``k`` nodes: k split
        over the batch's non-empty strata."""
        return np.where(self.strata > 0, np.maximum(1, k // np.maximum(self.strata, 1)), 0)

    def light_weight(self, batch, triangles, r2, cos_y, p_bsdf, primary):
        """Balance-heuristic weight w_L = K_s p_L/(K_s p_L + n_B p_B) of emission points on
        ``triangles`` at squared distance ``r2`` seen at cos θ_y, against the BSDF density
        (``batch``: the batch of each point; K_s its source draws, n_B its BSDF rays: those
        of an eye vertex where ``primary`` (bool or per point), else of a vertex reached by a
        sampled ray)."""
        k = np.where(primary, self.k, self.k_secondary)
        n_b = np.where(primary, self.rays, 1)
        strata = self.strata[batch]
        k_s = np.where(self.stratum_size[batch, 0] > 0, np.maximum(1, k // np.maximum(strata, 1)), 0)
        p_l = k_s * self.area_density[self.scene.emitter[triangles]] * r2 / np.maximum(cos_y, 1e-12)
        return p_l / np.maximum(p_l + n_b * p_bsdf, 1e-300)

    def gather(self, rng, x, n, wo, mat, batch, front, primary=True):
        """The connections' shares of the luminance at points ``x`` towards ``wo`` [cd·m⁻²]:
        ``(diffuse, glossy)``, the parts scattered by the points' diffuse and glossy components.

        ``batch``: the batch of each point, in non-decreasing order; ``rng`` the batches'
        :class:`~lsadphoto.solver._sampling.GroupStreams` (the node draws of each batch come
        from its own stream, as if the batches were gathered one at a time); ``primary``:
        whether the points are eye vertices (K nodes each) or reached by sampled rays (K/rays).
        """
        P = len(x)
        total = np.zeros((2, P))
        if not P:
            return total
        sky = 0.0
        if self.scene.distant_sources:  # next-event estimated: distant sources leave no nodes
            rng.counts = np.bincount(batch, minlength=len(rng.gens))
            u = stratified(rng.random((P, len(self.scene.distant_sources), GATHER_DISTANT_SAMPLES, 2)))
            sky = distant_reflection(self.scene, self.engine, x, n, wo, mat, u, fresnel_rule=self.rule)
        B = len(self.strata)
        draws = self.draws(self.k if primary else self.k_secondary)
        counts = np.bincount(batch, minlength=B)
        # the points' BSDF components towards wo, once per point (not per pair)
        parts = self.scene.bsdf.parts(mat, np.clip(np.einsum("ij,ij->i", n, wo), 1e-3, 1.0), front)
        for j in (0, 1):
            size = self.stratum_size[:, j]
            k_b = np.where(size > 0, draws, 0)
            rng.counts = np.where(size > 0, counts, 0)
            local = rng.integers(size, k_b)
            k_row = np.where(rng.counts[batch] > 0, k_b[batch], 0)
            owner = np.repeat(np.arange(P), k_row)
            pick = self.stratum_nodes[j][self.stratum_offset[batch[owner], j] + local]
            val = np.zeros((2, pick.size))
            for lo in range(0, pick.size, GATHER_PAIRS):
                sl = slice(lo, lo + GATHER_PAIRS)
                val[:, sl] = self._terms(pick[sl], owner[sl], x, n, wo, mat, batch, parts, primary)
            scale = np.where(k_row > 0, size[batch] / np.maximum(k_row, 1), 0.0)
            for c in (0, 1):
                total[c] += np.bincount(owner, weights=val[c], minlength=P) * scale
        return total / self.n_b + sky

    def _terms(self, pick, owner, x, n, wo, mat, batch, parts, primary):
        """Connection terms f_p·|cos θ_p|·I_n/r²·T of the pairs (point ``owner``, node ``pick``),
        shape (2, pairs): with the point's diffuse and glossy part of f_p; ``parts``: the
        points' :meth:`~lsadphoto.solver.materials.MaterialTable.parts`. At surface nodes
        I_n = W·f_n,diffuse·|cos θ_n| (their glossy part is left to the rays, see
        :func:`_scattered`), so only the diffuse part of f_p connects to them."""
        nd = self.nodes
        bsdf = self.scene.bsdf
        eps = self.engine.epsilon
        y, ny = nd.position[pick], nd.normal[pick]
        v = y - x[owner]
        r2 = np.einsum("ij,ij->i", v, v)
        w = v / np.sqrt(np.maximum(r2, 1e-300))[:, None]
        np_ = n[owner]
        cos_p = np.einsum("ij,ij->i", w, np_)
        kind = nd.kind[pick]
        surface = nd.depth[pick] > 0
        # the light of source nodes arrives straight from their luminaire (a Radiance light
        # source there, or not), that of surface nodes not
        direct = True
        if self.rule != "reciprocal":
            direct = nd.direct[pick] & ~surface
            area = np.flatnonzero(direct & (kind == KIND_COSINE))
            direct[area] = self.scene.light_source_at(self.scene.emitter[nd.triangle[pick[area]]], x[owner[area]])
        f_d, f_g = bsdf.evaluate(mat[owner], np_, wo[owner], w, split=True,
                                 parts={key: v[owner] for key, v in parts.items()}, rule=self.rule, direct=direct)
        cos_n = -np.einsum("ij,ij->i", w, ny)
        f_pg = np.where(kind == KIND_COSINE, 0.0, f_g)
        emitter = np.flatnonzero((kind == KIND_COSINE) & ~surface & (f_g > 0))
        if emitter.size:
            p_b = bsdf.pdf(mat[owner[emitter]], np_[emitter], wo[owner[emitter]], w[emitter],
                           parts={key: v[owner[emitter]] for key, v in parts.items()})
            f_pg[emitter] = f_g[emitter] * self.light_weight(
                batch[owner[emitter]], nd.triangle[pick[emitter]], r2[emitter], np.maximum(cos_n[emitter], 0.0),
                p_b, primary)
        intensity = np.where(kind == KIND_COSINE, nd.coefficient[pick] * np.maximum(cos_n, 0.0), 0.0)
        if surface.any():
            s = np.flatnonzero(surface)
            m_n = self.scene.material[nd.triangle[pick[s]]]
            rows = self.node_row[pick[s]]
            f_n, _ = bsdf.evaluate(m_n, ny[s], nd.incoming[pick[s]], -w[s], split=True,
                                   parts={key: v[rows] for key, v in self.node_parts.items()},
                                   rule=self.rule, direct=nd.direct[pick[s]], adjoint=True)
            intensity[s] = nd.coefficient[pick[s]] * f_n * np.abs(cos_n[s])
        point = np.flatnonzero(kind != KIND_COSINE)
        if point.size:
            intensity[point] = nd.coefficient[pick[point]] * self.sampler.point_intensity(
                nd.luminaire[pick[point]], -w[point])
        near = (kind == KIND_COSINE) & (r2 < self.eps2)
        geometry = np.where(near | (r2 <= 0), 0.0, np.abs(cos_p) * intensity / np.maximum(r2, 1e-300))
        val = np.stack([f_d * geometry, f_pg * geometry])
        ok = np.flatnonzero((val[0] > 0) | (val[1] > 0))
        if ok.size:
            side_p = np.sign(cos_p[ok])[:, None]
            side_n = np.where(surface[ok], np.sign(cos_n[ok]), 1.0)[:, None]
            target = y[ok] + eps * side_n * ny[ok] * (kind[ok] == KIND_COSINE)[:, None]
            val[:, ok] *= shadow_transmittance(self.scene, self.engine, x[owner[ok]] + eps * side_p * np_[ok],
                                               target)
        source = np.flatnonzero(~surface)
        for t in self.mirrors if source.size else ():
            val[:, source] += self._mirrored(t, pick[source], owner[source], x, n, wo, mat, parts)
        return val

    def _mirrored(self, t, pick, owner, x, n, wo, mat, parts):
        """Terms (2, pairs) of source nodes ``pick`` seen from points ``owner`` in mirror
        triangle ``t``: connected to the node's image y' behind the mirror's plane, through
        the point q where x→y' crosses the triangle (nothing in between, q→y unobstructed),
        R·f_p(ω_{x→q})·|cos θ_p|·I_y(ω_{y→q})/|y' − x|² (Radiance's virtual sources). The
        sampled rays count no emission reached by one mirror reflection from a non-delta
        vertex (:func:`_scattered`), so each path is counted once."""
        scene, nd, eps = self.scene, self.nodes, self.engine.epsilon
        out = np.zeros((2, pick.size))
        p0, nm = scene.triangles[t, 0], scene.normals[t]
        y, xp = nd.position[pick], x[owner]
        hy, hx = (y - p0) @ nm, (xp - p0) @ nm
        live = np.flatnonzero((hy > 0) & (hx > 0))             # both in front of the mirror
        if not live.size:
            return out
        image = y[live] - 2 * hy[live, None] * nm
        v = image - xp[live]
        length = np.sqrt(np.einsum("ij,ij->i", v, v))
        w = v / length[:, None]
        np_ = n[owner[live]]
        cos_p = np.einsum("ij,ij->i", w, np_)
        origin = xp[live] + eps * np.sign(cos_p)[:, None] * np_
        prim, dist = self.engine.closest_hit(origin, w)
        crossed = np.flatnonzero((prim == t) & (dist < length))
        if not crossed.size:
            return out
        live, w, cos_p, length, np_ = live[crossed], w[crossed], cos_p[crossed], length[crossed], np_[crossed]
        q = origin[crossed] + dist[crossed, None] * w
        to_q = q - y[live]
        to_q /= np.linalg.norm(to_q, axis=1, keepdims=True)
        k = pick[live]
        is_cos = nd.kind[k] == KIND_COSINE
        intensity = np.where(is_cos, nd.coefficient[k] * np.maximum(np.einsum("ij,ij->i", to_q, nd.normal[k]),
                                                                       0.0), 0.0)
        point = np.flatnonzero(~is_cos)
        if point.size:
            intensity[point] = nd.coefficient[k[point]] * self.sampler.point_intensity(
                nd.luminaire[k[point]], to_q[point])
        o = owner[live]
        reflectance = scene.bsdf.delta(np.full(live.size, scene.material[t]), np.abs(w @ nm),
                                       np.ones(live.size, bool))[0]
        geometry = reflectance * np.abs(cos_p) * intensity / (length * length)
        geometry *= self.engine.visible(q + eps * nm, y[live] + eps * nd.normal[k] * is_cos[:, None])
        # light by a mirror is not straight from the source (as the path tracer counts it)
        f_d, f_g = scene.bsdf.evaluate(mat[o], np_, wo[o], w, split=True,
                                       parts={key: value[o] for key, value in parts.items()},
                                       rule=self.rule, direct=False)
        out[:, live] = np.stack([f_d * geometry, f_g * geometry])
        return out


def _uniforms(rng, batch, columns):
    """Uniforms (len(batch), columns) for rows of non-decreasing ``batch``, each batch's from
    its own stream."""
    rng.counts = np.bincount(batch, minlength=len(rng.gens))
    return rng.random((len(batch), columns))


def _material_paths(scene, engine, gatherer, rng, x, n, front, tri, wo, batch, near_distance):
    """Per-path luminance [cd·m⁻²] towards ``wo`` at the primary points (emission excluded):
    the eye path followed through delta surfaces, and at each vertex the connections plus
    the BSDF-sampled rays of the rest (:func:`_scattered`). Rows are ordered by ``batch``
    (each path's batch); ``rng``: the batches' streams.

    At a delta vertex the path goes on with weight R + T (no roulette): in the reflected or
    the transmitted direction, chosen in proportion to R and T, except at the first
    :data:`DELTA_SPLITS` vertices that have both (glass), where it splits into both, of
    weights R and T — the luminaire or sky seen through a pane and its reflection in the
    pane then cost no variance."""
    bsdf = scene.bsdf
    eps = engine.epsilon
    total = np.zeros(len(x))
    idx = np.arange(len(x))
    weight = np.ones(len(x))
    for level in range(MAX_DELTA_BOUNCES + 1):
        if not idx.size:
            break
        mat = scene.material[tri]
        value = gatherer.gather(rng, x, n, wo, mat, batch, front).sum(axis=0)
        # the rays of the rest, gatherer.rays per vertex, each counted 1/rays
        rows = np.repeat(np.arange(idx.size), gatherer.rays)
        part = _scattered(scene, engine, gatherer, rng, x[rows], n[rows], np.asarray(front)[rows], wo[rows],
                          mat[rows], batch[rows], near_distance)
        value += np.bincount(rows, weights=part, minlength=idx.size) / gatherer.rays
        np.add.at(total, idx, weight * value)
        # continue through the delta parts
        mu = np.einsum("ij,ij->i", n, wo)
        r, t = bsdf.delta(mat, mu, front)
        u = _uniforms(rng, batch, 1)[:, 0]
        split = (r > 0) & (t > 0) & (level < DELTA_SPLITS)
        count = np.where(split, 2, (r + t > 0).astype(np.int64))
        parent = np.repeat(np.arange(idx.size), count)
        first_child = np.r_[True, parent[1:] != parent[:-1]] if parent.size else parent.astype(bool)
        refl = np.where(split[parent], first_child, u[parent] * (r + t)[parent] < r[parent])
        weight = weight[parent] * np.where(split[parent], np.where(refl, r[parent], t[parent]), (r + t)[parent])
        idx, x, n, batch, wo, mu = idx[parent], x[parent], n[parent], batch[parent], wo[parent], mu[parent]
        d = np.where(refl[:, None], 2 * mu[:, None] * n - wo, -wo)
        side = np.where(refl, 1.0, -1.0)[:, None]
        if not idx.size:
            break
        prim, dist = engine.closest_hit(x + eps * side * n, d)
        hit = prim >= 0
        if scene.distant_sources:  # the sky seen through glass or in a mirror
            np.add.at(total, idx[~hit], weight[~hit] * background_luminance(scene, d[~hit]))
        idx, x, n, d, side, prim, dist, batch, weight = (idx[hit], x[hit], n[hit], d[hit], side[hit], prim[hit],
                                                         dist[hit], batch[hit], weight[hit])
        x = x + eps * side * n + dist[:, None] * d
        n, front = scene.facing_normals(prim, d)
        wo, tri = -d, prim
        np.add.at(total, idx, weight * emitted_luminance(scene, prim, wo))
    return total


def _scattered(scene, engine, gatherer, rng, x, n, front, wo, mat, batch, near_distance):
    """What the connections leave out, by BSDF-sampled rays.

    At each vertex one ray is drawn from the BSDF mixture (weight w = f·|μ_i|/p, or R/P_R,
    T/P_T for a delta; at the first vertex the eye path follows the deltas itself). The
    luminance leaving a hit splits into its diffuse part L_D (what the hit's diffuse
    component scatters) and the rest, L_G (glossy lobes and deltas). A path carries two
    weights: β for L_D and β_f for L_G. From a vertex of weights (β, β_f) with BSDF parts
    f_d, f_g, a ray reaching a hit at distance r gets

    * β' = (β f_d [r < ε] + β_f f_g)·|μ|/p: the connections to surface nodes (beyond ε, with
      the nodes' diffuse part only) cover β f_d L_D;
    * β_f' = (β f_d + β_f f_g)·|μ|/p: no connection covers the glossy or delta light of the hit;
    * emission: (β f_d + β_f f_g)·|μ|/p closer than ε, else β_f f_g w_B·|μ|/p, w_B the
      balance-heuristic complement of the emitter connections.

    Behind straight-through transmissions, which connections pass with their transmittance,
    β' and the emission keep these forms, with r the distance along the path from the
    last non-delta vertex and the transmissions' weights as factors.

    A delta reflection turns β_f into the weight of everything beyond it (no connection
    reaches through it); a straight-through transmission keeps both. Russian roulette
    min(1, w) after the first ray. Each hit adds β·(diffuse share of its connections) +
    β_f·(glossy share).

    Under the ``"radiance"`` rule (the store's, :data:`~lsadphoto.solver.materials.FRESNEL_RULES`)
    the rays carry the smooth materials' diffuse part without 1 − F(μ_i), and emission of a
    Radiance light source reached from a non-delta vertex (through straight-through
    transmissions only; within the source's radius of that vertex, ``x_v``) takes that vertex's
    factor 1 − F(μ_i), ``g_v``.
    """
    bsdf = scene.bsdf
    rule = gatherer.rule
    eps = engine.epsilon
    total = np.zeros(len(x))
    idx = np.arange(len(x))
    beta = np.ones(len(x))
    beta_f = np.ones(len(x))
    # since the last non-delta vertex (for emission behind straight-through transmissions):
    # emission weights near / far, that vertex's BSDF density, whether it was an eye vertex,
    # the distance travelled, and whether only straight-through transmissions followed it
    e_near, e_far, pdf_v, primary_v, travelled = (np.zeros(len(x)) for _ in range(5))
    through = np.zeros(len(x), bool)
    # the triangle of each vertex (−1 at the first), and whether a non-delta ray reached it
    tri = np.full(len(x), -1, np.int64)
    arrived = np.zeros(len(x), bool)
    # weight of the distant sources' radiance, which the connections' next-event estimate
    # covers except after delta reflections (and straight transmissions after those)
    beta_s = np.zeros(len(x))
    g_v, x_v = np.ones(len(x)), x.copy()
    first = True
    while idx.size:
        u = _uniforms(rng, batch, 4)
        wi, w, delta, _ = bsdf.sample(mat, n, wo, u[:, :3], front, rule=rule, direct=False)
        keep = (w > 0) & ~(delta & first)
        (idx, beta, beta_f, beta_s, x, n, wi, w, delta, wo, mat, u, batch, e_near, e_far, pdf_v, primary_v,
         travelled, through, tri, arrived, g_v, x_v) = (a[keep] for a in (
             idx, beta, beta_f, beta_s, x, n, wi, w, delta, wo, mat, u, batch, e_near, e_far, pdf_v, primary_v,
             travelled, through, tri, arrived, g_v, x_v))
        front = np.asarray(front)[keep]
        if not idx.size:
            break
        side = np.sign(np.einsum("ij,ij->i", wi, n))[:, None]
        prim, dist = engine.closest_hit(x + eps * side * n, wi)
        reflected = delta & (side[:, 0] > 0)
        # weights of the hit's diffuse (b) and other (bf) luminance after a delta
        b = np.where(reflected, beta_f, beta) * w
        bf = beta_f * w
        # … and of its emission: all of it after a delta reflection
        be = b.copy()
        through = through & delta & ~reflected
        e_near, e_far = e_near * w, e_far * w
        travelled = travelled + np.where(np.isfinite(dist), dist, 0.0)
        nd = np.flatnonzero(~delta)
        if nd.size:
            f_d, f_g = bsdf.evaluate(mat[nd], n[nd], wo[nd], wi[nd], split=True, rule=rule, direct=False)
            pdf = bsdf.pdf(mat[nd], n[nd], wo[nd], wi[nd], front[nd])
            mu = np.abs(np.einsum("ij,ij->i", n[nd], wi[nd]))
            if rule != "reciprocal":
                g_v[nd] = diffuse_fresnel_factor(mu, bsdf.fresnel[mat[nd]], rule=rule, direct=True)
                x_v[nd] = x[nd]
            near = dist[nd] < near_distance
            scale = np.where(pdf > 0, mu / np.maximum(pdf, 1e-300), 0.0)
            b[nd] = (beta[nd] * f_d * near + beta_f[nd] * f_g) * scale
            bf[nd] = (beta[nd] * f_d + beta_f[nd] * f_g) * scale
            e_near[nd], e_far[nd] = bf[nd], beta_f[nd] * f_g * scale
            pdf_v[nd], primary_v[nd], travelled[nd], through[nd] = pdf, first, dist[nd], True
        # where the path left a non-delta vertex and went straight on since, the connections
        # from that vertex reach the hit through the transmissions: its diffuse light is
        # theirs unless it lies closer than ε along the path (not only the first segment) …
        b[through] = np.where(travelled[through] < near_distance, e_near[through], e_far[through])
        # … and so is its emission, beyond ε in the balance-heuristic share w_L
        lit = np.flatnonzero(through & (prim >= 0))
        if lit.size:
            lit = lit[scene.emitter[prim[lit]] >= 0]
        if lit.size:
            cos_y = np.abs(np.einsum("ij,ij->i", scene.normals[prim[lit]], wi[lit]))
            w_b = 1 - gatherer.light_weight(batch[lit], prim[lit], travelled[lit] ** 2, cos_y, pdf_v[lit],
                                            primary_v[lit].astype(bool))
            be[lit] = np.where(travelled[lit] < near_distance, e_near[lit], e_far[lit] * w_b)
        # emission one mirror reflection away from a non-delta vertex: that vertex's virtual sources
        be[reflected & arrived & gatherer.virtual[tri]] = 0.0
        hit = prim >= 0
        if rule != "reciprocal":
            straight = np.flatnonzero(through & hit)
            straight = straight[scene.emitter[prim[straight]] >= 0]
            straight = straight[scene.light_source_at(scene.emitter[prim[straight]], x_v[straight])]
            be[straight] *= g_v[straight]
        if hit.any():
            total[idx[hit]] += be[hit] * emitted_luminance(scene, prim[hit], -wi[hit])
        bs = np.where(delta, np.where(reflected, beta_f, beta_s), 0.0) * w
        away = np.flatnonzero(~hit & (bs > 0))
        if away.size and scene.distant_sources:
            total[idx[away]] += bs[away] * background_luminance(scene, wi[away])
        q = np.ones(idx.size) if first else np.minimum(w, 1.0)
        go = hit & ((b > 0) | (bf > 0)) & (u[:, 3] < q)
        (idx, beta, beta_f, beta_s, x, n, wi, side, prim, dist, batch, e_near, e_far, pdf_v, primary_v, travelled,
         through, arrived, g_v, x_v) = (a[go] for a in (idx, b / q, bf / q, bs / q, x, n, wi, side, prim, dist,
                                                        batch, e_near / q, e_far / q, pdf_v, primary_v, travelled,
                                                        through, ~delta, g_v, x_v))
        tri = prim
        if not idx.size:
            break
        x = x + eps * side * n + dist[:, None] * wi
        n, front = scene.facing_normals(prim, wi)
        wo, mat = -wi, scene.material[prim]
        diffuse, glossy = gatherer.gather(rng, x, n, wo, mat, batch, front, primary=False)
        total[idx] += beta * diffuse + beta_f * glossy
        first = False
    return total


def render_local_estimate_materials(store, projection, *, position, rotation, seed=0,
                                    nodes_per_pixel=AUTO_NODES_PER_PIXEL, rays_per_vertex=RAYS_PER_VERTEX,
                                    near_distance=None, chunk_pixels=2048, workers=1, progress=None):
    """Luminance map [cd·m⁻²] of a view of a scene with glossy, specular or transmitting
    materials by the double local estimate, from the store of its light chains.

    ``store``: an :class:`~lsadphoto.solver.store.LsadStore` of such a scene
    (:func:`~lsadphoto.solver.simulate`, whose chains sample the BSDFs:
    :func:`~lsadphoto.solver.chains.trace_material_chains`); any number of views render from
    one store. For each pixel and batch the eye path is
    followed through perfectly specular surfaces (mirror, glass, smooth plastic's mirror part:
    :func:`_material_paths`) and at every vertex the
    non-delta BSDF is evaluated towards the eye and connected to ``nodes_per_pixel`` chain
    nodes (:class:`_MaterialGatherer`), with the near field (nodes closer than
    ``near_distance``, default 1 % of the scene size) replaced by BSDF-sampled rays:
    ``rays_per_vertex`` of them at each eye vertex (each counted 1/n, the balance heuristic
    with n times the BSDF density), the vertices they reach gathering ``nodes_per_pixel`` /
    ``rays_per_vertex`` nodes. Connections pass straight-through transmitters (glass) with
    their transmittance, and reach source nodes through planar mirrors as virtual sources
    (:data:`MAX_VIRTUAL_MIRRORS` mirror triangles at most); connections to surface nodes use
    the nodes' diffuse part. The rest — glossy light of surfaces, light after other delta
    reflections (the reflection of a luminaire in glass on a floor), the near field — comes
    from the sampled rays (:func:`_scattered`). ``seed`` keys the eye paths' random streams
    (rendering with the store's own seed gives the map of a render of the scene itself).

    References
    ----------
    Marchuk et al. (1980), §3.3 (local estimates). Veach (1997), §9.2 (multiple importance
    sampling), §10 (connections and specular vertices). Ward, G. J. (1994). The RADIANCE
    lighting simulation and rendering system. *SIGGRAPH '94*, 459–472 (virtual light sources
    for planar mirrors).
    """
    from ..chains import EmissionSampler

    if not isinstance(store, LsadStore) or not store.materials:
        raise BadInputError("render_local_estimate_materials needs the LsadStore of a scene with non-Lambertian "
                            "materials")
    scene, batches = store.scene, store.batches
    position, rotation = check_pose(position, rotation)
    near_distance = float(RELATIVE_NEAR_DISTANCE * scene.size if near_distance is None else near_distance)
    if not near_distance > 0:
        raise BadInputError(f"near_distance must be positive, got {near_distance!r}")
    for name, value in (("nodes_per_pixel", nodes_per_pixel), ("rays_per_vertex", rays_per_vertex)):
        if isinstance(value, (str, bool)) or int(value) != value or value < 1:
            raise BadInputError(f"{name} must be a positive integer, got {value!r}")
    t0 = time.perf_counter()
    engine = engine_for(scene)
    sampler = EmissionSampler(scene)
    gatherer = _MaterialGatherer(scene, engine, sampler, store, per_pixel=nodes_per_pixel,
                                 near_distance=near_distance, rays=rays_per_vertex)
    valid, prim, dist, d = primary_rays(scene, engine, projection, position, rotation)
    hit = np.flatnonzero(prim >= 0)
    lum_b = np.zeros((valid.size, batches))
    chunk = chunk_size(chunk_pixels)

    def work(start):
        c = chunk_hits(scene, position, hit, prim, dist, d, start, chunk)
        out = np.repeat(c.emitted[:, None], batches, axis=1)
        for j in np.unique(c.block):
            # the block's pixels in all batches at once, batch-major, each batch from its own stream
            m = np.flatnonzero(c.block == j)
            rows = np.tile(m, batches)
            batch = np.repeat(np.arange(batches), m.size)
            rng = GroupStreams([stream(seed, "near", b, j) for b in range(batches)])
            value = _material_paths(scene, engine, gatherer, rng, c.point[rows], c.normal[rows], c.front[rows],
                                    c.triangle[rows], -d[c.index[rows]], batch, near_distance)
            out[m] += value.reshape(batches, m.size).T
        return c.index, out

    run_chunks(work, range(0, hit.size, chunk), lum_b, workers, progress, t0, hit.size)
    openings = luminous_openings(scene, position, d, dist)
    return luminance_map_from_batches(
        projection, valid, lum_b, model=scene, estimator="double local estimate (materials)",
        openings=openings,
        extra={"samples": int(store.chains), "chains": int(store.chains),
               "nodes": int(store.nodes), "near_field": "unbiased", "fresnel_rule": store.fresnel_rule,
               "near_distance_m": near_distance, "near_field_biased": False,
               "nodes_per_pixel": int(nodes_per_pixel), "rays_per_vertex": int(rays_per_vertex),
               "seed": int(seed), "simulation_seed": int(store.seed)},
        elapsed=time.perf_counter() - t0, pose=(position, rotation))
