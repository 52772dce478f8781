"""blobflow filters: the numerics, on NumPy arrays, with Numba kernels. No VTK here.

Simulations implement the protocol in :mod:`filters.simulation`: an immutable model, a state
that can be copied and restored, ``step(dt)`` / ``advance_to(t)``, and frames of plain arrays.
"""

from .simulation import (
    Frame,
    OutputSpec,
    Simulation,
    SimulationError,
    SimulationUnstableError,
    State,
    frame_times,
)
from .ballistic import BallisticModel, BallisticParticles
from .rigid import RigidBodies, RigidBody

__all__ = [
    "Frame",
    "OutputSpec",
    "Simulation",
    "SimulationError",
    "SimulationUnstableError",
    "State",
    "frame_times",
    "BallisticModel",
    "BallisticParticles",
    "RigidBody",
    "RigidBodies",
]
