"""OpenCV's calibrated camera models, implemented in numpy.

Two models, with OpenCV's parameter conventions so that the output of ``cv2.calibrateCamera``
and ``cv2.fisheye.calibrate`` can be used as is:

* :class:`OpenCVPinholeProjection` (``"opencv-pinhole"``): the Brown–Conrady model of
  ``cv2.projectPoints`` with radial, tangential and rational terms
  ``(k1, k2, p1, p2[, k3[, k4, k5, k6]])``.
* :class:`OpenCVFisheyeProjection` (``"opencv-fisheye"``): the Kannala–Brandt model of
  ``cv2.fisheye.projectPoints`` with ``(k1, k2, k3, k4)`` and zero skew.

Both are evaluated here rather than by OpenCV, so that the inverse (pixel → direction) is
solved to a residual below 1e-12 in normalised coordinates (OpenCV's ``undistortPoints``
stops after a fixed number of iterations by default), and so that fisheye directions beyond
90° off axis are available. OpenCV serves as the independent reference in the tests.

Conventions are those of :mod:`~lsadphoto.geometry.base`, which are OpenCV's: pixel
``(row, col)`` has its centre at ``u = col``, ``v = row``; camera frame x right, y down,
z forward.

References
----------
OpenCV documentation, *Camera Calibration and 3D Reconstruction* (calib3d module, detailed
description) and *Fisheye camera model* (``cv::fisheye``), OpenCV 4.x/5.x.
D. C. Brown, "Decentering distortion of lenses", Photogramm. Eng. 32(3), 1966, 444–462.
J. Kannala & S. S. Brandt, "A generic camera model and calibration method for conventional,
wide-angle, and fish-eye lenses", IEEE TPAMI 28(8), 2006, 1335–1340.
"""

import math

import numpy as np

from .._validation import check_positive
from ..errors import BadInputError
from ._spherical import corner_solid_angles
from .base import (
    Projection,
    binned_coordinate,
    check_binning_factor,
    check_centre,
    check_image_size,
)
from .pinhole import PinholeProjection

__all__ = ["OpenCVFisheyeProjection", "OpenCVPinholeProjection"]

#: Newton stops when the residual [normalised units] is below this.
_TOL = 1e-12
_MAX_ITER = 100


def _check_distortion(distortion, lengths, model):
    try:
        d = np.asarray(distortion, dtype=float).ravel()
    except (TypeError, ValueError):
        raise BadInputError(f"distortion must be a numeric array, got {distortion!r}") from None
    if d.size not in lengths:
        valid = ", ".join(str(n) for n in lengths)
        raise BadInputError(
            f"distortion of the {model} model must have {valid} coefficients, got {d.size}"
        )
    if not np.all(np.isfinite(d)):
        raise BadInputError("distortion contains NaN or infinite values")
    return tuple(float(v) for v in d)


def _split_camera_matrix(K):
    K = np.asarray(K, dtype=float)
    if K.shape != (3, 3):
        raise BadInputError(f"camera matrix K must have shape (3, 3), got {K.shape}")
    if K[0, 1] != 0.0 or K[1, 0] != 0.0 or not np.array_equal(K[2], [0.0, 0.0, 1.0]):
        raise BadInputError(
            "camera matrix K must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew)"
        )
    return K[0, 0], K[1, 1], K[0, 2], K[1, 2]


def _smallest_positive_root(coefficients, upper=math.inf):
    """Smallest real root in (0, upper) of a polynomial (ascending coefficients), else inf."""
    from numpy.polynomial import polynomial as P  # not at import: 5 ms of every score process

    c = np.trim_zeros(np.asarray(coefficients, float), "b")
    if c.size <= 1:
        return math.inf
    roots = P.polyroots(c)
    real = roots.real[(np.abs(roots.imag) <= 1e-12 * np.maximum(1.0, np.abs(roots.real)))]
    real = real[(real > 0) & (real < upper)]
    return float(real.min()) if real.size else math.inf


class _OpenCVBase(Projection):
    """Shared parts: size, solid angles, serialisation, equality."""

    _lengths = ()
    _fields = ("fx", "fy", "cx", "cy", "distortion", "width", "height")

    def __init__(self, fx, fy, cx, cy, distortion, width, height):
        self.fx = check_positive(fx, "fx")
        self.fy = check_positive(fy, "fy")
        self.cx, self.cy = check_centre(cx, cy)
        self.distortion = _check_distortion(distortion, self._lengths, self.model)
        self.width, self.height = check_image_size(width, height)

    @property
    def camera_matrix(self):
        """OpenCV's 3×3 camera matrix K."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @classmethod
    def from_camera_matrix(cls, K, dist, width, height):
        """Model from OpenCV's camera matrix ``K`` (3×3, zero skew) and distortion array."""
        fx, fy, cx, cy = _split_camera_matrix(K)
        return cls(fx, fy, cx, cy, dist, width, height)

    def _normalised(self, rows, cols):
        rows, cols = np.broadcast_arrays(np.asarray(rows, float), np.asarray(cols, float))
        return (cols - self.cx) / self.fx, (rows - self.cy) / self.fy

    def _pixels(self, xd, yd):
        return self.cy + self.fy * yd, self.cx + self.fx * xd

    def solid_angles(self, rows, cols):
        """Solid angle [sr] of the pixels ``(rows, cols)``.

        The geodesic quadrilateral of the four pixel-corner directions
        (:func:`~lsadphoto.geometry._spherical.quad_solid_angle`). A pixel with a corner where
        :meth:`directions` is NaN (outside the model's one-to-one region) gets 0.
        """
        return corner_solid_angles(self.directions, rows, cols)

    def binned(self, factor):
        """Model after ``factor``×``factor`` binning (see :meth:`PinholeProjection.binned`).

        The distortion acts on normalised coordinates and is unchanged; ``fx/factor`` and
        ``cx' = (cx − (factor − 1)/2)/factor``.
        """
        factor = check_binning_factor(factor)
        return type(self)(
            self.fx / factor, self.fy / factor, binned_coordinate(self.cx, factor),
            binned_coordinate(self.cy, factor), self.distortion, self.width // factor,
            self.height // factor,
        )

    def radiance_view(self):
        """Radiance view options with the same pixel→direction mapping, where one exists.

        Radiance's views have no distortion terms, so only a model whose distortion
        coefficients are all zero has one: the Brown–Conrady model is then Radiance's
        perspective view ``-vtv`` (:meth:`PinholeProjection.radiance_view`) and the
        Kannala–Brandt model (θd = θ) its angular fisheye ``-vta``. Any other model raises
        :class:`~lsadphoto.errors.BadInputError` (the HDR writer then writes no ``VIEW=``
        line: a view that traced other rays would mislead evalglare).

        References
        ----------
        Radiance ``src/common/image.c`` (viewray), ``src/common/view.h`` (VT_PER, VT_ANG).

        Examples
        --------
        >>> OpenCVFisheyeProjection(300.0, 300.0, 299.5, 299.5, (0, 0, 0, 0), 600, 600).radiance_view()[:20]
        '-vta -vp 0 0 0 -vd 0'
        """
        if any(self.distortion):
            raise BadInputError(
                f"an {self.model} model with distortion {tuple(self.distortion)} has no Radiance view "
                "(Radiance views have no distortion terms)"
            )
        return self._undistorted_radiance_view()

    def __repr__(self):
        dist = ", ".join(f"{v:.6g}" for v in self.distortion)
        return (
            f"{type(self).__name__}(fx={self.fx:.6g}, fy={self.fy:.6g}, cx={self.cx:.6g}, "
            f"cy={self.cy:.6g}, distortion=({dist}), width={self.width}, height={self.height})"
        )


class OpenCVPinholeProjection(_OpenCVBase):
    """OpenCV's pinhole camera with Brown–Conrady distortion (``cv2.projectPoints``).

    With ``x' = X/Z``, ``y' = Y/Z``, ``r² = x'² + y'²``::

        x'' = x'·(1 + k1 r² + k2 r⁴ + k3 r⁶)/(1 + k4 r² + k5 r⁴ + k6 r⁶) + 2 p1 x'y' + p2 (r² + 2x'²)
        y'' = y'·(1 + k1 r² + k2 r⁴ + k3 r⁶)/(1 + k4 r² + k5 r⁴ + k6 r⁶) + p1 (r² + 2y'²) + 2 p2 x'y'
        u = fx·x'' + cx,   v = fy·y'' + cy

    Parameters
    ----------
    fx, fy : float
        Focal lengths [px].
    cx, cy : float
        Principal point [px], pixel-centre convention (OpenCV's).
    distortion : sequence of 4, 5 or 8 floats
        ``(k1, k2, p1, p2[, k3[, k4, k5, k6]])`` [1]; missing ones are zero. OpenCV's thin-prism
        and tilt terms (12 or 14 coefficients) are not supported.
    width, height : int
        Image size [px].

    Notes
    -----
    The model is one-to-one only inside the radius ``r_fold`` where the radial part
    ``r·(1 + k1 r² + …)/(1 + k4 r² + …)`` stops increasing (or its denominator vanishes);
    :attr:`r_fold` is found exactly from the roots of the derivative's numerator. :meth:`project`
    returns NaN for directions with ``z ≤ 0`` or ``r ≥ r_fold``; :meth:`directions` inverts the
    distortion by Newton's method on ``(x', y')`` with the analytic 2×2 Jacobian to a residual
    below 1e-12 and returns NaN where it does not converge, where the solution lies at or
    beyond ``r_fold`` or where the Jacobian determinant is not positive (a folded region).

    References
    ----------
    OpenCV calib3d documentation (detailed description of the pinhole model);
    D. C. Brown, Photogramm. Eng. 32(3), 1966, 444–462.

    Examples
    --------
    >>> cam = OpenCVPinholeProjection(800.0, 800.0, 319.5, 239.5, (-0.2, 0.05, 0.0, 0.0), 640, 480)
    >>> row, col = cam.project(cam.directions(10.0, 20.0))
    >>> round(float(row), 9), round(float(col), 9)
    (10.0, 20.0)
    """

    model = "opencv-pinhole"
    _lengths = (4, 5, 8)

    def __init__(self, fx, fy, cx, cy, distortion, width, height):
        super().__init__(fx, fy, cx, cy, distortion, width, height)
        d = self.distortion + (0.0,) * (8 - len(self.distortion))
        self._k1, self._k2, self._p1, self._p2, self._k3, self._k4, self._k5, self._k6 = d
        self.r_fold = self._fold_radius()

    @classmethod
    def from_camera_matrix(cls, K, dist, width, height):
        """Model from OpenCV's ``K`` and ``dist`` (4, 5 or 8 values; 12 or 14 if the extra
        thin-prism and tilt terms are all zero)."""
        d = np.asarray(dist, dtype=float).ravel()
        if d.size in (12, 14) and np.all(d[8:] == 0.0):
            d = d[:8]
        return super().from_camera_matrix(K, d, width, height)

    def _undistorted_radiance_view(self):
        return PinholeProjection(self.fx, self.fy, self.cx, self.cy, self.width, self.height).radiance_view()

    def _fold_radius(self):
        """Radius r [normalised] where the radial mapping stops increasing (inf if never)."""
        from numpy.polynomial import polynomial as P

        n = np.array([1.0, self._k1, self._k2, self._k3])  # N(s), s = r²
        d = np.array([1.0, self._k4, self._k5, self._k6])  # D(s)
        s = np.array([0.0, 1.0])
        # d/dr [r N/D] = ((N + 2s N') D − 2s N D') / D²
        num = P.polysub(P.polymul(P.polyadd(n, P.polymul(2 * s, P.polyder(n))), d),
                        P.polymul(P.polymul(2 * s, n), P.polyder(d)))
        s_fold = min(_smallest_positive_root(num), _smallest_positive_root(d))
        return math.sqrt(s_fold)

    def _distort(self, x, y, jacobian=False):
        r2 = x * x + y * y
        n = 1.0 + r2 * (self._k1 + r2 * (self._k2 + r2 * self._k3))
        d = 1.0 + r2 * (self._k4 + r2 * (self._k5 + r2 * self._k6))
        g = n / d
        xy = x * y
        xd = x * g + 2.0 * self._p1 * xy + self._p2 * (r2 + 2.0 * x * x)
        yd = y * g + self._p1 * (r2 + 2.0 * y * y) + 2.0 * self._p2 * xy
        if not jacobian:
            return xd, yd
        dn = self._k1 + r2 * (2.0 * self._k2 + 3.0 * self._k3 * r2)
        dd = self._k4 + r2 * (2.0 * self._k5 + 3.0 * self._k6 * r2)
        gp = (dn * d - n * dd) / (d * d)  # dg/d(r²)
        jxx = g + 2.0 * x * x * gp + 2.0 * self._p1 * y + 6.0 * self._p2 * x
        jxy = 2.0 * xy * gp + 2.0 * self._p1 * x + 2.0 * self._p2 * y
        jyx = 2.0 * xy * gp + 2.0 * self._p1 * x + 2.0 * self._p2 * y
        jyy = g + 2.0 * y * y * gp + 6.0 * self._p1 * y + 2.0 * self._p2 * x
        return xd, yd, jxx, jxy, jyx, jyy

    def project(self, directions):
        """Image points ``(rows, cols)`` [px]; NaN for ``z ≤ 0`` or beyond :attr:`r_fold`."""
        d = np.asarray(directions, float)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(d[..., 2] > 0, d[..., 2], np.nan)
            x, y = d[..., 0] / z, d[..., 1] / z
            ok = x * x + y * y < self.r_fold ** 2
            x, y = np.where(ok, x, np.nan), np.where(ok, y, np.nan)
            return self._pixels(*self._distort(x, y))

    def undistort_normalised(self, xd, yd):
        """Undistorted ``(x', y')`` of distorted normalised points ``(x'', y'')`` (Newton)."""
        xd, yd = np.broadcast_arrays(np.asarray(xd, float), np.asarray(yd, float))
        rmax2 = self.r_fold ** 2
        with np.errstate(all="ignore"):
            # Start at the distorted point, pulled inside the fold radius if needed.
            r0 = np.hypot(xd, yd)
            scale = np.where(r0 < 0.9 * self.r_fold, 1.0, 0.9 * self.r_fold / r0)
            x, y = xd * scale, yd * scale
            fx, fy = self._distort(x, y)
            fx, fy = fx - xd, fy - yd
            res = np.hypot(fx, fy)
            failed = ~np.isfinite(res)
            for _ in range(_MAX_ITER):
                active = (res >= _TOL) & ~failed
                if not np.any(active):
                    break
                _, _, jxx, jxy, jyx, jyy = self._distort(x, y, jacobian=True)
                det = jxx * jyy - jxy * jyx
                sx = (jyy * fx - jxy * fy) / det
                sy = (jxx * fy - jyx * fx) / det
                step = np.where(active, 1.0, 0.0)
                # Backtracking: halve the step until the residual drops and the iterate
                # stays inside the fold radius.
                for _ in range(40):
                    nx, ny = x - step * sx, y - step * sy
                    gx, gy = self._distort(nx, ny)
                    gx, gy = gx - xd, gy - yd
                    nres = np.hypot(gx, gy)
                    good = (nres < res) & (nx * nx + ny * ny < rmax2)
                    retry = active & ~good & (step > 0)
                    if not np.any(retry):
                        break
                    step = np.where(retry, step * 0.5, step)
                accept = active & good
                x, y = np.where(accept, nx, x), np.where(accept, ny, y)
                fx, fy = np.where(accept, gx, fx), np.where(accept, gy, fy)
                res = np.where(accept, nres, res)
                failed |= active & ~good
            _, _, jxx, jxy, jyx, jyy = self._distort(x, y, jacobian=True)
            ok = (res < _TOL) & ~failed & (x * x + y * y < rmax2) & (jxx * jyy - jxy * jyx > 0)
        return np.where(ok, x, np.nan), np.where(ok, y, np.nan)

    def directions(self, rows, cols):
        """Unit directions ``(..., 3)``; NaN outside the one-to-one region (see Notes)."""
        x, y = self.undistort_normalised(*self._normalised(rows, cols))
        norm = np.sqrt(1.0 + x * x + y * y)
        return np.stack([x / norm, y / norm, 1.0 / norm], axis=-1)


class OpenCVFisheyeProjection(_OpenCVBase):
    """OpenCV's fisheye camera (Kannala–Brandt, ``cv2.fisheye.projectPoints``), zero skew.

    A direction at angle θ from the optical axis and azimuth φ maps to::

        θd = θ·(1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸)
        x' = θd cos φ,  y' = θd sin φ,   u = fx·x' + cx,  v = fy·y' + cy

    which for z > 0 is OpenCV's ``x' = (θd/r)·a`` with ``θ = atan(r)``; here θ comes from the
    direction itself, so that directions behind the camera (θ > 90°) are mapped too.

    Parameters
    ----------
    fx, fy : float
        Focal lengths [px].
    cx, cy : float
        Principal point [px], pixel-centre convention (OpenCV's).
    distortion : sequence of 4 floats
        ``(k1, k2, k3, k4)`` [1].
    width, height : int
        Image size [px].

    Notes
    -----
    The model is one-to-one for θ < :attr:`theta_max`, the smaller of π and the first root of
    dθd/dθ = 1 + 3k1θ² + 5k2θ⁴ + 7k3θ⁶ + 9k4θ⁸ (found exactly). :meth:`project` returns NaN
    beyond it; :meth:`directions` solves θd(θ) = ρ by bracketed Newton on [0, theta_max]
    to a residual below 1e-12 and returns NaN where ρ ≥ θd(theta_max).

    References
    ----------
    OpenCV documentation, ``cv::fisheye`` (fisheye camera model);
    J. Kannala & S. S. Brandt, IEEE TPAMI 28(8), 2006, 1335–1340.

    Examples
    --------
    >>> cam = OpenCVFisheyeProjection(300.0, 300.0, 499.5, 499.5, (0.05, -0.01, 0.003, -0.0005),
    ...                               1000, 1000)
    >>> row, col = cam.project(cam.directions(499.5, 980.0))
    >>> round(float(row), 9), round(float(col), 9)
    (499.5, 980.0)
    """

    model = "opencv-fisheye"
    _lengths = (4,)

    def __init__(self, fx, fy, cx, cy, distortion, width, height):
        super().__init__(fx, fy, cx, cy, distortion, width, height)
        k1, k2, k3, k4 = self.distortion
        # dθd/dθ as a polynomial in t = θ².
        t_fold = _smallest_positive_root([1.0, 3 * k1, 5 * k2, 7 * k3, 9 * k4], math.pi ** 2)
        self.theta_max = min(math.pi, math.sqrt(t_fold))
        self._rho_max = float(self._theta_d(self.theta_max))

    def _undistorted_radiance_view(self):
        # θ = ρ with ρ = (u − cx)/fx: Radiance's -vta has θ = π·X with X = x·vh/180 and
        # x = (u + ½)/W − ½ + vs, so vh = W/fx [rad] and the centre shift as for -vtv.
        vh, vv = math.degrees(self.width / self.fx), math.degrees(self.height / self.fy)
        vs = 0.5 - (self.cx + 0.5) / self.width
        vl = (self.cy + 0.5) / self.height - 0.5
        return (f"-vta -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh {vh:.17g} -vv {vv:.17g} "
                f"-vs {vs:.17g} -vl {vl:.17g}")

    def _theta_d(self, theta):
        k1, k2, k3, k4 = self.distortion
        t2 = theta * theta
        return theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))

    def _dtheta_d(self, theta):
        k1, k2, k3, k4 = self.distortion
        t2 = theta * theta
        return 1.0 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))

    def project(self, directions):
        """Image points ``(rows, cols)`` [px]; NaN where θ ≥ :attr:`theta_max`."""
        d = np.asarray(directions, float)
        rho = np.hypot(d[..., 0], d[..., 1])
        theta = np.arctan2(rho, d[..., 2])
        theta = np.where(theta < self.theta_max, theta, np.nan)
        with np.errstate(divide="ignore", invalid="ignore"):
            ca = np.where(rho > 0, d[..., 0] / rho, 1.0)
            sa = np.where(rho > 0, d[..., 1] / rho, 0.0)
        td = self._theta_d(theta)
        return self._pixels(td * ca, td * sa)

    def theta(self, rho):
        """Off-axis angle θ [rad] of distorted radius ``rho`` = θd [normalised]; NaN beyond."""
        rho = np.asarray(rho, float)
        lo = np.zeros(rho.shape)
        hi = np.full(rho.shape, self.theta_max)
        ok = (rho >= 0) & (rho < self._rho_max)
        target = np.where(ok, rho, 0.0)
        theta = np.minimum(target, 0.5 * self.theta_max)
        res = self._theta_d(theta) - target
        for _ in range(_MAX_ITER):
            active = np.abs(res) >= _TOL
            if not np.any(active):
                break
            lo = np.where(res < 0, theta, lo)
            hi = np.where(res > 0, theta, hi)
            with np.errstate(divide="ignore", invalid="ignore"):
                new = theta - res / self._dtheta_d(theta)
            inside = (new > lo) & (new < hi)
            new = np.where(inside, new, 0.5 * (lo + hi))
            theta = np.where(active, new, theta)
            res = self._theta_d(theta) - target
        ok &= np.abs(res) < _TOL
        return np.where(ok, theta, np.nan)

    def directions(self, rows, cols):
        """Unit directions ``(..., 3)``, θ up to :attr:`theta_max`; NaN beyond."""
        xd, yd = self._normalised(rows, cols)
        rho = np.hypot(xd, yd)
        theta = self.theta(rho)
        with np.errstate(divide="ignore", invalid="ignore"):
            ca = np.where(rho > 0, xd / rho, 1.0)
            sa = np.where(rho > 0, yd / rho, 0.0)
        s = np.sin(theta)
        return np.stack([s * ca, s * sa, np.cos(theta)], axis=-1)
