"""Peer agreement with Radiance's evalglare (PyPI ``pyradiance`` ships the binary).

Fisheye pictures are made by the project's own generators (uniform caps of known size and
luminance on a background; windows of 0.7–1.5 sr with luminance gradients and mullions,
below the line of sight and at the rim of the 180° image, lamps spaced about the search
radius), written as Radiance HDR with a ``-vta`` VIEW= line, and scored by evalglare and by
:func:`lsadphoto.metrics.score.score_map` in the same run — both read the same
RGBE-quantised file. Settings are evalglare's defaults and ours: fixed 2000 cd·m⁻²
threshold, ``-r 0.2``, peak extraction at 50 000 cd·m⁻², CIE background, evalglare's
position index at evalglare's source position, VCP with 6.374 (evalglare ≥ 2.07).
"""

import math
import os
import subprocess

import numpy as np
import pytest

from lsadphoto.datasets import disk_sources_scene, window_scene
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
    """evalglare -d: the summary line as a dict, with ``n_sources`` and ``sources`` (per
    source: x-pos, y-pos and Posindx of the -d table)."""
    proc = subprocess.run([EVALGLARE, "-d", str(path)], capture_output=True, text=True,
                          check=True, timeout=120)
    lines = proc.stdout.strip().splitlines()
    summary = next(line for line in lines if line.startswith("dgp,av_lum"))
    values = [float(v) for v in summary.split(":", 1)[1].split()]
    result = dict(zip(KEYS, values, strict=True))
    result["n_sources"] = int(lines[0].split()[0])
    # Rows "No pixels x-pos y-pos L_s Omega_s Posindx …"; y-pos is our row + 1.
    rows = [line.split() for line in lines[1:1 + result["n_sources"]]]
    result["sources"] = [(float(r[2]), float(r[3]), float(r[6])) for r in rows]
    return result


def _agree(v, peer):
    """The agreement targets of issue 11: grouped UGR within 0.1, DGP within 0.005,
    DGI/DGI_mod/CGI/UGR_exp within 0.2; UGP and UGP2 (0.26 and ≈0.4 per 8 UGR units at these
    levels) within 0.005, DGR within 0.5 %, VCP within 0.5 point. The field integrals use the
    same corner-quad solid angles: within 0.5 % (the two programs differ only at the rim
    pixels of the image circle)."""
    assert v["n_sources"] == peer["n_sources"]
    assert v["ugr_grouped"] == pytest.approx(peer["ugr"], abs=0.1)
    assert v["dgp"] == pytest.approx(peer["dgp"], abs=0.005)
    for ours_key, peer_key in (("dgi", "dgi"), ("ugr_exp", "ugr_exp"), ("dgi_mod", "dgi_mod"),
                               ("cgi", "cgi")):
        assert v[ours_key] == pytest.approx(peer[peer_key], abs=0.2), ours_key
    assert v["vertical_illuminance"] == pytest.approx(peer["E_v"], rel=5e-3)
    assert v["background_luminance"] == pytest.approx(peer["lum_backg"], rel=5e-3)
    assert v["direct_illuminance"] == pytest.approx(peer["E_v_dir"], rel=5e-3)
    assert v["source_solid_angle"] == pytest.approx(peer["omega_sources"], rel=5e-3)
    assert v["ugp"] == pytest.approx(peer["ugp"], abs=0.005)
    assert v["ugp2"] == pytest.approx(peer["ugp2"], abs=0.005)
    assert v["dgr"] == pytest.approx(peer["dgr"], rel=5e-3)
    assert v["vcp"] == pytest.approx(peer["vcp"], abs=0.5)


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
    _agree(score_map(read_hdr(path)).values, run_evalglare(path))


#: Scenes that look like real ones: large non-uniform windows, a source below the line of
#: sight, one at the rim of the 180° image, lamps about r/2 = 5.7° apart (two of them, 22°
#: apart in τ at σ = 30°, are 11.4° centre to centre, 5.7° edge to edge: they merge; the
#: third is 0.3° further out: it does not), a lamp with a peak-extracted neighbour.
REAL_SCENES = {
    "office window 1.5 sr with a mullion": dict(
        background=(40.0, 160.0),
        windows=[dict(azimuth=(-15, 75), elevation=(-8, 55), luminance=(2600.0, 14000.0),
                      side_gradient=0.6, mullions=(30.0,), mullion_width=3.0)]),
    "low window below the line of sight": dict(
        background=(60.0, 140.0),
        windows=[dict(azimuth=(-35, 35), elevation=(-55, -12), luminance=(9000.0, 3000.0),
                      side_gradient=-0.4)]),
    "window at the rim": dict(
        background=(50.0, 120.0),
        windows=[dict(azimuth=(55, 90), elevation=(-25, 45), luminance=(3000.0, 20000.0),
                      side_gradient=0.5)]),
    "lamps merging at the search radius": dict(
        background=(30.0, 90.0),
        disks=[(_direction(30, 40), 0.03, 20000.0), (_direction(30, 62), 0.03, 15000.0),
               (_direction(30, 84.5), 0.03, 9000.0), (_direction(55, 200), 0.05, 6000.0),
               (_direction(55, 213), 0.05, 70000.0)],
        windows=[dict(azimuth=(-70, -30), elevation=(10, 50), luminance=(2500.0, 6000.0))]),
}


def _sources_at_evalglare_positions(score, peer):
    """Each of evalglare's sources (its -d table: x, y from the bottom, P) has one of ours at
    the same pixel with the same P, to the float32 precision of evalglare's get_posindex."""
    for x, y, p in peer["sources"]:
        ours = min(score.sources, key=lambda s: (s.col - x) ** 2 + (s.row + 1 - y) ** 2)
        assert (ours.col, ours.row + 1) == pytest.approx((x, y), abs=1e-3)
        assert ours.position_index == pytest.approx(p, rel=1e-5)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(REAL_SCENES))
def test_real_looking_scenes_agree_with_evalglare(tmp_path, camera, name):
    d = camera.directions(*camera.pixel_grid())
    path = tmp_path / "scene.hdr"
    write_hdr(LuminanceMap(window_scene(d, **REAL_SCENES[name]), projection=camera,
                           calibrated=True), path)
    peer = run_evalglare(path)
    score = score_map(read_hdr(path))
    _agree(score.values, peer)
    # Each source's position index is evalglare's: the same pixel, so the same P to the
    # float32 precision of evalglare's get_posindex (its -d table prints 6 digits).
    _sources_at_evalglare_positions(score, peer)


@pytest.mark.slow
def test_real_rendering_with_the_sun_agrees_with_evalglare():
    """A real Radiance rendering (raytraverse's office desk, 1000² -vta, sun in view): nine
    sources, from the sun's disk to a 9-pixel glint, each at evalglare's position."""
    from .conftest import realdata

    path = realdata("hdr/raytraverse_rendered_desk_vta.hdr")
    peer = run_evalglare(path)
    score = score_map(read_hdr(path))
    _agree(score.values, peer)
    _sources_at_evalglare_positions(score, peer)
