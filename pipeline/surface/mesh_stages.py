"""Mesh stages wrapping VTK filters: windowed-sinc smoothing and point normals.

Each is a vtkPolyData -> vtkPolyData :class:`pipeline.algorithm.Algorithm`; a mesh without
triangles (or a stage switched off) passes through. :mod:`pipeline.surface` puts them at the end
of the surface chain and exports them; with the walls of a tank the surface was cut at
(:class:`pipeline.surface.liquid.ClipBox`), :class:`Smooth` keeps the cut faces on the walls.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
from vtkmodules.vtkFiltersCore import vtkPolyDataNormals, vtkWindowedSincPolyDataFilter

from filters.geometry import Box
from filters.surface.clip import wall_constraints
from filters.validation import check_int, check_range

from ..algorithm import Algorithm

__all__ = ["MeshFilter", "Smooth", "Normals"]


class MeshFilter(Algorithm):
    """A vtkPolyData -> vtkPolyData stage wrapping a VTK filter; a mesh without triangles (or a
    stage switched off) passes through."""

    def __init__(self):
        Algorithm.__init__(self, nInputPorts=1, inputType="vtkPolyData", nOutputPorts=1,
                           outputType="vtkPolyData")

    def _filter(self):  # pragma: no cover - abstract
        """The configured VTK filter, or None to pass the mesh through."""
        raise NotImplementedError

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkPolyData.GetData(inInfo[0], 0)
        out = vtkPolyData.GetData(outInfo, 0)
        f = self._filter() if inp.GetNumberOfPolys() else None
        if f is None:
            out.ShallowCopy(inp)
            return 1
        f.SetInputData(inp)
        f.Update()
        out.ShallowCopy(f.GetOutput())
        return 1


class Smooth(MeshFilter):
    """Windowed-sinc smoothing (Taubin, Zhang & Golub 1996) that keeps the enclosed volume.

    Parameters
    ----------
    iterations : int
        Filter degree (number of iterations), in [0, 1000]; 0 passes the mesh through.
    pass_band : float
        In (0, 2); lower smooths more. ``(100, 0.001)`` removes the particle-scale bumps of a
        lattice-filled ball (area within 1 % of the sphere's) while moving its enclosed volume
        by less than 0.1 %.
    walls : filters.geometry.Box, optional
        The tank a surface was cut at (:class:`pipeline.surface.liquid.ClipBox`): its flat faces
        on the walls are left out of the smoothing and the vertices on the walls stay where they are
        (the windowed sinc would pull the cut's edges off the walls).
    """

    def __init__(self, iterations: int = 100, pass_band: float = 0.001, *,
                 walls: Box | None = None):
        self.iterations = check_int("iterations", iterations, 0, 1000)
        self.pass_band = check_range("pass_band", pass_band, 0.0, 2.0, low_inclusive=False)
        if walls is not None and not isinstance(walls, Box):
            raise TypeError(f"walls must be a filters.geometry.Box or None, got "
                            f"{type(walls).__name__}")
        self.walls = walls
        MeshFilter.__init__(self)

    def _filter(self):
        if self.iterations == 0:
            return None
        f = vtkWindowedSincPolyDataFilter()
        f.SetNumberOfIterations(self.iterations)
        f.SetPassBand(self.pass_band)
        f.NormalizeCoordinatesOn()
        f.BoundarySmoothingOff()
        f.FeatureEdgeSmoothingOff()
        f.NonManifoldSmoothingOn()
        return f

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkPolyData.GetData(inInfo[0], 0)
        if self.walls is None or self.iterations == 0 or inp.GetNumberOfPolys() == 0:
            return MeshFilter.RequestData(self, request, inInfo, outInfo)
        pts = numpy_support.vtk_to_numpy(inp.GetPoints().GetData())
        tris = numpy_support.vtk_to_numpy(inp.GetPolys().GetConnectivityArray()).reshape(-1, 3)
        _, faces = wall_constraints(pts, tris, self.walls.lower, self.walls.upper)
        # the surface without its faces on the walls: the cut's edges are its boundary, which
        # the filter leaves alone (BoundarySmoothingOff); the faces go back unchanged
        part = vtkPolyData()
        part.ShallowCopy(inp)
        part.SetPolys(_cells(tris[~faces]))
        f = self._filter()
        f.SetInputData(part)
        f.Update()
        out = vtkPolyData.GetData(outInfo, 0)
        out.ShallowCopy(f.GetOutput())
        out.SetPolys(_cells(np.concatenate([tris[~faces], tris[faces]])))
        return 1


def _cells(triangles):
    """A vtkCellArray of triangles ``(T, 3)``."""
    cells = vtkCellArray()
    cells.SetData(numpy_support.numpy_to_vtkIdTypeArray(
        np.arange(0, 3 * len(triangles) + 1, 3, dtype=np.int64), deep=True),
        numpy_support.numpy_to_vtkIdTypeArray(
            np.ascontiguousarray(triangles, dtype=np.int64).ravel(), deep=True))
    return cells


class Normals(MeshFilter):
    """Point normals (vtkPolyDataNormals) without splitting sharp edges (stays watertight)."""

    def _filter(self):
        f = vtkPolyDataNormals()
        f.SplittingOff()
        f.ConsistencyOff()
        f.AutoOrientNormalsOff()
        f.ComputePointNormalsOn()
        f.ComputeCellNormalsOff()
        return f
