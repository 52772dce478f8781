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
    vtkFlyingEdges3D at ``value`` (0 for our fields): one watertight vtkPolyData, bricks
    contoured in voxel-index coordinates and stitched (:mod:`pipeline.contour`).
``FeatureSmoothing`` (mesh, particles)
    Feature-weighted Laplacian smoothing (Löschner et al. 2023,
    :mod:`filters.surface.smoothing`): flat liquid smoothed fully, droplets and sheets kept.
``InterpolateAttributes`` (mesh, particles)
    Particle arrays (``velocity``, ...) carried to the vertices with the splatting kernel
    (Shepard weights, :mod:`filters.surface.attributes`).
``Smooth`` (:mod:`pipeline.mesh_stages`)
    vtkWindowedSincPolyDataFilter (Taubin, Zhang & Golub 1996), whose low-pass filter does not
    shrink the surface the way Laplacian smoothing does.
``Normals``
    vtkPolyDataNormals without splitting (the mesh stays watertight).

:func:`surface_stages` builds the chain, and :func:`reconstruct` runs it on one point cloud, from
one set of options whose defaults,
:data:`pipeline.surface_options.SURFACE_DEFAULTS`, are the liquid scenes' surface and
``blobflow surface``'s (:mod:`pipeline.surface_options`).
"""

from __future__ import annotations

import math

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import (vtkDataObject, vtkDataSet, vtkImageData,
                                           vtkPartitionedDataSet,
                                           vtkPointSet, vtkPolyData)

from filters.geometry import Shape
from filters.kernels import SPLAT_DEFAULTS, SPLAT_KERNELS
from filters.surface.anisotropy import check_anisotropy
from filters.surface.attributes import interpolate_attributes
from filters.surface.csg import OPERATIONS, combine_dense, combine_sparse
from filters.surface.ellipsoids import ANISOTROPIC_KERNELS
from filters.surface.grid import DEFAULT_MAX_BYTES
from filters.surface.smoothing import smooth_surface
from filters.surface.splat import (splat_dense, splat_dense_anisotropic, splat_sparse,
                                   splat_sparse_anisotropic)
from filters.validation import check_bool, check_choice, check_int, check_range

from .algorithm import Algorithm, ParticleStage, run_chain
from .contour import Pieces, brick_images, flying_edges, image_of, mesh_to_polydata
from .mesh_stages import Normals, Smooth
from .surface_options import SURFACE_DEFAULTS

__all__ = [
    "MetaballSplat",
    "MarchingCubes",
    "FeatureSmoothing",
    "InterpolateAttributes",
    "Smooth",
    "Normals",
    "surface_stages",
    "surface_option_names",
    "reconstruct",
]


# --------------------------------------------------------------------------------------------
# Checks shared by the stages
# --------------------------------------------------------------------------------------------


def _check_optional_str(name, value):
    if value is not None and not (isinstance(value, str) and value):
        raise TypeError(f"{name} must be a point array name or None, got {value!r}")
    return value


def _check_names(name, values):
    if isinstance(values, str):
        raise TypeError(f"{name} must be a sequence of point array names, got the string "
                        f"{values!r}")
    try:
        values = tuple(values)
    except TypeError:
        raise TypeError(f"{name} must be a sequence of point array names, got {values!r}") from None
    for v in values:
        if not (isinstance(v, str) and v):
            raise TypeError(f"{name} must hold point array names, got {v!r}")
    return values


def _check_optional_range(name, value, low, high, low_inclusive=True):
    return None if value is None else check_range(name, value, low, high,
                                                  low_inclusive=low_inclusive)


def _particles_from(inp):
    n = inp.GetNumberOfPoints()
    if n == 0:
        return np.zeros((0, 3))
    return numpy_support.vtk_to_numpy(inp.GetPoints().GetData()).astype(np.float64)


def _radii_from(inp, positions, radius, radius_array):
    """The particle radii (m): ``radius`` or, when there are particles, the ``radius_array``."""
    if radius_array and positions.shape[0]:
        arr = inp.GetPointData().GetArray(radius_array)
        if arr is None:
            raise ValueError(f"radius_array {radius_array!r} is not a point array of the input")
        return numpy_support.vtk_to_numpy(arr).astype(np.float64).reshape(-1)
    return radius


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
    """

    def __init__(self, radius: float = SURFACE_DEFAULTS["radius"], cell_size: float | None = None,
                 *, kernel: str = SURFACE_DEFAULTS["kernel"], support_r=None, iso=None,
                 blobbiness: float = 4.0, radius_array: str | None = None, sparse: bool = True,
                 block_size: int = 8, brick_blocks: int = 4,
                 max_bytes: int = DEFAULT_MAX_BYTES, implicit: Shape | None = None,
                 operation: str = "intersection", anisotropic: bool = False,
                 anisotropy: dict | None = None):
        self.radius = check_range("radius", radius, 0.0, math.inf, low_inclusive=False)
        self.cell_size = (self.radius / 2 if cell_size is None else
                          check_range("cell_size", cell_size, 0.0, math.inf, low_inclusive=False))
        self.kernel = check_choice("kernel", kernel, SPLAT_KERNELS)
        self.anisotropic = check_bool("anisotropic", anisotropic)
        if self.anisotropic and kernel not in ANISOTROPIC_KERNELS:
            raise ValueError(f"kernel must be one of {', '.join(map(repr, ANISOTROPIC_KERNELS))} "
                             f"when anisotropic=True, got {kernel!r}")
        self.support_r = _check_optional_range("support_r", support_r, 0.0, 1e3, False)
        self.iso = _check_optional_range("iso", iso, 0.0, math.inf)
        self.blobbiness = check_range("blobbiness", blobbiness, 0.0, 100.0, low_inclusive=False)
        self.radius_array = _check_optional_str("radius_array", radius_array)
        self.sparse = check_bool("sparse", sparse)
        self.block_size = check_int("block_size", block_size, 4, 64)
        self.brick_blocks = check_int("brick_blocks", brick_blocks, 1, 64)
        self.max_bytes = check_int("max_bytes", max_bytes, 1)
        if implicit is not None and not isinstance(implicit, Shape):
            raise TypeError(f"implicit must be a filters.geometry.Shape or None, got "
                            f"{type(implicit).__name__}")
        self.implicit = implicit
        self.operation = check_choice("operation", operation, OPERATIONS)
        if anisotropy is not None and not isinstance(anisotropy, dict):
            raise TypeError(f"anisotropy must be a dict of options, got {anisotropy!r}")
        self.anisotropy = dict(anisotropy or {})
        if self.anisotropy:
            support = (self.support_r if self.support_r is not None
                       else SPLAT_DEFAULTS[self.kernel]["support"])
            check_anisotropy(support, **self.anisotropy)
        Algorithm.__init__(
            self, nInputPorts=1, inputType="vtkPointSet", nOutputPorts=1,
            outputType="vtkPartitionedDataSet" if self.sparse else "vtkImageData")

    def _options(self):
        options = dict(kernel=self.kernel, support_r=self.support_r, iso=self.iso,
                       block_size=self.block_size, blobbiness=self.blobbiness,
                       max_bytes=self.max_bytes)
        if self.anisotropic:
            options.update(self.anisotropy)
        return options

    def _splat(self, sparse: bool):
        """The splatting function for the chosen grid and kernel shape."""
        if self.anisotropic:
            return splat_sparse_anisotropic if sparse else splat_dense_anisotropic
        return splat_sparse if sparse else splat_dense

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkPointSet.GetData(inInfo[0], 0)
        positions = _particles_from(inp)
        radius = _radii_from(inp, positions, self.radius, self.radius_array)
        if self.sparse:
            grid = self._splat(True)(positions, radius, self.cell_size, **self._options())
            if self.implicit is not None:
                grid = combine_sparse(grid, self.implicit, self.operation,
                                      max_bytes=self.max_bytes)
            out = vtkPartitionedDataSet.GetData(outInfo, 0)
            out.Initialize()
            k = 0
            for origin, values in brick_images(grid, self.brick_blocks):
                # deep copies: the output outlives this call and the reused buffer
                image, _keep = image_of(values, origin, deep=True)
                image.SetOrigin(*(origin.astype(np.float64) * grid.cell_size))
                image.SetSpacing(grid.cell_size, grid.cell_size, grid.cell_size)
                out.SetPartition(k, image)
                k += 1
        else:
            field = self._splat(False)(positions, radius, self.cell_size, **self._options())
            if self.implicit is not None:
                field = combine_dense(field, self.implicit, self.operation)
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
    """

    def __init__(self, value: float = 0.0):
        self.value = check_range("value", value)
        if not math.isfinite(self.value):
            raise ValueError(f"value must be finite, got {value!r}")
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
            work = vtkImageData()
            work.ShallowCopy(im)
            work.SetOrigin(*index_origin)
            work.SetSpacing(1.0, 1.0, 1.0)
            fe.SetInputData(work)
            fe.Modified()
            fe.Update()
            pieces.add(fe, index_origin, index_origin + np.array(im.GetDimensions()) - 1)
        return pieces.mesh(1.0 if cell is None else cell)


class FeatureSmoothing(ParticleStage):
    """Feature-weighted Laplacian smoothing of a liquid surface (Löschner et al. 2023).

    Input port 0: the triangle mesh; port 1: the particles (see
    :func:`filters.surface.smoothing.smooth_surface`): flat liquid is smoothed fully, sheets
    and droplets of a few particles are left alone.

    Parameters
    ----------
    iterations : int
        Jacobi sweeps, in [0, 10000]; 0 passes the mesh through.
    radius : float
        Particle radius ``r`` (m), > 0, where the particles have no ``radius_array``; with
        per-particle radii the largest sets the spacing the fullness is measured against.
    radius_array : str, optional
        Point array of the particles holding their radii (m).
    reach_r : float
        Neighbourhood radius over ``r``, in [1, 20].
    """

    def __init__(self, iterations: int = SURFACE_DEFAULTS["feature_smoothing"], *,
                 radius: float = SURFACE_DEFAULTS["radius"], radius_array: str | None = None,
                 reach_r: float = 8.0):
        self.iterations = check_int("iterations", iterations, 0, 10000)
        self.radius = check_range("radius", radius, 0.0, math.inf, low_inclusive=False)
        self.radius_array = _check_optional_str("radius_array", radius_array)
        self.reach_r = check_range("reach_r", reach_r, 1.0, 20.0)
        ParticleStage.__init__(self)

    def RequestData(self, request, inInfo, outInfo):
        mesh = vtkPolyData.GetData(inInfo[0], 0)
        out = vtkPolyData.GetData(outInfo, 0)
        out.ShallowCopy(mesh)
        if not self.iterations or mesh.GetNumberOfPoints() == 0:
            return 1
        particles = vtkPointSet.GetData(inInfo[1], 0)
        positions = _particles_from(particles)
        radius = _radii_from(particles, positions, self.radius, self.radius_array)
        radius = np.broadcast_to(np.asarray(radius, np.float64), (positions.shape[0],))
        r = float(radius.max()) if radius.size else 1.0
        pts = numpy_support.vtk_to_numpy(mesh.GetPoints().GetData())
        tris = numpy_support.vtk_to_numpy(mesh.GetPolys().GetConnectivityArray()).reshape(-1, 3)
        smoothed = smooth_surface(pts.astype(np.float64), tris,
                                  np.ascontiguousarray(positions, np.float64), r,
                                  iterations=self.iterations, reach_r=self.reach_r)
        out.ShallowCopy(mesh_to_polydata(smoothed.astype(pts.dtype), tris))
        return 1


class InterpolateAttributes(ParticleStage):
    """Particle point arrays carried to the vertices of a surface (Shepard weights of the
    splatting kernel, :func:`filters.surface.attributes.interpolate_attributes`).

    Input port 0: the mesh; port 1: the particles. The splatting options must be those of the
    :class:`MetaballSplat` that made the surface (:func:`surface_stages` passes them).

    Parameters
    ----------
    attributes : sequence of str
        Point arrays of the particles to interpolate (missing ones are ignored).
    radius, cell_size, kernel, support_r, blobbiness, radius_array
        As in :class:`MetaballSplat`.
    """

    def __init__(self, attributes=SURFACE_DEFAULTS["attributes"], *,
                 radius: float = SURFACE_DEFAULTS["radius"], cell_size: float | None = None,
                 kernel: str = SURFACE_DEFAULTS["kernel"], support_r=None,
                 blobbiness: float = 4.0, radius_array: str | None = None):
        self.attributes = _check_names("attributes", attributes)
        self.radius = check_range("radius", radius, 0.0, math.inf, low_inclusive=False)
        self.cell_size = (self.radius / 2 if cell_size is None else
                          check_range("cell_size", cell_size, 0.0, math.inf, low_inclusive=False))
        self.kernel = check_choice("kernel", kernel, SPLAT_KERNELS)
        self.support_r = _check_optional_range("support_r", support_r, 0.0, 1e3, False)
        self.blobbiness = check_range("blobbiness", blobbiness, 0.0, 100.0, low_inclusive=False)
        self.radius_array = _check_optional_str("radius_array", radius_array)
        ParticleStage.__init__(self)

    def RequestData(self, request, inInfo, outInfo):
        mesh = vtkPolyData.GetData(inInfo[0], 0)
        particles = vtkPointSet.GetData(inInfo[1], 0)
        out = vtkPolyData.GetData(outInfo, 0)
        out.ShallowCopy(mesh)
        positions = _particles_from(particles)
        if not positions.shape[0]:
            return 1
        names, values = [], []
        for name in self.attributes:
            arr = particles.GetPointData().GetArray(name)
            if arr is not None:
                names.append(name)
                values.append(numpy_support.vtk_to_numpy(arr).astype(np.float64))
        if not names:
            return 1
        radius = _radii_from(particles, positions, self.radius, self.radius_array)
        radius = np.broadcast_to(np.asarray(radius, np.float64), (positions.shape[0],)).copy()
        n = mesh.GetNumberOfPoints()
        pd = out.GetPointData()
        if n == 0:
            result = [np.zeros((0,) + v.shape[1:], np.float64) for v in values]
        else:
            pts = numpy_support.vtk_to_numpy(mesh.GetPoints().GetData()).astype(np.float64)
            columns = [v.reshape(v.shape[0], -1) for v in values]
            # all attributes in one pass: the same kernel weights serve every column
            stacked = interpolate_attributes(
                pts, positions, radius, np.concatenate(columns, axis=1),
                cell_size=self.cell_size, kernel=self.kernel, support_r=self.support_r,
                blobbiness=self.blobbiness)
            result, start = [], 0
            for v, c in zip(values, columns):
                part = stacked[:, start:start + c.shape[1]]
                result.append(np.ascontiguousarray(part).reshape((n,) + v.shape[1:]))
                start += c.shape[1]
        for name, array in zip(names, result):
            vtk_array = numpy_support.numpy_to_vtk(np.ascontiguousarray(array), deep=True)
            vtk_array.SetName(name)
            pd.AddArray(vtk_array)
        return 1


# --------------------------------------------------------------------------------------------
# The chain
# --------------------------------------------------------------------------------------------


def surface_stages(radius: float = SURFACE_DEFAULTS["radius"], cell_size: float | None = None, *,
                   kernel: str = SURFACE_DEFAULTS["kernel"],
                   anisotropic: bool = SURFACE_DEFAULTS["anisotropic"],
                   feature_smoothing: int = SURFACE_DEFAULTS["feature_smoothing"],
                   smooth_iterations: int = SURFACE_DEFAULTS["smooth_iterations"],
                   pass_band: float = SURFACE_DEFAULTS["pass_band"],
                   normals: bool = SURFACE_DEFAULTS["normals"],
                   attributes=SURFACE_DEFAULTS["attributes"], support_r=None,
                   blobbiness: float = 4.0, radius_array: str | None = None,
                   **splat_options) -> list:
    """The chain particles -> surface as a list of algorithms.

    ``flow.add("surface", *surface_stages(radius=0.01), input="particles")``. The defaults
    (:data:`pipeline.surface_options.SURFACE_DEFAULTS`) are the liquid scenes' surface: anisotropic ``sph`` kernels, 25
    sweeps of feature smoothing, 30 windowed-sinc iterations with pass band 0.01, normals,
    ``velocity`` carried to the vertices (:func:`pipeline.surface_options.liquid_surface_options` adds a liquid's
    radius and tank).

    Parameters
    ----------
    radius : float
        Particle radius (m), > 0.
    cell_size : float, optional
        Voxel edge (m); default ``radius / 2``.
    kernel : str
        Splatting kernel (see :mod:`filters.kernels`).
    anisotropic : bool
        Anisotropic kernels (:class:`MetaballSplat`); only for ``sph``, ``metaball``, ``blobby``.
    feature_smoothing : int
        Sweeps of :class:`FeatureSmoothing`, in [0, 10000] (0: no such stage).
    smooth_iterations : int
        Windowed-sinc iterations of :class:`Smooth`, in [0, 1000] (0: no such stage).
    pass_band : float
        Windowed-sinc pass band, in (0, 2).
    normals : bool
        Append a :class:`Normals` stage.
    attributes : sequence of str
        Particle arrays carried to the vertices (:class:`InterpolateAttributes`; empty: no such
        stage).
    support_r, blobbiness, radius_array
        As in :class:`MetaballSplat` (shared with the stages that read the particles).
    **splat_options
        Further keyword arguments of :class:`MetaballSplat` (``iso``, ``sparse``, ``block_size``,
        ``brick_blocks``, ``max_bytes``, ``implicit``, ``operation``, ``anisotropy``).

    Returns
    -------
    list of Algorithm
    """
    splat = MetaballSplat(radius, cell_size, kernel=kernel, support_r=support_r,
                          blobbiness=blobbiness, radius_array=radius_array,
                          anisotropic=anisotropic, **splat_options)
    feature_smoothing = check_int("feature_smoothing", feature_smoothing, 0, 10000)
    smooth_iterations = check_int("smooth_iterations", smooth_iterations, 0, 1000)
    normals = check_bool("normals", normals)
    stages = [splat, MarchingCubes()]
    if feature_smoothing:
        stages.append(FeatureSmoothing(feature_smoothing, radius=radius,
                                       radius_array=radius_array))
    interpolate = InterpolateAttributes(attributes, radius=radius, cell_size=splat.cell_size,
                                        kernel=kernel, support_r=support_r,
                                        blobbiness=blobbiness, radius_array=radius_array)
    if interpolate.attributes:
        stages.append(interpolate)
    smooth = Smooth(smooth_iterations, pass_band)
    if smooth_iterations:
        stages.append(smooth)
    if normals:
        stages.append(Normals())
    return stages


def surface_option_names() -> tuple[str, ...]:
    """Names of the keyword options :func:`surface_stages` and :func:`reconstruct` take."""
    import inspect

    chain = [p.name for p in inspect.signature(surface_stages).parameters.values()
             if p.kind is not inspect.Parameter.VAR_KEYWORD]
    splat = [p.name for p in inspect.signature(MetaballSplat.__init__).parameters.values()
             if p.kind is inspect.Parameter.KEYWORD_ONLY and p.name not in chain]
    return tuple(chain + splat)


def _point_cloud(points_or_dataset):
    """A vtkPointSet of the particles: a dataset as given, or points (N, 3) without cells."""
    import pyvista as pv

    from filters.validation import check_points

    if isinstance(points_or_dataset, vtkPointSet):
        return points_or_dataset
    if isinstance(points_or_dataset, vtkDataObject):
        if not isinstance(points_or_dataset, vtkDataSet):
            raise TypeError(f"points_or_dataset must be points (N, 3) or a dataset, got a "
                            f"{points_or_dataset.GetClassName()}")
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


def reconstruct(points_or_dataset, radius: float, **options):
    """The surface of one point cloud: splat, contour, smooth (the :func:`surface_stages` chain).

    One call for what a :class:`pipeline.Flow` does at every frame: the same stages with the
    same options give the same surface, bit for bit. The accessor
    ``cloud.blobflow.surface(radius=...)`` of any PyVista dataset (:mod:`pipeline.accessor`)
    calls it.

    Parameters
    ----------
    points_or_dataset : (N, 3) array_like or vtkPointSet / pyvista.DataSet
        Particle positions (m), or a dataset whose points are the particles; its point arrays
        named in ``attributes`` (default ``velocity``) are carried to the surface's vertices and
        ``radius_array`` may name per-particle radii.
    radius : float
        Particle radius (m), > 0.
    **options
        Options of :func:`surface_stages` (``cell_size``, ``kernel``, ``anisotropic``,
        ``feature_smoothing``, ``smooth_iterations``, ``pass_band``, ``normals``,
        ``attributes``, ``support_r``, ``blobbiness``, ``radius_array``) and of
        :class:`MetaballSplat` (``iso``, ``sparse``, ``max_bytes``, ``implicit``,
        ``operation``, ``anisotropy``, ...); defaults
        :data:`pipeline.surface_options.SURFACE_DEFAULTS`.

    Returns
    -------
    pyvista.PolyData
        The triangle surface (m), with point normals and the carried arrays unless switched
        off; empty when there are no particles.

    Raises
    ------
    TypeError
        For an unknown option (the message lists the valid ones) or an input that is neither
        points nor a point dataset.
    ValueError
        For an option out of its range (named, with the range), before any work starts.

    Examples
    --------
    >>> import numpy as np
    >>> surface = reconstruct(np.random.default_rng(0).uniform(0, 0.05, (500, 3)),
    ...                       radius=0.005)                                  # doctest: +SKIP
    """
    import pyvista as pv

    names = surface_option_names()
    unknown = sorted(set(options) - set(names))
    if unknown:
        raise TypeError(f"reconstruct() has no option {unknown[0]!r}; options: "
                        f"{', '.join(n for n in names if n != 'radius')}")
    if "radius" in options:
        raise TypeError("reconstruct() got radius twice")
    stages = surface_stages(radius, **options)  # validates every option before any work
    cloud = _point_cloud(points_or_dataset)
    return pv.wrap(run_chain(stages, cloud, what="the surface reconstruction"))

