"""RAW decoding, exposure metadata, bracket merging and camera colour → luminance."""

from .bracket import MergedImage, NoiseModel, merge_bracket
from .colour import COLOUR_METHODS, camera_to_xyz_matrix, relative_luminance
from .decode import DEMOSAIC_METHODS, RawImage, decode_raw
from .metadata import ExposureMetadata, read_exposure_metadata

__all__ = [
    "DEMOSAIC_METHODS",
    "RawImage",
    "decode_raw",
    "ExposureMetadata",
    "read_exposure_metadata",
    "NoiseModel",
    "MergedImage",
    "merge_bracket",
    "COLOUR_METHODS",
    "camera_to_xyz_matrix",
    "relative_luminance",
]
