"""The metric registry: every metric listed once, read by score_map; the package's API.

References: the score record itself (every value it reports is a registry entry and back),
and a closed form for a registered extra index (UGR + 1 by construction).
"""

import dataclasses
import math

import numpy as np
import pytest

import lsadphoto.metrics as metrics
from lsadphoto.datasets import disk_sources_scene
from lsadphoto.errors import BadInputError
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.metrics import registry
from lsadphoto.metrics.score import score_map


@pytest.fixture(scope="module")
def lmap():
    cam = IdealFisheyeProjection("equidistant", 59.5, 59.5, 60.0, 180.0, 120, 120)
    d = cam.directions(*cam.pixel_grid())
    up = np.array([0.0, -math.sin(0.4), math.cos(0.4)])
    L = disk_sources_scene(d, background=80.0, sources=[(up, 0.12, 20000.0)])
    return LuminanceMap(L, uncertainty=0.05 * L, projection=cam, calibrated=True,
                        calibration_uncertainty=0.02)


def test_every_reported_value_is_registered_once(lmap):
    names = [m.name for m in registry.FIELD + registry.INDICES + registry.OTHER
             + registry.ANALYSES]
    assert len(names) == len(set(names)) == len(registry.METRICS)
    score = score_map(lmap, q_noise_samples=0)
    assert set(score.values) == set(names)
    for m in registry.METRICS.values():
        assert callable(m.function) and m.label and m.reference, m.name
        assert set(m.inputs) <= set(registry.QUANTITIES) | {i.name for i in registry.INDICES}
    # Every index carries both uncertainty parts (calibration and pixel noise).
    for m in registry.INDICES:
        assert m.name in score.uncertainty_calibration and m.name in score.uncertainty_noise


def test_unknown_metric_lists_the_valid_ones():
    with pytest.raises(BadInputError, match="ugr_grouped"):
        registry.metric("glare_of_doom")
    assert registry.metric("dgp").unit == "–"


def test_adding_an_index_is_one_function_and_one_line(lmap, monkeypatch):
    def ugr_plus_one(luminance, solid_angle, position_index, background_luminance):
        return metrics.ugr_CIE117(luminance, solid_angle, position_index,
                                  background_luminance) + 1.0

    extra = registry.Metric("ugr_plus_one", ugr_plus_one, "–", "UGR + 1", "this test",
                            inputs=("sources", "background_luminance"))
    monkeypatch.setattr(registry, "INDICES", registry.INDICES + (extra,))
    score = score_map(lmap, q_noise_samples=0)
    assert score.values["ugr_plus_one"] == pytest.approx(score.values["ugr_grouped"] + 1.0,
                                                         abs=1e-12)
    # Its uncertainties come for free and equal UGR's (a constant offset).
    assert score.uncertainty["ugr_plus_one"] == pytest.approx(score.uncertainty["ugr_grouped"],
                                                              rel=1e-9)
    assert "ugr_plus_one" in score.to_dict()


def test_the_package_exports_its_api():
    for name in metrics.__all__:
        assert getattr(metrics, name) is not None, name
    assert metrics.score_map is score_map
    assert metrics.METRICS is registry.METRICS
    with pytest.raises(AttributeError):
        metrics.no_such_metric  # noqa: B018


def test_compare_reads_the_registry():
    from lsadphoto.compare import COMPARED_METRICS

    assert set(COMPARED_METRICS) == {m.name for m in registry.FIELD + registry.INDICES} | {"q"}
    assert dataclasses.is_dataclass(registry.METRICS["q"])
