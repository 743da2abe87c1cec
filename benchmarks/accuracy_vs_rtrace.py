"""Per-pixel accuracy of the solver's maps against unbiased Radiance references (issue 13).

One Radiance scene file goes to both programs: our :func:`lsadphoto.solver.read_scene` and
Radiance's ``oconv``. The reference is ``rtrace`` with
:data:`~lsadphoto.solver.formats.radiance.RTRACE_UNBIASED` (pure Monte Carlo ambient sampling:
no irradiance cache, so no interpolation bias, no adaptive super-samples, which are biased
low, and every light source shadow-tested at every hit: Radiance's default ``-dt``/``-dc``
guesses the visibility of the untested ones from run-wide hit rates, which put the hall's
indirect light 10 % low on the walls and 3.5 % high on the floor; rpict's cache has its own
errors) through the
rays that ``vwrays`` makes of the same 180° fisheye view, on a random subset of the pixels
inside the image circle, **run ``--runs`` times** (default 2): the first two with the pixels in
opposite order, each further one with k·97 copies of the first ray traced before the subset
(rtrace's ambient samples follow a sequence indexed by the primary ray, so shifting the
index gives independent noise: the runs' deviations from their mean correlate as
−1/(runs − 1), PITFALLS.md). Their mean is the reference and their standard deviation over
√runs its standard error — with runs − 1 degrees of freedom: with two runs that estimate
alone makes z heavy-tailed (a perfect estimator of our noise equal to the reference's
would show only 98.6 % of pixels with |z| ≤ 3; 99.5 % with 8 runs). ``--repeats R`` traces
the subset R times over within each run: Radiance's default ``-u+`` draws every ambient
sample from ``random()`` (seeded from the clock), so each trace is an independent draw
(lag-1 correlation of consecutive traces of one ray 0.00 ± 0.03 at ``-ad 16``), and the
standard error has runs·R − 1 degrees of freedom.

**Small ``-ad`` for an unbiased reference.** With ``-aa 0`` and many ambient divisions
rtrace's first-bounce estimate is not unbiased near a wall: at a ceiling point of the
canonical room 0.3 m from the lit wall (1.5, 0.3, 3.0) ``rtrace -I`` gave 105.3 ± 0.4 lx
with ``-ad 1`` (one cosine-distributed sample: the plainest estimator), 105.6, 105.5, 105.4
and 105.1 lx with ``-ad 4, 9, 16, 64``, and 104.1, 104.0, 103.9, 103.9 lx with ``-ad 128, 256,
512, 1024`` (σ 0.05–0.2 lx), while 16 other points of the room agreed between ``-ad 16`` and
``-ad 512`` within 0.2 % (docs/accuracy.md, session 15). The divisions of rtrace's
stratified hemisphere reject a direction within (π/4)/n of a neighbouring division's sample
and draw again (``ambcollision`` in ambcomp.c), so its samples are no longer uniform within
a division; that is the likely cause. ``-ad 16 --repeats R`` costs about as much for the
same standard error in the canonical room (96 s of CPU for 1000 traces, 0.14 % mean relative
standard error, against 48 s for 8 runs at ``-ad 512``, 0.18 %) and gives it hundreds of
degrees of freedom instead of runs − 1.

Scenes:

* ``canonical``: the canonical room of FORMULAS.md Part A (:func:`canonical_room_rad`);
* ``hall``: a station-like hall made by :func:`lsadphoto.datasets.hall.make_station_hall`
  (reduced by ``--hall-scale``: floor, luminaires and tessellation), written as Radiance
  polygons with its luminaires as Radiance's own ``ies2rad`` output of the hall's IES file,
  placed by ``!xform`` — exactly what a user brings from Radiance — each under a black
  square of its opening's size (its housing: Radiance's light polygon stops inter-reflected
  light, our point luminaire would not; without it our pixels were 1.8 % brighter in median).

For each of our estimators (``cache``: direct light per pixel, indirect from the surface
cache; ``points``: the same direct light and the cache's own unbiased estimator of the
indirect light evaluated at the subset's hit points, no interpolation — what separates the
interpolation's error from the rest; ``local``: the per-pixel double local estimate) the
table gives, over the subset:
the field-mean ratio, the mean absolute relative per-pixel error (MARE) raw, with its standard
error over the subset (the standard deviation of the pixels' |relative error| over √pixels: a
few noisy pixels carry much of the sum, so on the hall's 126 pixels it is ≈ 0.2 points), and
with the reference's own noise removed in quadrature; the MARE that the uncertainties imply,
√(2/π)·mean(√(σ_ours² + σ_ref²)/reference) (what a ``--target-error`` render bounds, there
without the reference's part: :data:`~lsadphoto.solver.rendering.TARGET_MEASURE`; comparable
with the raw MARE — their ratio is how far the reported σ under- or over-states the error);
our self-reported per-pixel error (for the cache with its noise part and its estimated
interpolation bias); and the share of pixels with |z| ≤ 3, z = (ours − reference)/√(σ_ours² +
σ_ref²), with the number beyond. Pixels brighter than
``--max-luminance`` (the luminaires' openings, whose edges one ray per pixel resolves
differently in the two programs) are left out, and so are pixels whose primary hit points
differ by more than 1 cm (a silhouette that the two ray casters' eye rays, float64 and
vwrays' float32, pass on different sides).

Run (2-core machine)::

    python benchmarks/accuracy_vs_rtrace.py --scene canonical --size 128 --runs 2 --repeats 500
    python benchmarks/accuracy_vs_rtrace.py --scene hall --size 128 --hall-scale 0.35 --repeats 200

(the references: 96 s and 381 s of rtrace CPU; ``--rtrace "-ab 8 -ad 512 …" --runs 8
--repeats 1`` gives the earlier sessions' references). ``--seed 2``, ``--seed 3`` repeat our side
with independent streams against the same reference pixels: one seed's count beyond 3σ is a
draw (the canonical room: 0–8 of 247 over 24 seeds, docs/accuracy.md session 16).

Writes a Markdown fragment with the command to ``--output``. The references are kept in
``--reference-cache`` (default: a folder in the system's temporary directory), keyed by the
scene's files and every option that makes them, so that runs of two builds share one.
"""

import argparse
import math
import os
import platform
import shlex
import subprocess
import sys
import tempfile
import types
from pathlib import Path

import numpy as np
from _clock import Clock

from lsadphoto.constants import RADIANCE_RGB_LUMINANCE_WEIGHTS
from lsadphoto.solver import read_scene, render, simulate
from lsadphoto.solver.direct import DIRECT_SAMPLES, direct_illuminance
from lsadphoto.solver.engine import engine_for
from lsadphoto.solver.examples import canonical_room_rad
from lsadphoto.solver.formats.radiance import RTRACE_UNBIASED
from lsadphoto.solver.integrators.eye import primary_rays
from lsadphoto.solver.integrators.surface_cache import (
    CACHE_NODES,
    indirect_illuminance,
    render_cached,
)


def _radiance():
    import pyradiance

    binpath = os.path.join(os.path.dirname(pyradiance.__file__), "bin")
    env = dict(os.environ, RAYPATH=os.pathsep.join([".", os.path.join(binpath, "..", "lib")]),
               PATH=os.pathsep.join([binpath, os.environ.get("PATH", "")]))
    return binpath, env, pyradiance.__version__


def _hall_rad(folder, scale):
    """Write the reduced station hall as a Radiance scene; returns its path."""
    from lsadphoto.datasets.hall import make_station_hall

    toml = make_station_hall(folder, length=60.0 * scale, width=20.0 * max(scale, 0.5),
                             luminaires=max(8, round(120 * scale)), detail=scale)
    scene = read_scene(toml)
    binpath, env, _ = _radiance()
    subprocess.run([os.path.join(binpath, "ies2rad"), "-t", "default", "-m", "1", "-dm", "-o", "luminaire",
                    "luminaire.ies"], cwd=folder, env=env, check=True)
    lines = [f"# {scene.name}: {len(scene.triangles)} triangles, written by {Path(__file__).name}"]
    for k, (name, rho) in enumerate(zip(scene.material_names, scene.reflectance)):
        lines.append(f"void plastic m{k}\n0\n0\n5 {rho:.6g} {rho:.6g} {rho:.6g} 0 0\n")
    for t, (tri, mat) in enumerate(zip(scene.triangles, scene.material)):
        coords = " ".join(f"{v:.6f}" for v in tri.ravel())
        lines.append(f"m{mat} polygon t{t}\n0\n0\n9 {coords}")
    # Each luminaire's housing: a black square over its opening, 1 cm above it, facing down.
    # Radiance's ies2rad light polygon stops inter-reflected light (its pattern is 0 upwards);
    # our point luminaires alone would not, and the reflected light would pass them.
    lines.append("void plastic housing\n0\n0\n5 0 0 0 0 0\n")
    for lum in scene.point_luminaires:
        if not np.allclose(lum.frame[2], [0, 0, -1]) or not np.allclose(lum.frame[0], [1, 0, 0]):
            raise SystemExit(f"luminaire {lum.name}: only downward luminaires along +x are written")
        x, y, z = lum.position
        lines.append(f"!xform -n {lum.name} -t {x:.6f} {y:.6f} {z:.6f} luminaire.rad")
        a, b = lum.extent[0] / 2, lum.extent[1] / 2
        corners = [(x - a, y - b), (x - a, y + b), (x + a, y + b), (x + a, y - b)]
        lines.append(f"housing polygon {lum.name}_housing\n0\n0\n12 "
                     + " ".join(f"{u:.6f} {v:.6f} {z + 0.01:.6f}" for u, v in corners))
    path = Path(folder) / "hall.rad"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path, [(v.name, v.position, v.rotation) for v in scene.views]


def _reference(rad, view_options, size, pixels, rtrace_options, seed, runs=2, cache=None, repeats=1):
    """Flat pixel indices, reference luminance [cd·m⁻²], its standard error, rtrace's
    primary hit points [m] and rtrace CPU [s]; kept in the folder ``cache`` (if given) under a
    hash of the scene's files, the view, the pixels, the options, the runs, the repeats and
    Radiance's version, so that two of our builds compare against one reference (the CPU is
    that of the run that made it). Each run traces the subset ``repeats`` times over in one
    process; every trace is one draw."""
    binpath, env, version = _radiance()
    folder = rad.parent
    if cache:
        import hashlib

        key = (view_options, size, pixels, rtrace_options, seed, runs, version) + ((repeats,) if repeats > 1 else ())
        h = hashlib.sha256(repr(key).encode())
        for f in sorted(folder.iterdir()):
            if f.suffix in (".rad", ".dat", ".cal"):
                h.update(f.name.encode() + f.read_bytes())
        path = Path(cache) / f"rtrace_{h.hexdigest()[:24]}.npz"
        if path.exists():
            with np.load(path) as z:
                print(f"reference from {path}", file=sys.stderr)
                return z["pick"], z["mean"], z["sigma"], z["hits"], float(z["cpu"])
        result = _reference(rad, view_options, size, pixels, rtrace_options, seed, runs, repeats=repeats)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, **dict(zip(("pick", "mean", "sigma", "hits", "cpu"), result)))
        return result
    octree = folder / "scene.oct"
    with open(octree, "wb") as fh:
        subprocess.run([os.path.join(binpath, "oconv"), "-f", rad.name], stdout=fh, cwd=folder, env=env,
                       check=True)
    raw = subprocess.run([os.path.join(binpath, "vwrays"), *view_options, "-x", str(size), "-y", str(size),
                          "-ff"], capture_output=True, cwd=folder, env=env, check=True).stdout
    rays = np.frombuffer(raw, np.float32).reshape(-1, 6)
    # inside the 180° image circle: within 90° of the view direction (vwrays also gives the
    # corners' rays, beyond 90°, which our fisheye leaves undefined)
    forward = np.asarray(view_options[view_options.index("-vd") + 1:][:3], float)
    inside = np.flatnonzero(rays[:, 3:] @ (forward / np.linalg.norm(forward)) > 1e-6)
    pick = np.sort(np.random.default_rng(seed).choice(inside, min(pixels, inside.size), replace=False))
    values = []
    with Clock() as clock:
        for k in range(runs):
            order = slice(None) if k % 2 == 0 else slice(None, None, -1)
            lead = 97 * k if k >= 2 else 0
            subset = np.ascontiguousarray(np.concatenate([np.repeat(rays[pick][:1], lead, axis=0),
                                                          np.tile(rays[pick][order], (repeats, 1))]))
            out = subprocess.run([os.path.join(binpath, "rtrace"), "-h", "-ff", "-ovp", *rtrace_options.split(),
                                  str(octree)], input=subset.tobytes(), capture_output=True, cwd=folder,
                                 env=env, check=True).stdout
            traces = np.frombuffer(out, np.float32).reshape(-1, 6).astype(float)[lead:].reshape(repeats, pick.size, 6)
            rgb, hits = np.split(traces[:, order], 2, axis=2)
            values.extend(179.0 * rgb @ RADIANCE_RGB_LUMINANCE_WEIGHTS)
            hits = hits[0]
    values = np.array(values)
    return pick, values.mean(axis=0), values.std(axis=0, ddof=1) / math.sqrt(len(values)), hits, clock.cpu


def _at_points(store, view, pick, size, *, nodes, direct_samples, luminaires, seed):
    """Our luminance [cd·m⁻²] and its standard error at the pixels ``pick`` without the
    cache's interpolation: E_dir per pixel as render_cached (``direct_samples``), E_ind by the
    cache's estimator (:func:`indirect_illuminance`, ``nodes`` draws) at each hit, ``luminaires``
    as :func:`direct_illuminance`'s, the streams of ``seed``; a map-like record (NaN elsewhere)."""
    scene = store.scene
    engine = engine_for(scene)
    valid, prim, dist, d = primary_rays(scene, engine, view.projection, view.position, view.rotation)
    where = np.full(size * size, -1)
    where[valid] = np.arange(valid.size)
    row = where[pick]
    t = np.where(row >= 0, prim[np.maximum(row, 0)], -1)
    rho = np.where(t >= 0, scene.triangle_reflectance[np.maximum(t, 0)], 0.0)
    use = np.flatnonzero(rho > 0)
    x = view.position + d[row[use]] * dist[row[use], None]
    n = scene.normals[t[use]]
    n = np.where((np.einsum("ij,ij->i", n, d[row[use]]) < 0)[:, None], n, -n)
    e_dir, var = direct_illuminance(scene, engine, x, n, samples=direct_samples, luminaires=luminaires, seed=seed)
    e_ind = indirect_illuminance(store, x, n, nodes=nodes, seed=seed, key=9)
    lum, unc = np.full(size * size, np.nan), np.full(size * size, np.nan)
    k = rho[use] / math.pi
    lum[pick[use]] = k * (e_dir + e_ind.mean(axis=1))
    unc[pick[use]] = k * np.sqrt(var + e_ind.var(axis=1, ddof=1) / e_ind.shape[1])
    return types.SimpleNamespace(luminance=lum, uncertainty=unc, provenance={})


def _row(label, setting, lmap, pick, ref, ref_sigma, keep, cpu):
    ours = lmap.luminance.ravel()[pick][keep]
    sigma = lmap.uncertainty.ravel()[pick][keep]
    r, rs = ref[keep], ref_sigma[keep]
    rel = np.abs(ours / r - 1)
    raw = float(np.mean(rel))
    raw_se = float(np.std(rel, ddof=1)) / math.sqrt(rel.size) if rel.size > 1 else float("nan")
    ref_mae = 0.798 * float(np.mean(rs / r))  # E|z| of a unit Gaussian: MAEs add in quadrature
    corrected = math.sqrt(max(raw * raw - ref_mae * ref_mae, 0.0))
    implied = math.sqrt(2 / math.pi) * float(np.mean(np.sqrt(sigma ** 2 + rs ** 2) / r))
    z = (ours - r) / np.sqrt(sigma ** 2 + rs ** 2)
    p = lmap.provenance
    parts = (f" (noise {100 * p['pixel_relative_noise_median']:.2f} %, bias "
             f"{100 * p['pixel_relative_bias_median']:.2f} % / p95 {100 * p['pixel_relative_bias_p95']:.2f} %)"
             if "pixel_relative_bias_median" in p else "")
    return (f"| {label} | {setting} | {cpu:.0f} | {ours.mean() / r.mean():.4f} | {np.median(ours / r):.4f} | "
            f"{100 * raw:.2f} ± {100 * raw_se:.2f} % | {100 * corrected:.2f} % | {100 * implied:.2f} % | "
            f"{100 * float(np.median(sigma / ours)):.2f} %{parts} | "
            f"{100 * float(np.mean(np.abs(z) <= 3)):.1f} % ({int(np.sum(np.abs(z) > 3))} beyond) |")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", choices=("canonical", "hall"), default="canonical")
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--pixels", type=int, default=256, help="reference pixels (random subset)")
    parser.add_argument("--chains", type=int, default=65536)
    parser.add_argument("--target-error", type=float, default=None,
                        help="cache: render the scene by render(..., estimator='cache', target_error=E), "
                             "as `lsadphoto render SCENE --estimator cache --target-error E` does "
                             "(rounds of chains from --chains), instead of --chains and the defaults")
    parser.add_argument("--seed", type=int, default=1,
                        help="seed of our simulation, cache and render (the local estimate takes seed + 1); the "
                             "reference's pixels stay the same, so runs with seeds 1, 2, 3 are paired")
    parser.add_argument("--local-chains", type=int, default=262144)
    parser.add_argument("--hall-scale", type=float, default=0.5)
    # -ad 16: rtrace's estimate at many ambient divisions is biased near walls (module docstring)
    parser.add_argument("--rtrace", default=" ".join(("-ab 16 -ad 16", *RTRACE_UNBIASED, "-ds 0.02")))
    parser.add_argument("--runs", type=int, default=2, help="reference runs")
    parser.add_argument("--repeats", type=int, default=100,
                        help="traces of the subset per reference run, in one rtrace process (each one draw)")
    parser.add_argument("--max-luminance", type=float, default=1000.0)
    parser.add_argument("--estimators", default="cache,points,local",
                        help="comma-separated: cache, points (needs cache), local")
    parser.add_argument("--output", default="/tmp/frag_accuracy_rtrace.md")
    parser.add_argument("--per-pixel", default=None,
                        help="also write the compared pixels to this .npz: flat pixel index, reference and its "
                             "standard error, rtrace's hit point, and per estimator (keys '<name>_luminance', "
                             "'<name>_uncertainty') ours at those pixels")
    parser.add_argument("--reference-cache", default=os.path.join(tempfile.gettempdir(), "lsadphoto_rtrace_refs"),
                        help="folder that keeps the rtrace references between runs ('' : none)")
    args = parser.parse_args(argv)
    if args.runs < 1 or args.repeats < 1 or args.runs * args.repeats < 2:
        parser.error(f"--runs × --repeats must be at least 2 (the reference's own noise), got {args.runs} × "
                     f"{args.repeats}")
    folder = Path(tempfile.mkdtemp(prefix="acc_rtrace_"))
    if args.scene == "canonical":
        rad = folder / "room.rad"
        rad.write_text(canonical_room_rad(), encoding="ascii")
        views = [("observer", np.array([1.0, 2.0, 1.2]), None)]
        view_options = ["-vta", "-vp", "1", "2", "1.2", "-vd", "1", "0", "0", "-vu", "0", "0", "1",
                        "-vh", "180", "-vv", "180"]
    else:
        rad, views = _hall_rad(folder, args.hall_scale)
        name, position, rotation = views[0]
        d, u = rotation[:, 2], -rotation[:, 1]
        view_options = ["-vta", "-vp", *map(str, position), "-vd", *map(str, d), "-vu", *map(str, u),
                        "-vh", "180", "-vv", "180"]
    scene = read_scene(rad, views=[{"name": "reference view", "position": list(map(float, view_options[2:5])),
                                     "line_of_sight": list(map(float, view_options[6:9])),
                                     "up": list(map(float, view_options[10:13])),
                                     "projection": {"model": "fisheye-ideal", "kind": "equidistant",
                                                    "fov_deg": 180, "width": args.size,
                                                    "height": args.size}}])
    view = scene.views[0]
    pose = {"position": view.position, "rotation": view.rotation}
    pick, ref, ref_sigma, ref_hits, rtrace_cpu = _reference(rad, view_options, args.size, args.pixels, args.rtrace,
                                                            seed=5, runs=args.runs,
                                                            cache=args.reference_cache, repeats=args.repeats)
    # Pixels whose primary rays hit the same point in both programs: at a silhouette our
    # float64 eye ray and vwrays' float32 one can hit different objects (hall: 1 pixel of
    # 256, 0.8 m apart; the others agree to 2 µm at the 95th percentile), which compares two
    # surfaces, not two estimates of one. 1 cm is far above that agreement and far below
    # the scenes' object sizes.
    valid, prim, dist, d = primary_rays(scene, engine_for(scene), view.projection, view.position, view.rotation)
    ours_hits = np.full((args.size * args.size, 3), np.nan)
    ours_hits[valid[prim >= 0]] = view.position + d[prim >= 0] * dist[prim >= 0, None]
    same_hit = np.linalg.norm(ours_hits[pick] - ref_hits, axis=1) <= 0.01
    rows = []
    keep = None
    per_pixel = {}
    workers = os.cpu_count() or 1
    estimators = args.estimators.split(",")
    if "cache" in estimators:
        knobs = {"cache_nodes": CACHE_NODES, "direct_samples": DIRECT_SAMPLES, "luminaire_draws": "auto"}
        with Clock() as clock:
            if args.target_error is None:
                store = simulate(scene, samples=args.chains, seed=args.seed)
                lmap = render_cached(store, view.projection, seed=args.seed, workers=workers, **pose)
                setting = f"{args.chains} chains, defaults"
            else:
                lmap = render(scene, view.projection, estimator="cache", samples=args.chains,
                              target_error=args.target_error, seed=args.seed, workers=workers, **pose)
                last = lmap.provenance["rounds"][-1]
                knobs = {key: last[key] for key in knobs}
                setting = (f"target error {args.target_error:g}: "
                           + " → ".join(str(r["chains"]) for r in lmap.provenance["rounds"])
                           + f" chains, last {last['cache_nodes']} nodes, {last['direct_samples']} shadow rays, "
                             f"{last['luminaire_draws']} luminaire draws"
                           + ("" if lmap.provenance["target_reached"] else " (not reached)"))
        keep = np.isfinite(lmap.luminance.ravel()[pick]) & (ref < args.max_luminance) & (
            lmap.luminance.ravel()[pick] < args.max_luminance) & same_hit
        rows.append(("ours, surface cache", setting, lmap, clock.cpu))
        per_pixel["cache"] = lmap
        if "points" in estimators:
            if args.target_error is not None:  # the last round's store: the same streams, one run
                store = simulate(scene, samples=lmap.provenance["rounds"][-1]["chains"], seed=args.seed)
            with Clock() as clock:
                at_points = _at_points(store, view, pick, args.size, nodes=knobs["cache_nodes"],
                                       direct_samples=knobs["direct_samples"],
                                       luminaires=knobs["luminaire_draws"], seed=args.seed)
            rows.append(("ours, cache's estimator at the hits (no interpolation)",
                         f"the same store, {pick.size} points", at_points, clock.cpu))
            per_pixel["points"] = at_points
    if "local" in estimators:
        with Clock() as clock:
            store = simulate(scene, samples=args.local_chains, seed=args.seed + 1)
            lmap = render(store, view.projection, seed=args.seed + 1, workers=workers, **pose)
        if keep is None:
            keep = np.isfinite(lmap.luminance.ravel()[pick]) & (ref < args.max_luminance) & same_hit
        rows.append(("ours, double local estimate", f"{args.local_chains} chains, nodes per pixel auto",
                     lmap, clock.cpu))
        per_pixel["local"] = lmap
    _, _, version = _radiance()
    lines = [f"Command: `{shlex.join([os.path.basename(sys.executable), *sys.argv])}`  ",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
             f"Radiance binaries of pyradiance {version}; load average {os.getloadavg()[0]:.1f} at the end.  ",
             f"Scene: {scene.name} ({len(scene.triangles)} triangles, {len(scene.point_luminaires)} point and "
             f"{len(scene.area_luminaires)} area luminaires); view `{' '.join(view_options)}` at {args.size}².  ",
             f"Reference: `rtrace {args.rtrace}` on {int(keep.sum())} random pixels inside the image circle "
             f"(of {pick.size}; {int(np.sum(ref >= args.max_luminance))} luminaire pixels above "
             f"{args.max_luminance:g} cd/m² and {int(np.sum(~same_hit & (ref < args.max_luminance)))} whose "
             f"primary hits differ by more than 1 cm left out), {args.runs} runs"
             + (f" of {args.repeats} traces each" if args.repeats > 1 else "")
             + f", {rtrace_cpu:.0f} s CPU; its own mean "
             f"relative standard error "
             f"{100 * float(np.mean(ref_sigma[keep] / ref[keep])):.2f} %.", "",
             "| solver | setting | CPU [s] | field-mean ratio | median pixel ratio | MARE (± its standard error) | "
             "MARE, reference noise removed | MARE that σ and σ_ref imply | self-reported per-pixel error (median) | "
             "pixels with |z| ≤ 3 |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    lines += [_row(label, setting, lmap, pick, ref, ref_sigma, keep, cpu) for label, setting, lmap, cpu in rows]
    text = "\n".join(lines) + "\n"
    print(text)
    Path(args.output).write_text(text, encoding="utf-8")
    if args.per_pixel:
        np.savez(args.per_pixel, pixel=pick[keep], reference=ref[keep], reference_sigma=ref_sigma[keep],
                 hit=ref_hits[keep], **{f"{name}_{part}": getattr(m, part).ravel()[pick][keep]
                                        for name, m in per_pixel.items() for part in ("luminance", "uncertainty")})


if __name__ == "__main__":
    main()
