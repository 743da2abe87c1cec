"""The whole survey in one call: :func:`run_survey` → :class:`SurveyResult`."""

import sys
import time
from dataclasses import dataclass
from pathlib import Path

from ..errors import BadInputError
from .executors import check_dask_address, connect_dask, cpu_count, run_dask, run_local, run_serial
from .lock import survey_lock
from .manifest import Manifest, check_score_options, load_manifest
from .pipeline import make_task, read_done
from .tables import read_failures, write_tables

__all__ = ["SurveyResult", "run_survey"]


@dataclass
class SurveyResult:
    """What :func:`run_survey` did.

    Attributes
    ----------
    table : list of dict
        One row per finished view, in manifest order (the rows of ``metrics.csv``).
    failures : list of (str, str)
        ``(view id, one-line reason)`` of the views that failed in this run.
    processed : list of str
        Views processed in this run (finished or failed).
    skipped : list of str
        Views already done by an earlier run with the same inputs.
    outdir : Path
    elapsed : float
        Wall-clock time of the run [s].
    """

    table: list
    failures: list
    processed: list
    skipped: list
    outdir: Path
    elapsed: float = 0.0

    def to_dict(self):
        """JSON-ready summary (the table itself is in ``metrics.csv``)."""
        return {
            "outdir": str(self.outdir),
            "views_finished": len(self.table),
            "views_failed": len(self.failures),
            "processed": list(self.processed),
            "skipped": list(self.skipped),
            "failures": [{"view": v, "reason": r} for v, r in self.failures],
            "elapsed_s": self.elapsed,
            "table": self.table,
        }


def _progress_bar(*, total, initial, enabled):
    """tqdm bar on stderr with the estimated time left; silent unless stderr is a terminal."""
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="view", desc="survey", file=sys.stderr,
                disable=not (enabled and sys.stderr.isatty()), dynamic_ncols=True)


def _check_options(workers, dask_address, client):
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 0):
        raise BadInputError(f"workers must be a non-negative integer, got {workers!r}")
    if dask_address is not None and client is not None:
        raise BadInputError("give either a Dask scheduler address or a client, not both")
    if workers is not None and (dask_address is not None or client is not None):
        raise BadInputError("workers sets the local process pool; a Dask cluster has its own workers")
    if dask_address is not None:
        check_dask_address(dask_address)


def _output_folder(outdir):
    outdir = Path(outdir)
    if outdir.exists() and not outdir.is_dir():
        raise BadInputError(f"output folder {outdir} is a file")
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BadInputError(f"output folder {outdir} cannot be made ({exc.strerror})") from None
    if not _writable(outdir):
        raise BadInputError(f"output folder {outdir} is not writable")
    return outdir


def _writable(folder):
    import tempfile

    try:
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


def run_survey(manifest_or_path, outdir, *, workers=None, dask_address=None, client=None,
               progress=True, score_options=None):
    """Process every view of a survey; resumable, in parallel, failures isolated.

    Everything is checked before any view is processed: the manifest completely (see
    :func:`~lsadphoto.survey.manifest.load_manifest`), ``score_options``, the other options,
    and that the output folder can be written and is not in use by another run (a lock held
    for the whole run; see :mod:`~lsadphoto.survey.lock`).

    Parameters
    ----------
    manifest_or_path : Manifest or path-like
        The survey (see :func:`~lsadphoto.survey.manifest.load_manifest`).
    outdir : path-like
        Output folder: ``views/<id>/`` per view, ``metrics.csv``, ``metrics.parquet``,
        ``failures.log`` and, where views carry ratings, ``ratings.csv``.
    workers : int, optional
        Worker processes on this machine (``spawn`` start method); default: one per CPU,
        at most one per view to process. 0 processes the views in this process, one after
        the other (for debugging; a crash in native code then ends the run).
    dask_address : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``): the views are processed
        by its workers, which need lsadphoto and the files at the same paths.
    client : distributed.Client, optional
        An existing Dask client to use instead (left open).
    progress : bool
        Show a progress bar with the estimated time left on stderr (only on a terminal).
    score_options : dict, optional
        Options of :func:`~lsadphoto.metrics.score.score_map` replacing the manifest's
        survey-wide ``[score]`` ones (a view's own settings still win); checked against
        :data:`~lsadphoto.survey.manifest.SCORE_SCHEMA`.

    Returns
    -------
    SurveyResult

    Raises
    ------
    BadInputError
        A bad manifest or option, an output folder that cannot be written;
        :class:`~lsadphoto.survey.lock.SurveyLockedError` when another run holds the folder.
    """
    start = time.perf_counter()
    manifest = manifest_or_path if isinstance(manifest_or_path, Manifest) else load_manifest(manifest_or_path)
    options = check_score_options(score_options or {}, source="score_options")
    _check_options(workers, dask_address, client)
    # Connected before anything is written: an unreachable scheduler leaves no empty folder.
    own_client = None if dask_address is None else connect_dask(dask_address)
    try:
        return _run(manifest, outdir, options, workers=workers, client=client or own_client,
                    progress=progress, start=start)
    finally:
        if own_client is not None:
            own_client.close()


def _run(manifest, outdir, options, *, workers, client, progress, start):
    outdir = _output_folder(outdir)
    with survey_lock(outdir, manifest=manifest.path):
        tasks = [make_task(manifest, view, outdir, options) for view in manifest.views]
        earlier_failures = read_failures(outdir)
        skipped = [t["view"] for t in tasks if read_done(t) is not None]
        pending = [t for t in tasks if t["view"] not in set(skipped)]
        outcomes = {}
        bar = _progress_bar(total=len(tasks), initial=len(skipped), enabled=progress)

        def report(outcome):
            outcomes[outcome["view"]] = outcome
            if not outcome["ok"] and not bar.disable:
                bar.write(f"{outcome['view']}: failed: {outcome['reason']}", file=sys.stderr)
            bar.update(1)
            bar.set_postfix(failed=sum(not o["ok"] for o in outcomes.values()), refresh=False)

        try:
            if pending:
                if client is not None:
                    run_dask(pending, report, client=client)
                elif workers == 0:
                    run_serial(pending, report)
                else:
                    run_local(pending, min(workers or cpu_count(), len(pending)), report)
        finally:
            bar.close()
            failures = [(t["view"], outcomes[t["view"]]["reason"]) for t in tasks
                        if t["view"] in outcomes and not outcomes[t["view"]]["ok"]]
            table = write_tables(manifest, tasks, failures, outdir,
                                 earlier_failures=earlier_failures)
    return SurveyResult(table=table, failures=failures,
                        processed=[t["view"] for t in tasks if t["view"] in outcomes],
                        skipped=skipped, outdir=outdir, elapsed=time.perf_counter() - start)
