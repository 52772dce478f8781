"""pipeline.surface: particles -> watertight, smoothed surface meshes through VTK stages."""

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkDataObject, vtkPolyData
from vtkmodules.vtkIOXML import vtkXMLPolyDataReader, vtkXMLPolyDataWriter

from filters import BallisticParticles
from filters.kernels import lone_particle_radius
from filters.surface.mesh import mesh_stats
from filters.surface.splat import splat_dense, splat_sparse
from pipeline import SimulationSource
from pipeline.algorithm import Algorithm, connect_chain, run_chain, update
from pipeline.surface import (
    FeatureSmoothing,
    InterpolateAttributes,
    MarchingCubes,
    MetaballSplat,
    Normals,
    Smooth,
    surface_stages,
)
from pipeline.surface.contour import contour_dense, contour_sparse, polydata_to_mesh

S = 0.02  # lattice spacing (m)


def _lattice_in(inside, half_extent, offset=(0.003, -0.001, 0.002)):
    n = int(half_extent / S) + 2
    g = np.stack(np.meshgrid(*[np.arange(-n, n + 1)] * 3, indexing="ij"), -1).reshape(-1, 3) * S
    return g[inside(g)] + np.asarray(offset)


def _particles(x, velocity=None):
    poly = vtkPolyData()
    pts = vtkPoints()
    pts.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(x, dtype=np.float64), deep=True))
    poly.SetPoints(pts)
    if velocity is not None:
        arr = numpy_support.numpy_to_vtk(np.ascontiguousarray(velocity), deep=True)
        arr.SetName("velocity")
        poly.GetPointData().AddArray(arr)
    return poly


def _run(stages, data):
    return run_chain(stages, data)


def _stats(poly):
    return mesh_stats(*polydata_to_mesh(poly))


def test_one_particle_gives_the_predicted_sphere():
    centre = np.array([[0.0123, -0.0071, 0.0049]])
    cell = 0.0005
    out = _run([MetaballSplat(0.01, cell), MarchingCubes()], _particles(centre))
    pts, tris = polydata_to_mesh(out)
    radius = lone_particle_radius("sph", 0.01)  # W(r) / W(0) = 0.6: r = 0.311 * 4 * 0.01
    assert radius == pytest.approx(0.01244, abs=1e-5)
    dist = np.linalg.norm(pts - centre, axis=1)
    assert np.abs(dist - radius).max() < 0.1 * cell
    st = mesh_stats(pts, tris)
    assert st.closed and st.manifold and st.euler == 2
    assert st.volume == pytest.approx(4 / 3 * math.pi * radius**3, rel=0.01)


def test_lattice_ball_area_volume_and_topology_after_smoothing():
    r0 = 0.25
    x = _lattice_in(lambda g: np.linalg.norm(g, axis=1) < r0, r0)
    radius = (3 * len(x) / (4 * math.pi)) ** (1 / 3) * S  # the ball of the particles' volume
    assert radius == pytest.approx(r0, rel=0.01)
    # smoothing length 1.75 r (support 3.5 r), iso 0.6, cell r / 2; isotropic kernels and the
    # windowed sinc alone (100 iterations, pass band 0.001)
    stages = surface_stages(0.01, support_r=3.5, normals=True, anisotropic=False,
                            feature_smoothing=0, smooth_iterations=100, pass_band=0.001)
    out = _run(stages, _particles(x))
    st = _stats(out)
    assert st.closed and st.manifold and st.euler == 2 and st.components == 1
    assert st.area == pytest.approx(4 * math.pi * radius**2, rel=0.01)
    assert st.volume == pytest.approx(4 / 3 * math.pi * radius**3, rel=0.005)
    assert out.GetPointData().GetNormals() is not None


def test_torus_has_euler_characteristic_zero():
    big, small = 0.2, 0.07

    def inside(g):
        rho = np.hypot(g[:, 0], g[:, 1])
        return np.hypot(rho - big, g[:, 2]) < small

    x = _lattice_in(inside, big + small)
    st = _stats(_run([MetaballSplat(0.01), MarchingCubes(), Smooth(20, 0.05)], _particles(x)))
    assert st.closed and st.manifold and st.euler == 0 and st.components == 1


@pytest.mark.parametrize("gap, components", [(0.12, 2), (0.022, 1)])
def test_two_blobs_apart_or_merged(gap, components):
    blob = _lattice_in(lambda g: np.linalg.norm(g, axis=1) < 0.06, 0.06, offset=(0, 0, 0))
    width = np.ptp(blob[:, 0])
    x = np.concatenate([blob, blob + np.array([width + gap, 0.0, 0.0])])
    st = _stats(_run([MetaballSplat(0.01), MarchingCubes()], _particles(x)))
    assert st.closed and st.manifold
    assert st.components == components
    assert st.euler == 2 * components


def test_translation_translates_the_mesh():
    x = _lattice_in(lambda g: np.linalg.norm(g, axis=1) < 0.08, 0.08)
    cell = 0.005
    a = polydata_to_mesh(_run([MetaballSplat(0.01, cell), MarchingCubes()], _particles(x)))
    shift = np.array([7, -3, 11]) * cell  # whole cells: the same lattice samples
    b = polydata_to_mesh(_run([MetaballSplat(0.01, cell), MarchingCubes()],
                              _particles(x + shift)))
    assert a[1].shape == b[1].shape
    np.testing.assert_allclose(np.sort(a[0] + shift, axis=0), np.sort(b[0], axis=0), atol=1e-6)
    # any other shift: the same shape up to sampling
    c = polydata_to_mesh(_run([MetaballSplat(0.01, cell), MarchingCubes()],
                              _particles(x + np.array([0.1234, 0.0567, -0.0891]))))
    sa, sc = mesh_stats(*a), mesh_stats(*c)
    assert sc.volume == pytest.approx(sa.volume, rel=0.005)
    assert sc.area == pytest.approx(sa.area, rel=0.01)
    np.testing.assert_allclose(c[0].mean(axis=0) - [0.1234, 0.0567, -0.0891],
                               a[0].mean(axis=0), atol=0.2 * cell)


def _assert_same_mesh(a, b, tol=1e-6):
    """Same vertices (within float32 rounding, m) and the same oriented triangles."""
    (pa, ta), (pb, tb) = a, b
    assert pa.shape == pb.shape and ta.shape == tb.shape
    dist, match = cKDTree(pb).query(pa)
    assert dist.max() < tol
    assert np.unique(match).size == match.size
    mapped = match[ta]
    # rotate each triangle to start at its smallest index (keeps the orientation)

    def canon(t):
        first = np.argmin(t, axis=1)
        idx = (first[:, None] + np.arange(3)[None, :]) % 3
        t = np.take_along_axis(t, idx, axis=1)
        return t[np.lexsort(t.T[::-1])]

    np.testing.assert_array_equal(canon(mapped), canon(tb))


def test_sparse_and_dense_grids_give_the_same_mesh():
    x = _lattice_in(lambda g: np.linalg.norm(g, axis=1) < 0.16, 0.16)
    drop = x[:40] - x[:40].mean(axis=0) + np.array([0.4, 0.0, 0.0])
    x = np.concatenate([x, drop])  # and a detached droplet
    sparse = splat_sparse(x, 0.01, 0.005)
    assert sparse.inside_keys.size > 0  # interior really skipped
    ps, ts = contour_sparse(sparse)
    pd_, td = contour_dense(splat_dense(x, 0.01, 0.005))
    _assert_same_mesh((ps, ts), (pd_, td))
    st = mesh_stats(ps, ts)
    assert st.closed and st.manifold and st.components == 2
    # and through the VTK stages (image vs. brick set)
    a = polydata_to_mesh(_run([MetaballSplat(0.01, sparse=True), MarchingCubes()], _particles(x)))
    b = polydata_to_mesh(_run([MetaballSplat(0.01, sparse=False), MarchingCubes()],
                              _particles(x)))
    _assert_same_mesh(a, b)


def test_zero_particles_give_an_empty_valid_mesh(tmp_path):
    out = _run(surface_stages(0.01), _particles(np.zeros((0, 3))))
    assert out.GetNumberOfPoints() == 0 and out.GetNumberOfCells() == 0
    path = tmp_path / "empty.vtp"
    writer = vtkXMLPolyDataWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(out)
    assert writer.Write() == 1
    reader = vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    back = reader.GetOutput()
    assert back.GetNumberOfPoints() == 0 and back.GetNumberOfCells() == 0
    dense = _run([MetaballSplat(0.01, sparse=False), MarchingCubes()],
                 _particles(np.zeros((0, 3))))
    assert dense.GetNumberOfPoints() == 0


def test_nan_positions_raise_value_error():
    x = np.zeros((3, 3))
    x[1, 2] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        _run([MetaballSplat(0.01), MarchingCubes()], _particles(x))
    with pytest.raises(ValueError):
        MetaballSplat(-0.01)
    with pytest.raises(ValueError):
        MetaballSplat(0.01, kernel="cubic")


def test_velocity_is_interpolated_onto_vertices():
    x = _lattice_in(lambda g: np.linalg.norm(g, axis=1) < 0.06, 0.06)
    v = np.tile([1.0, -2.0, 3.0], (len(x), 1))
    out = _run([MetaballSplat(0.01), MarchingCubes(), InterpolateAttributes(radius=0.01), Smooth(),
                Normals()], _particles(x, v))
    vel = numpy_support.vtk_to_numpy(out.GetPointData().GetArray("velocity"))
    assert vel.shape == (out.GetNumberOfPoints(), 3)
    np.testing.assert_allclose(vel, np.tile([1.0, -2.0, 3.0], (len(vel), 1)), rtol=1e-12)


def test_stages_follow_time_requests_of_a_temporal_source():
    x = _lattice_in(lambda g: np.linalg.norm(g, axis=1) < 0.05, 0.05) + np.array([0, 0, 10.0])
    v = np.tile([1.0, 0.0, 0.0], (len(x), 1))
    sim = BallisticParticles(x, v, max_dt=1 / 100)
    source = SimulationSource(sim, fps=10, duration=0.5)
    stages = surface_stages(0.01, smooth_iterations=10, anisotropic=False, feature_smoothing=0)
    connect_chain(stages, upstream=source)
    centres = []
    for t in (0.3, 0.1):
        out = update(stages[-1], [source] + stages, t)
        assert out.GetInformation().Get(vtkDataObject.DATA_TIME_STEP()) == pytest.approx(t)
        pts, tris = polydata_to_mesh(out)
        assert mesh_stats(pts, tris).closed
        centres.append(pts.mean(axis=0))
        expected = x.mean(axis=0) + np.array([t, 0.0, -0.5 * 9.81 * t * t])
        np.testing.assert_allclose(pts.mean(axis=0), expected, atol=0.003)
    assert centres[0][0] - centres[1][0] == pytest.approx(0.2, abs=0.003)


def test_per_particle_radius_and_container_clip():
    x = np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0]])
    r = np.array([0.01, 0.02])
    poly = _particles(x)
    arr = numpy_support.numpy_to_vtk(r, deep=True)
    arr.SetName("radius")
    poly.GetPointData().AddArray(arr)
    pts, tris = polydata_to_mesh(_run([MetaballSplat(0.01, 0.001, radius_array="radius"),
                                       MarchingCubes()], poly))
    for centre, radius in zip(x, r, strict=False):
        near = np.linalg.norm(pts - centre, axis=1) < 0.1
        d = np.linalg.norm(pts[near] - centre, axis=1)
        assert d.mean() == pytest.approx(lone_particle_radius("sph", radius), rel=0.01)
    # liquid ball clipped by the inside of a tank whose lid is at z = 0.05
    from filters.geometry import Box
    ball = _lattice_in(lambda g: np.linalg.norm(g, axis=1) < 0.1, 0.1)
    tank = Box((-1.0, -1.0, -1.0), (1.0, 1.0, 0.05))
    for sparse in (True, False):
        out = _run([MetaballSplat(0.01, sparse=sparse, implicit=tank, operation="intersection"),
                    MarchingCubes()], _particles(ball))
        p, t = polydata_to_mesh(out)
        st = mesh_stats(p, t)
        assert st.closed and st.manifold and st.euler == 2
        assert p[:, 2].max() == pytest.approx(0.05, abs=1e-6)
        flat = np.abs(p[:, 2] - 0.05) < 1e-6
        assert flat.sum() > 100  # a flat lid where the tank cuts the liquid


def test_feature_smoothing_flattens_a_pool_and_keeps_the_mesh_valid():
    # a jittered lattice pool: the top face gets flatter, the mesh stays closed, the
    # velocity is interpolated at the smoothed vertices, and the stage equals the array filter
    rng = np.random.default_rng(0)
    g = np.stack(np.meshgrid(np.arange(14), np.arange(14), np.arange(5), indexing="ij"), -1)
    x = g.reshape(-1, 3) * S + rng.uniform(-0.1 * S, 0.1 * S, (14 * 14 * 5, 3))
    v = np.tile([0.5, 0.0, -1.0], (len(x), 1))
    plain = _run([MetaballSplat(0.01), MarchingCubes()], _particles(x, v))
    smooth = _run([MetaballSplat(0.01), MarchingCubes(), FeatureSmoothing(25, radius=0.01),
                   InterpolateAttributes(radius=0.01)], _particles(x, v))
    p0, t0 = polydata_to_mesh(plain)
    p1, t1 = polydata_to_mesh(smooth)
    assert np.array_equal(t0, t1)
    st = mesh_stats(p1, t1)
    assert st.closed and st.manifold and st.components == 1
    top = ((p0[:, 0] > 3 * S) & (p0[:, 0] < 10 * S) & (p0[:, 1] > 3 * S) & (p0[:, 1] < 10 * S)
           & (p0[:, 2] > 3.5 * S))
    assert top.sum() > 200
    assert p1[top, 2].std() < 0.6 * p0[top, 2].std()
    from filters.surface.smoothing import smooth_surface

    expected = smooth_surface(p0.astype(np.float64), t0, x, 0.01, iterations=25)
    np.testing.assert_allclose(p1, expected, atol=1e-7)
    vel = numpy_support.vtk_to_numpy(smooth.GetPointData().GetArray("velocity"))
    np.testing.assert_allclose(vel, np.tile([0.5, 0.0, -1.0], (len(vel), 1)), rtol=1e-12)


class _DropFieldData(Algorithm):
    """A VTK filter that keeps the geometry and drops every point, cell and field array."""

    def __init__(self):
        Algorithm.__init__(self, nInputPorts=1, inputType="vtkPolyData", nOutputPorts=1,
                           outputType="vtkPolyData")

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkPolyData.GetData(inInfo[0], 0)
        out = vtkPolyData.GetData(outInfo, 0)
        out.SetPoints(inp.GetPoints())
        out.SetPolys(inp.GetPolys())
        return 1


def test_particle_stages_read_the_particles_through_any_filter():
    # the particles reach feature smoothing and the attribute interpolation on their own input
    # port: a VTK filter between the stages that drops every array changes nothing
    x = _lattice_in(lambda g: np.linalg.norm(g, axis=1) < 0.07, 0.07)
    v = np.tile([1.0, -2.0, 3.0], (len(x), 1))
    direct = _run([MetaballSplat(0.01), MarchingCubes(), FeatureSmoothing(5, radius=0.01),
                   InterpolateAttributes(radius=0.01)], _particles(x, v))
    through = _run([MetaballSplat(0.01), MarchingCubes(), _DropFieldData(),
                    FeatureSmoothing(5, radius=0.01), _DropFieldData(),
                    InterpolateAttributes(radius=0.01)], _particles(x, v))
    np.testing.assert_array_equal(polydata_to_mesh(through)[0], polydata_to_mesh(direct)[0])
    vel = numpy_support.vtk_to_numpy(through.GetPointData().GetArray("velocity"))
    np.testing.assert_allclose(vel, np.tile([1.0, -2.0, 3.0], (len(vel), 1)), rtol=1e-12)


@pytest.mark.parametrize("build, error, match", [
    (lambda: FeatureSmoothing(-1), ValueError, "iterations"),
    (lambda: FeatureSmoothing(5, radius=0.0), ValueError, "radius"),
    (lambda: InterpolateAttributes("velocity"), TypeError, "attributes"),
    (lambda: InterpolateAttributes(kernel="cubic"), ValueError, "kernel"),
    (lambda: MarchingCubes(math.nan), ValueError, "value"),
    (lambda: MetaballSplat(0.01, support_r=-1.0), ValueError, "support_r"),
    (lambda: MetaballSplat(0.01, sparse="false"), TypeError, "sparse"),
    (lambda: MetaballSplat(0.01, radius_array=3), TypeError, "radius_array"),
    (lambda: MetaballSplat(0.01, implicit="tank"), TypeError, "implicit"),
    (lambda: MetaballSplat(0.01, anisotropy={"stretch": 0.5}), ValueError, "stretch"),
    (lambda: Smooth(iterations=-1), ValueError, "iterations"),
    (lambda: surface_stages(0.01, normals="yes"), TypeError, "normals"),
])
def test_every_stage_validates_every_argument(build, error, match):
    with pytest.raises(error, match=match):
        build()
