"""Radiance views: ``rvu``/``rpict``-style view options, ``.vf`` files and ``-vf``.

A view file holds one line of view options, optionally after a program name (``rvu``,
``rview``, ``rpict``; as ``rvu``'s ``view`` command writes it) or ``VIEW=`` (as in a picture
header); ``#`` lines are comments. ``-vf file`` inside options reads such a file at that
point, and options after it override it, as in Radiance.

References
----------
Radiance manual pages ``rpict(1)`` (view options, ``-vf``) and ``rvu(1)`` (``view``
command, view files).
"""

import shlex
from pathlib import Path

import numpy as np

from ...errors import BadInputError
from ...io.hdr import parse_view, projection_from_view
from ..scene import View, camera_to_world

__all__ = ["read_view", "view_from_options", "view_options"]

_PROGRAMS = ("rvu", "rview", "rpict", "rtrace", "VIEW=")


def view_options(text, *, base=None, _depth=0):
    """The view options of ``text`` as one string, every ``-vf file`` replaced by its contents.

    ``base`` is the folder relative file names are taken from (default the current one).

    Examples
    --------
    >>> view_options("-vta -vh 180")
    '-vta -vh 180'
    """
    if _depth > 8:
        raise BadInputError(f"-vf files nest deeper than 8 levels in {text!r}")
    try:
        words = shlex.split(text, comments=True)
    except ValueError as exc:
        raise BadInputError(f"cannot read view {text!r} ({exc})") from None
    if words and words[0] in _PROGRAMS:
        words = words[1:]
    out = []
    k = 0
    while k < len(words):
        if words[k] == "-vf":
            if k + 1 >= len(words):
                raise BadInputError(f"-vf needs a file name in view {text!r}")
            path = Path(words[k + 1])
            if not path.is_absolute() and base is not None:
                path = Path(base) / path
            if not path.is_file():
                raise BadInputError(f"view file {path} does not exist")
            lines = [line.strip() for line in path.read_text(encoding="utf-8", errors="replace").splitlines()]
            lines = [line[5:] if line.startswith("VIEW=") else line for line in lines
                     if line and not line.startswith("#")]
            out.append(view_options(" ".join(lines), base=path.parent, _depth=_depth + 1))
            k += 2
        else:
            out.append(words[k])
            k += 1
    return " ".join(w for w in out if w)


def read_view(text, width, height, *, name="view", base=None):
    """A solver :class:`~lsadphoto.solver.View` of Radiance view options (``-vf`` allowed).

    Parameters
    ----------
    text : str
        View options, e.g. ``"-vf cornell.vf"`` or ``"-vta -vp 1 2 1.2 -vd 1 0 0 -vh 180 -vv 180"``.
    width, height : int
        Image size [px].
    name : str
        The view's name.
    base : str or Path, optional
        Folder of relative ``-vf`` file names.

    Examples
    --------
    >>> v = read_view("-vtv -vp 0 0 1.5 -vd 0 1 0 -vh 60 -vv 45", 64, 48)
    >>> v.position.tolist(), type(v.projection).__name__
    ([0.0, 0.0, 1.5], 'PinholeProjection')
    """
    view = parse_view(view_options(text, base=base), strict=True)
    if "vp" not in view:
        raise BadInputError(f"view {text!r} gives no eye position (-vp X Y Z [m])")
    return view_from_options(view, width, height, name=name)


def view_from_options(view, width, height, *, name="view"):
    """A :class:`~lsadphoto.solver.View` of parsed view options (:func:`~lsadphoto.io.hdr.parse_view`)
    with an eye position ``vp``, for a picture of ``width`` × ``height`` [px]."""
    projection = projection_from_view(view, width, height)
    rotation = camera_to_world(view.get("vd", [0.0, 1.0, 0.0]), view.get("vu", [0.0, 0.0, 1.0]))
    return View(name, np.asarray(view["vp"], float), rotation, projection)
