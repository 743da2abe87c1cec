"""The central data type: an absolute luminance map with its geometry and provenance."""

from dataclasses import dataclass, field

import numpy as np

from ._validation import check_array
from .constants import STORAGE_DTYPE
from .errors import BadInputError
from .geometry.base import Projection

__all__ = ["LuminanceMap"]


@dataclass(eq=False)
class LuminanceMap:
    """Absolute luminance per pixel, with what is needed to use and trust it.

    Parameters
    ----------
    luminance : array_like, shape (rows, cols)
        Luminance [cd·m⁻²], stored as float32; NaN where unknown (saturated beyond
        recovery, outside the image circle). Values are signed: a measured map keeps the
        slightly negative values of noise around zero, so that means over dark regions are
        unbiased; ``uncertainty`` says where a pixel is noise.
    uncertainty : array_like, shape (rows, cols), optional
        Standard uncertainty of each pixel's luminance [cd·m⁻²] (calibration and noise
        combined), ≥ 0; NaN where unknown.
    projection : Projection, optional
        Camera geometry mapping each pixel to a direction; ``None`` when unknown.
    line_of_sight : array_like, shape (3,), optional
        Observer's line of sight in the camera frame (unit vector); ``None`` means the
        optical axis.
    calibration_factor : float
        Factor that turned relative values into cd·m⁻² (for spot calibration
        k = reading / mean relative value) [cd·m⁻² per relative unit].
    calibration_uncertainty : float
        Relative standard uncertainty of ``calibration_factor`` [–].
    calibrated : bool
        True when a spot-meter reading fixed the scale; False for an exposure-equation
        estimate (flagged ``uncalibrated`` in every output).
    provenance : dict
        JSON-serialisable record of sources, exposure values, options and versions.
    """

    luminance: np.ndarray
    uncertainty: np.ndarray | None = None
    projection: Projection | None = None
    line_of_sight: np.ndarray | None = None
    calibration_factor: float = 1.0
    calibration_uncertainty: float = 0.0
    calibrated: bool = False
    provenance: dict = field(default_factory=dict)

    def __post_init__(self):
        self.luminance = check_array(self.luminance, "luminance", ndim=2, dtype=STORAGE_DTYPE)
        if self.luminance.size == 0:
            raise BadInputError("luminance map is empty")
        # fmax/fmin skip NaN and reach ±inf where any value is infinite: no mask of the map
        # (1 byte per pixel of fresh memory) is made for the test.
        if np.isinf(np.fmax.reduce(self.luminance, axis=None)) or \
                np.isinf(np.fmin.reduce(self.luminance, axis=None)):
            raise BadInputError("luminance map has infinite values")
        if self.uncertainty is not None:
            self.uncertainty = check_array(
                self.uncertainty, "uncertainty", shape=self.luminance.shape, dtype=STORAGE_DTYPE
            )
            negative = int(np.count_nonzero(self.uncertainty < 0))
            if negative:
                raise BadInputError(f"uncertainty map has {negative} negative value(s): a standard "
                                    "uncertainty is ≥ 0 [cd/m²]")
        if self.projection is not None and tuple(self.projection.shape) != self.luminance.shape:
            raise BadInputError(
                f"projection is for {self.projection.shape} pixels but the map has "
                f"{self.luminance.shape}"
            )
        if self.line_of_sight is not None:
            v = check_array(self.line_of_sight, "line_of_sight", shape=(3,), finite=True, dtype=float)
            norm = np.linalg.norm(v)
            if norm == 0:
                raise BadInputError("line_of_sight must not be the zero vector")
            self.line_of_sight = v / norm
        self.calibration_factor = float(self.calibration_factor)
        self.calibration_uncertainty = float(self.calibration_uncertainty)
        self.calibrated = bool(self.calibrated)

    @property
    def shape(self):
        """Image size ``(rows, cols)`` [px]."""
        return self.luminance.shape

    @property
    def valid_fraction(self):
        """Fraction of pixels with a known (finite) luminance [–]."""
        return float(np.isfinite(self.luminance).mean())
