"""Reading and writing luminance maps: OpenEXR, Radiance HDR, false-colour PNG.

Public names are imported on first use (:mod:`lsadphoto._lazy`): reading a Radiance picture
does not load OpenEXR.
"""

from pathlib import Path

from .._lazy import lazy_exports
from ..errors import UnsupportedFileError

__getattr__, __dir__, _LAZY = lazy_exports(__name__, globals(), {
    ".exr": ["read_exr", "write_exr"],
    ".hdr": ["read_hdr", "write_hdr"],
    ".falsecolour": ["write_false_colour_png"],
})

__all__ = [*_LAZY, "read_map"]


def read_map(path):
    """Read a luminance map from an OpenEXR (``.exr``) or Radiance (``.hdr``/``.pic``) file."""
    suffix = Path(path).suffix.lower()
    if suffix == ".exr":
        from .exr import read_exr

        return read_exr(path)
    if suffix in (".hdr", ".pic", ".rgbe"):
        from .hdr import read_hdr

        return read_hdr(path)
    raise UnsupportedFileError(f"{path}: unknown map format {suffix!r} (expected .exr or .hdr)")
