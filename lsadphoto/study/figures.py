"""The paper's Figures 1 and 2 for an observer study (matplotlib Agg, nothing global touched).

* :func:`figure_ratings_vs_metric` — mean observer rating against a metric (Q), one point per
  scene with its standard error, the least-squares line and Pearson r (the paper's Figure 1).
* :func:`figure_r_vs_n` — Pearson r against the number of thresholds N with its confidence
  band, the best N marked and the Ns chosen by the leave-one-scene-out folds (Figure 2).

Each returns a :class:`matplotlib.figure.Figure`; :func:`write_scatter_png` and
:func:`write_sweep_png` write them as PNG, atomically. The HTML reports
(:mod:`lsadphoto.report.plots`) draw the same figures with these functions.

References
----------
Budak, V. P. et al. (2020), Luminance spatial-angular distribution as a basis for lighting
quality assessment, GraphiCon 2020, CEUR Vol-2744 short35, Figures 1 and 2.
"""

import math

import numpy as np

from .._atomic import atomic_path
from .correlation import pearson_r

__all__ = ["figure_ratings_vs_metric", "figure_r_vs_n", "write_scatter_png", "write_sweep_png"]


def _figure(width=6.0, height=4.5, dpi=100):
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=dpi)


def _vector(values):
    return np.asarray(values, dtype=np.float64).reshape(-1)


def _errors(values, size):
    """Error-bar half-lengths: non-finite or negative entries drawn as none (0)."""
    if values is None:
        return None
    errors = np.asarray(values, dtype=np.float64).reshape(-1)
    if errors.size != size:
        return None
    errors = np.where(np.isfinite(errors) & (errors > 0), errors, 0.0)
    return errors if np.any(errors > 0) else None


def _fit_line(ax, x, y):
    """Least-squares line y = a + b·x over the finite pairs (nothing for a constant x)."""
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 2 or np.ptp(x[ok]) == 0:
        return None
    slope, intercept = np.polyfit(x[ok], y[ok], 1)
    xs = np.linspace(x[ok].min(), x[ok].max(), 2)
    ax.plot(xs, intercept + slope * xs, color="tab:red", lw=1.2,
            label=f"least squares: y = {intercept:.3g} {'−' if slope < 0 else '+'} "
                  f"{abs(slope):.3g}·x")
    return slope, intercept


def _r_text(x, y):
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 3:
        return None
    r = float(pearson_r(x[ok], y[ok]))
    return None if math.isnan(r) else f"r = {r:.3f}, n = {int(ok.sum())}"


def _annotate(ax, x, y, labels):
    if labels is None or len(labels) > 40:  # beyond ~40 points the names only clutter
        return
    for xi, yi, label in zip(x, y, labels):
        if np.isfinite(xi) and np.isfinite(yi):
            ax.annotate(str(label), (xi, yi), xytext=(3, 3), textcoords="offset points",
                        fontsize=7, color="0.3")


def figure_ratings_vs_metric(metric, rating, *, sem=None, labels=None, metric_name="Q",
                             r=None, title=None, dpi=100):
    """Mean observer rating against a metric, with error bars and the fitted line (Fig. 1).

    Parameters
    ----------
    metric, rating : array_like, shape (n,)
        Metric value and mean rating per scene (NaN pairs are left out).
    sem : array_like, shape (n,), optional
        Standard error of each mean rating [rating units], drawn as vertical error bars.
    labels : sequence of str, optional
        Scene names written beside the points (only up to 40 scenes).
    metric_name : str
        Horizontal axis label.
    r : float, optional
        Pearson r to print in the title (default: computed from the points).

    Returns
    -------
    matplotlib.figure.Figure

    References
    ----------
    Budak et al. (2020), Figure 1.
    """
    x = _vector(metric)
    y = _vector(rating)
    fig = _figure(dpi=dpi)
    ax = fig.add_subplot()
    ax.errorbar(x, y, yerr=_errors(sem, y.size), fmt="o", ms=5, capsize=3,
                color="tab:blue", ecolor="0.55", label="scene (mean ± standard error)")
    _fit_line(ax, x, y)
    _annotate(ax, x, y, labels)
    ax.set_xlabel(metric_name)
    ax.set_ylabel("mean rating")
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7, loc="best", framealpha=0.8)
    text = f"r = {r:.3f}" if r is not None and math.isfinite(r) else _r_text(x, y)
    ax.set_title(title or f"Fig. 1 — ratings against {metric_name}"
                 + (f" ({text})" if text else ""), fontsize=10)
    fig.tight_layout()
    return fig


def figure_r_vs_n(n_values, r, *, ci_low=None, ci_high=None, best_n=None, best_r=None,
                  loo_chosen_n=None, confidence=0.95, title=None, dpi=100):
    """Pearson r of Q(N) with the mean ratings against N, band and best N marked (Fig. 2).

    Parameters
    ----------
    n_values, r : array_like, shape (k,)
        Numbers of thresholds N and r(N) (NaN where undefined).
    ci_low, ci_high : array_like, shape (k,), optional
        Confidence band of r (Fisher z), drawn shaded.
    best_n, best_r : float, optional
        The chosen N and its r, marked by a dashed line and a point.
    loo_chosen_n : array_like, optional
        N chosen in each leave-one-scene-out fold, drawn as ticks along the bottom.
    confidence : float
        Level of the band, for the legend.

    Returns
    -------
    matplotlib.figure.Figure

    References
    ----------
    Budak et al. (2020), Figure 2; Fisher (1921).
    """
    n_values = _vector(n_values)
    r = _vector(r)
    fig = _figure(dpi=dpi)
    ax = fig.add_subplot()
    if ci_low is not None and ci_high is not None:
        low = np.asarray(ci_low, dtype=np.float64)
        high = np.asarray(ci_high, dtype=np.float64)
        if low.shape == r.shape and high.shape == r.shape and np.any(np.isfinite(low)):
            ax.fill_between(n_values, low, high, color="tab:blue", alpha=0.15, lw=0,
                            label=f"{100 * confidence:g} % confidence band (Fisher z)")
    ax.plot(n_values, r, color="tab:blue", marker="." if n_values.size < 60 else None,
            label="r(N)")
    if best_n is not None and math.isfinite(float(best_n)):
        ax.axvline(float(best_n), color="tab:red", lw=1, ls="--",
                   label=f"best N = {float(best_n):g}"
                   + (f", r = {best_r:.3f}" if best_r is not None and math.isfinite(best_r)
                      else ""))
        if best_r is not None and math.isfinite(best_r):
            ax.plot([float(best_n)], [best_r], "o", color="tab:red", ms=6)
    if loo_chosen_n is not None:
        chosen = np.asarray([np.nan if c is None else c for c in loo_chosen_n],
                            dtype=np.float64)
        chosen = chosen[np.isfinite(chosen)]
        if chosen.size:
            ax.plot(chosen, np.full(chosen.shape, -1.0), "|", color="tab:green", ms=14,
                    label="N chosen per left-out scene")
    ax.set_xlabel("number of thresholds N")
    ax.set_ylabel("Pearson r with mean rating")
    ax.set_ylim(-1.05, 1.05)
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7, loc="lower right", framealpha=0.8)
    ax.set_title(title or "Fig. 2 — correlation r against the number of thresholds N",
                 fontsize=10)
    fig.tight_layout()
    return fig


def _write(figure, path):
    with atomic_path(path) as temp:
        figure.savefig(temp, format="png")


def write_scatter_png(metric, rating, path, *, sem=None, labels=None, metric_name="Q",
                      title=None, dpi=100):
    """:func:`figure_ratings_vs_metric` written to ``path`` (PNG, atomically)."""
    _write(figure_ratings_vs_metric(metric, rating, sem=sem, labels=labels,
                                    metric_name=metric_name, title=title, dpi=dpi), path)


def write_sweep_png(n_values, r, path, *, ci_low=None, ci_high=None, best_n=None,
                    loo_chosen_n=None, title=None, dpi=100):
    """:func:`figure_r_vs_n` written to ``path`` (PNG, atomically)."""
    _write(figure_r_vs_n(n_values, r, ci_low=ci_low, ci_high=ci_high, best_n=best_n,
                         loo_chosen_n=loo_chosen_n, title=title, dpi=dpi), path)
