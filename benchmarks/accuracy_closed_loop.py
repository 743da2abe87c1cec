"""Closed-loop accuracy of the luminance stage on synthetic DNGs (figures for docs/accuracy.md).

Run: ``.venv/bin/python benchmarks/accuracy_closed_loop.py``. Every figure compares with the
luminance the synthetic camera was given.
"""

import tempfile
import warnings
from pathlib import Path

import numpy as np
from scipy.ndimage import maximum_filter, minimum_filter

from lsadphoto import luminance_from_raw
from lsadphoto.calibrate import CameraProfile, SpotReading
from lsadphoto.datasets import SyntheticCamera, interior_scene, write_dng

warnings.simplefilter("ignore")


def profile(cam):
    return CameraProfile(id="acc", sensor_width=cam.sensor_width, sensor_height=cam.sensor_height, width=cam.width,
                         height=cam.height, focal_length=cam.focal_length,
                         calibration_constant=cam.calibration_constant)


def binned(x):
    return x.reshape(x.shape[0] // 2, 2, x.shape[1] // 2, 2).mean(axis=(1, 3))


def smooth(truth, radius):
    size = 2 * radius + 1
    return maximum_filter(truth, size) <= 1.15 * minimum_filter(truth, size)


def shoot(folder, cam, scene, name, *, t=1 / 125, n=4.0, iso=100, noise=False, seed=0):
    raw = cam.expose(scene, exposure_time=t, f_number=n, iso=iso, noise=noise, rng=np.random.default_rng(seed))
    return write_dng(folder / f"{name}.dng", raw, cam, exposure_time=t, f_number=n, iso=iso)


def main():
    folder = Path(tempfile.mkdtemp())
    cam = SyntheticCamera(width=1024, height=768)
    scene = interior_scene((cam.height, cam.width))
    print("| demosaic | noise | median abs. rel. error | 99th percentile | pixels checked |")
    print("|---|---|---|---|---|")
    for noise in (False, True):
        path = shoot(folder, cam, scene, f"scene_{noise}", noise=noise, iso=400 if noise else 100,
                     t=1 / 500 if noise else 1 / 125, seed=1)
        for method in ("superpixel", "linear", "ahd", "dcb"):
            result = luminance_from_raw([path], profile=profile(cam), demosaic=method)
            truth = binned(scene) if method == "superpixel" else scene
            mask = smooth(truth, 2 if method == "superpixel" else 4) & np.isfinite(result.map.luminance)
            err = np.abs(result.map.luminance[mask] / truth[mask] - 1)
            print(f"| {method} | {'ISO 400 shot+read' if noise else 'none'} | {100 * np.median(err):.3f} % | "
                  f"{100 * np.percentile(err, 99):.3f} % | {mask.mean() * 100:.0f} % |")
    # Noise model consistency (superpixel, uniform field).
    flat = np.full((cam.height, cam.width), 40.0)
    result = luminance_from_raw([shoot(folder, cam, flat, "flat", noise=True, iso=800, t=1 / 500, seed=2)],
                                profile=profile(cam))
    lmap = result.map
    u_noise = np.sqrt(lmap.uncertainty.astype(float) ** 2 - (lmap.calibration_uncertainty * lmap.luminance) ** 2)
    z = (lmap.luminance - 40.0) / u_noise
    print(f"\nnoise model: SD of (L − L_true)/u_noise = {np.std(z):.3f}, mean {np.mean(z):+.3f} "
          f"(ISO 800, {z.size} pixels)")
    # Spot factor with noise, 5 seeds.
    errors = []
    for seed in range(5):
        path = shoot(folder, cam, scene, f"spot{seed}", noise=True, iso=400, t=1 / 1000, seed=10 + seed)
        r = luminance_from_raw([path], profile=profile(cam),
                               spots=[SpotReading(0.62 * cam.height, 0.5 * cam.width, 60.0)])
        errors.append(r.summary["calibration_factor"] / cam.calibration_constant - 1)
    print(f"spot factor error (5 noisy shots, 1 spot): max |error| {100 * np.max(np.abs(errors)):.3f} %, "
          f"reported u = {100 * r.summary['calibration_uncertainty']:.2f} %")
    # Bracket over seven decades.
    ramp_cam = SyntheticCamera(width=1000, height=64)
    ramp = np.tile(np.logspace(-2, 5, ramp_cam.width), (ramp_cam.height, 1))
    settings = [(0.5, 2.0), (1 / 160, 4.0), (1 / 16000, 8.0)]
    for noise in (False, True):
        paths = [shoot(folder, ramp_cam, ramp, f"ramp{i}{noise}", t=t, n=n, noise=noise, seed=20 + i)
                 for i, (t, n) in enumerate(settings)]
        r = luminance_from_raw(paths, profile=profile(ramp_cam))
        err = np.abs(r.map.luminance / binned(ramp) - 1)
        col_err = np.abs(np.nanmean(r.map.luminance, axis=0) / binned(ramp)[0] - 1)
        print(f"bracket 0.01–100 000 cd/m², {'noisy' if noise else 'noise-free'}: max |error| "
              f"{100 * np.nanmax(err):.2f} %, median {100 * np.nanmedian(err):.3f} %, "
              f"max error of column means {100 * np.nanmax(col_err):.2f} %, unknown pixels {np.isnan(err).mean():.3f}")


if __name__ == "__main__":
    main()
