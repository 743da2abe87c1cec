"""Monte Carlo checks of a correlation: rating jitter (the paper's robustness check) and
the bootstrap over scenes.

Random numbers come from counter-based streams (Philox, Salmon et al. 2011) keyed by
(seed, stream): repetition j always reads the same block of the stream, found by advancing
the counter, so results depend only on the seed — not on the chunk size used to bound
memory. Uniform variates are ``Generator.random`` doubles (53 random bits each); a
bootstrap index is ⌊u·n⌋.

References
----------
Efron, B., Tibshirani, R. J. (1993), An Introduction to the Bootstrap, Chapman & Hall,
ch. 13 (percentile interval), ch. 14.3 (BCa interval), eq. 14.15 (acceleration from the
jackknife).
Salmon, J. K., Moraes, M. A., Dror, R. O., Shaw, D. E. (2011), Parallel random numbers: as
easy as 1, 2, 3, SC '11, doi:10.1145/2063384.2063405.
"""

import math

import numpy as np
from scipy import special

from ..errors import BadInputError
from .correlation import pearson_r

__all__ = ["JITTER_LEVELS", "uniform_block", "jitter_correlations", "jitter_summary",
           "bootstrap_correlation"]

#: Where the jitter is added: to each observer's rating (the paper: "the observers'
#: responses randomly varied within 0.25 of the nominal value"), or to the per-scene means.
JITTER_LEVELS = ("rating", "mean")

#: Repetitions per chunk: bounds memory to about CHUNK × (ratings + scenes × columns) doubles.
CHUNK = 1024

_STREAM_JITTER = 1
_STREAM_BOOTSTRAP = 2


def uniform_block(seed, stream, start, count, width):
    """Uniform [0, 1) variates for repetitions ``start`` … ``start + count − 1``.

    Row j of the result is the same for every (start, count) that contains repetition j.

    Parameters
    ----------
    seed : int
        Non-negative seed of the study.
    stream : int
        Independent stream number (jitter, bootstrap).
    start, count : int
        First repetition and number of repetitions.
    width : int
        Variates per repetition.

    Returns
    -------
    ndarray, shape (count, width)
    """
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
        raise BadInputError(f"seed must be a non-negative integer, got {seed!r}")
    key = np.random.SeedSequence(int(seed), spawn_key=(stream,)).generate_state(2, np.uint64)
    generator = np.random.Philox(key=key)
    padded = -(-width // 4) * 4  # Philox yields 4 × 64 bits per counter step
    generator.advance(start * padded // 4)
    return np.random.Generator(generator).random(count * padded).reshape(count, padded)[:, :width]


def _normalised_columns(metrics):
    """Centred metric columns scaled to unit norm (NaN columns where constant)."""
    centred = metrics - metrics.mean(axis=0)
    norm = np.sqrt((centred * centred).sum(axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        return centred / norm


def jitter_correlations(rating, scene_index, n_scenes, metrics, *, half_width=0.25,
                        n_trials=10000, level="rating", seed=0):
    """Pearson r between metrics and mean ratings when every rating is jittered.

    Each repetition adds independent uniform noise on [−w, w] to every individual rating
    (``level="rating"``) or to every scene's mean rating (``level="mean"``), recomputes the
    per-scene means and correlates them with each metric column. Fully vectorised in chunks
    of :data:`CHUNK` repetitions.

    Parameters
    ----------
    rating : ndarray, shape (m,)
        Individual ratings.
    scene_index : ndarray of int, shape (m,)
        Scene (0 … n_scenes − 1) of each rating.
    n_scenes : int
    metrics : ndarray, shape (n_scenes, k)
        Metric columns (e.g. Q and the Q(N) sweep).
    half_width : float
        w, half the width of the uniform jitter [rating units].
    n_trials : int
    level : {"rating", "mean"}
    seed : int

    Returns
    -------
    ndarray, shape (n_trials, k)
        r per repetition and column (NaN for a constant column).
    """
    if level not in JITTER_LEVELS:
        raise BadInputError(f"unknown jitter level {level!r}; valid: "
                            + ", ".join(repr(v) for v in JITTER_LEVELS))
    rating = np.asarray(rating, dtype=np.float64)
    scene_index = np.asarray(scene_index, dtype=np.intp)
    metrics = np.asarray(metrics, dtype=np.float64).reshape(n_scenes, -1)
    counts = np.bincount(scene_index, minlength=n_scenes).astype(np.float64)
    if np.any(counts == 0):
        raise BadInputError(f"scene {int(np.argmin(counts))} has no ratings")
    means = np.bincount(scene_index, rating, n_scenes) / counts
    columns = _normalised_columns(metrics)
    # Ratings grouped by scene, so that a per-scene sum is one np.add.reduceat; the noise
    # of rating j stays column j of the stream, whatever the file order.
    order = np.argsort(scene_index, kind="stable")
    starts = np.concatenate(([0], np.cumsum(counts[:-1]))).astype(np.intp)
    width = rating.size if level == "rating" else n_scenes
    result = np.empty((n_trials, metrics.shape[1]))
    for start in range(0, n_trials, CHUNK):
        count = min(CHUNK, n_trials - start)
        noise = half_width * (2.0 * uniform_block(seed, _STREAM_JITTER, start, count, width)
                              - 1.0)
        if level == "rating":
            noise = np.add.reduceat(noise[:, order], starts, axis=1) / counts
        shifted = means + noise
        shifted -= shifted.mean(axis=1, keepdims=True)
        norm = np.sqrt((shifted * shifted).sum(axis=1, keepdims=True))
        with np.errstate(invalid="ignore", divide="ignore"):
            result[start:start + count] = np.clip((shifted / norm) @ columns, -1.0, 1.0)
    return result


def jitter_summary(r_trials, r_nominal):
    """Mean, SD (ddof = 1), 2.5/97.5 % percentiles, extremes and the largest relative
    change max|r_j − r₀|/|r₀| of the jittered correlations ``r_trials`` (1-d)."""
    r_trials = np.asarray(r_trials, dtype=np.float64)
    finite = r_trials[np.isfinite(r_trials)]
    if finite.size == 0 or not math.isfinite(r_nominal):
        return {"r_nominal": r_nominal, "mean": math.nan, "sd": math.nan,
                "percentile_2.5": math.nan, "percentile_97.5": math.nan, "min": math.nan,
                "max": math.nan, "max_relative_change": math.nan}
    low, high = np.percentile(finite, [2.5, 97.5])
    change = np.abs(finite - r_nominal).max()
    return {
        "r_nominal": float(r_nominal),
        "mean": float(finite.mean()),
        "sd": float(finite.std(ddof=1)) if finite.size > 1 else 0.0,
        "percentile_2.5": float(low),
        "percentile_97.5": float(high),
        "min": float(finite.min()),
        "max": float(finite.max()),
        "max_relative_change": float(change / abs(r_nominal)) if r_nominal != 0 else math.nan,
    }


def _quantiles(values, probabilities):
    return np.quantile(values, probabilities)  # linear interpolation (Hyndman & Fan type 7)


def bootstrap_correlation(metric, rating, *, n_resamples=10000, confidence=0.95, seed=0):
    """Bootstrap distribution and intervals of Pearson's r, resampling scenes.

    Each resample draws n scenes with replacement (pairs kept together) and recomputes r.
    Resamples with a constant metric or rating (r undefined) are dropped and counted.

    Intervals, both at level c with α = (1 − c)/2:

    * percentile: the α and 1 − α quantiles of the bootstrap r (Efron & Tibshirani 1993,
      §13.3);
    * BCa (bias-corrected and accelerated, §14.3): quantiles at
      α₁,₂ = Φ(ẑ₀ + (ẑ₀ + z)/(1 − â(ẑ₀ + z))) for z = Φ⁻¹(α), Φ⁻¹(1 − α), with
      ẑ₀ = Φ⁻¹(#{r* < r̂}/B + #{r* = r̂}/(2B)) and the jackknife acceleration
      â = Σ(r̄₍·₎ − r₍ᵢ₎)³ / (6[Σ(r̄₍·₎ − r₍ᵢ₎)²]^{3/2}) (eq. 14.15).

    Quantiles interpolate linearly (Hyndman & Fan type 7), as ``scipy.stats.bootstrap``.

    Parameters
    ----------
    metric, rating : array_like, shape (n,)
    n_resamples : int
    confidence : float
    seed : int

    Returns
    -------
    dict
        ``distribution`` (ndarray of the kept r*), ``n_resamples``, ``n_degenerate``,
        ``standard_error``, ``percentile`` (lo, hi), ``bca`` (lo, hi), ``bias_correction``
        ẑ₀, ``acceleration`` â.

    References
    ----------
    Efron, B., Tibshirani, R. J. (1993), An Introduction to the Bootstrap, ch. 13–14.
    """
    metric = np.asarray(metric, dtype=np.float64)
    rating = np.asarray(rating, dtype=np.float64)
    n = metric.size
    if not 0.0 < confidence < 1.0:
        raise BadInputError(f"confidence must be between 0 and 1, got {confidence!r}")
    r_hat = float(pearson_r(metric, rating))
    parts = []
    for start in range(0, n_resamples, CHUNK):
        count = min(CHUNK, n_resamples - start)
        u = uniform_block(seed, _STREAM_BOOTSTRAP, start, count, n)
        index = np.minimum((u * n).astype(np.intp), n - 1)
        parts.append(pearson_r(metric[index], rating[index], axis=1))
    distribution = np.concatenate(parts) if parts else np.empty(0)
    kept = distribution[np.isfinite(distribution)]
    alpha = (1.0 - confidence) / 2.0
    result = {"distribution": kept, "n_resamples": int(n_resamples),
              "n_degenerate": int(distribution.size - kept.size),
              "standard_error": math.nan, "percentile": (math.nan, math.nan),
              "bca": (math.nan, math.nan), "bias_correction": math.nan,
              "acceleration": math.nan}
    if kept.size < 2 or not math.isfinite(r_hat):
        return result
    result["standard_error"] = float(kept.std(ddof=1))
    result["percentile"] = tuple(float(v) for v in _quantiles(kept, [alpha, 1.0 - alpha]))
    # BCa: bias correction from the share of r* below r̂ (ties count half, as scipy does).
    share = (np.count_nonzero(kept < r_hat) + np.count_nonzero(kept <= r_hat)) / (2.0 * kept.size)
    z0 = float(special.ndtri(share))
    leave_out = ~np.eye(n, dtype=bool)
    jack = pearson_r(np.broadcast_to(metric, (n, n))[leave_out].reshape(n, n - 1),
                     np.broadcast_to(rating, (n, n))[leave_out].reshape(n, n - 1), axis=1)
    d = jack.mean() - jack
    denominator = 6.0 * (d * d).sum() ** 1.5
    a = float((d ** 3).sum() / denominator) if denominator > 0 else 0.0
    result["bias_correction"], result["acceleration"] = z0, a
    if math.isfinite(z0) and math.isfinite(a):
        z = special.ndtri(np.array([alpha, 1.0 - alpha]))
        levels = special.ndtr(z0 + (z0 + z) / (1.0 - a * (z0 + z)))
        result["bca"] = tuple(float(v) for v in _quantiles(kept, levels))
    return result
