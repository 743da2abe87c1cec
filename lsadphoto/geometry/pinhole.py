"""Ideal rectilinear (pinhole) projection without distortion."""

import math

import numpy as np

from .._validation import check_positive
from .base import (
    Projection,
    binned_coordinate,
    check_binning_factor,
    check_centre,
    check_image_size,
)


class PinholeProjection(Projection):
    """Ideal pinhole camera: ``u = cx + fx·x/z``, ``v = cy + fy·y/z``.

    Parameters
    ----------
    fx, fy : float
        Focal lengths [px].
    cx, cy : float
        Principal point [px], in the pixel-centre convention of :mod:`~lsadphoto.geometry.base`.
    width, height : int
        Image size [px].

    References
    ----------
    Hartley & Zisserman, *Multiple View Geometry*, 2nd ed., §6.1. Radiance ``-vtv`` view
    (``src/common/image.c`` viewray).

    Examples
    --------
    >>> cam = PinholeProjection.from_sensor(focal_length=18.0, sensor_width=23.1,
    ...                                     sensor_height=15.4, width=4608, height=3072)
    >>> round(cam.fx, 3)
    3590.649
    """

    model = "pinhole"
    _fields = ("fx", "fy", "cx", "cy", "width", "height")

    def __init__(self, fx, fy, cx, cy, width, height):
        self.fx = check_positive(fx, "fx")
        self.fy = check_positive(fy, "fy")
        self.cx, self.cy = check_centre(cx, cy)
        self.width, self.height = check_image_size(width, height)

    @classmethod
    def from_sensor(cls, *, focal_length, sensor_width, sensor_height, width, height):
        """Nominal model from the lens focal length [mm] and the sensor size [mm] and [px]."""
        focal_length = check_positive(focal_length, "focal_length")
        fx = focal_length * width / check_positive(sensor_width, "sensor_width")
        fy = focal_length * height / check_positive(sensor_height, "sensor_height")
        return cls(fx, fy, (width - 1) / 2.0, (height - 1) / 2.0, width, height)

    def _plane(self, rows, cols):
        return (np.asarray(cols, float) - self.cx) / self.fx, (np.asarray(rows, float) - self.cy) / self.fy

    def directions(self, rows, cols):
        x, y = self._plane(rows, cols)
        norm = np.sqrt(1.0 + x * x + y * y)
        return np.stack([x / norm, y / norm, 1.0 / norm], axis=-1)

    def project(self, directions):
        d = np.asarray(directions, float)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(d[..., 2] > 0, d[..., 2], np.nan)
            return self.cy + self.fy * d[..., 1] / z, self.cx + self.fx * d[..., 0] / z

    def solid_angles(self, rows, cols):
        """Exact solid angle [sr] of each pixel rectangle on the image plane.

        Uses F(X, Y) = arctan(XY / √(1 + X² + Y²)) at the four pixel corners (FORMULAS.md
        §2.4.2, the ``-vtv`` row), which is exact for a rectangle on the plane z = 1.
        """
        rows = np.asarray(rows, float)
        cols = np.asarray(cols, float)
        x1, y1 = self._plane(rows - 0.5, cols - 0.5)
        x2, y2 = self._plane(rows + 0.5, cols + 0.5)

        def f(x, y):
            return np.arctan(x * y / np.sqrt(1.0 + x * x + y * y))

        return f(x2, y2) - f(x1, y2) - f(x2, y1) + f(x1, y1)

    def binned(self, factor):
        """Model of the image after ``factor``×``factor`` binning (superpixel demosaic);
        see :func:`~lsadphoto.geometry.base.binned_coordinate`."""
        factor = check_binning_factor(factor)
        return PinholeProjection(
            self.fx / factor,
            self.fy / factor,
            binned_coordinate(self.cx, factor),
            binned_coordinate(self.cy, factor),
            self.width // factor,
            self.height // factor,
        )

    def radiance_view(self):
        """Radiance view options (``-vtv …``) for the same pixels (FORMULAS.md §2.4.2).

        Radiance maps pixel ``i`` to ``x = (i + ½)/X − ½ + vs``, rows counted from the
        bottom; equating with this model gives ``vs = ½ − (cx + ½)/W`` and
        ``vl = (cy + ½)/H − ½``. Numbers are written with 17 significant digits, so that
        the round trip through Radiance's ``atof`` is exact.
        """
        vh = math.degrees(2.0 * math.atan(self.width / (2.0 * self.fx)))
        vv = math.degrees(2.0 * math.atan(self.height / (2.0 * self.fy)))
        vs = 0.5 - (self.cx + 0.5) / self.width
        vl = (self.cy + 0.5) / self.height - 0.5
        return (
            f"-vtv -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh {vh:.17g} -vv {vv:.17g} "
            f"-vs {vs:.17g} -vl {vl:.17g}"
        )

    @classmethod
    def from_radiance_view(cls, options, width, height):
        """Inverse of :meth:`radiance_view` for a parsed ``-vtv`` view (dict of floats)."""
        vh = options.get("vh", 45.0)
        vv = options.get("vv", 45.0)
        fx = width / (2.0 * math.tan(math.radians(vh) / 2.0))
        fy = height / (2.0 * math.tan(math.radians(vv) / 2.0))
        cx = (0.5 - options.get("vs", 0.0)) * width - 0.5
        cy = (options.get("vl", 0.0) + 0.5) * height - 0.5
        return cls(fx, fy, cx, cy, width, height)

    def __repr__(self):
        return (
            f"PinholeProjection(fx={self.fx:.6g}, fy={self.fy:.6g}, cx={self.cx:.6g}, "
            f"cy={self.cy:.6g}, width={self.width}, height={self.height})"
        )
