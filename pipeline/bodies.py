"""The bodies of a coupled liquid as a mesh output: the ``BodyMeshes`` stage.

A :class:`filters.coupling.Coupled` simulation's frames are the liquid's particles; the bodies
travel in their field data (per rigid body its orientation and translation, the elastic bodies'
surface vertices).  :class:`BodyMeshes` turns every such frame into the bodies' surfaces: each
rigid body's mesh as given, rotated and translated (``x = R(q) X + t``), and each elastic
body's embedded surface, with the point arrays ``body`` (which body) and ``id``, and the field
arrays ``body_orientation``, ``body_translation`` and ``body_position`` passed on, so that a
reader can also place a rigid body's mesh by its transform.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkPointSet, vtkPolyData

from filters.rigid import rotation_matrices
from filters.simulation import Frame, OutputSpec

from .algorithm import Algorithm
from .io.convert import dataset_time, frame_to_vtk

__all__ = ["BodyMeshes"]

#: Field arrays of the particles passed on to the bodies' meshes.
BODY_FIELDS = ("body_position", "body_orientation", "body_translation")


def _field(data, name):
    array = data.GetFieldData().GetArray(name)
    if array is None:
        raise ValueError(f"BodyMeshes: the input has no field array {name!r} (is it the "
                         f"output of a Coupled simulation?)")
    return numpy_support.vtk_to_numpy(array).astype(np.float64)


class BodyMeshes(Algorithm):
    """Particles of a coupled liquid (vtkPointSet with the bodies in its field data) -> the
    bodies' triangle meshes (vtkPolyData).

    Parameters
    ----------
    layout : list of dict
        :meth:`filters.coupling.Coupled.body_mesh_layout`: per body its kind, its mesh or
        triangles and where its rows are in the field data.
    """

    def __init__(self, layout: list[dict]):
        if not isinstance(layout, (list, tuple)) or not layout:
            raise ValueError("layout must be a non-empty list (Coupled.body_mesh_layout())")
        self.layout = list(layout)
        tris, start = [], 0
        body = []
        for k, item in enumerate(self.layout):
            count = (item["vertices"].shape[0] if item["kind"] == "rigid"
                     else item["stop"] - item["start"])
            tris.append(np.asarray(item["triangles"], dtype=np.int64) + start)
            body.append(np.full(count, k, dtype=np.int64))
            start += count
        tri = np.concatenate(tris)
        self._connectivity = (np.arange(0, 3 * tri.shape[0] + 1, 3, dtype=np.int64),
                              tri.ravel().copy())
        self._body = np.concatenate(body)
        Algorithm.__init__(self, nInputPorts=1, inputType="vtkPointSet", nOutputPorts=1,
                           outputType="vtkPolyData")

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkPointSet.GetData(inInfo[0], 0)
        rigid = [item for item in self.layout if item["kind"] == "rigid"]
        fields = {}
        if rigid:
            for name in BODY_FIELDS:
                fields[name] = _field(inp, name).reshape(-1, 4 if "orientation" in name else 3)
            rot = rotation_matrices(fields["body_orientation"])
            shift = fields["body_translation"]
        surface = (_field(inp, "solid_surface").reshape(-1, 3)
                   if len(rigid) < len(self.layout) else None)
        points = []
        for item in self.layout:
            if item["kind"] == "rigid":
                r = item["row"]
                points.append(item["vertices"] @ rot[r].T + shift[r])
            else:
                points.append(surface[item["start"]:item["stop"]])
        points = np.ascontiguousarray(np.concatenate(points))
        time = dataset_time(inp)
        frame = Frame(time=0.0 if time is None else time, points=points,
                      point_data={"body": self._body.copy(),
                                  "id": np.arange(points.shape[0], dtype=np.int64)},
                      connectivity=self._connectivity, field_data=fields)
        spec = OutputSpec(point_arrays=(("body", 1), ("id", 1)), topology="polys")
        vtkPolyData.GetData(outInfo, 0).ShallowCopy(frame_to_vtk(frame, spec, "polydata"))
        return 1
