"""Scene model of the solver: TOML schema, triangulation, and one-line errors for bad files."""

import math

import numpy as np
import pytest

from lsadphoto.errors import BadInputError
from lsadphoto.solver import (
    Photometry,
    camera_to_world,
    load_scene,
    scene_from_dict,
)
from lsadphoto.solver.examples import canonical_room, canonical_room_toml
from lsadphoto.solver.scene import polygon_triangles

ROOM = """
[materials]
wall = { reflectance = 0.5 }

[[surfaces]]
type = "box"
min = [0, 0, 0]
max = [2, 2, 2]
material = "wall"

[[luminaires]]
type = "point"
position = [1, 1, 1]
intensity = 100
"""


def write(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_canonical_room_geometry():
    room = canonical_room(size=32)
    # 6 box faces + 4 luminaires, 2 triangles each
    assert room.triangles.shape == (20, 3, 3)
    assert room.total_flux == pytest.approx(12000.0)
    floor = np.isclose(room.triangles[:, :, 2], 0).all(axis=1)
    assert room.triangle_reflectance[floor] == pytest.approx(0.2)
    assert np.allclose(room.normals[floor], [0, 0, 1])  # inward
    emit = room.emitter >= 0
    assert np.allclose(room.normals[emit], [0, 0, -1])  # luminaires face down
    assert room.areas[emit].sum() == pytest.approx(4 * 0.36)
    # luminance of a 3000 lm, 0.36 m² Lambertian panel: Φ/(πA)
    assert room.area_luminaires[0].luminance(room) == pytest.approx(3000 / (math.pi * 0.36))
    assert room.size == pytest.approx(math.sqrt(36 + 16 + 9))


def test_load_scene_from_file_matches_text(tmp_path):
    path = write(tmp_path, canonical_room_toml(size=16))
    scene = load_scene(path)
    assert scene.name == "canonical room"
    assert scene.views[0].projection.shape == (16, 16)
    assert np.allclose(scene.views[0].rotation @ [0, 0, 1], [1, 0, 0])


def test_concave_polygon_area_and_orientation():
    # an L-shape of area 3 m², counter-clockwise seen from +z
    tris = polygon_triangles([[0, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0]])
    cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    assert 0.5 * np.linalg.norm(cross, axis=1).sum() == pytest.approx(3.0)
    assert np.all(cross[:, 2] > 0)
    # every triangle centroid lies inside the L (none in the missing square)
    c = tris.mean(axis=1)
    assert not np.any((c[:, 0] > 1) & (c[:, 1] > 1))


def test_disc_keeps_area_and_sphere_faces_inward(tmp_path):
    scene = scene_from_dict({
        "materials": {"m": {"reflectance": 0.3}},
        "surfaces": [
            {"type": "disc", "centre": [0, 0, 0], "normal": [0, 0, 1], "radius": 0.5, "material": "m"},
            {"type": "sphere", "centre": [0, 0, 0], "radius": 3.0, "subdivisions": 2,
             "facing": "inward", "material": "m"},
        ],
        "luminaires": [{"type": "point", "position": [0, 0, 1], "flux": 1000}],
    })
    disc = np.isclose(scene.triangles[:, :, 2], 0).all(axis=1)
    assert scene.areas[disc].sum() == pytest.approx(math.pi * 0.25, rel=1e-12)
    sphere = ~disc
    centroids = scene.triangles[sphere].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", centroids, scene.normals[sphere]) < 0)
    assert scene.point_luminaires[0].flux == pytest.approx(1000.0)


def test_mesh_from_obj(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    box = trimesh.creation.box(extents=[1, 1, 1])
    box.export(tmp_path / "box.obj")
    path = write(tmp_path, ROOM + """
[[surfaces]]
type = "mesh"
file = "box.obj"
material = "wall"
translate = [1, 1, 0.5]
""")
    scene = load_scene(path)
    assert len(scene.triangles) == 12 + 12
    assert scene.areas[12:].sum() == pytest.approx(6.0)


def test_point_luminaire_with_callable_distribution():
    table = Photometry.from_function(lambda c, g: 100 * np.clip(np.cos(g), 0, None))
    # flux of I₀·cos γ over the lower hemisphere is π·I₀; the 1° bilinear table is within 1e-4
    assert table.luminous_flux == pytest.approx(100 * math.pi, rel=1e-4)
    frame = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, -1.0]])
    assert table.evaluate(np.array([0, 0, -1.0]), frame) == pytest.approx(100)
    assert table.evaluate(np.array([0, 0, 1.0]), frame) == pytest.approx(0)
    rng = np.random.default_rng(0)
    d, w = table.sample(rng, 20000, frame)
    # directions in the lower hemisphere; mean weight 1 (importance weights)
    assert np.all(d[:, 2] <= 1e-12)
    assert w.mean() == pytest.approx(1.0, abs=0.01)


def test_camera_to_world_is_a_rotation():
    r = camera_to_world([1, 1, 0], [0, 0, 1])
    assert np.allclose(r.T @ r, np.eye(3))
    assert np.isclose(np.linalg.det(r), 1.0)
    assert np.allclose(r @ [0, -1, 0], [0, 0, 1])  # image up is world up


BAD = {
    "missing material field": ("""
[[surfaces]]
type = "polygon"
vertices = [[0,0,0],[1,0,0],[0,1,0]]
""", "surfaces[0]: missing required key 'material'"),
    "unknown material": (ROOM.replace('material = "wall"', 'material = "wood"'), "unknown material 'wood'"),
    "reflectance one": (ROOM.replace("0.5", "1.0"), "reflectance must be in [0, 1)"),
    "negative reflectance": (ROOM.replace("0.5", "-0.1"), "reflectance must be in [0, 1)"),
    "degenerate polygon": (ROOM + """
[[surfaces]]
type = "polygon"
material = "wall"
vertices = [[0,0,0],[1,0,0],[2,0,0]]
""", "degenerate polygon"),
    "non-planar polygon": (ROOM + """
[[surfaces]]
type = "polygon"
material = "wall"
vertices = [[0,0,0],[1,0,0],[1,1,0.5],[0,1,0]]
""", "not coplanar"),
    "unknown shape": (ROOM.replace('type = "box"', 'type = "cone"'), "surfaces[0].type must be one of 'polygon', 'box', 'disc', 'sphere', 'mesh', got 'cone'"),
    "box max below min": (ROOM.replace("max = [2, 2, 2]", "max = [2, -1, 2]"), "max must exceed min"),
    "no luminaires": (ROOM.split("[[luminaires]]")[0], "no luminaires"),
    "both flux and intensity": (ROOM + "flux = 5\n", "exactly one of"),
    "not toml": ("[[surfaces]\ntype=", "not a valid TOML scene"),
    "unknown top-level key": (ROOM + "\n[lights]\nx = 1\n", "unknown key 'lights'; valid: scene, materials, surfaces, luminaires, views"),
    "bad vector": (ROOM.replace("position = [1, 1, 1]", "position = [1, 1]"), "luminaires[0].position must have 3 elements, got 2"),
    "bad view": (ROOM + """
[[views]]
position = [1, 1, 1]
line_of_sight = [0, 0, 1]
up = [0, 0, 1]
""", "parallel"),
    "bad projection": (ROOM + """
[[views]]
position = [1, 1, 1]
line_of_sight = [1, 0, 0]
projection = { model = "fisheye-ideal", kind = "equidistant", fov_deg = 400, width = 8, height = 8 }
""", "fov_deg"),
    "missing mesh": (ROOM + """
[[surfaces]]
type = "mesh"
file = "nothere.obj"
material = "wall"
""", "does not exist"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scene_files_give_one_line_errors(tmp_path, case):
    text, message = BAD[case]
    path = write(tmp_path, text)
    with pytest.raises(BadInputError) as info:
        load_scene(path)
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_missing_scene_file(tmp_path):
    with pytest.raises(BadInputError, match="does not exist"):
        load_scene(tmp_path / "none.toml")


def test_emission_sampler_vectorised_over_luminaires():
    """Issue 13: emission drawn in one pass over all luminaires — each luminaire in proportion
    to its flux, triangles of an area luminaire in proportion to their area, point
    luminaires' intensities per distinct table equal to each luminaire's own."""
    from lsadphoto.solver.chains import EmissionSampler
    from lsadphoto.solver.store import KIND_COSINE, KIND_POINT

    table = [{"type": "point", "position": [1.0 + k, 1.0, 2.5], "intensity": 50.0, "multiplier": 1.0 + k,
              "nadir": [0, 0.3 * k, -1]} for k in range(3)]
    scene = scene_from_dict({
        "materials": {"w": {"reflectance": 0.5}},
        "surfaces": [{"type": "box", "min": [0, 0, 0], "max": [6, 4, 3], "facing": "inward", "material": "w"}],
        "luminaires": [
            {"type": "area", "flux": 1000.0, "shape": {"type": "polygon", "vertices":
             [[1, 1, 2.9], [1, 2, 2.9], [3, 2, 2.9], [3, 1, 2.9]]}},
            {"type": "area", "flux": 3000.0, "shape": {"type": "polygon", "vertices":
             [[4, 1, 2.9], [4, 1.5, 2.9], [5, 1.5, 2.9], [5, 1, 2.9]]}},
            *table,
            {"type": "point", "position": [5.0, 3.0, 2.5], "intensity": 80.0},
        ],
    })
    sampler = EmissionSampler(scene)
    n = 400_000
    src = sampler.sample(np.random.default_rng(5), n)
    flux = np.array([l.flux for l in scene.area_luminaires] + [l.flux for l in scene.point_luminaires])
    counts = np.concatenate([np.bincount(src["luminaire"][src["kind"] == KIND_COSINE], minlength=2),
                             np.bincount(src["luminaire"][src["kind"] == KIND_POINT], minlength=4)])
    p = flux / flux.sum()
    # binomial counts: within 4 standard deviations of n·p for each luminaire
    assert np.all(np.abs(counts - n * p) <= 4 * np.sqrt(n * p * (1 - p)))
    first = scene.area_luminaires[0].triangles
    tri = src["triangle"][(src["kind"] == KIND_COSINE) & (src["luminaire"] == 0)]
    share = np.array([(tri == t).mean() for t in first])
    a = scene.areas[first] / scene.areas[first].sum()
    assert np.all(np.abs(share - a) <= 4 * np.sqrt(a * (1 - a) / tri.size))
    dirs = np.random.default_rng(1).normal(size=(60, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    which = np.arange(60) % 4
    got = sampler.point_intensity(which, dirs)
    want = [scene.point_luminaires[k].intensity(d[None])[0] for k, d in zip(which, dirs)]
    np.testing.assert_allclose(got, want, rtol=1e-12)
    assert len(sampler.tables) == 4  # isotropic tables are made per luminaire


def test_luminaires_of_one_file_share_its_table(tmp_path):
    from lsadphoto.solver.chains import EmissionSampler

    ies = tmp_path / "a.ies"
    from lsadphoto.datasets.design import write_ies_cosine

    write_ies_cosine(ies, exponent=2, flux=1000.0, length=0.2, width=0.2)
    scene = scene_from_dict({
        "materials": {"w": {"reflectance": 0.5}},
        "surfaces": [{"type": "box", "min": [0, 0, 0], "max": [6, 4, 3], "facing": "inward", "material": "w"}],
        "luminaires": [{"type": "point", "position": [1.0 + k, 2.0, 2.9], "photometry": "a.ies"} for k in range(5)],
    }, base=tmp_path)
    assert len({id(l.photometry) for l in scene.point_luminaires}) == 1
    assert len(EmissionSampler(scene).tables) == 1
