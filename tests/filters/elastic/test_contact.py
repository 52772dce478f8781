"""Colliders: signed distances, restitution, Coulomb friction, unions, Numba use, validation."""

import numpy as np
import pytest
from numba import njit

from filters.elastic.contact import Colliders, resolve_particle, union_sdf
from filters.geometry import Box, Plane, Sphere


def test_signed_distances_and_normals():
    c = (Colliders().add(Plane((0, 0, 0), (0, 0, 2)))
         .add(Sphere((0, 0, 2), 0.5))
         .add(Box((2, 2, 2), (3, 4, 5))))
    pts = np.array([[5.0, 5.0, 0.25],   # above the floor
                    [0.0, 0.0, 2.8],    # above the sphere
                    [2.5, 3.0, 3.5],    # inside the box, nearest face x
                    [3.5, 3.0, 6.0]])   # outside the box, off an edge
    phi, n = c.sdf(pts)
    assert phi[0] == pytest.approx(0.25) and np.allclose(n[0], [0, 0, 1])
    assert phi[1] == pytest.approx(0.3) and np.allclose(n[1], [0, 0, 1])
    assert phi[2] == pytest.approx(-0.5) and abs(n[2, 0]) == pytest.approx(1.0)
    assert phi[3] == pytest.approx(np.hypot(0.5, 1.0))
    assert np.allclose(n[3], np.array([0.5, 0.0, 1.0]) / np.hypot(0.5, 1.0))
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)


def test_restitution_and_friction_on_a_floor():
    c = Colliders().add(Plane((0, 0, 0), (0, 0, 1)), restitution=0.5, friction=0.2)
    x = np.array([[0.0, 0.0, -0.01], [1.0, 0.0, -0.02]])
    v = np.array([[3.0, 0.0, -2.0], [0.1, 0.0, -2.0]])
    assert c.resolve(x, v) == 2
    assert np.allclose(x[:, 2], 0.0)
    assert np.allclose(v[:, 2], 1.0)  # -e v_n
    # Coulomb: tangential speed drops by mu (1 + e) |v_n| = 0.6, and never reverses
    assert v[0, 0] == pytest.approx(2.4)
    assert v[1, 0] == 0.0
    # a separating particle keeps its velocity; one above the floor is untouched
    x2 = np.array([[0.0, 0.0, -0.01], [0.0, 0.0, 1.0]])
    v2 = np.array([[1.0, 0.0, 0.5], [0.0, 0.0, -1.0]])
    c.resolve(x2, v2)
    assert np.allclose(v2, [[1.0, 0.0, 0.5], [0.0, 0.0, -1.0]])
    assert np.allclose(x2[:, 2], [0.0, 1.0])


def test_containers_and_union_corner():
    c = Colliders(thickness=0.01).add(~Box((0, 0, 0), (1, 1, 1)))
    c.add(~Sphere((0, 0, 0), 10.0))
    rng = np.random.default_rng(0)
    x = rng.uniform(-0.5, 1.5, size=(200, 3))
    v = rng.normal(size=(200, 3))
    c.resolve(x, v)
    assert x.min() >= 0.01 - 1e-12 and x.max() <= 0.99 + 1e-12
    # a corner of two planes pushes a particle out of both
    corner = Colliders().add(Plane((0, 0, 0), (0, 0, 1))).add(Plane((0, 0, 0), (1, 0, 0)))
    x = np.array([[-0.1, 0.0, -0.2]])
    v = np.array([[-1.0, 0.0, -1.0]])
    corner.resolve(x, v)
    assert np.allclose(x, [[0.0, 0.0, 0.0]])
    assert v[0, 0] >= 0.0 and v[0, 2] >= 0.0


def test_callable_from_numba_kernels():
    c = Colliders(restitution=1.0, friction=0.0).add(Sphere((0, 0, 0), 1.0))

    @njit
    def user_kernel(x, v, planes, spheres, boxes):
        hits = 0
        for i in range(x.shape[0]):
            hits += resolve_particle(x[i], v[i], planes, spheres, boxes, 0.0)
        phi = union_sdf(x[0], planes, spheres, boxes)[0]
        return hits, phi

    x = np.array([[0.5, 0.0, 0.0]])
    v = np.array([[-1.0, 0.0, 0.0]])
    hits, phi = user_kernel(x, v, c.planes, c.spheres, c.boxes)
    assert hits == 1 and phi == pytest.approx(0.0)
    assert np.allclose(x, [[1.0, 0.0, 0.0]]) and np.allclose(v, [[1.0, 0.0, 0.0]])


def test_skip_mask_and_empty():
    c = Colliders().add(Plane((0, 0, 0), (0, 0, 1)))
    x = np.array([[0.0, 0.0, -1.0]])
    v = np.zeros((1, 3))
    assert c.resolve(x, v, skip=np.array([True])) == 0 and x[0, 2] == -1.0
    assert Colliders().resolve(x, v) == 0


@pytest.mark.parametrize("build, match", [
    (lambda c: c.add(Sphere((0, 0, 0), -1.0)), "radius"),
    (lambda c: c.add(Plane((0, 0, 0), (0, 0, 0))), "normal"),
    (lambda c: c.add(Box((0, 0, 0), (1, 0, 1))), "upper"),
    (lambda c: c.add(Plane((0, 0, 0), (0, 0, 1)), restitution=1.5), "restitution"),
    (lambda c: c.add(Sphere((0, 0, np.nan), 1.0)), "center"),
])
def test_bad_input(build, match):
    with pytest.raises(ValueError, match=match):
        build(Colliders())
    with pytest.raises(ValueError, match="friction"):
        Colliders(friction=-0.1)
    with pytest.raises(ValueError, match="positions"):
        Colliders().add(Plane((0, 0, 0), (0, 0, 1))).resolve(np.zeros((2, 3), np.float32),
                                                             np.zeros((2, 3)))
