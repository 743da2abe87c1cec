"""lsadphoto: calibrated absolute luminance maps from RAW photographs of lit interiors.

The stages follow the data flow of DESIGN.md: :mod:`lsadphoto.raw` (decode, merge, colour),
:mod:`lsadphoto.calibrate` (vignetting, spot meter, camera profiles), :mod:`lsadphoto.geometry`,
:mod:`lsadphoto.io` (OpenEXR, Radiance HDR, false colour), tied together by
:func:`lsadphoto.luminance_from_raw`.
"""

from ._version import __version__
from .errors import BadInputError, LsadError, MissingMetadataError, UnsupportedFileError
from .luminance import LuminanceResult, luminance_from_raw
from .luminance_map import LuminanceMap

__all__ = [
    "__version__",
    "LuminanceMap",
    "luminance_from_raw",
    "LuminanceResult",
    "LsadError",
    "BadInputError",
    "MissingMetadataError",
    "UnsupportedFileError",
]
