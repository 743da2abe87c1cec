"""Camera colour → luminance: the four matrix sources agree, on synthetic and real DNGs."""

import numpy as np
import pytest

from lsadphoto.errors import BadInputError
from lsadphoto.raw import camera_to_xyz_matrix, decode_raw
from lsadphoto.raw.decode import CameraColour

from .conftest import realdata


def _y_weights(colour_info, method):
    matrix, used = camera_to_xyz_matrix(colour_info, method=method)
    assert used == method
    return matrix[1]


def test_dng_paths_agree_on_synthetic_dng(camera, shoot):
    image = decode_raw(shoot(camera, np.full((camera.height, camera.width), 10.0)))
    truth = np.linalg.inv(np.asarray(camera.color_matrix))[1]  # Y row of the inverse ColorMatrix
    tags = _y_weights(image.colour, "dng-tags")
    libraw = _y_weights(image.colour, "libraw-color_matrix")
    # dng-tags inverts the written ColorMatrix1 (stored to 1e-4 as rationals).
    np.testing.assert_allclose(tags, truth, rtol=1e-3)
    # LibRaw's color_matrix route: float32 matrices and sRGB constants → 1e-3 relative.
    np.testing.assert_allclose(libraw, truth, rtol=2e-3, atol=2e-4)
    assert not np.any(image.colour.rgb_xyz_matrix)  # LibRaw leaves it zero for DNGs (PITFALLS.md)


def test_rgb_xyz_route_and_profile_route():
    cm = np.array([[0.6461, -0.1164, -0.0857], [-0.3825, 1.1597, 0.2534], [-0.0416, 0.1540, 0.6523]])
    info = CameraColour(rgb_xyz_matrix=cm, color_matrix=np.zeros((3, 3)), daylight_whitebalance=np.zeros(3))
    matrix, used = camera_to_xyz_matrix(info)
    assert used == "libraw-rgb_xyz"
    np.testing.assert_allclose(matrix @ cm, np.eye(3), atol=1e-12)
    fitted = np.diag([0.3, 0.6, 0.1])
    matrix, used = camera_to_xyz_matrix(info, profile_matrix=fitted)
    assert used == "profile" and np.allclose(matrix, fitted)


def test_unknown_method_lists_valid_ones():
    info = CameraColour(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros(3))
    with pytest.raises(BadInputError, match="valid: 'auto'"):
        camera_to_xyz_matrix(info, method="magic")
    with pytest.raises(BadInputError, match="no camera colour matrix"):
        camera_to_xyz_matrix(info)


@pytest.mark.realdata
def test_real_dng_colour_routes_agree():
    """On a real Canon DNG, the DNG tag route and LibRaw's color_matrix route give the same
    luminance weights (the 0.3 % agreement PITFALLS.md reports on block means)."""
    import warnings

    from lsadphoto.errors import MetadataWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MetadataWarning)
        image = decode_raw(realdata("raw/tinydng_colorchart.dng"))
    tags = camera_to_xyz_matrix(image.colour, method="dng-tags")[0]
    libraw = camera_to_xyz_matrix(image.colour, method="libraw-color_matrix")[0]
    y_tags = image.rgb @ tags[1]
    y_libraw = image.rgb @ libraw[1]
    ok = y_tags > 0.01
    # Agreement on the image, not only on the weights: within 0.5 % (float32 in LibRaw).
    assert np.median(np.abs(y_libraw[ok] / y_tags[ok] - 1)) < 0.005


def test_forward_matrix_route(camera, shoot):
    """A DNG with ForwardMatrix1: camera → XYZ = FM · diag(1/AsShotNeutral) (DNG 1.6 §6).

    The FM written is inv(ColorMatrix) · diag(neutral) (no chromatic adaptation), so the
    route must reproduce inv(ColorMatrix) itself.
    """
    from pidng.dng import Tag

    from lsadphoto.datasets.synthetic import D65_XY, _rational

    cm = np.asarray(camera.color_matrix)
    white = np.array([D65_XY[0] / D65_XY[1], 1.0, (1 - sum(D65_XY)) / D65_XY[1]])
    neutral = cm @ white
    neutral /= neutral.max()
    forward = np.linalg.inv(cm) @ np.diag(neutral)
    path = shoot(camera, np.full((camera.height, camera.width), 10.0),
                 extra_tags=[(Tag.ForwardMatrix1, [_rational(v, 10**6) for v in forward.ravel()])])
    image = decode_raw(path)
    assert image.colour.dng["forward_matrix"][0] is not None
    matrix, used = camera_to_xyz_matrix(image.colour, method="dng-tags")
    # AsShotNeutral is stored to 1e-4 as rationals, the FM to 1e-6: agreement to 2e-4.
    np.testing.assert_allclose(matrix[1], np.linalg.inv(cm)[1], rtol=2e-4, atol=2e-5)
