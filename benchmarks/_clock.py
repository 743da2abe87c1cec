"""Wall and CPU time of a block, children included (the peers run as subprocesses).

``with Clock() as c: ...`` then ``c.wall`` and ``c.cpu`` [s]: user + system time of this
process and of the child processes that ended inside the block.
"""

import resource
import time


def cpu_seconds():
    """User + system CPU time [s] of this process and its ended children."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


class Clock:
    def __enter__(self):
        self.t, self.c = time.perf_counter(), cpu_seconds()
        return self

    def __exit__(self, *exc):
        self.wall, self.cpu = time.perf_counter() - self.t, cpu_seconds() - self.c
