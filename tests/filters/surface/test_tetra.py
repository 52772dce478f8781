"""Marching tetrahedra on the Kuhn split: accuracy, watertightness, bricks, threads."""

import math

import numba
import numpy as np
import pytest

from filters.simplices import CORNER_OFFSETS, KUHN_DIRECTIONS, KUHN_TETS, kuhn_locate
from filters.surface.grid import SparseGrid, pack_keys
from filters.surface.mesh import mesh_stats
from filters.surface.splat import splat_dense, splat_sparse
from filters.surface.tetra import contour_array, contour_grid


def test_kuhn_split_fills_the_cube_and_cuts_opposite_faces_alike():
    corners = CORNER_OFFSETS.astype(float)
    vols = [np.linalg.det((corners[t[1:]] - corners[t[0]]).T) / 6.0 for t in KUHN_TETS]
    assert np.allclose(vols, 1.0 / 6.0)  # six positive tetrahedra of volume 1/6: the cube
    faces = {tuple(sorted(f)) for t in KUHN_TETS for f in
             ((t[0], t[1], t[2]), (t[0], t[1], t[3]), (t[0], t[2], t[3]), (t[1], t[2], t[3]))}
    for axis in range(3):
        low = {f for f in faces if all(CORNER_OFFSETS[c, axis] == 0 for c in f)}
        high = {f for f in faces if all(CORNER_OFFSETS[c, axis] == 1 for c in f)}
        shifted = {tuple(sorted(c | (1 << axis) for c in f)) for f in low}
        assert len(low) == 2 and shifted == high  # the neighbour's face is cut the same way
    edges = {tuple(CORNER_OFFSETS[b] - CORNER_OFFSETS[a]) for t in KUHN_TETS
             for a in t for b in t if a < b}
    assert edges == {tuple(d) for d in KUHN_DIRECTIONS}
    t = np.random.default_rng(0).uniform(size=(500, 3))
    which, w = kuhn_locate(t)
    np.testing.assert_allclose(np.einsum("mk,mkj->mj", w, corners[KUHN_TETS[which]]), t,
                               atol=1e-15)
    assert w.min() >= 0.0


def _sphere_field(radius_cells, centre=(0.31, -0.17, 0.23)):
    n = int(radius_cells) + 3
    ax = np.arange(-n, n + 1, dtype=np.float64)
    z, y, x = np.meshgrid(ax - centre[2], ax - centre[1], ax - centre[0], indexing="ij")
    return np.sqrt(x * x + y * y + z * z) - radius_cells, np.array([-n, -n, -n])


def _sparse_from_dense(values, index_origin, block):
    """The SparseGrid of a dense field (outside it: +1): blocks whose voxels, grown by one voxel
    on every side, hold both signs keep their values; the others are inside or outside."""
    pad = 2 * block + 1
    padded = np.pad(values, pad, constant_values=1.0)
    origin = np.asarray(index_origin) - pad
    nz, ny, nx = values.shape
    lo = np.asarray(index_origin) // block - 1
    hi = -(-(np.asarray(index_origin) + [nx, ny, nz]) // block) + 1
    keys, data, inside = [], [], []
    for bz in range(lo[2], hi[2]):
        for by in range(lo[1], hi[1]):
            for bx in range(lo[0], hi[0]):
                g = np.array([bx, by, bz]) * block - origin  # the block's first voxel in padded
                grown = padded[g[2] - 1:g[2] + block + 1, g[1] - 1:g[1] + block + 1,
                               g[0] - 1:g[0] + block + 1]
                if grown.max() < 0:
                    inside.append((bx, by, bz))
                elif grown.min() < 0:
                    keys.append((bx, by, bz))
                    data.append(padded[g[2]:g[2] + block, g[1]:g[1] + block, g[0]:g[0] + block])
    return SparseGrid(1.0, block, pack_keys(np.array(keys)), np.array(data, np.float32),
                      np.sort(pack_keys(np.array(inside))), -1.0, 1.0)


def test_sphere_area_and_volume_at_40_cells_per_diameter():
    values, origin = _sphere_field(20.0)
    pts, tris = contour_array(values.astype(np.float32), origin, 1.0)
    st = mesh_stats(pts, tris)
    assert st.closed and st.manifold and st.euler == 2 and st.components == 1
    assert st.area == pytest.approx(4 * math.pi * 20.0**2, rel=0.01)
    assert st.volume == pytest.approx(4 / 3 * math.pi * 20.0**3, rel=0.005)
    # every vertex on the sphere to the interpolation's accuracy
    dist = np.linalg.norm(pts - np.array([0.31, -0.17, 0.23]), axis=1)
    assert np.abs(dist - 20.0).max() < 0.05
    # the sparse brick path gives the same mesh: no cracks where bricks meet, with bricks of
    # 8 or 16 voxels (one or two blocks) and tiles of 32 or 5 voxels in the dense path
    grid = _sparse_from_dense(values.astype(np.float32), origin, 8)
    assert grid.inside_keys.size > 0
    for group in (1, 2):
        _assert_same_mesh(contour_grid(grid, group=group), (pts, tris))
    _assert_same_mesh(contour_array(values.astype(np.float32), origin, 1.0, tile=5), (pts, tris))


def _assert_same_mesh(a, b):
    """The same vertices and the same oriented triangles, compared by coordinates (two
    vertices may coincide in float32: indices alone could differ)."""
    (pa, ta), (pb, tb) = a, b
    assert pa.shape == pb.shape and ta.shape == tb.shape

    def canon(p, t):  # each triangle from its lexicographically least vertex, then all sorted
        corners = p[t]  # (T, 3, 3)
        flat = corners.reshape(-1, 3)
        rank = np.empty(flat.shape[0], np.int64)
        rank[np.lexsort(flat.T[::-1])] = np.arange(flat.shape[0])
        first = np.argmin(rank.reshape(-1, 3), axis=1)
        idx = (first[:, None] + np.arange(3)) % 3
        rows = np.take_along_axis(corners, idx[:, :, None], axis=1).reshape(len(t), 9)
        return rows[np.lexsort(rows.T[::-1])]

    assert np.array_equal(canon(pa, ta), canon(pb, tb))


def _block_100k():
    g = np.stack(np.meshgrid(np.arange(50), np.arange(50), np.arange(40), indexing="ij"), -1)
    rng = np.random.default_rng(0)
    g = g.reshape(-1, 3) * 0.02
    return np.ascontiguousarray(g + rng.uniform(-0.002, 0.002, g.shape))


def test_sparse_100k_block_is_closed_and_manifold():
    grid = splat_sparse(_block_100k(), 0.01, 0.005, kernel="sph", iso=0.6)
    pts, tris = contour_grid(grid, group=4)
    st = mesh_stats(pts, tris)
    assert st.closed and st.manifold and st.euler == 2 and st.components == 1
    assert st.volume == pytest.approx(100_000 * 0.02**3, rel=0.02)  # the particles' volume


def test_sparse_and_dense_splats_give_the_same_mesh():
    g = np.stack(np.meshgrid(*[np.arange(-8, 9)] * 3, indexing="ij"), -1).reshape(-1, 3) * 0.02
    x = g[np.linalg.norm(g, axis=1) < 0.16] + [0.003, -0.001, 0.002]
    drop = x[:40] - x[:40].mean(axis=0) + [0.4, 0.0, 0.0]
    x = np.concatenate([x, drop])
    sparse = contour_grid(splat_sparse(x, 0.01, 0.005))
    field = splat_dense(x, 0.01, 0.005)
    dense = contour_array(field.values, field.index_origin, field.cell_size)
    _assert_same_mesh(sparse, dense)
    st = mesh_stats(*sparse)
    assert st.closed and st.manifold and st.components == 2


def test_mesh_does_not_depend_on_the_thread_count():
    g = np.stack(np.meshgrid(*[np.arange(-8, 9)] * 3, indexing="ij"), -1).reshape(-1, 3) * 0.02
    grid = splat_sparse(g[np.linalg.norm(g, axis=1) < 0.16], 0.01, 0.005)
    meshes = []
    for threads in (1, 2):
        previous = numba.get_num_threads()
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
        try:
            meshes.append(contour_grid(grid))
        finally:
            numba.set_num_threads(previous)
    assert np.array_equal(meshes[0][0], meshes[1][0]) and np.array_equal(meshes[0][1],
                                                                          meshes[1][1])


def test_voxels_exactly_on_the_iso_value_and_empty_fields():
    ax = np.arange(20)
    z, y, x = np.meshgrid(ax, ax, ax, indexing="ij")
    box = np.maximum(np.maximum(abs(x - 10), abs(y - 10)), abs(z - 10)) - 5.0  # 0 on voxels
    pts, tris = contour_array(box.astype(np.float32), (0, 0, 0), 1.0, tile=7)
    st = mesh_stats(pts, tris)
    assert st.closed and st.manifold and st.euler == 2
    assert 0.95 * 10.0**3 < st.volume <= 10.0**3  # the cube [5, 15]^3, edges chamfered
    assert contour_array(np.ones((4, 4, 4), np.float32), (0, 0, 0), 1.0)[1].shape == (0, 3)
    assert contour_array(-np.ones((1, 4, 4), np.float32), (0, 0, 0), 1.0)[1].shape == (0, 3)
    with pytest.raises(ValueError, match="group"):
        contour_grid(splat_sparse(np.zeros((1, 3)), 0.01, 0.005), group=0)
