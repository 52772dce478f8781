"""The ``jello_fem`` scene: the finite-element jello drop, its tetrahedra and its embedded mesh."""

import numpy as np
import pytest

from filters.elastic.tetmesh import tet_volumes
from filters.elastic.topology import mesh_volume
from pipeline.cli import main
from pipeline.io.series import read_series
from pipeline.scene import load_scene

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
    for grid, surface in zip(tets, surfaces, strict=False):
        x = np.asarray(grid.points)
        # the mesh's vertices touch the floor (a 1 mm barrier): never through it
        assert np.asarray(surface.points)[:, 2].min() > 0.0
        # nu = 0.45: the impact, stopped by inelastic contacts within a step, compresses the
        # volume by up to ~1 % (2 % at the default 0.4 m drop); it comes back
        assert tet_volumes(x, cells).sum() == pytest.approx(rest, rel=0.02)
        assert mesh_volume(surface.points, triangles) == pytest.approx(rest_mesh, rel=0.02)
        density = np.asarray(grid.cell_data["strain_energy_density"])
        assert density.shape == (cells.shape[0],) and density.min() >= -1e-9
    # it fell from 0.1 m and now rests on the floor
    assert np.asarray(surfaces[0].points)[:, 2].min() == pytest.approx(0.1)
    assert np.asarray(surfaces[-1].points)[:, 2].min() < 2e-3
    # and, settling, keeps its volume within 1 %
    for grid, surface in zip(tets[-3:], surfaces[-3:], strict=False):
        assert tet_volumes(np.asarray(grid.points), cells).sum() == pytest.approx(rest, rel=0.01)
        assert mesh_volume(surface.points, triangles) == pytest.approx(rest_mesh, rel=0.01)
    assert np.asarray(tets[-1].cell_data["strain_energy_density"]).max() > 0.0


def _mass():
    return float(load_scene("jello_fem").build(**SMALL).source.simulation.system.masses.sum())


def test_energy_account_in_the_frames_never_rises(run):
    from filters.elastic.energy import ENERGY_FIELDS

    _, tets = read_series(run / "tets.pvd")
    totals = []
    for grid in tets:
        values = {name: float(np.asarray(grid.field_data[name]).ravel()[0])
                  for name in ENERGY_FIELDS}
        assert values["energy_total"] == pytest.approx(
            sum(values[name] for name in ENERGY_FIELDS[:-1]))
        totals.append(values["energy_total"])
    # nothing does work on the jello: damping, friction and inelastic contacts only take, up
    # to what backward Euler accepts per step (the kinetic energy of the whole mass at the
    # Newton tolerance, 1 mm/s), 8 steps of 1/240 s per frame
    mass = _mass()
    assert np.all(np.diff(totals) <= 8 * mass * 1e-3**2)
    assert totals[-1] < 0.9 * totals[0]


def test_embedded_mesh_follows_the_tetrahedra(run):
    flow = load_scene("jello_fem").build(**SMALL)
    embedding = flow.source.simulation.model.mesh.embedding
    _, tets = read_series(run / "tets.pvd")
    _, surfaces = read_series(run / "jello.pvd")
    for grid, surface in zip(tets[::8], surfaces[::8], strict=False):
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


# -- a user's own tetrahedral mesh, simulated as it is ------------------------------------------
def _column_tets(cells=8, size=0.1, jitter=0.2, seed=4):
    """A cube column of tetrahedra (a lattice with its interior nodes moved at random by up to
    ``jitter`` of a cell: not a lattice any more), lowest face at z = 0.5 mm."""
    from filters.elastic.tetmesh import box_tets

    mesh = box_tets((cells,) * 3, (size,) * 3, (0.0, 0.0, 0.0005))
    x = mesh.positions.copy()
    inner = np.all((mesh.positions > 1e-9) & (mesh.positions < size - 1e-9 + 0.0005 * np.array(
        [0, 0, 1])), axis=1) & (mesh.positions[:, 2] > 0.0005 + 1e-9)
    rng = np.random.default_rng(seed)
    x[inner] += rng.uniform(-jitter, jitter, (inner.sum(), 3)) * size / cells
    return x, mesh.tets


def _write(path, points, cells, file_format="gmsh22"):
    import meshio

    meshio.write(path, meshio.Mesh(points, cells), file_format=file_format)
    return path


def test_a_gmsh_tetrahedral_mesh_is_simulated_as_given(tmp_path):
    # a column of H = 0.1 m (nu = 0, frictionless floor) under its own weight shortens by
    # rho g H^2 / (2 E): written by meshio as Gmsh, read back, simulated on its own nodes
    from filters.elastic.contact import Colliders
    from filters.elastic.fem_simulation import FEMSimulation
    from filters.geometry import Plane
    from pipeline.io.volume_mesh import read_volume_mesh

    x, tets = _column_tets()
    path = _write(tmp_path / "column.msh", x, [("tetra", tets), ("triangle", tets[:5, :3])])
    points, read = read_volume_mesh(path)
    np.testing.assert_allclose(points, x)
    assert np.array_equal(read, tets)  # the boundary triangles beside them are ignored
    height, e_mod, h = 0.1, 1e5, 0.05
    floor = Colliders(friction=0.0).add(Plane((0, 0, 0), (0, 0, 1)))
    sim = FEMSimulation.from_tets(points, read, youngs_modulus=e_mod, poisson_ratio=0.0,
                                  colliders=floor, max_dt=h, mass_damping=30.0)
    np.testing.assert_array_equal(sim.state.positions, x)  # its own nodes, unchanged
    assert sim.system.n_tets == len(tets) and sim.model.mesh.fractions is None
    rest = sim.mesh_points()
    top = rest[:, 2] > rest[:, 2].max() - 1e-9
    bottom = rest[:, 2] < rest[:, 2].min() + 1e-9
    assert top.sum() == bottom.sum() == 81  # its boundary nodes are its surface
    for i in range(12):
        sim.advance_to((i + 1) * h)
    assert np.abs(sim.state.velocities).max() < 1e-6
    now = sim.mesh_points()
    shortening = height - (now[top, 2].mean() - now[bottom, 2].mean())
    assert shortening == pytest.approx(1000.0 * 9.81 * height**2 / (2 * e_mod), rel=0.05)


def test_the_scene_takes_a_volume_mesh_and_refuses_what_it_cannot_simulate(tmp_path, capsys):
    x, tets = _column_tets(cells=3)
    good = _write(tmp_path / "cube.msh", x, [("tetra", tets)])
    flow = load_scene("jello_fem").build(mesh=str(good), height=0.05)
    sim = flow.source.simulation
    assert sim.system.n_tets == len(tets)
    np.testing.assert_allclose(sim.state.positions[:, 2].min(), 0.05)
    # the other orientation convention (every tetrahedron negative) is the same mesh
    flipped = _write(tmp_path / "flipped.vtu", x, [("tetra", tets[:, [1, 0, 2, 3]])], "vtu")
    sim = load_scene("jello_fem").build(mesh=str(flipped)).source.simulation
    assert sim.volume() == pytest.approx(0.1**3)
    # Medit and Abaqus read the same
    for suffix, fmt in ((".mesh", "medit"), (".inp", "abaqus")):
        other = _write(tmp_path / f"cube{suffix}", x, [("tetra", tets)], fmt)
        assert load_scene("jello_fem").build(mesh=str(other)).source.simulation \
            .system.n_tets == len(tets)
    cases = {
        "hexahedron": _write(tmp_path / "hex.msh", np.array(
            [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1],
             [0, 1, 1]], float), [("hexahedron", np.arange(8)[None])]),
        "inverted": _write(tmp_path / "inverted.msh", x,
                           [("tetra", np.concatenate([tets[:3, [1, 0, 2, 3]], tets[3:]]))]),
        "flat": _write(tmp_path / "flat.msh", np.concatenate([x, x[:1] + 1e-3]),
                       [("tetra", np.concatenate([tets, [[0, len(x), 0, 1]]]))]),
        "separate bodies": _write(tmp_path / "two.msh", np.concatenate([x, x + 1.0]),
                                  [("tetra", np.concatenate([tets, tets + len(x)]))]),
    }
    capsys.readouterr()  # meshio's own warnings while writing the files
    for what, path in cases.items():
        code = main(["run", "jello_fem", "--set", f"mesh={path}", "--frames", "2", "--out",
                     str(tmp_path / "out"), "--no-render", "-q"])
        err = capsys.readouterr().err
        assert code == 2, what
        assert what.split()[-1].rstrip("s") in err and "mesh" in err, (what, err)
        assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_at_its_defaults_newton_converges_in_contact_and_the_energy_never_exceeds_its_start():
    # the scene's own drop (0.4 m, E = 5e4 Pa, friction 0.5, h = 1/240 s) through its 2 s:
    # Newton used to stop at its limit of 10 iterations in 38 % of the steps (44-56 % of those
    # in contact): the embedded surface's contact Hessian was a diagonal bound (linear
    # convergence) and the friction's smoothing 4 um wide (slip velocity 1 mm/s times h)
    flow = load_scene("jello_fem").build()
    sim = flow.source.simulation
    limit = sim.newton_options["max_newton"]
    h = sim.max_dt
    start = sim.energy()
    iterations, energies, touching = [], [], []
    for _ in range(int(round(2.0 / h))):
        sim.step(h)
        iterations.append(sim.last_info.newton_iterations)
        energies.append(sim.energy())
        touching.append(sim.contact.touching)
    iterations = np.array(iterations)
    assert np.mean(iterations >= limit) < 0.05
    assert max(touching) > 0 and np.mean(np.array(touching) > 0) > 0.5  # it landed and rests
    assert max(energies) <= start
    assert energies[-1] < 0.5 * start  # the landing took energy
