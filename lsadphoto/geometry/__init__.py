"""Camera geometry: pixel directions and solid angles.

This stage holds the rectilinear pinhole model that the luminance stage needs for spot-meter
cones and Radiance VIEW= lines, and the ideal fisheye mappings (equidistant ``-vta``,
orthographic ``-vth``, stereographic ``-vts``, equisolid) and OpenCV's calibrated models (Brown–Conrady
pinhole, Kannala–Brandt fisheye), all behind the :class:`~lsadphoto.geometry.base.Projection`
interface. :class:`ObserverFrame` gives
the visual angles σ, τ (with a levelled horizon from the camera's roll and pitch),
:func:`position_index` the position index of evalglare, Guth or Kim et al., and
:func:`guth_field_mask` evalglare's cut to Guth's field of view. :func:`pixel_geometry` and
:func:`visual_field` give cached per-pixel maps of a whole image.
"""

from ._spherical import quad_solid_angle
from .base import Projection, projection_from_dict
from .field import (
    PixelGeometry,
    VisualField,
    clear_geometry_cache,
    pixel_geometry,
    visual_field,
)
from .fisheye import IdealFisheyeProjection
from .lensfun import LensfunProjection
from .observer import ObserverFrame
from .opencv import OpenCVFisheyeProjection, OpenCVPinholeProjection
from .pinhole import PinholeProjection
from .position_index import guth_field_mask, position_index

__all__ = [
    "IdealFisheyeProjection",
    "LensfunProjection",
    "ObserverFrame",
    "OpenCVFisheyeProjection",
    "OpenCVPinholeProjection",
    "PinholeProjection",
    "PixelGeometry",
    "Projection",
    "VisualField",
    "clear_geometry_cache",
    "guth_field_mask",
    "pixel_geometry",
    "position_index",
    "projection_from_dict",
    "quad_solid_angle",
    "visual_field",
]
