"""Line casts against a triangle mesh (filters.surface.linecast): the grid walk finds what a
test of every triangle finds, bit for bit, for any cell size; fans of long thin triangles."""

import numpy as np
import pytest
from test_temporal import grid_plane, uv_sphere

from filters.surface.linecast import EDGE_SLACK, TriangleGrid, normal_offsets
from filters.surface.temporal import smooth_across_frames, vertex_normals


def brute_force(p, d, V, T, reach):
    """Möller & Trumbore (1997) against every triangle, in NumPy, with the operations of the
    kernel in the same order (so the same bits); the least |t| within reach, of t and -t the
    positive one."""
    a, b, c = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    e1, e2 = b - a, c - a
    out = np.full(len(p), np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        for i in range(len(p)):
            dx, dy, dz = d[i]
            qx = dy * e2[:, 2] - dz * e2[:, 1]
            qy = dz * e2[:, 0] - dx * e2[:, 2]
            qz = dx * e2[:, 1] - dy * e2[:, 0]
            det = e1[:, 0] * qx + e1[:, 1] * qy + e1[:, 2] * qz
            inv = 1.0 / det
            s = p[i] - a
            u = (s[:, 0] * qx + s[:, 1] * qy + s[:, 2] * qz) * inv
            rx = s[:, 1] * e1[:, 2] - s[:, 2] * e1[:, 1]
            ry = s[:, 2] * e1[:, 0] - s[:, 0] * e1[:, 2]
            rz = s[:, 0] * e1[:, 1] - s[:, 1] * e1[:, 0]
            v = (dx * rx + dy * ry + dz * rz) * inv
            t = (e2[:, 0] * rx + e2[:, 1] * ry + e2[:, 2] * rz) * inv
            ok = ((det != 0.0) & (u >= -EDGE_SLACK) & (u <= 1.0 + EDGE_SLACK)
                  & (v >= -EDGE_SLACK) & (u + v <= 1.0 + EDGE_SLACK) & (np.abs(t) <= reach))
            if ok.any():
                t = t[ok]
                least = np.abs(t).min()
                out[i] = t[np.abs(t) == least].max()
    return out


def fan(corners, apex=0):
    """A convex polygon triangulated as a fan from one corner (as a cut face on a wall)."""
    n = len(corners)
    return np.asarray(corners, float), np.array([[apex, (apex + i) % n, (apex + i + 1) % n]
                                                 for i in range(1, n - 1)])


def scene(seed):
    """A jittered sphere, a plane below it and a fan of long thin triangles on a wall beside
    it, and points near the sphere with jittered normals."""
    rng = np.random.default_rng(seed)
    v1, t1 = uv_sphere(0.3, n=20)
    v1 = v1 + rng.normal(0.0, 0.004, v1.shape)
    v2, t2 = grid_plane(-0.32, n=15, jitter=0.01, seed=seed)
    v2 = v2 - [0.5, 0.5, 0.0]
    angle = np.linspace(0.0, 2 * np.pi, 60, endpoint=False)
    v3, t3 = fan(np.column_stack([np.full(60, 0.31), 0.3 * np.cos(angle),
                                  0.25 * np.sin(angle)]))
    V = np.concatenate([v1, v2, v3])
    T = np.concatenate([t1, t2 + len(v1), t3 + len(v1) + len(v2)])
    src, st = uv_sphere(0.29, n=16)
    p = src + rng.normal(0.0, 0.01, src.shape)
    d = vertex_normals(src, st) + rng.normal(0.0, 0.2, src.shape)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return p, d, V, T


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_walk_finds_what_testing_every_triangle_finds_bitwise(seed):
    p, d, V, T = scene(seed)
    for reach in (0.01, 0.05, 0.2):
        expected = brute_force(p, d, V, T, reach)
        assert 0.1 < np.isfinite(expected).mean()  # crossings found, and some not (at 0.01)
        for cell in (0.3, 1.0, 2.5):
            got = normal_offsets(p, d, V, T, reach, cell_over_reach=cell)
            assert np.array_equal(got, expected, equal_nan=True), (reach, cell)


def test_a_soup_of_triangles_crossed_at_every_distance():
    # triangles in every orientation, lines in every direction: the nearest crossing is as
    # often in a later cell of the walk as in the first, on either side
    rng = np.random.default_rng(6)
    centres = rng.uniform(0.0, 1.0, (3000, 1, 3))
    V = (centres + rng.normal(0.0, 0.03, (3000, 3, 3))).reshape(-1, 3)
    T = np.arange(len(V)).reshape(-1, 3)
    p = rng.uniform(0.1, 0.9, (1500, 3))
    d = rng.normal(0.0, 1.0, (1500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    for reach in (0.05, 0.2):
        expected = brute_force(p, d, V, T, reach)
        assert 0.2 < np.isfinite(expected).mean() < 0.98
        for cell in (0.25, 1.0, 3.0):
            got = normal_offsets(p, d, V, T, reach, cell_over_reach=cell)
            assert np.array_equal(got, expected, equal_nan=True), (reach, cell)


def test_lines_along_the_fan_and_through_its_apex_find_the_wall():
    # every point on the wall's cut face, cast across it, from near the apex where all the
    # fan's triangles meet and along their long thin sides
    angle = np.linspace(0.0, 2 * np.pi, 200, endpoint=False)
    V, T = fan(np.column_stack([np.zeros(200), np.cos(angle), 0.5 * np.sin(angle)]))
    rng = np.random.default_rng(3)
    yz = np.concatenate([rng.uniform(-0.6, 0.6, (300, 2)) * [1.0, 0.5],
                         V[0, 1:] + rng.uniform(-1e-3, 1e-3, (50, 2))])
    yz = yz[(yz[:, 0] ** 2 + (yz[:, 1] / 0.5) ** 2) < 0.999]
    p = np.column_stack([np.full(len(yz), -0.02), yz])
    d = np.tile([1.0, 0.0, 0.0], (len(p), 1))
    np.testing.assert_allclose(normal_offsets(p, d, V, T, 0.05), 0.02, rtol=1e-12)
    np.testing.assert_allclose(normal_offsets(p, -d, V, T, 0.05), -0.02, rtol=1e-12)
    assert np.array_equal(normal_offsets(p, d, V, T, 0.05), brute_force(p, d, V, T, 0.05))


def test_a_grid_built_once_serves_many_casts_and_smoothing_takes_it():
    p, d, V, T = scene(4)
    grid = TriangleGrid(V, T, 0.05)
    every = normal_offsets(p, d, V, T, 0.05)
    assert np.array_equal(grid.offsets(p, d), every, equal_nan=True)
    some = np.arange(3, len(p), 7)
    partial = grid.offsets(p, d, only=some)
    assert np.array_equal(partial[some], every[some], equal_nan=True)
    assert np.isnan(np.delete(partial, some)).all() and np.isfinite(partial[some]).any()
    with pytest.raises(ValueError, match="only"):
        grid.offsets(p, d, only=[len(p)])
    src, st = uv_sphere(0.29, n=16)
    n = vertex_normals(src, st)
    by_mesh = smooth_across_frames(src, st, [(p, V, T)], [0.5, 0.5], 0.05, normals=n)
    by_grid = smooth_across_frames(src, st, [(p, grid)], [0.5, 0.5], 0.05, normals=n)
    assert np.array_equal(by_mesh, by_grid)
    with pytest.raises(ValueError, match="reach"):
        smooth_across_frames(src, st, [(p, TriangleGrid(V, T, 0.1))], [0.5, 0.5], 0.05)
    with pytest.raises(ValueError, match="cell_over_reach"):
        TriangleGrid(V, T, 0.05, cell_over_reach=0.0)


def test_vertex_normals_are_numpys_area_weighted_sums_bitwise():
    # the kernel sums face normals per corner in triangle order as np.bincount does
    p, _, V, T = scene(5)
    face = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    n = np.zeros_like(V)
    for corner in range(3):
        for axis in range(3):
            n[:, axis] += np.bincount(T[:, corner], weights=face[:, axis], minlength=len(V))
    length = np.linalg.norm(n, axis=1)
    expected = np.divide(n, length[:, None], out=np.zeros_like(n), where=length[:, None] > 0)
    V2 = np.concatenate([V, [[9.0, 9.0, 9.0]]])  # a vertex of no triangle: (0, 0, 0)
    got = vertex_normals(V2, T)
    assert np.array_equal(got[:-1], expected) and np.array_equal(got[-1], [0.0, 0.0, 0.0])
