"""``VIEW=`` lines of maps made through OpenCV camera models (issue 17, defect 8).

Radiance's views have no distortion terms, so an OpenCV model has a view only when its
distortion is zero: Brown–Conrady is then ``-vtv`` and Kannala–Brandt ``-vta``. The
references are Radiance's own ``vwrays`` (the ray of every pixel of a picture's VIEW= line)
and ``evalglare`` (vertical illuminance of a uniform hemisphere, E_v = π·L).
"""

import math
import os
import subprocess

import numpy as np
import pytest

from lsadphoto.geometry.opencv import OpenCVFisheyeProjection, OpenCVPinholeProjection
from lsadphoto.io import read_hdr, write_hdr
from lsadphoto.luminance_map import LuminanceMap

from .test_io_hdr import radiance  # noqa: F401  (the fixture running Radiance's programs)


def _rays(radiance, path, rows, cols):  # noqa: F811
    out = radiance("vwrays", "-fd", path)
    return np.frombuffer(out, np.float64).reshape(rows, cols, 6)


@pytest.mark.parametrize("projection", [
    OpenCVPinholeProjection(11.0, 9.0, 4.3, 5.6, (0.0, 0.0, 0.0, 0.0, 0.0), 13, 9),
    OpenCVFisheyeProjection(4.0, 4.0, 6.2, 3.9, (0.0, 0.0, 0.0, 0.0), 13, 9),
], ids=["opencv-pinhole", "opencv-fisheye"])
def test_undistorted_opencv_maps_get_a_view_vwrays_traces(tmp_path, radiance, projection):  # noqa: F811
    rows, cols = projection.height, projection.width
    path = tmp_path / "view.hdr"
    write_hdr(LuminanceMap(np.ones((rows, cols)), projection=projection), path)
    assert b"VIEW= -vt" in path.read_bytes()
    rays = _rays(radiance, path, rows, cols)
    d = projection.directions(*np.mgrid[0:rows, 0:cols])
    # Radiance world = (x_cam, z_cam, −y_cam) for -vd 0 1 0 -vu 0 0 1; scanlines from the top.
    expected = np.stack([d[..., 0], d[..., 2], -d[..., 1]], axis=-1)
    # The fisheye's corners lie beyond θ = 180° (Radiance returns a zero ray there, our
    # model NaN); everywhere else the rays agree to the 17 written digits (a half-pixel
    # convention error would be ≈ 0.5/fx ≥ 0.05).
    traced = np.any(rays[..., 3:] != 0.0, axis=-1)
    np.testing.assert_array_equal(traced, np.all(np.isfinite(d), axis=-1))
    np.testing.assert_allclose(rays[traced][:, 3:], expected[traced], rtol=0, atol=1e-6)


def test_distorted_opencv_map_has_no_view_but_keeps_its_model(tmp_path):
    projection = OpenCVFisheyeProjection(4.0, 4.0, 6.2, 3.9, (0.05, 0.0, 0.0, 0.0), 13, 9)
    path = tmp_path / "distorted.hdr"
    write_hdr(LuminanceMap(np.ones((9, 13)), projection=projection), path)
    assert b"VIEW=" not in path.read_bytes()
    assert read_hdr(path).projection == projection  # from our LSADPHOTO= metadata


def test_evalglare_reads_an_opencv_fisheye_map(tmp_path):
    """A uniform hemisphere of L = 100 cd/m² through an undistorted Kannala–Brandt model:
    evalglare computes E_v from our VIEW= line alone, E_v = π·L (analytic)."""
    pyradiance = pytest.importorskip("pyradiance", reason="pyradiance (evalglare) not installed")
    evalglare = os.path.join(os.path.dirname(pyradiance.__file__), "bin", "evalglare")
    n = 300
    projection = OpenCVFisheyeProjection(n / math.pi, n / math.pi, (n - 1) / 2, (n - 1) / 2,
                                         (0.0, 0.0, 0.0, 0.0), n, n)
    d = projection.directions(*projection.pixel_grid())
    luminance = np.where(d[..., 2] > 0, 100.0, np.nan).astype(np.float32)
    path = tmp_path / "uniform.hdr"
    write_hdr(LuminanceMap(luminance, projection=projection, calibrated=True), path)
    done = subprocess.run([evalglare, "-d", str(path)], capture_output=True, text=True, check=True,
                          timeout=120)
    summary = next(line for line in done.stdout.splitlines() if line.startswith("dgp,av_lum"))
    e_v = float(summary.split(":", 1)[1].split()[2])
    # The rim pixels of the 180° circle count whole or not at all (evalglare's rule): measured
    # +0.34 % at 300² (+0.34 % at 400²); 1 % is three times that.
    assert e_v == pytest.approx(math.pi * 100.0, rel=0.01)
