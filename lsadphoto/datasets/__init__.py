"""Synthetic data with known answers: a synthetic camera that writes real DNG files, and scenes."""

from .scenes import interior_scene, uniform_field
from .synthetic import SyntheticCamera, write_dng

__all__ = ["SyntheticCamera", "write_dng", "interior_scene", "uniform_field"]
