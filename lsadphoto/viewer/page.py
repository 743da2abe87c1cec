"""Build the viewer page: a luminance map, its geometry and its metrics packed into HTML.

Everything the page shows is computed here by the package's own code and embedded; the
browser script (``viewer.js``) only decodes, draws and sums.

Embedded arrays
---------------
Each array is stored little-endian in parts of at most :data:`PART_ITEMS` elements (in flat
order; one part for all but the largest arrays), each part's bytes regrouped into planes (all first bytes, then
all second bytes, …), each byte replaced by its difference from the previous one (mod 256),
compressed with zlib (RFC 1950, what the browser's ``DecompressionStream("deflate")``
reads) and written as base64 into a ``<script type="application/octet-stream">`` element of
its own, so that the page decodes the parts in parallel, off its main thread.
This is lossless; the regrouping and differencing are the OpenEXR ZIP predictor's idea
(neighbouring floats share their high bytes) and make the payload 0.7–0.8 of the OpenEXR
file's size on the real maps of ``docs/performance.md``.

* luminance (and its per-pixel standard uncertainty where the map has one): float32, every
  pixel — the probe and the regions read these exact values;
* the validity of every pixel's geometry (uint8), the glare-source labels (uint8, 16 or 32,
  0 = no source) of :func:`~lsadphoto.metrics.score.score_map`, and its evalglare band and
  zones where it was asked for them (uint8);
* the Q criterion's contrast map K [rad⁻¹]: float16 (3 significant digits), an overlay;
* for a map of more than :data:`PREVIEW_PIXELS` pixels, a display preview: the mean of the
  finite values of every f × f block (f the smallest integer that brings it to at most
  :data:`PREVIEW_PIXELS`), float32. It is placed before every other array in the document,
  with the call that starts the viewer right after it, so that the page draws the map and
  answers zoom, pan and the legend while the browser still parses the full-resolution data;
  the probe, the points and the regions wait for those (``lsadViewer.ready``) and never read
  the preview;
* the pixel geometry — direction, solid angle ω [sr] and position index — from
  :func:`~lsadphoto.geometry.pixel_geometry` and :func:`~lsadphoto.geometry.visual_field`
  on a grid of every :data:`GEOMETRY_STRIDE`-th row and column (plus the last; a finer grid
  for small images), float32, interpolated bilinearly by the page; the pixels of every grid
  cell where that misses by more than :data:`GEOMETRY_TOLERANCE` carry their exact values. σ, τ and cos σ follow
  from the direction and the observer frame's axes, as
  :meth:`~lsadphoto.geometry.ObserverFrame.angles` defines them. The largest remaining
  error against the package's full-resolution maps, over all valid pixels, is stated on
  the page. Embedding the maps at every pixel would make the page 5–6× larger than the
  map.

Containers measured for the parts (``docs/performance.md``): the browser parses the base64 in
``<script type="application/octet-stream">`` elements no slower than in one trailing HTML
comment, and faster than in JavaScript string literals.

References
----------
P. Deutsch, J.-L. Gailly, "ZLIB Compressed Data Format Specification version 3.3", RFC 1950
(1996). OpenEXR file layout (ZIP compression's predictor and byte reordering):
https://openexr.com/en/latest/OpenEXRFileLayout.html. WHATWG Compression Standard
(``DecompressionStream``): https://compression.spec.whatwg.org/.
"""

import base64
import html
import json
import math
import zlib
from importlib import resources
from pathlib import Path

import numpy as np

from .._version import __version__
from ..errors import BadInputError, LsadError
from ..geometry import ObserverFrame, pixel_geometry, visual_field
from ..geometry.observer import ON_AXIS  # τ's on-axis rule, as ObserverFrame.angles has it
from .._atomic import atomic_text
from ..io.falsecolour import false_colour_range
from ..luminance_map import LuminanceMap

__all__ = ["GEOMETRY_STRIDE", "PREVIEW_PIXELS", "check_same_geometry", "read_source_labels",
           "report_viewer", "viewer_assets", "viewer_fragment", "write_source_labels", "write_viewer"]

#: Rows and columns between the embedded geometry samples [px] (at most; see _geometry).
GEOMETRY_STRIDE = 8
#: Largest interpolation errors accepted in a grid cell (else its pixels are stored
#: exactly): pixel solid angle (relative: region means and solid angles within 10⁻⁴, ten
#: times inside the 0.1 % the viewer promises), direction [deg] (a hundredth of the
#: LS-100's 1° field; σ's error is at most the direction's) and position index (1…16;
#: 0.05 is the rounding of its usual two decimals, and 0.01 would store 3× more pixels
#: exactly on the real fisheye of docs/performance.md).
GEOMETRY_TOLERANCE = {"solid_angle_relative": 1e-4, "direction_deg": 0.01,
                      "position_index": 0.05}
#: Elements per embedded part [items]: the page decodes the parts of its arrays in parallel
#: (Web Workers), so a 24 MP map's luminance is six parts of 4 Mi floats (16 MiB).
PART_ITEMS = 1 << 22
#: Largest display preview [px]: maps with more pixels embed one (block means), drawn first;
#: 1 Mi px is about the canvas of a 1280 px wide window, where a fitted 24 MP map shows one
#: screen pixel per 5 × 5 map pixels anyway.
PREVIEW_PIXELS = 1 << 20
#: zlib level: 6 is zlib's default (level 9 gains < 1 % here at twice the time).
_ZLIB_LEVEL = 6
#: Colour maps offered for the false-colour view (matplotlib names), then the fixed ones of
#: the ratio, contrast and source overlays.
FALSE_COLOUR_MAPS = ("turbo", "viridis", "inferno", "gray")
_OVERLAY_MAPS = {"ratio": "RdBu_r", "contrast": "magma"}


def _encode(array, dtype):
    """The array as the page stores it (see the module notes): (description, base64 texts),
    one text per part of at most :data:`PART_ITEMS` elements (in flat order)."""
    a = np.ascontiguousarray(array, dtype=np.dtype(dtype).newbyteorder("<"))
    flat = a.reshape(-1)
    texts = []
    for start in range(0, max(flat.size, 1), PART_ITEMS):
        part = flat[start:start + PART_ITEMS]
        planes = part.view(np.uint8).reshape(-1, a.itemsize).T.reshape(-1)
        delta = np.diff(planes, prepend=np.uint8(0))
        texts.append(base64.b64encode(zlib.compress(delta.tobytes(), _ZLIB_LEVEL))
                     .decode("ascii"))
    return {"dtype": np.dtype(dtype).name, "shape": list(a.shape), "parts": len(texts),
            "part_items": PART_ITEMS}, texts


class _Arrays:
    """Collects the encoded arrays of one viewer; each part becomes a ``<script>`` element,
    those added ``early`` (the previews) before all others."""

    def __init__(self):
        self.early, self.scripts = [], []

    def add(self, name, array, dtype, *, early=False):
        description, texts = _encode(array, dtype)
        (self.early if early else self.scripts).extend(
            f'<script type="application/octet-stream" data-array="{name}">{text}</script>'
            for text in texts)
        return dict(description, name=name)


def _preview(luminance, arrays, prefix):
    """The display preview of a map of more than :data:`PREVIEW_PIXELS` pixels (see the
    module notes), or None: its array description and block size f [px]."""
    rows, cols = luminance.shape
    if rows * cols <= PREVIEW_PIXELS:
        return None
    f = math.ceil(math.sqrt(rows * cols / PREVIEW_PIXELS))
    while math.ceil(rows / f) * math.ceil(cols / f) > PREVIEW_PIXELS:
        f += 1
    padded = np.full((math.ceil(rows / f) * f, math.ceil(cols / f) * f), np.nan, np.float32)
    padded[:rows, :cols] = luminance
    blocks = padded.reshape(padded.shape[0] // f, f, padded.shape[1] // f, f)
    finite = np.isfinite(blocks)
    count = finite.sum(axis=(1, 3))
    total = np.where(finite, blocks, 0.0).sum(axis=(1, 3), dtype=np.float64)
    mean = np.full(count.shape, np.nan)
    np.divide(total, count, out=mean, where=count > 0)
    return dict(arrays.add(f"{prefix}.preview", mean, np.float32, early=True), block=f)


def _colour_tables():
    """256-entry RGB tables (base64 of 768 bytes) of the colour maps the page offers."""
    import matplotlib

    names = {name: name for name in FALSE_COLOUR_MAPS} | _OVERLAY_MAPS
    tables = {}
    for key, name in names.items():
        rgb = matplotlib.colormaps[name](np.linspace(0.0, 1.0, 256))[:, :3]
        tables[key] = base64.b64encode(np.round(rgb * 255).astype(np.uint8).tobytes()).decode()
    palette = matplotlib.colormaps["tab10"](np.arange(10))[:, :3]
    tables["sources"] = base64.b64encode(np.round(palette * 255).astype(np.uint8).tobytes()).decode()
    return tables


def _nodes(n, stride):
    """Grid node positions [px]: 0, stride, 2·stride, … and the last pixel."""
    nodes = list(range(0, n, stride))
    if nodes[-1] != n - 1:
        nodes.append(n - 1)
    return np.asarray(nodes)


def _frame_of(lmap, score):
    """The observer frame and position-index method: the score's, else the map's line of
    sight (or the optical axis) with the camera's up, as :func:`score_map` takes them."""
    if score is not None:
        settings = score["settings"]
        return (ObserverFrame(tuple(settings["line_of_sight"]), tuple(settings["up"])),
                settings["position_index_method"])
    sight = lmap.line_of_sight if lmap.line_of_sight is not None else (0.0, 0.0, 1.0)
    return ObserverFrame(tuple(map(float, sight)), (0.0, -1.0, 0.0)), "evalglare"


def _cells(n, nodes, stride):
    """Index of the grid interval of each pixel 0…n−1 and of the node after it."""
    i = np.minimum(np.arange(n) // stride, max(len(nodes) - 2, 0))
    return i, np.minimum(i + 1, len(nodes) - 1)


def _band_errors(full, grids, node_rows, node_cols, stride, cell, rows, frame, field):
    """Errors of the page's interpolation at every pixel of the image rows ``rows`` (all in
    grid cell row ``cell``): direction [deg], σ [deg], τ [deg] (NaN within 1° of the line of
    sight, where τ is undefined), solid angle (relative) and position index (absolute), each
    (len(rows), cols). Bilinear in the page's order: along the columns on the two node rows,
    then between them."""
    cols = full["dx"].shape[1]
    i, i1 = cell, min(cell + 1, len(node_rows) - 1)
    j, j1 = _cells(cols, node_cols, stride)
    span = np.maximum(node_cols[j1] - node_cols[j], 1)
    tj = np.where(j1 > j, (np.arange(cols) - node_cols[j]) / span, 0.0)
    ti = ((rows - node_rows[i]) / (node_rows[i1] - node_rows[i]) if i1 > i
          else np.zeros(rows.size))[:, None]
    at = {}
    for key in full:
        g = grids[key].astype(np.float64)
        top = g[i, j] * (1 - tj) + g[i, j1] * tj
        bottom = g[i1, j] * (1 - tj) + g[i1, j1] * tj
        at[key] = top * (1 - ti) + bottom * ti
    d = np.stack([at["dx"], at["dy"], at["dz"]], axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        true = np.stack([full[k][rows] for k in ("dx", "dy", "dz")], axis=-1)
        direction = np.degrees(np.arccos(np.clip(np.sum(d * true, axis=-1), -1.0, 1.0)))
        sigma, tau = frame.angles(d)
        true_sigma = field.sigma[rows]
        return {"direction_deg": direction,
                "sigma_deg": np.degrees(np.abs(sigma - true_sigma)),
                "tau_deg_beyond_1deg": np.where(true_sigma > math.radians(1.0),
                                                np.degrees(np.abs(tau - field.tau[rows])), np.nan),
                "solid_angle_relative": np.abs(at["solid_angle"] / full["solid_angle"][rows] - 1.0),
                "position_index": np.abs(at["position_index"] - field.position_index[rows])}


def _grid_plan(full, valid, frame, field, stride):
    """The node grid of ``stride`` px, the pixels that must be stored exactly (a mask) and
    the largest errors of the interpolation at the others."""
    rows, cols = valid.shape
    node_rows, node_cols = _nodes(rows, stride), _nodes(cols, stride)
    ix = np.ix_(node_rows, node_cols)
    grids = {key: np.where(valid[ix], np.asarray(value[ix], dtype=np.float64), 0.0)
             .astype(np.float32) for key, value in full.items()}
    row_cell, _ = _cells(rows, node_rows, stride)
    col_cell, _ = _cells(cols, node_cols, stride)
    col_starts = np.flatnonzero(np.diff(col_cell, prepend=-1))
    exact = np.zeros((rows, cols), dtype=bool)
    largest = dict.fromkeys(("direction_deg", "sigma_deg", "tau_deg_beyond_1deg",
                             "solid_angle_relative", "position_index"), 0.0)
    for cell in range(int(row_cell[-1]) + 1):
        band = np.flatnonzero(row_cell == cell)
        errors = _band_errors(full, grids, node_rows, node_cols, stride, cell, band, frame,
                              field)
        ok = valid[band]
        bad = ~ok.copy()
        for key, limit in GEOMETRY_TOLERANCE.items():
            bad |= ~(errors[key] <= limit)
        # A cell is exact if any valid pixel of it fails (invalid pixels fail trivially).
        failing = np.logical_or.reduceat((bad & ok), col_starts, axis=1).any(axis=0)
        exact_band = failing[col_cell][None, :] & ok
        exact[band] = exact_band
        kept = ok & ~exact_band
        for key in largest:
            values = errors[key][kept]
            values = values[np.isfinite(values)]
            if values.size:
                largest[key] = max(largest[key], float(values.max()))
    return node_rows, node_cols, grids, exact, largest


def _payload(plan):
    """Bytes the plan embeds before compression: five float32 per node, and five float32
    and a uint32 index per exact pixel."""
    node_rows, node_cols, _, exact, _ = plan
    return 20 * node_rows.size * node_cols.size + 24 * int(exact.sum())


def _geometry(lmap, score, arrays):
    """Embedded geometry with its interpolation error, or None (no projection).

    Direction, solid angle and position index are sampled every :data:`GEOMETRY_STRIDE` px
    and interpolated bilinearly; every grid cell in which the interpolation misses any of
    them by more than :data:`GEOMETRY_TOLERANCE` at any valid pixel (the rim of a fisheye's
    image circle, the line of sight, the horizon where evalglare's position index changes
    formula) stores its pixels' exact values instead. Where that leaves more than a tenth of
    the pixels exact (small images, where a cell spans degrees), the grid is halved while
    that makes the page smaller. σ and τ follow on the page from the direction and the
    observer's axes (v̂, û, ĥ), as :meth:`~lsadphoto.geometry.ObserverFrame.angles` defines
    them: they have a cone point at the line of sight that no grid interpolates. The errors
    stated on the page are the largest over all valid pixels.
    """
    if lmap.projection is None:
        return None
    frame, method = _frame_of(lmap, score)
    geometry = pixel_geometry(lmap.projection)
    field = visual_field(lmap.projection, frame, position_index_method=method)
    full = {"dx": geometry.directions[..., 0], "dy": geometry.directions[..., 1],
            "dz": geometry.directions[..., 2], "solid_angle": geometry.solid_angle,
            "position_index": field.position_index}
    valid = geometry.valid
    stride = GEOMETRY_STRIDE
    plan = _grid_plan(full, valid, frame, field, stride)
    while stride > 1 and plan[3].sum() > 0.1 * valid.sum():
        finer = _grid_plan(full, valid, frame, field, stride // 2)
        if _payload(finer) >= _payload(plan):
            break
        stride, plan = stride // 2, finer
    node_rows, node_cols, grids, exact, largest = plan
    exact_index = np.flatnonzero(exact)
    exact_values = {key: np.asarray(value.reshape(-1)[exact_index], dtype=np.float32)
                    for key, value in full.items()}
    largest["exact_pixels"] = int(exact_index.size)
    largest["valid_pixels"] = int(valid.sum())
    return {"stride": stride, "node_rows": node_rows.tolist(),
            "node_cols": node_cols.tolist(),
            "fields": {key: arrays.add(f"geometry.{key}", grids[key], np.float32)
                       for key in full},
            "exact_index": arrays.add("geometry.exact_index", exact_index, np.uint32),
            "exact": {key: arrays.add(f"geometry.exact.{key}", exact_values[key], np.float32)
                      for key in full},
            "valid": arrays.add("geometry.valid", valid, np.uint8),
            "interpolation_error": _json_safe(largest), "position_index_method": method,
            "axes": [np.asarray(a, dtype=np.float64).tolist() for a in frame.axes()],
            "on_axis": ON_AXIS, "projection": lmap.projection.to_dict()}


def _json_safe(value):
    """``value`` with every non-finite float (and numpy scalar) made JSON-ready (None)."""
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


def _regions(lmap, record, arrays, prefix):
    """evalglare's band and zones of the score (``band_deg``, ``zones`` in its settings) as
    pixel maps, drawn by the package's own :func:`~lsadphoto.metrics.regions.band_region`
    and :func:`~lsadphoto.metrics.regions.zone_map` over the pixels the score evaluated
    (valid geometry, finite luminance, in front of the observer), with the score's
    statistics of them."""
    settings = record.get("settings") or {}
    band_deg, zones = settings.get("band_deg"), settings.get("zones")
    if lmap.projection is None or (band_deg is None and not zones):
        return {}
    from ..metrics.analyses import centre_direction
    from ..metrics.regions import band_region, zone_map

    frame, method = _frame_of(lmap, record)
    geometry = pixel_geometry(lmap.projection)
    field = visual_field(lmap.projection, frame, position_index_method=method)
    valid = geometry.valid & np.isfinite(lmap.luminance) & (field.cos_sigma >= 0)
    out = {}
    if band_deg is not None:
        band = band_region(geometry.directions, valid, half_width=math.radians(band_deg))
        out["band"] = arrays.add(f"{prefix}.band", band, np.uint8)
        out["band_deg"] = float(band_deg)
        out["band_stats"] = _json_safe(record.get("band"))
    if zones:
        centre = centre_direction(zones["centre"], lmap.projection, "zone centre")
        opening = np.radians(np.atleast_1d(np.asarray(zones["opening_deg"], dtype=float)))
        zone = zone_map(geometry.directions, valid, centre, opening_angles=opening)
        out["zones"] = arrays.add(f"{prefix}.zones", zone, np.uint8)
        out["zone_opening_deg"] = _json_safe(list(zones["opening_deg"]))
        out["zone_stats"] = _json_safe(record.get("zones"))
    return out


def _label_dtype(labels):
    """The smallest unsigned integer type that holds every label."""
    most = labels.max(initial=0)
    return np.uint8 if most < 256 else np.uint16 if most < 65536 else np.uint32


def _score_record(score, lmap, arrays, prefix, source_labels=None):
    """Sources, values, band and zones and (from a :class:`Score`) the label and contrast
    maps; ``source_labels`` (an integer array of the map's shape) gives the labels where
    ``score`` is a record without them."""
    if score is None:
        return None
    record = score.to_dict() if hasattr(score, "to_dict") else score
    out = _json_safe({"sources": record.get("sources", []),
                      "values": {k: v for k, v in record.items()
                                 if isinstance(v, (int, float)) and not isinstance(v, bool)},
                      "uncertainty": record.get("uncertainty", {}),
                      "notes": record.get("notes", [])})
    labels = getattr(score, "source_labels", None) if source_labels is None else source_labels
    if labels is not None:
        labels = np.asarray(labels)
        if labels.shape != lmap.shape or not np.issubdtype(labels.dtype, np.integer):
            raise BadInputError(f"the glare-source labels ({labels.dtype}, {labels.shape}) are "
                                f"not integers of the map's shape {lmap.shape}")
        out["labels"] = arrays.add(f"{prefix}.labels", labels, _label_dtype(labels))
    if hasattr(score, "contrast"):
        contrast = np.asarray(score.contrast, dtype=np.float64)
        positive = contrast[np.isfinite(contrast) & (contrast > 0)]
        # float16 ends at 65504: larger contrasts (the rim of a sun) are shown at that value.
        out["contrast"] = arrays.add(f"{prefix}.contrast",
                                     np.minimum(contrast, np.finfo(np.float16).max), np.float16)
        if positive.size:
            low, high = np.percentile(positive, [1.0, 99.9])
            out["contrast_range"] = [float(low), float(max(high, low * 10))]
    out.update(_regions(lmap, record, arrays, prefix))
    return out


def _map_record(lmap, name, score, arrays, prefix, source_labels=None):
    luminance = np.asarray(lmap.luminance, dtype=np.float32)
    finite = luminance[np.isfinite(luminance) & (luminance > 0)]
    record = {
        "name": name, "rows": lmap.shape[0], "cols": lmap.shape[1],
        "calibrated": lmap.calibrated, "calibration_factor": lmap.calibration_factor,
        "calibration_uncertainty": lmap.calibration_uncertainty,
        "luminance": arrays.add(f"{prefix}.luminance", luminance, np.float32),
        "preview": _preview(luminance, arrays, prefix),
        "uncertainty": (arrays.add(f"{prefix}.uncertainty", lmap.uncertainty, np.float32)
                        if lmap.uncertainty is not None else None),
        "range": list(false_colour_range(luminance)),
        # Log-average luminance (the key of the tone mapping) [cd·m⁻²].
        "log_average": float(np.exp(np.mean(np.log(finite)))) if finite.size else 1.0,
        "source": str(lmap.provenance.get("source", "")) if isinstance(lmap.provenance, dict)
        else "",
        "score": _score_record(score, lmap, arrays, prefix, source_labels),
    }
    return record


def check_same_geometry(first, second, *, names=("first map", "second map")):
    """Raise :class:`BadInputError` unless two maps have one pixel grid and camera geometry.

    The side-by-side view and the ratio map compare pixel with pixel, so the two maps must
    have the same size and the same projection (or both none).
    """
    a, b = names
    if first.shape != second.shape:
        raise BadInputError(f"{b} is {second.shape[0]}×{second.shape[1]} px but {a} is "
                            f"{first.shape[0]}×{first.shape[1]} px: side by side needs one "
                            "pixel grid")
    if (first.projection is None) != (second.projection is None):
        which = a if first.projection is None else b
        raise BadInputError(f"{which} has no camera geometry and the other has: side by side "
                            "needs one camera geometry")
    if first.projection is not None and first.projection != second.projection:
        raise BadInputError(f"{a} and {b} have different camera geometries "
                            f"({first.projection.to_dict()} against "
                            f"{second.projection.to_dict()}): side by side needs one")


def viewer_fragment(lmap, *, second=None, score=None, second_score=None,
                    names=("photo", "model"), title=None, lazy=False, source_labels=None):
    """The viewer of one view as an HTML fragment (a ``<div>``) for embedding in a page.

    The page must also hold :func:`viewer_assets` once (the script and style).

    Parameters
    ----------
    lmap : LuminanceMap
        The map [cd·m⁻²].
    second : LuminanceMap, optional
        A second map of the same view (same pixel grid and camera geometry, e.g. a model
        rendered through the photo's camera), shown side by side with one probe and as the
        ratio second/first.
    score, second_score : Score or dict, optional
        :func:`~lsadphoto.metrics.score.score_map` results of the maps (or their
        ``to_dict()``, which gives the source list but not the label and contrast maps).
    names : (str, str)
        Names of the two maps.
    title : str, optional
        Heading of the viewer.
    lazy : bool
        Decode the data only when the viewer is scrolled into sight (for reports with many
        views).
    source_labels : array of int, optional
        The glare-source label of every pixel of ``lmap`` (0 = none), where ``score`` is a
        record without them (a survey's saved score).

    Returns
    -------
    str
        HTML.

    References
    ----------
    See the module notes.
    """
    if not isinstance(lmap, LuminanceMap) or (second is not None
                                              and not isinstance(second, LuminanceMap)):
        raise BadInputError("the viewer needs LuminanceMap objects")
    if second is not None:
        check_same_geometry(lmap, second, names=names)
    arrays = _Arrays()
    base_score = score.to_dict() if hasattr(score, "to_dict") else score
    maps = [_map_record(lmap, names[0], score, arrays, "map0", source_labels)]
    if second is not None:
        maps.append(_map_record(second, names[1], second_score, arrays, "map1"))
    data = {"version": __version__, "title": title or names[0], "maps": maps,
            "geometry": _geometry(lmap, base_score, arrays),
            "colour_tables": _colour_tables(), "colour_maps": list(FALSE_COLOUR_MAPS)}
    meta = json.dumps(data, allow_nan=False, separators=(",", ":")).replace("</", "<\\/")
    # The previews, then the call that starts this viewer while the rest is still parsed
    # (where viewer_assets came first; else the viewer starts when the page is parsed).
    return (f'<div class="lsad-viewer" data-lazy="{"yes" if lazy else "no"}">'
            f'<script type="application/json" data-meta="1">{meta}</script>'
            + "".join(arrays.early)
            + "<script>if (window.lsadViewerStart) lsadViewerStart(document.currentScript"
              ".parentNode);</script>"
            + "".join(arrays.scripts) + "</div>")


def report_viewer(lmap, *, second=None, score=None, second_score=None,
                  names=("photo", "model"), title=None, source_labels=None):
    """The lazily decoded viewer fragment a report embeds for one view, or why there is none.

    ``lmap`` and ``second`` are :class:`LuminanceMap` objects or paths of map files (read
    with :func:`lsadphoto.io.read_map`); the other parameters are those of
:func:`viewer_fragment`; ``source_labels`` is also a path of the ``.npz`` file a survey
    saves them in (:func:`read_source_labels`). A report never fails for a view it cannot show: an unreadable
    map, or two maps of different geometry, come back as the reason.

    Returns
    -------
    (str, None) or (None, str)
        The HTML fragment, or None and the reason.
    """
    from ..io import read_map

    try:
        maps = [m if m is None or isinstance(m, LuminanceMap) else read_map(m)
                for m in (lmap, second)]
        if source_labels is not None and not isinstance(source_labels, np.ndarray):
            source_labels = read_source_labels(source_labels)
        return viewer_fragment(maps[0], second=maps[1], score=score, second_score=second_score,
                               names=names, title=title, lazy=True,
                               source_labels=source_labels), None
    except LsadError as error:
        return None, str(error)


def write_source_labels(labels, file):
    """Save a glare-source label map (integers, 0 = no source) compactly: the smallest
    unsigned integer type that holds it, in a compressed ``.npz`` (key ``labels``).

    ``file`` is a path or a binary file object (a path is written as given, with no
    ``.npz`` added).
    """
    labels = np.asarray(labels)
    dtype = _label_dtype(labels)
    if isinstance(file, (str, Path)):
        with open(file, "wb") as handle:
            np.savez_compressed(handle, labels=labels.astype(dtype))
    else:
        np.savez_compressed(file, labels=labels.astype(dtype))


def read_source_labels(path):
    """The label map :func:`write_source_labels` saved; :class:`BadInputError` if the file
    cannot be read as one."""
    try:
        with np.load(path, allow_pickle=False) as archive:
            labels = archive["labels"]
    except (OSError, ValueError, KeyError) as error:
        raise BadInputError(f"{path}: not a glare-source label file ({error})") from None
    return labels


def _asset(name):
    return resources.files(__package__).joinpath(name).read_text(encoding="utf-8")


def viewer_assets():
    """The viewer's style and script (package files ``viewer.css``, ``viewer.js``), inline,
    to be placed once in a page that holds :func:`viewer_fragment` elements."""
    script = _asset("viewer.js").replace("</script", "<\\/script")
    return f"<style>{_asset('viewer.css')}</style>\n<script>{script}</script>"


def write_viewer(lmap, path, *, second=None, score=None, second_score=None,
                 names=("photo", "model"), title=None):
    """Write a self-contained viewer page (one HTML file, no external resource; atomic).

    Parameters are those of :func:`viewer_fragment`; ``path`` is the ``.html`` file.

    Returns
    -------
    pathlib.Path

    References
    ----------
    See the module notes.
    """
    path = Path(path)
    fragment = viewer_fragment(lmap, second=second, score=score, second_score=second_score,
                               names=names, title=title)
    heading = html.escape(title or names[0])
    page = ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<meta name=\"generator\" content=\"lsadphoto {__version__}\">\n"
            f"<title>{heading}</title>\n{viewer_assets()}\n</head>\n<body class=\"lsad-page\">\n"
            f"{fragment}\n</body>\n</html>\n")
    atomic_text(path, page)
    return path
