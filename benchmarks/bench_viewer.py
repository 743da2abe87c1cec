"""The viewer at 24 megapixels: time to write the page, its size against the EXR, time to open.

Run: PYTHONPATH=. .venv/bin/python benchmarks/bench_viewer.py [OUT_DIR] (from the repository
root; needs Debian's chromium and chromium-driver and selenium for the browser part).

The map: a 6000 × 4000 px 180° equidistant fisheye (image-circle radius 1990 px), an
interior-like luminance field (a vertical gradient and two disk sources, as
``lsadphoto.datasets.disk_sources_scene`` makes them) with 2 % multiplicative noise, so that
its float32 values compress like a photo's, and NaN outside the image circle.
"""

import json
import math
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from lsadphoto.datasets import disk_sources_scene
from lsadphoto.geometry import IdealFisheyeProjection, pixel_geometry
from lsadphoto.io import read_map, write_exr
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.metrics.score import score_map
from lsadphoto.viewer import write_viewer


def make_map():
    cam = IdealFisheyeProjection("equidistant", 2999.5, 1999.5, 1990.0, 180.0, 6000, 4000)
    geometry = pixel_geometry(cam)
    d = geometry.directions
    sources = [(np.array([0.2, -0.6, 0.77]) / 1.0, 0.05, 15000.0),
               (np.array([-0.5, -0.5, 0.71]) / 1.0, 0.04, 9000.0)]
    sources = [(v / np.linalg.norm(v), r, L) for v, r, L in sources]
    disk = disk_sources_scene(np.nan_to_num(d), background=0.0, sources=sources)
    rng = np.random.default_rng(0)
    field = 40.0 + 160.0 * (1.0 - np.nan_to_num(d[..., 1]) ** 2)
    luminance = np.where(disk > 0, disk, field) * rng.normal(1.0, 0.02, field.shape)
    luminance = np.where(geometry.valid, luminance, np.nan).astype(np.float32)
    return LuminanceMap(luminance, projection=cam, calibrated=True, calibration_uncertainty=0.05)


def browser_cpu_seconds(profile):
    """CPU time [s] (user + system) of the chromium processes of this profile so far: the
    load of a shared machine stretches wall-clock times but not this."""
    import os

    total = 0
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
            if profile.encode() not in cmdline:
                continue
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += int(fields[11]) + int(fields[12])  # utime, stime [clock ticks]
    return total / os.sysconf("SC_CLK_TCK")


def open_in_browser(page, lmap):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    profile = tempfile.mkdtemp(prefix="lsadphoto-bench-")
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run",
                 "--window-size=1280,1000", f"--user-data-dir={profile}"):
        options.add_argument(flag)
    session = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)
    session.set_script_timeout(300)
    try:
        start = time.perf_counter()
        session.get(page.resolve().as_uri())
        loaded = time.perf_counter() - start
        state = session.execute_async_script(
            "const done = arguments[0]; const wait = () => window.lsadViewer ? "
            "window.lsadViewer.ready.then((v) => done({decode: v.decodeMs, render: v.renderMs,"
            " workers: v.decodeWorkers}),"
            "(e) => done({error: String(e)})) : setTimeout(wait, 20); wait();")
        ready = time.perf_counter() - start
        cpu = browser_cpu_seconds(profile)
        rng = np.random.default_rng(1)
        rows = rng.integers(0, lmap.shape[0], 1000).tolist()
        cols = rng.integers(0, lmap.shape[1], 1000).tolist()
        got = session.execute_script(
            "return arguments[0].map((r, k) => window.lsadViewer.valueAt(r, arguments[1][k]));",
            rows, cols)
        expected = lmap.luminance[rows, cols]
        same = all((g is None and math.isnan(e)) or g == float(e) for g, e in zip(got, expected))
        t = time.perf_counter()
        mean = session.execute_script("return window.lsadViewer.regionMean(2000, 3000, 300);")
        region_s = time.perf_counter() - t
        zoom = session.execute_script(
            "const v = window.lsadViewer; const t = performance.now(); v.zoom(4, 300, 300);"
            "return performance.now() - t;")
    finally:
        session.quit()
    return {"html_loaded_s": loaded, "ready_s": ready, "browser_cpu_s_to_ready": cpu,
            "page": state, "lossless": same,
            "region_mean_300px_s": region_s, "region_mean": mean, "zoom_render_ms": zoom}


def main():
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="lsadphoto-"))
    out.mkdir(parents=True, exist_ok=True)
    lmap = make_map()
    exr = out / "map24.exr"
    write_exr(lmap, exr)
    lmap = read_map(exr)
    timings = {}
    t = time.perf_counter()
    score_map(lmap)  # compiles and caches the kernels: not the viewer's time
    timings["first_score_s"] = time.perf_counter() - t
    t = time.perf_counter()
    score = score_map(lmap)
    timings["score_s"] = time.perf_counter() - t
    t, c = time.perf_counter(), time.process_time()
    page = write_viewer(lmap, out / "map24.html", score=score)
    timings["write_viewer_s"] = time.perf_counter() - t
    timings["write_viewer_cpu_s"] = time.process_time() - c
    record = {"shape": list(lmap.shape), "exr_bytes": exr.stat().st_size,
              "html_bytes": page.stat().st_size,
              "html_over_exr": page.stat().st_size / exr.stat().st_size, **timings}
    if shutil.which("chromium") and shutil.which("chromedriver"):
        record["browser"] = open_in_browser(page, lmap)
    record["load_average"] = Path("/proc/loadavg").read_text().split()[:3]
    print(json.dumps(record, indent=2))


if __name__ == "__main__":
    main()
