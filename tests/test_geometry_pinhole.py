"""Pinhole geometry against closed forms."""

import numpy as np
import pytest

from lsadphoto.errors import BadInputError
from lsadphoto.geometry import PinholeProjection, projection_from_dict


def test_total_solid_angle_matches_rectangle_formula():
    cam = PinholeProjection(400.0, 400.0, 319.5, 239.5, 640, 480)
    rows, cols = cam.pixel_grid()
    total = cam.solid_angles(rows, cols).sum()
    a = np.arctan(320 / 400.0)
    b = np.arctan(240 / 400.0)
    # Solid angle of a rectangular pyramid with half-angles a, b: 4·arcsin(sin a · sin b).
    assert total == pytest.approx(4 * np.arcsin(np.sin(a) * np.sin(b)), rel=1e-9)


def test_centre_pixel_solid_angle_and_round_trip():
    cam = PinholeProjection(1000.0, 1000.0, 99.5, 49.5, 200, 100)
    # A centre pixel of a long-focus camera covers ≈ (1/f)² sr.
    assert cam.solid_angles(49.5, 99.5) == pytest.approx(1e-6, rel=1e-6)
    rows, cols = np.array([0.0, 10.3, 99.0]), np.array([0.0, 150.7, 199.0])
    back = cam.project(cam.directions(rows, cols))
    np.testing.assert_allclose(back[0], rows, atol=1e-9)
    np.testing.assert_allclose(back[1], cols, atol=1e-9)


def test_binning_keeps_directions():
    cam = PinholeProjection(500.0, 500.0, 99.5, 79.5, 200, 160)
    half = cam.binned(2)
    # Binned pixel (r, c) is the mean of sensor pixels 2r, 2r+1: its centre is at 2r + ½.
    np.testing.assert_allclose(half.directions(10, 20), cam.directions(20.5, 40.5), atol=1e-12)


def test_serialisation_and_bad_values():
    cam = PinholeProjection(500.0, 501.0, 99.5, 79.5, 200, 160)
    assert projection_from_dict(cam.to_dict()) == cam
    with pytest.raises(BadInputError, match="unknown projection model"):
        projection_from_dict({"model": "banana"})
    with pytest.raises(BadInputError):
        PinholeProjection(-1, 1, 0, 0, 10, 10)
