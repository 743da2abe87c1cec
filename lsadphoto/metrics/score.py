"""Score a luminance map: every metric of the package in one pass, with its settings.

:func:`score_map` takes a :class:`~lsadphoto.LuminanceMap` with a camera projection (our EXR
maps, or Radiance pictures with a VIEW= line), builds the per-pixel geometry once (cached),
selects glare-source pixels, groups them as evalglare does and evaluates every metric of
:mod:`~lsadphoto.metrics.registry` — pixel-wise and grouped UGR, DGP, DGI, UGP, CGI, DGR/VCP,
the Q criterion, E_v, L_b — through the public functions listed there, from one set of field
sums (:func:`~lsadphoto.metrics.field.field_sums`), plus luminance statistics.

Source position: by default each source's position index is taken where evalglare 3.06
takes it, at the pixel of the source's L·ω-weighted mean *pixel position*
(:func:`~lsadphoto.metrics.grouping.position_pixel_evalglare`); ``source_position=
"direction"`` takes it at the L·ω-weighted mean *direction* instead. The two differ for
large sources in a non-gnomonic projection (the mean of pixel positions is not the image of
the mean direction): 2–3° for a window of 1–2 sr in an equidistant fisheye.

Uncertainty, two parts combined in quadrature (``uncertainty``):

* calibration (``uncertainty_calibration``): a calibrated map carries the relative standard
  uncertainty u of its calibration factor, a common scale of every pixel. Each metric is
  re-evaluated with the luminances scaled by 1 ± u (the same source pixels and groups) and
  half the difference is its standard uncertainty; for UGR-type indices 8·u/ln 10 to first
  order;
* per-pixel noise (``uncertainty_noise``), where the map has a per-pixel ``uncertainty``:
  its variance less the calibration part (:func:`noise_variance`), independent between
  pixels. Every index but Q is a function of field sums that are then jointly Gaussian with
  exactly known moments (:func:`~lsadphoto.metrics.field.noise_moments`); ``noise_samples``
  antithetic draws of them are evaluated like noisy maps. Q is evaluated on
  ``q_noise_samples`` maps L ± √v·z. The mean change over the draws is each metric's bias
  from noise (``noise_bias``): large for Q, whose gradients noise inflates. Source pixels
  and groups are held fixed; the draws come from a fixed seed (common random numbers).

Undefined values are ``None`` in :meth:`Score.to_dict` with the reason in ``notes``.
"""

import math
from dataclasses import dataclass, field, replace

import numpy as np
from .._compiled import background, njit, populate, prange, row_blocks, run_blocks

from .._provenance import build_provenance
from .._validation import check_choice, check_positive, check_positive_int
from ..errors import BadInputError
from ..geometry import ObserverFrame, position_index
from ..geometry.field import pixel_geometry, visual_field
from ..geometry.position_index import METHODS as POSITION_INDEX_METHODS
from .analyses import centre_direction, evalglare_analyses, zone_split
from .checkfile import check_checkfile_path, check_picture, write_checkfile
from .corrections import fill_rows_evalglare
from .field import BACKGROUND_METHODS, field_sums, noise_moments
from .glare_indices import dgp_coefficients as dgp_coefficients_of
from .glare_indices import dgp_Wienold2006
from .grouping import (
    DEFAULT_PEAK_LUMINANCE,
    DEFAULT_SEARCH_ANGLE,
    SOURCE_POSITIONS,
    group_sources_evalglare,
    position_pixel_evalglare,
)
from .grouping import _describe as describe_sources
from .quality import q_Budak2021, q_sweep
from .registry import evaluate_indices
from .sources import SOURCE_METHODS, select_source_pixels
from .statistics import luminance_statistics

__all__ = ["Score", "score_map"]


#: Pixels per chunk of the compiled per-pixel passes.
_CHUNK = 1 << 16


@njit(parallel=True, cache=True, error_model="numpy", nogil=True,
      aot=tuple(f"Tuple((int64, float64, float64))({L}[::1], boolean[::1], {C}[::1], "
                "float64[::1])" for L in ("float32", "float64") for C in ("float32", "float64")))
def _field_luminance_kernel(image, evaluated, cos_sigma, luminance):
    """The luminance (float64; NaN outside the valid pixels; not written where
    ``luminance`` is empty), the number of evaluated pixels that are not valid (luminance
    not finite or cos σ < 0) and the smallest and largest positive luminance of the valid
    pixels (+inf, −inf where there is none)."""
    n = image.size
    n_chunks = (n + _CHUNK - 1) // _CHUNK
    write = luminance.size == n
    dropped = 0
    ranges = np.empty((n_chunks, 2))
    for k in prange(n_chunks):
        count = 0
        lo, hi = np.inf, -np.inf
        for i in range(k * _CHUNK, min(n, (k + 1) * _CHUNK)):
            L = np.float64(image[i])
            ok = evaluated[i] & (np.abs(L) < np.inf) & (cos_sigma[i] >= 0)
            if write:
                luminance[i] = L if ok else np.nan
            count += 1 if evaluated[i] and not ok else 0
            positive = ok & (L > 0)
            lo = min(lo, L if positive else np.inf)
            hi = max(hi, L if positive else -np.inf)
        dropped += count
        ranges[k, 0] = lo
        ranges[k, 1] = hi
    lo, hi = np.inf, -np.inf
    for k in range(n_chunks):
        lo = min(lo, ranges[k, 0])
        hi = max(hi, ranges[k, 1])
    return dropped, lo, hi


@njit(parallel=True, cache=True, error_model="numpy", nogil=True,
      aot="void(float64[::1], float64[::1], boolean[::1], float64[::1])")
def _field_solid_angle_kernel(luminance, solid_angle, valid, omega):
    """Valid pixels (luminance not NaN) and their solid angle (0 elsewhere)."""
    n = luminance.size
    for k in prange((n + _CHUNK - 1) // _CHUNK):
        for i in range(k * _CHUNK, min(n, (k + 1) * _CHUNK)):
            ok = luminance[i] == luminance[i]
            valid[i] = ok
            omega[i] = solid_angle[i] if ok else 0.0


def _field_inputs(image, geometry, evaluated, cos_sigma):
    """The field: valid pixels (``evaluated``, finite luminance, cos σ ≥ 0), the luminance
    [cd·m⁻²] that the field's consumers read, the solid angle [sr] (0 off the valid pixels),
    the smallest and largest positive luminance of the valid pixels (the range of the
    statistics' histogram, :func:`~lsadphoto.metrics.statistics.luminance_statistics`, found
    in the same pass), and a function that gives the luminance as float64 with NaN off the
    valid pixels (made once, on its first call).

    Where every evaluated pixel is valid and the evaluated pixels are the geometry's valid
    ones (the usual case), the validity and solid angle are the geometry's own read-only
    maps (its solid angle is 0 where it is not valid: two full-size maps fewer to allocate
    and fault in, 9 bytes per pixel), and the luminance the consumers read is the picture
    itself: each of them takes a pixel into the field only where ω > 0 (field sums,
    statistics, Q, the selection's mean and task luminance) or reads the selected pixels
    (selection, grouping, Eglare), so the picture's values off the field are never used,
    and a float32 value read as float64 is the same number — the same sums, bit for bit,
    without a float64 copy of the picture (8 bytes per pixel: 24 MP 192 MB). The NaN map is
    made only for what reads the luminance off the field (check picture, regions,
    regrouping, zone split, per-pixel noise). (Outputs are allocated by numpy, so that its
    page advice applies to them: a ``score`` process of a large picture asks for small
    pages, which this project's virtual machine faults in 4–6 times faster than fresh huge
    pages, lsadphoto.cli.)"""
    shape = evaluated.shape
    image = np.ascontiguousarray(image)
    flat = (image.reshape(-1), np.ascontiguousarray(evaluated).reshape(-1),
            np.ascontiguousarray(cos_sigma).reshape(-1))

    def field_pass(luminance):
        """(dropped, positive range); ``luminance`` (flat) written unless empty."""
        # Blocks of whole chunks, one per thread where the ahead-of-time code runs them.
        workers = _field_luminance_kernel.threads_for(*flat, luminance)

        def block(a, b):
            out = luminance[a:b] if luminance.size else luminance
            populate(out)
            return _field_luminance_kernel(*(x[a:b] for x in flat), out)

        parts = run_blocks(block, row_blocks(flat[0].size, workers, _CHUNK), workers)
        return sum(part[0] for part in parts), (
            min((part[1] for part in parts), default=math.inf),
            max((part[2] for part in parts), default=-math.inf))

    if evaluated is geometry.valid:
        dropped, positive = field_pass(np.empty(0))
        if dropped == 0:
            made = []

            def masked():
                if not made:
                    made.append(np.empty(shape))
                    field_pass(made[0].reshape(-1))
                return made[0]

            return geometry.valid, image, geometry.solid_angle, positive, masked
    luminance = np.empty(shape)
    _, positive = field_pass(luminance.reshape(-1))
    valid = np.empty(shape, dtype=bool)
    omega = np.empty(shape)
    _field_solid_angle_kernel(luminance.reshape(-1),
                              np.ascontiguousarray(geometry.solid_angle).reshape(-1),
                              valid.reshape(-1), omega.reshape(-1))
    return valid, luminance, omega, positive, lambda: luminance


@dataclass
class Score:
    """The result of :func:`score_map`.

    ``values`` holds the scalar metrics (NaN where undefined), ``uncertainty`` their
    combined standard uncertainties, ``uncertainty_calibration`` and ``uncertainty_noise``
    its two parts (calibration scale, per-pixel noise), ``noise_bias`` the mean change of
    each metric under the map's noise (with its Monte Carlo standard error in
    ``noise_bias_standard_error``), ``sources`` the grouped sources,
    ``source_mask`` and ``source_labels`` the per-pixel selection (for the glare-source
    map), ``quality`` the Q criterion's result and ``contrast`` its per-pixel contrast map
    (made when first read, :class:`~lsadphoto.metrics.quality.QualityResult`), ``notes``
    the reasons for undefined values.
    """

    values: dict
    uncertainty: dict
    sources: list
    source_mask: np.ndarray
    source_labels: np.ndarray
    quality: object = field(repr=False)
    statistics: dict
    settings: dict
    provenance: dict
    notes: list = field(default_factory=list)
    q_sweep: dict | None = None
    uncertainty_calibration: dict = field(default_factory=dict)
    uncertainty_noise: dict = field(default_factory=dict)
    noise_bias: dict = field(default_factory=dict)
    noise_bias_standard_error: dict = field(default_factory=dict)
    #: evalglare 3.06's optional analyses (band, zones, mask, task) and the per-source
    #: ``-d`` columns, in the order of ``sources`` (:mod:`~lsadphoto.metrics.analyses`).
    analyses: dict = field(default_factory=dict)
    source_details: list = field(default_factory=list)

    @property
    def contrast(self):
        return self.quality.contrast

    def to_dict(self):
        """JSON-ready record: every metric at the top level (None where undefined)."""
        def clean(value):
            if value is None:
                return None
            value = float(value)
            return value if math.isfinite(value) else None

        out = {key: clean(value) for key, value in self.values.items()}
        for name in ("uncertainty", "uncertainty_calibration", "uncertainty_noise", "noise_bias",
                     "noise_bias_standard_error"):
            out[name] = {key: clean(value) for key, value in getattr(self, name).items()}
        out["sources"] = [
            {"luminance": s.luminance, "solid_angle": s.solid_angle,
             "direction": list(s.direction), "row": s.row, "col": s.col,
             "position_index": s.position_index, "sigma_deg": s.sigma_deg,
             "tau_deg": s.tau_deg, "max_luminance": s.max_luminance,
             "min_luminance": s.min_luminance, "n_pixels": s.n_pixels, "peak": s.peak,
             "position_direction": list(s.position_direction),
             "position_pixel": None if s.position_pixel is None else list(s.position_pixel),
             **{k: clean(v) if k != "zone" else v for k, v in detail.items()}}
            for s, detail in zip(self.sources, self.source_details or [{}] * len(self.sources),
                                 strict=True)
        ]
        out.update(_clean_record(self.analyses, clean))
        out["statistics"] = self.statistics
        if self.q_sweep is not None:
            out["q_sweep"] = self.q_sweep
        out["settings"] = self.settings
        out["provenance"] = self.provenance
        out["notes"] = list(self.notes)
        return out


def _clean_record(record, clean):
    """Floats of a nested record through ``clean`` (None where not finite)."""
    if isinstance(record, dict):
        return {k: _clean_record(v, clean) for k, v in record.items()}
    if isinstance(record, list):
        return [_clean_record(v, clean) for v in record]
    if isinstance(record, float):
        return clean(record)
    return record


@dataclass(frozen=True)
class ScoredSource:
    """A grouped source with its place in the visual field.

    ``direction`` is the L·ω-weighted mean direction and (``row``, ``col``) the L·ω-weighted
    mean pixel position; ``position_direction`` is the direction at which the position index
    (and σ, τ) was evaluated, ``position_pixel`` the pixel it belongs to (None for
    ``source_position="direction"``).
    """

    luminance: float
    solid_angle: float
    direction: tuple
    row: float
    col: float
    position_index: float
    sigma_deg: float
    tau_deg: float
    max_luminance: float
    min_luminance: float
    n_pixels: int
    peak: bool
    position_direction: tuple = ()
    position_pixel: tuple | None = None


def _frame(lmap, line_of_sight, up):
    if line_of_sight is None:
        line_of_sight = lmap.line_of_sight if lmap.line_of_sight is not None else (0.0, 0.0, 1.0)
    return ObserverFrame(tuple(map(float, line_of_sight)),
                         (0.0, -1.0, 0.0) if up is None else tuple(map(float, up)))


def _scored_sources(groups, geometry, frame, *, position_index_method, source_position, notes):
    """Each group's position index at its evalglare pixel or its mean direction."""
    sources = []
    fallback = 0
    for g in groups:
        pixel, direction = None, g.direction
        if source_position == "evalglare":
            pixel = position_pixel_evalglare(g.row, g.col, geometry.valid.shape)
            d = geometry.directions_at(*pixel)
            if geometry.valid[pixel] and np.all(np.isfinite(d)) and frame.angles(d)[0] <= \
                    math.pi / 2:
                direction = tuple(map(float, d))
            else:  # the centroid pixel lies off the image or behind the observer
                pixel = None
                fallback += 1
        sigma, tau = frame.angles(np.asarray(direction))
        p = float(position_index(sigma, tau, method=position_index_method))
        sources.append(ScoredSource(g.luminance, g.solid_angle, g.direction, g.row, g.col, p,
                                    math.degrees(sigma), math.degrees(tau), g.max_luminance,
                                    g.min_luminance, g.n_pixels, g.peak, direction, pixel))
    if fallback:
        notes.append(f"{fallback} source(s) have their mean pixel position off the valid image "
                     "or behind the observer: their position index is taken at their mean "
                     "direction")
    return sources


def _scaled_thresholds(quality, n_thresholds, size_arcmin, method, scales):
    """Equivalent threshold counts for the luminances scaled by each k in ``scales``.

    Scaling every luminance by k scales L̄ and every luminance difference by k, so the
    contrasts K are unchanged; what changes is the threshold ΔL(k·L̄), which enters the
    cut-off (k·ΔL_j ≥ N·ΔL(k·L̄) ⇔ ΔL_j ≥ N'·ΔL(L̄)) and K_th ∝ ΔL/L̄. Hence
    Q(k·L; N) = Q(L; N')·N/N' with N' = N·ΔL(k·L̄)/(k·ΔL(L̄)). Returns ``[(N', N/N'), ...]``.
    """
    if not math.isfinite(quality.q) or not quality.threshold_difference > 0:
        return []
    from .adrian import threshold_luminance_difference

    options = {} if method == "Weber" else {
        "exposure_time": quality.settings.get("exposure_time", 2.0),
        "age": quality.settings.get("age", 23)}
    out = []
    for k in scales:
        delta = float(threshold_luminance_difference(k * quality.mean_luminance, size_arcmin,
                                                     method=method, **options))
        n_equiv = n_thresholds * delta / (k * quality.threshold_difference)
        out.append((n_equiv, n_thresholds / n_equiv))
    return out


#: Resamples of the field sums for the per-pixel noise (cheap: a few vectors per sample).
DEFAULT_NOISE_SAMPLES = 64
#: Resampled maps for Q's per-pixel noise (each one a full Q evaluation).
DEFAULT_Q_NOISE_SAMPLES = 8
#: Seed of the noise resampling: every run draws the same numbers (common random numbers).
DEFAULT_NOISE_SEED = 20261201


def noise_variance(lmap):
    """Variance of each pixel's luminance noise [cd²·m⁻⁴], or None when the map has no
    per-pixel uncertainty.

    :attr:`LuminanceMap.uncertainty` combines the calibration scale and the noise,
    u_j² = (L_j·u_k)² + v_j (u_k = ``calibration_uncertainty``); the calibration part is a
    common scale propagated separately, so v_j = u_j² − (L_j·u_k)², and 0 where that is
    within float32 rounding of u_j² or NaN.
    """
    if lmap.uncertainty is None:
        return None
    u = np.asarray(lmap.uncertainty, dtype=np.float64)
    scale = np.asarray(lmap.luminance, dtype=np.float64) * float(lmap.calibration_uncertainty)
    variance = u * u - scale * scale
    # u and L are float32: a difference within their rounding (2⁻²² of u²) is no noise.
    return np.where(variance > 1e-6 * u * u, variance, 0.0)


def _antithetic(rng, pairs, shape):
    """Standard normal draws z₁…z_p followed by −z₁…−z_p, shape (2·pairs, *shape)."""
    z = rng.standard_normal((pairs, *shape))
    return np.concatenate([z, -z])


def _gaussian(z, mean, covariance):
    """Normal vectors from standard draws ``z`` (m, ..., k): mean (..., k), covariance
    (..., k, k), positive semi-definite, through its eigen-decomposition."""
    lam, vec = np.linalg.eigh(covariance)
    root = vec * np.sqrt(np.clip(lam, 0.0, None))[..., None, :]
    return mean + np.einsum("...ij,m...j->m...i", root, z)


def _noise_resampling(indices, sums, source_solid_angle, moments, pairs, rng):
    """Every index evaluated on 2·``pairs`` antithetic draws of the field sums under noise.

    The sums are linear in the pixel luminances (pixel-UGR's quadratically, handled as in
    :class:`~lsadphoto.metrics.field.NoiseMoments`), so for Gaussian pixel noise they are
    jointly Gaussian with the moments computed in one pass: drawing them is drawing noisy
    maps, without the maps. Returns a dict name → array of the sample values.
    """
    background = _gaussian(_antithetic(rng, pairs, (2,)),
                           np.array([sums.background_illuminance,
                                     sums.background_luminance_solid_angle]), moments.background)
    per_source = _gaussian(_antithetic(rng, pairs, moments.source_means.shape),
                           moments.source_means, moments.source_covariances)
    quadratic = moments.quadratic_mean + math.sqrt(moments.quadratic_variance) * \
        _antithetic(rng, pairs, ())
    samples = []
    for m in range(2 * pairs):
        e_dir, total_lw, ugr_sum = per_source[m].sum(axis=0)
        field = replace(sums, illuminance=background[m, 0] + e_dir, source_illuminance=e_dir,
                        background_illuminance=background[m, 0],
                        background_luminance_solid_angle=background[m, 1],
                        luminance_solid_angle=background[m, 1] + total_lw,
                        ugr_sum=ugr_sum + quadratic[m])
        samples.append(indices(field, per_source[m][:, 1] / source_solid_angle))
    return {key: np.array([v[key] for v in samples]) for key in samples[0]}


def _noise_summary(values, samples):
    """Standard deviation, bias (mean − value) and the bias's standard error per metric,
    from antithetic samples (first half +z, second half −z): a pair's mean cancels the
    first-order change, so the bias's error comes from the spread of the pair means."""
    spread, bias, error = {}, {}, {}
    for key, draws in samples.items():
        if not math.isfinite(values[key]) or not np.all(np.isfinite(draws)) or draws.size < 4:
            continue
        pairs = draws.size // 2
        pair_means = (draws[:pairs] + draws[pairs:]) / 2
        spread[key] = float(np.std(draws, ddof=1))
        bias[key] = float(np.mean(draws) - values[key])
        error[key] = float(np.std(pair_means, ddof=1)) / math.sqrt(pairs)
    return spread, bias, error


def _pixel_noise(lmap, values, indices, sums, source_solid_angle, labels, n_sources, *, arrays,
                 noise_samples, q_noise_samples, seed, q_of):
    """Per-pixel noise: standard uncertainty, bias and its standard error of every metric.

    The indices from resampled field sums (:func:`_noise_resampling`), Q from maps
    L ± √v·z (antithetic pairs); the same source pixels and groups throughout. Sample
    counts are rounded up to even numbers; at least 4 are needed. Empty dicts when the map
    has no per-pixel uncertainty or the samples are 0.
    """
    noise_samples = 0 if noise_samples == 0 else check_positive_int(noise_samples, "noise_samples")
    q_noise_samples = 0 if q_noise_samples == 0 else check_positive_int(q_noise_samples,
                                                                        "q_noise_samples")
    variance = noise_variance(lmap)
    if variance is None or not np.any(variance > 0):
        return {}, {}, {}
    rng = np.random.default_rng(int(seed))
    samples = {}
    luminance = arrays[0]
    if noise_samples >= 4:
        moments = noise_moments(*arrays, labels, variance, n_sources)
        samples = _noise_resampling(indices, sums, source_solid_angle, moments,
                                    (noise_samples + 1) // 2, rng)
    if q_noise_samples >= 4 and math.isfinite(values["q"]):
        sd = np.sqrt(variance)
        z = [rng.standard_normal(sd.shape) for _ in range((q_noise_samples + 1) // 2)]
        samples["q"] = np.array([q_of(luminance + sign * sd * zk)
                                 for sign in (1.0, -1.0) for zk in z])
    return _noise_summary(values, samples)


def score_map(lmap, *, line_of_sight=None, up=None, source_method="fixed",
              source_threshold=None, task_direction=None, task_opening_deg=20.0,
              search_angle=DEFAULT_SEARCH_ANGLE, peak_luminance=DEFAULT_PEAK_LUMINANCE,
              background_method="CIE", position_index_method="evalglare",
              source_position="evalglare", guth_field=None, n_thresholds=50.0,
              size_arcmin=10.0, q_weight_exponent=1, q_threshold="Adrian1989",
              q_cutoff="difference", dgp_coefficients="evalglare", vcp_constant=6.374,
              sweep=None, noise_samples=DEFAULT_NOISE_SAMPLES,
              q_noise_samples=DEFAULT_Q_NOISE_SAMPLES, seed=DEFAULT_NOISE_SEED,
              band_deg=None, zone_centre=None, zone_opening_deg=None, mask=None, age=None,
              illuminance=None, illuminance_fill=None, low_light_correction=False,
              checkfile=None, smooth=False, patch_deg=None):
    """Score a luminance map with every metric (see the module notes).

    Parameters
    ----------
    lmap : LuminanceMap
        Absolute luminance [cd·m⁻²] with a projection.
    line_of_sight, up : array_like, shape (3,), optional
        Observer frame in the camera frame; default the map's line of sight (else the
        optical axis) and camera up.
    source_method : {"fixed", "task", "mean", "contrast"}
        Glare-source rule (:func:`~lsadphoto.metrics.sources.select_source_pixels`).
    source_threshold : float, optional
        Threshold [cd·m⁻²] (fixed) or factor (task, mean).
    task_direction : array_like, shape (3,) or (2,), optional
        Task direction for the task rule (default: the line of sight), or an image point
        (row, col); when given, the record holds ``task`` (evalglare ``-t``: its mean
        luminance L_t) whatever the source rule.
    task_opening_deg : float
        Full opening angle of the task cone [deg].
    search_angle : float
        evalglare ``-r`` [rad].
    peak_luminance : float or None
        Peak-extraction limit [cd·m⁻²]; None switches it off.
    background_method : {"CIE", "mean", "Ev"}
        L_b definition.
    position_index_method : {"evalglare", "Guth", "Kim2011"}
    source_position : {"evalglare", "direction"}
        Where each source's position index is evaluated: ``"evalglare"`` (default) at the
        pixel of its L·ω-weighted mean pixel position, as evalglare 3.06 does
        (:func:`~lsadphoto.metrics.grouping.position_pixel_evalglare`); ``"direction"`` at
        its L·ω-weighted mean direction, which does not depend on the projection.
    guth_field : {None, 1, 2}
        Restrict the evaluation to Guth's total (1) or central (2) field of view.
    n_thresholds, size_arcmin, q_weight_exponent, q_threshold, q_cutoff
        Options of the Q criterion (and N, α of the contrast source rule).
    dgp_coefficients : {"evalglare", "Wienold2006"} or 8 numbers
        evalglare ``-w``: a set name or (a1, a2, a3, a4, a5, c1, c2, c3).
    vcp_constant : float
        6.374 as published and in evalglare ≥ 2.07 (6.347 before its fix).
    sweep : sequence of float, optional
        N values for the one-pass Q(N) sweep (e.g. ``range(1, 101)``).
    noise_samples : int
        Draws of the field sums for the per-pixel noise (used when the map has a per-pixel
        ``uncertainty``), in antithetic pairs; 0 switches the noise propagation off, and at
        least 4 are needed.
    q_noise_samples : int
        Resampled maps for Q's noise (each a full Q evaluation), in antithetic pairs; 0
        switches it off, and at least 4 are needed.
    seed : int
        Seed of the noise resampling (the same draws in every run).
    band_deg : float, optional
        evalglare ``-B``: half-width [deg] of the horizontal band about the middle row;
        gives ``band`` (:mod:`~lsadphoto.metrics.regions`).
    zone_centre, zone_opening_deg : optional
        evalglare ``-l``/``-L``: zone centre (direction X,Y,Z or image point (row, col)) and
        one or two full opening angles [deg]; gives ``zones`` and splits the sources at
        the zone borders (every index follows), each source with its ``zone``.
    mask : ndarray or LuminanceMap, optional
        evalglare ``-A``: a picture of the map's size, pixels above 0.1 cd·m⁻² selected (or
        a boolean array); gives ``mask`` with PGSV, PGSV_sat and PGSV_con.
    age : float, optional
        Observer age [years]: CIE 146 age factor of the veiling luminance Lveil_cie.
    illuminance : float, optional
        evalglare ``-i``: external vertical illuminance [lx] used for DGP.
    illuminance_fill : (float, int, int), optional
        evalglare ``-I``: (E_v [lx], row_max, row_min), filling cut rows first
        (:func:`~lsadphoto.metrics.corrections.fill_rows_evalglare`).
    low_light_correction : bool
        evalglare ``-C l+``: DGP with the low-light correction (off by default, as evalglare).
    checkfile : path, optional
        evalglare ``-c``: write the check picture there (:mod:`~lsadphoto.metrics.checkfile`)
        once everything is computed.
    smooth : bool
        evalglare ``-s``: smoothing adds pixels around sources
        (:mod:`~lsadphoto.metrics.grouping_options`).
    patch_deg : float, optional
        evalglare ``-z patch_deg 1``: sources are fixed patches of this size [deg] (angular
        fisheye only).

    Returns
    -------
    Score
    """
    if lmap.projection is None:
        raise BadInputError("the map has no camera projection (no VIEW= line or lsadphoto "
                            "metadata); metrics need each pixel's direction and solid angle")
    check_choice(source_method, "glare-source method", SOURCE_METHODS)
    check_choice(background_method, "background luminance method", BACKGROUND_METHODS)
    check_choice(position_index_method, "position index method", POSITION_INDEX_METHODS)
    check_choice(source_position, "source position", SOURCE_POSITIONS)
    coefficients = dgp_coefficients_of(dgp_coefficients)
    region_mask = mask  # the evalglare -A mask (``mask`` below is the glare-source mask)
    if checkfile is not None:
        checkfile = check_checkfile_path(checkfile)
    if illuminance_fill is not None:
        if illuminance is not None:
            raise BadInputError("give either illuminance (-i) or illuminance_fill (-I), not both")
        if len(illuminance_fill) != 3:
            raise BadInputError("illuminance_fill is (E_v, row_max, row_min), got "
                                f"{illuminance_fill!r}")
        illuminance = illuminance_fill[0]
    if illuminance is not None:
        illuminance = check_positive(illuminance, "external vertical illuminance")
    if guth_field not in (None, 1, 2):
        raise BadInputError(f"guth_field must be 1, 2 or None, got {guth_field!r}")
    frame = _frame(lmap, line_of_sight, up)
    # The field first: a fisheye's geometry and field come from one pass where neither is cached.
    vf = visual_field(lmap.projection, frame, position_index_method=position_index_method)
    geometry = pixel_geometry(lmap.projection)
    if guth_field is None:
        evaluated = geometry.valid
    else:
        from ..geometry.position_index import guth_field_mask

        evaluated = geometry.valid & guth_field_mask(vf.sigma, vf.tau, kind=guth_field)
    # One pass: the valid pixels (in the evaluated part of the picture, finite luminance, in
    # front of the observer), the luminance the field's consumers read (the picture, or NaN
    # off the valid pixels; ``masked()``: NaN there) and solid angle (0 elsewhere).
    image = np.asarray(lmap.luminance)
    if illuminance_fill is not None:
        image = fill_rows_evalglare(image, geometry.valid & (vf.cos_sigma >= 0),
                                    row_max=illuminance_fill[1], row_min=illuminance_fill[2])
    valid, luminance, omega, positive, masked = _field_inputs(image, geometry, evaluated,
                                                              vf.cos_sigma)
    pindex = vf.position_index
    # Q and the statistics need neither the sources nor the field sums: each on a thread of
    # its own (where the kernels run ahead of time) while they are computed — the same calls
    # on the same arrays.
    q_options = dict(size_arcmin=size_arcmin, weight_exponent=q_weight_exponent,
                     threshold=q_threshold, cutoff=q_cutoff, valid=valid)
    pending_quality = background(lambda: q_Budak2021(luminance, geometry, omega, pindex,
                                                     n_thresholds=n_thresholds, **q_options))
    pending_statistics = background(lambda: luminance_statistics(luminance, omega, vf.cos_sigma,
                                                                 positive_range=positive))
    notes = []
    settings = {
        "line_of_sight": list(frame.axes()[0]), "up": list(frame.axes()[1]),
        "source_method": source_method, "source_threshold": source_threshold,
        "search_angle": float(search_angle), "peak_luminance": peak_luminance,
        "background_method": background_method, "position_index_method": position_index_method,
        "source_position": source_position,
        "guth_field": guth_field, "n_thresholds": float(n_thresholds),
        "size_arcmin": float(size_arcmin), "q_weight_exponent": q_weight_exponent,
        "q_threshold": q_threshold, "q_cutoff": q_cutoff,
        "dgp_coefficients": dgp_coefficients if isinstance(dgp_coefficients, str) else
        list(coefficients), "vcp_constant": float(vcp_constant), "illuminance": illuminance,
        "low_light_correction": bool(low_light_correction),
    }
    if task_direction is not None:
        task_direction = centre_direction(task_direction, lmap.projection, "task centre")
    task = None
    if source_method == "task":
        task = frame.axes()[0] if task_direction is None else task_direction
    # Whole-picture arrays: the evaluated field of the selection rules is exactly the valid
    # pixels (NaN luminance and zero solid angle elsewhere), handed over as it is.
    selection = select_source_pixels(
        luminance, omega, vf.cos_sigma, method=source_method, value=source_threshold,
        directions=geometry.directions if task is not None else None, task_direction=task,
        task_opening=math.radians(check_positive(task_opening_deg, "task opening")),
        n_thresholds=n_thresholds, size_arcmin=size_arcmin, field_mask=valid)
    settings["source_selection"] = dict(selection.settings)
    mask = np.asarray(selection.mask, dtype=bool)
    # Every field sum at once, on a thread of its own while the sources are grouped (it
    # needs the selection, not the groups): the same call on the same arrays.
    pending_sums = background(lambda: field_sums(luminance, omega, vf.cos_sigma, pindex, mask))
    groups, labels = group_sources_evalglare(luminance, geometry, omega, mask,
                                             search_angle=search_angle,
                                             peak_luminance=peak_luminance)
    if smooth or patch_deg is not None:
        from .grouping_options import regroup_sources  # only for -s/-z (scipy.ndimage)

        groups, labels = regroup_sources(masked(), geometry.directions, omega, mask, valid,
                                         projection=lmap.projection, search_angle=search_angle,
                                         peak_luminance=peak_luminance, smooth=smooth,
                                         patch_deg=patch_deg)
    # The pixels that may carry a label: the selected ones (-s and -z label others too).
    labelled = mask if not smooth and patch_deg is None else None
    sources = unsplit_sources = _scored_sources(
        groups, geometry, frame, position_index_method=position_index_method,
        source_position=source_position, notes=notes)
    zones = source_zones = None
    if zone_opening_deg is not None or zone_centre is not None:
        if zone_opening_deg is None or zone_centre is None:
            raise BadInputError("zones need both a centre and opening angles")
        zones, labels, parent, source_zones = zone_split(
            labels, directions=geometry.directions, valid=valid, projection=lmap.projection,
            zone_centre=zone_centre, zone_opening_deg=zone_opening_deg)
        groups = describe_sources(labels, len(parent), masked(), geometry, omega,
                                  [groups[k].peak for k in parent])
        sources = _scored_sources(groups, geometry, frame,
                                  position_index_method=position_index_method,
                                  source_position=source_position, notes=[])
        settings["zones"] = {"centre": list(np.asarray(zone_centre, dtype=float)),
                             "opening_deg": list(np.atleast_1d(zone_opening_deg).astype(float))}
    s_l = np.array([s.luminance for s in sources])
    s_w = np.array([s.solid_angle for s in sources])
    s_p = np.array([s.position_index for s in sources])
    # The indices are functions of the field sums and the sources.
    sums = pending_sums.result()

    def indices(field, source_luminance):
        quantities = field.quantities(background_method)
        quantities["sources"] = (source_luminance, s_w, s_p)
        quantities["dgp_illuminance"] = quantities["vertical_illuminance"] if illuminance is \
            None else illuminance
        return evaluate_indices(quantities, settings)

    values = indices(sums, s_l)
    # Without regions and with the sources from the selection, the analyses read the
    # luminance at the labelled pixels alone (Eglare).
    regions_read = labelled is None or any(x is not None for x in (band_deg, zones, region_mask,
                                                                   task_direction))
    analyses, details, regions, extra = evalglare_analyses(
        luminance=masked() if regions_read else luminance, solid_angle=omega, directions=geometry,
        cos_sigma=vf.cos_sigma, valid=valid, projection=lmap.projection,
        labels=labels, labelled=labelled, sources=sources, unsplit_sources=unsplit_sources,
        values=dict(values, dgp_raw=dgp_Wienold2006(values["vertical_illuminance"], s_l, s_w,
                                                    s_p, coefficients=coefficients)),
        dgp_coefficients=coefficients, zones=zones, source_zones=source_zones,
        band_deg=band_deg, mask=region_mask, task_direction=task_direction,
        task_opening_deg=task_opening_deg, age=age)
    values.update(extra)
    settings.update(band_deg=band_deg, mask=region_mask is not None, age=age, smooth=bool(smooth),
                    patch_deg=patch_deg)
    quality = pending_quality.result()
    values["q"] = quality.q
    values["n_sources"] = len(sources)
    values["source_solid_angle"] = float(s_w.sum()) if len(sources) else 0.0
    # Calibration: a common scale k = 1 ± u of every luminance (same sources and groups).
    u = float(lmap.calibration_uncertainty)
    calibration = {}
    extra_n = []
    if u > 0:
        hi, lo = indices(sums.scaled(1.0 + u), s_l * (1.0 + u)), indices(sums.scaled(1.0 - u),
                                                                         s_l * (1.0 - u))
        calibration = {k: abs(hi[k] - lo[k]) / 2.0 for k in hi}
        extra_n = _scaled_thresholds(quality, n_thresholds, size_arcmin, q_threshold, (1 + u, 1 - u))
    sweep_n = [] if sweep is None else [float(n) for n in sweep]
    sweep_record = None
    if sweep_n or (extra_n and math.isfinite(quality.q)):
        wanted = sweep_n + [n for n, _ in extra_n]
        _, q_values = q_sweep(luminance, geometry, omega, pindex,
                              n_values=np.asarray(wanted), **q_options)
        q_values = [float(q) for q in q_values]
        if sweep_n:
            sweep_record = {"n": sweep_n, "q": q_values[:len(sweep_n)]}
        if extra_n:
            # Q(k·L; N) = Q(L; N')·N/N' with N' = N·ΔL(k·L̄)/(k·ΔL(L̄)) (see _scaled_thresholds).
            scaled = [q * factor for q, (_, factor) in zip(q_values[len(sweep_n):], extra_n,
                                                            strict=True)]
            calibration["q"] = abs(scaled[0] - scaled[1]) / 2.0
    # Per-pixel noise, where the map has a per-pixel uncertainty; both parts combined.
    noise, bias, bias_error = _pixel_noise(
        lmap, values, indices, sums, s_w, labels, len(sources),
        arrays=(masked() if lmap.uncertainty is not None else luminance, omega, vf.cos_sigma,
                pindex), noise_samples=noise_samples,
        q_noise_samples=q_noise_samples, seed=seed,
        q_of=lambda noisy: q_Budak2021(noisy, geometry, omega, pindex,
                                       n_thresholds=n_thresholds, **q_options).q)
    uncertainty = {key: math.hypot(calibration.get(key, 0.0), noise.get(key, 0.0))
                   for key in {**calibration, **noise}}
    if noise:
        settings["noise"] = {"samples": int(noise_samples), "q_samples": int(q_noise_samples),
                             "seed": int(seed)}
    if not mask.any():
        notes.append("no glare sources: UGR, DGI, UGP, CGI, DGR and VCP have no value")
    elif not values["background_luminance"] > 0:
        notes.append("background luminance is zero: UGR-type indices diverge and are not given")
    if sums.n_pixels == 0:
        notes.append("no valid pixel in the evaluated field")
    if not math.isfinite(quality.q):
        notes.append(f"Q undefined: {quality.reason}")
    settings["q"] = quality.settings
    # Counted only where the smallest value is negative: no mask of the picture otherwise
    # (1 byte per pixel of fresh memory; fmin skips NaN).
    negative = int(np.count_nonzero(lmap.luminance < 0)) \
        if np.fmin.reduce(lmap.luminance, axis=None) < 0 else 0
    if negative:
        notes.append(f"{negative} pixel(s) have negative luminance (noise about zero in a signed map): "
                     "field sums keep them, which keeps the means unbiased; percentiles count them "
                     "as the lowest values")
    if lmap.calibrated is False:
        if "calibration_method" in (lmap.provenance or {}):  # our photo pipeline, no spot reading
            notes.append("map is not spot-calibrated: absolute metrics rest on the exposure equation "
                         "and the profile's calibration constant")
        else:
            notes.append("map carries no lsadphoto calibration (a foreign file, e.g. a Radiance "
                         "rendering): its values are taken as cd/m² as written, and absolute metrics "
                         "are only as right as that scale")
    overflow = (lmap.provenance or {}).get("overflow")
    if overflow and overflow.get("repair"):
        notes.append(f"metrics rest on a luminous-overflow repair ({overflow['repair']}): "
                     f"{overflow['pixels']} px set to {overflow['repaired_luminance']:.4g} cd/m²")
    elif overflow:
        notes.append(f"luminous overflow not repaired: {overflow['pixels']} px saturated in every frame are "
                     "unknown, so E_v and the glare indices are low")
    provenance = build_provenance(profile=(lmap.provenance or {}).get("profile"),
                                  calibration_factor=lmap.calibration_factor,
                                  calibration_uncertainty=lmap.calibration_uncertainty)
    provenance.update({"map": lmap.provenance, "calibration_factor": lmap.calibration_factor,
                       "calibration_uncertainty": lmap.calibration_uncertainty,
                       "calibrated": lmap.calibrated, "projection": lmap.projection.to_dict()})
    statistics = pending_statistics.result()
    # evalglare's Max_Lum: the largest luminance of the evaluated field [cd·m⁻²].
    values["max_luminance"] = statistics["field"]["max"] if statistics["field"]["max"] \
        is not None else math.nan
    if checkfile is not None:
        write_checkfile(checkfile, check_picture(masked(), labels=labels, zones=zones,
                                                 **regions), projection=lmap.projection)
    return Score(values=values, uncertainty=uncertainty, sources=sources, source_mask=mask,
                 source_labels=labels, quality=quality,
                 statistics=statistics,
                 settings=settings, provenance=provenance, notes=notes, q_sweep=sweep_record,
                 uncertainty_calibration=calibration, uncertainty_noise=noise, noise_bias=bias,
                 noise_bias_standard_error=bias_error, analyses=analyses,
                 source_details=details)
