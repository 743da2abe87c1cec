"""The luminance stage end to end: RAW file(s) → absolute luminance map [cd/m²].

decode → merge (brackets) → vignetting (linear camera space) → relative Y (colour matrix)
→ absolute scale (spot readings, or the profile's calibration constant with the exposure
equation, flagged uncalibrated).
"""

import warnings
from dataclasses import dataclass

import numpy as np

from ._provenance import build_provenance
from .calibrate.profile import CameraProfile
from .calibrate.spot import calibrate_spots
from .calibrate.vignetting import vignetting_gain
from .constants import DEFAULT_CALIBRATION_CONSTANT_UNCERTAINTY
from .errors import BadInputError, MissingMetadataError, SaturationWarning
from .luminance_map import LuminanceMap
from .raw.bracket import merge_bracket
from .raw.colour import camera_to_xyz_matrix
from .raw.decode import decode_raw

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
                       dark_frame=None, check_alignment=True):
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
    demosaic : {"superpixel", "linear", "ahd", "dcb"}
    colour_method : str
        See :data:`lsadphoto.raw.COLOUR_METHODS`.
    dark_frame : ndarray, optional
        Black-level map [ADU] (see :func:`lsadphoto.raw.decode.read_dark_frame`).
    check_alignment : bool

    Returns
    -------
    LuminanceResult
    """
    paths = list(paths)
    if not paths:
        raise BadInputError("no RAW files given")
    profile = profile or CameraProfile(id="none")
    images = [decode_raw(p, demosaic=demosaic, dark_frame=dark_frame) for p in paths]
    first = images[0]
    for image in images[1:]:
        if image.sensor_shape != first.sensor_shape:
            raise BadInputError(
                f"bracket frames differ in size: {first.path} is {first.sensor_shape}, "
                f"{image.path} is {image.sensor_shape}"
            )
    # Absolute exposures are needed to merge frames or to calibrate without spots.
    need_absolute = len(images) > 1 or not spots
    exposures, isos = _exposures(images, need_absolute)
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
        if spots:
            raise
    if spots:
        calibration = calibrate_spots(relative, saturated, projection, spots, binning=first.binning,
                                      relative_variance=relative_var)
        factor, u_factor, calibrated = calibration.factor, calibration.relative_uncertainty, True
        spot_records = calibration.spots
        method = "spot"
    else:
        if profile.calibration_constant is None:
            raise BadInputError(
                "absolute scale needs spot readings (--spot ROW,COL,CD_M2) or a camera profile "
                "with photometric.calibration_constant"
            )
        factor = profile.calibration_constant
        u_factor = profile.calibration_constant_uncertainty or DEFAULT_CALIBRATION_CONSTANT_UNCERTAINTY
        calibrated, spot_records, method = False, [], "exposure-equation"
    # Signed values: noise around black stays negative so that means over dark regions are
    # unbiased (clamping at 0 biases them upwards); u² = (L·u_k)² + k²·var(Y) says where a
    # pixel is noise.
    luminance = np.float32(factor) * relative
    uncertainty = np.float32(factor) * np.sqrt((relative * np.float32(u_factor)) ** 2 + relative_var)
    saturated_fraction = float(saturated.mean())
    if saturated_fraction > 0:
        warnings.warn(
            f"{100 * saturated_fraction:.2f} % of pixels are saturated in every frame; "
            "their luminance is unknown (NaN)",
            SaturationWarning,
            stacklevel=2,
        )
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
        "demosaic": demosaic,
        "colour_method": colour_used,
        "luminance_weights": [float(w) for w in weights],
        "vignetting": profile.vignetting.to_dict(),
        "profile": profile.id,
        "frames": frames,
        "spots": spot_records,
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
