"""``MarchingCubes(method="tetrahedra")``: the VTK stage and the surface chain with marching
tetrahedra (dense images and brick sets, attributes, options)."""

import numpy as np
import pytest
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkPolyData

from filters.surface.mesh import mesh_stats
from filters.surface.splat import splat_sparse
from pipeline.algorithm import run_chain
from pipeline.surface import MarchingCubes, MetaballSplat, surface_stages
from pipeline.surface.contour import contour_dense, contour_sparse, polydata_to_mesh
from pipeline.surface.options import SURFACE_PARAMETERS


def _ball(radius=0.1, spacing=0.02):
    n = int(radius / spacing) + 2
    g = np.stack(np.meshgrid(*[np.arange(-n, n + 1)] * 3, indexing="ij"), -1).reshape(-1, 3)
    g = g * spacing
    return g[np.linalg.norm(g, axis=1) < radius] + np.array([0.003, -0.001, 0.002])


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


def _sorted_triangles(points, tris):
    corners = np.asarray(points)[np.asarray(tris)].reshape(len(tris), 9)
    return corners[np.lexsort(corners.T[::-1])]


def test_images_and_brick_sets_give_the_same_watertight_mesh():
    x = _ball()
    sparse = polydata_to_mesh(run_chain([MetaballSplat(0.01, sparse=True),
                                         MarchingCubes(method="tetrahedra")], _particles(x)))
    dense = polydata_to_mesh(run_chain([MetaballSplat(0.01, sparse=False),
                                        MarchingCubes(method="tetrahedra")], _particles(x)))
    assert sparse[0].shape == dense[0].shape and sparse[1].shape == dense[1].shape
    # the same triangles up to the order of vertices in each (rotation kept: orientation)
    a = np.sort(_sorted_triangles(*sparse), axis=0)
    b = np.sort(_sorted_triangles(*dense), axis=0)
    np.testing.assert_array_equal(a, b)
    st = mesh_stats(*sparse)
    assert st.closed and st.manifold and st.euler == 2 and st.components == 1
    # the same surface as flying edges, with more (and thinner) triangles
    cubes = mesh_stats(*polydata_to_mesh(run_chain([MetaballSplat(0.01), MarchingCubes()],
                                                   _particles(x))))
    assert st.volume == pytest.approx(cubes.volume, rel=2e-3)
    assert st.area == pytest.approx(cubes.area, rel=5e-3)
    assert 2 * cubes.triangles < st.triangles < 5 * cubes.triangles


def test_array_contouring_takes_the_method_too():
    grid = splat_sparse(_ball(), 0.01, 0.005)
    a = contour_sparse(grid, method="tetrahedra")
    b = contour_dense(grid.to_dense(), method="tetrahedra")
    np.testing.assert_array_equal(np.sort(_sorted_triangles(*a), axis=0),
                                  np.sort(_sorted_triangles(*b), axis=0))
    with pytest.raises(ValueError, match="method"):
        contour_sparse(grid, method="marching_squares")


def test_surface_chain_with_tetrahedra_carries_the_attributes():
    x = _ball()
    v = np.tile([1.0, -2.0, 3.0], (len(x), 1))
    stages = surface_stages(0.01, contour="tetrahedra", anisotropic=False, feature_smoothing=5,
                            smooth_iterations=10)
    assert stages[1].method == "tetrahedra"
    out = run_chain(stages, _particles(x, v))
    vel = numpy_support.vtk_to_numpy(out.GetPointData().GetArray("velocity"))
    assert vel.shape == (out.GetNumberOfPoints(), 3)
    np.testing.assert_allclose(vel, np.tile([1.0, -2.0, 3.0], (len(vel), 1)), rtol=1e-12)
    st = mesh_stats(*polydata_to_mesh(out))
    assert st.closed and st.manifold and st.euler == 2
    assert out.GetPointData().GetNormals() is not None
    assert SURFACE_PARAMETERS["contour"].default == "flying_edges"


def test_method_is_validated():
    with pytest.raises(ValueError, match="method"):
        MarchingCubes(method="cubes")
    with pytest.raises(ValueError, match="method"):
        surface_stages(0.01, contour="marching")
