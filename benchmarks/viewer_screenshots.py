"""Make the viewer screenshots of docs/user-guide-viewer.md (docs/viewer-*.png).

Run: PYTHONPATH=. .venv/bin/python benchmarks/viewer_screenshots.py (from the repository root;
needs ../shared/realdata, Debian's chromium and chromium-driver, and selenium).

1. docs/viewer-single.png: `lsadphoto view` of the real Radiance rendering
   ../shared/realdata/hdr/raytraverse_rendered_desk_vta.hdr (180° fisheye, sun in view),
   with its glare sources, a circle and a polygon region, a pinned point and the probe.
2. docs/viewer-pair.png: the synthetic photo of tests/test_viewer.py and a "model" of it that
   errs from −15 % to +25 % across the view, side by side, and docs/viewer-ratio.png: their
   ratio map.
"""

import dataclasses
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image
from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.action_chains import ActionChains

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lsadphoto.cli import main  # noqa: E402
from lsadphoto.io import write_exr, write_hdr  # noqa: E402
from tests.test_viewer import _synthetic_map  # noqa: E402


def browser(profile):
    options = webdriver.ChromeOptions()
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run",
                 "--hide-scrollbars", "--window-size=1280,1250", f"--user-data-dir={profile}"):
        options.add_argument(flag)
    session = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)
    session.set_script_timeout(120)
    return session


def open_page(session, page):
    session.get(page.resolve().as_uri())
    session.execute_async_script(
        "const done = arguments[0]; const wait = () => window.lsadViewer ? "
        "window.lsadViewer.ready.then(() => done(1)) : setTimeout(wait, 20); wait();")


def save(session, name, *, height):
    raw = Path(tempfile.mkdtemp()) / "shot.png"
    session.save_screenshot(str(raw))
    image = Image.open(raw).convert("RGB")
    image = image.crop((0, 0, image.width, min(height, image.height)))
    image = image.resize((image.width * 3 // 4, image.height * 3 // 4), Image.LANCZOS)
    image.quantize(colors=256, method=Image.Quantize.FASTOCTREE).save(ROOT / "docs" / name,
                                                                    optimize=True)


def probe(session, row, col):
    """Move the mouse over pixel (row, col) of the first panel."""
    canvas = session.find_element("css selector", ".lv-panel .lv-over")
    x, y = session.execute_script("const v = window.lsadViewer; const p = v.toScreen(arguments[0],"
                                  " arguments[1]); return p;", row, col)
    width, height = canvas.size["width"], canvas.size["height"]
    ActionChains(session).move_to_element_with_offset(canvas, int(x - width / 2),
                                                      int(y - height / 2)).perform()


def run():
    folder = Path(tempfile.mkdtemp(prefix="lsadphoto-shots-"))
    desk = ROOT.parent / "shared" / "realdata" / "hdr" / "raytraverse_rendered_desk_vta.hdr"
    assert main(["view", str(desk), "-o", str(folder / "desk.html"),
                 "--title", "raytraverse desk (Radiance rendering, 180° fisheye)"]) == 0
    photo, model = folder / "photo.exr", folder / "model.hdr"
    write_exr(_synthetic_map(), photo)
    photo_map = _synthetic_map()
    cols = np.arange(photo_map.shape[1]) / photo_map.shape[1]
    # A model that errs from −15 % on the left to +25 % on the right of the view.
    write_hdr(dataclasses.replace(photo_map, luminance=photo_map.luminance
                                  * (0.85 + 0.4 * cols)[None, :].astype(np.float32)), model)
    assert main(["view", str(photo), str(model), "-o", str(folder / "pair.html"),
                 "--title", "synthetic photo and model of one view"]) == 0
    session = browser(folder / "profile")
    try:
        open_page(session, folder / "desk.html")
        session.execute_script(
            "const v = window.lsadViewer; v.addCircle(330, 620, 45);"
            "v.addPolygon([[640, 420], [700, 560], [880, 520], [790, 380]]); v.pin(520, 250);")
        probe(session, 455, 700)
        save(session, "viewer-single.png", height=1250)
        open_page(session, folder / "pair.html")
        session.execute_script("window.lsadViewer.addCircle(338, 599, 60);")
        probe(session, 520, 315)
        save(session, "viewer-pair.png", height=900)
        session.execute_script("window.lsadViewer.setLayout('ratio');")
        probe(session, 520, 315)
        save(session, "viewer-ratio.png", height=900)
    finally:
        session.quit()


if __name__ == "__main__":
    run()
