"""Photometric calibration (spot meter, vignetting) and camera profiles.

Public names are imported on first use (:mod:`lsadphoto._lazy`): OpenCV and the RAW stage
load only where a calibration needs them.
"""

from .._lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, globals(), {
    ".profile": ["CameraProfile", "load_profile", "save_profile"],
    ".draft": ["draft_profile"],
    ".geometric": ["GeometricCalibration", "calibrate_geometry", "parse_pattern"],
    ".spot": ["SpotReading", "SpotCalibration", "calibrate_spots", "spot_cone"],
    ".vignetting": ["VignettingModel", "vignetting_gain", "fit_vignetting_polynomial"],
})
