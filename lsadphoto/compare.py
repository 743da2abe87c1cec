"""Model against photo: two luminance maps of the same view, pixel by pixel and metric by metric.

Both maps must share one camera geometry (render the model through the photo's camera
profile and observer); :func:`compare_maps` then gives the per-pixel ratio model/photo, error
statistics over the field and in regions (σ rings around the line of sight and a coarse
grid of image blocks), and every metric of :func:`~lsadphoto.metrics.score.score_map` for
both maps with its difference and the combined standard uncertainty.

Uncertainties: the photo's is its calibration factor's (a common scale) and its per-pixel
noise (:func:`score_map` propagates both); the model's is its Monte Carlo error. Monte Carlo errors of neighbouring pixels are correlated (they share the
same light chains), so the model's scale uncertainty is taken as the fully correlated bound
Σ u_j·ω_j / Σ L_j·ω_j from its per-pixel standard errors — conservative — unless the model
map states a relative ``calibration_uncertainty`` of its own. Metric uncertainties of both
maps come from :func:`score_map`'s scale perturbation and are combined in quadrature.

References
----------
JCGM 100:2008 (GUM) §5.1.2 (combination of uncorrelated uncertainties).
"""

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from .errors import BadInputError
from .geometry.field import pixel_geometry, visual_field
from .geometry.observer import ObserverFrame
from .luminance_map import LuminanceMap
from .metrics.registry import FIELD, INDICES
from .metrics.score import score_map

__all__ = ["Comparison", "compare_maps", "model_scale_uncertainty"]

#: Metrics compared (keys of :meth:`Score.to_dict`): every field quantity and index of the
#: metric registry, and Q.
COMPARED_METRICS = tuple(m.name for m in FIELD + INDICES) + ("q",)


@dataclass
class Comparison:
    """Result of :func:`compare_maps` (see the module notes); ``ratio`` is model/photo,
    ``scores`` the two :class:`~lsadphoto.metrics.score.Score` results (photo, model), for
    the report's viewer overlays."""

    ratio: np.ndarray
    field: dict
    regions: dict
    metrics: dict
    uncertainty: dict
    settings: dict = field(default_factory=dict)
    scores: tuple = ()

    def to_dict(self):
        """JSON-ready record (None for undefined values)."""
        return {"field": self.field, "regions": self.regions, "metrics": self.metrics,
                "uncertainty": self.uncertainty, "settings": self.settings}


def _clean(value):
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def model_scale_uncertainty(lmap):
    """Relative standard uncertainty of a model map's overall scale [–] (see module notes)."""
    if lmap.calibration_uncertainty > 0:
        return float(lmap.calibration_uncertainty)
    if lmap.uncertainty is None or lmap.projection is None:
        return 0.0
    w = pixel_geometry(lmap.projection).solid_angle
    L = np.asarray(lmap.luminance, dtype=np.float64)
    u = np.asarray(lmap.uncertainty, dtype=np.float64)
    ok = np.isfinite(L) & np.isfinite(u) & (w > 0)
    total = float(np.sum(L[ok] * w[ok]))
    return float(np.sum(u[ok] * w[ok]) / total) if total > 0 else 0.0


def _statistics(log_ratio, weights):
    """ω-weighted statistics of log(model/photo) reported as ratios and percentages."""
    if log_ratio.size == 0 or not weights.sum() > 0:
        return {"n_pixels": 0, "solid_angle": 0.0, "mean_ratio": None, "median_ratio": None,
                "rms_relative_error": None, "p05_ratio": None, "p95_ratio": None,
                "within_10_percent": None}
    order = np.argsort(log_ratio)
    cdf = np.cumsum(weights[order]) / weights.sum()
    pick = lambda q: float(np.exp(log_ratio[order][min(np.searchsorted(cdf, q), cdf.size - 1)]))  # noqa: E731
    rel = np.expm1(log_ratio)
    return {
        "n_pixels": int(log_ratio.size),
        "solid_angle": float(weights.sum()),
        "mean_ratio": float(np.exp(np.sum(log_ratio * weights) / weights.sum())),
        "median_ratio": pick(0.5),
        "rms_relative_error": float(np.sqrt(np.sum(rel**2 * weights) / weights.sum())),
        "p05_ratio": pick(0.05),
        "p95_ratio": pick(0.95),
        "within_10_percent": float(np.sum(weights[np.abs(rel) <= 0.1]) / weights.sum()),
    }


def compare_maps(photo, model, *, line_of_sight=None, up=None, grid=(4, 4),
                 ring_edges_deg=(0.0, 30.0, 60.0, 90.0), floor_luminance=1e-3, **score_options):
    """Compare a model luminance map with a photo of the same view.

    Parameters
    ----------
    photo, model : LuminanceMap
        The same projection (model rendered through the photo's camera) [cd·m⁻²].
    line_of_sight, up : array_like, shape (3,), optional
        Observer frame (default: the photo's line of sight, camera up).
    grid : (int, int)
        Blocks (rows, cols) of the per-region table.
    ring_edges_deg : sequence of float
        σ edges of the ring regions [deg].
    floor_luminance : float
        Pixels darker than this in either map [cd·m⁻²] are left out of the ratio statistics
        (their ratios are noise).
    **score_options
        Passed to :func:`~lsadphoto.metrics.score.score_map` for both maps.

    Returns
    -------
    Comparison
    """
    for name, lmap in (("photo", photo), ("model", model)):
        if not isinstance(lmap, LuminanceMap):
            raise BadInputError(f"{name} must be a LuminanceMap")
        if lmap.projection is None:
            raise BadInputError(f"the {name} map has no camera geometry")
    if photo.projection != model.projection:
        raise BadInputError("photo and model maps have different camera geometries; render the "
                            "model through the photo's camera profile")
    if line_of_sight is None and photo.line_of_sight is not None:
        line_of_sight = photo.line_of_sight
    frame = ObserverFrame(tuple(line_of_sight) if line_of_sight is not None else (0.0, 0.0, 1.0),
                          tuple(up) if up is not None else (0.0, -1.0, 0.0))
    geometry = pixel_geometry(photo.projection)
    vf = visual_field(photo.projection, frame)
    L_p = np.asarray(photo.luminance, dtype=np.float64)
    L_m = np.asarray(model.luminance, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = L_m / L_p
    ok = (geometry.valid & np.isfinite(L_p) & np.isfinite(L_m) & (L_p > floor_luminance)
          & (L_m > floor_luminance) & (vf.cos_sigma >= 0))
    log_ratio = np.log(np.where(ok, ratio, 1.0))
    w = geometry.solid_angle
    field_stats = _statistics(log_ratio[ok], w[ok])
    sigma_deg = np.degrees(vf.sigma)
    rings = []
    for lo, hi in zip(ring_edges_deg[:-1], ring_edges_deg[1:], strict=True):
        sel = ok & (sigma_deg >= lo) & (sigma_deg <= hi if hi == ring_edges_deg[-1] else
                                         sigma_deg < hi)
        rings.append({"sigma_deg": [lo, hi], **_statistics(log_ratio[sel], w[sel])})
    rows, cols = L_p.shape
    gr, gc = grid
    if int(gr) != gr or int(gc) != gc or gr < 1 or gc < 1:
        raise BadInputError(f"grid must be two positive integers, got {grid!r}")
    blocks = []
    for i in range(gr):
        for j in range(gc):
            r0, r1 = rows * i // gr, rows * (i + 1) // gr
            c0, c1 = cols * j // gc, cols * (j + 1) // gc
            sel = ok[r0:r1, c0:c1]
            stats = _statistics(log_ratio[r0:r1, c0:c1][sel], w[r0:r1, c0:c1][sel])
            blocks.append({"rows": [r0, r1], "cols": [c0, c1], **stats})
    options = dict(score_options, line_of_sight=frame.line_of_sight, up=frame.up)
    score_p = score_map(photo, **options)
    u_model = model_scale_uncertainty(model)
    model_options = dict(options)
    if u_model > 0 and model.calibration_uncertainty == 0:
        # The model's Monte Carlo scale uncertainty enters its metrics like a calibration's;
        # taken as fully correlated, its pixel errors are not propagated again as
        # independent noise.
        model = dataclasses.replace(model, calibration_uncertainty=u_model)
        model_options.update(noise_samples=0, q_noise_samples=0)
    score_m = score_map(model, **model_options)
    metrics = {}
    for key in COMPARED_METRICS:
        a, b = score_p.values.get(key), score_m.values.get(key)
        ua, ub = score_p.uncertainty.get(key, 0.0), score_m.uncertainty.get(key, 0.0)
        diff = (b - a) if a is not None and b is not None else None
        combined = math.hypot(ua or 0.0, ub or 0.0)
        metrics[key] = {"photo": _clean(a), "model": _clean(b), "difference": _clean(diff),
                        "photo_uncertainty": _clean(ua), "model_uncertainty": _clean(ub),
                        "combined_uncertainty": _clean(combined),
                        "agree_within_2u": (None if _clean(diff) is None or combined == 0
                                            else bool(abs(diff) <= 2 * combined))}
    uncertainty = {"photo_calibration_relative": float(photo.calibration_uncertainty),
                   "model_monte_carlo_relative": u_model}
    settings = {"grid": [int(gr), int(gc)], "ring_edges_deg": list(ring_edges_deg),
                "floor_luminance": float(floor_luminance), "score": score_p.settings}
    return Comparison(ratio=np.where(ok, ratio, np.nan), field=field_stats,
                      regions={"rings": rings, "blocks": blocks}, metrics=metrics,
                      uncertainty=uncertainty, settings=settings, scores=(score_p, score_m))
