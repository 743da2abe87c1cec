"""Atomic output: write to a temporary file beside the target, then rename."""

import contextlib
import os
import tempfile
from pathlib import Path


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_outputs(*paths):
    """Yield temporary paths for ``paths``; rename them all into place only on success.

    Either every output appears complete or none is touched: a failure while writing any of
    them removes every temporary file and leaves existing targets as they were.
    """
    targets = [Path(p) for p in paths]
    temps = []
    try:
        for target in targets:
            if not target.parent.exists():
                target.parent.mkdir(parents=True, exist_ok=True)
            fd, name = tempfile.mkstemp(
                prefix=f".{target.stem}.", suffix=f".tmp{target.suffix}", dir=target.parent
            )
            os.close(fd)
            os.chmod(name, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual mode
            temps.append(Path(name))
        yield temps
        for temp, target in zip(temps, targets):
            os.replace(temp, target)
    finally:
        for temp in temps:
            with contextlib.suppress(FileNotFoundError):
                temp.unlink()


@contextlib.contextmanager
def atomic_path(path):
    """Yield one temporary path that is renamed to ``path`` on success."""
    with atomic_outputs(path) as (temp,):
        yield temp


def atomic_text(path, text):
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_path(path) as temp:
        temp.write_text(text, encoding="utf-8")
