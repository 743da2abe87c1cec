"""evalglare's check picture (``-c``): the map in grey with the analysed regions in colour.

The picture keeps every pixel's luminance (each colour below is scaled so that Radiance's
luminance of the pixel, 179·(0.265074 R + 0.670115 G + 0.064811 B), is the map's) and is
written as a Radiance picture with the map's ``VIEW=`` line, so ``ximage``, ``pvalue``,
``falsecolor`` and evalglare itself read it. Layers, in evalglare's order (later ones paint
over earlier ones):

1. the map in grey (R = G = B = L/179);
2. glare source k (1-based, in the order of the score's sources) in evalglare's colour
   number k mod 5 + 1: green, blue, olive, purple, teal (evalglare's table ``pcol``);
3. the band (``-B``) in green;
4. outside a mask (``-A``) black;
5. zone 1 (``-l``/``-L``) in purple (0.66, 0.01, 0.33) and zone 2 in orange (0.65, 0.33, 0.02),
   as evalglare colours them.

Invalid pixels (NaN) are black. evalglare numbers its sources in its own scan order, so a
source may get another of the five colours there.

References
----------
Radiance ``src/util/evalglare.c`` v3.06 (setglcolor; the ``-B``, ``-A`` and zone colouring;
``-c``).
"""

from pathlib import Path

import numpy as np

from ..constants import RADIANCE_RGB_LUMINANCE_WEIGHTS, RADIANCE_WHITE_EFFICACY
from ..errors import BadInputError
from ..io.hdr import write_hdr_rgb

__all__ = ["SOURCE_COLOURS", "ZONE_COLOURS", "check_picture", "check_checkfile_path",
           "write_checkfile"]

#: evalglare's source colours (fractions of the luminance carried by R, G, B), numbers 1–5.
SOURCE_COLOURS = ((0.0, 1.0, 0.0), (0.15, 0.15, 0.7), (0.5, 0.5, 0.0), (0.5, 0.0, 0.5),
                  (0.0, 0.5, 0.5))
#: evalglare's zone colours (normalised to a luminance fraction of 1 as evalglare does).
ZONE_COLOURS = ((0.66, 0.01, 0.33), (0.65, 0.33, 0.02))
_BAND_COLOUR = (0.0, 1.0, 0.0)


def _paint(rgb, luminance, region, fractions):
    """Pixels of ``region`` in a colour whose R, G, B carry ``fractions`` of the luminance."""
    weights = np.asarray(RADIANCE_RGB_LUMINANCE_WEIGHTS)
    f = np.asarray(fractions, dtype=np.float64)
    channel = f / f.sum() / weights
    rgb[region] = luminance[region, None] / RADIANCE_WHITE_EFFICACY * channel


def check_picture(luminance, *, labels, band=None, zones=None, mask=None):
    """Radiance RGB ``(rows, cols, 3)`` of evalglare's check picture (see the module notes).

    Parameters
    ----------
    luminance : ndarray, shape (rows, cols)
        L [cd·m⁻²] (NaN where invalid).
    labels : ndarray of int, shape (rows, cols)
        Source number + 1 per pixel (0: none).
    band, mask : ndarray of bool, optional
        Band and mask pixels.
    zones : ndarray of int, optional
        Zone number per pixel (0 outside).

    Returns
    -------
    ndarray, float64, shape (rows, cols, 3)
    """
    L = np.nan_to_num(np.asarray(luminance, dtype=np.float64), nan=0.0)
    rgb = np.repeat((L / RADIANCE_WHITE_EFFICACY)[..., None], 3, axis=-1)
    labels = np.asarray(labels)
    for k in range(5):
        _paint(rgb, L, (labels > 0) & (labels % 5 == k), SOURCE_COLOURS[k])
    if band is not None:
        _paint(rgb, L, np.asarray(band, dtype=bool), _BAND_COLOUR)
    if mask is not None:
        rgb[~np.asarray(mask, dtype=bool)] = 0.0
    if zones is not None:
        for k, colour in enumerate(ZONE_COLOURS, start=1):
            _paint(rgb, L, np.asarray(zones) == k, colour)
    return rgb


def check_checkfile_path(path):
    """Refuse a check-picture path that cannot be written as a file (e.g. a directory)."""
    path = Path(path)
    if path.is_dir():
        raise BadInputError(f"checkfile {path} is a directory, not a file name")
    if path.exists() and not path.is_file():
        raise BadInputError(f"checkfile {path} exists and is not a regular file")
    return path


def write_checkfile(path, rgb, *, projection):
    """Write the check picture (atomic) with the map's ``VIEW=`` line.

    References
    ----------
    Radiance ``src/util/evalglare.c`` v3.06 (``-c``).
    """
    write_hdr_rgb(rgb, check_checkfile_path(path), projection=projection)
