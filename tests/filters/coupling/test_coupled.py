"""Rigid and elastic bodies two-way coupled with the DFSPH liquid (filters.coupling): the
hydrostatic force on a held box, Archimedes' draft, a sinking box, momentum in a closed tank
without gravity, no liquid inside a body, bitwise resume, bad input."""

import numpy as np
import pytest

from filters.coupling import Coupled, coupled_boundary, solid_layers
from filters.coupling.parts import count_inside, world_meshes
from filters.elastic.contact import Colliders
from filters.geometry import Box
from filters.rigid import RigidBodies, RigidBody
from filters.rigid.meshes import box_mesh
from filters.sph import SPHLiquid
from filters.sph.boundary import box_boundary, lattice_volume
from filters.sph.settle import hydrostatic_pressure

RHO, G = 1000.0, 9.81


def _lattice(lo, hi, s):
    axes = [lo[k] + (np.arange(int(round((hi[k] - lo[k]) / s))) + 0.5) * s for k in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def _pool(bodies, *, s=0.01, tank=(0.12, 0.12, 0.2), depth=0.1, gravity=(0.0, 0.0, -G),
          water=None, nu=1e-4, **options):
    """A pool in a closed tank with the rigid bodies ``bodies`` (a RigidBodies) in it."""
    x = _lattice((0, 0, 0), (tank[0], tank[1], depth), s) if water is None else water
    for v, f in world_meshes(bodies):
        x = x[~count_inside(x, v, f)]
    walls = box_boundary((0, 0, 0), tank, s)
    liquid = SPHLiquid(x, spacing=s, boundary=coupled_boundary(walls, bodies, s),
                       solver="dfsph", gravity=gravity, kinematic_viscosity=nu, max_dt=0.005,
                       initial_pressure=hydrostatic_pressure(x, s, gravity),
                       container=((0, 0, 0), tank), **options)
    return Coupled(liquid, bodies)


def _box(size, center, **options):
    v, f = box_mesh(size, center)
    return RigidBody(v, f, **options)


def test_solid_layers_of_a_box_are_the_tanks_wall_layers_inside_out():
    s = 0.01
    v, f = box_mesh(0.06, (0.03, 0.03, 0.03))
    layer = solid_layers(v, f, s)
    # 6^3 cells, the inner 2^3 are deeper than two layers
    assert layer.n_points == 6 ** 3 - 2 ** 3
    assert np.allclose(layer.volumes, lattice_volume(s, 2 * s))
    # normals: outward, the axis of the nearest face
    assert np.allclose(np.abs(layer.normals).sum(axis=1), 1.0)
    c = layer.points - 0.03
    assert (np.einsum("ij,ij->i", layer.normals, c) > 0).all()


def test_solid_layers_of_any_box_start_half_a_step_inside_every_face():
    # a box of 4.4 x 5.7 x 3.2 spacings: the lattice's steps are fitted to whole cells (4, 6, 3)
    s = 0.01
    size = np.array([0.044, 0.057, 0.032])
    v, f = box_mesh(size, (0.1, 0.2, 0.3))
    layer = solid_layers(v, f, s)
    step = size / np.round(size / s)
    lo, hi = layer.points.min(axis=0), layer.points.max(axis=0)
    np.testing.assert_allclose(lo - (v.min(axis=0)), 0.5 * step, rtol=1e-9)
    np.testing.assert_allclose(v.max(axis=0) - hi, 0.5 * step, rtol=1e-9)
    # the volume gives a lattice of those steps rest density: sum_j V W(x_j) = 1
    from filters.kernels import kernel_value
    g = [np.arange(-4, 5) * d for d in step]
    r = np.linalg.norm(np.stack(np.meshgrid(*g, indexing="ij"), -1).reshape(-1, 3), axis=1)
    assert layer.volumes[0] * kernel_value("cubic", r, 2 * s).sum() == pytest.approx(1.0,
                                                                                        rel=1e-12)


@pytest.mark.parametrize("size", [0.044, 0.046])
def test_a_box_off_the_liquids_lattice_is_held_like_one_on_it(size):
    # a held box whose sides are not whole spacings: before its layers were fitted to it, the
    # 4.4 spacing box let 1,621 particles in within 0.5 s (the safety net put them back) and
    # was pushed sideways with 0.146 rho g V in a symmetric pool; the 4.6 one got 1.19-1.28
    # rho g V up; measured after: 26 / 93 particles, 0.005 / 0.014 sideways, 0.94 / 0.92 up
    f, corrections = _held_box_force(size)
    assert corrections < 200, corrections
    assert np.abs(f[:2]).max() < 0.03, f
    assert abs(f[2] - 1.0) < 0.12, f


def _held_box_force(size, s=0.01):
    """A cube of side ``size`` (m) held under water in the middle of a resting pool: the mean
    force and torque of the liquid on it over 0.2-0.5 s over ``rho g V`` (6,), and how many
    particles the body's safety net put back."""
    bodies = RigidBodies([_box(size, (0.06, 0.06, 0.05), fixed=True)])
    sim = _pool(bodies, s=s)
    forces = []

    def record(sim):
        _no_liquid_inside(sim)
        if sim.state.time > 0.2:
            forces.append(sim.last_body_forces[0][0].copy())

    _run(sim, 0.5, record)
    return np.mean(forces, axis=0) / (RHO * G * size ** 3), sim.corrections


@pytest.fixture(scope="module")
def held_box():
    # a box held under water: the mean force of the liquid on it over 0.3 s of a resting pool
    return _held_box_force(0.04)[0]


def test_a_held_box_gets_about_the_hydrostatic_force(held_box):
    # measured: 0.91 rho g V (2026-11-28; 0.81 and 1.17 for boxes of 6 and 8 cm in the same 12
    # cm pool, which is not at rest: started on the lattice, its top moves by half a spacing in
    # a tenth of a second, and a box two thirds of the tank wide is pushed by that motion;
    # earlier 0.91-0.92 for 4-8 spacings at 1 and 2 cm).  With the pool settled first
    # (filters.sph.settle, the box held in it): 0.88 and 0.79 for the 4 and 6 cm boxes, steady
    # over 0.5 s; the 6 cm box leaves two spacings of water under and over it.  The boundary
    # term of the pressure solves carries each fluid
    # particle's own pressure once (Akinci et al. 2012; SPlisHSPlasH's factor 1): next to boundary
    # layers that complete a particle's neighbourhood that pressure cancels, the layer next to every
    # wall and face is held by its fluid neighbours alone and rests at 0.27-0.31 spacings from it
    # instead of the lattice's 0.5 (measured), and a body gets less than the hydrostatic force.
    # Tried and measured: the boundary taking the particle's pressure extrapolated with gravity
    # (Adami et al. 2012) from the fluid side gives 1.00 rho g V and the lattice gap in a resting
    # pool, but with the own pressure twice in the solve the Jacobi iteration stalls (a converging
    # flow in a closed box: 0.042 per step against 0.01) and a resting pool keeps 0.2-0.3 m/s of
    # jitter; with it lagged by a step the pool does not settle (the own pressure twice is no longer
    # the transpose of the density solve's boundary term, so the pressure does work: a resting
    # pool's jitter grew to 0.5 m/s with it, even at 1 ms steps, measured 2026-11-28).  The
    # extrapolation has to be per boundary particle, from its fluid neighbours (Band et al. 2018),
    # inside the solve.  Also measured: the wall constraints' single-wall minimum at the lattice's
    # distance (0.578 instead of 0.3 spacings, DFSPH_WALL_GAP_SINGLE) holds the layer half a spacing
    # off the box's faces and lets a lattice pool start nearly at rest (0.06 m/s instead of 0.27),
    # but the force is 0.95 / 0.93 / 1.04 rho g V (4 / 6 / 8 cm), the floating box's draft 0.905 of
    # Archimedes' (0.897), and the 10k dam break takes 7 % more steps.
    assert abs(held_box[2] - 1.0) < 0.12, held_box
    assert np.abs(held_box[:2]).max() < 0.03  # no sideways push in a symmetric pool


@pytest.mark.xfail(strict=True, reason="measured 0.91 rho g V, see the test above")
def test_a_held_box_gets_the_hydrostatic_force_within_3_percent(held_box):
    assert abs(held_box[2] - 1.0) < 0.03, held_box

def _run(sim, until, every=None):
    """Step to ``until`` (s); call ``every(sim)`` after each step."""
    while sim.state.time < until - 1e-12:
        sim.step(min(sim.max_step(), until - sim.state.time))
        if every is not None:
            every(sim)


def _no_liquid_inside(sim):
    # the liquid's centres never inside a body after a step: held off the faces by the wall
    # constraints, and put back by the bodies' safety net where a convex corner lets one in
    assert sim.penetration() == 0.0, f"liquid inside a body at t = {sim.state.time:.4f} s"

def _energy(sim):
    """Kinetic plus gravitational energy (J) of the liquid and the rigid bodies."""
    liquid = sim.liquid
    v = liquid.state.velocities
    e = liquid.model.mass * (0.5 * (v * v).sum() - liquid.state.positions[:, 2].sum()
                             * liquid.gravity[2])
    return e + sum(p.sim.energy() for p in sim.parts)


def _water_level(x, s, away_from, half_width):
    """Mean top of the water columns farther than ``half_width`` + 2 s from ``away_from``
    (x, y): the highest particle of each column plus half a spacing."""
    far = np.max(np.abs(x[:, :2] - away_from[:2]), axis=1) > half_width + 2 * s
    key = np.floor(x[far, :2] / s).astype(np.int64)
    key = key[:, 0] * 1_000_000 + key[:, 1]
    z = x[far, 2]
    order = np.lexsort((z, key))
    last = np.r_[key[order][1:] != key[order][:-1], True]
    return float(z[order][last].mean()) + 0.5 * s


@pytest.fixture(scope="module")
def floating_box():
    # a flat box (stable upright) of half the water's density, released at the surface
    s, size, height = 0.01, 0.08, 0.04
    tank = (0.14, 0.14, 0.14)
    bodies = RigidBodies([_box((size, size, height), (0.07, 0.07, 0.06 + height / 2),
                               density=500.0)],
                         colliders=Colliders().add(~Box((0, 0, 0), tank)))
    sim = _pool(bodies, s=s, tank=tank, depth=0.06)
    vz = []

    def record(sim):
        _no_liquid_inside(sim)
        vz.append(bodies.state.velocities[0, 2])

    _run(sim, 1.2, record)
    x = sim.liquid.state.positions
    c = bodies.state.positions[0]
    level = _water_level(x, s, c, size / 2 - s)
    vz = np.array(vz[len(vz) // 2:])
    return {"draft": level - (c[2] - height / 2), "archimedes": 0.5 * height,
            "speed": float(np.linalg.norm(bodies.state.velocities[0])),
            "tilt": float(abs(bodies.state.extra["orientations"][0, 0])),
            "jitter": float(np.abs(vz[1:-1] - 0.5 * (vz[:-2] + vz[2:])).max())}


def test_a_floating_box_comes_to_rest_near_its_archimedes_draft(floating_box):
    # measured: 0.88-0.90 of Archimedes' draft at 4 spacings of draft at t = 1.2 s, still bobbing
    # by +-0.4 mm (the issue asks for 5 %, not met: see the held box); upright; nearly at rest
    # (measured 0.004 m/s)
    assert abs(floating_box["draft"] / floating_box["archimedes"] - 1.0) < 0.15, floating_box
    assert floating_box["speed"] < 0.05
    assert floating_box["tilt"] > 0.999


def test_a_floating_box_moves_smoothly_from_step_to_step(floating_box):
    # the bodies move inside the density solve (filters.coupling.strong): the liquid's step
    # expects the motion the body makes with the force it gets.  Measured over the last 0.6 s:
    # the vertical velocity departs from the mean of its neighbours in time by at most
    # 0.0009 m/s; with the bodies moved after the liquid's step (the coupling before) it
    # alternated from step to step by up to 0.064 m/s (0.025 on average)
    assert floating_box["jitter"] < 0.005, floating_box


def test_the_density_solve_moves_a_body_with_the_force_it_then_gets():
    # two turning boxes in a viscous pool: after each step, the force and torque the density
    # solve's last sweep moved each body with (its pressures, wall pressures and the divergence
    # solve's) are those the body gets, which come from the link's own pairs (plus the
    # viscous force summed there); both equal the liquid's boundary forces on the bodies'
    # particles (an independent pass over the pairs) summed about the centres of mass
    from filters.coupling import parts
    from filters.rigid.dynamics import point_force_sums
    tank = (0.12, 0.12, 0.2)
    bodies = RigidBodies([_box(0.04, (0.05, 0.06, 0.07), density=700.0),
                          _box(0.04, (0.03, 0.03, 0.02), density=1200.0)],
                         colliders=Colliders().add(~Box((0, 0, 0), tank)),
                         angular_velocities=[[0.0, 3.0, 1.0], [1.0, 0.0, 0.0]])
    sim = _pool(bodies, tank=tank, nu=1e-3)
    solver = sim.liquid._stepper.solver
    checked = []

    def compare(part, wrenches):  # before the bodies step: where they were in the solve
        forces = sim.liquid.boundary_forces(sim._indices[0])
        direct = point_force_sums(np.ascontiguousarray(sim._where[0]), forces, part.owner,
                                  part.sim.state.positions)
        pressure = sim._link.wrench(solver.pi, solver.wall_pressure)
        checked.append((np.abs(wrenches - direct).max() / np.abs(direct).max(),
                        np.abs(sim._link.viscous).max() / np.abs(direct).max(),
                        np.abs(pressure[:, 2]).min()))
        return push(part, wrenches)

    push = parts.RigidPart.push_wrenches
    try:
        parts.RigidPart.push_wrenches = compare
        for _ in range(10):
            sim.step(sim.max_step())
    finally:
        parts.RigidPart.push_wrenches = push
    rel, viscous, push_z = np.array(checked).T
    assert rel.max() < 1e-12, rel.max()  # measured 2e-15
    assert viscous.min() > 1e-4  # the viscous part is in both
    assert push_z.min() > 0.05  # the liquid pushes each box (N)


def test_a_heavy_box_sinks_to_the_floor():
    s, size = 0.01, 0.04
    tank = (0.1, 0.1, 0.12)
    bodies = RigidBodies([_box(size, (0.05, 0.05, 0.06 + size / 2), density=1500.0)],
                         colliders=Colliders().add(~Box((0, 0, 0), tank)))
    sim = _pool(bodies, s=s, tank=tank, depth=0.06)
    bottoms = []
    energy = [_energy(sim)]

    def record(sim):
        _no_liquid_inside(sim)
        bottoms.append((sim.state.time, bodies.state.positions[0, 2] - size / 2))
        energy.append(_energy(sim))

    _run(sim, 0.8, record)
    t, bottom = np.array(bottoms).T
    # energy of liquid and box never above its start: the box's fall is the only source and
    # viscosity, contacts and the pressure solves take energy away (measured: never above its
    # start; 1 % of the energy the fall releases allowed for the solver's tolerance)
    energy = np.array(energy)
    drop = energy[0] - energy.min()
    assert drop > 0 and (energy <= energy[0] + 0.01 * drop).all(), (energy - energy[0]).max()
    assert bottom.min() > -1e-9  # never through the floor
    # on the floor, on the one layer of liquid a particle thick that it cannot squeeze out
    # (the wall constraints hold that layer off both): measured 0.96-1.1 spacings
    assert (bottom[t > 0.5] < 1.5 * s).all(), bottom[t > 0.5].max()


def test_momentum_of_liquid_and_body_is_conserved_without_gravity():
    # a box shot through a blob of liquid floating in a closed tank without gravity: the
    # liquid's push on the box is the box's push on the liquid, step by step
    s, size = 0.01, 0.04
    tank = (0.3, 0.2, 0.2)
    water = _lattice((0.05, 0.04, 0.04), (0.25, 0.16, 0.16), s)
    bodies = RigidBodies([_box(size, (0.1, 0.1, 0.1), density=800.0)],
                         velocities=[[0.5, 0.0, 0.0]], gravity=(0.0, 0.0, 0.0))
    sim = _pool(bodies, s=s, tank=tank, water=water, gravity=(0.0, 0.0, 0.0))
    p0 = sim.momentum()
    _run(sim, 0.15)
    assert bodies.state.velocities[0, 0] < 0.45  # the liquid slowed the box down ...
    p1 = sim.momentum()
    assert np.linalg.norm(p1 - p0) < 1e-3 * np.linalg.norm(p0), (p0, p1)  # ... and took it up
    x = sim.liquid.state.positions  # no particle near a wall: walls gave no impulse
    assert x.min() > 2 * s and (x.max(axis=0) < np.array(tank) - 2 * s).all()
    _no_liquid_inside(sim)


def test_coupled_state_resumes_bit_for_bit():
    s = 0.02
    bodies = RigidBodies([_box(0.06, (0.08, 0.08, 0.12), density=700.0)],
                         angular_velocities=[[0.0, 2.0, 0.0]])
    sim = _pool(bodies, s=s, tank=(0.16, 0.16, 0.2), depth=0.1)
    _run(sim, 0.05)
    saved = sim.get_state()
    _run(sim, 0.1)
    first = sim.get_state().to_arrays()
    sim.set_state(saved)
    _run(sim, 0.1)
    second = sim.get_state().to_arrays()
    assert first.keys() == second.keys() and "extra:body0:orientations" in first
    for name in first:
        assert np.array_equal(first[name], second[name]), name


def test_bad_input_is_refused():
    s = 0.02
    bodies = RigidBodies([_box(0.06, (0.08, 0.08, 0.15), density=700.0)])
    walls = box_boundary((0, 0, 0), (0.16, 0.16, 0.2), s)
    x = _lattice((0, 0, 0), (0.16, 0.16, 0.06), s)
    wc = SPHLiquid(x, spacing=s, boundary=coupled_boundary(walls, bodies, s))
    with pytest.raises(ValueError, match="dfsph"):
        Coupled(wc, bodies)
    alone = SPHLiquid(x, spacing=s, boundary=walls, solver="dfsph")
    with pytest.raises(ValueError, match="coupled_boundary"):
        Coupled(alone, bodies)
    with pytest.raises(TypeError, match="RigidBodies or FEMSimulation"):
        Coupled(alone, [object()])
    with pytest.raises(TypeError, match="strong"):
        Coupled(alone, bodies, strong="yes")
    other = RigidBodies([_box(0.06, (0.08, 0.08, 0.15))], gravity=(0.0, 0.0, -1.0))
    liquid = SPHLiquid(x, spacing=s, boundary=coupled_boundary(walls, other, s), solver="dfsph")
    with pytest.raises(ValueError, match="gravity"):
        Coupled(liquid, other)


def test_a_coupled_run_is_the_same_on_one_thread_and_two():
    """SPHLiquid's promise (results identical for any thread count) with moving bodies in the
    liquid: a light box dropped in and a heavy one sinking, 0.3 s on one thread and on two,
    bit for bit."""
    import numba

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs two Numba threads")
    runs = []
    for threads in (1, 2):
        bodies = RigidBodies([_box(0.044, (0.06, 0.06, 0.12), density=600.0),
                              _box(0.03, (0.03, 0.03, 0.15), density=1500.0)],
                             colliders=Colliders().add(~Box((0, 0, 0), (0.12, 0.12, 0.2))))
        sim = _pool(bodies, threads=threads)
        _run(sim, 0.3)
        runs.append((sim.liquid.state.positions.copy(), sim.liquid.state.velocities.copy(),
                     bodies.state.positions.copy(), bodies.state.velocities.copy()))
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)
