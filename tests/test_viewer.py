"""``lsadphoto view``: the interactive viewer page, checked in a real headless browser.

The maps have known values: a luminance gradient, a disk source of known luminance, NaN
outside the fisheye circle. The browser (Debian's chromium, driven by selenium through
chromedriver) opens the page from ``file://`` and the page's test interface
(``window.lsadViewer``) is compared with references computed here, independently of the
page: the map's own float32 values, ω-weighted means from the package's exact per-pixel
solid angles, and the ``lsadphoto score`` JSON record.
"""

import json
import math
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

from lsadphoto.cli import main
from lsadphoto.datasets import disk_sources_scene
from lsadphoto.geometry import IdealFisheyeProjection, ObserverFrame, pixel_geometry, visual_field
from lsadphoto.io import read_map, write_exr, write_hdr
from lsadphoto.luminance_map import LuminanceMap

from .conftest import realdata

#: Source of the test map: luminance [cd/m²] and angular radius [rad].
SOURCE_LUMINANCE, SOURCE_RADIUS = 20000.0, 0.07
#: regionMean against the exact ω-weighted mean: the issue's 0.1 %. The page interpolates
#: ω from every 8th pixel (its stated error is < 10⁻³ relative away from the rim).
REGION_TOLERANCE = 1e-3
CHROME_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                "--disable-component-update", "--disable-sync", "--no-first-run",
                "--disable-quic", "--window-size=1280,1000")


def _synthetic_map(scale=1.0):
    """A 180° equidistant fisheye (non-square, so that rows and columns cannot be swapped):
    a gradient across the image, a disk source, NaN outside the image circle."""
    cam = IdealFisheyeProjection("equidistant", 500.0, 470.0, 465.0, 180.0, 1001, 941)
    rows, cols = cam.pixel_grid()
    d = cam.directions(rows, cols)
    source = np.array([0.3, -0.4, 0.8])
    source /= np.linalg.norm(source)
    disk = disk_sources_scene(d, background=0.0, sources=[(source, SOURCE_RADIUS,
                                                            SOURCE_LUMINANCE)])
    gradient = 20.0 + 180.0 * cols / cols.max() + 40.0 * rows / rows.max()
    luminance = np.where(disk > 0, disk, gradient) * scale
    luminance = np.where(pixel_geometry(cam).valid, luminance, np.nan).astype(np.float32)
    return LuminanceMap(luminance, projection=cam, calibrated=True, calibration_uncertainty=0.04)


@pytest.fixture(scope="module")
def folder():
    with tempfile.TemporaryDirectory(prefix="lsadphoto-viewer-") as name:
        yield Path(name)


@pytest.fixture(scope="module")
def pages(folder):
    """The map as EXR, its viewer page and its ``score`` JSON, through the CLI."""
    lmap = _synthetic_map()
    exr, model = folder / "photo.exr", folder / "model.hdr"
    write_exr(lmap, exr)
    write_hdr(_synthetic_map(1.1), model)
    assert main(["view", str(exr), "-o", str(folder / "view.html")]) == 0
    assert main(["view", str(exr), str(model), "-o", str(folder / "pair.html")]) == 0
    assert main(["score", str(exr), "--output-json", str(folder / "score.json")]) == 0
    return {"map": lmap, "exr": exr, "view": folder / "view.html", "pair": folder / "pair.html",
            "score": json.loads((folder / "score.json").read_text())}


@pytest.fixture(scope="module")
def browser(folder):
    """A headless chromium under selenium (skipped with the reason where absent)."""
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is not installed "
                                    "(pip install selenium: the test extra)")
    from selenium.webdriver.chrome.service import Service

    chromium, driver = shutil.which("chromium"), shutil.which("chromedriver")
    if chromium is None or driver is None:
        pytest.skip("chromium or chromedriver is not installed (Debian: apt-get install -y "
                    "chromium chromium-driver); the browser checks of the viewer are skipped")
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for flag in CHROME_FLAGS + (f"--user-data-dir={folder / 'profile'}",):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    session = webdriver.Chrome(service=Service(driver), options=options)
    session.set_script_timeout(60)
    yield session
    session.quit()


def _open(browser, page):
    browser.get(page.resolve().as_uri())
    # A report's viewers decode when scrolled into sight: scroll to the first one.
    state = browser.execute_async_script(
        "const done = arguments[0];"
        "const wait = () => { const v = window.lsadViewer; if (!v) return setTimeout(wait, 20);"
        "  v.container.scrollIntoView();"
        "  v.ready.then(() => done('ready'), (e) => done('failed: ' + e)); }; wait();")
    assert state == "ready"


def _severe(browser):
    return [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]


@pytest.mark.slow
def test_value_at_returns_the_embedded_float32_values(browser, pages):
    _open(browser, pages["view"])
    luminance = pages["map"].luminance
    rng = np.random.default_rng(1)
    rows = rng.integers(0, luminance.shape[0], 300)
    cols = rng.integers(0, luminance.shape[1], 300)
    got = browser.execute_script(
        "return arguments[0].map((r, k) => window.lsadViewer.valueAt(r, arguments[1][k]));",
        rows.tolist(), cols.tolist())
    expected = luminance[rows, cols]
    # Lossless: bit-identical float32, NaN (JSON null) outside the fisheye circle.
    got = np.array([np.nan if v is None else v for v in got], dtype=np.float64)
    assert np.isnan(expected).any() and np.isfinite(expected).any()
    np.testing.assert_array_equal(got, expected.astype(np.float64))
    assert _severe(browser) == []


@pytest.mark.slow
def test_arrays_in_many_parts_are_decoded_by_workers_losslessly(browser, folder, monkeypatch):
    # Parts of 100 000 elements: the test map's luminance (941 941 px) and the geometry's
    # validity become 10 parts each, decoded by the page's Workers and joined in order; the
    # values must still be the map's own float32 at every sampled pixel (parts' ends too).
    from lsadphoto.viewer import page

    monkeypatch.setattr(page, "PART_ITEMS", 100_000)
    lmap = _synthetic_map()
    path = page.write_viewer(lmap, folder / "parts.html")
    assert path.read_text().count('data-array="map0.luminance"') == 10
    _open(browser, path)
    assert browser.execute_script("return window.lsadViewer.decodeWorkers;") >= 1
    luminance = lmap.luminance
    flat = np.concatenate([np.arange(k * 100_000 - 2, k * 100_000 + 2) for k in range(1, 10)]
                          + [np.random.default_rng(2).integers(0, luminance.size, 300)])
    rows, cols = np.unravel_index(flat, luminance.shape)
    got = browser.execute_script(
        "return arguments[0].map((r, k) => window.lsadViewer.valueAt(r, arguments[1][k]));",
        rows.tolist(), cols.tolist())
    got = np.array([np.nan if v is None else v for v in got], dtype=np.float64)
    np.testing.assert_array_equal(got, luminance[rows, cols].astype(np.float64))
    assert _severe(browser) == []


#: The page's test hook: a promise it awaits before decoding the full-resolution data.
HOLD = ("window.lsadViewerHoldFullResolution = new Promise((release) => "
        "{ window.lsadViewerRelease = release; });")


@pytest.mark.slow
def test_preview_is_drawn_before_the_full_data_and_never_probed(browser, folder, monkeypatch):
    # A preview for maps above 100 000 px: the 1001 × 941 map gets blocks of 4 × 4 px. The
    # page is held (its test hook) before decoding the full-resolution data, so that the
    # preview state can be looked at; then released.
    from lsadphoto.viewer import page

    monkeypatch.setattr(page, "PREVIEW_PIXELS", 100_000)
    lmap = _synthetic_map()
    path = page.write_viewer(lmap, folder / "preview.html")
    text = path.read_text(encoding="utf-8")
    # The preview comes first, then the call that starts the viewer, then the full data.
    first_array = text.index('data-array="map0.luminance"')
    assert text.index('data-array="map0.preview"') < text.index("lsadViewerStart(") < first_array
    assert all(text.index(f'data-array="{name}"') > first_array
               for name in ("geometry.valid", "geometry.dx"))
    hook = browser.execute_cdp_cmd("Page.addScriptToEvaluateOnNewDocument", {"source": HOLD})
    try:
        browser.get(path.resolve().as_uri())
        state = browser.execute_async_script(
            "const done = arguments[0]; window.lsadViewer.previewReady.then("
            "(v) => done([v.state, v.display[0].block, Array.from(v.display[0].L)]),"
            " (e) => done(['failed: ' + e]));")
    finally:
        browser.execute_cdp_cmd("Page.removeScriptToEvaluateOnNewDocument", hook)
    assert state[:2] == ["preview", 4]
    # The drawn array is the block mean of the finite values (NaN where a block has none),
    # computed here block by block.
    rows, cols = lmap.shape
    expected = np.full((-(-rows // 4), -(-cols // 4)), np.nan)
    for r in range(expected.shape[0]):
        for c in range(expected.shape[1]):
            block = lmap.luminance[4 * r:4 * r + 4, 4 * c:4 * c + 4].astype(np.float64)
            if np.isfinite(block).any():
                expected[r, c] = block[np.isfinite(block)].mean()
    got = np.array([np.nan if v is None else v for v in state[2]])
    # float32 of a float64 mean: within half a float32 ulp (6e-8 relative).
    np.testing.assert_allclose(got, expected.reshape(-1), rtol=1.2e-7)
    # It is on the canvas (the map's colours, not the empty panel's) and it zooms.
    pixel = browser.execute_script(
        "const c = document.querySelector('.lv-base');"
        "return Array.from(c.getContext('2d').getImageData(c.width / 2, c.height / 2, 1, 1).data);")
    assert pixel[3] == 255 and pixel[:3] != [250, 250, 250]
    scale = browser.execute_script("const v = window.lsadViewer; const s = v.scale;"
                                   "v.zoom(2, 100, 100); return v.scale / s;")
    assert scale == pytest.approx(2.0)
    # No value is read from the preview: the readers refuse, the probe says it waits.
    refusals = browser.execute_script(
        "const v = window.lsadViewer, out = [];"
        "for (const f of [() => v.valueAt(500, 500), () => v.regionMean(500, 500, 20),"
        "                 () => v.geometryAt(500, 500), () => v.csv()]) {"
        "  try { f(); out.push('answered'); } catch (e) { out.push(e.message); } }"
        "return out;")
    assert all("still loading" in message for message in refusals), refusals
    from selenium.webdriver.common.action_chains import ActionChains

    canvas = browser.find_element("css selector", ".lv-panel .lv-over")
    ActionChains(browser).move_to_element_with_offset(canvas, 5, 5).perform()
    assert "loading the full-resolution data" in browser.find_element(
        "css selector", ".lv-probe").text
    # Released: the full data, bit for bit, drawn after the preview.
    assert browser.execute_async_script(
        "const done = arguments[0]; window.lsadViewerRelease();"
        "window.lsadViewer.ready.then((v) => done(v.state), (e) => done('failed: ' + e));") == "full"
    rng = np.random.default_rng(5)
    pick_rows, pick_cols = rng.integers(0, rows, 300), rng.integers(0, cols, 300)
    values = browser.execute_script(
        "return arguments[0].map((r, k) => window.lsadViewer.valueAt(r, arguments[1][k]));",
        pick_rows.tolist(), pick_cols.tolist())
    values = np.array([np.nan if v is None else v for v in values], dtype=np.float64)
    np.testing.assert_array_equal(values, lmap.luminance[pick_rows, pick_cols].astype(np.float64))
    assert "L [cd/m²]" in browser.find_element("css selector", ".lv-probe").text
    timings = browser.execute_async_script(
        "const done = arguments[0]; requestAnimationFrame(() => requestAnimationFrame(() =>"
        " done(window.lsadViewer.timings)));")
    assert timings["preview"] < timings["full"]
    assert _severe(browser) == []


def test_maps_up_to_the_preview_size_embed_no_preview(pages):
    # The 1001 × 941 map (under 1 Mi px) is drawn from its full data: no preview array.
    assert 'data-array="map0.preview"' not in pages["view"].read_text(encoding="utf-8")

def _reference_mean(lmap, row, col, radius):
    """ω-weighted mean of the pixels with centres within ``radius`` px, from the exact
    per-pixel solid angles of the geometry (not the page's interpolated ones)."""
    rows, cols = np.indices(lmap.shape)
    omega = pixel_geometry(lmap.projection).solid_angle
    L = lmap.luminance.astype(np.float64)
    sel = ((rows - row) ** 2 + (cols - col) ** 2 <= radius ** 2) & np.isfinite(L) & (omega > 0)
    return float(np.sum(L[sel] * omega[sel]) / np.sum(omega[sel])), int(sel.sum())


@pytest.mark.slow
@pytest.mark.parametrize("row, col, radius", [(520, 315, 64.5), (338, 599, 60.0),
                                              (470, 500, 360.0), (15, 500, 40.0)])
def test_region_mean_is_the_solid_angle_weighted_mean(browser, pages, row, col, radius):
    # The four regions: in the gradient, over the disk source, most of the image, and at
    # the rim of the image circle (partly NaN).
    _open(browser, pages["view"])
    got = browser.execute_script("return window.lsadViewer.regionMean(...arguments);",
                                 row, col, radius)
    expected, n = _reference_mean(pages["map"], row, col, radius)
    assert n > 0
    assert got == pytest.approx(expected, rel=REGION_TOLERANCE)


@pytest.mark.slow
def test_polygon_and_circle_statistics(browser, pages):
    _open(browser, pages["view"])
    lmap = pages["map"]
    # Vertices off the pixel lattice, so that no pixel centre lies on an edge.
    triangle = [[160.3, 205.7], [790.6, 315.2], [410.1, 880.45]]
    stats = browser.execute_script(
        "const v = window.lsadViewer;"
        "return v.regionStats({shape: 'polygon', points: arguments[0]});", triangle)
    # Reference: the pixel centres inside the triangle (barycentric test), exact ω and cos σ.
    rows, cols = np.indices(lmap.shape).astype(np.float64)
    (r0, c0), (r1, c1), (r2, c2) = triangle

    def side(ra, ca, rb, cb):
        return (cb - ca) * (rows - ra) - (rb - ra) * (cols - ca)

    s = [side(r0, c0, r1, c1), side(r1, c1, r2, c2), side(r2, c2, r0, c0)]
    inside = (s[0] > 0) & (s[1] > 0) & (s[2] > 0) | (s[0] < 0) & (s[1] < 0) & (s[2] < 0)
    L = lmap.luminance.astype(np.float64)
    omega = pixel_geometry(lmap.projection).solid_angle
    frame = ObserverFrame((0.0, 0.0, 1.0), (0.0, -1.0, 0.0))
    cos_sigma = visual_field(lmap.projection, frame).cos_sigma
    sel = inside & np.isfinite(L)
    assert stats["n"] == sel.sum()
    assert stats["solidAngle"] == pytest.approx(omega[sel].sum(), rel=REGION_TOLERANCE)
    assert stats["mean"] == pytest.approx(np.sum(L[sel] * omega[sel]) / omega[sel].sum(),
                                          rel=REGION_TOLERANCE)
    assert stats["max"] == pytest.approx(L[sel].max(), rel=1e-7)  # float32 → float64
    illuminance = np.sum((L * omega * np.maximum(cos_sigma, 0))[sel])
    assert stats["illuminance"] == pytest.approx(illuminance, rel=REGION_TOLERANCE)
    # The disk source alone: its luminance, and ω close to the cap's 2π(1 − cos r).
    disk = browser.execute_script(
        "return window.lsadViewer.regionStats({shape: 'circle', row: arguments[0], "
        "col: arguments[1], radius: 1500});", 0, 0)
    assert disk["max"] == pytest.approx(SOURCE_LUMINANCE, rel=1e-7)
    assert browser.execute_script("return window.lsadViewer.regionStats({shape: 'circle', "
                                  "row: 470, col: 500, radius: 1500}).solidAngle") == \
        pytest.approx(2 * math.pi, rel=0.01)  # the hemisphere, to the rim's pixelation


@pytest.mark.slow
def test_probe_geometry_within_the_stated_error(browser, pages):
    _open(browser, pages["view"])
    lmap = pages["map"]
    error = browser.execute_script("return window.lsadViewer.meta.geometry.interpolation_error")
    rng = np.random.default_rng(2)
    valid = np.flatnonzero(pixel_geometry(lmap.projection).valid)
    pick = rng.choice(valid, 200, replace=False)
    rows, cols = np.divmod(pick, lmap.shape[1])
    got = browser.execute_script(
        "return arguments[0].map((r, k) => window.lsadViewer.geometryAt(r, arguments[1][k]));",
        rows.tolist(), cols.tolist())
    geometry = pixel_geometry(lmap.projection)
    field = visual_field(lmap.projection, ObserverFrame((0.0, 0.0, 1.0), (0.0, -1.0, 0.0)))
    sigma = np.array([g["sigma"] for g in got])
    omega = np.array([g["solidAngle"] for g in got])
    direction = np.array([g["direction"] for g in got])
    tau = np.array([g["tau"] for g in got])
    pindex = np.array([g["positionIndex"] for g in got])
    # The stated errors are maxima over all valid pixels of the same computation (in
    # float64 from the float32 nodes), so they bound these pixels; the slack is the page's
    # own rounding (float32 values, 1e-6 relative: < 1e-4° and 1e-5 in P).
    assert np.degrees(np.max(np.abs(sigma - field.sigma[rows, cols]))) <= error["sigma_deg"] + 1e-4
    away = field.sigma[rows, cols] > np.radians(1.0)
    assert np.degrees(np.max(np.abs(tau - field.tau[rows, cols])[away])) <= \
        error["tau_deg_beyond_1deg"] + 1e-4
    assert np.max(np.abs(pindex - field.position_index[rows, cols])) <= \
        error["position_index"] + 1e-5
    assert np.max(np.abs(omega / geometry.solid_angle[rows, cols] - 1)) <= \
        error["solid_angle_relative"] + 1e-6
    cos = np.clip(np.sum(direction * geometry.directions[rows, cols], axis=-1), -1, 1)
    assert np.degrees(np.max(np.arccos(cos))) <= error["direction_deg"] + 1e-4
    # And the stated errors are within the tolerance of the grid, and most pixels are
    # interpolated (an 8-px grid on a 180° fisheye of 465 px radius).
    assert error["direction_deg"] <= 0.01 and error["sigma_deg"] <= 0.01
    assert error["solid_angle_relative"] <= 1e-4
    assert error["exact_pixels"] < 0.5 * error["valid_pixels"]
    # The page states them.
    note = browser.find_element("css selector", ".lv-note").text
    assert "interpolated bilinearly" in note and "float32" in note


@pytest.mark.slow
def test_glare_source_overlay_matches_the_score_json(browser, pages):
    _open(browser, pages["view"])
    record = pages["score"]
    assert record["n_sources"] >= 1
    shown = browser.execute_script("return window.lsadViewer.sources()")
    assert len(shown) == len(record["sources"])
    for a, b in zip(shown, record["sources"], strict=True):
        for key in ("luminance", "solid_angle", "row", "col", "position_index", "n_pixels"):
            assert a[key] == pytest.approx(b[key], rel=1e-12)
    # The label overlay: its pixels of each source sum to the source's ω and count.
    sums = browser.execute_script(
        "const v = window.lsadViewer, out = {};"
        "for (let r = 0; r < v.rows; r++) for (let c = 0; c < v.cols; c++) {"
        "  const k = v.sourceLabelAt(r, c); if (!k) continue;"
        "  const g = v.geometryAt(r, c); out[k] = out[k] || [0, 0];"
        "  out[k][0] += g.solidAngle; out[k][1] += 1; }"
        "return out;")
    for k, source in enumerate(record["sources"], start=1):
        omega, count = sums[str(k)]
        assert count == source["n_pixels"]
        assert omega == pytest.approx(source["solid_angle"], rel=REGION_TOLERANCE)
    # The source list is on the page, with the map's UGR.
    text = browser.find_element("css selector", ".lv-tables").text
    assert "Glare sources" in text and "UGR" in text
    assert _severe(browser) == []


@pytest.mark.slow
def test_side_by_side_probe_ratio_and_csv(browser, pages):
    _open(browser, pages["pair"])
    lmap = pages["map"]
    row, col = 630, 360
    values = browser.execute_script(
        "const v = window.lsadViewer; return [v.valueAt(arguments[0], arguments[1], 0),"
        "v.valueAt(arguments[0], arguments[1], 1)];", row, col)
    assert values[0] == float(lmap.luminance[row, col])
    # The model map went through Radiance HDR (RGBE: 8-bit mantissa, ≤ 0.4 % rounding).
    assert values[1] / values[0] == pytest.approx(1.1, rel=4e-3)
    # The probe under the mouse shows both maps and their ratio.
    from selenium.webdriver.common.action_chains import ActionChains

    canvas = browser.find_element("css selector", ".lv-panel .lv-over")
    ActionChains(browser).move_to_element_with_offset(canvas, 5, 5).perform()
    probe = browser.find_element("css selector", ".lv-probe").text
    assert "ratio model / photo" in probe and "model L" in probe
    # Points and regions export as CSV, one row per map.
    csv_text = browser.execute_script(
        "const v = window.lsadViewer; v.pin(arguments[0], arguments[1]);"
        "v.addCircle(520, 315, 64.5); return v.csv();", row, col)
    lines = [line.split(",") for line in csv_text.strip().splitlines()]
    header = lines[0]
    assert len(lines) == 5  # header, point × 2 maps, region × 2 maps
    point = dict(zip(header, lines[1], strict=True))
    assert float(point["luminance_cd_m2"]) == pytest.approx(float(lmap.luminance[row, col]))
    # No per-pixel uncertainty in the map: ± is the calibration's 4 %.
    assert float(point["uncertainty_cd_m2"]) == pytest.approx(0.04 * values[0])
    region = dict(zip(header, lines[2], strict=True))
    assert region["kind"] == "region"
    assert float(region["mean_cd_m2"]) == pytest.approx(_reference_mean(lmap, 520, 315, 64.5)[0],
                                                        rel=REGION_TOLERANCE)
    # The ratio layout draws without errors.
    browser.execute_script("window.lsadViewer.setLayout('ratio');")
    assert _severe(browser) == []


@pytest.mark.slow
def test_page_is_self_contained(pages):
    text = pages["view"].read_text(encoding="utf-8")
    # No external resource: no URL of any scheme in the page, nothing loaded by src=.
    assert "http://" not in text and "https://" not in text and "src=" not in text


@pytest.mark.slow
@pytest.mark.realdata
def test_page_of_a_real_map_is_at_most_twice_the_exr(tmp_path):
    # A real Radiance rendering, 1000 × 1000 px, 180° fisheye with the sun: its page (with
    # the score overlays, as `lsadphoto view` writes it) against the same map as our EXR.
    source = realdata("hdr/raytraverse_rendered_desk_vta.hdr")
    exr = tmp_path / "desk.exr"
    write_exr(read_map(source), exr)
    assert main(["view", str(source), "-o", str(tmp_path / "desk.html")]) == 0
    assert (tmp_path / "desk.html").stat().st_size <= 2 * exr.stat().st_size


def test_page_of_a_small_wide_map_is_at_most_twice_the_exr(tmp_path):
    # A small wide-angle map (320 × 212 px, 98° across: a grid cell of 8 px spans 2.5°)
    # with a per-pixel uncertainty, like the quickstart's office map: the page takes a finer
    # geometry grid rather than storing most pixels exactly.
    from lsadphoto.geometry import PinholeProjection

    cam = PinholeProjection(140.0, 140.0, 159.5, 105.5, 320, 212)
    rows, cols = cam.pixel_grid()
    rng = np.random.default_rng(4)
    L = (50.0 + 2.0 * cols + rows) * rng.normal(1.0, 0.02, rows.shape)
    lmap = LuminanceMap(L.astype(np.float32), uncertainty=(0.012 * L).astype(np.float32),
                        projection=cam, calibrated=True, calibration_uncertainty=0.012)
    write_exr(lmap, tmp_path / "office.exr")
    assert main(["view", str(tmp_path / "office.exr"), "-o", str(tmp_path / "v.html")]) == 0
    assert (tmp_path / "v.html").stat().st_size <= 2 * (tmp_path / "office.exr").stat().st_size


def test_bad_inputs_are_one_line_and_write_nothing(tmp_path, capsys):
    garbage = tmp_path / "bad.exr"
    garbage.write_bytes(b"not an exr file")
    out = tmp_path / "v.html"
    assert main(["view", str(garbage), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bad.exr" in err
    a = _synthetic_map()
    write_exr(a, tmp_path / "a.exr")
    small = IdealFisheyeProjection("equidistant", 50.0, 45.0, 44.0, 180.0, 101, 91)
    write_exr(LuminanceMap(np.ones((91, 101), np.float32), projection=small), tmp_path / "b.exr")
    assert main(["view", str(tmp_path / "a.exr"), str(tmp_path / "b.exr"), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pixel grid" in err
    other = IdealFisheyeProjection("equisolid", 500.0, 470.0, 465.0, 180.0, 1001, 941)
    write_exr(LuminanceMap(a.luminance, projection=other), tmp_path / "c.exr")
    assert main(["view", str(tmp_path / "a.exr"), str(tmp_path / "c.exr"), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "different camera geometries" in err
    assert not out.exists() and not list(tmp_path.glob(".v.*"))


@pytest.mark.slow
def test_comparison_report_embeds_the_viewer(browser, pages, folder):
    from lsadphoto.compare import compare_maps
    from lsadphoto.report import write_comparison_report

    photo, model = pages["map"], read_map(folder / "model.hdr")
    comparison = compare_maps(photo, model)
    report = write_comparison_report(comparison, folder / "comparison.html", photo=photo,
                                     model=model)
    _open(browser, report)
    rng = np.random.default_rng(3)
    rows, cols = rng.integers(0, photo.shape[0], 50), rng.integers(0, photo.shape[1], 50)
    got = browser.execute_script(
        "const v = window.lsadViewer;"
        "return arguments[0].map((r, k) => [v.valueAt(r, arguments[1][k], 0),"
        "                                   v.valueAt(r, arguments[1][k], 1)]);",
        rows.tolist(), cols.tolist())
    for (a, b), r, c in zip(got, rows, cols, strict=True):
        for value, lmap in ((a, photo), (b, model)):
            expected = float(lmap.luminance[r, c])
            assert (value is None and math.isnan(expected)) or value == expected
    # The photo's glare sources are those of the comparison's score of the photo.
    shown = browser.execute_script("return window.lsadViewer.sources(0)")
    assert [s["luminance"] for s in shown] == [s.luminance for s in comparison.scores[0].sources]
    assert _severe(browser) == []


@pytest.mark.slow
def test_survey_report_embeds_a_viewer_per_view(browser, pages, folder):
    from lsadphoto.report import write_survey_report

    survey = folder / "survey"
    view = survey / "views" / "v1"
    view.mkdir(parents=True)
    (survey / "metrics.csv").write_text("view,ugr_pixel\nv1,12.5\n", encoding="utf-8")
    shutil.copy(pages["exr"], view / "v1.exr")
    (view / "v1-score.json").write_text(json.dumps(pages["score"]), encoding="utf-8")
    # The survey saves each view's glare-source labels beside its score (as the pipeline
    # writes them); the reference labels are score_map's own, of the same map.
    from lsadphoto.metrics.score import score_map
    from lsadphoto.viewer import write_source_labels

    labels = score_map(pages["map"]).source_labels
    write_source_labels(labels, view / "v1-source-labels.npz")
    # The view's done marker lists its files (lsadphoto.survey.ViewLayout).
    (view / "v1-done.json").write_text(json.dumps(
        {"outputs": {"exr": "v1.exr", "score": "v1-score.json",
                     "source_labels": "v1-source-labels.npz"}}), encoding="utf-8")
    report = write_survey_report(survey)
    text = report.read_text(encoding="utf-8")
    assert text.count('class="lsad-viewer"') == 1 and 'data-lazy="yes"' in text
    _open(browser, report)
    row, col = 630, 360
    assert browser.execute_script("return window.lsadViewer.valueAt(arguments[0], arguments[1])",
                                  row, col) == float(pages["map"].luminance[row, col])
    shown = browser.execute_script("return window.lsadViewer.sources()")
    assert len(shown) == pages["score"]["n_sources"]
    # The tinted source pixels: the page's labels are the saved ones, at every source pixel
    # and at random others.
    inside = np.argwhere(labels > 0)
    assert len(inside) > 0
    sample = np.concatenate([inside[:: max(1, len(inside) // 200)],
                             np.random.default_rng(3).integers(0, labels.shape, (200, 2))])
    got = browser.execute_script(
        "return arguments[0].map((p) => window.lsadViewer.sourceLabelAt(p[0], p[1]));",
        sample.tolist())
    assert got == labels[sample[:, 0], sample[:, 1]].tolist()
    assert _severe(browser) == []


@pytest.mark.slow
def test_mouse_draws_regions_pins_zooms_and_pans(browser, pages):
    # The same actions a user takes, as real mouse events through chromedriver.
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.actions.wheel_input import ScrollOrigin

    _open(browser, pages["view"])
    canvas = browser.find_element("css selector", ".lv-panel .lv-over")
    width, height = canvas.size["width"], canvas.size["height"]

    def at(row, col):
        """Offset from the canvas centre (selenium's origin) of pixel (row, col)."""
        x, y = browser.execute_script("return window.lsadViewer.toScreen(arguments[0], "
                                      "arguments[1])", row, col)
        return int(round(x - width / 2)), int(round(y - height / 2))

    scale = browser.execute_script("return window.lsadViewer.scale")  # screen px per pixel
    browser.execute_script("window.lsadViewer.setTool('circle')")
    x0, y0 = at(520, 315)
    ActionChains(browser).move_to_element_with_offset(canvas, x0, y0).click_and_hold() \
        .move_by_offset(20, 0).move_by_offset(40, 0).release().perform()
    browser.execute_script("window.lsadViewer.setTool('polygon')")
    corners = [(300, 300), (300, 600), (600, 600), (600, 300)]
    chain = ActionChains(browser)
    for row, col in corners[:-1]:
        chain.move_to_element_with_offset(canvas, *at(row, col)).click()
    chain.move_to_element_with_offset(canvas, *at(*corners[-1])).double_click().perform()
    browser.execute_script("window.lsadViewer.setTool('probe')")
    ActionChains(browser).move_to_element_with_offset(canvas, *at(630, 360)).click().perform()
    regions, points = browser.execute_script(
        "const v = window.lsadViewer; return [v.regions, v.points];")
    assert [r["shape"] for r in regions] == ["circle", "polygon"]
    circle, polygon = regions
    # Mouse positions are whole screen pixels: within one screen pixel of the target.
    tolerance = 1.0 / scale + 0.5
    assert abs(circle["row"] - 520) <= tolerance and abs(circle["col"] - 315) <= tolerance
    assert circle["radius"] == pytest.approx(60 / scale, abs=tolerance)
    assert len(polygon["points"]) == 4
    for (row, col), (r, c) in zip(corners, polygon["points"], strict=True):
        assert abs(r - row) <= tolerance and abs(c - col) <= tolerance
    assert len(points) == 1 and abs(points[0]["row"] - 630) <= tolerance
    # The tables list them.
    text = browser.find_element("css selector", ".lv-tables").text
    assert "R1" in text and "R2" in text and "P1" in text
    # Wheel: zoom about the cursor, the pixel under it stays put.
    x, y = at(400, 500)
    before = browser.execute_script("return window.lsadViewer.scale")
    ActionChains(browser).scroll_from_origin(ScrollOrigin.from_element(canvas, x, y), 0, -100) \
        .perform()
    after = browser.execute_script("return window.lsadViewer.scale")
    assert after == pytest.approx(1.25 * before)
    assert at(400, 500) == pytest.approx((x, y), abs=1)
    # Drag: pan by the mouse's movement.
    ActionChains(browser).move_to_element_with_offset(canvas, x, y).click_and_hold() \
        .move_by_offset(30, 20).move_by_offset(30, 20).release().perform()
    assert at(400, 500) == pytest.approx((x + 60, y + 40), abs=1)
    assert _severe(browser) == []


@pytest.mark.slow
def test_band_and_zone_overlays_match_the_score_json(browser, pages, folder):
    options = ["--band-deg", "20", "--zones", "0.2,-0.3,0.93,30,60"]
    page, record = folder / "regions.html", folder / "regions.json"
    assert main(["view", str(pages["exr"]), "-o", str(page), *options]) == 0
    assert main(["score", str(pages["exr"]), "--output-json", str(record), *options]) == 0
    record = json.loads(record.read_text())
    _open(browser, page)
    sums = browser.execute_script(
        "const v = window.lsadViewer, out = {band: [0, 0], zone1: [0, 0], zone2: [0, 0]};"
        "for (let r = 0; r < v.rows; r++) for (let c = 0; c < v.cols; c++) {"
        "  const b = v.bandAt(r, c), z = v.zoneAt(r, c); if (!b && !z) continue;"
        "  const w = v.geometryAt(r, c).solidAngle;"
        "  if (b) { out.band[0] += w; out.band[1] += 1; }"
        "  if (z) { out['zone' + z][0] += w; out['zone' + z][1] += 1; } }"
        "return out;")
    expected = {"band": record["band"], "zone1": record["zones"][0], "zone2": record["zones"][1]}
    for key, stats in expected.items():
        omega, count = sums[key]
        assert count == stats["n_pixels"], key
        # ω from the page's interpolated geometry (within 10⁻⁴ per pixel).
        assert omega == pytest.approx(stats["solid_angle"], rel=REGION_TOLERANCE), key
    text = browser.find_element("css selector", ".lv-tables").text
    assert "Band and zones" in text and "zone 2" in text
    assert _severe(browser) == []
