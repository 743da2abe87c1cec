"""The canonical room side by side with Radiance ``rpict``, from the same scene file.

One ``.rad`` file (FORMULAS.md Part A: the canonical room as ``plastic`` of zero
specularity and ``light`` panels) is read by :func:`lsadphoto.solver.read_radiance_scene`
for our solver and compiled by ``oconv`` for ``rpict``; both render the same 180°
equidistant fisheye (``-vta -vh 180 -vv 180`` from (1.0, 2.0, 1.2) along +x, up +z) at
the pixel centres (``-ps 1 -pj 0``). rpict runs without irradiance caching (``-aa 0``:
plain Monte Carlo hemisphere sampling, no interpolation bias), 256 ambient divisions, 8
ambient bounces, Russian roulette below weight 1e-4 (``-lr -10 -lw 1e-4``), no source
jitter (``-dj 0``: the direct light of the panels is computed without noise).

Noise of rpict (it has no seed option: two identical runs give identical pictures). A
second run with ``-ps 2 -pt 0`` re-traces the fill-in pixels in another order, so their
ambient samples are independent draws; σ_rpict/L is estimated from the pixels that differ
between the two runs as 1.4826·MAD(L_B/L_A − 1)/√2 (the MAD is robust to the few pixels
that ``-ps 2`` interpolates across edges), and applied as σ_rpict = (σ/L)·L_A. RGBE
quantisation adds ≤ 1/128 relative (uniform: σ ≤ 0.23 %); 0.25 % is added in quadrature.

Measured (64² px, 65 536 chains, 128 nodes per pixel and batch; 2 cores, shared):
field-mean luminance −0.10 %; σ_rpict/L ≈ 0.93 %; per-pixel z = (ours − rpict)/
√(σ_ours² + σ_rpict²): median |z| 0.67 (Gaussian: 0.674), 2.9 % beyond 3σ, all of them
negative and 5–15 cm from concave edges (see the note in the test); UGR 17.48 vs 17.50,
Q 0.2196 vs 0.2226 (−1.3 %). Wall time ≈ 30 s (the two rpict runs in parallel) + 10 s.
"""

import math
import os
import subprocess

import numpy as np
import pytest

from lsadphoto.io.hdr import read_hdr
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.metrics.score import score_map
from lsadphoto.solver import read_radiance_scene, render, simulate
from lsadphoto.solver.examples import canonical_room_rad

from .conftest import radiance_bin

SIZE = 64

#: The canonical room as a Radiance scene (the same file goes to our reader and to oconv).
ROOM_RAD = canonical_room_rad()

VIEW = ["-vta", "-vp", "1", "2", "1.2", "-vd", "1", "0", "0", "-vu", "0", "0", "1",
        "-vh", "180", "-vv", "180"]
AMBIENT = ["-ab", "8", "-ad", "256", "-aa", "0", "-lr", "-10", "-lw", "1e-4", "-dj", "0"]

#: Field-mean luminance, UGR and Q tolerances of the issue.
MEAN_TOL = 0.02
UGR_TOL = 0.5
Q_TOL = 0.02
#: RGBE quantisation, relative standard deviation (≤ 1/128 uniform → ≤ 0.23 %).
RGBE_SIGMA = 0.0025




@pytest.fixture(scope="module")
def pictures(tmp_path_factory):
    binpath = radiance_bin("rpict")
    tmp = tmp_path_factory.mktemp("rpict")
    rad = tmp / "room.rad"
    rad.write_text(ROOM_RAD)
    env = dict(os.environ, RAYPATH=os.path.join(binpath, "..", "lib"))
    octree = tmp / "room.oct"
    with open(octree, "wb") as fh:
        subprocess.run([os.path.join(binpath, "oconv"), str(rad)], stdout=fh, check=True, env=env)
    rpict = [os.path.join(binpath, "rpict"), *VIEW, "-x", str(SIZE), "-y", str(SIZE), "-pj", "0",
             *AMBIENT]
    with open(tmp / "A.hdr", "wb") as fa, open(tmp / "B.hdr", "wb") as fb:
        runs = [subprocess.Popen([*rpict, "-ps", "1", str(octree)], stdout=fa, env=env),
                subprocess.Popen([*rpict, "-ps", "2", "-pt", "0", str(octree)], stdout=fb, env=env)]
        # our solver on the same file while rpict runs
        scene = read_radiance_scene(rad, views=[{
            "name": "observer", "position": [1.0, 2.0, 1.2], "line_of_sight": [1, 0, 0],
            "up": [0, 0, 1], "projection": {"model": "fisheye-ideal", "kind": "equidistant",
                                            "fov_deg": 180, "width": SIZE, "height": SIZE}}])
        view = scene.views[0]
        store = simulate(scene, samples=65536, seed=1)
        ours = render(store, view.projection, position=view.position, rotation=view.rotation,
                      nodes_per_pixel=128, seed=2)
        for proc in runs:
            assert proc.wait(timeout=600) == 0
    return ours, read_hdr(tmp / "A.hdr"), read_hdr(tmp / "B.hdr")


@pytest.mark.slow
def test_same_projection(pictures):
    ours, a, _ = pictures
    # read_hdr takes the projection from rpict's VIEW= line: it must be ours, pixel for pixel
    assert repr(a.projection) == repr(ours.projection)
    rows, cols = ours.projection.pixel_grid()
    assert np.allclose(a.projection.directions(rows, cols), ours.projection.directions(rows, cols),
                       equal_nan=True)
    # rpict traces the corners beyond 180° too; inside the circle both have every pixel
    inside = np.isfinite(ours.luminance)
    assert inside.sum() > 0.75 * SIZE * SIZE and np.all(np.isfinite(a.luminance[inside]))


@pytest.mark.slow
def test_field_mean_within_two_percent(pictures):
    ours, a, _ = pictures
    ok = np.isfinite(ours.luminance)
    omega = ours.projection.solid_angles(*np.nonzero(ok))
    mean_rpict = (a.luminance[ok] * omega).sum() / omega.sum()
    mean_ours = ours.provenance["field_mean_luminance"]
    assert mean_ours == pytest.approx((ours.luminance[ok] * omega).sum() / omega.sum(), rel=1e-5)
    assert abs(mean_ours / mean_rpict - 1) <= MEAN_TOL  # measured −0.10 %


@pytest.mark.slow
def test_pixel_differences_match_the_noise(pictures):
    ours, a, b = pictures
    la, lb = a.luminance.astype(float), b.luminance.astype(float)
    ok = np.isfinite(ours.luminance) & (la > 0)
    redrawn = ok & (la != lb)
    assert redrawn.sum() > 0.5 * ok.sum()
    sigma_rel = 1.4826 * np.median(np.abs(lb[redrawn] / la[redrawn] - 1)) / math.sqrt(2)
    assert 0.001 < sigma_rel < 0.05  # measured 0.93 %
    sigma = np.sqrt(ours.uncertainty.astype(float) ** 2 + (sigma_rel ** 2 + RGBE_SIGMA ** 2) * la ** 2)
    z = ((ours.luminance - la) / sigma)[ok]
    # The bulk is Gaussian: median |z| of N(0, 1) is 0.674; ±20 % allows for the estimated
    # σ's (16 batches: ±18 % relative at 1σ per pixel, far less for the median).
    assert 0.54 < np.median(np.abs(z)) < 0.81
    assert abs(np.median(z)) < 0.15
    # The tail is heavier than Gaussian (0.27 % beyond 3σ): measured 2.9 %, all negative,
    # at points 5–15 cm from concave edges. There most of the irradiance comes from the
    # adjacent wall within a few ε (ε = 7.8 cm), i.e. from a few rare nodes of large
    # weight; with 128 uniformly drawn nodes per pixel and batch they are seldom drawn,
    # so the estimate is unbiased (the field mean agrees to 0.1 %) but skewed, and the
    # 16-batch σ underestimates its spread. The path tracer agrees with rpict there.
    assert np.mean(np.abs(z) > 3) < 0.05


@pytest.mark.slow
def test_ugr_and_q_agree(pictures):
    ours, a, _ = pictures
    mine = score_map(LuminanceMap(ours.luminance, projection=ours.projection, calibrated=True)).values
    theirs = score_map(a).values
    assert abs(mine["ugr_grouped"] - theirs["ugr_grouped"]) <= UGR_TOL  # measured 0.02
    assert abs(mine["ugr_pixel"] - theirs["ugr_pixel"]) <= UGR_TOL
    assert abs(mine["q"] / theirs["q"] - 1) <= Q_TOL  # measured −1.3 %
