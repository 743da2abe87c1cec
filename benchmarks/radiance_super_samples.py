"""Radiance's pixel values against its own irradiance, with and without ambient super-samples.

A reference made with ``rtrace -aa 0`` must be unbiased. This script checks Radiance against
itself: at the hit points of random rays in the daylit room of ``data_samples/radiance``, the
radiance of the ray (a Lambertian surface of reflectance ρ) must equal ρ/π times rtrace's
``-I`` irradiance at the same point and normal. With Radiance's default adaptive ambient
super-samples (``-as 512``) it does not (docs/accuracy.md, "Unbiased Radiance references");
with :data:`lsadphoto.solver.formats.radiance.RTRACE_UNBIASED` it does.

    PYTHONPATH=. .venv/bin/python benchmarks/radiance_super_samples.py [--rays 40] [--runs 8]
"""

import argparse
import os
import subprocess
from pathlib import Path

import numpy as np

from lsadphoto.solver.formats.radiance import RTRACE_UNBIASED, radiance_programs

ROOM = Path(__file__).resolve().parents[1] / "data_samples" / "radiance"
#: Diffuse reflectances of the room's materials (plastic, specularity 0).
RHO = {"wall_white": 0.5, "floor_grey": 0.2, "ceiling_white": 0.7}
OPTIONS = {"Radiance's defaults (-as 512), -lw 1e-5": ("-aa", "0", "-lw", "1e-5", "-dj", "0"),
           "RTRACE_UNBIASED (-as 0 -lw 1e-9)": RTRACE_UNBIASED}


def _rtrace(binpath, env, octree, args, text):
    out = subprocess.run([str(binpath / "rtrace"), "-h", *args, str(octree)], input=text, capture_output=True,
                         text=True, cwd=ROOM, env=env, check=True).stdout
    return np.array(out.split(), float)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rays", type=int, default=40)
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--ab", type=int, default=8)
    ap.add_argument("--ad", type=int, default=1024)
    a = ap.parse_args()
    binpath = radiance_programs()
    if binpath is None:
        raise SystemExit("pyradiance's Radiance programs are needed")
    env = dict(os.environ, PATH=f"{binpath}{os.pathsep}{os.environ['PATH']}", RAYPATH=str(binpath.parent / "lib"))
    octree = Path(os.environ.get("TMPDIR", "/tmp")) / "daylit_room_super_samples.oct"
    octree.write_bytes(subprocess.run([str(binpath / "oconv"), "daylit_room.rad"], capture_output=True, cwd=ROOM,
                                      env=env, check=True).stdout)
    rng = np.random.default_rng(3)
    d = rng.normal(size=(a.rays, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    origin = np.array([2.0, 2.2, 1.2])
    rays = "".join(" ".join(f"{v:.6f}" for v in (*origin, *u)) + "\n" for u in d)
    hits = subprocess.run([str(binpath / "rtrace"), "-h", "-opNm", "-ab", "0", str(octree)], input=rays,
                          capture_output=True, text=True, cwd=ROOM, env=env, check=True).stdout.splitlines()
    keep, points, rho = [], [], []
    for i, line in enumerate(hits):
        f = line.split()
        if len(f) < 7 or f[6] not in RHO:
            continue  # the sky through the window, or a ray that left the room
        n = np.array(f[3:6], float)
        n = -n if n @ d[i] > 0 else n  # the side the ray came from
        keep.append(i)
        points.append((*(np.array(f[:3], float) + 1e-4 * n), *n))
        rho.append(RHO[f[6]])
    rho = np.array(rho)
    ptext = "".join(" ".join(f"{v:.6f}" for v in p) + "\n" for p in points)
    rtext = "".join(rays.splitlines(True)[i] for i in keep)
    depth = ("-ab", str(a.ab), "-ad", str(a.ad))
    print(f"{len(keep)} room pixels of {a.rays} rays, {a.runs} runs each, rtrace {' '.join(depth)}")
    print("| rtrace options | pixel / (ρ/π·E_I), median | mean ± s.e. | rms z |\n|---|---|---|---|")
    for label, options in OPTIONS.items():
        e = _rtrace(binpath, env, octree, ["-I", *depth, *options], ptext * a.runs).reshape(a.runs, -1, 3)[..., 0]
        lum = _rtrace(binpath, env, octree, [*depth, *options], rtext * a.runs).reshape(a.runs, -1, 3)[..., 0]
        ratio = lum.mean(0) / (rho / np.pi * e.mean(0))
        rel = np.hypot(lum.std(0, ddof=1) / lum.mean(0), e.std(0, ddof=1) / e.mean(0)) / np.sqrt(a.runs)
        z = (ratio - 1) / (rel * ratio)
        print(f"| {label} | {np.median(ratio):.4f} | {ratio.mean():.4f} ± {ratio.std(ddof=1) / np.sqrt(len(ratio)):.4f} "
              f"| {np.sqrt(np.mean(z ** 2)):.2f} |")


if __name__ == "__main__":
    main()
