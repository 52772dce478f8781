"""SimulationSource: temporal keys, caching, time travel, and use inside a VTK pipeline."""

import numpy as np
import pytest
from vtkmodules.vtkCommonDataModel import vtkDataObject
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline as SDDP
from vtkmodules.vtkFiltersCore import vtkElevationFilter

from filters import BallisticParticles, frame_times
from pipeline import SimulationSource
from pipeline.io.convert import dataset_time, has_state


def _sim():
    x = np.column_stack([np.arange(5.0), np.zeros(5), np.full(5, 50.0)])
    return BallisticParticles(x, np.ones((5, 3)), max_dt=1 / 120)


def _output_at(source, t):
    source.UpdateTimeStep(t)
    return source.GetOutputDataObject(0)


def test_publishes_time_steps_and_range():
    source = SimulationSource(_sim(), fps=24, duration=1.5)
    source.UpdateInformation()
    info = source.GetOutputInformation(0)
    steps = [info.Get(SDDP.TIME_STEPS(), i) for i in range(info.Length(SDDP.TIME_STEPS()))]
    assert steps == frame_times(24, duration=1.5).tolist()
    assert len(steps) == 37
    assert info.Get(SDDP.TIME_RANGE(), 0) == 0.0 and info.Get(SDDP.TIME_RANGE(), 1) == 1.5


def test_same_time_twice_does_not_step():
    source = SimulationSource(_sim(), fps=30, duration=1.0)
    out = _output_at(source, 0.5)
    steps = source.simulation.steps_taken
    assert steps == 60
    assert out.GetInformation().Get(vtkDataObject.DATA_TIME_STEP()) == 0.5
    assert dataset_time(out) == 0.5
    source.Modified()  # even a re-execution must not step again
    _output_at(source, 0.5)
    assert source.simulation.steps_taken == steps


def test_earlier_time_restores_from_cache_instead_of_resimulating():
    sim = _sim()
    source = SimulationSource(sim, fps=10, duration=1.0, cache_size=32)
    for t in frame_times(10, duration=1.0):
        _output_at(source, t)
    total = sim.steps_taken
    assert total == 120
    out = _output_at(source, 0.4)  # cached exactly: zero steps
    assert sim.steps_taken == total
    assert sim.state.time == 0.4
    reference = _sim()
    for t in (0.1, 0.2, 0.3, 0.4):  # the same steps, so the same bits
        reference.advance_to(t)
    np.testing.assert_array_equal(np.asarray(out.GetPoints().GetData()), reference.state.positions)
    _output_at(source, 0.5)  # cached too
    assert sim.steps_taken == total


def test_bounded_cache_restores_nearest_earlier_state():
    sim = _sim()
    source = SimulationSource(sim, fps=10, duration=1.0, cache_size=3)
    for t in frame_times(10, duration=1.0):
        _output_at(source, t)
    assert source.cached_times == [0.0, 0.8, 0.9, 1.0]
    before = sim.steps_taken
    _output_at(source, 0.3)  # nothing cached between 0 and 0.3: re-simulate 0 -> 0.3 only
    assert sim.steps_taken - before == 36
    before = sim.steps_taken
    assert source.cached_times == [0.0, 0.3, 0.9, 1.0]  # least recently used 0.8 dropped
    _output_at(source, 0.95)  # restore 0.9, then 6 steps; not 0.3 -> 0.95
    assert sim.steps_taken - before == 6


def test_output_carries_arrays_not_the_state_which_the_source_keeps():
    source = SimulationSource(_sim(), fps=30, duration=1.0)
    out = _output_at(source, 0.2)
    assert out.GetNumberOfPoints() == 5 and out.GetNumberOfVerts() == 5
    assert out.GetPointData().GetArray("velocity").GetNumberOfComponents() == 3
    assert out.GetPointData().GetArray("id") is not None
    assert not has_state(out)  # the checkpoint lives beside a written series, not in frames
    assert [out.GetFieldData().GetArrayName(i)
            for i in range(out.GetFieldData().GetNumberOfArrays())] == ["TimeValue"]
    state = source.state_at(0.2)  # cached after the frame was made
    assert state.time == 0.2
    np.testing.assert_array_equal(state.positions, np.asarray(out.GetPoints().GetData()))
    assert source.state_at(0.1) is None  # never asked for


def test_any_vtk_filter_downstream_sees_the_requested_time():
    source = SimulationSource(_sim(), fps=30, duration=1.0)
    elevation = vtkElevationFilter()
    elevation.SetInputConnection(source.GetOutputPort())
    elevation.SetLowPoint(0, 0, 0)
    elevation.SetHighPoint(0, 0, 100)
    elevation.UpdateTimeStep(0.3)
    out = elevation.GetOutputDataObject(0)
    assert out.GetInformation().Get(vtkDataObject.DATA_TIME_STEP()) == pytest.approx(0.3)
    z = np.asarray(out.GetPoints().GetData())[:, 2]
    elev = np.asarray(out.GetPointData().GetArray("Elevation"))
    np.testing.assert_allclose(elev, z / 100, atol=1e-6)
    assert source.simulation.state.time == 0.3


def test_unstructured_output_on_request():
    source = SimulationSource(_sim(), fps=30, duration=0.5, dataset="unstructured")
    out = _output_at(source, 0.1)
    assert out.GetClassName() == "vtkUnstructuredGrid"
    assert out.GetNumberOfCells() == 5


@pytest.mark.parametrize("kwargs, error, match", [
    (dict(fps=-1), ValueError, "fps"),
    (dict(cache_size=-1), ValueError, "cache_size"),
    (dict(dataset="image"), ValueError, "dataset"),
])
def test_rejects_bad_arguments(kwargs, error, match):
    with pytest.raises(error, match=match):
        SimulationSource(_sim(), **kwargs)


def test_rejects_non_simulation():
    with pytest.raises(TypeError, match="simulation"):
        SimulationSource(object())
