"""blobflow pipeline: VTK algorithms and plumbing around the simulations of :mod:`filters`.

No physics here.  :class:`SimulationSource` publishes a simulation as a temporal VTK source,
:class:`Flow` chains it with any VTK algorithms into named outputs and writes them as time series
(:mod:`pipeline.series`; exports: XDMF, :mod:`pipeline.xdmf`; USD, :mod:`pipeline.usd`), and
:mod:`pipeline.scene` finds ready-made scenes through entry points.
"""

from .compose import Flow, Stage
from .series import SeriesWriter, export_xdmf, read_series
from .sources import SimulationSource
from .usd import export_usd

__all__ = ["Flow", "Stage", "SimulationSource", "SeriesWriter", "read_series", "export_xdmf",
           "export_usd"]
