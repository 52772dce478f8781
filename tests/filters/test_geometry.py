"""filters.geometry: the one set of shapes, one sign convention (negative inside the solid),
shared by colliders, CSG, the curl-noise ramp and SPH walls."""

import math

import numpy as np
import pytest

from filters.elastic.contact import Colliders
from filters.geometry import (
    Box,
    Complement,
    Plane,
    Sphere,
    pack_shapes,
    packed_distance,
    union_distance,
)
from filters.sph.boundary import box_boundary


def test_primitives_and_csg():
    pts = np.array([[0.0, 0, 0], [2.0, 0, 0], [0.5, 0.5, 0.5], [0, 0, 3.0]])
    s = Sphere((0, 0, 0), 1.0)
    np.testing.assert_allclose(s(pts), [-1.0, 1.0, math.sqrt(0.75) - 1, 2.0])
    b = Box((-1, -1, -1), (1, 1, 1))
    np.testing.assert_allclose(b(pts), [-1.0, 1.0, -0.5, 2.0])
    p = Plane((0, 0, 0.25), (0, 0, 2.0))
    np.testing.assert_allclose(p(pts), [-0.25, -0.25, 0.25, 2.75])
    np.testing.assert_allclose((s | p)(pts), np.minimum(s(pts), p(pts)))
    np.testing.assert_allclose((s & p)(pts), np.maximum(s(pts), p(pts)))
    np.testing.assert_allclose((b - s)(pts), np.maximum(b(pts), -s(pts)))
    assert (b - s)(np.array([[0.0, 0.0, 0.0]]))[0] > 0  # hollow
    with pytest.raises(ValueError):
        Box((0, 0, 0), (0, 1, 1))
    with pytest.raises(ValueError):
        Plane(normal=(0, 0, 0))



def test_one_sign_convention_for_every_consumer(rng):
    pts = rng.uniform(-2.0, 2.0, (300, 3))
    shapes = [Plane((0, 0, 0.3), (0, 0, 1)), Sphere((0.2, -0.1, 0.0), 0.7),
              ~Sphere((0, 0, 0), 1.8)]
    # the shapes themselves: negative inside the solid (behind a plane, in a ball, outside a
    # container)
    assert Plane()(np.array([[0.0, 0.0, -1.0]]))[0] < 0
    assert Sphere()(np.array([[0.0, 0.0, 0.0]]))[0] < 0
    assert (~Sphere())(np.array([[0.0, 0.0, 0.0]]))[0] > 0
    expected = np.min([s(pts) for s in shapes], axis=0)
    # the curl-noise ramp's packed rows, from Numba
    d, normals = union_distance(pts, shapes)
    np.testing.assert_allclose(d, expected, atol=1e-12)
    packed = pack_shapes(shapes)
    assert packed_distance(packed, *pts[0])[0] == pytest.approx(expected[0], abs=1e-12)
    # the colliders' rows, from Numba
    contact = Colliders()
    for shape in shapes:
        contact.add(shape)
    phi, contact_normals = contact.sdf(pts)
    np.testing.assert_allclose(phi, expected, atol=1e-12)
    np.testing.assert_allclose(contact_normals, normals, atol=1e-12)
    # the normal points out of the solid: a step along it increases the distance
    np.testing.assert_array_less(d, union_distance(pts + 1e-4 * normals, shapes)[0])


def test_complements_and_combinations():
    box = Box((0, 0, 0), (1, 2, 3))
    tank = ~box
    assert isinstance(tank, Complement) and tank.shape == box
    pts = np.array([[0.5, 1.0, 1.5], [2.0, 1.0, 1.5]])
    np.testing.assert_allclose(tank(pts), -box(pts))
    assert (box | Sphere()).bounds() is not None and (box | Plane()).bounds() is None
    lo, hi = (box & Sphere((0, 0, 0), 0.5)).bounds()
    np.testing.assert_allclose(lo, [0, 0, 0]) and np.testing.assert_allclose(hi, [0.5, 0.5, 0.5])
    # equal shapes are equal, and usable as keys
    assert Sphere((1, 2, 3), 0.5) == Sphere((1.0, 2.0, 3.0), 0.5)
    assert len({Plane(), Plane((0, 0, 0), (0, 0, 2))}) == 1
    with pytest.raises(TypeError, match="Shape"):
        Complement("tank")
    with pytest.raises(TypeError, match="boxes"):
        pack_shapes([box])
    with pytest.raises(TypeError, match="shape must be"):
        Colliders().add(box | Sphere())


def test_sph_walls_take_a_box():
    box = Box((0.0, 0.0, 0.0), (0.1, 0.1, 0.2))
    a = box_boundary(box, spacing=0.02)
    b = box_boundary((0.0, 0.0, 0.0), (0.1, 0.1, 0.2), 0.02)
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.volumes, b.volumes)
    with pytest.raises(ValueError, match="upper"):
        box_boundary(box, (1, 1, 1), 0.02)
