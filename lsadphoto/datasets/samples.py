"""Make the bundled ``data_samples/`` and the demo camera profile (deterministic).

Run ``python -m lsadphoto.datasets.samples data_samples`` (or ``make samples``). Writes:

- ``office/office_{1,2,3}.dng``: a 3-frame bracket (f/5.6, ISO 100; 1/15, 1/500, 1/8000 s) of
  :func:`~lsadphoto.datasets.interior_scene` through the demo camera, with shot and read noise;
- ``office/spots.csv``: two spot-meter readings (row, col, cd/m²) on the grey target and the
  wall, computed from the true scene over the LS-100's 1° cone and rounded as its display does;
- ``flat/flat_{1,2}.dng``: flat-field frames of a uniform 40 cd/m² field for
  ``lsadphoto calibrate vignetting``;
- ``boards/board_{01…10}.png``: chessboard photographs (9 × 6 inner corners, 25 mm squares)
  through the demo camera's lens, for ``lsadphoto calibrate geometry``
  (:mod:`~lsadphoto.datasets.boards`);
- ``../calibration/synthetic-demo.toml``: the demo camera's profile;
- ``stations/``: the demo survey — six station halls (:mod:`~lsadphoto.datasets.stations`)
  rendered by the Monte Carlo solver through the demo camera and written as 2–3-frame DNG
  brackets, with two spot readings each, synthetic observers' ratings, the scene models
  (``models/*.toml``) and the survey manifest ``survey.toml``.
"""

import sys
from pathlib import Path

import numpy as np

from ..calibrate.geometric import ChessboardPattern
from ..calibrate.profile import CameraProfile, save_profile
from ..calibrate.vignetting import VignettingModel
from ..constants import LS100_ACCEPTANCE_ANGLE
from ..geometry.pinhole import PinholeProjection
from ..raw.bracket import NoiseModel
from .boards import chessboard_image, supersampled_directions
from .scenes import interior_scene, uniform_field
from .synthetic import SyntheticCamera, write_dng

DEMO_CAMERA = SyntheticCamera(width=640, height=424, vignetting=(-0.3, 0.05), read_noise=3.0,
                              full_well=30000.0, model="synthetic demo camera")
BRACKET = [(1 / 15, 5.6, 100), (1 / 500, 5.6, 100), (1 / 8000, 5.6, 100)]
SPOT_POSITIONS = [(0.62, 0.5), (0.85, 0.15)]  # fractions of rows, cols


def demo_scene():
    """The true luminance of the demo view [cd·m⁻²] (sensor resolution)."""
    return interior_scene((DEMO_CAMERA.height, DEMO_CAMERA.width))


def demo_profile():
    cam = DEMO_CAMERA
    return CameraProfile(
        id="synthetic-demo", camera=f"{cam.make} {cam.model}", lens=f"{cam.focal_length:g} mm rectilinear",
        sensor_width=cam.sensor_width, sensor_height=cam.sensor_height, width=cam.width, height=cam.height,
        focal_length=cam.focal_length,
        vignetting=VignettingModel(kind="polynomial", coefficients=list(cam.vignetting)),
        calibration_constant=cam.calibration_constant, calibration_constant_uncertainty=0.02,
        noise=NoiseModel(full_well=cam.full_well, read_noise=cam.read_noise),
        provenance={"source": "lsadphoto.datasets.samples: the synthetic camera's own parameters (exact)"},
    )


#: Directions sampling the spot meter's cone in :func:`meter_reading`: rings × azimuths.
METER_RINGS, METER_AZIMUTHS = 24, 64


def meter_reading(luminance, projection, row, col):
    """What an LS-100 would display aimed at (row, col): the cone mean, 3 significant digits.

    The meter's 1° cone is sampled directly — :data:`METER_RINGS` rings equally spaced in cos θ
    about the aim direction (equal solid angle each) times :data:`METER_AZIMUTHS` directions — and each direction
    is read at the sensor pixel it projects into. This is independent of
    :func:`lsadphoto.calibrate.spot.spot_cone` (pixel centres inside the cone, weighted by
    their solid angle), which the calibration uses: the bundled readings test it.
    """
    axis = np.asarray(projection.directions(row, col), np.float64)
    axis = axis / np.linalg.norm(axis)
    u = np.cross(axis, [0.0, 1.0, 0.0] if abs(axis[1]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    cos_half = np.cos(LS100_ACCEPTANCE_ANGLE / 2)
    cos_t = 1.0 - (np.arange(METER_RINGS) + 0.5) / METER_RINGS * (1.0 - cos_half)
    sin_t = np.sqrt(1.0 - cos_t**2)
    phi = (np.arange(METER_AZIMUTHS) + 0.5) * 2 * np.pi / METER_AZIMUTHS
    ring = np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * v
    directions = cos_t[:, None, None] * axis + sin_t[:, None, None] * ring[None]
    r, c = projection.project(directions)
    value = float(np.mean(luminance[np.rint(r).astype(int), np.rint(c).astype(int)]))
    return float(f"{value:.3g}")


#: The bundled chessboard: 9 × 6 inner corners, 25 mm squares (README's Quickstart).
BOARD = ChessboardPattern(9, 6, 25.0)
#: Board poses: Rodrigues vectors [rad] and centres [mm] in the camera frame — frontal, tilted
#: ±0.5 rad about each axis, pushed towards the four corners and turned towards the centre,
#: and turned in its plane (this spread recovers fx, fy to 0.1 %: tests/test_quickstart.py).
BOARD_POSES = [
    ((0.0, 0.0, 0.0), (0, 0, 380)),
    ((0.5, 0.0, 0.0), (0, 0, 380)),
    ((-0.5, 0.0, 0.0), (0, 0, 380)),
    ((0.0, 0.5, 0.0), (0, 0, 380)),
    ((0.0, -0.5, 0.0), (0, 0, 380)),
    ((-0.3, 0.3, 0.1), (-150, -90, 480)),
    ((0.3, 0.3, -0.1), (-150, 90, 480)),
    ((-0.3, -0.3, -0.1), (150, -90, 480)),
    ((0.3, -0.3, 0.1), (150, 90, 480)),
    ((0.1, 0.1, 0.5), (0, 0, 360)),
]


def demo_projection():
    """The demo camera's lens: the nominal pinhole of its sensor and focal length."""
    cam = DEMO_CAMERA
    return PinholeProjection.from_sensor(focal_length=cam.focal_length, sensor_width=cam.sensor_width,
                                         sensor_height=cam.sensor_height, width=cam.width, height=cam.height)


def make_board_samples(folder):
    """``boards/board_NN.png``: the chessboard at :data:`BOARD_POSES` through the demo lens."""
    import cv2

    out = Path(folder) / "boards"
    out.mkdir(parents=True, exist_ok=True)
    directions = supersampled_directions(demo_projection(), 3)
    for k, (rvec, centre) in enumerate(BOARD_POSES, start=1):
        image = chessboard_image(directions, rvec, centre, pattern=BOARD)
        if not cv2.imwrite(str(out / f"board_{k:02d}.png"), image, [cv2.IMWRITE_PNG_COMPRESSION, 9]):
            raise OSError(f"could not write {out / f'board_{k:02d}.png'}")


def make_samples(folder):
    folder = Path(folder)
    cam = DEMO_CAMERA
    rng = np.random.default_rng(20261123)
    scene = demo_scene()
    for i, (t, n, iso) in enumerate(BRACKET, start=1):
        raw = cam.expose(scene, exposure_time=t, f_number=n, iso=iso, rng=rng)
        write_dng(folder / "office" / f"office_{i}.dng", raw, cam, exposure_time=t, f_number=n, iso=iso)
    projection = demo_projection()
    lines = ["row,col,cd_m2"]
    for fr, fc in SPOT_POSITIONS:
        row, col = round(fr * cam.height), round(fc * cam.width)
        lines.append(f"{row},{col},{meter_reading(scene, projection, row, col):g}")
    (folder / "office" / "spots.csv").write_text("\n".join(lines) + "\n")
    flat = uniform_field((cam.height, cam.width), 40.0)
    for i in (1, 2):  # at the office bracket's aperture: a vignetting fit holds for its f-number
        raw = cam.expose(flat, exposure_time=1 / 30, f_number=5.6, iso=100, rng=rng)
        write_dng(folder / "flat" / f"flat_{i}.dng", raw, cam, exposure_time=1 / 30, f_number=5.6, iso=100)
    make_board_samples(folder)
    save_profile(demo_profile(), folder.parent / "calibration" / "synthetic-demo.toml")


#: Station views: (view id, layout, observer position [m], optical axis) — two views look
#: across the hall so that the survey has positions as well as layouts to compare.
STATION_VIEWS = [
    ("coves", "coves", None, None),
    ("panels", "panels", None, None),
    ("rows", "rows", None, None),
    ("mixed", "mixed", None, None),
    ("downlights", "downlights", None, None),
    ("sparse", "sparse", None, None),
]
#: Synthetic observers per view and their rating model (10-point scale): a comfort score
#: rising with Q and falling with pixel-UGR, plus each observer's own offset and noise.
N_OBSERVERS = 12
STATION_SPOTS = [(0.85, 0.5), (0.55, 0.08)]  # floor ahead, left wall (fractions of rows, cols)


def _bracket_times(luminance, *, f_number=4.0, iso=100, step=64.0):
    """Exposure times [s]: the longest puts the median at 20 % of full scale, then shorter
    by ``step`` until the brightest pixel stays below 80 %."""
    gain = iso / f_number**2 / DEMO_CAMERA.calibration_constant
    t = 0.2 / (float(np.median(luminance)) * gain)
    times = [t]
    while float(np.max(luminance)) * gain * times[-1] > 0.8:
        times.append(times[-1] / step)
    return times


def make_station_samples(folder, *, chains=60000, nodes_per_pixel=32, seed=20261123):
    """The demo survey of station halls (see the module notes); minutes of solver time."""
    import tomli_w

    from ..metrics.score import score_map
    from ..solver import camera_to_world, render, scene_from_dict, simulate
    from .stations import OBSERVER, station_scene

    folder = Path(folder) / "stations"
    cam = DEMO_CAMERA
    rng = np.random.default_rng(seed)
    projection = PinholeProjection.from_sensor(focal_length=cam.focal_length, sensor_width=cam.sensor_width,
                                               sensor_height=cam.sensor_height, width=cam.width, height=cam.height)
    half = projection.binned(2)
    rows_out, views = [], []
    for index, (view_id, layout, position, direction) in enumerate(STATION_VIEWS):
        spec = station_scene(layout)
        (folder / "models").mkdir(parents=True, exist_ok=True)
        (folder / "models" / f"{layout}.toml").write_text(tomli_w.dumps(spec))
        position = position or OBSERVER["position"]
        direction = direction or OBSERVER["direction"]
        store = simulate(scene_from_dict(spec), samples=chains, seed=seed + index)
        truth = render(store, half, position=position, rotation=camera_to_world(direction, OBSERVER["up"]),
                       nodes_per_pixel=nodes_per_pixel, seed=seed + index)
        # The render is at the superpixel resolution; each value covers its 2 × 2 sensor block.
        sensor = np.repeat(np.repeat(np.asarray(truth.luminance, np.float64), 2, axis=0), 2, axis=1)
        raws = []
        for k, t in enumerate(_bracket_times(sensor), start=1):
            raw = cam.expose(sensor, exposure_time=t, f_number=4.0, iso=100, rng=rng)
            name = f"{view_id}/{view_id}_{k}.dng"
            write_dng(folder / name, raw, cam, exposure_time=t, f_number=4.0, iso=100)
            raws.append(name)
        spots = []
        for fr, fc in STATION_SPOTS:
            row, col = round(fr * cam.height), round(fc * cam.width)
            spots.append({"row": row, "col": col, "cd_m2": meter_reading(sensor, projection, row, col)})
        score = score_map(truth)
        rows_out.append((view_id, score.values["q"], score.values["ugr_pixel"]))
        views.append({"id": view_id, "raw": raws, "spots": spots,
                      "ratings": f"{view_id}/ratings.csv",
                      "model": {"scene": f"models/{layout}.toml", "position": list(position),
                                "direction": list(direction), "up": list(OBSERVER["up"]),
                                "samples": 20000, "nodes_per_pixel": 8, "seed": 1}})
    q = np.array([r[1] for r in rows_out])
    ugr = np.array([np.nan_to_num(r[2], nan=10.0) for r in rows_out])
    comfort = 5.5 + 1.5 * (q - q.mean()) / q.std() - 0.8 * (ugr - ugr.mean()) / ugr.std()
    offsets = rng.normal(0.0, 0.5, N_OBSERVERS)
    for (view_id, _, _), c in zip(rows_out, comfort, strict=True):
        ratings = np.clip(np.round(2 * (c + offsets + rng.normal(0.0, 0.8, N_OBSERVERS))) / 2, 1, 10)
        lines = ["observer,rating"] + [f"observer{j + 1:02d},{r:g}" for j, r in enumerate(ratings)]
        (folder / view_id / "ratings.csv").write_text("\n".join(lines) + "\n")
    manifest = {"schema": "lsadphoto.survey/1", "name": "demo: six station halls",
                "description": "synthetic station halls rendered by the lsadphoto solver, photographed "
                               "by the synthetic demo camera; ratings from synthetic observers",
                "profile": "../../calibration/synthetic-demo.toml", "view": views}
    (folder / "survey.toml").write_text(tomli_w.dumps(manifest))


if __name__ == "__main__":
    target = sys.argv[1] if len(sys.argv) > 1 else "data_samples"
    make_samples(target)
    make_station_samples(target)
