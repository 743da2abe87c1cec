"""Radiance's secondary and directed emitters in the scene reader: illum and spotlight.

References: the Radiance reference manual (refman, "illum", "spotlight") and Radiance's own
programs on the same files (rtrace), as each test says.
"""

import numpy as np
import pytest

from lsadphoto.errors import BadInputError
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
