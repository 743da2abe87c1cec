"""Provenance built once (lsadphoto._provenance) and carried by every result."""

import hashlib

import numpy as np

from lsadphoto import _provenance
from lsadphoto._provenance import build_provenance, file_record
from lsadphoto._version import __version__


def test_file_record_hashes_small_files_and_sizes_large_ones(tmp_path, monkeypatch):
    small = tmp_path / "ratings.csv"
    small.write_bytes(b"scene,observer,rating\na,1,3\n")
    record = file_record(small)
    assert record["sha256"] == hashlib.sha256(small.read_bytes()).hexdigest()  # independent digest
    assert record["size_bytes"] == 28 and record["modified"].endswith("+00:00")
    monkeypatch.setattr(_provenance, "HASH_LIMIT", 10)
    assert file_record(small)["sha256"] is None and file_record(small)["size_bytes"] == 28
    assert file_record(tmp_path / "gone.dng") == {"path": str(tmp_path / "gone.dng"), "size_bytes": None,
                                                   "modified": None, "sha256": None}


def test_core_keys(tmp_path):
    p = build_provenance(arguments={"seed": 3}, inputs=[], profile="cam", calibration_factor=12.0,
                         calibration_uncertainty=0.02)
    assert p["lsadphoto_version"] == __version__ == p["versions"]["lsadphoto"]
    assert p["versions"]["numpy"] == np.__version__
    assert p["arguments"] == {"seed": 3} and p["profile"] == "cam" and p["inputs"] == []
    assert (p["calibration_factor"], p["calibration_uncertainty"]) == (12.0, 0.02)


def test_score_and_solver_records_carry_the_core():
    from lsadphoto.geometry import PinholeProjection
    from lsadphoto.luminance_map import LuminanceMap
    from lsadphoto.metrics.score import score_map
    from lsadphoto.solver import simulate
    from lsadphoto.solver.examples import canonical_room

    lmap = LuminanceMap(np.full((24, 32), 100.0, np.float32), projection=PinholeProjection(30, 30, 15.5, 11.5, 32, 24),
                        calibration_factor=2.5, calibration_uncertainty=0.03, calibrated=True)
    p = score_map(lmap).provenance
    assert {"versions", "timestamp", "lsadphoto_version"} <= set(p)
    assert (p["calibration_factor"], p["calibration_uncertainty"]) == (2.5, 0.03)
    store = simulate(canonical_room(size=8), samples=256, seed=1)
    assert store.provenance["arguments"]["seed"] == 1 and "versions" in store.provenance
