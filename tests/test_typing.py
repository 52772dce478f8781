"""The packages say they are typed (PEP 561) and the public API of ``pipeline`` and ``filters``
carries its type hints, resolvable names included.

Every module of either package that declares ``__all__`` is found by walking the packages (not
from a hand list), and its public functions and methods (the names of its ``__all__`` that it
defines, and the methods of those classes) must annotate every parameter and the return, with
names that :func:`typing.get_type_hints` resolves (names imported only for annotations, under
``if TYPE_CHECKING:``, included).
"""

import ast
import importlib
import importlib.util
import inspect
import pkgutil
import typing
from pathlib import Path

import pytest
import tomllib

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("pipeline", "filters")

#: Modules with an ``__all__`` that are not checked, each with the reason.
EXEMPT: dict[str, str] = {}
_VTK_METHODS = {"RequestData", "RequestInformation", "RequestUpdateExtent", "ProcessRequest",
                "RequestDataObject", "FillInputPortInformation", "FillOutputPortInformation"}


def _declares_all(path: Path) -> bool:
    """Whether the module's source assigns ``__all__`` (read, not imported)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return any(isinstance(node, (ast.Assign, ast.AnnAssign)) and any(
        isinstance(t, ast.Name) and t.id == "__all__"
        for t in (node.targets if isinstance(node, ast.Assign) else [node.target]))
        for node in tree.body)


def _modules_with_all() -> list[str]:
    found = []
    for top in PACKAGES:
        package = importlib.import_module(top)
        for info in [None, *pkgutil.walk_packages(package.__path__, top + ".")]:
            name = top if info is None else info.name
            spec = importlib.util.find_spec(name)
            if spec is not None and spec.origin and _declares_all(Path(spec.origin)):
                found.append(name)
    return sorted(found)


MODULES = _modules_with_all()


def test_py_typed_markers_ship_with_the_packages():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    data = config["tool"]["setuptools"]["package-data"]
    for package in PACKAGES:
        assert (ROOT / package / "py.typed").is_file()
        assert "py.typed" in data[package]


def test_the_walk_finds_the_modules_of_both_packages():
    # the check is only as good as the discovery: both packages, their subpackages, and
    # modules known to declare __all__ are among the modules checked
    assert {"filters.simulation", "filters.sph.liquid", "filters.elastic.springs",
            "filters.linalg.cg", "pipeline.compose", "pipeline.scene"} <= set(MODULES)
    assert len(MODULES) > 120
    assert set(EXEMPT) <= set(MODULES), "an exemption names a module that no longer exists"


def _public_functions(module):
    for name in getattr(module, "__all__", []):
        obj = getattr(module, name, None)
        if getattr(obj, "__module__", None) != module.__name__:
            continue
        if inspect.isfunction(obj):
            yield name, obj
        elif inspect.isclass(obj):
            for attr, value in vars(obj).items():
                if (attr.startswith("_") and attr != "__init__") or attr in _VTK_METHODS:
                    continue
                value = value.fget if isinstance(value, property) else getattr(
                    value, "__func__", value)
                if inspect.isfunction(value):
                    yield f"{name}.{attr}", value


def _annotation_namespace(module) -> dict:
    """The module's globals plus the names it imports for annotations only."""
    namespace = dict(vars(module))
    path = Path(module.__file__)
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.If) and getattr(node.test, "id", None) == "TYPE_CHECKING":
            exec(compile(ast.Module(body=node.body, type_ignores=[]), str(path), "exec"),
                 namespace)
    return namespace


def _problems(module) -> list[str]:
    namespace = _annotation_namespace(module)
    found = []
    for qualname, func in _public_functions(module):
        signature = inspect.signature(func)
        missing = [p for p, v in signature.parameters.items()
                   if p not in ("self", "cls") and v.annotation is inspect.Parameter.empty]
        if missing:
            found.append(f"{qualname}: {missing} not annotated")
        if func.__name__ != "__init__" and \
                signature.return_annotation is inspect.Signature.empty:
            found.append(f"{qualname}: no return annotation")
        try:
            typing.get_type_hints(func, globalns=namespace)
        except NameError as exc:
            if "'Color'" not in str(exc):  # pyvista.ColorLike's own forward reference
                found.append(f"{qualname}: {exc}")
    return found


@pytest.mark.parametrize("name", [m for m in MODULES if m not in EXEMPT])
def test_public_api_is_annotated(name):
    module = importlib.import_module(name)
    assert _problems(module) == []


def test_the_check_sees_a_missing_annotation():
    # a module whose public function lacks a parameter's and the return's annotation, and one
    # whose annotation names something that does not resolve, are reported
    import types

    module = types.ModuleType("probe")
    exec("__all__ = ['f', 'g', 'C']\n"
         "def f(x, y: int): return x\n"
         "def g(x: 'Missing') -> int: return 1\n"
         "class C:\n"
         "    def m(self, a: int): return a\n", module.__dict__)
    module.__file__ = __file__
    for obj in (module.f, module.g, module.C):
        obj.__module__ = "probe"
    problems = _problems(module)
    assert "f: ['x'] not annotated" in problems
    assert "f: no return annotation" in problems
    assert any(p.startswith("g:") and "Missing" in p for p in problems)
    assert "C.m: no return annotation" in problems
