"""Photon transfer: the noise model measured from flat pairs of a known synthetic sensor."""

import json
import subprocess
import sys

import numpy as np
import pytest

from lsadphoto.calibrate import load_profile
from lsadphoto.datasets import SyntheticCamera, write_dng

FULL_WELL, READ_NOISE, ISO = 20000.0, 5.0, 400
#: 96 × 128 px per channel in the centre half: each variance is known to ≈ 2 %, twelve points
#: (six levels, R and B) fix the slope to ≈ 1 %; the dark pair fixes σ_r to ≈ 1.5 %. Bounds
#: 3 % (full well) and 5 % (read noise) are about 3 standard errors.
FULL_WELL_RTOL, READ_NOISE_RTOL = 0.03, 0.05


def test_photon_transfer_recovers_the_sensor(tmp_path):
    camera = SyntheticCamera(width=512, height=384, full_well=FULL_WELL, read_noise=READ_NOISE)
    rng = np.random.default_rng(7)
    flat = np.full((camera.height, camera.width), 100.0)
    paths = []
    for k, t in enumerate((1 / 4000, 1 / 2000, 1 / 1000, 1 / 500, 1 / 250, 1 / 125)):
        for j in range(2):
            raw = camera.expose(flat, exposure_time=t, f_number=8.0, iso=ISO, rng=rng)
            paths.append(write_dng(tmp_path / f"flat{k}{j}.dng", raw, camera, exposure_time=t, f_number=8.0, iso=ISO))
    darks = []
    for j in range(2):
        raw = camera.expose(np.zeros_like(flat), exposure_time=1 / 125, f_number=8.0, iso=ISO, rng=rng)
        darks.append(write_dng(tmp_path / f"dark{j}.dng", raw, camera, exposure_time=1 / 125, f_number=8.0, iso=ISO))
    out = tmp_path / "noise.toml"
    run = subprocess.run([sys.executable, "-m", "lsadphoto.cli", "calibrate", "noise", *map(str, paths), "--dark",
                          *map(str, darks), "-o", str(out), "--json"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    record = json.loads(run.stdout)
    assert record["full_well_electrons"] == pytest.approx(FULL_WELL, rel=FULL_WELL_RTOL)
    assert record["read_noise_electrons"] == pytest.approx(READ_NOISE, rel=READ_NOISE_RTOL)
    profile = load_profile(out)
    assert profile.noise_measured and "noise" not in profile.nominal_values()
    assert "photon transfer" in profile.sources["noise"]
