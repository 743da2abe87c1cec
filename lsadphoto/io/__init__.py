"""Reading and writing luminance maps: OpenEXR, Radiance HDR, false-colour PNG."""

from pathlib import Path

from ..errors import UnsupportedFileError
from .exr import read_exr, write_exr
from .falsecolour import write_false_colour_png
from .hdr import read_hdr, write_hdr

__all__ = [
    "read_exr",
    "write_exr",
    "read_hdr",
    "write_hdr",
    "read_map",
    "write_false_colour_png",
]


def read_map(path):
    """Read a luminance map from an OpenEXR (``.exr``) or Radiance (``.hdr``/``.pic``) file."""
    suffix = Path(path).suffix.lower()
    if suffix == ".exr":
        return read_exr(path)
    if suffix in (".hdr", ".pic", ".rgbe"):
        return read_hdr(path)
    raise UnsupportedFileError(f"{path}: unknown map format {suffix!r} (expected .exr or .hdr)")
