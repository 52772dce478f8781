"""Contouring implicit fields on arrays, dense boxes and brick sets: VTK's flying edges, or
marching tetrahedra (:mod:`filters.surface.tetra`).

A :class:`filters.surface.grid.SparseGrid` is contoured brick by brick in *voxel index*
coordinates, where the vertices two bricks share come out bitwise equal, and stitched by merging
those exact duplicates (:func:`filters.surface.mesh.stitch`): one watertight mesh, no cracks,
with memory bounded by the bricks that hold surface. Flying edges is Schroeder, Maynard & Geveci
(2015), "Flying edges: a high-performance scalable isocontouring algorithm"
(``vtkFlyingEdges3D``); marching tetrahedra cut every cube into the six tetrahedra of the Kuhn
split, the same in every cube, so its bricks stitch the same way. The
:class:`pipeline.surface.MarchingCubes` stage uses the same pieces.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkPoints, vtkTypeInt32Array, vtkTypeInt64Array
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkImageData, vtkPolyData
from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D

from filters.surface.grid import DEFAULT_MAX_BYTES, DenseField, SparseGrid, check_budget
from filters.surface.mesh import piece_flags, stitch
from filters.surface.tetra import contour_array, contour_grid
from filters.validation import check_choice, check_int

if TYPE_CHECKING:
    from collections.abc import Iterator, Mapping

__all__ = [
    "FIELD_NAME",
    "CONTOUR_METHODS",
    "flying_edges",
    "image_of",
    "Pieces",
    "brick_images",
    "brick_chunk",
    "check_grid_sizes",
    "contour_dense",
    "contour_sparse",
    "mesh_to_polydata",
    "polydata_to_mesh",
]

#: Name of the point array holding the implicit values in the images.
FIELD_NAME = "implicit"

#: Contouring methods: VTK's flying edges (marching cubes) or marching tetrahedra.
CONTOUR_METHODS = ("flying_edges", "tetrahedra")


def flying_edges() -> vtkFlyingEdges3D:
    """A vtkFlyingEdges3D at value 0 computing nothing but the contour."""
    fe = vtkFlyingEdges3D()
    fe.SetValue(0, 0.0)
    fe.ComputeNormalsOff()
    fe.ComputeGradientsOff()
    fe.ComputeScalarsOff()
    fe.InterpolateAttributesOff()
    return fe


def image_of(values: np.ndarray, index_origin: np.ndarray,
             deep: bool = False) -> tuple[vtkImageData, np.ndarray]:
    """vtkImageData (index units) over ``values`` (nz, ny, nx); shared unless ``deep``."""
    nz, ny, nx = values.shape
    image = vtkImageData()
    image.SetDimensions(nx, ny, nz)
    image.SetOrigin(*[float(v) for v in index_origin])
    image.SetSpacing(1.0, 1.0, 1.0)
    arr = numpy_support.numpy_to_vtk(values.reshape(-1), deep=deep)
    arr.SetName(FIELD_NAME)
    image.GetPointData().SetScalars(arr)
    return image, arr


class Pieces:
    """Collects the flying-edges output of pieces contoured in voxel-index coordinates.

    Vertices that another piece may share (on the piece's boundary planes) or that may
    coincide within the piece (all coordinates integral: a voxel exactly on the iso value) are
    flagged; :func:`filters.surface.mesh.stitch` merges those by exact coordinates."""

    def __init__(self):
        self.points, self.tris, self.lo, self.hi, self.starts = [], [], [], [], [0]
        self.count = 0

    def add(self, fe: vtkFlyingEdges3D, lo: np.ndarray, hi: np.ndarray) -> None:
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

    def mesh(self, cell_size: float) -> tuple[np.ndarray, np.ndarray]:
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


def contour_dense(field: DenseField,
                  method: str = "flying_edges") -> tuple[np.ndarray, np.ndarray]:
    """Zero level set of a dense field with vtkFlyingEdges3D or marching tetrahedra.

    Parameters
    ----------
    field : DenseField
    method : {"flying_edges", "tetrahedra"}
        Contouring method (:data:`CONTOUR_METHODS`).

    Returns
    -------
    points : (P, 3) float32
        Vertices (m).
    triangles : (T, 3) int32
        Outward-oriented triangles.
    """
    if check_choice("method", method, CONTOUR_METHODS) == "tetrahedra":
        if min(field.values.shape) < 2:
            return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32)
        return contour_array(field.values, field.index_origin, field.cell_size)
    pieces = Pieces()
    if min(field.values.shape) >= 2:
        image, _keep = image_of(field.values, field.index_origin)
        fe = flying_edges()
        fe.SetInputData(image)
        fe.Update()
        lo = np.asarray(field.index_origin, np.float64)
        pieces.add(fe, lo, lo + np.array(field.dimensions) - 1)
    return pieces.mesh(field.cell_size)


def brick_chunk(span: int, max_bytes: int, chunk: int = 16) -> int:
    """Bricks of ``span + 1`` voxels a side filled at once: at most ``chunk``, and as many as
    fit a quarter of ``max_bytes`` (at least one; :func:`check_grid_sizes` refuses a brick
    larger than that)."""
    brick = 4 * (span + 1) ** 3
    return int(max(1, min(chunk, (max_bytes // 4) // brick)))


def check_grid_sizes(radius: float, cell_size: float, kernel: str, support_r: float | None,
                     block_size: int, brick_blocks: int, max_bytes: int,
                     fixed_radius: bool = True) -> None:
    """Refuse, before any work, grid settings that cannot fit ``max_bytes`` or reach.

    A brick of ``block_size * brick_blocks + 1`` voxels a side is filled and contoured whole:
    it must fit a quarter of ``max_bytes`` (the rest is the grid's). With one radius for all
    particles (``fixed_radius``), the kernel's support ``support_r * radius`` may span at most
    64 blocks (the splat's limit), which a ``cell_size`` far below the radius exceeds.

    Raises
    ------
    ValueError
        Naming the settings and the limit.
    """
    from filters.kernels import SPLAT_DEFAULTS
    from filters.surface.grid import GridTooLargeError, format_bytes

    span = block_size * brick_blocks
    brick = 4 * (span + 1) ** 3
    if brick > max_bytes // 4:
        raise GridTooLargeError(
            f"block_size * brick_blocks = {block_size} * {brick_blocks}: a brick of {span + 1}^3 "
            f"voxels needs {format_bytes(brick)}, more than a quarter of max_bytes = "
            f"{format_bytes(max_bytes)}; lower block_size or brick_blocks")
    support = SPLAT_DEFAULTS[kernel]["support"] if support_r is None else support_r
    reach = support * radius / cell_size
    if fixed_radius and reach > 64 * block_size:
        raise ValueError(f"cell_size = {cell_size:g} m is too small for radius = {radius:g} m: "
                         f"the kernel's support would span {reach:.3g} voxels, more than "
                         f"{64 * block_size} (64 blocks of {block_size}); increase cell_size")


def brick_images(grid: SparseGrid, group: int, chunk: int = 16,
                 max_bytes: int = DEFAULT_MAX_BYTES) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Yield (index_origin, values) of each brick that holds a sign change.

    The values live in a buffer reused for every chunk of bricks: use them before the next.
    The buffer holds at most a quarter of ``max_bytes`` (:func:`brick_chunk`)."""
    bricks = grid.bricks(group)
    table = grid.block_table()
    # bricks whose blocks hold one sign only are not filled (a third of them on a 100k block)
    bricks = bricks[grid.may_cross(bricks, group, table)]
    span = group * grid.block_size
    check_budget(4 * (span + 1) ** 3, max(max_bytes // 4, 1),
                 f"one brick of {span + 1}^3 voxels (a quarter of max_bytes)")
    chunk = brick_chunk(span, max_bytes, chunk)
    buffer = np.empty((min(chunk, bricks.shape[0]),) + (span + 1,) * 3, np.float32)
    for s in range(0, bricks.shape[0], chunk):
        part = bricks[s:s + chunk]
        vals, crossing = grid.fill_bricks(part, group, table, crossing=True, out=buffer)
        for b in np.flatnonzero(crossing):
            yield part[b] * span, vals[b]


def contour_sparse(grid: SparseGrid, group: int = 4,
                   method: str = "flying_edges") -> tuple[np.ndarray, np.ndarray]:
    """Zero level set of a sparse grid: contoured per brick, stitched into one mesh.

    Bricks of ``group ** 3`` blocks overlap their neighbours by one voxel layer; each is
    contoured in voxel-index coordinates, where a vertex on a shared face is computed from the
    same two voxel values by the same arithmetic in both bricks and so is bitwise equal; those
    duplicates are merged exactly (:func:`filters.surface.mesh.stitch`).

    Parameters
    ----------
    grid : SparseGrid
    group : int
        Blocks per brick edge.
    method : {"flying_edges", "tetrahedra"}
        Contouring method (:data:`CONTOUR_METHODS`); marching tetrahedra contour a chunk of
        bricks in parallel.

    Returns
    -------
    points : (P, 3) float32
        Vertices (m).
    triangles : (T, 3) int32
        Outward-oriented triangles.
    """
    group = check_int("group", group, 1, 64)
    if check_choice("method", method, CONTOUR_METHODS) == "tetrahedra":
        return contour_grid(grid, group)
    pieces = Pieces()
    if not grid.empty:
        fe = flying_edges()
        span = group * grid.block_size
        # one image and one buffer for all bricks: only the values and the origin change
        buffer = np.empty((span + 1,) * 3, np.float32)
        image, array = image_of(buffer, (0, 0, 0))
        fe.SetInputData(image)
        for origin, values in brick_images(grid, group):
            np.copyto(buffer, values)
            image.SetOrigin(*[float(v) for v in origin])
            array.Modified()
            fe.Modified()
            fe.Update()
            pieces.add(fe, origin, origin + span)
    return pieces.mesh(grid.cell_size)


def mesh_to_polydata(points: np.ndarray, triangles: np.ndarray,
                     point_data: Mapping[str, np.ndarray] | None = None) -> vtkPolyData:
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


def polydata_to_mesh(poly: vtkPolyData) -> tuple[np.ndarray, np.ndarray]:
    """vtkPolyData of triangles -> ``(points (P, 3) float64, triangles (T, 3) int64)``."""
    if poly.GetNumberOfPoints() == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    pts = numpy_support.vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64)
    conn = numpy_support.vtk_to_numpy(poly.GetPolys().GetConnectivityArray()).astype(np.int64)
    return pts, conn.reshape(-1, 3)
