"""Grouping glare-source pixels into sources, as evalglare does.

evalglare (FORMULAS.md §2.4.5–2.4.6) gives each candidate pixel the number of an earlier
source pixel within the search distance, then merges sources repeatedly whenever a pixel of
one lies within the search distance of a pixel of another. When nothing changes any more,
two pixels share a source exactly when a chain of source pixels links them in which every
step is at most r/2 apart (r the ``-r`` search *opening* angle, 0.2 rad by default; the
code tests 2·arccos(d̂₁·d̂₂) ≤ r). That fixed point is single-linkage clustering at an
angular distance of r/2, which this module computes directly: links between neighbouring
pixels plus, through a k-d tree on the unit directions, links between boundary pixels of
different patches (the closest pair of two patches always includes a boundary pixel). It
does not depend on scan order, which evalglare's merge rule (a source moves into a *larger*
one) only affects for exact ties in solid angle.

Peak extraction (``-y``, on by default): when a source holds pixels at or above the peak
limit (50 000 cd·m⁻²), those pixels leave it and form sources of their own, grouped in the
same way; the parent keeps the rest. evalglare's first pass joins split pixels at r/4 and
then merges the split sources at r/2, which again ends in single linkage at r/2.

Not reproduced: evalglare's optional smoothing (``-s``, off by default), and its
unconditional linking of vertically adjacent pixels in the first scan, which differs from
the rule above only when the pixel pitch exceeds r/2 (images narrower than about 30 pixels
across 180°).

References
----------
Wienold, J., Christoffersen, J. (2006), Energy and Buildings 38, 743–757; Radiance
``src/util/evalglare.c`` (find_near_pgs, find_split, peak extraction); FORMULAS.md §2.4.5–6.
"""

from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage, sparse
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .._validation import check_positive

__all__ = ["GlareSource", "group_sources_evalglare", "DEFAULT_SEARCH_ANGLE",
           "DEFAULT_PEAK_LUMINANCE"]

#: evalglare's ``-r`` search opening angle [rad].
DEFAULT_SEARCH_ANGLE = 0.2
#: evalglare's peak-extraction limit ``-Y`` [cd·m⁻²].
DEFAULT_PEAK_LUMINANCE = 50000.0

_EIGHT = np.ones((3, 3), dtype=bool)


@dataclass(frozen=True)
class GlareSource:
    """One grouped glare source.

    Attributes
    ----------
    luminance : float
        ω-weighted mean luminance L_s [cd·m⁻²].
    solid_angle : float
        ω_s [sr].
    direction : tuple of float
        L·ω-weighted mean direction, normalised (camera frame) — the source's centroid.
    row, col : float
        L·ω-weighted centroid in image coordinates [px].
    max_luminance, min_luminance : float
        Extremes of the source's pixels [cd·m⁻²].
    n_pixels : int
        Number of pixels.
    peak : bool
        True for a source split off by peak extraction.
    """

    luminance: float
    solid_angle: float
    direction: tuple
    row: float
    col: float
    max_luminance: float
    min_luminance: float
    n_pixels: int
    peak: bool = False


def _chord(angle):
    """Chord length between unit vectors ``angle`` [rad] apart."""
    return 2.0 * np.sin(angle / 2.0)


def _link(mask, directions, separation):
    """Single-linkage labels (1…n, 0 elsewhere) of ``mask`` pixels at angular ``separation``."""
    labels = np.zeros(mask.shape, dtype=np.int64)
    index = np.flatnonzero(mask.T.ravel())  # column-major order, like evalglare's scan
    if index.size == 0:
        return labels, 0
    rows_t, cols_t = np.unravel_index(index, mask.T.shape)
    rows, cols = cols_t, rows_t
    node = np.full(mask.shape, -1, dtype=np.int64)
    node[rows, cols] = np.arange(index.size)
    pts = directions[rows, cols].astype(np.float64)
    chord = _chord(separation)
    edges_a, edges_b = [], []
    # Neighbouring pixels (right, down, down-right, down-left), if close enough.
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        r2, c2 = rows + dr, cols + dc
        ok = (r2 < mask.shape[0]) & (c2 >= 0) & (c2 < mask.shape[1])
        a = np.flatnonzero(ok)
        b = node[r2[ok], c2[ok]]
        keep = b >= 0
        a, b = a[keep], b[keep]
        close = np.linalg.norm(pts[a] - pts[b], axis=-1) <= chord
        edges_a.append(a[close])
        edges_b.append(b[close])
    # Boundary pixels of different patches within reach of each other.
    boundary = mask & ~ndimage.binary_erosion(mask, structure=_EIGHT, border_value=0)
    bnodes = node[boundary]
    if bnodes.size > 1:
        pairs = cKDTree(pts[bnodes]).query_pairs(chord, output_type="ndarray")
        edges_a.append(bnodes[pairs[:, 0]])
        edges_b.append(bnodes[pairs[:, 1]])
    a = np.concatenate(edges_a)
    b = np.concatenate(edges_b)
    graph = sparse.coo_matrix((np.ones(a.size, dtype=np.int8), (a, b)),
                              shape=(index.size, index.size))
    n, component = connected_components(graph, directed=False)
    # Number sources in order of their first pixel in the column-major scan.
    first = np.full(n, index.size, dtype=np.int64)
    np.minimum.at(first, component, np.arange(index.size))
    order = np.argsort(np.argsort(first))
    labels[rows, cols] = order[component] + 1
    return labels, n


def _describe(labels, n, luminance, directions, solid_angle, peak_flags):
    if n == 0:
        return []
    flat = labels.ravel()
    sel = flat > 0
    lab = flat[sel] - 1
    L = luminance.ravel()[sel].astype(np.float64)
    w = solid_angle.ravel()[sel].astype(np.float64)
    d = directions.reshape(-1, 3)[sel].astype(np.float64)
    rows, cols = np.divmod(np.flatnonzero(sel), labels.shape[1])
    lw = L * w
    omega = np.bincount(lab, w, n)
    sum_lw = np.bincount(lab, lw, n)
    dirs = np.stack([np.bincount(lab, lw * d[:, k], n) for k in range(3)], axis=-1)
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    row_c = np.bincount(lab, lw * rows, n) / sum_lw
    col_c = np.bincount(lab, lw * cols, n) / sum_lw
    lmax = np.full(n, -np.inf)
    lmin = np.full(n, np.inf)
    np.maximum.at(lmax, lab, L)
    np.minimum.at(lmin, lab, L)
    count = np.bincount(lab, minlength=n)
    return [GlareSource(float(sum_lw[i] / omega[i]), float(omega[i]), tuple(map(float, dirs[i])),
                        float(row_c[i]), float(col_c[i]), float(lmax[i]), float(lmin[i]),
                        int(count[i]), bool(peak_flags[i]))
            for i in range(n)]


def group_sources_evalglare(luminance, directions, solid_angle, source_mask, *,
                            search_angle=DEFAULT_SEARCH_ANGLE,
                            peak_luminance=DEFAULT_PEAK_LUMINANCE):
    """Group glare-source pixels into sources the way evalglare does (see module notes).

    Parameters
    ----------
    luminance : ndarray, shape (rows, cols)
        L [cd·m⁻²].
    directions : ndarray, shape (rows, cols, 3)
        Unit pixel directions.
    solid_angle : ndarray, shape (rows, cols)
        ω [sr].
    source_mask : ndarray of bool, shape (rows, cols)
        Glare-source pixels (from :func:`~lsadphoto.metrics.sources.select_source_pixels`).
    search_angle : float
        evalglare's ``-r`` opening angle r [rad]; pixels up to r/2 apart are linked.
    peak_luminance : float or None
        Peak-extraction limit [cd·m⁻²]; ``None`` switches it off (evalglare ``-x``).

    Returns
    -------
    sources : list of GlareSource
    labels : ndarray of int, shape (rows, cols)
        Source number + 1 per pixel (0: not a source), indexing ``sources``.
    """
    separation = check_positive(search_angle, "search_angle") / 2.0
    full_mask = np.asarray(source_mask, dtype=bool)
    labels_full = np.zeros(full_mask.shape, dtype=np.int64)
    rows_any = np.flatnonzero(full_mask.any(axis=1))
    if rows_any.size == 0:
        return [], labels_full
    # Work inside the sources' bounding box: the rest of the picture holds no source pixel.
    cols_any = np.flatnonzero(full_mask[rows_any[0]:rows_any[-1] + 1].any(axis=0))
    box = (slice(rows_any[0], rows_any[-1] + 1), slice(cols_any[0], cols_any[-1] + 1))
    mask = full_mask[box]
    luminance = np.asarray(luminance)[box]
    directions = np.asarray(directions)[box]
    solid_angle = np.asarray(solid_angle)[box]
    labels, n = _link(mask, directions, separation)
    peak_flags = [False] * n
    if peak_luminance is not None and n:
        limit = check_positive(peak_luminance, "peak_luminance")
        with np.errstate(invalid="ignore"):
            peak_mask = mask & (luminance >= limit)
        if peak_mask.any():
            peak_labels, n_peak = _link(peak_mask, directions, separation)
            rest = np.where(peak_mask, 0, labels)
            kept = np.unique(rest[rest > 0])
            renumber = np.zeros(n + 1, dtype=np.int64)
            renumber[kept] = np.arange(1, kept.size + 1)
            labels = np.where(peak_mask, peak_labels + kept.size, renumber[rest])
            n = kept.size + n_peak
            peak_flags = [False] * kept.size + [True] * n_peak
    sources = _describe(labels, n, luminance, directions, solid_angle, peak_flags)
    offset_row, offset_col = box[0].start, box[1].start
    sources = [replace(s, row=s.row + offset_row, col=s.col + offset_col) for s in sources]
    labels_full[box] = labels
    return sources, labels_full
