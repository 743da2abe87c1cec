"""Score a luminance map: every metric of the package in one pass, with its settings.

:func:`score_map` takes a :class:`~lsadphoto.LuminanceMap` with a camera projection (our EXR
maps, or Radiance pictures with a VIEW= line), builds the per-pixel geometry once (cached),
selects glare-source pixels, groups them as evalglare does and evaluates pixel-wise UGR,
grouped UGR, the Q criterion, DGP and the other indices, E_v, L_b and luminance statistics.

Uncertainty: a calibrated map carries the relative standard uncertainty u of its
calibration factor, a common scale of every pixel. Each metric is re-evaluated with the
luminances scaled by 1 ± u (the same source pixels and groups) and half the difference is
reported as its standard uncertainty (``uncertainty`` in the result). For UGR-type indices
this is exactly 8·u/ln 10 to first order. Per-pixel noise averages out in the field sums and
is not propagated.

Undefined values are ``None`` in :meth:`Score.to_dict` with the reason in ``notes``.
"""

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange

from .._provenance import build_provenance
from .._validation import check_choice, check_positive
from ..errors import BadInputError
from ..geometry import ObserverFrame, position_index
from ..geometry.field import pixel_geometry, visual_field
from ..geometry.position_index import METHODS as POSITION_INDEX_METHODS
from .field import BACKGROUND_METHODS, field_sums
from .glare_indices import (
    DGP_COEFFICIENTS,
    cgi_Einhorn1979,
    dgi_Hopkinson1972,
    dgi_mod_Fisekis2003,
    dgp_Wienold2006,
    dgr_Guth1963,
    ugp2_Hirning2016,
    ugp_Hirning2014,
    ugr_exp_Fisekis2003,
    vcp_Guth1963,
)
from .grouping import (
    DEFAULT_PEAK_LUMINANCE,
    DEFAULT_SEARCH_ANGLE,
    group_sources_evalglare,
)
from .quality import q_Budak2021, q_sweep
from .sources import SOURCE_METHODS, select_source_pixels
from .statistics import luminance_statistics
from .ugr import ugr_CIE117

__all__ = ["Score", "score_map"]


#: Pixels per chunk of the compiled per-pixel passes.
_CHUNK = 1 << 16


@njit(parallel=True, cache=True, error_model="numpy", nogil=True)
def _field_inputs_kernel(image, evaluated, solid_angle, cos_sigma, valid, luminance, omega):
    n = image.size
    for k in prange((n + _CHUNK - 1) // _CHUNK):
        for i in range(k * _CHUNK, min(n, (k + 1) * _CHUNK)):
            L = np.float64(image[i])
            ok = evaluated[i] & (np.abs(L) < np.inf) & (cos_sigma[i] >= 0)
            valid[i] = ok
            luminance[i] = L if ok else np.nan
            omega[i] = solid_angle[i] if ok else 0.0


def _field_inputs(image, evaluated, solid_angle, cos_sigma):
    """Valid pixels (``evaluated``, finite luminance, cos σ ≥ 0), the luminance [cd·m⁻²]
    as float64 with NaN elsewhere and the solid angle [sr] with 0 elsewhere, in one pass.
    (Outputs are allocated by numpy, which asks for huge pages: faulting in 400 MB of
    small pages costs more than the pass itself.)"""
    shape = evaluated.shape
    valid = np.empty(shape, dtype=bool)
    luminance = np.empty(shape)
    omega = np.empty(shape)
    flat = [np.ascontiguousarray(a).reshape(-1) for a in (image, evaluated, solid_angle, cos_sigma)]
    _field_inputs_kernel(*flat, valid.reshape(-1), luminance.reshape(-1), omega.reshape(-1))
    return valid, luminance, omega


@dataclass
class Score:
    """The result of :func:`score_map`.

    ``values`` holds the scalar metrics (NaN where undefined), ``uncertainty`` their
    standard uncertainties from the calibration, ``sources`` the grouped sources,
    ``source_mask`` and ``source_labels`` the per-pixel selection (for the glare-source
    map), ``contrast`` the Q criterion's per-pixel contrast map, ``notes`` the reasons for
    undefined values.
    """

    values: dict
    uncertainty: dict
    sources: list
    source_mask: np.ndarray
    source_labels: np.ndarray
    contrast: np.ndarray
    statistics: dict
    settings: dict
    provenance: dict
    notes: list = field(default_factory=list)
    q_sweep: dict | None = None

    def to_dict(self):
        """JSON-ready record: every metric at the top level (None where undefined)."""
        def clean(value):
            if value is None:
                return None
            value = float(value)
            return value if math.isfinite(value) else None

        out = {key: clean(value) for key, value in self.values.items()}
        out["uncertainty"] = {key: clean(value) for key, value in self.uncertainty.items()}
        out["sources"] = [
            {"luminance": s.luminance, "solid_angle": s.solid_angle,
             "direction": list(s.direction), "row": s.row, "col": s.col,
             "position_index": s.position_index, "sigma_deg": s.sigma_deg,
             "tau_deg": s.tau_deg, "max_luminance": s.max_luminance,
             "min_luminance": s.min_luminance, "n_pixels": s.n_pixels, "peak": s.peak}
            for s in self.sources
        ]
        out["statistics"] = self.statistics
        if self.q_sweep is not None:
            out["q_sweep"] = self.q_sweep
        out["settings"] = self.settings
        out["provenance"] = self.provenance
        out["notes"] = list(self.notes)
        return out


@dataclass(frozen=True)
class ScoredSource:
    """A grouped source with its place in the visual field."""

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


def _frame(lmap, line_of_sight, up):
    if line_of_sight is None:
        line_of_sight = lmap.line_of_sight if lmap.line_of_sight is not None else (0.0, 0.0, 1.0)
    return ObserverFrame(tuple(map(float, line_of_sight)),
                         (0.0, -1.0, 0.0) if up is None else tuple(map(float, up)))


def _ugr_pixel(n_sources, total, l_b):
    """Pixel-wise UGR from the number of source pixels and their ΣL²ω/P², with the undefined
    cases of :func:`~lsadphoto.metrics.ugr.ugr_pixel` (no source, L_b ≤ 0, empty sum)."""
    if n_sources == 0 or not l_b > 0 or total <= 0:
        return math.nan
    return 8.0 * math.log10(0.25 / l_b * total)


def _indices(sources_l, sources_w, sources_p, *, e_v, e_dir, l_b, mean_l, pixel_sum, settings):
    """Every source-based index for given source luminances (a function of scale);
    ``pixel_sum`` is (number of source pixels, their ΣL²ω/P²)."""
    values = {
        "ugr_grouped": ugr_CIE117(sources_l, sources_w, sources_p, l_b),
        "ugr_pixel": _ugr_pixel(*pixel_sum, l_b),
        "dgp": dgp_Wienold2006(e_v, sources_l, sources_w, sources_p,
                               coefficients=settings["dgp_coefficients"]),
        "dgp_low_light": dgp_Wienold2006(e_v, sources_l, sources_w, sources_p,
                                         coefficients=settings["dgp_coefficients"],
                                         low_light_correction=True),
        "dgi": dgi_Hopkinson1972(sources_l, sources_w, sources_p, l_b),
        "dgi_mod": dgi_mod_Fisekis2003(sources_l, sources_w, sources_p, e_v),
        "ugr_exp": ugr_exp_Fisekis2003(sources_l, sources_w, sources_p, e_v, l_b),
        "ugp": ugp_Hirning2014(sources_l, sources_w, sources_p, l_b),
        "ugp2": ugp2_Hirning2016(sources_l, sources_w, sources_p, l_b),
        "cgi": cgi_Einhorn1979(sources_l, sources_w, sources_p, e_v, e_dir),
    }
    dgr = dgr_Guth1963(sources_l, sources_w, sources_p, mean_l)
    values["dgr"] = dgr
    values["vcp"] = vcp_Guth1963(dgr, constant=settings["vcp_constant"]) if len(sources_l) else \
        math.nan
    return values


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


def score_map(lmap, *, line_of_sight=None, up=None, source_method="fixed",
              source_threshold=None, task_direction=None, task_opening_deg=20.0,
              search_angle=DEFAULT_SEARCH_ANGLE, peak_luminance=DEFAULT_PEAK_LUMINANCE,
              background_method="CIE", position_index_method="evalglare", guth_field=None,
              n_thresholds=50.0, size_arcmin=10.0, q_weight_exponent=1, q_threshold="Adrian1989",
              q_cutoff="difference", dgp_coefficients="evalglare", vcp_constant=6.374,
              sweep=None):
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
    task_direction : array_like, shape (3,), optional
        Task direction for the task rule (default: the line of sight).
    task_opening_deg : float
        Full opening angle of the task cone [deg].
    search_angle : float
        evalglare ``-r`` [rad].
    peak_luminance : float or None
        Peak-extraction limit [cd·m⁻²]; None switches it off.
    background_method : {"CIE", "mean", "Ev"}
        L_b definition.
    position_index_method : {"evalglare", "Guth", "Kim2011"}
    guth_field : {None, 1, 2}
        Restrict the evaluation to Guth's total (1) or central (2) field of view.
    n_thresholds, size_arcmin, q_weight_exponent, q_threshold, q_cutoff
        Options of the Q criterion (and N, α of the contrast source rule).
    dgp_coefficients : {"evalglare", "Wienold2006"}
    vcp_constant : float
        6.374 as published; evalglare's code uses 6.347.
    sweep : sequence of float, optional
        N values for the one-pass Q(N) sweep (e.g. ``range(1, 101)``).

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
    check_choice(dgp_coefficients, "DGP coefficient set", tuple(DGP_COEFFICIENTS))
    if guth_field not in (None, 1, 2):
        raise BadInputError(f"guth_field must be 1, 2 or None, got {guth_field!r}")
    frame = _frame(lmap, line_of_sight, up)
    geometry = pixel_geometry(lmap.projection)
    vf = visual_field(lmap.projection, frame, position_index_method=position_index_method)
    if guth_field is None:
        evaluated = geometry.valid
    else:
        from ..geometry.position_index import guth_field_mask

        evaluated = geometry.valid & guth_field_mask(vf.sigma, vf.tau, kind=guth_field)
    # One pass: the valid pixels (in the evaluated part of the picture, finite luminance, in
    # front of the observer), the luminance (NaN elsewhere) and solid angle (0 elsewhere).
    valid, luminance, omega = _field_inputs(np.asarray(lmap.luminance), evaluated,
                                            geometry.solid_angle, vf.cos_sigma)
    pindex = vf.position_index
    notes = []
    settings = {
        "line_of_sight": list(frame.axes()[0]), "up": list(frame.axes()[1]),
        "source_method": source_method, "source_threshold": source_threshold,
        "search_angle": float(search_angle), "peak_luminance": peak_luminance,
        "background_method": background_method, "position_index_method": position_index_method,
        "guth_field": guth_field, "n_thresholds": float(n_thresholds),
        "size_arcmin": float(size_arcmin), "q_weight_exponent": q_weight_exponent,
        "q_threshold": q_threshold, "q_cutoff": q_cutoff, "dgp_coefficients": dgp_coefficients,
        "vcp_constant": float(vcp_constant),
    }
    task = None
    if source_method == "task":
        task = frame.axes()[0] if task_direction is None else task_direction
    # Whole-picture arrays: the evaluated field of the selection rules is exactly the valid
    # pixels (NaN luminance and zero solid angle elsewhere).
    selection = select_source_pixels(
        luminance, omega, vf.cos_sigma, method=source_method, value=source_threshold,
        directions=geometry.directions if task is not None else None, task_direction=task,
        task_opening=math.radians(check_positive(task_opening_deg, "task opening")),
        n_thresholds=n_thresholds, size_arcmin=size_arcmin)
    settings["source_selection"] = dict(selection.settings)
    mask = np.asarray(selection.mask, dtype=bool)
    groups, labels = group_sources_evalglare(luminance, geometry.directions, omega, mask,
                                             search_angle=search_angle,
                                             peak_luminance=peak_luminance)
    sources = []
    for g in groups:
        sigma, tau = frame.angles(np.asarray(g.direction))
        p = float(position_index(sigma, tau, method=position_index_method))
        sources.append(ScoredSource(g.luminance, g.solid_angle, g.direction, g.row, g.col, p,
                                    math.degrees(sigma), math.degrees(tau), g.max_luminance,
                                    g.min_luminance, g.n_pixels, g.peak))
    s_l = np.array([s.luminance for s in sources])
    s_w = np.array([s.solid_angle for s in sources])
    s_p = np.array([s.position_index for s in sources])
    # Every field sum at once; a scale k of the luminances scales them by k (ΣL²ω/P² by k²).
    sums = field_sums(luminance, omega, vf.cos_sigma, pindex, mask)

    def evaluate(scale):
        e_v = scale * sums.illuminance
        e_dir = scale * sums.source_illuminance
        mean_l = scale * sums.luminance_solid_angle / sums.solid_angle \
            if sums.solid_angle > 0 else math.nan
        if background_method == "CIE":  # (E_v − E_dir)/π, summed over the non-source pixels
            l_b = scale * sums.background_illuminance / math.pi
        elif background_method == "Ev":
            l_b = e_v / math.pi
        elif sums.background_solid_angle > 0:
            l_b = scale * sums.background_luminance_solid_angle / sums.background_solid_angle
        else:  # every pixel a source: the mean over the field (as background_luminance)
            l_b = mean_l
        values = {"vertical_illuminance": e_v, "direct_illuminance": e_dir,
                  "background_luminance": l_b, "mean_luminance": mean_l}
        values.update(_indices(s_l * scale, s_w, s_p, e_v=e_v, e_dir=e_dir, l_b=l_b,
                               mean_l=mean_l,
                               pixel_sum=(sums.n_sources, scale * scale * sums.ugr_sum),
                               settings=settings))
        return values

    values = evaluate(1.0)
    quality = q_Budak2021(luminance, geometry.directions, omega, pindex,
                          n_thresholds=n_thresholds, size_arcmin=size_arcmin,
                          weight_exponent=q_weight_exponent, threshold=q_threshold,
                          cutoff=q_cutoff, valid=valid)
    values["q"] = quality.q
    values["n_sources"] = len(sources)
    values["source_solid_angle"] = float(s_w.sum()) if len(sources) else 0.0
    u = float(lmap.calibration_uncertainty)
    uncertainty = {}
    q_options = dict(size_arcmin=size_arcmin, weight_exponent=q_weight_exponent,
                     threshold=q_threshold, cutoff=q_cutoff, valid=valid)
    extra_n = []
    if u > 0:
        hi, lo = evaluate(1.0 + u), evaluate(1.0 - u)
        uncertainty = {k: abs(hi[k] - lo[k]) / 2.0 for k in hi}
        extra_n = _scaled_thresholds(quality, n_thresholds, size_arcmin, q_threshold, (1 + u, 1 - u))
    sweep_n = [] if sweep is None else [float(n) for n in sweep]
    sweep_record = None
    if sweep_n or (extra_n and math.isfinite(quality.q)):
        wanted = sweep_n + [n for n, _ in extra_n]
        _, q_values = q_sweep(luminance, geometry.directions, omega, pindex,
                              n_values=np.asarray(wanted), **q_options)
        q_values = [float(q) for q in q_values]
        if sweep_n:
            sweep_record = {"n": sweep_n, "q": q_values[:len(sweep_n)]}
        if extra_n:
            # Q(k·L; N) = Q(L; N')·N/N' with N' = N·ΔL(k·L̄)/(k·ΔL(L̄)) (see _scaled_thresholds).
            scaled = [q * factor for q, (_, factor) in zip(q_values[len(sweep_n):], extra_n,
                                                            strict=True)]
            uncertainty["q"] = abs(scaled[0] - scaled[1]) / 2.0
    if not mask.any():
        notes.append("no glare sources: UGR, DGI, UGP, CGI, DGR and VCP have no value")
    elif not values["background_luminance"] > 0:
        notes.append("background luminance is zero: UGR-type indices diverge and are not given")
    if sums.n_pixels == 0:
        notes.append("no valid pixel in the evaluated field")
    if not math.isfinite(quality.q):
        notes.append(f"Q undefined: {quality.reason}")
    settings["q"] = quality.settings
    negative = int(np.count_nonzero(lmap.luminance < 0))
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
    provenance = build_provenance(profile=(lmap.provenance or {}).get("profile"),
                                  calibration_factor=lmap.calibration_factor,
                                  calibration_uncertainty=lmap.calibration_uncertainty)
    provenance.update({"map": lmap.provenance, "calibration_factor": lmap.calibration_factor,
                       "calibration_uncertainty": lmap.calibration_uncertainty,
                       "calibrated": lmap.calibrated, "projection": lmap.projection.to_dict()})
    return Score(values=values, uncertainty=uncertainty, sources=sources, source_mask=mask,
                 source_labels=labels, contrast=quality.contrast,
                 statistics=luminance_statistics(luminance, omega, vf.cos_sigma),
                 settings=settings, provenance=provenance, notes=notes, q_sweep=sweep_record)
