"""Per-pixel accuracy of the surface cache on the generated station hall (issue 13).

The hall of :func:`lsadphoto.datasets.hall.make_station_hall` is simulated, its surface
cache built and one fisheye view rendered from it (``render_cached``); a random subset of
its pixels is compared with an unbiased per-pixel reference made without any cache: at the
pixel's own hit point (pixels that see a surface, not a luminous opening), L_e + ρ/π·(E_dir + E_ind) with E_dir from every luminaire
(``luminaires="all"``, 16 shadow samples) and E_ind by the double local estimate with
``--ref-nodes`` node draws at that very point from an independent simulation (seed 1000).
Printed: the mean absolute relative error (MARE) with the reference's own noise taken out
in quadrature, the median and 95th percentile of the cache's self-reported per-pixel
relative errors, the share of pixels with |z| > 3 (z = difference / combined standard
error), the mean signed error, and the CPU time of each step.

    PYTHONPATH=. .venv/bin/python benchmarks/accuracy_station_hall.py [--size 256] [--pixels 400]
        [--samples 65536] [--cache-nodes 2048] [--spacing auto] [--detail 1] [--luminaires 120]
"""

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np
from _reference import pixel_reference

from lsadphoto.datasets.hall import make_station_hall
from lsadphoto.solver import load_scene, simulate
from lsadphoto.solver.integrators.eye import luminous_openings
from lsadphoto.solver.integrators.surface_cache import (
    build_surface_cache,
    render_cached,
)


def reference(scene, view, pixels, *, chains, nodes, seed=1000):
    """Flat pixel indices, L_ref [cd·m⁻²] and σ_ref of ``pixels`` random lit pixels
    (:func:`_reference.pixel_reference`, direct light from every luminaire)."""
    def random_lit(valid, prim, dist, d):
        # pixels that see a reflecting surface, not a luminaire's luminous opening in front of it
        seen = ~np.isfinite(luminous_openings(scene, view.position, d, dist))
        hit = np.flatnonzero((prim >= 0) & (scene.triangle_reflectance[np.maximum(prim, 0)] > 0) & seen)
        return np.sort(np.random.default_rng(seed).choice(hit, min(pixels, hit.size), replace=False))

    return pixel_reference(scene, view, random_lit, chains=chains, nodes=nodes, direct_samples=16,
                           luminaires="all", seed=seed)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--detail", type=float, default=1.0)
    ap.add_argument("--luminaires", type=int, default=120)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--pixels", type=int, default=400)
    ap.add_argument("--samples", type=int, default=65536)
    ap.add_argument("--cache-nodes", type=int, default=2048)
    ap.add_argument("--spacing", default="auto")
    ap.add_argument("--ref-nodes", type=int, default=32768)
    ap.add_argument("--view", default="along")
    ap.add_argument("--workers", type=int, default=1)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        scene = load_scene(make_station_hall(Path(tmp) / "hall", luminaires=a.luminaires,
                                             detail=a.detail, view_size=a.size))
    view = next(v for v in scene.views if v.name == a.view)
    c0 = time.process_time()
    store = simulate(scene, samples=a.samples, seed=0)
    c1 = time.process_time()
    cache = build_surface_cache(store, nodes=a.cache_nodes, workers=a.workers,
                                spacing=None if a.spacing == "auto" else float(a.spacing))
    c2 = time.process_time()
    lmap = render_cached(store, view.projection, position=view.position, rotation=view.rotation,
                         cache=cache, workers=a.workers)
    c3 = time.process_time()
    idx, ref, ref_sigma = reference(scene, view, a.pixels, chains=4 * a.samples, nodes=a.ref_nodes)
    c4 = time.process_time()
    got = lmap.luminance.ravel()[idx].astype(float)
    sigma = lmap.uncertainty.ravel()[idx].astype(float)
    ok = ref > 1e-3 * np.median(ref)
    rel = (got - ref)[ok] / ref[ok]
    mare = float(np.mean(np.abs(rel)))
    ref_mare = 0.798 * float(np.mean(ref_sigma[ok] / ref[ok]))
    z = (got - ref)[ok] / np.hypot(sigma, ref_sigma)[ok]
    p = lmap.provenance
    print(f"hall: {len(scene.triangles)} triangles, {a.luminaires} luminaires; view {a.view!r} "
          f"at {a.size}²; {ok.sum()} reference pixels")
    print(f"CPU [s]: simulate {c1 - c0:.1f}, cache {c2 - c1:.1f} ({cache.size} points: "
          f"{cache.provenance['grid_points']} grid, {cache.provenance['leaf_patches']} leaf patches), "
          f"render {c3 - c2:.1f}, reference {c4 - c3:.1f}")
    print(f"MARE {100 * mare:.2f} % (reference noise removed: "
          f"{100 * math.sqrt(max(mare ** 2 - ref_mare ** 2, 0)):.2f} %; reference's own {100 * ref_mare:.2f} %); "
          f"mean signed {100 * rel.mean():+.2f} %; |rel| p95 {100 * np.percentile(np.abs(rel), 95):.1f} %")
    print(f"self-reported per-pixel error median {100 * p['pixel_relative_error_median']:.2f} % / "
          f"p95 {100 * p['pixel_relative_error_p95']:.2f} %; |z| > 3: {100 * np.mean(np.abs(z) > 3):.1f} % "
          f"of pixels; median |z| {np.median(np.abs(z)):.2f} (0.67 for pure noise)")


if __name__ == "__main__":
    main()
