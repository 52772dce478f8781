"""Sphinx configuration of blobflow's documentation.

Build: ``python -m sphinx -W -b html docs docs/_build/html`` (``-D plot_gallery=0`` skips
running the examples; the gallery pages then show their code without pictures).

The API reference (``docs/api/generated/``, written at every build) follows the packages: every
package and module of :mod:`pipeline` and :mod:`filters`, found by walking their folders, gets a
page with its docstring and a table of the names of its ``__all__``; every name is documented
from its docstring (numpydoc) on the page of the module that defines it, and a package that
re-exports a name links there. Reorganising the packages needs no change here.
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import inspect
import os
import pkgutil
import shutil
import sys
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE / "_ext"))
# Examples run by sphinx-gallery draw offscreen, with no display.
os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")

import pyvista  # noqa: E402

pyvista.OFF_SCREEN = True

from pipeline.version import version as _installed_version  # noqa: E402

project = "blobflow"
author = "blobflow developers"
copyright = "blobflow developers"  # noqa: A001 (Sphinx's name)
release = _installed_version()
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
]

exclude_patterns = ["_build", "paraview_screenshot.py", "gallery/*.ipynb", "**.md5",
                    "gallery/*.py", "gallery/*.zip", "gallery/*.json"]
root_doc = "index"
default_role = "py:obj"
nitpicky = False

# -- API reference -------------------------------------------------------------------------
autosummary_generate = False  # docs/conf.py writes the pages
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "none"  # numpydoc's Parameters sections give the types, with shapes and units
autodoc_class_signature = "separated"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set = set()

#: The packages whose modules the API reference documents (walked recursively).
API_PACKAGES = ("pipeline", "filters")
API_DIR = HERE / "api" / "generated"


def _declares_all(path: str) -> bool:
    """Whether the module's source assigns ``__all__`` (read, not imported)."""
    tree = ast.parse(Path(path).read_text(encoding="utf-8"))
    return any(isinstance(node, (ast.Assign, ast.AnnAssign)) and any(
        isinstance(t, ast.Name) and t.id == "__all__"
        for t in (node.targets if isinstance(node, ast.Assign) else [node.target]))
        for node in tree.body)


def api_modules() -> list[tuple[str, bool]]:
    """``(module name, is a package)`` of every documented module, packages first in each folder.

    Every package is documented; a module is when it declares ``__all__`` (its public names).
    Left out: ``__main__`` and the ParaView-side scripts that declare no ``__all__`` because
    ParaView's own Python runs them (described in the ParaView guide).
    """
    found = []
    for top in API_PACKAGES:
        package = importlib.import_module(top)
        found.append((top, True))
        for info in pkgutil.walk_packages(package.__path__, top + "."):
            if info.name.rsplit(".", 1)[-1].startswith("_"):
                continue
            if info.ispkg:
                found.append((info.name, True))
                continue
            spec = importlib.util.find_spec(info.name)
            if spec is not None and spec.origin and _declares_all(spec.origin):
                found.append((info.name, False))
    return sorted(found)


def _home(obj, name: str, module) -> str:
    """The module whose page documents ``obj`` (the one that defines it)."""
    home = getattr(obj, "__module__", None)
    if inspect.isclass(obj) or callable(obj):
        if isinstance(home, str) and (home == module.__name__ or home.startswith(
                tuple(p + "." for p in API_PACKAGES))):
            return home
        return module.__name__
    # data: defined here unless a submodule's __all__ exports the same object
    if hasattr(module, "__path__"):
        for info in pkgutil.iter_modules(module.__path__, module.__name__ + "."):
            try:
                sub = importlib.import_module(info.name)
            except ImportError:
                continue
            if name in getattr(sub, "__all__", ()) and getattr(sub, name, None) is obj:
                return _home(obj, name, sub)
    return module.__name__


def _public(module) -> list[str]:
    names = getattr(module, "__all__", None)
    if names is None:
        return []
    return [n for n in names if not n.startswith("_")]


def _table(names: list[str]) -> list[str]:
    if not names:
        return []
    return [".. autosummary::", "   :nosignatures:", ""] + [f"   {n}" for n in names] + [""]


def _directive(module, name: str) -> list[str]:
    """The autodoc directive that documents ``module.name``."""
    obj = getattr(module, name)
    if inspect.isclass(obj) and issubclass(obj, BaseException):
        return [f".. autoexception:: {name}", "   :show-inheritance:", ""]
    if inspect.isclass(obj):
        return [f".. autoclass:: {name}", "   :members:", "   :show-inheritance:", ""]
    if callable(obj):
        return [f".. autofunction:: {name}", ""]
    return [f".. autodata:: {name}", ""]


def write_api_pages() -> None:
    """Write ``api/generated/MODULE.rst`` for every documented module (see :func:`api_modules`).

    A page holds the module's docstring, a table of its public names, each name it defines
    documented from its docstring, links to the names it re-exports from submodules (their
    home pages document them), and its submodules.
    """
    modules = api_modules()
    if API_DIR.exists():
        shutil.rmtree(API_DIR)
    API_DIR.mkdir(parents=True)
    names = [m for m, _ in modules]
    for name, is_package in modules:
        module = importlib.import_module(name)
        own, reexported = [], []
        for public in _public(module):
            home = _home(getattr(module, public), public, module)
            if home == name:
                own.append(public)
            else:  # autosummary wants names relative to the current module
                target = f"{home}.{public}"
                reexported.append("~" + target.removeprefix(name + "."))
        children = [m for m in names if m.rpartition(".")[0] == name]
        title = f"``{name}``"
        lines = [title, "=" * len(title), "", f".. automodule:: {name}", "",
                 f".. currentmodule:: {name}", ""]
        if own or reexported:
            lines += ["Public names", "------------", ""] + _table(own + reexported)
        if children:
            kind = "Subpackages and modules" if is_package else "Modules"
            lines += [kind, "-" * len(kind), ""]
            lines += _table([c.rpartition(".")[2] for c in children])
            lines += [".. toctree::", "   :hidden:", ""] + [f"   {c}" for c in children] + [""]
        if own:
            lines += ["Reference", "---------", ""]
            for public in own:
                lines += _directive(module, public)
        (API_DIR / f"{name}.rst").write_text("\n".join(lines), encoding="utf-8")


def _data_docstring(app, what, name, obj, options, lines):
    """Drop a data object's class docstring.

    A module constant without a ``#:`` comment would show its type's docstring (a NumPy
    array's: ndarray's whole reference); it shows its value only.  (Data never carries a
    docstring of its own: its ``__doc__`` is its type's.)
    """
    if what == "data" and "__doc__" not in getattr(obj, "__dict__", {}):
        from sphinx.pycode import ModuleAnalyzer

        module, _, attribute = name.rpartition(".")
        try:
            commented = ("", attribute) in ModuleAnalyzer.for_module(module).find_attr_docs()
        except Exception:  # noqa: BLE001 (no source to read: no comment either)
            commented = False
        if not commented:
            lines[:] = []


def _summary_keeping_markup(doc, settings):
    """autosummary's one-line summary, cut at the first sentence end that leaves the inline
    markup whole (Sphinx 9.0's ``extract_summary`` parses the whole paragraph instead of the
    cut sentence when it checks that, so a period inside a literal such as ````p . H p````
    cut it there and broke the markup)."""
    from docutils import nodes
    from sphinx.ext import autosummary as asm

    stanza = []
    for line in doc:
        if not line.strip():
            if stanza:
                break
            continue
        stanza.append(line)
    if not stanza:
        return ""
    node = asm._parse_summary(stanza, settings)
    if isinstance(node[0], nodes.section):
        return node[0].astext().strip()
    if not isinstance(node[0], nodes.paragraph):
        return stanza[0].strip()
    text = " ".join(stanza)
    sentences = asm.periods_re.split(text)
    summary = text
    for i in range(1, len(sentences)):
        candidate = ". ".join(sentences[:i]).rstrip(".") + "."
        if candidate.endswith(asm.WELL_KNOWN_ABBREVIATIONS):
            continue
        parsed = asm._parse_summary([candidate], settings)
        if not any(parsed.findall(nodes.system_message)) and not any(
                parsed.findall(nodes.problematic)):
            summary = candidate
            break
    return asm.literal_re.sub(".", summary)


def _resolve_reexport(app, env, node, contnode):
    """Resolve ``pipeline.Flow`` (a name a package re-exports, as users import it) to the page of
    the module that defines it (``pipeline.compose.Flow``), also with an attribute after it."""
    if node.get("refdomain") != "py" or not node.get("reftarget", "").startswith(
            tuple(p + "." for p in API_PACKAGES)):
        return None
    parts = node["reftarget"].split(".")
    for cut in range(len(parts) - 1, 0, -1):
        try:
            module = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        obj = getattr(module, parts[cut], None)
        home = getattr(obj, "__module__", None)
        if obj is None or not isinstance(home, str) or home == module.__name__:
            return None
        target = ".".join([home, *parts[cut:]])
        return env.domains["py"].resolve_xref(env, node["refdoc"], app.builder,
                                              node["reftype"], target, node, contnode)
    return None


def setup(app):
    from sphinx.ext import autosummary

    autosummary.extract_summary = _summary_keeping_markup
    app.connect("autodoc-process-docstring", _data_docstring, priority=100)
    app.connect("missing-reference", _resolve_reexport)


# -- Gallery ------------------------------------------------------------------------------
sphinx_gallery_conf = {
    "examples_dirs": [str(ROOT / "examples")],
    "gallery_dirs": ["gallery"],
    "filename_pattern": r"\.py$",  # every example runs (unless plot_gallery=0)
    "ignore_pattern": r"__init__\.py|^_",
    # the PNGs an example writes into $BLOBFLOW_EXAMPLES_OUT/NAME are its pictures
    "image_scrapers": ("example_pictures.scraper",),
    "reset_modules": ("example_pictures.reset",),
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "matplotlib_animations": False,
    "show_memory": False,
    "capture_repr": (),
    "default_thumb_file": str(HERE / "dam_break.png"),
    "thumbnail_size": (320, 240),
}

def _drop_stale_gallery_pages() -> None:
    """Remove the gallery pages of examples that no longer exist (sphinx-gallery keeps them, and
    a page in no toctree is a warning)."""
    gallery = HERE / "gallery"
    if not gallery.is_dir():
        return
    examples = {p.stem for p in (ROOT / "examples").glob("*.py")}
    for page in gallery.iterdir():
        stem = page.name.split(".")[0]
        if page.is_file() and stem not in examples and stem not in ("index", "sg_execution_times"):
            page.unlink()


_drop_stale_gallery_pages()

# The examples write their outputs under this folder when the gallery runs them, not into the
# source tree (they write under ./outputs/examples when a user runs them).
os.environ["BLOBFLOW_EXAMPLES_OUT"] = str(HERE / "_build" / "example_outputs")

# -- HTML ----------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = "blobflow"
html_logo = None
html_static_path = ["_static"]
html_css_files = ["blobflow.css"]
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 7,
    "navbar_align": "left",
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
# pages without sections of their own: no section navigation; the benchmark table gets the width
html_sidebars = {page: [] for page in ("index", "getting_started", "benchmarks", "design",
                                       "features", "changelog")}
html_context = {"default_mode": "light"}
html_show_sourcelink = False

warnings.filterwarnings("ignore", category=UserWarning,
                        message="Matplotlib is currently using agg")


# Written when Sphinx reads this file, before it looks for source files (autosummary then finds
# these pages and writes the pages of the names they list).
write_api_pages()
