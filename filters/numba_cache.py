"""Numba's on-disk cache made safe for blobflow's kernels: fresh after any source change, and a
damaged entry read as a miss.

Numba caches a ``cache=True`` kernel under ``__pycache__`` and keys the entry on the kernel's own
source file only (its modification time and size).  Two things follow that a user should never
see:

* **stale machine code**: a kernel compiled against a helper in another file (an inlined kernel
  function, a called ``@njit`` function) keeps the old helper's code after the helper's file
  changes, e.g. after ``git pull`` in an editable install, until the kernel's own file changes;
* **a crash on a damaged entry**: an index or data file that cannot be read back (a truncated
  file from a full disk or a killed process) raises from inside Numba's loader on every run.

:func:`install` hooks Numba's per-function cache for the functions defined in blobflow's
packages (``filters``, ``pipeline``, ``scenes``) only: the entry's stamp also holds the
modification times and sizes of every blobflow module the kernel's module reaches through its
globals (modules, functions and classes it imports, transitively), so editing any of them
recompiles it; and an entry that fails to load is reported once (a ``RuntimeWarning`` naming the
folder), its index removed, and the kernel compiled again.  Other packages' Numba caches are
left as Numba makes them.

``import filters`` calls :func:`install_when_numba_loads`, which installs the hook at once if
Numba is loaded, else when it is first imported, so ``import filters`` itself loads no Numba.
"""

from __future__ import annotations

import os
import sys
import warnings
from importlib.abc import MetaPathFinder
from importlib.machinery import PathFinder

__all__ = ["install", "install_when_numba_loads", "is_installed", "package_roots"]

#: Folders whose modules' kernels get the guarded cache (blobflow's packages; tests add theirs).
_ROOTS: list[str] = []
_installed = False
_stat_memo: dict[str, tuple[int, int]] = {}
_closure_memo: dict[tuple[str, int], frozenset[str]] = {}
_warned: set[str] = set()


def package_roots() -> list[str]:
    """Folders whose modules' Numba kernels are guarded (absolute, normalised)."""
    if not _ROOTS:
        here = os.path.dirname(os.path.abspath(__file__))
        parent = os.path.dirname(here)
        for name in ("filters", "pipeline", "scenes"):
            folder = os.path.join(parent, name)
            if os.path.isdir(folder):
                _ROOTS.append(os.path.normcase(folder) + os.sep)
    return _ROOTS


def _ours(path: str | None) -> bool:
    if not path:
        return False
    path = os.path.normcase(os.path.abspath(path))
    return any(path.startswith(root) for root in package_roots())


def _stamp(path: str) -> tuple[int, int]:
    if path not in _stat_memo:
        try:
            st = os.stat(path)
            _stat_memo[path] = (st.st_mtime_ns, st.st_size)
        except OSError:
            _stat_memo[path] = (0, -1)
    return _stat_memo[path]


def _module_of(value) -> str | None:
    """Name of the module an object of a namespace comes from (None if unknown)."""
    try:
        if isinstance(value, type(sys)):
            return value.__name__
        py_func = getattr(value, "py_func", None)  # a Numba dispatcher
        if py_func is not None:
            return getattr(py_func, "__module__", None)
        return getattr(value, "__module__", None)
    except Exception:  # noqa: BLE001 -- a proxy whose attributes raise: not a dependency
        return None


def _closure(module_name: str) -> frozenset[str]:
    """Source files of ``module_name`` and of every blobflow module its globals reach."""
    module = sys.modules.get(module_name)
    namespace = getattr(module, "__dict__", {})
    key = (module_name, len(namespace))
    if key in _closure_memo:
        return _closure_memo[key]
    files: set[str] = set()
    seen: set[str] = set()
    todo = [module_name]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        mod = sys.modules.get(name)
        path = getattr(mod, "__file__", None)
        if mod is None or not _ours(path):
            continue
        files.add(os.path.abspath(path))
        for value in list(vars(mod).values()):
            other = _module_of(value)
            if isinstance(other, str) and other not in seen:
                todo.append(other)
    result = frozenset(files)
    _closure_memo[key] = result
    return result


def dependency_stamp(module_name: str) -> tuple:
    """The (file, mtime_ns, size) of every blobflow source file ``module_name`` reaches."""
    return tuple((os.path.basename(p), *_stamp(p)) for p in sorted(_closure(module_name)))


def _warn_once(folder: str, error: BaseException) -> None:
    if folder in _warned:
        return
    _warned.add(folder)
    warnings.warn(f"an unreadable Numba cache entry in {folder} was ignored "
                  f"({type(error).__name__}: {error}); the kernel is compiled again and the "
                  "entry rewritten", RuntimeWarning, stacklevel=3)


def install() -> None:
    """Guard the Numba caches of blobflow's kernels (idempotent; imports Numba)."""
    global _installed
    if _installed:
        return
    from numba.core import caching, dispatcher

    base = dispatcher.FunctionCache

    class GuardedFunctionCache(base):
        """Numba's per-function cache; for blobflow's kernels stamped with their
        dependencies and forgiving of damaged entries."""

        def __init__(self, py_func):
            super().__init__(py_func)
            self._guarded = _ours(getattr(self._impl.locator, "_py_file", None)) or _ours(
                getattr(getattr(py_func, "__code__", None), "co_filename", None))
            if self._guarded:
                old = self._cache_file
                stamp = (old._source_stamp, dependency_stamp(py_func.__module__))
                self._cache_file = caching.IndexDataCacheFile(
                    cache_path=self._cache_path, filename_base=self._impl.filename_base,
                    source_stamp=stamp)

        def load_overload(self, sig, target_context):
            if not self._guarded:
                return super().load_overload(sig, target_context)
            try:
                return super().load_overload(sig, target_context)
            except Exception as error:  # noqa: BLE001 -- any damage reads as a miss
                _warn_once(self._cache_path, error)
                try:
                    os.unlink(self._cache_file._index_path)
                except OSError:
                    pass
                return None

    dispatcher.FunctionCache = GuardedFunctionCache
    _installed = True


def is_installed() -> bool:
    """Whether :func:`install` has run in this process."""
    return _installed


class _NumbaImportHook(MetaPathFinder):
    """Runs :func:`install` right after Numba's dispatcher module is first imported."""

    target = "numba.core.dispatcher"

    def find_spec(self, fullname, path, target=None):
        if fullname != self.target:
            return None
        spec = PathFinder.find_spec(fullname, path)
        if spec is None or spec.loader is None:
            return spec
        loader = spec.loader
        exec_module = loader.exec_module

        def exec_then_install(module):
            exec_module(module)
            _remove_hook()
            sys.modules[fullname] = module
            install()

        loader.exec_module = exec_then_install
        return spec


def _remove_hook() -> None:
    sys.meta_path[:] = [f for f in sys.meta_path if not isinstance(f, _NumbaImportHook)]


def install_when_numba_loads() -> None:
    """:func:`install` now if Numba's dispatcher is loaded, else as soon as it is."""
    if os.environ.get("BLOBFLOW_NUMBA_CACHE_GUARD", "1") == "0":
        return
    if _NumbaImportHook.target in sys.modules:
        install()
    elif not any(isinstance(f, _NumbaImportHook) for f in sys.meta_path):
        sys.meta_path.insert(0, _NumbaImportHook())
