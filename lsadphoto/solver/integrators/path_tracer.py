"""Path tracing from the eye with next-event estimation: the independent cross-check.

A conventional estimator that shares no code with the light chains' double local estimate
but the ray engine, the emission sampler and the eye rays (:mod:`.eye`), so agreement of the
two within their standard errors checks both (tests/test_solver_accuracy.py).

References
----------
Kajiya, J. T. (1986). The rendering equation. *SIGGRAPH '86*, 143–150. Veach, E. (1997).
*Robust Monte Carlo Methods for Light Transport Simulation*, PhD thesis, Stanford, ch. 10.
"""

import math
import time

import numpy as np

from ..._validation import check_choice
from ...errors import BadInputError
from .._sampling import GroupStreams, cosine_directions, stream
from ..chains import KIND_DISTANT, EmissionSampler
from ..engine import engine_for
from ..materials import FRESNEL_RULES, shadow_transmittance
from ..scene import Scene
from ..sky import background_luminance
from ..store import KIND_COSINE, KIND_POINT
from .eye import (PIXEL_BLOCK, check_pose, chunk_hits, chunk_size, emitted_luminance,
                  luminance_map_from_batches, luminous_openings, primary_rays, run_chunks,
                  warn_odd_view)

__all__ = ["render_path_traced"]


def render_path_traced(scene, projection, *, position, rotation, samples=64, seed=0, batches=16,
                       max_depth=None, chunk_pixels=1024, workers=1, progress=None, fresnel_rule="reciprocal"):
    """Luminance map by path tracing from the eye with next-event estimation [cd·m⁻²].

    A conventional, independent estimator for cross-checks of :func:`render`: from the
    point x_p seen through each pixel centre, ``samples`` paths per pixel (split into
    ``batches`` independent batches for the standard errors); at every vertex the direct
    illuminance is estimated by sampling one luminaire point in proportion to flux (the
    same distribution as the light chains' sources) with a shadow ray; the path continues
    in a cosine-distributed direction with Russian-roulette probability ρ. Emission found
    by the continuation rays is not counted (next-event estimation covers it), so no
    multiple importance sampling is needed for unbiasedness.

    Parameters are those of :func:`~lsadphoto.solver.render` (``scene`` instead of a store), plus
    ``samples`` (paths per pixel, a multiple of ``batches``), ``batches`` (≥ 2) and
    ``max_depth`` (bounce limit, biased; default unlimited) and ``fresnel_rule``
    (:data:`~lsadphoto.solver.materials.FRESNEL_RULES`: under ``"radiance"`` the next-event
    estimates of Radiance's light sources take the smooth materials' factor 1 − F(μ_i), the
    continuation rays do not). Returns a
    :class:`~lsadphoto.luminance_map.LuminanceMap` [cd·m⁻²] with per-pixel standard errors.

    References
    ----------
    Kajiya, J. T. (1986). The rendering equation. *SIGGRAPH '86*. Veach (1997), §10.
    """
    if not isinstance(scene, Scene):
        raise BadInputError("render_path_traced needs a Scene")
    if int(workers) != workers or workers < 1:
        raise BadInputError(f"workers must be a positive integer, got {workers!r}")
    workers = int(workers)
    check_choice(fresnel_rule, "fresnel_rule", FRESNEL_RULES)
    position, rotation = check_pose(position, rotation)
    samples = int(samples)
    batches = int(batches)
    if batches < 2 or samples < batches or samples % batches:
        raise BadInputError(f"samples ({samples}) must be a positive multiple of batches ({batches} ≥ 2)")
    per_batch = samples // batches
    engine = engine_for(scene)
    sampler = EmissionSampler(scene)
    limit = 10_000 if max_depth is None else int(max_depth)
    t0 = time.perf_counter()
    valid, prim, dist, d = primary_rays(scene, engine, projection, position, rotation)
    hit = np.flatnonzero(prim >= 0)
    lum_b = np.zeros((valid.size, batches))
    eps = engine.epsilon
    chunk = chunk_size(chunk_pixels)

    def work(start):
        c = chunk_hits(scene, position, hit, prim, dist, d, start, chunk)
        h, t, x0, n0, emitted = c.index, c.triangle, c.point, c.normal, c.emitted
        # paths ordered by (batch, pixel block, pixel, sample); one stream per (batch, block)
        local_block = np.arange(h.size) // PIXEL_BLOCK
        n_blocks = int(local_block[-1]) + 1
        j0 = start // PIXEL_BLOCK
        pix = np.tile(np.repeat(np.arange(h.size), per_batch), batches)
        path_batch = np.repeat(np.arange(batches), h.size * per_batch)
        group = path_batch * n_blocks + local_block[pix]
        streams = GroupStreams([stream(seed, "path", b, j0 + jl)
                                 for b in range(batches) for jl in range(n_blocks)])
        acc = np.zeros(pix.size)
        alive = np.arange(pix.size)
        x, nx, tri = x0[pix], n0[pix], t[pix]
        if scene.bsdf is not None:
            _trace_materials(scene, engine, sampler, streams, group, acc, x, nx, c.front[pix], tri,
                             -d[h][pix], limit, fresnel_rule)
            return h, emitted[:, None] + acc.reshape(batches, h.size, per_batch).mean(axis=2).T
        depth = 0
        while alive.size and depth < limit:
            streams.counts = np.bincount(group[alive], minlength=len(streams.gens))
            rho = scene.triangle_reflectance[tri]
            # next-event estimation
            src, w, r2, cos_x, is_cos, g = _light_sample(sampler, streams, x, nx)
            ok = (cos_x > 0) & (g > 0) & (rho > 0)
            if ok.any():
                tgt = src["position"][ok] + eps * src["normal"][ok] * is_cos[ok, None]
                vis = engine.visible(x[ok] + eps * nx[ok], tgt)
                acc[alive[ok]] += (rho[ok] / math.pi * src["coefficient"][ok] * g[ok] * cos_x[ok]
                                   / r2[ok] * vis)
            # continuation
            u = streams.random((alive.size, 3))
            go = u[:, 0] < rho
            depth += 1
            alive, x, nx, u = alive[go], x[go], nx[go], u[go]
            if not alive.size:
                break
            dirs = cosine_directions(nx, u[:, 1:])
            p2, d2 = engine.closest_hit(x + eps * nx, dirs)
            ok = p2 >= 0
            alive, x, nx, dirs, p2, d2 = alive[ok], x[ok], nx[ok], dirs[ok], p2[ok], d2[ok]
            x = x + eps * nx + d2[:, None] * dirs
            nx, _ = scene.facing_normals(p2, dirs)
            tri = p2
        return h, emitted[:, None] + acc.reshape(batches, h.size, per_batch).mean(axis=2).T

    run_chunks(work, range(0, hit.size, chunk), lum_b, workers, progress, t0, hit.size)
    openings = luminous_openings(scene, position, d, dist)
    warn_odd_view(scene, engine, prim, dist, lum_b, position, openings=openings)
    return luminance_map_from_batches(
        projection, valid, lum_b, model=scene, estimator="path tracing (NEE)",
        openings=openings,
        extra={"samples": samples, "samples_per_pixel": samples, "seed": int(seed),
               "near_field": "none (path tracing)", "near_field_biased": False,
               "max_depth": max_depth, "fresnel_rule": fresnel_rule},
        elapsed=time.perf_counter() - t0, pose=(position, rotation))


def _light_sample(sampler, streams, x, nx):
    """One emission point per path vertex ``x`` (normals ``nx``) for next-event estimation:
    the source nodes, the unit direction w towards them, the squared distance r2 [m²],
    cos θ at the vertex (n·w), whether each is a cosine (Lambertian) emitter, and the
    emitter's factor g — cos θ at a Lambertian emitter, the intensity [cd] of a point
    luminaire towards the vertex, the weight L/(p·K) of a distant source's direction (then
    r2 = 1 and the node's position is a far point along it)."""
    src = sampler.sample(streams, len(x))
    v = src["position"] - x
    r2 = np.einsum("ij,ij->i", v, v)
    w = v / np.sqrt(r2)[:, None]
    cos_x = np.einsum("ij,ij->i", w, nx)
    is_cos = src["kind"] == KIND_COSINE
    g = np.where(is_cos, -np.einsum("ij,ij->i", w, src["normal"]), 0.0)
    pt = np.flatnonzero(src["kind"] == KIND_POINT)
    if pt.size:
        g[pt] = sampler.point_intensity(src["luminaire"][pt], -w[pt])
    far = np.flatnonzero(src["kind"] == KIND_DISTANT)
    if far.size:
        # a direction ω towards a distant source: no distance (r² = 1), g = L/(p·K), and
        # the shadow ray's target beyond the bounding sphere along ω
        w[far] = src["direction"][far]
        r2[far] = 1.0
        cos_x[far] = np.einsum("ij,ij->i", w[far], nx[far])
        g[far] = src["factor"][far]
        src["position"][far] = x[far] + (4 * sampler.scene.sphere[1] + 1.0) * w[far]
    return src, w, r2, cos_x, is_cos, g


def _trace_materials(scene, engine, sampler, streams, group, acc, x, nx, front, tri, wo, limit, rule):
    """Add to ``acc`` the luminance of paths from points ``x`` (normals ``nx`` facing ``wo``,
    on the triangles' front side where ``front``, triangles ``tri``) in a scene with
    non-Lambertian materials (``scene.bsdf``).

    At each vertex: next-event estimation with the BSDF's non-delta part f(ω_light, ω_o)
    (on either side of transmitting surfaces), the shadow ray passing straight-through
    transmitters with their transmittance (:func:`~lsadphoto.solver.materials.shadow_transmittance`);
    then a direction from :meth:`~lsadphoto.solver.materials.MaterialTable.sample`, survival
    with q = min(1, albedo) and weight w/q. Emission found by a continuation ray counts only
    on paths that NEE cannot reach: after a delta reflection (mirror, glass, smooth plastic),
    possibly followed by straight-through transmissions; the eye counts as such a vertex (a
    luminaire seen through glass is seen). ``rule``: the smooth materials' factor 1 − F(μ_i)
    (:data:`~lsadphoto.solver.materials.FRESNEL_RULES`) — under ``"radiance"`` on the next-event
    estimates of Radiance's light sources only, not on the continuation rays (whose emission
    counts only after deltas, where the diffuse factor plays no part).
    """
    bsdf = scene.bsdf
    eps = engine.epsilon
    alive = np.arange(len(x))
    beta = np.ones(len(x))
    count_emission = np.ones(len(x), dtype=bool)
    depth = 0
    while alive.size and depth < limit:
        streams.counts = np.bincount(group[alive], minlength=len(streams.gens))
        mat = scene.material[tri]
        src, w, r2, cos_x, is_cos, g = _light_sample(sampler, streams, x, nx)
        f = bsdf.evaluate(mat, nx, wo, w, rule=rule, direct=sampler.light_source_at(src, x))
        ok = (f > 0) & (g > 0) & (np.abs(cos_x) > 0)
        if ok.any():
            side = np.sign(cos_x[ok])[:, None]
            tgt = src["position"][ok] + eps * src["normal"][ok] * is_cos[ok, None]
            vis = shadow_transmittance(scene, engine, x[ok] + eps * side * nx[ok], tgt)
            acc[alive[ok]] += (beta[ok] * f[ok] * src["coefficient"][ok] * g[ok] * np.abs(cos_x[ok])
                               / r2[ok] * vis)
        u = streams.random((alive.size, 3))
        wi, weight, is_delta, albedo = bsdf.sample(mat, nx, wo, u, front, rule=rule, direct=False)
        q = np.minimum(albedo, 1.0)
        go = (u[:, 2] < q) & (weight > 0)
        depth += 1
        straight = is_delta & (np.einsum("ij,ij->i", wi, nx) < 0)
        count_emission = (count_emission & straight) | (is_delta & ~straight)
        alive, x, nx, wi, count_emission = alive[go], x[go], nx[go], wi[go], count_emission[go]
        beta = beta[go] * weight[go] / q[go]
        if not alive.size:
            break
        side = np.sign(np.einsum("ij,ij->i", wi, nx))[:, None]
        p2, d2 = engine.closest_hit(x + eps * side * nx, wi)
        ok = p2 >= 0
        gone = np.flatnonzero(~ok & count_emission)
        if gone.size and scene.distant_sources:  # the sky seen after a delta reflection
            acc[alive[gone]] += beta[gone] * background_luminance(scene, wi[gone])
        alive, x, nx, wi, p2, d2, beta, count_emission, side = (
            alive[ok], x[ok], nx[ok], wi[ok], p2[ok], d2[ok], beta[ok], count_emission[ok], side[ok])
        x = x + eps * side * nx + d2[:, None] * wi
        nx, front = scene.facing_normals(p2, wi)
        wo = -wi
        tri = p2
        if count_emission.any():
            seen = np.flatnonzero(count_emission)
            acc[alive[seen]] += beta[seen] * emitted_luminance(scene, p2[seen], wo[seen])
