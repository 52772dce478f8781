"""Surface stages: particles -> implicit field -> triangle mesh -> smoothed mesh with normals.

Each stage is a VTK algorithm (:class:`pipeline.algorithm.Algorithm`, a
:class:`VTKPythonAlgorithmBase` whose exceptions reach the caller), so any VTK filter can sit
between two of them, and each passes time requests upstream (a temporal particle source drives
them). Stages that need the particles read them on their second input port
(:class:`pipeline.algorithm.ParticleStage`), connected to the particles the chain starts from:

``MetaballSplat``
    vtkPointSet particles -> vtkImageData (``sparse=False``) or a vtkPartitionedDataSet of
    image *bricks* (``sparse=True``, default) holding the implicit value ``implicit`` (negative
    inside) computed by :mod:`filters.surface.splat`, optionally combined with a shape of
    :mod:`filters.geometry` (:mod:`filters.surface.csg`).
``MarchingCubes``
    vtkFlyingEdges3D at ``value`` (0 for our fields), or marching tetrahedra
    (``method="tetrahedra"``): one watertight vtkPolyData, bricks contoured in voxel-index
    coordinates and stitched (:mod:`pipeline.contour`).
``ClipBox`` (with a tank whose walls the particles are mirrored across)
    The surface cut exactly at the tank's walls and closed with flat faces
    (:mod:`pipeline.liquid`); the smoothing stages keep those faces on the walls.
``FeatureSmoothing`` (mesh, particles; :mod:`pipeline.particle_stages`)
    Feature-weighted Laplacian smoothing (Löschner et al. 2023,
    :mod:`filters.surface.smoothing`): flat liquid smoothed fully, droplets and sheets kept.
``InterpolateAttributes`` (mesh, particles; :mod:`pipeline.particle_stages`)
    Particle arrays (``velocity``, ...) carried to the vertices with the splatting kernel
    (Shepard weights, :mod:`filters.surface.attributes`).
``Smooth`` (:mod:`pipeline.mesh_stages`)
    vtkWindowedSincPolyDataFilter (Taubin, Zhang & Golub 1996), whose low-pass filter does not
    shrink the surface the way Laplacian smoothing does (:mod:`pipeline.mesh_stages`).
``VolumeCorrection`` (mesh, particles; a liquid's particles)
    Every closed piece offset along its normals until it encloses its particles' volume
    (:mod:`pipeline.liquid`, :mod:`filters.surface.correction`).
``Normals``
    vtkPolyDataNormals without splitting (the mesh stays watertight).
``SurfaceKind``
    ``blobflow_kind`` in the field data: ``liquid_surface`` (drawn as water) or
    ``particle_surface`` (:mod:`pipeline.liquid`).

:func:`surface_stages` builds the chain, and :func:`reconstruct` runs it on one point cloud, from
one set of options whose defaults are :data:`pipeline.surface_options.OPTION_DEFAULTS` (the
options of ``blobflow surface --option``); with ``liquid=True`` and a liquid's radius and tank
(:func:`pipeline.surface_options.liquid_surface_options`) they give the liquid scenes' surface.
"""

from __future__ import annotations

import inspect
import math
import warnings
from typing import TYPE_CHECKING, Sequence

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import (vtkDataObject, vtkDataSet, vtkImageData,
                                           vtkMultiBlockDataSet, vtkPartitionedDataSet,
                                           vtkPointSet, vtkPolyData)

from filters.geometry import Box, Shape
from filters.kernels import SPLAT_DEFAULTS, SPLAT_KERNELS
from filters.surface.anisotropy import check_anisotropy
from filters.surface.csg import OPERATIONS, combine_dense, combine_sparse
from filters.surface.ellipsoids import ANISOTROPIC_KERNELS
from filters.surface.grid import DEFAULT_MAX_BYTES, check_budget
from filters.surface.splat import (splat_dense, splat_dense_anisotropic, splat_sparse,
                                   splat_sparse_anisotropic)
from filters.surface.tetra import TetraPieces
from filters.surface.walls import WALL_MARGIN_R, grow_walls
from filters.validation import check_bool, check_choice, check_int, check_range

from .algorithm import Algorithm, run_chain
from .contour import (CONTOUR_METHODS, Pieces, brick_images, check_grid_sizes, flying_edges,
                      image_of, mesh_to_polydata)
from .feedback import BlobflowWarning, compile_notice, stage_progress
from .liquid import (LIQUID_SURFACE, PARTICLE_SURFACE, ClipBox, SurfaceKind,
                     VolumeCorrection)
from .mesh_stages import Normals, Smooth
from .particle_stages import (FeatureSmoothing, InterpolateAttributes, check_optional_range,
                              check_optional_str, particles_from, radii_from)
from .surface_options import OPTION_DEFAULTS, SURFACE_DEFAULTS

if TYPE_CHECKING:
    import pyvista as pv
    from numpy.typing import ArrayLike

_D = OPTION_DEFAULTS  # the one table of defaults (pipeline.surface_options.SURFACE_PARAMETERS)

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
# Stages
# --------------------------------------------------------------------------------------------


class MetaballSplat(Algorithm):
    """Particles (vtkPolyData / any vtkPointSet) -> implicit field on a voxel lattice.

    Parameters
    ----------
    radius : float
        Particle radius (m), > 0, used where the input has no ``radius_array``.
    cell_size : float, optional
        Voxel edge (m), > 0; default ``radius / 2`` (splashsurf's cube size 0.5).
    kernel : {"blobby", "metaball", "sph", "zhu_bridson"}
        See :mod:`filters.kernels`.
    support_r, iso, blobbiness
        See :func:`filters.surface.splat.splat_sparse` (``support_r`` in (0, 1000] multiples
        of the radius, ``iso`` > 0, ``blobbiness`` in (0, 100]).
    radius_array : str, optional
        Point array holding per-particle radii (m).
    sparse : bool
        True: a vtkPartitionedDataSet of image bricks covering the surface (memory follows the
        surface); False: one vtkImageData over the whole reachable box.
    block_size, brick_blocks : int
        Voxels per block edge, in [4, 64]; blocks per brick edge, in [1, 64] (sparse output).
    max_bytes : int
        Memory budget (bytes) of the grid, >= 1.
    implicit : filters.geometry.Shape, optional
        A shape combined with the particle field by ``operation`` (:mod:`filters.surface.csg`).
        A :class:`filters.geometry.Box` intersected with the field is the liquid's tank (see
        ``mirror_walls``).
    operation : {"union", "intersection", "difference"}
        How ``implicit`` combines with the particles' field.
    anisotropic : bool
        Splat ellipsoidal kernels stretched along the local particle distribution (Yu & Turk
        2013, :mod:`filters.surface.anisotropy`): flat water without bumps and sharper edges, at
        a higher cost; drops of a few particles come out larger. Kernels ``sph``, ``metaball``
        and ``blobby``.
    anisotropy : dict, optional
        Options of :func:`filters.surface.anisotropy.anisotropic_kernels` (``neighbor_radius_r``,
        ``stretch``, ``min_neighbors``, ``smoothing``, ``layer_band_r``, ``max_axis_r``,
        ``isotropy``).
    mirror_walls : bool
        With a :class:`filters.geometry.Box` ``implicit`` and ``operation="intersection"`` (the
        liquid's tank): mirror the particles near its walls across them (ghost particles,
        :mod:`filters.surface.walls`) and intersect the field with the box grown by one
        spacing (:data:`filters.surface.walls.WALL_MARGIN_R` radii) instead: the surface goes
        on through the walls, and :class:`pipeline.liquid.ClipBox` cuts it exactly at them
        (:func:`surface_stages` adds it), so that it meets the walls, their edges and corners
        without a gap.
    """

    def __init__(self, radius: float = SURFACE_DEFAULTS["radius"], cell_size: float | None = None,
                 *, kernel: str = SURFACE_DEFAULTS["kernel"], support_r: float | None = None,
                 iso: float | None = None,
                 blobbiness: float = 4.0, radius_array: str | None = None, sparse: bool = True,
                 block_size: int = 8, brick_blocks: int = 4,
                 max_bytes: int = DEFAULT_MAX_BYTES, implicit: Shape | None = None,
                 operation: str = "intersection", anisotropic: bool = False,
                 anisotropy: dict | None = None, mirror_walls: bool = False):
        self.radius = check_range("radius", radius, 0.0, math.inf, low_inclusive=False,
                                  high_inclusive=False)
        self.cell_size = (self.radius / 2 if cell_size is None else
                          check_range("cell_size", cell_size, 0.0, math.inf, low_inclusive=False,
                                      high_inclusive=False))
        self.kernel = check_choice("kernel", kernel, SPLAT_KERNELS)
        self.anisotropic = check_bool("anisotropic", anisotropic)
        if self.anisotropic and kernel not in ANISOTROPIC_KERNELS:
            raise ValueError(f"kernel must be one of {', '.join(map(repr, ANISOTROPIC_KERNELS))} "
                             f"when anisotropic=True, got {kernel!r}")
        self.support_r = check_optional_range("support_r", support_r, 0.0, 1e3, False)
        self.iso = check_optional_range("iso", iso, 0.0, math.inf)
        self.blobbiness = check_range("blobbiness", blobbiness, 0.0, 100.0, low_inclusive=False)
        self.radius_array = check_optional_str("radius_array", radius_array)
        self.sparse = check_bool("sparse", sparse)
        self.block_size = check_int("block_size", block_size, 4, 64)
        self.brick_blocks = check_int("brick_blocks", brick_blocks, 1, 64)
        self.max_bytes = check_int("max_bytes", max_bytes, 1)
        if implicit is not None and not isinstance(implicit, Shape):
            raise TypeError(f"implicit must be a filters.geometry.Shape or None, got "
                            f"{type(implicit).__name__}")
        self.implicit = implicit
        self.operation = check_choice("operation", operation, OPERATIONS)
        self.mirror_walls = check_bool("mirror_walls", mirror_walls)
        if anisotropy is not None and not isinstance(anisotropy, dict):
            raise TypeError(f"anisotropy must be a dict of options, got {anisotropy!r}")
        self.anisotropy = dict(anisotropy or {})
        if self.anisotropy:
            support = (self.support_r if self.support_r is not None
                       else SPLAT_DEFAULTS[self.kernel]["support"])
            check_anisotropy(support, **self.anisotropy)
        check_grid_sizes(self.radius, self.cell_size, self.kernel, self.support_r,
                         self.block_size, self.brick_blocks, self.max_bytes,
                         self.sparse and self.radius_array is None)
        Algorithm.__init__(
            self, nInputPorts=1, inputType="vtkPointSet", nOutputPorts=1,
            outputType="vtkPartitionedDataSet" if self.sparse else "vtkImageData")

    def _options(self):
        options = dict(kernel=self.kernel, support_r=self.support_r, iso=self.iso,
                       block_size=self.block_size, blobbiness=self.blobbiness,
                       max_bytes=self.max_bytes)
        if self.walls is not None:
            # the liquid's tank: ghosts mirrored across its walls
            options["walls"] = self.walls
        if self.anisotropic:
            options.update(self.anisotropy)
        return options

    @property
    def walls(self) -> Box | None:
        """The tank whose walls the particles are mirrored across, or None."""
        if self.mirror_walls and isinstance(self.implicit, Box) \
                and self.operation == "intersection":
            return self.implicit
        return None

    def _shape(self, radius):
        """The shape combined with the field: the tank grown by WALL_MARGIN_R radii with
        ghosts, else ``implicit``."""
        if self.walls is None:
            return self.implicit
        margin = WALL_MARGIN_R * float(np.max(radius)) if np.size(radius) else 0.0
        lo, hi = grow_walls((np.asarray(self.walls.lower, float),
                             np.asarray(self.walls.upper, float)), margin)
        return Box(tuple(lo), tuple(hi))

    def _splat(self, sparse: bool):
        """The splatting function for the chosen grid and kernel shape."""
        if self.anisotropic:
            return splat_sparse_anisotropic if sparse else splat_dense_anisotropic
        return splat_sparse if sparse else splat_dense

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkPointSet.GetData(inInfo[0], 0)
        positions = particles_from(inp)
        radius = radii_from(inp, positions, self.radius, self.radius_array)
        if self.sparse:
            grid = self._splat(True)(positions, radius, self.cell_size, **self._options())
            if self.implicit is not None:
                grid = combine_sparse(grid, self._shape(radius), self.operation,
                                      max_bytes=self.max_bytes)
            out = vtkPartitionedDataSet.GetData(outInfo, 0)
            out.Initialize()
            k = 0
            spent = grid.data.nbytes
            for origin, values in brick_images(grid, self.brick_blocks, max_bytes=self.max_bytes):
                # deep copies: the output outlives this call and the reused buffer; they count
                # against the budget with the grid
                spent += values.nbytes
                check_budget(spent, self.max_bytes, f"the grid and {k + 1} brick images of "
                             f"{values.shape[0]}^3 voxels")
                image, _keep = image_of(values, origin, deep=True)
                image.SetOrigin(*(origin.astype(np.float64) * grid.cell_size))
                image.SetSpacing(grid.cell_size, grid.cell_size, grid.cell_size)
                out.SetPartition(k, image)
                k += 1
        else:
            field = self._splat(False)(positions, radius, self.cell_size, **self._options())
            if self.implicit is not None:
                field = combine_dense(field, self._shape(radius), self.operation)
            out = vtkImageData.GetData(outInfo, 0)
            image, _keep = image_of(np.ascontiguousarray(field.values), field.index_origin,
                                    deep=True)
            out.ShallowCopy(image)
            out.SetOrigin(*field.origin)
            out.SetSpacing(field.cell_size, field.cell_size, field.cell_size)
        return 1


class MarchingCubes(Algorithm):
    """Implicit field (vtkImageData or a brick set) -> one watertight vtkPolyData.

    Parameters
    ----------
    value : float
        Contour value, finite (0 for :class:`MetaballSplat` output: negative inside).
    method : {"flying_edges", "tetrahedra"}
        ``"flying_edges"``: VTK's vtkFlyingEdges3D (marching cubes); ``"tetrahedra"``: marching
        tetrahedra on the Kuhn split of every cube (:mod:`filters.surface.tetra`), in Numba,
        about twice the triangles.  Both stitch bricks into one mesh with shared vertices.
    """

    def __init__(self, value: float = 0.0, method: str = "flying_edges"):
        self.value = check_range("value", value)
        if not math.isfinite(self.value):
            raise ValueError(f"value must be finite, got {value!r}")
        self.method = check_choice("method", method, CONTOUR_METHODS)
        Algorithm.__init__(self, nInputPorts=1, inputType="vtkDataObject", nOutputPorts=1,
                           outputType="vtkPolyData")

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkDataObject.GetData(inInfo[0], 0)
        pts, tris = self._contour(inp)
        vtkPolyData.GetData(outInfo, 0).ShallowCopy(mesh_to_polydata(pts, tris))
        return 1

    def _contour(self, inp):
        if isinstance(inp, vtkImageData):
            images = [inp]
        elif isinstance(inp, vtkPartitionedDataSet):
            images = [inp.GetPartition(i) for i in range(inp.GetNumberOfPartitions())]
            images = [im for im in images if im is not None]
        else:
            raise TypeError(f"MarchingCubes needs vtkImageData or vtkPartitionedDataSet input, "
                            f"got {inp.GetClassName()}")
        tetra = self.method == "tetrahedra"
        if tetra:
            pieces = TetraPieces(self.value)
        else:
            fe = flying_edges()
            fe.SetValue(0, self.value)
            pieces = Pieces()
        cell = None
        for im in images:
            if im.GetNumberOfPoints() == 0 or min(im.GetDimensions()) < 2:
                continue
            spacing = np.array(im.GetSpacing())
            if not np.allclose(spacing, spacing[0]):
                raise ValueError(f"MarchingCubes needs cubic voxels, got spacing "
                                 f"{spacing.tolist()}")
            if cell is None:
                cell = float(spacing[0])
            # contour in index space so that bricks share bitwise equal vertices
            index_origin = np.round(np.array(im.GetOrigin()) / spacing)
            if tetra:
                nx, ny, nz = im.GetDimensions()
                scalars = im.GetPointData().GetScalars()
                if scalars is None:
                    raise ValueError("MarchingCubes needs point scalars on its input images")
                values = numpy_support.vtk_to_numpy(scalars).reshape(nz, ny, nx)
                pieces.add(values, index_origin.astype(np.int64))
                continue
            work = vtkImageData()
            work.ShallowCopy(im)
            work.SetOrigin(*index_origin)
            work.SetSpacing(1.0, 1.0, 1.0)
            fe.SetInputData(work)
            fe.Modified()
            fe.Update()
            pieces.add(fe, index_origin, index_origin + np.array(im.GetDimensions()) - 1)
        return pieces.mesh(1.0 if cell is None else cell)


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
    :class:`filters.geometry.Box` intersected with the field a :class:`pipeline.liquid.ClipBox`
    (the smoothing then keeps the cut faces on the walls), :class:`FeatureSmoothing`,
    :class:`InterpolateAttributes`, :class:`Smooth`, :class:`pipeline.liquid.VolumeCorrection`,
    :class:`Normals`, each left out where its option switches it off, and last
    :class:`pipeline.liquid.SurfaceKind`, which writes ``blobflow_kind`` (``liquid_surface``
    with ``liquid=True``, else ``particle_surface``) into the surface's field data.
    :func:`pipeline.surface_options.liquid_surface_options` gives a liquid's options (its
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


def reconstruct(points_or_dataset: ArrayLike | vtkPointSet | vtkDataSet, radius: float, *, cell_size: float | None = _D["cell_size"],
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
        particles' volume, ``(2 radius)^3`` each (:class:`pipeline.liquid.VolumeCorrection`).
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
