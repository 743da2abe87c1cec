"""Synthetic data with known answers: a synthetic camera that writes real DNG files, and scenes.

Public names are imported on first use (:mod:`lsadphoto._lazy`).
"""

from .._lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, globals(), {
    ".synthetic": ["SyntheticCamera", "rotation_sequence", "write_dng"],
    ".scenes": ["interior_scene", "uniform_field", "disk_sources_scene",
                   "window_scene"],
})
