"""Exposure metadata of RAW files, with the source of every value.

LibRaw (through rawpy's ``other`` and ``lens``) is read first; EXIF (exifread) fills what
LibRaw lacks. LibRaw reports missing values as 0 (e.g. ISO stored in IFD0 of a DNG, see
PITFALLS.md) and derives shutter and aperture from APEX tags, so an APEX value of 0 comes
back as 1 s and f/1: where EXIF states the direct tag as 0, such values count as missing.
"""

import datetime as _dt
import math
import warnings
from dataclasses import dataclass, field

import exifread

from ..errors import MetadataWarning, MissingMetadataError
from ._quiet import quiet_loggers

_FIELDS = ("exposure_time", "f_number", "iso", "focal_length")
_UNITS = {"exposure_time": "s", "f_number": "", "iso": "", "focal_length": "mm"}


@dataclass
class ExposureMetadata:
    """Exposure settings of one RAW file.

    Attributes
    ----------
    exposure_time : float or None
        Exposure time t [s].
    f_number : float or None
        Relative aperture N [–].
    iso : float or None
        ISO speed S [–].
    focal_length : float or None
        Lens focal length [mm].
    camera, lens : str or None
    time : str or None
        Capture time, ISO 8601.
    focal_plane_resolution : (float, float) or None
        Sensor pixels per mm (x, y) from EXIF FocalPlane[XY]Resolution.
    sources : dict
        For each field, ``"libraw"``, ``"exif"`` or ``"missing"``.
    """

    exposure_time: float | None = None
    f_number: float | None = None
    iso: float | None = None
    focal_length: float | None = None
    camera: str | None = None
    lens: str | None = None
    time: str | None = None
    focal_plane_resolution: tuple | None = None
    sources: dict = field(default_factory=dict)

    def exposure(self, *, path=""):
        """Photometric exposure factor e = t·S/N² [s] used to normalise frames.

        Raises :class:`MissingMetadataError` naming every missing value.
        """
        missing = [f for f in ("exposure_time", "iso", "f_number") if getattr(self, f) is None]
        if missing:
            where = f"{path}: " if path else ""
            raise MissingMetadataError(
                f"{where}missing exposure metadata ({', '.join(missing)}); a single frame can be "
                "calibrated with a spot reading (--spot) instead, a bracket needs the values in its "
                "files (e.g. exiftool -ExposureTime=1/125 -FNumber=4 -ISO=100 FILE)"
            )
        return self.exposure_time * self.iso / self.f_number**2

    def to_dict(self):
        """JSON-ready dict of the values and their sources."""
        out = {f: getattr(self, f) for f in (*_FIELDS, "camera", "lens", "time")}
        out["focal_plane_resolution"] = (
            list(self.focal_plane_resolution) if self.focal_plane_resolution else None
        )
        out["sources"] = dict(self.sources)
        return out


def _ratio(tag):
    try:
        value = tag.values[0]
        number = float(value.num) / float(value.den) if hasattr(value, "num") else float(value)
    except (ZeroDivisionError, IndexError, TypeError, ValueError):
        return 0.0
    return number if math.isfinite(number) else 0.0


def _exif(path):
    try:
        with quiet_loggers("exifread"), open(path, "rb") as fh:
            return exifread.process_file(fh, details=False)
    except Exception:  # exifread raises assorted errors on non-TIFF data
        return {}


def _exif_number(tags, *names):
    """(value or None, present): first of ``names`` present; value None when it is 0."""
    for name in names:
        for prefix in ("EXIF ", "Image "):
            if prefix + name in tags:
                value = _ratio(tags[prefix + name])
                return (value if value > 0 else None), True
    return None, False


def _exif_text(tags, *names):
    for name in names:
        if name in tags:
            text = str(tags[name]).strip()
            if text:
                return text
    return None


def read_exposure_metadata(path, raw=None):
    """Read exposure metadata of ``path``; ``raw`` is an open rawpy object to reuse.

    Parameters
    ----------
    path : path-like
    raw : rawpy.RawPy, optional

    Returns
    -------
    ExposureMetadata
    """
    libraw = {}
    lens = None
    timestamp = None
    if raw is not None:
        other = raw.other
        libraw = {
            "exposure_time": other.shutter_speed,
            "f_number": other.aperture,
            "iso": other.iso_speed,
            "focal_length": other.focal_length,
        }
        lens = " ".join(p for p in (raw.lens.make, raw.lens.model) if p).strip() or None
        if other.timestamp and other.timestamp > _dt.datetime(1971, 1, 1):
            timestamp = other.timestamp.isoformat()
    tags = _exif(path)
    exif = {
        "exposure_time": _exif_number(tags, "ExposureTime"),
        "f_number": _exif_number(tags, "FNumber"),
        "iso": _exif_number(tags, "ISOSpeedRatings", "PhotographicSensitivity"),
        "focal_length": _exif_number(tags, "FocalLength"),
    }
    meta = ExposureMetadata()
    for name in _FIELDS:
        lib_value = libraw.get(name) or None
        exif_value, exif_present = exif[name]
        if lib_value is not None and not math.isfinite(lib_value):
            lib_value = None
        if (
            lib_value == 1.0
            and name in ("exposure_time", "f_number")
            and exif_present
            and exif_value is None
        ):
            warnings.warn(
                f"{path}: LibRaw reports {name} = 1 but EXIF records 0; treated as missing",
                MetadataWarning,
                stacklevel=2,
            )
            lib_value = None
        if lib_value is not None:
            if exif_value is not None and abs(exif_value - lib_value) > 0.01 * exif_value:
                warnings.warn(
                    f"{path}: {name} is {lib_value:g} in LibRaw but {exif_value:g} in EXIF; "
                    "using LibRaw's",
                    MetadataWarning,
                    stacklevel=2,
                )
            setattr(meta, name, float(lib_value))
            meta.sources[name] = "libraw"
        elif exif_value is not None:
            setattr(meta, name, float(exif_value))
            meta.sources[name] = "exif"
        else:
            meta.sources[name] = "missing"
    make = _exif_text(tags, "Image Make")
    model = _exif_text(tags, "Image Model")
    if make and model and model.startswith(make):
        meta.camera = model
    else:
        meta.camera = " ".join(p for p in (make, model) if p) or None
    meta.lens = lens or _exif_text(tags, "EXIF LensModel", "Image LensModel")
    meta.time = timestamp or _exif_text(tags, "EXIF DateTimeOriginal", "Image DateTime")
    xres, _ = _exif_number(tags, "FocalPlaneXResolution")
    yres, _ = _exif_number(tags, "FocalPlaneYResolution")
    unit_tag = tags.get("EXIF FocalPlaneResolutionUnit") or tags.get("Image FocalPlaneResolutionUnit")
    if xres and yres and unit_tag is not None:
        values = unit_tag.values if isinstance(unit_tag.values, list) else []  # empty in a corrupt file
        per_mm = {2: 1 / 25.4, 3: 1 / 10.0, 4: 1.0}.get(values[0] if values else None)
        if per_mm:
            meta.focal_plane_resolution = (xres * per_mm, yres * per_mm)
    for name in ("camera", "lens", "time"):
        meta.sources[name] = "missing" if getattr(meta, name) is None else "libraw/exif"
    return meta
