"""Frame-parallel processing: serial and Dask runs agree byte for byte, and failures stay local."""


import _frame_tasks
import pytest
from _helpers import ballistic

from pipeline import Flow, SimulationSource, read_series
from pipeline.cli import main
from pipeline.surface.frames import surface_series
from pipeline.tasks import FramesError, map_frames

distributed = pytest.importorskip("dask.distributed", reason="install blobflow[dask]")


@pytest.fixture(scope="module")
def particles(tmp_path_factory):
    out = tmp_path_factory.mktemp("particles")
    flow = Flow(SimulationSource(ballistic(n=60), fps=10, duration=0.7))
    return flow.run(out, progress=False)["particles"]


@pytest.fixture(scope="module")
def client():
    import cloudpickle

    cloudpickle.register_pickle_by_value(_frame_tasks)
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address=":0")
    client = distributed.Client(cluster)
    yield client
    client.close()
    cluster.close()


def _files(folder):
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_local_cluster_is_byte_identical_to_serial(particles, client, tmp_path):
    serial = map_frames(particles, tmp_path / "serial" / "lift.pvd", _frame_tasks.lift_task,
                        {"scale": 2.0}, progress=False)
    parallel = map_frames(particles, tmp_path / "parallel" / "lift.pvd", _frame_tasks.lift_task,
                          {"scale": 2.0}, client=client, progress=False)
    assert serial.computed == parallel.computed == 8
    assert len(parallel.peak_memory) == 2 and min(parallel.peak_memory.values()) > 10 * 2**20
    assert _files(tmp_path / "serial") == _files(tmp_path / "parallel")
    times, meshes = read_series(tmp_path / "parallel" / "lift.pvd")
    assert len(times) == 8 and "height" in meshes[3].point_data


def test_surface_series_parallel_matches_serial(particles, client, tmp_path):
    options = dict(radius=0.08, smooth_iterations=5)
    surface_series(particles, tmp_path / "a" / "surface.pvd", progress=False, **options)
    surface_series(particles, tmp_path / "b" / "surface.pvd", client=client, progress=False,
                   **options)
    assert _files(tmp_path / "a") == _files(tmp_path / "b")
    times, meshes = read_series(tmp_path / "b" / "surface.pvd")
    assert len(times) == 8 and all(m.n_cells > 0 for m in meshes)


def test_surfaces_across_frames_parallel_match_serial(particles, client, tmp_path):
    options = dict(radius=0.08, smooth_iterations=5, across_frames=1)
    surface_series(particles, tmp_path / "a" / "surface.pvd", progress=False, **options)
    surface_series(particles, tmp_path / "b" / "surface.pvd", client=client, progress=False,
                   **options)
    assert _files(tmp_path / "a") == _files(tmp_path / "b")
    assert len(read_series(tmp_path / "b" / "surface.pvd")[0]) == 8


def test_killed_worker_run_still_completes_correctly(particles, client, tmp_path):
    options = {"scale": 1.0, "victim": 4, "marker": str(tmp_path / "killed")}
    map_frames(particles, tmp_path / "ok" / "lift.pvd", _frame_tasks.lift_task, {"scale": 1.0},
               progress=False)
    result = map_frames(particles, tmp_path / "run" / "lift.pvd", _frame_tasks.killing_task,
                        options, client=client, progress=False)
    assert (tmp_path / "killed").exists(), "the worker was never killed"
    assert result.computed == 8
    assert _files(tmp_path / "ok") == _files(tmp_path / "run")
    client.wait_for_workers(2, timeout=60)


@pytest.mark.parametrize("parallel", [False, True])
def test_frame_failing_twice_is_reported_and_others_kept(particles, client, tmp_path, parallel):
    out = tmp_path / "lift.pvd"
    with pytest.raises(FramesError,
                       match=r"frame 3 \(t = 0.3 s\): RuntimeError: this frame is cursed") as info:
        map_frames(particles, out, _frame_tasks.failing_task, {"bad": 3},
                   client=client if parallel else None, progress=False)
    assert [f.index for f in info.value.failures] == [3]
    assert not out.exists(), "no collection until every frame is done"
    written = sorted(p.name for p in (tmp_path / "lift").glob("*.vtp"))
    assert len(written) == 7 and "lift_000003.vtp" not in written
    before = {p: p.stat().st_mtime_ns for p in (tmp_path / "lift").glob("*.vtp")}
    result = map_frames(particles, out, _frame_tasks.lift_task, {}, resume=True, progress=False)
    assert (result.computed, result.skipped) == (1, 7)
    assert all(p.stat().st_mtime_ns == m for p, m in before.items())
    assert len(read_series(out)[0]) == 8


def test_cli_bad_scheduler_address(particles, tmp_path, capsys):
    code = main(["surface", str(particles), "--out", str(tmp_path / "s"), "--scheduler",
                 "tcp://127.0.0.1:9", "-q"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "cannot reach the Dask scheduler" in err
    assert not (tmp_path / "s").exists()


def test_cli_surface_serial_and_render_with_workers(particles, tmp_path, capsys):
    code = main(["surface", str(particles), "--out", str(tmp_path), "--radius", "0.08", "-q"])
    assert code == 0, capsys.readouterr().err
    assert len(read_series(tmp_path / "surface.pvd")[0]) == 8
    serial = tmp_path / "serial.gif"
    from pipeline.render import render_frames
    render_frames([tmp_path / "surface.pvd"], serial, size=(96, 64), progress=False)
    code = main(["render", str(tmp_path / "surface.pvd"), "--out", str(tmp_path / "par.gif"),
                 "--size", "96x64", "--workers", "2", "-q"])
    assert code == 0, capsys.readouterr().err
    assert (tmp_path / "par.gif").read_bytes() == serial.read_bytes()
