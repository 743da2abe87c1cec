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
* For the fisheye models (:class:`IdealFisheyeProjection`, :class:`OpenCVFisheyeProjection`)
  the solid angle and validity are computed per pixel in one compiled pass (:mod:`._kernels`,
  numba, rows on all CPUs), and cos σ and the position index in a second one (σ and τ in
  the same kernel, only when they are read: the metrics do not need them), each over the
  part of every row that can hold valid pixels (the rest is set invalid directly); IEEE
  float64, no fast-math. Above 2²⁰ pixels no direction map is stored: the second pass, Q,
  the grouping and the sources compute the directions they need from the model's
  parameters with the same per-pixel function (``_kernels._centre_row``;
  :meth:`PixelGeometry.directions_at`), and ``directions`` makes the whole map only when it
  is read. There, :func:`visual_field` called before the geometry is cached (as
  :func:`~lsadphoto.metrics.score.score_map` does) computes both in one pass, each centre
  direction once. The ideal fisheye's maps equal its methods bit for bit, except the
  equidistant kind's, within a few ulp (its tan(θ/2) is a branch-free Cephes tan within 2
  ulp of the C library's, which runs on SIMD lanes). Other models evaluate
  their own (numpy) ``directions`` in blocks of rows on threads, with the compiled
  solid-angle kernel.
* The kernels are compiled on first use and cached on disk (numba ``cache=True``): the
  first call in a fresh installation takes some seconds more (see docs/performance.md).

References
----------
A. Van Oosterom & J. Strackee, "The solid angle of a plane triangle", IEEE Trans. Biomed.
Eng. BME-30(2), 1983, 125–126. Radiance ``src/util/pictool.c`` (pict_get_sangle: pixel solid
angle from the four corner directions). FORMULAS.md "Notation", §2.1–2.4.
"""

import json
import math
import threading
from collections import OrderedDict

import numpy as np

from .._compiled import populate, row_blocks, run_blocks
from .._validation import check_choice
from ..errors import BadInputError
from ._spherical import quad_solid_angle_components

__all__ = [
    "PixelGeometry",
    "VisualField",
    "clear_geometry_cache",
    "direction_map",
    "directions_at",
    "directions_of_runs",
    "pixel_geometry",
    "quad_solid_angle_components",
    "visual_field",
]

#: Entries kept by each cache (a 24-megapixel map set is about 0.8 GB).
CACHE_SIZE = 4
#: Pixels per block of work: 192 kB per float64 temporary, so a block's working set stays
#: in the L2 cache (measured best of 2¹²…2¹⁷ on the 2-core test machine).
_BLOCK_PIXELS = 24_000
#: The fisheye models store their direction map with the geometry up to this many pixels:
#: Q evaluates every pixel of such a picture (it screens only larger ones, quality.py), so its
#: stencils would make the map anyway, and the visual field reads it instead of computing the
#: directions again. Larger pictures store none (24 bytes per pixel of fresh memory).
DIRECTION_MAP_MAX_PIXELS = 1 << 20
#: Pixels per band of rows of the compiled fisheye kernel (bands are shared out among the
#: threads; each recomputes the row of corners above it: 21-row bands at 6000 columns,
#: 5 % more corner directions).
_KERNEL_BLOCK_PIXELS = 1 << 17
#: Blocks of rows per thread of the compiled fisheye kernel (handed out as threads come
#: free): with one block per thread, one thread worked half as long again as the other
#: (a circle's rows hold more pixels the nearer its centre; 24 MP, session 15).
_BLOCKS_PER_THREAD = 4
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


def _read_only(array):
    array.flags.writeable = False
    return array


# --- pixel geometry -------------------------------------------------------------------------


class PixelGeometry:
    """Direction, solid angle and validity of every pixel of an image.

    Compared by identity (the cache hands out one object per model and image size).

    For the fisheye models with a compiled kernel (the ideal fisheye, the OpenCV fisheye)
    pictures of more than :data:`DIRECTION_MAP_MAX_PIXELS` have no stored direction map: the
    metrics compute the directions they need from the model's parameters
    (:meth:`directions_at`, :meth:`stencil_directions`, and inside the visual-field kernel),
    which spares a score 24 bytes per pixel of fresh memory (docs/performance.md);
    :attr:`directions` computes the whole map on first access (the same values bit for bit).

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

    def __init__(self, directions, solid_angle, valid, model=None):
        self._directions = directions
        self.solid_angle = solid_angle
        self.valid = valid
        #: (model code, parameters, table) of :func:`._kernels.fisheye_directions`, or None
        #: where the directions are a stored map.
        self.model = model
        self._lock = threading.Lock()

    @property
    def directions(self):
        with self._lock:
            if self._directions is None:
                rows, cols = self.valid.shape
                r = np.arange(rows, dtype=np.int64)
                d = self._segments(r, np.zeros(rows, np.int64), np.full(rows, cols, np.int64))
                self._directions = _read_only(d.reshape(rows, cols, 3))
        return self._directions

    def _segments(self, rows, cols, lengths):
        """Directions of the row segments (rows[k], cols[k] + j), j < lengths[k], one after
        the other, computed from the model."""
        from . import _kernels

        starts = np.zeros(rows.size, dtype=np.int64)
        np.cumsum(lengths[:-1], out=starts[1:])
        out = np.empty((int(lengths.sum()), 3))
        _kernels.fisheye_directions(*self.model, self.valid, rows, cols, lengths, starts, out)
        return out

    def directions_at(self, rows, cols):
        """Directions of the pixels (``rows``, ``cols``) (integer arrays of one shape, inside
        the image), shape ``rows.shape + (3,)``: NaN where invalid; equal to
        ``directions[rows, cols]`` and computed from the model without the map where the
        geometry has a model and the map was not made."""
        rows = np.asarray(rows, dtype=np.int64)
        cols = np.asarray(cols, dtype=np.int64)
        if self.model is None or self._directions is not None:
            return np.asarray(self.directions)[rows, cols]
        shape = rows.shape
        rows, cols = rows.reshape(-1), cols.reshape(-1)
        if rows.size == 0:
            return np.empty(shape + (3,))
        # Pixels that follow each other along a row form one segment (row-major input, as
        # np.nonzero gives, is computed in runs).
        starts = np.flatnonzero(np.r_[True, (rows[1:] != rows[:-1]) | (cols[1:] != cols[:-1] + 1)])
        lengths = np.diff(np.r_[starts, rows.size])
        d = self._segments(rows[starts], cols[starts], lengths)
        return d.reshape(shape + (3,))

    def directions_of_runs(self, rows, cols, lengths):
        """Directions of the row segments (``rows[k]``, ``cols[k]`` + j), j < ``lengths[k]``
        (inside the image), one after the other, shape (Σ lengths, 3): equal to
        :meth:`directions_at` of their pixels, without arrays of the pixels' coordinates
        where the directions come from the model."""
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        cols = np.asarray(cols, dtype=np.int64).reshape(-1)
        lengths = np.asarray(lengths, dtype=np.int64).reshape(-1)
        if rows.size == 0:
            return np.empty((0, 3))
        if self.model is None or self._directions is not None:
            return directions_of_runs(np.asarray(self.directions), rows, cols, lengths)
        return self._segments(rows, cols, lengths)

    def stencil_directions(self, index):
        """Directions around the flat pixels ``index`` (each with its four neighbours in the
        image) for central differences: ``(d, i, step)`` with ``d`` flat (n, 3) such that
        d[i ∓ 1] are the directions left and right of each pixel and d[i ∓ step] above and
        below. The whole map (``i = index``, ``step`` = columns) where it exists or where the
        stencils would cover more pixels than the image has (every pixel of a small image is
        a stencil's centre); else each stencil's five pixels from the model (up, left,
        centre, right, down: ``i = 5k + 2``, ``step`` = 2)."""
        index = np.asarray(index, dtype=np.int64)
        rows, cols = self.valid.shape
        if self.model is None or self._directions is not None or 5 * index.size >= rows * cols:
            return np.asarray(self.directions).reshape(-1, 3), index, cols
        r, c = np.divmod(index, cols)
        seg_rows = np.stack([r - 1, r, r + 1], axis=1).reshape(-1)
        seg_cols = np.stack([c, c - 1, c], axis=1).reshape(-1)
        lengths = np.tile(np.array([1, 3, 1], dtype=np.int64), index.size)
        d = self._segments(seg_rows, seg_cols, lengths)
        return d, 5 * np.arange(index.size, dtype=np.int64) + 2, 2


def _fisheye_kernel_parameters(projection):
    """Model code, parameters and table of :func:`._kernels.fisheye_geometry`, or None for a
    model without a compiled kernel."""
    from . import _kernels
    from .fisheye import IdealFisheyeProjection
    from .opencv import OpenCVFisheyeProjection

    if type(projection) is IdealFisheyeProjection:
        cam = projection
        tm, scale = cam.theta_max, 1.0 / cam.radius
        # The radial coefficient exactly as IdealFisheyeProjection._unclipped_components has it.
        coefficient = {"equidistant": tm * scale, "equisolid": math.sin(tm / 2.0) * scale,
                       "orthographic": math.sin(tm) * scale,
                       "stereographic": math.tan(tm / 2.0) * scale}[cam.kind]
        p = [cam.cx, cam.cy, _kernels.FISHEYE_KINDS.index(cam.kind), coefficient,
             cam.radius * (1.0 + 1e-12)]
        return _kernels.IDEAL_FISHEYE, np.array(p, dtype=np.float64), np.zeros(2)
    if type(projection) is OpenCVFisheyeProjection:
        table, step = _kannala_brandt_table(projection)
        cam = projection
        p = [cam.cx, cam.cy, cam.fx, cam.fy, *cam.distortion, float(cam.theta_max),
             _kannala_brandt_rho_max(cam), step]
        return _kernels.OPENCV_FISHEYE, np.array(p, dtype=np.float64), table
    return None


def _kannala_brandt_rho_max(cam):
    k1, k2, k3, k4 = cam.distortion
    t = float(cam.theta_max)
    t2 = t * t
    return float(t * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))))


def _kannala_brandt_table(cam, n=1 << 16):
    """θ on a uniform grid of n + 1 values of ρ = θd(θ) from 0 to ρmax, and the grid step.

    The kernel interpolates it linearly (error ≈ Δρ²/8·|θ″|: ≤ 2·10⁻¹⁰ rad up to 0.9 ρmax on
    the benchmark camera, growing towards the fold of the mapping, where |θ″| → ∞) and takes
    one Newton step, which converges quadratically to rounding (10⁻¹⁰ → 10⁻²⁰) except close
    to the fold (dθd/dθ → 0), where the points still at a residual of 10⁻¹³ or more (about
    0.1 % of a 24-megapixel image) are finished by the model's own safeguarded solver
    (:meth:`OpenCVFisheyeProjection.theta`, ported point by point). The 2¹⁶ intervals (a
    0.5 MB table, 8 ms to build) make the one Newton step enough, where 2¹² would need two:
    the step saves more than the larger table costs (measured). For comparison,
    :meth:`~OpenCVFisheyeProjection.directions` runs that solver from θ = ρ for every point,
    to a residual below 10⁻¹².
    """
    k1, k2, k3, k4 = cam.distortion
    theta_max = float(cam.theta_max)
    theta = np.linspace(0.0, theta_max, 8 * n + 1)
    t2 = theta * theta
    rho = theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
    rho_max = _kannala_brandt_rho_max(cam)
    table = np.interp(np.linspace(0.0, rho_max, n + 1), rho, theta)
    return table, rho_max / n


def _mirror_rows(cy, rows):
    """(2·cy, [(0, m), (m, rows)]) where the image rows mirror about the row cy (2·cy a whole
    number, :func:`._kernels.fisheye_geometry`): rows 0 … m − 1 are computed and write their
    mirror images, rows m … rows − 1 that have none are computed on their own; else
    (−1, [(0, rows)])."""
    twice = 2.0 * float(cy)
    if not (twice == math.floor(twice) and 0.0 <= twice < 2.0 * rows):
        return -1, [(0, rows)]
    mirror = int(twice)
    m = mirror // 2 + 1  # the rows g ≤ cy
    return mirror, [(0, m), (min(mirror + 1, rows), rows)]


def _mirror_cols(cx):
    """2·cx where the image columns mirror about the column cx (2·cx a whole number:
    :func:`._kernels.fisheye_geometry` copies the directions right of cx from their mirror
    images), else −1."""
    twice = 2.0 * float(cx)
    return int(twice) if twice == math.floor(twice) and abs(twice) < 2.0 ** 52 else -1


def _allocate(name, shape, dtype):
    return np.empty(shape, dtype=dtype)


def _compute_pixel_geometry(projection, field=None, allocate=_allocate, stored=False):
    """The :class:`PixelGeometry` of ``projection``; with ``field`` = (axes, method), for a
    fisheye model, also the visual field's position index and cos σ from the same pass:
    (geometry, (P, cos σ)). The fisheye models' solid angle, validity, position index and
    cos σ maps are ``allocate(name, shape, dtype)`` (names of :data:`._map_cache.MAPS`);
    where ``stored``, they hold the maps already (read from the disk cache) and nothing
    is computed."""
    from . import _kernels

    rows, cols = projection.shape
    compiled = _fisheye_kernel_parameters(projection)
    if compiled is not None:
        model, p, table = compiled
        solid_angle = allocate("solid_angle", (rows, cols), np.float64)
        valid = allocate("valid", (rows, cols), np.bool_)
        band_rows = max(1, min(rows, _KERNEL_BLOCK_PIXELS // max(cols, 1)))
        store = rows * cols <= DIRECTION_MAP_MAX_PIXELS
        directions = np.empty((rows, cols, 3) if store else (1, 1, 3))
        field_args = _field_arguments(field, (rows, cols), allocate)
        position, cos_sigma = field_args[-2:]
        on = field is not None
        if stored:
            geometry = PixelGeometry(_read_only(directions) if store else None,
                                     _read_only(solid_angle), _read_only(valid),
                                     model=compiled)
            return geometry if field is None else (geometry, (_read_only(position),
                                                              _read_only(cos_sigma)))

        mirror, computed = _mirror_rows(p[1], rows)
        mirror_cols = _mirror_cols(p[0])

        def rows_of(array, r0, r1):  # the block's rows of a map (a placeholder as it is)
            return array[r0:r1] if array.shape[0] == rows else array

        def task(r0, r1, mirrored):
            spans = [(r0, r1)]
            if mirrored and mirror >= 0:  # the mirror images of rows r0 … r1 − 1
                spans.append((max(mirror - r1 + 1, r1), min(mirror - r0 + 1, rows)))
            for a, b in spans:
                if a < b:
                    populate(rows_of(directions, a, b), solid_angle[a:b], valid[a:b],
                             rows_of(position, a, b), rows_of(cos_sigma, a, b))
            _kernels.fisheye_geometry(model, p, table, band_rows, r0, r1,
                                      mirror if mirrored else -1, mirror_cols, store,
                                      directions, solid_angle, valid, on, *field_args)

        # Blocks of whole bands, a few per thread where the ahead-of-time code runs them (a
        # circle's rows hold more pixels the nearer its centre: threads that finish early
        # take the next block), the rows that mirror rows below them (with those), then
        # the rest.
        workers = _kernels.fisheye_geometry.threads_for(
            model, p, table, band_rows, 0, rows, mirror, mirror_cols, store, directions,
            solid_angle, valid, on, *field_args)
        parts = workers if workers == 1 else _BLOCKS_PER_THREAD * workers
        blocks = [(a + r0, a + r1, k == 0) for k, (a, b) in enumerate(computed)
                  for r0, r1 in row_blocks(b - a, parts, band_rows)]
        run_blocks(task, blocks, workers)
        geometry = PixelGeometry(_read_only(directions) if store else None,
                                 _read_only(solid_angle), _read_only(valid), model=compiled)
        if field is None:
            return geometry
        return geometry, tuple(_read_only(a) for a in field_args[-2:])

    # Other models: their own (numpy) directions on the corner and centre grids, in blocks on
    # threads; the solid-angle kernel releases the GIL.
    solid_angle = np.empty((rows, cols))
    valid = np.empty((rows, cols), dtype=bool)
    directions = np.empty((rows, cols, 3))
    centre_cols = np.arange(cols, dtype=float)
    corner_cols = np.arange(cols + 1, dtype=float) - 0.5
    grid = projection._grid_direction_components

    def task(r0, r1):
        corner_rows = np.arange(r0, r1 + 1, dtype=float) - 0.5
        g = tuple(np.ascontiguousarray(v) for v in grid(corner_rows, corner_cols, corners=True))
        omega = solid_angle[r0:r1]
        _kernels.quad_solid_angle_grid(*g, omega)
        d = grid(np.arange(r0, r1, dtype=float), centre_cols)
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(omega) & (omega > 0)
        for component in d:
            ok &= np.isfinite(component)
        block = directions[r0:r1]
        for k in range(3):
            block[..., k] = d[k]
        valid[r0:r1] = ok
        if not ok.all():
            bad = ~ok
            block[bad] = np.nan
            omega[bad] = 0.0

    run_blocks(task, _blocks(rows, cols))
    return PixelGeometry(_read_only(directions), _read_only(solid_angle), _read_only(valid))


def _field_constants(axes, method):
    """(v, u, h, method code, cap): the visual-field kernels' arguments for the frame
    ``axes`` and the position-index ``method``."""
    from . import _kernels
    from .position_index import POSITION_INDEX_CAP

    v, u, h = (np.ascontiguousarray(a, dtype=np.float64) for a in axes)
    return v, u, h, _kernels.POSITION_INDEX_METHODS.index(method), POSITION_INDEX_CAP


def _field_arguments(field, shape, allocate=_allocate):
    """:func:`_field_constants` of ``field`` = (axes, method) and the P and cos σ maps of
    ``shape`` from ``allocate``; placeholders for None."""
    if field is None:
        unused = np.empty((1, 1), dtype=np.float32)
        return np.zeros(3), np.zeros(3), np.zeros(3), 0, 0.0, unused, unused
    return (*_field_constants(*field), allocate("position_index", shape, np.float32),
            allocate("cos_sigma", shape, np.float32))


def pixel_geometry(projection):
    """Directions, solid angles and validity of all pixels of ``projection`` (cached).

    The first call for a camera model and image size computes the maps (for a 24-megapixel
    fisheye, 6000 × 4000, about 0.1 s of CPU time for the ideal 180° centred in the picture
    (rows computed with their mirror images) and 0.35 s for the OpenCV model with an
    off-centre principal point on the 2-core test machine, allocation of the maps included; see
    benchmarks/bench_geometry.py); later calls with an equal projection (same
    :meth:`to_dict`) return the same object.

    Parameters
    ----------
    projection : Projection
        Any camera model of :mod:`lsadphoto.geometry`.

    Returns
    -------
    PixelGeometry
        Read-only maps; ``directions`` equal ``projection.directions`` at the pixel centres
        and ``solid_angle`` the geodesic quad of the corner directions (for the ideal
        fisheye ``projection.solid_angles`` bit for bit (equidistant: to a few ulp, its
        tan); for the other models equal to it
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


def direction_map(directions):
    """The (rows, cols, 3) direction map of a map or of a :class:`PixelGeometry` (made on
    first use where the geometry stores none)."""
    return directions.directions if isinstance(directions, PixelGeometry) else directions


def directions_of_runs(directions, rows, cols, lengths):
    """The directions of the row segments (``rows[k]``, ``cols[k]`` + j), j < ``lengths[k]``,
    one after the other, of a direction map or of a :class:`PixelGeometry`
    (:meth:`PixelGeometry.directions_of_runs`)."""
    if isinstance(directions, PixelGeometry):
        return directions.directions_of_runs(rows, cols, lengths)
    rows = np.asarray(rows, dtype=np.int64).reshape(-1)
    lengths = np.asarray(lengths, dtype=np.int64).reshape(-1)
    pixel_rows = np.repeat(rows, lengths)
    offsets = np.arange(pixel_rows.size) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    pixel_cols = np.repeat(np.asarray(cols, dtype=np.int64).reshape(-1), lengths) + offsets
    return np.asarray(directions)[pixel_rows, pixel_cols]


def directions_at(directions, rows, cols):
    """``directions[rows, cols]`` of a direction map or of a :class:`PixelGeometry` (computed
    from its model where it stores no map): what the metrics that take ``directions`` call."""
    if isinstance(directions, PixelGeometry):
        return directions.directions_at(rows, cols)
    return np.asarray(directions)[rows, cols]


# --- visual field ---------------------------------------------------------------------------


class VisualField:
    """The observer's visual angles and position index of every pixel.

    The position index and cos σ are computed with the object; σ and τ on first access
    (the same kernel, the same values bit for bit): the glare metrics need only the first
    two, and two full-size float64 maps fewer is 16 bytes per pixel not allocated, written
    and faulted in (0.4 GB at 24 MP; docs/performance.md).

    Attributes
    ----------
    sigma : numpy.ndarray, shape (rows, cols)
        Angle σ between the pixel direction and the line of sight [rad], 0…π; NaN where
        invalid. Read-only.
    tau : numpy.ndarray, shape (rows, cols)
        Angle τ around the line of sight from the upward half-plane [rad], 0…π (0 above,
        π/2 to the side, π below; 0 on the line of sight); NaN where invalid. Read-only.
    position_index : numpy.ndarray, shape (rows, cols), float32
        Position index P [–] of the chosen method; NaN where invalid. Read-only.
    cos_sigma : numpy.ndarray, shape (rows, cols), float32
        d̂·v̂ [–] (the cosine factor of vertical illuminance; negative behind the observer);
        0 where invalid, so that sums over the image need no mask. Read-only.

    The position index and cos σ are computed in float64 and stored as float32 (rounded
    once: relative 2⁻²⁴ ≈ 6·10⁻⁸, far below any metric's uncertainty; the sums over the
    field stay float64): 8 bytes per pixel fewer to fault in, write and read (at 24 MP
    0.19 GB; docs/performance.md, session 14).
    """

    def __init__(self, geometry, axes, method, maps=None):
        self._inputs = (geometry, axes, method)
        self._angles = None
        self._lock = threading.Lock()
        self.position_index, self.cos_sigma = \
            _visual_field_maps(*self._inputs, angles=False) if maps is None else maps

    def _angle_maps(self):
        with self._lock:
            if self._angles is None:
                self._angles = _visual_field_maps(*self._inputs, angles=True)
        return self._angles

    @property
    def sigma(self):
        return self._angle_maps()[0]

    @property
    def tau(self):
        return self._angle_maps()[1]


def _visual_field_maps(geometry, axes, method, *, angles):
    """(σ, τ) where ``angles``, else (position index, cos σ): read-only maps."""
    from . import _kernels

    shape = geometry.valid.shape
    # σ, τ float64; position index and cos σ float32 (VisualField).
    dtype = np.float64 if angles else np.float32
    unused = np.empty((1, 1), dtype=np.float32 if angles else np.float64)
    out = [np.empty(shape, dtype=dtype), np.empty(shape, dtype=dtype)]
    maps = (out + [unused, unused]) if angles else ([unused, unused] + out)
    # The directions from the fisheye model inside the kernel where no map is stored.
    if geometry.model is not None and geometry._directions is None:
        directions, model = np.empty((1, 1, 3)), geometry.model
    else:
        directions, model = geometry.directions, (-1, np.empty(0), np.empty(0))
    _kernels.visual_field_maps(directions, geometry.valid, *model,
                               *_field_constants(axes, method), angles, not angles, *maps)
    return tuple(_read_only(array) for array in out)


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
        geometry_key = _projection_key(projection)
        rows, cols = projection.shape
        if (_GEOMETRY_CACHE.get(geometry_key) is None and rows * cols > DIRECTION_MAP_MAX_PIXELS
                and _fisheye_kernel_parameters(projection) is not None):
            # No geometry yet and no map to store: the geometry and this field in one pass,
            # which computes each centre direction once (the same values), or their maps
            # from the disk cache of an earlier process (_map_cache).
            from ._map_cache import cached_geometry_and_field

            geometry, maps = cached_geometry_and_field(
                geometry_key, (rows, cols), axes, position_index_method,
                lambda allocate=_allocate, stored=False: _compute_pixel_geometry(
                    projection, (axes, position_index_method), allocate, stored))
            _GEOMETRY_CACHE.put(geometry_key, geometry)
            cached = VisualField(geometry, axes, position_index_method, maps)
        else:
            cached = VisualField(pixel_geometry(projection), axes, position_index_method)
        _FIELD_CACHE.put(key, cached)
    return cached
