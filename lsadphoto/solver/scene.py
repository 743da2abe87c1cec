"""Scene model of the solver: surfaces, luminaires and views, and its TOML structure.

A scene is a set of triangles (every shape is triangulated when it is read), each with a
material — a Lambertian reflectance, or one of Radiance's plastic, metal, trans, glass and
mirror (:mod:`lsadphoto.solver.materials`) — and possibly a Lambertian emission, plus point-like luminaires with
a luminous intensity distribution, plus named views. Lengths are in metres, flux in lumens,
intensity in candelas, luminance in cd·m⁻². The TOML schema is declared in
:data:`SCENE_SCHEMA` and documented in ``docs/user-guide-solver.md``;
:func:`scene_from_dict` accepts the same structure as a Python ``dict``. Files (TOML,
Radiance) are read by :func:`lsadphoto.solver.formats.read_scene`.

Surfaces reflect on both sides (the shading normal is turned towards the side a ray comes
from); Lambertian luminaires emit from their front side only, the side towards which the
polygon's vertices turn counter-clockwise (right-hand rule).

References
----------
Budak, V. P., Zheltov, V. S., Kalakutsky, T. K. (2012). Local estimations of Monte Carlo
method with the object spectral representation in the solution of global illumination
equation. *Computer Research and Modeling* 4(1), 75–84.
"""

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._schema import ArrayOf, Key, MapOf, Table, Variants, validate
from ..errors import BadInputError, SolverWarning
from ..geometry.base import Projection, projection_from_dict
from ..geometry.observer import orthonormal_pair
from .materials import GLASS_INDEX, KINDS, Material, MaterialTable, glass_transmissivity
from .photometry import Photometry, luminaire_frame, read_photometry
from .sky import TOML_SKY_MODELS, DistantSource, sky_sources

__all__ = [
    "AreaLuminaire",
    "PointLuminaire",
    "SCENE_SCHEMA",
    "Scene",
    "View",
    "as_views",
    "build_scene",
    "camera_to_world",
    "polygon_triangles",
    "scene_from_dict",
]

#: Relative tolerance of the planarity check of polygons (fraction of the polygon size).
PLANARITY_TOLERANCE = 1e-6


def camera_to_world(line_of_sight, up=(0.0, 0.0, 1.0)):
    """3×3 rotation taking camera-frame vectors (x right, y down, z forward) to the world.

    Parameters
    ----------
    line_of_sight : array_like, shape (3,)
        World direction of the optical axis (need not be unit length).
    up : array_like, shape (3,)
        World direction that appears up in the image (made perpendicular).

    Examples
    --------
    >>> r = camera_to_world([1, 0, 0], [0, 0, 1])
    >>> (r @ [0, 0, 1]).tolist(), (r @ [1, 0, 0]).tolist(), (r @ [0, 1, 0]).tolist()
    ([1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0])
    """
    v, u = orthonormal_pair(_vector(line_of_sight, "line_of_sight"), _vector(up, "up"))
    right = np.cross(v, u)
    out = np.stack([right, -u, v], axis=1)
    return out + 0.0  # no negative zeros in printed examples


def _vector(value, name, size=3):
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise BadInputError(f"{name} must be a list of {size} numbers, got {value!r}") from None
    if v.shape != (size,) or not np.all(np.isfinite(v)):
        raise BadInputError(f"{name} must be a list of {size} finite numbers, got {value!r}")
    return v


# --- triangulation -------------------------------------------------------------------------

def _newell_normal(points):
    p = points
    q = np.concatenate([points[1:], points[:1]])  # the next vertex (np.roll, without its overhead)
    return np.array([
        np.sum((p[:, 1] - q[:, 1]) * (p[:, 2] + q[:, 2])),
        np.sum((p[:, 2] - q[:, 2]) * (p[:, 0] + q[:, 0])),
        np.sum((p[:, 0] - q[:, 0]) * (p[:, 1] + q[:, 1])),
    ])


def _cross3(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def polygon_triangles(vertices, name="polygon"):
    """Triangles ``(n − 2, 3, 3)`` of a planar simple polygon (convex or concave) [m].

    Ear clipping in the polygon's plane; the triangles keep the vertex winding, so their
    normals point to the polygon's front side. Raises :class:`BadInputError` for fewer
    than three distinct vertices, zero area, or a polygon that is not planar (relative
    tolerance :data:`PLANARITY_TOLERANCE`).

    Examples
    --------
    >>> polygon_triangles([[0, 0, 0], [2, 0, 0], [2, 1, 0], [1, 0.5, 0], [0, 1, 0]]).shape
    (3, 3, 3)
    """
    try:
        pts = np.asarray(vertices, dtype=float)
    except (TypeError, ValueError):
        raise BadInputError(f"{name}: vertices must be a list of [x, y, z] points") from None
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
        raise BadInputError(f"{name}: vertices must be a list of [x, y, z] points")
    # drop repeated consecutive vertices (and a closing copy of the first)
    keep = np.any(pts != np.concatenate([pts[-1:], pts[:-1]]), axis=1)
    pts = pts[keep] if keep.any() else pts[:1]
    if len(pts) < 3:
        raise BadInputError(f"{name}: needs at least 3 distinct vertices, got {len(pts)}")
    normal = _newell_normal(pts)
    size = np.ptp(pts, axis=0).max()
    area2 = np.linalg.norm(normal)
    if area2 <= 1e-12 * size * size:
        raise BadInputError(f"{name}: degenerate polygon (zero area)")
    normal = normal / area2
    offset = (pts - pts.mean(axis=0)) @ normal
    if np.abs(offset).max() > PLANARITY_TOLERANCE * size:
        raise BadInputError(
            f"{name}: vertices are not coplanar (off the plane by {np.abs(offset).max():.3g} m)")
    # 2-D coordinates in the plane, counter-clockwise seen from the front
    a = np.eye(3)[np.argmin(np.abs(normal))]
    e1 = _cross3(normal, a)
    e1 /= np.linalg.norm(e1)
    e2 = _cross3(normal, e1)
    xy = pts @ np.stack([e1, e2], axis=1)
    edges = np.concatenate([xy[1:], xy[:1]]) - xy
    after = np.concatenate([edges[1:], edges[:1]])
    turns = edges[:, 0] * after[:, 1] - edges[:, 1] * after[:, 0]
    if np.all(turns > 1e-14 * size * size):
        # strictly convex: the triangles ear clipping below makes, (n−1, j, j+1) and last
        # (n−3, n−2, n−1), without its search (same order, so the same random streams)
        n = len(pts)
        j = np.arange(n - 3)
        fan = np.stack([np.full_like(j, n - 1), j, j + 1], axis=1)
        return pts[np.concatenate([fan, [[n - 3, n - 2, n - 1]]])]
    idx = list(range(len(pts)))
    tris = []
    guard = 0
    while len(idx) > 3:
        guard += 1
        if guard > 10 * len(pts) ** 2:
            raise BadInputError(f"{name}: self-intersecting polygon cannot be triangulated")
        n = len(idx)
        clipped = False
        for k in range(n):
            i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % n]
            a0, a1, a2 = xy[i0], xy[i1], xy[i2]
            cross = (a1[0] - a0[0]) * (a2[1] - a0[1]) - (a1[1] - a0[1]) * (a2[0] - a0[0])
            if cross <= 1e-14 * size * size:
                continue  # reflex or collinear corner
            # other vertices inside the ear forbid it, except copies of its own corners (the
            # two sides of a seam that joins a hole to the outline, as genprism and genbox -i write)
            others = [j for j in idx if j not in (i0, i1, i2)
                      and min(np.abs(xy[j] - a0).max(), np.abs(xy[j] - a1).max(),
                              np.abs(xy[j] - a2).max()) > 1e-12 * size]
            if others and _points_in_triangle(xy[others], a0, a1, a2).any():
                continue
            tris.append((i0, i1, i2))
            idx.pop(k)
            clipped = True
            break
        if not clipped:
            # only collinear corners left: drop one collinear vertex
            for k in range(n):
                i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % n]
                a0, a1, a2 = xy[i0], xy[i1], xy[i2]
                cross = (a1[0] - a0[0]) * (a2[1] - a0[1]) - (a1[1] - a0[1]) * (a2[0] - a0[0])
                if abs(cross) <= 1e-14 * size * size:
                    idx.pop(k)
                    break
            else:
                raise BadInputError(f"{name}: self-intersecting polygon cannot be triangulated")
    tris.append(tuple(idx))
    out = pts[np.array(tris)]
    # collinear leftovers can leave zero-area triangles: drop them
    areas = 0.5 * np.linalg.norm(np.cross(out[:, 1] - out[:, 0], out[:, 2] - out[:, 0]), axis=1)
    out = out[areas > 1e-12 * size * size]
    if len(out) == 0:
        raise BadInputError(f"{name}: degenerate polygon (zero area)")
    return out


def _points_in_triangle(p, a, b, c):
    def side(p1, p2):
        return (p2[0] - p1[0]) * (p[:, 1] - p1[1]) - (p2[1] - p1[1]) * (p[:, 0] - p1[0])

    d1, d2, d3 = side(a, b), side(b, c), side(c, a)
    return (d1 >= 0) & (d2 >= 0) & (d3 >= 0)


_BOX_FACES = {  # outward-facing quads of the unit cube [0, 1]³, counter-clockwise from outside
    "-x": [(0, 0, 0), (0, 0, 1), (0, 1, 1), (0, 1, 0)],
    "+x": [(1, 0, 0), (1, 1, 0), (1, 1, 1), (1, 0, 1)],
    "-y": [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)],
    "+y": [(0, 1, 0), (0, 1, 1), (1, 1, 1), (1, 1, 0)],
    "-z": [(0, 0, 0), (0, 1, 0), (1, 1, 0), (1, 0, 0)],
    "+z": [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)],
}
_FACE_ALIASES = {"floor": "-z", "ceiling": "+z"}


def box_faces(minimum, maximum, *, facing="inward", axes=None):
    """Six quads of a box as ``{face: (4, 3) vertices}`` [m], normals in or out.

    ``minimum``/``maximum`` are the corners in the box's own axes (``axes``: 3×3 rows,
    default the world axes, orthonormalised); faces are named ``-x``, ``+x``, … in those axes.
    """
    lo, hi = np.asarray(minimum, float), np.asarray(maximum, float)
    r = np.eye(3) if axes is None else np.asarray(axes, float)
    out = {}
    for face, corners in _BOX_FACES.items():
        c = lo + np.asarray(corners, float) * (hi - lo)
        if facing == "inward":
            c = c[::-1]
        out[face] = c @ r
    return out


def disc_polygon(centre, normal, radius, segments=64):
    """Vertices ``(segments, 3)`` of a regular polygon inscribed in a disc [m].

    The polygon has the same area as the disc (its circumradius is enlarged by
    √(2π/(n sin(2π/n)))), so fluxes and form factors of a disc are kept.
    """
    n = _vector(normal, "normal")
    if np.linalg.norm(n) == 0:
        raise BadInputError("disc normal must not be the zero vector")
    n = n / np.linalg.norm(n)
    a = np.eye(3)[np.argmin(np.abs(n))]
    e1 = np.cross(n, a)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    k = int(segments)
    scale = math.sqrt(2 * math.pi / (k * math.sin(2 * math.pi / k)))
    phi = 2 * math.pi * np.arange(k) / k
    return (np.asarray(centre, float) + radius * scale
            * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2))


# --- scene objects -------------------------------------------------------------------------

@dataclass
class AreaLuminaire:
    """A Lambertian emitting surface: its triangles emit ``flux`` [lm] from their front side.

    ``light_source_radius`` [m]: Radiance's direct calculation takes it as a light source at
    the points within this distance of its centre (the area-weighted centroid of its
    triangles) — ∞ for a ``light``, a ``glow``'s radius of influence (0: never, ``srcskip`` of
    Radiance's ``source.c``); decides the factor 1 − F(μ_i) under the ``"radiance"`` rule
    (:data:`~lsadphoto.solver.materials.FRESNEL_RULES`, :meth:`Scene.light_source_at`).
    """

    name: str
    flux: float
    triangles: np.ndarray  # indices into Scene.triangles
    light_source_radius: float = math.inf

    def luminance(self, scene):
        """Uniform luminance of the emitting surface [cd·m⁻²]: Φ/(π·A)."""
        return self.flux / (math.pi * scene.areas[self.triangles].sum())


@dataclass
class PointLuminaire:
    """A luminaire with a luminous intensity distribution, as a point or a small rectangle.

    Emission points are uniform on the luminous rectangle ``extent`` = (length, width) [m]
    (along the C0 and C90 axes, centred on ``position``; (0, 0) is a point); each emits the
    distribution's shape. The luminaire is not geometry: it blocks no light. A rectangle of
    non-zero area appears in renders with the luminance I(ω)/(A·|cos γ|) of that emission
    model (in front of whatever lies behind it); a point does not appear.
    """

    name: str
    position: np.ndarray
    photometry: Photometry
    frame: np.ndarray  # rows e_C0, e_C90, e_nadir
    extent: tuple = (0.0, 0.0)
    multiplier: float = 1.0

    def __post_init__(self):
        if not isinstance(self.photometry, Photometry):
            raise BadInputError(f"luminaire {self.name!r}: its intensity distribution is a "
                                f"{type(self.photometry).__name__}, not a Photometry")
        if not self.photometry.luminous_flux > 0:
            raise BadInputError(f"luminaire {self.name!r}: its intensity distribution emits no flux")

    @property
    def flux(self):
        """Luminous flux [lm]."""
        return self.multiplier * self.photometry.luminous_flux

    def intensity(self, directions):
        """Luminous intensity [cd] towards world directions ``(..., 3)``."""
        return self.multiplier * self.photometry.evaluate(directions, self.frame)


@dataclass
class View:
    """An observer: eye ``position`` [m], camera-to-world ``rotation`` and a projection."""

    name: str
    position: np.ndarray
    rotation: np.ndarray
    projection: Projection


@dataclass
class Scene:
    """Triangulated Lambertian scene with luminaires and views.

    Attributes
    ----------
    triangles : ndarray, shape (n, 3, 3)
        Vertex coordinates [m].
    material : ndarray of int, shape (n,)
        Index into ``material_names``/``reflectance`` per triangle.
    reflectance : ndarray, shape (m,)
        Lambertian reflectance ρ of each material [–], 0 ≤ ρ < 1 (for a material that is not
        Lambertian: its diffuse reflectance at normal incidence).
    emitter : ndarray of int, shape (n,)
        Index into ``area_luminaires`` per triangle, −1 where the triangle does not emit.
    surface_materials : list of Material, optional
        The :class:`~lsadphoto.solver.materials.Material` of each material index, when some
        are not Lambertian (glossy, specular, transmitting); ``None``: all are Lambertian of
        ``reflectance``. ``bsdf`` is then their
        :class:`~lsadphoto.solver.materials.MaterialTable` (``None`` for Lambertian scenes,
        whose estimators are unchanged).
    """

    triangles: np.ndarray
    material: np.ndarray
    material_names: list
    reflectance: np.ndarray
    emitter: np.ndarray
    area_luminaires: list = field(default_factory=list)
    point_luminaires: list = field(default_factory=list)
    views: list = field(default_factory=list)
    name: str = "scene"
    source: dict = field(default_factory=dict)
    surface_materials: list = None
    distant_sources: list = field(default_factory=list)

    def __post_init__(self):
        self.triangles = np.ascontiguousarray(self.triangles, dtype=float).reshape(-1, 3, 3)
        e1 = self.triangles[:, 1] - self.triangles[:, 0]
        e2 = self.triangles[:, 2] - self.triangles[:, 0]
        cross = np.cross(e1, e2)
        norm = np.linalg.norm(cross, axis=1)
        if len(self.triangles) == 0:
            raise BadInputError("scene has no surfaces")
        if np.any(norm <= 0):
            raise BadInputError("scene has degenerate (zero-area) triangles")
        self.normals = cross / norm[:, None]
        self.areas = 0.5 * norm
        self.material = np.asarray(self.material, dtype=np.int64)
        self.emitter = np.asarray(self.emitter, dtype=np.int64)
        self.reflectance = np.asarray(self.reflectance, dtype=float)
        if np.any(self.reflectance < 0) or np.any(self.reflectance >= 1):
            raise BadInputError("reflectance must be in [0, 1)")
        if not self.area_luminaires and not self.point_luminaires and not self.distant_sources:
            raise BadInputError("scene has no luminaires")
        lo = self.triangles.reshape(-1, 3).min(axis=0)
        hi = self.triangles.reshape(-1, 3).max(axis=0)
        self._warn_luminaires_outside()
        for lum in self.point_luminaires:
            lo, hi = np.minimum(lo, lum.position), np.maximum(hi, lum.position)
        self.bounds = (lo, hi)
        #: Characteristic size of the scene: diagonal of its bounding box [m].
        self.size = float(np.linalg.norm(hi - lo))
        #: Bounding sphere (centre [m], radius [m]) through which distant sources' light
        #: enters (:mod:`lsadphoto.solver.sky`).
        self.sphere = (0.5 * (lo + hi), 0.5 * self.size * (1 + 1e-3) + 1e-9)
        self.triangle_reflectance = self.reflectance[self.material]
        # each area luminaire's centre [m] and squared light-source radius [m²] (light_source_at)
        self._source_centre = np.array([
            (self.areas[l.triangles, None] * self.triangles[l.triangles].mean(axis=1)).sum(axis=0)
            / self.areas[l.triangles].sum() for l in self.area_luminaires]).reshape(-1, 3)
        self._source_radius2 = np.array([l.light_source_radius for l in self.area_luminaires], float) ** 2
        self.bsdf = None
        if self.surface_materials is not None:
            if len(self.surface_materials) != len(self.reflectance):
                raise BadInputError("surface_materials must give one material per reflectance")
            if not all(m.is_lambertian for m in self.surface_materials):
                self.bsdf = MaterialTable(self.surface_materials)

    def light_source_at(self, luminaire, points):
        """Whether Radiance's direct calculation takes area luminaires ``luminaire`` (indices,
        shape (k,)) as light sources at ``points`` (k, 3) [m]: within their
        ``light_source_radius`` of their centres (bool, shape (k,))."""
        luminaire = np.asarray(luminaire, dtype=np.int64)
        if not luminaire.size:
            return np.zeros(0, bool)
        d = np.asarray(points, float).reshape(-1, 3) - self._source_centre[luminaire]
        r2 = self._source_radius2[luminaire]
        return (r2 > 0) & (np.einsum("ij,ij->i", d, d) <= r2)

    @property
    def lambertian(self):
        """Whether every surface is Lambertian (no glossy, specular or transmitting material)."""
        return self.bsdf is None

    def _winding_number(self, point):
        """Generalised winding number of the scene's triangles at ``point`` [m]: 1 inside a
        closed surface whose fronts face inwards (a room), 0 outside (Jacobson, Kavan &
        Sorkine-Hornung 2013, doi:10.1145/2461912.2461916; triangle solid angles by Van
        Oosterom & Strackee 1983, doi:10.1109/TBME.1983.325207)."""
        a, b, c = (self.triangles[:, k] - point for k in range(3))
        la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
        numerator = np.einsum("ij,ij->i", a, np.cross(b, c))
        denominator = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", a, c) * lb
                       + np.einsum("ij,ij->i", b, c) * la)
        # Triangles wound counter-clockwise seen from the point have their fronts towards it.
        return float(-2.0 * np.arctan2(numerator, denominator).sum() / (4 * math.pi))

    def _warn_luminaires_outside(self):
        """A luminaire outside a closed room lights only the room's outsides, so that every
        view inside is black: say so (SolverWarning).

        The scene is a room when its surfaces enclose the centre of the passive surfaces'
        bounding box with their fronts facing it (winding number ≥ 0.9 there); open models (a plane, a solid on
        a plane) are not rooms and are not checked. A point luminaire is outside where the
        winding number at its position is below ½; an area luminaire where it is at a point
        just in front of its emitting side.
        """
        passive = self.triangles[self.emitter < 0].reshape(-1, 3)
        box = passive if len(passive) else self.triangles.reshape(-1, 3)
        lo, hi = box.min(axis=0), box.max(axis=0)
        size = float(np.linalg.norm(hi - lo))
        if not self._winding_number(0.5 * (lo + hi)) >= 0.9:
            return
        places = [(lum.name, np.asarray(lum.position, float)) for lum in self.point_luminaires]
        for k, lum in enumerate(self.area_luminaires):
            own = self.emitter == k
            front = (self.normals[own] * self.areas[own, None]).sum(axis=0)
            front /= max(float(np.linalg.norm(front)), 1e-300)
            places.append((lum.name, self.triangles[own].reshape(-1, 3).mean(axis=0) + 1e-4 * size * front))
        outside = [(name, where) for name, where in places if self._winding_number(where) < 0.5]
        if outside:
            name, where = outside[0]
            others = f" (and {len(outside) - 1} more)" if len(outside) > 1 else ""
            warnings.warn(
                f"luminaire {name!r} near ({', '.join(f'{v:.4g}' for v in where)}) m{others} is outside the "
                "closed room the scene's surfaces form: it lights the room from outside, and views "
                "inside may be black", SolverWarning, stacklevel=3)

    def __repr__(self):
        return (f"Scene({self.name!r}, {len(self.triangles)} triangles, "
                f"{len(self.area_luminaires)} area + {len(self.point_luminaires)} point luminaires, "
                f"{len(self.distant_sources)} distant sources, "
                f"{len(self.views)} views)")

    @property
    def total_flux(self):
        """Luminous flux of all luminaires [lm]."""
        return (sum(l.flux for l in self.area_luminaires)
                + sum(l.flux for l in self.point_luminaires)
                + sum(self.distant_flux(s) for s in self.distant_sources))

    def distant_flux(self, source):
        """Luminous flux [lm] of a distant source through the cross-section πR² of the
        scene's bounding sphere (what the light chains carry into the scene)."""
        return math.pi * self.sphere[1] ** 2 * source.integral

    def facing_normals(self, prim, direction):
        """Normals of triangles ``prim`` turned against rays of unit ``direction`` that hit
        them (towards where the rays came from), and whether each ray hit the front side."""
        normals = self.normals[prim]
        front = np.einsum("ij,ij->i", normals, direction) < 0
        return normals * np.where(front, 1.0, -1.0)[:, None], front

    def view(self, name=None):
        """The view called ``name`` (the first one when ``None``)."""
        if not self.views:
            raise BadInputError("scene defines no views")
        if name is None:
            return self.views[0]
        for v in self.views:
            if v.name == name:
                return v
        valid = ", ".join(repr(v.name) for v in self.views)
        raise BadInputError(f"unknown view {name!r}; valid: {valid}")


# --- reading -------------------------------------------------------------------------------

def _vec3(doc, **kw):
    return Key(list, items=float, length=3, doc=doc, **kw)


_FACING = ("inward", "outward")
#: Keys of each shape type (a surface adds ``material`` and ``name``).
_SHAPES = {
    "polygon": {"vertices": Key(list, required=True, items=Key(list, items=float, length=3),
                                doc="planar polygon's vertices [m], counter-clockwise seen from its front")},
    "box": {"min": _vec3("lower corner [m]", required=True), "max": _vec3("upper corner [m]", required=True),
            "facing": Key(str, default="inward", choices=_FACING),
            "axes": Key(list, length=3, items=Key(list, items=float, length=3), doc="orthonormal rows"),
            "face_materials": Key(dict, doc="material per face (floor, ceiling, x-, x+, …)")},
    "disc": {"centre": _vec3("centre [m]"), "center": _vec3("centre [m] (US spelling)"),
             "normal": _vec3("front normal", required=True),
             "radius": Key(float, required=True, minimum=0, exclusive=True, doc="radius [m]"),
             "segments": Key(int, default=64, minimum=3, doc="polygon sides")},
    "sphere": {"centre": _vec3("centre [m]"), "center": _vec3("centre [m] (US spelling)"),
               "radius": Key(float, required=True, minimum=0, exclusive=True, doc="radius [m]"),
               "subdivisions": Key(int, default=3, minimum=0, maximum=7, doc="icosphere subdivisions"),
               "facing": Key(str, default="outward", choices=_FACING)},
    "mesh": {"file": Key(str, required=True, doc="mesh file (OBJ, PLY, STL, …), relative to the scene"),
             "scale": Key(float, default=1.0, minimum=0, exclusive=True),
             "translate": _vec3("offset [m]", default=[0.0, 0.0, 0.0]),
             "flip": Key(bool, default=False, doc="turn the triangles' fronts over")},
}
_POSITIVE = {"minimum": 0, "exclusive": True}

#: The declared schema of a TOML scene (lsadphoto._schema): unknown tables and keys are
#: refused, types and ranges checked, each problem one line; geometry (planarity, orthonormal
#: axes, one of flux/luminance) is checked while the scene is built.
SCENE_SCHEMA = Table({
    "scene": Table({"name": Key(str, default="scene")}),
    "materials": MapOf(Table({
        "type": Key(str, default="lambertian", choices=KINDS, doc="Radiance's material types"),
        "reflectance": Key(float, doc="grey colour: Lambertian ρ, 0 ≤ ρ < 1 (or give colour)"),
        "colour": Key(list, items=float, length=3, doc="RGB as Radiance's first three reals"),
        "color": Key(list, items=float, length=3, doc="colour (US spelling)"),
        "specularity": Key(float, default=0.0, doc="plastic, metal, trans: s, 0 ≤ s ≤ 1"),
        "roughness": Key(float, default=0.0, doc="plastic, metal, trans: α ≥ 0"),
        "transmissivity": Key(float, default=0.0, doc="trans: τ, 0 ≤ τ ≤ 1"),
        "transmitted_specularity": Key(float, default=0.0, doc="trans: τ_s, 0 ≤ τ_s ≤ 1"),
        "refractive_index": Key(float, default=GLASS_INDEX, doc="glass: n > 1"),
        "transmittance": Key(float, doc="glass: normal transmittance T_n (instead of colour)")})),
    "surfaces": ArrayOf(Variants("type", {kind: Table({**keys, "material": Key(str), "name": Key(str)})
                                          for kind, keys in _SHAPES.items()})),
    "luminaires": ArrayOf(Variants("type", {
        "area": Table({"name": Key(str), "material": Key(str, default="black"),
                       "shape": Variants("type", {kind: Table(keys) for kind, keys in _SHAPES.items()},
                                         required=True),
                       "flux": Key(float, **_POSITIVE, doc="[lm]"),
                       "luminance": Key(float, **_POSITIVE, doc="[cd·m⁻²]")}),
        "point": Table({"name": Key(str), "position": _vec3("[m]", required=True),
                        "intensity": Key(float, **_POSITIVE, doc="isotropic [cd]"),
                        "flux": Key(float, **_POSITIVE, doc="isotropic [lm]"),
                        "photometry": Key(str, doc="IES or EULUMDAT file, relative to the scene"),
                        "nadir": _vec3("luminaire's nadir (γ = 0)", default=[0.0, 0.0, -1.0]),
                        "length_axis": _vec3("C0 direction", default=[1.0, 0.0, 0.0]),
                        "extent": Key(list, items=float, length=2, minimum=0, doc="[length, width] [m]"),
                        "multiplier": Key(float, default=1.0, **_POSITIVE)}),
        "sun": Table({"name": Key(str), "direction": _vec3("towards the sun", required=True),
                      "illuminance": Key(float, **_POSITIVE, doc="normal illuminance E_n [lx]"),
                      "luminance": Key(float, **_POSITIVE, doc="[cd·m⁻²]"),
                      "angle": Key(float, default=0.533, minimum=0, exclusive=True, maximum=360,
                                   doc="angular diameter [°]")}),
        "sky": Table({"name": Key(str), "model": Key(str, required=True, choices=tuple(TOML_SKY_MODELS)),
                      "zenith_luminance": Key(float, required=True, **_POSITIVE, doc="[cd·m⁻²]"),
                      "sun_direction": _vec3("towards the sun (cie-clear, cie-intermediate)"),
                      "ground_luminance": Key(float, default=0.0, minimum=0,
                                              doc="uniform ground below the horizon [cd·m⁻²]")}),
    })),
    "views": ArrayOf(Table({"name": Key(str), "position": _vec3("eye [m]", required=True),
                            "line_of_sight": _vec3("[m]", required=True),
                            "up": _vec3("", default=[0.0, 0.0, 1.0]),
                            "projection": Key(dict, doc="a projection (default a 180° fisheye)")})),
})


def _shape_triangles(spec, ctx, base, material_of):
    """List of (triangles, material name) of one checked shape table."""
    kind = spec["type"]
    material = material_of(spec, ctx)
    ctx = f"{ctx} ({kind})"
    if kind == "polygon":
        return [(polygon_triangles(spec["vertices"], ctx), material)]
    if kind in ("disc", "sphere"):
        centre = spec.get("centre", spec.get("center"))
        if centre is None:
            raise BadInputError(f"{ctx}: missing required key 'centre'")
        centre = np.asarray(centre, float)
    if kind == "box":
        lo, hi = np.asarray(spec["min"], float), np.asarray(spec["max"], float)
        if np.any(hi <= lo):
            raise BadInputError(f"{ctx}: max must exceed min on every axis")
        axes = None
        if "axes" in spec:
            axes = np.asarray(spec["axes"], float)
            if not np.allclose(axes @ axes.T, np.eye(3), atol=1e-9):
                raise BadInputError(f"{ctx}: axes must be 3 orthonormal rows")
        faces = box_faces(lo, hi, facing=spec["facing"], axes=axes)
        chosen = {}
        for key, mat in spec.get("face_materials", {}).items():
            face = _FACE_ALIASES.get(key, key)
            if face not in faces:
                raise BadInputError(f"{ctx}: unknown face {key!r}; valid: {', '.join(list(faces) + list(_FACE_ALIASES))}")
            chosen[face] = material_of({"material": mat}, f"{ctx} face {key}")
        return [(polygon_triangles(q, f"{ctx} face {f}"), chosen.get(f, material))
                for f, q in faces.items()]
    if kind == "disc":
        normal = _vector(spec["normal"], f"{ctx} normal")
        return [(polygon_triangles(disc_polygon(centre, normal, spec["radius"], spec["segments"]), ctx),
                 material)]
    if kind == "sphere":
        import trimesh

        ico = trimesh.creation.icosphere(subdivisions=spec["subdivisions"], radius=spec["radius"])
        tris = np.asarray(ico.triangles, float) + centre
        if spec["facing"] == "inward":
            tris = tris[:, ::-1]
        return [(tris, material)]
    # mesh
    import trimesh

    file = Path(spec["file"])
    if not file.is_absolute() and base is not None:
        file = Path(base) / file
    if not file.is_file():
        raise BadInputError(f"{ctx}: mesh file {file} does not exist")
    try:
        mesh = trimesh.load(file, force="mesh", process=False)
    except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds; report in one line
        raise BadInputError(f"{ctx}: cannot read mesh {file} ({exc})") from None
    tris = np.asarray(mesh.triangles, float)
    if tris.size == 0:
        raise BadInputError(f"{ctx}: mesh {file} has no triangles")
    tris = tris * spec["scale"] + np.asarray(spec["translate"], float)
    if spec["flip"]:
        tris = tris[:, ::-1]
    e = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    tris = tris[np.linalg.norm(e, axis=1) > 0]  # meshes often carry slivers: drop them
    return [(tris, material)]


_DEFAULT_PROJECTION = {"model": "fisheye-ideal", "kind": "equidistant", "fov_deg": 180.0,
                       "width": 256, "height": 256}


def _projection(spec, ctx):
    data = dict(_DEFAULT_PROJECTION) if spec.get("model", "fisheye-ideal") == "fisheye-ideal" else {}
    data.update(spec)
    if data.get("model") == "fisheye-ideal":
        w, h = data.get("width"), data.get("height")
        if isinstance(w, int) and isinstance(h, int):
            data.setdefault("cx", (w - 1) / 2.0)
            data.setdefault("cy", (h - 1) / 2.0)
            data.setdefault("radius", min(w, h) / 2.0)
    try:
        return projection_from_dict(data)
    except BadInputError as exc:
        raise BadInputError(f"{ctx}: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise BadInputError(f"{ctx}: bad projection ({exc})") from None


def scene_from_dict(data, *, base=None, photometry_reader=None):
    """Build a :class:`Scene` from the TOML structure (a ``dict``), checked against
    :data:`SCENE_SCHEMA`; see :func:`lsadphoto.solver.formats.load_scene`."""
    data = validate(data, SCENE_SCHEMA, source="scene")
    return build_scene(data, base=base, photometry_reader=photometry_reader, source="scene")


def build_scene(data, *, base, photometry_reader, source):
    """The :class:`Scene` of a document that passed :data:`SCENE_SCHEMA` (relative file names
    in it are taken relative to ``base``; ``source`` names the document in errors)."""
    try:
        return _build_checked(data, base, photometry_reader)
    except BadInputError as exc:
        raise BadInputError(f"{source}: {exc}") from None


def _build_checked(data, base, photometry_reader):
    name = data.get("scene", {}).get("name", "scene")
    names, rho, surface = [], [], []
    for mname, m in data.get("materials", {}).items():
        material = _material(m, f"materials.{mname}")
        names.append(mname)
        rho.append(m["reflectance"] if material.kind == "lambertian" else material.diffuse_reflectance)
        surface.append(material)

    def material_of(spec, ctx):
        m = spec.get("material")
        if m is None:
            raise BadInputError(f"{ctx}: missing required key 'material'")
        if m not in names:
            if m == "black":  # built-in ρ = 0
                names.append("black")
                rho.append(0.0)
                surface.append(Material.lambertian(0.0))
            else:
                valid = ", ".join(repr(n) for n in names) or "none defined"
                raise BadInputError(f"{ctx}: unknown material {m!r}; defined: {valid}")
        return names.index(m)

    tri_list, mat_list, emit_list = [], [], []
    for k, spec in enumerate(data.get("surfaces", [])):
        for tris, mat in _shape_triangles(spec, f"surfaces[{k}]", base, material_of):
            tri_list.append(tris)
            mat_list.append(np.full(len(tris), mat))
            emit_list.append(np.full(len(tris), -1))
    area_lums, point_lums, distant = [], [], []
    files = {}
    for k, spec in enumerate(data.get("luminaires", [])):
        ctx = f"luminaires[{k}]"
        lname = spec.get("name", f"luminaire{k}")
        if spec["type"] in ("sun", "sky"):
            distant += _distant_sources(spec, lname, ctx)
        elif spec["type"] == "area":
            lum_material = material_of({"material": spec["material"]}, ctx)
            parts = _shape_triangles(spec["shape"], f"{ctx} shape", base, lambda s, c, m=lum_material: m)
            tris = np.concatenate([t for t, _ in parts])
            mat = parts[0][1]
            area = 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1).sum()
            if ("flux" in spec) == ("luminance" in spec):
                raise BadInputError(f"{ctx}: give exactly one of 'flux' [lm] or 'luminance' [cd/m²]")
            flux = spec["flux"] if "flux" in spec else float(math.pi * area * spec["luminance"])
            first = sum(len(t) for t in tri_list)
            tri_list.append(tris)
            mat_list.append(np.full(len(tris), mat))
            emit_list.append(np.full(len(tris), len(area_lums)))
            area_lums.append(AreaLuminaire(lname, flux, np.arange(first, first + len(tris))))
        else:
            position = np.asarray(spec["position"], float)
            frame = luminaire_frame(_vector(spec["nadir"], f"{ctx} nadir"),
                                    _vector(spec["length_axis"], f"{ctx} length_axis"))
            given = [key for key in ("intensity", "flux", "photometry") if key in spec]
            if len(given) != 1:
                raise BadInputError(f"{ctx}: give exactly one of 'intensity' [cd], 'flux' [lm] "
                                    "(isotropic) or 'photometry' (file)")
            extent = (0.0, 0.0)
            if given[0] == "intensity":
                photometry = Photometry.isotropic(spec["intensity"])
            elif given[0] == "flux":
                photometry = Photometry.isotropic(spec["flux"] / (4 * math.pi))
            else:
                key = (str(Path(base or ".") / spec["photometry"]), photometry_reader)
                if key not in files:  # luminaires of one file share its distribution (one draw each)
                    files[key] = _photometry_file(spec["photometry"], ctx, base, photometry_reader)
                photometry, extent = files[key]
            if "extent" in spec:
                extent = tuple(spec["extent"])
            point_lums.append(PointLuminaire(lname, position, photometry, frame, extent, spec["multiplier"]))
    views = _views(data.get("views", []))
    if not tri_list:
        raise BadInputError("scene has no surfaces")
    if not area_lums and not point_lums and not distant:
        raise BadInputError("scene has no luminaires")
    return Scene(np.concatenate(tri_list), np.concatenate(mat_list), names, np.asarray(rho),
                 np.concatenate(emit_list), area_lums, point_lums, views, name=name,
                 source=data,
                 surface_materials=None if all(m.is_lambertian for m in surface) else surface,
                 distant_sources=distant)


def _distant_sources(spec, name, ctx):
    """The :class:`~lsadphoto.solver.sky.DistantSource` list of a checked ``sun`` or ``sky``
    luminaire table."""
    try:
        if spec["type"] == "sky":
            return sky_sources(name, spec["model"], spec["zenith_luminance"],
                               sun_direction=spec.get("sun_direction"),
                               ground_luminance=spec["ground_luminance"])
        if ("illuminance" in spec) == ("luminance" in spec):
            raise BadInputError("give exactly one of 'illuminance' (normal, [lx]) or 'luminance' [cd/m²]")
        half = math.radians(spec["angle"]) / 2
        luminance = spec.get("luminance") or spec["illuminance"] / (2 * math.pi * (1 - math.cos(half)))
        return [DistantSource(name, _vector(spec["direction"], "direction"), half, luminance)]
    except BadInputError as exc:
        raise BadInputError(f"{ctx}: {exc}") from None


def _material(spec, ctx):
    """The :class:`Material` of one checked ``[materials.NAME]`` table."""
    kind = spec["type"]
    given = [key for key in ("reflectance", "colour", "color", "transmittance") if key in spec]
    if kind == "lambertian":
        if given != ["reflectance"]:
            raise BadInputError(f"{ctx}: a lambertian material takes 'reflectance' (ρ, 0 ≤ ρ < 1) only")
        r = spec["reflectance"]
        if not 0 <= r < 1:
            raise BadInputError(f"{ctx}: reflectance must be in [0, 1), got {r!r}")
        return Material.lambertian(r)
    if len(given) != 1:
        extra = " or 'transmittance'" if kind == "glass" else ""
        raise BadInputError(f"{ctx}: give exactly one of 'reflectance' (grey) or 'colour' (RGB){extra}")
    if given[0] == "reflectance":
        colour = (spec["reflectance"],) * 3
    elif given[0] == "transmittance":
        if kind != "glass":
            raise BadInputError(f"{ctx}: 'transmittance' is for glass only")
        try:
            colour = (glass_transmissivity(spec["transmittance"]),) * 3
        except BadInputError as exc:
            raise BadInputError(f"{ctx}: {exc}") from None
    else:
        colour = spec[given[0]]
    return Material.checked(kind, colour, specularity=spec["specularity"], roughness=spec["roughness"],
                            transmissivity=spec["transmissivity"],
                            transmitted_specularity=spec["transmitted_specularity"],
                            refractive_index=spec["refractive_index"], where=ctx)


def _views(specs):
    views = []
    for k, spec in enumerate(specs):
        ctx = f"views[{k}]"
        try:
            rotation = camera_to_world(spec["line_of_sight"], spec["up"])
        except BadInputError as exc:
            raise BadInputError(f"{ctx}: {exc}") from None
        views.append(View(spec.get("name", f"view{k}"), np.asarray(spec["position"], float), rotation,
                          _projection(spec.get("projection", {}), ctx)))
    return views


def as_views(items):
    """:class:`View`\\ s of a list of views and ``[[views]]`` tables (the TOML structure,
    checked against :data:`SCENE_SCHEMA`), e.g. to add views to a scene read from another
    format; views are kept, tables built, in that order."""
    items = list(items or [])
    tables = [v for v in items if not isinstance(v, View)]
    built = _views(validate({"views": tables}, SCENE_SCHEMA, source="views")["views"]) if tables else []
    return [v for v in items if isinstance(v, View)] + built


def _photometry_file(file, ctx, base, reader):
    """The :class:`Photometry` and luminous rectangle (length, width) [m] of a photometric file.

    The luminous opening gives the emission rectangle (length along C0, width along C90); a
    circular opening (negative sizes, IES convention) becomes the square of the same area.
    """
    file = Path(file)
    if not file.is_absolute() and base is not None:
        file = Path(base) / file
    try:
        phot = (reader or read_photometry)(file)
    except BadInputError as exc:
        raise BadInputError(f"{ctx}: {exc}") from None
    if not isinstance(phot, Photometry):
        raise BadInputError(f"{ctx}: the photometry reader returned a {type(phot).__name__}, "
                            "not a Photometry")
    length, width = phot.length, phot.width
    if length < 0 or width < 0:  # circular/elliptical opening: square of equal area
        side = math.sqrt(math.pi * abs(length) * abs(width)) / 2.0
        length = width = side
    return phot, (length, width)
