"""Reading a Lambertian subset of Radiance scene descriptions into a solver scene.

Supported primitives: ``polygon`` surfaces whose modifier is ``plastic`` with zero
specularity (Lambertian reflectance ρ = 0.265074 R + 0.670115 G + 0.064811 B, the
luminance weights of Radiance RGB), or ``light`` (a Lambertian emitter of luminance
L = 179 · (0.265074 R + 0.670115 G + 0.064811 B) cd·m⁻², front side only, not reflecting).
``void`` and comment lines are understood; anything else (other materials, other surfaces,
``!`` commands, aliases) is refused with one line naming it, rather than approximated.

References
----------
Ward Larson, G., Shakespeare, R. (1998). *Rendering with Radiance*, Morgan Kaufmann, ch. 1
(scene description syntax; ``plastic``, ``light``, ``polygon``). Radiance
``src/common/color.h`` (``WHTEFFICACY`` = 179 lm/W; CIE luminance weights; FORMULAS.md
§2.4.1).
"""

import shlex
from pathlib import Path

from ..constants import RADIANCE_RGB_LUMINANCE_WEIGHTS, RADIANCE_WHITE_EFFICACY
from ..errors import BadInputError
from .scene import scene_from_dict

__all__ = ["radiance_luminance", "read_radiance_scene"]


def radiance_luminance(r, g, b):
    """Luminance [cd·m⁻²] (or reflectance [–] without the efficacy) of Radiance RGB."""
    wr, wg, wb = RADIANCE_RGB_LUMINANCE_WEIGHTS
    return wr * r + wg * g + wb * b


def _primitives(text, name):
    try:
        words = shlex.split(text, comments=True, posix=True)
    except ValueError as exc:
        raise BadInputError(f"{name}: cannot parse ({exc})") from None
    pos = 0
    while pos < len(words):
        if words[pos].startswith("!"):
            raise BadInputError(f"{name}: inline commands ({words[pos]}) are not supported")
        if pos + 3 > len(words):
            raise BadInputError(f"{name}: truncated primitive at word {pos + 1}")
        modifier, kind, ident = words[pos:pos + 3]
        pos += 3
        args = []
        for what in ("string", "integer", "real"):
            try:
                n = int(words[pos])
            except (IndexError, ValueError):
                raise BadInputError(f"{name}: {kind} {ident!r}: bad {what} argument count") from None
            args.append(words[pos + 1:pos + 1 + n])
            if len(args[-1]) != n:
                raise BadInputError(f"{name}: {kind} {ident!r}: truncated arguments")
            pos += 1 + n
        try:
            reals = [float(x) for x in args[2]]
        except ValueError:
            raise BadInputError(f"{name}: {kind} {ident!r}: real arguments must be numbers") from None
        yield modifier, kind, ident, args[0], args[1], reals


def read_radiance_scene(path_or_text, *, views=None):
    """A :class:`~lsadphoto.solver.Scene` from a Radiance scene file (or its text).

    Parameters
    ----------
    path_or_text : str or Path
        A ``.rad`` file, or scene text containing a newline.
    views : list of dict, optional
        View tables as in the TOML schema (``[[views]]``), added to the scene.

    Examples
    --------
    >>> scene = read_radiance_scene('''
    ... void plastic grey 0 0 5 .5 .5 .5 0 0
    ... void light lamp 0 0 3 10 10 10
    ... grey polygon floor 0 0 12 0 0 0  1 0 0  1 1 0  0 1 0
    ... lamp polygon panel 0 0 12 0 0 1  0 1 1  1 1 1  1 0 1
    ... ''')
    >>> round(float(scene.reflectance[0]), 6), round(scene.area_luminaires[0].flux, 3)
    (0.5, 5623.451)
    """
    if isinstance(path_or_text, str) and "\n" in path_or_text:
        text, name = path_or_text, "Radiance scene"
    else:
        path = Path(path_or_text)
        if not path.is_file():
            raise BadInputError(f"Radiance scene {path} does not exist")
        text, name = path.read_text(encoding="utf-8", errors="replace"), str(path)
    materials = {}
    surfaces, luminaires, mats = [], [], {}
    for modifier, kind, ident, strings, ints, reals in _primitives(text, name):
        if kind == "plastic":
            if len(reals) != 5:
                raise BadInputError(f"{name}: plastic {ident!r} needs 5 real arguments")
            if reals[3] != 0:
                raise BadInputError(f"{name}: plastic {ident!r} is specular ({reals[3]:g}); "
                                    "only Lambertian materials (specularity 0) are supported")
            rho = radiance_luminance(*reals[:3])
            if not 0 <= rho < 1:
                raise BadInputError(f"{name}: plastic {ident!r}: reflectance {rho:g} not in [0, 1)")
            materials[ident] = ("plastic", rho)
            mats[ident] = {"reflectance": rho}
        elif kind == "light":
            if len(reals) != 3:
                raise BadInputError(f"{name}: light {ident!r} needs 3 real arguments")
            materials[ident] = ("light", RADIANCE_WHITE_EFFICACY * radiance_luminance(*reals))
        elif kind == "polygon":
            if modifier not in materials:
                raise BadInputError(f"{name}: polygon {ident!r}: unknown or unsupported modifier {modifier!r}")
            if len(reals) < 9 or len(reals) % 3:
                raise BadInputError(f"{name}: polygon {ident!r} needs 3·n ≥ 9 coordinates")
            vertices = [reals[i:i + 3] for i in range(0, len(reals), 3)]
            shape = {"type": "polygon", "vertices": vertices}
            mtype, value = materials[modifier]
            if mtype == "light":
                if value > 0:
                    luminaires.append({"type": "area", "name": ident, "luminance": value, "shape": shape})
            else:
                surfaces.append(dict(shape, material=modifier, name=ident))
        else:
            raise BadInputError(f"{name}: {kind} {ident!r} is not supported (only polygon, "
                                "plastic with specularity 0, light)")
    data = {"materials": mats, "surfaces": surfaces, "luminaires": luminaires}
    if views:
        data["views"] = list(views)
    return scene_from_dict(data)
