"""OpenCV camera models (numpy) against OpenCV itself and closed forms."""

import cv2
import numpy as np
import pytest

from lsadphoto.errors import BadInputError
from lsadphoto.geometry import PinholeProjection, projection_from_dict
from lsadphoto.geometry.opencv import OpenCVFisheyeProjection, OpenCVPinholeProjection

BROWN = (-0.28, 0.09, 1e-3, -5e-4, -0.01)
RATIONAL = (0.12, -0.03, 4e-4, -2e-4, 0.002, 0.35, -0.02, 0.004)
KB = (0.05, -0.01, 0.003, -0.0005)


def _pinhole(dist):
    return OpenCVPinholeProjection(1000.0, 1010.0, 640.3, 479.7, dist, 1280, 960)


def _fisheye():
    # f = 300 px on a 1000² image: the corners lie ~125° off axis, inside θmax ≈ 132°.
    return OpenCVFisheyeProjection(300.0, 302.0, 499.5, 500.2, KB, 1000, 1000)


def _random_directions(rng, n, theta_max):
    theta = np.arccos(rng.uniform(np.cos(theta_max), 1.0, n))
    phi = rng.uniform(0.0, 2 * np.pi, n)
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)


def _edge_grid(cam, n=81):
    """Image points over the whole image, including the outer pixel corners."""
    h, w = cam.shape
    return np.meshgrid(np.linspace(-0.5, h - 0.5, n), np.linspace(-0.5, w - 0.5, n),
                       indexing="ij")


@pytest.mark.parametrize("dist", [BROWN, RATIONAL])
def test_pinhole_project_matches_cv2(dist):
    cam = _pinhole(dist)
    # Directions up to 40° off axis: beyond the image but inside r_fold for both sets.
    assert cam.r_fold > np.tan(np.radians(40))
    d = _random_directions(np.random.default_rng(1), 2000, np.radians(40))
    rows, cols = cam.project(d)
    ref, _ = cv2.projectPoints(d, np.zeros(3), np.zeros(3), cam.camera_matrix,
                               np.array(dist))
    # Same closed-form expression in float64 on both sides: rounding is ~1e-13 px.
    np.testing.assert_allclose(cols, ref[:, 0, 0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(rows, ref[:, 0, 1], rtol=0, atol=1e-9)


def test_fisheye_project_matches_cv2():
    cam = _fisheye()
    # cv2.fisheye divides by z, so only the front hemisphere (θ < 89°) is comparable.
    d = _random_directions(np.random.default_rng(2), 2000, np.radians(89))
    rows, cols = cam.project(d)
    ref, _ = cv2.fisheye.projectPoints(d[:, None, :], np.zeros(3), np.zeros(3),
                                       cam.camera_matrix, np.array(KB))
    # Same polynomial in float64 (θ via atan(r) there, atan2 here): rounding ~1e-12 px.
    np.testing.assert_allclose(cols, ref[:, 0, 0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(rows, ref[:, 0, 1], rtol=0, atol=1e-9)


@pytest.mark.parametrize("dist", [BROWN, RATIONAL])
def test_pinhole_round_trip_whole_image(dist):
    cam = _pinhole(dist)
    rows, cols = _edge_grid(cam)
    d = cam.directions(rows, cols)
    assert np.all(np.isfinite(d))
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-14)
    back_r, back_c = cam.project(d)
    # Newton stops at a residual < 1e-12 normalised, i.e. < 1e-12·f ≈ 1e-9 px.
    assert np.max(np.abs(back_r - rows)) < 1e-8
    assert np.max(np.abs(back_c - cols)) < 1e-8


def test_fisheye_round_trip_beyond_90_degrees():
    cam = _fisheye()
    rows, cols = _edge_grid(cam)
    d = cam.directions(rows, cols)
    assert np.all(np.isfinite(d))
    theta = np.degrees(np.arccos(np.clip(d[..., 2], -1, 1)))
    assert theta.max() > 120.0  # the corners are behind the camera plane
    back_r, back_c = cam.project(d)
    # Residual < 1e-12 in θd, times f = 300 px: < 1e-9 px.
    assert np.max(np.abs(back_r - rows)) < 1e-8
    assert np.max(np.abs(back_c - cols)) < 1e-8
    # Beyond θmax (where dθd/dθ = 0) the inverse reports NaN.
    far = cam.cx + cam.fx * (cam._rho_max * 1.01)
    assert np.all(np.isnan(cam.directions(cam.cy, far)))
    assert np.all(np.isnan(cam.project([0.0, np.sin(cam.theta_max + 0.01),
                                        np.cos(cam.theta_max + 0.01)])))


def test_fisheye_theta_max_is_where_the_polynomial_turns():
    cam = _fisheye()
    # Independent: dense sampling of θd(θ) finds where it stops increasing (grid 1e-5 rad).
    t = np.linspace(0, np.pi, 314160)
    k1, k2, k3, k4 = KB
    td = t * (1 + k1 * t**2 + k2 * t**4 + k3 * t**6 + k4 * t**8)
    first_drop = t[np.argmax(np.diff(td) <= 0)]
    assert cam.theta_max == pytest.approx(first_drop, abs=2e-5)


@pytest.mark.parametrize("dist", [BROWN, RATIONAL])
def test_pinhole_directions_match_cv2_undistort(dist):
    cam = _pinhole(dist)
    rng = np.random.default_rng(3)
    pts = np.stack([rng.uniform(100, 1180, 500), rng.uniform(80, 880, 500)], -1)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 1000, 1e-15)
    ref = cv2.undistortPoints(pts[:, None, :], cam.camera_matrix, np.array(dist),
                              criteria=crit)[:, 0, :]
    d = cam.directions(pts[:, 1], pts[:, 0])
    x, y = d[..., 0] / d[..., 2], d[..., 1] / d[..., 2]
    # OpenCV's fixed-point iteration with 1000 steps converges to ~1e-15 here; 1e-11
    # normalised (1e-8 px) leaves room for both solvers' stopping tolerances.
    np.testing.assert_allclose(x, ref[:, 0], rtol=0, atol=1e-11)
    np.testing.assert_allclose(y, ref[:, 1], rtol=0, atol=1e-11)


def test_fisheye_directions_match_cv2_undistort():
    cam = _fisheye()
    rng = np.random.default_rng(4)
    # Interior points: up to ~70° off axis, where x/z stays moderate.
    r = rng.uniform(0, 300 * 1.2, 500)
    phi = rng.uniform(0, 2 * np.pi, 500)
    pts = np.stack([cam.cx + r * np.cos(phi), cam.cy + r * np.sin(phi)], -1)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-15)
    ref = cv2.fisheye.undistortPoints(pts[:, None, :], cam.camera_matrix, np.array(KB),
                                      criteria=crit)[:, 0, :]
    d = cam.directions(pts[:, 1], pts[:, 0])
    x, y = d[..., 0] / d[..., 2], d[..., 1] / d[..., 2]
    # Both solve θd(θ) = ρ by Newton to ~1e-15; tan θ ≤ 3 here amplifies to ~1e-14, and
    # 1e-10 normalised leaves margin for OpenCV's own EPS test on θ.
    np.testing.assert_allclose(x, ref[:, 0], rtol=0, atol=1e-10)
    np.testing.assert_allclose(y, ref[:, 1], rtol=0, atol=1e-10)


def test_zero_distortion_solid_angles_equal_pinhole():
    cam = OpenCVPinholeProjection(400.0, 400.0, 319.5, 239.5, (0, 0, 0, 0), 640, 480)
    ref = PinholeProjection(400.0, 400.0, 319.5, 239.5, 640, 480)
    rows, cols = cam.pixel_grid()
    omega = cam.solid_angles(rows, cols)
    # Both exact (geodesic quad vs arctan formula); float64 rounding ~1e-13 relative.
    np.testing.assert_allclose(omega, ref.solid_angles(rows, cols), rtol=1e-9)
    a, b = np.arctan(320 / 400.0), np.arctan(240 / 400.0)
    # Rectangular pyramid with half-angles a, b: 4·arcsin(sin a · sin b).
    assert omega.sum() == pytest.approx(4 * np.arcsin(np.sin(a) * np.sin(b)), rel=1e-9)


def test_fisheye_solid_angles_sum_to_cap():
    cam = _fisheye()
    rows, cols = cam.pixel_grid()
    omega = cam.solid_angles(rows, cols)
    assert np.all(omega > 0)
    theta = np.arccos(np.clip(cam.directions(rows, cols)[..., 2], -1, 1))
    for theta0 in np.radians([60.0, 80.0]):
        # Pixels whose centre lies within θ0 tile the cap 2π(1 − cos θ0) up to the rim
        # pixels the centre rule takes or leaves whole: ~2600 rim pixels of ~1e-5 sr with
        # random over/under-shoot, measured −4.8e-5 and −2.2e-5 relative; 2e-4 bounds it.
        cap = 2 * np.pi * (1 - np.cos(theta0))
        assert omega[theta < theta0].sum() == pytest.approx(cap, rel=2e-4)


def test_invalid_corners_give_zero_solid_angle():
    # Strong barrel with the image far wider than the fold radius.
    cam = OpenCVPinholeProjection(200.0, 200.0, 319.5, 239.5, (-0.4, 0, 0, 0), 640, 480)
    omega = cam.solid_angles(0, 0)
    assert omega == 0.0
    assert np.all(np.isnan(cam.directions(0, 0)))
    assert cam.solid_angles(239, 319) > 0


def test_binning_keeps_directions():
    for cam in (_pinhole(BROWN), _fisheye()):
        half = cam.binned(2)
        # Binned pixel (r, c) is the mean of sensor pixels 2r, 2r+1: centre at 2r + ½.
        np.testing.assert_allclose(half.directions(10, 20), cam.directions(20.5, 40.5),
                                   atol=1e-12)
        assert half.distortion == cam.distortion


def test_serialisation_and_camera_matrix():
    for cam in (_pinhole(BROWN), _pinhole(RATIONAL), _fisheye()):
        again = projection_from_dict(cam.to_dict())
        assert again == cam
        assert type(cam).from_camera_matrix(cam.camera_matrix, np.array(cam.distortion),
                                            cam.width, cam.height) == cam
        assert repr(cam).startswith(type(cam).__name__)
    assert _pinhole(BROWN) != _fisheye()
    dist14 = np.zeros(14)
    dist14[:5] = BROWN
    assert OpenCVPinholeProjection.from_camera_matrix(
        _pinhole(BROWN).camera_matrix, dist14, 1280, 960).distortion == BROWN + (0.0,) * 3


def test_bad_arguments():
    with pytest.raises(BadInputError, match="distortion"):
        OpenCVPinholeProjection(1000, 1000, 0, 0, (0.1, 0.2, 0.3), 10, 10)
    with pytest.raises(BadInputError, match="distortion"):
        OpenCVFisheyeProjection(1000, 1000, 0, 0, (0.1, 0.2, 0.3, 0.4, 0.5), 10, 10)
    with pytest.raises(BadInputError, match="fx"):
        OpenCVPinholeProjection(0, 1000, 0, 0, (0, 0, 0, 0), 10, 10)
    with pytest.raises(BadInputError, match="fy"):
        OpenCVFisheyeProjection(1000, -5, 0, 0, KB, 10, 10)
    with pytest.raises(BadInputError, match="image size"):
        OpenCVFisheyeProjection(1000, 1000, 0, 0, KB, 0, 10)
    with pytest.raises(BadInputError, match="skew"):
        OpenCVFisheyeProjection.from_camera_matrix([[1, 0.1, 0], [0, 1, 0], [0, 0, 1]], KB, 4, 4)
    with pytest.raises(BadInputError, match="factor"):
        _fisheye().binned(0)
    with pytest.raises(BadInputError, match="distortion"):
        OpenCVPinholeProjection(1000, 1000, 0, 0, (0, 0, 0, np.nan), 10, 10)
