"""Ideal (distortion-free) fisheye projections with a circular image.

A radial lens maps the off-axis angle θ of a direction to the image radius ``r = g(θ)`` [px]
measured from the image-circle centre ``(cx, cy)``; the azimuth is kept. With θmax = fov/2
and ``R`` the image-circle radius [px] (``g(θmax) = R``):

* equidistant:   r = R·θ/θmax                  (Radiance ``-vta``)
* equisolid:     r = R·sin(θ/2)/sin(θmax/2)
* orthographic:  r = R·sin θ/sin θmax          (Radiance ``-vth``)
* stereographic: r = R·tan(θ/2)/tan(θmax/2)    (Radiance ``-vts``)

Conventions are those of :mod:`~lsadphoto.geometry.base` (pixel centres at integer
``(row, col)``, x right, y down the image, z along the optical axis).

References
----------
FORMULAS.md §2.4.2 (Radiance viewray for ``-vta``/``-vth``/``-vts``; pixel solid angles);
K. Miyamoto, "Fish eye lens", J. Opt. Soc. Am. 54(8), 1964, 1060–1061 (the four mappings).
"""

import itertools
import math

import numpy as np

from .._validation import check_choice, check_positive
from ..errors import BadInputError
from .base import (
    Projection,
    binned_coordinate,
    check_binning_factor,
    check_centre,
    check_image_size,
)

__all__ = ["IdealFisheyeProjection"]

KINDS = ("equidistant", "equisolid", "orthographic", "stereographic")
#: Largest full field of view [deg] each mapping can represent one-to-one.
_MAX_FOV = {"equidistant": 360.0, "equisolid": 360.0, "orthographic": 180.0, "stereographic": 360.0}
#: Radiance view types (``-vt?``) this model reproduces.
_RADIANCE_TYPES = {"a": "equidistant", "h": "orthographic", "s": "stereographic"}
#: Names of Radiance's view types (``src/common/view.h``), for messages.
RADIANCE_VIEW_NAMES = {"v": "perspective", "l": "parallel", "c": "cylindrical panorama",
                       "h": "hemispherical fisheye", "a": "angular fisheye",
                       "s": "planisphere (stereographic) fisheye"}
#: Largest θ [rad] each mapping reaches when extended beyond the image circle.
_MAX_THETA = {"equidistant": math.pi, "equisolid": math.pi, "orthographic": math.pi / 2,
              "stereographic": math.pi}


def _g(kind, theta):
    """Un-normalised radial function g(θ) of the mapping."""
    if kind == "equidistant":
        return theta
    if kind == "equisolid":
        return np.sin(theta / 2.0)
    if kind == "orthographic":
        return np.sin(theta)
    return np.tan(theta / 2.0)


class IdealFisheyeProjection(Projection):
    """Ideal fisheye lens of one of four radial mappings, clipped to its image circle.

    Parameters
    ----------
    kind : {"equidistant", "equisolid", "orthographic", "stereographic"}
        Radial mapping.
    cx, cy : float
        Centre of the image circle [px], pixel-centre convention.
    radius : float
        Radius R of the image circle [px], where θ = fov/2.
    fov_deg : float
        Full field of view of the image circle [deg] (≤ 180 for orthographic, < 360 for
        stereographic, ≤ 360 otherwise).
    width, height : int
        Image size [px].

    Notes
    -----
    Points with ``r > R`` (θ > fov/2) are invalid: :meth:`directions` returns NaN there and
    :meth:`valid` False. :meth:`solid_angles` follows evalglare (FORMULAS.md §2.4.2): the
    geodesic quadrilateral of the four pixel-corner directions. A pixel counts if and only if
    its *centre* is valid (centre rule); the corners of rim pixels are taken from the mapping
    extended beyond the circle (θ clamped to where the mapping ends, 90° for orthographic).
    The centre rule makes the sum over a 180° circle miss 2π by what the rim pixels gain
    or lose: measured for R = 500 px, relative +5.8e-5 (equidistant), +7.5e-5 (equisolid),
    +3.7e-5 (stereographic) and −1.5 % (orthographic, whose pixels grow without bound
    towards 90°, so clamping their outer corners to the horizon cuts them short).
    :meth:`clipped_solid_angles` gives the exact share of each pixel inside the circle
    instead, which sums to 2π(1 − cos θmax) to rounding; use it for field integrals where
    the rim matters.

    Examples
    --------
    >>> cam = IdealFisheyeProjection("equidistant", 499.5, 499.5, 500.0, 180.0, 1000, 1000)
    >>> float(cam.directions(499.5, 499.5)[2])
    1.0
    """

    model = "fisheye-ideal"
    _fields = ("kind", "cx", "cy", "radius", "fov_deg", "width", "height")

    def __init__(self, kind, cx, cy, radius, fov_deg, width, height):
        self.kind = check_choice(kind, "fisheye kind", KINDS)
        self.cx, self.cy = check_centre(cx, cy)
        self.radius = check_positive(radius, "radius")
        self.fov_deg = check_positive(fov_deg, "fov_deg")
        limit = _MAX_FOV[self.kind]
        if self.fov_deg > limit or (self.kind == "stereographic" and self.fov_deg >= limit):
            raise BadInputError(
                f"fov_deg must be {'<' if self.kind == 'stereographic' else '≤'} {limit:g} "
                f"for a {self.kind} fisheye, got {fov_deg!r}"
            )
        self.width, self.height = check_image_size(width, height)

    # --- mapping ---------------------------------------------------------------------------

    @property
    def theta_max(self):
        """Half field of view θmax [rad]."""
        return math.radians(self.fov_deg) / 2.0

    def _theta(self, r):
        """θ [rad] of image radius ``r`` [px], extended (and clamped) beyond the circle."""
        t = r / self.radius
        tm = self.theta_max
        if self.kind == "equidistant":
            return np.minimum(t * tm, math.pi)
        if self.kind == "equisolid":
            return 2.0 * np.arcsin(np.minimum(t * math.sin(tm / 2.0), 1.0))
        if self.kind == "orthographic":
            return np.arcsin(np.minimum(t * math.sin(tm), 1.0))
        return 2.0 * np.arctan(t * math.tan(tm / 2.0))

    def _offsets(self, rows, cols):
        rows, cols = np.broadcast_arrays(np.asarray(rows, float), np.asarray(cols, float))
        return cols - self.cx, rows - self.cy

    def _unclipped_components(self, x, y):
        """Components (dx, dy, dz) of the directions of offsets ``(x, y)`` [px] from the centre.

        θ is extended (and clamped) beyond the image circle as in :meth:`_theta`. sin θ and
        cos θ come from half-angle identities (sin θ = 2t/(1 + t²), cos θ = (1 − t²)/(1 + t²)
        with t = tan(θ/2); cos θ = 1 − 2 sin²(θ/2) for equisolid), which need at most one
        transcendental function per point (none for the equisolid, orthographic and
        stereographic mappings) and are accurate to a few ulp.
        """
        r = np.sqrt(x * x + y * y)
        scale = 1.0 / self.radius
        tm = self.theta_max
        if self.kind == "equisolid":
            h = np.minimum(r * (math.sin(tm / 2.0) * scale), 1.0)  # sin(θ/2)
            s = 2.0 * h * np.sqrt(1.0 - h * h)
            c = 1.0 - 2.0 * h * h
        elif self.kind == "orthographic":
            s = np.minimum(r * (math.sin(tm) * scale), 1.0)
            c = np.sqrt(1.0 - s * s)
        else:
            if self.kind == "equidistant":
                t = np.tan(np.minimum(r * (tm * scale), math.pi) * 0.5)
            else:  # stereographic
                t = r * (math.tan(tm / 2.0) * scale)
            t2 = t * t
            s = 2.0 * t / (1.0 + t2)
            c = (1.0 - t2) / (1.0 + t2)
        q = np.divide(s, r, out=np.zeros_like(r), where=r > 0)  # sin θ / r
        return q * x, q * y, c

    def _unclipped(self, x, y):
        return np.stack(self._unclipped_components(x, y), axis=-1)

    def _inside(self, x, y):
        # A relative slack of 1e-12 keeps points computed *on* the rim (cx + R·cos φ, …)
        # valid despite rounding.
        return np.hypot(x, y) <= self.radius * (1.0 + 1e-12)

    def valid(self, rows, cols):
        """True where the image point lies inside (or on) the image circle."""
        return self._inside(*self._offsets(rows, cols))

    def directions(self, rows, cols):
        """Unit directions of image points; NaN outside the image circle."""
        x, y = self._offsets(rows, cols)
        d = self._unclipped(x, y)
        return np.where(self._inside(x, y)[..., None], d, np.nan)

    def project(self, directions):
        """Image points ``(rows, cols)`` of directions; NaN beyond θmax (or for zero vectors)."""
        d = np.asarray(directions, float)
        rho = np.hypot(d[..., 0], d[..., 1])
        theta = np.arctan2(rho, d[..., 2])
        tm = self.theta_max
        # A relative slack of 1e-12 keeps rim points valid after rounding in the round trip.
        ok = (theta <= tm * (1.0 + 1e-12)) & (np.linalg.norm(d, axis=-1) > 0)
        r = self.radius * _g(self.kind, np.minimum(theta, tm)) / _g(self.kind, tm)
        with np.errstate(divide="ignore", invalid="ignore"):
            ux = np.where(rho > 0, d[..., 0] / rho, 0.0)
            uy = np.where(rho > 0, d[..., 1] / rho, 0.0)
        rows = np.where(ok, self.cy + r * uy, np.nan)
        cols = np.where(ok, self.cx + r * ux, np.nan)
        return rows, cols

    # --- solid angles ----------------------------------------------------------------------

    def solid_angles(self, rows, cols):
        """Solid angle [sr] of pixels: geodesic quad of the corner directions, centre rule.

        0 for pixels whose centre lies outside the image circle (see the class notes). The
        quad is measured by :func:`~lsadphoto.geometry._spherical.quad_solid_angle_components`,
        the kernel that :func:`~lsadphoto.geometry.field.pixel_geometry` uses, so the cached
        maps equal this method bit for bit.
        """
        from ._spherical import quad_solid_angle_components

        rows, cols = np.broadcast_arrays(np.asarray(rows, float), np.asarray(cols, float))
        x0, x1 = (cols - 0.5) - self.cx, (cols + 0.5) - self.cx
        y0, y1 = (rows - 0.5) - self.cy, (rows + 0.5) - self.cy
        omega = quad_solid_angle_components(
            self._unclipped_components(x0, y0), self._unclipped_components(x1, y0),
            self._unclipped_components(x1, y1), self._unclipped_components(x0, y1),
        )
        return np.where(self._inside(cols - self.cx, rows - self.cy), omega, 0.0)

    def _grid_direction_components(self, rows, cols, *, corners=False):
        """Direction components on the grid ``rows[:, None] × cols[None, :]`` (1-D image
        coordinates [px]); corners extend the mapping beyond the circle (centre rule)."""
        rows = np.asarray(rows, float)[:, None]
        cols = np.asarray(cols, float)[None, :]
        x = np.broadcast_to(cols - self.cx, (rows.shape[0], cols.shape[1]))
        y = np.broadcast_to(rows - self.cy, x.shape)
        dx, dy, dz = self._unclipped_components(x, y)
        if not corners:
            outside = ~self._inside(x, y)
            for component in (dx, dy, dz):
                component[outside] = np.nan
        return dx, dy, dz

    def clipped_solid_angles(self, rows, cols, order=24):
        """Exact solid angle [sr] of the part of each pixel square inside the image circle.

        With F(r) = 1 − cos θ(r), the solid angle of an image region D is the boundary
        integral ∮∂D F dφ (Green's theorem; dω = F′(r)/r dA for a radial mapping). The
        straight pixel edges inside the circle are integrated with ``order``-point
        Gauss–Legendre quadrature after a smoothstep substitution (which tames the
        square-root end point of the orthographic mapping at 180°), the circle arcs
        analytically as F(R)·Δφ. Pixel squares are measured through the lens mapping itself
        (not through geodesic corner quads), so inside the circle they differ from
        :meth:`solid_angles` by the curvature of the mapped edges: relative ≈1e-6 per pixel
        at R = 500 px for the equidistant, equisolid and stereographic mappings, up to
        3e-4 next to the rim of an orthographic 180° image (its θ(r) has a √ singularity).
        """
        x, y = self._offsets(rows, cols)
        nodes, weights = np.polynomial.legendre.leggauss(int(order))
        tau = 0.5 * (nodes + 1.0)
        s = tau * tau * (3.0 - 2.0 * tau)
        ds = 6.0 * tau * (1.0 - tau) * 0.5 * weights  # ds/dτ · dτ
        R2 = self.radius ** 2
        f_rim = 1.0 - math.cos(min(self.theta_max, _MAX_THETA[self.kind]))
        corners = ((-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5), (-0.5, -0.5))
        total = np.zeros(x.shape)
        edge_dphi = np.zeros(x.shape)
        for (ax, ay), (bx, by) in itertools.pairwise(corners):
            px, py = x + ax, y + ay
            ex, ey = bx - ax, by - ay
            # |p + t·e|² ≤ R² for t in [t0, t1] ∩ [0, 1]
            qa = ex * ex + ey * ey
            qb = 2.0 * (px * ex + py * ey)
            qc = px * px + py * py - R2
            disc = qb * qb - 4.0 * qa * qc
            root = np.sqrt(np.maximum(disc, 0.0))
            t0 = np.clip((-qb - root) / (2.0 * qa), 0.0, 1.0)
            t1 = np.clip((-qb + root) / (2.0 * qa), 0.0, 1.0)
            t1 = np.where(disc > 0, np.maximum(t1, t0), t0)
            span = t1 - t0
            t = t0[..., None] + span[..., None] * s
            qx = px[..., None] + t * ex
            qy = py[..., None] + t * ey
            r2 = qx * qx + qy * qy
            theta = self._theta(np.sqrt(r2))
            f = 2.0 * np.sin(theta / 2.0) ** 2
            with np.errstate(divide="ignore", invalid="ignore"):
                dphi = np.where(r2 > 0, (qx * ey - qy * ex) / r2, 0.0)
            total += span * np.sum(f * dphi * ds, axis=-1)
            # Exact Δφ of the part of the edge inside the circle (for the arcs below).
            a0x, a0y = px + t0 * ex, py + t0 * ey
            a1x, a1y = px + t1 * ex, py + t1 * ey
            edge_dphi += np.arctan2(a0x * a1y - a0y * a1x, a0x * a1x + a0y * a1y)
        # Arcs: ∮dφ over the whole boundary is 2π if the centre is inside the clipped
        # region, else 0; the arcs carry what the edges do not.
        inside = (np.abs(x) < 0.5) & (np.abs(y) < 0.5)
        arc = np.where(inside, 2.0 * math.pi, 0.0) - edge_dphi
        partial = (np.hypot(np.abs(x) + 0.5, np.abs(y) + 0.5) > self.radius)
        total += np.where(partial, f_rim * arc, 0.0)
        return np.abs(total)

    # --- derived models --------------------------------------------------------------------

    def binned(self, factor):
        """Model after ``factor``×``factor`` binning (see :meth:`PinholeProjection.binned`)."""
        factor = check_binning_factor(factor)
        return IdealFisheyeProjection(
            self.kind, binned_coordinate(self.cx, factor), binned_coordinate(self.cy, factor),
            self.radius / factor, self.fov_deg, self.width // factor, self.height // factor,
        )

    def radiance_view(self):
        """Radiance view options (``-vta``/``-vth``/``-vts``) with the same pixel→direction mapping.

        Radiance maps pixel column i to ``x = (i + ½)/W − ½ + vs`` (rows from the bottom,
        FORMULAS.md §2.4.2; Radiance ``src/common/image.c`` viewray):

        * ``-vta``: θ = π·√(X² + Y²) with X = x·vh/180, so vh = 180·W·θmax/(π·R);
        * ``-vth``: sin θ = √(X² + Y²) with X = x·2 sin(vh/2), so vh = 2·asin(W·sin θmax/(2R));
        * ``-vts`` (VT_PLS, planisphere): with X = x·2 tan(vh/4) and d = X² + Y², Radiance
          takes cos θ = (1 − d)/(1 + d), i.e. tan(θ/2) = √(X² + Y²), so
          vh = 4·atan(W·tan(θmax/2)/(2R)).

        Radiance itself also traces the pixels beyond this model's circle (up to θ = 180°
        for ``-vta`` and ``-vts``); here they stay invalid. The equisolid kind has no
        Radiance view type.

        References
        ----------
        Radiance ``src/common/image.c`` (setview, viewray), v2.55.
        """
        w, h = self.width, self.height
        tm = self.theta_max
        if self.kind == "equidistant":
            vt = "a"
            # 180·W·θmax/(π·R), written in degrees so that round values stay round.
            vh = self.fov_deg * w / (2.0 * self.radius)
            vv = self.fov_deg * h / (2.0 * self.radius)
        elif self.kind == "orthographic":
            vt = "h"
            sx = w * math.sin(tm) / (2.0 * self.radius)
            sy = h * math.sin(tm) / (2.0 * self.radius)
            if sx > 1.0 or sy > 1.0:
                raise BadInputError(
                    "an orthographic image wider than the hemisphere has no -vth view "
                    f"(width·sin θmax/(2·radius) = {max(sx, sy):.6g} > 1)"
                )
            vh = math.degrees(2.0 * math.asin(sx))
            vv = math.degrees(2.0 * math.asin(sy))
        elif self.kind == "stereographic":
            vt = "s"
            vh = math.degrees(4.0 * math.atan(w * math.tan(tm / 2.0) / (2.0 * self.radius)))
            vv = math.degrees(4.0 * math.atan(h * math.tan(tm / 2.0) / (2.0 * self.radius)))
        else:
            raise BadInputError(
                f"Radiance has no view type for a {self.kind} fisheye (only -vta equidistant, "
                "-vth orthographic and -vts stereographic)"
            )
        vs = 0.5 - (self.cx + 0.5) / w
        vl = (self.cy + 0.5) / h - 0.5
        return (
            f"-vt{vt} -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh {vh:.17g} -vv {vv:.17g} "
            f"-vs {vs:.17g} -vl {vl:.17g}"
        )

    @classmethod
    def from_radiance_view(cls, options, width, height, fov_deg=180.0):
        """Model of a parsed ``-vta``/``-vth``/``-vts`` view (dict from :func:`~lsadphoto.io.hdr.parse_view`).

        ``options["type"]`` must be ``"a"``, ``"h"`` or ``"s"``; Radiance's defaults vh = vv = 45°
        apply. The image circle is cut at ``fov_deg`` (default 180°, the front hemisphere),
        although Radiance renders ``-vta`` and ``-vts`` up to 180° off axis. Both axes must
        have the same angular scale per pixel (relative 1e-9), since the model is
        rotationally symmetric. Any other view type raises :class:`BadInputError` naming it.
        """
        vtype = options.get("type")
        if vtype not in _RADIANCE_TYPES:
            name = RADIANCE_VIEW_NAMES.get(vtype, "unknown view type")
            raise BadInputError(
                f"view type -vt{vtype} ({name}) is not a fisheye view (need -vta, -vth or -vts)")
        kind = _RADIANCE_TYPES[vtype]
        vh = check_positive(options.get("vh", 45.0), "vh")
        vv = check_positive(options.get("vv", 45.0), "vv")
        fov = check_positive(fov_deg, "fov_deg")
        tm = math.radians(fov) / 2.0
        if kind == "equidistant":
            scale_x, scale_y = vh / width, vv / height  # θ per px [deg]
            radius = fov / (2.0 * scale_x)
        elif kind == "orthographic":
            scale_x = 2.0 * math.sin(math.radians(vh) / 2.0) / width  # sin θ per px
            scale_y = 2.0 * math.sin(math.radians(vv) / 2.0) / height
            radius = math.sin(tm) / scale_x
        else:
            if vh >= 360.0 or vv >= 360.0:
                raise BadInputError(f"-vts view needs vh, vv < 360°, got vh={vh:g}, vv={vv:g}")
            scale_x = 2.0 * math.tan(math.radians(vh) / 4.0) / width  # tan(θ/2) per px
            scale_y = 2.0 * math.tan(math.radians(vv) / 4.0) / height
            radius = math.tan(tm / 2.0) / scale_x
        if abs(scale_x - scale_y) > 1e-9 * scale_x:
            raise BadInputError(
                f"-vt{vtype} view with vh={vh:g}, vv={vv:g} on {width}×{height} px has unequal "
                "angular scales per pixel; vh and vv must match the image aspect"
            )
        cx = (0.5 - options.get("vs", 0.0)) * width - 0.5
        cy = (options.get("vl", 0.0) + 0.5) * height - 0.5
        return cls(kind, cx, cy, radius, fov, width, height)

    # --- serialisation ---------------------------------------------------------------------

    def __repr__(self):
        return (
            f"IdealFisheyeProjection({self.kind!r}, cx={self.cx:.6g}, cy={self.cy:.6g}, "
            f"radius={self.radius:.6g}, fov_deg={self.fov_deg:.6g}, width={self.width}, "
            f"height={self.height})"
        )
