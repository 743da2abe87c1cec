"""Which pixels are glare sources: the threshold rules.

Four rules, chosen with ``method`` (FORMULAS.md Part A, §2.4.4 and §3.4):

``"fixed"`` (default)
    L > value [cd·m⁻²]; value defaults to 2000 cd·m⁻², evalglare's ``-b`` default since
    v2.05 (Pierson's study).
``"task"``
    L > factor · L_task, with L_task the ω-weighted mean luminance inside a cone of full
    opening angle ``task_opening`` around ``task_direction`` (evalglare ``-t``; factor 5 by
    default, as evalglare uses when ``-t`` comes without ``-b``).
``"mean"``
    L > factor · L̄ over the evaluated field (evalglare ``-b`` ≤ 100 without a task; its
    manual calls this "not recommended").
``"contrast"``
    L − L_b ≥ N · ΔL(L_a, α): the paper's selection "based on contrasts" [RECONSTRUCTED:
    the paper gives no formula]. ΔL is Adrian's threshold luminance difference for a detail
    of α arcmin at the adaptation luminance L_a = L̄, and L_b the CIE background
    luminance (E_v − E_dir)/π. Since L_b depends on which pixels are sources, the rule is
    solved as a fixed point: start from L_b = E_v/π, select, recompute L_b, repeat until
    the selection no longer changes (L_b only falls as sources are added, so the selection
    grows monotonically and the iteration ends).

In every rule the comparison is strict (``>``) as in evalglare, except the contrast rule,
which reads "at least N thresholds" (``≥``).

References
----------
Radiance ``src/util/evalglare.c`` (``-b``, ``-t``); Pierson, C., Wienold, J., Bodart, M.
(2018), *Discomfort glare perception in daylighting: influencing factors*, Energy Procedia
122, 331–336 (2000 cd·m⁻² threshold). Budak et al. (seed paper, §4 and Fig. 3).
"""

from dataclasses import dataclass, field

import numpy as np

from .._validation import check_array, check_choice, check_positive
from ..errors import BadInputError
from .field import background_luminance, evaluated_field, mean_luminance, vertical_illuminance

__all__ = ["SOURCE_METHODS", "DEFAULT_SOURCE_THRESHOLD", "SourceSelection", "task_luminance",
           "select_source_pixels"]

SOURCE_METHODS = ("fixed", "task", "mean", "contrast")

#: evalglare's fixed glare-source threshold [cd·m⁻²] (``-b 2000``, default since v2.05).
DEFAULT_SOURCE_THRESHOLD = 2000.0
#: evalglare's factor for the task rule when ``-t`` is given without ``-b``.
DEFAULT_TASK_FACTOR = 5.0
#: Largest number of fixed-point iterations of the contrast rule.
_MAX_CONTRAST_ITERATIONS = 100


@dataclass(frozen=True)
class SourceSelection:
    """Glare-source pixels and the rule that chose them.

    Attributes
    ----------
    mask : ndarray of bool, shape (rows, cols)
        True for glare-source pixels.
    threshold : float
        The luminance [cd·m⁻²] a pixel had to exceed (for the contrast rule: L_b + N·ΔL).
    settings : dict
        Method and parameters, with derived values (L_task, L̄, ΔL, iterations).
    """

    mask: np.ndarray
    threshold: float
    settings: dict = field(default_factory=dict)


def _above(luminance, threshold, field_mask, *, strict=True):
    """``field_mask & (luminance > threshold)`` (``>=`` unless ``strict``), the threshold
    compared as a float64 number (numpy would round a Python float to a float32 picture's
    precision before comparing); one boolean map, written in place (no temporary of the
    picture's size)."""
    compare = np.greater if strict else np.greater_equal
    out = compare(luminance, np.float64(threshold))
    out &= field_mask
    return out


def task_luminance(luminance, directions, solid_angle, task_direction, opening_angle):
    """ω-weighted mean luminance [cd·m⁻²] inside a cone around ``task_direction``.

    ``opening_angle`` [rad] is the cone's full apex angle: a pixel belongs to the task when
    2·arccos(d̂·t̂) ≤ opening_angle (evalglare ``-t x y angle``). NaN when no valid pixel
    falls inside.
    """
    t = check_array(task_direction, "task_direction", shape=(3,), finite=True, dtype=float)
    norm = np.linalg.norm(t)
    if norm == 0:
        raise BadInputError("task_direction must not be the zero vector")
    opening = check_positive(opening_angle, "task opening angle")
    cos_half = np.cos(opening / 2.0)
    with np.errstate(invalid="ignore"):
        inside = (directions @ (t / norm)) >= cos_half
    inside &= np.isfinite(luminance) & (solid_angle > 0)
    omega = solid_angle[inside].astype(np.float64)
    if omega.sum() <= 0:
        return float("nan")
    return float(np.sum(luminance[inside] * omega) / omega.sum())


def select_source_pixels(luminance, solid_angle, cos_sigma, *, method="fixed", value=None,
                         directions=None, task_direction=None, task_opening=np.radians(20.0),
                         n_thresholds=50.0, size_arcmin=10.0, threshold_options=None,
                         field_mask=None):
    """Glare-source pixels of a map by one of the threshold rules (see the module notes).

    Parameters
    ----------
    luminance, solid_angle, cos_sigma : ndarray, shape (rows, cols)
        L [cd·m⁻²] (NaN unknown), ω [sr], cos σ [–].
    method : {"fixed", "task", "mean", "contrast"}
    value : float, optional
        Threshold [cd·m⁻²] for ``"fixed"`` (default 2000) or the factor for ``"task"``
        (default 5) and ``"mean"`` (default 5).
    directions : ndarray, shape (rows, cols, 3)
        Pixel directions; needed by ``"task"``.
    task_direction : array_like, shape (3,)
        Task direction in the camera frame, for ``"task"``.
    task_opening : float
        Full opening angle of the task cone [rad] (default 20°).
    n_thresholds : float
        N of the contrast rule (default 50, the paper's optimum for Q).
    size_arcmin : float
        Critical detail α of the contrast rule [arcmin] (default 10′).
    threshold_options : dict, optional
        Extra keyword options for :func:`~lsadphoto.metrics.adrian.threshold_Adrian1989`
        (exposure time, age, polarity).
    field_mask : ndarray of bool, shape (rows, cols), optional
        The evaluated field of these arrays (:func:`~lsadphoto.metrics.field.evaluated_field`:
        finite L, ω > 0, cos σ ≥ 0) where the caller has it already (a score's valid
        pixels); computed from the arrays otherwise.

    Returns
    -------
    SourceSelection
    """
    check_choice(method, "glare-source method", SOURCE_METHODS)
    # Thresholds compared as float64 numbers (_above).
    if field_mask is None:
        field_mask = evaluated_field(luminance, solid_angle, cos_sigma)
    elif np.shape(field_mask) != np.shape(luminance):
        raise BadInputError(f"field_mask must have the luminance's shape {np.shape(luminance)}")
    with np.errstate(invalid="ignore"):
        if method == "fixed":
            threshold = check_positive(DEFAULT_SOURCE_THRESHOLD if value is None else value,
                                       "source threshold")
            return SourceSelection(_above(luminance, threshold, field_mask), threshold,
                                   {"method": method, "threshold": threshold})
        if method == "mean":
            factor = check_positive(DEFAULT_TASK_FACTOR if value is None else value, "factor")
            mean = mean_luminance(luminance, solid_angle, cos_sigma)
            threshold = factor * mean
            mask = _above(luminance, threshold, field_mask) if np.isfinite(threshold) else \
                np.zeros_like(field_mask)
            return SourceSelection(mask, threshold, {"method": method, "factor": factor,
                                                     "mean_luminance": mean})
        if method == "task":
            if directions is None or task_direction is None:
                raise BadInputError("the task rule needs pixel directions and a task direction")
            factor = check_positive(DEFAULT_TASK_FACTOR if value is None else value, "factor")
            l_task = task_luminance(luminance, directions, solid_angle, task_direction,
                                    task_opening)
            if not np.isfinite(l_task):
                raise BadInputError("the task cone holds no valid pixel")
            threshold = factor * l_task
            return SourceSelection(_above(luminance, threshold, field_mask), threshold,
                                   {"method": method, "factor": factor,
                                    "task_luminance": l_task,
                                    "task_opening_deg": float(np.degrees(task_opening))})
        return _contrast_sources(luminance, solid_angle, cos_sigma, field_mask,
                                 n_thresholds=n_thresholds, size_arcmin=size_arcmin,
                                 options=threshold_options or {})


def _contrast_sources(luminance, solid_angle, cos_sigma, field_mask, *, n_thresholds,
                      size_arcmin, options):
    from .adrian import threshold_Adrian1989

    n = check_positive(n_thresholds, "n_thresholds")
    adaptation = mean_luminance(luminance, solid_angle, cos_sigma)
    settings = {"method": "contrast", "n_thresholds": n, "size_arcmin": float(size_arcmin),
                "adaptation_luminance": adaptation, **options}
    if not np.isfinite(adaptation) or adaptation <= 0:
        settings["note"] = "dark or empty field: no contrast sources"
        return SourceSelection(np.zeros_like(field_mask), float("nan"), settings)
    delta = float(threshold_Adrian1989(adaptation, size_arcmin, **options))
    l_b = vertical_illuminance(luminance, solid_angle, cos_sigma) / np.pi
    mask = np.zeros_like(field_mask)
    for iteration in range(1, _MAX_CONTRAST_ITERATIONS + 1):
        threshold = l_b + n * delta
        new_mask = _above(luminance, threshold, field_mask, strict=False)
        if np.array_equal(new_mask, mask) and iteration > 1:
            break
        mask = new_mask
        l_b = background_luminance(luminance, solid_angle, cos_sigma, mask, method="CIE")
    settings.update(threshold_difference=delta, background_luminance=l_b, iterations=iteration)
    return SourceSelection(mask, float(threshold), settings)
