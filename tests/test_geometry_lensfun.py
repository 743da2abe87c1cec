"""lensfun lens models: our numpy projection against lensfun's own Modifier (lensfunpy)."""

import numpy as np
import pytest

lensfunpy = pytest.importorskip("lensfunpy")

from lsadphoto.calibrate.draft import _database, lensfun_projection  # noqa: E402
from lsadphoto.geometry import pixel_geometry  # noqa: E402
from lsadphoto.geometry.lensfun import LensfunProjection  # noqa: E402

WIDTH, HEIGHT = 600, 400
#: Measured agreement on a 600 × 400 image (half-diagonal 360 px): poly3 0.003 px, poly5 and
#: ptlens ≤ 0.062 px, fisheyes (lensfun's geometry conversion through an equirectangular
#: intermediate) ≤ 0.37 px, growing towards the corners: ≤ 1.7e-4 (rectilinear) and 1e-3
#: (fisheye) of the radius. lensfun computes in float32 with single-precision trigonometry;
#: the residual's source beyond that was not pinned down, so the bounds are the measured
#: values with a margin of about a third.
RECTILINEAR_PX = 0.08
FISHEYE_PX = 0.5

LENSES = [  # (maker, model) of lensfun entries covering every distortion model and fisheyes
    ("Beroflex", "Beroflex 1:8 500mm"),                       # poly3, 3:2
    ("Canon", "Canon PowerShot G12 & compatibles (Standard)"),  # poly5, 4:3 sensor
    ("Apple", "iPhone XS back camera 4.25mm f/1.8 & compatibles"),  # ptlens, 4:3
    ("Zenitar", "Zenitar MC 16mm f/2.8"),                      # equidistant fisheye, poly3
    ("GoPro", "HERO4"),                                        # equisolid fisheye, ptlens
    ("AEE", "AEE SD19 & compatibles"),                         # equisolid, measured real focal length
]


def _lens(maker, model):
    found = [lens for lens in _database().lenses if lens.model == model]
    if not found:
        pytest.skip(f"lensfun database lacks {maker} {model}")
    return found[0]


@pytest.mark.parametrize("maker,model", LENSES, ids=[m for _, m in LENSES])
def test_projection_matches_lensfun_modifier(maker, model):
    """For each pixel of lensfun's corrected (rectilinear) image, lensfun's Modifier gives the
    pixel of the recorded image it comes from; our projection of that pixel's direction must
    land on the same point."""
    lens = _lens(maker, model)
    focal = lens.calib_distortion[0].focal
    cam, _, geometry = lensfun_projection(lens, width=WIDTH, height=HEIGHT, crop_factor=lens.crop_factor,
                                          focal_length=focal)
    modifier = lensfunpy.Modifier(lens, lens.crop_factor, WIDTH, HEIGHT)
    flags = lensfunpy.ModifyFlags.DISTORTION
    if lens.type != lensfunpy.LensType.RECTILINEAR:
        flags |= lensfunpy.ModifyFlags.GEOMETRY
    modifier.initialize(focal, lens.min_aperture or 4.0, 1000.0, scale=1.0,
                        targeom=lensfunpy.LensType.RECTILINEAR, flags=flags)
    reference = modifier.apply_geometry_distortion()[::10, ::10]
    v, u = np.mgrid[0:HEIGHT:10, 0:WIDTH:10].astype(float)
    # The corrected image is lensfun's rectilinear view of the same normalised coordinates.
    directions = np.stack([(u - cam.cx) / cam.scale, (v - cam.cy) / cam.scale, np.full(u.shape, cam.focal)], -1)
    rows, cols = cam.project(directions)
    error = np.hypot(cols - reference[..., 0], rows - reference[..., 1])
    limit = RECTILINEAR_PX if cam.kind == "rectilinear" else FISHEYE_PX
    assert np.all(np.isfinite(error)) and error.max() < limit


@pytest.mark.parametrize("distortion,terms", [("poly3", [-0.03]), ("poly5", [-0.05, 0.01]),
                                              ("ptlens", [0.01, -0.03, 0.02]), ("none", [])])
@pytest.mark.parametrize("kind", ["rectilinear", "equidistant", "equisolid", "stereographic", "orthographic", "thoby"])
def test_round_trip_and_solid_angles(kind, distortion, terms):
    """directions() inverts project() to 1e-9 px, and a pixel's solid angle equals the sum of
    its 4 × 4 sub-pixels' on the same lens at 4× the resolution."""
    cam = LensfunProjection(kind, distortion, terms, 1.5, 150.0, 159.5, 119.5, 320, 240)
    rows, cols = np.mgrid[0:240:7, 0:320:7].astype(float)
    back = cam.project(cam.directions(rows, cols))
    ok = np.isfinite(back[0])
    assert ok.mean() > 0.9
    assert np.nanmax(np.abs(back[0] - rows)) < 1e-9 and np.nanmax(np.abs(back[1] - cols)) < 1e-9
    # The geodesic quadrilaterals of the sub-pixels tile the pixel's footprint up to the
    # curvature of the mapped pixel edges: measured ≤ 4e-6 relative here.
    r, c = 60.0, 200.0
    omega = cam.solid_angles(np.array([r]), np.array([c]))[0]
    sub = np.linspace(-0.375, 0.375, 4)
    fine = LensfunProjection(kind, distortion, terms, 1.5, 600.0, 4 * 159.5 + 1.5, 4 * 119.5 + 1.5, 1280, 960)
    fr, fc = np.meshgrid(4 * (r + sub) + 1.5, 4 * (c + sub) + 1.5, indexing="ij")
    assert fine.solid_angles(fr, fc).sum() == pytest.approx(omega, rel=1e-5)


def test_binned_and_toml_round_trip():
    from lsadphoto.geometry import projection_from_dict

    cam = LensfunProjection("equisolid", "ptlens", [0.01, -0.03, 0.02], 0.9, 150.0, 159.5, 119.5, 320, 240)
    assert projection_from_dict(cam.to_dict()) == cam
    half = cam.binned(2)
    d = cam.directions(np.array([0.5]), np.array([0.5]))  # centre of the first 2 × 2 cell
    np.testing.assert_allclose(half.directions(np.array([0.0]), np.array([0.0])), d, atol=1e-12)
    assert pixel_geometry(half).solid_angle.shape == (120, 160)
