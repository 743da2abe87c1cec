"""Grouping glare-source pixels into sources, as evalglare does.

evalglare (FORMULAS.md §2.4.5–2.4.6) gives each candidate pixel the number of an earlier
source pixel within the search distance, then merges sources repeatedly whenever a pixel of
one lies within the search distance of a pixel of another. When nothing changes any more,
two pixels share a source exactly when a chain of source pixels links them in which every
step is at most r/2 apart (r the ``-r`` search *opening* angle, 0.2 rad by default; the
code tests 2·arccos(d̂₁·d̂₂) ≤ r). That fixed point is single-linkage clustering at an
angular distance of r/2, which this module computes directly: links between neighbouring
pixels plus, through a grid of cubes on the unit directions, links between boundary pixels of
different patches (the closest pair of two patches always includes a boundary pixel). It
does not depend on scan order, which evalglare's merge rule (a source moves into a *larger*
one) only affects for exact ties in solid angle.

Peak extraction (``-y``, on by default): when a source holds pixels at or above the peak
limit (50 000 cd·m⁻²), those pixels leave it and form sources of their own, grouped in the
same way; the parent keeps the rest. evalglare's first pass joins split pixels at r/4 and
then merges the split sources at r/2, which again ends in single linkage at r/2.

Each source carries both of its centroids: the L·ω-weighted mean direction and the
L·ω-weighted mean pixel position; :func:`position_pixel_evalglare` gives the pixel at which
evalglare takes the source's position index.

Not reproduced: evalglare's optional smoothing (``-s``, off by default), and its
unconditional linking of vertically adjacent pixels in the first scan, which differs from
the rule above only when the pixel pitch exceeds r/2 (images narrower than about 30 pixels
across 180°).

References
----------
Wienold, J., Christoffersen, J. (2006), Energy and Buildings 38, 743–757; Radiance
``src/util/evalglare.c`` (find_near_pgs, find_split, peak extraction); FORMULAS.md §2.4.5–6.
"""

import math
from dataclasses import dataclass, replace

import numpy as np
from .._compiled import njit

from .._validation import check_positive
from ..geometry.field import directions_at, directions_of_runs

__all__ = ["GlareSource", "group_sources_evalglare", "position_pixel_evalglare",
           "SOURCE_POSITIONS", "DEFAULT_SEARCH_ANGLE", "DEFAULT_PEAK_LUMINANCE"]

#: evalglare's ``-r`` search opening angle [rad].
DEFAULT_SEARCH_ANGLE = 0.2
#: evalglare's peak-extraction limit ``-Y`` [cd·m⁻²].
DEFAULT_PEAK_LUMINANCE = 50000.0
#: Where a source's position index is evaluated: evalglare's pixel of the mean pixel
#: position (default), or the mean direction (see :func:`position_pixel_evalglare`).
SOURCE_POSITIONS = ("evalglare", "direction")

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


def position_pixel_evalglare(row, col, shape):
    """The pixel at which evalglare evaluates a source's position index.

    evalglare keeps each source's L·ω-weighted mean pixel position (``add_pixel_to_gs``,
    L·ω weights since v2.14) in its own pixel coordinates — x the column, y the row counted
    from the *bottom* of the picture — and hands it to ``get_posindex(float x, float y)``,
    whose angle functions (``pict_get_sigma`` …) pass it on to ``pict_get_dir(int x, int y)``:
    the position is truncated to a pixel, and σ, τ are those of that pixel's centre
    direction. In our row/column convention (row 0 at the top) that is column ⌊col⌋ and row
    rows − 1 − ⌊rows − 1 − row⌋ (= ⌈row⌉), with the coordinates rounded to float32 first
    as the ``float`` parameters do. The result can lie off the valid image (a crescent
    along a fisheye's rim); it is clipped to the picture.

    Parameters
    ----------
    row, col : float
        L·ω-weighted mean pixel position [px] (:attr:`GlareSource.row`, ``col``).
    shape : (int, int)
        Picture shape (rows, cols).

    Returns
    -------
    (int, int)
        Row and column of the pixel.

    Examples
    --------
    >>> position_pixel_evalglare(116.85, 295.85, (400, 400))
    (117, 295)

    References
    ----------
    Radiance ``src/util/evalglare.c`` (add_pixel_to_gs, get_posindex) and
    ``src/util/pictool.c`` (pict_get_sigma, pict_get_tau, pict_get_vangle, pict_get_dir,
    pict_read_fp: bottom-up rows of a standard ``-Y N +X M`` picture).
    """
    rows, cols = (int(n) for n in shape)
    y = math.floor(float(np.float32(rows - 1 - float(row))))
    x = math.floor(float(np.float32(float(col))))
    return min(max(rows - 1 - y, 0), rows - 1), min(max(x, 0), cols - 1)


def _chord(angle):
    """Chord length between unit vectors ``angle`` [rad] apart."""
    return 2.0 * np.sin(angle / 2.0)


_OPTIONS = {"cache": True, "error_model": "numpy", "nogil": True}


@njit(**_OPTIONS,
      aot=("Tuple((int32[:, ::1], boolean[::1], int64[::1], int64[::1], int64[::1]))"
           "(boolean[:, ::1])"))
def _nodes(mask):
    """Node number of each ``mask`` pixel in row-major order (the order of
    ``np.nonzero(mask)``; −1 elsewhere), whether each node lies on the patch boundary (a
    pixel of its 8 neighbours, or the edge of the box, is not in the mask), the nodes' rows
    and columns, and the first node of each run of mask pixels along a row."""
    rows, cols = mask.shape
    n = 0
    for r in range(rows):
        for c in range(cols):
            n += 1 if mask[r, c] else 0
    node = np.full((rows, cols), -1, np.int32)
    node_rows = np.empty(n, np.int64)
    node_cols = np.empty(n, np.int64)
    boundary = np.zeros(n, np.bool_)
    starts = np.empty(n, np.int64)  # only the runs' entries are written (and faulted in)
    k = 0
    n_runs = 0
    for r in range(rows):
        for c in range(cols):
            if not mask[r, c]:
                continue
            if c == 0 or not mask[r, c - 1]:
                starts[n_runs] = k
                n_runs += 1
            node[r, c] = k
            node_rows[k] = r
            node_cols[k] = c
            edge = False
            for dr in range(-1, 2):
                for dc in range(-1, 2):
                    rr, cc = r + dr, c + dc
                    if rr < 0 or rr >= rows or cc < 0 or cc >= cols or not mask[rr, cc]:
                        edge = True
            boundary[k] = edge
            k += 1
    return node, boundary, node_rows, node_cols, starts[:n_runs]


@njit(inline="always", **_OPTIONS)
def _find(parent, k):
    root = k
    while parent[root] != root:
        root = parent[root]
    while parent[k] != root:  # path compression
        parent[k], k = root, parent[k]
    return root


@njit(inline="always", **_OPTIONS)
def _union(parent, a, b):
    ra, rb = _find(parent, a), _find(parent, b)
    if ra != rb:
        if ra < rb:
            parent[rb] = ra
        else:
            parent[ra] = rb


@njit(inline="always", **_OPTIONS)
def _close(directions, a, b, chord):
    """|d̂_a − d̂_b| ≤ chord for rows a, b of ``directions`` (n, 3), in float64 (the sum of
    squares in the order of np.linalg.norm)."""
    x = directions[a, 0] - directions[b, 0]
    y = directions[a, 1] - directions[b, 1]
    z = directions[a, 2] - directions[b, 2]
    return math.sqrt(x * x + y * y + z * z) <= chord


@njit(**_OPTIONS,
      aot=("int64(int32[:, ::1], int64[::1], int64[::1], float64[:, ::1], float64, "
           "int64[::1], int64[::1], int64[::1])"))
def _components(node, node_rows, node_cols, directions, chord, pair_a, pair_b, node_label):
    """Union–find over the nodes (``directions``: one row per node): neighbouring pixels
    (right, down, down-right, down-left) within ``chord``, and the given boundary pairs;
    writes each node's label 1…n, numbered in the order of each component's first pixel in
    a column-major scan (evalglare's scan order), and returns n."""
    rows, cols = node.shape
    n_nodes = node_rows.size
    parent = np.arange(n_nodes)
    for k in range(n_nodes):
        r, c = node_rows[k], node_cols[k]
        for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
            r2, c2 = r + dr, c + dc
            if r2 < rows and 0 <= c2 < cols:
                m = node[r2, c2]
                # Nodes with one parent are in one component already (inside a patch, most
                # neighbours: their unions have linked them to its root): no test, no union.
                if m >= 0 and parent[k] != parent[m] and _close(directions, k, m, chord):
                    _union(parent, k, m)
    for i in range(pair_a.size):
        _union(parent, pair_a[i], pair_b[i])
    # Each component's first pixel in column-major order (its smallest col·rows + row), kept
    # at its root in ``node_label`` (scratch until the last loop). A root is its component's
    # first node (unions keep the smaller root), so it is met before its other nodes; after
    # _find, every node's parent is its root.
    n = 0
    for k in range(n_nodes):
        root = _find(parent, k)
        key = node_cols[k] * rows + node_rows[k]
        if root == k:
            n += 1
            node_label[k] = key
        else:
            node_label[root] = min(node_label[root], key)
    roots = np.empty(n, np.int64)
    j = 0
    for k in range(n_nodes):
        if parent[k] == k:
            roots[j] = k
            j += 1
    # The components numbered by their first pixel (pixels differ: no ties), each number
    # kept as −number in its root's parent (no further _find).
    order = np.argsort(node_label[roots])
    for i in range(n):
        parent[roots[order[i]]] = -(i + 1)
    for k in range(n_nodes):
        p = parent[k]
        node_label[k] = -p if p < 0 else -parent[p]
    return n


@njit(**_OPTIONS, aot="UniTuple(int64[::1], 2)(float64[:, ::1], float64)")
def _close_pairs(directions, chord):
    """Index pairs (a < b) of the rows of ``directions`` (n, 3) that are :func:`_close`: each
    direction falls in a cube of side ``chord``, and only the 27 cubes around a pixel's can
    hold its partners (a grid hash; one pass counts, one fills)."""
    m = directions.shape[0]
    cell = np.empty((m, 3), np.int64)
    for a in range(m):
        for k in range(3):
            cell[a, k] = np.int64(math.floor((directions[a, k] + 1.0) / chord))
    span = np.int64(math.floor(2.0 / chord)) + 3  # cube indices −1 … span − 2 along each axis
    key = ((cell[:, 0] + 1) * span + cell[:, 1] + 1) * span + cell[:, 2] + 1
    order = np.argsort(key)
    sorted_key = key[order]
    count = 0
    pair_a = np.empty(0, np.int64)
    pair_b = np.empty(0, np.int64)
    for fill in (False, True):
        if fill:
            pair_a = np.empty(count, np.int64)
            pair_b = np.empty(count, np.int64)
            count = 0
        for a in range(m):
            for dx in range(-1, 2):
                for dy in range(-1, 2):
                    for dz in range(-1, 2):
                        near = (((cell[a, 0] + dx + 1) * span + cell[a, 1] + dy + 1) * span
                                + cell[a, 2] + dz + 1)
                        s = np.searchsorted(sorted_key, near)
                        while s < m and sorted_key[s] == near:
                            b = order[s]
                            s += 1
                            if b > a and _close(directions, a, b, chord):
                                if fill:
                                    pair_a[count] = a
                                    pair_b[count] = b
                                count += 1
    return pair_a, pair_b


def _link(mask, directions, separation, offset=(0, 0), pixel_directions=None):
    """Single-linkage labels of ``mask`` pixels at angular ``separation``; ``directions`` a
    map or a PixelGeometry of the whole picture, in which ``mask`` starts at ``offset``:
    only the mask pixels' directions are read (or computed from the model), unless
    ``pixel_directions`` gives them (row-major order). Returns the mask pixels in row-major
    order (``np.nonzero(mask)``) — rows, columns, labels 1…n and directions — and n."""
    node, boundary, rows, cols, starts = _nodes(np.ascontiguousarray(mask))
    if rows.size == 0:
        return rows, cols, np.zeros(0, dtype=np.int64), np.empty((0, 3)), 0
    chord = float(_chord(separation))
    # The nodes' directions, in their (row-major) order: the runs along rows, from their
    # first nodes (no arrays of every node's picture coordinates).
    if pixel_directions is None:
        lengths = np.diff(np.append(starts, rows.size))
        pixel_directions = directions_of_runs(directions, rows[starts] + offset[0],
                                              cols[starts] + offset[1], lengths)
    d = np.ascontiguousarray(pixel_directions, dtype=np.float64)
    # Boundary pixels of different patches within reach of each other (the closest pair of
    # two patches always includes a boundary pixel).
    bnodes = np.flatnonzero(boundary)
    pair_a, pair_b = _close_pairs(np.ascontiguousarray(d[bnodes]), chord)
    label = np.empty(rows.size, dtype=np.int64)
    n = _components(node, rows, cols, d, chord, bnodes[pair_a], bnodes[pair_b], label)
    return rows, cols, label, d, n


@njit(**_OPTIONS,
      aot=tuple("Tuple((float64[:, ::1], float64[::1], float64[::1], int64[::1]))(int64[::1], "
                f"int64, {L}[:, :], float64[:, ::1], float64[:, :], int64[::1], int64[::1])"
                for L in ("float32", "float64")))
def _source_sums(label, n, luminance, directions, solid_angle, rows, cols):
    """Per label 1…n over the labelled pixels (``label``, d̂, row and column of each, in
    row-major pixel order, as np.bincount; L and ω read from their maps at those rows and
    columns): Σω, ΣL·ω, ΣL·ω·d̂, ΣL·ω·row, ΣL·ω·col, max and min L and the pixel count."""
    sums = np.zeros((n, 7))
    lmax = np.full(n, -np.inf)
    lmin = np.full(n, np.inf)
    count = np.zeros(n, np.int64)
    for i in range(label.size):
        k = label[i] - 1
        L = np.float64(luminance[rows[i], cols[i]])
        w = np.float64(solid_angle[rows[i], cols[i]])
        lw = L * w
        sums[k, 0] += w
        sums[k, 1] += lw
        for a in range(3):
            sums[k, 2 + a] += lw * directions[i, a]
        sums[k, 5] += lw * rows[i]
        sums[k, 6] += lw * cols[i]
        lmax[k] = max(lmax[k], L)
        lmin[k] = min(lmin[k], L)
        count[k] += 1
    return sums, lmax, lmin, count


def _describe(labels, n, luminance, directions, solid_angle, peak_flags, offset=(0, 0)):
    """The sources of ``labels`` (1…n; ``luminance``, ``solid_angle`` of their shape, which
    starts at ``offset`` in the picture of ``directions``: a map or a PixelGeometry)."""
    if n == 0:
        return []
    labels = np.asarray(labels)
    rows, cols = np.nonzero(labels)  # row-major order
    return _describe_pixels(rows, cols, labels[rows, cols], n, luminance, directions,
                            solid_angle, peak_flags, offset)


def _describe_pixels(rows, cols, label, n, luminance, directions, solid_angle, peak_flags,
                     offset=(0, 0), pixel_directions=None):
    """:func:`_describe` from the labelled pixels: their ``rows`` and ``cols`` in row-major
    order and their ``label`` (1…n), without a label map; ``pixel_directions`` their
    directions where the caller has them already."""
    rows = np.ascontiguousarray(rows, dtype=np.int64)
    cols = np.ascontiguousarray(cols, dtype=np.int64)
    if pixel_directions is None:
        pixel_directions = directions_at(directions, rows + offset[0], cols + offset[1])
    # L and ω are read at the pixels inside the kernel (no copies of the source pixels').
    luminance = np.asarray(luminance)
    if luminance.dtype not in (np.float32, np.float64):
        luminance = luminance.astype(np.float64)
    sums, lmax, lmin, count = _source_sums(
        np.ascontiguousarray(label, dtype=np.int64), n, luminance,
        np.ascontiguousarray(pixel_directions, dtype=np.float64),
        np.asarray(solid_angle, dtype=np.float64), rows, cols)
    omega, sum_lw = sums[:, 0], sums[:, 1]
    dirs = sums[:, 2:5] / np.linalg.norm(sums[:, 2:5], axis=-1, keepdims=True)
    row_c = sums[:, 5] / sum_lw
    col_c = sums[:, 6] / sum_lw
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
    directions : ndarray, shape (rows, cols, 3), or PixelGeometry
        Unit pixel directions, or the :class:`~lsadphoto.geometry.PixelGeometry` that gives
        them (the directions of the source pixels are then computed from the camera model,
        without a map of the picture).
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
    solid_angle = np.asarray(solid_angle)[box]
    offset = (box[0].start, box[1].start)
    # From here on only the source pixels (row-major order), their labels and directions:
    # no label maps of the box (8 bytes per pixel each, most of them 0) are made or written.
    rows, cols, label, pixel_directions, n = _link(mask, directions, separation, offset)
    peak_flags = [False] * n
    if peak_luminance is not None and n:
        limit = check_positive(peak_luminance, "peak_luminance")
        with np.errstate(invalid="ignore"):
            peak = luminance[rows, cols] >= np.float64(limit)  # float64 also for float32 L
        if peak.any():
            peak_mask = np.zeros(mask.shape, dtype=bool)
            peak_mask[rows[peak], cols[peak]] = True
            _, _, peak_label, _, n_peak = _link(peak_mask, directions, separation, offset,
                                                pixel_directions[peak])
            rest = np.where(peak, 0, label)
            # The labels left after peak extraction, in increasing order (np.unique would
            # import numpy.ma, 0.05 s of a short process).
            kept = np.flatnonzero(np.bincount(rest[rest > 0], minlength=n + 1))
            renumber = np.zeros(n + 1, dtype=np.int64)
            renumber[kept] = np.arange(1, kept.size + 1)
            label = renumber[rest]
            label[peak] = peak_label + kept.size
            n = kept.size + n_peak
            peak_flags = [False] * kept.size + [True] * n_peak
    labelled = label > 0
    if not labelled.all():
        rows, cols, label = rows[labelled], cols[labelled], label[labelled]
        pixel_directions = pixel_directions[labelled]
    sources = _describe_pixels(rows, cols, label, n, luminance, directions, solid_angle,
                               peak_flags, offset, pixel_directions) if n else []
    offset_row, offset_col = offset
    sources = [replace(s, row=s.row + offset_row, col=s.col + offset_col) for s in sources]
    labels_full[box][rows, cols] = label  # (a view: no offset copies of rows and cols)
    return sources, labels_full
