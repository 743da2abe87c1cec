"""The surface cache's data: indirect illuminance on a subdivision of every triangle.

A :class:`SurfaceCache` is what :func:`~lsadphoto.solver.integrators.surface_cache.build_surface_cache`
estimates and an :class:`~lsadphoto.solver.store.LsadStore` saves: values at the vertices of a
regular level-m subdivision of each reflecting triangle (one set per side), further
subdivided cells where the values vary strongly, and the linear interpolation that gives a
point's value from its cell's three vertices. It holds data and look-ups only, no estimator.
"""

from dataclasses import dataclass, field

import numpy as np

from ..errors import BadInputError

__all__ = ["SurfaceCache", "grid_index"]


def grid_index(m, i, j):
    """Index of vertex (i, j) of a level-m triangle grid (rows i = 0…m of m + 1 − i vertices)."""
    return i * (m + 1) - i * (i - 1) // 2 + j


def _cell(m, b1, b2):
    """Cell of barycentric point (b1, b2) in a level-m grid (m ≥ 1, arrays).

    Returns the grid indices of its corners P0, P1, P2, the interpolation weights of P1 and
    P2 (the point is P0 + w1·(P1 − P0) + w2·(P2 − P0)) and the cell's key 2·index(i, j) +
    upper. Lower cells are (i, j), (i + 1, j), (i, j + 1); upper cells (i + 1, j + 1),
    (i + 1, j), (i, j + 1).
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
    return k0, k1, k2, w1, w2, 2 * grid_index(m, i, j) + upper


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


@dataclass
class SurfaceCache:
    """Indirect illuminance at the vertices of a subdivision of every reflecting triangle.

    Attributes
    ----------
    spacing : float
        Target spacing of the cache points [m].
    level : ndarray of int, shape (T,)
        Subdivision level m of each triangle (0: one point at the centroid; −1: not cached).
    offset : ndarray of int, shape (T, 2)
        Index of each triangle's first vertex for its front (0) and back (1) side.
    values : ndarray, shape (V, groups)
        E_ind [lx] at each vertex, per group of node draws.
    positions : ndarray, shape (V, 3)
        Where each value was estimated [m] (grid vertices, moved a few ray offsets inside
        their triangle).
    refined_key, refined_offset : ndarray of int, shape (C,)
        Refined cells (sorted keys 2·(global index of the cell's (i, j) vertex) + upper) and
        the index of the first vertex of each one's level-``refine`` grid in ``values``.
    refine : int
        Subdivision level of refined cells.
    provenance : dict
        Nodes per point, ε, seed, build time.
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

    @property
    def size(self):
        """Number of cache points."""
        return len(self.values)

    def corners(self, scene, prim, x, side):
        """Indices of the three cache points around points ``x`` on triangles ``prim``
        (side 0 front, 1 back) and their linear-interpolation weights, each (n, 3)."""
        b1, b2 = _barycentric(scene.triangles[prim], x)
        m = self.level[prim]
        base = self.offset[prim, side]
        if np.any(m < 0) or np.any(base < 0):
            raise BadInputError("surface cache lacks a triangle seen in this view (a stale cache?)")
        mi = np.maximum(m, 1)
        k0, k1, k2, w1, w2, key = _cell(mi, b1, b2)
        index = np.stack([base + k0, base + k1, base + k2], axis=1)
        weight = np.stack([1.0 - w1 - w2, w1, w2], axis=1)
        single = m == 0
        index[single] = base[single, None]
        weight[single] = (1.0, 0.0, 0.0)
        if self.refined_key.size:
            global_key = 2 * base + key  # base + index(i, j) doubled, plus upper
            pos = np.minimum(np.searchsorted(self.refined_key, global_key), self.refined_key.size - 1)
            fine = (self.refined_key[pos] == global_key) & ~single
            if fine.any():
                r = self.refine
                f0, f1, f2, v1, v2, _ = _cell(r, w1[fine], w2[fine])
                start = self.refined_offset[pos[fine]]
                index[fine] = np.stack([start + f0, start + f1, start + f2], axis=1)
                weight[fine] = np.stack([1.0 - v1 - v2, v1, v2], axis=1)
        return index, weight

    def interpolate(self, scene, prim, x, side):
        """E_ind per group [lx] at points ``x`` on triangles ``prim``, side 0 (front) or 1."""
        index, weight = self.corners(scene, prim, x, side)
        return np.einsum("nk,nkg->ng", weight, self.values[index])
