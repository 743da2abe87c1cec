"""A camera profile drafted from the RAW file itself: EXIF and the lensfun database.

Used whenever no ``--profile`` is given, and written by ``lsadphoto calibrate profile`` for
editing. Every value says where it came from (``profile.sources``); values that are only
nominal (not measured for this camera) are listed in ``profile.nominal``.

Sensor geometry, in order of preference:

1. EXIF ``FocalPlaneXResolution``/``FocalPlaneYResolution`` (pixels per unit of the focal
   plane): the pixel pitch, right in every crop mode.
2. EXIF ``FocalLengthIn35mmFilm`` over ``FocalLength``: the crop factor of *this* image
   (crop modes included); the sensor diagonal is 43.27 mm over it.
3. The lensfun camera entry's crop factor: the full sensor's, wrong in crop modes (said so).

Lens: the lensfun entry matching EXIF's lens name gives the projection type (rectilinear or a
fisheye), the distortion model (poly3, poly5, ptlens) at the shot's focal length, and the
``pa`` vignetting model at its focal length, aperture and focus distance. Without a lensfun
entry the lens is a nominal distortion-free rectilinear lens of the EXIF focal length.

References
----------
CIPA DC-008-2019 (Exif 2.32), tags FocalPlaneXResolution (0xA20E), FocalPlaneResolutionUnit
(0xA210), FocalLengthIn35mmFilm (0xA405), SubjectDistance (0x9206). lensfun 0.3
documentation and ``libs/lensfun/modifier.cpp`` (coordinate systems; the crop-factor
correction between the calibration sensor and the image). ISO 517:2008 (35 mm film frame,
36 × 24 mm, diagonal 43.27 mm).
"""

import math
from functools import lru_cache

import exifread
import numpy as np

from .._validation import check_file
from ..errors import BadInputError
from ..geometry.lensfun import LensfunProjection
from ..raw.metadata import read_exposure_metadata
from .profile import CameraProfile
from .vignetting import VignettingModel

__all__ = ["draft_profile", "lensfun_geometry", "lensfun_projection", "find_camera", "find_lens",
           "FULL_FRAME_DIAGONAL_MM"]

#: Diagonal of the 36 × 24 mm frame [mm] (ISO 517).
FULL_FRAME_DIAGONAL_MM = math.hypot(36.0, 24.0)
#: Aspect ratio lensfun assumes for a lens's calibration sensor when the database gives none
#: (lensfun 0.3 default).
LENSFUN_DEFAULT_ASPECT = 1.5
#: Focus distance [m] lensfun uses when none is known (its Modifier default).
LENSFUN_DEFAULT_DISTANCE = 1000.0
#: Relative disagreement between the focal-plane and 35-mm-equivalent sensor sizes that is
#: reported (the 35-mm focal length is rounded to 1 mm: ≤ 2 % at 25 mm equivalent).
SENSOR_AGREEMENT = 0.03

_KINDS = {"RECTILINEAR": "rectilinear", "FISHEYE": "equidistant", "FISHEYE_EQUISOLID": "equisolid",
          "FISHEYE_ORTHOGRAPHIC": "orthographic", "FISHEYE_STEREOGRAPHIC": "stereographic",
          "FISHEYE_THOBY": "thoby"}
_DISTORTIONS = {"POLY3": "poly3", "POLY5": "poly5", "PTLENS": "ptlens"}
_PER_MM = {2: 1 / 25.4, 3: 1 / 10.0, 4: 1.0, 5: 1000.0}  # EXIF unit: inch, cm, mm, µm


@lru_cache(maxsize=1)
def _database():
    import lensfunpy

    return lensfunpy.Database()


@lru_cache(maxsize=1)
def _lens_xml():
    """{(maker, model): {"aspect", "real_focal", "fov"}} from the lensfun XML files lensfunpy ships.

    lensfunpy does not expose a lens's ``<aspect-ratio>`` (of its calibration sensor: 4:3 for
    compact cameras, 3:2 by default), ``<real-focal-length>`` or ``<field-of-view>``, which
    lensfun's coordinate system and geometry need.
    """
    import xml.etree.ElementTree as ET
    from pathlib import Path

    import lensfunpy

    out = {}
    for xml in sorted((Path(lensfunpy.__file__).parent / "db_files").glob("*.xml")):
        for lens in ET.parse(xml).getroot().iter("lens"):
            maker = next((m.text for m in lens.findall("maker") if "lang" not in m.attrib), None)
            ratio = lens.findtext("aspect-ratio")
            entry = {"aspect": LENSFUN_DEFAULT_ASPECT, "real_focal": [], "fov": []}
            if ratio:
                num, _, den = ratio.partition(":")
                entry["aspect"] = float(num) / float(den) if den else float(num)
            for calib in lens.findall("calibration"):
                for item in calib.findall("real-focal-length"):
                    entry["real_focal"].append((float(item.get("focal")), float(item.get("real-focal"))))
                for item in calib.findall("field-of-view"):
                    entry["fov"].append((float(item.get("focal")), float(item.get("fov"))))
            for model in lens.findall("model"):
                if "lang" not in model.attrib:
                    out[(maker, model.text)] = entry
    return out


def _lens_entry(lens):
    return _lens_xml().get((lens.maker, lens.model), {"aspect": LENSFUN_DEFAULT_ASPECT, "real_focal": [], "fov": []})


def lens_aspect(lens):
    """Aspect ratio of the sensor ``lens`` (a lensfunpy Lens) was calibrated on [–]."""
    return _lens_entry(lens)["aspect"]


def _interpolate(pairs, focal_length):
    pairs = sorted(pairs)
    return float(np.interp(focal_length, [p[0] for p in pairs], [p[1] for p in pairs]))


def geometry_focal_length(lens, focal_length, distortion, terms, mm_per_unit):
    """(focal length [mm] of the lens's undistorted ideal projection, its source).

    As lensfun 0.3 (``GetRealFocalLength`` over the Hugin correction d — 1 − k₁ for poly3,
    1 − a − b − c for ptlens): a measured real focal length f_r gives f_r/d; a measured field
    of view gives the focal length of the ideal projection that spans it on the calibration
    sensor's width; otherwise the nominal (EXIF) focal length. Several entries of a zoom are
    interpolated linearly in focal length.
    """
    entry = _lens_entry(lens)
    if entry["real_focal"]:
        hugin = {"poly3": 1 - terms[0] if terms else 1.0,
                 "ptlens": 1 - sum(terms) if terms else 1.0}.get(distortion, 1.0)
        real = _interpolate(entry["real_focal"], focal_length)
        return real / hugin, f"lensfun real focal length {real:g} mm / Hugin correction {hugin:.5g}"
    if entry["fov"]:
        fov = math.radians(_interpolate(entry["fov"], focal_length))
        half = mm_per_unit * entry["aspect"]
        kind = _KINDS.get(lens.type.name)
        f = {"rectilinear": half / math.tan(fov / 2), "equidistant": half / (fov / 2),
             "orthographic": half / math.sin(fov / 2), "stereographic": half / (2 * math.tan(fov / 4)),
             "equisolid": half / (2 * math.sin(fov / 4)),
             "thoby": half / (1.47 * math.sin(0.713 * fov / 2))}[kind]
        return f, f"lensfun field of view {math.degrees(fov):g}°"
    return focal_length, "nominal focal length (EXIF)"


def _norm(text):
    return "".join(ch for ch in (text or "").lower().replace("f/", "f") if ch.isalnum())


def find_camera(make, model):
    """The lensfun camera entry for EXIF ``make``/``model``, or None."""
    if not model:
        return None
    db = _database()
    found = db.find_cameras(make, model) if make else []
    if not found:
        key = _norm(model)
        found = [c for c in db.cameras if _norm(c.model) == key or _norm(f"{c.maker} {c.model}") == key]
    return found[0] if found else None


def find_lens(camera, lens_name):
    """The lensfun lens entry whose name matches EXIF's ``lens_name``, or None.

    lensfun's own search (which refuses lenses calibrated on a smaller sensor than the
    camera's, as in crop modes) first; then an exact match of the normalised names.
    """
    if not lens_name:
        return None
    db = _database()
    if camera is not None:
        found = db.find_lenses(camera, None, lens_name, loose_search=True)
        if found and _norm(found[0].model) == _norm(lens_name):
            return found[0]
    key = _norm(lens_name)
    found = [lens for lens in db.lenses if _norm(lens.model) == key or _norm(f"{lens.maker} {lens.model}") == key]
    return found[0] if found else None


def lensfun_geometry(*, width, height, crop_factor, calibration_crop_factor,
                     calibration_aspect=LENSFUN_DEFAULT_ASPECT, centre_offset=(0.0, 0.0)):
    """Pixel scale and optical centre of lensfun's normalised coordinates for one image.

    Parameters
    ----------
    width, height : int
        Image size [px].
    crop_factor : float
        Crop factor of this image [–] (its diagonal over 43.27 mm, inverted).
    calibration_crop_factor, calibration_aspect : float
        Crop factor and aspect ratio of the sensor the lens was calibrated on [–].
    centre_offset : (float, float)
        lensfun's lens centre shift (x, y) [normalised].

    Returns
    -------
    dict
        ``scale`` [px per normalised unit], ``cx``, ``cy`` [px], ``mm_per_unit`` [mm],
        ``vignetting_radius_scale`` [–] (image corner radius → calibration corner radius).

    Notes
    -----
    lensfun 0.3 (``lfModifier`` constructor): with s = min(width, height), image aspect
    a_i ≥ 1 and k = (c_cal/c)·√(a_cal² + 1)/√(a_i² + 1), one normalised unit is (s − 1)/(2k)
    px, the centre lies at ((width/s + δx)(s − 1)/2, (height/s + δy)(s − 1)/2), and one unit
    is 21.63 mm/(c_cal·√(a_cal² + 1)) on the focal plane.
    """
    size = min(width, height)
    aspect = max(width, height) / size
    k = calibration_crop_factor / crop_factor * math.hypot(calibration_aspect, 1.0) / math.hypot(aspect, 1.0)
    return {
        "scale": (size - 1) / 2.0 / k,
        "cx": (width / size + centre_offset[0]) * (size - 1) / 2.0,
        "cy": (height / size + centre_offset[1]) * (size - 1) / 2.0,
        "mm_per_unit": FULL_FRAME_DIAGONAL_MM / 2.0 / math.hypot(calibration_aspect, 1.0) / calibration_crop_factor,
        "vignetting_radius_scale": calibration_crop_factor / crop_factor,
    }


def _exif(path):
    with open(path, "rb") as fh:
        return exifread.process_file(fh, details=False)


def _number(tags, name):
    for prefix in ("EXIF ", "Image "):
        tag = tags.get(prefix + name)
        if tag is not None:
            try:
                value = tag.values[0]
                number = float(value.num) / float(value.den) if hasattr(value, "num") else float(value)
            except (ZeroDivisionError, IndexError, TypeError, ValueError):
                return None
            return number if math.isfinite(number) and number > 0 else None
    return None


def _sensor(tags, meta, width, height, camera_lookup):
    """(width_mm, height_mm, crop_factor, source, notes) of this image's sensor area."""
    notes = []
    diagonal_px = math.hypot(width, height)
    from_plane = None
    xres, yres = _number(tags, "FocalPlaneXResolution"), _number(tags, "FocalPlaneYResolution")
    unit_tag = tags.get("EXIF FocalPlaneResolutionUnit") or tags.get("Image FocalPlaneResolutionUnit")
    per_mm = _PER_MM.get(int(unit_tag.values[0])) if unit_tag is not None else None
    if xres and yres and per_mm:
        from_plane = (width / (xres * per_mm), height / (yres * per_mm))
    from_35 = None
    f35 = _number(tags, "FocalLengthIn35mmFilm")
    if f35 and meta.focal_length:
        crop = f35 / meta.focal_length
        diagonal = FULL_FRAME_DIAGONAL_MM / crop
        from_35 = (diagonal * width / diagonal_px, diagonal * height / diagonal_px)
    if from_plane:
        w, h = from_plane
        source = "exif FocalPlaneXResolution/FocalPlaneYResolution (pixel pitch)"
        if from_35 and abs(from_35[0] / w - 1) > SENSOR_AGREEMENT:
            notes.append(f"sensor width {w:.3g} mm from the focal-plane resolution but {from_35[0]:.3g} mm "
                         "from FocalLengthIn35mmFilm; the focal-plane value is used")
    elif from_35:
        w, h = from_35
        source = "exif FocalLengthIn35mmFilm / FocalLength (crop factor of this image)"
    elif (camera_entry := camera_lookup()) is not None and camera_entry.crop_factor:
        diagonal = FULL_FRAME_DIAGONAL_MM / camera_entry.crop_factor
        w, h = diagonal * width / diagonal_px, diagonal * height / diagonal_px
        source = (f"lensfun camera {camera_entry.maker} {camera_entry.model}: crop factor "
                  f"{camera_entry.crop_factor:.4g} of the full sensor (nominal: wrong in a crop mode)")
    else:
        return None, None, None, "missing", notes
    crop = FULL_FRAME_DIAGONAL_MM / math.hypot(w, h)
    return w, h, crop, source, notes


def draft_profile(path, *, metadata=None):
    """A camera profile for ``path`` drafted from its EXIF and the lensfun database.

    Parameters
    ----------
    path : path-like
        A RAW file.
    metadata : ExposureMetadata, optional
        Its exposure metadata where already read (saves reading it twice).

    Returns
    -------
    CameraProfile
        With ``sources`` (where each value came from), ``nominal`` (values that are not a
        measurement of this camera and need calibration), ``notes`` (disagreements between
        sources), ``drafted_from`` (the file) and the shot's focal length and f-number.

    Raises
    ------
    BadInputError
        Never for missing values: those are recorded as missing, and the stage that needs
        them says so.
    """
    from ..raw.decode import _reading

    path = check_file(path, "RAW file")
    with _reading(path) as raw:
        width, height = int(raw.sizes.width), int(raw.sizes.height)
        meta = metadata or read_exposure_metadata(path, raw)
    tags = _exif(path)
    make = str(tags.get("Image Make", "")).strip() or None
    model = str(tags.get("Image Model", "")).strip() or None
    # The lensfun database (≈ 2 s to load) is opened only where EXIF leaves a gap or names a lens.
    camera_lookup = lru_cache(maxsize=1)(lambda: find_camera(make, model))
    lens_entry = find_lens(camera_lookup(), meta.lens) if meta.lens else None
    sources, nominal = {}, []
    profile = CameraProfile(id=f"drafted from {path.name}", camera=meta.camera, lens=meta.lens,
                            width=width, height=height)
    sources["camera"] = "exif Make/Model" if meta.camera else "missing"
    sources["lens"] = meta.sources.get("lens", "missing") if meta.lens else "missing"
    sources["image_size"] = "LibRaw visible area"
    w_mm, h_mm, crop, sensor_source, notes = _sensor(tags, meta, width, height, camera_lookup)
    profile.sensor_width, profile.sensor_height = w_mm, h_mm
    sources["sensor"] = sensor_source
    if sensor_source.startswith("lensfun"):
        nominal.append("sensor")
    f = meta.focal_length
    profile.focal_length = f
    sources["focal_length"] = f"{meta.sources['focal_length']} FocalLength (nominal focal length of the lens)" \
        if f else "missing"
    profile.f_number = meta.f_number
    sources["f_number"] = f"{meta.sources['f_number']} FNumber" if meta.f_number else "missing"
    distance = _number(tags, "SubjectDistance")
    if lens_entry is not None and f and crop:
        profile.lens_projection, vignetting, lens_source = _lensfun_lens(
            lens_entry, width=width, height=height, crop=crop, focal_length=f,
            f_number=meta.f_number, distance=distance)
        sources["lens_model"] = lens_source
        if vignetting is not None:
            profile.vignetting = vignetting
            sources["vignetting"] = (f"lensfun pa model of {lens_entry.maker} {lens_entry.model} at "
                                     f"{f:g} mm, f/{meta.f_number:g}, "
                                     f"{distance or LENSFUN_DEFAULT_DISTANCE:g} m"
                                     + ("" if distance else " (lensfun's default distance)"))
            nominal.append("vignetting")
        else:
            sources["vignetting"] = "none: lensfun has no vignetting data for this lens at this aperture"
    else:
        why = ("no lens name in the file" if not meta.lens else
               f"lens {meta.lens!r} is not in the lensfun database" if lens_entry is None else
               "focal length or sensor size missing")
        sources["lens_model"] = f"nominal distortion-free rectilinear lens ({why})"
        sources["vignetting"] = f"none ({why}): calibrate with flat fields or the rotation method"
        nominal.append("lens_model")
    sources["noise"] = (f"nominal defaults ({profile.noise.full_well:g} e⁻ full well, "
                        f"{profile.noise.read_noise:g} e⁻ read noise at ISO 100), not measured for this camera")
    nominal.append("noise")
    sources["calibration_constant"] = "missing: give spot readings or an illuminance reading"
    profile.sources, profile.nominal, profile.notes = sources, nominal, notes
    profile.drafted_from = str(path)
    return profile


def lensfun_projection(lens, *, width, height, crop_factor, focal_length):
    """The :class:`~lsadphoto.geometry.lensfun.LensfunProjection` of a lensfun lens on one image.

    Parameters
    ----------
    lens : lensfunpy.Lens
    width, height : int
        Image size [px].
    crop_factor : float
        Crop factor of the image [–].
    focal_length : float
        The shot's (nominal) focal length [mm]; distortion is interpolated to it.

    Returns
    -------
    projection : LensfunProjection
    source : str
        What was used, for the profile's sources.
    geometry : dict
        :func:`lensfun_geometry` of the image.
    """
    kind = _KINDS.get(lens.type.name)
    if kind is None:
        raise BadInputError(f"lensfun lens {lens.model!r} is of type {lens.type.name}, which has no "
                            "projection here")
    geometry = lensfun_geometry(width=width, height=height, crop_factor=crop_factor,
                                calibration_crop_factor=lens.crop_factor,
                                calibration_aspect=lens_aspect(lens),
                                centre_offset=(lens.center_x, lens.center_y))
    distortion, terms = "none", []
    calib = lens.interpolate_distortion(focal_length)
    if calib is not None and calib.model.name in _DISTORTIONS:
        distortion = _DISTORTIONS[calib.model.name]
        terms = [float(t) for t in calib.terms[: {"poly3": 1, "poly5": 2, "ptlens": 3}[distortion]]]
    focal, focal_source = geometry_focal_length(lens, focal_length, distortion, terms, geometry["mm_per_unit"])
    projection = LensfunProjection(kind, distortion, terms, focal / geometry["mm_per_unit"],
                                   geometry["scale"], geometry["cx"], geometry["cy"], width, height)
    source = (f"lensfun {lens.maker} {lens.model}: {kind} projection, {distortion} distortion at "
              f"{focal_length:g} mm (calibrated at crop factor {lens.crop_factor:.4g}), "
              f"projection focal length {focal:.4g} mm from the {focal_source}")
    return projection, source, geometry


def _lensfun_lens(lens, *, width, height, crop, focal_length, f_number, distance):
    """(projection, vignetting or None, source text) of a lensfun lens for one image."""
    projection, source, geometry = lensfun_projection(lens, width=width, height=height, crop_factor=crop,
                                                      focal_length=focal_length)
    vignetting = None
    if f_number:
        calib_v = lens.interpolate_vignetting(focal_length, f_number, distance or LENSFUN_DEFAULT_DISTANCE)
        if calib_v is not None and calib_v.model.name == "PA":
            s2 = geometry["vignetting_radius_scale"] ** 2
            coefficients = [float(k) * s2 ** (i + 1) for i, k in enumerate(calib_v.terms[:3])]
            vignetting = VignettingModel(kind="polynomial", coefficients=coefficients,
                                         centre=(geometry["cy"], geometry["cx"]),
                                         focal_length=focal_length, f_number=f_number)
    return projection, vignetting, source
