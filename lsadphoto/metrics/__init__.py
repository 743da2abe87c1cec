"""Lighting-quality metrics of absolute luminance maps."""
