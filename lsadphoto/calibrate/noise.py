"""Measuring the noise model (profile ``[noise]``) by the photon-transfer method.

For one CFA pixel of normalised value v (0 at black, 1 at the white level) with g electrons
per unit of v, shot and read noise give var(v) = v/g + (σ_r/g)². Pairs of flat frames at the
same settings and several exposure levels (a bracket of a uniform, steady field) give, per
level, the mean of v and the variance of the pair's difference over two (which removes fixed
pattern and the field's own non-uniformity); a straight line through (mean, variance) has
slope 1/g and intercept (σ_r/g)². A pair of dark frames (lens cap on) gives σ_r directly.
The profile's noise model wants the electrons at the white level at ISO 100,
full_well = g·S/100, and σ_r in electrons.

Only the red and blue channels of superpixel decoding are used: each is one CFA pixel (the
green is the mean of two, whose variance is halved).

References
----------
J. R. Janesick, *Photon Transfer: DN → λ*, SPIE Press (2007), chapters 2–5 (the photon
transfer curve, differencing frame pairs). EMVA Standard 1288, release 4.0 (2021),
section 6 (linear model; mean and temporal variance from two frames).
"""

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import BadInputError

__all__ = ["NoiseFit", "fit_photon_transfer"]

#: Levels above this normalised value are left out (the sensor leaves its linear range near
#: the white level, constants.SATURATION_FRACTION).
MAX_LEVEL = 0.9
#: Share of the image (centred) used per frame: vignetting changes the mean across the
#: frame, which the difference removes from the variance but not from the mean.
CENTRE_SHARE = 0.5


@dataclass
class NoiseFit:
    """Result of :func:`fit_photon_transfer`.

    Attributes
    ----------
    full_well : float
        Electrons at the white level at ISO 100 [e⁻].
    read_noise : float
        Read noise [e⁻].
    gain : float
        Electrons per unit of normalised value at the frames' ISO [e⁻].
    iso : float
    points : list of (float, float)
        (mean, variance) per pair and channel [–].
    rms_residual : float
        RMS relative residual of the variances about the line [–].
    read_noise_source : str
    """

    full_well: float
    read_noise: float
    gain: float
    iso: float
    points: list = field(default_factory=list)
    rms_residual: float = math.nan
    read_noise_source: str = ""


def _centre(image):
    rows, cols = image.shape[:2]
    dr, dc = int(rows * (1 - CENTRE_SHARE) / 2), int(cols * (1 - CENTRE_SHARE) / 2)
    return image[dr:rows - dr, dc:cols - dc]


def _pair_statistics(a, b):
    a, b = _centre(np.asarray(a, np.float64)), _centre(np.asarray(b, np.float64))
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 100:
        raise BadInputError("a frame pair has fewer than 100 usable pixels in its centre")
    return 0.5 * (a[ok].mean() + b[ok].mean()), 0.5 * np.var(a[ok] - b[ok], ddof=1)


def _pair_points(a, b):
    """[(mean, variance)] of each channel of a frame pair."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if a.shape != b.shape:
        raise BadInputError("the two frames of a pair differ in size")
    if a.ndim == 2:
        a, b = a[..., None], b[..., None]
    return [tuple(map(float, _pair_statistics(a[..., c], b[..., c]))) for c in range(a.shape[-1])]


def fit_photon_transfer(pairs, *, iso, dark_pair=None):
    """Fit the noise model from pairs of flat frames (and optionally a pair of dark frames).

    Parameters
    ----------
    pairs : sequence of (ndarray, ndarray)
        Two frames of one exposure level each, as arrays ``(rows, cols, channels)`` of
        single-CFA-pixel normalised values (e.g. superpixel R and B) [–]; at least three
        levels spread over the range.
    iso : float
        ISO speed S of all frames [–].
    dark_pair : (ndarray, ndarray), optional
        Two dark frames of the same shape and settings: σ_r from their difference.

    Returns
    -------
    NoiseFit
    """
    if iso is None or not iso > 0:
        raise BadInputError("the photon-transfer fit needs the frames' ISO speed")
    points = []
    for a, b in pairs:
        for mean, var in _pair_points(a, b):
            if 0 < mean < MAX_LEVEL:
                points.append((mean, var))
    levels = {round(m, 3) for m, _ in points}
    if len(levels) < 3:
        raise BadInputError(f"the photon-transfer fit needs at least three exposure levels below {MAX_LEVEL} "
                            f"of the white level, got {len(levels)}")
    mean, var = np.array(points).T
    # Relative weights: var(sample variance) ∝ var², so weight each point by 1/var.
    w = 1.0 / var
    design = np.stack([mean, np.ones_like(mean)], axis=1)
    (slope, intercept), *_ = np.linalg.lstsq(design * np.sqrt(w)[:, None], var * np.sqrt(w), rcond=None)
    if not slope > 0:
        raise BadInputError("the photon-transfer fit gave a non-positive slope: are the frames flat and steady?")
    gain = 1.0 / slope
    residual = float(np.sqrt(np.mean((var / (design @ [slope, intercept]) - 1.0) ** 2)))
    if dark_pair is not None:
        dark_var = float(np.mean([v for _, v in _pair_points(*dark_pair)]))
        read_noise, source = gain * math.sqrt(dark_var), "dark-frame pair"
    else:
        read_noise, source = gain * math.sqrt(max(intercept, 0.0)), "intercept of the photon-transfer line"
    return NoiseFit(full_well=gain * iso / 100.0, read_noise=read_noise, gain=gain, iso=float(iso),
                    points=points, rms_residual=residual, read_noise_source=source)
