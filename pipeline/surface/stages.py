"""Surface stages: particles -> implicit field -> triangle mesh -> smoothed mesh with normals.

Each stage is a VTK algorithm (:class:`pipeline.algorithm.Algorithm`, a
:class:`VTKPythonAlgorithmBase` whose exceptions reach the caller), so any VTK filter can sit
between two of them, and each passes time requests upstream (a temporal particle source drives
them). Stages that need the particles read them on their second input port
(:class:`pipeline.algorithm.ParticleStage`), connected to the particles the chain starts from:

``MetaballSplat`` (:mod:`pipeline.surface.implicit`)
    vtkPointSet particles -> vtkImageData (``sparse=False``) or a vtkPartitionedDataSet of
    image *bricks* (``sparse=True``, default) holding the implicit value ``implicit`` (negative
    inside) computed by :mod:`filters.surface.splat`, optionally combined with a shape of
    :mod:`filters.geometry` (:mod:`filters.surface.csg`).
``MarchingCubes``
    vtkFlyingEdges3D at ``value`` (0 for our fields), or marching tetrahedra
    (``method="tetrahedra"``): one watertight vtkPolyData, bricks contoured in voxel-index
    coordinates and stitched (:mod:`pipeline.surface.contour`).
``ClipBox`` (with a tank whose walls the particles are mirrored across)
    The surface cut exactly at the tank's walls and closed with flat faces
    (:mod:`pipeline.surface.liquid`); the smoothing stages keep those faces on the walls.
``FeatureSmoothing`` (mesh, particles; :mod:`pipeline.surface.particle_stages`)
    Feature-weighted Laplacian smoothing (Löschner et al. 2023,
    :mod:`filters.surface.smoothing`): flat liquid smoothed fully, droplets and sheets kept.
``InterpolateAttributes`` (mesh, particles; :mod:`pipeline.surface.particle_stages`)
    Particle arrays (``velocity``, ...) carried to the vertices with the splatting kernel
    (Shepard weights, :mod:`filters.surface.attributes`).
``Smooth`` (:mod:`pipeline.surface.mesh_stages`)
    vtkWindowedSincPolyDataFilter (Taubin, Zhang & Golub 1996), whose low-pass filter does not
    shrink the surface the way Laplacian smoothing does (:mod:`pipeline.surface.mesh_stages`).
``VolumeCorrection`` (mesh, particles; a liquid's particles)
    Every closed piece offset along its normals until it encloses its particles' volume
    (:mod:`pipeline.surface.liquid`, :mod:`filters.surface.correction`).
``Normals``
    vtkPolyDataNormals without splitting (the mesh stays watertight).
``SurfaceKind``
    ``blobflow_kind`` in the field data: ``liquid_surface`` (drawn as water) or
    ``particle_surface`` (:mod:`pipeline.surface.liquid`).

:func:`surface_stages` builds the chain, and :func:`reconstruct` runs it on one point cloud, from
one set of options whose defaults are :data:`pipeline.surface.options.OPTION_DEFAULTS` (the
options of ``blobflow surface --option``); with ``liquid=True`` and a liquid's radius and tank
(:func:`pipeline.surface.options.liquid_surface_options`) they give the liquid scenes' surface.
"""

from __future__ import annotations

import inspect
import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from vtkmodules.vtkCommonDataModel import (
    vtkDataObject,
    vtkDataSet,
    vtkMultiBlockDataSet,
    vtkPointSet,
)

from filters.geometry import Shape
from filters.validation import check_bool, check_int

from ..algorithm import Algorithm, run_chain
from ..feedback import BlobflowWarning, compile_notice, stage_progress
from .implicit import MarchingCubes, MetaballSplat
from .liquid import LIQUID_SURFACE, PARTICLE_SURFACE, ClipBox, SurfaceKind, VolumeCorrection
from .mesh_stages import Normals, Smooth
from .options import OPTION_DEFAULTS
from .particle_stages import (
    FeatureSmoothing,
    InterpolateAttributes,
)

if TYPE_CHECKING:
    import pyvista as pv
    from numpy.typing import ArrayLike

_D = OPTION_DEFAULTS  # the one table of defaults (pipeline.surface.options.SURFACE_PARAMETERS)

__all__ = [
    "MetaballSplat",
    "MarchingCubes",
    "FeatureSmoothing",
    "InterpolateAttributes",
    "Smooth",
    "Normals",
    "ClipBox",
    "VolumeCorrection",
    "SurfaceKind",
    "surface_stages",
    "surface_option_names",
    "reconstruct",
]


# --------------------------------------------------------------------------------------------
# The chain
# --------------------------------------------------------------------------------------------


def surface_stages(radius: float = _D["radius"], cell_size: float | None = _D["cell_size"], *,
                   kernel: str = _D["kernel"], anisotropic: bool = _D["anisotropic"],
                   feature_smoothing: int = _D["feature_smoothing"],
                   smooth_iterations: int = _D["smooth_iterations"],
                   pass_band: float = _D["pass_band"], normals: bool = _D["normals"],
                   attributes: Sequence[str] = _D["attributes"], liquid: bool = _D["liquid"],
                   volume_correction: bool | None = _D["volume_correction"],
                   support_r: float | None = _D["support_r"],
                   blobbiness: float = _D["blobbiness"],
                   radius_array: str | None = _D["radius_array"], iso: float | None = _D["iso"],
                   sparse: bool = _D["sparse"], block_size: int = _D["block_size"],
                   brick_blocks: int = _D["brick_blocks"], max_bytes: int = _D["max_bytes"],
                   implicit: Shape | None = None, operation: str = _D["operation"],
                   anisotropy: dict | None = None, mirror_walls: bool = _D["mirror_walls"],
                   contour: str = _D["contour"]) -> list[Algorithm]:
    """The chain particles -> surface as a list of algorithms.

    ``flow.add("surface", *surface_stages(radius=0.01, liquid=True), input="particles")``.
    :class:`MetaballSplat`, :class:`MarchingCubes`, with ``mirror_walls`` and a
    :class:`filters.geometry.Box` intersected with the field a
    :class:`pipeline.surface.liquid.ClipBox` (the smoothing then keeps the cut faces on the
    walls), :class:`FeatureSmoothing`, :class:`InterpolateAttributes`, :class:`Smooth`,
    :class:`pipeline.surface.liquid.VolumeCorrection`, :class:`Normals`, each left out where its
    option switches it off, and last :class:`pipeline.surface.liquid.SurfaceKind`, which writes
    ``blobflow_kind`` (``liquid_surface`` with ``liquid=True``, else ``particle_surface``) into
    the surface's field data.
    :func:`pipeline.surface.options.liquid_surface_options` gives a liquid's options (its
    radius, its tank, ``liquid=True``): the liquid scenes' surface.

    Parameters
    ----------
    radius, cell_size, kernel, anisotropic, feature_smoothing, smooth_iterations, pass_band,
    normals, attributes, liquid, volume_correction, support_r, blobbiness, radius_array, iso,
    sparse, block_size, brick_blocks, max_bytes, implicit, operation, anisotropy, mirror_walls,
    contour
        As in :func:`reconstruct`, with the same defaults.

    Returns
    -------
    list of Algorithm
    """
    splat = MetaballSplat(radius, cell_size, kernel=kernel, support_r=support_r, iso=iso,
                          blobbiness=blobbiness, radius_array=radius_array, sparse=sparse,
                          block_size=block_size, brick_blocks=brick_blocks, max_bytes=max_bytes,
                          implicit=implicit, operation=operation, anisotropic=anisotropic,
                          anisotropy=anisotropy, mirror_walls=mirror_walls)
    feature_smoothing = check_int("feature_smoothing", feature_smoothing, 0, 10000)
    smooth_iterations = check_int("smooth_iterations", smooth_iterations, 0, 1000)
    normals = check_bool("normals", normals)
    liquid = check_bool("liquid", liquid)
    volume_correction = (liquid if volume_correction is None
                         else check_bool("volume_correction", volume_correction))
    walls = splat.walls
    stages = [splat, MarchingCubes(method=contour)]
    if walls is not None:
        stages.append(ClipBox(walls, tolerance=0.01 * splat.cell_size))
    if feature_smoothing:
        stages.append(FeatureSmoothing(feature_smoothing, radius=radius,
                                       radius_array=radius_array, walls=walls))
    interpolate = InterpolateAttributes(attributes, radius=radius, cell_size=splat.cell_size,
                                        kernel=kernel, support_r=support_r,
                                        blobbiness=blobbiness, radius_array=radius_array)
    if interpolate.attributes:
        stages.append(interpolate)
    smooth = Smooth(smooth_iterations, pass_band, walls=walls)
    if smooth_iterations:
        stages.append(smooth)
    if volume_correction and (splat.implicit is None or splat.operation != "union"):
        container = splat.implicit
        if container is not None and splat.operation == "difference":
            container = ~container
        stages.append(VolumeCorrection(radius=radius, radius_array=radius_array,
                                       container=container, cell_size=splat.cell_size))
    if normals:
        stages.append(Normals())
    stages.append(SurfaceKind(LIQUID_SURFACE if liquid else PARTICLE_SURFACE))
    return stages


def surface_option_names() -> tuple[str, ...]:
    """Names of the keyword options :func:`surface_stages` and :func:`reconstruct` take."""
    return tuple(inspect.signature(surface_stages).parameters)


def _point_cloud(points_or_dataset):
    """A vtkPointSet of the particles: a dataset as given, or points (N, 3) without cells."""
    import pyvista as pv

    from filters.validation import check_points

    if isinstance(points_or_dataset, vtkPointSet):
        return points_or_dataset
    if isinstance(points_or_dataset, vtkDataObject):
        if not isinstance(points_or_dataset, vtkDataSet):
            hint = (" (one surface per block: multiblock.blobflow.surface(radius))"
                    if isinstance(points_or_dataset, vtkMultiBlockDataSet) else "")
            raise TypeError(f"points_or_dataset must be points (N, 3) or a dataset, got a "
                            f"{points_or_dataset.GetClassName()}{hint}")
        data = pv.wrap(points_or_dataset)  # image data, rectilinear grids: their points
        cloud = pv.PolyData(np.asarray(data.points, dtype=np.float64))
        for name in data.point_data.keys():
            cloud.point_data[name] = data.point_data[name]
        return cloud
    try:
        points = check_points("points_or_dataset", points_or_dataset)
    except (TypeError, ValueError) as exc:
        raise type(exc)(f"{exc} (or pass a PyVista/VTK point dataset)") from None
    return pv.PolyData(np.ascontiguousarray(points, dtype=np.float64))


def reconstruct(points_or_dataset: ArrayLike | vtkPointSet | vtkDataSet, radius: float, *,
                cell_size: float | None = _D["cell_size"],
                kernel: str = _D["kernel"], anisotropic: bool = _D["anisotropic"],
                feature_smoothing: int = _D["feature_smoothing"],
                smooth_iterations: int = _D["smooth_iterations"],
                pass_band: float = _D["pass_band"], normals: bool = _D["normals"],
                attributes: Sequence[str] = _D["attributes"], liquid: bool = _D["liquid"],
                volume_correction: bool | None = _D["volume_correction"],
                support_r: float | None = _D["support_r"], blobbiness: float = _D["blobbiness"],
                radius_array: str | None = _D["radius_array"], iso: float | None = _D["iso"],
                sparse: bool = _D["sparse"], block_size: int = _D["block_size"],
                brick_blocks: int = _D["brick_blocks"], max_bytes: int = _D["max_bytes"],
                implicit: Shape | None = None, operation: str = _D["operation"],
                anisotropy: dict | None = None, mirror_walls: bool = _D["mirror_walls"],
                contour: str = _D["contour"], progress_bar: bool = False) -> pv.PolyData:
    """The surface of one point cloud: splat, contour, smooth (the :func:`surface_stages` chain).

    One call for what a :class:`pipeline.Flow` does at every frame: the same options give the
    same surface, bit for bit. The accessor ``cloud.blobflow.surface(radius=...)`` of PyVista
    datasets and multiblocks (:mod:`pipeline.accessor`) calls it. The first call on a machine
    compiles Numba kernels (a minute or two, then cached): a
    :class:`pipeline.feedback.CompileNotice` warning says so when it starts.

    Parameters
    ----------
    points_or_dataset : (N, 3) array_like or vtkPointSet / pyvista.DataSet
        Particle positions (m), or a dataset whose points are the particles.
    radius : float
        Particle radius (m), > 0.
    cell_size : float, optional
        Voxel edge (m), > 0; default ``radius / 2``.
    kernel : {"sph", "blobby", "metaball", "zhu_bridson"}
        Splatting kernel (:mod:`filters.kernels`).
    anisotropic : bool
        Ellipsoidal kernels along the local particle distribution (Yu & Turk 2013): flat
        water comes out flat; kernels ``sph``, ``metaball``, ``blobby``.
    feature_smoothing : int
        Sweeps of feature-weighted Laplacian smoothing (Löschner et al. 2023), in [0, 10000].
    smooth_iterations : int
        Windowed-sinc iterations (Taubin, Zhang & Golub 1996), in [0, 1000].
    pass_band : float
        Windowed-sinc pass band, in (0, 2); lower smooths more.
    normals : bool
        Compute point normals.
    attributes : sequence of str
        Point arrays of the particles carried to the vertices. A name the particles lack gives
        a :class:`pipeline.feedback.BlobflowWarning` (the default, ``velocity``, is carried
        where the particles have it, silently).
    liquid : bool
        The particles are a liquid's, sampled at a spacing of ``2 radius`` (the particles of
        an SPH simulation): the volume correction is on by default, and the surface is tagged
        ``liquid_surface`` (drawn as water). Otherwise (any other point cloud) it is tagged
        ``particle_surface``.
    volume_correction : bool, optional
        Offset every closed piece of the surface along its normals until it encloses its
        particles' volume, ``(2 radius)^3`` each
        (:class:`pipeline.surface.liquid.VolumeCorrection`).
        Default (None): as ``liquid``. Not with an ``implicit`` shape in a union.
    support_r : float, optional
        Kernel support over the radius, in (0, 1000]; default the kernel's.
    blobbiness : float
        The blobby kernel's sharpness ``a``, in (0, 100].
    radius_array : str, optional
        Point array of per-particle radii (m).
    iso : float, optional
        Iso value of the field, > 0; default the kernel's.
    sparse : bool
        A sparse grid of bricks around the particles (memory follows the surface) instead of
        one dense grid.
    block_size, brick_blocks : int
        Voxels per block edge, in [4, 64]; blocks per brick edge, in [1, 64].
    max_bytes : int
        Memory budget of the grid (bytes), >= 1.
    implicit : filters.geometry.Shape, optional
        A shape combined with the field by ``operation`` (a liquid's tank).
    operation : {"intersection", "union", "difference"}
        How ``implicit`` combines with the field.
    anisotropy : dict, optional
        Options of :func:`filters.surface.anisotropy.anisotropic_kernels`.
    mirror_walls : bool
        With a :class:`filters.geometry.Box` intersected with the field: particles mirrored
        across its walls and the surface cut exactly at them (:class:`MetaballSplat`).
    contour : {"flying_edges", "tetrahedra"}
        Contouring method (:class:`MarchingCubes`).
    progress_bar : bool
        Show a progress bar over the stages (on stderr).

    Returns
    -------
    pyvista.PolyData
        The triangle surface (m), with point normals and the carried arrays unless switched
        off, and ``blobflow_kind`` in its field data; empty when there are no particles.

    Raises
    ------
    TypeError
        For an unknown option, or an input that is neither points nor a point dataset.
    ValueError
        For an option out of its range (named, with the range), before any work starts.

    Examples
    --------
    >>> import numpy as np
    >>> surface = reconstruct(np.random.default_rng(0).uniform(0, 0.05, (500, 3)),
    ...                       radius=0.005, progress_bar=True)              # doctest: +SKIP
    """
    options = {name: value for name, value in locals().items()
               if name not in ("points_or_dataset", "progress_bar")}
    import pyvista as pv

    stages = surface_stages(**options)  # validates every option before any work
    progress_bar = check_bool("progress_bar", progress_bar)
    cloud = _point_cloud(points_or_dataset)
    if tuple(attributes) != _D["attributes"]:
        have = cloud.GetPointData()
        missing = [n for n in attributes if have.GetAbstractArray(n) is None]
        if missing:
            names = sorted(have.GetArrayName(i) for i in range(have.GetNumberOfArrays()))
            warnings.warn(f"attributes: the particles have no point array "
                          f"{', '.join(map(repr, missing))} (their arrays: "
                          f"{', '.join(names) or 'none'}); the surface goes without",
                          BlobflowWarning, stacklevel=2)
    with compile_notice("the surface"), stage_progress(stages, progress_bar, "surface"):
        return pv.wrap(run_chain(stages, cloud, what="the surface reconstruction"))
