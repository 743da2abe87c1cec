"""Evaluating designs from precomputed candidates, and searching for the best ones.

A design chooses, at every candidate position, no luminaire or one catalogue type at one
dimming level (a *genome*: one choice index per position). Its maps and grids are the
superposition of the chosen candidates' solutions (:func:`~lsadphoto.design.superpose`);
its view metrics are those :func:`~lsadphoto.metrics.score_map` gives for them — so a
design's numbers are the numbers ``lsadphoto score`` gives for its render — evaluated for
many designs at once, without forming the maps, by
:class:`~lsadphoto.design.batch.BatchEvaluator`. Grid values (Ē, U₀), installed power and
the number of luminaires complete the record.

Undefined view metrics: a view without glare sources has no UGR or DGP from sources (NaN);
for objectives and constraints such a view counts as free of glare (UGR, DGP = 0). A view
whose Q or E_v is undefined counts as the worst possible.

The search is **exhaustive** where the design space is small (every design evaluated, in
batches, the exact Pareto set), otherwise **NSGA-II** (pymoo) over the integer genomes with
the constraints as one inequality constraint, uniform crossover and random-reset mutation
(a gene's choices are categories); the Pareto set reported is the non-dominated set of
every design evaluated. The **best** design is the feasible Pareto design that is best in the
first objective, ties broken by the following ones. When no design is feasible the records
closest to feasibility (smallest summed relative violation) are reported instead.

References
----------
Deb, K. et al. (2002), NSGA-II, *IEEE Trans. Evol. Comput.* 6(2), 182–197. Blank, J., Deb,
K. (2020), pymoo: Multi-Objective Optimization in Python, *IEEE Access* 8, 89497–89509.
"""

import itertools
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import BadInputError
from .problem import METRICS
from .superposition import superpose

__all__ = ["DesignEvaluator", "DesignRecord", "pareto_front", "search"]

#: Metrics that are 0 where a view has no glare source (undefined in score_map).
_GLARE = ("ugr_pixel", "ugr_grouped", "dgp")
#: Designs per batch of the exhaustive search.
_CHUNK = 4096
#: A view's metrics with an uncertainty in the records (score_map's names).
_UNCERTAIN = ("q", "ugr_pixel", "ugr_grouped", "dgp", "vertical_illuminance")


def _view_record(values):
    """A view's record from the batch evaluator's values: None where undefined; no
    uncertainties (the search's evaluations have the noise resampling off)."""
    out = {k: (float(values[k]) if math.isfinite(values[k]) else None)
           for k in ("q", "ugr_pixel", "ugr_grouped", "dgp", "E_v")}
    out["uncertainty"] = dict.fromkeys(_UNCERTAIN)
    out["sources"] = int(values["sources"])
    return out


@dataclass
class DesignRecord:
    """One evaluated design: its genome, choices, metric values, objectives, violations."""

    genome: tuple
    choices: list
    views: dict
    grids: dict
    power: float
    luminaires: int
    objectives: list
    violation: float
    violations: list = field(default_factory=list)

    @property
    def feasible(self):
        return self.violation <= 0

    def to_dict(self):
        return {"genome": list(self.genome), "choices": self.choices, "views": self.views,
                "grids": self.grids, "power_w": self.power, "luminaires": self.luminaires,
                "objectives": self.objectives, "feasible": self.feasible,
                "violation": self.violation, "violations": self.violations}


class DesignEvaluator:
    """Evaluates genomes of ``problem`` from the candidates' solutions (with a cache).

    The search evaluates designs in batches through :class:`~lsadphoto.design.batch.BatchEvaluator`
    (equal to score_map on the superposed maps, see there); :meth:`evaluate` with
    ``score_options`` scores the superposed maps with :func:`~lsadphoto.metrics.score_map`
    itself (the reported best design, with its uncertainties).

    Parameters
    ----------
    problem : DesignProblem
    solutions : dict
        ``(position index, type name) → CandidateSolution`` at full output.
    base : CandidateSolution, optional
        The space's own luminaires (always on), if it has any.
    """

    def __init__(self, problem, solutions, *, base=None):
        self.problem = problem
        self.choices = problem.choices
        self.solutions = solutions
        self.base = base
        self.keys = list(solutions)
        column = {key: k for k, key in enumerate(self.keys)}
        # choice (position i, index g) → (column, weight); g = 0 is off
        self.table = [[None] + [(column[(i, kind)], level) for kind, level in choices[1:]]
                      for i, choices in enumerate(self.choices)]
        self._batch = None
        self.cache = {}
        self.evaluations = 0
        self.seconds = 0.0

    @property
    def batch(self):
        """The :class:`~lsadphoto.design.batch.BatchEvaluator` (built on first use)."""
        if self._batch is None:
            from .batch import BatchEvaluator

            self._batch = BatchEvaluator([self.solutions[k] for k in self.keys],
                                         [[c for c in row if c is not None] for row in self.table],
                                         base=self.base)
        return self._batch

    def weights(self, genomes):
        """The (designs × candidates) weight matrix of ``genomes``."""
        genomes = np.atleast_2d(np.asarray(genomes, dtype=np.int64))
        w = np.zeros((genomes.shape[0], len(self.keys)))
        for i, row in enumerate(self.table):
            for g, choice in enumerate(row):
                if choice is not None:
                    w[genomes[:, i] == g, choice[0]] = choice[1]
        return w

    def combine(self, genome):
        """The chosen candidates and weights of ``genome``: (solutions, weights, choices)."""
        sols, weights, chosen = [], [], []
        if self.base is not None:
            sols.append(self.base)
            weights.append(1.0)
        for i, g in enumerate(genome):
            choice = self.choices[i][g]
            if choice is None:
                chosen.append(None)
                continue
            kind, level = choice
            sols.append(self.solutions[(i, kind)])
            weights.append(level)
            chosen.append({"type": kind, "level": level})
        return sols, weights, chosen

    def maps_and_grids(self, genome):
        """The superposed maps (per view) and grids of ``genome``."""
        sols, weights, _ = self.combine(genome)
        if not sols:  # nothing on: all dark
            sols, weights = [next(iter(self.solutions.values()))], [0.0]
        return superpose(sols, weights)

    def evaluate_many(self, genomes):
        """The :class:`DesignRecord` of each genome, new ones evaluated in one batch (cached)."""
        genomes = [tuple(int(g) for g in genome) for genome in genomes]
        new = list(dict.fromkeys(g for g in genomes if g not in self.cache))
        if new:
            t0 = time.perf_counter()
            values = self.batch.evaluate(self.weights(new))
            for k, genome in enumerate(new):
                views = {name: _view_record({key: v[key][k] for key in v}) for name, v in values["views"].items()}
                grids = {name: {key: float(v[key][k]) for key in v} for name, v in values["grids"].items()}
                self.cache[genome] = self._record(genome, views, grids)
            self.evaluations += len(new)
            self.seconds += time.perf_counter() - t0
        return [self.cache[g] for g in genomes]

    def evaluate(self, genome, *, score_options=None):
        """The :class:`DesignRecord` of ``genome``; with ``score_options`` (keywords of
        :func:`~lsadphoto.metrics.score_map`, noise resampling off unless given) scored by
        score_map on the superposed maps, with its uncertainties, and not cached."""
        if score_options is None:
            return self.evaluate_many([genome])[0]
        from ..metrics import score_map

        genome = tuple(int(g) for g in genome)
        maps, grids = self.maps_and_grids(genome)
        options = {"noise_samples": 0, "q_noise_samples": 0, **score_options}
        views = {}
        for name, lmap in maps.items():
            rec = score_map(lmap, **options).to_dict()
            views[name] = {"q": rec.get("q"), "ugr_pixel": rec.get("ugr_pixel"),
                           "ugr_grouped": rec.get("ugr_grouped"), "dgp": rec.get("dgp"),
                           "E_v": rec.get("vertical_illuminance"),
                           "uncertainty": {k: rec["uncertainty"].get(k) for k in _UNCERTAIN},
                           "sources": len(rec["sources"])}
        grid_values = {name: {"e_m": g.average, "e_m_standard_error": g.average_standard_error,
                              "e_min": g.minimum, "u0": g.uniformity}
                       for name, g in grids.items()}
        return self._record(genome, views, grid_values)

    def _record(self, genome, views, grids):
        chosen = [None if c is None else {"type": c[0], "level": c[1]}
                  for c in (self.choices[i][g] for i, g in enumerate(genome))]
        power = sum(self.problem.catalogue[c["type"]]["power_w"] * c["level"] for c in chosen if c)
        count = sum(1 for c in chosen if c)
        record = DesignRecord(genome=genome, choices=chosen, views=views, grids=grids,
                              power=float(power), luminaires=count, objectives=[], violation=0.0)
        record.objectives = [self._value(o, record, worst=o["sense"]) for o in self.problem.objectives]
        record.objectives = [v if o["sense"] == "min" else -v
                             for v, o in zip(record.objectives, self.problem.objectives)]
        record.violations = self._violations(record)
        record.violation = float(sum(v for _, v in record.violations))
        return record

    def _value(self, target, record, *, worst):
        """A metric's value for an objective/constraint; over views, the worst one."""
        metric = target["metric"]
        scope = METRICS[metric]["scope"]
        if scope == "design":
            return record.power if metric == "power" else float(record.luminaires)
        if scope == "grid":
            return float(record.grids[target["grid"]][metric])
        names = self.problem.view_names if target["view"] == "all" else [target["view"]]
        values = []
        for name in names:
            v = record.views[name][metric if metric != "e_v" else "E_v"]
            if v is None or not math.isfinite(v):
                v = 0.0 if metric in _GLARE else (math.inf if worst == "min" else -math.inf)
            values.append(v)
        return max(values) if worst == "min" else min(values)

    def _violations(self, record):
        out = []
        for c in self.problem.constraints:
            label = f"{c['metric']}" + (f"[{c['grid']}]" if c.get("grid") else "") + \
                (f"[{c['view']}]" if METRICS[c["metric"]]["scope"] == "view" else "")
            if c.get("max") is not None:
                v = self._value(c, record, worst="min")
                excess = (v - c["max"]) / max(abs(c["max"]), 1.0)
                if excess > 0:
                    out.append((f"{label} = {v:.4g} > {c['max']:g}", float(excess)))
            if c.get("min") is not None:
                v = self._value(c, record, worst="max")
                short = (c["min"] - v) / max(abs(c["min"]), 1.0)
                if short > 0:
                    out.append((f"{label} = {v:.4g} < {c['min']:g}", float(short)))
        return out


def pareto_front(records):
    """The non-dominated records (all objectives minimised), in input order; of records with
    identical objective vectors the first.

    Records are visited in lexicographic order of their objectives, so that any record that
    dominates another comes before it and only the front found so far needs checking.
    """
    objs = np.array([r.objectives for r in records], dtype=float)
    if objs.size == 0:
        return []
    order = np.lexsort(objs.T[::-1])
    front = []
    for i in order:
        a = objs[i]
        if front:
            f = objs[front]
            if np.any(np.all(f <= a, axis=1)):  # dominated, or a copy of a front member
                continue
        front.append(i)
    # of identical vectors the lexsort keeps the first in input order (a stable sort)
    return [records[i] for i in sorted(front)]


def _best(front):
    return min(front, key=lambda r: tuple(r.objectives)) if front else None


def search(evaluator, *, progress=None):
    """Search the design space of ``evaluator.problem``; return a result dict.

    Returns
    -------
    dict
        ``method``, ``evaluated`` (records), ``pareto`` (feasible non-dominated records),
        ``best`` (record or None), ``closest`` (least-violating records when none is
        feasible), ``evaluations``, ``seconds``.
    """
    problem = evaluator.problem
    settings = problem.search
    count = problem.design_count
    method = settings["method"]
    if method == "auto":
        method = "exhaustive" if count <= settings["max_exhaustive"] else "nsga2"
    if method == "exhaustive":
        if count > 10 * settings["max_exhaustive"]:
            raise BadInputError(f"exhaustive search over {count} designs is too large "
                                f"(max_exhaustive = {settings['max_exhaustive']}); use method = 'nsga2'")
        ranges = [range(len(c)) for c in evaluator.choices]
        genomes = itertools.product(*ranges)
        done = 0
        while chunk := list(itertools.islice(genomes, _CHUNK)):
            evaluator.evaluate_many(chunk)
            done += len(chunk)
            if progress is not None:
                progress(done / count, None)
    else:
        _nsga2(evaluator, settings, progress)
    records = list(evaluator.cache.values())
    feasible = [r for r in records if r.feasible]
    front = pareto_front(feasible)
    closest = [] if feasible else sorted(records, key=lambda r: r.violation)[:5]
    return {"method": method, "design_count": count, "evaluated": records, "pareto": front,
            "best": _best(front), "closest": closest, "evaluations": evaluator.evaluations,
            "seconds": evaluator.seconds}


def _nsga2(evaluator, settings, progress):
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.mutation import Mutation
    from pymoo.core.problem import Problem
    from pymoo.operators.crossover.ux import UniformCrossover
    from pymoo.operators.sampling.rnd import IntegerRandomSampling
    from pymoo.optimize import minimize

    n_obj = len(evaluator.problem.objectives)
    upper = np.array([len(c) - 1 for c in evaluator.choices])
    generations = settings["generations"]

    class _Problem(Problem):
        def __init__(self):
            super().__init__(n_var=len(upper), n_obj=n_obj, n_ieq_constr=1, xl=0, xu=upper,
                             vtype=int)
            self.generation = 0

        def _evaluate(self, X, out, *args, **kwargs):
            recs = evaluator.evaluate_many(np.clip(np.rint(X), 0, upper).astype(int))
            out["F"] = np.array([r.objectives for r in recs], dtype=float)
            out["G"] = np.array([[r.violation] for r in recs], dtype=float)
            self.generation += 1
            if progress is not None:
                progress(min(1.0, self.generation / (generations + 1)), None)

    class _Reset(Mutation):
        """Random reset: each gene, with probability 1/genes, takes any of its choices. A
        gene's choices (off, or a type at a level) are categories, without an order that a
        small step (polynomial mutation) or a blend (SBX) could follow."""

        def _do(self, problem, X, random_state=None, **kwargs):
            reset = random_state.random(X.shape) < self.get_prob_var(problem, size=(len(X), 1))
            return np.where(reset, random_state.integers(0, upper + 1, size=X.shape), X)

    algorithm = NSGA2(pop_size=settings["population"], sampling=IntegerRandomSampling(),
                      crossover=UniformCrossover(), mutation=_Reset(), eliminate_duplicates=True)
    minimize(_Problem(), algorithm, ("n_gen", generations), seed=settings["seed"], verbose=False)
