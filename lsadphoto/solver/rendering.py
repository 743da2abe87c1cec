"""Rendering a view of a model: the public entry point of the solver's estimators.

:func:`render` renders a view of a simulated :class:`~lsadphoto.solver.store.LsadStore` (or of a
scene, simulated first) by the double local estimate
(:mod:`lsadphoto.solver.integrators.local_estimate`, the unbiased reference);
``ESTIMATORS`` names the estimators a user can choose for a store's view ("cache": direct
light per pixel, indirect light from the store's surface cache,
:func:`~lsadphoto.solver.integrators.surface_cache.render_cached`). The path tracer
(:func:`~lsadphoto.solver.integrators.path_tracer.render_path_traced`) is the independent
cross-check.
"""

from ..errors import BadInputError, SolverWarning
from .integrators.local_estimate import render_local_estimate
from .integrators.path_tracer import render_path_traced
from .scene import Scene
from .simulation import simulate
from .store import LsadStore

__all__ = ["ESTIMATORS", "SolverWarning", "render", "render_path_traced"]

#: Estimators of a view: "local", the per-pixel double local estimate (:func:`render`, the
#: unbiased reference); "cache", direct light per pixel and indirect light interpolated from
#: the store's surface cache (:func:`~lsadphoto.solver.integrators.surface_cache.render_cached`).
ESTIMATORS = ("local", "cache")


def render(store_or_scene, projection, *, position, rotation, samples=None, seed=0,
           near_field=None, near_distance=None, nodes_per_pixel="auto", chunk_pixels=2048,
           workers=1, progress=None):
    """Luminance map of a view by the double local estimate [cd·m⁻²].

    Parameters
    ----------
    store_or_scene : LsadStore or Scene
        A simulated store (any number of views render from one simulation), or a scene,
        which is simulated first with ``samples`` chains and ``seed``.
    projection : Projection
        Camera model (pixel → direction in the camera frame: x right, y down, z forward).
    position : array_like, shape (3,)
        Eye position [m].
    rotation : array_like, shape (3, 3)
        Camera-to-world rotation (see :func:`~lsadphoto.solver.camera_to_world`).
    samples : int, optional
        Light chains to simulate when given a scene (ignored for a store).
    seed : int
        Seed of the near-field rays (and of the simulation when given a scene).
    near_field : {"unbiased", "clamp"}, optional
        Near-field treatment (:mod:`~lsadphoto.solver.integrators.local_estimate`); default the store's.
    near_distance : float, optional
        ε [m]; default :data:`~lsadphoto.solver.integrators.local_estimate.RELATIVE_NEAR_DISTANCE` × scene size.
    nodes_per_pixel : int, "all" or "auto"
        An integer K connects each visible point to K nodes per batch, drawn uniformly
        (stratified: source and surface nodes) and scaled by count/K — unbiased, render
        cost ∝ pixels × K × batches. ``"all"`` (or None) connects every node: the full
        double local estimate, cost ∝ pixels × nodes. ``"auto"`` (default): all nodes when
        pixels × nodes ≤ :data:`~.local_estimate.FULL_GATHER_PAIRS`, else :data:`~.local_estimate.AUTO_NODES_PER_PIXEL`.
    chunk_pixels : int
        Pixels per processing chunk (rounded up to a multiple of :data:`~.eye.PIXEL_BLOCK`);
        bounds memory, never changes the result.
    workers : int
        Threads working on chunks at once (numpy and Embree release the GIL for most of
        the work); never changes the result.
    progress : callable, optional
        ``progress(done_fraction, eta_s)``.

    Returns
    -------
    LuminanceMap
        Luminance [cd·m⁻²] (NaN outside the projection's valid region; 0 where a ray
        leaves an open scene), ``uncertainty`` the per-pixel standard error, and
        ``provenance`` with estimator, samples, seed, near-field treatment and the
        achieved relative standard error of the field-mean luminance.

    Warns
    -----
    SolverWarning
        When the eye lies on a surface (more than 1 % of the primary rays hit within 10 ray
        offsets), or when it sees lit-able surfaces but no light at all (an eye outside a
        closed room or inside a solid). A view that hits nothing (out of an open model) or
        only black surfaces is legal and silent.

    References
    ----------
    Budak, Zheltov & Kalakutsky (2012); Marchuk et al. (1980); Kollig & Keller (2004).

    Examples
    --------
    A 100 cd isotropic point 2 m above a grey (ρ = 0.5) disc, seen straight down:
    L = ρ·I/(π d²) = 0.5 · 100/(4π) cd·m⁻².

    >>> from lsadphoto.geometry import PinholeProjection
    >>> from lsadphoto.solver import camera_to_world, scene_from_dict, simulate
    >>> scene = scene_from_dict({
    ...     "materials": {"grey": {"reflectance": 0.5}},
    ...     "surfaces": [{"type": "disc", "centre": [0, 0, 0], "normal": [0, 0, 1],
    ...                   "radius": 5, "material": "grey"}],
    ...     "luminaires": [{"type": "point", "position": [0, 0, 2], "intensity": 100}]})
    >>> store = simulate(scene, samples=256)
    >>> lmap = render(store, PinholeProjection(100, 100, 0, 0, 1, 1), position=[0, 0, 3],
    ...               rotation=camera_to_world([0, 0, -1], [0, 1, 0]))
    >>> round(float(lmap.luminance[0, 0]), 4), lmap.provenance["near_field"]
    (3.9789, 'unbiased')
    """
    if isinstance(store_or_scene, Scene):
        store = simulate(store_or_scene, samples=samples, seed=seed,
                         near_field=near_field or "unbiased")
    elif isinstance(store_or_scene, LsadStore):
        store = store_or_scene
    else:
        raise BadInputError("render needs an LsadStore or a Scene")
    return render_local_estimate(store, projection, position=position, rotation=rotation,
                                 seed=seed, near_field=near_field, near_distance=near_distance,
                                 nodes_per_pixel=nodes_per_pixel, chunk_pixels=chunk_pixels,
                                 workers=workers, progress=progress)
