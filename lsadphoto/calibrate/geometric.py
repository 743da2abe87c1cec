"""Geometric camera calibration from chessboard photographs.

Finds the inner corners of a planar chessboard in several 8-bit photographs, fits OpenCV's
pinhole (Brown–Conrady, 5 coefficients) or fisheye (Kannala–Brandt, 4 coefficients) camera
model to them, drops views whose reprojection error is far above the others and fits once
more. The result carries an :class:`~lsadphoto.geometry.opencv.OpenCVPinholeProjection` or
:class:`~lsadphoto.geometry.opencv.OpenCVFisheyeProjection` ready for the rest of the package.

Units: focal lengths, principal point and reprojection errors in pixels (pixel centres at
integer coordinates, OpenCV's convention); square size in millimetres (it only scales the
board poses, never the intrinsics).

References
----------
Z. Zhang, "A flexible new technique for camera calibration", IEEE TPAMI 22(11), 2000,
1330–1334.
J. Kannala & S. S. Brandt, "A generic camera model and calibration method for conventional,
wide-angle, and fish-eye lenses", IEEE TPAMI 28(8), 2006, 1335–1340.
OpenCV documentation, *Camera Calibration and 3D Reconstruction* (calib3d) and *Fisheye
camera model* (``cv::fisheye``), OpenCV 4.x/5.x.
"""

import math
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import BadInputError
from ..geometry.opencv import OpenCVFisheyeProjection, OpenCVPinholeProjection

__all__ = ["ChessboardPattern", "GeometricCalibration", "calibrate_geometry", "parse_pattern"]

_MODELS = ("pinhole", "fisheye")
_MIN_VIEWS = 3
_PATTERN_RE = re.compile(
    r"^\s*chessboard\s*:\s*(\d+)\s*[x×]\s*(\d+)\s*:\s*([0-9]*\.?[0-9]+(?:[eE][-+]?\d+)?)\s*$",
    re.IGNORECASE,
)


@dataclass(frozen=True)
class ChessboardPattern:
    """A planar chessboard target.

    Attributes
    ----------
    cols, rows : int
        Inner corners along the board's width and height (a board of 10×7 squares has 9×6).
    square_mm : float
        Side of one square [mm].
    """

    cols: int
    rows: int
    square_mm: float

    @property
    def corner_count(self):
        """Number of inner corners."""
        return self.cols * self.rows

    def object_points(self):
        """Board coordinates ``(cols·rows, 3)`` [mm] of the inner corners, x fastest, z = 0."""
        grid = np.mgrid[0:self.cols, 0:self.rows].T.reshape(-1, 2)
        pts = np.zeros((self.corner_count, 3), np.float64)
        pts[:, :2] = grid * self.square_mm
        return pts

    def __str__(self):
        return f"chessboard:{self.cols}x{self.rows}:{self.square_mm:g}"


def parse_pattern(text):
    """Parse ``"chessboard:COLSxROWS:SQUARE_MM"`` (inner corners, square side in mm).

    >>> parse_pattern("chessboard:9x6:25")
    ChessboardPattern(cols=9, rows=6, square_mm=25.0)
    """
    if isinstance(text, ChessboardPattern):
        return text
    if not isinstance(text, str):
        raise BadInputError(
            f"pattern must be a string like 'chessboard:9x6:25', got {text!r}"
        )
    m = _PATTERN_RE.match(text)
    if m is None:
        raise BadInputError(
            f"pattern {text!r} is not of the form 'chessboard:COLSxROWS:SQUARE_MM' "
            "(inner corners, e.g. 'chessboard:9x6:25')"
        )
    cols, rows, square = int(m.group(1)), int(m.group(2)), float(m.group(3))
    if cols < 2 or rows < 2:
        raise BadInputError(
            f"pattern {text!r} needs at least 2×2 inner corners, got {cols}×{rows}"
        )
    if cols == rows:
        raise BadInputError(
            f"pattern {text!r} must have different numbers of inner corners along its sides "
            "(a square grid is ambiguous under rotation)"
        )
    if not (math.isfinite(square) and square > 0):
        raise BadInputError(f"pattern {text!r} needs a positive square size in mm")
    return ChessboardPattern(cols, rows, square)


@dataclass
class GeometricCalibration:
    """Result of :func:`calibrate_geometry`.

    Attributes
    ----------
    projection : OpenCVPinholeProjection or OpenCVFisheyeProjection
        The fitted camera.
    rms_px : float
        Root-mean-square reprojection error [px] over all corners of the used views
        (Euclidean distance per corner).
    width, height : int
        Image size [px].
    model : str
        ``"pinhole"`` or ``"fisheye"``.
    per_image : list of dict
        One per input, in order: ``name``, ``used`` (bool), ``reason`` (why it was rejected,
        else None), ``rms_px`` (its reprojection error [px] in the last fit it took part in,
        else None).
    pattern : ChessboardPattern
        The board used.
    """

    projection: object
    rms_px: float
    width: int
    height: int
    model: str
    per_image: list = field(default_factory=list)
    pattern: ChessboardPattern = None

    def summary(self):
        """JSON-ready dict of the result (pixels for fx, fy, cx, cy and RMS)."""
        p = self.projection
        return {
            "model": self.model,
            "width": self.width,
            "height": self.height,
            "rms_px": float(self.rms_px),
            "fx": float(p.fx),
            "fy": float(p.fy),
            "cx": float(p.cx),
            "cy": float(p.cy),
            "distortion": [float(v) for v in p.distortion],
            "pattern": str(self.pattern) if self.pattern is not None else None,
            "used_images": [r["name"] for r in self.per_image if r["used"]],
            "rejected_images": [
                {"name": r["name"], "reason": r["reason"]}
                for r in self.per_image if not r["used"]
            ],
            "per_image": [dict(r) for r in self.per_image],
        }


def _cv2():
    try:
        import cv2
    except ImportError:  # pragma: no cover - declared dependency
        raise BadInputError("geometric calibration needs OpenCV (opencv-python)") from None
    return cv2


def _load(cv2, item, index):
    """(name, grayscale uint8 array or None)."""
    if isinstance(item, np.ndarray):
        name = f"image {index + 1}"
        img = item
        if img.dtype != np.uint8 or img.ndim not in (2, 3) or img.size == 0:
            return name, None
        if img.ndim == 3:
            if img.shape[2] == 1:
                img = img[:, :, 0]
            elif img.shape[2] == 3:
                img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
            elif img.shape[2] == 4:
                img = cv2.cvtColor(img, cv2.COLOR_BGRA2GRAY)
            else:
                return name, None
        return name, np.ascontiguousarray(img)
    path = Path(item)
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE) if path.is_file() else None
    return path.name, img


def _find_corners(cv2, gray, pattern):
    size = (pattern.cols, pattern.rows)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    found, corners = cv2.findChessboardCorners(gray, size, flags=flags)
    if not found:
        found, corners = cv2.findChessboardCornersSB(gray, size)
        if not found:
            return None
        # The SB detector is sub-pixel accurate already.
        return corners.reshape(-1, 2).astype(np.float64)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-3)
    # Half window [px]: small enough to stay inside one square of a small or distant board.
    spacing = _min_spacing(corners.reshape(-1, 2), pattern)
    half = int(max(2, min(11, spacing / 4)))
    corners = cv2.cornerSubPix(gray, corners.astype(np.float32), (half, half), (-1, -1),
                               criteria)
    return corners.reshape(-1, 2).astype(np.float64)


def _min_spacing(pts, pattern):
    grid = pts.reshape(pattern.rows, pattern.cols, 2)
    dx = np.linalg.norm(np.diff(grid, axis=1), axis=-1).min()
    dy = np.linalg.norm(np.diff(grid, axis=0), axis=-1).min()
    return float(min(dx, dy))


def _fit(cv2, model, obj, img_pts, size):
    """(K, dist, rvecs, tvecs); raises BadInputError if OpenCV fails."""
    w, h = size
    try:
        if model == "pinhole":
            K = np.eye(3)
            dist = np.zeros(5)
            criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
            _, K, dist, rvecs, tvecs = cv2.calibrateCamera(
                [obj.astype(np.float32)] * len(img_pts),
                [p.reshape(-1, 1, 2).astype(np.float32) for p in img_pts],
                (w, h), K, dist, flags=0, criteria=criteria,
            )
            dist = np.asarray(dist, float).ravel()[:5]
        else:
            K = np.zeros((3, 3))
            dist = np.zeros((4, 1))
            flags = cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_FIX_SKEW
            criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-10)
            _, K, dist, rvecs, tvecs = cv2.fisheye.calibrate(
                [obj.reshape(1, -1, 3)] * len(img_pts),
                [p.reshape(1, -1, 2) for p in img_pts],
                (w, h), K, dist, flags=flags, criteria=criteria,
            )
            dist = np.asarray(dist, float).ravel()
    except cv2.error as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else "unknown error"
        raise BadInputError(f"OpenCV calibration failed: {msg}") from None
    K = np.asarray(K, float).copy()
    K[0, 1] = K[1, 0] = 0.0
    K[2] = (0.0, 0.0, 1.0)
    if not (np.all(np.isfinite(K)) and np.all(np.isfinite(dist))):
        raise BadInputError("OpenCV calibration did not converge (non-finite parameters)")
    return K, dist, rvecs, tvecs


def _view_errors(cv2, model, obj, img_pts, K, dist, rvecs, tvecs):
    """Per-view arrays of corner distances [px]."""
    out = []
    for pts, r, t in zip(img_pts, rvecs, tvecs):
        if model == "pinhole":
            proj, _ = cv2.projectPoints(obj, r, t, K, dist)
        else:
            proj, _ = cv2.fisheye.projectPoints(obj.reshape(1, -1, 3), r, t, K, dist)
        out.append(np.linalg.norm(proj.reshape(-1, 2) - pts, axis=1))
    return out


def calibrate_geometry(images, *, pattern, model="pinhole", outlier_factor=3.0):
    """Calibrate a camera's geometry from photographs of a chessboard.

    Parameters
    ----------
    images : sequence of path-like or numpy arrays
        8-bit photographs (read in grayscale with ``cv2.imread``), or uint8 arrays (gray,
        BGR or BGRA) named ``"image 1"``, ``"image 2"``, … in the report.
    pattern : str or ChessboardPattern
        ``"chessboard:COLSxROWS:SQUARE_MM"``: inner corners and square side [mm].
    model : {"pinhole", "fisheye"}
        ``"pinhole"``: ``cv2.calibrateCamera`` with 5 coefficients ``(k1, k2, p1, p2, k3)``
        (Zhang 2000). ``"fisheye"``: ``cv2.fisheye.calibrate`` with ``(k1, k2, k3, k4)``,
        zero skew and extrinsics recomputed at each iteration (Kannala & Brandt 2006).
    outlier_factor : float
        A view whose RMS reprojection error [px] exceeds ``outlier_factor`` × the median of
        the views' RMS is rejected and the camera fitted once more without it (> 1).

    Returns
    -------
    GeometricCalibration

    Raises
    ------
    BadInputError
        Bad pattern, model or factor, fewer than 3 usable views, or an OpenCV failure.

    Notes
    -----
    Corners come from ``cv2.findChessboardCorners`` (adaptive threshold, normalised image)
    refined by ``cv2.cornerSubPix``, with ``cv2.findChessboardCornersSB`` as fallback. The
    image size is the most common size among the readable images; others are rejected with
    reason ``"size differs"``. Per-view RMS is sqrt(mean of squared corner distances).

    References
    ----------
    Z. Zhang, IEEE TPAMI 22(11), 2000, 1330–1334; J. Kannala & S. S. Brandt, IEEE TPAMI
    28(8), 2006, 1335–1340; OpenCV calib3d documentation.
    """
    pattern = parse_pattern(pattern)
    if model not in _MODELS:
        raise BadInputError(f"model must be 'pinhole' or 'fisheye', got {model!r}")
    try:
        outlier_factor = float(outlier_factor)
    except (TypeError, ValueError):
        raise BadInputError(f"outlier_factor must be a number, got {outlier_factor!r}") from None
    if not (math.isfinite(outlier_factor) and outlier_factor > 1.0):
        raise BadInputError(f"outlier_factor must be a finite number > 1, got {outlier_factor}")
    if isinstance(images, (str, Path, np.ndarray)):
        images = [images]
    images = list(images)
    if not images:
        raise BadInputError("no images given for geometric calibration")
    cv2 = _cv2()

    records = []
    loaded = []
    for i, item in enumerate(images):
        name, img = _load(cv2, item, i)
        records.append({"name": name, "used": False, "reason": None, "rms_px": None})
        loaded.append(img)
        if img is None:
            records[-1]["reason"] = "unreadable"

    sizes = Counter(img.shape for img in loaded if img is not None)
    if not sizes:
        raise BadInputError("none of the images could be read")
    most = max(sizes.values())
    shape = next(im.shape for im in loaded if im is not None and sizes[im.shape] == most)
    height, width = shape

    views = []  # (record index, corners)
    for i, img in enumerate(loaded):
        if img is None:
            continue
        if img.shape != shape:
            records[i]["reason"] = "size differs"
            continue
        try:
            corners = _find_corners(cv2, img, pattern)
        except cv2.error:  # e.g. an image too small for the adaptive threshold
            corners = None
        if corners is None:
            records[i]["reason"] = "board not found"
            continue
        views.append((i, corners))

    def need_views(n):
        if n < _MIN_VIEWS:
            rejected = "; ".join(f"{r['name']}: {r['reason']}" for r in records if r["reason"])
            raise BadInputError(
                f"geometric calibration needs at least {_MIN_VIEWS} usable views of the "
                f"{pattern} board, got {n}" + (f" (rejected: {rejected})" if rejected else "")
            )

    need_views(len(views))
    obj = pattern.object_points()
    fit = _fit(cv2, model, obj, [c for _, c in views], (width, height))
    errors = _view_errors(cv2, model, obj, [c for _, c in views], *fit)
    rms = np.array([math.sqrt(float(np.mean(e ** 2))) for e in errors])
    median = float(np.median(rms))
    keep = rms <= outlier_factor * median
    if not np.all(keep):
        for (i, _), r, k in zip(views, rms, keep):
            if not k:
                records[i]["reason"] = (
                    f"outlier: RMS {r:.3g} px > {outlier_factor:g} × median {median:.3g} px"
                )
                records[i]["rms_px"] = float(r)
        views = [v for v, k in zip(views, keep) if k]
        need_views(len(views))
        fit = _fit(cv2, model, obj, [c for _, c in views], (width, height))
        errors = _view_errors(cv2, model, obj, [c for _, c in views], *fit)
    for (i, _), e in zip(views, errors):
        records[i]["used"] = True
        records[i]["rms_px"] = math.sqrt(float(np.mean(e ** 2)))
    all_err = np.concatenate(errors)
    rms_px = math.sqrt(float(np.mean(all_err ** 2)))

    K, dist = fit[0], fit[1]
    cls = OpenCVPinholeProjection if model == "pinhole" else OpenCVFisheyeProjection
    projection = cls.from_camera_matrix(K, dist, width, height)
    return GeometricCalibration(projection, rms_px, width, height, model, records, pattern)
