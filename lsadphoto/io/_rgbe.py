"""Compiled RGBE decoding of Radiance pictures: scanlines to bytes, bytes to luminance.

The scanline decoder follows Radiance's ``freadcolrs``: in a picture 8…0x7FFF pixels wide,
a scanline whose first bytes are 2, 2 and a byte below 128 is new-style run-length
encoded, one component after the other in packets — a count above 128 repeats the next byte
count − 128 times, a count of 1…128 is followed by that many literal bytes; any other
scanline is flat RGBE pixels, where a pixel 1, 1, 1, n repeats the previous pixel n·256ᵏ
times (k counts the consecutive repeat pixels: Radiance's old-style runs). It runs once over
the file's bytes; a Python loop over the packets (the previous decoder) took 1.2 s for a
1572² picture.

:func:`decode_luminance` decodes a pixel as Radiance's ``colr_color`` does,
(mantissa + ½)·2^(exponent − 136), divides by the EXPOSURE product and the COLORCORR factors
and weights the channels, scanline by scanline, without an RGBE or float64 RGB copy of the
whole picture.

References
----------
G. Ward, "Real pixels", *Graphics Gems II* (1991) 80–83. Radiance ``src/common/color.c``
(freadcolrs, oldreadcolrs, colr_color).
"""

import math

import numpy as np
from .._compiled import njit

__all__ = ["SCANLINE_ERRORS", "decode_luminance", "decode_scanlines", "mantissa_tables",
           "scanline_offsets"]


#: Messages of the error codes :func:`decode_scanlines` returns.
SCANLINE_ERRORS = {
    1: "file truncated inside a scanline",
    2: "scanline length mismatch",
    3: "corrupt run length",
    4: "old-style run at the start of a scanline",
    5: "corrupt old-style run",
}


@njit(cache=True, nogil=True)
def _decode_scanline(data, pos, rle, out, store):
    """Decode one scanline from ``data[pos:]`` (uint8) into ``out`` ``(cols, 4)`` uint8, new
    style where ``rle`` (the width allows it); returns ``(position after it, error code)``,
    error code 0 on success (else a key of :data:`SCANLINE_ERRORS`). Without ``store`` the
    scanline is only walked (its length and errors; ``out`` gives the width, nothing is
    written)."""
    cols = out.shape[0]
    n = data.size
    if rle and pos + 4 <= n and data[pos] == 2 and data[pos + 1] == 2 and data[pos + 2] < 128:
        if (np.int64(data[pos + 2]) << 8 | np.int64(data[pos + 3])) != cols:
            return pos, 2
        pos += 4
        for c in range(4):
            col = 0
            while col < cols:
                if pos >= n:
                    return pos, 1
                code = np.int64(data[pos])
                pos += 1
                if code > 128:
                    run = code - 128
                    if col + run > cols or pos >= n:
                        return pos, 3
                    value = data[pos]
                    pos += 1
                    if store:
                        for k in range(col, col + run):
                            out[k, c] = value
                    col += run
                else:
                    if code == 0 or col + code > cols or pos + code > n:
                        return pos, 3
                    if store:
                        for k in range(code):
                            out[col + k, c] = data[pos + k]
                    pos += code
                    col += code
        return pos, 0
    col, shift = 0, 0
    while col < cols:
        if pos + 4 > n:
            return pos, 1
        if data[pos] == 1 and data[pos + 1] == 1 and data[pos + 2] == 1:
            if col == 0:
                return pos, 4
            run = np.int64(data[pos + 3]) << shift
            if col + run > cols:
                return pos, 5
            if store:
                for k in range(col, col + run):
                    for c in range(4):
                        out[k, c] = out[col - 1, c]
            col += run
            shift += 8
        else:
            if store:
                for c in range(4):
                    out[col, c] = data[pos + c]
            col += 1
            shift = 0
        pos += 4
    return pos, 0


@njit(cache=True, nogil=True,
      aot="UniTuple(int64, 3)(uint8[::1], int64, boolean, uint8[:, :, ::1])")
def decode_scanlines(data, pos, rle, rgbe):
    """Decode ``rgbe.shape[0]`` scanlines from ``data[pos:]`` (uint8) into ``rgbe``
    ``(rows, cols, 4)`` uint8, taking new-style scanlines where ``rle`` (the width allows
    them); returns ``(position after the last scanline, error code, row)`` with error code 0
    on success (else a key of :data:`SCANLINE_ERRORS`)."""
    for row in range(rgbe.shape[0]):
        pos, error = _decode_scanline(data, pos, rle, rgbe[row], True)
        if error:
            return pos, error, row
    return pos, 0, rgbe.shape[0]


@njit(cache=True, nogil=True, aot="UniTuple(int64, 3)(uint8[::1], int64, boolean, int64, int64[::1])")
def scanline_offsets(data, pos, rle, cols, offsets):
    """The position in ``data`` of each of ``offsets.size`` scanlines ``cols`` wide from
    ``data[pos:]`` (as :func:`decode_scanlines` walks them, without decoding a pixel), so
    that blocks of scanlines can be decoded at the same time; returns what
    :func:`decode_scanlines` returns."""
    scratch = np.empty((cols, 4), dtype=np.uint8)  # gives the width; not written
    for row in range(offsets.size):
        offsets[row] = pos
        pos, error = _decode_scanline(data, pos, rle, scratch, False)
        if error:
            return pos, error, row
    return pos, 0, offsets.size


def mantissa_tables(exposure, colorcorr, weights, efficacy):
    """``tables[c, m]`` = ((m + ½) / exposure / colorcorr[c]) · weights[c] (float64, the
    operations of :func:`decode_luminance` without the power of two), or None where they do
    not give its values bit for bit.

    A product or quotient with 2^k rounds as the same operation without it, times 2^k, and
    so does a sum of such terms, as long as no value leaves the normal range of float64: so
    the luminance of a pixel is efficacy · (2^(e − 136) · ((t₀ + t₁) + t₂)) with each t_c
    looked up, three divisions and two multiplications per channel fewer. That holds where
    every intermediate value, times the smallest and the largest scale 2^−135 and 2^119, stays
    normal: nonzero values within [2^−887, 2^900] (sums of non-negative terms lie between
    their largest term and three times it), which the arguments of a real picture are far
    inside; otherwise (or with a negative weight, whose sums could cancel) None, and the
    pixels are decoded without tables."""
    m = np.arange(256, dtype=np.float64) + 0.5
    colorcorr, weights = np.asarray(colorcorr, np.float64), np.asarray(weights, np.float64)
    steps = [m / exposure]
    steps.append(steps[0][None, :] / colorcorr[:, None])
    tables = steps[1] * weights[:, None]
    largest = 3.0 * float(tables.max()) * max(float(efficacy), 1.0)
    values = np.concatenate([steps[0], steps[1].ravel(), tables.ravel(),
                             float(efficacy) * tables.ravel(), [largest]])
    values = np.abs(values[values != 0])
    if not (np.all(weights >= 0) and efficacy > 0 and np.all(np.isfinite(values)) and
            values.min() >= 2.0 ** -887 and values.max() <= 2.0 ** 900):
        return None
    return np.ascontiguousarray(tables)


@njit(cache=True, nogil=True,
      aot=("UniTuple(int64, 3)(uint8[::1], int64, boolean, float64, float64[::1], float64[::1], "
           "float64, float64[:, ::1], boolean, float32[:, ::1])"))
def decode_luminance(data, pos, rle, exposure, colorcorr, weights, efficacy, tables, use_tables,
                     out):
    """Decode ``out.shape[0]`` scanlines from ``data[pos:]`` (as :func:`decode_scanlines`)
    straight into luminance: ``out`` (rows, cols) float32 = efficacy · Σ_c weights[c] · rgb_c
    with rgb_c = (m_c + ½)·2^(e − 136) / exposure / colorcorr[c] (the float64 operations of
    :func:`lsadphoto.io.hdr.read_hdr_rgb`); 0 where the exponent byte is 0. Where
    ``use_tables``, each channel's term is looked up in ``tables`` (:func:`mantissa_tables`:
    the same values bit for bit). Each scanline goes through one row of RGBE bytes, not a
    copy of the whole picture (4 bytes per pixel less to allocate and fault in). Returns what
    :func:`decode_scanlines` returns."""
    rows, cols = out.shape
    rgbe = np.empty((cols, 4), dtype=np.uint8)
    t0, t1, t2 = tables[0], tables[1], tables[2]
    scales = np.empty(256)  # 2^(e − 136), exact
    for e in range(256):
        scales[e] = math.ldexp(1.0, e - 136)
    for row in range(rows):
        pos, error = _decode_scanline(data, pos, rle, rgbe, True)
        if error:
            return pos, error, row
        if use_tables:
            line = out[row]
            for col in range(cols):
                e = rgbe[col, 3]
                total = scales[e] * ((t0[rgbe[col, 0]] + t1[rgbe[col, 1]]) + t2[rgbe[col, 2]])
                line[col] = np.float32(efficacy * total) if e != 0 else np.float32(0.0)
            continue
        for col in range(cols):
            e = np.int64(rgbe[col, 3])
            if e == 0:
                out[row, col] = 0.0
                continue
            scale = math.ldexp(1.0, e - 136)
            total = 0.0
            for c in range(3):
                value = (np.float64(rgbe[col, c]) + 0.5) * scale
                total += value / exposure / colorcorr[c] * weights[c]
            out[row, col] = np.float32(efficacy * total)
    return pos, 0, rows
