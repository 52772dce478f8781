"""Contacts: rest, friction on an incline, restitution, stacks, collisions between bodies."""

import math

import numpy as np
import pytest
from rigid_shapes import ball, box_mesh, l_prism

from filters.elastic.contact import Colliders
from filters.geometry import Box, Plane, Sphere
from filters.rigid import RigidBodies, RigidBody, quaternion_from_axis_angle

G = 9.81
H = 1.0 / 240.0


def _floor(friction=0.5, restitution=0.0):
    return Colliders(friction=friction, restitution=restitution).add(Plane((0, 0, 0), (0, 0, 1)))


def _run(sim, seconds, h=H):
    for _ in range(int(round(seconds / h))):
        sim.step(h)


@pytest.mark.parametrize("restitution", [0.0, 0.8])
def test_a_box_at_rest_on_the_floor_stays_exactly_at_rest(restitution):
    v, f = box_mesh((0.2, 0.3, 0.1), center=(0.0, 0.0, 0.05))
    sim = RigidBodies([RigidBody(v, f, density=600.0, restitution=restitution)],
                      colliders=_floor())
    x0 = sim.state.positions.copy()
    q0 = sim.state.extra["orientations"].copy()
    _run(sim, 0.25)
    x1 = sim.state.positions.copy()
    _run(sim, 2.0)
    # the first step settles to round-off; after it nothing moves: no jitter, no creep
    assert np.abs(x1 - x0).max() < 1e-12
    assert np.abs(sim.state.positions - x1).max() < 1e-14
    assert np.abs(sim.state.extra["orientations"] - q0).max() < 1e-14
    assert np.abs(sim.state.velocities).max() < 1e-14
    assert np.abs(sim.state.extra["angular_velocities"]).max() < 1e-13
    assert sim.last_contacts > 0 and sim.last_sweeps == 1  # warm-started: converged at once
    assert sim.energies().kinetic < 1e-26


@pytest.mark.parametrize("alpha_deg, mu", [(20.0, 0.5), (30.0, 0.3), (35.0, 0.2)])
def test_a_box_on_an_incline_sticks_below_the_friction_angle_and_slides_above(alpha_deg, mu):
    a = math.radians(alpha_deg)
    normal = np.array([-math.sin(a), 0.0, math.cos(a)])
    downhill = np.array([-math.cos(a), 0.0, -math.sin(a)])
    v, f = box_mesh((0.2, 0.2, 0.05))
    body = RigidBody(v, f, density=500.0, friction=mu)
    incline = Colliders(friction=mu).add(Plane((0, 0, 0), normal))  # mixed: sqrt(mu mu) = mu
    sim = RigidBodies([body], positions=[0.025 * normal],
                      orientations=[quaternion_from_axis_angle((0, 1, 0), -a)], colliders=incline)
    x0 = sim.state.positions[0].copy()
    _run(sim, 1.0)
    t = sim.state.time
    moved = (sim.state.positions[0] - x0) @ downhill
    speed = sim.state.velocities[0] @ downhill
    assert abs((sim.state.positions[0] - x0) @ normal) < 1e-12  # stays on the plane
    assert np.abs(sim.state.extra["angular_velocities"]).max() < 1e-12  # does not tip
    if math.tan(a) < mu:
        assert abs(moved) < 1e-12 and abs(speed) < 1e-12
    else:
        accel = G * (math.sin(a) - mu * math.cos(a))
        assert speed == pytest.approx(accel * t, rel=1e-12)
        # symplectic Euler: s = a t (t + h) / 2
        assert moved == pytest.approx(0.5 * accel * t * (t + H), rel=1e-12)


def _first_rebound(restitution, h, drop=0.5, radius=0.05):
    """Highest point of the ball's centre (less its radius) after its first contact."""
    v, f = ball(radius, 3)
    body = RigidBody(v, f, density=1000.0, restitution=restitution, friction=0.0)
    sim = RigidBodies([body], positions=[[0.0, 0.0, drop + radius]],
                      colliders=_floor(friction=0.0, restitution=restitution))
    fall = math.sqrt(2 * drop / G)
    heights, landed = [], False
    for _ in range(int((fall * (1 + 2 * restitution) + 0.05) / h)):
        sim.step(h)
        landed = landed or sim.state.velocities[0, 2] >= 0.0
        if landed:
            heights.append(sim.state.positions[0, 2] - radius)
    assert landed
    assert np.abs(sim.state.extra["angular_velocities"]).max() < 1e-10  # hit under the centre
    return max(heights)


def test_a_dropped_ball_rebounds_to_e_squared_of_its_height_at_first_order():
    e, drop = 0.5, 0.5
    coarse = _first_rebound(e, 1.0 / 1000.0, drop) / drop
    fine = _first_rebound(e, 1.0 / 4000.0, drop) / drop
    assert fine == pytest.approx(e * e, rel=0.01)
    # the bounce happens up to one step's travel above the floor: the error is O(h)
    assert abs(fine - e * e) < 0.5 * abs(coarse - e * e)
    assert _first_rebound(0.0, 1.0 / 1000.0, drop) < 1e-3  # inelastic: stays down


def test_a_stack_of_two_boxes_is_stable():
    lower, fl = box_mesh(0.2, center=(0.0, 0.0, 0.1))
    for size in (0.12, 0.2):  # smaller on top, and flush (edges on edges)
        upper, fu = box_mesh((size, size, 0.1), center=(0.0, 0.0, 0.25))
        sim = RigidBodies([RigidBody(lower, fl, density=500.0),
                           RigidBody(upper, fu, density=500.0)], colliders=_floor())
        x0 = sim.state.positions.copy()
        _run(sim, 0.5)
        x1 = sim.state.positions.copy()
        _run(sim, 2.0)
        assert np.abs(x1 - x0).max() < 1e-5      # the first steps settle (cold start)
        assert np.abs(sim.state.positions - x1).max() < 1e-12   # then nothing moves
        assert np.abs(sim.state.velocities).max() < 1e-12
        assert np.abs(sim.state.extra["angular_velocities"]).max() < 1e-12


def test_a_box_dropped_off_centre_onto_another_comes_to_rest_on_it():
    lower, fl = box_mesh(0.2, center=(0.0, 0.0, 0.1))
    upper, fu = box_mesh((0.12, 0.12, 0.1), center=(0.02, 0.01, 0.35))
    sim = RigidBodies([RigidBody(lower, fl, density=500.0), RigidBody(upper, fu, density=500.0)],
                      colliders=_floor())
    _run(sim, 2.0)
    np.testing.assert_allclose(sim.state.positions[1], [0.02, 0.01, 0.25], atol=1e-5)
    assert np.abs(sim.state.velocities).max() < 1e-10


def _momenta_conserved(bodies, positions, velocities, spins, seconds=1.0):
    sim = RigidBodies(bodies, positions=positions, velocities=velocities,
                      angular_velocities=spins, gravity=(0, 0, 0))
    p0, l0 = sim.momentum()
    e0 = sim.energy()
    touched = 0
    for _ in range(int(seconds / H)):
        sim.step(H)
        touched = max(touched, sim.last_contacts)
        p1, l1 = sim.momentum()
        assert np.abs(p1 - p0).max() <= 1e-9 * np.abs(p0).max()
        assert np.abs(l1 - l0).max() <= 1e-9 * np.abs(l0).max()
        assert sim.energy() <= e0 * (1 + 1e-9)  # energy never grows without a source
    return sim, touched, e0


def test_colliding_bodies_conserve_momentum_and_angular_momentum():
    v1, f1 = box_mesh(0.2)
    v2, f2 = ball(0.1, 2)
    bodies = [RigidBody(v1, f1, density=500.0, restitution=0.5, friction=0.4),
              RigidBody(v2, f2, density=800.0, restitution=0.5, friction=0.4)]
    sim, touched, e0 = _momenta_conserved(
        bodies, [[0, 0, 0], [0.5, 0.05, 0.03]], [[1, 0, 0], [-2, 0.3, 0]],
        [[0, 1, 2], [3, 0, 0]])
    assert touched > 0 and sim.energy() < 0.9 * e0  # they met, inelastically


def test_a_non_convex_body_collides_through_its_distance_grid():
    vl, fl = l_prism()
    vb, fb = ball(0.04, 2)
    body = RigidBody(vl, fl, density=500.0, restitution=0.3, friction=0.3)
    assert not body.convex
    # the ball flies into the L's notch, between its two legs
    sim, touched, _ = _momenta_conserved(
        [body, RigidBody(vb, fb, density=900.0, restitution=0.3, friction=0.3)],
        [body.center, [0.5, 0.0, 0.2]], [[0, 0, 0], [-1.5, 0, -0.5]], [[0, 0, 0], [0, 2, 0]])
    assert touched > 0
    # the ball never got inside the L
    x, _ = sim.to_world(sim._vertices, sim._vertex_body)
    from filters.rigid import rotation_matrices
    r = rotation_matrices(sim.state.extra["orientations"][:1])[0]
    d, _ = body.signed_distance((x[sim._vertex_body == 1] - sim.state.positions[0]) @ r)
    assert d.min() > -2e-3


def test_a_box_rests_in_the_notch_of_a_fixed_non_convex_body():
    vl, fl = l_prism()
    vb, fb = box_mesh(0.08, center=(0.21, 0.0, 0.16))
    sim = RigidBodies([RigidBody(vl, fl, fixed=True), RigidBody(vb, fb, density=300.0)],
                      colliders=_floor())
    _run(sim, 1.5)
    np.testing.assert_allclose(sim.state.positions[1], [0.21, 0.0, 0.14], atol=2e-4)
    assert np.abs(sim.state.velocities).max() < 1e-10
    np.testing.assert_array_equal(sim.state.positions[0], RigidBody(vl, fl).center)


def test_a_body_stays_in_a_container_and_rests_on_a_sphere():
    v, f = box_mesh(0.1)
    tank = Colliders(friction=0.3).add(~Box((-0.5, -0.5, 0.0), (0.5, 0.5, 1.0)))
    sim = RigidBodies([RigidBody(v, f, density=700.0)], positions=[[0.3, 0.2, 0.5]],
                      velocities=[[3.0, 2.0, 0.0]], angular_velocities=[[1.0, 2.0, 3.0]],
                      colliders=tank)
    for _ in range(int(3.0 / H)):
        sim.step(H)
        x, _ = sim.to_world(sim._vertices, sim._vertex_body)
        assert x.min(axis=0)[2] > -1e-3 and np.abs(x[:, :2]).max() < 0.5 + 1e-3
    assert np.abs(sim.state.velocities).max() < 1e-6  # at rest in the end
    dome = Colliders(friction=0.5).add(Sphere((0, 0, 0), 0.5))
    sim = RigidBodies([RigidBody(v, f, density=500.0)], positions=[[0.0, 0.0, 0.6]],
                      colliders=dome)
    _run(sim, 1.0)
    # the dome touches the box's face between its contact points (0.02 m apart, the default
    # quarter of its radius): it sinks in by about (0.01 m)^2 / (2 R) = 1e-4 m
    np.testing.assert_allclose(sim.state.positions[0], [0.0, 0.0, 0.55], atol=2e-4)
    assert np.abs(sim.state.velocities).max() < 1e-10


def test_friction_is_a_cone_the_slide_direction_does_not_matter():
    a, mu = math.radians(30.0), 0.3
    speeds = []
    for azimuth in (0.0, math.radians(37.0), math.radians(-115.0)):
        normal = np.array([-math.sin(a) * math.cos(azimuth), -math.sin(a) * math.sin(azimuth),
                           math.cos(a)])
        v, f = box_mesh((0.2, 0.2, 0.05))
        tilt = np.cross([0, 0, 1.0], normal)
        sim = RigidBodies([RigidBody(v, f, density=500.0, friction=mu)],
                          positions=[0.025 * normal],
                          orientations=[quaternion_from_axis_angle(tilt, a)],
                          colliders=Colliders(friction=mu).add(Plane((0, 0, 0), normal)))
        _run(sim, 0.5)
        speeds.append(np.linalg.norm(sim.state.velocities[0]))
    expected = G * (math.sin(a) - mu * math.cos(a)) * 0.5
    np.testing.assert_allclose(speeds, expected, rtol=1e-12)


def test_a_fast_ball_does_not_tunnel_through_a_thin_wall():
    # 20 m/s at 60 steps per second: 0.33 m per step through a wall 1 cm thick
    vb, fb = ball(0.05, 2)
    vw, fw = box_mesh((0.01, 1.0, 1.0))
    sim = RigidBodies([RigidBody(vb, fb, density=500.0, restitution=0.0),
                       RigidBody(vw, fw, fixed=True)],
                      positions=[[-1.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
                      velocities=[[20.0, 0.0, 0.0], [0, 0, 0]], gravity=(0, 0, 0))
    ball_points = sim._vertex_body == 0
    front = []
    for _ in range(30):
        sim.step(1.0 / 60.0)
        x, _ = sim.to_world(sim._vertices, sim._vertex_body)
        front.append(x[ball_points, 0].max())
    assert max(front) < -0.005 + 1e-3  # at most 1 mm into the wall's face
    assert max(front) > -0.005 - 1e-3  # and it reached the wall
    assert abs(sim.state.velocities[0, 0]) < 0.05  # inelastic: 20 m/s stopped at the wall


def test_overlaps_are_pushed_apart_without_gaining_speed():
    v, f = box_mesh(0.2)
    sim = RigidBodies([RigidBody(v, f, density=500.0), RigidBody(v, f, density=800.0)],
                      positions=[[0, 0, 0], [0.19, 0.0, 0.0]], gravity=(0, 0, 0))
    for _ in range(120):
        sim.step(H)
        assert np.abs(sim.state.velocities).max() == 0.0
        assert np.abs(sim.state.extra["angular_velocities"]).max() < 1e-15
    gap = sim.state.positions[1, 0] - sim.state.positions[0, 0]
    assert 0.2 - 1e-4 - 1e-9 <= gap < 0.2  # separated to within the slop, no further
    # the centre of mass stays put: the push conserves momentum
    mass = np.array([b.mass for b in sim.model.bodies])
    assert abs(mass @ sim.state.positions[:, 0] - mass[1] * 0.19) < 1e-15
