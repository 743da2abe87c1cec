"""Ray engine: closest hits and visibility through Embree (embreex).

All triangles of a scene live in one Embree scene; per-triangle data (normal, material,
emitter) stay in numpy arrays indexed by Embree's primitive id. Embree works in float32,
so rays start a small distance off the surface they leave: origins are offset by
``epsilon`` along the surface normal (towards the side the ray goes), and visibility rays
stop ``epsilon`` short of their target. ``epsilon`` defaults to
:data:`RELATIVE_EPSILON` × the scene's bounding-box diagonal (1e-5: 60 µm for a 6 m room,
far above float32 rounding of coordinates, ≈ 1e-7 relative, and far below any feature that
matters for lighting).

References
----------
Wald, I. et al. (2014). Embree: a kernel framework for efficient CPU ray tracing. *ACM
Trans. Graph.* 33(4), 143. PITFALLS.md (embreex 4.4 throughput).
"""

import math

import numpy as np

from .._compiled import njit

__all__ = ["RELATIVE_EPSILON", "RayEngine", "engine_for"]

#: Self-intersection offset as a fraction of the scene's bounding-box diagonal.
RELATIVE_EPSILON = 1e-5

#: Largest number of rays handed to Embree in one call (bounds temporary memory).
_RAY_BATCH = 1 << 20


class RayEngine:
    """Closest-hit and occlusion queries on a triangle soup.

    Parameters
    ----------
    triangles : ndarray, shape (n, 3, 3)
        Vertex coordinates [m].
    epsilon : float, optional
        Self-intersection offset [m]; default :data:`RELATIVE_EPSILON` × scene size.
    """

    def __init__(self, triangles, *, epsilon=None):
        import embreex.rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh

        tris = np.asarray(triangles, dtype=float)
        lo, hi = tris.reshape(-1, 3).min(axis=0), tris.reshape(-1, 3).max(axis=0)
        size = float(np.linalg.norm(hi - lo))
        self.epsilon = RELATIVE_EPSILON * size if epsilon is None else float(epsilon)
        self._scene = rtcs.EmbreeScene()
        # Keep a reference: Embree shares the vertex buffer.
        self._vertices = np.ascontiguousarray(tris, dtype=np.float32)
        self._mesh = TriangleMesh(self._scene, self._vertices)

    def closest_hit(self, origins, directions):
        """Primitive id (−1 on a miss) and distance [m] of the first hit of each ray.

        ``directions`` must be unit vectors; ``origins`` are used as given (offset them).
        """
        o = np.asarray(origins, dtype=np.float32).reshape(-1, 3)
        d = np.asarray(directions, dtype=np.float32).reshape(-1, 3)
        prim = np.empty(len(o), dtype=np.int64)
        dist = np.empty(len(o), dtype=np.float64)
        for s in range(0, len(o), _RAY_BATCH):
            out = self._scene.run(np.ascontiguousarray(o[s:s + _RAY_BATCH]),
                                  np.ascontiguousarray(d[s:s + _RAY_BATCH]), output=1)
            prim[s:s + _RAY_BATCH] = out["primID"]
            dist[s:s + _RAY_BATCH] = out["tfar"]
        dist[prim < 0] = np.inf
        return prim, dist

    def visible(self, origins, targets):
        """True where the segment from each origin to its target is unobstructed.

        The segment is shortened by ``epsilon`` at the target end; offset the origin
        yourself. Zero-length segments count as visible.
        """
        o = np.ascontiguousarray(origins, dtype=np.float64).reshape(-1, 3)
        t = np.ascontiguousarray(targets, dtype=np.float64).reshape(-1, 3)
        index = np.empty(len(o), dtype=np.int64)
        o32, d32 = np.empty((len(o), 3), dtype=np.float32), np.empty((len(o), 3), dtype=np.float32)
        t32 = np.empty(len(o), dtype=np.float32)
        m = _segments(o, t, self.epsilon, index, o32, d32, t32)
        out = np.ones(len(o), dtype=bool)
        if m:
            out[index[:m]] = ~self.occluded(o32[:m], d32[:m], t32[:m])
        return out

    def occluded(self, origins, directions, tmax):
        """True where a ray hits anything before ``tmax`` (float32 arrays, unit directions,
        as Embree takes them: no conversion or copy when contiguous)."""
        hit = np.empty(len(origins), dtype=bool)
        for s in range(0, len(origins), _RAY_BATCH):
            res = self._scene.run(np.ascontiguousarray(origins[s:s + _RAY_BATCH], dtype=np.float32),
                                  np.ascontiguousarray(directions[s:s + _RAY_BATCH], dtype=np.float32),
                                  dists=np.ascontiguousarray(tmax[s:s + _RAY_BATCH], dtype=np.float32),
                                  query="OCCLUDED")
            hit[s:s + _RAY_BATCH] = np.asarray(res) >= 0
        return hit


@njit(cache=True, error_model="numpy", nogil=True,
      aot="int64(float64[:, ::1], float64[:, ::1], float64, int64[::1], float32[:, ::1], float32[:, ::1], "
          "float32[::1])")
def _segments(origins, targets, epsilon, index, o32, d32, t32):
    """The float32 rays of the segments from ``origins`` to ``targets`` longer than
    ``epsilon``: returns their number m, their rows in ``index[:m]``, and origin, unit
    direction and length less ``epsilon`` in ``o32``, ``d32``, ``t32`` [:m] (computed in
    float64, rounded once)."""
    m = 0
    for i in range(origins.shape[0]):
        vx = targets[i, 0] - origins[i, 0]
        vy = targets[i, 1] - origins[i, 1]
        vz = targets[i, 2] - origins[i, 2]
        length = math.sqrt(vx * vx + vy * vy + vz * vz)
        if length > epsilon:
            index[m] = i
            o32[m, 0], o32[m, 1], o32[m, 2] = origins[i, 0], origins[i, 1], origins[i, 2]
            d32[m, 0], d32[m, 1], d32[m, 2] = vx / length, vy / length, vz / length
            t32[m] = length - epsilon
            m += 1
    return m


def engine_for(scene):
    """The scene's :class:`RayEngine`, built on first use and kept on the scene.

    Every estimator of one scene shares it, so Embree builds its bounding-volume hierarchy
    once per scene.
    """
    eng = getattr(scene, "_engine", None)
    if eng is None:
        eng = RayEngine(scene.triangles)
        scene._engine = eng
    return eng
