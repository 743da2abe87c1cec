"""Merging an exposure bracket into one relative radiance map.

Each frame's normalised camera value v is divided by its exposure factor e = t·S/N², so every
frame estimates the same x = v/e. Saturated values and values below a few read-noise
standard deviations are left out per channel; the rest are combined with inverse-variance
weights from a shot + read noise model, evaluated at a first estimate of x (so that the
weights do not depend on each frame's own noise, which would bias the mean).

References
----------
Granados, Ajdin, Wand, Theobalt, Seidel & Lensch, "Optimal HDR reconstruction with linear
digital cameras", CVPR 2010 (inverse-variance weights from a shot + read noise model).
Hasinoff, Durand & Freeman, "Noise-optimal capture for high dynamic range photography",
CVPR 2010. EMVA 1288 Release 4.0 (linear camera noise model).
"""

import warnings
from dataclasses import dataclass

import numpy as np

from .._validation import check_positive
from ..constants import SATURATION_FRACTION
from ..errors import BadInputError, MisalignmentWarning


#: Fraction of the saturation level above which a frame's expected value counts as too
#: close to the clip to be used in a merge (see :func:`merge_bracket`).
NEAR_SATURATION = 0.9


@dataclass(frozen=True)
class NoiseModel:
    """Linear sensor noise model (EMVA 1288) at ISO 100.

    Parameters
    ----------
    full_well : float
        Electrons that reach the white level at ISO 100 [e⁻]; at ISO S the white level
        holds full_well·100/S electrons.
    read_noise : float
        Read noise at the sensor input [e⁻ rms].

    The variance of a normalised value v at ISO S is v/g + (r/g)² with g = full_well·100/S.
    """

    full_well: float = 30000.0
    read_noise: float = 3.0

    def gain(self, iso):
        """Electrons per unit normalised value at ISO ``iso`` [e⁻]."""
        return self.full_well * 100.0 / iso

    def variance(self, value, iso):
        """Variance of normalised value(s) ``value`` at ISO ``iso`` [–]."""
        g = self.gain(iso)
        return np.maximum(value, 0.0) / g + (self.read_noise / g) ** 2


@dataclass
class MergedImage:
    """Relative radiance x = v/e per camera channel with its variance.

    Attributes
    ----------
    radiance : ndarray, float32, (rows, cols, 3)
        Exposure-normalised camera RGB [N²·s⁻¹ per unit ISO]; NaN where every frame was
        saturated.
    saturated : ndarray, bool, (rows, cols, 3)
        Channels saturated in every frame.
    shifts : list of (float, float)
        Measured shift of each frame against the reference frame [px of the sensor].

    The variance of any linear combination of the channels (e.g. luminance Y) comes from
    :meth:`variance_of`. A merged bracket stores per-channel variances; a single frame
    stores the noise model's linear form a_c·v_c + b_c, which is cheaper to combine.
    """

    radiance: np.ndarray
    saturated: np.ndarray
    shifts: list
    channel_variance: np.ndarray | None = None
    linear_noise: tuple | None = None  # (v, a, b) of a single frame

    def variance_of(self, weights):
        """Variance [–] of ``radiance @ weights`` per pixel (float32, (rows, cols))."""
        w2 = np.asarray(weights, dtype=np.float64) ** 2
        if self.channel_variance is not None:
            return self.channel_variance @ w2.astype(np.float32)
        value, a, b = self.linear_noise
        # Shot noise of values below black (read noise around 0) is 0, not negative.
        shot = np.maximum(value @ (w2 * a).astype(np.float32), np.float32(0))
        shot += np.float32(np.dot(w2, b))
        return shot


def measure_shift(reference, moving, low, high, *, max_size=512):
    """Translation (rows, cols) [px] of ``moving`` against ``reference`` by phase correlation.

    Both images (exposure-normalised, one channel) are clipped to [low, high], the range
    where both frames hold valid values: beyond it both saturate or vanish alike, so the
    clipped images differ only by noise and the shift. Computed on log values of a copy at
    most ``max_size`` px, to a tenth of its pixel.

    References
    ----------
    Guizar-Sicairos, Thurman & Fienup, "Efficient subpixel image registration algorithms",
    Opt. Lett. 33 (2008) 156 (scikit-image's ``phase_cross_correlation``).
    """
    from skimage.registration import phase_cross_correlation
    from skimage.transform import downscale_local_mean

    step = max(1, int(np.ceil(max(reference.shape) / max_size)))

    def prep(x):
        y = np.log(np.clip(np.nan_to_num(x, nan=low), low, high))
        if step > 1:
            rows, cols = (y.shape[0] // step) * step, (y.shape[1] // step) * step
            y = downscale_local_mean(y[:rows, :cols], (step, step))
        return y - y.mean()

    from scipy.ndimage import shift as shift_image

    ref, mov = prep(reference), prep(moving)
    if not ref.any() or not mov.any():
        return (0.0, 0.0)
    shift, _, _ = phase_cross_correlation(ref, mov, upsample_factor=10)
    # A shift is only real if applying it explains the difference between the frames: an
    # image without structure along one direction (a ramp, a blank wall) leaves that
    # component undetermined. Compare residuals away from the borders.
    margin = int(np.ceil(np.abs(shift).max())) + 2
    if 2 * margin >= min(ref.shape):
        return (0.0, 0.0)
    inner = (slice(margin, -margin), slice(margin, -margin))
    before = np.mean((ref - mov)[inner] ** 2)
    after = np.mean((ref - shift_image(mov, shift, order=1, mode="nearest"))[inner] ** 2)
    if not after < 0.5 * before:
        return (0.0, 0.0)
    return (float(-shift[0] * step), float(-shift[1] * step))


def merge_bracket(frames, exposures, isos, *, noise=NoiseModel(), near_black_sigma=3.0, binning=1,
                  averaged=(1, 1, 1), check_alignment=True, saturation_level=SATURATION_FRACTION):
    """Merge normalised frames of one view into relative radiance.

    Parameters
    ----------
    frames : sequence of (rgb, saturated)
        Normalised camera RGB ``(rows, cols, 3)`` and its saturation mask, as from
        :func:`~lsadphoto.raw.decode_raw`.
    exposures : sequence of float
        Exposure factor e = t·S/N² of each frame [s].
    isos : sequence of float
        ISO speed of each frame (for the noise model).
    noise : NoiseModel
    near_black_sigma : float
        Values below this many read-noise standard deviations are left out, unless no
        frame has more signal.
    binning : int
        Sensor pixels per output pixel (shifts are reported in sensor pixels).
    averaged : (int, int, int)
        CFA values averaged into each output value per channel (superpixel: 1, 2, 1); the
        noise variance of the channel is divided by it. Interpolated values of LibRaw's
        methods are counted as single values, which overstates their noise a little.
    check_alignment : bool
        Measure each frame's shift against the reference and warn above one pixel.
    saturation_level : float
        Normalised value where frames saturate (bounds the range used for alignment).

    Returns
    -------
    MergedImage
    """
    if len(frames) == 0:
        raise BadInputError("no frames to merge")
    if not len(frames) == len(exposures) == len(isos):
        raise BadInputError("frames, exposures and ISO values differ in number")
    shape = frames[0][0].shape
    for i, (rgb, sat) in enumerate(frames):
        if rgb.shape != shape or sat.shape != shape:
            raise BadInputError(f"bracket frame {i + 1} is {rgb.shape[:2]} but frame 1 is {shape[:2]}")
        if not np.all(np.isfinite(rgb)):
            raise BadInputError(f"bracket frame {i + 1} contains NaN or infinite values")
    exposures = [check_positive(e, "exposure") for e in exposures]
    isos = [check_positive(s, "ISO") for s in isos]

    order = np.argsort(exposures)[::-1]  # longest first
    rgb = [frames[i][0] for i in order]
    sat = [frames[i][1] for i in order]
    e = [float(exposures[i]) for i in order]
    s = [float(isos[i]) for i in order]
    read_sd = [noise.read_noise / noise.gain(iso) for iso in s]
    per_channel = (1.0 / np.asarray(averaged, dtype=np.float64)).astype(np.float32)

    def variance_x(value, k):
        """Variance of x = v/e for expected normalised value(s) ``value`` in frame k
        (NoiseModel.variance, computed in place in float32 for speed)."""
        g = noise.gain(s[k])
        out = np.maximum(value, np.float32(0), dtype=np.float32)
        out *= (per_channel / np.float32(g * e[k] ** 2)).astype(np.float32)
        out += (per_channel * np.float32(read_sd[k] ** 2 / e[k] ** 2)).astype(np.float32)
        return out

    if len(rgb) == 1:
        # One frame: x = v/e, its variance from the noise model at the measured value:
        # var(x_c) = a_c·v_c + b_c.
        radiance = rgb[0] / np.float32(e[0])
        radiance[sat[0]] = np.nan
        g = noise.gain(s[0])
        a = per_channel / (g * e[0] ** 2)
        b = per_channel * read_sd[0] ** 2 / e[0] ** 2
        return MergedImage(radiance=radiance, saturated=sat[0], shifts=[(0.0, 0.0)],
                           linear_noise=(rgb[0], a, b))
    valid = [~sat[k] & (rgb[k] > np.float32(near_black_sigma * read_sd[k])) for k in range(len(rgb))]
    # First estimate: pooled x = Σ v / Σ e over usable frames (the estimate for pure
    # shot noise); where no frame is usable, the longest unsaturated frame.
    num = np.zeros(shape, np.float32)
    den = np.zeros(shape, np.float32)
    fallback = np.full(shape, np.nan, np.float32)
    for k in range(len(rgb)):
        num += np.where(valid[k], rgb[k], np.float32(0))
        den += np.where(valid[k], np.float32(e[k]), np.float32(0))
        take = np.isnan(fallback) & ~sat[k]
        fallback[take] = rgb[k][take] / np.float32(e[k])
    with np.errstate(invalid="ignore", divide="ignore"):
        first = np.where(den > 0, num / den, fallback)
    # Second pass: inverse-variance weights evaluated at the first estimate. A frame
    # whose expected value (first estimate × e) lies near saturation is left out too:
    # keeping only its draws that happened to stay below the clip would bias the mean.
    wsum = np.zeros(shape, np.float32)
    xsum = np.zeros(shape, np.float32)
    for k in range(len(rgb)):
        expected = first * np.float32(e[k])
        usable = valid[k] & ~(expected > np.float32(NEAR_SATURATION * saturation_level))
        with np.errstate(invalid="ignore", divide="ignore"):
            w = np.where(usable, 1.0 / variance_x(expected, k), np.float32(0))
        wsum += w
        xsum += w * (rgb[k] / np.float32(e[k]))
    none_valid = wsum == 0
    with np.errstate(invalid="ignore", divide="ignore"):
        radiance = np.where(none_valid, fallback, xsum / wsum)
        variance = 1.0 / wsum
    # Where only the fallback was used, its variance is that of the longest
    # unsaturated frame (the frame the fallback took its value from).
    for k in range(len(rgb)):
        if not none_valid.any():
            break
        use = none_valid & ~sat[k]
        variance[use] = variance_x(np.where(use, first * np.float32(e[k]), 0), k)[use]
        none_valid &= ~use
    saturated = sat[0].copy()
    for k in range(1, len(rgb)):
        saturated &= sat[k]
    radiance[saturated] = np.nan
    variance[saturated] = np.nan

    shifts = [(0.0, 0.0)] * len(frames)
    if check_alignment and len(frames) > 1:
        ref = int(np.argmax([v[..., 1].sum() for v in valid]))
        for k in range(len(rgb)):
            low = max(near_black_sigma * read_sd[k] / e[k], near_black_sigma * read_sd[ref] / e[ref])
            high = min(saturation_level / e[k], saturation_level / e[ref])
            if k == ref or low >= high:
                continue
            # Pixels saturated in either frame read as saturated in both, so that the dilated
            # masks of demosaicing do not show up as moved edges.
            either = sat[ref][..., 1] | sat[k][..., 1]
            dr, dc = measure_shift(np.where(either, high, rgb[ref][..., 1] / e[ref]),
                                   np.where(either, high, rgb[k][..., 1] / e[k]), low, high)
            shift = (dr * binning, dc * binning)
            shifts[order[k]] = shift
            if np.hypot(*shift) > 1.0:
                warnings.warn(
                    f"bracket frame {order[k] + 1} is shifted by ({shift[0]:.1f}, {shift[1]:.1f}) px "
                    "against the reference frame; the merged map will be blurred (use a tripod)",
                    MisalignmentWarning,
                    stacklevel=2,
                )
    return MergedImage(
        radiance=radiance,
        channel_variance=variance,
        saturated=saturated,
        shifts=shifts,
    )
