"""The Radiance scene reader, and the solver against Radiance's rpict (pyradiance binaries)."""

import os
import subprocess

import numpy as np
import pytest

from lsadphoto.solver import render, simulate
from lsadphoto.solver.examples import canonical_room, canonical_room_rad
from lsadphoto.solver.formats import read_radiance_scene

from .conftest import radiance_bin

#: The canonical room as a Radiance scene (the same file goes to our reader and to oconv).
ROOM_RAD = canonical_room_rad()


def test_reader_gives_the_canonical_room():
    scene = read_radiance_scene(ROOM_RAD)
    room = canonical_room(size=16)
    assert scene.total_flux == pytest.approx(room.total_flux, rel=1e-12)
    assert scene.areas.sum() == pytest.approx(room.areas.sum(), rel=1e-12)
    assert sorted(scene.triangle_reflectance.round(12)) == sorted(room.triangle_reflectance.round(12))
    emit = scene.emitter >= 0
    assert np.allclose(scene.normals[emit], [0, 0, -1])




@pytest.mark.slow
def test_double_local_estimate_agrees_with_rpict(tmp_path):
    # Peer tool: Radiance rpict with irradiance caching (-ab 5 -ad 512 -as 128 -aa 0.1
    # -ar 128; 16² px to keep it near 30 s), pixel centres (-ps 1 -pj 0), the same -vta view (IdealFisheyeProjection.
    # radiance_view). Radiance's ambient cache interpolates (biased a few % near edges and
    # at the luminaires' rims) and RGBE stores 0.4 %, so the comparison is statistical: the
    # median pixel ratio within 2 % and half of the pixels within 4 %. Measured at 32²
    # (-ad 1024 -as 256 -ar 256): median +0.4 %, interquartile range −2.3 … +3.0 %.
    from lsadphoto.io.hdr import read_hdr

    binpath = radiance_bin("rpict")
    rad = tmp_path / "room.rad"
    rad.write_text(ROOM_RAD)
    env = dict(os.environ, RAYPATH=os.path.join(binpath, "..", "lib"))
    octree = tmp_path / "room.oct"
    with open(octree, "wb") as fh:
        subprocess.run([os.path.join(binpath, "oconv"), str(rad)], stdout=fh, check=True, env=env)
    scene = read_radiance_scene(rad, views=[{
        "name": "observer", "position": [1.0, 2.0, 1.2], "line_of_sight": [1, 0, 0], "up": [0, 0, 1],
        "projection": {"model": "fisheye-ideal", "width": 16, "height": 16}}])
    view = scene.views[0]
    options = view.projection.radiance_view().split()
    options[options.index("-vp") + 1:options.index("-vp") + 4] = ["1", "2", "1.2"]
    options[options.index("-vd") + 1:options.index("-vd") + 4] = ["1", "0", "0"]
    picture = tmp_path / "room.hdr"
    with open(picture, "wb") as fh:
        subprocess.run([os.path.join(binpath, "rpict"), *options, "-x", "16", "-y", "16", "-pa", "0",
                        "-ps", "1", "-pj", "0", "-ab", "5", "-ad", "512", "-as", "128", "-aa", "0.1",
                        "-ar", "128", "-lw", "1e-4", "-dj", "0", str(octree)],
                       stdout=fh, check=True, env=env, timeout=600)
    radiance = read_hdr(picture).luminance
    store = simulate(scene, samples=65536, seed=1)
    ours = render(store, view.projection, position=view.position, rotation=view.rotation,
                  nodes_per_pixel=128).luminance
    ok = np.isfinite(ours) & (ours > 0) & np.isfinite(radiance)
    ratio = radiance[ok] / ours[ok] - 1
    assert abs(np.median(ratio)) < 0.02
    assert np.mean(np.abs(ratio) < 0.04) >= 0.5
