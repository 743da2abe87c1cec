"""The survey's tables: ``metrics.csv`` / ``metrics.parquet``, ``ratings.csv``, ``failures.log``.

They are rebuilt at the end of every run from the done markers of all the manifest's views
(so a table never lists a view whose outputs are incomplete), and written as one group of
the atomic writer. ``failures.log`` lists every view of the manifest that is not done, with
the reason of its latest failure: this run's, or, for a view this run did not get to (an
interrupted run), the reason an earlier run wrote — it is never emptied by a run that did
not retry those views.
"""

import csv
import io
import json
from pathlib import Path

from .._provenance import timestamp
from .._version import __version__
from .manifest import SCHEMA
from .pipeline import json_default, read_done

__all__ = ["METRICS_CSV", "METRICS_PARQUET", "RATINGS_CSV", "FAILURES_LOG", "write_tables",
           "read_failures"]

METRICS_CSV = "metrics.csv"
METRICS_PARQUET = "metrics.parquet"
RATINGS_CSV = "ratings.csv"
FAILURES_LOG = "failures.log"


def _csv_text(columns, rows):
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow(["" if row.get(c) is None else row.get(c) for c in columns])
    return buffer.getvalue()


def _write_parquet(path, columns, rows, metadata):
    import pyarrow as pa
    import pyarrow.parquet as pq

    arrays = {c: pa.array([row.get(c) for row in rows]) for c in columns}
    if not rows:
        arrays = {c: pa.array([], pa.string()) for c in columns}
    table = pa.table(arrays).replace_schema_metadata(
        {"lsadphoto.survey": json.dumps(metadata, default=json_default)})
    pq.write_table(table, path)


def read_failures(outdir):
    """``{view: reason}`` from an earlier run's ``failures.log`` (empty if there is none)."""
    try:
        lines = (Path(outdir) / FAILURES_LOG).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return {}
    failures = {}
    for line in lines:
        view, sep, reason = line.partition(": ")
        if sep:
            failures.setdefault(view, reason)
    return failures


def write_tables(manifest, tasks, failures, outdir, *, earlier_failures=None):
    """Write the tables of ``outdir`` from every current done marker; return the rows.

    Parameters
    ----------
    manifest : Manifest
    tasks : list of dict
        Every view's task (:func:`~lsadphoto.survey.pipeline.make_task`), in manifest order.
    failures : list of (str, str)
        Views that failed in this run, with their reasons.
    outdir : Path
    earlier_failures : dict, optional
        ``{view: reason}`` of the log before this run; kept for views not done and not
        retried now.
    """
    from .._atomic import atomic_outputs

    outdir = Path(outdir)
    rows = [row for row in (read_done(task) for task in tasks) if row is not None]
    columns = list(dict.fromkeys(["view", *(c for row in rows for c in row)]))
    # Every row gets every column (None where a view has no value, e.g. no model).
    rows = [{c: row.get(c) for c in columns} for row in rows]
    metadata = {"schema": SCHEMA, "manifest": str(manifest.path), "name": manifest.name,
                "lsadphoto_version": __version__,
                "written": timestamp()}
    finished = {row["view"] for row in rows}
    now = dict(failures)
    earlier = earlier_failures or {}
    log = [(t["view"], now.get(t["view"], earlier.get(t["view"]))) for t in tasks
           if t["view"] not in finished]
    log = [(view, reason) for view, reason in log if reason is not None]
    ratings = [{"scene": task["view"], "observer": observer, "rating": rating}
               for task in tasks if task["view"] in finished and task["ratings"]
               for observer, rating in task["ratings"]]
    names = [METRICS_CSV, METRICS_PARQUET, FAILURES_LOG] + ([RATINGS_CSV] if ratings else [])
    with atomic_outputs(*(outdir / n for n in names)) as temps:
        temp = dict(zip(names, temps))
        temp[METRICS_CSV].write_text(_csv_text(columns, rows), encoding="utf-8")
        _write_parquet(temp[METRICS_PARQUET], columns, rows, metadata)
        temp[FAILURES_LOG].write_text("".join(f"{v}: {r}\n" for v, r in log), encoding="utf-8")
        if ratings:
            temp[RATINGS_CSV].write_text(_csv_text(["scene", "observer", "rating"], ratings),
                                         encoding="utf-8")
    if not ratings:  # an earlier run's file would no longer match the table
        (outdir / RATINGS_CSV).unlink(missing_ok=True)
    return rows
