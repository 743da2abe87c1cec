"""Solid angles of spherical polygons given by their corner directions.

References
----------
A. Van Oosterom & J. Strackee, "The solid angle of a plane triangle", IEEE Trans. Biomed.
Eng. BME-30(2), 1983, 125–126: for unit vectors a, b, c the triangle they span on the unit
sphere has ``tan(Ω/2) = |a·(b×c)| / (1 + a·b + b·c + c·a)``. Unlike the spherical-excess
form with arccos of near-1 dot products (FORMULAS.md §2.4.2, evalglare's pict_get_sangle), it
keeps full relative precision for triangles of 1e-12 sr and below.
"""

import numpy as np

__all__ = ["corner_solid_angles", "quad_solid_angle", "triangle_solid_angle"]


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
