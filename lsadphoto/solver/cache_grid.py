"""The surface cache's data: indirect illuminance on the scene's surfaces, and its look-ups.

A :class:`SurfaceCache` is what :func:`~lsadphoto.solver.integrators.surface_cache.build_surface_cache`
estimates and an :class:`~lsadphoto.solver.store.LsadStore` saves. Its points follow the
surface *area*, not the triangle count:

* a triangle larger than the spacing carries the vertices of a regular level-m subdivision
  (one set per side), further subdivided cells where the values vary strongly, and a point's
  value is the linear interpolation of its cell's three vertices;
* the sides of the triangles smaller than the spacing (the tessellation of a vault, a
  column, a bench) share points: they are grouped into *patches* by position (a grid of
  cubes of the spacing), orientation (24 cube-map cells of the side's normal, ≈ 45° each)
  and offset along the normal (slices of spacing/8, which keep apart parallel sheets such
  as the two sides of a column seen through it), one point per patch on its member triangle
  nearest the patch's area centroid (:func:`patch_sides`); patches whose values differ
  strongly from their neighbours' are split again at half the spacing. A point's value is a
  normalised kernel average of the patch points within 1.5 patch sizes whose normal agrees
  with its own, which lie near its tangent plane and which its own patch's point sees (a
  visibility ray per pair of neighbouring patches, cast when the cache is built) (:meth:`SurfaceCache.interpolate`;
  Shepard 1968, with Wendland's compact weight and Ward et al.'s normal criterion).

So a mesh of many small triangles costs as many points as its area needs. The cache holds
data and look-ups only, no estimator.

References
----------
Shepard, D. (1968). A two-dimensional interpolation function for irregularly-spaced data.
*Proc. 23rd ACM National Conference*, 517–524. Wendland, H. (1995). Piecewise polynomial,
positive definite and compactly supported radial functions of minimal degree. *Advances in
Computational Mathematics* 4, 389–396. Ward, G. J., Rubinstein, F. M., Clear, R. D. (1988).
A ray tracing solution for diffuse interreflection. *SIGGRAPH '88*, 85–92. Rossignac, J.,
Borrel, P. (1993). Multi-resolution 3D approximations for rendering complex scenes.
*Modeling in Computer Graphics*, 455–465 (grouping a mesh's elements by a spatial grid).
"""

import math
from dataclasses import dataclass, field

import numpy as np
from .._compiled import njit

from ..errors import BadInputError
from .engine import engine_for
from .materials import shadow_transmittance

__all__ = ["PATCH_KERNEL", "Patches", "SurfaceCache", "cells_over_contrast", "grid_index", "patch_neighbours",
           "patch_sides"]

#: Kernel radius of the patch interpolation, in patch sizes (the grid's cube edge).
PATCH_KERNEL = 1.5
#: Normal agreement below which a patch point does not count (cos 60°), and the largest
#: |sine| of the angle between a patch point's offset and the tangent plane (30°).
_PATCH_COS, _PATCH_PLANE = 0.5, 0.5
#: Standard errors by which a refined cell's corner values may miss the refinement test for
#: an independent cache to leave the cell unrefined (:meth:`SurfaceCache.interpolate_with_bias`).
BORDERLINE_SLACK = 3.0
#: Offset slices per patch size along the normal.
_PATCH_SLICES = 8

_NUMBA = {"cache": True, "error_model": "numpy", "nogil": True}


def grid_index(m, i, j):
    """Index of vertex (i, j) of a level-m triangle grid (rows i = 0…m of m + 1 − i vertices)."""
    return i * (m + 1) - i * (i - 1) // 2 + j


def _cell(m, b1, b2):
    """Cell of barycentric point (b1, b2) in a level-m grid (m ≥ 1, arrays).

    Returns the grid indices of its corners P0, P1, P2, the interpolation weights of P1 and
    P2 (the point is P0 + w1·(P1 − P0) + w2·(P2 − P0)), the cell's key 2·index(i, j) +
    upper, and its (i, j, upper). Lower cells are (i, j), (i + 1, j), (i, j + 1); upper
    cells (i + 1, j + 1), (i + 1, j), (i, j + 1).
    """
    s, t = b1 * m, b2 * m
    i = np.clip(np.floor(s), 0, m - 1).astype(np.int64)
    j = np.clip(np.floor(t), 0, m - 1 - i).astype(np.int64)
    fs, ft = s - i, t - j
    upper = fs + ft > 1.0
    k0 = np.where(upper, grid_index(m, i + 1, j + 1), grid_index(m, i, j))
    k1 = grid_index(m, i + 1, j)
    k2 = grid_index(m, i, j + 1)
    w1 = np.where(upper, 1.0 - ft, fs)
    w2 = np.where(upper, 1.0 - fs, ft)
    return k0, k1, k2, w1, w2, 2 * grid_index(m, i, j) + upper, (i, j, upper)


def cells_over_contrast(mean, se, contrast, *, slack=0.0):
    """Cells whose corner values (group means ``mean`` and their standard errors ``se``
    [lx], each (n, 3)) differ by more than ``contrast`` × the largest and by more than 3
    standard errors of the difference, each test tightened by ``slack`` of those standard
    errors (0: the refinement test of
    :func:`~lsadphoto.solver.integrators.surface_cache.build_surface_cache`). Boolean, (n,)."""
    hi, lo = mean.argmax(axis=1), mean.argmin(axis=1)
    rows = np.arange(len(mean))
    spread = mean[rows, hi] - mean[rows, lo]
    noise = np.hypot(se[rows, hi], se[rows, lo])
    return (spread - slack * noise > contrast * mean[rows, hi]) & (spread > (3.0 + slack) * noise)


def _second_difference(values, m, base, i, j, along):
    """Second differences f(c − e) − 2 f(c) + f(c + e) [lx] of the values (per group) of
    level-m grids (first vertex ``base``) along grid direction ``along`` (0: i, 1: j, 2:
    (1, −1)), averaged over the two stencils centred on the ends of the cell edge that
    starts at vertex (i, j) in that direction, each moved to the nearest stencil that lies
    in the grid (m ≥ 2): e·H·e of the field's Hessian H over the edge vector e where the
    field is quadratic."""
    total = 0.0
    for end in (0, 1):
        if along == 0:  # edge (i, j)–(i + 1, j)
            jc = np.minimum(j, m - 2)
            ic = np.clip(i + end, 1, m - 1 - jc)
            lo, hi = grid_index(m, ic - 1, jc), grid_index(m, ic + 1, jc)
        elif along == 1:  # edge (i, j)–(i, j + 1)
            ic = np.minimum(i, m - 2)
            jc = np.clip(j + end, 1, m - 1 - ic)
            lo, hi = grid_index(m, ic, jc - 1), grid_index(m, ic, jc + 1)
        else:  # edge (i + 1, j)–(i, j + 1), on the line i + j = s
            sc = np.clip(i + j + 1, 2, m)
            ic = np.clip(i + end, 1, sc - 1)
            jc = sc - ic
            lo, hi = grid_index(m, ic + 1, jc - 1), grid_index(m, ic - 1, jc + 1)
        mid = grid_index(m, ic, jc)
        total = total + (values[base + lo] - 2.0 * values[base + mid] + values[base + hi])
    return 0.5 * total


def _barycentric(tri, x):
    """Barycentric coordinates (b1, b2) of points x in triangles tri (n, 3, 3), clipped in."""
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    w = x - tri[:, 0]
    d11 = np.einsum("ij,ij->i", e1, e1)
    d12 = np.einsum("ij,ij->i", e1, e2)
    d22 = np.einsum("ij,ij->i", e2, e2)
    w1 = np.einsum("ij,ij->i", w, e1)
    w2 = np.einsum("ij,ij->i", w, e2)
    det = d11 * d22 - d12 * d12
    b1 = np.clip((d22 * w1 - d12 * w2) / det, 0.0, 1.0)
    b2 = np.clip((d11 * w2 - d12 * w1) / det, 0.0, 1.0)
    total = np.maximum(b1 + b2, 1.0)
    return b1 / total, b2 / total


def _normal_cell(n):
    """Cube-map cell (0…23) of unit vectors n: the dominant axis and its sign, then 2 × 2
    quadrants of the other two components over it."""
    axis = np.abs(n).argmax(axis=1)
    rows = np.arange(len(n))
    major = n[rows, axis]
    u = n[rows, (axis + 1) % 3] / np.abs(major)
    v = n[rows, (axis + 2) % 3] / np.abs(major)
    return ((2 * axis + (major < 0)) * 4 + 2 * (u >= 0) + (v >= 0)).astype(np.int64)


@dataclass
class Patches:
    """Sides of small triangles grouped into patches (:func:`patch_sides`).

    ``patch`` (S,): the patch of each given side; ``point``, ``normal`` (C, 3): each patch's
    point [m] (the centroid of its member side nearest the patch's area centroid) and that
    side's normal; ``reach`` (C,): the largest distance from the point to a vertex of a
    member [m]; ``size``: the patch size [m].
    """

    patch: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    reach: np.ndarray
    size: float


def patch_sides(triangles, normals, areas, size, *, origin, label=None):
    """Group triangle sides into patches of about ``size`` [m] (module docstring).

    Parameters
    ----------
    triangles : ndarray, shape (S, 3, 3)
        Vertices [m] of each side's triangle.
    normals : ndarray, shape (S, 3)
        Unit normal of each side (the triangle's normal or its opposite).
    areas : ndarray, shape (S,)
        Triangle areas [m²].
    size : float
        Edge of the grid's cubes [m].
    origin : array_like, shape (3,)
        Corner of the grid [m].
    label : ndarray of int or bool, shape (S,), optional
        Sides of different labels never share a patch (the cache's Fresnel-weighted sides and
        the others, whose values are different quantities).

    Returns
    -------
    Patches
    """
    S = len(triangles)
    if S == 0:
        return Patches(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), size)
    centroid = triangles.mean(axis=1)
    cube = np.floor((centroid - origin) / size).astype(np.int64)
    middle = np.asarray(origin) + (cube + 0.5) * size
    offset = np.floor(np.einsum("ij,ij->i", normals, centroid - middle) * _PATCH_SLICES / size)
    key = np.column_stack([cube, _normal_cell(normals), offset.astype(np.int64),
                           np.zeros(S, np.int64) if label is None else np.asarray(label, np.int64)])
    _, patch = np.unique(key, axis=0, return_inverse=True)
    patch = patch.ravel()
    C = int(patch.max()) + 1
    mass = np.bincount(patch, weights=areas, minlength=C)
    mean = np.stack([np.bincount(patch, weights=areas * centroid[:, k], minlength=C)
                     for k in range(3)], axis=1) / np.maximum(mass, 1e-300)[:, None]
    dist = np.linalg.norm(centroid - mean[patch], axis=1)
    order = np.lexsort((dist, patch))
    first = order[np.r_[0, np.flatnonzero(np.diff(patch[order])) + 1]]
    point = centroid[first]
    reach = np.zeros(C)
    np.maximum.at(reach, patch, np.linalg.norm(triangles - point[patch][:, None], axis=2).max(axis=1))
    return Patches(patch, point, np.ascontiguousarray(normals[first]), reach, float(size))


def patch_neighbours(point, radius, reach):
    """CSR lists (start (C + 1,), index) of the patches within ``radius + reach`` of each
    patch's point: every patch point within ``radius`` of any point of a patch is in its list."""
    from scipy.spatial import cKDTree

    C = len(point)
    if C == 0:
        return np.zeros(1, np.int64), np.zeros(0, np.int64)
    lists = cKDTree(point).query_ball_point(point, radius + reach)
    start = np.zeros(C + 1, np.int64)
    start[1:] = np.cumsum([len(x) for x in lists])
    return start, np.concatenate([np.asarray(x, np.int64) for x in lists])


@njit(inline="always", **_NUMBA)
def _patch_weight(x, n, i, point, normal, clearance, j, r2):
    """Kernel weight of patch point j at point i (normal n[i]) and their offset
    (point[j] − x[i]): (1 − d²/r²)² within the radius, times how well the normals agree
    (above cos 60°) and how close j lies to i's tangent plane; 0 outside, and 0 where the
    distance exceeds j's clearance (:attr:`SurfaceCache.clearance`)."""
    dx = point[j, 0] - x[i, 0]
    dy = point[j, 1] - x[i, 1]
    dz = point[j, 2] - x[i, 2]
    d2 = dx * dx + dy * dy + dz * dz
    if d2 >= r2 or d2 > clearance[j] * clearance[j]:
        return 0.0, dx, dy, dz
    agree = n[i, 0] * normal[j, 0] + n[i, 1] * normal[j, 1] + n[i, 2] * normal[j, 2]
    if agree <= _PATCH_COS:
        return 0.0, dx, dy, dz
    d = math.sqrt(d2)
    tilt = abs(n[i, 0] * dx + n[i, 1] * dy + n[i, 2] * dz) / d if d > 0 else 0.0
    if tilt >= _PATCH_PLANE:
        return 0.0, dx, dy, dz
    q = 1.0 - d2 / r2
    return q * q * (agree - _PATCH_COS) / (1.0 - _PATCH_COS) * (1.0 - tilt / _PATCH_PLANE), dx, dy, dz


@njit(**_NUMBA, aot="void(float64[:, ::1], float64[:, ::1], int64[::1], float64[:, ::1], float64[:, ::1], "
                    "float64[::1], float64[::1], int64[::1], int64[::1], float64[:, ::1], boolean, "
                    "float64[:, ::1], float64[:, ::1], float64[::1], float64[::1])")
def _patch_kernel(x, n, own, point, normal, clearance, radius, start, index, values, with_bias, out,
                  bias, support, lean):
    """out[i] = the kernel average of ``values`` over the patches near point i (see
    :meth:`SurfaceCache.interpolate`), its own patch's value where none qualifies;
    support[i] = the weights' mean distance [m] from point i to those patch points (to its
    own patch's point where none qualifies); lean[i] = the length [m] of the weights' centroid
    ū of the patch points' offsets on the tangent plane (defined below; ≈ support[i] where
    all of them lie on one side of x, the average then an extrapolation; support[i] where
    none qualifies); and, with
    ``with_bias``, bias[i] = that average's first-order bias per group: g·ū, ū the weights'
    centroid of the patch points' offsets u_j = q_j − x projected on the tangent plane, g the
    gradient of a weighted least-squares plane through their values (g = (C + λI)⁻¹ Σ w_j
    (u_j − ū)(E_j − Ē), C = Σ w_j (u_j − ū)(u_j − ū)ᵀ, λ = 10⁻³·trace C): the kernel average
    minus the weighted linear fit's value at x, exact for a linear field; 0 where fewer than
    two points qualify (no gradient to fit). One walk over the neighbours gives both."""
    P = x.shape[0]
    G = values.shape[1]
    K = 1
    for c in range(start.size - 1):
        K = max(K, start[c + 1] - start[c])
    wk = np.empty(K)
    uk = np.empty((K, 2))
    jk = np.empty(K, np.int64)
    for i in range(P):
        c = own[i]
        r2 = radius[c] * radius[c]
        # a tangent basis (t1, t2) at x
        if abs(n[i, 0]) < 0.9:
            ax, ay, az = 1.0, 0.0, 0.0
        else:
            ax, ay, az = 0.0, 1.0, 0.0
        dot = ax * n[i, 0] + ay * n[i, 1] + az * n[i, 2]
        t1x, t1y, t1z = ax - dot * n[i, 0], ay - dot * n[i, 1], az - dot * n[i, 2]
        norm = math.sqrt(t1x * t1x + t1y * t1y + t1z * t1z)
        t1x, t1y, t1z = t1x / norm, t1y / norm, t1z / norm
        t2x = n[i, 1] * t1z - n[i, 2] * t1y
        t2y = n[i, 2] * t1x - n[i, 0] * t1z
        t2z = n[i, 0] * t1y - n[i, 1] * t1x
        count = 0
        total = 0.0
        reach = 0.0
        u0 = 0.0
        u1 = 0.0
        for g in range(G):
            out[i, g] = 0.0
            bias[i, g] = 0.0
        for k in range(start[c], start[c + 1]):
            j = index[k]
            w, dx, dy, dz = _patch_weight(x, n, i, point, normal, clearance, j, r2)
            if w <= 0.0:
                continue
            total += w
            reach += w * math.sqrt(dx * dx + dy * dy + dz * dz)
            p0 = dx * t1x + dy * t1y + dz * t1z  # the offset on the tangent plane
            p1 = dx * t2x + dy * t2y + dz * t2z
            u0 += w * p0
            u1 += w * p1
            for g in range(G):
                out[i, g] += w * values[j, g]
            if with_bias:
                wk[count] = w
                uk[count, 0] = p0
                uk[count, 1] = p1
                jk[count] = j
            count += 1
        if total > 0:
            for g in range(G):
                out[i, g] /= total
            support[i] = reach / total
            lean[i] = math.sqrt(u0 * u0 + u1 * u1) / total
        else:
            for g in range(G):
                out[i, g] = values[c, g]
            support[i] = math.sqrt((point[c, 0] - x[i, 0]) ** 2 + (point[c, 1] - x[i, 1]) ** 2
                                   + (point[c, 2] - x[i, 2]) ** 2)
            lean[i] = support[i]
        if not with_bias or count < 2 or total <= 0:
            continue
        m0 = u0 / total  # ū
        m1 = u1 / total
        c00 = 0.0
        c01 = 0.0
        c11 = 0.0
        for k in range(count):
            a0, a1 = uk[k, 0] - m0, uk[k, 1] - m1
            c00 += wk[k] * a0 * a0
            c01 += wk[k] * a0 * a1
            c11 += wk[k] * a1 * a1
        lam = 1e-3 * (c00 + c11)
        c00 += lam
        c11 += lam
        det = c00 * c11 - c01 * c01
        if not det > 0:
            continue
        for g in range(G):
            mean = out[i, g]
            s0 = 0.0
            s1 = 0.0
            for k in range(count):
                e = wk[k] * (values[jk[k], g] - mean)
                s0 += e * (uk[k, 0] - m0)
                s1 += e * (uk[k, 1] - m1)
            g0 = (c11 * s0 - c01 * s1) / det
            g1 = (c00 * s1 - c01 * s0) / det
            bias[i, g] = g0 * m0 + g1 * m1


@dataclass
class SurfaceCache:
    """Indirect illuminance on the scene's surfaces: triangle grids and shared patch points.

    Attributes
    ----------
    spacing : float
        Target spacing of the cache points [m].
    level : ndarray of int, shape (T,)
        Subdivision level m of each triangle (≥ 1: its own grid; 0: a small triangle whose
        sides take their values from patches; −1: not cached).
    offset : ndarray of int, shape (T, 2)
        Index of each grid triangle's first vertex for its front (0) and back (1) side (−1
        for the others).
    values : ndarray, shape (V, groups)
        E_ind [lx] at each point, per group of node draws.
    positions : ndarray, shape (V, 3)
        Where each value was estimated [m] (grid vertices, moved a few ray offsets inside
        their triangle; patch points).
    refined_key, refined_offset : ndarray of int, shape (C,)
        Refined cells (sorted keys 2·(global index of the cell's (i, j) vertex) + upper) and
        the index of the first vertex of each one's level-``refine`` grid in ``values``.
    refine : int
        Subdivision level of refined cells.
    provenance : dict
        Nodes per point, ε, seed, build time.
    patch : ndarray of int, shape (T, 2)
        The (finest) patch of each side of a small triangle (−1 for the others).
    patch_row : ndarray of int, shape (Q,)
        Row in ``values`` of each patch's point.
    patch_normal : ndarray, shape (Q, 3)
        Unit normal at each patch point.
    patch_radius : ndarray, shape (Q,)
        Kernel radius [m] of interpolations on the patch's sides (:data:`PATCH_KERNEL` ×
        its patch size).
    patch_start, patch_index : ndarray of int
        CSR lists of the patches that may lie within the kernel radius of a point of each
        patch (:func:`patch_neighbours`) and whose point that patch's point sees.
    clearance : ndarray, shape (V,)
        Free distance [m] in front of each point along its normal (∞ where the ray leaves
        the scene; ∞ for caches saved without it): a point counts in an interpolation at x
        only if |x − point| ≤ its clearance (:meth:`interpolate`).
    """

    spacing: float
    level: np.ndarray
    offset: np.ndarray
    values: np.ndarray
    positions: np.ndarray
    refined_key: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    refined_offset: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    refine: int = 4
    provenance: dict = field(default_factory=dict)
    patch: np.ndarray = None
    patch_row: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    patch_normal: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    patch_radius: np.ndarray = field(default_factory=lambda: np.zeros(0))
    patch_start: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    patch_index: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    clearance: np.ndarray = None

    #: The arrays a store saves (besides ``spacing``, ``refine`` and ``provenance``).
    ARRAYS = ("level", "offset", "values", "positions", "refined_key", "refined_offset",
              "patch", "patch_row", "patch_normal", "patch_radius", "patch_start",
              "patch_index", "clearance")

    def __post_init__(self):
        if self.patch is None:
            self.patch = np.full((len(self.level), 2), -1, np.int64)
        if self.clearance is None:
            self.clearance = np.full(len(self.values), np.inf)

    @property
    def size(self):
        """Number of cache points."""
        return len(self.values)

    def _cells(self, scene, prim, x, side, *, refined=True):
        """Indices of the three grid points around points ``x`` on grid triangles ``prim``
        (level ≥ 1; side 0 front, 1 back) and their linear-interpolation weights, each (n, 3),
        and the cells as (level, first vertex, i, j, upper) of the grid they lie in (the
        triangle's, or with ``refined`` a refined cell's level-``refine`` grid)."""
        b1, b2 = _barycentric(scene.triangles[prim], x)
        m = self.level[prim]
        base = self.offset[prim, side]
        if np.any(m < 1) or np.any(base < 0):
            raise BadInputError("surface cache lacks a triangle seen in this view (a stale cache?)")
        k0, k1, k2, w1, w2, key, (i, j, upper) = _cell(m, b1, b2)
        index = np.stack([base + k0, base + k1, base + k2], axis=1)
        weight = np.stack([1.0 - w1 - w2, w1, w2], axis=1)
        if refined and self.refined_key.size:
            global_key = 2 * base + key  # base + index(i, j) doubled, plus upper
            pos = np.minimum(np.searchsorted(self.refined_key, global_key), self.refined_key.size - 1)
            fine = self.refined_key[pos] == global_key
            if fine.any():
                r = self.refine
                f0, f1, f2, v1, v2, _, (fi, fj, fu) = _cell(r, w1[fine], w2[fine])
                start = self.refined_offset[pos[fine]]
                index[fine] = np.stack([start + f0, start + f1, start + f2], axis=1)
                weight[fine] = np.stack([1.0 - v1 - v2, v1, v2], axis=1)
                m[fine], base[fine], i[fine], j[fine], upper[fine] = r, start, fi, fj, fu
        return index, weight, (m, base, i, j, upper)

    def interpolate(self, scene, prim, x, side):
        """E_ind per group [lx] at points ``x`` on triangles ``prim``, side 0 (front) or 1.

        On grid triangles the linear interpolation of the cell's corners; on small
        triangles the kernel average over patch points q_j within the kernel radius R,

            E(x) = Σ_j w_j E_j / Σ_j w_j,   w_j = (1 − d²/R²)² · (c_j − ½)/½ · (1 − 2 s_j),

        with d = |q_j − x|, c_j = n·n_j > ½ (normals within 60°) and s_j = |n·(q_j − x)|/d
        < ½ (q_j within 30° of the tangent plane at x, which keeps the far side of a column
        or a parallel sheet out); the side's own patch where no point qualifies.

        Both drop a point farther from x than its clearance t_j (the free distance along its
        normal) and renormalise the others' weights: a surface at t_j in front of a point
        changes E_ind over distances of about t_j along the surface, so a point behind a
        panel, a shelf or furniture standing close does not stand for the uncovered surface
        beside it (Ward et al. 1988's validity radius, with the distance along the normal
        in place of the harmonic mean of the hemisphere's, which a concave corner's
        grazing rays would shrink to nothing where E_ind varies smoothly). On grid
        triangles a corner is also dropped where a visibility ray between x and it (both a
        ray offset off the surface) is blocked: a column, a partition or a box standing on
        the triangle, whose footprint's points are dark and whose lid or the far ceiling
        gives them a large clearance (a glass pane does not hide). A grid cell none of whose corners with a positive
        weight qualifies keeps its plain interpolation: within a convex occluder's
        footprint, where no pixel sees the wall. (Patches need no such ray: their
        neighbour lists hold only the patches that the own patch's point sees.)
        """
        return self._interpolate(scene, prim, x, side, False)[0]

    def interpolate_with_bias(self, scene, prim, x, side, *, support=False):
        """:meth:`interpolate` and its estimated bias [lx] per group, each shape (n, groups),
        in one pass: the estimate minus the true E_ind, to leading order (grid triangles:
        :meth:`_grid_bias`, and in refined cells near the refinement test the difference from
        the coarse interpolation, :meth:`_borderline_bias`; the patches of small triangles: the kernel average's first-order
        bias, :func:`_patch_kernel`). With ``support``, also the interpolation's support
        distance [m], shape (n,): the weights' mean distance from each point to the cache
        points that interpolate it (the bias estimate sees E_ind only at that distance), and
        its lean [m], shape (n,): on small triangles the distance from each point to those
        points' weighted centroid on its tangent plane (near the support distance where they
        all lie on one side: an extrapolation; :func:`_patch_kernel`), 0 on grid triangles,
        whose cells enclose the point."""
        value, bias, distance, lean = self._interpolate(scene, prim, x, side, True)
        return (value, bias, distance, lean) if support else (value, bias)

    def _interpolate(self, scene, prim, x, side, with_bias):
        """E_ind per group, shape (n, groups), with ``with_bias`` its bias (else None), and
        the support distance and lean [m], shape (n,) each (:meth:`interpolate_with_bias`): the grid's
        interpolation where ``prim`` has a grid (level ≥ 1), the patches' kernel average on
        small triangles (level 0)."""
        prim = np.asarray(prim)
        side = np.broadcast_to(np.asarray(side), prim.shape)
        m = self.level[prim]
        if np.any(m < 0):
            raise BadInputError("surface cache lacks a triangle seen in this view (a stale cache?)")
        value = np.zeros((len(prim), self.values.shape[1]))
        bias = np.zeros_like(value) if with_bias else None
        distance = np.zeros(len(prim))
        lean = np.zeros(len(prim))
        grid = np.flatnonzero(m >= 1)
        if grid.size:
            index, weight, cells = self._cells(scene, prim[grid], x[grid], side[grid])
            normal = np.where((side[grid] == 0)[:, None], 1.0, -1.0) * scene.normals[prim[grid]]
            weight = self._seen(scene, x[grid], normal, index, weight)
            value[grid] = np.einsum("nk,nkg->ng", weight, self.values[index])
            distance[grid] = np.einsum("nk,nk->n", weight,
                                       np.linalg.norm(self.positions[index] - x[grid][:, None], axis=2))
            if with_bias:
                b = self._grid_bias(weight, cells)
                if self.refined_key.size:  # added to the magnitude of the groups' mean
                    sign = np.where(b.mean(axis=1) < 0, -1.0, 1.0)[:, None]
                    b = b + sign * self._borderline_bias(scene, prim[grid], x[grid], side[grid], normal, index,
                                                         value[grid])
                bias[grid] = b
        small = np.flatnonzero(m == 0)
        if small.size:
            value[small], b, distance[small], lean[small] = self._on_patches(scene, prim[small], x[small],
                                                                             side[small], with_bias)
            if with_bias:
                bias[small] = b
        return value, bias, distance, lean

    def _seen(self, scene, x, normal, index, weight):
        """The corner weights (n, 3) of points ``x`` (unit normals ``normal`` of their side)
        with the corners farther than their clearance or hidden from x dropped and the rest
        renormalised (unchanged where none with a positive weight qualifies;
        :meth:`interpolate`). Hidden: the segment between x and the corner, both a ray offset
        off the surface, is blocked by an opaque surface — a column, a partition or a box
        standing on the triangle between them (glass lets it pass, as shadow rays do:
        :func:`~lsadphoto.solver.materials.shadow_transmittance`)."""
        q = self.positions[index]
        drop = np.linalg.norm(q - x[:, None], axis=2) > self.clearance[index]
        test = np.flatnonzero(~drop & (weight > 0))
        if test.size:
            engine = engine_for(scene)
            row, corner = np.divmod(test, 3)
            lift = engine.epsilon * normal[row]
            drop.flat[test] = shadow_transmittance(scene, engine, x[row] + lift, q[row, corner] + lift) <= 0
        if not drop.any():
            return weight
        kept = np.where(drop, 0.0, weight)
        total = kept.sum(axis=1, keepdims=True)
        return np.where(total > 0, kept / np.where(total > 0, total, 1.0), weight)

    def _grid_bias(self, weight, cells):
        """Estimated bias of the linear interpolation [lx] per group at points in ``cells``
        (:meth:`_cells`) with corner weights ``weight``, shape (n, groups).

        Linear interpolation over a cell with corners P_a and barycentric weights w_a errs
        for a field f of Hessian H by (I − f)(x) = ½ Σ_(a<b) w_a·w_b·(P_a − P_b)ᵀH(P_a − P_b)
        (exact for a quadratic f; the error of a field with bounded second derivatives
        falls as h², h the cell's edge). Each quadratic form is the second difference of the
        cached values along that edge's grid direction (:func:`_second_difference`): the
        difference between the interpolation at h and the quadratic one through the
        neighbouring vertices (a stencil of 2h), i.e. the Richardson estimate of the
        leading error with its order p = 2. Level-1 grids (no stencil) give 0.
        """
        m, base, i, j, upper = cells
        v = self.values
        out = np.zeros((len(m), v.shape[1]))
        ok = np.flatnonzero(m >= 2)
        if not ok.size:
            return out
        m, base, i, j, upper, w = m[ok], base[ok], i[ok], j[ok], upper[ok], weight[ok]
        # edges P0P1, P0P2, P1P2: lower cell along i from (i, j), along j from (i, j); upper
        # cell along j from (i + 1, j), along i from (i, j + 1); both along (1, −1) from (i, j)
        q01, q02 = np.empty((2, len(m), v.shape[1]))
        lo, hi = np.flatnonzero(~upper), np.flatnonzero(upper)
        q01[lo] = _second_difference(v, m[lo], base[lo], i[lo], j[lo], 0)
        q02[lo] = _second_difference(v, m[lo], base[lo], i[lo], j[lo], 1)
        q01[hi] = _second_difference(v, m[hi], base[hi], i[hi] + 1, j[hi], 1)
        q02[hi] = _second_difference(v, m[hi], base[hi], i[hi], j[hi] + 1, 0)
        q12 = _second_difference(v, m, base, i, j, 2)
        out[ok] = 0.5 * (w[:, :1] * w[:, 1:2] * q01 + w[:, :1] * w[:, 2:] * q02
                         + w[:, 1:2] * w[:, 2:] * q12)
        return out

    def _borderline_bias(self, scene, prim, x, side, normal, index, value):
        """|fine − coarse| [lx] per group, shape (n, groups), at points ``x`` whose
        interpolation ``value`` (corner indices ``index``) is a refined cell's whose corner
        values on the triangle's own grid pass the refinement test by less than
        :data:`BORDERLINE_SLACK` standard errors (:func:`cells_over_contrast`); 0 elsewhere.
        The build's refinement follows the noise of those corner values, so an independent
        cache leaves such a cell unrefined as often as not and interpolates it on the coarse
        grid, which all its groups share: the difference between the two interpolations is
        an error that one cache's groups do not see (docs/accuracy.md, session 12)."""
        out = np.zeros_like(value)
        own, own_weight, _ = self._cells(scene, prim, x, side, refined=False)
        fine = np.flatnonzero(np.any(own != index, axis=1))
        contrast = self.provenance.get("refine_contrast")
        if not fine.size or contrast is None:
            return out
        corner = self.values[own[fine]]
        G = self.values.shape[1]
        clear = cells_over_contrast(corner.mean(axis=2), corner.std(axis=2, ddof=1) / math.sqrt(G), contrast,
                                    slack=BORDERLINE_SLACK)
        near = fine[~clear]
        w = self._seen(scene, x[near], normal[near], own[near], own_weight[near])
        out[near] = np.abs(value[near] - np.einsum("nk,nkg->ng", w, self.values[own[near]]))
        return out

    def _on_patches(self, scene, prim, x, side, with_bias):
        """:func:`_patch_kernel` at points ``x`` on small triangles ``prim``, side 0 (front)
        or 1: the kernel average and its bias (zeros without ``with_bias``), each (n, groups),
        and the support distance and lean [m], (n,) each."""
        own = self.patch[prim, side]
        if np.any(own < 0):
            raise BadInputError("surface cache lacks a triangle seen in this view (a stale cache?)")
        sign = np.where(side == 0, 1.0, -1.0)[:, None]
        n = np.ascontiguousarray(sign * scene.normals[prim], dtype=np.float64)
        value = np.empty((len(prim), self.values.shape[1]))
        bias = np.empty_like(value)
        support = np.empty(len(prim))
        lean = np.empty(len(prim))
        _patch_kernel(np.ascontiguousarray(x, dtype=np.float64), n, own,
                      np.ascontiguousarray(self.positions[self.patch_row]),
                      np.ascontiguousarray(self.patch_normal),
                      np.ascontiguousarray(self.clearance[self.patch_row]), self.patch_radius,
                      self.patch_start, self.patch_index,
                      np.ascontiguousarray(self.values[self.patch_row]), with_bias, value, bias, support, lean)
        return value, bias, support, lean
