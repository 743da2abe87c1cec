"""Figures and reports of scored maps and studies.

* :mod:`~lsadphoto.report.figures` — per-view PNGs (glare sources, contrast, ratio);
* :mod:`~lsadphoto.report.plots` — the paper's Figures 1, 2 and 4 for a user's data;
* :mod:`~lsadphoto.report.html` — self-contained HTML reports of a survey and of a
  model-vs-photo comparison (``docs/user-guide-report.md``).
"""

from .figures import write_contrast_png, write_glare_source_png, write_ratio_png
from .html import check_survey_folder, write_comparison_report, write_survey_report
from .plots import figure_q_vs_ugr, figure_r_vs_n, figure_ratings_vs_metric

__all__ = ["write_glare_source_png", "write_contrast_png", "write_ratio_png",
           "write_survey_report", "write_comparison_report", "check_survey_folder", "figure_ratings_vs_metric",
           "figure_r_vs_n", "figure_q_vs_ugr"]
