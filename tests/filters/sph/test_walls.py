"""The boundary holds without the container safety net; boundary particles move and report the
fluid's force on them (filters.sph.boundary, filters.sph.boundary_set, the DFSPH walls)."""

import warnings

import numpy as np
import pytest

from filters.sph import BoundaryParticles, ContainerCorrectionWarning, SPHLiquid
from filters.sph.boundary import (
    boundary_volumes,
    box_boundary,
    concatenate_boundaries,
    lattice_volume,
    mesh_boundary,
)
from filters.sph.scenarios import dam_break_liquid
from filters.sph.wall_profile import WallProfile, equivalent_distance, half_space_fraction

G = 9.81


def _scene_liquid(**kw):
    """The dam_break scene's liquid (a = 0.1 m column, 0.4 m tank, DFSPH, its viscosity)."""
    options = dict(column_width=0.1, column_height=0.2, tank_length=0.4, depth=0.1,
                   tank_height=0.3, solver="dfsph", kinematic_viscosity=4e-4, max_dt=0.005)
    options.update(kw)
    return dam_break_liquid(**options)


def test_dam_break_at_a_coarse_spacing_needs_no_container_correction():
    sim = _scene_liquid(spacing=0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ContainerCorrectionWarning)
        sim.advance_to(1.5)  # the scene's whole duration: collapse, impact, plunging wave
    assert sim.contained == 0
    assert sim.frame().field_data["container_corrections"].tolist() == [0]
    x = sim.state.positions
    assert (x >= 0).all() and (x <= [0.4, 0.1, 0.3]).all()


def test_dam_break_at_the_scenes_spacing_needs_no_container_correction():
    """The scene's 4 mm through the impact on the far wall and the run-up (a slab 5 particles
    deep keeps the test fast; the thin front, where particles leaked, is the same)."""
    sim = _scene_liquid(spacing=0.004, depth=0.02)
    sim.advance_to(0.4)
    assert sim.state.positions[:, 0].max() > 0.39  # the front reached the far wall
    assert sim.contained == 0


@pytest.mark.parametrize("case", ["lone particle", "sheet"])
def test_what_lacks_neighbours_stays_off_the_floor(case):
    """With pressure clamped at zero, a particle short of fluid neighbours feels no pressure
    until it overlaps the wall; the wall constraints keep it off (the safety net off here)."""
    s = 0.01
    walls = box_boundary((0, 0, 0), (0.1, 0.1, 0.1), s)
    if case == "lone particle":
        x = np.array([[0.05, 0.05, 0.05]])
    else:
        g = (np.arange(10) + 0.5) * s
        x = np.stack(np.meshgrid(g, g, [0.02], indexing="ij"), -1).reshape(-1, 3)
    v = np.zeros_like(x)
    v[:, 2] = -2.0
    v[:, 0] = 0.5
    sim = SPHLiquid(x, v, spacing=s, boundary=walls, solver="dfsph")
    lowest = np.inf
    while sim.state.time < 0.3:
        sim.step(sim.max_step())
        lowest = min(lowest, sim.state.positions[:, 2].min())
    # the constraints allow 0.1 spacings to the boundary as a whole, 0.3 to one wall
    assert lowest > 0.05 * s
    assert sim.state.positions[:, 2].max() < 0.05  # and nothing bounced off


def test_safety_net_counts_warns_and_reports():
    """Without boundary particles the container is all that keeps a particle in the box."""
    x = np.array([[0.05, 0.05, 0.05]])
    v = np.array([[3.0, 0.0, 0.0]])
    sim = SPHLiquid(x, v, spacing=0.01, solver="dfsph", gravity=(0, 0, 0),
                    container=((0, 0, 0), (0.1, 0.1, 0.1)))
    with pytest.warns(ContainerCorrectionWarning, match="container safety net"):
        sim.advance_to(0.05)
    assert sim.contained >= 1
    assert sim.state.positions[0, 0] <= 0.1
    assert sim.frame().field_data["container_corrections"].tolist() == [sim.contained]


def _momentum_balance(sim, steps):
    """(force of the fluid on all boundary particles in the last step, minus the fluid's
    momentum change rate plus its weight): equal by Newton's third law."""
    m = sim.model.mass
    n = sim.state.n_points
    for _ in range(steps):
        ids = sim.state.extra["id"]
        before = np.empty((n, 3))
        before[ids] = sim.state.velocities
        dt = sim.max_step()
        sim.step(dt)
        after = np.empty((n, 3))
        after[sim.state.extra["id"]] = sim.state.velocities
    expected = -(m * (after - before).sum(axis=0) / dt - m * n * np.array([0.0, 0.0, -G]))
    return sim.boundary_forces().sum(axis=0), expected, m * n * G


def test_pressure_forces_on_the_boundary_balance_the_fluids_momentum():
    """Newton's third law, exactly: fluid-fluid pressure forces cancel, so in a step the force
    on all boundary particles (mirrored and wall pressures) is what changed the fluid's
    momentum besides gravity."""
    sim = _scene_liquid(spacing=0.01, kinematic_viscosity=None, viscosity=0.0,
                        boundary_viscosity=0.0)
    force, expected, weight = _momentum_balance(sim, 60)  # into the collapse
    assert np.abs(expected).max() > 0.1 * weight
    np.testing.assert_allclose(force, expected, atol=1e-9 * weight)


def test_boundary_forces_are_the_last_steps_after_a_density_evaluation():
    """A frame's density pass re-sorts the particles and overwrites the work arrays the
    record of the last step borrows: the forces asked for afterwards are still that step's."""
    sim = _scene_liquid(spacing=0.01)
    for _ in range(40):
        sim.step(sim.max_step())
    forces = sim.boundary_forces()
    assert np.abs(forces).max() > 0.0
    sim.state.positions[:] += 0.2 * sim.model.spacing  # the pass then sees another state
    sim.evaluate_density()
    np.testing.assert_array_equal(sim.boundary_forces(), forces)
    sim.step(sim.max_step())
    assert not np.array_equal(sim.boundary_forces(), forces)


def test_boundary_forces_are_zero_after_a_step_that_failed_part_way():
    """The docstring's promise: no force from a step that did not finish is reported as the
    last step's."""
    from filters.simulation import SimulationUnstableError

    sim = _scene_liquid(spacing=0.01)
    for _ in range(20):
        sim.step(sim.max_step())
    assert np.abs(sim.boundary_forces()).max() > 0.0
    sim.state.positions[0] = np.nan
    with pytest.raises(SimulationUnstableError):
        sim.step(sim.max_step())
    assert not sim.boundary_forces().any()


def test_viscous_forces_on_the_boundary_balance_the_fluids_momentum():
    """With the scene's viscosity the balance holds to the implicit viscosity solve's
    tolerance (its residual is not momentum-free)."""
    force, expected, weight = _momentum_balance(_scene_liquid(spacing=0.01), 60)
    np.testing.assert_allclose(force, expected, atol=0.01 * weight)


def test_floor_carries_the_weight_of_a_resting_pool():
    from filters.sph.scenarios import drop_liquid

    sim = drop_liquid(tank_length=0.12, tank_width=0.12, tank_height=1.0, pool_depth=0.05,
                      drop_radius=0.012, drop_height=0.95, spacing=0.012, solver="dfsph")
    pool = sim.state.positions[:, 2] < 0.1
    weight = sim.model.mass * pool.sum() * G
    sim.advance_to(0.05)
    total = np.zeros(3)
    for _ in range(10):
        sim.step(sim.max_step())
        total += sim.boundary_forces().sum(axis=0) / 10
    assert total[2] == pytest.approx(-weight, rel=0.03)  # the tank is pushed down by the water
    assert np.abs(total[:2]).max() < 0.01 * weight  # and not sideways


def test_a_moving_plate_pushes_the_liquid_and_feels_it():
    """A plate (two layers of boundary particles, a support radius thick) moved into a resting
    slab of liquid at 0.5 m/s: no particle passes it, the liquid ahead of it moves with it, and
    the plate feels a force against its motion."""
    s = 0.01
    tank = box_boundary((0, 0, 0), (0.3, 0.1, 0.2), s)
    gy = (np.arange(10) + 0.5) * s
    gz = (np.arange(20) + 0.5) * s
    plate = np.stack(np.meshgrid([-0.5 * s, -1.5 * s], gy, gz, indexing="ij"), -1).reshape(-1, 3)
    plate_b = BoundaryParticles(plate, np.full(plate.shape[0], lattice_volume(s, 2 * s)),
                                np.tile([1.0, 0.0, 0.0], (plate.shape[0], 1)))
    walls = concatenate_boundaries(tank, plate_b)
    lattice = [np.arange(lo + 0.5 * s, hi, s) for lo, hi in ((0.02, 0.3), (0, 0.1), (0, 0.1))]
    x = np.stack(np.meshgrid(*lattice, indexing="ij"), -1).reshape(-1, 3)
    sim = SPHLiquid(x, spacing=s, boundary=walls, solver="dfsph", gravity=(0, 0, 0),
                    container=((0, 0, 0), (0.3, 0.1, 0.2)))
    mine = np.arange(tank.n_points, walls.n_points)
    speed = 0.5
    pushes = []
    while sim.state.time < 0.1:
        dt = sim.max_step()
        sim.move_boundary(plate + [speed * sim.state.time, 0.0, 0.0],
                          np.tile([speed, 0.0, 0.0], (plate.shape[0], 1)), indices=mine)
        sim.step(dt)
        assert sim.state.positions[:, 0].min() > speed * sim.state.time  # none passed it
        pushes.append(sim.boundary_forces(mine)[:, 0].sum())
    assert sim.contained == 0
    assert np.mean(pushes[-5:]) < 0.0  # the liquid pushes back against the plate
    x = sim.state.positions
    near = x[:, 0] < speed * sim.state.time + 2 * s
    assert np.mean(sim.state.velocities[near, 0]) > 0.5 * speed


def test_free_slip_walls_let_the_liquid_slide():
    """A block of liquid sliding along the floor without gravity: a no-slip floor (friction 1)
    brakes it through the boundary viscosity, a free-slip floor (friction 0) does not."""
    s = 0.01
    lattice = [np.arange(lo + 0.5 * s, hi, s) for lo, hi in ((0.05, 0.15), (0, 0.1), (0, 0.05))]
    x = np.stack(np.meshgrid(*lattice, indexing="ij"), -1).reshape(-1, 3)
    v = np.tile([0.3, 0.0, 0.0], (x.shape[0], 1))
    lost = {}
    for slip in ((), ("z-",)):
        walls = box_boundary((0, 0, 0), (0.3, 0.1, 0.1), s, free_slip=("y",) + slip)
        sim = SPHLiquid(x, v, spacing=s, boundary=walls, solver="dfsph", gravity=(0, 0, 0),
                        kinematic_viscosity=4e-4)
        sim.advance_to(0.05)
        lost[slip] = 0.3 - sim.state.velocities[:, 0].mean()
    assert lost[()] > 0.005  # m/s
    assert abs(lost[("z-",)]) < 0.01 * lost[()]


def test_box_boundary_normals_and_free_slip_faces():
    b = box_boundary((0, 0, 0), (0.1, 0.05, 0.1), 0.01, free_slip=("x+", "y"))
    n = b.normals
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    floor = (b.points[:, 2] < 0) & (b.points[:, 0] > 0) & (b.points[:, 0] < 0.1) & (
        b.points[:, 1] > 0) & (b.points[:, 1] < 0.05)
    assert (n[floor] == [0, 0, 1]).all()
    far = (b.points[:, 0] > 0.1) & (b.points[:, 2] > 0) & (b.points[:, 2] < 0.1) & (
        b.points[:, 1] > 0) & (b.points[:, 1] < 0.05)
    assert (n[far] == [-1, 0, 0]).all() and (b.friction[far] == 0).all()
    assert (b.friction[floor] == 1).all()
    with pytest.raises(ValueError, match="free_slip faces must be among"):
        box_boundary((0, 0, 0), (1, 1, 1), 0.1, free_slip=("top",))


def test_mesh_boundary_normals_point_out_of_a_closed_box():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1],
                  [0, 1, 1]], dtype=float) * 0.1
    f = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4], [1, 2, 6],
                  [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    b = mesh_boundary(v, f, 0.01)
    assert np.allclose(np.linalg.norm(b.normals, axis=1), 1.0)
    outward = ((b.points - 0.05) * b.normals).sum(axis=1)
    assert (outward > 0).all()


def test_boundary_particles_and_moves_refuse_bad_input():
    with pytest.raises(ValueError, match="friction"):
        BoundaryParticles(np.zeros((2, 3)), np.ones(2), friction=[-1.0, 1.0])
    with pytest.raises(ValueError, match="normals must be unit vectors"):
        BoundaryParticles(np.zeros((1, 3)), np.ones(1), normals=[[2.0, 0, 0]])
    walls = box_boundary((0, 0, 0), (0.1, 0.1, 0.1), 0.02)
    sim = SPHLiquid([[0.05, 0.05, 0.05]], spacing=0.02, boundary=walls, solver="dfsph")
    with pytest.raises(ValueError, match=r"indices must be in \[0, "):
        sim.move_boundary(np.zeros((1, 3)), indices=[walls.n_points])
    with pytest.raises(ValueError, match="volumes must be > 0"):
        sim.move_boundary(volumes=np.zeros(walls.n_points))
    before = sim.boundary.points.copy()
    with pytest.raises(ValueError, match="points must be a finite array"):
        sim.move_boundary(np.full((walls.n_points, 3), np.nan))
    np.testing.assert_array_equal(sim.boundary.points, before)  # nothing changed
    wcsph = SPHLiquid([[0.05, 0.05, 0.05]], spacing=0.02, boundary=walls)
    with pytest.raises(ValueError, match="needs solver='dfsph'"):
        wcsph.move_boundary(before)


def test_wall_profile_reads_the_boundary_as_a_distance():
    h = 0.02
    assert half_space_fraction(0.0, h) == pytest.approx(0.5, abs=1e-6)
    assert half_space_fraction(h, h) == pytest.approx(0.0, abs=1e-9)
    assert half_space_fraction(-h, h) == pytest.approx(1.0, abs=1e-6)
    p = WallProfile(h)
    for d in (-0.5 * h, 0.0, 0.2 * h, 0.6 * h):
        phi = half_space_fraction(d, h)
        got, slope = equivalent_distance(phi, p.inverse_distance, p.inverse_slope)
        assert got == pytest.approx(d, abs=1e-4 * h)
        numeric = (half_space_fraction(d - 1e-4 * h, h) - half_space_fraction(d + 1e-4 * h, h))
        assert slope == pytest.approx(numeric / (2e-4 * h), rel=5e-3)
    # the lattice walls of box_boundary fill the kernel as a flat half-space does: on the
    # wall plane exactly, half a spacing away within the midpoint rule's error
    from filters.kernels import kernel_value

    s = h / 2
    walls = box_boundary((-0.1, -0.1, 0), (0.1, 0.1, 0.1), s)

    def phi_at(z):  # sum V_b W over the floor's particles, off the lattice sideways
        r = np.linalg.norm(walls.points - [0.003, 0.002, z], axis=1)
        return float((kernel_value("cubic", r, h) * walls.volumes)[r < h].sum())

    assert phi_at(0.0) == pytest.approx(0.5, abs=0.005)
    d, _ = equivalent_distance(phi_at(0.5 * s), p.inverse_distance, p.inverse_slope)
    assert 0.5 * s < d < 0.65 * s


def _sheet(s, half=0.1, z=0.0):
    """One layer of samples on a square lattice of step ``s`` in the plane ``z``, with the
    volumes of a sampled surface (boundary_volumes): a cloth, as the liquid would see it."""
    g = np.arange(-half, half + 0.5 * s, s)
    x, y = np.meshgrid(g, g, indexing="ij")
    points = np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], axis=1)
    normals = np.zeros_like(points)
    normals[:, 2] = 1.0
    return BoundaryParticles(points, boundary_volumes(points, s), normals)


def test_one_layer_of_samples_fills_a_fifth_of_the_kernel():
    """What the DFSPH walls' docstring says: a flat sheet sampled in one layer fills at most
    0.22 of a particle's kernel on it (a box wall: 1/2 on its plane), as much as a thick wall
    half a spacing away."""
    from filters.kernels import kernel_value

    s, h = 0.01, 0.02
    sheet = _sheet(s)

    def phi(z):
        r = np.linalg.norm(sheet.points - [0.003, 0.002, z], axis=1)
        return float((kernel_value("cubic", r, h) * sheet.volumes)[r < h].sum())

    assert 0.18 < phi(0.0) < 0.22
    assert phi(0.0) == max(phi(z) for z in np.linspace(-0.01, 0.01, 9))
    assert phi(0.5 * s) == pytest.approx(half_space_fraction(0.58 * s, h), abs=0.01)


def _pool_on(floor, solver, s=0.01, top=0.1, until=0.4):
    """A six-layer pool resting on ``floor`` (boundary particles whose upper surface is the
    plane ``z = top``) in a 0.2 x 0.2 m tank; returns the most particles below ``top`` at any
    step."""
    tank = (0.2, 0.2, 0.3)
    axes = [(np.arange(20) + 0.5) * s] * 2 + [top + (np.arange(6) + 0.5) * s]
    x = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    options = {"kinematic_viscosity": 1e-4} if solver == "dfsph" else {}
    sim = SPHLiquid(x, spacing=s, boundary=concatenate_boundaries(
        box_boundary((0, 0, 0), tank, s), floor), solver=solver,
        container=((0, 0, 0), tank), **options)
    worst = 0
    while sim.state.time < until:
        sim.step(sim.max_step())
        worst = max(worst, int((sim.state.positions[:, 2] < top).sum()))
    return worst


@pytest.mark.parametrize("solver, top", [("dfsph", 0.1), ("wcsph", 0.1), ("dfsph", 0.1045)])
def test_a_pool_rests_on_a_closed_mesh(solver, top):
    """mesh_boundary fills a closed mesh's outer layers, which hold a liquid as a tank's walls
    do: no particle of a pool resting on a block (a closed box mesh filling the tank's lower
    part) ever below its top face (measured: none; with the surface sampled in one layer, as
    mesh_boundary did before, all 2,400 within 0.13 s, both solvers; with a top face 10.45
    spacings up and the layers on a lattice of step ``spacing``, 400 particles down to 0.36
    spacings below it)."""
    from filters.rigid.meshes import box_mesh

    block = mesh_boundary(*box_mesh((0.2, 0.2, top), (0.1, 0.1, top / 2)), 0.01)
    assert _pool_on(block, solver, top=top) == 0


def test_liquid_falling_on_a_mesh_ball_never_gets_inside_it():
    """A pool dropped onto a ball (an icosphere, 5 spacings in radius, sampled by
    mesh_boundary) splashes around it and never has a particle inside it (measured: none over
    0.5 s; with the ball's surface sampled in one layer, 264 of 2,400 at once)."""
    from filters.coupling.parts import count_inside
    from filters.elastic.topology import icosphere

    s, tank = 0.01, (0.2, 0.2, 0.3)
    v, f = icosphere(0.05, 3, center=(0.1, 0.1, 0.07))
    axes = [(np.arange(20) + 0.5) * s] * 2 + [0.14 + (np.arange(6) + 0.5) * s]
    x = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    sim = SPHLiquid(x, spacing=s, boundary=concatenate_boundaries(
        box_boundary((0, 0, 0), tank, s), mesh_boundary(v, f, s)), solver="dfsph",
        kinematic_viscosity=1e-4, container=((0, 0, 0), tank))
    lowest = np.inf
    while sim.state.time < 0.5:
        sim.step(sim.max_step())
        assert not count_inside(sim.state.positions, v, f).any(), sim.state.time
        lowest = min(lowest, sim.state.positions[:, 2].min())
    assert lowest < 0.02  # the water went past the ball to the floor


def test_one_layer_of_samples_does_not_hold_a_pool():
    """What the DFSPH walls' and mesh_boundary's docstrings say: a surface sampled in one layer
    fills too little of the kernel for the pressure to engage (a clamped pressure needs rest
    density), and a pool resting on it falls through (measured: all 2,400 particles)."""
    sheet = _sheet(0.01, half=0.1, z=0.1)
    sheet = BoundaryParticles(sheet.points + [0.1, 0.1, 0.0], sheet.volumes, sheet.normals)
    assert _pool_on(sheet, "dfsph", until=0.2) > 2000


def test_a_moved_boundary_is_sorted_as_a_new_one():
    """BoundarySet.move keeps the unmoved particles' reach mask between sorts (a body moves,
    the tank does not): after moves of a part, a whole-set move, and one beyond the old grid,
    the sorted arrays and the mask are those of a set built afresh from the same particles."""
    from filters.sph.boundary_set import BoundarySet
    from filters.sph.neighbourhood import boundary_reach_mask

    rng = np.random.default_rng(2)
    walls = box_boundary((0, 0, 0), (0.2, 0.1, 0.1), 0.01)
    body = mesh_boundary(*_cube(0.04, (0.1, 0.05, 0.05)), 0.01)
    both = concatenate_boundaries(walls, body)
    live = BoundarySet(both, 1000.0, 0.01)
    idx = walls.n_points + np.arange(body.n_points)
    shifts = [(0.003, -0.002, 0.001), (0.01, 0.0, -0.004), (0.0, 0.0, 0.2)]  # last: out of the box
    for shift in shifts:
        pts = live.points[idx] + shift
        vel = rng.standard_normal((idx.size, 3))
        live.move(points=pts, velocities=vel, indices=idx)
        fresh = BoundarySet(BoundaryParticles(live.points, live.volumes, normals=live.normals,
                                              velocities=live.velocities,
                                              friction=live.friction), 1000.0, 0.01)
        for name in ("order", "sorted_points", "sorted_velocities", "sorted_normals",
                     "sorted_volumes", "sorted_mass", "sorted_friction_volumes", "origin",
                     "dims", "start", "mask"):
            np.testing.assert_array_equal(getattr(live, name), getattr(fresh, name), name)
        assert np.array_equal(live.mask, boundary_reach_mask(live.sorted_points, live.origin,
                                                             0.01, live.dims))
    live.move(points=live.points + 0.001)  # every particle
    assert np.array_equal(live.mask, boundary_reach_mask(live.sorted_points, live.origin, 0.01,
                                                         live.dims))


def _cube(size, center):
    v = (np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1],
                   [0, 1, 1]], dtype=float) - 0.5) * size + center
    f = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4], [1, 2, 6],
                  [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    return v, f


def test_walls_on_opposite_sides_of_a_particle_are_two_walls_and_not_enforced():
    """A particle in a film between the floor (below, normal +z) and a body's underside (above,
    normal -z): both normals face it, so they are two walls (either orientation otherwise: a
    sample the particle is beside or behind matches a wall of the opposite normal), and the
    two opposed single-wall constraints are dropped (filters.sph.dfsph_kernels.wall_start)."""
    from filters.sph.dfsph_kernels import NO_WALL, wall_start
    from filters.sph.neighbourhood import wall_key, wall_of
    from filters.sph.wall_profile import WallProfile

    cn = np.zeros((1, 4, 3))
    cn[0, 1] = wall_key(0.0, 0.0, 1.0, 0.0, 0.0, 0.01)  # the floor's sample below
    below = wall_key(0.0, 0.0, -1.0, 0.0, 0.0, -0.01)  # the body's sample above, facing it
    assert wall_of(0, *below, 2, cn) == 2  # a wall of its own
    beside = wall_key(0.0, 0.0, -1.0, 0.01, 0.0, 0.001)  # a body sample the particle is beside
    assert wall_of(0, *beside, 2, cn) == 1  # either orientation, as before
    assert wall_of(0, *wall_key(0.0, 0.0, 1.0, 0.003, 0.0, 0.01), 2, cn) == 1  # the floor again

    h = 0.02
    p = WallProfile(h)
    g = 30.0  # 1/m, a flat wall's slope near it
    ncl = np.array([3])
    cphi = np.array([[0.6, 0.3, 0.3, 0.0]])
    cgb = np.zeros((1, 4, 3))
    cgb[0, 0] = (0.0, 0.0, 0.5 * g)  # the whole boundary: the two nearly cancel
    cgb[0, 1] = (0.0, 0.0, -g)  # grad phi points into the floor ...
    cgb[0, 2] = (0.0, 0.0, 1.5 * g)  # ... and into the body
    cvb = np.array([[0.0, 0.0, -40.0, 0.0]])  # the body comes down
    wsrc = np.empty((1, 4))
    pw = np.empty((1, 4))
    args = (np.zeros((1, 3)), ncl, cphi, cgb, cvb, 1e-3, 1.0, np.array([0.1, 0.3]) * 0.01, 0.01,
            p.inverse_distance, p.inverse_slope, wsrc, pw)
    wall_start(*args)
    assert wsrc[0, 1] == NO_WALL and wsrc[0, 2] == NO_WALL
    cgb[0, 2] = (0.0, g, 0.0)  # walls at right angles (a corner): both kept
    wall_start(*args)
    assert wsrc[0, 1] < NO_WALL and wsrc[0, 2] < NO_WALL
