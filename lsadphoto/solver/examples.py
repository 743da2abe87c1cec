"""Example scenes: the canonical validation room of FORMULAS.md Part A.

A closed box room 6 m × 4 m × 3 m; Lambertian grey walls ρ = 0.5, ceiling 0.7, floor 0.2;
four square 0.6 m × 0.6 m Lambertian luminaires of 3000 lm each, centred at (1.5, 1),
(1.5, 3), (4.5, 1), (4.5, 3) m and facing down; the observer's eye at (1.0, 2.0, 1.2) m
looking along +x, horizontal, up +z; a 180° equidistant fisheye view. The luminaires hang
1 cm below the ceiling (z = 2.99 m): coplanar emitter and ceiling triangles would make the
first hit ambiguous in float32; their backs are black.
"""

from .scene import scene_from_dict

__all__ = ["canonical_room", "canonical_room_toml"]

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
