"""Decoding of RAW files to linear, normalised camera RGB with a saturation mask.

Values are normalised as the DNG specification does: (raw − black) / (white − black) per
CFA channel, so 1.0 is the white level; no white balance, gamma or brightening is applied.

References
----------
Adobe, *Digital Negative (DNG) Specification* 1.6 (2023), chapter 5 "Mapping Raw Values to
Linear Reference Values". LibRaw API notes (libraw.org/docs/API-datastruct-eng.html):
``cblack``, ``maximum``, ``linear_max``. rawpy issues #7 (copy data inside the ``with``
block), #80 and #122 (per-channel white level).
"""

import contextlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import rawpy

from .._validation import check_choice, check_file, check_positive
from ..constants import SATURATION_FRACTION
from ..errors import BadInputError, UnsupportedFileError
from ._dngtags import dng_black_map, read_dng_tags
from .integrity import (check_declared_extent, check_raw_data_present, check_repeated_rows, libraw_reports,
                        raw_compression)
from .metadata import ExposureMetadata, read_exposure_metadata
from .methods import DEMOSAIC_METHODS

_LIBRAW_ALGORITHM = {
    "linear": rawpy.DemosaicAlgorithm.LINEAR,
    "ahd": rawpy.DemosaicAlgorithm.AHD,
    "dcb": rawpy.DemosaicAlgorithm.DCB,
}
#: Half-width [px] of the CFA neighbourhood each LibRaw method reads around a pixel:
#: bilinear reads 3 × 3; AHD interpolates green over 5 × 5 and chroma from it; DCB
#: iterates green and chroma passes over 5 × 5 stencils (its default single iteration
#: reaches 3 px). A saturated CFA value anywhere in it taints the output pixel.
_FOOTPRINT = {"linear": 1, "ahd": 2, "dcb": 3}


@dataclass
class CameraColour:
    """The colour information a RAW file carries (see :mod:`lsadphoto.raw.colour`)."""

    rgb_xyz_matrix: np.ndarray  # LibRaw cam_xyz (XYZ → camera), zeros when not filled
    color_matrix: np.ndarray  # LibRaw rgb_cam (camera → linear sRGB after daylight WB), 3 × 3
    daylight_whitebalance: np.ndarray  # LibRaw pre_mul, 3
    dng: dict = field(default_factory=dict)  # DNG colour tags read directly (may be empty)


@dataclass
class RawImage:
    """A decoded RAW frame.

    Attributes
    ----------
    rgb : ndarray, float32, shape (rows, cols, 3)
        Linear camera RGB normalised to the white level [–].
    saturated : ndarray, bool, shape (rows, cols, 3)
        Channel values that a saturated CFA value entered.
    demosaic : str
    binning : int
        Output pixel size in sensor pixels (2 for ``superpixel``).
    sensor_shape : (int, int)
        Visible raw area [px].
    black_level, white_level : ndarray
        Per colour channel (R, G, B, G2) [ADU]; ``black_map_used`` says whether a per-pixel
        black-level map replaced the per-channel values.
    metadata : ExposureMetadata
    colour : CameraColour
    path : str
    """

    rgb: np.ndarray
    saturated: np.ndarray
    demosaic: str
    binning: int
    sensor_shape: tuple
    black_level: np.ndarray
    white_level: np.ndarray
    black_map_used: bool
    cfa_pattern: str
    metadata: ExposureMetadata
    colour: CameraColour
    path: str

    @property
    def shape(self):
        return self.rgb.shape[:2]


def _open(path):
    try:
        return rawpy.imread(str(path))
    except (rawpy.LibRawError, OSError, ValueError) as exc:
        kind = type(exc).__name__.replace("LibRaw", "").replace("Error", "").lower() or "error"
        raise UnsupportedFileError(f"{path}: not a readable RAW file ({kind})") from None


@contextlib.contextmanager
def _reading(path):
    """Open and unpack ``path`` with LibRaw after the integrity checks of :mod:`.integrity`.

    A file shorter than its declared data is refused before LibRaw reads it; whatever LibRaw
    reports about damaged data while it opens and unpacks the file refuses it, naming the
    report (LibRaw writes it to the C standard error stream; it is captured, not shown).
    """
    check_declared_extent(path)
    check_raw_data_present(path)
    failure = None
    with libraw_reports() as reports:
        raw = _open(path)
        try:
            raw.unpack()
        except rawpy.LibRawError as exc:
            failure = type(exc).__name__
    with raw:
        if reports:
            report = reports[0].removeprefix(f"{path}:").strip()
            raise UnsupportedFileError(f"{path}: damaged: LibRaw reports {report!r}")
        try:
            if failure is None:
                yield raw
        except rawpy.LibRawError as exc:
            failure = type(exc).__name__
        if failure == "LibRawFileUnsupportedError":
            coding = raw_compression(path)
            raise UnsupportedFileError(
                f"{path}: LibRaw {'.'.join(map(str, rawpy.libraw_version))} cannot unpack its raw data"
                + (f" ({coding})" if coding else "") + f" ({failure})")
        if failure:
            raise UnsupportedFileError(f"{path}: RAW data is corrupt or truncated ({failure})")


def _cfa_info(raw, path):
    pattern = raw.raw_pattern
    if pattern is None or raw.raw_type != rawpy.RawType.Flat:
        raise UnsupportedFileError(f"{path}: not a CFA (Bayer) raw image; linear/Foveon RAWs are not supported")
    desc = raw.color_desc.decode("ascii", "replace")
    if raw.num_colors != 3 or pattern.shape != (2, 2) or set(desc[:4]) - set("RGB"):
        raise UnsupportedFileError(
            f"{path}: unsupported colour filter array ({desc}, {pattern.shape[0]}×{pattern.shape[1]}); "
            "only 2×2 RGB Bayer patterns are supported"
        )
    letters = "".join(desc[c] for c in pattern.ravel())
    return letters


def _copy_raw(raw, path):
    check_repeated_rows(raw.raw_image, path)
    try:
        image = raw.raw_image_visible.copy()
        colours = raw.raw_colors_visible.copy()
    except (rawpy.LibRawError, OSError, ValueError) as exc:
        raise UnsupportedFileError(f"{path}: RAW data cannot be unpacked ({type(exc).__name__})") from None
    if image.size == 0:
        raise UnsupportedFileError(f"{path}: RAW image is empty")
    return image, colours


def _levels(raw):
    black = np.asarray(raw.black_level_per_channel, dtype=np.float64)
    white = float(raw.white_level)
    per_channel = raw.camera_white_level_per_channel
    whites = np.asarray(per_channel, dtype=np.float64) if per_channel is not None else np.full(4, white)
    whites = np.where(whites > 0, whites, white)
    return black, whites


def _black_map(path, shape, dark_frame, dng):
    """Per-pixel black level [ADU] where one replaces the per-channel values, else None."""
    if dark_frame is not None:
        dark = np.asarray(dark_frame, dtype=np.float64)
        if dark.shape != shape:
            raise BadInputError(f"dark frame is {dark.shape} but {path} is {shape}")
        return dark
    return dng_black_map(dng, shape)


def read_dark_frame(paths):
    """Mean raw values [ADU] of one or more dark frames (lens cap on, same settings)."""
    frames = []
    for path in paths:
        path = check_file(path, "dark frame")
        with _reading(path) as raw:
            _cfa_info(raw, path)
            image, _ = _copy_raw(raw, path)
        if frames and image.shape != frames[0].shape:
            raise BadInputError(f"dark frame {path} differs in size from the first")
        frames.append(image.astype(np.float64))
    if not frames:
        raise BadInputError("no dark frames given")
    return np.mean(frames, axis=0)


def _dilate(mask, radius):
    import cv2

    if radius <= 0 or not mask.any():
        return mask
    kernel = np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)
    return cv2.dilate(mask.view(np.uint8), kernel).astype(bool)


def decode_raw(path, *, demosaic="superpixel", saturation_fraction=SATURATION_FRACTION, dark_frame=None):
    """Decode a RAW file to linear camera RGB normalised to the white level.

    Parameters
    ----------
    path : path-like
        Any LibRaw-readable Bayer RAW (NEF, CR2, ARW, DNG, …).
    demosaic : {"superpixel", "linear", "ahd", "dcb"}
        ``superpixel`` bins each 2 × 2 CFA cell into one pixel (half resolution, no
        interpolation); the others are LibRaw's demosaic algorithms at full resolution.
    saturation_fraction : float
        A CFA value whose black-subtracted value reaches this fraction of its channel's
        white-minus-black range counts as saturated.
    dark_frame : ndarray, optional
        Per-pixel black level [ADU] of the visible area (e.g. :func:`read_dark_frame`);
        replaces the file's black levels.

    Returns
    -------
    RawImage

    Notes
    -----
    Black levels: LibRaw's per-channel values, or a black-level map where the DNG has
    BlackLevelDeltaH/V or a repeat pattern beyond 2 × 2, or the dark frame. Saturation is
    decided per CFA value after black subtraction, against its channel's white level, and
    carried through demosaicing: an output channel is flagged when a saturated CFA value
    lies in the method's neighbourhood (same colour for ``linear``; any colour for ``ahd``
    and ``dcb``, which interpolate colour differences).
    """
    path = check_file(path, "RAW file")
    check_choice(demosaic, "demosaic method", DEMOSAIC_METHODS)
    saturation_fraction = check_positive(saturation_fraction, "saturation_fraction")
    with _reading(path) as raw:
        return _decode(path, raw, demosaic, saturation_fraction, dark_frame)


def _decode(path, raw, demosaic, saturation_fraction, dark_frame):
    """Body of :func:`decode_raw` on an open file (copies everything out of LibRaw).

    Work is done plane by plane of the 2 × 2 CFA cell, where black and white levels are
    constants, unless a black-level map is in use.
    """
    pattern = _cfa_info(raw, path)
    image, colours = _copy_raw(raw, path)
    black, whites = _levels(raw)
    dng = read_dng_tags(path)  # {} for files that are not DNGs
    black_map = _black_map(path, colours.shape, dark_frame, dng)
    cell = colours[:2, :2]
    planes = [(dr, dc, int(cell[dr, dc])) for dr in (0, 1) for dc in (0, 1)]
    if np.any(whites <= black) or (black_map is not None and np.any(whites[colours] <= black_map)):
        raise UnsupportedFileError(f"{path}: white level {whites.min():g} is not above black level")

    def plane_black(dr, dc, c, rows=None, cols=None):
        if black_map is None:
            return np.float32(black[c])
        return black_map[dr:rows:2, dc:cols:2].astype(np.float32)

    sat_cfa = np.empty(image.shape, bool)
    for dr, dc, c in planes:
        b = plane_black(dr, dc, c)
        sat_cfa[dr::2, dc::2] = image[dr::2, dc::2] >= b + np.float32(saturation_fraction) * (whites[c] - b)
    if demosaic == "superpixel":
        rows, cols = (image.shape[0] // 2) * 2, (image.shape[1] // 2) * 2
        rgb = np.zeros((rows // 2, cols // 2, 3), np.float32)
        saturated = np.zeros((rows // 2, cols // 2, 3), bool)
        for dr, dc, c in planes:
            channel = 1 if c == 3 else c
            b = plane_black(dr, dc, c, rows, cols)
            share = np.float32(0.5 if channel == 1 else 1.0)  # two greens per cell
            rgb[..., channel] += (image[dr:rows:2, dc:cols:2] - b) * (share / (np.float32(whites[c]) - b))
            saturated[..., channel] |= sat_cfa[dr:rows:2, dc:cols:2]
        binning = 2
    else:
        if black_map is not None:
            # Fold the map's deviation from LibRaw's per-channel black into the data so
            # that LibRaw's uniform subtraction removes the map.
            shifted = image.astype(np.float64) - (black_map - black[colours])
            raw.raw_image_visible[...] = np.clip(np.rint(shifted), 0, 65535).astype(np.uint16)
        try:
            out = raw.postprocess(
                demosaic_algorithm=_LIBRAW_ALGORITHM[demosaic],
                output_color=rawpy.ColorSpace.raw,
                gamma=(1, 1),
                no_auto_bright=True,
                output_bps=16,
                user_wb=[1.0, 1.0, 1.0, 1.0],
                user_flip=0,
                adjust_maximum_thr=0.0,
                highlight_mode=rawpy.HighlightMode.Clip,
            )
        except (rawpy.LibRawError, MemoryError) as exc:
            raise UnsupportedFileError(f"{path}: LibRaw could not demosaic ({type(exc).__name__})") from None
        # LibRaw scales (raw − black_c) by 65535 / (maximum − min black) (checked
        # against native CFA sites in tests/test_decode.py); undo that, then normalise
        # per channel as the DNG specification does — one multiplication per value.
        libraw_unit = (float(raw.white_level) - black.min()) / 65535.0
        scale = np.array([libraw_unit / (whites[c] - black[c]) for c in range(3)], np.float32)
        rgb = np.multiply(out, scale, dtype=np.float32)
        if black_map is not None:
            # LibRaw divided by (white − channel black); the DNG normalisation divides
            # by (white − black of the pixel).
            white_px = whites[colours]
            rgb *= ((white_px - black[colours]) / (white_px - black_map)).astype(np.float32)[..., None]
        radius = _FOOTPRINT[demosaic]
        if demosaic == "linear":
            saturated = np.zeros(image.shape + (3,), bool)
            for c in range(3):
                mask = np.zeros(image.shape, bool)
                for dr, dc, cc in planes:
                    if (1 if cc == 3 else cc) == c:
                        mask[dr::2, dc::2] = sat_cfa[dr::2, dc::2]
                saturated[..., c] = _dilate(mask, radius)
        else:
            saturated = np.repeat(_dilate(sat_cfa, radius)[..., None], 3, axis=-1)
        binning = 1
    colour = CameraColour(
        rgb_xyz_matrix=np.array(raw.rgb_xyz_matrix[:3, :3], dtype=np.float64),
        color_matrix=np.array(raw.color_matrix[:3, :3], dtype=np.float64),
        daylight_whitebalance=np.array(raw.daylight_whitebalance[:3], dtype=np.float64),
    )
    metadata = read_exposure_metadata(path, raw)
    if Path(path).suffix.lower() == ".dng":
        colour.dng = dng
    return RawImage(
        rgb=rgb,
        saturated=saturated,
        demosaic=demosaic,
        binning=binning,
        sensor_shape=image.shape,
        black_level=black,
        white_level=whites,
        black_map_used=black_map is not None,
        cfa_pattern=pattern,
        metadata=metadata,
        colour=colour,
        path=str(path),
    )
