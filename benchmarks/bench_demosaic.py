"""Speed and accuracy of the demosaic methods on a synthetic 24-megapixel DNG (docs/performance.md).

Run: ``.venv/bin/python benchmarks/bench_demosaic.py [--size 6000x4000] [--repeat 3]``;
``--profile METHOD`` prints a pyinstrument profile of one end-to-end call instead.

For each method (superpixel, linear, ahd, dcb) it times, best and worst of ``--repeat`` runs
(``time.perf_counter``):

* ``rawpy``: ``rawpy.imread`` + ``postprocess`` with the same options as our decoder
  (LibRaw's own demosaic, the reference; for superpixel LibRaw's ``half_size`` mode);
* ``decode``: :func:`lsadphoto.raw.decode.decode_raw`;
* ``end-to-end``: :func:`lsadphoto.luminance_from_raw` (decode, merge, vignetting, colour,
  absolute scale, uncertainty).

Throughput is given in megapixels of the sensor for every method (also superpixel, whose
output has a quarter of the pixels). The luminance error is measured against the map the
synthetic camera was given (binned 2 × 2 by mean for superpixel): the median and 99th
percentile of |L/L_true − 1| over unsaturated pixels more than 4 sensor pixels away from an
edge of the truth map ("smooth"), over the unsaturated pixels within 4 px of an edge (the
"edge band" around the target and the luminaires, the worst case) and over every
unsaturated pixel ("whole image"). A second, noisy frame (shot + read
noise at ISO 400, same exposure level) shows the noise-limited error. Temporary files go to
a ``tempfile.TemporaryDirectory``.
"""

import argparse
import gc
import os
import platform
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import rawpy
from scipy.ndimage import maximum_filter

from lsadphoto import luminance_from_raw
from lsadphoto.calibrate import CameraProfile
from lsadphoto.datasets import SyntheticCamera, interior_scene, write_dng
from lsadphoto.raw.decode import decode_raw

METHODS = ("superpixel", "linear", "ahd", "dcb")
LIBRAW = {
    "superpixel": None,  # LibRaw's half_size mode
    "linear": rawpy.DemosaicAlgorithm.LINEAR,
    "ahd": rawpy.DemosaicAlgorithm.AHD,
    "dcb": rawpy.DemosaicAlgorithm.DCB,
}
#: A jump of more than this between neighbouring truth pixels is an edge [–].
EDGE_JUMP = 0.01
#: Pixels within this distance of an edge are left out of the "smooth" statistics [sensor px].
EDGE_MARGIN = 4


def parse_size(text):
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must be WIDTHxHEIGHT, not {text!r}") from None
    if width < 64 or height < 64 or width % 2 or height % 2:
        raise argparse.ArgumentTypeError("width and height must be even and at least 64")
    return width, height


def rawpy_reference(path, method):
    """LibRaw's own decode of the same file with the options our decoder uses."""
    options = dict(output_color=rawpy.ColorSpace.raw, gamma=(1, 1), no_auto_bright=True, output_bps=16,
                   user_wb=[1, 1, 1, 1], user_flip=0)
    if method == "superpixel":
        options["half_size"] = True
    else:
        options["demosaic_algorithm"] = LIBRAW[method]
    with rawpy.imread(str(path)) as raw:
        return raw.postprocess(**options)


def timed(function, repeat):
    """(best, worst) wall time [s] of ``repeat`` calls and the last result."""
    times, result = [], None
    for _ in range(repeat):
        result = None
        gc.collect()
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return min(times), max(times), result


def smooth_mask(truth):
    """Pixels more than EDGE_MARGIN px from a jump of more than EDGE_JUMP in ``truth``.

    A jump between neighbours (rather than a max/min filter over the window) keeps the
    smooth gradient of the scene in, at any image size.
    """
    log = np.log(truth)
    edge = np.zeros(truth.shape, bool)
    jump_r = np.abs(np.diff(log, axis=0)) > np.log1p(EDGE_JUMP)
    jump_c = np.abs(np.diff(log, axis=1)) > np.log1p(EDGE_JUMP)
    edge[:-1] |= jump_r
    edge[1:] |= jump_r
    edge[:, :-1] |= jump_c
    edge[:, 1:] |= jump_c
    return ~maximum_filter(edge, size=2 * EDGE_MARGIN + 1)


def bin2(x, how="mean"):
    rows, cols = x.shape
    blocks = x.reshape(rows // 2, 2, cols // 2, 2)
    return blocks.mean(axis=(1, 3)) if how == "mean" else blocks.all(axis=(1, 3))


def errors(luminance, truth, smooth):
    """Median and 99th percentile of |L/L_true − 1| [–]: smooth regions, edge band, whole image."""
    finite = np.isfinite(luminance)
    out = {}
    for name, mask in (("smooth", smooth & finite), ("edges", ~smooth & finite), ("whole", finite)):
        rel = np.abs(luminance[mask] / truth[mask] - 1.0)
        out[name] = (float(np.median(rel)), float(np.percentile(rel, 99)), float(mask.mean()))
    return out


def profile_for(cam):
    return CameraProfile(id="bench", sensor_width=cam.sensor_width, sensor_height=cam.sensor_height, width=cam.width,
                         height=cam.height, focal_length=cam.focal_length,
                         calibration_constant=cam.calibration_constant)


def shoot(folder, cam, scene, name, *, t, n, iso, noise):
    raw = cam.expose(scene, exposure_time=t, f_number=n, iso=iso, noise=noise, rng=np.random.default_rng(1))
    path = write_dng(folder / f"{name}.dng", raw, cam, exposure_time=t, f_number=n, iso=iso)
    cfa_signal = (raw.astype(np.float64) - cam.black_map()) / (cam.white_level - cam.black_map())
    saturated = cfa_signal >= 0.98
    return path, float(saturated.mean()), float(np.median(cfa_signal)), float(cfa_signal[~saturated].max())


def profile_end_to_end(size, method):
    """pyinstrument profile of one end-to-end call (the bench extra installs pyinstrument)."""
    from pyinstrument import Profiler

    cam = SyntheticCamera(width=size[0], height=size[1])
    scene = interior_scene((cam.height, cam.width))
    with tempfile.TemporaryDirectory(prefix="lsad-bench-") as tmp:
        path, *_ = shoot(Path(tmp), cam, scene, "clean", t=1 / 125, n=4.0, iso=100, noise=False)
        del scene
        luminance_from_raw([path], profile=profile_for(cam), demosaic=method)  # warm-up
        profiler = Profiler(interval=0.002)
        profiler.start()
        luminance_from_raw([path], profile=profile_for(cam), demosaic=method)
        profiler.stop()
    print(profiler.output_text(unicode=True, color=False))


def pct(x, digits=3):
    return f"{100 * x:.{digits}f} %"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=parse_size, default=(6000, 4000), help="WIDTHxHEIGHT (default 6000x4000)")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per measurement (default 3)")
    parser.add_argument("--methods", default=",".join(METHODS), help="comma-separated subset of " + ",".join(METHODS))
    parser.add_argument("--no-noise", action="store_true", help="skip the noisy (ISO 400) accuracy run")
    parser.add_argument("--profile", choices=METHODS, metavar="METHOD",
                        help="instead of the tables, print a pyinstrument profile of one end-to-end call "
                             "(after a warm-up call) with this method")
    args = parser.parse_args(argv)
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    if set(methods) - set(METHODS) or args.repeat < 1:
        parser.error("unknown method or --repeat below 1")
    warnings.simplefilter("ignore")
    if args.profile:
        return profile_end_to_end(args.size, args.profile)

    width, height = args.size
    cam = SyntheticCamera(width=width, height=height)
    megapixels = width * height / 1e6
    scene = interior_scene((cam.height, cam.width))
    smooth_full = smooth_mask(scene)
    truths = {"full": (scene, smooth_full), "binned": (bin2(scene), bin2(smooth_full, "all"))}
    prof = profile_for(cam)
    t, n, iso = 1 / 125, 4.0, 100  # brightest wall at ~60 % of white; only luminaires saturate

    print(f"# Demosaic benchmark: {width}×{height} = {megapixels:.1f} MP synthetic DNG, best of {args.repeat}\n")
    print(f"python {platform.python_version()}, numpy {np.__version__}, rawpy {rawpy.__version__} "
          f"(LibRaw {'.'.join(map(str, rawpy.libraw_version))}), {platform.machine()}, "
          f"{len(os.sched_getaffinity(0))} CPU cores\n")

    with tempfile.TemporaryDirectory(prefix="lsad-bench-") as tmp:
        folder = Path(tmp)
        path, sat_fraction, median_signal, max_unsat = shoot(folder, cam, scene, "clean", t=t, n=n, iso=iso,
                                                             noise=False)
        print(f"exposure t = 1/{round(1 / t)} s, N = {n:g}, ISO {iso}, noise-free: saturated CFA values "
              f"{pct(sat_fraction, 2)} (the luminaires); CFA signal of white: median {median_signal:.3f}, "
              f"brightest unsaturated {max_unsat:.3f}\n")

        rows, accuracy = [], []
        for method in methods:
            ref_best, ref_worst, ref = timed(lambda m=method: rawpy_reference(path, m), args.repeat)
            del ref
            dec_best, dec_worst, image = timed(lambda m=method: decode_raw(path, demosaic=m), args.repeat)
            del image
            e2e_best, e2e_worst, result = timed(
                lambda m=method: luminance_from_raw([path], profile=prof, demosaic=m), args.repeat)
            truth, smooth = truths["binned" if method == "superpixel" else "full"]
            err = errors(result.map.luminance, truth, smooth)
            del result
            rows.append((method, ref_best, ref_worst, dec_best, dec_worst, e2e_best, e2e_worst))
            accuracy.append((method, "none", err))
            print(f"  {method}: rawpy {ref_best:.3f} s, decode {dec_best:.3f} s, end-to-end {e2e_best:.3f} s",
                  file=sys.stderr, flush=True)

        if not args.no_noise:
            noisy, *_ = shoot(folder, cam, scene, "noisy", t=t / 4, n=n, iso=4 * iso, noise=True)
            for method in methods:
                result = luminance_from_raw([noisy], profile=prof, demosaic=method)
                truth, smooth = truths["binned" if method == "superpixel" else "full"]
                accuracy.append((method, "ISO 400 shot + read", errors(result.map.luminance, truth, smooth)))
                del result

    print("## Time (best of %d; worst in parentheses)\n" % args.repeat)
    print("| method | output | rawpy (LibRaw) [s] | decode_raw [s] | end-to-end [s] | end-to-end [s/MP] | "
          "end-to-end [MP/s] | rawpy [MP/s] | end-to-end / rawpy | decode / rawpy |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for method, ref_b, ref_w, dec_b, dec_w, e2e_b, e2e_w in rows:
        out = f"{width // 2}×{height // 2}" if method == "superpixel" else f"{width}×{height}"
        print(f"| {method} | {out} | {ref_b:.3f} ({ref_w:.3f}) | {dec_b:.3f} ({dec_w:.3f}) | "
              f"{e2e_b:.3f} ({e2e_w:.3f}) | {e2e_b / megapixels:.4f} | {megapixels / e2e_b:.1f} | "
              f"{megapixels / ref_b:.1f} | {e2e_b / ref_b:.2f} | {dec_b / ref_b:.2f} |")
    print("\nrawpy for superpixel: LibRaw's half_size postprocess (2 × 2 binning without interpolation).")
    print("MP = megapixels of the sensor for every method.\n")

    print("## Luminance error against the synthetic truth\n")
    print("| method | noise | smooth: median | smooth: 99th pct | edge band: median | edge band: 99th pct | "
          "whole image: median | whole image: 99th pct | pixels: smooth / edge band |")
    print("|---|---|---|---|---|---|---|---|---|")
    for method, noise, err in accuracy:
        (sm, s99, sf), (em, e99, ef), (wm, w99, _) = err["smooth"], err["edges"], err["whole"]
        print(f"| {method} | {noise} | {pct(sm, 4)} | {pct(s99, 4)} | {pct(em, 3)} | {pct(e99, 2)} | "
              f"{pct(wm, 4)} | {pct(w99, 3)} | {pct(sf, 1)} / {pct(ef, 2)} |")
    print(f"\nSmooth: unsaturated pixels more than {EDGE_MARGIN} sensor px from a jump of more than "
          f"{pct(EDGE_JUMP, 0)} between neighbouring truth pixels; edge band: the other unsaturated pixels; "
          "truth binned 2 × 2 by mean for superpixel.")

    print("\n## Targets\n")
    for method, ref_b, _, _, _, e2e_b, _ in rows:
        ratio = e2e_b / ref_b
        print(f"- {method}: end-to-end / rawpy = {ratio:.2f} (target ≤ 2): {'met' if ratio <= 2 else 'MISSED'}")
    for method, _, _, _, _, e2e_b, _ in rows:
        if method == "superpixel":
            rate = megapixels / e2e_b
            print(f"- superpixel end to end: {rate:.1f} MP/s (target ≥ 30): {'met' if rate >= 30 else 'MISSED'}")


if __name__ == "__main__":
    main()
