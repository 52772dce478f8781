"""Integrators: analytic oscillators, energy growth/decay laws, momentum, advection, solvers."""

import math

import numpy as np
import pytest

from filters.integrators import (backward_euler, euler, implicit_advection, integrate,
                                 symplectic_euler)
from filters.linalg import pcg, solve_linear
from filters.simulation import State
from filters.elastic.springs import SpringSystem
from filters.elastic.topology import cloth_grid


def _oscillator(k=1.0, m=1.0, c=0.0, x0=1.0):
    """A particle on a zero-rest-length spring to a pinned anchor: x'' = -(k/m) x - (c/m) x'."""
    sysm = SpringSystem([[0, 1]], 0.0, k, [1.0, m], damping=c, gravity=(0, 0, 0),
                        pinned=[True, False])
    state = State(np.array([[0.0, 0.0, 0.0], [x0, 0.0, 0.0]]))
    return sysm, state


def _analytic(t, w0, zeta):
    if zeta < 1.0:
        wd = w0 * math.sqrt(1.0 - zeta ** 2)
        return np.exp(-zeta * w0 * t) * (np.cos(wd * t) + zeta * w0 / wd * np.sin(wd * t))
    if zeta == 1.0:
        return (1.0 + w0 * t) * np.exp(-w0 * t)
    r1 = -w0 * (zeta - math.sqrt(zeta ** 2 - 1.0))
    r2 = -w0 * (zeta + math.sqrt(zeta ** 2 - 1.0))
    return (r2 * np.exp(r1 * t) - r1 * np.exp(r2 * t)) / (r2 - r1)


@pytest.mark.parametrize("zeta", [0.25, 1.0, 2.0])
def test_damped_oscillator_matches_analytic_solution(zeta):
    w0, m = 2.0, 1.0
    c = 2.0 * zeta * w0 * m
    # symplectic Euler, small step: first-order accurate
    sysm, state = _oscillator(k=w0 ** 2, m=m, c=c)
    h, n = 4e-4, 6000
    xs = np.empty(n)
    for i in range(n):
        symplectic_euler(sysm, state, h)
        xs[i] = state.positions[1, 0]
    t = h * np.arange(1, n + 1)
    assert np.abs(xs - _analytic(t, w0, zeta)).max() < 3e-3
    assert np.allclose(state.positions[1, 1:], 0.0) and np.allclose(state.positions[0], 0.0)
    # backward Euler (Newton), larger step: first-order accurate and over-damped, never ahead
    sysm, state = _oscillator(k=w0 ** 2, m=m, c=c)
    h, n = 5e-3, 400
    xs = np.empty(n)
    for i in range(n):
        backward_euler(sysm, state, h, solver="direct", newton_tol=1e-12)
        xs[i] = state.positions[1, 0]
    t = h * np.arange(1, n + 1)
    assert np.abs(xs - _analytic(t, w0, zeta)).max() < 3e-2


def test_forward_euler_energy_grows_as_predicted():
    sysm, state = _oscillator()
    h, n = 0.1, 200
    e0 = sysm.energy(state.positions, state.velocities)
    for i in range(1, n + 1):
        euler(sysm, state, h)
        e = sysm.energy(state.positions, state.velocities)
        assert e / e0 == pytest.approx((1.0 + h * h) ** i, rel=1e-10)


@pytest.mark.parametrize("scheme", ["backward_euler", "linearized_backward_euler"])
def test_backward_euler_energy_decays_as_predicted(scheme):
    sysm, state = _oscillator()
    h, n = 0.1, 200
    e0 = sysm.energy(state.positions, state.velocities)
    options = dict(solver="direct")
    if scheme == "backward_euler":
        options["newton_tol"] = 1e-13
    for i in range(1, n + 1):
        integrate(sysm, state, h, scheme, **options)
        e = sysm.energy(state.positions, state.velocities)
        assert e / e0 == pytest.approx((1.0 + h * h) ** -i, rel=1e-9)


def test_symplectic_euler_energy_bounded_over_1000_periods():
    sysm, state = _oscillator()
    h = 0.1  # h w = 0.1
    per_period = int(round(2 * math.pi / h))
    n = 1000 * per_period
    e0 = sysm.energy(state.positions, state.velocities)
    energies = np.empty(n)
    shadow = np.empty(n)
    for i in range(n):
        symplectic_euler(sysm, state, h)
        x, v = state.positions[1, 0], state.velocities[1, 0]
        energies[i] = 0.5 * (v * v + x * x)
        # symplectic Euler conserves the modified energy (v^2 + w^2 x^2 - h w^2 x v) / 2
        shadow[i] = 0.5 * (v * v + x * x - h * x * v)
    first = energies[:per_period].mean()
    last = energies[-per_period:].mean()
    assert abs(last / first - 1.0) < 0.01  # no drift over 1000 periods
    assert np.abs(energies / e0 - 1.0).max() < 0.06  # oscillates within O(h w / 2)
    assert np.ptp(shadow) < 1e-9 * e0


@pytest.mark.parametrize("scheme", ["euler", "symplectic_euler", "linearized_backward_euler",
                                    "backward_euler"])
@pytest.mark.parametrize("mode", ["axial", "relative"])
def test_momentum_conserved_without_gravity_and_pins(scheme, mode):
    top = cloth_grid(5, 4, size=(0.4, 0.3))
    rng = np.random.default_rng(7)
    x = top.positions + 0.02 * rng.normal(size=top.positions.shape)
    v = rng.normal(size=x.shape)
    sysm = SpringSystem(top.springs, top.rest_lengths, 50.0, top.masses, damping=0.05,
                        damping_mode=mode, gravity=(0, 0, 0))
    state = State(x, v)
    p0 = (top.masses[:, None] * v).sum(axis=0)
    scale = (top.masses[:, None] * np.abs(v)).sum()  # round-off of the force sums: ~1e-11
    options = {} if scheme in ("euler", "symplectic_euler") else dict(solver="direct")
    for _ in range(20):
        integrate(sysm, state, 1e-3 if scheme in ("euler", "symplectic_euler") else 1e-2, scheme,
                  **options)
    p = (top.masses[:, None] * state.velocities).sum(axis=0)
    assert np.abs(p - p0).max() < 1e-10 * scale


@pytest.mark.parametrize("with_colliders", [False, True])
def test_newton_line_search_never_gains_energy_on_stiff_chain(with_colliders):
    # a stiff hanging chain released sideways: large steps, nonlinear springs; with colliders,
    # it swings into a floor below its pin and a ball, with friction, and the energy account
    # includes the contacts' barrier energy
    from filters.elastic.contact import Colliders
    from filters.elastic.contact_model import ContactModel
    from filters.geometry import Plane, Sphere

    n = 12
    x = np.stack([np.linspace(0, 1.0, n), np.zeros(n), np.zeros(n)], axis=1)
    pairs = np.stack([np.arange(n - 1), np.arange(1, n)], 1)
    pinned = np.zeros(n, bool)
    pinned[0] = True
    sysm = SpringSystem(pairs, 1.0 / (n - 1), 1e4, np.full(n, 0.01), pinned=pinned)
    contact = None
    if with_colliders:
        colliders = (Colliders(friction=0.5, thickness=0.01)
                     .add(Plane((0, 0, -0.6), (0, 0, 1))).add(Sphere((0.3, 0.0, -0.45), 0.1)))
        contact = ContactModel(colliders, sysm.masses, 1.0 / 30.0, pinned=pinned,
                               elastic_diagonal=sysm.elastic_diagonal())
    state = State(x)

    def energy():
        e = sysm.energy(state.positions, state.velocities)
        return e if contact is None else e + contact.energy(state.positions)

    e = energy()
    touched = 0
    for _ in range(60):
        info = backward_euler(sysm, state, 1.0 / 30.0, solver="direct", newton_tol=1e-6,
                              max_newton=50, contact=contact)
        e_new = energy()
        assert e_new <= e + 1e-9 * abs(e)
        e = e_new
        if contact is not None:
            touched = max(touched, contact.touching)
            assert contact.clearance(state.positions).min() > 0.0
    assert info.newton_iterations >= 1
    assert touched >= (2 if with_colliders else 0)


def test_implicit_advection_is_backward_euler_for_linear_fields():
    w, h, n = 2.0, 0.1, 40
    a = np.array([[0.0, -w, 0.0], [w, 0.0, 0.0], [0.0, 0.0, -0.5]])
    x0 = np.array([[1.0, 0.0, 1.0], [0.0, 2.0, -1.0]])
    x = x0.copy()
    for _ in range(n):
        x = implicit_advection(x, x @ a.T, np.broadcast_to(a, (2, 3, 3)), h)
    step = np.linalg.inv(np.eye(3) - h * a)
    expected = x0 @ np.linalg.matrix_power(step, n).T
    assert np.allclose(x, expected, rtol=1e-12, atol=1e-14)
    # radius in the rotating plane shrinks as (1 + h^2 w^2)^(-n/2)
    assert np.hypot(x[0, 0], x[0, 1]) == pytest.approx((1 + (h * w) ** 2) ** (-n / 2), rel=1e-12)
    # the slide's form without h on the Jacobian, (I - J) dx = h v, is a different (wrong) map
    wrong = x0[0] + np.linalg.solve(np.eye(3) - a, h * a @ x0[0])
    right = implicit_advection(x0[:1], x0[:1] @ a.T, a[None], h)[0]
    assert not np.allclose(wrong, right)
    with pytest.raises(ValueError, match="singular"):
        implicit_advection(x0[:1], x0[:1], np.eye(3)[None] * 10.0, 0.1)
    with pytest.raises(ValueError, match="h"):
        implicit_advection(x0, x0, np.broadcast_to(a, (2, 3, 3)), 0.0)


def test_pcg_and_direct_agree_and_warm_start_helps():
    top = cloth_grid(8, 8)
    sysm = SpringSystem(top.springs, top.rest_lengths, 100.0, top.masses,
                        pinned=np.eye(1, 64, 0, dtype=bool)[0])
    x = top.positions + 0.01 * np.random.default_rng(0).normal(size=(64, 3))
    mat = sysm.system_matrix(x, x, 1 / 60)
    b = np.random.default_rng(1).normal(size=mat.shape[0])
    b[:3] = 0.0
    xd, _, direct = solve_linear(mat, b, solver="direct")
    xp, it, res = pcg(mat, b, tol=1e-10, max_iter=5000)
    assert direct and res < 1e-10
    assert np.allclose(xp, xd, rtol=1e-7, atol=1e-9 * np.abs(xd).max())
    _, it_warm, _ = pcg(mat, b, xd + 1e-6 * np.abs(xd).max(), tol=1e-10, max_iter=5000)
    assert it_warm < it
    xa, _, used_direct = solve_linear(mat, b, solver="auto", max_iter=1)
    assert used_direct and np.allclose(xa, xd)


def test_bad_arguments():
    sysm, state = _oscillator()
    with pytest.raises(ValueError, match="h"):
        symplectic_euler(sysm, state, -1.0)
    with pytest.raises(ValueError, match="scheme"):
        integrate(sysm, state, 0.1, "rk4")
    with pytest.raises(ValueError, match="solver"):
        backward_euler(sysm, state, 0.1, solver="cholesky")
    with pytest.raises(ValueError, match="max_newton"):
        backward_euler(sysm, state, 0.1, max_newton=0)
