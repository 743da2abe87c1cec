"""Figures of an observer study (matplotlib Agg, written atomically as PNG).

* :func:`write_scatter_png` — mean rating against a metric, one point per scene with its
  standard error, and the least-squares line (the paper's Figure 1).
* :func:`write_sweep_png` — Pearson r against N with its Fisher-z band, the best N marked
  and the Ns chosen by the leave-one-scene-out folds (the paper's Figure 2).
"""

import numpy as np

from ..io._atomic import atomic_path

__all__ = ["write_scatter_png", "write_sweep_png"]


def _figure(width=6.0, height=4.5, dpi=100):
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=dpi)


def write_scatter_png(metric, rating, path, *, sem=None, labels=None, metric_name="Q",
                      title=None, dpi=100):
    """Scatter of mean rating (vertical) against a metric (horizontal), with the fitted line.

    Parameters
    ----------
    metric, rating : array_like, shape (n,)
        Metric and mean rating per scene.
    path : path-like
        PNG to write (atomically).
    sem : array_like, shape (n,), optional
        Standard error of each mean rating, drawn as error bars (NaN: none).
    labels : sequence of str, optional
        Scene names written beside the points.
    """
    metric = np.asarray(metric, dtype=np.float64)
    rating = np.asarray(rating, dtype=np.float64)
    fig = _figure(dpi=dpi)
    ax = fig.add_subplot()
    yerr = None if sem is None else np.nan_to_num(np.asarray(sem, dtype=np.float64))
    ax.errorbar(metric, rating, yerr=yerr, fmt="o", ms=5, capsize=3, color="tab:blue",
                ecolor="0.6")
    if np.ptp(metric) > 0:
        slope, intercept = np.polyfit(metric, rating, 1)
        xs = np.linspace(metric.min(), metric.max(), 2)
        ax.plot(xs, intercept + slope * xs, color="tab:red", lw=1)
    if labels is not None:
        for x, y, label in zip(metric, rating, labels):
            ax.annotate(str(label), (x, y), xytext=(3, 3), textcoords="offset points",
                        fontsize=7, color="0.3")
    ax.set_xlabel(metric_name)
    ax.set_ylabel("mean rating (± standard error)")
    ax.grid(True, lw=0.3)
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    with atomic_path(path) as temp:
        fig.savefig(temp, format="png")


def write_sweep_png(n_values, r, path, *, ci_low=None, ci_high=None, best_n=None,
                    loo_chosen_n=None, title=None, dpi=100):
    """Pearson r against the number of thresholds N, with its confidence band.

    Parameters
    ----------
    n_values, r : array_like, shape (k,)
        N and r(N).
    path : path-like
        PNG to write (atomically).
    ci_low, ci_high : array_like, shape (k,), optional
        Confidence band of r (Fisher z).
    best_n : float, optional
        The chosen N, marked by a vertical line.
    loo_chosen_n : array_like, optional
        N chosen in each leave-one-scene-out fold, drawn as ticks along the bottom.
    """
    n_values = np.asarray(n_values, dtype=np.float64)
    r = np.asarray(r, dtype=np.float64)
    fig = _figure(dpi=dpi)
    ax = fig.add_subplot()
    if ci_low is not None and ci_high is not None:
        ax.fill_between(n_values, ci_low, ci_high, color="tab:blue", alpha=0.15, lw=0,
                        label="confidence band (Fisher z)")
    ax.plot(n_values, r, color="tab:blue", marker="." if n_values.size < 60 else None,
            label="r(N)")
    if best_n is not None:
        ax.axvline(best_n, color="tab:red", lw=1, ls="--", label=f"best N = {best_n:g}")
    if loo_chosen_n is not None and len(loo_chosen_n):
        chosen = np.asarray(loo_chosen_n, dtype=np.float64)
        ax.plot(chosen, np.full(chosen.shape, -1.0), "|", color="tab:green", ms=14,
                label="N chosen per left-out scene")
    ax.set_xlabel("number of thresholds N")
    ax.set_ylabel("Pearson r with mean rating")
    ax.set_ylim(-1.05, 1.05)
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7, loc="upper right", framealpha=0.8)
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    with atomic_path(path) as temp:
        fig.savefig(temp, format="png")
