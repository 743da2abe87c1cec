"""Figures and reports of scored maps and studies."""

from .figures import write_contrast_png, write_glare_source_png

__all__ = ["write_glare_source_png", "write_contrast_png"]
