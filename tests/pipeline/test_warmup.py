"""First runs: the surface compiled in a second process while the simulation runs ahead."""

from pathlib import Path

import numpy as np
import pytest

from filters.simulation import SimulationUnstableError
from pipeline.algorithm import run_chain
from pipeline.cli import warmup
from pipeline.io.convert import frame_to_vtk
from pipeline.scene import load_scene
from pipeline.surface import surface_stages
from pipeline.surface.options import surface_options_from_record


class _Worker:
    """Stands for the compiling process: alive for ``checks`` calls of ``is_alive``."""

    def __init__(self, checks):
        self.checks = checks
        self.joined = False

    def is_alive(self):
        self.checks -= 1
        return self.checks >= 0

    def join(self):
        self.joined = True


def _dam_break(frames=4):
    scene = load_scene("dam_break")
    params = {**scene.defaults(), "spacing": 0.02, "tank_length": 0.2, "smooth_iterations": 2,
              "feature_smoothing": 2}
    flow = scene.build(**params)
    flow.source.set_frames(30.0, frames=frames)
    return flow, params


def _bytes(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_a_run_after_simulating_ahead_writes_the_same_bytes_without_stepping_again(tmp_path):
    plain, _ = _dam_break()
    plain.run(tmp_path / "plain", progress=False)
    plain_steps = plain.source.simulation.steps_taken

    ahead, _ = _dam_break()
    worker = _Worker(checks=2)
    assert warmup.simulate_while(worker, ahead.source) == 2
    assert worker.joined
    assert ahead.source.simulation.state.time == pytest.approx(2 / 30.0)
    ahead.run(tmp_path / "ahead", progress=False)
    # DFSPH keeps warm starts in its state: restored, not recomputed, and the same bits
    assert ahead.source.simulation.steps_taken == plain_steps
    assert _bytes(tmp_path / "ahead") == _bytes(tmp_path / "plain")


def test_simulating_ahead_stops_at_the_limit_and_at_a_simulation_error():
    flow, _ = _dam_break(frames=6)
    assert warmup.simulate_while(_Worker(checks=99), flow.source, limit=3) == 3

    class Failing:
        cache_size = 16
        times = np.arange(5) / 30.0

        def go_to(self, t):
            if t > 0.05:
                raise SimulationUnstableError(t, "density error", "smaller steps")

    worker = _Worker(checks=99)
    assert warmup.simulate_while(worker, Failing()) == 1  # the run meets the error itself
    assert worker.joined


def test_a_rewind_after_a_restore_forgets_the_states_of_the_other_start():
    flow, _ = _dam_break()
    source = flow.source
    source.go_to(float(source.times[1]))
    source.go_to(float(source.times[2]))
    assert source.cached_times[-1] == pytest.approx(source.times[2])
    source.rewind()  # simulated from the initial state: kept
    assert source.simulation.state.time == 0.0 and len(source.cached_times) == 3
    source.restore(source._cache[float(source.times[1])])
    source.rewind()  # a restored state may be of another run: forgotten
    assert source.cached_times == [0.0]


def test_the_made_up_block_builds_a_closed_surface_in_the_tank_corner():
    flow, _ = _dam_break()
    params = load_scene("dam_break").defaults()  # the main job's spacing and tank
    options = surface_options_from_record({"parameters": params})
    spec = flow.source.simulation.output_spec
    box = options["implicit"]
    frame = warmup._block(params["spacing"], box.lower, spec, box.upper)
    assert set(frame.point_data) == {name for name, _ in spec.point_arrays}
    assert frame.point_data["id"].dtype == np.int64
    surface = run_chain(surface_stages(**options), frame_to_vtk(frame, spec, "polydata"))
    import pyvista as pv

    mesh = pv.wrap(surface)
    assert mesh.n_cells > 0
    assert mesh.n_open_edges == 0  # cut at the walls and closed there
    assert mesh.bounds[0] == pytest.approx(0.0, abs=1e-6)  # on the wall x = 0
    pieces = mesh.connectivity().point_data["RegionId"].max() + 1
    assert pieces >= 2  # the block and at least one loose drop


def test_nothing_starts_without_surface_options_or_with_a_warm_cache(monkeypatch):
    flow, params = _dam_break()
    spec = flow.source.simulation.output_spec
    assert warmup.compile_surface_in_background({}, spec) is None
    monkeypatch.setattr(warmup, "surface_cache_is_warm", lambda: True)
    options = surface_options_from_record({"parameters": params})
    assert warmup.compile_surface_in_background(options, spec) is None


def test_simulating_ahead_leaves_a_core_to_the_compiling_process(monkeypatch):
    import numba

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs 2 numba threads")
    monkeypatch.setattr(warmup, "_usable_cores", lambda: 2)
    seen = []

    class Source:
        cache_size = 16
        times = np.arange(4) / 30.0

        def go_to(self, t):
            seen.append(numba.get_num_threads())

    before = numba.get_num_threads()
    assert warmup.simulate_while(_Worker(checks=99), Source()) == 3
    assert seen == [1, 1, 1]
    assert numba.get_num_threads() == before
