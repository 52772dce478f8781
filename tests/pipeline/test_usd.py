"""USD export: one time sample per frame, points to float32, changing topology, z-up metres."""

import numpy as np
import pytest
import pyvista as pv

from filters import BallisticParticles
from pipeline import Flow, SimulationSource
from pipeline.cli import main
from pipeline.io.series import SeriesWriter, read_series
from pipeline.surface import surface_stages

pxr = pytest.importorskip("pxr", reason="usd-core is not installed (pip install -e \".[usd]\")")
from pxr import Usd, UsdGeom  # noqa: E402

from pipeline.io.usd import export_usd, time_codes  # noqa: E402

FPS = 10


@pytest.fixture(scope="module")
def series(tmp_path_factory):
    """A particle series whose count grows (ids kept) and a surface whose topology changes."""
    out = tmp_path_factory.mktemp("usd")
    rng = np.random.default_rng(7)
    particles = SeriesWriter(out / "particles.pvd")
    surface = SeriesWriter(out / "surface.pvd")
    for k in range(4):
        t = round(k / FPS, 9)
        cloud = pv.PolyData(rng.uniform(0, 1, (20 + 5 * k, 3)))
        cloud.point_data["velocity"] = rng.normal(size=(cloud.n_points, 3))
        cloud.point_data["id"] = np.arange(cloud.n_points, dtype=np.int64)[::-1]
        particles.write(cloud, t)
        sphere = pv.Sphere(radius=0.2 + 0.1 * k, theta_resolution=6 + 2 * k,
                           phi_resolution=5 + k).compute_normals()
        surface.write(sphere, t)
    return out / "particles.pvd", out / "surface.pvd"


def _check_stage(path, series_paths):
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == FPS and stage.GetFramesPerSecond() == FPS
    for series_path in series_paths:
        times, frames = read_series(series_path)
        prim = stage.GetPrimAtPath(f"/blobflow/{series_path.stem}")
        assert prim.IsValid()
        points_attr = UsdGeom.PointBased(prim).GetPointsAttr()
        codes = [round(t * FPS) for t in times]
        assert points_attr.GetTimeSamples() == codes  # one sample per frame, on whole frames
        assert stage.GetStartTimeCode() == codes[0] and stage.GetEndTimeCode() == codes[-1]
        for code, frame in zip(codes, frames, strict=False):
            np.testing.assert_array_equal(np.asarray(points_attr.Get(code)),
                                          np.asarray(frame.points, np.float32))
            velocities = UsdGeom.PointBased(prim).GetVelocitiesAttr().Get(code)
            if "velocity" in frame.point_data.keys():
                np.testing.assert_array_equal(np.asarray(velocities),
                                              frame.point_data["velocity"].astype(np.float32))
            if prim.IsA(UsdGeom.Mesh):
                mesh = UsdGeom.Mesh(prim)
                faces = frame.faces.reshape(-1, 4)  # triangles: 3, a, b, c
                assert list(mesh.GetFaceVertexCountsAttr().Get(code)) == faces[:, 0].tolist()
                assert (list(mesh.GetFaceVertexIndicesAttr().Get(code))
                        == faces[:, 1:].reshape(-1).tolist())
                np.testing.assert_array_equal(np.asarray(mesh.GetNormalsAttr().Get(code)),
                                              frame.point_data["Normals"].astype(np.float32))
            else:
                points = UsdGeom.Points(prim)
                assert list(points.GetIdsAttr().Get(code)) == frame.point_data["id"].tolist()
                assert len(points.GetWidthsAttr().Get(code)) == frame.n_points
            extent = np.asarray(UsdGeom.Boundable(prim).GetExtentAttr().Get(code))
            assert np.all(extent[0] <= frame.points.min(axis=0) + 1e-6)
            assert np.all(extent[1] >= frame.points.max(axis=0) - 1e-6)
    return stage


@pytest.mark.parametrize("suffix", [".usda", ".usd"])
def test_round_trip_of_particles_and_a_changing_surface(series, tmp_path, suffix):
    path = export_usd(series, tmp_path / f"scene{suffix}", fps=FPS)
    stage = _check_stage(path, series)
    assert stage.GetPrimAtPath("/blobflow/particles").IsA(UsdGeom.Points)
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/blobflow/surface"))
    counts = [len(mesh.GetFaceVertexCountsAttr().Get(c)) for c in range(4)]
    assert len(set(counts)) == 4  # the topology changes at every frame and survives
    assert mesh.GetFaceVertexIndicesAttr().GetTimeSamples() == [0, 1, 2, 3]
    assert stage.GetDefaultPrim().GetPath() == "/blobflow"


def test_flow_series_round_trip_and_fps_from_the_times(tmp_path):
    x = (np.mgrid[0:4, 0:4, 0:4].reshape(3, -1).T + 0.5) * 0.01 + [0, 0, 1.0]
    flow = Flow(SimulationSource(BallisticParticles(x, np.zeros_like(x)), fps=FPS, duration=0.2))
    flow.add("surface", *surface_stages(0.005, smooth_iterations=5, feature_smoothing=0),
             input="particles")
    paths = flow.run(tmp_path, progress=False)
    path = export_usd([paths["particles"], paths["surface"]], tmp_path / "flow.usd")  # fps: 10
    _check_stage(path, [paths["particles"], paths["surface"]])


def test_fixed_topology_is_written_once(tmp_path):
    writer = SeriesWriter(tmp_path / "cloth.pvd")
    sphere = pv.Sphere(theta_resolution=8, phi_resolution=6)
    for k in range(3):
        writer.write(sphere.translate((0, 0, -0.1 * k)), k / FPS)
    stage = _check_stage(export_usd(writer.path, tmp_path / "cloth.usda"), [writer.path])
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/blobflow/cloth"))
    assert mesh.GetFaceVertexIndicesAttr().GetTimeSamples() == []  # one value, not animated
    assert mesh.GetPointsAttr().GetTimeSamples() == [0, 1, 2]


def test_time_codes_snap_rounded_times_to_frames():
    assert time_codes([0.0, 0.033333333, 0.066666667, 1.0], 30).tolist() == [0, 1, 2, 30]
    assert time_codes([0.05], 30).tolist() == [1.5]


def test_bad_arguments_write_nothing(series, tmp_path):
    with pytest.raises(ValueError, match="usd_path must end in"):
        export_usd(series, tmp_path / "scene.abc")
    with pytest.raises(ValueError, match="fps"):
        export_usd(series, tmp_path / "scene.usd", fps=0)
    with pytest.raises(ValueError, match="names must differ"):
        export_usd([series[0], series[0]], tmp_path / "scene.usd")
    with pytest.raises(FileNotFoundError):
        export_usd(tmp_path / "missing.pvd", tmp_path / "scene.usd")
    assert not list(tmp_path.iterdir())


def test_cli_export(series, tmp_path, capsys):
    out = tmp_path / "cli.usda"
    code = main(["export", str(series[0]), str(series[1]), "--usd", str(out), "--fps", str(FPS)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert str(out) in captured.out
    _check_stage(out, series)
    code = main(["export", str(series[0]), "--usd", str(tmp_path / "x.obj")])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("blobflow: error: ") and err.count("\n") == 1
    assert "must end in .usd" in err and not (tmp_path / "x.obj").exists()


def _strands(cells, order):
    """3 strands of 4 segments (5 points each) as line cells, the points stored in ``order``
    (a permutation: frames are sorted by id, not by strand)."""
    strands = [np.c_[np.full(5, 0.1 * s), np.zeros(5), 1.0 - 0.05 * np.arange(5)]
               for s in range(3)]
    natural = np.concatenate(strands)  # point 5 s + j: strand s, vertex j
    stored = np.empty_like(natural)
    stored[order] = natural  # natural point p is stored at row order[p]
    rows = order.reshape(3, 5)
    if cells == "segments":
        lines = np.concatenate([[2, r[j], r[j + 1]] for r in rows for j in range(4)])
    else:
        lines = np.concatenate([[5, *r] for r in rows])
    mesh = pv.PolyData(stored, lines=lines)
    mesh.point_data["velocity"] = stored * 2.0
    return mesh, natural.reshape(3, 5, 3)


@pytest.mark.parametrize("cells", ["segments", "polylines"])
def test_hair_round_trip_one_curve_per_strand(tmp_path, cells):
    # BasisCurves hold one vertex count per curve and the curves' vertices in order: a strand
    # written as 2-point segments is one curve of 5 vertices, not 4 curves of 2
    order = np.random.default_rng(3).permutation(15)
    writer = SeriesWriter(tmp_path / "hair.pvd")
    for k in range(2):
        mesh, strands = _strands(cells, order)
        writer.write(mesh.translate((0, 0, -0.1 * k)), k / FPS)
    stage = Usd.Stage.Open(str(export_usd(writer.path, tmp_path / "hair.usda", fps=FPS)))
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath("/blobflow/hair"))
    assert curves.GetTypeAttr().Get() == UsdGeom.Tokens.linear
    counts = list(curves.GetCurveVertexCountsAttr().Get())
    assert counts == [5, 5, 5]
    for k in range(2):
        points = np.asarray(curves.GetPointsAttr().Get(k))
        assert len(points) == sum(counts)  # what a USD reader checks
        expected = (strands + [0, 0, -0.1 * k]).reshape(-1, 3).astype(np.float32)
        np.testing.assert_allclose(points, expected, atol=1e-6)  # strand after strand, in order
        np.testing.assert_allclose(np.asarray(curves.GetVelocitiesAttr().Get(k)),
                                   2.0 * strands.reshape(-1, 3),  # velocity: not moved
                                   rtol=1e-6, atol=1e-6)
        assert len(curves.GetWidthsAttr().Get(k)) == sum(counts)


def test_curves_of_lines_joins_only_cells_that_continue_one_another():
    from pipeline.io.usd import curves_of_lines

    # segments 0-1, 1-2 (one curve), then 5-6 (a new one), then a polyline 6-7-8 starting
    # where the last ended (joined), and an empty input
    counts, order = curves_of_lines([2, 2, 2, 3], [0, 1, 1, 2, 5, 6, 6, 7, 8])
    assert counts.tolist() == [3, 4] and order.tolist() == [0, 1, 2, 5, 6, 7, 8]
    counts, order = curves_of_lines([], [])
    assert counts.size == 0 and order.size == 0
