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


def _every_solve():
    """(name, solve(b, x0) -> x) for every linear solver of filters.linalg, on one SPD system
    (a pinned cloth's implicit matrix, assembled and matrix-free)."""
    from filters.linalg import direct_solve, pcg, pcg_operator, solve_linear

    system, state = _cloth(5)
    x, h = state.positions, 0.01
    mat = system.system_matrix(x, x, h)
    op = system.implicit_operator(x, x, h)
    tight = dict(tol=1e-12, max_iter=5000)
    solves = [("pcg_block3", lambda b, w: pcg(mat, b, w, **tight)[0]),
              ("pcg_jacobi", lambda b, w: pcg(mat, b, w, block=1, **tight)[0]),
              ("direct_solve", lambda b, w: direct_solve(mat, b))]
    for method in ("auto", "pcg", "direct"):
        solves.append((f"solve_linear_{method}",
                       lambda b, w, method=method: solve_linear(mat, b, w, solver=method,
                                                                **tight)[0]))
    for pre in ("ssor", "sgs", "block_jacobi"):
        solves.append((f"pcg_operator_{pre}",
                       lambda b, w, pre=pre: pcg_operator(op, b, w, preconditioner=pre,
                                                          **tight)[0]))
    for method in ("auto", "pcg", "direct"):
        for target in (system, _AssembledOnly(system)):
            solver = LinearSolver(method)
            name = f"LinearSolver_{method}_{'operator' if target is system else 'csr'}"
            solves.append((name, lambda b, w, s=solver, t=target: s.solve(
                t, x, x, h, b.reshape(-1, 3), w, 1e-12, 5000)[0]))
    return mat, solves


@pytest.mark.parametrize("scale", [1e-200, 1e-310, 5e-324])
def test_tiny_and_denormal_states_through_every_linear_solver(scale):
    # a long undamped backward Euler run decays to ~1e-160 and below: CG squares its vectors,
    # which underflowed (a ZeroDivisionError, or a residual of 0 that ended the solve early)
    mat, solves = _every_solve()
    rng = np.random.default_rng(3)
    b = rng.normal(size=mat.shape[0])
    b[:3] = 0.0  # the first pin's rows
    b[3 * 5 - 3:3 * 5] = 0.0  # the second pin's
    exact = np.linalg.solve(mat.toarray(), b)
    tiny = b * scale
    for name, solve in solves:
        for warm in (None, exact):  # also from a warm start of ordinary size
            got = solve(tiny, warm).ravel()
            assert np.all(np.isfinite(got)), name
            if scale >= 1e-300:  # normal numbers: the solution of the tiny system itself
                np.testing.assert_allclose(got / scale, exact, rtol=1e-8,
                                           atol=1e-8 * np.abs(exact).max(), err_msg=name)
            else:  # denormals: the answer is zero to within the smallest numbers
                assert np.abs(got).max() <= 1e3 * scale * np.abs(exact).max(), name
        zero = solve(np.zeros_like(b), None).ravel()
        assert np.array_equal(zero, np.zeros_like(b)), name


def test_embedded_point_hessians_are_added_exactly():
    # a point inside a cell of a spring lattice, weights w: its Hessian H joins the system as
    # W^T H W (blocks w_a w_b H), not the diagonal bound sum_k w_k H
    from filters.elastic.topology import icosphere, jello_from_mesh
    from filters.linalg.coupling import add_point_hessians_csr, add_point_hessians_pairs

    top = jello_from_mesh(*icosphere(0.1, 1), spacing=0.05)
    system = SpringSystem(top.springs, top.rest_lengths, 1e3, top.masses)
    x, h = top.positions, 0.01
    emb = top.embedding
    rng = np.random.default_rng(2)
    m = emb.nodes.shape[0]
    a = rng.normal(size=(m, 3, 3))
    full = np.einsum("mij,mkj->mik", a, a)  # SPD per point
    hess = full[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]]
    n = x.shape[0]
    w = np.zeros((m, n))
    np.put_along_axis(w, emb.nodes, emb.weights, axis=1)
    exact = np.einsum("ma,mij,mb->aibj", w, full, w).reshape(3 * n, 3 * n)
    base = system.system_matrix(x, x, h).toarray()
    points = (emb.nodes, emb.weights, np.ascontiguousarray(hess))
    got = add_point_hessians_csr(system.system_matrix(x, x, h), *points, system.pinned)
    np.testing.assert_allclose(got.toarray(), base + exact, atol=1e-9 * np.abs(base).max())
    # the matrix-free operator: the diagonal bound, then the pair corrections
    bound = np.zeros((n, 3, 3))
    np.add.at(bound, emb.nodes.ravel(), (emb.weights[:, :, None, None]
                                         * full[:, None]).reshape(-1, 3, 3))
    op = system.implicit_operator(x, x, h)
    op.diag += bound
    assert add_point_hessians_pairs(op, *points)
    p = rng.normal(size=(n, 3))
    np.testing.assert_allclose(op.matvec(p).ravel(), (base + exact) @ p.ravel(),
                               rtol=1e-9, atol=1e-9 * np.abs(base).max())
    # a pattern without the pairs: refused, nothing changed
    cloth, _ = _cloth(4)
    far = (np.array([[1, 14]]), np.array([[0.5, 0.5]]), np.ones((1, 6)))
    assert add_point_hessians_csr(cloth.system_matrix(_.positions, _.positions, h), *far,
                                  cloth.pinned) is None
