"""Options of the surface chain (:func:`pipeline.surface.surface_stages`): their defaults, their
types for ``blobflow surface --option NAME=VALUE``, and a liquid's options from its spacing and
tank, for the scenes and from a run record (``scene.json``) for ``blobflow surface``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from filters.geometry import Box
from filters.surface.grid import DEFAULT_MAX_BYTES
from filters.validation import check_range

from ..assignments import Parameter

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["SURFACE_DEFAULTS", "SURFACE_PARAMETERS", "OPTION_DEFAULTS", "liquid_surface_options",
           "surface_options_from_record"]

#: Every surface option that ``blobflow surface --option NAME=VALUE`` can set: its default, a
#: short description and its type. The one table of defaults: the signatures of
#: :func:`pipeline.surface.surface_stages` and :func:`pipeline.surface.reconstruct` take theirs
#: from :data:`OPTION_DEFAULTS`, built from it.
SURFACE_PARAMETERS = {p.name: p for p in (
    Parameter("radius", 0.01, "particle radius (m)"),
    Parameter("cell_size", None, "voxel edge (m)", kind="float"),
    Parameter("kernel", "sph", "splatting kernel"),
    Parameter("anisotropic", True, "anisotropic kernels"),
    Parameter("feature_smoothing", 25, "feature sweeps"),
    Parameter("smooth_iterations", 30, "windowed sinc"),
    Parameter("pass_band", 0.01, "windowed-sinc pass band"),
    Parameter("normals", True, "point normals"),
    Parameter("attributes", ("velocity",), "particle arrays carried", kind="names"),
    Parameter("liquid", False, "the particles are a liquid's (spacing 2 radius): volume "
              "correction, drawn as water"),
    Parameter("volume_correction", None, "pieces enclose their particles' volume (default: "
              "when liquid)", kind="bool"),
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

#: The default of every option of :data:`SURFACE_PARAMETERS`, by name.
OPTION_DEFAULTS: dict[str, Any] = {name: p.default for name, p in SURFACE_PARAMETERS.items()}

#: The main options and their defaults: the options of the ParaView plugin's panel and of
#: ``blobflow surface --help``. With ``liquid=True`` (:func:`liquid_surface_options`: the liquid
#: scenes, and ``blobflow surface`` on their particles) they are the liquid scenes' surface.
SURFACE_DEFAULTS: dict[str, Any] = {name: OPTION_DEFAULTS[name] for name in (
    "radius", "kernel", "anisotropic", "feature_smoothing", "smooth_iterations", "pass_band",
    "normals", "attributes", "liquid", "volume_correction")}


def liquid_surface_options(spacing: float, tank_lo: ArrayLike | None = None,
                           tank_hi: ArrayLike | None = None, **options: Any) -> dict[str, Any]:
    """Options of :func:`pipeline.surface.surface_stages` for a liquid of particle spacing
    ``spacing`` (m).

    The particle radius is half the spacing (kernel support of two spacings, as splashsurf
    uses); with a tank, its inner box ``[tank_lo, tank_hi]`` (m) bounds the liquid: the
    particles near its walls are mirrored across them and the surface is cut exactly at them
    (``mirror_walls``: flat where the liquid touches a wall, meeting the walls' edges and
    corners without a gap), and the volume correction keeps the vertices on the walls; the
    particles are a liquid's (``liquid=True``: the volume correction, a surface drawn as
    water); the rest are :data:`OPTION_DEFAULTS` unless given in ``options``.
    """
    spacing = check_range("spacing", spacing, 0.0, math.inf, low_inclusive=False)
    result = {"radius": 0.5 * spacing, "liquid": True}
    if tank_lo is not None or tank_hi is not None:
        result["implicit"] = Box(tank_lo, tank_hi)
        result["operation"] = "intersection"
        result["mirror_walls"] = True
    result.update(options)
    return result


def surface_options_from_record(record: dict) -> dict:
    """The surface options of the run that wrote a record (``scene.json``).

    From the scene's parameters: the particle radius from ``spacing``; with a tank
    (``tank_length``, ``tank_width`` or ``depth``, ``tank_height``, from the origin: the liquid
    scenes) the particles are a liquid's in it (:func:`liquid_surface_options`: the tank as the
    clipping box, ``liquid=True``), and ``anisotropic``, ``smooth_iterations`` and
    ``feature_smoothing`` when the scene has them (the surface the liquid scenes write). An
    empty dict when the record has no ``spacing``; only the radius without a tank (particles
    that are no liquid's, e.g. a lattice of balls).
    """
    params = record.get("parameters") if isinstance(record, dict) else None
    if not isinstance(params, dict) or "spacing" not in params:
        return {}
    width = params.get("tank_width", params.get("depth"))
    tank = (params.get("tank_length"), width, params.get("tank_height"))
    if None in tank:
        spacing = check_range("spacing", params["spacing"], 0.0, math.inf, low_inclusive=False)
        return {"radius": 0.5 * float(spacing)}
    corners = ((0.0, 0.0, 0.0), tuple(float(v) for v in tank))
    options = {k: params[k] for k in ("anisotropic", "smooth_iterations", "feature_smoothing")
               if k in params}
    return liquid_surface_options(float(params["spacing"]), *corners, **options)
