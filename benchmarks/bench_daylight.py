"""Daylight in a room: the cost and the noise of the sun's and the sky's light indoors.

The worked example ``data_samples/radiance/daylit_room.rad`` (4 × 3 × 2.7 m, a 2 × 1.2 m
south window opening, gensky's sun and sky with the sky and ground glows). Measured:

* the light chains: CPU time of ``simulate`` for 2¹⁷ and 2¹⁹ chains (most of them hit the
  room's outside: the chains enter through the scene's bounding sphere);
* the direct sky light at three work-plane points out of the sun (next-event estimation
  through the window): for s shadow rays per source, the observed relative standard
  deviation over 20 seeds, the mean reported σ/E and the CPU time per point.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_daylight.py [--seeds 20]
"""

import argparse
import time
from pathlib import Path

import numpy as np

from lsadphoto.solver import read_scene, simulate
from lsadphoto.solver.direct import direct_illuminance
from lsadphoto.solver.engine import engine_for

ROOM = Path(__file__).resolve().parents[1] / "data_samples" / "radiance" / "daylit_room.rad"
POINTS = np.array([[1, 1.5, .8], [2, 2.0, .8], [3, 2.5, .8]])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    args = parser.parse_args()
    scene = read_scene(ROOM)
    engine = engine_for(scene)
    for chains in (2 ** 17, 2 ** 19):
        t0 = time.process_time()
        store = simulate(scene, samples=chains, seed=1)
        print(f"simulate {chains} chains: {time.process_time() - t0:.1f} s CPU, {store.nodes} nodes")
    up = np.tile([0, 0, 1.0], (len(POINTS), 1))
    print("| shadow rays per source | observed σ/E (3 points) | mean reported σ/E | CPU per point [ms] |")
    print("|---|---|---|---|")
    for s in (64, 256, 1024, 4096):
        t0 = time.process_time()
        runs = [direct_illuminance(scene, engine, POINTS, up, samples=s, seed=k) for k in range(args.seeds)]
        cpu = (time.process_time() - t0) / (args.seeds * len(POINTS))
        E = np.array([e for e, _ in runs])
        reported = np.mean([np.sqrt(v) / e for e, v in runs], axis=0)
        observed = E.std(axis=0, ddof=1) / E.mean(axis=0)
        print(f"| {s} | {', '.join(f'{o:.3f}' for o in observed)} | {', '.join(f'{r:.3f}' for r in reported)} "
              f"| {1e3 * cpu:.1f} |")


if __name__ == "__main__":
    main()
