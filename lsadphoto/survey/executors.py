"""Where the views are processed: this process, a local pool of spawned workers, or Dask.

Every executor takes the tasks of :func:`~lsadphoto.survey.pipeline.make_task` and calls
``report(outcome)`` once per task with the outcome of
:func:`~lsadphoto.survey.pipeline.process_view`; a problem of one view never stops the
others. Local workers are started with the ``spawn`` context (fork + OpenMP deadlocks), each
with single-threaded numeric libraries (:data:`WORKER_ENVIRONMENT`), so that the local pool
and a Dask cluster give bit-identical tables.

References
----------
Python ``concurrent.futures.ProcessPoolExecutor`` and ``multiprocessing`` start methods;
Dask.distributed ``Client``; rawpy issue #265 (fork + OpenMP deadlock).
"""

import contextlib
import multiprocessing
import os
import re
import uuid
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool

from ..errors import BadInputError
from .pipeline import process_view

__all__ = ["WORKER_ENVIRONMENT", "check_dask_address", "connect_dask", "cpu_count", "run_serial", "run_local",
           "run_dask", "failure"]

#: Thread counts of the numeric libraries in each worker process: one, as Dask's nanny sets
#: them (``distributed.nanny.pre-spawn-environ``). N processes × N threads would oversubscribe
#: the CPUs, and BLAS sums depend on the thread count in their last bits: with the same
#: setting, the local pool and a Dask cluster give bit-identical tables.
WORKER_ENVIRONMENT = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}

#: A Dask scheduler address: ``tcp://host:port``, ``tls://…``, ``ws(s)://…``, ``ucx://…``,
#: or ``host:port`` (tcp), with a port.
_DASK_ADDRESS = re.compile(r"((tcp|tls|ws|wss|ucx)://)?[A-Za-z0-9.-]+:\d{1,5}"
                           r"|(tcp|tls)://\[[0-9a-fA-F:]+\]:\d{1,5}")


def check_dask_address(address):
    """Check a Dask scheduler address before connecting (``tcp://HOST:PORT``).

    distributed waits its whole connect timeout on an address it cannot use, and a client
    that failed to start prints a traceback when it is collected: the form is checked first.

    Examples
    --------
    >>> check_dask_address("tcp://10.0.0.5:8786")
    'tcp://10.0.0.5:8786'
    >>> check_dask_address("banana")
    Traceback (most recent call last):
    ...
    lsadphoto.errors.BadInputError: Dask scheduler address 'banana' must look like tcp://HOST:PORT (or tls://HOST:PORT)
    """
    if not (isinstance(address, str) and _DASK_ADDRESS.fullmatch(address)):
        raise BadInputError(f"Dask scheduler address {address!r} must look like "
                            "tcp://HOST:PORT (or tls://HOST:PORT)")
    return address


def failure(task, reason):
    """The outcome of a view that failed outside :func:`process_view` (its worker died)."""
    return {"view": task["view"], "ok": False, "row": None, "reason": reason, "seconds": None}


def cpu_count():
    """CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


def run_serial(tasks, report):
    """Every task in this process, one after the other (a native crash ends the run)."""
    for task in tasks:
        report(process_view(task))


@contextlib.contextmanager
def _worker_environment():
    """Set :data:`WORKER_ENVIRONMENT` (where the user has not) while workers are spawned."""
    added = {k: v for k, v in WORKER_ENVIRONMENT.items() if k not in os.environ}
    os.environ.update(added)
    try:
        yield
    finally:
        for key in added:
            os.environ.pop(key, None)


def run_local(tasks, workers, report, *, function=process_view):
    """Worker processes started with ``spawn``; a view whose worker dies is retried alone."""
    context = multiprocessing.get_context("spawn")
    lost = []
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context)
    try:
        # ProcessPoolExecutor starts its spawn workers in submit(): all of them here.
        with _worker_environment():
            futures = {pool.submit(function, task): task for task in tasks}
        for future in as_completed(futures):
            task = futures[future]
            try:
                report(future.result())
            except BrokenProcessPool:
                lost.append(task)  # this view, or another one running beside it, crashed
            except Exception as exc:  # noqa: BLE001 — e.g. a result that could not be pickled
                report(failure(task, f"internal error: {type(exc).__name__}: {exc}"))
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    # A crashing worker (native code, out of memory) breaks the whole pool: retry each lost
    # view in a pool of its own, so that only the culprit is reported.
    for task in lost:
        with ProcessPoolExecutor(max_workers=1, mp_context=context) as single:
            try:
                with _worker_environment():
                    future = single.submit(function, task)
                outcome = future.result()
            except BrokenProcessPool:
                outcome = failure(task, "internal error: the worker process died while processing "
                                        "this view (a crash in native code, or out of memory)")
        report(outcome)


def connect_dask(address):
    """A new ``distributed.Client`` for ``address``; a one-line error if none can be made."""
    from distributed import Client

    check_dask_address(address)
    try:
        return Client(address, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise BadInputError(f"cannot connect to the Dask scheduler at {address}: "
                            f"{' '.join(str(exc).split())}") from None


def run_dask(tasks, report, *, client):
    """The tasks on the Dask cluster of ``client`` (a ``distributed.Client``, left open)."""
    from distributed import as_completed as dask_as_completed

    token = uuid.uuid4().hex[:8]
    waiting = {}
    try:
        for task in tasks:
            future = client.submit(process_view, task, key=f"lsadphoto-survey-{task['view']}-{token}",
                                   pure=False)
            waiting[future.key] = (future, task)
        for future in dask_as_completed([f for f, _ in waiting.values()], loop=client.loop):
            task = waiting.pop(future.key)[1]
            try:
                outcome = future.result()
            except Exception as exc:  # noqa: BLE001 — e.g. KilledWorker after repeated crashes
                outcome = failure(task, f"internal error: {type(exc).__name__}: "
                                        f"{' '.join(str(exc).split())}")
            future.release()
            report(outcome)
    finally:
        if waiting:  # interrupted: withdraw what has not run yet
            client.cancel([f for f, _ in waiting.values()])
