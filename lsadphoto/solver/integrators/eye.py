"""What every view estimator shares: eye rays and the map they make.

A view is a camera pose (position, camera-to-world rotation) and a
:class:`~lsadphoto.geometry.base.Projection`. Every estimator — the double local estimate
(:mod:`.local_estimate`), the surface cache (:mod:`.surface_cache`) and the path tracer
(:mod:`.path_tracer`) — traces the same primary rays through the pixel centres, adds what
the eye sees directly (luminous surfaces, the luminous openings of point luminaires), runs
its per-pixel work in chunks of whole random-stream blocks, and turns per-batch pixel values
into a :class:`~lsadphoto.luminance_map.LuminanceMap` with per-pixel standard errors and the
view's pose in its provenance.
"""

import math
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from ..._compiled import njit

from ..._provenance import build_provenance
from ...errors import BadInputError, SolverWarning
from ...geometry.base import Projection
from ...luminance_map import LuminanceMap
from .._sampling import cosine_directions
from ..sky import background_luminance

__all__ = ["PIXEL_BLOCK", "ChunkHits", "check_pose", "chunk_hits", "chunk_size", "emitted_luminance", "luminance_map_from_batches",
           "luminous_openings", "near_step", "pixel_solid_angles", "primary_rays", "run_chunks", "view_pose",
           "warn_odd_view"]

#: Pixels per random-stream block of a render; pixel chunks are whole blocks.
PIXEL_BLOCK = 256


def check_pose(position, rotation):
    try:
        pos = np.asarray(position, dtype=float)
        rot = np.asarray(rotation, dtype=float)
    except (TypeError, ValueError):
        raise BadInputError("position must be 3 numbers and rotation a 3×3 matrix") from None
    if pos.shape != (3,) or not np.all(np.isfinite(pos)):
        raise BadInputError(f"position must be 3 finite numbers, got {position!r}")
    if rot.shape != (3, 3) or not np.allclose(rot.T @ rot, np.eye(3), atol=1e-6):
        raise BadInputError("rotation must be a 3×3 orthonormal camera-to-world matrix "
                            "(see camera_to_world)")
    return pos, rot


def primary_rays(scene, engine, projection, position, rotation):
    """Valid pixel indices, their hit triangle (−1: miss), distance [m] and world direction."""
    if not isinstance(projection, Projection):
        raise BadInputError("projection must be a lsadphoto.geometry Projection")
    rows, cols = projection.pixel_grid()
    d_cam = projection.directions(rows, cols).reshape(-1, 3)
    valid = np.flatnonzero(np.all(np.isfinite(d_cam), axis=1))
    d = d_cam[valid] @ rotation.T
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    prim, dist = engine.closest_hit(np.broadcast_to(position, d.shape), d)
    return valid, prim, dist, d


@dataclass(frozen=True)
class ChunkHits:
    """The primary hits of one chunk of pixels: what every estimator starts from.

    ``index``: positions in the view's hit list (pixels along the valid-pixel order);
    ``triangle``, ``point`` [m], ``normal`` (the side facing the eye), ``front`` (whether that
    is the triangle's front side), ``reflectance`` and ``emitted`` (luminance towards the eye
    [cd·m⁻²]) per hit; ``block`` the random-stream block of each hit.
    """

    index: np.ndarray
    triangle: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    front: np.ndarray
    reflectance: np.ndarray
    emitted: np.ndarray
    block: np.ndarray


def chunk_size(chunk_pixels):
    """Pixels per processing chunk: ``chunk_pixels`` rounded up to whole stream blocks."""
    return max(PIXEL_BLOCK, math.ceil(chunk_pixels / PIXEL_BLOCK) * PIXEL_BLOCK)


def chunk_hits(scene, position, hit, prim, dist, d, start, chunk):
    """:class:`ChunkHits` of the hits ``hit[start:start + chunk]`` of rays from ``position``
    along ``d`` that hit triangles ``prim`` at distances ``dist`` (:func:`primary_rays`)."""
    h = hit[start:start + chunk]
    t = prim[h]
    normal, front = scene.facing_normals(t, d[h])
    return ChunkHits(h, t, position + dist[h, None] * d[h], normal, front,
                     scene.triangle_reflectance[t], emitted_luminance(scene, t, -d[h]),
                     (start + np.arange(h.size)) // PIXEL_BLOCK)


#: Primary hits closer than this many ray offsets count as "the eye lies on a surface".
_ON_SURFACE_OFFSETS = 10
#: … and the view is flagged when more than this fraction of its hits are that close.
_ON_SURFACE_FRACTION = 0.01


def warn_odd_view(scene, engine, prim, dist, lum_b, position, *, openings=None, stacklevel=3):
    """Warn about views that are legal but probably wrong (an eye on or in a wall).

    An eye within a few ray offsets of a surface (in the plane of a wall) makes the rays
    that start there ambiguous in float32; an eye outside a closed room or inside a solid
    sees only surfaces that no light reaches, so the whole view is black: no value of
    ``lum_b`` (valid pixels × batches) is positive and no luminous opening
    (:func:`luminous_openings`, ``openings``: finite where one is seen) is in view. ``stacklevel``
    is :func:`warnings.warn`'s as seen from this function (3: the caller of the estimator
    that calls it).
    """
    hit = prim >= 0
    close = hit & (dist < _ON_SURFACE_OFFSETS * engine.epsilon)
    where = f"eye at ({', '.join(f'{v:g}' for v in position)}) m"
    if hit.any() and close.sum() > _ON_SURFACE_FRACTION * hit.sum():
        warnings.warn(f"{where} lies on a surface ({close.sum()} of {hit.sum()} primary rays "
                      f"hit within {_ON_SURFACE_OFFSETS * engine.epsilon:.2g} m): move it into "
                      "the room", SolverWarning, stacklevel=stacklevel)
    elif (scene.total_flux > 0 and np.any(scene.triangle_reflectance[prim[hit]] > 0)
          and not (openings is not None and np.isfinite(openings).any()) and not np.any(lum_b > 0)):
        # (a view that hits nothing, e.g. out of an open model into the sky, or only black
        # surfaces, is legal and black)
        warnings.warn(f"{where} sees surfaces but no light at all: is it outside the room "
                      "or inside a solid?", SolverWarning, stacklevel=stacklevel)


def emitted_luminance(scene, prim, towards):
    """Luminance [cd·m⁻²] that triangles ``prim`` emit towards unit directions ``towards``."""
    out = np.zeros(len(prim))
    em = scene.emitter[prim]
    for k, lum in enumerate(scene.area_luminaires):
        m = em == k
        if m.any():
            front = np.einsum("ij,ij->i", scene.normals[prim[m]], towards[m]) > 0
            out[m] = np.where(front, lum.luminance(scene), 0.0)
    return out


@njit(cache=True, error_model="numpy", nogil=True,
      aot="int64(float64[::1], float64[:, ::1], float64[::1], float64[:, ::1], float64[:, :, ::1], "
          "float64[:, ::1], int64[::1], int64[::1], float64[::1], float64[::1])")
def _opening_crossings(position, d, dist, centre, frame, half, ray, lum, t_out, denom_out):
    """The crossings of rays (origin ``position``, directions ``d``) with the luminous
    rectangles (``centre``, ``frame`` rows: the rectangle's axes and its normal, ``half``:
    half its length and width) in front of the rays' surface hits (``dist``): ray, rectangle,
    distance and d·normal of each, in rectangle order, written to the output arrays; returns
    their count, or −(count) where it exceeds the arrays' size (nothing valid then)."""
    cap = ray.size
    m = 0
    for k in range(centre.shape[0]):
        nx, ny, nz = frame[k, 2, 0], frame[k, 2, 1], frame[k, 2, 2]
        num = ((centre[k, 0] - position[0]) * nx + (centre[k, 1] - position[1]) * ny
               + (centre[k, 2] - position[2]) * nz)
        for i in range(d.shape[0]):
            denom = d[i, 0] * nx + d[i, 1] * ny + d[i, 2] * nz
            if not abs(denom) > 1e-6:
                continue
            t = num / denom
            if not (t > 0 and t < dist[i]):
                continue
            hx = position[0] + t * d[i, 0] - centre[k, 0]
            hy = position[1] + t * d[i, 1] - centre[k, 1]
            hz = position[2] + t * d[i, 2] - centre[k, 2]
            if (abs(hx * frame[k, 0, 0] + hy * frame[k, 0, 1] + hz * frame[k, 0, 2]) <= half[k, 0]
                    and abs(hx * frame[k, 1, 0] + hy * frame[k, 1, 1] + hz * frame[k, 1, 2]) <= half[k, 1]):
                if m < cap:
                    ray[m], lum[m], t_out[m], denom_out[m] = i, k, t, denom
                m += 1
    return m if m <= cap else -m


def luminous_openings(scene, position, d, dist):
    """Luminance [cd·m⁻²] of point luminaires' luminous rectangles seen along rays.

    For a luminaire with a rectangle of area A (extent > 0) whose plane (normal = nadir
    axis) the ray crosses inside the rectangle and before its surface hit, the opening's
    luminance towards the eye is L = I(−d̂)/(A·|cos γ|), the radiance of emission points
    uniform on the rectangle that each emit I/A (the chains' emission model). NaN where
    no opening is seen (or it emits nothing towards the eye); the nearest opening wins.
    Rays that hit nothing see the distant sources (:func:`~lsadphoto.solver.sky.background_luminance`).
    """
    out = np.full(len(d), np.nan)
    dist = np.asarray(dist, float)
    if scene.distant_sources:  # rays that leave the scene see the sun and the sky
        away = np.flatnonzero(~np.isfinite(dist))
        sky = background_luminance(scene, d[away])
        out[away[sky > 0]] = sky[sky > 0]
    lums = [lum for lum in scene.point_luminaires if lum.extent[0] > 0 and lum.extent[1] > 0]
    if not lums or not len(d):
        return out
    centre = np.array([lum.position for lum in lums], dtype=float)
    frame = np.array([lum.frame for lum in lums], dtype=float)
    half = np.array([lum.extent for lum in lums], dtype=float) / 2
    args = (np.asarray(position, float), np.ascontiguousarray(d, dtype=float), dist, centre, frame, half)
    size = 1024
    while True:  # one pass over rays × rectangles; again, larger, if the crossings overflow
        ray, k, t, denom = np.empty(size, np.int64), np.empty(size, np.int64), np.empty(size), np.empty(size)
        m = _opening_crossings(*args, ray, k, t, denom)
        if m >= 0:
            break
        size = -m
    ray, k, t, denom = ray[:m], k[:m], t[:m], denom[:m]
    value = np.zeros(m)
    for j in np.unique(k):
        sel = np.flatnonzero(k == j)
        lum = lums[j]
        value[sel] = lum.intensity(-d[ray[sel]]) / (lum.extent[0] * lum.extent[1] * np.abs(denom[sel]))
    # per ray the nearest opening that emits towards the eye (equal distances: the first)
    seen = np.flatnonzero(value > 0)
    order = seen[np.lexsort((k[seen], t[seen], ray[seen]))]
    first = order[np.r_[True, ray[order][1:] != ray[order][:-1]]] if order.size else order
    out[ray[first]] = value[first]
    return out


def near_step(scene, engine, x, nx, u, near_distance, rho_prev):
    """One bounce of near-field paths from points ``x`` (normals ``nx``), uniforms ``u`` (k, 3).

    A cosine-distributed ray from each point; a path goes on where its first hit lies closer
    than ``near_distance`` and, after the first bounce (``rho_prev`` given), it survives
    Russian roulette with q = ρ of the vertex it leaves (weight ρ/q = 1). Returns the mask
    of the paths that go on and, for those, the hit point, its facing normal, the ray
    direction and the triangle.
    """
    d = cosine_directions(nx, u[:, :2])
    prim, dist = engine.closest_hit(x + engine.epsilon * nx, d)
    near = (prim >= 0) & (dist < near_distance)
    if rho_prev is not None:
        near &= u[:, 2] < rho_prev
    x, nx, d, prim, dist = x[near], nx[near], d[near], prim[near], dist[near]
    y = x + engine.epsilon * nx + dist[:, None] * d
    ny, _ = scene.facing_normals(prim, d)
    return near, y, ny, d, prim



def run_chunks(work, starts, lum_b, workers, progress, t0, total, *, meanwhile=None):
    """Run ``work(start) -> (pixel indices, values)`` for every chunk, in threads if asked.

    Each chunk draws only from its own pixel blocks' streams, so the result is the same
    for any number of workers (and any completion order). ``meanwhile()``, if given, runs on
    the calling thread while the workers run the chunks (serial work that the chunks do not
    need, which would otherwise wait for them); its result is returned.
    """
    starts = list(starts)
    done = 0

    def report(n):
        nonlocal done
        done += n
        if progress is not None:
            frac = min(1.0, done / max(total, 1))
            elapsed = time.perf_counter() - t0
            progress(frac, elapsed * (1 - frac) / frac if frac > 0 else float("nan"))

    if workers <= 1 or len(starts) <= 1:
        extra = meanwhile() if meanwhile is not None else None
        for start in starts:
            h, values = work(start)
            lum_b[h] = values
            report(h.size)
        return extra
    with ThreadPoolExecutor(max_workers=workers) as pool:
        results = pool.map(work, starts)  # every chunk is submitted here
        extra = meanwhile() if meanwhile is not None else None
        for h, values in results:
            lum_b[h] = values
            report(h.size)
    return extra


def pixel_solid_angles(projection, valid):
    """Solid angles [sr] of the pixels ``valid`` (flat indices) of ``projection``."""
    return projection.solid_angles(*np.unravel_index(valid, projection.shape))


def view_pose(position, rotation):
    """The world pose of a camera as Radiance view vectors: ``{"vp", "vd", "vu"}``.

    ``vd`` is the optical axis (camera +z) and ``vu`` the image's up (camera −y, rows run
    down), both in world coordinates; Radiance's ``-vp``/``-vd``/``-vu``.
    """
    r = np.asarray(rotation, dtype=float)
    return {"vp": [float(v) for v in position], "vd": [float(v) for v in r[:, 2]],
            "vu": [float(v) for v in -r[:, 1]]}


def luminance_map_from_batches(projection, valid, lum_b, *, model, estimator, extra, elapsed,
                               pose, openings=None, shared_variance=None, bias=None,
                               bias_variance=None, solid_angles=None):
    """The LuminanceMap of per-batch pixel values ``lum_b`` (valid pixels × batches).

    ``model`` is the store or scene rendered (its scene's name is recorded); ``pose`` =
    (position, rotation) of the camera: recorded as ``provenance["view_pose"]``
    (:func:`view_pose`), so the Radiance HDR writer gives the rendered view's ``VIEW=`` line.

    ``solid_angles`` [sr] (per valid pixel; default :func:`pixel_solid_angles`) may come
    precomputed. ``shared_variance`` (per valid pixel) is the variance of a component that all batches
    share (added to the batches' squared standard error; independent between pixels).

    ``bias`` (per valid pixel, signed, cd·m⁻²) is an estimated systematic error of the
    estimator and ``bias_variance`` its estimate's own sampling variance (both None: an
    unbiased estimator). The map's uncertainty is then σ_total = √(σ_noise² + b²), b² =
    max(bias² − bias_variance, 0) (an unbiased estimate of the squared bias); the provenance
    keeps the noise part (``pixel_relative_noise_*``) and the bias part
    (``pixel_relative_bias_*``) apart, and the field mean's signed bias estimate.

    Over the pixels with light the provenance gives the median and 95th percentile of the
    relative uncertainty σ/L (``pixel_relative_error_median``, ``_p95``) and the mean absolute
    relative error that σ implies, √(2/π)·mean(σ/L)
    (``pixel_relative_error_expected_mean_absolute``; the mean |x| of a Gaussian error of σ is
    √(2/π)·σ).
    """
    rows, cols = projection.shape
    shared = np.zeros(len(valid)) if shared_variance is None else shared_variance
    if openings is not None:
        seen = np.isfinite(openings)
        lum_b[seen] = openings[seen, None]  # luminous openings in front of the surfaces
        shared[seen] = 0.0
    B = lum_b.shape[1]
    mean = lum_b.mean(axis=1)
    noise = np.sqrt(lum_b.var(axis=1, ddof=1) / B + shared)
    b2 = np.zeros(len(valid))
    if bias is not None:
        if openings is not None:
            bias = np.where(seen, 0.0, bias)
            bias_variance = np.where(seen, 0.0, bias_variance)
        b2 = np.maximum(bias ** 2 - bias_variance, 0.0)
    se = np.sqrt(noise ** 2 + b2)
    lum = np.full(rows * cols, np.nan)
    unc = np.full(rows * cols, np.nan)
    lum[valid] = mean
    unc[valid] = se
    omega = pixel_solid_angles(projection, valid) if solid_angles is None else solid_angles
    field_b = (omega[:, None] * lum_b).sum(axis=0) / omega.sum()
    field_mean = float(field_b.mean())
    field_se = float(math.sqrt(field_b.var(ddof=1) / B + (omega ** 2 * shared).sum() / omega.sum() ** 2))
    with np.errstate(divide="ignore", invalid="ignore"):
        rel, rel_noise, rel_bias = se / mean, noise / mean, np.sqrt(b2) / mean
    lit = (mean > 0) & np.isfinite(rel)

    def quantiles(name, v):
        v = v[lit]
        return {f"pixel_relative_{name}_median": float(np.median(v)) if v.size else float("nan"),
                f"pixel_relative_{name}_p95": float(np.percentile(v, 95)) if v.size else float("nan")}

    # the per-pixel relative uncertainties (of pixels with light), which the field mean's error
    # understates by orders of magnitude: the total (the map's uncertainty) and, for a biased
    # estimator, its noise and bias parts and the field mean's signed relative bias estimate
    parts = {} if bias is None else {
        **quantiles("noise", rel_noise), **quantiles("bias", rel_bias),
        # their means: which of the two holds the mean absolute error that a target bounds
        "pixel_relative_noise_mean": float(np.mean(rel_noise[lit])) if lit.any() else float("nan"),
        "pixel_relative_bias_mean": float(np.mean(rel_bias[lit])) if lit.any() else float("nan"),
        "field_mean_relative_bias_estimate": float((omega * bias).sum() / omega.sum() / field_mean)
        if field_mean > 0 else float("nan")}

    provenance = {
        **build_provenance(),
        "solver": "lsadphoto.solver",
        "estimator": estimator,
        "batches": int(B),
        "field_mean_luminance": field_mean,
        "field_mean_standard_error": field_se,
        "achieved_relative_error": field_se / field_mean if field_mean > 0 else float("nan"),
        **quantiles("error", rel),
        # what a target on the per-pixel error bounds (rendering.render's target_error): the
        # mean absolute relative error to expect, √(2/π)·σ for a Gaussian error of σ
        "pixel_relative_error_expected_mean_absolute": float(math.sqrt(2 / math.pi) * np.mean(rel[lit]))
        if lit.any() else float("nan"),
        **parts,
        "render_time_s": float(elapsed),
        "scene": model.scene.name if hasattr(model, "scene") else model.name,
        "view_pose": view_pose(*pose),
    }
    provenance.update(extra)
    return LuminanceMap(lum.reshape(rows, cols).astype(np.float32),
                        uncertainty=unc.reshape(rows, cols).astype(np.float32),
                        projection=projection, calibrated=True, provenance=provenance)
