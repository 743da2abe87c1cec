"""The luminance stage end to end: RAW file(s) → absolute luminance map [cd/m²].

decode → merge (brackets) → vignetting (linear camera space) → relative Y (colour matrix)
→ absolute scale (spot readings, or the profile's calibration constant with the exposure
equation, flagged uncalibrated).
"""

import warnings
from dataclasses import dataclass

import numpy as np

from ._provenance import build_provenance
from .calibrate.consistency import check_profile_frame, image_facts
from .calibrate.draft import draft_profile
from .calibrate.illuminance import calibrate_illuminance, cross_check_illuminance
from .calibrate.overflow import describe_overflow, nd_exposure_factor, repair_overflow_from_illuminance
from .calibrate.spot import calibrate_spots
from .calibrate.vignetting import vignetting_gain
from .constants import DEFAULT_CALIBRATION_CONSTANT_UNCERTAINTY, SATURATION_FRACTION
from .errors import BadInputError, MissingMetadataError, SaturationWarning
from .luminance_map import LuminanceMap
from .raw.bracket import merge_bracket
from .raw.colour import camera_to_xyz_matrix
from .raw.decode import decode_raw

#: Luminance more negative than this many noise standard deviations is a colour artefact
#: (NaN in the map, counted in ``summary["colour_artefact_pixels"]``), not noise: Gaussian
#: noise goes that far below zero with probability 3·10⁻⁷.
IMPOSSIBLE_NEGATIVE_SIGMA = 5.0

__all__ = ["luminance_from_raw", "LuminanceResult"]


@dataclass
class LuminanceResult:
    """A luminance map and the JSON-ready summary of how it was made."""

    map: LuminanceMap
    summary: dict


def _exposures(images, need_absolute):
    """Exposure factors e = t·S/N²; relative ones (1) only for a single spot-calibrated frame."""
    values, isos = [], []
    for image in images:
        meta = image.metadata
        try:
            values.append(meta.exposure(path=image.path))
            isos.append(meta.iso)
        except MissingMetadataError:
            if need_absolute:
                raise
            values.append(1.0)
            isos.append(meta.iso or 100.0)
    return values, isos


def luminance_from_raw(paths, *, spots=(), profile=None, demosaic="superpixel", colour_method="auto",
                       dark_frame=None, check_alignment=True, illuminance=None, nd_filter=None):
    """Absolute luminance map from one RAW file or an exposure bracket of one view.

    Parameters
    ----------
    paths : sequence of path-like
        RAW files of one view (several: an exposure bracket).
    spots : sequence of SpotReading
        Spot-meter readings (positions in full-resolution sensor pixels). Without them the
        profile's calibration constant gives an ``uncalibrated`` estimate.
    profile : CameraProfile, optional
        Camera profile (geometry, vignetting, colour matrix, calibration constant, noise).
        Without one, a profile is drafted from the first file's EXIF and the lensfun
        database (:func:`lsadphoto.calibrate.draft.draft_profile`); the summary's
        ``camera_values`` says where each value came from and ``nominal`` which ones are
        not measured for this camera. The profile is checked against every frame
        (:mod:`lsadphoto.calibrate.consistency`): camera, lens, image size, focal length and
        aperture must agree, else :class:`BadInputError` names both values.
    demosaic : {"superpixel", "linear", "ahd", "dcb"}
    colour_method : str
        See :data:`lsadphoto.raw.COLOUR_METHODS`.
    dark_frame : ndarray, optional
        Black-level map [ADU] (see :func:`lsadphoto.raw.decode.read_dark_frame`).
    check_alignment : bool
    illuminance : IlluminanceReading, optional
        An illuminance-meter reading at the lens facing along the optical axis (a
        hemispherical map only): without spots it calibrates the map; with spots it
        cross-checks them (:mod:`lsadphoto.calibrate.illuminance`), warning with both numbers
        beyond twice the combined uncertainty. With spots, it also repairs a luminous
        overflow (pixels saturated in every frame): their luminance becomes the meter's
        deficit spread over them (:mod:`lsadphoto.calibrate.overflow`).
    nd_filter : sequence of float, optional
        Neutral-density filter per frame [stops] (0 for frames without): the frame's
        exposure is divided by 2^stops, so an ND frame of the sun joins the bracket.

    Returns
    -------
    LuminanceResult
    """
    paths = list(paths)
    if not paths:
        raise BadInputError("no RAW files given")
    images = [decode_raw(p, demosaic=demosaic, dark_frame=dark_frame) for p in paths]
    first = images[0]
    for image in images[1:]:
        if image.sensor_shape != first.sensor_shape:
            raise BadInputError(
                f"bracket frames differ in size: {first.path} is {first.sensor_shape}, "
                f"{image.path} is {image.sensor_shape}"
            )
    if profile is None:
        profile = draft_profile(paths[0], metadata=first.metadata)
        checks = [check_profile_frame(profile, image_facts(im)) for im in images[1:]]
    else:
        checks = [check_profile_frame(profile, image_facts(im)) for im in images]
    # Absolute exposures are needed to merge frames or to calibrate without spots.
    need_absolute = len(images) > 1 or not spots
    exposures, isos = _exposures(images, need_absolute)
    if nd_filter is not None:
        if len(nd_filter) != len(images):
            raise BadInputError(f"give one ND filter density per frame ({len(images)}), got {len(nd_filter)}")
        exposures = [e * nd_exposure_factor(s) for e, s in zip(exposures, nd_filter)]
    merged = merge_bracket(
        [(im.rgb, im.saturated) for im in images], exposures, isos, noise=profile.noise,
        binning=first.binning, averaged=(1, 2, 1) if demosaic == "superpixel" else (1, 1, 1),
        check_alignment=check_alignment,
    )
    matrix, colour_used = camera_to_xyz_matrix(first.colour, method=colour_method,
                                               profile_matrix=profile.camera_to_xyz)
    weights = matrix[1]
    relative = merged.radiance @ weights.astype(np.float32)
    relative_var = merged.variance_of(weights)
    gain = np.float32(1.0)
    if profile.vignetting.kind != "none":
        # The gain is the same for the three camera channels, so dividing Y by it is the
        # same as dividing linear camera RGB (and cheaper).
        gain = vignetting_gain(profile.vignetting, first.sensor_shape, first.shape, binning=first.binning)
        relative /= gain
        relative_var /= gain * gain
    saturated = merged.saturated[..., 0] | merged.saturated[..., 1] | merged.saturated[..., 2]
    relative[saturated] = np.nan
    relative_var[saturated] = np.nan
    meta = first.metadata
    projection = None
    try:
        projection = profile.projection(first.sensor_shape, binning=first.binning,
                                        focal_length=meta.focal_length,
                                        focal_plane_resolution=meta.focal_plane_resolution)
    except BadInputError:
        if spots or illuminance is not None:
            raise
    illuminance_check = None
    if illuminance is not None and not spots and saturated.any():
        raise BadInputError(
            f"{100 * saturated.mean():.2f} % of pixels are saturated in every frame (luminous overflow): an "
            "illuminance reading cannot both calibrate the map and fill in the overflow; add spot readings (the "
            "reading then repairs the overflow) or an ND-filter frame (--nd-filter)")
    if illuminance is not None and not spots:
        illuminance_check = calibrate_illuminance(relative, projection, illuminance, relative_variance=relative_var,
                                                  saturated=saturated)
        factor, u_factor, calibrated = illuminance_check.factor, illuminance_check.relative_uncertainty, True
        spot_records, method = [], "illuminance"
    elif spots:
        calibration = calibrate_spots(relative, saturated, projection, spots, binning=first.binning,
                                      relative_variance=relative_var)
        factor, u_factor, calibrated = calibration.factor, calibration.relative_uncertainty, True
        spot_records = calibration.spots
        method = "spot"
        if illuminance is not None and not saturated.any():
            illuminance_check = cross_check_illuminance(relative, projection, illuminance, factor=factor,
                                                        factor_uncertainty=u_factor, relative_variance=relative_var,
                                                        saturated=saturated)
    else:
        if profile.calibration_constant is None:
            raise BadInputError(
                "absolute scale needs spot readings (--spot ROW,COL,CD_M2), an illuminance reading "
                "(--illuminance LUX, hemispherical maps) or a camera profile with photometric.calibration_constant"
            )
        factor = profile.calibration_constant
        u_factor = profile.calibration_constant_uncertainty or DEFAULT_CALIBRATION_CONSTANT_UNCERTAINTY
        calibrated, spot_records, method = False, [], "exposure-equation"
    # Signed values: noise around black stays negative so that means over dark regions are
    # unbiased (clamping at 0 biases them upwards); u² = (L·u_k)² + k²·var(Y) says where a
    # pixel is noise.
    luminance = np.float32(factor) * relative
    uncertainty = np.float32(factor) * np.sqrt((relative * np.float32(u_factor)) ** 2 + relative_var)
    # Luminance below −IMPOSSIBLE_NEGATIVE_SIGMA noise standard deviations is not noise: it is
    # a colour artefact where the pixel's camera channels saw different luminances (a sharp
    # luminaire edge across a superpixel or the demosaic's footprint, combined with negative
    # camera → Y weights). Such a value is unknown, not a measurement: NaN, counted.
    noise = np.float32(factor) * np.sqrt(relative_var)
    artefact = luminance < -np.float32(IMPOSSIBLE_NEGATIVE_SIGMA) * noise
    artefacts = int(np.count_nonzero(artefact))
    if artefacts:
        luminance = np.where(artefact, np.float32(np.nan), luminance)
        uncertainty = np.where(artefact, np.float32(np.nan), uncertainty)
    saturated_fraction = float(saturated.mean())
    # The least-exposed frame saturates at x = SATURATION_FRACTION/e in every channel: a
    # neutral source there has Y = x·Σw (then the vignetting correction).
    bound = factor * SATURATION_FRACTION / min(exposures) * float(weights.sum()) / gain
    overflow = describe_overflow(saturated, luminance, projection, luminance_lower_bound=bound,
                                 binning=first.binning)
    if overflow is not None and illuminance is not None and spots:
        luminance = repair_overflow_from_illuminance(luminance, saturated, projection, illuminance, overflow)
        uncertainty = np.where(saturated, np.float32(overflow.repaired_uncertainty), uncertainty)
    elif overflow is not None:
        warnings.warn(overflow.message(), SaturationWarning, stacklevel=2)
    frames = [
        {"path": im.path, "exposure_factor": e, **im.metadata.to_dict(),
         "shift_px": list(shift)}
        for im, e, shift in zip(images, exposures, merged.shifts)
    ]
    summary = {
        **build_provenance(inputs=[im.path for im in images], profile=profile.id,
                           calibration_factor=factor, calibration_uncertainty=u_factor),
        "calibration_factor": factor,
        "calibration_uncertainty": u_factor,
        "calibrated": calibrated,
        "calibration_method": method,
        "saturated_fraction": saturated_fraction,
        "colour_artefact_pixels": artefacts,
        "overflow": None if overflow is None else overflow.to_dict(),
        "demosaic": demosaic,
        "colour_method": colour_used,
        "luminance_weights": [float(w) for w in weights],
        "vignetting": profile.vignetting.to_dict(),
        "profile": profile.id,
        "camera_values": dict(profile.sources),
        "nominal": profile.nominal_values(),
        "profile_checks": checks,
        "frames": frames,
        "spots": spot_records,
        "illuminance": None if illuminance_check is None else illuminance_check.to_dict(),
        "shape": list(relative.shape),
        "black_map_used": first.black_map_used,
    }
    lmap = LuminanceMap(
        luminance=luminance,
        uncertainty=uncertainty,
        projection=projection,
        calibration_factor=factor,
        calibration_uncertainty=u_factor,
        calibrated=calibrated,
        provenance=summary,
    )
    return LuminanceResult(map=lmap, summary=summary)
