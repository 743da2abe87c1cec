"""Batch processing of a whole survey: many views → maps, scores and one metrics table.

* :mod:`~lsadphoto.survey.manifest` — the manifest (schema ``lsadphoto.survey/1``), declared
  once and checked completely before anything runs;
* :mod:`~lsadphoto.survey.pipeline` — one view: its output layout (:class:`ViewLayout`) and
  the photo pipeline that fills it;
* :mod:`~lsadphoto.survey.executors` — where views run: this process, spawned workers, Dask;
* :mod:`~lsadphoto.survey.tables` — ``metrics.csv`` / ``.parquet``, ``ratings.csv``,
  ``failures.log``;
* :mod:`~lsadphoto.survey.lock` — one run at a time per output folder;
* :func:`run_survey` — all of it, returning a :class:`SurveyResult`.

:func:`run_survey` processes every view — luminance map (OpenEXR, Radiance HDR, false
colour), scores (:func:`~lsadphoto.metrics.score.score_map` with the Q(N) sweep N = 1…100),
glare-source and contrast maps, a per-view JSON record — in parallel. Every view's files are
written as one atomic group and its "done" marker last, so a killed run loses no finished
view and a rerun skips what is done. A view that fails is reported with a one-line reason
and the others go on. The user guide is ``docs/user-guide-survey.md``.
"""

from .lock import LOCK_NAME, StaleLockWarning, SurveyLockedError, survey_lock
from .manifest import (
    MANIFEST_SCHEMA,
    SCHEMA,
    SCORE_SCHEMA,
    Manifest,
    SurveyView,
    check_score_options,
    load_manifest,
)
from .pipeline import SWEEP, ViewLayout
from .run import SurveyResult, run_survey

__all__ = ["SCHEMA", "MANIFEST_SCHEMA", "SCORE_SCHEMA", "SWEEP", "Manifest", "SurveyView",
           "SurveyResult", "ViewLayout", "load_manifest", "check_score_options", "run_survey",
           "survey_lock", "SurveyLockedError", "StaleLockWarning", "LOCK_NAME"]
