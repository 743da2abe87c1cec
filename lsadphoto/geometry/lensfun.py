"""Lens models of the lensfun database as a :class:`~lsadphoto.geometry.base.Projection`.

lensfun describes a lens by its projection type (rectilinear or one of several fisheyes) and
a radial distortion polynomial that maps an *undistorted* radius r_u to the *distorted*
(recorded) radius r_d, both in lensfun's normalised units:

* ``poly3``:  r_d = r_u·(1 − k₁ + k₁·r_u²)
* ``poly5``:  r_d = r_u·(1 + k₁·r_u² + k₂·r_u⁴)
* ``ptlens``: r_d = r_u·(a·r_u³ + b·r_u² + c·r_u + 1 − a − b − c)

The undistorted radius belongs to the lens's ideal projection of focal length f (same
units): r_u = f·tan θ (rectilinear), f·θ (``fisheye``, equidistant), 2f·sin(θ/2)
(equisolid), f·sin θ (orthographic), 2f·tan(θ/2) (stereographic), 1.47f·sin(0.713θ)
(Thoby). This module evaluates the model in numpy; the lensfun database itself is read by
:mod:`lsadphoto.calibrate.draft`, which turns a lens entry, the camera's crop factor and the
image size into the parameters here.

Normalised units follow lensfun 0.3 (``lfModifier``): one unit is ``scale`` pixels, half the
shorter image side of the *calibration* sensor mapped onto this image; the optical centre
lies at ``(cx, cy)`` [px]. Conventions otherwise those of :mod:`~lsadphoto.geometry.base`.

References
----------
lensfun documentation, "Lens distortion models" and "Coordinate systems"
(lensfun.github.io; ``libs/lensfun/modifier.cpp``, ``mod-coord.cpp`` of lensfun 0.3).
H. Dersch, *PanoTools* (the ``ptlens`` model, a, b, c). M. Thoby, "About the various
projections of the photographic objective lenses" (2012) for the Thoby fisheye.
"""

import math

import numpy as np

from .._validation import check_choice, check_positive
from ..errors import BadInputError
from ._spherical import corner_solid_angles
from .base import Projection, binned_coordinate, check_binning_factor, check_centre, check_image_size

__all__ = ["LensfunProjection", "LENS_KINDS", "DISTORTION_MODELS"]

#: Ideal projections of lensfun's lens types (lensfun names in the comments).
LENS_KINDS = ("rectilinear", "equidistant", "equisolid", "orthographic", "stereographic", "thoby")
#: Distortion models and their number of terms.
DISTORTION_MODELS = {"none": 0, "poly3": 1, "poly5": 2, "ptlens": 3}
#: Largest off-axis angle [rad] each ideal projection maps one-to-one.
_THETA_MAX = {"rectilinear": math.pi / 2, "equidistant": math.pi, "equisolid": math.pi,
              "orthographic": math.pi / 2, "stereographic": math.pi, "thoby": math.pi / 2 / 0.713}
_TOL = 1e-13
_MAX_ITER = 60


def _ideal_radius(kind, theta):
    """r/f of the ideal projection at off-axis angle θ [rad]."""
    if kind == "rectilinear":
        return np.tan(theta)
    if kind == "equidistant":
        return theta
    if kind == "equisolid":
        return 2.0 * np.sin(theta / 2.0)
    if kind == "orthographic":
        return np.sin(theta)
    if kind == "stereographic":
        return 2.0 * np.tan(theta / 2.0)
    return 1.47 * np.sin(0.713 * theta)


def _ideal_angle(kind, rho):
    """θ [rad] of the ideal projection at r/f = ρ (NaN beyond its range)."""
    with np.errstate(invalid="ignore"):
        if kind == "rectilinear":
            return np.arctan(rho)
        if kind == "equidistant":
            return np.where(rho <= math.pi, rho, np.nan)
        if kind == "equisolid":
            return 2.0 * np.arcsin(np.where(rho <= 2.0, rho / 2.0, np.nan))
        if kind == "orthographic":
            return np.arcsin(np.where(rho <= 1.0, rho, np.nan))
        if kind == "stereographic":
            return 2.0 * np.arctan(rho / 2.0)
        return np.arcsin(np.where(rho <= 1.47, rho / 1.47, np.nan)) / 0.713


class LensfunProjection(Projection):
    """A lens of the lensfun database: ideal projection plus radial distortion.

    Parameters
    ----------
    kind : {"rectilinear", "equidistant", "equisolid", "orthographic", "stereographic", "thoby"}
        The lens's ideal projection (lensfun ``RECTILINEAR``, ``FISHEYE``,
        ``FISHEYE_EQUISOLID``, ``FISHEYE_ORTHOGRAPHIC``, ``FISHEYE_STEREOGRAPHIC``,
        ``FISHEYE_THOBY``).
    distortion : {"none", "poly3", "poly5", "ptlens"}
    terms : sequence of float
        k₁ (poly3); k₁, k₂ (poly5); a, b, c (ptlens); empty for none [–].
    focal : float
        Focal length in normalised units [–] (lensfun: focal length in mm over
        ``NormalizedInMillimeters``).
    scale : float
        Pixels per normalised unit [px].
    cx, cy : float
        Optical centre [px], pixel-centre convention.
    width, height : int
        Image size [px].

    Notes
    -----
    The distortion is one-to-one up to the radius where r_u·P(r_u) stops increasing (found
    from the roots of its derivative); :meth:`directions` inverts it by Newton's method to a
    residual below 1e-13 and returns NaN beyond that radius or beyond the ideal projection's
    range (θ = 90° for rectilinear and orthographic lenses).

    Examples
    --------
    >>> cam = LensfunProjection("rectilinear", "poly3", [-0.02], 1.5, 500.0, 749.5, 499.5, 1500, 1000)
    >>> row, col = cam.project(cam.directions(100.0, 200.0))
    >>> round(float(row), 8), round(float(col), 8)
    (100.0, 200.0)
    """

    model = "lensfun"
    _fields = ("kind", "distortion", "terms", "focal", "scale", "cx", "cy", "width", "height")

    def __init__(self, kind, distortion, terms, focal, scale, cx, cy, width, height):
        self.kind = check_choice(kind, "lens kind", LENS_KINDS)
        self.distortion = check_choice(distortion, "distortion model", tuple(DISTORTION_MODELS))
        try:
            terms = tuple(float(t) for t in terms)
        except (TypeError, ValueError):
            raise BadInputError(f"distortion terms must be numbers, got {terms!r}") from None
        if len(terms) != DISTORTION_MODELS[self.distortion] or not all(map(math.isfinite, terms)):
            raise BadInputError(f"{self.distortion} distortion takes {DISTORTION_MODELS[self.distortion]} "
                                f"finite terms, got {terms!r}")
        self.terms = terms
        self.focal = check_positive(focal, "focal")
        self.scale = check_positive(scale, "scale")
        self.cx, self.cy = check_centre(cx, cy)
        self.width, self.height = check_image_size(width, height)
        self._poly = self._radial_polynomial()
        self.r_fold = self._fold_radius()

    def _radial_polynomial(self):
        """Coefficients (ascending powers of r_u) of r_d(r_u)."""
        t = self.terms
        if self.distortion == "poly3":
            return np.array([0.0, 1.0 - t[0], 0.0, t[0]])
        if self.distortion == "poly5":
            return np.array([0.0, 1.0, 0.0, t[0], 0.0, t[1]])
        if self.distortion == "ptlens":
            a, b, c = t
            return np.array([0.0, 1.0 - a - b - c, c, b, a])
        return np.array([0.0, 1.0])

    def _fold_radius(self):
        derivative = np.polynomial.polynomial.polyder(self._poly)
        roots = np.polynomial.polynomial.polyroots(derivative) if len(derivative) > 1 else []
        positive = [r.real for r in np.atleast_1d(roots) if abs(r.imag) < 1e-12 and r.real > 0]
        if derivative[0] <= 0:
            raise BadInputError(f"{self.distortion} distortion {self.terms} is not increasing at the centre")
        return min(positive, default=math.inf)

    def _distort(self, ru):
        return np.polynomial.polynomial.polyval(ru, self._poly)

    def undistort_radius(self, rd):
        """Undistorted radius r_u of distorted radii ``rd`` [normalised]; NaN beyond the fold."""
        rd = np.asarray(rd, float)
        if self.distortion == "none":
            return rd.copy()
        derivative = np.polynomial.polynomial.polyder(self._poly)
        limit = self._distort(self.r_fold) if math.isfinite(self.r_fold) else math.inf
        with np.errstate(invalid="ignore", over="ignore"):
            ok = rd < limit
            ru = np.where(ok, rd, np.nan)
            if math.isfinite(self.r_fold):
                ru = np.minimum(ru, 0.99 * self.r_fold)
            for _ in range(_MAX_ITER):
                step = (self._distort(ru) - rd) / np.polynomial.polynomial.polyval(ru, derivative)
                ru = ru - step
                if not np.any(np.abs(step) > _TOL):
                    break
            good = ok & (ru >= 0) & (ru < self.r_fold) & (np.abs(self._distort(ru) - rd) < 1e-10)
        return np.where(good, ru, np.nan)

    def directions(self, rows, cols):
        """Unit directions ``(..., 3)`` of image points ``(rows, cols)`` [px]; NaN where invalid."""
        rows, cols = np.broadcast_arrays(np.asarray(rows, float), np.asarray(cols, float))
        x, y = (cols - self.cx) / self.scale, (rows - self.cy) / self.scale
        rd = np.hypot(x, y)
        ru = self.undistort_radius(rd)
        theta = _ideal_angle(self.kind, ru / self.focal)
        with np.errstate(invalid="ignore", divide="ignore"):
            inv = np.where(rd > 0, 1.0 / rd, 0.0)
            s = np.sin(theta)
            out = np.stack([s * x * inv, s * y * inv, np.cos(theta)], axis=-1)
        return out

    def project(self, directions):
        """Image points ``(rows, cols)`` [px] of directions ``(..., 3)``; NaN outside the model."""
        d = np.asarray(directions, float)
        with np.errstate(invalid="ignore", divide="ignore"):
            d = d / np.linalg.norm(d, axis=-1, keepdims=True)
            theta = np.arccos(np.clip(d[..., 2], -1.0, 1.0))
            theta = np.where(theta < _THETA_MAX[self.kind], theta, np.nan)
            ru = self.focal * _ideal_radius(self.kind, theta)
            ru = np.where(ru < self.r_fold, ru, np.nan)
            rd = self._distort(ru)
            lateral = np.hypot(d[..., 0], d[..., 1])
            factor = np.where(lateral > 0, rd * self.scale / lateral, 0.0)
        return self.cy + d[..., 1] * factor, self.cx + d[..., 0] * factor

    def solid_angles(self, rows, cols):
        """Solid angle [sr] of pixels ``(rows, cols)``: the geodesic quadrilateral of their
        corner directions (0 where a corner lies outside the model)."""
        return corner_solid_angles(self.directions, rows, cols)

    def binned(self, factor):
        """The same lens seen through ``factor`` × ``factor`` binning (scale and centre move)."""
        factor = check_binning_factor(factor)
        return LensfunProjection(self.kind, self.distortion, self.terms, self.focal, self.scale / factor,
                                 binned_coordinate(self.cx, factor), binned_coordinate(self.cy, factor),
                                 self.width // factor, self.height // factor)

    def __repr__(self):
        return (f"LensfunProjection({self.kind!r}, {self.distortion!r}, {list(self.terms)}, focal={self.focal:.6g}, "
                f"scale={self.scale:.6g}, cx={self.cx:.6g}, cy={self.cy:.6g}, {self.width}×{self.height})")
