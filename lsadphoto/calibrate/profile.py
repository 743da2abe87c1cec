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

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import tomli_w

from .._atomic import atomic_text
from .._schema import Key, Table, Variants, read_toml
from .._validation import check_file
from ..errors import BadInputError
from ..geometry.base import Projection, projection_from_dict
from ..geometry.fisheye import KINDS as FISHEYE_KINDS
from ..geometry.lensfun import DISTORTION_MODELS, LENS_KINDS
from ..geometry.pinhole import PinholeProjection
from ..raw.bracket import NoiseModel
from .vignetting import MAX_VIGNETTING_TERMS, VignettingModel

SCHEMA = "lsadphoto.camera-profile/1"

_POSITIVE = {"minimum": 0, "exclusive": True}


def _centre():
    return {"cx": Key(float, required=True, doc="principal point, column [px]"),
            "cy": Key(float, required=True, doc="principal point, row [px]")}


def _focal_px():
    return {"fx": Key(float, required=True, **_POSITIVE, doc="focal length [px], x"),
            "fy": Key(float, required=True, **_POSITIVE, doc="focal length [px], y")}


def _vignetting_setting():
    return {"uncertainty": Key(float, minimum=0, doc="largest relative standard uncertainty of V"),
            "focal_length_mm": Key(float, **_POSITIVE, doc="focal length the model belongs to [mm]"),
            "f_number": Key(float, **_POSITIVE, doc="aperture the model belongs to")}


#: The declared schema of a camera profile (lsadphoto._schema): unknown sections and keys are
#: refused, every value is type- and range-checked, each problem is one line.
PROFILE_SCHEMA = Table({
    "schema": Key(str, default=SCHEMA, choices=(SCHEMA,), doc="format identifier"),
    "id": Key(str, required=True, doc="profile id, recorded in every result"),
    "f_number": Key(float, **_POSITIVE, doc="the aperture the profile belongs to (checked against each frame)"),
    "camera": Key(str, doc="camera body"),
    "lens": Key(str, doc="lens"),
    "sensor": Table({
        "width_mm": Key(float, **_POSITIVE, doc="sensor width [mm]"),
        "height_mm": Key(float, **_POSITIVE, doc="sensor height [mm]"),
        "width_px": Key(int, minimum=1, doc="image width [px]"),
        "height_px": Key(int, minimum=1, doc="image height [px]"),
    }),
    "lens_model": Variants("model", {
        "pinhole": Table({"focal_length_mm": Key(float, **_POSITIVE, doc="nominal focal length [mm]"),
                          # a calibrated pinhole (fx, fy, cx, cy), as PinholeProjection.to_dict writes it
                          **{k: Key(float, **(_POSITIVE if k[0] == "f" else {}), doc=v.doc)
                             for k, v in {**_focal_px(), **_centre()}.items()}}),
        "opencv-pinhole": Table({**_focal_px(), **_centre(),
                                 "distortion": Key(list, required=True, items=float, length=(4, 5, 8),
                                                   doc="k1, k2, p1, p2[, k3[, k4, k5, k6]]")}),
        "opencv-fisheye": Table({**_focal_px(), **_centre(),
                                 "distortion": Key(list, required=True, items=float, length=4,
                                                   doc="k1, k2, k3, k4")}),
        "fisheye-ideal": Table({"kind": Key(str, required=True, choices=FISHEYE_KINDS),
                                **_centre(),
                                "radius": Key(float, required=True, **_POSITIVE, doc="image radius [px] at fov_deg"),
                                "fov_deg": Key(float, required=True, **_POSITIVE, doc="full field of view [deg]")}),
        "lensfun": Table({"kind": Key(str, required=True, choices=LENS_KINDS, doc="ideal projection"),
                          "distortion": Key(str, required=True, choices=tuple(DISTORTION_MODELS)),
                          "terms": Key(list, required=True, items=float, length=(0, 1, 2, 3),
                                       doc="k1 (poly3); k1, k2 (poly5); a, b, c (ptlens)"),
                          "focal": Key(float, required=True, **_POSITIVE, doc="focal length [normalised units]"),
                          "scale": Key(float, required=True, **_POSITIVE, doc="pixels per normalised unit"),
                          **_centre()}),
    }, default="pinhole"),
    "vignetting": Variants("model", {
        "none": Table({}),
        "polynomial": Table({
            "coefficients": Key(list, items=float, length=range(MAX_VIGNETTING_TERMS + 1), default=[],
                                doc="a1, a2, … of V = 1 + Σ a_k r^2k, r over the half-diagonal"),
            "centre": Key(list, items=float, length=2, doc="optical centre (row, col) [sensor px]"),
            "rms_residual": Key(float, minimum=0, doc="RMS relative residual of the fit"),
            **_vignetting_setting(),
        }),
        "flat-field": Table({
            "map": Key(str, required=True, doc="flat-field gain map (.npy), relative to the profile"),
            "centre": Key(list, items=float, length=2, doc="optical centre (row, col) [sensor px]"),
            "rms_residual": Key(float, minimum=0, doc="RMS relative residual"),
            **_vignetting_setting(),
        }),
    }, default="none"),
    "colour": Table({
        "camera_to_xyz": Key(list, length=3, items=Key(list, items=float, length=3),
                             doc="3×3 matrix, camera RGB → CIE XYZ"),
    }),
    "photometric": Table({
        "calibration_constant": Key(float, **_POSITIVE, doc="C [cd·s·m⁻²]: L = C·Y·N²/(t·S)"),
        "calibration_constant_uncertainty": Key(float, minimum=0, doc="relative standard uncertainty"),
    }),
    "noise": Table({
        "full_well_electrons": Key(float, **_POSITIVE, doc="full-well capacity at ISO 100 [e⁻]"),
        "read_noise_electrons": Key(float, **_POSITIVE, doc="read noise at ISO 100 [e⁻]"),
    }),
    "provenance": Table(open=True, doc="free-form strings"),
})


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


def load_profile(path):
    """Read a camera profile TOML file, checked against :data:`PROFILE_SCHEMA`.

    Raises
    ------
    BadInputError
        One line naming the file and the offending section and key.
    """
    data = read_toml(path, PROFILE_SCHEMA, what="camera profile")
    path = Path(path)
    sensor = data.get("sensor", {})
    lens_model = data.get("lens_model", {"model": "pinhole"})
    vig = data.get("vignetting", {"model": "none"})
    kind = vig["model"]
    vignetting = VignettingModel(kind=kind, coefficients=list(vig.get("coefficients", [])),
                                 centre=tuple(vig["centre"]) if "centre" in vig else None,
                                 rms_residual=vig.get("rms_residual"),
                                 uncertainty=vig.get("uncertainty"),
                                 focal_length=vig.get("focal_length_mm"), f_number=vig.get("f_number"))
    if kind == "flat-field":
        map_path = check_file(path.parent / vig["map"], "flat-field map")
        try:
            vignetting.gain_map = np.load(map_path, allow_pickle=False)
        except (ValueError, OSError) as exc:
            raise BadInputError(f"{map_path}: not a numpy .npy gain map ({exc})") from None
    lens_projection = None
    model = lens_model["model"]
    if model != "pinhole" or "fx" in lens_model:
        if not ("width_px" in sensor and "height_px" in sensor):
            raise BadInputError(f"{path}: lens_model {model!r} needs sensor.width_px and sensor.height_px")
        try:
            lens_projection = projection_from_dict(
                {**lens_model, "width": sensor["width_px"], "height": sensor["height_px"]})
        except BadInputError as exc:
            raise BadInputError(f"{path}: bad lens_model {model!r} ({exc})") from None
    matrix = data.get("colour", {}).get("camera_to_xyz")
    photometric = data.get("photometric", {})
    noise = data.get("noise", {})
    provenance = {k: v for k, v in data.get("provenance", {}).items()
                  if not k.startswith("source.") and k != "nominal"}
    sources = {k[len("source."):]: v for k, v in data.get("provenance", {}).items() if k.startswith("source.")}
    for key in ("sensor", "lens_model", "vignetting", "colour", "photometric", "noise"):
        if key in data:
            sources[key] = f"profile {path.name}" + (f" ({sources[key]})" if key in sources else "")
    nominal = [n.strip() for n in str(data.get("provenance", {}).get("nominal", "")).split(",") if n.strip()]
    nominal = [n for n in nominal if n != "noise" or "noise" not in data]
    return CameraProfile(
        id=data["id"],
        camera=data.get("camera"),
        lens=data.get("lens"),
        sensor_width=sensor.get("width_mm"),
        sensor_height=sensor.get("height_mm"),
        width=sensor.get("width_px"),
        height=sensor.get("height_px"),
        focal_length=lens_model.get("focal_length_mm"),
        lens_projection=lens_projection,
        vignetting=vignetting,
        camera_to_xyz=None if matrix is None else np.asarray(matrix, dtype=float),
        calibration_constant=photometric.get("calibration_constant"),
        calibration_constant_uncertainty=photometric.get("calibration_constant_uncertainty"),
        noise=NoiseModel(full_well=noise.get("full_well_electrons", NoiseModel.full_well),
                         read_noise=noise.get("read_noise_electrons", NoiseModel.read_noise)),
        noise_measured="noise" in data,
        f_number=data.get("f_number"),
        provenance={k: str(v) for k, v in provenance.items()},
        sources=sources,
        nominal=nominal,
        path=str(path),
    )


def save_profile(profile, path):
    """Write ``profile`` as TOML (atomic)."""
    atomic_text(Path(path), tomli_w.dumps(profile.to_dict()))
