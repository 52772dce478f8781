"""The ``jello_fem`` scene: the finite-element jello drop, its tetrahedra and its embedded mesh."""

import numpy as np
import pytest

from filters.elastic.tetmesh import tet_volumes
from filters.elastic.topology import mesh_volume
from pipeline.cli import main
from pipeline.scene import load_scene
from pipeline.series import read_series

SMALL = {"spacing": 0.06, "radius": 0.12, "height": 0.1}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The scene (small lattice), 0.8 s at 30 fps, written through the command line."""
    out = tmp_path_factory.mktemp("jello_fem")
    argv = ["run", "jello_fem", "--duration", "0.8", "--out", str(out), "--no-render", "-q"]
    for key, value in SMALL.items():
        argv += ["--set", f"{key}={value}"]
    assert main(argv) == 0
    return out


def test_jello_falls_rests_on_the_floor_and_keeps_its_volume(run):
    times, tets = read_series(run / "tets.pvd")
    _, surfaces = read_series(run / "jello.pvd")
    assert len(times) == len(surfaces) == 25
    first = tets[0]
    cells = first.cells_dict[10]  # VTK_TETRA
    rest = tet_volumes(first.points, cells).sum()
    triangles = surfaces[0].faces.reshape(-1, 4)[:, 1:]
    rest_mesh = mesh_volume(surfaces[0].points, triangles)
    for grid, surface in zip(tets, surfaces):
        x = np.asarray(grid.points)
        assert x[:, 2].min() > -2e-3  # never through the floor
        # nu = 0.45: the volume stays within 1 % through the fall, the impact and the wobble
        assert tet_volumes(x, cells).sum() == pytest.approx(rest, rel=0.01)
        assert mesh_volume(surface.points, triangles) == pytest.approx(rest_mesh, rel=0.01)
        density = np.asarray(grid.cell_data["strain_energy_density"])
        assert density.shape == (cells.shape[0],) and density.min() >= -1e-9
    # it fell from 0.1 m and now rests on the floor (the lattice reaches 0.25 spacing below)
    assert np.asarray(surfaces[0].points)[:, 2].min() == pytest.approx(0.1)
    assert np.asarray(surfaces[-1].points)[:, 2].min() < 0.3 * SMALL["spacing"]
    assert np.asarray(tets[-1].cell_data["strain_energy_density"]).max() > 0.0


def test_embedded_mesh_follows_the_tetrahedra(run):
    flow = load_scene("jello_fem").build(**SMALL)
    embedding = flow.source.simulation.model.mesh.embedding
    _, tets = read_series(run / "tets.pvd")
    _, surfaces = read_series(run / "jello.pvd")
    for grid, surface in zip(tets[::8], surfaces[::8]):
        np.testing.assert_allclose(surface.points, embedding.points(np.asarray(grid.points)),
                                   rtol=0, atol=1e-12)
        np.testing.assert_allclose(surface.point_data["velocity"],
                                   embedding.points(np.asarray(grid.point_data["velocity"])),
                                   rtol=0, atol=1e-12)


def test_a_resumed_run_writes_the_same_bytes(run, tmp_path):
    out = tmp_path / "resumed"
    argv = ["run", "jello_fem", "--out", str(out), "--no-render", "-q"]
    for key, value in SMALL.items():
        argv += ["--set", f"{key}={value}"]
    assert main(argv + ["--duration", "0.3"]) == 0
    assert main(argv + ["--duration", "0.8", "--resume"]) == 0
    for name in ("tets/tets_000024.vtu", "jello/jello_000024.vtp", "tets/tets_000015.vtu"):
        assert (out / name).read_bytes() == (run / name).read_bytes()


def test_the_tetrahedra_are_not_drawn_the_mesh_is():
    flow = load_scene("jello_fem").build(**SMALL)
    assert flow.written_outputs() == ["tets", "jello"]
    assert flow.drawn_outputs() == ["jello"]


def test_bad_parameters_are_refused_before_anything_is_written(tmp_path, capsys):
    for assignment in ("material=rubber", "poisson_ratio=0.5", "youngs_modulus=0",
                       "damping=-1"):
        code = main(["run", "jello_fem", "--set", assignment, "--frames", "2", "--out",
                     str(tmp_path / "x"), "--no-render", "-q"])
        assert code == 2
        assert assignment.split("=")[0] in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
