"""Example scenes: the canonical validation room of FORMULAS.md Part A, and variants of it
with glossy, metal, glass and mirror surfaces (:func:`material_room_rad`).

A closed box room 6 m × 4 m × 3 m; Lambertian grey walls ρ = 0.5, ceiling 0.7, floor 0.2;
four square 0.6 m × 0.6 m Lambertian luminaires of 3000 lm each, centred at (1.5, 1),
(1.5, 3), (4.5, 1), (4.5, 3) m and facing down; the observer's eye at (1.0, 2.0, 1.2) m
looking along +x, horizontal, up +z; a 180° equidistant fisheye view. The luminaires hang
1 cm below the ceiling (z = 2.99 m): coplanar emitter and ceiling triangles would make the
first hit ambiguous in float32; their backs are black.
"""

import math
import re

from .scene import scene_from_dict

__all__ = ["MATERIAL_ROOMS", "canonical_room", "canonical_room_rad", "canonical_room_toml",
           "material_room_rad"]

_LUMINAIRE = """
[[luminaires]]
type = "area"
name = "{name}"
flux = 3000
material = "black"
shape = {{ type = "polygon", vertices = [[{x0}, {y0}, 2.99], [{x0}, {y1}, 2.99], [{x1}, {y1}, 2.99], [{x1}, {y0}, 2.99]] }}
"""


def canonical_room_toml(*, size=256):
    """TOML text of the canonical room with a ``size`` × ``size`` px fisheye view."""
    text = f"""# Canonical validation room (FORMULAS.md Part A)
[scene]
name = "canonical room"

[materials]
wall = {{ reflectance = 0.5 }}
ceiling = {{ reflectance = 0.7 }}
floor = {{ reflectance = 0.2 }}

[[surfaces]]
type = "box"
min = [0, 0, 0]
max = [6, 4, 3]
facing = "inward"
material = "wall"
face_materials = {{ floor = "floor", ceiling = "ceiling" }}

[[views]]
name = "observer"
position = [1.0, 2.0, 1.2]
line_of_sight = [1, 0, 0]
up = [0, 0, 1]
projection = {{ model = "fisheye-ideal", kind = "equidistant", fov_deg = 180, width = {size}, height = {size} }}
"""
    for k, (cx, cy) in enumerate(((1.5, 1.0), (1.5, 3.0), (4.5, 1.0), (4.5, 3.0))):
        # vertices counter-clockwise seen from below, so the front (emitting) side faces down
        text += _LUMINAIRE.format(name=f"L{k + 1}", x0=cx - 0.3, x1=cx + 0.3, y0=cy - 0.3, y1=cy + 0.3)
    return text


def canonical_room(*, size=256):
    """The canonical room as a :class:`~lsadphoto.solver.Scene`.

    Examples
    --------
    >>> room = canonical_room(size=64)
    >>> round(room.total_flux), len(room.area_luminaires), room.views[0].projection.shape
    (12000, 4, (64, 64))
    """
    import tomllib

    return scene_from_dict(tomllib.loads(canonical_room_toml(size=size)))


def canonical_room_rad():
    """The canonical room in Radiance's scene language (the Lambertian subset).

    Grey ``plastic`` (R = G = B = ρ, so Radiance 5 and 6 luminance weights both give ρ) and
    one-sided ``light`` panels facing down, of luminance 3000 lm/(π·0.36 m²) — in Radiance
    units 3000/(π·0.36)/179 = 14.8189 W·sr⁻¹·m⁻² (179 lm/W, FORMULAS.md §2.4.1). The same
    file is read by :func:`~lsadphoto.solver.read_radiance_scene` and by Radiance's oconv.
    """
    r = repr(3000 / (math.pi * 0.36) / 179)
    return f"""# Canonical validation room (FORMULAS.md Part A)
void plastic wall 0 0 5 0.5 0.5 0.5 0 0
void plastic ceiling 0 0 5 0.7 0.7 0.7 0 0
void plastic floor 0 0 5 0.2 0.2 0.2 0 0
void light panel 0 0 3 {r} {r} {r}
floor polygon f 0 0 12 0 0 0  0 4 0  6 4 0  6 0 0
ceiling polygon c 0 0 12 0 0 3  6 0 3  6 4 3  0 4 3
wall polygon w1 0 0 12 0 0 0  6 0 0  6 0 3  0 0 3
wall polygon w2 0 0 12 0 4 0  0 4 3  6 4 3  6 4 0
wall polygon w3 0 0 12 0 0 0  0 0 3  0 4 3  0 4 0
wall polygon w4 0 0 12 6 0 0  6 4 0  6 4 3  6 0 3
panel polygon p1 0 0 12 1.2 0.7 2.99  1.2 1.3 2.99  1.8 1.3 2.99  1.8 0.7 2.99
panel polygon p2 0 0 12 1.2 2.7 2.99  1.2 3.3 2.99  1.8 3.3 2.99  1.8 2.7 2.99
panel polygon p3 0 0 12 4.2 0.7 2.99  4.2 1.3 2.99  4.8 1.3 2.99  4.8 0.7 2.99
panel polygon p4 0 0 12 4.2 2.7 2.99  4.2 3.3 2.99  4.8 3.3 2.99  4.8 2.7 2.99
"""


#: Variants of :func:`material_room_rad`.
MATERIAL_ROOMS = ("glossy floor", "smooth floor", "metal panel", "mirror", "glass partition", "curved shapes")

_METAL = ("void metal alu 0 0 5 0.8 0.8 0.8 0.9 0.1\n"
          "alu polygon m1 0 0 12 3 0.01 0.3  3 0.01 2.5  1 0.01 2.5  1 0.01 0.3\n")
_MIRROR = ("void mirror mir 0 0 3 0.9 0.9 0.9\n"
           "mir polygon m2 0 0 12 3.2 0.01 0.3  3.2 0.01 2.5  5 0.01 2.5  5 0.01 0.3\n")
_SHAPES = ("void plastic glossy_ball 0 0 5 0.6 0.6 0.6 0.04 0.08\n"
           "glossy_ball sphere ball 0 0 4 2 1.5 0.5 0.5\n"
           "void metal steel 0 0 5 0.7 0.7 0.7 0.8 0.15\n"
           "steel cylinder post 0 0 7 4 2.5 0  4 2.5 2.99  0.15\n")


def material_room_rad(variant):
    """The canonical room with non-Lambertian surfaces, in Radiance's scene language, and a
    view of them: ``(text, eye, line_of_sight)``.

    ``variant`` (:data:`MATERIAL_ROOMS`, or ``"metal and mirror"`` for both panels):

    * ``glossy floor``: the floor as ``plastic`` of specularity 0.05, roughness 0.05;
    * ``smooth floor``: the floor as perfectly smooth ``plastic`` of specularity 0.05 (roughness
      0: a mirror reflection raised by Radiance's Fresnel factor, which also weights its
      diffuse part), seen from the glossy floor's eye, the panels as ``glow`` of the same
      luminance (radius 0): Radiance's ambient rays skip ``light`` sources, so the panels'
      light that the floor mirrors onto the ceiling would be missing from a Radiance
      reference (``rtrace -I`` at the ceiling's centre: 86.7 lx with ``light`` panels, 93.7 ± 1.0
      lx with ``glow``);
    * ``metal panel``: a 2 × 2.2 m ``metal`` panel (grey 0.8, specularity 0.9, roughness 0.1)
      1 cm in front of the wall y = 0;
    * ``mirror``: a 1.8 × 2.2 m ``mirror`` (0.9) there;
    * ``glass partition``: a ``glass`` pane (transmissivity 0.96) across the room at x = 3,
      the room lit by a luminous ceiling of ``glow`` (1 W·sr⁻¹·m⁻², radius 0) instead of the
      panels: Radiance's ambient rays ignore light sources and glass relays none (only
      mirrors have virtual sources), so the panels' reflections in the pane would be missing
      from a Radiance reference, while a glow ceiling is seen by its rays like any surface;
    * ``curved shapes``: a ``sphere`` of glossy ``plastic`` (grey 0.6, specularity 0.04,
      roughness 0.08, radius 0.5 m) on the floor and a ``cylinder`` of ``metal`` (grey 0.7,
      specularity 0.8, roughness 0.15, radius 0.15 m) from floor to ceiling.

    Examples
    --------
    >>> text, eye, sight = material_room_rad("mirror")
    >>> "void mirror" in text, eye
    (True, (3.0, 3.5, 1.4))
    """
    room = canonical_room_rad()
    if variant == "glossy floor":
        return (room.replace("void plastic floor 0 0 5 0.2 0.2 0.2 0 0",
                             "void plastic floor 0 0 5 0.2 0.2 0.2 0.05 0.05"), (1.0, 2.0, 1.5), (1.2, -0.3, -1.5))
    if variant == "smooth floor":
        room = room.replace("void plastic floor 0 0 5 0.2 0.2 0.2 0 0", "void plastic floor 0 0 5 0.2 0.2 0.2 0.05 0")
        return re.sub(r"void light panel 0 0 3 (\S+) (\S+) (\S+)", r"void glow panel 0 0 4 \1 \2 \3 0", room), \
            (1.0, 2.0, 1.5), (1.2, -0.3, -1.5)
    panels = {"metal panel": _METAL, "mirror": _MIRROR, "metal and mirror": _METAL + _MIRROR}
    if variant in panels:
        return room + panels[variant], (3.0, 3.5, 1.4), (0.0, -1.0, -0.1)
    if variant == "glass partition":
        room = "\n".join(line for line in room.splitlines()
                         if "panel" not in line and "ceiling polygon" not in line)
        return (room + "\nvoid glow lum 0 0 4 1 1 1 0\nlum polygon c 0 0 12 0 0 3  0 4 3  6 4 3  6 0 3\n"
                "void glass gl 0 0 3 0.96 0.96 0.96\n"
                "gl polygon g1 0 0 12 3 0 0  3 4 0  3 4 3  3 0 3\n"), (1.0, 2.0, 1.5), (1.0, 0.3, -0.3)
    if variant == "curved shapes":
        return room + _SHAPES, (0.5, 3.2, 1.6), (1.0, -0.4, -0.3)
    raise ValueError(f"unknown material room {variant!r}; valid: {', '.join(MATERIAL_ROOMS)}")
