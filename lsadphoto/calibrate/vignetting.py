"""Vignetting: relative illumination of the sensor, as a radial polynomial or a flat-field map.

The gain V(r) = 1 + a₁r² + a₂r⁴ + a₃r⁶ (r: distance from the optical centre over the
half-diagonal of the sensor) multiplies the scene's image; it is divided out of linear
camera RGB before the colour conversion, at the same stage where it was fitted (lensfun
issue #494). A flat-field map gives V per pixel instead (1 at the centre).

References
----------
Goldman, "Vignette and exposure calibration and compensation", IEEE TPAMI 32(12), 2010
(even polynomial in r). Inanici 2006, LR&T 38(2) (polynomial fall-off correction for HDR
photometry).
"""

from dataclasses import dataclass, field

import numpy as np

from .._validation import check_array
from ..errors import BadInputError


@dataclass
class VignettingModel:
    """Vignetting of one lens/aperture.

    Attributes
    ----------
    kind : {"none", "polynomial", "flat-field"}
    coefficients : list of float
        a₁, a₂, … of V = 1 + Σ aₖ r^{2k} (``polynomial``).
    gain_map : ndarray, optional
        V per pixel at any resolution (``flat-field``), resampled to the image.
    centre : (float, float), optional
        Optical centre (row, col) in sensor pixels; default the sensor centre.
    rms_residual : float, optional
        RMS relative residual of the fit [–].
    focal_length, f_number : float, optional
        Focal length [mm] and f-number [–] the model belongs to (vignetting changes with
        both); checked against each frame (:mod:`lsadphoto.calibrate.consistency`).
    """

    kind: str = "none"
    coefficients: list = field(default_factory=list)
    gain_map: np.ndarray | None = None
    centre: tuple | None = None
    rms_residual: float | None = None
    focal_length: float | None = None
    f_number: float | None = None

    def to_dict(self):
        out = {"model": self.kind}
        if self.kind == "polynomial":
            out["coefficients"] = [float(c) for c in self.coefficients]
        if self.centre is not None:
            out["centre"] = [float(c) for c in self.centre]
        if self.rms_residual is not None:
            out["rms_residual"] = float(self.rms_residual)
        if self.focal_length is not None:
            out["focal_length_mm"] = float(self.focal_length)
        if self.f_number is not None:
            out["f_number"] = float(self.f_number)
        return out


def _sensor_radius(sensor_shape, out_shape, binning, centre):
    rows, cols = sensor_shape
    cr, cc = centre if centre is not None else ((rows - 1) / 2.0, (cols - 1) / 2.0)
    shift = (binning - 1) / 2.0
    r = np.arange(out_shape[0]) * binning + shift - cr
    c = np.arange(out_shape[1]) * binning + shift - cc
    half_diagonal = 0.5 * np.hypot(rows, cols)
    return np.sqrt(r[:, None] ** 2 + c[None, :] ** 2) / half_diagonal


def vignetting_gain(model, sensor_shape, out_shape, *, binning=1):
    """Gain V per output pixel (float32, ``out_shape``) of ``model``.

    Parameters
    ----------
    model : VignettingModel
    sensor_shape : (int, int)
        Visible sensor area [px] the model's radius refers to.
    out_shape : (int, int)
        Shape of the image to correct.
    binning : int
        Sensor pixels per output pixel.
    """
    if model is None or model.kind == "none":
        return np.ones(out_shape, np.float32)
    if model.kind == "polynomial":
        r2 = _sensor_radius(sensor_shape, out_shape, binning, model.centre) ** 2
        gain = np.ones(out_shape)
        for k, a in enumerate(model.coefficients, start=1):
            gain += a * r2**k
    elif model.kind == "flat-field":
        import cv2

        gain_map = check_array(model.gain_map, "flat-field map", ndim=2, finite=True, dtype=np.float32)
        gain = cv2.resize(gain_map, (out_shape[1], out_shape[0]), interpolation=cv2.INTER_LINEAR)
    else:
        raise BadInputError(f"unknown vignetting model {model.kind!r}; valid: 'none', 'polynomial', 'flat-field'")
    if np.any(gain <= 0.05):
        raise BadInputError("vignetting gain falls below 0.05 inside the image; check the model")
    return gain.astype(np.float32)


def fit_vignetting_polynomial(flat, sensor_shape, *, binning=1, degree=3, saturated=None, centre=None):
    """Fit V = 1 + Σ_{k=1..degree} aₖ r^{2k} to a flat-field image.

    Parameters
    ----------
    flat : ndarray, (rows, cols)
        Signal of a uniform, diffuse field (e.g. the sum of camera channels of averaged
        flat-field frames, linear).
    sensor_shape : (int, int)
    binning : int
    degree : int
    saturated : ndarray of bool, optional
        Pixels to leave out.
    centre : (float, float), optional

    Returns
    -------
    VignettingModel
        With the fitted coefficients and the RMS relative residual.

    Notes
    -----
    The centre value is fitted as a free scale c₀: flat ≈ c₀ + Σ bₖ r^{2k}, aₖ = bₖ/c₀, by
    linear least squares on all valid pixels.
    """
    flat = check_array(flat, "flat-field image", ndim=2, dtype=np.float64)
    r2 = _sensor_radius(sensor_shape, flat.shape, binning, centre) ** 2
    ok = np.isfinite(flat) & (flat > 0)
    if saturated is not None:
        ok &= ~saturated
    if ok.sum() < 10 * (degree + 1):
        raise BadInputError("flat-field image has too few usable pixels to fit vignetting")
    design = np.stack([r2[ok] ** k for k in range(degree + 1)], axis=1)
    coef, *_ = np.linalg.lstsq(design, flat[ok], rcond=None)
    if coef[0] <= 0:
        raise BadInputError("flat-field fit gave a non-positive centre value")
    model = VignettingModel(kind="polynomial", coefficients=list(coef[1:] / coef[0]), centre=centre)
    fitted = design @ coef
    model.rms_residual = float(np.sqrt(np.mean((flat[ok] / fitted - 1.0) ** 2)))
    return model
