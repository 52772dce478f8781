"""ParaView (Debian's pvpython) opens the series and XDMF files blobflow writes, and loads
blobflow's plugin: the surface filter on a particle series, a scene as a temporal source."""

import ast
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from _helpers import ballistic

from filters import BallisticParticles
from filters.kernels import SPLAT_KERNELS
from pipeline import Flow, SimulationSource
from pipeline.cli import main
from pipeline.io.series import read_frame, read_series
from pipeline.scene import available_scenes, load_scene
from pipeline.surface import reconstruct
from pipeline.surface.options import SURFACE_DEFAULTS

PVPYTHON = shutil.which("pvpython")
PVBATCH = shutil.which("pvbatch")
PARAVIEW = shutil.which("paraview")
XVFB_RUN = shutil.which("xvfb-run")
HERE = Path(__file__).parent
ROOT = Path(__file__).resolve().parents[2]
PLUGIN = ROOT / "pipeline" / "paraview" / "plugin.py"
STARTUP = PLUGIN.with_name("startup.py")
GUIDE = (ROOT / "docs" / "user_guide" / "paraview.rst").read_text(encoding="utf-8")
SCENE_COUNT = len(list(available_scenes()))

needs_pvpython = pytest.mark.skipif(
    PVPYTHON is None, reason="pvpython not found: install Debian's 'paraview' package "
    "(.ci/run does) to run the ParaView round trips")
needs_gui = pytest.mark.skipif(
    PARAVIEW is None or XVFB_RUN is None, reason="paraview or xvfb-run not found: install "
    "Debian's 'paraview' and 'xvfb' packages (.ci/run does) to start ParaView's GUI headless")
pytestmark = [pytest.mark.paraview]


def _blobflow_python(folder):
    """blobflow's Python as the plugin should run it: this interpreter, with this process's
    PYTHONPATH (a worktree's code) in a wrapper, since the plugin drops ParaView's PYTHONPATH."""
    path = os.environ.get("PYTHONPATH")
    if not path:
        return sys.executable
    wrapper = Path(folder) / "blobflow-python"
    wrapper.write_text(f'#!/bin/sh\nPYTHONPATH={shlex.quote(path)} exec '
                       f'{shlex.quote(sys.executable)} "$@"\n')
    wrapper.chmod(0o755)
    return str(wrapper)


def _environment(tmp_path, **extra):
    """A clean environment for ParaView's programs: no venv, no PYTHONPATH of ours."""
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path),
           "BLOBFLOW_PYTHON": _blobflow_python(tmp_path)}
    for name in ("NUMBA_NUM_THREADS", "NUMBA_CACHE_DIR"):
        if name in os.environ:
            env[name] = os.environ[name]
    env.update(extra)
    return env


def _pvpython(script, *arguments, tmp_path=None, timeout=240):
    env = {"PATH": "/usr/bin:/bin", "BLOBFLOW_PYTHON": sys.executable,
           "HOME": str(tmp_path or Path.home())}
    result = subprocess.run([PVPYTHON, str(script), *map(str, arguments)], capture_output=True,
                            text=True, timeout=timeout, env=env)
    assert result.returncode == 0, (result.stdout + result.stderr)[-3000:]
    line = next(line for line in result.stdout.splitlines() if line.startswith("PROBE "))
    return json.loads(line[len("PROBE "):]), result.stderr


def _readme_recipe(pattern):
    """The ParaView guide's recipe matching ``pattern`` (a regex on the text between
    backticks) in its section *Loading it* (docs/user_guide/paraview.rst; the README links
    there), with PATH made this clone's root."""
    section = GUIDE.split("Loading it\n~~~~~~~~~~", 1)[1].split("How it works\n", 1)[0]
    recipes = [r.replace("\n", " ") for r in re.findall(r"`([^`]+)`", section)
               if re.fullmatch(pattern, r.replace("\n", " "))]
    assert len(recipes) == 1, f"{len(recipes)} recipes like {pattern} in the guide's section"
    return recipes[0].replace("PATH/", f"{ROOT}/")


EXEC_RECIPE = r'exec\(open\("PATH/pipeline/paraview/startup\.py"\)\.read\(\)\)'
LOADED = re.compile(r"blobflow: loaded the ParaView plugin (\S+) \(filter blobflowParticleSurface,"
                    r" (\d+) scene sources\)")


@pytest.fixture(scope="module")
def series(tmp_path_factory):
    out = tmp_path_factory.mktemp("pv")
    flow = Flow(SimulationSource(ballistic(n=30), fps=10, duration=0.7))
    return flow.run(out, progress=False)["particles"]


@needs_pvpython
@pytest.mark.parametrize("which", ["pvd", "series"])
def test_paraview_reads_times_and_arrays(series, which):
    path = series if which == "pvd" else series.with_name("particles.vtp.series")
    seen, _ = _pvpython(HERE / "paraview_probe.py", path)
    assert seen["times"] == [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]
    assert [f["points"] for f in seen["frames"]] == [30] * 8
    assert {"velocity", "id"} <= set(seen["point_arrays"])


@needs_pvpython
def test_paraview_reads_the_tetrahedra_and_the_embedded_mesh_of_a_fem_jello(tmp_path):
    flow = load_scene("jello_fem").build(spacing=0.06, radius=0.12)
    flow.source.set_frames(10, frames=3)
    paths = flow.run(tmp_path, progress=False)
    tets = _pvpython(HERE / "paraview_probe.py", paths["tets"])[0]
    assert tets["reader"] == "PVDReader" and tets["times"] == [0.0, 0.1, 0.2]
    n_tets = flow.source.simulation.model.mesh.tets.shape[0]
    assert [f["cells"] for f in tets["frames"]] == [n_tets] * 3
    assert "strain_energy_density" in tets["cell_arrays"]
    assert {"velocity", "id"} <= set(tets["point_arrays"])
    jello = _pvpython(HERE / "paraview_probe.py", paths["jello"])[0]
    assert jello["times"] == [0.0, 0.1, 0.2]
    assert {"velocity", "id"} <= set(jello["point_arrays"])


@needs_pvpython
@pytest.mark.parametrize("scene, settings", [
    ("hair", ["strands=4", "segments=5"]),
    ("cloth_drape", ["resolution=6"]),
    ("jello_drop", ["spacing=0.1"]),
])
def test_scene_xdmf_opens_every_step_in_paraview(tmp_path, capsys, scene, settings):
    out = tmp_path / scene
    argv = ["run", scene, "--frames", "4", "--out", str(out), "--no-render", "-q"]
    assert main(argv + [a for s in settings for a in ("--set", s)]) == 0, capsys.readouterr().err
    name = {"hair": "hair", "cloth_drape": "cloth", "jello_drop": "jello"}[scene]
    times, frames = read_series(out / f"{name}.pvd")
    seen, stderr = _pvpython(HERE / "paraview_probe.py", out / f"{name}.xdmf")
    assert "ERR" not in stderr, stderr[-2000:]
    assert seen["reader"].startswith("Xdmf")
    assert seen["times"] == times.tolist()
    # every step, t = 0 included, with the series' points and cells
    assert [f["points"] for f in seen["frames"]] == [f.n_points for f in frames]
    assert [f["cells"] for f in seen["frames"]] == [f.n_cells for f in frames]
    assert all(f["points"] > 0 for f in seen["frames"])
    assert {"velocity", "id"} <= set(seen["point_arrays"])


def _plugin_constants():
    tree = ast.parse(PLUGIN.read_text(encoding="utf-8"))
    values = {}
    for node in tree.body:
        if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name):
            if node.targets[0].id in ("SURFACE", "KERNELS"):
                values[node.targets[0].id] = ast.literal_eval(node.value)
    return values


def test_plugin_panel_defaults_are_blobflows():
    # the plugin cannot import blobflow; its panel's defaults and kernels must not drift
    constants = _plugin_constants()
    assert constants["SURFACE"] == SURFACE_DEFAULTS
    assert sorted(constants["KERNELS"]) == sorted(SPLAT_KERNELS)


@needs_pvpython
def test_readme_pvpython_recipe_loads_the_plugin_from_another_folder(tmp_path):
    # the README's line, as typed, in a user's script run from a folder far from the clone
    x = (np.mgrid[0:6, 0:6, 0:6].reshape(3, -1).T + 0.5) * 0.01 + [0.0, 0.0, 1.0]
    flow = Flow(SimulationSource(BallisticParticles(x, np.zeros_like(x)), fps=10, duration=0.2))
    particles = flow.run(tmp_path / "series", progress=False)["particles"]
    user = tmp_path / "elsewhere"
    user.mkdir()
    script = user / "my_script.py"
    script.write_text(_readme_recipe(EXEC_RECIPE) + "\n"
                      + (HERE / "paraview_plugin_probe.py").read_text(encoding="utf-8"))
    result = subprocess.run([PVPYTHON, script.name, str(particles), "0.005", str(tmp_path)],
                            cwd=user,
                            capture_output=True, text=True, timeout=300,
                            env=_environment(tmp_path))
    assert result.returncode == 0, (result.stdout + result.stderr)[-3000:]
    loaded = LOADED.search(result.stdout)
    assert loaded and Path(loaded.group(1)) == PLUGIN and int(loaded.group(2)) == SCENE_COUNT
    seen = json.loads(next(line for line in result.stdout.splitlines()
                           if line.startswith("PROBE "))[len("PROBE "):])
    scenes = {f"blobflow{name}" for name in ("bouncing", "dam_break", "hair", "cloth_drape")}
    assert {"blobflowParticleSurface"} | scenes <= set(seen["proxies"])
    assert seen["panel"]["Kernel"].strip("'") == "sph"
    assert seen["panel"]["Anisotropic"] == "1" and seen["panel"]["Attributes"] == "velocity"
    assert seen["panel"]["Liquid"] == "0" and seen["panel"]["VolumeCorrection"] == "'as Liquid'"

    # two time steps of the surface filter: closed surfaces, bitwise blobflow's reconstruct
    from vtkmodules.util.numpy_support import vtk_to_numpy

    times, frames = read_series(particles)
    assert [s["time"] for s in seen["surfaces"]] == times[:2].tolist()
    for index, (step, frame) in enumerate(zip(seen["surfaces"], frames, strict=False)):
        assert step["points"] > 0 and step["triangles"] > 0 and step["open_edges"] == 0
        assert step["kind"] == "particle_surface"
        plugin = read_frame(tmp_path / f"plugin_surface_{index}.vtp")
        expected = reconstruct(frame, 0.005, feature_smoothing=5, smooth_iterations=10)
        np.testing.assert_array_equal(vtk_to_numpy(plugin.GetPoints().GetData()),
                                      np.asarray(expected.points))
        assert plugin.GetNumberOfPolys() == expected.n_cells
        np.testing.assert_array_equal(
            vtk_to_numpy(plugin.GetPointData().GetArray("velocity")),
            expected.point_data["velocity"])
    assert seen["surfaces"][0]["points"] != seen["surfaces"][1]["points"]  # it moved on
    # Liquid on: the liquid's surface (volume correction), tagged as such
    plugin = read_frame(tmp_path / "plugin_liquid_0.vtp")
    expected = reconstruct(frames[0], 0.005, feature_smoothing=5, smooth_iterations=10,
                           liquid=True)
    np.testing.assert_array_equal(vtk_to_numpy(plugin.GetPoints().GetData()),
                                  np.asarray(expected.points))
    assert plugin.GetFieldData().GetAbstractArray("blobflow_kind").GetValue(0) == "liquid_surface"

    # the bouncing scene as a temporal source: its frames at its times, as the scene runs
    assert seen["scene_times"] == [0.0, 0.1, 0.2, 0.3]
    reference = load_scene("bouncing").build(count=2)
    for step in seen["scene_frames"]:
        assert step["blocks"] == 1 and step["name"] == "particles" and step["points"] == 8
        z = reference.output("particles", step["time"]).points[:, 2].mean()
        assert step["z_mean"] == pytest.approx(z, abs=1e-12)
    assert (tmp_path / "run" / "particles.pvd").is_file()


LIGHT_PROBE = ('print("PROBE " + __import__("json").dumps(sorted(n for n in globals() '
               'if n.startswith("blobflow"))))')


def _in_terminal(command, env, cwd):
    """Start ``command`` in a terminal of its own (a pty, as a user would: line-buffered
    output); return the terminal's end and the process."""
    import pty

    master, slave = pty.openpty()
    process = subprocess.Popen(command, stdin=slave, stdout=slave, stderr=slave, env=env,
                               cwd=cwd, start_new_session=True)
    os.close(slave)
    return master, process


def _terminal_output(master, process, done, timeout=240):
    """What the terminal shows until ``done(text)``, the process exits or ``timeout`` s."""
    import select

    out, deadline = b"", time.monotonic() + timeout
    while time.monotonic() < deadline:
        ready, _, _ = select.select([master], [], [], 1.0)
        if ready:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # the other end closed: the process exited
                break
            if not chunk:
                break
            out += chunk
            if done(out.decode("utf-8", "replace")):
                break
        elif process.poll() is not None:
            break
    os.close(master)
    return out.decode("utf-8", "replace").replace("\r", "")


def _proxies(stdout):
    return json.loads(next(line for line in stdout.splitlines()
                           if line.startswith("PROBE "))[len("PROBE "):])


@pytest.mark.skipif(PVBATCH is None, reason="pvbatch not found: install Debian's 'paraview'")
def test_readme_pvbatch_recipe_loads_the_plugin_from_another_folder(tmp_path):
    script = tmp_path / "batch.py"
    script.write_text(_readme_recipe(EXEC_RECIPE) + "\n" + LIGHT_PROBE + "\n")
    result = subprocess.run([PVBATCH, script.name], cwd=tmp_path, capture_output=True, text=True,
                            timeout=300, env=_environment(tmp_path))
    assert result.returncode == 0, (result.stdout + result.stderr)[-3000:]
    loaded = LOADED.search(result.stdout)
    assert loaded and Path(loaded.group(1)) == PLUGIN
    assert "blobflowParticleSurface" in _proxies(result.stdout)
    assert len(_proxies(result.stdout)) == 1 + SCENE_COUNT


@needs_pvpython
def test_readme_recipe_typed_at_pvpythons_prompt(tmp_path):
    # an interactive prompt (a terminal): no BLOBFLOW_PYTHON, no blobflow on PATH; the startup
    # finds itself in the line typed
    env = _environment(tmp_path, TERM="dumb")
    del env["BLOBFLOW_PYTHON"]
    master, process = _in_terminal([PVPYTHON], env, tmp_path)
    for line in (_readme_recipe(EXEC_RECIPE), LIGHT_PROBE, "exit()"):
        os.write(master, line.encode() + b"\n")
    text = _terminal_output(master, process, lambda text: False)
    assert process.wait(timeout=30) == 0
    loaded = LOADED.search(text)
    assert loaded and Path(loaded.group(1)) == PLUGIN, text[-2000:]
    assert "blobflowParticleSurface" in _proxies(text)


@needs_pvpython
def test_readme_recipe_piped_to_pvpython_asks_blobflows_python(tmp_path):
    # no file, no line history: BLOBFLOW_PYTHON tells where blobflow (and so the plugin) is
    result = subprocess.run([PVPYTHON], input=_readme_recipe(EXEC_RECIPE) + "\n" + LIGHT_PROBE
                            + "\n", cwd=tmp_path, capture_output=True, text=True, timeout=300,
                            env=_environment(tmp_path))
    assert result.returncode == 0, (result.stdout + result.stderr)[-3000:]
    where = subprocess.run([_blobflow_python(tmp_path), "-c", "import pipeline; "
                            "print(pipeline.__file__)"], capture_output=True, text=True,
                           env=_environment(tmp_path), check=True).stdout.strip()
    loaded = LOADED.search(result.stdout)
    assert loaded and Path(loaded.group(1)) == Path(where).parent / "paraview" / "plugin.py"
    assert len(_proxies(result.stdout)) == 1 + SCENE_COUNT
    # and without any hint: one line saying what to set
    env = _environment(tmp_path)
    del env["BLOBFLOW_PYTHON"]
    result = subprocess.run([PVPYTHON], input=_readme_recipe(EXEC_RECIPE) + "\n", cwd=tmp_path,
                            capture_output=True, text=True, timeout=120, env=env)
    assert "set BLOBFLOW_PYTHON" in result.stderr


@needs_gui
def test_readme_paraview_script_recipe_loads_the_plugin_in_the_gui(tmp_path):
    recipe = shlex.split(_readme_recipe(r"paraview --script=PATH/pipeline/paraview/startup\.py"))
    # headless: under Xvfb; --exit quits once the script has run
    result = subprocess.run([XVFB_RUN, "-a", *recipe, "--exit"], cwd=tmp_path,
                            capture_output=True, text=True, timeout=300,
                            env=_environment(tmp_path))
    assert result.returncode == 0, (result.stdout + result.stderr)[-3000:]
    loaded = LOADED.search(result.stdout)
    assert loaded and Path(loaded.group(1)) == PLUGIN and int(loaded.group(2)) == SCENE_COUNT


@needs_gui
def test_readme_launch_recipe_opens_the_files_after_the_plugin(series, tmp_path):
    recipe = shlex.split(_readme_recipe(r"blobflow paraview --launch \[FILE \.\.\.\]"))
    assert recipe[-2:] == ["[FILE", "...]"]
    blobflow = Path(sys.executable).with_name("blobflow")
    command = [str(blobflow), *recipe[1:-2], str(series), str(series.with_name(
        "particles.vtp.series"))]
    env = _environment(tmp_path)
    if "PYTHONPATH" in os.environ:  # the worktree's blobflow, as the tests import it
        env["PYTHONPATH"] = os.environ["PYTHONPATH"]
    master, process = _in_terminal([XVFB_RUN, "-a", *command], env, tmp_path)
    try:
        text = _terminal_output(master, process, lambda text: text.count("blobflow: opened") == 2)
    finally:
        os.killpg(process.pid, signal.SIGTERM)  # the GUI stays open: close it
        process.wait(timeout=60)
    loaded = LOADED.search(text)
    assert loaded and Path(loaded.group(1)) == PLUGIN, text[-2000:]
    opened = [line.split("blobflow: opened ", 1)[1].strip() for line in text.splitlines()
              if "blobflow: opened " in line]
    assert opened == [str(series), str(series.with_name("particles.vtp.series"))], text[-2000:]
    assert text.index("loaded the ParaView plugin") < text.index("blobflow: opened")
