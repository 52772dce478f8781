"""A surface carried by a volume mesh: the ``EmbeddedSurface`` stage, and reading closed meshes.

A finite-element solid is written as its tetrahedra (:class:`filters.elastic.fem_simulation.
FEMSimulation`); the user's surface lives inside them with fixed interpolation weights
(:class:`filters.elastic.topology.Embedding`).  :class:`EmbeddedSurface` turns every frame of
the volume mesh into that surface: vertex ``j`` at ``sum_k w[j, k] x[nodes[j, k]]``, and every
listed point array interpolated with the same weights.  :func:`read_closed_mesh` reads the
surface a scene embeds from any file PyVista reads.
"""

from __future__ import annotations

import logging
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkPointSet, vtkPolyData

from filters.elastic.topology import Embedding
from filters.simulation import Frame, OutputSpec

from .algorithm import Algorithm, vtk_messages
from .io.convert import dataset_time, frame_to_vtk
from .io.xmlcheck import XML_SUFFIXES, UnsafeFileError, check_vtk_xml

if TYPE_CHECKING:
    from collections.abc import Sequence

__all__ = ["EmbeddedSurface", "read_closed_mesh"]


class EmbeddedSurface(Algorithm):
    """Volume mesh (any vtkPointSet) -> the triangle surface embedded in it (vtkPolyData).

    Parameters
    ----------
    embedding : filters.elastic.topology.Embedding
        Per surface vertex the input points it follows and their weights, and the triangles.
    point_arrays : sequence of str
        Point arrays of the input interpolated to the surface (those the input lacks are
        skipped); the surface also gets an ``id`` per vertex.
    """

    def __init__(self, embedding: Embedding, point_arrays: Sequence[str] = ("velocity",)):
        if not isinstance(embedding, Embedding):
            raise TypeError(f"embedding must be a filters.elastic.topology.Embedding, got "
                            f"{type(embedding).__name__}")
        names = (point_arrays,) if isinstance(point_arrays, str) else tuple(point_arrays)
        if not all(isinstance(n, str) and n for n in names):
            raise ValueError(f"point_arrays must be names of point arrays, got {point_arrays!r}")
        self.embedding = embedding
        self.point_arrays = names
        tris = np.asarray(embedding.triangles, dtype=np.int64)
        self._connectivity = (np.arange(0, 3 * tris.shape[0] + 1, 3, dtype=np.int64),
                              tris.ravel().copy())
        Algorithm.__init__(self, nInputPorts=1, inputType="vtkPointSet", nOutputPorts=1,
                           outputType="vtkPolyData")

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkPointSet.GetData(inInfo[0], 0)
        n = inp.GetNumberOfPoints()
        nodes = self.embedding.nodes
        if nodes.size and nodes.max() >= n:
            raise ValueError(f"EmbeddedSurface: the embedding refers to point {int(nodes.max())} "
                             f"but the input has {n} points")
        x = numpy_support.vtk_to_numpy(inp.GetPoints().GetData()).astype(np.float64)
        data = {}
        for name in self.point_arrays:
            array = inp.GetPointData().GetArray(name)
            if array is not None:
                values = numpy_support.vtk_to_numpy(array).astype(np.float64)
                data[name] = (self.embedding.points(values) if values.ndim == 2 else
                              np.einsum("mk,mk->m", self.embedding.weights, values[nodes]))
        points = self.embedding.points(x)
        data["id"] = np.arange(points.shape[0], dtype=np.int64)
        time = dataset_time(inp)
        frame = Frame(time=0.0 if time is None else time, points=points, point_data=data,
                      connectivity=self._connectivity)
        spec = OutputSpec(point_arrays=tuple((k, 1 if v.ndim == 1 else v.shape[1])
                                             for k, v in data.items()), topology="polys")
        vtkPolyData.GetData(outInfo, 0).ShallowCopy(frame_to_vtk(frame, spec, "polydata"))
        return 1


#: Files that make VTK read other files (collections, parallel pieces): not one mesh.
_MULTI_FILE = (".vtm", ".vtmb", ".pvd", ".pvtp", ".pvtu", ".pvti", ".pvts", ".pvtr", ".series")


def read_closed_mesh(path: str | Path, name: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """Read a closed triangle surface from any file PyVista reads.

    Parameters
    ----------
    path : str or Path
        The file.
    name : str
        The parameter the path came from, for messages.

    Returns
    -------
    points : (M, 3) float64
        Vertices.
    triangles : (T, 3) int64
        Triangles (the surface of the data set, triangulated and cleaned).

    Raises
    ------
    ValueError
        Naming ``name``: a missing file, one PyVista cannot read, several meshes, or fewer than
        4 points or triangles.
    """
    import pyvista as pv

    if not Path(path).is_file():
        raise ValueError(f"{name}: no such file {str(path)!r}")
    suffix = Path(path).suffix.lower()
    if suffix in _MULTI_FILE:
        raise ValueError(f"{name}: {str(path)!r} is a {suffix} file, which names other files; "
                         f"give one mesh file")
    if suffix in XML_SUFFIXES:  # declared sizes checked before VTK allocates them
        try:
            check_vtk_xml(path)
        except (UnsafeFileError, OSError) as exc:
            raise ValueError(f"{name}: {exc}") from None
    # PyVista reports a reader's failure as log records and a warning: keep them, say it once
    logging.disable(logging.CRITICAL)
    try:
        with vtk_messages() as log, warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            data = pv.read(path)
            mesh = data.extract_surface().triangulate().clean() if isinstance(
                data, pv.DataSet) else None
    except Exception as exc:  # noqa: BLE001 - any reader failure is a bad argument
        raise ValueError(f"{name}: {str(path)!r} is not a mesh PyVista can read "
                         f"({type(exc).__name__}: {exc})") from None
    finally:
        logging.disable(logging.NOTSET)
    failures = log.errors + [str(w.message).splitlines()[0] for w in caught
                             if "error" in str(w.message).lower()]
    if failures:
        raise ValueError(f"{name}: {str(path)!r} cannot be read: {failures[0]}")
    if mesh is None:
        raise ValueError(f"{name}: {str(path)!r} holds a {type(data).__name__}, not one mesh")
    if mesh.n_points < 4 or mesh.n_cells < 4:
        raise ValueError(f"{name}: {str(path)!r} holds no closed surface ({mesh.n_points} "
                         f"points, {mesh.n_cells} triangles)")
    faces = mesh.faces.reshape(-1, 4)[:, 1:]
    return np.asarray(mesh.points, dtype=np.float64), np.asarray(faces, dtype=np.int64)
