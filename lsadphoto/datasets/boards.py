"""Chessboard photographs with a known answer: a board ray-cast through a known camera model.

Each pixel is sampled at ``ss × ss`` points; every sample ray is intersected with the board
plane, and the board — ``(cols + 1) × (rows + 1)`` squares for ``cols × rows`` inner corners,
dark or bright by checker parity — lies on an infinite bright plane (the white margin). The
samples are averaged per pixel and rounded to 8 bits, as a camera's JPEG or PNG would be.
``lsadphoto calibrate geometry`` on such views recovers the camera model it was rendered
with (tests/test_calibrate_geometry.py; the bundled ``data_samples/boards/``).
"""

import cv2
import numpy as np

__all__ = ["chessboard_image", "supersampled_directions"]

#: Grey levels of the dark and bright squares (8-bit, away from clipping).
DARK, BRIGHT = 20.0, 235.0


def supersampled_directions(projection, ss):
    """Camera-frame directions ``(height, width, ss, ss, 3)`` at ss×ss sub-pixel points.

    The points sit at the centres of an ss×ss grid over each pixel (offsets
    ``(k + ½)/ss − ½`` [px] from the pixel centre).
    """
    off = (np.arange(ss) + 0.5) / ss - 0.5
    rows = np.arange(projection.height)[:, None, None, None] + off[None, None, :, None]
    cols = np.arange(projection.width)[None, :, None, None] + off[None, None, None, :]
    return projection.directions(rows, cols)


def chessboard_image(directions, rotation_vector, centre, *, pattern):
    """8-bit image ``(height, width)`` of a chessboard seen along ``directions``.

    Parameters
    ----------
    directions : array (height, width, ss, ss, 3)
        Sample directions in the camera frame (:func:`supersampled_directions`).
    rotation_vector : 3 floats
        Board orientation, a Rodrigues vector [rad] (board x, y axes → camera frame).
    centre : 3 floats
        Position of the middle of the inner-corner grid in the camera frame [mm].
    pattern : ChessboardPattern
        Inner corners and square side [mm] (:class:`lsadphoto.calibrate.geometric.ChessboardPattern`).
    """
    cols, rows, square = pattern.cols, pattern.rows, pattern.square_mm
    R = cv2.Rodrigues(np.asarray(rotation_vector, float))[0]
    t = np.asarray(centre, float) - R @ np.array([(cols - 1) * square / 2, (rows - 1) * square / 2, 0])
    n = R[:, 2]
    with np.errstate(all="ignore"):
        s = (n @ t) / (directions @ n)
        p = s[..., None] * directions - t
        X, Y = p @ R[:, 0], p @ R[:, 1]
    X, Y = np.nan_to_num(X), np.nan_to_num(Y)
    on = (np.isfinite(s) & (s > 0) & (X > -square) & (X < cols * square)
          & (Y > -square) & (Y < rows * square))
    parity = (np.floor(X / square) + np.floor(Y / square)) % 2
    value = np.where(on & (parity == 0), DARK, BRIGHT).mean(axis=(2, 3))
    return np.round(value).astype(np.uint8)
