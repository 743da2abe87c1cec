"""Per-surface indirect illuminance of a scene, and rendering from it.

The per-pixel double local estimate (:func:`~lsadphoto.solver.render`) connects every
pixel to chain nodes: its cost grows with pixels × nodes, and a few thousand nodes per
pixel are needed for a per-pixel error of a few per cent. In a Lambertian scene the light
that reaches a surface point after at least one reflection — the *indirect* illuminance —
varies smoothly over each surface, while the *direct* illuminance carries the sharp
shadows and the near-luminaire gradients. This module splits the two:

    L(x_p) = L_e(x_p) + ρ_p/π · (E_dir(x_p) + E_ind(x_p)).

* **E_dir per pixel**, by the first local estimate from the luminaires with Lambert's
  closed form as control variate (:func:`~lsadphoto.solver.direct.direct_illuminance`):
  exact where a luminaire is fully visible, sampled only in its shadows.
* **E_ind on a cache of surface points**, by the double local estimate restricted to the
  nodes of depth ≥ 1 (the nodes that carry reflected flux): each point draws ``nodes``
  nodes in :data:`GROUPS` independent groups (group g: the chains of batches ≡ g), in
  proportion to their coefficient and stratified along a Morton curve through the group's
  nodes (one draw from each of k equal slices of the coefficient mass; independent draws
  per point and group), connects those farther than ε with a visibility ray, and
  estimates the part within ε without
  bias by cosine-sampled rays (at a near hit y it adds ρ_y·(E_dir(y) + E_ind(y)), E_ind(y)
  again by far nodes and a further near ray, continued by Russian roulette with
  probability ρ_y) — the near-field split of :mod:`~lsadphoto.solver.integrators.local_estimate`, with
  emission left out because the direct part is counted separately.
* The cache points follow the surface area (:mod:`~lsadphoto.solver.cache_grid`): the
  vertices of a regular subdivision of every reflecting triangle larger than the spacing
  (level m ≈ √(2·area)/spacing), one set per side, and one point per *patch* of the sides
  of the smaller triangles (grouped by position, orientation and offset: a vault of
  48 000 facets needs as many points as its area, not two per facet); grid cells whose
  corner values differ strongly (shadow edges of indirect light, objects standing close,
  concave corners) are subdivided further, and such patches split at half the size. A
  pixel's E_ind is the **linear interpolation** of its sub-triangle's three vertices, or
  the kernel average of the patch points around it, per group, so per-pixel standard
  errors still come from independent groups.

What this costs and gives: the cache is view-independent (it is saved in the store, and a
further view needs only its primary rays, its direct shadow rays and the interpolation);
the estimate of E_ind at every cache point is unbiased, the interpolation adds a bias of
order spacing² × (curvature of E_ind) — largest next to concave edges; on patches, whose
kernel average reproduces constants but not gradients, of order spacing × |∇E_ind| where the
points lie on one side (an edge of a mesh), less the part that a weighted plane fit finds
clear of the noise (:meth:`~lsadphoto.solver.cache_grid.SurfaceCache.interpolate`).
:func:`render_cached` estimates it per pixel from the cached values themselves (:meth:`~lsadphoto.solver.cache_grid.SurfaceCache.interpolate_with_bias`)
and adds it to the reported uncertainty in quadrature. It is measured against per-pixel
estimates in docs/accuracy.md; halve ``spacing`` to quarter it.

Scenes with glossy, specular and transmitting materials (:mod:`~lsadphoto.solver.materials`)
cache the same quantity — E_ind, everything but the luminaires seen directly or through
glass — on the sides of every surface with a diffuse part: far connections to the material
chains' surface nodes with the node's whole BSDF per pair, and cosine-sampled paths for the
near field and for light relayed by delta reflections (:class:`_MaterialIndirectEstimator`).
Per pixel the eye path follows deltas; each vertex takes its diffuse part from E_dir (shadow
rays through glass with its transmittance) + the interpolated E_ind, and its glossy part from
lobe-sampled rays whose hits are evaluated the same way, with next-event estimates for what
rays cannot hit (point luminaires, the sun and sky) (:func:`_material_chunk`). Smooth
plastic, metal and trans of specularity ≥ 0.018 carry Radiance's Fresnel factor 1 − F(μ_i) on
their diffuse part (:mod:`~lsadphoto.solver.materials`), which then scatters the
*Fresnel-weighted* irradiance E_F = ∫(1 − F(μ_i))·L·μ_i dω, not E: their cache points hold
E_F,ind (each far connection weighted by 1 − F(cos θ_x), each cosine-sampled ray's π by
1 − F(μ_i) of its direction; patches never mix the two quantities), and their vertices take
E_F,dir from the direct part (``fresnel=`` of :func:`direct_illuminance`). Under the
``"radiance"`` rule of the store (:data:`~lsadphoto.solver.materials.FRESNEL_RULES`) the
factor applies to light straight from Radiance's light sources only: every cache point holds
the plain E_ind, and only those luminaires' direct light is Fresnel-weighted.
docs/user-guide-solver.md §2a gives the rules and where the estimate is not unbiased.

References
----------
Budak, Zheltov & Kalakutsky (2012), *Computer Research and Modeling* 4(1), 75–84 (double
local estimate). Marchuk et al. (1980), *The Monte Carlo Methods in Atmospheric Optics*,
§3.3. Ward, G. J., Rubinstein, F. M., Clear, R. D. (1988). A ray tracing solution for diffuse
interreflection. *SIGGRAPH '88*, 85–92 (indirect irradiance is smooth and can be cached and
interpolated; direct light is computed per pixel). Chen & Asau (1974), AIIE Transactions
6(2), 163–166 (cutpoint inverse-CDF draws). Morton (1966), IBM report (Z-order).
"""

import math
import time

import numpy as np
from ..._compiled import njit

from ..._validation import check_positive_int
from ...errors import BadInputError
from .._sampling import cosine_directions, orthonormal_basis, stream
from ..cache_grid import PATCH_KERNEL, SurfaceCache, cells_over_contrast, grid_index, patch_neighbours, patch_sides
from ..direct import (ALL_LUMINAIRES_UP_TO, DIRECT_SAMPLES, LuminaireTable, direct_illuminance,
                      sampled_direct_illuminance)
from ..engine import engine_for
from ..materials import diffuse_fresnel_factor, fresnel_weighted, shadow_transmittance
from ..sky import DISTANT_RAYS_PER_DIRECT_SAMPLE, background_luminance, distant_reflection, stratified
from ..store import KIND_COSINE, LsadStore
from .eye import (check_pose, chunk_hits, chunk_size, emitted_luminance, luminance_map_from_batches,
                  luminous_openings, near_step, pixel_solid_angles, primary_rays, run_chunks, warn_odd_view)

__all__ = ["CACHE_NODES", "GLOSSY_RAYS", "RELATIVE_CACHE_SPACING", "build_surface_cache",
           "indirect_illuminance", "render_cached"]

#: Default cache spacing as a fraction of the scene's bounding-box diagonal.
RELATIVE_CACHE_SPACING = 1 / 24
#: Longest edge of a grid triangle's cells, in spacings: what the area rule of
#: :func:`_cache_points` gives a rectangle's halves (the canonical room's walls: 1.47), here also
#: on thin triangles, whose cells that rule alone let grow to 3 spacings along their length —
#: on the station hall's end walls (slivers fanned under the vault) cells 2.4 m tall, across
#: which E_ind rises and falls (35 → 45 → 38 lx) and pixels came out 12–15 % low with a
#: reported 0.5 % (docs/accuracy.md, session 16).
GRID_CELL_EDGE = 1.5
#: Default node draws per cache point (over all batch groups).
CACHE_NODES = 8192
#: Independent groups of node draws (the per-pixel standard error comes from their spread).
GROUPS = 16
#: Cosine-sampled near-field paths per point and group.
NEAR_RAYS = 4
#: … in scenes with materials, where they also carry the light relayed by delta reflections
#: (a luminaire in a glass pane). Floor points of the glass-partition room (131 072 chains,
#: 4096 node draws): 4 per group left that part (18 % of E_ind) at 58 % relative error and
#: E_ind at 11 %, for 8 % of the time of the far part; 16: 31 % and 6.6 % for 27 %; 32: 23 %
#: and 5.0 % for 73 %.
MATERIAL_NEAR_RAYS = 16
#: Default ε of the indirect estimate as a fraction of the scene's bounding-box diagonal:
#: larger than the per-pixel renderer's, which bounds the far terms (c/ε²) and moves the
#: neighbourhood of concave edges to the cosine-sampled near paths.
RELATIVE_CACHE_NEAR_DISTANCE = 0.04
#: Subdivision level of refined cells, and the relative contrast that triggers it.
REFINE, REFINE_CONTRAST = 3, 0.2
#: Halvings of the patches of small triangles where their values vary strongly.
PATCH_REFINE = 1
#: Cache points per random-stream block.
POINT_BLOCK = 256

#: Stream tags of the material cache (keys of the "cache" purpose beyond the node draws'); the
#: next-event draws of each use take _TAG_POINT + k, k = 0 … 7.
_TAG_RAYS, _TAG_GLOSSY, _TAG_DELTA, _TAG_POINT = 1 << 20, (1 << 20) + 1, (1 << 20) + 2, (1 << 20) + 3
#: Glossy-lobe rays per eye vertex and group of :func:`render_cached` in a material scene (as
#: many per pixel as the material local estimate's default). Before the emitters' next-event
#: estimate the glossy reflection of an area luminaire was these rays' alone: with 4 the
#: glossy floor's pixels in a lobe's tail came out ~5 % low with too small an error (most
#: groups missed the luminaire).
GLOSSY_RAYS = 16
#: Point-luminaire emission points drawn per vertex for the glossy part's next-event estimate.
POINT_DRAWS = 4
#: Area-luminaire emission points drawn per vertex and group for the glossy part's next-event
#: estimate (combined with the lobe-sampled rays by the balance heuristic), stratified along the
#: group's emission points. At the metal panel's highlight (docs/accuracy.md, session 10; six
#: renders of one store at 16 glossy rays) 4 left a spread of 15 % per render against a
#: reported 10 %; 16: 4.6 % against 5.0 %, for a few more shadow rays per glossy vertex.
EMITTER_DRAWS = 16
#: Directions per distant source (sun, sky) and vertex for the glossy part's next-event estimate.
DISTANT_GLOSSY_SAMPLES = 4
#: Vertices a sampled path visits at most (Russian roulette ends nearly all before).
MAX_PATH_VERTICES = 32
#: Cosine-sampled near-field paths per group of :func:`render_cached`'s own estimate of E_ind at
#: a pixel that the cache does not resolve (its Notes; the columns' feet behind the station
#: hall's benches, docs/accuracy.md session 12: at 8192 node draws their
#: relative standard error was 11 % with 4 paths, 4.1 % with 64, for the same CPU time — the
#: near field is nearly all of E_ind there, so more node draws do not help, and the paths'
#: node draws per hit fall as their number grows).
PIXEL_NEAR_RAYS = 64
#: A pixel's E_ind is interpolated only where the interpolation's support distance is at most
#: this fraction of the pixel's free distance (Ward et al. 1988's accuracy parameter a, with
#: which a cached value counts within a·R of its point; :func:`render_cached`'s Notes). On the
#: station hall with 1: the floor under a bench 0.12 m inside its edge (one corner outside
#: kept) still came out 1.1–2× too bright, the columns at free distances of 1–2 supports +6 %.
PIXEL_VALIDITY = 0.5
#: Polar angles [°] of the two rings of 6 probe rays each (azimuths 60° apart) whose harmonic
#: mean free distance stands for the hemisphere's in that test on small triangles' sides
#: (:func:`_free_distance`): the middles, sin²θ = ¼ and ¾, of the two halves of the
#: cosine-weighted hemisphere that Ward et al. sample.
PIXEL_PROBE_POLAR_DEG = (30.0, 60.0)
#: On small triangles' sides a pixel's E_ind is interpolated only where the lean of its patch
#: kernel (the distance from the pixel to the weighted centroid of the patch points' offsets
#: on its tangent plane, :meth:`SurfaceCache.interpolate_with_bias`) is at most this fraction
#: of the support distance: beyond it the points lie within ±37° (cos⁻¹ 0.8) of one direction
#: as seen from the pixel, and the kernel extrapolates from one side — the top of a column
#: above the luminaires' plane, where E_ind falls by a third within the top patch, below
#: its points (docs/accuracy.md, session 14).
PIXEL_LEAN = 0.8
#: Pixels of one triangle side whose own estimates of E_ind share one record: those in one
#: cube of edge ``PIXEL_RECORD`` × 2^⌊log₂ t⌋, t the distance [m] to the nearest surface that
#: the pixel's normal ray and probe rays meet (between t/8 and t/4: a record serves points
#: within 0.43·t of it). Session 12 took t from the validity test's free distance; on patch
#: pixels that is a harmonic mean, and a column face 0.09 m above a bench seat (free distance
#: 0.71 m, nearest surface 0.27 m) shared the estimate of any point in its cube of 0.125 m,
#: while E_ind falls by 17 % within 0.06 m below it (docs/accuracy.md, session 14).
PIXEL_RECORD = 0.25

_NUMBA = {"cache": True, "error_model": "numpy", "nogil": True}


def _morton_codes(positions, lo, size):
    """Morton (Z-order) codes of points' cells in a 2¹⁰-per-axis grid of the cube
    [lo, lo + size]³: bit b of the cell's index along axis a is bit 3b + a of the code, so
    that points of consecutive codes are close in space. Each 10-bit index is spread to
    every third bit by four shift-and-mask steps (Morton 1966; the masks keep the bits that
    each step has moved into place)."""
    q = np.clip(((positions - lo) / size * 1024).astype(np.int64), 0, 1023)
    q = (q | (q << 16)) & 0x030000FF
    q = (q | (q << 8)) & 0x0300F00F
    q = (q | (q << 4)) & 0x030C30C3
    q = (q | (q << 2)) & 0x09249249
    return q[:, 0] | (q[:, 1] << 1) | (q[:, 2] << 2)


def _guide_table(cdf):
    """guide[t] = first index i with cdf[i] ≥ t/n, t = 0…n (n = cdf.size): inverse-CDF
    look-ups start there and rarely step further (Chen & Asau's cutpoint method)."""
    n = cdf.size
    return np.minimum(np.searchsorted(cdf, np.arange(n + 1) / n, side="left"), n - 1)


@njit(**_NUMBA, aot="int64(float64[:, ::1], float64[:, ::1], float64, float64[::1], int64[::1], "
                    "float64[:, ::1], float64[:, ::1], float64, float64, float64[:, ::1], int64[::1], "
                    "float32[:, ::1], float32[:, ::1], float32[::1])")
def _far_terms(points, normals, offset, cdf, guide, nodes, u, eps2, tiny, out, pair, o32, d32,
               t32):
    """cos θ_n·cos θ_x/r² of the pairs (point i, node drawn with u[i, j]) farther than ε,
    0 for pairs closer than ε, behind either surface or grazing (|r|·cos < tiny); returns the
    number m of pairs that need a shadow ray, whose flat index and float32 ray (origin, unit
    direction, length; both ends moved ``offset`` off their surfaces) are in ``pair``,
    ``o32``, ``d32``, ``t32`` [:m]. Node j of point i is the inverse CDF of the stratified
    uniform (j + u[i, j])/k over the pool (rows x, y, z, nx, ny, nz of ``nodes``, in Morton
    order; ``cdf`` of their coefficients, ``guide`` its cutpoint table)."""
    P, k = out.shape
    n = nodes.shape[0]
    m = 0
    for i in range(P):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        nx, ny, nz = normals[i, 0], normals[i, 1], normals[i, 2]
        ox, oy, oz = px + offset * nx, py + offset * ny, pz + offset * nz
        for j in range(k):
            v = (j + u[i, j]) / k
            q = guide[min(int(v * n), n)]
            while q < n - 1 and cdf[q] < v:
                q += 1
            dx = nodes[q, 0] - px
            dy = nodes[q, 1] - py
            dz = nodes[q, 2] - pz
            r2 = dx * dx + dy * dy + dz * dz
            a_p = dx * nx + dy * ny + dz * nz
            a_n = -(dx * nodes[q, 3] + dy * nodes[q, 4] + dz * nodes[q, 5])
            if a_p > tiny and a_n > tiny and r2 >= eps2:
                out[i, j] = a_n * a_p / (r2 * r2)
                ex = nodes[q, 0] + offset * nodes[q, 3] - ox
                ey = nodes[q, 1] + offset * nodes[q, 4] - oy
                ez = nodes[q, 2] + offset * nodes[q, 5] - oz
                length = math.sqrt(ex * ex + ey * ey + ez * ez)
                if length > offset:
                    pair[m] = i * k + j
                    o32[m, 0], o32[m, 1], o32[m, 2] = ox, oy, oz
                    d32[m, 0], d32[m, 1], d32[m, 2] = ex / length, ey / length, ez / length
                    t32[m] = length - offset
                    m += 1
            else:
                out[i, j] = 0.0
    return m


class _NodeHull:
    """What both indirect estimators share: the test for points facing no node, the
    many-luminaire table and the stream keys of their direct samples (attributes ``store``,
    ``scene``, ``engine``, ``key``)."""

    def _pools_along_curve(self, nodes, groups):
        """``nodes`` (store indices) in ``groups`` pools — pool g holds those of the batches
        b ≡ g (mod groups): independent chains — each in the order of its nodes' positions
        along a Morton curve through the scene's bounding cube (consecutive nodes are close
        in space; equal codes in ``nodes``' order)."""
        corners = self.scene.triangles.reshape(-1, 3)
        code = _morton_codes(self.store.position[nodes], corners.min(axis=0),
                             float(np.ptp(corners, axis=0).max()) or 1.0)
        group = (self.store.batch[nodes] % groups).astype(np.int64)
        order = np.argsort(group << 30 | code, kind="stable")  # codes have 30 bits
        bounds = np.searchsorted(group[order], np.arange(groups + 1))
        ranked = nodes[order]
        return [ranked[bounds[g]:bounds[g + 1]] for g in range(groups)]

    def _facing_nodes(self, x, n):
        """True where some node lies in front of the point's tangent plane (else the far
        part is exactly 0: every pair has cos θ_x ≤ 0), by the support function of the
        nodes' convex hull."""
        hull = self.store.surface_node_hull()
        if hull.size == 0:
            return np.zeros(len(x), dtype=bool)
        support = (n @ hull.T).max(axis=1)
        return support > np.einsum("ij,ij->i", n, x) + self.engine.epsilon

    def _luminaire_table(self, near_distance):
        """With many luminaires, the per-region table from which a near hit or a path vertex
        draws one of them (:class:`~lsadphoto.solver.direct.LuminaireTable`); else None."""
        scene = self.scene
        many = len(scene.area_luminaires) + len(scene.point_luminaires) > ALL_LUMINAIRES_UP_TO
        return LuminaireTable(scene, near_distance) if many else None

    def _direct_key(self, level):
        """Stream key of the direct samples at near hits and path vertices (≥ 1; 0 is the
        pixels')."""
        return 1 + self.key * 4096 + level


class _IndirectEstimator(_NodeHull):
    """E_ind at points from the depth ≥ 1 nodes of a store, per group of draws."""

    def __init__(self, store, engine, *, nodes, near_distance, direct_samples, seed, key,
                 near_rays=NEAR_RAYS):
        self.store = store
        self.scene = store.scene
        self.engine = engine
        self.eps2 = near_distance ** 2
        self.near_distance = near_distance
        self.tiny = 1e-9 * store.scene.size
        self.direct_samples = direct_samples
        self.seed = seed
        self.key = key
        surface = np.flatnonzero(store.depth > 0)
        self.groups = min(GROUPS, store.batches)
        # Nodes are drawn in proportion to their coefficient c (importance sampling: the
        # estimate Σc/k·Σ_draws g·V has no variance from the spread of chain weights), with
        # the k draws of a point stratified along a Morton curve through the pool (each
        # draw from its own 1/k of the coefficient mass, in space order: a spatially
        # stratified sample; unbiased, each draw being exact for its stratum).
        self.tables, self.totals, self.packed = [], [], []
        pools = self._pools_along_curve(surface, self.groups)
        ranked = np.concatenate(pools)
        # The nodes of each pool in Morton order, position and normal in one row.
        rows = np.hstack([store.position[ranked], store.normal[ranked]]).astype(np.float64, copy=False)
        coefficient = store.coefficient[ranked]
        end = np.cumsum([pool.size for pool in pools])
        for a, b in zip(end - [pool.size for pool in pools], end):
            c = coefficient[a:b]
            total = float(c.sum())
            self.totals.append(total)
            cdf = np.cumsum(c) / total if total > 0 else None
            self.tables.append(None if cdf is None else (cdf, _guide_table(cdf)))
            self.packed.append(rows[a:b])
        self.draws = max(1, int(nodes) // self.groups)
        self.chains_per_group = store.chains / self.groups
        self.near_rays = int(near_rays)
        # node draws at each near hit: draws/8 with 4 paths, fewer with more paths (the near
        # paths' total stays draws/2; their noise is the paths' directions')
        self.near_draws = max(1, self.draws // (2 * self.near_rays))
        self.luminaire_table = self._luminaire_table(near_distance)

    def far(self, x, n, group, blocks, level, draws=None):
        """Far-node part of E_ind [lx] at points ``x`` for one group: Σc/k · Σ_draws cos θ_n
        ·cos θ_x·V/r² over k nodes drawn ∝ c (stratified), per chain of the group."""
        table = self.tables[group]
        P = len(x)
        if P == 0 or table is None:
            return np.zeros(P)
        k = self.draws if draws is None else draws
        u = _uniforms_by(self.seed, np.full(P, group), blocks, k, self.key, level)
        vals = np.empty((P, k))
        pair = np.empty(P * k, dtype=np.int64)
        o32 = np.empty((P * k, 3), dtype=np.float32)
        d32 = np.empty((P * k, 3), dtype=np.float32)
        t32 = np.empty(P * k, dtype=np.float32)
        rays = _far_terms(np.ascontiguousarray(x), np.ascontiguousarray(n), self.engine.epsilon,
                          table[0], table[1], self.packed[group], u, self.eps2, self.tiny, vals,
                          pair, o32, d32, t32)
        if rays:
            hit = self.engine.occluded(o32[:rays], d32[:rays], t32[:rays])
            vals.ravel()[pair[:rays][hit]] = 0.0
        return vals.sum(axis=1) * (self.totals[group] / k / self.chains_per_group)

    def estimate(self, x, n, blocks):
        """E_ind [lx] at points ``x`` (normals ``n``), shape (P, groups)."""
        P = len(x)
        out = np.zeros((P, self.groups))
        lit = np.flatnonzero(self._facing_nodes(x, n))
        for g in range(self.groups):
            out[lit, g] = self.far(x[lit], n[lit], g, blocks[lit], 0)
        return out + self._near(x, n, blocks)

    def _near(self, x0, n0, blocks0):
        """Unbiased estimates of the part of E_ind from surface points within ε, per group:
        the mean of ``near_rays`` cosine-sampled paths per point and group (each near hit y
        adds ρ_y·(E_dir(y) + far part of E_ind(y)) with ``near_draws`` node draws of the
        path's group, and continues by roulette). The paths of all groups are traced
        together; each (group, block) draws from its own stream."""
        scene, engine = self.scene, self.engine
        G, R, P = self.groups, self.near_rays, len(x0)
        point = np.repeat(np.arange(P), G * R)
        group = np.tile(np.repeat(np.arange(G), R), P)
        x, nx, blocks = x0[point], n0[point], blocks0[point]
        total = np.zeros(P * G * R)
        active = np.arange(P * G * R)
        rho_prev = None
        level = 0
        while active.size:
            level += 1
            u = np.empty((active.size, 3))
            key = group[active] * (int(blocks0.max()) + 1) + blocks[active]
            for k in np.unique(key):
                m = key == k
                g, j = group[active[m][0]], blocks[active[m][0]]
                u[m] = stream(self.seed, "near", self.key, g, level, j).random((int(m.sum()), 3))
            near, y, ny, _, prim = near_step(scene, engine, x, nx, u, self.near_distance,
                                              rho_prev)
            active = active[near]
            if not active.size:
                break
            rho_y = scene.triangle_reflectance[prim]
            lit = np.flatnonzero(rho_y > 0)
            if lit.size:
                paths = active[lit]
                keys = {"seed": self.seed, "block_ids": blocks[paths] * G + group[paths],
                        "purpose_key": self._direct_key(level)}
                if self.luminaire_table is None:
                    e_dir, _ = direct_illuminance(scene, engine, y[lit], ny[lit],
                                                  samples=self.direct_samples, **keys)
                else:
                    e_dir = sampled_direct_illuminance(scene, engine, y[lit], ny[lit],
                                                       table=self.luminaire_table, **keys)
                e_far = np.zeros(lit.size)
                for g in np.unique(group[paths]):
                    m = group[paths] == g
                    e_far[m] = self.far(y[lit[m]], ny[lit[m]], g, blocks[paths[m]], level,
                                        self.near_draws)
                total[paths] += rho_y[lit] * (e_dir + e_far)
            x, nx, rho_prev = y, ny, rho_y
        return total.reshape(P, G, R).mean(axis=2)


def indirect_illuminance(store, points, normals, *, nodes=CACHE_NODES, near_distance=None,
                         direct_samples=DIRECT_SAMPLES, seed=0, key=0, block_ids=None):
    """Indirect illuminance [lx] at surface points from a store, per group of node draws.

    The double local estimate over the store's nodes of depth ≥ 1, ``nodes`` draws per
    point in :data:`GROUPS` independent groups, with the unbiased near-field treatment
    (module docstring).

    Parameters
    ----------
    store : LsadStore
    points, normals : ndarray, shape (P, 3)
        Points [m] and unit normals of the lit side.
    nodes : int
        Node draws per point over all groups.
    near_distance : float, optional
        ε [m]; default :data:`RELATIVE_CACHE_NEAR_DISTANCE` × scene size.
    direct_samples : int
        Shadow-ray samples of the direct illuminance at near-field hits.
    seed, key : int
        Random streams ``(seed, "cache", key, …)``; different keys give independent estimates.
    block_ids : ndarray of int, optional
        Stream block of each point (default: consecutive blocks of 256 points).

    Returns
    -------
    numpy.ndarray, shape (P, groups)
        Independent unbiased estimates; their mean is the estimate, their standard
        deviation over √groups its standard error.
    """
    if not isinstance(store, LsadStore):
        raise BadInputError("indirect_illuminance needs an LsadStore")
    scene = store.scene
    eps = RELATIVE_CACHE_NEAR_DISTANCE * scene.size if near_distance is None else float(near_distance)
    if not eps > 0:
        raise BadInputError(f"near_distance must be positive, got {near_distance!r}")
    check_positive_int(nodes, "nodes")
    x = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    blocks = np.arange(len(x)) // POINT_BLOCK if block_ids is None else np.asarray(block_ids)
    estimator = _IndirectEstimator if scene.lambertian else _MaterialIndirectEstimator
    est = estimator(store, engine_for(scene), nodes=nodes, near_distance=eps, direct_samples=direct_samples,
                    seed=seed, key=key)
    return est.estimate(x, n, blocks)


def _cache_points(scene, spacing, inset, reflecting):
    """Levels, offsets, points and normals of the regular cache grids (both sides) of the
    ``reflecting`` triangles larger than the spacing (level ≥ 1); level 0 marks the smaller
    ones, which share patch points (:func:`_patches`), −1 the others; and the triangle of each
    point."""
    tris = scene.triangles
    T = len(tris)
    longest = np.stack([np.linalg.norm(tris[:, 1] - tris[:, 0], axis=1),
                        np.linalg.norm(tris[:, 2] - tris[:, 1], axis=1),
                        np.linalg.norm(tris[:, 0] - tris[:, 2], axis=1)], axis=1).max(axis=1)
    # The level gives sub-triangles of about spacing²/2 in area (√(2A)/m ≈ spacing; for an
    # equilateral triangle of edge a, √(2A) = 0.93a); a triangle with an edge longer than 3 ×
    # spacing has a grid even where it is thin, and no cell edge longer than GRID_CELL_EDGE ×
    # spacing.
    extent = np.maximum(np.sqrt(2.0 * scene.areas), longest / 3.0)
    level = np.where(extent < spacing, 0,
                     np.maximum(np.ceil(extent / spacing), np.ceil(longest / (GRID_CELL_EDGE * spacing)))
                     ).astype(np.int64)
    level[~reflecting] = -1
    offset = np.full((T, 2), -1, dtype=np.int64)
    pts, nrm, owner = [], [], []
    cursor = 0
    for t in np.flatnonzero(level >= 1):
        m = level[t]
        a, b, c = tris[t]
        centroid = (a + b + c) / 3.0
        ij = np.array([(i, j) for i in range(m + 1) for j in range(m + 1 - i)], dtype=float)
        p = a + (ij[:, :1] / m) * (b - a) + (ij[:, 1:] / m) * (c - a)
        # A vertex on an edge is moved a few ray offsets inside, so that its rays do not
        # start in the plane of a neighbouring surface (E_ind is continuous there).
        to_c = centroid - p
        length = np.linalg.norm(to_c, axis=1, keepdims=True)
        p = p + to_c * np.minimum(inset, 0.5 * length) / np.where(length > 0, length, 1.0)
        for side, sign in ((0, 1.0), (1, -1.0)):
            offset[t, side] = cursor
            pts.append(p)
            nrm.append(np.broadcast_to(sign * scene.normals[t], p.shape))
            owner.append(np.full(len(p), t, np.int64))
            cursor += len(p)
    points = np.concatenate(pts) if pts else np.zeros((0, 3))
    normals = np.concatenate(nrm) if nrm else np.zeros((0, 3))
    triangle = np.concatenate(owner) if owner else np.zeros(0, np.int64)
    return level, offset, points, np.ascontiguousarray(normals), triangle


def _small_sides(scene, level):
    """Triangle, side (0 front, 1 back) and oriented normal of both sides of the level-0
    triangles."""
    small = np.flatnonzero(level == 0)
    tri = np.concatenate([small, small])
    side = np.repeat([0, 1], small.size)
    normal = np.where((side == 0)[:, None], 1.0, -1.0) * scene.normals[tri]
    return tri, side, np.ascontiguousarray(normal)


def _patches_to_split(values, point, normal, radius, start, index, contrast):
    """Patches whose value differs from the kernel average of their neighbours' (the
    interpolation at the patch's own point without it) by more than ``contrast`` × its
    value and by more than 3 standard errors: where the interpolation would miss a
    curvature, an edge of the mesh or a shadow of indirect light (a steady gradient
    passes)."""
    G = values.shape[1]
    C = len(point)
    mean = values.mean(axis=1)
    se = values.std(axis=1, ddof=1) / math.sqrt(G)
    owner = np.repeat(np.arange(C), np.diff(start))
    other = index
    d = point[other] - point[owner]
    d2 = np.einsum("ij,ij->i", d, d)
    dist = np.sqrt(d2)
    agree = np.einsum("ij,ij->i", normal[owner], normal[other])
    tilt = np.abs(np.einsum("ij,ij->i", normal[owner], d)) / np.maximum(dist, 1e-300)
    used = (owner != other) & (dist < radius[owner]) & (agree > 0.5) & (tilt < 0.5)
    w = np.where(used, (1 - d2 / radius[owner] ** 2) ** 2 * (agree - 0.5) / 0.5
                 * (1 - tilt / 0.5), 0.0)
    total = np.bincount(owner, weights=w, minlength=C)
    pred = np.bincount(owner, weights=w * mean[other], minlength=C) / np.maximum(total, 1e-300)
    pred_se = np.sqrt(np.bincount(owner, weights=(w * se[other]) ** 2, minlength=C)) / np.maximum(total, 1e-300)
    gap = np.abs(pred - mean)
    flag = (total > 0) & (gap > contrast * mean) & (gap > 3.0 * np.hypot(se, pred_se))
    return np.flatnonzero(flag)


def _cells_to_refine(level, offset, values, contrast):
    """Keys and corner indices (k, 3) of the cells whose corner values differ by more than
    ``contrast`` × the largest and by more than 3 standard errors of the difference
    (:func:`~lsadphoto.solver.cache_grid.cells_over_contrast`)."""
    G = values.shape[1]
    mean = values.mean(axis=1)
    se = values.std(axis=1, ddof=1) / math.sqrt(G)
    keys, corners = [], []
    for t in np.flatnonzero(level >= 1):
        m = int(level[t])
        ij = np.array([(i, j) for i in range(m) for j in range(m - i)], dtype=np.int64)
        i, j = ij[:, 0], ij[:, 1]
        up = i + j <= m - 2
        cells = [(np.zeros(i.size, bool), grid_index(m, i, j), grid_index(m, i + 1, j),
                  grid_index(m, i, j + 1), grid_index(m, i, j)),
                 (np.ones(up.sum(), bool), grid_index(m, i[up] + 1, j[up] + 1),
                  grid_index(m, i[up] + 1, j[up]), grid_index(m, i[up], j[up] + 1),
                  grid_index(m, i[up], j[up]))]
        for side in (0, 1):
            base = offset[t, side]
            for upper, c0, c1, c2, corner_ij in cells:
                c = base + np.stack([c0, c1, c2], axis=1)
                flag = cells_over_contrast(mean[c], se[c], contrast)
                keys.append(2 * (base + corner_ij[flag]) + upper[flag])
                corners.append(c[flag])
    if not keys:
        return np.zeros(0, np.int64), np.zeros((0, 3), np.int64)
    keys, corners = np.concatenate(keys), np.concatenate(corners)
    order = np.argsort(keys)
    return keys[order], corners[order]


def build_surface_cache(store, *, spacing=None, nodes=CACHE_NODES, near_distance=None,
                        direct_samples=DIRECT_SAMPLES, refine=REFINE, contrast=REFINE_CONTRAST,
                        patch_refine=PATCH_REFINE, seed=0, workers=1, progress=None):
    """Indirect illuminance on a cache of points over every reflecting surface of a store.

    Two passes: the regular grid of every triangle larger than the spacing and one point
    per patch of the smaller triangles' sides (:mod:`~lsadphoto.solver.cache_grid`: the
    points follow the area, not the triangle count); then every grid cell whose three
    corner values differ by more than ``contrast`` (relative to the largest, and
    significantly: more than 3 standard errors) — a shadow edge of indirect light, an
    object standing close, a concave corner — is subdivided into a level-``refine`` grid of
    its own, and every patch that differs so from a neighbour is split at half its size
    (``patch_refine`` times at most).

    Parameters
    ----------
    store : LsadStore
    spacing : float, optional
        Target spacing of the cache points [m]; default :data:`RELATIVE_CACHE_SPACING` ×
        the scene's bounding-box diagonal.
    nodes : int
        Node draws per cache point (over all groups): the per-point standard error of E_ind
        falls as 1/√nodes.
    near_distance : float, optional
        ε [m] of the near-field split; default :data:`RELATIVE_CACHE_NEAR_DISTANCE` × size.
    direct_samples : int
        Shadow-ray samples of the direct illuminance at near-field hits.
    refine : int
        Subdivision level of refined cells (1: no refinement).
    contrast : float
        Relative difference of corner values above which a cell (or a patch, against a
        neighbour) is refined.
    patch_refine : int
        Times a patch of small triangles may be split at half its size (0: never).
    seed : int
        Seed of the node draws and near-field rays.
    workers : int
        Threads (never changes the result).
    progress : callable, optional
        ``progress(done_fraction, eta_s)`` (per pass).

    Returns
    -------
    SurfaceCache
    """
    if not isinstance(store, LsadStore):
        raise BadInputError("build_surface_cache needs an LsadStore")
    scene = store.scene
    spacing = RELATIVE_CACHE_SPACING * scene.size if spacing is None else float(spacing)
    if not (spacing > 0 and math.isfinite(spacing)):
        raise BadInputError(f"cache spacing must be a positive length in metres, got {spacing!r}")
    check_positive_int(workers, "workers")
    check_positive_int(refine, "refine")
    if not contrast > 0:
        raise BadInputError(f"contrast must be positive, got {contrast!r}")
    if not (isinstance(patch_refine, int) and patch_refine >= 0):
        raise BadInputError(f"patch_refine must be a whole number ≥ 0, got {patch_refine!r}")
    check_positive_int(nodes, "nodes")
    eps = RELATIVE_CACHE_NEAR_DISTANCE * scene.size if near_distance is None else float(near_distance)
    t0 = time.perf_counter()
    engine = engine_for(scene)
    inset = 10 * engine.epsilon
    if scene.lambertian:
        reflecting = scene.triangle_reflectance > 0
    else:  # a diffuse reflection or transmission: its triangles' sides get cache points
        kd, td = _diffuse_coefficients(scene)
        reflecting = (kd + td)[scene.material] > 0
    level, offset, points, normals, point_tri = _cache_points(scene, spacing, inset, reflecting)
    # The sides of smooth plastic, metal and trans (Radiance's Fresnel factor on their diffuse
    # part) cache the Fresnel-weighted E_ind (_MaterialIndirectEstimator.estimate), under the
    # reciprocal rule: the Radiance rule leaves indirect light unweighted.
    weighted_tri = (np.zeros(len(scene.triangles), bool) if scene.lambertian else
                    fresnel_weighted(scene.bsdf.fresnel[scene.material], rule=store.fresnel_rule, direct=False))
    weighted = weighted_tri[point_tri]
    # The small triangles' sides share patch points (cache_grid.patch_sides), never across
    # weightings.
    side_tri, side_of, side_normal = _small_sides(scene, level)
    origin = scene.triangles.reshape(-1, 3).min(axis=0) if len(scene.triangles) else np.zeros(3)
    side_tris = scene.triangles[side_tri]
    side_areas = scene.areas[side_tri]
    side_weighted = weighted_tri[side_tri]
    groups = patch_sides(side_tris, side_normal, side_areas, spacing, origin=origin, label=side_weighted)
    grid_points = len(points)
    leaf_of_side = groups.patch.copy()
    p_point, p_normal, p_reach = groups.point, groups.normal, groups.reach
    p_weighted = _patch_weighting(groups, side_weighted)
    p_size = np.full(len(p_point), spacing)
    p_row = grid_points + np.arange(len(p_point))
    points = np.concatenate([points, p_point])
    normals = np.concatenate([normals, p_normal])
    weighted = np.concatenate([weighted, p_weighted])
    estimator = _IndirectEstimator if scene.lambertian else _MaterialIndirectEstimator
    est = estimator(store, engine, nodes=nodes, near_distance=eps, direct_samples=direct_samples, seed=seed, key=0)

    def evaluate(pts, nrm, fresnel, first_block):
        values = np.zeros((len(pts), est.groups))
        blocks = first_block + np.arange(len(pts)) // POINT_BLOCK

        def work(start):
            sl = slice(start, start + POINT_BLOCK)
            idx = np.arange(start, min(start + POINT_BLOCK, len(pts)))
            if scene.lambertian:
                return idx, est.estimate(pts[sl], nrm[sl], blocks[sl])
            return idx, est.estimate(pts[sl], nrm[sl], blocks[sl], fresnel[sl])

        run_chunks(work, range(0, len(pts), POINT_BLOCK), values, int(workers), progress,
                    time.perf_counter(), len(pts))
        return values

    def next_block():
        return (len(points) + POINT_BLOCK - 1) // POINT_BLOCK

    values = evaluate(points, normals, weighted, 0)
    first_points = len(points)
    keys, corners = (_cells_to_refine(level, offset, values, contrast) if refine > 1
                     else (np.zeros(0, np.int64), np.zeros((0, 3), np.int64)))
    refined_offset = np.zeros(0, np.int64)
    if keys.size:
        r = int(refine)
        ab = np.array([(a, b) for a in range(r + 1) for b in range(r + 1 - a)], dtype=float) / r
        p0, p1, p2 = (points[corners[:, k]] for k in range(3))
        fine_points = (p0[:, None] + ab[None, :, :1] * (p1 - p0)[:, None]
                       + ab[None, :, 1:] * (p2 - p0)[:, None])
        fine_values = np.empty((*fine_points.shape[:2], est.groups))
        # The cell's corners are grid points already estimated: (0, 0) → P0, (r, 0) → P1,
        # (0, r) → P2 in the local grid; only the other points are new.
        corner_slots = [0, grid_index(r, r, 0), grid_index(r, 0, r)]
        for slot, k in zip(corner_slots, range(3)):
            fine_values[:, slot] = values[corners[:, k]]
        new = np.setdiff1d(np.arange(len(ab)), corner_slots)
        fresh_points = fine_points[:, new].reshape(-1, 3)
        fresh_normals = np.repeat(normals[corners[:, 0]], new.size, axis=0)
        fine_values[:, new] = evaluate(fresh_points, fresh_normals, np.repeat(weighted[corners[:, 0]], new.size),
                                       next_block()).reshape(keys.size, new.size, est.groups)
        refined_offset = len(points) + len(ab) * np.arange(keys.size, dtype=np.int64)
        values = np.concatenate([values, fine_values.reshape(-1, est.groups)])
        points = np.concatenate([points, fine_points.reshape(-1, 3)])
        normals = np.concatenate([normals, np.repeat(normals[corners[:, 0]], len(ab), axis=0)])
        weighted = np.concatenate([weighted, np.repeat(weighted[corners[:, 0]], len(ab))])
    # Patches that differ strongly from a neighbour are split at half their size (their
    # points stay in the cache but no side refers to them any more).
    leaf = np.ones(len(p_point), dtype=bool)
    split_patches = 0
    for halving in range(1, int(patch_refine) + 1):
        radius = PATCH_KERNEL * p_size
        start, index = patch_neighbours(p_point, radius, p_reach)
        start, index = _visible_lists(engine, p_point, p_normal, *_kin_lists(start, index, leaf, p_weighted))
        split = _patches_to_split(values[p_row], p_point, p_normal, radius, start, index, contrast)
        if split.size == 0:
            break
        sides = np.flatnonzero(np.isin(leaf_of_side, split))
        finer = patch_sides(side_tris[sides], side_normal[sides], side_areas[sides],
                            spacing / 2 ** halving, origin=origin, label=side_weighted[sides])
        finer_weighted = _patch_weighting(finer, side_weighted[sides])
        leaf[split] = False
        split_patches += split.size
        first = len(p_point)
        leaf_of_side[sides] = first + finer.patch
        new_values = evaluate(finer.point, finer.normal, finer_weighted, next_block())
        p_row = np.concatenate([p_row, len(points) + np.arange(len(finer.point))])
        points = np.concatenate([points, finer.point])
        normals = np.concatenate([normals, finer.normal])
        weighted = np.concatenate([weighted, finer_weighted])
        values = np.concatenate([values, new_values])
        p_point = np.concatenate([p_point, finer.point])
        p_normal = np.concatenate([p_normal, finer.normal])
        p_weighted = np.concatenate([p_weighted, finer_weighted])
        p_reach = np.concatenate([p_reach, finer.reach])
        p_size = np.concatenate([p_size, np.full(len(finer.point), finer.size)])
        leaf = np.concatenate([leaf, np.ones(len(finer.point), dtype=bool)])
    # The cache keeps the leaf patches only, renumbered.
    keep = np.flatnonzero(leaf)
    renumber = np.full(len(leaf), -1, np.int64)
    renumber[keep] = np.arange(keep.size)
    radius = PATCH_KERNEL * p_size[keep]
    start, index = _visible_lists(engine, p_point[keep], p_normal[keep],
                                  *_kin_lists(*patch_neighbours(p_point[keep], radius, p_reach[keep]),
                                              np.ones(keep.size, bool), p_weighted[keep]))
    patch = np.full((len(scene.triangles), 2), -1, np.int64)
    patch[side_tri, side_of] = renumber[leaf_of_side]
    # each point's free distance along its normal: its validity radius (SurfaceCache.interpolate)
    clearance = engine.closest_hit(points + engine.epsilon * normals, normals)[1]
    return SurfaceCache(spacing, level, offset, values, points, keys, refined_offset, int(refine),
                        provenance={
        "nodes_per_point": int(est.draws * est.groups), "groups": int(est.groups),
        "near_distance_m": eps, "near_rays": est.near_rays, "direct_samples": int(direct_samples),
        "seed": int(seed), "grid_points": grid_points, "patch_points": int(first_points - grid_points),
        "refined_cells": int(keys.size), "split_patches": int(split_patches),
        "leaf_patches": int(keep.size), "points": len(values), "fresnel_weighted_points": int(weighted.sum()),
        "fresnel_rule": store.fresnel_rule,
        "refine_contrast": float(contrast),
        "build_time_s": time.perf_counter() - t0},
                        patch=patch, patch_row=p_row[keep], patch_normal=p_normal[keep],
                        patch_radius=radius, patch_start=start, patch_index=index,
                        clearance=clearance)


def _visible_lists(engine, point, normal, start, index):
    """The CSR neighbour lists ``start``/``index`` of patches restricted to the pairs whose
    points see each other (both moved a ray offset off their surfaces) and each patch
    itself: the far side of a thin solid or a sheet behind a wall never enters a kernel."""
    owner = np.repeat(np.arange(len(start) - 1), np.diff(start))
    keep = owner == index
    pair = np.flatnonzero(~keep)
    if pair.size:
        a, b = owner[pair], index[pair]
        keep[pair] = engine.visible(point[a] + engine.epsilon * normal[a],
                                    point[b] + engine.epsilon * normal[b])
    new_start = np.zeros_like(start)
    new_start[1:] = np.cumsum(np.bincount(owner[keep], minlength=len(start) - 1))
    return new_start, index[keep]


def _kin_lists(start, index, leaf, weighted):
    """The CSR lists ``start``/``index`` restricted to the leaf entries weighted as their row's
    patch (rows kept): a kernel never averages a Fresnel-weighted E_ind with a plain one."""
    owner = np.repeat(np.arange(len(start) - 1), np.diff(start))
    keepers = leaf[index] & (weighted[index] == weighted[owner])
    new_start = np.zeros_like(start)
    new_start[1:] = np.cumsum(np.bincount(owner[keepers], minlength=len(start) - 1))
    return new_start, index[keepers]


def _patch_weighting(patches, side_weighted):
    """Whether each patch of ``patches`` caches the Fresnel-weighted E_ind (its sides all do:
    :func:`patch_sides` keeps the weightings apart)."""
    out = np.zeros(len(patches.point), bool)
    out[patches.patch] = side_weighted
    return out


def render_cached(store, projection, *, position, rotation, cache=None,
                  direct_samples=DIRECT_SAMPLES, luminaire_draws=None, glossy_rays=GLOSSY_RAYS, seed=0,
                  chunk_pixels=8192, workers=1, progress=None):
    """Luminance map of a view from a surface cache: direct light per pixel, indirect
    interpolated [cd·m⁻²].

    Parameters
    ----------
    store : LsadStore
        A simulated store; its ``surface_cache`` is used unless ``cache`` is given (one is
        built with the defaults of :func:`build_surface_cache` when neither exists).
    projection, position, rotation
        As :func:`~lsadphoto.solver.render`.
    cache : SurfaceCache, optional
    direct_samples : int
        Shadow-ray samples per luminaire and pixel (:func:`direct_illuminance`).
    luminaire_draws : int, optional
        Luminaire draws per pixel where the direct light samples its luminaires
        (:func:`direct_illuminance`'s ``luminaires=K``; every luminaire when K is at least
        their number); default ``"auto"`` there.
    glossy_rays : int
        Scenes with non-Lambertian materials: rays from the glossy lobes per eye vertex and
        group (:func:`_material_chunk`; the diffuse parts at their hits come from the cache).
    seed : int
        Seed of the direct-light samples (and of the glossy rays).
    chunk_pixels, workers, progress
        As :func:`~lsadphoto.solver.render`; never change the result.

    Returns
    -------
    LuminanceMap
        Luminance, per-pixel uncertainty σ_total = √(σ_noise² + b²) — σ_noise from the
        direct part's sampling variance and the spread of the interpolated groups, b the
        estimated interpolation bias (:meth:`SurfaceCache.interpolate_with_bias`, per group:
        b² is its squared mean less that mean's variance) — and provenance, which keeps the
        parts apart (``pixel_relative_noise_*``, ``pixel_relative_bias_*``, and
        ``field_mean_relative_bias_estimate``, signed), and counts the pixels whose E_ind was
        estimated without the cache (``pixels_estimated_without_cache``) and the records they
        share (``pixel_records``; Notes).

    Notes
    -----
    Where a surface stands in front of a pixel's point not far beyond the cache points that
    interpolate it — the interpolation's support distance (the weights' mean distance to
    those points, :meth:`SurfaceCache.interpolate_with_bias`) exceeds :data:`PIXEL_VALIDITY`
    times the point's free distance along its normal — E_ind changes between the pixel and the
    points over distances the cache does not sample, and neither the interpolation nor its
    bias estimate, which sees the values only at the points, can follow it (the foot of a
    column behind a bench: E_ind halves below the points). Such a pixel takes E_ind from the
    cache's own unbiased estimator at its point instead (:func:`indirect_illuminance`, the
    cache's node draws, :data:`PIXEL_NEAR_RAYS` near-field paths per group, no bias): the
    validity test of Ward et al. (1988), with the smaller of the point's free distance along
    its normal and the harmonic mean of 12 probe rays' (:func:`_free_distance`; small
    triangles' sides only) for their harmonic mean distance over the hemisphere: a bench below a column's face lowers
    E_ind there though the normal ray passes over it. On small triangles' sides a pixel whose
    patch kernel leans to one side — its points' weighted centroid on the tangent plane lies
    farther than :data:`PIXEL_LEAN` times the support distance from the pixel, so that the
    kernel extrapolates — takes E_ind at its point too: the top of a column above the
    luminaires' plane, where E_ind falls beyond the top patch's points with nothing near to
    flag it.
    Neighbouring such pixels share one estimate, a *record* (:func:`_pixel_records`), so that
    their cost follows the area they cover, not the view's resolution; its size follows the
    distance to the nearest surface that the probe rays meet (the harmonic mean lets a bench
    seat just below a column face count little, while E_ind changes within that distance).
    Lambertian scenes only.
    """
    if not isinstance(store, LsadStore):
        raise BadInputError("render_cached needs an LsadStore (simulate the scene first)")
    scene = store.scene
    check_positive_int(glossy_rays, "glossy_rays")
    luminaires = "auto" if luminaire_draws is None else check_positive_int(luminaire_draws, "luminaire draws")
    if cache is None:
        cache = store.surface_cache or build_surface_cache(store, workers=workers)
    if not scene.lambertian and cache.provenance.get("fresnel_rule", "reciprocal") != store.fresnel_rule:
        raise BadInputError(f"the surface cache was built under the Fresnel rule "
                            f"{cache.provenance.get('fresnel_rule', 'reciprocal')!r}, the store's is "
                            f"{store.fresnel_rule!r}: build it from this store")
    position, rotation = check_pose(position, rotation)
    check_positive_int(workers, "workers")
    engine = engine_for(scene)
    t0 = time.perf_counter()
    valid, prim, dist, d = primary_rays(scene, engine, projection, position, rotation)
    hit = np.flatnonzero(prim >= 0)
    G = cache.values.shape[1]
    lum_b = np.zeros((valid.size, G))
    direct_var = np.zeros(valid.size)
    bias, bias_var = np.zeros(valid.size), np.zeros(valid.size)
    chunk = chunk_size(chunk_pixels)
    nodes = cache.provenance.get("nodes_per_point", CACHE_NODES)
    near_distance = cache.provenance.get("near_distance_m", RELATIVE_CACHE_NEAR_DISTANCE * scene.size)
    est = None if scene.lambertian else _MaterialIndirectEstimator(
        store, engine, nodes=nodes, near_distance=near_distance,
        direct_samples=direct_samples, luminaires=luminaires, seed=seed, key=1, connections=False)

    def meanwhile():
        """What the chunks do not need, made while they run: the estimator of E_ind at the
        pixels the cache does not resolve (Notes) and the pixels' solid angles."""
        at_pixel = None if not scene.lambertian else _IndirectEstimator(
            store, engine, nodes=nodes, near_distance=near_distance,
            direct_samples=cache.provenance.get("direct_samples", DIRECT_SAMPLES), seed=seed, key=2,
            near_rays=PIXEL_NEAR_RAYS)
        return at_pixel, pixel_solid_angles(projection, valid)

    # the pixels that take E_ind from records (Notes): their point, normal, nearest surface [m],
    # stream block, triangle side and ρ/π
    own = np.zeros(valid.size, dtype=bool)
    own_point, own_normal = np.zeros((valid.size, 3)), np.zeros((valid.size, 3))
    own_nearest, own_block, own_side, own_k = (np.zeros(valid.size), np.zeros(valid.size, np.int64),
                                            np.zeros(valid.size, np.int64), np.zeros(valid.size))

    def work(start):
        c = chunk_hits(scene, position, hit, prim, dist, d, start, chunk)
        if est is not None:
            out, direct_var[c.index], b = _material_chunk(est, cache, c, d, seed, glossy_rays)
            bias[c.index] = b.mean(axis=1)
            bias_var[c.index] = b.var(axis=1, ddof=1) / G
            return c.index, out
        out = np.repeat(c.emitted[:, None], G, axis=1)
        refl = np.flatnonzero(c.reflectance > 0)
        if refl.size:
            x = c.point[refl]
            e_dir, var = direct_illuminance(scene, engine, x, c.normal[refl],
                                            samples=direct_samples, seed=seed,
                                            block_ids=c.block[refl], luminaires=luminaires,
                                            distant_samples=DISTANT_RAYS_PER_DIRECT_SAMPLE * direct_samples)
            side = np.where(c.front[refl], 0, 1)
            e_ind, b, support, lean = cache.interpolate_with_bias(scene, c.triangle[refl], x, side, support=True)
            free, nearest = _free_distance(engine, x, c.normal[refl], ring=cache.level[c.triangle[refl]] == 0)
            k = (c.reflectance[refl] / math.pi)[:, None]
            unresolved = np.flatnonzero((PIXEL_VALIDITY * free < support) | (lean > PIXEL_LEAN * support))
            if unresolved.size:  # their E_ind comes after all chunks, from records
                e_ind[unresolved] = 0.0
                b[unresolved] = 0.0
                rows = c.index[refl][unresolved]
                own[rows] = True
                own_point[rows], own_normal[rows] = x[unresolved], c.normal[refl][unresolved]
                own_nearest[rows], own_block[rows] = nearest[unresolved], c.block[refl][unresolved]
                own_side[rows] = 2 * c.triangle[refl][unresolved] + side[unresolved]
                own_k[rows] = k[unresolved, 0]
            out[refl] += k * (e_dir[:, None] + e_ind)
            direct_var[c.index[refl]] = k[:, 0] ** 2 * var
            # the interpolation's bias per group: its mean, and the variance of that mean
            b = k * b
            bias[c.index[refl]] = b.mean(axis=1)
            bias_var[c.index[refl]] = b.var(axis=1, ddof=1) / G
        return c.index, out

    at_pixel, omega = run_chunks(work, range(0, hit.size, chunk), lum_b, int(workers), progress, t0, hit.size,
                                 meanwhile=meanwhile)
    rows = np.flatnonzero(own)
    records = 0
    if rows.size:
        e_ind, records = _pixel_records(at_pixel, own_point[rows], own_normal[rows], own_nearest[rows],
                                        own_side[rows], own_block[rows], workers=int(workers))
        lum_b[rows] += own_k[rows, None] * e_ind
    openings = luminous_openings(scene, position, d, dist)
    warn_odd_view(scene, engine, prim, dist, lum_b, position, openings=openings)
    return luminance_map_from_batches(
        projection, valid, lum_b, model=store,
        estimator="surface cache (direct per pixel, indirect interpolated" + (")" if est is None else
                                                                              "; glossy by sampled rays)"),
        openings=openings, shared_variance=direct_var, bias=bias, bias_variance=bias_var, solid_angles=omega,
        extra={"chains": int(store.chains), "nodes": int(store.nodes),
               "direct_samples": int(direct_samples), "luminaire_draws": luminaires, "seed": int(seed),
               "simulation_seed": int(store.seed),
               "cache_spacing_m": float(cache.spacing),
               "cache_points": int(cache.size),
               "cache_nodes_per_point": cache.provenance.get("nodes_per_point"),
               "fresnel_rule": store.fresnel_rule,
               **({} if est is not None else {"pixels_estimated_without_cache": int(rows.size),
                                              "pixel_records": int(records)}),
               **({} if est is None else {"glossy_rays": int(glossy_rays)}),
               "uncertainty": "noise and estimated interpolation bias in quadrature"},
        elapsed=time.perf_counter() - t0, pose=(position, rotation))


def _free_distance(engine, x, n, *, ring):
    """Free distance [m] in front of points ``x`` (unit normals ``n``): the distance along the
    normal, and where ``ring`` (bool per point) the smaller of it and the harmonic mean over
    two rings of 6 probe rays at :data:`PIXEL_PROBE_POLAR_DEG` from it (∞ where every ray
    leaves the scene); and the distance [m] to the nearest surface that those rays meet (the
    normal ray's where not ``ring``), which sizes a pixel's record (:func:`_pixel_records`).
    Ward et al. (1988) take the harmonic mean of the distances their cosine-weighted
    hemisphere samples travel; the rings sit at the middles of its two halves, in fixed
    directions, so that a pixel's value does not depend on chunks or threads. The normal ray
    alone (session 12) misses a surface standing beside the normal: the bench below a
    column's face just above its seat, whose effect the patch kernel — an average over 1.5
    patch sizes with a plane's bias — cannot see (station hall, docs/accuracy.md session
    13). :func:`render_cached` asks for the rings on small triangles' sides only: a grid's
    points reach the triangle's edges, refined where their values differ, and its
    second-difference bias follows a concave corner's profile, where the rings, counting the
    adjacent surface, flagged thousands of pixels for no gain (the canonical room at 512²:
    5325 pixels against 74, CPU 9–11 → 41–43 s)."""
    lift = x + engine.epsilon * n
    along = engine.closest_hit(lift, n)[1]
    if not np.any(ring):
        return along, along.copy()
    nearest = along.copy()
    x, n, lift = x[ring], n[ring], lift[ring]
    t1, t2 = orthonormal_basis(n)
    inverse = np.zeros(len(x))
    near = along[ring]
    rays = 0
    with np.errstate(divide="ignore"):
        for polar in np.radians(PIXEL_PROBE_POLAR_DEG):
            for azimuth in np.radians(np.arange(0.0, 360.0, 60.0)):
                d = math.cos(polar) * n + math.sin(polar) * (math.cos(azimuth) * t1 + math.sin(azimuth) * t2)
                hit = engine.closest_hit(lift, d)[1]
                inverse += 1.0 / hit  # 0 for a ray that leaves the scene
                near = np.minimum(near, hit)
                rays += 1
        nearest[ring] = near
        along[ring] = np.minimum(along[ring], rays / inverse)
    return along, nearest


def _pixel_records(est, x, n, nearest, side, block, *, workers):
    """E_ind [lx] per group, shape (P, groups), at pixel points ``x`` (normals ``n``, distances
    ``nearest`` [m] to their nearest surface, triangle sides ``side``, stream blocks ``block``; in
    the view's pixel order) from records: the pixels of one side in one cube of edge
    :data:`PIXEL_RECORD` × 2^⌊log₂ t⌋ (the same power of two of their distance t) take
    ``est``'s estimate at the first of them, drawn from that pixel's block's streams (so the
    map depends neither on chunks nor on threads); and the number of records."""
    scale = np.exp2(np.floor(np.log2(np.maximum(nearest, est.engine.epsilon))))  # 0 where surfaces touch
    cube = np.floor(x / (PIXEL_RECORD * scale)[:, None]).astype(np.int64)
    key = np.column_stack([side, np.log2(scale).astype(np.int64), cube])
    _, first, record = np.unique(key, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)  # the records in the order of their first pixel
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    first, record = first[order], rank[record.ravel()]
    values = np.zeros((first.size, est.groups))
    starts = np.flatnonzero(np.r_[True, np.diff(block[first]) != 0])
    ends = dict(zip(starts.tolist(), np.r_[starts[1:], first.size].tolist()))

    def work(start):
        rows = first[start:ends[start]]
        return np.arange(start, ends[start]), est.estimate(x[rows], n[rows], block[rows])

    run_chunks(work, starts.tolist(), values, workers, None, time.perf_counter(), first.size)
    return values[record], first.size


# --- scenes with glossy, specular and transmitting materials ---------------------------------


def _diffuse_coefficients(scene):
    """Diffuse reflection and transmission coefficients kd, td [–] of every material at normal
    incidence μ_o = 1 (f_d = kd·g/π on the side of ω_o, td·g/π on the other; they depend on μ_o
    where a Fresnel factor applies, and are positive at every μ_o where they are at 1)."""
    bsdf = scene.bsdf
    p = bsdf.parts(np.arange(len(bsdf.materials)), np.ones(len(bsdf.materials)))
    return p["kd"], p["td"]


def _uniforms_by(seed, group, blocks, cols, *keys):
    """Uniforms (rows, cols), each (group, block) pair of rows from its own stream
    ``(seed, "cache", *keys[:1], group, *keys[1:], block)``, in row order."""
    out = np.empty((len(group), cols))
    if not len(group):
        return out
    span = int(blocks.max()) + 1
    key = group * span + blocks
    for k in np.unique(key):
        m = key == k
        out[m] = stream(seed, "cache", keys[0], int(k // span), *keys[1:], int(k % span)).random((int(m.sum()), cols))
    return out


class _MaterialIndirectEstimator(_NodeHull):
    """E_ind at points of a scene with non-Lambertian materials, per group of node draws.

    E_ind is the irradiance from everything but the luminaires seen directly or through
    straight transmitters (which :func:`~lsadphoto.solver.direct.direct_illuminance` gives
    with their transmittance): the light whose last non-delta scattering is at a surface
    node y farther than ε, reaching the point directly or through glass — the **far part**,
    Σ W·f_y(ω_in, ω_{y→x})·|μ_y|·cos θ_x·T/r² over nodes of depth ≥ 1 drawn ∝ W (stratified
    along a Morton curve, as the Lambertian cache), f_y the node's whole non-delta BSDF — and
    the rest by cosine-sampled paths (:meth:`_rays`): surfaces closer than ε (near field) and
    everything relayed by a delta reflection (a mirror, a glass pane's or smooth plastic's
    reflection: luminaires included), which no connection reaches.
    """

    def __init__(self, store, engine, *, nodes, near_distance, direct_samples, seed, key,
                 near_rays=MATERIAL_NEAR_RAYS, connections=True, luminaires="auto"):
        """``connections=False``: without the node pools of the far part (rendering from a
        cache needs only the next-event estimates and the direct part); ``luminaires``: the
        direct light's luminaire draws (:func:`direct_illuminance`)."""
        from ..chains import EmissionSampler

        scene = store.scene
        self.store, self.scene, self.engine = store, scene, engine
        self.rule = store.fresnel_rule   # the smooth materials' 1 − F(μ_i) (FRESNEL_RULES)
        self.near_distance, self.eps2 = near_distance, near_distance ** 2
        self.direct_samples, self.seed, self.key = direct_samples, seed, key
        self.luminaires = luminaires
        self.groups = G = min(GROUPS, store.batches)
        self.chains_per_group = store.chains / G
        self.draws = max(1, int(nodes) // G)
        self.near_draws = max(1, self.draws // 8)
        self.near_rays = int(near_rays)
        surface = np.flatnonzero(store.depth > 0) if connections else np.zeros(0, np.int64)
        self.pools, self.cdfs, self.totals = [], [], []
        for pool in self._pools_along_curve(surface, G):
            w = store.coefficient[pool]
            total = float(w.sum())
            self.pools.append(pool)
            self.totals.append(total)
            self.cdfs.append(np.cumsum(w) / total if total > 0 else None)
        # each surface node's BSDF components towards its incoming direction (fixed per node)
        mu = np.clip(np.einsum("ij,ij->i", store.normal[surface], store.incoming[surface]), 1e-3, 1.0)
        self.node_parts = scene.bsdf.parts(scene.material[store.triangle[surface]], mu)
        self.node_row = np.full(store.nodes, -1, np.int64)
        self.node_row[surface] = np.arange(surface.size)
        # point-luminaire emission points (source nodes) per group, along a Morton curve (the
        # draws are stratified over it): the glossy part's next-event estimate (no ray can
        # hit a point)
        point = np.flatnonzero((store.depth == 0) & (store.kind != KIND_COSINE))
        self.point_pools = self._pools_along_curve(point, G)
        # area-luminaire emission points per group, and each luminaire's emission-point
        # density per unit area (Φ_l/Φ)/A_l (the glossy part's next-event estimate)
        emit = np.flatnonzero((store.depth == 0) & (store.kind == KIND_COSINE) & (store.triangle >= 0))
        self.emit_pools = self._pools_along_curve(emit, G)
        self.sampler = EmissionSampler(scene) if point.size or emit.size else None
        self.area_density = np.array([lum.flux / (scene.total_flux * scene.areas[lum.triangles].sum())
                                      for lum in scene.area_luminaires])
        self.luminaire_table = self._luminaire_table(near_distance)

    # -- connections -----------------------------------------------------------------------

    def far(self, x, n, group, blocks, level, draws=None, wo=None, mat=None, fresnel=None):
        """Far part [lx, or cd·m⁻² with ``mat``] at points ``x`` (normals ``n``) of one group:
        (ΣW/k)/N_g · Σ_draws f_y|μ_y|·h_x·T/r² over k nodes drawn ∝ W, stratified; h_x = cos θ_x
        (irradiance, cos θ_x > 0 only; times 1 − F(cos θ_x) at the cache points where
        ``fresnel``: the Fresnel-weighted irradiance) or, at a path vertex of material ``mat``
        seen from ``wo``, f_x(ω_{x→y}, ω_o)·|cos θ_x| (its whole non-delta BSDF, both sides)."""
        P = len(x)
        cdf = self.cdfs[group]
        if P == 0 or cdf is None:
            return np.zeros(P)
        k = self.draws if draws is None else draws
        u = _uniforms_by(self.seed, np.full(P, group), blocks, k, self.key, level)
        v = (np.arange(k)[None, :] + u) / k
        pick = self.pools[group][np.minimum(np.searchsorted(cdf, v.ravel()), cdf.size - 1)]
        owner = np.repeat(np.arange(P), k)
        return np.bincount(owner, weights=self._terms(pick, owner, x, n, wo, mat, fresnel), minlength=P) * (
            self.totals[group] / k / self.chains_per_group)

    def _terms(self, pick, owner, x, n, wo, mat, fresnel):
        """f_y|μ_y|·h_x·T/r² of the pairs (point ``owner``, node ``pick``), 0 closer than ε."""
        st, bsdf, eps = self.store, self.scene.bsdf, self.engine.epsilon
        y, ny = st.position[pick], st.normal[pick]
        v = y - x[owner]
        r2 = np.einsum("ij,ij->i", v, v)
        w = v / np.sqrt(np.maximum(r2, 1e-300))[:, None]
        nx = n[owner]
        cos_x = np.einsum("ij,ij->i", w, nx)
        cos_y = -np.einsum("ij,ij->i", w, ny)
        if mat is None:
            h = np.where(cos_x > 0, cos_x, 0.0)
            if fresnel is not None:
                h *= diffuse_fresnel_factor(cos_x, fresnel[owner])
        else:
            h = bsdf.evaluate(mat[owner], nx, wo[owner], w, rule=self.rule, direct=False) * np.abs(cos_x)
        far = r2 >= self.eps2
        live = np.flatnonzero(far & (h > 0))
        val = np.zeros(len(pick))
        if not live.size:
            return val
        p = pick[live]
        rows = self.node_row[p]
        f_y = bsdf.evaluate(self.scene.material[st.triangle[p]], ny[live], st.incoming[p], -w[live],
                            parts={key: value[rows] for key, value in self.node_parts.items()},
                            rule=self.rule, direct=st.direct[p], adjoint=True)
        val[live] = f_y * np.abs(cos_y[live]) * h[live] / r2[live]
        ok = live[val[live] > 0]
        if ok.size:
            origin = x[owner[ok]] + eps * np.sign(cos_x[ok])[:, None] * nx[ok]
            target = y[ok] + eps * np.sign(cos_y[ok])[:, None] * ny[ok]
            val[ok] *= shadow_transmittance(self.scene, self.engine, origin, target)
        return val

    def _draw_from_pools(self, pools, draws, count, group, blocks, level, tag):
        """``draws`` nodes per point from the pool (one per group, ordered along a Morton
        curve) of each of ``count`` points' ``group``, stratified: draw j uniformly from the
        j-th of ``draws`` equal slices of the pool (every node keeps the probability
        draws/size of a uniform draw, so (size/draws)·Σ_j is unbiased, while each luminaire —
        a stretch of the curve — gets its share of the draws instead of a binomial number of
        them). Returns the points' rows (``owner``, points whose pool is empty left out), the
        nodes' indices in the store (``pick``) and each point's pool size."""
        u = _uniforms_by(self.seed, group, blocks, draws, tag, self.key, level)
        u = (np.arange(draws)[None, :] + u) / draws
        size = np.array([len(p) for p in pools])[group]
        owner = np.repeat(np.arange(count), draws)
        live = size[owner] > 0
        owner = owner[live]
        local = np.minimum((u.ravel()[live] * size[owner]).astype(np.int64), size[owner] - 1)
        offsets = np.cumsum([0] + [len(p) for p in pools])
        return owner, np.concatenate(pools)[offsets[group[owner]] + local], size

    def point_glossy(self, x, n, wo, mat, group, blocks, level, tag):
        """Glossy part [cd·m⁻²] of the light of point luminaires (intensity distributions,
        luminous rectangles) that points reflect or transmit towards ``wo``, per row of
        ``group``: POINT_DRAWS emission points (source nodes of the row's group) drawn
        uniformly, (count/k)/N_g·Σ c·I(ω_{y→x})·f_g·|cos θ_x|·T/r² — the next-event estimate
        of what no sampled ray can hit."""
        out = np.zeros(len(x))
        if not self.scene.point_luminaires or not len(x):
            return out
        st = self.store
        owner, pick, size = self._draw_from_pools(self.point_pools, POINT_DRAWS, len(x), group, blocks,
                                                  level, tag)
        v = st.position[pick] - x[owner]
        r2 = np.einsum("ij,ij->i", v, v)
        w = v / np.sqrt(np.maximum(r2, 1e-300))[:, None]
        cos_x = np.einsum("ij,ij->i", w, n[owner])
        _, f_g = self.scene.bsdf.evaluate(mat[owner], n[owner], wo[owner], w, split=True)
        val = f_g * np.abs(cos_x) * st.coefficient[pick] * self.sampler.point_intensity(st.luminaire[pick], -w) / \
            np.maximum(r2, 1e-300)
        ok = np.flatnonzero(val > 0)
        if ok.size:
            origin = x[owner[ok]] + self.engine.epsilon * np.sign(cos_x[ok])[:, None] * n[owner[ok]]
            val[ok] *= shadow_transmittance(self.scene, self.engine, origin, st.position[pick[ok]])
        scale = size[owner] / POINT_DRAWS / self.chains_per_group
        return np.bincount(owner, weights=val * scale, minlength=len(x))

    def light_weight(self, prim, r2, cos_y, p_rays):
        """Balance-heuristic weight w_L = p_L/(p_L + p_rays) of the emitter next-event estimate
        for points on emitting triangles ``prim`` at squared distance ``r2`` seen at cos θ_y:
        p_L = :data:`EMITTER_DRAWS`·(Φ_l/Φ)/A_l·r²/cos θ_y, the solid-angle density of its
        draws; ``p_rays`` = rays × the lobe sampler's density of that direction."""
        p_l = EMITTER_DRAWS * self.area_density[self.scene.emitter[prim]] * r2 / np.maximum(cos_y, 1e-12)
        return p_l / np.maximum(p_l + p_rays, 1e-300)

    def emitter_glossy(self, x, n, wo, mat, group, blocks, level, tag, rays, p_scale):
        """Glossy part [cd·m⁻²] of the area luminaires' light that points reflect or
        transmit towards ``wo``, by :data:`EMITTER_DRAWS` emission points (source nodes of the
        row's group) drawn uniformly, (count/k)/N_g·Σ c·cos θ_y·f_g·|cos θ_x|·T/r²·w_L — the
        next-event half of the balance heuristic whose other half is the lobe-sampled rays
        (``rays`` of them, each drawn with ``p_scale`` × :meth:`~lsadphoto.solver.materials.MaterialTable.pdf_glossy`;
        per row)."""
        out = np.zeros(len(x))
        if not self.area_density.size or not len(x):
            return out
        st, bsdf = self.store, self.scene.bsdf
        owner, pick, size = self._draw_from_pools(self.emit_pools, EMITTER_DRAWS, len(x), group, blocks,
                                                  level, tag)
        y, ny = st.position[pick], st.normal[pick]
        v = y - x[owner]
        r2 = np.einsum("ij,ij->i", v, v)
        w = v / np.sqrt(np.maximum(r2, 1e-300))[:, None]
        cos_x = np.einsum("ij,ij->i", w, n[owner])
        cos_y = np.maximum(-np.einsum("ij,ij->i", w, ny), 0.0)
        m, nx, wx = mat[owner], n[owner], wo[owner]
        parts = bsdf.parts(m, np.clip(np.einsum("ij,ij->i", nx, wx), 1e-3, 1.0))
        _, f_g = bsdf.evaluate(m, nx, wx, w, parts=parts, split=True)
        val = f_g * np.abs(cos_x) * st.coefficient[pick] * cos_y / np.maximum(r2, 1e-300)
        ok = np.flatnonzero(val > 0)
        if ok.size:
            p_rays = (rays * p_scale)[owner[ok]] * bsdf.pdf_glossy(m[ok], nx[ok], wx[ok], w[ok],
                                                                   {key: v[ok] for key, v in parts.items()})
            val[ok] *= self.light_weight(st.triangle[pick[ok]], r2[ok], cos_y[ok], p_rays)
            origin = x[owner[ok]] + self.engine.epsilon * np.sign(cos_x[ok])[:, None] * nx[ok]
            val[ok] *= shadow_transmittance(self.scene, self.engine, origin, y[ok] + self.engine.epsilon * ny[ok])
        scale = size[owner] / EMITTER_DRAWS / self.chains_per_group
        return np.bincount(owner, weights=val * scale, minlength=len(x))

    def distant_glossy(self, x, n, wo, mat, group, blocks, level, tag):
        """Glossy part [cd·m⁻²] of the light of the distant sources (sun, sky) that points
        reflect or transmit towards ``wo``, next-event estimated with
        :data:`DISTANT_GLOSSY_SAMPLES` stratified directions per source
        (:func:`~lsadphoto.solver.sky.distant_reflection`, through glass with its T); the
        rays that leave the scene after a non-delta vertex count no background."""
        sources = len(self.scene.distant_sources)
        if not sources or not len(x):
            return np.zeros(len(x))
        u = _uniforms_by(self.seed, group, blocks, sources * DISTANT_GLOSSY_SAMPLES * 2, tag, self.key, level)
        u = stratified(u.reshape(len(x), sources, DISTANT_GLOSSY_SAMPLES, 2))
        return distant_reflection(self.scene, self.engine, x, n, wo, mat, u)[1]

    def direct_diffuse(self, y, ny, parts, keys, distant_samples=None):
        """kd/π·E_dir(front) + td/π·E_dir(back) [cd·m⁻²] at points ``y`` (facing normals
        ``ny``; kd, td and the Fresnel flag from ``parts``, :meth:`~lsadphoto.solver.materials.MaterialTable.parts`
        at the points' μ_o), E_dir Fresnel-weighted on smooth plastic, metal and trans
        (``fresnel`` of :func:`direct_illuminance`), and its sampling variance
        (``distant_samples``: shadow rays per distant source, default ``direct_samples``)."""
        out, var = np.zeros(len(y)), np.zeros(len(y))
        fresnel = parts["fresnel"]
        for coef, sign in ((parts["kd"], 1.0), (parts["td"], -1.0)):
            m = np.flatnonzero(coef > 0)
            if not m.size:
                continue
            sub = {k: (v[m] if isinstance(v, np.ndarray) else v) for k, v in keys.items()}
            if self.luminaire_table is None:
                e, v = direct_illuminance(self.scene, self.engine, y[m], sign * ny[m],
                                          samples=self.direct_samples, distant_samples=distant_samples,
                                          luminaires=self.luminaires, fresnel=fresnel[m], fresnel_rule=self.rule,
                                          **sub)
            else:
                e, v = sampled_direct_illuminance(self.scene, self.engine, y[m], sign * ny[m],
                                                  table=self.luminaire_table, fresnel=fresnel[m],
                                                  fresnel_rule=self.rule, **sub), 0.0
            out[m] += coef[m] / math.pi * e
            var[m] += (coef[m] / math.pi) ** 2 * v
        return out, var

    # -- the cache points ------------------------------------------------------------------

    def estimate(self, x, n, blocks, fresnel=None):
        """E_ind [lx] at points ``x`` (normals ``n``), shape (P, groups); Fresnel-weighted,
        E_F,ind = ∫(1 − F(μ_i))·L_ind·μ_i dω, at the points where ``fresnel`` (bool, (P,)):
        what the diffuse part of smooth plastic, metal and trans scatters."""
        out = np.zeros((len(x), self.groups))
        lit = np.flatnonzero(self._facing_nodes(x, n))
        sub = None if fresnel is None else fresnel[lit]
        for g in range(self.groups):
            out[lit, g] = self.far(x[lit], n[lit], g, blocks[lit], 0, fresnel=sub)
        return out + self._rays(x, n, blocks, fresnel)

    def _rays(self, x0, n0, blocks0, fresnel=None):
        """The part of E_ind no far connection gives, per group: the mean of ``near_rays``
        cosine-sampled paths per point and group (estimator π·L). A path carries the weight
        w of what no connection covers and the weight w_e of emission it may count:

        * leaving the point, w = π (π·(1 − F(μ_i)) of the sampled direction at the points
          where ``fresnel``), w_e = 0 (the luminaires, seen directly or through glass, are
          the direct part);
        * at a hit y, its emission counts w_e; its non-delta light counts w where no
          connection covered it — closer than ε along the path from the last non-delta
          vertex, or after a delta reflection — as kd/π·E_dir + td/π·E_dir(back) + the far
          part with y's whole BSDF (:meth:`far`) + the glossy part of point luminaires, and
          the path goes on by y's whole BSDF (w_e ← w·f_g/f: the diffuse part of the direct
          light is counted); where covered, only y's delta parts go on;
        * a delta reflection makes every later term count (w_e ← w); a straight-through
          transmission keeps the state, and its T multiplies both;
        * Russian roulette min(1, sample weight) after the first ray.
        """
        scene, engine, bsdf = self.scene, self.engine, self.scene.bsdf
        eps = engine.epsilon
        G, R, P = self.groups, self.near_rays, len(x0)
        point = np.repeat(np.arange(P), G * R)
        group = np.tile(np.repeat(np.arange(G), R), P)
        blocks = blocks0[point]
        row = np.arange(P * G * R)
        total = np.zeros(P * G * R)
        w, w_e = np.full(row.size, math.pi), np.zeros(row.size)
        w_bg = np.zeros(row.size)    # weight of the background (sun, sky) if the ray leaves
        covered = np.ones(row.size, bool)
        travelled = np.zeros(row.size)
        u = _uniforms_by(self.seed, group, blocks, 2, _TAG_RAYS, self.key, 0)
        d = cosine_directions(n0[point], u)
        if fresnel is not None:
            w *= diffuse_fresnel_factor(np.einsum("ij,ij->i", d, n0[point]), fresnel[point])
        origin = x0[point] + eps * n0[point]
        for level in range(1, MAX_PATH_VERTICES + 1):
            prim, dist = engine.closest_hit(origin, d)
            hit = prim >= 0
            away = np.flatnonzero(~hit & (w_bg > 0))
            if away.size:
                total[row[away]] += w_bg[away] * background_luminance(scene, d[away])
            (row, group, blocks, w, w_e, w_bg, covered, travelled, origin, d, prim, dist) = (
                a[hit] for a in (row, group, blocks, w, w_e, w_bg, covered, travelled, origin, d, prim, dist))
            if not row.size:
                break
            y = origin + dist[:, None] * d
            ny, front = scene.facing_normals(prim, d)
            wo, mat = -d, scene.material[prim]
            travelled = travelled + dist
            total[row] += w_e * emitted_luminance(scene, prim, wo)
            counted = ~covered | (travelled < self.near_distance)
            parts = bsdf.parts(mat, np.clip(np.einsum("ij,ij->i", ny, wo), 1e-3, 1.0), front)
            nd = np.flatnonzero(counted & (parts["kd"] + parts["td"] + parts["rs"] + parts["ts"] > 0))
            if nd.size:
                keys = {"seed": self.seed, "block_ids": blocks[nd] * G + group[nd],
                        "purpose_key": self._direct_key(level)}
                value, _ = self.direct_diffuse(y[nd], ny[nd], {k: v[nd] for k, v in parts.items()}, keys)
                for g in np.unique(group[nd]):
                    m = np.flatnonzero(group[nd] == g)
                    value[m] += self.far(y[nd[m]], ny[nd[m]], int(g), blocks[nd[m]], level, self.near_draws,
                                         wo[nd[m]], mat[nd[m]])
                value += self.point_glossy(y[nd], ny[nd], wo[nd], mat[nd], group[nd], blocks[nd], level,
                                           _TAG_POINT)
                value += self.distant_glossy(y[nd], ny[nd], wo[nd], mat[nd], group[nd], blocks[nd], level,
                                             _TAG_POINT + 2)
                total[row[nd]] += w[nd] * value
            # the continuation: y's whole BSDF where its non-delta light counted, its deltas elsewhere
            u = _uniforms_by(self.seed, group, blocks, 4, _TAG_RAYS, self.key, level)
            wi, weight, delta, _ = bsdf.sample(mat, ny, wo, u[:, :3], front, rule=self.rule, direct=False)
            glossy_share = np.zeros(row.size)
            full = np.flatnonzero(counted & ~delta & (weight > 0))
            if full.size:
                f_d, f_g = bsdf.evaluate(mat[full], ny[full], wo[full], wi[full], split=True, rule=self.rule,
                                         direct=False)
                glossy_share[full] = f_g / np.maximum(f_d + f_g, 1e-300)
            only = np.flatnonzero(~counted)
            if only.size:
                # a delta reflection relays light no connection covers, a straight transmission
                # in this state mostly leads to covered light: where both exist (glass) each is
                # chosen with probability ½ (weight R/½ or T/½) rather than in proportion
                r_, t_ = parts["R"][only], parts["T"][only]
                p_r = np.where(t_ > 0, np.where(r_ > 0, 0.5, 0.0), 1.0)
                refl = u[only, 0] < p_r
                mu = np.einsum("ij,ij->i", ny[only], wo[only])
                wi[only] = np.where(refl[:, None], 2 * mu[:, None] * ny[only] - wo[only], -wo[only])
                weight[only] = np.where(refl, r_ / np.maximum(p_r, 1e-300), t_ / np.maximum(1 - p_r, 1e-300))
                delta[only] = True
            reflected = delta & (np.einsum("ij,ij->i", wi, ny) > 0)
            straight = delta & ~reflected
            w_e = np.where(reflected, w, np.where(straight, w_e, w * glossy_share)) * weight
            # the background after a delta reflection (next-event estimates cannot follow one)
            w_bg = np.where(reflected, w, np.where(straight, w_bg, 0.0)) * weight
            covered = np.where(delta, covered & straight, True)
            travelled = np.where(delta, travelled, 0.0)
            w = w * weight
            q = np.minimum(weight, 1.0)
            go = (weight > 0) & (u[:, 3] < q)
            side = np.where(np.einsum("ij,ij->i", wi, ny) > 0, 1.0, -1.0)[:, None]
            (row, group, blocks, w, w_e, w_bg, covered, travelled, origin, d, q) = (
                a[go] for a in (row, group, blocks, w, w_e, w_bg, covered, travelled, y + eps * side * ny, wi, q))
            w, w_e, w_bg = w / q, w_e / q, w_bg / q
            if not row.size:
                break
        return total.reshape(P, G, R).mean(axis=2)


def _glossy_paths(est, cache, seed, x, n, wo, mat, parts, group, blocks, level, rays):
    """Per-row estimates [cd·m⁻²] of the glossy part of the luminance leaving ``x`` towards
    ``wo``: a ray from the glossy lobes (:meth:`~lsadphoto.solver.materials.MaterialTable.sample_glossy`,
    weight f_g|μ|/p_g), whose hit y adds its emission, its diffuse part from the cache —
    kd/π·(E_dir + E_ind) + td/π·(E_dir + E_ind)(back), E_ind interpolated in the row's
    group — and the glossy light of point and area luminaires (next-event; the rays' emission
    hits weighted by the balance heuristic's complement), and goes on by y's glossy
    and delta parts (chosen in proportion to rs + ts, R, T; Russian roulette min(1, weight)):
    a path tracer whose diffuse parts are the cache's. Returns ``(total, bias)``: the
    estimates and, per row, the path-weighted sum of the estimated interpolation bias of
    the cached values at its hits (:meth:`~lsadphoto.solver.cache_grid.SurfaceCache.interpolate_with_bias`
    in the row's group)."""
    scene, engine, bsdf = est.scene, est.engine, est.scene.bsdf
    eps, G = engine.epsilon, cache.values.shape[1]
    total, bias = np.zeros(len(x)), np.zeros(len(x))
    row = np.arange(len(x))
    u = _uniforms_by(seed, group, blocks, 2, _TAG_GLOSSY, level, 0)
    wi, w, pdf = bsdf.sample_glossy(mat, n, wo, u, parts)
    delta = np.zeros(len(x), bool)   # whether the ray left a delta reflection or transmission
    # for the balance heuristic with the emitters' next-event estimate: rays × density of the
    # last lobe sample (0 after a delta reflection) and the distance travelled since
    p_rays, travelled = rays * pdf, np.zeros(len(x))
    side = np.where(np.einsum("ij,ij->i", wi, n) > 0, 1.0, -1.0)[:, None]
    origin, d = x + eps * side * n, wi
    for depth in range(1, MAX_PATH_VERTICES + 1):
        go = w > 0
        row, group, blocks, w, delta, origin, d, p_rays, travelled = (
            a[go] for a in (row, group, blocks, w, delta, origin, d, p_rays, travelled))
        if not row.size:
            break
        prim, dist = engine.closest_hit(origin, d)
        hit = prim >= 0
        away = np.flatnonzero(~hit & delta)
        if away.size and scene.distant_sources:  # after a lobe, the next-event estimate has it
            total[row[away]] += w[away] * background_luminance(scene, d[away])
        row, group, blocks, w, origin, d, prim, dist, p_rays, travelled = (
            a[hit] for a in (row, group, blocks, w, origin, d, prim, dist, p_rays, travelled))
        if not row.size:
            break
        travelled = travelled + dist
        y = origin + dist[:, None] * d
        ny, front = scene.facing_normals(prim, d)
        wo_y, mat_y = -d, scene.material[prim]
        value = emitted_luminance(scene, prim, wo_y)
        lit = np.flatnonzero((value > 0) & (p_rays > 0) & (scene.emitter[prim] >= 0))
        if lit.size:  # the rays' share of the balance heuristic
            cos_y = np.abs(np.einsum("ij,ij->i", scene.normals[prim[lit]], d[lit]))
            value[lit] *= 1 - est.light_weight(prim[lit], travelled[lit] ** 2, cos_y, p_rays[lit])
        p = bsdf.parts(mat_y, np.clip(np.einsum("ij,ij->i", ny, wo_y), 1e-3, 1.0), front)
        diff = np.flatnonzero(p["kd"] + p["td"] > 0)
        if diff.size:
            keys = {"seed": seed, "block_ids": blocks[diff] * G + group[diff], "purpose_key": 30000 + 64 * level + depth}
            sub = {key: v[diff] for key, v in p.items()}
            value[diff] += est.direct_diffuse(y[diff], ny[diff], sub, keys)[0]
            cached, b = _cached_diffuse(est, cache, prim[diff], y[diff], front[diff], sub, with_bias=True)
            value[diff] += cached[np.arange(diff.size), group[diff]]
            bias[row[diff]] += w[diff] * b[np.arange(diff.size), group[diff]]
        gl = np.flatnonzero(p["rs"] + p["ts"] > 0)
        if gl.size:
            value[gl] += est.point_glossy(y[gl], ny[gl], wo_y[gl], mat_y[gl], group[gl], blocks[gl],
                                          64 * level + depth, _TAG_POINT + 4)
            value[gl] += est.distant_glossy(y[gl], ny[gl], wo_y[gl], mat_y[gl], group[gl], blocks[gl],
                                            64 * level + depth, _TAG_POINT + 5)
            s_gl = p["rs"][gl] + p["ts"][gl]
            value[gl] += est.emitter_glossy(y[gl], ny[gl], wo_y[gl], mat_y[gl], group[gl], blocks[gl],
                                            64 * level + depth, _TAG_POINT + 6, np.ones(gl.size),
                                            s_gl / (s_gl + p["R"][gl] + p["T"][gl]))
        total[row] += w * value
        # go on by the glossy lobes or the deltas, in proportion to their coefficients
        u = _uniforms_by(seed, group, blocks, 4, _TAG_GLOSSY, level, depth)
        g_sum = p["rs"] + p["ts"]
        s_all = g_sum + p["R"] + p["T"]
        c = u[:, 0] * s_all
        lobe, refl = c < g_sum, (c >= g_sum) & (c < g_sum + p["R"])
        weight = np.where(s_all > 0, s_all, 0.0)
        mu = np.einsum("ij,ij->i", ny, wo_y)
        wi = np.where(refl[:, None], 2 * mu[:, None] * ny - wo_y, -wo_y)
        k = np.flatnonzero(lobe & (g_sum > 0))
        if k.size:
            uu = np.stack([c[k] / g_sum[k], u[k, 1]], axis=1)
            wi[k], wg, pdf = bsdf.sample_glossy(mat_y[k], ny[k], wo_y[k], uu, {key: v[k] for key, v in p.items()})
            weight[k] = wg * s_all[k] / g_sum[k]
        straight = ~lobe & ~refl
        p_rays = np.where(straight, p_rays, 0.0)
        travelled = np.where(straight, travelled, 0.0)
        if k.size:
            p_rays[k] = pdf * g_sum[k] / s_all[k]
        q = np.minimum(weight, 1.0)
        go = u[:, 3] < q
        w = np.where(go, w * weight / np.maximum(q, 1e-300), 0.0)
        delta = ~lobe
        side = np.where(np.einsum("ij,ij->i", wi, ny) > 0, 1.0, -1.0)[:, None]
        origin, d = y + eps * side * ny, wi
    return total, bias


def _cached_diffuse(est, cache, prim, y, front, parts, *, with_bias=False):
    """kd/π·E_ind(front) + td/π·E_ind(back) [cd·m⁻²] from the cache per group, shape (n, G)
    (kd, td from ``parts`` at the points' μ_o; E_ind as cached: Fresnel-weighted on smooth
    plastic, metal and trans), and with ``with_bias`` its estimated interpolation bias (else None)."""
    side = np.where(front, 0, 1)
    G = cache.values.shape[1]
    out = np.zeros((len(y), G))
    bias = np.zeros((len(y), G)) if with_bias else None
    for coef, s in ((parts["kd"], side), (parts["td"], 1 - side)):
        m = np.flatnonzero(coef > 0)
        if m.size:
            k = (coef[m] / math.pi)[:, None]
            if with_bias:
                e_ind, e_bias = cache.interpolate_with_bias(est.scene, prim[m], y[m], s[m])
                bias[m] += k * e_bias
            else:
                e_ind = cache.interpolate(est.scene, prim[m], y[m], s[m])
            out[m] += k * e_ind
    return out, bias


def _material_chunk(est, cache, c, d, seed, glossy_rays):
    """Per-group luminance (n, G) [cd·m⁻²] of a chunk of primary hits ``c`` of a scene with
    materials, the direct part's sampling variance and the interpolation bias per group.

    The eye path is followed through delta surfaces as by the material local estimate (split
    at the first :data:`~.local_estimate.DELTA_SPLITS` vertices with both R and T, else one
    chosen in proportion to R and T); at each vertex x, kd/π·(E_dir + E_ind)(x) + td/π·(E_dir
    + E_ind)(back of x), E_dir per pixel with its shadow transmittance and E_ind interpolated
    per group, plus the glossy part by ``glossy_rays`` rays per group
    (:func:`_glossy_paths`) and the glossy light of point and area luminaires and of the sun and sky
    (next-event)."""
    from .local_estimate import DELTA_SPLITS, MAX_DELTA_BOUNCES

    scene, engine, bsdf = est.scene, est.engine, est.scene.bsdf
    eps, G = engine.epsilon, cache.values.shape[1]
    P = c.index.size
    out = np.repeat(c.emitted[:, None], G, axis=1)
    direct_var = np.zeros(P)
    bias = np.zeros((P, G))
    pix, x, n, front, tri, blocks = np.arange(P), c.point, c.normal, c.front, c.triangle, c.block
    wo, weight = -d[c.index], np.ones(P)
    for level in range(MAX_DELTA_BOUNCES + 1):
        mat = scene.material[tri]
        parts = bsdf.parts(mat, np.clip(np.einsum("ij,ij->i", n, wo), 1e-3, 1.0), front)
        diff = np.flatnonzero(parts["kd"] + parts["td"] > 0)
        if diff.size:
            keys = {"seed": seed, "block_ids": blocks[diff], "purpose_key": 0 if level == 0 else 20000 + level}
            sub = {key: v[diff] for key, v in parts.items()}
            value, var = est.direct_diffuse(x[diff], n[diff], sub, keys,
                                            DISTANT_RAYS_PER_DIRECT_SAMPLE * est.direct_samples)
            ind, b = _cached_diffuse(est, cache, tri[diff], x[diff], front[diff], sub, with_bias=True)
            np.add.at(out, pix[diff], weight[diff, None] * (value[:, None] + ind))
            np.add.at(direct_var, pix[diff], weight[diff] ** 2 * var)
            np.add.at(bias, pix[diff], weight[diff, None] * b)
        gl = np.flatnonzero(parts["rs"] + parts["ts"] > 0)
        if gl.size:
            R = int(glossy_rays)
            rep = np.repeat(gl, G * R)
            grp = np.tile(np.repeat(np.arange(G), R), gl.size)
            sub = {key: v[rep] for key, v in parts.items()}
            val, vb = _glossy_paths(est, cache, seed, x[rep], n[rep], wo[rep], mat[rep], sub, grp, blocks[rep], level, R)
            val = val.reshape(gl.size, G, R).mean(axis=2)
            np.add.at(bias, pix[gl], weight[gl, None] * vb.reshape(gl.size, G, R).mean(axis=2))
            rep = np.repeat(gl, G)
            grp = np.tile(np.arange(G), gl.size)
            val += est.point_glossy(x[rep], n[rep], wo[rep], mat[rep], grp, blocks[rep], level,
                                    _TAG_POINT + 1).reshape(gl.size, G)
            val += est.distant_glossy(x[rep], n[rep], wo[rep], mat[rep], grp, blocks[rep], level,
                                      _TAG_POINT + 3).reshape(gl.size, G)
            val += est.emitter_glossy(x[rep], n[rep], wo[rep], mat[rep], grp, blocks[rep], level, _TAG_POINT + 7,
                                      np.full(rep.size, R), np.ones(rep.size)).reshape(gl.size, G)
            np.add.at(out, pix[gl], weight[gl, None] * val)
        # continue through the delta parts
        r, t = parts["R"], parts["T"]
        u = np.empty(pix.size)
        for j in np.unique(blocks):
            m = blocks == j
            u[m] = stream(seed, "cache", _TAG_DELTA, level, j).random(int(m.sum()))
        split = (r > 0) & (t > 0) & (level < DELTA_SPLITS)
        count = np.where(split, 2, (r + t > 0).astype(np.int64))
        parent = np.repeat(np.arange(pix.size), count)
        if not parent.size:
            break
        first_child = np.r_[True, parent[1:] != parent[:-1]]
        refl = np.where(split[parent], first_child, u[parent] * (r + t)[parent] < r[parent])
        weight = weight[parent] * np.where(split[parent], np.where(refl, r[parent], t[parent]), (r + t)[parent])
        pix, x, n, blocks, wo = pix[parent], x[parent], n[parent], blocks[parent], wo[parent]
        mu = np.einsum("ij,ij->i", n, wo)
        dd = np.where(refl[:, None], 2 * mu[:, None] * n - wo, -wo)
        side = np.where(refl, 1.0, -1.0)[:, None]
        prim, dist = engine.closest_hit(x + eps * side * n, dd)
        hit = prim >= 0
        if scene.distant_sources:  # the sky seen through glass or in a mirror
            np.add.at(out, pix[~hit], (weight[~hit] * background_luminance(scene, dd[~hit]))[:, None])
        pix, x, n, dd, side, prim, dist, blocks, weight = (a[hit] for a in (pix, x, n, dd, side, prim, dist, blocks,
                                                                            weight))
        if not pix.size:
            break
        x = x + eps * side * n + dist[:, None] * dd
        n, front = scene.facing_normals(prim, dd)
        wo, tri = -dd, prim
        np.add.at(out, pix, (weight * emitted_luminance(scene, prim, wo))[:, None])
    return out, direct_var, bias
