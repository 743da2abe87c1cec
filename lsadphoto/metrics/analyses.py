"""evalglare 3.06's optional analyses of a scored map, gathered for :func:`score_map`.

:func:`~lsadphoto.metrics.score.score_map` calls :func:`zone_split` after grouping (zones
change the sources, and so every index) and :func:`evalglare_analyses` at the end; both
compose the public functions of :mod:`~lsadphoto.metrics.regions`,
:mod:`~lsadphoto.metrics.veiling` and :mod:`~lsadphoto.metrics.contributions`. Option
names and their evalglare equivalents:

==========================  ==============  ==========================================
score_map keyword           evalglare       result
==========================  ==============  ==========================================
``band_deg``                ``-B``          ``band``
``zone_centre``,            ``-l``/``-L``   ``zones``; sources split, each with ``zone``
``zone_opening_deg``
``mask``                    ``-A``          ``mask`` (with PGSV, PGSV_sat, PGSV_con)
``task_direction``,         ``-t``          ``task`` (L_t; PGSV; the task source rule)
``task_opening_deg``
``age``                     (CIE 146)       age factor of Lveil_cie
==========================  ==============  ==========================================

Angles are in degrees with evalglare's meaning: the band's half-width, the full opening
angles of zones and task cone. A centre is a direction (3 numbers, camera frame) or an image
point ``(row, col)``.

References
----------
Radiance ``src/util/evalglare.c`` v3.06.
"""

import math

import numpy as np

from .._validation import check_array, check_positive
from ..errors import BadInputError
from ..geometry.field import direction_map
from .contributions import glare_term_sum, source_columns, source_illuminance
from .regions import (
    band_region,
    mask_region,
    pgsv_evalglare,
    pgsv_saturation,
    pgsv_Tokura1996,
    region_statistics,
    split_sources_at_zones,
    zone_map,
    zone_statistics,
)
from .veiling import veiling_luminance_CIE146, veiling_luminance_Poynter

__all__ = ["centre_direction", "zone_split", "evalglare_analyses"]


def centre_direction(value, projection, name):
    """A direction (3 numbers) as given, or that of the image point (row, col) [px].

    Raises :class:`BadInputError` for a point off the image or outside its valid area.
    """
    value = check_array(value, name, finite=True, dtype=float)
    if value.shape == (3,):
        return value
    if value.shape != (2,):
        raise BadInputError(f"{name} must be a direction X,Y,Z or an image point ROW,COL, got "
                            f"{value.tolist()}")
    row, col = value
    rows, cols = projection.height, projection.width
    if not (-0.5 <= row <= rows - 0.5 and -0.5 <= col <= cols - 0.5):
        raise BadInputError(f"{name} ({row:g}, {col:g}) is off the image ({rows} rows × {cols} "
                            "columns)")
    direction = np.asarray(projection.directions(row, col), dtype=float)
    if not np.all(np.isfinite(direction)):
        raise BadInputError(f"{name} ({row:g}, {col:g}) lies outside the image's valid area")
    return direction


def _opening(values, name, *, count=(1, 2)):
    values = [values] if np.ndim(values) == 0 else list(values)
    if len(values) not in count:
        raise BadInputError(f"{name} takes {' or '.join(map(str, count))} angles, got {len(values)}")
    out = []
    for v in values:
        deg = check_positive(v, name)
        if deg > 360.0:
            raise BadInputError(f"{name} must be at most 360°, got {deg:g}°")
        out.append(math.radians(deg))
    return out


def zone_split(labels, *, directions, valid, projection, zone_centre, zone_opening_deg):
    """Zone map and the zone split of the source labels (see
    :func:`~lsadphoto.metrics.regions.split_sources_at_zones`).

    Returns ``(zones, new_labels, parent, source_zone)``.
    """
    centre = centre_direction(zone_centre, projection, "zone centre")
    zones = zone_map(directions, valid, centre,
                     opening_angles=_opening(zone_opening_deg, "zone opening angle"))
    new_labels, parent, source_zone = split_sources_at_zones(labels, zones)
    return zones, new_labels, parent, source_zone


def evalglare_analyses(*, luminance, solid_angle, directions, cos_sigma, valid,
                       projection, labels, sources, unsplit_sources, values, dgp_coefficients,
                       labelled=None, zones=None, source_zones=None, band_deg=None, mask=None,
                       task_direction=None, task_opening_deg=20.0, age=None):
    """Every optional analysis of a scored map (see the module notes).

    Parameters
    ----------
    luminance, solid_angle, cos_sigma : ndarray, shape (rows, cols)
        L [cd·m⁻²] (NaN where invalid), ω [sr] (0 where invalid), cos σ [–].
    directions : ndarray, shape (rows, cols, 3), or PixelGeometry
        The pixel directions, or the geometry that makes them (only if a band or a task
        needs them: :func:`~lsadphoto.geometry.field.direction_map`).
    valid : ndarray of bool
        The evaluated field.
    projection : Projection
    labels : ndarray of int
        Source labels after any zone split.
    labelled : ndarray of bool, optional
        Pixels that may carry a label (e.g. the glare-source selection), where the labels
        are read (:func:`~lsadphoto.metrics.contributions.source_illuminance`).
    sources, unsplit_sources : list
        Scored sources (luminance, solid_angle, position_index, sigma_deg) after and before
        the zone split.
    values : dict
        The scalar metrics so far (``vertical_illuminance``, ``mean_luminance``, ``dgp_raw``).
    dgp_coefficients : tuple of 8 float
        (a1…a5, c1, c2, c3).
    zones, source_zones : ndarray, optional
        Zone map and each source's zone (from :func:`zone_split`).
    band_deg : float, optional
        Band half-width [deg], 0 < A ≤ 180.
    mask : ndarray or LuminanceMap, optional
    task_direction : array_like, optional
        Task centre: direction or image point (row, col).
    task_opening_deg : float
        Full opening angle of the task cone [deg].
    age : float, optional
        Observer age [years] (CIE age factor of Lveil_cie).

    Returns
    -------
    record : dict
        ``band``, ``zones``, ``mask``, ``task`` entries that apply.
    per_source : list of dict
        evalglare's ``-d`` columns per source (:func:`~lsadphoto.metrics.contributions.source_columns`).
    regions : dict
        The band and mask pixels (boolean arrays) where computed, for the check picture.
    extra_values : dict
        ``veiling_luminance_poynter``, ``veiling_luminance_cie`` [cd·m⁻²] and
        ``task_luminance`` [cd·m⁻²] (L_t: the task's, else the mean luminance, as evalglare
        prints).
    """
    record, regions = {}, {}
    e_v = float(values["vertical_illuminance"])
    mean_l = float(values["mean_luminance"])
    if band_deg is not None:
        deg = check_positive(band_deg, "band angle")
        if deg > 180.0:
            raise BadInputError(f"band angle must be at most 180°, got {deg:g}°")
        regions["band"] = band_region(direction_map(directions), valid,
                                      half_width=math.radians(deg))
        record["band"] = region_statistics(luminance, solid_angle, regions["band"])
    if zones is not None:
        record["zones"] = zone_statistics(luminance, solid_angle, cos_sigma, zones)
    task_l = None
    if task_direction is not None:
        centre = centre_direction(task_direction, projection, "task centre")
        opening = _opening(task_opening_deg, "task opening angle", count=(1,))
        task = zone_map(direction_map(directions), valid, centre, opening_angles=opening) == 1
        stats = region_statistics(luminance, solid_angle, task)
        task_l = stats["mean"]
        record["task"] = {"luminance": task_l, "solid_angle": stats["solid_angle"],
                          "n_pixels": stats["n_pixels"], "opening_deg": float(task_opening_deg),
                          "direction": [float(c) for c in centre / np.linalg.norm(centre)]}
    if mask is not None:
        picture = getattr(mask, "luminance", mask)
        region = regions["mask"] = mask_region(picture, valid)
        stats = region_statistics(luminance, solid_angle, region)
        stats["illuminance"] = float(np.sum(np.where(region, luminance * cos_sigma * solid_angle,
                                                     0.0)))
        w, l_w = stats["solid_angle"], stats["mean"]
        if l_w is None:
            raise BadInputError("the mask selects no valid pixel of the map")
        stats["PGSV"] = pgsv_evalglare(e_v, l_w, w, mean_l, task_l)
        stats["PGSV_sat"] = pgsv_saturation(e_v)
        stats["PGSV_con"] = pgsv_Tokura1996(l_w, w, mean_l)
        record["mask"] = stats
    # Per-source -d columns; θ is σ where the position index is taken (evalglare: the pixel
    # of the source's pixel centroid, whose angle evalglare prints as both Sigma and teta).
    n = len(sources)
    theta = np.radians([s.sigma_deg for s in sources]) if n else np.zeros(0)
    s_l = np.array([s.luminance for s in sources], dtype=float)
    s_w = np.array([s.solid_angle for s in sources], dtype=float)
    s_p = np.array([s.position_index for s in sources], dtype=float)
    e_glare = source_illuminance(labels, n, luminance, cos_sigma, solid_angle, labelled)
    unsplit = glare_term_sum([s.luminance for s in unsplit_sources],
                             [s.solid_angle for s in unsplit_sources],
                             [s.position_index for s in unsplit_sources])
    a3, c2 = dgp_coefficients[2], dgp_coefficients[6]
    per_source = source_columns(s_l, s_w, s_p, theta, e_glare, vertical_illuminance=e_v,
                                dgp=float(values["dgp_raw"]), unsplit_sum=unsplit, c2=c2, a3=a3,
                                zones=source_zones, age=age)
    extra = {
        "veiling_luminance_poynter": veiling_luminance_Poynter(s_l, s_w, theta),
        "veiling_luminance_cie": float(np.sum(veiling_luminance_CIE146(e_glare, theta, age=age))),
        "task_luminance": task_l if task_l is not None else mean_l,
    }
    return record, per_source, regions, extra
