"""Figures for the HTML reports: the paper's Figures 1, 2 and 4 drawn from a user's data.

Figures 1 and 2 are the study's own (:mod:`lsadphoto.study.figures`), re-exported here.
Each ``figure_*`` function returns a :class:`matplotlib.figure.Figure` (Agg backend, no
screen needed, nothing global touched); :func:`png_bytes` turns it into PNG bytes for
embedding and :func:`write_png` writes it atomically.

* :func:`figure_ratings_vs_metric` — mean observer rating against Q, one point per scene with
  its standard error, the least-squares line and Pearson r (the paper's Figure 1).
* :func:`figure_r_vs_n` — Pearson r against the number of thresholds N with its confidence
  band and the best N marked (the paper's Figure 2).
* :func:`figure_q_vs_ugr` — Q against pixel-wise UGR, one point per view with its standard
  uncertainties, and Pearson r (the paper's Figure 4).

The glare-source maps (the paper's Figure 3) are per view:
:func:`lsadphoto.report.figures.write_glare_source_png`.

References
----------
Budak, V. P. et al. (2020), Luminance spatial-angular distribution as a basis for lighting
quality assessment, GraphiCon 2020, CEUR Vol-2744 short35, Figures 1–4.
"""

import io

from .._atomic import atomic_path
from ..study.figures import (  # the study's own Figures 1 and 2, and their drawing helpers
    _annotate,
    _errors,
    _figure,
    _fit_line,
    _r_text,
    _vector,
    figure_r_vs_n,
    figure_ratings_vs_metric,
)

__all__ = ["figure_ratings_vs_metric", "figure_r_vs_n", "figure_q_vs_ugr", "png_bytes",
           "write_png"]


def figure_q_vs_ugr(ugr, q, *, ugr_uncertainty=None, q_uncertainty=None, labels=None,
                    ugr_name="pixel-wise UGR", title=None, dpi=100):
    """Q against UGR, one point per view with its standard uncertainties, and r (Fig. 4).

    Parameters
    ----------
    ugr, q : array_like, shape (n,)
        UGR [–] and Q [–] per view (NaN pairs are left out).
    ugr_uncertainty, q_uncertainty : array_like, shape (n,), optional
        Standard uncertainties, drawn as horizontal and vertical error bars.
    labels : sequence of str, optional
        View names written beside the points (only up to 40 views).

    Returns
    -------
    matplotlib.figure.Figure

    References
    ----------
    Budak et al. (2020), Figure 4; CIE 117-1995 (UGR).
    """
    x = _vector(ugr)
    y = _vector(q)
    fig = _figure(dpi=dpi)
    ax = fig.add_subplot()
    ax.errorbar(x, y, xerr=_errors(ugr_uncertainty, x.size),
                yerr=_errors(q_uncertainty, y.size), fmt="s", ms=5, capsize=3,
                color="tab:purple", ecolor="0.55", label="view (± standard uncertainty)")
    _fit_line(ax, x, y)
    _annotate(ax, x, y, labels)
    ax.set_xlabel(ugr_name)
    ax.set_ylabel("Q")
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7, loc="best", framealpha=0.8)
    text = _r_text(x, y)
    ax.set_title(title or "Fig. 4 — Q against " + ugr_name + (f" ({text})" if text else ""),
                 fontsize=10)
    fig.tight_layout()
    return fig


def png_bytes(figure):
    """The figure as PNG bytes (at the figure's own dpi)."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png")
    return buffer.getvalue()


def write_png(figure, path):
    """Write the figure as a PNG, atomically; returns the path."""
    with atomic_path(path) as temp:
        figure.savefig(temp, format="png")
    return path
