"""Accuracy of the solver against closed forms and against an independent estimator.

References
----------
Integrating sphere: for a closed sphere of area A with uniform Lambertian reflectance ρ and
a Lambertian emitter of flux Φ that is part of its wall, the kernel cos θ cos θ'/r² is
1/(4R²) for every pair of wall points, so every reflection spreads uniformly and the
luminance of every non-emitting wall point is L = ρΦ/(πA(1 − ρ)) (direct ρΦ/(πA) plus
the interreflected part; Walsh 1958, *Photometry*, §9; FORMULAS.md Part B §6).
Point source over a plane: L = ρ·I(γ)·cos θ/(π d²) (inverse-square and cosine laws).
"""

import math

import numpy as np
import pytest

from lsadphoto.geometry import IdealFisheyeProjection, PinholeProjection
from lsadphoto.solver import (
    AreaLuminaire,
    Photometry,
    PointLuminaire,
    Scene,
    camera_to_world,
    render,
    render_path_traced,
    scene_from_dict,
    simulate,
)
from lsadphoto.solver.examples import canonical_room
from lsadphoto.solver.photometry import luminaire_frame

#: Statistical tolerance in standard errors, and the relative accuracy asked of the solver.
K_SIGMA = 3.0
REL_TOL = 0.01


def sphere_scene(rho, *, flux=1000.0, subdivisions=4):
    """Inside of an icosphere of radius 1 m; the facets with centroid z > 0.97 m emit."""
    trimesh = pytest.importorskip("trimesh")
    ico = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    tris = np.asarray(ico.triangles)[:, ::-1]  # inward-facing
    cap = tris.mean(axis=1)[:, 2] > 0.97
    return Scene(tris, np.zeros(len(tris), int), ["wall"], [rho], np.where(cap, 0, -1),
                 [AreaLuminaire("cap", flux, np.flatnonzero(cap))], name="integrating sphere")


#: Looking straight down from the centre: the lower hemisphere, far from the emitting cap.
DOWN = camera_to_world([0, 0, -1], [0, 1, 0])
FISHEYE = IdealFisheyeProjection("equidistant", 15.5, 15.5, 16.0, 180.0, 32, 32)
#: A large ε (0.3 R) makes the near-field share large: clamping at this ε loses a known
#: fraction (below), which the unbiased treatment must recover.
EPS = 0.3


def sphere_view_mean(rho, near_field, seed, store=None):
    scene = sphere_scene(rho) if store is None else store.scene
    store = simulate(scene, samples=8192, seed=seed) if store is None else store
    lmap = render(store, FISHEYE, position=[0, 0, 0], rotation=DOWN, near_field=near_field,
                  near_distance=EPS, nodes_per_pixel=64, seed=seed + 100)
    p = lmap.provenance
    expected = rho * 1000.0 / (math.pi * scene.areas.sum() * (1 - rho))
    return p["field_mean_luminance"], p["field_mean_standard_error"], expected, lmap


@pytest.mark.parametrize("rho", [0.0, 0.5, 0.8, 0.95])
def test_integrating_sphere_unbiased(rho):
    # Geometry: the icosphere (5120 facets, edge ≈ 0.063 R) has the polyhedron's area A
    # (used here, 0.12 % below 4πR²); its facet normals tilt by ≤ 0.04 rad from the radius,
    # which changes the kernel only in second order, O(δ²) ≈ 2e-3 point-wise at most and
    # far less in the view mean — inside the 1 % tolerance. Statistics: 8192 weighted
    # chains, 64 nodes per pixel and batch, 16 batches.
    mean, se, expected, lmap = sphere_view_mean(rho, "unbiased", seed=1)
    if rho == 0:
        assert mean == 0 and np.nanmax(lmap.luminance) == 0
        return
    assert abs(mean - expected) <= K_SIGMA * se
    assert abs(mean / expected - 1) <= REL_TOL
    assert lmap.provenance["near_field_biased"] is False


def test_clamping_is_biased_in_a_bright_sphere():
    # Clamping 1/r² at ε loses, of the interreflected part, the share of wall within
    # chord distance ε weighted by 1 − r²/ε²: ∫₀^ε (1 − r²/ε²)·2πr dr/(4πR²) = ε²/(8R²).
    # The interreflected part is ρ of the total here, so the expected bias is −ρε²/8 ≈ −1.07 %.
    rho = 0.95
    store = simulate(sphere_scene(rho), samples=8192, seed=2)
    mean_u, se_u, expected, _ = sphere_view_mean(rho, "unbiased", seed=2, store=store)
    mean_c, se_c, _, lmap = sphere_view_mean(rho, "clamp", seed=2, store=store)
    bias = mean_c / expected - 1
    assert lmap.provenance["near_field_biased"] is True
    assert bias < -K_SIGMA * se_c / expected                       # measurably low …
    assert abs(bias + rho * EPS**2 / 8) <= K_SIGMA * se_c / expected  # … by the predicted amount
    assert abs(mean_u - expected) <= K_SIGMA * se_u                 # unbiased: within 3σ …
    assert abs(mean_u / expected - 1) < abs(bias)                  # … and better than clamped


def test_point_luminaire_over_a_plane():
    # Floor of ρ = 0.5, nothing else; a point luminaire 2 m above it with I(γ) = 100 cd·cos γ.
    # Every chain's source node is the same point with coefficient 1, and floor nodes see
    # the floor edge-on, so both estimators are exact up to the 1° intensity table (bilinear
    # interpolation of cos: ≤ 4e-5 relative) and float32 output: tolerance 2e-4.
    rho, h, i0 = 0.5, 2.0, 100.0
    table = Photometry.from_function(lambda c, g: i0 * np.clip(np.cos(g), 0.0, None))
    floor = scene_from_dict({
        "materials": {"grey": {"reflectance": rho}},
        "surfaces": [{"type": "polygon", "material": "grey",
                      "vertices": [[-10, -10, 0], [10, -10, 0], [10, 10, 0], [-10, 10, 0]]}],
        "luminaires": [{"type": "point", "position": [0, 0, h], "intensity": 1.0}],
    })
    floor.point_luminaires[0] = PointLuminaire(
        "cosine", np.array([0.0, 0.0, h]), table, luminaire_frame([0, 0, -1], [1, 0, 0]))
    camera = PinholeProjection(12.0, 12.0, 11.5, 11.5, 24, 24)
    position = np.array([0.5, 0.3, 4.0])
    rotation = camera_to_world([0, 0, -1], [0, 1, 0])
    rows, cols = camera.pixel_grid()
    d = camera.directions(rows, cols) @ rotation.T
    hit = position + (-position[2] / d[..., 2])[..., None] * d
    dist2 = hit[..., 0] ** 2 + hit[..., 1] ** 2 + h * h
    cos = h / np.sqrt(dist2)
    expected = rho * i0 * cos * cos / (math.pi * dist2)
    store = simulate(floor, samples=2048, seed=4)
    dle = render(store, camera, position=position, rotation=rotation)
    pt = render_path_traced(floor, camera, position=position, rotation=rotation, samples=16)
    for lmap in (dle, pt):
        assert np.allclose(lmap.luminance, expected, rtol=2e-4, atol=0)
        assert np.all(lmap.uncertainty <= 2e-4 * expected)


def test_isotropic_point_luminaire_from_toml_over_a_plane():
    # I = Φ/(4π) = 100 cd isotropic; L = ρ·I·cos θ/(π d²) straight below: 0.5·100/(π·4)
    scene = scene_from_dict({
        "materials": {"grey": {"reflectance": 0.5}},
        "surfaces": [{"type": "disc", "centre": [0, 0, 0], "normal": [0, 0, 1], "radius": 5,
                      "material": "grey"}],
        "luminaires": [{"type": "point", "position": [0, 0, 2], "flux": 400 * math.pi}],
    })
    camera = PinholeProjection(100.0, 100.0, 0.0, 0.0, 1, 1)
    store = simulate(scene, samples=256, seed=0)
    lmap = render(store, camera, position=[0, 0, 3], rotation=camera_to_world([0, 0, -1], [0, 1, 0]))
    assert lmap.luminance[0, 0] == pytest.approx(0.5 * 100 / (math.pi * 4), rel=1e-6)


def test_double_local_estimate_agrees_with_path_tracing_in_the_canonical_room():
    # Two independent unbiased estimators of the same pixels (the same x_p per pixel):
    # the field means must agree within their combined 3σ, and per pixel the z-scores
    # must look like standard normal ones (16-batch standard errors have a t-like spread,
    # so |z| > 4 is allowed in ≤ 1 % of pixels and the mean z² in 0.6 … 1.6).
    room = canonical_room(size=32)
    view = room.views[0]
    store = simulate(room, samples=16384, seed=3)
    dle = render(store, view.projection, position=view.position, rotation=view.rotation,
                 nodes_per_pixel=64, seed=5)
    pt = render_path_traced(room, view.projection, position=view.position,
                            rotation=view.rotation, samples=64, seed=7)
    a, b = dle.provenance, pt.provenance
    diff = a["field_mean_luminance"] - b["field_mean_luminance"]
    assert abs(diff) <= K_SIGMA * math.hypot(a["field_mean_standard_error"], b["field_mean_standard_error"])
    assert abs(diff) / b["field_mean_luminance"] < REL_TOL
    sigma = np.hypot(dle.uncertainty, pt.uncertainty)
    ok = np.isfinite(sigma) & (sigma > 0)          # luminaire pixels are exact in both
    z = (dle.luminance[ok] - pt.luminance[ok]) / sigma[ok]
    assert np.mean(np.abs(z) > 4) <= 0.01
    assert 0.6 <= np.mean(z * z) <= 1.6
    # the luminaires themselves: L = Φ/(πA) exactly in both
    lum = room.area_luminaires[0].luminance(room)
    assert np.nanmax(dle.luminance) == pytest.approx(lum, rel=1e-6)
    assert np.nanmax(pt.luminance) == pytest.approx(lum, rel=1e-6)


IES = """IESNA:LM-63-2002
[TEST] synthetic downlight for lsadphoto solver tests
TILT=NONE
1 1000 1 3 1 1 2 0.6 0.3 0.0
1 1 100
0 45 90
0
1000 707.10678 0
"""


@pytest.mark.parametrize("extent", ["[0, 0]", None])
def test_photometric_luminaire_over_a_plane(tmp_path, extent):
    # IES type C file: I(γ) = 1000, 707.1, 0 cd at γ = 0, 45, 90° (bilinear in γ), opening
    # 0.3 m (C0) × 0.6 m (C90). As a point ([0, 0]) the answer is exact; with its opening the
    # emission points are uniform on the rectangle, and the reference is the same average
    # by a 40 × 40 midpoint rule (independent of the solver; error < 1e-4 for this smooth
    # integrand), compared within 3 standard errors and 1 %.
    from lsadphoto.solver import load_scene
    from lsadphoto.solver.photometry import read_photometry

    (tmp_path / "down.ies").write_text(IES)
    h, rho = 2.5, 0.4
    text = f"""
[materials]
grey = {{ reflectance = {rho} }}
[[surfaces]]
type = "polygon"
material = "grey"
vertices = [[-20, -20, 0], [20, -20, 0], [20, 20, 0], [-20, 20, 0]]
[[luminaires]]
type = "point"
position = [0, 0, {h}]
photometry = "down.ies"
"""
    if extent:
        text += f"extent = {extent}\n"
    path = tmp_path / "scene.toml"
    path.write_text(text)
    scene = load_scene(path)
    phot = read_photometry(tmp_path / "down.ies")
    assert scene.point_luminaires[0].flux == pytest.approx(phot.luminous_flux, rel=1e-12)
    camera = PinholeProjection(6.0, 6.0, 3.5, 3.5, 8, 8)
    position = np.array([0.2, -0.1, 4.0])
    rotation = camera_to_world([0, 0, -1], [0, 1, 0])
    rows, cols = camera.pixel_grid()
    d = camera.directions(rows, cols) @ rotation.T
    hit = position + (-position[2] / d[..., 2])[..., None] * d
    if extent:
        sx = sy = np.zeros(1)
    else:
        sx = (np.arange(40) + 0.5) / 40 * phot.length - phot.length / 2
        sy = (np.arange(40) + 0.5) / 40 * phot.width - phot.width / 2
    ex, ey = np.meshgrid(sx, sy, indexing="ij")
    v = hit[..., None, None, :] - np.stack([ex, ey, np.full_like(ex, h)], axis=-1)
    r = np.linalg.norm(v, axis=-1)
    gamma = np.arccos(np.clip(-v[..., 2] / r, -1, 1))
    c = np.arctan2(v[..., 1], v[..., 0])
    expected = (rho / math.pi * phot.intensity(c, gamma) * (-v[..., 2] / r) / r**2).mean(axis=(-1, -2))
    store = simulate(scene, samples=8192, seed=6)
    lmap = render(store, camera, position=position, rotation=rotation)
    if extent:
        assert np.allclose(lmap.luminance, expected, rtol=1e-5)
    else:
        err = lmap.luminance - expected
        # 64 pixels: a few may lie beyond 3σ by chance (expected 0.17 of 64)
        assert np.mean(np.abs(err) > K_SIGMA * lmap.uncertainty + 1e-6 * expected) <= 0.05
        assert np.all(np.abs(err) <= REL_TOL * expected)


def test_luminous_opening_is_seen_with_its_luminance(tmp_path):
    # Looking at the IES luminaire's 0.3 m × 0.6 m opening from below and obliquely: the
    # opening's luminance is I(γ)/(A·cos γ) (uniform emission over the rectangle), with
    # I(γ) bilinear between the file's 0° and 45° values; a point luminaire stays invisible.
    from lsadphoto.solver import load_scene

    (tmp_path / "down.ies").write_text(IES)
    text = """
[materials]
grey = { reflectance = 0.4 }
[[surfaces]]
type = "polygon"
material = "grey"
vertices = [[-20, -20, 0], [20, -20, 0], [20, 20, 0], [-20, 20, 0]]
[[luminaires]]
type = "point"
position = [0, 0, 2.5]
photometry = "down.ies"
"""
    (tmp_path / "s.toml").write_text(text)
    scene = load_scene(tmp_path / "s.toml")
    eye = np.array([0.5, 0.0, 0.5])
    camera = PinholeProjection(100.0, 100.0, 0.0, 0.0, 1, 1)
    rotation = camera_to_world(np.array([0, 0, 2.5]) - eye, [1, 0, 0])
    store = simulate(scene, samples=256, seed=0)
    cos_g = 2.0 / math.hypot(0.5, 2.0)
    gamma = math.degrees(math.acos(cos_g))
    intensity = 1000 + (707.10678 - 1000) * gamma / 45
    expected = intensity / (0.3 * 0.6 * cos_g)
    for lmap in (render(store, camera, position=eye, rotation=rotation),
                 render_path_traced(scene, camera, position=eye, rotation=rotation, samples=16)):
        assert lmap.luminance[0, 0] == pytest.approx(expected, rel=1e-6)
        assert lmap.uncertainty[0, 0] == 0
    (tmp_path / "s.toml").write_text(text + "extent = [0, 0]\n")
    point = load_scene(tmp_path / "s.toml")
    lmap = render(simulate(point, samples=256), camera, position=eye, rotation=rotation)
    assert lmap.luminance[0, 0] == 0  # the ray leaves the open scene: nothing seen


def test_nearest_emitting_opening_wins(tmp_path):
    # Three openings of the downlight (0.3 m × 0.6 m) on the z axis, an eye below looking up
    # it: the nearest that emits towards the eye is seen, L = I(0)/A = 1000 cd/(0.18 m²)
    # (closed form; the farthest, at twice the multiplier, would give twice that); one turned to face up (nadir +z) emits nothing downwards (γ = 180°:
    # the file's 0 beyond 90°) and does not hide the ones behind it; a surface hit before
    # every opening hides them all; a ray beside the rectangles sees none.
    from lsadphoto.solver import load_scene
    from lsadphoto.solver.integrators.eye import luminous_openings

    (tmp_path / "down.ies").write_text(IES)
    lum = """
[[luminaires]]
type = "point"
position = [0, 0, {z}]
photometry = "down.ies"
nadir = [0, 0, {nz}]
multiplier = {m}
"""
    text = ("[materials]\ngrey = { reflectance = 0.4 }\n[[surfaces]]\ntype = \"polygon\"\n"
            "material = \"grey\"\nvertices = [[-20, -20, 0], [20, -20, 0], [20, 20, 0], [-20, 20, 0]]\n"
            + lum.format(z=3.0, nz=-1, m=2) + lum.format(z=2.0, nz=1, m=1) + lum.format(z=2.5, nz=-1, m=1))
    (tmp_path / "s.toml").write_text(text)
    scene = load_scene(tmp_path / "s.toml")
    eye = np.array([0.0, 0.0, 1.0])
    d = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.6, 0.0, 0.8]])
    out = luminous_openings(scene, eye, d, np.array([np.inf, 1.2, np.inf]))
    assert out[0] == pytest.approx(1000 / (0.3 * 0.6), rel=1e-12)
    assert np.isnan(out[1]) and np.isnan(out[2])


def test_mixed_luminaires_double_local_estimate_agrees_with_path_tracing(tmp_path):
    # The canonical room lit by one Lambertian panel, the IES downlight (with its opening)
    # and an isotropic 50 cd point: point-luminaire nodes now feed interreflections and
    # the near field too. Independent estimators, field means within combined 3σ and 1 %.
    import tomllib

    from lsadphoto.solver.examples import canonical_room_toml

    (tmp_path / "down.ies").write_text(IES)
    data = tomllib.loads(canonical_room_toml(size=32))
    data["luminaires"] = data["luminaires"][:1] + [
        {"type": "point", "position": [4.5, 2.0, 2.5], "photometry": "down.ies"},
        {"type": "point", "position": [3.0, 3.0, 1.0], "intensity": 50.0},
    ]
    scene = scene_from_dict(data, base=tmp_path)
    view = scene.views[0]
    store = simulate(scene, samples=16384, seed=2)
    a = render(store, view.projection, position=view.position, rotation=view.rotation,
               nodes_per_pixel=64, seed=3).provenance
    b = render_path_traced(scene, view.projection, position=view.position,
                           rotation=view.rotation, samples=128, seed=4).provenance
    diff = a["field_mean_luminance"] - b["field_mean_luminance"]
    assert abs(diff) <= K_SIGMA * math.hypot(a["field_mean_standard_error"], b["field_mean_standard_error"])
    assert abs(diff) / b["field_mean_luminance"] < REL_TOL
