"""Luminaire photometric files: IES LM-63 (1986–2019) and EULUMDAT, read without third parties.

Both readers return a :class:`Photometry`: a luminous intensity distribution [cd] on a
C–γ grid expanded to the full sphere of C-planes, with bilinear interpolation, the luminous
flux of that interpolated distribution, and the luminous opening for luminance.

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

References
----------
ANSI/IES LM-63-19, *Approved Method: IES Standard File Format for the Electronic Transfer
of Photometric Data and Related Information* (2019). ANSI/IESNA LM-63-02 (2002).
IESNA LM-63-95 (1995). Stockmar, A. W. (1990), "EULUMDAT – ein Leuchtendatenformat für den
europäischen Beleuchtungsplaner", Tagungsband Licht '90, 641–644 (the de-facto EULUMDAT
specification). CIE 121-1996, *The Photometry and Goniophotometry of Luminaires* (C–γ
system). DIAL/Lighting Analysts (2009), "Handling of absolute photometry data in EULUMDAT
files" (negative number of lamps).
"""

import functools
import inspect
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._validation import check_array
from ..errors import BadInputError, UnsupportedFileError

__all__ = [
    "PHOTOMETRY_FORMATS",
    "Photometry",
    "read_eulumdat",
    "read_ies",
    "read_photometry",
]

#: Format names a :class:`Photometry` can carry.
PHOTOMETRY_FORMATS = (
    "IES LM-63-1986",
    "IES LM-63-1991",
    "IES LM-63-1995",
    "IES LM-63-2002",
    "IES LM-63-2019",
    "EULUMDAT",
)

#: Tolerance [deg] within which an angle counts as equal to a sampled one (snapping, symmetry).
_ANGLE_EPS = 1e-9

_FOOT = 0.3048  # [m], international foot (LM-63 units type 1)


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
        Luminous flux [lm] of the bilinear distribution, integrated (not the file's lamp
        lumens); computed when not given.
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
    luminous_flux: float = None
    width: float = 0.0
    length: float = 0.0
    height: float = 0.0
    source: str = ""
    format: str = ""
    metadata: dict = field(default_factory=dict)

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
        if self.luminous_flux is None:
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
        inside = (g_deg >= self.gamma_angles[0] - _ANGLE_EPS) & (g_deg <= self.gamma_angles[-1] + _ANGLE_EPS)
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
        if not (0.0 <= lo <= hi <= 180.0 + _ANGLE_EPS):
            raise BadInputError(
                f"zone limits must satisfy 0 <= gamma_min <= gamma_max <= pi, got {gamma_min}, {gamma_max}")
        return _flux(self.c_angles, self.gamma_angles, self.candela, lo, hi)


def _locate(grid, x):
    """Index i and fraction t with x = grid[i] + t·(grid[i+1] − grid[i]), snapped to nodes."""
    i = np.clip(np.searchsorted(grid, x, side="right") - 1, 0, grid.size - 2)
    t = np.clip((x - grid[i]) / (grid[i + 1] - grid[i]), 0.0, 1.0)
    t = np.where(np.abs(x - grid[i]) < _ANGLE_EPS, 0.0, t)
    t = np.where(np.abs(x - grid[i + 1]) < _ANGLE_EPS, 1.0, t)
    return i, t


# --------------------------------------------------------------------------------------------
# Symmetry expansion (shared by both formats)
# --------------------------------------------------------------------------------------------

#: Mirror images of a stored C angle [deg] for each symmetry.
_MIRRORS = {
    "none": lambda c: [],
    "rotational": None,  # handled separately
    "plane C0-C180": lambda c: [360.0 - c],
    "plane C90-C270": lambda c: [(180.0 - c) % 360.0],
    "quadrant": lambda c: [180.0 - c, 180.0 + c, (360.0 - c) % 360.0],
}


def _expand(c_stored, rows, symmetry, name):
    """Full 0..360° C grid and (n_c, n_gamma) rows from the stored planes and a symmetry."""
    rows = np.asarray(rows, dtype=float)
    if symmetry == "rotational":
        return np.array([0.0, 360.0]), np.vstack([rows[0], rows[0]])
    planes = {}
    for angle, row in zip(c_stored, rows):
        planes.setdefault(round(float(angle), 9), row)
    for angle, row in zip(c_stored, rows):
        for mirrored in _MIRRORS[symmetry](float(angle) % 360.0):
            planes.setdefault(round(mirrored % 360.0, 9), row)
    if 0.0 not in planes:
        raise UnsupportedFileError(f"{name}: the C-planes ({symmetry} symmetry) do not include C = 0 after expansion")
    if 360.0 not in planes:
        planes[360.0] = planes[0.0]
    angles = np.array(sorted(planes))
    return angles, np.vstack([planes[a] for a in angles])


# --------------------------------------------------------------------------------------------
# Reading helpers
# --------------------------------------------------------------------------------------------


def _read_text(path):
    """Text of a photometric file; empty / unreadable → UnsupportedFileError."""
    path = Path(path)
    if not path.exists():
        raise BadInputError(f"photometric file {path} does not exist")
    if not path.is_file():
        raise BadInputError(f"photometric file {path} is not a file")
    data = path.read_bytes()
    if not data.strip():
        raise UnsupportedFileError(f"{path}: the file is empty")
    if b"\x00" in data:
        raise UnsupportedFileError(f"{path}: binary data (NUL bytes), not a text photometric file")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        text = data.decode("latin-1")  # older files: Windows-1252 / Latin-1 header text
    return text.removeprefix("\ufeff")  # a byte-order mark written by some editors


class _Tokens:
    """Numeric tokens of a whitespace/comma-delimited block, with messages naming the file."""

    def __init__(self, text, name, *, decimal_comma=False):
        # IES allows commas as delimiters (LM-63-02 §3); EULUMDAT has one value per line, where
        # a comma can only be a decimal comma (written by some European tools).
        if decimal_comma:
            self.items = [t.replace(",", ".") for t in text.split()]
        else:
            self.items = [t for t in re.split(r"[\s,]+", text) if t]
        self.pos = 0
        self.name = name

    def number(self, what):
        if self.pos >= len(self.items):
            raise UnsupportedFileError(f"{self.name}: truncated, {what} missing")
        token = self.items[self.pos]
        self.pos += 1
        try:
            value = float(token)
        except ValueError:
            raise UnsupportedFileError(f"{self.name}: non-numeric value {token[:20]!r} for {what}") from None
        if not math.isfinite(value):
            raise UnsupportedFileError(f"{self.name}: non-finite value {token!r} for {what}")
        return value

    def integer(self, what, minimum=None):
        value = self.number(what)
        if value != int(value):
            raise UnsupportedFileError(f"{self.name}: {what} must be an integer, got {value:g}")
        if minimum is not None and value < minimum:
            raise UnsupportedFileError(f"{self.name}: {what} must be at least {minimum}, got {value:g}")
        return int(value)

    def numbers(self, count, what):
        start = self.pos
        if start + count > len(self.items):
            raise UnsupportedFileError(
                f"{self.name}: truncated, {what} needs {count} values but only {len(self.items) - start} remain")
        return np.array([self.number(f"{what} #{k + 1}") for k in range(count)])

    def rest(self):
        return self.items[self.pos:]


def _check_angles(angles, what, name, low, high):
    if np.any(np.diff(angles) <= 0):
        raise UnsupportedFileError(f"{name}: {what} are not strictly ascending")
    if angles[0] < low - _ANGLE_EPS or angles[-1] > high + _ANGLE_EPS:
        raise UnsupportedFileError(f"{name}: {what} {angles[0]:g}..{angles[-1]:g} outside {low:g}..{high:g} degrees")


def _guarded(reader):
    """Run a reader; any stray parsing exception becomes a one-line UnsupportedFileError."""

    signature = inspect.signature(reader)

    @functools.wraps(reader)
    def wrapped(path, **kwargs):
        signature.bind(path, **kwargs)  # a wrong option is the caller's TypeError, not the file's
        try:
            return reader(path, **kwargs)
        except BadInputError:
            raise
        except (IndexError, ValueError, KeyError, TypeError, ZeroDivisionError, OverflowError) as exc:
            message = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise UnsupportedFileError(f"{path}: cannot parse the file ({message})") from None

    return wrapped


# --------------------------------------------------------------------------------------------
# IES LM-63
# --------------------------------------------------------------------------------------------

_IES_VERSIONS = {
    "IESNA:LM-63-1995": "IES LM-63-1995",
    "IESNA:LM-63-2002": "IES LM-63-2002",
    "IES:LM-63-2019": "IES LM-63-2019",
    "IESNA:LM-63-2019": "IES LM-63-2019",
    "IESNA91": "IES LM-63-1991",
    "IESNA95": "IES LM-63-1995",  # not a standard first line, but written by old tools (Radiance examp1)
}

_PHOTOMETRIC_TYPES = {1: "C", 2: "B", 3: "A"}


def _ies_tilt(tokens, name):
    """The TILT block: lamp-to-luminaire geometry, angles [deg] and multiplying factors."""
    geometry = tokens.integer("TILT lamp-to-luminaire geometry")
    count = tokens.integer("number of TILT angles", minimum=1)
    angles = tokens.numbers(count, "TILT angle")
    factors = tokens.numbers(count, "TILT multiplying factor")
    if count > 1 and np.any(np.diff(angles) <= 0):
        raise UnsupportedFileError(f"{name}: TILT angles are not strictly ascending")
    return {"geometry": geometry, "angles": angles.tolist(), "factors": factors.tolist()}


@_guarded
def read_ies(path, *, tilt=0.0):
    """Read an IES LM-63 photometric file (type C photometry) into a :class:`Photometry`.

    Accepts LM-63-1986 (no version line), -1991 (``IESNA91``), -1995 (``IESNA:LM-63-1995``,
    also the non-standard ``IESNA95``), -2002 (``IESNA:LM-63-2002``) and -2019
    (``IES:LM-63-2019``) files: keyword lines (``[MORE]`` continues the previous keyword),
    numeric blocks spread over any number of lines, space or comma delimiters, and every
    horizontal-angle symmetry of LM-63 (single 0° = rotational; 0–90° = quadrant; 0–180° =
    bilateral about the 0–180° plane; 90–270° = bilateral about the 90–270° plane; 0–360°
    = none).

    The intensities [cd] are the file's values × candela multiplier × ballast factor × (1995
    and earlier only) ballast-lamp photometric factor × TILT factor. The lamp count and
    lumens per lamp do not scale them: LM-63 candela values already refer to the rated lamps
    (lumens per lamp = −1 marks absolute photometry). The second value of line 11 is the
    ballast-lamp factor in 1995, "future use" in 2002 and the file generation type in 2019;
    only the first is applied.

    Parameters
    ----------
    path : path-like
        The ``.ies`` file.
    tilt : float, keyword-only
        Installed tilt of the luminaire [deg] at which a TILT=INCLUDE or TILT=<file> table
        is evaluated (linear interpolation, clamped to the table), in the sense of the
        table's lamp-to-luminaire geometry code (recorded, not interpreted). Ignored for
        TILT=NONE.

    Returns
    -------
    Photometry
        ``metadata`` holds the keywords (``"TEST"``, ``"MANUFAC"``, …), ``"header_lines"``
        (other header text), ``"tilt"`` and the numeric header (``"n_lamps"``,
        ``"lumens_per_lamp"``, ``"multiplier"``, ``"ballast_factor"``, …, ``"absolute"``).

    Raises
    ------
    UnsupportedFileError
        Malformed or truncated file, photometric type A or B, a horizontal-angle range
        that matches no LM-63 symmetry, a missing TILT file.
    BadInputError
        The file does not exist.

    References
    ----------
    ANSI/IES LM-63-19 (file structure, TILT, luminous opening, symmetry); ANSI/IESNA
    LM-63-02 (§3 definitions; file structure); IESNA LM-63-95; CIE 121-1996 (C–γ system).

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "isotropic.ies"
    ...     _ = path.write_text("IES:LM-63-2019\\n[TEST] doctest\\nTILT=NONE\\n"
    ...                         "1 -1 1 3 1 1 2 0 0 0\\n1 1 10\\n0 45 90\\n0\\n100 100 100\\n")
    ...     p = read_ies(path)
    >>> p.format, round(p.luminous_flux, 3)   # 2π·100 lm over the lower hemisphere
    ('IES LM-63-2019', 628.319)
    """
    tilt = float(check_array(tilt, "tilt", ndim=0, finite=True, dtype=float))
    path = Path(path)
    name = str(path)
    lines = _read_text(path).splitlines()
    first = lines[0].strip()
    version_line = first.upper().replace(" ", "")
    fmt = _IES_VERSIONS.get(version_line)
    header_start = 1
    if fmt is None:
        if version_line.startswith(("IESNA", "IES:")):
            raise UnsupportedFileError(f"{name}: unknown IES version line {first[:40]!r}")
        fmt, header_start = "IES LM-63-1986", 0
    tilt_index = next((k for k, line in enumerate(lines) if re.match(r"\s*TILT\s*=", line, re.IGNORECASE)), None)
    if tilt_index is None:
        raise UnsupportedFileError(f"{name}: no TILT= line (not an IES LM-63 file, or truncated)")

    metadata = {"version_line": first, "header_lines": []}
    keywords = {}
    last = None
    for line in lines[header_start:tilt_index]:
        text = line.strip()
        match = re.match(r"\[([^\]]+)\]\s*(.*)$", text)
        if match:
            key, value = match.group(1).strip().upper(), match.group(2).strip()
            if key == "MORE" and last is not None:
                keywords[last] = f"{keywords[last]}\n{value}"
                continue
            keywords[key] = f"{keywords[key]}\n{value}" if key in keywords else value
            last = key
        elif text:
            metadata["header_lines"].append(text)
    metadata.update(keywords)

    tilt_line = lines[tilt_index].strip()
    tilt_value = tilt_line.split("=", 1)[1].strip() if "=" in tilt_line else ""
    tokens = _Tokens("\n".join(lines[tilt_index + 1:]), name)
    if tilt_value.upper() == "NONE":
        tilt_table = None
    elif tilt_value.upper() == "INCLUDE":
        tilt_table = _ies_tilt(tokens, name)
    elif tilt_value:
        tilt_path = path.parent / tilt_value
        if not tilt_path.is_file():
            raise UnsupportedFileError(f"{name}: TILT file {tilt_value!r} not found beside the IES file")
        tilt_table = _ies_tilt(_Tokens(_read_text(tilt_path), str(tilt_path)), str(tilt_path))
    else:
        raise UnsupportedFileError(f"{name}: malformed TILT line {tilt_line[:40]!r}")
    tilt_factor = 1.0
    if tilt_table is not None:
        tilt_factor = float(np.interp(float(tilt), tilt_table["angles"], tilt_table["factors"]))
        tilt_table.update(source=tilt_value, applied_tilt=float(tilt), applied_factor=tilt_factor)
    metadata["tilt"] = tilt_table

    n_lamps = tokens.integer("number of lamps")
    lumens = tokens.number("lumens per lamp")
    multiplier = tokens.number("candela multiplier")
    n_vertical = tokens.integer("number of vertical angles", minimum=1)
    n_horizontal = tokens.integer("number of horizontal angles", minimum=1)
    photometric_type = tokens.integer("photometric type")
    units_type = tokens.integer("units type")
    width, length, height = (tokens.number(what) for what in ("width", "length", "height"))
    ballast_factor = tokens.number("ballast factor")
    second_factor = tokens.number("ballast-lamp photometric factor / future use / file generation type")
    input_watts = tokens.number("input watts")

    if photometric_type not in _PHOTOMETRIC_TYPES:
        raise UnsupportedFileError(f"{name}: photometric type {photometric_type} is not 1 (C), 2 (B) or 3 (A)")
    if photometric_type != 1:
        raise UnsupportedFileError(
            f"{name}: photometric type {_PHOTOMETRIC_TYPES[photometric_type]} is not supported (type C only)")
    if units_type not in (1, 2):
        raise UnsupportedFileError(f"{name}: units type {units_type} is not 1 (feet) or 2 (metres)")
    if n_vertical < 2:
        raise UnsupportedFileError(f"{name}: at least two vertical angles are needed, got {n_vertical}")

    gamma = tokens.numbers(n_vertical, "vertical angle")
    c_stored = tokens.numbers(n_horizontal, "horizontal angle")
    values = tokens.numbers(n_vertical * n_horizontal, "candela value").reshape(n_horizontal, n_vertical)
    leftover = tokens.rest()
    if leftover:
        raise UnsupportedFileError(
            f"{name}: {len(leftover)} values after the {n_horizontal}×{n_vertical} candela table "
            f"(wrong counts in the header?), first {leftover[0][:20]!r}")
    _check_angles(gamma, "vertical angles", name, 0.0, 180.0)
    if n_horizontal > 1:
        _check_angles(c_stored, "horizontal angles", name, 0.0, 360.0)
    if np.any(values < 0):
        raise UnsupportedFileError(f"{name}: negative candela values")

    first_c, last_c = c_stored[0], c_stored[-1]
    if n_horizontal == 1:
        symmetry = "rotational"
    elif first_c == 0 and last_c == 90:
        symmetry = "quadrant"
    elif first_c == 0 and last_c == 180:
        symmetry = "plane C0-C180"
    elif first_c == 90 and last_c == 270:
        symmetry = "plane C90-C270"
    elif first_c == 0 and last_c > 180 and 360 - last_c <= np.diff(c_stored).max() + _ANGLE_EPS:
        symmetry = "none"  # LM-63 ends at 360; a last angle one step short closes periodically
    else:
        raise UnsupportedFileError(
            f"{name}: horizontal angles {first_c:g}..{last_c:g} match no LM-63 symmetry "
            "(0, 0–90, 0–180, 90–270, 0–360)")

    scale = multiplier * ballast_factor * tilt_factor
    if fmt in ("IES LM-63-1986", "IES LM-63-1991", "IES LM-63-1995"):
        scale *= second_factor
    if not scale > 0:
        raise UnsupportedFileError(
            f"{name}: candela multiplier × ballast factor(s) × TILT factor = {scale:g} is not positive")
    c_angles, candela = _expand(c_stored, values * scale, symmetry, name)
    to_metre = _FOOT if units_type == 1 else 1.0

    metadata.update(
        n_lamps=n_lamps, lumens_per_lamp=lumens, absolute=(lumens == -1), multiplier=multiplier,
        photometric_type="C", units_type=units_type, ballast_factor=ballast_factor,
        input_watts=input_watts, symmetry=symmetry, stored_c_angles=c_stored.tolist(),
        rated_lamp_lumens=(n_lamps * lumens if lumens > 0 else None),
    )
    if fmt == "IES LM-63-2019":
        metadata["file_generation_type"] = second_factor
    elif fmt == "IES LM-63-2002":
        metadata["future_use"] = second_factor
    else:
        metadata["ballast_lamp_photometric_factor"] = second_factor

    return Photometry(c_angles=c_angles, gamma_angles=gamma, candela=candela,
                      width=width * to_metre, length=length * to_metre, height=height * to_metre,
                      source=name, format=fmt, metadata=metadata)


# --------------------------------------------------------------------------------------------
# EULUMDAT
# --------------------------------------------------------------------------------------------

_LDT_SYMMETRY = {0: "none", 1: "rotational", 2: "plane C0-C180", 3: "plane C90-C270", 4: "quadrant"}

#: Header lines 1–25 (Stockmar 1990): (key, kind); kind "s" text, "i" integer, "f" number.
_LDT_HEADER = (
    ("company", "s"), ("type_indicator", "i"), ("symmetry_indicator", "i"), ("n_c_planes", "i"),
    ("c_plane_distance", "f"), ("n_intensities", "i"), ("gamma_distance", "f"),
    ("report_number", "s"), ("luminaire_name", "s"), ("luminaire_number", "s"), ("file_name", "s"),
    ("date_user", "s"), ("luminaire_length", "f"), ("luminaire_width", "f"), ("luminaire_height", "f"),
    ("luminous_length", "f"), ("luminous_width", "f"), ("luminous_height_c0", "f"),
    ("luminous_height_c90", "f"), ("luminous_height_c180", "f"), ("luminous_height_c270", "f"),
    ("downward_flux_fraction", "f"), ("light_output_ratio", "f"), ("conversion_factor", "f"),
    ("measurement_tilt", "f"),
)
_LAMP_FIELDS = (("n_lamps", "i"), ("lamp_type", "s"), ("lamp_flux", "f"), ("colour", "s"),
                ("colour_rendering", "s"), ("wattage", "f"))


def _ldt_stored_planes(isym, mc, name):
    """0-based indices into the C-angle list of the planes stored for a symmetry (Mc1..Mc2)."""
    if isym == 0:
        return list(range(mc))
    if isym == 1:
        return [0]
    if isym == 2:
        if mc % 2:
            raise UnsupportedFileError(f"{name}: Isym 2 needs an even number of C-planes, got Mc = {mc}")
        return list(range(mc // 2 + 1))
    if mc % 4:
        raise UnsupportedFileError(f"{name}: Isym {isym} needs Mc divisible by 4, got Mc = {mc}")
    if isym == 3:
        # Stockmar: Mc1 = 3·Mc/4 + 1, Mc2 = Mc1 + Mc/2 (1-based) — C270 through C0 to C90.
        return [(3 * mc // 4 + k) % mc for k in range(mc // 2 + 1)]
    return list(range(mc // 4 + 1))


@_guarded
def read_eulumdat(path):
    """Read a EULUMDAT (``.ldt``) photometric file into a :class:`Photometry`.

    Header lines 1–25 and the lamp sets (line 26: number of sets n, then six lines per set:
    number of lamps, type, total lamp flux [lm], colour, colour rendering, wattage [W]) are
    read line by line; the direct ratios (10 values), the Mc C-angles, the Ng γ-angles and
    the intensities [cd/klm] are read as a token stream. The stored C-planes follow the
    symmetry indicator Isym (Stockmar 1990): 0 all Mc planes; 1 one plane (rotational);
    2 C0…C180; 3 C270…C360/C0…C90 (Mc1 = 3Mc/4+1, Mc2 = Mc1+Mc/2); 4 C0…C90.

    Absolute intensity [cd] = value [cd/klm] × Φ_lamps/1000 × conversion factor (line 24),
    with Φ_lamps the *total* lamp flux of the first lamp set (line 26c, already the total of
    all its lamps). A negative number of lamps marks absolute photometry (DIAL/Lighting
    Analysts 2009): line 26c is then the luminaire flux, LORL is 100 %, and the conversion
    is the same; ``metadata["absolute"]`` records it.

    Parameters
    ----------
    path : path-like
        The ``.ldt`` file.

    Returns
    -------
    Photometry
        Opening [m]: length = luminous length (line 16), width = luminous width (line 17),
        height = mean of the four luminous heights (lines 18–21); a width of 0 (circular)
        becomes ``width = length = −diameter`` (the IES convention). ``metadata`` holds the
        header fields by name, ``"lamp_sets"``, ``"direct_ratios"`` and ``"absolute"``.

    Raises
    ------
    UnsupportedFileError
        Malformed, truncated or inconsistent file (Isym outside 0–4, counts, non-numbers).

    References
    ----------
    Stockmar, A. W. (1990), EULUMDAT (the de-facto specification, as tabulated by
    Lighting Analysts' "EULUMDAT file format"); DIAL/Lighting Analysts (2009), absolute
    photometry in EULUMDAT; CIE 121-1996 (C–γ system).
    """
    path = Path(path)
    name = str(path)
    lines = [line.rstrip("\r") for line in _read_text(path).split("\n")]
    metadata = {}
    cursor = 0

    def take(key, kind):
        nonlocal cursor
        if cursor >= len(lines):
            raise UnsupportedFileError(f"{name}: truncated, header line {cursor + 1} ({key}) missing")
        text = lines[cursor].strip()
        cursor += 1
        if kind == "s":
            return text
        try:
            value = float(text.replace(",", ".")) if text else math.nan
        except ValueError:
            raise UnsupportedFileError(
                f"{name}: line {cursor} ({key}) is not a number: {text[:20]!r}") from None
        if kind == "i":
            if not math.isfinite(value) or value != int(value):
                raise UnsupportedFileError(f"{name}: line {cursor} ({key}) must be an integer, got {text[:20]!r}")
            return int(value)
        if not math.isfinite(value):
            raise UnsupportedFileError(f"{name}: line {cursor} ({key}) is empty or not finite")
        return value

    for key, kind in _LDT_HEADER:
        metadata[key] = take(key, kind)
    isym, mc, ng = metadata["symmetry_indicator"], metadata["n_c_planes"], metadata["n_intensities"]
    if isym not in _LDT_SYMMETRY:
        raise UnsupportedFileError(f"{name}: symmetry indicator Isym = {isym} is not 0–4")
    if mc < 1 or ng < 2:
        raise UnsupportedFileError(f"{name}: Mc = {mc} C-planes and Ng = {ng} intensities per plane are too few")
    n_sets = take("number of lamp sets", "i")
    if n_sets < 1:
        raise UnsupportedFileError(f"{name}: number of lamp sets must be at least 1, got {n_sets}")
    sets = []
    for index in range(n_sets):
        sets.append({key: take(f"lamp set {index + 1} {key}", kind) for key, kind in _LAMP_FIELDS})
    metadata["lamp_sets"] = sets

    tokens = _Tokens("\n".join(lines[cursor:]), name, decimal_comma=True)
    metadata["direct_ratios"] = tokens.numbers(10, "direct ratio").tolist()
    c_list = tokens.numbers(mc, "C angle")
    gamma = tokens.numbers(ng, "gamma angle")
    stored = _ldt_stored_planes(isym, mc, name)
    values = tokens.numbers(len(stored) * ng, "intensity").reshape(len(stored), ng)
    leftover = tokens.rest()
    if leftover:
        raise UnsupportedFileError(
            f"{name}: {len(leftover)} values after the {len(stored)}×{ng} intensity table "
            f"(wrong Mc, Ng or Isym?), first {leftover[0][:20]!r}")
    _check_angles(c_list, "C angles", name, 0.0, 360.0)
    _check_angles(gamma, "gamma angles", name, 0.0, 180.0)
    if np.any(values < 0):
        raise UnsupportedFileError(f"{name}: negative intensities")

    lamp = sets[0]
    if not lamp["lamp_flux"] > 0:
        raise UnsupportedFileError(f"{name}: lamp flux {lamp['lamp_flux']:g} lm of lamp set 1 must be positive")
    scale = lamp["lamp_flux"] / 1000.0 * metadata["conversion_factor"]
    if not scale > 0:
        raise UnsupportedFileError(f"{name}: conversion factor {metadata['conversion_factor']:g} must be positive")
    symmetry = _LDT_SYMMETRY[isym]
    c_angles, candela = _expand(c_list[stored], values * scale, symmetry, name)

    metadata.update(symmetry=symmetry, absolute=lamp["n_lamps"] < 0, lamp_flux=lamp["lamp_flux"],
                    stored_c_angles=c_list[stored].tolist(), c_angles_listed=c_list.tolist())
    length = metadata["luminous_length"] / 1000.0
    width = metadata["luminous_width"] / 1000.0
    heights = [metadata[f"luminous_height_c{c}"] for c in (0, 90, 180, 270)]
    height = float(np.mean(heights)) / 1000.0
    if width == 0 and length > 0:  # circular luminous area: diameter in line 16
        width = length = -length
    return Photometry(c_angles=c_angles, gamma_angles=gamma, candela=candela,
                      width=width, length=length, height=height,
                      source=name, format="EULUMDAT", metadata=metadata)


# --------------------------------------------------------------------------------------------

_READERS = {".ies": read_ies, ".ldt": read_eulumdat}


def read_photometry(path, **kwargs):
    """Read a photometric file, choosing the reader by suffix (``.ies`` or ``.ldt``, any case).

    Parameters
    ----------
    path : path-like
        An IES LM-63 or EULUMDAT file.
    **kwargs
        Keyword options of the reader (``tilt`` for :func:`read_ies`).

    Returns
    -------
    Photometry

    Raises
    ------
    BadInputError
        Unknown suffix (the message lists the known ones), or a missing file.
    UnsupportedFileError
        Malformed file (see the readers).

    References
    ----------
    ANSI/IES LM-63-19; Stockmar (1990).
    """
    suffix = Path(path).suffix.lower()
    if suffix not in _READERS:
        raise BadInputError(f"unknown photometric file suffix {Path(path).suffix!r} of {path}; valid: .ies, .ldt")
    return _READERS[suffix](path, **kwargs)
