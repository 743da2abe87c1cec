"""Peer agreement with Radiance's evalglare (PyPI ``pyradiance`` ships the binary).

Fisheye pictures are made by the project's own generator (uniform caps of known size and
luminance on a background), written as Radiance HDR with a ``-vta`` VIEW= line, and scored
by evalglare and by :func:`lsadphoto.metrics.score.score_map` in the same run — both read the
same RGBE-quantised file. Settings are matched: fixed 2000 cd·m⁻² threshold, ``-r 0.2``,
peak extraction at 50 000 cd·m⁻², CIE background, evalglare's position index, VCP with
evalglare's constant 6.347.
"""

import math
import os
import subprocess

import numpy as np
import pytest

from lsadphoto.datasets import disk_sources_scene
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.io import read_hdr, write_hdr
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.metrics.score import score_map

pyradiance = pytest.importorskip("pyradiance", reason="pyradiance (evalglare) not installed")
EVALGLARE = os.path.join(os.path.dirname(pyradiance.__file__), "bin", "evalglare")

SIZE = 600
KEYS = ("dgp", "av_lum", "E_v", "lum_backg", "E_v_dir", "dgi", "ugr", "vcp", "cgi",
        "lum_sources", "omega_sources", "Lveil", "Lveil_cie", "dgr", "ugp", "ugr_exp", "dgi_mod",
        "av_lum_pos", "av_lum_pos2", "med_lum", "med_lum_pos", "med_lum_pos2", "ugp2")


def run_evalglare(path):
    """evalglare -d: the number of sources and the summary line as a dict."""
    proc = subprocess.run([EVALGLARE, "-d", str(path)], capture_output=True, text=True,
                          check=True, timeout=120)
    lines = proc.stdout.strip().splitlines()
    summary = next(line for line in lines if line.startswith("dgp,av_lum"))
    values = [float(v) for v in summary.split(":", 1)[1].split()]
    result = dict(zip(KEYS, values, strict=True))
    result["n_sources"] = int(lines[0].split()[0])
    return result


def _direction(sigma_deg, tau_deg):
    """Camera-frame direction σ from the optical axis, τ around it from straight up."""
    s, t = math.radians(sigma_deg), math.radians(tau_deg)
    return np.array([math.sin(s) * math.sin(t), -math.sin(s) * math.cos(t), math.cos(s)])


SCENES = {
    "one source above": dict(background=120.0, sources=[(_direction(25, 0), 0.05, 20000.0)]),
    "three sizes above, below, beside": dict(background=150.0, sources=[
        (_direction(20, 10), 0.02, 30000.0), (_direction(35, 180), 0.07, 5000.0),
        (_direction(50, 90), 0.14, 3000.0)]),
    "window with the sun": dict(background=60.0, sources=[
        (_direction(40, 60), 0.25, 8000.0), (_direction(45, 55), 0.012, 1.6e9)]),
    "dim room, small bright lamps": dict(background=8.0, sources=[
        (_direction(15, 300), 0.01, 45000.0), (_direction(30, 200), 0.015, 12000.0),
        (_direction(60, 120), 0.03, 2500.0)]),
}


@pytest.fixture(scope="module")
def camera():
    return IdealFisheyeProjection("equidistant", (SIZE - 1) / 2, (SIZE - 1) / 2, SIZE / 2, 180.0,
                                  SIZE, SIZE)


@pytest.mark.parametrize("name", sorted(SCENES))
def test_grouped_ugr_and_dgp_agree_with_evalglare(tmp_path, camera, name):
    d = camera.directions(*camera.pixel_grid())
    L = disk_sources_scene(d, **SCENES[name])
    path = tmp_path / "scene.hdr"
    write_hdr(LuminanceMap(L, projection=camera, calibrated=True), path)
    peer = run_evalglare(path)
    ours = score_map(read_hdr(path), vcp_constant=6.347)
    v = ours.values
    # The agreement targets: grouped UGR within 0.5, DGP within 0.01.
    assert v["ugr_grouped"] == pytest.approx(peer["ugr"], abs=0.5)
    assert v["dgp"] == pytest.approx(peer["dgp"], abs=0.01)
    assert v["n_sources"] == peer["n_sources"]
    # Field integrals use the same corner-quad solid angles: within 0.5 % (the two programs
    # differ only at the rim pixels of the image circle).
    assert v["vertical_illuminance"] == pytest.approx(peer["E_v"], rel=5e-3)
    assert v["background_luminance"] == pytest.approx(peer["lum_backg"], rel=5e-3)
    assert v["direct_illuminance"] == pytest.approx(peer["E_v_dir"], rel=5e-3)
    # The other indices follow from the same sources: the same relative tolerance as UGR's
    # (0.5 on ≈25) for the log-scaled ones, 2 % for DGR, 1 point for VCP.
    for ours_key, peer_key in (("dgi", "dgi"), ("ugr_exp", "ugr_exp"), ("dgi_mod", "dgi_mod"),
                               ("cgi", "cgi")):
        assert v[ours_key] == pytest.approx(peer[peer_key], abs=0.5), ours_key
    assert v["ugp"] == pytest.approx(peer["ugp"], abs=0.02)
    assert v["ugp2"] == pytest.approx(peer["ugp2"], abs=0.02)
    assert v["dgr"] == pytest.approx(peer["dgr"], rel=0.02)
    assert v["vcp"] == pytest.approx(peer["vcp"], abs=1.0)
