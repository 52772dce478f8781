"""Mass properties of closed meshes against analytic values, and the meshes that are refused."""

import math

import numpy as np
import pytest
from rigid_shapes import ball, box_mesh, l_prism, tet_inertia, tetrahedron

from filters.elastic.topology import icosphere
from filters.rigid import (
    RigidBody,
    check_closed_mesh,
    mass_properties,
    quaternion_from_axis_angle,
    rotation_matrices,
)
from filters.rigid.body import edge_points


def _tet_sum(vertices, faces, density):
    """An independent exact integration: the mesh cut into tetrahedra (centroid, triangle),
    each by the closed-form second moment of ``tet_inertia``."""
    apex = vertices.mean(axis=0)
    mass = 0.0
    first = np.zeros(3)
    second = np.zeros((3, 3))
    for a, b, c in faces:
        p = np.array([apex, vertices[a], vertices[b], vertices[c]])
        sign = np.sign(np.dot(np.cross(p[2] - p[1], p[3] - p[1]), p[1] - p[0]))
        m, centre, inertia = tet_inertia(p, density)
        mass += sign * m
        first += sign * m * centre
        # back to the origin's second moment: S = (tr(I)/2) 1 - I + m c c^T
        s = np.trace(inertia) / 2 * np.eye(3) - inertia + m * np.outer(centre, centre)
        second += sign * s
    centre = first / mass
    second -= mass * np.outer(centre, centre)
    return mass, centre, np.trace(second) * np.eye(3) - second


def test_box_mass_properties_are_the_analytic_ones_for_any_pose():
    a, b, c, rho = 0.3, 0.2, 0.1, 700.0
    v, f = box_mesh((a, b, c), center=(5.0, -3.0, 2.0))
    p = mass_properties(v, f, rho)
    mass = rho * a * b * c
    assert p.volume == pytest.approx(a * b * c, rel=1e-14)
    assert p.mass == pytest.approx(mass, rel=1e-14)
    np.testing.assert_allclose(p.center, [5.0, -3.0, 2.0], rtol=0, atol=1e-14)
    expected = mass / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    np.testing.assert_allclose(p.inertia, expected, rtol=0, atol=1e-14 * expected.max())
    np.testing.assert_allclose(p.principal_moments, np.sort(np.diag(expected)), rtol=1e-13)
    # turned: I' = R I R^T, the centre turns with the mesh
    r = rotation_matrices([quaternion_from_axis_angle((1, 2, 3), 0.7)])[0]
    q = mass_properties(v @ r.T, f, rho)
    np.testing.assert_allclose(q.inertia, r @ expected @ r.T, rtol=0, atol=1e-13 * mass)
    np.testing.assert_allclose(q.center, r @ [5.0, -3.0, 2.0], rtol=0, atol=1e-13)
    axes = q.principal_axes
    assert np.linalg.det(axes) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(axes @ np.diag(q.principal_moments) @ axes.T, q.inertia,
                               rtol=0, atol=1e-13 * mass)


def test_tetrahedron_mass_properties_match_the_closed_form():
    points = [[0.1, 0.0, 0.2], [1.3, 0.2, -0.1], [0.4, 1.1, 0.3], [0.2, 0.3, 0.9]]
    v, f = tetrahedron(points)
    p = mass_properties(v, f, 2500.0)
    mass, centre, inertia = tet_inertia(v, 2500.0)
    assert p.mass == pytest.approx(mass, rel=1e-13)
    np.testing.assert_allclose(p.center, centre, rtol=0, atol=1e-14)
    np.testing.assert_allclose(p.inertia, inertia, rtol=0, atol=1e-12 * np.abs(inertia).max())


@pytest.mark.parametrize("mesh", ["icosphere", "l_prism"])
def test_mass_properties_agree_with_an_independent_tetrahedral_sum(mesh):
    v, f = icosphere(0.4, 2, (1.0, 2.0, -0.5)) if mesh == "icosphere" else l_prism()
    p = mass_properties(v, f, 1000.0)
    mass, centre, inertia = _tet_sum(v, f, 1000.0)
    assert p.mass == pytest.approx(mass, rel=1e-12)
    np.testing.assert_allclose(p.center, centre, rtol=0, atol=1e-12)
    np.testing.assert_allclose(p.inertia, inertia, rtol=0, atol=1e-11 * np.abs(inertia).max())


def test_icosphere_converges_to_the_ball_at_second_order_with_isotropic_inertia():
    radius, rho = 0.5, 1000.0
    mass = rho * 4 / 3 * math.pi * radius ** 3
    errors = []
    for s in (2, 3, 4):
        v, f = icosphere(radius, s, (1.0, 2.0, 3.0))
        p = mass_properties(v, f, rho)
        np.testing.assert_allclose(p.center, [1.0, 2.0, 3.0], rtol=0, atol=1e-13)
        # icosahedral symmetry makes the inertia tensor isotropic
        i0 = p.inertia[0, 0]
        assert np.abs(p.inertia - i0 * np.eye(3)).max() < 1e-12 * i0
        errors.append((abs(p.mass / mass - 1), abs(i0 / (0.4 * mass * radius ** 2) - 1)))
    errors = np.array(errors)
    assert errors[-1, 0] < 3e-3 and errors[-1, 1] < 5e-3  # subdivision 4, 5120 triangles
    ratios = errors[:-1] / errors[1:]
    assert np.all((ratios > 3.5) & (ratios < 4.5)), ratios  # second order in the edge length


def test_body_frame_is_the_mesh_about_its_centre_of_mass():
    v, f = ball(0.1, 2, center=(0.3, 0.2, 0.5))
    body = RigidBody(v, f, density=800.0)
    np.testing.assert_allclose(body.center, [0.3, 0.2, 0.5], atol=1e-15)
    np.testing.assert_allclose(body.vertices, v - body.center, atol=0)
    assert body.convex and body.radius == pytest.approx(0.1, rel=1e-12)
    assert not body.vertices.flags.writeable and not body.inertia.flags.writeable
    # principal rotation: the body-frame inertia is A diag A^T with A = R(principal_rotation)
    a = rotation_matrices([body.principal_rotation])[0]
    np.testing.assert_allclose(a @ np.diag(body.principal_moments) @ a.T, body.inertia,
                               rtol=0, atol=1e-14 * body.inertia.max())


def test_edge_points_cover_every_edge_at_the_spacing():
    v, f = box_mesh((0.3, 0.1, 0.1))
    p = edge_points(v, f, 0.05)
    # 8 corners; edges 0.3 (x4) -> 5 inner points, 0.1 (x8) -> 1; face diagonals:
    # sqrt(0.1) (x4 on the long faces... ) counted from the formula below
    e = np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1),
                  axis=0)
    lengths = np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1)
    assert p.shape[0] == 8 + int((np.ceil(lengths / 0.05 - 1e-9) - 1).sum())
    # every edge point lies on its box's surface, and none is further than 0.05 from another
    d, _ = RigidBody(v, f).signed_distance(p - v.mean(axis=0))
    assert np.abs(d).max() < 1e-15
    gaps = np.linalg.norm(p[:, None] - p[None], axis=2) + np.eye(len(p))
    assert gaps.min(axis=1).max() <= 0.05 + 1e-12
    assert edge_points(v, f, math.inf).shape[0] == 8


def test_meshes_that_bound_no_solid_are_refused_by_name():
    v, f = box_mesh(1.0)
    with pytest.raises(ValueError, match="open"):
        check_closed_mesh(v, f[:-1])
    flipped = f.copy()
    flipped[3] = flipped[3, [0, 2, 1]]
    with pytest.raises(ValueError, match="inconsistently oriented"):
        check_closed_mesh(v, flipped)
    with pytest.raises(ValueError, match="inverted"):
        check_closed_mesh(v, f[:, [0, 2, 1]])
    # a fin: three triangles share the edge (0, 1)
    fin_v = np.vstack([v, [[0.5, -0.5, -1.5]]])
    with pytest.raises(ValueError, match="non-manifold"):
        check_closed_mesh(fin_v, np.vstack([f, [[0, 1, 8], [1, 0, 8]]]))
    # a flat tetrahedron: closed and consistently oriented, but no volume
    sq = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)
    with pytest.raises(ValueError, match="no volume"):
        check_closed_mesh(sq, tetrahedron(sq + [[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 1]])[1])
    with pytest.raises(ValueError, match="index vertices"):
        check_closed_mesh(v, f + 1)
    with pytest.raises(ValueError, match="three different vertices"):
        check_closed_mesh(v, np.vstack([f, [[0, 0, 1]]]))
    with pytest.raises(ValueError, match="NaN"):
        check_closed_mesh(np.where(v == v.max(), np.nan, v), f)
    with pytest.raises(ValueError, match="density"):
        mass_properties(v, f, 0.0)
    with pytest.raises(ValueError, match="restitution"):
        RigidBody(v, f, restitution=1.5)
    with pytest.raises(ValueError, match="friction"):
        RigidBody(v, f, friction=-0.1)
    with pytest.raises(ValueError, match="sample_spacing"):
        RigidBody(v, f, sample_options={"kernel": "cubic"})


def test_two_solids_touching_at_a_vertex_are_one_valid_body():
    a, fa = box_mesh(1.0, (0.5, 0.5, 0.5))
    b, fb = box_mesh(1.0, (-0.5, -0.5, -0.5))
    v = np.vstack([a, b])
    f = np.vstack([fa, fb + 8])
    # merge the shared corner (0, 0, 0): corner 0 of a and corner 7 of b
    f[f == 8 + 7] = 0
    p = mass_properties(v, f, 1.0)
    assert p.volume == pytest.approx(2.0, rel=1e-14)
    np.testing.assert_allclose(p.center, 0.0, atol=1e-15)


def test_the_distance_grid_of_a_non_convex_body_is_within_a_cell_of_the_exact_distance(rng):
    from filters.rigid.sdf import triangle_distance, winding_number

    v, f = l_prism()
    body = RigidBody(v, f, sdf_resolution=32)
    assert not body.convex
    origin, cell, grid = body.sdf[1:]
    # points over the grid (3 cells beyond the mesh on every side)
    x = rng.uniform(origin, origin + cell * (np.array(grid.shape) - 1), size=(400, 3))
    d, n = body.signed_distance(x)
    exact = np.array([min(triangle_distance(*p, body.vertices, body.faces, t)
                          for t in range(len(body.faces))) ** 0.5 for p in x])
    inside = np.array([winding_number(*p, body.vertices, body.faces) > 0.5 for p in x])
    exact[inside] *= -1
    assert np.abs(d - exact).max() < cell
    far = np.abs(exact) > cell
    assert np.array_equal(d[far] < 0, exact[far] < 0)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, rtol=1e-12)
    # a convex body's distance is exact inside (the nearest face)
    vb, fb = box_mesh((0.4, 0.2, 0.1))
    box = RigidBody(vb, fb)
    p = rng.uniform([-0.2, -0.1, -0.05], [0.2, 0.1, 0.05], size=(200, 3))
    d, _ = box.signed_distance(p)
    np.testing.assert_allclose(d, -np.min(np.abs(np.abs(p) - [0.2, 0.1, 0.05]), axis=1),
                               atol=1e-15)
