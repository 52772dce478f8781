"""Turn simulation frames (plain arrays) into VTK datasets and back.

Checkpoints travel in field data: every array of :meth:`filters.State.to_arrays` is stored as a
field-data array named ``state:NAME``, bit for bit, beside the field array ``TimeValue``.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkDoubleArray, vtkPoints
from vtkmodules.vtkCommonDataModel import (
    VTK_VERTEX,
    vtkCellArray,
    vtkDataObject,
    vtkPolyData,
    vtkUnstructuredGrid,
)

from filters.simulation import Frame, OutputSpec, State

__all__ = [
    "frame_to_vtk",
    "state_to_field_data",
    "state_from_dataset",
    "has_state",
    "dataset_time",
    "TIME_ARRAY",
    "STATE_PREFIX",
]

#: Name of the field-data array carrying the time of a dataset (ParaView's convention).
TIME_ARRAY = "TimeValue"
#: Prefix of the field-data arrays carrying a simulation checkpoint.
STATE_PREFIX = "state:"


def _to_vtk_array(name: str, values: np.ndarray):
    values = np.ascontiguousarray(values)
    if values.dtype == np.bool_:
        values = values.astype(np.uint8)
    array = numpy_support.numpy_to_vtk(values, deep=True)
    array.SetName(name)
    return array


def _cell_array(offsets: np.ndarray, indices: np.ndarray) -> vtkCellArray:
    cells = vtkCellArray()
    cells.SetData(
        numpy_support.numpy_to_vtkIdTypeArray(np.ascontiguousarray(offsets, dtype=np.int64), deep=True),
        numpy_support.numpy_to_vtkIdTypeArray(np.ascontiguousarray(indices, dtype=np.int64), deep=True),
    )
    return cells


def _check_frame(frame: Frame, spec: OutputSpec) -> None:
    """Refuse to build a dataset holding NaN: nothing non-finite is ever written."""
    if not np.isfinite(frame.points).all():
        raise ValueError(f"frame at t = {frame.time} has non-finite points")
    names = {name for name, _ in spec.point_arrays}
    for name, values in frame.point_data.items():
        if np.issubdtype(np.asarray(values).dtype, np.floating) and not np.isfinite(values).all():
            raise ValueError(f"frame at t = {frame.time} has non-finite values in {name!r}")
    for name, values in frame.field_data.items():
        if name == TIME_ARRAY or name.startswith(STATE_PREFIX):
            raise ValueError(f"frame field data may not be named {name!r} (reserved)")
        if np.issubdtype(np.asarray(values).dtype, np.floating) and not np.isfinite(values).all():
            raise ValueError(f"frame at t = {frame.time} has non-finite field data {name!r}")
    missing = names - set(frame.point_data)
    if missing:
        raise ValueError(f"frame is missing the point arrays {sorted(missing)} its OutputSpec lists")
    cell_data = frame.cell_data or {}
    for name, values in cell_data.items():
        if np.issubdtype(np.asarray(values).dtype, np.floating) and not np.isfinite(values).all():
            raise ValueError(f"frame at t = {frame.time} has non-finite values in {name!r}")
    missing = {name for name, _ in spec.cell_arrays} - set(cell_data)
    if missing:
        raise ValueError(f"frame is missing the cell arrays {sorted(missing)} its OutputSpec "
                         f"lists")


def frame_to_vtk(frame: Frame, spec: OutputSpec, dataset: str | None = None):
    """Build a VTK dataset from a :class:`filters.Frame`.

    Parameters
    ----------
    frame : Frame
        Points (M, 3), point data (M rows each), optional CSR connectivity and cell data (one
        row per cell).
    spec : OutputSpec
        How to read the frame: its topology and the names of its point arrays.
    dataset : {"polydata", "unstructured"}, optional
        Output type; ``spec.dataset`` when omitted.  Vertices, lines and polygons fit both;
        volumetric cells need ``"unstructured"``.

    Returns
    -------
    vtkPolyData or vtkUnstructuredGrid
        With the point arrays named as in ``spec``, the frame's field arrays and a
        ``TimeValue`` field array.
    """
    dataset = dataset or spec.dataset
    if dataset not in ("polydata", "unstructured"):
        raise ValueError(f"dataset must be 'polydata' or 'unstructured', got {dataset!r}")
    if spec.topology == "cells" and dataset != "unstructured":
        raise ValueError("volumetric cells need dataset='unstructured'")
    _check_frame(frame, spec)
    n = frame.points.shape[0]
    points = vtkPoints()
    points.SetData(_to_vtk_array("Points", np.asarray(frame.points, dtype=np.float64)))

    if spec.topology == "vertices" or frame.connectivity is None:
        offsets = np.arange(n + 1, dtype=np.int64)
        indices = np.arange(n, dtype=np.int64)
        cell_type = np.full(n, VTK_VERTEX, dtype=np.uint8)
        topology = "vertices"
    else:
        offsets, indices = frame.connectivity
        topology = spec.topology
        cell_type = frame.cell_types
    cells = _cell_array(offsets, indices)

    if dataset == "polydata":
        output = vtkPolyData()
        output.SetPoints(points)
        {"vertices": output.SetVerts, "lines": output.SetLines, "polys": output.SetPolys}[topology](cells)
    else:
        output = vtkUnstructuredGrid()
        output.SetPoints(points)
        if cell_type is None:
            raise ValueError("an unstructured grid of lines or polygons needs frame.cell_types")
        types = numpy_support.numpy_to_vtk(np.ascontiguousarray(cell_type, dtype=np.uint8), deep=True,
                                           array_type=3)  # VTK_UNSIGNED_CHAR
        output.SetCells(types, cells)

    # Stable order: the spec's arrays first, then any others the frame adds.
    order = [name for name, _ in spec.point_arrays]
    order += [name for name in frame.point_data if name not in order]
    for name in order:
        output.GetPointData().AddArray(_to_vtk_array(name, frame.point_data[name]))
    if frame.cell_data:
        order = [name for name, _ in spec.cell_arrays]
        order += [name for name in frame.cell_data if name not in order]
        for name in order:
            output.GetCellData().AddArray(_to_vtk_array(name, frame.cell_data[name]))
    for name, values in frame.field_data.items():
        output.GetFieldData().AddArray(_to_vtk_array(name, np.asarray(values)))
    set_time(output, frame.time)
    return output


def set_time(data: vtkDataObject, time: float) -> None:
    """Store ``time`` as the ``TimeValue`` field array and as the data's DATA_TIME_STEP."""
    array = vtkDoubleArray()
    array.SetName(TIME_ARRAY)
    array.InsertNextValue(float(time))
    data.GetFieldData().AddArray(array)
    data.GetInformation().Set(vtkDataObject.DATA_TIME_STEP(), float(time))


def state_to_field_data(data: vtkDataObject, state: State) -> None:
    """Attach ``state`` as ``state:*`` field arrays (exact copies) to ``data``."""
    field = data.GetFieldData()
    for name, values in state.to_arrays().items():
        field.AddArray(_to_vtk_array(STATE_PREFIX + name, np.asarray(values)))


def has_state(data: vtkDataObject) -> bool:
    """Whether ``data`` carries a checkpoint in its field data."""
    field = data.GetFieldData()
    return field.GetArray(STATE_PREFIX + "positions") is not None or (
        field.GetAbstractArray(STATE_PREFIX + "positions") is not None
    )


def state_from_dataset(data: vtkDataObject) -> State:
    """Rebuild the checkpoint stored in ``data``'s field data.

    Raises
    ------
    ValueError
        If ``data`` carries no checkpoint.
    """
    field = data.GetFieldData()
    arrays = {}
    for i in range(field.GetNumberOfArrays()):
        array = field.GetAbstractArray(i)
        name = array.GetName() or ""
        if name.startswith(STATE_PREFIX):
            values = numpy_support.vtk_to_numpy(array)
            arrays[name[len(STATE_PREFIX):]] = np.array(values, copy=True)
    if not arrays:
        raise ValueError("this dataset carries no simulation state (no 'state:' field arrays)")
    return State.from_arrays(arrays)


def dataset_time(data: vtkDataObject) -> float | None:
    """The time stored in ``data`` (``TimeValue`` field array), or ``None``."""
    array = data.GetFieldData().GetArray(TIME_ARRAY)
    if array is None or array.GetNumberOfTuples() == 0:
        return None
    return float(array.GetValue(0))
