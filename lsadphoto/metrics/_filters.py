"""Compiled image filters of the Q criterion: a separable correlation and a square erosion.

Q (:mod:`~lsadphoto.metrics.quality`) needs the pixel derivatives of its blurred field
(two separable filters, a third for the luminance cut-off) and the pixels whose whole
stencil lies in the field (a binary erosion). OpenCV's ``sepFilter2D`` and ``erode`` did
this; importing OpenCV costs a score process 0.03–0.07 s, as much as the filters themselves
at 786² (docs/performance.md), so the two operations are the project's own kernels here
(:mod:`lsadphoto._compiled`, compiled ahead of time with the other kernels). Q itself takes
its two derivatives with the row and column sums of this module (``_taps``, ``_column_taps``)
inside its own pass over the evaluated pixels (``quality._candidates_kernel``: no maps of
the derivatives, the same values); :func:`correlate_separable_each` serves its luminance
cut-off and the design module's gradient components.

* :func:`correlate_separable`: ``out[i, j] = Σ_a Σ_b ky[a]·kx[b]·x[i + a − ry, j + b − rx]``
  (correlation, each kernel centred on its middle tap: OpenCV's convention with the default
  anchor) for kernels that are symmetric or antisymmetric (Q's Gaussian and its
  derivative), the taps at ±b sharing one product; the row pass first, summed in float64
  (the float32 inputs and taps are exact in it) and rounded once to float32, then the
  column pass summed in float32: within (r_y + 4)·2⁻²⁴ of Σ|k_y|·|k_x|·|x| of the exact
  correlation (tested against float64), which moves Q by about 10⁻⁸ relative
  (docs/performance.md, session 14). The float32 column pass streams half the bytes on
  twice the SIMD lanes: Q's candidate pass, which shares these sums, 0.21 → 0.16 s of CPU
  at 24 MP. Only pixels whose whole stencil
  lies in the image are computed; the border of ``ry`` rows and ``rx`` columns is NaN (Q
  reads none of it: its evaluated pixels are eroded by the stencil). OpenCV sums in float32
  (with fused multiply–adds in its SIMD lanes, without in the row tails), so the two agree to
  float32 summation error (tested).
* :func:`erode_square`: ``out[i, j]`` true where every pixel of the (2r + 1)² square centred
  on (i, j) is true and inside the image (OpenCV's ``erode`` with a square of ones and a
  constant border of 0) — exact, by run lengths along rows and then columns.
"""

import numpy as np

from .._compiled import njit, prange, run_blocks

__all__ = ["correlate_separable", "correlate_separable_each", "erode_square"]

_OPTIONS = {"cache": True, "error_model": "numpy", "nogil": True}
#: Output rows per band of :func:`_correlate`: bands are shared out among the threads, each
#: recomputing the 2·ry rows of row-filtered input above its first row.
_BAND_ROWS = 64


@njit(inline="always", **_OPTIONS)
def _taps(out, acc, x, k, centre, parity, n):
    """out[j] = Σ_b k[centre + b]·x[centre + j + b] over |b| ≤ centre for j < n, summed in
    the float64 row ``acc`` and rounded once to ``out``'s dtype (float32 rows of the rings),
    the kernel symmetric (``parity`` 1) or antisymmetric (−1): the pairs x[j + b] ± x[j − b]
    share one product."""
    c = k[centre]
    xc = x[centre:centre + n]
    for j in range(n):
        acc[j] = c * np.float64(xc[j])
    for b in range(1, centre + 1):
        t = k[centre + b]
        xp = x[centre + b:centre + b + n]
        xm = x[centre - b:centre - b + n]
        if parity > 0:
            for j in range(n):
                acc[j] += t * (np.float64(xp[j]) + np.float64(xm[j]))
        else:
            for j in range(n):
                acc[j] += t * (np.float64(xp[j]) - np.float64(xm[j]))
    for j in range(n):
        out[j] = acc[j]


@njit(parallel=True, **_OPTIONS,
      aot=("void(float32[:, ::1], float64[::1], float64[::1], int64, int64, int64, "
           "float32[:, ::1])"))
def _correlate(image, kx, ky, parity_x, parity_y, band_rows, out):
    """:func:`correlate_separable` into ``out`` (kernels as float64 copies of the float32
    taps, each symmetric or antisymmetric: ``parity_x``, ``parity_y`` ±1). Each band of
    output rows keeps its row-filtered input rows in a ring of 2·ry + 1 float32 rows; every
    output value is the same sum in the same order whatever the bands, so the result does
    not depend on them or on the threads."""
    rows, cols = image.shape
    nx, ny = kx.size, ky.size
    rx, ry = nx // 2, ny // 2
    nan = np.float32(np.nan)
    inner = cols - 2 * rx  # columns with a complete row stencil
    for i in range(rows):
        if i < ry or i >= rows - ry or inner <= 0:
            out[i, :] = nan
        else:
            out[i, :rx] = nan
            out[i, cols - rx:] = nan
    if inner <= 0 or rows < ny:
        return
    first, last = ry, rows - ry  # output rows with a complete column stencil
    n_bands = (last - first + band_rows - 1) // band_rows
    ky32 = ky.astype(np.float32)  # the column pass's taps (float32 arithmetic)
    for band in prange(n_bands):
        r0 = first + band * band_rows
        r1 = min(r0 + band_rows, last)
        ring = np.empty((ny, inner), dtype=np.float32)
        row_sums = np.empty(inner)
        acc = np.empty(inner, dtype=np.float32)
        for src in range(r0 - ry, r1 + ry):
            # The row pass of input row ``src`` into its slot of the ring.
            _taps(ring[src % ny], row_sums, image[src], kx, rx, parity_x, inner)
            i = src - ry  # the output row whose stencil this input row completes
            if i < r0:
                continue
            _column_taps(acc, ring, i, ky32, ry, parity_y, inner)
            o = out[i, rx:rx + inner]
            for j in range(inner):
                o[j] = acc[j]


@njit(inline="always", **_OPTIONS)
def _column_taps(out, ring, i, k, centre, parity, n):
    """out[j] = Σ_a k[centre + a]·(row i + a)[j] over |a| ≤ centre, input row m kept in
    ``ring[m % len(ring)]``, paired as in :func:`_taps`, in the arithmetic of ``out``,
    ``ring`` and ``k`` (float32 in this module's callers)."""
    size = ring.shape[0]
    c = k[centre]
    rc = ring[i % size]
    for j in range(n):
        out[j] = c * rc[j]
    for a in range(1, centre + 1):
        t = k[centre + a]
        hp, hm = ring[(i + a) % size], ring[(i - a) % size]
        if parity > 0:
            for j in range(n):
                out[j] += t * (hp[j] + hm[j])
        else:
            for j in range(n):
                out[j] += t * (hp[j] - hm[j])


def _parity(kernel):
    """1 for a symmetric kernel, −1 for an antisymmetric one (Q's smoothing and derivative
    kernels are exactly one or the other)."""
    if np.array_equal(kernel, kernel[::-1]):
        return 1
    if np.array_equal(kernel, -kernel[::-1]):
        return -1
    raise ValueError("correlate_separable takes symmetric or antisymmetric kernels")


def correlate_separable(image, kx, ky):
    """The separable correlation of a float32 ``image`` with the column kernel ``kx`` (along
    each row) and the row kernel ``ky`` (along each column), odd lengths, each symmetric or
    antisymmetric, as float32; NaN on the border where the stencil leaves the image (see the
    module's docstring)."""
    return correlate_separable_each(image, [(kx, ky)])[0]


def correlate_separable_each(image, kernels):
    """:func:`correlate_separable` of ``image`` with each pair ``(kx, ky)`` of ``kernels``,
    a list of float32 maps; the filters run at the same time, one per thread, where the
    ahead-of-time code runs them (:func:`lsadphoto._compiled.run_blocks`): the same values."""
    image = np.ascontiguousarray(image, dtype=np.float32)
    calls = []
    for kx, ky in kernels:
        kx = np.asarray(kx, dtype=np.float32).reshape(-1).astype(np.float64)
        ky = np.asarray(ky, dtype=np.float32).reshape(-1).astype(np.float64)
        calls.append((image, kx, ky, _parity(kx), _parity(ky), _BAND_ROWS,
                      np.empty(image.shape, dtype=np.float32)))

    def run(*args):
        _correlate(*args)
        return args[-1]

    return run_blocks(run, calls, _correlate.threads_for(*calls[0]))


@njit(**_OPTIONS, aot="void(boolean[:, ::1], int64, boolean[:, ::1], int32[::1], int32[::1])")
def _erode(mask, radius, out, run, column_run):
    """:func:`erode_square` into ``out``: ``run`` counts the true pixels ending at each
    column of the current row; a row's horizontally complete pixels then extend per-column
    runs (``column_run``) downwards, and a vertical run of 2r + 1 completes the square of
    the pixel r rows up."""
    rows, cols = mask.shape
    size = 2 * radius + 1
    out[:, :] = False
    column_run[:] = 0
    for i in range(rows):
        count = 0
        m = mask[i]
        for j in range(cols):
            count = count + 1 if m[j] else 0
            run[j] = count
        # Row i is complete around column c = j − r where the run ending at j has 2r + 1.
        for c in range(cols):
            j = c + radius
            complete = j < cols and c >= radius and run[j] >= size
            column_run[c] = column_run[c] + 1 if complete else 0
            if column_run[c] >= size:
                out[i - radius, c] = True


def erode_square(mask, radius):
    """Pixels of the boolean ``mask`` whose (2·radius + 1)² square lies wholly in the mask
    and in the image."""
    mask = np.ascontiguousarray(mask, dtype=bool)
    out = np.empty(mask.shape, dtype=bool)
    cols = mask.shape[1]
    _erode(mask, int(radius), out, np.empty(cols, dtype=np.int32), np.empty(cols, dtype=np.int32))
    return out
