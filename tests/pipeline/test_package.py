"""pipeline/ by purpose: what the packages export resolves, the old module paths of the flat
pipeline/ still import (with a DeprecationWarning), the entry points in pyproject.toml name
modules that exist, and no module is over 600 lines."""

from __future__ import annotations

import importlib
import importlib.metadata
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
import tomllib

from pipeline._lazy import MOVED

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ["pipeline", "pipeline.io", "pipeline.surface", "pipeline.render", "pipeline.cli"]


@pytest.mark.parametrize("package", PACKAGES)
def test_every_exported_name_resolves_to_its_modules_object(package):
    module = importlib.import_module(package)
    assert module.__all__, package
    for name in module.__all__:
        obj = getattr(module, name)
        home = getattr(obj, "__module__", None)
        if isinstance(home, str) and home.startswith("pipeline."):
            assert getattr(importlib.import_module(home), name) is obj, (package, name)
        assert name in dir(module)
    with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
        module.no_such_name  # noqa: B018


def test_the_names_users_import_from_pipeline():
    from pipeline import Flow, SimulationSource, load_scene, read_series, reconstruct
    from pipeline.compose import Flow as flow
    from pipeline.surface.stages import reconstruct as stages_reconstruct

    assert Flow is flow and reconstruct is stages_reconstruct
    assert callable(load_scene) and callable(read_series) and SimulationSource.__name__


@pytest.mark.parametrize("old", sorted(MOVED))
def test_old_module_paths_import_with_a_deprecation_warning(old):
    targets = [MOVED[old]] if isinstance(MOVED[old], str) else list(MOVED[old])
    news = [importlib.import_module(t) for t in targets]
    sys.modules.pop(f"pipeline.{old}", None)
    with pytest.warns(DeprecationWarning, match=f"pipeline.{old} moved to {targets[0]}"):
        moved = importlib.import_module(f"pipeline.{old}")
    names = [n for new in news for n in getattr(new, "__all__", [])]
    assert names, old
    for name in names:
        assert getattr(moved, name) is getattr(next(m for m in news if hasattr(m, name)), name)
    assert not (ROOT / "pipeline" / f"{old}.py").exists()  # no file of the flat pipeline/ left


def test_an_old_path_outside_moved_is_not_found():
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("pipeline.no_such_module")


def test_entry_points_in_pyproject_resolve():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    scripts = config["project"]["scripts"]
    accessors = config["project"]["entry-points"]["pyvista.accessors"]
    for value in [*scripts.values(), *accessors.values()]:
        module, _, attribute = value.partition(":")
        loaded = importlib.import_module(module)
        if attribute:
            assert callable(getattr(loaded, attribute)), value


def test_python_dash_m_pipeline_runs_the_cli(tmp_path):
    # `python -m pipeline` is the `blobflow` command, from another folder too
    result = subprocess.run([sys.executable, "-m", "pipeline", "list"], cwd=tmp_path,
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert "dam_break" in result.stdout


def test_no_module_of_pipeline_is_over_600_lines():
    long = {str(p.relative_to(ROOT)): n for p in (ROOT / "pipeline").rglob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > 600}
    assert long == {}


def test_the_package_folders_are_the_architecture():
    # the subpackages DESIGN.md names, each with the modules of its purpose
    folders = {p.name for p in (ROOT / "pipeline").iterdir()
               if p.is_dir() and (p / "__init__.py").is_file()}
    assert folders == {"io", "surface", "render", "cli", "paraview"}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        import pipeline.io.series
        import pipeline.surface.stages  # noqa: F401
    assert pipeline.io.series.__file__.endswith("pipeline/io/series.py")


@pytest.mark.parametrize("package", ["pipeline", "filters"])
def test_importing_the_package_loads_no_vtk_numba_or_numpy(package, tmp_path):
    # issue 33: the heavy packages load when a name that needs them is first used
    code = (f"import sys; import {package}; "
            "print(sorted(m for m in ('vtkmodules', 'vtk', 'numba', 'numpy', 'pyvista', "
            "'scipy') if m in sys.modules))")
    result = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"
    # ... and do load when a name is used
    name = "Flow" if package == "pipeline" else "State"
    code = f"import sys; import {package}; {package}.{name}; print('numpy' in sys.modules)"
    result = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                            text=True, timeout=120)
    assert result.stdout.strip() == "True", result.stderr


@pytest.mark.parametrize("package, module", [("pipeline.render", "pipeline.render.pictures"),
                                             ("pipeline.surface", "pipeline.surface.stages")])
def test_a_package_that_replaced_a_module_exports_all_it_had(package, module):
    # pipeline.render and pipeline.surface were modules: every name of theirs imports as before
    old = importlib.import_module(module)
    new = importlib.import_module(package)
    missing = [n for n in old.__all__ if n not in new.__all__]
    assert missing == []
    for name in old.__all__:
        assert getattr(new, name) is getattr(old, name)
