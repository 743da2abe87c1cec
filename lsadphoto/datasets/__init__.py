"""Synthetic data with known answers: a synthetic camera that writes real DNG files, and scenes."""

from .scenes import disk_sources_scene, interior_scene, uniform_field
from .synthetic import SyntheticCamera, rotation_sequence, write_dng

__all__ = ["SyntheticCamera", "rotation_sequence", "write_dng", "interior_scene", "uniform_field", "disk_sources_scene"]
