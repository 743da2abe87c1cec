"""The compiled RGBE scanline decoder on the scanline kinds Radiance's ``freadcolrs`` accepts.

New-style runs and literals, flat pixels and EXPOSURE/COLORCORR are compared with ``pvalue``
in ``test_io_hdr.py``; Radiance no longer writes old-style runs (a pixel 1, 1, 1, n repeating
the previous pixel n·256ᵏ times), but still reads them, so they are checked here against
``pvalue`` on hand-made bytes, together with an RLE scanline mixing runs and literals at
every packet length.
"""

import numpy as np
import pytest

from lsadphoto.errors import UnsupportedFileError
from lsadphoto.io.hdr import read_hdr, read_hdr_rgb

from .test_io_hdr import SAME_BYTES_RTOL, W_PACKAGE, pvalue_rgb, radiance  # noqa: F401 (fixture)


def _picture(rows, cols, pixels):
    return b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {rows} +X {cols}\n".encode() + pixels


def _old_style_bytes(rng, rows, cols):
    """Flat scanlines with old-style runs, among them two consecutive repeat pixels
    (count n₀ + 256·n₁) and one at the very end of a scanline."""
    lines = []
    for _ in range(rows):
        line, col = [], 0
        while col < cols:
            pixel = [int(v) for v in rng.integers(2, 256, 3)] + [int(rng.integers(120, 140))]
            line.append(bytes(pixel))
            col += 1
            left = cols - col
            if left >= 300 and rng.random() < 0.2:
                line += [bytes([1, 1, 1, 44]), bytes([1, 1, 1, 1])]  # 44 + 256 repeats
                col += 300
            elif left and rng.random() < 0.4:
                n = int(rng.integers(1, min(left, 255) + 1))
                line.append(bytes([1, 1, 1, n]))
                col += n
        lines.append(b"".join(line))
    return b"".join(lines)


def _rle_bytes(rng, rows, cols):
    """New-style scanlines whose packets are runs (129…255) and literals (1…128) of random
    lengths, the component bytes random."""
    out = []
    for _ in range(rows):
        out.append(bytes([2, 2, cols >> 8, cols & 0xFF]))
        for c in range(4):
            col = 0
            while col < cols:
                n = int(rng.integers(1, min(cols - col, 127) + 1))
                if rng.random() < 0.5:
                    value = int(rng.integers(120, 140)) if c == 3 else int(rng.integers(0, 256))
                    out.append(bytes([128 + n, value]))
                else:
                    low, high = (120, 140) if c == 3 else (0, 256)
                    out.append(bytes([n]) + rng.integers(low, high, n, dtype=np.uint8).tobytes())
                col += n
    return b"".join(out)


@pytest.mark.parametrize("kind, cols", [("old-style", 700), ("old-style", 5), ("rle", 300)])
def test_decoder_matches_pvalue(tmp_path, radiance, kind, cols):  # noqa: F811 (fixture)
    rng = np.random.default_rng(7)
    rows = 4
    make = _old_style_bytes if kind == "old-style" else _rle_bytes
    path = tmp_path / "picture.hdr"
    path.write_bytes(_picture(rows, cols, make(rng, rows, cols)))
    reference = pvalue_rgb(radiance, path, rows, cols)
    rgb, _ = read_hdr_rgb(path)
    # Same bytes, two exact decoders; pvalue's float32 output (SAME_BYTES_RTOL).
    np.testing.assert_allclose(rgb, reference, rtol=SAME_BYTES_RTOL, atol=0)
    luminance = read_hdr(path).luminance
    np.testing.assert_allclose(luminance, 179.0 * reference @ W_PACKAGE, rtol=SAME_BYTES_RTOL, atol=0)


@pytest.mark.parametrize("pixels, message", [
    (bytes([1, 1, 1, 3]) + bytes(36), "old-style run at the start of a scanline"),
    (bytes([9, 9, 9, 130]) + bytes([1, 1, 1, 10]), "corrupt old-style run"),
    (bytes([2, 2, 0, 10]) + bytes([0]) + bytes(60), "corrupt run length"),
    (bytes([2, 2, 0, 10]) + bytes([128 + 11, 5]) + bytes(60), "corrupt run length"),
])
def test_corrupt_scanlines_raise_one_line(tmp_path, pixels, message):
    cols = 10 if pixels[:2] == b"\x02\x02" else 5
    path = tmp_path / "bad.hdr"
    path.write_bytes(_picture(1, cols, pixels))
    with pytest.raises(UnsupportedFileError, match=message) as info:
        read_hdr(path)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("exposure, colorcorr", [(1.0, (1.0, 1.0, 1.0)), (0.37, (0.9, 1.1, 1.3)),
                                                 (2.5e-3, (1.0, 1.0, 1.0)), (7.3e4, (1.7, 1.0, 0.6))])
def test_mantissa_tables_give_the_formula_bit_for_bit(exposure, colorcorr):
    """Every mantissa byte of every channel at every exponent byte (0…255), decoded with the
    tables and with the per-pixel formula (three divisions per channel, as Radiance's
    colr_color and read_hdr_rgb): the same float32 bits (the tables move only powers of two,
    which round exactly; see ``mantissa_tables``)."""
    from lsadphoto.constants import RADIANCE_RGB_LUMINANCE_WEIGHTS, RADIANCE_WHITE_EFFICACY
    from lsadphoto.io._rgbe import decode_luminance, mantissa_tables

    rng = np.random.default_rng(11)
    cols = 256
    rgbe = np.empty((256, cols, 4), np.uint8)
    rgbe[:, :, :3] = rng.integers(0, 256, (256, cols, 3))
    rgbe[:, :, 0] = np.arange(256)[None, :]  # each mantissa byte once per exponent
    rgbe[:, :, 3] = np.arange(256)[:, None]
    # Flat scanlines (the random bytes hold no 1, 1, 1 that would be an old-style run).
    data = np.ascontiguousarray(rgbe.reshape(-1))
    args = (float(exposure), np.asarray(colorcorr, np.float64),
            np.asarray(RADIANCE_RGB_LUMINANCE_WEIGHTS, np.float64), float(RADIANCE_WHITE_EFFICACY))
    tables = mantissa_tables(*args)
    assert tables is not None
    with_tables = np.empty((256, cols), np.float32)
    formula = np.empty((256, cols), np.float32)
    assert decode_luminance(data, 0, False, *args, tables, True, with_tables)[1] == 0
    assert decode_luminance(data, 0, False, *args, tables, False, formula)[1] == 0
    assert np.array_equal(with_tables.view(np.uint32), formula.view(np.uint32))
    assert np.all(with_tables[0] == 0) and np.all(with_tables[1:] > 0)


def test_mantissa_tables_refuse_what_would_leave_the_normal_range():
    """An EXPOSURE so small that a pixel's value would overflow, or a negative weight (sums
    that could cancel): no tables, the formula decodes."""
    from lsadphoto.io._rgbe import mantissa_tables

    weights = np.array([0.265, 0.670, 0.065])
    assert mantissa_tables(1e-290, np.ones(3), weights, 179.0) is None
    assert mantissa_tables(1e290, np.ones(3), weights, 179.0) is None
    assert mantissa_tables(1.0, np.ones(3), np.array([0.5, -0.1, 0.6]), 179.0) is None
    assert mantissa_tables(1.0, np.ones(3), weights, 179.0) is not None


@pytest.mark.parametrize("threads", ["1", "2", "3"])
def test_scanline_blocks_on_threads_decode_the_same(tmp_path, monkeypatch, threads):
    """Blocks of scanlines decoded at the same time (their positions found first) give the
    one-thread values bit for bit, for new-style and old-style scanlines; an error in a later
    block names the scanline the sequential decoder names."""
    rng = np.random.default_rng(5)
    rows = 9
    for kind, cols, make in (("rle", 300, _rle_bytes), ("old-style", 700, _old_style_bytes)):
        path = tmp_path / f"{kind}.hdr"
        path.write_bytes(_picture(rows, cols, make(rng, rows, cols)))
        monkeypatch.setenv("LSADPHOTO_THREADS", "1")
        one = read_hdr(path).luminance
        monkeypatch.setenv("LSADPHOTO_THREADS", threads)
        assert np.array_equal(read_hdr(path).luminance.view(np.uint32), one.view(np.uint32))
    good = _rle_bytes(rng, rows - 1, 300)
    bad = bytes([2, 2, 1, 44]) + bytes([0]) + bytes(60)  # a zero count in scanline 8
    path = tmp_path / "bad.hdr"
    path.write_bytes(_picture(rows, 300, good + bad))
    with pytest.raises(UnsupportedFileError, match=r"corrupt run length \(scanline 8\)"):
        read_hdr(path)
