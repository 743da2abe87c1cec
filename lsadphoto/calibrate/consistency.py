"""Checks of a camera profile against each frame it is applied to.

A profile describes one camera body, lens, focal length and aperture; used on a frame of
another, it gives silently wrong geometry (a 640 × 424 px profile on a 1734 × 1156 px file),
wrong vignetting (another aperture) or wrong field of view (a zoom at another focal length).
Each check compares what the profile states with what the frame's metadata says; a
contradiction is a :class:`~lsadphoto.errors.BadInputError` naming both values. A value the
frame does not carry cannot be checked and is reported as ``unchecked``.

A zoom lens at another focal length is **refused**, not rescaled: the lens model's distortion
and vignetting change with focal length in ways a profile fitted at one setting does not
describe.
"""

from ..errors import BadInputError

__all__ = ["FOCAL_LENGTH_RTOL", "F_NUMBER_RTOL", "check_profile_frame", "check_profile_frames", "frame_facts",
           "image_facts"]

#: Focal lengths [mm] of one zoom setting agree within 2 % (EXIF records them to 0.1 mm or
#: better; 2 % is a change of the field of view that moves the edge of a 60° view by 0.6°).
FOCAL_LENGTH_RTOL = 0.02
#: f-numbers agree within 6 % (1/12 stop): cameras record nominal 1/3-stop values, so one
#: setting always gives the same number, and the nearest other setting differs by 12 %.
F_NUMBER_RTOL = 0.06


def _norm(text):
    return "".join(ch for ch in (text or "").lower() if ch.isalnum())


def frame_facts(path):
    """Camera, lens, focal length [mm], f-number [–] and visible size (rows, cols) [px] of a RAW file."""
    from ..raw.decode import _reading
    from ..raw.metadata import read_exposure_metadata

    with _reading(path) as raw:
        meta = read_exposure_metadata(path, raw)
        shape = (int(raw.sizes.height), int(raw.sizes.width))
    return {"camera": meta.camera, "lens": meta.lens, "focal_length": meta.focal_length,
            "f_number": meta.f_number, "shape": shape, "path": str(path)}


def image_facts(image):
    """:func:`frame_facts` of a decoded :class:`~lsadphoto.raw.decode.RawImage`."""
    meta = image.metadata
    return {"camera": meta.camera, "lens": meta.lens, "focal_length": meta.focal_length,
            "f_number": meta.f_number, "shape": tuple(image.sensor_shape), "path": image.path}


def check_profile_frame(profile, facts):
    """Compare ``profile`` with one frame's ``facts`` (see :func:`frame_facts`).

    Parameters
    ----------
    profile : CameraProfile
    facts : dict
        ``camera``, ``lens``, ``focal_length``, ``f_number``, ``shape`` and ``path`` of the frame.

    Returns
    -------
    dict
        For each checked quantity ``"agrees"`` or ``"unchecked (…)"``.

    Raises
    ------
    BadInputError
        On the first contradiction, naming the profile's and the frame's value.
    """
    where = f"{facts['path']}: camera profile {profile.id!r}"
    report = {}

    def contradiction(what, mine, theirs, advice=""):
        raise BadInputError(f"{where} is for {what} {mine} but the frame has {theirs}{advice}")

    for key, what in (("camera", "camera"), ("lens", "lens")):
        mine, theirs = getattr(profile, key), facts.get(key)
        if mine and theirs:
            if _norm(mine) != _norm(theirs):
                contradiction(what, repr(mine), repr(theirs))
            report[key] = "agrees"
        else:
            report[key] = f"unchecked ({'profile' if not mine else 'frame'} names none)"
    rows, cols = facts["shape"]
    if profile.width and profile.height:
        if (profile.width, profile.height) != (cols, rows):
            contradiction("images of", f"{profile.width}×{profile.height} px", f"{cols}×{rows} px")
        report["image_size"] = "agrees"
    else:
        report["image_size"] = "unchecked (profile states none)"
    focal = facts.get("focal_length")
    mine = profile.focal_length
    if mine and focal:
        if abs(mine - focal) > FOCAL_LENGTH_RTOL * focal:
            contradiction("focal length", f"{mine:g} mm", f"{focal:g} mm",
                          "; refused, not rescaled: a zoom's distortion, vignetting and field of view "
                          "change with focal length (draft a profile for this setting with `lsadphoto "
                          "calibrate profile`, or omit --profile)")
        report["focal_length"] = "agrees"
    else:
        report["focal_length"] = f"unchecked ({'profile' if not mine else 'frame'} states none)"
    f_number = facts.get("f_number")
    stated = [(v, name) for v, name in ((profile.f_number, "the profile"),
                                        (profile.vignetting.f_number, "its vignetting model")) if v]
    if stated and f_number:
        for value, name in stated:
            if abs(value - f_number) > F_NUMBER_RTOL * f_number:
                contradiction("aperture", f"f/{value:g} ({name})", f"f/{f_number:g}",
                              "; vignetting changes with aperture: fit it at this aperture")
        report["f_number"] = "agrees"
    else:
        report["f_number"] = f"unchecked ({'profile' if not stated else 'frame'} states none)"
    vig_focal = profile.vignetting.focal_length
    if vig_focal and focal and abs(vig_focal - focal) > FOCAL_LENGTH_RTOL * focal:
        contradiction("vignetting at focal length", f"{vig_focal:g} mm", f"{focal:g} mm")
    return report


def check_profile_frames(profile, paths):
    """:func:`check_profile_frame` for each RAW file in ``paths``; returns their reports."""
    return [check_profile_frame(profile, frame_facts(p)) for p in paths]
