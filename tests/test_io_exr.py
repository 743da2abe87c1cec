"""OpenEXR luminance maps: exact float32 round trip, metadata, foreign files, bad files.

Independent references: the OpenEXR binding itself (reading and writing channels and
attributes directly) and the Rec. 709 luminance weights of ITU-R BT.709-6 (0.2126, 0.7152,
0.0722), OpenEXR's default chromaticities.
"""

import json
from types import SimpleNamespace

import numpy as np
import OpenEXR
import pytest

import lsadphoto.io.exr as exr_module
from lsadphoto.errors import BadInputError, UnsupportedFileError
from lsadphoto.geometry.pinhole import PinholeProjection
from lsadphoto.io.exr import read_exr, write_exr
from lsadphoto.luminance_map import LuminanceMap

from .conftest import realdata

BT709 = np.array([0.2126, 0.7152, 0.0722])
#: A weighted sum done in float64 and stored as float32 is off by ≤ ½ ulp of float32
#: (2⁻²⁴ ≈ 6e-8 relative) plus float64 rounding (1e-16); 2e-7 leaves a margin of 3.
FLOAT32_RTOL = 2e-7


def _plain_header(**extra):
    return {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, **extra}


def _luminance(rows=40, cols=30):
    values = np.logspace(-3.0, 9.0, rows * cols).reshape(rows, cols).astype(np.float32)
    values[0, 0] = 0.0
    values[3, 4] = np.nan
    values[-1, :5] = np.nan
    return values


def test_round_trip_is_exact(tmp_path):
    luminance = _luminance()
    uncertainty = (0.05 * luminance).astype(np.float32)
    uncertainty[5, 5] = np.nan
    projection = PinholeProjection(35.25, 36.0, 14.75, 20.125, 30, 40)
    provenance = {
        "source": ["IMG_0001.CR3", "IMG_0002.CR3"],
        "exposure": {"times": [1 / 125, 1 / 30], "iso": 100, "f_number": 4.0},
        "note": "Büro, 3. OG — lamp on\nsecond line",
        "nested": {"empty": {}, "none": None, "flag": True},
    }
    lmap = LuminanceMap(
        luminance,
        uncertainty=uncertainty,
        projection=projection,
        line_of_sight=[0.0, 0.0, 1.0],
        calibration_factor=0.1 + 0.2,  # 0.30000000000000004: not representable as float32
        calibration_uncertainty=0.0375,
        calibrated=True,
        provenance=provenance,
    )
    path = tmp_path / "map.exr"
    write_exr(lmap, path)
    back = read_exr(path)

    # float32 in, float32 out: bit-exact, NaN where NaN (ZIP is lossless).
    assert back.luminance.dtype == np.float32
    np.testing.assert_array_equal(back.luminance, luminance)
    np.testing.assert_array_equal(back.uncertainty, uncertainty)
    assert back.projection == projection
    assert back.calibration_factor == 0.1 + 0.2 and type(back.calibration_factor) is float
    assert back.calibration_uncertainty == 0.0375
    assert back.calibrated is True
    assert back.provenance == provenance
    np.testing.assert_array_equal(back.line_of_sight, [0.0, 0.0, 1.0])

    # The file as other readers see it: float32 channels Y and Y.uncertainty, attributes.
    f = OpenEXR.File(str(path), separate_channels=True)
    channels = f.channels()
    assert set(channels) == {"Y", "Y.uncertainty"}
    assert channels["Y"].pixels.dtype == np.float32
    np.testing.assert_array_equal(channels["Y"].pixels, luminance)
    header = f.header()
    assert header["lsadphoto.unit"] == "cd/m2"
    assert header["lsadphoto.calibrated"] == "yes"
    assert json.loads(header["lsadphoto.metadata"])["calibration_factor"] == 0.1 + 0.2


def test_round_trip_without_uncertainty_uncalibrated(tmp_path):
    lmap = LuminanceMap(np.full((3, 4), 7.5), calibration_factor=12.5)
    path = tmp_path / "plain.exr"
    write_exr(lmap, path)
    back = read_exr(path)
    assert back.uncertainty is None
    assert back.projection is None and back.line_of_sight is None
    assert back.calibrated is False and back.calibration_factor == 12.5
    assert back.provenance == {}
    np.testing.assert_array_equal(back.luminance, np.full((3, 4), 7.5, np.float32))
    f = OpenEXR.File(str(path))
    assert set(f.channels()) == {"Y"}
    assert f.header()["lsadphoto.calibrated"] == "uncalibrated"


def test_write_into_new_directory(tmp_path):
    target = tmp_path / "a" / "b" / "map.exr"
    write_exr(LuminanceMap(np.ones((2, 2))), target)
    assert [p.name for p in target.parent.iterdir()] == ["map.exr"]
    np.testing.assert_array_equal(read_exr(target).luminance, np.ones((2, 2), np.float32))


# --- foreign files --------------------------------------------------------------------------


def test_foreign_rgb_exr_uses_rec709(tmp_path):
    rng = np.random.default_rng(4)
    rgb = (rng.uniform(-0.6, 1.0, (20, 30, 3)) * np.logspace(-2, 4, 30)[None, :, None]).astype(np.float32)
    path = tmp_path / "rgb.exr"
    # Contiguous copies: the binding (3.5.3) ignores strides and would write rgb[..., 0]
    # as interleaved garbage.
    channels = {c: np.ascontiguousarray(rgb[..., i]) for i, c in enumerate("RGB")}
    OpenEXR.File(_plain_header(), channels).write(str(path))
    lmap = read_exr(path)
    reference = rgb.astype(np.float64) @ BT709
    negative = reference < 0
    assert negative.any() and (~negative).any()
    assert np.all(np.isnan(lmap.luminance[negative]))  # not luminances: unknown
    np.testing.assert_allclose(lmap.luminance[~negative], reference[~negative], rtol=FLOAT32_RTOL, atol=0)
    assert lmap.calibrated is False
    assert "foreign" in lmap.provenance["note"]


def test_foreign_half_y_exr(tmp_path):
    y = np.linspace(0, 60000, 12, dtype=np.float16).reshape(3, 4)
    path = tmp_path / "y.exr"
    OpenEXR.File(_plain_header(), {"Y": y}).write(str(path))
    lmap = read_exr(path)
    np.testing.assert_array_equal(lmap.luminance, y.astype(np.float32))  # half → float32 is exact
    assert lmap.uncertainty is None


@pytest.mark.realdata
def test_real_desk_exr():
    path = realdata("hdr/openexr_Desk.exr")
    lmap = read_exr(path)
    pixels = OpenEXR.File(str(path)).channels()["RGBA"].pixels  # half-float R, G, B, A
    reference = pixels[..., :3].astype(np.float64) @ BT709
    assert lmap.shape == reference.shape == (874, 644)
    valid = np.isfinite(lmap.luminance)
    # Finite and non-negative wherever known; the photo has slightly negative G/B values
    # (colour-transformed HDR), and exactly the pixels with a negative Rec. 709 sum are NaN
    # (4837 of 562856, 0.86 %).
    assert not np.any(np.isinf(lmap.luminance))
    assert np.all(lmap.luminance[valid] >= 0)
    np.testing.assert_array_equal(~valid, reference < 0)
    assert lmap.valid_fraction > 0.99
    np.testing.assert_allclose(lmap.luminance[valid], reference[valid], rtol=FLOAT32_RTOL, atol=0)
    assert 100 < np.nanmax(lmap.luminance) < 300  # relative scale; the lamp peaks at ≈ 202
    assert lmap.calibrated is False


# --- bad files --------------------------------------------------------------------------------


@pytest.fixture
def good_exr_bytes(tmp_path):
    path = tmp_path / "good.exr"
    write_exr(LuminanceMap(_luminance(200, 300), uncertainty=np.ones((200, 300))), path)
    return path.read_bytes()


def _zeroed_middle(data):
    b = bytearray(data)
    mid = len(b) // 2
    b[mid : mid + 2000] = bytes(2000)
    return bytes(b)


@pytest.mark.parametrize(
    "make, error",
    [
        (lambda good: b"", BadInputError),
        (lambda good: b"this is not an OpenEXR file\n" * 10, UnsupportedFileError),
        (lambda good: b"\x76\x2f\x31\x01" + bytes(100), UnsupportedFileError),  # magic, no header
        (lambda good: good[:20], UnsupportedFileError),
        (lambda good: good[:400], UnsupportedFileError),  # inside the header
        (lambda good: good[: len(good) // 2], UnsupportedFileError),
        (lambda good: good[:-10], UnsupportedFileError),
        (_zeroed_middle, UnsupportedFileError),
    ],
    ids=["empty", "text", "magic-only", "truncated-20", "truncated-header", "truncated-half",
         "truncated-end", "zeroed-chunks"],
)
def test_bad_exr_raises(tmp_path, good_exr_bytes, make, error):
    path = tmp_path / "bad.exr"
    path.write_bytes(make(good_exr_bytes))
    with pytest.raises(error) as info:
        read_exr(path)
    assert "\n" not in str(info.value)  # one line for the command line


def test_exr_without_luminance_channels(tmp_path):
    path = tmp_path / "z.exr"
    OpenEXR.File(_plain_header(), {"Z": np.ones((2, 3), np.float32)}).write(str(path))
    with pytest.raises(UnsupportedFileError, match="no Y or R,G,B"):
        read_exr(path)


@pytest.mark.parametrize("text", ["{not json", json.dumps({"schema": "someone-else/7"}), "[1, 2]"])
def test_exr_with_bad_metadata(tmp_path, text):
    path = tmp_path / "meta.exr"
    OpenEXR.File(_plain_header(**{"lsadphoto.metadata": text}), {"Y": np.ones((2, 3), np.float32)}).write(str(path))
    with pytest.raises(UnsupportedFileError, match="metadata"):
        read_exr(path)


def test_missing_exr(tmp_path):
    with pytest.raises(BadInputError, match="does not exist"):
        read_exr(tmp_path / "absent.exr")


# --- atomic writes ------------------------------------------------------------------------------


def test_invalid_map_leaves_directory_unchanged(tmp_path):
    """The writer fails inside the atomic block (channels of different shapes): no
    temporary file remains and an existing target is untouched."""
    target = tmp_path / "out.exr"
    target.write_bytes(b"previous")
    bad = SimpleNamespace(
        luminance=np.ones((4, 5), np.float32), uncertainty=np.ones((3, 5), np.float32), projection=None,
        line_of_sight=None, calibration_factor=1.0, calibration_uncertainty=0.0, calibrated=False, provenance={},
    )
    with pytest.raises(ValueError):
        write_exr(bad, target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.exr"]
    assert target.read_bytes() == b"previous"


def test_failure_mid_write_leaves_directory_unchanged(tmp_path, monkeypatch):
    """The EXR library writes part of the file and then fails."""

    class HalfWriter:
        def __init__(self, header, channels):
            pass

        def write(self, name):
            with open(name, "wb") as fh:
                fh.write(b"\x76\x2f\x31\x01partial")
            raise OSError("disk full")

    monkeypatch.setattr(exr_module.OpenEXR, "File", HalfWriter)
    target = tmp_path / "out.exr"
    target.write_bytes(b"previous")
    with pytest.raises(OSError, match="disk full"):
        write_exr(LuminanceMap(np.ones((2, 2))), target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.exr"]
    assert target.read_bytes() == b"previous"
