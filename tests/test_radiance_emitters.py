"""Radiance's secondary and directed emitters in the scene reader: illum and spotlight.

References: the Radiance reference manual (refman, "illum", "spotlight") and Radiance's own
programs on the same files (rtrace), as each test says.
"""

import numpy as np
import pytest

from lsadphoto.errors import BadInputError, SolverWarning
from lsadphoto.solver import read_radiance_scene

LAMP = ("void plastic grey 0 0 5 .5 .5 .5 0 0\nvoid light lamp 0 0 3 10 10 10\n"
        "grey polygon floor 0 0 12 -3 -3 0  3 -3 0  3 3 0  -3 3 0\n"
        "lamp polygon panel 0 0 12 -.5 -.5 3  -.5 .5 3  .5 .5 3  .5 -.5 3\n")
WINDOW = "polygon window 0 0 12 -1 -1 1  1 -1 1  1 1 1  -1 1 1\n"


def _surfaces(scene):
    """Triangles and reflectances of the scene's non-emitting surfaces, in order."""
    passive = scene.emitter < 0
    return scene.triangles[passive], scene.triangle_reflectance[passive]


def test_illum_is_its_alternate_material_or_invisible():
    # refman: an illum is a light source for shadow rays only; all other rays see its
    # alternate material, or nothing when it has none (void). The solver computes the light
    # the illum stands for by interreflection, so the reference is the same scene written with
    # the alternate material itself, or without the surface.
    plain = read_radiance_scene(LAMP + "grey " + WINDOW)
    alternate = read_radiance_scene(LAMP + "void illum ill 1 grey 0 3 50 50 50\nill " + WINDOW)
    for a, b in zip(_surfaces(plain), _surfaces(alternate)):
        np.testing.assert_array_equal(a, b)
    without = read_radiance_scene(LAMP)
    for invisible in ("void illum ill 0 0 3 50 50 50\n", "void illum ill 1 void 0 3 50 50 50\n"):
        scene = read_radiance_scene(LAMP + invisible + "ill " + WINDOW)
        for a, b in zip(_surfaces(without), _surfaces(scene)):
            np.testing.assert_array_equal(a, b)
        assert scene.total_flux == pytest.approx(without.total_flux, rel=1e-12)


def test_illum_with_an_illum_as_alternate_is_refused():
    with pytest.raises(BadInputError, match="another illum"):
        read_radiance_scene(LAMP + "void illum a 1 grey 0 3 1 1 1\nvoid illum b 1 a 0 3 1 1 1\nb " + WINDOW)


SPOT = ("void plastic black 0 0 5 0 0 0 0 0\n"
        "void spotlight spot 0 0 7 20 20 20 60 0 0 -0.0005\n"
        "black polygon floor 0 0 12 -6 -6 0  6 -6 0  6 6 0  -6 6 0\n"
        "spot polygon panel 0 0 12 -.25 -.25 3  -.25 .25 3  .25 .25 3  .25 -.25 3\n")
#: floor points: on the axis, 1 m off it in x and in y (18.4°, ±4.8° over the panel: inside the
#: 60° cone), 2.5 m off (39.8°: outside)
POINTS = np.array([[0.0, 0.0, 1e-4], [1.0, 0.0, 1e-4], [0.0, 1.0, 1e-4], [2.5, 0.0, 1e-4]])


def _rtrace_illuminance(tmp_path, text):
    """rtrace -I -ab 0 (direct light only, fine source subdivision, no jitter) at POINTS [lx]."""
    import os
    import subprocess

    from .conftest import radiance_tool

    (tmp_path / "spot.rad").write_text(text)
    env = dict(os.environ, RAYPATH=os.path.join(os.path.dirname(radiance_tool("oconv")), "..", "lib"))
    with open(tmp_path / "spot.oct", "wb") as fh:
        subprocess.run([radiance_tool("oconv"), "spot.rad"], stdout=fh, check=True, cwd=tmp_path, env=env)
    rays = "".join(f"{x} {y} {z} 0 0 1\n" for x, y, z in POINTS)
    out = subprocess.run([radiance_tool("rtrace"), "-h", "-I", "-ab", "0", "-ds", "0.01", "-dj", "0",
                          "spot.oct"], input=rays, capture_output=True, text=True, check=True,
                         cwd=tmp_path, env=env).stdout
    rgb = np.array([[float(v) for v in line.split()] for line in out.strip().splitlines()])
    return 179.0 * rgb @ [0.265074, 0.670115, 0.064811]


def _our_illuminance(scene):
    from lsadphoto.solver.direct import direct_illuminance
    from lsadphoto.solver.engine import engine_for

    up = np.tile([0.0, 0.0, 1.0], (len(POINTS), 1))
    return direct_illuminance(scene, engine_for(scene), POINTS, up, samples=4096, seed=1)[0]


def test_spotlight_direct_illuminance_equals_rtrace(tmp_path):
    # Peer: rtrace on the same file. A 0.5 m square spotlight 3 m above a black floor, cone 60°
    # about the nadir, aim vector 0.5 mm long (a negligible focus: the solver emits from the
    # panel, which renders show). Radiance gives 0 outside the cone. Inside, the solver's
    # tabulated intensity (1° grid, bilinear) and its sampling of the opening (4096 samples:
    # ±0.5 %) allow 1.5 %.
    reference = _rtrace_illuminance(tmp_path, SPOT)
    scene = read_radiance_scene(tmp_path / "spot.rad")
    (lum,) = scene.point_luminaires
    assert lum.photometry.format == "Radiance spotlight" and lum.extent[0] == pytest.approx(0.5)
    ours = _our_illuminance(scene)
    assert reference[3] == 0 and ours[3] == 0
    np.testing.assert_allclose(ours[:3], reference[:3], rtol=0.015)


def test_spotlight_focus_behind_the_surface_equals_rtrace_on_its_axis(tmp_path):
    # A unit aim vector: Radiance's effective focus 1 m behind the panel scales the direct
    # light by (d/(d + 1))² — 0.56 under the panel. The solver emits from the focus point: on
    # the axis exactly Radiance's (1.5 % as above). 1 m off the axis the two differ by design:
    # Radiance takes the panel's cosines (3/√10 at both ends) over (√10 + 1)², the solver a
    # point at the focus, cosines 4/√17 over 17 m² — ours/Radiance = (16/289)/(0.9/(√10 + 1)²)
    # = 1.066, which the reference is corrected by.
    text = SPOT.replace("0 0 -0.0005", "0 0 -1")
    reference = _rtrace_illuminance(tmp_path, text)
    with pytest.warns(SolverWarning, match="effective focus 1 m behind the surface"):
        scene = read_radiance_scene(tmp_path / "spot.rad")
    (lum,) = scene.point_luminaires
    np.testing.assert_allclose(lum.position, [0.0, 0.0, 4.0], atol=1e-9)
    assert lum.extent == (0.0, 0.0)
    ours = _our_illuminance(scene)
    off_axis = (16 / 289) / (0.9 / (np.sqrt(10) + 1) ** 2)
    np.testing.assert_allclose(ours[:3], reference[:3] * [1.0, off_axis, off_axis], rtol=0.015)
    assert reference[3] == 0 and ours[3] == 0


def test_spotlight_cone_and_aim_follow_xform(tmp_path):
    # The aim vector turns with the surfaces (Radiance's xform rotates a spotlight's direction):
    # rotated by 90° about x, the nadir-pointing spotlight points along +y, with the same flux.
    # Closed form of that flux: a flat Lambertian patch of luminance L and area A seen within
    # a cone of half angle θ about its normal emits L·A·π·sin²θ (here θ = 30°).
    (tmp_path / "spot.rad").write_text(SPOT)
    (tmp_path / "turned.rad").write_text("!xform -rx 90 spot.rad\n")
    (a,) = read_radiance_scene(tmp_path / "spot.rad").point_luminaires
    (b,) = read_radiance_scene(tmp_path / "turned.rad").point_luminaires
    np.testing.assert_allclose(a.frame[2], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(b.frame[2], [0, 1, 0], atol=1e-12)
    assert b.flux == pytest.approx(a.flux, rel=1e-9)
    # 2e-3: the bilinear table on a 1° grid with the cone's edge between two nodes 1e-6° apart
    assert a.flux == pytest.approx(179 * 20 * 0.25 * np.pi * 0.25, rel=2e-3)
    with pytest.raises(BadInputError, match="cone angle"):
        read_radiance_scene(SPOT.replace("20 20 20 60 0 0 -0.0005", "20 20 20 0 0 0 -0.0005"))


def test_instance_is_read_from_the_files_its_octree_was_compiled_from(tmp_path):
    # Peer: Radiance's own oconv makes the octree (its header records the command); the
    # reference is the same chair placed by !xform with the instance's transform words —
    # what Radiance renders for an instance with modifier void. The instance's definitions
    # stay inside it: the outer scene's 'grey' (ρ = 0.5) is not replaced by the chair's (0.2).
    import os
    import subprocess

    from .conftest import radiance_tool

    (tmp_path / "chair.rad").write_text("void plastic grey 0 0 5 .2 .2 .2 0 0\n!genbox grey seat .5 .5 .45\n")
    env = dict(os.environ, PATH=os.pathsep.join([os.path.dirname(radiance_tool("oconv")), os.environ["PATH"]]))
    with open(tmp_path / "chair.oct", "wb") as fh:
        subprocess.run([radiance_tool("oconv"), "-f", "chair.rad"], stdout=fh, check=True, cwd=tmp_path, env=env)
    head = LAMP
    (tmp_path / "room.rad").write_text(head + "void instance chair1 7 chair.oct -rz 30 -t 1 0 0 0 0\n"
                                       "grey polygon wall 0 0 12 3 -3 0  3 3 0  3 3 3  3 -3 3\n")
    (tmp_path / "xformed.rad").write_text(head + "!xform -n chair1 -rz 30 -t 1 0 0 chair.rad\n"
                                          "void plastic grey 0 0 5 .5 .5 .5 0 0\n"
                                          "grey polygon wall 0 0 12 3 -3 0  3 3 0  3 3 3  3 -3 3\n")
    a, b = (read_radiance_scene(tmp_path / name) for name in ("room.rad", "xformed.rad"))
    for x, y in zip(_surfaces(a), _surfaces(b)):
        np.testing.assert_allclose(x, y, atol=1e-12)
    assert sorted(set(_surfaces(a)[1])) == [0.2, 0.5]
    # a source edited after the octree was made: the octree may be stale
    os.utime(tmp_path / "chair.rad", (os.path.getmtime(tmp_path / "chair.oct") + 10,) * 2)
    with pytest.raises(BadInputError, match="newer than chair.oct"):
        read_radiance_scene(tmp_path / "room.rad")
    with pytest.raises(BadInputError, match="only instances with the octree's own materials"):
        read_radiance_scene(LAMP + "grey instance c 1 chair.oct 0 0\n")
