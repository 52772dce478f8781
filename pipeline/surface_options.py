"""Options of the surface chain (:func:`pipeline.surface.surface_stages`): their defaults, their
types for ``blobflow surface --option NAME=VALUE``, and a liquid's options from its spacing and
tank, for the scenes and from a run record (``scene.json``) for ``blobflow surface``.
"""

from __future__ import annotations

import math

from filters.geometry import Box
from filters.surface.grid import DEFAULT_MAX_BYTES
from filters.validation import check_range

from .assignments import Parameter

__all__ = ["SURFACE_DEFAULTS", "SURFACE_PARAMETERS", "liquid_surface_options",
           "surface_options_from_record"]

#: Defaults of :func:`pipeline.surface.surface_stages`: the surface of the liquid scenes and of ``blobflow
#: surface`` (particle radius 0.01 m unless the run record gives the spacing).
SURFACE_DEFAULTS = {
    "radius": 0.01,
    "kernel": "sph",
    "anisotropic": True,
    "feature_smoothing": 25,
    "smooth_iterations": 30,
    "pass_band": 0.01,
    "normals": True,
    "attributes": ("velocity",),
    "volume_correction": True,
}


#: Types of the options of :func:`pipeline.surface.surface_stages` (``blobflow surface --option NAME=VALUE``).
SURFACE_PARAMETERS = {p.name: p for p in (
    Parameter("radius", SURFACE_DEFAULTS["radius"], "particle radius (m)"),
    Parameter("cell_size", None, "voxel edge (m)", kind="float"),
    Parameter("kernel", SURFACE_DEFAULTS["kernel"], "splatting kernel"),
    Parameter("anisotropic", SURFACE_DEFAULTS["anisotropic"], "anisotropic kernels"),
    Parameter("feature_smoothing", SURFACE_DEFAULTS["feature_smoothing"], "feature sweeps"),
    Parameter("smooth_iterations", SURFACE_DEFAULTS["smooth_iterations"], "windowed sinc"),
    Parameter("pass_band", SURFACE_DEFAULTS["pass_band"], "windowed-sinc pass band"),
    Parameter("normals", SURFACE_DEFAULTS["normals"], "point normals"),
    Parameter("attributes", SURFACE_DEFAULTS["attributes"], "particle arrays carried",
              kind="names"),
    Parameter("volume_correction", SURFACE_DEFAULTS["volume_correction"],
              "pieces enclose their particles' volume"),
    Parameter("support_r", None, "support radius / particle radius", kind="float"),
    Parameter("blobbiness", 4.0, "blobby kernel's a"),
    Parameter("radius_array", None, "point array of radii (m)", kind="str"),
    Parameter("iso", None, "iso value", kind="float"),
    Parameter("sparse", True, "sparse brick grid"),
    Parameter("block_size", 8, "voxels per block edge"),
    Parameter("brick_blocks", 4, "blocks per brick edge"),
    Parameter("max_bytes", DEFAULT_MAX_BYTES, "grid memory budget (bytes)"),
    Parameter("operation", "intersection", "how the tank combines with the field"),
    Parameter("mirror_walls", False, "ghosts across the tank's walls, exact cut"),
    Parameter("contour", "flying_edges", "flying_edges or tetrahedra"),
)}



def liquid_surface_options(spacing: float, tank_lo=None, tank_hi=None, **options) -> dict:
    """Options of :func:`pipeline.surface.surface_stages` for a liquid of particle spacing ``spacing`` (m).

    The particle radius is half the spacing (kernel support of two spacings, as splashsurf
    uses); with a tank, its inner box ``[tank_lo, tank_hi]`` (m) bounds the liquid: the
    particles near its walls are mirrored across them and the surface is cut exactly at them
    (``mirror_walls``: flat where the liquid touches a wall, meeting the walls' edges and
    corners without a gap), and the volume correction keeps the vertices on the walls; the rest
    are :data:`SURFACE_DEFAULTS` unless given in ``options``.
    """
    spacing = check_range("spacing", spacing, 0.0, math.inf, low_inclusive=False)
    result = {"radius": 0.5 * spacing}
    if tank_lo is not None or tank_hi is not None:
        result["implicit"] = Box(tank_lo, tank_hi)
        result["operation"] = "intersection"
        result["mirror_walls"] = True
    result.update(options)
    return result


def surface_options_from_record(record: dict) -> dict:
    """The surface options of the run that wrote a record (``scene.json``), for a liquid.

    From the scene's parameters: the particle radius from ``spacing``, the tank
    (``tank_length``, ``tank_width`` or ``depth``, ``tank_height``, from the origin) as the
    clipping box, and ``anisotropic``, ``smooth_iterations`` and ``feature_smoothing`` when the
    scene has them (:func:`liquid_surface_options`: the surface the liquid scenes write). An
    empty dict when the record has no ``spacing``.
    """
    params = record.get("parameters") if isinstance(record, dict) else None
    if not isinstance(params, dict) or "spacing" not in params:
        return {}
    width = params.get("tank_width", params.get("depth"))
    tank = (params.get("tank_length"), width, params.get("tank_height"))
    corners = ((0.0, 0.0, 0.0), tuple(float(v) for v in tank)) if None not in tank else (None,
                                                                                         None)
    options = {k: params[k] for k in ("anisotropic", "smooth_iterations", "feature_smoothing")
               if k in params}
    return liquid_surface_options(float(params["spacing"]), *corners, **options)
