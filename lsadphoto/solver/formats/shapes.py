"""Curved surfaces tessellated into the solver's triangles, with an explicit accuracy knob.

Radiance's ``sphere``/``bubble``, ``cone``/``cup``, ``cylinder``/``tube`` and ``ring`` are
exact quadrics; the solver traces triangles. Each shape is cut into ``n`` segments around
its axis, where ``n`` is the smallest number for which the chord's sagitta is at most
``tessellation_error`` times the radius, 1 − cos(π/n) ≤ ε, and the vertices are then
pushed out radially by the factor that makes the tessellated **area equal to the exact
area** (to rounding). So fluxes of emitting surfaces and the reflecting area are exact, and
the surface lies within about ε·r of the true one; a projected area (the solid angle a
shape subtends, seen from afar) therefore differs from the exact one by a relative amount
of order ε (measured in ``tests/test_radiance_reader.py`` over 200 directions: at most
0.7 ε for spheres and 0.2 ε for cylinders; exact for rings).

Every function returns triangles ``(k, 3, 3)`` [m] wound counter-clockwise seen from the
shape's front side (the side Radiance's surface normal points to).

References
----------
Ward Larson, G., Shakespeare, R. (1998). *Rendering with Radiance*, Morgan Kaufmann,
ch. 1 and the Radiance reference manual (``ray.html``: sphere, bubble, cone, cup, cylinder,
tube, ring — definitions and normal directions).
"""

import math

import numpy as np

from ...errors import BadInputError

__all__ = ["DEFAULT_TESSELLATION_ERROR", "annulus_triangles", "cone_triangles", "segments_for",
           "sphere_triangles"]

#: Default largest sagitta of a tessellated curve relative to its radius [–] (0.1 %).
DEFAULT_TESSELLATION_ERROR = 1e-3


def segments_for(tessellation_error):
    """Segments around a circle so that the sagitta 1 − cos(π/n) is at most ε (n ≥ 8).

    Examples
    --------
    >>> segments_for(1e-3), segments_for(1e-2)
    (71, 23)
    """
    eps = float(tessellation_error)
    if not 0 < eps < 0.5:
        raise BadInputError(f"tessellation_error must be in (0, 0.5), got {tessellation_error!r}")
    return max(8, math.ceil(math.pi / math.acos(1.0 - eps)))


def _frame(normal):
    n = np.asarray(normal, float)
    length = np.linalg.norm(n)
    if not length > 0:
        raise BadInputError("axis or normal must not be the zero vector")
    n = n / length
    a = np.eye(3)[np.argmin(np.abs(n))]
    e1 = np.cross(n, a)
    e1 /= np.linalg.norm(e1)
    return n, e1, np.cross(n, e1)


def _areas(tris):
    return 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)


def annulus_triangles(centre, normal, inner, outer, *, tessellation_error=DEFAULT_TESSELLATION_ERROR):
    """Triangles of a flat ring (``inner`` = 0: a disc) facing ``normal``, area π(R² − r²).

    Examples
    --------
    >>> t = annulus_triangles([0, 0, 0], [0, 0, 1], 0.0, 1.0)
    >>> round(float(_areas(t).sum()) / math.pi, 12)
    1.0
    """
    if not 0 <= inner < outer:
        raise BadInputError(f"ring radii must satisfy 0 ≤ inner < outer, got {inner:g}, {outer:g}")
    n, e1, e2 = _frame(normal)
    k = segments_for(tessellation_error)
    scale = math.sqrt(2 * math.pi / (k * math.sin(2 * math.pi / k)))  # equal-area n-gon
    phi = 2 * math.pi * np.arange(k + 1) / k
    ring = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
    c = np.asarray(centre, float)
    out = c + outer * scale * ring
    if inner == 0:
        tris = np.stack([np.broadcast_to(c, out[:-1].shape), out[:-1], out[1:]], axis=1)
    else:
        inn = c + inner * scale * ring
        tris = np.concatenate([np.stack([inn[:-1], out[:-1], out[1:]], axis=1),
                               np.stack([inn[:-1], out[1:], inn[1:]], axis=1)])
    return tris


def cone_triangles(start, end, r0, r1, *, inward=False, tessellation_error=DEFAULT_TESSELLATION_ERROR):
    """Triangles of the open lateral surface of a cone frustum (a cylinder when r0 = r1).

    The axis runs from ``start`` (radius ``r0``) to ``end`` (radius ``r1``) [m]; fronts face
    outwards (Radiance ``cone``, ``cylinder``) or inwards (``cup``, ``tube``). The lateral area
    equals π (r0 + r1) √(h² + (r1 − r0)²).

    Examples
    --------
    >>> t = cone_triangles([0, 0, 0], [0, 0, 2], 1.0, 1.0)
    >>> round(float(_areas(t).sum()) / (4 * math.pi), 12)
    1.0
    """
    p0, p1 = np.asarray(start, float), np.asarray(end, float)
    height = float(np.linalg.norm(p1 - p0))
    if not height > 0 or r0 < 0 or r1 < 0 or r0 + r1 <= 0:
        raise BadInputError("cone needs distinct end points and radii ≥ 0, not both 0")
    axis, e1, e2 = _frame(p1 - p0)
    k = segments_for(tessellation_error)
    phi = 2 * math.pi * np.arange(k + 1) / k
    ring = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
    exact = math.pi * (r0 + r1) * math.hypot(height, r1 - r0)

    def build(scale):
        a, b = p0 + r0 * scale * ring, p1 + r1 * scale * ring
        parts = []
        if r0 > 0:
            parts.append(np.stack([a[:-1], a[1:], b[1:]], axis=1))
        if r1 > 0:
            parts.append(np.stack([a[:-1], b[1:], b[:-1]], axis=1))
        return np.concatenate(parts)

    scale = 1.0
    for _ in range(30):  # the area is nearly proportional to the scale: a fixed point
        scale *= exact / _areas(build(scale)).sum()
    tris = build(scale)
    return tris[:, ::-1] if inward else tris


def sphere_triangles(centre, radius, *, inward=False, tessellation_error=DEFAULT_TESSELLATION_ERROR):
    """Triangles of a sphere (latitude–longitude grid), area 4πr², fronts out (or in).

    Examples
    --------
    >>> t = sphere_triangles([0, 0, 0], 2.0)
    >>> round(float(_areas(t).sum()) / (16 * math.pi), 12)
    1.0
    """
    if not radius > 0:
        raise BadInputError(f"sphere radius must be positive, got {radius:g}")
    k = segments_for(tessellation_error)
    rows = max(4, math.ceil(k / 2))
    theta = math.pi * np.arange(rows + 1) / rows
    phi = 2 * math.pi * np.arange(k + 1) / k
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    grid = np.stack([st * np.cos(phi), st * np.sin(phi), np.broadcast_to(ct, (rows + 1, k + 1))], axis=-1)
    a, b = grid[:-1, :-1], grid[:-1, 1:]
    c, d = grid[1:, :-1], grid[1:, 1:]
    # rows run from the north pole down: (a, c, d) and (a, d, b) face outwards; the second
    # is degenerate in the first row (a = b = pole), the first in the last row (c = d)
    unit = np.concatenate([np.stack([a, c, d], axis=2)[:-1].reshape(-1, 3, 3),
                           np.stack([a, d, b], axis=2)[1:].reshape(-1, 3, 3)])
    scale = math.sqrt(4 * math.pi / _areas(unit).sum())
    tris = np.asarray(centre, float) + radius * scale * unit
    return tris[:, ::-1] if inward else tris
