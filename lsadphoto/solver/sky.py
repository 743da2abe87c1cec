"""Distant light sources — the sun and the sky — for every estimator of the solver.

A :class:`DistantSource` is Radiance's ``source`` primitive with a ``light`` or ``glow``
material: light that arrives from directions within a cone (axis towards the source,
``half_angle``) with luminance L(ω) [cd·m⁻²] that does not depend on where it arrives, as
from infinitely far away. The sun is a cone of 0.5° (0.533° in gendaylit) of uniform
luminance; the sky and the ground glow are hemispheres whose luminance follows a sky model
(:func:`sky_luminance_shape`): the CIE clear, intermediate, overcast and uniform skies of
Radiance's ``skybright.cal`` as ``gensky`` writes them, and the Perez all-weather sky of
``perezlum.cal`` as ``gendaylit`` writes it, evaluated natively from the same arguments.
Overlapping sources add: where Radiance shows only the sun, the sky behind its disc is added
(at most L_sky·Ω_sun, Ω_sun = 6·10⁻⁵ sr).

How the estimators use them (one path per concept):

* **direct light** at a point x with normal n, E = ∫ L(ω) max(0, n·ω) V(x, ω) dω, by
  next-event estimation with directions drawn in proportion to L (:meth:`DistantSource.sample`;
  uniform in the cone for a uniform source, a tabulated 32 × 64 grid of equal-solid-angle
  cells for a sky, with the weight L(ω)/(p(ω)·K), K = ∫L dω), the s directions of a point
  stratified (four independent groups, each jittered on a grid of the unit square, which the
  sampler maps continuously onto the cone; the groups' spread is the variance): unbiased,
  and exact for a fully visible sun (:func:`distant_illuminance`; with the whole non-delta
  BSDF and the shadow transmittance through glass for other materials,
  :func:`distant_reflection`);
* **light chains** enter the scene through its bounding sphere: a source chosen in
  proportion to its flux Φ = πR²·K through the sphere's cross-section, a direction ω drawn
  as above, a point uniform on the disc of radius R perpendicular to ω, the chain travelling
  along −ω with weight W₀·L/(p·K) (:class:`~lsadphoto.solver.chains.EmissionSampler`);
* **rays that leave the scene** see L(ω) (:func:`background_luminance`): eye rays (through
  glass and mirrors too), and rays after a delta reflection, which next-event estimation
  cannot follow (as emission found by such rays).

References
----------
CIE S 011/E:2003 = ISO 15469:2004, *Spatial distribution of daylight — CIE standard general
sky* (the clear and overcast gradation and indicatrix functions). Moon, P., Spencer, D. E.
(1942). Illumination from a non-uniform sky. *Illuminating Engineering* 37, 707–726 (the
overcast sky L = L_z(1 + 2 cos θ)/3). Perez, R., Seals, R., Michalsky, J. (1993).
All-weather model for sky luminance distribution. *Solar Energy* 50(3), 235–245. Radiance
``lib/skybright.cal``, ``lib/perezlum.cal``, ``src/gen/gensky.c``, ``src/gen/gendaylit.c``
(the arguments these functions take); Radiance reference manual, "source", "glow".
"""

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import BadInputError
from ._sampling import orthonormal_basis, stream
from .materials import diffuse_fresnel_factor, shadow_transmittance, shadows_transmit

__all__ = ["DISTANT_RAYS_PER_DIRECT_SAMPLE", "DistantSource", "GATHER_DISTANT_SAMPLES", "SKY_FUNCTIONS",
           "TOML_SKY_MODELS", "background_luminance", "distant_illuminance", "distant_reflection",
           "distant_uniforms", "sky_luminance_shape", "sky_sources", "stratified"]

#: The sky functions read natively: (function, .cal file) → number of real arguments.
SKY_FUNCTIONS = {("skybr", "skybright.cal"): (3, 7), ("skybright", "perezlum.cal"): (10,)}
#: skybright.cal's sky types (its first argument).
SKY_TYPES = {1: "CIE clear", 2: "CIE overcast", 3: "uniform", 4: "CIE intermediate"}
#: Equal-solid-angle cells of the direction table of a sky: cos θ × azimuth about the axis.
TABLE_CELLS = (32, 64)
#: Sub-points per cell side at which the table's cell means are evaluated.
TABLE_SUBPOINTS = 3


def _horizon_blend(dz, sky, ground):
    """skybright.cal's and perezlum.cal's wmean((Dz+1.01)^10, sky, (Dz+1.01)^-10, ground)."""
    a = (dz + 1.01) ** 10
    b = (dz + 1.01) ** -10
    return (a * sky + b * ground) / (a + b)


def sky_luminance_shape(function, calfile, args, directions):
    """Value of a Radiance sky function at world directions ``(..., 3)`` (towards the sky).

    ``skybr`` of ``skybright.cal`` (gensky): A1 the sky type (1 CIE clear, 2 CIE overcast,
    3 uniform, 4 CIE intermediate), A2 the zenith brightness, A3 the ground brightness, and
    for types 1 and 4 A4 the normalisation and A5–A7 the sun direction; ``skybright`` of
    ``perezlum.cal`` (gendaylit): A1 the diffuse normalisation, A2 the ground brightness,
    A3–A7 the Perez coefficients a–e, A8–A10 the sun direction. Both blend the sky with the
    ground brightness near the horizon as the .cal files do (weights (Dz + 1.01)^±10), so
    the value is the one Radiance computes; the sky formulas are those of CIE S 011 (clear:
    gradation 1 − e^(−0.32/cos θ), indicatrix 0.91 + 10 e^(−3γ) + 0.45 cos²γ; overcast:
    Moon & Spencer's (1 + 2 cos θ)/3) and of Perez et al. (1993).
    """
    d = np.asarray(directions, float)
    dx, dy, dz = d[..., 0], d[..., 1], d[..., 2]
    a = list(args)
    if (function, calfile) == ("skybr", "skybright.cal"):
        kind, zenith, ground = int(a[0]), a[1], a[2]
        if kind == 2:
            sky = zenith * (1 + 2 * dz) / 3
        elif kind == 3:
            sky = np.full(dz.shape, float(zenith))
        else:
            cosg = dx * a[4] + dy * a[5] + dz * a[6]
            gamma = np.arccos(np.clip(cosg, -1.0, 1.0))
            if kind == 1:
                with np.errstate(divide="ignore", over="ignore"):
                    grad = np.where(dz - 0.01 > 0, 1.0 - np.exp(-0.32 / np.where(dz > 0, dz, 1.0)), 1.0)
                sky = zenith * (0.91 + 10 * np.exp(-3 * gamma) + 0.45 * cosg * cosg) * grad / a[3]
            else:
                zt = math.acos(max(-1.0, min(1.0, a[6])))
                eta = np.arccos(np.clip(dz, -1.0, 1.0))
                sky = (zenith * ((1.35 * np.sin(5.631 - 3.59 * eta) + 3.12) * math.sin(4.396 - 2.6 * zt)
                                 + 6.37 - eta) / 2.326
                       * np.exp(gamma * -0.563 * ((2.629 - eta) * (1.562 - zt) + 0.812)) / a[3])
        return _horizon_blend(dz, sky, ground)
    if (function, calfile) == ("skybright", "perezlum.cal"):
        norm, ground, pa, pb, pc, pd, pe = a[:7]
        cosg = dx * a[7] + dy * a[8] + dz * a[9]
        gamma = np.arccos(np.clip(cosg, -1.0, 1.0))
        with np.errstate(over="ignore"):
            grad = 1 + pa * np.exp(pb / np.where(dz - 0.01 > 0, dz, 0.01))
        sky = norm * grad * (1 + pc * np.exp(pd * gamma) + pe * cosg * cosg)
        return _horizon_blend(dz, sky, ground)
    raise BadInputError(f"sky function {function} of {calfile} is not supported; supported: "
                        + ", ".join(f"{f} of {c}" for f, c in SKY_FUNCTIONS))


def check_sky_arguments(function, calfile, args, where):
    """Raise :class:`BadInputError` (one line, ``where`` first) unless ``args`` are what the
    sky function takes."""
    counts = SKY_FUNCTIONS.get((function, calfile))
    if counts is None:
        raise BadInputError(f"{where}: {function} of {calfile} is not supported on a source; supported: "
                            + ", ".join(f"{f} of {c}" for f, c in SKY_FUNCTIONS))
    if function == "skybr":
        if not args or args[0] not in SKY_TYPES:
            raise BadInputError(f"{where}: skybr's first argument must be the sky type "
                                f"({', '.join(f'{k} {v}' for k, v in SKY_TYPES.items())}), got "
                                f"{args[0] if args else 'none'}")
        counts = (3, 7) if args[0] in (2, 3) else (7,)
    if len(args) not in counts:
        raise BadInputError(f"{where}: {function} of {calfile} needs {' or '.join(map(str, counts))} "
                            f"real arguments, got {len(args)}")
    if function == "skybr" and args[0] in (1, 4) and not args[3] > 0:
        raise BadInputError(f"{where}: skybr's normalisation (fourth argument) must be positive")


@dataclass(eq=False)
class DistantSource:
    """Light from a cone of directions at infinity (Radiance ``source`` with ``light``/``glow``).

    Parameters
    ----------
    name : str
    axis : array_like, shape (3,)
        Direction towards the source's centre (normalised).
    half_angle : float
        Half the cone's angle [rad], 0 < half_angle ≤ π (Radiance's angle / 2: π/2 for a
        hemisphere of sky).
    luminance : float
        Luminance [cd·m⁻²] (uniform source), or the factor of the sky function (179 lm/W ×
        Y of the glow's RGB) [cd·m⁻² per unit of the function].
    function : tuple, optional
        ``(function, calfile, args)`` of a sky function (:func:`sky_luminance_shape`);
        ``None``: uniform.
    transform : array_like, shape (3, 3), optional
        Maps world directions into the function's coordinates (the pattern's own transform
        in Radiance).
    where : str
        Where it was defined (``file:line``), for messages.
    light_source : bool
        Whether Radiance's direct calculation takes it as a light source: a ``source`` of
        ``light`` (the sun); a ``glow`` one (the sky, the ground) is skipped there and lights
        only through the ambient calculation (``SSKIP`` in Radiance's ``source.c``). Decides the
        factor 1 − F(μ_i) under the ``"radiance"`` rule
        (:data:`~lsadphoto.solver.materials.FRESNEL_RULES`).
    """

    name: str
    axis: np.ndarray
    half_angle: float
    luminance: float
    function: tuple = None
    transform: np.ndarray = None
    where: str = ""
    light_source: bool = True
    _table: dict = field(default=None, repr=False)

    def __post_init__(self):
        a = np.asarray(self.axis, float)
        label = f"{self.where}: source {self.name!r}" if self.where else f"distant source {self.name!r}"
        if a.shape != (3,) or not np.linalg.norm(a) > 0:
            raise BadInputError(f"{label}: its direction must be a non-zero 3-vector")
        self.axis = a / np.linalg.norm(a)
        if not 0 < self.half_angle <= math.pi:
            raise BadInputError(f"{label}: its angle must be in (0°, 360°], got "
                                f"{math.degrees(2 * self.half_angle):g}°")
        if not self.luminance > 0:
            raise BadInputError(f"{label}: its luminance must be positive, got {self.luminance!r}")
        if self.function is not None:
            check_sky_arguments(*self.function, label)
        self.cos_half = math.cos(self.half_angle)
        #: Solid angle of the cone [sr].
        self.solid_angle = 2 * math.pi * (1 - self.cos_half)
        self._frame = np.stack([*orthonormal_basis(self.axis[None]), self.axis[None]], axis=1)[0]
        if self.function is not None:
            self._build_table()
        #: K = ∫ L dω over the cone [lx]: the illuminance on a plane facing a small source
        #: (the sun's normal illuminance); πR²·K is the flux through a disc of radius R
        #: perpendicular to each direction, summed over the directions (the light chains'
        #: flux, :meth:`~lsadphoto.solver.scene.Scene.distant_flux`). A sky's K is the
        #: table's (its cell means on 3 × 3 sub-points), which the weights L/(p·K) correct.
        self.integral = (self.luminance * self.solid_angle if self.function is None
                         else self.luminance * float(self._table["mass"].sum()))
        if not self.integral > 0:
            raise BadInputError(f"{label} emits no light (its sky function is zero)")

    def to_dict(self):
        """JSON-ready description (stores)."""
        f = self.function
        return {"name": self.name, "axis": self.axis.tolist(), "half_angle": self.half_angle,
                "luminance": self.luminance, "where": self.where, "light_source": self.light_source,
                "function": None if f is None else [f[0], f[1], list(f[2])],
                "transform": None if self.transform is None else np.asarray(self.transform).tolist()}

    @classmethod
    def from_dict(cls, d):
        f = d.get("function")
        return cls(d["name"], np.asarray(d["axis"]), d["half_angle"], d["luminance"],
                   None if f is None else (f[0], f[1], tuple(f[2])),
                   None if d.get("transform") is None else np.asarray(d["transform"]), d.get("where", ""),
                   bool(d.get("light_source", True)))

    def _shape(self, directions):
        f, cal, args = self.function
        d = directions
        if self.transform is not None:
            d = d @ np.asarray(self.transform).T
            d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        return np.maximum(sky_luminance_shape(f, cal, args, d), 0.0)

    def radiance(self, directions):
        """Luminance [cd·m⁻²] arriving from unit world ``directions`` ``(n, 3)``."""
        d = np.asarray(directions, float).reshape(-1, 3)
        inside = d @ self.axis >= self.cos_half
        out = np.zeros(len(d))
        if inside.any():
            out[inside] = self.luminance * (1.0 if self.function is None else self._shape(d[inside]))
        return out

    def _directions(self, cos_t, phi):
        cos_t, phi = np.broadcast_arrays(cos_t, phi)
        s = np.sqrt(np.maximum(0.0, 1 - cos_t * cos_t))
        local = np.stack([s * np.cos(phi), s * np.sin(phi), cos_t], axis=-1)
        return local @ self._frame

    def _build_table(self):
        nu, nphi = TABLE_CELLS
        k = TABLE_SUBPOINTS
        cu = self.cos_half + (1 - self.cos_half) * (np.arange(nu * k) + 0.5) / (nu * k)
        ph = 2 * math.pi * (np.arange(nphi * k) + 0.5) / (nphi * k)
        values = self._shape(self._directions(cu[:, None], ph[None, :]).reshape(-1, 3))
        mean = values.reshape(nu, k, nphi, k).mean(axis=(1, 3))
        mean = np.maximum(mean, 1e-6 * mean.max(initial=0.0))  # p > 0 wherever light may come from
        mass = mean * (self.solid_angle / (nu * nphi))
        rows = mass.sum(axis=1)
        if not rows.sum() > 0:
            self._table = {"mass": mass}  # emits nothing: refused by __post_init__
            return
        self._table = {"mean": mean, "mass": mass, "rows": np.cumsum(rows) / rows.sum(),
                       "cols": np.cumsum(mass, axis=1) / rows[:, None]}

    def sample(self, u):
        """Directions towards the source from uniforms ``u`` ``(n, ≥ 2)`` and their weights
        L(ω)/(p(ω)·K) (1 for a uniform source), so that K·weight·g(ω) estimates ∫L g dω.

        The unit square maps continuously onto the cone (cos θ from ``u[:, 0]``, azimuth from
        ``u[:, 1]``; for a sky through the table's marginal and conditional distributions of
        cells, piecewise constant density), so stratified uniforms give stratified directions.
        """
        n = len(u)
        if self.function is None:
            cos_t = 1 - u[:, 0] * (1 - self.cos_half)
            return self._directions(cos_t, 2 * math.pi * u[:, 1]), np.ones(n)
        t = self._table
        nu, nphi = TABLE_CELLS
        iu = np.minimum(np.searchsorted(t["rows"], u[:, 0], side="right"), nu - 1)
        below = np.where(iu > 0, t["rows"][iu - 1], 0.0)
        r0 = np.clip((u[:, 0] - below) / (t["rows"][iu] - below), 0.0, 1.0)
        cols = t["cols"][iu]
        ip = np.minimum((cols < u[:, 1:2]).sum(axis=1), nphi - 1)
        left = np.where(ip > 0, cols[np.arange(n), ip - 1], 0.0)
        r1 = np.clip((u[:, 1] - left) / (cols[np.arange(n), ip] - left), 0.0, 1.0)
        cos_t = self.cos_half + (1 - self.cos_half) * (iu + r0) / nu
        d = self._directions(cos_t, 2 * math.pi * (ip + r1) / nphi)
        return d, self._shape(d) / t["mean"][iu, ip]


def background_luminance(scene, directions):
    """Luminance [cd·m⁻²] of the scene's distant sources seen along unit ``directions``
    ``(n, 3)`` by rays that leave the scene (the sum over sources)."""
    d = np.asarray(directions, float).reshape(-1, 3)
    out = np.zeros(len(d))
    for src in scene.distant_sources:
        out += src.radiance(d)
    return out


#: Shadow rays per distant source, point and batch in the double local estimate's gathers
#: (16 batches: 256 per pixel, beside its 16 × 32 node connections).
GATHER_DISTANT_SAMPLES = 16


#: Shadow rays per distant source and pixel or grid point for each of the surface cache's
#: and the grids' ``direct_samples`` (4 by default: 64 rays, four stratified groups of 16,
#: whose spread gives the pixel's variance; a near-field hit, averaged anyway, takes
#: ``direct_samples``).
DISTANT_RAYS_PER_DIRECT_SAMPLE = 16


#: Independent stratified groups of a point's samples (from 16 samples on), whose spread
#: gives the variance.
STRATIFIED_GROUPS = 4


def distant_uniforms(scene, seed, key, blocks, samples, generators=None):
    """Uniforms ``(P, sources, samples, 2)`` for :func:`distant_illuminance`, stratified: the
    samples of a point and source form :data:`STRATIFIED_GROUPS` interleaved groups (one
    below 16 samples), each jittered one per cell of an m × m grid of the unit square
    (m = ⌊√(group size)⌋; the rest of the group uniform). Every uniform is uniform on the
    square (unbiased), and the groups are independent. Each block of ``blocks`` (one key per
    point) draws from its own stream ``(seed, "distant", *key, block)``, so results do not
    depend on how points are chunked; ``generators`` (a dict) keeps the streams between
    calls, so that repeated calls for one block draw new numbers."""
    blocks = np.asarray(blocks)
    s = int(samples)
    u = np.empty((len(blocks), len(scene.distant_sources), s, 2))
    for j in np.unique(blocks):
        m = blocks == j
        g = None if generators is None else generators.get((*key, j))
        if g is None:
            g = stream(seed, "distant", *key, j)
            if generators is not None:
                generators[(*key, j)] = g
        u[m] = g.random((int(m.sum()), *u.shape[1:]))
    return stratified(u)


def stratified(u):
    """Uniforms ``(..., s, 2)`` made stratified in place (and returned), as
    :func:`distant_uniforms` describes: :data:`STRATIFIED_GROUPS` interleaved groups of the
    s samples (one below 16), each jittered on an m × m grid."""
    s = u.shape[-2]
    groups = _groups(s)
    for first in range(groups):
        size = len(range(first, s, groups))
        side = math.isqrt(size)
        if side > 1:
            idx = np.arange(first, s, groups)[:side * side]
            cell = np.arange(side * side)
            u[..., idx, 0] = (cell // side + u[..., idx, 0]) / side
            u[..., idx, 1] = (cell % side + u[..., idx, 1]) / side
    return u


def _groups(samples):
    return STRATIFIED_GROUPS if samples >= 16 else 1


def distant_illuminance(scene, engine, points, normals, u, *, fresnel=None, fresnel_rule="reciprocal"):
    """Direct illuminance [lx] of the scene's distant sources at points, and its variance.

    ``u`` ``(P, sources, s, 2)`` uniforms (:func:`distant_uniforms`): s shadow rays per
    source and point, directions drawn by :meth:`DistantSource.sample`;
    E = Σ_sources K·mean(w·max(0, n·ω)·V), unbiased; V passes glass and smooth ``trans`` with
    their straight-through transmittance. The variance is the spread of the
    independent stratified groups' means (from 16 samples on); below, the samples' spread as
    if they were independent, an upper bound for stratified samples (for s = 1 the square of
    the estimate, also an upper bound). ``fresnel`` (bool per point, optional): where true,
    the Fresnel-weighted illuminance E_F, each term times 1 − F(n·ω)
    (:func:`~lsadphoto.solver.direct.direct_illuminance`) — under ``fresnel_rule``
    ``"radiance"`` only for the sources that are Radiance light sources (``light_source``).
    """
    x = np.asarray(points, float).reshape(-1, 3)
    n = np.asarray(normals, float).reshape(-1, 3)
    P = len(x)
    E, var = np.zeros(P), np.zeros(P)
    sources = scene.distant_sources
    if P == 0 or not sources:
        return E, var
    s = u.shape[2]
    origins = np.repeat(x + engine.epsilon * n, s, axis=0).astype(np.float32)
    normals_s = np.repeat(n, s, axis=0)
    reach = np.float32(4 * scene.sphere[1] + 1.0)
    for k, src in enumerate(sources):
        d, w = src.sample(u[:, k].reshape(-1, 2))
        cos = np.einsum("ij,ij->i", d, normals_s)
        g = w * cos if fresnel is None else w * cos * diffuse_fresnel_factor(
            cos, np.repeat(fresnel, s), rule=fresnel_rule, direct=src.light_source)
        lit = np.flatnonzero(g > 0)
        value = np.zeros(P * s)
        if lit.size and shadows_transmit(scene):
            # through glass and smooth trans with their transmittance (Radiance's shadow rays)
            o = origins[lit].astype(float)
            value[lit] = src.integral * g[lit] * shadow_transmittance(scene, engine, o, o + float(reach) * d[lit])
        elif lit.size:
            blocked = engine.occluded(origins[lit], d[lit].astype(np.float32), np.full(lit.size, reach))
            value[lit] = np.where(blocked, 0.0, src.integral * g[lit])
        value = value.reshape(P, s)
        E += value.mean(axis=1)
        groups = _groups(s)
        if groups > 1:
            means = np.stack([value[:, g::groups].mean(axis=1) for g in range(groups)], axis=1)
            var += means.var(axis=1, ddof=1) / groups
        else:
            var += value.var(axis=1, ddof=1) / s if s > 1 else value[:, 0] ** 2
    return E, var


def distant_reflection(scene, engine, points, normals, towards, materials, u, *, fresnel_rule="reciprocal"):
    """Luminance [cd·m⁻²] that points with non-Lambertian materials reflect or transmit
    towards ``towards`` from the distant sources, by next-event estimation.

    ``u`` ``(P, sources, s, 2)`` uniforms (stratified); per source Σ K·w·f(ω, ω_o)·|n·ω|·T/s
    with f the whole non-delta BSDF (:meth:`~lsadphoto.solver.materials.MaterialTable.evaluate`,
    either side of transmitting surfaces) and T the shadow transmittance (glass passes light
    straight through). The delta parts (mirror reflections) are left to sampled rays.
    Shape ``(2, P)``: the parts scattered by the diffuse and by the glossy component of f
    (the double local estimate weights them differently). ``fresnel_rule``: the smooth
    materials' factor 1 − F(μ_i) (:data:`~lsadphoto.solver.materials.FRESNEL_RULES`), under
    ``"radiance"`` for the sources that are Radiance light sources only.
    """
    x = np.asarray(points, float).reshape(-1, 3)
    P = len(x)
    out = np.zeros((2, P))
    if P == 0 or not scene.distant_sources:
        return out
    s = u.shape[2]
    owner = np.repeat(np.arange(P), s)
    n, wo, mat = normals[owner], towards[owner], np.asarray(materials)[owner]
    reach = 4 * scene.sphere[1] + 1.0
    eps = engine.epsilon
    for k, src in enumerate(scene.distant_sources):
        d, w = src.sample(u[:, k].reshape(-1, 2))
        cos = np.einsum("ij,ij->i", d, n)
        f = np.stack(scene.bsdf.evaluate(mat, n, wo, d, split=True, rule=fresnel_rule, direct=src.light_source))
        val = src.integral * w * np.abs(cos) * f
        ok = np.flatnonzero((val[0] > 0) | (val[1] > 0))
        if ok.size:
            origin = x[owner[ok]] + eps * np.sign(cos[ok])[:, None] * n[ok]
            seen = shadow_transmittance(scene, engine, origin, origin + reach * d[ok])
            for c in (0, 1):
                out[c] += np.bincount(owner[ok], weights=val[c, ok] * seen, minlength=P) / s
    return out


#: Sky models of a TOML scene's ``[[luminaires]] type = "sky"`` → skybright.cal's sky type.
TOML_SKY_MODELS = {"cie-clear": 1, "cie-overcast": 2, "uniform": 3, "cie-intermediate": 4}


def sky_sources(name, model, zenith_luminance, *, sun_direction=None, ground_luminance=0.0):
    """The distant sources of a sky given by its model and zenith luminance [cd·m⁻²]: the
    sky hemisphere (skybright.cal's function, normalised so that the zenith has exactly
    ``zenith_luminance``, its horizon blended with ``ground_luminance`` as gensky's sky is)
    and, when ``ground_luminance`` > 0, a uniform ground hemisphere below the horizon (what
    gensky users add as the ground glow). ``sun_direction`` (towards the sun) is needed by
    the clear and intermediate skies."""
    kind = TOML_SKY_MODELS[model]
    if not zenith_luminance > 0:
        raise BadInputError(f"{name}: zenith_luminance must be positive, got {zenith_luminance!r}")
    if not ground_luminance >= 0:
        raise BadInputError(f"{name}: ground_luminance must be ≥ 0, got {ground_luminance!r}")
    args = (kind, zenith_luminance, ground_luminance)
    if kind in (1, 4):
        if sun_direction is None:
            raise BadInputError(f"{name}: a {model} sky needs its sun_direction")
        sun = np.asarray(sun_direction, float)
        if sun.shape != (3,) or not np.linalg.norm(sun) > 0:
            raise BadInputError(f"{name}: sun_direction must be a non-zero 3-vector")
        sun = sun / np.linalg.norm(sun)
        args = (kind, zenith_luminance, ground_luminance, 1.0, *sun)
        # the normalisation A4: the function's own value at the zenith, so that L(zenith) = A2
        args = (*args[:3], float(sky_luminance_shape("skybr", "skybright.cal", args, np.array([0.0, 0.0, 1.0]))
                                 / _horizon_blend(1.0, 1.0, 0.0) / zenith_luminance), *sun)
    # gensky's sky and ground are glows: no light sources of Radiance's direct calculation
    sources = [DistantSource(f"{name}", np.array([0.0, 0.0, 1.0]), math.pi / 2, 1.0,
                             ("skybr", "skybright.cal", args), light_source=False)]
    if ground_luminance > 0:
        sources.append(DistantSource(f"{name} ground", np.array([0.0, 0.0, -1.0]), math.pi / 2,
                                     float(ground_luminance), light_source=False))
    return sources
