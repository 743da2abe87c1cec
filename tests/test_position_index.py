"""Observer angles and position index against FORMULAS.md's worked values (computed outside
the project from the published closed forms) and geometric identities."""

import numpy as np
import pytest

from lsadphoto.errors import BadInputError
from lsadphoto.geometry.observer import ObserverFrame
from lsadphoto.geometry.position_index import guth_field_mask, position_index

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


# --- edge cases: σ = 0, the seam τ = 90°, the cap, behind the observer ---------------------


def test_on_the_line_of_sight_p_is_one_for_every_tau():
    # Guth: exp(0) = 1; Iwata: β = 0, exp(0) = 1 — exactly, for any τ (FORMULAS.md §2.1).
    tau = np.radians([0.0, 45.0, 90.0, 135.0, 180.0])
    np.testing.assert_array_equal(position_index(np.zeros(5), tau), np.ones(5))
    np.testing.assert_array_equal(position_index(np.zeros(5), tau, method="Guth"), np.ones(5))


def test_seam_belongs_to_the_upper_field():
    # evalglare moves φ = 0 to +1e-5 before testing φ < 0, so the horizontal through the
    # line of sight (τ = 90° exactly) takes Guth's formula, not Iwata's.
    from lsadphoto.geometry.position_index import (
        position_index_Guth,
        position_index_Iwata,
    )

    sigma = np.radians(40.0)
    assert position_index(sigma, np.pi / 2) == position_index_Guth(sigma, np.pi / 2)
    assert position_index(sigma, np.nextafter(np.pi / 2, 4.0)) == position_index_Iwata(
        sigma, np.nextafter(np.pi / 2, 4.0))


def test_behind_the_observer_is_continuous_and_capped():
    # At σ = 90°, τ = 180°: β = 90° exactly (atan2(1.15, 0)), P = exp(6.49e-3·90 + 21e-5·90²)
    # = exp(0.5841 + 1.701) = 9.82667 (hand calculation); just beyond 90° P must not jump
    # (evalglare's atan(tan σ·…) flips β to about −90° there).
    below = np.pi
    just_before = position_index(np.radians(90.0) - 1e-9, below)
    just_after = position_index(np.radians(90.0) + 1e-9, below)
    assert position_index(np.radians(90.0), below) == pytest.approx(9.826669, rel=1e-6)
    assert just_after == pytest.approx(just_before, rel=1e-6)
    # σ = 103°, τ = 180°: tan β = 1.15·tan 103° = −4.981 → β = 101.35° → P = exp(0.6578 +
    # 2.1571) = 16.7 → capped at 16; σ = 120° likewise (evalglare's literal code gives 1.54).
    assert position_index(np.radians(103.0), below) == 16.0
    assert position_index(np.radians(120.0), below) == 16.0
    # Whole sphere behind 102.1° (the largest σ with P < 16 is 102.0°, straight below): cap.
    sigma, tau = np.meshgrid(np.radians(np.linspace(102.1, 180.0, 300)), np.radians(np.linspace(0, 180, 181)))
    assert np.all(position_index(sigma, tau) == 16.0)
    # P never decreases with σ at fixed τ (the continuation is monotonic up to the cap).
    s = np.radians(np.linspace(0.0, 180.0, 3601))
    for t in np.radians([0.0, 60.0, 90.0, 91.0, 135.0, 180.0]):
        assert np.all(np.diff(position_index(s, t)) >= 0)
    # Kim2011 is not capped: at σ = 150°, τ = 0: exp((150 − 21.633)/8.772) = 2.2e6.
    assert position_index(np.radians(150.0), 0.0, method="Kim2011") == pytest.approx(
        np.exp((150 - 21.633) / 8.772), rel=1e-12)


def test_nan_in_nan_out():
    assert np.isnan(position_index(np.nan, 0.3))
    assert np.isnan(position_index(0.3, np.nan))


# --- Guth field-of-view cut (evalglare -G 1 / -G 2, FORMULAS.md §2.4.9) -------------------
#
# Border values worked by hand from the polynomials (checked in a separate Python session):
#   type 1 upper, τ = 0:   7.7458218² = 59.99776°
#   type 1 upper, τ = 45°: 7.7458218 + 0.02583356 − 0.44036294 + 0.77978146 = 8.11107388,
#                          squared 65.78952°
#   type 1 lower, τ = 180° (t′ = 0):  −1/(−0.014699242) = 68.03072°
#   type 1 lower, τ = 136° (t′ = 44): −0.014699242 − 0.000683809 + 0.009079466 − 0.004390357
#                          = −0.010693942 → 93.51089°
#   type 2 lower, τ = 180°: 68.227109°; τ = 150° (t′ = 30): 21.6616928/0.39411906 = 54.96237°;
#                          t′ > 73° (τ < 107°): 60°.


GUTH_BORDERS = [  # (kind, τ [deg], border σ [deg])
    (1, 0.0, 59.99776), (1, 45.0, 65.78952), (1, 180.0, 68.03072), (1, 136.0, 93.51089),
    (2, 0.0, 60.0), (2, 60.0, 60.0), (2, 180.0, 68.227109), (2, 150.0, 54.96237), (2, 100.0, 60.0),
]


@pytest.mark.parametrize(("kind", "tau", "border"), GUTH_BORDERS)
def test_guth_borders_against_hand_values(kind, tau, border):
    # The hand values carry 7 significant digits: points 1e-3° inside and outside the border
    # are decided correctly (well beyond the 1e-5° rounding of the hand values).
    sigma = np.radians([border - 1e-3, border + 1e-3])
    assert guth_field_mask(sigma, np.radians(tau), kind=kind).tolist() == [True, False]


def test_guth_field_lower_band_and_seam():
    # Type 1 cuts nothing below the line of sight for 90° ≤ τ ≤ 135° (evalglare applies the
    # lower border only for τ > 135°), even behind the observer.
    assert guth_field_mask(np.radians(170.0), np.radians(120.0), kind=1)
    assert guth_field_mask(np.radians(170.0), np.radians(135.0), kind=1)
    # The seam τ = 90° belongs to the lower part: σ = 155° is inside there, while just
    # above it (τ = 89.9°) the upper border is 150.24° and σ = 155° is outside.
    assert guth_field_mask(np.radians(155.0), np.pi / 2, kind=1)
    assert not guth_field_mask(np.radians(155.0), np.radians(89.9), kind=1)
    # Type 2 is continuous across the seam (60° on both sides) and across t′ = 73°.
    assert guth_field_mask(np.radians(59.99), np.pi / 2, kind=2)
    assert not guth_field_mask(np.radians(60.01), np.pi / 2, kind=2)
    assert guth_field_mask(np.radians(59.99), np.radians(107.0), kind=2)
    # NaN directions are outside; the line of sight is inside.
    assert guth_field_mask(0.0, 0.0, kind=1) and guth_field_mask(0.0, 0.0, kind=2)
    assert not guth_field_mask(np.nan, 0.0) and not guth_field_mask(0.3, np.nan)
    with pytest.raises(BadInputError, match="Guth field kind 3"):
        guth_field_mask(0.1, 0.1, kind=3)
