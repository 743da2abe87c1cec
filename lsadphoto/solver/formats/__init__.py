"""Scene files read into a solver :class:`~lsadphoto.solver.Scene`: one :func:`read_scene`.

- ``.toml``: the solver's own structure (:func:`load_scene`; meshes — OBJ, PLY, STL — enter
  as ``[[surfaces]] type = "mesh"``, read with trimesh);
- ``.rad``: Radiance scene descriptions (:func:`read_radiance_scene`), with their ``!``
  commands, ``xform`` transforms and ies2rad luminaires; ``.rif``: rad's project files, their
  materials, scene and views (:func:`read_rif_scene`);
- views: Radiance view options and ``.vf`` files (:func:`read_view`).

References
----------
TOML v1.0.0, https://toml.io/en/v1.0.0. Ward Larson, G., Shakespeare, R. (1998). *Rendering
with Radiance*, Morgan Kaufmann.
"""

from pathlib import Path

from ...errors import BadInputError
from ..scene import as_views
from .radiance import read_radiance_scene, read_rif_scene
from .toml import load_scene
from .views import read_view

__all__ = ["MESH_SUFFIXES", "load_scene", "read_radiance_scene", "read_rif_scene", "read_scene", "read_view"]

#: File endings of bare meshes: geometry without materials or luminaires.
MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")


def read_scene(path, *, views=None, **radiance_options):
    """The :class:`~lsadphoto.solver.Scene` of a scene file, whatever its format.

    Parameters
    ----------
    path : str or Path
        A TOML scene (``.toml``), a Radiance scene (``.rad``) or a rad input file (``.rif``,
        with its views). A bare mesh (``.obj``, …) is
        refused with a line saying how to use it: it has neither materials nor luminaires.
    views : list of View or dict, optional
        Views added to the scene's own: :class:`~lsadphoto.solver.View`\\ s or ``[[views]]``
        tables of the TOML structure.
    **radiance_options
        ``tessellation_error``, ``command_timeout`` of :func:`read_radiance_scene` (Radiance
        scenes only).

    Examples
    --------
    >>> read_scene("room.dwg")
    Traceback (most recent call last):
    ...
    lsadphoto.errors.BadInputError: room.dwg: unknown scene format '.dwg'; give a TOML scene (.toml), a Radiance scene (.rad) or a rad file (.rif)
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".rad":
        return read_radiance_scene(path, views=views, **radiance_options)
    if suffix == ".rif":
        scene = read_rif_scene(path, **radiance_options)
        scene.views.extend(as_views(views))
        return scene
    if radiance_options:
        raise BadInputError(f"{path}: {', '.join(radiance_options)} apply to Radiance scenes (.rad) only")
    if suffix == ".toml":
        scene = load_scene(path)
        scene.views.extend(as_views(views))
        return scene
    if suffix in MESH_SUFFIXES:
        raise BadInputError(f"{path}: a bare mesh has no materials or luminaires; reference it from a "
                            "TOML scene ([[surfaces]] type = \"mesh\") or a Radiance scene (!obj2rad)")
    raise BadInputError(f"{path}: unknown scene format {path.suffix!r}; give a TOML scene (.toml), a "
                        "Radiance scene (.rad) or a rad file (.rif)")
