"""The README's script example runs as written, and its Quickstart matches .ci/run."""

import re
from pathlib import Path

from pipeline import read_series

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text(encoding="utf-8")


def test_script_example_runs(tmp_path, monkeypatch):
    code = re.search(r"## A script\n\n```python\n(.*?)```", README, re.S).group(1)
    assert len(code.strip().splitlines()) <= 12
    monkeypatch.chdir(tmp_path)
    namespace = {}
    exec(compile(code.replace('flow.run("outputs/script")',
                              'flow.run("outputs/script", progress=False)'),
                 "README", "exec"), namespace)
    times, frames = read_series(tmp_path / "outputs/script/height.pvd")
    assert len(times) == 31 and frames[0].n_points == 500
    assert "Elevation" in frames[-1].point_data


def test_quickstart_test_command_is_what_ci_runs():
    block = re.search(r"## Quickstart.*?```bash\n(.*?)```", README, re.S).group(1)
    lines = [line for line in block.splitlines() if line.strip()]
    assert len(lines) == 2
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert lines[1] in ci


def test_pyvista_example_runs():
    code = re.search(r"## From PyVista, Blender and Houdini\n\n```python\n(.*?)```", README,
                     re.S).group(1)
    namespace = {}
    exec(compile(code, "README", "exec"), namespace)
    surface = namespace["surface"]
    assert type(surface).__name__ == "PolyData" and surface.n_points > 0
    assert surface.n_open_edges == 0
