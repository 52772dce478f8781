"""The layering rule of DESIGN.md, read from the source: ``scenes -> pipeline -> filters``.

``filters/`` imports no VTK, PyVista, ``pipeline`` or ``scenes`` (every filter runs on arrays
alone); ``pipeline/`` never imports ``scenes`` (scenes are found through entry points); no
module of ``filters/`` imports another module's ``_private`` name; no two modules of
``pipeline/`` or ``filters/`` import each other, and their module-level imports have no cycle.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _modules(package: str) -> list[Path]:
    return sorted((ROOT / package).rglob("*.py"))


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _type_checking_imports(tree: ast.Module) -> set[int]:
    """``id`` of the import nodes under ``if TYPE_CHECKING:`` (read by type checkers only)."""
    return {id(node) for block in ast.walk(tree) if isinstance(block, ast.If)
            and getattr(block.test, "id", None) == "TYPE_CHECKING"
            for stmt in block.body for node in ast.walk(stmt)}


def _imports(path: Path, runtime_only: bool = False):
    """Yield ``(line, imported module, names)`` for every import in ``path``, relative resolved
    (with ``runtime_only``, not the imports under ``if TYPE_CHECKING:``, which never run)."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(), filename=str(path))
    skip = _type_checking_imports(tree) if runtime_only else set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name, []
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[:len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            yield node.lineno, base, [a.name for a in node.names]


def _top(module: str) -> str:
    return module.split(".")[0]


def _violations(package: str, forbidden: set[str]) -> list[str]:
    return [f"{path.relative_to(ROOT)}:{line} imports {module}"
            for path in _modules(package)
            for line, module, _ in _imports(path) if _top(module) in forbidden]


def test_the_import_reader_sees_relative_imports():
    # The rule is only as good as the reader: a relative import must resolve to its package.
    names = {m for _, m, _ in _imports(ROOT / "filters" / "sph" / "liquid.py")}
    assert any(m.startswith("filters.") for m in names), names


def test_the_import_reader_tells_annotation_only_imports_apart():
    # filters/sph/wcsph.py names the liquid for its annotations only: the layering rules see
    # that import (no VTK even for annotations), the cycle rule does not (it never runs)
    path = ROOT / "filters" / "sph" / "wcsph.py"
    assert "filters.sph.liquid" in {m for _, m, _ in _imports(path)}
    assert "filters.sph.liquid" not in {m for _, m, _ in _imports(path, runtime_only=True)}
    assert "filters.binning" in {m for _, m, _ in _imports(path, runtime_only=True)}


@pytest.mark.parametrize("package, forbidden", [
    ("filters", {"vtk", "vtkmodules", "pyvista", "paraview", "pipeline", "scenes"}),
    ("pipeline", {"scenes"}),
])
def test_lower_layers_do_not_import_upper_ones(package, forbidden):
    assert _violations(package, forbidden) == []


def test_filters_import_only_public_names_of_other_modules():
    found = []
    for path in _modules("filters"):
        own = _module_name(path)
        for line, module, names in _imports(path):
            if _top(module) != "filters" or module == own:
                continue
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            if private:
                found.append(f"{path.relative_to(ROOT)}:{line} {module} {private}")
    assert found == []


@pytest.mark.parametrize("package", ["filters", "pipeline"])
def test_no_two_modules_import_each_other(package):
    # DESIGN.md: "no two modules importing each other" (filters/elastic/topology.py and
    # voxelize.py did, pipeline's series.py and xdmf.py, frames.py and across_frames.py), at
    # any level, in functions too; a package's __init__ re-exporting its modules does not count,
    # nor an import under ``if TYPE_CHECKING:`` (a name for an annotation only, never imported
    # at run time: the SPH steppers annotate the liquid that owns them)
    graph = {}
    for path in _modules(package):
        if path.name == "__init__.py":
            continue
        deps = set()
        for _, module, names in _imports(path, runtime_only=True):
            deps.add(module)
            deps.update(f"{module}.{n}" for n in names)
        graph[_module_name(path)] = deps
    cycles = sorted(f"{a} <-> {b}" for a in graph for b in graph[a]
                    if b in graph and a < b and a in graph[b])
    assert cycles == []


def _module_level_imports(path: Path):
    """Yield the imports ``_imports`` reads that run when the module is imported: those of its
    top-level statements (inside ``if``/``try`` too), not in functions or classes, nor under
    ``if TYPE_CHECKING:``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    lines = set()

    def walk(body):
        for node in body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                lines.add(node.lineno)
            elif isinstance(node, ast.If):
                if "TYPE_CHECKING" not in ast.unparse(node.test):
                    walk(node.body)
                walk(node.orelse)
            elif isinstance(node, ast.Try):
                for part in (node.body, node.orelse, node.finalbody, *(h.body for h in
                                                                         node.handlers)):
                    walk(part)
            elif isinstance(node, (ast.With,)):
                walk(node.body)

    walk(tree.body)
    return [(line, module, names) for line, module, names in _imports(path) if line in lines]


def import_graph(packages=("pipeline", "filters")) -> dict[str, set[str]]:
    """``{module: modules it imports at module level}`` over ``packages`` (their ``__init__``
    files included); ``from P import x`` of a submodule ``P.x`` is an import of ``P.x`` (not of
    ``P``: a package is initialised before its modules), of ``P`` otherwise."""
    paths = {_module_name(p): p for package in packages for p in _modules(package)}
    graph = {}
    for name, path in paths.items():
        deps = set()
        for _, module, names in _module_level_imports(path):
            targets = [f"{module}.{n}" if f"{module}.{n}" in paths else module
                       for n in names] or [module]
            deps.update(t for t in targets if t in paths and t != name)
        graph[name] = deps
    return graph


def cycles_of(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of ``graph`` with more than one module (Tarjan 1972),
    each sorted: every import cycle lies in one of them."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def test_the_cycle_finder_finds_a_cycle():
    # the finder is only as good as its answer on a known cycle, of three modules
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert cycles_of(graph) == [["a", "b", "c"]]
    assert cycles_of({"a": {"b"}, "b": set()}) == []


def test_the_graph_sees_module_level_imports_only():
    graph = import_graph()
    # pipeline/tasks.py imports pipeline.io.series at module level ...
    assert "pipeline.io.series" in graph["pipeline.tasks"]
    # ... and pipeline/render/pictures.py imports pipeline.tasks in a function only
    assert "pipeline.tasks" not in graph["pipeline.render.pictures"]
    # relative imports in a subpackage resolve, to the modules a package's __init__ imports
    assert "filters.sph.liquid" in graph["filters.sph"]
    # "from . import particles" is an import of the module, not of its package
    assert "filters.sph.particles" in graph["filters.sph.wcsph"]
    assert "filters.sph" not in graph["filters.sph.wcsph"]


def test_no_import_cycles_in_pipeline_and_filters():
    # DESIGN.md: no module imports itself through others when it is imported (a cycle works
    # or not by the order of the imports, and hides which module is the lower layer)
    assert cycles_of(import_graph()) == []
