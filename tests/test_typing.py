"""The packages say they are typed (PEP 561) and the public API of ``pipeline`` carries its
type hints, resolvable names included."""

import ast
import importlib
import inspect
import typing
from pathlib import Path

import pytest
import tomllib

ROOT = Path(__file__).resolve().parent.parent

#: Modules whose public functions and methods (their ``__all__``) are annotated throughout.
ANNOTATED = ["accessor", "algorithm", "assignments", "embedding", "feedback", "scene",
             "cli.surface", "cli.tools", "cli.warmup", "io.colliders", "io.usd", "io.xdmf",
             "render.actors", "render.framing", "render.gallery", "render.looks",
             "render.pictures", "render.renderer", "surface.across_frames", "surface.contour",
             "surface.liquid", "surface.mesh_stages", "surface.options",
             "surface.particle_stages", "surface.stages"]
_VTK_METHODS = {"RequestData", "RequestInformation", "RequestUpdateExtent", "ProcessRequest",
                "RequestDataObject", "FillInputPortInformation", "FillOutputPortInformation"}


def test_py_typed_markers_ship_with_the_packages():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    data = config["tool"]["setuptools"]["package-data"]
    for package in ("pipeline", "filters"):
        assert (ROOT / package / "py.typed").is_file()
        assert "py.typed" in data[package]


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


@pytest.mark.parametrize("name", ANNOTATED)
def test_public_api_of_pipeline_is_annotated(name):
    module = importlib.import_module(f"pipeline.{name}")
    # the names imported for annotations only (under TYPE_CHECKING) must exist
    namespace = dict(vars(module))
    path = Path(module.__file__)
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.If) and getattr(node.test, "id", None) == "TYPE_CHECKING":
            exec(compile(ast.Module(body=node.body, type_ignores=[]), str(path), "exec"),
                 namespace)
    for qualname, func in _public_functions(module):
        signature = inspect.signature(func)
        missing = [p for p, v in signature.parameters.items()
                   if p not in ("self", "cls") and v.annotation is inspect.Parameter.empty]
        assert not missing, f"{name}.{qualname}: {missing} not annotated"
        if func.__name__ != "__init__":
            assert signature.return_annotation is not inspect.Signature.empty, \
                f"{name}.{qualname}: no return annotation"
        try:
            typing.get_type_hints(func, globalns=namespace)
        except NameError as exc:
            if "'Color'" not in str(exc):  # pyvista.ColorLike's own forward reference
                raise AssertionError(f"{name}.{qualname}: {exc}") from None
