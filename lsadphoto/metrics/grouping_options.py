"""evalglare 3.06's optional source groupings: smoothing (``-s``) and patch mode (``-z``).

Both change which pixels form a source before peak extraction, so :func:`regroup_sources`
redoes the grouping of :func:`~lsadphoto.metrics.grouping.group_sources_evalglare` with them:

Smoothing (``-s``)
    After the sources are found, every valid pixel that is not a source pixel joins a source
    when more than 20 % of the solid angle within a circle of ``radius`` pixels around it
    belongs to that source's (threshold-passing) pixels. evalglare uses one radius for the
    whole picture: r/(1.75·δ) pixels, r the ``-r`` search angle and δ twice the angle between
    the centre pixel and the one 10 columns right and 10 rows up, divided by 10
    (:func:`smoothing_radius_px`). The window is a square clipped to the picture as evalglare
    clips it (its last column and top row are left out when the square reaches them). The
    circle's solid angle counts every pixel Radiance traces, also those behind the observer:
    for the angular fisheye the pixels beyond the 180° circle up to the picture's corners
    (:func:`traced_solid_angle`), which matters for sources at the rim. A pixel
    near two sources would join both in evalglare (counted twice); sources are more than r/2
    apart and the circle is smaller than r/4, so this does not occur at the resolutions
    evalglare accepts, and here a pixel joins the last qualifying source only.
Patch mode (``-z angle 1``)
    Instead of grouping, threshold-passing pixels are assigned to fixed patches of ``angle``
    degrees laid out on the picture in rows, every second row offset by half a patch; a pixel
    goes to the nearer of the two candidate patch centres evalglare tests. Only for the
    angular fisheye (``-vta``). Patch numbers follow evalglare's layout.

Peak extraction follows either as evalglare does it: in a source holding pixels at or above
the peak limit those pixels leave it, grouped (single linkage at r/2) within that source only.

References
----------
Radiance ``src/util/evalglare.c`` v3.06 (add_secondary_gs, the ``-s`` radius, the patch
layout of ``-z``, peak extraction with find_split).
"""

import math

import numpy as np
from .._compiled import njit

from .._validation import check_positive
from ..errors import BadInputError
from .grouping import _describe, group_sources_evalglare

__all__ = ["traced_solid_angle", "smoothing_radius_px", "smoothing_labels", "patch_labels", "regroup_sources"]

#: Fraction of the circle's solid angle above which a pixel joins a source (evalglare -s).
SMOOTHING_FRACTION = 0.2


def traced_solid_angle(projection, solid_angle):
    """Solid angle [sr] of every pixel Radiance traces: for an equidistant fisheye (``-vta``)
    the same mapping continued to θ = 180° (the corners of a square picture); otherwise
    ``solid_angle`` as given."""
    from ..geometry import IdealFisheyeProjection
    from ..geometry.field import pixel_geometry

    if isinstance(projection, IdealFisheyeProjection) and projection.kind == "equidistant":
        scale = 360.0 / projection.fov_deg
        extended = IdealFisheyeProjection("equidistant", projection.cx, projection.cy,
                                          projection.radius * scale, 360.0, projection.width,
                                          projection.height)
        return pixel_geometry(extended).solid_angle
    return np.asarray(solid_angle, dtype=np.float64)


def smoothing_radius_px(directions, search_angle):
    """evalglare's smoothing radius [px]: r/(1.75·δ), δ = 2·∠(centre, centre + 10 px)/10.

    ``directions`` (rows, cols, 3) are the pixel directions, ``search_angle`` r [rad]. The
    centre is evalglare's (x, y) = (cols // 2, rows // 2) counted from the bottom.
    """
    d = np.asarray(directions, dtype=np.float64)
    rows, cols = d.shape[:2]
    row, col = rows - 1 - rows // 2, cols // 2
    if not (0 <= row - 10 and col + 10 < cols):
        raise BadInputError("the picture is too small for evalglare's smoothing radius")
    cos_angle = float(np.clip(d[row, col] @ d[row - 10, col + 10], -1.0, 1.0))
    delta = math.acos(cos_angle) * 2.0 / 10.0
    if not delta > 0:
        raise BadInputError("the picture's centre pixels have no valid directions")
    return check_positive(search_angle, "search_angle") / delta / 1.75


@njit(cache=True, nogil=True,
      aot=("void(int64[:, ::1], boolean[:, ::1], float64[:, ::1], int64[:, :], float64, "
           "int64, int64[:, ::1])"))
def _smooth(labels, primary, solid_angle, candidates, radius, n_sources, out):
    """evalglare's add_secondary_gs for every candidate pixel; arrays in evalglare's (y, x)
    order, y from the bottom."""
    ys, xs = labels.shape
    acc = np.zeros(n_sources + 1)
    for k in range(candidates.shape[0]):
        y, x = candidates[k, 0], candidates[k, 1]
        x_min = max(int(x - radius), 0)
        x_max = int(x + radius)
        if x_max > xs - 1:
            x_max = xs - 2
        y_min = max(int(y - radius), 0)
        y_max = int(y + radius)
        if y_max > ys - 1:
            y_max = ys - 2
        total = 0.0
        acc[:] = 0.0
        for ix in range(x_min, x_max + 1):
            for iy in range(y_min, y_max + 1):
                if math.sqrt((x - ix) * (x - ix) + (y - iy) * (y - iy)) <= radius:
                    w = solid_angle[iy, ix]
                    total += w
                    if primary[iy, ix]:
                        acc[labels[iy, ix]] += w
        for s in range(1, n_sources + 1):
            if total > 0 and acc[s] / total > SMOOTHING_FRACTION:
                out[y, x] = s


def smoothing_labels(labels, source_mask, solid_angle, valid, *, radius):
    """The pixels smoothing adds (evalglare ``-s``): their source number + 1, 0 elsewhere.

    Parameters
    ----------
    labels : ndarray of int, shape (rows, cols)
        Sources before peak extraction (source number + 1, 0: none).
    source_mask : ndarray of bool
        Threshold-passing pixels (evalglare's primary pixels).
    solid_angle : ndarray
        ω [sr] of every traced pixel (:func:`traced_solid_angle`).
    valid : ndarray of bool
        Pixels that may join.
    radius : float
        Circle radius [px] (:func:`smoothing_radius_px`).

    Returns
    -------
    ndarray of int64, shape (rows, cols)
    """
    labels = np.asarray(labels, dtype=np.int64)
    n = int(labels.max()) if labels.size else 0
    out = np.zeros(labels.shape, dtype=np.int64)
    if n == 0:
        return out
    # evalglare's coordinates: y counts rows from the bottom.
    flip = (slice(None, None, -1), slice(None))
    lab, prim = np.ascontiguousarray(labels[flip]), np.ascontiguousarray(
        np.asarray(source_mask, dtype=bool)[flip])
    omega = np.ascontiguousarray(np.asarray(solid_angle, dtype=np.float64)[flip])
    cand = np.asarray(valid, dtype=bool)[flip] & (lab == 0)
    # Only pixels within the radius of a source pixel can qualify.
    from scipy.ndimage import distance_transform_edt  # only where smoothing is asked for

    near = distance_transform_edt(~prim) <= radius
    candidates = np.argwhere(cand & near).astype(np.int64)
    result = np.zeros_like(lab)
    _smooth(lab, prim, omega, candidates, float(radius), n, result)
    out[flip] = result
    return out


def patch_labels(source_mask, projection, patch_deg):
    """Patch number + 1 of every threshold-passing pixel (evalglare ``-z angle 1``).

    Parameters
    ----------
    source_mask : ndarray of bool, shape (rows, cols)
    projection : IdealFisheyeProjection
        An equidistant fisheye (Radiance ``-vta``); its view angles set the layout.
    patch_deg : float
        Patch size [deg].

    Returns
    -------
    ndarray of int64, shape (rows, cols)
        Labels 1…n in evalglare's patch order, only for patches that hold pixels.
    """
    from ..io.hdr import parse_view

    if getattr(projection, "kind", None) != "equidistant":
        raise BadInputError("patch mode needs an angular fisheye (Radiance -vta), as evalglare")
    angle = check_positive(patch_deg, "patch angle")
    view = parse_view(projection.radiance_view())
    angle_h, angle_v = float(view["vh"]), float(view["vv"])
    rows, cols = np.asarray(source_mask).shape
    pdx = math.floor(cols / angle_h * angle)
    pdy = math.floor(rows / angle_v * angle)
    if pdx < 1 or pdy < 1:
        raise BadInputError(f"patch angle {angle:g}° is smaller than a pixel")
    nx = math.floor(angle_v / angle) + 1
    ny = math.floor(angle_h / angle) + 1
    x_off, y_off = pdx // 2, pdy // 2
    centre_x = np.empty(nx * ny + 1)
    centre_y = np.empty(nx * ny + 1)
    k, shift = 1, 0
    for iy in range(1, ny + 1):
        for ix in range(1, nx + 1):
            centre_x[k] = x_off + shift * x_off + (ix - 1) * pdx
            centre_y[k] = y_off + (iy - 1) * pdy
            k += 1
        shift = 1 - shift
    n_patches = nx * ny
    r_idx, c_idx = np.nonzero(np.asarray(source_mask, dtype=bool))
    y = rows - 1 - r_idx  # evalglare's y from the bottom
    x = c_idx
    lines = y // pdy
    xxx = np.maximum(x / pdx - 0.5 * (lines % 2), 0.0)
    i1 = lines * nx + np.floor(xxx).astype(np.int64) + 1
    if np.any(i1 > n_patches):
        raise BadInputError("pixels fall outside evalglare's patch layout for this view")
    add = lines % 2
    above = y > centre_y[i1]
    right = x > centre_x[i1]
    i2 = np.where(above, np.where(right, i1 + nx + add, i1 + nx - 1 + add),
                  np.where(right, i1 - nx + add, i1 - nx - 1 + add))
    inside = (i2 >= 1) & (i2 <= n_patches)
    i2c = np.clip(i2, 1, n_patches)
    d1 = (x - centre_x[i1]) ** 2 + (y - centre_y[i1]) ** 2
    d2 = (x - centre_x[i2c]) ** 2 + (y - centre_y[i2c]) ** 2
    patch = np.where(inside & ~(d1 < d2), i2c, i1)
    used, renumbered = np.unique(patch, return_inverse=True)
    out = np.zeros((rows, cols), dtype=np.int64)
    out[r_idx, c_idx] = renumbered + 1 if used.size else 0
    return out


def regroup_sources(luminance, directions, solid_angle, source_mask, valid, *, projection,
                    search_angle, peak_luminance, smooth=False, patch_deg=None):
    """Sources with evalglare's smoothing and/or patch mode, then peak extraction.

    Parameters
    ----------
    luminance : ndarray, shape (rows, cols)
        L [cd·m⁻²].
    directions : ndarray, shape (rows, cols, 3)
    solid_angle : ndarray, shape (rows, cols)
        ω [sr] (0 where invalid).
    source_mask : ndarray of bool
        Threshold-passing pixels.
    valid : ndarray of bool
        The evaluated field.
    projection : Projection
    search_angle : float
        evalglare ``-r`` [rad].
    peak_luminance : float or None
        Peak-extraction limit [cd·m⁻²] (None: off).
    smooth : bool
        evalglare ``-s``.
    patch_deg : float, optional
        evalglare ``-z patch_deg 1``.

    Returns
    -------
    sources : list of GlareSource
    labels : ndarray of int64
        As :func:`~lsadphoto.metrics.grouping.group_sources_evalglare`.
    """
    source_mask = np.asarray(source_mask, dtype=bool)
    if patch_deg is not None:
        pre = patch_labels(source_mask, projection, patch_deg)
    else:
        pre = group_sources_evalglare(luminance, directions, solid_angle, source_mask,
                                      search_angle=search_angle, peak_luminance=None)[1]
    n_pre = int(pre.max()) if pre.size else 0
    if smooth and n_pre:
        added = smoothing_labels(pre, source_mask, traced_solid_angle(projection, solid_angle),
                                 valid,
                                 radius=smoothing_radius_px(directions, search_angle))
        pre = np.where(added > 0, added, pre)
    peak_groups = []
    peak_mask = np.zeros_like(source_mask)
    if peak_luminance is not None and n_pre:
        limit = check_positive(peak_luminance, "peak_luminance")
        with np.errstate(invalid="ignore"):
            peak_mask = source_mask & (np.asarray(luminance) >= limit)
        for i in np.unique(pre[peak_mask]):
            _, peak_labels = group_sources_evalglare(
                luminance, directions, solid_angle, peak_mask & (pre == i),
                search_angle=search_angle, peak_luminance=None)
            peak_groups.append(peak_labels)
    rest = np.where(peak_mask, 0, pre)
    kept = np.unique(rest[rest > 0])
    renumber = np.zeros(n_pre + 1, dtype=np.int64)
    renumber[kept] = np.arange(1, kept.size + 1)
    labels = renumber[rest]
    n = kept.size
    for peak_labels in peak_groups:
        inside = peak_labels > 0
        labels[inside] = peak_labels[inside] + n
        n += int(peak_labels.max())
    peaks = [False] * kept.size + [True] * (n - kept.size)
    return _describe(labels, n, luminance, directions, solid_angle, peaks), labels
