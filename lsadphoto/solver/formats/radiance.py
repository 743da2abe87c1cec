"""Radiance scene descriptions (``.rad``) read into a solver :class:`~lsadphoto.solver.Scene`.

What is read, as Radiance reads it:

- **Surfaces** ``polygon``, ``sphere``, ``bubble``, ``cone``, ``cup``, ``cylinder``, ``tube``,
  ``ring``, tessellated into triangles (:mod:`lsadphoto.solver.formats.shapes`, accuracy knob
  ``tessellation_error``; areas exact). Polygons must be planar.
- **Modifiers** resolved as Radiance resolves them: ``void`` is none, a name means its most
  recent definition *before* the line that uses it, ``alias`` copies a definition (with a new
  modifier unless that is ``void``), ``xform -m`` replaces the surfaces' modifiers.
- **Materials** are read into :class:`RadianceMaterial` records (``plastic``, ``metal``,
  ``trans``, ``glass``, ``dielectric``, ``mirror``, ``light``, ``glow``, ``illum``,
  ``spotlight`` and the rest by name). Surfaces take ``plastic``, ``metal`` and ``trans`` (any
  specularity, roughness and transmission), ``glass`` and ``mirror``, modelled as Radiance
  defines them (:mod:`lsadphoto.solver.materials`; colour reduced to luminance,
  0.265074 R + 0.670115 G + 0.064811 B, :func:`radiance_luminance`; those of specularity and
  transmissivity 0 are Lambertian, exactly as before), ``light`` (a Lambertian emitter of luminance
  179 lm/W × the same weights, front side only, not reflecting), ``glow`` whose radius of
  influence is 0 (it then lights everything, like a ``light``), ``illum`` as its alternate
  material (or left out without one: see :meth:`_Reader.place_illum`), ``spotlight`` as a
  luminaire emitting within its cone (:meth:`_Reader.spotlight`); a ``glow`` with a
  positive radius of influence is the same emitter (the radius only chooses how Radiance
  samples it), one with a negative radius is refused. Anything else is refused
  when a surface uses it, in one line naming file, line, modifier and parameter.
- **Distant sources**: a ``source`` (direction, angle) with a ``light`` or ``glow`` material
  becomes a :class:`~lsadphoto.solver.sky.DistantSource` — the sun of ``gensky``/``gendaylit``,
  and sky and ground glows modified by their ``brightfunc skyfunc`` (``skybr`` of
  ``skybright.cal``: CIE clear, intermediate, overcast, uniform; ``skybright`` of
  ``perezlum.cal``: Perez), evaluated natively from the arguments written
  (:func:`~lsadphoto.solver.sky.sky_luminance_shape`). Other patterns on a source, other
  functions or a ``.cal`` file that is not found are refused in one line.
- **Luminaires from ies2rad**: a ``light`` modified by a ``brightdata`` of Radiance's
  ``source.cal`` (``flatcorr``, ``corr``, ``boxcorr``, ``cylcorr`` over ``src_theta``,
  ``src_phi``, ``src_phi2``, ``src_phi4``) becomes one luminaire with a luminous intensity
  distribution (:class:`~lsadphoto.solver.PointLuminaire` with an
  :class:`~lsadphoto.solver.Photometry`): its intensity is Radiance's emitted radiance
  times the emitting surfaces' projected area, I(ω) = 179·Y(rgb)·b(ω)·A⊥(ω), where b is the
  ``.dat`` table interpolated as Radiance's ``datavalue`` does (linear, one division of linear
  extrapolation, then a harmonic taper to zero), so for ies2rad's geometry I(ω) is the IES
  file's candela table times ies2rad's multiplier. It emits from a rectangle of the
  luminaire's projected area toward its nadir (``extent``) and, like every solver luminaire
  with a distribution, is not geometry (it casts no shadow).
- **Commands**: a ``!`` line is split with :mod:`shlex` into argument lists and run without
  a shell, in the top scene file's folder, with a time limit (``command_timeout``); stages
  joined by ``|`` are piped. Programs are Radiance's as the ``pyradiance`` package ships them
  (``genbox``, ``genrev``, ``genworm``, ``gensurf``, ``genprism``, ``ies2rad``, ``obj2rad``, …);
  ``xform`` is applied here (its files are read by this reader, so their lines are named in
  errors; transforms ``-t -rx -ry -rz -s -mx -my -mz -a -i``, ``-n``, ``-m``).

A ``mesh`` is read from the OBJ it was compiled from (``name.obj`` beside ``name.rtm``,
through trimesh; one modifier for all faces), an ``instance`` from the Radiance files its
octree's header names (its ``oconv`` command). Everything else is refused with one line
(:class:`~lsadphoto.errors.BadInputError`) naming the file, the line, the primitive or
modifier: compiled meshes
without their OBJ (or with per-face ``usemtl``: use ``!obj2rad``), patterns and textures on materials, other functions or ``.cal``
files. Colour is reduced to luminance with Radiance's own RGB weights (those of its
primaries, ``color.h``), the weights the photo pipeline uses for Radiance pictures
(:mod:`lsadphoto.io.hdr`), so a model's luminance is what Radiance's ``pvalue`` would give
for the same scene; for coloured interreflections this grey reduction is exact at the first
reflection and an approximation after that.

References
----------
Ward Larson, G., Shakespeare, R. (1998). *Rendering with Radiance*, Morgan Kaufmann, ch. 1
(scene description syntax, materials, patterns). Radiance reference manual (``ray.html``);
``src/common/color.h`` (``WHTEFFICACY`` = 179 lm/W, CIE luminance weights of Radiance RGB);
``src/rt/data.c`` (``datavalue``: interpolation and extrapolation of ``.dat`` tables);
``lib/source.cal`` (``flatcorr``, ``boxcorr``, ``cylcorr``, ``src_theta``, ``src_phi``);
``src/cv/ies2rad.c`` (how IES files become ``brightdata`` luminaires).
"""

import importlib.util
import math
import os
import shlex
import subprocess
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...constants import RADIANCE_RGB_LUMINANCE_WEIGHTS, RADIANCE_WHITE_EFFICACY
from ...errors import BadInputError, SolverWarning
from ...io.hdr import parse_view
from ..materials import Material
from ..photometry import Photometry, luminaire_frame
from ..scene import AreaLuminaire, PointLuminaire, Scene, as_views, polygon_triangles
from ..sky import DistantSource, check_sky_arguments
from .shapes import DEFAULT_TESSELLATION_ERROR, annulus_triangles, cone_triangles, sphere_triangles
from .xform import TRANSFORM_WORDS, Transform, parse_transform

__all__ = ["DEFAULT_COMMAND_TIMEOUT", "RTRACE_UNBIASED", "RadianceMaterial", "radiance_luminance",
           "radiance_programs", "read_radiance_scene", "read_rif_scene"]

#: Default time limit of one ``!`` command line (all its piped stages together) [s].
DEFAULT_COMMAND_TIMEOUT = 60.0

_SURFACES = {"polygon", "sphere", "bubble", "cone", "cup", "cylinder", "tube", "ring"}
_MATERIALS = {"plastic", "metal", "trans", "plastic2", "metal2", "trans2", "glass", "dielectric",
              "interface", "mirror", "light", "glow", "illum", "spotlight", "mist", "prism1", "prism2",
              "antimatter", "plasfunc", "metfunc", "transfunc", "plasdata", "metdata", "transdata",
              "BRTDfunc", "BSDF", "aBSDF", "ashik2", "WGMDfunc", "mixfunc", "mixdata", "mixpict",
              "mixtext", "clip"}
_PATTERNS = {"brightfunc", "brightdata", "brighttext", "colorfunc", "colordata", "colorpict",
             "colortext", "texfunc", "texdata", "specfunc", "specdata", "specpict", "spectrum"}
#: Number of real arguments of the materials read here.
#: Radiance materials the solver's surfaces take (besides the emitters light and glow).
SURFACE_MATERIALS = ("plastic", "metal", "trans", "glass", "mirror")
_REALS = {"plastic": 5, "metal": 5, "trans": 7, "light": 3, "glow": 4, "spotlight": 7, "mirror": 3,
          "glass": (3, 4), "illum": 3}
#: Focal length [m] of a ``spotlight`` (its aim vector's length) up to which the solver emits
#: from the surface itself: Radiance's falloff (d/(d + f))² then stays above 0.99 beyond 0.2 m.
SPOT_FOCUS_NEGLIGIBLE = 1e-3
_SOURCE_COORDINATES = ("src_theta", "src_phi", "src_phi2", "src_phi4")
_SOURCE_CORRECTIONS = {"flatcorr": (0, 1), "corr": (0, 1), "boxcorr": (4, 4), "cylcorr": (3, 3)}
_MAX_DEPTH = 16


def radiance_luminance(r, g, b):
    """Luminance [cd·m⁻²] (or reflectance [–] without the efficacy) of Radiance RGB.

    Examples
    --------
    >>> round(radiance_luminance(1, 1, 1), 6)
    1.0
    """
    wr, wg, wb = RADIANCE_RGB_LUMINANCE_WEIGHTS
    return wr * r + wg * g + wb * b


def radiance_programs():
    """Folder of the Radiance programs that the ``pyradiance`` package ships, or ``None``."""
    spec = importlib.util.find_spec("pyradiance")
    if spec is None or spec.origin is None:
        return None
    folder = Path(spec.origin).parent / "bin"
    return folder if folder.is_dir() else None


#: ``rtrace`` options that make Radiance an unbiased (pure Monte Carlo) reference for the
#: solver, to be followed by ``-ab`` and ``-ad``: no irradiance cache (``-aa 0``), no adaptive
#: ambient super-samples (``-as 0``), practically no ray-weight cut-off (``-lw 1e-9``), no
#: source jitter (``-dj 0``). The super-samples matter: Radiance re-samples the ambient
#: divisions whose first samples differed most from their neighbours and averages them, a
#: choice made from the samples themselves, which is biased low where a few divisions see a
#: small bright patch. Measured with Radiance 6.0a (pyradiance 1.3.1) on
#: ``data_samples/radiance/daylit_room.rad``, 38 random room pixels, 8 runs: with the default
#: ``-as 512`` the pixel values are 4.9 ± 0.5 % below ρ/π times rtrace's own ``-I`` irradiance
#: at the same hit points (rms z 5.9); with these options 1.001 in median (rms z 1.2)
#: (benchmarks/radiance_super_samples.py, docs/accuracy.md). Every source is shadow-tested
#: at every hit (``-dt 0 -dc 1``): by default Radiance's ``direct()`` (rt/source.c) tests the
#: sources in order of their potential only while the rest carry more than ``-dt`` divided
#: by the *ray weight* of the ray's value, and adds the untested ones scaled by hit rates
#: gathered over the whole run — not this point's visibility. Ambient rays have small
#: weights (≈ ρ/``-ad``), so in a scene where columns or benches hide some of many
#: luminaires the indirect light comes out wrong per point, and changes with ``-ad``.
#: Measured on the station hall (42 ies2rad luminaires; docs/accuracy.md, session 10): the
#: one-bounce indirect irradiance at a floor point 27.3 lx with the defaults, 39.8 lx with
#: ``-dt 0 -dc 1``, 40.7 lx as π × the mean of rtrace's own ``-ab 0`` radiances over 4000
#: cosine-distributed directions (the luminaires' openings, black to ambient rays, left
#: out); over 253 pixels the indirect light per surface kind was −10 … +3.5 %
#: off ours with the defaults, within 1.5 % with these options. Keep ``-ad`` small: with
#: many divisions rtrace's stratified hemisphere is biased near walls (a ceiling point of the
#: canonical room 0.3 m from the lit wall: 105.3 ± 0.4 lx at ``-ad 1``, 105.4 at ``-ad 16``,
#: 103.9 at ``-ad 512``; docs/accuracy.md, session 15), so an exact reference takes
#: ``-ad 16`` and many traces (benchmarks/accuracy_vs_rtrace.py ``--repeats``).
RTRACE_UNBIASED = ("-aa", "0", "-as", "0", "-lw", "1e-9", "-dj", "0", "-dt", "0", "-dc", "1")


@dataclass(eq=False)  # identity: two definitions with equal words are still two modifiers
class RadianceMaterial:
    """A Radiance modifier (material or pattern) as read from a scene file.

    Attributes
    ----------
    kind : str
        Radiance type (``plastic``, ``light``, ``brightdata``, …).
    name : str
        Its identifier.
    modifier : RadianceMaterial or None
        The modifier it is modified by (``None`` for ``void``).
    strings, reals : tuple
        Its string and real arguments as written.
    where : str
        ``file:line`` of its definition.
    transform : Transform
        Transform in force where it was defined (for patterns: with the transform words of
        its string arguments), mapping its own coordinates to the world.
    """

    kind: str
    name: str
    modifier: "RadianceMaterial | None"
    strings: tuple
    reals: tuple
    where: str
    transform: Transform = field(default_factory=Transform)

    def describe(self):
        """``kind 'name' (file:line)`` for messages."""
        return f"{self.kind} {self.name!r} ({self.where})"

    def surface_material(self):
        """The solver :class:`~lsadphoto.solver.materials.Material` of a ``plastic``, ``metal``,
        ``trans``, ``glass`` or ``mirror``, and its reflectance ρ [–] (Lambertian ρ, or the
        diffuse reflectance at normal incidence); :class:`BadInputError` naming the parameter
        that is out of range."""
        where = f"{self.where}: {self.kind} {self.name!r}"
        if self.kind not in SURFACE_MATERIALS:
            raise BadInputError(f"{where} is not a surface material; the solver models "
                                f"{', '.join(SURFACE_MATERIALS)}, light, glow, illum and spotlight")
        self._check_reals()
        if self.kind == "mirror" and self.strings:
            raise BadInputError(f"{where}: a mirror with an alternate material ({self.strings[0]!r}) "
                                "is not supported")
        r, g, b = self.reals[:3]
        if min(r, g, b) < 0:
            raise BadInputError(f"{where}: negative colour ({r:g} {g:g} {b:g})")
        options = {}
        if self.kind in ("plastic", "metal", "trans"):
            options = {"specularity": self.reals[3], "roughness": self.reals[4]}
            if self.kind == "trans":
                options.update(transmissivity=self.reals[5], transmitted_specularity=self.reals[6])
        elif self.kind == "glass" and len(self.reals) == 4:
            options = {"refractive_index": self.reals[3]}
        material = Material.checked(self.kind, (r, g, b), where=where, **options)
        if material.is_lambertian:
            rho = radiance_luminance(r, g, b)
            if not rho < 1:
                raise BadInputError(f"{where}: reflectance {rho:g} (of {r:g} {g:g} {b:g}) not in [0, 1)")
            return material, rho
        return material, material.diffuse_reflectance

    def _check_reals(self):
        want = _REALS.get(self.kind)
        if want is not None and len(self.reals) not in (want if isinstance(want, tuple) else (want,)):
            raise BadInputError(f"{self.where}: {self.kind} {self.name!r} needs {want} real arguments, "
                                f"got {len(self.reals)}")

    def emitted_luminance(self):
        """Luminance [cd·m⁻²] a ``light``/``glow`` emits (179 lm/W × Y of its RGB radiance)."""
        self._check_reals()
        r, g, b = self.reals[:3]
        if min(r, g, b) < 0:
            raise BadInputError(f"{self.where}: {self.kind} {self.name!r}: negative radiance")
        return RADIANCE_WHITE_EFFICACY * radiance_luminance(r, g, b)


# --- words and lines -------------------------------------------------------------------------

def _strip_comment(line):
    """The line without a ``#`` comment (a ``#`` that starts a word, outside quotes)."""
    quote = None
    for k, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = None
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (k == 0 or line[k - 1].isspace()):
            return line[:k]
    return line


def _tokens(text, source):
    """``[(kind, value, line)]``: ``("word", w, n)`` or ``("command", text, n)``."""
    out = []
    lines = text.splitlines()
    k = 0
    while k < len(lines):
        number, line = k + 1, lines[k]
        k += 1
        if line.lstrip().startswith("!"):
            command = line.lstrip()[1:]
            while command.endswith("\\") and k < len(lines):
                command = command[:-1] + " " + lines[k]
                k += 1
            out.append(("command", command.strip(), number))
            continue
        line = _strip_comment(line)
        if not line.strip():
            continue
        try:  # quotes (ies2rad writes 'names') need shlex; plain lines split faster
            words = shlex.split(line, posix=True) if "'" in line or '"' in line else line.split()
        except ValueError as exc:
            raise BadInputError(f"{source}:{number}: cannot read this line ({exc})") from None
        out.extend(("word", w, number) for w in words)
    return out


# --- .dat tables of brightdata ------------------------------------------------------------------

class _DataTable:
    """A Radiance data file (``N``; ``begin end n`` or ``0 0 n p…`` per dimension; values)."""

    def __init__(self, path, where):
        try:
            text = path.read_text(encoding="utf-8", errors="replace")
            words = " ".join(line.split("#", 1)[0] for line in text.splitlines()).split()
            values = [float(w) for w in words]
        except (OSError, ValueError) as exc:
            raise BadInputError(f"{where}: cannot read data file {path} ({exc})") from None
        try:
            pos, ndim = 1, int(values[0])
            if ndim < 1 or ndim != values[0]:
                raise ValueError("bad number of dimensions")
            self.axes = []
            for _ in range(ndim):
                begin, end, n = values[pos:pos + 3]
                pos += 3
                if n != int(n) or n < 2:
                    raise ValueError("a dimension needs at least 2 points")
                n = int(n)
                if begin == end:
                    grid = np.asarray(values[pos:pos + n])
                    pos += n
                    if len(grid) != n or np.any(np.diff(grid) <= 0):
                        raise ValueError("irregular points must increase")
                else:
                    grid = np.linspace(begin, end, n)
                self.axes.append(grid)
            count = int(np.prod([len(a) for a in self.axes]))
            data = np.asarray(values[pos:])
            if len(data) != count:
                raise ValueError(f"{len(data)} values for {count} grid points")
        except (ValueError, IndexError) as exc:
            raise BadInputError(f"{where}: bad data file {path} ({exc})") from None
        self.values = data.reshape([len(a) for a in self.axes])

    def __call__(self, *coords):
        """Radiance's ``datavalue``: multilinear, extrapolated one division, then tapered."""
        return self._value(self.values, self.axes, [np.asarray(c, float) for c in coords])

    def _value(self, values, axes, coords):
        grid, x_coord = axes[0], coords[0]
        n = len(grid)
        i = np.clip(np.searchsorted(grid, x_coord, side="right") - 1, 0, n - 2)
        x = i + (x_coord - grid[i]) / (grid[i + 1] - grid[i])
        if len(axes) > 1:
            sub = [values[k] for k in range(n)]
            rest = [self._value(s, axes[1:], coords[1:]) for s in sub]
            stack = np.stack(np.broadcast_arrays(*rest))
            y0 = np.take_along_axis(stack, i[None], 0)[0]
            y1 = np.take_along_axis(stack, (i + 1)[None], 0)[0]
        else:
            y0, y1 = values[i], values[i + 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(x > i + 2, (2 * y1 - y0) / (x - (i - 1)),
                            np.where(x < i - 1, (2 * y0 - y1) / (i - x),
                                     y0 * ((i + 1) - x) + y1 * (x - i)))


def _source_coordinate(name, d):
    """A ``source.cal`` coordinate [deg] of ray directions ``d`` (towards the source)."""
    theta = np.degrees(np.arccos(np.clip(d[..., 2], -1.0, 1.0)))
    if name == "src_theta":
        return theta
    phi = np.mod(np.degrees(np.arctan2(-d[..., 1], -d[..., 0])), 360.0)
    fold = {"src_phi": None, "src_phi2": 180.0, "src_phi4": 90.0}[name]
    if fold is None:
        return phi
    return np.abs(fold - np.mod(phi - fold, 2 * fold))  # rayinit.cal tri(n, d)


# --- the reader -------------------------------------------------------------------------------

class _Reader:
    def __init__(self, base, tessellation_error, command_timeout):
        self.base = base
        self.eps = tessellation_error
        self.timeout = command_timeout
        self.defs = {}
        self.triangles, self.material, self.emitter = [], [], []
        self.count = 0  # triangles so far
        self.names, self.rho, self.index, self.models = [], [], {}, []
        self.area_luminaires, self.luminaire_parts, self.spot_parts = [], {}, {}
        self.distant_sources = []
        self.folder_of = {}  # definition -> folder of the file that defined it

    # the scene's materials (reflectance) by record
    def _material_index(self, record):
        key = record if record is not None else "black"
        if key not in self.index:
            if record is None:
                name, material, rho = "black", Material.lambertian(0.0), 0.0
            else:
                name = record.name
                material, rho = record.surface_material()
                while name in self.names:
                    name += "'"
            self.index[key] = len(self.names)
            self.names.append(name)
            self.rho.append(rho)
            self.models.append(material)
        return self.index[key]

    def read(self, text, source, transform, *, folder, override=None, prefix="", depth=0):
        if depth > _MAX_DEPTH:
            raise BadInputError(f"{source}: files and commands nest deeper than {_MAX_DEPTH} levels")
        tokens = _tokens(text, source)
        pos = 0

        def take(what, line):
            nonlocal pos
            if pos >= len(tokens) or tokens[pos][0] != "word":
                raise BadInputError(f"{source}:{line}: {what} missing (truncated primitive)")
            pos += 1
            return tokens[pos - 1][1]

        while pos < len(tokens):
            kind, value, line = tokens[pos]
            if kind == "command":
                pos += 1
                self.command(value, f"{source}:{line}", transform, override, prefix, depth)
                continue
            modifier = take("modifier", line)
            ptype = take("primitive type", line)
            ident = take("identifier", line)
            where = f"{source}:{line}"
            if ptype == "alias":
                old = take("aliased identifier", line)
                self.alias(modifier, ident, old, where)
                continue
            args = []
            for what in ("string", "integer", "real"):
                count = take(f"{what} argument count", line)
                try:
                    n = int(count)
                except ValueError:
                    n = -1
                if n < 0:
                    raise BadInputError(f"{where}: {ptype} {ident!r}: {what} argument count {count!r} "
                                        "is not a whole number ≥ 0")
                args.append([take(f"{what} argument", line) for _ in range(n)])
            try:
                reals = tuple(float(x) for x in args[2])
            except ValueError:
                word = next(x for x in args[2] if not _is_number(x))
                raise BadInputError(f"{where}: {ptype} {ident!r}: real argument {word!r} is not a number "
                                    "(too few arguments for the count given?)") from None
            if not all(math.isfinite(r) for r in reals):
                raise BadInputError(f"{where}: {ptype} {ident!r}: real arguments must be finite")
            if ptype == "mesh":
                self.mesh(override or modifier, prefix + ident, args[0], where, transform, folder)
            elif ptype == "instance":
                self.instance(override or modifier, prefix + ident, args[0], where, transform, folder,
                              depth)
            elif ptype == "source":
                self.distant(override or modifier, prefix + ident, reals, where, transform)
            elif ptype in _SURFACES:
                self.surface(override or modifier, ptype, prefix + ident, reals, where, transform)
            elif ptype in _MATERIALS or ptype in _PATTERNS:
                self.define(modifier, ptype, ident, tuple(args[0]), reals, where, transform)
                self.folder_of[self.defs[ident]] = folder
            else:
                raise BadInputError(f"{where}: unknown primitive type {ptype!r} ({modifier} {ptype} {ident})")

    def resolve(self, modifier, where, what):
        if modifier == "void":
            return None
        record = self.defs.get(modifier)
        if record is None:
            raise BadInputError(f"{where}: {what}: modifier {modifier!r} is not defined before this line")
        return record

    def alias(self, modifier, ident, old, where):
        record = self.resolve(old, where, f"alias {ident!r}")
        if record is None:
            raise BadInputError(f"{where}: alias {ident!r} of void")
        new = RadianceMaterial(record.kind, ident, record.modifier, record.strings, record.reals, where,
                               record.transform)
        if modifier != "void":
            new.modifier = self.resolve(modifier, where, f"alias {ident!r}")
        self.defs[ident] = new
        self.folder_of[new] = self.folder_of.get(record, self.base)

    def define(self, modifier, ptype, ident, strings, reals, where, transform):
        record = RadianceMaterial(ptype, ident, self.resolve(modifier, where, f"{ptype} {ident!r}"),
                                  strings, reals, where, transform)
        if ptype in _PATTERNS:
            words = list(strings)
            first = next((k for k, w in enumerate(words) if w in TRANSFORM_WORDS), len(words))
            record.strings = tuple(words[:first])
            if first < len(words):
                record.transform = transform @ parse_transform(words[first:], f"{where}: {ptype} {ident!r}")[0][1]
        self.defs[ident] = record

    # surfaces
    def surface(self, modifier, ptype, ident, reals, where, transform):
        what = f"{ptype} {ident!r}"
        tris = self.tessellate(ptype, what, reals, where, transform)
        self.place(modifier, ident, ptype, reals, tris, where, transform)

    def place(self, modifier, ident, ptype, reals, tris, where, transform):
        """Add a surface's triangles with the material (or emission) its modifier gives."""
        what = f"{ptype} {ident!r}"
        material, patterns = self.material_of(self.resolve(modifier, where, what), where, what)
        if material.kind == "illum":
            self.place_illum(material, ident, ptype, reals, tris, where, transform)
            return
        if material.kind == "spotlight":
            if patterns:
                raise BadInputError(f"{where}: {what}: {material.describe()} is modified by "
                                    f"{patterns[0].describe()}: patterns on a spotlight are not supported")
            if len(material.reals) != 7:
                raise BadInputError(f"{where}: {what}: {material.describe()} needs 7 real arguments "
                                    f"(r g b angle xdir ydir zdir), got {len(material.reals)}")
            self.spot_parts.setdefault(material, []).append((tris, ident))
            return
        if material.kind in ("light", "glow"):
            luminance = material.emitted_luminance()
            _check_glow_radius(material, where, what)
            if patterns:
                # a sphere's projected area is πr² in every direction: kept exact, not tessellated
                disc = math.pi * (reals[3] * transform.scale) ** 2 if ptype == "sphere" else None
                self.patterned_emitter(material, patterns, tris, disc, ident, where, what)
                return
            if luminance <= 0:
                self.add(tris, None, -1)
                return
            area = float(_areas(tris).sum())
            k = len(self.area_luminaires)
            first = self.count
            self.add(tris, None, k)
            self.area_luminaires.append(AreaLuminaire(ident, math.pi * area * luminance,
                                                      np.arange(first, first + len(tris)),
                                                      light_source_radius=_light_source_radius(material)))
            return
        if material.kind not in SURFACE_MATERIALS:
            raise BadInputError(f"{where}: {what}: {material.describe()} is not supported: "
                                f"the solver models {', '.join(SURFACE_MATERIALS)}, light, glow, illum and spotlight")
        if patterns:
            raise BadInputError(f"{where}: {what}: {material.describe()} is modified by "
                                f"{patterns[0].describe()}: patterns and textures are not supported")
        try:
            self.add(tris, material, -1)
        except BadInputError as exc:
            raise BadInputError(f"{where}: {what} uses {exc}") from None

    def distant(self, modifier, ident, reals, where, transform):
        """A ``source`` (direction, angle) with a ``light`` or ``glow`` material: the sun, or a
        sky or ground glow modified by a sky function (:mod:`lsadphoto.solver.sky`)."""
        what = f"source {ident!r}"
        if len(reals) != 4:
            raise BadInputError(f"{where}: {what} needs 4 real arguments (xdir ydir zdir angle), got {len(reals)}")
        material, patterns = self.material_of(self.resolve(modifier, where, what), where, what)
        if material.kind not in ("light", "glow"):
            raise BadInputError(f"{where}: {what}: {material.describe()} is not supported on a distant "
                                "source; use light or glow")
        luminance = material.emitted_luminance()
        _check_glow_radius(material, where, what)
        axis = transform.vector(reals[:3])
        if not np.linalg.norm(axis) > 0 or not 0 < reals[3] <= 360:
            raise BadInputError(f"{where}: {what}: needs a non-zero direction and an angle in (0, 360] degrees")
        function = inverse = None
        if patterns:
            pattern = patterns[0]
            if pattern.kind != "brightfunc" or len(patterns) > 1:
                raise BadInputError(f"{where}: {what}: {material.describe()} is modified by "
                                    f"{pattern.describe()}; only a brightfunc sky function is supported "
                                    "on a distant source")
            function, inverse = self.sky_function(pattern)
        if luminance <= 0:  # black: it emits nothing (as a black light surface)
            return
        self.distant_sources.append(DistantSource(ident, axis, math.radians(reals[3]) / 2, luminance,
                                                  function, inverse, where, light_source=material.kind == "light"))

    def sky_function(self, pattern):
        """``(function, calfile, args)`` and the world-to-pattern rotation of a sky
        ``brightfunc``, checked: the .cal file must exist (beside the scene or in Radiance's
        library) and be one the solver evaluates natively."""
        where = f"{pattern.where}: brightfunc {pattern.name!r}"
        if len(pattern.strings) < 2:
            raise BadInputError(f"{where} needs a function and a .cal file")
        function, calfile = pattern.strings[0], pattern.strings[1]
        folders = [self.folder_of.get(pattern, self.base), self.base, *_radiance_library()]
        if not any((Path(f) / calfile).is_file() for f in folders):
            raise BadInputError(f"{where}: {calfile} not found (beside the scene, on RAYPATH or in "
                                "Radiance's library)")
        check_sky_arguments(function, Path(calfile).name, pattern.reals, where)
        m = pattern.transform.matrix[:3, :3]
        inverse = None if np.allclose(m, np.eye(3)) else np.linalg.inv(m)
        return (function, Path(calfile).name, tuple(pattern.reals)), inverse

    def mesh(self, modifier, ident, strings, where, transform, folder):
        """A ``mesh`` from the OBJ file it was compiled from (``name.obj`` beside ``name.rtm``),
        with the mesh's transform words and its modifier on every face."""
        what = f"mesh {ident!r}"
        if not strings:
            raise BadInputError(f"{where}: {what} names no mesh file")
        compiled = Path(strings[0])
        if len(strings) > 1:
            transform = transform @ parse_transform(strings[1:], f"{where}: {what}")[0][1]
        source = next((f / compiled.with_suffix(".obj") for f in (folder, self.base)
                       if (f / compiled.with_suffix(".obj")).is_file()), None)
        if source is None:
            raise BadInputError(f"{where}: {what}: {compiled.name} is a compiled (binary) mesh and its source "
                                f"{compiled.with_suffix('.obj').name} is not beside it; give the OBJ "
                                "(read from its source) or '!obj2rad file.obj'")
        text = source.read_text(encoding="utf-8", errors="replace")
        if any(line.split()[:1] == ["usemtl"] for line in text.splitlines()):
            raise BadInputError(f"{where}: {what}: {source.name} assigns materials per face (usemtl); "
                                "read it with '!obj2rad' and define those modifiers")
        import trimesh

        try:
            mesh = trimesh.load(source, force="mesh", process=False)
        except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds; report in one line
            raise BadInputError(f"{where}: {what}: cannot read {source} ({exc})") from None
        tris = np.asarray(mesh.triangles, float)
        tris = tris[_areas(tris) > 0]  # meshes often carry slivers
        if tris.size == 0:
            raise BadInputError(f"{where}: {what}: {source} has no triangles")
        tris = transform.point(tris)
        if transform.mirrored:
            tris = tris[:, ::-1]
        self.place(modifier, ident, "mesh", None, tris, where, transform)

    def instance(self, modifier, ident, strings, where, transform, folder, depth):
        """An ``instance`` of an octree, read from the Radiance files it was compiled from.

        An octree is binary, but its header records the ``oconv`` command that made it: the
        files named there (relative to the octree's folder; ``-i`` octrees in turn) are read
        with the instance's transform words, their own modifiers kept, as Radiance shows an
        instance whose modifier is ``void``. Refused in one line: a source file that is missing
        or newer than the octree (the octree would no longer be what Radiance renders), input
        from the standard input, and a modifier other than ``void``."""
        what = f"instance {ident!r}"
        if not strings:
            raise BadInputError(f"{where}: {what} names no octree")
        if modifier != "void":
            raise BadInputError(f"{where}: {what} has modifier {modifier!r}; only instances with the "
                                "octree's own materials (modifier void) are supported")
        octree = next((f / strings[0] for f in (folder, self.base) if (f / strings[0]).is_file()), None)
        if octree is None:
            raise BadInputError(f"{where}: {what}: octree {strings[0]} not found")
        inner = transform
        if len(strings) > 1:
            inner = transform @ parse_transform(strings[1:], f"{where}: {what}")[0][1]
        # an octree is compiled on its own: its definitions neither see the scene's nor leak into it
        outer, self.defs = self.defs, {}
        try:
            for path in _octree_sources(octree, f"{where}: {what}"):
                self.read(path.read_text(encoding="utf-8", errors="replace"), str(path), inner,
                          folder=path.parent, prefix=f"{ident}.", depth=depth + 1)
        finally:
            self.defs = outer

    @staticmethod
    def material_of(record, where, what):
        """The material a surface uses and the patterns applied to it, as Radiance's shading
        walks the modifier chain: patterns before the first material, then the material's own."""
        patterns = []
        while record is not None and record.kind in _PATTERNS:
            patterns.append(record)
            record = record.modifier
        if record is None:
            raise BadInputError(f"{where}: {what} has no material (its modifiers end in void)")
        chain = record.modifier
        while chain is not None:
            patterns.append(chain)
            chain = chain.modifier
        return record, patterns

    def add(self, tris, material, emitter):
        self.triangles.append(tris)
        self.count += len(tris)
        self.material.append(np.full(len(tris), self._material_index(material)))
        self.emitter.append(np.full(len(tris), emitter))

    def tessellate(self, ptype, what, r, where, transform):
        need = {"sphere": 4, "bubble": 4, "cone": 8, "cup": 8, "cylinder": 7, "tube": 7, "ring": 8}
        name = f"{where}: {what}"
        if ptype == "polygon":
            if len(r) < 9 or len(r) % 3:
                raise BadInputError(f"{name} needs 3·n ≥ 9 coordinates, got {len(r)}")
            vertices = transform.point(np.reshape(r, (-1, 3)))
            if transform.mirrored:
                vertices = vertices[::-1]
            if len(vertices) == 3:  # a triangle (most of obj2rad's output) needs no triangulation
                v = vertices
                size = float(np.ptp(v, axis=0).max())
                if float(np.linalg.norm(np.cross(v[1] - v[0], v[2] - v[0]))) > 1e-12 * size * size:
                    return v[None]
            return polygon_triangles(vertices, name)
        if len(r) != need[ptype]:
            raise BadInputError(f"{name} needs {need[ptype]} real arguments, got {len(r)}")
        s, eps = transform.scale, self.eps
        try:
            if ptype in ("sphere", "bubble"):
                return sphere_triangles(transform.point(r[:3]), r[3] * s, inward=ptype == "bubble",
                                        tessellation_error=eps)
            if ptype == "ring":
                return annulus_triangles(transform.point(r[:3]), transform.vector(r[3:6]), r[6] * s,
                                         r[7] * s, tessellation_error=eps)
            r0, r1 = (r[6], r[7]) if ptype in ("cone", "cup") else (r[6], r[6])
            if ptype in ("cylinder", "tube") and not r0 > 0:
                raise BadInputError(f"radius must be positive, got {r0:g}")
            return cone_triangles(transform.point(r[:3]), transform.point(r[3:6]), r0 * s, r1 * s,
                                  inward=ptype in ("cup", "tube"), tessellation_error=eps)
        except BadInputError as exc:
            raise BadInputError(f"{name}: {exc}") from None

    def place_illum(self, illum, ident, ptype, reals, tris, where, transform):
        """An ``illum`` surface (mkillum's secondary light source) as the solver needs it.

        Radiance uses an illum as a light source for shadow rays only; every other ray sees its
        alternate material (its first string argument), or nothing when that is absent or
        ``void`` (refman, "illum"). The solver traces the light that an illum stands for through
        the scene itself (full interreflection), so it takes the surface as its alternate
        material — or leaves it out — and not the illum's precomputed distribution, which would
        count that light twice.
        """
        alternate = illum.strings[0] if illum.strings else "void"
        if alternate == "void":
            return
        record = self.resolve(alternate, where, f"alternate material of illum {illum.name!r}")
        if record is not None and record.kind == "illum":
            raise BadInputError(f"{where}: illum {illum.name!r} ({illum.where}) has another illum "
                                f"({alternate!r}) as its alternate material")
        self.place(alternate, ident, ptype, reals, tris, where, transform)

    def patterned_emitter(self, light, patterns, tris, disc, ident, where, what):
        pattern = patterns[0]
        if pattern.kind != "brightdata" or len(patterns) > 1:
            raise BadInputError(
                f"{where}: {what}: {light.describe()} is modified by {pattern.describe()}; only the "
                "brightdata patterns of source.cal that ies2rad writes are supported")
        self.luminaire_parts.setdefault(pattern, []).append((light, tris, disc, ident))

    # commands
    def command(self, text, where, transform, override, prefix, depth):
        lexer = shlex.shlex(text, posix=True, punctuation_chars="|;&<>()")
        lexer.whitespace_split = True
        try:
            words = list(lexer)
        except ValueError as exc:
            raise BadInputError(f"{where}: cannot read command !{text} ({exc})") from None
        stages, current = [], []
        for w in words:
            if w == "|":
                stages.append(current)
                current = []
            elif set(w) <= set("|;&<>()"):
                raise BadInputError(f"{where}: !{text}: shell syntax {w!r} is not supported (commands "
                                    "run without a shell; pipes '|' of Radiance programs only)")
            else:
                current.append(w)
        stages.append(current)
        if any(not s for s in stages):
            raise BadInputError(f"{where}: !{text}: empty command in the pipeline")
        last = stages[-1]
        internal = last[0] == "xform"
        external = stages[:-1] if internal else stages
        output = self.run_external(external, text, where) if external else None
        if not internal:
            self.read(output, f"{where} (!{external[-1][0]} output)", transform, folder=self.base,
                      override=override, prefix=prefix, depth=depth + 1)
            return
        self.xform(last[1:], output, text, where, transform, override, prefix, depth)

    def run_external(self, stages, text, where):
        folder = radiance_programs()
        if folder is None:
            raise BadInputError(f"{where}: !{text}: running Radiance programs needs the pyradiance "
                                "package (pip install pyradiance), which ships them")
        env = dict(os.environ, RAYPATH=os.pathsep.join([".", str(folder.parent / "lib")]),
                   PATH=os.pathsep.join([str(folder), os.environ.get("PATH", "")]))
        data = None
        deadline = time.monotonic() + self.timeout
        for stage in stages:
            program = folder / stage[0]
            if "/" in stage[0] or not program.is_file():
                raise BadInputError(f"{where}: !{text}: {stage[0]!r} is not one of the Radiance programs "
                                    f"that pyradiance ships ({folder})")
            try:
                done = subprocess.run([str(program), *stage[1:]], input=data if data is not None else b"",
                                      capture_output=True,
                                      cwd=self.base, env=env, timeout=max(0.001, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                raise BadInputError(f"{where}: !{text}: did not finish within {self.timeout:g} s "
                                    "(command_timeout)") from None
            if done.returncode != 0:
                message = done.stderr.decode("utf-8", "replace").strip().splitlines()
                raise BadInputError(f"{where}: !{text}: {stage[0]} failed (exit {done.returncode})"
                                    + (f": {message[0]}" if message else ""))
            data = done.stdout
        return data.decode("utf-8", "replace")

    def xform(self, args, stdin, text, where, transform, override, prefix, depth):
        name, modifier, k = None, override, 0
        words = []
        while k < len(args):
            w = args[k]
            if w in ("-n", "-m"):
                if k + 1 >= len(args):
                    raise BadInputError(f"{where}: !{text}: {w} needs a value")
                if w == "-n":
                    name = args[k + 1]
                else:
                    modifier = args[k + 1]
                k += 2
            elif w in ("-c", "-e"):
                k += 1
            elif w in TRANSFORM_WORDS:
                n = TRANSFORM_WORDS[w]
                if len(args) < k + 1 + n or not all(_is_number(v) for v in args[k + 1:k + 1 + n]):
                    raise BadInputError(f"{where}: !{text}: {w} needs {n} number(s)")
                words.extend(args[k:k + 1 + n])
                k += 1 + n
            elif w.startswith("-") and len(w) > 1:
                raise BadInputError(f"{where}: !{text}: xform option {w!r} is not supported (only "
                                    f"{', '.join(TRANSFORM_WORDS)}, -n, -m, -c, -e)")
            else:
                break
        files = args[k:]
        if stdin is not None and files:
            raise BadInputError(f"{where}: !{text}: xform reads either piped input or files, not both")
        if stdin is None and not files:
            raise BadInputError(f"{where}: !{text}: xform has no input files")
        copies = parse_transform(words, f"{where}: !{text}")
        for index, copy in copies:
            inner = transform @ copy
            tag = prefix + (f"{name}." if name else "") + "".join(f"a{i}." for i in index)
            if stdin is not None:
                self.read(stdin, f"{where} (piped input)", inner, folder=self.base, override=modifier,
                          prefix=tag, depth=depth + 1)
                continue
            for file in files:
                path = Path(file) if Path(file).is_absolute() else self.base / file
                if not path.is_file():
                    raise BadInputError(f"{where}: !{text}: file {file} does not exist")
                self.read(path.read_text(encoding="utf-8", errors="replace"), str(path), inner,
                          folder=path.parent, override=modifier, prefix=tag, depth=depth + 1)

    def scene(self, name, views):
        """The :class:`Scene` of everything read."""
        points = self.luminaires() + self.spotlights()
        if not self.triangles:
            raise BadInputError(f"{name}: the scene has no surfaces")
        if not self.area_luminaires and not points and not self.distant_sources:
            raise BadInputError(f"{name}: the scene has no light sources (light, glow, ies2rad luminaires "
                                "or distant sources)")
        return Scene(np.concatenate(self.triangles), np.concatenate(self.material), self.names,
                     np.asarray(self.rho), np.concatenate(self.emitter), self.area_luminaires, points,
                     views, name=Path(name).stem, source={"radiance": name},
                     surface_materials=None if all(m.is_lambertian for m in self.models) else self.models,
                     distant_sources=self.distant_sources)

    # brightdata luminaires
    def luminaires(self):
        out = []
        for pattern, parts in self.luminaire_parts.items():
            out.append(self.luminaire(pattern, parts))
        return out

    def luminaire(self, pattern, parts):
        where = f"{pattern.where}: brightdata {pattern.name!r}"
        words = list(pattern.strings)
        if len(words) < 4:
            raise BadInputError(f"{where} needs a function, a data file, a function file and coordinates")
        function, datafile, calfile, coords = words[0], words[1], words[2], words[3:]
        if Path(calfile).name != "source.cal" or function not in _SOURCE_CORRECTIONS:
            raise BadInputError(f"{where}: {function} of {calfile} is not supported; only the source.cal "
                                f"patterns ies2rad writes ({', '.join(_SOURCE_CORRECTIONS)})")
        bad = [c for c in coords if c not in _SOURCE_COORDINATES]
        if bad:
            raise BadInputError(f"{where}: coordinate {bad[0]!r} is not supported "
                                f"(valid: {', '.join(_SOURCE_COORDINATES)})")
        low, high = _SOURCE_CORRECTIONS[function]
        a = pattern.reals
        if not low <= len(a) <= high:
            raise BadInputError(f"{where}: {function} takes {low}–{high} real arguments, got {len(a)}")
        folders = [self.folder_of.get(pattern, self.base), self.base]
        path = next((f / datafile for f in folders if (f / datafile).is_file()), None)
        if path is None:
            raise BadInputError(f"{where}: data file {datafile} not found "
                                f"(looked in {', '.join(str(f) for f in dict.fromkeys(folders))})")
        table = _DataTable(path, where)
        if len(table.axes) != len(coords):
            raise BadInputError(f"{where}: data file {datafile} has {len(table.axes)} dimensions for "
                                f"{len(coords)} coordinates")
        xf = pattern.transform
        tris = np.concatenate([t for _, t, _, _ in parts])
        facets = [(lt, t) for lt, t, disc, _ in parts if disc is None]  # projected area from triangles
        spheres = sum(lt.emitted_luminance() * disc for lt, _, disc, _ in parts if disc is not None)
        if facets:
            normals = np.concatenate([t for _, t in facets])
            normals = np.cross(normals[:, 1] - normals[:, 0], normals[:, 2] - normals[:, 0])  # 2·area·n
            luminance = np.concatenate([np.full(len(t), lt.emitted_luminance()) for lt, t in facets])
        else:
            normals, luminance = np.zeros((0, 3)), np.zeros(0)
        flat = function == "flatcorr"
        area = 0.5 * np.linalg.norm(normals, axis=1)
        nadir = xf.vector([0.0, 0.0, -1.0])
        frame = luminaire_frame(nadir, xf.vector([1.0, 0.0, 0.0]))

        def intensity(c, gamma):
            local = np.stack([np.sin(gamma) * np.cos(c), np.sin(gamma) * np.sin(c), np.cos(gamma)], axis=-1)
            world = local @ frame
            d = -xf.inverse_direction(world)  # Radiance's ray direction, in the pattern's frame
            value = table(*(_source_coordinate(name, d) for name in coords))
            if function == "boxcorr":
                value = value / (np.abs(d[..., 0]) * a[2] * a[3] + np.abs(d[..., 1]) * a[1] * a[3]
                                 + np.abs(d[..., 2]) * a[1] * a[2])
            elif function == "cylcorr":
                value = value / (a[1] * a[2] * np.sqrt(np.maximum(0.0, 1 - d[..., 2] ** 2))
                                 + math.pi / 4 * a[1] ** 2 * np.abs(d[..., 2]))
            if a:
                value = a[0] * value
            return np.maximum(value, 0.0) * projected(world)

        def projected(world):
            # Σ over the triangles facing ω of L_t·A_t·cos (flatcorr: L_t·A_t, its 1/Rdot cancels)
            flat_world = world.reshape(-1, 3)
            out = np.empty(len(flat_world))
            for k in range(0, len(flat_world), 2048):
                cosines = flat_world[k:k + 2048] @ normals.T * 0.5  # area · cos per triangle
                weights = np.where(cosines > 0, area if flat else cosines, 0.0)
                out[k:k + 2048] = weights @ luminance + spheres
            return out.reshape(world.shape[:-1])

        gamma = _angle_grid(180.0, 1.0, [table.axes[k] for k, n in enumerate(coords)
                                         if n == "src_theta"], (90.0,))
        phi_axes = [_phi_nodes(table.axes[k], n) for k, n in enumerate(coords) if n != "src_theta"]
        if xf.mirrored:
            phi_axes = [np.mod(360.0 - p, 360.0) for p in phi_axes]
        c = _angle_grid(360.0, 5.0, phi_axes, ())
        name = parts[0][3].rsplit(".", 1)[0] if len(parts) > 1 else parts[0][3]
        discs = sum(disc for _, _, disc, _ in parts if disc is not None)
        return _tabulated_luminaire(name, tris, normals, discs, frame, intensity, c, gamma, where,
                                    "Radiance brightdata")

    def spotlights(self):
        """One luminaire per ``spotlight`` material: its surfaces' emission inside its cone."""
        return [self.spotlight(record, parts) for record, parts in self.spot_parts.items()]

    def spotlight(self, record, parts):
        """A ``spotlight``'s surfaces as one luminaire (refman, "spotlight"; Radiance
        ``srcsupp.c`` ``makespot``, ``source.c`` ``spotout`` and ``srcray``).

        Radiance: the radiance of a ``light`` (179 lm/W × Y of its RGB, front side only) in the
        directions within half the cone angle of the aim vector, none outside; the aim vector
        turns with the surfaces (xform), and its length f is the distance of the "effective
        focus" behind the source: Radiance's direct calculation scales each source sample's
        solid angle by (d/(d + f))², as if the light came from a point f further away. The
        solver emits I(ω) = L·Σ A_t·max(0, n_t·ω) inside the cone — from the surfaces
        themselves (a visible opening) when f ≤ :data:`SPOT_FOCUS_NEGLIGIBLE`, otherwise from the
        focus point, which reproduces that falloff (exactly on the axis; off the axis
        Radiance's d + f is the distance along the ray, ours the distance from the focus) and
        does not appear in renders (a :class:`SolverWarning` says so)."""
        where = f"{record.where}: spotlight {record.name!r}"
        angle = float(record.reals[3])
        if not 0 < angle <= 360:
            raise BadInputError(f"{where}: cone angle {angle:g}° must be in (0, 360]")
        aim = record.transform.vector(np.asarray(record.reals[4:7], float))
        focus = float(np.linalg.norm(aim))
        if not focus > 0:
            raise BadInputError(f"{where}: zero aim (focus) vector")
        aim = aim / focus
        tris = np.concatenate([t for t, _ in parts])
        normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])  # 2·area·n
        luminance = record.emitted_luminance()
        cos_half = math.cos(math.radians(angle / 2))
        helper = np.eye(3)[int(np.argmin(np.abs(aim)))]
        frame = luminaire_frame(aim, helper - (helper @ aim) * aim)

        def intensity(c, gamma):
            local = np.stack([np.sin(gamma) * np.cos(c), np.sin(gamma) * np.sin(c), np.cos(gamma)], axis=-1)
            world = (local @ frame).reshape(-1, 3)
            projected = np.maximum(world @ normals.T * 0.5, 0.0).sum(axis=1)
            inside = world @ aim >= cos_half - 1e-12
            return (luminance * projected * inside).reshape(np.shape(c))

        gamma = _angle_grid(180.0, 1.0, (), (angle / 2,) if angle < 360 else ())
        c = _angle_grid(360.0, 5.0, (), ())
        name = parts[0][1].rsplit(".", 1)[0] if len(parts) > 1 else parts[0][1]
        lum = _tabulated_luminaire(name, tris, normals, 0.0, frame, intensity, c, gamma, where,
                                   "Radiance spotlight")
        if focus <= SPOT_FOCUS_NEGLIGIBLE:
            return lum
        warnings.warn(f"{where}: its aim vector's length puts Radiance's effective focus {focus:g} m "
                      "behind the surface; the solver emits from that point, which does not appear in "
                      f"renders (an aim vector shorter than {SPOT_FOCUS_NEGLIGIBLE:g} m emits from the "
                      "surface itself)", SolverWarning, stacklevel=2)
        return PointLuminaire(lum.name, lum.position - focus * aim, lum.photometry, frame, (0.0, 0.0), 1.0)


def _tabulated_luminaire(name, tris, normals, discs, frame, intensity, c, gamma, where, fmt):
    """A :class:`PointLuminaire` of emitting surfaces ``tris`` (n, 3, 3) [m] with the luminous
    intensity ``intensity(c, gamma)`` [cd] (angles [rad] in ``frame``) tabulated on the grid
    ``c``, ``gamma`` [deg], emitting from a rectangle of the surfaces' projected area towards
    the frame's nadir (``normals``: 2·area·n of the flat ones; ``discs``: the projected area
    [m²] of spheres, the same from everywhere)."""
    cc, gg = np.meshgrid(np.radians(c), np.radians(gamma), indexing="ij")
    values = intensity(cc, gg)
    values[-1] = values[0]
    try:
        photometry = Photometry(c, gamma, values, source=where, format=fmt)
        if not photometry.luminous_flux > 0:
            raise BadInputError("its intensity distribution emits no flux")
    except BadInputError as exc:
        raise BadInputError(f"{where}: {exc}") from None
    centroid = (tris.mean(axis=1) * _areas(tris)[:, None]).sum(axis=0) / _areas(tris).sum()
    pts = tris.reshape(-1, 3) - centroid
    u, v = pts @ frame[0], pts @ frame[1]
    length, width = float(np.ptp(u)), float(np.ptp(v))
    down = float(np.maximum(0.0, normals @ frame[2]).sum() * 0.5) + discs
    if down > 0 and length * width > 0:  # a rectangle of the projected area towards the nadir
        scale = math.sqrt(down / (length * width))
        length, width = length * scale, width * scale
    return PointLuminaire(name, centroid, photometry, frame, (length, width), 1.0)


def _octree_sources(octree, where, seen=()):
    """The Radiance files an octree was compiled from, in order, as its header's ``oconv``
    command names them (``-i`` octrees expanded), each checked to exist and to be no newer than
    the octree."""
    octree = Path(octree).resolve()
    if octree in seen:
        raise BadInputError(f"{where}: octree {octree.name} includes itself (oconv -i)")
    with open(octree, "rb") as fh:
        head = fh.read(1 << 16)
    if not head.startswith(b"#?RADIANCE"):
        raise BadInputError(f"{where}: {octree.name} is not a Radiance octree (no #?RADIANCE header)")
    lines = head.split(b"\n\n", 1)[0].decode("latin-1").splitlines()
    command = next((line.split() for line in lines if line.split()[:1] == ["oconv"]), None)
    if command is None:
        raise BadInputError(f"{where}: the header of {octree.name} names no oconv command to read its "
                            "sources from")
    takes = {"-b": 4, "-n": 1, "-r": 1, "-i": 1}
    files, k = [], 1
    while k < len(command):
        word = command[k]
        if word == "-i":
            files += _octree_sources(octree.parent / command[k + 1], where, seen + (octree,))
            k += 2
        elif word in takes:
            k += 1 + takes[word]
        elif word in ("-f", "-w"):
            k += 1
        elif word.startswith("-"):
            raise BadInputError(f"{where}: {octree.name} was made from {'standard input' if word == '-' else word} "
                                f"(oconv {' '.join(command[1:])}); give its Radiance files instead")
        else:
            path = octree.parent / word
            if not path.is_file():
                raise BadInputError(f"{where}: {octree.name} was compiled from {word}, which is not "
                                    f"beside it; give the Radiance files instead of the octree")
            if path.stat().st_mtime > octree.stat().st_mtime + 1:
                raise BadInputError(f"{where}: {word} is newer than {octree.name}, so the octree may no "
                                    "longer hold it; run oconv again or give the Radiance files")
            files.append(path)
            k += 1
    return files


def _is_number(word):
    try:
        float(word)
    except ValueError:
        return False
    return True


def _phi_nodes(axis, name):
    """C angles [deg] in 0…360 where a folded ``src_phi*`` axis has its nodes."""
    fold = {"src_phi": 360.0, "src_phi2": 180.0, "src_phi4": 90.0}[name]
    nodes = [np.asarray(axis, float)]
    if fold < 360:
        for start in np.arange(0.0, 360.0, fold):
            nodes += [start + axis, start + fold - axis]
    return np.concatenate(nodes)


def _angle_grid(top, step, node_sets, cuts):
    """Sorted grid 0…top [deg]: a regular ``step`` plus every node and both sides of each cut."""
    tiny = 1e-6
    parts = [np.linspace(0.0, top, round(top / step) + 1)]
    parts += [np.asarray(n, float) for n in node_sets]
    parts += [np.array([c - tiny, c + tiny]) for c in cuts]
    grid = np.unique(np.clip(np.concatenate(parts), 0.0, top).round(9))
    return grid


def _light_source_radius(material):
    """Distance [m] from its centre within which Radiance's direct calculation takes a surface
    of ``light``/``glow`` material as a light source: ∞ for a ``light``, a ``glow``'s radius of
    influence (``srcskip``), 0 for a ``glow`` of radius 0 (``marksources`` skips it: it lights
    only through the ambient calculation)."""
    if material.kind == "light":
        return math.inf
    return material.reals[3] if material.reals[3] > 1e-6 else 0.0


def _check_glow_radius(material, where, what):
    """A ``glow`` with a negative radius of influence lights nothing in Radiance (it is only
    seen), which no emitter of the solver does: refused. A positive radius only decides where
    Radiance samples the glow as a light source (shadow rays within it, interreflection
    beyond); both estimate the same light, so the solver takes it as a plain emitter."""
    if material.kind == "glow" and material.reals[3] < 0:
        raise BadInputError(
            f"{where}: {what}: glow {material.name!r} ({material.where}) has a negative radius of influence "
            f"({material.reals[3]:g}): Radiance then shows it but lets it light nothing, which no "
            "emitter does; use 0 or a positive radius (the same light) or a light")


def _radiance_library():
    """Folders where Radiance looks for .cal files: RAYPATH, then the pyradiance library."""
    folders = [p for p in os.environ.get("RAYPATH", "").split(os.pathsep) if p]
    programs = radiance_programs()
    if programs is not None:
        folders.append(str(programs.parent / "lib"))
    return folders


def _areas(tris):
    return 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)


def read_radiance_scene(path_or_text, *, views=None, tessellation_error=DEFAULT_TESSELLATION_ERROR,
                        command_timeout=DEFAULT_COMMAND_TIMEOUT):
    """A :class:`~lsadphoto.solver.Scene` from a Radiance scene file (or its text).

    Parameters
    ----------
    path_or_text : str or Path
        A ``.rad`` file, or scene text containing a newline (commands then run in the
        current folder).
    views : list of View or dict, optional
        Views to attach: :class:`~lsadphoto.solver.View`\\ s (e.g. from
        :func:`lsadphoto.solver.formats.read_view`) or ``[[views]]`` tables as in the TOML
        structure.
    tessellation_error : float
        Largest sagitta of tessellated curves relative to their radius [–]
        (:mod:`~lsadphoto.solver.formats.shapes`; areas are exact whatever the value).
    command_timeout : float
        Time limit of each ``!`` command line [s].

    Examples
    --------
    >>> scene = read_radiance_scene('''
    ... void plastic grey 0 0 5 .5 .5 .5 0 0
    ... void light lamp 0 0 3 10 10 10
    ... grey polygon floor 0 0 12 0 0 0  1 0 0  1 1 0  0 1 0
    ... lamp polygon panel 0 0 12 0 0 1  0 1 1  1 1 1  1 0 1
    ... ''')
    >>> round(float(scene.reflectance[scene.material[0]]), 6), round(scene.area_luminaires[0].flux, 3)
    (0.5, 5623.451)
    """
    if isinstance(path_or_text, str) and "\n" in path_or_text:
        text, name, base = path_or_text, "Radiance scene", Path.cwd()
    else:
        path = Path(path_or_text)
        if not path.is_file():
            raise BadInputError(f"Radiance scene {path} does not exist")
        text, name, base = path.read_text(encoding="utf-8", errors="replace"), str(path), path.resolve().parent
    reader = _reader(base, tessellation_error, command_timeout)
    reader.read(text, name, Transform(), folder=base)
    return reader.scene(name, as_views(views))


def _reader(base, tessellation_error, command_timeout):
    if not command_timeout > 0:
        raise BadInputError(f"command_timeout must be positive, got {command_timeout!r}")
    return _Reader(base, tessellation_error, float(command_timeout))


#: Variables of rad's input files (``.rif``) and the shortest abbreviation rad accepts.
_RIF_VARIABLES = {"OCTREE": 3, "ZONE": 2, "EXPOSURE": 3, "RESOLUTION": 3, "QUALITY": 3,
                  "VARIABILITY": 3, "DETAIL": 3, "INDIRECT": 3, "PENUMBRAS": 3, "AMBFILE": 3,
                  "OPTFILE": 3, "PICTURE": 3, "RAWFILE": 3, "ZFILE": 2, "REPORT": 3, "UP": 2,
                  "materials": 3, "scene": 3, "objects": 3, "view": 2, "illum": 3, "mkillum": 3,
                  "mkpmap": 3, "oconv": 3, "render": 3, "rvu": 3, "rpict": 3, "pfilt": 2}


def _rif_variable(word, where):
    for name, shortest in _RIF_VARIABLES.items():
        if len(word) >= shortest and name.startswith(word):
            return name
    raise BadInputError(f"{where}: unknown rad variable {word!r}")


def read_rif_scene(path, *, tessellation_error=DEFAULT_TESSELLATION_ERROR,
                   command_timeout=DEFAULT_COMMAND_TIMEOUT):
    """A :class:`~lsadphoto.solver.Scene` from a rad input file (``.rif``), with its views.

    The ``materials`` files are read first, then the ``scene`` files and commands (as
    ``oconv`` gets them from ``rad``), each as :func:`read_radiance_scene` reads a file; every
    ``view`` (``[name] options``, ``-vf`` allowed, ``UP`` giving the default up axis) becomes
    a view of ``RESOLUTION`` (default 512) reduced to square pixels as ``rpict -pa 1`` does
    (the vertical angle then rounded to whole pixels). Rendering options (``QUALITY``,
    ``render``, …) do not change the model and are not used; ``illum`` (mkillum's secondary
    sources) is refused.

    References
    ----------
    Radiance manual page ``rad(1)`` (variables, abbreviations, order of files).
    """
    from .views import view_from_options, view_options

    path = Path(path)
    if not path.is_file():
        raise BadInputError(f"rad file {path} does not exist")
    base = path.resolve().parent
    values = {}
    lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    k = 0
    while k < len(lines):
        number, line = k + 1, _strip_comment(lines[k])
        k += 1
        while line.rstrip().endswith("\\") and k < len(lines):
            line = line.rstrip()[:-1] + " " + _strip_comment(lines[k])
            k += 1
        if not line.strip():
            continue
        where = f"{path}:{number}"
        if "=" not in line:
            raise BadInputError(f"{where}: expected 'variable = value'")
        name, value = (part.strip() for part in line.split("=", 1))
        values.setdefault(_rif_variable(name, where), []).append((value, where))
    if "illum" in values:
        raise BadInputError(f"{values['illum'][0][1]}: illum (mkillum secondary sources) is not supported")
    reader = _reader(base, tessellation_error, command_timeout)
    for variable in ("materials", "scene"):
        for value, where in values.get(variable, []):
            try:
                items = shlex.split(value)
            except ValueError as exc:
                raise BadInputError(f"{where}: cannot read {variable} ({exc})") from None
            for item in items:
                command = item[1:] if item.startswith("!") else f"xform {shlex.quote(item)}"
                reader.command(command, where, Transform(), None, "", 0)
    size = [int(v) for v in (values.get("RESOLUTION", [("512", "")])[-1][0].split() + ["0"])[:2]]
    xres, yres = size[0], size[1] or size[0]
    up = {"X": "1 0 0", "-X": "-1 0 0", "Y": "0 1 0", "-Y": "0 -1 0", "Z": "0 0 1", "-Z": "0 0 -1"}
    axis = values.get("UP", [("Z", "")])[-1][0].upper()
    if axis not in up:
        raise BadInputError(f"{values['UP'][-1][1]}: UP must be one of {', '.join(up)}, got {axis!r}")
    views = []
    for n, (value, where) in enumerate(values.get("view", []), 1):
        words = value.split(None, 1)
        name, options = (words[0], words[1] if len(words) > 1 else "") if words and not words[0].startswith("-") \
            else (str(n), value)
        try:
            view = parse_view(f"-vu {up[axis]} " + view_options(options, base=base), strict=True)
            if "vp" not in view:
                raise BadInputError(f"view {name!r} gives no eye position -vp (rad's standard views from "
                                    "ZONE are not supported)")
            width, height, view = _square_pixels(view, xres, yres)
            views.append(view_from_options(view, width, height, name=name))
        except BadInputError as exc:
            raise BadInputError(f"{where}: {exc}") from None
    return reader.scene(str(path), views)


def _square_pixels(view, xres, yres):
    """Picture size within ``xres`` × ``yres`` with square pixels (``rpict -pa 1``), and the
    view with its vertical angle made a whole number of pixels."""
    kind = view.get("type", "v")
    vh, vv = math.radians(view.get("vh", 45.0)), math.radians(view.get("vv", 45.0))
    forward = {"v": (lambda a: math.tan(a / 2), lambda t: 2 * math.atan(t)),
               "a": (lambda a: a, lambda t: t), "h": (lambda a: math.sin(a / 2), lambda t: 2 * math.asin(t)),
               "s": (lambda a: math.tan(a / 4), lambda t: 4 * math.atan(t))}
    if kind not in forward:
        return xres, yres, view  # refused with its reason by the projection
    f, inverse = forward[kind]
    aspect = f(vv) / f(vh)
    if aspect * xres <= yres:
        width, height = xres, max(1, round(xres * aspect))
    else:
        width, height = max(1, round(yres / aspect)), yres
    view = dict(view, vv=math.degrees(inverse(f(vh) * height / width)))
    return width, height, view
