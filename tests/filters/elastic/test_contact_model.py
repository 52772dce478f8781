"""Contact and friction inside the time step: barrier derivatives, the line-search filter,
Coulomb friction on a tilted plane and inelastic drops in every scheme, energy never gained."""

import math

import numpy as np
import pytest

from filters.elastic.contact import Colliders
from filters.elastic.contact_model import ContactModel, barrier
from filters.elastic.mass_spring import ClothSimulation, MassSpringSimulation
from filters.elastic.springs import SpringSystem
from filters.elastic.topology import STRETCH, SpringTopology
from filters.geometry import Box, Plane, Sphere
from filters.integrators import backward_euler
from filters.simulation import State

SCHEMES = [("symplectic_euler", 1e-3), ("linearized_backward_euler", 1.0 / 120.0),
           ("backward_euler", 1.0 / 60.0)]


def _colliders(friction=0.4, thickness=0.01):
    return (Colliders(friction=friction, thickness=thickness)
            .add(Plane((0, 0, 0), (0, 0.3, 1.0)))
            .add(Sphere((0.5, 0, 0.3), 0.2))
            .add(~Box((-1, -1, -1), (2, 2, 2)), friction=0.1))


def test_barrier_is_c2_at_dhat_and_infinite_at_contact():
    dhat = 0.01
    b, db, ddb = barrier(dhat, dhat)
    assert (b, db, ddb) == (0.0, 0.0, 0.0)
    below = barrier(dhat * (1 - 1e-6), dhat)
    assert below[0] > 0 and abs(below[1]) < 1e-9 and abs(below[2]) < 1e-4
    assert barrier(0.0, dhat)[0] == math.inf
    d = 0.3 * dhat  # derivatives by central differences
    eps = 1e-9
    assert barrier(d, dhat)[1] == pytest.approx(
        (barrier(d + eps, dhat)[0] - barrier(d - eps, dhat)[0]) / (2 * eps), rel=1e-5)
    assert barrier(d, dhat)[2] == pytest.approx(
        (barrier(d + eps, dhat)[1] - barrier(d - eps, dhat)[1]) / (2 * eps), rel=1e-5)


@pytest.mark.parametrize("embedded", [False, True])
def test_contact_gradient_matches_finite_differences_and_blocks_are_psd(embedded):
    rng = np.random.default_rng(1)
    n = 12
    # points near the tilted floor, the sphere and the box's walls, within the barrier's reach
    x0 = np.array([[0.1, 0.0, 0.006], [0.5, 0.0, 0.507], [1.994, 0.5, 0.5], [0.3, 0.2, -0.05]])
    x0 = np.vstack([x0, rng.uniform(0.2, 1.5, size=(n - 4, 3))])
    masses = rng.uniform(0.5, 1.5, n)
    emb = None
    if embedded:
        nodes = rng.integers(0, n, size=(20, 3))
        weights = rng.uniform(0.1, 1.0, size=(20, 3))
        weights /= weights.sum(axis=1, keepdims=True)
        nodes[:4, 0] = np.arange(4)
        weights[:4] = [1.0, 0.0, 0.0]
        emb = (nodes, weights)
    contact = ContactModel(_colliders(), masses, 0.01, embedding=emb, slip_velocity=0.05)
    contact.begin_step(x0, 0.01)
    assert contact.touching >= 3
    dx = 1e-3 * rng.standard_normal((n, 3))
    dx[:4] *= 0.5
    grad = np.zeros((n, 3))
    blocks = np.zeros((n, 3, 3))
    e = contact.derivatives(x0, dx, grad, blocks)
    assert e == pytest.approx(contact.value(x0, dx))
    eps = 1e-8
    numeric = np.zeros_like(grad)
    for i in range(n):
        for k in range(3):
            plus = dx.copy()
            plus[i, k] += eps
            minus = dx.copy()
            minus[i, k] -= eps
            numeric[i, k] = (contact.value(x0, plus) - contact.value(x0, minus)) / (2 * eps)
    np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-6 * np.abs(grad).max())
    assert np.all(np.linalg.eigvalsh(blocks) >= -1e-9 * np.abs(blocks).max())
    assert np.allclose(blocks, blocks.transpose(0, 2, 1))


def test_line_search_filter_keeps_every_point_outside():
    contact = ContactModel(_colliders(friction=0.0), np.ones(4), 0.01)
    x0 = np.array([[0.1, 0.0, 0.02], [0.5, 0.0, 0.52], [1.9, 0.5, 0.5], [0.2, 0.2, 1.0]])
    d = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.1]])
    before = contact.clearance(x0)
    alpha = contact.max_step(x0, np.zeros_like(x0), d)
    after = contact.clearance(x0 + alpha * d)
    assert 0.0 < alpha < 1.0
    assert np.all(after >= contact.KEEP * before - 1e-12)
    # the tightest point lands exactly on its bound (exact for planes and spheres)
    assert np.min(after - contact.KEEP * before) == pytest.approx(0.0, abs=1e-9)
    # each particle alone may move farther than the common fraction
    steps = contact.particle_steps(x0, np.zeros_like(x0), d)
    assert steps.min() == pytest.approx(alpha) and steps[3] == 1.0


def _block(angle_deg, scheme, h, mu=0.5, stiffness=1e3):
    """A 10 cm cube of 8 particles (1 kg, every pair a spring) resting on a plane tilted by
    ``angle_deg`` about the y axis; returns the simulation and the uphill unit vector."""
    a = math.radians(angle_deg)
    n = np.array([-math.sin(a), 0.0, math.cos(a)])
    up = np.array([math.cos(a), 0.0, math.sin(a)])
    side = np.cross(n, up)
    corners = np.array([[i, j, k] for k in (0, 1) for j in (0, 1) for i in (0, 1)], float) * 0.1
    pos = corners[:, :1] * up + corners[:, 1:2] * side + (corners[:, 2:] + 5e-4) * n
    pairs = np.array([(p, q) for p in range(8) for q in range(p + 1, 8)])
    top = SpringTopology(pos, pairs, np.full(len(pairs), STRETCH, np.int8), np.full(8, 0.125),
                         np.zeros(8, bool), "polys", np.array([0]), np.zeros(0, np.int64))
    plane = Colliders(friction=mu, thickness=1e-3).add(Plane((0, 0, 0), tuple(n)))
    sim = MassSpringSimulation(top, stretch_stiffness=stiffness, damping=0.5, scheme=scheme,
                               colliders=plane, max_dt=h)
    return sim, up


@pytest.mark.parametrize("scheme, h, stiffness, creep", [
    *((scheme, h, 1e3, 1.0) for scheme, h in SCHEMES),
    ("euler", 1e-3, 20.0, 2.0)])  # forward Euler: a soft block, whose position lags a step
def test_block_on_a_tilted_plane_sticks_below_the_friction_angle_and_slides_above(
        scheme, h, stiffness, creep):
    """Coulomb friction, mu = 0.5 (friction angle 26.6 degrees): at 20 degrees the block stays
    (static friction holds it with a creep below the slip velocity, 1 cm/s by default); at 35
    degrees it slides with a = g (sin a - mu cos a) = 1.609 m/s^2.  Measured at a slip velocity
    of 1 mm/s: 0.48 mm in 1 s (0.94 mm with forward Euler), and the acceleration to 1e-4 in
    every scheme."""
    for angle in (20.0, 35.0):
        sim, up = _block(angle, scheme, h, stiffness=stiffness)
        sim.advance_to(0.2)  # the normal contact settles
        s0 = sim.state.positions.mean(axis=0) @ up
        times = np.arange(1, 21) * 0.05
        travel = []
        for t in times:
            sim.advance_to(0.2 + t)
            travel.append(sim.state.positions.mean(axis=0) @ up - s0)
        travel = np.array(travel)
        assert sim.contact.clearance(sim.state.positions).min() > 0.0
        a = math.radians(angle)
        if angle < 26.0:
            assert abs(travel[-1]) < creep * sim.contact.slip_velocity * 1.0  # mm in 1 s
        else:
            accel = -2.0 * np.polyfit(times, travel, 2)[0]
            expected = 9.81 * (math.sin(a) - 0.5 * math.cos(a))
            assert accel == pytest.approx(expected, rel=0.05)


@pytest.mark.parametrize("scheme, h", [("symplectic_euler", 2e-4),
                                       ("linearized_backward_euler", 1.0 / 120.0),
                                       ("backward_euler", 1.0 / 60.0)])
def test_a_dropped_cloth_does_not_bounce(scheme, h):
    """Contacts are inelastic (critical normal damping): a cloth dropped flat from 20 cm onto
    the floor rises less than 1 % of its drop height above where it rests."""
    drop = 0.2
    floor = Colliders(friction=0.5, thickness=0.005).add(Plane((0, 0, 0), (0, 0, 1)))
    sim = ClothSimulation.grid(6, 6, size=(0.3, 0.3), origin=(-0.15, -0.15, drop),
                               stretch_stiffness=50.0, scheme=scheme, colliders=floor, max_dt=h)
    landed, highest = False, 0.0
    for k in range(1, 25):
        sim.advance_to(k / 40)
        z = sim.state.positions[:, 2]
        if landed:
            highest = max(highest, z.max())
        landed = landed or z.min() < floor.thickness
    assert landed and sim.contact.clearance(sim.state.positions).min() > 0.0
    assert highest - floor.thickness < 0.01 * drop


def test_newton_with_colliders_never_gains_energy_and_keeps_the_contacts():
    """A stiff chain (k_e h^2 / m = 1.8e3) pinned at one end swings down onto a sphere and the
    floor with friction: the energy account (kinetic + elastic + gravitational + barrier) never
    rises from one step to the next, and no particle enters a collider."""
    n = 12
    x = np.stack([np.linspace(0, 1.0, n), np.zeros(n), np.full(n, 0.5)], axis=1)
    pairs = np.stack([np.arange(n - 1), np.arange(1, n)], 1)
    pinned = np.zeros(n, bool)
    pinned[0] = True
    system = SpringSystem(pairs, 1.0 / (n - 1), 1e4, np.full(n, 0.01), pinned=pinned)
    colliders = (Colliders(friction=0.5, thickness=0.01).add(Plane((0, 0, 0), (0, 0, 1)))
                 .add(Sphere((0.6, 0.0, 0.15), 0.15)))
    h = 1.0 / 30.0
    contact = ContactModel(colliders, system.masses, h, pinned=pinned,
                           elastic_diagonal=system.elastic_diagonal())
    state = State(x)

    def energy():
        return system.energy(state.positions, state.velocities) + contact.energy(state.positions)

    e = energy()
    touched = 0
    for _ in range(60):
        info = backward_euler(system, state, h, solver="direct", newton_tol=1e-4, max_newton=50,
                              contact=contact)
        e_new = energy()
        assert e_new <= e + 1e-9 * abs(e)
        assert info.velocity_scale == 1.0  # Newton converged without the energy budget
        e = e_new
        touched = max(touched, contact.touching)
        assert contact.clearance(state.positions).min() > 0.0
    assert touched >= 3


def test_bad_input():
    floor = Colliders().add(Plane((0, 0, 0), (0, 0, 1)))
    with pytest.raises(ValueError, match="restitution"):
        ContactModel(Colliders(restitution=0.5).add(Plane()), np.ones(2), 0.01)
    with pytest.raises(TypeError, match="colliders"):
        ContactModel([Plane()], np.ones(2), 0.01)
    with pytest.raises(ValueError, match="reference_step"):
        ContactModel(floor, np.ones(2), 0.0)
    with pytest.raises(ValueError, match="embedding weights"):
        ContactModel(floor, np.ones(2), 0.01, embedding=([[0, 1]], [[0.7, 0.7]]))
    with pytest.raises(ValueError, match="embedding nodes"):
        ContactModel(floor, np.ones(2), 0.01, embedding=([[0, 5]], [[0.5, 0.5]]))
    with pytest.raises(ValueError, match="slip_velocity"):
        ContactModel(floor, np.ones(2), 0.01, slip_velocity=0.0)
    contact = ContactModel(floor, np.ones(2), 0.01)
    with pytest.raises(ValueError, match="inside a collider"):
        contact.begin_step(np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -0.1]]), 0.01)
