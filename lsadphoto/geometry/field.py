"""Per-pixel geometry of a whole image, computed once and cached.

:func:`pixel_geometry` gives the direction, solid angle and validity of every pixel of a
projection; :func:`visual_field` adds the observer's visual angles σ, τ, the position index
and cos σ for a given :class:`~lsadphoto.geometry.observer.ObserverFrame`. Both keep the last
few results (least recently used first out), keyed by the projection's :meth:`to_dict` (as
JSON), so that every metric evaluated on images of one camera shares one set of maps.
Returned arrays are read-only.

How the maps are computed (FORMULAS.md §2.4.2):

* The directions of the ``(rows + 1) × (cols + 1)`` pixel *corners* are evaluated once and
  shared by the four pixels that meet at each corner, instead of four evaluations per pixel.
* Each pixel's solid angle is the geodesic quadrilateral of its corner directions, split
  along a diagonal into two triangles measured with the Van Oosterom–Strackee formula
  ``tan(Ω/2) = |a·(b×c)| / (1 + a·b + b·c + c·a)``; the two half-angles are added inside a
  single ``arctan2``; the triple products are taken of the edge vectors (b − a, c − a),
  which keeps full relative precision for tiny pixels; and, for the small pixels of real images (tan(Ω/2) < 10⁻³), the arc
  tangent is its series ``t − t³/3 + t⁵/5`` (relative error < t⁶/7 < 2·10⁻¹⁹).
* The image is processed in blocks of rows small enough to stay in the processor cache, on
  as many threads as there are CPUs (numpy releases the GIL inside its loops).

References
----------
A. Van Oosterom & J. Strackee, "The solid angle of a plane triangle", IEEE Trans. Biomed.
Eng. BME-30(2), 1983, 125–126. Radiance ``src/util/pictool.c`` (pict_get_sangle: pixel solid
angle from the four corner directions). FORMULAS.md "Notation", §2.1–2.4.
"""

import json
import math
import os
import threading
from collections import OrderedDict
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .._validation import check_choice
from ..errors import BadInputError

__all__ = [
    "PixelGeometry",
    "VisualField",
    "clear_geometry_cache",
    "pixel_geometry",
    "quad_solid_angle_components",
    "visual_field",
]

#: Entries kept by each cache (a 24-megapixel map set is about 0.8 GB).
CACHE_SIZE = 4
#: Pixels per block of work: 192 kB per float64 temporary, so a block's working set stays
#: in the L2 cache (measured best of 2¹²…2¹⁷ on the 2-core test machine).
_BLOCK_PIXELS = 24_000
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


# --- caches ---------------------------------------------------------------------------------


class _LRU:
    def __init__(self, size):
        self.size = size
        self.data = OrderedDict()
        self.lock = threading.Lock()

    def get(self, key):
        with self.lock:
            if key in self.data:
                self.data.move_to_end(key)
                return self.data[key]
        return None

    def put(self, key, value):
        with self.lock:
            self.data[key] = value
            self.data.move_to_end(key)
            while len(self.data) > self.size:
                self.data.popitem(last=False)

    def clear(self):
        with self.lock:
            self.data.clear()


_GEOMETRY_CACHE = _LRU(CACHE_SIZE)
_FIELD_CACHE = _LRU(CACHE_SIZE)


def clear_geometry_cache():
    """Empty the caches of :func:`pixel_geometry` and :func:`visual_field`."""
    _GEOMETRY_CACHE.clear()
    _FIELD_CACHE.clear()


def _projection_key(projection):
    if not hasattr(projection, "to_dict") or not hasattr(projection, "shape"):
        raise BadInputError(
            f"projection must be a lsadphoto.geometry.Projection, got {type(projection).__name__}"
        )
    return json.dumps(projection.to_dict(), sort_keys=True)


def _blocks(rows, cols):
    step = max(1, _BLOCK_PIXELS // max(cols, 1))
    return [(r0, min(r0 + step, rows)) for r0 in range(0, rows, step)]


def _run(task, blocks):
    workers = min(os.cpu_count() or 1, len(blocks))
    if workers <= 1:
        for block in blocks:
            task(*block)
        return
    with ThreadPoolExecutor(max_workers=workers) as pool:
        for future in [pool.submit(task, *block) for block in blocks]:
            future.result()


def _read_only(array):
    array.flags.writeable = False
    return array


# --- pixel geometry -------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class PixelGeometry:
    """Direction, solid angle and validity of every pixel of an image.

    Compared by identity (the cache hands out one object per model and image size).

    Attributes
    ----------
    directions : numpy.ndarray, shape (rows, cols, 3)
        Unit direction of each pixel centre in the camera frame (x right, y down, z along
        the optical axis), float64; NaN where invalid. Read-only.
    solid_angle : numpy.ndarray, shape (rows, cols)
        Pixel solid angle [sr], float64; 0 where invalid. Read-only.
    valid : numpy.ndarray, shape (rows, cols)
        True where the pixel has a direction and a positive solid angle. Read-only.
    """

    directions: np.ndarray
    solid_angle: np.ndarray
    valid: np.ndarray


def _opencv_fisheye_grid(cam):
    """Fast direction grid for :class:`OpenCVFisheyeProjection` (Kannala–Brandt).

    θ(ρ) is inverted from a table of θd(θ) (linear interpolation on a uniform grid of 4096
    steps of ρ, error ≈ Δρ²/8·|θ″| ≲ 10⁻⁷ rad) followed by two Newton steps, which converge
    quadratically to rounding (10⁻⁷ → 10⁻¹⁴ → 10⁻²⁸) except close to the fold of the
    mapping (dθd/dθ → 0), where the few points still above a residual of 10⁻¹³ are finished by the model's own
    safeguarded solver (:meth:`theta`). :meth:`directions` runs that solver from θ = ρ
    over whole arrays, to a residual below 10⁻¹², about 20 times slower. Directions beyond
    ``theta_max`` are NaN, as there.
    """
    k1, k2, k3, k4 = cam.distortion
    theta_max = float(cam.theta_max)

    def theta_d(t):
        t2 = t * t
        return t * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))

    def dtheta_d(t):
        t2 = t * t
        return 1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)))

    rho_max = float(theta_d(theta_max))
    n = 4096
    theta_table = np.linspace(0.0, theta_max, 8 * n + 1)
    rho_grid = np.linspace(0.0, rho_max, n + 1)
    table = np.interp(rho_grid, theta_d(theta_table), theta_table)
    step = rho_max / n

    def grid(rows, cols, *, corners=False):
        with np.errstate(divide="ignore", invalid="ignore"):  # beyond the fold: NaN, no warning
            return _grid(rows, cols)

    def _grid(rows, cols):
        rows = np.asarray(rows, float)[:, None]
        cols = np.asarray(cols, float)[None, :]
        xd = np.broadcast_to((cols - cam.cx) / cam.fx, (rows.shape[0], cols.shape[1]))
        yd = np.broadcast_to((rows - cam.cy) / cam.fy, xd.shape)
        rho = np.sqrt(xd * xd + yd * yd)
        ok = rho < rho_max
        u = np.minimum(rho, rho_max) / step
        i = np.minimum(u.astype(np.intp), n - 1)
        f = u - i
        theta = table[i] * (1.0 - f) + table[i + 1] * f
        for _ in range(2):
            theta = np.clip(theta - (theta_d(theta) - rho) / dtheta_d(theta), 0.0, theta_max)
        # Near the fold (dθd/dθ → 0) Newton converges slowly: finish the few points whose
        # residual is not yet at the model's own tolerance with its safeguarded solver.
        slow = ok & ~(np.abs(theta_d(theta) - rho) < 1e-13)
        if slow.any():
            theta[slow] = cam.theta(rho[slow])
        half = np.tan(0.5 * theta)
        h2 = half * half
        s = 2.0 * half / (1.0 + h2)
        c = (1.0 - h2) / (1.0 + h2)
        q = np.divide(s, rho, out=np.ones_like(rho), where=rho > 0)
        nan = np.where(ok, 1.0, np.nan)
        return q * xd * nan, q * yd * nan, c * nan

    return grid


def _grid_function(projection):
    from .opencv import OpenCVFisheyeProjection

    if type(projection) is OpenCVFisheyeProjection:
        return _opencv_fisheye_grid(projection)
    return projection._grid_direction_components


def _compute_pixel_geometry(projection):
    rows, cols = projection.shape
    directions = np.empty((rows, cols, 3))
    solid_angle = np.empty((rows, cols))
    valid = np.empty((rows, cols), dtype=bool)
    centre_cols = np.arange(cols, dtype=float)
    corner_cols = np.arange(cols + 1, dtype=float) - 0.5
    grid = _grid_function(projection)

    def task(r0, r1):
        corner_rows = np.arange(r0, r1 + 1, dtype=float) - 0.5
        g = grid(corner_rows, corner_cols, corners=True)
        g = tuple(np.ascontiguousarray(v) for v in g)
        with np.errstate(invalid="ignore"):
            omega = quad_solid_angle_components(
                tuple(v[:-1, :-1] for v in g), tuple(v[:-1, 1:] for v in g),
                tuple(v[1:, 1:] for v in g), tuple(v[1:, :-1] for v in g),
            )
            d = grid(np.arange(r0, r1, dtype=float), centre_cols)
            ok = np.isfinite(omega) & (omega > 0)
            for component in d:
                ok &= np.isfinite(component)
        block = directions[r0:r1]
        for k in range(3):
            block[..., k] = d[k]
        solid_angle[r0:r1] = omega
        valid[r0:r1] = ok
        if not ok.all():
            bad = ~ok
            block[bad] = np.nan
            solid_angle[r0:r1][bad] = 0.0

    _run(task, _blocks(rows, cols))
    return PixelGeometry(_read_only(directions), _read_only(solid_angle), _read_only(valid))


def pixel_geometry(projection):
    """Directions, solid angles and validity of all pixels of ``projection`` (cached).

    The first call for a camera model and image size computes the maps (2–4 s of CPU time for
    24 megapixels on the 2-core test machine; see docs/performance.md); later calls
    with an equal projection (same :meth:`to_dict`) return the same object.

    Parameters
    ----------
    projection : Projection
        Any camera model of :mod:`lsadphoto.geometry`.

    Returns
    -------
    PixelGeometry
        Read-only maps; ``directions`` equal ``projection.directions`` at the pixel centres
        and ``solid_angle`` the geodesic quad of the corner directions (for the ideal
        fisheye bit for bit ``projection.solid_angles``; for the other models equal to it
        to rounding, relative 10⁻¹²). A pixel is valid where its centre direction and all
        four corner directions exist and its solid angle is positive.

    References
    ----------
    FORMULAS.md §2.4.2; Radiance ``src/util/pictool.c`` (pict_get_sangle).

    Examples
    --------
    >>> from lsadphoto.geometry import IdealFisheyeProjection
    >>> cam = IdealFisheyeProjection("equidistant", 49.5, 49.5, 50.0, 180.0, 100, 100)
    >>> geometry = pixel_geometry(cam)
    >>> geometry is pixel_geometry(cam), geometry.solid_angle.flags.writeable
    (True, False)
    >>> round(float(geometry.solid_angle.sum()) / (2 * np.pi), 2)  # the hemisphere
    1.0
    """
    key = _projection_key(projection)
    cached = _GEOMETRY_CACHE.get(key)
    if cached is None:
        cached = _compute_pixel_geometry(projection)
        _GEOMETRY_CACHE.put(key, cached)
    return cached


# --- visual field ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class VisualField:
    """The observer's visual angles and position index of every pixel.

    Attributes
    ----------
    sigma : numpy.ndarray, shape (rows, cols)
        Angle σ between the pixel direction and the line of sight [rad], 0…π; NaN where
        invalid. Read-only.
    tau : numpy.ndarray, shape (rows, cols)
        Angle τ around the line of sight from the upward half-plane [rad], 0…π (0 above,
        π/2 to the side, π below; 0 on the line of sight); NaN where invalid. Read-only.
    position_index : numpy.ndarray, shape (rows, cols)
        Position index P [–] of the chosen method; NaN where invalid. Read-only.
    cos_sigma : numpy.ndarray, shape (rows, cols)
        d̂·v̂ [–] (the cosine factor of vertical illuminance; negative behind the observer);
        0 where invalid, so that sums over the image need no mask. Read-only.
    """

    sigma: np.ndarray
    tau: np.ndarray
    position_index: np.ndarray
    cos_sigma: np.ndarray


def _compute_visual_field(geometry, axes, method):
    from .position_index import position_index_from_components

    v, u, h = axes
    rows, cols = geometry.valid.shape
    out = {name: np.empty((rows, cols)) for name in ("sigma", "tau", "position_index", "cos_sigma")}
    d = geometry.directions

    def task(r0, r1):
        block = d[r0:r1]
        dx, dy, dz = block[..., 0], block[..., 1], block[..., 2]
        forward = dx * v[0] + dy * v[1] + dz * v[2]
        up = dx * u[0] + dy * u[1] + dz * u[2]
        side = dx * h[0] + dy * h[1] + dz * h[2]
        sigma, tau = _angles(forward, up, side)
        out["sigma"][r0:r1] = sigma
        out["tau"][r0:r1] = tau
        out["position_index"][r0:r1] = position_index_from_components(
            forward, up, side, sigma, tau, method=method)
        out["cos_sigma"][r0:r1] = np.where(geometry.valid[r0:r1], forward, 0.0)

    _run(task, _blocks(rows, cols))
    return VisualField(**{name: _read_only(array) for name, array in out.items()})


def _angles(forward, up, side):
    """σ and τ [rad] from the components of unit directions along v̂, û and ĥ."""
    lateral = np.sqrt(up * up + side * side)
    sigma = np.arctan2(lateral, forward)
    tau = np.arctan2(np.abs(side), up)
    # On the line of sight τ is undefined; rounding in the components would give any value.
    # Fix it at 0 where the lateral component is at rounding level (σ < 1e-15 rad).
    return sigma, np.where(lateral < 1e-15, 0.0 * tau, tau)


def visual_field(projection, frame, *, position_index_method="evalglare"):
    """σ, τ, position index and cos σ of every pixel, for an observer frame (cached).

    Parameters
    ----------
    projection : Projection
        Camera model; its :func:`pixel_geometry` supplies the directions.
    frame : ObserverFrame
        Line of sight and up vector in the camera frame.
    position_index_method : {"evalglare", "Guth", "Kim2011"}
        See :func:`~lsadphoto.geometry.position_index.position_index`.

    Returns
    -------
    VisualField
        Read-only maps, the same object for a repeated call with an equal projection, frame
        axes and method.

    References
    ----------
    FORMULAS.md "Notation" and §2.1–2.3; Radiance ``src/util/evalglare.c`` (get_posindex).

    Examples
    --------
    >>> from lsadphoto.geometry import IdealFisheyeProjection, ObserverFrame
    >>> cam = IdealFisheyeProjection("equidistant", 49.5, 49.5, 50.0, 180.0, 100, 100)
    >>> field = visual_field(cam, ObserverFrame())
    >>> round(float(np.nanmax(field.sigma)), 2), float(np.nanmax(field.position_index))
    (1.57, 16.0)
    """
    from .observer import ObserverFrame
    from .position_index import METHODS

    if not isinstance(frame, ObserverFrame):
        raise BadInputError(f"frame must be an ObserverFrame, got {type(frame).__name__}")
    check_choice(position_index_method, "position index method", METHODS)
    axes = frame.axes()
    key = json.dumps([_projection_key(projection), [a.tolist() for a in axes], position_index_method])
    cached = _FIELD_CACHE.get(key)
    if cached is None:
        cached = _compute_visual_field(pixel_geometry(projection), axes, position_index_method)
        _FIELD_CACHE.put(key, cached)
    return cached
