"""Ballistic particles against their analytic trajectory."""

import numpy as np
import pytest

from filters import BallisticParticles


def test_matches_parabola_before_first_bounce(rng):
    x0 = rng.uniform(-1, 1, (50, 3))
    x0[:, 2] += 20.0
    v0 = rng.normal(0, 2, (50, 3))
    g = np.array([0.3, -0.2, -9.81])
    sim = BallisticParticles(x0, v0, gravity=g, max_dt=1 / 97)
    for t in np.linspace(0.05, 1.5, 30):  # lowest start ~19 m: no particle reaches the floor
        sim.advance_to(t)
        exact = x0 + v0 * t + 0.5 * g * t * t
        np.testing.assert_allclose(sim.state.positions, exact, rtol=0, atol=1e-9)
        np.testing.assert_allclose(sim.state.velocities, v0 + g * t, rtol=0, atol=1e-9)


def test_bounce_time_and_rebound_speed():
    h, e, g = 2.0, 0.6, 9.81
    sim = BallisticParticles(np.array([[0.0, 0.0, h]]), restitution=e, max_dt=0.05)
    t_hit = np.sqrt(2 * h / g)
    v_hit = g * t_hit
    t = t_hit + 0.1  # 0.1 s after the bounce: z = e v t - g t^2 / 2
    sim.advance_to(t)
    np.testing.assert_allclose(sim.state.positions[0, 2], e * v_hit * 0.1 - 0.5 * g * 0.01,
                               atol=1e-9)
    np.testing.assert_allclose(sim.state.velocities[0, 2], e * v_hit - g * 0.1, atol=1e-9)


def test_comes_to_rest_on_floor_and_never_below():
    sim = BallisticParticles(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.3]]),
                             np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 2.0]]), floor=0.1,
                             restitution=0.5)
    lowest = np.inf
    for t in np.arange(0.05, 6.0, 0.05):
        sim.advance_to(t)
        lowest = min(lowest, sim.state.positions[:, 2].min())
    assert lowest >= 0.1 - 1e-12
    np.testing.assert_allclose(sim.state.positions[:, 2], 0.1)
    np.testing.assert_allclose(sim.state.velocities[:, 2], 0.0)
    # The floor is frictionless: horizontal motion goes on at constant speed.
    np.testing.assert_allclose(sim.state.positions[0, 0], 1.0 * sim.state.time, atol=1e-9)


@pytest.mark.parametrize("kwargs, match", [
    (dict(restitution=1.5), "restitution"),
    (dict(restitution=-0.1), "restitution"),
    (dict(gravity=(0, 0)), "gravity"),
    (dict(max_dt=0.0), "max_dt"),
    (dict(floor=2.0), "above the floor"),
])
def test_rejects_bad_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        BallisticParticles(np.array([[0.0, 0.0, 1.0]]), **kwargs)
