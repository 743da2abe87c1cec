"""The one grouped atomic writer: a command's outputs are planned and checked before any
work, then written all together or not at all.

Every command (and the survey's per-view pipeline) writes its outputs the same way::

    plan = plan_outputs({"exr": args.output, "hdr": args.hdr, "png": None},
                        folders={"figures": args.figures})  # None entries are left out
    ...                                 # the work: nothing has been written yet
    with plan.write() as temps:         # temps["exr"] is a temporary file beside the target,
        write_exr(lmap, temps["exr"])   # temps["figures"] a temporary folder beside it
        write_hdr(lmap, temps["hdr"])

:func:`plan_outputs` refuses, with a one-line :class:`~lsadphoto.errors.BadInputError` that
names the path, before anything is computed: two outputs that resolve to the same file, a
target that is an existing folder, a parent that is a file, and a folder that cannot be
written (read-only, no permission, a read-only file system; tested by creating and removing a
probe file, which also holds for root). :meth:`OutputPlan.write` renames the temporaries into
place only when the whole block succeeded; existing targets are kept aside until every rename
has worked, so that a failure at any point leaves every target as it was and no temporary
behind. An ``OSError`` while writing (disk full, a folder that appeared at a target in the
meantime) becomes one-line :class:`~lsadphoto.errors.OutputError`. A folder output (e.g.
``study --figures DIR``) is staged as a temporary folder whose files are moved into the target
folder (created if needed) on success; files already there and not rewritten are kept.

:func:`atomic_outputs`, :func:`atomic_path` and :func:`atomic_text` are the same mechanism for
library functions that write one or a few files themselves.
"""

import contextlib
import os
import shutil
import tempfile
from pathlib import Path

from .errors import BadInputError, OutputError

__all__ = ["OutputPlan", "plan_outputs", "atomic_outputs", "atomic_path", "atomic_text"]


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _existing_ancestor(path):
    """The nearest existing ancestor folder of ``path``; BadInputError if it is not a folder."""
    parent = path.parent
    while not parent.exists():
        if parent == parent.parent:
            break
        parent = parent.parent
    if not parent.is_dir():
        raise BadInputError(f"output {path}: {parent} is a file, not a folder")
    return parent


def _check_writable(folder, path):
    try:
        fd, probe = tempfile.mkstemp(prefix=".lsadphoto-probe.", dir=folder)
    except OSError as exc:
        raise BadInputError(f"output {path}: folder {folder} is not writable ({exc.strerror})") from None
    os.close(fd)
    os.unlink(probe)


class OutputPlan:
    """The checked outputs of one command; see the module docstring.

    Attributes
    ----------
    files : dict of str → Path
        Output files by role.
    folders : dict of str → Path
        Output folders by role.
    """

    def __init__(self, files, folders):
        self.files = files
        self.folders = folders

    @property
    def paths(self):
        """All planned outputs by role (files and folders)."""
        return {**self.files, **self.folders}

    @contextlib.contextmanager
    def write(self):
        """Yield ``{role: temporary path}``; rename everything into place only on success.

        Raises
        ------
        OutputError
            An ``OSError`` while writing or renaming; every target is left as it was.
        """
        created = []  # folders this call made, deepest last
        temps = {}
        kept = []  # (backup, target): existing targets set aside until all renames worked
        moved = []  # targets now holding new content
        try:
            try:
                for role, target in self.paths.items():
                    folder = target if role in self.folders else target.parent
                    missing = [p for p in (folder, *folder.parents) if not p.exists()]
                    for p in reversed(missing):
                        p.mkdir()
                        created.append(p)
                    if role in self.folders:
                        temps[role] = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp",
                                                            dir=target.parent))
                        continue
                    fd, name = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=f".tmp{target.suffix}",
                                                dir=target.parent)
                    os.close(fd)
                    os.chmod(name, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual mode
                    temps[role] = Path(name)
                yield dict(temps)
                renames = [(temps[role], target) for role, target in self.files.items()]
                for role, target in self.folders.items():
                    renames += [(f, target / f.name) for f in sorted(temps[role].iterdir())]
                for temp, target in renames:
                    if target.is_dir():
                        raise IsADirectoryError(21, "is a folder", str(target))
                for temp, target in renames:
                    if target.exists():
                        backup = Path(tempfile.mktemp(prefix=f".{target.name}.", suffix=".old",
                                                      dir=target.parent))
                        os.replace(target, backup)
                        kept.append((backup, target))
                    os.replace(temp, target)
                    moved.append(target)
            except OSError as exc:
                for target in moved:
                    with contextlib.suppress(OSError):
                        target.unlink()
                for backup, target in kept:
                    with contextlib.suppress(OSError):
                        os.replace(backup, target)
                kept, moved = [], []
                if isinstance(exc, OutputError):  # from a writer's own atomic write to our temporary
                    message = str(exc)
                else:
                    where = exc.filename or ", ".join(map(str, self.paths.values()))
                    message = f"cannot write {where}: {exc.strerror or exc}"
                for role, temp in temps.items():  # name the user's paths, not our temporaries
                    message = message.replace(str(temp), str(self.paths[role]))
                raise OutputError(message) from None
        finally:
            for backup, _ in kept:
                with contextlib.suppress(OSError):
                    backup.unlink()
            for temp in temps.values():
                with contextlib.suppress(FileNotFoundError):
                    if temp.is_dir():
                        shutil.rmtree(temp)
                    else:
                        temp.unlink()
            if not moved:
                for folder in reversed(created):
                    with contextlib.suppress(OSError):
                        folder.rmdir()


def plan_outputs(files, *, folders=None):
    """Check a command's outputs before any work and return the :class:`OutputPlan`.

    Parameters
    ----------
    files : dict of str → path-like or None
        Output files by role (``None``: not requested).
    folders : dict of str → path-like or None, optional
        Output folders by role, whose files are written together.

    Raises
    ------
    BadInputError
        Two outputs resolving to the same path, a file target that is a folder (or a folder
        target that is a file), a parent that is a file, a folder that is not writable.

    Examples
    --------
    >>> import tempfile
    >>> d = tempfile.mkdtemp()
    >>> plan_outputs({"exr": f"{d}/a.exr", "hdr": f"{d}/./a.exr"})  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    lsadphoto.errors.BadInputError: outputs exr and hdr are the same file .../a.exr
    """
    wanted_files = {role: Path(p) for role, p in files.items() if p is not None}
    wanted_folders = {role: Path(p) for role, p in (folders or {}).items() if p is not None}
    seen = {}
    for role, path in {**wanted_files, **wanted_folders}.items():
        resolved = path.resolve()
        if resolved in seen:
            raise BadInputError(f"outputs {seen[resolved]} and {role} are the same file {path}")
        seen[resolved] = role
        if role in wanted_files and path.is_dir():
            raise BadInputError(f"output {path} is an existing folder")
        if role in wanted_folders and path.exists() and not path.is_dir():
            raise BadInputError(f"output folder {path} is an existing file")
        folder = path if role in wanted_folders and path.is_dir() else _existing_ancestor(path)
        _check_writable(folder, path)
    return OutputPlan(wanted_files, wanted_folders)


@contextlib.contextmanager
def atomic_outputs(*paths):
    """Yield temporary paths for ``paths``; rename them all into place only on success.

    The same checks and guarantees as :func:`plan_outputs` and :meth:`OutputPlan.write`.
    """
    plan = plan_outputs(dict(enumerate(paths)))
    with plan.write() as temps:
        yield [temps[i] for i in range(len(paths))]


@contextlib.contextmanager
def atomic_path(path):
    """Yield one temporary path that is renamed to ``path`` on success."""
    with atomic_outputs(path) as (temp,):
        yield temp


def atomic_text(path, text):
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_path(path) as temp:
        temp.write_text(text, encoding="utf-8")
