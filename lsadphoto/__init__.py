"""lsadphoto: calibrated absolute luminance maps from RAW photographs of lit interiors.

The stages follow the data flow of DESIGN.md: :mod:`lsadphoto.raw` (decode, merge, colour),
:mod:`lsadphoto.calibrate` (vignetting, spot meter, camera profiles), :mod:`lsadphoto.geometry`,
:mod:`lsadphoto.io` (OpenEXR, Radiance HDR, false colour), tied together by
:func:`lsadphoto.luminance_from_raw`.

The public names below are imported when first used (:mod:`lsadphoto._lazy`), so that a
command such as ``lsadphoto score`` loads only the stages it needs.
"""

from ._lazy import lazy_exports
from ._version import __version__
from .errors import BadInputError, LsadError, MissingMetadataError, UnsupportedFileError

__getattr__, __dir__, _LAZY = lazy_exports(__name__, globals(), {
    ".luminance_map": ["LuminanceMap"],
    ".luminance": ["luminance_from_raw", "LuminanceResult"],
})

__all__ = [
    "__version__",
    *_LAZY,
    "LsadError",
    "BadInputError",
    "MissingMetadataError",
    "UnsupportedFileError",
]
