"""Camera geometry: pixel directions and solid angles.

This stage holds the rectilinear pinhole model that the luminance stage needs for spot-meter
cones and Radiance VIEW= lines, and the ideal fisheye mappings (equidistant ``-vta``,
orthographic ``-vth``, equisolid, stereographic) and OpenCV's calibrated models (Brown–Conrady
pinhole, Kannala–Brandt fisheye), all behind the :class:`~lsadphoto.geometry.base.Projection`
interface. :class:`ObserverFrame` gives
the visual angles σ, τ and :func:`position_index` the position index of evalglare, Guth or
Kim et al.
"""

from ._spherical import quad_solid_angle
from .base import Projection, projection_from_dict
from .fisheye import IdealFisheyeProjection
from .observer import ObserverFrame
from .opencv import OpenCVFisheyeProjection, OpenCVPinholeProjection
from .pinhole import PinholeProjection
from .position_index import position_index

__all__ = [
    "IdealFisheyeProjection",
    "ObserverFrame",
    "OpenCVFisheyeProjection",
    "OpenCVPinholeProjection",
    "PinholeProjection",
    "Projection",
    "projection_from_dict",
    "position_index",
    "quad_solid_angle",
]
