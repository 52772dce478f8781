"""Lazy re-exports for the packages of :mod:`pipeline` (PEP 562 module ``__getattr__``).

``import pipeline`` loads no VTK, PyVista or Numba: a package names what it re-exports and from
which of its modules, and a name's module is imported the first time the name is asked for
(``pipeline.Flow``, ``from pipeline import reconstruct``). A package's ``__init__`` does::

    __getattr__, __dir__ = lazy_exports(__name__, globals(), {"Flow": ".compose", ...})

Old module paths of the flat ``pipeline/`` of version 0.1 (``pipeline.io.series``,
``pipeline.surface.options``, ...) keep importing, as the module that now holds them
(:data:`MOVED`), with a :class:`DeprecationWarning` that names the new path.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings
from types import ModuleType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence
    from typing import Any

__all__ = ["lazy_exports", "MOVED", "install_moved_modules"]


def lazy_exports(package: str, namespace: dict, exports: dict[str, str]
                 ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of a package that re-exports names lazily.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    namespace : dict
        The package's ``globals()``: a name, once imported, is stored there (later look-ups
        do not call ``__getattr__`` again).
    exports : dict of str to str
        ``{name: module}``, the module relative to ``package`` (``".compose"``).

    Returns
    -------
    getattr, dir : callable
        Functions to bind as the package's ``__getattr__`` and ``__dir__``.
    """

    def __getattr__(name: str) -> Any:
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module, package), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(exports))

    return __getattr__, __dir__


#: The modules of the flat ``pipeline/`` of version 0.1 and where they live now: old name ->
#: new module, or several modules for a module that was split (``frames``).
MOVED: dict[str, str | tuple[str, ...]] = {
    "checkpoint": "pipeline.io.checkpoint", "colliders": "pipeline.io.colliders",
    "convert": "pipeline.io.convert", "folderlock": "pipeline.io.folderlock",
    "outfiles": "pipeline.io.outfiles", "series": "pipeline.io.series",
    "usd": "pipeline.io.usd", "volume_mesh": "pipeline.io.volume_mesh",
    "xdmf": "pipeline.io.xdmf", "xmlcheck": "pipeline.io.xmlcheck",
    "across_frames": "pipeline.surface.across_frames", "contour": "pipeline.surface.contour",
    "liquid": "pipeline.surface.liquid", "mesh_stages": "pipeline.surface.mesh_stages",
    "particle_stages": "pipeline.surface.particle_stages",
    "surface_options": "pipeline.surface.options",
    "frames": ("pipeline.tasks", "pipeline.surface.frames"),
    "actors": "pipeline.render.actors", "framing": "pipeline.render.framing",
    "gallery": "pipeline.render.gallery", "looks": "pipeline.render.looks",
    "offscreen": "pipeline.render.offscreen", "renderer": "pipeline.render.renderer",
    "cli_common": "pipeline.cli.common", "cli_surface": "pipeline.cli.surface",
    "cli_tools": "pipeline.cli.tools", "warmup": "pipeline.cli.warmup",
    "bridge": "pipeline.paraview.bridge",
}


class _Moved(ModuleType):
    """An old module path: its names are read from the module(s) that now hold them (a module
    object of its own: the real module's ``__spec__`` stays its own)."""

    def __init__(self, name: str, targets: Sequence[str]):
        super().__init__(name)
        self.__targets = [importlib.import_module(t) for t in targets]

    def __getattr__(self, name: str) -> Any:
        for module in self.__targets:
            if hasattr(module, name):
                return getattr(module, name)
        raise AttributeError(f"module {self.__name__!r} has no attribute {name!r}")

    def __dir__(self) -> list[str]:
        return sorted({n for m in self.__targets for n in dir(m)})


class _MovedLoader(importlib.abc.Loader):
    def __init__(self, target: str | tuple[str, ...]):
        self.target = target

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        targets = (self.target,) if isinstance(self.target, str) else self.target
        warnings.warn(f"{spec.name} moved to {' and '.join(targets)}; import it from there",
                      DeprecationWarning, stacklevel=2)
        return _Moved(spec.name, targets)

    def exec_module(self, module: ModuleType) -> None:
        """Nothing to run: the module is the one already imported."""


class _MovedFinder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname: str, path: Any = None, target: Any = None
                  ) -> importlib.machinery.ModuleSpec | None:
        package, _, name = fullname.rpartition(".")
        if package != "pipeline" or name not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, _MovedLoader(MOVED[name]))


def install_moved_modules() -> None:
    """Let the old module paths of :data:`MOVED` import (once per interpreter).

    The finder goes first on ``sys.meta_path``: it answers for those names only, and a finder
    of an editable install of another checkout would otherwise find the old files there."""
    if not any(isinstance(f, _MovedFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _MovedFinder())
