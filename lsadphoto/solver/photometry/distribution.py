"""The luminous intensity distribution of a luminaire: one type, :class:`Photometry`.

Every luminaire of the solver that is not a Lambertian surface — a photometric file, an
isotropic point, a tabulated function, an ies2rad luminaire of a Radiance scene — is one
:class:`Photometry`: intensities [cd] on a grid of C-planes and vertical angles γ [deg],
bilinear in between (zero outside the grid's γ range), with the luminous flux of that
interpolant computed exactly, its luminous opening, and emission directions sampled from a
piecewise-constant density over the grid cells. The sampling weight I(ω)/(Φ·p(ω)) is carried
by the light chain, so the sampling is unbiased for the interpolant whatever the grid.

Coordinate convention (CIE 121-1996 C–γ system, IES "type C" photometry)
------------------------------------------------------------------------
The luminaire hangs with its axis vertical; x, y, z is right-handed with z up::

                 +z (up, γ = 180°, zenith)
                  |
                  |      +y  (C = 90°)
                  |     /
                  |    /
                  +-----------> +x  (C = 0°, along the luminaire's length)
                  |
                  |
                 -z (down, γ = 0°, nadir)

* γ (vertical angle) is measured from the nadir −z: γ = 0 straight down, 90° horizontal,
  180° straight up.
* C (horizontal angle, C-plane) is measured about the vertical axis from +x (the length
  axis of the luminaire), counter-clockwise seen from above, so that C = 90° is +y.
* The direction of emission (C, γ) is ``(sin γ cos C, sin γ sin C, −cos γ)``.

LM-63-02 §3 defines vertical angles as the displacement from straight down (nadir) and
horizontal angles of type C photometry as measured counter-clockwise in the horizontal
plane; the luminous opening's *length* is the 0–180° dimension and its *width* the 90–270°
one, so 0° lies along the luminaire's length (the real Ledalite file says so:
``[ALGN] 0 degree plane parallel to lamps``). EULUMDAT (Stockmar 1990) uses the C–γ system
of CIE 121: γ = 0 at the nadir, C0 along the luminaire's length ("length of luminous area"
is the C0–C180 dimension, "width b1" the C90–C270 one), C increasing counter-clockwise.
For type C photometry the two formats therefore share one convention and their angles are
copied without change.

Caveat (handedness): LM-63 says "counter-clockwise" without naming the viewpoint; this
module reads it (and EULUMDAT's C) as seen from above (C = 90° along +y). Radiance's
ies2rad documents the opposite reading (IES horizontal angle = −φ of its azimuth from +x
towards +y). The two readings are mirror images about the C0–C180 plane and differ only
for files without C0–C180 symmetry (IES 0–360° or 90–270°, EULUMDAT Isym 0 or 3); to
mirror a luminaire, call ``intensity(-c, gamma)``.

In the world, a luminaire's frame (:func:`luminaire_frame`) holds its axes as rows: e_C0 (the
length axis), e_C90 (= zenith × e_C0) and e_nadir (γ = 0).

References
----------
CIE 121-1996, *The Photometry and Goniophotometry of Luminaires* (C–γ system).
EN 13032-1:2004+A1:2012, *Light and lighting — Measurement and presentation of photometric
data of lamps and luminaires*, Part 1 (C-planes). ANSI/IES LM-63-19 (luminous opening).
Marchuk, G. I. et al. (1980), *Monte Carlo Methods in Atmospheric Optics*, Springer, ch. 2
(sampling of source distributions, weights).
"""

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from ..._compiled import njit

from ..._validation import check_array
from ...errors import BadInputError
from ...geometry.observer import orthonormal_pair

__all__ = ["PACKED_TABLES", "PHOTOMETRY_FORMATS", "Photometry", "local_angles", "luminaire_frame",
           "pack_photometries", "packed_intensity"]

#: numba type of :func:`pack_photometries`' ``tables`` (for the kernels' ahead-of-time
#: signatures, :mod:`lsadphoto._compiled`).
PACKED_TABLES = ("Tuple((int64[::1], int64[::1], int64[::1], float64[::1], float64[::1], float64[::1], "
                 "float64[::1], boolean[::1]))")

#: Format names a :class:`Photometry` can carry: the photometric files read by
#: :mod:`lsadphoto.solver.photometry`, and distributions made otherwise.
PHOTOMETRY_FORMATS = (
    "IES LM-63-1986",
    "IES LM-63-1991",
    "IES LM-63-1995",
    "IES LM-63-2002",
    "IES LM-63-2019",
    "EULUMDAT",
    "isotropic",
    "function",
    "Radiance brightdata",
)

#: Tolerance [deg] within which an angle counts as equal to a sampled one (snapping, symmetry).
ANGLE_EPS = 1e-9

# --------------------------------------------------------------------------------------------
# The distribution
# --------------------------------------------------------------------------------------------


def _segment_weights(gamma):
    """Exact weights of ∫ I(γ) sin γ dγ for I linear between the nodes ``gamma`` [rad].

    On a segment [a, b] of width h with I = I_a (b−γ)/h + I_b (γ−a)/h:
    ∫ (b−γ) sin γ dγ / h = cos a − (sin b − sin a)/h and
    ∫ (γ−a) sin γ dγ / h = −cos b + (sin b − sin a)/h.
    """
    a, b = gamma[:-1], gamma[1:]
    h = b - a
    ds = np.sin(b) - np.sin(a)
    with np.errstate(divide="ignore", invalid="ignore"):
        wa = np.where(h > 0, np.cos(a) - ds / np.where(h > 0, h, 1.0), 0.0)
        wb = np.where(h > 0, -np.cos(b) + ds / np.where(h > 0, h, 1.0), 0.0)
    weights = np.zeros_like(gamma)
    weights[:-1] += wa
    weights[1:] += wb
    return weights


def _c_weights(c_deg):
    """Trapezoid weights [rad] over the closed C grid 0..360° (exact for I linear in C)."""
    c = np.radians(c_deg)
    h = np.diff(c)
    weights = np.zeros_like(c)
    weights[:-1] += h / 2
    weights[1:] += h / 2
    return weights


def _flux(c_deg, gamma_deg, candela, gamma_min=0.0, gamma_max=180.0):
    """Flux [lm] of the bilinear distribution between two vertical angles [deg]."""
    lo = max(gamma_min, gamma_deg[0])
    hi = min(gamma_max, gamma_deg[-1])
    if hi <= lo:
        return 0.0
    inner = gamma_deg[(gamma_deg > lo) & (gamma_deg < hi)]
    nodes = np.concatenate([[lo], inner, [hi]])
    rows = np.array([np.interp(nodes, gamma_deg, row) for row in candela])
    per_plane = rows @ _segment_weights(np.radians(nodes))
    return float(per_plane @ _c_weights(c_deg))


@dataclass(frozen=True, eq=False)
class Photometry:
    """Luminous intensity distribution of a luminaire on a C–γ grid (type C photometry).

    Angles follow CIE 121 (module docstring): γ = 0 at the nadir (−z), C = 0 along the
    luminaire's length (+x), C = 90° along +y (counter-clockwise seen from above).

    Attributes
    ----------
    c_angles : ndarray, shape (n_c,)
        C-plane angles [deg], ascending from 0 to 360 inclusive (the 360° plane repeats 0°),
        after the file's symmetry has been expanded.
    gamma_angles : ndarray, shape (n_gamma,)
        Vertical angles γ [deg], ascending, within 0..180.
    candela : ndarray, shape (n_c, n_gamma)
        Absolute luminous intensity [cd]: the file's values with its multipliers applied
        (IES candela multiplier, ballast factor, 1995 ballast-lamp factor, TILT factor;
        EULUMDAT cd/klm × lamp flux/1000 × conversion factor).
    luminous_flux : float
        Luminous flux [lm] of the bilinear distribution, integrated exactly (not the file's
        lamp lumens); computed, not an argument.
    width, length, height : float
        Luminous opening [m]: length along C0–C180 (x), width along C90–C270 (y), height
        along z. IES sign conventions: negative width and length = circular/elliptical
        opening (diameter |width|), all three negative = sphere/ellipsoid. 0 = point source.
    source : str
        The file read.
    format : str
        One of :data:`PHOTOMETRY_FORMATS`.
    metadata : dict
        IES keywords (``"TEST"``, ``"MANUFAC"``, …) and numeric header; EULUMDAT header
        fields, lamp sets and ratios. Not interpreted further.

    References
    ----------
    CIE 121-1996 (C–γ system); ANSI/IES LM-63-19 (file structure); Stockmar (1990).
    """

    c_angles: np.ndarray
    gamma_angles: np.ndarray
    candela: np.ndarray
    width: float = 0.0
    length: float = 0.0
    height: float = 0.0
    source: str = ""
    format: str = ""
    metadata: dict = field(default_factory=dict)
    luminous_flux: float = field(init=False)

    def __post_init__(self):
        c = check_array(self.c_angles, "c_angles", ndim=1, finite=True, dtype=float).copy()
        g = check_array(self.gamma_angles, "gamma_angles", ndim=1, finite=True, dtype=float).copy()
        cd = check_array(self.candela, "candela", ndim=2, finite=True, dtype=float).copy()
        if cd.shape != (c.size, g.size):
            raise BadInputError(f"candela must have shape (n_c, n_gamma) = {(c.size, g.size)}, got {cd.shape}")
        if c.size < 2 or c[0] != 0.0 or c[-1] != 360.0 or np.any(np.diff(c) <= 0):
            raise BadInputError("c_angles must ascend strictly from 0 to 360 degrees inclusive")
        if g.size < 2 or g[0] < 0.0 or g[-1] > 180.0 or np.any(np.diff(g) <= 0):
            raise BadInputError("gamma_angles must ascend strictly within 0..180 degrees (at least two)")
        if np.any(cd < 0):
            raise BadInputError("candela contains negative intensities")
        for array in (c, g, cd):
            array.setflags(write=False)
        object.__setattr__(self, "c_angles", c)
        object.__setattr__(self, "gamma_angles", g)
        object.__setattr__(self, "candela", cd)
        object.__setattr__(self, "luminous_flux", _flux(c, g, cd))
        for name in ("width", "length", "height"):
            object.__setattr__(self, name, float(getattr(self, name)))

    def __repr__(self):
        return (f"Photometry(format={self.format!r}, source={self.source!r}, "
                f"n_c={self.c_angles.size}, n_gamma={self.gamma_angles.size}, "
                f"luminous_flux={self.luminous_flux:.6g} lm, max={self.candela.max():.6g} cd)")

    # ---------------------------------------------------------------------------------------
    def intensity(self, c, gamma):
        """Luminous intensity [cd] in the direction (C, γ), bilinear in (C, γ).

        Parameters
        ----------
        c : array_like
            C-plane angle [rad]; periodic (any real value, taken modulo 2π).
        gamma : array_like
            Vertical angle γ [rad] from the nadir; broadcast against ``c``.

        Returns
        -------
        ndarray
            Intensity [cd], the broadcast shape of ``c`` and ``gamma``. Exactly the file's
            value at a sampled (C, γ) (angles within 1e-9° snap to the grid); 0 outside the
            sampled γ range (e.g. above 90° for a file that stops there); NaN where an input
            is NaN.

        References
        ----------
        CIE 121-1996 (C–γ system); ANSI/IES LM-63-19 (interpolation left to the user).

        Examples
        --------
        >>> p = Photometry([0.0, 360.0], [0.0, 90.0], [[100.0, 0.0], [100.0, 0.0]])
        >>> float(p.intensity(1.0, np.radians(45.0)))
        50.0
        """
        c_deg, g_deg = np.broadcast_arrays(np.degrees(np.asarray(c, dtype=float)),
                                           np.degrees(np.asarray(gamma, dtype=float)))
        nan = np.isnan(c_deg) | np.isnan(g_deg)
        c_deg = np.where(nan, 0.0, c_deg) % 360.0
        g_deg = np.where(nan, self.gamma_angles[0], g_deg)
        i, t = _locate(self.c_angles, c_deg)
        j, u = _locate(self.gamma_angles, g_deg)
        cd = self.candela
        value = ((1 - t) * ((1 - u) * cd[i, j] + u * cd[i, j + 1])
                 + t * ((1 - u) * cd[i + 1, j] + u * cd[i + 1, j + 1]))
        inside = (g_deg >= self.gamma_angles[0] - ANGLE_EPS) & (g_deg <= self.gamma_angles[-1] + ANGLE_EPS)
        value = np.where(inside, value, 0.0)
        return np.where(nan, np.nan, value)

    def projected_area(self, c, gamma):
        """Projected area [m²] of the luminous opening seen from the direction (C, γ).

        With d = (sin γ cos C, sin γ sin C, −cos γ), length l along x, width w along y and
        height h along z (see :class:`Photometry`):

        * rectangular opening (w, l, h ≥ 0; h > 0 adds luminous sides):
          A = l·w·|cos γ| + w·h·|sin γ cos C| + l·h·|sin γ sin C|;
        * circular/elliptical opening (w < 0, l < 0; diameters |l| along x, |w| along y;
          h > 0 adds a luminous vertical cylinder):
          A = π|l||w|/4·|cos γ| + h·√(l² sin²C + w² cos²C)·|sin γ|;
        * sphere/ellipsoid (w, l, h < 0; diameters |l|, |w|, |h|):
          A = π·√(b²c²d_x² + a²c²d_y² + a²b²d_z²) with semi-axes a, b, c = |l|/2, |w|/2, |h|/2.

        A flat opening is counted from both sides (|cos γ|): the file's intensity decides
        whether light leaves upwards. Other sign combinations of LM-63-19 (horizontal
        cylinders, …) raise :class:`BadInputError`.

        Parameters
        ----------
        c, gamma : array_like
            Direction [rad], broadcast together.

        Returns
        -------
        ndarray
            Projected area [m²].

        References
        ----------
        ANSI/IES LM-63-19 (luminous opening dimensions and shapes); ANSI/IESNA LM-63-02
        (luminous opening dimensions, negative values for round openings).
        """
        c = np.asarray(c, dtype=float)
        gamma = np.asarray(gamma, dtype=float)
        dx, dy, dz = np.sin(gamma) * np.cos(c), np.sin(gamma) * np.sin(c), -np.cos(gamma)
        w, l, h = self.width, self.length, self.height
        if w >= 0 and l >= 0 and h >= 0:
            return l * w * np.abs(dz) + w * h * np.abs(dx) + l * h * np.abs(dy)
        if w < 0 and l < 0 and h >= 0:
            return (math.pi * l * w / 4 * np.abs(dz)
                    + h * np.sqrt(l**2 * np.sin(c) ** 2 + w**2 * np.cos(c) ** 2) * np.abs(np.sin(gamma)))
        if w < 0 and l < 0 and h < 0:
            a, b, cz = abs(l) / 2, abs(w) / 2, abs(h) / 2
            return math.pi * np.sqrt((b * cz * dx) ** 2 + (a * cz * dy) ** 2 + (a * b * dz) ** 2)
        raise BadInputError(
            f"luminous opening width={w}, length={l}, height={h} m: this sign combination "
            "(LM-63-19 luminous shapes) is not supported by the luminance model")

    def luminance(self, c, gamma):
        """Mean luminance [cd·m⁻²] of the luminous opening seen from (C, γ): I / A_projected.

        Parameters
        ----------
        c, gamma : array_like
            Direction [rad], broadcast together.

        Returns
        -------
        ndarray
            Luminance [cd·m⁻²]. Where the projected area is 0 (a point source, or a flat
            opening seen edge-on): +inf where I > 0 and NaN where I = 0 (undefined); no
            warning is emitted. See :meth:`projected_area` for the opening model.

        References
        ----------
        CIE 121-1996 (luminance of a luminaire as intensity over projected luminous area);
        ANSI/IES LM-63-19 (luminous opening).

        Examples
        --------
        >>> p = Photometry([0.0, 360.0], [0.0, 90.0], [[100.0, 0.0], [100.0, 0.0]],
        ...                width=0.5, length=0.2)
        >>> float(p.luminance(0.0, 0.0))   # 100 cd over 0.1 m²
        1000.0
        """
        intensity = self.intensity(c, gamma)
        area = self.projected_area(c, gamma)
        with np.errstate(divide="ignore", invalid="ignore"):
            return intensity / area

    def zonal_flux(self, gamma_min, gamma_max):
        """Luminous flux [lm] emitted between two vertical angles [rad] (all C).

        Integrates the bilinear distribution exactly: trapezoid weights over the periodic C
        grid (exact for I linear in C) and, in γ, the closed form of ∫ I(γ) sin γ dγ for I
        linear between the sampled angles (nodes inserted at the zone's limits).

        Parameters
        ----------
        gamma_min, gamma_max : float
            Zone limits [rad], 0 ≤ gamma_min ≤ gamma_max ≤ π.

        Returns
        -------
        float
            Flux [lm].

        References
        ----------
        CIE 121-1996 (luminous flux from an intensity distribution).
        """
        lo, hi = math.degrees(float(gamma_min)), math.degrees(float(gamma_max))
        if not (0.0 <= lo <= hi <= 180.0 + ANGLE_EPS):
            raise BadInputError(
                f"zone limits must satisfy 0 <= gamma_min <= gamma_max <= pi, got {gamma_min}, {gamma_max}")
        return _flux(self.c_angles, self.gamma_angles, self.candela, lo, hi)


    # ---------------------------------------------------------------------------------------
    # Other sources of a distribution
    @classmethod
    def isotropic(cls, intensity):
        """A constant intensity [cd] in every direction (flux 4π·I), a point source.

        Examples
        --------
        >>> round(Photometry.isotropic(10.0).luminous_flux, 6) == round(40 * math.pi, 6)
        True
        """
        value = float(intensity)
        if not (math.isfinite(value) and value > 0):
            raise BadInputError(f"intensity must be a finite positive number, got {intensity!r}")
        return cls([0.0, 360.0], [0.0, 180.0], np.full((2, 2), value), format="isotropic")

    @classmethod
    def from_function(cls, function, *, c_step_deg=5.0, gamma_step_deg=1.0, source=""):
        """Tabulate ``function(c, gamma) -> intensity [cd]`` (angles in radians, numpy-vectorised).

        The grid steps [deg] are keyword options; the bilinear interpolant of the tabulated
        values is what is then used (evaluation, flux and sampling alike). The 360° plane
        repeats the 0° one.
        """
        c = np.linspace(0.0, 360.0, round(360.0 / c_step_deg) + 1)
        g = np.linspace(0.0, 180.0, round(180.0 / gamma_step_deg) + 1)
        cc, gg = np.meshgrid(np.radians(c), np.radians(g), indexing="ij")
        try:
            values = np.broadcast_to(np.asarray(function(cc, gg), dtype=float), cc.shape).copy()
        except Exception as exc:  # noqa: BLE001 - any failure of a user callable becomes one line
            raise BadInputError(f"intensity function failed on a (C, γ) grid: {exc}") from None
        values[-1] = values[0]
        return cls(c, g, values, source=source, format="function")

    # ---------------------------------------------------------------------------------------
    # In the world: evaluation and sampling in a luminaire's frame
    def evaluate(self, directions, frame):
        """Intensity [cd] towards world ``directions`` (..., 3) of a luminaire with ``frame``
        (its axes as rows, :func:`luminaire_frame`; one (3, 3) or one per direction)."""
        return self.intensity(*local_angles(directions, frame))

    @cached_property
    def _sampling(self):
        """Cell probabilities, their cumulative sum and the cells' solid angles [sr].

        The density is piecewise constant: a cell's probability is its largest corner
        intensity × its solid angle, so p > 0 wherever the bilinear interpolant is > 0.
        """
        c, g = np.radians(self.c_angles), np.radians(self.gamma_angles)
        i = self.candela
        peak = np.maximum.reduce([i[:-1, :-1], i[1:, :-1], i[:-1, 1:], i[1:, 1:]])
        omega = (np.diff(c)[:, None] * (np.cos(g[:-1]) - np.cos(g[1:]))[None, :]).ravel()
        mass = peak.ravel() * omega
        if not mass.sum() > 0:
            raise BadInputError(f"intensity distribution {self.source or self.format!r} emits no flux")
        prob = mass / mass.sum()
        cdf = np.cumsum(prob)
        cdf[-1] = 1.0
        return prob, cdf, omega, c, np.cos(g)

    def sample_local(self, rng, n):
        """``n`` emission directions in the luminaire's own frame and their weights.

        Directions are unit vectors (sin γ cos C, sin γ sin C, cos γ) with γ measured from
        the frame's third axis (the nadir); the weight I(ω)/(Φ·p(ω)) [–] has mean 1 under the
        sampling density and is exactly 1 where the intensity is constant over a cell.
        """
        prob, cdf, omega, c_grid, cos_grid = self._sampling
        cell = np.minimum(np.searchsorted(cdf, rng.random(n), side="right"), cdf.size - 1)
        ci, gi = np.divmod(cell, self.gamma_angles.size - 1)
        u = rng.random((2, n))
        c = c_grid[ci] + u[0] * (c_grid[ci + 1] - c_grid[ci])
        cos_g = cos_grid[gi] + u[1] * (cos_grid[gi + 1] - cos_grid[gi])
        sin_g = np.sqrt(np.maximum(0.0, 1.0 - cos_g * cos_g))
        local = np.stack([sin_g * np.cos(c), sin_g * np.sin(c), cos_g], axis=-1)
        pdf = prob[cell] / omega[cell]
        weight = self.intensity(c, np.arccos(np.clip(cos_g, -1.0, 1.0))) / (self.luminous_flux * pdf)
        return local, weight

    def sample(self, rng, n, frame):
        """``n`` world emission directions and their weights (see :meth:`sample_local`).

        ``frame`` is one luminaire frame (3, 3) or one per direction (n, 3, 3).
        """
        local, weight = self.sample_local(rng, n)
        frame = np.asarray(frame, float)
        if frame.ndim == 3:
            return np.einsum("nk,nkj->nj", local, frame), weight
        return local @ frame, weight


def luminaire_frame(nadir, length_axis):
    """Orthonormal axes (e_C0, e_C90, e_nadir) of a luminaire in the world, as rows (3, 3).

    ``nadir`` is the γ = 0 direction, ``length_axis`` the C = 0 half-plane (made
    perpendicular to the nadir); e_C90 = zenith × e_C0 (C counter-clockwise seen from above).
    """
    n = check_array(nadir, "nadir", shape=(3,), finite=True, dtype=float)
    a = check_array(length_axis, "length_axis", shape=(3,), finite=True, dtype=float)
    n, a = orthonormal_pair(n, a, zero_message="luminaire nadir axis must not be the zero vector",
                            parallel_message="luminaire length axis must not be parallel to its "
                                             "nadir axis")
    return np.stack([a, np.cross(-n, a), n])


def local_angles(directions, frame):
    """C, γ [rad] of world ``directions`` (..., 3) in a luminaire ``frame`` (3, 3) or one frame
    per direction (..., 3, 3)."""
    d = np.asarray(directions, float)
    frame = np.asarray(frame, float)
    local = d @ frame.T if frame.ndim == 2 else np.einsum("...j,...kj->...k", d, frame)
    gamma = np.arccos(np.clip(local[..., 2], -1.0, 1.0))
    return np.mod(np.arctan2(local[..., 1], local[..., 0]), 2 * math.pi), gamma


def _locate(grid, x):
    """Index i and fraction t with x = grid[i] + t·(grid[i+1] − grid[i]), snapped to nodes."""
    i = np.clip(np.searchsorted(grid, x, side="right") - 1, 0, grid.size - 2)
    t = np.clip((x - grid[i]) / (grid[i + 1] - grid[i]), 0.0, 1.0)
    t = np.where(np.abs(x - grid[i]) < ANGLE_EPS, 0.0, t)
    t = np.where(np.abs(x - grid[i + 1]) < ANGLE_EPS, 1.0, t)
    return i, t



# --------------------------------------------------------------------------------------------
# Compiled look-ups of many distributions
# --------------------------------------------------------------------------------------------


def pack_photometries(photometries):
    """The intensity tables of several distributions in flat arrays, for :func:`packed_intensity`.

    Distributions that are the same object (luminaires sharing a file) share one table.

    Returns
    -------
    (index, tables)
        ``index`` (n,) int64: the table of each distribution; ``tables``: the tuple
        ``(c_start, g_start, v_start, c_deg, g_deg, candela, g_step, symmetric)`` — each
        table's first C angle, γ angle and intensity in the flat arrays of C angles [deg], γ
        angles [deg] and intensities [cd] (row-major over C, γ), with one end entry each; per
        table the γ step [deg] where the γ grid is uniform (else 0: searched), and whether
        every C-plane is the same (rotational symmetry: no C look-up).
    """
    seen, distinct = {}, []
    index = np.empty(len(photometries), dtype=np.int64)
    for k, p in enumerate(photometries):
        if id(p) not in seen:
            seen[id(p)] = len(distinct)
            distinct.append(p)
        index[k] = seen[id(p)]

    def starts(sizes):
        return np.concatenate([[0], np.cumsum(sizes, dtype=np.int64)]).astype(np.int64)

    flat = [np.concatenate([getattr(p, a).ravel() for p in distinct]) if distinct else np.zeros(0)
            for a in ("c_angles", "gamma_angles", "candela")]
    tables = (starts([p.c_angles.size for p in distinct]), starts([p.gamma_angles.size for p in distinct]),
              starts([p.candela.size for p in distinct]),
              *(np.ascontiguousarray(a, dtype=np.float64) for a in flat),
              np.array([_uniform_step(p.gamma_angles) for p in distinct], dtype=np.float64),
              np.array([bool(np.all(p.candela == p.candela[:1])) for p in distinct], dtype=np.bool_))
    return index, tables


def _uniform_step(grid):
    """The step of an evenly spaced grid (to 1e-9 of it), else 0."""
    step = np.diff(grid)
    return float(step.mean()) if np.allclose(step, step[0], rtol=1e-9, atol=0) else 0.0


@njit(cache=True, error_model="numpy", nogil=True, inline="always")
def _locate_one(grid, lo, hi, x, step):
    """As :func:`_locate` for one value in ``grid[lo:hi]``: (i − lo, t). An evenly spaced
    grid (``step`` > 0) is indexed directly: off by one cell only where x lies within
    rounding of a node, where both cells give the node's value."""
    if step > 0.0:
        i = min(max(math.floor((x - grid[lo]) / step) + lo, lo), hi - 2)
    else:
        a, b = lo, hi  # first index in [lo, hi) with grid > x (searchsorted "right")
        while a < b:
            mid = (a + b) // 2
            if grid[mid] <= x:
                a = mid + 1
            else:
                b = mid
        i = min(max(a - 1, lo), hi - 2)
    t = (x - grid[i]) / (grid[i + 1] - grid[i])
    t = min(max(t, 0.0), 1.0)
    if abs(x - grid[i]) < ANGLE_EPS:
        t = 0.0
    if abs(x - grid[i + 1]) < ANGLE_EPS:
        t = 1.0
    return i - lo, t


@njit(cache=True, error_model="numpy", nogil=True, inline="always")
def packed_intensity(tables, table, dx, dy, dz, frame):
    """Intensity [cd] of table ``table`` of :func:`pack_photometries` towards the world
    direction (dx, dy, dz) (a unit vector) of a luminaire with ``frame`` (3, 3), as
    :meth:`Photometry.evaluate` computes it: bilinear in (C, γ) [deg], snapped to the grid
    within :data:`ANGLE_EPS`, 0 outside the sampled γ range."""
    c_start, g_start, v_start, c_deg, g_deg, candela, g_step, symmetric = tables
    l2 = dx * frame[2, 0] + dy * frame[2, 1] + dz * frame[2, 2]
    g = math.degrees(math.acos(min(max(l2, -1.0), 1.0)))
    g0, g1 = g_start[table], g_start[table + 1]
    if g < g_deg[g0] - ANGLE_EPS or g > g_deg[g1 - 1] + ANGLE_EPS:
        return 0.0
    j, u = _locate_one(g_deg, g0, g1, g, g_step[table])
    ng = g1 - g0
    if symmetric[table]:
        base = v_start[table] + j
        return (1 - u) * candela[base] + u * candela[base + 1]
    l0 = dx * frame[0, 0] + dy * frame[0, 1] + dz * frame[0, 2]
    l1 = dx * frame[1, 0] + dy * frame[1, 1] + dz * frame[1, 2]
    c = math.degrees(math.atan2(l1, l0) % (2 * math.pi)) % 360.0
    i, t = _locate_one(c_deg, c_start[table], c_start[table + 1], c, 0.0)
    base = v_start[table] + i * ng + j
    return ((1 - t) * ((1 - u) * candela[base] + u * candela[base + 1])
            + t * ((1 - u) * candela[base + ng] + u * candela[base + ng + 1]))
