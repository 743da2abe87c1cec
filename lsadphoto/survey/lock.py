"""One run at a time per survey output folder.

Two runs writing into one folder would each process every view, remove each other's
temporary files and overwrite each other's tables (issue 17, defect 2). :func:`survey_lock`
holds an exclusive lock on ``OUTDIR/.lsadphoto-survey.lock`` for the whole run; the file
records who holds it (process id, host, start time, manifest). A second run refuses at once
with one line naming them (:class:`SurveyLockedError`, exit code 2).

The lock is an advisory ``flock`` on the open file, which the operating system releases when
its process ends, however it ends: a lock file left by a killed run (its process gone) is
not held, so the next run takes it over and says whose it was. A file that another host
holds is refused the same way (``flock`` works across hosts on NFS v4 and on most cluster
file systems; on file systems where it does not, give each run its own folder).

References
----------
POSIX ``flock(2)`` (Linux man-pages); Python :mod:`fcntl`.
"""

import contextlib
import json
import os
import socket
import warnings

from .._provenance import timestamp
from ..errors import BadInputError, LsadWarning

__all__ = ["LOCK_NAME", "SurveyLockedError", "StaleLockWarning", "survey_lock"]

LOCK_NAME = ".lsadphoto-survey.lock"


class SurveyLockedError(BadInputError):
    """Another run is writing into the same survey output folder."""


class StaleLockWarning(LsadWarning):
    """The lock of an earlier run that ended without releasing it (killed) was taken over."""


def _describe(holder):
    if not isinstance(holder, dict):
        return "another run (no details recorded)"
    return (f"process {holder.get('pid', '?')} on {holder.get('host', '?')}, started "
            f"{holder.get('started', '?')}")


def _read_holder(fd):
    os.lseek(fd, 0, os.SEEK_SET)
    data = b""
    while chunk := os.read(fd, 65536):
        data += chunk
    try:
        return json.loads(data.decode("utf-8")) if data.strip() else None
    except (UnicodeDecodeError, ValueError):
        return None


@contextlib.contextmanager
def survey_lock(outdir, *, manifest=None):
    """Hold the lock of the survey output folder ``outdir`` (which must exist) while inside.

    Parameters
    ----------
    outdir : Path
        The survey output folder.
    manifest : path-like, optional
        Recorded in the lock file, for the message another run gives.

    Raises
    ------
    SurveyLockedError
        Another live run holds the lock: ``output folder … is in use by process PID on HOST,
        started TIME (…)``.

    Warns
    -----
    StaleLockWarning
        The lock file of a run that ended without releasing it was taken over.
    """
    import fcntl

    path = outdir / LOCK_NAME
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_holder(fd)
            os.close(fd)
            raise SurveyLockedError(
                f"output folder {outdir} is in use by {_describe(holder)} (manifest "
                f"{(holder or {}).get('manifest', '?')}); wait for it to finish or use another "
                "folder") from None
        # A run that finished removed the file after we opened it: lock the new one instead.
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(path))
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        earlier = _read_holder(fd)
        if earlier is not None:
            warnings.warn(f"{outdir}: took over the lock of {_describe(earlier)}, which ended "
                          "without releasing it (killed?)", StaleLockWarning, stacklevel=3)
        holder = {"pid": os.getpid(), "host": socket.gethostname(),
                  "started": timestamp(),
                  "manifest": None if manifest is None else str(manifest)}
        os.ftruncate(fd, 0)
        os.lseek(fd, 0, os.SEEK_SET)
        os.write(fd, json.dumps(holder).encode("utf-8"))
        os.fsync(fd)
        yield holder
    finally:
        # Removed while still held, so that no other run can lock this file in between.
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)
        os.close(fd)
