"""The interface every camera projection implements.

Array conventions (STYLE.md habit 7): images are ``(rows, cols)``; pixel ``(row, col)`` has its
centre at image coordinates ``u = col``, ``v = row`` (OpenCV's convention, corners at ±½).
Directions are unit vectors in the camera frame: x to the right of the image, y down the
image, z along the optical axis (OpenCV's camera frame).
"""

import math
from abc import ABC, abstractmethod

import numpy as np

from ..errors import BadInputError

_REGISTRY = {}


def check_image_size(width, height):
    """``(int(width), int(height))`` after checking both are positive integers [px]."""
    try:
        ok = int(width) == width and int(height) == height and width >= 1 and height >= 1
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise BadInputError(f"image size must be positive integers, got {width}×{height}")
    return int(width), int(height)


def check_centre(cx, cy):
    """``(float(cx), float(cy))`` after checking both are finite numbers [px]."""
    try:
        cx, cy = float(cx), float(cy)
    except (TypeError, ValueError):
        raise BadInputError(f"cx, cy must be numbers, got {cx!r}, {cy!r}") from None
    if not (math.isfinite(cx) and math.isfinite(cy)):
        raise BadInputError(f"cx, cy must be finite, got {cx!r}, {cy!r}")
    return cx, cy


def check_binning_factor(factor):
    """``int(factor)`` after checking it is a positive integer."""
    if int(factor) != factor or factor < 1:
        raise BadInputError(f"factor must be a positive integer, got {factor!r}")
    return int(factor)


def binned_coordinate(coordinate, factor):
    """Image coordinate [px] after ``factor``×``factor`` binning.

    New pixel ``u'`` covers old pixels ``factor·u' … factor·u' + factor − 1``, whose mean
    centre is ``factor·u' + (factor − 1)/2``.
    """
    return (coordinate - (factor - 1) / 2.0) / factor


class Projection(ABC):
    """A mapping between pixels of an image of fixed size and directions in the camera frame.

    Subclasses keep their image size in ``width`` and ``height`` and list their constructor
    arguments, in order, in ``_fields``; serialisation and equality follow from those.
    """

    #: Name used in serialised form (``{"model": name, ...}``).
    model = None
    #: Constructor arguments in order (attributes of the same names).
    _fields = ()

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.model is not None:
            _REGISTRY[cls.model] = cls

    @property
    def shape(self):
        """Image size ``(rows, cols)`` [px]."""
        return (self.height, self.width)

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

    def to_dict(self):
        """A JSON-serialisable description, inverted by :func:`projection_from_dict`."""
        out = {"model": self.model}
        for name in self._fields:
            value = getattr(self, name)
            out[name] = list(value) if isinstance(value, tuple) else value
        return out

    @classmethod
    def from_dict(cls, data):
        """Rebuild from :meth:`to_dict` output (see :func:`projection_from_dict`)."""
        try:
            return cls(*(data[name] for name in cls._fields))
        except KeyError as exc:
            raise BadInputError(f"{cls.model} projection lacks {exc.args[0]!r}") from None

    def __eq__(self, other):
        return type(other) is type(self) and self.to_dict() == other.to_dict()

    __hash__ = None

    def _grid_direction_components(self, rows, cols, *, corners=False):
        """Direction components ``(dx, dy, dz)``, each ``(len(rows), len(cols))``, on the grid
        ``rows[:, None] × cols[None, :]`` of image coordinates [px].

        Used by :func:`~lsadphoto.geometry.field.pixel_geometry`. With ``corners=True`` the
        points are pixel corners, for which a model may extend its mapping beyond its valid
        region (the ideal fisheye's centre rule); the default evaluates :meth:`directions`,
        so that the cached maps equal it element for element.
        """
        r, c = np.meshgrid(np.asarray(rows, float), np.asarray(cols, float), indexing="ij")
        d = self.directions(r, c)
        return d[..., 0], d[..., 1], d[..., 2]

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
