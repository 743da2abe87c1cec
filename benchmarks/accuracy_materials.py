"""Per-pixel accuracy of the material estimators against unbiased Radiance references (issue 14).

Scenes: :func:`lsadphoto.solver.examples.material_room_rad` — the canonical room with a
glossy floor, a smooth (Fresnel-weighted) floor under glow panels, a metal panel, a mirror, a
glass partition (glow ceiling) or curved shapes. One Radiance
file goes to both programs (our :func:`~lsadphoto.solver.read_radiance_scene`, Radiance's
``oconv``). The reference is pure Monte Carlo ``rtrace -aa 0`` (no irradiance cache, so no
interpolation bias) with many ambient samples through the rays of our own pinhole view's
pixel centres, on a random subset of the pixels, **run twice** with the rays in opposite
order (independent noise, PITFALLS.md), each ray traced ``--repeats`` times in a run (rtrace's
ambient samples follow a sequence indexed by the primary ray, so every trace has its own):
the mean of the 2 × repeats traces is the reference, their standard deviation over
√(2 × repeats) its standard error, with 2 × repeats − 1 degrees of freedom. (Half the two
runs' difference, the estimate before session 12, has one: |z| against it is heavy-tailed —
an estimator with an honest σ of a third of the reference's shows only 90 % of its pixels
within 3σ — and its mean is 0.80 of the standard error, which the MARE's correction then
took a second time.) References are kept in ``--cache`` (keyed by scene, view, pixels and
options), so a rerun of the solver side does not repeat them.

For each estimator (``local``: the double local estimate with materials,
:func:`~lsadphoto.solver.integrators.local_estimate.render_local_estimate_materials`, which
:func:`lsadphoto.solver.render` runs for such scenes; ``cache``: the surface cache,
:func:`~lsadphoto.solver.integrators.surface_cache.build_surface_cache` +
:func:`~lsadphoto.solver.integrators.surface_cache.render_cached`, from a simulation of the
same chains; ``path``: :func:`lsadphoto.solver.render_path_traced`) the
table gives: the CPU time (simulation, cache and render together), the field-mean ratio
over the subset with its standard error, the mean absolute relative per-pixel error (MARE)
raw and with the reference's own noise removed in quadrature, the highlight ratio (ours /
reference at the subset's brightest reference pixel), the median self-reported relative
error and its mean, the median |z| (z = (ours − ref) / √(σ_ours² + σ_ref²); 0.674 for a standard normal)
and the share of |z| ≤ 3.

Run (2-core machine)::

    python benchmarks/accuracy_materials.py --variant "glossy floor" --estimators local,cache

``--fresnel-rule radiance`` renders under the smooth materials' Radiance rule
(:data:`~lsadphoto.solver.materials.FRESNEL_RULES`; default ``reciprocal``).

Writes a Markdown fragment with the command to ``--output``.
"""

import argparse
import hashlib
import itertools
import math
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from _clock import Clock

from lsadphoto.constants import RADIANCE_RGB_LUMINANCE_WEIGHTS
from lsadphoto.geometry.pinhole import PinholeProjection
from lsadphoto.solver import read_radiance_scene, render_path_traced, simulate
from lsadphoto.solver.engine import engine_for
from lsadphoto.solver.examples import MATERIAL_ROOMS, material_room_rad
from lsadphoto.solver.formats.radiance import RTRACE_UNBIASED
from lsadphoto.solver.integrators.eye import primary_rays
from lsadphoto.solver.integrators.local_estimate import render_local_estimate_materials
from lsadphoto.solver.integrators.surface_cache import build_surface_cache, render_cached
from lsadphoto.solver.materials import FRESNEL_RULES
from lsadphoto.solver.scene import camera_to_world

#: Radiance's options: pure Monte Carlo (RTRACE_UNBIASED: -aa 0 -as 0 -lw 1e-9), deep (-ab 12), fine source
#: subdivision (-ds 0.005: the lobe widening by a source piece's solid angle is negligible).
#: ``-ss 1`` (one sample per glossy reflection, Radiance's default): with ``-ss 64`` Radiance's
#: glossy reflection came out 9 % darker on the metal panel and 0.6 % on the glossy floor
#: than with ``-ss 1`` (-ds made < 1 % difference), while our path tracer and local estimate
#: agree with each other and with ``-ss 1``; its noise is averaged by ``--repeats``.
RTRACE = " ".join(("-ab 12 -ad 8192", *RTRACE_UNBIASED, "-st 0 -ds 0.005"))


def _radiance():
    import pyradiance

    binpath = os.path.join(os.path.dirname(pyradiance.__file__), "bin")
    env = dict(os.environ, RAYPATH=os.pathsep.join([".", os.path.join(binpath, "..", "lib")]))
    return binpath, env, pyradiance.__version__


def view_of(variant, size):
    """Scene, pinhole projection (70° across), eye position and rotation of a variant."""
    rad, eye, sight = material_room_rad(variant)
    scene = read_radiance_scene(rad)
    focal = size / (2 * math.tan(math.radians(35)))
    proj = PinholeProjection(fx=focal, fy=focal, cx=(size - 1) / 2, cy=(size - 1) / 2, width=size, height=size)
    return rad, scene, proj, np.asarray(eye, float), camera_to_world(sight)


def reference(variant, size, pixels, options, cache, repeats=1):
    """Flat pixel indices, reference [cd·m⁻²], its standard error, rtrace CPU [s] (0 if cached).

    Each of the two runs traces every ray ``repeats`` times; the standard error comes from the
    spread of all 2 × ``repeats`` traces of a ray."""
    rad, scene, proj, pos, rot = view_of(variant, size)
    valid, _, _, d = primary_rays(scene, engine_for(scene), proj, pos, rot)
    pick = np.sort(valid[np.random.default_rng(0).choice(len(valid), min(pixels, len(valid)), replace=False)])
    key = hashlib.sha256(repr((rad, size, pixels, options, pick.tolist())
                              + ((repeats, "traces") if repeats > 1 else ())).encode()).hexdigest()[:16]
    path = Path(cache) / f"materials_{key}.npz"
    if path.exists():
        z = np.load(path)
        return pick, z["ref"], z["ref_se"], 0.0
    binpath, env, _ = _radiance()
    rays = np.ascontiguousarray(np.column_stack([np.tile(pos, (pick.size, 1)), d[np.searchsorted(valid, pick)]]),
                                dtype=np.float32)
    rays = np.repeat(rays, repeats, axis=0)
    with tempfile.TemporaryDirectory() as folder:
        (Path(folder) / "s.rad").write_text(rad)
        with open(Path(folder) / "s.oct", "wb") as fh:
            subprocess.run([os.path.join(binpath, "oconv"), "s.rad"], stdout=fh, cwd=folder, env=env, check=True)
        runs = []
        with Clock() as clock:
            for order in (slice(None), slice(None, None, -1)):
                out = subprocess.run([os.path.join(binpath, "rtrace"), "-h", "-ff", *options.split(), "s.oct"],
                                     input=np.ascontiguousarray(rays[order]).tobytes(), capture_output=True,
                                     cwd=folder, env=env, check=True).stdout
                rgb = np.frombuffer(out, np.float32).reshape(-1, 3).astype(float)
                lum = (179.0 * rgb @ RADIANCE_RGB_LUMINANCE_WEIGHTS)[order]
                runs.append(lum.reshape(-1, repeats))
    traces = np.concatenate(runs, axis=1)
    ref, ref_se = traces.mean(axis=1), traces.std(axis=1, ddof=1) / math.sqrt(traces.shape[1])
    Path(cache).mkdir(parents=True, exist_ok=True)
    np.savez(path, ref=ref, ref_se=ref_se)
    return pick, ref, ref_se, clock.cpu


def summary(ours, sigma, ref, ref_se):
    """Field-mean ratio and its standard error, MARE raw and with the reference's noise
    removed, median and mean relative self-error (the MARE that σ implies is √(2/π) times the
    mean, plus the reference's share), median |z|, share of |z| ≤ 3."""
    rel = np.abs(ours / ref - 1)
    raw = float(np.mean(rel))
    # E|e| of a Gaussian error e is 0.798 σ: the reference's share of the MARE, removed in quadrature
    ref_mae = 0.798 * float(np.mean(ref_se / ref))
    z = (ours - ref) / np.sqrt(sigma ** 2 + ref_se ** 2 + (1e-4 * ref) ** 2)
    field = ours.mean() / ref.mean()
    field_se = math.sqrt((sigma ** 2).sum() + (field ** 2) * (ref_se ** 2).sum()) / ref.sum()
    return {"field": field, "field_se": field_se, "mare": raw,
            "mare_corrected": math.sqrt(max(raw * raw - ref_mae * ref_mae, 0.0)),
            "self": float(np.median(sigma / ours)), "self_mean": float(np.mean(sigma / ours)),
            "median_z": float(np.median(np.abs(z))),
            "highlight": float(ours[np.argmax(ref)] / ref.max()),
            "z3": float(np.mean(np.abs(z) <= 3)), "ref_rel": float(np.mean(ref_se / ref))}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", choices=MATERIAL_ROOMS, action="append")
    parser.add_argument("--size", type=int, default=24)
    parser.add_argument("--pixels", type=int, default=160, help="reference pixels (random subset)")
    parser.add_argument("--rtrace", default=RTRACE)
    parser.add_argument("--repeats", type=int, default=8, help="traces of each reference ray per run")
    parser.add_argument("--estimators", default="local", help="comma-separated: local, cache, path")
    parser.add_argument("--chains", type=int, default=262144, help="light chains of the local estimate")
    parser.add_argument("--nodes-per-pixel", type=int, default=128)
    parser.add_argument("--rays-per-vertex", type=int, default=16)
    parser.add_argument("--paths", type=int, default=4096, help="paths per pixel of the path tracer")
    parser.add_argument("--cache-spacing", type=float, default=1 / 24, help="cache spacing / scene diagonal")
    parser.add_argument("--cache-nodes", type=int, default=8192, help="node draws per cache point")
    parser.add_argument("--glossy-rays", type=int, default=16, help="glossy rays per eye vertex and group (cache)")
    parser.add_argument("--direct-samples", type=int, default=4, help="shadow rays per luminaire and pixel (cache)")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--fresnel-rule", default="reciprocal", choices=FRESNEL_RULES,
                        help="the smooth materials' rule for 1 − F(μ_i) (lsadphoto.solver.materials)")
    parser.add_argument("--reference-only", action="store_true")
    parser.add_argument("--cache", default=os.path.join(tempfile.gettempdir(), "lsadphoto_material_refs"))
    parser.add_argument("--output", default="/tmp/frag_accuracy_materials.md")
    args = parser.parse_args(argv)
    _, _, version = _radiance()
    lines = [f"Command: `{' '.join([os.path.basename(sys.executable), *sys.argv])}`  ",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
             f"Radiance binaries of pyradiance {version}; reference `rtrace {args.rtrace}`, {args.pixels} random "
             f"pixels of a {args.size}² view, two runs of {args.repeats} traces per ray.", "",
             "| scene | estimator | setting | CPU (wall) [s] | field-mean ratio | MARE | MARE, reference noise removed "
             "| highlight ratio | reference's own error (mean) | self-reported error, median (mean) | median \\|z\\| "
             "| \\|z\\| ≤ 3 |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    comparisons = []
    for variant in args.variant or MATERIAL_ROOMS:
        pick, ref, ref_se, cpu = reference(variant, args.size, args.pixels, args.rtrace, args.cache, args.repeats)
        print(f"{variant}: reference {cpu:.0f} s CPU, own error {100 * np.mean(ref_se / ref):.2f} %", flush=True)
        if args.reference_only:
            continue
        _, scene, proj, pos, rot = view_of(variant, args.size)
        maps = {}
        for name in args.estimators.split(","):
            with Clock() as clock:
                if name == "local":
                    setting = (f"{args.chains} chains, {args.nodes_per_pixel} nodes/px, "
                               f"{args.rays_per_vertex} rays/vertex")
                    store = simulate(scene, samples=args.chains, seed=1, fresnel_rule=args.fresnel_rule)
                    with Clock() as view:
                        lmap = render_local_estimate_materials(
                            store, proj, position=pos, rotation=rot, nodes_per_pixel=args.nodes_per_pixel,
                            rays_per_vertex=args.rays_per_vertex, seed=1, workers=args.workers)
                    setting += f" (CPU: view {view.cpu:.0f} s)"
                elif name == "cache":
                    setting = (f"{args.chains} chains, spacing {args.cache_spacing:.3g} × diagonal, "
                               f"{args.cache_nodes} nodes/point, {args.glossy_rays} glossy rays/vertex/group, "
                               f"{args.direct_samples} shadow rays/luminaire/px")
                    store = simulate(scene, samples=args.chains, seed=1, fresnel_rule=args.fresnel_rule)
                    with Clock() as build:
                        cache = build_surface_cache(store, spacing=args.cache_spacing * scene.size,
                                                    nodes=args.cache_nodes, seed=1, workers=args.workers)
                    with Clock() as view:
                        lmap = render_cached(store, proj, position=pos, rotation=rot, cache=cache, seed=1,
                                             glossy_rays=args.glossy_rays, direct_samples=args.direct_samples,
                                             workers=args.workers)
                    setting += (f" ({cache.size} points; CPU: cache {build.cpu:.0f} s, view {view.cpu:.1f} s)")
                else:
                    setting = f"{args.paths} paths/px"
                    lmap = render_path_traced(scene, proj, position=pos, rotation=rot, samples=args.paths,
                                              batches=16, seed=1, workers=args.workers,
                                              fresnel_rule=args.fresnel_rule)
            maps[name] = (np.asarray(lmap.luminance, float).ravel(), np.asarray(lmap.uncertainty, float).ravel())
            ours, sigma = maps[name][0][pick], maps[name][1][pick]
            s = summary(ours, sigma, ref, ref_se)
            lines.append(f"| {variant} | {name}, {args.fresnel_rule} rule | {setting} | {clock.cpu:.0f} ({clock.wall:.0f}) | {s['field']:.4f} ± "
                         f"{s['field_se']:.4f} | {100 * s['mare']:.2f} % | {100 * s['mare_corrected']:.2f} % | {s['highlight']:.3f} | "
                         f"{100 * s['ref_rel']:.2f} % | {100 * s['self']:.2f} % ({100 * s['self_mean']:.2f} %) | {s['median_z']:.2f} | "
                         f"{100 * s['z3']:.0f} % |")
            print(lines[-1], flush=True)
        for first, second in itertools.combinations(maps, 2):
            # two estimators against each other over the whole view (independent runs)
            (a, sa), (b, sb) = maps[first], maps[second]
            ok = np.isfinite(a) & np.isfinite(b) & (sa + sb > 0)
            z = (a[ok] - b[ok]) / np.sqrt(sa[ok] ** 2 + sb[ok] ** 2)
            comparisons.append(f"{variant}, {args.fresnel_rule} rule: {first} / {second} field mean {a[ok].mean() / b[ok].mean():.4f} ± "
                               f"{math.sqrt((sa[ok] ** 2).sum() + (sb[ok] ** 2).sum()) / b[ok].sum():.4f}, "
                               f"mean z² {np.mean(z * z):.2f}, median |z| {np.median(np.abs(z)):.2f} over "
                               f"{int(ok.sum())} pixels.")
            print(comparisons[-1], flush=True)
    lines += ["", *[f"* {c}" for c in comparisons], "", f"Load average at the end: {os.getloadavg()[0]:.1f}."]
    text = "\n".join(lines) + "\n"
    print(text)
    Path(args.output).write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
