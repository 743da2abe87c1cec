"""``make demo``: the luminance stage on the bundled ``data_samples/``.

1. ``lsadphoto calibrate vignetting`` fits the demo camera's vignetting from two flat fields;
2. ``lsadphoto luminance`` merges the 3-frame office bracket, corrects vignetting with the
   fitted profile and calibrates with the two spot readings of ``spots.csv``;
3. the result is compared with the scene's true luminance (known: the samples are synthetic);
4. ``lsadphoto score`` scores the map: pixel-wise and grouped UGR, Q, DGP and the rest, with
   the glare-source and contrast maps;
5. the main job: ``lsadphoto survey`` processes the bundled survey of six station halls
   (luminance maps, metrics, and each view's scene model rendered by the Monte Carlo solver
   and compared with the photo), then ``lsadphoto study`` correlates the synthetic observers'
   ratings with the metrics and writes the HTML report with the paper's figures;
6. ``lsadphoto render`` renders the Radiance worked example (``data_samples/radiance``: a
   Radiance office with ies2rad downlights placed by ``!xform``) through its ``.vf`` view;
7. ``lsadphoto design`` chooses luminaires for a stated quality.

Outputs go to ``demo_output/`` (EXR, HDR, false-colour PNG, fitted profile, scores JSON and
figures).
"""

import csv
import json
import sys
from contextlib import redirect_stdout
from io import StringIO
from pathlib import Path

import numpy as np

from .cli import main as cli
from .datasets.samples import demo_scene
from .io import read_exr

ROOT = Path(__file__).resolve().parents[1]


def run(out=Path("demo_output")):
    samples = ROOT / "data_samples"
    out = Path(out)
    out.mkdir(exist_ok=True)
    fitted = out / "synthetic-demo-fitted.toml"
    flats = sorted(str(p) for p in (samples / "flat").glob("*.dng"))
    code = cli(["calibrate", "vignetting", *flats, "--profile", str(ROOT / "calibration" / "synthetic-demo.toml"),
                "-o", str(fitted)])
    if code:
        return code
    with open(samples / "office" / "spots.csv", newline="") as fh:
        spots = [f"{r['row']},{r['col']},{r['cd_m2']}" for r in csv.DictReader(fh)]
    bracket = sorted(str(p) for p in (samples / "office").glob("office_*.dng"))
    args = ["luminance", *bracket, "--profile", str(fitted), "-o", str(out / "office.exr"),
            "--hdr", str(out / "office.hdr"), "--png", str(out / "office.png"), "--json"]
    for spot in spots:
        args += ["--spot", spot]
    buffer = StringIO()
    with redirect_stdout(buffer):
        code = cli(args)
    if code:
        return code
    summary = json.loads(buffer.getvalue())
    lmap = read_exr(out / "office.exr")
    truth = demo_scene()
    truth = truth.reshape(truth.shape[0] // 2, 2, truth.shape[1] // 2, 2).mean(axis=(1, 3))
    known = np.isfinite(lmap.luminance)
    error = np.abs(lmap.luminance[known] / truth[known] - 1)
    print(f"calibration factor k = {summary['calibration_factor']:.4f} ± "
          f"{100 * summary['calibration_uncertainty']:.2f} % (spots: {len(spots)}); "
          f"saturated {100 * summary['saturated_fraction']:.2f} % of pixels")
    print(f"against the true scene: median |error| {100 * np.median(error):.2f} %, "
          f"95th percentile {100 * np.percentile(error, 95):.2f} %")
    print(f"maps: {out / 'office.exr'}, {out / 'office.hdr'}; false colour: {out / 'office.png'}")
    code = cli(["score", str(out / "office.exr"), "--sweep", "--output-json", str(out / "office-score.json"),
                "--sources-png", str(out / "office-sources.png"),
                "--contrast-png", str(out / "office-contrast.png")])
    if code:
        return code
    print(f"scores: {out / 'office-score.json'}; glare sources: {out / 'office-sources.png'}; "
          f"contrasts: {out / 'office-contrast.png'}")
    survey = out / "stations"
    code = cli(["survey", str(samples / "stations" / "survey.toml"), "-o", str(survey), "--no-report"])
    if code:
        return code
    code = cli(["study", str(survey / "ratings.csv"), str(survey / "metrics.csv"), "--report", str(survey),
                "--output-json", str(survey / "study.json")])
    if code:
        return code
    print(f"model-vs-photo reports: {survey / 'views' / '<view>' / '<view>-model-comparison.html'}")
    print(f"open the survey report: {survey / 'report.html'}")
    model = samples / "radiance"
    code = cli(["render", str(model / "office.rad"), "--view", f"-vf {model / 'office.vf'}", "--size", "96x96",
                "--estimator", "cache", "-o", str(out / "radiance-office.exr"),
                "--hdr", str(out / "radiance-office.hdr"), "--quiet"])
    if code:
        return code
    design = out / "design"
    code = cli(["design", str(samples / "design" / "problem.toml"), "-o", str(design), "--quiet"])
    if code:
        return code
    print(f"design for a quality: {design / 'design.json'}, {design / 'best.toml'}, {design / 'report.html'}")
    return 0


if __name__ == "__main__":
    sys.exit(run())
