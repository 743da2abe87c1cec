"""Time of the material local estimate (simulate + render_local_estimate_materials) on the glossy-floor room.

The canonical room with a glossy floor (:func:`lsadphoto.solver.examples.material_room_rad`),
a 24² pinhole view, 131 072 light chains and 256 nodes per pixel, run twice; prints wall and
CPU time and the map's mean, and with ``--save`` writes the map and its per-pixel errors
(for a statistical comparison of two versions: z = Δ/√(σ₁² + σ₂²) per pixel).

Run (2-core machine; for an older version check it out and leave out ``--rays-per-vertex``,
which it does not have)::

    python benchmarks/bench_material_render.py --rays-per-vertex 16 --save /tmp/now.npy
"""

import argparse
import math
import time

import numpy as np

from lsadphoto.geometry.pinhole import PinholeProjection
from lsadphoto.solver import read_radiance_scene, simulate
from lsadphoto.solver.examples import material_room_rad
from lsadphoto.solver.integrators.local_estimate import render_local_estimate_materials
from lsadphoto.solver.scene import camera_to_world


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=24)
    parser.add_argument("--chains", type=int, default=131072)
    parser.add_argument("--nodes-per-pixel", type=int, default=256)
    parser.add_argument("--rays-per-vertex", type=int)
    parser.add_argument("--save")
    args = parser.parse_args(argv)
    rad, eye, sight = material_room_rad("glossy floor")
    scene = read_radiance_scene(rad)
    focal = args.size / (2 * math.tan(math.radians(35)))
    proj = PinholeProjection(fx=focal, fy=focal, cx=(args.size - 1) / 2, cy=(args.size - 1) / 2, width=args.size,
                             height=args.size)
    options = {} if args.rays_per_vertex is None else {"rays_per_vertex": args.rays_per_vertex}
    for _ in range(2):
        wall, cpu = time.perf_counter(), time.process_time()
        lmap = render_local_estimate_materials(simulate(scene, samples=args.chains, seed=1), proj,
                                               position=np.asarray(eye, float), rotation=camera_to_world(sight),
                                               nodes_per_pixel=args.nodes_per_pixel, seed=1, **options)
        print(f"wall {time.perf_counter() - wall:.1f} s, CPU {time.process_time() - cpu:.1f} s, "
              f"mean {float(np.nanmean(lmap.luminance)):.4f} cd/m²", flush=True)
    if args.save:
        np.save(args.save, np.stack([np.asarray(lmap.luminance, float), np.asarray(lmap.uncertainty, float)]))


if __name__ == "__main__":
    main()
