"""Pressure as data and water that starts at rest (filters.sph.settle, SPHLiquid's frames)."""

import numpy as np
import pytest

from filters.sph import SPHLiquid
from filters.sph.boundary import box_boundary
from filters.sph.scenarios import drop_liquid
from filters.sph.settle import hydrostatic_pressure, settle

G = 9.81
RHO0 = 1000.0


def _column(s, width=0.1, height=0.2):
    axes = [(np.arange(round(n / s)) + 0.5) * s for n in (width, width, height)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)


def _gradient(points, pressure, h, width):
    """-dp/dz / (rho0 g) by least squares over the particles at least a support radius from
    the side walls, the floor and the free surface."""
    z = points[:, 2]
    inner = (np.abs(points[:, :2] - 0.5 * width) < 0.5 * width - h).all(axis=1)
    band = inner & (z > h) & (z < z.max() - h)
    A = np.stack([z[band], np.ones(band.sum())], axis=1)
    slope = np.linalg.lstsq(A, pressure[band], rcond=None)[0][0]
    return -slope / (RHO0 * G)


def test_frames_carry_the_hydrostatic_pressure_of_a_settled_column():
    """A 0.1 x 0.1 x 0.2 m column at 1 cm, settled, written as the pipeline writes frames
    (advance_to the frame time, then frame()): the pressure gradient is rho0 g within 3 % on
    average over 30 frames and within 10 % in every one (the issue measured 1.23 on average
    and up to 2.5 in single frames before)."""
    s, width = 0.01, 0.1
    x = _column(s)
    walls = box_boundary((0, 0, 0), (width, width, 0.3), s)
    sim = SPHLiquid(x, spacing=s, boundary=walls, solver="dfsph",
                    initial_pressure=hydrostatic_pressure(x, s))
    settle(sim, max_time=1.0, damping=0.05)
    h = sim.model.support
    ratios = []
    for k in range(1, 31):
        sim.advance_to(k / 30)
        f = sim.frame()
        ratios.append(_gradient(f.points, f.point_data["pressure"], h, width))
        top = f.points[:, 2] > f.points[:, 2].max() - 0.5 * s
        assert f.point_data["pressure"][top].mean() < RHO0 * G * s  # gauge: ~0 at the top
    ratios = np.array(ratios)
    assert abs(ratios.mean() - 1.0) < 0.03, ratios
    assert np.abs(ratios - 1.0).max() < 0.10, ratios


def test_advance_to_leaves_no_sliver_of_a_step():
    """The last steps before a frame time are at least half a step long: a DFSPH density
    solve given a sliver of a step asks for velocities as much larger."""
    x = _column(0.02, 0.1, 0.1)
    sim = SPHLiquid(x, spacing=0.02, boundary=box_boundary((0, 0, 0), (0.1, 0.1, 0.2), 0.02),
                    solver="dfsph")
    taken = []
    step = sim.step

    def record(dt):
        taken.append((dt, sim.max_step()))
        step(dt)

    sim.step = record
    for k in range(1, 20):
        sim.advance_to(k / 300 + 1e-7)  # frame times a sliver past whole steps
    assert all(dt >= 0.5 * full * (1 - 1e-9) for dt, full in taken[1:])


def test_pools_start_at_rest():
    """The drop scene's pool starts settled: with the drop still far above (the tank made
    tall), the pool's surface moves by less than 0.01 spacings over the first 0.5 s."""
    s = 0.012
    sim = drop_liquid(tank_length=0.24, tank_width=0.24, tank_height=2.0, pool_depth=0.05,
                      drop_radius=0.04, drop_height=1.9, spacing=s, solver="dfsph")
    def heights():
        z = np.empty(sim.state.n_points)
        z[sim.state.extra["id"]] = sim.state.positions[:, 2]
        return z

    z = heights()
    pool = np.flatnonzero(z < 0.1)
    top = pool[z[pool] > z[pool].max() - 0.5 * s]
    assert top.size >= 300  # the whole top layer
    start = z[top].mean()
    worst = 0.0
    for k in range(1, 16):
        sim.advance_to(k / 30)
        z = heights()
        worst = max(worst, abs(z[top].mean() - start) / s)
        assert z[pool].max() < 0.1  # nothing fell in yet
    assert worst < 0.01


def test_hydrostatic_pressure_of_a_lattice_column():
    s = 0.01
    x = _column(s, 0.05, 0.1)
    p = hydrostatic_pressure(x, s)
    np.testing.assert_allclose(p, RHO0 * G * (0.1 - x[:, 2]), rtol=1e-12)
    sideways = hydrostatic_pressure(x[:, [2, 1, 0]], s, gravity=(-G, 0, 0))
    np.testing.assert_allclose(sideways, p, rtol=1e-12)
    assert (hydrostatic_pressure(x, s, gravity=(0, 0, 0)) == 0).all()
    with pytest.raises(ValueError, match="spacing"):
        hydrostatic_pressure(x, 0.0)


def test_settle_refuses_what_it_cannot_do():
    x = _column(0.02, 0.04, 0.04)
    with pytest.raises(ValueError, match="solver='dfsph'"):
        settle(SPHLiquid(x, spacing=0.02))
    sim = SPHLiquid(x, spacing=0.02, solver="dfsph")
    with pytest.raises(ValueError, match="max_time"):
        settle(sim, max_time=0.0)
    with pytest.raises(ValueError, match="damping"):
        settle(sim, damping=0.0)
    with pytest.raises(ValueError, match="initial_pressure"):
        SPHLiquid(x, spacing=0.02, solver="dfsph", initial_pressure=-np.ones(x.shape[0]))
    with pytest.raises(ValueError, match="initial_pressure needs solver='dfsph'"):
        SPHLiquid(x, spacing=0.02, initial_pressure=np.zeros(x.shape[0]))


def test_a_settled_pool_stays_about_still():
    """settle's docstring: with its default damping the pool left after a second of settling
    moves at a median 4e-3 m/s over the next 0.3 s (with the velocities zeroed after every
    settling step, the earlier default, 1.8e-2: the particles random-walk on the solves'
    residual)."""
    s, tank = 0.01, (0.12, 0.12, 0.2)
    x = _column(s, 0.12, 0.1)
    sim = SPHLiquid(x, spacing=s, boundary=box_boundary((0, 0, 0), tank, s), solver="dfsph",
                    kinematic_viscosity=1e-4, max_dt=0.005,
                    initial_pressure=hydrostatic_pressure(x, s))
    moved = settle(sim, max_time=1.0)
    assert 1e-4 < moved < 0.05  # the tolerance is not reached: the time limit ended it
    speeds = []
    while sim.state.time < 0.3:
        sim.step(sim.max_step())
        speeds.append(np.linalg.norm(sim.state.velocities, axis=1))
    assert np.median(speeds) < 8e-3, np.median(speeds)
