"""The viewer at 24 megapixels: time to write the page, its size against the EXR, time to
the first frame (the preview) and to the full-resolution data in a browser.

Run (from the repository root; needs Debian's chromium and chromium-driver and selenium for
the browser part)::

    PYTHONPATH=. .venv/bin/python benchmarks/bench_viewer.py [OUT_DIR] [--runs N]
        [--also PAGE.html ...] [--real]

``--also`` opens other pages of the same 24 MP map (e.g. written by an earlier version of the
package: ``git worktree add /tmp/old COMMIT`` and this script there) in the same session,
interleaved with this version's page, ``--runs`` times each; ``--real`` adds the 1000 × 1000 px
real fisheye ``../shared/realdata/hdr/raytraverse_rendered_desk_vta.hdr``.

The map: a 6000 × 4000 px 180° equidistant fisheye (image-circle radius 1990 px), an
interior-like luminance field (a vertical gradient and two disk sources, as
``lsadphoto.datasets.disk_sources_scene`` makes them) with 2 % multiplicative noise, so that
its float32 values compress like a photo's, and NaN outside the image circle.

Times in the browser: ``first_frame`` is the animation frame after the first drawing (the
preview where the page has one), ``full`` the one after the full-resolution data are decoded
and drawn (``lsadViewer.ready``), both from the page's own clock, measured from the start of
the navigation (``wall``, seconds); ``cpu`` is the CPU time (user + system) of all the
browser's processes spent from the start of the navigation to that moment (sampled every
50 ms), ``cpu_with_start`` the same from the browser's start.
"""

import argparse
import json
import math
import os
import shutil
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from lsadphoto.datasets import disk_sources_scene
from lsadphoto.geometry import IdealFisheyeProjection, pixel_geometry
from lsadphoto.io import read_map, write_exr
from lsadphoto.luminance_map import LuminanceMap
from lsadphoto.metrics.score import score_map
from lsadphoto.viewer import write_viewer

REAL_MAP = Path("../shared/realdata/hdr/raytraverse_rendered_desk_vta.hdr")


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


class _CpuSampler(threading.Thread):
    """(epoch time [s], browser CPU [s]) every 50 ms until stopped."""

    def __init__(self, profile):
        super().__init__(daemon=True)
        self.profile, self.samples, self.stop = profile, [], threading.Event()

    def run(self):
        while not self.stop.is_set():
            self.samples.append((time.time(), browser_cpu_seconds(self.profile)))
            self.stop.wait(0.05)

    def at(self, epoch):
        """CPU at the first sample at or after ``epoch`` (the last one if none)."""
        for t, cpu in self.samples:
            if t >= epoch:
                return cpu
        return self.samples[-1][1]


# Waits for the viewer's full data and two more frames, then returns its clock's readings
# (ms); an older page without `timings` gets the frame after `ready` as both.
_WAIT = """
const done = arguments[0];
const frame = () => new Promise((resolve) => requestAnimationFrame(() => resolve(performance.now())));
const wait = () => {
  const v = window.lsadViewer;
  if (!v) return setTimeout(wait, 20);
  v.ready.then(async () => {
    const after = await frame(); await frame();
    const t = v.timings || {};
    done({origin: performance.timeOrigin, first: t.preview || t.full || after, full: t.full || after,
          preview_block: v.display && v.meta.maps[0].preview ? v.meta.maps[0].preview.block : null,
          decode_ms: v.decodeMs, workers: v.decodeWorkers});
  }, (e) => done({error: String(e)}));
};
wait();
"""


def open_in_browser(page, lmap, *, region=(2000, 3000, 300)):
    """Open ``page`` in a fresh headless chromium: times to the first frame and to the full
    data, browser CPU, and whether ``valueAt`` gives the map's float32 values."""
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
    sampler = _CpuSampler(profile)
    try:
        cpu_start = browser_cpu_seconds(profile)
        sampler.start()
        start = time.time()
        session.get(page.resolve().as_uri())
        loaded = time.time() - start
        state = session.execute_async_script(_WAIT)
        sampler.stop.set()
        sampler.join()
        if "error" in state:
            raise RuntimeError(f"{page}: {state['error']}")
        first = (state["origin"] + state["first"]) / 1000.0
        full = (state["origin"] + state["full"]) / 1000.0
        times = {key: {"wall": moment - start, "cpu": sampler.at(moment) - cpu_start,
                       "cpu_with_start": sampler.at(moment)}
                 for key, moment in (("first_frame", first), ("full", full))}
        rng = np.random.default_rng(1)
        rows = rng.integers(0, lmap.shape[0], 1000).tolist()
        cols = rng.integers(0, lmap.shape[1], 1000).tolist()
        got = session.execute_script(
            "return arguments[0].map((r, k) => window.lsadViewer.valueAt(r, arguments[1][k]));",
            rows, cols)
        expected = lmap.luminance[rows, cols]
        same = all((g is None and math.isnan(e)) or g == float(e) for g, e in zip(got, expected))
        t = time.perf_counter()
        mean = session.execute_script("return window.lsadViewer.regionMean(...arguments);",
                                      *region)
        region_s = time.perf_counter() - t
        zoom = session.execute_script(
            "const v = window.lsadViewer; const t = performance.now(); v.zoom(4, 300, 300);"
            "return performance.now() - t;")
    finally:
        sampler.stop.set()
        session.quit()
        shutil.rmtree(profile, ignore_errors=True)
    return {"page": page.name, "html_loaded_s": loaded, **times,
            "preview_block": state["preview_block"], "decode_ms": state["decode_ms"],
            "workers": state["workers"], "lossless": same, "region_mean_s": region_s,
            "region_mean": mean, "zoom_render_ms": zoom,
            "load_average": Path("/proc/loadavg").read_text().split()[:3]}


def _summary(runs):
    """Median and range of the browser times of the runs of one page."""
    out = {}
    for key in ("first_frame", "full"):
        for what in ("wall", "cpu"):
            values = sorted(run[key][what] for run in runs)
            out[f"{key}_{what}_s"] = {"median": round(float(np.median(values)), 2),
                                      "all": [round(v, 2) for v in values]}
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", nargs="?", type=Path)
    parser.add_argument("--runs", type=int, default=1)
    parser.add_argument("--also", nargs="*", type=Path, default=[])
    parser.add_argument("--real", action="store_true")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="lsadphoto-"))
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
    pages = [(page, lmap)] + [(other, lmap) for other in args.also]
    if args.real:
        real = read_map(REAL_MAP)
        real_exr, real_page = out / "real.exr", out / "real.html"
        write_exr(real, real_exr)
        write_viewer(real, real_page, score=score_map(real))
        record["real"] = {"shape": list(real.shape), "html_over_exr":
                          real_page.stat().st_size / real_exr.stat().st_size}
        pages.append((real_page, real))
    if shutil.which("chromium") and shutil.which("chromedriver"):
        runs = {str(p): [] for p, _ in pages}
        for _ in range(args.runs):
            for p, m in pages:
                middle = (m.shape[0] // 2, m.shape[1] // 2, min(m.shape) // 13)
                runs[str(p)].append(open_in_browser(p, m, region=middle))
                print(json.dumps(runs[str(p)][-1]), flush=True)
        record["browser"] = {name: {"summary": _summary(r), "runs": r} for name, r in runs.items()}
    print(json.dumps(record, indent=2))


if __name__ == "__main__":
    main()
