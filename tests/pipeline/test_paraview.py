"""ParaView (Debian's pvpython) opens the series and XDMF files blobflow writes, and loads
blobflow's plugin: the surface filter on a particle series, a scene as a temporal source."""

import ast
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from filters import BallisticParticles
from filters.kernels import SPLAT_KERNELS
from pipeline import Flow, SimulationSource
from pipeline.cli import main
from pipeline.scene import load_scene
from pipeline.series import read_frame, read_series
from pipeline.surface import reconstruct
from pipeline.surface_options import SURFACE_DEFAULTS

from _helpers import ballistic

PVPYTHON = shutil.which("pvpython")
HERE = Path(__file__).parent
PLUGIN = Path(__file__).resolve().parents[2] / "pipeline" / "paraview_plugin.py"
STARTUP = PLUGIN.with_name("paraview_startup.py")

needs_pvpython = pytest.mark.skipif(
    PVPYTHON is None, reason="pvpython not found: install Debian's 'paraview' package "
    "(.ci/run does) to run the ParaView round trips")
pytestmark = [pytest.mark.paraview]


def _pvpython(script, *arguments, tmp_path=None, timeout=240):
    env = {"PATH": "/usr/bin:/bin", "BLOBFLOW_PYTHON": sys.executable,
           "HOME": str(tmp_path or Path.home())}
    for name in ("NUMBA_NUM_THREADS", "NUMBA_CACHE_DIR"):
        if name in os.environ:
            env[name] = os.environ[name]
    result = subprocess.run([PVPYTHON, str(script), *map(str, arguments)], capture_output=True,
                            text=True, timeout=timeout, env=env)
    assert result.returncode == 0, (result.stdout + result.stderr)[-3000:]
    line = next(l for l in result.stdout.splitlines() if l.startswith("PROBE "))
    return json.loads(line[len("PROBE "):]), result.stderr


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
def test_plugin_surface_filter_and_scene_source(tmp_path):
    x = (np.mgrid[0:6, 0:6, 0:6].reshape(3, -1).T + 0.5) * 0.01 + [0.0, 0.0, 1.0]
    flow = Flow(SimulationSource(BallisticParticles(x, np.zeros_like(x)), fps=10, duration=0.2))
    particles = flow.run(tmp_path / "series", progress=False)["particles"]
    seen, _ = _pvpython(HERE / "paraview_plugin_probe.py", STARTUP, particles, 0.005, tmp_path,
                        tmp_path=tmp_path)
    scenes = {f"blobflow{name}" for name in ("bouncing", "dam_break", "hair", "cloth_drape")}
    assert {"blobflowParticleSurface"} | scenes <= set(seen["proxies"])
    assert seen["panel"]["Kernel"].strip("'") == "sph"
    assert seen["panel"]["Anisotropic"] == "1" and seen["panel"]["Attributes"] == "velocity"

    # two time steps of the surface filter: closed surfaces, bitwise blobflow's reconstruct
    times, frames = read_series(particles)
    assert [s["time"] for s in seen["surfaces"]] == times[:2].tolist()
    for index, (step, frame) in enumerate(zip(seen["surfaces"], frames)):
        assert step["points"] > 0 and step["triangles"] > 0 and step["open_edges"] == 0
        plugin = read_frame(tmp_path / f"plugin_surface_{index}.vtp")
        expected = reconstruct(frame, 0.005, feature_smoothing=5, smooth_iterations=10)
        from vtkmodules.util.numpy_support import vtk_to_numpy
        np.testing.assert_array_equal(vtk_to_numpy(plugin.GetPoints().GetData()),
                                      np.asarray(expected.points))
        assert plugin.GetNumberOfPolys() == expected.n_cells
        np.testing.assert_array_equal(
            vtk_to_numpy(plugin.GetPointData().GetArray("velocity")),
            expected.point_data["velocity"])
    assert seen["surfaces"][0]["points"] != seen["surfaces"][1]["points"]  # it moved on

    # the bouncing scene as a temporal source: its frames at its times, as the scene runs
    assert seen["scene_times"] == [0.0, 0.1, 0.2, 0.3]
    reference = load_scene("bouncing").build(count=2)
    for step in seen["scene_frames"]:
        assert step["blocks"] == 1 and step["name"] == "particles" and step["points"] == 8
        z = reference.output("particles", step["time"]).points[:, 2].mean()
        assert step["z_mean"] == pytest.approx(z, abs=1e-12)
    assert (tmp_path / "run" / "particles.pvd").is_file()
