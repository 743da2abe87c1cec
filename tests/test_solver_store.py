"""Reproducibility, the view-independent store, accuracy control and input checks."""

import math

import numpy as np
import pytest

from lsadphoto.errors import BadInputError, SolverWarning, UnsupportedFileError
from lsadphoto.solver import (
    camera_to_world,
    load_store,
    render,
    render_path_traced,
    simulate,
)
from lsadphoto.solver.chains import trace_chains
from lsadphoto.solver.direct import LUMINAIRE_DRAWS
from lsadphoto.solver.engine import engine_for
from lsadphoto.solver.examples import canonical_room
from lsadphoto.solver.rendering import MAX_LUMINAIRE_DRAWS, TARGET_MEASURE

NODE_FIELDS = ("position", "normal", "coefficient", "kind", "luminaire", "batch", "depth", "triangle")


@pytest.fixture(scope="module")
def room():
    return canonical_room(size=16)


@pytest.fixture(scope="module")
def store(room):
    return simulate(room, samples=2048, seed=9)


def view_args(room):
    v = room.views[0]
    return v.projection, {"position": v.position, "rotation": v.rotation}


#: A 32² fisheye has ~800 valid pixels: several 256-pixel blocks, so chunking matters.
BIG = canonical_room(size=32).views[0].projection


@pytest.mark.parametrize("nodes_per_pixel", [None, 16])
def test_chunk_size_does_not_change_a_render(room, nodes_per_pixel):
    small = simulate(room, samples=256, seed=8)
    _, pose = view_args(room)
    a = render(small, BIG, **pose, chunk_pixels=1, nodes_per_pixel=nodes_per_pixel, seed=4)
    b = render(small, BIG, **pose, chunk_pixels=4096, nodes_per_pixel=nodes_per_pixel, seed=4)
    assert np.array_equal(a.luminance, b.luminance, equal_nan=True)
    assert np.array_equal(a.uncertainty, b.uncertainty, equal_nan=True)


def test_simulation_in_rounds_equals_one_run(room):
    engine = engine_for(room)
    whole = trace_chains(room, engine, seed=5, first_block=0, blocks=4, batches=16)
    part = trace_chains(room, engine, seed=5, first_block=0, blocks=1, batches=16)
    part.extend(trace_chains(room, engine, seed=5, first_block=1, blocks=3, batches=16))
    for name in NODE_FIELDS:
        assert np.array_equal(getattr(whole, name), getattr(part, name)), name
    assert whole.chains == part.chains == 1024


def test_seeds_differ_and_repeat(room):
    a = simulate(room, samples=256, seed=1)
    b = simulate(room, samples=256, seed=1)
    c = simulate(room, samples=256, seed=2)
    assert np.array_equal(a.position, b.position)
    assert not np.array_equal(a.position[: min(a.nodes, c.nodes)], c.position[: min(a.nodes, c.nodes)])


def test_store_round_trip_renders_identically(room, store, tmp_path):
    path = tmp_path / "room.lsad.npz"
    store.save(path)
    assert [p.name for p in tmp_path.iterdir()] == ["room.lsad.npz"]  # no temporary left
    loaded = load_store(path)
    for name in NODE_FIELDS:
        assert np.array_equal(getattr(loaded, name), getattr(store, name))
    assert loaded.chains == store.chains and loaded.batches == store.batches
    assert loaded.scene.views[0].projection == room.views[0].projection
    proj, pose = view_args(room)
    a = render(store, proj, **pose, seed=2)
    b = render(loaded, proj, **pose, seed=2)
    assert np.array_equal(a.luminance, b.luminance, equal_nan=True)
    assert np.array_equal(a.uncertainty, b.uncertainty, equal_nan=True)


def test_surface_node_hull_is_saved_and_bounds_every_node(room, tmp_path):
    # The hull's support function must equal the largest n·p over all surface nodes (brute
    # force, the independent reference) in any direction: a smaller value would zero the
    # far part of E_ind at points that do face a node. Exact up to rounding of the same
    # products, so the tolerance is a few ulps of the room's size.
    store = simulate(room, samples=256, seed=3)
    hull = store.surface_node_hull()
    nodes = store.position[store.depth > 0]
    assert 4 <= len(hull) < len(nodes)
    normals = np.random.default_rng(1).normal(size=(500, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    assert np.allclose((normals @ hull.T).max(axis=1), (normals @ nodes.T).max(axis=1), rtol=0, atol=1e-12)
    path = tmp_path / "room.lsad.npz"
    store.save(path)  # the hull travels with the store, so a further view does not recompute it
    assert np.array_equal(load_store(path).node_hull, hull)
    bare = tmp_path / "bare.lsad.npz"
    simulate(room, samples=256, seed=3).save(bare)  # saved before any hull: computed on demand
    assert load_store(bare).node_hull is None
    assert np.array_equal(load_store(bare).surface_node_hull(), hull)
    store.extend(simulate(room, samples=256, seed=4))  # new nodes: the hull is recomputed
    assert store.node_hull is None
    with np.load(path) as data:  # a hull that is no list of 3-D points: a one-line refusal
        arrays = {k: data[k] for k in data.files}
    arrays["node_hull"] = hull[:, :2]
    np.savez(tmp_path / "odd.lsad.npz", **arrays)
    with pytest.raises(UnsupportedFileError, match="node hull"):
        load_store(tmp_path / "odd.lsad.npz")


def test_one_store_many_views(room, store):
    # view independence: a second observer needs no new simulation
    proj, _ = view_args(room)
    lmap = render(store, proj, position=[5.0, 1.0, 1.6], rotation=camera_to_world([-1, 0.5, 0], [0, 0, 1]))
    assert lmap.provenance["chains"] == store.chains
    assert np.nanmean(lmap.luminance) > 0


def test_render_provenance_and_errors(room, store):
    proj, pose = view_args(room)
    lmap = render(store, proj, **pose)
    p = lmap.provenance
    assert p["estimator"] == "double local estimate"
    assert p["near_field"] == "unbiased" and p["near_field_biased"] is False
    assert p["batches"] == 16 and p["chains"] == 2048
    assert 0 < p["achieved_relative_error"] < 1
    valid = np.isfinite(lmap.luminance)
    assert np.all(lmap.uncertainty[valid] >= 0)
    assert np.all(np.isnan(lmap.luminance[~valid]))  # outside the fisheye circle
    clamp = render(store, proj, **pose, near_field="clamp")
    assert clamp.provenance["near_field_biased"] is True


@pytest.mark.slow
def test_per_pixel_errors_are_reported_and_honest(room):
    # Pairs of independent simulations of one view: a pixel's difference has variance
    # se₁² + se₂², so with honest errors the median over pixels of |d|/√(se₁² + se₂²) is that
    # of |t₁₅| (errors from B = 16 batches), 0.69. The pixels of one pair share their chains
    # and are strongly correlated (one pair's median ranges over 0.4…1.5), so the pairs are the
    # independent samples: their mean must lie within 3 of its standard errors of 0.69.
    proj, pose = view_args(room)
    medians = []
    for k in range(10):
        a, b = (render(simulate(room, samples=2048, seed=100 + 2 * k + i), proj, seed=2 * k + i, **pose)
                for i in (0, 1))
        sigma = np.hypot(a.uncertainty, b.uncertainty)
        ok = np.isfinite(a.luminance) & (sigma > 0)  # (luminaires seen directly are exact: σ = 0)
        assert ok.sum() > 150
        medians.append(np.median(np.abs(a.luminance[ok] - b.luminance[ok]) / sigma[ok]))
    se = np.std(medians, ddof=1) / math.sqrt(len(medians))
    assert abs(np.mean(medians) - 0.69) < 3 * se, (np.mean(medians), se)
    # the provenance states the median and 95th percentile of the relative errors, which the
    # field mean's error understates
    p = a.provenance
    lit = np.isfinite(a.luminance) & (a.luminance > 0)
    rel = a.uncertainty[lit] / a.luminance[lit]
    assert math.isclose(p["pixel_relative_error_median"], np.median(rel), rel_tol=1e-6)
    assert math.isclose(p["pixel_relative_error_p95"], np.percentile(rel, 95), rel_tol=1e-6)
    assert math.isclose(p["pixel_relative_error_expected_mean_absolute"], math.sqrt(2 / math.pi) * np.mean(rel),
                        rel_tol=1e-6)
    assert p["pixel_relative_error_median"] > 5 * p["achieved_relative_error"]


def test_render_to_a_per_pixel_target_error(room):
    # Rounds: 1/√chains predicts the chains; the reported errors are honest (test above), so
    # reaching the target means the map has it: the mean absolute relative error that they
    # imply (TARGET_MEASURE; measured against a reference in the test below).
    proj, pose = view_args(room)
    lmap = render(room, proj, **pose, samples=1024, target_error=0.01)
    p = lmap.provenance
    assert TARGET_MEASURE in p["target_measure"]
    assert p["target_reached"] is True and p[TARGET_MEASURE] <= 0.01
    assert len(p["rounds"]) >= 2 and p["rounds"][0]["chains"] == 1024  # 1024 give ≈ 2 %
    assert p["rounds"][-1]["chains"] == p["chains"]
    errors = [r[TARGET_MEASURE] for r in p["rounds"]]
    assert all(b < a for a, b in zip(errors, errors[1:]))
    # The rounds append chains to the earlier ones (chain i has its own random stream), so
    # the result is exactly one simulation of the final number of chains, rendered once:
    # an independent run through simulate + render, bit for bit.
    once = render(simulate(room, samples=p["chains"]), proj, **pose)
    np.testing.assert_array_equal(lmap.luminance, once.luminance)
    np.testing.assert_array_equal(lmap.uncertainty, once.uncertainty)


@pytest.mark.slow
def test_a_per_pixel_target_bounds_the_mean_absolute_error_against_a_reference(room):
    # What the target promises, measured: the map rendered to 2 % against an independent
    # reference (another seed, 16× the chains, every node connected: its own mean absolute
    # error ≈ 0.4 %, removed in quadrature). Measured: 1.59 % for an expected 1.54 % (198
    # pixels; the pixels share their chains, so the mean absolute error of one map moves
    # with them: 1.3× the target allowed). In this uniformly lit room the median of σ/L, the
    # measure before session 11, is as large (1.52 %); on the station hall it was 1.5× below
    # the mean absolute error (docs/accuracy.md).
    proj, pose = view_args(room)
    lmap = render(room, proj, **pose, samples=1024, target_error=0.02)
    p = lmap.provenance
    assert p["target_reached"] is True and p[TARGET_MEASURE] <= 0.02
    ref = render(simulate(room, samples=16 * p["chains"], seed=99), proj, **pose, seed=5, nodes_per_pixel="all")
    ok = np.isfinite(lmap.luminance) & (lmap.luminance > 0) & (ref.uncertainty > 0)
    assert ok.sum() > 150
    error = np.mean(np.abs(lmap.luminance[ok] / ref.luminance[ok] - 1))
    own = math.sqrt(2 / math.pi) * np.mean(ref.uncertainty[ok] / ref.luminance[ok])
    assert own < 0.3 * error
    assert math.sqrt(error ** 2 - own ** 2) <= 1.3 * 0.02


@pytest.mark.slow
def test_surface_cache_render_to_a_per_pixel_target(room):
    # The cache's rounds grow chains, node draws, shadow rays and luminaire draws by one factor
    # (the room's 4 luminaires: every one whole, "auto", then any K ≥ 4, up to
    # MAX_LUMINAIRE_DRAWS), so the reported per-pixel error (the map's own: the honesty of these
    # errors is tested above and in test_solver_cache.py) falls round by round until it
    # reaches the target.
    proj, pose = view_args(room)
    # (0.4 %, the target here before session 11, when it bounded the median σ/L, is not reached
    # by the mean absolute error: the interpolation bias's tail near the panels, which more
    # chains do not lower, holds it at 0.41 % — twice the median — and the rounds stop with a
    # SolverWarning. 0.8 % is reached in three rounds: 1024 → 13 824 → 27 648 chains, the last
    # with the draws at their cap; two rounds sufficed before session 12's bias term for refined
    # cells near the refinement test, which put the second round's measure at 0.96 %.)
    lmap = render(room, proj, **pose, estimator="cache", samples=1024, cache_nodes=256,
                  direct_samples=1, target_error=0.008)
    p = lmap.provenance
    assert p["target_reached"] is True and p[TARGET_MEASURE] <= 0.008
    rounds = p["rounds"]
    assert len(rounds) >= 2 and rounds[0] == {**rounds[0], "chains": 1024, "cache_nodes": 256,
                                              "direct_samples": 1, "luminaire_draws": "auto"}
    for a, b in zip(rounds, rounds[1:]):
        growth = b["chains"] / a["chains"]
        assert 2 <= growth <= 16
        assert b["cache_nodes"] == pytest.approx(a["cache_nodes"] * growth, rel=0.01)
        assert b["luminaire_draws"] == pytest.approx(
            min(MAX_LUMINAIRE_DRAWS, LUMINAIRE_DRAWS * b["chains"] / rounds[0]["chains"]), abs=1)
        assert b[TARGET_MEASURE] < a[TARGET_MEASURE]
    with pytest.raises(BadInputError, match="apply to the double local estimate"):
        render(room, proj, **pose, estimator="cache", nodes_per_pixel=4)
    with pytest.raises(BadInputError, match="apply to the surface cache"):
        render(room, proj, **pose, estimator="local", cache_nodes=64)


@pytest.mark.slow
def test_cache_target_says_when_the_interpolation_bias_holds_the_error(room):
    # A cache of 1.5 m spacing in the 6 × 4 m room: its estimated interpolation bias (mean
    # 0.94 % per pixel, measured) is twice its noise (0.47 %) by the third round and does not
    # fall with chains, so a 0.4 % target stalls, and the advice is a finer cache, not more
    # chains. The two parts are compared as means, the measure the target bounds.
    proj, pose = view_args(room)
    with pytest.warns(SolverWarning, match="interpolation bias .* give a finer cache_spacing"):
        lmap = render(room, proj, **pose, estimator="cache", samples=1024, cache_nodes=256, direct_samples=1,
                      cache_spacing=1.5, target_error=0.004)
    p = lmap.provenance
    assert p["target_reached"] is False
    assert p["pixel_relative_bias_mean"] > p["pixel_relative_noise_mean"] > 0


def test_render_target_error_says_when_it_stalls_or_applies_not(room, store):
    proj, pose = view_args(room)
    # One node per pixel and batch: more chains do not lower a pixel's error.
    with pytest.warns(SolverWarning, match="stopped falling"):
        lmap = render(room, proj, **pose, samples=1024, target_error=0.002, nodes_per_pixel=1,
                      max_samples=4096)
    assert lmap.provenance["target_reached"] is False
    with pytest.raises(BadInputError, match="chains are fixed"):
        render(store, proj, **pose, target_error=0.05)
    with pytest.raises(BadInputError, match="per-pixel relative error"):
        render(room, proj, **pose, target_error=1e-5)


def test_target_error_is_reached(room):
    calls = []
    store = simulate(room, target_error=0.001, samples=256, seed=3,
                     progress=lambda f, eta: calls.append((f, eta)))
    p = store.provenance
    assert p["target_reached"] is True
    assert p["achieved_relative_error"] <= 0.001
    assert store.chains > 256  # it needed more than the first round
    assert calls and all(0 <= f <= 1 for f, _ in calls) and calls[-1][0] == 1.0


def test_progress_of_render(room, store):
    proj, pose = view_args(room)
    seen = []
    render(store, proj, **pose, progress=lambda f, eta: seen.append(f))
    assert seen[-1] == 1.0


@pytest.mark.parametrize("kwargs, message", [
    ({"near_field": "soft"}, "unknown near_field 'soft'"),
    ({"batches": 7}, "batches"),
    ({"samples": 0}, "samples"),
    ({"max_depth": 0}, "max_depth"),
    ({"target_error": 2.0}, "target_error"),
    ({"absorption": "none"}, "unknown absorption"),
])
def test_bad_simulation_options(room, kwargs, message):
    with pytest.raises(BadInputError, match=message):
        simulate(room, **kwargs)


def test_bad_render_options(room, store):
    proj, pose = view_args(room)
    with pytest.raises(BadInputError, match="orthonormal"):
        render(store, proj, position=pose["position"], rotation=np.eye(3) * 2)
    with pytest.raises(BadInputError, match="Projection"):
        render(store, "fisheye", **pose)
    with pytest.raises(BadInputError, match="nodes_per_pixel"):
        render(store, proj, **pose, nodes_per_pixel=0)
    with pytest.raises(BadInputError, match="nodes_per_pixel"):
        render(store, proj, **pose, nodes_per_pixel="most")
    with pytest.raises(BadInputError, match="multiple of batches"):
        render_path_traced(room, proj, **pose, samples=20)


def test_bad_store_files(tmp_path):
    with pytest.raises(BadInputError, match="does not exist"):
        load_store(tmp_path / "none.npz")
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(UnsupportedFileError):
        load_store(bad)
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(UnsupportedFileError, match="no header"):
        load_store(tmp_path / "other.npz")


def _rewritten(path, out, edit):
    """Copy of the store file ``path`` at ``out`` with its arrays and JSON header edited by
    ``edit(arrays, meta)`` (in place)."""
    import json

    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(arrays.pop("meta").tobytes().decode("utf-8"))
    edit(arrays, meta)
    np.savez_compressed(out, meta=np.frombuffer(json.dumps(meta).encode("utf-8"), np.uint8), **arrays)
    return out


def test_store_format_versions(room, store, tmp_path):
    # A store of format /3 (written before materials had stores: the same layout without the
    # nodes' incoming directions and sides and the scene's materials) still loads and renders
    # as before; an unknown format, and a /4 store of a material scene without its nodes'
    # incoming directions, are one-line errors.
    from lsadphoto.solver.examples import material_room_rad
    from lsadphoto.solver.formats.radiance import read_radiance_scene
    from lsadphoto.solver.store import STORE_FORMAT

    assert STORE_FORMAT == "lsadphoto-lsad-store/5"
    store.save(tmp_path / "new.npz")
    old = load_store(_rewritten(tmp_path / "new.npz", tmp_path / "old.npz",
                                lambda a, m: m.update(format="lsadphoto-lsad-store/3")))
    proj, pose = view_args(room)
    assert np.array_equal(render(old, proj, **pose, seed=2).luminance, render(store, proj, **pose, seed=2).luminance,
                          equal_nan=True)
    with pytest.raises(UnsupportedFileError, match="unknown store format 'lsadphoto-lsad-store/9'"):
        load_store(_rewritten(tmp_path / "new.npz", tmp_path / "x.npz",
                              lambda a, m: m.update(format="lsadphoto-lsad-store/9")))
    glossy = read_radiance_scene(material_room_rad("glossy floor")[0])
    simulate(glossy, samples=256).save(tmp_path / "glossy.npz")
    with pytest.raises(UnsupportedFileError, match="LSAD store lacks 'incoming'"):
        load_store(_rewritten(tmp_path / "glossy.npz", tmp_path / "y.npz", lambda a, m: a.pop("incoming")))
    # a /4 material store (the reciprocal rule, nodes without ``direct``) loads as before
    old4 = load_store(_rewritten(tmp_path / "glossy.npz", tmp_path / "z.npz",
                                 lambda a, m: (a.pop("direct"), m.pop("fresnel_rule"),
                                               m.update(format="lsadphoto-lsad-store/4"))))
    assert old4.fresnel_rule == "reciprocal" and old4.nodes == load_store(tmp_path / "glossy.npz").nodes


def test_max_depth_truncates(room):
    one = simulate(room, samples=256, seed=1, max_depth=1)
    assert one.depth.max() == 1
    assert one.provenance["max_depth"] == 1
    full = simulate(room, samples=256, seed=1)
    assert full.depth.max() > 1
    assert math.isclose(one.provenance["total_flux_lm"], 12000.0)


def test_chunk_size_does_not_change_a_path_traced_render(room):
    _, pose = view_args(room)
    a = render_path_traced(room, BIG, **pose, samples=16, seed=3, chunk_pixels=1)
    b = render_path_traced(room, BIG, **pose, samples=16, seed=3, chunk_pixels=10_000)
    assert np.array_equal(a.luminance, b.luminance, equal_nan=True)
    assert np.array_equal(a.uncertainty, b.uncertainty, equal_nan=True)


def test_worker_threads_do_not_change_results(room):
    small = simulate(room, samples=256, seed=8)
    _, pose = view_args(room)
    a = render(small, BIG, **pose, chunk_pixels=256, nodes_per_pixel=16, seed=4, workers=1)
    b = render(small, BIG, **pose, chunk_pixels=256, nodes_per_pixel=16, seed=4, workers=2)
    assert np.array_equal(a.luminance, b.luminance, equal_nan=True)
    assert np.array_equal(a.uncertainty, b.uncertainty, equal_nan=True)
    c = render_path_traced(room, BIG, **pose, samples=16, chunk_pixels=256, workers=1)
    e = render_path_traced(room, BIG, **pose, samples=16, chunk_pixels=256, workers=2)
    assert np.array_equal(c.luminance, e.luminance, equal_nan=True)


def test_auto_gather_chooses_by_cost(room, store, monkeypatch):
    import lsadphoto.solver.integrators.local_estimate as render_module

    proj, pose = view_args(room)
    assert render(store, proj, **pose).provenance["nodes_per_pixel"] == "all"
    monkeypatch.setattr(render_module, "FULL_GATHER_PAIRS", 10)
    lmap = render(store, proj, **pose)
    assert lmap.provenance["nodes_per_pixel"] == render_module.AUTO_NODES_PER_PIXEL
