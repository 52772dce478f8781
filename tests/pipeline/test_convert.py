"""Frames of every topology become the right VTK datasets, and checkpoints survive the trip."""

import numpy as np
import pytest
import pyvista as pv

from filters import Frame, OutputSpec, State
from pipeline.io.convert import frame_to_vtk, state_from_dataset, state_to_field_data


def _frame(points, connectivity=None, cell_types=None):
    n = len(points)
    return Frame(0.5, np.asarray(points, float), {"velocity": np.zeros((n, 3)), "id": np.arange(n)},
                 connectivity, cell_types)


def test_lines_and_polys_become_polydata_cells():
    pts = np.eye(3)
    lines = frame_to_vtk(_frame(pts, (np.array([0, 2, 4]), np.array([0, 1, 1, 2]))),
                         OutputSpec(topology="lines"))
    assert lines.GetNumberOfLines() == 2 and lines.GetNumberOfVerts() == 0
    polys = pv.wrap(frame_to_vtk(_frame(pts, (np.array([0, 3]), np.array([0, 1, 2]))),
                                 OutputSpec(topology="polys")))
    assert polys.GetNumberOfPolys() == 1
    np.testing.assert_allclose(polys.compute_cell_sizes()["Area"], np.sqrt(3) / 2)


def test_volumetric_cells_become_unstructured_grid():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    spec = OutputSpec(topology="cells")
    grid = pv.wrap(frame_to_vtk(_frame(pts, (np.array([0, 4]), np.arange(4)),
                                       np.array([10], np.uint8)), spec))
    assert isinstance(grid, pv.UnstructuredGrid)
    np.testing.assert_allclose(grid.volume, 1 / 6)
    with pytest.raises(ValueError, match="unstructured"):
        frame_to_vtk(_frame(pts, (np.array([0, 4]), np.arange(4)), np.array([10], np.uint8)), spec,
                     "polydata")


def test_nan_frames_and_missing_arrays_are_refused():
    with pytest.raises(ValueError, match="non-finite points"):
        frame_to_vtk(_frame([[0.0, np.nan, 0.0]]), OutputSpec())
    frame = _frame([[0.0, 0.0, 0.0]])
    del frame.point_data["id"]
    with pytest.raises(ValueError, match="missing the point arrays"):
        frame_to_vtk(frame, OutputSpec())


def test_checkpoint_in_field_data_is_exact(rng):
    state = State(rng.random((6, 3)), rng.random((6, 3)), time=1 / 3, step=7,
                  extra={"density": rng.random(6), "counter": np.array([2**40], np.int64)})
    data = frame_to_vtk(_frame(state.positions), OutputSpec())
    state_to_field_data(data, state)
    back = state_from_dataset(data)
    assert back.time == 1 / 3 and back.step == 7
    for a, b in zip(state.to_arrays().values(), back.to_arrays().values(), strict=False):
        assert np.array_equal(a, b) and a.dtype == b.dtype
