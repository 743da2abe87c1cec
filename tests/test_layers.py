"""The package's import structure follows DESIGN.md (read from the source with ``ast``).

Three rules (DESIGN.md, "Layout"):

1. no import cycle between lsadphoto modules — every import counts, also one made inside a
   function (a deferred import hides a cycle from the interpreter, not from the design);
2. a private module (a path part ``_name``) is imported only from inside its own package,
   except the foundation's top-level ``lsadphoto/_*.py`` modules;
3. layers, lowest first: foundation → geometry, luminance_map, io → raw → calibrate →
   luminance; metrics; solver; compare, study, design; report, viewer; survey; cli — a module
   imports only from its own layer or lower ones.

Today's violations are listed below, each with the issue that removes it, so that the test
fails on any new one and on an entry that is no longer needed (delete it then).
"""

import ast
from collections import defaultdict
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "lsadphoto"

#: Layer of each top-level module or subpackage of lsadphoto (DESIGN.md; lowest first).
#: DESIGN.md does not name ``datasets`` (synthetic data: the synthetic camera, scenes, and the
#: demo survey rendered by the solver and scored) nor ``demo`` (``make demo``): the first is
#: placed with the workflows that sit on the solver and the metrics, the second with the CLI.
LAYERS = [
    {"errors", "constants", "_validation", "_schema", "_atomic", "_provenance", "_progress", "_version",
     "_lazy", "_native", "_compiled"},
    {"geometry", "luminance_map", "io"},
    {"raw"},
    {"calibrate"},
    {"luminance"},
    {"metrics"},
    {"solver"},
    {"compare", "study", "design", "datasets"},
    {"report", "viewer"},
    {"survey"},
    {"cli", "demo", "__init__"},
]
RANK = {name: rank for rank, names in enumerate(LAYERS) for name in names}

#: Known cycles, each as the sorted modules of one strongly connected component, with the issue
#: that removes it. None today (issue 17 split the solver's estimators into solver/integrators/,
#: below the simulation and the public render).
ALLOWED_CYCLES = {}

#: Known cross-package imports of private modules: (importer, private module) → issue. None
#: today (issue 17 moved the grouped atomic writer from io/_atomic.py to the foundation).
ALLOWED_PRIVATE = {}

#: Known imports from a higher layer: (importer, imported module) → issue. None today.
ALLOWED_LAYER = {}


def _module_name(path):
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules():
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _lazy_table(name, tree):
    """``{public name: submodule}`` of a package ``__init__`` that calls
    ``lazy_exports(__name__, globals(), {".sub": [names]})`` (lsadphoto/_lazy.py): an access
    to the name imports the submodule, so it is an import of that submodule."""
    table = {}
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "lazy_exports"
                and len(node.args) == 3 and isinstance(node.args[2], ast.Dict)):
            for key, value in zip(node.args[2].keys, node.args[2].values, strict=True):
                relative = ast.literal_eval(key)
                module = name + relative if relative.startswith(".") else relative
                for item in ast.literal_eval(value):
                    table[item] = module
    return table


def _imports(name, path, modules, lazy):
    """lsadphoto modules that module ``name`` imports (anywhere in its source)."""
    is_package = path.name == "__init__.py"
    here = name if is_package else name.rsplit(".", 1)[0]
    found = set(lazy.get(name, {}).values())

    def add(target, names=()):
        # ``from X import y``: y is a submodule, or a lazy name of X's submodule, or a name in X.
        rest = []
        for n in names:
            if f"{target}.{n}" in modules:
                found.add(f"{target}.{n}")
            elif n in lazy.get(target, {}):
                found.add(lazy[target][n])
            else:
                rest.append(n)
        if (rest or not names) and target in modules:
            found.add(target)

    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name == "lsadphoto" or alias.name.startswith("lsadphoto."):
                    add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here.split(".")[: len(here.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target == "lsadphoto" or target.startswith("lsadphoto."):
                add(target, [a.name for a in node.names])
    found.discard(name)
    return found


@pytest.fixture(scope="module")
def graph():
    modules = _modules()
    lazy = {name: _lazy_table(name, ast.parse(path.read_text(encoding="utf-8")))
            for name, path in modules.items() if path.name == "__init__.py"}
    return {name: _imports(name, path, modules, lazy) for name, path in modules.items()}


def _cycles(graph):
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index, low, on_stack, stack, components = {}, {}, set(), [], []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    components.append(tuple(sorted(component)))
    return components


def _unit(name):
    """The top-level module or subpackage of lsadphoto that ``name`` belongs to."""
    parts = name.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _private_owner(name):
    """Package that owns ``name``'s innermost private part, or None for a public module.

    The foundation's top-level private modules (``lsadphoto._x``) are shared by design.
    """
    parts = name.split(".")
    for i in range(len(parts) - 1, 0, -1):
        if parts[i].startswith("_"):
            return None if i == 1 else ".".join(parts[:i])
    return None


def test_the_reader_sees_the_package(graph):
    # The scan is not vacuous: the CLI reaches the luminance pipeline, the survey the solver.
    assert len(graph) > 50
    assert "lsadphoto.luminance" in graph["lsadphoto.cli"] or any(
        m.startswith("lsadphoto.luminance") for m in graph["lsadphoto.cli"])
    assert any(m.startswith("lsadphoto.geometry") for m in graph["lsadphoto.io.hdr"])
    # A lazy public name (lsadphoto/_lazy.py) counts as an import of the submodule defining it.
    assert {"lsadphoto.io.exr", "lsadphoto.io.hdr"} <= graph["lsadphoto.io"]


def test_every_part_of_the_package_has_a_layer(graph):
    unknown = sorted({_unit(m) for m in graph} - set(RANK))
    assert not unknown, f"add these to LAYERS as DESIGN.md places them: {unknown}"


def test_no_import_cycles(graph):
    found = {cycle: None for cycle in _cycles(graph)}
    new = sorted(set(found) - set(ALLOWED_CYCLES))
    assert not new, f"new import cycles: {new}"
    stale = sorted(set(ALLOWED_CYCLES) - set(found))
    assert not stale, f"cycles gone, remove from ALLOWED_CYCLES: {stale}"


def _private_violations(graph):
    found = set()
    for importer, targets in graph.items():
        for target in targets:
            owner = _private_owner(target)
            if owner is not None and not (importer == owner or importer.startswith(owner + ".")):
                found.add((importer, target))
    return found


def _layer_violations(graph):
    found = set()
    for importer, targets in graph.items():
        for target in targets:
            if RANK.get(_unit(target), -1) > RANK.get(_unit(importer), len(LAYERS)):
                found.add((importer, target))
    return found


def test_private_modules_stay_in_their_package(graph):
    found = _private_violations(graph)
    new = sorted(found - set(ALLOWED_PRIVATE))
    assert not new, f"private modules used outside their package: {new}"
    stale = sorted(set(ALLOWED_PRIVATE) - found)
    assert not stale, f"no longer used, remove from ALLOWED_PRIVATE: {stale}"


def test_layers_point_down(graph):
    found = _layer_violations(graph)
    new = sorted(found - set(ALLOWED_LAYER))
    assert not new, f"imports from a higher layer: {new}"
    stale = sorted(set(ALLOWED_LAYER) - found)
    assert not stale, f"gone, remove from ALLOWED_LAYER: {stale}"


def test_the_rules_catch_violations():
    # The checks themselves, on made-up graphs with one violation of each kind.
    fake = {"lsadphoto.geometry.pinhole": {"lsadphoto.solver.scene"},  # up from layer 1 to 6
            "lsadphoto.solver.scene": {"lsadphoto.geometry._kernels",  # another package's private
                                       "lsadphoto._validation"},        # the foundation's: fine
            "lsadphoto.geometry.field": {"lsadphoto.geometry._kernels"}}  # its own: fine
    assert _layer_violations(fake) == {("lsadphoto.geometry.pinhole", "lsadphoto.solver.scene")}
    assert _private_violations(fake) == {("lsadphoto.solver.scene", "lsadphoto.geometry._kernels")}


def test_cycle_finder_finds_cycles():
    # The finder itself, on a known graph: a → b → c → a and d → e → d, f alone.
    g = defaultdict(set, {"a": {"b"}, "b": {"c"}, "c": {"a", "f"}, "d": {"e"}, "e": {"d"}, "f": set()})
    assert sorted(_cycles(dict(g))) == [("a", "b", "c"), ("d", "e")]
