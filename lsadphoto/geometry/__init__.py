"""Camera geometry: pixel directions and solid angles.

This stage holds the rectilinear pinhole model that the luminance stage needs for spot-meter
cones and Radiance VIEW= lines, and the ideal fisheye mappings (equidistant ``-vta``,
orthographic ``-vth``, equisolid, stereographic); calibrated models with distortion plug into
the same :class:`~lsadphoto.geometry.base.Projection` interface.
"""

from ._spherical import quad_solid_angle
from .base import Projection, projection_from_dict
from .fisheye import IdealFisheyeProjection
from .pinhole import PinholeProjection

__all__ = [
    "IdealFisheyeProjection",
    "PinholeProjection",
    "Projection",
    "projection_from_dict",
    "quad_solid_angle",
]
