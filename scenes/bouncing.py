"""``bouncing``: a block of particles thrown sideways, falling and bouncing on the floor."""

from __future__ import annotations

import numpy as np

from filters import BallisticParticles
from filters.geometry import Plane
from filters.validation import check_int, check_range
from pipeline import Flow, SimulationSource
from pipeline.scene import Scene


def build(*, count: int = 8, spacing: float = 0.1, height: float = 1.0, speed: float = 1.0,
          spread: float = 0.5, restitution: float = 0.7, seed: int = 0) -> Flow:
    """A ``count``**3 lattice of particles thrown along +x from ``height`` above the floor.

    Parameters
    ----------
    count : int
        Particles per side of the cubic lattice (1 to 200).
    spacing : float
        Lattice spacing (m), > 0.
    height : float
        Height of the lattice's lowest layer above the floor (m), >= 0.
    speed : float
        Mean initial speed along +x (m/s).
    spread : float
        Standard deviation of the random initial velocity (m/s), >= 0.
    restitution : float
        Coefficient of restitution of the floor, in [0, 1].
    seed : int
        Seed of the random initial velocities.
    """
    count = check_int("count", count, 1, 200)
    spacing = check_range("spacing", spacing, 0.0, low_inclusive=False)
    height = check_range("height", height, 0.0)
    spread = check_range("spread", spread, 0.0)
    axis = np.arange(count) * spacing
    x, y, z = np.meshgrid(axis, axis, axis + height, indexing="ij")
    positions = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    rng = np.random.default_rng(seed)
    velocities = rng.normal(0.0, spread, positions.shape)
    velocities[:, 0] += speed
    velocities[:, 2] = np.abs(velocities[:, 2])
    simulation = BallisticParticles(positions, velocities, restitution=restitution)
    flow = Flow(SimulationSource(simulation, fps=SCENE_FPS, duration=SCENE_DURATION))
    floor = simulation.model.floor
    flow.add_collider("floor", Plane((0.0, 0.0, floor), (0.0, 0.0, 1.0)), role="floor", size=4.0)
    return flow


SCENE_FPS = 30.0
SCENE_DURATION = 2.0
SCENE = Scene("bouncing", build, "ballistic particles bouncing on a floor (analytic motion)",
              fps=SCENE_FPS, duration=SCENE_DURATION)
