"""Speed of design evaluations from precomputed candidates, and of the worked example.

Run: .venv/bin/python benchmarks/bench_design.py [--sizes 64,128,256] [--evaluations 20]
     [--example]   (from the repository root)

For each view size: the worked example's space (data_samples/design) with its two views at
that size, six candidate solutions (one solved candidate reused at every position: the
evaluation cost does not depend on which candidate it is), then random designs evaluated
through DesignEvaluator (superposition + score_map of both views + grid + power), CPU and
wall time per evaluation. With --example, the whole `lsadphoto design` of the worked example.
"""

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lsadphoto.datasets.design import make_design_samples  # noqa: E402
from lsadphoto.design.problem import load_problem  # noqa: E402
from lsadphoto.design.run import _grids, luminaire_entry  # noqa: E402
from lsadphoto.design.search import DesignEvaluator  # noqa: E402
from lsadphoto.design.superposition import solve_candidate  # noqa: E402


def evaluations(size, count):
    folder = make_design_samples(Path(tempfile.mkdtemp()), size=size)
    problem = load_problem(folder / "problem.toml")
    grids = _grids(problem)
    lum = luminaire_entry(problem.catalogue["downlight"], problem.positions[0], name="c")
    sol = solve_candidate(problem.space, lum, base=folder, grids=grids, samples=2048, seed=1,
                          grid_options={"nodes": 64})
    solutions = {(i, k): sol for i in range(len(problem.positions)) for k in problem.catalogue}
    ev = DesignEvaluator(problem, solutions)
    ev.evaluate((1,) * len(problem.positions))  # compiled kernels loaded
    rng = np.random.default_rng(0)
    genomes = {tuple(rng.integers(0, 4, len(problem.positions))) for _ in range(4 * count)}
    genomes = list(genomes)[:count]
    wall, cpu = time.perf_counter(), time.process_time()
    for g in genomes:
        ev.evaluate(g)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    n = len(genomes)
    print(f"| {size}² × 2 views | {n} | {1e3 * cpu / n:.1f} | {1e3 * wall / n:.1f} | {n / wall:.1f} |")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="64,128,256")
    ap.add_argument("--evaluations", type=int, default=20)
    ap.add_argument("--example", action="store_true")
    args = ap.parse_args()
    print("| views | designs | CPU per design [ms] | wall per design [ms] | designs per second |")
    print("|---|---|---|---|---|")
    for size in map(int, args.sizes.split(",")):
        evaluations(size, args.evaluations)
    if args.example:
        out = Path(tempfile.mkdtemp()) / "out"
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "lsadphoto.cli", "design",
                        str(ROOT / "data_samples" / "design" / "problem.toml"), "-o", str(out), "--quiet"],
                       check=True, cwd=ROOT)
        print(f"worked example (lsadphoto design, whole process): {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
