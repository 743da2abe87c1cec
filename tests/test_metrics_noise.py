"""Per-pixel noise in the metrics' uncertainty, through score_map.

References: (1) the analytic variance of a linear metric — E_v = Σ L·cos σ·ω and
L̄ = Σ L·ω/Σ ω with independent pixel noise of variance v_j have Var = Σ v_j·(cos σ_j·ω_j)²
and Σ v_j·ω_j²/(Σ ω)², computed here from the projection directly; (2) a Monte Carlo over
independently noised copies of one synthetic scene (made by the project's generator, the
truth known): the spread of each metric over the copies and the mean change from the
noise-free scene (the bias) are what score_map must report from a *single* noisy copy and
its per-pixel uncertainty.
"""

import math

import numpy as np
import pytest

from lsadphoto.datasets import window_scene
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.metrics.score import noise_variance, score_map

SIZE = 128
#: Relative per-pixel noise of the synthetic maps.
NOISE = 0.1
#: Noisy copies of the scene in the Monte Carlo reference: independent antithetic pairs.
PAIRS = 16


def _direction(sigma_deg, tau_deg):
    s, t = math.radians(sigma_deg), math.radians(tau_deg)
    return np.array([math.sin(s) * math.sin(t), -math.sin(s) * math.cos(t), math.cos(s)])


@pytest.fixture(scope="module")
def camera():
    return IdealFisheyeProjection("equidistant", (SIZE - 1) / 2, (SIZE - 1) / 2, SIZE / 2, 180.0,
                                  SIZE, SIZE)


@pytest.fixture(scope="module")
def truth(camera):
    """A window with a gradient and a bright lamp on a flat background; every source pixel
    ≥ 4250 cd·m⁻², 7σ of the noise above the 2000 cd·m⁻² threshold, and the background far
    below it, so that the noise never changes which pixels are sources."""
    d = camera.directions(*camera.pixel_grid())
    return window_scene(d, background=(90.0, 90.0),
                        windows=[dict(azimuth=(10, 40), elevation=(10, 40),
                                      luminance=(5000.0, 9000.0), side_gradient=0.3)],
                        disks=[(_direction(35, 220), 0.06, 30000.0)])


def _noisy(truth, z):
    return truth + NOISE * truth * z


@pytest.fixture(scope="module")
def monte_carlo(camera, truth):
    """Metrics of the noise-free scene and of noised copies: PAIRS independent draws z of
    standard normal pixel noise, each used as +z and −z (antithetic: a pair's mean cancels
    the first-order change exactly, so the mean over pairs measures the bias with a small
    error; each copy alone is an honest noisy map)."""
    rng = np.random.default_rng(11)
    off = dict(noise_samples=0, q_noise_samples=0)
    clean = score_map(LuminanceMap(truth, projection=camera), **off)
    copies = []
    for _ in range(PAIRS):
        z = rng.standard_normal(truth.shape)
        copies += [score_map(LuminanceMap(_noisy(truth, sign * z), projection=camera), **off)
                   for sign in (1.0, -1.0)]
    assert all(c.values["n_sources"] == clean.values["n_sources"] for c in copies)
    return clean.values, {key: np.array([c.values[key] for c in copies]) for key in clean.values}


def test_linear_metrics_have_the_analytic_variance(camera, truth):
    sigma = NOISE * truth
    score = score_map(LuminanceMap(truth, uncertainty=sigma, projection=camera),
                      noise_samples=4000, q_noise_samples=0)
    d = camera.directions(*camera.pixel_grid())
    w = camera.solid_angles(*camera.pixel_grid())
    field = np.isfinite(truth) & (w > 0) & (d[..., 2] >= 0)
    var_e = np.sum((sigma * d[..., 2] * w)[field] ** 2)
    var_mean = np.sum((sigma * w)[field] ** 2) / np.sum(w[field]) ** 2
    # 2000 antithetic pairs: the sample standard deviation is within 1/√(2·2000) = 1.6 %
    # (one σ) of the true one; 5 % is 3σ.
    assert score.uncertainty_noise["vertical_illuminance"] == pytest.approx(math.sqrt(var_e),
                                                                            rel=0.05)
    assert score.uncertainty_noise["mean_luminance"] == pytest.approx(math.sqrt(var_mean),
                                                                      rel=0.05)
    # A linear metric has no bias, and antithetic pairs of draws cancel its change exactly:
    # zero to float64 rounding of the sums.
    for key in ("vertical_illuminance", "mean_luminance"):
        assert abs(score.noise_bias[key]) <= 1e-9 * score.values[key], key
    # No calibration uncertainty: the combined uncertainty is the noise part.
    assert score.uncertainty["vertical_illuminance"] == score.uncertainty_noise[
        "vertical_illuminance"]


@pytest.mark.slow
def test_spread_and_bias_match_independently_noised_copies(camera, truth, monte_carlo):
    clean, copies = monte_carlo
    observed = _noisy(truth, np.random.default_rng(12).standard_normal(truth.shape))
    score = score_map(LuminanceMap(observed, uncertainty=NOISE * truth, projection=camera),
                      noise_samples=256, q_noise_samples=16)
    for key in ("vertical_illuminance", "background_luminance", "ugr_grouped", "ugr_pixel",
                "dgp", "dgi", "dgi_mod", "cgi", "ugr_exp", "ugp", "dgr", "q"):
        spread = np.std(copies[key], ddof=1)
        # The spread over 16 pairs is known to about 1/√32 = 18 % (one σ), score_map's from
        # 128 antithetic pairs of draws of the sums to 6 % and Q's from 8 pairs to 25 %: 50 %
        # is 2σ of the combined error for Q (the loosest) and 2.6σ for the others.
        assert score.uncertainty_noise[key] == pytest.approx(spread, rel=0.5), key
    # Biases: pixel-UGR's matters (ΣL²ω/P² gains Σω·v/P²), and Q's (noise adds gradients);
    # those of the grouped indices are second-order and small. The reference is the mean
    # change over the copies, known to the standard error of the pair means; score_map's
    # estimate (antithetic resampling about the observed copy) to its own. They must agree
    # within 4 combined standard errors plus 20 % of the bias: the resampled estimate is
    # taken about the noisy map, not the truth, which is right to first order only.
    for key in ("ugr_pixel", "q", "ugr_grouped", "dgi", "dgr", "dgp"):
        true_bias = np.mean(copies[key]) - clean[key]
        pair_means = copies[key].reshape(PAIRS, 2).mean(axis=1)
        reference_error = np.std(pair_means, ddof=1) / math.sqrt(PAIRS)
        error = math.hypot(reference_error, score.noise_bias_standard_error[key])
        if key in ("ugr_pixel", "q"):
            assert true_bias > 4 * reference_error, key  # the bias is real
        assert score.noise_bias[key] == pytest.approx(true_bias, abs=4 * error
                                                      + 0.2 * abs(true_bias)), key


def test_noise_is_the_uncertainty_less_its_calibration_part(camera, truth):
    u_k = 0.03
    only_scale = LuminanceMap(truth, uncertainty=u_k * truth, projection=camera,
                              calibration_uncertainty=u_k)
    # u_j = L_j·u_k is the calibration scale alone: no noise left to propagate.
    assert np.nanmax(noise_variance(only_scale)) == pytest.approx(0.0, abs=1e-6)
    score = score_map(only_scale, q_noise_samples=0)
    assert score.uncertainty_noise == {} and score.noise_bias == {}
    both = LuminanceMap(truth, uncertainty=np.hypot(u_k, NOISE) * truth, projection=camera,
                        calibration_uncertainty=u_k)
    s = score_map(both, q_noise_samples=0)
    # The parts add in quadrature (GUM §5.1.2); the calibration part is 8·u/ln 10-like for
    # UGR and exactly u·E_v for E_v.
    for key in ("ugr_grouped", "vertical_illuminance", "dgp"):
        assert s.uncertainty[key] == pytest.approx(math.hypot(
            s.uncertainty_calibration[key], s.uncertainty_noise[key]), rel=1e-12), key
    assert s.uncertainty_calibration["vertical_illuminance"] == pytest.approx(
        u_k * s.values["vertical_illuminance"], rel=1e-9)
    # Reproducible: the same seed draws the same numbers.
    again = score_map(both, q_noise_samples=0)
    assert again.uncertainty_noise == s.uncertainty_noise


def test_bad_sample_counts_are_rejected(camera, truth):
    from lsadphoto.errors import BadInputError

    lmap = LuminanceMap(truth, uncertainty=NOISE * truth, projection=camera)
    for bad in (-1, 2.5, "many"):
        with pytest.raises(BadInputError, match="noise_samples"):
            score_map(lmap, noise_samples=bad)
