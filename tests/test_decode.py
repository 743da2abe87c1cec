"""Decoding: LibRaw scaling, saturation masks, black-level maps, extremes and real files."""

import warnings

import numpy as np
import pytest
import rawpy

from lsadphoto.errors import MetadataWarning, UnsupportedFileError
from lsadphoto.raw import decode_raw, read_exposure_metadata
from lsadphoto.raw.decode import read_dark_frame

from .conftest import interior_scene, realdata


@pytest.mark.parametrize("demosaic", ["linear", "ahd", "dcb"])
def test_libraw_output_matches_native_cfa_values(camera, shoot, demosaic):
    """At each CFA site LibRaw keeps the native value: our rescaled output there must equal
    (raw − black)/(white − black) computed directly from rawpy's raw_image_visible."""
    truth = interior_scene((camera.height, camera.width))
    path = shoot(camera, truth)
    image = decode_raw(path, demosaic=demosaic)
    with rawpy.imread(str(path)) as raw:
        values = raw.raw_image_visible.astype(float)
        colours = raw.raw_colors_visible.copy()
        black = np.asarray(raw.black_level_per_channel, float)[colours]
        white = float(raw.white_level)
    expected = (values - black) / (white - black)
    channel = np.where(colours == 3, 1, colours)
    native = np.take_along_axis(image.rgb, channel[..., None], axis=-1)[..., 0]
    ok = ~image.saturated.any(axis=-1) & (expected > 0.05)
    # LibRaw rounds to 16 bits after scaling by ≈ 4: ≤ 0.5/65535 absolute → ≤ 2e-4 at 0.05.
    assert np.max(np.abs(native[ok] - expected[ok])) < 1.5e-4
    assert ok.mean() > 0.5


def test_superpixel_is_exact_binning(camera, shoot):
    truth = interior_scene((camera.height, camera.width))
    path = shoot(camera, truth)
    image = decode_raw(path, demosaic="superpixel")
    with rawpy.imread(str(path)) as raw:
        v = raw.raw_image_visible.astype(float)
        black = np.asarray(raw.black_level_per_channel, float)[raw.raw_colors_visible]
        norm = (v - black) / (raw.white_level - black)
    # RGGB: R at (0,0), G at (0,1) and (1,0), B at (1,1) — straight from the definition.
    np.testing.assert_allclose(image.rgb[..., 0], norm[0::2, 0::2], rtol=1e-6)
    np.testing.assert_allclose(image.rgb[..., 1], (norm[0::2, 1::2] + norm[1::2, 0::2]) / 2, rtol=1e-6)
    np.testing.assert_allclose(image.rgb[..., 2], norm[1::2, 1::2], rtol=1e-6)
    assert image.binning == 2 and image.shape == (camera.height // 2, camera.width // 2)


@pytest.mark.parametrize("demosaic", ["superpixel", "linear", "ahd", "dcb"])
def test_saturation_mask_follows_saturated_cfa_values(camera, shoot, demosaic):
    truth = np.full((camera.height, camera.width), 10.0)
    truth[90:100, 120:130] = 1e6  # a 10 × 10 px spot far above the white level
    image = decode_raw(shoot(camera, truth), demosaic=demosaic)
    b = image.binning
    sat = image.saturated.any(axis=-1)
    assert sat[95 // b, 125 // b]
    assert not sat[20 // b, 20 // b]
    # Neighbourhood that LibRaw's interpolation reads (≤ 3 px) plus the 2 × 2 cell.
    assert sat.sum() * b * b <= (10 + 2 * 3 + 2) ** 2
    assert sat.sum() * b * b >= 100


def test_fully_saturated_and_black_frames(camera, shoot):
    white = decode_raw(shoot(camera, np.full((camera.height, camera.width), 1e9)))
    assert white.saturated.all()
    black = decode_raw(shoot(camera, np.zeros((camera.height, camera.width))))
    assert not black.saturated.any()
    assert np.all(black.rgb == 0)


def test_fourteen_bit_extremes(camera, tmp_path):
    from lsadphoto.datasets import write_dng

    raw = np.zeros((camera.height, camera.width), np.uint16)
    raw[:, camera.width // 2 :] = camera.white_level  # left half 0 ADU (below black), right half white
    path = write_dng(tmp_path / "extreme.dng", raw, camera, exposure_time=0.01, f_number=2.8, iso=100)
    image = decode_raw(path)
    left, right = image.rgb[:, : image.shape[1] // 2], image.rgb[:, image.shape[1] // 2 :]
    # 0 ADU is 512 below black: −512/15871 of the range; the white level is saturated.
    np.testing.assert_allclose(left, -512 / (16383 - 512), rtol=1e-6)
    np.testing.assert_allclose(right, 1.0, rtol=1e-6)  # the white level is 1 by definition
    assert image.saturated[:, image.shape[1] // 2 :].all() and not image.saturated[:, : image.shape[1] // 2].any()


def test_black_level_delta_v_map(camera, tmp_path):
    """A DNG with BlackLevelDeltaV (per-row black offsets) decodes against the map."""
    from pidng.dng import Type

    from lsadphoto.datasets import write_dng

    truth = np.full((camera.height, camera.width), 40.0)
    delta = (20 * np.sin(np.arange(camera.height) / 15.0)).round()
    plain = camera.expose(truth, exposure_time=1 / 125, f_number=4, iso=100, noise=False).astype(float)
    black = camera.black_map()
    v = (plain - black) / (camera.white_level - black)
    # DNG 1.6 ch. 5: linear = (raw − black(row, col)) / (white − black(row, col)).
    black_px = black + delta[:, None]
    raw = np.rint(black_px + v * (camera.white_level - black_px)).astype(np.uint16)
    path = write_dng(tmp_path / "delta_v.dng", raw, camera, exposure_time=1 / 125, f_number=4, iso=100,
                     extra_tags=[((50716, Type.Srational), [[int(d), 1] for d in delta])])
    for demosaic in ("superpixel", "linear"):
        image = decode_raw(path, demosaic=demosaic)
        assert image.black_map_used
        g = image.rgb[..., 1]
        # With the map the rows agree to quantisation (≤ 1 ADU of ≈ 2800 → 4e-4); without
        # it they would vary by ±20 ADU ≈ ±0.7 %.
        assert np.ptp(g.mean(axis=1)) / g.mean() < 1e-3, demosaic


def test_dark_frame_map(camera, shoot, tmp_path):
    from lsadphoto.datasets import write_dng

    pattern = (np.arange(camera.width) % 7).astype(int) * 3  # fixed-pattern column offsets
    dark = camera.expose(np.zeros((camera.height, camera.width)), exposure_time=1 / 125, f_number=4, iso=100,
                         noise=False).astype(int) + pattern
    dark_path = write_dng(tmp_path / "dark.dng", dark.astype(np.uint16), camera, exposure_time=1 / 125,
                          f_number=4, iso=100)
    light = camera.expose(np.full((camera.height, camera.width), 40.0), exposure_time=1 / 125, f_number=4,
                          iso=100, noise=False).astype(int) + pattern
    light_path = write_dng(tmp_path / "light.dng", light.astype(np.uint16), camera, exposure_time=1 / 125,
                           f_number=4, iso=100)
    black_map = read_dark_frame([dark_path])
    image = decode_raw(light_path, dark_frame=black_map)
    g = image.rgb[..., 1]
    assert image.black_map_used
    assert np.ptp(g) / g.mean() < 2e-3  # the column pattern is gone (it was ±1 %)


def test_metadata_sources(camera, shoot):
    path = shoot(camera, np.full((camera.height, camera.width), 10.0), exposure_time=1 / 60, f_number=5.6, iso=400)
    meta = read_exposure_metadata(path, None)
    with rawpy.imread(str(path)) as raw:
        meta_lr = read_exposure_metadata(path, raw)
    # LibRaw misses ISO in IFD0 of a DNG (PITFALLS.md): it must come from EXIF.
    assert meta_lr.iso == 400 and meta_lr.sources["iso"] == "exif"
    assert meta_lr.exposure_time == pytest.approx(1 / 60, rel=1e-6) and meta_lr.sources["exposure_time"] == "libraw"
    assert meta.f_number == pytest.approx(5.6) and meta.sources["f_number"] == "exif"
    assert meta_lr.focal_plane_resolution[0] == pytest.approx(camera.width / camera.sensor_width, rel=1e-3)
    assert meta_lr.exposure() == pytest.approx((1 / 60) * 400 / 5.6**2, rel=1e-6)


@pytest.mark.realdata
def test_real_dng_decodes():
    path = realdata("raw/tinydng_colorchart.dng")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        image = decode_raw(path, demosaic="superpixel")
        full = decode_raw(path, demosaic="ahd")
    # Sizes and levels from the file's README: visible 1734 × 1156, black 2056, white 15000.
    assert image.sensor_shape == (1156, 1734)
    assert image.shape == (578, 867) and full.shape == (1156, 1734)
    assert np.all(image.black_level == 2056) and np.all(image.white_level == 15000)
    assert image.cfa_pattern == "RGGB"
    # Exposure fields are empty: LibRaw's APEX-derived 1 s and f/1 are treated as missing.
    assert image.metadata.exposure_time is None and image.metadata.f_number is None
    assert image.metadata.iso is None
    assert image.metadata.camera == "Canon EOS Kiss X4"
    assert any(issubclass(w.category, MetadataWarning) for w in caught)
    assert 0 < np.median(image.rgb) < 1
    # Superpixel and AHD agree on the image's mean green within 1 % (same data, binned).
    assert np.mean(image.rgb[..., 1]) == pytest.approx(np.mean(full.rgb[..., 1]), rel=0.01)


@pytest.mark.realdata
def test_non_raw_file_is_refused():
    with pytest.raises(UnsupportedFileError):
        decode_raw(realdata("raw/halide_bayer_small.png"))
