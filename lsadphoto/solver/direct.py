"""Direct illuminance at surface points: the first local estimate from the luminaires.

For a point x with unit normal n, the illuminance from an area luminaire of uniform
luminance L over triangles A (Lambertian, emitting from their front side) is

    E_l(x) = L · ∫_A V(x, y) · cos⁺θ_x · cos θ_y / |y − x|² dA_y = L · (Π_l − ∫_A (1 − V)·g dA),

with g = cos⁺θ_x·cos θ_y/r². Π_l = ∫_A g dA, the projected solid angle of the unoccluded
triangles (clipped to the horizon of x), has a closed form (Lambert's polygon formula:
Π = ½ Σ_edges γ_e · n·m̂_e, γ_e the angle an edge subtends at x and m̂_e the unit normal of
the plane through x and the edge). Only the visible fraction is sampled, with ``samples``
points per luminaire distributed by area (stratified over the luminaire's triangles), each
with a shadow ray, as the ratio

    Ê_l = L · Π_l · Σ_j V_j·g_j / Σ_j g_j,

which is exact (zero variance) wherever the luminaire is fully visible or fully hidden and
never negative. In a partial shadow it is a ratio estimator: consistent, with a bias of
order 1/s — not detectable in the half-shadow test of tests/test_solver_cache.py (−0.04 ±
0.30 % at s = 4, 20 000 estimates), far below its noise there (43 % per estimate at s = 4).
(The control-variate form L·(Π − (A/s)Σ(1 − V_j)g_j) is unbiased but can come out
negative in a penumbra, which a luminance map cannot hold.) Point luminaires (an intensity
distribution I, emitted from a point or uniformly from a luminous rectangle) contribute
I(ω_{y→x})·cos⁺θ_x·V/r², averaged over ``samples`` points of the rectangle (one for a point):
unbiased.

At points on smooth plastic, metal or trans of specularity ≥ 0.018 the diffuse part
scatters the *Fresnel-weighted* illuminance E_F = ∫(1 − F(μ))·L·μ dω (Radiance's factor
1 − F(μ_i) of ``normal.c``, :func:`~lsadphoto.solver.materials.diffuse_fresnel_factor`);
``fresnel=`` asks for it. The point luminaires' and the distant sources' terms are weighted
by 1 − F(cos θ_x) (unbiased); an area luminaire's estimate subtracts its Fresnel part from
the ratio estimate above,

    Ê_F,l = Ê_l − L·(A/s)·Σ_j F_j·V_j·g_j,   F_j = F(cos θ_x,j),

whose second term is the plain Monte Carlo estimate of L·∫F·V·g dA (the samples are
distributed by area): unbiased where Ê_l is (exact where the luminaire is fully visible or
hidden), with the noise of the small Fresnel part only. The ratio form L·Π·Σ(1 − F_j)V_j g_j/Σg_j
is not: 2.5–5 % low at s = 4 under a large panel (tests/test_solver_direct.py), because
1 − F and g vary together over the luminaire. A difference that comes out negative (grazing
samples drawn far above their mean) is set to 0.

Each estimate comes with its sampling variance (the delta-method variance of the ratio; for
point luminaires the sample variance over s). Both ignore the stratification, which lowers
the true variance: conservative (1.2–1.4× the observed variance in the half-shadow test).

Many luminaires (:func:`direct_illuminance`, ``luminaires`` an integer K or ``"auto"``
above :data:`ALL_LUMINAIRES_UP_TO`) are sampled, not all evaluated. A compiled planning pass
(:func:`_plan`) weighs at each point only the :data:`LUMINAIRE_CANDIDATES` luminaires of
largest bound in its region of a :class:`LuminaireTable` — their exact unoccluded values
(Lambert's Π, or I·cos⁺θ/r² from the intensity tables by
:func:`~.photometry.packed_intensity`) — and gives every other luminaire its region's
weight. A luminaire giving at least 1/K of the point's total weight is taken whole (the
*closed-form path* where one luminaire dominates: its Lambert or I·cos/r² value times the
visibility of its samples, exact where it is fully visible); K stratified draws take the
rest with p ∝ weight, each one estimate weighted 1/(K·p) (one point of a luminous
rectangle per draw). Every luminaire keeps p > 0 wherever it may give light, so the sum is
unbiased (for area luminaires: as unbiased as their ratio estimate above); it is exact —
zero variance — where nothing is in the way and every luminaire is a candidate with an
exact value. Shadow rays of all the point luminaires' samples go to Embree in one call.
The draws' variance is estimated by collapsing adjacent strata in pairs (one draw per
stratum has no variance estimate of its own; Cochran 1977, ch. 5A): conservative only by the
spread of neighbouring strata means, where the plain sample variance over the K draws would
add back the whole spread that the stratification removed.

References
----------
Lambert, J. H. (1760). *Photometria*, §§ 170–176 (the polygon formula); in modern form
Arvo, J. (1995). Applications of irradiance tensors to the simulation of non-Lambertian
phenomena. *SIGGRAPH '95*, eq. (6). Marchuk et al. (1980), §3.3 (local estimate).
Cochran, W. G. (1977). *Sampling Techniques*, 3rd ed., Wiley, §6 (ratio estimators, their
bias and delta-method variance). FORMULAS.md §6.1.
"""

import math
import threading

import numpy as np
from .._compiled import njit

from .._validation import check_positive_int
from ._sampling import stream
from .materials import diffuse_fresnel_factor, fresnel_weighted, shadow_transmittance, shadows_transmit
from .photometry import pack_photometries, packed_intensity
from .photometry.distribution import PACKED_TABLES
from .sky import distant_illuminance, distant_uniforms

__all__ = ["ALL_LUMINAIRES_UP_TO", "DIRECT_SAMPLES", "LUMINAIRE_CANDIDATES", "LUMINAIRE_DRAWS",
           "REGION_CELL", "LuminaireTable", "direct_illuminance", "projected_solid_angle",
           "sampled_direct_illuminance", "unoccluded_illuminance"]

#: Default shadow-ray samples per luminaire and point.
DIRECT_SAMPLES = 4
#: ``luminaires="auto"`` of :func:`direct_illuminance` evaluates every luminaire up to this
#: many, and samples them above it …
ALL_LUMINAIRES_UP_TO = 8
#: … with this many draws per point (besides the luminaires taken whole; 64, not 32: in the
#: station hall with 480 luminaires the median per-pixel error of a 512² render fell from
#: 2.65 % to 1.70 % for 1.45× its CPU time — more luminaires pass the 1/K share to be taken
#: whole — and 128 draws gave 1.34 % for 2.2×; docs/performance.md) …
LUMINAIRE_DRAWS = 64
#: … after weighing exactly, per point, this many candidate luminaires of its region
#: (:class:`LuminaireTable`) …
LUMINAIRE_CANDIDATES = 16
#: … whose regions are cubes of this edge, as a fraction of the scene's bounding-box diagonal.
REGION_CELL = 1 / 32

_NUMBA = {"cache": True, "error_model": "numpy", "nogil": True}
#: Ahead-of-time argument types (:mod:`lsadphoto._compiled`): arrays of float64 and int64 of
#: 1, 2 and 3 dimensions (C order), and :class:`_Lights`' ``points`` and ``areas`` tuples.
_F1, _F2, _F3, _I1, _I2 = "float64[::1]", "float64[:, ::1]", "float64[:, :, ::1]", "int64[::1]", "int64[:, ::1]"
_POINTS = f"Tuple(({_F2}, {_F3}, {_F1}, {_F2}, {_I1}, {PACKED_TABLES}))"
_AREAS = f"Tuple(({_I1}, {_F3}, {_F2}, {_F1}))"


@njit(**_NUMBA)
def _lambert_edge(px, py, pz, qx, qy, qz, n):
    """One edge's term of Lambert's polygon formula, γ·(p × q)·n/|p × q| (γ the angle
    between the vertex directions p and q); 0 for a vertex at the point or a degenerate edge,
    which subtend no angle."""
    cx = py * qz - pz * qy
    cy = pz * qx - px * qz
    cz = px * qy - py * qx
    norm = math.sqrt(cx * cx + cy * cy + cz * cz)
    if norm == 0.0:
        return 0.0
    return math.atan2(norm, px * qx + py * qy + pz * qz) * (cx * n[0] + cy * n[1] + cz * n[2]) / norm


@njit(**_NUMBA)
def _triangle_projected_solid_angle(x, n, a, b, c):
    """Π [sr] of triangle a, b, c seen from x (normal n), clipped to the half-space n·v ≥ 0.

    The clipped polygon's vertices (Sutherland–Hodgman: each edge's start where above the
    horizon, then its crossing of the horizon) are taken one by one and each edge's term
    added as its end comes, the closing edge last: no arrays, so no allocation per call."""
    total = 0.0
    m = 0
    fx = fy = fz = 0.0  # the polygon's first vertex
    lx = ly = lz = 0.0  # its last vertex so far
    for k in range(3):
        if k == 0:
            p, q = a, b
        elif k == 1:
            p, q = b, c
        else:
            p, q = c, a
        px, py, pz = p[0] - x[0], p[1] - x[1], p[2] - x[2]
        qx, qy, qz = q[0] - x[0], q[1] - x[1], q[2] - x[2]
        hp = px * n[0] + py * n[1] + pz * n[2]
        hq = qx * n[0] + qy * n[1] + qz * n[2]
        if hp >= 0.0:
            if m == 0:
                fx, fy, fz = px, py, pz
            else:
                total += _lambert_edge(lx, ly, lz, px, py, pz, n)
            lx, ly, lz = px, py, pz
            m += 1
        if (hp > 0.0 and hq < 0.0) or (hp < 0.0 and hq > 0.0):
            t = hp / (hp - hq)
            vx, vy, vz = px + t * (qx - px), py + t * (qy - py), pz + t * (qz - pz)
            if m == 0:
                fx, fy, fz = vx, vy, vz
            else:
                total += _lambert_edge(lx, ly, lz, vx, vy, vz, n)
            lx, ly, lz = vx, vy, vz
            m += 1
    if m < 3:
        return 0.0
    total += _lambert_edge(lx, ly, lz, fx, fy, fz, n)
    return abs(0.5 * total)


@njit(**_NUMBA, aot=f"void({_F2}, {_F2}, {_F3}, {_F2}, {_F2})")
def _projected_solid_angles(points, normals, triangles, front, out):
    """``out[i, l]`` += Π of triangle l (vertices ``triangles[l]``, front normal ``front[l]``)
    seen from point i, where i lies in front of it (one-sided emitters). Serial: callers
    work on chunks of points in threads."""
    for i in range(points.shape[0]):
        x = points[i]
        n = normals[i]
        for t in range(triangles.shape[0]):
            tri = triangles[t]
            side = ((x[0] - tri[0, 0]) * front[t, 0] + (x[1] - tri[0, 1]) * front[t, 1]
                    + (x[2] - tri[0, 2]) * front[t, 2])
            if side > 0.0:
                out[i, t] = _triangle_projected_solid_angle(x, n, tri[0], tri[1], tri[2])


def projected_solid_angle(points, normals, triangles):
    """Projected solid angle Π = ∫ cos⁺θ_x dω [sr] of triangles seen from points.

    Lambert's polygon formula after clipping each triangle to the horizon of the point;
    a triangle counts only where the point lies on its front side (the side its normal,
    ``(b − a) × (c − a)``, points to).

    Parameters
    ----------
    points, normals : array_like, shape (P, 3)
        Points [m] and their unit normals.
    triangles : array_like, shape (T, 3, 3)
        Triangle vertices [m].

    Returns
    -------
    numpy.ndarray, shape (P, T)
        Π [sr] (π for a plane filling the whole hemisphere).

    Examples
    --------
    A 2 × 2 m square 1 m above a point, facing it. By the corner-rectangle form factor
    F = (1/2π)·[X/√(1+X²)·atan(Y/√(1+X²)) + Y/√(1+Y²)·atan(X/√(1+Y²))] with X = Y = 1 for each
    of its four quadrants, F = Π/π = (4/π)·atan(1/√2)/√2 = 0.5541.

    >>> sq = np.array([[[-1, -1, 1], [1, 1, 1], [1, -1, 1]], [[-1, -1, 1], [-1, 1, 1], [1, 1, 1]]], float)
    >>> pi_ = projected_solid_angle([[0, 0, 0]], [[0, 0, 1]], sq).sum()
    >>> round(float(pi_ / np.pi), 4)
    0.5541
    """
    tris = np.ascontiguousarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    return _projected_solid_angle(points, normals, tris, _front_normals(tris))


def _front_normals(tris):
    front = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    length = np.linalg.norm(front, axis=1)
    return np.ascontiguousarray(front / np.where(length > 0, length, 1.0)[:, None])


def _projected_solid_angle(points, normals, tris, front):
    pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    nrm = np.ascontiguousarray(normals, dtype=np.float64).reshape(-1, 3)
    out = np.zeros((len(pts), len(tris)))
    _projected_solid_angles(pts, nrm, tris, front, out)
    return out


@njit(**_NUMBA, aot=f"void({_F2}, {_F2}, {_F3}, {_F2}, {_F1}, {_F3}, float64, {_F3}, {_F2}, {_F2})")
def _area_samples(x, n, tris, tri_normals, cdf, u, offset, targets, g, cosine):
    """Stratified points on a luminaire's triangles for points x (normals n): shadow-ray
    targets (the point moved ``offset`` off the emitting side), g = cos⁺θ_x·cos⁺θ_y/r²
    (one-sided emitter) and cos θ_x. ``u`` (P, s, 3): the first uniform picks the triangle
    within its stratum of the area CDF, the other two the point (square-root warp)."""
    P, s = g.shape
    nt = cdf.size
    for i in range(P):
        for j in range(s):
            v = (j + u[i, j, 0]) / s
            t = 0
            while t < nt - 1 and cdf[t] <= v:
                t += 1
            su = math.sqrt(u[i, j, 1])
            b1 = u[i, j, 2] * su
            b0 = 1.0 - su
            b2 = 1.0 - b0 - b1
            rx = ry = rz = 0.0
            for k in range(3):
                y_k = b0 * tris[t, 0, k] + b1 * tris[t, 1, k] + b2 * tris[t, 2, k]
                targets[i, j, k] = y_k + offset * tri_normals[t, k]
                if k == 0:
                    rx = y_k - x[i, 0]
                elif k == 1:
                    ry = y_k - x[i, 1]
                else:
                    rz = y_k - x[i, 2]
            r2 = rx * rx + ry * ry + rz * rz
            cx = rx * n[i, 0] + ry * n[i, 1] + rz * n[i, 2]
            cy = -(rx * tri_normals[t, 0] + ry * tri_normals[t, 1] + rz * tri_normals[t, 2])
            g[i, j] = cx * cy / (r2 * r2) if (cx > 0.0 and cy > 0.0) else 0.0
            cosine[i, j] = cx / math.sqrt(r2) if r2 > 0.0 else 0.0


class _LuminaireSampler:
    """Area-stratified points on one area luminaire's triangles."""

    def __init__(self, scene, lum):
        self.triangles = np.ascontiguousarray(scene.triangles[lum.triangles], dtype=np.float64)
        self.front = _front_normals(self.triangles)
        self.normals = np.ascontiguousarray(scene.normals[lum.triangles], dtype=np.float64)
        self.luminance = lum.luminance(scene)
        areas = scene.areas[lum.triangles]
        self.area = float(areas.sum())
        self.cdf = np.cumsum(areas) / self.area
        self.cdf[-1] = 1.0

    def sample(self, x, n, u, offset):
        """Shadow-ray targets (P, s, 3), g and cos θ_x (P, s) for points x, normals n, uniforms u."""
        P, s, _ = u.shape
        targets = np.empty((P, s, 3))
        g = np.empty((P, s))
        cosine = np.empty((P, s))
        _area_samples(np.ascontiguousarray(x), np.ascontiguousarray(n), self.triangles,
                      self.normals, self.cdf, np.ascontiguousarray(u), offset, targets, g, cosine)
        return targets, g, cosine


def _area_estimate(scene, sampler, x, n, origins, u, engine, unoccluded=None, fresnel=None):
    """Ratio estimate of one area luminaire's direct illuminance [lx] at points x (normals
    n, ray origins ``origins``) from uniforms u (P, s, 3), and its delta-method variance;
    ``unoccluded`` = L·Π at x where already known. V_j is the shadow transmittance (1 or 0;
    through glass and smooth ``trans`` their straight-through T:
    :func:`~lsadphoto.solver.materials.shadow_transmittance`, as Radiance's shadow rays).
    At the points where ``fresnel``, the Fresnel-weighted E_F: the ratio estimate less
    L·(A/s)·Σ_j F_j·V_j·g_j (module docstring)."""
    P, s, _ = u.shape
    E = np.zeros(P)
    var = np.zeros(P)
    L = sampler.luminance
    if unoccluded is not None and L > 0:
        pi_l = unoccluded / L
    else:
        pi_l = _projected_solid_angle(x, n, sampler.triangles, sampler.front).sum(axis=1)
    lit = np.flatnonzero(pi_l > 0)
    if lit.size == 0:
        return E, var
    if lit.size == P:  # (every point, as where the caller passes only lit pairs: no copies)
        targets, g, cosine = sampler.sample(x, n, u, engine.epsilon)
    else:
        targets, g, cosine = sampler.sample(x[lit], n[lit], u[lit], engine.epsilon)
    seen = np.zeros_like(g)
    lost = None  # F_j·V_j·g_j: the Fresnel part of each sample (Fresnel-weighted points)
    cand = np.flatnonzero(g.ravel() > 0)
    if cand.size:
        p_of = lit[cand // s]
        seen.ravel()[cand] = g.ravel()[cand] * shadow_transmittance(scene, engine, origins[p_of], targets.reshape(-1, 3)[cand])
        if fresnel is not None:
            lost = np.zeros_like(g)
            lost.ravel()[cand] = seen.ravel()[cand] * (1 - diffuse_fresnel_factor(cosine.ravel()[cand], fresnel[p_of]))
    total = g.sum(axis=1)
    sampled = total > 0  # else no sample fell where g > 0: taken as visible
    ratio = np.ones(lit.size)
    ratio[sampled] = seen[sampled].sum(axis=1) / total[sampled]
    E[lit] = L * pi_l[lit] * ratio
    if lost is not None:
        # never negative: only where the sampled Fresnel part exceeds the estimate (grazing
        # samples drawn far above their mean) does the clip leave a bias
        E[lit] = np.maximum(E[lit] - L * sampler.area * lost.mean(axis=1), 0.0)
    if s > 1:
        # Delta method: Ê − E ≈ mean_j q_j, q_j = L·Π·g_j·(V_j − R)/ḡ (− L·A·F_j·V_j·g_j), so
        # Var ≈ var_j(q_j)/s.
        resid = np.where(g > 0, seen - g * ratio[:, None], 0.0)
        mean_g = total / s
        q = np.zeros_like(g)
        q[sampled] = (L * pi_l[lit][sampled] / mean_g[sampled])[:, None] * resid[sampled]
        if lost is not None:
            q -= L * sampler.area * lost
        var[lit] = q.var(axis=1, ddof=1) / s
    return E, var


class _Lights:
    """Every luminaire of a scene packed for the compiled kernels, in the scene's order (area
    luminaires first).

    ``points``: (position (L, 3), frame (L, 3, 3), multiplier (L,), extent (L, 2), table (L,),
    tables) of the point luminaires (:func:`~.photometry.pack_photometries`); ``areas``:
    (start (A + 1,), triangles (T, 3, 3), front normals (T, 3), luminance (A,)) of the area
    luminaires' triangles; ``exact[l]``: whether l's unoccluded value (:func:`_unoccluded`)
    is exact (area luminaires, points) or a guide (a luminous rectangle's centre).
    """

    def __init__(self, scene):
        samplers = _samplers(scene)
        lums = scene.point_luminaires
        index, tables = pack_photometries([lum.photometry for lum in lums])
        self.points = (np.array([lum.position for lum in lums], dtype=np.float64).reshape(-1, 3),
                       np.array([lum.frame for lum in lums], dtype=np.float64).reshape(-1, 3, 3),
                       np.array([lum.multiplier for lum in lums], dtype=np.float64),
                       np.array([lum.extent for lum in lums], dtype=np.float64).reshape(-1, 2),
                       index, tables)
        start = np.concatenate([[0], np.cumsum([len(s.triangles) for s in samplers])]).astype(np.int64)
        self.areas = (start,
                      np.concatenate([s.triangles for s in samplers]) if samplers else np.zeros((0, 3, 3)),
                      np.concatenate([s.front for s in samplers]) if samplers else np.zeros((0, 3)),
                      np.array([s.luminance for s in samplers], dtype=np.float64))
        self.n_area = len(samplers)
        self.count = self.n_area + len(lums)
        rect = (self.points[3] > 0).all(axis=1)
        self.exact = np.concatenate([np.ones(self.n_area, dtype=bool), ~rect])


def _lights(scene):
    lights = getattr(scene, "_packed_lights", None)
    if lights is None:  # built once per scene (scenes are not modified after loading)
        lights = scene._packed_lights = _Lights(scene)
    return lights


@njit(inline="always", **_NUMBA)
def _point_value(points, k, x, n, y0, y1, y2):
    """I(ω_{y→x})·cos⁺θ_x/r² [lx] of point luminaire k emitting from y at point x (normal n)."""
    rx, ry, rz = y0 - x[0], y1 - x[1], y2 - x[2]
    r2 = rx * rx + ry * ry + rz * rz
    if not r2 > 0.0:
        return 0.0
    r = math.sqrt(r2)
    cos_x = (rx * n[0] + ry * n[1] + rz * n[2]) / r
    if not cos_x > 0.0:
        return 0.0
    frame = points[1]
    return (points[2][k] * packed_intensity(points[5], points[4][k], -rx / r, -ry / r, -rz / r, frame[k])
            * cos_x / r2)


@njit(inline="always", **_NUMBA)
def _unoccluded(points, areas, n_area, l, x, n):
    """Unoccluded illuminance [lx] of luminaire l at x (normal n): L·Π for an area luminaire
    (Lambert's closed form over its triangles, front sides only), I·cos⁺θ/r² from the centre
    of a point luminaire (for a luminous rectangle a guide)."""
    if l >= n_area:
        k = l - n_area
        pos = points[0]
        return _point_value(points, k, x, n, pos[k, 0], pos[k, 1], pos[k, 2])
    start, tris, front, luminance = areas
    total = 0.0
    for t in range(start[l], start[l + 1]):
        tri = tris[t]
        side = ((x[0] - tri[0, 0]) * front[t, 0] + (x[1] - tri[0, 1]) * front[t, 1]
                + (x[2] - tri[0, 2]) * front[t, 2])
        if side > 0.0:
            total += _triangle_projected_solid_angle(x, n, tri[0], tri[1], tri[2])
    return luminance[l] * total


@njit(**_NUMBA, aot=f"void({_F2}, {_F2}, {_POINTS}, {_AREAS}, int64, {_F2})")
def _unoccluded_all(x, n, points, areas, n_area, out):
    """``out[i, l]`` = :func:`_unoccluded` of every luminaire l at every point i."""
    for i in range(x.shape[0]):
        for l in range(out.shape[1]):
            out[i, l] = _unoccluded(points, areas, n_area, l, x[i], n[i])


@njit(**_NUMBA, aot=f"Tuple((int64, {_I1}))({_F2}, {_F2}, float64, {_I1}, {_I1}, {_F1}, {_I1}, {_F2}, {_I1}, "
           f"{_POINTS}, {_F2}, {_F2}, float32[:, ::1], float32[:, ::1], float32[::1], {_I1})")
def _point_terms(x, n, offset, point, lum, guide, count, u, u_start, points, values, cosine, o32, d32,
                 t32, ray):
    """Terms of the estimates of point luminaires ``lum[e]`` (index among the point
    luminaires) at points ``point[e]``: ``values[e, j]`` = I·cos⁺θ_x/r² from emission point j
    < ``count[e]`` of the luminous rectangle (uniforms ``u[u_start[e] + j, :2]``; one point, the centre,
    with the exact ``guide[e]`` as its value, for a luminaire without one), and ``cosine[e, j]``
    its cos θ_x where nonzero; returns the number m of nonzero terms, whose flat index and float32 shadow ray (from x moved ``offset`` along n to the
    emission point, stopped ``offset`` short) are in ``ray``, ``o32``, ``d32``, ``t32`` [:m].
    Returns also how many terms each estimate has (``ns``)."""
    E, s = values.shape
    pos, frame, _, extent = points[0], points[1], points[2], points[3]
    ns = np.ones(E, dtype=np.int64)
    m = 0
    for e in range(E):
        i, k = point[e], lum[e]
        length, width = extent[k, 0], extent[k, 1]
        rect = length > 0.0 and width > 0.0
        if rect:
            ns[e] = count[e]
        ox, oy, oz = x[i, 0] + offset * n[i, 0], x[i, 1] + offset * n[i, 1], x[i, 2] + offset * n[i, 2]
        for j in range(s):
            values[e, j] = 0.0
            if j >= ns[e]:
                continue
            if rect:
                a = (u[u_start[e] + j, 0] - 0.5) * length
                b = (u[u_start[e] + j, 1] - 0.5) * width
                y0 = pos[k, 0] + a * frame[k, 0, 0] + b * frame[k, 1, 0]
                y1 = pos[k, 1] + a * frame[k, 0, 1] + b * frame[k, 1, 1]
                y2 = pos[k, 2] + a * frame[k, 0, 2] + b * frame[k, 1, 2]
                v = _point_value(points, k, x[i], n[i], y0, y1, y2)
            else:
                y0, y1, y2 = pos[k, 0], pos[k, 1], pos[k, 2]
                v = guide[e]
            values[e, j] = v
            if v > 0.0:
                rx, ry, rz = y0 - x[i, 0], y1 - x[i, 1], y2 - x[i, 2]
                cosine[e, j] = (rx * n[i, 0] + ry * n[i, 1] + rz * n[i, 2]) / math.sqrt(rx * rx + ry * ry + rz * rz)
                ex, ey, ez = y0 - ox, y1 - oy, y2 - oz
                d = math.sqrt(ex * ex + ey * ey + ez * ez)
                if d > offset:  # (else: taken as visible, as RayEngine.visible does)
                    ray[m] = e * s + j
                    o32[m, 0], o32[m, 1], o32[m, 2] = ox, oy, oz
                    d32[m, 0], d32[m, 1], d32[m, 2] = ex / d, ey / d, ez / d
                    t32[m] = d - offset
                    m += 1
    return m, ns


def _point_estimates(scene, lights, x, n, point, lum, guide, u, u_start, count, engine, fresnel=None):
    """Direct illuminance [lx] of point luminaires ``lum`` (index among the point luminaires)
    at points ``x[point]``, and the sample variance of each mean: the mean over ``count[e]``
    emission points of a luminous rectangle (placed by the uniforms ``u[u_start[e]:][:count[e],
    :2]``), or the exact ``guide`` times the visibility of the centre; all shadow rays in one
    Embree call. Each term times 1 − F(cos θ_x) at the points where ``fresnel``."""
    E = len(point)
    s = max(int(count.max(initial=1)), 1)
    values = np.empty((E, s))
    cosine = np.zeros((E, s))
    o32 = np.empty((E * s, 3), dtype=np.float32)
    d32 = np.empty((E * s, 3), dtype=np.float32)
    t32 = np.empty(E * s, dtype=np.float32)
    ray = np.empty(E * s, dtype=np.int64)
    m, ns = _point_terms(x, n, engine.epsilon, point, lum, guide, count, u, u_start, lights.points,
                         values, cosine, o32, d32, t32, ray)
    if fresnel is not None:
        values *= diffuse_fresnel_factor(cosine, fresnel[point][:, None])
    if m and shadows_transmit(scene):
        o = o32[:m].astype(float)
        values.ravel()[ray[:m]] *= shadow_transmittance(scene, engine, o, o + d32[:m] * t32[:m, None])
    elif m:
        values.ravel()[ray[:m][engine.occluded(o32[:m], d32[:m], t32[:m])]] = 0.0
    mean = values.sum(axis=1) / ns
    var = np.zeros(E)
    for k in np.unique(ns[ns > 1]):
        sel = ns == k
        var[sel] = values[sel, :k].var(axis=1, ddof=1) / k
    return mean, var


def unoccluded_illuminance(scene, points, normals):
    """Illuminance [lx] each luminaire would give at each point with nothing in the way.

    Area luminaires: L·Π_l, Lambert's closed form; point luminaires: I(ω)·cos⁺θ/r² from the
    luminaire's centre, which for a luminous rectangle is a guide, not the exact value.
    Returns ``(u, exact)``: ``u`` of shape (P, luminaires) in the scene's order (area
    luminaires first), and a boolean per luminaire, true where ``u`` is exact. One compiled
    pass over points × luminaires (intensity tables by
    :func:`~.photometry.packed_intensity`).
    """
    x = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    n = np.ascontiguousarray(normals, dtype=np.float64).reshape(-1, 3)
    lights = _lights(scene)
    u = np.zeros((len(x), lights.count))
    _unoccluded_all(x, n, lights.points, lights.areas, lights.n_area, u)
    return u, lights.exact.copy()


def _samplers(scene):
    samplers = getattr(scene, "_luminaire_samplers", None)
    if samplers is None:  # built once per scene (scenes are not modified after loading)
        samplers = scene._luminaire_samplers = [_LuminaireSampler(scene, lum)
                                                for lum in scene.area_luminaires]
    return samplers


@njit(**_NUMBA, aot=f"void({_F2}, {_F2}, {_I1}, {_I2}, {_I1}, {_F2}, {_F2}, {_F2}, {_POINTS}, {_AREAS}, int64, "
           f"boolean[::1], {_I2}, {_F2}, {_I2}, {_F2}, {_F2}, {_I1})")
def _plan(x, n, row, cand, n_cand, rest_w, rest_cum, picks, points, areas, n_area, exact,
          ev_lum, ev_weight, ev_count, ev_prob, ev_guide, ev_n):
    """Which luminaires each point i evaluates, with what weight: the planning pass of
    :func:`direct_illuminance`.

    Point i's region ``row[i]`` lists its candidates ``cand[r, :n_cand[r]]``, whose
    unoccluded values u_c (:func:`_unoccluded`) are computed here, and gives every other
    luminaire l a weight ``rest_w[r, l]`` > 0 (cumulative ``rest_cum[r]``) on the same scale.
    With M = Σu_c + Σ rest weights, candidates with u_c ≥ M/D are taken whole (weight 1);
    D = ``picks.shape[1]`` stratified draws (uniforms ``picks[i]``) go to the rest —
    candidates with p ∝ u_c (guides floored at 10⁻³ of the mean, so p > 0 wherever light
    may arrive), other luminaires with p ∝ their region weight — each draw an evaluation of
    its own, weighted 1/(D·p). Writes, per point, ``ev_n[i]`` ≤ 2D evaluations: luminaire,
    weight, draw count (0: whole, 1: drawn), probability and unoccluded value (exact or
    guide)."""
    P, D = picks.shape
    N = rest_w.shape[1]
    K = cand.shape[1]
    u = np.empty(K)
    up = np.empty(K)
    whole = np.empty(K, dtype=np.bool_)
    for i in range(P):
        r = row[i]
        k = n_cand[r]
        total = rest_cum[r, N - 1]
        rest = total
        for c in range(k):
            u[c] = _unoccluded(points, areas, n_area, cand[r, c], x[i], n[i])
            total += u[c]
        m = 0
        for c in range(k):
            whole[c] = u[c] > 0.0 and u[c] * D >= total
            if whole[c]:
                ev_lum[i, m], ev_weight[i, m], ev_count[i, m] = cand[r, c], 1.0, 0
                ev_prob[i, m], ev_guide[i, m] = 0.0, u[c]
                m += 1
            else:
                rest += u[c]
        floor = max(1e-3 * rest / N, 1e-300)
        mass_c = 0.0
        for c in range(k):
            up[c] = 0.0 if whole[c] else (u[c] if exact[cand[r, c]] else max(u[c], floor))
            mass_c += up[c]
        mass = mass_c + rest_cum[r, N - 1]
        if mass > 0.0:
            for j in range(D):
                t = (j + picks[i, j]) / D * mass
                if t < mass_c or rest_cum[r, N - 1] <= 0.0:
                    c, acc, last = 0, 0.0, -1
                    while c < k:
                        if up[c] > 0.0:
                            last = c
                            acc += up[c]
                            if acc > t:
                                break
                        c += 1
                    c = last if c >= k else c
                    lum, prob, guide = cand[r, c], up[c] / mass, u[c]
                else:
                    t -= mass_c
                    a, b = 0, N  # first l with rest_cum > t
                    while a < b:
                        mid = (a + b) // 2
                        if rest_cum[r, mid] <= t:
                            a = mid + 1
                        else:
                            b = mid
                    lum = min(a, N - 1)
                    while rest_w[r, lum] <= 0.0:  # rounding past the end: the last one
                        lum -= 1
                    prob = rest_w[r, lum] / mass
                    guide = _unoccluded(points, areas, n_area, lum, x[i], n[i])
                ev_lum[i, m], ev_count[i, m], ev_prob[i, m] = lum, 1, prob
                ev_weight[i, m], ev_guide[i, m] = 1.0 / (D * prob), guide
                m += 1
        ev_n[i] = m


def direct_illuminance(scene, engine, points, normals, *, samples=DIRECT_SAMPLES, seed=0,
                       block_ids=None, purpose_key=0, luminaires="auto", distant_samples=None, fresnel=None,
                       fresnel_rule="reciprocal"):
    """Direct illuminance [lx] at surface points, and its sampling variance [lx²].

    Parameters
    ----------
    scene : Scene
    engine : RayEngine
        Ray engine of ``scene`` (shadow rays).
    points, normals : ndarray, shape (P, 3)
        Points [m] and unit normals (of the side that receives light).
    samples : int
        Shadow-ray samples per luminaire and point (≥ 1): area luminaires sample only their
        visible fraction (module docstring); point luminaires with a luminous rectangle
        sample the rectangle; a point luminaire needs one ray.
    seed : int
        Seed of the samples' random streams.
    block_ids : ndarray of int, shape (P,), optional
        Block key of each point (default: all 0); each block draws from its own stream
        ``(seed, "direct", purpose_key, block)``, so results do not depend on chunking.
    purpose_key : int
        Distinguishes independent uses (e.g. pixels and cache points) within one seed.
    luminaires : "all", int or "auto"
        ``"all"``: every luminaire at every point. An integer K: at each point the
        candidate luminaires of its region (:class:`LuminaireTable`; all of them up to
        :data:`LUMINAIRE_CANDIDATES`) that give at least 1/K of its unoccluded illuminance
        (:func:`unoccluded_illuminance`; the other luminaires counted by their region's
        weights) are taken whole and K draws are made from the rest in proportion to
        those values and weights, each weighted by 1/(K·p) — unbiased importance sampling
        of luminaires (Shirley et al. 1996; module docstring), at the cost of ≤ 2K
        luminaire estimates per point instead of all. ``"auto"`` (default): all up to
        :data:`ALL_LUMINAIRES_UP_TO` luminaires, else K = :data:`LUMINAIRE_DRAWS`.
    distant_samples : int, optional
        Shadow rays per distant source (sun, sky: :func:`~lsadphoto.solver.sky.distant_illuminance`)
        and point; default ``samples``.
    fresnel : ndarray of bool, shape (P,), optional
        Points where the *Fresnel-weighted* illuminance E_F = ∫(1 − F(μ))·L·μ dω [lx] is
        wanted instead of E (F: Radiance's Fresnel estimate; the irradiance the diffuse part
        of smooth plastic, metal and trans of specularity ≥ 0.018 scatters,
        :func:`~lsadphoto.solver.materials.diffuse_fresnel_factor`): each sample's term is
        weighted by 1 − F(cos θ_x) (module docstring).
    fresnel_rule : {"reciprocal", "radiance"}
        :data:`~lsadphoto.solver.materials.FRESNEL_RULES`: under ``"radiance"`` only the
        luminaires that are light sources of Radiance's direct calculation are Fresnel-weighted
        (not a ``glow`` of radius 0, nor a sky's glow).

    Returns
    -------
    (E, variance) : tuple of ndarray, shape (P,)
        Exact where luminaires are fully visible or hidden and none is drawn (at
        Fresnel-weighted points up to the sampled Fresnel part of area luminaires), never
        negative; in a partial shadow of an area luminaire a ratio estimate (bias of order
        1/s, module docstring). With sampled luminaires the variance is that of the whole
        ones plus the draws' (collapsed strata: Σ over pairs of adjacent strata of
        (Ê_a/p_a − Ê_b/p_b)², / K²; conservative by the spread of neighbouring strata
        means only — docs/user-guide-solver.md §3a).

    References
    ----------
    Shirley, P., Wang, C., Zimmerman, K. (1996). Monte Carlo techniques for direct lighting
    calculations. *ACM Transactions on Graphics* 15(1), 1–36.
    """
    s = check_positive_int(samples, "direct samples")
    x = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    n = np.ascontiguousarray(normals, dtype=np.float64).reshape(-1, 3)
    P = len(x)
    E = np.zeros(P)
    var = np.zeros(P)
    lights = _lights(scene)
    n_lum = lights.count
    draws = _luminaire_draws(luminaires, n_lum)
    blocks = np.zeros(P, dtype=np.int64) if block_ids is None else np.asarray(block_ids)
    fresnel = _fresnel_points(fresnel, P)
    if scene.distant_sources:  # the sun and the sky, next-event estimated (solver/sky.py)
        u = distant_uniforms(scene, seed, (0, purpose_key), blocks,
                             s if distant_samples is None else check_positive_int(distant_samples, "distant samples"))
        E, var = distant_illuminance(scene, engine, x, n, u, fresnel=fresnel, fresnel_rule=fresnel_rule)
    if P == 0 or n_lum == 0:
        return E, var
    origins = x + engine.epsilon * n
    if draws is None:
        # Every luminaire at every point; the uniforms of luminaire l are slot l.
        u = np.empty((P, n_lum, s, 3))
        for j in np.unique(blocks):
            m = blocks == j
            u[m] = stream(seed, "direct", purpose_key, j).random((int(m.sum()), n_lum, s, 3))
        guide = np.zeros((P, n_lum))
        _unoccluded_all(x, n, lights.points, lights.areas, lights.n_area, guide)
        # the pairs luminaire by luminaire (each luminaire's uniforms one block of rows); a
        # point's terms still add in luminaire order
        lum, point = np.nonzero(((guide > 0) | ~lights.exact[None, :]).T)
        e, v = _estimates(scene, lights, engine, x, n, origins, point, lum, guide[point, lum],
                          u[point, lum].reshape(-1, 3), np.full(len(point), s, dtype=np.int64), fresnel,
                          fresnel_rule)
        return E + np.bincount(point, e, P), var + np.bincount(point, v, P)
    # Importance sampling of luminaires (_plan): each point evaluates its whole luminaires
    # and its draws; a block's stream gives first its draws, then the evaluations' uniforms.
    table = _luminaire_table(scene)
    picks = np.empty((P, draws))
    slots = []
    for j in np.unique(blocks):
        m = np.flatnonzero(blocks == j)
        g = stream(seed, "direct", purpose_key, j)
        picks[m] = g.random((m.size, draws))
        slots.append((j, g))
    row, cand, n_cand, rest_w, rest_cum = table.plan_rows(x, n)
    S = 2 * draws  # at most draws whole luminaires (each ≥ 1/draws of the total) + draws drawn
    ev_lum = np.empty((P, S), dtype=np.int64)
    ev_count = np.empty((P, S), dtype=np.int64)
    ev_weight, ev_prob, ev_guide = np.empty((P, S)), np.empty((P, S)), np.empty((P, S))
    ev_n = np.empty(P, dtype=np.int64)
    _plan(x, n, row, cand, n_cand, rest_w, rest_cum, picks, lights.points, lights.areas,
          lights.n_area, lights.exact, ev_lum, ev_weight, ev_count, ev_prob, ev_guide, ev_n)
    point, slot = np.nonzero(np.arange(S)[None, :] < ev_n[:, None])
    lum, weight = ev_lum[point, slot], ev_weight[point, slot]
    drawn = ev_count[point, slot] > 0
    # Samples per evaluation: s for an area luminaire (its ratio estimate) and for a luminous
    # rectangle taken whole, one point of the rectangle per draw, none for a point.
    rect = ~lights.exact[lum]
    count = np.where(lum < lights.n_area, s, np.where(rect, np.where(drawn, 1, s), 0))
    u = np.empty((int(count.sum()), 3))
    u_start = np.cumsum(count) - count
    order = np.argsort(blocks[point], kind="stable")
    bounds = np.searchsorted(blocks[point][order], [j for j, _ in slots] + [np.inf])
    for k, (_, g) in enumerate(slots):
        # in the order of the block's own points and evaluations, so that a block's draws do
        # not depend on which other blocks share the call (chunking)
        sel = order[bounds[k]:bounds[k + 1]]
        need = count[sel]
        rows = np.repeat(u_start[sel] - (np.cumsum(need) - need), need) + np.arange(int(need.sum()))
        u[rows] = g.random((rows.size, 3))
    e, v = _estimates(scene, lights, engine, x, n, origins, point, lum, ev_guide[point, slot],
                      u, count, fresnel, fresnel_rule)
    E += np.bincount(point, weight * e, P)
    var += np.bincount(point[~drawn], v[~drawn], P)
    if draws > 1 and drawn.any():
        # the draws' spread by collapsed strata: draw j (stratum j, the last draws slots of
        # its point) in group ⌊j/2⌋, the last three together for an odd count;
        # Var ≈ Σ_groups g/(g − 1)·Σ_{j∈group} (y_j − ȳ_group)² / draws², y = Ê/p
        p_drawn = point[drawn]
        ratio = e[drawn] / ev_prob[point, slot][drawn]
        j = slot[drawn] - (ev_n[p_drawn] - draws)
        groups = draws // 2
        key = p_drawn * groups + np.minimum(j // 2, groups - 1)
        g = np.full(groups, 2.0)
        g[-1] = draws - 2 * (groups - 1)
        total = np.bincount(key, ratio, P * groups).reshape(P, groups)
        square = np.bincount(key, ratio ** 2, P * groups).reshape(P, groups)
        spread = np.maximum(square - total ** 2 / g, 0.0) * (g / (g - 1))
        var += spread.sum(axis=1) / draws ** 2
    return E, var


def _estimates(scene, lights, engine, x, n, origins, point, lum, guide, u, count, fresnel=None, rule="reciprocal"):
    """Direct illuminance [lx] of luminaire ``lum[e]`` at point ``point[e]`` and its
    sampling variance, for every pair e (``guide``: the unoccluded value, exact for area
    luminaires and points), from ``count[e]`` samples (uniforms: the rows of ``u`` (U, 3) in
    order, ``count[e]`` per pair): point luminaires in one compiled pass and one Embree call,
    area luminaires by :func:`_area_estimate` per luminaire (Fresnel-weighted at the points where
    ``fresnel``, under the ``"radiance"`` ``rule`` only for Radiance light sources; point
    luminaires are ``light``s)."""
    e = np.zeros(len(point))
    v = np.zeros(len(point))
    u_start = np.cumsum(count) - count
    is_point = lum >= lights.n_area
    if is_point.any():
        sel = np.flatnonzero(is_point)
        e[sel], v[sel] = _point_estimates(scene, lights, x, n, point[sel], lum[sel] - lights.n_area,
                                          guide[sel], u, u_start[sel], count[sel], engine, fresnel)
    samplers = _samplers(scene)
    for li in np.unique(lum[~is_point]):
        sel = np.flatnonzero(lum == li)
        p = point[sel]
        c = int(count[sel[0]])
        if sel[-1] - sel[0] + 1 == sel.size:  # consecutive pairs: their rows are one block
            u3 = u[u_start[sel[0]]:u_start[sel[0]] + sel.size * c].reshape(sel.size, c, 3)
        else:
            u3 = u[u_start[sel, None] + np.arange(c)]
        e[sel], v[sel] = _area_estimate(scene, samplers[li], x[p], n[p], origins[p], u3, engine,
                                        unoccluded=guide[sel], fresnel=None if fresnel is None else fresnel_weighted(
                                            fresnel[p], rule=rule, direct=scene.light_source_at(np.full(p.size, li), x[p])))
    return e, v


def _fresnel_points(fresnel, count):
    """The ``fresnel`` argument of :func:`direct_illuminance` as a bool array of ``count``
    points, or None where no point is Fresnel-weighted."""
    if fresnel is None:
        return None
    fresnel = np.broadcast_to(np.asarray(fresnel, dtype=bool), (count,))
    return fresnel if fresnel.any() else None


def _luminaire_draws(luminaires, n_lum):
    """Draws per point of :func:`direct_illuminance` (None: every luminaire)."""
    if luminaires == "all" or (luminaires == "auto" and n_lum <= ALL_LUMINAIRES_UP_TO):
        return None
    if luminaires == "auto":
        return LUMINAIRE_DRAWS
    k = check_positive_int(luminaires, "luminaire draws")
    return None if k >= n_lum else k


@njit(**_NUMBA, aot=f"void({_F3}, {_F2}, float64, {_POINTS}, {_AREAS}, int64, {_F1}, {_F2}, {_F2}, {_F2})")
def _region_weights(q, axes, r_min2, points, areas, n_area, area_flux, area_centre, bound, rep):
    """Per region i and luminaire l: ``bound[i, l]``, the largest over the probe points
    ``q[i]`` of strength/max(r², r_min²)·max(0, cos θ_a + 0.82) (:class:`LuminaireTable`),
    and ``rep[i, l]``, l's unoccluded value at the region's centre ``q[i, 0]`` for the normal
    ``axes[i]``."""
    pos, frame, mult, _, table, tables = points
    for i in range(q.shape[0]):
        a = axes[i]
        for l in range(bound.shape[1]):
            k = l - n_area
            b = 0.0
            for p in range(q.shape[1]):
                if k < 0:
                    c0, c1, c2 = area_centre[l, 0], area_centre[l, 1], area_centre[l, 2]
                else:
                    c0, c1, c2 = pos[k, 0], pos[k, 1], pos[k, 2]
                r0, r1, r2_ = c0 - q[i, p, 0], c1 - q[i, p, 1], c2 - q[i, p, 2]
                r2 = r0 * r0 + r1 * r1 + r2_ * r2_
                dist = math.sqrt(max(r2, 1e-300))
                cos_a = (r0 * a[0] + r1 * a[1] + r2_ * a[2]) / dist
                if k < 0:
                    strength = area_flux[l]
                else:
                    strength = mult[k] * packed_intensity(tables, table[k], -r0 / dist, -r1 / dist,
                                                          -r2_ / dist, frame[k])
                b = max(b, strength / max(r2, r_min2) * max(0.0, cos_a + 0.82))
            bound[i, l] = b
            rep[i, l] = _unoccluded(points, areas, n_area, l, q[i, 0], a)


@njit(**_NUMBA, aot=f"void({_F2}, {_F2}, {_I1}, {_I1}, {_POINTS}, {_AREAS}, int64, {_F1})")
def _unoccluded_pairs(x, n, point, lum, points, areas, n_area, out):
    """``out[e]`` = :func:`_unoccluded` of luminaire ``lum[e]`` at point ``point[e]``."""
    for e in range(point.size):
        out[e] = _unoccluded(points, areas, n_area, lum[e], x[point[e]], n[point[e]])


@njit(**_NUMBA, aot=f"void({_F2}, {_I1}, {_F1}, {_I1}, {_F1})")
def _pick_rows(cdf, row, u, pick, prob):
    """Inverse-CDF draw of one luminaire per point from its region's row ``cdf[row[i]]``
    (uniform ``u[i]``), with its probability."""
    N = cdf.shape[1]
    for i in range(row.size):
        c = cdf[row[i]]
        a, b = 0, N - 1  # first l with cdf > u (the last one at worst)
        while a < b:
            mid = (a + b) // 2
            if c[mid] <= u[i]:
                a = mid + 1
            else:
                b = mid
        pick[i] = a
        prob[i] = c[a] - (c[a - 1] if a > 0 else 0.0)


class LuminaireTable:
    """A per-region importance table over many luminaires: which to sample, without
    evaluating them all at every point.

    Space is cut into cubes of edge ``cell`` [m], and each cube into six regions by the
    dominant axis (and sign) of a point's normal. A region's *bound* of luminaire l is what
    l can give there at most, roughly: the largest over nine probe points q (the cube's
    centre and corners) of I_l(ω_{l→q})/max(r², (cell/2)²)·max(0, cos θ_a + 0.82), θ_a the
    angle between the direction to l and the region's axis (a normal in the region lies
    within 54.7° of it, so cos θ_a ≥ −0.82 wherever l can lie in front of it); area
    luminaires: L·A/max(r², (cell/2)²) from their centroid, with the same factor. Every
    luminaire keeps at least 10⁻³ of the region's mean bound. Per region the table holds

    * the bounds' CDF (:meth:`cdf`: one luminaire drawn per point by
      :func:`sampled_direct_illuminance`);
    * the ``candidates`` luminaires of largest bound, whose exact unoccluded values
      :func:`direct_illuminance` computes at each point, and for every other luminaire a
      weight: its unoccluded value at the region's centre for the region's axis, at least
      10⁻² of its bound (:meth:`plan_rows`).

    Every weight is > 0, so that p > 0 wherever light may arrive: sampling by the table is
    unbiased however rough it is. Rows are built once per region, for all luminaires in one
    compiled pass (cost ∝ regions × luminaires, never points × luminaires).

    References
    ----------
    Shirley, P., Wang, C., Zimmerman, K. (1996). Monte Carlo techniques for direct lighting
    calculations. *ACM Transactions on Graphics* 15(1), 1–36 (luminaires sampled by
    estimated contribution, per region of space). Ward, G. J. (1991). Adaptive shadow
    testing for ray tracing. *Eurographics Workshop on Rendering* (importance per region).
    """

    def __init__(self, scene, cell, *, candidates=None):
        self.scene = scene
        self.cell = float(cell)
        tris = scene.triangles.reshape(-1, 3)
        self.origin = tris.min(axis=0) if len(tris) else np.zeros(3)
        samplers = _samplers(scene)
        self.lights = _lights(scene)
        self.area_flux = np.array([s.luminance * s.area for s in samplers], dtype=np.float64)
        self.area_centre = np.array(
            [(s.triangles.mean(axis=1) * (scene.areas[l.triangles] / s.area)[:, None]).sum(axis=0)
             for s, l in zip(samplers, scene.area_luminaires)], dtype=np.float64).reshape(-1, 3)
        self.count = self.lights.count
        k = LUMINAIRE_CANDIDATES if candidates is None else check_positive_int(candidates, "candidates")
        self.candidates = min(k, self.count)
        self.rows = {}  # region key → row of the arrays below (grown by doubling)
        N, K = self.count, self.candidates
        self._store = {"cdf": np.zeros((0, N)), "cand": np.zeros((0, K), dtype=np.int64),
                       "rest_w": np.zeros((0, N)), "rest_cum": np.zeros((0, N))}
        self._lock = threading.Lock()  # renderers call from several threads

    def __getattr__(self, name):  # _cdf, _cand, _rest_w, _rest_cum: the rows built so far
        store = self.__dict__.get("_store")
        if store is None or name[1:] not in store:
            raise AttributeError(name)
        return store[name[1:]][:len(self.rows)]

    def _keys(self, x, n):
        """One int64 key per point: its cube (offset by 1, 20 bits per axis) and face."""
        cube = np.floor((x - self.origin) / self.cell).astype(np.int64) + 1
        axis = np.abs(n).argmax(axis=1)
        sign = n[np.arange(len(n)), axis] < 0
        face = 2 * axis + sign
        return (cube[:, 0] << 43) | (cube[:, 1] << 23) | (cube[:, 2] << 3) | face

    def _build(self, keys):
        """Append the rows of the regions ``keys``."""
        cubes = np.column_stack([keys >> 43, (keys >> 23) & 0xFFFFF, (keys >> 3) & 0xFFFFF]) - 1
        faces = keys & 7
        corners = np.array([[0.5, 0.5, 0.5]] + [[i, j, k] for i in (0, 1) for j in (0, 1)
                                               for k in (0, 1)], dtype=float)
        q = np.ascontiguousarray(self.origin + (cubes[:, None, :] + corners[None]) * self.cell)
        a = np.zeros((len(faces), 3))
        a[np.arange(len(faces)), faces // 2] = np.where(faces % 2, -1.0, 1.0)
        bound = np.empty((len(faces), self.count))
        rep = np.empty_like(bound)
        L = self.lights
        _region_weights(q, a, (self.cell / 2) ** 2, L.points, L.areas, L.n_area, self.area_flux,
                        self.area_centre, bound, rep)
        bound = np.maximum(bound, np.maximum(1e-3 * bound.mean(axis=1, keepdims=True), 1e-300))
        cdf = np.cumsum(bound, axis=1)
        cand = np.argsort(-bound, axis=1, kind="stable")[:, :self.candidates]
        rest_w = np.maximum(rep, 1e-2 * bound)
        np.put_along_axis(rest_w, cand, 0.0, axis=1)
        first = len(self.rows)
        for name, new in (("cdf", cdf / cdf[:, -1:]), ("cand", cand), ("rest_w", rest_w),
                          ("rest_cum", np.cumsum(rest_w, axis=1))):
            old = self._store[name]
            if first + len(new) > len(old):
                grown = np.empty((max(2 * len(old), first + len(new)), old.shape[1]), dtype=old.dtype)
                grown[:first] = old[:first]
                self._store[name] = old = grown
            old[first:first + len(new)] = new
        for k, key in enumerate(keys.tolist()):
            self.rows[key] = first + k

    def _rows(self, x, n, *names):
        """The row of each point's region, built where missing, and the arrays ``names``
        (``"cdf"``, ``"cand"``, ``"rest_w"``, ``"rest_cum"``) as they are then (one thread
        builds at a time; arrays read later by another thread stay valid: views)."""
        keys, inverse = np.unique(self._keys(x, n), return_inverse=True)
        with self._lock:
            missing = np.asarray([k for k in keys.tolist() if k not in self.rows], dtype=np.int64)
            if missing.size:
                self._build(missing)
            rows = np.asarray([self.rows[k] for k in keys.tolist()], dtype=np.int64)[inverse.ravel()]
            return (rows, *(self._store[name][:len(self.rows)] for name in names))

    def cdf(self, x, n):
        """CDF rows (P, N) of the bounds in the regions of points ``x`` with normals ``n``."""
        rows, cdf = self._rows(x, n, "cdf")
        return cdf[rows]

    def plan_rows(self, x, n):
        """What the planning pass of :func:`direct_illuminance` reads for points ``x``
        (normals ``n``): (row of each point, candidates (R, K), their count per row (R,),
        the other luminaires' weights (R, N) and their cumulative sums (R, N)). With at
        most ``candidates`` luminaires, one row: every luminaire a candidate."""
        N = self.count
        if self.candidates >= N:
            return (np.zeros(len(x), dtype=np.int64), np.arange(N, dtype=np.int64)[None, :],
                    np.array([N], dtype=np.int64), np.zeros((1, N)), np.zeros((1, N)))
        row, cand, rest_w, rest_cum = self._rows(x, n, "cand", "rest_w", "rest_cum")
        return (row, cand, np.full(len(cand), self.candidates, dtype=np.int64), rest_w, rest_cum)


def _luminaire_table(scene):
    """The scene's table of :func:`direct_illuminance` (cells of :data:`REGION_CELL` × its
    diagonal), built on first use and kept on the scene."""
    table = getattr(scene, "_luminaire_table", None)
    if table is None:
        table = scene._luminaire_table = LuminaireTable(scene, REGION_CELL * scene.size)
    return table


def sampled_direct_illuminance(scene, engine, points, normals, *, table, seed=0, block_ids=None,
                               purpose_key=0, fresnel=None, fresnel_rule="reciprocal"):
    """Direct illuminance [lx] at points by one luminaire drawn from a :class:`LuminaireTable`.

    Each point draws one luminaire l with the probability p_l of its region's row of bounds
    and returns Ê_l/p_l, Ê_l the one-sample estimate of l (one shadow ray to a point of a
    luminous rectangle or of an area luminaire: unbiased, unlike the ratio form of
    :func:`direct_illuminance`). Unbiased for any table (every p_l > 0), with a variance that
    depends on how well the table ranks the luminaires; meant for many cheap estimates that
    are averaged anyway (the surface cache's near-field hits), where evaluating every
    luminaire at every hit would make the cost ∝ hits × luminaires.

    Parameters
    ----------
    scene, engine, points, normals, fresnel, fresnel_rule
        As :func:`direct_illuminance`.
    table : LuminaireTable
    seed, block_ids, purpose_key
        Random streams ``(seed, "direct", purpose_key, block, 1)`` per block.

    Returns
    -------
    numpy.ndarray, shape (P,)
    """
    x = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    n = np.ascontiguousarray(normals, dtype=np.float64).reshape(-1, 3)
    P = len(x)
    E = np.zeros(P)
    blocks = np.zeros(P, dtype=np.int64) if block_ids is None else np.asarray(block_ids)
    fresnel = _fresnel_points(fresnel, P)
    sky = 0.0
    if scene.distant_sources:  # the sun and the sky, one next-event sample each (solver/sky.py)
        sky = distant_illuminance(scene, engine, x, n, distant_uniforms(scene, seed, (2, purpose_key), blocks, 1),
                                  fresnel=fresnel, fresnel_rule=fresnel_rule)[0]
    if P == 0 or table.count == 0:
        return E + sky
    u = np.empty((P, 4))
    for j in np.unique(blocks):
        m = blocks == j
        u[m] = stream(seed, "direct", purpose_key, j, 1).random((int(m.sum()), 4))
    pick = np.empty(P, dtype=np.int64)
    prob = np.empty(P)
    rows, cdf = table._rows(x, n, "cdf")
    _pick_rows(cdf, rows, np.ascontiguousarray(u[:, 0]), pick, prob)
    lights = _lights(scene)
    of_point = np.flatnonzero(pick >= lights.n_area)
    if of_point.size:
        guide = np.empty(of_point.size)
        _unoccluded_pairs(x, n, of_point, pick[of_point], lights.points, lights.areas,
                          lights.n_area, guide)
        E[of_point] = _point_estimates(scene, lights, x, n, of_point, pick[of_point] - lights.n_area, guide,
                                       np.ascontiguousarray(u[of_point, 1:]), np.arange(of_point.size),
                                       np.ones(of_point.size, dtype=np.int64), engine, fresnel)[0]
    origins = x + engine.epsilon * n
    samplers = _samplers(scene)
    for li in np.unique(pick[pick < lights.n_area]):
        m = np.flatnonzero(pick == li)
        s = samplers[li]
        targets, g, cosine = s.sample(x[m], n[m], u[m, None, 1:], engine.epsilon)
        lit = np.flatnonzero(g[:, 0] > 0)
        if lit.size:
            E[m[lit]] = s.luminance * s.area * g[lit, 0] * shadow_transmittance(scene, engine, origins[m[lit]], targets[lit, 0])
            if fresnel is not None:
                E[m[lit]] *= diffuse_fresnel_factor(cosine[lit, 0], fresnel[m[lit]], rule=fresnel_rule,
                                                    direct=scene.light_source_at(np.full(lit.size, li), x[m[lit]]))
    return E / prob + sky
