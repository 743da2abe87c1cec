"""Monte Carlo parts of the observer study: the rating jitter (the paper's robustness check)
against the attenuation formula, the bootstrap intervals against scipy.stats.bootstrap fed
with the same resamples, reproducibility and chunk independence of the random streams, and
the leave-one-scene-out choice of N against a plain loop and against in-sample choice."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

from lsadphoto.study import (
    bootstrap_correlation,
    jitter_correlations,
    jitter_summary,
    leave_one_out_selection,
    pearson_r,
)
from lsadphoto.study.resampling import CHUNK, uniform_block

# Deterministic arithmetic, compared with an independent implementation (see test_study.py).
EPS = 1e-12


def _sample(seed, n, rho):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=n)
    y = rho * x + math.sqrt(1 - rho * rho) * rng.normal(size=n)
    return x, y


def test_uniform_block_independent_of_chunking_and_seeded():
    whole = uniform_block(7, 1, 0, 50, 13)
    parts = np.vstack([uniform_block(7, 1, 0, 17, 13), uniform_block(7, 1, 17, 33, 13)])
    np.testing.assert_array_equal(whole, parts)
    assert not np.array_equal(whole, uniform_block(8, 1, 0, 50, 13))  # seed
    assert not np.array_equal(whole, uniform_block(7, 2, 0, 50, 13))  # stream
    assert whole.min() >= 0.0 and whole.max() < 1.0


def test_jitter_zero_width_gives_the_nominal_r_every_time():
    x, y = _sample(0, 21, 0.6)
    r = jitter_correlations(y, np.arange(21), 21, x[:, None], half_width=0.0, n_trials=200)
    summary = jitter_summary(r[:, 0], float(pearson_r(x, y)))
    # Every repetition is the same arithmetic on the same numbers, up to the order of sums.
    assert summary["sd"] == pytest.approx(0.0, abs=EPS)
    assert summary["max_relative_change"] == pytest.approx(0.0, abs=1e-10)
    assert summary["mean"] == pytest.approx(summary["r_nominal"], abs=EPS)


@pytest.mark.parametrize("observers, level", [(1, "rating"), (4, "rating"), (4, "mean")])
def test_jitter_mean_r_follows_the_attenuation_formula(observers, level):
    # Ratings y (per scene) receive independent noise e, uniform on [−w, w]: var e = w²/3.
    # The noise is independent of x and y, so cov(x, y + ē) = cov(x, y) while the variance
    # of the jittered means is σ_y² + var ē, with var ē = w²/(3k) when each of k observers'
    # ratings is jittered ("rating") and w²/3 when the mean is jittered ("mean"). Hence
    #     E r' ≈ r · σ_y / √(σ_y² + var ē)
    # (exact as n → ∞; the finite-n corrections are O(1/n)). With n = 4000 scenes the
    # per-trial SD of r' is ≈ 0.008, so the mean over 400 trials has MC SE ≈ 0.0004; the
    # tolerance 0.003 is ≈ 7 SE, also covering the O(1/n) ≈ 0.00025 bias.
    n, w = 4000, 1.5
    x, y = _sample(3, n, 0.6)
    ratings = np.repeat(y, observers)  # every observer gives the scene's value
    scene = np.repeat(np.arange(n), observers)
    r0, sigma = float(pearson_r(x, y)), y.std()
    var_noise = w * w / 3 / (observers if level == "rating" else 1)
    expected = r0 * sigma / math.sqrt(sigma ** 2 + var_noise)
    r = jitter_correlations(ratings, scene, n, x[:, None], half_width=w, n_trials=400,
                            level=level, seed=11)[:, 0]
    assert r.mean() == pytest.approx(expected, abs=0.003)
    assert r.mean() < r0 - 0.03  # the attenuation is real, ≥ 10× the tolerance


def test_jitter_reproducible_and_chunk_independent():
    x, y = _sample(1, 21, 0.5)
    ratings = np.repeat(y, 5) + np.tile(np.linspace(-1, 1, 5), 21)
    scene = np.repeat(np.arange(21), 5)
    columns = np.column_stack([x, x ** 2])
    big = jitter_correlations(ratings, scene, 21, columns, n_trials=CHUNK + 100, seed=2)
    small = jitter_correlations(ratings, scene, 21, columns, n_trials=100, seed=2)
    np.testing.assert_array_equal(big[:100], small)  # same repetitions, other chunking
    # The first repetition equals a hand-made jitter from the same stream.
    noise = 0.25 * (2 * uniform_block(2, 1, 0, 1, ratings.size)[0] - 1)
    means = np.bincount(scene, ratings + noise) / 5
    assert big[0, 0] == pytest.approx(stats.pearsonr(x, means).statistic, abs=EPS)
    assert not np.array_equal(
        small, jitter_correlations(ratings, scene, 21, columns, n_trials=100, seed=3))


def _bootstrap_reference(x, y, distribution, method, confidence):
    """scipy.stats.bootstrap's interval from our bootstrap distribution (no new resamples)."""
    def r(a, b, axis=-1):
        a = a - a.mean(axis=axis, keepdims=True)
        b = b - b.mean(axis=axis, keepdims=True)
        return (a * b).sum(axis) / np.sqrt((a * a).sum(axis) * (b * b).sum(axis))

    result = stats.bootstrap((x, y), r, paired=True, vectorized=True, n_resamples=0,
                             method=method, confidence_level=confidence,
                             bootstrap_result=SimpleNamespace(
                                 bootstrap_distribution=distribution))
    return result.confidence_interval


@pytest.mark.parametrize("confidence", [0.9, 0.95])
def test_bootstrap_intervals_equal_scipy_on_the_same_resamples(confidence):
    # scipy computes the percentile and BCa intervals (its own ẑ₀, jackknife â and
    # quantiles) from our distribution; the arithmetic must agree to rounding.
    x, y = _sample(4, 21, 0.6)
    boot = bootstrap_correlation(x, y, n_resamples=2000, confidence=confidence, seed=5)
    assert boot["n_degenerate"] == 0 and boot["distribution"].size == 2000
    for method, key in (("percentile", "percentile"), ("BCa", "bca")):
        ci = _bootstrap_reference(x, y, boot["distribution"], method, confidence)
        assert boot[key] == pytest.approx((ci.low, ci.high), abs=EPS)


def test_bootstrap_distribution_matches_resampling_theory():
    # For bivariate normal data, r's sampling SD is ≈ (1 − ρ²)/√(n − 1) (Fisher 1915);
    # the bootstrap SE over scenes estimates it. n = 200, ρ = 0.5: 0.053. The bootstrap SE
    # itself has a sampling error of ≈ 10 % at this n, hence rel = 0.2.
    x, y = _sample(6, 200, 0.5)
    boot = bootstrap_correlation(x, y, n_resamples=2000, seed=1)
    r = float(pearson_r(x, y))
    assert boot["standard_error"] == pytest.approx((1 - r * r) / math.sqrt(199), rel=0.2)
    low, high = boot["percentile"]
    assert low < r < high
    again = bootstrap_correlation(x, y, n_resamples=2000, seed=1)
    np.testing.assert_array_equal(boot["distribution"], again["distribution"])


def test_bootstrap_drops_degenerate_resamples():
    # Two distinct scenes only: a resample of one repeated scene has r undefined.
    x = np.array([0.0, 1.0, 0.0, 1.0])
    y = np.array([1.0, 2.0, 1.0, 2.0])
    boot = bootstrap_correlation(x, y, n_resamples=500, seed=0)
    # P(all four draws from one of the two values) = 2·(1/2)⁴ = 1/8 → about 62 of 500.
    assert 30 < boot["n_degenerate"] < 100
    assert np.all(np.abs(boot["distribution"]) == pytest.approx(1.0))


# --- leave-one-scene-out --------------------------------------------------------------------

def _loo_by_loop(metrics, rating):
    """Plain-loop reference: scipy's pearsonr for the choice, numpy.polyfit for the line."""
    n = rating.size
    prediction = np.empty(n)
    chosen = []
    for i in range(n):
        train = np.arange(n) != i
        r = [stats.pearsonr(metrics[train, j], rating[train]).statistic
             for j in range(metrics.shape[1])]
        j = int(np.argmax(r))
        chosen.append(j)
        slope, intercept = np.polyfit(metrics[train, j], rating[train], 1)
        prediction[i] = intercept + slope * metrics[i, j]
    return np.array(chosen), prediction


def test_leave_one_out_equals_a_plain_loop():
    rng = np.random.default_rng(8)
    rating = rng.uniform(2, 9, 15)
    metrics = rng.normal(size=(15, 12)) + 0.4 * rating[:, None] * rng.uniform(0, 1, 12)
    out = leave_one_out_selection(metrics, rating)
    chosen, prediction = _loo_by_loop(metrics, rating)
    np.testing.assert_array_equal(out["chosen_index"], chosen)
    # polyfit solves the least-squares problem by SVD, we by centred sums: both stable,
    # agreeing to ~1e-14 relative on ratings of O(10); 1e-10 leaves room.
    np.testing.assert_allclose(out["prediction"], prediction, rtol=0, atol=1e-10)
    assert out["r_loo"] == pytest.approx(stats.pearsonr(prediction, rating).statistic,
                                         abs=1e-10)
    residual = ((rating - prediction) ** 2).sum()
    assert out["q2"] == pytest.approx(1 - residual / ((rating - rating.mean()) ** 2).sum(),
                                      abs=1e-10)


def test_leave_one_out_is_less_optimistic_than_in_sample_choice():
    # 100 columns of pure noise and one weakly informative column (true ρ = 0.3), n = 25
    # scenes. The in-sample best r is the maximum of 101 noisy estimates: inflated well
    # above what the chosen column achieves on new scenes (known here: ρ if the signal
    # column is chosen, 0 for a noise column). Leave-one-out redoes the choice without
    # each scene, so it is not inflated — it is below in-sample for every seed, and on
    # average not above the true out-of-sample r. (LOO is, if anything, pessimistic for
    # small n: regression predictions from n − 1 points correlate negatively with the
    # held-out value under the null.)
    rho, n = 0.3, 25
    in_sample, loo, generalisation = [], [], []
    for seed in range(12):
        rng = np.random.default_rng(seed)
        rating = rng.normal(size=n)
        signal = rho * rating + math.sqrt(1 - rho * rho) * rng.normal(size=n)
        metrics = np.column_stack([rng.normal(size=(n, 100)), signal])
        out = leave_one_out_selection(metrics, rating)
        in_sample.append(out["r_in_sample"])
        loo.append(out["r_loo"])
        generalisation.append(rho if out["best_index"] == 100 else 0.0)
        assert out["r_loo"] < out["r_in_sample"]
    assert np.mean(in_sample) > np.mean(generalisation) + 0.2
    assert np.mean(loo) < np.mean(generalisation) + 0.05


def test_leave_one_out_recovers_a_clear_optimum():
    # One column is a strong predictor (ρ = 0.95), the rest noise: every fold chooses it
    # and the LOO r stays close to the in-sample r.
    rng = np.random.default_rng(2)
    rating = rng.normal(size=21)
    metrics = rng.normal(size=(21, 30))
    metrics[:, 17] = 0.95 * rating + math.sqrt(1 - 0.95 ** 2) * rng.normal(size=21)
    out = leave_one_out_selection(metrics, rating)
    assert np.all(out["chosen_index"] == 17) and out["best_index"] == 17
    assert out["r_loo"] == pytest.approx(out["r_loo_fixed"], abs=EPS)
    assert out["r_in_sample"] - 0.05 < out["r_loo"] < out["r_in_sample"]
