"""``lsadphoto design``: solve the candidates once, search, and write the chosen design.

Outputs in the folder ``OUT``: ``design.json`` (the Pareto set under ``pareto``, the chosen
design under ``best`` with ``best.views.NAME`` = {q, ugr_pixel, ugr_grouped, dgp, E_v,
uncertainty} and ``best.grids``), ``best.toml`` (the space with the chosen luminaires: a scene
file the solver reads, with the problem's views under the same names) and ``report.html``.
They are written together, all or none, after the search. The candidates' solutions are kept
in ``OUT/candidates/`` as each is finished (one ``.npz`` per candidate, keyed by a hash of
everything it depends on), so an interrupted run resumes where it stopped and a changed
problem reuses every candidate that did not change.
"""

import hashlib
import json
import math
import time
from pathlib import Path

import numpy as np

from .._atomic import atomic_path, plan_outputs
from .._provenance import build_provenance
from ..geometry.base import projection_from_dict
from ..luminance_map import LuminanceMap
from ..solver.grids import GridIlluminance, work_plane_grid
from .problem import load_problem, luminaire_entry
from .search import DesignEvaluator, search
from .superposition import CandidateSolution, solve_candidate

__all__ = ["run_design"]

#: Layout of a candidate file (bump when it changes).
_CANDIDATE_FORMAT = "lsadphoto.design-candidate/1"


def _grids(problem):
    return [work_plane_grid(g["min"], g["max"], height=g["height"], spacing=g.get("spacing"),
                            border=g["border"], name=g["name"], kind=g["kind"], normal=g.get("normal"))
            for g in problem.grids]


def _key(problem, luminaire):
    text = json.dumps({"format": _CANDIDATE_FORMAT, "space": problem.space, "luminaire": luminaire,
                       "simulation": problem.simulation, "grids": problem.grids,
                       "photometry": _file_hash(luminaire.get("photometry"))},
                      sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _file_hash(path):
    if not path:
        return None
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _save_candidate(sol, path):
    arrays = {}
    meta = {"format": _CANDIDATE_FORMAT, "name": sol.name, "luminaire": sol.luminaire, "flux": sol.flux,
            "provenance": sol.provenance, "views": {}, "grids": {}}
    for k, (view, m) in enumerate(sol.maps.items()):
        arrays[f"v{k}_L"] = m.luminance
        arrays[f"v{k}_u"] = m.uncertainty
        meta["views"][view] = {"index": k, "projection": m.projection.to_dict()}
    for k, (name, g) in enumerate(sol.grids.items()):
        for part in ("illuminance", "standard_error", "direct", "indirect"):
            arrays[f"g{k}_{part}"] = getattr(g, part)
        meta["grids"][name] = {"index": k, "average": g.average, "average_standard_error":
                               g.average_standard_error, "minimum": g.minimum,
                               "uniformity": g.uniformity, "notes": g.notes}
    arrays["meta"] = np.frombuffer(json.dumps(meta, default=str).encode(), dtype=np.uint8)
    with atomic_path(path) as temp:
        with open(temp, "wb") as fh:
            np.savez(fh, **arrays)


def _load_candidate(path, grids):
    with np.load(path, allow_pickle=False) as data:
        meta = json.loads(bytes(data["meta"]).decode())
        if meta.get("format") != _CANDIDATE_FORMAT:
            return None
        maps = {view: LuminanceMap(data[f"v{v['index']}_L"], uncertainty=data[f"v{v['index']}_u"],
                                   projection=projection_from_dict(v["projection"]), calibrated=True)
                for view, v in meta["views"].items()}
        by_name = {g.name: g for g in grids}
        results = {}
        for name, g in meta["grids"].items():
            k = g["index"]
            results[name] = GridIlluminance(grid=by_name[name], illuminance=data[f"g{k}_illuminance"],
                                            standard_error=data[f"g{k}_standard_error"],
                                            direct=data[f"g{k}_direct"], indirect=data[f"g{k}_indirect"],
                                            average=g["average"],
                                            average_standard_error=g["average_standard_error"],
                                            minimum=g["minimum"], uniformity=g["uniformity"],
                                            notes=g["notes"])
    return CandidateSolution(name=meta["name"], luminaire=meta["luminaire"], maps=maps, grids=results,
                             flux=meta["flux"], provenance=meta["provenance"])


def _clean(value):
    """JSON-safe: non-finite floats become None."""
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def _best_scene(problem, record):
    """The best design as TOML scene text: the space plus its luminaires at their levels."""
    import tomli_w

    doc = dict(problem.space)
    lums = list(problem.space.get("luminaires", []))
    for i, choice in enumerate(record.choices):
        if choice:
            lums.append(luminaire_entry(problem.catalogue[choice["type"]], problem.positions[i],
                                        name=f"p{i}-{choice['type']}", level=choice["level"]))
    # The space's own relative paths (its luminaires' photometric files) are relative to the
    # space's folder: made absolute, so that best.toml reads from wherever it is.
    doc["luminaires"] = [dict(lum, photometry=str((problem.space_path.parent / lum["photometry"]).resolve()))
                         if "photometry" in lum and not Path(lum["photometry"]).is_absolute() else lum
                         for lum in lums]
    return tomli_w.dumps(_clean(doc))


def run_design(problem_path, outdir, *, report=None, progress=None, log=print):
    """Solve, search and write a design problem's results into ``outdir``.

    Parameters
    ----------
    problem_path : path-like
        A ``lsadphoto.design/1`` TOML file (:mod:`~lsadphoto.design.problem`).
    outdir : path-like
        Output folder (created).
    report : callable, optional
        ``report(record, best_maps) → HTML text`` for ``report.html`` (the report layer's
        :func:`lsadphoto.report.design.design_report_html`, passed in by the caller: the
        design layer sits below the reports). Without it no report is written.
    progress : callable, optional
        ``progress(stage, done_fraction)``.
    log : callable
        Receives one line per stage.

    Returns
    -------
    dict
        The ``design.json`` record.
    """
    problem = load_problem(problem_path)
    out = Path(outdir)
    plan = plan_outputs({"json": out / "design.json", "toml": out / "best.toml",
                         "report": None if report is None else out / "report.html"})
    cache = out / "candidates"
    grids = _grids(problem)
    sim = problem.simulation
    t0 = time.perf_counter()
    solutions, reused = {}, 0
    jobs = [(i, t) for i, pos in enumerate(problem.positions) for t in (pos.get("types") or problem.catalogue)]
    for k, (i, kind) in enumerate(jobs):
        lum = luminaire_entry(problem.catalogue[kind], problem.positions[i], name=f"p{i}-{kind}")
        path = cache / f"{_key(problem, lum)}.npz"
        sol = _load_candidate(path, grids) if path.is_file() else None
        if sol is None:
            sol = solve_candidate(problem.space, lum, name=lum["name"], base=problem.space_path.parent,
                                  grids=grids, samples=sim["samples"], seed=sim["seed"] + 1 + k,
                                  grid_options={"nodes": sim["grid_nodes"]})
            _save_candidate(sol, path)
        else:
            reused += 1
        solutions[(i, kind)] = sol
        if progress is not None:
            progress("candidates", (k + 1) / len(jobs))
    base = None
    if problem.space.get("luminaires"):
        base = solve_candidate(problem.space, None, name="space", base=problem.space_path.parent,
                               grids=grids, samples=sim["samples"], seed=sim["seed"],
                               grid_options={"nodes": sim["grid_nodes"]})
    t_solve = time.perf_counter() - t0
    log(f"{len(jobs)} candidates solved ({reused} reused from {cache}) in {t_solve:.1f} s")
    evaluator = DesignEvaluator(problem, solutions, base=base)
    result = search(evaluator, progress=None if progress is None else
                    (lambda f, _eta: progress("search", f)))
    rate = result["evaluations"] / result["seconds"] if result["seconds"] > 0 else math.nan
    log(f"{result['method']} search: {result['evaluations']} of {result['design_count']} designs "
        f"evaluated ({rate:.0f} per second)")
    best = result["best"]
    notes = []
    if best is None:
        notes.append("no design meets the constraints: 'closest' lists the designs nearest to "
                     "feasibility with what each violates")
        log(notes[-1])
    record = {
        "schema": "lsadphoto.design-result/1", "problem": str(problem.path), "name": problem.name,
        "method": result["method"], "design_count": result["design_count"],
        "evaluations": result["evaluations"], "evaluations_per_second": rate,
        "objectives": problem.objectives, "constraints": problem.constraints,
        "positions": problem.positions, "catalogue": problem.catalogue,
        "pareto": [r.to_dict() for r in result["pareto"]],
        "best": None, "closest": [r.to_dict() for r in result["closest"]], "notes": notes,
        "provenance": build_provenance(arguments={"problem": str(problem.path), "output": str(out)},
                                       inputs=[problem.path, problem.space_path]),
    }
    toml_text = None
    best_maps = {}
    if best is not None:
        # The reported best design is scored afresh with the noise propagation on, so that
        # its uncertainties include the candidates' per-pixel Monte Carlo errors.
        scored = evaluator.evaluate(best.genome, score_options={"noise_samples": 256, "q_noise_samples": 4})
        record["best"] = scored.to_dict()
        toml_text = _best_scene(problem, best)
        best_maps, _ = evaluator.maps_and_grids(best.genome)
    record = _clean(record)
    html = None if report is None else report(record, best_maps)
    with plan.write() as temps:
        temps["json"].write_text(json.dumps(record, indent=1), encoding="utf-8")
        temps["toml"].write_text(toml_text if toml_text is not None else
                                 "# no feasible design: see design.json 'closest'\n", encoding="utf-8")
        if html is not None:
            temps["report"].write_text(html, encoding="utf-8")
    return record
