"""Offsets between surfaces along normals and the motion-compensated temporal filter
(filters.surface.temporal): analytic planes and spheres, rigid motion, static frames."""

import numpy as np
import pytest

from filters.surface.temporal import normal_offsets, smooth_across_frames, vertex_normals


def grid_plane(z, n=12, size=1.0, jitter=0.0, seed=0):
    """A triangulated square [0, size]^2 at height z (vertices, triangles)."""
    g = np.linspace(0.0, size, n)
    x, y = np.meshgrid(g, g, indexing="ij")
    v = np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], axis=1)
    if jitter:
        v[:, :2] += np.random.default_rng(seed).uniform(-jitter, jitter, (v.shape[0], 2))
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = (idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(),
                  idx[:-1, 1:].ravel())
    return v, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def uv_sphere(radius, n=64):
    """A closed UV sphere of ``radius`` about the origin (vertices, outward triangles)."""
    theta = np.linspace(0.0, np.pi, n + 1)[1:-1]
    phi = np.linspace(0.0, 2 * np.pi, 2 * n, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    v = np.concatenate([[[0, 0, 1.0]], ring, [[0, 0, -1.0]]]) * radius
    m = 2 * n
    tris = [[0, 1 + (j + 1) % m, 1 + j] for j in range(m)]
    for i in range(n - 2):
        for j in range(m):
            a, b = 1 + i * m + j, 1 + i * m + (j + 1) % m
            tris += [[a, b, b + m], [a, b + m, a + m]]
    last = 1 + (n - 1) * m
    tris += [[last, 1 + (n - 2) * m + j, 1 + (n - 2) * m + (j + 1) % m] for j in range(m)]
    return v, np.asarray(tris, np.int64)[:, ::-1].copy()  # listed clockwise: reversed


def test_offset_to_a_parallel_plane_is_its_distance_with_the_sign_of_the_direction():
    v, t = grid_plane(0.1, jitter=0.02)
    rng = np.random.default_rng(1)
    p = np.column_stack([rng.uniform(0.1, 0.9, (200, 2)), np.zeros(200)])
    up = np.tile([0.0, 0.0, 1.0], (200, 1))
    np.testing.assert_allclose(normal_offsets(p, up, v, t, 0.5), 0.1, atol=1e-12)
    np.testing.assert_allclose(normal_offsets(p, -up, v, t, 0.5), -0.1, atol=1e-12)
    # beyond reach, or off the mesh's edge: no crossing
    assert np.isnan(normal_offsets(p, up, v, t, 0.05)).all()
    assert np.isnan(normal_offsets(p + [2.0, 0.0, 0.0], up, v, t, 0.5)).all()


def test_a_slanted_line_finds_the_crossing_along_it():
    v, t = grid_plane(0.1)
    d = np.array([[0.6, 0.0, 0.8]])
    np.testing.assert_allclose(normal_offsets(np.array([[0.5, 0.5, 0.0]]), d, v, t, 1.0),
                               0.125, rtol=1e-12)


def test_offset_between_concentric_spheres_is_the_difference_of_radii():
    inner, ti = uv_sphere(1.0)
    outer, to = uv_sphere(1.05)
    normals = inner / np.linalg.norm(inner, axis=1, keepdims=True)
    sag = 1.05 * (1 - np.cos(np.pi / 64))  # how far the outer sphere's flat facets sit inside it
    t = normal_offsets(inner, normals, outer, to, 0.2)
    assert np.isfinite(t).all()
    assert (t <= 0.05 + 1e-12).all() and (t >= 0.05 - sag - 1e-12).all()
    # from outside, looking inward: the same surface, positive along the direction
    t_out = normal_offsets(1.1 * inner, -normals, outer, to, 0.2)
    assert (t_out >= 0.05 - 1e-12).all() and (t_out <= 0.05 + sag + 1e-12).all()
    # the nearest of two crossings: the inner sphere's vertices, a line through both spheres
    both = normal_offsets(inner, normals, np.concatenate([outer, 0.9 * inner]),
                          np.concatenate([to, ti + len(outer)]), 0.2)
    np.testing.assert_array_equal(both, t)


def test_large_triangles_are_found_from_anywhere_they_cover():
    # a tank wall's cut face: two triangles much larger than the search reach
    v = np.array([[0.0, 0.0, 0.2], [10.0, 0.0, 0.2], [10.0, 10.0, 0.2], [0.0, 10.0, 0.2]])
    t = np.array([[0, 1, 2], [0, 2, 3]])
    rng = np.random.default_rng(2)
    p = np.column_stack([rng.uniform(0.5, 9.5, (500, 2)), np.full(500, 0.15)])
    up = np.tile([0.0, 0.0, 1.0], (500, 1))
    np.testing.assert_allclose(normal_offsets(p, up, v, t, 0.1), 0.05, atol=1e-12)


def test_a_static_surface_is_left_where_it_is():
    v, t = uv_sphere(0.3, n=24)
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    out = smooth_across_frames(v, t, [(v, v, t), (v, v, t)], [0.5, 0.25, 0.25], 0.05, normals=n)
    np.testing.assert_allclose(out, v, atol=1e-12)
    again = smooth_across_frames(v, t, [(v, v, t), (v, v, t)], [0.5, 0.25, 0.25], 0.05, normals=n)
    assert np.array_equal(out, again)


def test_a_rigid_motion_that_the_displacements_describe_changes_nothing():
    v, t = uv_sphere(0.3, n=24)
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    shift = np.array([0.013, -0.007, 0.021])
    out = smooth_across_frames(v, t, [(v + shift, v + shift, t), (v - shift, v - shift, t)],
                               [0.5, 0.25, 0.25], 0.05, normals=n)
    np.testing.assert_allclose(out, v, atol=1e-12)


def test_weights_average_the_neighbours_offsets_and_far_ones_are_left_out():
    v, t = grid_plane(0.0)
    inner = (v[:, 0] > 0.05) & (v[:, 0] < 0.95) & (v[:, 1] > 0.05) & (v[:, 1] < 0.95)
    up = np.tile([0.0, 0.0, 1.0], (len(v), 1))
    above, below, far = grid_plane(0.1)[0], grid_plane(-0.1)[0], grid_plane(0.3)[0]
    # symmetric neighbours cancel
    out = smooth_across_frames(v, t, [(v, above, t), (v, below, t)], [0.5, 0.25, 0.25], 0.2,
                               normals=up)
    np.testing.assert_allclose(out[inner, 2], 0.0, atol=1e-12)
    # a neighbour beyond reach is left out and the weights renormalised: 0.25 * 0.1 / 0.75 (a
    # uniform offset, which the sweeps over the mesh keep)
    out = smooth_across_frames(v, t, [(v, above, t), (v, far, t)], [0.5, 0.25, 0.25], 0.2,
                               normals=up)
    np.testing.assert_allclose(out[inner, 2], 0.1 / 3.0, atol=1e-12)
    np.testing.assert_array_equal(out[:, :2], v[:, :2])
    # fixed vertices stay, and pull their neighbours' offsets toward zero
    edge = ~inner
    out = smooth_across_frames(v, t, [(v, above, t)], [0.5, 0.5], 0.2, normals=up, fixed=edge)
    np.testing.assert_array_equal(out[edge], v[edge])
    assert 0.0 < out[inner, 2].min() < out[inner, 2].max() < 0.05 + 1e-12


def test_offset_smoothing_removes_vertex_scale_noise_and_keeps_a_smooth_offset():
    v, t = grid_plane(0.0, n=40)
    up = np.tile([0.0, 0.0, 1.0], (len(v), 1))
    inner = np.all((v[:, :2] > 0.2) & (v[:, :2] < 0.8), axis=1)
    rng = np.random.default_rng(4)
    bumpy = v.copy()
    bumpy[:, 2] = 0.05 + rng.uniform(-0.01, 0.01, len(v))  # a plane 0.05 up, noisy per vertex
    raw = smooth_across_frames(v, t, [(v, bumpy, t)], [0.5, 0.5], 0.2, normals=up, sweeps=0)
    smooth = smooth_across_frames(v, t, [(v, bumpy, t)], [0.5, 0.5], 0.2, normals=up)
    assert abs(raw[inner, 2].mean() - 0.025) < 1e-3 and abs(smooth[inner, 2].mean() - 0.025) < 1e-3
    assert smooth[inner, 2].std() < 0.3 * raw[inner, 2].std()


def test_bad_input_is_refused_naming_the_parameter():
    v, t = grid_plane(0.0, n=4)
    up = np.tile([0.0, 0.0, 1.0], (len(v), 1))
    with pytest.raises(ValueError, match="reach"):
        normal_offsets(v, up, v, t, 0.0)
    with pytest.raises(ValueError, match="directions"):
        normal_offsets(v, up[:3], v, t, 0.1)
    with pytest.raises(ValueError, match="triangles"):
        normal_offsets(v, up, v, t + 100, 0.1)
    with pytest.raises(ValueError, match="points"):
        normal_offsets(np.full((2, 3), np.nan), up[:2], v, t, 0.1)
    with pytest.raises(ValueError, match="weights"):
        smooth_across_frames(v, t, [(v, v, t)], [1.0], 0.1)
    with pytest.raises(ValueError, match="weights"):
        smooth_across_frames(v, t, [(v, v, t)], [0.0, 1.0], 0.1)
    with pytest.raises(ValueError, match="normals"):
        smooth_across_frames(v, t, [], [1.0], 0.1, normals=up[:2])
    with pytest.raises(ValueError, match="reach"):
        smooth_across_frames(v, t, [], [1.0], 0.0)
    with pytest.raises(ValueError, match="sweeps"):
        smooth_across_frames(v, t, [], [1.0], 0.1, sweeps=-1)
    with pytest.raises(ValueError, match="fixed"):
        smooth_across_frames(v, t, [], [1.0], 0.1, fixed=[True])


def test_vertex_normals_of_a_sphere_point_outward():
    v, t = uv_sphere(0.3, n=24)
    n = vertex_normals(v, t)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, rtol=1e-12)
    assert np.min(np.sum(n * v / 0.3, axis=1)) > 0.99
    # a vertex of no triangle has no normal
    lonely = vertex_normals(np.vstack([v, [[5.0, 5.0, 5.0]]]), t)
    np.testing.assert_array_equal(lonely[-1], 0.0)


def test_a_surface_jumping_up_and_down_every_frame_is_held_to_a_ninth_of_it():
    # static particles, a reconstruction that puts the plane at +d and -d in turn: with weights
    # 1, 2, 3, 2, 1 frame k's offset is 2 (2/9) (-2 d) = -8 d / 9, so it lands at d / 9
    v, t = grid_plane(0.0, n=20)
    up = np.tile([0.0, 0.0, 1.0], (len(v), 1))
    d = 0.01
    inner = np.all((v[:, :2] > 0.1) & (v[:, :2] < 0.9), axis=1)
    frames = [grid_plane(d if k % 2 == 0 else -d, n=20)[0] for k in range(5)]
    me = frames[2]
    others = [(me, frames[k], t) for k in (0, 1, 3, 4)]
    out = smooth_across_frames(me, t, others, np.array([3, 1, 2, 2, 1]) / 9, 0.1, normals=up)
    np.testing.assert_allclose(out[inner, 2], d / 9, atol=1e-12)


def test_neighbours_sharing_their_particles_move_the_vertices_as_one_by_one():
    # follow_particles_across_frames interpolates the displacements of the neighbours that have
    # the same particles in one pass (same Shepard weights): bit for bit what one interpolation
    # per neighbour gives, also when one neighbour has lost some of the particles
    from filters.surface.attributes import interpolate_attributes
    from filters.surface.temporal import follow_particles_across_frames

    rng = np.random.default_rng(3)
    v, t = grid_plane(0.5, n=24)
    x = np.column_stack([rng.uniform(0, 1, (600, 2)), rng.uniform(0.44, 0.5, 600)])
    radius = 0.06
    everyone = np.arange(len(x))
    some = everyone[::2]
    neighbours = []
    for j, rows in enumerate((everyone, everyone, some, everyone)):
        where = x[rows] + rng.normal(0, 0.004, (len(rows), 3)) + [0, 0, 0.003 * (j - 1.5)]
        neighbours.append((rows, where, *grid_plane(0.5 + 0.004 * (j - 1.5), n=17)))
    weights = [3, 1, 2, 2, 1]
    out = follow_particles_across_frames(v, t, x, neighbours, weights, radius)
    others = [(v + interpolate_attributes(v, x[rows], radius, where - x[rows],
                                          cell_size=0.5 * radius), pv, pt)
              for rows, where, pv, pt in neighbours]
    expected = smooth_across_frames(v, t, others, weights, radius)
    assert np.array_equal(out, expected)
    assert np.abs(out[:, 2] - 0.5).max() > 1e-4  # the neighbours did move it
