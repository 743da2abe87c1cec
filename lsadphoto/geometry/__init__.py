"""Camera geometry: pixel directions and solid angles.

This stage so far holds the rectilinear pinhole model that the luminance stage needs for
spot-meter cones and Radiance VIEW= lines; the full set of calibrated models (distortion,
fisheye, Radiance view types) plugs into the same :class:`~lsadphoto.geometry.base.Projection`
interface.
"""

from .base import Projection, projection_from_dict
from .pinhole import PinholeProjection

__all__ = ["Projection", "PinholeProjection", "projection_from_dict"]
