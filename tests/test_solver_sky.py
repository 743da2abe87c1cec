"""Distant sources (sun, sky: Radiance ``source`` with gensky/gendaylit skies) against
independent references: Radiance's own evaluation of its .cal sky functions (rcalc), the
closed forms of an unobstructed plane (Moon & Spencer's overcast sky, E = E_n cos θ for the
sun), and rtrace in a daylit room."""

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lsadphoto.constants import RADIANCE_RGB_LUMINANCE_WEIGHTS
from lsadphoto.errors import BadInputError
from lsadphoto.geometry import IdealFisheyeProjection
from lsadphoto.solver import camera_to_world, load_store, read_scene, render, simulate
from lsadphoto.solver.direct import direct_illuminance
from lsadphoto.solver.engine import engine_for
from lsadphoto.solver.formats.radiance import RTRACE_UNBIASED, read_radiance_scene
from lsadphoto.solver.grids import CalculationGrid, grid_illuminance
from lsadphoto.solver.integrators.path_tracer import render_path_traced
from lsadphoto.solver.sky import sky_luminance_shape

from .conftest import radiance_tool

EXAMPLE = Path(__file__).resolve().parents[1] / "data_samples" / "radiance"
GLOWS = ("skyfunc glow sky_glow 0 0 4 1 1 1 0\nsky_glow source sky 0 0 4 0 0 1 180\n"
         "skyfunc glow ground_glow 0 0 4 1 1 1 0\nground_glow source ground 0 0 4 0 0 -1 180\n")
# a grey floor of 400 m² at z = 0 (it hides the ground glow from points on it)
FLOOR = ("void plastic grey 0 0 5 .5 .5 .5 0 0\n"
         "grey polygon floor 0 0 12 -10 -10 0  10 -10 0  10 10 0  -10 10 0\n")


def _radiance(args, cwd=None, **kwargs):
    folder = os.path.dirname(radiance_tool("rtrace"))
    env = dict(os.environ, RAYPATH=os.pathsep.join([".", os.path.join(folder, "..", "lib")]),
               PATH=os.pathsep.join([folder, os.environ.get("PATH", "")]))
    return subprocess.run([radiance_tool(args[0]), *args[1:]], env=env, check=True, cwd=cwd,
                          capture_output=True, timeout=600, **kwargs).stdout


def _sky_arguments(words):
    """(function, calfile, reals) of the brightfunc skyfunc in gensky/gendaylit output."""
    lines = words.decode().split("\n")
    k = next(i for i, line in enumerate(lines) if "brightfunc skyfunc" in line)
    function, calfile = lines[k + 1].split()[1:3]
    reals = [float(v) for v in lines[k + 3].split()[1:]]
    return function, calfile, reals


@pytest.mark.parametrize("generator", [
    ["gensky", "3", "21", "12", "+s", "-a", "52", "-o", "-5", "-m", "0"],   # CIE clear with sun
    ["gensky", "6", "21", "9", "-s", "-a", "40", "-o", "0", "-m", "0"],     # CIE clear, no sun
    ["gensky", "3", "21", "12", "+i", "-a", "52", "-o", "-5", "-m", "0"],   # CIE intermediate
    ["gensky", "3", "21", "12", "-c", "-B", "100"],                          # CIE overcast
    ["gensky", "3", "21", "12", "-u", "-B", "100"],                          # uniform
    ["gendaylit", "3", "21", "12", "-a", "52", "-o", "-5", "-m", "0", "-W", "600", "100"],  # Perez
])
def test_sky_functions_are_radiance_s(generator):
    function, calfile, reals = _sky_arguments(_radiance(generator))
    d = np.random.default_rng(3).normal(size=(400, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:50, 2] = np.abs(d[:50, 2]) * 0.02  # near the horizon, where the ground is blended in
    defs = ";".join(f"A{k + 1}={v!r}" for k, v in enumerate(reals))
    rays = "".join(f"{x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in d)
    # Acos and Exp as Radiance's rayinit.cal defines them (rcalc lacks rayinit.cal's arg())
    library = "Acos(x)=acos(if(x-1,1,if(-1-x,-1,x)));Exp(x)=if(-x-100,0,exp(x))"
    out = _radiance(["rcalc", "-e", defs, "-e", library, "-e", "Dx=$1;Dy=$2;Dz=$3", "-f", calfile,
                     "-e", f"$1={function}"], input=rays.encode())
    reference = np.array([float(v) for v in out.split()])
    # rcalc prints 6 significant digits: agreement to 1e-5 relative is Radiance's value
    np.testing.assert_allclose(sky_luminance_shape(function, calfile, reals, d), reference, rtol=1e-5)


def test_overcast_sky_lights_a_plane_as_moon_and_spencer(tmp_path):
    # CIE overcast sky L(θ) = L_z(1 + 2 cos θ)/3 over an unobstructed horizontal plane:
    # E_h = ∫ L cos θ dω = 7π/9 · L_z (Moon & Spencer 1942). The ground brightness (A3) is set
    # to the sky's horizon luminance L_z/3, so skybright.cal's horizon blend changes E_h by
    # less than 1e-4 (2π∫(2/3)Dz²·w dDz with the blend weight w < 0.45 below Dz = 0.1).
    zenith = 100.0
    text = (f"void brightfunc skyfunc 2 skybr skybright.cal 0 3 2 {zenith} {zenith / 3}\n"
            + GLOWS + FLOOR)
    scene = read_radiance_scene(text)
    L_z = 179.0 * zenith
    E_h = 7 * math.pi / 9 * L_z
    n = 4000
    x = np.column_stack([np.random.default_rng(1).uniform(-1, 1, (n, 2)), np.zeros(n)])
    E, var = direct_illuminance(scene, engine_for(scene), x, np.tile([0, 0, 1.0], (n, 1)), samples=16,
                                block_ids=np.arange(n) // 256)
    se = math.sqrt(var.sum()) / n
    assert se < 0.003 * E_h
    # unbiased: within 4 standard errors (a failure rate of 6e-5 for a correct estimator)
    assert abs(E.mean() - E_h) < 4 * se, (E.mean() / E_h - 1, se / E_h)
    # The floor (ρ = 0.5, nothing above it) has L = ρE_h/π = 7/18·L_z, seen by every
    # estimator from 0.5 m above it; the zenith of the sky is L_z.
    cam = IdealFisheyeProjection("equidistant", 7.5, 7.5, 8.0, 90.0, 16, 16)
    position = np.array([0.0, 0.0, 0.5])
    down = camera_to_world([0, 0, -1], [0, 1, 0])
    store = simulate(scene, samples=4096, seed=2)
    maps = {"local": render(store, cam, position=position, rotation=down),
            "cache": render(store, cam, position=position, rotation=down, estimator="cache"),
            "path": render_path_traced(scene, cam, position=position, rotation=down, samples=32)}
    for name, lmap in maps.items():
        mean = lmap.provenance["field_mean_luminance"]
        err = lmap.provenance["field_mean_standard_error"]
        assert abs(mean - 7 / 18 * L_z) < 4 * err + 1e-6 * L_z, (name, mean / (7 / 18 * L_z) - 1, err)
    up = render(store, cam, position=position, rotation=camera_to_world([0, 0, 1], [0, 1, 0]))
    centre = float(np.asarray(up.luminance, float)[7:9, 7:9].mean())  # within 5.6° of the zenith
    assert centre == pytest.approx(L_z, rel=(1 - math.cos(math.radians(5.6))) * 2 / 3)
    # a store keeps its distant sources: the same map after saving and reading it back
    store.save(tmp_path / "sky.npz")
    again = render(load_store(tmp_path / "sky.npz"), cam, position=position, rotation=down)
    np.testing.assert_array_equal(again.luminance, maps["local"].luminance)


def test_sun_gives_its_normal_illuminance_times_cos_and_rtrace_s_value(tmp_path):
    sky = _radiance(["gensky", "-ang", "45", "30", "+s"]).decode()
    roof = "grey polygon roof 0 0 12 4 -1 1  6 -1 1  6 1 1  4 1 1\n"  # shades the points below it
    scene = read_radiance_scene(sky + FLOOR + roof)
    sun = scene.distant_sources[0]
    radiance = float(sky.split("void light solar")[1].split()[3])  # r = g = b in gensky's output
    E_n = 179.0 * radiance * 2 * math.pi * (1 - math.cos(math.radians(0.5 / 2)))  # L·Ω of a 0.5° disc
    assert sun.integral == pytest.approx(E_n, rel=1e-12)
    points = np.array([[0.0, 0.0, 0.0], [-3.0, 2.0, 0.0], [5.0, 0.0, 0.0]])
    up = np.tile([0, 0, 1.0], (3, 1))
    E, var = direct_illuminance(scene, engine_for(scene), points, up, samples=64)
    # Shadow rays sample the 0.5° disc, over which cos θ varies by ±0.3 %: within 4 of the
    # reported standard errors (the disc's mean of cos differs from cos 45° by < 1e-5).
    tolerance = 4 * np.sqrt(var[:2]) + 1e-5 * E_n
    assert np.all(np.abs(E[:2] - E_n * math.cos(math.radians(45))) < tolerance), E[:2] / E_n
    assert 0 < var[0] < (1e-3 * E[0]) ** 2
    assert E[2] == 0.0  # shaded
    octree = tmp_path / "sun.oct"
    (tmp_path / "sun.rad").write_text(sky + FLOOR + roof)
    octree.write_bytes(_radiance(["oconv", "sun.rad"], cwd=tmp_path))
    rays = "".join(f"{x} {y} {z + 1e-4} 0 0 1\n" for x, y, z in points)
    rgb = np.array(_radiance(["rtrace", "-h", "-I", "-ab", "0", "-dj", "0", str(octree)], cwd=tmp_path,
                             input=rays.encode()).split(), float).reshape(-1, 3)
    # rtrace prints 6 digits and takes the sun's centre direction (-dj 0)
    E_rtrace = 179.0 * rgb @ RADIANCE_RGB_LUMINANCE_WEIGHTS
    assert E_rtrace[2] == 0.0
    assert np.all(np.abs(E[:2] - E_rtrace[:2]) < tolerance + 2e-5 * E_rtrace[:2]), E[:2] / E_rtrace[:2]


def test_glow_with_a_radius_of_influence_is_the_same_emitter():
    # Radiance's radius only chooses how a glow is sampled (shadow rays within it,
    # interreflection beyond); its light is the same, so the solver's emitter is too.
    base = "void plastic grey 0 0 5 .5 .5 .5 0 0\ngrey polygon f 0 0 12 0 0 0 1 0 0 1 1 0 0 1 0\n"
    scenes = [read_radiance_scene(base + f"void glow g 0 0 4 5 5 5 {r}\ng sphere b 0 0 4 0 0 1 .1\n")
              for r in (0, 1.5)]
    assert scenes[0].area_luminaires[0].flux == scenes[1].area_luminaires[0].flux > 0
    np.testing.assert_array_equal(scenes[0].triangles, scenes[1].triangles)


@pytest.mark.slow
def test_daylit_room_matches_rtrace(tmp_path):
    # The worked example's room (south window, gensky sun and sky, sky and ground glows):
    # illuminance at five work-plane points, two of them in the sun patch, against rtrace
    # with pure Monte Carlo ambient sampling (-aa 0, no irradiance cache), 8 bounces, each
    # point traced 16 times for the reference's own noise (with 4 traces its standard error
    # came out 3× too small in some draws — 0.18 … 0.71 % for one point over 8 sets of 4 —
    # and z reached 5 where both estimates were within 0.2 %; 16 keep the estimate within
    # ≈ ±35 %, for ≈ 10 s of rtrace).
    scene = read_scene(EXAMPLE / "daylit_room.rad")
    points = np.array([[1, 1.5, .8], [2, 2.0, .8], [3, 2.5, .8], [3, 1.0, .8], [2, .5, .8]])
    octree = tmp_path / "room.oct"
    octree.write_bytes(_radiance(["oconv", "daylit_room.rad"], cwd=EXAMPLE))
    runs = 16
    rays = "".join(f"{x} {y} {z} 0 0 1\n" for x, y, z in points) * runs
    rgb = np.array(_radiance(["rtrace", "-h", "-I", "-ab", "8", "-ad", "4096", *RTRACE_UNBIASED,
                              str(octree)], cwd=EXAMPLE, input=rays.encode()).split(), float)
    E_ref = (179.0 * rgb.reshape(runs, len(points), 3) @ RADIANCE_RGB_LUMINANCE_WEIGHTS)
    ref, ref_se = E_ref.mean(axis=0), E_ref.std(axis=0, ddof=1) / math.sqrt(runs)
    store = simulate(scene, samples=2 ** 19, seed=4)
    grid = grid_illuminance(store, CalculationGrid("points", points, (1, len(points))), nodes=2 ** 17,
                            direct_samples=256, seed=1)
    ours, se = grid.illuminance.ravel(), grid.standard_error.ravel()
    z = (ours - ref) / np.hypot(se, ref_se)
    # both estimates are unbiased for the same model: within 4 combined standard errors each
    print("daylit room: ours/rtrace − 1", np.round(ours / ref - 1, 4), "z", np.round(z, 2),
          "σ_ours", np.round(se / ref, 4), "σ_rtrace", np.round(ref_se / ref, 4))
    assert np.all(np.abs(z) < 4), (ours / ref - 1, z)
    # and the errors are small enough for that to mean something: below 6 % of the values
    assert np.all(np.hypot(se, ref_se) < 0.06 * ref), (se / ref, ref_se / ref)


def _cli(*args):
    proc = subprocess.run([sys.executable, "-m", "lsadphoto.cli", *map(str, args)],
                          capture_output=True, text=True)
    return proc.returncode, proc.stderr


@pytest.mark.parametrize("sky, message", [
    ("void brightfunc skyfunc 2 skybright skybright.cal 0 3 2 10 3\n",
     "sky.rad:1: brightfunc 'skyfunc': skybright of skybright.cal is not supported on a source"),
    ("void brightfunc skyfunc 2 skybr nosuch.cal 0 3 2 10 3\n", "sky.rad:1: brightfunc 'skyfunc': nosuch.cal not found"),
])
def test_bad_sky_is_refused_in_one_line_with_exit_2(tmp_path, sky, message):
    (tmp_path / "sky.rad").write_text(sky + GLOWS + FLOOR)
    code, err = _cli("simulate", tmp_path / "sky.rad", "-o", tmp_path / "s.npz")
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "s.npz").exists()
    with pytest.raises(BadInputError, match=message.split(": ", 1)[1]):
        read_scene(tmp_path / "sky.rad")


def test_daylight_through_glass_and_in_a_mirror_local_estimate_matches_path_tracer():
    # a floor under a glass pane and beside a mirror, gensky's sun and sky with the glows:
    # the double local estimate with materials (sun and sky by next-event estimation through
    # the glass, the sky after delta reflections by sampled rays, sun light relayed by the
    # mirror by the light chains) against the independent path tracer, two views
    sky = _radiance(["gensky", "-ang", "50", "20", "+s"]).decode()
    text = (sky + GLOWS + FLOOR + "void glass pane 0 0 3 .9 .9 .9\nvoid mirror mir 0 0 3 .9 .9 .9\n"
            "pane polygon roof 0 0 12 -1 -1 1  1 -1 1  1 1 1  -1 1 1\n"
            "mir polygon m 0 0 12 2 -1 0  2 1 0  2 1 1.5  2 -1 1.5\n")
    scene = read_radiance_scene(text)
    cam = IdealFisheyeProjection("equidistant", 11.5, 11.5, 12.0, 150.0, 24, 24)
    position = np.array([0.0, 0.0, 0.5])
    for rotation in (camera_to_world([0, 0, -1], [0, 1, 0]), camera_to_world([1, 0, 0], [0, 0, 1])):
        a = render(scene, cam, position=position, rotation=rotation, samples=2 ** 16, seed=1)
        b = render_path_traced(scene, cam, position=position, rotation=rotation, samples=512, seed=2)
        pa, pb = a.provenance, b.provenance
        assert pa["estimator"] == "double local estimate (materials)"
        diff = pa["field_mean_luminance"] - pb["field_mean_luminance"]
        # both unbiased: field means within 4 combined standard errors (each below 1 %)
        se = math.hypot(pa["field_mean_standard_error"], pb["field_mean_standard_error"])
        assert abs(diff) < 4 * se and se < 0.01 * pb["field_mean_luminance"], (diff / pb["field_mean_luminance"], se)


def test_a_rotated_sky_turns_its_sun_and_its_sky_function(tmp_path):
    # !xform -rz 90 turns the sources' directions and the sky function's coordinates (its
    # pattern's transform), as Radiance's xform does: L_rotated(R·d) = L(d)
    sky = _radiance(["gensky", "3", "21", "10", "+s", "-a", "52", "-o", "-5", "-m", "0"]).decode() + GLOWS
    (tmp_path / "sky.rad").write_text(sky)
    (tmp_path / "plain.rad").write_text(sky + FLOOR)
    (tmp_path / "turned.rad").write_text("!xform -rz 90 sky.rad\n" + FLOOR)
    plain, turned = read_scene(tmp_path / "plain.rad"), read_scene(tmp_path / "turned.rad")
    rz = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    d = np.random.default_rng(2).normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    for a, b in zip(plain.distant_sources, turned.distant_sources):
        np.testing.assert_allclose(b.axis, rz @ a.axis, atol=1e-12)
        np.testing.assert_allclose(b.radiance(d @ rz.T), a.radiance(d), rtol=1e-9)


def test_daylight_renders_do_not_depend_on_chunking():
    # the distant sources' shadow rays draw from streams keyed by pixel block (and batch),
    # like every other sample: the same map for any chunk size and thread count
    scene = read_scene(EXAMPLE / "daylit_room.rad")
    cam = IdealFisheyeProjection("equidistant", 15.5, 15.5, 16.0, 180.0, 32, 32)
    pose = {"position": np.array([2.0, 2.8, 1.2]), "rotation": camera_to_world([0, -1, 0], [0, 0, 1])}
    store = simulate(scene, samples=2048, seed=3)
    a = render(store, cam, nodes_per_pixel=4, chunk_pixels=256, **pose)
    b = render(store, cam, nodes_per_pixel=4, chunk_pixels=1024, workers=2, **pose)
    np.testing.assert_array_equal(a.luminance, b.luminance)
    c = render_path_traced(scene, cam, samples=16, chunk_pixels=256, **pose)
    d = render_path_traced(scene, cam, samples=16, chunk_pixels=1024, **pose)
    np.testing.assert_array_equal(c.luminance, d.luminance)


def test_toml_sun_and_sky():
    # [[luminaires]] type = "sky" / "sun" in a TOML scene: the CIE overcast sky (ground at the
    # horizon's luminance, so the horizon blend is < 1e-4 of E_h, as above) and a sun of
    # given normal illuminance over an open plane: E_h = 7π/9·L_z + E_n·cos 45° (Moon &
    # Spencer; the disc's mean cos is within 1e-5 of cos 45°); a clear sky has its zenith
    # luminance as given (Radiance's skybright.cal function normalised at the zenith)
    from lsadphoto.solver import scene_from_dict

    L_z, E_n = 3000.0, 80000.0
    data = {"materials": {"grey": {"reflectance": 0.5}},
            "surfaces": [{"type": "polygon", "material": "grey",
                          "vertices": [[-10, -10, 0], [10, -10, 0], [10, 10, 0], [-10, 10, 0]]}],
            "luminaires": [{"type": "sky", "name": "sky", "model": "cie-overcast", "zenith_luminance": L_z,
                            "ground_luminance": L_z / 3},
                           {"type": "sun", "name": "sun", "direction": [0, -1, 1], "illuminance": E_n}]}
    scene = scene_from_dict(data)
    assert [s.name for s in scene.distant_sources] == ["sky", "sky ground", "sun"]
    assert scene.distant_sources[2].integral == pytest.approx(E_n, rel=1e-12)
    n = 2000
    E, var = direct_illuminance(scene, engine_for(scene), np.zeros((n, 3)), np.tile([0, 0, 1.0], (n, 1)),
                                samples=16, block_ids=np.arange(n) // 256)
    expected = 7 * math.pi / 9 * L_z + E_n * math.cos(math.radians(45))
    assert abs(E.mean() - expected) < 4 * math.sqrt(var.sum()) / n + 1e-4 * expected, E.mean() / expected - 1
    clear = {"type": "sky", "model": "cie-clear", "zenith_luminance": L_z, "sun_direction": [0.3, -0.5, 0.8]}
    sky = scene_from_dict({**data, "luminaires": [clear]}).distant_sources[0]
    # the horizon blend weight at the zenith is 2.01⁻²⁰ ≈ 1e-6
    assert sky.radiance(np.array([[0.0, 0.0, 1.0]]))[0] == pytest.approx(L_z, rel=1e-5)
    for bad, message in ((dict(clear, sun_direction=None), "needs its sun_direction"),
                         ({"type": "sun", "direction": [0, 0, 1]}, "give exactly one of 'illuminance'"),
                         ({"type": "sky", "model": "perez", "zenith_luminance": 1.0}, "model must be one of")):
        bad = {k: v for k, v in bad.items() if v is not None}
        with pytest.raises(BadInputError, match=message):
            scene_from_dict({**data, "luminaires": [bad]})
