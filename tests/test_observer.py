"""Observer frame: constructors, levelled horizon, serialisation and plot coordinates,
against analytic cases (rotations written out by hand) and geometric identities."""

import json
import math

import numpy as np
import pytest

from lsadphoto.errors import BadInputError
from lsadphoto.geometry import IdealFisheyeProjection, ObserverFrame, PinholeProjection

# Rounding tolerance for unit-vector arithmetic in double precision: a handful of
# operations on O(1) numbers, each exact to 1.1e-16; 1e-12 leaves a wide margin.
EPS = 1e-12


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _camera_basis(roll_deg, pitch_deg):
    """Camera axes (x right, y down, z forward) in world coordinates (E, N, Up), built by
    rotating a level camera looking north: pitch up about x, then roll clockwise (seen from
    behind) about z — composed here from elementary rotation matrices, independently of the
    closed form in ObserverFrame.levelled."""
    p, r = math.radians(pitch_deg), math.radians(roll_deg)
    level = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # columns x=E, y=−Up, z=N
    # Pitch: rotate the camera about its own x axis so that z rises towards Up.
    pitch = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(p), -math.sin(p)], [0.0, math.sin(p), math.cos(p)]])
    # Roll clockwise seen from behind = rotation by −r about +z (camera axes x→y when r = 90°).
    roll = np.array([[math.cos(r), -math.sin(r), 0.0], [math.sin(r), math.cos(r), 0.0], [0.0, 0.0, 1.0]])
    # Intrinsic rotations: body axes = level · pitch · roll (columns are the new axes). A
    # clockwise roll seen from behind takes the top of the camera (−y) towards +x, so the
    # new x is (cos r, sin r, 0) in body coordinates: the right side tilts down (+y).
    return level @ pitch @ roll


def test_basis_helper_conventions():
    # Pitch 90°: the optical axis points at the zenith, image top (−y) towards the south.
    basis = _camera_basis(0.0, 90.0)
    np.testing.assert_allclose(basis[:, 2], [0, 0, 1], atol=EPS)
    np.testing.assert_allclose(-basis[:, 1], [0, -1, 0], atol=EPS)
    # Roll 90° clockwise seen from behind: the camera's right side (x) points down.
    basis = _camera_basis(90.0, 0.0)
    np.testing.assert_allclose(basis[:, 0], [0, 0, -1], atol=EPS)


@pytest.mark.parametrize(("roll", "pitch"), [(0.0, 10.0), (5.0, 10.0), (-20.0, -35.0), (30.0, 0.0), (170.0, 60.0)])
def test_levelled_up_is_the_true_vertical(roll, pitch):
    basis = _camera_basis(roll, pitch)
    world_up_in_camera = basis.T @ np.array([0.0, 0.0, 1.0])
    frame = ObserverFrame.levelled(roll_deg=roll, pitch_deg=pitch)
    np.testing.assert_allclose(frame.up, world_up_in_camera, atol=EPS)
    # The default line of sight is the horizontal direction in front of the camera.
    forward = basis[:, 2].copy()
    forward[2] = 0.0
    np.testing.assert_allclose(frame.line_of_sight, basis.T @ _unit(forward), atol=EPS)
    # Every true-horizontal direction (world z = 0) lies at τ = 90° — the levelled horizon.
    azimuth = np.radians(np.linspace(0.0, 359.0, 360))
    horizontal_world = np.stack([np.sin(azimuth), np.cos(azimuth), np.zeros_like(azimuth)], axis=-1)
    sigma, tau = frame.angles(horizontal_world @ basis)
    off_axis = (sigma > 1e-6) & (sigma < np.pi - 1e-6)  # τ is 0 on the axis, ahead or behind
    np.testing.assert_allclose(np.degrees(tau[off_axis]), 90.0, atol=1e-9)
    # Directions above the horizon have τ < 90°, below it τ > 90°.
    _, tau_up = frame.angles(_unit([0.3, 0.2, 0.5]) @ basis)
    assert tau_up < np.pi / 2
    _, tau_down = frame.angles(_unit([0.3, 0.2, -0.5]) @ basis)
    assert tau_down > np.pi / 2


def test_levelled_pitch_ten_degrees_worked_numbers():
    # Pitch 10°, roll 0: true up in camera coordinates (0, −cos 10°, sin 10°); the optical
    # axis is 10° above the horizon, i.e. σ = 10° straight above the levelled line of sight.
    frame = ObserverFrame.levelled(roll_deg=0.0, pitch_deg=10.0)
    np.testing.assert_allclose(frame.up, [0.0, -math.cos(math.radians(10)), math.sin(math.radians(10))], atol=EPS)
    sigma, tau = frame.angles(np.array([0.0, 0.0, 1.0]))
    assert math.degrees(sigma) == pytest.approx(10.0, abs=1e-10)
    assert tau == pytest.approx(0.0, abs=1e-10)
    # With the optical axis kept as the line of sight, the horizon in front is 10° below.
    axis_frame = ObserverFrame.levelled(roll_deg=0.0, pitch_deg=10.0, line_of_sight=(0, 0, 1))
    horizon_ahead = np.array([0.0, math.sin(math.radians(10)), math.cos(math.radians(10))])
    sigma, tau = axis_frame.angles(horizon_ahead)
    assert (math.degrees(sigma), math.degrees(tau)) == pytest.approx((10.0, 180.0), abs=1e-10)
    with pytest.raises(BadInputError, match="pitch_deg"):
        ObserverFrame.levelled(roll_deg=0.0, pitch_deg=90.0)
    with pytest.raises(BadInputError, match="roll_deg"):
        ObserverFrame.levelled(roll_deg=float("nan"), pitch_deg=0.0)


def test_sigma_is_invariant_under_rotation_about_the_line_of_sight():
    rng = np.random.default_rng(11)
    d = _unit(rng.normal(size=(500, 3)))
    frame = ObserverFrame.levelled(roll_deg=7.0, pitch_deg=-12.0)
    v = frame.axes()[0]
    sigma, tau = frame.angles(d)
    for angle in np.radians([13.0, 90.0, 181.0]):
        k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
        rotation = np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k  # Rodrigues
        sigma_rot, _ = frame.angles(d @ rotation.T)
        np.testing.assert_allclose(sigma_rot, sigma, atol=EPS)
    # Directions behind the observer: σ > 90° and τ defined in [0, π].
    behind = sigma > np.pi / 2
    assert behind.any() and np.all((tau[behind] >= 0) & (tau[behind] <= np.pi))
    np.testing.assert_allclose(np.cos(sigma), d @ v, atol=EPS)


def test_tau_on_the_line_of_sight_is_zero():
    # With a skew line of sight the components perpendicular to v̂ are only zero to
    # rounding (≈ 1e-17), which would give an arbitrary τ; it is fixed at 0.
    frame = ObserverFrame(line_of_sight=(0.3, -0.2, 0.9), up=(0.1, -1.0, 0.05))
    v = frame.axes()[0]
    sigma, tau = frame.angles(v)
    assert sigma == pytest.approx(0.0, abs=1e-15) and tau == 0.0
    x, y = frame.angular_coordinates(v)
    assert x == 0.0 and y == 0.0
    sigma, tau = frame.angles(-v)  # straight behind
    assert sigma == pytest.approx(np.pi, abs=1e-15) and tau == 0.0
    assert np.all(np.isnan(frame.angles(np.full(3, np.nan))))


def test_angular_coordinates():
    frame = ObserverFrame.levelled(roll_deg=25.0, pitch_deg=5.0)
    v, u, h = frame.axes()
    # Worked directions: 30° to the right, 20° up, 40° down-left (at 45° around v̂).
    cases = [(30.0, 90.0, +1), (20.0, 0.0, +1), (40.0, 135.0, -1)]
    for sigma_deg, tau_deg, side in cases:
        s, t = math.radians(sigma_deg), math.radians(tau_deg)
        d = math.cos(s) * v + math.sin(s) * (math.cos(t) * u + side * math.sin(t) * h)
        x, y = frame.angular_coordinates(d)
        assert x == pytest.approx(side * s * math.sin(t), abs=EPS)
        assert y == pytest.approx(s * math.cos(t), abs=EPS)
        assert math.hypot(x, y) == pytest.approx(s, abs=EPS)
    # Behind the observer: radius σ > π/2.
    x, y = frame.angular_coordinates(-_unit(v + 0.1 * u))
    assert math.hypot(x, y) > np.pi / 2


def test_from_pixel_and_serialisation():
    cam = IdealFisheyeProjection("equidistant", 99.5, 99.5, 100.0, 180.0, 200, 200)
    # 50 px right of centre on a 180° equidistant circle of radius 100 px: θ = 45°.
    frame = ObserverFrame.from_pixel(cam, 99.5, 149.5)
    np.testing.assert_allclose(frame.line_of_sight, [math.sqrt(0.5), 0.0, math.sqrt(0.5)], atol=EPS)
    np.testing.assert_allclose(frame.axes()[1], [0.0, -1.0, 0.0], atol=EPS)
    levelled = ObserverFrame.levelled(roll_deg=3.0, pitch_deg=4.0)
    frame = ObserverFrame.from_pixel(cam, 80.0, 120.0, up=levelled.up)
    back = ObserverFrame.from_dict(json.loads(json.dumps(frame.to_dict())))
    assert back == frame
    assert ObserverFrame.from_dict({}) == ObserverFrame()
    with pytest.raises(BadInputError, match="no direction"):
        ObserverFrame.from_pixel(cam, 0.0, 0.0)  # the image corner, outside the circle
    with pytest.raises(BadInputError, match="parallel"):
        ObserverFrame.from_pixel(PinholeProjection(100, 100, 49.5, 49.5, 100, 100), 49.5, 49.5, up=(0, 0, 1))
    with pytest.raises(BadInputError, match="unknown keys"):
        ObserverFrame.from_dict({"los": [0, 0, 1]})
    with pytest.raises(BadInputError, match="shape"):
        ObserverFrame.from_dict({"up": [0, 1]})
