"""Radiance HDR (RGBE) luminance maps, read and written the way Radiance does.

Conventions (FORMULAS.md §2.4.1; PITFALLS.md):

- Luminance = 179 · (0.265074 R + 0.670115 G + 0.064811 B) after dividing each channel by
  the product of all ``EXPOSURE=`` values and by ``COLORCORR=`` where present.
- An RGBE pixel decodes as (mantissa + ½)·2^(exponent − 136) (Radiance ``colr_color``);
  OpenCV leaves out the ½ and reads about 0.3 % low, so decoding is done here.
- We write grey pixels R = G = B = L / 179, so Radiance's luminance of the pixel is L
  (the three weights sum to 1), a ``VIEW=`` line from the projection so that evalglare can
  use the file, and our metadata on an ``LSADPHOTO=`` header line.

References
----------
G. Ward, "Real pixels", *Graphics Gems II* (1991) 80–83. Radiance ``src/common/color.c``
(setcolr, colr_color, fwritecolrs, freadcolrs) and ``src/common/header.c``.
"""

import contextlib
import math
import mmap
import re

import numpy as np

from .._validation import check_file
from .._version import __version__
from ..constants import RADIANCE_RGB_LUMINANCE_WEIGHTS, RADIANCE_WHITE_EFFICACY
from ..errors import BadInputError, UnsupportedFileError
from ..geometry.fisheye import RADIANCE_VIEW_NAMES, IdealFisheyeProjection
from ..geometry.pinhole import PinholeProjection
from ..luminance_map import LuminanceMap
from .._atomic import atomic_path
from ._metadata import metadata_fields, metadata_json

_RESOLUTION = re.compile(rb"^-Y\s+(\d+)\s+\+X\s+(\d+)$")  # Radiance 6 pads the numbers
_MIN_RLE, _MAX_RLE = 8, 0x7FFF


# --- RGBE encoding ---------------------------------------------------------------------------


def float_to_rgbe(rgb):
    """Encode float RGB ``(..., 3)`` as RGBE bytes ``(..., 4)`` as Radiance's setcolr does."""
    rgb = np.asarray(rgb, dtype=np.float64)
    peak = rgb.max(axis=-1)
    mantissa, exponent = np.frexp(peak)
    out = np.zeros(rgb.shape[:-1] + (4,), dtype=np.uint8)
    ok = peak > 1e-32
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(ok, mantissa * 256.0 / peak, 0.0)
    values = np.floor(np.clip(rgb, 0.0, None) * scale[..., None])
    out[..., :3] = np.where(ok[..., None], np.clip(values, 0, 255), 0).astype(np.uint8)
    out[..., 3] = np.where(ok, np.clip(exponent + 128, 0, 255), 0).astype(np.uint8)
    return out


def rgbe_to_float(rgbe):
    """Decode RGBE bytes ``(..., 4)`` to float RGB as Radiance's colr_color does."""
    rgbe = np.asarray(rgbe)
    exponent = rgbe[..., 3].astype(np.int32)
    scale = np.where(exponent > 0, np.ldexp(1.0, exponent - 136), 0.0)
    return (rgbe[..., :3].astype(np.float64) + 0.5) * scale[..., None]


def _encode_scanlines(rgbe):
    """New-style RLE scanlines made of literal runs only (valid for every Radiance reader)."""
    rows, cols, _ = rgbe.shape
    if not _MIN_RLE <= cols <= _MAX_RLE:
        return rgbe.tobytes()  # flat scanlines, as Radiance writes outside the RLE range
    starts = np.arange(0, cols, 128)
    counts = np.minimum(128, cols - starts).astype(np.uint8)
    # Per component: [count, bytes...] for each chunk. Build the index layout once.
    comp_len = len(starts) + cols
    layout = np.empty(comp_len, dtype=np.int64)  # -1 for count bytes, else column index
    pos = 0
    count_positions = []
    for start, count in zip(starts.tolist(), counts.tolist()):
        count_positions.append(pos)
        layout[pos] = -1
        layout[pos + 1 : pos + 1 + count] = np.arange(start, start + count)
        pos += 1 + count
    is_data = layout >= 0
    line = np.empty((rows, 4 + 4 * comp_len), dtype=np.uint8)
    line[:, 0] = 2
    line[:, 1] = 2
    line[:, 2] = cols >> 8
    line[:, 3] = cols & 0xFF
    for c in range(4):
        block = line[:, 4 + c * comp_len : 4 + (c + 1) * comp_len]
        block[:, np.asarray(count_positions)] = counts
        block[:, is_data] = rgbe[:, layout[is_data], c]
    return line.tobytes()


# --- header ----------------------------------------------------------------------------------


_VIEW_COUNTS = {"vp": 3, "vd": 3, "vu": 3, "vh": 1, "vv": 1, "vs": 1, "vl": 1, "vo": 1, "va": 1}


def parse_view(text, *, strict=False):
    """Parse Radiance view options (``-vtv -vh 60 …``) into a dict; the type under ``"type"``.

    With ``strict`` (views typed by a user, e.g. ``render --view``) anything that is not a
    view option, and an unknown view type, is a :class:`BadInputError`; file headers are
    read leniently (other words are skipped).

    References
    ----------
    Radiance ``rpict`` manual page (view options ``-vt? -vp -vd -vu -vh -vv -vs -vl -vo
    -va``).

    Examples
    --------
    >>> parse_view("-vta -vp 1 2 1.2 -vh 180")
    {'type': 'a', 'vp': [1.0, 2.0, 1.2], 'vh': 180.0}
    >>> parse_view("banana", strict=True)
    Traceback (most recent call last):
    ...
    lsadphoto.errors.BadInputError: 'banana' in view 'banana' is not a Radiance view option; valid: -vt[vlchas], -vp X Y Z, -vd X Y Z, -vu X Y Z, -vh, -vv, -vs, -vl, -vo, -va
    """
    options = {"type": "v"}
    tokens = text.split()
    error = BadInputError if strict else UnsupportedFileError
    valid = "-vt[" + "".join(RADIANCE_VIEW_NAMES) + "], " + ", ".join(
        f"-{k} X Y Z" if n == 3 else f"-{k}" for k, n in _VIEW_COUNTS.items())
    i = 0
    while i < len(tokens):
        token = tokens[i]
        if token.startswith("-vt") and len(token) == 4:
            if strict and token[3] not in RADIANCE_VIEW_NAMES:
                raise error(f"unknown Radiance view type {token} in view {text!r}; valid: {valid}")
            options["type"] = token[3]
            i += 1
        elif token.startswith("-v") and token[1:] in _VIEW_COUNTS:
            key = token[1:]
            k = _VIEW_COUNTS[key]
            try:
                values = [float(t) for t in tokens[i + 1 : i + 1 + k]]
            except ValueError:
                raise error(f"bad view option {token} in {text!r}: needs {k} number(s)") from None
            if len(values) != k or not all(math.isfinite(v) for v in values):
                raise error(f"bad view option {token} in {text!r}: needs {k} finite number(s)")
            options[key] = values if k > 1 else values[0]
            i += 1 + k
        elif strict:
            raise error(f"{token!r} in view {text!r} is not a Radiance view option; valid: {valid}")
        else:
            i += 1
    return options


def projection_from_view(view, width, height, *, fov_deg=180.0):
    """Camera model of a Radiance view (dict from :func:`parse_view`) for a picture [px].

    ``-vtv`` gives a :class:`~lsadphoto.geometry.PinholeProjection`; ``-vta`` (angular,
    equidistant), ``-vth`` (hemispherical, orthographic) and ``-vts`` (planisphere,
    stereographic) an :class:`~lsadphoto.geometry.IdealFisheyeProjection` whose image circle
    is cut at ``fov_deg`` [deg] (default 180°, the front hemisphere). ``-vtl`` (parallel),
    ``-vtc`` (cylindrical panorama) and unknown types raise :class:`BadInputError` naming
    the type.

    References
    ----------
    Radiance ``src/common/image.c`` (setview, viewray) and ``src/common/view.h`` (VT_*).

    Examples
    --------
    >>> projection_from_view(parse_view("-vta -vh 180 -vv 180"), 100, 100).kind
    'equidistant'
    """
    vtype = view.get("type", "v")
    if vtype == "v":
        return PinholeProjection.from_radiance_view(view, width, height)
    if vtype in ("a", "h", "s"):
        return IdealFisheyeProjection.from_radiance_view(view, width, height, fov_deg)
    name = RADIANCE_VIEW_NAMES.get(vtype, "unknown view type")
    raise BadInputError(
        f"Radiance view type -vt{vtype} ({name}) has no camera model; supported: -vtv, -vta, -vth, -vts"
    )


def _read_header(data, path):
    """Parsed header, rows, cols and the position of the first scanline of ``data`` (bytes
    or a read-only map of the file)."""
    if data[:2] != b"#?":
        raise UnsupportedFileError(f"{path}: not a Radiance picture (no '#?' magic line)")
    end = data.find(b"\n\n")
    if end < 0:
        raise UnsupportedFileError(f"{path}: header has no end")
    lines = data[:end].split(b"\n")
    rest = end + 2
    eol = data.find(b"\n", rest)
    if eol < 0:
        raise UnsupportedFileError(f"{path}: no resolution line")
    match = _RESOLUTION.match(data[rest:eol].strip())
    if not match:
        raise UnsupportedFileError(
            f"{path}: unsupported resolution line {data[rest:eol][:40]!r} (only -Y N +X M)"
        )
    rows, cols = int(match.group(1)), int(match.group(2))
    header = {"exposure": 1.0, "colorcorr": np.ones(3), "view": None, "format": None, "lsadphoto": None}
    for raw in lines[1:]:
        line = raw.decode("latin-1").strip()
        key, _, value = line.partition("=")
        key = key.strip().upper()
        try:
            if key == "EXPOSURE":
                header["exposure"] *= float(value)
            elif key == "COLORCORR":
                header["colorcorr"] = header["colorcorr"] * np.array([float(v) for v in value.split()[:3]])
            elif key == "VIEW":
                header["view"] = value if header["view"] is None else header["view"] + " " + value
            elif key == "FORMAT":
                header["format"] = value.strip()
            elif key == "LSADPHOTO":
                header["lsadphoto"] = value
        except ValueError:
            raise UnsupportedFileError(f"{path}: bad header line {line[:60]!r}") from None
    if header["format"] not in (None, "32-bit_rle_rgbe"):
        raise UnsupportedFileError(f"{path}: unsupported pixel format {header['format']!r}")
    if header["exposure"] <= 0 or np.any(header["colorcorr"] <= 0):
        raise UnsupportedFileError(f"{path}: non-positive EXPOSURE or COLORCORR")
    return header, rows, cols, eol + 1


@contextlib.contextmanager
def _mapped(path):
    """The bytes of the file at ``path`` mapped read-only (the page cache's own pages, not
    a copy in fresh memory: 97 MB for a 24 MP picture)."""
    with open(path, "rb") as file, mmap.mmap(file.fileno(), 0, access=mmap.ACCESS_READ) as data:
        yield data


def _decode(path, decoder, out, args):
    """Header of the Radiance picture at ``path`` and its scanlines decoded by ``decoder``
    (``decode_scanlines`` or ``decode_luminance`` of :mod:`._rgbe`, with the further arguments
    ``args(header)``) into ``out(rows, cols)``."""
    from ._rgbe import SCANLINE_ERRORS

    path = check_file(path, "HDR file")
    with _mapped(path) as data:
        header, rows, cols, pos = _read_header(data, path)
        target = out(rows, cols)
        array = np.frombuffer(data, np.uint8)
        try:
            error, row = _decode_blocks(decoder, array, pos, _MIN_RLE <= cols <= _MAX_RLE,
                                        args(header), target)
        finally:
            del array  # the map closes only without views of it
    if error:
        raise UnsupportedFileError(f"{path}: {SCANLINE_ERRORS[error]} (scanline {row})")
    return target, header


def _decode_blocks(decoder, data, pos, rle, args, target):
    """``decoder`` over every scanline into ``target``; (error code, scanline) as the
    decoders return them. Where the compiled code runs on several threads, the scanlines'
    positions are found first (:func:`._rgbe.scanline_offsets`: the same walk, which meets
    any error the decoder would meet, at the same scanline) and blocks of scanlines are
    decoded at the same time: the same values."""
    from .._compiled import populate, row_blocks, run_blocks
    from ._rgbe import scanline_offsets

    rows, cols = target.shape[:2]
    workers = decoder.threads_for(data, pos, rle, *args, target)
    if workers <= 1 or rows < 2:
        populate(target)
        _, error, row = decoder(data, pos, rle, *args, target)
        return error, row
    offsets = np.empty(rows, dtype=np.int64)
    _, error, row = scanline_offsets(data, pos, rle, cols, offsets)
    if error:
        return error, row
    blocks = row_blocks(rows, workers)

    def block(a, b):
        populate(target[a:b])
        return decoder(data, int(offsets[a]), rle, *args, target[a:b])

    done = run_blocks(block, blocks, workers)
    return next(((error, a + row) for (a, _), (_, error, row) in zip(blocks, done, strict=True)
                 if error), (0, rows))


def _read_rgbe(path):
    """RGBE bytes ``(rows, cols, 4)`` uint8 of a Radiance picture and its parsed header."""
    from ._rgbe import decode_scanlines  # numba loads only for reading

    return _decode(path, decode_scanlines, lambda rows, cols: np.zeros((rows, cols, 4), np.uint8),
                   lambda header: ())


def read_hdr_rgb(path):
    """Read a Radiance picture: float64 RGB ``(rows, cols, 3)`` with EXPOSURE and COLORCORR
    divided out, and the parsed header."""
    rgbe, header = _read_rgbe(path)
    rgb = rgbe_to_float(rgbe) / header["exposure"] / header["colorcorr"]
    return rgb, header


def read_hdr(path):
    """Read a Radiance HDR picture as a :class:`LuminanceMap` [cd·m⁻²] (179 lm/W convention).

    Files written by :func:`write_hdr` come back with their metadata; for other files a
    ``-vtv`` VIEW= line gives a :class:`PinholeProjection`, ``-vta``, ``-vth`` and ``-vts`` an
    :class:`IdealFisheyeProjection` (image circle cut at 180°; see
    :func:`projection_from_view`); other view types (``-vtl``, ``-vtc``) are kept in the
    provenance (``radiance_view``) without a projection, so that their luminance can still
    be read.
    """
    from ._rgbe import decode_luminance, mantissa_tables

    def arguments(header):
        values = (float(header["exposure"]), np.asarray(header["colorcorr"], np.float64),
                  np.asarray(RADIANCE_RGB_LUMINANCE_WEIGHTS, np.float64),
                  float(RADIANCE_WHITE_EFFICACY))
        tables = mantissa_tables(*values)
        return (*values, np.zeros((3, 256)) if tables is None else tables, tables is not None)

    luminance, header = _decode(
        path, decode_luminance, lambda rows, cols: np.empty((rows, cols), np.float32), arguments)
    rows, cols = luminance.shape
    if header["lsadphoto"] is not None:
        fields = metadata_fields(header["lsadphoto"], path)
    else:
        fields = {"provenance": {"source": str(path), "radiance_view": header["view"]}}
        if header["view"] is not None:
            view = parse_view(header["view"])
            try:
                if view["type"] in ("v", "a", "h", "s"):
                    fields["projection"] = projection_from_view(view, cols, rows)
            except BadInputError as exc:
                raise UnsupportedFileError(f"{path}: unusable VIEW= line ({exc})") from None
    try:
        return LuminanceMap(luminance, **fields)
    except BadInputError as exc:  # e.g. metadata of a projection of another size
        raise UnsupportedFileError(f"{path}: {exc}") from None


def write_hdr(lmap, path):
    """Write ``lmap`` as a Radiance picture (atomic), readable by evalglare and pvalue.

    Pixels are grey with R = G = B = L/179; unknown (NaN) pixels are written as 0, which is
    what evalglare does with invalid pixels. ``EXPOSURE`` is not written (1). The
    ``VIEW=`` line comes from the projection where it has a Radiance equivalent. RGBE cannot
    hold negative values: negative luminances (noise around zero in a measured map) are
    written as 0, and a ``CLAMPED=`` header line says how many, since means over dark
    regions of such a file are biased upwards (the OpenEXR map keeps the signed values).
    """
    luminance = np.nan_to_num(np.asarray(lmap.luminance, np.float64), nan=0.0)
    negative = int(np.count_nonzero(luminance < 0))
    luminance = np.maximum(luminance, 0.0)
    value = luminance / RADIANCE_WHITE_EFFICACY
    lines = []
    if negative:
        lines.append(f"CLAMPED= {negative} pixels of negative luminance (noise) written as 0; "
                     "means over dark regions are biased upwards; the OpenEXR map keeps them signed")
    lines.append(f"LSADPHOTO={metadata_json(lmap)}")
    write_hdr_rgb(np.repeat(value[..., None], 3, axis=-1), path, projection=lmap.projection,
                  header_lines=lines, view_pose=(lmap.provenance or {}).get("view_pose"))


def _placed(view, pose):
    """Radiance view options with ``-vp``/``-vd``/``-vu`` taken from ``pose`` (when given)."""
    if not pose:
        return view
    # exact values (17 digits round-trip); + 0.0 writes a negative zero as 0
    vectors = " ".join(f"-{k} " + " ".join(f"{float(c) + 0.0:.17g}" for c in pose[k]) for k in ("vp", "vd", "vu"))
    return re.sub(r"-vp \S+ \S+ \S+ -vd \S+ \S+ \S+ -vu \S+ \S+ \S+", vectors, view, count=1)


def write_hdr_rgb(rgb, path, *, projection=None, header_lines=(), view_pose=None):
    """Write Radiance RGB values ``(rows, cols, 3)`` (W·sr⁻¹·m⁻², luminance = 179·(0.265074 R
    + 0.670115 G + 0.064811 B)) as a Radiance picture (atomic), with a ``VIEW=`` line from
    ``projection`` where it has a Radiance equivalent and the given extra header lines.

    ``view_pose`` (``{"vp", "vd", "vu"}`` in world coordinates, e.g. a rendered map's
    ``provenance["view_pose"]``) places the view in the scene; without it the view is given in
    the camera's own frame (``-vp 0 0 0 -vd 0 1 0 -vu 0 0 1``)."""
    rgbe = float_to_rgbe(np.nan_to_num(np.asarray(rgb, np.float64), nan=0.0))
    rows, cols = rgbe.shape[:2]
    lines = ["#?RADIANCE", f"SOFTWARE=lsadphoto {__version__}"]
    if projection is not None and hasattr(projection, "radiance_view"):
        try:
            lines.append(f"VIEW= {_placed(projection.radiance_view(), view_pose)}")
        except BadInputError:
            pass  # no Radiance view type for this projection (e.g. equisolid): no VIEW= line
    lines.extend(header_lines)
    lines.append("FORMAT=32-bit_rle_rgbe")
    head = ("\n".join(lines) + f"\n\n-Y {rows} +X {cols}\n").encode("latin-1", "replace")
    with atomic_path(path) as temp, open(temp, "wb") as fh:
        fh.write(head)
        fh.write(_encode_scanlines(rgbe))



__all__ = [
    "float_to_rgbe",
    "parse_view",
    "projection_from_view",
    "read_hdr",
    "read_hdr_rgb",
    "rgbe_to_float",
    "write_hdr",
    "write_hdr_rgb",
]
