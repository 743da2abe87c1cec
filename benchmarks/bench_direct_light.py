"""Direct light from many luminaires: every luminaire against importance-sampled luminaires.

A hall floor (60 × 20 m, 1 m columns every 4 m that shadow it) under N isotropic point
luminaires at 5 m in three rows (points, or emitting from 0.6 × 0.6 m luminous rectangles as
IES luminaires do); P random floor points. For each N: CPU time of
``direct_illuminance`` with ``luminaires="all"`` (exact per point: one shadow ray per point
luminaire) and with the default ``"auto"`` (all up to 8 luminaires, else 32 draws per point
besides the luminaires taken whole, weighing 16 candidates per region), and the sampled estimate's relative error against
the exact one (RMS over points).

    PYTHONPATH=. .venv/bin/python benchmarks/bench_direct_light.py [--points 65536] [--lights 8,30,120,480]
"""

import argparse
import time

import numpy as np

from lsadphoto.solver import scene_from_dict
from lsadphoto.solver.direct import direct_illuminance
from lsadphoto.solver.engine import engine_for


def hall(n_lights, extent=None):
    rows = 3
    per_row = -(-n_lights // rows)
    lights = [{"type": "point", "intensity": 300.0,
               "position": [60.0 * (i + 0.5) / per_row, 5.0 + 5.0 * r, 5.0],
               **({"extent": list(extent)} if extent else {})}
              for r in range(rows) for i in range(per_row)][:n_lights]
    surfaces = [{"type": "polygon", "material": "grey",
                 "vertices": [[0, 0, 0], [60, 0, 0], [60, 20, 0], [0, 20, 0]]}]
    surfaces += [{"type": "box", "material": "grey", "min": [4.0 * k + 1.5, y - 0.5, 0],
                  "max": [4.0 * k + 2.5, y + 0.5, 4.5]} for k in range(15) for y in (7.5, 12.5)]
    return scene_from_dict({"materials": {"grey": {"reflectance": 0.5}}, "surfaces": surfaces,
                            "luminaires": lights})


def cpu(f):
    t0 = time.process_time()
    out = f()
    return out, time.process_time() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=65536)
    ap.add_argument("--lights", default="8,30,120,480")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(0.2, 59.8, args.points), rng.uniform(0.2, 19.8, args.points),
                           np.zeros(args.points)])
    nrm = np.tile([0.0, 0.0, 1.0], (args.points, 1))
    print("| luminaires | luminous rectangle | all: CPU [s] | auto: CPU [s] | speed-up | "
          "auto: RMS relative error | auto: mean reported σ/E |")
    print("|---|---|---|---|---|---|---|")
    for n, extent in ((int(v), e) for v in args.lights.split(",") for e in (None, (0.6, 0.6))):
        scene = hall(n, extent)
        engine = engine_for(scene)
        direct_illuminance(scene, engine, pts[:256], nrm[:256])  # compile, build the BVH
        blocks = np.arange(args.points) // 256
        (exact, _), t_all = cpu(lambda s=scene, e=engine, b=blocks: direct_illuminance(
            s, e, pts, nrm, luminaires="all", block_ids=b))
        (est, var), t_auto = cpu(lambda s=scene, e=engine, b=blocks: direct_illuminance(
            s, e, pts, nrm, block_ids=b))
        lit = exact > 0  # "all" is exact for points, 4 rays per rectangle (a reference too)
        rms = float(np.sqrt(np.mean(((est[lit] - exact[lit]) / exact[lit]) ** 2)))
        sigma = float(np.mean(np.sqrt(var[lit]) / exact[lit]))
        rect = "0.6 × 0.6 m" if extent else "none (a point)"
        print(f"| {n} | {rect} | {t_all:.2f} | {t_auto:.2f} | {t_all / t_auto:.1f}× | {rms:.4f} | {sigma:.4f} |")


if __name__ == "__main__":
    main()
