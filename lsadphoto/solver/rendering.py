"""Rendering a view of a model: the public entry point of the solver's estimators.

:func:`render` renders a view of a simulated :class:`~lsadphoto.solver.store.LsadStore` (or of a
scene, simulated first) by one of ``ESTIMATORS``: ``"local"``, the double local estimate
(:mod:`lsadphoto.solver.integrators.local_estimate`, the unbiased reference), or ``"cache"``,
direct light per pixel and indirect light from a surface cache
(:func:`~lsadphoto.solver.integrators.surface_cache.render_cached`); ``"auto"`` chooses
(:func:`choose_estimator`) and says why. Scenes with glossy, specular or transmitting
materials render by the double local estimate with materials
(:func:`~lsadphoto.solver.integrators.local_estimate.render_local_estimate_materials`), from
their store like Lambertian ones. With ``target_error`` a scene is simulated and
rendered in rounds until the expected mean absolute per-pixel relative error is reached. The path tracer
(:func:`~lsadphoto.solver.integrators.path_tracer.render_path_traced`) is the independent
cross-check.
"""

import math
import warnings

from .._validation import check_choice
from ..errors import BadInputError, SolverWarning
from .direct import DIRECT_SAMPLES, LUMINAIRE_DRAWS
from .integrators.local_estimate import (AUTO_NODES_PER_PIXEL, RAYS_PER_VERTEX, render_local_estimate,
                                         render_local_estimate_materials)
from .integrators.path_tracer import render_path_traced
from .integrators.surface_cache import CACHE_NODES, build_surface_cache, render_cached
from .materials import FRESNEL_RULES
from .scene import Scene
from .simulation import DEFAULT_BATCHES, DEFAULT_CHAINS, ChainRun, check_simulation_options, simulate
from .store import LsadStore

__all__ = ["DEFAULT_TARGET_ERROR", "ESTIMATORS", "FIRST_RENDER_CHAINS", "MAX_RENDER_CHAINS",
           "MIN_PIXEL_TARGET_ERROR", "SolverWarning", "TARGET_MEASURE", "choose_estimator", "render",
           "render_path_traced"]

#: Chains of the first round of a ``target_error`` render (unless ``samples`` says).
FIRST_RENDER_CHAINS = 16_384
#: Default cap on chains of a ``target_error`` render.
MAX_RENDER_CHAINS = 1 << 22
#: Smallest per-pixel target [1]: each pixel's error falls as 1/√chains from a few per cent at
#: 10⁴ chains (the canonical room), so 10⁻³ already needs of the order of 10⁷ chains.
MIN_PIXEL_TARGET_ERROR = 1e-3

#: Estimators of a view: "local", the per-pixel double local estimate (the unbiased
#: reference); "cache", direct light per pixel and indirect light interpolated from a surface
#: cache (:func:`~lsadphoto.solver.integrators.surface_cache.render_cached`); "auto", the
#: choice of :func:`choose_estimator`.
ESTIMATORS = ("local", "cache", "auto")
#: Per-pixel target of the command line's ``render`` of a scene when no ``--samples`` are given.
DEFAULT_TARGET_ERROR = 0.02
#: What a per-pixel target bounds: the mean absolute relative error that the map's own
#: uncertainties imply over the pixels with light, √(2/π)·mean(σ/L) (eye.py), which a
#: comparison with a reference measures (docs/accuracy.md: MARE). Until session 11 it was the
#: median of σ/L, which a long upper tail (partly shadowed and near-edge pixels) left ≈ 1.5×
#: below the MARE measured against Radiance on the station hall.
TARGET_MEASURE = "pixel_relative_error_expected_mean_absolute"
#: Caps of a surface-cache ``target_error`` render's rounds: node draws per cache point,
#: shadow-ray samples per luminaire and pixel, and luminaire draws per pixel (first
#: :data:`~lsadphoto.solver.direct.LUMINAIRE_DRAWS`, where the direct light samples its
#: luminaires).
MAX_CACHE_NODES = 1 << 17
MAX_DIRECT_SAMPLES = 256
MAX_LUMINAIRE_DRAWS = 1024
#: Caps of a ``target_error`` render of a scene with non-Lambertian materials: nodes per pixel
#: and batch, and BSDF-sampled rays per eye vertex (their first round's are the defaults,
#: :data:`~.local_estimate.AUTO_NODES_PER_PIXEL` and :data:`~.local_estimate.RAYS_PER_VERTEX`).
MAX_MATERIAL_NODES = 1024
MAX_RAYS_PER_VERTEX = 256


def choose_estimator(store_or_scene, *, samples=None, target_error=None):
    """The estimator ``"auto"`` renders with, and why (one line).

    A store renders from its surface cache if it holds one, else by the double local estimate
    (building a cache is a choice for ``simulate --surface-cache``). A store or scene with
    glossy, specular or transmitting materials renders by the double local estimate with
    materials, the unbiased reference (a target is reached by its rounds; the surface cache
    is a choice, ``estimator="cache"``). A Lambertian
    scene with a fixed number
    of chains and no target renders by the double local estimate, the unbiased reference; a
    scene with a per-pixel target (or neither) by the surface cache, which reaches a per-pixel
    error at a small fraction of the per-pixel estimate's cost (docs/accuracy.md: 0.63 % mean
    absolute error against rtrace in the canonical room where the double local estimate has
    7.8 %, in comparable time) — at the price of an interpolation bias near edges.
    """
    if isinstance(store_or_scene, LsadStore):
        if store_or_scene.surface_cache is not None:
            return "cache", "the store holds a surface cache"
        return "local", "the store holds no surface cache (simulate --surface-cache builds one)"
    if not store_or_scene.lambertian:
        return "local", ("non-Lambertian materials: the double local estimate with materials, the unbiased "
                         "reference (estimator 'cache' is a choice)"
                         + ("" if target_error is None else "; the per-pixel target by rounds of chains"))
    if samples is not None and target_error is None:
        return "local", "a fixed number of chains: the unbiased double local estimate"
    return "cache", ("a per-pixel target: the surface cache reaches it at a fraction of the double "
                     "local estimate's cost (docs/accuracy.md)")


def render(store_or_scene, projection, *, position, rotation, estimator="local", samples=None,
           target_error=None, max_samples=MAX_RENDER_CHAINS, seed=0, near_field=None,
           near_distance=None, nodes_per_pixel="auto", cache_spacing=None, cache_nodes=None,
           direct_samples=None, chunk_pixels=2048, workers=1, progress=None, fresnel_rule=None):
    """Luminance map of a view by the double local estimate or the surface cache [cd·m⁻²].

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
    estimator : {"local", "cache", "auto"}
        ``"local"`` (default): the double local estimate per pixel, unbiased. ``"cache"``:
        direct light per pixel, indirect light interpolated from a surface cache (the store's,
        or one built with ``cache_spacing`` and ``cache_nodes``); its per-pixel uncertainty
        includes the estimated interpolation bias, and the provenance gives the noise and
        bias parts apart (:func:`~lsadphoto.solver.integrators.surface_cache.render_cached`).
        ``"auto"``: as
        :func:`choose_estimator` says, recorded in ``provenance["estimator_choice"]``.
    samples : int, optional
        Light chains to simulate when given a scene (an error for a store, whose chains are
        fixed); with ``target_error``, those of the first round.
    target_error : float, optional
        With a scene: the per-pixel relative error to reach — the mean absolute relative
        error that the map's uncertainties imply over the pixels with light, √(2/π)·mean(σ/L)
        (``provenance["pixel_relative_error_expected_mean_absolute"]``). The scene is
        simulated in rounds, each with the chains that 1/√chains predicts from the last
        (2–16 times as many; with ``"cache"`` the cache's node draws, the direct light's
        samples and its luminaire draws grow by the same factor; with non-Lambertian materials the nodes per pixel
        and the BSDF-sampled rays per eye vertex, up to :data:`MAX_MATERIAL_NODES` and
        :data:`MAX_RAYS_PER_VERTEX`), up to ``max_samples``; a
        :class:`~lsadphoto.errors.SolverWarning` says when the target is not reached, or
        when the error stops falling with more chains because each pixel connects to a
        fixed number of nodes (``nodes_per_pixel``: then ask for ``"all"`` or a larger K).
        ``provenance`` records the target, the rounds and whether it was reached.
    max_samples : int
        Cap on chains for ``target_error`` (default :data:`MAX_RENDER_CHAINS`).
    seed : int
        Seed of the near-field rays (and of the simulation when given a scene).
    near_field : {"unbiased", "clamp"}, optional
        Near-field treatment (:mod:`~lsadphoto.solver.integrators.local_estimate`); default the store's
        ("clamp" is an error for non-Lambertian materials).
    near_distance : float, optional
        ε [m]; default :data:`~lsadphoto.solver.integrators.local_estimate.RELATIVE_NEAR_DISTANCE` × scene size.
    fresnel_rule : {"reciprocal", "radiance"}, optional
        The smooth materials' rule for the factor 1 − F(μ_i)
        (:data:`~lsadphoto.solver.materials.FRESNEL_RULES`, ``fresnel_rule`` of
        :func:`~lsadphoto.solver.simulate`): a store's own (another is an error), or for a
        scene the one it is simulated with (default ``"reciprocal"``).
    cache_spacing, cache_nodes : float [m], int, optional
        Surface cache of ``"cache"`` when one is built (defaults of
        :func:`~lsadphoto.solver.integrators.surface_cache.build_surface_cache`); an error for
        a store that already holds a cache. With ``target_error`` the first round's nodes.
    direct_samples : int, optional
        ``"cache"``: shadow-ray samples per luminaire and pixel (default
        :data:`~lsadphoto.solver.direct.DIRECT_SAMPLES`; with ``target_error`` the first
        round's).
    nodes_per_pixel : int, "all" or "auto"
        An integer K connects each visible point to K nodes per batch, drawn uniformly
        (stratified: source and surface nodes) and scaled by count/K — unbiased, render
        cost ∝ pixels × K × batches. ``"all"`` (or None) connects every node: the full
        double local estimate, cost ∝ pixels × nodes. ``"auto"`` (default): all nodes when
        pixels × nodes ≤ :data:`~.local_estimate.FULL_GATHER_PAIRS`, else :data:`~.local_estimate.AUTO_NODES_PER_PIXEL`.
        With non-Lambertian materials an integer, or ``"auto"`` for
        :data:`~.local_estimate.AUTO_NODES_PER_PIXEL` (``"all"`` is an error).
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
        leaves an open scene), ``uncertainty`` the per-pixel standard error (with the
        cache: noise and estimated interpolation bias in quadrature), and
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
    check_choice(estimator, "estimator", ESTIMATORS)
    if not isinstance(store_or_scene, (LsadStore, Scene)):
        raise BadInputError("render needs an LsadStore or a Scene")
    if fresnel_rule is not None:
        check_choice(fresnel_rule, "fresnel_rule", FRESNEL_RULES)
    if isinstance(store_or_scene, LsadStore):
        if fresnel_rule not in (None, store_or_scene.fresnel_rule):
            raise BadInputError(f"fresnel_rule {fresnel_rule!r} differs from the store's "
                                f"{store_or_scene.fresnel_rule!r} (its chains were traced with it: simulate again)")
        fresnel_rule = store_or_scene.fresnel_rule
    fresnel_rule = fresnel_rule or "reciprocal"
    choice = None
    if estimator == "auto":
        estimator, reason = choose_estimator(store_or_scene, samples=samples, target_error=target_error)
        choice = f"auto: {estimator} ({reason})"
    if estimator == "cache":
        local_only = [name for name, value in (("near_field", near_field), ("near_distance", near_distance))
                      if value is not None] + (["nodes_per_pixel"] if nodes_per_pixel != "auto" else [])
        if local_only:
            raise BadInputError(f"{', '.join(local_only)} apply to the double local estimate, not the "
                                "surface cache")
        lmap = _render_from_cache(store_or_scene, projection, position=position, rotation=rotation,
                                  samples=samples, target_error=target_error, max_samples=max_samples,
                                  seed=seed, spacing=cache_spacing, nodes=cache_nodes,
                                  direct_samples=direct_samples, chunk_pixels=chunk_pixels,
                                  workers=workers, progress=progress, fresnel_rule=fresnel_rule)
    else:
        cache_only = [name for name, value in (("cache_spacing", cache_spacing), ("cache_nodes", cache_nodes),
                                               ("direct_samples", direct_samples)) if value is not None]
        if cache_only:
            raise BadInputError(f"{', '.join(cache_only)} apply to the surface cache (estimator 'cache')")
        lmap = _render_local(store_or_scene, projection, position=position, rotation=rotation,
                             samples=samples, target_error=target_error, max_samples=max_samples,
                             seed=seed, near_field=near_field, near_distance=near_distance,
                             nodes_per_pixel=nodes_per_pixel, chunk_pixels=chunk_pixels,
                             workers=workers, progress=progress, fresnel_rule=fresnel_rule)
    if choice is not None:
        lmap.provenance["estimator_choice"] = choice
    return lmap


def _render_local(store_or_scene, projection, *, samples, target_error, max_samples, progress, **rest):
    """The double local estimate of :func:`render` (options as there)."""
    options = {k: rest[k] for k in ("position", "rotation", "seed", "near_field", "near_distance",
                                    "nodes_per_pixel", "chunk_pixels", "workers")}
    seed, near_field = rest["seed"], rest["near_field"]
    scene = store_or_scene.scene if isinstance(store_or_scene, LsadStore) else store_or_scene
    if not scene.lambertian:
        return _render_local_materials(store_or_scene, projection, samples=samples, target_error=target_error,
                                       max_samples=max_samples, progress=progress, **rest)
    if isinstance(store_or_scene, LsadStore):
        _refuse_chains_for_store(store_or_scene, samples, target_error)
        return render_local_estimate(store_or_scene, projection, progress=progress, **options)
    if target_error is None:
        store = simulate(store_or_scene, samples=samples, seed=seed,
                         near_field=near_field or "unbiased", fresnel_rule=rest["fresnel_rule"])
        return render_local_estimate(store, projection, progress=progress, **options)

    def render_round(store, growth):
        lmap = render_local_estimate(store, projection, progress=progress, **options)
        k = lmap.provenance["nodes_per_pixel"]
        advice = None if k == "all" else (f"each pixel connects to {k} nodes per batch; render with "
                                          "nodes_per_pixel='all' or a larger number to reach the target")
        return lmap, {}, advice

    return _render_to_target(store_or_scene, samples=samples, target_error=target_error,
                             max_samples=max_samples, seed=seed, near_field=near_field or "unbiased",
                             first_chains=FIRST_RENDER_CHAINS, render_round=render_round,
                             fresnel_rule=rest["fresnel_rule"])


def _refuse_chains_for_store(store, samples, target_error):
    """One-line error: a store's chains are fixed."""
    if samples is not None or target_error is not None:
        raise BadInputError("samples and target_error apply when rendering a scene; a store's "
                            f"{store.chains} chains are fixed (simulate again for more)")


def _render_local_materials(store_or_scene, projection, *, samples, target_error, max_samples, progress,
                            **rest):
    """The double local estimate with materials (options as :func:`render`'s): a store of
    chains that sample the BSDFs, simulated like any other (one path: a render of the scene
    is :func:`simulate` + the render of its store, the same map bit for bit)."""
    if rest["near_field"] == "clamp":
        raise BadInputError("scenes with non-Lambertian materials render with the unbiased near field only "
                            "(near_field='clamp' applies to Lambertian scenes)")
    k = rest["nodes_per_pixel"]
    if k is None or k == "all":
        raise BadInputError("nodes_per_pixel='all' applies to Lambertian scenes; with non-Lambertian materials "
                            f"each pixel connects to a number of nodes per batch (default {AUTO_NODES_PER_PIXEL})")
    first_k = AUTO_NODES_PER_PIXEL if k == "auto" else k
    view = {key: rest[key] for key in ("position", "rotation", "seed", "near_distance", "chunk_pixels", "workers")}
    view["progress"] = progress
    if isinstance(store_or_scene, LsadStore):
        _refuse_chains_for_store(store_or_scene, samples, target_error)
        return render_local_estimate_materials(store_or_scene, projection, nodes_per_pixel=first_k, **view)
    if target_error is None:
        store = simulate(store_or_scene, samples=samples, seed=rest["seed"], fresnel_rule=rest["fresnel_rule"])
        return render_local_estimate_materials(store, projection, nodes_per_pixel=first_k, **view)

    def render_round(store, growth):
        # the node draws and the sampled rays per pixel grow with the chains: each noise of the
        # map falls as 1/√ of its samples (the secondary vertices keep K/rays nodes each)
        nodes = min(MAX_MATERIAL_NODES, max(first_k, round(first_k * growth)))
        rays = min(MAX_RAYS_PER_VERTEX, max(RAYS_PER_VERTEX, round(RAYS_PER_VERTEX * growth)))
        lmap = render_local_estimate_materials(store, projection, nodes_per_pixel=nodes, rays_per_vertex=rays,
                                               **view)
        capped = nodes == MAX_MATERIAL_NODES or rays == MAX_RAYS_PER_VERTEX
        advice = (f"the material local estimate reached its caps ({MAX_MATERIAL_NODES} nodes per pixel and "
                  f"batch, {MAX_RAYS_PER_VERTEX} sampled rays per eye vertex); give a larger target or "
                  "render_path_traced") if capped else None
        return lmap, {"nodes_per_pixel": nodes, "rays_per_vertex": rays}, advice

    return _render_to_target(store_or_scene, samples=samples, target_error=target_error,
                             max_samples=max_samples, seed=rest["seed"], near_field="unbiased",
                             first_chains=FIRST_RENDER_CHAINS, render_round=render_round,
                             fresnel_rule=rest["fresnel_rule"])


def _render_from_cache(store_or_scene, projection, *, position, rotation, samples, target_error,
                       max_samples, seed, spacing, nodes, direct_samples, chunk_pixels, workers,
                       progress, fresnel_rule):
    """The surface-cache estimator of :func:`render` (options as there)."""
    view = {"position": position, "rotation": rotation, "seed": seed, "chunk_pixels": chunk_pixels,
            "workers": workers, "progress": progress}
    first_nodes = int(nodes) if nodes is not None else CACHE_NODES
    first_samples = int(direct_samples) if direct_samples is not None else DIRECT_SAMPLES

    def cache_of(store, node_draws):
        return build_surface_cache(store, spacing=spacing, nodes=node_draws, seed=seed, workers=workers)

    if isinstance(store_or_scene, LsadStore):
        store = store_or_scene
        _refuse_chains_for_store(store, samples, target_error)
        cache = store.surface_cache
        if cache is not None and (spacing is not None or nodes is not None):
            raise BadInputError(f"cache_spacing and cache_nodes cannot apply: the store already holds a "
                                f"surface cache (spacing {cache.spacing:.3g} m)")
        return render_cached(store, projection, cache=cache or cache_of(store, first_nodes),
                             direct_samples=first_samples, **view)
    if target_error is None:
        store = simulate(store_or_scene, samples=samples, seed=seed, fresnel_rule=fresnel_rule)
        return render_cached(store, projection, cache=cache_of(store, first_nodes),
                             direct_samples=first_samples, **view)

    def render_round(store, growth):
        # every noise of the map (chains, node draws, shadow rays, luminaire draws) grows by
        # the chains' factor; the first round's luminaire draws are direct_illuminance's "auto"
        node_draws = min(MAX_CACHE_NODES, max(first_nodes, round(first_nodes * growth)))
        shadow_rays = min(MAX_DIRECT_SAMPLES, max(first_samples, math.ceil(first_samples * growth)))
        draws = min(MAX_LUMINAIRE_DRAWS, max(LUMINAIRE_DRAWS, math.ceil(LUMINAIRE_DRAWS * growth)))
        lmap = render_cached(store, projection, cache=cache_of(store, node_draws),
                             direct_samples=shadow_rays,
                             luminaire_draws=None if draws == LUMINAIRE_DRAWS else draws, **view)
        capped = (node_draws == MAX_CACHE_NODES or shadow_rays == MAX_DIRECT_SAMPLES
                  or draws == MAX_LUMINAIRE_DRAWS)
        p = lmap.provenance
        advice = (f"the surface cache reached its caps ({MAX_CACHE_NODES} node draws per point, "
                  f"{MAX_DIRECT_SAMPLES} shadow rays per luminaire and {MAX_LUMINAIRE_DRAWS} luminaire "
                  "draws per pixel); render with the double local estimate or give more chains") if capped else None
        if p["pixel_relative_bias_mean"] > p["pixel_relative_noise_mean"]:
            # more samples do not reduce the interpolation bias; a finer cache does. Compared
            # as means, the measure a target bounds (TARGET_MEASURE): the bias's tail near
            # edges can hold the mean while its median is below the noise's.
            advice = (f"the cache's estimated interpolation bias (mean {p['pixel_relative_bias_mean']:.2g} "
                      f"per pixel) exceeds its noise ({p['pixel_relative_noise_mean']:.2g}) and does not fall "
                      "with more chains; give a finer cache_spacing")
        return lmap, {"cache_nodes": node_draws, "direct_samples": shadow_rays,
                      "luminaire_draws": p["luminaire_draws"]}, advice

    return _render_to_target(store_or_scene, samples=samples, target_error=target_error,
                             max_samples=max_samples, seed=seed, near_field="unbiased",
                             first_chains=DEFAULT_CHAINS, render_round=render_round, fresnel_rule=fresnel_rule)


def _render_to_target(scene, *, samples, target_error, max_samples, seed, near_field, first_chains,
                      render_round, fresnel_rule):
    """Rounds of simulate + render until the expected mean absolute per-pixel relative error
    (:data:`TARGET_MEASURE`) ≤ target.

    ``render_round(store, growth) -> (map, knobs, advice)`` renders a round's store, its own
    accuracy knobs grown by ``growth`` = chains / first round's chains; ``knobs`` are recorded
    with the round, ``advice`` (or None) says what to do when the error stops falling.
    """
    target = float(target_error)
    if not MIN_PIXEL_TARGET_ERROR <= target < 1:
        raise BadInputError(f"target_error must be a per-pixel relative error from "
                            f"{MIN_PIXEL_TARGET_ERROR:g} to below 1, got {target_error!r}")
    if int(max_samples) != max_samples or max_samples < 1:
        raise BadInputError(f"max_samples must be a positive integer, got {max_samples!r}")
    check_simulation_options(scene, near_field=near_field, absorption="weight",
                             batches=DEFAULT_BATCHES, max_depth=None, samples=samples, fresnel_rule=fresnel_rule)
    run = ChainRun(scene, seed=seed, max_depth=None, near_field=near_field,
                   absorption="weight", batches=DEFAULT_BATCHES, fresnel_rule=fresnel_rule)
    chains = first = min(int(samples or first_chains), int(max_samples))
    rounds = []
    while True:
        # each round appends chains to the last round's (the same streams as one long run)
        store = run.grow(chains)
        lmap, knobs, advice = render_round(store, store.chains / first)
        error = lmap.provenance[TARGET_MEASURE]
        rounds.append({"chains": int(store.chains), **knobs, TARGET_MEASURE: error,
                       "pixel_relative_error_median": lmap.provenance["pixel_relative_error_median"]})
        reached = bool(error <= target)
        stalled = (len(rounds) > 1 and advice is not None and error > 0.8 * rounds[-2][TARGET_MEASURE])
        if reached or stalled or not math.isfinite(error) or chains >= max_samples:
            break
        # σ ∝ 1/√chains: the chains that reach the target, with a 20 % margin; at least 2× and
        # at most 16× per round (a stalling error shows before the budget is spent)
        predicted = math.ceil(1.2 * store.chains * (error / target) ** 2)
        chains = min(int(max_samples), max(2 * store.chains, min(16 * store.chains, predicted)))
    lmap.provenance.update({"target_error": target, "target_reached": reached,
                            "target_measure": "expected mean absolute per-pixel relative error "
                                              f"({TARGET_MEASURE})",
                            "rounds": rounds})
    if stalled and not reached:
        warnings.warn(f"per-pixel error {error:.2g} stopped falling with more chains "
                      f"({rounds[-2]['chains']} → {rounds[-1]['chains']}): {advice}", SolverWarning,
                      stacklevel=4)
    elif not reached:
        warnings.warn(f"per-pixel error {error:.2g} above the target {target:g} after "
                      f"{rounds[-1]['chains']} chains (max_samples)", SolverWarning, stacklevel=4)
    return lmap
