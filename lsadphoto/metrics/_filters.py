"""Compiled image filters of the Q criterion: a separable correlation and a square erosion.

Q (:mod:`~lsadphoto.metrics.quality`) needs the pixel derivatives of its blurred field
(two separable filters, a third for the luminance cut-off) and the pixels whose whole
stencil lies in the field (a binary erosion). OpenCV's ``sepFilter2D`` and ``erode`` did
this; importing OpenCV costs a score process 0.03–0.07 s, as much as the filters themselves
at 786² (docs/performance.md), so the two operations are the project's own kernels here
(:mod:`lsadphoto._compiled`, compiled ahead of time with the other kernels).

* :func:`correlate_separable`: ``out[i, j] = Σ_a Σ_b ky[a]·kx[b]·x[i + a − ry, j + b − rx]``
  (correlation, each kernel centred on its middle tap: OpenCV's convention with the default
  anchor), the row pass first, both passes summed in float64 from exact float64 products of
  the float32 inputs, the result rounded once to float32. Only pixels whose whole stencil
  lies in the image are computed; the border of ``ry`` rows and ``rx`` columns is NaN (Q
  reads none of it: its evaluated pixels are eroded by the stencil). OpenCV sums in float32
  (with fused multiply–adds in its SIMD lanes, without in the row tails), so the two agree to
  float32 summation error, ≤ (n_x + n_y + 2)·2⁻²⁴ of Σ|k_y|·|k_x|·|x| (tested).
* :func:`erode_square`: ``out[i, j]`` true where every pixel of the (2r + 1)² square centred
  on (i, j) is true and inside the image (OpenCV's ``erode`` with a square of ones and a
  constant border of 0) — exact, by run lengths along rows and then columns.
"""

import numpy as np

from .._compiled import njit, prange

__all__ = ["correlate_separable", "erode_square"]

_OPTIONS = {"cache": True, "error_model": "numpy", "nogil": True}
#: Output rows per band of :func:`_correlate`: bands are shared out among the threads, each
#: recomputing the 2·ry rows of row-filtered input above its first row.
_BAND_ROWS = 64


@njit(parallel=True, **_OPTIONS,
      aot="void(float32[:, ::1], float64[::1], float64[::1], int64, float32[:, ::1])")
def _correlate(image, kx, ky, band_rows, out):
    """:func:`correlate_separable` into ``out`` (kernels as float64 copies of the float32
    taps). Each band of output rows keeps its row-filtered input rows in a ring of
    2·ry + 1 float64 rows; every output value is the same sum in the same order whatever the
    bands, so the result does not depend on them or on the threads."""
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
    for band in prange(n_bands):
        r0 = first + band * band_rows
        r1 = min(r0 + band_rows, last)
        ring = np.empty((ny, inner))
        acc = np.empty(inner)
        for src in range(r0 - ry, r1 + ry):
            # The row pass of input row ``src`` into its slot of the ring.
            slot = ring[src % ny]
            x = image[src]
            for j in range(inner):
                slot[j] = 0.0
            for b in range(nx):
                k = kx[b]
                xs = x[b:b + inner]
                for j in range(inner):
                    slot[j] += k * np.float64(xs[j])
            i = src - ry  # the output row whose stencil this input row completes
            if i < r0:
                continue
            for j in range(inner):
                acc[j] = 0.0
            for a in range(ny):
                k = ky[a]
                h = ring[(i - ry + a) % ny]
                for j in range(inner):
                    acc[j] += k * h[j]
            o = out[i, rx:rx + inner]
            for j in range(inner):
                o[j] = np.float32(acc[j])


def correlate_separable(image, kx, ky):
    """The separable correlation of a float32 ``image`` with the column kernel ``kx`` (along
    each row) and the row kernel ``ky`` (along each column), odd lengths, as float32; NaN on
    the border where the stencil leaves the image (see the module's docstring)."""
    image = np.ascontiguousarray(image, dtype=np.float32)
    kx = np.asarray(kx, dtype=np.float32).reshape(-1).astype(np.float64)
    ky = np.asarray(ky, dtype=np.float32).reshape(-1).astype(np.float64)
    out = np.empty(image.shape, dtype=np.float32)
    _correlate(image, kx, ky, _BAND_ROWS, out)
    return out


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
