"""Reference Monte Carlo lighting solver: double local estimate, view-independent LSAD store.

Lambertian scenes (TOML, :func:`load_scene`) are simulated once by light chains from the
luminaires (:func:`simulate` → :class:`LsadStore`, saved with :meth:`LsadStore.save`);
any view is then rendered from the store by the double local estimate (:func:`render`)
through the same :mod:`lsadphoto.geometry` projections that photographs use. A
conventional path tracer (:func:`render_path_traced`) is included for cross-checks, and
:func:`read_radiance_scene` reads the Lambertian subset of Radiance scene files.

References
----------
Budak, V. P., Zheltov, V. S., Kalakutsky, T. K. (2012). *Computer Research and Modeling*
4(1), 75–84. Marchuk, G. I. et al. (1980). *The Monte Carlo Methods in Atmospheric
Optics*. Springer. Kollig, T., Keller, A. (2004). Illumination in the presence of weak
singularities. Veach, E. (1997). PhD thesis, Stanford.
"""

from .intensity import IntensityTable
from .radiance import read_radiance_scene
from .rendering import SolverWarning, render, render_path_traced
from .scene import (
    AreaLuminaire,
    PointLuminaire,
    Scene,
    View,
    camera_to_world,
    load_scene,
    scene_from_dict,
)
from .simulation import simulate
from .store import LsadStore, load_store

__all__ = [
    "AreaLuminaire",
    "IntensityTable",
    "LsadStore",
    "PointLuminaire",
    "Scene",
    "SolverWarning",
    "View",
    "camera_to_world",
    "load_scene",
    "load_store",
    "read_radiance_scene",
    "render",
    "render_path_traced",
    "scene_from_dict",
    "simulate",
]
