"""RAW integrity: truncated or damaged files are refused in one line; levels of real files."""

import struct
import subprocess
import sys

import exifread
import numpy as np
import pytest

from lsadphoto.errors import UnsupportedFileError
from lsadphoto.raw import decode_raw
from lsadphoto.raw.integrity import declared_extent

from .conftest import interior_scene, raw_samples, realdata, refused_raw_samples

SAMPLES = raw_samples()
REFUSED = refused_raw_samples()
#: The real Canon DNG's exposure fields are empty; the decoder says so with a MetadataWarning
#: (tested in test_decode.py). Here only its levels and its integrity matter.
EMPTY_EXPOSURE = pytest.mark.filterwarnings("ignore::lsadphoto.errors.MetadataWarning")
#: The issue's cuts: 1 MB, 50 %, 90 %, 99 % of the file.
CUTS = ("1MB", 0.5, 0.9, 0.99)


def _cut(source, tmp_path, cut):
    data = source.read_bytes()
    n = 1_000_000 if cut == "1MB" else int(cut * len(data))
    if n >= len(data):
        pytest.skip(f"{source.name} is not larger than {cut}")
    path = tmp_path / f"cut{source.suffix}"
    path.write_bytes(data[:n])
    return path


def _refusal(path, tmp_path, spot="100,100,50"):
    """The one stderr line of ``lsadphoto luminance PATH`` run as a user runs it, after checking
    that it exited with 2 and wrote no map."""
    out = tmp_path / "map.exr"
    run = subprocess.run([sys.executable, "-m", "lsadphoto.cli", "luminance", str(path), "--spot",
                          spot, "-o", str(out)], capture_output=True, text=True)
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and not out.exists(), run.stderr
    return lines[0]


def _sample_ids():
    return [p.name for p in SAMPLES]


@pytest.mark.parametrize("cut", CUTS)
@pytest.mark.parametrize("source", ["realdata", "data_samples"])
def test_truncated_dng_refused_in_one_line(tmp_path, source, cut):
    """The CLI's luminance command refuses each cut of a real DNG (Canon 550D, tinydng) and of
    the project's own sample DNG with exit 2 and one line, and writes nothing."""
    from pathlib import Path

    full = (realdata("raw/tinydng_colorchart.dng") if source == "realdata"
            else Path(__file__).parents[1] / "data_samples" / "office" / "office_1.dng")
    line = _refusal(_cut(full, tmp_path, cut), tmp_path)
    assert "truncated" in line and "bytes missing" in line, line


@pytest.mark.skipif(not SAMPLES, reason="no real RAW samples (../shared/realdata/raw, LSADPHOTO_RAW_SAMPLES)")
@pytest.mark.parametrize("cut", CUTS)
@pytest.mark.parametrize("source", SAMPLES, ids=_sample_ids())
def test_every_real_sample_refused_when_cut(tmp_path, source, cut):
    path = _cut(source, tmp_path, cut)
    with pytest.raises(UnsupportedFileError, match="truncated|damaged|corrupt|not a readable"):
        decode_raw(path)


def test_libraw_report_refuses_a_file_whose_tags_lie(tmp_path):
    """A DNG cut at 50 % whose StripByteCounts is rewritten to the shorter length passes the
    extent check; LibRaw then runs out of data and says so, and that report refuses it."""
    import tifffile

    source = realdata("raw/tinydng_colorchart.dng")
    data = bytearray(source.read_bytes())
    half = len(data) // 2
    with tifffile.TiffFile(source) as tif:
        page = tif.pages[0]
        counts, offsets = page.tags[279], page.tags[273]
        order = tif.byteorder
        assert counts.count == 1 and counts.dtype == 4  # one LONG, stored in the entry
        data[counts.valueoffset:counts.valueoffset + 4] = struct.pack(order + "I", half - offsets.value[0])
    path = tmp_path / "lying.dng"
    path.write_bytes(bytes(data[:half]))
    end, _ = declared_extent(path)
    assert end == half  # the structure alone no longer shows the damage
    with pytest.raises(UnsupportedFileError, match="LibRaw reports 'Unexpected end of file'"):
        decode_raw(path)


def _rewrite_raw_ifd(tmp_path, name, tag, value):
    """The real Canon DNG with one SHORT/LONG entry of its raw IFD (IFD 0) rewritten in place."""
    import tifffile

    source = realdata("raw/tinydng_colorchart.dng")
    data = bytearray(source.read_bytes())
    with tifffile.TiffFile(source) as tif:
        entry = tif.pages[0].tags[tag]
        assert entry.count == 1 and tif.pages[0].photometric == 32803  # one value, stored in the entry
        data[entry.valueoffset:entry.valueoffset + (2 if entry.dtype == 3 else 4)] = struct.pack(
            tif.byteorder + ("H" if entry.dtype == 3 else "I"), value)
    path = tmp_path / name
    path.write_bytes(bytes(data))
    return path


def test_metadata_only_copy_refused_in_one_line(tmp_path):
    """The real Canon DNG with its raw strip declared 22 bytes long, as ExifTool's test copy of
    a Canon DNG declares its raw tiles (the file keeps its full length, so no declared extent
    is short): LibRaw would decode it, the raw data check refuses it (exit 2, one line, nothing
    written). 1888 × 1182 samples need at least 278 952 bytes at one bit each."""
    line = _refusal(_rewrite_raw_ifd(tmp_path, "stripped.dng", 279, 22), tmp_path)
    assert "no image data" in line and "declares 22 bytes" in line and "(278952 bytes)" in line, line


@EMPTY_EXPOSURE
def test_coding_libraw_cannot_unpack_is_named():
    """A raw IFD coded with JPEG XL (DNG 1.7, compression 52546; the real Canon DNG relabelled)
    is refused naming the coding and LibRaw's version, not as 'corrupt or truncated'."""
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as folder:
        path = _rewrite_raw_ifd(Path(folder), "jxl.dng", 259, 52546)
        with pytest.raises(UnsupportedFileError, match=r"LibRaw [0-9.]+ cannot unpack its raw data \(JPEG XL \(DNG 1\.7\)\)"):
            decode_raw(path)


@pytest.mark.skipif(not REFUSED, reason="no refused real RAW samples (a 'refused' folder in LSADPHOTO_RAW_SAMPLES)")
@pytest.mark.parametrize("source", REFUSED, ids=[p.name for p in REFUSED])
def test_refused_real_samples_refused_in_one_line(tmp_path, source):
    """Real RAW-named files that hold no usable image (ExifTool's, exiv2's and hachoir's test
    copies with the data stripped; a JPEG XL DNG of Adobe's DNG SDK) are refused by the CLI:
    exit 2, one line naming the file, nothing written."""
    line = _refusal(source, tmp_path, spot="10,10,50")
    assert str(source) in line, line


def test_repeated_bottom_rows_refused(camera, shoot, tmp_path):
    """Rows filled with copies of the last good one (what LibRaw leaves in a cut compressed
    file) are refused; the same scene with its real bottom rows decodes."""
    from lsadphoto.datasets import write_dng

    truth = interior_scene((camera.height, camera.width))
    raw = camera.expose(truth, exposure_time=1 / 125, f_number=4.0, iso=100, noise=True,
                        rng=np.random.default_rng(1))
    good = write_dng(tmp_path / "good.dng", raw, camera, exposure_time=1 / 125, f_number=4.0, iso=100)
    decode_raw(good)
    filled = raw.copy()
    filled[-40:] = filled[-41]
    bad = write_dng(tmp_path / "filled.dng", filled, camera, exposure_time=1 / 125, f_number=4.0, iso=100)
    with pytest.raises(UnsupportedFileError, match="last 41 raw rows are copies"):
        decode_raw(bad)


def _exif_levels(path):
    with open(path, "rb") as fh:
        tags = exifread.process_file(fh, details=True)
    found = {}
    for key, tag in tags.items():
        name = key.split()[-1]
        if name in ("BlackLevel", "WhiteLevel") or key.endswith("Tag 0xC61A") or key.endswith("Tag 0xC61D"):
            label = "black" if ("Black" in name or key.endswith("C61A")) else "white"
            values = [float(v.num) / float(v.den) if hasattr(v, "num") else float(v) for v in tag.values]
            found.setdefault(label, values)
    return found


@EMPTY_EXPOSURE
def test_real_canon_dng_levels_match_its_tags():
    """Black and white levels of the real Canon 550D DNG: the decoder's per-channel values
    equal the DNG BlackLevel/WhiteLevel tags read by exifread (an independent TIFF parser),
    2056 and 15000 as shared/realdata's README records."""
    path = realdata("raw/tinydng_colorchart.dng")
    image = decode_raw(path)
    levels = _exif_levels(path)
    np.testing.assert_array_equal(image.black_level, np.full(4, levels["black"][0]))
    np.testing.assert_array_equal(image.white_level, np.full(4, levels["white"][0]))
    assert (image.black_level[0], image.white_level[0]) == (2056, 15000)


@pytest.mark.skipif(not SAMPLES, reason="no real RAW samples (../shared/realdata/raw, LSADPHOTO_RAW_SAMPLES)")
@pytest.mark.parametrize("source", SAMPLES, ids=_sample_ids())
@EMPTY_EXPOSURE
def test_real_samples_exposure_metadata_match_exifread(source):
    """Exposure time, f-number and focal length decoded from each real sample agree with
    exifread's reading of the same file within 1 % (EXIF rationals rounded by the maker)."""
    image = decode_raw(source)
    with open(source, "rb") as fh:
        tags = exifread.process_file(fh, details=False)
    meta = image.metadata
    for field, tag in (("exposure_time", "ExposureTime"), ("f_number", "FNumber"), ("focal_length", "FocalLength")):
        value = tags.get(f"EXIF {tag}") or tags.get(f"Image {tag}")
        if value is None or getattr(meta, field) is None:
            continue
        v = value.values[0]
        exif = float(v.num) / float(v.den) if hasattr(v, "num") and v.den else float(v)
        if exif > 0:
            assert getattr(meta, field) == pytest.approx(exif, rel=0.01), field
    assert np.all(image.white_level > image.black_level)


#: Side of the square blocks, per CFA channel, whose mean estimates a dark region's level [px].
DARK_BLOCK = 32


@pytest.mark.skipif(not SAMPLES, reason="no real RAW samples (../shared/realdata/raw, LSADPHOTO_RAW_SAMPLES)")
@pytest.mark.parametrize("source", SAMPLES, ids=_sample_ids())
@EMPTY_EXPOSURE
def test_real_samples_black_level_not_above_their_darkest_pixels(source):
    """The decoder's black level of each CFA channel is not above the mean of that channel's
    darkest 32 × 32 block of the file's own pixels (read by LibRaw, the independent
    reference): an unlit region averages the black level, so a higher one would clip real
    shadows. Tolerance: 4 standard errors of that block's mean (its pixel noise / 32). The
    Sony ARW's darkest red block averages 511.85 ± 0.35 ADU against its black level 512."""
    import rawpy

    image = decode_raw(source)
    with rawpy.imread(str(source)) as raw:
        values = raw.raw_image_visible.astype(np.float64)
        colours = raw.raw_colors_visible
    for dr in (0, 1):
        for dc in (0, 1):
            plane = values[dr::2, dc::2]
            rows, cols = (plane.shape[0] // DARK_BLOCK) * DARK_BLOCK, (plane.shape[1] // DARK_BLOCK) * DARK_BLOCK
            blocks = plane[:rows, :cols].reshape(rows // DARK_BLOCK, DARK_BLOCK, cols // DARK_BLOCK, DARK_BLOCK)
            blocks = blocks.transpose(0, 2, 1, 3).reshape(-1, DARK_BLOCK * DARK_BLOCK)
            darkest = blocks[blocks.mean(axis=1).argmin()]
            black = image.black_level[colours[dr, dc]]
            assert black <= darkest.mean() + 4 * darkest.std() / DARK_BLOCK, (dr, dc, black, darkest.mean())
