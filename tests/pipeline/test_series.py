"""Series on disk: format, round trips through VTK's readers and meshio, XDMF, atomic and resumable
runs."""

import json
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest
from _helpers import ballistic, failing_ballistic
from vtkmodules.vtkFiltersCore import vtkElevationFilter

from filters import SimulationError
from pipeline import Flow, SimulationSource, export_xdmf, read_series
from pipeline.io.series import SeriesError, SeriesWriter, read_collection


def _run(tmp_path, name="run", sim=None, dataset=None, **kwargs):
    sim = sim or ballistic()
    flow = Flow(SimulationSource(sim, fps=20, duration=0.5, dataset=dataset))
    return flow, flow.run(tmp_path / name, progress=False, **kwargs)


def _reference_frames(fps=20, duration=0.5):
    """Positions and velocities at each frame, stepping a fresh simulation frame by frame."""
    sim = ballistic()
    frames = []
    for i in range(int(duration * fps) + 1):
        sim.advance_to(round(i / fps, 9))
        frames.append((sim.state.positions.copy(), sim.state.velocities.copy()))
    return frames


def test_round_trip_through_vtk_readers(tmp_path):
    _, paths = _run(tmp_path)
    times, meshes = read_series(paths["particles"])
    assert times.tolist() == [round(i / 20, 9) for i in range(11)]
    for mesh, (x, v), t in zip(meshes, _reference_frames(), times, strict=False):
        np.testing.assert_array_equal(mesh.points, x)
        np.testing.assert_array_equal(mesh.point_data["velocity"], v)
        np.testing.assert_array_equal(mesh.point_data["id"], np.arange(20))
        assert mesh.field_data["TimeValue"][0] == t
    # The ParaView .series file lists the same frames and times.
    assert read_collection(paths["particles"].with_name("particles.vtp.series")) == \
        read_collection(paths["particles"])


def test_files_use_raw_appended_zlib_uint64(tmp_path):
    _, paths = _run(tmp_path)
    root = ET.parse(paths["particles"]).getroot()
    first = root.find("Collection/DataSet").get("file")
    assert first == "particles/particles_000000.vtp"
    head = (paths["particles"].parent / first).read_bytes()[:2000]
    assert b'header_type="UInt64"' in head
    assert b'compressor="vtkZLibDataCompressor"' in head
    assert b'<AppendedData encoding="raw">' in (paths["particles"].parent / first).read_bytes()
    assert 'timestep="0.15"' in paths["particles"].read_text()  # times written as rounded


def test_round_trip_through_meshio_vtu(tmp_path):
    _, paths = _run(tmp_path, dataset="unstructured")
    times, _ = read_series(paths["particles"])
    folder = paths["particles"].parent
    for (t, name), (x, v) in zip(read_collection(paths["particles"]), _reference_frames(),
                                 strict=False):
        mesh = meshio.read(folder / name)
        np.testing.assert_array_equal(mesh.points, x)
        np.testing.assert_array_equal(mesh.point_data["velocity"], v)
        assert mesh.cells[0].type == "vertex" and len(mesh.cells[0].data) == 20
        assert mesh.field_data["TimeValue"][0] == t


def _read_xdmf(path):
    """Every time step of an XDMF file as VTK's XDMF reader sees it: (times, datasets)."""
    import pyvista as pv
    from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline as SDDP
    from vtkmodules.vtkIOXdmf2 import vtkXdmfReader

    reader = vtkXdmfReader()
    reader.SetFileName(str(path))
    reader.UpdateInformation()
    info = reader.GetOutputInformation(0)
    times = [info.Get(SDDP.TIME_STEPS(), i) for i in range(info.Length(SDDP.TIME_STEPS()))]
    frames = []
    for t in times:
        reader.UpdateTimeStep(t)
        frames.append(pv.wrap(reader.GetOutputDataObject(0)).copy())
    return times, frames


def test_xdmf_export_round_trip_through_vtk_reader(tmp_path):
    _, paths = _run(tmp_path)
    xdmf = export_xdmf(paths["particles"])
    assert xdmf.with_suffix(".h5").is_file()
    expected = _reference_frames()
    times, frames = _read_xdmf(xdmf)
    assert times == [round(k / 20, 9) for k in range(len(expected))]
    # every step, t = 0 included, bit for bit
    for frame, (x, v) in zip(frames, expected, strict=False):
        assert frame.n_points == len(x) and frame.n_cells == len(x)
        assert set(frame.celltypes.tolist()) <= {1, 2}  # one-point (poly)vertices
        assert frame.get_cell(len(x) - 1).point_ids == [len(x) - 1]
        np.testing.assert_array_equal(frame.points, x)
        np.testing.assert_array_equal(frame.point_data["velocity"], v)
    series_times, series = read_series(paths["particles"])
    np.testing.assert_array_equal(frames[0].point_data["id"], series[0].point_data["id"])


def test_xdmf_export_refuses_changing_topology(tmp_path):
    writer = SeriesWriter(tmp_path / "s.pvd")
    import pyvista as pv
    writer.write(pv.Sphere(theta_resolution=8), 0.0)
    writer.write(pv.Sphere(theta_resolution=10), 0.1)
    with pytest.raises(ValueError, match="topology"):
        export_xdmf(tmp_path / "s.pvd")


def test_failure_at_frame_k_leaves_valid_k_frame_series(tmp_path):
    flow = Flow(SimulationSource(failing_ballistic(fail_after=0.26), fps=20, duration=0.5))
    with pytest.raises(SimulationError, match="injected"):
        flow.run(tmp_path / "run", progress=False)
    times, meshes = read_series(tmp_path / "run" / "particles.pvd")
    assert times.tolist() == [0.0, 0.05, 0.1, 0.15, 0.2, 0.25]  # frame 0.3 never completed
    assert all(m.n_points == 20 for m in meshes)
    assert not list((tmp_path / "run").rglob("*.tmp")), "temporary files left behind"
    series = json.loads((tmp_path / "run" / "particles.vtp.series").read_text())
    assert len(series["files"]) == 6


def test_resume_after_failure_is_bitwise_identical(tmp_path):
    _, clean = _run(tmp_path, "clean")
    failing = Flow(SimulationSource(failing_ballistic(fail_after=0.26), fps=20, duration=0.5))
    failing.add("elevation", vtkElevationFilter())
    clean_flow = Flow(SimulationSource(ballistic(), fps=20, duration=0.5))
    clean_flow.add("elevation", vtkElevationFilter())
    clean = clean_flow.run(tmp_path / "clean", progress=False)
    with pytest.raises(SimulationError):
        failing.run(tmp_path / "resumed", progress=False)
    resumed_flow = Flow(SimulationSource(ballistic(), fps=20, duration=0.5))
    resumed_flow.add("elevation", vtkElevationFilter())
    steps_before = resumed_flow.source.simulation.steps_taken
    resumed = resumed_flow.run(tmp_path / "resumed", resume=True, progress=False)
    # Only the missing frames were simulated: 0.25 -> 0.5 at 5 steps per frame.
    assert resumed_flow.source.simulation.steps_taken - steps_before == 25
    for name in ("particles", "elevation"):
        a, b = clean[name].parent, resumed[name].parent
        assert clean[name].read_bytes() == resumed[name].read_bytes()
        files = sorted(p.relative_to(a) for p in (a / name).iterdir())
        assert files == sorted(p.relative_to(b) for p in (b / name).iterdir())
        for f in files:
            assert (a / f).read_bytes() == (b / f).read_bytes(), f"{f} differs after resume"


def test_resume_of_a_complete_run_writes_nothing_new(tmp_path):
    _, paths = _run(tmp_path)
    before = {p: p.stat().st_mtime_ns for p in (tmp_path / "run").rglob("*.vtp")}
    _run(tmp_path, resume=True)
    after = {p: p.stat().st_mtime_ns for p in (tmp_path / "run").rglob("*.vtp")}
    assert before == after


def test_fresh_run_removes_stale_frames(tmp_path):
    _run(tmp_path)
    flow = Flow(SimulationSource(ballistic(), fps=20, frames=3))
    flow.run(tmp_path / "run", progress=False)
    assert len(list((tmp_path / "run" / "particles").glob("*.vtp"))) == 3


def test_writer_refuses_nan_and_mixed_types(tmp_path):
    import pyvista as pv
    writer = SeriesWriter(tmp_path / "s.pvd")
    bad = pv.PolyData(np.array([[0.0, np.nan, 0.0]]))
    with pytest.raises(ValueError, match="NaN"):
        writer.write(bad, 0.0)
    assert not (tmp_path / "s").exists() or not list((tmp_path / "s").iterdir())
    writer.write(pv.PolyData(np.zeros((1, 3))), 0.0)
    with pytest.raises(TypeError, match="holds vtkPolyData"):
        writer.write(pv.UnstructuredGrid(), 0.1)
    with pytest.raises(ValueError, match="increase"):
        writer.write(pv.PolyData(np.zeros((1, 3))), 0.0)
    assert len(read_series(tmp_path / "s.pvd")[0]) == 1


def test_empty_dataset_round_trips(tmp_path):
    import pyvista as pv
    writer = SeriesWriter(tmp_path / "e.pvd")
    writer.write(pv.PolyData(), 0.0)
    times, meshes = read_series(tmp_path / "e.pvd")
    assert times.tolist() == [0.0] and meshes[0].n_points == 0


def test_read_series_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_series(tmp_path / "missing.pvd")
    bad = tmp_path / "bad.pvd"
    bad.write_text("<VTKFile type='Collection'><Collection><DataSet file='x/none.vtp'/>")
    with pytest.raises(SeriesError, match="not a valid series"):
        read_series(bad)
    bad.write_text("<VTKFile type='Collection'><Collection>"
                   "<DataSet timestep='0' file='x/none.vtp'/></Collection></VTKFile>")
    with pytest.raises(SeriesError, match="missing"):
        read_series(bad)


def test_xdmf_export_keeps_polylines(tmp_path):
    # strands of equal length are one Polyline topology with NodesPerElement (ParaView 5.11
    # aborts on a Polyline without it); strands of different lengths a Mixed topology
    import pyvista as pv
    points = np.array([[0, 0, 0], [0, 0, 1], [0, 0, 2], [1, 0, 0], [1, 0, 1.0], [1, 0, 2]])
    for name, lines, text in (("equal", [3, 0, 1, 2, 3, 3, 4, 5], 'NodesPerElement="3"'),
                              ("mixed", [3, 0, 1, 2, 2, 3, 4], 'TopologyType="Mixed"')):
        writer = SeriesWriter(tmp_path / f"{name}.pvd")
        for t in (0.0, 0.5):
            writer.write(pv.PolyData(points + t, lines=np.array(lines)), t)
        xdmf = export_xdmf(tmp_path / f"{name}.pvd")
        assert text in xdmf.read_text()
        times, frames = _read_xdmf(xdmf)
        assert times == [0.0, 0.5]
        for t, frame in zip(times, frames, strict=False):
            np.testing.assert_array_equal(frame.points, points + t)
            cells = [frame.get_cell(i).point_ids for i in range(frame.n_cells)]
            assert cells == ([[0, 1, 2], [3, 4, 5]] if name == "equal" else [[0, 1, 2], [3, 4]])


def test_interrupt_inside_a_vtk_request_stops_the_run(tmp_path):
    """Ctrl-C while VTK runs our RequestData must stop the run, not be swallowed by VTK."""
    class Interrupted(type(ballistic())):
        def _step(self, dt):
            if self.state.time + dt > 0.12:
                raise KeyboardInterrupt
            super()._step(dt)

    base = ballistic()
    sim = Interrupted(base.state.positions, base.state.velocities, max_dt=1 / 100)
    flow = Flow(SimulationSource(sim, fps=20, duration=0.5))
    with pytest.raises(KeyboardInterrupt):
        flow.run(tmp_path / "run", progress=False)
    times, _ = read_series(tmp_path / "run" / "particles.pvd")
    assert times.tolist() == [0.0, 0.05, 0.1]
