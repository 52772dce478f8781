"""ParaView (Debian's pvpython) opens the series blobflow writes as one animated dataset."""

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from pipeline import Flow, SimulationSource

from _helpers import ballistic

PVPYTHON = shutil.which("pvpython")
PROBE = Path(__file__).with_name("paraview_probe.py")

pytestmark = [
    pytest.mark.paraview,
    pytest.mark.skipif(PVPYTHON is None, reason="pvpython not found: install Debian's 'paraview' "
                       "package (.ci/run does) to run the ParaView round trip"),
]


def _probe(path):
    result = subprocess.run([PVPYTHON, str(PROBE), str(path)], capture_output=True, text=True,
                            timeout=120, env={"PATH": "/usr/bin:/bin"})
    assert result.returncode == 0, result.stderr[-2000:]
    line = next(l for l in result.stdout.splitlines() if l.startswith("PROBE "))
    return json.loads(line[len("PROBE "):])


@pytest.fixture(scope="module")
def series(tmp_path_factory):
    out = tmp_path_factory.mktemp("pv")
    flow = Flow(SimulationSource(ballistic(n=30), fps=10, duration=0.7))
    return flow.run(out, progress=False)["particles"]


@pytest.mark.parametrize("which", ["pvd", "series"])
def test_paraview_reads_times_and_arrays(series, which):
    path = series if which == "pvd" else series.with_name("particles.vtp.series")
    seen = _probe(path)
    assert seen["times"] == [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]
    assert [f["points"] for f in seen["frames"]] == [30] * 8
    assert {"velocity", "id"} <= set(seen["point_arrays"])


def test_paraview_reads_the_tetrahedra_and_the_embedded_mesh_of_a_fem_jello(tmp_path):
    from pipeline.scene import load_scene

    flow = load_scene("jello_fem").build(spacing=0.06, radius=0.12)
    flow.source.set_frames(10, frames=3)
    paths = flow.run(tmp_path, progress=False)
    tets = _probe(paths["tets"])
    assert tets["reader"] == "PVDReader" and tets["times"] == [0.0, 0.1, 0.2]
    n_tets = flow.source.simulation.model.mesh.tets.shape[0]
    assert [f["cells"] for f in tets["frames"]] == [n_tets] * 3
    assert "strain_energy_density" in tets["cell_arrays"]
    assert {"velocity", "id"} <= set(tets["point_arrays"])
    jello = _probe(paths["jello"])
    assert jello["times"] == [0.0, 0.1, 0.2]
    assert {"velocity", "id"} <= set(jello["point_arrays"])
