"""The simulation protocol: states, frame times, stepping and instability errors."""

import numpy as np
import pytest

from filters import Simulation, SimulationUnstableError, State, frame_times
from filters.ballistic import BallisticParticles


def test_frame_times_are_rounded_and_complete():
    times = frame_times(10, duration=1.0)
    assert len(times) == 11
    assert times[3] == 0.3  # not 0.30000000000000004
    assert times[-1] == 1.0
    np.testing.assert_allclose(np.diff(times), 0.1, atol=1e-12)
    assert len(frame_times(24, frames=5)) == 5
    assert frame_times(30, duration=0.0).tolist() == [0.0]


@pytest.mark.parametrize("kwargs, match", [
    (dict(fps=0, duration=1.0), "fps"),
    (dict(fps=30, duration=-1.0), "duration"),
    (dict(fps=30, frames=0), "frames"),
    (dict(fps=30), "exactly one"),
    (dict(fps=30, duration=1.0, frames=3), "exactly one"),
])
def test_frame_times_reject_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        frame_times(**kwargs)


def test_state_round_trips_through_arrays_bit_for_bit(rng):
    state = State(rng.random((7, 3)), rng.random((7, 3)), time=0.1 + 0.2, step=3,
                  extra={"density": rng.random(7),
                         "rng": np.array([1, 2**63 + 5], dtype=np.uint64)})
    back = State.from_arrays(state.to_arrays())
    assert back.time == state.time and back.step == 3
    assert np.array_equal(back.positions, state.positions)
    assert np.array_equal(back.velocities, state.velocities)
    assert np.array_equal(back.extra["rng"], state.extra["rng"])
    assert back.extra["rng"].dtype == np.uint64


def test_state_copy_is_independent(rng):
    state = State(rng.random((4, 3)), rng.random((4, 3)), time=0.25, step=7,
                  extra={"id": np.arange(4), "density": rng.random(4),
                         "rng": np.array([3, 5], dtype=np.uint64)})
    copy = state.copy()
    # equal, field for field, to the bit
    assert copy.time == state.time and copy.step == state.step
    for name in ("positions", "velocities"):
        np.testing.assert_array_equal(getattr(copy, name), getattr(state, name))
    assert set(copy.extra) == set(state.extra)
    for name, values in state.extra.items():
        assert copy.extra[name].dtype == values.dtype
        np.testing.assert_array_equal(copy.extra[name], values)
    # and shares no memory: changing every array of the copy leaves the original as it was
    before = state.to_arrays()
    copy.positions[:] = 99.0
    copy.velocities[:] = -99.0
    for values in copy.extra.values():
        values[...] = 0
    copy.extra["new"] = np.ones(2)
    copy.time, copy.step = 9.0, 99
    after = state.to_arrays()
    assert set(after) == set(before)
    for name in before:
        np.testing.assert_array_equal(after[name], before[name])
    # nor the other way round
    state.positions[0, 0] = -1.0
    assert copy.positions[0, 0] == 99.0


@pytest.mark.parametrize("positions, match", [
    (np.zeros((3, 2)), r"shape \(N, 3\)"),
    (np.array([[0.0, np.nan, 0.0]]), "NaN"),
])
def test_state_rejects_bad_positions(positions, match):
    with pytest.raises(ValueError, match=match):
        State(positions)


def test_advance_to_lands_exactly_on_frame_times():
    sim = BallisticParticles(np.array([[0.0, 0.0, 100.0]]), max_dt=0.013)
    for t in frame_times(30, duration=1.0)[1:]:
        sim.advance_to(t)
        assert sim.state.time == t
    assert sim.steps_taken == 30 * 3  # ceil((1/30) / 0.013) steps per frame
    with pytest.raises(ValueError, match="backwards"):
        sim.advance_to(0.5)


@pytest.mark.parametrize("dt", [0.0, -1.0, float("nan"), float("inf")])
def test_step_rejects_bad_dt(dt):
    sim = BallisticParticles(np.zeros((1, 3)))
    with pytest.raises(ValueError, match="dt"):
        sim.step(dt)


class _Exploding(Simulation):
    """Velocities double every step: overflows to inf, then NaN."""

    instability_hint = "the test's amplification factor is > 1"

    def __init__(self):
        self.model = None
        self.state = State(np.ones((2, 3)), np.full((2, 3), 1e300))

    def _step(self, dt):
        with np.errstate(over="ignore", invalid="ignore"):
            self.state.velocities *= 1e10
            self.state.positions += self.state.velocities * dt


def test_divergence_raises_with_time_and_quantity():
    sim = _Exploding()
    with pytest.raises(SimulationUnstableError) as info:
        sim.advance_to(1.0)
    assert info.value.time > 0
    assert "non-finite" in info.value.quantity
    assert "amplification" in str(info.value)
