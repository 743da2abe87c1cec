"""Build the viewer page: a luminance map, its geometry and its metrics packed into HTML.

Everything the page shows is computed here by the package's own code and embedded; the
browser script (``viewer.js``) only decodes, draws and sums.

Embedded arrays
---------------
Each array is stored little-endian, its bytes regrouped into planes (all first bytes, then
all second bytes, …), each byte replaced by its difference from the previous one (mod 256),
compressed with zlib (RFC 1950, what the browser's ``DecompressionStream("deflate")``
reads) and written as base64 into a ``<script type="application/octet-stream">`` element.
This is lossless; the regrouping and differencing are the OpenEXR ZIP predictor's idea
(neighbouring floats share their high bytes) and make the payload 0.7–0.8 of the OpenEXR
file's size on the real maps of ``docs/performance.md``.

* luminance (and its per-pixel standard uncertainty where the map has one): float32, every
  pixel — the probe and the regions read these exact values;
* the validity of every pixel's geometry (uint8) and the glare-source labels (uint16 or
  uint32, 0 = no source) of :func:`~lsadphoto.metrics.score.score_map`;
* the Q criterion's contrast map K [rad⁻¹]: float16 (3 significant digits), an overlay;
* the pixel geometry — direction, solid angle ω [sr], σ, τ [rad], position index, cos σ —
  from :func:`~lsadphoto.geometry.pixel_geometry` and
  :func:`~lsadphoto.geometry.visual_field` on a grid of every :data:`GEOMETRY_STRIDE`-th
  row and column (plus the last), float64 rounded to float32. The page interpolates it
  bilinearly; the largest error of that interpolation against the full-resolution maps is
  measured here, on a random sample of valid pixels, and stated on the page. Embedding the
  eight maps at every pixel would make the page 8× larger than the map.

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
from ..errors import BadInputError
from ..geometry import ObserverFrame, pixel_geometry, visual_field
from ..io._atomic import atomic_text
from ..io.falsecolour import false_colour_range
from ..luminance_map import LuminanceMap

__all__ = ["GEOMETRY_STRIDE", "check_same_geometry", "viewer_assets", "viewer_fragment",
           "write_viewer"]

#: Rows and columns between the embedded geometry samples [px].
GEOMETRY_STRIDE = 8
#: Valid pixels on which the geometry interpolation error is measured.
_ERROR_SAMPLE = 1 << 17
#: zlib level: 6 is zlib's default (level 9 gains < 1 % here at twice the time).
_ZLIB_LEVEL = 6
#: Colour maps offered for the false-colour view (matplotlib names), then the fixed ones of
#: the ratio, contrast and source overlays.
FALSE_COLOUR_MAPS = ("turbo", "viridis", "inferno", "gray")
_OVERLAY_MAPS = {"ratio": "RdBu_r", "contrast": "magma"}
#: Geometry fields: (key, attribute of PixelGeometry / VisualField).
_GEOMETRY_FIELDS = ("dx", "dy", "dz", "solid_angle", "sigma", "tau", "position_index",
                    "cos_sigma")


def _encode(array, dtype):
    """The array as the page stores it (see the module notes): (description, base64 text)."""
    a = np.ascontiguousarray(array, dtype=np.dtype(dtype).newbyteorder("<"))
    planes = a.view(np.uint8).reshape(-1, a.itemsize).T.reshape(-1)
    delta = np.diff(planes, prepend=np.uint8(0))
    text = base64.b64encode(zlib.compress(delta.tobytes(), _ZLIB_LEVEL)).decode("ascii")
    return {"dtype": np.dtype(dtype).name, "shape": list(a.shape)}, text


class _Arrays:
    """Collects the encoded arrays of one viewer; each becomes a ``<script>`` element."""

    def __init__(self):
        self.scripts = []

    def add(self, name, array, dtype):
        description, text = _encode(array, dtype)
        self.scripts.append(f'<script type="application/octet-stream" data-array="{name}">'
                            f"{text}</script>")
        return dict(description, name=name)


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


def _bilinear(grid, node_rows, node_cols, rows, cols):
    """Bilinear interpolation of ``grid`` (on the nodes) at pixel ``(rows, cols)``, as the
    page does it."""
    i = np.clip(np.searchsorted(node_rows, rows, side="right") - 1, 0, max(len(node_rows) - 2, 0))
    j = np.clip(np.searchsorted(node_cols, cols, side="right") - 1, 0, max(len(node_cols) - 2, 0))
    i1, j1 = np.minimum(i + 1, len(node_rows) - 1), np.minimum(j + 1, len(node_cols) - 1)
    ti = np.where(i1 > i, (rows - node_rows[i]) / np.maximum(node_rows[i1] - node_rows[i], 1), 0.0)
    tj = np.where(j1 > j, (cols - node_cols[j]) / np.maximum(node_cols[j1] - node_cols[j], 1), 0.0)
    top = grid[i, j] * (1 - tj) + grid[i, j1] * tj
    bottom = grid[i1, j] * (1 - tj) + grid[i1, j1] * tj
    return top * (1 - ti) + bottom * ti


def _filled(values, valid):
    """``values`` with every invalid node set to its nearest valid node's value (so that the
    interpolation at the image-circle rim needs no special case)."""
    from scipy import ndimage

    if valid.all() or not valid.any():
        return np.where(valid, values, 0.0)
    _, (r, c) = ndimage.distance_transform_edt(~valid, return_indices=True)
    return values[r, c]


def _frame_of(lmap, score):
    """The observer frame and position-index method: the score's, else the map's line of
    sight (or the optical axis) with the camera's up, as :func:`score_map` takes them."""
    if score is not None:
        settings = score["settings"]
        return (ObserverFrame(tuple(settings["line_of_sight"]), tuple(settings["up"])),
                settings["position_index_method"])
    sight = lmap.line_of_sight if lmap.line_of_sight is not None else (0.0, 0.0, 1.0)
    return ObserverFrame(tuple(map(float, sight)), (0.0, -1.0, 0.0)), "evalglare"


def _geometry(lmap, score, arrays, rng):
    """Embedded geometry grid with its measured interpolation error, or None."""
    if lmap.projection is None:
        return None
    frame, method = _frame_of(lmap, score)
    geometry = pixel_geometry(lmap.projection)
    field = visual_field(lmap.projection, frame, position_index_method=method)
    rows, cols = lmap.shape
    node_rows, node_cols = _nodes(rows, GEOMETRY_STRIDE), _nodes(cols, GEOMETRY_STRIDE)
    ix = np.ix_(node_rows, node_cols)
    node_valid = geometry.valid[ix]
    full = {"dx": geometry.directions[..., 0], "dy": geometry.directions[..., 1],
            "dz": geometry.directions[..., 2], "solid_angle": geometry.solid_angle,
            "sigma": field.sigma, "tau": field.tau, "position_index": field.position_index,
            "cos_sigma": field.cos_sigma}
    grids = {key: _filled(np.asarray(full[key][ix], dtype=np.float64), node_valid)
             for key in _GEOMETRY_FIELDS}
    # Interpolation error, measured as the page computes it (float32 nodes).
    valid_index = np.flatnonzero(geometry.valid)
    errors = {}
    if valid_index.size:
        pick = rng.choice(valid_index, size=min(_ERROR_SAMPLE, valid_index.size), replace=False)
        r, c = np.divmod(pick, cols)
        at = {key: _bilinear(grids[key].astype(np.float32).astype(np.float64), node_rows,
                             node_cols, r, c) for key in _GEOMETRY_FIELDS}
        d = np.stack([at["dx"], at["dy"], at["dz"]], axis=-1)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        exact = geometry.directions[r, c]
        cos_error = np.clip(np.sum(d * exact, axis=-1), -1.0, 1.0)
        sigma = field.sigma[r, c]
        away = sigma > math.radians(5.0)  # τ is undefined on the line of sight
        omega = geometry.solid_angle[r, c]
        errors = {
            "sample_pixels": int(pick.size),
            "direction_deg": float(np.degrees(np.max(np.arccos(cos_error)))),
            "solid_angle_relative": float(np.max(np.abs(at["solid_angle"] / omega - 1.0))),
            "sigma_deg": float(np.degrees(np.max(np.abs(at["sigma"] - sigma)))),
            "tau_deg_beyond_5deg": float(np.degrees(np.max(np.abs(at["tau"] - field.tau[r, c])[away])))
            if away.any() else None,
            "position_index": float(np.nanmax(np.abs(at["position_index"]
                                                     - field.position_index[r, c]))),
        }
    fields = {key: arrays.add(f"geometry.{key}", grids[key], np.float32)
              for key in _GEOMETRY_FIELDS}
    return {"stride": GEOMETRY_STRIDE, "node_rows": node_rows.tolist(),
            "node_cols": node_cols.tolist(), "fields": fields,
            "valid": arrays.add("geometry.valid", geometry.valid, np.uint8),
            "interpolation_error": _json_safe(errors), "position_index_method": method,
            "line_of_sight": list(map(float, frame.axes()[0])),
            "up": list(map(float, frame.axes()[1])),
            "projection": lmap.projection.to_dict()}


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


def _score_record(score, arrays, prefix):
    """Sources, values and (from a :class:`Score`) the label and contrast maps."""
    if score is None:
        return None
    record = score.to_dict() if hasattr(score, "to_dict") else score
    out = _json_safe({"sources": record.get("sources", []),
                      "values": {k: v for k, v in record.items()
                                 if isinstance(v, (int, float)) and not isinstance(v, bool)},
                      "uncertainty": record.get("uncertainty", {}),
                      "notes": record.get("notes", [])})
    if hasattr(score, "source_labels"):
        labels = np.asarray(score.source_labels)
        dtype = np.uint16 if labels.max(initial=0) < 65536 else np.uint32
        out["labels"] = arrays.add(f"{prefix}.labels", labels, dtype)
        contrast = np.asarray(score.contrast, dtype=np.float64)
        positive = contrast[np.isfinite(contrast) & (contrast > 0)]
        # float16 ends at 65504: larger contrasts (the rim of a sun) are shown at that value.
        out["contrast"] = arrays.add(f"{prefix}.contrast",
                                     np.minimum(contrast, np.finfo(np.float16).max), np.float16)
        if positive.size:
            low, high = np.percentile(positive, [1.0, 99.9])
            out["contrast_range"] = [float(low), float(max(high, low * 10))]
    return out


def _map_record(lmap, name, score, arrays, prefix):
    luminance = np.asarray(lmap.luminance, dtype=np.float32)
    finite = luminance[np.isfinite(luminance) & (luminance > 0)]
    record = {
        "name": name, "rows": lmap.shape[0], "cols": lmap.shape[1],
        "calibrated": lmap.calibrated, "calibration_factor": lmap.calibration_factor,
        "calibration_uncertainty": lmap.calibration_uncertainty,
        "luminance": arrays.add(f"{prefix}.luminance", luminance, np.float32),
        "uncertainty": (arrays.add(f"{prefix}.uncertainty", lmap.uncertainty, np.float32)
                        if lmap.uncertainty is not None else None),
        "range": list(false_colour_range(luminance)),
        # Log-average luminance (the key of the tone mapping) [cd·m⁻²].
        "log_average": float(np.exp(np.mean(np.log(finite)))) if finite.size else 1.0,
        "source": str(lmap.provenance.get("source", "")) if isinstance(lmap.provenance, dict)
        else "",
        "score": _score_record(score, arrays, prefix),
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
                    names=("photo", "model"), title=None, lazy=False, seed=0):
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
    seed : int
        Seed of the pixel sample on which the geometry interpolation error is measured.

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
    rng = np.random.default_rng(seed)
    base_score = score.to_dict() if hasattr(score, "to_dict") else score
    maps = [_map_record(lmap, names[0], score, arrays, "map0")]
    if second is not None:
        maps.append(_map_record(second, names[1], second_score, arrays, "map1"))
    data = {"version": __version__, "title": title or names[0], "maps": maps,
            "geometry": _geometry(lmap, base_score, arrays, rng),
            "colour_tables": _colour_tables(), "colour_maps": list(FALSE_COLOUR_MAPS)}
    meta = json.dumps(data, allow_nan=False, separators=(",", ":")).replace("</", "<\\/")
    return (f'<div class="lsad-viewer" data-lazy="{"yes" if lazy else "no"}">'
            f'<script type="application/json" data-meta="1">{meta}</script>'
            + "".join(arrays.scripts) + "</div>")


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
