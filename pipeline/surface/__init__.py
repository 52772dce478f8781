"""The surface of particles, as VTK algorithms.

A particle set becomes a watertight, smoothed triangle surface through a chain of stages
(:func:`surface_stages`, or once on points with :func:`reconstruct`): the splat of the particles
into a scalar grid (:class:`MetaballSplat`, anisotropic kernels included), its contour
(:class:`MarchingCubes`; :mod:`~pipeline.surface.contour`), smoothing of the particles and of the
mesh (:mod:`~pipeline.surface.particle_stages`, :mod:`~pipeline.surface.mesh_stages`), and for a
liquid the clip at the container's walls and the volume correction
(:mod:`~pipeline.surface.liquid`). The options and their defaults are one table
(:mod:`~pipeline.surface.options`); :func:`surface_series` runs the chain on every frame of a
series (:mod:`~pipeline.surface.frames`), smoothed across frames on request
(:mod:`~pipeline.surface.across_frames`).
"""

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from .frames import surface_series
    from .options import SURFACE_DEFAULTS, SURFACE_PARAMETERS, liquid_surface_options
    from .stages import (
        ClipBox,
        FeatureSmoothing,
        InterpolateAttributes,
        MarchingCubes,
        MetaballSplat,
        Normals,
        Smooth,
        SurfaceKind,
        VolumeCorrection,
        reconstruct,
        surface_option_names,
        surface_stages,
    )

_EXPORTS = {
    "MetaballSplat": ".implicit", "MarchingCubes": ".implicit",
    **dict.fromkeys(["FeatureSmoothing", "InterpolateAttributes",
                     "Smooth", "Normals", "ClipBox", "VolumeCorrection", "SurfaceKind",
                     "surface_stages", "surface_option_names", "reconstruct"], ".stages"),
    **dict.fromkeys(["SURFACE_DEFAULTS", "SURFACE_PARAMETERS", "liquid_surface_options"],
                    ".options"),
    "surface_series": ".frames",
}

__all__ = ["MetaballSplat", "MarchingCubes", "FeatureSmoothing", "InterpolateAttributes", "Smooth",
           "Normals", "ClipBox", "VolumeCorrection", "SurfaceKind", "surface_stages",
           "surface_option_names", "reconstruct", "SURFACE_DEFAULTS", "SURFACE_PARAMETERS",
           "liquid_surface_options", "surface_series"]

__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)
