"""Speed of design evaluations from precomputed candidates, NSGA-II against enumeration,
and the whole worked example.

Run: .venv/bin/python benchmarks/bench_design.py [--sizes 64,256] [--designs 20000]
     [--before 5] [--samples 256] [--enumerate SIZE] [--example] [--cache DIR]
     (from the repository root)

For each view size: the worked example's space (data_samples/design) with its two views at
that size and its 18 candidates (6 positions × 3 types), each solved with ``--samples``
light chains (the evaluation cost does not depend on the candidates' noise). Then

* **before**: ``--before`` random designs scored one by one the way the search did before
  the batch evaluator — superposed maps, ``score_map`` of both views (noise resampling off),
  grid values (``DesignEvaluator.evaluate(genome, score_options={})``);
* **after**: ``--designs`` random designs through ``BatchEvaluator.evaluate``. Each evaluation
  includes, for both views, Q, pixel-wise UGR, grouped UGR, DGP, E_v and the number of
  grouped sources, and for the grid Ē, Ē's standard error, E_min and U₀ — every metric the
  design records hold — equal to score_map (tests/test_design_batch.py);
* **records**: the same designs through ``DesignEvaluator.evaluate_many``, which adds the
  records, objectives and constraint violations the search works on.

CPU [s] is the process time (all threads), wall the elapsed time. ``--enumerate SIZE``: the
worked example's space with 8 candidate positions × (off + 3 types) = 65 536 designs at
SIZE² views, enumerated and searched by NSGA-II at several settings, for three objective
sets (how much of the exhaustive Pareto set each recovers). ``--example``: the whole ``lsadphoto design`` of the
worked example (solving its candidates included).
"""

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import tomli_w

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lsadphoto.datasets.design import make_design_samples  # noqa: E402
from lsadphoto.design.problem import load_problem  # noqa: E402
from lsadphoto.design.run import _grids, _load_candidate, _save_candidate, luminaire_entry  # noqa: E402
from lsadphoto.design.search import DesignEvaluator, search  # noqa: E402
from lsadphoto.design.superposition import solve_candidate  # noqa: E402

#: 8 ceiling positions for the enumeration (as tests/test_design_batch.py).
EIGHT = [(1.0, 1.0), (1.0, 3.0), (2.3, 1.3), (2.3, 2.7), (3.7, 1.3), (3.7, 2.7), (5.0, 1.0), (5.0, 3.0)]


def _solved(size, samples, positions=None, search_settings=None, cache=None):
    """The worked example at ``size``² views and its candidates, solved (or read from
    ``cache``, a folder of candidate files named by size, chains, position and type)."""
    import tomllib

    folder = make_design_samples(Path(tempfile.mkdtemp()), size=size)
    if positions is not None:
        doc = tomllib.loads((folder / "problem.toml").read_text())
        doc["positions"] = [{"position": [x, y, 2.95]} for x, y in positions]
        doc["search"] = search_settings
        (folder / "problem.toml").write_text(tomli_w.dumps(doc))
    problem = load_problem(folder / "problem.toml")
    grids = _grids(problem)
    t0 = time.perf_counter()
    solutions = {}
    for k, (i, kind) in enumerate((i, t) for i in range(len(problem.positions)) for t in problem.catalogue):
        lum = luminaire_entry(problem.catalogue[kind], problem.positions[i], name=f"p{i}-{kind}")
        path = None if cache is None else \
            Path(cache) / f"{size}-{samples}-{len(problem.positions)}-{i}-{kind}.npz"
        if path is not None and path.is_file():
            solutions[(i, kind)] = _load_candidate(path, grids)
            continue
        solutions[(i, kind)] = solve_candidate(problem.space, lum, base=folder, grids=grids, samples=samples,
                                               seed=k + 1, grid_options={"nodes": 64})
        if path is not None:
            _save_candidate(solutions[(i, kind)], path)
    print(f"  ({len(solutions)} candidates at {size}², {samples} chains: {time.perf_counter() - t0:.0f} s)")
    return problem, solutions


def _timed(fn):
    wall, cpu = time.perf_counter(), time.process_time()
    result = fn()
    return result, time.process_time() - cpu, time.perf_counter() - wall


def evaluations(size, designs, before, samples, cache):
    problem, solutions = _solved(size, samples, cache=cache)
    evaluator = DesignEvaluator(problem, solutions)
    rng = np.random.default_rng(0)
    genomes = rng.integers(0, 4, (designs, len(problem.positions)))
    _, cpu, wall = _timed(lambda: evaluator.batch)
    print(f"  (batch evaluator set up in {cpu:.1f} s CPU, {wall:.1f} s wall)")
    rows = []
    if before:
        evaluator.evaluate(genomes[0], score_options={})  # compiled kernels loaded
        _, cpu, wall = _timed(lambda: [evaluator.evaluate(g, score_options={}) for g in genomes[1:before + 1]])
        rows.append(("before: superpose + score_map", before, cpu, wall))
    weights = evaluator.weights(genomes)
    evaluator.batch.evaluate(weights[:1024])  # compiled kernels loaded, patterns found
    _, cpu, wall = _timed(lambda: evaluator.batch.evaluate(weights))
    rows.append(("after: BatchEvaluator.evaluate", designs, cpu, wall))
    _, cpu, wall = _timed(lambda: evaluator.evaluate_many(genomes))
    rows.append(("after: DesignEvaluator.evaluate_many (records)", len(evaluator.cache), cpu, wall))
    for label, n, cpu, wall in rows:
        print(f"| {size}² × 2 views | {label} | {n} | {1e6 * cpu / n:.0f} | {1e6 * wall / n:.0f} | "
              f"{n / cpu:.0f} | {n / wall:.0f} |")


#: Objective sets of the enumeration: the worked example's, and the two of
#: tests/test_design_batch.py's problem.
OBJECTIVES = {
    "min worst grouped UGR, min power": [{"metric": "ugr_grouped", "sense": "min", "view": "all"},
                                         {"metric": "power", "sense": "min", "view": "all"}],
    "max Q (desk), max U₀": [{"metric": "q", "sense": "max", "view": "desk"},
                             {"metric": "u0", "sense": "max", "grid": "work plane", "view": "all"}],
    "max Ē, min power": [{"metric": "e_m", "sense": "max", "grid": "work plane", "view": "all"},
                         {"metric": "power", "sense": "min", "view": "all"}],
}


def enumeration(size, samples, cache):
    problem, solutions = _solved(size, samples, positions=EIGHT, cache=cache,
                                 search_settings={"method": "exhaustive", "max_exhaustive": 70000})
    for label, objectives in OBJECTIVES.items():
        problem.objectives = objectives
        problem.search = {"method": "exhaustive", "max_exhaustive": 70000}
        exhaustive, cpu, wall = _timed(lambda: search(DesignEvaluator(problem, solutions)))
        truth = {tuple(r.objectives) for r in exhaustive["pareto"]}
        print(f"| {label} | exhaustive | – | {exhaustive['evaluations']} | {cpu:.1f} | {wall:.1f} | yes | "
              f"{len(truth)} of {len(truth)} |")
        for population, generations in ((40, 40), (100, 80), (128, 100)):
            for seed in (0, 1, 2):
                problem.search = {"method": "nsga2", "population": population, "generations": generations,
                                  "seed": seed, "max_exhaustive": 70000}
                genetic, cpu, wall = _timed(lambda: search(DesignEvaluator(problem, solutions)))
                found = {tuple(r.objectives) for r in genetic["pareto"]}
                best = genetic["best"] is not None and genetic["best"].objectives == exhaustive["best"].objectives
                print(f"| {label} | NSGA-II {population} × {generations} | {seed} | {genetic['evaluations']} | "
                      f"{cpu:.1f} | {wall:.1f} | {'yes' if best else 'no'} | {len(found & truth)} of "
                      f"{len(truth)}{'' if found <= truth else ' (+ ' + str(len(found - truth)) + ' not on it)'} |")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="64,256")
    ap.add_argument("--designs", type=int, default=20000)
    ap.add_argument("--before", type=int, default=5)
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--enumerate", type=int, default=0, metavar="SIZE")
    ap.add_argument("--example", action="store_true")
    ap.add_argument("--cache", help="folder keeping solved candidates between runs")
    args = ap.parse_args()
    print("| views | evaluator | designs | CPU per design [µs] | wall per design [µs] | "
          "designs per CPU-second | designs per second (wall) |")
    print("|---|---|---|---|---|---|---|")
    for size in map(int, filter(None, args.sizes.split(","))):
        evaluations(size, args.designs, args.before, args.samples, args.cache)
    if args.enumerate:
        print("| objectives | search | seed | designs evaluated | CPU [s] | wall [s] | optimum found | "
              "exhaustive Pareto points recovered |")
        print("|---|---|---|---|---|---|---|---|")
        enumeration(args.enumerate, args.samples, args.cache)
    if args.example:
        out = Path(tempfile.mkdtemp()) / "out"
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "lsadphoto.cli", "design",
                        str(ROOT / "data_samples" / "design" / "problem.toml"), "-o", str(out), "--quiet"],
                       check=True, cwd=ROOT)
        print(f"worked example (lsadphoto design, whole process): {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
