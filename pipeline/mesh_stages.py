"""Mesh stages wrapping VTK filters: windowed-sinc smoothing and point normals.

Each is a vtkPolyData -> vtkPolyData :class:`pipeline.algorithm.Algorithm`; a mesh without
triangles (or a stage switched off) passes through. :mod:`pipeline.surface` puts them at the end
of the surface chain and exports them.
"""

from __future__ import annotations

from vtkmodules.vtkCommonDataModel import vtkPolyData
from vtkmodules.vtkFiltersCore import vtkPolyDataNormals, vtkWindowedSincPolyDataFilter

from filters.validation import check_int, check_range

from .algorithm import Algorithm

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
    """

    def __init__(self, iterations: int = 100, pass_band: float = 0.001):
        self.iterations = check_int("iterations", iterations, 0, 1000)
        self.pass_band = check_range("pass_band", pass_band, 0.0, 2.0, low_inclusive=False)
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
