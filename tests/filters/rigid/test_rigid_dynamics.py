"""Free motion of rigid bodies: free fall, torque-free tumbling, applied forces, body points."""

import numpy as np
import pytest
from rigid_shapes import ball, box_mesh

from filters import SimulationUnstableError
from filters.rigid import RigidBodies, RigidBody, quaternion_from_axis_angle, rotation_matrices
from filters.rigid.dynamics import FORCE_CHUNKS, point_force_sums

G = np.array([0.0, 0.0, -9.81])


def _box_body(size=(0.1, 0.2, 0.3), **kw):
    v, f = box_mesh(size)
    return RigidBody(v, f, density=1000.0, **kw)


@pytest.mark.parametrize("scheme, sign", [("symplectic_euler", 1.0), ("euler", -1.0)])
def test_free_fall_follows_the_scheme_exactly_and_the_spin_does_not_matter(scheme, sign):
    h, n = 1e-3, 500
    x0 = np.array([0.1, -0.2, 3.0])
    v0 = np.array([1.0, 0.5, 2.0])
    w0 = np.array([3.0, -2.0, 5.0])
    sim = RigidBodies([_box_body()], positions=[x0], velocities=[v0], angular_velocities=[w0],
                      scheme=scheme)
    _, l0 = sim.momentum()
    for _ in range(n):
        sim.step(h)
    t = n * h
    # velocity exact; position: the parabola plus the scheme's +-g h t / 2
    np.testing.assert_allclose(sim.state.velocities[0], v0 + G * t, rtol=0, atol=1e-12)
    exact = x0 + v0 * t + 0.5 * G * t * t
    np.testing.assert_allclose(sim.state.positions[0], exact + sign * 0.5 * G * h * t,
                               rtol=0, atol=1e-12)
    # the error of the parabola is first order: g h t / 2
    assert abs(sim.state.positions[0, 2] - exact[2]) == pytest.approx(0.5 * 9.81 * h * t,
                                                                      rel=1e-9)
    # the spin does not touch the centre of mass; its own angular momentum is conserved
    _, l1 = sim.momentum()
    spin0 = l0 - np.cross(x0, 1000 * 0.006 * v0)
    spin1 = l1 - np.cross(sim.state.positions[0], 1000 * 0.006 * sim.state.velocities[0])
    np.testing.assert_allclose(spin1, spin0, rtol=1e-12)


def _tumble(w0, h, duration, every=5):
    body = _box_body()
    sim = RigidBodies([body], angular_velocities=[w0], gravity=(0, 0, 0))
    e0 = sim.energy()
    _, l0 = sim.momentum()
    energy, axis_rate = [], []
    for i in range(int(round(duration / h))):
        sim.step(h)
        if i % every == 0:
            energy.append(sim.energy())
            r = rotation_matrices(sim.state.extra["orientations"])[0]
            axis_rate.append(r.T @ sim.state.extra["angular_velocities"][0])
    _, l1 = sim.momentum()
    return (np.abs(np.array(energy) / e0 - 1).max(), np.linalg.norm(l1 - l0) / np.linalg.norm(l0),
            np.array(axis_rate))


def test_torque_free_tumbling_conserves_momentum_and_energy_and_flips_the_middle_axis():
    # box 0.1 x 0.2 x 0.3: moments (0.13, 0.10, 0.05) * m / 12, y is the intermediate axis
    w0 = np.array([1e-3, 10.0, 1e-3])
    de1, dl1, _ = _tumble(w0, 2e-3, 8.0)
    de2, dl2, rates = _tumble(w0, 1e-3, 8.0)
    assert dl1 < 1e-11 and dl2 < 1e-11          # angular momentum: round-off
    assert de2 < 2e-6                            # energy: bounded, second order
    assert 3.5 < de1 / de2 < 4.5
    # the Dzhanibekov flip: the spin about y reverses, and comes back
    wy = rates[:, 1]
    assert wy.min() < -9.0 and wy.max() > 9.0
    assert np.count_nonzero(np.diff(np.sign(wy))) >= 2
    # spins about the largest and the smallest axis are stable: no flip
    for w in ([10.0, 1e-3, 1e-3], [1e-3, 1e-3, 10.0]):
        k = int(np.argmax(w))
        _, _, rates = _tumble(np.array(w), 2e-3, 8.0)
        assert rates[:, k].min() > 0.99 * 10.0


def test_energy_of_tumbling_does_not_drift_over_many_periods():
    w0 = np.array([2.0, 5.0, 1.0])
    de, dl, _ = _tumble(w0, 4e-3, 60.0, every=25)
    assert de < 2e-5 and dl < 1e-10
    # a step of about half a radian per step: still bounded, still exact in L
    de, dl, _ = _tumble(w0, 0.1, 200.0, every=1)
    assert de < 1e-2 and dl < 1e-11


def test_applied_forces_and_torques_act_for_one_step():
    body = _box_body()
    sim = RigidBodies([body], gravity=(0, 0, 0))
    h = 0.01
    sim.apply_force(0, [2.0, 0.0, 0.0], point=sim.state.positions[0] + [0.0, 0.1, 0.0])
    sim.apply_torque(0, [0.0, 0.0, 0.5])
    sim.step(h)
    m = body.mass
    np.testing.assert_allclose(sim.state.velocities[0], [2.0 * h / m, 0, 0], rtol=1e-14)
    # torque (0.1 y) x (2 x) = -0.2 z, plus 0.5 z: 0.3 z about the z principal axis
    expected_w = h * 0.3 / body.inertia[2, 2]
    np.testing.assert_allclose(sim.state.extra["angular_velocities"][0], [0, 0, expected_w],
                               rtol=1e-12, atol=1e-16)
    v1 = sim.state.velocities.copy()
    sim.step(h)  # no force now
    np.testing.assert_allclose(sim.state.velocities, v1, rtol=0, atol=0)


def test_point_forces_sum_to_the_explicit_force_and_torque_on_any_thread_count(rng):
    n, bodies = 50_000, 3
    points = rng.normal(size=(n, 3))
    forces = rng.normal(size=(n, 3))
    which = rng.integers(0, bodies, n)
    centers = rng.normal(size=(bodies, 3))
    sums = point_force_sums(points, forces, which, centers)
    for b in range(bodies):
        sel = which == b
        np.testing.assert_allclose(sums[b, :3], forces[sel].sum(0), rtol=1e-10, atol=1e-9)
        torque = np.cross(points[sel] - centers[b], forces[sel]).sum(0)
        np.testing.assert_allclose(sums[b, 3:], torque, rtol=1e-10, atol=1e-9)
    import numba
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        again = point_force_sums(points, forces, which, centers)
    finally:
        numba.set_num_threads(before)
    assert np.array_equal(sums, again) and FORCE_CHUNKS > 1


def test_apply_point_forces_is_what_the_next_step_feels():
    sim = RigidBodies([_box_body(), _box_body()], positions=[[0, 0, 0], [1, 0, 0]],
                      gravity=(0, 0, 0))
    x, _ = sim.to_world(sim._vertices, sim._vertex_body)
    f = np.tile([0.0, 0.0, 1.0], (x.shape[0], 1))
    added = sim.apply_point_forces(x, f, sim._vertex_body)
    np.testing.assert_allclose(added[:, :3], [[0, 0, 8.0], [0, 0, 8.0]])
    np.testing.assert_allclose(added[:, 3:], 0.0, atol=1e-14)  # symmetric: no torque
    sim.step(0.1)
    np.testing.assert_allclose(sim.state.velocities[:, 2], 0.1 * 8.0 / 6.0, rtol=1e-14)
    with pytest.raises(ValueError, match="bodies"):
        sim.apply_point_forces(x, f, np.full(x.shape[0], 2))
    with pytest.raises(ValueError, match="forces"):
        sim.apply_point_forces(x, f[:-1], 0)


def test_apply_wrenches_is_the_same_as_forces_and_torques():
    sims = [RigidBodies([_box_body(), _box_body()], positions=[[0, 0, 0], [1, 0, 0]],
                        gravity=(0, 0, -1.0)) for _ in range(2)]
    w = np.array([[1.0, 0.0, 2.0, 0.0, 0.3, 0.0], [0.0, -1.0, 0.0, 0.1, 0.0, 0.2]])
    sims[0].apply_wrenches(w)
    for b in range(2):
        sims[1].apply_force(b, w[b, :3])
        sims[1].apply_torque(b, w[b, 3:])
    for sim in sims:
        sim.step(0.1)
    assert np.array_equal(sims[0].state.velocities, sims[1].state.velocities)
    assert np.array_equal(sims[0].state.extra["angular_velocities"],
                          sims[1].state.extra["angular_velocities"])
    assert np.abs(sims[0].state.extra["angular_velocities"]).max() > 0
    with pytest.raises(ValueError, match="wrenches"):
        sims[0].apply_wrenches(w[:1])
    with pytest.raises(ValueError, match="wrenches"):
        sims[0].apply_wrenches(np.full((2, 6), np.nan))


def test_surface_samples_move_with_the_body():
    v, f = box_mesh(0.2)
    body = RigidBody(v, f, sample_spacing=0.02)
    q = quaternion_from_axis_angle((1, 1, 0), 0.4)
    w = np.array([0.5, -1.0, 2.0])
    sim = RigidBodies([body], positions=[[1.0, 2.0, 3.0]], orientations=[q],
                      velocities=[[0.1, 0.2, 0.3]], angular_velocities=[w], gravity=(0, 0, 0))
    x, u, which, volumes = sim.surface_samples()
    assert x.shape == (body.samples.n_points, 3) and (which == 0).all()
    np.testing.assert_array_equal(volumes, body.samples.volumes)
    r = rotation_matrices([q])[0]
    np.testing.assert_allclose(x, [1.0, 2.0, 3.0] + body.samples.points @ r.T, atol=1e-15)
    np.testing.assert_allclose(u, [0.1, 0.2, 0.3] + np.cross(w, x - [1.0, 2.0, 3.0]),
                               atol=1e-14)
    # they fill the body's outer layers where it is now (two spacings deep)
    d, _ = body.signed_distance((x - [1.0, 2.0, 3.0]) @ r)
    assert d.max() < 0.0 and d.min() >= -2 * 0.02 - 1e-12
    # and the positions follow the motion: a small step moves them by ~ h u
    sim.step(1e-6)
    x1, _, _, _ = sim.surface_samples()
    np.testing.assert_allclose((x1 - x) / 1e-6, u, atol=1e-5)


def test_a_runaway_body_raises_the_instability_error():
    sim = RigidBodies([_box_body()], max_speed=10.0)
    sim.apply_force(0, [1e6, 0, 0])
    with pytest.raises(SimulationUnstableError, match="max_speed") as err:
        sim.step(0.01)
    assert err.value.time == pytest.approx(0.01)


def test_ball_samples_and_vertices_use_one_body_frame():
    v, f = ball(0.1, 2, center=(0.0, 0.0, 1.0))
    body = RigidBody(v, f, sample_spacing=0.03)
    sim = RigidBodies([body])
    frame = sim.frame()
    np.testing.assert_allclose(frame.points, v, atol=1e-15)  # where the mesh was given
    # the samples fill the ball's outer layers (two spacings) around where it was given
    x = sim.surface_samples()[0]
    r = np.linalg.norm(x - [0, 0, 1.0], axis=1)
    assert r.max() < 0.1 and r.min() > 0.1 - 2 * 0.03 - 0.01
    np.testing.assert_allclose(x.mean(axis=0), [0.0, 0.0, 1.0], atol=0.01)


def test_inverse_masses_are_those_of_the_turned_inertia_and_zero_when_fixed():
    q = quaternion_from_axis_angle((1.0, 2.0, 0.5), 0.7)
    sim = RigidBodies([_box_body(), _box_body(fixed=True)], orientations=[q, q])
    inv_mass, inv_inertia = sim.inverse_masses()
    body = sim.model.bodies[0]
    r = rotation_matrices(np.asarray([q]))[0]
    assert inv_mass[0] == pytest.approx(1.0 / body.mass) and inv_mass[1] == 0.0
    np.testing.assert_allclose(inv_inertia[0], np.linalg.inv(r @ body.inertia @ r.T),
                               rtol=1e-12, atol=0.0)
    assert not inv_inertia[1].any()
