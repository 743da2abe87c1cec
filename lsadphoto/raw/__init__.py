"""RAW decoding, exposure metadata, bracket merging and camera colour → luminance.

Public names are imported on first use (:mod:`lsadphoto._lazy`), so that commands which
never read a RAW file do not load LibRaw and its metadata readers.
"""

from .._lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, globals(), {
    ".methods": ["DEMOSAIC_METHODS"],
    ".decode": ["RawImage", "decode_raw"],
    ".metadata": ["ExposureMetadata", "read_exposure_metadata"],
    ".bracket": ["NoiseModel", "MergedImage", "merge_bracket"],
    ".colour": ["COLOUR_METHODS", "camera_to_xyz_matrix", "relative_luminance"],
})
