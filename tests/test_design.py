"""lsadphoto design: problem checks, exhaustive vs NSGA-II, and best.toml scored afresh."""

import json
from pathlib import Path

import pytest
import tomli_w

from lsadphoto.cli import main
from lsadphoto.datasets.design import make_design_samples
from lsadphoto.design.problem import load_problem
from lsadphoto.design.run import _grids, luminaire_entry
from lsadphoto.design.search import DesignEvaluator, pareto_front, search
from lsadphoto.design.superposition import solve_candidate
from lsadphoto.errors import BadInputError


def _tiny(folder, *, positions=((1.5, 1.0), (4.5, 3.0), (3.0, 2.0)), types=("downlight", "panel"),
          constraints=None, size=24):
    """The worked example reduced: 3 positions × (off + 2 types) = 27 designs, 24² views."""
    make_design_samples(folder, size=size)
    problem = tomllib_load(folder / "problem.toml")
    problem["catalogue"] = {k: v for k, v in problem["catalogue"].items() if k in types}
    problem["positions"] = [{"position": [x, y, 2.95]} for x, y in positions]
    problem["simulation"] = {"samples": 2048, "grid_nodes": 128}
    problem["search"] = {"method": "auto", "max_exhaustive": 1000}  # 27 designs: enumerated
    problem["grids"][0]["spacing"] = 2.5
    if constraints is not None:
        problem["constraints"] = constraints
    (folder / "problem.toml").write_text(tomli_w.dumps(problem))
    return folder / "problem.toml"


def tomllib_load(path):
    import tomllib

    return tomllib.loads(Path(path).read_text())


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The tiny problem with its candidates solved once."""
    path = _tiny(tmp_path_factory.mktemp("design"))
    problem = load_problem(path)
    grids = _grids(problem)
    solutions = {}
    for k, (i, kind) in enumerate((i, t) for i in range(len(problem.positions)) for t in problem.catalogue):
        lum = luminaire_entry(problem.catalogue[kind], problem.positions[i], name=f"p{i}-{kind}")
        solutions[(i, kind)] = solve_candidate(problem.space, lum, base=path.parent, grids=grids,
                                               samples=2048, seed=k + 1, grid_options={"nodes": 128})
    return path, problem, solutions


@pytest.mark.slow
def test_nsga2_finds_the_exhaustive_optimum_and_pareto_set(tiny):
    _, problem, solutions = tiny
    problem.search = dict(problem.search, method="exhaustive")
    exhaustive = search(DesignEvaluator(problem, solutions))
    assert exhaustive["evaluations"] == problem.design_count == 27
    # The Pareto set is every feasible design that no other feasible design dominates:
    # checked here by brute force against the definition.
    feasible = [r for r in exhaustive["evaluated"] if r.feasible]
    brute = {tuple(r.objectives) for r in feasible
             if not any(all(a <= b for a, b in zip(o.objectives, r.objectives)) and o.objectives != r.objectives
                        for o in feasible)}
    assert {tuple(r.objectives) for r in exhaustive["pareto"]} == brute
    problem.search = dict(problem.search, method="nsga2", population=8, generations=12, seed=3)
    genetic = search(DesignEvaluator(problem, solutions))
    assert genetic["best"].genome == exhaustive["best"].genome
    assert sorted(tuple(r.objectives) for r in genetic["pareto"]) == \
        sorted(tuple(r.objectives) for r in exhaustive["pareto"])


def test_pareto_front_definition():
    class R:
        def __init__(self, o):
            self.objectives = o
    rs = [R([1, 5]), R([2, 2]), R([3, 3]), R([5, 1]), R([2, 2])]
    assert [r.objectives for r in pareto_front(rs)] == [[1, 5], [2, 2], [5, 1]]


@pytest.mark.slow
def test_design_command_and_best_toml_scored_afresh(tiny, tmp_path):
    path, problem, _ = tiny
    out = tmp_path / "out"
    assert main(["design", str(path), "-o", str(out), "--quiet"]) == 0
    record = json.loads((out / "design.json").read_text())
    best = record["best"]
    assert record["method"] == "exhaustive" and record["pareto"]
    assert set(best["views"]) == {"desk", "door"}
    for v in best["views"].values():
        assert {"q", "ugr_pixel", "ugr_grouped", "uncertainty"} <= set(v)
    assert (out / "best.toml").is_file() and (out / "report.html").stat().st_size > 10_000
    # A rerun reuses every solved candidate (resumable).
    assert len(list((out / "candidates").glob("*.npz"))) == 6
    # best.toml is a scene the solver reads: render its desk view afresh (another seed, more
    # chains) and score it; the claimed metrics hold within their combined uncertainties.
    exr = tmp_path / "desk.exr"
    assert main(["render", str(out / "best.toml"), "--view-name", "desk", "--samples", "8192",
                 "--seed", "77", "-o", str(exr), "--quiet"]) == 0
    js = tmp_path / "score.json"
    assert main(["score", str(exr), "--output-json", str(js)]) == 0
    fresh = json.loads(js.read_text())
    claim = best["views"]["desk"]
    for key in ("ugr_grouped", "ugr_pixel", "q"):
        if claim[key] is None:
            assert fresh[key] is None
            continue
        u = (claim["uncertainty"][key] or 0.0) ** 2 + (fresh["uncertainty"][key] or 0.0) ** 2
        # 3σ of the two independent estimates, plus 2 % for the render's seed-dependent
        # source edges (a grouped source's pixels change where L crosses the threshold)
        assert abs(fresh[key] - claim[key]) <= 3 * u ** 0.5 + 0.02 * abs(claim[key]) + 1e-6, key


def _write(folder, problem):
    (folder / "problem.toml").write_text(tomli_w.dumps(problem))
    return folder / "problem.toml"


@pytest.mark.parametrize("change, message", [
    (lambda p: p["constraints"].append({"metric": "e_m", "grid": "work plane", "max": 100.0}),
     "constraints on e_m contradict each other"),
    (lambda p: p["positions"].append({"position": [9.0, 1.0, 2.9]}), "lies outside the space"),
    (lambda p: p["positions"][0].update(types=["chandelier"]), "unknown luminaire type 'chandelier'"),
    (lambda p: p["catalogue"]["downlight"].update(photometry="missing.ies"), "does not exist"),
    (lambda p: p["objectives"][0].update(view="attic"), "unknown view 'attic'"),
    (lambda p: p.update(objectivs=[]), "unknown key 'objectivs' (did you mean 'objectives'?)"),
    (lambda p: p["constraints"].append({"metric": "u0", "min": 0.5}), "needs one of the grids"),
])
def test_bad_problems_are_one_line_errors(tmp_path, capsys, change, message):
    make_design_samples(tmp_path, size=16)
    problem = tomllib_load(tmp_path / "problem.toml")
    change(problem)
    path = _write(tmp_path, problem)
    with pytest.raises(BadInputError, match=message.replace("(", r"\(").replace(")", r"\)").replace("?", r"\?")):
        load_problem(path)
    out = tmp_path / "out"
    assert main(["design", str(path), "-o", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err
    assert not out.exists()


@pytest.mark.slow
def test_infeasible_problem_reports_the_closest_designs(tmp_path):
    path = _tiny(tmp_path, positions=((1.5, 1.0),), constraints=[
        {"metric": "e_m", "grid": "work plane", "min": 1e6}])
    out = tmp_path / "out"
    assert main(["design", str(path), "-o", str(out), "--quiet"]) == 0
    record = json.loads((out / "design.json").read_text())
    assert record["best"] is None and record["closest"]
    assert "no design meets the constraints" in record["notes"][0]
    assert all("e_m[work plane]" in r["violations"][0][0] for r in record["closest"])
