"""Reference Monte Carlo lighting solver: double local estimate, view-independent LSAD store.

Lambertian scenes (TOML or Radiance files, :func:`read_scene`) are simulated once by light chains from the
luminaires (:func:`simulate` → :class:`LsadStore`, saved with :meth:`LsadStore.save`);
any view is then rendered from the store by the double local estimate or its surface cache
(:func:`render`, ``estimator="auto"`` choosing) through the same :mod:`lsadphoto.geometry`
projections that photographs use. Scenes with Radiance's glossy, specular and transmitting
materials (:mod:`~lsadphoto.solver.materials`) render directly from the scene. A conventional
path tracer (:func:`render_path_traced`) is included for cross-checks, and
:func:`read_radiance_scene` reads Radiance scene files (with ies2rad luminaires, and the sun and
the sky of gensky/gendaylit as distant sources, :class:`DistantSource` in :mod:`~lsadphoto.solver.sky`).
Luminaires' intensity distributions are :class:`Photometry` objects.

References
----------
Budak, V. P., Zheltov, V. S., Kalakutsky, T. K. (2012). *Computer Research and Modeling*
4(1), 75–84. Marchuk, G. I. et al. (1980). *The Monte Carlo Methods in Atmospheric
Optics*. Springer. Kollig, T., Keller, A. (2004). Illumination in the presence of weak
singularities. Veach, E. (1997). PhD thesis, Stanford.

Public names are imported on first use (:mod:`lsadphoto._lazy`).
"""

from .._lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, globals(), {
    ".photometry": ["Photometry", "read_photometry"],
    ".formats": ["load_scene", "read_radiance_scene", "read_rif_scene", "read_scene", "read_view"],
    ".integrators.path_tracer": ["render_path_traced"],
    ".rendering": ["SolverWarning", "render"],
    ".scene": ["AreaLuminaire", "PointLuminaire", "Scene", "View", "camera_to_world",
               "scene_from_dict"],
    ".simulation": ["simulate"],
    ".sky": ["DistantSource"],
    ".store": ["LsadStore", "load_store"],
})
