"""Scenes written in the solver's own TOML structure (:data:`~lsadphoto.solver.scene.SCENE_SCHEMA`)."""

from pathlib import Path

from ..._schema import read_toml
from ..scene import SCENE_SCHEMA, build_scene

__all__ = ["load_scene"]


def load_scene(path, *, photometry_reader=None):
    """Read a scene from a TOML file checked against
    :data:`~lsadphoto.solver.scene.SCENE_SCHEMA` (documented in ``docs/user-guide-solver.md``).

    Relative file names inside (meshes, photometric files) are taken relative to the
    TOML file's folder. Every problem with the file is reported as one
    :class:`~lsadphoto.errors.BadInputError` naming the offending entry.

    Parameters
    ----------
    path : str or Path
        The TOML scene file.
    photometry_reader : callable, optional
        ``reader(path) -> Photometry`` for ``photometry = "file"`` luminaires; default
        :func:`lsadphoto.solver.photometry.read_photometry`.

    References
    ----------
    TOML v1.0.0, https://toml.io/en/v1.0.0.
    """
    data = read_toml(path, SCENE_SCHEMA, what="scene")
    return build_scene(data, base=Path(path).parent, photometry_reader=photometry_reader, source=str(path))
