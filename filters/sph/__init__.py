"""SPH liquids: the WCSPH / DFSPH solver, its boundary particles and ready-made set-ups.

:class:`SPHLiquid` (:mod:`filters.sph.liquid`) with the divergence-free pressure solves of
:mod:`filters.sph.dfsph`; :mod:`filters.sph.scenarios` builds the dam break and the drop.
"""

from .liquid import SPHLiquid, SPHModel, default_support_factor
from .scenarios import dam_break_liquid, drop_liquid

__all__ = ["SPHLiquid", "SPHModel", "default_support_factor", "dam_break_liquid", "drop_liquid"]
