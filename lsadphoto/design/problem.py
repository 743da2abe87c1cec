"""A design problem: the space, the catalogue, candidate positions, objectives, constraints.

Schema ``lsadphoto.design/1`` (TOML; paths relative to the problem file)::

    schema = "lsadphoto.design/1"
    space = "vestibule.toml"            # a scene the solver reads, with its [[views]];
                                        # its own luminaires stay on in every design
    dimming = [1.0]                     # output levels of an installed luminaire (0 = off
                                        # is always a choice)

    [catalogue.downlight]               # luminaire types
    photometry = "downlight.ies"        # IES LM-63 or EULUMDAT
    power_w = 18.0                      # input power at full output [W]

    [[positions]]                       # candidate positions (one luminaire at most each)
    position = [1.0, 1.0, 2.95]         # [m]
    nadir = [0, 0, -1]                  # optional aiming (default straight down)
    types = ["downlight"]               # optional: the types allowed here (default all)

    [[grids]]                           # calculation grids (solver.grids.work_plane_grid)
    name = "work plane"
    min = [0.5, 0.5]
    max = [5.5, 3.5]
    height = 0.8
    kind = "horizontal"                 # or "vertical" (with normal), "cylindrical"

    [[objectives]]                      # minimised or maximised, in order of priority
    metric = "ugr_grouped"              # see METRICS
    sense = "min"
    view = "all"                        # a view's name, or "all": the worst view

    [[constraints]]
    metric = "e_m"                      # mean illuminance of a grid
    grid = "work plane"
    min = 500.0

    [search]
    method = "auto"                     # "exhaustive", "nsga2" or "auto"
    max_exhaustive = 100000             # "auto" enumerates up to this many designs
    population = 40
    generations = 25
    seed = 0

    [simulation]
    samples = 65536                     # light chains per candidate
    grid_nodes = 4096                   # node draws per grid point

References
----------
EN 12464-1:2021 (maintained illuminance Ē, uniformity U₀, UGR limit); Deb, K., Pratap, A.,
Agarwal, S., Meyarivan, T. (2002), A fast and elitist multiobjective genetic algorithm:
NSGA-II, *IEEE Trans. Evol. Comput.* 6(2), 182–197.
"""

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._schema import ArrayOf, Key, Table, read_toml, validate
from ..errors import BadInputError

__all__ = ["METRICS", "SCHEMA", "DesignProblem", "load_problem", "luminaire_entry"]

SCHEMA = "lsadphoto.design/1"

#: Metrics a design can be judged by: per view (from lsadphoto.metrics.score_map), per grid,
#: and of the installation. "worst" is the direction in which a view is worse.
METRICS = {
    "q": {"scope": "view", "key": "q", "unit": "–"},
    "ugr_pixel": {"scope": "view", "key": "ugr_pixel", "unit": "–"},
    "ugr_grouped": {"scope": "view", "key": "ugr_grouped", "unit": "–"},
    "dgp": {"scope": "view", "key": "dgp", "unit": "–"},
    "e_v": {"scope": "view", "key": "E_v", "unit": "lx"},
    "e_m": {"scope": "grid", "unit": "lx"},
    "u0": {"scope": "grid", "unit": "–"},
    "power": {"scope": "design", "unit": "W"},
    "luminaires": {"scope": "design", "unit": "–"},
}

_POSITION = Table({"position": Key(list, required=True, items=float, length=3),
                   "nadir": Key(list, items=float, length=3, default=[0.0, 0.0, -1.0]),
                   "length_axis": Key(list, items=float, length=3, default=[1.0, 0.0, 0.0]),
                   "types": Key(list, items=str)})
_GRID = Table({"name": Key(str, required=True), "min": Key(list, required=True, items=float, length=2),
               "max": Key(list, required=True, items=float, length=2),
               "height": Key(float, default=0.8), "spacing": Key(float, minimum=0, exclusive=True),
               "border": Key(float, minimum=0, default=0.0),
               "kind": Key(str, default="horizontal", choices=("horizontal", "vertical", "cylindrical")),
               "normal": Key(list, items=float, length=3)})
_TARGET = {"metric": Key(str, required=True, choices=tuple(METRICS)), "view": Key(str, default="all"),
           "grid": Key(str)}
_OBJECTIVE = Table({**_TARGET, "sense": Key(str, default="min", choices=("min", "max"))})
_CONSTRAINT = Table({**_TARGET, "min": Key(float), "max": Key(float)})
PROBLEM_SCHEMA = Table({
    "schema": Key(str, default=SCHEMA, choices=(SCHEMA,)),
    "name": Key(str, default="design"),
    "space": Key(str, required=True),
    "dimming": Key(list, items=float, default=[1.0]),
    "catalogue": Table(open=True),
    "positions": ArrayOf(_POSITION, required=True, min_items=1),
    "grids": ArrayOf(_GRID),
    "objectives": ArrayOf(_OBJECTIVE, required=True, min_items=1),
    "constraints": ArrayOf(_CONSTRAINT),
    "search": Table({"method": Key(str, default="auto", choices=("auto", "exhaustive", "nsga2")),
                     "max_exhaustive": Key(int, minimum=1, default=100_000),
                     "population": Key(int, minimum=4, default=40),
                     "generations": Key(int, minimum=1, default=25),
                     "seed": Key(int, minimum=0, default=0)}),
    "simulation": Table({"samples": Key(int, minimum=256, default=65536),
                         "grid_nodes": Key(int, minimum=16, default=4096),
                         "seed": Key(int, minimum=0, default=0)}),
})
_TYPE = Table({"photometry": Key(str, required=True), "power_w": Key(float, required=True, minimum=0),
               "multiplier": Key(float, minimum=0, exclusive=True, default=1.0),
               "extent": Key(list, items=float, length=2)})


@dataclass
class DesignProblem:
    """A parsed and checked design problem (module docstring)."""

    path: Path
    name: str
    space: dict
    space_path: Path
    catalogue: dict
    positions: list
    dimming: list
    grids: list
    objectives: list
    constraints: list
    search: dict
    simulation: dict
    view_names: list = field(default_factory=list)

    @property
    def choices(self):
        """The choices at each position: ``[None, (type, level), …]`` (None = no luminaire)."""
        out = []
        for pos in self.positions:
            types = pos.get("types") or list(self.catalogue)
            out.append([None] + [(t, level) for t in types for level in self.dimming])
        return out

    @property
    def design_count(self):
        """Number of distinct designs (the product of the choices per position)."""
        return math.prod(len(c) for c in self.choices)


def load_problem(path):
    """Read and check a design problem; every problem is a one-line :class:`BadInputError`."""
    path = Path(path)
    data = read_toml(path, PROBLEM_SCHEMA, what="design problem")
    base = path.parent
    space_path = base / data["space"]
    if not space_path.is_file():
        raise BadInputError(f"{path}: space {space_path} does not exist")
    if space_path.suffix.lower() != ".toml":
        raise BadInputError(f"{path}: space {space_path} must be a TOML scene (the superposition "
                            "adds luminaires to its [[luminaires]])")
    try:
        space = tomllib.loads(space_path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise BadInputError(f"{space_path}: not a valid TOML scene ({exc})") from None
    catalogue = {}
    if not data["catalogue"]:
        raise BadInputError(f"{path}: the catalogue is empty")
    for name, spec in data["catalogue"].items():
        spec = validate(spec, _TYPE, source=f"{path}: catalogue.{name}")
        file = base / spec["photometry"]
        if not file.is_file():
            raise BadInputError(f"{path}: catalogue.{name}: photometric file {file} does not exist")
        catalogue[name] = dict(spec, photometry=str(file.resolve()))
    from ..solver import scene_from_dict

    first_type = next(iter(catalogue))
    probe = dict(space, luminaires=list(space.get("luminaires", []))
                 + [luminaire_entry(catalogue[first_type], data["positions"][0], name="probe")])
    scene = scene_from_dict(probe, base=space_path.parent)  # checks the space once, up front
    if not scene.views:
        raise BadInputError(f"{space_path}: the space has no [[views]] to judge designs by")
    views = [v.name for v in scene.views]
    if len(set(views)) != len(views):
        raise BadInputError(f"{space_path}: view names must be unique, got {views}")
    levels = data["dimming"]
    if not levels or any(not 0 < v <= 1 for v in levels) or len(set(levels)) != len(levels):
        raise BadInputError(f"{path}: dimming levels must be distinct values in (0, 1], got {levels}")
    corners = scene.triangles.reshape(-1, 3)
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    for k, pos in enumerate(data["positions"]):
        p = np.asarray(pos["position"])
        if np.any(p < lo) or np.any(p > hi):
            raise BadInputError(f"{path}: positions[{k}] {pos['position']} lies outside the space "
                                f"({lo.round(3).tolist()}–{hi.round(3).tolist()})")
        unknown = [t for t in pos.get("types") or [] if t not in catalogue]
        if unknown:
            raise BadInputError(f"{path}: positions[{k}] names unknown luminaire type {unknown[0]!r}; "
                                f"catalogue: {', '.join(catalogue)}")
    grid_names = [g["name"] for g in data["grids"]]
    for kind, entries in (("objectives", data["objectives"]), ("constraints", data["constraints"])):
        for k, entry in enumerate(entries):
            where = f"{path}: {kind}[{k}]"
            scope = METRICS[entry["metric"]]["scope"]
            if scope == "view" and entry["view"] != "all" and entry["view"] not in views:
                raise BadInputError(f"{where}: unknown view {entry['view']!r}; views: {', '.join(views)}")
            if scope == "grid" and entry.get("grid") not in grid_names:
                raise BadInputError(f"{where}: metric {entry['metric']!r} needs one of the grids "
                                    f"{grid_names or '(none defined)'}, got {entry.get('grid')!r}")
            if kind == "constraints":
                if entry.get("min") is None and entry.get("max") is None:
                    raise BadInputError(f"{where}: a constraint needs 'min' or 'max'")
                if entry.get("min") is not None and entry.get("max") is not None and entry["min"] > entry["max"]:
                    raise BadInputError(f"{where}: min {entry['min']} > max {entry['max']}: no design can meet it")
    _check_contradictions(path, data["constraints"])
    return DesignProblem(path=path, name=data["name"], space=space, space_path=space_path,
                         catalogue=catalogue, positions=data["positions"], dimming=levels,
                         grids=data["grids"], objectives=data["objectives"],
                         constraints=data["constraints"], search=data["search"],
                         simulation=data["simulation"], view_names=views)


def luminaire_entry(kind, position, *, name, level=1.0):
    """The ``[[luminaires]]`` scene entry of a catalogue type at a candidate position."""
    entry = {"type": "point", "name": name, "photometry": kind["photometry"],
             "position": list(position["position"]), "nadir": list(position["nadir"]),
             "length_axis": list(position["length_axis"]), "multiplier": kind["multiplier"] * level}
    if kind.get("extent") is not None:
        entry["extent"] = list(kind["extent"])
    return entry


def _check_contradictions(path, constraints):
    """Constraints on the same quantity whose ranges do not overlap cannot all be met."""
    ranges = {}
    for c in constraints:
        key = (c["metric"], c.get("view"), c.get("grid"))
        lo, hi = ranges.get(key, (-math.inf, math.inf))
        lo = max(lo, c["min"]) if c.get("min") is not None else lo
        hi = min(hi, c["max"]) if c.get("max") is not None else hi
        if lo > hi:
            raise BadInputError(f"{path}: constraints on {c['metric']} contradict each other "
                                f"(min {lo:g} > max {hi:g})")
        ranges[key] = (lo, hi)
