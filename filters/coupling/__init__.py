"""Bodies in a liquid: rigid and elastic bodies two-way coupled with the DFSPH liquid.

:class:`Coupled` (:mod:`~filters.coupling.coupled`) is one simulation of a liquid and the body
simulations in it; :func:`coupled_boundary` builds the liquid's boundary (walls, then the
bodies' solid layers, :mod:`~filters.coupling.samples`); :mod:`~filters.coupling.parts` says
how rigid bodies and finite-element solids are sampled, moved and pushed.
"""

from .coupled import Coupled, CoupledModel, coupled_boundary
from .samples import locate_in_tets, mesh_distances, solid_layers

__all__ = ["Coupled", "CoupledModel", "coupled_boundary", "solid_layers", "mesh_distances",
           "locate_in_tets"]
