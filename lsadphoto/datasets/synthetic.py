"""A synthetic camera: known luminance map in, real DNG file out (written with pidng).

Forward model (the inverse of the luminance stage): relative luminance Y = L / C with the
camera's calibration constant C [cd·s·m⁻²]; camera RGB = ColorMatrix · XYZ (XYZ of the
scene's chromaticity, D65 white by default); normalised value v = RGB · e · V(r) with
e = t·S/N² and the vignetting gain V; electrons v·g (g = full_well·100/S) with Poisson shot
noise and Gaussian read noise; ADU = black + v·(white − black), rounded and clipped to the
white level. DNG tags carry the CFA pattern, black and white levels, ColorMatrix1 (D65),
AsShotNeutral, exposure time, f-number, ISO (in IFD0, which LibRaw does not read: see
PITFALLS.md), focal length and focal-plane resolution.
"""

import os
from fractions import Fraction
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import BadInputError

#: ColorMatrix1 (XYZ → camera, D65) of a Canon EOS 550D as its real DNG carries it
#: (shared/realdata/raw/tinydng_colorchart.dng, tag 0xC621).
CANON_550D_COLOR_MATRIX = (
    (0.6461, -0.1164, -0.0857),
    (-0.3825, 1.1597, 0.2534),
    (-0.0416, 0.1540, 0.6523),
)

#: CIE 1931 chromaticity of D65 (CIE 015:2018 Table T.3).
D65_XY = (0.31272, 0.32903)


@dataclass
class SyntheticCamera:
    """Description of a synthetic camera (sensor sizes in px and mm, levels in ADU)."""

    width: int = 768
    height: int = 512
    sensor_width: float = 23.1
    sensor_height: float = 15.4
    focal_length: float = 18.0
    cfa: str = "RGGB"
    color_matrix: tuple = CANON_550D_COLOR_MATRIX
    black_level: tuple = (512, 512, 512, 512)  # per CFA position of the 2 × 2 cell
    white_level: int = 16383
    bit_depth: int = 14
    full_well: float = 30000.0
    read_noise: float = 3.0
    vignetting: tuple = ()  # a1, a2, … of V = 1 + Σ a_k r^(2k)
    vignetting_map: np.ndarray | None = None  # V per sensor pixel (e.g. lensfun's), replaces the polynomial
    calibration_constant: float = 12.0  # C [cd·s·m⁻²]
    make: str = "lsadphoto"
    model: str = "synthetic camera"
    extra: dict = field(default_factory=dict)

    def vignetting_gain(self):
        """V per sensor pixel (radius over the half-diagonal, centre at the sensor centre), or
        ``vignetting_map`` where given."""
        if self.vignetting_map is not None:
            return np.asarray(self.vignetting_map, dtype=np.float64)
        r = np.arange(self.height) - (self.height - 1) / 2.0
        c = np.arange(self.width) - (self.width - 1) / 2.0
        r2 = (r[:, None] ** 2 + c[None, :] ** 2) / (0.25 * (self.height**2 + self.width**2))
        gain = np.ones((self.height, self.width))
        for k, a in enumerate(self.vignetting, start=1):
            gain += a * r2**k
        return gain

    def cfa_indices(self):
        """Channel index (0 R, 1 G, 2 B) of every sensor pixel."""
        letters = {"R": 0, "G": 1, "B": 2}
        cell = np.array([[letters[self.cfa[0]], letters[self.cfa[1]]], [letters[self.cfa[2]], letters[self.cfa[3]]]])
        return np.tile(cell, (self.height // 2 + 1, self.width // 2 + 1))[: self.height, : self.width]

    def expose(self, luminance, *, exposure_time, f_number, iso, chromaticity=D65_XY, rng=None, noise=True):
        """Raw ADU values (uint16, sensor shape) for a luminance map [cd·m⁻²].

        ``chromaticity`` is one (x, y) pair or an array ``(rows, cols, 2)``.
        """
        luminance = np.asarray(luminance, dtype=np.float64)
        if luminance.shape != (self.height, self.width):
            raise BadInputError(f"luminance is {luminance.shape}, camera is {(self.height, self.width)}")
        xy = np.broadcast_to(np.asarray(chromaticity, dtype=np.float64), luminance.shape + (2,))
        y_rel = luminance / self.calibration_constant
        xyz = np.stack([xy[..., 0] / xy[..., 1], np.ones(luminance.shape), (1 - xy[..., 0] - xy[..., 1]) / xy[..., 1]], -1)
        cam = (xyz * y_rel[..., None]) @ np.asarray(self.color_matrix).T
        e = exposure_time * iso / f_number**2
        idx = self.cfa_indices()
        v = np.take_along_axis(cam, idx[..., None], axis=-1)[..., 0] * e * self.vignetting_gain()
        v = np.clip(v, 0.0, None)
        if noise:
            rng = rng if rng is not None else np.random.default_rng(0)
            g = self.full_well * 100.0 / iso
            electrons = rng.poisson(np.minimum(v * g, 1e12)).astype(np.float64)
            electrons += rng.normal(0.0, self.read_noise, size=v.shape)
            v = electrons / g
        black = self.black_map()
        adu = black + v * (self.white_level - black)
        return np.clip(np.rint(adu), 0, self.white_level).astype(np.uint16)

    def black_map(self):
        cell = np.array(self.black_level, dtype=np.float64).reshape(2, 2)
        return np.tile(cell, (self.height // 2 + 1, self.width // 2 + 1))[: self.height, : self.width]


def _rational(value, max_denominator=10000):
    """TIFF (S)RATIONAL of ``value``: the nearest fraction (1/16000 s stays exact)."""
    fraction = Fraction(float(value)).limit_denominator(max_denominator)
    return [fraction.numerator, fraction.denominator]


def write_dng(path, raw, camera, *, exposure_time, f_number, iso, extra_tags=(), focal_plane=True,
              focal_length_35mm=None, lens=None):
    """Write raw ADU values as a real DNG (atomic). ``None`` exposure values are left out.

    ``focal_plane=False`` leaves out the FocalPlane resolution tags (as many cameras do);
    ``focal_length_35mm`` [mm] writes FocalLengthIn35mmFilm (rounded to 1 mm, as EXIF
    stores it); ``lens`` writes the EXIF lens model.
    """
    from pidng.core import RAW2DNG, DNGTags, Tag
    from pidng.defs import CalibrationIlluminant, DNGVersion, Orientation, PhotometricInterpretation

    raw = np.ascontiguousarray(raw, dtype=np.uint16)
    height, width = raw.shape
    letters = {"R": 0, "G": 1, "B": 2}
    tags = DNGTags()
    tags.set(Tag.ImageWidth, width)
    tags.set(Tag.ImageLength, height)
    tags.set(Tag.TileWidth, width)
    tags.set(Tag.TileLength, height)
    tags.set(Tag.Orientation, Orientation.Horizontal)
    tags.set(Tag.PhotometricInterpretation, PhotometricInterpretation.Color_Filter_Array)
    tags.set(Tag.SamplesPerPixel, 1)
    tags.set(Tag.BitsPerSample, 16)
    tags.set(Tag.CFARepeatPatternDim, [2, 2])
    tags.set(Tag.CFAPattern, [letters[c] for c in camera.cfa])
    tags.set(Tag.BlackLevelRepeatDim, [2, 2])
    tags.set(Tag.BlackLevel, [int(b) for b in camera.black_level])
    tags.set(Tag.WhiteLevel, int(camera.white_level))
    tags.set(Tag.ColorMatrix1, [_rational(v) for v in np.asarray(camera.color_matrix).ravel()])
    tags.set(Tag.CalibrationIlluminant1, CalibrationIlluminant.D65)
    # Camera response to D65 white, normalised to its largest channel.
    white_xyz = np.array([D65_XY[0] / D65_XY[1], 1.0, (1 - sum(D65_XY)) / D65_XY[1]])
    neutral = np.asarray(camera.color_matrix) @ white_xyz
    neutral = neutral / neutral.max()
    tags.set(Tag.AsShotNeutral, [_rational(v) for v in neutral])
    if exposure_time is not None:
        tags.set(Tag.ExposureTime, [_rational(exposure_time, 10**7)])
    if f_number is not None:
        tags.set(Tag.FNumber, [_rational(f_number, 100)])
    if iso is not None:
        tags.set(Tag.PhotographicSensitivity, [int(iso)])
    tags.set(Tag.FocalLength, [_rational(camera.focal_length, 100)])
    if focal_plane:
        tags.set(Tag.FocalPlaneXResolution, [_rational(camera.width / (camera.sensor_width / 10.0), 1000)])
        tags.set(Tag.FocalPlaneYResolution, [_rational(camera.height / (camera.sensor_height / 10.0), 1000)])
        tags.set(Tag.FocalPlaneResolutionUnit, 3)  # centimetres
    if focal_length_35mm is not None:
        tags.set(Tag.FocalLengthIn35mmFilm, [int(round(focal_length_35mm))])
    if lens is not None:
        tags.set(Tag.EXIFPhotoLensModel, lens)
    tags.set(Tag.Make, camera.make)
    tags.set(Tag.Model, camera.model)
    tags.set(Tag.UniqueCameraModel, f"{camera.make} {camera.model}")
    tags.set(Tag.DNGVersion, DNGVersion.V1_4)
    tags.set(Tag.DNGBackwardVersion, DNGVersion.V1_2)
    for tag, value in extra_tags:
        tags.set(tag, value)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{path.stem}.", dir=path.parent)
    os.close(fd)
    os.unlink(name)
    writer = RAW2DNG()
    writer.options(tags, path="", compress=False)
    try:
        writer.convert(raw, filename=name)
        os.replace(name + ".dng", path)
    finally:
        if os.path.exists(name + ".dng"):
            os.unlink(name + ".dng")
    return path


def rotation_sequence(projection, angles_deg, *, target_radius_deg, target_luminance, background=0.0):
    """Luminance images [cd·m⁻²] of a rotation-method vignetting measurement.

    A uniform disk target of angular radius ``target_radius_deg`` and luminance
    ``target_luminance`` stays fixed while the camera turns about its entrance pupil (the
    vertical image axis) by each of ``angles_deg``: in the camera frame the target lies at
    (sin α, 0, cos α). Pixels outside the projection's valid region are black (0), the rest
    ``background``.

    Parameters
    ----------
    projection : Projection
        The camera's geometry at sensor resolution.
    angles_deg : sequence of float
        Rotation angles α [deg].
    target_radius_deg, target_luminance, background : float

    Returns
    -------
    list of ndarray, (rows, cols)
    """
    rows, cols = projection.pixel_grid()
    directions = projection.directions(rows.astype(float), cols.astype(float))
    valid = np.all(np.isfinite(directions), axis=-1)
    cos_radius = np.cos(np.radians(target_radius_deg))
    images = []
    for alpha in np.radians(np.asarray(angles_deg, dtype=float)):
        axis = np.array([np.sin(alpha), 0.0, np.cos(alpha)])
        inside = np.nan_to_num(directions @ axis, nan=-1.0) >= cos_radius
        image = np.where(valid, background, 0.0)
        images.append(np.where(inside & valid, target_luminance, image))
    return images
