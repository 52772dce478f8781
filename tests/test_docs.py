"""The documentation builds without a warning, documents every public name, and its recipes run.

The build is Sphinx's own command (``python -m sphinx -W``) in a subprocess, on a copy of
``docs/`` and ``examples/`` (so that the generated pages never land in the source tree), with
the gallery's examples not executed (``plot_gallery=0``; ``tests/test_examples.py`` runs them).
"""

from __future__ import annotations

import ast
import importlib
import os
import pkgutil
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
GENERATED = ("_build", "gallery", "api/generated", "sg_execution_times.rst")


def _env() -> dict:
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get("PYTHONPATH", "")
                                                       .split(os.pathsep) if p])
    return env


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The HTML documentation built from a copy of the sources: (html folder, sphinx output)."""
    work = tmp_path_factory.mktemp("docs")
    shutil.copytree(DOCS, work / "docs",
                    ignore=lambda d, names: [n for n in names
                                             if (Path(d) / n).relative_to(DOCS).as_posix()
                                             in GENERATED])
    shutil.copytree(ROOT / "examples", work / "examples")
    shutil.copy(ROOT / "CHANGELOG.md", work / "CHANGELOG.md")
    html = work / "html"
    result = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-b", "html", "-q",
         "-D", "plot_gallery=0", str(work / "docs"), str(html)],
        cwd=work, env=_env(), capture_output=True, text=True, timeout=600)
    return html, result


def test_docs_build_without_warnings(built):
    html, result = built
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-6000:]
    assert "WARNING" not in result.stderr and "ERROR" not in result.stderr, result.stderr[-6000:]
    for page in ("index", "getting_started", "user_guide/scripts", "api/index", "benchmarks",
                 "design", "gallery/index", "changelog"):
        assert (html / f"{page}.html").is_file(), page


def _documented_modules():
    """Every module of pipeline and filters that declares ``__all__``, imported."""
    for top in ("pipeline", "filters"):
        package = importlib.import_module(top)
        yield package
        for info in pkgutil.walk_packages(package.__path__, top + "."):
            if info.name.rsplit(".", 1)[-1].startswith("_"):
                continue
            origin = importlib.util.find_spec(info.name).origin
            tree = ast.parse(Path(origin).read_text(encoding="utf-8"))
            if info.ispkg or any(isinstance(n, ast.Assign) and any(
                    getattr(t, "id", None) == "__all__" for t in n.targets) for n in tree.body):
                yield importlib.import_module(info.name)


def test_api_reference_documents_every_public_name(built):
    """Every name in the ``__all__`` of every module of pipeline and filters is in the
    reference, under the module that defines it (objects.inv, Sphinx's own inventory)."""
    from sphinx.util.inventory import InventoryFile

    html, result = built
    assert result.returncode == 0, result.stderr[-3000:]
    with open(html / "objects.inv", "rb") as f:
        inventory = InventoryFile.load(f, str(html), os.path.join)
    documented = set()
    for kind, entries in (inventory.data if hasattr(inventory, "data") else inventory).items():
        if kind.startswith("py:"):
            documented.update(entries)
    modules = list(_documented_modules())
    # where else each name is public: a package re-exports its submodules' names
    aliases: dict = {}
    for module in modules:
        for name in getattr(module, "__all__", ()):
            aliases.setdefault((name, id(getattr(module, name))), set()).add(
                f"{module.__name__}.{name}")
    missing, names = [], 0
    for module in modules:
        assert module.__name__ in documented, module.__name__
        for name in getattr(module, "__all__", ()):
            names += 1
            obj = getattr(module, name)
            home = getattr(obj, "__module__", None)
            candidates = set(aliases[(name, id(obj))])
            if isinstance(home, str):
                candidates.add(f"{home}.{name}")
            if not candidates & documented:
                missing.append(f"{module.__name__}.{name}")
    assert names > 300 and not missing, missing


def test_gallery_has_every_example(built):
    html, _ = built
    examples = sorted((ROOT / "examples").glob("*.py"))
    index = (html / "gallery" / "index.html").read_text(encoding="utf-8")
    for example in examples:
        page = html / "gallery" / f"{example.stem}.html"
        assert page.is_file(), example.name
        title = ast.get_docstring(ast.parse(example.read_text(encoding="utf-8"))).splitlines()[0]
        assert title in page.read_text(encoding="utf-8") and f"{example.stem}.html" in index, title


def test_pages_show_the_scene_pictures(built):
    html, _ = built
    images = {p.name for p in (html / "_images").glob("*.png")}
    stills = {p.name for p in DOCS.glob("*.png")}
    assert stills and stills <= images, stills - images


def test_quickstart_commands_are_the_readmes():
    page = (DOCS / "getting_started.rst").read_text(encoding="utf-8")
    block = re.search(r"\.\. code-block:: bash\n\n(.*?)\n\n", page, re.S).group(1)
    commands = [line.strip() for line in block.splitlines() if line.strip()]
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    quickstart = re.search(r"## Quickstart.*?```bash\n(.*?)```", readme, re.S).group(1)
    assert commands == [line.strip() for line in quickstart.splitlines() if line.strip()]


def _python_blocks(page: Path) -> str:
    """The page's ``.. code-block:: python`` blocks, dedented, in order."""
    code = []
    lines = page.read_text(encoding="utf-8").splitlines()
    i = 0
    while i < len(lines):
        if lines[i].strip() == ".. code-block:: python":
            i += 1
            block = []
            while i < len(lines) and (not lines[i].strip() or lines[i].startswith("   ")):
                block.append(lines[i][3:])
                i += 1
            code.append("\n".join(block).strip("\n"))
        else:
            i += 1
    return "\n\n".join(code)


PAGES_WITH_CODE = sorted(p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.rst")
                         if ".. code-block:: python" in p.read_text(encoding="utf-8")
                         and not any(p.relative_to(DOCS).as_posix().startswith(g)
                                     for g in GENERATED))


def test_pages_with_code_are_found():
    assert {"getting_started.rst", "user_guide/scripts.rst"} <= set(PAGES_WITH_CODE)


@pytest.mark.parametrize("page", PAGES_WITH_CODE)
def test_page_code_runs_as_written(page, tmp_path):
    """A page's Python blocks, run top to bottom as one script from an empty folder, as a user
    following the page would."""
    code = _python_blocks(DOCS / page)
    script = tmp_path / "page.py"
    script.write_text(code + "\n", encoding="utf-8")
    result = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=_env(),
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, f"{page}:\n{result.stdout[-2000:]}\n{result.stderr[-4000:]}"
    assert any((tmp_path / "outputs").rglob("*.pvd")), page


def test_the_whole_tree_is_ruff_clean():
    """``ruff check`` (the configuration in pyproject.toml) passes on every Python file of the
    project: the packages, scenes, tests, benchmarks, examples and docs."""
    result = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "."],
                            cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
