"""The whole observer-study analysis in one call: :func:`run_study` → :class:`StudyResult`."""

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._provenance import build_provenance, file_record
from ..errors import BadInputError
from .correlation import chaddock_label, correlate, fisher_interval_Fisher1921, pearson_r
from .resampling import (
    JITTER_LEVELS,
    bootstrap_correlation,
    jitter_correlations,
    jitter_summary,
)
from .selection import (
    DIRECTIONS,
    best_index,
    leave_one_out_selection,
    sweep_correlations,
)
from .tables import rated_scenes_only, read_metrics, read_ratings, scene_ratings, sweep_columns

__all__ = ["MIN_SCENES", "StudyResult", "run_study"]

#: Columns of a survey table that are not metrics to correlate with ratings: the ratings
#: themselves and their count, calibration bookkeeping, and standard uncertainties (``*_u``).
_BOOKKEEPING = frozenset({"rating_mean", "rating_n", "mean_rating", "calibration_factor",
                          "calibration_uncertainty", "saturated_fraction", "model_mc_uncertainty"})


def _bookkeeping(column):
    return column in _BOOKKEEPING or column.endswith("_u")

#: Fewest scenes a study can have: a correlation needs 3 (and its Fisher interval and the
#: leave-one-out check need 4; they are reported as undefined for 3).
MIN_SCENES = 3


def _json_ready(value):
    """Floats (NaN → None), lists and dicts that :func:`json.dumps` accepts."""
    if isinstance(value, dict):
        return {str(k): _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, np.ndarray):
        return [_json_ready(v) for v in value.tolist()]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    return value


def _n_label(n):
    """N as an int where it is integral (50, not 50.0)."""
    return int(n) if float(n).is_integer() else float(n)


@dataclass
class StudyResult:
    """Result of :func:`run_study`.

    Attributes (all JSON-ready through :meth:`to_dict`; undefined numbers are NaN here and
    ``None`` there, with the reason in ``notes``):

    ``provenance``
        package and library versions, the arguments, each input file's path and SHA-256.
    ``scenes``
        per scene: name, mean rating, SD, n, standard error, value of the selected metric.
    ``correlations``
        per metric column (the sweep columns excepted): :func:`~.correlation.correlate` of
        the metric against the mean ratings, over the scenes where the metric is given.
    ``between_metrics``
        Pearson r of the selected metric with each other metric column (the paper's
        UGR ↔ Q).
    ``sweep``
        r(N) with Fisher intervals and the best N, or ``None`` without sweep columns.
    ``jitter``
        the paper's robustness check for the selected metric (and the best N's stability).
    ``bootstrap``
        bootstrap standard error, percentile and BCa intervals of r for the selected metric.
    ``leave_one_out``
        the leave-one-scene-out choice of N (see :mod:`~lsadphoto.study.selection`).
    ``notes``
        why values are missing.
    """

    provenance: dict
    metric: str
    scenes: list
    correlations: dict
    between_metrics: dict
    sweep: dict = None
    jitter: dict = None
    bootstrap: dict = None
    leave_one_out: dict = None
    notes: list = field(default_factory=list)
    _plot: dict = field(default_factory=dict, repr=False)

    def to_dict(self):
        """Everything but the plotting arrays, as JSON-ready builtins (NaN → None)."""
        return _json_ready({
            "provenance": self.provenance,
            "metric": self.metric,
            "scenes": self.scenes,
            "correlations": self.correlations,
            "between_metrics": self.between_metrics,
            "sweep": self.sweep,
            "jitter": self.jitter,
            "bootstrap": self.bootstrap,
            "leave_one_out": self.leave_one_out,
            "notes": self.notes,
        })

    def to_json(self, **kwargs):
        """:meth:`to_dict` as a JSON string (``kwargs`` go to :func:`json.dumps`)."""
        kwargs.setdefault("indent", 2)
        kwargs.setdefault("ensure_ascii", False)
        return json.dumps(self.to_dict(), allow_nan=False, **kwargs)

    def figures(self, outdir, *, dpi=100):
        """Write ``scatter_<metric>.png`` (Figure 1) and, with a sweep, ``r_vs_n.png``
        (Figure 2) into ``outdir`` (created if needed), each atomically.

        Returns
        -------
        list of Path
        """
        from .figures import write_scatter_png, write_sweep_png

        outdir = Path(outdir)
        outdir.mkdir(parents=True, exist_ok=True)
        plot = self._plot
        written = []
        stats = self.correlations[self.metric]
        r = stats["pearson_r"]
        # Undefined correlations (a constant metric or constant ratings) are drawn, and said.
        strength = "r undefined" if math.isnan(r) else f"r = {r:.3f} ({stats['chaddock']})"
        path = outdir / f"scatter_{self.metric}.png"
        write_scatter_png(plot["metric"], plot["mean"], path, sem=plot["sem"],
                          labels=plot["scenes"], metric_name=self.metric,
                          title=f"{self.metric}: {strength}, n = {stats['n']}", dpi=dpi)
        written.append(path)
        if self.sweep is not None:
            path = outdir / "r_vs_n.png"
            best = self.sweep["best"]
            loo = None if self.leave_one_out is None else self.leave_one_out["chosen_n"]
            title = ("r(N): no best N (every r undefined)" if best is None else
                     f"r(N): best N = {best['n']}, r = {best['r']:.3f}")
            write_sweep_png(self.sweep["n"], plot["sweep_r"], path, ci_low=plot["sweep_low"],
                            ci_high=plot["sweep_high"], best_n=None if best is None else best["n"],
                            loo_chosen_n=loo, title=title, dpi=dpi)
            written.append(path)
        return written


def _check_count(value, name):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise BadInputError(f"{name} must be a non-negative integer, got {value!r}")
    return int(value)


def _complete(metrics, column):
    """The column's values, after checking that every scene has one."""
    values = metrics.values[column]
    missing = np.flatnonzero(~np.isfinite(values))
    if missing.size:
        i = int(missing[0])
        raise BadInputError(f"{metrics.path}, line {metrics.line[i]}, column {column!r}: "
                            f"missing value (scene {metrics.scenes[i]!r})")
    return values


def run_study(ratings_csv, metrics_csv, *, metric="q", sweep_prefix="q_n", jitter=0.25,
              n_jitter=10000, n_bootstrap=10000, confidence=0.95, seed=0,
              direction="positive", jitter_level="rating", rating_scale=None):
    """Correlate observer ratings with lighting metrics, as in the paper's §4, and check it.

    Reads ``RATINGS.csv`` and ``METRICS.csv`` (formats in ``docs/user-guide-study.md``),
    averages the ratings per scene and computes:

    1. per-scene mean, SD, n and standard error of the ratings;
    2. for every metric column, Pearson r with its Fisher-z interval, Spearman ρ and
       Kendall τ-b with p-values, and the Chaddock label;
    3. r against N over the sweep columns ``<sweep_prefix><N>`` and the best N;
    4. the paper's robustness check: ratings jittered uniformly within ±``jitter``,
       ``n_jitter`` times — distribution of r for ``metric`` and of the best N;
    5. bootstrap (over scenes) percentile and BCa intervals of r for ``metric``;
    6. the leave-one-scene-out choice of N and its out-of-sample correlation.

    Parameters
    ----------
    ratings_csv, metrics_csv : path-like
        The two tables.
    metric : str
        Metric column analysed in detail (jitter, bootstrap, scatter figure); default ``q``.
    sweep_prefix : str or None
        Prefix of the Q(N) sweep columns (``q_n`` → ``q_n1`` … ``q_n100``); ``None`` or ""
        for no sweep.
    jitter : float
        Half-width w of the uniform rating jitter [rating units] (paper: 0.25).
    n_jitter, n_bootstrap : int
        Repetitions of the jitter check and bootstrap resamples (0 skips).
    confidence : float
        Level of every interval.
    seed : int
        Seed of the random streams; results are reproducible for a given seed.
    direction : {"positive", "negative", "either"}
        Which r counts as best when choosing N: the largest ("positive", default: higher
        rating and higher metric both mean better), the most negative, or the largest |r|.
    jitter_level : {"rating", "mean"}
        Jitter each observer's rating (default, as the paper) or each scene's mean rating.
    rating_scale : (float, float), optional
        Lowest and highest allowed rating, checked when reading (e.g. ``(1, 10)``).

    Returns
    -------
    StudyResult

    References
    ----------
    Budak, V. P. et al. (2020), GraphiCon 2020, CEUR Vol-2744 short35, §4.
    Fisher (1921); Chaddock (1925); Efron & Tibshirani (1993); Stone (1974).
    """
    if direction not in DIRECTIONS:
        raise BadInputError(f"unknown direction {direction!r}; valid: "
                            + ", ".join(repr(d) for d in DIRECTIONS))
    if jitter_level not in JITTER_LEVELS:
        raise BadInputError(f"unknown jitter level {jitter_level!r}; valid: "
                            + ", ".join(repr(v) for v in JITTER_LEVELS))
    n_jitter = _check_count(n_jitter, "n_jitter")
    n_bootstrap = _check_count(n_bootstrap, "n_bootstrap")
    _check_count(seed, "seed")
    try:
        jitter = float(jitter)
        confidence = float(confidence)
    except (TypeError, ValueError):
        raise BadInputError("jitter and confidence must be numbers") from None
    if not (math.isfinite(jitter) and jitter >= 0):
        raise BadInputError(f"jitter must be a finite non-negative number, got {jitter!r}")
    if not 0.0 < confidence < 1.0:
        raise BadInputError(f"confidence must be between 0 and 1, got {confidence!r}")

    ratings = read_ratings(ratings_csv, rating_scale=rating_scale)
    metrics, unrated = rated_scenes_only(read_metrics(metrics_csv), ratings)
    summary = scene_ratings(ratings, metrics)
    n_scenes = len(metrics.scenes)
    if n_scenes < MIN_SCENES and unrated:  # the ratings cover too few of the scenes
        raise BadInputError(f"{ratings.path}: rates {n_scenes} of the "
                            f"{n_scenes + len(unrated)} scene(s) of {metrics.path}; a "
                            f"correlation needs at least {MIN_SCENES} rated scenes")
    if n_scenes < MIN_SCENES:
        raise BadInputError(f"{metrics.path}: {n_scenes} scene(s); a correlation needs at "
                            f"least {MIN_SCENES}")
    sweep = sweep_columns(metrics, sweep_prefix) if sweep_prefix else []
    sweep_names = {c for _, c in sweep}
    if metric not in metrics.values:
        raise BadInputError(f"{metrics.path}: no metric column {metric!r}; columns: "
                            + ", ".join(metrics.values))
    x = _complete(metrics, metric)
    notes = []
    if unrated:
        notes.append(f"{len(unrated)} scene(s) of the metrics file have no ratings and are left "
                     f"out: {', '.join(unrated)}")
    if n_scenes < 4:
        notes.append("fewer than 4 scenes: no Fisher interval and no leave-one-out check")
    constant_ratings = bool(np.ptp(summary.mean) == 0)
    if constant_ratings:
        notes.append(f"the mean rating is the same for every scene ({summary.mean[0]:g}): "
                     "every correlation with the ratings is undefined (null)")

    # 1–2. Scenes and correlations of every (non-sweep) metric column.
    scenes = [{"scene": s, "mean": summary.mean[i], "sd": summary.sd[i], "n": summary.n[i],
               "sem": summary.sem[i], metric: x[i]} for i, s in enumerate(metrics.scenes)]
    correlations, between = {}, {}
    for column, values in metrics.values.items():
        if column in sweep_names and column != metric:
            continue
        if column != metric and _bookkeeping(column):
            continue
        given = np.isfinite(values)
        if given.sum() < MIN_SCENES:
            notes.append(f"metric {column!r}: given for {int(given.sum())} scene(s), "
                         "too few to correlate")
            continue
        if np.ptp(values[given]) == 0:
            notes.append(f"metric {column!r} is constant: correlations undefined")
        stats = correlate(values[given], summary.mean[given], confidence=confidence)
        if not given.all():
            notes.append(f"metric {column!r}: missing for {int((~given).sum())} scene(s), "
                         f"correlated over {int(given.sum())}")
        correlations[column] = stats
        if column != metric:
            between[column] = {"pearson_r": float(pearson_r(values[given], x[given])),
                               "n": int(given.sum())}

    # 3. The sweep r(N).
    sweep_result, sweep_x, plot_sweep = None, None, {}
    if sweep:
        sweep_x = np.column_stack([_complete(metrics, c) for _, c in sweep])
        r_sweep = sweep_correlations(sweep_x, summary.mean)
        intervals = [fisher_interval_Fisher1921(r, n_scenes, confidence=confidence)
                     for r in r_sweep]
        best = int(best_index(r_sweep, direction=direction))
        if best < 0:
            notes.append("no best N: r(N) is undefined for every N ("
                         + ("the ratings are constant)" if constant_ratings
                            else "every sweep column is constant)"))
        sweep_result = {
            "prefix": sweep_prefix,
            "direction": direction,
            "n": [_n_label(n) for n, _ in sweep],
            "column": [c for _, c in sweep],
            "r": r_sweep,
            "ci_low": [lo for lo, _ in intervals],
            "ci_high": [hi for _, hi in intervals],
            "best": None if best < 0 else {
                "n": _n_label(sweep[best][0]), "column": sweep[best][1], "r": r_sweep[best],
                "ci": intervals[best], "chaddock": chaddock_label(r_sweep[best])},
        }
        plot_sweep = {"sweep_r": r_sweep, "sweep_low": sweep_result["ci_low"],
                      "sweep_high": sweep_result["ci_high"]}
    elif sweep_prefix:
        notes.append(f"no sweep columns {sweep_prefix}<N> in {metrics.path}")

    # 4. Jitter: the selected metric and the sweep in one pass.
    jitter_result = None
    if n_jitter:
        scene_index = {s: i for i, s in enumerate(metrics.scenes)}
        where = np.array([scene_index[s] for s in ratings.scene], dtype=np.intp)
        columns = x[:, None] if sweep_x is None else np.column_stack([x, sweep_x])
        r_trials = jitter_correlations(ratings.rating, where, n_scenes, columns,
                                       half_width=jitter, n_trials=n_jitter,
                                       level=jitter_level, seed=seed)
        jitter_result = {"half_width": jitter, "level": jitter_level, "n_trials": n_jitter,
                         **jitter_summary(r_trials[:, 0],
                                          correlations[metric]["pearson_r"])}
        if sweep_x is not None:
            chosen = best_index(r_trials[:, 1:], direction=direction)
            values, counts = np.unique(chosen[chosen >= 0], return_counts=True)
            jitter_result["best_n_counts"] = {str(_n_label(sweep[v][0])): int(c)
                                              for v, c in zip(values, counts)}

    # 5. Bootstrap over scenes.
    bootstrap_result = None
    if n_bootstrap:
        boot = bootstrap_correlation(x, summary.mean, n_resamples=n_bootstrap,
                                     confidence=confidence, seed=seed)
        bootstrap_result = {k: v for k, v in boot.items() if k != "distribution"}
        bootstrap_result["confidence"] = confidence
        if boot["n_degenerate"]:
            notes.append(f"bootstrap: {boot['n_degenerate']} resample(s) with a constant "
                         "metric or rating dropped")

    # 6. Leave-one-scene-out choice of N.
    loo_result = None
    if sweep_x is not None and n_scenes >= 4:
        loo = leave_one_out_selection(sweep_x, summary.mean, direction=direction)
        chosen_n = [_n_label(sweep[c][0]) if c >= 0 else None for c in loo["chosen_index"]]
        values, counts = np.unique([c for c in loo["chosen_index"] if c >= 0],
                                   return_counts=True)
        loo_result = {
            "folds": [{"scene": s, "chosen_n": chosen_n[i], "train_r": loo["train_r"][i],
                       "prediction": loo["prediction"][i], "rating": summary.mean[i]}
                      for i, s in enumerate(metrics.scenes)],
            "chosen_n": chosen_n,
            "chosen_n_counts": {str(_n_label(sweep[v][0])): int(c)
                                for v, c in zip(values, counts)},
            "r_in_sample": loo["r_in_sample"],
            "r_loo": loo["r_loo"],
            "r_loo_ci": fisher_interval_Fisher1921(loo["r_loo"], n_scenes,
                                                   confidence=confidence),
            "r_loo_fixed": loo["r_loo_fixed"],
            "q2": loo["q2"],
            "rmse": loo["rmse"],
        }

    provenance = build_provenance()
    provenance.update({
        "ratings_csv": {**file_record(ratings_csv),
                        "n_ratings": int(ratings.rating.size),
                        "n_missing": ratings.n_missing,
                        "n_observers": len(set(ratings.observer)),
                        "rating_min": float(ratings.rating.min()),
                        "rating_max": float(ratings.rating.max())},
        "metrics_csv": {**file_record(metrics_csv), "n_scenes": n_scenes},
        "arguments": {"metric": metric, "sweep_prefix": sweep_prefix, "jitter": jitter,
                      "n_jitter": n_jitter, "n_bootstrap": n_bootstrap,
                      "confidence": confidence, "seed": seed, "direction": direction,
                      "jitter_level": jitter_level,
                      "rating_scale": None if rating_scale is None else list(rating_scale)},
    })
    plot = {"metric": x, "mean": summary.mean, "sem": summary.sem,
            "scenes": list(metrics.scenes), **plot_sweep}
    return StudyResult(provenance, metric, scenes, correlations, between, sweep_result,
                       jitter_result, bootstrap_result, loo_result, notes, plot)
