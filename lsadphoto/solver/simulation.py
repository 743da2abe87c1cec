"""Simulation entry point: trace light chains into a view-independent LSAD store.

References
----------
Budak, Zheltov & Kalakutsky (2012); Marchuk et al. (1980). See
:mod:`lsadphoto.solver.chains` and :mod:`lsadphoto.solver.integrators.local_estimate`.
"""

import math
import time
import warnings

import numpy as np

from .._provenance import build_provenance
from .._validation import check_choice
from .._version import __version__
from ..errors import BadInputError, SolverWarning
from .chains import (
    ABSORPTION_MODES,
    CHAIN_BLOCK,
    EmissionSampler,
    trace_chains,
    trace_material_chains,
)
from .engine import engine_for
from .integrators.local_estimate import (
    NEAR_FIELD_TREATMENTS,
    render_local_estimate,
    render_local_estimate_materials,
)
from .materials import FRESNEL_RULES
from .scene import Scene

__all__ = ["DEFAULT_BATCHES", "DEFAULT_CHAINS", "MAX_CHAINS", "ChainRun", "check_simulation_options", "simulate"]

#: Light chains of a simulation when neither ``samples`` nor ``target_error`` is given.
DEFAULT_CHAINS = 65_536
#: Independent batches for the standard errors (must divide the chain block size).
DEFAULT_BATCHES = 16
#: Upper limit of chains a ``target_error`` simulation may use.
MAX_CHAINS = 1 << 24
#: Smallest target relative standard error [1]. On the canonical room the error reached is
#: ≈ 1e-3 with 8 192 to 65 536 chains (field-mean luminance of its view); it falls at best as
#: 1/√chains, so 1e-4 already needs of the order of MAX_CHAINS, and below it no run within
#: MAX_CHAINS gets there: such a target would only spend the whole budget. The model's own
#: inputs (reflectances known to ±0.01, fluxes to a few per cent) dominate long before.
MIN_TARGET_ERROR = 1e-4
#: Largest image side of the low-resolution view used to estimate the error in rounds [px].
_ERROR_VIEW_SIDE = 24
#: Nodes per pixel and batch of that low-resolution render.
_ERROR_VIEW_NODES = 128


def _error_estimate(store):
    """Relative standard error [–] of the field-mean luminance of the first view.

    Rendered at ≤ 24 px per side from the store, 128 nodes per pixel and batch (the
    estimate includes that subsampling noise, so it errs on the safe side; with
    non-Lambertian materials by the material local estimate, with its sampled rays). Without
    views: of the area-mean exitance of all surfaces (collision estimate, per batch; with
    non-Lambertian materials of the flux arriving on them, the nodes' weights).
    """
    scene = store.scene
    if scene.views:
        view = scene.views[0]
        factor = max(1, math.ceil(max(view.projection.shape) / _ERROR_VIEW_SIDE))
        proj = view.projection.binned(factor) if factor > 1 else view.projection
        renderer = render_local_estimate_materials if store.materials else render_local_estimate
        lmap = renderer(store, proj, position=view.position, rotation=view.rotation, seed=store.seed,
                        nodes_per_pixel=_ERROR_VIEW_NODES)
        return lmap.provenance["achieved_relative_error"], "field-mean luminance of view " + repr(view.name)
    total = np.zeros(store.batches)
    surf = store.depth > 0
    np.add.at(total, store.batch[surf], store.coefficient[surf])
    rel = total.std(ddof=1) / math.sqrt(store.batches) / total.mean() if total.mean() > 0 else 0.0
    return float(rel), "surface-incident flux" if store.materials else "area-mean reflected exitance"


class ChainRun:
    """Light chains added to one store in rounds: round k traces the next blocks of chains.

    Chain i always uses the same random stream (:func:`~lsadphoto.solver.chains.trace_chains`),
    so a run grown in rounds to N chains holds exactly the chains of one run of N chains: rounds
    cost no more than the final run alone. Options as :func:`simulate`'s (checked there).
    """

    def __init__(self, scene, *, seed, max_depth, near_field, absorption, batches, progress=None,
                 fresnel_rule="reciprocal"):
        self.scene, self.seed, self.max_depth, self.fresnel_rule = scene, seed, max_depth, fresnel_rule
        self.near_field, self.absorption, self.batches = near_field, absorption, batches
        self.engine = engine_for(scene)
        self.sampler = EmissionSampler(scene)
        self.store = None
        self.blocks = 0
        self.started = time.perf_counter()
        self._progress = progress

    @property
    def chains(self):
        """Chains traced so far."""
        return self.blocks * CHAIN_BLOCK

    def grow(self, chains):
        """Trace chains until at least ``chains`` are held (whole blocks); return the store."""
        blocks = max(1 if self.store is None else 0, math.ceil(chains / CHAIN_BLOCK) - self.blocks)
        if blocks:
            done, planned = self.blocks, self.blocks + blocks

            def report(k):
                if self._progress is not None:
                    frac = min(1.0, (done + k) / planned)
                    elapsed = time.perf_counter() - self.started
                    self._progress(frac, elapsed * (1 - frac) / frac if frac > 0 else float("nan"))

            common = {"seed": self.seed, "first_block": self.blocks, "blocks": blocks, "batches": self.batches,
                      "max_depth": self.max_depth, "sampler": self.sampler, "progress": report}
            if self.scene.lambertian:
                part = trace_chains(self.scene, self.engine, absorption=self.absorption, **common)
            else:
                part = trace_material_chains(self.scene, self.engine, fresnel_rule=self.fresnel_rule, **common)
            part.fresnel_rule = self.fresnel_rule
            if self.store is None:
                self.store = part
            else:
                self.store.extend(part)
            self.blocks += blocks
        self.store.near_field = self.near_field
        return self.store

    def provenance(self, arguments, **results):
        """The store's provenance: the call's ``arguments``, the run's settings and ``results``."""
        store = self.store
        return {
            **build_provenance(arguments=arguments),
            "solver": "lsadphoto.solver", "version": __version__,
            "chains": int(store.chains), "batches": self.batches, "seed": int(self.seed),
            "max_depth": self.max_depth, "absorption": self.absorption, "fresnel_rule": self.fresnel_rule,
            "nodes": int(store.nodes),
            "total_flux_lm": float(self.scene.total_flux),
            "simulation_time_s": time.perf_counter() - self.started, **results,
        }


def check_simulation_options(scene, *, near_field, absorption, batches, max_depth, samples,
                             fresnel_rule="reciprocal"):
    """One-line errors for the options of :func:`simulate` (and of renders that simulate)."""
    if not isinstance(scene, Scene):
        raise BadInputError("simulate needs a Scene (see load_scene)")
    check_choice(near_field, "near_field", NEAR_FIELD_TREATMENTS)
    check_choice(fresnel_rule, "fresnel_rule", FRESNEL_RULES)
    check_choice(absorption, "absorption", ABSORPTION_MODES)
    if not scene.lambertian and (near_field != "unbiased" or absorption != "weight"):
        raise BadInputError("scenes with non-Lambertian materials simulate with near_field='unbiased' and "
                            "absorption='weight' only (the material chains and local estimate)")
    if int(batches) != batches or batches < 8 or CHAIN_BLOCK % int(batches):
        raise BadInputError(f"batches must be a divisor of {CHAIN_BLOCK} and at least 8, got {batches}")
    if max_depth is not None and (int(max_depth) != max_depth or max_depth < 1):
        raise BadInputError(f"max_depth must be a positive integer, got {max_depth!r}")
    if samples is not None and (int(samples) != samples or samples < 1):
        raise BadInputError(f"samples must be a positive integer, got {samples!r}")


def simulate(scene, *, samples=None, target_error=None, seed=0, max_depth=None,
             near_field="unbiased", absorption="weight", batches=DEFAULT_BATCHES,
             max_samples=MAX_CHAINS, progress=None, fresnel_rule="reciprocal"):
    """Trace light chains from the luminaires of ``scene``; return an :class:`LsadStore`.

    In a scene with glossy, specular or transmitting materials the chains sample the BSDFs
    (:func:`~lsadphoto.solver.chains.trace_material_chains`) and the store holds what the
    material local estimate needs (the nodes' incoming directions and sides, the scene's
    materials); such scenes take ``near_field="unbiased"`` and ``absorption="weight"`` only.

    Parameters
    ----------
    scene : Scene
    samples : int, optional
        Number of light chains (rounded up to a multiple of 256). Default 65 536, or the
        first round of a ``target_error`` run.
    target_error : float, optional
        Relative standard error [–] of the field-mean luminance of the scene's first view
        (rendered at ≤ 24 px per side; without views, of the area-mean reflected exitance)
        to reach: chains are added in rounds until it is reached or ``max_samples`` is.
    seed : int
        Root of all random streams; chain i always uses the same stream, so a run of
        N chains equals the first N chains of any longer run.
    max_depth : int, optional
        Largest number of bounces (biased truncation); default unlimited (Russian
        roulette ends the chains).
    near_field : {"unbiased", "clamp"}
        Default near-field treatment of renders from this store.
    absorption : {"weight", "roulette"}
        How chains account for absorption (:func:`~lsadphoto.solver.chains.trace_chains`).
    batches : int
        Independent batches (8 … 256, a divisor of 256).
    max_samples : int
        Cap on chains for ``target_error`` runs; when it stops a run before the target is
        reached, a :class:`~lsadphoto.solver.SolverWarning` gives the achieved error (also
        in the provenance, ``target_reached = False``).
    progress : callable, optional
        ``progress(done_fraction, eta_s)``.
    fresnel_rule : {"reciprocal", "radiance"}
        Where the diffuse part of smooth plastic, metal and trans (roughness 0, specularity
        ≥ 0.018) takes the factor 1 − F(μ_i) of the arriving light
        (:data:`~lsadphoto.solver.materials.FRESNEL_RULES`): ``"reciprocal"`` (default), on all
        light — a reciprocal BRDF, the physically consistent model; ``"radiance"``, only on
        light straight from a light source of Radiance's direct calculation, as Radiance
        renders the same scene file. Recorded in the store (and its provenance); renders from
        the store use it. No effect on scenes without such materials.

    Returns
    -------
    LsadStore
        With provenance: chains, seed, max_depth, wall time, and (for ``target_error``)
        the achieved relative error and how it was estimated.

    References
    ----------
    Budak, Zheltov & Kalakutsky (2012); Marchuk et al. (1980), ch. 2–3.
    """
    check_simulation_options(scene, near_field=near_field, absorption=absorption, batches=batches,
                             max_depth=max_depth, samples=samples, fresnel_rule=fresnel_rule)
    batches = int(batches)
    if target_error is not None and not (MIN_TARGET_ERROR <= float(target_error) < 1):
        raise BadInputError(f"target_error must be a relative error from {MIN_TARGET_ERROR:g} to below 1, "
                            f"got {target_error!r}")
    first = samples if samples is not None else (16_384 if target_error is not None else DEFAULT_CHAINS)
    run = ChainRun(scene, seed=seed, max_depth=max_depth, near_field=near_field,
                   absorption=absorption, batches=batches, progress=progress, fresnel_rule=fresnel_rule)
    max_chains = max(math.ceil(first / CHAIN_BLOCK), int(max_samples) // CHAIN_BLOCK) * CHAIN_BLOCK
    achieved, measured = None, None
    store = run.grow(first)
    while target_error is not None:
        achieved, measured = _error_estimate(store)
        if not achieved > target_error or run.chains >= max_chains:
            break
        store = run.grow(min(max_chains, math.ceil(run.chains * (achieved / target_error) ** 2 * 1.1)))
    store.provenance = run.provenance(
        {"samples": samples, "target_error": target_error, "seed": seed, "max_depth": max_depth,
         "near_field": near_field, "absorption": absorption, "batches": batches,
         "max_samples": max_samples, "fresnel_rule": fresnel_rule},
        target_error=target_error, achieved_relative_error=achieved, error_measured_on=measured,
        target_reached=None if target_error is None else bool(achieved <= target_error))
    if target_error is not None and not achieved <= target_error:
        warnings.warn(f"target_error {target_error:g} not reached: achieved {achieved:.3g} "
                      f"with {store.chains} chains (max_samples = {int(max_samples)}; "
                      f"{measured})", SolverWarning, stacklevel=2)
    if progress is not None:
        progress(1.0, 0.0)
    return store
