"""Tests of filters.advect.NoiseAdvection: integrators against the theory of a rigid rotation,
incompressible advection without clumping, the emitter, colliders and bit-identical resume."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from filters.advect import BoxEmitter, NoiseAdvection
from filters.fields import CurlNoise, NoiseWind, RigidRotation, Uniform
from filters.geometry import Plane, Sphere
from filters.simulation import State

OMEGA = 2.0
STEPS_PER_REV = 100


def _rotate(integrator, revolutions=1):
    r0 = np.array([[1.0, 0.0, 0.3], [0.0, -2.0, -0.1], [0.5, 0.5, 0.0]])
    sim = NoiseAdvection(RigidRotation((0.0, 0.0, OMEGA)), positions=r0, integrator=integrator)
    h = 2 * np.pi / OMEGA / STEPS_PER_REV
    for _ in range(STEPS_PER_REV * revolutions):
        sim.step(h)
    radius0 = np.linalg.norm(r0[:, :2], axis=1)
    radius = np.linalg.norm(sim.state.positions[:, :2], axis=1)
    return sim, r0, radius0, radius, h * OMEGA


def test_forward_euler_spirals_out_as_theory_says():
    sim, r0, radius0, radius, a = _rotate("euler")
    # |1 + i a| per step
    np.testing.assert_allclose(radius / radius0, (1 + a * a) ** (STEPS_PER_REV / 2), rtol=1e-12)
    assert np.all(radius > radius0 * 1.2)
    np.testing.assert_array_equal(sim.state.positions[:, 2], r0[:, 2])  # axial motion: none


def test_rk2_grows_at_fourth_order_rate():
    _, _, radius0, radius, a = _rotate("rk2")
    # explicit midpoint: |1 + z + z^2/2| = sqrt(1 + a^4 / 4) for z = i a
    np.testing.assert_allclose(radius / radius0, (1 + a ** 4 / 4) ** (STEPS_PER_REV / 2),
                               rtol=1e-12)


def test_rk4_holds_the_radius_to_1e_6_per_revolution():
    sim, r0, radius0, radius, a = _rotate("rk4", revolutions=2)
    per_rev = np.abs(radius / radius0 - 1.0) / 2
    assert per_rev.max() < 1e-6
    # and the particles come back where they started (phase error ~ a^4 / 120 per step)
    assert np.abs(sim.state.positions - r0).max() < 1e-5
    # the amplification of RK4 is 1 - a^6/144 + ...: slightly inside, not outside
    assert np.all(radius < radius0)


def test_backward_euler_spirals_in_as_theory_says():
    _, _, radius0, radius, a = _rotate("linearized_backward_euler")
    # linear field, exact Jacobian: the step is exact backward Euler, |1 / (1 - i a)|
    np.testing.assert_allclose(radius / radius0, (1 + a * a) ** (-STEPS_PER_REV / 2),
                               rtol=1e-12)
    assert np.all(radius < radius0 / 1.2)


def _nn_quantiles(points):
    d, _ = cKDTree(points).query(points, k=2)
    return np.quantile(d[:, 1], [0.1, 0.25, 0.5, 0.75, 0.9])


def test_curl_noise_advection_does_not_clump():
    rng = np.random.default_rng(7)
    pts = rng.uniform(0.0, 2.0, (20000, 3))
    # particles that start deep inside the cloud keep full neighbourhoods while it deforms
    core = np.all((pts > 0.5) & (pts < 1.5), axis=1)

    def run(field):
        sim = NoiseAdvection(field, positions=pts, integrator="rk4")
        for _ in range(100):
            sim.step(0.01)
        return sim.state.positions

    curl = CurlNoise(amplitude=0.3, frequency=1.5, octaves=2, seed=3)
    moved = run(curl)
    # the flow really moves and shears the particles
    assert np.median(np.linalg.norm(moved - pts, axis=1)) > 0.1
    before = _nn_quantiles(pts)
    d_before, _ = cKDTree(pts).query(pts[core], k=2)
    d_after, _ = cKDTree(moved).query(moved[core], k=2)
    q_before = np.quantile(d_before[:, 1], [0.1, 0.25, 0.5, 0.75, 0.9])
    q_after = np.quantile(d_after[:, 1], [0.1, 0.25, 0.5, 0.75, 0.9])
    assert np.all(np.abs(q_after / q_before - 1.0) < 0.10), (q_before, q_after)
    assert before[2] > 0  # sanity
    # a compressible noise of the same strength does clump: the contrast shows the test bites
    wind = NoiseWind(amplitude=(0.6, 0.6, 0.6), frequency=1.5, octaves=2, seed=3)
    squeezed = run(wind)
    d_w, _ = cKDTree(squeezed).query(squeezed[core], k=2)
    q_w = np.quantile(d_w[:, 1], [0.1, 0.25, 0.5, 0.75, 0.9])
    assert np.abs(q_w / q_before - 1.0).max() > 0.10


def test_emitter_rate_lifetime_ids_and_box():
    emitter = BoxEmitter(lower=(0, 0, 0), upper=(1, 2, 0.5), rate=600.0, lifetime=0.5,
                         lifetime_jitter=0.0, jitter=1.0)
    sim = NoiseAdvection(Uniform((0.0, 0.0, 0.0)), emitter, integrator="euler")
    dt = 1.0 / 60.0
    for _ in range(15):
        sim.step(dt)
    s = sim.state
    assert s.n_points == 150  # 600 /s for 0.25 s, nothing has died yet
    assert np.all(s.positions >= [0, 0, 0]) and np.all(s.positions <= [1, 2, 0.5])
    assert np.array_equal(s.extra["id"], np.arange(150))
    ages = np.sort(s.extra["age"])
    # stratified birth times: ages cover (0, 0.25] evenly
    assert ages[0] > 0 and ages[-1] <= 0.25 + 1e-12
    assert abs(np.median(ages) - 0.125) < 0.01
    for _ in range(45):
        sim.step(dt)
    s = sim.state
    assert np.all(s.extra["age"] < 0.5)
    assert abs(s.n_points - 300) <= 1  # steady state: rate * lifetime
    assert np.all(np.diff(s.extra["id"]) > 0) and s.extra["id"][-1] == 599
    frame = sim.frame()
    names = [name for name, _ in sim.output_spec.point_arrays]
    assert set(frame.point_data) == set(names)
    assert all(len(frame.point_data[n]) == s.n_points for n in names)
    assert not sim.output_spec.fixed_topology


def test_newborns_advance_by_their_age():
    # a uniform wind: a particle of age a has moved a * w from its birth point
    emitter = BoxEmitter(lower=(0, 0, 0), upper=(0, 0, 0), rate=100.0, lifetime=10.0)
    sim = NoiseAdvection(Uniform((0.0, 0.0, 2.0)), emitter, integrator="rk2")
    for _ in range(10):
        sim.step(0.02)
    s = sim.state
    np.testing.assert_allclose(s.positions[:, 2], 2.0 * s.extra["age"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.velocities, np.tile([0, 0, 2.0], (s.n_points, 1)))


def test_colliders_push_particles_out():
    emitter = BoxEmitter(lower=(-1, -1, 0.5), upper=(1, 1, 1.0), rate=2000.0, lifetime=5.0)
    floor = Plane((0, 0, 0.0), (0, 0, 1))
    ball = Sphere((0.0, 0.0, 0.3), 0.25)
    field = Uniform((0.0, 0.0, -1.5)) + CurlNoise(amplitude=0.3, frequency=2.0)
    sim = NoiseAdvection(field, emitter, colliders=(floor, ball), collider_margin=0.01,
                         integrator="rk4")
    for _ in range(60):
        sim.step(1.0 / 60.0)
    p = sim.state.positions
    assert p.shape[0] > 1000
    assert p[:, 2].min() >= 0.01 - 1e-12
    assert np.linalg.norm(p - [0.0, 0.0, 0.3], axis=1).min() >= 0.26 - 1e-9
    assert np.sum(p[:, 2] < 0.05) > 100  # they did reach the floor


def test_ramped_curl_noise_keeps_particles_off_a_sphere_by_itself():
    ball = Sphere((0.0, 0.0, 0.0), 0.5)
    flow = CurlNoise(amplitude=0.5, frequency=1.5, colliders=(ball,), ramp_distance=0.3)
    rng = np.random.default_rng(1)
    pts = rng.uniform(-1.0, 1.0, (3000, 3))
    pts = pts[np.linalg.norm(pts, axis=1) > 0.55]
    sim = NoiseAdvection(flow, positions=pts, integrator="rk4")  # no push-out
    for _ in range(100):
        sim.step(0.01)
    assert np.linalg.norm(sim.state.positions, axis=1).min() > 0.5


def test_resume_from_checkpoint_is_bit_identical():
    def make():
        field = CurlNoise(amplitude=0.4, frequency=2.0, octaves=2, time_scale=0.5) \
            + Uniform((0.0, 0.0, 0.3))
        emitter = BoxEmitter(rate=333.3, lifetime=0.4, lifetime_jitter=0.3)
        return NoiseAdvection(field, emitter, colliders=(Plane(),), seed=17,
                              integrator="linearized_backward_euler", size_range=(0.01, 0.02))

    a = make()
    a.advance_to(0.5)
    checkpoint = a.state.to_arrays()
    a.advance_to(1.0)
    b = make()
    b.set_state(State.from_arrays(checkpoint))
    b.advance_to(1.0)
    sa, sb = a.state.to_arrays(), b.state.to_arrays()
    assert sa.keys() == sb.keys()
    for key in sa:
        assert np.array_equal(sa[key], sb[key]), key
    assert a.state.n_points > 100
    # a different seed gives a different run
    c = NoiseAdvection(CurlNoise(), BoxEmitter(rate=100.0), seed=18)
    d = NoiseAdvection(CurlNoise(), BoxEmitter(rate=100.0), seed=19)
    c.step(0.1)
    d.step(0.1)
    assert not np.array_equal(c.state.positions, d.state.positions)


def test_validation():
    with pytest.raises(ValueError, match="integrator"):
        NoiseAdvection(Uniform(), integrator="leapfrog")
    with pytest.raises(TypeError, match="field"):
        NoiseAdvection(lambda x, t: x)
    with pytest.raises(ValueError, match="rate"):
        BoxEmitter(rate=-1.0)
    with pytest.raises(ValueError, match="upper"):
        BoxEmitter(lower=(0, 0, 1), upper=(1, 1, 0))
    with pytest.raises(ValueError, match="max_dt"):
        NoiseAdvection(Uniform(), max_dt=0.0)
    with pytest.raises(ValueError, match="dt"):
        NoiseAdvection(Uniform()).step(-1.0)
    with pytest.raises(ValueError, match="size_range"):
        NoiseAdvection(Uniform(), size_range=(2.0, 1.0))


def test_noise_smoke_scene_writes_points_and_surface(tmp_path):
    from pipeline.io.series import read_series
    from scenes.noise_smoke import SCENE

    assert all(p.doc for p in SCENE.parameters.values())  # every parameter documented
    flow = SCENE.build(rate=600.0, radius=0.03, seed=2, surface=True)
    flow.source.set_frames(10.0, frames=4)
    flow.run(tmp_path, progress=False)
    times, particles = read_series(tmp_path / "particles.pvd")
    assert times.tolist() == [0.0, 0.1, 0.2, 0.3]
    counts = [m.n_points for m in particles]
    assert counts[0] == 0
    assert all(abs(c - 600 * t) <= 2 for c, t in zip(counts, times, strict=False))
    last = particles[-1]
    for name in ("velocity", "id", "age", "size", "color"):
        assert name in last.point_data
    assert last.points[:, 2].min() >= 0.0  # the floor holds
    assert 0.015 - 1e-12 <= last.point_data["size"].min() <= last.point_data["size"].max() <= 0.03
    _, surfaces = read_series(tmp_path / "surface.pvd")
    surface = surfaces[-1]
    assert surface.n_cells > 100
    # the surface wraps the particles: its bounds lie within a few radii of theirs
    assert np.all(np.abs(np.array(surface.bounds) - np.array(last.bounds)) < 0.15)


def test_noise_smoke_resumes_bit_identically_from_disk(tmp_path):
    from pipeline.io.series import read_series
    from scenes.noise_smoke import SCENE

    def run(directory, frames, resume=False):
        flow = SCENE.build(rate=500.0, surface=False, seed=4)
        flow.source.set_frames(10.0, frames=frames)
        flow.run(directory, progress=False, resume=resume)

    run(tmp_path / "full", 6)
    run(tmp_path / "split", 3)
    run(tmp_path / "split", 6, resume=True)  # continues from the checkpoint in frame 2
    _, full = read_series(tmp_path / "full" / "particles.pvd")
    _, split = read_series(tmp_path / "split" / "particles.pvd")
    assert len(full) == len(split) == 6
    for a, b in zip(full, split, strict=False):
        assert np.array_equal(a.points, b.points)
        assert np.array_equal(a.point_data["id"], b.point_data["id"])
        assert np.array_equal(a.point_data["velocity"], b.point_data["velocity"])
