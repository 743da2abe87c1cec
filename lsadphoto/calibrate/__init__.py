"""Photometric calibration (spot meter, vignetting) and camera profiles."""

from .draft import draft_profile
from .geometric import GeometricCalibration, calibrate_geometry, parse_pattern
from .profile import CameraProfile, load_profile, save_profile
from .spot import SpotCalibration, SpotReading, calibrate_spots, spot_cone
from .vignetting import VignettingModel, fit_vignetting_polynomial, vignetting_gain

__all__ = [
    "CameraProfile",
    "draft_profile",
    "GeometricCalibration",
    "calibrate_geometry",
    "parse_pattern",
    "load_profile",
    "save_profile",
    "SpotReading",
    "SpotCalibration",
    "calibrate_spots",
    "spot_cone",
    "VignettingModel",
    "vignetting_gain",
    "fit_vignetting_polynomial",
]
