"""Tests of filters.fields: each term against its formula, Jacobians against finite differences,
sums, the packed form called from a user's Numba kernel, and noise-driven particle variation."""

import math

import numpy as np
import pytest
from numba import njit

from filters.fields import (
    CurlNoise,
    Drag,
    FieldSum,
    Gravity,
    NoiseWind,
    RigidRotation,
    Uniform,
    Vortex,
    field_point,
    field_point_jacobian,
    jacobian_packed,
)
from filters.geometry import Plane, Sphere
from filters.noise import fbm3, noise_variation

RNG = np.random.default_rng(2024)
PTS = RNG.uniform(-1.5, 1.5, (200, 3))


def _fd_jacobian(field, pts, t=0.0, h=1e-6):
    jac = np.empty((pts.shape[0], 3, 3))
    for axis in range(3):
        e = np.zeros(3)
        e[axis] = h
        jac[:, :, axis] = (field.evaluate(pts + e, t) - field.evaluate(pts - e, t)) / (2 * h)
    return jac


def test_gravity_uniform_and_drag():
    g = Gravity().evaluate(PTS)
    assert np.array_equal(g, np.tile([0.0, 0.0, -9.81], (PTS.shape[0], 1)))
    assert np.array_equal(Uniform((1, 2, 3)).evaluate(PTS[:2]), [[1, 2, 3], [1, 2, 3]])
    vel = RNG.normal(size=PTS.shape)
    drag = Drag(0.7, (1.0, 0.0, -2.0))
    np.testing.assert_allclose(drag.evaluate(PTS, 0.0, vel), -0.7 * (vel - [1.0, 0.0, -2.0]),
                               rtol=0, atol=1e-15)
    # without velocities the particle is taken at rest: the air pushes it along
    np.testing.assert_allclose(drag.evaluate(PTS[:1]), [[0.7, 0.0, -1.4]], atol=1e-15)
    _, jac = drag.jacobian(PTS, 0.0, vel)
    assert np.all(jac == 0.0)


def test_rigid_rotation_formula_and_jacobian():
    omega = np.array([0.3, -1.2, 2.0])
    center = np.array([0.5, 0.1, -0.2])
    field = RigidRotation(omega, center)
    np.testing.assert_allclose(field.evaluate(PTS), np.cross(omega, PTS - center), atol=1e-14)
    _, jac = field.jacobian(PTS)
    skew = np.array([[0, -omega[2], omega[1]], [omega[2], 0, -omega[0]],
                     [-omega[1], omega[0], 0]])
    assert np.allclose(jac, skew, atol=0)


def test_lamb_oseen_vortex_profile_and_jacobian():
    gamma, rc = 2.5, 0.3
    field = Vortex(center=(0.2, -0.1, 0.0), axis=(0, 0, 2.0), circulation=gamma, core_radius=rc)
    r = np.array([1e-9, 0.05, 0.3, 1.0, 3.0])
    pts = np.stack([0.2 + r, np.full_like(r, -0.1), np.linspace(-1, 1, r.size)], axis=1)
    v = field.evaluate(pts)
    r = pts[:, 0] - 0.2  # the radius as represented
    expected = gamma / (2 * np.pi * r) * -np.expm1(-(r / rc) ** 2)
    np.testing.assert_allclose(v[:, 1], expected, rtol=1e-12)  # azimuthal = +y at +x
    assert np.abs(v[:, [0, 2]]).max() < 1e-15
    # near the axis: rigid rotation at gamma / (2 pi rc^2)
    assert abs(v[0, 1] / r[0] - gamma / (2 * np.pi * rc ** 2)) < 1e-6
    _, jac = field.jacobian(PTS)
    np.testing.assert_allclose(jac, _fd_jacobian(field, PTS), rtol=0, atol=1e-7)
    assert np.abs(np.trace(jac, axis1=1, axis2=2)).max() < 1e-12  # divergence-free
    # invariant along the axis
    shifted = PTS + [0.0, 0.0, 0.75]
    np.testing.assert_allclose(field.evaluate(shifted), field.evaluate(PTS), atol=1e-14)


def test_noise_wind_components_are_fbm_with_consecutive_seeds():
    field = NoiseWind(amplitude=(1.0, -2.0, 0.5), frequency=1.7, octaves=3, seed=4)
    v = field.evaluate(PTS)
    for i, a in enumerate((1.0, -2.0, 0.5)):
        np.testing.assert_allclose(v[:, i], a * fbm3(PTS, octaves=3, frequency=1.7, seed=4 + i),
                                   rtol=0, atol=1e-15)
    _, jac = field.jacobian(PTS, 0.8)
    moving = NoiseWind(amplitude=(1.0, -2.0, 0.5), frequency=1.7, octaves=3, seed=4,
                       time_scale=0.5)
    _, jac_m = moving.jacobian(PTS, 0.8)
    np.testing.assert_allclose(jac_m, _fd_jacobian(moving, PTS, 0.8), rtol=0, atol=1e-7)
    assert np.abs(moving.evaluate(PTS, 0.8) - field.evaluate(PTS, 0.8)).max() > 1e-2
    assert np.abs(jac).max() > 0.1


def test_curl_noise_packed_and_vectorised_paths_agree_bitwise():
    colliders = (Plane((0, 0, -1.0)), Sphere((0.3, 0.0, 0.2), 0.4))
    field = CurlNoise(amplitude=0.8, frequency=1.2, octaves=2, seed=6, time_scale=0.4,
                      colliders=colliders, ramp_distance=0.5)
    # the packed term (what simulations evaluate in Numba) and the block-vectorised arrays
    np.testing.assert_array_equal(field.evaluate(PTS, 1.3), field.velocity(PTS, 1.3))
    v, jac = field.jacobian(PTS, 1.3)
    v_ref, jac_ref = jacobian_packed(field.packed, PTS, 1.3)
    np.testing.assert_allclose(v, v_ref, rtol=0, atol=1e-13)
    np.testing.assert_array_equal(jac, jac_ref)
    np.testing.assert_allclose(jac, _fd_jacobian(field, PTS, 1.3), rtol=0, atol=2e-6)


def test_field_sum_adds_terms_and_jacobians():
    a = RigidRotation((0, 0, 1.0))
    b = Vortex(circulation=-1.0, core_radius=0.5)
    c = CurlNoise(amplitude=0.4, frequency=2.0, seed=1)
    d = NoiseWind(amplitude=(0.1, 0.2, 0.3), seed=9)
    total = a + b + c + d + Gravity()
    assert isinstance(total, FieldSum) and len(total.fields) == 5  # flattened
    expected = sum(f.evaluate(PTS, 0.2) for f in (a, b, c, d, Gravity()))
    np.testing.assert_allclose(total.evaluate(PTS, 0.2), expected, rtol=0, atol=1e-13)
    _, jac = total.jacobian(PTS, 0.2)
    np.testing.assert_allclose(jac, _fd_jacobian(total, PTS, 0.2), rtol=0, atol=2e-6)
    packed = total.pack()
    assert packed.kinds.shape == (5,) and packed.params.shape == (5, 16)
    assert packed.tables.shape == (7, 512)  # one dummy row + 3 per noise term
    with pytest.raises(TypeError):
        FieldSum((a, "wind"))


@njit
def _user_kernel(x, t, kinds, params, tables, colliders):
    """What an SPH or spring kernel would do: evaluate the packed field per particle."""
    out = np.empty_like(x)
    jac_trace = np.empty(x.shape[0])
    J = np.empty((3, 3))
    for i in range(x.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = field_point(kinds, params, tables, colliders, x[i, 0],
                                                      x[i, 1], x[i, 2], 0.0, 0.0, 0.0, t)
        field_point_jacobian(kinds, params, tables, colliders, x[i, 0], x[i, 1], x[i, 2], 0.0,
                             0.0, 0.0, t, J)
        jac_trace[i] = J[0, 0] + J[1, 1] + J[2, 2]
    return out, jac_trace


def test_packed_field_is_callable_from_user_numba_kernels():
    field = (CurlNoise(amplitude=0.5, frequency=1.5, colliders=(Plane(),),
                               ramp_distance=0.3)
             + Vortex(core_radius=0.2) + Uniform((0.0, 0.0, 0.4)))
    p = field.pack()
    out, trace = _user_kernel(PTS, 0.5, p.kinds, p.params, p.tables, p.colliders)
    np.testing.assert_array_equal(out, field.evaluate(PTS, 0.5))
    # all three terms are divergence-free (the ramped one up to its FD Jacobian)
    assert np.abs(trace).max() < 1e-5


def test_noise_variation_range_coherence_and_ids():
    pts = RNG.uniform(-3, 3, (2000, 3))
    size = noise_variation(pts, 0.01, 0.03, frequency=0.5)
    assert size.min() >= 0.01 and size.max() <= 0.03
    assert size.max() - size.min() > 0.01  # uses the range
    np.testing.assert_array_equal(size, noise_variation(pts, 0.01, 0.03, frequency=0.5))
    # spatially coherent: a nearby point has a nearby value
    near = noise_variation(pts + 1e-4, 0.01, 0.03, frequency=0.5)
    assert np.abs(near - size).max() < 1e-5
    # particles born at one place differ by id
    same = np.zeros((50, 3))
    by_id = noise_variation(same, 0.0, 1.0, ids=np.arange(50))
    assert np.std(by_id) > 0.05
    with pytest.raises(ValueError, match="high"):
        noise_variation(pts, 1.0, 0.5)
    with pytest.raises(ValueError, match="ids"):
        noise_variation(pts, 0.0, 1.0, ids=np.arange(3))


def test_validation_names_parameters():
    with pytest.raises(ValueError, match="core_radius"):
        Vortex(core_radius=0.0)
    with pytest.raises(ValueError, match="coefficient"):
        Drag(-1.0)
    with pytest.raises(ValueError, match="frequency"):
        NoiseWind(frequency=-1.0)
    with pytest.raises(ValueError, match="octaves"):
        CurlNoise(octaves=99)
    with pytest.raises(ValueError, match="axis"):
        Vortex(axis=(0, 0, 0))
    with pytest.raises(ValueError, match="velocities"):
        Drag(1.0).evaluate(PTS, 0.0, np.zeros((3, 3)))
    with pytest.raises(ValueError, match="t must"):
        Gravity().evaluate(PTS, math.nan)
