"""Bad input and extreme scenes: what the solver refuses, warns about, and still gets right.

Decisions (documented in docs/user-guide-solver.md by the lead):

* Degenerate geometry (zero-area polygons, collinear vertices, zero-area triangles) and
  reflectances outside [0, 1) are refused with one-line :class:`BadInputError`\\ s; so is a
  photometric file that does not parse.
* A room that is not closed is legal: light that leaves it is lost (chains end when their
  ray misses), and pixels whose ray leaves the model are 0 cd·m⁻². No warning: an open
  model (a plane under a luminaire, a façade) is a normal use.
* An eye on a surface (within 10 ray offsets of it for more than 1 % of the primary rays)
  or one that sees surfaces but no light at all (outside a closed room, inside a solid)
  gives a :class:`SolverWarning`, and the map is still returned. A view that hits nothing
  (out of an open model) is legal and silent: 0 cd·m⁻².
* A ``target_error`` that ``max_samples`` does not allow gives a :class:`SolverWarning`
  with the achieved error (and ``target_reached = False``), never a longer run.
* Coplanar overlapping surfaces: each ray takes one of them (Embree's choice); every pixel
  then has the exact value of one of the two surfaces. Touching surfaces leak no light.

Closed forms: a plane under a point (or tiny Lambertian) source has no interreflection, so
L = ρ·E/π exactly, E = I·cos θ/d² (point) or Φ·cos θ·cos θ'/(π d²) (small Lambertian
disc of flux Φ, error O((s/d)²)). The integrating sphere: L = ρΦ/(πA(1−ρ)) (see
test_solver_accuracy.py).
"""

import math
import time
import warnings

import numpy as np
import pytest

from lsadphoto.errors import BadInputError
from lsadphoto.geometry import IdealFisheyeProjection, PinholeProjection
from lsadphoto.solver import (
    AreaLuminaire,
    Scene,
    SolverWarning,
    camera_to_world,
    load_scene,
    render,
    scene_from_dict,
    simulate,
)
from lsadphoto.solver.examples import canonical_room

K_SIGMA = 3.0
#: A point source over a plane is exact up to float32 output rounding (measured 2e-4 in
#: test_solver_accuracy.py, the gather adds terms in float64).
EXACT = 1e-4


def _one_line(exc_info):
    text = str(exc_info.value)
    assert "\n" not in text and "Traceback" not in text
    return text


def _plane(materials=None, surfaces=None, luminaires=None):
    return scene_from_dict({
        "materials": materials or {"grey": {"reflectance": 0.5}},
        "surfaces": surfaces or [{"type": "polygon", "material": "grey",
                                  "vertices": [[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]]}],
        "luminaires": luminaires or [{"type": "point", "position": [0, 0, 2], "intensity": 100}]})


# --- refused input -------------------------------------------------------------------------

@pytest.mark.parametrize("vertices, message", [
    ([[0, 0, 0], [1, 0, 0], [2, 0, 0]], "degenerate polygon (zero area)"),
    ([[0, 0, 0], [0, 0, 0], [1, 1, 1]], "at least 3 distinct vertices"),
    ([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.5]], "not coplanar"),
])
def test_degenerate_polygons_are_refused(vertices, message):
    with pytest.raises(BadInputError) as exc:
        _plane(surfaces=[{"type": "polygon", "material": "grey", "vertices": vertices}])
    assert message in _one_line(exc) and "surfaces[0]" in str(exc.value)


def test_degenerate_triangles_are_refused():
    tris = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 0], [1, 1, 1], [2, 2, 2]]], float)
    with pytest.raises(BadInputError) as exc:
        Scene(tris, [0, 0], ["g"], [0.5], [0, -1], [AreaLuminaire("L", 1.0, np.array([0]))])
    assert "degenerate" in _one_line(exc)


@pytest.mark.parametrize("rho", [1.0, 1.5, -0.1])
def test_reflectance_outside_zero_one_is_refused(rho):
    with pytest.raises(BadInputError) as exc:
        _plane(materials={"grey": {"reflectance": rho}})
    assert "materials.grey: reflectance must be in [0, 1)" in _one_line(exc)
    tris = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], float)
    with pytest.raises(BadInputError, match=r"reflectance must be in \[0, 1\)"):
        Scene(tris, [0], ["g"], [rho], [0], [AreaLuminaire("L", 1.0, np.array([0]))])


@pytest.mark.parametrize("name, text, message", [
    ("bad.ies", "this is not a photometric file\n1 2 3\n", "no TILT= line"),
    ("bad.ldt", "x\n", "type_indicator"),
    ("empty.ies", "", "empty.ies"),
])
def test_unparsable_photometric_file_is_one_line(tmp_path, name, text, message):
    (tmp_path / name).write_text(text)
    (tmp_path / "scene.toml").write_text(f"""
[materials]
grey = {{ reflectance = 0.5 }}
[[surfaces]]
type = "polygon"
material = "grey"
vertices = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
[[luminaires]]
type = "point"
position = [0.5, 0.5, 1]
photometry = "{name}"
""")
    with pytest.raises(BadInputError) as exc:
        load_scene(tmp_path / "scene.toml")
    text = _one_line(exc)
    assert text.startswith(f"{tmp_path / 'scene.toml'}: luminaires[0]: ") and message in text


# --- warnings, never hangs -----------------------------------------------------------------

def test_unreachable_target_error_warns_and_stops():
    room = canonical_room(size=16)
    t0 = time.perf_counter()
    # The smallest target allowed (MIN_TARGET_ERROR = 1e-4), beyond 8192 chains' reach.
    with pytest.warns(SolverWarning, match=r"target_error 0.0001 not reached: achieved 0\.\d+ with 8192 chains"):
        store = simulate(room, target_error=1e-4, max_samples=8192, samples=8192, seed=1)
    assert time.perf_counter() - t0 < 30
    p = store.provenance
    assert p["target_reached"] is False and p["chains"] == 8192
    assert 1e-4 < p["achieved_relative_error"] < 0.01


def test_reached_target_error_does_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        store = simulate(canonical_room(size=16), target_error=0.05, seed=1)
    assert store.provenance["target_reached"] is True


@pytest.fixture(scope="module")
def room_store():
    return simulate(canonical_room(size=16), samples=4096, seed=1)


def test_eye_outside_the_room_warns(room_store):
    view = room_store.scene.views[0]
    with pytest.warns(SolverWarning, match=r"eye at \(8, 2, 1.2\) m sees surfaces but no light at all"):
        lmap = render(room_store, view.projection, position=[8, 2, 1.2],
                      rotation=camera_to_world([-1, 0, 0], [0, 0, 1]), nodes_per_pixel=8)
    assert np.nanmax(lmap.luminance) == 0  # it sees the unlit outside of the walls


def test_eye_in_a_wall_warns(room_store):
    view = room_store.scene.views[0]
    with pytest.warns(SolverWarning, match=r"eye at \(0, 2, 1.2\) m lies on a surface"):
        render(room_store, view.projection, position=[0, 2, 1.2], rotation=view.rotation,
               nodes_per_pixel=8)


def test_eye_inside_a_solid_warns():
    scene = scene_from_dict({
        "materials": {"grey": {"reflectance": 0.5}},
        "surfaces": [{"type": "box", "min": [-1, -1, 0], "max": [1, 1, 1], "facing": "outward",
                      "material": "grey"},
                     {"type": "polygon", "material": "grey",
                      "vertices": [[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]]}],
        "luminaires": [{"type": "point", "position": [0, 0, 2.5], "intensity": 100}]})
    store = simulate(scene, samples=1024, seed=1)
    with pytest.warns(SolverWarning, match="sees surfaces but no light"):
        render(store, IdealFisheyeProjection("equidistant", 7.5, 7.5, 8, 180, 16, 16),
               position=[0, 0, 0.5], rotation=camera_to_world([1, 0, 0], [0, 0, 1]),
               nodes_per_pixel=8)


def test_open_room_is_legal_and_light_escapes():
    # The canonical room without its ceiling: no warning (warnings are errors here), the
    # panels' light reflected upwards leaves, pixels looking out through the open top are
    # 0, and the walls are darker than in the closed room.
    closed = canonical_room(size=16)
    keep = closed.normals[:, 2] > -0.5  # drop the ceiling (inward normal −z) …
    keep |= closed.emitter >= 0         # … but keep the panels (they face down too)
    lums = [AreaLuminaire(l.name, l.flux, np.searchsorted(np.flatnonzero(keep), l.triangles))
            for l in closed.area_luminaires]
    open_room = Scene(closed.triangles[keep], closed.material[keep], closed.material_names,
                      closed.reflectance, closed.emitter[keep], lums, views=closed.views)
    assert len(open_room.triangles) == len(closed.triangles) - 2
    view = closed.views[0]
    up = camera_to_world([0, 0, 1], [1, 0, 0])
    means = []
    for scene in (closed, open_room):
        store = simulate(scene, samples=8192, seed=1)
        side = render(store, view.projection, position=view.position, rotation=view.rotation,
                      nodes_per_pixel=32)
        means.append(side.provenance)
        top = render(store, PinholeProjection(40, 40, 3.5, 3.5, 8, 8), position=[3, 2, 1.5],
                     rotation=up, nodes_per_pixel=8)
    assert np.all(top.luminance == 0)  # straight up through the missing ceiling
    closed_mean, open_mean = (p["field_mean_luminance"] for p in means)
    assert open_mean < closed_mean - K_SIGMA * math.hypot(*(p["field_mean_standard_error"] for p in means))


# --- extremes ------------------------------------------------------------------------------

def test_bright_sphere_rho_099_finite_time_and_closed_form():
    # ρ = 0.99: weighted chains live ≈ ln(0.05)/ln(0.99) ≈ 300 bounces before roulette
    # (≈ 400 nodes per chain). Energy balance makes the area-mean exitance of any closed
    # enclosure exact, and the sphere's kernel is uniform, so L = ρΦ/(πA(1−ρ)) holds
    # point-wise; the tolerance is 3σ and 3 % (looser than the 1 % of ρ ≤ 0.95 in
    # test_solver_accuracy.py because 1/(1 − ρ) = 100 amplifies the chains' noise; measured
    # below 1 %).
    trimesh = pytest.importorskip("trimesh")
    ico = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    tris = np.asarray(ico.triangles)[:, ::-1]
    cap = tris.mean(axis=1)[:, 2] > 0.95
    scene = Scene(tris, np.zeros(len(tris), int), ["wall"], [0.99], np.where(cap, 0, -1),
                  [AreaLuminaire("cap", 1000.0, np.flatnonzero(cap))])
    t0 = time.perf_counter()
    store = simulate(scene, samples=1024, seed=1)
    elapsed = time.perf_counter() - t0
    assert elapsed < 60
    assert store.nodes / store.chains > 200  # long chains, as expected
    lmap = render(store, IdealFisheyeProjection("equidistant", 7.5, 7.5, 8, 180, 16, 16),
                  position=[0, 0, 0], rotation=camera_to_world([0, 0, -1], [0, 1, 0]),
                  nodes_per_pixel=64, near_distance=0.3, seed=2)
    p = lmap.provenance
    expected = 0.99 * 1000.0 / (math.pi * scene.areas.sum() * 0.01)
    assert abs(p["field_mean_luminance"] - expected) <= K_SIGMA * p["field_mean_standard_error"]
    assert abs(p["field_mean_luminance"] / expected - 1) <= 0.03


def test_single_tiny_luminaire():
    # A 1 cm × 1 cm Lambertian panel of 0.01 lm, 2 m above a grey plane (ρ = 0.5), facing
    # down: E(r) = Φ·cos θ·cos θ'/(π d²) with cos θ = cos θ' = h/d, L = ρE/π; the panel's
    # size changes it by O((s/d)²) ≈ 2.5e-5. Only the direct light exists (a plane does not
    # see itself), so the map must be the closed form to the subsampling noise of the
    # source nodes: with every source node gathered ("all") it is exact to 1e-3.
    s = 0.005
    scene = scene_from_dict({
        "materials": {"grey": {"reflectance": 0.5}},
        "surfaces": [{"type": "polygon", "material": "grey",
                      "vertices": [[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]]}],
        "luminaires": [{"type": "area", "flux": 0.01, "shape": {"type": "polygon", "vertices": [
            [-s, -s, 2], [-s, s, 2], [s, s, 2], [s, -s, 2]]}}]})
    store = simulate(scene, samples=1024, seed=1)
    proj = PinholeProjection(8, 8, 3.5, 3.5, 8, 8)
    lmap = render(store, proj, position=[0, 0, 3], rotation=camera_to_world([0, 0, -1], [0, 1, 0]),
                  nodes_per_pixel="all")
    rows, cols = proj.pixel_grid()
    d = proj.directions(rows, cols) @ camera_to_world([0, 0, -1], [0, 1, 0]).T
    point = np.array([0, 0, 3]) + d * (3 / -d[..., 2:3])
    h2 = 4.0 + point[..., 0] ** 2 + point[..., 1] ** 2
    expected = 0.5 / math.pi * 0.01 * (4.0 / h2) / (math.pi * h2)
    assert np.allclose(lmap.luminance, expected, rtol=1e-3)


def test_coplanar_overlapping_surfaces_take_one_value_per_pixel():
    # Two overlapping coplanar squares (ρ 0.3 and 0.6) under a 100 cd point: each pixel is
    # exactly the closed form of one of them, L = ρ·I·cos θ/(π d²).
    scene = scene_from_dict({
        "materials": {"a": {"reflectance": 0.3}, "b": {"reflectance": 0.6}},
        "surfaces": [{"type": "polygon", "material": "a",
                      "vertices": [[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]]},
                     {"type": "polygon", "material": "b",
                      "vertices": [[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]]}],
        "luminaires": [{"type": "point", "position": [0, 0, 2], "intensity": 100}]})
    proj = PinholeProjection(8, 8, 7.5, 7.5, 16, 16)
    rot = camera_to_world([0, 0, -1], [0, 1, 0])
    lmap = render(simulate(scene, samples=256, seed=1), proj, position=[0, 0, 3], rotation=rot)
    rows, cols = proj.pixel_grid()
    d = proj.directions(rows, cols) @ rot.T
    point = np.array([0, 0, 3]) + d * (3 / -d[..., 2:3])
    r2 = 4.0 + point[..., 0] ** 2 + point[..., 1] ** 2
    base = 100 * (2 / np.sqrt(r2)) / (math.pi * r2)
    ratio = lmap.luminance / base
    assert np.all(np.isclose(ratio, 0.3, rtol=EXACT) | np.isclose(ratio, 0.6, rtol=EXACT))


def test_touching_surfaces_leak_no_light():
    # The plane split into two squares that touch along x = 0 gives the one-plane values.
    half = [{"type": "polygon", "material": "grey", "vertices": v} for v in (
        [[-5, -5, 0], [0, -5, 0], [0, 5, 0], [-5, 5, 0]], [[0, -5, 0], [5, -5, 0], [5, 5, 0], [0, 5, 0]])]
    proj = PinholeProjection(8, 8, 7.5, 7.5, 16, 16)
    rot = camera_to_world([0, 0, -1], [0, 1, 0])
    maps = [render(simulate(sc, samples=256, seed=1), proj, position=[0.001, 0, 3], rotation=rot).luminance
            for sc in (_plane(), _plane(surfaces=half))]
    assert np.allclose(maps[0], maps[1], rtol=EXACT)


def test_grazing_view_is_the_closed_form():
    # Eye 1 cm above the plane looking along it: rows just below the horizon see the plane
    # at grazing angles down to ≈ 0.1°; Lambertian luminance does not depend on the view
    # angle, so every pixel is ρ·I·cos θ/(π d²) of the point it sees.
    proj = PinholeProjection(200, 200, 7.5, 7.5, 16, 16)  # ±2.1°
    rot = camera_to_world([1, 0, -0.035], [0, 0, 1])
    eye = np.array([-4.0, 0.3, 0.01])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lmap = render(simulate(_plane(), samples=256, seed=1), proj, position=eye, rotation=rot)
    rows, cols = proj.pixel_grid()
    d = proj.directions(rows, cols) @ rot.T
    t = -eye[2] / d[..., 2]
    point = eye + d * t[..., None]
    seen = (d[..., 2] < 0) & (np.abs(point[..., 0]) < 5) & (np.abs(point[..., 1]) < 5)
    assert seen.sum() > 50
    grazing = np.degrees(np.arcsin(-d[..., 2][seen]))
    assert grazing.min() < 0.5
    r2 = (point[..., 0] ** 2 + point[..., 1] ** 2 + 4.0)[seen]
    expected = 0.5 * 100 * (2 / np.sqrt(r2)) / (math.pi * r2)
    assert np.allclose(lmap.luminance[seen], expected, rtol=EXACT)
    assert np.all(lmap.luminance[~seen & np.isfinite(lmap.luminance)] == 0)  # sky: nothing
