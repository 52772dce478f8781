"""Frames keep their particles in one order, by ``id``: a particle is the same row in every frame,
emitted particles come after the others and dead ones leave the rest in order, so that viewers
interpolating between time samples by index (ParaView's TemporalInterpolator, USD) move every
particle to the middle of its own path.  Frames stay lean: no checkpoint in them."""

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from filters.simulation import Frame, OutputSpec, Simulation, State
from pipeline import Flow, SimulationSource
from pipeline.io.convert import frame_to_vtk, id_order
from pipeline.io.series import read_collection, read_series
from pipeline.scene import load_scene

HERE = Path(__file__).parent
PVPYTHON = shutil.which("pvpython")


def _ids(frame) -> np.ndarray:
    return np.asarray(frame.point_data["id"]).reshape(-1)


def _run_scene(name, out, frames, fps=10.0, **parameters):
    flow = load_scene(name).build(**parameters)
    flow.source.set_frames(fps, frames=frames)
    flow.run(out, progress=False)
    return flow, read_series(out / "particles.pvd")


@pytest.fixture(scope="module")
def drop_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("drop")
    flow, (times, frames) = _run_scene("drop", out, 6, surface=False, spacing=0.02)
    return out, flow, times, frames


# -- one order in every frame ----------------------------------------------------------------
@pytest.mark.parametrize("scene", ["drop", "dam_break"])
def test_sph_scenes_write_every_particle_in_the_same_row_in_every_frame(scene, tmp_path):
    """Whatever order the solver keeps its particles in (the SPH solvers sort them by grid cell
    as they move: in all 6 of these frames), the frames keep theirs by id."""
    flow = load_scene(scene).build(surface=False, spacing=0.02)
    flow.source.set_frames(10.0, frames=6)
    sim = flow.source.simulation
    for t in flow.times:
        frame = flow.output("particles", float(t))
        n = sim.state.n_points
        np.testing.assert_array_equal(_ids(frame), np.arange(n))  # fixed count: ids 0..N-1
        inner = sim.state.extra["id"]
        # row k of the frame is the particle the solver calls k, with its own velocity
        order = np.argsort(inner)
        np.testing.assert_array_equal(frame.points, sim.state.positions[order])
        np.testing.assert_array_equal(frame.point_data["velocity"], sim.state.velocities[order])


def test_written_drop_frames_are_in_id_order_and_move_continuously(drop_run):
    _, _, times, frames = drop_run
    for a, b, dt in zip(frames, frames[1:], np.diff(times), strict=False):
        np.testing.assert_array_equal(_ids(a), np.arange(a.n_points))
        np.testing.assert_array_equal(_ids(b), _ids(a))
        # the same row is the same particle: it moved at most as far as the fastest went
        speed = max(np.linalg.norm(a.point_data["velocity"], axis=1).max(),
                    np.linalg.norm(b.point_data["velocity"], axis=1).max())
        step = np.linalg.norm(b.points - a.points, axis=1)
        assert step.max() <= 2.0 * speed * dt + 1e-9


def test_noise_smoke_appends_the_emitted_and_removes_the_dead_in_order(tmp_path):
    _, (times, frames) = _run_scene("noise_smoke", tmp_path, 8, rate=400.0, lifetime=0.2,
                                    surface=False, seed=3)
    died = appended = 0
    for a, b in zip(frames, frames[1:], strict=False):
        ia, ib = _ids(a), _ids(b)
        assert np.all(np.diff(ib) > 0)
        survivors = ia[np.isin(ia, ib)]
        m = survivors.shape[0]
        np.testing.assert_array_equal(ib[:m], survivors)  # the survivors first, in order
        assert ia.shape[0] == 0 or np.all(ib[m:] > ia.max())  # then the newborn, appended
        keep = np.isin(ia, ib)
        np.testing.assert_array_equal(b.point_data["size"][:m], a.point_data["size"][keep])
        died += int(ia.shape[0] - m)
        appended += int(ib.shape[0] - m)
    assert died > 20 and appended > 200, (died, appended)  # both happened


class _Shuffled(Simulation):
    """A user simulation that keeps its particles in a new random order every step, emits
    some and kills some: frames written from it are still in id order."""

    def __init__(self, n=12, lines=False):
        self.rng = np.random.default_rng(5)
        self.lines = lines
        x = self.rng.uniform(0, 1, (n, 3))
        self.model = None
        self.state = State(x, np.ones((n, 3)), extra={"id": np.arange(n, dtype=np.int64)})

    variable_count = True

    @property
    def output_spec(self):
        if self.lines:
            return OutputSpec(point_arrays=(("velocity", 3), ("id", 1)), topology="lines",
                              fixed_topology=False)
        return OutputSpec(point_arrays=(("velocity", 3), ("id", 1)), fixed_topology=False)

    def frame(self):
        s = self.state
        data = {"velocity": s.velocities.copy(), "id": s.extra["id"].copy()}
        if not self.lines:
            return Frame(s.time, s.positions.copy(), data)
        # one line between the two particles of smallest id, in the solver's rows
        rows = np.argsort(s.extra["id"])[:2]
        return Frame(s.time, s.positions.copy(), data,
                     connectivity=(np.array([0, 2]), rows.astype(np.int64)))

    def _step(self, dt):
        s = self.state
        s.positions += dt * s.velocities
        ids = s.extra["id"]
        alive = np.ones(ids.shape[0], bool)
        alive[self.rng.integers(ids.shape[0])] = False
        born = np.arange(2, dtype=np.int64) + ids.max() + 1
        x = np.concatenate([s.positions[alive], self.rng.uniform(0, 1, (2, 3))])
        ids = np.concatenate([ids[alive], born])
        order = self.rng.permutation(ids.shape[0])
        s.positions = x[order]
        s.velocities = np.ones_like(x)
        s.extra["id"] = ids[order]


def test_flow_of_a_user_simulation_writes_in_id_order(tmp_path):
    flow = Flow(SimulationSource(_Shuffled(), fps=10, frames=5))
    _, frames = read_series(flow.run(tmp_path, progress=False)["particles"])
    previous = None
    for frame in frames:
        ids = _ids(frame)
        assert np.all(np.diff(ids) > 0)
        if previous is not None:
            kept = previous[np.isin(previous, ids)]
            np.testing.assert_array_equal(ids[:kept.shape[0]], kept)
        previous = ids


def test_cells_follow_their_points_when_reordered():
    sim = _Shuffled(lines=True)
    sim.advance_to(0.3)
    data = frame_to_vtk(sim.frame(), sim.output_spec)
    ids = np.asarray(data.GetPointData().GetArray("id"))
    assert np.all(np.diff(ids) > 0)
    line = data.GetCell(0)
    ends = [line.GetPointId(0), line.GetPointId(1)]
    np.testing.assert_array_equal(ids[ends], np.sort(sim.state.extra["id"])[:2])


def test_id_order_with_gaps_duplicates_and_floats():
    rng = np.random.default_rng(1)
    ids = rng.permutation(np.arange(0, 40, 2))  # gaps (dead particles)
    np.testing.assert_array_equal(ids[id_order(ids)], np.sort(ids))
    big = rng.permutation(10**9 + np.arange(9))  # far from 0..N: a sort
    np.testing.assert_array_equal(big[id_order(big)], np.sort(big))
    dup = np.array([3, 1, 3, 0])  # equal ids keep their order
    np.testing.assert_array_equal(id_order(dup), [3, 1, 0, 2])
    np.testing.assert_array_equal(id_order(np.array([2.5, -1.0, 0.0])), [1, 2, 0])
    assert id_order(np.arange(5)) is None and id_order(np.zeros(0, int)) is None
    with pytest.raises(ValueError, match="shape"):
        id_order(np.zeros((2, 2)))


# -- interpolating between frames ------------------------------------------------------------
def _matched_midpoint(a, b):
    """The middle of every particle's path between frames a and b, by id."""
    ia, ib = _ids(a), _ids(b)
    common = np.intersect1d(ia, ib)
    oa, ob = np.argsort(ia), np.argsort(ib)
    xa = a.points[oa[np.searchsorted(ia[oa], common)]]
    xb = b.points[ob[np.searchsorted(ib[ob], common)]]
    return common, 0.5 * (xa + xb)


def test_usd_time_samples_interpolate_to_the_id_matched_midpoint(drop_run, tmp_path):
    pytest.importorskip("pxr", reason="usd-core is not installed")
    from pxr import Usd, UsdGeom

    from pipeline.io.usd import export_usd

    out, _, times, frames = drop_run
    usd = export_usd([out / "particles.pvd"], tmp_path / "drop.usda", fps=10)
    stage = Usd.Stage.Open(str(usd))
    prim = UsdGeom.Points(stage.GetPrimAtPath("/blobflow/particles"))
    travel = 0.0
    for k in range(len(frames) - 1):
        ids, middle = _matched_midpoint(frames[k], frames[k + 1])
        np.testing.assert_array_equal(np.asarray(prim.GetIdsAttr().Get(k)), ids)
        between = np.asarray(prim.GetPointsAttr().Get(k + 0.5), dtype=np.float64)
        np.testing.assert_allclose(between, middle, rtol=0, atol=1e-6)  # float32 samples
        travel = max(travel, np.abs(frames[k + 1].points - frames[k].points).max())
    assert travel > 0.02  # the drop moved by far more than the tolerance


@pytest.mark.paraview
@pytest.mark.skipif(PVPYTHON is None, reason="pvpython not found: install Debian's 'paraview'")
def test_paraview_temporal_interpolator_lands_on_the_id_matched_midpoint(drop_run, tmp_path):
    out, _, times, frames = drop_run
    k = 3
    t = 0.5 * (times[k] + times[k + 1])
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    result = subprocess.run([PVPYTHON, str(HERE / "paraview_interpolate_probe.py"),
                             str(out / "particles.pvd"), repr(float(t))],
                            capture_output=True, text=True, timeout=240, env=env)
    assert result.returncode == 0, (result.stdout + result.stderr)[-3000:]
    line = next(line for line in result.stdout.splitlines() if line.startswith("PROBE "))
    seen = json.loads(line[len("PROBE "):])
    ids, middle = _matched_midpoint(frames[k], frames[k + 1])
    np.testing.assert_array_equal(np.asarray(seen["id"]), ids)
    np.testing.assert_allclose(np.asarray(seen["points"]), middle, rtol=0, atol=1e-12)
    assert np.abs(frames[k + 1].points - frames[k].points).max() > 0.01


# -- lean frames ---------------------------------------------------------------------------
def test_particle_frames_hold_no_state_and_at_most_100_bytes_a_particle(tmp_path):
    """``drop`` at its default size (1,745 particles) through the impact: every frame file is
    at most 100 bytes a particle (130 when each frame carried the simulation's state)."""
    out = tmp_path / "drop"
    flow, (times, frames) = _run_scene("drop", out, 16, fps=30.0, surface=False)
    n = flow.source.simulation.state.n_points
    assert n > 1500
    for (t, name), frame in zip(read_collection(out / "particles.pvd"), frames, strict=False):
        # no checkpoint arrays: the time and the safety net's count are all the field data
        assert sorted(frame.field_data.keys()) == ["TimeValue", "container_corrections"]
        size = (out / name).stat().st_size
        assert size <= 100 * n, f"frame t = {t}: {size / n:.1f} bytes a particle"
    assert sorted(frames[-1].point_data.keys()) == ["density", "id", "pressure", "velocity"]
