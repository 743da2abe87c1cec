"""RAW file integrity: refuse files that are shorter than their data or that LibRaw reports damaged.

LibRaw decodes a truncated file without complaint in many formats: it fills the rows it
could not read with copies of the last good one (or with zeros), so a cut-off photo becomes
a plausible but wrong luminance map. Three independent checks catch this before any number
is computed:

1. **Declared extent** (:func:`declared_extent`): every byte range the file's own structure
   declares — TIFF strips and tiles (StripOffsets/StripByteCounts, TileOffsets/
   TileByteCounts) and embedded JPEGs in every IFD and SubIFD of TIFF-based RAWs (DNG, NEF,
   CR2, ARW, PEF, SRW, ORF, RW2), the JPEG and CFA ranges of a Fujifilm RAF header, the
   boxes of an ISO base-media file (CR3) — must end inside the file.
2. **LibRaw's own reports**: LibRaw calls its data-error handler ("Unexpected end of file",
   "Corrupt data near …") on the C-level standard error stream while it unpacks; that stream
   is captured during decoding and any report refuses the file.
3. **Raw data present** (:func:`check_raw_data_present`): a raw image IFD (CFA or LinearRaw)
   whose strips or tiles hold fewer bytes than one bit per sample is a metadata-only copy
   (ExifTool's and exiv2's test files strip the image data this way, and LibRaw then
   "decodes" an all-zero frame). Every lossless coding of a camera's raw data — uncompressed,
   lossless JPEG and the makers' Huffman codings — spends at least one bit on each sample,
   since a Huffman code word is at least one bit long; lossy and Deflate codings are left
   out of this check.
4. **Repeated rows**: a block of identical, non-constant rows at the bottom of the raw image
   is what LibRaw leaves where data ran out; a real exposure has photon noise in every row.

References
----------
Adobe, *TIFF Revision 6.0* (1992), section 2 (IFD structure) and 3 (StripOffsets,
StripByteCounts); *DNG Specification* 1.6, chapter 3 (SubIFDs). ISO/IEC 14496-12:2022
(ISO base media file format), 4.2 (box structure). ITU-T T.81 (1992), annex C (Huffman
code lengths 1–16 bits) and annex H (lossless processes). LibRaw API notes, "Data error
callback" (libraw.org/docs/API-notes.html).
"""

import contextlib
import os
import struct

import numpy as np

from .._native import native_output
from ..errors import UnsupportedFileError

__all__ = ["declared_extent", "check_declared_extent", "check_raw_data_present", "raw_compression",
           "libraw_reports", "check_repeated_rows"]

_STRIPS = ((273, 279), (324, 325), (513, 514))  # offsets tag, byte-count tag
_SUB_IFDS = (330, 34665)  # SubIFDs, Exif IFD
_TYPE_SIZE = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 6: 1, 7: 1, 8: 2, 9: 4, 10: 8, 11: 4, 12: 8, 13: 4, 16: 8, 18: 8}
_MAX_IFDS = 64
#: Photometric interpretations of raw image IFDs: CFA (TIFF/EP, DNG) and LinearRaw (DNG).
_RAW_PHOTOMETRIC = (32803, 34892)
#: Compressions that may spend less than one bit on a sample: Deflate (a noise-free synthetic
#: frame), lossy JPEG (DNG 1.4) and JPEG XL (DNG 1.7).
_SUB_BIT_COMPRESSIONS = (8, 34892, 52546)
#: Names of the compressions in raw IFDs that messages mention (TIFF 6.0, DNG 1.4 and 1.7).
COMPRESSION_NAMES = {1: "uncompressed", 7: "lossless JPEG", 8: "Deflate", 34892: "lossy JPEG (DNG 1.4)",
                     52546: "JPEG XL (DNG 1.7)"}
#: Rows repeated at the bottom of the raw image that count as filled-in data [rows]. A real
#: frame has photon noise: two identical non-constant rows of thousands of pixels do not occur.
REPEATED_ROWS_LIMIT = 4


def _tiff_ranges(data, size, raws=None):
    """(offset, length, what) byte ranges declared by a TIFF-structured file (any magic).

    ``raws``, a list, receives one dict per raw image IFD (CFA or LinearRaw): its size,
    samples per pixel, compression and the bytes its strips or tiles declare.
    """
    order = {b"II": "<", b"MM": ">"}[data[:2]]
    first = struct.unpack(order + "I", data[4:8])[0]
    ranges, seen, todo = [], set(), [first]

    def read(offset, n):
        if offset + n > size:
            raise _Short(offset + n, "an IFD")
        return data[offset:offset + n]

    while todo and len(seen) < _MAX_IFDS:
        ifd = todo.pop()
        if ifd == 0 or ifd in seen:
            continue
        seen.add(ifd)
        ranges.append((ifd, 2, "an IFD"))
        count = struct.unpack(order + "H", read(ifd, 2))[0]
        entries = read(ifd + 2, 12 * count)
        tags = {}
        for k in range(count):
            tag, kind, n = struct.unpack(order + "HHI", entries[12 * k:12 * k + 8])
            width = _TYPE_SIZE.get(kind)
            if width is None or kind not in (3, 4, 13):
                continue
            letter = "H" if kind == 3 else "I"
            if n * width <= 4:
                raw = entries[12 * k + 8:12 * k + 8 + n * width]
            else:
                pointer = struct.unpack(order + "I", entries[12 * k + 8:12 * k + 12])[0]
                raw = read(pointer, n * width)
            tags[tag] = struct.unpack(order + letter * n, raw)
        declared = 0
        for offsets_tag, counts_tag in _STRIPS:
            if offsets_tag in tags and counts_tag in tags:
                for offset, length in zip(tags[offsets_tag], tags[counts_tag]):
                    ranges.append((offset, length, "its image data"))
                    declared += length
        if raws is not None and tags.get(262, (None,))[0] in _RAW_PHOTOMETRIC and 256 in tags and 257 in tags:
            raws.append({"width": tags[256][0], "height": tags[257][0], "samples": tags.get(277, (1,))[0],
                         "compression": tags.get(259, (1,))[0], "bytes": declared})
        for tag in _SUB_IFDS:
            todo.extend(tags.get(tag, ()))
        todo.append(struct.unpack(order + "I", read(ifd + 2 + 12 * count, 4))[0])
    return ranges


def _raf_ranges(data, size):
    """Ranges of a Fujifilm RAF header: JPEG, CFA header and CFA data (big-endian, at 84)."""
    if size < 108:
        raise _Short(108, "the RAF header")
    jpeg, jpeg_n, header, header_n, cfa, cfa_n = struct.unpack(">6I", data[84:108])
    return [(jpeg, jpeg_n, "its JPEG preview"), (header, header_n, "its CFA header"),
            (cfa, cfa_n, "its raw data")]


def _bmff_ranges(data, size):
    """Top-level boxes of an ISO base-media file (CR3), each of declared size."""
    ranges, offset = [], 0
    while offset < size:
        if offset + 8 > size:
            raise _Short(offset + 8, "a box header")
        length = struct.unpack(">I", data[offset:offset + 4])[0]
        if length == 1:
            if offset + 16 > size:
                raise _Short(offset + 16, "a box header")
            length = struct.unpack(">Q", data[offset + 8:offset + 16])[0]
        elif length == 0:
            length = size - offset
        if length < 8:
            break  # not a box structure we understand: leave it to LibRaw
        ranges.append((offset, length, f"its {data[offset + 4:offset + 8].decode('latin-1')!r} box"))
        offset += length
    return ranges


class _Short(Exception):
    def __init__(self, end, what):
        super().__init__(end, what)
        self.end, self.what = end, what


def declared_extent(path):
    """(end, what): the largest byte offset the file's structure declares, and what lies there.

    Returns ``(None, None)`` for containers it does not know (LibRaw's own checks remain).

    Parameters
    ----------
    path : path-like

    Returns
    -------
    end : int or None
        One past the last declared byte [B].
    what : str or None
        The structure ending there (e.g. ``"its image data"``).
    """
    with open(path, "rb") as fh:
        data = fh.read()
    size = len(data)
    try:
        if data[:2] in (b"II", b"MM") and size >= 8:
            ranges = _tiff_ranges(data, size)
        elif data[:8] == b"FUJIFILM":
            ranges = _raf_ranges(data, size)
        elif data[4:8] == b"ftyp":
            ranges = _bmff_ranges(data, size)
        else:
            return None, None
    except _Short as short:
        return short.end, short.what
    except (struct.error, KeyError):
        return None, None
    ranges = [r for r in ranges if r[1] > 0]
    if not ranges:
        return None, None
    offset, length, what = max(ranges, key=lambda r: r[0] + r[1])
    return offset + length, what


def _raw_ifds(path):
    """The raw image IFDs of a TIFF-structured file (see :func:`_tiff_ranges`); [] otherwise."""
    with open(path, "rb") as fh:
        data = fh.read()
    raws = []
    if data[:2] in (b"II", b"MM") and len(data) >= 8:
        try:
            _tiff_ranges(data, len(data), raws)
        except (_Short, struct.error, KeyError):
            return []
    return raws


def raw_compression(path):
    """Name of the compression of the file's first raw image IFD, or None where unknown.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    str or None
        e.g. ``"JPEG XL (DNG 1.7)"``, or ``"compression 34713"`` for a code not named here.
    """
    raws = _raw_ifds(path)
    if not raws:
        return None
    code = raws[0]["compression"]
    return COMPRESSION_NAMES.get(code, f"compression {code}")


def check_raw_data_present(path):
    """Raise :class:`UnsupportedFileError` when a raw image IFD declares less than one bit of
    data per sample (a metadata-only copy of a RAW file), for lossless codings.

    Parameters
    ----------
    path : path-like
    """
    for ifd in _raw_ifds(path):
        if ifd["compression"] in _SUB_BIT_COMPRESSIONS:
            continue
        needed = ifd["width"] * ifd["height"] * ifd["samples"] // 8
        if ifd["bytes"] < needed:
            raise UnsupportedFileError(
                f"{path}: no image data: its {ifd['width']}×{ifd['height']} px raw image declares "
                f"{ifd['bytes']} bytes, less than one bit per sample ({needed} bytes); a metadata-only copy"
            )


def check_declared_extent(path):
    """Raise :class:`UnsupportedFileError` when ``path`` is shorter than its declared data."""
    end, what = declared_extent(path)
    size = os.path.getsize(path)
    if end is not None and end > size:
        raise UnsupportedFileError(
            f"{path}: truncated: {what} is declared to end at byte {end} but the file has "
            f"{size} ({end - size} bytes missing)"
        )


@contextlib.contextmanager
def libraw_reports():
    """Capture what C code writes to standard error (LibRaw's data-error reports), through
    the package's one native-output capture (:func:`lsadphoto._native.native_output`).

    Yields a list that holds the captured lines once the block ends.
    """
    with native_output([]) as lines:
        yield lines


def check_repeated_rows(raw_image, path):
    """Refuse a raw image whose last rows are identical copies of a non-constant row.

    An image made of one row repeated throughout (a noise-free test pattern) passes: nothing
    above the copies shows where good data ended.

    Parameters
    ----------
    raw_image : ndarray, (rows, cols)
        The raw CFA values [ADU] as LibRaw unpacked them (the whole raw area).
    path : str
        Named in the message.
    """
    image = np.asarray(raw_image)
    last = image[-1]
    if image.shape[0] <= REPEATED_ROWS_LIMIT or last.min() == last.max():
        return
    if np.all(image[-REPEATED_ROWS_LIMIT - 1:] == last):
        same = np.all(image[::-1] == last, axis=1)
        if same.all():
            return  # one row throughout: a test pattern, not a cut (nothing differs to compare)
        run = int(same.argmin())
        raise UnsupportedFileError(
            f"{path}: damaged: the last {run} raw rows are copies of one row (data ran out "
            "while LibRaw unpacked it)"
        )
