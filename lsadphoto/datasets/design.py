"""The worked design example: an office/vestibule, a catalogue of IES files, candidate positions.

``python -m lsadphoto.datasets.design data_samples/design`` writes:

- ``space.toml``: a 6 × 4 × 3 m room (walls ρ = 0.5, ceiling 0.7, floor 0.2) with two
  observer views (180° fisheyes at eye height, 64 × 64 px);
- ``downlight.ies``, ``spot.ies``, ``panel.ies``: IES LM-63-2002 files with rotationally
  symmetric I(γ) = I₀·cosⁿγ (n = 2, 8, 1) and luminous openings of 0.2 × 0.2, 0.1 × 0.1 and
  0.6 × 0.6 m — the kind of file a manufacturer publishes, made here so that the answer is
  known (Φ = 2π·I₀/(n + 1));
- ``problem.toml``: six candidate ceiling positions, the three types on or off (4⁶ = 4096
  designs, searched by NSGA-II), a work-plane grid, objectives (min grouped UGR over both
  views, min power) and constraints (Ē ≥ 300 lx, U₀ ≥ 0.4, UGR ≤ 22).

References
----------
ANSI/IESNA LM-63-02 (2002) file format.
"""

import math
import sys
from pathlib import Path

import numpy as np
import tomli_w

__all__ = ["make_design_samples", "write_ies_cosine"]

#: (name, exponent n, flux [lm], opening length × width [m], power [W]).
CATALOGUE = (("downlight", 2, 1500.0, (0.2, 0.2), 15.0),
             ("spot", 8, 900.0, (0.1, 0.1), 9.0),
             ("panel", 1, 3000.0, (0.6, 0.6), 30.0))


def write_ies_cosine(path, *, exponent, flux, length, width, name="luminaire"):
    """Write an IES LM-63-2002 file of I(γ) = I₀·cosⁿγ (γ ≤ 90°, 0 above) with flux Φ [lm].

    I₀ = Φ·(n + 1)/(2π) [cd]; vertical angles every 5°, one horizontal angle (rotational
    symmetry), absolute photometry (lumens per lamp −1), dimensions in metres.
    """
    i0 = flux * (exponent + 1) / (2 * math.pi)
    gamma = np.arange(0, 181, 5.0)
    cd = np.where(gamma <= 90, i0 * np.cos(np.radians(np.minimum(gamma, 90))) ** exponent, 0.0)
    cd[gamma == 90] = 0.0
    lines = ["IESNA:LM-63-2002", f"[TEST] lsadphoto.datasets.design, I = I0 cos^{exponent}",
             "[MANUFAC] lsadphoto (synthetic)", f"[LUMINAIRE] {name}", "TILT=NONE",
             f"1 -1 1 {len(gamma)} 1 1 2 {width:.3f} {length:.3f} 0.000",
             "1.0 1.0 0.0",
             " ".join(f"{g:g}" for g in gamma), "0",
             " ".join(f"{v:.4f}" for v in cd)]
    Path(path).write_text("\n".join(lines) + "\n", encoding="ascii")


def _space(size):
    fisheye = {"model": "fisheye-ideal", "kind": "equidistant", "fov_deg": 180, "width": size,
               "height": size}
    return {
        "scene": {"name": "design example: office 6 × 4 × 3 m"},
        "materials": {"wall": {"reflectance": 0.5}, "ceiling": {"reflectance": 0.7},
                      "floor": {"reflectance": 0.2}},
        "surfaces": [{"type": "box", "min": [0, 0, 0], "max": [6, 4, 3], "facing": "inward",
                      "material": "wall", "face_materials": {"floor": "floor", "ceiling": "ceiling"}}],
        "views": [
            {"name": "desk", "position": [1.0, 2.0, 1.2], "line_of_sight": [1, 0, 0], "up": [0, 0, 1],
             "projection": fisheye},
            {"name": "door", "position": [5.0, 0.6, 1.6], "line_of_sight": [-1, 0.6, 0], "up": [0, 0, 1],
             "projection": fisheye},
        ],
    }


def _problem(positions):
    return {
        "schema": "lsadphoto.design/1", "name": "office luminaire layout", "space": "space.toml",
        "dimming": [1.0],
        "catalogue": {name: {"photometry": f"{name}.ies", "power_w": power}
                      for name, _, _, _, power in CATALOGUE},
        "positions": [{"position": [x, y, 2.95]} for x, y in positions],
        "grids": [{"name": "work plane", "min": [0.0, 0.0], "max": [6.0, 4.0], "height": 0.8,
                   "border": 0.5, "spacing": 1.0}],
        "objectives": [{"metric": "ugr_grouped", "sense": "min", "view": "all"},
                       {"metric": "power", "sense": "min"}],
        "constraints": [{"metric": "e_m", "grid": "work plane", "min": 300.0},
                        {"metric": "u0", "grid": "work plane", "min": 0.4},
                        {"metric": "ugr_grouped", "view": "all", "max": 22.0}],
        # 4⁶ = 4096 designs: NSGA-II evaluates a few hundred of them, to show the search
        # (enumerating all of them takes about a second with the batch evaluator)
        "search": {"method": "nsga2", "population": 16, "generations": 10, "seed": 0},
        "simulation": {"samples": 8192, "grid_nodes": 512},
    }


def make_design_samples(folder, *, size=64):
    """Write the worked example into ``folder`` (module docstring)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name, n, flux, (length, width), _ in CATALOGUE:
        write_ies_cosine(folder / f"{name}.ies", exponent=n, flux=flux, length=length, width=width, name=name)
    (folder / "space.toml").write_text(tomli_w.dumps(_space(size)), encoding="utf-8")
    positions = [(1.5, 1.0), (1.5, 3.0), (3.0, 1.0), (3.0, 3.0), (4.5, 1.0), (4.5, 3.0)]
    (folder / "problem.toml").write_text(tomli_w.dumps(_problem(positions)), encoding="utf-8")
    return folder


if __name__ == "__main__":
    make_design_samples(sys.argv[1] if len(sys.argv) > 1 else "data_samples/design")
