"""Synthetic metro-station halls with different luminaire layouts, as solver scene models.

Each layout is a scene description in the solver's TOML schema (a dict; see
``docs/user-guide-solver.md``): a hall 30 m × 12 m × 5 m (floor ρ = 0.25, walls 0.45, ceiling
0.6, a darker platform-edge band), lit by Lambertian area luminaires arranged in one of six
ways, from a comfortable indirect scheme to a few very bright small sources. The observer
stands at :data:`OBSERVER` looking down the hall. They feed the bundled demo survey
(``data_samples/stations``): rendered by the solver, photographed by the synthetic camera,
scored, and compared with their own models.
"""

import numpy as np

__all__ = ["HALL", "OBSERVER", "LAYOUTS", "station_scene"]

#: Hall size (x along the hall, y across, z up) [m].
HALL = (30.0, 12.0, 5.0)
#: Observer: eye position [m], line of sight and up (world), horizontal view down the hall.
OBSERVER = {"position": [2.5, 6.0, 1.6], "direction": [1.0, 0.0, -0.08], "up": [0.0, 0.0, 1.0]}


def _rect(x0, x1, y0, y1, z, *, facing="down"):
    """Horizontal rectangle at height z, counter-clockwise seen from the side it faces."""
    pts = [[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]]
    return pts if facing == "up" else pts[::-1]


def _area(name, vertices, *, flux=None, luminance=None):
    entry = {"type": "area", "name": name, "shape": {"type": "polygon", "vertices": vertices}}
    if flux is not None:
        entry["flux"] = float(flux)
    else:
        entry["luminance"] = float(luminance)
    return entry


def _rows(ceiling, *, width=0.15, y_positions=(4.0, 8.0), flux_per_m=1200.0, length=26.0):
    x0 = (HALL[0] - length) / 2
    return [_area(f"row{i}", _rect(x0, x0 + length, y - width / 2, y + width / 2, ceiling),
                  flux=flux_per_m * length) for i, y in enumerate(y_positions)]


def _grid(ceiling, *, nx, ny, size, flux, margin_x=2.0, margin_y=2.0, name="lum"):
    out = []
    xs = np.linspace(margin_x, HALL[0] - margin_x, nx)
    ys = np.linspace(margin_y, HALL[1] - margin_y, ny)
    for i, x in enumerate(xs):
        for j, y in enumerate(ys):
            out.append(_area(f"{name}{i}_{j}", _rect(x - size / 2, x + size / 2, y - size / 2,
                                                     y + size / 2, ceiling), flux=flux))
    return out


def _coves(*, height=4.2, width=0.3, flux_per_m=2500.0, length=26.0):
    """Upward-facing strips along both long walls (indirect light off the ceiling)."""
    x0 = (HALL[0] - length) / 2
    return [_area(f"cove{i}", _rect(x0, x0 + length, y0, y0 + width, height, facing="up"),
                  flux=flux_per_m * length)
            for i, y0 in enumerate((0.2, HALL[1] - 0.2 - width))]


def _layout_luminaires(layout):
    c = HALL[2] - 0.02  # luminaires 2 cm below the ceiling (no coplanar triangles)
    if layout == "rows":
        return _rows(c)
    if layout == "downlights":
        return _grid(c, nx=8, ny=3, size=0.25, flux=2200.0, name="down")
    if layout == "panels":
        return _grid(c, nx=7, ny=3, size=1.2, flux=3600.0, name="panel")
    if layout == "coves":
        return _coves()
    if layout == "mixed":
        return _rows(c, y_positions=(6.0,), flux_per_m=1500.0) + _grid(
            c, nx=6, ny=2, size=0.25, flux=2000.0, margin_y=3.0, name="down")
    if layout == "sparse":
        return _grid(c, nx=4, ny=2, size=0.15, flux=9000.0, margin_y=3.5, name="spot")
    raise ValueError(f"unknown layout {layout!r}")


#: The six layouts, from diffuse to harsh.
LAYOUTS = ("coves", "panels", "rows", "mixed", "downlights", "sparse")


def station_scene(layout):
    """Scene description (dict in the solver's TOML schema) of one station layout."""
    length, width, height = HALL
    return {
        "scene": {"name": f"station hall, {layout}"},
        "materials": {"wall": {"reflectance": 0.45}, "ceiling": {"reflectance": 0.6},
                      "floor": {"reflectance": 0.25}, "edge": {"reflectance": 0.08}},
        "surfaces": [
            {"type": "box", "min": [0.0, 0.0, 0.0], "max": [length, width, height],
             "facing": "inward", "material": "wall",
             "face_materials": {"floor": "floor", "ceiling": "ceiling"}},
            # A dark platform-edge band on the floor, 0.5 m wide, along the right-hand side.
            {"type": "polygon", "material": "edge",
             "vertices": _rect(0.0, length, 2.0, 2.5, 0.005, facing="up")},
        ],
        "luminaires": _layout_luminaires(layout),
    }
