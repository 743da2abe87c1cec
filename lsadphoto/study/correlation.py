"""Correlation coefficients between a metric and the mean ratings, with tests and intervals.

Pearson's r with a Fisher z confidence interval, Spearman's ρ and Kendall's τ-b with their
two-sided p-values, and the Chaddock scale label of |r|. The coefficients are computed here
with numpy (centred two-pass sums, float64); the p-values use the same null distributions as
:mod:`scipy.stats` so that they agree with ``pearsonr``, ``spearmanr`` and ``kendalltau``:

* Pearson and Spearman: Student's t with n − 2 degrees of freedom, written as the regularised
  incomplete beta function p = I_{1−r²}((n − 2)/2, 1/2).
* Kendall: the exact permutation distribution (Kendall 1970, the number of permutations with
  a given number of inversions) when there are no ties and n ≤ 33 (or the statistic is
  within one pair of the extreme), else the normal approximation with the tie-corrected
  variance (Kendall 1970, eq. 4.3) — the choice of ``scipy.stats.kendalltau(method='auto')``.

References
----------
Fisher, R. A. (1915), Frequency distribution of the values of the correlation coefficient in
samples from an indefinitely large population, Biometrika 10(4), 507–521.
Fisher, R. A. (1921), On the "probable error" of a coefficient of correlation deduced from a
small sample, Metron 1, 3–32.
Kendall, M. G. (1970), Rank Correlation Methods, 4th ed., Griffin, London.
Chaddock, R. E. (1925), Principles and Methods of Statistics, Houghton Mifflin, Boston.
"""

import math

import numpy as np
from scipy import special

from .._validation import check_array
from ..errors import BadInputError

__all__ = ["CHADDOCK_SCALE", "chaddock_label", "pearson_r", "ranks", "fisher_interval_Fisher1921",
           "correlation_p_value", "kendall_tau_b", "correlate"]

#: Chaddock (1925) scale of the strength of a correlation: (lower bound of |r|, label).
#: Lower bounds are inclusive; |r| < 0.1 is "none". The labels are the usual English renderings
#: of the Russian "слабая, умеренная, заметная, высокая, весьма высокая" used with this scale
#: in Russian-language statistics texts, as in the paper ("a noticeable correlation on the
#: Chaddock scale" for r = 0.61).
CHADDOCK_SCALE = ((0.9, "very high"), (0.7, "high"), (0.5, "noticeable"), (0.3, "moderate"),
                  (0.1, "weak"), (0.0, "none"))

#: Largest n for which Kendall's exact null distribution is used without ties (scipy's rule).
KENDALL_EXACT_MAX_N = 33


def chaddock_label(r):
    """Chaddock scale label of the correlation coefficient ``r`` (by |r|).

    0.1 ≤ |r| < 0.3 weak, 0.3–0.5 moderate, 0.5–0.7 noticeable, 0.7–0.9 high, 0.9–1 very high,
    below 0.1 none; ``None`` for NaN.

    References
    ----------
    Chaddock, R. E. (1925), Principles and Methods of Statistics.

    Examples
    --------
    >>> chaddock_label(0.61), chaddock_label(-0.73), chaddock_label(0.05)
    ('noticeable', 'high', 'none')
    """
    r = float(r)
    if math.isnan(r):
        return None
    for bound, label in CHADDOCK_SCALE:
        if abs(r) >= bound:
            return label
    return "none"  # pragma: no cover (the last bound is 0)


def pearson_r(x, y, *, axis=-1):
    """Pearson's correlation coefficient along ``axis`` (broadcasting x against y).

    Centred two-pass sums in float64; NaN where either input is constant along the axis.

    Parameters
    ----------
    x, y : array_like
        Paired samples; the correlation is taken along ``axis`` after broadcasting.
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    x, y = np.broadcast_arrays(x, y)
    xc = x - x.mean(axis=axis, keepdims=True)
    yc = y - y.mean(axis=axis, keepdims=True)
    sxy = (xc * yc).sum(axis=axis)
    sxx = (xc * xc).sum(axis=axis)
    syy = (yc * yc).sum(axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = sxy / np.sqrt(sxx * syy)
    # Rounding can push |r| a few ulp past 1 (as in scipy.stats.pearsonr, which clips).
    return np.clip(r, -1.0, 1.0)


def ranks(values):
    """Ranks 1…n of a 1-d sample, ties given their average rank ("fractional ranking")."""
    values = np.asarray(values, dtype=np.float64)
    order = np.argsort(values, kind="mergesort")
    sorted_values = values[order]
    # Start index of each run of equal values, and the run it belongs to.
    new_run = np.concatenate(([True], sorted_values[1:] != sorted_values[:-1]))
    run = np.cumsum(new_run) - 1
    starts = np.flatnonzero(new_run)
    ends = np.concatenate((starts[1:], [values.size]))
    average = (starts + ends + 1) / 2.0  # mean of positions start+1 … end
    result = np.empty(values.size)
    result[order] = average[run]
    return result


def fisher_interval_Fisher1921(r, n, *, confidence=0.95):
    """Confidence interval of a Pearson correlation by Fisher's z transformation.

    z = artanh(r) is nearly normal with standard error 1/√(n − 3) (Fisher 1915, 1921); the
    interval is tanh(z ± z_{(1+c)/2}/√(n − 3)). ``(nan, nan)`` for n ≤ 3 or NaN r; (r, r)
    for |r| = 1.

    Parameters
    ----------
    r : float
        Sample correlation coefficient.
    n : int
        Number of pairs.
    confidence : float
        Confidence level c, 0 < c < 1.

    Returns
    -------
    (float, float)

    References
    ----------
    Fisher, R. A. (1921), Metron 1, 3–32.

    Examples
    --------
    >>> lo, hi = fisher_interval_Fisher1921(0.61, 21)
    >>> round(lo, 3), round(hi, 3)
    (0.242, 0.825)
    """
    if not 0.0 < confidence < 1.0:
        raise BadInputError(f"confidence must be between 0 and 1, got {confidence!r}")
    r = float(r)
    if n <= 3 or math.isnan(r):
        return (math.nan, math.nan)
    if abs(r) >= 1.0:
        return (r, r)
    half = special.ndtri(0.5 + confidence / 2.0) / math.sqrt(n - 3)
    z = math.atanh(r)
    return (math.tanh(z - half), math.tanh(z + half))


def correlation_p_value(r, n):
    """Two-sided p-value of a Pearson (or Spearman) coefficient under independence.

    p = I_{1−r²}((n − 2)/2, 1/2), the two-sided tail of Student's t = r√((n−2)/(1−r²)) with
    n − 2 degrees of freedom (exact for Pearson's r of bivariate normal data).
    """
    r = np.asarray(r, dtype=np.float64)
    df = n - 2
    if df < 1:
        return np.full(r.shape, np.nan)[()]
    return special.betainc(df / 2.0, 0.5, np.clip(1.0 - r * r, 0.0, 1.0))[()]


def _tie_sums(values):
    """Σ t(t−1)/2, Σ t(t−1)(t−2), Σ t(t−1)(2t+5) over groups of t tied values."""
    _, counts = np.unique(values, return_counts=True)
    t = counts[counts > 1].astype(np.float64)
    return (float((t * (t - 1) / 2).sum()), float((t * (t - 1) * (t - 2)).sum()),
            float((t * (t - 1) * (2 * t + 5)).sum()))


def _kendall_exact_p(n, discordant):
    """Two-sided exact p-value of Kendall's statistic without ties.

    The number of permutations of n items with k inversions (discordant pairs) is the
    coefficient of q^k in Π_{j=1}^{n} (1 + q + … + q^{j−1}) (Kendall 1970, ch. 4); the
    distribution is symmetric, so p = 2·P(K ≤ min(k, n(n−1)/2 − k)), at most 1. Counts are
    exact Python integers.
    """
    total = n * (n - 1) // 2
    c = min(discordant, total - discordant)
    counts = [1]  # polynomial coefficients up to q^c
    for j in range(2, n + 1):
        new = []
        running = 0
        for k in range(min(len(counts) + j - 1, c + 1)):
            running += counts[k] if k < len(counts) else 0
            if k - j >= 0:
                running -= counts[k - j]
            new.append(running)
        counts = new
    return min(1.0, 2.0 * sum(counts[:c + 1]) / math.factorial(n))


def kendall_tau_b(x, y):
    """Kendall's τ-b and its two-sided p-value.

    τ_b = (C − D)/√((P − T_x)(P − T_y)) over the P = n(n−1)/2 pairs, C concordant, D
    discordant, T_x and T_y pairs tied in x or y (Kendall 1970). The p-value is exact
    (:func:`_kendall_exact_p`) without ties for n ≤ 33 or D within one of 0 or P, otherwise
    from the normal approximation with the tie-corrected variance

        var(C − D) = [n(n−1)(2n+5) − Σt(t−1)(2t+5) − Σu(u−1)(2u+5)]/18
                     + Σt(t−1)(t−2)·Σu(u−1)(u−2)/(9n(n−1)(n−2))
                     + Σt(t−1)·Σu(u−1)/(2n(n−1)).

    Returns
    -------
    (float, float)
        τ_b, p; NaN for n < 2 or a constant input.
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = x.size
    if n < 2:
        return (math.nan, math.nan)
    upper = np.triu_indices(n, 1)
    sx = np.sign(x[:, None] - x[None, :])[upper]
    sy = np.sign(y[:, None] - y[None, :])[upper]
    s = float((sx * sy).sum())  # C − D
    total = n * (n - 1) / 2
    x_ties, x2, x3 = _tie_sums(x)
    y_ties, y2, y3 = _tie_sums(y)
    if x_ties == total or y_ties == total:
        return (math.nan, math.nan)
    tau = s / math.sqrt(total - x_ties) / math.sqrt(total - y_ties)
    discordant = int(((sx * sy) < 0).sum())
    if x_ties == 0 and y_ties == 0 and (
            n <= KENDALL_EXACT_MAX_N or min(discordant, total - discordant) <= 1):
        p = _kendall_exact_p(n, discordant)
    else:
        m = n * (n - 1.0)
        var = ((m * (2 * n + 5) - x3 - y3) / 18 + 2 * x_ties * y_ties / m
               + x2 * y2 / (9 * m * (n - 2)))
        p = float(special.erfc(abs(s) / math.sqrt(var) / math.sqrt(2.0)))
    return (tau, p)


def correlate(metric, rating, *, confidence=0.95):
    """All correlation statistics between a metric and the mean ratings of the same scenes.

    Parameters
    ----------
    metric : array_like, shape (n,)
        Metric value per scene (e.g. Q or pixel-UGR).
    rating : array_like, shape (n,)
        Mean rating per scene.
    confidence : float
        Level of the Fisher-z interval of r.

    Returns
    -------
    dict
        ``n``, ``pearson_r``, ``pearson_p``, ``pearson_ci`` (Fisher z), ``spearman_rho``,
        ``spearman_p``, ``kendall_tau`` (τ-b), ``kendall_p``, ``chaddock`` (label of |r|);
        NaN (label ``None``) where undefined, e.g. for a constant metric.

    References
    ----------
    Fisher (1921); Kendall (1970); Chaddock (1925).

    Examples
    --------
    >>> stats = correlate([1, 2, 3, 4, 5], [2.0, 2.5, 3.9, 4.1, 5.2])
    >>> round(stats["pearson_r"], 4), stats["chaddock"], round(stats["kendall_tau"], 12)
    (0.9809, 'very high', 1.0)
    """
    metric = check_array(metric, "metric", ndim=1, dtype=np.float64, finite=True)
    rating = check_array(rating, "rating", ndim=1, dtype=np.float64, finite=True)
    if metric.shape != rating.shape:
        raise BadInputError(f"metric and rating differ in length: {metric.size} and "
                            f"{rating.size}")
    n = metric.size
    if n < 3:
        raise BadInputError(f"a correlation needs at least 3 scenes, got {n}")
    r = float(pearson_r(metric, rating))
    rho = float(pearson_r(ranks(metric), ranks(rating)))
    tau, tau_p = kendall_tau_b(metric, rating)
    return {
        "n": n,
        "pearson_r": r,
        "pearson_p": float(correlation_p_value(r, n)) if not math.isnan(r) else math.nan,
        "pearson_ci": fisher_interval_Fisher1921(r, n, confidence=confidence),
        "spearman_rho": rho,
        "spearman_p": float(correlation_p_value(rho, n)) if not math.isnan(rho) else math.nan,
        "kendall_tau": tau,
        "kendall_p": tau_p,
        "chaddock": chaddock_label(r),
    }
