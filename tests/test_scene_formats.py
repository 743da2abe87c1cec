"""One ``read_scene`` for every scene format, and Radiance views from ``.vf`` files and ``-vf``.

References: Radiance's own view files (../shared/realdata/radiance) and Radiance's vwrays
(pyradiance's binary) for the pixel rays of the same view.
"""

import subprocess
import sys

import numpy as np
import pytest

from lsadphoto.errors import BadInputError
from lsadphoto.io import read_exr
from lsadphoto.solver import load_scene, read_scene, read_view
from lsadphoto.solver.examples import canonical_room_rad, canonical_room_toml
from .conftest import radiance_tool, realdata


def test_read_scene_dispatches_on_the_file_ending(tmp_path):
    (tmp_path / "room.toml").write_text(canonical_room_toml(size=16))
    (tmp_path / "room.rad").write_text(canonical_room_rad())
    toml, rad = read_scene(tmp_path / "room.toml"), read_scene(tmp_path / "room.rad")
    assert np.array_equal(toml.triangles, load_scene(tmp_path / "room.toml").triangles)
    # the same room written in both formats (solver.examples): same flux and surface areas
    assert rad.total_flux == pytest.approx(toml.total_flux, rel=1e-12)
    assert rad.areas.sum() == pytest.approx(toml.areas.sum(), rel=1e-12)
    # views given as [[views]] tables (the TOML structure) or as View objects, in that order
    table = {"name": "t", "position": [1, 2, 1.2], "line_of_sight": [1, 0, 0]}
    view = read_view("-vta -vp 1 2 1.2 -vd 1 0 0 -vh 180 -vv 180", 8, 8, name="v")
    both = read_scene(tmp_path / "room.rad", views=[table, view])
    assert [v.name for v in both.views] == ["v", "t"]
    assert np.allclose(both.views[0].rotation, both.views[1].rotation)


@pytest.mark.parametrize("name, options, message", [
    ("chair.obj", {}, r"a bare mesh has no materials or luminaires; reference it from a TOML scene"),
    ("room.dwg", {}, r"unknown scene format '.dwg'"),
    ("room.toml", {"tessellation_error": 0.01}, r"tessellation_error apply to Radiance scenes \(.rad\) only"),
])
def test_read_scene_refuses_in_one_line(tmp_path, name, options, message):
    (tmp_path / name).write_text("")
    with pytest.raises(BadInputError, match=message):
        read_scene(tmp_path / name, **options)


@pytest.mark.realdata
@pytest.mark.parametrize("file, size", [("cornell_box/cornell.vf", (20, 20)), ("renders/inside.vf", (24, 24)),
                                        ("renders/fish.vf", (36, 35))])
def test_view_files_give_radiance_s_pixel_rays(file, size):
    # Peer: Radiance's vwrays -vf on the same file (pixel centres, -pa 0), rays in world
    # coordinates (fish.vf: 180° × 175° at 5° per pixel, as our fisheye needs equal scales). Both evaluate the same closed forms in double precision from the file's
    # 6-digit numbers: directions agree to 1e-9.
    path = realdata(f"radiance/{file}")
    width, height = size
    view = read_view(f"-vf {path.name}", width, height, base=path.parent)
    rays = subprocess.run([radiance_tool("vwrays"), "-ff", "-x", str(width), "-y", str(height), "-pa", "0",
                           "-vf", str(path)], capture_output=True, check=True).stdout
    rays = np.frombuffer(rays, dtype=np.float32).reshape(height, width, 6).astype(float)
    rows, cols = np.meshgrid(np.arange(height), np.arange(width), indexing="ij")
    ours = view.projection.directions(rows.ravel(), cols.ravel()) @ view.rotation.T
    theirs = rays[..., 3:].reshape(-1, 3)
    valid = np.isfinite(ours).all(axis=1) & (np.linalg.norm(theirs, axis=1) > 0)
    assert valid.mean() > 0.7
    assert np.allclose(rays[..., :3].reshape(-1, 3)[valid], view.position, atol=1e-5)
    # vwrays -ff writes float32: 1e-7 relative
    assert np.abs(ours[valid] - theirs[valid]).max() < 2e-7


def test_options_after_vf_override_the_file(tmp_path):
    (tmp_path / "a.vf").write_text("rvu -vtv -vp 1 2 3 -vd 0 1 0 -vu 0 0 1 -vh 60 -vv 40\n")
    view = read_view("-vf a.vf -vp 0 0 1", 30, 20, base=tmp_path)
    assert view.position.tolist() == [0.0, 0.0, 1.0]
    assert np.allclose(view.rotation @ [0, 0, 1], [0, 1, 0])
    with pytest.raises(BadInputError, match=r"view file .*missing.vf does not exist"):
        read_view("-vf missing.vf", 30, 20, base=tmp_path)


def test_cli_renders_a_radiance_scene_through_a_view_file(tmp_path):
    (tmp_path / "room.rad").write_text(canonical_room_rad())
    (tmp_path / "eye.vf").write_text("rview -vta -vp 1 2 1.2 -vd 1 0 0 -vu 0 0 1 -vh 180 -vv 180\n")
    proc = subprocess.run([sys.executable, "-m", "lsadphoto.cli", "render", str(tmp_path / "room.rad"),
                           f"--view=-vf {tmp_path / 'eye.vf'}", "--size", "8x8", "--samples", "512",
                           "-o", str(tmp_path / "m.exr")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    pose = read_exr(tmp_path / "m.exr").provenance["view_pose"]
    assert pose["vp"] == [1.0, 2.0, 1.2] and np.allclose(pose["vd"], [1, 0, 0])


@pytest.mark.parametrize("specularity, message", [("0", None), (".05", None),
                                                  ("1.05", "specularity must be in [0, 1], got 1.05")])
def test_survey_manifest_reads_radiance_models_through_read_scene(tmp_path, specularity, message):
    # The survey checks a view's model when the manifest is read (one line naming the view
    # and the field); a Radiance model is read there by the same read_scene.
    from lsadphoto.survey import load_manifest
    from .test_survey import MANIFEST, make_survey

    path = make_survey(tmp_path, MANIFEST.replace('scene = "model.toml"', 'scene = "model.rad"', 1))
    room = canonical_room_rad().replace("0 0 5 0.5 0.5 0.5 0 0", f"0 0 5 0.5 0.5 0.5 {specularity} 0", 1)
    assert room != canonical_room_rad() or specularity == "0"
    (path.parent / "model.rad").write_text(room)
    if message is None:
        load_manifest(path)
        return
    with pytest.raises(BadInputError) as info:
        load_manifest(path)
    assert "\n" not in str(info.value)
    assert "view 'single': model.scene: " in str(info.value) and message in str(info.value)


def test_rif_project_reads_its_materials_scene_and_views(tmp_path):
    # A rad project file: the same scene as the .rad that includes the same files, and views
    # whose picture sizes are rpict's with square pixels (peer: vwrays -d -pa 1, which prints
    # the resolution rpict would use for the same view and RESOLUTION).
    (tmp_path / "m.mat").write_text("void plastic wall 0 0 5 .5 .5 .5 0 0\nvoid light lamp 0 0 3 9 9 9\n")
    (tmp_path / "lamp.rad").write_text("lamp polygon panel 0 0 12 1 1 2.9 1 3 2.9 3 3 2.9 3 1 2.9\n")
    (tmp_path / "eye.vf").write_text("rview -vta -vp 2 2 1.2 -vd 1 0 0 -vh 180 -vv 150\n")
    views = {"def": "-vf eye.vf", "top": "-vtv -vp 2 2 2.5 -vd 0 0 -1 -vu 0 1 0 -vh 60 -vv 40",
             "hemi": "-vth -vp 2 2 1 -vd 0 0 1 -vu 0 1 0 -vh 170 -vv 170"}
    (tmp_path / "p.rif").write_text(
        "# project\nOCTREE = p.oct\nmaterials = m.mat\nscene = \"!genbox wall box 4 4 3 -i\" \\\n  lamp.rad\n"
        "RES = 64 48\nQUAL = Med\n" + "".join(f"view = {k} {v}\n" for k, v in views.items()))
    (tmp_path / "same.rad").write_text("!xform m.mat\n!genbox wall box 4 4 3 -i\n!xform lamp.rad\n")
    rif, rad = read_scene(tmp_path / "p.rif"), read_scene(tmp_path / "same.rad")
    assert np.array_equal(rif.triangles, rad.triangles) and rif.total_flux == rad.total_flux
    assert [v.name for v in rif.views] == list(views)
    for view, options in zip(rif.views, views.values()):
        size = subprocess.run([radiance_tool("vwrays"), "-d", "-x", "64", "-y", "48", "-pa", "1",
                               *options.split()], capture_output=True, text=True, check=True, cwd=tmp_path).stdout
        assert f"-x {view.projection.width} -y {view.projection.height}" == size.strip()


@pytest.mark.realdata
def test_radiance_s_own_rif_is_refused_for_its_striped_torus():
    # its glossy floor (plastic of specularity 0.02) is read now; the torus's mixfunc is not
    path = realdata("radiance/renders/glass.rif")
    with pytest.raises(BadInputError, match=r"torus.rad:19 .*cone 'torus.1': mixfunc 'striped' .* is not supported"):
        read_scene(path)
