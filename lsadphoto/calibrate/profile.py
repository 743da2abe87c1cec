"""Camera profiles: TOML files describing one camera + lens (schema ``lsadphoto.camera-profile/1``).

Schema (all sections optional except ``id``; lengths in mm, sizes in px)::

    schema = "lsadphoto.camera-profile/1"
    id = "synthetic-demo"
    camera = "…"
    lens = "…"
    [sensor]      width_mm, height_mm, width_px, height_px
    [lens_model]  model = "pinhole"        # nominal rectilinear model from focal_length_mm
                  focal_length_mm
    [lens_model]  model = "opencv-pinhole" | "opencv-fisheye" | "fisheye-ideal" | …
                  parameters of that projection (see lsadphoto.geometry), in px of the
                  full [sensor] width_px × height_px
    [vignetting]  model = "none" | "polynomial" | "flat-field"
                  coefficients = [a1, a2, a3]   # V = 1 + Σ a_k r^(2k), r over half-diagonal
                  map = "file.npy"              # flat-field gain, relative to the profile
                  centre = [row, col]           # optional, sensor px
    [colour]      camera_to_xyz = [[…], […], […]]
    [photometric] calibration_constant          # C [cd·s·m⁻²]: L = C·Y·N²/(t·S)
                  calibration_constant_uncertainty   # relative standard uncertainty
    [noise]       full_well_electrons, read_noise_electrons   # at ISO 100; absent: nominal
    [provenance]  free-form strings; "source.NAME" says where value NAME came from,
                  "nominal" lists the values that are not measured for this camera
    f_number                                    # the f-number the profile belongs to
    [vignetting]  focal_length_mm, f_number     # what the vignetting model belongs to

A calibrated ``[lens_model]`` is tied to the sensor size in pixels: images of another size
are refused (or use ``binning`` for superpixel maps).
"""

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import tomli_w

from .._validation import check_file
from ..errors import BadInputError
from ..geometry.base import Projection, projection_from_dict
from ..geometry.pinhole import PinholeProjection
from ..raw.bracket import NoiseModel
from ..io._atomic import atomic_text
from .vignetting import VignettingModel

SCHEMA = "lsadphoto.camera-profile/1"


@dataclass
class CameraProfile:
    """A camera + lens description (see the module docstring for the TOML schema)."""

    id: str
    camera: str | None = None
    lens: str | None = None
    sensor_width: float | None = None
    sensor_height: float | None = None
    width: int | None = None
    height: int | None = None
    focal_length: float | None = None
    lens_projection: Projection | None = None
    vignetting: VignettingModel = field(default_factory=VignettingModel)
    camera_to_xyz: np.ndarray | None = None
    calibration_constant: float | None = None
    calibration_constant_uncertainty: float | None = None
    noise: NoiseModel = field(default_factory=NoiseModel)
    noise_measured: bool = False
    f_number: float | None = None
    provenance: dict = field(default_factory=dict)
    path: str | None = None
    #: Where each value came from ("exif …", "lensfun …", "profile FILE", "nominal …").
    sources: dict = field(default_factory=dict)
    #: Values that are not a measurement of this camera (need calibration).
    nominal: list = field(default_factory=list)
    #: Disagreements between sources found while drafting.
    notes: list = field(default_factory=list)
    #: The RAW file a drafted profile was made from.
    drafted_from: str | None = None

    def nominal_values(self):
        """Names of the values that are nominal (noise unless measured, plus ``nominal``)."""
        return list(dict.fromkeys([*self.nominal, *([] if self.noise_measured else ["noise"])]))

    def projection(self, sensor_shape, *, binning=1, focal_length=None, focal_plane_resolution=None):
        """Nominal pinhole model for an image of ``sensor_shape`` seen through ``binning``.

        The focal length [mm] comes from the profile, else from the file's metadata; the
        sensor size from the profile, else from the file's focal-plane resolution [px/mm].
        """
        rows, cols = sensor_shape
        if self.lens_projection is not None:
            if tuple(self.lens_projection.shape) != (rows, cols):
                raise BadInputError(
                    f"camera profile {self.id!r} models a {self.lens_projection.shape[1]}×"
                    f"{self.lens_projection.shape[0]} px image, not {cols}×{rows}"
                )
            return self.lens_projection.binned(binning) if binning > 1 else self.lens_projection
        f = self.focal_length or focal_length
        if self.sensor_width and self.sensor_height:
            width_mm = self.sensor_width * cols / (self.width or cols)
            height_mm = self.sensor_height * rows / (self.height or rows)
        elif focal_plane_resolution:
            width_mm, height_mm = cols / focal_plane_resolution[0], rows / focal_plane_resolution[1]
        else:
            width_mm = height_mm = None
        missing = [n for n, v in (("focal length", f), ("sensor size", width_mm)) if not v]
        if missing:
            raise BadInputError(
                f"camera geometry needs the {' and '.join(missing)}, which the file does not record: "
                "give a camera profile with [sensor] and [lens_model] sections"
            )
        model = PinholeProjection.from_sensor(
            focal_length=f, sensor_width=width_mm, sensor_height=height_mm, width=cols, height=rows
        )
        return model.binned(binning) if binning > 1 else model

    def to_dict(self):
        out = {"schema": SCHEMA, "id": self.id}
        for key in ("camera", "lens"):
            if getattr(self, key):
                out[key] = getattr(self, key)
        sensor = {"width_mm": self.sensor_width, "height_mm": self.sensor_height,
                  "width_px": self.width, "height_px": self.height}
        sensor = {k: v for k, v in sensor.items() if v is not None}
        if sensor:
            out["sensor"] = sensor
        if self.lens_projection is not None:
            model = self.lens_projection.to_dict()
            out["lens_model"] = {k: v for k, v in model.items() if k not in ("width", "height")}
        elif self.focal_length:
            out["lens_model"] = {"model": "pinhole", "focal_length_mm": self.focal_length}
        out["vignetting"] = self.vignetting.to_dict()
        if self.camera_to_xyz is not None:
            out["colour"] = {"camera_to_xyz": np.asarray(self.camera_to_xyz).tolist()}
        if self.calibration_constant:
            out["photometric"] = {"calibration_constant": self.calibration_constant}
            if self.calibration_constant_uncertainty is not None:
                out["photometric"]["calibration_constant_uncertainty"] = self.calibration_constant_uncertainty
        if self.f_number:
            out["f_number"] = self.f_number
        if self.noise_measured:
            out["noise"] = {"full_well_electrons": self.noise.full_well,
                            "read_noise_electrons": self.noise.read_noise}
        provenance = {k: str(v) for k, v in self.provenance.items()}
        provenance.update({f"source.{k}": str(v) for k, v in self.sources.items()})
        nominal = self.nominal_values()
        if nominal:
            provenance["nominal"] = ", ".join(nominal)
        if provenance:
            out["provenance"] = provenance
        return out


def _number(section, key, name, *, required=False):
    value = section.get(key)
    if value is None:
        if required:
            raise BadInputError(f"camera profile lacks {name}")
        return None
    if not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
        raise BadInputError(f"camera profile {name} must be a positive number, got {value!r}")
    return float(value)


def load_profile(path):
    """Read a camera profile TOML file; errors name the offending entry."""
    path = check_file(path, "camera profile")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise BadInputError(f"{path}: not a valid TOML camera profile ({exc})") from None
    schema = data.get("schema", SCHEMA)
    if schema != SCHEMA:
        raise BadInputError(f"{path}: unsupported profile schema {schema!r} (expected {SCHEMA!r})")
    if "id" not in data:
        raise BadInputError(f"{path}: camera profile lacks 'id'")
    sensor = data.get("sensor", {})
    lens_model = data.get("lens_model", {})
    vig = data.get("vignetting", {})
    kind = vig.get("model", "none")
    vignetting = VignettingModel(kind=kind, coefficients=list(vig.get("coefficients", [])),
                                 centre=tuple(vig["centre"]) if "centre" in vig else None,
                                 rms_residual=vig.get("rms_residual"),
                                 focal_length=_number(vig, "focal_length_mm", "vignetting.focal_length_mm"),
                                 f_number=_number(vig, "f_number", "vignetting.f_number"))
    if kind == "flat-field":
        if "map" not in vig:
            raise BadInputError(f"{path}: flat-field vignetting needs 'map'")
        map_path = check_file(path.parent / vig["map"], "flat-field map")
        try:
            vignetting.gain_map = np.load(map_path, allow_pickle=False)
        except (ValueError, OSError) as exc:
            raise BadInputError(f"{map_path}: not a numpy .npy gain map ({exc})") from None
    elif kind not in ("none", "polynomial"):
        raise BadInputError(f"{path}: unknown vignetting model {kind!r}; valid: none, polynomial, flat-field")
    lens_projection = None
    model = lens_model.get("model", "pinhole")
    if model != "pinhole":
        if not (sensor.get("width_px") and sensor.get("height_px")):
            raise BadInputError(f"{path}: lens_model {model!r} needs sensor.width_px and sensor.height_px")
        params = {k: v for k, v in lens_model.items() if k != "model"}
        try:
            lens_projection = projection_from_dict(
                {"model": model, **params, "width": sensor["width_px"], "height": sensor["height_px"]}
            )
        except (TypeError, ValueError) as exc:
            raise BadInputError(f"{path}: bad lens_model {model!r} ({exc})") from None
    matrix = data.get("colour", {}).get("camera_to_xyz")
    if matrix is not None:
        matrix = np.asarray(matrix, dtype=float)
        if matrix.shape != (3, 3) or not np.all(np.isfinite(matrix)):
            raise BadInputError(f"{path}: colour.camera_to_xyz must be a finite 3×3 matrix")
    photometric = data.get("photometric", {})
    noise = data.get("noise", {})
    provenance = {k: v for k, v in data.get("provenance", {}).items()
                  if not k.startswith("source.") and k != "nominal"}
    sources = {k[len("source."):]: v for k, v in data.get("provenance", {}).items() if k.startswith("source.")}
    for key in ("sensor", "lens_model", "vignetting", "colour", "photometric"):
        if key in data:
            sources[key] = f"profile {path.name}" + (f" ({sources[key]})" if key in sources else "")
    if "noise" in data:
        sources["noise"] = f"profile {path.name}"
    nominal = [n.strip() for n in str(data.get("provenance", {}).get("nominal", "")).split(",") if n.strip()]
    nominal = [n for n in nominal if n != "noise" or "noise" not in data]
    return CameraProfile(
        id=str(data["id"]),
        camera=data.get("camera"),
        lens=data.get("lens"),
        sensor_width=_number(sensor, "width_mm", "sensor.width_mm"),
        sensor_height=_number(sensor, "height_mm", "sensor.height_mm"),
        width=sensor.get("width_px"),
        height=sensor.get("height_px"),
        focal_length=_number(lens_model, "focal_length_mm", "lens_model.focal_length_mm"),
        lens_projection=lens_projection,
        vignetting=vignetting,
        camera_to_xyz=matrix,
        calibration_constant=_number(photometric, "calibration_constant", "photometric.calibration_constant"),
        calibration_constant_uncertainty=photometric.get("calibration_constant_uncertainty"),
        noise=NoiseModel(
            full_well=_number(noise, "full_well_electrons", "noise.full_well_electrons") or NoiseModel.full_well,
            read_noise=_number(noise, "read_noise_electrons", "noise.read_noise_electrons") or NoiseModel.read_noise,
        ),
        noise_measured="noise" in data,
        f_number=_number(data, "f_number", "f_number"),
        provenance=provenance,
        sources=sources,
        nominal=nominal,
        path=str(path),
    )


def save_profile(profile, path):
    """Write ``profile`` as TOML (atomic)."""
    atomic_text(Path(path), tomli_w.dumps(profile.to_dict()))
