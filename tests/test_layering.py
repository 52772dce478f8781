"""The layering rule of DESIGN.md, read from the source: ``scenes -> pipeline -> filters``.

``filters/`` imports no VTK, PyVista, ``pipeline`` or ``scenes`` (every filter runs on arrays
alone); ``pipeline/`` never imports ``scenes`` (scenes are found through entry points); and no
module of ``filters/`` imports another module's ``_private`` name.
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


def test_no_two_modules_of_filters_import_each_other():
    # DESIGN.md: "no two modules importing each other" (filters/elastic/topology.py and
    # voxelize.py did); a package's __init__ re-exporting its modules does not count, nor an
    # import under ``if TYPE_CHECKING:`` (a name for an annotation only, never imported at run
    # time: the SPH steppers annotate the liquid that owns them)
    graph = {}
    for package in ("filters",):
        for path in _modules(package):
            if path.name == "__init__.py":
                continue
            name = _module_name(path)
            deps = set()
            for _, module, names in _imports(path, runtime_only=True):
                deps.add(module)
                deps.update(f"{module}.{n}" for n in names)
            graph[name] = deps
    cycles = sorted(f"{a} <-> {b}" for a in graph for b in graph[a]
                    if b in graph and a < b and a in graph[b])
    assert cycles == []
