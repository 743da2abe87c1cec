"""Make the bundled ``data_samples/`` and the demo camera profile (deterministic).

Run ``python -m lsadphoto.datasets.samples data_samples`` (or ``make samples``). Writes:

- ``office/office_{1,2,3}.dng``: a 3-frame bracket (f/5.6, ISO 100; 1/15, 1/500, 1/8000 s) of
  :func:`~lsadphoto.datasets.interior_scene` through the demo camera, with shot and read noise;
- ``office/spots.csv``: two spot-meter readings (row, col, cd/m²) on the grey target and the
  wall, computed from the true scene over the LS-100's 1° cone and rounded as its display does;
- ``flat/flat_{1,2}.dng``: flat-field frames of a uniform 40 cd/m² field for
  ``lsadphoto calibrate vignetting``;
- ``../calibration/synthetic-demo.toml``: the demo camera's profile.
"""

import sys
from pathlib import Path

import numpy as np

from ..calibrate.profile import CameraProfile, save_profile
from ..calibrate.spot import spot_cone
from ..calibrate.vignetting import VignettingModel
from ..constants import LS100_ACCEPTANCE_ANGLE
from ..geometry.pinhole import PinholeProjection
from ..raw.bracket import NoiseModel
from .scenes import interior_scene, uniform_field
from .synthetic import SyntheticCamera, write_dng

DEMO_CAMERA = SyntheticCamera(width=640, height=424, vignetting=(-0.3, 0.05), read_noise=3.0,
                              full_well=30000.0, model="synthetic demo camera")
BRACKET = [(1 / 15, 5.6, 100), (1 / 500, 5.6, 100), (1 / 8000, 5.6, 100)]
SPOT_POSITIONS = [(0.62, 0.5), (0.85, 0.15)]  # fractions of rows, cols


def demo_scene():
    """The true luminance of the demo view [cd·m⁻²] (sensor resolution)."""
    return interior_scene((DEMO_CAMERA.height, DEMO_CAMERA.width))


def demo_profile():
    cam = DEMO_CAMERA
    return CameraProfile(
        id="synthetic-demo", camera=f"{cam.make} {cam.model}", lens=f"{cam.focal_length:g} mm rectilinear",
        sensor_width=cam.sensor_width, sensor_height=cam.sensor_height, width=cam.width, height=cam.height,
        focal_length=cam.focal_length,
        vignetting=VignettingModel(kind="polynomial", coefficients=list(cam.vignetting)),
        calibration_constant=cam.calibration_constant, calibration_constant_uncertainty=0.02,
        noise=NoiseModel(full_well=cam.full_well, read_noise=cam.read_noise),
        provenance={"source": "lsadphoto.datasets.samples: the synthetic camera's own parameters (exact)"},
    )


def meter_reading(luminance, projection, row, col):
    """What an LS-100 would display aimed at (row, col): the cone mean, 3 significant digits."""
    window, mask, weights = spot_cone(projection, row, col, LS100_ACCEPTANCE_ANGLE)
    value = float(np.sum(luminance[window][mask] * weights[mask]) / np.sum(weights[mask]))
    return float(f"{value:.3g}")


def make_samples(folder):
    folder = Path(folder)
    cam = DEMO_CAMERA
    rng = np.random.default_rng(20261123)
    scene = demo_scene()
    for i, (t, n, iso) in enumerate(BRACKET, start=1):
        raw = cam.expose(scene, exposure_time=t, f_number=n, iso=iso, rng=rng)
        write_dng(folder / "office" / f"office_{i}.dng", raw, cam, exposure_time=t, f_number=n, iso=iso)
    projection = PinholeProjection.from_sensor(focal_length=cam.focal_length, sensor_width=cam.sensor_width,
                                               sensor_height=cam.sensor_height, width=cam.width, height=cam.height)
    lines = ["row,col,cd_m2"]
    for fr, fc in SPOT_POSITIONS:
        row, col = round(fr * cam.height), round(fc * cam.width)
        lines.append(f"{row},{col},{meter_reading(scene, projection, row, col):g}")
    (folder / "office" / "spots.csv").write_text("\n".join(lines) + "\n")
    flat = uniform_field((cam.height, cam.width), 40.0)
    for i in (1, 2):
        raw = cam.expose(flat, exposure_time=1 / 60, f_number=4.0, iso=100, rng=rng)
        write_dng(folder / "flat" / f"flat_{i}.dng", raw, cam, exposure_time=1 / 60, f_number=4.0, iso=100)
    save_profile(demo_profile(), folder.parent / "calibration" / "synthetic-demo.toml")


if __name__ == "__main__":
    make_samples(sys.argv[1] if len(sys.argv) > 1 else "data_samples")
