"""The interface every camera projection implements.

Array conventions (STYLE.md habit 7): images are ``(rows, cols)``; pixel ``(row, col)`` has its
centre at image coordinates ``u = col``, ``v = row`` (OpenCV's convention, corners at ±½).
Directions are unit vectors in the camera frame: x to the right of the image, y down the
image, z along the optical axis (OpenCV's camera frame).
"""

from abc import ABC, abstractmethod

import numpy as np

from ..errors import BadInputError

_REGISTRY = {}


class Projection(ABC):
    """A mapping between pixels of an image of fixed size and directions in the camera frame."""

    #: Name used in serialised form (``{"model": name, ...}``).
    model = None

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.model is not None:
            _REGISTRY[cls.model] = cls

    @property
    @abstractmethod
    def shape(self):
        """Image size ``(rows, cols)`` [px]."""

    @abstractmethod
    def directions(self, rows, cols):
        """Unit direction vectors ``(..., 3)`` of image points ``(rows, cols)`` [px]."""

    @abstractmethod
    def project(self, directions):
        """Image points ``(rows, cols)`` [px] of direction vectors ``(..., 3)``."""

    @abstractmethod
    def solid_angles(self, rows, cols):
        """Solid angle [sr] of the pixels with integer indices ``(rows, cols)``."""

    @abstractmethod
    def binned(self, factor):
        """The same camera seen through ``factor`` × ``factor`` pixel binning."""

    @abstractmethod
    def to_dict(self):
        """A JSON-serialisable description, inverted by :func:`projection_from_dict`."""

    def pixel_grid(self):
        """Row and column index arrays of the whole image."""
        rows, cols = self.shape
        return np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")


def projection_from_dict(data):
    """Rebuild a projection from :meth:`Projection.to_dict` output."""
    if not isinstance(data, dict) or "model" not in data:
        raise BadInputError("projection description needs a 'model' key")
    cls = _REGISTRY.get(data["model"])
    if cls is None:
        valid = ", ".join(sorted(_REGISTRY))
        raise BadInputError(f"unknown projection model {data['model']!r}; valid: {valid}")
    return cls.from_dict(data)
