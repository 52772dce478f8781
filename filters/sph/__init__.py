"""SPH liquids: the WCSPH / DFSPH solver, its boundary particles and ready-made set-ups.

:class:`SPHLiquid` (:mod:`filters.sph.liquid`) steps with :mod:`filters.sph.wcsph` or with the
divergence-free pressure solves of :mod:`filters.sph.dfsph`; walls and bodies are boundary
particles (:mod:`filters.sph.boundary`); :mod:`filters.sph.scenarios` builds the dam break and
the drop, and :mod:`filters.sph.settle` lets resting water settle before a scene starts.
"""

from .boundary import BoundaryParticles
from .liquid import ContainerCorrectionWarning, SPHLiquid, SPHModel, default_support_factor
from .scenarios import dam_break_liquid, drop_liquid

__all__ = ["BoundaryParticles", "ContainerCorrectionWarning", "SPHLiquid", "SPHModel",
           "dam_break_liquid", "default_support_factor", "drop_liquid"]
