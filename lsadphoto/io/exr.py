"""OpenEXR luminance maps: float32 ``Y`` (and ``Y.uncertainty``) with metadata attributes.

References
----------
OpenEXR file layout: https://openexr.com/en/latest/OpenEXRFileLayout.html. The Python
binding's API is noted in PITFALLS.md.
"""

import numpy as np
import OpenEXR

from .._native import native_output
from .._validation import check_file
from ..errors import BadInputError, UnsupportedFileError
from ..luminance_map import LuminanceMap
from .._atomic import atomic_path
from ._metadata import metadata_fields, metadata_json

METADATA_ATTRIBUTE = "lsadphoto.metadata"
LUMINANCE_CHANNEL = "Y"
UNCERTAINTY_CHANNEL = "Y.uncertainty"

#: Luminance weights of linear Rec. 709 RGB, OpenEXR's default chromaticities (ITU-R BT.709-6).
REC709_LUMINANCE_WEIGHTS = (0.2126, 0.7152, 0.0722)


def write_exr(lmap, path):
    """Write ``lmap`` to ``path`` as a ZIP-compressed float32 scanline OpenEXR file (atomic).

    The luminance [cd·m⁻²] is channel ``Y``; the per-pixel standard uncertainty, where
    known, ``Y.uncertainty``. Metadata (projection, calibration factor and uncertainty,
    exposure, provenance, package version) goes into the ``lsadphoto.metadata`` header
    attribute as JSON; the calibration factor is also a plain float attribute for other
    readers.
    """
    channels = {LUMINANCE_CHANNEL: np.ascontiguousarray(lmap.luminance, dtype=np.float32)}
    if lmap.uncertainty is not None:
        channels[UNCERTAINTY_CHANNEL] = np.ascontiguousarray(lmap.uncertainty, dtype=np.float32)
    header = {
        "compression": OpenEXR.ZIP_COMPRESSION,
        "type": OpenEXR.scanlineimage,
        METADATA_ATTRIBUTE: metadata_json(lmap),
        "lsadphoto.unit": "cd/m2",
        "lsadphoto.calibrated": "yes" if lmap.calibrated else "uncalibrated",
        # EXR float attributes are 32-bit: a convenience copy; the JSON holds the exact value.
        "lsadphoto.calibration_factor": lmap.calibration_factor,
    }
    with atomic_path(path) as temp:
        OpenEXR.File(header, channels).write(str(temp))


def read_exr(path):
    """Read a luminance map from an OpenEXR file.

    Files written by :func:`write_exr` come back with all their metadata and their signed
    values (noise around zero stays negative). Other files are
    accepted with a ``Y`` channel or ``R``, ``G``, ``B`` channels (converted with the
    Rec. 709 luminance weights); their scale is whatever the file holds, marked
    uncalibrated.
    """
    path = check_file(path, "EXR file")
    chatter = []  # OpenEXR's own lines on a corrupt file: the first goes into our message
    try:
        with native_output(chatter, python=True):
            exr = OpenEXR.File(str(path))
            header = exr.header()
            channels = exr.channels()
    except Exception as exc:  # the binding raises bare RuntimeError for corrupt files
        detail = chatter[0].removeprefix(f"{path}: ") if chatter else str(exc)
        raise UnsupportedFileError(f"{path}: not a readable OpenEXR file ({detail})") from None
    names = set(channels)
    if LUMINANCE_CHANNEL in names:
        luminance = channels[LUMINANCE_CHANNEL].pixels.astype(np.float32)
    elif {"R", "G", "B"} <= names:
        rgb = [channels[c].pixels.astype(np.float64) for c in "RGB"]
        luminance = sum(w * c for w, c in zip(REC709_LUMINANCE_WEIGHTS, rgb)).astype(np.float32)
    elif "RGB" in names or "RGBA" in names:
        pixels = channels["RGB" if "RGB" in names else "RGBA"].pixels.astype(np.float64)
        luminance = (pixels[..., :3] @ np.array(REC709_LUMINANCE_WEIGHTS)).astype(np.float32)
    else:
        raise UnsupportedFileError(f"{path}: no Y or R,G,B channels (has {sorted(names)})")
    uncertainty = None
    if UNCERTAINTY_CHANNEL in names:
        uncertainty = channels[UNCERTAINTY_CHANNEL].pixels.astype(np.float32)
    if METADATA_ATTRIBUTE in header:
        fields = metadata_fields(header[METADATA_ATTRIBUTE], path)
    else:
        fields = {"provenance": {"source": str(path), "note": "foreign EXR, relative scale"}}
        # Negative values from foreign files (e.g. filtered renderings) are not luminances;
        # our own maps keep their signed noise (see LuminanceMap).
        luminance = np.where(luminance < 0, np.nan, luminance)
    try:
        return LuminanceMap(luminance, uncertainty=uncertainty, **fields)
    except BadInputError as exc:  # e.g. a negative uncertainty channel, a projection of another size
        raise UnsupportedFileError(f"{path}: {exc}") from None
