"""Observer angles and position index against FORMULAS.md's worked values (computed outside
the project from the published closed forms) and geometric identities."""

import numpy as np
import pytest

from lsadphoto.errors import BadInputError
from lsadphoto.geometry.observer import ObserverFrame
from lsadphoto.geometry.position_index import position_index

# FORMULAS.md §2.1 (Guth, Levin's closed form): (σ, τ) → P, given to 3–4 significant digits.
GUTH = [((26.565, 0), 2.860), ((10, 0), 1.434), ((30, 0), 3.348), ((30, 45), 2.383), ((30, 90), 1.468),
        ((45, 0), 7.059), ((45, 90), 2.050), ((60, 90), 3.146)]
# §2.2 (Iwata/Osterhaus below the line of sight).
IWATA = [((30, 180), 1.576), ((30, 135), 1.523), ((45, 180), 2.275), ((60, 180), 3.503)]


@pytest.mark.parametrize(("angles", "expected"), GUTH + IWATA)
def test_worked_values(angles, expected):
    sigma, tau = np.radians(angles)
    # Tables give 4 significant digits: half a unit of the last digit, 5e-4 relative.
    assert position_index(sigma, tau) == pytest.approx(expected, rel=5e-4, abs=5e-4)


def test_cap_kim_and_continuity():
    assert position_index(np.radians(60), 0.0) == 16.0  # Guth gives 16.36: capped (§2.1)
    assert position_index(np.radians(60), 0.0, method="Guth") == 16.0
    assert position_index(np.radians(10), 0.0, method="Kim2011") == pytest.approx(0.265, abs=5e-4)
    assert position_index(0.0, 1.0) == 1.0  # P(0, any τ) = 1
    # Across the horizontal (φ = 0 ⇔ τ = 90°) the branches meet up to evalglare's rounded
    # coefficients: Guth's brackets at τ = 90° minus (6.49e-3, 21e-5), at σ = 35°.
    above = position_index(np.radians(35), np.radians(90) - 1e-9)
    below = position_index(np.radians(35), np.radians(90) + 1e-9)
    gap = ((35.2 - 0.31889 * 90 - 1.22 * np.exp(-20) - 6.49) * 1e-3 * 35
           + (21 + 0.26667 * 90 - 0.002963 * 90**2 - 21) * 1e-5 * 35**2)
    assert above / below == pytest.approx(np.exp(gap), rel=1e-6)
    assert abs(above / below - 1) < 5e-4
    with pytest.raises(BadInputError, match="valid: evalglare"):
        position_index(0.1, 0.1, method="CIE117")


def test_observer_angles():
    frame = ObserverFrame()
    d = np.array([[0, -1, 1], [0, 1, 1], [1, 0, 1], [-1, 0, 1], [0, 0, 1], [0, 0, -1]], float)
    d /= np.linalg.norm(d, axis=1)[:, None]
    sigma, tau = frame.angles(d)
    np.testing.assert_allclose(np.degrees(sigma), [45, 45, 45, 45, 0, 180], atol=1e-12)
    np.testing.assert_allclose(np.degrees(tau[:4]), [0, 180, 90, 90], atol=1e-12)  # up, down, right, left


def test_angles_invariant_under_rotation_about_line_of_sight():
    rng = np.random.default_rng(5)
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    v = np.array([0.3, -0.2, 0.9])
    v /= np.linalg.norm(v)
    frame = ObserverFrame(line_of_sight=tuple(v), up=(0, -1, 0))
    sigma, _ = frame.angles(d)
    # Rodrigues rotation by 37° about v: σ must not change (a σ-only quantity).
    a = np.radians(37)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    rotation = np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k
    sigma_rot, _ = frame.angles(d @ rotation.T)
    np.testing.assert_allclose(sigma_rot, sigma, atol=1e-12)
    with pytest.raises(BadInputError, match="parallel"):
        ObserverFrame(line_of_sight=(0, 1, 0), up=(0, -1, 0)).axes()
