"""Rendering luminance maps: the double local estimate from a store, and a path tracer.

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
Methods 2004*, 245–257. Veach, E. (1997). *Robust Monte Carlo Methods for Light Transport
Simulation*, PhD thesis, Stanford, ch. 10 (bidirectional path tracing; the path tracer
with next-event estimation used for cross-checks).
"""

import math
import time
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .._provenance import build_provenance
from .._validation import check_choice
from ..errors import BadInputError, SolverWarning
from ..geometry.base import Projection
from ..luminance_map import LuminanceMap
from ._sampling import cosine_directions, stream
from .chains import EmissionSampler
from .engine import RayEngine
from .scene import Scene
from .store import KIND_COSINE, KIND_POINT, LsadStore

__all__ = ["AUTO_NODES_PER_PIXEL", "ESTIMATORS", "FULL_GATHER_PAIRS", "NEAR_FIELD_TREATMENTS",
           "RELATIVE_NEAR_DISTANCE", "SolverWarning", "render", "render_path_traced"]

NEAR_FIELD_TREATMENTS = ("unbiased", "clamp")
#: Estimators of a view: "local", the per-pixel double local estimate (:func:`render`, the
#: unbiased reference); "cache", direct light per pixel and indirect light interpolated from
#: the store's surface cache (:func:`~lsadphoto.solver.surface_cache.render_cached`).
ESTIMATORS = ("local", "cache")

#: Default near-field distance ε as a fraction of the scene's bounding-box diagonal.
RELATIVE_NEAR_DISTANCE = 0.01

#: "auto" gathers every node while pixels × nodes stays below this (≈ 5–20 s on 2 cores) …
FULL_GATHER_PAIRS = 20_000_000
#: … and this many nodes per pixel and batch above it.
AUTO_NODES_PER_PIXEL = 32

#: Nodes per gather block (fixed, so sums do not depend on the pixel chunk size). With the
#: default 2048-pixel chunks the dense pair arrays of a block take ≈ 8 MB each.
NODE_BLOCK = 512

#: Pixels per random-stream block of a render; pixel chunks are whole blocks.
PIXEL_BLOCK = 256


# --- helpers ---------------------------------------------------------------------------------

def _engine_for(scene):
    eng = getattr(scene, "_engine", None)
    if eng is None:
        eng = RayEngine(scene.triangles)
        scene._engine = eng
    return eng


def _check_pose(position, rotation):
    try:
        pos = np.asarray(position, dtype=float)
        rot = np.asarray(rotation, dtype=float)
    except (TypeError, ValueError):
        raise BadInputError("position must be 3 numbers and rotation a 3×3 matrix") from None
    if pos.shape != (3,) or not np.all(np.isfinite(pos)):
        raise BadInputError(f"position must be 3 finite numbers, got {position!r}")
    if rot.shape != (3, 3) or not np.allclose(rot.T @ rot, np.eye(3), atol=1e-6):
        raise BadInputError("rotation must be a 3×3 orthonormal camera-to-world matrix "
                            "(see camera_to_world)")
    return pos, rot


def _primary(scene, engine, projection, position, rotation):
    """Valid pixel indices, their hit triangle (−1: miss), distance [m] and world direction."""
    if not isinstance(projection, Projection):
        raise BadInputError("projection must be a lsadphoto.geometry Projection")
    rows, cols = projection.pixel_grid()
    d_cam = projection.directions(rows, cols).reshape(-1, 3)
    valid = np.flatnonzero(np.all(np.isfinite(d_cam), axis=1))
    d = d_cam[valid] @ rotation.T
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    prim, dist = engine.closest_hit(np.broadcast_to(position, d.shape), d)
    return valid, prim, dist, d


#: Primary hits closer than this many ray offsets count as "the eye lies on a surface".
_ON_SURFACE_OFFSETS = 10
#: … and the view is flagged when more than this fraction of its hits are that close.
_ON_SURFACE_FRACTION = 0.01


def _check_view(scene, engine, prim, dist, lum_b, position):
    """Warn about views that are legal but probably wrong (an eye on or in a wall).

    An eye within a few ray offsets of a surface (in the plane of a wall) makes the rays
    that start there ambiguous in float32; an eye outside a closed room or inside a solid
    sees only surfaces that no light reaches, so the whole view is black.
    """
    hit = prim >= 0
    close = hit & (dist < _ON_SURFACE_OFFSETS * engine.epsilon)
    where = f"eye at ({', '.join(f'{v:g}' for v in position)}) m"
    if hit.any() and close.sum() > _ON_SURFACE_FRACTION * hit.sum():
        warnings.warn(f"{where} lies on a surface ({close.sum()} of {hit.sum()} primary rays "
                      f"hit within {_ON_SURFACE_OFFSETS * engine.epsilon:.2g} m): move it into "
                      "the room", SolverWarning, stacklevel=3)
    elif (scene.total_flux > 0 and np.any(scene.triangle_reflectance[prim[hit]] > 0)
          and not np.any(lum_b > 0)):
        # (a view that hits nothing, e.g. out of an open model into the sky, or only black
        # surfaces, is legal and black)
        warnings.warn(f"{where} sees surfaces but no light at all: is it outside the room "
                      "or inside a solid?", SolverWarning, stacklevel=3)


def _emitted(scene, prim, towards):
    """Luminance [cd·m⁻²] that triangles ``prim`` emit towards unit directions ``towards``."""
    out = np.zeros(len(prim))
    em = scene.emitter[prim]
    for k, lum in enumerate(scene.area_luminaires):
        m = em == k
        if m.any():
            front = np.einsum("ij,ij->i", scene.normals[prim[m]], towards[m]) > 0
            out[m] = np.where(front, lum.luminance(scene), 0.0)
    return out


def _luminous_openings(scene, position, d, dist):
    """Luminance [cd·m⁻²] of point luminaires' luminous rectangles seen along rays.

    For a luminaire with a rectangle of area A (extent > 0) whose plane (normal = nadir
    axis) the ray crosses inside the rectangle and before its surface hit, the opening's
    luminance towards the eye is L = I(−d̂)/(A·|cos γ|), the radiance of emission points
    uniform on the rectangle that each emit I/A (the chains' emission model). NaN where
    no opening is seen (or it emits nothing towards the eye); the nearest opening wins.
    """
    out = np.full(len(d), np.nan)
    best = np.asarray(dist, float).copy()
    for lum in scene.point_luminaires:
        length, width = lum.extent
        if not (length > 0 and width > 0):
            continue
        nadir = lum.frame[2]
        denom = d @ nadir
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((lum.position - position) @ nadir) / denom
        ok = np.isfinite(t) & (t > 0) & (t < best) & (np.abs(denom) > 1e-6)
        if not ok.any():
            continue
        hit = position + t[ok, None] * d[ok] - lum.position
        inside = (np.abs(hit @ lum.frame[0]) <= length / 2) & (np.abs(hit @ lum.frame[1]) <= width / 2)
        idx = np.flatnonzero(ok)[inside]
        if idx.size == 0:
            continue
        lum_value = lum.intensity(-d[idx]) / (length * width * np.abs(denom[idx]))
        seen = lum_value > 0
        idx = idx[seen]
        out[idx] = lum_value[seen]
        best[idx] = t[idx]
    return out


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


def _near_step(scene, engine, x, nx, u, near_distance, rho_prev):
    """One bounce of near-field paths from points ``x`` (normals ``nx``), uniforms ``u`` (k, 3).

    A cosine-distributed ray from each point; a path goes on where its first hit lies closer
    than ``near_distance`` and, after the first bounce (``rho_prev`` given), it survives
    Russian roulette with q = ρ of the vertex it leaves (weight ρ/q = 1). Returns the mask
    of the paths that go on and, for those, the hit point, its facing normal, the ray
    direction and the triangle.
    """
    d = cosine_directions(nx, u[:, :2])
    prim, dist = engine.closest_hit(x + engine.epsilon * nx, d)
    near = (prim >= 0) & (dist < near_distance)
    if rho_prev is not None:
        near &= u[:, 2] < rho_prev
    x, nx, d, prim, dist = x[near], nx[near], d[near], prim[near], dist[near]
    y = x + engine.epsilon * nx + dist[:, None] * d
    ny, _ = scene.facing_normals(prim, d)
    return near, y, ny, d, prim


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
        near, y, ny, d, prim = _near_step(scene, engine, x, nx, u, near_distance, rho_prev)
        active = active[near]
        throughput = throughput[near]
        if not active.size:
            break
        blocks_now = block_ids[active]
        rho_y = scene.triangle_reflectance[prim]
        value = _emitted(scene, prim, -d)
        has_rho = rho_y > 0
        if has_rho.any():
            e = gatherer.gather(y[has_rho], ny[has_rho], batch, blocks_now[has_rho])
            value[has_rho] += rho_y[has_rho] / math.pi * e / n_b
        total[active] += throughput * value
        x, nx, rho_prev = y, ny, rho_y
    return total


# --- double local estimate -------------------------------------------------------------------

def render(store_or_scene, projection, *, position, rotation, samples=None, seed=0,
           near_field=None, near_distance=None, nodes_per_pixel="auto", chunk_pixels=2048,
           workers=1, progress=None):
    """Luminance map of a view by the double local estimate [cd·m⁻²].

    Parameters
    ----------
    store_or_scene : LsadStore or Scene
        A simulated store (any number of views render from one simulation), or a scene,
        which is simulated first with ``samples`` chains and ``seed``.
    projection : Projection
        Camera model (pixel → direction in the camera frame: x right, y down, z forward).
    position : array_like, shape (3,)
        Eye position [m].
    rotation : array_like, shape (3, 3)
        Camera-to-world rotation (see :func:`~lsadphoto.solver.camera_to_world`).
    samples : int, optional
        Light chains to simulate when given a scene (ignored for a store).
    seed : int
        Seed of the near-field rays (and of the simulation when given a scene).
    near_field : {"unbiased", "clamp"}, optional
        Near-field treatment (module docstring); default the store's.
    near_distance : float, optional
        ε [m]; default :data:`RELATIVE_NEAR_DISTANCE` × scene size.
    nodes_per_pixel : int, "all" or "auto"
        An integer K connects each visible point to K nodes per batch, drawn uniformly
        (stratified: source and surface nodes) and scaled by count/K — unbiased, render
        cost ∝ pixels × K × batches. ``"all"`` (or None) connects every node: the full
        double local estimate, cost ∝ pixels × nodes. ``"auto"`` (default): all nodes when
        pixels × nodes ≤ :data:`FULL_GATHER_PAIRS`, else :data:`AUTO_NODES_PER_PIXEL`.
    chunk_pixels : int
        Pixels per processing chunk (rounded up to a multiple of :data:`PIXEL_BLOCK`);
        bounds memory, never changes the result.
    workers : int
        Threads working on chunks at once (numpy and Embree release the GIL for most of
        the work); never changes the result.
    progress : callable, optional
        ``progress(done_fraction, eta_s)``.

    Returns
    -------
    LuminanceMap
        Luminance [cd·m⁻²] (NaN outside the projection's valid region; 0 where a ray
        leaves an open scene), ``uncertainty`` the per-pixel standard error, and
        ``provenance`` with estimator, samples, seed, near-field treatment and the
        achieved relative standard error of the field-mean luminance.

    Warns
    -----
    SolverWarning
        When the eye lies on a surface (more than 1 % of the primary rays hit within 10 ray
        offsets), or when it sees lit-able surfaces but no light at all (an eye outside a
        closed room or inside a solid). A view that hits nothing (out of an open model) or
        only black surfaces is legal and silent.

    References
    ----------
    Budak, Zheltov & Kalakutsky (2012); Marchuk et al. (1980); Kollig & Keller (2004).

    Examples
    --------
    A 100 cd isotropic point 2 m above a grey (ρ = 0.5) disc, seen straight down:
    L = ρ·I/(π d²) = 0.5 · 100/(4π) cd·m⁻².

    >>> from lsadphoto.geometry import PinholeProjection
    >>> from lsadphoto.solver import camera_to_world, scene_from_dict, simulate
    >>> scene = scene_from_dict({
    ...     "materials": {"grey": {"reflectance": 0.5}},
    ...     "surfaces": [{"type": "disc", "centre": [0, 0, 0], "normal": [0, 0, 1],
    ...                   "radius": 5, "material": "grey"}],
    ...     "luminaires": [{"type": "point", "position": [0, 0, 2], "intensity": 100}]})
    >>> store = simulate(scene, samples=256)
    >>> lmap = render(store, PinholeProjection(100, 100, 0, 0, 1, 1), position=[0, 0, 3],
    ...               rotation=camera_to_world([0, 0, -1], [0, 1, 0]))
    >>> round(float(lmap.luminance[0, 0]), 4), lmap.provenance["near_field"]
    (3.9789, 'unbiased')
    """
    if isinstance(store_or_scene, Scene):
        from .simulation import simulate

        store = simulate(store_or_scene, samples=samples, seed=seed,
                         near_field=near_field or "unbiased")
    elif isinstance(store_or_scene, LsadStore):
        store = store_or_scene
    else:
        raise BadInputError("render needs an LsadStore or a Scene")
    near_field = check_choice(near_field or store.near_field, "near_field", NEAR_FIELD_TREATMENTS)
    scene = store.scene
    if near_distance is None:
        near_distance = RELATIVE_NEAR_DISTANCE * scene.size
    near_distance = float(near_distance)
    if not near_distance > 0:
        raise BadInputError(f"near_distance must be positive, got {near_distance!r}")
    position, rotation = _check_pose(position, rotation)
    engine = _engine_for(scene)
    t0 = time.perf_counter()
    valid, prim, dist, d = _primary(scene, engine, projection, position, rotation)
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
        # The valid pixels are those _primary traced: no second pass over the projection.
        nodes_per_pixel = None if valid.size * store.nodes <= FULL_GATHER_PAIRS else AUTO_NODES_PER_PIXEL
    elif nodes_per_pixel is not None and (isinstance(nodes_per_pixel, (str, bool))
                                          or int(nodes_per_pixel) != nodes_per_pixel or nodes_per_pixel < 1):
        raise BadInputError("nodes_per_pixel must be a positive integer, 'all' or 'auto', "
                            f"got {nodes_per_pixel!r}")
    gatherer = _Gatherer(store, engine, near_field=near_field, near_distance=near_distance,
                         per_pixel=nodes_per_pixel, seed=seed)
    chunk = max(PIXEL_BLOCK, math.ceil(chunk_pixels / PIXEL_BLOCK) * PIXEL_BLOCK)

    def work(start):
        h = hit[start:start + chunk]
        t = prim[h]
        x = position + dist[h, None] * d[h]
        nrm, _ = scene.facing_normals(t, d[h])
        rho = scene.triangle_reflectance[t]
        emitted = _emitted(scene, t, -d[h])
        block_ids = (start + np.arange(h.size)) // PIXEL_BLOCK
        refl = rho > 0
        out = np.empty((h.size, B))
        for b in range(B):
            value = emitted.copy()
            if refl.any():
                e = gatherer.gather(x[refl], nrm[refl], b, block_ids[refl])
                value[refl] += rho[refl] / math.pi * e / n_b
                if near_field == "unbiased":
                    value[refl] += _near_field_terms(scene, engine, gatherer, x[refl], nrm[refl],
                                                     rho[refl], b, block_ids[refl], seed,
                                                     near_distance, n_b)
            out[:, b] = value
        return h, out

    _run_chunks(work, range(0, hit.size, chunk), lum_b, workers, progress, t0, hit.size)
    openings = _luminous_openings(scene, position, d, dist)
    _check_view(scene, engine, prim, dist, np.where(np.isfinite(openings)[:, None], 1.0, lum_b),
                position)
    return _finish(projection, valid, lum_b, store_or_scene=store, estimator="double local estimate",
                   openings=openings,
                   extra={"samples": int(store.chains), "chains": int(store.chains),
                          "nodes": int(store.nodes),
                          "near_field": near_field, "near_distance_m": near_distance,
                          "near_field_biased": near_field == "clamp",
                          "nodes_per_pixel": "all" if nodes_per_pixel is None else int(nodes_per_pixel),
                          "seed": int(seed), "simulation_seed": int(store.seed)},
                   elapsed=time.perf_counter() - t0, pose=(position, rotation))


def _run_chunks(work, starts, lum_b, workers, progress, t0, total):
    """Run ``work(start) -> (pixel indices, values)`` for every chunk, in threads if asked.

    Each chunk draws only from its own pixel blocks' streams, so the result is the same
    for any number of workers (and any completion order).
    """
    starts = list(starts)
    done = 0

    def report(n):
        nonlocal done
        done += n
        if progress is not None:
            frac = min(1.0, done / max(total, 1))
            elapsed = time.perf_counter() - t0
            progress(frac, elapsed * (1 - frac) / frac if frac > 0 else float("nan"))

    if workers <= 1 or len(starts) <= 1:
        for start in starts:
            h, values = work(start)
            lum_b[h] = values
            report(h.size)
        return
    with ThreadPoolExecutor(max_workers=workers) as pool:
        for h, values in pool.map(work, starts):
            lum_b[h] = values
            report(h.size)


def view_pose(position, rotation):
    """The world pose of a camera as Radiance view vectors: ``{"vp", "vd", "vu"}``.

    ``vd`` is the optical axis (camera +z) and ``vu`` the image's up (camera −y, rows run
    down), both in world coordinates; Radiance's ``-vp``/``-vd``/``-vu``.
    """
    r = np.asarray(rotation, dtype=float)
    return {"vp": [float(v) for v in position], "vd": [float(v) for v in r[:, 2]],
            "vu": [float(v) for v in -r[:, 1]]}


def _finish(projection, valid, lum_b, *, store_or_scene, estimator, extra, elapsed, pose,
            openings=None, shared_variance=None):
    """The LuminanceMap of per-batch pixel values ``lum_b`` (valid pixels × batches).

    ``pose`` = (position, rotation) of the camera: recorded as ``provenance["view_pose"]``
    (:func:`view_pose`), so the Radiance HDR writer gives the rendered view's ``VIEW=`` line.

    ``shared_variance`` (per valid pixel) is the variance of a component that all batches
    share (added to the batches' squared standard error; independent between pixels).
    """
    rows, cols = projection.shape
    shared = np.zeros(len(valid)) if shared_variance is None else shared_variance
    if openings is not None:
        seen = np.isfinite(openings)
        lum_b[seen] = openings[seen, None]  # luminous openings in front of the surfaces
        shared[seen] = 0.0
    B = lum_b.shape[1]
    mean = lum_b.mean(axis=1)
    se = np.sqrt(lum_b.var(axis=1, ddof=1) / B + shared)
    lum = np.full(rows * cols, np.nan)
    unc = np.full(rows * cols, np.nan)
    lum[valid] = mean
    unc[valid] = se
    r, c = np.unravel_index(valid, (rows, cols))
    omega = projection.solid_angles(r, c)
    field_b = (omega[:, None] * lum_b).sum(axis=0) / omega.sum()
    field_mean = float(field_b.mean())
    field_se = float(math.sqrt(field_b.var(ddof=1) / B + (omega ** 2 * shared).sum() / omega.sum() ** 2))
    provenance = {
        **build_provenance(),
        "solver": "lsadphoto.solver",
        "estimator": estimator,
        "batches": int(B),
        "field_mean_luminance": field_mean,
        "field_mean_standard_error": field_se,
        "achieved_relative_error": field_se / field_mean if field_mean > 0 else float("nan"),
        "render_time_s": float(elapsed),
        "scene": store_or_scene.scene.name if hasattr(store_or_scene, "scene") else store_or_scene.name,
        "view_pose": view_pose(*pose),
    }
    provenance.update(extra)
    return LuminanceMap(lum.reshape(rows, cols).astype(np.float32),
                        uncertainty=unc.reshape(rows, cols).astype(np.float32),
                        projection=projection, calibrated=True, provenance=provenance)


# --- path tracer ------------------------------------------------------------------------------

class _GroupStreams:
    """Draws for paths sorted by group, each group from its own generator.

    ``counts`` (set before each use) holds the number of live paths per group; ``random``
    concatenates each generator's draws, so a group's numbers do not depend on which
    other groups share the array.
    """

    def __init__(self, gens):
        self.gens = gens
        self.counts = np.zeros(len(gens), dtype=np.int64)

    def random(self, size):
        shape = (size,) if np.isscalar(size) else tuple(size)
        rest = shape[1:]
        return np.concatenate([g.random((int(c), *rest)) for g, c in zip(self.gens, self.counts)])


def render_path_traced(scene, projection, *, position, rotation, samples=64, seed=0, batches=16,
                       max_depth=None, chunk_pixels=1024, workers=1, progress=None):
    """Luminance map by path tracing from the eye with next-event estimation [cd·m⁻²].

    A conventional, independent estimator for cross-checks of :func:`render`: from the
    point x_p seen through each pixel centre, ``samples`` paths per pixel (split into
    ``batches`` independent batches for the standard errors); at every vertex the direct
    illuminance is estimated by sampling one luminaire point in proportion to flux (the
    same distribution as the light chains' sources) with a shadow ray; the path continues
    in a cosine-distributed direction with Russian-roulette probability ρ. Emission found
    by the continuation rays is not counted (next-event estimation covers it), so no
    multiple importance sampling is needed for unbiasedness.

    Parameters are those of :func:`render` (``scene`` instead of a store), plus
    ``samples`` (paths per pixel, a multiple of ``batches``), ``batches`` (≥ 2) and
    ``max_depth`` (bounce limit, biased; default unlimited). Returns a
    :class:`~lsadphoto.luminance_map.LuminanceMap` [cd·m⁻²] with per-pixel standard errors.

    References
    ----------
    Kajiya, J. T. (1986). The rendering equation. *SIGGRAPH '86*. Veach (1997), §10.
    """
    if not isinstance(scene, Scene):
        raise BadInputError("render_path_traced needs a Scene")
    if int(workers) != workers or workers < 1:
        raise BadInputError(f"workers must be a positive integer, got {workers!r}")
    workers = int(workers)
    position, rotation = _check_pose(position, rotation)
    samples = int(samples)
    batches = int(batches)
    if batches < 2 or samples < batches or samples % batches:
        raise BadInputError(f"samples ({samples}) must be a positive multiple of batches ({batches} ≥ 2)")
    per_batch = samples // batches
    engine = _engine_for(scene)
    sampler = EmissionSampler(scene)
    limit = 10_000 if max_depth is None else int(max_depth)
    t0 = time.perf_counter()
    valid, prim, dist, d = _primary(scene, engine, projection, position, rotation)
    hit = np.flatnonzero(prim >= 0)
    lum_b = np.zeros((valid.size, batches))
    eps = engine.epsilon
    chunk = max(PIXEL_BLOCK, math.ceil(chunk_pixels / PIXEL_BLOCK) * PIXEL_BLOCK)

    def work(start):
        h = hit[start:start + chunk]
        t = prim[h]
        x0 = position + dist[h, None] * d[h]
        n0, _ = scene.facing_normals(t, d[h])
        emitted = _emitted(scene, t, -d[h])
        # paths ordered by (batch, pixel block, pixel, sample); one stream per (batch, block)
        local_block = np.arange(h.size) // PIXEL_BLOCK
        n_blocks = int(local_block[-1]) + 1
        j0 = start // PIXEL_BLOCK
        pix = np.tile(np.repeat(np.arange(h.size), per_batch), batches)
        path_batch = np.repeat(np.arange(batches), h.size * per_batch)
        group = path_batch * n_blocks + local_block[pix]
        streams = _GroupStreams([stream(seed, "path", b, j0 + jl)
                                 for b in range(batches) for jl in range(n_blocks)])
        acc = np.zeros(pix.size)
        alive = np.arange(pix.size)
        x, nx, tri = x0[pix], n0[pix], t[pix]
        depth = 0
        while alive.size and depth < limit:
            streams.counts = np.bincount(group[alive], minlength=len(streams.gens))
            rho = scene.triangle_reflectance[tri]
            # next-event estimation
            src = sampler.sample(streams, alive.size)
            v = src["position"] - x
            r2 = np.einsum("ij,ij->i", v, v)
            r = np.sqrt(r2)
            w = v / r[:, None]
            cos_x = np.einsum("ij,ij->i", w, nx)
            is_cos = src["kind"] == KIND_COSINE
            g = np.where(is_cos, -np.einsum("ij,ij->i", w, src["normal"]), 0.0)
            pt = np.flatnonzero(src["kind"] == KIND_POINT)
            if pt.size:
                g[pt] = sampler.point_intensity(src["luminaire"][pt], -w[pt])
            ok = (cos_x > 0) & (g > 0) & (rho > 0)
            if ok.any():
                tgt = src["position"][ok] + eps * src["normal"][ok] * is_cos[ok, None]
                vis = engine.visible(x[ok] + eps * nx[ok], tgt)
                acc[alive[ok]] += (rho[ok] / math.pi * src["coefficient"][ok] * g[ok] * cos_x[ok]
                                   / r2[ok] * vis)
            # continuation
            u = streams.random((alive.size, 3))
            go = u[:, 0] < rho
            depth += 1
            alive, x, nx, u = alive[go], x[go], nx[go], u[go]
            if not alive.size:
                break
            dirs = cosine_directions(nx, u[:, 1:])
            p2, d2 = engine.closest_hit(x + eps * nx, dirs)
            ok = p2 >= 0
            alive, x, nx, dirs, p2, d2 = alive[ok], x[ok], nx[ok], dirs[ok], p2[ok], d2[ok]
            x = x + eps * nx + d2[:, None] * dirs
            nx, _ = scene.facing_normals(p2, dirs)
            tri = p2
        return h, emitted[:, None] + acc.reshape(batches, h.size, per_batch).mean(axis=2).T

    _run_chunks(work, range(0, hit.size, chunk), lum_b, workers, progress, t0, hit.size)
    openings = _luminous_openings(scene, position, d, dist)
    _check_view(scene, engine, prim, dist, np.where(np.isfinite(openings)[:, None], 1.0, lum_b),
                position)
    return _finish(projection, valid, lum_b, store_or_scene=scene, estimator="path tracing (NEE)",
                   openings=openings,
                   extra={"samples": samples, "samples_per_pixel": samples, "seed": int(seed),
                          "near_field": "none (path tracing)", "near_field_biased": False,
                          "max_depth": max_depth},
                   elapsed=time.perf_counter() - t0, pose=(position, rotation))
