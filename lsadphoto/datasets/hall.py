"""A station hall at the scale of a real one, for the solver's scale benchmarks (issue 13).

``make_station_hall(folder)`` writes ``hall.toml`` and its files: a hall of
``length`` × ``width`` m (default 60 × 20) with vertical walls to 6 m under a barrel vault
(a triangulated half-cylinder, ``vault.obj``), rows of round columns (``columns.obj``,
tessellated cylinders), benches (boxes) and ``luminaires`` point luminaires in rows under
the vault springing, all with one photometric file (``luminaire.ies``: I = I₀·cos²γ with
a 0.6 × 0.6 m luminous opening, written by :func:`~lsadphoto.datasets.design.write_ies_cosine`;
or a real IES file given as ``photometry``). The vault's and the columns' tessellation sets
the triangle count: the defaults give ≈ 68 000 triangles; ``detail`` scales the number of
segments per axis (triangles ∝ detail²), ``luminaires`` the light count, so that the
benchmark can grow each by 4×. Two observer views (180° equidistant fisheyes at 1.6 m, one
along the hall, one across) are in the scene.
"""

import math
import shutil
import sys
from pathlib import Path

import numpy as np
import tomli_w

from .design import write_ies_cosine

__all__ = ["make_station_hall"]

#: Wall height [m] and vault rise [m] above it.
WALL_HEIGHT, VAULT_RISE = 6.0, 4.0


def _write_obj(path, vertices, faces):
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    Path(path).write_text("\n".join(lines) + "\n", encoding="ascii")


def _vault(length, width, n_along, n_around):
    """Triangles of a half-elliptic barrel vault over x ∈ [0, length], facing down (inward)."""
    xs = np.linspace(0.0, length, n_along + 1)
    phi = np.linspace(0.0, math.pi, n_around + 1)
    ys = width / 2 * (1 - np.cos(phi))
    zs = WALL_HEIGHT + VAULT_RISE * np.sin(phi)
    vertices = [(x, y, z) for x in xs for y, z in zip(ys, zs, strict=True)]
    faces = []
    stride = n_around + 1
    for i in range(n_along):
        for j in range(n_around):
            a, b = i * stride + j, i * stride + j + 1
            c, d = a + stride, b + stride
            faces += [(a, c, b), (b, c, d)]  # normals towards the hall's axis (downwards)
    return vertices, faces


def _end_wall(x, width, n_around, sign):
    """The end wall at ``x``: floor edge, walls and the vault's profile (front towards +x
    for ``sign`` = +1)."""
    phi = np.linspace(0.0, math.pi, n_around + 1)
    profile = [[x, width / 2 * (1 - math.cos(p)), WALL_HEIGHT + VAULT_RISE * math.sin(p)] for p in phi]
    outline = [[x, 0.0, 0.0]] + profile + [[x, width, 0.0]]
    return outline[::-1] if sign > 0 else outline


def _columns(length, width, *, rows, per_row, radius, height, segments, stacks):
    """Triangles of round columns (outward normals), ``stacks`` rings high."""
    vertices, faces = [], []
    ys = [width * (k + 1) / (rows + 1) for k in range(rows)]
    xs = [length * (i + 0.5) / per_row for i in range(per_row)]
    angle = np.linspace(0.0, 2 * math.pi, segments, endpoint=False)
    zs = np.linspace(0.0, height, stacks + 1)
    for y0 in ys:
        for x0 in xs:
            base = len(vertices)
            vertices += [(x0 + radius * math.cos(a), y0 + radius * math.sin(a), z)
                         for z in zs for a in angle]
            for s in range(stacks):
                for k in range(segments):
                    a = base + s * segments + k
                    b = base + s * segments + (k + 1) % segments
                    faces += [(a, b, a + segments), (b, b + segments, a + segments)]
    return vertices, faces


def make_station_hall(folder, *, length=60.0, width=20.0, luminaires=120, detail=1.0,
                      photometry=None, view_size=256):
    """Write the hall scene into ``folder``; returns the path of ``hall.toml``.

    Parameters
    ----------
    length, width : float
        Floor size [m].
    luminaires : int
        Point luminaires, in four rows at 5.5 m, 2 m inside the walls and the columns' lines.
    detail : float
        Tessellation scale: ≈ 68 000 triangles at 1, ∝ detail².
    photometry : path, optional
        A real IES/EULUMDAT file for every luminaire (copied beside the scene); default a
        synthetic cos²γ file of 3000 lm.
    view_size : int
        Pixels per side of the two fisheye views.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    n_along, n_around = max(2, round(300 * detail)), max(2, round(80 * detail))
    _write_obj(folder / "vault.obj", *_vault(length, width, n_along, n_around))
    _write_obj(folder / "columns.obj", *_columns(length, width, rows=2, per_row=20, radius=0.4,
                                                 height=WALL_HEIGHT,
                                                 segments=max(6, round(24 * detail)),
                                                 stacks=max(1, round(8 * detail))))
    if photometry is None:
        write_ies_cosine(folder / "luminaire.ies", exponent=2, flux=3000.0, length=0.6, width=0.6,
                         name="hall luminaire")
        phot = "luminaire.ies"
    else:
        phot = Path(photometry).name
        shutil.copy(photometry, folder / phot)
    rows = (2.0, width / 3 + 0.8, 2 * width / 3 - 0.8, width - 2.0)
    # Bench rows between the hall's axis and the column rows (y = width/3, 2·width/3, radius
    # 0.4): 1.5 m off the axis, as in the 20 m hall, closer in narrower halls so that they
    # clear the columns down to 8 m width (at 10 m, rows at ±1.5 m ran through the columns).
    bench_off = min(1.5, width / 12)
    per_row = math.ceil(luminaires / len(rows))
    lights = [{"type": "point", "name": f"l{r}_{i}", "photometry": phot,
               "position": [length * (i + 0.5) / per_row, y, 5.5]}
              for r, y in enumerate(rows) for i in range(per_row)][:luminaires]
    fisheye = {"model": "fisheye-ideal", "kind": "equidistant", "fov_deg": 180,
               "width": view_size, "height": view_size}
    scene = {
        "scene": {"name": f"station hall {length:g} × {width:g} m, {luminaires} luminaires"},
        "materials": {"floor": {"reflectance": 0.3}, "wall": {"reflectance": 0.5},
                      "vault": {"reflectance": 0.6}, "stone": {"reflectance": 0.4},
                      "bench": {"reflectance": 0.25}},
        "surfaces": [
            {"type": "polygon", "material": "floor",
             "vertices": [[0.0, 0.0, 0.0], [length, 0.0, 0.0], [length, width, 0.0], [0.0, width, 0.0]]},
            {"type": "polygon", "material": "wall",
             "vertices": [[0.0, 0.0, 0.0], [0.0, 0.0, WALL_HEIGHT], [length, 0.0, WALL_HEIGHT], [length, 0.0, 0.0]]},
            {"type": "polygon", "material": "wall",
             "vertices": [[0.0, width, 0.0], [length, width, 0.0], [length, width, WALL_HEIGHT], [0.0, width, WALL_HEIGHT]]},
            # end walls up to the vault: its profile at x = 0 and x = length (planar, convex)
            {"type": "polygon", "material": "wall", "vertices": _end_wall(0.0, width, n_around, +1)},
            {"type": "polygon", "material": "wall", "vertices": _end_wall(length, width, n_around, -1)},
            {"type": "mesh", "file": "vault.obj", "material": "vault"},
            {"type": "mesh", "file": "columns.obj", "material": "stone"},
        ] + [{"type": "box", "material": "bench", "facing": "outward",
              "min": [length * (i + 0.5) / 10 - 1.0, y - 0.25, 0.0],
              "max": [length * (i + 0.5) / 10 + 1.0, y + 0.25, 0.45]}
             for i in range(10) for y in (width / 2 - bench_off, width / 2 + bench_off)],
        "luminaires": lights,
        "views": [
            {"name": "along", "position": [3.0, width / 2, 1.6], "line_of_sight": [1.0, 0.0, 0.0],
             "projection": fisheye},
            {"name": "across", "position": [length / 2 + 2.0, 1.5, 1.6],
             "line_of_sight": [0.0, 1.0, 0.0], "projection": fisheye},
        ],
    }
    path = folder / "hall.toml"
    path.write_text(tomli_w.dumps(scene), encoding="utf-8")
    return path


if __name__ == "__main__":
    print(make_station_hall(sys.argv[1] if len(sys.argv) > 1 else "hall"))
