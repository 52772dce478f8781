"""The checkpoint lives beside the series, in one file: a run killed anywhere (between two
frames, between a frame and its checkpoint, half way through writing either) resumes to the
same bytes as a run never interrupted; runs from when every frame carried the state still
resume; the file is read without pickle, and a damaged or foreign one is never used."""

import os
import subprocess
import sys
from pathlib import Path

import _checkpoint_runs
import numpy as np
import pytest
from _helpers import ballistic
from vtkmodules.vtkFiltersCore import vtkElevationFilter

from filters.simulation import State
from pipeline import Flow, SimulationSource
from pipeline.cli import main
from pipeline.io.checkpoint import (
    Checkpoint,
    CheckpointError,
    checkpoint_path,
    file_digest,
    read_checkpoint,
    write_checkpoint,
)
from pipeline.io.convert import has_state, state_to_field_data
from pipeline.io.series import read_collection, read_frame

ROOT = Path(__file__).resolve().parents[2]
DRIVER = ROOT / "tests" / "_checkpoint_runs.py"


def _tree(folder: Path) -> dict:
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _assert_same_tree(a: Path, b: Path) -> None:
    ta, tb = _tree(a), _tree(b)
    assert sorted(ta) == sorted(tb)
    for name in ta:
        assert ta[name] == tb[name], f"{name} differs"


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """Each flow run once without interruption: the bytes every resumed run must end with."""
    runs = {}
    for kind in ("ballistic", "drop"):
        out = tmp_path_factory.mktemp(f"full-{kind}")
        _checkpoint_runs.run(out, kind)
        runs[kind] = out
    return runs


# -- the file ------------------------------------------------------------------------------------
def _state(rng, n=6):
    return State(rng.random((n, 3)), rng.random((n, 3)), time=0.25, step=9, extra={
        "id": rng.permutation(n).astype(np.int64), "rng": np.array([2**63 + 5, 7], np.uint64),
        "flag": np.array([True, False]), "carry": np.array([0.3])})


def test_checkpoint_round_trip_is_exact_and_deterministic(tmp_path, rng):
    state = _state(rng)
    path = tmp_path / "particles.checkpoint.npz"
    digest = bytes(range(32))
    write_checkpoint(path, Checkpoint(state, 5, 0.25, {"particles": digest}))
    first = path.read_bytes()
    write_checkpoint(path, Checkpoint(state, 5, 0.25, {"particles": digest}))
    assert path.read_bytes() == first  # no clock in it
    back = read_checkpoint(path)
    assert (back.frame, back.time, back.digests) == (5, 0.25, {"particles": digest})
    arrays, again = state.to_arrays(), back.state.to_arrays()
    assert list(arrays) == list(again)
    for name in arrays:
        assert arrays[name].dtype == again[name].dtype, name  # uint64, bool kept as they are
        assert arrays[name].tobytes() == again[name].tobytes(), name
    assert not list(tmp_path.glob(".*tmp"))
    assert checkpoint_path(tmp_path / "particles.pvd") == path
    assert checkpoint_path(tmp_path / "particles.vtp.series") == path


class _Trap:
    """Unpickling this creates ``marker``: proof that a loader ran pickle."""

    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        return (Path.touch, (Path(self.marker),))


def _npz(path, **arrays):
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def test_damaged_or_hostile_checkpoints_are_refused_without_pickle(tmp_path, rng):
    good = tmp_path / "good.npz"
    write_checkpoint(good, Checkpoint(_state(rng), 5, 0.25, {}))
    with np.load(good) as archive:
        members = {name: archive[name] for name in archive.files}
    marker = tmp_path / "unpickled"
    trap = np.empty(1, dtype=object)
    trap[0] = _Trap(marker)
    cases = {
        "pickle": {**members, "state:extra:evil": trap},
        "text": {**members, "state:extra:note": np.array(["hello"])},
        "format": {**members, "format": np.array([2])},
        "no_positions": {k: v for k, v in members.items() if k != "state:positions"},
        "nan": {**members, "state:positions": np.full((6, 3), np.nan)},
        "shapes": {**members, "state:velocities": np.zeros((5, 3))},
        "time": {**members, "time": np.array([0.5])},
        "frame": {**members, "frame": np.array([-1])},
        "digest": {**members, "digest:particles": np.zeros(8, np.uint8)},
    }
    for name, arrays in cases.items():
        path = tmp_path / f"{name}.npz"
        _npz(path, **arrays)
        with pytest.raises(CheckpointError, match="not a (valid|readable) checkpoint"):
            read_checkpoint(path)
    assert not marker.exists(), "a checkpoint loader unpickled"
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"PK\x03\x04" + bytes(100))
    for path in (truncated, garbage):
        with pytest.raises(CheckpointError):
            read_checkpoint(path)
    with pytest.raises(FileNotFoundError):
        read_checkpoint(tmp_path / "missing.npz")


# -- kept by a run ----------------------------------------------------------------------------
def test_one_checkpoint_beside_the_series_none_in_the_frames(uninterrupted):
    out = uninterrupted["ballistic"]
    assert sorted(p.name for p in out.iterdir()) == [
        "elevation", "elevation.pvd", "elevation.vtp.series", "particles",
        "particles.checkpoint.npz", "particles.pvd", "particles.vtp.series"]
    checkpoint = read_checkpoint(out / "particles.checkpoint.npz")
    assert (checkpoint.frame, checkpoint.time) == (10, 0.5)  # the last frame
    for name in ("particles", "elevation"):
        entries = read_collection(out / f"{name}.pvd")
        assert checkpoint.digests[name] == file_digest(out / entries[10][1])
        assert not any(has_state(read_frame(out / file)) for _, file in entries)
    reference = ballistic()
    for k in range(11):  # frame by frame, as the run stepped
        reference.advance_to(round(k / 20, 9))
    np.testing.assert_array_equal(checkpoint.state.positions, reference.state.positions)


def test_checkpoint_every_k_frames_or_seconds(tmp_path):
    seen = {}

    def record(name):
        def on_frame(index, t):
            seen.setdefault(name, []).append(read_checkpoint(
                tmp_path / name / "particles.checkpoint.npz").frame)
        return on_frame

    for name, every, seconds in (("frames", 3, 1e6), ("seconds", 1000, 1e-9)):
        flow = Flow(SimulationSource(ballistic(), fps=20, frames=8))
        flow.run(tmp_path / name, progress=False, on_frame=record(name),
                 checkpoint_every=every, checkpoint_seconds=seconds)
    assert seen["frames"] == [0, 0, 0, 3, 3, 3, 6, 7]  # 0, every 3, and the last
    assert seen["seconds"] == list(range(8))
    flow = Flow(SimulationSource(ballistic(), fps=20, frames=3, checkpoint=False))
    flow.run(tmp_path / "none", progress=False)
    assert not (tmp_path / "none" / "particles.checkpoint.npz").exists()
    with pytest.raises(ValueError, match="checkpoint_every"):
        flow.run(tmp_path / "none", checkpoint_every=0)
    with pytest.raises(ValueError, match="checkpoint_seconds"):
        flow.run(tmp_path / "none", checkpoint_seconds=0.0)


# -- killed anywhere, resumed to the same bytes -----------------------------------------------
@pytest.mark.parametrize("kind, where, index", [
    ("ballistic", "after_frame", 0),         # only the first checkpoint
    ("ballistic", "after_frame", 2),         # two frames after it
    ("ballistic", "before_checkpoint", 4),   # a frame whose checkpoint never came
    ("ballistic", "inside_checkpoint", 8),   # the new checkpoint half way to its place
    ("ballistic", "mid_frame", 5),           # one series a frame longer than the other
    ("ballistic", "before_checkpoint", 10),  # every frame written, the last checkpoint not
    ("drop", "before_checkpoint", 3),        # SPH: sorts its particles while making frames
    ("drop", "after_frame", 5),
])
def test_resume_after_a_kill_anywhere_is_bitwise_identical(uninterrupted, tmp_path, kind, where,
                                                           index):
    out = tmp_path / "run"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), str(ROOT / "tests")])}
    killed = subprocess.run([sys.executable, str(DRIVER), str(out), kind, where, str(index)],
                            capture_output=True, text=True, timeout=240, env=env)
    assert killed.returncode == -9, killed.stderr[-2000:]
    listed = read_collection(out / "particles.pvd")
    assert len(listed) == index + 1
    done = index if where == "mid_frame" else index + 1  # frames complete in every series
    before = {name: (out / name).stat().st_mtime_ns for _, name in listed[:done]}
    _checkpoint_runs.run(out, kind, resume=True)
    _assert_same_tree(out, uninterrupted[kind])
    # the frames complete before the kill were left as they were (simulated again, not written)
    assert {name: (out / name).stat().st_mtime_ns for name in before} == before


def test_ctrl_c_keeps_a_checkpoint_of_the_last_frame(uninterrupted, tmp_path):
    class Interrupted(type(ballistic())):
        def _step(self, dt):
            if self.state.time + dt > 0.32:
                raise KeyboardInterrupt
            super()._step(dt)

    base = ballistic()
    sim = Interrupted(base.state.positions, base.state.velocities, max_dt=1 / 100)
    flow, _ = _checkpoint_runs.build("ballistic", sim)
    with pytest.raises(KeyboardInterrupt):
        flow.run(tmp_path, progress=False, checkpoint_every=4)
    assert read_checkpoint(tmp_path / "particles.checkpoint.npz").frame == 6  # t = 0.3
    flow, _ = _checkpoint_runs.build("ballistic")
    steps = flow.source.simulation.steps_taken
    flow.run(tmp_path, resume=True, progress=False, checkpoint_every=4)
    assert flow.source.simulation.steps_taken - steps == 20  # 0.3 -> 0.5 only
    _assert_same_tree(tmp_path, uninterrupted["ballistic"])


def test_a_foreign_or_damaged_checkpoint_is_never_resumed_from(uninterrupted, tmp_path):
    other = tmp_path / "other"
    flow = Flow(SimulationSource(ballistic(seed=11), fps=20, frames=5))
    flow.add("elevation", vtkElevationFilter())
    flow.run(other, progress=False, checkpoint_every=4)
    out = tmp_path / "run"
    for damage in ("foreign", "damaged"):
        flow, _ = _checkpoint_runs.build("ballistic")
        flow.source.set_frames(20, frames=5)
        flow.run(out, progress=False, checkpoint_every=4)  # a fresh run of 5 frames
        target = out / "particles.checkpoint.npz"
        if damage == "foreign":  # another run's, at the same frame and time
            target.write_bytes((other / "particles.checkpoint.npz").read_bytes())
            _checkpoint_runs.run(out, "ballistic", resume=True)
        else:
            target.write_bytes(target.read_bytes()[:200])
            with pytest.warns(RuntimeWarning, match="not a readable checkpoint"):
                _checkpoint_runs.run(out, "ballistic", resume=True)
        _assert_same_tree(out, uninterrupted["ballistic"])


# -- runs from when every frame carried the state ----------------------------------------------
class _StateInFrames(SimulationSource):
    """Writes frames as blobflow did before the checkpoint left them: each one with the whole
    state as ``state:*`` field data, and no checkpoint file."""

    def current_dataset(self):
        data = SimulationSource.current_dataset(self)
        state_to_field_data(data, self.simulation.state)
        return data


def test_a_run_with_the_state_in_every_frame_still_resumes(uninterrupted, tmp_path):
    flow, _ = _checkpoint_runs.build("drop")
    old = Flow(_StateInFrames(flow.source.simulation, fps=10.0, frames=4, checkpoint=False))
    old.run(tmp_path, progress=False)
    assert has_state(read_frame(tmp_path / "particles" / "particles_000003.vtp"))
    assert not (tmp_path / "particles.checkpoint.npz").exists()
    counted, _ = _checkpoint_runs.build("drop")  # steps of an uninterrupted run at each frame
    steps_at = []
    counted.run(tmp_path / "counted", progress=False,
                on_frame=lambda i, t: steps_at.append(counted.source.simulation.steps_taken))
    flow, _ = _checkpoint_runs.build("drop")
    steps = flow.source.simulation.steps_taken
    flow.run(tmp_path, resume=True, progress=False, checkpoint_every=3)
    assert flow.source.simulation.steps_taken - steps == steps_at[6] - steps_at[3]  # from 0.3
    full = uninterrupted["drop"]
    for k in range(4, 7):  # the frames written now: as an uninterrupted run writes them
        name = f"particles/particles_{k:06d}.vtp"
        assert (tmp_path / name).read_bytes() == (full / name).read_bytes(), name
    assert ((tmp_path / "particles.checkpoint.npz").read_bytes()
            == (full / "particles.checkpoint.npz").read_bytes())


def test_cli_info_says_a_run_is_resumable(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", "bouncing", "--frames", "3", "--out", str(out), "--no-render", "-q",
                 "--set", "count=2"]) == 0
    capsys.readouterr()
    assert main(["info", str(out / "particles.pvd")]) == 0
    assert "checkpointed (resumable)" in capsys.readouterr().out
    (out / "particles.checkpoint.npz").unlink()
    assert main(["info", str(out / "particles.pvd")]) == 0
    assert "resumable" not in capsys.readouterr().out
