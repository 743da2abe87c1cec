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

import math
import warnings

from ..errors import BadInputError, SolverWarning
from .integrators.local_estimate import render_local_estimate
from .integrators.path_tracer import render_path_traced
from .scene import Scene
from .simulation import DEFAULT_BATCHES, ChainRun, check_simulation_options, simulate
from .store import LsadStore

__all__ = ["ESTIMATORS", "FIRST_RENDER_CHAINS", "MAX_RENDER_CHAINS", "MIN_PIXEL_TARGET_ERROR",
           "SolverWarning", "render", "render_path_traced"]

#: Chains of the first round of a ``target_error`` render (unless ``samples`` says).
FIRST_RENDER_CHAINS = 16_384
#: Default cap on chains of a ``target_error`` render.
MAX_RENDER_CHAINS = 1 << 22
#: Smallest per-pixel target [1]: each pixel's error falls as 1/√chains from a few per cent at
#: 10⁴ chains (the canonical room), so 10⁻³ already needs of the order of 10⁷ chains.
MIN_PIXEL_TARGET_ERROR = 1e-3

#: Estimators of a view: "local", the per-pixel double local estimate (:func:`render`, the
#: unbiased reference); "cache", direct light per pixel and indirect light interpolated from
#: the store's surface cache (:func:`~lsadphoto.solver.integrators.surface_cache.render_cached`).
ESTIMATORS = ("local", "cache")


def render(store_or_scene, projection, *, position, rotation, samples=None, target_error=None,
           max_samples=MAX_RENDER_CHAINS, seed=0, near_field=None, near_distance=None,
           nodes_per_pixel="auto", chunk_pixels=2048, workers=1, progress=None):
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
        Light chains to simulate when given a scene (an error for a store, whose chains are
        fixed); with ``target_error``, those of the first round.
    target_error : float, optional
        With a scene: the per-pixel relative standard error to reach — the median over the
        pixels with light (``provenance["pixel_relative_error_median"]``). The scene is
        simulated in rounds, each with the chains that 1/√chains predicts from the last
        (2–16 times as many), up to ``max_samples``; a
        :class:`~lsadphoto.errors.SolverWarning` says when the target is not reached, or
        when the error stops falling with more chains because each pixel connects to a
        fixed number of nodes (``nodes_per_pixel``: then ask for ``"all"`` or a larger K).
        ``provenance`` records the target, the rounds and whether it was reached.
    max_samples : int
        Cap on chains for ``target_error`` (default :data:`MAX_RENDER_CHAINS`).
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
    options = {"position": position, "rotation": rotation, "seed": seed, "near_field": near_field,
               "near_distance": near_distance, "nodes_per_pixel": nodes_per_pixel,
               "chunk_pixels": chunk_pixels, "workers": workers}
    if isinstance(store_or_scene, LsadStore):
        if samples is not None or target_error is not None:
            raise BadInputError("samples and target_error apply when rendering a scene; a store's "
                                f"{store_or_scene.chains} chains are fixed (simulate again for more)")
        return render_local_estimate(store_or_scene, projection, progress=progress, **options)
    if not isinstance(store_or_scene, Scene):
        raise BadInputError("render needs an LsadStore or a Scene")
    if target_error is None:
        store = simulate(store_or_scene, samples=samples, seed=seed,
                         near_field=near_field or "unbiased")
        return render_local_estimate(store, projection, progress=progress, **options)
    return _render_to_target(store_or_scene, projection, options, samples=samples,
                             target_error=target_error, max_samples=max_samples, progress=progress)


def _render_to_target(scene, projection, options, *, samples, target_error, max_samples, progress):
    """Rounds of simulate + render until the median per-pixel relative error ≤ target."""
    target = float(target_error)
    if not MIN_PIXEL_TARGET_ERROR <= target < 1:
        raise BadInputError(f"target_error must be a per-pixel relative error from "
                            f"{MIN_PIXEL_TARGET_ERROR:g} to below 1, got {target_error!r}")
    if int(max_samples) != max_samples or max_samples < 1:
        raise BadInputError(f"max_samples must be a positive integer, got {max_samples!r}")
    near_field = options["near_field"] or "unbiased"
    check_simulation_options(scene, near_field=near_field, absorption="weight",
                             batches=DEFAULT_BATCHES, max_depth=None, samples=samples)
    run = ChainRun(scene, seed=options["seed"], max_depth=None, near_field=near_field,
                   absorption="weight", batches=DEFAULT_BATCHES)
    chains = min(int(samples or FIRST_RENDER_CHAINS), int(max_samples))
    rounds = []
    while True:
        # each round appends chains to the last round's (the same streams as one long run)
        store = run.grow(chains)
        lmap = render_local_estimate(store, projection, progress=progress, **options)
        error = lmap.provenance["pixel_relative_error_median"]
        rounds.append({"chains": int(store.chains), "pixel_relative_error_median": error})
        reached = bool(error <= target)
        stalled = (len(rounds) > 1 and lmap.provenance["nodes_per_pixel"] != "all"
                   and error > 0.8 * rounds[-2]["pixel_relative_error_median"])
        if reached or stalled or not math.isfinite(error) or store.chains >= max_samples:
            break
        # σ ∝ 1/√chains: the chains that reach the target, with a 20 % margin; at least 2× and
        # at most 16× per round (a stalling error shows before the budget is spent)
        predicted = math.ceil(1.2 * store.chains * (error / target) ** 2)
        chains = min(int(max_samples), max(2 * store.chains, min(16 * store.chains, predicted)))
    lmap.provenance.update({"target_error": target, "target_reached": reached,
                            "target_measure": "median per-pixel relative standard error",
                            "rounds": rounds})
    if stalled and not reached:
        warnings.warn(f"per-pixel error {error:.2g} stopped falling with more chains "
                      f"({rounds[-2]['chains']} → {rounds[-1]['chains']}): each pixel connects to "
                      f"{lmap.provenance['nodes_per_pixel']} nodes per batch; render with "
                      "nodes_per_pixel='all' or a larger number to reach the target", SolverWarning,
                      stacklevel=3)
    elif not reached:
        warnings.warn(f"per-pixel error {error:.2g} above the target {target:g} after "
                      f"{rounds[-1]['chains']} chains (max_samples)", SolverWarning, stacklevel=3)
    return lmap
