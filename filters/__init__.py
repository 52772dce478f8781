"""blobflow filters: the numerics, on NumPy arrays, with Numba kernels. No VTK here.

Simulations implement the protocol in :mod:`filters.simulation`: an immutable model, a state
that can be copied and restored, ``step(dt)`` / ``advance_to(t)``, and frames of plain arrays.
"""

import importlib
from typing import TYPE_CHECKING

from .numba_cache import install_when_numba_loads

# Numba's cache keyed on each kernel's dependencies too, damaged entries read as misses
# (filters.numba_cache); installed when Numba is first imported, so not loaded here.
install_when_numba_loads()

if TYPE_CHECKING:
    from .ballistic import BallisticModel, BallisticParticles
    from .rigid import RigidBodies, RigidBody
    from .simulation import (
        Frame,
        OutputSpec,
        Simulation,
        SimulationError,
        SimulationUnstableError,
        State,
        frame_times,
    )

#: Where the names below live: ``import filters`` loads neither NumPy nor Numba; a name loads
#: its module when first used (PEP 562).
_EXPORTS = {
    **dict.fromkeys(["Frame", "OutputSpec", "Simulation", "SimulationError",
                     "SimulationUnstableError", "State", "frame_times"], ".simulation"),
    "BallisticModel": ".ballistic", "BallisticParticles": ".ballistic",
    "RigidBody": ".rigid", "RigidBodies": ".rigid",
}

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


def __getattr__(name):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))
