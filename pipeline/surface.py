"""Surface stages: particles -> implicit field -> triangle mesh -> smoothed mesh with normals.

Each stage is a VTK algorithm (:class:`pipeline.algorithm.Algorithm`, a
:class:`VTKPythonAlgorithmBase` whose exceptions reach the caller), so any VTK filter can sit between
two of them, and each passes time requests upstream (a temporal particle source drives them):

``MetaballSplat``
    vtkPolyData particles -> vtkImageData (``sparse=False``) or a vtkPartitionedDataSet of
    image *bricks* (``sparse=True``, default) holding the implicit value ``implicit`` (negative
    inside) computed by :mod:`filters.surface.splat`. The particles' positions and chosen point arrays
    ride along as field data so that the contour can carry them to the surface.
``MarchingCubes``
    vtkFlyingEdges3D at ``value`` (0 for our fields). A brick set is contoured brick by brick in
    *voxel index* coordinates, where the vertices two bricks share come out bitwise equal, and
    stitched by merging those exact duplicates: one watertight mesh, no cracks, with memory
    bounded by the bricks that hold surface. Particle arrays (e.g. ``velocity``) are
    interpolated onto the vertices with the splatting kernel (Shepard weights).
``Smooth``
    vtkWindowedSincPolyDataFilter (Taubin, Zhang & Golub 1996), whose low-pass filter does not
    shrink the surface the way Laplacian smoothing does.
``Normals``
    vtkPolyDataNormals without splitting (the mesh stays watertight).

:func:`surface_stages` builds the chain for ``flow.add("surface", *surface_stages(...))``.
"""

from __future__ import annotations

import math

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkPoints, vtkTypeInt32Array, vtkTypeInt64Array
from vtkmodules.vtkCommonDataModel import (
    vtkCellArray,
    vtkDataObject,
    vtkImageData,
    vtkPartitionedDataSet,
    vtkPointSet,
    vtkPolyData,
)
from vtkmodules.vtkFiltersCore import (
    vtkFlyingEdges3D,
    vtkPolyDataNormals,
    vtkWindowedSincPolyDataFilter,
)

from .algorithm import Algorithm
from filters.surface.grid import DEFAULT_MAX_BYTES, DenseField, SparseGrid
from filters.surface.smoothing import smooth_surface
from filters.kernels import SPLAT_KERNELS as KERNELS
from filters.surface.attributes import interpolate_attributes
from filters.surface.splat import splat_dense, splat_sparse
from filters.surface.mesh import piece_flags, stitch
from filters.validation import check_bool, check_choice, check_int, check_range

__all__ = [
    "MetaballSplat",
    "MarchingCubes",
    "Smooth",
    "Normals",
    "surface_stages",
    "contour_dense",
    "contour_sparse",
    "mesh_to_polydata",
    "polydata_to_mesh",
]

_FIELD = "implicit"
_PREFIX = "particles:"


# --------------------------------------------------------------------------------------------
# Array-level contouring
# --------------------------------------------------------------------------------------------


def _flying_edges():
    fe = vtkFlyingEdges3D()
    fe.SetValue(0, 0.0)
    fe.ComputeNormalsOff()
    fe.ComputeGradientsOff()
    fe.ComputeScalarsOff()
    fe.InterpolateAttributesOff()
    return fe


def _image(values, index_origin, deep=False):
    """vtkImageData (index units) over ``values`` (nz, ny, nx); shared unless ``deep``."""
    nz, ny, nx = values.shape
    image = vtkImageData()
    image.SetDimensions(nx, ny, nz)
    image.SetOrigin(*[float(v) for v in index_origin])
    image.SetSpacing(1.0, 1.0, 1.0)
    arr = numpy_support.numpy_to_vtk(values.reshape(-1), deep=deep)
    arr.SetName(_FIELD)
    image.GetPointData().SetScalars(arr)
    return image, arr


class _Pieces:
    """Collects flying-edges output of pieces contoured in voxel-index coordinates.

    Vertices that another piece may share (on the piece's boundary planes) or that may
    coincide within the piece (all coordinates integral: a voxel exactly on the iso value) are
    flagged; :func:`filters.surface.mesh.stitch` merges those by exact coordinates."""

    def __init__(self):
        self.points, self.tris, self.lo, self.hi, self.starts = [], [], [], [], [0]
        self.count = 0

    def add(self, fe, lo, hi):
        out = fe.GetOutput()
        n = out.GetNumberOfPoints()
        if n == 0 or out.GetNumberOfPolys() == 0:
            return
        pts = numpy_support.vtk_to_numpy(out.GetPoints().GetData())
        self.points.append(np.array(pts, dtype=np.float32))  # a copy: fe's output is reused
        conn = numpy_support.vtk_to_numpy(out.GetPolys().GetConnectivityArray())
        dtype = np.int32 if self.count + n < 2**31 else np.int64
        tris = np.empty((conn.size // 3, 3), dtype)
        np.add(conn.reshape(-1, 3), self.count, out=tris, casting="unsafe")
        self.tris.append(tris)
        self.lo.append(lo)
        self.hi.append(hi)
        self.count += n
        self.starts.append(self.count)

    def mesh(self, cell_size):
        if not self.points:
            return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32)
        pts = np.concatenate(self.points)
        self.points = []
        flags = piece_flags(pts, np.array(self.starts, np.int64),
                            np.array(self.lo, np.float32).reshape(-1, 3),
                            np.array(self.hi, np.float32).reshape(-1, 3))
        dtype = np.int64 if any(t.dtype == np.int64 for t in self.tris) else np.int32
        tris = np.concatenate(self.tris).astype(dtype, copy=False)
        self.tris = []
        # flying edges orients the triangles of a negative-inside field inward: stitch()
        # reverses them, so that the normals point out (positive enclosed volume)
        pts, tris = stitch(pts, tris, flags, reverse=True)
        pts *= np.float32(cell_size)
        return pts, tris


def contour_dense(field: DenseField):
    """Zero level set of a dense field with vtkFlyingEdges3D.

    Parameters
    ----------
    field : DenseField

    Returns
    -------
    points : (P, 3) float32
        Vertices (m).
    triangles : (T, 3) int32
        Outward-oriented triangles.
    """
    pieces = _Pieces()
    if min(field.values.shape) >= 2:
        image, _keep = _image(field.values, field.index_origin)
        fe = _flying_edges()
        fe.SetInputData(image)
        fe.Update()
        lo = np.asarray(field.index_origin, np.float64)
        pieces.add(fe, lo, lo + np.array(field.dimensions) - 1)
    return pieces.mesh(field.cell_size)


def _brick_images(grid: SparseGrid, group: int, chunk: int = 16):
    """Yield (index_origin, values) of each brick that holds a sign change.

    The values live in a buffer reused for every chunk of bricks: use them before the next."""
    bricks = grid.bricks(group)
    table = grid.block_table()
    span = group * grid.block_size
    buffer = np.empty((min(chunk, bricks.shape[0]),) + (span + 1,) * 3, np.float32)
    for s in range(0, bricks.shape[0], chunk):
        part = bricks[s:s + chunk]
        vals, crossing = grid.fill_bricks(part, group, table, crossing=True, out=buffer)
        for b in np.flatnonzero(crossing):
            yield part[b] * span, vals[b]


def contour_sparse(grid: SparseGrid, group: int = 4):
    """Zero level set of a sparse grid: flying edges per brick, stitched into one mesh.

    Bricks of ``group ** 3`` blocks overlap their neighbours by one voxel layer; each is
    contoured in voxel-index coordinates, where a vertex on a shared face is computed from the
    same two voxel values by the same arithmetic in both bricks and so is bitwise equal; those
    duplicates are merged exactly (:func:`filters.surface.mesh.stitch`).

    Parameters
    ----------
    grid : SparseGrid
    group : int
        Blocks per brick edge.

    Returns
    -------
    points : (P, 3) float32
        Vertices (m).
    triangles : (T, 3) int32
        Outward-oriented triangles.
    """
    group = check_int("group", group, 1, 64)
    pieces = _Pieces()
    if not grid.empty:
        fe = _flying_edges()
        span = group * grid.block_size
        # one image and one buffer for all bricks: only the values and the origin change
        buffer = np.empty((span + 1,) * 3, np.float32)
        image, array = _image(buffer, (0, 0, 0))
        fe.SetInputData(image)
        for origin, values in _brick_images(grid, group):
            np.copyto(buffer, values)
            image.SetOrigin(*[float(v) for v in origin])
            array.Modified()
            fe.Modified()
            fe.Update()
            pieces.add(fe, origin, origin + span)
    return pieces.mesh(grid.cell_size)


def mesh_to_polydata(points, triangles, point_data=None) -> vtkPolyData:
    """Arrays -> vtkPolyData with triangle cells (always valid, also when empty).

    Parameters
    ----------
    points : (P, 3) float array
        Vertices (m), copied (as float32) into the polydata.
    triangles : (T, 3) int array
        Vertex indices; stored with 32-bit cell storage when they fit.
    point_data : dict of str -> (P,) or (P, k) array, optional
    """
    poly = vtkPolyData()
    vpts = vtkPoints()
    pts = np.ascontiguousarray(points, dtype=np.float32).reshape(-1, 3)
    vpts.SetData(numpy_support.numpy_to_vtk(pts, deep=True))
    poly.SetPoints(vpts)
    tris = np.asarray(triangles).reshape(-1, 3)
    small = pts.shape[0] < 2**31 - 1 and 3 * tris.shape[0] < 2**31 - 1
    kind = (vtkTypeInt32Array if small else vtkTypeInt64Array)
    dtype = np.int32 if small else np.int64
    offsets, conn = kind(), kind()
    offsets.SetNumberOfTuples(tris.shape[0] + 1)
    conn.SetNumberOfTuples(3 * tris.shape[0])
    numpy_support.vtk_to_numpy(offsets)[:] = np.arange(0, 3 * tris.shape[0] + 1, 3, dtype=dtype)
    if tris.shape[0]:
        numpy_support.vtk_to_numpy(conn)[:] = tris.reshape(-1)
    cells = vtkCellArray()
    cells.SetData(offsets, conn)
    poly.SetPolys(cells)
    for name, values in (point_data or {}).items():
        arr = numpy_support.numpy_to_vtk(np.ascontiguousarray(values), deep=True)
        arr.SetName(name)
        poly.GetPointData().AddArray(arr)
    return poly


def polydata_to_mesh(poly: vtkPolyData):
    """vtkPolyData of triangles -> ``(points (P, 3) float64, triangles (T, 3) int64)``."""
    if poly.GetNumberOfPoints() == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    pts = numpy_support.vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64)
    conn = numpy_support.vtk_to_numpy(poly.GetPolys().GetConnectivityArray()).astype(np.int64)
    return pts, conn.reshape(-1, 3)


# --------------------------------------------------------------------------------------------
# Algorithms
# --------------------------------------------------------------------------------------------


def _particles_from(inp):
    n = inp.GetNumberOfPoints()
    if n == 0:
        return np.zeros((0, 3))
    return numpy_support.vtk_to_numpy(inp.GetPoints().GetData()).astype(np.float64)


class MetaballSplat(Algorithm):
    """Particles (vtkPolyData / any vtkPointSet) -> implicit field on a voxel lattice.

    Parameters
    ----------
    radius : float
        Particle radius (m), used where the input has no ``radius_array``.
    cell_size : float, optional
        Voxel edge (m); default ``radius / 2`` (splashsurf's cube size 0.5).
    kernel : {"blobby", "metaball", "sph", "zhu_bridson"}
        See :mod:`filters.surface.splat`.
    support_r, iso, blobbiness
        See :func:`filters.surface.splat.splat_sparse`.
    radius_array : str, optional
        Point array holding per-particle radii (m).
    sparse : bool
        True: a vtkPartitionedDataSet of image bricks covering the surface (memory follows the
        surface); False: one vtkImageData over the whole reachable box.
    block_size, brick_blocks : int
        Voxels per block edge; blocks per brick edge (sparse output).
    attributes : sequence of str
        Point arrays of the particles to carry to the surface (missing ones are ignored).
    max_bytes : int
        Memory budget (bytes) of the grid.
    implicit : callable, optional
        A :mod:`filters.surface.csg` shape combined with the particle field by ``operation``.
    operation : {"union", "intersection", "difference"}
        How ``implicit`` combines with the particles' field.
    anisotropic : bool
        Splat ellipsoidal kernels stretched along the local particle distribution (Yu & Turk
        2013, :mod:`filters.surface.anisotropy`): flat water without bumps and sharper edges, about
        1.35x the reconstruction time; drops of a few particles come out larger
        (``benchmarks/bench_anisotropy.py``). Kernels ``sph``,
        ``metaball`` and ``blobby``.
    anisotropy : dict, optional
        Options of :func:`filters.surface.anisotropy.anisotropic_kernels` (``stretch``,
        ``min_neighbors``, ``smoothing``, ``neighbor_factor``, ``layer_band``, ``max_axis``,
        ``isotropy``).
    """

    def __init__(self, radius: float = 0.01, cell_size: float | None = None, *,
                 kernel: str = "sph", support_r=None, iso=None, blobbiness: float = 4.0,
                 radius_array: str | None = None, sparse: bool = True, block_size: int = 8,
                 brick_blocks: int = 4, attributes=("velocity",),
                 max_bytes: int = DEFAULT_MAX_BYTES, implicit=None,
                 operation: str = "intersection", anisotropic: bool = False,
                 anisotropy: dict | None = None):
        from filters.surface.ellipsoids import ANISOTROPIC_KERNELS

        self.anisotropic = check_bool("anisotropic", anisotropic)
        if self.anisotropic and kernel not in ANISOTROPIC_KERNELS:
            raise ValueError(f"kernel must be one of {', '.join(map(repr, ANISOTROPIC_KERNELS))} "
                             f"when anisotropic=True, got {kernel!r}")
        self.anisotropy = dict(anisotropy or {})
        self.radius = check_range("radius", radius, 0.0, math.inf, low_inclusive=False)
        self.cell_size = (self.radius / 2 if cell_size is None else
                          check_range("cell_size", cell_size, 0.0, math.inf, low_inclusive=False))
        self.kernel = check_choice("kernel", kernel, KERNELS)
        self.support_r = support_r
        self.iso = iso
        self.blobbiness = blobbiness
        self.radius_array = radius_array
        self.sparse = bool(sparse)
        self.block_size = check_int("block_size", block_size, 4, 64)
        self.brick_blocks = check_int("brick_blocks", brick_blocks, 1, 64)
        self.attributes = tuple(attributes)
        self.max_bytes = check_int("max_bytes", max_bytes, 1)
        self.implicit = implicit
        self.operation = check_choice("operation", operation,
                                      ("union", "intersection", "difference"))
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
            from filters.surface.splat import splat_dense_anisotropic, splat_sparse_anisotropic

            return splat_sparse_anisotropic if sparse else splat_dense_anisotropic
        return splat_sparse if sparse else splat_dense

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkPointSet.GetData(inInfo[0], 0)
        positions = _particles_from(inp)
        radius = self.radius
        if self.radius_array and positions.shape[0]:
            arr = inp.GetPointData().GetArray(self.radius_array)
            if arr is None:
                raise ValueError(f"radius_array {self.radius_array!r} is not a point array of "
                                 f"the input")
            radius = numpy_support.vtk_to_numpy(arr).astype(np.float64).reshape(-1)
        if self.implicit is not None:
            from filters.surface.csg import combine_dense, combine_sparse
        if self.sparse:
            grid = self._splat(True)(positions, radius, self.cell_size, **self._options())
            if self.implicit is not None:
                grid = combine_sparse(grid, self.implicit, self.operation,
                                      max_bytes=self.max_bytes)
            out = vtkPartitionedDataSet.GetData(outInfo, 0)
            out.Initialize()
            k = 0
            for origin, values in _brick_images(grid, self.brick_blocks):
                # deep copies: the output outlives this call and the reused buffer
                image, _keep = _image(values, origin, deep=True)
                image.SetOrigin(*(origin.astype(np.float64) * grid.cell_size))
                image.SetSpacing(grid.cell_size, grid.cell_size, grid.cell_size)
                out.SetPartition(k, image)
                k += 1
            cell = grid.cell_size
        else:
            field = self._splat(False)(positions, radius, self.cell_size, **self._options())
            if self.implicit is not None:
                field = combine_dense(field, self.implicit, self.operation)
            out = vtkImageData.GetData(outInfo, 0)
            image, _keep = _image(np.ascontiguousarray(field.values), field.index_origin,
                                  deep=True)
            out.ShallowCopy(image)
            out.SetOrigin(*field.origin)
            out.SetSpacing(field.cell_size, field.cell_size, field.cell_size)
            cell = field.cell_size
        _attach_particles(out, inp, positions, radius, cell, self)
        return 1


def _attach_particles(out, inp, positions, radius, cell, splat):
    fd = out.GetFieldData()
    arrays = {"positions": positions,
              "radius": np.broadcast_to(np.asarray(radius, np.float64),
                                        (positions.shape[0],)).copy(),
              "settings": np.array([cell, KERNELS.index(splat.kernel),
                                    np.nan if splat.support_r is None else splat.support_r,
                                    splat.blobbiness])}
    if positions.shape[0]:
        for name in splat.attributes:
            arr = inp.GetPointData().GetArray(name)
            if arr is not None:
                arrays["attr:" + name] = numpy_support.vtk_to_numpy(arr)
    for name, values in arrays.items():
        arr = numpy_support.numpy_to_vtk(np.ascontiguousarray(values), deep=True)
        arr.SetName(_PREFIX + name)
        fd.AddArray(arr)


class MarchingCubes(Algorithm):
    """Implicit field (vtkImageData or a brick set) -> one watertight vtkPolyData.

    Parameters
    ----------
    value : float
        Contour value (0 for :class:`MetaballSplat` output: negative inside).
    interpolate : bool
        Interpolate the particle arrays carried by :class:`MetaballSplat` onto the vertices.
    feature_smoothing : int
        Sweeps of feature-weighted Laplacian smoothing (Löschner et al. 2023,
        :func:`filters.surface.smoothing.smooth_surface`) applied to the contour before the
        attributes are interpolated, in [0, 10000]; 0 (default) leaves the contour as is. The
        weights come from the particles :class:`MetaballSplat` carries: flat liquid is smoothed
        fully, sheets and droplets of a few particles are left alone. Needs
        :class:`MetaballSplat` input (the particles); plain images raise ``ValueError``.
    """

    def __init__(self, value: float = 0.0, *, interpolate: bool = True,
                 feature_smoothing: int = 0):
        self.value = check_range("value", value)
        self.interpolate = check_bool("interpolate", interpolate)
        self.feature_smoothing = check_int("feature_smoothing", feature_smoothing, 0, 10000)
        Algorithm.__init__(self, nInputPorts=1, inputType="vtkDataObject", nOutputPorts=1,
                           outputType="vtkPolyData")

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkDataObject.GetData(inInfo[0], 0)
        pts, tris = self._contour(inp)
        if self.feature_smoothing and pts.shape[0]:
            pts = self._smooth(inp, pts, tris)
        poly = mesh_to_polydata(pts, tris, self._attributes(inp, pts))
        vtkPolyData.GetData(outInfo, 0).ShallowCopy(poly)
        return 1

    def _contour(self, inp):
        images = []
        if isinstance(inp, vtkImageData):
            images = [inp]
        elif isinstance(inp, vtkPartitionedDataSet):
            images = [inp.GetPartition(i) for i in range(inp.GetNumberOfPartitions())]
            images = [im for im in images if im is not None]
        else:
            raise TypeError(f"MarchingCubes needs vtkImageData or vtkPartitionedDataSet input, "
                            f"got {inp.GetClassName()}")
        fe = _flying_edges()
        fe.SetValue(0, self.value)
        pieces = _Pieces()
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

    def _smooth(self, inp, pts, tris):
        fd = inp.GetFieldData()
        if fd is None or fd.GetArray(_PREFIX + "positions") is None:
            raise ValueError("MarchingCubes(feature_smoothing=...) needs the particles that "
                             "MetaballSplat carries; its input has none")
        positions = numpy_support.vtk_to_numpy(fd.GetArray(_PREFIX + "positions")).reshape(-1, 3)
        radius = numpy_support.vtk_to_numpy(fd.GetArray(_PREFIX + "radius"))
        # per-particle radii: the largest sets the spacing the fullness is measured against
        r = float(radius.max()) if radius.size else 1.0
        smoothed = smooth_surface(pts.astype(np.float64), tris,
                                  np.ascontiguousarray(positions, np.float64), r,
                                  iterations=self.feature_smoothing)
        return smoothed.astype(pts.dtype)

    def _attributes(self, inp, pts):
        fd = inp.GetFieldData()
        if not self.interpolate or fd is None or fd.GetArray(_PREFIX + "positions") is None:
            return {}
        get = lambda name: numpy_support.vtk_to_numpy(fd.GetArray(_PREFIX + name))  # noqa: E731
        names = [fd.GetArrayName(i) for i in range(fd.GetNumberOfArrays())]
        attrs = [n[len(_PREFIX) + 5:] for n in names if n and n.startswith(_PREFIX + "attr:")]
        if not attrs:
            return {}
        positions = get("positions").reshape(-1, 3)
        radius = get("radius")
        cell, kid, support, blob = get("settings")
        values = [get("attr:" + name).astype(np.float64) for name in attrs]
        columns = [v.reshape(v.shape[0], -1) for v in values]
        if positions.shape[0] == 0 or pts.shape[0] == 0:
            return {name: np.zeros((pts.shape[0],) + v.shape[1:], np.float64)
                    for name, v in zip(attrs, values)}
        # all attributes in one pass: the same kernel weights serve every column
        stacked = interpolate_attributes(
            pts.astype(np.float64), positions, radius, np.concatenate(columns, axis=1),
            cell_size=float(cell), kernel=KERNELS[int(kid)],
            support_r=None if np.isnan(support) else float(support), blobbiness=float(blob))
        out, start = {}, 0
        for name, v, c in zip(attrs, values, columns):
            part = stacked[:, start:start + c.shape[1]]
            out[name] = np.ascontiguousarray(part).reshape((pts.shape[0],) + v.shape[1:])
            start += c.shape[1]
        return out


class Smooth(Algorithm):
    """Windowed-sinc smoothing (Taubin, Zhang & Golub 1996) that keeps the enclosed volume.

    Parameters
    ----------
    iterations : int
        Filter degree (number of iterations).
    pass_band : float
        In (0, 2); lower smooths more. The defaults (100, 0.001) remove the particle-scale
        bumps of a lattice-filled ball (area within 1 % of the sphere's) while moving its
        enclosed volume by less than 0.1 %.
    """

    def __init__(self, iterations: int = 100, pass_band: float = 0.001):
        self.iterations = check_int("iterations", iterations, 0, 1000)
        self.pass_band = check_range("pass_band", pass_band, 0.0, 2.0, low_inclusive=False)
        Algorithm.__init__(self, nInputPorts=1, inputType="vtkPolyData", nOutputPorts=1,
                           outputType="vtkPolyData")

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkPolyData.GetData(inInfo[0], 0)
        out = vtkPolyData.GetData(outInfo, 0)
        if inp.GetNumberOfPolys() == 0 or self.iterations == 0:
            out.ShallowCopy(inp)
            return 1
        f = vtkWindowedSincPolyDataFilter()
        f.SetInputData(inp)
        f.SetNumberOfIterations(self.iterations)
        f.SetPassBand(self.pass_band)
        f.NormalizeCoordinatesOn()
        f.BoundarySmoothingOff()
        f.FeatureEdgeSmoothingOff()
        f.NonManifoldSmoothingOn()
        f.Update()
        out.ShallowCopy(f.GetOutput())
        return 1


class Normals(Algorithm):
    """Point normals (vtkPolyDataNormals) without splitting sharp edges (stays watertight)."""

    def __init__(self):
        Algorithm.__init__(self, nInputPorts=1, inputType="vtkPolyData", nOutputPorts=1,
                           outputType="vtkPolyData")

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkPolyData.GetData(inInfo[0], 0)
        out = vtkPolyData.GetData(outInfo, 0)
        if inp.GetNumberOfPolys() == 0:
            out.ShallowCopy(inp)
            return 1
        f = vtkPolyDataNormals()
        f.SetInputData(inp)
        f.SplittingOff()
        f.ConsistencyOff()
        f.AutoOrientNormalsOff()
        f.ComputePointNormalsOn()
        f.ComputeCellNormalsOff()
        f.Update()
        out.ShallowCopy(f.GetOutput())
        return 1


def surface_stages(radius: float = 0.01, cell_size: float | None = None, *,
                   kernel: str = "sph", smooth_iterations: int = 100, pass_band: float = 0.001,
                   feature_smoothing: int = 0, normals: bool = True, **splat_options) -> list:
    """The chain particles -> surface as a list of algorithms.

    ``flow.add("surface", *surface_stages(radius=0.01), input="particles")``.

    Parameters
    ----------
    radius : float
        Particle radius (m).
    cell_size : float, optional
        Voxel edge (m); default ``radius / 2``.
    kernel : str
        Splatting kernel (see :mod:`filters.surface.splat`).
    smooth_iterations : int
        Windowed-sinc iterations; 0 leaves the marching-cubes mesh as is.
    pass_band : float
        Windowed-sinc pass band.
    feature_smoothing : int
        Sweeps of feature-weighted Laplacian smoothing in :class:`MarchingCubes` (0: none).
    normals : bool
        Append a :class:`Normals` stage.
    **splat_options
        Further keyword arguments of :class:`MetaballSplat` (``support_r``, ``iso``, ``sparse``,
        ``attributes``, ``max_bytes``, ``implicit``, ``operation``, ...).

    Returns
    -------
    list of Algorithm
    """
    stages = [MetaballSplat(radius, cell_size, kernel=kernel, **splat_options),
              MarchingCubes(feature_smoothing=feature_smoothing)]
    if smooth_iterations:
        stages.append(Smooth(smooth_iterations, pass_band))
    if normals:
        stages.append(Normals())
    return stages
