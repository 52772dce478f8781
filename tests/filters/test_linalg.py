"""filters.linalg: the implicit-system protocol, the solver that owns its scratch arrays, and the
one vocabulary of time-stepping schemes."""

import numpy as np
import pytest

from filters.advect import NoiseAdvection
from filters.elastic.springs import SpringSystem
from filters.elastic.topology import cloth_grid
from filters.fields import Uniform
from filters.integrators import SCHEMES, backward_euler, integrate
from filters.linalg import BlockOperator, ImplicitSystem, LinearSolver
from filters.simulation import State


def _cloth(n=6):
    top = cloth_grid(n, n, size=(1.0, 1.0)).with_pins([0, n - 1])
    system = SpringSystem(top.springs, top.rest_lengths, 1e3, top.masses, damping=0.1,
                          pinned=top.pinned)
    return system, State(top.positions.copy())


class _AssembledOnly(ImplicitSystem):
    """A system without a matrix-free form: the solvers assemble its CSR matrix."""

    def __init__(self, system):
        self.inner = system
        self.masses, self.inv_mass = system.masses, system.inv_mass
        self.pinned, self.gravity = system.pinned, system.gravity

    def forces(self, x, v):
        return self.inner.forces(x, v)

    def conservative_forces(self, x):
        return self.inner.conservative_forces(x)

    def damping_forces(self, xdir, v):
        return self.inner.damping_forces(xdir, v)

    def potential_energy(self, x):
        return self.inner.potential_energy(x)

    def system_matrix(self, x, xdir, h):
        return self.inner.system_matrix(x, xdir, h)


def test_springs_are_an_implicit_system_with_a_block_operator():
    system, state = _cloth()
    assert isinstance(system, ImplicitSystem)
    op = system.implicit_operator(state.positions, state.positions, 0.01)
    assert isinstance(op, BlockOperator)
    p = np.random.default_rng(1).normal(size=state.positions.shape)
    dense = system.system_matrix(state.positions, state.positions, 0.01).toarray()
    np.testing.assert_allclose(op.matvec(p).ravel(), dense @ p.ravel(), rtol=1e-12, atol=1e-9)
    assert not hasattr(op, "_ssor_work")  # the scratch belongs to the solver


def test_the_solver_keeps_its_scratch_and_gives_the_same_steps():
    system, state = _cloth()
    solver = LinearSolver("pcg")
    a, b = state.copy(), state.copy()
    for _ in range(3):
        backward_euler(system, a, 0.01, solver=solver)
        backward_euler(system, b, 0.01, solver="pcg")
    first = solver.workspace.arrays
    assert first is not None
    backward_euler(system, a, 0.01, solver=solver)
    assert solver.workspace.arrays is first  # reused, not reallocated
    backward_euler(system, b, 0.01, solver="pcg")
    np.testing.assert_array_equal(a.positions, b.positions)
    with pytest.raises(ValueError, match="LinearSolver"):
        backward_euler(system, a, 0.01, solver=solver, preconditioner="sgs")


def test_a_system_without_an_operator_is_solved_on_its_matrix():
    system, state = _cloth()
    assembled = _AssembledOnly(system)
    assert assembled.implicit_operator(state.positions, state.positions, 0.01) is None
    a, b = state.copy(), state.copy()
    tight = dict(newton_tol=1e-10, tol=1e-12, forcing=None, max_iter=5000)
    backward_euler(system, a, 0.01, solver="direct", **tight)
    backward_euler(assembled, b, 0.01, solver="auto", **tight)  # CSR PCG
    np.testing.assert_allclose(a.positions, b.positions, atol=1e-9)


@pytest.mark.parametrize("old, new", [("forward", "euler"), ("symplectic", "symplectic_euler"),
                                      ("linearized", "linearized_backward_euler"),
                                      ("newton", "backward_euler")])
def test_former_scheme_names_say_the_current_one(old, new):
    system, state = _cloth()
    assert new in SCHEMES
    with pytest.raises(ValueError, match=f"now called '{new}'"):
        integrate(system, state, 0.01, old)


def test_advection_and_springs_share_the_scheme_names():
    assert {"euler", "linearized_backward_euler"} <= set(SCHEMES)
    sim = NoiseAdvection(Uniform((1.0, 0.0, 0.0)), positions=np.zeros((1, 3)),
                         integrator="linearized_backward_euler")
    sim.advance_to(0.1)
    assert sim.state.positions[0, 0] == pytest.approx(0.1)
    with pytest.raises(ValueError, match="linearized_backward_euler"):
        NoiseAdvection(Uniform(), positions=np.zeros((1, 3)), integrator="backward_euler")
