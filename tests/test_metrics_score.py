"""score_map: extremes, invariances and the uncertainty it reports.

References: closed forms (UGR scale law 8·log10(k); P = 1 on the line of sight), symmetry
(rotating a centred fisheye image by 90° about the optical axis rotates every direction
exactly), and the documented behaviour for undefined cases (null with a reason).
"""

import json
import math

import numpy as np
import pytest

from lsadphoto.datasets import disk_sources_scene
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.metrics.score import score_map

REQUIRED_KEYS = ("ugr_pixel", "ugr_grouped", "q", "dgp", "background_luminance",
                 "vertical_illuminance", "sources", "settings", "provenance")


def _camera(size):
    return IdealFisheyeProjection("equidistant", (size - 1) / 2, (size - 1) / 2, size / 2, 180.0,
                                  size, size)


def _direction(sigma_deg, tau_deg):
    s, t = math.radians(sigma_deg), math.radians(tau_deg)
    return np.array([math.sin(s) * math.sin(t), -math.sin(s) * math.cos(t), math.cos(s)])


def _map(size, background, sources, **kwargs):
    cam = _camera(size)
    L = disk_sources_scene(cam.directions(*cam.pixel_grid()), background=background,
                           sources=sources)
    return LuminanceMap(L, projection=cam, calibrated=True, **kwargs)


def test_record_has_the_required_keys_and_is_json():
    score = score_map(_map(200, 100.0, [(_direction(30, 0), 0.08, 20000.0)]))
    record = score.to_dict()
    for key in REQUIRED_KEYS:
        assert key in record
    json.dumps(record, allow_nan=False)  # strict JSON: no NaN or infinity
    assert record["sources"][0]["n_pixels"] > 0


def test_no_source_reports_null_with_a_reason():
    record = score_map(_map(200, 100.0, [])).to_dict()
    assert record["ugr_pixel"] is None and record["ugr_grouped"] is None
    assert record["n_sources"] == 0 and record["sources"] == []
    assert any("no glare sources" in n for n in record["notes"])
    # DGP is defined without sources: c1·E_v + c3 with E_v ≈ π·100 (rim pixels: 1e-3).
    assert record["dgp"] == pytest.approx(5.87e-5 * math.pi * 100 + 0.159, abs=1e-4)


def test_zero_background_reports_null():
    record = score_map(_map(200, 0.0, [(_direction(30, 0), 0.08, 20000.0)])).to_dict()
    assert record["background_luminance"] == 0.0
    assert record["ugr_grouped"] is None and record["ugr_pixel"] is None
    assert any("background luminance is zero" in n for n in record["notes"])


def test_sun_in_view_is_finite():
    record = score_map(_map(400, 50.0, [(_direction(40, 90), 0.2, 6000.0),
                                        (_direction(40, 90), 0.01, 1.6e9)])).to_dict()
    assert record["dgp"] == 1.0
    assert math.isfinite(record["ugr_grouped"]) and record["ugr_grouped"] > 60
    assert any(s["peak"] for s in record["sources"])


@pytest.mark.parametrize("size", [1, 2])
def test_tiny_maps(size):
    """One or four pixels of 3000 cd/m²: each is a glare source (above 2000 cd/m²), there is no
    background, so L_b = (E_v − E_dir)/π = 0, the UGR-type indices (∝ log 1/L_b) and Q (no
    3×3 stencil) are undefined with a note, and E_v is the sum L·ω·cos σ over the pixels'
    solid angles and directions as the camera model gives them (the definition, FORMULAS.md)."""
    cam = _camera(size)
    record = score_map(LuminanceMap(np.full((size, size), 3000.0), projection=cam)).to_dict()
    json.dumps(record, allow_nan=False)
    grid = cam.pixel_grid()
    cos_sigma = np.clip(cam.directions(*grid)[..., 2], 0, None)
    expected = float(np.sum(3000.0 * cam.solid_angles(*grid) * cos_sigma))
    # cos σ as the visual field stores it (float32, each value rounded once: VisualField):
    # the same sum to 1e-12, and within 2⁻²⁴ of the float64 one.
    stored = float(np.sum(3000.0 * cam.solid_angles(*grid) * cos_sigma.astype(np.float32)))
    assert record["vertical_illuminance"] == pytest.approx(stored, rel=1e-12)
    assert record["direct_illuminance"] == pytest.approx(stored, rel=1e-12)
    assert record["vertical_illuminance"] == pytest.approx(expected, rel=2.0 ** -24)
    assert record["mean_luminance"] == pytest.approx(3000.0, rel=1e-12)
    assert record["n_sources"] == size * size and record["background_luminance"] == 0.0
    assert record["ugr_pixel"] is None and record["ugr_grouped"] is None and record["q"] is None
    assert any("background luminance is zero" in n for n in record["notes"])
    assert any("Q undefined" in n for n in record["notes"])


def test_all_nan_and_half_nan_maps():
    cam = _camera(64)
    record = score_map(LuminanceMap(np.full((64, 64), np.nan), projection=cam)).to_dict()
    assert record["vertical_illuminance"] == 0.0
    assert record["q"] is None and record["ugr_pixel"] is None
    assert any("no valid pixel" in n for n in record["notes"])
    full = disk_sources_scene(cam.directions(*cam.pixel_grid()), background=100.0,
                              sources=[(_direction(30, 270), 0.2, 9000.0)])  # left half
    half = full.copy()
    half[:, 32:] = np.nan  # the right half of a centred 64-px circle, exactly
    e_full = score_map(LuminanceMap(full, projection=cam)).values["vertical_illuminance"]
    record = score_map(LuminanceMap(half, projection=cam)).to_dict()
    uniform = score_map(LuminanceMap(np.full((64, 64), 100.0), projection=cam))
    # By mirror symmetry the missing half held half the uniform background's E_v.
    assert e_full - record["vertical_illuminance"] == pytest.approx(
        uniform.values["vertical_illuminance"] / 2, rel=1e-9)
    assert record["ugr_grouped"] is not None


def test_source_on_the_line_of_sight_and_at_the_edge():
    lmap = _map(300, 100.0, [(_direction(0, 0), 0.05, 10000.0)])
    centre = score_map(lmap, source_position="direction").to_dict()["sources"][0]
    assert centre["position_index"] == pytest.approx(1.0, abs=1e-3)
    # evalglare's position: the pixel of the mean pixel position (149.5, 149.5), truncated in
    # its bottom-up coordinates: row 150, column 149, half a pixel off the axis diagonally.
    record = score_map(lmap).to_dict()
    source = record["sources"][0]
    assert source["row"] == pytest.approx(149.5) and source["position_pixel"] == [150, 149]
    d = lmap.projection.directions(150.0, 149.0)
    from lsadphoto.geometry import ObserverFrame, position_index

    assert source["position_index"] == pytest.approx(
        float(position_index(*ObserverFrame().angles(d))), rel=1e-12)
    edge = score_map(_map(300, 100.0, [(_direction(89, 0), 0.05, 10000.0)])).to_dict()
    # Straight above at σ ≈ 90° Guth's index exceeds 16: evalglare's cap (FORMULAS.md §2.1).
    assert edge["sources"][0]["position_index"] == pytest.approx(16.0)
    assert edge["sources"][0]["sigma_deg"] > 80


def test_rotation_about_the_line_of_sight_leaves_sigma_only_quantities():
    lmap = _map(240, 80.0, [(_direction(30, 20), 0.1, 15000.0), (_direction(55, 200), 0.15,
                                                                   4000.0)])
    rotated = LuminanceMap(np.rot90(lmap.luminance).copy(), projection=lmap.projection)
    a = score_map(lmap, q_weight_exponent=0)
    b = score_map(rotated, q_weight_exponent=0)
    # rot90 of a centred square fisheye maps pixel directions onto each other exactly; sums
    # are reordered, so agreement is to float64 summation error.
    for key in ("vertical_illuminance", "background_luminance", "mean_luminance", "q"):
        assert b.values[key] == pytest.approx(a.values[key], rel=1e-9), key
    for ring_a, ring_b in zip(a.statistics["rings"], b.statistics["rings"], strict=True):
        assert ring_b["mean"] == pytest.approx(ring_a["mean"], rel=1e-9)
        assert ring_b["percentiles"] == ring_a["percentiles"]


def test_calibration_uncertainty_propagates_as_8_u_over_ln10():
    lmap = _map(200, 100.0, [(_direction(30, 0), 0.08, 20000.0)], calibration_uncertainty=0.03)
    u = score_map(lmap).uncertainty
    # UGR(k·L) = UGR + 8·log10 k; half the spread over k = 1 ± u is 4·log10((1+u)/(1−u)).
    expected = 4 * math.log10(1.03 / 0.97)
    assert u["ugr_grouped"] == pytest.approx(expected, rel=1e-9)
    assert u["ugr_pixel"] == pytest.approx(expected, rel=1e-9)
    assert u["vertical_illuminance"] == pytest.approx(0.03 * score_map(lmap).values[
        "vertical_illuminance"], rel=1e-9)


def test_map_without_geometry_is_rejected():
    from lsadphoto.errors import BadInputError

    with pytest.raises(BadInputError, match="no camera projection"):
        score_map(LuminanceMap(np.ones((4, 4))))


def test_q_uncertainty_from_one_sweep_equals_recomputing_at_scaled_luminance():
    from lsadphoto.geometry.field import pixel_geometry, visual_field
    from lsadphoto.geometry.observer import ObserverFrame
    from lsadphoto.metrics.quality import q_Budak2021

    u = 0.05
    lmap = _map(200, 40.0, [(_direction(30, 0), 0.08, 3000.0), (_direction(50, 150), 0.12, 600.0)],
                calibration_uncertainty=u)
    score = score_map(lmap)
    g = pixel_geometry(lmap.projection)
    P = visual_field(lmap.projection, ObserverFrame()).position_index
    L = np.asarray(lmap.luminance, dtype=np.float64)
    direct = [q_Budak2021(L * k, g.directions, g.solid_angle, P).q for k in (1 + u, 1 - u)]
    # The sweep uses Q(kL; N) = Q(L; N')·N/N' exactly; only float rounding differs.
    assert score.uncertainty["q"] == pytest.approx(abs(direct[0] - direct[1]) / 2, rel=1e-6)
    assert score.uncertainty["q"] > 0


def test_field_consumers_read_the_float32_picture_as_the_float64_map():
    # score_map hands the float32 picture itself to the field sums, the statistics and Q
    # where ω is 0 off the valid pixels. Reference: the same functions on the float64 map
    # with NaN off the field (the path the evalglare comparisons check): equal bit for bit,
    # since every float32 value is a float64 number and the pixels off the field are not
    # read (here they hold 1e6 cd/m²: a consumer that took them into its field would change).
    from lsadphoto.geometry import pixel_geometry
    from lsadphoto.geometry.position_index import position_index as position_index_of
    from lsadphoto.metrics.field import field_sums
    from lsadphoto.metrics.quality import q_Budak2021
    from lsadphoto.metrics.statistics import luminance_statistics

    cam = IdealFisheyeProjection("equidistant", 63.5, 63.5, 64.0, 180.0, 128, 128)
    geometry = pixel_geometry(cam)
    d = cam.directions(*cam.pixel_grid())
    rng = np.random.default_rng(2)
    picture = disk_sources_scene(d, background=120.0, sources=[((0.3, 0.2, 0.93), 0.1, 9000.0)])
    picture = (np.nan_to_num(picture) * rng.uniform(0.8, 1.2, picture.shape)).astype(np.float32)
    picture[~geometry.valid] = 1e6
    omega = geometry.solid_angle  # 0 off the valid pixels
    cos_sigma = np.where(geometry.valid, np.nan_to_num(d[..., 2]), 0.0)
    with np.errstate(invalid="ignore"):
        sigma = np.arccos(np.clip(d[..., 2], -1, 1))
        tau = np.arctan2(np.abs(d[..., 0]), d[..., 1])
    pindex = np.where(geometry.valid, position_index_of(sigma, tau), np.nan)
    masked = np.where(geometry.valid, picture.astype(np.float64), np.nan)
    mask = geometry.valid & (masked > 2000.0)
    assert field_sums(picture, omega, cos_sigma, pindex, mask) == \
        field_sums(masked, omega, cos_sigma, pindex, mask)
    assert luminance_statistics(picture, omega, cos_sigma) == \
        luminance_statistics(masked, omega, cos_sigma)
    ours, reference = (q_Budak2021(L, geometry, omega, pindex, valid=geometry.valid)
                       for L in (picture, masked))
    assert (ours.q, ours.mean_luminance, ours.kept_fraction) == \
        (reference.q, reference.mean_luminance, reference.kept_fraction) and math.isfinite(ours.q)
    np.testing.assert_array_equal(ours.contrast, reference.contrast)
