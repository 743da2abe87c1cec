"""Shared fixtures: a synthetic camera, its DNGs, and the real-data folder."""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# Property tests draw the same examples on every run (CI reproducible, no flaky draws);
# set HYPOTHESIS_PROFILE=explore for fresh random examples while developing.
settings.register_profile("reproducible", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(__import__("os").environ.get("HYPOTHESIS_PROFILE", "reproducible"))

from lsadphoto.calibrate import CameraProfile
from lsadphoto.datasets import SyntheticCamera, interior_scene, write_dng

#: ../shared/realdata beside the repository (absent in a user's fresh clone).
REALDATA = Path(__file__).resolve().parents[2] / "shared" / "realdata"


def realdata(relative):
    """Path of a real-data file, or skip the test with a reason."""
    path = REALDATA / relative
    if not path.exists():
        pytest.skip(f"real data {relative} not available (../shared/realdata is absent)")
    return path


def skip_without_ahead_of_time_kernels():
    """Skip the test, with the build's own message, where this machine could not build the
    ahead-of-time kernels (no C compiler: lsadphoto._compiled then runs numba's JIT)."""
    from lsadphoto._compiled import cache_folder

    failed = cache_folder() / "build.failed"
    if failed.exists():
        lines = failed.read_text().strip().splitlines()
        pytest.skip("no ahead-of-time kernels on this machine: " + (lines[-1] if lines else "?"))


#: File name endings of camera RAW files looked for by :func:`raw_samples`.
RAW_SUFFIXES = (".dng", ".arw", ".cr2", ".cr3", ".nef", ".raf", ".orf", ".rw2", ".pef", ".srw")


def radiance_tool(name):
    """Path of a Radiance program that pyradiance ships (the test skips without it)."""
    import os

    pyradiance = pytest.importorskip("pyradiance")
    path = os.path.join(os.path.dirname(pyradiance.__file__), "bin", name)
    if not os.path.exists(path):
        pytest.skip(f"pyradiance ships no {name} binary on this platform")
    return path


def radiance_bin(program="rtrace"):
    """Folder of the Radiance programs that pyradiance ships (the test skips without
    ``program``)."""
    import os

    return os.path.dirname(radiance_tool(program))


#: Folder name, anywhere under a sample folder, of real RAW-named files that must be refused
#: (metadata-only copies, codings LibRaw cannot unpack); :func:`raw_samples` leaves them out.
REFUSED_FOLDER = "refused"


def _sample_files():
    folders = [REALDATA / "raw"]
    folders += [Path(p) for p in __import__("os").environ.get("LSADPHOTO_RAW_SAMPLES", "").split(
        __import__("os").pathsep) if p]
    found = []
    for folder in folders:
        if folder.is_dir():
            found += sorted(p for p in folder.rglob("*") if p.suffix.lower() in RAW_SUFFIXES)
    return found


def raw_samples():
    """Real camera RAW files: ../shared/realdata/raw and the folders in LSADPHOTO_RAW_SAMPLES
    (``os.pathsep``-separated; files of other people, never part of the repository), except
    those under a folder named ``refused`` (see :func:`refused_raw_samples`)."""
    return [p for p in _sample_files() if REFUSED_FOLDER not in p.parts]


def refused_raw_samples():
    """Real RAW-named files under a ``refused`` folder of the sample folders: files that must
    be refused in one line (e.g. ExifTool's test images, whose image data is stripped)."""
    return [p for p in _sample_files() if REFUSED_FOLDER in p.parts]


@pytest.fixture(scope="session", autouse=True)
def _geometry_cache_of_the_session(tmp_path_factory):
    """The geometry maps' disk cache (lsadphoto.geometry._map_cache) in a folder of this
    test session, not the user's cache (the score processes the tests start inherit it)."""
    import os

    if "LSADPHOTO_GEOMETRY_CACHE" in os.environ:  # the user's choice (e.g. off) stands
        yield
        return
    os.environ["LSADPHOTO_GEOMETRY_CACHE"] = str(tmp_path_factory.mktemp("geometry-cache"))
    yield
    del os.environ["LSADPHOTO_GEOMETRY_CACHE"]


@pytest.fixture
def camera():
    return SyntheticCamera(width=256, height=192)


@pytest.fixture
def profile_for():
    def make(camera, **kwargs):
        return CameraProfile(
            id="synthetic-test",
            sensor_width=camera.sensor_width,
            sensor_height=camera.sensor_height,
            width=camera.width,
            height=camera.height,
            focal_length=camera.focal_length,
            calibration_constant=camera.calibration_constant,
            **kwargs,
        )

    return make


@pytest.fixture
def shoot(tmp_path):
    """Write a DNG of a luminance map through a camera; returns its path."""
    counter = iter(range(10_000))

    def make(camera, luminance, *, exposure_time=1 / 125, f_number=4.0, iso=100, noise=False, seed=0,
             chromaticity=None, **dng):
        kwargs = {} if chromaticity is None else {"chromaticity": chromaticity}
        # exposure_time=None: expose at 1/125 s but leave the tag out of the DNG.
        raw = camera.expose(luminance, exposure_time=exposure_time or 1 / 125, f_number=f_number, iso=iso,
                            noise=noise,
                            rng=np.random.default_rng(seed), **kwargs)
        path = tmp_path / f"shot{next(counter)}.dng"
        write_dng(path, raw, camera, exposure_time=exposure_time, f_number=f_number, iso=iso, **dng)
        return path

    return make


def binned_truth(luminance, factor=2):
    rows, cols = (luminance.shape[0] // factor) * factor, (luminance.shape[1] // factor) * factor
    return luminance[:rows, :cols].reshape(rows // factor, factor, cols // factor, factor).mean(axis=(1, 3))


def smooth_mask(truth, radius=4, tolerance=0.01):
    """Pixels whose (2·radius+1)² neighbourhood varies by at most ``tolerance`` (relative)."""
    from scipy.ndimage import maximum_filter, minimum_filter

    size = 2 * radius + 1
    return maximum_filter(truth, size) <= (1 + tolerance) * minimum_filter(truth, size)


__all__ = ["raw_samples", "refused_raw_samples", "realdata", "binned_truth", "smooth_mask", "interior_scene"]


def pytest_terminal_summary(terminalreporter):
    """Count of fuzzed mutants per reader and command (tests/test_fuzz.py records them as the
    user property ``fuzz_mutants``, which pytest-xdist carries back from its workers)."""
    counts = {}
    for reports in terminalreporter.stats.values():
        for report in reports:
            if getattr(report, "when", None) != "call":
                continue
            for key, value in getattr(report, "user_properties", ()):
                if key == "fuzz_mutants":
                    name, n = value
                    counts[name] = counts.get(name, 0) + n
    if counts:
        terminalreporter.write_sep("-", f"fuzz: {sum(counts.values())} mutated files read (per reader and command)")
        for name in sorted(counts):
            terminalreporter.write_line(f"{counts[name]:6d}  {name}")
