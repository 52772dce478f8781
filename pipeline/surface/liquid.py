"""Stages of a liquid's surface in its tank: the surface cut exactly at the tank's walls
(:class:`ClipBox`) and every piece of it enclosing the volume of its particles
(:class:`VolumeCorrection`, :func:`filters.surface.correction.correct_volume`); and what a
surface is, written into it (:class:`SurfaceKind`, read back by :func:`dataset_kind`): a
liquid's surface is drawn as water whatever its series is called."""

from __future__ import annotations

import math

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkPoints, vtkStringArray
from vtkmodules.vtkCommonDataModel import (
    vtkCellArray,
    vtkDataObject,
    vtkFieldData,
    vtkPointSet,
    vtkPolyData,
)
from vtkmodules.vtkFiltersGeneral import vtkContourTriangulator

from filters.geometry import Box, Shape
from filters.surface.clip import cap_loops, clip_half_space, refill_runs
from filters.surface.correction import correct_volume
from filters.validation import check_range

from ..algorithm import Algorithm, ParticleStage
from .contour import mesh_to_polydata

__all__ = ["ClipBox", "VolumeCorrection", "SurfaceKind", "dataset_kind", "KIND_ARRAY",
           "LIQUID_SURFACE", "PARTICLE_SURFACE"]

#: Field-data array (a string array of one value) that says what a dataset is.
KIND_ARRAY = "blobflow_kind"
#: The surface of a liquid's particles (``liquid=True``): drawn as water.
LIQUID_SURFACE = "liquid_surface"
#: The surface of any other particles (a point cloud, smoke): drawn as a solid.
PARTICLE_SURFACE = "particle_surface"
_KINDS = (LIQUID_SURFACE, PARTICLE_SURFACE)


class ClipBox(Algorithm):
    """Cut a closed surface at the six planes of a box and close it with the cut faces.

    For the field of a liquid whose particles are mirrored across the walls of its tank
    (:class:`pipeline.surface.MetaballSplat` with ``mirror_walls``), which goes on beyond the
    walls: the surface is cut exactly at the walls' planes, one after the other
    (:func:`filters.surface.clip.clip_half_space`), and each cut is closed by a flat face
    triangulated by vtkContourTriangulator, so the surface meets the walls, their edges and
    corners without the rounding and the sub-voxel shifts that sampling a crease of the field
    on the voxel lattice gives. Point data are interpolated at the cuts.

    Parameters
    ----------
    box : filters.geometry.Box
        The region kept (the tank's inner box, m).
    tolerance : float
        Vertices closer than this to a wall (m) are put on it first, >= 0.
    """

    def __init__(self, box: Box, tolerance: float = 0.0):
        if not isinstance(box, Box):
            raise TypeError(f"box must be a filters.geometry.Box, got {type(box).__name__}")
        self.box = box
        self.tolerance = check_range("tolerance", tolerance, 0.0, math.inf)
        Algorithm.__init__(self, nInputPorts=1, inputType="vtkPolyData", nOutputPorts=1,
                           outputType="vtkPolyData")

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkPolyData.GetData(inInfo[0], 0)
        out = vtkPolyData.GetData(outInfo, 0)
        if inp.GetNumberOfPolys() == 0:
            out.ShallowCopy(inp)
            return 1
        pts = numpy_support.vtk_to_numpy(inp.GetPoints().GetData()).astype(np.float64)
        tris = numpy_support.vtk_to_numpy(inp.GetPolys().GetConnectivityArray()).reshape(-1, 3)
        pd = inp.GetPointData()
        arrays = [pd.GetArray(k) for k in range(pd.GetNumberOfArrays())]
        arrays = [a for a in arrays if a is not None]
        columns = [numpy_support.vtk_to_numpy(a).reshape(pts.shape[0], -1) for a in arrays]
        data = (np.concatenate(columns, axis=1).astype(np.float64) if columns else None)
        tris = tris.astype(np.int64)
        for axis in range(3):
            for value, keep in ((self.box.lower[axis], 1), (self.box.upper[axis], -1)):
                pts, tris, data, cap = clip_half_space(pts, tris, axis, value, keep, data=data,
                                                       eps=self.tolerance)
                if cap.size:
                    normal = [0.0, 0.0, 0.0]
                    normal[axis] = -float(keep)
                    tris = np.concatenate([tris, _cap(pts, cap, normal, axis, self.box,
                                                      self.tolerance ** 2)])
        # drop the vertices no triangle uses
        used = np.zeros(pts.shape[0], bool)
        used[tris.ravel()] = True
        index = np.cumsum(used) - 1
        pts, tris = pts[used], index[tris]
        poly = mesh_to_polydata(pts, tris)
        start = 0
        for array, column in zip(arrays, columns, strict=False):
            width = column.shape[1]
            values = data[used, start:start + width].astype(column.dtype)
            start += width
            vtk_array = numpy_support.numpy_to_vtk(
                np.ascontiguousarray(values.reshape((-1,) if width == 1 and
                                                    array.GetNumberOfComponents() == 1
                                                    else (-1, width))), deep=True)
            vtk_array.SetName(array.GetName())
            poly.GetPointData().AddArray(vtk_array)
        out.ShallowCopy(poly)
        return 1


def _cap(points, edges, normal, axis, box, tiny):
    """Triangles (indices into ``points``) filling the loops of directed ``edges`` on the wall
    normal to ``axis``, facing ``normal``: the runs of points along the box's edges are reduced
    to their ends (:func:`filters.surface.clip.cap_loops`), the loops triangulated, the runs put
    back as fans (:func:`filters.surface.clip.refill_runs`). Loops of an area below ``tiny``
    (m^2; slivers where the surface grazes the wall) are closed by fans; if the triangulation
    of the others fails (loops that touch), each loop is closed by a fan from its first point:
    still closed, the holes' fans facing the other way (the enclosed volume stays exact)."""
    loops, runs = cap_loops(points, edges, axis, box.lower, box.upper)
    others = [a for a in range(3) if a != axis]
    areas = np.array([_area(points[loop][:, others]) for loop in loops])
    sliver = np.abs(areas) < tiny
    fans = [_fan(loop) for loop, s in zip(loops, sliver, strict=False) if s]
    rest = [loop for loop, s in zip(loops, sliver, strict=False) if not s]
    if rest:
        simple = np.concatenate([np.stack([loop, np.roll(loop, -1)], axis=1) for loop in rest])
        filled = _triangulate(points, simple, normal)
        if filled is None:
            filled = np.concatenate([_fan(loop) for loop in rest])
        fans.append(filled)
    return refill_runs(np.concatenate(fans), runs)


def _area(q):
    """Signed area of a closed 2-D polygon ``q`` (L, 2)."""
    x, y = q[:, 0], q[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _fan(loop):
    """A fan of triangles from the first point of a loop, oriented with it."""
    loop = np.asarray(loop, np.int64)
    return np.stack([np.full(loop.size - 2, loop[0]), loop[1:-1], loop[2:]], axis=1)


def _triangulate(points, edges, normal):
    """Triangles (indices into ``points``) filling the loops of directed ``edges`` on a plane,
    facing ``normal`` (vtkContourTriangulator: loops with holes); None if it fails."""
    ids = np.unique(edges)
    local = np.searchsorted(ids, edges)
    contour = vtkPolyData()
    vtk_points = vtkPoints()
    vtk_points.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(points[ids]), deep=True))
    contour.SetPoints(vtk_points)
    lines = vtkCellArray()
    lines.SetData(numpy_support.numpy_to_vtkIdTypeArray(
        np.arange(0, 2 * len(local) + 1, 2, dtype=np.int64), deep=True),
        numpy_support.numpy_to_vtkIdTypeArray(np.ascontiguousarray(local.ravel()), deep=True))
    contour.SetLines(lines)
    polys = vtkCellArray()
    ok = vtkContourTriangulator.TriangulateContours(contour, 0, len(local), polys, normal)
    if not ok:
        return None
    conn = numpy_support.vtk_to_numpy(polys.GetConnectivityArray()).reshape(-1, 3)
    return ids[conn].astype(np.int64)


class VolumeCorrection(ParticleStage):
    """Offset every closed piece of a surface along its normals until it encloses the volume of
    the particles inside it.

    Input port 0: the closed triangle mesh (outward normals); port 1: the particles, each of
    volume ``(2 r)^3`` (the lattice cell of a liquid of spacing ``2 r``). Point data are kept;
    vertices move, triangles do not change. With a ``container`` (the region the liquid is
    confined to, negative inside: the tank's inner box) the vertices on its walls slide along
    them and none ends outside.

    Parameters
    ----------
    radius : float
        Particle radius ``r`` (m), > 0, where the particles have no ``radius_array``.
    radius_array : str, optional
        Point array of the particles holding their radii (m).
    container : filters.geometry.Shape, optional
        Region of the liquid.
    cell_size : float, optional
        Voxel edge of the surface (m), > 0; vertices within half of it of the container's
        boundary count as on the wall. Default ``radius / 2``.
    max_offset_r : float
        Largest outward offset of a piece over ``r``, in [0, 100] (a pool whose particles the
        solver packs closer to the walls than half a spacing needs a fraction of ``r``).
    max_shrink_r : float
        Largest inward offset over ``r``, in [0, 100]: a drop of anisotropic kernels 3
        spacings in radius needs 0.23; a splash encloses more than its particles (the field
        fills the gaps between them), and shrinking it further would eat its thin sheets.
    """

    def __init__(self, *, radius: float = 0.01, radius_array: str | None = None,
                 container: Shape | None = None, cell_size: float | None = None,
                 max_offset_r: float = 1.0, max_shrink_r: float = 0.3):
        self.radius = check_range("radius", radius, 0.0, math.inf, low_inclusive=False)
        if radius_array is not None and not (isinstance(radius_array, str) and radius_array):
            raise TypeError(f"radius_array must be a point array name or None, got "
                            f"{radius_array!r}")
        self.radius_array = radius_array
        if container is not None and not isinstance(container, Shape):
            raise TypeError(f"container must be a filters.geometry.Shape or None, got "
                            f"{type(container).__name__}")
        self.container = container
        self.cell_size = (self.radius / 2 if cell_size is None else
                          check_range("cell_size", cell_size, 0.0, math.inf,
                                      low_inclusive=False))
        self.max_offset_r = check_range("max_offset_r", max_offset_r, 0.0, 100.0)
        self.max_shrink_r = check_range("max_shrink_r", max_shrink_r, 0.0, 100.0)
        ParticleStage.__init__(self)

    def RequestData(self, request, inInfo, outInfo):
        mesh = vtkPolyData.GetData(inInfo[0], 0)
        out = vtkPolyData.GetData(outInfo, 0)
        out.ShallowCopy(mesh)
        particles = vtkPointSet.GetData(inInfo[1], 0)
        if mesh.GetNumberOfPolys() == 0 or particles.GetNumberOfPoints() == 0:
            return 1
        positions = numpy_support.vtk_to_numpy(particles.GetPoints().GetData()).astype(
            np.float64)
        radius = self.radius
        if self.radius_array:
            arr = particles.GetPointData().GetArray(self.radius_array)
            if arr is None:
                raise ValueError(f"radius_array {self.radius_array!r} is not a point array of "
                                 f"the particles")
            radius = numpy_support.vtk_to_numpy(arr).astype(np.float64).reshape(-1)
        pts = numpy_support.vtk_to_numpy(mesh.GetPoints().GetData())
        tris = numpy_support.vtk_to_numpy(mesh.GetPolys().GetConnectivityArray()).reshape(-1, 3)
        rmax = float(np.max(radius))
        moved, _ = correct_volume(pts.astype(np.float64), tris, positions,
                                  (2.0 * np.asarray(radius, np.float64)) ** 3,
                                  shape=self.container, wall_band=0.5 * self.cell_size,
                                  max_offset=self.max_offset_r * rmax,
                                  max_shrink=self.max_shrink_r * rmax)
        points = vtkPoints()
        points.SetData(numpy_support.numpy_to_vtk(
            np.ascontiguousarray(moved.astype(pts.dtype)), deep=True))
        out.SetPoints(points)
        return 1


class SurfaceKind(Algorithm):
    """Write what a surface is into its field data: ``blobflow_kind`` = ``kind``.

    The last stage of :func:`pipeline.surface.surface_stages`; the series, ParaView and the
    renderer (:mod:`pipeline.render.renderer`) read it back (:func:`dataset_kind`). Everything else
    passes unchanged (shallow copies).

    Parameters
    ----------
    kind : {"liquid_surface", "particle_surface"}
        :data:`LIQUID_SURFACE` or :data:`PARTICLE_SURFACE`.
    """

    def __init__(self, kind: str):
        if kind not in _KINDS:
            raise ValueError(f"kind must be one of {', '.join(map(repr, _KINDS))}, got {kind!r}")
        self.kind = kind
        Algorithm.__init__(self, nInputPorts=1, inputType="vtkPolyData", nOutputPorts=1,
                           outputType="vtkPolyData")

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkPolyData.GetData(inInfo[0], 0)
        out = vtkPolyData.GetData(outInfo, 0)
        out.ShallowCopy(inp)
        field = vtkFieldData()  # a new one: the input's stays as it was
        field.ShallowCopy(inp.GetFieldData())
        tag = vtkStringArray()
        tag.SetName(KIND_ARRAY)
        tag.InsertNextValue(self.kind)
        field.AddArray(tag)
        out.SetFieldData(field)
        return 1


def dataset_kind(data: vtkDataObject) -> str | None:
    """What a dataset says it is (its ``blobflow_kind`` field array, see :class:`SurfaceKind`),
    or None where it says nothing (any dataset not made by blobflow's surface stages, and the
    surfaces written before the tag existed)."""
    field = data.GetFieldData() if data is not None else None
    array = field.GetAbstractArray(KIND_ARRAY) if field is not None else None
    if array is None or array.GetNumberOfValues() == 0:
        return None
    return str(array.GetValue(0)) if isinstance(array, vtkStringArray) else None
