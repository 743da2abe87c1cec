"""Q's compiled filters (lsadphoto.metrics._filters) against OpenCV, the independent
reference they replace in the score path: ``sepFilter2D`` (float32) within its float32
summation error, ``erode`` exactly; and Q itself against Q computed with OpenCV's filters."""

import math

import cv2
import numpy as np
import pytest

from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.geometry.field import pixel_geometry
from lsadphoto.metrics import _filters
from lsadphoto.metrics import quality as quality_module
from lsadphoto.metrics.quality import _kernels, q_Budak2021

#: Q's blur widths [px]: none (central differences), below and above one pixel, wide.
SIGMAS = (0.0, 0.7, 1.8, 3.0)


@pytest.mark.parametrize("sigma_px", SIGMAS)
def test_separable_correlation_equals_opencv(sigma_px):
    smooth, derivative, _ = _kernels(sigma_px)
    rng = np.random.default_rng(7)
    image = (rng.random((120, 97)) * 1e4).astype(np.float32)
    image[40:60, 30:50] += 5e4  # an edge, as a window's frame
    for kx, ky in ((derivative, smooth), (smooth, derivative), (smooth, smooth)):
        ours = _filters.correlate_separable(image, kx, ky)
        reference = cv2.sepFilter2D(image, cv2.CV_32F, kx, ky)
        rx, ry = kx.size // 2, ky.size // 2
        inner = (slice(ry, image.shape[0] - ry), slice(rx, image.shape[1] - rx))
        # OpenCV sums n_x, then n_y float32 terms (each sum within γ_n = n·2⁻²⁴ of Σ|terms|)
        # and rounds the row pass; ours is within (r_y + 4)·2⁻²⁴ of the same scale of the exact
        # value (test_separable_correlation_is_within_float32_bound_of_float64). Before session
        # 14 ours was exact to one rounding and the bound below, (n_x + n_y + 2)·2⁻²⁴·(|k_y| ⊗
        # |k_x|) ∗ |x| computed in float64, was proven; with the float32 column pass the two
        # worst cases add up to more, and it is kept as it was: rounding errors of these data
        # stay far below their worst case.
        scale = cv2.sepFilter2D(np.abs(image).astype(np.float64), cv2.CV_64F,
                                np.abs(kx.astype(np.float64)), np.abs(ky.astype(np.float64)))
        bound = (kx.size + ky.size + 2) * 2.0 ** -24 * scale[inner]
        assert np.all(np.abs(ours[inner].astype(np.float64) - reference[inner]) <= bound)
        # The border where the stencil leaves the image is NaN (Q never reads it), nothing else.
        border = np.ones(image.shape, dtype=bool)
        border[inner] = False
        assert np.array_equal(np.isnan(ours), border)


@pytest.mark.parametrize("sigma_px", SIGMAS)
def test_separable_correlation_is_within_float32_bound_of_float64(sigma_px):
    # The independent reference: the same correlation of the same float32 data and taps in
    # float64 (OpenCV's CV_64F: exact to ~1e-16, negligible here). Ours rounds each row pass
    # (summed in float64) once to float32 (≤ 2⁻²⁴ of |row|) and sums the column pass in
    # float32, paired taps: the centre term takes r_y + 1 roundings (its product and the r_y
    # additions), a pair r_y + 2 (its sum, its product, up to r_y additions); to first order
    # |ours − exact| ≤ (r_y + 4)·2⁻²⁴·(|k_y| ⊗ |k_x|) ∗ |x|. The factor 1 + 1e-6 covers the
    # second-order terms ((r_y + 4)²·2⁻⁴⁸ ≈ 1e-11 relative).
    smooth, derivative, _ = _kernels(sigma_px)
    rng = np.random.default_rng(11)
    image = (rng.random((120, 97)) * 1e4).astype(np.float32)
    image[40:60, 30:50] += 5e4
    for kx, ky in ((derivative, smooth), (smooth, derivative), (smooth, smooth)):
        ours = _filters.correlate_separable(image, kx, ky)
        kx64, ky64 = kx.astype(np.float64), ky.astype(np.float64)
        exact = cv2.sepFilter2D(image.astype(np.float64), cv2.CV_64F, kx64, ky64)
        scale = cv2.sepFilter2D(np.abs(image).astype(np.float64), cv2.CV_64F, np.abs(kx64),
                                np.abs(ky64))
        rx, ry = kx.size // 2, ky.size // 2
        inner = (slice(ry, image.shape[0] - ry), slice(rx, image.shape[1] - rx))
        bound = (ry + 4) * 2.0 ** -24 * scale[inner] * (1.0 + 1e-6)
        error = np.abs(ours[inner].astype(np.float64) - exact[inner])
        assert np.all(error <= bound)
        if ry > 0:  # the float32 column pass is not exact: the test sees its rounding
            assert error.max() > 0


def test_separable_correlation_is_exact_on_a_ramp():
    # The derivative kernel is normalised so that a linear ramp gets its slope (quality._kernels):
    # on x = 3·col (exact in float32) the row derivative is 3 to float32 rounding.
    smooth, derivative, _ = _kernels(1.8)
    image = np.tile(3.0 * np.arange(64, dtype=np.float32), (40, 1))
    lu = _filters.correlate_separable(image, derivative, smooth)
    inner = lu[~np.isnan(lu)]
    assert inner.size > 0 and np.allclose(inner, 3.0, rtol=1e-6, atol=0)


@pytest.mark.parametrize("radius", [1, 3, 7])
def test_erosion_equals_opencv(radius):
    rng = np.random.default_rng(radius)
    mask = rng.random((90, 111)) > 0.01
    mask[:, :5] = True  # true up to the image's edge: the border counts as false
    mask[30:33, 40:90] = False
    ours = _filters.erode_square(mask, radius)
    size = 2 * radius + 1
    reference = cv2.erode(mask.view(np.uint8), np.ones((size, size), np.uint8),
                          borderType=cv2.BORDER_CONSTANT, borderValue=0).view(bool)
    assert ours.any() and np.array_equal(ours, reference)


def _opencv_correlate(image, kx, ky):
    return cv2.sepFilter2D(np.ascontiguousarray(image, dtype=np.float32), cv2.CV_32F, kx, ky)


@pytest.mark.parametrize("size_arcmin", [40.0, 10.0])
def test_q_equals_q_with_opencvs_filters(monkeypatch, size_arcmin):
    # A 180° fisheye with a bright window-like patch: at 400 px a 40' detail is blurred by
    # σ ≈ 0.66 px, a 10' one not at all (central differences, exact in float32 either way).
    cam = IdealFisheyeProjection("equidistant", 199.5, 199.5, 200.0, 180.0, 400, 400)
    geometry = pixel_geometry(cam)
    d = geometry.directions
    with np.errstate(invalid="ignore"):
        luminance = 200.0 + 3000.0 * (np.abs(d[..., 0] - 0.3) < 0.2) * (np.abs(d[..., 1]) < 0.3) \
            + 50.0 * d[..., 1]
    options = dict(size_arcmin=size_arcmin, valid=geometry.valid)
    ours = q_Budak2021(luminance, d, geometry.solid_angle, None, **options)
    monkeypatch.setattr(quality_module, "correlate_separable", _opencv_correlate)
    reference = q_Budak2021(luminance, d, geometry.solid_angle, None, **options)
    assert math.isfinite(ours.q) and ours.q > 0
    # Q = Σ K·ω/(Σω·K_th) over about 10⁵ candidates; each gradient differs by at most the
    # filters' float32 summation error (≤ 34·2⁻²⁴ ≈ 2·10⁻⁶ of the local luminance scale, the
    # test above), which a sum of positive terms keeps as a relative bound on Q, unless a
    # pixel crosses the cut-off (its key within 2·10⁻⁶ of N·ΔL: none in this scene, whose
    # gradients are far from it).
    assert ours.q == pytest.approx(reference.q, rel=2e-6, abs=0)
    assert ours.kept_fraction == reference.kept_fraction
    if ours.settings["blur_sigma_px"] == 0:  # central differences: every sum is exact
        assert ours.q == reference.q


def test_separable_correlation_takes_symmetric_or_antisymmetric_kernels():
    with pytest.raises(ValueError, match="symmetric or antisymmetric"):
        _filters.correlate_separable(np.ones((9, 9), np.float32), np.array([1.0, 2.0, 0.0]),
                                     np.ones(1))
