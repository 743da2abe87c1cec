"""Furnace tests of the estimators: a lamp at the centre of a closed sphere (issue 14).

Inside a closed sphere of radius R whose wall reflects light independently of the angle of
incidence, every wall point receives the same irradiance E (symmetry), and energy balance
gives it in closed form. A spherical lamp of radius r and flux Φ at the centre puts
E₀ = Φ/(4πR²) on the wall directly. The wall reflects a Lambertian part ρ_d and a mirror part
s (angle-independent: Radiance's plastic and trans below their Fresnel threshold s < 0.018).
Of the diffusely reflected light the fraction f = r²/R² falls back on the lamp (its solid
angle πr²/R², cosine-weighted, over π) and is absorbed there (a ``light`` does not reflect);
the mirror sends the lamp's own light straight back into the lamp, and the wall's light
along chords that meet the wall at equal angles at both ends, so that the wall's luminance,
seen from any point inside away from the lamp and its mirror images, is the same L in every
direction: L = ρ_d E/π + s L. The irradiance is E₀ plus that luminance over the wall's solid
angle, E = E₀ + π L (1 − f), hence

    L = ρ_d E / (π (1 − s)),   E = E₀ / (1 − ρ_d (1 − f) / (1 − s)).

(An independent photon simulation of the same sphere, 400 000 photons, gives E/E₀ within
0.2 % of this.) With ρ → 1 the light travels through many bounces (≈ 10 here): the test of
an estimator's long paths, Russian roulette and material sampling that no single-bounce
reference reaches. The path tracer and the double local estimate take the same scene file
through the public functions users call.

The lamp is large (r = R/4) on purpose: the spheres are tessellated into flat facets, whose
normals deviate from the radius by up to ≈ 0.05 rad at this tessellation error; a mirror
facet returns the lamp's light to within ≈ 0.1 rad of the centre, which a lamp of
r/R = 0.025 would mostly not catch (measured: the estimators then land on the value for a
lamp that does not absorb its own reflection, +1.1 … +1.9 %).
"""

import math

import numpy as np
import pytest

from lsadphoto.geometry.pinhole import PinholeProjection
from lsadphoto.solver import camera_to_world, render
from lsadphoto.solver.formats import read_radiance_scene
from lsadphoto.solver.integrators.path_tracer import render_path_traced

R, R_LAMP = 2.0, 0.5
LAMP_RADIANCE = 10.0  # Radiance units; luminance 179 × 10 cd/m² (grey, so Y = 10)

WALLS = {
    # name: (Radiance material, diffuse reflectance ρ_d, mirror reflectance s)
    "lambertian 0.9": ("void plastic wall 0 0 5 0.9 0.9 0.9 0 0", 0.9, 0.0),
    "plastic mirror-like 0.8": ("void plastic wall 0 0 5 0.8 0.8 0.8 0.015 0", 0.8 * (1 - 0.015), 0.015),
    # trans: what it transmits leaves the sphere for good (nothing outside); it reflects
    # diffusely Y(C)(1 − s)(1 − τ) and mirrors s
    "trans 0.95, τ 0.3": ("void trans wall 0 0 7 0.95 0.95 0.95 0.01 0 0.3 0.5", 0.95 * 0.99 * 0.7, 0.01),
}


def _scene(material):
    return read_radiance_scene(
        f"void light lamp 0 0 3 {LAMP_RADIANCE} {LAMP_RADIANCE} {LAMP_RADIANCE}\n"
        f"lamp sphere bulb 0 0 4 0 0 0 {R_LAMP}\n"
        f"{material}\n"
        f"wall bubble shell 0 0 4 0 0 0 {R}\n")


def _closed_form(rho_d, s):
    flux = math.pi * 179.0 * LAMP_RADIANCE * 4 * math.pi * R_LAMP ** 2  # Lambertian sphere [lm]
    e0 = flux / (4 * math.pi * R ** 2)
    f = (R_LAMP / R) ** 2
    e = e0 / (1 - rho_d * (1 - f) / (1 - s))
    return rho_d * e / (math.pi * (1 - s))


def _view():
    # off-centre, looking sideways: the lamp and its mirror images (about the line through eye
    # and lamp) are outside the 60° field
    size = 12
    focal = size / (2 * math.tan(math.radians(30)))
    proj = PinholeProjection(fx=focal, fy=focal, cx=(size - 1) / 2, cy=(size - 1) / 2, width=size, height=size)
    return proj, np.array([1.0, 0.0, 0.0]), camera_to_world((0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


@pytest.mark.parametrize("wall", list(WALLS))
@pytest.mark.parametrize("estimator", ["path tracer", "local estimate"])
def test_lamp_in_a_closed_sphere_gives_the_closed_form(wall, estimator):
    material, rho_d, s = WALLS[wall]
    scene = _scene(material)
    proj, position, rotation = _view()
    if estimator == "path tracer":
        lmap = render_path_traced(scene, proj, position=position, rotation=rotation, samples=1024, seed=3)
    else:
        lmap = render(scene, proj, position=position, rotation=rotation, samples=40_000, seed=3,
                      nodes_per_pixel=64)
    expected = _closed_form(rho_d, s)
    mean = lmap.luminance.mean()
    sigma = lmap.provenance["field_mean_standard_error"]  # the estimator's own: 0.3–0.75 %
    # 3σ (fixed seeds; measured deviations −0.72 … +0.33 %, within 1.1σ), plus < 0.2 % for the
    # tessellated spheres (areas exact, ε = 1e-3 sagitta): an error of 2 % in E is caught
    assert abs(mean - expected) <= 3 * sigma + 2e-3 * expected, (mean, expected, sigma)
    # and no pixel strays far: the wall is uniform, so each pixel is the closed form within its
    # own error. Per-pixel errors from 16 batches are heavy-tailed (a few per cent of pixels
    # beyond 3σ, docs/accuracy.md; here at most 2 of 144 beyond 4σ, the largest 5.4σ)
    z = (lmap.luminance - expected) / np.hypot(lmap.uncertainty, 2e-3 * expected)
    assert np.mean(np.abs(z) > 4) <= 0.025 and np.all(np.abs(z) < 6), np.sort(np.abs(z).ravel())[-5:]
