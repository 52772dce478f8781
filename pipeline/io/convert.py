"""Turn simulation frames (plain arrays) into VTK datasets and back.

Frames leave the simulation in one particle order: by their ``id`` array when they have one
(:func:`id_order`), so that a particle is the same row in every frame and viewers that
interpolate between time samples by index (ParaView's TemporalInterpolator, USD, motion blur)
move each particle to where it belongs; emitted particles come after the older ones (their ids
are larger) and dead ones leave the rest in order.

Checkpoints live beside a series (:mod:`pipeline.io.checkpoint`), not in its frames.  Series written
by earlier versions carry one in every frame's field data: every array of
:meth:`filters.State.to_arrays` as a field-data array named ``state:NAME``, bit for bit, beside
the field array ``TimeValue``; :func:`has_state` and :func:`state_from_dataset` read them, so that
those runs can still be resumed.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

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

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = [
    "frame_to_vtk",
    "id_order",
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
        numpy_support.numpy_to_vtkIdTypeArray(np.ascontiguousarray(offsets, dtype=np.int64),
                                              deep=True),
        numpy_support.numpy_to_vtkIdTypeArray(np.ascontiguousarray(indices, dtype=np.int64),
                                              deep=True),
    )
    return cells


def _check_frame(frame: Frame, spec: OutputSpec) -> None:
    """Refuse to build a dataset holding NaN: nothing non-finite is ever written."""
    if not np.isfinite(frame.points).all():
        raise ValueError(f"frame at t = {frame.time} has non-finite points")
    names = {name for name, _ in spec.point_arrays}
    n = np.shape(frame.points)[0]
    for name, values in frame.point_data.items():
        if np.shape(values)[:1] != (n,):
            raise ValueError(f"point array {name!r} has shape {np.shape(values)}; a frame of "
                             f"{n} points needs {n} rows")
        if np.issubdtype(np.asarray(values).dtype, np.floating) and not np.isfinite(values).all():
            raise ValueError(f"frame at t = {frame.time} has non-finite values in {name!r}")
    for name, values in frame.field_data.items():
        if name == TIME_ARRAY or name.startswith(STATE_PREFIX):
            raise ValueError(f"frame field data may not be named {name!r} (reserved)")
        if np.issubdtype(np.asarray(values).dtype, np.floating) and not np.isfinite(values).all():
            raise ValueError(f"frame at t = {frame.time} has non-finite field data {name!r}")
    missing = names - set(frame.point_data)
    if missing:
        raise ValueError(f"frame is missing the point arrays {sorted(missing)} its OutputSpec "
                         f"lists")
    cell_data = frame.cell_data or {}
    for name, values in cell_data.items():
        if np.issubdtype(np.asarray(values).dtype, np.floating) and not np.isfinite(values).all():
            raise ValueError(f"frame at t = {frame.time} has non-finite values in {name!r}")
    missing = {name for name, _ in spec.cell_arrays} - set(cell_data)
    if missing:
        raise ValueError(f"frame is missing the cell arrays {sorted(missing)} its OutputSpec "
                         f"lists")


def id_order(ids: ArrayLike) -> np.ndarray | None:
    """The permutation that puts particles in increasing ``id`` order, or ``None`` if they are.

    Parameters
    ----------
    ids : (M,) array_like of int or float
        The ``id`` of every point (an ``(M, 1)`` column is accepted).

    Returns
    -------
    (M,) int64 array or None
        ``order`` such that ``ids[order]`` increases (equal ids keep their relative order);
        ``None`` when ``ids`` already strictly increases, the common case of a simulation that
        keeps its particles in order.

    Notes
    -----
    Unique non-negative integer ids below ``2 M`` (a permutation of ``0 .. M-1``, or ids with
    gaps from dead particles) are ordered by scattering them into a table, in O(M); any other
    ids by a stable sort.
    """
    ids = np.asarray(ids)
    if ids.ndim == 2 and ids.shape[1] == 1:
        ids = ids[:, 0]
    if ids.ndim != 1:
        raise ValueError(f"ids must have shape (M,), got {ids.shape}")
    n = ids.shape[0]
    if n < 2 or bool(np.all(ids[1:] > ids[:-1])):
        return None
    if np.issubdtype(ids.dtype, np.integer):
        low, high = int(ids.min()), int(ids.max())
        if low >= 0 and high < 2 * n:
            rank = np.full(high + 1, -1, dtype=np.int64)
            rank[ids] = np.arange(n, dtype=np.int64)
            order = rank[rank >= 0]
            if order.shape[0] == n:  # the ids were unique
                return order
    return np.argsort(ids, kind="stable").astype(np.int64, copy=False)


def _in_id_order(frame: Frame, vertices: bool) -> Frame:
    """``frame`` with its points, point data (and the cells of ``vertices``) in ``id`` order."""
    ids = frame.point_data.get("id")
    if ids is None:
        return frame
    order = id_order(ids)
    if order is None:
        return frame
    points = np.asarray(frame.points)[order]
    point_data = {name: np.asarray(values)[order] for name, values in frame.point_data.items()}
    connectivity, cell_data = frame.connectivity, frame.cell_data
    if vertices:  # one vertex cell per point: the cells follow their points
        connectivity = None
        if cell_data:
            cell_data = {name: np.asarray(values)[order] for name, values in cell_data.items()}
    else:  # cells keep their order; their point indices follow
        rank = np.empty_like(order)
        rank[order] = np.arange(order.shape[0], dtype=np.int64)
        offsets, indices = connectivity
        connectivity = (offsets, rank[np.asarray(indices, dtype=np.int64)])
    return Frame(time=frame.time, points=points, point_data=point_data,
                 connectivity=connectivity, cell_types=frame.cell_types, cell_data=cell_data,
                 field_data=frame.field_data)


def frame_to_vtk(frame: Frame, spec: OutputSpec,
                 dataset: str | None = None) -> vtkPolyData | vtkUnstructuredGrid:
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
        ``TimeValue`` field array; the points in increasing ``id`` order when the frame has an
        ``id`` point array (:func:`id_order`; cells keep their order and follow their points).
    """
    dataset = dataset or spec.dataset
    if dataset not in ("polydata", "unstructured"):
        raise ValueError(f"dataset must be 'polydata' or 'unstructured', got {dataset!r}")
    if spec.topology == "cells" and dataset != "unstructured":
        raise ValueError("volumetric cells need dataset='unstructured'")
    _check_frame(frame, spec)
    frame = _in_id_order(frame, spec.topology == "vertices" or frame.connectivity is None)
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
        setters = {"vertices": output.SetVerts, "lines": output.SetLines,
                   "polys": output.SetPolys}
        setters[topology](cells)
    else:
        output = vtkUnstructuredGrid()
        output.SetPoints(points)
        if cell_type is None:
            raise ValueError("an unstructured grid of lines or polygons needs frame.cell_types")
        types = numpy_support.numpy_to_vtk(np.ascontiguousarray(cell_type, dtype=np.uint8),
                                           deep=True, array_type=3)  # VTK_UNSIGNED_CHAR
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
