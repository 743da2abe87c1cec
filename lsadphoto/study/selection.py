"""Choosing the number of thresholds N: the r(N) sweep and its leave-one-scene-out check.

The paper chose N = 50 as the value with the largest Pearson r between Q(N) and the mean
observer ratings over the 21 stations (its Figure 2) and reported that r = 0.61. An r
maximised over N on the same scenes it is reported for is optimistic (the maximum of many
noisy estimates). :func:`leave_one_out_selection` repeats the whole choice of N without each
scene in turn and predicts that scene only from the others, so the resulting correlation is
an out-of-sample one.

Sign convention (``direction``): "positive" (default) takes the N with the largest r, the
right choice when a higher rating and a higher metric both mean better (the paper's r = 0.61
between Q and "how comfortable" ratings); "negative" takes the most negative r (a metric of
discomfort such as UGR against comfort ratings); "either" takes the largest |r|. Ties go to
the smallest N.

References
----------
Stone, M. (1974), Cross-validatory choice and assessment of statistical predictions, J. R.
Stat. Soc. B 36(2), 111–147.
Varma, S., Simon, R. (2006), Bias in error estimation when using cross-validation for model
selection, BMC Bioinformatics 7, 91, doi:10.1186/1471-2105-7-91.
"""

import math

import numpy as np

from ..errors import BadInputError
from .correlation import pearson_r

__all__ = ["DIRECTIONS", "best_index", "sweep_correlations", "leave_one_out_selection"]

#: Valid values of ``direction``: which r counts as "best".
DIRECTIONS = ("positive", "negative", "either")


def _check_direction(direction):
    if direction not in DIRECTIONS:
        raise BadInputError(f"unknown direction {direction!r}; valid: "
                            + ", ".join(repr(d) for d in DIRECTIONS))


def best_index(r, *, direction="positive"):
    """Index of the best correlation along the last axis (NaN ignored; ties → first index).

    Returns -1 where every entry is NaN.

    Examples
    --------
    >>> int(best_index([0.2, 0.6, -0.7])), int(best_index([0.2, 0.6, -0.7], direction="either"))
    (1, 2)
    """
    _check_direction(direction)
    r = np.asarray(r, dtype=np.float64)
    score = {"positive": r, "negative": -r, "either": np.abs(r)}[direction]
    score = np.where(np.isfinite(score), score, -np.inf)
    index = np.argmax(score, axis=-1)  # first maximum
    all_nan = ~np.isfinite(r).any(axis=-1)
    return np.where(all_nan, -1, index)[()]


def sweep_correlations(metrics, rating):
    """Pearson r between each metric column and the ratings.

    Parameters
    ----------
    metrics : ndarray, shape (n_scenes, k)
        Q(N) for k values of N.
    rating : ndarray, shape (n_scenes,)
        Mean rating per scene.

    Returns
    -------
    ndarray, shape (k,)
    """
    metrics = np.asarray(metrics, dtype=np.float64)
    return pearson_r(metrics.T, np.asarray(rating, dtype=np.float64)[None, :], axis=-1)


def leave_one_out_selection(metrics, rating, *, direction="positive"):
    """Leave-one-scene-out choice of N and the out-of-sample correlation.

    For every scene i (fold):

    1. on the other n − 1 scenes, compute r(N) for every column and choose N₍₋ᵢ₎ by
       ``direction`` (:func:`best_index`);
    2. on the same n − 1 scenes, fit the least-squares line rating = a + b·Q(N₍₋ᵢ₎);
    3. predict scene i: ŷᵢ = a + b·Qᵢ(N₍₋ᵢ₎).

    Scene i's own rating is used in none of these steps. The line maps Q(N) of different N
    (different scales) onto one rating scale, so the predictions of all folds can be compared.
    The reported ``r_loo`` is Pearson's r between ŷ and the observed mean ratings; also
    ``q2`` = 1 − Σ(yᵢ − ŷᵢ)²/Σ(yᵢ − ȳ)² (predictive R², can be negative) and ``rmse``.

    ``r_loo_fixed`` repeats steps 2–3 with N fixed at the in-sample best N (chosen on all
    scenes): the gap between ``r_in_sample`` and ``r_loo_fixed`` is the ordinary
    leave-one-out shrinkage of a fitted line, and the gap between ``r_loo_fixed`` and
    ``r_loo`` the optimism of choosing N on the reported scenes.

    Parameters
    ----------
    metrics : ndarray, shape (n_scenes, k)
        Q(N) for the k values of N.
    rating : ndarray, shape (n_scenes,)
        Mean rating per scene (n_scenes ≥ 4, so that each fold keeps 3 scenes).
    direction : {"positive", "negative", "either"}

    Returns
    -------
    dict
        ``chosen_index`` (ndarray of int, per held-out scene; −1 if no column is defined),
        ``prediction`` (ndarray), ``train_r`` (best r of each fold), ``best_index`` and
        ``r_in_sample`` (on all scenes), ``r_loo``, ``q2``, ``rmse``, ``r_loo_fixed``.

    References
    ----------
    Stone (1974); Varma & Simon (2006).
    """
    _check_direction(direction)
    metrics = np.asarray(metrics, dtype=np.float64)
    rating = np.asarray(rating, dtype=np.float64)
    n = rating.size
    if n < 4:
        raise BadInputError(f"leave-one-out needs at least 4 scenes, got {n}")
    keep = ~np.eye(n, dtype=bool)
    # Training sets of all folds at once: (fold, n−1) ratings and (fold, n−1, k) metrics.
    y_train = np.broadcast_to(rating, (n, n))[keep].reshape(n, n - 1)
    x_train = np.broadcast_to(metrics, (n,) + metrics.shape)[keep].reshape(n, n - 1, -1)
    r_train = pearson_r(np.moveaxis(x_train, 1, 2), y_train[:, None, :], axis=-1)  # (n, k)
    chosen = best_index(r_train, direction=direction)
    r_all = sweep_correlations(metrics, rating)
    best = int(best_index(r_all, direction=direction))

    def predict(column_of_fold):
        prediction = np.full(n, np.nan)
        for i in range(n):
            c = column_of_fold[i]
            if c < 0:
                continue
            x = x_train[i, :, c]
            xc = x - x.mean()
            sxx = (xc * xc).sum()
            if sxx == 0:
                continue
            slope = (xc * (y_train[i] - y_train[i].mean())).sum() / sxx
            prediction[i] = y_train[i].mean() + slope * (metrics[i, c] - x.mean())
        return prediction

    prediction = predict(chosen)
    fixed = predict(np.full(n, best)) if best >= 0 else np.full(n, np.nan)
    total = ((rating - rating.mean()) ** 2).sum()
    if np.all(np.isfinite(prediction)):
        residual = ((rating - prediction) ** 2).sum()
        r_loo = float(pearson_r(prediction, rating))
        q2 = float(1.0 - residual / total) if total > 0 else math.nan
        rmse = float(math.sqrt(residual / n))
    else:
        r_loo = q2 = rmse = math.nan
    r_fixed = float(pearson_r(fixed, rating)) if np.all(np.isfinite(fixed)) else math.nan
    return {
        "chosen_index": np.asarray(chosen, dtype=np.intp),
        "prediction": prediction,
        "train_r": np.array([r_train[i, c] if c >= 0 else np.nan for i, c in enumerate(chosen)]),
        "best_index": best,
        "r_in_sample": float(r_all[best]) if best >= 0 else math.nan,
        "r_loo": r_loo,
        "q2": q2,
        "rmse": rmse,
        "r_loo_fixed": r_fixed,
    }
