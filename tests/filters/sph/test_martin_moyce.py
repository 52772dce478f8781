"""The dam break's surge front and residual column against Martin & Moyce (1952), at a coarse
resolution (a / 10), full depth and quasi-2D (benchmarks/bench_dam_break_validation.py runs
a / 25 and a / 50)."""

import math

import numpy as np
import pytest

from filters.sph.martin_moyce import (
    FRONT_T,
    FRONT_Z,
    HEIGHT_H,
    HEIGHT_TAU,
    column_height,
    compare,
    surge_front,
)
from filters.sph.scenarios import dam_break_liquid

A = 0.1
G = 9.81


def _collapse(setup, friction, divisor=10):
    s = A / divisor
    depth = A if setup == "full" else 4 * s
    slip = ("x", "y", "z") if not friction else ("y",) if setup == "quasi2d" else ()
    sim = dam_break_liquid(column_width=A, column_height=2 * A, tank_length=4 * A, depth=depth,
                           tank_height=3 * A, spacing=s, free_slip=slip, solver="dfsph",
                           kinematic_viscosity=4e-4, max_dt=0.005)
    scale = math.sqrt(2 * G / A)
    times, fronts, heights = [], [], []
    for T in np.arange(0.0, 3.0 + 1e-9, 0.05):
        sim.advance_to(T / scale)
        times.append(T / scale)
        fronts.append(surge_front(sim.state.positions, s, depth))
        heights.append(column_height(sim.state.positions, s, depth))
    assert sim.contained == 0
    return compare(times, fronts, heights, A, G)


@pytest.mark.parametrize("setup", ["full", "quasi2d"])
def test_front_and_column_follow_martin_and_moyce(setup):
    """The scene's settings (no-slip walls, kinematic viscosity 4e-4 m^2/s): front within 10 %
    on average over 0.8 <= T <= 3 (Table 2), the column's height within 10 % (Table 6)."""
    r = _collapse(setup, friction=True)
    assert len(r["front_errors"]) == 12 and len(r["height_errors"]) == 9
    assert r["front_mean_abs"] < 0.10, r["front_errors"]
    assert r["height_mean_abs"] < 0.10, r["height_errors"]


def test_frictionless_walls_let_the_front_run_ahead():
    """Why the scene keeps its walls' friction: with free-slip walls the surge outruns the
    experiment, whose front the floor's friction (and the gate's release) hold back."""
    free = _collapse("quasi2d", friction=False)
    held = _collapse("quasi2d", friction=True)
    assert free["front_mean"] > 0.05
    assert free["front_mean"] > held["front_mean"] + 0.03


def test_measures_and_tables():
    x = np.stack(np.meshgrid((np.arange(10) + 0.5) * 0.01, (np.arange(4) + 0.5) * 0.01,
                             (np.arange(20) + 0.5) * 0.01, indexing="ij"), -1).reshape(-1, 3)
    assert surge_front(x, 0.01, 0.04) == pytest.approx(A)
    assert column_height(x, 0.01, 0.04) == pytest.approx(2 * A)
    assert (np.diff(FRONT_T) > 0).all() and (np.diff(FRONT_Z) > 0).all()
    assert (np.diff(HEIGHT_TAU) > 0).all() and (np.diff(HEIGHT_H) < 0).all()
    # the table itself compared with itself: no error
    t = FRONT_T / math.sqrt(2 * G / A)
    r = compare(t, FRONT_Z * A, np.interp(t * math.sqrt(G / A), HEIGHT_TAU, HEIGHT_H) * 2 * A,
                A, G)
    assert max(map(abs, r["front_errors"])) < 1e-12
