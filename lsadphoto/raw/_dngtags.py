"""Direct reading of the DNG tags LibRaw does not hand out (colour matrices, black maps)."""

import numpy as np
import tifffile

from ._quiet import quiet_loggers

# DNG 1.6 tag numbers (Adobe DNG Specification 1.6.0.0, chapter 4).
BLACK_LEVEL_REPEAT_DIM = 50713
BLACK_LEVEL = 50714
BLACK_LEVEL_DELTA_H = 50715
BLACK_LEVEL_DELTA_V = 50716
COLOR_MATRIX = (50721, 50722)
CALIBRATION_ILLUMINANT = (50778, 50779)
AS_SHOT_NEUTRAL = 50728
FORWARD_MATRIX = (50964, 50965)
CFA_PATTERN = 33422


def _value(tag):
    value = tag.value
    if isinstance(value, tuple) and tag.dtype in (5, 10):  # RATIONAL, SRATIONAL as flat pairs
        flat = np.asarray(value, dtype=np.float64)
        return flat[0::2] / np.where(flat[1::2] == 0, np.nan, flat[1::2])
    return np.atleast_1d(np.asarray(value, dtype=np.float64))


def read_dng_tags(path):
    """Return the colour and black-level tags of the raw IFD of a DNG, or ``{}`` for non-DNG."""
    try:
        with quiet_loggers("tifffile"), tifffile.TiffFile(path) as tif:
            pages = [tif.pages[0]]
            pages += list(getattr(tif.pages[0], "pages", []) or [])
            if 50706 not in tif.pages[0].tags:  # DNGVersion
                return {}
            tags = {}
            for page in pages:
                for code, tag in page.tags.items():
                    tags.setdefault(code, tag)
            raw_page = next((p for p in pages if CFA_PATTERN in p.tags), pages[0])
            out = {"raw_page_tags": {code: _value(t) for code, t in raw_page.tags.items()
                                     if code in (BLACK_LEVEL_REPEAT_DIM, BLACK_LEVEL,
                                                 BLACK_LEVEL_DELTA_H, BLACK_LEVEL_DELTA_V)}}
            for name, codes in (("color_matrix", COLOR_MATRIX), ("forward_matrix", FORWARD_MATRIX)):
                out[name] = [_value(tags[c]).reshape(3, -1)[:3, :3] if c in tags else None for c in codes]
            out["calibration_illuminant"] = [
                int(_value(tags[c])[0]) if c in tags else None for c in CALIBRATION_ILLUMINANT
            ]
            out["as_shot_neutral"] = _value(tags[AS_SHOT_NEUTRAL])[:3] if AS_SHOT_NEUTRAL in tags else None
            return out
    except Exception:  # tifffile raises assorted errors on corrupt tags (TypeError seen fuzzing)
        return {}


def dng_black_map(dng, shape):
    """Black level per pixel of the visible area from BlackLevel[RepeatDim] and DeltaH/V.

    Returns ``None`` when the tags give no more than LibRaw's per-channel black levels
    (no deltas and a repeat pattern of at most 2 × 2).
    """
    tags = dng.get("raw_page_tags", {})
    if BLACK_LEVEL not in tags:
        return None
    dims = tags.get(BLACK_LEVEL_REPEAT_DIM, np.array([1.0, 1.0])).astype(int)
    delta_h = tags.get(BLACK_LEVEL_DELTA_H)
    delta_v = tags.get(BLACK_LEVEL_DELTA_V)
    if delta_h is None and delta_v is None and dims[0] <= 2 and dims[1] <= 2:
        return None
    rows, cols = shape
    pattern = tags[BLACK_LEVEL].reshape(dims[0], dims[1])
    # DNG black levels are indexed from the top-left of the ActiveArea, which is LibRaw's
    # visible area for DNG files.
    r = np.arange(rows) % dims[0]
    c = np.arange(cols) % dims[1]
    black = pattern[np.ix_(r, c)].astype(np.float64)
    if delta_v is not None and len(delta_v) >= rows:
        black += delta_v[:rows, None]
    if delta_h is not None and len(delta_h) >= cols:
        black += delta_h[None, :cols]
    return black
