"""blobflow pipeline: VTK algorithms and plumbing around the simulations of :mod:`filters`.

No physics here.  :class:`SimulationSource` publishes a simulation as a temporal VTK source,
:class:`Flow` chains it with any VTK algorithms into named outputs and writes them as time series,
and :mod:`pipeline.scene` finds ready-made scenes through entry points. The subpackages, by
purpose:

- :mod:`pipeline.io`: time series (PVD/``.series``), XDMF and USD exports, checkpoints,
  colliders, conversions between simulation frames and VTK data, the checks of files read;
- :mod:`pipeline.surface`: the surface of particles (splat, contour, smoothing, the liquid's
  clip and volume correction), over a whole series and across frames;
- :mod:`pipeline.render`: offscreen pictures, turntables and movies of series;
- :mod:`pipeline.cli`: the ``blobflow`` command;
- :mod:`pipeline.paraview`: the ParaView plugin and its worker process.

At the top: :mod:`~pipeline.algorithm` (the base of the VTK algorithms), :mod:`~pipeline.sources`,
:mod:`~pipeline.compose`, :mod:`~pipeline.scene`, :mod:`~pipeline.tasks` (frame-parallel work,
serially or on Dask), :mod:`~pipeline.accessor` (``dataset.blobflow`` in PyVista).

``import pipeline`` is light (no VTK, PyVista or Numba): the names below load their modules
when first used.
"""

from typing import TYPE_CHECKING

from ._lazy import install_moved_modules, lazy_exports

if TYPE_CHECKING:
    from .compose import Flow, Stage
    from .io.series import SeriesWriter, read_series
    from .io.usd import export_usd
    from .io.xdmf import export_xdmf
    from .render.pictures import render_still
    from .scene import available_scenes, load_scene
    from .sources import SimulationSource
    from .surface.stages import reconstruct, surface_stages

_EXPORTS = {
    "Flow": ".compose", "Stage": ".compose", "SimulationSource": ".sources",
    "SeriesWriter": ".io.series", "read_series": ".io.series", "export_xdmf": ".io.xdmf",
    "export_usd": ".io.usd", "reconstruct": ".surface.stages",
    "surface_stages": ".surface.stages", "load_scene": ".scene",
    "available_scenes": ".scene", "render_still": ".render.pictures",
}

__all__ = ["Flow", "Stage", "SimulationSource", "SeriesWriter", "read_series", "export_xdmf",
           "export_usd", "reconstruct", "surface_stages", "load_scene", "available_scenes",
           "render_still"]

__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)
install_moved_modules()
