"""Radiance HDR (RGBE) input/output, checked against Radiance itself (pyradiance's binaries).

References used by these tests, independent of ``lsadphoto.io.hdr``:

- ``pvalue`` (Radiance) decodes pictures: ``-o`` undoes EXPOSURE= and COLORCORR=, ``-b``
  gives the brightness (Radiance's luminance weights), ``-h -H`` drop header and resolution
  string, ``-dd`` writes binary doubles; ``pvalue -r`` encodes floats into a picture with
  Radiance's own setcolr and RLE writer.
- ``pfilt -1 -e 2`` (one pass, exposure 2) writes EXPOSURE= lines, ``-er/-eg/-eb`` also a
  COLORCORR= line; ``getinfo`` prints headers, ``getinfo -a`` adds header lines.
- ``vwrays`` computes the ray of every pixel of a view (or of a picture's VIEW= line).

Quantisation bound of a grey RGBE pixel: setcolr stores ``floor(256·m)`` with the mantissa
m ∈ [½, 1), i.e. an integer n ∈ [128, 255], and colr_color decodes ``(n + ½)·2^(e−8)``;
the true value is ``256·m·2^(e−8)`` with ``256·m ∈ [n, n + 1)``, so the decoding is off by
at most ½ of a step of at least 128 steps: relative error ≤ 0.5/128 = 2⁻⁸. Storage of the
read map as float32 adds at most 2⁻²⁴ relative.
"""

import math
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

from lsadphoto.constants import RADIANCE_RGB_LUMINANCE_WEIGHTS
from lsadphoto.errors import BadInputError, UnsupportedFileError
from lsadphoto.geometry.pinhole import PinholeProjection
from lsadphoto.io.hdr import float_to_rgbe, parse_view, read_hdr, read_hdr_rgb, rgbe_to_float, write_hdr
from lsadphoto.luminance_map import LuminanceMap

from .conftest import realdata

#: Worst-case relative RGBE error of a grey pixel (module docstring) plus float32 storage.
RGBE_BOUND = 0.5 / 128 + 2.0**-23
#: Two decoders of the same RGBE bytes: both are exact in binary ((n + ½)·2^k); pvalue then
#: works in float32 (brightness sum, 1/EXPOSURE), a few float32 ulps ≈ 1e-7 relative, and
#: our map is float32 (6e-8). 1e-6 leaves a factor ~5 of margin, far below any decoding
#: difference (the ½ offset alone is ≥ 0.2 %).
SAME_BYTES_RTOL = 1e-6
#: Package weights (Radiance ≤ 5.x color.h, white point x = y = 0.3333).
W_PACKAGE = np.array(RADIANCE_RGB_LUMINANCE_WEIGHTS)


def _weights_from_primaries(white):
    """Y row of Radiance's RGB→XYZ matrix for its nominal primaries and a white point."""
    primaries = [(0.640, 0.330), (0.290, 0.600), (0.150, 0.060)]
    m = np.array([[x / y, 1.0, (1.0 - x - y) / y] for x, y in primaries]).T
    xw, yw = white
    scale = np.linalg.solve(m, [xw / yw, 1.0, (1.0 - xw - yw) / yw])
    return m[1] * scale


#: Radiance 6 (the pvalue shipped with pyradiance 1.3.1) derives its weights from the exact
#: equal-energy white (1/3, 1/3): 0.2651058, 0.6701058, 0.0647884.
W_RADIANCE6 = _weights_from_primaries((1.0 / 3.0, 1.0 / 3.0))


# --- Radiance tools -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def radiance():
    """Run a Radiance program from pyradiance's bin folder; returns its stdout bytes."""
    pyradiance = pytest.importorskip("pyradiance", reason="pyradiance (test extra) ships the Radiance tools")
    bindir = Path(pyradiance.__file__).resolve().parent / "bin"
    if not (bindir / "pvalue").exists():
        pytest.skip(f"no Radiance binaries in {bindir}")
    env = dict(os.environ)
    env["PATH"] = f"{bindir}{os.pathsep}{env.get('PATH', '')}"
    env["RAYPATH"] = str(bindir.parent / "lib")

    def run(program, *args, stdin=None):
        done = subprocess.run(
            [str(bindir / program), *map(str, args)], input=stdin, capture_output=True, env=env, timeout=60
        )
        if done.returncode != 0:
            raise AssertionError(f"{program} {args} failed: {done.stderr.decode(errors='replace')}")
        return done.stdout

    return run


def pvalue_rgb(radiance, path, rows, cols):
    """Radiance's decoding of ``path``: RGB with EXPOSURE and COLORCORR undone (``-o``)."""
    out = radiance("pvalue", "-o", "-h", "-H", "-dd", path)
    return np.frombuffer(out, dtype=np.float64).reshape(rows, cols, 3)


def pvalue_luminance(radiance, path, rows, cols):
    """179 × Radiance's brightness (``-b``) of ``path`` with exposure undone [cd·m⁻²]."""
    out = radiance("pvalue", "-o", "-h", "-H", "-b", "-dd", path)
    return 179.0 * np.frombuffer(out, dtype=np.float64).reshape(rows, cols)


def radiance_picture(radiance, rgb, *filters):
    """Bytes of a picture that Radiance encodes (``pvalue -r``) from float RGB, then piped
    through ``filters`` (argument tuples such as ``("pfilt", "-1", "-e", 2)``)."""
    rows, cols, _ = rgb.shape
    raw = np.ascontiguousarray(rgb, dtype=np.float32).tobytes()
    data = radiance("pvalue", "-r", "-h", "-H", "-y", rows, "+x", cols, "-df", stdin=raw)
    for program, *args in filters:
        data = radiance(program, *args, stdin=data)
    return data


def scanline_bytes(data):
    start = data.index(b"\n\n") + 2
    return data[data.index(b"\n", start) + 1 :]


def log_spaced_map(rows, cols, *, nan_every=0):
    values = np.logspace(-3.0, 9.0, rows * cols).reshape(rows, cols)
    if nan_every:
        values.flat[::nan_every] = np.nan
    return values.astype(np.float32)


def relative(a, b):
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    return np.abs(a - b) / np.abs(b)


WIDTHS = [1, 7, 8, 128, 129, 300]  # flat (< 8), RLE edge cases, several 128-byte chunks


# --- 1. our write → our read ----------------------------------------------------------------


@pytest.mark.parametrize("cols", WIDTHS)
def test_round_trip_within_rgbe_bound(tmp_path, cols):
    rows = max(4, 2400 // cols)
    truth = log_spaced_map(rows, cols, nan_every=97)  # 1e-3 … 1e9 cd/m², 12 decades
    path = tmp_path / "map.hdr"
    write_hdr(LuminanceMap(truth), path)
    back = read_hdr(path)

    assert back.shape == truth.shape
    assert back.luminance.dtype == np.float32
    nan = np.isnan(truth)
    assert np.all(back.luminance[nan] == 0.0)  # NaN is written as 0 (evalglare's "invalid")
    error = relative(back.luminance[~nan], truth[~nan])
    assert error.max() <= RGBE_BOUND  # bound derived in the module docstring
    # Radiance decodes at the middle of the quantisation step: errors are centred on 0
    # (OpenCV's decoding without the ½ would be biased by about −0.3 %). The relative error
    # is spread over ±0.5/n, n ∈ [128, 255] (std ≈ 1.5e-3), so the mean of > 1000 values
    # has a std ≤ 5e-5: 4e-4 is > 8σ from 0 and far from the −2.6e-3 of a biased decoder.
    signed = (back.luminance[~nan].astype(float) - truth[~nan]) / truth[~nan]
    if signed.size > 1000:
        assert abs(signed.mean()) < 4e-4
        assert error.max() > 0.5 / 256  # the bound is nearly reached: the test is not vacuous


def test_round_trip_metadata(tmp_path):
    projection = PinholeProjection(40.0, 42.0, 17.25, 9.5, 36, 20)
    lmap = LuminanceMap(
        np.full((20, 36), 250.0),
        projection=projection,
        line_of_sight=[0.0, 0.0, 1.0],
        calibration_factor=0.1 + 0.2,
        calibration_uncertainty=0.034,
        calibrated=True,
        provenance={"source": "shot.dng", "exposure_times": [1 / 125, 1 / 30], "note": "désk\nlamp"},
    )
    path = tmp_path / "m.hdr"
    write_hdr(lmap, path)
    back = read_hdr(path)
    assert back.projection == projection
    assert back.calibration_factor == 0.1 + 0.2  # JSON keeps the repr of a float: exact
    assert back.calibration_uncertainty == 0.034
    assert back.calibrated is True
    assert back.provenance == lmap.provenance
    np.testing.assert_array_equal(back.line_of_sight, [0.0, 0.0, 1.0])


def test_encoder_matches_radiance_setcolr_bytes(radiance):
    """float_to_rgbe gives the very bytes Radiance's setcolr writes (pvalue -r, flat
    scanlines for a width < 8), for greys over 12 decades, colours, zero and tiny values."""
    rng = np.random.default_rng(1)
    greys = np.repeat(np.logspace(-6, 7, 7 * 40)[:, None], 3, axis=1)
    colours = rng.uniform(0, 1, (7 * 40, 3)) * np.logspace(-4, 4, 7 * 40)[:, None]
    specials = np.array([[0, 0, 0], [1e-33, 1e-33, 1e-33], [1, 0, 0], [0, 0.5, 1], [2.0, 2.0, 2.0],
                         [1.0, 1.0, 1.0], [255.0 / 256, 1e-9, 0.25]])
    rgb = np.concatenate([greys, colours, specials]).astype(np.float32).astype(np.float64)
    rgb = rgb.reshape(-1, 7, 3)
    expected = np.frombuffer(scanline_bytes(radiance_picture(radiance, rgb)), np.uint8).reshape(rgb.shape[:2] + (4,))
    np.testing.assert_array_equal(float_to_rgbe(rgb), expected)  # exact: same double arithmetic


def test_rgbe_decoding_matches_colr_color():
    """rgbe_to_float against a scalar transcription of Radiance's colr_color."""

    def colr_color(r, g, b, e):
        if e == 0:
            return (0.0, 0.0, 0.0)
        f = math.ldexp(1.0, e - (128 + 8))
        return tuple((c + 0.5) * f for c in (r, g, b))

    rng = np.random.default_rng(2)
    rgbe = rng.integers(0, 256, (500, 4)).astype(np.uint8)
    rgbe[:5, 3] = 0
    expected = np.array([colr_color(*map(int, p)) for p in rgbe])
    np.testing.assert_array_equal(rgbe_to_float(rgbe), expected)  # powers of two: exact


# --- 2. peer checks with Radiance -------------------------------------------------------------


@pytest.mark.parametrize("cols", WIDTHS)
def test_pvalue_reads_our_file(tmp_path, radiance, cols):
    rows = max(4, 2400 // cols)
    truth = log_spaced_map(rows, cols, nan_every=61)
    path = tmp_path / "ours.hdr"
    write_hdr(LuminanceMap(truth), path)
    ours = read_hdr(path).luminance
    theirs = pvalue_luminance(radiance, path, rows, cols)
    # Grey pixels: the brightness is independent of the weight set (both sum to 1).
    np.testing.assert_allclose(ours, theirs, rtol=SAME_BYTES_RTOL, atol=0)
    nan = np.isnan(truth)
    assert np.all(theirs[nan] == 0.0)
    assert relative(theirs[~nan], truth[~nan]).max() <= RGBE_BOUND
    rgb = pvalue_rgb(radiance, path, rows, cols)
    assert np.all(rgb[..., 0] == rgb[..., 1]) and np.all(rgb[..., 1] == rgb[..., 2])  # grey


def test_getinfo_shows_our_view_and_resolution(tmp_path, radiance):
    projection = PinholeProjection(300.0, 310.0, 140.25, 97.0, 320, 200)
    path = tmp_path / "view.hdr"
    write_hdr(LuminanceMap(np.ones((200, 320)), projection=projection), path)
    header = radiance("getinfo", path).decode()
    lines = [line.strip() for line in header.splitlines()]
    assert f"VIEW= {projection.radiance_view()}" in lines
    assert "FORMAT=32-bit_rle_rgbe" in header
    resolution = radiance("getinfo", "-d", path).decode().split(":", 1)[1].split()
    assert resolution == ["-Y", "200", "+X", "320"]


def test_vwrays_rays_of_our_picture_match_directions(tmp_path, radiance):
    """vwrays reads our VIEW= line and resolution and traces every pixel; Radiance world =
    (x_cam, z_cam, −y_cam) for -vd 0 1 0 -vu 0 0 1, scanlines from the top as our rows."""
    rows, cols = 9, 13
    projection = PinholeProjection(11.0, 9.0, 4.3, 5.6, cols, rows)  # off-centre, fx ≠ fy
    path = tmp_path / "view.hdr"
    write_hdr(LuminanceMap(np.ones((rows, cols)), projection=projection), path)
    rays = np.frombuffer(radiance("vwrays", "-fd", path), np.float64).reshape(rows, cols, 6)
    r, c = np.mgrid[0:rows, 0:cols]
    d = projection.directions(r, c)
    expected = np.stack([d[..., 0], d[..., 2], -d[..., 1]], axis=-1)
    assert np.all(rays[..., :3] == 0.0)  # -vp 0 0 0
    # View angles are written with 17 significant digits; a half-pixel convention error
    # would be ≈ 0.5/fx ≈ 0.05.
    np.testing.assert_allclose(rays[..., 3:], expected, rtol=0, atol=1e-6)


# --- Radiance-written pictures -----------------------------------------------------------------


def _scene(rows, cols, seed=3):
    """Coloured scene with long constant stretches (so that Radiance's RLE writes runs)."""
    rng = np.random.default_rng(seed)
    rgb = rng.uniform(0.0, 1.0, (rows, cols, 3)) * np.logspace(-2, 6, cols)[None, :, None]
    rgb[:, cols // 8 : cols // 2] = [0.3, 0.5, 0.2]
    rgb[1, :] = 0.0
    return rgb.astype(np.float32)


#: name: (Radiance filters after pvalue -r, expected EXPOSURE product, error factor).
#: Error factor: each encoding errs by ≤ 2⁻⁸ of the pixel's largest component (shared
#: exponent), so n encodings by ≤ n·2⁻⁸. With per-channel factors k_i (COLORCORR) the
#: re-encoding errs by 2⁻⁸·max(k)·peak, which undoing k_i turns into 2⁻⁸·(max k/k_i)·peak:
#: 1 + 2/0.5 = 5 for -er 2 -eg 1 -eb 0.5.
FILTERS = {
    "none": ((), 1.0, 1),
    "exposure2": ((("pfilt", "-1", "-e", 2),), 2.0, 2),
    "exposure2x3": ((("pfilt", "-1", "-e", 2), ("pfilt", "-1", "-e", 3)), 6.0, 3),
    "colorcorr": ((("pfilt", "-1", "-er", 2, "-eg", 1, "-eb", 0.5),), None, 5),
}


@pytest.mark.parametrize("cols", [5, 300])
@pytest.mark.parametrize("name", FILTERS)
def test_read_radiance_written_pictures(tmp_path, radiance, cols, name):
    filters, exposure, factor = FILTERS[name]
    rows = 6
    scene = _scene(rows, cols)
    data = radiance_picture(radiance, scene, *filters)
    path = tmp_path / f"{name}.hdr"
    path.write_bytes(data)
    pixels = scanline_bytes(data)
    if cols == 300:  # new-style RLE scanlines with at least one run (code > 128)
        assert pixels[:4] == bytes([2, 2, cols >> 8, cols & 0xFF])
        assert len(pixels) < rows * cols * 4
    else:
        assert len(pixels) == rows * cols * 4  # flat pixels below the RLE minimum width

    rgb, header = read_hdr_rgb(path)
    reference = pvalue_rgb(radiance, path, rows, cols)
    np.testing.assert_allclose(rgb, reference, rtol=SAME_BYTES_RTOL, atol=0)
    if exposure is not None:
        assert header["exposure"] == pytest.approx(exposure, rel=1e-4)  # EXPOSURE=2.0000e+00
    else:
        assert header["exposure"] != 1.0 and not np.all(header["colorcorr"] == 1.0)
    # Luminance with the package's weights from Radiance's RGB decoding of the same bytes.
    luminance = read_hdr(path).luminance
    np.testing.assert_allclose(luminance, 179.0 * reference @ W_PACKAGE, rtol=SAME_BYTES_RTOL, atol=0)
    # Exposure undone: back at the scene within the quantisations (FILTERS), relative to
    # each pixel's largest component; pfilt writes EXPOSURE= with 5 and COLORCORR= with 6
    # significant digits while scaling by the exact values: ≤ 1e-4 relative more.
    peak = scene.max(axis=-1, keepdims=True).astype(float)
    ok = peak[..., 0] > 0
    assert np.all(np.abs(rgb - scene)[ok] <= (factor * RGBE_BOUND + 1e-4) * peak[ok])
    assert np.all(rgb[~ok] == 0.0)


def test_pvalue_brightness_differs_only_by_the_weight_set(tmp_path, radiance):
    """Radiance 6 computes its weights from the exact white point; the package keeps the
    Radiance 5 constants. On coloured pixels the two luminances differ by at most
    179·Σ|Δw_i|·rgb_i (≤ 3.5e-4 relative); on grey pixels not at all."""
    rows, cols = 6, 300
    path = tmp_path / "colour.hdr"
    path.write_bytes(radiance_picture(radiance, _scene(rows, cols)))
    rgb = pvalue_rgb(radiance, path, rows, cols)
    theirs = pvalue_luminance(radiance, path, rows, cols)
    np.testing.assert_allclose(theirs, 179.0 * rgb @ W_RADIANCE6, rtol=SAME_BYTES_RTOL, atol=0)
    ours = read_hdr(path).luminance.astype(np.float64)
    bound = 179.0 * rgb @ np.abs(W_PACKAGE - W_RADIANCE6) + SAME_BYTES_RTOL * theirs
    assert np.all(np.abs(ours - theirs) <= bound)
    # The package constants are those weights rounded to 6 decimals.
    np.testing.assert_allclose(W_PACKAGE, _weights_from_primaries((0.3333, 0.3333)), rtol=0, atol=5e-7)


def test_reads_radiance_padded_resolution_line(tmp_path, radiance):
    data = radiance_picture(radiance, _scene(5, 300))
    if b"-Y        5 +X      300\n" not in data:  # as Radiance 6 writes it ("%8d")
        pytest.skip("this Radiance does not pad its resolution line")
    path = tmp_path / "padded.hdr"
    path.write_bytes(data)
    np.testing.assert_allclose(read_hdr_rgb(path)[0], pvalue_rgb(radiance, path, 5, 300), rtol=SAME_BYTES_RTOL)


def test_old_style_runs_match_pvalue(tmp_path, radiance):
    """Old-format run-length pixels (1,1,1,n); consecutive runs count in base 256."""
    cols = 302
    pixel_a, pixel_b, pixel_c = bytes([200, 100, 50, 130]), bytes([1, 2, 3, 140]), bytes([128, 128, 128, 120])
    row1 = pixel_a + bytes([1, 1, 1, 44]) + bytes([1, 1, 1, 1]) + pixel_b  # 1 + 44 + 256 + 1
    row2 = pixel_c * 2 + bytes([1, 1, 1, 255]) + pixel_a * 45  # 2 + 255 + 45
    data = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 302\n" + row1 + row2
    path = tmp_path / "old.hdr"
    path.write_bytes(data)
    rgb, _ = read_hdr_rgb(path)
    reference = pvalue_rgb(radiance, path, 2, cols)
    np.testing.assert_allclose(rgb, reference, rtol=SAME_BYTES_RTOL, atol=0)
    assert np.all(rgb[0, :301] == rgb[0, 0]) and np.all(rgb[1, 2:257] == rgb[1, 0])


def test_foreign_vtv_view_gives_projection(tmp_path, radiance):
    """A VIEW= line added by getinfo -a to a Radiance picture: the projection we build from
    it traces the same rays as vwrays does from the same file."""
    rows, cols = 6, 300
    data = radiance_picture(radiance, _scene(rows, cols))
    source = tmp_path / "plain.hdr"
    source.write_bytes(data)
    view = "-vtv -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 70 -vv 3 -vs 0.1 -vl -0.2"
    path = tmp_path / "view.hdr"
    path.write_bytes(radiance("getinfo", "-a", f"VIEW= {view}", stdin=source.read_bytes()))
    lmap = read_hdr(path)
    assert isinstance(lmap.projection, PinholeProjection)
    assert lmap.provenance["radiance_view"].split() == view.split()
    rays = np.frombuffer(radiance("vwrays", "-fd", path), np.float64).reshape(rows, cols, 6)
    r, c = np.mgrid[0:rows, 0:cols]
    d = lmap.projection.directions(r, c)
    # Exact view values here, so only double rounding: 1e-9 is ample.
    np.testing.assert_allclose(rays[..., 3:], np.stack([d[..., 0], d[..., 2], -d[..., 1]], -1), atol=1e-9)


# --- 3. real Radiance rendering ------------------------------------------------------------


@pytest.fixture(scope="module")
def desk():
    return realdata("hdr/raytraverse_rendered_desk_vta.hdr")


@pytest.mark.realdata
def test_real_rendering_matches_pvalue(desk, radiance):
    lmap = read_hdr(desk)
    rows, cols = lmap.shape
    assert (rows, cols) == (1000, 1000)
    rgb, header = read_hdr_rgb(desk)
    reference = pvalue_rgb(radiance, desk, rows, cols)
    np.testing.assert_allclose(rgb, reference, rtol=SAME_BYTES_RTOL, atol=0)  # measured 1.2e-7
    expected = 179.0 * reference @ W_PACKAGE
    np.testing.assert_allclose(lmap.luminance, expected, rtol=SAME_BYTES_RTOL, atol=0)
    assert header["exposure"] == pytest.approx(0.1343958, rel=1e-12)
    # -vta gives the ideal equidistant fisheye; its pixel directions must be Radiance's.
    view = lmap.provenance["radiance_view"]
    assert "-vta" in view and lmap.projection.kind == "equidistant"
    pick_rows = np.array([500, 0, 250, 999, 700])
    pick_cols = np.array([500, 500, 250, 500, 120])
    positions = "".join(f"{c} {rows - 1 - r}\n" for r, c in zip(pick_rows, pick_cols)).encode()
    out = radiance("vwrays", "-i", "-fd", "-x", cols, "-y", rows, "-pa", 0, *view.split(), stdin=positions)
    rays = np.frombuffer(out, np.float64).reshape(len(pick_rows), 6)
    d = lmap.projection.directions(pick_rows, pick_cols)
    v, up = np.array(parse_view(view)["vd"]), np.array(parse_view(view).get("vu", [0, 0, 1]))
    v /= np.linalg.norm(v)
    right = np.cross(v, up)
    right /= np.linalg.norm(right)
    world = d[:, :1] * right + d[:, 2:] * v - d[:, 1:2] * np.cross(right, v)
    # Both evaluate the same closed form in doubles from the same header numbers.
    np.testing.assert_allclose(rays[:, 3:], world, atol=1e-9)
    # Peak: README says ≈ 7e7 "after EXPOSURE is divided out", but that is the value with
    # the exposure still applied (pvalue without -o); divided out it is ≈ 5.2e8 cd/m².
    peak = float(np.max(lmap.luminance))
    assert peak == pytest.approx(float(np.max(expected)), rel=SAME_BYTES_RTOL)
    assert peak * header["exposure"] == pytest.approx(7e7, rel=0.01)
    as_stored = 179.0 * np.frombuffer(radiance("pvalue", "-h", "-H", "-b", "-dd", desk), np.float64)
    assert as_stored.max() == pytest.approx(7e7, rel=0.01)


# --- 5. bad input -----------------------------------------------------------------------------


def _good_bytes(tmp_path, rows=4, cols=20):
    path = tmp_path / "good.hdr"
    write_hdr(LuminanceMap(np.linspace(1, 100, rows * cols).reshape(rows, cols)), path)
    return path.read_bytes()


@pytest.mark.parametrize(
    "make, error",
    [
        (lambda good: b"", BadInputError),
        (lambda good: b"\x89PNG\r\n\x1a\n" + bytes(200), UnsupportedFileError),
        (lambda good: b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n", UnsupportedFileError),  # no header end
        (lambda good: b"#?RADIANCE\n\n", UnsupportedFileError),  # no resolution line
        (lambda good: good.replace(b"-Y 4 +X 20", b"+X 20 -Y 4"), UnsupportedFileError),
        (lambda good: good.replace(b"-Y 4 +X 20", b"-Y 4 -X 20"), UnsupportedFileError),
        (lambda good: good.replace(b"-Y 4 +X 20", b"-Y four +X 20"), UnsupportedFileError),
        (lambda good: good[: len(good) - 37], UnsupportedFileError),  # truncated scanline
        (lambda good: good[: good.index(b"+X 20\n") + 6 + 2], UnsupportedFileError),
        (lambda good: good.replace(b"FORMAT=32-bit_rle_rgbe", b"FORMAT=32-bit_rle_xyze"), UnsupportedFileError),
        (lambda good: good.replace(b"FORMAT=", b"EXPOSURE=abc\nFORMAT="), UnsupportedFileError),
        (lambda good: good.replace(b"FORMAT=", b"EXPOSURE=0\nFORMAT="), UnsupportedFileError),
        (lambda good: good.replace(b"-Y 4 +X 20\n\x02\x02\x00\x14", b"-Y 4 +X 20\n\x02\x02\x00\x13"),
         UnsupportedFileError),  # scanline length ≠ width
    ],
    ids=["empty", "png", "no-header-end", "no-resolution", "transposed", "flipped-x", "non-numeric",
         "truncated", "truncated-early", "xyze", "bad-exposure", "zero-exposure", "length-mismatch"],
)
def test_bad_hdr_raises(tmp_path, make, error):
    data = make(_good_bytes(tmp_path))
    path = tmp_path / "bad.hdr"
    path.write_bytes(data)
    with pytest.raises(error) as info:
        read_hdr(path)
    assert "\n" not in str(info.value)  # one-line message for the command line


def test_missing_hdr_raises(tmp_path):
    with pytest.raises(BadInputError, match="does not exist"):
        read_hdr(tmp_path / "absent.hdr")


def test_failed_hdr_write_leaves_nothing(tmp_path, monkeypatch):
    """A failure after the header is written: no temporary file, the old target intact."""
    import lsadphoto.io.hdr as hdr

    target = tmp_path / "out.hdr"
    target.write_bytes(b"previous contents")

    def boom(rgbe):
        raise RuntimeError("disk full")

    monkeypatch.setattr(hdr, "_encode_scanlines", boom)
    with pytest.raises(RuntimeError, match="disk full"):
        write_hdr(LuminanceMap(np.ones((3, 20))), target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.hdr"]
    assert target.read_bytes() == b"previous contents"


def test_write_into_new_directory(tmp_path):
    target = tmp_path / "new" / "deeper" / "map.hdr"
    write_hdr(LuminanceMap(np.full((2, 3), 5.0)), target)
    assert [p.name for p in target.parent.iterdir()] == ["map.hdr"]
    np.testing.assert_allclose(read_hdr(target).luminance, 5.0, rtol=RGBE_BOUND)


# --- 7. VIEW round trip -----------------------------------------------------------------------

CAMERAS = {
    "centred": PinholeProjection(3590.649, 3590.649, 2303.5, 1535.5, 4608, 3072),
    "off-centre": PinholeProjection(3612.25, 3598.5, 2290.125, 1551.75, 4608, 3072),
    "wide": PinholeProjection(300.0, 280.0, 700.0, -20.0, 1000, 700),  # 118° × 103°, pp outside
    "tiny": PinholeProjection(1.5, 2.0, 0.0, 0.0, 1, 1),
}


@pytest.mark.parametrize("name", CAMERAS)
def test_view_round_trip(name):
    cam = CAMERAS[name]
    view = parse_view(cam.radiance_view())
    assert view["type"] == "v" and view["vd"] == [0.0, 1.0, 0.0] and view["vu"] == [0.0, 0.0, 1.0]
    back = PinholeProjection.from_radiance_view(view, cam.width, cam.height)
    # radiance_view prints 17 significant digits (exact for doubles), so only the rounding
    # of atan/tan/degrees remains: a few ulps, amplified by 1/(sin θ cos θ) ≤ 4 here.
    assert back.fx == pytest.approx(cam.fx, rel=1e-12)
    assert back.fy == pytest.approx(cam.fy, rel=1e-12)
    assert back.cx == pytest.approx(cam.cx, abs=1e-12 * cam.width)
    assert back.cy == pytest.approx(cam.cy, abs=1e-12 * cam.height)
    assert (back.width, back.height) == (cam.width, cam.height)


@pytest.mark.parametrize("name", CAMERAS)
def test_view_matches_vwrays(radiance, name):
    """Directions of a few pixels: vwrays with our view options vs PinholeProjection."""
    cam = CAMERAS[name]
    rows = np.array([0, cam.height - 1, cam.height // 2, cam.height // 3])
    cols = np.array([0, cam.width - 1, cam.width // 3, cam.width // 2])
    # vwrays -i reads pixel positions "x y" as text (y counted from the bottom; integer x
    # means the centre (x + ½)/X, as our integer columns); -fd writes doubles; -pa 0 keeps
    # the resolution rather than fitting it to the view's pixel aspect.
    positions = "".join(f"{c} {cam.height - 1 - r}\n" for r, c in zip(rows, cols)).encode()
    out = radiance("vwrays", "-i", "-fd", "-x", cam.width, "-y", cam.height, "-pa", 0,
                   *cam.radiance_view().split(), stdin=positions)
    rays = np.frombuffer(out, np.float64).reshape(len(rows), 6)
    d = cam.directions(rows, cols)
    expected = np.stack([d[..., 0], d[..., 2], -d[..., 1]], axis=-1)
    # Radiance computes in doubles from our 17-digit view; a half-pixel convention error
    # would be ≥ 0.5/fx ≈ 1.4e-4 for the 4608-px cameras.
    np.testing.assert_allclose(rays[:, 3:], expected, rtol=0, atol=1e-6)


def test_parse_view_options():
    view = parse_view("-vth -vp 1 2 3 -vd 0 0 -1 -vh 180 -vv 180 -vo 0.5 -va 10 -vs 0 -vl 0 -x 5 junk")
    assert view == {"type": "h", "vp": [1.0, 2.0, 3.0], "vd": [0.0, 0.0, -1.0], "vh": 180.0, "vv": 180.0,
                    "vo": 0.5, "va": 10.0, "vs": 0.0, "vl": 0.0}
    assert parse_view("") == {"type": "v"}
    with pytest.raises(UnsupportedFileError):
        parse_view("-vtv -vh wide")
    with pytest.raises(UnsupportedFileError):
        parse_view("-vtv -vp 1 2")


def test_fisheye_projection_round_trips_and_equisolid_has_no_view(tmp_path):
    from lsadphoto.geometry import IdealFisheyeProjection

    for kind, has_view in (("equidistant", True), ("equisolid", False)):
        projection = IdealFisheyeProjection(kind, 31.5, 31.5, 32.0, 180.0, 64, 64)
        path = tmp_path / f"{kind}.hdr"
        write_hdr(LuminanceMap(np.ones((64, 64)), projection=projection), path)
        assert (b"VIEW=" in path.read_bytes()) == has_view  # Radiance has no equisolid view type
        assert read_hdr(path).projection == projection
