"""Absolute calibration with spot luminance meter readings.

For each spot the factor is k = reading / mean(Y over the meter's acceptance cone), the
mean weighted by pixel solid angle (FORMULAS.md §8). Several spots combine robustly: with
three or more, spots further than 3 scaled MADs from the median are left out (with a
warning), and the mean of the rest is used. The relative standard uncertainty combines
the meter's own (common to every spot, so it does not average down) with the scatter of
the spots (s/√n), or, for one spot, with the noise of its mean.

References
----------
Konica Minolta LS-100/LS-110 instruction manual (1° acceptance angle, ±2 % accuracy).
Pierson, Cauwerts, Bodart & Wienold 2020, LEUKOS, doi:10.1080/15502724.2019.1684319
(photometric adjustment with a measured spot luminance). JCGM 100:2008 (GUM) §4.3.7,
§5.1.2.
"""

import warnings
from dataclasses import dataclass, field

import numpy as np

from .._validation import check_positive
from ..constants import LS100_ACCEPTANCE_ANGLE, LS100_RELATIVE_STANDARD_UNCERTAINTY, SPOT_CV_WARNING
from ..errors import BadInputError, NonUniformSpotWarning

#: Two spots whose factors differ by more than this ratio are reported. The LS-100 reads to
#: ±2 % and the photo's relative luminance over a uniform 1° target is known to a few per
#: cent (noise, residual vignetting), so readings that disagree by 20 % point at a wrong
#: reading, a mis-aimed meter or a non-uniform target, not at measurement noise.
SPOT_DISAGREEMENT_RATIO = 1.2


@dataclass(frozen=True)
class SpotReading:
    """One spot-meter reading.

    Attributes
    ----------
    row, col : float
        Where the meter pointed, in pixels of the full-resolution (visible) RAW frame.
    luminance : float
        The meter's reading [cd·m⁻²].
    acceptance_angle : float
        Full cone angle of the meter [rad] (LS-100: 1°).
    """

    row: float
    col: float
    luminance: float
    acceptance_angle: float = LS100_ACCEPTANCE_ANGLE

    def __post_init__(self):
        angle = self.acceptance_angle
        if isinstance(angle, bool) or not isinstance(angle, (int, float, np.floating)) or not 0 < angle < np.pi:
            shown = f"{np.degrees(angle):g}°" if isinstance(angle, (int, float, np.floating)) else repr(angle)
            raise BadInputError(f"spot acceptance angle must be above 0° and below 180° (full cone), got {shown}")

    @classmethod
    def parse(cls, text, *, acceptance_angle=LS100_ACCEPTANCE_ANGLE):
        """Parse ``"ROW,COL,CD_M2"``."""
        parts = text.split(",")
        if len(parts) != 3:
            raise BadInputError(f"spot {text!r} must be ROW,COL,CD_M2")
        try:
            row, col, value = (float(p) for p in parts)
        except ValueError:
            raise BadInputError(f"spot {text!r} must be three numbers ROW,COL,CD_M2") from None
        if not all(np.isfinite([row, col, value])):
            raise BadInputError(f"spot {text!r} has a non-finite value")
        check_positive(value, f"spot reading in {text!r}")
        return cls(row, col, value, acceptance_angle)


@dataclass
class SpotCalibration:
    """Result of spot calibration.

    Attributes
    ----------
    factor : float
        k [cd·m⁻² per unit of relative luminance].
    relative_uncertainty : float
        Relative standard uncertainty of k [–].
    spots : list of dict
        Per spot: position, reading, mean relative luminance, CV, pixels, factor, used.
    """

    factor: float
    relative_uncertainty: float
    spots: list = field(default_factory=list)


def spot_cone(projection, row, col, acceptance_angle, *, label=None):
    """Pixels of ``projection``'s image inside the cone of full angle ``acceptance_angle``
    around the direction of image point (row, col).

    ``label`` names the spot in messages (default ``spot at (row, col)``, in this image's
    pixels).

    Returns
    -------
    window : (slice, slice)
    mask : ndarray of bool
        Pixels of the window whose centre direction lies in the cone.
    weights : ndarray
        Their solid angles [sr].

    Raises :class:`BadInputError` when the cone reaches outside the image.
    """
    rows, cols = projection.shape
    label = label or f"spot at ({row:g}, {col:g})"
    if not (-0.5 <= row <= rows - 0.5 and -0.5 <= col <= cols - 0.5):
        raise BadInputError(f"{label} is off the image ({rows}×{cols} px)")
    half = 0.5 * acceptance_angle
    axis = projection.directions(row, col)
    # Directions on the cone's rim: rotate the axis by `half` towards 16 azimuths.
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    phi = np.linspace(0, 2 * np.pi, 32, endpoint=False)[:, None]
    rim = np.cos(half) * axis + np.sin(half) * (np.cos(phi) * e1 + np.sin(phi) * e2)
    rim_rows, rim_cols = projection.project(rim)
    if not (np.all(np.isfinite(rim_rows)) and np.all(np.isfinite(rim_cols))):
        raise BadInputError(f"{label}: its cone leaves the camera's field of view")
    r0, r1 = int(np.floor(rim_rows.min())) - 1, int(np.ceil(rim_rows.max())) + 2
    c0, c1 = int(np.floor(rim_cols.min())) - 1, int(np.ceil(rim_cols.max())) + 2
    if rim_rows.min() < -0.5 or rim_cols.min() < -0.5 or rim_rows.max() > rows - 0.5 or rim_cols.max() > cols - 0.5:
        raise BadInputError(f"{label}: its cone reaches beyond the image edge")
    r0, c0 = max(r0, 0), max(c0, 0)
    r1, c1 = min(r1, rows), min(c1, cols)
    rr, cc = np.meshgrid(np.arange(r0, r1), np.arange(c0, c1), indexing="ij")
    dirs = projection.directions(rr, cc)
    mask = dirs @ axis >= np.cos(half)
    if not mask.any():  # cone narrower than a pixel: the pixel holding its axis
        mask[int(round(row)) - r0, int(round(col)) - c0] = True
    return (slice(r0, r1), slice(c0, c1)), mask, projection.solid_angles(rr, cc)


def calibrate_spots(relative, saturated, projection, spots, *, meter_uncertainty=LS100_RELATIVE_STANDARD_UNCERTAINTY,
                    binning=1, relative_variance=None):
    """Calibration factor from spot readings.

    Parameters
    ----------
    relative : ndarray, (rows, cols)
        Relative luminance Y [–]; NaN where unknown.
    saturated : ndarray of bool, (rows, cols)
        Pixels saturated in any channel.
    projection : Projection
        Geometry of ``relative``'s pixels.
    spots : sequence of SpotReading
        Positions in full-resolution sensor pixels.
    meter_uncertainty : float
        Relative standard uncertainty of the meter [–].
    binning : int
        Sensor pixels per pixel of ``relative``.
    relative_variance : ndarray, optional
        Variance of ``relative`` per pixel, for the noise of a single spot's mean.

    Returns
    -------
    SpotCalibration
    """
    if not spots:
        raise BadInputError("no spot readings given")
    shift = (binning - 1) / 2.0
    rows, cols = projection.shape
    results = []
    for spot in spots:
        # Messages name the spot as the user gave it: in full-resolution sensor pixels.
        where = f"spot at ({spot.row:g}, {spot.col:g})"
        if not (-0.5 <= spot.row <= rows * binning - 0.5 and -0.5 <= spot.col <= cols * binning - 0.5):
            raise BadInputError(f"{where} is off the image ({rows * binning}×{cols * binning} sensor px; "
                                "ROW,COL are full-resolution sensor pixels)")
        row = (spot.row - shift) / binning
        col = (spot.col - shift) / binning
        window, mask, weights = spot_cone(projection, row, col, spot.acceptance_angle, label=where)
        n_sat = int(saturated[window][mask].sum())
        if n_sat:
            raise BadInputError(f"{where} covers {n_sat} saturated pixel(s); measure a darker target")
        values = relative[window][mask].astype(np.float64)
        if not np.all(np.isfinite(values)):
            raise BadInputError(f"{where} covers pixels of unknown luminance")
        w = weights[mask]
        mean = float(np.sum(values * w) / np.sum(w))
        if mean <= 0:
            raise BadInputError(f"{where} sees no light in the image (mean relative luminance {mean:g})")
        cv = float(np.sqrt(np.sum(w * (values - mean) ** 2) / np.sum(w)) / mean)
        if cv > SPOT_CV_WARNING:
            warnings.warn(
                f"{where}: luminance varies by {100 * cv:.0f} % (CV) inside the "
                f"{np.degrees(spot.acceptance_angle):g}° cone; "
                "aim at a uniform target",
                NonUniformSpotWarning,
                stacklevel=2,
            )
        if relative_variance is not None:
            var = relative_variance[window][mask].astype(np.float64)
            noise = float(np.sqrt(np.sum(w**2 * var)) / np.sum(w) / mean)
        else:
            noise = cv / np.sqrt(mask.sum())
        results.append({
            "row": spot.row, "col": spot.col, "reading": spot.luminance,
            "acceptance_angle_deg": float(np.degrees(spot.acceptance_angle)),
            "mean_relative": mean, "cv": cv, "pixels": int(mask.sum()),
            "factor": spot.luminance / mean, "noise": noise, "used": True,
        })
    factors = np.array([r["factor"] for r in results])
    if len(factors) >= 3:
        median = np.median(factors)
        mad = 1.4826 * np.median(np.abs(factors - median))
        if mad > 0:
            for r in results:
                if abs(r["factor"] - median) > 3 * mad:
                    r["used"] = False
                    warnings.warn(
                        f"spot at ({r['row']:g}, {r['col']:g}) disagrees with the others "
                        f"(factor {r['factor']:.4g} vs median {median:.4g}); left out",
                        NonUniformSpotWarning,
                        stacklevel=2,
                    )
    used = np.array([r["factor"] for r in results if r["used"]])
    factor = float(used.mean())
    if len(used) >= 2:
        scatter = float(used.std(ddof=1) / np.sqrt(len(used)) / factor)
    else:
        scatter = next(r["noise"] for r in results if r["used"])
    uncertainty = float(np.hypot(meter_uncertainty, scatter))
    kept = [r for r in results if r["used"]]
    low, high = min(kept, key=lambda r: r["factor"]), max(kept, key=lambda r: r["factor"])
    if high["factor"] > SPOT_DISAGREEMENT_RATIO * low["factor"]:
        warnings.warn(
            f"spots disagree: factor {low['factor']:.4g} at ({low['row']:g}, {low['col']:g}) "
            f"({low['reading']:g} cd/m²) against {high['factor']:.4g} at ({high['row']:g}, "
            f"{high['col']:g}) ({high['reading']:g} cd/m²), ×{high['factor'] / low['factor']:.2g}; "
            f"their mean has u = {100 * uncertainty:.0f} %: check the readings and where the meter pointed",
            NonUniformSpotWarning, stacklevel=2)
    return SpotCalibration(factor=factor, relative_uncertainty=uncertainty, spots=results)
