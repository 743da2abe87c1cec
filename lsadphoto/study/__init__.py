"""Observer studies: correlating lighting metrics with people's ratings.

The paper's §4 (Budak et al. 2020) rated 21 Moscow Metro stations on a 10-point scale,
correlated the mean ratings with the quality criterion Q(N) (Pearson r = 0.61 at the chosen
N = 50), checked the robustness by jittering the ratings by ±0.25 over 10 000 trials, and
compared with pixel-wise UGR. This subpackage repeats that analysis from two CSV tables and
adds what the paper did not report: rank correlations, confidence intervals (Fisher z and the
bootstrap) and a leave-one-scene-out choice of N, so that the reported r is not tuned on the
scenes it is reported for.

* :mod:`~lsadphoto.study.tables` — reading and checking ``RATINGS.csv`` / ``METRICS.csv``;
* :mod:`~lsadphoto.study.correlation` — Pearson/Spearman/Kendall, Fisher interval, Chaddock;
* :mod:`~lsadphoto.study.resampling` — rating jitter and bootstrap (seeded, vectorised);
* :mod:`~lsadphoto.study.selection` — r(N) sweep and leave-one-scene-out choice of N;
* :mod:`~lsadphoto.study.figures` — the paper's Figures 1 and 2;
* :func:`run_study` — all of it, returning a :class:`StudyResult`.

The user guide is ``docs/user-guide-study.md``.

Public names are imported on first use (:mod:`lsadphoto._lazy`).
"""

from .._lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, globals(), {
    ".correlation": ["CHADDOCK_SCALE", "chaddock_label", "correlate",
                     "fisher_interval_Fisher1921", "kendall_tau_b", "pearson_r"],
    ".resampling": ["bootstrap_correlation", "jitter_correlations", "jitter_summary"],
    ".run": ["MIN_SCENES", "StudyResult", "run_study"],
    ".selection": ["DIRECTIONS", "best_index", "leave_one_out_selection", "sweep_correlations"],
    ".tables": ["read_metrics", "read_ratings", "scene_ratings", "sweep_columns"],
})
