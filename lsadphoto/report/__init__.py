"""Figures and reports of scored maps and studies.

* :mod:`~lsadphoto.report.figures` — per-view PNGs (glare sources, contrast, ratio);
* :mod:`~lsadphoto.report.plots` — the paper's Figures 1, 2 and 4 for a user's data;
* :mod:`~lsadphoto.report.html` — self-contained HTML reports of a survey and of a
  model-vs-photo comparison (``docs/user-guide-report.md``).

Public names are imported on first use (:mod:`lsadphoto._lazy`): matplotlib loads only
where a figure is drawn.
"""

from .._lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, globals(), {
    ".figures": ["write_glare_source_png", "write_contrast_png", "write_ratio_png"],
    ".html": ["write_survey_report", "write_comparison_report", "check_survey_folder"],
    ".plots": ["figure_ratings_vs_metric", "figure_r_vs_n", "figure_q_vs_ugr"],
})
