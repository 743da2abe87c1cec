"""Vignetting: relative illumination of the sensor, as a radial polynomial or a flat-field map.

The gain V(r) = 1 + a₁r² + a₂r⁴ + a₃r⁶ (r: distance from the optical centre over the
half-diagonal of the sensor) multiplies the scene's image; it is divided out of linear
camera RGB before the colour conversion, at the same stage where it was fitted (lensfun
issue #494). A flat-field map gives V per pixel instead (1 at the centre).

Two ways to measure V: flat fields (:func:`fit_vignetting_polynomial`: a uniform diffuse
field filling the view, which needs an integrating sphere for a fisheye) and the rotation
method (:func:`fit_vignetting_rotation`: the camera turned about its entrance pupil in steps
while a fixed, uniformly lit target moves across the field; the target's signal against its
position is the fall-off).

References
----------
Goldman, "Vignette and exposure calibration and compensation", IEEE TPAMI 32(12), 2010
(even polynomial in r). Inanici 2006, LR&T 38(2) (polynomial fall-off correction for HDR
photometry; the rotation measurement of a fisheye's fall-off). Pierson, Cauwerts, Bodart &
Wienold, "Tutorial: luminance maps for daylighting studies from high dynamic range
photography", LEUKOS 17(2), 2021, 140–169 (vignetting by rotating the camera in front of a
fixed target, per aperture).
"""

from dataclasses import dataclass, field

import numpy as np

from .._validation import check_array
from ..errors import BadInputError


#: Most even terms of a vignetting polynomial V = 1 + Σ_{k=1..n} aₖ r^{2k}. Three terms
#: describe camera lenses to better than 1 % (lensfun's ``pa`` model, Kang & Weiss 2000 use
#: r², r⁴, r⁶); beyond six the least-squares fit oscillates between the sampled radii and
#: the powers r^{2k} ≤ 1 become numerically dependent.
MAX_VIGNETTING_TERMS = 6

#: Largest RMS relative residual [1] of a flat-field fit that is accepted as a flat field. A
#: uniform diffuse field leaves photon noise and the lens's small non-radial terms (0.42 % on
#: data_samples/flat, both frames); frames of an ordinary scene leave tens of per cent (46 % on
#: data_samples/office/office_1.dng), which no vignetting model should absorb.
MAX_FLAT_FIELD_RESIDUAL = 0.05


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
    uncertainty : float, optional
        Largest relative standard uncertainty of V over the fitted radii [–] (from the fit's
        covariance).
    focal_length, f_number : float, optional
        Focal length [mm] and f-number [–] the model belongs to (vignetting changes with
        both); checked against each frame (:mod:`lsadphoto.calibrate.consistency`).
    """

    kind: str = "none"
    coefficients: list = field(default_factory=list)
    gain_map: np.ndarray | None = None
    centre: tuple | None = None
    rms_residual: float | None = None
    uncertainty: float | None = None
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
        if self.uncertainty is not None:
            out["uncertainty"] = float(self.uncertainty)
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
        Number of even terms, 1 to :data:`MAX_VIGNETTING_TERMS`.
    saturated : ndarray of bool, optional
        Pixels to leave out.
    centre : (float, float), optional

    Returns
    -------
    VignettingModel
        With the fitted coefficients and the RMS relative residual.

    Raises
    ------
    BadInputError
        A degree out of range, too few usable pixels, or a residual above
        :data:`MAX_FLAT_FIELD_RESIDUAL` (the frames are not a flat field).

    Notes
    -----
    The centre value is fitted as a free scale c₀: flat ≈ c₀ + Σ bₖ r^{2k}, aₖ = bₖ/c₀, by
    linear least squares on all valid pixels.
    """
    if (isinstance(degree, bool) or not isinstance(degree, (int, np.integer))
            or not 1 <= degree <= MAX_VIGNETTING_TERMS):
        raise BadInputError(f"vignetting degree (number of even terms) must be an integer from 1 to "
                            f"{MAX_VIGNETTING_TERMS}, got {degree!r}")
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
    if not model.rms_residual <= MAX_FLAT_FIELD_RESIDUAL:
        raise BadInputError(
            f"the flat-field fit leaves an RMS residual of {100 * model.rms_residual:.1f} % (at most "
            f"{100 * MAX_FLAT_FIELD_RESIDUAL:g} % for a flat field): the frames do not show a uniform "
            "diffuse field")
    return model


def _fit_even_polynomial(r2, signal, weights, degree, centre):
    """Weighted least squares of signal ≈ c₀(1 + Σ aₖ r^{2k}); the model with its residual and
    uncertainty (largest relative standard uncertainty of V over the samples)."""
    design = np.stack([r2 ** k for k in range(degree + 1)], axis=1)
    w = np.sqrt(weights)
    coef, *_ = np.linalg.lstsq(design * w[:, None], signal * w, rcond=None)
    if coef[0] <= 0:
        raise BadInputError("vignetting fit gave a non-positive centre value")
    fitted = design @ coef
    relative = signal / fitted - 1.0
    dof = max(len(signal) - (degree + 1), 1)
    sigma2 = float(np.sum(weights * (signal - fitted) ** 2) / dof)
    covariance = sigma2 * np.linalg.inv((design * weights[:, None]).T @ design)
    # V = fitted/c₀: its relative variance from the gradient of log(fitted) − log(c₀).
    grad = design / fitted[:, None]
    grad[:, 0] -= 1.0 / coef[0]
    u_v = np.sqrt(np.einsum("ij,jk,ik->i", grad, covariance, grad))
    model = VignettingModel(kind="polynomial", coefficients=list(coef[1:] / coef[0]), centre=centre)
    model.rms_residual = float(np.sqrt(np.mean(relative ** 2)))
    model.uncertainty = float(np.max(u_v))
    return model


def _find_target(frame, predicted, size, previous_level):
    """(row, col, mean, standard error, pixels) of the bright target nearest ``predicted``."""
    from scipy import ndimage

    rows, cols = frame.shape
    half = int(3 * size) + 2
    r0, c0 = int(round(predicted[0])), int(round(predicted[1]))
    window = (slice(max(r0 - half, 0), min(r0 + half + 1, rows)), slice(max(c0 - half, 0), min(c0 + half + 1, cols)))
    patch = frame[window]
    if patch.size == 0 or not np.isfinite(patch).any():
        return None
    background = float(np.nanmedian(frame))
    peak = float(np.nanmax(patch))
    if peak <= background or (previous_level is not None and peak < 0.2 * previous_level):
        return None
    labels, count = ndimage.label(np.nan_to_num(patch, nan=background) > 0.5 * (peak + background))
    if count == 0:
        return None
    centres = ndimage.center_of_mass(np.ones_like(patch), labels, range(1, count + 1))
    dist = [np.hypot(r + window[0].start - predicted[0], c + window[1].start - predicted[1]) for r, c in centres]
    label = 1 + int(np.argmin(dist))
    region = ndimage.binary_erosion(labels == label, iterations=2)
    if region.sum() < 5:
        return None
    values = patch[region]
    rr, cc = np.nonzero(region)
    row = float(rr.mean() + window[0].start)
    col = float(cc.mean() + window[1].start)
    touches = (window[0].start + rr.min() <= 2 or window[1].start + cc.min() <= 2
               or window[0].start + rr.max() >= rows - 3 or window[1].start + cc.max() >= cols - 3)
    if touches:
        return None  # cut by the image edge: its mean is not the target's
    return row, col, float(values.mean()), float(values.std(ddof=1) / np.sqrt(values.size)), int(values.size)


def fit_vignetting_rotation(frames, target, sensor_shape, *, binning=1, degree=3, centre=None, saturated=None,
                            f_number=None):
    """Fit V = 1 + Σ aₖ r^{2k} from a rotation sequence of a fixed, uniformly lit target.

    The camera is turned about its entrance pupil in steps (any size, e.g. 5°) while a small,
    uniform target (a lit diffuser, a matt card under steady light) stays put; each frame
    sees the target at another field position, and its mean signal there, relative to the
    largest near the centre, is the relative illumination V at that radius.

    Parameters
    ----------
    frames : sequence of ndarray, (rows, cols)
        Linear signal of each frame (e.g. the sum of camera channels), in rotation order, all
        at the same exposure.
    target : (float, float)
        The target's position (row, col) in the first frame [sensor px].
    sensor_shape : (int, int)
    binning : int
        Sensor pixels per frame pixel.
    degree : int
        Number of even terms.
    centre : (float, float), optional
        Optical centre (row, col) [sensor px]; default the sensor centre.
    saturated : sequence of ndarray of bool, optional
        Per frame, pixels to leave out.
    f_number : float, optional
        The aperture of the sequence [–], recorded in the model (fit one model per aperture).

    Returns
    -------
    model : VignettingModel
        With ``rms_residual`` and ``uncertainty``.
    samples : list of dict
        Per frame: ``row``, ``col`` [sensor px], ``radius`` [half-diagonals], ``signal`` and
        its ``standard_error``, or ``found: False``.

    Notes
    -----
    The target is followed from frame to frame: each search starts where the last two
    positions predict, within three target sizes, and takes the bright connected region
    (above half-way between the frame's median and the local peak) nearest to it, eroded by
    2 px so that blurred edges are left out; a target cut by the image edge or lost is
    skipped. Samples are weighted by their inverse variance (pixel scatter over the region).

    References
    ----------
    Inanici 2006, LR&T 38(2); Pierson et al. 2021, LEUKOS 17(2) (the rotation method).
    """
    frames = [check_array(f, "rotation frame", ndim=2, dtype=np.float64) for f in frames]
    if len(frames) < degree + 2:
        raise BadInputError(f"the rotation method needs at least {degree + 2} frames for {degree} terms, "
                            f"got {len(frames)}")
    shape = frames[0].shape
    if any(f.shape != shape for f in frames):
        raise BadInputError("rotation frames differ in size")
    rows, cols = sensor_shape
    cr, cc = centre if centre is not None else ((rows - 1) / 2.0, (cols - 1) / 2.0)
    shift = (binning - 1) / 2.0
    position = ((target[0] - shift) / binning, (target[1] - shift) / binning)
    if not (0 <= position[0] < shape[0] and 0 <= position[1] < shape[1]):
        raise BadInputError(f"target {target} lies outside the first frame")
    samples, history, size, level = [], [], 3.0, None
    for k, frame in enumerate(frames):
        if saturated is not None:
            frame = np.where(saturated[k], np.nan, frame)
        if len(history) >= 2:
            predicted = (2 * history[-1][0] - history[-2][0], 2 * history[-1][1] - history[-2][1])
        elif history:
            predicted = history[-1]
        else:
            predicted = position
        found = _find_target(frame, predicted, size if history else max(size, 20.0), level)
        if found is None:
            samples.append({"frame": k, "found": False})
            continue
        row, col, mean, error, n = found
        size = max(np.sqrt(n / np.pi) * 2 + 4, 3.0)
        history.append((row, col))
        level = mean
        r_sensor = np.hypot(row * binning + shift - cr, col * binning + shift - cc) / (0.5 * np.hypot(rows, cols))
        samples.append({"frame": k, "found": True, "row": row * binning + shift, "col": col * binning + shift,
                        "radius": float(r_sensor), "signal": mean, "standard_error": error})
    good = [s for s in samples if s["found"]]
    if len(good) < degree + 2:
        raise BadInputError(f"the target was found in {len(good)} of {len(frames)} frames; "
                            f"{degree + 2} are needed (check --target and that it stays in view)")
    r2 = np.array([s["radius"] for s in good]) ** 2
    signal = np.array([s["signal"] for s in good])
    error = np.array([max(s["standard_error"], 1e-12 * abs(s["signal"])) for s in good])
    model = _fit_even_polynomial(r2, signal, 1.0 / error ** 2, degree, centre)
    model.f_number = f_number
    return model, samples
