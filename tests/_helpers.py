"""Small builders shared by the pipeline tests."""

import numpy as np

from filters import BallisticParticles, SimulationError


def ballistic(n=20, seed=3, **kwargs):
    """A deterministic ballistic simulation of ``n`` particles that bounce within a second."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0, 1, (n, 3))
    x[:, 2] += 0.5
    v = rng.normal(0, 1, (n, 3))
    return BallisticParticles(x, v, max_dt=1 / 100, **kwargs)


class FailingBallistic(BallisticParticles):
    """Ballistic particles that raise once the simulated time passes ``fail_after``."""

    def __init__(self, *args, fail_after=0.25, **kwargs):
        super().__init__(*args, **kwargs)
        self.fail_after = fail_after

    def _step(self, dt):
        if self.state.time + dt > self.fail_after:
            raise SimulationError(f"injected failure at t = {self.state.time}")
        super()._step(dt)


def failing_ballistic(n=20, seed=3, fail_after=0.25):
    base = ballistic(n, seed)
    return FailingBallistic(base.state.positions, base.state.velocities, max_dt=1 / 100,
                            fail_after=fail_after)
