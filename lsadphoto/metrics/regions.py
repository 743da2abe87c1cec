"""Regions of the visual field as evalglare 3.06 evaluates them: band, zones, mask.

Three kinds of region, each with the same luminance statistics (:func:`region_statistics`):

Horizontal band (evalglare ``-B angle``)
    In every image column, the pixels within the band's half-width of the pixel in the
    middle row of that column, ``arccos(d̂·d̂_mid) ≤ half_width``, plus the middle row itself.
    The middle row is evalglare's ``y_mid = (rows − 1) // 2`` counted from the bottom, i.e.
    row ``rows − 1 − (rows − 1)//2`` counted from the top as here.
Zones (``-l x y angle`` and ``-L x y angle1 angle2``)
    Zone 1 holds the pixels whose angle to the zone centre, doubled, is at most
    ``opening_angles[0]`` (a cone of full opening angle ``angle1``); zone 2 the ring up to
    ``angle2``. A glare source with pixels in a zone is split as evalglare splits it: its
    pixels in zone 1 form one new source, those in zone 2 another, and the rest stays
    (:func:`split_sources_at_zones`). Each source records its zone (0: outside).
Mask (``-A maskfile``)
    The pixels of a picture of the same size whose luminance exceeds 0.1 cd·m⁻² (evalglare
    reads a mask picture as luminance). The mask should be the window: PGSV and its
    saturation and contrast forms (:func:`pgsv_Tokura1996` and friends) describe it.

Only valid pixels count (in front of the observer, positive solid angle), as in evalglare.

Statistics are weighted as evalglare weights them (Radiance ``muc_randvar.c``): the mean
luminance by solid angle (ΣL·ω/Σω), but the median, the 75th and 95th percentiles and the
standard deviation over the *pixels*, each pixel counting once (evalglare adds unweighted
samples); the standard deviation is the population one, √(E[L²] − E[L]²). The median of an
even count is the mean of the two middle values; a percentile p is the mean of the sorted
values at indices ⌊n·p⌋ and ⌊n·p − 1⌋ (evalglare's ``muc_rvar_get_percentile`` always
averages those two). On a fisheye, where pixel solid angles vary, the pixel median is not the
solid-angle median (:func:`~lsadphoto.metrics.statistics.luminance_statistics` gives that).

References
----------
Radiance ``src/util/evalglare.c`` v3.06 (``-B``, ``-l``, ``-L``, ``-A``; ``get_pgsv``,
``get_pgsv_con``, ``get_pgsv_sat``) and ``src/common/muc_randvar.c`` (median, percentile,
variance). Tokura, M., Iwata, T., Shukuya, M. (1996), Development of a method for evaluating
discomfort glare from a large source, J. Archit. Plann. Environ. Eng. (AIJ) 489, 17–25 (PGSV).
Wienold, J., Iwata, T., Sarey Khanie, M., Erell, E., Kaftan, E., Rodriguez, R. G., Yamin
Garreton, J. A., Tzempelikos, T., Konstantzos, I., Christoffersen, J., Kuhn, T. E.,
Pierson, C., Andersen, M. (2019), Cross-validation and robustness of daylight glare metrics,
Lighting Res. Technol. 51(7), 983–1013 (PGSV_sat as coded in evalglare).
"""

import math

import numpy as np

from .._validation import check_array, check_positive
from ..errors import BadInputError

__all__ = ["MASK_THRESHOLD", "REGION_KEYS", "region_statistics", "band_region", "zone_map",
           "zone_statistics", "mask_region", "pgsv_saturation", "pgsv_Tokura1996",
           "pgsv_evalglare", "split_sources_at_zones"]

#: Luminance [cd·m⁻²] above which a mask picture's pixel belongs to the mask (evalglare 3.06).
MASK_THRESHOLD = 0.1

#: Keys of a region's statistics record.
REGION_KEYS = ("solid_angle", "mean", "median", "std", "p75", "p95", "min", "max", "n_pixels")


def _sorted_percentile(values, fraction):
    """evalglare's percentile of sorted ``values``: mean of indices ⌊n·p⌋ and ⌊n·p − 1⌋
    (C truncation towards zero)."""
    n = values.size
    return 0.5 * (float(values[int(n * fraction)]) + float(values[int(n * fraction - 1)]))


def region_statistics(luminance, solid_angle, region):
    """Luminance statistics of a region, weighted as evalglare weights them.

    Parameters
    ----------
    luminance : ndarray, shape (rows, cols)
        L [cd·m⁻²].
    solid_angle : ndarray, shape (rows, cols)
        ω [sr].
    region : ndarray of bool, shape (rows, cols)
        The region's pixels (already restricted to valid pixels).

    Returns
    -------
    dict
        ``solid_angle`` Σω [sr]; ``mean`` ΣL·ω/Σω, ``median``, ``std``, ``p75``, ``p95``,
        ``min``, ``max`` [cd·m⁻²] (see the module notes for the weighting); ``n_pixels``.
        Luminance entries are None for an empty region.

    Examples
    --------
    Four pixels, one of them four times larger: the mean is weighted by solid angle, the
    median is not.

    >>> s = region_statistics(np.array([1.0, 2.0, 3.0, 10.0]), np.array([1.0, 1.0, 1.0, 4.0]),
    ...                       np.ones(4, bool))
    >>> s["mean"], s["median"], s["n_pixels"]
    (6.571428571428571, 2.5, 4)

    References
    ----------
    Radiance ``src/common/muc_randvar.c`` (muc_rvar_get_median, muc_rvar_get_percentile,
    muc_rvar_get_vx); ``src/util/evalglare.c`` v3.06.
    """
    region = np.asarray(region, dtype=bool)
    values = np.asarray(luminance, dtype=np.float64)[region]
    omega = np.asarray(solid_angle, dtype=np.float64)[region]
    n = int(values.size)
    out = {"solid_angle": float(omega.sum()), "n_pixels": n}
    if n == 0 or not out["solid_angle"] > 0:
        out.update({key: None for key in REGION_KEYS if key not in out})
        return out
    ordered = np.sort(values)
    median = float(ordered[n // 2]) if n % 2 else 0.5 * float(ordered[n // 2] + ordered[n // 2 - 1])
    out.update(mean=float(np.sum(values * omega) / out["solid_angle"]), median=median,
               std=float(np.std(values)), p75=_sorted_percentile(ordered, 0.75),
               p95=_sorted_percentile(ordered, 0.95), min=float(ordered[0]),
               max=float(ordered[-1]))
    return {key: out[key] for key in REGION_KEYS}


def band_region(directions, valid, *, half_width):
    """Pixels of evalglare's horizontal band (``-B``) about the middle row.

    Parameters
    ----------
    directions : ndarray, shape (rows, cols, 3)
        Unit pixel directions (NaN where invalid).
    valid : ndarray of bool, shape (rows, cols)
        Pixels that take part (in front of the observer, ω > 0).
    half_width : float
        The band's half-width [rad], 0 < half_width ≤ π: a pixel belongs to the band when its
        angle to the middle-row pixel of its column is at most ``half_width``.

    Returns
    -------
    ndarray of bool, shape (rows, cols)

    References
    ----------
    Radiance ``src/util/evalglare.c`` v3.06 (``-B``: ``acos(DOT(dir(x, y_mid), dir(x, y)))
    <= band_angle || y == y_mid``).
    """
    width = check_positive(half_width, "band half-width")
    if width > math.pi:
        raise BadInputError(f"band half-width must be at most 180°, got {math.degrees(width):g}°")
    d = np.asarray(directions, dtype=np.float64)
    rows = d.shape[0]
    middle = rows - 1 - (rows - 1) // 2
    with np.errstate(invalid="ignore"):
        cos_angle = np.clip(np.einsum("rck,ck->rc", d, d[middle]), -1.0, 1.0)
        band = np.arccos(cos_angle) <= width
    band[middle] = True
    return band & np.asarray(valid, dtype=bool)


def zone_map(directions, valid, centre, *, opening_angles):
    """Zone number of every pixel (evalglare ``-l``/``-L``): 1, 2, or 0 outside the zones.

    Parameters
    ----------
    directions : ndarray, shape (rows, cols, 3)
        Unit pixel directions (NaN where invalid).
    valid : ndarray of bool, shape (rows, cols)
    centre : array_like, shape (3,)
        Zone centre direction (camera frame).
    opening_angles : sequence of one or two float
        Full opening angles [rad] of zone 1 and, optionally, of the outer edge of the ring
        zone 2 (larger than the first). A pixel is in zone 1 when twice its angle to the
        centre is at most the first angle.

    Returns
    -------
    ndarray of int8, shape (rows, cols)

    References
    ----------
    Radiance ``src/util/evalglare.c`` v3.06 (zones: ``acos(DOT(dir, dir_zone))·2 <= angle_z1``,
    ``angle_z1 < r <= angle_z2``).
    """
    angles = [check_positive(a, "zone opening angle") for a in opening_angles]
    if len(angles) not in (1, 2):
        raise BadInputError(f"zones take one or two opening angles, got {len(angles)}")
    if len(angles) == 2 and not angles[1] > angles[0]:
        raise BadInputError("the outer zone angle must be larger than the inner one, got "
                            f"{math.degrees(angles[0]):g}° and {math.degrees(angles[1]):g}°")
    c = check_array(centre, "zone centre", shape=(3,), finite=True, dtype=float)
    norm = np.linalg.norm(c)
    if norm == 0:
        raise BadInputError("the zone centre must not be the zero vector")
    d = np.asarray(directions, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        r = 2.0 * np.arccos(np.clip(d @ (c / norm), -1.0, 1.0))
        out = np.where(r <= angles[0], 1, 0).astype(np.int8)
        if len(angles) == 2:
            out[(r > angles[0]) & (r <= angles[1])] = 2
    out[~np.asarray(valid, dtype=bool)] = 0
    return out


def zone_statistics(luminance, solid_angle, cos_sigma, zones):
    """Statistics of each zone of :func:`zone_map`, with its illuminance at the eye.

    Parameters
    ----------
    luminance, solid_angle, cos_sigma : ndarray, shape (rows, cols)
        L [cd·m⁻²], ω [sr], cos σ to the line of sight [–].
    zones : ndarray of int, shape (rows, cols)
        Zone numbers (0 outside).

    Returns
    -------
    list of dict
        One record per zone number present in the map's definition (1, or 1 and 2): the keys
        of :func:`region_statistics` and ``illuminance``, Σ L·cos σ·ω over the zone [lx]
        (evalglare's Ez1, Ez2).
    """
    zones = np.asarray(zones)
    out = []
    for k in range(1, max(1, int(zones.max())) + 1):
        region = zones == k
        record = region_statistics(luminance, solid_angle, region)
        record["illuminance"] = float(np.sum(
            np.asarray(luminance, np.float64)[region] * np.asarray(cos_sigma, np.float64)[region]
            * np.asarray(solid_angle, np.float64)[region]))
        out.append(record)
    return out


def mask_region(mask, valid):
    """Pixels of a mask (evalglare ``-A``): a picture's luminance above 0.1 cd·m⁻², or a boolean
    array, restricted to valid pixels.

    Parameters
    ----------
    mask : ndarray, shape (rows, cols)
        Boolean mask, or a luminance picture [cd·m⁻²] (NaN counts as outside).
    valid : ndarray of bool, shape (rows, cols)

    Returns
    -------
    ndarray of bool, shape (rows, cols)
    """
    mask = np.asarray(mask)
    valid = np.asarray(valid, dtype=bool)
    if mask.shape != valid.shape:
        raise BadInputError(f"the mask is {mask.shape[1]}×{mask.shape[0]} pixels but the map "
                            f"is {valid.shape[1]}×{valid.shape[0]}: they must be the same size"
                            if mask.ndim == 2 else f"the mask must be a 2-d picture, got shape "
                            f"{mask.shape}")
    if mask.dtype == bool:
        return mask & valid
    with np.errstate(invalid="ignore"):
        return (mask.astype(np.float64) > MASK_THRESHOLD) & valid


def pgsv_saturation(vertical_illuminance):
    """Saturation form of the predicted glare sensation vote, PGSV_sat [–].

    PGSV_sat = 3.3 − 3.87/(1 + (E_v/(π·1250))^1.7), E_v [lx].

    Examples
    --------
    >>> round(pgsv_saturation(1250 * math.pi), 3)
    1.365

    References
    ----------
    Wienold et al. (2019), Lighting Res. Technol. 51(7), 983–1013; Radiance
    ``src/util/evalglare.c`` v3.06 (get_pgsv_sat).
    """
    e_v = float(vertical_illuminance)
    if not e_v >= 0:
        return math.nan
    return 3.3 - (0.57 + 3.3) / (1.0 + (e_v / math.pi / 1250.0) ** 1.7)


def _pgsv_background(mean_luminance, window_luminance, window_solid_angle):
    """evalglare's PGSV background: the hemisphere's mean luminance without the window,
    (2π·L̄ − L_w·ω_w)/(2π − ω_w) [cd·m⁻²]."""
    return (2.0 * math.pi * mean_luminance - window_luminance * window_solid_angle) / (
        2.0 * math.pi - window_solid_angle)


def pgsv_Tokura1996(window_luminance, window_solid_angle, mean_luminance):
    """Predicted glare sensation vote of a window, contrast form PGSV_con [–].

    PGSV = 3.2·log L_w − 0.64·log ω_w + (0.79·log ω_w − 0.61)·log L_b − 8.2, with L_w the
    window's mean luminance [cd·m⁻²], ω_w its solid angle [sr] and L_b the background as in
    evalglare: (2π·L̄ − L_w·ω_w)/(2π − ω_w), L̄ the field's mean luminance [cd·m⁻²].
    NaN where a logarithm is undefined.

    References
    ----------
    Tokura, Iwata, Shukuya (1996), J. Archit. Plann. Environ. Eng. (AIJ) 489, 17–25;
    Radiance ``src/util/evalglare.c`` v3.06 (get_pgsv_con).
    """
    l_w, w = float(window_luminance), float(window_solid_angle)
    l_b = _pgsv_background(float(mean_luminance), l_w, w)
    if not (l_w > 0 and w > 0 and l_b > 0):
        return math.nan
    return (3.2 * math.log10(l_w) - 0.64 * math.log10(w)
            + (0.79 * math.log10(w) - 0.61) * math.log10(l_b) - 8.2)


def pgsv_evalglare(vertical_illuminance, window_luminance, window_solid_angle, mean_luminance,
                   task_luminance):
    """PGSV as evalglare chooses it: the contrast form where the window's contrast with its
    background exceeds E_v/(π·L_task), else the saturation form [–].

    Parameters
    ----------
    vertical_illuminance : float
        E_v [lx].
    window_luminance, window_solid_angle : float
        The mask's mean luminance [cd·m⁻²] and solid angle [sr].
    mean_luminance : float
        The field's mean luminance L̄ [cd·m⁻²].
    task_luminance : float
        Mean luminance of the task area [cd·m⁻²] (evalglare ``-t``); without one PGSV has no
        value (NaN; evalglare prints −99).

    References
    ----------
    Radiance ``src/util/evalglare.c`` v3.06 (get_pgsv).
    """
    l_task = float(task_luminance) if task_luminance is not None else math.nan
    if not l_task > 0:
        return math.nan
    l_w, w = float(window_luminance), float(window_solid_angle)
    l_b = _pgsv_background(float(mean_luminance), l_w, w)
    if l_b == 0:
        return math.nan
    if l_w / l_b > float(vertical_illuminance) / (math.pi * l_task):
        return pgsv_Tokura1996(l_w, w, mean_luminance)
    return pgsv_saturation(vertical_illuminance)


def split_sources_at_zones(labels, zones):
    """Split glare sources at zone borders as evalglare does (``-l``/``-L``).

    Each source's pixels in zone 1 become one new source and its pixels in zone 2 another;
    the pixels outside the zones stay in the source (which disappears when none is left).

    Parameters
    ----------
    labels : ndarray of int, shape (rows, cols)
        Source number + 1 per pixel (0: not a source), as
        :func:`~lsadphoto.metrics.grouping.group_sources_evalglare` returns.
    zones : ndarray of int, shape (rows, cols)
        Zone number per pixel (:func:`zone_map`).

    Returns
    -------
    new_labels : ndarray of int64, shape (rows, cols)
        Renumbered labels 1…m (0: not a source): first the sources' parts outside the zones
        in their old order, then the zone parts, by old source and zone.
    parent : ndarray of int64, shape (m,)
        Old source index (0-based) of each new source.
    zone : ndarray of int64, shape (m,)
        Zone of each new source (0 outside the zones).

    Examples
    --------
    >>> new, parent, zone = split_sources_at_zones(np.array([[1, 1, 2]]), np.array([[0, 1, 1]]))
    >>> new.tolist(), parent.tolist(), zone.tolist()
    ([[1, 2, 3]], [0, 0, 1], [0, 1, 1])
    """
    labels = np.asarray(labels, dtype=np.int64)
    zones = np.asarray(zones, dtype=np.int64)
    if labels.shape != zones.shape:
        raise BadInputError(f"labels {labels.shape} and zones {zones.shape} differ in shape")
    key = np.where(labels > 0, zones * (labels.max() + 1) + labels, 0)
    present = np.unique(key[key > 0])
    # Order: zone 0 parts by old label, then zone 1 and 2 parts by old label and zone.
    old, zone_of = present % (labels.max() + 1), present // (labels.max() + 1)
    order = np.lexsort((zone_of, old, zone_of > 0))
    present, old, zone_of = present[order], old[order], zone_of[order]
    lookup = np.zeros(int(key.max()) + 1, dtype=np.int64)
    lookup[present] = np.arange(1, present.size + 1)
    return lookup[key], old - 1, zone_of
