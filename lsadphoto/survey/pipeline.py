"""One view of a survey: its output layout and the pipeline that fills it.

:class:`ViewLayout` names every file of a view (``views/<id>/<id>.exr``, …, the done marker
last); the pipeline writes them, the table builder reads the marker, and the marker records
the files by kind, which is how the report finds them. :func:`make_task` turns a manifest's
view into plain picklable data for a worker (with the fingerprint of every input that
decides the outputs); :func:`process_view` runs the photo pipeline on it — luminance map
(OpenEXR, Radiance HDR, false colour), scores (:func:`~lsadphoto.metrics.score.score_map`
with the Q(N) sweep N = 1…100), glare-source and contrast maps, the model comparison, the
JSON record — and never raises for a problem of the view itself. Each view's outputs are
one group of the atomic writer: all of them appear, or none changes; the done marker comes
after them, so a killed run loses no finished view and a rerun skips what is done.

References
----------
rawpy issue #265 (fork + OpenMP deadlock: workers are spawned, see executors).
"""

import contextlib
import dataclasses
import hashlib
import json
import math
import os
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._provenance import file_record, timestamp
from .._version import __version__
from ..errors import LsadError

__all__ = ["SWEEP", "VIEW_RECORD_SCHEMA", "ViewLayout", "make_task", "read_done",
           "process_view", "json_default"]

VIEW_RECORD_SCHEMA = "lsadphoto.survey-view/1"

#: N values of the Q(N) sweep in the metrics table (columns ``q_n1`` … ``q_n100``).
SWEEP = tuple(range(1, 101))

#: Metrics of a Score without an uncertainty (counts and geometry, not luminance scale).
_NO_UNCERTAINTY = ("n_sources", "source_solid_angle")



@dataclass(frozen=True)
class ViewLayout:
    """The files of one view in a survey output folder: ``views/<id>/<id><suffix>``.

    Attributes
    ----------
    outdir : Path
        The survey's output folder.
    view : str
        The view id.
    with_model : bool
        The view has a scene model (four more files).

    Examples
    --------
    >>> layout = ViewLayout(Path("out"), "hall")
    >>> layout.path("sources").as_posix(), layout.done.name
    ('out/views/hall/hall-sources.png', 'hall-done.json')
    >>> list(layout.outputs())[-1]
    'done'
    """

    outdir: Path
    view: str
    with_model: bool = False

    #: Folder of the per-view folders, inside the output folder.
    VIEWS = "views"
    #: Suffix of each kind of output (the done marker last: it is written last).
    PHOTO = (("exr", ".exr"), ("hdr", ".hdr"), ("falsecolour", "-falsecolour.png"),
             ("sources", "-sources.png"), ("source_labels", "-source-labels.npz"),
             ("contrast", "-contrast.png"), ("score", "-score.json"))
    MODEL = (("model_exr", "-model.exr"), ("model_ratio", "-model-ratio.png"),
             ("model_json", "-model-comparison.json"),
             ("model_report", "-model-comparison.html"))
    DONE = ("done", "-done.json")

    @property
    def folder(self):
        """The view's folder."""
        return Path(self.outdir) / self.VIEWS / self.view

    def path(self, kind):
        """Path of one output by kind (``exr``, ``sources``, ``done``, …)."""
        suffix = dict(self.PHOTO + self.MODEL + (self.DONE,))[kind]
        return self.folder / f"{self.view}{suffix}"

    @property
    def done(self):
        """The done marker."""
        return self.path("done")

    def outputs(self):
        """``{kind: path}`` of every output of the view, the done marker last."""
        kinds = self.PHOTO + (self.MODEL if self.with_model else ()) + (self.DONE,)
        return {kind: self.path(kind) for kind, _ in kinds}


def _stat(path):
    """Size [B] and modification time [ns] of a file; None if it has gone (the view fails)."""
    try:
        info = os.stat(path)
    except OSError:
        return None, None
    return info.st_size, info.st_mtime_ns


def make_task(manifest, view, outdir, score_options):
    """Everything a worker needs for one view, as plain picklable data."""
    profile = view.profile or manifest.profile
    score = {**manifest.score, **(score_options or {}), **view.score}
    if view.line_of_sight is not None:
        score["line_of_sight"] = view.line_of_sight
    task = {
        "view": view.id,
        "manifest": str(manifest.path),
        "raw": [str(p) for p in view.raw],
        "raw_as_written": list(view.raw_as_written),
        "profile": None if profile is None else str(profile),
        "spots": list(view.spots),
        "demosaic": manifest.demosaic,
        "colour_method": manifest.colour_method,
        "score": score,
        "ratings": None if view.ratings is None else [list(r) for r in view.ratings],
        "model": view.model,
        "note": view.note,
    }
    # Inputs that decide the outputs: a changed file, spot or option redoes the view.
    identity = {k: v for k, v in task.items() if k not in ("manifest",)}
    identity["spots"] = [dataclasses.astuple(s) for s in view.spots]
    identity["raw_stat"] = [(p, *_stat(p)) for p in task["raw"]]
    identity["profile_sha256"] = None if profile is None else file_record(profile)["sha256"]
    text = json.dumps(identity, sort_keys=True, default=json_default)
    task["fingerprint"] = hashlib.sha256(text.encode("utf-8")).hexdigest()
    layout = ViewLayout(Path(outdir), view.id, with_model=view.model is not None)
    task["outputs"] = {k: str(v) for k, v in layout.outputs().items()}
    return task


def read_done(task):
    """The done marker's row when the view's outputs are complete and current, else None."""
    outputs = {k: Path(v) for k, v in task["outputs"].items()}
    try:
        marker = json.loads(outputs["done"].read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(marker, dict) or marker.get("fingerprint") != task["fingerprint"]:
        return None
    if not all(p.is_file() for k, p in outputs.items()):
        return None
    return marker.get("row")


def json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)  # paths, and anything else a record may carry


def _clean(value):
    """A table cell: finite float, int, bool, str, or None."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    value = float(value)
    return value if math.isfinite(value) else None


def _remove_stale_temporaries(view_dir):
    """Temporary files of atomic writes that a killed run left behind (``.name.XXXX.tmp.ext``)."""
    if view_dir.is_dir():
        for temp in view_dir.glob(".*.tmp*"):
            with contextlib.suppress(FileNotFoundError):
                temp.unlink()


def _row(task, summary, scalars, record, warning_lines):
    """One line of the metrics table from a view's score record and luminance summary.

    ``scalars`` are the names of the scalar metrics (``Score.values``), in their order.
    """
    row = {"view": task["view"]}
    for key in scalars:
        row[key] = _clean(record[key])
    for key in scalars:
        if key not in _NO_UNCERTAINTY:
            row[f"{key}_u"] = _clean(record["uncertainty"].get(key))
    sweep = record.get("q_sweep") or {"n": [], "q": []}
    for n, q in zip(sweep["n"], sweep["q"]):
        row[f"q_n{int(n)}"] = _clean(q)
    ratings = task["ratings"]
    row["rating_mean"] = float(np.mean([r for _, r in ratings])) if ratings else None
    row["rating_n"] = len(ratings) if ratings else None
    comparison = record.get("model_comparison")
    if comparison is not None:
        from ..metrics.registry import HEADLINE

        row["model_ratio_median"] = _clean(comparison["field"]["median_ratio"])
        row["model_rms_relative_error"] = _clean(comparison["field"]["rms_relative_error"])
        row["model_mc_uncertainty"] = _clean(comparison["uncertainty"]["model_monte_carlo_relative"])
        for key in HEADLINE:  # the model map's headline metrics (model_<name>)
            row[f"model_{key}"] = _clean(comparison["metrics"].get(key, {}).get("model"))
    los = record["settings"]["line_of_sight"]
    row.update({
        "line_of_sight": ",".join(f"{float(v):.6g}" for v in los),
        "lsadphoto_version": __version__,
        "raw_files": ";".join(task["raw_as_written"]),
        "profile": summary["profile"],
        "calibration_method": summary["calibration_method"],
        "calibration_factor": _clean(summary["calibration_factor"]),
        "calibration_uncertainty": _clean(summary["calibration_uncertainty"]),
        "calibrated": bool(summary["calibrated"]),
        "saturated_fraction": _clean(summary["saturated_fraction"]),
        "demosaic": summary["demosaic"],
        "notes": " | ".join(record["notes"]) or None,
        "warnings": " | ".join(warning_lines) or None,
        "timestamp": timestamp(),
    })
    return row


def _process_view_outputs(task, caught):
    from ..calibrate.profile import load_profile
    from ..io import write_exr, write_false_colour_png, write_hdr
    from .._atomic import atomic_outputs, atomic_text
    from ..luminance import luminance_from_raw
    from ..metrics.score import score_map
    from ..report import write_comparison_report, write_ratio_png
    from ..report.figures import write_contrast_png, write_glare_source_png
    from ..viewer import write_source_labels

    outputs = {k: Path(v) for k, v in task["outputs"].items()}
    view_dir = outputs["done"].parent
    view_dir.mkdir(parents=True, exist_ok=True)
    # Outputs are about to change: the view is not done until the new marker is written.
    with contextlib.suppress(FileNotFoundError):
        outputs["done"].unlink()
    _remove_stale_temporaries(view_dir)
    # The work first: nothing is written until every number is known.
    profile = load_profile(task["profile"]) if task["profile"] else None
    result = luminance_from_raw(task["raw"], spots=task["spots"], profile=profile,
                                demosaic=task["demosaic"], colour_method=task["colour_method"])
    lmap = result.map
    options = dict(task["score"])
    if options.get("line_of_sight") is not None:
        # The map carries the view's line of sight into its EXR/HDR metadata.
        lmap = dataclasses.replace(lmap, line_of_sight=np.asarray(options["line_of_sight"]))
    score = score_map(lmap, sweep=SWEEP, **options)
    record = score.to_dict()
    record["provenance"]["input"] = [str(p) for p in task["raw"]]
    record["survey"] = {
        "manifest": task["manifest"], "view": task["view"], "raw": list(task["raw_as_written"]),
        "note": task["note"],
        "ratings": None if task["ratings"] is None else
        [{"observer": o, "rating": r} for o, r in task["ratings"]],
        "model": task["model"],
    }
    model = None
    if task["model"] is not None:
        model, comparison, record["model_comparison"] = _compare_with_model(task, lmap, options)
    warning_lines = _warning_lines(caught)
    record["warnings"] = warning_lines
    row = _row(task, result.summary, list(score.values), record, warning_lines)
    # Every output but the marker as one group: all of them are renamed into place, or none.
    kinds = [k for k in outputs if k != "done"]
    with atomic_outputs(*(outputs[k] for k in kinds)) as paths:
        temp = dict(zip(kinds, paths))
        write_exr(lmap, temp["exr"])
        write_hdr(lmap, temp["hdr"])
        write_false_colour_png(lmap, temp["falsecolour"], title=f"{task['view']}: luminance")
        write_glare_source_png(lmap.luminance, score.source_labels, temp["sources"])
        write_source_labels(score.source_labels, temp["source_labels"])  # for the viewer
        write_contrast_png(score.contrast, temp["contrast"])
        temp["score"].write_text(json.dumps(record, indent=2, default=json_default),
                                 encoding="utf-8")
        if model is not None:
            write_exr(model, temp["model_exr"])
            write_ratio_png(comparison.ratio, temp["model_ratio"],
                            title=f"{task['view']}: model / photo")
            temp["model_json"].write_text(
                json.dumps(record["model_comparison"], indent=2, default=json_default),
                encoding="utf-8")
            write_comparison_report(comparison, temp["model_report"], photo=lmap, model=model,
                                    title=f"{task['view']}: model against photo")
    # The marker lists the view's files by kind (the report finds them through it).
    marker = {"schema": VIEW_RECORD_SCHEMA, "view": task["view"], "fingerprint": task["fingerprint"],
              "outputs": {k: v.name for k, v in outputs.items() if k != "done"}, "row": row}
    # Written last: its presence means every other output of the view is complete.
    atomic_text(outputs["done"], json.dumps(marker, indent=1, default=json_default))
    return row


def _compare_with_model(task, photo, options):
    """Render the view's scene model through the photo's camera and compare with the photo.

    Returns the model map, the :class:`~lsadphoto.compare.Comparison` and its JSON record.
    """
    from ..compare import compare_maps
    from ..solver import camera_to_world, read_scene, render, simulate

    spec = task["model"]
    scene = read_scene(spec["scene"])
    store = simulate(scene, samples=spec["samples"], seed=spec["seed"])
    rotation = camera_to_world(spec["direction"], spec.get("up", [0.0, 0.0, 1.0]))
    model = render(store, photo.projection, position=spec["position"], rotation=rotation,
                   nodes_per_pixel=spec["nodes_per_pixel"], seed=spec["seed"])
    if photo.line_of_sight is not None:
        model = dataclasses.replace(model, line_of_sight=photo.line_of_sight)
    score_options = {k: v for k, v in options.items() if k != "line_of_sight"}
    comparison = compare_maps(photo, model, **score_options)
    record = comparison.to_dict()
    record["model"] = {k: (str(v) if k == "scene" else v) for k, v in spec.items()}
    return model, comparison, record


def _warning_lines(caught):
    return list(dict.fromkeys(f"{w.category.__name__}: {w.message}" for w in caught))


def process_view(task):
    """Process one view in a worker; never raises for a problem of the view itself.

    Returns ``{"view", "ok", "row", "reason", "seconds"}``: ``reason`` is the one-line
    message of an :class:`~lsadphoto.errors.LsadError`, or ``"internal error: Type: msg"``.
    Warnings (saturation, non-uniform spots, …) go into the view's record and table row.
    """
    start = time.perf_counter()
    row, reason = None, None
    # Recording warnings changes process-wide state: safe in worker processes (the default),
    # not in several threads of one process at once.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            row = _process_view_outputs(task, caught)
        except LsadError as exc:
            reason = str(exc)
        except MemoryError:
            reason = "out of memory"
        except OSError as exc:  # disk full, a folder made read-only meanwhile, …
            reason = f"cannot write the view's outputs: {exc.strerror or exc} ({exc.filename})"
        except Exception as exc:  # noqa: BLE001 — reported, and the survey goes on
            reason = f"internal error: {type(exc).__name__}: {exc}"
    reason = None if reason is None else " ".join(reason.split())  # one line
    return {"view": task["view"], "ok": row is not None, "row": row, "reason": reason,
            "seconds": time.perf_counter() - start}


