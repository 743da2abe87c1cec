"""Solid angles of spherical polygons given by their corner directions.

References
----------
A. Van Oosterom & J. Strackee, "The solid angle of a plane triangle", IEEE Trans. Biomed.
Eng. BME-30(2), 1983, 125–126: for unit vectors a, b, c the triangle they span on the unit
sphere has ``tan(Ω/2) = |a·(b×c)| / (1 + a·b + b·c + c·a)``. Unlike the spherical-excess
form with arccos of near-1 dot products (FORMULAS.md §2.4.2, evalglare's pict_get_sangle), it
keeps full relative precision for triangles of 1e-12 sr and below.
"""

import math

import numpy as np

__all__ = ["corner_solid_angles", "quad_solid_angle", "quad_solid_angle_components", "triangle_solid_angle"]


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def triangle_solid_angle(a, b, c):
    """Solid angle [sr] of the spherical triangles with corner directions ``a, b, c`` (…, 3).

    Corner vectors need not be unit length (they are normalised). The result is non-negative
    and lies in [0, 2π) (Van Oosterom & Strackee 1983); ``arctan2`` makes triangles larger
    than a hemisphere's half come out right as long as the triangle is smaller than 2π sr.
    """
    a, b, c = _unit(a), _unit(b), _unit(c)
    numerator = np.abs(np.einsum("...i,...i->...", a, np.cross(b, c)))
    denominator = (
        1.0
        + np.einsum("...i,...i->...", a, b)
        + np.einsum("...i,...i->...", b, c)
        + np.einsum("...i,...i->...", c, a)
    )
    return 2.0 * np.arctan2(numerator, denominator)


def quad_solid_angle(d00, d01, d11, d10):
    """Solid angle [sr] of spherical quadrilaterals from their four corner directions.

    The corners are given in order around the quadrilateral (e.g. a pixel's corners
    top-left, top-right, bottom-right, bottom-left), each an array ``(…, 3)``; the edges are
    great-circle arcs. The quadrilateral is split along the diagonal ``d00–d11`` into two
    triangles, each measured with the Van Oosterom–Strackee formula
    ``tan(Ω/2) = |a·(b×c)| / (1 + a·b + b·c + c·a)`` (A. Van Oosterom & J. Strackee, IEEE
    Trans. Biomed. Eng. BME-30(2), 1983, 125–126). Exact for convex quadrilaterals (all
    pixel footprints of the projections in this package), vectorised, float64.

    Examples
    --------
    >>> x, y, z = np.eye(3)
    >>> round(float(quad_solid_angle(x, y, z, z)), 12) == round(np.pi / 2, 12)
    True
    """
    return triangle_solid_angle(d00, d01, d11) + triangle_solid_angle(d00, d11, d10)


def corner_solid_angles(directions, rows, cols):
    """Solid angle [sr] of pixels ``(rows, cols)`` from the directions of their four corners.

    ``directions(rows, cols)`` maps image points [px] to direction vectors ``(…, 3)`` (a
    projection's :meth:`directions`); corners lie at ±½ px. A pixel with a corner where it
    is NaN (outside the model's one-to-one region) gets 0.
    """
    rows, cols = np.broadcast_arrays(np.asarray(rows, float), np.asarray(cols, float))
    corners = [directions(rows + dr, cols + dc) for dr, dc in ((-0.5, -0.5), (-0.5, 0.5), (0.5, 0.5), (0.5, -0.5))]
    bad = np.zeros(rows.shape, bool)
    for d in corners:
        bad |= np.any(~np.isfinite(d), axis=-1)
    fill = np.array([0.0, 0.0, 1.0])
    corners = [np.where(bad[..., None], fill, d) for d in corners]
    with np.errstate(invalid="ignore", divide="ignore"):
        omega = quad_solid_angle(*corners)
    return np.where(bad, 0.0, omega)


#: Below this tan(Ω/2) the arc tangent is replaced by its 3-term series (error < t⁶/7).
_SERIES_LIMIT = 1e-3


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _triple(a, p, q):
    """a·(p×q) from component tuples."""
    return (a[0] * (p[1] * q[2] - p[2] * q[1]) + a[1] * (p[2] * q[0] - p[0] * q[2])
            + a[2] * (p[0] * q[1] - p[1] * q[0]))


def quad_solid_angle_components(d00, d01, d11, d10):
    """Solid angle [sr] of geodesic quadrilaterals from unit corner directions.

    Each corner is a tuple of three arrays ``(dx, dy, dz)`` (broadcastable), the corners in
    order around the quadrilateral. The quad is split along ``d00–d11`` into two triangles,
    each with ``tan(Ω/2) = |a·(b×c)| / (1 + a·b + b·c + c·a)`` (Van Oosterom & Strackee
    1983), the triple product evaluated as a·((b − a)×(c − a)) so that small quads keep
    full relative precision (relative ≈ eps/edge length, set by how precisely the unit
    corner vectors themselves are stored); the half-angles are summed as ``arctan2(n₁d₂ + n₂d₁, d₁d₂ − n₁n₂)``, and where
    that tangent is below 10⁻³ the arc tangent is its series to t⁵. Valid for quads smaller
    than 2π sr (any pixel). The corners must be unit vectors (they are not normalised);
    NaN corners give NaN.

    Parameters
    ----------
    d00, d01, d11, d10 : tuple of 3 array_like
        Corner direction components, in order around the quadrilateral.

    Returns
    -------
    numpy.ndarray
        Solid angle [sr], float64.

    References
    ----------
    A. Van Oosterom & J. Strackee, IEEE Trans. Biomed. Eng. BME-30(2), 1983, 125–126.

    Examples
    --------
    >>> x, y, z = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    >>> round(float(quad_solid_angle_components(x, y, z, z)) / np.pi, 12)  # an octant
    0.5
    """
    a, b, c, e = d00, d01, d11, d10
    ac = _dot(a, c)
    # a·(b×c) = a·((b − a)×(c − a)): the cross product of the short edge vectors keeps full
    # relative precision, where b×c of two nearly parallel unit vectors would leave an
    # absolute error of ~eps (relative eps/Ω: 1e-7 for a 1e-9 sr quad).
    p, q, r = _sub(b, a), _sub(c, a), _sub(e, a)
    n1 = np.abs(_triple(a, p, q))
    d1 = 1.0 + _dot(a, b) + _dot(b, c) + ac
    n2 = np.abs(_triple(a, q, r))
    d2 = 1.0 + ac + _dot(c, e) + _dot(e, a)
    num = n1 * d2 + n2 * d1
    den = d1 * d2 - n1 * n2
    with np.errstate(divide="ignore", invalid="ignore"):
        t = num / den
        small = (den > 0) & (t < _SERIES_LIMIT)
        t2 = t * t
        series = 2.0 * t * (1.0 - t2 * (1.0 / 3.0 - t2 * 0.2))
        if np.all(small):
            return series
        half = np.arctan2(num, den)
        half = np.where(half < 0, half + 2.0 * math.pi, half)
        return np.where(small, series, 2.0 * half)
